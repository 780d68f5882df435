//! `eemp hw` (a controller on an A1 over UDP or a Go2 over DDS, behind the safety layer) and
//! `eemp sim-robot` (the MuJoCo robot speaking the same interface).

use crate::link_arg::{LinkArgs, Resolved};
use eemp_core::estimator::KfConfig;
use eemp_core::leg::{Leg, LegMap};
use eemp_core::planner::{Gait, PlannerConfig, PlannerParams, VelocityCommand};
use eemp_core::robot::RobotConfig;
use eemp_core::safety::SafetyConfig;
use eemp_hw::dds::{ROBOT_DOMAIN_ID, SIM_DOMAIN_ID};
use eemp_hw::link::{Faults, Link};
use eemp_hw::motion_switcher::ReleaseOptions;
use eemp_hw::runner::{run_hw, HwOptions, TorqueSpike, Transport};
use eemp_hw::sim_robot::{run_sim_robot, RobotWire, SimRobotOptions};
use eemp_hw::wire::a1_protocol::LowState;
use eemp_rl::run::{BuiltWalk, Sensing, WalkDescription};
use eemp_sim::walk::{StartPose, WalkSpec};
use std::io::Write;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;

/// Faults to inject on the datagrams (or DDS samples) this side sends (tests, rehearsals).
#[derive(clap::Args, Debug, Clone)]
pub struct FaultArgs {
    /// Probability that a sent datagram is lost.
    #[arg(long, default_value_t = 0.0)]
    pub drop: f64,
    /// Probability that one byte of a sent datagram is flipped.
    #[arg(long, default_value_t = 0.0)]
    pub corrupt: f64,
    /// Probability that a datagram is sent after the next one.
    #[arg(long, default_value_t = 0.0)]
    pub reorder: f64,
    /// Delay of every sent datagram, ms.
    #[arg(long, default_value_t = 0.0)]
    pub delay_ms: f64,
    #[arg(long, default_value_t = 1)]
    pub fault_seed: u64,
}

impl FaultArgs {
    fn faults(&self) -> Faults {
        Faults {
            drop_prob: self.drop,
            corrupt_prob: self.corrupt,
            reorder_prob: self.reorder,
            delay_s: self.delay_ms * 1e-3,
            seed: self.fault_seed,
        }
    }
}

#[derive(clap::Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct HwArgs {
    /// UDP only: the robot's address (the A1: 192.168.123.10:8007; `eemp sim-robot`:
    /// 127.0.0.1:PORT). (Before robot files took `--robot`, this was `--robot`.)
    #[arg(long)]
    pub address: Option<SocketAddr>,
    #[command(flatten)]
    pub robot: crate::robot_arg::RobotArgs,
    #[command(flatten)]
    pub link: LinkArgs,
    /// DDS only: the robot is already in low-level mode; do not ask its motion switcher to
    /// release sport mode first (without it, hw refuses to start when the release fails).
    #[arg(long)]
    pub no_release: bool,
    /// DDS only: give up releasing sport mode after this long, s.
    #[arg(long, default_value_t = 20.0)]
    pub release_timeout: f64,
    /// On a robot there is no truth: the recording shows the filter's estimate, the commands
    /// and the torques sent (`--rerun-serve PORT` for a robot computer without a display).
    #[command(flatten)]
    pub rerun: crate::rerun_arg::RerunArgs,
    /// UDP only: local address to send from (the SDK uses port 8080).
    #[arg(long, default_value = "0.0.0.0:8080")]
    pub bind: SocketAddr,
    /// Print the first commands it would send for a robot standing still, without a socket.
    #[arg(long)]
    pub dry_run: bool,
    /// eemp, model-free, imitation or eemp-rl (with --policy).
    #[arg(long, default_value = "eemp")]
    pub controller: String,
    /// Policy file of a learned --controller (e.g. policies/a1_model_free.safetensors).
    #[arg(long)]
    pub policy: Option<PathBuf>,
    /// EEMP's gait and per-speed table (default tables/<robot>_<gait>.toml).
    #[arg(long, default_value = "trot")]
    pub gait: String,
    #[arg(long)]
    pub params_table: Option<PathBuf>,
    #[arg(long, default_value_t = 0.0)]
    pub speed: f64,
    #[arg(long, default_value_t = 0.0)]
    pub lateral: f64,
    #[arg(long, default_value_t = 0.0)]
    pub yaw_rate: f64,
    /// Seconds to run (then the robot is left in damping).
    #[arg(long, default_value_t = 10.0)]
    pub duration: f64,
    /// Control rate, Hz.
    #[arg(long, default_value_t = 500.0)]
    pub rate: f64,
    /// Safety settings (TOML, `eemp_core::safety::SafetyConfig`; default values
    /// otherwise).
    #[arg(long)]
    pub safety: Option<PathBuf>,
    /// Fault injection: add this torque (N·m) to FL calf's command for one cycle at --spike-at.
    #[arg(long, requires = "spike_at")]
    pub spike_nm: Option<f64>,
    #[arg(long, requires = "spike_nm")]
    pub spike_at: Option<f64>,
    #[command(flatten)]
    pub faults: FaultArgs,
    /// summary.json and trace.csv (100 Hz) go here.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// The run the arguments describe, built by the walk's own description: `eemp walk
/// --estimator kf`'s defaults, tables, policies, filter settings and checks. On a robot, EEMP's
/// table must exist (no fallback to Table II's constants, which were tuned for the A1).
fn describe(args: &HwArgs, robot: &RobotConfig) -> Result<BuiltWalk, String> {
    let params_table = if args.controller == "eemp" {
        let gait: Gait = args.gait.parse()?;
        Some(
            args.params_table
                .clone()
                .unwrap_or_else(|| robot.shipped_table_path(gait)),
        )
    } else {
        args.params_table.clone()
    };
    WalkDescription {
        robot: args.robot.robot.clone(),
        allow_robot_mismatch: args.robot.allow_robot_mismatch,
        controller: args.controller.clone(),
        policy: args.policy.clone(),
        gait: args.gait.clone(),
        params_table,
        sensing: Sensing {
            estimator: "kf".into(),
            ..Default::default()
        },
        duration_s: args.duration,
        ..Default::default()
    }
    .build()
}

/// The state datagram of the A1 standing still, level, in the standing pose.
fn standing_state(robot: &RobotConfig) -> LowState {
    let mut s = LowState::default();
    s.imu.quaternion = [1.0, 0.0, 0.0, 0.0];
    s.imu.accelerometer = [0.0, 0.0, 9.81];
    let q = robot.standing_pose();
    let order = robot.motor_order();
    for leg in Leg::ALL {
        for j in 0..3 {
            s.motors[order.index(leg, j)].q = q[leg][j] as f32;
        }
    }
    s
}

/// What summary.json says about the wire.
fn link_json(t: &Transport) -> serde_json::Value {
    match t {
        Transport::Udp { robot, bind, .. } => {
            serde_json::json!({"kind": "udp", "robot": robot.to_string(), "bind": bind.to_string()})
        }
        Transport::Dds {
            config, release, ..
        } => serde_json::json!({
            "kind": "dds",
            "domain": config.domain_id,
            "iface": config.iface,
            "release_sport_mode": release.is_some(),
        }),
        Transport::DryRun { .. } => serde_json::json!({"kind": "dry-run"}),
    }
}

pub fn run_hw_cmd(args: &HwArgs) -> Result<(), String> {
    let robot = args.robot.load()?;
    let link = args.link.resolve(&robot, ROBOT_DOMAIN_ID, None)?;
    // Defaults and caps scaled to the robot's size (the A1's own values on the A1).
    let size = robot.scale();
    let safety: SafetyConfig = match &args.safety {
        Some(p) => SafetyConfig::load_for(p, &size).map_err(|e| e.to_string())?,
        None => SafetyConfig::for_size(&size),
    };
    let speed = size.factor("m/s").unwrap_or(1.0);
    let rate = size.factor("rad/s").unwrap_or(1.0);
    for (name, v, lo, hi) in [
        ("--speed", args.speed, -1.5 * speed, 1.5 * speed),
        ("--lateral", args.lateral, -speed, speed),
        ("--yaw-rate", args.yaw_rate, -2.0 * rate, 2.0 * rate),
    ] {
        if !(v.is_finite() && (lo..=hi).contains(&v)) {
            return Err(format!("{name} {v} is out of range: allowed [{lo}, {hi}]"));
        }
    }
    let transport = if args.dry_run {
        Transport::DryRun {
            state: Box::new(standing_state(&robot)),
        }
    } else {
        match link {
            Resolved::Udp => Transport::Udp {
                robot: args
                    .address
                    .ok_or("--address is required on the UDP link (the A1: 192.168.123.10:8007)")?,
                bind: args.bind,
                faults: args.faults.faults(),
            },
            Resolved::Dds(config) => {
                if args.address.is_some() {
                    return Err(
                        "--address is a UDP setting: the DDS link finds the robot by \
                                discovery on --domain / --iface"
                            .into(),
                    );
                }
                Transport::Dds {
                    config,
                    faults: args.faults.faults(),
                    release: (!args.no_release).then(|| ReleaseOptions {
                        timeout_s: args.release_timeout,
                        ..Default::default()
                    }),
                }
            }
        }
    };
    let mut opts = HwOptions {
        transport,
        rate_hz: args.rate,
        duration_s: if args.dry_run {
            args.duration.min(0.02)
        } else {
            args.duration
        },
        safety,
        // Replaced below by the run's own, once the options are known to be valid.
        kf: KfConfig::default(),
        torque_spike: args.spike_at.map(|at_s| TorqueSpike {
            at_s,
            leg: Leg::FrontLeft,
            joint: 2,
            nm: args.spike_nm.unwrap_or(0.0),
        }),
    };
    opts.validate()?;
    let run = describe(args, &robot)?;
    // The filter as `eemp walk --estimator kf` runs it (a policy trained on the filter: its
    // training's settings).
    opts.kf = run
        .spec
        .state_source
        .kf_config()
        .cloned()
        .ok_or("the description runs on the filter")?;
    let mut controller = run.into_controller(1.0 / args.rate)?;
    let command = VelocityCommand {
        vx_mps: args.speed,
        vy_mps: args.lateral,
        yaw_rate_rps: args.yaw_rate,
    };
    let mut trace = match &args.out {
        Some(dir) => {
            std::fs::create_dir_all(dir)
                .map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
            let mut f = std::fs::File::create(dir.join("trace.csv"))
                .map_err(|e| format!("cannot write trace.csv: {e}"))?;
            writeln!(
                f,
                "time_s,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps,yaw_rate_rps,cmd_vx_mps,new_state,interventions"
            )
            .map_err(|e| e.to_string())?;
            Some(f)
        }
        None => None,
    };
    let mut next_row = 0.0;
    let mut printed = 0;
    let dry = args.dry_run;
    let mut recorder = args.rerun.open_world(crate::rerun_arg::World {
        name: &format!("hw: {} (the filter's estimate)", args.controller),
        robot: robot.clone(),
        scene: Default::default(),
        pushes: Vec::new(),
        estimated: false,
        step_s: 1.0 / args.rate,
    })?;
    let kin = eemp_core::kinematics::LegKinematics::new(&robot);
    let report = run_hw(&robot, controller.as_mut(), &|_| command, &opts, &mut |c| {
        if let Some(e) = c.estimate {
            let output = eemp_core::locomotion::ControlOutput {
                torques: LegMap::from_fn(|leg| {
                    let j = c.sent[leg];
                    nalgebra::Vector3::new(j[0].tau, j[1].tau, j[2].tau)
                }),
                forces_world: LegMap::splat(nalgebra::Vector3::zeros()),
                mpc_event: None,
            };
            recorder.observe(&eemp_sim::closed_loop::StepRecord {
                state: e,
                estimate: e,
                plan: None,
                command: c.command,
                output: &output,
                feet_world: &eemp_core::locomotion::feet_world(&kin, e),
                contacts: LegMap::splat(false),
                loaded: LegMap::splat(false),
                foot_normal_n: LegMap::splat(0.0),
            });
        }
        if dry && printed < 5 {
            printed += 1;
            println!("t {:.3} s: would send (kp, kd, q*, τ) per joint:", c.t_s);
            for leg in Leg::ALL {
                let j = c.sent[leg];
                println!(
                    "  {}: {}",
                    leg.short_name(),
                    j.iter()
                        .map(|j| format!("({:.1}, {:.1}, {:+.3}, {:+.2})", j.kp, j.kd, j.q, j.tau))
                        .collect::<Vec<_>>()
                        .join(" ")
                );
            }
            println!("  interventions: {:?}", c.interventions);
        }
        if let (Some(f), Some(e)) = (trace.as_mut(), c.estimate) {
            if c.t_s >= next_row {
                next_row += 0.01;
                let b = &e.body;
                let _ = writeln!(
                    f,
                    "{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.3},{},{}",
                    c.t_s,
                    b.p_world.x,
                    b.p_world.y,
                    b.p_world.z,
                    b.v_world.x,
                    b.v_world.y,
                    b.v_world.z,
                    b.omega_world.z,
                    c.command.vx_mps,
                    c.new_state as u8,
                    c.interventions.len()
                );
            }
        }
    })?;
    let recording = recorder.finish();
    let summary = serde_json::json!({
        "rerun": recording,
        "controller": args.controller,
        "address": args.address.map(|a| a.to_string()),
        "link": link_json(&opts.transport),
        "robot": crate::robot_arg::robot_json(&robot, args.robot.allow_robot_mismatch),
        "dry_run": args.dry_run,
        "rate_hz": args.rate,
        "command": {"vx_mps": args.speed, "vy_mps": args.lateral, "yaw_rate_rps": args.yaw_rate},
        "report": report,
    });
    println!("{}", serde_json::to_string(&summary).expect("serialises"));
    if let Some(dir) = &args.out {
        std::fs::write(
            dir.join("summary.json"),
            serde_json::to_string_pretty(&summary).expect("serialises"),
        )
        .map_err(|e| format!("cannot write summary.json: {e}"))?;
    }
    // A run that never heard from the robot did nothing: say so rather than end as a success.
    if !args.dry_run && report.states == 0 {
        return Err(format!(
            "no valid state arrived from the robot in {} s ({}; {} bad datagrams, {} stale \
             states): is it on, reachable, in low-level mode and of the robot file's kind? \
             (summary.json says what was sent)",
            args.duration,
            link_json(&opts.transport),
            report.bad_datagrams,
            report.stale_states
        ));
    }
    Ok(())
}

#[derive(clap::Args, Debug)]
pub struct SimRobotArgs {
    /// UDP only: address to listen on for command datagrams.
    #[arg(long, default_value = "127.0.0.1:8007")]
    pub bind: SocketAddr,
    /// Simulated seconds before it stops.
    #[arg(long, default_value_t = 60.0)]
    pub duration: f64,
    /// Stop sending states after this many seconds (a frozen state stream).
    #[arg(long)]
    pub freeze_after: Option<f64>,
    #[command(flatten)]
    pub faults: FaultArgs,
    /// Robot description (default: the shipped A1); robots/go2.toml speaks DDS.
    #[arg(long)]
    pub robot: Option<PathBuf>,
    #[command(flatten)]
    pub link: LinkArgs,
    /// DDS only: start in low-level mode, with no motion-switcher service (a Go2 starts in
    /// sport mode and ignores low-level commands until `eemp hw` releases it).
    #[arg(long)]
    pub low_level_mode: bool,
    /// summary.json and truth.csv (100 Hz) go here.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub fn run_sim_robot_cmd(args: &SimRobotArgs) -> Result<(), String> {
    if !(args.duration > 0.0 && args.duration <= 3600.0) {
        return Err(format!(
            "--duration {} is out of range: allowed (0, 3600] s",
            args.duration
        ));
    }
    let robot = crate::robot_arg::load_robot(args.robot.as_deref())?;
    let link = args.link.resolve(&robot, SIM_DOMAIN_ID, Some("lo"))?;
    if link == Resolved::Udp && args.low_level_mode {
        return Err(
            "--low-level-mode is a DDS setting (the A1 has no sport mode to release)".into(),
        );
    }
    // Standing as EEMP starts (Table II's trunk height, feet under the hips).
    let spec = WalkSpec::constant(
        PlannerConfig::default(),
        PlannerParams::default(),
        VelocityCommand::default(),
        args.duration,
    );
    let start = StartPose::eemp(&robot, &spec).map_err(|e| e.to_string())?;
    let wire = match link {
        Resolved::Udp => RobotWire::udp(Link::bind(args.bind, args.faults.faults())?),
        Resolved::Dds(cfg) => RobotWire::dds(&cfg, args.faults.faults(), !args.low_level_mode)?,
    };
    eprintln!(
        "sim-robot '{}' listening on {}",
        robot.name,
        wire.describe()
    );
    let opts = SimRobotOptions {
        duration_s: args.duration,
        state_period_s: 0.002,
        freeze_after_s: args.freeze_after,
        start,
    };
    let report = run_sim_robot(&robot, &opts, wire, &AtomicBool::new(false))?;
    let summary = serde_json::json!({
        "robot": crate::robot_arg::robot_json(&robot, false),
        "steps": report.steps,
        "commands": report.commands,
        "bad_datagrams": report.bad_datagrams,
        "ignored_commands": report.ignored_commands,
        "late_steps": report.late_steps,
        "fell_at_s": report.fell_at_s,
        "link": report.link,
    });
    println!("{}", serde_json::to_string(&summary).expect("serialises"));
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir)
            .map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
        std::fs::write(
            dir.join("summary.json"),
            serde_json::to_string_pretty(&summary).expect("serialises"),
        )
        .map_err(|e| format!("cannot write summary.json: {e}"))?;
        let mut f = std::fs::File::create(dir.join("truth.csv"))
            .map_err(|e| format!("cannot write truth.csv: {e}"))?;
        writeln!(f, "time_s,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps,yaw_rate_rps")
            .map_err(|e| e.to_string())?;
        for r in &report.truth {
            writeln!(
                f,
                "{:.3},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4}",
                r.t_s,
                r.p_world[0],
                r.p_world[1],
                r.p_world[2],
                r.v_world[0],
                r.v_world[1],
                r.v_world[2],
                r.yaw_rate_rps
            )
            .map_err(|e| e.to_string())?;
        }
    }
    Ok(())
}
