//! `eemp bench rl`: the learned-controller pipeline's speed, all measured in one run:
//! environment stepping (random actions) on 1 thread and on all, full training (rollouts +
//! PPO updates), and bare MuJoCo steps of the same model *from the same states* the envs
//! visited (a falling, flailing robot costs MuJoCo more than a standing one, so a bare step on a
//! calm robot would flatter nothing but the ratio), with the ratios the targets use.

use eemp_core::joint_pd::pd_torques;
use eemp_core::robot::RobotConfig;
use eemp_rl::config::TrainConfig;
use eemp_rl::env::VecEnv;
use eemp_rl::tasks::model_free::{joint_targets, training_model, ModelFreeEnv};
use eemp_rl::train::{train, TrainOptions};
use eemp_sim::backend::SimSnapshot;
use eemp_sim::Simulation;
use std::time::Instant;

pub struct RlBenchOptions {
    pub num_envs: usize,
    /// Policy steps per env for each stepping measurement.
    pub steps: usize,
    /// Training iterations for the training measurement.
    pub train_iterations: usize,
    pub threads: usize,
    /// Hidden layers of actor and critic.
    pub hidden: Vec<usize>,
    pub robot: RobotConfig,
}

pub struct RlBenchReport {
    pub rows: Vec<(String, f64, String)>,
    pub env_steps_per_s: f64,
    pub env_steps_per_s_1: f64,
    pub train_steps_per_s: f64,
    pub bare_substeps_per_s: f64,
    pub substeps_per_env_step: usize,
}

/// Env steps per second with uniform random actions; with `record`, the simulator state of
/// every env before every step and the action it got (to replay the very same MuJoCo steps).
fn env_rate(
    config: &TrainConfig,
    robot: &RobotConfig,
    o: &RlBenchOptions,
    threads: usize,
    record: Option<&mut Vec<(SimSnapshot, Vec<f32>)>>,
) -> Result<f64, String> {
    let model = training_model(robot, &config.model_free)?;
    let envs = (0..o.num_envs)
        .map(|_| ModelFreeEnv::new(robot, model.clone(), config.model_free.clone()))
        .collect::<Result<Vec<_>, _>>()?;
    let mut v = VecEnv::new(envs, 7, threads)?;
    let actions = eemp_rl::env::random_actions(v.len() * v.act_dim(), o.steps, 3);
    let Some(record) = record else {
        return Ok(eemp_rl::env::stepping_rate(&mut v, &actions));
    };
    let mut elapsed = 0.0;
    for a in &actions {
        let act = v.act_dim();
        record.extend(
            v.envs()
                .enumerate()
                .map(|(i, e)| (e.sim().snapshot(), a[i * act..(i + 1) * act].to_vec())),
        );
        let t = Instant::now();
        v.step(a);
        elapsed += t.elapsed().as_secs_f64();
    }
    Ok((o.steps * v.len()) as f64 / elapsed)
}

pub fn bench_rl(o: &RlBenchOptions) -> Result<RlBenchReport, String> {
    let robot = o.robot.clone();
    let mut config = TrainConfig {
        num_envs: o.num_envs,
        ..Default::default()
    };
    config.network.actor_hidden = o.hidden.clone();
    config.network.critic_hidden = o.hidden.clone();
    let substeps =
        (config.model_free.policy_period_s / config.model_free.train_timestep_s).round() as usize;
    let mut states = Vec::new();
    let one = env_rate(&config, &robot, o, 1, Some(&mut states))?;
    let all = env_rate(&config, &robot, o, o.threads, None)?;
    // Bare MuJoCo: mj_step alone, `substeps` of them from each state the envs visited, with the
    // joint PD's torques for the action they got (so MuJoCo does the same work as in the env:
    // the PD's changing torques cost its solver more iterations than constant ones).
    let model = training_model(&robot, &config.model_free)?;
    let mut sim = Simulation::with_model(model, &robot).map_err(|e| e.to_string())?;
    let q0 = robot.standing_pose();
    let mf = &config.model_free;
    let mut bare_time = 0.0;
    for (s, action) in &states {
        sim.restore(s).map_err(|e| e.to_string())?;
        let targets = joint_targets(mf, &q0, action);
        let t = Instant::now();
        for _ in 0..substeps {
            let st = sim.ground_truth_state();
            let tau = pd_torques(
                &mf.pd,
                &targets,
                &st.joints.map(|_, j| j.q),
                &st.joints.map(|_, j| j.qd),
                robot.leg.torque_limit_nm,
            );
            sim.step_bare(&tau);
        }
        bare_time += t.elapsed().as_secs_f64();
    }
    let bare = (states.len() * substeps) as f64 / bare_time;
    let dir = tempfile_dir()?;
    let train_cfg = TrainConfig {
        total_env_steps: (o.num_envs * config.steps_per_env * o.train_iterations) as u64,
        checkpoint_every: 1_000_000,
        ..config.clone()
    };
    let t = Instant::now();
    train(
        &train_cfg,
        &robot,
        &TrainOptions {
            out: dir.clone(),
            resume: false,
            threads: o.threads,
            max_iterations: None,
        },
        &mut |_| {},
    )?;
    let train_rate = train_cfg.total_env_steps as f64 / t.elapsed().as_secs_f64();
    let _ = std::fs::remove_dir_all(&dir);
    let rows = vec![
        (
            "bare MuJoCo substep (training model, the envs' own states)".into(),
            1e6 / bare,
            "µs".into(),
        ),
        ("env stepping, 1 thread".into(), one, "env steps/s".into()),
        (
            format!("env stepping, {} threads", o.threads),
            all,
            "env steps/s".into(),
        ),
        (
            format!(
                "training (rollouts + PPO), {} threads, {} envs × {} steps, networks {:?}",
                o.threads, o.num_envs, config.steps_per_env, o.hidden
            ),
            train_rate,
            "env steps/s".into(),
        ),
    ];
    Ok(RlBenchReport {
        rows,
        env_steps_per_s: all,
        env_steps_per_s_1: one,
        train_steps_per_s: train_rate,
        bare_substeps_per_s: bare,
        substeps_per_env_step: substeps,
    })
}

fn tempfile_dir() -> Result<std::path::PathBuf, String> {
    let d = std::env::temp_dir().join(format!("eemp-bench-rl-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).map_err(|e| e.to_string())?;
    Ok(d)
}

impl RlBenchReport {
    /// Time of one env step (1 thread) over the time of its bare substeps.
    pub fn env_cost_ratio(&self) -> f64 {
        (1.0 / self.env_steps_per_s_1)
            / (self.substeps_per_env_step as f64 / self.bare_substeps_per_s)
    }

    pub fn table(&self) -> String {
        let mut s = String::from("| measurement | value | unit |\n|---|---|---|\n");
        for (name, v, unit) in &self.rows {
            s += &format!("| {name} | {v:.1} | {unit} |\n");
        }
        s
    }

    pub fn json_line(&self) -> String {
        serde_json::json!({
            "env_steps_per_s": self.env_steps_per_s,
            "train_steps_per_s": self.train_steps_per_s,
            "bare_substeps_per_s": self.bare_substeps_per_s,
            "env_cost_ratio": self.env_cost_ratio(),
            "train_fraction": self.train_steps_per_s / self.env_steps_per_s,
            "scaling_2_over_1": self.env_steps_per_s / self.env_steps_per_s_1,
        })
        .to_string()
    }
}
