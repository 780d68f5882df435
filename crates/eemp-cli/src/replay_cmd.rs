//! `eemp replay DIR --video FILE`: a video of a finished walk from its `trace.csv` (joint
//! angles and trunk pose per row; traces from before the joint columns cannot be replayed).

use crate::video::{write_gif, VideoFrame, FPS};
use eemp_core::leg::{Leg, LegMap};
use nalgebra::Vector3;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct ReplayArgs {
    /// A walk's output folder (trace.csv, summary.json).
    pub dir: PathBuf,
    /// The video to write (animated GIF).
    #[arg(long)]
    pub video: PathBuf,
    #[arg(long)]
    pub robot: Option<PathBuf>,
}

pub fn run(args: &ReplayArgs) -> Result<(), String> {
    let robot = crate::robot_arg::load_robot(args.robot.as_deref())?;
    let trace = args.dir.join("trace.csv");
    let mut rd = csv::Reader::from_path(&trace)
        .map_err(|e| format!("cannot read {}: {e}", trace.display()))?;
    let header = rd
        .headers()
        .map_err(|e| format!("{}: {e}", trace.display()))?
        .clone();
    let col = |name: &str| {
        header.iter().position(|h| h == name).ok_or_else(|| {
            format!(
                "{} has no column {name} (written by an older eemp? walk again to replay)",
                trace.display()
            )
        })
    };
    let base = [
        "time_s",
        "x_m",
        "y_m",
        "z_m",
        "roll_rad",
        "pitch_rad",
        "yaw_rad",
    ]
    .map(col);
    let base: Vec<usize> = base.into_iter().collect::<Result<_, _>>()?;
    let vel: Vec<usize> = ["vx_mps", "vy_mps", "cmd_vx_mps", "cmd_vy_mps"]
        .iter()
        .map(|n| col(n))
        .collect::<Result<_, _>>()?;
    let mut qcol = LegMap::splat([0usize; 3]);
    for leg in Leg::ALL {
        for j in 0..3 {
            qcol[leg][j] = col(&format!("{}_q{j}_rad", leg.short_name()))?;
        }
    }
    // The ground the walk was on: its scenario's terrain.
    let summary: serde_json::Value = std::fs::read_to_string(args.dir.join("summary.json"))
        .ok()
        .and_then(|s| serde_json::from_str(&s).ok())
        .unwrap_or_default();
    let (terrain, friction) = match summary["scenario"].as_str() {
        Some(p) => {
            let sc = eemp_sim::scenario::Scenario::load(std::path::Path::new(p))
                .map_err(|e| format!("the walk's scenario: {e}"))?;
            (sc.terrain, sc.floor_friction)
        }
        None => (Default::default(), None),
    };
    let mut frames = Vec::new();
    let mut next_t = f64::NEG_INFINITY;
    for (k, rec) in rd.records().enumerate() {
        let rec = rec.map_err(|e| format!("{} row {}: {e}", trace.display(), k + 2))?;
        let v = |i: usize| -> Result<f64, String> {
            rec.get(i)
                .and_then(|s| s.parse::<f64>().ok())
                .filter(|x| x.is_finite())
                .ok_or_else(|| {
                    format!(
                        "{} row {}, column {}: not a finite number",
                        trace.display(),
                        k + 2,
                        &header[i]
                    )
                })
        };
        let t = v(base[0])?;
        if t + 1e-9 < next_t {
            continue;
        }
        next_t = if next_t.is_finite() {
            next_t + 1.0 / FPS
        } else {
            t + 1.0 / FPS
        };
        let mut q = LegMap::splat(Vector3::zeros());
        for leg in Leg::ALL {
            for j in 0..3 {
                q[leg][j] = v(qcol[leg][j])?;
            }
        }
        frames.push(VideoFrame {
            t_s: t,
            p_world: Vector3::new(v(base[1])?, v(base[2])?, v(base[3])?),
            rpy: Vector3::new(v(base[4])?, v(base[5])?, v(base[6])?),
            q,
            cmd: [v(vel[2])?, v(vel[3])?],
            measured: [v(vel[0])?, v(vel[1])?],
        });
    }
    if frames.is_empty() {
        return Err(format!("{} holds no rows", trace.display()));
    }
    let label = summary["method"]
        .as_str()
        .or(summary["controller"].as_str())
        .unwrap_or("replay")
        .to_string();
    let scene = terrain.scene(friction.unwrap_or(robot.simulation.floor_friction));
    write_gif(&robot, &scene, &frames, &label, &args.video)?;
    println!("wrote {} ({} frames)", args.video.display(), frames.len());
    Ok(())
}
