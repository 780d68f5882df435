//! EEMP-Analytical's selection (paper Sec. V):
//!
//! 1. every grid point's metrics are averaged over its seeds;
//! 2. a point is *selectable* unless a seed fell or failed (could not be run), it has no
//!    CoT / manipulability / mean speed, its mean velocity RMSE exceeds `max_vel_rmse_mps`, or
//!    its mean speed (distance over the metrics window) is off the command by more than
//!    `max_speed_error_ratio` × the command (it did not move at the commanded speed, so its
//!    CoT is not a CoT of that speed);
//! 3. score = `cot − manipulability_weight · manipulability` (lower is better): the paper's
//!    objective is the lowest CoT, with the force-manipulability measure (eq. 9, higher = more
//!    robust) as the robustness term; the default weight 0.01 makes a manipulability gain of 1
//!    worth a CoT drop of 0.01, so it mostly breaks near-ties in CoT;
//! 4. per gait and speed the lowest score wins → the lookup table;
//! 5. per gait, the *best constant parameters* (Table II analogue) are the combination,
//!    ignoring speed, that is selectable at every speed of the gait's *stable range* and has
//!    the lowest mean score over those speeds. The stable range is the table's speeds below
//!    the gait's instability (see [`Instability`]; all of them if there is none): a gait is not
//!    used where it is unstable, and a lone survivor there (a point that happens not to fall at
//!    0.7 m/s) would otherwise dictate the "constant" of the whole range;
//! 6. the table's *improvement* over any fixed parameters (the best constant, the paper's
//!    Table II) has one definition, [`GaitStudy::improvement_over`]: the mean of
//!    [`cot_saving`] = (CoT_fixed − CoT_table) / CoT_fixed over the speeds of the stable range
//!    where both the table and the fixed parameters have a selectable point.

use crate::config::{gait_rank, SelectionConfig};
use crate::grid::GridPoint;
use crate::store::ResultRow;
use eemp_core::config_error::ConfigError;
use eemp_core::planner::params_table::{Interpolation, ParamsTable, TableEntry};
use eemp_core::planner::{Gait, PlannerParams};
use std::collections::BTreeMap;

/// A value at the config's 1e-6 resolution, as an exact key.
fn micro(v: f64) -> i64 {
    (v * 1e6).round() as i64
}

/// The five planner parameters as an exact, ordered key.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct ParamsKey([i64; 5]);

impl ParamsKey {
    pub fn of(p: &PlannerParams) -> Self {
        ParamsKey([
            micro(p.swing_time_s),
            micro(p.step_height_m),
            micro(p.body_height_m),
            micro(p.ellipse_rx_m),
            micro(p.ellipse_ry_m),
        ])
    }
}

/// A grid point's metrics, averaged over the seeds it has rows for.
#[derive(Clone, Debug, PartialEq)]
pub struct PointSummary {
    pub point: GridPoint,
    pub seeds: usize,
    /// Some seed fell.
    pub fell: bool,
    /// Some seed could not be run (simulator error).
    pub failed: bool,
    /// Mean dimensionless CoT (`None` if any seed has none).
    pub cot: Option<f64>,
    pub cot_j_per_m: Option<f64>,
    pub manipulability: Option<f64>,
    pub vel_rmse_mps: Option<f64>,
    /// Mean forward speed over the metrics window, m/s (compare with the command: CoT is per
    /// distance, so a point that overshoots the command looks cheaper).
    pub mean_speed_mps: Option<f64>,
    pub distance_m: f64,
    pub energy_j: f64,
    pub all_stance_fraction: f64,
    pub steps_total: f64,
}

/// Why a point is not selectable.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Exclusion {
    Fell,
    Failed,
    NoMetrics,
    /// Mean velocity RMSE above the limit, m/s.
    OffCommand(f64),
    /// Mean speed (m/s) off the command by more than `max_speed_error_ratio` × the command.
    OffSpeed(f64),
}

impl PointSummary {
    pub fn exclusion(&self, sel: &SelectionConfig) -> Option<Exclusion> {
        if self.failed {
            return Some(Exclusion::Failed);
        }
        if self.fell {
            return Some(Exclusion::Fell);
        }
        let (Some(cot), Some(m), Some(rmse), Some(speed)) = (
            self.cot,
            self.manipulability,
            self.vel_rmse_mps,
            self.mean_speed_mps,
        ) else {
            return Some(Exclusion::NoMetrics);
        };
        if ![cot, m, rmse, speed].iter().all(|v| v.is_finite()) {
            return Some(Exclusion::NoMetrics);
        }
        if rmse > sel.max_vel_rmse_mps {
            return Some(Exclusion::OffCommand(rmse));
        }
        let command = self.point.speed_mps;
        ((speed - command).abs() > sel.max_speed_error_ratio * command)
            .then_some(Exclusion::OffSpeed(speed))
    }

    /// `cot − w · manipulability` of a selectable point.
    pub fn score(&self, sel: &SelectionConfig) -> Option<f64> {
        if self.exclusion(sel).is_some() {
            return None;
        }
        Some(self.cot? - sel.manipulability_weight * self.manipulability?)
    }

    /// Mean CoT of a point that stood in every seed (whether or not it followed the command).
    pub fn standing_cot(&self) -> Option<f64> {
        (!self.fell && !self.failed)
            .then_some(self.cot)
            .flatten()
            .filter(|c| c.is_finite())
    }
}

/// Seed averages of every grid point in `rows`, in canonical order (gait, speed, parameters).
pub fn summarize(rows: &[ResultRow]) -> Vec<PointSummary> {
    let mut groups: BTreeMap<(usize, i64, ParamsKey, i64), Vec<&ResultRow>> = BTreeMap::new();
    for r in rows {
        let p = r.point();
        let key = (
            gait_rank(p.gait),
            micro(p.speed_mps),
            ParamsKey::of(&p.params),
            micro(p.duration_s),
        );
        groups.entry(key).or_default().push(r);
    }
    groups
        .into_values()
        .map(|g| {
            let n = g.len() as f64;
            let mean = |f: fn(&ResultRow) -> f64| g.iter().map(|r| f(r)).sum::<f64>() / n;
            let mean_opt = |f: fn(&ResultRow) -> Option<f64>| {
                g.iter().map(|r| f(r)).sum::<Option<f64>>().map(|s| s / n)
            };
            PointSummary {
                point: g[0].point(),
                seeds: g.len(),
                fell: g.iter().any(|r| r.fell),
                failed: g.iter().any(|r| r.failed()),
                cot: mean_opt(|r| r.cot),
                cot_j_per_m: mean_opt(|r| r.cot_j_per_m),
                manipulability: mean_opt(|r| r.manipulability),
                vel_rmse_mps: mean_opt(|r| r.vel_rmse_mps),
                mean_speed_mps: mean_opt(ResultRow::mean_speed_mps),
                distance_m: mean(|r| r.distance_m),
                energy_j: mean(|r| r.energy_j),
                all_stance_fraction: mean(|r| r.all_stance_fraction),
                steps_total: mean(|r| r.steps_total as f64),
            }
        })
        .collect()
}

/// A selectable point with its score.
#[derive(Clone, Debug, PartialEq)]
pub struct Scored {
    pub summary: PointSummary,
    pub score: f64,
}

impl Scored {
    /// CoT of a scored point (always present).
    pub fn cot(&self) -> f64 {
        self.summary.cot.unwrap_or(f64::NAN)
    }

    pub fn manipulability(&self) -> f64 {
        self.summary.manipulability.unwrap_or(f64::NAN)
    }
}

/// The choice at one commanded speed.
#[derive(Clone, Debug, PartialEq)]
pub struct SpeedChoice {
    pub speed_mps: f64,
    /// Grid points with results at this speed.
    pub points: usize,
    /// Points where some seed fell (and none failed).
    pub fell: usize,
    /// Points where some seed could not be run (simulator error, panic): no information about
    /// the gait, not a fall.
    pub failed: usize,
    /// Standing points off the command: velocity RMSE or mean-speed error above its limit.
    pub off_command: usize,
    /// Standing points without a finite CoT, manipulability, velocity RMSE or mean speed.
    pub no_metrics: usize,
    /// The lowest score (`None`: no selectable point).
    pub best: Option<Scored>,
}

/// The best constant parameters of a gait (Table II analogue).
#[derive(Clone, Debug, PartialEq)]
pub struct BestConstant {
    pub params: PlannerParams,
    pub mean_score: f64,
    /// The combination at each speed of the table, ascending.
    pub per_speed: Vec<Scored>,
}

impl BestConstant {
    pub fn mean_cot(&self) -> f64 {
        self.per_speed.iter().map(Scored::cot).sum::<f64>() / self.per_speed.len() as f64
    }

    /// The combination at `speed_mps`, if that speed is one of `per_speed`'s.
    pub fn at(&self, speed_mps: f64) -> Option<&Scored> {
        self.per_speed
            .iter()
            .find(|s| micro(s.summary.point.speed_mps) == micro(speed_mps))
    }
}

/// Relative CoT saving of the per-speed table over fixed parameters at one speed:
/// (CoT_fixed − CoT_table) / CoT_fixed (positive: the table is cheaper).
pub fn cot_saving(fixed_cot: f64, table_cot: f64) -> f64 {
    (fixed_cot - table_cot) / fixed_cot
}

/// The per-speed table's CoT improvement over fixed parameters
/// ([`GaitStudy::improvement_over`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Improvement {
    /// Mean of [`cot_saving`] over `speeds_mps`, %.
    pub pct: f64,
    /// The speeds averaged over: the stable range's table speeds where the fixed parameters
    /// are selectable too, ascending.
    pub speeds_mps: Vec<f64>,
}

/// Where a gait stops working as the speed rises.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instability {
    pub speed_mps: f64,
    pub reason: InstabilityReason,
}

/// Why a gait counts as unstable from a speed v on: the lower of
///
/// - the top of the speed range without a selectable point: v is the lowest tabulated speed
///   such that no point is selectable at v or at any higher speed (speeds where every point
///   failed to run are skipped at the bottom of that range: they say nothing about the gait).
///   A speed without a selectable point *below* a selectable one is a gap, not the instability;
/// - a CoT jump: the best CoT at v is more than [`COT_JUMP`] × the best CoT at the previous
///   speed with a selectable point (the paper's "sharp increase in CoT");
/// - most points fall: at v and at every higher speed more than [`MOST_FELL`] of the grid
///   points that ran fell. A lone survivor among falling neighbours is luck, not a gait that
///   works at that speed, and it would otherwise dictate the gait's best constant parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum InstabilityReason {
    /// No point is selectable from v up, and every point there fell (none failed to run).
    AllFell,
    /// No point is selectable from v up; counts of grid points over those speeds.
    NoneSelectable {
        points: usize,
        fell: usize,
        failed: usize,
        off_command: usize,
        no_metrics: usize,
    },
    /// The best CoT is `ratio` × the best CoT at `from_speed_mps`, the previous speed with a
    /// selectable point (ratio > [`COT_JUMP`]).
    CotJump { from_speed_mps: f64, ratio: f64 },
    /// At v, `fell` of the `ran` grid points that ran fell (more than [`MOST_FELL`] of them),
    /// and so at every higher speed.
    MostFell { fell: usize, ran: usize },
}

/// Share of a speed's grid points that must fall, there and at every higher speed, for the
/// gait to count as unstable from that speed on.
pub const MOST_FELL: f64 = 0.5;

/// [`MOST_FELL`] in % ("50 %").
pub fn most_fell_pct_text() -> String {
    format!("{:.0} %", 100.0 * MOST_FELL)
}

/// A rise of the best CoT by more than this factor from one speed to the next marks the
/// instability (the paper's "sharp increase in CoT").
pub const COT_JUMP: f64 = 1.5;

/// [`COT_JUMP`] as the rise it stands for, in % ("50 %").
pub fn cot_jump_pct_text() -> String {
    format!("{:.0} %", 100.0 * (COT_JUMP - 1.0))
}

impl std::fmt::Display for Instability {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let s = self.speed_mps;
        match self.reason {
            InstabilityReason::AllFell => write!(
                f,
                "{s} m/s (every grid point fell, at this and every higher speed)"
            ),
            InstabilityReason::NoneSelectable {
                points,
                fell,
                failed,
                off_command,
                no_metrics,
            } => write!(
                f,
                "{s} m/s (no grid point is selectable at this or any higher speed: of {points} \
                 points {fell} fell, {off_command} were off the command, {no_metrics} had no \
                 metrics, {failed} failed to run)"
            ),
            InstabilityReason::CotJump {
                from_speed_mps,
                ratio,
            } => write!(
                f,
                "{s} m/s (best CoT jumps to {ratio:.2}× its value at {from_speed_mps} m/s)"
            ),
            InstabilityReason::MostFell { fell, ran } => write!(
                f,
                "{s} m/s ({fell} of the {ran} grid points that ran fell, more than {}, here and \
                 at every higher speed)",
                most_fell_pct_text()
            ),
        }
    }
}

/// Selection results of one gait.
#[derive(Clone, Debug, PartialEq)]
pub struct GaitStudy {
    pub gait: Gait,
    /// Every speed with results, ascending.
    pub speeds: Vec<SpeedChoice>,
    /// Over the stable range: the table's speeds below `instability` (module docs, step 5).
    pub constant: Option<BestConstant>,
    /// The table's improvement over `constant` ([`GaitStudy::improvement_over`]).
    pub improvement: Option<Improvement>,
    /// The lowest speed where the gait fails (see [`InstabilityReason`]); `None` if it works
    /// at every speed.
    pub instability: Option<Instability>,
}

impl GaitStudy {
    /// The chosen points, ascending in speed.
    pub fn best(&self) -> impl Iterator<Item = &Scored> {
        self.speeds.iter().filter_map(|s| s.best.as_ref())
    }

    pub fn best_at(&self, speed_mps: f64) -> Option<&Scored> {
        self.speeds
            .iter()
            .find(|s| micro(s.speed_mps) == micro(speed_mps))
            .and_then(|s| s.best.as_ref())
    }

    /// Whether `speed_mps` is in the stable range: below the instability, if there is one.
    pub fn is_stable(&self, speed_mps: f64) -> bool {
        self.instability
            .is_none_or(|i| micro(speed_mps) < micro(i.speed_mps))
    }

    /// The table's CoT improvement over fixed parameters whose selectable point at a speed is
    /// `fixed(speed)` — the one definition the report uses: the mean of [`cot_saving`] over
    /// the speeds of the stable range where both the table and the fixed parameters have a
    /// selectable point. `None` if there is no such speed.
    pub fn improvement_over<'a>(
        &self,
        fixed: impl Fn(f64) -> Option<&'a Scored>,
    ) -> Option<Improvement> {
        let (speeds_mps, savings): (Vec<f64>, Vec<f64>) = self
            .best()
            .filter(|t| self.is_stable(t.summary.point.speed_mps))
            .filter_map(|t| {
                let speed = t.summary.point.speed_mps;
                Some((speed, cot_saving(fixed(speed)?.cot(), t.cot())))
            })
            .unzip();
        (!savings.is_empty()).then(|| Improvement {
            pct: 100.0 * savings.iter().sum::<f64>() / savings.len() as f64,
            speeds_mps,
        })
    }

    /// The lookup table (`None` if no speed has a selectable point), with each entry's CoT and
    /// manipulability.
    pub fn table(&self, interpolation: Interpolation) -> Option<Result<ParamsTable, ConfigError>> {
        let entries: Vec<TableEntry> = self
            .best()
            .map(|b| TableEntry {
                cot: b.summary.cot,
                manipulability: b.summary.manipulability,
                ..TableEntry::new(b.summary.point.speed_mps, &b.summary.point.params)
            })
            .collect();
        (!entries.is_empty()).then(|| ParamsTable::new(self.gait, interpolation, entries))
    }
}

/// The whole selection.
#[derive(Clone, Debug, PartialEq)]
pub struct Study {
    pub selection: SelectionConfig,
    pub points: Vec<PointSummary>,
    /// One per gait with results, in canonical gait order.
    pub gaits: Vec<GaitStudy>,
}

impl Study {
    pub fn analyse(rows: &[ResultRow], selection: SelectionConfig) -> Study {
        let points = summarize(rows);
        let mut gaits: Vec<Gait> = points.iter().map(|p| p.point.gait).collect();
        gaits.dedup();
        let gaits = gaits
            .into_iter()
            .map(|g| {
                let mine: Vec<&PointSummary> =
                    points.iter().filter(|p| p.point.gait == g).collect();
                study_gait(g, &mine, &selection)
            })
            .collect();
        Study {
            selection,
            points,
            gaits,
        }
    }

    pub fn gait(&self, gait: Gait) -> Option<&GaitStudy> {
        self.gaits.iter().find(|g| g.gait == gait)
    }

    /// Mean over the speeds ≤ `max_speed_mps` where both gaits have a selected point of
    /// CoT_a / CoT_b (best per speed). With the robot's mass the same, this is the ratio of
    /// energy per distance. Returns the ratio and the speeds used.
    pub fn cot_ratio(&self, a: Gait, b: Gait, max_speed_mps: f64) -> Option<(f64, Vec<f64>)> {
        let (ga, gb) = (self.gait(a)?, self.gait(b)?);
        let pairs: Vec<(f64, f64)> = ga
            .best()
            .filter(|s| s.summary.point.speed_mps <= max_speed_mps + 1e-9)
            .filter_map(|s| {
                let other = gb.best_at(s.summary.point.speed_mps)?;
                Some((s.summary.point.speed_mps, s.cot() / other.cot()))
            })
            .collect();
        if pairs.is_empty() {
            return None;
        }
        let mean = pairs.iter().map(|p| p.1).sum::<f64>() / pairs.len() as f64;
        Some((mean, pairs.iter().map(|p| p.0).collect()))
    }

    /// Fixed parameters (e.g. the paper's Table II) at each speed of `gait`'s table: their
    /// selectable point there, if any. `None` if the gait has no table or `params` is not on
    /// the grid.
    pub fn fixed_params(&self, gait: Gait, params: &PlannerParams) -> Option<FixedParams> {
        let g = self.gait(gait)?;
        let key = ParamsKey::of(params);
        let on_grid = self
            .points
            .iter()
            .any(|p| p.point.gait == gait && ParamsKey::of(&p.point.params) == key);
        if !on_grid || g.best().next().is_none() {
            return None;
        }
        let per_speed = g
            .best()
            .map(|t| {
                let speed = t.summary.point.speed_mps;
                let at = self.points.iter().find(|p| {
                    p.point.gait == gait
                        && micro(p.point.speed_mps) == micro(speed)
                        && ParamsKey::of(&p.point.params) == key
                });
                let scored = at.and_then(|p| {
                    p.score(&self.selection).map(|score| Scored {
                        summary: p.clone(),
                        score,
                    })
                });
                (speed, scored)
            })
            .collect();
        Some(FixedParams {
            params: *params,
            per_speed,
        })
    }

    /// Fig. 5's map for one gait and speed: for each (r_x, ΔT), the lowest seed-averaged CoT
    /// over the other parameters among points that stood in every seed; NaN where none did.
    pub fn cot_map(&self, gait: Gait, speed_mps: f64) -> CotMap {
        let mine: Vec<&PointSummary> = self
            .points
            .iter()
            .filter(|p| p.point.gait == gait)
            .collect();
        let axis = |f: fn(&PointSummary) -> f64| {
            let mut v: Vec<f64> = mine.iter().map(|p| f(p)).collect();
            v.sort_by(f64::total_cmp);
            v.dedup();
            v
        };
        let swing = axis(|p| p.point.params.swing_time_s);
        let rx = axis(|p| p.point.params.ellipse_rx_m);
        let mut cot = vec![vec![f64::NAN; swing.len()]; rx.len()];
        for p in mine
            .iter()
            .filter(|p| micro(p.point.speed_mps) == micro(speed_mps))
        {
            let Some(c) = p.standing_cot() else { continue };
            let iy = rx.iter().position(|&v| v == p.point.params.ellipse_rx_m);
            let ix = swing.iter().position(|&v| v == p.point.params.swing_time_s);
            if let (Some(iy), Some(ix)) = (iy, ix) {
                let cell = &mut cot[iy][ix];
                if cell.is_nan() || c < *cell {
                    *cell = c;
                }
            }
        }
        CotMap {
            gait,
            speed_mps,
            swing_time_s: swing,
            ellipse_rx_m: rx,
            cot,
        }
    }
}

/// Fixed parameters at the speeds of a gait's table.
#[derive(Clone, Debug, PartialEq)]
pub struct FixedParams {
    pub params: PlannerParams,
    /// (speed, the point there if it is selectable), ascending.
    pub per_speed: Vec<(f64, Option<Scored>)>,
}

impl FixedParams {
    /// Speeds where the parameters are selectable.
    pub fn selectable(&self) -> usize {
        self.per_speed.iter().filter(|p| p.1.is_some()).count()
    }

    /// The selectable point at `speed_mps`, if any.
    pub fn at(&self, speed_mps: f64) -> Option<&Scored> {
        self.per_speed
            .iter()
            .find(|p| micro(p.0) == micro(speed_mps))
            .and_then(|p| p.1.as_ref())
    }

    /// The gait's table's improvement over these parameters
    /// ([`GaitStudy::improvement_over`]).
    pub fn improvement(&self, gait: &GaitStudy) -> Option<Improvement> {
        gait.improvement_over(|v| self.at(v))
    }
}

/// CoT over r_x (rows) × ΔT (columns) at one speed.
#[derive(Clone, Debug, PartialEq)]
pub struct CotMap {
    pub gait: Gait,
    pub speed_mps: f64,
    pub swing_time_s: Vec<f64>,
    pub ellipse_rx_m: Vec<f64>,
    /// `cot[i_rx][i_swing]`; NaN: no point stood.
    pub cot: Vec<Vec<f64>>,
}

/// The value of `values` nearest to `target` (ties: the lower).
pub fn nearest(values: &[f64], target: f64) -> Option<f64> {
    values
        .iter()
        .copied()
        .min_by(|a, b| (a - target).abs().total_cmp(&(b - target).abs()))
}

fn study_gait(gait: Gait, points: &[&PointSummary], sel: &SelectionConfig) -> GaitStudy {
    let mut by_speed: BTreeMap<i64, Vec<&PointSummary>> = BTreeMap::new();
    for p in points {
        by_speed
            .entry(micro(p.point.speed_mps))
            .or_default()
            .push(p);
    }
    let speeds: Vec<SpeedChoice> = by_speed
        .values()
        .map(|pts| {
            let mut choice = SpeedChoice {
                speed_mps: pts[0].point.speed_mps,
                points: pts.len(),
                fell: 0,
                failed: 0,
                off_command: 0,
                no_metrics: 0,
                best: None,
            };
            for p in pts {
                match p.exclusion(sel) {
                    Some(Exclusion::Fell) => choice.fell += 1,
                    Some(Exclusion::Failed) => choice.failed += 1,
                    Some(Exclusion::OffCommand(_) | Exclusion::OffSpeed(_)) => {
                        choice.off_command += 1
                    }
                    Some(Exclusion::NoMetrics) => choice.no_metrics += 1,
                    None => {
                        let score = p.score(sel).expect("selectable");
                        // Strictly lower wins: ties keep the first in canonical order.
                        if choice.best.as_ref().is_none_or(|b| score < b.score) {
                            choice.best = Some(Scored {
                                summary: (*p).clone(),
                                score,
                            });
                        }
                    }
                }
            }
            choice
        })
        .collect();
    let instability = instability(&speeds);
    let mut study = GaitStudy {
        gait,
        speeds,
        constant: None,
        improvement: None,
        instability,
    };
    let stable: Vec<&SpeedChoice> = study
        .speeds
        .iter()
        .filter(|s| study.is_stable(s.speed_mps))
        .collect();
    let constant = best_constant(points, &stable, sel);
    study.improvement = constant
        .as_ref()
        .and_then(|c| study.improvement_over(|v| c.at(v)));
    study.constant = constant;
    study
}

fn best_constant(
    points: &[&PointSummary],
    speeds: &[&SpeedChoice],
    sel: &SelectionConfig,
) -> Option<BestConstant> {
    let table_speeds: Vec<i64> = speeds
        .iter()
        .filter(|s| s.best.is_some())
        .map(|s| micro(s.speed_mps))
        .collect();
    if table_speeds.is_empty() {
        return None;
    }
    let mut by_params: BTreeMap<ParamsKey, BTreeMap<i64, Scored>> = BTreeMap::new();
    for p in points {
        if let Some(score) = p.score(sel) {
            by_params
                .entry(ParamsKey::of(&p.point.params))
                .or_default()
                .insert(
                    micro(p.point.speed_mps),
                    Scored {
                        summary: (*p).clone(),
                        score,
                    },
                );
        }
    }
    let mut best: Option<BestConstant> = None;
    // BTreeMap order: ties keep the lowest parameters.
    for at_speed in by_params.into_values() {
        let per_speed: Option<Vec<Scored>> = table_speeds
            .iter()
            .map(|s| at_speed.get(s).cloned())
            .collect();
        let Some(per_speed) = per_speed else { continue };
        let mean_score = per_speed.iter().map(|s| s.score).sum::<f64>() / per_speed.len() as f64;
        if best.as_ref().is_none_or(|b| mean_score < b.mean_score) {
            best = Some(BestConstant {
                params: per_speed[0].summary.point.params,
                mean_score,
                per_speed,
            });
        }
    }
    best
}

/// See [`InstabilityReason`].
fn instability(speeds: &[SpeedChoice]) -> Option<Instability> {
    // The first CoT jump between consecutive speeds with a selectable point.
    let selectable: Vec<(f64, f64)> = speeds
        .iter()
        .filter_map(|s| Some((s.speed_mps, s.best.as_ref()?.cot())))
        .collect();
    let jump = selectable
        .windows(2)
        .find(|w| w[1].1 > COT_JUMP * w[0].1)
        .map(|w| Instability {
            speed_mps: w[1].0,
            reason: InstabilityReason::CotJump {
                from_speed_mps: w[0].0,
                ratio: w[1].1 / w[0].1,
            },
        });
    // The top of the speed range without a selectable point, less the speeds at its bottom
    // where nothing could be run.
    let top = speeds
        .iter()
        .rposition(|s| s.best.is_some())
        .map_or(0, |i| i + 1);
    let top = &speeds[top..];
    let none_selectable = top.iter().position(|s| s.failed < s.points).map(|k| {
        let range = &top[k..];
        let sum = |f: fn(&SpeedChoice) -> usize| range.iter().map(f).sum::<usize>();
        let (points, fell, failed) = (sum(|s| s.points), sum(|s| s.fell), sum(|s| s.failed));
        let reason = if fell == points {
            InstabilityReason::AllFell
        } else {
            InstabilityReason::NoneSelectable {
                points,
                fell,
                failed,
                off_command: sum(|s| s.off_command),
                no_metrics: sum(|s| s.no_metrics),
            }
        };
        Instability {
            speed_mps: range[0].speed_mps,
            reason,
        }
    });
    // The lowest speed of the top range where most points fall (speeds where nothing ran are
    // skipped, as above).
    let most_fell = |s: &SpeedChoice| {
        let ran = s.points - s.failed;
        ran > 0 && s.fell as f64 > MOST_FELL * ran as f64
    };
    let start = speeds
        .iter()
        .rposition(|s| !(most_fell(s) || s.failed == s.points))
        .map_or(0, |i| i + 1);
    let most = speeds[start..]
        .iter()
        .find(|s| most_fell(s))
        .map(|s| Instability {
            speed_mps: s.speed_mps,
            reason: InstabilityReason::MostFell {
                fell: s.fell,
                ran: s.points - s.failed,
            },
        });
    // Ties keep the first: "every point fell" says more than "most fell".
    [jump, none_selectable, most]
        .into_iter()
        .flatten()
        .min_by(|a, b| a.speed_mps.total_cmp(&b.speed_mps))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::grid::RunSpec;
    use crate::store::RunOutcome;

    fn params(swing_time_s: f64) -> PlannerParams {
        PlannerParams {
            swing_time_s,
            ..Default::default()
        }
    }

    /// A result row; `cot: None` = the run fell (with a CoT of 0.1, which must be ignored).
    fn row(gait: Gait, speed: f64, p: PlannerParams, seed: u64, cot: Option<f64>) -> ResultRow {
        row_full(gait, speed, p, seed, cot, 3.0, 0.1)
    }

    /// A result row of the grid point (`gait`, `speed`, `p`): 18 s of metrics at the commanded
    /// speed; `cot: None` = the run fell. (The sensitivity study's tests build theirs on it.)
    pub(crate) fn row_full(
        gait: Gait,
        speed: f64,
        p: PlannerParams,
        seed: u64,
        cot: Option<f64>,
        manipulability: f64,
        rmse: f64,
    ) -> ResultRow {
        let spec = RunSpec {
            index: 0,
            point: GridPoint {
                gait,
                speed_mps: speed,
                params: p,
                duration_s: 20.0,
            },
            seed,
        };
        // On the command: 18 s of metrics at the commanded speed.
        let outcome = RunOutcome {
            fell: cot.is_none(),
            cot: Some(cot.unwrap_or(0.1)),
            manipulability: Some(manipulability),
            vel_rmse_mps: Some(rmse),
            distance_m: speed * 18.0,
            metrics_window_s: 18.0,
            ..Default::default()
        };
        ResultRow::new(&spec, &outcome, 1.0)
    }

    /// A run that could not be done.
    fn failed(gait: Gait, speed: f64, p: PlannerParams) -> ResultRow {
        let mut r = row(gait, speed, p, 0, Some(0.5));
        r.error = "simulator error".into();
        r
    }

    const SEL: SelectionConfig = SelectionConfig {
        max_vel_rmse_mps: 0.25,
        max_speed_error_ratio: 0.5,
        manipulability_weight: 0.01,
        interpolation: Interpolation::Nearest,
        objective: crate::config::Objective::Eq8,
    };

    #[test]
    fn seeds_are_averaged_and_a_fall_in_any_seed_excludes_the_point() {
        let (a, b) = (params(0.25), params(0.2));
        let rows = vec![
            row(Gait::Trot, 0.5, a, 0, Some(1.0)),
            row(Gait::Trot, 0.5, a, 1, Some(1.2)),
            row(Gait::Trot, 0.5, b, 0, Some(0.5)),
            row(Gait::Trot, 0.5, b, 1, None),
        ];
        let points = summarize(&rows);
        assert_eq!(points.len(), 2);
        // Canonical order: ΔT 0.2 before 0.25.
        assert_eq!(points[0].point.params, b);
        assert!(points[0].fell);
        assert_eq!(points[0].exclusion(&SEL), Some(Exclusion::Fell));
        assert_eq!(points[1].seeds, 2);
        assert!((points[1].cot.unwrap() - 1.1).abs() < 1e-12);
        let study = Study::analyse(&rows, SEL);
        let best = study.gait(Gait::Trot).unwrap().best_at(0.5).unwrap();
        assert_eq!(
            best.summary.point.params, a,
            "the lower-CoT point fell once"
        );
        assert!((best.score - (1.1 - 0.03)).abs() < 1e-12);
        let s = &study.gait(Gait::Trot).unwrap().speeds[0];
        assert_eq!((s.points, s.fell, s.off_command), (2, 1, 0));
    }

    #[test]
    fn selection_picks_the_known_best_with_rmse_limit_and_manipulability_weight() {
        let (a, b, c, d) = (params(0.1), params(0.15), params(0.2), params(0.25));
        let rows = vec![
            // score a = 1.00 − 0.03 = 0.97
            row_full(Gait::Walk, 0.1, a, 0, Some(1.00), 3.0, 0.1),
            // lowest CoT but does not follow the command: excluded
            row_full(Gait::Walk, 0.1, b, 0, Some(0.50), 3.0, 0.30),
            // fell: excluded
            row_full(Gait::Walk, 0.1, c, 0, None, 3.0, 0.1),
            // CoT 1.005 > 1.00, but manipulability 4: score 1.005 − 0.04 = 0.965 < 0.97
            row_full(Gait::Walk, 0.1, d, 0, Some(1.005), 4.0, 0.1),
        ];
        let study = Study::analyse(&rows, SEL);
        let w = study.gait(Gait::Walk).unwrap();
        assert_eq!(w.best_at(0.1).unwrap().summary.point.params, d);
        assert_eq!((w.speeds[0].fell, w.speeds[0].off_command), (1, 1));
        // Without the robustness term the lowest CoT wins.
        let cot_only = SelectionConfig {
            manipulability_weight: 0.0,
            ..SEL
        };
        let w = Study::analyse(&rows, cot_only).gaits.remove(0);
        assert_eq!(w.best_at(0.1).unwrap().summary.point.params, a);
        // A looser RMSE limit admits b.
        let loose = SelectionConfig {
            max_vel_rmse_mps: 0.5,
            ..SEL
        };
        let w = Study::analyse(&rows, loose).gaits.remove(0);
        assert_eq!(w.best_at(0.1).unwrap().summary.point.params, b);
    }

    /// CoT (manipulability 3 everywhere, so score = CoT − 0.03):
    ///
    /// |    | 0.1  | 0.5  |
    /// |----|------|------|
    /// | P1 | 1.00 | 0.40 |
    /// | P2 | 0.80 | 0.65 |
    /// | P3 | 0.70 | fell |
    ///
    /// Table: 0.1 → P3 (0.70), 0.5 → P1 (0.40). Constant: P3 is out (fell at 0.5); P1 mean score
    /// 0.67 < P2 0.695 → P1. Improvement: ((1.00 − 0.70)/1.00 + (0.40 − 0.40)/0.40)/2 = 15 %.
    fn hand_table() -> Vec<ResultRow> {
        let (p1, p2, p3) = (params(0.25), params(0.2), params(0.15));
        vec![
            row(Gait::Trot, 0.1, p1, 0, Some(1.00)),
            row(Gait::Trot, 0.5, p1, 0, Some(0.40)),
            row(Gait::Trot, 0.1, p2, 0, Some(0.80)),
            row(Gait::Trot, 0.5, p2, 0, Some(0.65)),
            row(Gait::Trot, 0.1, p3, 0, Some(0.70)),
            row(Gait::Trot, 0.5, p3, 0, None),
        ]
    }

    #[test]
    fn best_constant_and_improvement_by_hand() {
        let study = Study::analyse(&hand_table(), SEL);
        let t = study.gait(Gait::Trot).unwrap();
        assert_eq!(t.best_at(0.1).unwrap().summary.point.params, params(0.15));
        assert_eq!(t.best_at(0.5).unwrap().summary.point.params, params(0.25));
        let c = t.constant.as_ref().unwrap();
        assert_eq!(c.params, params(0.25));
        assert!((c.mean_score - 0.67).abs() < 1e-12);
        assert!((c.mean_cot() - 0.70).abs() < 1e-12);
        assert!((t.improvement.as_ref().unwrap().pct - 15.0).abs() < 1e-9);
        assert_eq!(t.instability, None);
        // The table carries the selecting metrics and survives a TOML round trip.
        let table = t.table(Interpolation::Nearest).unwrap().unwrap();
        assert_eq!(table.gait, Gait::Trot);
        assert_eq!(table.entries.len(), 2);
        assert_eq!(table.entries[0].cot, Some(0.70));
        assert_eq!(table.entries[0].manipulability, Some(3.0));
        assert_eq!(table.lookup(0.45).swing_time_s, 0.25);
        let back: ParamsTable = toml::from_str(&table.to_toml()).unwrap();
        assert_eq!(back, table);
    }

    #[test]
    fn fixed_parameters_are_compared_where_they_are_selectable() {
        let study = Study::analyse(&hand_table(), SEL);
        let t = study.gait(Gait::Trot).unwrap();
        // P3 fell at 0.5: selectable at 1 of 2 speeds, where it is the table's choice.
        let p3 = study.fixed_params(Gait::Trot, &params(0.15)).unwrap();
        assert_eq!((p3.selectable(), p3.per_speed.len()), (1, 2));
        assert_eq!(p3.improvement(t).unwrap().pct, 0.0);
        // P2: ((0.80 − 0.70)/0.80 + (0.65 − 0.40)/0.65)/2.
        let p2 = study.fixed_params(Gait::Trot, &params(0.2)).unwrap();
        let expected = 100.0 * (0.1 / 0.8 + 0.25 / 0.65) / 2.0;
        assert!((p2.improvement(t).unwrap().pct - expected).abs() < 1e-9);
        assert_eq!(
            study.fixed_params(Gait::Trot, &params(0.1)),
            None,
            "off the grid"
        );
        assert_eq!(
            study.fixed_params(Gait::Walk, &params(0.2)),
            None,
            "no walk results"
        );
    }

    #[test]
    fn the_constant_is_chosen_over_the_stable_range_only() {
        let (p1, p2) = (params(0.25), params(0.2));
        let rows = vec![
            row(Gait::Walk, 0.1, p1, 0, Some(0.5)),
            row(Gait::Walk, 0.3, p1, 0, Some(0.4)),
            row(Gait::Walk, 0.7, p1, 0, None),
            row(Gait::Walk, 0.1, p2, 0, Some(0.6)),
            row(Gait::Walk, 0.3, p2, 0, Some(0.5)),
            // The lone survivor beyond the jump (2.0 > 1.5 × 0.4): walk is unstable at 0.7.
            row(Gait::Walk, 0.7, p2, 0, Some(2.0)),
        ];
        let w = Study::analyse(&rows, SEL).gaits.remove(0);
        assert_eq!(w.instability.unwrap().speed_mps, 0.7);
        assert_eq!(w.best().count(), 3, "the table still covers 0.7");
        let c = w.constant.unwrap();
        assert_eq!(c.params, p1, "p2's survival at 0.7 m/s does not count");
        assert_eq!(c.per_speed.len(), 2);
        assert_eq!(w.improvement.as_ref().map(|i| i.pct), Some(0.0));
    }

    #[test]
    fn no_constant_when_no_combination_works_at_every_speed() {
        let (p1, p2) = (params(0.25), params(0.2));
        let rows = vec![
            row(Gait::Trot, 0.1, p1, 0, Some(1.0)),
            row(Gait::Trot, 0.5, p1, 0, None),
            row(Gait::Trot, 0.1, p2, 0, None),
            row(Gait::Trot, 0.5, p2, 0, Some(0.5)),
        ];
        let t = Study::analyse(&rows, SEL).gaits.remove(0);
        assert_eq!(t.best().count(), 2);
        assert_eq!((t.constant, t.improvement), (None, None));
    }

    #[test]
    fn instability_rules() {
        let p = params(0.25);
        let walk = |cots: &[(f64, Option<f64>)]| {
            let rows: Vec<ResultRow> = cots
                .iter()
                .map(|&(v, c)| row(Gait::Walk, v, p, 0, c))
                .collect();
            Study::analyse(&rows, SEL).gaits.remove(0).instability
        };
        // The CoT falls with speed, then jumps by more than 50 %.
        assert_eq!(cot_jump_pct_text(), "50 %");
        let i = walk(&[
            (0.1, Some(0.9)),
            (0.3, Some(0.8)),
            (0.5, Some(1.3)),
            (0.7, Some(1.4)),
        ])
        .unwrap();
        assert_eq!(i.speed_mps, 0.5);
        assert!(
            matches!(i.reason, InstabilityReason::CotJump { from_speed_mps, ratio }
                if from_speed_mps == 0.3 && (ratio - 1.625).abs() < 1e-12)
        );
        assert!(i.to_string().contains("1.62×"), "{i}");
        // +45 % is not a jump; then every point falls.
        let i = walk(&[(0.1, Some(0.8)), (0.3, Some(1.16)), (0.5, None)]).unwrap();
        assert_eq!((i.speed_mps, i.reason), (0.5, InstabilityReason::AllFell));
        // Standing but off the command, at the top speed.
        let rows = vec![
            row(Gait::Walk, 0.1, p, 0, Some(0.8)),
            row_full(Gait::Walk, 0.5, p, 0, Some(0.8), 3.0, 0.4),
        ];
        let i = Study::analyse(&rows, SEL).gaits[0].instability.unwrap();
        assert_eq!(i.speed_mps, 0.5);
        assert!(
            matches!(
                i.reason,
                InstabilityReason::NoneSelectable {
                    points: 1,
                    fell: 0,
                    off_command: 1,
                    ..
                }
            ),
            "{i:?}"
        );
        assert!(i.to_string().contains("1 were off the command"), "{i}");
        assert_eq!(walk(&[(0.1, Some(0.9)), (0.5, Some(0.5))]), None);
    }

    #[test]
    fn most_points_falling_at_the_top_speeds_is_the_instability() {
        // Per speed: how many of three points (ΔT 0.15, 0.2, 0.25) fall; the others stand
        // with CoT 0.5 (no jump).
        let walk = |falls: &[(f64, usize)]| {
            let rows: Vec<ResultRow> = falls
                .iter()
                .flat_map(|&(v, n)| {
                    [0.15, 0.2, 0.25]
                        .into_iter()
                        .enumerate()
                        .map(move |(k, dt)| {
                            row(Gait::Walk, v, params(dt), 0, (k >= n).then_some(0.5))
                        })
                })
                .collect();
            Study::analyse(&rows, SEL).gaits.remove(0)
        };
        // 2 of 3 fall at 0.7 and 1.0: unstable from 0.7 although a point survives there.
        let w = walk(&[(0.3, 0), (0.5, 1), (0.7, 2), (1.0, 2)]);
        let i = w.instability.unwrap();
        assert_eq!(
            (i.speed_mps, i.reason),
            (0.7, InstabilityReason::MostFell { fell: 2, ran: 3 })
        );
        assert!(i.to_string().contains("2 of the 3 grid points"), "{i}");
        assert!(w.is_stable(0.5) && !w.is_stable(0.7));
        // The best constant is chosen over the stable range only: it stands at 0.3 and 0.5.
        assert_eq!(w.constant.as_ref().unwrap().per_speed.len(), 2);
        // A majority falling below a speed where most stand is not the instability.
        assert_eq!(walk(&[(0.3, 0), (0.5, 2), (0.7, 1)]).instability, None);
        // The top range starts where most fall; every point falling at the top alone is
        // reported as such.
        let i = walk(&[(0.3, 0), (0.5, 2), (0.7, 3)]).instability.unwrap();
        assert_eq!(
            (i.speed_mps, i.reason),
            (0.5, InstabilityReason::MostFell { fell: 2, ran: 3 })
        );
        let i = walk(&[(0.3, 0), (0.5, 0), (0.7, 3)]).instability.unwrap();
        assert_eq!((i.speed_mps, i.reason), (0.7, InstabilityReason::AllFell));
    }

    #[test]
    fn a_gap_below_a_selectable_speed_is_not_the_instability() {
        let p = params(0.25);
        let walk = |cots: &[(f64, Option<f64>)]| {
            let rows: Vec<ResultRow> = cots
                .iter()
                .map(|&(v, c)| row(Gait::Walk, v, p, 0, c))
                .collect();
            Study::analyse(&rows, SEL).gaits.remove(0)
        };
        // Every point fell at the lowest speed only: stable everywhere, and the constant and
        // the improvement cover the speeds with a table entry.
        let w = walk(&[
            (0.05, None),
            (0.1, Some(0.9)),
            (0.3, Some(0.8)),
            (0.5, Some(0.7)),
        ]);
        assert_eq!(w.instability, None);
        assert!(w.is_stable(1.0));
        assert_eq!(w.constant.unwrap().per_speed.len(), 3);
        // A gap in the middle neither.
        let w = walk(&[(0.1, Some(0.9)), (0.3, None), (0.5, Some(0.8))]);
        assert_eq!(w.instability, None);
        // The jump is measured from the previous speed with a selectable point, across a gap.
        let w = walk(&[(0.1, Some(0.5)), (0.3, None), (0.5, Some(0.9))]);
        let i = w.instability.unwrap();
        assert_eq!(i.speed_mps, 0.5);
        assert!(matches!(
            i.reason,
            InstabilityReason::CotJump { from_speed_mps, .. } if from_speed_mps == 0.1
        ));
        // Gaps at both ends: unstable from the lowest speed of the top gap, not the bottom one.
        let w = walk(&[
            (0.05, None),
            (0.1, Some(0.9)),
            (0.3, None),
            (0.5, Some(0.8)),
            (0.7, None),
            (1.0, None),
        ]);
        let i = w.instability.unwrap();
        assert_eq!((i.speed_mps, i.reason), (0.7, InstabilityReason::AllFell));
        assert!(w.is_stable(0.5) && !w.is_stable(0.7) && !w.is_stable(1.0));
        // The lower of the two rules wins: a jump below the top gap.
        let w = walk(&[(0.1, Some(0.5)), (0.3, Some(0.9)), (0.5, None)]);
        assert_eq!(w.instability.unwrap().speed_mps, 0.3);
    }

    #[test]
    fn failed_runs_are_counted_apart_from_falls_and_are_not_instability() {
        let (a, b) = (params(0.25), params(0.2));
        let rows = vec![
            row(Gait::Walk, 0.1, a, 0, Some(0.9)),
            row(Gait::Walk, 0.1, b, 0, Some(0.8)),
            row(Gait::Walk, 0.5, a, 0, None),
            failed(Gait::Walk, 0.5, b),
            failed(Gait::Walk, 0.7, a),
            failed(Gait::Walk, 0.7, b),
        ];
        let w = Study::analyse(&rows, SEL).gaits.remove(0);
        let s = &w.speeds[1];
        assert_eq!((s.points, s.fell, s.failed), (2, 1, 1));
        // From 0.5 up nothing is selectable: 1 fell, 3 failed; not "every point fell".
        let i = w.instability.unwrap();
        assert_eq!(i.speed_mps, 0.5);
        assert!(matches!(
            i.reason,
            InstabilityReason::NoneSelectable {
                points: 4,
                fell: 1,
                failed: 3,
                ..
            }
        ));
        // Nothing but failures above the table: no instability claimed.
        let w = Study::analyse(
            &rows[..2]
                .iter()
                .chain(&rows[4..])
                .cloned()
                .collect::<Vec<_>>(),
            SEL,
        )
        .gaits
        .remove(0);
        assert_eq!(w.instability, None);
        assert_eq!(w.speeds[1].failed, 2);
    }

    #[test]
    fn a_mean_speed_off_the_command_by_more_than_the_ratio_is_excluded() {
        let (a, b) = (params(0.25), params(0.2));
        let mut slow = row(Gait::Trot, 0.05, b, 0, Some(0.3));
        // 0.08 m/s for a 0.05 m/s command: +60 %, within the RMSE limit.
        slow.distance_m = 0.08 * slow.metrics_window_s;
        let rows = vec![row(Gait::Trot, 0.05, a, 0, Some(0.5)), slow];
        let study = Study::analyse(&rows, SEL);
        let t = study.gait(Gait::Trot).unwrap();
        assert_eq!(t.best_at(0.05).unwrap().summary.point.params, a);
        assert_eq!(t.speeds[0].off_command, 1);
        let excluded = &study.points[0];
        assert!(
            matches!(excluded.exclusion(&SEL), Some(Exclusion::OffSpeed(v)) if (v - 0.08).abs() < 1e-12)
        );
        // Allowed with a looser ratio.
        let loose = SelectionConfig {
            max_speed_error_ratio: 0.7,
            ..SEL
        };
        let t = Study::analyse(&rows, loose).gaits.remove(0);
        assert_eq!(t.best_at(0.05).unwrap().summary.point.params, b);
        // No mean speed (metrics window of zero): no metrics.
        let mut blind = row(Gait::Trot, 0.05, a, 0, Some(0.5));
        blind.metrics_window_s = 0.0;
        let p = &summarize(&[blind])[0];
        assert_eq!(p.exclusion(&SEL), Some(Exclusion::NoMetrics));
    }

    #[test]
    fn both_improvements_use_the_stable_speeds_where_both_are_selectable() {
        // P1 is the best constant over the stable range (0.1, 0.3); walk is unstable at 0.7
        // (CoT jump), where the table still has an entry and P1 is selectable.
        let (p1, p2) = (params(0.25), params(0.2));
        let rows = vec![
            row(Gait::Walk, 0.1, p1, 0, Some(0.48)),
            row(Gait::Walk, 0.3, p1, 0, Some(0.4)),
            row(Gait::Walk, 0.7, p1, 0, Some(3.0)),
            row(Gait::Walk, 0.1, p2, 0, Some(0.4)),
            row(Gait::Walk, 0.3, p2, 0, Some(0.5)),
            row(Gait::Walk, 0.7, p2, 0, Some(2.0)),
        ];
        let study = Study::analyse(&rows, SEL);
        let w = study.gait(Gait::Walk).unwrap();
        assert_eq!(w.instability.unwrap().speed_mps, 0.7);
        assert_eq!(w.best().count(), 3);
        // Table: 0.1 → P2 (0.4), 0.3 → P1 (0.4). Constant P1 (mean score 0.44 − 0.03 < P2's
        // 0.45 − 0.03) at 0.1, 0.3: ((0.48 − 0.4)/0.48 + 0)/2.
        let c = w.constant.as_ref().unwrap();
        assert_eq!(c.params, p1);
        let expected = 100.0 * (0.08 / 0.48) / 2.0;
        assert!((w.improvement.as_ref().unwrap().pct - expected).abs() < 1e-9);
        // The same parameters as "fixed" give the same number: 0.7 m/s is left out although
        // both are selectable there.
        let fixed = study.fixed_params(Gait::Walk, &p1).unwrap();
        assert_eq!(fixed.selectable(), 3);
        let i = fixed.improvement(w).unwrap();
        assert_eq!(i.speeds_mps, vec![0.1, 0.3]);
        assert!((i.pct - w.improvement.as_ref().unwrap().pct).abs() < 1e-12);
        assert_eq!(cot_saving(0.5, 0.4), (0.5 - 0.4) / 0.5);
    }

    #[test]
    fn walk_trot_cot_ratio_over_common_low_speeds() {
        let p = params(0.25);
        let rows = vec![
            row(Gait::Trot, 0.1, p, 0, Some(1.0)),
            row(Gait::Trot, 0.3, p, 0, Some(0.5)),
            row(Gait::Trot, 0.5, p, 0, Some(0.4)),
            row(Gait::Walk, 0.1, p, 0, Some(0.6)),
            row(Gait::Walk, 0.3, p, 0, Some(0.4)),
            row(Gait::Walk, 0.5, p, 0, Some(0.1)),
        ];
        let study = Study::analyse(&rows, SEL);
        let (ratio, speeds) = study.cot_ratio(Gait::Walk, Gait::Trot, 0.4).unwrap();
        assert_eq!(speeds, vec![0.1, 0.3]);
        assert!((ratio - (0.6 + 0.8) / 2.0).abs() < 1e-12);
        assert_eq!(study.cot_ratio(Gait::Walk, Gait::Free, 0.4), None);
    }

    #[test]
    fn cot_map_takes_the_minimum_over_other_parameters_and_greys_out_falls() {
        let mk = |swing: f64, rx: f64, h: f64| PlannerParams {
            swing_time_s: swing,
            ellipse_rx_m: rx,
            step_height_m: h,
            ..Default::default()
        };
        let rows = vec![
            row(Gait::Trot, 0.5, mk(0.2, 0.05, 0.05), 0, Some(0.9)),
            row(Gait::Trot, 0.5, mk(0.2, 0.05, 0.10), 0, Some(0.7)),
            row(Gait::Trot, 0.5, mk(0.25, 0.05, 0.05), 0, None),
            row(Gait::Trot, 0.5, mk(0.25, 0.05, 0.10), 0, None),
            row(Gait::Trot, 0.5, mk(0.2, 0.10, 0.10), 0, Some(0.8)),
            row(Gait::Trot, 0.5, mk(0.25, 0.10, 0.10), 0, Some(0.6)),
            // Another speed: not in the map, but its axes are shared.
            row(Gait::Trot, 0.1, mk(0.15, 0.10, 0.10), 0, Some(5.0)),
        ];
        let map = Study::analyse(&rows, SEL).cot_map(Gait::Trot, 0.5);
        assert_eq!(map.swing_time_s, vec![0.15, 0.2, 0.25]);
        assert_eq!(map.ellipse_rx_m, vec![0.05, 0.10]);
        assert!(map.cot[0][0].is_nan() && map.cot[1][0].is_nan());
        assert_eq!(map.cot[0][1], 0.7);
        assert!(map.cot[0][2].is_nan(), "both points fell");
        assert_eq!((map.cot[1][1], map.cot[1][2]), (0.8, 0.6));
        assert_eq!(nearest(&[0.05, 0.1, 0.5], 0.01), Some(0.05));
    }
}
