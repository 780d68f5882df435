//! What gait a controller walks, measured from the feet's contacts and loads (issue 21): duty
//! factor per leg, how often leg pairs share their contact state, and the left/right split of
//! the load. Any controller is measured the same way, a learned policy without a plan too.

use crate::leg::{Leg, LegMap};
use serde::Serialize;
use std::collections::BTreeMap;

/// Running sums over a walk; [`GaitMeter::finish`] gives the [`GaitMeasure`].
#[derive(Clone, Debug, Default)]
pub struct GaitMeter {
    time_s: f64,
    loaded_s: [f64; 4],
    /// Time each pair class shares its contact state, summed over the class's two pairs.
    together_s: [f64; 3],
    left_impulse_ns: f64,
    right_impulse_ns: f64,
}

/// Pairs of legs by class: diagonal (a trot moves them together), lateral or ipsilateral (a
/// pace), front/rear (a bound or pronk moves the two fronts and the two rears together).
const PAIRS: [[(Leg, Leg); 2]; 3] = [
    [
        (Leg::FrontRight, Leg::RearLeft),
        (Leg::FrontLeft, Leg::RearRight),
    ],
    [
        (Leg::FrontRight, Leg::RearRight),
        (Leg::FrontLeft, Leg::RearLeft),
    ],
    [
        (Leg::FrontRight, Leg::FrontLeft),
        (Leg::RearRight, Leg::RearLeft),
    ],
];

/// The gait of a walk.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GaitMeasure {
    /// Fraction of the time each foot carries load, by leg ("FR", "FL", "RR", "RL").
    pub duty_factor: BTreeMap<String, f64>,
    /// Fraction of the time diagonal pairs (FR–RL, FL–RR) are both loaded or both in the air
    /// (mean of the two pairs): 1 for a trot.
    pub diagonal_pairs_together: f64,
    /// The same for lateral (same-side) pairs, FR–RR and FL–RL: 1 for a pace.
    pub lateral_pairs_together: f64,
    /// The same for the front pair and the rear pair: 1 for a bound.
    pub front_rear_pairs_together: f64,
    /// The left feet's share of the vertical load's impulse (0.5: balanced).
    pub left_load_share: f64,
    /// (left − right) / (left + right) of the feet's normal-force impulse; |·| ≤ 0.1 is a
    /// left/right balance within 10 %.
    pub left_right_imbalance: f64,
}

impl GaitMeter {
    /// One step of `dt` s: which feet carry load and their normal forces, N.
    pub fn observe(&mut self, dt: f64, loaded: &LegMap<bool>, normal_n: &LegMap<f64>) {
        self.time_s += dt;
        for leg in Leg::ALL {
            if loaded[leg] {
                self.loaded_s[leg.index()] += dt;
            }
            let f = normal_n[leg].max(0.0) * dt;
            match leg.side_sign() > 0.0 {
                true => self.left_impulse_ns += f,
                false => self.right_impulse_ns += f,
            }
        }
        for (class, pairs) in PAIRS.iter().enumerate() {
            for (a, b) in pairs {
                if loaded[*a] == loaded[*b] {
                    self.together_s[class] += dt;
                }
            }
        }
    }

    /// `None` before any step or without any load.
    pub fn finish(&self) -> Option<GaitMeasure> {
        let load = self.left_impulse_ns + self.right_impulse_ns;
        if self.time_s <= 0.0 || load <= 0.0 {
            return None;
        }
        let t = self.time_s;
        Some(GaitMeasure {
            duty_factor: Leg::ALL
                .iter()
                .map(|l| (l.short_name().to_string(), self.loaded_s[l.index()] / t))
                .collect(),
            diagonal_pairs_together: self.together_s[0] / (2.0 * t),
            lateral_pairs_together: self.together_s[1] / (2.0 * t),
            front_rear_pairs_together: self.together_s[2] / (2.0 * t),
            left_load_share: self.left_impulse_ns / load,
            left_right_imbalance: (self.left_impulse_ns - self.right_impulse_ns) / load,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scripted_trot_and_a_three_legged_walk_by_hand() {
        // A trot: FR+RL loaded for 0.2 s, then FL+RR for 0.2 s, 40 N on each loaded foot.
        let mut trot = GaitMeter::default();
        for i in 0..40 {
            let first = i < 20;
            let loaded = LegMap::from_fn(|l| {
                (first && (l == Leg::FrontRight || l == Leg::RearLeft))
                    || (!first && (l == Leg::FrontLeft || l == Leg::RearRight))
            });
            let f = loaded.map(|_, &c| if c { 40.0 } else { 0.0 });
            trot.observe(0.01, &loaded, &f);
        }
        let m = trot.finish().unwrap();
        assert!((m.diagonal_pairs_together - 1.0).abs() < 1e-12);
        assert!(m.lateral_pairs_together.abs() < 1e-12);
        assert!(m.front_rear_pairs_together.abs() < 1e-12);
        assert!((m.duty_factor["FR"] - 0.5).abs() < 1e-12);
        assert!(m.left_right_imbalance.abs() < 1e-12);
        // Three legs: RR never lifts and carries 60 N, the others 30 N: left 60 against right
        // 90 → imbalance −0.2, left share 0.4.
        let mut three = GaitMeter::default();
        let loaded = LegMap::splat(true);
        let f = LegMap::from_fn(|l| if l == Leg::RearRight { 60.0 } else { 30.0 });
        three.observe(0.5, &loaded, &f);
        let m = three.finish().unwrap();
        assert!((m.left_right_imbalance + 0.2).abs() < 1e-12);
        assert!((m.left_load_share - 0.4).abs() < 1e-12);
        assert_eq!(m.duty_factor["RR"], 1.0);
        assert!(GaitMeter::default().finish().is_none());
    }
}
