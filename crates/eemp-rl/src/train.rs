//! The training loop: rollouts on the vectorised environments, PPO updates, `train.csv`
//! (one row per iteration, flushed), checkpoints every few iterations, resume.
//!
//! Resume equals an uninterrupted run (same seed; the thread count does not matter, the
//! environments are independent and the action noise is drawn on one thread): a checkpoint holds the
//! network, Adam's moments, the normaliser, every RNG and every environment's full state, and
//! rows of `train.csv` after the checkpoint are dropped and rewritten.

use crate::adam::Adam;
use crate::config::{TaskKind, TrainConfig, TrainEstimator};
use crate::env::{Env, VecEnv};
use crate::imitation::motion::ReferenceMotion;
use crate::mirror::MirrorMap;
use crate::nn::gaussian_log_prob;
use crate::policy::{normalizer_from_json, normalizer_to_json, Policy};
use crate::ppo::{update, ActionMirror, Rollout, UpdateStats};
use crate::tasks::cartpole::{cartpole_model, CartPole};
use crate::tasks::eemp_rl::EempRlEnv;
use crate::tasks::imitation::ImitationEnv;
use crate::tasks::model_free::{training_model, ModelFreeEnv};
use crate::tasks::OnClosedLoop;
use crate::tensor_file::TensorFile;
use candle_core::{Device, Tensor};
use eemp_core::robot::RobotConfig;
use eemp_sim::closed_loop::StateSource;
use eemp_sim::sensors::SensorNoise;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

pub struct TrainOptions {
    pub out: PathBuf,
    pub resume: bool,
    pub threads: usize,
    /// Stop after this many iterations in this call (tests; `None`: run to the config's end).
    pub max_iterations: Option<usize>,
}

/// One iteration's log line.
#[derive(Clone, Debug, PartialEq)]
pub struct IterationLog {
    pub iteration: usize,
    pub env_steps: u64,
    pub wall_s: f64,
    /// Mean return of the last (up to) 100 finished episodes.
    pub mean_return: f64,
    pub mean_episode_len: f64,
    pub episodes: usize,
    pub falls: usize,
    pub invalid: usize,
    pub mean_step_reward: f64,
    pub terms: Vec<f64>,
    pub update: UpdateStats,
    pub mean_std: f64,
    pub env_steps_per_s: f64,
    pub total_env_steps: u64,
}

#[derive(Serialize, Deserialize)]
struct RngState {
    seed: Vec<u8>,
    stream: u64,
    word_pos: String,
}

fn rng_save(r: &ChaCha8Rng) -> RngState {
    RngState {
        seed: r.get_seed().to_vec(),
        stream: r.get_stream(),
        word_pos: r.get_word_pos().to_string(),
    }
}

fn rng_load(s: &RngState) -> Result<ChaCha8Rng, String> {
    let seed: [u8; 32] = s
        .seed
        .clone()
        .try_into()
        .map_err(|_| "checkpoint RNG seed is not 32 bytes".to_string())?;
    let mut r = ChaCha8Rng::from_seed(seed);
    r.set_stream(s.stream);
    r.set_word_pos(
        s.word_pos
            .parse()
            .map_err(|_| "checkpoint RNG position is not a number".to_string())?,
    );
    Ok(r)
}

#[derive(Serialize, Deserialize)]
struct CheckpointState {
    config: TrainConfig,
    threads: usize,
    iteration: usize,
    env_steps: u64,
    wall_s: f64,
    adam_step: u64,
    adam_lr: f64,
    normalizer: String,
    rng: RngState,
    env_rngs: Vec<RngState>,
    env_counters: Vec<(f64, usize)>,
    env_states: Vec<serde_json::Value>,
    recent_returns: Vec<f64>,
    recent_lengths: Vec<f64>,
}

/// The environments of a config's task.
pub enum AnyVecEnv {
    ModelFree(VecEnv<ModelFreeEnv>),
    /// With the reference motion file's text (stored in the policy).
    Imitation(VecEnv<ImitationEnv>, String),
    EempRl(VecEnv<EempRlEnv>),
    CartPole(VecEnv<CartPole>),
}

/// Reads and checks an imitation task's reference motion: (motion, file text).
pub fn load_motion(path: &Path, robot: &RobotConfig) -> Result<(ReferenceMotion, String), String> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| format!("cannot read motion file {}: {e}", path.display()))?;
    parse_motion(path, text, robot)
}

/// Checks a reference motion's text (named `path` in messages) against the robot.
pub fn parse_motion(
    path: &Path,
    text: String,
    robot: &RobotConfig,
) -> Result<(ReferenceMotion, String), String> {
    let motion = ReferenceMotion::parse(path, &text).map_err(|e| e.to_string())?;
    motion
        .check_against(&eemp_core::kinematics::LegKinematics::new(robot), path)
        .map_err(|e| e.to_string())?;
    Ok((motion, text))
}

/// The environments of a config's task; an imitation task reads `imitation.motion_file`.
pub fn make_envs(
    config: &TrainConfig,
    robot: &RobotConfig,
    threads: usize,
) -> Result<AnyVecEnv, String> {
    make_envs_with(config, robot, threads, None)
}

/// `n` environments from `make`, environment i on `source(i)`.
fn envs_on<E: OnClosedLoop>(
    n: usize,
    make: impl Fn() -> Result<E, String>,
    source: &dyn Fn(usize) -> StateSource,
) -> Result<Vec<E>, String> {
    (0..n)
        .map(|i| {
            let mut e = make()?;
            e.set_state_source(&source(i))?;
            Ok(e)
        })
        .collect()
}

/// What environment `i` of a run observes: ground truth, or the filter with its own sensor noise
/// seeded from the config's seed and `i`.
pub fn training_state_source(config: &TrainConfig, robot: &RobotConfig, i: u64) -> StateSource {
    match config.estimator {
        TrainEstimator::GroundTruth => StateSource::GroundTruth,
        TrainEstimator::Kf => {
            let mut source = StateSource::kf(
                robot,
                SensorNoise::default(),
                config.seed.wrapping_mul(0x9E37_79B9).wrapping_add(i),
            );
            if let Some(kf) = source.kf_config_mut() {
                config.kf.apply(kf);
            }
            source
        }
    }
}

/// [`make_envs`] with an imitation task's motion given (as [`parse_motion`] returns it) instead
/// of read from the config's file.
pub fn make_envs_with(
    config: &TrainConfig,
    robot: &RobotConfig,
    threads: usize,
    motion: Option<(ReferenceMotion, String)>,
) -> Result<AnyVecEnv, String> {
    let source = |i: usize| training_state_source(config, robot, i as u64);
    Ok(match config.task {
        TaskKind::ModelFree => {
            // Friction randomisation: environment i on floor i mod n of the listed frictions.
            let frictions = &config.model_free.floor_frictions;
            let models = match frictions.is_empty() {
                true => vec![training_model(robot, &config.model_free)?],
                false => frictions
                    .iter()
                    .map(|&mu| {
                        let mut r = robot.clone();
                        r.simulation.floor_friction = mu;
                        training_model(&r, &config.model_free)
                    })
                    .collect::<Result<Vec<_>, _>>()?,
            };
            let next = std::cell::Cell::new(0usize);
            let envs = envs_on(
                config.num_envs,
                || {
                    let i = next.replace(next.get() + 1);
                    let model = models[i % models.len()].clone();
                    ModelFreeEnv::new(robot, model, config.model_free.clone())
                },
                &source,
            )?;
            AnyVecEnv::ModelFree(VecEnv::new(envs, config.seed, threads)?)
        }
        TaskKind::Imitation => {
            let c = &config.imitation;
            let (motion, text) = match motion {
                Some(m) => m,
                None => load_motion(Path::new(&c.motion_file), robot)?,
            };
            let mut r = robot.clone();
            r.simulation.timestep_s = c.train_timestep_s;
            let model = eemp_sim::backend::build_model(&r, &Default::default())
                .map_err(|e| e.to_string())?;
            let envs = envs_on(
                config.num_envs,
                || ImitationEnv::new(robot, model.clone(), c.clone(), &motion),
                &source,
            )?;
            AnyVecEnv::Imitation(VecEnv::new(envs, config.seed, threads)?, text)
        }
        TaskKind::EempRl => {
            // EEMP runs at the robot file's time step (its MPC and swing law are tuned there).
            let model = eemp_sim::backend::build_model(robot, &Default::default())
                .map_err(|e| e.to_string())?;
            // Training worlds: each env its own floor and payload, drawn from the run's seed.
            let next = std::cell::Cell::new(0usize);
            let envs = envs_on(
                config.num_envs,
                || {
                    let i = next.replace(next.get() + 1);
                    match &config.eemp_rl.worlds {
                        Some(w) => EempRlEnv::in_world(
                            robot,
                            &w.draw(config.seed, i),
                            config.eemp_rl.clone(),
                        ),
                        None => EempRlEnv::new(robot, model.clone(), config.eemp_rl.clone()),
                    }
                },
                &source,
            )?;
            AnyVecEnv::EempRl(VecEnv::new(envs, config.seed, threads)?)
        }
        TaskKind::CartPole => {
            let model = cartpole_model()?;
            let envs = (0..config.num_envs)
                .map(|_| CartPole::new(model.clone(), config.cart_pole.clone()))
                .collect();
            AnyVecEnv::CartPole(VecEnv::new(envs, config.seed, threads)?)
        }
    })
}

/// Trains (or resumes) a policy; `on_iteration` sees every log line. Returns the final policy.
pub fn train(
    config: &TrainConfig,
    robot: &RobotConfig,
    opts: &TrainOptions,
    on_iteration: &mut dyn FnMut(&IterationLog),
) -> Result<Policy, String> {
    config.validate().map_err(|e| e.to_string())?;
    let id = robot.id();
    match make_envs(config, robot, opts.threads)? {
        AnyVecEnv::ModelFree(v) => Trainer::new(config, v, None, opts)?
            .stamped(id)?
            .run(opts, on_iteration),
        AnyVecEnv::Imitation(v, m) => Trainer::new(config, v, Some(m), opts)?
            .stamped(id)?
            .run(opts, on_iteration),
        AnyVecEnv::EempRl(v) => Trainer::new(config, v, None, opts)?
            .stamped(id)?
            .run(opts, on_iteration),
        AnyVecEnv::CartPole(v) => Trainer::new(config, v, None, opts)?
            .stamped(id)?
            .run(opts, on_iteration),
    }
}

struct Trainer<E: Env> {
    config: TrainConfig,
    envs: VecEnv<E>,
    policy: Policy,
    adam: Adam,
    rng: ChaCha8Rng,
    iteration: usize,
    env_steps: u64,
    wall_before_s: f64,
    recent_returns: VecDeque<f64>,
    recent_lengths: VecDeque<f64>,
    threads: usize,
    /// With the mirror loss: the observation's mirror and the action's.
    mirror: Option<(MirrorMap, ActionMirror)>,
}

const CSV_HEADER: [&str; 20] = [
    "iteration",
    "env_steps",
    "wall_s",
    "mean_return",
    "mean_episode_len",
    "episodes",
    "falls",
    "invalid_episodes",
    "mean_step_reward",
    "policy_loss",
    "value_loss",
    "kl",
    "entropy",
    "learning_rate",
    "clip_fraction",
    "grad_norm",
    "mean_std",
    "env_steps_per_s",
    "total_env_steps",
    "symmetry_loss",
];

/// Whether a run with config `new` may continue a checkpoint of a run with config `old`: the
/// same config, or one that only trains for longer. Nothing but a linear learning-rate schedule
/// depends on the total, so the longer run's first iterations are the shorter run's.
fn extends(old: &TrainConfig, new: &TrainConfig) -> bool {
    let same_but_total = TrainConfig {
        total_env_steps: new.total_env_steps,
        ..old.clone()
    };
    same_but_total == *new
        && (old.total_env_steps == new.total_env_steps
            || (new.total_env_steps > old.total_env_steps
                && new.ppo.lr_schedule != crate::config::LrSchedule::Linear))
}

fn checkpoint_dir(out: &Path) -> PathBuf {
    out.join("checkpoint")
}

impl<E: Env> Trainer<E> {
    fn new(
        config: &TrainConfig,
        envs: VecEnv<E>,
        motion: Option<String>,
        opts: &TrainOptions,
    ) -> Result<Self, String> {
        let mut policy = Policy::new(config)?;
        policy.motion = motion;
        let mirror = if config.ppo.symmetry_coef > 0.0 {
            let named =
                |e: String| format!("ppo.symmetry_coef = {}: {e}", config.ppo.symmetry_coef);
            let (obs_map, act_map) = envs.mirror_maps().map_err(named)?;
            obs_map
                .check_width(envs.obs_dim(), "the observation")
                .map_err(named)?;
            act_map
                .check_width(envs.act_dim(), "the action")
                .map_err(named)?;
            let am = ActionMirror::new(&act_map).map_err(|e| e.to_string())?;
            Some((obs_map, am))
        } else {
            None
        };
        let adam =
            Adam::new(policy.net.vars(), config.ppo.learning_rate).map_err(|e| e.to_string())?;
        let mut t = Trainer {
            config: config.clone(),
            envs,
            policy,
            adam,
            rng: ChaCha8Rng::seed_from_u64(config.seed ^ 0x00AC_7105),
            iteration: 0,
            env_steps: 0,
            wall_before_s: 0.0,
            recent_returns: VecDeque::new(),
            recent_lengths: VecDeque::new(),
            threads: opts.threads,
            mirror,
        };
        if opts.resume && checkpoint_dir(&opts.out).join("state.json").exists() {
            t.load_checkpoint(&checkpoint_dir(&opts.out))?;
        } else {
            if opts.resume {
                eprintln!(
                    "note: no checkpoint in {}; starting from scratch",
                    opts.out.display()
                );
            }
            if let Some(path) = &config.init_policy {
                t.start_from(path)?;
            }
        }
        Ok(t)
    }

    /// The policy records the robot it is trained on; a checkpoint made on another robot is
    /// refused (its stamp survives the resume).
    fn stamped(mut self, robot: eemp_core::robot::RobotId) -> Result<Self, String> {
        if let Some(theirs) = &self.policy.robot {
            if *theirs != robot {
                return Err(format!(
                    "the checkpoint was trained on robot '{}' (physics {}), not on '{}' \
                     (physics {}); resume with its robot file or use another --out",
                    theirs.name, theirs.physics_hash, robot.name, robot.physics_hash
                ));
            }
        }
        self.policy.robot = Some(robot);
        Ok(self)
    }

    /// Fine-tuning ([`TrainConfig::init_policy`]): the networks, log-std and normaliser of a
    /// policy file of the same task and shapes.
    fn start_from(&mut self, path: &Path) -> Result<(), String> {
        let mut p = Policy::load(path, Some(self.config.task))?;
        // A fine-tune starts a new run: it takes the robot it trains on (transfer is allowed).
        p.robot = None;
        if adds_gait_clock(&p.config, &self.config) {
            p = p.with_appended_inputs(self.policy.net.obs_dim())?;
        }
        let (ours, theirs) = (self.policy.net.vars(), p.net.vars());
        let shapes = |v: &[candle_core::Var]| -> Vec<Vec<usize>> {
            v.iter().map(|x| x.dims().to_vec()).collect()
        };
        if shapes(&ours) != shapes(&theirs) {
            return Err(format!(
                "init_policy {}: its networks ({:?}) are not this config's ({:?})",
                path.display(),
                shapes(&theirs),
                shapes(&ours)
            ));
        }
        for (dst, src) in ours.iter().zip(theirs) {
            dst.set(src.as_tensor()).map_err(|e| e.to_string())?;
        }
        self.policy.normalizer = p.normalizer;
        Ok(())
    }

    fn total_iterations(&self) -> usize {
        let per = (self.config.num_envs * self.config.steps_per_env) as u64;
        self.config.total_env_steps.div_ceil(per) as usize
    }

    fn run(
        mut self,
        opts: &TrainOptions,
        on_iteration: &mut dyn FnMut(&IterationLog),
    ) -> Result<Policy, String> {
        std::fs::create_dir_all(&opts.out)
            .map_err(|e| format!("cannot create {}: {e}", opts.out.display()))?;
        let mut csv = self.open_csv(&opts.out.join("train.csv"))?;
        let total = self.total_iterations();
        let mut done_here = 0;
        while self.iteration < total && opts.max_iterations.is_none_or(|m| done_here < m) {
            let log = self.iterate()?;
            write_row(&mut csv, &log, self.envs.reward_terms().len())?;
            on_iteration(&log);
            done_here += 1;
            if self.iteration.is_multiple_of(self.config.checkpoint_every)
                || self.iteration == total
            {
                self.save_checkpoint(&checkpoint_dir(&opts.out))?;
                self.policy.save(&opts.out.join("policy.safetensors"))?;
            }
        }
        std::fs::write(
            opts.out.join("config.toml"),
            toml::to_string(&self.config).map_err(|e| e.to_string())?,
        )
        .map_err(|e| format!("cannot write config.toml: {e}"))?;
        Ok(self.policy)
    }

    fn open_csv(&self, path: &Path) -> Result<std::fs::File, String> {
        let terms = self.envs.reward_terms();
        let mut header: Vec<String> = CSV_HEADER.iter().map(|s| s.to_string()).collect();
        header.extend(terms.iter().map(|t| format!("reward_{t}")));
        let header = header.join(",");
        // Keep the rows up to the checkpoint's iteration: later ones are recomputed.
        let mut kept = vec![header.clone()];
        if self.iteration > 0 {
            if let Ok(text) = std::fs::read_to_string(path) {
                let mut lines = text.lines();
                if lines.next() == Some(header.as_str()) {
                    kept.extend(
                        lines
                            .filter(|l| {
                                l.split(',')
                                    .next()
                                    .and_then(|i| i.parse::<usize>().ok())
                                    .is_some_and(|i| i <= self.iteration)
                            })
                            .map(|l| l.to_string()),
                    );
                }
            }
        }
        let mut f = std::fs::File::create(path)
            .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        for l in kept {
            writeln!(f, "{l}").map_err(|e| e.to_string())?;
        }
        Ok(f)
    }

    fn iterate(&mut self) -> Result<IterationLog, String> {
        let started = Instant::now();
        let (n, d, a) = (self.envs.len(), self.envs.obs_dim(), self.envs.act_dim());
        let k = self.envs.reward_terms().len();
        let cfg = self.config.clone();
        let mut rollout = Rollout::new(n, d, a);
        rollout.log_std = self
            .policy
            .net
            .log_std
            .as_tensor()
            .to_vec1()
            .map_err(|e| e.to_string())?;
        let std = self.policy.net.std().map_err(|e| e.to_string())?;
        let mut raw_all: Vec<f32> = Vec::with_capacity(cfg.steps_per_env * n * d);
        let mut term_sums = vec![0f64; k];
        let mut reward_sum = 0f64;
        let (mut episodes, mut falls, mut invalid) = (0, 0, 0);
        let mut obs_n = vec![0f32; n * d];
        let mut actions = vec![0f32; n * a];
        for _ in 0..cfg.steps_per_env {
            raw_all.extend_from_slice(&self.envs.obs);
            self.policy.normalizer.apply(&self.envs.obs, &mut obs_n);
            let x =
                Tensor::from_vec(obs_n.clone(), (n, d), &Device::Cpu).map_err(|e| e.to_string())?;
            let mean: Vec<f32> = self
                .policy
                .net
                .mean(&x)
                .and_then(|m| m.flatten_all())
                .and_then(|m| m.to_vec1())
                .map_err(|e| e.to_string())?;
            let values: Vec<f32> = values_of(&self.policy, &x)?;
            if mean.iter().chain(&values).any(|v| !v.is_finite()) {
                return Err(format!(
                    "the network produced a non-finite action or value at iteration {}; \
                     stopping before anything is saved (the last checkpoint is intact)",
                    self.iteration + 1
                ));
            }
            for i in 0..n * a {
                let z: f64 = self.rng.sample(StandardNormal);
                actions[i] = mean[i] + std[i % a] * z as f32;
            }
            for e in 0..n {
                rollout.log_probs.push(gaussian_log_prob(
                    &actions[e * a..(e + 1) * a],
                    &mean[e * a..(e + 1) * a],
                    &std,
                ) as f32);
            }
            rollout.obs.extend_from_slice(&obs_n);
            rollout.actions.extend_from_slice(&actions);
            rollout.means.extend_from_slice(&mean);
            rollout.values.extend_from_slice(&values);
            self.envs.step(&actions);
            // Time-limit truncation: the return continues past the limit, so bootstrap γ·V(s_T).
            let truncated: Vec<usize> = (0..n).filter(|&e| self.envs.infos[e].truncated).collect();
            let mut bootstrap = vec![0f32; n];
            if !truncated.is_empty() {
                let mut fo = Vec::with_capacity(truncated.len() * d);
                for &e in &truncated {
                    fo.extend_from_slice(&self.envs.final_obs[e * d..(e + 1) * d]);
                }
                let mut fon = vec![0f32; fo.len()];
                self.policy.normalizer.apply(&fo, &mut fon);
                let t = Tensor::from_vec(fon, (truncated.len(), d), &Device::Cpu)
                    .map_err(|e| e.to_string())?;
                let v: Vec<f32> = values_of(&self.policy, &t)?;
                for (j, &e) in truncated.iter().enumerate() {
                    let gamma = match self.envs.infos[e].periods {
                        Some(k) => cfg.ppo.gamma.powf(k),
                        None => cfg.ppo.gamma,
                    };
                    bootstrap[e] = (gamma as f32) * v[j];
                }
            }
            let semi_mdp = self.envs.infos.iter().any(|i| i.periods.is_some());
            if semi_mdp && rollout.periods.is_empty() {
                rollout.periods = vec![1.0; rollout.rewards.len()];
            }
            for e in 0..n {
                let info = self.envs.infos[e];
                rollout.rewards.push(info.reward as f32 + bootstrap[e]);
                rollout.dones.push(info.terminated || info.truncated);
                if semi_mdp || !rollout.periods.is_empty() {
                    rollout.periods.push(info.periods.unwrap_or(1.0) as f32);
                }
                reward_sum += info.reward;
            }
            for (s, t) in term_sums.iter_mut().zip(self.envs.terms.chunks(k).fold(
                vec![0f64; k],
                |mut acc, row| {
                    acc.iter_mut().zip(row).for_each(|(a, r)| *a += r);
                    acc
                },
            )) {
                *s += t;
            }
            for end in &self.envs.ended {
                episodes += 1;
                falls += end.fell as usize;
                invalid += end.invalid as usize;
                self.recent_returns.push_back(end.episode_return);
                self.recent_lengths.push_back(end.length as f64);
                if self.recent_returns.len() > 100 {
                    self.recent_returns.pop_front();
                    self.recent_lengths.pop_front();
                }
            }
        }
        self.policy.normalizer.apply(&self.envs.obs, &mut obs_n);
        let x = Tensor::from_vec(obs_n, (n, d), &Device::Cpu).map_err(|e| e.to_string())?;
        let last_values: Vec<f32> = values_of(&self.policy, &x)?;
        if let Some((obs_map, _)) = &self.mirror {
            // The normaliser is the one the rollout ran with (it is updated after the update).
            let mirrored = obs_map.apply_rows(&raw_all);
            rollout.obs_mirrored = vec![0f32; mirrored.len()];
            self.policy
                .normalizer
                .apply(&mirrored, &mut rollout.obs_mirrored);
        }
        let progress = self.iteration as f64 / self.total_iterations().max(1) as f64;
        let stats = update(
            &self.policy.net,
            &mut self.adam,
            &cfg.ppo,
            &rollout,
            &last_values,
            progress,
            self.mirror.as_ref().map(|(_, am)| am),
            &mut self.rng,
        )
        .map_err(|e| e.to_string())?;
        self.policy.normalizer.update(&raw_all);
        self.iteration += 1;
        let steps = (cfg.steps_per_env * n) as u64;
        self.env_steps += steps;
        let dt = started.elapsed().as_secs_f64();
        self.wall_before_s += dt;
        let samples = (cfg.steps_per_env * n) as f64;
        let mean = |v: &VecDeque<f64>| {
            if v.is_empty() {
                f64::NAN
            } else {
                v.iter().sum::<f64>() / v.len() as f64
            }
        };
        let std_now = self.policy.net.std().map_err(|e| e.to_string())?;
        Ok(IterationLog {
            iteration: self.iteration,
            env_steps: self.env_steps,
            wall_s: self.wall_before_s,
            mean_return: mean(&self.recent_returns),
            mean_episode_len: mean(&self.recent_lengths),
            episodes,
            falls,
            invalid,
            mean_step_reward: reward_sum / samples,
            terms: term_sums.iter().map(|s| s / samples).collect(),
            update: stats,
            mean_std: std_now.iter().map(|&s| s as f64).sum::<f64>() / std_now.len() as f64,
            env_steps_per_s: steps as f64 / dt,
            total_env_steps: self.config.total_env_steps,
        })
    }

    fn save_checkpoint(&self, dir: &Path) -> Result<(), String> {
        std::fs::create_dir_all(dir)
            .map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
        let mut f = self.policy.to_file()?;
        for (i, (m, v)) in self.adam.m.iter().zip(&self.adam.v).enumerate() {
            f.insert_tensor(&format!("adam.m.{i}"), m)
                .map_err(|e| e.to_string())?;
            f.insert_tensor(&format!("adam.v.{i}"), v)
                .map_err(|e| e.to_string())?;
        }
        f.metadata
            .insert("iteration".into(), self.iteration.to_string());
        f.save(&dir.join("learner.safetensors"))?;
        let state = CheckpointState {
            config: self.config.clone(),
            threads: self.threads,
            iteration: self.iteration,
            env_steps: self.env_steps,
            wall_s: self.wall_before_s,
            adam_step: self.adam.step,
            adam_lr: self.adam.lr,
            normalizer: normalizer_to_json(&self.policy.normalizer),
            rng: rng_save(&self.rng),
            env_rngs: self.envs.rngs().iter().map(rng_save).collect(),
            env_counters: self.envs.episode_counters(),
            env_states: self.envs.env_states(),
            recent_returns: self.recent_returns.iter().copied().collect(),
            recent_lengths: self.recent_lengths.iter().copied().collect(),
        };
        let tmp = dir.join("state.json.tmp");
        std::fs::write(&tmp, serde_json::to_vec(&state).map_err(|e| e.to_string())?)
            .map_err(|e| format!("cannot write {}: {e}", tmp.display()))?;
        std::fs::rename(&tmp, dir.join("state.json")).map_err(|e| e.to_string())
    }

    fn load_checkpoint(&mut self, dir: &Path) -> Result<(), String> {
        let path = dir.join("state.json");
        let text = std::fs::read_to_string(&path)
            .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
        let s: CheckpointState = serde_json::from_str(&text)
            .map_err(|e| format!("{} is malformed: {e}", path.display()))?;
        if !extends(&s.config, &self.config) {
            return Err(format!(
                "{} was written by a run with another config; resume with the same config \
                 (or one that only raises total_env_steps, without a linear learning-rate \
                 schedule), or train into another --out",
                path.display()
            ));
        }
        let lpath = dir.join("learner.safetensors");
        let f = TensorFile::load(&lpath)?;
        if f.meta(&lpath, "iteration")? != s.iteration.to_string() {
            return Err(format!(
                "{} is of iteration {} but {} of iteration {}: the run was killed while \
                 checkpointing; restart it without --resume",
                lpath.display(),
                f.meta(&lpath, "iteration")?,
                path.display(),
                s.iteration
            ));
        }
        let p = Policy::from_file(&lpath, &f, Some(self.config.task))?;
        self.policy.robot = p.robot.clone();
        for (dst, src) in self.policy.net.vars().iter().zip(p.net.vars()) {
            dst.set(src.as_tensor()).map_err(|e| e.to_string())?;
        }
        for i in 0..self.adam.m.len() {
            let shape = self.adam.m[i].dims().to_vec();
            self.adam.m[i] = f.tensor(&lpath, &format!("adam.m.{i}"), &shape)?;
            self.adam.v[i] = f.tensor(&lpath, &format!("adam.v.{i}"), &shape)?;
        }
        self.adam.step = s.adam_step;
        self.adam.lr = s.adam_lr;
        self.policy.normalizer = normalizer_from_json(&s.normalizer)?;
        self.rng = rng_load(&s.rng)?;
        let rngs = s
            .env_rngs
            .iter()
            .map(rng_load)
            .collect::<Result<Vec<_>, _>>()?;
        self.envs.restore(rngs, &s.env_counters, &s.env_states)?;
        self.iteration = s.iteration;
        self.env_steps = s.env_steps;
        self.wall_before_s = s.wall_s;
        self.recent_returns = s.recent_returns.into();
        self.recent_lengths = s.recent_lengths.into();
        Ok(())
    }
}

/// V(o) for a batch of normalised observations.
fn values_of(policy: &Policy, x: &Tensor) -> Result<Vec<f32>, String> {
    policy
        .net
        .value(x)
        .and_then(|v| v.to_vec1())
        .map_err(|e| e.to_string())
}

fn write_row(f: &mut std::fs::File, l: &IterationLog, n_terms: usize) -> Result<(), String> {
    let u = &l.update;
    let mut cols = vec![
        l.iteration.to_string(),
        l.env_steps.to_string(),
        format!("{:.3}", l.wall_s),
        format!("{}", l.mean_return),
        format!("{}", l.mean_episode_len),
        l.episodes.to_string(),
        l.falls.to_string(),
        l.invalid.to_string(),
        format!("{}", l.mean_step_reward),
        format!("{}", u.policy_loss),
        format!("{}", u.value_loss),
        format!("{}", u.kl),
        format!("{}", u.entropy),
        format!("{}", u.learning_rate),
        format!("{}", u.clip_fraction),
        format!("{}", u.grad_norm),
        format!("{}", l.mean_std),
        format!("{:.1}", l.env_steps_per_s),
        l.total_env_steps.to_string(),
        format!("{}", u.symmetry_loss),
    ];
    cols.extend(l.terms.iter().take(n_terms).map(|t| format!("{t}")));
    writeln!(f, "{}", cols.join(",")).map_err(|e| format!("cannot write train.csv: {e}"))?;
    f.flush().map_err(|e| e.to_string())
}

/// A model-free fine-tune that adds a gait clock (`extra_obs.gait_clock_hz` 0 → > 0) to an
/// otherwise equal observation: the clock is appended last, so the init policy's inputs are
/// a prefix of the new ones.
fn adds_gait_clock(init: &TrainConfig, ours: &TrainConfig) -> bool {
    let (a, b) = (&init.model_free, &ours.model_free);
    let mut a_extra = a.extra_obs.clone();
    a_extra.gait_clock_hz = b.extra_obs.gait_clock_hz;
    init.task == TaskKind::ModelFree
        && ours.task == TaskKind::ModelFree
        && a.extra_obs.gait_clock_hz == 0.0
        && b.extra_obs.gait_clock_hz > 0.0
        && a.history == b.history
        && a_extra == b.extra_obs
}
