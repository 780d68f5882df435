//! What parameters a run actually walked with: the planner parameters in force, grouped by
//! commanded speed (for EEMP-RL, which changes them at every decision, and for tables, which
//! change them with the command), as mean and range per speed.

use super::params::PlannerParams;
use serde::Serialize;
use std::collections::BTreeMap;

/// Commanded speeds are grouped to this resolution, m/s.
const SPEED_BIN_MPS: f64 = 0.01;

#[derive(Clone, Debug, Default)]
struct Bin {
    n: usize,
    sum: [f64; 5],
    min: [f64; 5],
    max: [f64; 5],
}

/// Accumulates the parameters in force at every control step.
#[derive(Clone, Debug, Default)]
pub struct ParamsStats {
    bins: BTreeMap<i64, Bin>,
}

/// One commanded speed's parameters: samples, mean, min and max of each, in
/// [`PlannerParams::NAMES`]' order.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SpeedParams {
    pub speed_mps: f64,
    pub samples: usize,
    pub mean: PlannerParams,
    pub min: PlannerParams,
    pub max: PlannerParams,
}

impl ParamsStats {
    /// One control step at commanded speed `speed_mps` with `params` in force.
    pub fn observe(&mut self, speed_mps: f64, params: &PlannerParams) {
        if !speed_mps.is_finite() {
            return;
        }
        let a = params.to_array();
        let bin = self
            .bins
            .entry((speed_mps / SPEED_BIN_MPS).round() as i64)
            .or_insert_with(|| Bin {
                min: [f64::INFINITY; 5],
                max: [f64::NEG_INFINITY; 5],
                ..Default::default()
            });
        bin.n += 1;
        for i in 0..5 {
            bin.sum[i] += a[i];
            bin.min[i] = bin.min[i].min(a[i]);
            bin.max[i] = bin.max[i].max(a[i]);
        }
    }

    /// Per commanded speed, slowest first.
    pub fn per_speed(&self) -> Vec<SpeedParams> {
        self.bins
            .iter()
            .map(|(&k, b)| SpeedParams {
                speed_mps: k as f64 * SPEED_BIN_MPS,
                samples: b.n,
                mean: PlannerParams::from_array(b.sum.map(|s| s / b.n as f64)),
                min: PlannerParams::from_array(b.min),
                max: PlannerParams::from_array(b.max),
            })
            .collect()
    }

    /// The mean over every sample (None without samples).
    pub fn mean(&self) -> Option<PlannerParams> {
        let n: usize = self.bins.values().map(|b| b.n).sum();
        (n > 0).then(|| {
            let mut sum = [0.0; 5];
            for b in self.bins.values() {
                for (s, v) in sum.iter_mut().zip(b.sum) {
                    *s += v;
                }
            }
            PlannerParams::from_array(sum.map(|s| s / n as f64))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parameters_are_grouped_by_commanded_speed_with_mean_and_range() {
        let mut s = ParamsStats::default();
        let p = PlannerParams::default();
        let q = PlannerParams {
            swing_time_s: 0.15,
            ..p
        };
        s.observe(0.3, &p);
        s.observe(0.3004, &q);
        s.observe(0.5, &q);
        s.observe(f64::NAN, &q);
        let v = s.per_speed();
        assert_eq!(v.len(), 2);
        assert_eq!(v[0].samples, 2);
        assert!((v[0].speed_mps - 0.3).abs() < 1e-12);
        assert!((v[0].mean.swing_time_s - 0.2).abs() < 1e-12);
        assert_eq!(v[0].min.swing_time_s, 0.15);
        assert_eq!(v[0].max.swing_time_s, 0.25);
        assert_eq!(v[1].mean, q);
        // Overall: (0.25 + 0.15 + 0.15) / 3.
        assert!((s.mean().unwrap().swing_time_s - 0.55 / 3.0).abs() < 1e-12);
        assert!(ParamsStats::default().mean().is_none());
    }
}
