//! Which legs swing when a stance foot leaves its ellipse.

use crate::leg::{Leg, LegMap};
use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Hash)]
#[serde(rename_all = "snake_case")]
pub enum Gait {
    /// Diagonal pairs swing together and alternate: after FR+RL comes FL+RR.
    Trot,
    /// One leg at a time in the fixed order RL → FL → RR → FR (the lateral-sequence walk).
    Walk,
    /// No predetermined order: the legs outside their ellipses swing (a diagonal pair at most,
    /// so two feet always support the body), never a leg that swung in the previous step.
    Free,
}

impl std::str::FromStr for Gait {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "trot" => Ok(Gait::Trot),
            "walk" => Ok(Gait::Walk),
            "free" => Ok(Gait::Free),
            other => Err(format!("unknown gait '{other}': allowed trot, walk, free")),
        }
    }
}

impl std::fmt::Display for Gait {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Gait::Trot => "trot",
            Gait::Walk => "walk",
            Gait::Free => "free",
        })
    }
}

/// The lateral-sequence walk order.
pub const WALK_ORDER: [Leg; 4] = [
    Leg::RearLeft,
    Leg::FrontLeft,
    Leg::RearRight,
    Leg::FrontRight,
];

/// Chooses the legs of the next swing. `ellipse_values` are eq. (5)'s left-hand sides of the
/// stance feet (> 1 is outside); `previous` are the legs of the previous swing. Returns an empty
/// set when no foot is outside (all four stay in stance).
pub fn next_swing(gait: Gait, ellipse_values: &LegMap<f64>, previous: &[Leg]) -> Vec<Leg> {
    let outside: Vec<Leg> = Leg::ALL
        .into_iter()
        .filter(|l| ellipse_values[*l] > 1.0)
        .collect();
    if outside.is_empty() {
        return Vec::new();
    }
    match gait {
        Gait::Trot => {
            // Alternate pairs; the very first pair is the one of the foot furthest outside.
            let leg = match previous.first() {
                Some(prev) => prev.diagonal().other_pair_member(),
                None => most_outside(&outside, ellipse_values),
            };
            vec![leg, leg.diagonal()]
        }
        Gait::Walk => {
            let next = match previous.first() {
                Some(prev) => {
                    WALK_ORDER
                        [(WALK_ORDER.iter().position(|l| l == prev).expect("walk leg") + 1) % 4]
                }
                None => most_outside(&outside, ellipse_values),
            };
            vec![next]
        }
        Gait::Free => {
            let candidates: Vec<Leg> = outside
                .into_iter()
                .filter(|l| !previous.contains(l))
                .collect();
            if candidates.is_empty() {
                return Vec::new();
            }
            let leg = most_outside(&candidates, ellipse_values);
            if candidates.contains(&leg.diagonal()) {
                vec![leg, leg.diagonal()]
            } else {
                vec![leg]
            }
        }
    }
}

fn most_outside(legs: &[Leg], values: &LegMap<f64>) -> Leg {
    *legs
        .iter()
        .max_by(|a, b| values[**a].total_cmp(&values[**b]))
        .expect("non-empty")
}

impl Leg {
    /// A leg of the other diagonal pair (the same side, other end).
    const fn other_pair_member(self) -> Leg {
        match self {
            Leg::FrontRight => Leg::RearRight,
            Leg::FrontLeft => Leg::RearLeft,
            Leg::RearRight => Leg::FrontRight,
            Leg::RearLeft => Leg::FrontLeft,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn values(outside: &[Leg]) -> LegMap<f64> {
        LegMap::from_fn(|l| if outside.contains(&l) { 1.5 } else { 0.5 })
    }

    #[test]
    fn nothing_outside_means_no_swing() {
        for gait in [Gait::Trot, Gait::Walk, Gait::Free] {
            assert!(next_swing(gait, &values(&[]), &[]).is_empty());
        }
    }

    #[test]
    fn trot_pairs_alternate() {
        let first = next_swing(Gait::Trot, &values(&[Leg::FrontRight]), &[]);
        assert_eq!(first, vec![Leg::FrontRight, Leg::RearLeft]);
        // Whatever triggers next, the other pair goes.
        let second = next_swing(Gait::Trot, &values(&[Leg::RearLeft]), &first);
        let mut s = second.clone();
        s.sort();
        assert_eq!(s, vec![Leg::FrontLeft, Leg::RearRight]);
        let third = next_swing(Gait::Trot, &values(&[Leg::FrontLeft]), &second);
        let mut t = third.clone();
        t.sort();
        assert_eq!(t, vec![Leg::FrontRight, Leg::RearLeft]);
    }

    #[test]
    fn walk_swings_one_leg_at_a_time_in_order() {
        let mut prev = next_swing(Gait::Walk, &values(&[Leg::FrontLeft]), &[]);
        assert_eq!(prev, vec![Leg::FrontLeft]);
        let mut seen = Vec::new();
        for _ in 0..8 {
            let next = next_swing(
                Gait::Walk,
                &values(&[Leg::FrontRight, Leg::RearLeft]),
                &prev,
            );
            assert_eq!(next.len(), 1);
            seen.push(next[0]);
            prev = next;
        }
        assert_eq!(
            &seen[..4],
            &[
                Leg::RearRight,
                Leg::FrontRight,
                Leg::RearLeft,
                Leg::FrontLeft
            ]
        );
    }

    #[test]
    fn free_never_repeats_a_leg_and_swings_at_most_a_diagonal_pair() {
        let first = next_swing(Gait::Free, &values(&[Leg::FrontRight]), &[]);
        assert_eq!(first, vec![Leg::FrontRight]);
        // FR still outside but just swung: not again.
        assert!(next_swing(Gait::Free, &values(&[Leg::FrontRight]), &first).is_empty());
        let pair = next_swing(Gait::Free, &LegMap([1.2, 2.0, 1.1, 0.3]), &first);
        // FL is furthest out; its diagonal RR is outside too; FR is excluded.
        assert_eq!(pair, vec![Leg::FrontLeft, Leg::RearRight]);
        let lone = next_swing(Gait::Free, &LegMap([1.2, 2.0, 0.5, 1.3]), &[]);
        assert_eq!(
            lone,
            vec![Leg::FrontLeft],
            "FL's diagonal RR is inside: FL swings alone"
        );
    }
}
