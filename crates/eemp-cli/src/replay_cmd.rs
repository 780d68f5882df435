//! `eemp replay DIR --video FILE` / `--rerun FILE.rrd`: a video or a Rerun recording of a
//! finished walk from its `trace.csv` (trunk pose, joints, torques, feet per row; traces from
//! before the joint columns cannot be replayed).
//!
//! A trace holds no planner geometry, forces or estimate, but a walk is deterministic and its
//! `summary.json` keeps its command line: `--rerun` first simulates the walk again and, when the
//! new trace equals `trace.csv` byte for byte, records that same run with everything (ellipses,
//! footholds, forces). Otherwise (another code version, moved files, `--from-trace`) it records
//! what the trace holds: the robot, its touchdowns and the time series.

use crate::video::{write_gif, VideoFrame, FPS};
use eemp_core::body_state::{BodyState, LegJointState, RobotState};
use eemp_core::leg::{Leg, LegMap};
use eemp_core::locomotion::ControlOutput;
use eemp_core::planner::VelocityCommand;
use eemp_sim::closed_loop::StepRecord;
use nalgebra::{UnitQuaternion, Vector3};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct ReplayArgs {
    /// A walk's output folder (trace.csv, summary.json).
    pub dir: PathBuf,
    /// The video to write (animated GIF).
    #[arg(long)]
    pub video: Option<PathBuf>,
    /// The robot file the walk ran (default: the shipped A1); give the same one the walk had.
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// Replay on --robot even where the walk's summary names other physics (a robot file edited
    /// since the walk, say).
    #[arg(long)]
    pub allow_robot_mismatch: bool,
    #[command(flatten)]
    pub rerun: crate::rerun_arg::RerunArgs,
    /// Record from the trace only, without simulating the walk again (no planner geometry).
    #[arg(long)]
    pub from_trace: bool,
}

/// One trace row as the closed loop would have shown it.
struct Row {
    state: RobotState,
    command: VelocityCommand,
    torques: LegMap<Vector3<f64>>,
    feet_world: LegMap<Vector3<f64>>,
    contacts: LegMap<bool>,
}

pub fn run(args: &ReplayArgs) -> Result<(), String> {
    if args.video.is_none() && !args.rerun.wanted() {
        return Err("replay needs --video FILE.gif and/or --rerun FILE.rrd (or --rerun-connect/--rerun-serve)".into());
    }
    let robot = crate::robot_arg::load_robot(args.robot.as_deref())?;
    // The walk's summary: the robot it ran (a trace drawn on another robot's body would be wrong
    // without a word) and its scenario's ground.
    let summary: serde_json::Value = std::fs::read_to_string(args.dir.join("summary.json"))
        .ok()
        .and_then(|s| serde_json::from_str(&s).ok())
        .unwrap_or_default();
    if let (Some(name), Some(physics_hash)) = (
        summary["robot"]["name"].as_str(),
        summary["robot"]["physics_hash"].as_str(),
    ) {
        let walked = eemp_core::robot::RobotId {
            name: name.into(),
            physics_hash: physics_hash.into(),
        };
        if !args.allow_robot_mismatch {
            walked
                .check(&robot, &format!("the walk in {}", args.dir.display()))
                .map_err(|e| {
                    format!(
                        "{} was walked by another robot than {}: {e}",
                        args.dir.display(),
                        args.robot
                            .as_ref()
                            .map_or("the shipped A1".to_string(), |p| p.display().to_string()),
                    )
                })?;
        }
    }
    let trace = args.dir.join("trace.csv");
    let mut rerun_done = false;
    if args.rerun.wanted() && !args.from_trace {
        match resimulate(args, &trace)? {
            Ok(()) => rerun_done = true,
            Err(why) => eprintln!("note: {why}; recording what the trace holds"),
        }
    }
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
    let vel: Vec<usize> = [
        "vx_mps",
        "vy_mps",
        "cmd_vx_mps",
        "cmd_vy_mps",
        "vz_mps",
        "cmd_yaw_rate_rps",
    ]
    .iter()
    .map(|n| col(n))
    .collect::<Result<_, _>>()?;
    let mut qcol = LegMap::splat([0usize; 3]);
    let mut qdcol = LegMap::splat([0usize; 3]);
    let mut taucol = LegMap::splat([0usize; 3]);
    let mut footcol = LegMap::splat([0usize; 3]);
    let mut contactcol = LegMap::splat(0usize);
    for leg in Leg::ALL {
        let n = leg.short_name();
        for j in 0..3 {
            qcol[leg][j] = col(&format!("{n}_q{j}_rad"))?;
            qdcol[leg][j] = col(&format!("{n}_qd{j}_radps"))?;
            taucol[leg][j] = col(&format!("{n}_tau{j}_nm"))?;
            footcol[leg][j] = col(&format!("{n}_foot_{}_m", ["x", "y", "z"][j]))?;
        }
        contactcol[leg] = col(&format!("{n}_contact"))?;
    }
    // The ground the walk was on: its scenario's terrain.
    let (terrain, friction) = match summary["scenario"].as_str() {
        Some(p) => {
            let sc = eemp_sim::scenario::Scenario::load(std::path::Path::new(p))
                .map_err(|e| format!("the walk's scenario: {e}"))?;
            (sc.terrain, sc.floor_friction)
        }
        None => (Default::default(), None),
    };
    let mut frames = Vec::new();
    let mut rows = Vec::new();
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
        if args.rerun.wanted() && !rerun_done {
            let mut joints = LegMap::splat(LegJointState::default());
            let (mut torques, mut feet_world) = (
                LegMap::splat(Vector3::zeros()),
                LegMap::splat(Vector3::zeros()),
            );
            let mut contacts = LegMap::splat(false);
            for leg in Leg::ALL {
                for j in 0..3 {
                    joints[leg].q[j] = v(qcol[leg][j])?;
                    joints[leg].qd[j] = v(qdcol[leg][j])?;
                    torques[leg][j] = v(taucol[leg][j])?;
                    feet_world[leg][j] = v(footcol[leg][j])?;
                }
                contacts[leg] = v(contactcol[leg])? > 0.5;
            }
            let r_world_body =
                UnitQuaternion::from_euler_angles(v(base[4])?, v(base[5])?, v(base[6])?);
            let heading = UnitQuaternion::from_euler_angles(0.0, 0.0, v(base[6])?);
            rows.push(Row {
                state: RobotState {
                    time_s: t,
                    body: BodyState {
                        p_world: Vector3::new(v(base[1])?, v(base[2])?, v(base[3])?),
                        r_world_body,
                        v_world: heading * Vector3::new(v(vel[0])?, v(vel[1])?, v(vel[4])?),
                        omega_world: Vector3::zeros(),
                    },
                    joints,
                },
                command: VelocityCommand {
                    vx_mps: v(vel[2])?,
                    vy_mps: v(vel[3])?,
                    yaw_rate_rps: v(vel[5])?,
                },
                torques,
                feet_world,
                contacts,
            });
        }
        if args.video.is_none() || t + 1e-9 < next_t {
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
    if frames.is_empty() && rows.is_empty() && !rerun_done {
        return Err(format!("{} holds no rows", trace.display()));
    }
    let label = summary["method"]
        .as_str()
        .or(summary["controller"].as_str())
        .unwrap_or("replay")
        .to_string();
    let scene = terrain.scene(friction.unwrap_or(robot.simulation.floor_friction));
    if !rows.is_empty() {
        record(args, &robot, &scene, &label, &mut rows)?;
    }
    if let Some(video) = &args.video {
        write_gif(&robot, &scene, &frames, &label, video)?;
        println!("wrote {} ({} frames)", video.display(), frames.len());
    }
    Ok(())
}

/// The trace's rows through the recorder, as the closed loop's observer would have seen them
/// (the yaw rate from successive yaws; no plan, forces or estimate).
fn record(
    args: &ReplayArgs,
    robot: &eemp_core::robot::RobotConfig,
    scene: &eemp_sim::mjcf::SceneExtras,
    label: &str,
    rows: &mut [Row],
) -> Result<(), String> {
    let step_s = match rows {
        [a, b, ..] => b.state.time_s - a.state.time_s,
        _ => robot.simulation.timestep_s,
    };
    for k in 1..rows.len() {
        let dt = rows[k].state.time_s - rows[k - 1].state.time_s;
        let dyaw = rows[k].state.body.rpy().z - rows[k - 1].state.body.rpy().z;
        let dyaw =
            (dyaw + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
        if dt > 0.0 {
            rows[k].state.body.omega_world.z = dyaw / dt;
        }
    }
    let mut recorder = args.rerun.open_world(crate::rerun_arg::World {
        name: &format!("replay: {label}"),
        robot: robot.clone(),
        scene: scene.clone(),
        pushes: Vec::new(),
        estimated: false,
        step_s,
    })?;
    for row in rows.iter() {
        let output = ControlOutput {
            torques: row.torques,
            forces_world: LegMap::splat(Vector3::zeros()),
            mpc_event: None,
        };
        recorder.observe(&StepRecord {
            state: &row.state,
            estimate: &row.state,
            plan: None,
            command: row.command,
            output: &output,
            feet_world: &row.feet_world,
            contacts: row.contacts,
            loaded: row.contacts,
            foot_normal_n: LegMap::splat(0.0),
        });
    }
    if let Some(summary) = recorder.finish() {
        println!("recorded {} trace rows: {summary}", rows.len());
    }
    Ok(())
}

/// Options of a walk's command line that name its outputs (dropped when it runs again), with
/// whether they take a value.
const OUTPUT_OPTIONS: &[(&str, bool)] = &[
    ("--out", true),
    ("--video", true),
    ("--rerun", true),
    ("--rerun-connect", true),
    ("--rerun-serve", true),
    ("--rerun-hz", true),
];

/// The walk's arguments without its outputs.
fn without_outputs(command: &[String]) -> Vec<String> {
    let mut out = Vec::new();
    let mut it = command.iter();
    while let Some(a) = it.next() {
        let name = a.split('=').next().unwrap_or(a);
        match OUTPUT_OPTIONS.iter().find(|(o, _)| *o == name) {
            Some((_, true)) if !a.contains('=') => {
                it.next();
            }
            Some(_) => {}
            None => out.push(a.clone()),
        }
    }
    out
}

/// Simulates the walk of `args.dir` again from its `summary.json` command; when its trace
/// equals the stored one, simulates it once more with the recorder. `Ok(Err(why))`: it cannot
/// be re-simulated to the same run.
fn resimulate(args: &ReplayArgs, trace: &std::path::Path) -> Result<Result<(), String>, String> {
    let summary: serde_json::Value = match std::fs::read_to_string(args.dir.join("summary.json"))
        .ok()
        .and_then(|s| serde_json::from_str(&s).ok())
    {
        Some(v) => v,
        None => {
            return Ok(Err(format!(
                "{}/summary.json cannot be read",
                args.dir.display()
            )))
        }
    };
    let Some(command) = summary["command"].as_array().and_then(|a| {
        a.iter()
            .map(|v| v.as_str().map(String::from))
            .collect::<Option<Vec<String>>>()
    }) else {
        return Ok(Err(
            "summary.json has no command (a walk from before eemp kept it)".into(),
        ));
    };
    if command.first().map(String::as_str) != Some("walk") {
        return Ok(Err(format!(
            "the run was `eemp {}`, not a walk",
            command.join(" ")
        )));
    }
    let cwd = summary["cwd"]
        .as_str()
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("."));
    let stored =
        std::fs::read(trace).map_err(|e| format!("cannot read {}: {e}", trace.display()))?;
    let exe = std::env::current_exe().map_err(|e| format!("cannot find eemp itself: {e}"))?;
    let tmp = std::env::temp_dir().join(format!("eemp-replay-{}", std::process::id()));
    // The walk runs again in its own folder: a relative $EEMP_PYTHON means this folder's.
    let python_env = std::env::var_os(eemp_viz::backend::PYTHON_ENV)
        .map(PathBuf::from)
        .filter(|p| p.components().count() > 1)
        .and_then(|p| std::path::absolute(p).ok());
    let walk = |out: &std::path::Path, extra: &[String]| -> Result<bool, String> {
        let mut c = std::process::Command::new(&exe);
        if let Some(py) = &python_env {
            c.env(eemp_viz::backend::PYTHON_ENV, py);
        }
        let status = c
            .args(without_outputs(&command))
            .arg("--out")
            .arg(out)
            .args(extra)
            .current_dir(&cwd)
            .stdout(std::process::Stdio::null())
            .status()
            .map_err(|e| format!("cannot run the walk again: {e}"))?;
        Ok(status.success())
    };
    let check_dir = tmp.join("check");
    let same = walk(&check_dir, &[])?
        && std::fs::read(check_dir.join("trace.csv")).ok().as_deref() == Some(&stored[..]);
    if !same {
        let _ = std::fs::remove_dir_all(&tmp);
        return Ok(Err(format!(
            "`eemp {}` (in {}) does not give the same trace again (another code version or \
             moved inputs)",
            command.join(" "),
            cwd.display()
        )));
    }
    let r = &args.rerun;
    let mut extra = vec!["--rerun-hz".to_string(), r.rerun_hz.to_string()];
    if let Some(f) = &r.rerun {
        let abs = std::path::absolute(f).map_err(|e| format!("{}: {e}", f.display()))?;
        extra.extend(["--rerun".into(), abs.display().to_string()]);
    }
    if let Some(a) = &r.rerun_connect {
        extra.extend(["--rerun-connect".into(), a.clone()]);
    }
    if let Some(p) = r.rerun_serve {
        extra.extend(["--rerun-serve".into(), p.to_string()]);
    }
    let ok = walk(&tmp.join("record"), &extra)?;
    let _ = std::fs::remove_dir_all(&tmp);
    if !ok {
        return Err("the re-simulated walk could not be recorded".into());
    }
    println!(
        "re-simulated `eemp {}`: the same trace byte for byte; recorded it with the planner's \
         geometry",
        without_outputs(&command).join(" ")
    );
    Ok(Ok(()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_walks_outputs_are_dropped_from_its_command() {
        let c: Vec<String> = [
            "walk",
            "--speed",
            "0.3",
            "--out",
            "o",
            "--video=v.gif",
            "--rerun",
            "a.rrd",
            "--gait",
            "free",
        ]
        .map(String::from)
        .to_vec();
        assert_eq!(
            without_outputs(&c),
            ["walk", "--speed", "0.3", "--gait", "free"]
                .map(String::from)
                .to_vec()
        );
    }
}
