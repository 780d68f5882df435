//! `eemp retarget`: a raw dog clip → an A1 reference motion file, with figures to check it.

use crate::plots::{gait_diagram, line_panels, stick_figures, Panel, Series, StickFrame};
use eemp_core::kinematics::LegKinematics;
use eemp_core::leg::Leg;
use eemp_core::robot::RobotConfig;
use eemp_rl::imitation::mocap::MocapClip;
use eemp_rl::imitation::motion::{gait_of, CONTACT_HEIGHT_M, CONTACT_SPEED_MPS};
use eemp_rl::imitation::retarget::{retarget, RetargetConfig, Retargeted};
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct RetargetArgs {
    /// Clip name (e.g. dog_walk03, as `<name>_joint_pos.txt` in --mocap-dir) or a file path.
    #[arg(long)]
    pub clip: String,
    /// Frames A..B (half-open, as the original work's windows: pace dog_walk00 162..201,
    /// trot dog_walk03 448..481, trot2 dog_run04 630..663); default: the whole clip.
    #[arg(long)]
    pub frames: Option<String>,
    /// Folder of the raw clips.
    #[arg(long, default_value = "../shared/reference/dog_mocap/raw_keypoints")]
    pub mocap_dir: PathBuf,
    /// Reference motion file to write (CSV); figures beside it (`.png`, `_frames.png`).
    #[arg(long)]
    pub out: PathBuf,
    /// Robot description (default: the shipped A1).
    #[arg(long)]
    pub robot: Option<PathBuf>,
}

fn parse_frames(s: &str) -> Result<(usize, usize), String> {
    let bad = || format!("--frames '{s}' is not A..B with whole numbers A < B");
    let (a, b) = s.split_once("..").ok_or_else(bad)?;
    let a: usize = a.trim().parse().map_err(|_| bad())?;
    let b: usize = b.trim().parse().map_err(|_| bad())?;
    if a >= b {
        return Err(format!("--frames {a}..{b} is empty: allowed A < B"));
    }
    Ok((a, b))
}

pub fn run(args: &RetargetArgs) -> Result<(), String> {
    let path = {
        let p = Path::new(&args.clip);
        if p.extension().is_some() || p.components().count() > 1 {
            p.to_path_buf()
        } else {
            args.mocap_dir.join(format!("{}_joint_pos.txt", args.clip))
        }
    };
    let robot = crate::robot_arg::load_robot(args.robot.as_deref())?;
    let clip = MocapClip::load(&path).map_err(|e| e.to_string())?;
    let (start, end) = match &args.frames {
        Some(f) => parse_frames(f)?,
        None => (0, clip.frames.len()),
    };
    let cfg = RetargetConfig::default();
    let r = retarget(&cfg, &robot, &clip, start, end).map_err(|e| e.to_string())?;
    let contacts = r.motion.contacts(CONTACT_HEIGHT_M, CONTACT_SPEED_MPS);
    let gait = gait_of(&contacts);
    // Everything is computed before anything is written.
    r.motion.save(&args.out).map_err(|e| e.to_string())?;
    let feet_png = args.out.with_extension("png");
    let frames_png = with_suffix(&args.out, "_frames.png");
    let gait_png = with_suffix(&args.out, "_gait.png");
    feet_figure(&r, &feet_png, &args.clip).map_err(|e| e.to_string())?;
    // Two cycles of the reference's footfalls, in the legend order of every walk's gait.png.
    let n = contacts.len();
    let time: Vec<f64> = (0..=2 * n).map(|k| k as f64 * r.motion.frame_s).collect();
    let stance: Vec<[bool; 4]> = (0..2 * n).map(|k| contacts[k % n].0).collect();
    gait_diagram(
        &gait_png,
        &format!(
            "Reference footfalls of {clip} ({gait}), two cycles",
            clip = args.clip
        ),
        &time,
        &stance,
        Leg::ALL.map(|l| l.short_name()),
    )
    .map_err(|e| e.to_string())?;
    frames_figure(&r, &robot, &frames_png, &args.clip).map_err(|e| e.to_string())?;
    println!(
        "{}: frames {start}..{end} → {} ({} frames, cycle {:.3} s, {:.3} m/s, gait {gait}, largest IK residual {:.2} mm)",
        path.display(),
        args.out.display(),
        r.motion.frames.len(),
        r.motion.cycle_s(),
        r.motion.speed_mps(),
        r.max_residual_m * 1e3
    );
    println!(
        "figures: {}, {} and {}",
        feet_png.display(),
        frames_png.display(),
        gait_png.display()
    );
    Ok(())
}

fn with_suffix(p: &Path, suffix: &str) -> PathBuf {
    let stem = p
        .file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_default();
    p.with_file_name(format!("{stem}{suffix}"))
}

fn feet_figure(r: &Retargeted, png: &Path, clip: &str) -> Result<(), crate::plots::PlotError> {
    let t: Vec<f64> = (0..r.motion.frames.len())
        .map(|k| k as f64 * r.motion.frame_s)
        .collect();
    let mut panels = Vec::new();
    for (axis, name) in [(0usize, "fore-aft, relative to the root"), (2, "height")] {
        for leg in Leg::ALL {
            let root = |k: usize| {
                if axis == 0 {
                    r.motion.frames[k].p_root_world.x
                } else {
                    0.0
                }
            };
            panels.push(Panel {
                title: format!("{} foot {name}", leg.short_name()),
                x_label: "time [s]".into(),
                y_label: if axis == 0 {
                    "x − x_root [m]".into()
                } else {
                    "z [m]".into()
                },
                series: vec![
                    Series {
                        label: "dog toe (scaled)".into(),
                        x: t.clone(),
                        y: (0..t.len())
                            .map(|k| r.toe_targets[k][leg][axis] - root(k))
                            .collect(),
                    },
                    Series {
                        label: "A1 foot".into(),
                        x: t.clone(),
                        y: (0..t.len())
                            .map(|k| r.motion.frames[k].p_foot_world[leg][axis] - root(k))
                            .collect(),
                    },
                ],
                markers: vec![],
                bands: vec![],
            });
        }
    }
    line_panels(
        png,
        &format!("Retargeted {clip}: A1 feet against the dog's toes"),
        &panels,
    )
}

/// Marker chains of the dog skeleton drawn as sticks (spine and head, four legs, tail).
const DOG_CHAINS: [&[usize]; 6] = [
    &[0, 1, 2, 3, 4, 5],
    &[3, 6, 7, 8, 9, 10],
    &[3, 11, 12, 13, 14, 15],
    &[0, 16, 17, 18, 19],
    &[0, 20, 21, 22, 23],
    &[0, 24, 25, 26],
];

fn frames_figure(
    r: &Retargeted,
    robot: &RobotConfig,
    png: &Path,
    clip: &str,
) -> Result<(), crate::plots::PlotError> {
    let kin = LegKinematics::new(robot);
    let n = r.motion.frames.len();
    let picks: Vec<usize> = (0..8).map(|i| i * (n - 1) / 7).collect();
    let frames: Vec<StickFrame> = picks
        .iter()
        .map(|&k| {
            let f = &r.motion.frames[k];
            let xz = |p: nalgebra::Vector3<f64>| (p.x, p.z);
            let dog = DOG_CHAINS
                .iter()
                .map(|c| c.iter().map(|&m| xz(r.dog_markers[k][m])).collect())
                .collect();
            let mut a1 = Vec::new();
            let w = |p: nalgebra::Vector3<f64>| f.p_root_world + f.r_world_root * p;
            a1.push(vec![
                xz(w(kin.hip_position_body(Leg::FrontLeft))),
                xz(w(kin.hip_position_body(Leg::RearLeft))),
            ]);
            for leg in Leg::ALL {
                let lf = kin.link_frames(leg, &f.q[leg]);
                a1.push(vec![
                    xz(w(lf.hip.0)),
                    xz(w(lf.thigh.0)),
                    xz(w(lf.calf.0)),
                    xz(f.p_foot_world[leg]),
                ]);
            }
            StickFrame {
                title: format!("frame {k} (t = {:.3} s)", k as f64 * r.motion.frame_s),
                a: dog,
                b: a1,
            }
        })
        .collect();
    stick_figures(
        png,
        &format!("Retargeted {clip}: side view, dog markers and A1 links"),
        ("x [m]", "z [m]"),
        ("dog (scaled markers)", "A1"),
        &frames,
    )
}
