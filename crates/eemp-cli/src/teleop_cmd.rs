//! `eemp teleop`: a walk in the simulation driven by an operator — a gamepad (Linux joystick
//! device), the keyboard, or a command script — through the same shaping (deadzone, limits,
//! slew rate) as on the robot. Real time unless `--headless`. The walk is the one run
//! description of `eemp walk` ([`WalkDescription`]: EEMP on a gait's table by default, any
//! controller, floor or scenario with `--run FILE`), the operator in place of its command.
//! Writes the paper's Fig. 10 analogue: commanded against estimated velocity, and the foot
//! heights.

use crate::plots::{line_panels, Panel, Series};
use eemp_core::planner::VelocityCommand;
use eemp_core::teleop::{
    key_step, CommandShaper, JsEvent, OperatorInput, PadMapping, PadState, TeleopConfig,
};
use eemp_rl::run::{Driver, Sensing, WalkDescription};
use eemp_sim::walk::VelocityProfile;
use std::io::Read;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct TeleopArgs {
    /// A command script: `[[segment]]` tables with start_s, vx_mps, vy_mps, yaw_rate_rps (the
    /// wish; the shaper's slew limits apply as to a stick).
    #[arg(long, conflicts_with_all = ["joystick", "keyboard"])]
    pub commands: Option<PathBuf>,
    /// A gamepad through the Linux joystick interface (e.g. /dev/input/js0): left stick
    /// forward/sideways, right stick turn, button 1 (B) stops.
    #[arg(long, conflicts_with = "keyboard")]
    pub joystick: Option<PathBuf>,
    /// The keyboard of this terminal: w/s forward, a/d sideways, q/e turn, space zero, x stop.
    #[arg(long)]
    pub keyboard: bool,
    /// Run as fast as the computer allows instead of in real time (scripts, tests).
    #[arg(long)]
    pub headless: bool,
    /// trot, walk or free, with its per-speed table (tables/<robot>_<gait>.toml).
    #[arg(long, default_value = "trot")]
    pub gait: String,
    /// eemp, or a learned controller (model-free, imitation, eemp-rl) with --policy.
    #[arg(long, default_value = "eemp")]
    pub controller: String,
    /// The policy file of a learned --controller.
    #[arg(long)]
    pub policy: Option<PathBuf>,
    /// The walk to drive, as `eemp walk --run` takes it (controller, gait, parameters, floor,
    /// scenario, sensing, robot; `eemp_rl::run::WalkDescription`), in place of the options
    /// here. The operator replaces its command (speed, lateral, yaw rate, profile) and
    /// --duration its duration.
    #[arg(long, value_name = "FILE", conflicts_with_all = RUN_FILE_REPLACES)]
    pub run: Option<PathBuf>,
    /// Simulated seconds (default: a script's last segment + 3 s, else 60 s).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Shaping limits (TOML, `eemp_core::teleop::TeleopConfig`).
    #[arg(long)]
    pub teleop_config: Option<PathBuf>,
    /// What the controller sees (default here: the Kalman filter, as on the robot).
    #[arg(long, default_value = "kf")]
    pub estimator: String,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    #[command(flatten)]
    pub robot: crate::robot_arg::RobotArgs,
    #[command(flatten)]
    pub rerun: crate::rerun_arg::RerunArgs,
    /// Output folder (summary.json, trace.csv, teleop.png).
    #[arg(long)]
    pub out: PathBuf,
}

/// The options `--run FILE` stands in for.
const RUN_FILE_REPLACES: [&str; 7] = [
    "gait",
    "controller",
    "policy",
    "estimator",
    "seed",
    "robot",
    "allow_robot_mismatch",
];

/// The walk the operator drives: `--run FILE`, or the options here (the Kalman filter by
/// default, as on the robot). Its command is the operator's: the run starts from rest, as for
/// a command of 0.
fn description(args: &TeleopArgs, duration_s: f64) -> Result<WalkDescription, String> {
    let mut d = match &args.run {
        Some(p) => {
            let d: WalkDescription =
                eemp_core::config_error::load_toml(p).map_err(|e| e.to_string())?;
            let defaults = WalkDescription::default();
            let replaced: Vec<&str> = [
                ("speed_mps", d.speed_mps != defaults.speed_mps),
                ("lateral_mps", d.lateral_mps != defaults.lateral_mps),
                ("yaw_rate_rps", d.yaw_rate_rps != defaults.yaw_rate_rps),
                ("profile", d.profile.is_some()),
                ("duration_s", d.duration_s != defaults.duration_s),
            ]
            .into_iter()
            .filter_map(|(key, set)| set.then_some(key))
            .collect();
            if !replaced.is_empty() {
                eprintln!(
                    "teleop: {} of {} replaced by the operator's commands and the session's \
                     duration ({duration_s} s)",
                    replaced.join(", "),
                    p.display()
                );
            }
            d
        }
        None => WalkDescription {
            robot: args.robot.robot.clone(),
            allow_robot_mismatch: args.robot.allow_robot_mismatch,
            controller: args.controller.clone(),
            policy: args.policy.clone(),
            gait: args.gait.clone(),
            sensing: Sensing {
                estimator: args.estimator.clone(),
                seed: args.seed,
                ..Default::default()
            },
            ..Default::default()
        },
    };
    d.speed_mps = 0.0;
    d.lateral_mps = 0.0;
    d.yaw_rate_rps = 0.0;
    d.profile = None;
    d.duration_s = duration_s;
    Ok(d)
}

/// Where the wish comes from.
enum Source {
    Script(VelocityProfile),
    /// Filled by a device thread (joystick, keyboard).
    Shared(Arc<Mutex<(VelocityCommand, bool)>>),
}

impl OperatorInput for Source {
    fn wish(&mut self, t_s: f64) -> (VelocityCommand, bool) {
        match self {
            Source::Script(p) => (p.command_at(t_s), false),
            Source::Shared(s) => *s.lock().expect("not poisoned"),
        }
    }
}

/// A plain file or another device (/dev/null) would read as no input at all, silently: a Linux
/// joystick is a character device of the input subsystem (major number 13).
fn check_joystick_device(path: &std::path::Path) -> Result<(), String> {
    #[cfg(target_os = "linux")]
    {
        use std::os::unix::fs::{FileTypeExt, MetadataExt};
        let meta = std::fs::metadata(path)
            .map_err(|e| format!("cannot open joystick {}: {e}", path.display()))?;
        let major = (meta.rdev() >> 8) & 0xfff;
        if !meta.file_type().is_char_device() || major != 13 {
            return Err(format!(
                "--joystick {} is not a joystick device (a Linux joystick is /dev/input/jsN)",
                path.display()
            ));
        }
    }
    Ok(())
}

fn spawn_joystick(path: &PathBuf, cfg: TeleopConfig) -> Result<Source, String> {
    let mut dev = std::fs::File::open(path)
        .map_err(|e| format!("cannot open joystick {}: {e}", path.display()))?;
    let shared = Arc::new(Mutex::new((VelocityCommand::default(), false)));
    let s = shared.clone();
    std::thread::spawn(move || {
        let (mut pad, map) = (PadState::default(), PadMapping::default());
        let mut b = [0u8; 8];
        while dev.read_exact(&mut b).is_ok() {
            pad.apply(&JsEvent::parse(&b), &map);
            let mut g = s.lock().expect("not poisoned");
            *g = (pad.sticks.desired(&cfg), pad.stop);
        }
        s.lock().expect("not poisoned").1 = true; // unplugged: stop
    });
    Ok(Source::Shared(shared))
}

fn spawn_keyboard() -> Result<Source, String> {
    use crossterm::event::{read, Event, KeyCode, KeyEventKind};
    crossterm::terminal::enable_raw_mode().map_err(|e| format!("keyboard: {e}"))?;
    let shared = Arc::new(Mutex::new((VelocityCommand::default(), false)));
    let s = shared.clone();
    std::thread::spawn(move || loop {
        let Ok(Event::Key(k)) = read() else { continue };
        if k.kind != KeyEventKind::Press {
            continue;
        }
        let mut g = s.lock().expect("not poisoned");
        match k.code {
            KeyCode::Char('x') | KeyCode::Esc => {
                g.1 = true;
                break;
            }
            KeyCode::Char(c) => key_step(&mut g.0, c),
            _ => {}
        }
    });
    eprintln!("keyboard: w/s forward, a/d sideways, q/e turn, space zero, x stop\r");
    Ok(Source::Shared(shared))
}

pub fn run(args: &TeleopArgs) -> Result<(), String> {
    let cfg: TeleopConfig = match &args.teleop_config {
        Some(p) => eemp_core::config_error::load_toml(p).map_err(|e| e.to_string())?,
        None => TeleopConfig::default(),
    };
    let mut shaper = CommandShaper::new(cfg.clone()).map_err(|e| e.to_string())?;
    let script = match &args.commands {
        Some(p) => {
            let prof: VelocityProfile =
                eemp_core::config_error::load_toml(p).map_err(|e| e.to_string())?;
            prof.validate()
                .map_err(|e| format!("{}: {e}", p.display()))?;
            Some(prof)
        }
        None => None,
    };
    let duration = match (args.duration, &script) {
        (Some(d), _) => d,
        (None, Some(p)) => p.segments.last().map(|s| s.start_s).unwrap_or(0.0) + 3.0,
        (None, None) => 60.0,
    };
    if !(duration.is_finite() && duration > 0.0 && duration <= 3600.0) {
        return Err(format!(
            "--duration {duration} is out of range: allowed (0, 3600] s"
        ));
    }
    if script.is_none() && args.joystick.is_none() && !args.keyboard {
        return Err(
            "say where commands come from: --commands FILE, --joystick DEV or --keyboard".into(),
        );
    }
    if let Some(dev) = &args.joystick {
        check_joystick_device(dev)?;
    }
    let mut built = description(args, duration)?.build()?;
    // The whole session is measured: there is no speed-up to leave out.
    built.spec.metrics_start_s = 0.0;
    let method = built.method();
    let gait = matches!(built.driver, Driver::Eemp).then(|| built.gait.to_string());
    let (robot, spec) = (built.robot.clone(), built.spec.clone());
    let mut source = match (&script, &args.joystick) {
        (Some(p), _) => Source::Script(p.clone()),
        (None, Some(dev)) => spawn_joystick(dev, cfg.clone())?,
        (None, None) => spawn_keyboard()?,
    };
    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("cannot create {}: {e}", args.out.display()))?;
    let dt = robot.simulation.timestep_s;
    let wall0 = Instant::now();
    let realtime = !args.headless;
    let mut stopped_at: Option<f64> = None;
    let mut command_at = |t: f64| {
        let (wish, stop) = source.wish(t);
        if stop && stopped_at.is_none() {
            stopped_at = Some(t);
        }
        if realtime {
            let ahead = t - wall0.elapsed().as_secs_f64();
            if ahead > 0.0 {
                std::thread::sleep(std::time::Duration::from_secs_f64(ahead));
            }
        }
        // After a stop the robot is brought to rest (the walk goes on standing).
        let wish = if stopped_at.is_some() {
            VelocityCommand::default()
        } else {
            wish
        };
        shaper.step(wish, dt)
    };
    struct Row {
        t: f64,
        cmd: [f64; 3],
        est: [f64; 3],
        truth: [f64; 3],
        feet_z: [f64; 4],
    }
    let mut rows: Vec<Row> = Vec::new();
    let kin = eemp_core::kinematics::LegKinematics::new(&robot);
    let mut recorder = args
        .rerun
        .open(&format!("teleop: {method}"), &robot, &spec)?;
    let run = built.run_commanded(&mut command_at, |r| {
        recorder.observe(r);
        let k = (r.state.time_s / dt).round() as usize;
        if !k.is_multiple_of(10) {
            return;
        }
        let heading = |b: &eemp_core::body_state::BodyState| {
            let v = b.v_heading();
            [v.x, v.y, b.omega_world.z]
        };
        let feet = eemp_core::locomotion::feet_world(&kin, r.state);
        rows.push(Row {
            t: r.state.time_s,
            cmd: [r.command.vx_mps, r.command.vy_mps, r.command.yaw_rate_rps],
            est: heading(&r.estimate.body),
            truth: heading(&r.state.body),
            feet_z: [0, 1, 2, 3].map(|i| feet.0[i].z - robot.leg.foot_radius_m),
        });
    })?;
    if let Some(summary) = recorder.finish() {
        eprintln!("rerun: {summary}\r");
    }
    if args.keyboard {
        let _ = crossterm::terminal::disable_raw_mode();
    }
    let mut csv = String::from(
        "time_s,cmd_vx_mps,cmd_vy_mps,cmd_yaw_rate_rps,est_vx_mps,est_vy_mps,est_yaw_rate_rps,\
         vx_mps,vy_mps,yaw_rate_rps,FR_sole_z_m,FL_sole_z_m,RR_sole_z_m,RL_sole_z_m\n",
    );
    for r in &rows {
        let v: Vec<String> = std::iter::once(r.t)
            .chain(r.cmd)
            .chain(r.est)
            .chain(r.truth)
            .chain(r.feet_z)
            .map(|x| format!("{x:.4}"))
            .collect();
        csv.push_str(&v.join(","));
        csv.push('\n');
    }
    std::fs::write(args.out.join("trace.csv"), csv).map_err(|e| e.to_string())?;
    let t: Vec<f64> = rows.iter().map(|r| r.t).collect();
    let series = |label: &str, f: &dyn Fn(&Row) -> f64| Series {
        label: label.into(),
        x: t.clone(),
        y: rows.iter().map(f).collect(),
    };
    let mut panels = Vec::new();
    for (i, (name, unit)) in [
        ("forward velocity", "m/s"),
        ("lateral velocity", "m/s"),
        ("yaw rate", "rad/s"),
    ]
    .iter()
    .enumerate()
    {
        panels.push(Panel {
            title: format!("{name}: commanded and estimated (heading frame)"),
            x_label: "time [s]".into(),
            y_label: format!("{name} [{unit}]"),
            series: vec![
                series("commanded (shaped)", &|r| r.cmd[i]),
                series("estimated (KF)", &|r| r.est[i]),
                series("true (simulator)", &|r| r.truth[i]),
            ],
            markers: vec![],
            bands: vec![],
        });
    }
    panels.push(Panel {
        title: "foot heights (sole above the floor)".into(),
        x_label: "time [s]".into(),
        y_label: "height [m]".into(),
        series: ["FR", "FL", "RR", "RL"]
            .iter()
            .enumerate()
            .map(|(i, n)| series(n, &|r| r.feet_z[i]))
            .collect(),
        markers: vec![],
        bands: vec![],
    });
    line_panels(
        &args.out.join("teleop.png"),
        &format!("Teleoperation, {method} (Fig. 10 analogue)"),
        &panels,
    )
    .map_err(|e| e.to_string())?;
    let rmse = |i: usize| {
        let e: Vec<f64> = rows
            .iter()
            .map(|r| (r.cmd[i] - r.truth[i]).powi(2))
            .collect();
        (e.iter().sum::<f64>() / e.len().max(1) as f64).sqrt()
    };
    let summary = serde_json::json!({
        "method": method,
        // EEMP's gait (a policy walks the gait it learned).
        "gait": gait,
        "run": args.run.as_ref().map(|p| p.display().to_string()),
        "source": if script.is_some() { "script" } else if args.joystick.is_some() { "joystick" } else { "keyboard" },
        "duration_s": duration,
        "fell": run.stats.fell,
        "fell_at_s": run.stats.fell_at_s,
        "stopped_at_s": stopped_at,
        "rmse_vx_mps": rmse(0),
        "rmse_vy_mps": rmse(1),
        "rmse_yaw_rate_rps": rmse(2),
        "estimation_vel_rmse_mps": run.estimation.vel_rmse_mps(),
        "distance_m": run.metrics.distance_m,
        "teleop": cfg,
    });
    std::fs::write(
        args.out.join("summary.json"),
        serde_json::to_string_pretty(&summary).expect("serialises"),
    )
    .map_err(|e| e.to_string())?;
    println!("{}", serde_json::to_string(&summary).expect("serialises"));
    if !args.headless && !args.rerun.wanted() {
        eprintln!(
            "note: the figure is {}; to watch a session live, give --rerun-serve PORT or \
             --rerun-connect ADDR (docs/viewer.md)",
            args.out.join("teleop.png").display()
        );
    }
    Ok(())
}
