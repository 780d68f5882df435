//! EEMP-RL's second optimiser (issue 20, part 6): CMA-ES (the `cmaes` crate) on the same
//! residual task PPO trains on, as Yang et al. (CoRL 2021) tuned gait parameters over a convex
//! MPC.
//!
//! CMA-ES cannot search a 128×128 network's ≈ 20 000 weights (its covariance is n²), so its
//! policy is the residual's open-loop form: one bounded correction per entry of the table,
//! x ∈ ℝ^(5 × entries), and at each decision the action is the slice of x of the entry nearest
//! to the commanded speed (Δ = bounds ⊙ tanh(x), the PPO policy's own squashing without a
//! deadband, which CMA-ES refuses). With the table's nearest-entry look-up this is exactly a
//! re-tuned table, which is what the run writes
//! (`table.toml`, usable as `eemp walk --gait free --params-table …`).
//!
//! Fitness: a candidate's mean undiscounted return over `episodes_per_candidate` episodes of the
//! EEMP-RL environment (same rewards, worlds, filter, pushes and commands as PPO's), the same
//! episodes for every candidate of a generation (common random numbers), new ones every
//! generation. The budget is the config's `total_env_steps` counted in decisions, as for PPO.
//!
//! Per entry (`cmaes.per_entry`, issue 20): one 5-dimensional search per table
//! entry instead of one over all of them, each on episodes commanded at that entry's speed
//! throughout, with the budget split evenly between the entries. The joint search gives each
//! entry only the few command segments that fall near its speed, on a 5 × entries-dimensional
//! covariance; the entries are independent under the nearest-entry look-up (but for the first
//! 0.5 s of every episode, commanded 0 and so walked on the first entry as kept so far), so
//! searching them apart loses little. Each entry searches until its share of the budget is used
//! (the last generation may overrun it), and the validation episodes come on top of the budget.
//! Moving one parameter of one entry by hand finds corrections that lower CoT at that entry's
//! speed, which a search over all entries at once (and PPO) misses in its larger space. After
//! its search, an entry's correction (the distribution's mean) is
//! kept only if it beats the table on `validation_episodes` fresh episodes, the same ones for
//! both (else the entry stays the table's): a correction that only wins on the noise of the
//! search's own episodes is not a gain. With `nominal_episodes` it must also, on that many fresh
//! episodes in the robot file's own world (flat floor, no payload, no pushes), walk without a
//! fall at no more than `nominal_cot_tolerance` above the table's energy per distance: the
//! return counts tracking too, so without this check an entry can be kept for better tracking
//! at more CoT on the flat floor than issue 20 allows (3 %).
//!
//! Resume: the CMA-ES state is not serialisable, but the search is deterministic given its seed
//! and the fitness values, so `checkpoint/evaluations.csv` records every evaluation and a resumed
//! run replays them (without simulating) up to where the killed one stopped: the result equals an
//! uninterrupted run's, whatever the thread count.

use crate::config::TrainConfig;
use eemp_core::planner::params_table::{ParamsTable, TableEntry};
// The search itself (CMA-ES, episodes, the cache) is part of the `learning` feature.
#[cfg(feature = "learning")]
use {
    crate::tasks::eemp_rl::{EempRlEnv, ACT_DIM},
    crate::tasks::OnClosedLoop,
    crate::train::{training_state_source, TrainOptions},
    cmaes::{CMAESOptions, DVector, Mode},
    eemp_core::robot::RobotConfig,
    rand::SeedableRng,
    rand_chacha::ChaCha8Rng,
    rayon::prelude::*,
    std::collections::HashMap,
    std::io::Write,
    std::path::Path,
    std::sync::atomic::{AtomicUsize, Ordering},
    std::sync::Mutex,
    std::time::Instant,
};

// The `[cmaes]` settings and their check belong to the training config, below the search.
pub use crate::config::{check_cmaes_config as check_config, CmaesConfig};

/// One generation's line of `cmaes.csv`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GenerationLog {
    pub generation: usize,
    /// Decisions taken so far (PPO's `env_steps`).
    pub env_steps: u64,
    pub wall_s: f64,
    /// Mean fitness (mean episode return) of the generation's candidates.
    pub mean_return: f64,
    pub best_return: f64,
    pub sigma: f64,
    pub episodes: usize,
    pub falls: usize,
}

#[cfg(feature = "learning")]
const CSV_HEADER: &str =
    "generation,env_steps,wall_s,mean_return,best_return,sigma,episodes,falls\n";

#[cfg(feature = "learning")]
/// One candidate's evaluation.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Evaluation {
    fitness: f64,
    steps: u64,
    falls: usize,
    /// The episodes' energy (the reward's, `rewards.objective`) and distance summed over their decision
    /// intervals (NaN in a cache written before they were recorded).
    energy_j: f64,
    distance_m: f64,
}

#[cfg(feature = "learning")]
impl Evaluation {
    /// The evaluation's fields of a `checkpoint/evaluations.csv` row, `wall_s` last.
    fn cache_row(&self, wall_s: f64) -> String {
        format!(
            "{:?},{},{},{:?},{:?},{wall_s:?}",
            self.fitness, self.steps, self.falls, self.energy_j, self.distance_m
        )
    }
}

#[cfg(feature = "learning")]
/// The exact bits of a candidate: a replayed search proposes bit-identical ones.
fn key(x: &[f64]) -> String {
    x.iter().map(|v| format!("{:016x}", v.to_bits())).collect()
}

/// The table the candidate `x` stands for: each entry corrected by Δ = bounds ⊙ tanh(x_entry),
/// clipped to the table's ranges ([`ParamsTable::param_ranges`]: Table I, widened to its
/// entries); metrics dropped (they were the original's).
pub fn corrected_table(table: &ParamsTable, bounds: &[f64; 5], x: &[f64]) -> ParamsTable {
    let ranges = table.param_ranges();
    let entries = table
        .entries
        .iter()
        .enumerate()
        .map(|(k, e)| {
            let delta: [f64; 5] = std::array::from_fn(|i| bounds[i] * x[5 * k + i].tanh());
            TableEntry::new(e.speed_mps, &e.params().offset_within(&delta, &ranges))
        })
        .collect();
    ParamsTable {
        entries,
        ..table.clone()
    }
}

#[cfg(feature = "learning")]
/// Runs CMA-ES on EEMP-RL's residual; writes `cmaes.csv`, `checkpoint/evaluations.csv`,
/// `table.toml` (the distribution's mean, the usual answer on a noisy objective) and
/// `config.toml` in `opts.out` (per entry also `validation.csv`), and calls `on_generation` after
/// each generation.
pub fn train_cmaes(
    config: &TrainConfig,
    robot: &RobotConfig,
    opts: &TrainOptions,
    on_generation: &mut dyn FnMut(&GenerationLog),
) -> Result<ParamsTable, String> {
    check_config(config).map_err(|e| e.to_string())?;
    let residual = config.eemp_rl.residual.as_ref().expect("checked");
    let table = residual
        .table
        .clone()
        .ok_or("the residual's table is not read")?;
    let bounds = residual.bounds.to_array();
    let dim = ACT_DIM * table.entries.len();
    std::fs::create_dir_all(opts.out.join("checkpoint"))
        .map_err(|e| format!("cannot create {}: {e}", opts.out.display()))?;
    let cache_path = opts.out.join("checkpoint").join("evaluations.csv");
    let cache = if opts.resume {
        read_cache(&cache_path)?
    } else {
        HashMap::new()
    };
    let cache_file = open_append(&cache_path, !opts.resume)?;
    let mut log_file = std::fs::File::create(opts.out.join("cmaes.csv"))
        .map_err(|e| format!("cannot write cmaes.csv: {e}"))?;
    log_file
        .write_all(CSV_HEADER.as_bytes())
        .map_err(|e| e.to_string())?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(opts.threads.max(1))
        .build()
        .map_err(|e| e.to_string())?;
    let mut run = Run {
        config,
        robot,
        table: &table,
        bounds,
        pool,
        cache,
        cache_path,
        cache_file,
        log_file,
        log: GenerationLog::default(),
        replayed_wall: 0.0,
        started: Instant::now(),
        out: &opts.out,
    };
    let x = match config.cmaes.per_entry {
        false => run.search(
            config,
            &vec![0.0; dim],
            &(0..dim).collect::<Vec<_>>(),
            0,
            config.total_env_steps,
            on_generation,
        )?,
        true => {
            let n = table.entries.len();
            let mut x = vec![0.0; dim];
            let mut validation = std::fs::File::create(opts.out.join("validation.csv"))
                .map_err(|e| format!("cannot write validation.csv: {e}"))?;
            writeln!(
                validation,
                "entry,speed_mps,episodes,table_return,corrected_return,\
                 nominal_episodes,table_nominal_j_per_m,corrected_nominal_j_per_m,\
                 corrected_nominal_falls,kept"
            )
            .map_err(|e| e.to_string())?;
            for k in 0..n {
                let speed = table.entries[k].speed_mps;
                // Commanded at the entry's speed throughout (from command_start_s on).
                let mut at_speed = config.clone();
                at_speed.eemp_rl.vx_mps = [speed, speed];
                let slots: Vec<usize> = (ACT_DIM * k..ACT_DIM * (k + 1)).collect();
                // Each entry's generations and episodes are numbered apart from the others'.
                let offset = k * ENTRY_GENERATIONS;
                let budget = config.total_env_steps / n as u64;
                // A budget below one decision per entry (a smoke run): nothing searched, the
                // entry stays the table's.
                if budget > 0 {
                    let found = run.search(&at_speed, &x, &slots, offset, budget, on_generation)?;
                    let (v, nv) = (
                        config.cmaes.validation_episodes,
                        config.cmaes.nominal_episodes,
                    );
                    let keep = (v == 0 && nv == 0) || {
                        let check = run.check_entry(&at_speed, &x, &found, offset)?;
                        writeln!(validation, "{k},{speed},{v},{}", check.csv_fields(nv))
                            .and_then(|_| validation.flush())
                            .map_err(|e| format!("cannot write validation.csv: {e}"))?;
                        check.keep
                    };
                    if keep {
                        x = found;
                    }
                }
                write_table(
                    &opts.out.join("table.toml"),
                    &corrected_table(&table, &bounds, &x),
                    config,
                    &run.log,
                )?;
            }
            x
        }
    };
    std::fs::write(
        opts.out.join("config.toml"),
        toml::to_string(config).map_err(|e| e.to_string())?,
    )
    .map_err(|e| format!("cannot write config.toml: {e}"))?;
    Ok(corrected_table(&table, &bounds, &x))
}

/// An entry's checks after its search ([`Run::check_entry`]): each pair is (table, corrected).
#[cfg(feature = "learning")]
struct EntryCheck {
    /// Mean returns on the fresh disturbed episodes (NaN without them).
    returns: [f64; 2],
    /// Energy per distance on the fresh nominal episodes, J/m (NaN without them).
    nominal_j_per_m: [f64; 2],
    /// The corrected table's falls there (None without them).
    nominal_falls: Option<usize>,
    keep: bool,
}

#[cfg(feature = "learning")]
impl EntryCheck {
    /// `validation.csv`'s fields after `entry,speed_mps,episodes` (the nominal falls empty
    /// without that check).
    fn csv_fields(&self, nominal_episodes: usize) -> String {
        format!(
            "{:?},{:?},{nominal_episodes},{:?},{:?},{},{}",
            self.returns[0],
            self.returns[1],
            self.nominal_j_per_m[0],
            self.nominal_j_per_m[1],
            self.nominal_falls.map_or(String::new(), |f| f.to_string()),
            self.keep
        )
    }
}

/// Generations numbered per entry (the per-entry search's entry k uses k × this onwards; its last
/// number holds the validation episodes, the one before it the nominal ones).
#[cfg(feature = "learning")]
const ENTRY_GENERATIONS: usize = 1_000_000;

/// The episodes a generation's candidates run: `count` of them, numbered from
/// `generation × count`.
#[cfg(feature = "learning")]
#[derive(Clone, Copy)]
struct EpisodeSet {
    generation: usize,
    count: usize,
}

/// One training run's shared state: the evaluation cache (a resumed run replays it), the logs
/// and the decision count.
#[cfg(feature = "learning")]
struct Run<'a> {
    config: &'a TrainConfig,
    robot: &'a RobotConfig,
    table: &'a ParamsTable,
    bounds: [f64; 5],
    pool: rayon::ThreadPool,
    cache: Cache,
    cache_path: std::path::PathBuf,
    cache_file: std::fs::File,
    log_file: std::fs::File,
    log: GenerationLog,
    replayed_wall: f64,
    started: Instant,
    out: &'a Path,
}

#[cfg(feature = "learning")]
impl Run<'_> {
    /// `x`'s evaluation on `episodes` of `episode_config`, from the cache when a killed run made
    /// it already (else simulated and recorded).
    fn evaluate_cached(
        &mut self,
        episode_config: &TrainConfig,
        x: &[f64],
        episodes: EpisodeSet,
    ) -> Result<Evaluation, String> {
        let k = (episodes.generation, key(x));
        if let Some(e) = self.cache.get(&k) {
            self.replayed_wall = self.replayed_wall.max(e.1);
            return Ok(e.0);
        }
        let e = self
            .pool
            .install(|| evaluate(episode_config, self.robot, self.table, x, episodes))?;
        let wall_s = self.replayed_wall + self.started.elapsed().as_secs_f64();
        writeln!(self.cache_file, "{},{},{}", k.0, k.1, e.cache_row(wall_s))
            .and_then(|_| self.cache_file.flush())
            .map_err(|e| format!("cannot write {}: {e}", self.cache_path.display()))?;
        self.cache.insert(k, (e, wall_s));
        Ok(e)
    }

    /// The checks an entry's correction `found` must pass against `x` (the table's entry) to be
    /// kept: a higher return on fresh disturbed episodes (`cmaes.validation_episodes`) and, on
    /// fresh episodes in the robot file's own world (`cmaes.nominal_episodes`), no fall and an
    /// energy per distance at most `nominal_cot_tolerance` above the table's. Both sets come
    /// after the entry's search (`offset`), the same for both tables.
    fn check_entry(
        &mut self,
        at_speed: &TrainConfig,
        x: &[f64],
        found: &[f64],
        offset: usize,
    ) -> Result<EntryCheck, String> {
        let cfg = &self.config.cmaes;
        let (v, nv, tolerance) = (
            cfg.validation_episodes,
            cfg.nominal_episodes,
            cfg.nominal_cot_tolerance,
        );
        let mut check = EntryCheck {
            returns: [f64::NAN; 2],
            nominal_j_per_m: [f64::NAN; 2],
            nominal_falls: None,
            keep: true,
        };
        if v > 0 {
            let episodes = EpisodeSet {
                generation: offset + ENTRY_GENERATIONS - 1,
                count: v,
            };
            let base = self.evaluate_cached(at_speed, x, episodes)?;
            let corrected = self.evaluate_cached(at_speed, found, episodes)?;
            check.keep = corrected.fitness > base.fitness;
            check.returns = [base.fitness, corrected.fitness];
        }
        if nv > 0 {
            let mut nominal = at_speed.clone();
            if let Some(w) = &mut nominal.eemp_rl.worlds {
                w.nominal_share = 1.0;
            }
            let episodes = EpisodeSet {
                generation: offset + ENTRY_GENERATIONS - 2,
                count: nv,
            };
            let base = self.evaluate_cached(&nominal, x, episodes)?;
            let corrected = self.evaluate_cached(&nominal, found, episodes)?;
            // Eq. (8) in J/m over all the episodes (m g is the same for both tables).
            let [table, ours] = [&base, &corrected].map(|e| {
                eemp_core::metrics::cost_of_transport_j_per_m(e.energy_j, e.distance_m)
                    .unwrap_or(f64::NAN)
            });
            check.nominal_j_per_m = [table, ours];
            check.nominal_falls = Some(corrected.falls);
            // No distance (a non-finite energy per distance) fails the check.
            check.keep &=
                corrected.falls == 0 && ours.is_finite() && ours <= table * (1.0 + tolerance);
        }
        Ok(check)
    }

    /// CMA-ES over the components `slots` of the correction `x0` (the others held), on
    /// `episode_config`'s episodes, for `budget` decisions; generations numbered from `offset`.
    /// Returns `x0` with the search's final mean in `slots`.
    fn search(
        &mut self,
        episode_config: &TrainConfig,
        x0: &[f64],
        slots: &[usize],
        offset: usize,
        budget: u64,
        on_generation: &mut dyn FnMut(&GenerationLog),
    ) -> Result<Vec<f64>, String> {
        let cfg = &self.config.cmaes;
        let embed = |y: &[f64]| -> Vec<f64> {
            let mut x = x0.to_vec();
            for (s, v) in slots.iter().zip(y) {
                x[*s] = *v;
            }
            x
        };
        let start: Vec<f64> = slots.iter().map(|s| x0[*s]).collect();
        let generation = AtomicUsize::new(offset);
        let fresh: Mutex<HashMap<(usize, String), Evaluation>> = Mutex::new(HashMap::new());
        let failure: Mutex<Option<String>> = Mutex::new(None);
        let (cache, robot, table) = (&self.cache, self.robot, self.table);
        let objective = |y: &DVector<f64>| -> f64 {
            let g = generation.load(Ordering::SeqCst);
            let x = embed(y.as_slice());
            let k = key(&x);
            if let Some(e) = cache.get(&(g, k.clone())) {
                fresh.lock().expect("no panic").insert((g, k), e.0);
                return e.0.fitness;
            }
            let episodes = EpisodeSet {
                generation: g,
                count: cfg.episodes_per_candidate,
            };
            match evaluate(episode_config, robot, table, &x, episodes) {
                Ok(e) => {
                    fresh.lock().expect("no panic").insert((g, k), e);
                    e.fitness
                }
                Err(err) => {
                    *failure.lock().expect("no panic") = Some(err);
                    f64::NAN
                }
            }
        };
        let mut options = CMAESOptions::new(start, cfg.initial_sigma)
            .mode(Mode::Maximize)
            .seed(self.config.seed.wrapping_add(offset as u64))
            .max_function_evals(usize::MAX)
            .tol_stagnation(usize::MAX);
        if cfg.population != 0 {
            options = options.population_size(cfg.population);
        }
        let mut cma = options
            .build(&objective)
            .map_err(|e| format!("CMA-ES options: {e:?}"))?;
        let mut used = 0u64;
        while used < budget {
            let g = offset + cma.generation();
            if cfg.per_entry && g + 2 >= offset + ENTRY_GENERATIONS {
                // The entry's last two numbers hold its validation episodes.
                return Err(format!(
                    "entry search at generation {}: more than {} generations per entry",
                    g - offset,
                    ENTRY_GENERATIONS - 2
                ));
            }
            generation.store(g, Ordering::SeqCst);
            let stop = self.pool.install(|| cma.next_parallel());
            if let Some(err) = failure.lock().expect("no panic").take() {
                return Err(err);
            }
            let mut evals: Vec<((usize, String), Evaluation)> = fresh
                .lock()
                .expect("no panic")
                .drain()
                .filter(|((gen, _), _)| *gen == g)
                .collect();
            // In key order: logs and sums the same whatever order the threads finished in.
            evals.sort_by(|a, b| a.0.cmp(&b.0));
            let was_cached = evals.iter().all(|(k, _)| self.cache.contains_key(k));
            let wall_s = match was_cached {
                true => {
                    self.replayed_wall = evals
                        .iter()
                        .filter_map(|(k, _)| self.cache.get(k).map(|c| c.1))
                        .fold(self.replayed_wall, f64::max);
                    self.replayed_wall
                }
                false => self.replayed_wall + self.started.elapsed().as_secs_f64(),
            };
            if !was_cached {
                for ((gen, k), e) in &evals {
                    writeln!(self.cache_file, "{gen},{k},{}", e.cache_row(wall_s))
                        .map_err(|e| format!("cannot write {}: {e}", self.cache_path.display()))?;
                }
                self.cache_file.flush().map_err(|e| e.to_string())?;
            }
            let steps: u64 = evals.iter().map(|(_, e)| e.steps).sum();
            used += steps;
            let fitness: Vec<f64> = evals.iter().map(|(_, e)| e.fitness).collect();
            self.log = GenerationLog {
                generation: self.log.generation + 1,
                env_steps: self.log.env_steps + steps,
                wall_s,
                mean_return: fitness.iter().sum::<f64>() / fitness.len().max(1) as f64,
                best_return: fitness.iter().copied().fold(f64::NEG_INFINITY, f64::max),
                sigma: cma.sigma(),
                episodes: evals.len() * cfg.episodes_per_candidate,
                falls: evals.iter().map(|(_, e)| e.falls).sum(),
            };
            let log = &self.log;
            writeln!(
                self.log_file,
                "{},{},{:.3},{:?},{:?},{:?},{},{}",
                log.generation,
                log.env_steps,
                log.wall_s,
                log.mean_return,
                log.best_return,
                log.sigma,
                log.episodes,
                log.falls
            )
            .and_then(|_| self.log_file.flush())
            .map_err(|e| format!("cannot write cmaes.csv: {e}"))?;
            // Per entry the table is written once an entry is validated (its header says so).
            if !cfg.per_entry {
                let x = embed(cma.mean().as_slice());
                let out = corrected_table(self.table, &self.bounds, &x);
                write_table(&self.out.join("table.toml"), &out, self.config, &self.log)?;
            }
            on_generation(&self.log);
            if let Some(t) = stop {
                eprintln!(
                    "note: CMA-ES stopped at generation {} ({:?})",
                    self.log.generation, t.reasons
                );
                break;
            }
        }
        Ok(embed(cma.mean().as_slice()))
    }
}

/// Candidate `x`'s fitness on `episodes`: the mean return of its episodes.
#[cfg(feature = "learning")]
fn evaluate(
    config: &TrainConfig,
    robot: &RobotConfig,
    table: &ParamsTable,
    x: &[f64],
    episodes: EpisodeSet,
) -> Result<Evaluation, String> {
    let n = episodes.count;
    let results: Vec<Result<Episode, String>> = (0..n)
        .into_par_iter()
        .map(|e| run_episode(config, robot, table, x, episodes.generation * n + e))
        .collect();
    let mut total = Evaluation {
        fitness: 0.0,
        steps: 0,
        falls: 0,
        energy_j: 0.0,
        distance_m: 0.0,
    };
    for r in results {
        let e = r?;
        total.fitness += e.ret / n as f64;
        total.steps += e.steps;
        total.falls += e.fell as usize;
        total.energy_j += e.energy_j;
        total.distance_m += e.distance_m;
    }
    Ok(total)
}

/// One episode's outcome.
#[cfg(feature = "learning")]
struct Episode {
    ret: f64,
    /// Decisions taken.
    steps: u64,
    fell: bool,
    /// Summed over the decision intervals (the reward's energy, `rewards.objective`, and ΔD
    /// of each).
    energy_j: f64,
    distance_m: f64,
}

/// Episode `index` of the run (its world, filter noise, start, commands and pushes fixed by the
/// config's seed and `index`) under the correction `x`.
#[cfg(feature = "learning")]
fn run_episode(
    config: &TrainConfig,
    robot: &RobotConfig,
    table: &ParamsTable,
    x: &[f64],
    index: usize,
) -> Result<Episode, String> {
    let mut env = match &config.eemp_rl.worlds {
        Some(w) => EempRlEnv::in_world(robot, &w.draw(config.seed, index), config.eemp_rl.clone())?,
        None => {
            let model = eemp_sim::backend::build_model(robot, &Default::default())
                .map_err(|e| e.to_string())?;
            EempRlEnv::new(robot, model, config.eemp_rl.clone())?
        }
    };
    env.set_state_source(&training_state_source(config, robot, index as u64))?;
    let mut rng = ChaCha8Rng::seed_from_u64(
        config
            .seed
            .wrapping_mul(0xC3A5_C85C_97CB_3127)
            .wrapping_add(index as u64),
    );
    use crate::env::Env;
    let (fall_penalty, objective) = config
        .eemp_rl
        .residual
        .as_ref()
        .map_or((0.0, Default::default()), |r| {
            (r.rewards.fall, r.rewards.objective)
        });
    let mut obs = vec![0f32; env.obs_dim()];
    let mut terms = vec![0f64; env.reward_terms().len()];
    env.reset(&mut rng, &mut obs);
    let mut out = Episode {
        ret: 0.0,
        steps: 0,
        fell: false,
        energy_j: 0.0,
        distance_m: 0.0,
    };
    loop {
        let k = table.nearest_entry(env.commanded_speed_mps());
        let action: [f32; ACT_DIM] = std::array::from_fn(|i| x[ACT_DIM * k + i] as f32);
        let info = env.step(&action, &mut rng, &mut obs, &mut terms);
        // A non-finite reward (an unstable simulation) counts as the fall it ends in.
        out.ret += match info.reward.is_finite() {
            true => info.reward,
            false => -fall_penalty,
        };
        out.steps += 1;
        if let Some(m) = env.last_interval() {
            out.energy_j += objective.energy_j(m).unwrap_or(f64::NAN);
            out.distance_m += m.distance_m;
        }
        if info.invalid || info.terminated || info.truncated {
            out.fell = info.invalid || info.terminated;
            return Ok(out);
        }
    }
}

#[cfg(feature = "learning")]
type Cache = HashMap<(usize, String), (Evaluation, f64)>;

#[cfg(feature = "learning")]
fn read_cache(path: &Path) -> Result<Cache, String> {
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(_) => {
            eprintln!(
                "note: no evaluations in {}; starting from scratch",
                path.display()
            );
            return Ok(HashMap::new());
        }
    };
    let mut out = HashMap::new();
    // A row cut by a kill (the text after the last line break) is dropped, from the file too, so
    // that the rows this run appends start on a line of their own: that evaluation runs again.
    let complete = &text[..text.rfind('\n').map_or(0, |i| i + 1)];
    if complete.len() < text.len() {
        std::fs::OpenOptions::new()
            .write(true)
            .open(path)
            .and_then(|f| f.set_len(complete.len() as u64))
            .map_err(|e| format!("cannot cut the partial last row of {}: {e}", path.display()))?;
    }
    for (n, line) in complete.lines().enumerate() {
        let f: Vec<&str> = line.split(',').collect();
        let bad = || format!("{} line {}: not an evaluation row", path.display(), n + 1);
        let parse = |s: &str| s.parse::<f64>().map_err(|_| bad());
        // Rows written before energy and distance were recorded have 6 fields.
        let (energy_j, distance_m) = match f.len() {
            6 => (f64::NAN, f64::NAN),
            8 => (parse(f[5])?, parse(f[6])?),
            _ => return Err(bad()),
        };
        let e = Evaluation {
            fitness: parse(f[2])?,
            steps: f[3].parse().map_err(|_| bad())?,
            falls: f[4].parse().map_err(|_| bad())?,
            energy_j,
            distance_m,
        };
        out.insert(
            (f[0].parse().map_err(|_| bad())?, f[1].to_string()),
            (e, parse(f[f.len() - 1])?),
        );
    }
    Ok(out)
}

#[cfg(feature = "learning")]
fn open_append(path: &Path, truncate: bool) -> Result<std::fs::File, String> {
    std::fs::OpenOptions::new()
        .create(true)
        .append(!truncate)
        .write(true)
        .truncate(truncate)
        .open(path)
        .map_err(|e| format!("cannot write {}: {e}", path.display()))
}

#[cfg(feature = "learning")]
fn write_table(
    path: &Path,
    table: &ParamsTable,
    config: &TrainConfig,
    log: &GenerationLog,
) -> Result<(), String> {
    let how = match config.cmaes.per_entry {
        false => "",
        // Per entry the mean is that of each entry's own search, kept where it passed its checks.
        true => " (one search per entry; an entry\n# is the table's where its correction did not beat the table on fresh episodes, or, with\n# cmaes.nominal_episodes, cost more energy per distance on the flat floor: validation.csv)",
    };
    let text = format!(
        "# EEMP-RL by CMA-ES (issue 20, part 6): the residual's table ({}) re-tuned, each entry\n\
         # corrected by the search distribution's mean after generation {} ({} decisions, seed {}){how}.\n\
         # Use: eemp walk --gait free --params-table <this file>\n{}",
        config
            .eemp_rl
            .residual
            .as_ref()
            .map(|r| r.table_file.display().to_string())
            .unwrap_or_default(),
        log.generation,
        log.env_steps,
        config.seed,
        table.to_toml()
    );
    std::fs::write(path, text).map_err(|e| format!("cannot write {}: {e}", path.display()))
}
