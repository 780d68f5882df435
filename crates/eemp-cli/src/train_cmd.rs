//! `eemp train`: trains a learned controller with PPO; progress bar, train.csv, checkpoints,
//! curves.png, policy.safetensors.

use crate::plots::{line_panels, Panel, Series};
use eemp_core::robot::RobotConfig;
use eemp_rl::config::{Optimizer, TaskKind, TrainConfig};
use eemp_rl::train::{train, TrainOptions};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct TrainArgs {
    /// model-free (the paper's RL baseline), imitation (its motion-imitation baseline), eemp-rl
    /// (the paper's learned planner parameters: PPO or CMA-ES, per the config's `optimizer`) or
    /// cart-pole (PPO's test task).
    #[arg(long)]
    pub task: String,
    /// Training config (TOML; every key optional, defaults in `eemp_rl::config`). Its `task`
    /// must agree with --task.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Output folder: train.csv, curves.png, checkpoint/, policy.safetensors, config.toml.
    #[arg(long)]
    pub out: PathBuf,
    /// Continue from the checkpoint in --out (same config → the same result as an
    /// uninterrupted run, whatever the thread count).
    #[arg(long)]
    pub resume: bool,
    /// Worker threads for environment stepping (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Override the config's total environment steps (e.g. a smoke run).
    #[arg(long)]
    pub env_steps: Option<u64>,
    /// Reference motion for --task imitation (a file of `eemp retarget`; overrides the
    /// config's imitation.motion_file).
    #[arg(long)]
    pub motion: Option<PathBuf>,
    /// Robot description (default: the shipped A1).
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// With `optimizer = "cmaes"`: a PPO run's train.csv whose return curve curves.png draws
    /// beside CMA-ES's, against decisions.
    #[arg(long)]
    pub compare_curve: Option<PathBuf>,
}

pub fn run(args: &TrainArgs) -> Result<(), String> {
    let task: TaskKind = args.task.parse()?;
    let mut config = match &args.config {
        Some(p) => TrainConfig::load(p).map_err(|e| e.to_string())?,
        None => TrainConfig {
            task,
            ..Default::default()
        },
    };
    if config.task != task {
        return Err(format!(
            "--task {} but {} is a config for task {}",
            task.name(),
            args.config
                .as_ref()
                .map(|p| p.display().to_string())
                .unwrap_or_default(),
            config.task.name()
        ));
    }
    if let Some(m) = &args.motion {
        if task != TaskKind::Imitation {
            return Err(format!(
                "--motion is for --task imitation, not {}",
                task.name()
            ));
        }
        config.imitation.motion_file = m.display().to_string();
    }
    if let Some(n) = args.env_steps {
        if n == 0 {
            return Err("--env-steps 0 is out of range: allowed ≥ 1".into());
        }
        config.total_env_steps = n;
    }
    config.validate().map_err(|e| e.to_string())?;
    let threads = match args.threads {
        Some(0) => return Err("--threads 0 is out of range: allowed ≥ 1".into()),
        Some(t) => t,
        None => std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1),
    };
    let robot = crate::robot_arg::load_robot(args.robot.as_deref())?;
    if !args.resume && args.out.join("checkpoint").join("state.json").exists() {
        return Err(format!(
            "{} already holds a training run: pass --resume to continue it, or choose another --out",
            args.out.display()
        ));
    }
    if config.optimizer == Optimizer::Cmaes {
        return run_cmaes(args, &config, &robot, threads);
    }
    if args.compare_curve.is_some() {
        return Err("--compare-curve is for optimizer = \"cmaes\" configs".into());
    }
    let bar = ProgressBar::new(config.total_env_steps);
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} env steps  {msg}  ETA {eta}")
            .expect("valid template"),
    );
    let opts = TrainOptions {
        out: args.out.clone(),
        resume: args.resume,
        threads,
        max_iterations: None,
    };
    let policy = train(&config, &robot, &opts, &mut |log| {
        bar.set_position(log.env_steps);
        bar.set_message(format!(
            "it {}  {:.0} steps/s  return {:.2}  len {:.0}  falls {}",
            log.iteration, log.env_steps_per_s, log.mean_return, log.mean_episode_len, log.falls
        ));
        if !bar.is_hidden() {
            return;
        }
        // No terminal: a line every 10 iterations for logs.
        if log.iteration % 10 == 0 {
            eprintln!(
                "it {} env_steps {} wall {:.0}s steps/s {:.0} return {:.3} len {:.0} falls {}",
                log.iteration,
                log.env_steps,
                log.wall_s,
                log.env_steps_per_s,
                log.mean_return,
                log.mean_episode_len,
                log.falls
            );
        }
    })?;
    bar.finish();
    policy.save(&args.out.join("policy.safetensors"))?;
    training_curves(
        &args.out.join("train.csv"),
        &args.out.join("curves.png"),
        task,
    )?;
    println!(
        "wrote {}/policy.safetensors, train.csv, curves.png, config.toml",
        args.out.display()
    );
    Ok(())
}

/// `eemp train` with `optimizer = "cmaes"`: table.toml, cmaes.csv, curves.png, config.toml.
fn run_cmaes(
    args: &TrainArgs,
    config: &TrainConfig,
    robot: &RobotConfig,
    threads: usize,
) -> Result<(), String> {
    let cache = args.out.join("checkpoint").join("evaluations.csv");
    if !args.resume && cache.exists() {
        return Err(format!(
            "{} already holds a CMA-ES run: pass --resume to continue it, or choose another --out",
            args.out.display()
        ));
    }
    if let Some(p) = &args.compare_curve {
        if !p.exists() {
            return Err(format!("--compare-curve {}: no such file", p.display()));
        }
    }
    let opts = TrainOptions {
        out: args.out.clone(),
        resume: args.resume,
        threads,
        max_iterations: None,
    };
    let bar = ProgressBar::new(config.total_env_steps);
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} decisions  {msg}  ETA {eta}")
            .expect("valid template"),
    );
    eemp_rl::cma_table::train_cmaes(config, robot, &opts, &mut |log| {
        bar.set_position(log.env_steps);
        let line = format!(
            "gen {} decisions {} wall {:.0}s mean {:.3} best {:.3} sigma {:.3} falls {}/{}",
            log.generation,
            log.env_steps,
            log.wall_s,
            log.mean_return,
            log.best_return,
            log.sigma,
            log.falls,
            log.episodes
        );
        match bar.is_hidden() {
            true => eprintln!("{line}"),
            false => bar.set_message(line),
        }
    })?;
    bar.finish();
    cmaes_curves(
        &args.out.join("cmaes.csv"),
        args.compare_curve.as_deref(),
        &args.out.join("curves.png"),
    )?;
    println!(
        "wrote {}/table.toml, cmaes.csv, curves.png, config.toml",
        args.out.display()
    );
    Ok(())
}

/// Columns `names` of a CSV file, as numbers (NaN where a cell is not one).
fn csv_columns(path: &Path, names: &[&str]) -> Result<Vec<Vec<f64>>, String> {
    let mut r =
        csv::Reader::from_path(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    let headers = r.headers().map_err(|e| e.to_string())?.clone();
    let idx: Vec<usize> = names
        .iter()
        .map(|n| {
            headers
                .iter()
                .position(|h| h == *n)
                .ok_or_else(|| format!("{} has no column {n}", path.display()))
        })
        .collect::<Result<_, _>>()?;
    let mut out = vec![Vec::new(); names.len()];
    for row in r.records() {
        let row = row.map_err(|e| format!("{}: {e}", path.display()))?;
        for (col, &i) in out.iter_mut().zip(&idx) {
            col.push(
                row.get(i)
                    .and_then(|s| s.parse::<f64>().ok())
                    .unwrap_or(f64::NAN),
            );
        }
    }
    Ok(out)
}

/// CMA-ES's return (population mean and best) against decisions, with PPO's mean return from
/// `ppo_csv` beside it; and the share of episodes that fell.
pub fn cmaes_curves(cmaes_csv: &Path, ppo_csv: Option<&Path>, png: &Path) -> Result<(), String> {
    let c = csv_columns(
        cmaes_csv,
        &[
            "env_steps",
            "mean_return",
            "best_return",
            "episodes",
            "falls",
        ],
    )?;
    let k = |v: &[f64]| v.iter().map(|x| x / 1e3).collect::<Vec<_>>();
    let fall_share: Vec<f64> = c[3]
        .iter()
        .zip(&c[4])
        .map(|(n, f)| f / n.max(1.0))
        .collect();
    let mut returns = vec![
        Series {
            label: "CMA-ES, population mean".into(),
            x: k(&c[0]),
            y: c[1].clone(),
        },
        Series {
            label: "CMA-ES, best candidate".into(),
            x: k(&c[0]),
            y: c[2].clone(),
        },
    ];
    let mut falls = vec![Series {
        label: "CMA-ES".into(),
        x: k(&c[0]),
        y: fall_share,
    }];
    if let Some(p) = ppo_csv {
        let v = csv_columns(p, &["env_steps", "mean_return", "episodes", "falls"])?;
        returns.push(Series {
            label: "PPO, mean of the last 100 episodes".into(),
            x: k(&v[0]),
            y: v[1].clone(),
        });
        falls.push(Series {
            label: "PPO".into(),
            x: k(&v[0]),
            y: v[2]
                .iter()
                .zip(&v[3])
                .map(|(n, f)| f / n.max(1.0))
                .collect(),
        });
    }
    let panels = vec![
        Panel {
            title: "episode return".into(),
            x_label: "decisions [thousands]".into(),
            y_label: "return [-]".into(),
            series: returns,
            markers: vec![],
            bands: vec![],
        },
        Panel {
            title: "episodes that fell".into(),
            x_label: "decisions [thousands]".into(),
            y_label: "share of episodes [-]".into(),
            series: falls,
            markers: vec![],
            bands: vec![],
        },
    ];
    line_panels(png, "EEMP-RL's residual: CMA-ES and PPO", &panels).map_err(|e| e.to_string())
}

/// The Fig. 9 analogue: return, episode length and falls against environment steps.
pub fn training_curves(csv_path: &Path, png: &Path, task: TaskKind) -> Result<(), String> {
    let mut r = csv::Reader::from_path(csv_path)
        .map_err(|e| format!("cannot read {}: {e}", csv_path.display()))?;
    let headers = r.headers().map_err(|e| e.to_string())?.clone();
    let col = |name: &str| headers.iter().position(|h| h == name);
    let (Some(is), Some(ir), Some(il), Some(ik)) = (
        col("env_steps"),
        col("mean_return"),
        col("mean_episode_len"),
        col("mean_step_reward"),
    ) else {
        return Err(format!("{} lacks the training columns", csv_path.display()));
    };
    let (mut x, mut ret, mut len, mut step) = (vec![], vec![], vec![], vec![]);
    for row in r.records() {
        let row = row.map_err(|e| e.to_string())?;
        let v = |i: usize| {
            row.get(i)
                .and_then(|s| s.parse::<f64>().ok())
                .unwrap_or(f64::NAN)
        };
        x.push(v(is) / 1e6);
        ret.push(v(ir));
        len.push(v(il));
        step.push(v(ik));
    }
    let keep = |y: &[f64]| -> (Vec<f64>, Vec<f64>) {
        x.iter()
            .zip(y)
            .filter(|(_, v)| v.is_finite())
            .map(|(a, b)| (*a, *b))
            .unzip()
    };
    let series = |label: &str, y: &[f64]| {
        let (xs, ys) = keep(y);
        Series {
            label: label.into(),
            x: xs,
            y: ys,
        }
    };
    let panels = vec![
        Panel {
            title: "mean episode return (last 100 episodes)".into(),
            x_label: "environment steps [millions]".into(),
            y_label: "return [-]".into(),
            series: vec![series("PPO", &ret)],
            markers: vec![],
            bands: vec![],
        },
        Panel {
            title: "mean reward per policy step".into(),
            x_label: "environment steps [millions]".into(),
            y_label: "reward per step [-]".into(),
            series: vec![series("PPO", &step)],
            markers: vec![],
            bands: vec![],
        },
        Panel {
            title: "mean episode length (last 100 episodes)".into(),
            x_label: "environment steps [millions]".into(),
            y_label: "policy steps [-]".into(),
            series: vec![series("PPO", &len)],
            markers: vec![],
            bands: vec![],
        },
    ];
    line_panels(
        png,
        &format!(
            "Training curves ({}): the paper's Fig. 9 analogue",
            task.name()
        ),
        &panels,
    )
    .map_err(|e| e.to_string())
}
