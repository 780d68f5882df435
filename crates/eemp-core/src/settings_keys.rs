//! What each key of the settings tree (`settings`) means: its unit, the range its
//! struct's `validate()` allows, and what it does, one [`KeyDoc`] per leaf key (nested structs
//! dotted, `planner.gait` left out: a run's gait is not a setting). Option fields that are
//! absent from the tree while unset are listed too.
//!
//! `unit`: SI units, "1" dimensionless, "bool", "count" for integers, "" for enums. `range`: as
//! `validate()` checks it (bounds inclusive unless written with a parenthesis; "each" for every
//! component of a list; "or unset" for an Option), "any" where nothing checks it.

/// One key of the settings tree.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KeyDoc {
    /// Dotted key, as `--set` and `eemp config show` write it.
    pub key: &'static str,
    pub unit: &'static str,
    pub range: &'static str,
    pub what: &'static str,
}

const fn k(
    key: &'static str,
    unit: &'static str,
    range: &'static str,
    what: &'static str,
) -> KeyDoc {
    KeyDoc {
        key,
        unit,
        range,
        what,
    }
}

/// Every key of the settings tree, table by table (`settings::TABLES`), in the order the
/// structs declare their fields.
pub const KEYS: &[KeyDoc] = &[
    // planner: PlannerConfig
    k(
        "planner.progress_factor",
        "1",
        "[0, 2]",
        "Factor on V_des·ΔT in eq. (6): ½ as in the paper's eq. (6), 1 as in its Algorithm 1",
    ),
    k(
        "planner.max_accel_mps2",
        "m/s²",
        "[0.05, 20]",
        "How fast the body reference may follow a step in the command",
    ),
    k(
        "planner.retarget_swing",
        "bool",
        "true/false",
        "Re-evaluate eq. (6) at every step of a running swing and move its touchdown",
    ),
    k(
        "planner.preview_swings",
        "bool",
        "true/false",
        "Show the MPC the swings Algorithm 1 will start within its horizon, not only running ones",
    ),
    k(
        "planner.free_pairing.pair_tolerance",
        "1",
        "[0, 1]",
        "Free gait: the diagonal partner swings along when its eq. (5) value is above 1 − this",
    ),
    k(
        "planner.free_pairing.support_margin_m",
        "m",
        "[-0.2, 0.2]",
        "Free gait: partner goes along if a lone swing leaves the trunk less than this in support",
    ),
    k(
        "planner.free_pairing.support_check",
        "bool",
        "true/false",
        "Free gait: whether the support rule (support_margin_m) applies at all",
    ),
    k(
        "planner.walk_support.check",
        "bool",
        "true/false",
        "Walk: pass over a leg whose lone swing leaves the capture point outside the other feet",
    ),
    k(
        "planner.walk_support.margin_m",
        "m",
        "[-0.2, 0]",
        "Walk: how far inside the other feet's triangle the capture point must lie (<0: outside)",
    ),
    k(
        "planner.walk_support.max_speed_mps",
        "m/s",
        "[0, 10]",
        "Walk: the support check runs below this commanded speed (0: at every speed)",
    ),
    k(
        "planner.first_step_on_command",
        "bool",
        "true/false",
        "Step as soon as a horizontal speed is commanded, not when a foot leaves its ellipse",
    ),
    k(
        "planner.position_error_max_m",
        "m",
        "[0, 0.5]",
        "Body reference at the integrated command, kept this close to the trunk; 0: off",
    ),
    k(
        "planner.ellipse_friction_factor",
        "1",
        "[0, 3] or unset",
        "Keeps ellipse radii ≤ factor·μ̂·X_z (friction cone from the hip); 0: off; unset: gait's",
    ),
    k(
        "planner.touchdown_friction_factor",
        "1",
        "[0, 3] or unset",
        "Keeps eq. (6)'s feedback term ≤ factor·μ̂·X_z long; 0: off; unset: the gait's",
    ),
    // mpc: MpcConfig
    k(
        "mpc.horizon",
        "count",
        "[1, 40]",
        "Number of MPC prediction steps",
    ),
    k("mpc.dt_s", "s", "[0.002, 0.1]", "MPC prediction step"),
    k(
        "mpc.friction_coefficient",
        "1",
        "[0.05, 2]",
        "Friction coefficient of the MPC's pyramid constraints (below the floor's, for margin)",
    ),
    k(
        "mpc.f_min_n",
        "N",
        "[0, 1000]",
        "Lower bound on the normal force of a foot in contact",
    ),
    k(
        "mpc.f_max_n",
        "N",
        "[max(mpc.f_min_n, 1), 5000] or unset",
        "A foot's normal force bound; unset: the robot file's, else what a leg holds",
    ),
    k(
        "mpc.weight_rpy",
        "1/rad²",
        "[0, 1e6] each",
        "Weights on roll, pitch, yaw errors",
    ),
    k(
        "mpc.weight_position",
        "1/m²",
        "[0, 1e6] each",
        "Weights on x, y, z position errors",
    ),
    k(
        "mpc.weight_omega",
        "s²/rad²",
        "[0, 1e6] each",
        "Weights on angular-velocity errors",
    ),
    k(
        "mpc.weight_velocity",
        "s²/m²",
        "[0, 1e6] each",
        "Weights on linear-velocity errors",
    ),
    k(
        "mpc.weight_force",
        "1/N²",
        "[1e-12, 1]",
        "Weight on every squared force component",
    ),
    k(
        "mpc.weight_heat",
        "1/W",
        "[0, 1] or unset",
        "Weight on stance legs' Joule heat; 0: off; unset: the robot file's, else 0",
    ),
    k(
        "mpc.solver",
        "",
        "quadprog, clarabel",
        "QP solver: quadprog (dense active set) or clarabel (interior point)",
    ),
    k(
        "mpc.drop_swing_forces",
        "bool",
        "true/false",
        "Leave swing feet's force variables out of the QP instead of bounding them to zero",
    ),
    k(
        "mpc.force_hold_steps",
        "steps",
        "[1, mpc.horizon]",
        "Move blocking: a foot's force held over this many steps; 1: one per step (eq. 2)",
    ),
    k(
        "mpc.force_hold_start",
        "steps",
        "[1, mpc.horizon]",
        "First horizon step whose force may be held with the next ones (move blocking)",
    ),
    // swing: SwingGains
    k(
        "swing.kp_n_per_m",
        "N/m",
        "[0, 1e5] each",
        "Swing law's proportional gain K_p (eq. 1), per body-frame axis",
    ),
    k(
        "swing.kd_n_s_per_m",
        "N·s/m",
        "[0, 1e4] each",
        "Swing law's derivative gain K_d (eq. 1), per body-frame axis",
    ),
    k(
        "swing.feedforward_acceleration",
        "bool",
        "true/false",
        "Add the feed-forward Jᵀ Λ a_ref term of eq. (1)",
    ),
    // slip: SlipConfig
    k(
        "slip.adapt_friction",
        "bool",
        "true/false",
        "Lower the MPC's friction coefficient when a stance foot slides",
    ),
    k(
        "slip.speed_threshold_mps",
        "m/s",
        "[0.01, 2]",
        "Horizontal ground speed above which a stance foot slides",
    ),
    k(
        "slip.min_normal_force_n",
        "N",
        "[0, 1000]",
        "Only a foot the MPC asks to carry at least this normal force counts",
    ),
    k(
        "slip.settle_s",
        "s",
        "[0, 1]",
        "Time after touchdown before a foot can count as sliding",
    ),
    k(
        "slip.backoff",
        "1",
        "[0.1, 1]",
        "Factor on the friction coefficient at a slip",
    ),
    k(
        "slip.min_friction",
        "1",
        "[0.05, 2]",
        "The friction coefficient never drops below this",
    ),
    k(
        "slip.recovery_per_s",
        "1/s",
        "[0, 10]",
        "Recovery of the coefficient towards the nominal without slips, per second",
    ),
    k(
        "slip.refractory_s",
        "s",
        "[0, 10]",
        "After a backoff, further slips within this time do not lower the coefficient again",
    ),
    k(
        "slip.raise_on_hold",
        "bool",
        "true/false",
        "A loaded foot that holds a force ratio above the coefficient raises it to that ratio",
    ),
    k(
        "slip.initial_friction",
        "1",
        "[0.05, 2] or unset",
        "Coefficient the adapter starts from; unset: robot file's, else the cautious start",
    ),
    k(
        "slip.hold_cap_after_slip",
        "1",
        "[0, 1]",
        "After a slip, holds raise the coefficient to at most this × the one at the slip; 0: no cap",
    ),
    k(
        "slip.hold_cap_recovery_per_s",
        "1/s",
        "[0, 10]",
        "The hold cap's own recovery towards the nominal, per second (0: the cap stays)",
    ),
    k(
        "slip.max_vertical_speed_mps",
        "m/s",
        "[0, 10]",
        "A stance foot moving vertically faster than this never counts as a slip; 0: off",
    ),
    k(
        "slip.require_ground_speed",
        "bool",
        "true/false",
        "A foot slides only if it also moves over the ground faster than speed_threshold_mps",
    ),
    k(
        "slip.hold_raise_fraction",
        "1",
        "[0.1, 1]",
        "A hold raises the coefficient to this fraction of the force ratio the MPC asked",
    ),
    k(
        "slip.max_speed_mps",
        "m/s",
        "[0, 10]",
        "Slip handling runs only while the reference speed is below this (0: no limit)",
    ),
    k(
        "slip.slow_below_friction",
        "1",
        "0 or (slip.min_friction, slip.slow_release_friction]",
        "Below this coefficient the commanded speed is capped at slow_speed_mps; 0: off",
    ),
    k(
        "slip.slow_speed_mps",
        "m/s",
        "[0, 10]",
        "The speed cap on a floor found slippery",
    ),
    k(
        "slip.slow_release_friction",
        "1",
        "[0.05, 2]",
        "The coefficient at which the speed cap lifts again",
    ),
    // schedule: ControllerConfig::mpc_period_s
    k(
        "schedule.mpc_period_s",
        "s",
        "[0.001, 0.1]",
        "Time between MPC solves; a change of the stance set triggers an extra solve",
    ),
    // filter: KfConfig (the units follow from how the filter adds each to its covariances)
    k(
        "filter.imu_process_noise_position",
        "m²/s",
        "[1e-9, 100]",
        "Process noise of the trunk position (variance added per step: dt/20 × this)",
    ),
    k(
        "filter.imu_process_noise_velocity",
        "m/s",
        "[1e-9, 100]",
        "Process noise of the trunk velocity (variance added per step: dt·g/20 × this)",
    ),
    k(
        "filter.foot_process_noise_position",
        "m²/s",
        "[1e-9, 100]",
        "Process noise of the foot positions (variance per second, × suspect for untrusted legs)",
    ),
    k(
        "filter.foot_sensor_noise_position",
        "m²",
        "[1e-9, 100]",
        "Variance of a leg's kinematic foot-position reading",
    ),
    k(
        "filter.foot_sensor_noise_velocity",
        "m²/s²",
        "[1e-9, 100]",
        "Variance of a stance leg's trunk-velocity reading (× suspect for untrusted legs)",
    ),
    k(
        "filter.foot_height_sensor_noise",
        "m²",
        "[1e-9, 100]",
        "Variance of a stance foot's height reading (× suspect for untrusted legs)",
    ),
    k(
        "filter.foot_height_m",
        "m",
        "[0, 0.2]",
        "Height of a foot centre above flat ground in stance (the foot radius)",
    ),
    k(
        "filter.suspect_factor",
        "1",
        "[1, 1e6]",
        "Factor by which an untrusted leg's noise grows",
    ),
    k(
        "filter.velocity_jump_mps",
        "m/s",
        "[0, 10]",
        "Trusted legs agreeing on a velocity this far off take over at once; 0: off",
    ),
    k(
        "filter.velocity_jump_agreement",
        "1",
        "[0, 1]",
        "How closely legs must agree for a jump: each within this fraction of it from their mean",
    ),
    k(
        "filter.velocity_jump_dragged_fraction",
        "1",
        "[0, 1]",
        "A push's jump some legs read: the others must read at least this fraction of it; 0: off",
    ),
    k(
        "filter.leg_outlier_mps",
        "m/s",
        "[0, 10]",
        "A stance leg disagreeing by more than this loses trust (to 0 at twice it); 0: off",
    ),
];

/// The doc of a dotted key, if it is one.
pub fn doc(key: &str) -> Option<&'static KeyDoc> {
    KEYS.iter().find(|d| d.key == key)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::convex_mpc::MpcConfig;
    use crate::estimator::KfConfig;
    use crate::locomotion::ControllerConfig;
    use crate::planner::{Gait, PlannerConfig};
    use crate::settings::{leaves, ControllerSettings};
    use crate::slip::SlipConfig;
    use std::collections::HashSet;

    /// The full default settings of a gait on the filter, every option set (in range).
    fn full(gait: Gait) -> ControllerSettings {
        ControllerSettings {
            planner: PlannerConfig {
                gait,
                ellipse_friction_factor: Some(1.0),
                touchdown_friction_factor: Some(0.5),
                ..Default::default()
            },
            controller: ControllerConfig {
                mpc: MpcConfig {
                    weight_heat: Some(0.0),
                    f_max_n: Some(160.0),
                    ..Default::default()
                },
                slip: SlipConfig {
                    initial_friction: Some(0.3),
                    ..SlipConfig::default_for(gait)
                },
                ..Default::default()
            },
            filter: Some(KfConfig::default()),
        }
    }

    const GAITS: [Gait; 3] = [Gait::Trot, Gait::Walk, Gait::Free];

    #[test]
    fn every_leaf_has_a_doc_and_every_doc_a_leaf() {
        for gait in GAITS {
            let keys: Vec<String> = leaves(&full(gait).to_tree())
                .into_iter()
                .map(|(k, _)| k)
                .filter(|k| k != "planner.gait")
                .collect();
            for key in &keys {
                assert!(doc(key).is_some(), "{gait}: {key} has no KeyDoc");
            }
            for d in KEYS {
                assert!(
                    keys.iter().any(|k| k == d.key),
                    "{gait}: KeyDoc {} is not a key of the tree",
                    d.key
                );
            }
            assert_eq!(keys.len(), KEYS.len(), "{gait}");
        }
    }

    #[test]
    fn no_key_twice_and_every_doc_filled_in() {
        let mut seen = HashSet::new();
        for d in KEYS {
            assert!(seen.insert(d.key), "{} twice", d.key);
            assert!(!d.range.is_empty(), "{}: no range", d.key);
            assert!(
                !d.what.is_empty() && d.what.chars().count() <= 90,
                "{}: what is {} chars",
                d.key,
                d.what.chars().count()
            );
            assert!(d.key != "planner.gait");
            assert_eq!(doc(d.key), Some(d));
        }
        assert!(doc("mpc.horizn").is_none());
    }

    /// A `[lo, hi]` range (optionally "each" or "or unset"), parsed.
    fn closed_range(range: &str) -> Option<(f64, f64)> {
        let r = range
            .trim_end_matches(" or unset")
            .trim_end_matches(" each");
        let inner = r.strip_prefix('[')?.strip_suffix(']')?;
        let (lo, hi) = inner.split_once(", ")?;
        Some((lo.parse().ok()?, hi.parse().ok()?))
    }

    /// Each plain `[lo, hi]` range is what validation checks: the bounds are accepted (unless
    /// another key's own range refuses them) and values just outside are refused by this key.
    #[test]
    fn closed_ranges_are_what_validation_checks() {
        let mut checked = 0;
        for gait in GAITS {
            let s = full(gait);
            let tree = s.to_tree();
            let values: std::collections::HashMap<String, toml::Value> =
                leaves(&tree).into_iter().collect();
            for d in KEYS {
                let Some((lo, hi)) = closed_range(d.range) else {
                    continue;
                };
                // The error of `--set key=...` names the value it refuses first, by its key.
                let names_own_key = |e: &str, set: &str| {
                    let why = e.strip_prefix(&format!("--set {set}: ")).unwrap_or(e);
                    let own = d.key;
                    why.starts_with(&format!("{own} "))
                        || why.starts_with(&format!("{own}["))
                        || why.starts_with(&format!("{own}:"))
                };
                let render = |x: f64| -> String {
                    match &values[d.key] {
                        toml::Value::Integer(_) => format!("{}", x as i64),
                        toml::Value::Array(a) => {
                            format!("[{}]", vec![format!("{x:?}"); a.len()].join(", "))
                        }
                        _ => format!("{x:?}"),
                    }
                };
                let integer = matches!(values[d.key], toml::Value::Integer(_));
                let (below, above) = if integer {
                    (lo - 1.0, hi + 1.0)
                } else {
                    (
                        lo - (lo.abs() * 1e-3).max(1e-15),
                        hi + (hi.abs() * 1e-3).max(1e-15),
                    )
                };
                for x in [lo, hi] {
                    let set = format!("{}={}", d.key, render(x));
                    if let Err(e) = s.with_sets(std::slice::from_ref(&set)) {
                        assert!(
                            !names_own_key(&e, &set),
                            "{gait}: {set} refused for its own key: {e}"
                        );
                    }
                }
                for x in [below, above] {
                    let set = format!("{}={}", d.key, render(x));
                    let e = s
                        .with_sets(std::slice::from_ref(&set))
                        .expect_err(&format!("{gait}: {set} accepted"));
                    assert!(names_own_key(&e, &set), "{gait}: {set}: {e}");
                }
                checked += 1;
            }
        }
        assert!(checked > 3 * 40, "{checked}");
    }
}
