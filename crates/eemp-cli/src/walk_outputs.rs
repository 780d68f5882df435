//! What `eemp walk` writes: `trace.csv` (streamed), `summary.json`, the figures, the video and
//! the Rerun recording, from one observer on the walk the run description built.

use crate::output::{create_dir, write_json, Trace};
use crate::plots::{gait_diagram, line_panels, Panel, Series};
use eemp_core::leg::Leg;
use eemp_core::metrics::positive_power_w;
use eemp_core::planner::Gait;
use eemp_rl::run::WalkDescription;
use std::path::PathBuf;

/// Where and how a walk's results are written.
pub struct WalkOutputs<'a> {
    pub out: PathBuf,
    pub video: Option<PathBuf>,
    /// Rows per simulated second in trace.csv, (0, 1000].
    pub trace_hz: f64,
    pub rerun: &'a crate::rerun_arg::RerunArgs,
}

/// Builds the walk `d` describes, runs it and writes its outputs.
pub fn walk(d: &WalkDescription, o: &WalkOutputs) -> Result<(), String> {
    let built = d.build()?;
    // The observer reads the spec while the walk runs; the walk takes the built run.
    let (robot, spec) = (built.robot.clone(), built.spec.clone());
    let (gait, params) = (built.gait, built.params);
    let params_table = built.params_table_path.clone();
    let is_eemp = d.controller == "eemp";
    if !(o.trace_hz.is_finite() && o.trace_hz > 0.0 && o.trace_hz <= 1000.0) {
        return Err(format!(
            "--trace-hz {} is out of range: allowed (0, 1000]",
            o.trace_hz
        ));
    }
    let trace_every = (1000.0 / o.trace_hz).round().max(1.0) as usize;
    // Before anything is written: a video folder that cannot be made, a bad recording path or
    // an absent viewer stops here.
    if let Some(parent) = o.video.as_ref().and_then(|v| v.parent()) {
        if !parent.as_os_str().is_empty() {
            std::fs::create_dir_all(parent).map_err(|e| {
                format!(
                    "--video: cannot create the folder {}: {e}",
                    parent.display()
                )
            })?;
        }
    }
    let recording_name = format!("walk: {} at {} m/s", built.method(), d.speed_mps);
    let mut recorder = o.rerun.open(&recording_name, &robot, &spec)?;
    create_dir(&o.out).map_err(|e| e.to_string())?;
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
        // Eq. (8)'s power (the paper's: net mechanical, clipped after the sum), W.
        "power_w",
        // The battery's power under the robot's motor model (drives and idle), W; NaN
        // without a `[motor]` section.
        "electrical_power_w",
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
        // Slip handling's speed cap on a floor it found slippery (`slip.slow_below_friction`,
        // the walk's default), m/s; NaN: no cap.
        "speed_cap_mps",
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
    let mut trace = Trace::create(&o.out.join("trace.csv"), &header).map_err(|e| e.to_string())?;
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
    let motor = robot.motor_model();
    let motor = motor.as_ref();
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
        if o.video.is_some() && i.is_multiple_of(video_every) {
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
                motor
                    .map(|m| m.battery_power_w(&qd, &r.output.torques))
                    .unwrap_or(f64::NAN),
            ];
            match r.plan.and_then(|p| p.params) {
                Some(p) => row.extend(p.to_array()),
                None => row.extend([f64::NAN; 5]),
            }
            row.push(mu_estimate);
            row.push(r.plan.and_then(|p| p.speed_cap_mps).unwrap_or(f64::NAN));
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
    let method = built.method();
    let run = built.run(observer)?;
    let recording = recorder.finish();
    if let Some(e) = write_error {
        return Err(e.to_string());
    }
    trace.finish().map_err(|e| e.to_string())?;
    let m = &run.metrics;
    let st = &run.stats;
    let total = st.wall_time_s.max(1e-12);
    let summary = serde_json::json!({
        "controller": d.controller,
        "policy": d.policy.as_ref().map(|p| p.display().to_string()),
        "gait": if is_eemp { Some(gait.to_string()) } else { None },
        // With a profile the command is the profile's (--speed is not used).
        "speed_mps": d.profile.is_none().then_some(d.speed_mps),
        "profile": d.profile.as_ref().map(|p| p.display().to_string()),
        // Constant parameters given (--params or Table II); what actually ran, per commanded
        // speed, is under params_in_force (a table's, EEMP-RL's choices).
        "params": (is_eemp && params_table.is_none()).then_some(params),
        "params_in_force": params_in_force.per_speed(),
        // A learned policy acts with its Gaussian's mean (no sampling).
        "policy_action": d.policy.as_ref().map(|_| "mean"),
        // The table EEMP walked on: --params-table's, or the shipped one by default.
        "params_table": params_table.as_ref().map(|p| p.display().to_string()),
        "progress_factor": spec.planner.progress_factor,
        "retarget_swing": spec.planner.retarget_swing,
        "first_step_on_command": spec.planner.first_step_on_command,
        "max_accel_mps2": spec.planner.max_accel_mps2,
        "ellipse_friction_factor": spec.planner.ellipse_friction_factor_in_force(),
        "touchdown_friction_factor": spec.planner.touchdown_friction_factor_in_force(),
        "preview_swings": spec.planner.preview_swings,
        // What the free gait's planner used (EEMP-RL keeps its training's, in the policy file).
        "free_pairing": (is_eemp && gait == Gait::Free)
            .then_some(spec.planner.free_pairing),
        "walk_support": (is_eemp && gait == Gait::Walk).then_some(spec.planner.walk_support),
        "kf": spec.state_source.kf_config(),
        "duration_s": st.sim_time_s,
        // None when the walk ended (a fall) before the window opened: no metrics.
        "metrics_window_s": (st.sim_time_s > spec.metrics_start_s)
            .then_some([spec.metrics_start_s, st.sim_time_s]),
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
        "adapt_friction": is_eemp && spec.controller.slip.adapt_friction,
        "mpc_solve_us_median": st.mpc_solve_median_us(),
        "time_share": {
            "physics": st.stages.physics_s / total,
            "mpc": st.stages.mpc_s / total,
            "leg_control": st.stages.leg_control_s / total,
            "planner": st.stages.planner_s / total,
            "logging": st.stages.observer_s / total,
        },
        "scenario": d.scenario.as_ref().map(|p| p.display().to_string()),
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
        // The energy a battery pays under the robot file's motor model (docs/energy.md):
        // electrical power, energy, Wh/km, CoT with and without idle power, the k band.
        ("electrical", serde_json::json!(m.electrical)),
        ("electrical_note", serde_json::json!(m.electrical_note)),
        (
            "cot_definition",
            serde_json::json!(
                "cot, cot_j_per_m, energy_j: the paper's eq. (8), net mechanical power of all \
                 joints clipped after the sum (no motor heat, no electronics); electrical.cot: \
                 the battery's, with idle power"
            ),
        ),
        ("gait_measure", serde_json::json!(run.gait)),
        (
            "robot",
            crate::robot_arg::robot_json(&robot, d.allow_robot_mismatch),
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
                // The share of the run the speed cap for a floor found slippery was on
                // (`slip.slow_below_friction`; a command already below it stays as it was).
                "slowed_share": st.slowed_steps as f64 / st.steps.max(1) as f64,
            }),
        ),
        ("rerun", serde_json::json!(recording)),
        // The command line and its folder: `eemp replay --rerun` simulates the walk again.
        (
            "command",
            serde_json::json!(std::env::args().skip(1).collect::<Vec<String>>()),
        ),
        (
            "cwd",
            serde_json::json!(std::env::current_dir()
                .ok()
                .map(|d| d.display().to_string())),
        ),
    ] {
        summary[key] = value;
    }
    write_json(&o.out.join("summary.json"), &summary).map_err(|e| e.to_string())?;
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
        &o.out.join("velocity_and_feet.png"),
        &format!("A1 under {method}: velocity tracking and foot heights"),
        &panels,
    )
    .map_err(|e| e.to_string())?;
    gait_diagram(
        &o.out.join("gait.png"),
        &format!("Gait diagram ({method}, {} m/s)", d.speed_mps),
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
        o.out.display()
    );
    if let Some(video) = &o.video {
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
