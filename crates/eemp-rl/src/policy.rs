//! A trained policy on disk: the actor-critic's parameters, the observation normaliser and the
//! full training config (so the observation layout, action scaling and PD gains that the
//! network was trained with travel with it), in one small safetensors file.

use crate::config::{TaskKind, TrainConfig};
use crate::nn::ActorCritic;
use crate::normalizer::ObsNormalizer;
use crate::tensor_file::TensorFile;
use candle_core::{Device, Tensor};
use rand::SeedableRng;
use std::path::Path;

pub const POLICY_FORMAT: &str = "eemp-policy/1";

pub struct Policy {
    pub config: TrainConfig,
    pub net: ActorCritic,
    pub normalizer: ObsNormalizer,
    /// The reference motion file's text (imitation policies carry the motion they follow).
    pub motion: Option<String>,
    /// The robot it was trained on (metadata `robot`; `None`: a file from before stamps,
    /// trained on the A1).
    pub robot: Option<eemp_core::robot::RobotId>,
    /// Let a controller run it on another robot (an experiment; not saved).
    pub allow_robot_mismatch: bool,
}

/// Observation and action sizes of a config's task.
pub fn task_dims(config: &TrainConfig) -> (usize, usize) {
    match config.task {
        TaskKind::ModelFree => (
            config.model_free.obs_dim(),
            crate::tasks::model_free::ACT_DIM,
        ),
        TaskKind::Imitation => (config.imitation.obs_dim(), crate::tasks::imitation::ACT_DIM),
        TaskKind::EempRl => (config.eemp_rl.obs_dim(), crate::tasks::eemp_rl::ACT_DIM),
        TaskKind::CartPole => (4, 1),
    }
}

#[derive(serde::Serialize, serde::Deserialize)]
struct NormalizerJson {
    mean: Vec<f64>,
    var: Vec<f64>,
    count: f64,
    clip: f64,
}

pub fn normalizer_to_json(n: &ObsNormalizer) -> String {
    serde_json::to_string(&NormalizerJson {
        mean: n.mean.clone(),
        var: n.var.clone(),
        count: n.count,
        clip: n.clip,
    })
    .expect("serialises")
}

pub fn normalizer_from_json(s: &str) -> Result<ObsNormalizer, String> {
    let j: NormalizerJson = serde_json::from_str(s).map_err(|e| e.to_string())?;
    if j.mean.len() != j.var.len() || j.var.iter().any(|v| !v.is_finite() || *v < 0.0) {
        return Err("observation normaliser is malformed".into());
    }
    Ok(ObsNormalizer {
        mean: j.mean,
        var: j.var,
        count: j.count,
        clip: j.clip,
    })
}

impl Policy {
    /// A fresh policy for `config` (initialised from its seed).
    pub fn new(config: &TrainConfig) -> Result<Self, String> {
        let (obs_dim, act_dim) = task_dims(config);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(config.seed ^ 0x005E_ED0F_AC70);
        let net = ActorCritic::new(
            obs_dim,
            act_dim,
            &config.network,
            config.ppo.init_std,
            &mut rng,
        )
        .map_err(|e| e.to_string())?;
        Ok(Policy {
            config: config.clone(),
            net,
            normalizer: ObsNormalizer::new(obs_dim),
            motion: None,
            robot: None,
            allow_robot_mismatch: false,
        })
    }

    pub fn to_file(&self) -> Result<TensorFile, String> {
        let mut f = TensorFile::default();
        for (name, t) in self.net.named() {
            f.insert_tensor(&name, &t).map_err(|e| e.to_string())?;
        }
        f.metadata.insert("format".into(), POLICY_FORMAT.into());
        f.metadata
            .insert("task".into(), self.config.task.name().to_string());
        let (o, a) = task_dims(&self.config);
        f.metadata.insert("obs_dim".into(), o.to_string());
        f.metadata.insert("act_dim".into(), a.to_string());
        f.metadata.insert(
            "config".into(),
            toml::to_string(&self.config).map_err(|e| e.to_string())?,
        );
        f.metadata.insert(
            "obs_normalizer".into(),
            normalizer_to_json(&self.normalizer),
        );
        if let Some(m) = &self.motion {
            f.metadata.insert("motion".into(), m.clone());
        }
        if let Some(r) = &self.robot {
            f.metadata.insert(
                "robot".into(),
                toml::to_string(r).map_err(|e| e.to_string())?,
            );
        }
        Ok(f)
    }

    pub fn save(&self, path: &Path) -> Result<(), String> {
        self.to_file()?.save(path)
    }

    /// Loads a policy file; `expect` names the task it must be for.
    pub fn load(path: &Path, expect: Option<TaskKind>) -> Result<Self, String> {
        let f = TensorFile::load(path)?;
        Self::from_file(path, &f, expect)
    }

    pub fn from_file(
        path: &Path,
        f: &TensorFile,
        expect: Option<TaskKind>,
    ) -> Result<Self, String> {
        let fmt = f.meta(path, "format")?;
        if fmt != POLICY_FORMAT {
            return Err(format!(
                "{}: format '{fmt}' is not {POLICY_FORMAT}",
                path.display()
            ));
        }
        let task: TaskKind = f.meta(path, "task")?.parse()?;
        if let Some(want) = expect {
            if task != want {
                return Err(format!(
                    "{} is a policy for task {}, not {}",
                    path.display(),
                    task.name(),
                    want.name()
                ));
            }
        }
        let config: TrainConfig = toml::from_str(f.meta(path, "config")?)
            .map_err(|e| format!("{}: embedded config: {e}", path.display()))?;
        config
            .validate()
            .map_err(|e| format!("{}: embedded config: {e}", path.display()))?;
        let mut policy = Policy::new(&config)?;
        let (o, a) = task_dims(&config);
        for (key, want) in [("obs_dim", o), ("act_dim", a)] {
            let got: usize = f
                .meta(path, key)?
                .parse()
                .map_err(|_| format!("{}: {key} is not a number", path.display()))?;
            if got != want {
                return Err(format!(
                    "{}: {key} {got} does not match its config's {want}",
                    path.display()
                ));
            }
        }
        for (name, t) in policy.net.named() {
            let loaded = f.tensor(path, &name, t.dims())?;
            let var = policy
                .net
                .vars()
                .into_iter()
                .find(|v| v.as_tensor().id() == t.id())
                .expect("named() lists the vars");
            var.set(&loaded).map_err(|e| e.to_string())?;
        }
        policy.normalizer = normalizer_from_json(f.meta(path, "obs_normalizer")?)
            .map_err(|e| format!("{}: {e}", path.display()))?;
        if task == TaskKind::Imitation {
            policy.motion = Some(f.meta(path, "motion")?.to_string());
        }
        if let Some(text) = f.metadata.get("robot") {
            policy.robot = Some(
                toml::from_str(text)
                    .map_err(|e| format!("{}: metadata 'robot': {e}", path.display()))?,
            );
        }
        if policy.normalizer.dim() != o {
            return Err(format!(
                "{}: normaliser has {} dims, the task {o}",
                path.display(),
                policy.normalizer.dim()
            ));
        }
        Ok(policy)
    }

    /// This policy with `obs_dim` inputs: the first layers of actor and critic gain zero
    /// columns for the new (last) inputs and the normaliser unit statistics for them, so it
    /// acts exactly as before whatever the new inputs read (a fine-tune that adds a gait clock).
    pub fn with_appended_inputs(mut self, obs_dim: usize) -> Result<Self, String> {
        let old = self.net.obs_dim();
        if obs_dim < old {
            return Err(format!(
                "cannot narrow a policy's inputs from {old} to {obs_dim}"
            ));
        }
        for mlp in [&mut self.net.actor, &mut self.net.critic] {
            let w = mlp.layers[0].weight.as_tensor();
            let zeros = Tensor::zeros((w.dims()[0], obs_dim - old), w.dtype(), w.device())
                .map_err(|e| e.to_string())?;
            let wide = Tensor::cat(&[w, &zeros], 1).map_err(|e| e.to_string())?;
            mlp.layers[0].weight =
                candle_core::Var::from_tensor(&wide).map_err(|e| e.to_string())?;
        }
        self.normalizer.mean.resize(obs_dim, 0.0);
        self.normalizer.var.resize(obs_dim, 1.0);
        Ok(self)
    }

    /// The robot it was trained on (an unstamped file: the A1).
    pub fn robot_id(&self) -> eemp_core::robot::RobotId {
        self.robot
            .clone()
            .unwrap_or_else(eemp_core::robot::RobotId::unstamped)
    }

    /// Refuses to run on `robot` a policy trained on another, unless `allow_robot_mismatch`.
    pub fn check_robot(&self, robot: &eemp_core::robot::RobotConfig) -> Result<(), String> {
        if self.allow_robot_mismatch {
            return Ok(());
        }
        self.robot_id()
            .check(robot, &format!("the {} policy", self.config.task.name()))
    }

    /// The deterministic action (the Gaussian's mean) for one raw observation.
    pub fn act(&self, raw_obs: &[f32]) -> Result<Vec<f32>, String> {
        let mut x = vec![0f32; raw_obs.len()];
        self.normalizer.apply(raw_obs, &mut x);
        let t = Tensor::from_vec(x, (1, raw_obs.len()), &Device::Cpu).map_err(|e| e.to_string())?;
        self.net
            .mean(&t)
            .and_then(|m| m.squeeze(0))
            .and_then(|m| m.to_vec1::<f32>())
            .map_err(|e| e.to_string())
    }
}

/// A trained policy chooses EEMP-RL's parameters (the task's controller is written against the
/// trait, so the task sits below the policy files it runs).
impl crate::tasks::eemp_rl::ParamsPolicy for Policy {
    fn act(&mut self, obs: &[f32]) -> Option<Vec<f32>> {
        Policy::act(self, obs).ok()
    }
    fn check_robot(&self, robot: &eemp_core::robot::RobotConfig) -> Result<(), String> {
        Policy::check_robot(self, robot)
    }
    fn allow_robot_mismatch(&self) -> bool {
        self.allow_robot_mismatch
    }
}
