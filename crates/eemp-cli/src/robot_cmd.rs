//! `eemp robot check ROBOT [--out DIR]`: what the project reads from a robot's model, its leg
//! kinematics against MuJoCo's own, a stand and a trot, and first per-speed tables; or a refusal
//! naming what is missing (exit 2, nothing written).

use crate::output::create_dir;
use eemp_core::gait::Gait;
use eemp_core::kinematics::LegKinematics;
use eemp_core::leg::{Leg, LegMap};
use eemp_core::planner::params_table::ParamsTable;
use eemp_core::robot::RobotConfig;
use eemp_sim::mjcf::SceneExtras;
use eemp_sim::Simulation;
use nalgebra::{UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use std::fmt::Write;
use std::path::{Path, PathBuf};

#[derive(clap::Subcommand, Debug)]
pub enum RobotCommand {
    /// Read a robot (a binding of its own MuJoCo model, or a typed robot file), say what was
    /// found, check the leg kinematics against MuJoCo's, stand and trot it, and write first
    /// per-speed tables (the A1's scaled to it) and a report.
    Check(RobotCheckArgs),
}

#[derive(clap::Args, Debug)]
pub struct RobotCheckArgs {
    /// The robot file (`robots/<name>.toml`).
    pub robot: PathBuf,
    /// Output folder: report.md, stand/, trot/, tables/.
    #[arg(long, default_value = "out/robot-check")]
    pub out: PathBuf,
    /// Simulated seconds of the stand and of the trot.
    #[arg(long, default_value_t = 10.0)]
    pub duration: f64,
}

pub fn run(cmd: &RobotCommand) -> Result<(), String> {
    match cmd {
        RobotCommand::Check(args) => check(args),
    }
}

/// The largest foot-position (m) and Jacobian-entry errors of the project's kinematics against
/// MuJoCo's foot sites, over random poses within the joint ranges.
pub fn kinematics_error(robot: &RobotConfig, poses: usize) -> Result<(f64, f64), String> {
    let kin = LegKinematics::new(robot);
    let mut sim = Simulation::new(robot, &SceneExtras::default()).map_err(|e| e.to_string())?;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let mut worst = (0.0f64, 0.0f64);
    for _ in 0..poses {
        let q = LegMap::from_fn(|leg| {
            Vector3::from_fn(|j, _| {
                let [lo, hi] = robot.joint_range_rad(leg, j);
                rng.random_range(lo.max(-3.0)..hi.min(3.0))
            })
        });
        let p = Vector3::new(0.0, 0.0, 2.0);
        let r = UnitQuaternion::from_euler_angles(
            rng.random_range(-0.5..0.5),
            rng.random_range(-0.5..0.5),
            rng.random_range(-3.0..3.0),
        );
        sim.reset(p, &q);
        let c = r.coords;
        sim.data_mut().qpos_mut()[3..7].copy_from_slice(&[c.w, c.x, c.y, c.z]);
        sim.data_mut().forward();
        let feet = sim.foot_positions_world();
        for leg in Leg::ALL {
            let core = p + r * kin.foot_position_body(leg, &q[leg]);
            worst.0 = worst.0.max((core - feet[leg]).norm());
            let jac = r.to_rotation_matrix().matrix() * kin.foot_jacobian_body(leg, &q[leg]);
            worst.1 = worst
                .1
                .max((jac - sim.foot_jacobian_world(leg)).abs().max());
        }
    }
    Ok(worst)
}

/// Runs this very program with `args`; its summary.json as JSON.
fn run_self(args: &[String], summary: &Path) -> Result<serde_json::Value, String> {
    let exe = std::env::current_exe().map_err(|e| e.to_string())?;
    let out = std::process::Command::new(exe)
        .args(args)
        .output()
        .map_err(|e| e.to_string())?;
    if !out.status.success() {
        return Err(format!(
            "eemp {} failed: {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr)
        ));
    }
    let text = std::fs::read_to_string(summary).map_err(|e| e.to_string())?;
    serde_json::from_str(&text).map_err(|e| e.to_string())
}

fn check(args: &RobotCheckArgs) -> Result<(), String> {
    if !(args.duration.is_finite() && args.duration >= 1.0 && args.duration <= 600.0) {
        return Err(format!(
            "--duration {} is out of range: allowed [1, 600] s",
            args.duration
        ));
    }
    // Everything that can refuse the robot runs before anything is written.
    let robot = eemp_sim::robot_model::load_robot(&args.robot).map_err(|e| e.to_string())?;
    let (pos_err, jac_err) = kinematics_error(&robot, 200)?;
    let scale = robot.scale();
    let kin = LegKinematics::new(&robot);
    let standing = robot.standing_pose();
    let height = Leg::ALL
        .iter()
        .map(|&l| -kin.foot_position_body(l, &standing[l]).z)
        .fold(f64::NEG_INFINITY, f64::max)
        + robot.leg.foot_radius_m;
    let mut tables = Vec::new();
    for gait in [Gait::Trot, Gait::Free, Gait::Walk] {
        let a1 = RobotConfig::a1().shipped_table_path(gait);
        if let Ok(t) = ParamsTable::load(&a1) {
            tables.push((gait, a1, t.scaled(&scale, robot.id())));
        }
    }
    create_dir(&args.out).map_err(|e| e.to_string())?;
    let tables_dir = args.out.join("tables");
    create_dir(&tables_dir).map_err(|e| e.to_string())?;
    let mut written = Vec::new();
    for (gait, from, t) in &tables {
        let path = tables_dir.join(format!("{}_{gait}.toml", robot.name));
        let text = format!(
            "# A first table for {name}: {from} carried over by equal Froude number (speeds × √λ, \
             lengths × λ,\n# swing times × √λ; λ = {l:.4}), written by `eemp robot check`. Not \
             selected on this robot:\n# a sweep (`eemp sweep`) does that.\n{}",
            t.to_toml(),
            name = robot.name,
            from = from.display(),
            l = scale.length,
        );
        std::fs::write(&path, text).map_err(|e| format!("{}: {e}", path.display()))?;
        written.push(path);
    }
    let robot_arg = args.robot.display().to_string();
    let duration = format!("{}", args.duration);
    let stand_dir = args.out.join("stand");
    let stand = run_self(
        &[
            "stand".into(),
            "--robot".into(),
            robot_arg.clone(),
            "--duration".into(),
            duration.clone(),
            "--out".into(),
            stand_dir.display().to_string(),
        ],
        &stand_dir.join("summary.json"),
    )?;
    let speed = (0.3 * scale.length.sqrt() * 1000.0).round() / 1000.0;
    let trot_dir = args.out.join("trot");
    let trot_table = tables_dir.join(format!("{}_trot.toml", robot.name));
    let mut trot_args: Vec<String> = vec![
        "walk".into(),
        "--robot".into(),
        robot_arg,
        "--gait".into(),
        "trot".into(),
        "--speed".into(),
        format!("{speed}"),
        "--duration".into(),
        duration,
        "--estimator".into(),
        "kf".into(),
        "--seed".into(),
        "1".into(),
        "--out".into(),
        trot_dir.display().to_string(),
    ];
    if trot_table.exists() {
        trot_args.extend(["--params-table".into(), trot_table.display().to_string()]);
    }
    let trot = run_self(&trot_args, &trot_dir.join("summary.json"))?;

    let mut r = String::new();
    let m = robot.model.as_ref();
    writeln!(r, "# Robot check: {}\n", robot.name).unwrap();
    match m {
        Some(m) => writeln!(
            r,
            "Read from its own MuJoCo model `{}`.\n",
            // Relative to the working directory where it lies below it (reports are committed).
            std::env::current_dir()
                .ok()
                .and_then(|d| m.source.strip_prefix(d).ok().map(Path::to_path_buf))
                .unwrap_or_else(|| m.source.clone())
                .display()
        ),
        None => writeln!(
            r,
            "Typed into its robot file (the model is generated from it).\n"
        ),
    }
    .unwrap();
    writeln!(r, "## What was found\n").unwrap();
    writeln!(r, "| quantity | value |\n|---|---|").unwrap();
    writeln!(r, "| total mass | {:.3} kg |", robot.total_mass_kg()).unwrap();
    writeln!(
        r,
        "| standing height (trunk origin, standing pose) | {height:.3} m |"
    )
    .unwrap();
    writeln!(r, "| leg length over the A1's, λ | {:.4} |", scale.length).unwrap();
    writeln!(r, "| mass over the A1's, μ | {:.4} |", scale.mass).unwrap();
    writeln!(
        r,
        "| torque limits (abduction, thigh, calf) | {:?} N·m |",
        robot.leg.torque_limit_nm
    )
    .unwrap();
    writeln!(r, "| foot radius | {} m |", robot.leg.foot_radius_m).unwrap();
    writeln!(
        r,
        "| settings | {} |",
        match robot.settings_scale() {
            Some(_) => "the A1's scaled by unit at equal Froude number",
            None => "as the files write them (not scaled)",
        }
    )
    .unwrap();
    writeln!(
        r,
        "\n| leg | abduction anchor (m, trunk frame) | axis signs | knee | thigh / shank (m) | ranges (rad) |\n|---|---|---|---|---|---|"
    )
    .unwrap();
    for leg in Leg::ALL {
        let g = robot.leg_geometry(leg);
        let a = g.abduction_anchor_m;
        let [l1, l2] = g.segment_lengths_m();
        writeln!(
            r,
            "| {} | ({:.4}, {:.4}, {:.4}) | {:?} | {} | {l1:.4} / {l2:.4} | {:?} |",
            leg.short_name(),
            a.x,
            a.y,
            a.z,
            g.axis_sign,
            if g.knee_branch < 0.0 {
                "behind the foot's line"
            } else {
                "ahead of the foot's line"
            },
            robot.joint_ranges_rad(leg)
        )
        .unwrap();
    }
    writeln!(r, "\n## Leg kinematics against MuJoCo's\n").unwrap();
    writeln!(
        r,
        "Over 200 random poses within the joint ranges: largest foot-position error {pos_err:.2e} m, \
         largest Jacobian-entry error {jac_err:.2e} m/rad."
    )
    .unwrap();
    // A number to three decimals, a flag as written, "–" where the run has none.
    let field = |v: &serde_json::Value, k: &str| match v.get(k) {
        Some(serde_json::Value::Number(n)) => match n.as_f64() {
            Some(x) if n.is_f64() => format!("{x:.3}"),
            _ => n.to_string(),
        },
        Some(serde_json::Value::Null) | None => "–".to_string(),
        Some(other) => other.to_string(),
    };
    writeln!(r, "\n## Stand and trot\n").unwrap();
    writeln!(
        r,
        "| run | fell | fell at (s) | velocity RMSE (m/s) | folder |\n|---|---|---|---|---|"
    )
    .unwrap();
    writeln!(
        r,
        "| stand {} s, the A1's profile scaled, ground truth | {} | {} | – | stand/ |",
        args.duration,
        field(&stand, "fell"),
        field(&stand, "fell_at_s")
    )
    .unwrap();
    writeln!(
        r,
        "| trot at {speed} m/s (the A1's 0.3 × √λ), {} s, Kalman filter, seed 1 | {} | {} | {} | trot/ |",
        args.duration,
        field(&trot, "fell"),
        field(&trot, "fell_at_s"),
        field(&trot, "vel_rmse_mps")
    )
    .unwrap();
    writeln!(r, "\n## Thresholds scaled to its size\n").unwrap();
    writeln!(
        r,
        "Measurement thresholds and input limits that follow the robot's size \
         (`eemp_core::robot_size`; the A1's value × the factor of its unit):\n"
    )
    .unwrap();
    writeln!(
        r,
        "| constant | the A1's | this robot's | unit | what |\n|---|---|---|---|---|"
    )
    .unwrap();
    let size = robot.scale();
    for c in eemp_core::robot_size::SIZED_CONSTANTS {
        writeln!(
            r,
            "| `{}` | {} | {:.4} | {} | {} |",
            c.name,
            c.a1_value,
            size.sized(&c),
            c.unit,
            c.about
        )
        .unwrap();
    }
    writeln!(r, "\n## First tables\n").unwrap();
    for p in &written {
        // Named from the report's folder: the report moves with it.
        let shown = p.strip_prefix(&args.out).unwrap_or(p);
        writeln!(r, "- `{}`", shown.display()).unwrap();
    }
    writeln!(
        r,
        "\nThe A1's tables carried over by equal Froude number; copy them to `tables/` to make \
         them the robot's defaults, or select its own with `eemp sweep`."
    )
    .unwrap();
    let report = args.out.join("report.md");
    std::fs::write(&report, &r).map_err(|e| format!("{}: {e}", report.display()))?;
    print!("{r}");
    eprintln!("wrote {}", report.display());
    Ok(())
}

/// The shipped robot files (`robots/*.toml`), for tests and listings.
pub fn shipped_robot_files(repo: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(repo.join("robots"))
        .map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    files.retain(|p| p.extension().is_some_and(|e| e == "toml"));
    files.sort();
    files
}
