//! The run list: every (grid point, seed) in canonical order, with stable ids, and the shards
//! that split it.

use crate::config::{gait_rank, Grid};
use crate::error::StudyError;
use eemp_core::planner::{Gait, PlannerParams};
use std::fmt;
use std::str::FromStr;

/// One grid point: a gait, a commanded speed and the five planner parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridPoint {
    pub gait: Gait,
    pub speed_mps: f64,
    pub params: PlannerParams,
    pub duration_s: f64,
}

/// One run: a grid point and a start seed. `index` is its position in [`Grid::runs`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RunSpec {
    pub index: usize,
    pub point: GridPoint,
    pub seed: u64,
}

/// A stable 64-bit id: FNV-1a of a canonical parameter string, shown as 16 hex digits.
/// It depends only on the parameter values, never on process, platform or map order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct RunId(pub u64);

impl RunId {
    pub fn of(canonical: &str) -> Self {
        RunId(eemp_core::robot::fnv1a64(canonical))
    }
}

impl fmt::Display for RunId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:016x}", self.0)
    }
}

impl FromStr for RunId {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        if s.len() != 16 {
            return Err(format!("'{s}' is not a 16-digit hex run id"));
        }
        u64::from_str_radix(s, 16)
            .map(RunId)
            .map_err(|_| format!("'{s}' is not a 16-digit hex run id"))
    }
}

impl serde::Serialize for RunId {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> serde::Deserialize<'de> for RunId {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        s.parse().map_err(serde::de::Error::custom)
    }
}

impl GridPoint {
    /// `gait=trot;speed_mps=0.5;swing_time_s=0.25;…;duration_s=20`: numbers in Rust's shortest
    /// round-trip form, so equal values always give the same text.
    pub fn canonical(&self) -> String {
        let p = &self.params;
        format!(
            "gait={};speed_mps={};swing_time_s={};step_height_m={};body_height_m={};\
             ellipse_rx_m={};ellipse_ry_m={};duration_s={}",
            self.gait,
            self.speed_mps,
            p.swing_time_s,
            p.step_height_m,
            p.body_height_m,
            p.ellipse_rx_m,
            p.ellipse_ry_m,
            self.duration_s
        )
    }

    /// Id of the grid point (all seeds share it).
    pub fn point_id(&self) -> RunId {
        RunId::of(&self.canonical())
    }
}

impl RunSpec {
    /// The point's canonical string followed by `;seed=N`.
    pub fn canonical(&self) -> String {
        format!("{};seed={}", self.point.canonical(), self.seed)
    }

    pub fn run_id(&self) -> RunId {
        RunId::of(&self.canonical())
    }
}

impl Grid {
    /// Every run in canonical order: gait (trot, walk, free), then speed, ΔT, h_step, X_z, r_x,
    /// r_y and seed, each ascending. The order (and so every run's index) depends only on the
    /// grid.
    pub fn runs(&self) -> Vec<RunSpec> {
        let mut runs = Vec::with_capacity(self.run_count());
        let mut gaits = self.gaits.clone();
        gaits.sort_by_key(|g| gait_rank(*g));
        for &gait in &gaits {
            for &speed_mps in &self.speed_mps {
                for &swing_time_s in &self.swing_time_s {
                    for &step_height_m in &self.step_height_m {
                        for &body_height_m in &self.body_height_m {
                            for &ellipse_rx_m in &self.ellipse_rx_m {
                                for &ellipse_ry_m in &self.ellipse_ry_m {
                                    let point = GridPoint {
                                        gait,
                                        speed_mps,
                                        params: PlannerParams {
                                            swing_time_s,
                                            step_height_m,
                                            body_height_m,
                                            ellipse_rx_m,
                                            ellipse_ry_m,
                                        },
                                        duration_s: self.duration_s,
                                    };
                                    for &seed in &self.seeds {
                                        runs.push(RunSpec {
                                            index: runs.len(),
                                            point,
                                            seed,
                                        });
                                    }
                                }
                            }
                        }
                    }
                }
            }
        }
        runs
    }
}

/// `--shard K/N`: the K-th (1-based) of N disjoint slices of the run list; run `i` belongs to
/// shard `i % N + 1`, so every shard gets a similar mix of gaits and speeds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl Shard {
    pub fn contains(&self, run_index: usize) -> bool {
        run_index % self.count == self.index - 1
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl FromStr for Shard {
    type Err = StudyError;
    fn from_str(s: &str) -> Result<Self, StudyError> {
        let err = |message: String| StudyError::Shard {
            value: s.to_string(),
            message,
        };
        let (k, n) = s
            .split_once('/')
            .ok_or_else(|| err("expected K/N, e.g. 2/8 for the second of 8 shards".into()))?;
        let parse = |what: &str, v: &str| {
            v.trim().parse::<usize>().map_err(|_| {
                err(format!(
                    "{what} = '{v}' is not a whole number (expected K/N, e.g. 2/8)"
                ))
            })
        };
        let (index, count) = (parse("K", k)?, parse("N", n)?);
        if count < 1 {
            return Err(err("N = 0 is out of range: allowed 1 or more".into()));
        }
        if index < 1 || index > count {
            return Err(err(format!(
                "K = {index} is out of range: allowed 1..={count} (K is 1-based)"
            )));
        }
        Ok(Shard { index, count })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::SweepConfig;
    use std::collections::HashSet;
    use std::path::Path;

    fn grid() -> Grid {
        SweepConfig::parse(
            r#"
[grid]
gaits = ["walk", "trot"]
speed_mps = [0.5, 0.1, 1.0]
swing_time_s = [0.25, 0.2]
step_height_m = [0.1]
body_height_m = [0.31, 0.28]
ellipse_rx_m = [0.07]
ellipse_ry_m = [0.05]
duration_s = 20
seeds = [0, 3]
"#,
            Path::new("t.toml"),
        )
        .unwrap()
        .grid
    }

    #[test]
    fn expansion_count_and_canonical_order() {
        let g = grid();
        let runs = g.runs();
        assert_eq!(runs.len(), 2 * 3 * 2 * 2 * 2);
        assert_eq!(runs.len(), g.run_count());
        assert!(runs.iter().enumerate().all(|(i, r)| r.index == i));
        // Trot before walk, then speed, ΔT, …, seed innermost, all ascending.
        assert_eq!(runs[0].point.gait, Gait::Trot);
        assert_eq!(runs[0].point.speed_mps, 0.1);
        assert_eq!(runs[0].point.params.swing_time_s, 0.2);
        assert_eq!(runs[0].point.params.body_height_m, 0.28);
        assert_eq!((runs[0].seed, runs[1].seed), (0, 3));
        assert_eq!(runs[2].point.params.body_height_m, 0.31);
        assert_eq!(runs[4].point.params.swing_time_s, 0.25);
        assert_eq!(runs[8].point.speed_mps, 0.5);
        assert_eq!(runs[24].point.gait, Gait::Walk);
        let ids: HashSet<RunId> = runs.iter().map(RunSpec::run_id).collect();
        assert_eq!(ids.len(), runs.len(), "run ids are unique");
        // Same grid, same list.
        assert_eq!(grid().runs(), runs);
    }

    #[test]
    fn run_id_is_stable() {
        let spec = RunSpec {
            index: 0,
            point: GridPoint {
                gait: Gait::Trot,
                speed_mps: 0.5,
                params: PlannerParams::default(),
                duration_s: 20.0,
            },
            seed: 0,
        };
        assert_eq!(
            spec.canonical(),
            "gait=trot;speed_mps=0.5;swing_time_s=0.25;step_height_m=0.1;body_height_m=0.31;\
             ellipse_rx_m=0.07;ellipse_ry_m=0.05;duration_s=20;seed=0"
        );
        // Hard-coded: changing the canonical form or the hash breaks resuming old folders.
        assert_eq!(spec.run_id().to_string(), "00f15679ff366d5d");
        assert_eq!(RunId::of("").to_string(), "cbf29ce484222325");
        assert_eq!("00f15679ff366d5d".parse::<RunId>().unwrap(), spec.run_id());
        assert!("xyz".parse::<RunId>().is_err());
        assert_ne!(spec.point.point_id(), spec.run_id());
    }

    #[test]
    fn shards_are_disjoint_and_cover_the_grid() {
        let runs = grid().runs();
        for n in [1, 2, 3, 5, 7, 48, 100] {
            let mut seen = vec![0usize; runs.len()];
            for k in 1..=n {
                let shard: Shard = format!("{k}/{n}").parse().unwrap();
                let mine: Vec<&RunSpec> = runs.iter().filter(|r| shard.contains(r.index)).collect();
                // Balanced: sizes differ by at most one.
                assert!(mine.len() >= runs.len() / n && mine.len() <= runs.len().div_ceil(n));
                for r in mine {
                    seen[r.index] += 1;
                }
            }
            assert!(seen.iter().all(|&c| c == 1), "N = {n}: {seen:?}");
        }
    }

    #[test]
    fn bad_shards_are_rejected() {
        for (s, needle) in [
            ("0/4", "K = 0"),
            ("5/4", "allowed 1..=4"),
            ("1/0", "N = 0"),
            ("a/4", "K = 'a'"),
            ("3", "expected K/N"),
            ("1/-2", "N = '-2'"),
        ] {
            let e = s.parse::<Shard>().unwrap_err().to_string();
            assert!(
                e.contains("--shard") && e.contains(s) && e.contains(needle),
                "{e}"
            );
        }
        assert_eq!(
            " 2/ 8".parse::<Shard>().unwrap(),
            Shard { index: 2, count: 8 }
        );
    }
}
