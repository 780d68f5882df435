//! `eemp walk`: the A1 walking under EEMP, with its energy and robustness metrics.

use crate::output::{create_dir, write_json, Trace};
use crate::plots::{gait_diagram, line_panels, Panel, Series};
use eemp_core::config_error::load_toml;
use eemp_core::leg::Leg;
use eemp_core::metrics::positive_power_w;
use eemp_core::planner::{FreePairing, Gait, PlannerConfig, PlannerParams, VelocityCommand};
use eemp_sim::closed_loop::Push;
use eemp_sim::walk::{run_walk, run_walk_with, StartPose, VelocityProfile, WalkSpec};
use nalgebra::Vector3;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
// `--speed -0.3` is a backward command and `--duration -1` must reach the range check.
#[command(allow_negative_numbers = true)]
pub struct WalkArgs {
    /// Who drives the robot: eemp (planner + MPC + swing law) or model-free (a trained policy,
    /// --policy). Both run the same scenario, metrics and outputs.
    #[arg(long, default_value = "eemp")]
    pub controller: String,
    /// Policy file for a learned --controller (e.g. policies/a1_model_free.safetensors).
    #[arg(long)]
    pub policy: Option<PathBuf>,
    #[command(flatten)]
    pub sensing: crate::state_source_arg::StateSourceArgs,
    /// trot, walk or free (no predetermined order). EEMP only.
    #[arg(long, default_value = "trot")]
    pub gait: String,
    /// Forward speed command, m/s (heading frame). Ignored with --profile.
    #[arg(long, default_value_t = 0.3)]
    pub speed: f64,
    /// Lateral speed command, m/s.
    #[arg(long, default_value_t = 0.0)]
    pub lateral: f64,
    /// Yaw-rate command, rad/s.
    #[arg(long, default_value_t = 0.0)]
    pub yaw_rate: f64,
    /// Velocity profile (TOML `[[segment]]` tables: start_s, vx_mps, vy_mps, yaw_rate_rps) in place of --speed.
    #[arg(long)]
    pub profile: Option<PathBuf>,
    /// Simulated seconds.
    #[arg(long, default_value_t = 20.0)]
    pub duration: f64,
    /// Planner parameters (TOML: swing_time_s, step_height_m, body_height_m, ellipse_rx_m,
    /// ellipse_ry_m); default: the paper's Table II.
    #[arg(long)]
    pub params: Option<PathBuf>,
    /// EEMP-Analytical: a per-speed parameter table (tables/<robot>_<gait>.toml) used in place of --params.
    #[arg(long, conflicts_with = "params")]
    pub params_table: Option<PathBuf>,
    /// Factor on V·ΔT in eq. (6): 0.5 = the paper's eq. (6), 1.0 = its Algorithm 1.
    /// Default: the --params-table's own factor if it records one, else 0.5.
    #[arg(long)]
    pub progress_factor: Option<f64>,
    /// Re-evaluate eq. (6) during each swing with the velocity measured at that moment
    /// (`false`: touchdown fixed at lift-off).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub retarget_swing: bool,
    /// Take the first step when a speed is commanded, not when a foot leaves its ellipse.
    #[arg(long)]
    pub first_step_on_command: bool,
    /// Show the MPC the swings the planner will start within its horizon (`false`: only the
    /// running ones, as in the paper).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub preview_swings: bool,
    /// The body reference follows a change of the command at most this fast, m/s².
    #[arg(long, default_value_t = PlannerConfig::default().max_accel_mps2)]
    pub max_accel: f64,
    /// Scenario file (scenarios/*.toml): `[terrain.rough]` amplitude_m/wavelength_m/seed/size_m,
    /// `[terrain.ramp]` start_x_m/grade/rise_m/plateau_m, `[terrain.step]` at_x_m/height_m,
    /// `[[terrain.friction_patch]]` x0_m/x1_m/width_m/friction, floor_friction, `[[push]]`
    /// at_s/dv_mps/duration_s, `[push_schedule]` first_s/every_s/dv_mps/duration_s/jitter_s (duration 0: a velocity step, else a force pulse), payload_kg, `[model_error]`
    /// trunk_mass_scale/trunk_inertia_scale/motor_strength_scale, `[sensors]` (noise for
    /// --estimator kf). Applied on top of the other options.
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Floor friction coefficient (slippery ground below ~0.4); default: the robot file's.
    #[arg(long)]
    pub friction: Option<f64>,
    /// Apply a push at this time (s): a sudden lateral change of the trunk velocity.
    #[arg(long)]
    pub push_at: Option<f64>,
    /// Lateral velocity change of the push, m/s.
    #[arg(long, default_value_t = 0.3)]
    pub push_dv: f64,
    /// Friction coefficient the MPC assumes (its friction pyramid); keep it at or below the
    /// floor's. Default: `MpcConfig`'s 0.6.
    #[arg(long)]
    pub mpc_friction: Option<f64>,
    /// Free gait: take a leg's diagonal partner along when its eq. (5) value is above 1 − this
    /// (`FreePairing::pair_tolerance`, 0–1; default 0.5; 0: only when it is outside too).
    #[arg(long)]
    pub free_pair_tolerance: Option<f64>,
    /// Free gait: take the partner along when a lone swing would leave the trunk less than this
    /// inside the other three feet's triangle, m (`FreePairing::support_margin_m`, −0.2–0.2;
    /// default 0).
    #[arg(long)]
    pub free_support_margin: Option<f64>,
    /// Free gait: the earlier rule, a partner only when it is outside its ellipse too
    /// (`FreePairing::UNPAIRED`; EEMP-RL's shipped policy was trained with it).
    #[arg(long, conflicts_with_all = ["free_pair_tolerance", "free_support_margin"])]
    pub free_unpaired: bool,
    /// Keep the MPC's friction coefficient fixed: no slip handling (`eemp_core::slip`, on by
    /// default for the trot and the free gait: a sliding stance foot lowers the coefficient, a
    /// holding one raises it).
    #[arg(long, conflicts_with = "adapt_friction")]
    pub no_adapt_friction: bool,
    /// Slip handling on whatever the gait (the walk's default is off).
    #[arg(long)]
    pub adapt_friction: bool,
    /// MPC horizon, steps of its dt (default: MpcConfig's 10).
    #[arg(long)]
    pub mpc_horizon: Option<usize>,
    /// Time between MPC solves, s (a stance change also triggers a solve).
    #[arg(long, default_value_t = eemp_core::controller::ControllerConfig::default().mpc_period_s)]
    pub mpc_period: f64,
    /// Rows per second in trace.csv (the simulation runs at 1000 Hz; writing every step costs
    /// about a quarter of the run time).
    #[arg(long, default_value_t = 100.0)]
    pub trace_hz: f64,
    #[command(flatten)]
    pub robot: crate::robot_arg::RobotArgs,
    #[command(flatten)]
    pub rerun: crate::rerun_arg::RerunArgs,
    /// Also write a video of the walk (animated GIF, 25 frames/s, rendered offscreen).
    #[arg(long)]
    pub video: Option<PathBuf>,
    /// Output folder.
    #[arg(long, default_value = "out/walk")]
    pub out: PathBuf,
}

/// Which controller a walk runs.
enum Driver {
    Eemp,
    /// A trained policy (model-free or imitation).
    Policy(Box<eemp_rl::policy::Policy>),
}

pub fn run(args: &WalkArgs) -> Result<(), String> {
    let gait: Gait = args.gait.parse()?;
    let driver = match (args.controller.as_str(), &args.policy) {
        ("eemp", None) => Driver::Eemp,
        ("eemp", Some(_)) => {
            return Err(
                "--policy is for a learned --controller (model-free, imitation), not eemp".into(),
            )
        }
        (c @ ("model-free" | "imitation" | "eemp-rl"), Some(p)) => Driver::Policy(Box::new(
            eemp_rl::policy::Policy::load(p, Some(c.parse()?))?,
        )),
        (c @ ("model-free" | "imitation" | "eemp-rl"), None) => {
            return Err(format!(
                "--controller {c} needs --policy FILE (e.g. policies/a1_{}.safetensors)",
                c.replace('-', "_")
            ))
        }
        (other, _) => {
            return Err(format!(
                "unknown --controller '{other}': allowed eemp, model-free, imitation, eemp-rl"
            ))
        }
    };
    let free_flags = args.free_unpaired
        || args.free_pair_tolerance.is_some()
        || args.free_support_margin.is_some();
    if free_flags && (args.controller != "eemp" || gait != Gait::Free) {
        return Err(format!(
            "--free-unpaired, --free-pair-tolerance and --free-support-margin are for \
             --controller eemp --gait free, not --controller {} --gait {gait} (EEMP-RL runs \
             the rule it was trained with)",
            args.controller
        ));
    }
    if (args.no_adapt_friction || args.adapt_friction) && args.controller != "eemp" {
        return Err(format!(
            "--no-adapt-friction and --adapt-friction are for --controller eemp, not {} (a policy runs with the \
             controller it was trained with)",
            args.controller
        ));
    }
    if !(args.duration.is_finite() && args.duration > 0.0 && args.duration <= 3600.0) {
        return Err(format!(
            "--duration {} is out of range: allowed (0, 3600] s",
            args.duration
        ));
    }
    let robot = args.robot.load()?;
    let driver = match driver {
        Driver::Policy(mut p) => {
            p.allow_robot_mismatch = args.robot.allow_robot_mismatch;
            p.check_robot(&robot)?;
            Driver::Policy(p)
        }
        d => d,
    };
    let params: PlannerParams = match &args.params {
        Some(p) => load_toml(p).map_err(|e| e.to_string())?,
        None => PlannerParams::default(),
    };
    let params_table = match &args.params_table {
        Some(p) => Some(
            eemp_core::planner::params_table::ParamsTable::load(p).map_err(|e| e.to_string())?,
        ),
        None => None,
    };
    if let (Some(t), false) = (&params_table, args.robot.allow_robot_mismatch) {
        t.robot_id().check(
            &robot,
            &args
                .params_table
                .as_ref()
                .expect("loaded")
                .display()
                .to_string(),
        )?;
    }
    if let Some(f) = args.progress_factor {
        let [lo, hi] = eemp_core::planner::PROGRESS_FACTOR_RANGE;
        if !(f.is_finite() && (lo..=hi).contains(&f)) {
            return Err(format!(
                "--progress-factor {f} is out of range: allowed [{lo}, {hi}] (0.5 = the paper's \
                 eq. 6, 1 = its Algorithm 1)"
            ));
        }
        if let Some(theirs) = params_table.as_ref().and_then(|t| t.progress_factor) {
            if theirs != f {
                eprintln!(
                    "note: --params-table was selected with progress factor {theirs}; walking \
                     with --progress-factor {f} as asked"
                );
            }
        }
    }
    let progress_factor = progress_factor(args.progress_factor, params_table.as_ref());
    let planner = PlannerConfig {
        gait,
        progress_factor,
        retarget_swing: args.retarget_swing,
        max_accel_mps2: args.max_accel,
        preview_swings: args.preview_swings,
        free_pairing: free_pairing(args),
        first_step_on_command: args.first_step_on_command,
    };
    planner.validate().map_err(|e| e.to_string())?;
    let command = VelocityCommand {
        vx_mps: args.speed,
        vy_mps: args.lateral,
        yaw_rate_rps: args.yaw_rate,
    };
    let mut spec = WalkSpec::constant(planner, params, command, args.duration);
    if let Some(p) = &args.profile {
        spec.profile = load_toml::<VelocityProfile>(p).map_err(|e| e.to_string())?;
    }
    spec.controller.mpc_period_s = args.mpc_period;
    if let Some(h) = args.mpc_horizon {
        spec.controller.mpc.horizon = h;
    }
    if let Some(mu) = args.mpc_friction {
        spec.controller.mpc.friction_coefficient = mu;
    }
    if args.no_adapt_friction {
        spec.controller.slip.adapt_friction = false;
    } else if args.adapt_friction {
        spec.controller.slip.adapt_friction = true;
    }
    spec.seed = args.sensing.seed;
    spec.state_source = args.sensing.source(&robot)?;
    spec.allow_robot_mismatch = args.robot.allow_robot_mismatch;
    if let Driver::Policy(p) = &driver {
        crate::state_source_arg::adopt_policy_filter(
            &mut spec.state_source,
            p,
            &args.sensing.kf_options(),
        );
    }
    spec.floor_friction = args.friction;
    let scenario = match &args.scenario {
        Some(p) => Some(eemp_sim::scenario::Scenario::load(p).map_err(|e| e.to_string())?),
        None => None,
    };
    if let Some(sc) = &scenario {
        sc.apply(&mut spec);
        if let Some(noise) = &sc.sensors {
            if let eemp_sim::closed_loop::StateSource::Kf { sensors, .. } = &mut spec.state_source {
                *sensors = noise.clone();
            }
        }
    }
    spec.params_table = params_table;
    if let Some(at) = args.push_at {
        if !(at.is_finite() && at >= 0.0 && at < args.duration) {
            return Err(format!(
                "--push-at {at} is out of range: allowed [0, duration {})",
                args.duration
            ));
        }
        spec.pushes
            .push(Push::step(at, Vector3::new(0.0, args.push_dv, 0.0)));
    }
    spec.validate().map_err(|e| e.to_string())?;

    if !(args.trace_hz.is_finite() && args.trace_hz > 0.0 && args.trace_hz <= 1000.0) {
        return Err(format!(
            "--trace-hz {} is out of range: allowed (0, 1000]",
            args.trace_hz
        ));
    }
    let trace_every = (1000.0 / args.trace_hz).round().max(1.0) as usize;
    // Before anything is written: a bad recording path or an absent viewer stops here.
    let recording_name = format!(
        "walk: {} at {} m/s",
        match &driver {
            Driver::Eemp => format!("EEMP ({gait})"),
            Driver::Policy(_) => args.controller.clone(),
        },
        args.speed
    );
    let mut recorder = args.rerun.open(&recording_name, &robot, &spec)?;
    create_dir(&args.out).map_err(|e| e.to_string())?;
    let mut header: Vec<String> = [
        "time_s",
        "x_m",
        "y_m",
        "z_m",
        "roll_rad",
        "pitch_rad",
        "yaw_rad",
        "vx_mps",
        "vy_mps",
        "vz_mps",
        "est_vx_mps",
        "est_vy_mps",
        "est_vz_mps",
        "est_z_m",
        "cmd_vx_mps",
        "cmd_vy_mps",
        "cmd_yaw_rate_rps",
        "power_w",
        // The planner parameters in force (EEMP: constant, the table's at the command, or
        // EEMP-RL's choice; NaN for a controller without them).
        "swing_time_s",
        "step_height_m",
        "body_height_m",
        "ellipse_rx_m",
        "ellipse_ry_m",
        // The MPC's friction coefficient (slip handling's belief about the floor; NaN without
        // an MPC).
        "mu_estimate",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    for leg in Leg::ALL {
        let n = leg.short_name();
        header.extend([
            format!("{n}_foot_x_m"),
            format!("{n}_foot_y_m"),
            format!("{n}_foot_z_m"),
            format!("{n}_foot_z_ref_body_m"),
            format!("{n}_stance_cmd"),
            format!("{n}_contact"),
        ]);
        header.extend((0..3).map(|j| format!("{n}_tau{j}_nm")));
        header.extend((0..3).map(|j| format!("{n}_qd{j}_radps")));
        header.extend((0..3).map(|j| format!("{n}_q{j}_rad")));
    }
    let mut trace =
        Trace::create(&args.out.join("trace.csv"), &header).map_err(|e| e.to_string())?;
    let mut write_error = None;
    let (mut t, mut vx, mut vy, mut cvx, mut cvy) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut foot_z: [Vec<f64>; 4] = Default::default();
    let mut stance: Vec<[bool; 4]> = Vec::new();
    let mut i = 0usize;
    let mut params_in_force = eemp_core::planner::params_stats::ParamsStats::default();
    let mut frames = Vec::new();
    let video_every = (1.0 / (crate::video::FPS * robot.simulation.timestep_s)).round() as usize;
    let mut mu_estimate = f64::NAN;
    let observer = |r: &eemp_sim::closed_loop::StepRecord| {
        recorder.observe(r);
        if let Some(ev) = &r.output.mpc_event {
            mu_estimate = ev.friction_coefficient;
        }
        let s = &r.state.body;
        let v = s.v_heading();
        let cmd = spec.profile.command_at(r.state.time_s);
        if let Some(p) = r.plan.and_then(|p| p.params) {
            params_in_force.observe(cmd.vx_mps.hypot(cmd.vy_mps), &p);
        }
        if args.video.is_some() && i.is_multiple_of(video_every) {
            frames.push(crate::video::VideoFrame::of(
                r.state,
                [cmd.vx_mps, cmd.vy_mps],
            ));
        }
        // A trace row is built only for the steps written (every `trace_every`-th).
        if i.is_multiple_of(trace_every) {
            let rpy = s.rpy();
            // What the controller saw (the truth on ground truth), in its own heading frame
            // (its yaw estimate; the truth's columns use the true yaw).
            let v_est = r.estimate.body.v_heading();
            let qd = r.state.joints.map(|_, j| j.qd);
            let mut row = vec![
                r.state.time_s,
                s.p_world.x,
                s.p_world.y,
                s.p_world.z,
                rpy.x,
                rpy.y,
                rpy.z,
                v.x,
                v.y,
                v.z,
                v_est.x,
                v_est.y,
                v_est.z,
                r.estimate.body.p_world.z,
                cmd.vx_mps,
                cmd.vy_mps,
                cmd.yaw_rate_rps,
                positive_power_w(&qd, &r.output.torques),
            ];
            match r.plan.and_then(|p| p.params) {
                Some(p) => row.extend(p.to_array()),
                None => row.extend([f64::NAN; 5]),
            }
            row.push(mu_estimate);
            for leg in Leg::ALL {
                let f = r.feet_world[leg];
                let z_ref = r
                    .plan
                    .and_then(|p| p.swing[leg])
                    .map(|sw| sw.p_body.z)
                    .unwrap_or(f64::NAN);
                row.extend([
                    f.x,
                    f.y,
                    f.z,
                    z_ref,
                    r.stance()[leg] as u8 as f64,
                    r.contacts[leg] as u8 as f64,
                ]);
                row.extend(r.output.torques[leg].iter());
                row.extend(qd[leg].iter());
                row.extend(r.state.joints[leg].q.iter());
            }
            if let Err(e) = trace.row(&row) {
                write_error.get_or_insert(e);
            }
        }
        // Figures at 100 Hz are plenty.
        if i.is_multiple_of(10) {
            t.push(r.state.time_s);
            vx.push(v.x);
            vy.push(v.y);
            cvx.push(cmd.vx_mps);
            cvy.push(cmd.vy_mps);
            for leg in Leg::ALL {
                foot_z[leg.index()].push(r.feet_world[leg].z);
            }
            stance.push(r.stance().0);
        }
        i += 1;
    };
    let (run, method) = match driver {
        Driver::Eemp => (
            run_walk(&robot, &spec, observer).map_err(|e| e.to_string())?,
            format!("EEMP ({gait})"),
        ),
        Driver::Policy(policy) if policy.config.task == eemp_rl::config::TaskKind::EempRl => {
            let cfg = policy.config.eemp_rl.clone();
            let start =
                eemp_rl::tasks::eemp_rl::EempRlController::<eemp_rl::policy::Policy>::start_pose(
                    &robot,
                    &cfg,
                    spec.profile.first_speed_mps(),
                )?;
            let mut c = eemp_rl::tasks::eemp_rl::EempRlController::new(&robot, cfg, *policy)?;
            let run = run_walk_with(&robot, &spec, &start, &mut c, observer)
                .map_err(|e| e.to_string())?;
            (run, "EEMP-RL".to_string())
        }
        Driver::Policy(policy) => {
            let label = match policy.config.task {
                eemp_rl::config::TaskKind::Imitation => "motion imitation",
                _ => "model-free RL",
            };
            let mut c = eemp_rl::controller::PolicyController::new(
                *policy,
                &robot,
                robot.simulation.timestep_s,
            )?;
            let start = StartPose::from_joints(&robot, c.default_pose());
            let run = run_walk_with(&robot, &spec, &start, &mut c, observer)
                .map_err(|e| e.to_string())?;
            if c.invalid_steps > 0 {
                eprintln!(
                    "warning: {} policy steps had a non-finite observation or action (targets held)",
                    c.invalid_steps
                );
            }
            (run, label.to_string())
        }
    };
    let recording = recorder.finish();
    if let Some(e) = write_error {
        return Err(e.to_string());
    }
    trace.finish().map_err(|e| e.to_string())?;
    let m = &run.metrics;
    let st = &run.stats;
    let total = st.wall_time_s.max(1e-12);
    let summary = serde_json::json!({
        "controller": args.controller,
        "policy": args.policy.as_ref().map(|p| p.display().to_string()),
        "gait": if args.controller == "eemp" { Some(gait.to_string()) } else { None },
        "speed_mps": args.speed,
        "profile": args.profile.as_ref().map(|p| p.display().to_string()),
        // Constant parameters given (--params or Table II); what actually ran, per commanded
        // speed, is under params_in_force (a table's, EEMP-RL's choices).
        "params": (args.controller == "eemp" && args.params_table.is_none()).then_some(params),
        "params_in_force": params_in_force.per_speed(),
        // A learned policy acts with its Gaussian's mean (no sampling).
        "policy_action": args.policy.as_ref().map(|_| "mean"),
        "params_table": args.params_table.as_ref().map(|p| p.display().to_string()),
        "progress_factor": spec.planner.progress_factor,
        "retarget_swing": args.retarget_swing,
        "first_step_on_command": args.first_step_on_command,
        "max_accel_mps2": args.max_accel,
        "preview_swings": args.preview_swings,
        // What the free gait's planner used (EEMP-RL keeps its training's, in the policy file).
        "free_pairing": (args.controller == "eemp" && gait == Gait::Free)
            .then_some(spec.planner.free_pairing),
        "kf": spec.state_source.kf_config(),
        "duration_s": st.sim_time_s,
        "metrics_window_s": [spec.metrics_start_s, st.sim_time_s],
        "fell": st.fell,
        "fell_at_s": st.fell_at_s,
        "distance_m": m.distance_m,
        "energy_j": m.energy_j,
        "cot_j_per_m": m.cot_j_per_m,
        "cot": m.cot,
        "manipulability": m.manipulability,
        "vel_rmse_mps": m.vel_rmse_mps,
        "steps": Leg::ALL.iter().map(|l| (l.short_name().to_string(), serde_json::json!(run.steps[*l]))).collect::<serde_json::Map<_, _>>(),
        "steps_total": run.steps.0.iter().sum::<usize>(),
        "all_stance_fraction": m.all_stance_fraction,
        "realtime_factor": st.realtime_factor(),
        "mpc_solves": st.mpc_solves,
        "mpc_failures": st.mpc_failures,
        "mpc_friction_min": st.mpc_friction_min,
        "adapt_friction": args.controller == "eemp" && spec.controller.slip.adapt_friction,
        "mpc_solve_us_median": st.mpc_solve_median_us(),
        "time_share": {
            "physics": st.stages.physics_s / total,
            "mpc": st.stages.mpc_s / total,
            "leg_control": st.stages.leg_control_s / total,
            "planner": st.stages.planner_s / total,
            "logging": st.stages.observer_s / total,
        },
        "scenario": args.scenario.as_ref().map(|p| p.display().to_string()),
        "state_estimate": spec.state_source.name(),
        "estimation_vel_rmse_mps": run.estimation.vel_rmse_mps(),
        "estimation_pos_rmse_m": run.estimation.pos_rmse_m(),
    });
    let mut summary = summary;
    // Energy beside eq. 8's CoT: each joint's positive and negative work, and the CoT of the
    // absolute joint power (Fu et al. 2021's measure); the gait walked (any controller).
    for (key, value) in [
        (
            "joint_positive_work_j",
            serde_json::json!(m.joint_positive_work_j),
        ),
        (
            "joint_negative_work_j",
            serde_json::json!(m.joint_negative_work_j),
        ),
        (
            "negative_work_share",
            serde_json::json!(m.negative_work_share),
        ),
        ("cot_abs_power", serde_json::json!(m.cot_abs_power)),
        ("gait_measure", serde_json::json!(run.gait)),
        (
            "robot",
            crate::robot_arg::robot_json(&robot, args.robot.allow_robot_mismatch),
        ),
        (
            // What slip handling believed the floor's friction to be (the MPC's coefficient,
            // never above its nominal) and the floor it walked on.
            "friction_estimate",
            serde_json::json!({
                "final": st.mpc_friction_last,
                "min": st.mpc_friction_min,
                "mean": (st.mpc_solves > 0).then(|| st.mpc_friction_sum / st.mpc_solves as f64),
                "floor_friction": spec.floor_friction.unwrap_or(robot.simulation.floor_friction),
            }),
        ),
        ("rerun", serde_json::json!(recording)),
    ] {
        summary[key] = value;
    }
    write_json(&args.out.join("summary.json"), &summary).map_err(|e| e.to_string())?;
    let panels = vec![
        Panel {
            title: "forward velocity".into(),
            x_label: "time [s]".into(),
            y_label: "v_x [m/s]".into(),
            series: vec![
                Series {
                    label: "commanded".into(),
                    x: t.clone(),
                    y: cvx,
                },
                Series {
                    label: "actual".into(),
                    x: t.clone(),
                    y: vx,
                },
            ],
            markers: vec![],
            bands: vec![],
        },
        Panel {
            title: "lateral velocity".into(),
            x_label: "time [s]".into(),
            y_label: "v_y [m/s]".into(),
            series: vec![
                Series {
                    label: "commanded".into(),
                    x: t.clone(),
                    y: cvy,
                },
                Series {
                    label: "actual".into(),
                    x: t.clone(),
                    y: vy,
                },
            ],
            markers: vec![],
            bands: vec![],
        },
        Panel {
            title: "foot heights (flat intervals: all four feet in stance)".into(),
            x_label: "time [s]".into(),
            y_label: "foot centre z [m]".into(),
            series: Leg::ALL
                .iter()
                .map(|l| Series {
                    label: l.short_name().into(),
                    x: t.clone(),
                    y: foot_z[l.index()].clone(),
                })
                .collect(),
            markers: vec![],
            bands: vec![],
        },
    ];
    line_panels(
        &args.out.join("velocity_and_feet.png"),
        &format!("A1 under {method}: velocity tracking and foot heights"),
        &panels,
    )
    .map_err(|e| e.to_string())?;
    gait_diagram(
        &args.out.join("gait.png"),
        &format!("Gait diagram ({method}, {} m/s)", args.speed),
        &t,
        &stance,
        ["FR", "FL", "RR", "RL"],
    )
    .map_err(|e| e.to_string())?;
    println!(
        "{}",
        serde_json::to_string_pretty(&summary).expect("serialises")
    );
    println!(
        "wrote {}/summary.json, trace.csv, velocity_and_feet.png, gait.png",
        args.out.display()
    );
    if let Some(video) = &args.video {
        let friction = spec
            .floor_friction
            .unwrap_or(robot.simulation.floor_friction);
        crate::video::write_gif(
            &robot,
            &spec.terrain.scene(friction),
            &frames,
            &method,
            video,
        )?;
        println!("wrote {} ({} frames)", video.display(), frames.len());
    }
    Ok(())
}

/// Eq. (6)'s factor of a walk: the one given on the command line, else the one the parameter
/// table was selected with (a table's entries are best with the factor they were found with),
/// else the paper's 0.5.
fn progress_factor(
    given: Option<f64>,
    table: Option<&eemp_core::planner::params_table::ParamsTable>,
) -> f64 {
    given
        .or_else(|| table.and_then(|t| t.progress_factor))
        .unwrap_or(eemp_core::planner::PAPER_PROGRESS_FACTOR)
}

/// `--free-unpaired`, `--free-pair-tolerance`, `--free-support-margin` over the defaults.
fn free_pairing(args: &WalkArgs) -> FreePairing {
    if args.free_unpaired {
        return FreePairing::UNPAIRED;
    }
    let mut p = FreePairing::default();
    if let Some(t) = args.free_pair_tolerance {
        p.pair_tolerance = t;
    }
    if let Some(m) = args.free_support_margin {
        p.support_margin_m = m;
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;
    use eemp_core::planner::params_table::{Interpolation, ParamsTable, TableEntry};

    #[test]
    fn the_progress_factor_comes_from_the_option_then_the_table_then_the_paper() {
        let table = ParamsTable::new(
            Gait::Walk,
            Interpolation::Nearest,
            vec![TableEntry::new(0.3, &PlannerParams::default())],
        )
        .unwrap();
        assert_eq!(progress_factor(None, None), 0.5);
        assert_eq!(progress_factor(None, Some(&table)), 0.5);
        let table = table.with_progress_factor(1.5).unwrap();
        assert_eq!(progress_factor(None, Some(&table)), 1.5);
        assert_eq!(progress_factor(Some(1.0), Some(&table)), 1.0);
    }
}
