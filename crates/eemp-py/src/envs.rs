//! The A1 tasks of `eemp-rl` as one vectorised environment object: N environments stepped in
//! Rust worker threads behind one `step` call, numpy arrays in and out. The gymnasium classes
//! (`python/eemp/envs.py`) wrap it; a single environment is a batch of one.

use eemp_rl::config::{TaskKind, TrainConfig};
use eemp_rl::env::{env_seed, random_actions, stepping_rate};
use eemp_rl::train::{make_envs_with, parse_motion, AnyVecEnv};
use numpy::{
    PyArray1, PyArray2, PyArray3, PyArrayMethods, PyReadonlyArray2, PyReadonlyArray3,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::sync::MutexExt;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

/// The reference motion the shipped imitation policy was trained on; the default of the
/// imitation task, so it runs from any working directory.
const SHIPPED_TROT: &str = include_str!("../../../motions/a1_trot.csv");
const SHIPPED_TROT_NAME: &str = "motions/a1_trot.csv";

/// Calls `$body` with `$v` bound to the task's `VecEnv<E>`, whatever E is.
macro_rules! with_env {
    ($any:expr, $v:ident => $body:expr) => {
        match $any {
            AnyVecEnv::ModelFree($v) => $body,
            AnyVecEnv::Imitation($v, _) => $body,
            AnyVecEnv::EempRl($v) => $body,
            AnyVecEnv::CartPole($v) => $body,
        }
    };
}

pub(crate) fn value_error(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// The task's training config: `config` (a TOML file like `policies/a1_model_free.toml`) or the
/// defaults, for `task`, with `num_envs` environments.
fn task_config(task: &str, config: Option<&Path>, num_envs: usize) -> PyResult<TrainConfig> {
    let kind = match task.parse::<TaskKind>() {
        Ok(TaskKind::CartPole) => {
            return Err(value_error(
                "task 'cart-pole' is PPO's own test task, not exposed: allowed model-free, imitation, eemp-rl",
            ))
        }
        Ok(k) => k,
        Err(_) => {
            return Err(value_error(format!(
                "unknown task '{task}': allowed model-free, imitation, eemp-rl"
            )))
        }
    };
    if !(1..=65536).contains(&num_envs) {
        return Err(value_error(format!(
            "num_envs {num_envs} is out of range: allowed [1, 65536]"
        )));
    }
    let mut c = match config {
        Some(p) => TrainConfig::load(p).map_err(value_error)?,
        None => TrainConfig {
            task: kind,
            ..Default::default()
        },
    };
    if c.task != kind {
        return Err(value_error(format!(
            "config {} is for task '{}', not '{}'",
            config.map(|p| p.display().to_string()).unwrap_or_default(),
            c.task.name(),
            kind.name()
        )));
    }
    c.num_envs = num_envs;
    Ok(c)
}

/// Builds the task's environments on `robot` (a robot file; None: the A1); an imitation task
/// gets `motion` (a file) or, without a config naming one, the shipped trot.
pub fn build(
    task: &str,
    num_envs: usize,
    seed: u64,
    threads: usize,
    config: Option<&Path>,
    motion: Option<&Path>,
    robot: Option<&Path>,
) -> PyResult<(AnyVecEnv, TrainConfig)> {
    if !(1..=1024).contains(&threads) {
        return Err(value_error(format!(
            "threads {threads} is out of range: allowed [1, 1024]"
        )));
    }
    let mut c = task_config(task, config, num_envs)?;
    c.seed = seed;
    if motion.is_some() && c.task != TaskKind::Imitation {
        return Err(value_error(format!(
            "motion is for the imitation task, not '{}'",
            c.task.name()
        )));
    }
    let robot = eemp_sim::robot_model::load_robot_or_a1(robot).map_err(value_error)?;
    let m = if c.task != TaskKind::Imitation {
        None
    } else if let Some(p) = motion {
        c.imitation.motion_file = p.display().to_string();
        Some(eemp_rl::train::load_motion(p, &robot).map_err(value_error)?)
    } else if config.is_none() {
        c.imitation.motion_file = SHIPPED_TROT_NAME.into();
        Some(
            parse_motion(Path::new(SHIPPED_TROT_NAME), SHIPPED_TROT.into(), &robot)
                .map_err(value_error)?,
        )
    } else {
        None
    };
    let mut v = make_envs_with(&c, &robot, threads, m).map_err(value_error)?;
    // The trainer's stagger of first episodes is not gymnasium's contract: every episode a
    // user starts runs its full length.
    with_env!(&mut v, e => e.set_staggered_start(false, c.seed));
    Ok((v, c))
}

/// What the Python side needs to know of a task, fixed at construction.
struct Shape {
    num_envs: usize,
    obs_dim: usize,
    act_dim: usize,
    n_terms: usize,
}

/// N environments of one task (`eemp._eemp.VecEnv`).
#[pyclass(module = "eemp._eemp", name = "VecEnv")]
pub struct PyVecEnv {
    // pyclasses must be Sync; MuJoCo's data is Send only.
    inner: Mutex<AnyVecEnv>,
    shape: Shape,
    task: TaskKind,
    action_bound: f64,
    reward_terms: Vec<String>,
    episode_s: f64,
}

/// Locks what a Python object holds, waiting with the GIL released (another Python thread may
/// hold the lock with the GIL released too: waiting with it held would deadlock both). A panic
/// inside a call (turned into a Python exception) leaves the data as it was, so a poisoned lock
/// is taken as it is: the next reset starts clean episodes.
pub(crate) fn lock<'a, T>(m: &'a Mutex<T>, py: Python<'_>) -> MutexGuard<'a, T> {
    m.lock_py_attached(py).unwrap_or_else(|p| p.into_inner())
}

impl PyVecEnv {
    fn lock(&self, py: Python<'_>) -> MutexGuard<'_, AnyVecEnv> {
        lock(&self.inner, py)
    }
}

#[pymethods]
impl PyVecEnv {
    #[new]
    #[pyo3(signature = (task, num_envs = 1, seed = 0, threads = 1, config = None, motion = None, robot = None))]
    fn new(
        task: &str,
        num_envs: usize,
        seed: u64,
        threads: usize,
        config: Option<PathBuf>,
        motion: Option<PathBuf>,
        robot: Option<PathBuf>,
    ) -> PyResult<Self> {
        let (v, c) = build(
            task,
            num_envs,
            seed,
            threads,
            config.as_deref(),
            motion.as_deref(),
            robot.as_deref(),
        )?;
        let (obs_dim, act_dim, terms) =
            with_env!(&v, e => (e.obs_dim(), e.act_dim(), e.reward_terms()));
        let (action_bound, episode_s) = match c.task {
            TaskKind::ModelFree => (c.model_free.action_clip, c.model_free.episode_s),
            TaskKind::Imitation => (c.imitation.action_clip, c.imitation.episode_s),
            // Any real action is squashed into Table I's ranges.
            TaskKind::EempRl => (f64::INFINITY, c.eemp_rl.episode_s),
            TaskKind::CartPole => (f64::INFINITY, 0.0),
        };
        Ok(PyVecEnv {
            inner: Mutex::new(v),
            shape: Shape {
                num_envs,
                obs_dim,
                act_dim,
                n_terms: terms.len(),
            },
            task: c.task,
            action_bound,
            reward_terms: terms.iter().map(|s| s.to_string()).collect(),
            episode_s,
        })
    }

    #[getter]
    fn num_envs(&self) -> usize {
        self.shape.num_envs
    }
    #[getter]
    fn obs_dim(&self) -> usize {
        self.shape.obs_dim
    }
    #[getter]
    fn act_dim(&self) -> usize {
        self.shape.act_dim
    }
    #[getter]
    fn task(&self) -> &'static str {
        self.task.name()
    }
    /// Actions beyond ±bound act as ±bound (inf: any real value is used, e.g. squashed).
    #[getter]
    fn action_bound(&self) -> f64 {
        self.action_bound
    }
    #[getter]
    fn reward_terms(&self) -> Vec<String> {
        self.reward_terms.clone()
    }
    #[getter]
    fn episode_s(&self) -> f64 {
        self.episode_s
    }

    /// Starts new episodes in every environment; with `seeds`, environment i's RNG is first
    /// re-seeded with `seeds[i]`. Returns the observations (num_envs × obs_dim, float32).
    #[pyo3(signature = (seeds = None))]
    fn reset<'py>(
        &self,
        py: Python<'py>,
        seeds: Option<Vec<u64>>,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let mut g = self.lock(py);
        let any = &mut *g;
        py.detach(|| match seeds {
            Some(s) => with_env!(any, v => v.reseed(&s)),
            None => {
                with_env!(any, v => v.reset_all());
                Ok(())
            }
        })
        .map_err(value_error)?;
        self.obs_array(py, with_env!(&*g, v => &v.obs))
    }

    /// The current observations (after an auto-reset: the new episodes' first ones).
    fn observations<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let g = self.lock(py);
        self.obs_array(py, with_env!(&*g, v => &v.obs))
    }

    /// Steps every environment with its row of `actions` (num_envs × act_dim, float32, all
    /// finite). Environments whose episode ended are reset at once, as the Rust trainer does.
    /// Returns (obs, reward, terminated, truncated, final_obs, invalid, reward_terms):
    /// `final_obs` rows are the last observations of the episodes that ended (zeros elsewhere
    /// are not promised; read them only where terminated or truncated).
    #[allow(clippy::type_complexity)]
    fn step<'py>(
        &self,
        py: Python<'py>,
        actions: PyReadonlyArray2<'py, f32>,
    ) -> PyResult<(
        Bound<'py, PyArray2<f32>>,
        Bound<'py, PyArray1<f64>>,
        Bound<'py, PyArray1<bool>>,
        Bound<'py, PyArray1<bool>>,
        Bound<'py, PyArray2<f32>>,
        Bound<'py, PyArray1<bool>>,
        Bound<'py, PyArray2<f64>>,
    )> {
        let (n, a) = (self.shape.num_envs, self.shape.act_dim);
        let dims = actions.shape();
        if dims != [n, a] {
            return Err(value_error(format!(
                "actions have shape {dims:?}, expected [{n}, {a}] (num_envs × act_dim)"
            )));
        }
        // A copy: other Python threads run while the environments step and could write to
        // the caller's array (and slip a NaN past the check below).
        let flat: Vec<f32> = match actions.as_slice() {
            Ok(sl) => sl.to_vec(),
            Err(_) => actions.as_array().iter().copied().collect(),
        };
        if let Some(i) = flat.iter().position(|x| !x.is_finite()) {
            return Err(value_error(format!(
                "action [{}, {}] is {}: actions must be finite",
                i / a,
                i % a,
                flat[i]
            )));
        }
        let mut g = self.lock(py);
        let any = &mut *g;
        py.detach(|| with_env!(any, v => v.step(&flat)));
        with_env!(&*g, v => {
            let rewards: Vec<f64> = v.infos.iter().map(|i| i.reward).collect();
            let term: Vec<bool> = v.infos.iter().map(|i| i.terminated).collect();
            let trunc: Vec<bool> = v.infos.iter().map(|i| i.truncated).collect();
            let invalid: Vec<bool> = v.infos.iter().map(|i| i.invalid).collect();
            Ok((
                self.obs_array(py, &v.obs)?,
                PyArray1::from_vec(py, rewards),
                PyArray1::from_vec(py, term),
                PyArray1::from_vec(py, trunc),
                self.obs_array(py, &v.final_obs)?,
                PyArray1::from_vec(py, invalid),
                PyArray1::from_slice(py, &v.terms)
                    .reshape([n, self.shape.n_terms])?,
            ))
        })
    }
}

impl PyVecEnv {
    fn obs_array<'py>(&self, py: Python<'py>, obs: &[f32]) -> PyResult<Bound<'py, PyArray2<f32>>> {
        PyArray1::from_slice(py, obs).reshape([self.shape.num_envs, self.shape.obs_dim])
    }
}

/// `eemp_rl::env::env_seed`: the RNG seed of environment `index` of a run seeded `seed` (how
/// `eemp train` and the vectorised environment seed their environments).
#[pyfunction]
pub fn env_seed_of(seed: u64, index: usize) -> u64 {
    env_seed(seed, index)
}

/// The Rust-only reference of a rollout: the task's environments built and stepped by
/// `eemp-rl` alone (as `eemp train` does, seeded `seed`), with `actions` (T × num_envs ×
/// act_dim). Returns (obs (T+1) × N × D, rewards T × N, terminated T × N, truncated T × N,
/// final obs T × N × D: the last observation of each episode that ended, zeros elsewhere).
#[pyfunction]
#[pyo3(signature = (task, seed, actions, config = None))]
#[allow(clippy::type_complexity)]
pub fn rust_rollout<'py>(
    py: Python<'py>,
    task: &str,
    seed: u64,
    actions: PyReadonlyArray3<'py, f32>,
    config: Option<PathBuf>,
) -> PyResult<(
    Bound<'py, PyArray3<f32>>,
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray2<bool>>,
    Bound<'py, PyArray2<bool>>,
    Bound<'py, PyArray3<f32>>,
)> {
    let [t_len, n, width] = *actions.shape() else {
        unreachable!("a 3-d array")
    };
    let acts = actions.as_array().to_owned();
    let (mut any, _) = build(task, n, seed, 1, config.as_deref(), None, None)?;
    let act_dim = with_env!(&any, v => v.act_dim());
    if width != act_dim {
        return Err(value_error(format!(
            "actions have shape [{t_len}, {n}, {width}], expected [T, {n}, {act_dim}]"
        )));
    }
    let (obs, rew, term, trunc, finals, d) = py.detach(|| {
        with_env!(&mut any, v => {
            let d = v.obs_dim();
            let mut obs = v.obs.clone();
            let (mut rew, mut term, mut trunc, mut finals) =
                (Vec::new(), Vec::new(), Vec::new(), Vec::new());
            for t in 0..t_len {
                let a: Vec<f32> = acts.index_axis(numpy::ndarray::Axis(0), t).iter().copied().collect();
                v.step(&a);
                obs.extend_from_slice(&v.obs);
                for (i, info) in v.infos.iter().enumerate() {
                    rew.push(info.reward);
                    term.push(info.terminated);
                    trunc.push(info.truncated);
                    if info.terminated || info.truncated {
                        finals.extend_from_slice(&v.final_obs[i * d..(i + 1) * d]);
                    } else {
                        finals.extend(std::iter::repeat_n(0.0, d));
                    }
                }
            }
            (obs, rew, term, trunc, finals, d)
        })
    });
    Ok((
        PyArray1::from_vec(py, obs).reshape([t_len + 1, n, d])?,
        PyArray1::from_vec(py, rew).reshape([t_len, n])?,
        PyArray1::from_vec(py, term).reshape([t_len, n])?,
        PyArray1::from_vec(py, trunc).reshape([t_len, n])?,
        PyArray1::from_vec(py, finals).reshape([t_len, n, d])?,
    ))
}

/// Env steps per second of the task stepped in Rust alone with uniform random actions in
/// [-1, 1] (the stepping measurement of `eemp bench rl`), for the Python throughput benchmark.
#[pyfunction]
#[pyo3(signature = (task, num_envs, steps, threads, seed = 7))]
pub fn rust_stepping_rate(
    py: Python<'_>,
    task: &str,
    num_envs: usize,
    steps: usize,
    threads: usize,
    seed: u64,
) -> PyResult<f64> {
    let (mut any, _) = build(task, num_envs, seed, threads, None, None, None)?;
    py.detach(|| {
        with_env!(&mut any, v => {
            let actions = random_actions(v.len() * v.act_dim(), steps, 3);
            Ok(stepping_rate(v, &actions))
        })
    })
}
