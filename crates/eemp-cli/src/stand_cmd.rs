//! `eemp stand`: rise, follow a body-motion profile on four legs, report tracking.

use crate::output::{create_dir, write_json, Trace};
use crate::plots::{line_panels, Panel, Series};
use eemp_core::config_error::load_toml;
use eemp_core::locomotion::ControllerConfig;
use eemp_core::stand_profile::BodyMotionProfile;
use eemp_sim::closed_loop::{percentile, Push};
use eemp_sim::stand::run_stand_on;
use nalgebra::Vector3;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
// `--duration -1` must reach the range check rather than be taken for an option.
#[command(allow_negative_numbers = true)]
pub struct StandArgs {
    /// Simulated seconds to run.
    #[arg(long, default_value_t = 20.0)]
    pub duration: f64,
    /// Body-motion profile (TOML: height_m, rise_s, [[segments]] axis/amplitude/period_s/cycles);
    /// default: ±3 cm x/y/z and ±0.15 rad roll/pitch/yaw, one at a time.
    #[arg(long)]
    pub profile: Option<PathBuf>,
    #[command(flatten)]
    pub push: crate::push_arg::PushArgs,
    /// Rows per second in trace.csv (the simulation runs at 1000 Hz; writing every step costs
    /// about a quarter of the run time).
    #[arg(long, default_value_t = 100.0)]
    pub trace_hz: f64,
    #[command(flatten)]
    pub sensing: crate::state_source_arg::StateSourceArgs,
    /// A controller setting, KEY=VALUE (repeatable), as `eemp walk --set` takes it: `mpc.*`,
    /// `swing.*`, `slip.*`, `schedule.*`, and `filter.*` with `--estimator kf` (standing has no
    /// planner).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Robot description: robots/a1.toml (the default, compiled in), robots/go2.toml,
    /// robots/go1.toml, or your own file.
    #[arg(long)]
    pub robot: Option<PathBuf>,
    #[command(flatten)]
    pub rerun: crate::rerun_arg::RerunArgs,
    /// Output folder.
    #[arg(long, default_value = "out/stand")]
    pub out: PathBuf,
}

pub fn run(args: &StandArgs) -> Result<(), String> {
    // Validate everything before writing anything.
    if !(args.duration.is_finite() && args.duration > 0.0 && args.duration <= 3600.0) {
        return Err(format!(
            "--duration {} is out of range: allowed (0, 3600] s",
            args.duration
        ));
    }
    let robot = crate::robot_arg::load_robot(args.robot.as_deref())?;
    let scale = robot.settings_scale();
    let profile: BodyMotionProfile = match (&args.profile, &scale) {
        (Some(p), _) => load_toml(p).map_err(|e| e.to_string())?,
        (None, Some(s)) => BodyMotionProfile::default().scaled(s),
        (None, None) => BodyMotionProfile::default(),
    };
    robot
        .check_body_height("profile.height_m", profile.height_m)
        .map_err(|e| e.to_string())?;
    profile.validate().map_err(|e| e.to_string())?;
    let mut pushes = Vec::new();
    if let Some(at) = args.push.push_at {
        if !(at.is_finite() && at >= 0.0 && at < args.duration) {
            return Err(format!(
                "--push-at {at} is out of range: allowed [0, duration {})",
                args.duration
            ));
        }
        if !(args.push.push_dv.is_finite() && args.push.push_dv.abs() <= 3.0) {
            return Err(format!(
                "--push-dv {} is out of range: allowed [-3, 3] m/s",
                args.push.push_dv
            ));
        }
        pushes.push(Push::step(at, Vector3::new(0.0, args.push.push_dv, 0.0)));
    }
    if !(args.trace_hz.is_finite() && args.trace_hz > 0.0 && args.trace_hz <= 1000.0) {
        return Err(format!(
            "--trace-hz {} is out of range: allowed (0, 1000]",
            args.trace_hz
        ));
    }
    let trace_every = (1000.0 / args.trace_hz).round().max(1.0) as usize;
    // The walk's controller defaults (MPC every 20 ms); `--set schedule.mpc_period_s=…`.
    let controller = ControllerConfig::default();
    let mut source = args.sensing.source(&robot)?;
    if let Some(s) = args
        .set
        .iter()
        .find(|s| eemp_core::settings::key_of(s).starts_with("planner."))
    {
        return Err(format!(
            "--set {s}: standing has no planner (planner.* is for eemp walk)"
        ));
    }
    let mut settings = eemp_core::settings::ControllerSettings {
        planner: Default::default(),
        controller,
        filter: source.kf_config().cloned(),
    };
    if let Some(s) = &scale {
        settings = settings.scaled(s)?;
    }
    let settings = settings.with_sets(&args.set)?;
    let controller = settings.controller;
    if let (Some(kf), Some(mine)) = (settings.filter, source.kf_config_mut()) {
        *mine = kf;
    }
    create_dir(&args.out).map_err(|e| e.to_string())?;
    let header: Vec<String> = [
        "time_s",
        "x_m",
        "y_m",
        "z_m",
        "roll_rad",
        "pitch_rad",
        "yaw_rad",
        "x_ref_m",
        "y_ref_m",
        "z_ref_m",
        "roll_ref_rad",
        "pitch_ref_rad",
        "yaw_ref_rad",
    ]
    .iter()
    .map(|s| s.to_string())
    .chain(
        eemp_core::Leg::ALL
            .iter()
            .flat_map(|l| (0..3).map(move |j| format!("tau_{}_{j}_nm", l.short_name()))),
    )
    .collect();
    let mut trace =
        Trace::create(&args.out.join("trace.csv"), &header).map_err(|e| e.to_string())?;
    let mut series: Vec<Vec<f64>> = vec![Vec::new(); 13];
    let (mut sq_pos, mut sq_rpy, mut n) = (0.0, 0.0, 0usize);
    let mut write_error = None;
    let mut step = 0usize;
    let rise_s = profile.rise_s;
    let mut recorder = args.rerun.open_world(crate::rerun_arg::World {
        name: "stand: body motion on four feet",
        robot: robot.clone(),
        scene: Default::default(),
        pushes: pushes.clone(),
        estimated: !matches!(source, eemp_sim::closed_loop::StateSource::GroundTruth),
        step_s: robot.simulation.timestep_s,
    })?;
    let run = run_stand_on(
        &robot,
        controller,
        profile,
        args.duration,
        &pushes,
        &source,
        |r| {
            recorder.observe(r);
            let s = &r.state.body;
            let rpy = s.rpy();
            let rf = &r.plan.expect("the stand controller always plans").body_now;
            let mut row = vec![
                r.state.time_s,
                s.p_world.x,
                s.p_world.y,
                s.p_world.z,
                rpy.x,
                rpy.y,
                rpy.z,
                rf.p_world.x,
                rf.p_world.y,
                rf.p_world.z,
                rf.rpy.x,
                rf.rpy.y,
                rf.rpy.z,
            ];
            for (i, v) in row.iter().enumerate() {
                series[i].push(*v);
            }
            row.extend(r.output.torques.0.iter().flat_map(|t| t.iter().copied()));
            if step.is_multiple_of(trace_every) {
                if let Err(e) = trace.row(&row) {
                    write_error.get_or_insert(e);
                }
            }
            step += 1;
            // Tracking is scored once the rise is over (plus 0.5 s to settle).
            if r.state.time_s >= rise_s + 0.5 {
                sq_pos += (s.p_world - rf.p_world).norm_squared();
                let mut e = rpy - rf.rpy;
                e.z = (e.z + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI)
                    - std::f64::consts::PI;
                sq_rpy += e.norm_squared();
                n += 1;
            }
        },
    )
    .map_err(|e| e.to_string())?;
    if let Some(summary) = recorder.finish() {
        eprintln!("rerun: {summary}");
    }
    if let Some(e) = write_error {
        return Err(e.to_string());
    }
    trace.finish().map_err(|e| e.to_string())?;
    let stats = &run.stats;
    let rmse = |sq: f64| {
        if n > 0 {
            (sq / n as f64).sqrt()
        } else {
            f64::NAN
        }
    };
    let summary = serde_json::json!({
        "duration_s": stats.sim_time_s,
        "fell": stats.fell,
        "fell_at_s": stats.fell_at_s,
        "tracking_rmse_pos_m": rmse(sq_pos),
        "tracking_rmse_rpy_rad": rmse(sq_rpy),
        "tracking_window_start_s": rise_s + 0.5,
        "mpc_solves": stats.mpc_solves,
        "mpc_failures": stats.mpc_failures,
        "mpc_solve_us_median": stats.mpc_solve_median_us(),
        "mpc_solve_us_p99": percentile(&stats.mpc_solve_times_s, 0.99) * 1e6,
        "realtime_factor": stats.realtime_factor(),
        "pushes": pushes.iter().map(|p| serde_json::json!({"at_s": p.at_s, "dv_world_mps": [p.dv_world.x, p.dv_world.y, p.dv_world.z]})).collect::<Vec<_>>(),
        "state_estimate": source.name(),
        "estimation_vel_rmse_mps": run.estimation.vel_rmse_mps(),
        "estimation_pos_rmse_m": run.estimation.pos_rmse_m(),
    });
    write_json(&args.out.join("summary.json"), &summary).map_err(|e| e.to_string())?;
    let t = series[0].clone();
    let panel = |title: &str, unit: &str, i: usize| Panel {
        title: title.to_string(),
        x_label: "time [s]".into(),
        y_label: unit.to_string(),
        series: vec![
            Series {
                label: "actual".into(),
                x: t.clone(),
                y: series[i].clone(),
            },
            Series {
                label: "reference".into(),
                x: t.clone(),
                y: series[i + 6].clone(),
            },
        ],
        markers: pushes
            .iter()
            .map(|p| (p.at_s, "push".to_string()))
            .collect(),
        bands: vec![],
    };
    let panels = vec![
        panel("trunk x", "x [m]", 1),
        panel("trunk y", "y [m]", 2),
        panel("trunk z", "z [m]", 3),
        panel("roll", "roll [rad]", 4),
        panel("pitch", "pitch [rad]", 5),
        panel("yaw", "yaw [rad]", 6),
    ];
    line_panels(
        &args.out.join("body_pose.png"),
        "A1 standing: reference vs actual trunk pose",
        &panels,
    )
    .map_err(|e| e.to_string())?;
    println!(
        "{}",
        serde_json::to_string_pretty(&summary).expect("serialises")
    );
    println!(
        "wrote {}/summary.json, trace.csv, body_pose.png",
        args.out.display()
    );
    Ok(())
}
