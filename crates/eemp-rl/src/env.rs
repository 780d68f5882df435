//! The environment interface and its vectorised runner: N environments stepped in parallel on
//! a fixed worker pool, auto-reset, time-limit truncation kept apart from termination.
//!
//! Determinism: every environment owns its RNG (seeded from the run seed and its index) and
//! its MuJoCo data; nothing is shared between them while they step, so the rollout is the same
//! whatever the number of threads or the order the pool runs them in.

use crate::mirror::MirrorMap;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// One step's outcome, besides the next observation.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepInfo {
    pub reward: f64,
    /// The episode ended in a failure state (fall): no bootstrapping from its value.
    pub terminated: bool,
    /// The episode hit its time limit: the return is bootstrapped from the final state's value.
    pub truncated: bool,
    /// A NaN/inf appeared in the action or the state: the episode was ended and counted, and the
    /// bad values never reach the network.
    pub invalid: bool,
    /// Semi-MDP steps: this step lasted this many of the task's nominal periods, and the next
    /// value is discounted by γ^periods. None: one period (every fixed-rate task).
    pub periods: Option<f64>,
}

/// A reinforcement-learning task.
pub trait Env: Send {
    fn obs_dim(&self) -> usize;
    fn act_dim(&self) -> usize;
    /// Names of the reward terms, in the order `step` writes them.
    fn reward_terms(&self) -> &'static [&'static str];
    /// Starts an episode and writes the first observation.
    fn reset(&mut self, rng: &mut ChaCha8Rng, obs: &mut [f32]);
    /// Applies `action`, writes the next observation and each reward term's value.
    fn step(
        &mut self,
        action: &[f32],
        rng: &mut ChaCha8Rng,
        obs: &mut [f32],
        terms: &mut [f64],
    ) -> StepInfo;
    /// Forgets earlier episodes: the next `reset` starts as the first one after construction
    /// does (tasks that stagger their first episodes start staggered again).
    fn restart(&mut self) {}
    /// Whether first episodes start at a random step (the trainer's stagger, so truncations
    /// spread out; on by default). A gymnasium environment turns it off: `reset(seed)` then
    /// starts a full-length episode.
    fn set_staggered_start(&mut self, _on: bool) {}
    /// Whether the last step ended in a fall (for logs).
    fn fell(&self) -> bool {
        false
    }
    /// The current observation (recomputed from the state; used after a restore).
    fn observe(&self, obs: &mut [f32]);
    /// Everything needed to continue bit for bit (checkpoints).
    fn save_state(&self) -> serde_json::Value;
    fn load_state(&mut self, state: &serde_json::Value) -> Result<(), String>;
    /// The left–right mirror of the observation and of the action (`crate::mirror`), for the
    /// mirror loss; tasks without one say why not.
    fn mirror_maps(&self) -> Result<(MirrorMap, MirrorMap), String> {
        Err("this task has no left–right mirror".into())
    }
}

/// Per-environment bookkeeping.
struct Slot<E> {
    env: E,
    rng: ChaCha8Rng,
    episode_return: f64,
    episode_len: usize,
}

/// A finished episode, for logs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EpisodeEnd {
    pub env: usize,
    pub episode_return: f64,
    pub length: usize,
    pub fell: bool,
    pub invalid: bool,
}

/// N environments with their observation buffer.
pub struct VecEnv<E: Env> {
    slots: Vec<Slot<E>>,
    pool: rayon::ThreadPool,
    obs_dim: usize,
    act_dim: usize,
    n_terms: usize,
    /// Current observations, row-major (env, obs).
    pub obs: Vec<f32>,
    /// Observations at which episodes were truncated in the last step (row of the env; only the
    /// rows of truncated envs are meaningful).
    pub final_obs: Vec<f32>,
    /// Per-step outputs of the last step.
    pub infos: Vec<StepInfo>,
    /// Reward terms of the last step, row-major (env, term).
    pub terms: Vec<f64>,
    /// Episodes that ended in the last step.
    pub ended: Vec<EpisodeEnd>,
}

/// The seed of environment `i` of a run seeded `seed`.
pub fn env_seed(seed: u64, i: usize) -> u64 {
    seed.wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(i as u64)
        .wrapping_mul(0xBF58_476D_1CE4_E5B9)
}

impl<E: Env> VecEnv<E> {
    /// `envs[i]` gets RNG seed `env_seed(seed, i)`; the pool has `threads` workers.
    pub fn new(envs: Vec<E>, seed: u64, threads: usize) -> Result<Self, String> {
        if envs.is_empty() {
            return Err("a vectorised environment needs at least one environment".into());
        }
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads.max(1))
            .build()
            .map_err(|e| format!("cannot start {threads} worker threads: {e}"))?;
        let (obs_dim, act_dim, n_terms) = (
            envs[0].obs_dim(),
            envs[0].act_dim(),
            envs[0].reward_terms().len(),
        );
        let n = envs.len();
        let mut v = VecEnv {
            slots: envs
                .into_iter()
                .enumerate()
                .map(|(i, env)| Slot {
                    env,
                    rng: ChaCha8Rng::seed_from_u64(env_seed(seed, i)),
                    episode_return: 0.0,
                    episode_len: 0,
                })
                .collect(),
            pool,
            obs_dim,
            act_dim,
            n_terms,
            obs: vec![0.0; n * obs_dim],
            final_obs: vec![0.0; n * obs_dim],
            infos: vec![StepInfo::default(); n],
            terms: vec![0.0; n * n_terms],
            ended: Vec::new(),
        };
        v.reset_all();
        Ok(v)
    }

    pub fn len(&self) -> usize {
        self.slots.len()
    }

    pub fn is_empty(&self) -> bool {
        self.slots.is_empty()
    }

    pub fn obs_dim(&self) -> usize {
        self.obs_dim
    }

    pub fn act_dim(&self) -> usize {
        self.act_dim
    }

    pub fn reward_terms(&self) -> &'static [&'static str] {
        self.slots[0].env.reward_terms()
    }

    /// The first environment's [`Env::mirror_maps`] (every environment has the same layout).
    pub fn mirror_maps(&self) -> Result<(MirrorMap, MirrorMap), String> {
        self.slots[0].env.mirror_maps()
    }

    pub fn envs(&self) -> impl Iterator<Item = &E> {
        self.slots.iter().map(|s| &s.env)
    }

    /// The RNG states (for checkpoints) and their restoration.
    pub fn rngs(&self) -> Vec<ChaCha8Rng> {
        self.slots.iter().map(|s| s.rng.clone()).collect()
    }

    pub fn episode_counters(&self) -> Vec<(f64, usize)> {
        self.slots
            .iter()
            .map(|s| (s.episode_return, s.episode_len))
            .collect()
    }

    /// Restores RNGs, episode counters and environment states, and recomputes `obs`.
    pub fn restore(
        &mut self,
        rngs: Vec<ChaCha8Rng>,
        counters: &[(f64, usize)],
        states: &[serde_json::Value],
    ) -> Result<(), String> {
        if rngs.len() != self.slots.len()
            || counters.len() != self.slots.len()
            || states.len() != self.slots.len()
        {
            return Err(format!(
                "checkpoint has {} environments, the run {}",
                states.len(),
                self.slots.len()
            ));
        }
        let d = self.obs_dim;
        for (i, ((s, r), c)) in self.slots.iter_mut().zip(rngs).zip(counters).enumerate() {
            s.rng = r;
            s.episode_return = c.0;
            s.episode_len = c.1;
            s.env.load_state(&states[i])?;
            s.env.observe(&mut self.obs[i * d..(i + 1) * d]);
        }
        Ok(())
    }

    pub fn env_states(&self) -> Vec<serde_json::Value> {
        self.slots.iter().map(|s| s.env.save_state()).collect()
    }

    /// Turns the first episodes' stagger on or off ([`Env::set_staggered_start`]) and starts
    /// again as `new(.., seed, ..)` would have with that setting.
    pub fn set_staggered_start(&mut self, on: bool, seed: u64) {
        for s in self.slots.iter_mut() {
            s.env.set_staggered_start(on);
        }
        let seeds: Vec<u64> = (0..self.slots.len()).map(|i| env_seed(seed, i)).collect();
        self.reseed(&seeds).expect("one seed per environment");
    }

    /// Gives environment `i` a fresh RNG seeded `seeds[i]` and starts new episodes in all of
    /// them as freshly built ones would: `reseed(&(0..n).map(|i| env_seed(s, i)).collect())` is
    /// the state `new(.., s, ..)` starts from (the Python bindings seed this way).
    pub fn reseed(&mut self, seeds: &[u64]) -> Result<(), String> {
        if seeds.len() != self.slots.len() {
            return Err(format!(
                "{} seeds for {} environments",
                seeds.len(),
                self.slots.len()
            ));
        }
        for (s, &seed) in self.slots.iter_mut().zip(seeds) {
            s.rng = ChaCha8Rng::seed_from_u64(seed);
            s.env.restart();
        }
        self.reset_all();
        Ok(())
    }

    pub fn reset_all(&mut self) {
        let d = self.obs_dim;
        let (slots, obs) = (&mut self.slots, &mut self.obs);
        self.pool.install(|| {
            slots
                .par_iter_mut()
                .zip(obs.par_chunks_mut(d))
                .for_each(|(s, o)| {
                    s.env.reset(&mut s.rng, o);
                    s.episode_return = 0.0;
                    s.episode_len = 0;
                    sanitize(o);
                })
        });
    }

    /// Steps every environment with its row of `actions` (row-major, env × act) and resets
    /// the ones whose episode ended; `obs` then holds the first observation of the new episode.
    pub fn step(&mut self, actions: &[f32]) {
        assert_eq!(
            actions.len(),
            self.slots.len() * self.act_dim,
            "action batch shape"
        );
        let (d, a, k) = (self.obs_dim, self.act_dim, self.n_terms);
        let (slots, obs, final_obs, infos, terms) = (
            &mut self.slots,
            &mut self.obs,
            &mut self.final_obs,
            &mut self.infos,
            &mut self.terms,
        );
        self.pool.install(|| {
            slots
                .par_iter_mut()
                .zip(obs.par_chunks_mut(d))
                .zip(final_obs.par_chunks_mut(d))
                .zip(actions.par_chunks(a))
                .zip(infos.par_iter_mut())
                .zip(terms.par_chunks_mut(k))
                .for_each(|(((((s, o), fo), act), info), t)| {
                    *info = step_slot(s, act, o, fo, t);
                })
        });
        self.ended.clear();
        for (i, (s, info)) in self.slots.iter_mut().zip(&self.infos).enumerate() {
            if info.terminated || info.truncated {
                self.ended.push(EpisodeEnd {
                    env: i,
                    episode_return: s.episode_return,
                    length: s.episode_len,
                    fell: info.terminated && !info.invalid,
                    invalid: info.invalid,
                });
                s.episode_return = 0.0;
                s.episode_len = 0;
            }
        }
    }
}

fn step_slot<E: Env>(
    s: &mut Slot<E>,
    action: &[f32],
    obs: &mut [f32],
    final_obs: &mut [f32],
    terms: &mut [f64],
) -> StepInfo {
    terms.iter_mut().for_each(|t| *t = 0.0);
    let mut info = if action.iter().all(|v| v.is_finite()) {
        s.env.step(action, &mut s.rng, obs, terms)
    } else {
        StepInfo {
            invalid: true,
            periods: None,
            ..Default::default()
        }
    };
    if !info.reward.is_finite() || obs.iter().any(|v| !v.is_finite()) {
        info.invalid = true;
    }
    if info.invalid {
        // A broken state is a failure: no bootstrap from it, and it is not shown to anyone.
        info.reward = 0.0;
        info.terminated = true;
        info.truncated = false;
        terms.iter_mut().for_each(|t| *t = 0.0);
    }
    s.episode_return += info.reward;
    s.episode_len += 1;
    if info.terminated || info.truncated {
        final_obs.copy_from_slice(obs);
        sanitize(final_obs);
        s.env.reset(&mut s.rng, obs);
        sanitize(obs);
    }
    info
}

/// `steps` batches of `len` actions, each uniform in [-1, 1] from a ChaCha8 RNG seeded `seed`:
/// the stepping measurements' inputs (`eemp bench rl`, the Python bindings' benchmark).
pub fn random_actions(len: usize, steps: usize, seed: u64) -> Vec<Vec<f32>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..steps)
        .map(|_| (0..len).map(|_| rng.random_range(-1.0..1.0)).collect())
        .collect()
}

/// Env steps per second of `v` stepped with each batch of `actions` in turn (row-major, env ×
/// act): the Rust side of `eemp bench rl` and of the Python bindings' throughput benchmark.
pub fn stepping_rate<E: Env>(v: &mut VecEnv<E>, actions: &[Vec<f32>]) -> f64 {
    let t = std::time::Instant::now();
    for a in actions {
        v.step(a);
    }
    (actions.len() * v.len()) as f64 / t.elapsed().as_secs_f64()
}

/// Replaces non-finite values (a reset can only produce them from a broken model) by 0.
fn sanitize(obs: &mut [f32]) {
    for v in obs {
        if !v.is_finite() {
            *v = 0.0;
        }
    }
}
