//! Which legs swing when a stance foot leaves its ellipse.

use crate::config_error::{check_range, ConfigError};
use crate::leg::{Leg, LegMap};
use nalgebra::Vector2;
use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Hash)]
#[serde(rename_all = "snake_case")]
pub enum Gait {
    /// Diagonal pairs swing together and alternate: after FR+RL comes FL+RR.
    Trot,
    /// One leg at a time in the fixed order RL → FL → RR → FR (the lateral-sequence walk).
    Walk,
    /// No predetermined order: a leg outside its ellipse swings (never one that swung in the
    /// previous step), alone or with its diagonal partner (a diagonal pair at most, so two feet
    /// always support the body); [`FreePairing`] says when the partner goes along, which may
    /// be a partner inside its ellipse or one of the previous step.
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

/// The walk's order when the trunk moves backwards: [`WALK_ORDER`] with front and rear swapped, so
/// that the legs at the back of the motion lead as the hind legs do forwards. Walked backwards in
/// the forward order, the legs at the front of the motion lead, and the walk tracks badly, costs
/// more and falls; in this order it walks backwards as it does forwards (forward walks are
/// unchanged bit for bit).
pub const WALK_ORDER_BACKWARD: [Leg; 4] = [
    Leg::FrontLeft,
    Leg::RearLeft,
    Leg::FrontRight,
    Leg::RearRight,
];

/// When the free gait swings a leg's diagonal partner with it (the paper leaves the free gait's
/// choice open). Both rules target the same failure: a lone swing with the feet behind the hips
/// (at the back of their ellipses) leaves the trunk ahead of the other three feet, it tips
/// towards the swinging foot, and on a floor of friction 0.3 the loaded feet slide out (without
/// either rule the free gait does not stay up on such a floor).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FreePairing {
    /// The partner goes along when its eq. (5) value is above 1 − this, i.e. it is near its
    /// own edge and would leave within a fraction of a step (0: only when it is outside, the
    /// earlier rule). From a standing start all four feet reach their edges within a
    /// millimetre, and the first foot over alone set the gait out of its diagonal rhythm.
    pub pair_tolerance: f64,
    /// The partner goes along, even one that swung in the previous step, when a lone swing
    /// would leave the trunk's ground projection less than this inside the triangle of the
    /// other three feet, m (negative: outside by up to that much is accepted).
    pub support_margin_m: f64,
    /// Whether the support rule applies at all.
    pub support_check: bool,
}

impl Default for FreePairing {
    fn default() -> Self {
        FreePairing {
            pair_tolerance: 0.5,
            support_margin_m: 0.0,
            support_check: true,
        }
    }
}

/// Whether the walk lets the next leg of its order swing (issue 22; the paper's walk always
/// does). A lone swing leaves the trunk on the other three feet, and in the walk's symmetric
/// stance the trunk stands on the diagonal those feet span, so a velocity error towards the
/// lifted foot's corner tips it over that diagonal: the MPC cannot brake while the centre of
/// pressure it needs lies outside the triangle. Under a side push on a slippery floor, a leg on
/// the pushed side that lifts right after the push leaves the trunk sliding sideways over that
/// diagonal for the whole swing, and it runs out of its feet within the next steps. So a leg is
/// passed over while the capture point of the velocity error (the trunk plus eq. (6)'s feedback
/// term √(X_z/g)·(V_cur − V_des), unbounded) lies more than `-margin_m` outside the other three
/// feet's triangle, and the next leg of the order whose triangle holds it swings instead (the
/// order then goes on from that leg); when none does, the leg of the order swings. On command
/// the capture point is the trunk, so a walk that tracks its command keeps its order. Only
/// below a commanded speed (`max_speed_mps`, 0.6 m/s, where the walk's slip handling stops
/// too): at 0.7–1.0 m/s the walk tracks 0.2 m/s behind its command and its trunk runs ahead of
/// its feet, so the check would pass over legs there and break the order the fast walk needs
/// to stay up even on the flat floor.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WalkSupport {
    /// Whether the check applies (off: the fixed order, the paper's walk).
    pub check: bool,
    /// How far inside the other feet's triangle the capture point must lie, m (negative:
    /// outside by up to that much is accepted).
    pub margin_m: f64,
    /// The check runs while the commanded horizontal speed is below this, m/s (0: at every
    /// speed).
    pub max_speed_mps: f64,
}

/// Allowed [`WalkSupport::margin_m`], m.
pub const WALK_SUPPORT_MARGIN_RANGE: [f64; 2] = [-0.2, 0.0];

/// [`WalkSupport::margin_m`] by default, m (see [`WalkSupport::default`]).
pub const DEFAULT_WALK_SUPPORT_MARGIN_M: f64 = -0.05;

/// [`WalkSupport::max_speed_mps`] by default, m/s: where the walk's slip handling stops too
/// (`slip.max_speed_mps` in `settings/walk.toml`; a test keeps the two equal).
pub const DEFAULT_WALK_SUPPORT_MAX_SPEED_MPS: f64 = 0.6;

/// Allowed [`WalkSupport::max_speed_mps`], m/s.
pub const WALK_SUPPORT_MAX_SPEED_RANGE: [f64; 2] = [0.0, 10.0];

impl Default for WalkSupport {
    /// −0.05 m: an ordinary walk's capture point lies up to ≈ 2 cm outside the triangle of the
    /// leg its order lifts, so a margin that tight passes over legs in ordinary walking and the
    /// walk loses its order; −0.05 m leaves room for that and still passes over the legs whose
    /// lift would tip the trunk under a side push on a slippery floor (it keeps as many such
    /// pushes as −0.03 m, and far more than no check).
    fn default() -> Self {
        WalkSupport {
            check: true,
            margin_m: DEFAULT_WALK_SUPPORT_MARGIN_M,
            max_speed_mps: DEFAULT_WALK_SUPPORT_MAX_SPEED_MPS,
        }
    }
}

impl WalkSupport {
    /// The paper's walk: the fixed order always.
    pub const OFF: WalkSupport = WalkSupport {
        check: false,
        margin_m: DEFAULT_WALK_SUPPORT_MARGIN_M,
        max_speed_mps: DEFAULT_WALK_SUPPORT_MAX_SPEED_MPS,
    };

    pub fn validate(&self, prefix: &str) -> Result<(), ConfigError> {
        let [lo, hi] = WALK_SUPPORT_MARGIN_RANGE;
        check_range(&format!("{prefix}.margin_m"), self.margin_m, lo, hi)?;
        let [lo, hi] = WALK_SUPPORT_MAX_SPEED_RANGE;
        check_range(
            &format!("{prefix}.max_speed_mps"),
            self.max_speed_mps,
            lo,
            hi,
        )
    }

    /// The check as it applies under a command of this horizontal speed (m/s): off from
    /// `max_speed_mps` on.
    pub fn in_force(&self, command_speed_mps: f64) -> WalkSupport {
        let fast = self.max_speed_mps > 0.0 && command_speed_mps >= self.max_speed_mps;
        WalkSupport {
            check: self.check && !fast,
            ..*self
        }
    }

    /// `next`, or, when its lone swing would leave the capture point outside the support (a
    /// NaN margin counts as outside), the first leg after it in `order` that would not; `next`
    /// when none.
    fn choose(&self, order: &[Leg; 4], next: Leg, margin_m: &dyn Fn(Leg) -> f64) -> Leg {
        let supported = |leg: Leg| margin_m(leg) >= self.margin_m - MARGIN_TOLERANCE_M;
        if !self.check || supported(next) {
            return next;
        }
        let at = order.iter().position(|l| *l == next).expect("walk leg");
        (1..4)
            .map(|i| order[(at + i) % 4])
            .find(|leg| supported(*leg))
            .unwrap_or(next)
    }
}

/// Lone-swing margins within this of `support_margin_m` count as at it, m: in a symmetric
/// stance the trunk lies on both diagonals and every margin is 0 up to rounding.
const MARGIN_TOLERANCE_M: f64 = 1e-6;

impl FreePairing {
    pub fn validate(&self, prefix: &str) -> Result<(), ConfigError> {
        check_range(
            &format!("{prefix}.pair_tolerance"),
            self.pair_tolerance,
            0.0,
            1.0,
        )?;
        check_range(
            &format!("{prefix}.support_margin_m"),
            self.support_margin_m,
            -0.2,
            0.2,
        )
    }

    /// The free gait before these rules (a partner only when it is outside its ellipse too).
    pub const UNPAIRED: FreePairing = FreePairing {
        pair_tolerance: 0.0,
        support_margin_m: 0.0,
        support_check: false,
    };
}

/// Signed distance of `point` inside the triangle `tri` (negative outside: the distance to the
/// nearest edge's line), m; either winding.
pub fn triangle_margin(point: &Vector2<f64>, tri: [Vector2<f64>; 3]) -> f64 {
    let winding = (tri[1] - tri[0]).perp(&(tri[2] - tri[0])).signum();
    (0..3)
        .map(|i| {
            let (a, b) = (tri[i], tri[(i + 1) % 3]);
            let edge = b - a;
            winding * edge.perp(&(point - a)) / edge.norm().max(1e-9)
        })
        // NaN in, NaN out (f64::min would drop it).
        .fold(f64::INFINITY, |a, b| {
            if a.is_nan() || b.is_nan() {
                f64::NAN
            } else {
                a.min(b)
            }
        })
}

/// What the swing choice reads: eq. (5)'s left-hand sides of the stance feet (> 1 is outside),
/// and how far inside the other three feet's triangle the support point would be if a leg
/// swung alone (see [`triangle_margin`]; asked by the free gait's support check, with the
/// trunk's origin, and by the walk's, [`WalkSupport`], with the capture point).
#[derive(Clone, Copy)]
pub struct SwingInputs<'a> {
    pub ellipse_values: &'a LegMap<f64>,
    pub lone_swing_margin_m: &'a dyn Fn(Leg) -> f64,
    /// The trunk's reference moves backwards (the walk then takes [`WALK_ORDER_BACKWARD`]).
    pub backward: bool,
}

/// Chooses the legs of the next swing; `previous` are the legs of the previous swing. Returns an
/// empty set when no foot is outside (all four stay in stance).
pub fn next_swing(
    gait: Gait,
    inputs: SwingInputs,
    previous: &[Leg],
    pairing: &FreePairing,
    walk_support: &WalkSupport,
) -> Vec<Leg> {
    let ellipse_values = inputs.ellipse_values;
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
            let order = match inputs.backward {
                true => &WALK_ORDER_BACKWARD,
                false => &WALK_ORDER,
            };
            let next = match previous.first() {
                Some(prev) => {
                    order[(order.iter().position(|l| l == prev).expect("walk leg") + 1) % 4]
                }
                None => most_outside(&outside, ellipse_values),
            };
            vec![walk_support.choose(order, next, inputs.lone_swing_margin_m)]
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
            let partner = leg.diagonal();
            let partner_near = !previous.contains(&partner)
                && ellipse_values[partner] > 1.0 - pairing.pair_tolerance;
            // A margin that is not a number (a NaN foot position) counts as unsupported.
            let unsupported_alone = pairing.support_check && {
                let margin = (inputs.lone_swing_margin_m)(leg);
                margin.is_nan() || margin < pairing.support_margin_m - MARGIN_TOLERANCE_M
            };
            if partner_near || unsupported_alone {
                vec![leg, partner]
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

    /// The choice with every lone swing well supported and the earlier free-gait rule.
    fn next_swing(gait: Gait, values: &LegMap<f64>, previous: &[Leg]) -> Vec<Leg> {
        next_swing_with(
            gait,
            values,
            &LegMap::splat(1.0),
            previous,
            &FreePairing::UNPAIRED,
        )
    }

    fn next_swing_with(
        gait: Gait,
        values: &LegMap<f64>,
        margins: &LegMap<f64>,
        previous: &[Leg],
        pairing: &FreePairing,
    ) -> Vec<Leg> {
        super::next_swing(
            gait,
            SwingInputs {
                ellipse_values: values,
                lone_swing_margin_m: &|leg| margins[leg],
                backward: false,
            },
            previous,
            pairing,
            &WalkSupport::default(),
        )
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
    fn walking_backwards_the_walk_swaps_front_and_rear_in_its_order() {
        let values = values(&[Leg::FrontRight, Leg::RearLeft]);
        let mut prev = vec![Leg::FrontLeft];
        let mut seen: Vec<Leg> = Vec::new();
        for _ in 0..4 {
            prev = super::next_swing(
                Gait::Walk,
                SwingInputs {
                    ellipse_values: &values,
                    lone_swing_margin_m: &|_| 1.0,
                    backward: true,
                },
                &prev,
                &FreePairing::default(),
                &WalkSupport::default(),
            );
            seen.extend(&prev);
        }
        // FL → RL → FR → RR: each side's front leg first, as the hind legs lead forwards.
        assert_eq!(
            seen,
            [
                Leg::RearLeft,
                Leg::FrontRight,
                Leg::RearRight,
                Leg::FrontLeft
            ]
        );
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
    fn the_walk_passes_over_a_leg_whose_lone_swing_would_leave_the_capture_point_outside() {
        let outside = values(&[Leg::FrontLeft]);
        let walk = |margins: LegMap<f64>, support: WalkSupport| {
            super::next_swing(
                Gait::Walk,
                SwingInputs {
                    ellipse_values: &outside,
                    lone_swing_margin_m: &|leg| margins[leg],
                    backward: false,
                },
                // After RL comes FL.
                &[Leg::RearLeft],
                &FreePairing::default(),
                &support,
            )
        };
        let on = WalkSupport::default();
        // FL's margin at the threshold (−0.05 m) still swings; an ordinary walk's ≈ −0.02 too.
        let mut m = LegMap::splat(0.03);
        m[Leg::FrontLeft] = -0.05;
        assert_eq!(walk(m, on), vec![Leg::FrontLeft]);
        // 7 cm outside (a side push towards FL): the next leg of the order, RR, swings.
        m[Leg::FrontLeft] = -0.07;
        assert_eq!(walk(m, on), vec![Leg::RearRight]);
        // RR unsupported too: FR, the one after it.
        m[Leg::RearRight] = -0.06;
        assert_eq!(walk(m, on), vec![Leg::FrontRight]);
        // None supported (or a NaN margin): the order's own leg.
        assert_eq!(walk(LegMap::splat(-0.1), on), vec![Leg::FrontLeft]);
        assert_eq!(walk(LegMap::splat(f64::NAN), on), vec![Leg::FrontLeft]);
        // Off: the paper's fixed order whatever the margins; so from 0.6 m/s commanded on.
        m[Leg::FrontRight] = 0.03;
        assert_eq!(walk(m, WalkSupport::OFF), vec![Leg::FrontLeft]);
        assert_eq!(walk(m, on.in_force(0.59)), vec![Leg::FrontRight]);
        assert_eq!(walk(m, on.in_force(0.6)), vec![Leg::FrontLeft]);
        let unlimited = WalkSupport {
            max_speed_mps: 0.0,
            ..on
        };
        assert_eq!(walk(m, unlimited.in_force(5.0)), vec![Leg::FrontRight]);
        // The trot and the free gait ignore it (their choice with and without is the same).
        for gait in [Gait::Trot, Gait::Free] {
            let choose = |support: WalkSupport| {
                super::next_swing(
                    gait,
                    SwingInputs {
                        ellipse_values: &outside,
                        lone_swing_margin_m: &|_| -0.1,
                        backward: false,
                    },
                    &[Leg::RearLeft],
                    &FreePairing::default(),
                    &support,
                )
            };
            assert_eq!(choose(on), choose(WalkSupport::OFF), "{gait}");
        }
    }

    #[test]
    fn walk_support_margins_outside_their_range_are_refused_by_name() {
        let d = WalkSupport::default();
        let margin = |m| WalkSupport { margin_m: m, ..d };
        let speed = |v| WalkSupport {
            max_speed_mps: v,
            ..d
        };
        // (the config, the key named, the range named; a NaN names no range)
        for (bad, key, range) in [
            (margin(0.01), "margin_m", "[-0.2, 0]"),
            (margin(-0.3), "margin_m", "[-0.2, 0]"),
            (margin(f64::NAN), "margin_m", ""),
            (speed(-0.1), "max_speed_mps", "[0, 10]"),
            (speed(11.0), "max_speed_mps", "[0, 10]"),
        ] {
            let err = bad
                .validate("planner.walk_support")
                .unwrap_err()
                .to_string();
            assert!(
                err.contains(&format!("planner.walk_support.{key}")),
                "{err}"
            );
            assert!(err.contains(range), "{err}");
        }
        assert!(WalkSupport::default().validate("p").is_ok());
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

    #[test]
    fn free_takes_a_partner_near_its_edge_along() {
        let pairing = FreePairing::default();
        let supported = LegMap::splat(1.0);
        // FL just over its edge, its partner RR at 0.6 (above 1 - 0.5): both go.
        let v = LegMap([0.2, 1.01, 0.6, 0.3]);
        assert_eq!(
            next_swing_with(Gait::Free, &v, &supported, &[], &pairing),
            vec![Leg::FrontLeft, Leg::RearRight]
        );
        // RR at 0.4 is not near: FL alone (and alone under the earlier rule at 0.6 too).
        let v = LegMap([0.2, 1.01, 0.4, 0.3]);
        assert_eq!(
            next_swing_with(Gait::Free, &v, &supported, &[], &pairing),
            vec![Leg::FrontLeft]
        );
        let v = LegMap([0.2, 1.01, 0.6, 0.3]);
        assert_eq!(next_swing(Gait::Free, &v, &[]), vec![Leg::FrontLeft]);
        // A partner that swung in the previous step is not taken for being near.
        assert_eq!(
            next_swing_with(Gait::Free, &v, &supported, &[Leg::RearRight], &pairing),
            vec![Leg::FrontLeft]
        );
    }

    #[test]
    fn free_pairs_a_lone_swing_that_would_leave_the_trunk_unsupported() {
        let pairing = FreePairing::default();
        let v = LegMap([1.2, 0.3, 0.2, 0.1]);
        // FR alone would leave the trunk 3 cm outside FL-RR-RL: RL goes too, although it
        // swung in the previous step.
        let margins = LegMap([-0.03, 0.04, 0.04, 0.04]);
        assert_eq!(
            next_swing_with(Gait::Free, &v, &margins, &[Leg::RearLeft], &pairing),
            vec![Leg::FrontRight, Leg::RearLeft]
        );
        // 1 cm inside is enough at the default margin of 0; off, FR goes alone.
        let margins = LegMap([0.01, 0.04, 0.04, 0.04]);
        assert_eq!(
            next_swing_with(Gait::Free, &v, &margins, &[Leg::RearLeft], &pairing),
            vec![Leg::FrontRight]
        );
        // A symmetric stance puts the trunk on the diagonal: a margin of 0 up to rounding is
        // at the default margin, not below it; a NaN margin (a NaN foot) is unsupported.
        let margins = LegMap([-1e-12, 0.04, 0.04, 0.04]);
        assert_eq!(
            next_swing_with(Gait::Free, &v, &margins, &[Leg::RearLeft], &pairing),
            vec![Leg::FrontRight]
        );
        let margins = LegMap([f64::NAN, 0.04, 0.04, 0.04]);
        assert_eq!(
            next_swing_with(Gait::Free, &v, &margins, &[Leg::RearLeft], &pairing),
            vec![Leg::FrontRight, Leg::RearLeft]
        );
        let margins = LegMap([-0.03, 0.04, 0.04, 0.04]);
        let off = FreePairing {
            support_check: false,
            ..pairing
        };
        assert_eq!(
            next_swing_with(Gait::Free, &v, &margins, &[Leg::RearLeft], &off),
            vec![Leg::FrontRight]
        );
    }

    #[test]
    fn triangle_margin_is_the_distance_to_the_nearest_edge() {
        // Right triangle (0,0) (1,0) (0,1), either winding.
        let tri = [
            Vector2::new(0.0, 0.0),
            Vector2::new(1.0, 0.0),
            Vector2::new(0.0, 1.0),
        ];
        let rev = [tri[2], tri[1], tri[0]];
        for t in [tri, rev] {
            assert!((triangle_margin(&Vector2::new(0.2, 0.1), t) - 0.1).abs() < 1e-12);
            assert!((triangle_margin(&Vector2::new(-0.3, 0.5), t) + 0.3).abs() < 1e-12);
            // Beyond the hypotenuse x + y = 1 by 0.2·√2 / 2.
            let d = triangle_margin(&Vector2::new(0.6, 0.6), t);
            assert!((d + 0.2 / 2f64.sqrt()).abs() < 1e-12, "{d}");
            assert!(triangle_margin(&Vector2::new(f64::NAN, 0.1), t).is_nan());
        }
    }
}
