//! Training configuration: one TOML file, every field with a default, a unit and a range.

use crate::tasks::cartpole::CartPoleConfig;
use crate::tasks::eemp_rl::EempRlConfig;
use crate::tasks::imitation::ImitationConfig;
use crate::tasks::model_free::ModelFreeConfig;
use eemp_core::config_error::{check_range, ConfigError};
use serde::{Deserialize, Serialize};

/// Which task a run trains (and which a policy file is for).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TaskKind {
    /// The paper's model-free RL baseline (Sec. II-C): joint targets from proprioception.
    ModelFree,
    /// The paper's motion-imitation baseline: joint targets about a retargeted dog gait.
    Imitation,
    /// EEMP-RL: the planner's five parameters chosen by the policy.
    EempRl,
    /// A MuJoCo cart-pole the project builds: PPO's own test task.
    CartPole,
}

impl TaskKind {
    pub fn name(self) -> &'static str {
        match self {
            TaskKind::ModelFree => "model-free",
            TaskKind::Imitation => "imitation",
            TaskKind::EempRl => "eemp-rl",
            TaskKind::CartPole => "cart-pole",
        }
    }
}

impl std::str::FromStr for TaskKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "model-free" => Ok(TaskKind::ModelFree),
            "imitation" => Ok(TaskKind::Imitation),
            "eemp-rl" => Ok(TaskKind::EempRl),
            "cart-pole" => Ok(TaskKind::CartPole),
            other => Err(format!(
                "unknown task '{other}': allowed model-free, imitation, eemp-rl, cart-pole"
            )),
        }
    }
}

/// How the learning rate moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LrSchedule {
    Constant,
    /// rsl_rl's rule: ÷1.5 when the KL of a minibatch exceeds 2·desired_kl, ×1.5 below half.
    Adaptive,
    /// Linear decay to lr_min over the run.
    Linear,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PpoConfig {
    /// Discount per policy step.
    pub gamma: f64,
    /// GAE λ.
    pub lambda: f64,
    /// Clip range ε of the probability ratio (and of the value change).
    pub clip: f64,
    pub epochs: usize,
    pub minibatches: usize,
    pub learning_rate: f64,
    pub lr_schedule: LrSchedule,
    pub desired_kl: f64,
    pub lr_min: f64,
    pub lr_max: f64,
    pub entropy_coef: f64,
    pub value_coef: f64,
    pub clip_value_loss: bool,
    pub max_grad_norm: f64,
    /// Initial standard deviation of the Gaussian policy (action units).
    pub init_std: f64,
    /// Lower bound of the standard deviation, enforced after every optimiser step.
    pub min_std: f64,
    /// Weight of the left–right mirror loss (`crate::mirror`; rsl_rl's mirror loss, Mittal et
    /// al. 2024); 0: off. Only for tasks with a mirror (model-free).
    pub symmetry_coef: f64,
}

impl Default for PpoConfig {
    /// rsl_rl's legged_gym settings (see rl-recipes-notes.md §1b).
    fn default() -> Self {
        PpoConfig {
            gamma: 0.99,
            lambda: 0.95,
            clip: 0.2,
            epochs: 5,
            minibatches: 4,
            learning_rate: 1e-3,
            lr_schedule: LrSchedule::Adaptive,
            desired_kl: 0.01,
            lr_min: 1e-5,
            lr_max: 1e-2,
            entropy_coef: 0.01,
            value_coef: 1.0,
            clip_value_loss: true,
            max_grad_norm: 1.0,
            init_std: 1.0,
            min_std: 0.05,
            symmetry_coef: 0.0,
        }
    }
}

impl PpoConfig {
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range("ppo.gamma", self.gamma, 0.0, 1.0)?;
        check_range("ppo.lambda", self.lambda, 0.0, 1.0)?;
        check_range("ppo.clip", self.clip, 0.01, 1.0)?;
        check_range("ppo.epochs", self.epochs as f64, 1.0, 100.0)?;
        check_range("ppo.minibatches", self.minibatches as f64, 1.0, 1024.0)?;
        check_range("ppo.learning_rate", self.learning_rate, 0.0, 1.0)?;
        check_range("ppo.desired_kl", self.desired_kl, 1e-6, 1.0)?;
        check_range("ppo.lr_min", self.lr_min, 0.0, 1.0)?;
        check_range("ppo.lr_max", self.lr_max, self.lr_min, 1.0)?;
        check_range("ppo.entropy_coef", self.entropy_coef, 0.0, 1.0)?;
        check_range("ppo.value_coef", self.value_coef, 0.0, 100.0)?;
        check_range("ppo.max_grad_norm", self.max_grad_norm, 1e-6, 1e6)?;
        check_range("ppo.init_std", self.init_std, 1e-3, 10.0)?;
        check_range("ppo.symmetry_coef", self.symmetry_coef, 0.0, 100.0)?;
        check_range("ppo.min_std", self.min_std, 1e-4, self.init_std)
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Activation {
    Elu,
    Tanh,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NetworkConfig {
    pub actor_hidden: Vec<usize>,
    pub critic_hidden: Vec<usize>,
    pub activation: Activation,
    /// Init gain of the actor's last layer (0.01: the policy starts near its mean action; 0:
    /// exactly at it, e.g. EEMP-RL's residual starts as the table).
    pub actor_output_gain: f64,
}

impl Default for NetworkConfig {
    fn default() -> Self {
        NetworkConfig {
            actor_hidden: vec![128, 128],
            critic_hidden: vec![128, 128],
            activation: Activation::Elu,
            actor_output_gain: 0.01,
        }
    }
}

impl NetworkConfig {
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range(
            "network.actor_output_gain",
            self.actor_output_gain,
            0.0,
            10.0,
        )?;
        for (name, layers) in [
            ("network.actor_hidden", &self.actor_hidden),
            ("network.critic_hidden", &self.critic_hidden),
        ] {
            if layers.is_empty() || layers.len() > 8 {
                return Err(ConfigError::Invalid {
                    name: name.into(),
                    message: format!("has {} layers: allowed 1..=8", layers.len()),
                });
            }
            for (i, &n) in layers.iter().enumerate() {
                check_range(&format!("{name}[{i}]"), n as f64, 1.0, 4096.0)?;
            }
        }
        Ok(())
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrainConfig {
    pub task: TaskKind,
    pub seed: u64,
    /// Parallel environments.
    pub num_envs: usize,
    /// Policy steps per environment per iteration (rollout length).
    pub steps_per_env: usize,
    /// Training stops after this many environment (policy) steps.
    pub total_env_steps: u64,
    /// Write a checkpoint every this many iterations.
    pub checkpoint_every: usize,
    pub ppo: PpoConfig,
    pub network: NetworkConfig,
    pub model_free: ModelFreeConfig,
    pub imitation: ImitationConfig,
    pub eemp_rl: EempRlConfig,
    pub cart_pole: CartPoleConfig,
    /// What the policy observes (and EEMP-RL's controller sees): the simulator's state, or the
    /// Kalman filter on the simulated IMU and encoders with A1-like noise, as on the robot.
    pub estimator: TrainEstimator,
    /// The filter's settings with `estimator = "kf"` (`eemp_core::estimator::KfConfig`; the
    /// rest of it is the filter's default).
    pub kf: TrainKf,
    /// What trains the policy: PPO (every task) or CMA-ES (EEMP-RL's residual, as a re-tuned
    /// table: the `cma_table` module).
    pub optimizer: Optimizer,
    /// CMA-ES's settings with `optimizer = "cmaes"`.
    pub cmaes: CmaesConfig,
    /// Fine-tuning: start from this policy file's networks, exploration noise and observation
    /// normaliser (same task and network shapes) instead of random ones; the optimiser starts
    /// fresh. None: from scratch.
    pub init_policy: Option<std::path::PathBuf>,
}

/// The optimiser of a training run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Optimizer {
    #[default]
    Ppo,
    Cmaes,
}

/// The state a policy trains on. On the filter a checkpoint holds no filter or sensor state:
/// a resumed run restarts each env's filter at its restored pose, so it is deterministic but
/// not bit-equal to an uninterrupted run (on ground truth it is).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TrainEstimator {
    #[default]
    GroundTruth,
    Kf,
}

/// The settings of the filter a policy trains on that have changed since policies were first
/// trained on it; a policy trained on the filter is evaluated on the same (`eemp walk`, the
/// suites). The default is the filter of the first policies (jump test and leg-outlier gate
/// off), so that a policy file written before this setting existed reads as what it was
/// trained on; `[kf] velocity_jump_mps = 0.15, velocity_jump_dragged_fraction = 0.15,
/// leg_outlier_mps = 0.15` trains on the filter's current defaults. (The shipped policies were
/// trained before the dragged-leg rule, so they run without it.)
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrainKf {
    pub velocity_jump_mps: f64,
    pub velocity_jump_dragged_fraction: f64,
    pub leg_outlier_mps: f64,
}

impl TrainKf {
    /// `kf` with these settings.
    pub fn apply(&self, kf: &mut eemp_core::estimator::KfConfig) {
        kf.velocity_jump_mps = self.velocity_jump_mps;
        kf.velocity_jump_dragged_fraction = self.velocity_jump_dragged_fraction;
        kf.leg_outlier_mps = self.leg_outlier_mps;
    }
}

impl Default for TrainConfig {
    fn default() -> Self {
        TrainConfig {
            task: TaskKind::ModelFree,
            seed: 1,
            num_envs: 128,
            steps_per_env: 24,
            total_env_steps: 20_000_000,
            checkpoint_every: 10,
            ppo: PpoConfig::default(),
            network: NetworkConfig::default(),
            model_free: ModelFreeConfig::default(),
            imitation: ImitationConfig::default(),
            eemp_rl: EempRlConfig::default(),
            cart_pole: CartPoleConfig::default(),
            estimator: TrainEstimator::GroundTruth,
            kf: TrainKf::default(),
            optimizer: Optimizer::Ppo,
            cmaes: Default::default(),
            init_policy: None,
        }
    }
}

impl TrainConfig {
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range("num_envs", self.num_envs as f64, 1.0, 65536.0)?;
        check_range("steps_per_env", self.steps_per_env as f64, 1.0, 10000.0)?;
        check_range("total_env_steps", self.total_env_steps as f64, 1.0, 1e11)?;
        check_range("checkpoint_every", self.checkpoint_every as f64, 1.0, 1e6)?;
        let batch = self.num_envs * self.steps_per_env;
        if batch < self.ppo.minibatches {
            return Err(ConfigError::Invalid {
                name: "ppo.minibatches".into(),
                message: format!(
                    "{} is more than the {batch} transitions of an iteration (num_envs × steps_per_env)",
                    self.ppo.minibatches
                ),
            });
        }
        self.ppo.validate()?;
        self.network.validate()?;
        let mut kf = eemp_core::estimator::KfConfig::default();
        self.kf.apply(&mut kf);
        kf.validate()?;
        if self.task == TaskKind::CartPole && self.estimator == TrainEstimator::Kf {
            return Err(ConfigError::Invalid {
                name: "estimator".into(),
                message: "\"kf\" is for the A1 tasks, not cart-pole (allowed: \"ground-truth\")"
                    .into(),
            });
        }
        if self.optimizer == Optimizer::Cmaes {
            check_cmaes_config(self)?;
        }
        match self.task {
            TaskKind::ModelFree => self.model_free.validate(),
            TaskKind::Imitation => self.imitation.validate(),
            TaskKind::EempRl => self.eemp_rl.validate(),
            TaskKind::CartPole => self.cart_pole.validate(),
        }
    }

    /// Reads and validates a config file; errors name the file and the key.
    pub fn load(path: &std::path::Path) -> Result<Self, ConfigError> {
        let mut c: TrainConfig = eemp_core::config_error::load_toml(path)?;
        c.eemp_rl.read_files().map_err(|e| ConfigError::Invalid {
            name: path.display().to_string(),
            message: e.to_string(),
        })?;
        c.validate().map_err(|e| ConfigError::Invalid {
            name: path.display().to_string(),
            message: e.to_string(),
        })?;
        Ok(c)
    }
}

/// `[cmaes]` of a training config with `optimizer = "cmaes"`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CmaesConfig {
    /// Candidates per generation; 0: CMA-ES's default 4 + ⌊3 ln n⌋.
    pub population: usize,
    /// Episodes each candidate runs per generation (the same ones for every candidate).
    pub episodes_per_candidate: usize,
    /// Initial step size in the action's units (Δ = bounds ⊙ tanh(x); x starts at 0, the table).
    pub initial_sigma: f64,
    /// One search per table entry, on episodes at that entry's speed (see the module docs).
    pub per_entry: bool,
    /// Per entry: the fresh episodes its correction must beat the table on to be kept (0: kept
    /// as found).
    pub validation_episodes: usize,
    /// Per entry: fresh episodes in the robot file's own world (flat floor, its friction, no
    /// payload, no pushes) on which the correction's CoT must stay within
    /// `nominal_cot_tolerance` of the table's to be kept (0: no such check).
    pub nominal_episodes: usize,
    /// How far above the table's CoT on the nominal episodes a kept correction may be, as a
    /// share (0.01: 1 %).
    pub nominal_cot_tolerance: f64,
}

impl Default for CmaesConfig {
    fn default() -> Self {
        CmaesConfig {
            population: 0,
            episodes_per_candidate: 8,
            initial_sigma: 0.5,
            per_entry: false,
            validation_episodes: 0,
            nominal_episodes: 0,
            nominal_cot_tolerance: 0.01,
        }
    }
}

impl CmaesConfig {
    pub fn validate(&self) -> Result<(), ConfigError> {
        if self.population != 0 {
            check_range("cmaes.population", self.population as f64, 4.0, 4096.0)?;
        }
        check_range(
            "cmaes.episodes_per_candidate",
            self.episodes_per_candidate as f64,
            1.0,
            4096.0,
        )?;
        check_range("cmaes.initial_sigma", self.initial_sigma, 1e-3, 3.0)?;
        for (name, n) in [
            ("validation_episodes", self.validation_episodes),
            ("nominal_episodes", self.nominal_episodes),
        ] {
            if !self.per_entry && n > 0 {
                return Err(ConfigError::Invalid {
                    name: format!("cmaes.{name}"),
                    message: format!(
                        "is {n} but validates each entry's search: it needs per_entry = true \
                         (allowed: 0 without it)"
                    ),
                });
            }
            check_range(&format!("cmaes.{name}"), n as f64, 0.0, 4096.0)?;
        }
        check_range(
            "cmaes.nominal_cot_tolerance",
            self.nominal_cot_tolerance,
            0.0,
            1.0,
        )
    }
}

/// Checks that `config` is one CMA-ES can run: EEMP-RL, residual, nearest-entry table.
pub fn check_cmaes_config(config: &TrainConfig) -> Result<(), ConfigError> {
    let invalid = |message: &str| ConfigError::Invalid {
        name: "optimizer".into(),
        message: message.into(),
    };
    if config.task != TaskKind::EempRl {
        return Err(invalid(&format!(
            "\"cmaes\" trains EEMP-RL's residual, not task {} (allowed: \"ppo\")",
            config.task.name()
        )));
    }
    let Some(r) = &config.eemp_rl.residual else {
        return Err(invalid(
            "\"cmaes\" needs [eemp_rl.residual] (the absolute form has no table to correct)",
        ));
    };
    if r.paired {
        // A whole-episode return already compares candidates on the same episodes.
        return Err(ConfigError::Invalid {
            name: "eemp_rl.residual.paired".into(),
            message: "is true but \"cmaes\" compares candidates on the same episodes already; \
                      the paired reward is for PPO (allowed: false, or optimizer = \"ppo\")"
                .into(),
        });
    }
    if r.deadband != 0.0 {
        // The band is for a policy's noisy answers; CMA-ES searches each entry's correction
        // itself, and a band would only flatten its search space around the table.
        return Err(ConfigError::Invalid {
            name: "eemp_rl.residual.deadband".into(),
            message: format!(
                "is {} but \"cmaes\" corrects each table entry directly and has no band \
                 (allowed: 0, or optimizer = \"ppo\")",
                r.deadband
            ),
        });
    }
    if let Some(t) = &r.table {
        if t.interpolation != eemp_core::planner::params_table::Interpolation::Nearest {
            return Err(ConfigError::Invalid {
                name: r.table_file.display().to_string(),
                message: "CMA-ES corrects each entry: the table's interpolation must be \
                          \"nearest\" (allowed: \"nearest\")"
                    .into(),
            });
        }
    }
    config.cmaes.validate()
}
