//! The floor's friction from slips: a stance foot that slides says the floor gives less than the
//! MPC's friction pyramid assumes, so the MPC is told a lower friction coefficient; a foot that
//! holds a steeper force than the coefficient raises it again. On by default for every gait
//! (the walk gates its slides and runs below 0.6 m/s: `settings/walk.toml`,
//! [`SlipConfig::default_for`]); `eemp walk --set slip.adapt_friction=false` turns it off. How
//! each rule was traced and chosen, and the variants not kept, are in
//! `docs/notebook/2026-12-04-slippery-ground.md`.
//!
//! Why: the MPC's pyramid (|f_x|, |f_y| ≤ μ f_z with μ = 0.6 by default) lets its corners reach
//! √2·μ = 0.85, and the forces the legs really put on the ground also carry the leg's own
//! dynamics, so on a 0.3 floor stance feet slide. (The free gait's lone swings are a cause of
//! falls there of their own, which its diagonal pairing, `planner::FreePairing`, removes.) A
//! robot does not know the floor beforehand; it feels the slip.
//!
//! Rule: a foot in planned stance for at least [`SlipConfig::settle_s`] and loaded by the MPC
//! whose horizontal speed, relative to the most planted loaded foot, exceeds
//! [`SlipConfig::speed_threshold_mps`] starts a slip (a push moves all feet together: no slip).
//! At a slip the coefficient drops to `backoff` × itself, never below `min_friction`; a leg
//! counts one slip per stance. Without slips it climbs back towards the nominal at
//! `recovery_per_s`. (The ratio of the force the MPC asked of the sliding foot is no estimate
//! of the floor's friction: feet slid while asked for less than 0.3 on the 0.8 floor, and
//! lowering towards that ratio made the free gait at 0.1 m/s track worse.)
//!
//! What it trades: a slide lowers the coefficient whatever made the foot slide, so a side push,
//! which slides feet on any floor, leaves the MPC braking more gently than the floor allows
//! until the coefficient comes back; `raise_on_hold` (below) brings it back after a push. A
//! higher floor for the coefficient keeps more pushes but loses the slippery floor, so the floor
//! stays low. On the normal floor feet slide a little too and lower the coefficient, so a slow
//! free gait tracks a little worse; at walking speeds tracking and CoT stay within a few percent.
//!
//! Raising on hold without a ratchet. `raise_on_hold` raises the coefficient to the *norm* of
//! the tangential/normal ratio the MPC asked, but the MPC's pyramid lets that norm reach √2·μ̂
//! at its corners, and what the MPC asks is not what the foot puts on the ground. Unchecked,
//! holds after a slip lift the coefficient above the floor that just let a foot slide, and the
//! next touchdown's foot slides under the trunk. Two rules stop that:
//! - after a slip a hold raises the coefficient to at most [`SlipConfig::hold_cap_after_slip`]
//!   (0.95) × the coefficient at that slip, the cap recovering at
//!   [`SlipConfig::hold_cap_recovery_per_s`] (0.05/s): a slip is firmer evidence than a force the
//!   MPC asked for;
//! - a cautious start: the coefficient starts at [`CAUTIOUS_START`] (0.3) unless the run or the
//!   robot file gives another, and feet that hold raise it.
//!
//! These values were chosen on seeds the suites do not use, so that the suites test them rather
//! than fit them; nearby values moved the falls by no more than other seeds do. The stance a leg
//! starts in counts too: on a slippery floor the slides while the robot settles are the first
//! evidence. Part of what falls remain is not the estimate: an MPC held at a coefficient that
//! fits the floor, with no adapter, falls on those floors too. The cost on the flat floor: when
//! the trot's feet slide while it settles, the coefficient drops and the placement ellipses
//! shrink into that cone for the first 1–2 s, after which the trot keeps a gait cycle with more
//! lateral sway and tracks slightly worse (`docs/comparison-and-robustness.md`).
//!
//! Slowing down on a slippery floor: once the coefficient is below
//! [`SlipConfig::slow_below_friction`] the command's speed is capped at
//! [`SlipConfig::slow_speed_mps`] (0.3 m/s) until the coefficient is back at
//! [`SlipConfig::slow_release_friction`] (0.25), as a person slows down on ice. The walk uses it
//! (`settings/walk.toml`: 0.205, just above its floor of 0.2): at 0.5 m/s on a
//! slippery floor its coefficient reaches its floor seconds before it would fall, in time to slow
//! down, and on the normal floor it stays above the threshold, so the cap costs nothing there.
//! Not for the trot and the free gait: they walk those floors at speed, and their feet slide
//! while the robot settles, so the coefficient drops to its floor on the normal floor too and
//! the cap would slow and worsen their flat runs.

use crate::config_error::{check_range, ConfigError};
use crate::leg::{Leg, LegMap};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SlipConfig {
    /// Lower the MPC's friction coefficient when a stance foot slides.
    pub adapt_friction: bool,
    /// Horizontal ground speed above which a stance foot slides, m/s (the Kalman filter's
    /// velocity error is ≈ 0.03 m/s; a planted foot on the A1's floor moves < 0.02 m/s). Low, so
    /// a slip is caught at its start: with a threshold well above those errors the first slips on
    /// a slippery floor are seen too late to keep the robot up.
    pub speed_threshold_mps: f64,
    /// Only a foot the MPC asks to carry at least this normal force counts, N (an unloaded foot
    /// that drags, as the walk's rear feet do before lift-off, says nothing about the floor).
    pub min_normal_force_n: f64,
    /// Time after touchdown before a foot can count as sliding, s (touchdown transients).
    pub settle_s: f64,
    /// Factor on the coefficient at a slip.
    pub backoff: f64,
    /// The coefficient never drops below this.
    pub min_friction: f64,
    /// Recovery towards the nominal coefficient without slips, per second.
    pub recovery_per_s: f64,
    /// After a backoff, further slips within this time do not lower the coefficient again, s:
    /// one event (a push, a stumble, the first steps on ice) slides several feet within a few
    /// tens of milliseconds, and counting each cut the coefficient to its floor at once. 0 by
    /// default: on a slippery floor the robot falls within seconds, and a refractory time brings
    /// the coefficient down too slowly for that; raise_on_hold brings it back after a push
    /// instead.
    pub refractory_s: f64,
    /// A loaded stance foot that holds (no slide, relative or over the ground) while the MPC
    /// asks it for a tangential/normal force ratio above the coefficient shows the floor gives
    /// at least that much: the coefficient rises to that ratio (up to the nominal, and after a slip
    /// up to `hold_cap_after_slip`'s cap). Pushes ask
    /// for such forces, so after a push on a grippy floor the coefficient comes back within a
    /// few solves instead of the recovery's tens of seconds.
    pub raise_on_hold: bool,
    /// The coefficient the adapter starts from. A robot set down on an unknown floor starts
    /// cautious and lets feet that hold raise it (`raise_on_hold`). None: the robot file's
    /// `control.slip_initial_friction`, else [`CAUTIOUS_START`] (`LocomotionController::new`
    /// fills it); a bare [`FrictionAdapter`] starts at the MPC's nominal.
    pub initial_friction: Option<f64>,
    /// After a slip, a hold never raises the coefficient above this factor times the
    /// coefficient in force at that slip (the lowest such cap so far, recovering at
    /// `hold_cap_recovery_per_s`); 0: no cap. A slip says
    /// the floor gave less than that coefficient; the force a holding foot was *asked* for is
    /// weaker evidence (the pyramid's corners reach √2·μ̂, and the leg's own dynamics add to
    /// what is asked), and without the cap it lifted the coefficient above a 0.3 floor.
    pub hold_cap_after_slip: f64,
    /// The cap's own recovery towards the nominal, per second (faster than the coefficient's
    /// `recovery_per_s`, so that after a push on a grippy floor holds bring the coefficient
    /// back within seconds; 0: the cap stays).
    pub hold_cap_recovery_per_s: f64,
    /// A stance foot whose contact point moves vertically faster than this, m/s, is landing
    /// late or lifting off, not sliding on the floor: it never counts as a slip; 0: off (the
    /// trot's and the free gait's default). The walk's feet do both while planned in stance
    /// (late touchdowns descend at ≈ 1 m/s, rear feet lift at 0.3–0.8 m/s), and on the 0.8
    /// floor at 0.5 m/s those readings cut the coefficient to its floor.
    pub max_vertical_speed_mps: f64,
    /// A foot slides only if it moves over the ground faster than `speed_threshold_mps` too,
    /// not only relative to the most planted loaded foot (the walk's default): in the walk
    /// the anchor's own reading moves by ±0.06 m/s, so two feet that hold read as 0.1 m/s apart.
    pub require_ground_speed: bool,
    /// A hold raises the coefficient to this fraction of the tangential/normal ratio the MPC
    /// asked of the foot (1: the ratio itself, `Default` and the walk's; 0.8 for the trot and
    /// the free gait, [`SlipConfig::default_for`]). What the MPC asks is not what the foot
    /// applies, and the pyramid's corners let the asked ratio reach √2·μ̂, so a hold is weaker
    /// evidence than the ratio it was asked for; the discount matters once the capture step is
    /// bounded by the coefficient (`planner.touchdown_friction_factor`, see
    /// `settings/trot.toml`).
    pub hold_raise_fraction: f64,
    /// Slip handling runs only while the planner's reference speed (its trunk reference at the
    /// first horizon step) is below this, m/s; from it on the MPC keeps its nominal coefficient
    /// and the detector starts afresh from the nominal when the speed comes back under (0: no
    /// limit, the trot's and the free gait's default; the walk's 0.6, see
    /// [`SlipConfig::default_for`]).
    pub max_speed_mps: f64,
    /// Slow down on a floor found slippery: once the coefficient is below this, the commanded
    /// speed is capped at `slow_speed_mps` (its direction kept, the yaw rate untouched) until
    /// the coefficient is back at `slow_release_friction` or above. 0: off (the trot's and the
    /// free gait's default; the walk's, see [`SlipConfig::default_for`]).
    pub slow_below_friction: f64,
    /// The speed cap on a floor found slippery, m/s.
    pub slow_speed_mps: f64,
    /// The coefficient at which the cap lifts again (≥ `slow_below_friction`: the gap keeps the
    /// cap from flickering while the coefficient hovers at the threshold).
    pub slow_release_friction: f64,
}

/// The coefficient slip handling starts from when neither the run (`slip.initial_friction`)
/// nor the robot file (`control.slip_initial_friction`) gives one: the robot does not know the
/// floor, so it starts at a coefficient a 0.3 floor gives and lets feet that hold raise it. A
/// start at the nominal would meet a slippery floor with a pyramid wider than the floor's cone
/// until the first slides; on a grippy floor holds raise it within a few solves (see the module
/// docs).
pub const CAUTIOUS_START: f64 = 0.3;

/// The speed cap on a floor found slippery ([`SlipConfig::slow_speed_mps`]). The walk at 0.5 m/s
/// does not stay up on the slippery floors and under side pushes there; at 0.4 m/s (the paper's
/// walk is stable up to 0.4 m/s) it still lost some of those pushes, at 0.3 m/s none.
pub const SLIPPERY_SPEED_MPS: f64 = 0.3;

impl Default for SlipConfig {
    fn default() -> Self {
        SlipConfig {
            adapt_friction: true,
            speed_threshold_mps: 0.1,
            min_normal_force_n: 15.0,
            settle_s: 0.04,
            backoff: 0.7,
            min_friction: 0.15,
            recovery_per_s: 0.02,
            refractory_s: 0.0,
            raise_on_hold: true,
            initial_friction: None,
            hold_cap_after_slip: 0.95,
            hold_cap_recovery_per_s: 0.05,
            max_vertical_speed_mps: 0.0,
            require_ground_speed: false,
            hold_raise_fraction: 1.0,
            max_speed_mps: 0.0,
            slow_below_friction: 0.0,
            slow_speed_mps: SLIPPERY_SPEED_MPS,
            slow_release_friction: 0.25,
        }
    }
}

impl SlipConfig {
    /// The default for a gait: the structs' defaults with the gait's `[slip]` of
    /// `settings/<gait>.toml` over them (the walk's gates, speed limit, speed cap and floor, and
    /// why, are in that file).
    pub fn default_for(gait: crate::gait::Gait) -> Self {
        crate::gait_settings::with_gait_table(&SlipConfig::default(), &gait.to_string(), "slip")
    }

    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range(
            "slip.speed_threshold_mps",
            self.speed_threshold_mps,
            0.01,
            2.0,
        )?;
        check_range(
            "slip.min_normal_force_n",
            self.min_normal_force_n,
            0.0,
            1000.0,
        )?;
        check_range("slip.settle_s", self.settle_s, 0.0, 1.0)?;
        check_range("slip.backoff", self.backoff, 0.1, 1.0)?;
        check_range(
            "slip.min_friction",
            self.min_friction,
            crate::convex_mpc::FRICTION_RANGE[0],
            crate::convex_mpc::FRICTION_RANGE[1],
        )?;
        check_range("slip.recovery_per_s", self.recovery_per_s, 0.0, 10.0)?;
        check_range("slip.refractory_s", self.refractory_s, 0.0, 10.0)?;
        check_range(
            "slip.hold_cap_after_slip",
            self.hold_cap_after_slip,
            0.0,
            1.0,
        )?;
        check_range(
            "slip.hold_cap_recovery_per_s",
            self.hold_cap_recovery_per_s,
            0.0,
            10.0,
        )?;
        check_range(
            "slip.hold_raise_fraction",
            self.hold_raise_fraction,
            0.1,
            1.0,
        )?;
        check_range("slip.max_speed_mps", self.max_speed_mps, 0.0, 10.0)?;
        check_range(
            "slip.slow_release_friction",
            self.slow_release_friction,
            crate::convex_mpc::FRICTION_RANGE[0],
            crate::convex_mpc::FRICTION_RANGE[1],
        )?;
        // At most the release: a cap that starts above where it lifts would never lift.
        check_range(
            "slip.slow_below_friction",
            self.slow_below_friction,
            0.0,
            self.slow_release_friction,
        )?;
        // Above the coefficient's floor, or the cap could never come on (0: off).
        if self.slow_below_friction > 0.0 && self.slow_below_friction <= self.min_friction {
            return Err(ConfigError::Invalid {
                name: "slip.slow_below_friction".into(),
                message: format!(
                    "{} is at or below slip.min_friction = {}, so the coefficient never gets \
                     under it (allowed: 0, or ({}, {}])",
                    self.slow_below_friction,
                    self.min_friction,
                    self.min_friction,
                    self.slow_release_friction
                ),
            });
        }
        check_range("slip.slow_speed_mps", self.slow_speed_mps, 0.0, 10.0)?;
        check_range(
            "slip.max_vertical_speed_mps",
            self.max_vertical_speed_mps,
            0.0,
            10.0,
        )?;
        if let Some(mu) = self.initial_friction {
            check_range(
                "slip.initial_friction",
                mu,
                crate::convex_mpc::FRICTION_RANGE[0],
                crate::convex_mpc::FRICTION_RANGE[1],
            )?;
        }
        Ok(())
    }
}

/// The MPC's friction coefficient, lowered at slips.
#[derive(Clone, Debug, PartialEq)]
pub struct FrictionAdapter {
    config: SlipConfig,
    nominal: f64,
    current: f64,
    stance_since: LegMap<Option<f64>>,
    slipped_this_stance: LegMap<bool>,
    last_t: Option<f64>,
    last_backoff_s: Option<f64>,
    /// The highest coefficient a hold may raise to (none before the first slip).
    hold_cap: Option<f64>,
    slips: usize,
    /// The floor was found slippery: the speed cap is on ([`SlipConfig::slow_below_friction`]).
    slowed: bool,
}

impl FrictionAdapter {
    pub fn new(config: SlipConfig, nominal: f64) -> Result<Self, ConfigError> {
        config.validate()?;
        let start = match (config.adapt_friction, config.initial_friction) {
            (true, Some(mu)) => mu.min(nominal),
            _ => nominal,
        };
        Ok(FrictionAdapter {
            current: start,
            nominal,
            config,
            stance_since: LegMap::splat(None),
            slipped_this_stance: LegMap::splat(false),
            last_t: None,
            last_backoff_s: None,
            hold_cap: None,
            slips: 0,
            slowed: false,
        })
    }

    /// The coefficient to use now.
    pub fn friction_coefficient(&self) -> f64 {
        self.current
    }

    /// Slips seen so far.
    pub fn slips(&self) -> usize {
        self.slips
    }

    /// The speed cap on a floor found slippery, m/s, as of the last update (None: no cap).
    pub fn speed_cap_mps(&self) -> Option<f64> {
        self.slowed.then_some(self.config.slow_speed_mps)
    }

    /// Latches the cap on below `slow_below_friction` and off from `slow_release_friction`.
    fn update_speed_cap(&mut self) {
        let c = &self.config;
        if c.slow_below_friction <= 0.0 {
            self.slowed = false;
        } else if self.current < c.slow_below_friction {
            self.slowed = true;
        } else if self.current >= c.slow_release_friction.min(self.nominal) {
            // (An MPC nominal below the release would otherwise keep the cap on for good.)
            self.slowed = false;
        }
    }

    /// At or above [`SlipConfig::max_speed_mps`]: the nominal coefficient, and no slip, hold,
    /// cap or stance carried over to when the speed comes back under the limit.
    fn rest_at_nominal(&mut self, t_s: f64) {
        self.current = self.nominal;
        self.hold_cap = None;
        self.last_t = Some(t_s);
        self.last_backoff_s = None;
        self.stance_since = LegMap::splat(None);
        self.slipped_this_stance = LegMap::splat(false);
        self.slowed = false;
    }

    /// One control step at `t_s`: the planned stance, each foot's ground velocity (world, m/s),
    /// the forces the MPC asks of the feet (world, N) and the planner's reference speed (m/s).
    /// Returns the coefficient.
    pub fn update(
        &mut self,
        t_s: f64,
        stance: &LegMap<bool>,
        foot_velocity_world: &LegMap<Vector3<f64>>,
        forces_world: &LegMap<Vector3<f64>>,
        reference_speed_mps: f64,
    ) -> f64 {
        if !self.config.adapt_friction {
            return self.current;
        }
        // Below the limit, with room for rounding (a 0.6 m/s command turned by the yaw and back
        // reads 0.6 ± 1e-16, and must not flip between the two); a speed that is not finite
        // rests too.
        let limit = self.config.max_speed_mps;
        let under = reference_speed_mps.is_finite() && reference_speed_mps < limit - 1e-9;
        if limit > 0.0 && !under {
            self.rest_at_nominal(t_s);
            return self.current;
        }
        let dt = self.last_t.map(|l| (t_s - l).max(0.0)).unwrap_or(0.0);
        self.last_t = Some(t_s);
        self.current = (self.current + self.config.recovery_per_s * dt).min(self.nominal);
        if let Some(cap) = &mut self.hold_cap {
            *cap = (*cap + self.config.hold_cap_recovery_per_s * dt).min(self.nominal);
        }
        let loaded = LegMap::from_fn(|leg| {
            stance[leg] && forces_world[leg].z >= self.config.min_normal_force_n
        });
        let speed = |v: &Vector3<f64>| v.x.hypot(v.y);
        // Against the most planted loaded foot: a push moves every foot with the trunk at once
        // (nothing slides over the ground locally), and the anchor itself never counts, so of
        // two loaded feet only the one sliding does. With a single loaded foot no slide can be
        // told from the robot moving as a whole: none counts.
        let anchor = Leg::ALL
            .iter()
            .filter(|l| loaded[**l])
            .map(|l| foot_velocity_world[*l])
            .min_by(|a, b| speed(a).total_cmp(&speed(b)))
            .unwrap_or_else(Vector3::zeros);
        for leg in Leg::ALL {
            if !stance[leg] {
                self.stance_since[leg] = None;
                self.slipped_this_stance[leg] = false;
                continue;
            }
            let since = *self.stance_since[leg].get_or_insert(t_s);
            let settled = t_s - since >= self.config.settle_s && loaded[leg];
            let v = foot_velocity_world[leg] - anchor;
            let threshold = self.config.speed_threshold_mps;
            let ground_speed = speed(&foot_velocity_world[leg]);
            let vertical = self.config.max_vertical_speed_mps;
            let on_floor = vertical <= 0.0 || foot_velocity_world[leg].z.abs() <= vertical;
            let over_ground = !self.config.require_ground_speed || ground_speed > threshold;
            let sliding = settled && on_floor && over_ground && speed(&v) > threshold;
            if sliding && !self.slipped_this_stance[leg] {
                self.slipped_this_stance[leg] = true;
                self.slips += 1;
                let refractory = self
                    .last_backoff_s
                    .is_some_and(|t0| t_s - t0 < self.config.refractory_s);
                // One event (within the refractory time) sets the cap once, from the coefficient
                // it found, as it backs off once. (With the defaults the new cap is never above
                // the old; a cap that recovers slower than the coefficient keeps the lower.)
                if self.config.hold_cap_after_slip > 0.0 && !refractory {
                    let cap = self.config.hold_cap_after_slip * self.current;
                    self.hold_cap = Some(self.hold_cap.map_or(cap, |c| c.min(cap)));
                }
                if !refractory {
                    self.last_backoff_s = Some(t_s);
                    self.current = (self.config.backoff * self.current)
                        .max(self.config.min_friction)
                        .min(self.current);
                }
            }
            // A foot the vertical gate leaves out can still hold (it raises μ̂ only by what the
            // MPC asked of it, little for a foot landing or lifting off).
            let holds = settled
                && !self.slipped_this_stance[leg]
                && speed(&v) <= threshold
                && ground_speed <= threshold;
            if self.config.raise_on_hold && holds {
                let f = forces_world[leg];
                let ratio = self.config.hold_raise_fraction * f.x.hypot(f.y) / f.z;
                // The cap never exceeds the nominal (set below the coefficient, recovering to it).
                let ceiling = self.hold_cap.unwrap_or(self.nominal);
                if ratio > self.current {
                    self.current = ratio.min(ceiling).max(self.current);
                }
            }
        }
        self.update_speed_cap();
        self.current
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn still() -> LegMap<Vector3<f64>> {
        LegMap::splat(Vector3::zeros())
    }

    /// The rule without the cautious start and the cap (each test turns on what it checks).
    fn on() -> SlipConfig {
        SlipConfig {
            adapt_friction: true,
            initial_friction: None,
            hold_cap_after_slip: 0.0,
            ..Default::default()
        }
    }

    fn loaded() -> LegMap<Vector3<f64>> {
        LegMap::splat(Vector3::new(5.0, 0.0, 40.0))
    }

    #[test]
    fn planted_feet_leave_the_coefficient_alone() {
        let mut a = FrictionAdapter::new(on(), 0.6).unwrap();
        let mut v = still();
        v[Leg::FrontRight] = Vector3::new(0.09, 0.0, 0.0); // below the threshold
        v[Leg::RearLeft] = Vector3::new(0.0, 0.0, 0.3); // moving up: not a slide over the ground
        v[Leg::FrontLeft] = Vector3::new(0.5, 0.0, 0.0); // dragged, but carries nothing: no slide
        let mut forces = loaded();
        forces[Leg::FrontLeft].z = 5.0;
        for k in 0..1000 {
            assert_eq!(
                a.update(k as f64 * 1e-3, &LegMap::splat(true), &v, &forces, 0.0),
                0.6
            );
        }
        assert_eq!(a.slips(), 0);
    }

    #[test]
    fn feet_moving_together_are_pushed_not_slipping() {
        // A push moves the whole robot: every foot at the same 0.5 m/s, none over the ground
        // relative to the others.
        let mut a = FrictionAdapter::new(on(), 0.6).unwrap();
        let v = LegMap::splat(Vector3::new(0.0, 0.5, 0.0));
        for k in 0..200 {
            assert_eq!(
                a.update(k as f64 * 1e-3, &LegMap::splat(true), &v, &loaded(), 0.0),
                0.6
            );
        }
        // One of them faster than the rest by more than the threshold is a slip.
        let mut w = v;
        w[Leg::RearRight].y = 0.65;
        assert!(a.update(0.3, &LegMap::splat(true), &w, &loaded(), 0.0) < 0.6);
    }

    /// Front right slides flat over the ground while front left holds; the rear legs carry
    /// nothing: foot velocities and forces.
    fn front_right_slides_flat() -> (LegMap<Vector3<f64>>, LegMap<Vector3<f64>>) {
        let mut v = LegMap::splat(Vector3::new(5.0, 5.0, 0.0));
        v[Leg::FrontRight] = Vector3::new(0.3, 0.0, 0.05);
        v[Leg::FrontLeft] = Vector3::zeros();
        let mut forces = loaded();
        forces[Leg::RearLeft].z = 0.0;
        forces[Leg::RearRight].z = 0.0;
        (v, forces)
    }

    #[test]
    fn the_walks_gates_leave_late_touchdowns_lift_offs_and_a_moving_anchor_alone() {
        // Readings from the walk at 0.5 m/s on the 0.8 floor (filter): each slid under the
        // trot's rule, none under the walk's.
        use crate::gait::Gait;
        assert!(SlipConfig::default_for(Gait::Walk).adapt_friction);
        // The gait's rule turned on, without the cautious start and the cap.
        let turned_on = |gait| SlipConfig {
            adapt_friction: true,
            initial_friction: None,
            hold_cap_after_slip: 0.0,
            ..SlipConfig::default_for(gait)
        };
        let (walk, trot) = (turned_on(Gait::Walk), turned_on(Gait::Trot));
        let readings = [
            // (the foot, the anchor): a late touchdown, still descending at 0.85 m/s;
            (Vector3::new(0.13, -0.29, -0.85), Vector3::zeros()),
            // a rear foot lifting off at 0.45 m/s;
            (Vector3::new(0.4, 0.1, 0.45), Vector3::zeros()),
            // two feet that hold, 0.12 m/s apart from the anchor's own estimate error.
            (Vector3::new(0.07, 0.0, 0.0), Vector3::new(-0.05, 0.0, 0.0)),
        ];
        for (foot, anchor_v) in readings {
            let mut v = LegMap::splat(Vector3::new(5.0, 5.0, 0.0)); // unloaded legs
            v[Leg::FrontRight] = foot;
            v[Leg::FrontLeft] = anchor_v;
            let mut forces = loaded();
            forces[Leg::RearLeft].z = 0.0;
            forces[Leg::RearRight].z = 0.0;
            let stance = LegMap::splat(true);
            for (config, slips) in [(&walk, 0), (&trot, 1)] {
                let mut a = FrictionAdapter::new(config.clone(), 0.6).unwrap();
                a.update(0.0, &stance, &v, &forces, 0.0);
                a.update(0.05, &stance, &v, &forces, 0.0);
                assert_eq!(a.slips(), slips, "{foot:?} against {anchor_v:?}");
            }
        }
        // A foot that slides flat over the ground slips under both.
        let (v, forces) = front_right_slides_flat();
        let mut a = FrictionAdapter::new(walk, 0.6).unwrap();
        a.update(0.0, &LegMap::splat(true), &v, &forces, 0.0);
        assert!((a.update(0.05, &LegMap::splat(true), &v, &forces, 0.0) - 0.42).abs() < 1e-12);
    }

    #[test]
    fn the_walks_slip_handling_rests_at_the_nominal_above_its_speed() {
        use crate::gait::Gait;
        let walk = SlipConfig {
            initial_friction: None,
            hold_cap_after_slip: 0.0,
            ..SlipConfig::default_for(Gait::Walk)
        };
        // The walk's support check stops where its slip handling does.
        assert_eq!(
            walk.max_speed_mps,
            crate::gait::DEFAULT_WALK_SUPPORT_MAX_SPEED_MPS
        );
        assert_eq!(SlipConfig::default_for(Gait::Trot).max_speed_mps, 0.0);
        let (v, forces) = front_right_slides_flat();
        let stance = LegMap::splat(true);
        // Above 0.6 m/s the same slide is no slip: the nominal stays.
        let mut a = FrictionAdapter::new(walk.clone(), 0.6).unwrap();
        a.update(0.0, &stance, &v, &forces, 0.7);
        assert_eq!(a.update(0.05, &stance, &v, &forces, 0.7), 0.6);
        assert_eq!(a.slips(), 0);
        // At 0.5 m/s it is one (0.6 × 0.7).
        let mut b = FrictionAdapter::new(walk, 0.6).unwrap();
        b.update(0.0, &stance, &v, &forces, 0.5);
        assert!((b.update(0.05, &stance, &v, &forces, 0.5) - 0.42).abs() < 1e-12);
        // Crossing the limit brings the nominal back at once; under it again the detector
        // starts afresh: the same stance's slide counts once more after settling.
        assert_eq!(b.update(0.06, &stance, &v, &forces, 0.61), 0.6);
        assert_eq!(b.update(0.07, &stance, &v, &forces, 0.5), 0.6);
        assert!((b.update(0.12, &stance, &v, &forces, 0.5) - 0.42).abs() < 1e-12);
        assert_eq!(b.slips(), 2);
        // The limit itself rests, read with rounding either way; just under it runs; a speed
        // that is not a number rests.
        let mut c = FrictionAdapter::new(b.config.clone(), 0.6).unwrap();
        for speed in [0.6 - 1e-15, 0.6 + 1e-15] {
            c.update(0.0, &stance, &v, &forces, speed);
            assert_eq!(c.update(0.05, &stance, &v, &forces, speed), 0.6);
        }
        c.update(0.1, &stance, &v, &forces, 0.59);
        assert!((c.update(0.15, &stance, &v, &forces, 0.59) - 0.42).abs() < 1e-12);
        assert_eq!(c.update(0.16, &stance, &v, &forces, f64::NAN), 0.6);
        // The limit is validated.
        let bad = SlipConfig {
            max_speed_mps: -1.0,
            ..SlipConfig::default()
        };
        assert!(bad
            .validate()
            .unwrap_err()
            .to_string()
            .contains("slip.max_speed_mps"));
    }

    #[test]
    fn a_floor_found_slippery_caps_the_walks_speed_until_the_coefficient_recovers() {
        use crate::gait::Gait;
        let walk = SlipConfig::default_for(Gait::Walk);
        assert_eq!(walk.slow_below_friction, 0.205);
        assert_eq!(walk.slow_speed_mps, SLIPPERY_SPEED_MPS);
        assert_eq!(SlipConfig::default_for(Gait::Trot).slow_below_friction, 0.0);
        assert_eq!(SlipConfig::default_for(Gait::Free).slow_below_friction, 0.0);
        assert_eq!(walk.min_friction, 0.2);
        assert_eq!(SlipConfig::default_for(Gait::Trot).min_friction, 0.15);
        // Starting at 0.25 (above 0.205: no cap), one slip takes the coefficient to the walk's
        // floor of 0.2 (0.25 × 0.7 = 0.175): capped at 0.3 m/s.
        let cfg = SlipConfig {
            initial_friction: Some(0.25),
            hold_cap_after_slip: 0.0,
            ..walk
        };
        let (v, forces) = front_right_slides_flat();
        let stance = LegMap::splat(true);
        let mut a = FrictionAdapter::new(cfg.clone(), 0.6).unwrap();
        assert_eq!(a.update(0.0, &stance, &v, &forces, 0.5), 0.25);
        assert_eq!(a.speed_cap_mps(), None);
        assert_eq!(a.update(0.05, &stance, &v, &forces, 0.5), 0.2);
        assert_eq!(a.speed_cap_mps(), Some(0.3));
        // Nothing slides or holds from here (the feet in swing): the coefficient recovers at
        // 0.02/s. Past 0.205 the cap stays (the hysteresis); from 0.25 (2.5 s later) it lifts.
        let swing = LegMap::splat(false);
        let mu = a.update(2.05, &swing, &still(), &forces, 0.3);
        assert!((mu - 0.24).abs() < 1e-12, "{mu}");
        assert_eq!(a.speed_cap_mps(), Some(0.3));
        assert!(a.update(2.5, &swing, &still(), &forces, 0.3) < 0.25);
        assert_eq!(a.speed_cap_mps(), Some(0.3));
        assert!(a.update(2.6, &swing, &still(), &forces, 0.3) >= 0.25);
        assert_eq!(a.speed_cap_mps(), None);
        // Resting at the nominal (above the walk's 0.6 m/s) lifts the cap as well; without slip
        // handling there is none.
        let mut b = FrictionAdapter::new(cfg.clone(), 0.6).unwrap();
        b.update(0.0, &stance, &v, &forces, 0.5);
        b.update(0.05, &stance, &v, &forces, 0.5);
        assert_eq!(b.speed_cap_mps(), Some(0.3));
        b.update(0.06, &stance, &v, &forces, 0.7);
        assert_eq!(b.speed_cap_mps(), None);
        let off = SlipConfig {
            adapt_friction: false,
            ..cfg.clone()
        };
        let mut c = FrictionAdapter::new(off, 0.6).unwrap();
        c.update(0.0, &stance, &v, &forces, 0.5);
        c.update(0.05, &stance, &v, &forces, 0.5);
        assert_eq!(c.speed_cap_mps(), None);
        // A threshold above the release is refused, naming the key and the release.
        let bad = SlipConfig {
            slow_release_friction: 0.1,
            ..cfg
        };
        let err = bad.validate().unwrap_err().to_string();
        assert!(
            err.contains("slip.slow_below_friction") && err.contains("[0, 0.1]"),
            "{err}"
        );
        // So is one at or below the coefficient's floor (it could never come on).
        let never = SlipConfig {
            slow_below_friction: 0.2,
            ..SlipConfig::default_for(Gait::Walk)
        };
        let err = never.validate().unwrap_err().to_string();
        assert!(
            err.contains("slip.slow_below_friction: 0.2") && err.contains("(0.2, 0.25]"),
            "{err}"
        );
    }

    #[test]
    fn of_two_loaded_feet_only_the_sliding_one_slips() {
        // A trot's stance pair: front left planted, rear right sliding; the swing pair unloaded.
        let mut a = FrictionAdapter::new(on(), 0.6).unwrap();
        let stance = LegMap::from_fn(|l| matches!(l, Leg::FrontLeft | Leg::RearRight));
        let mut v = still();
        v[Leg::RearRight] = Vector3::new(0.3, 0.0, 0.0);
        a.update(0.0, &stance, &v, &loaded(), 0.0);
        let mu = a.update(0.05, &stance, &v, &loaded(), 0.0);
        assert_eq!(a.slips(), 1);
        assert!((mu - 0.42).abs() < 1e-12, "{mu}");
        // A single loaded foot cannot tell a slide from the robot moving: no slip.
        let mut b = FrictionAdapter::new(on(), 0.6).unwrap();
        let one = LegMap::from_fn(|l| l == Leg::RearRight);
        b.update(0.0, &one, &v, &loaded(), 0.0);
        assert_eq!(b.update(0.05, &one, &v, &loaded(), 0.0), 0.6);
    }

    #[test]
    fn a_slip_lowers_the_coefficient_by_the_backoff_and_it_recovers() {
        let refractory = SlipConfig {
            refractory_s: 0.3,
            ..on()
        };
        let mut a = FrictionAdapter::new(refractory, 0.6).unwrap();
        let stance = LegMap::splat(true);
        let mut v = still();
        a.update(0.0, &stance, &v, &loaded(), 0.0);
        // A slide right after touchdown (within settle_s) is a transient, not a slip.
        v[Leg::FrontRight] = Vector3::new(0.06, 0.07, 0.0); // below the threshold
        assert_eq!(a.update(0.02, &stance, &v, &loaded(), 0.0), 0.6);
        v[Leg::FrontRight] = Vector3::new(0.3, 0.0, 0.0);
        assert_eq!(a.update(0.03, &stance, &v, &loaded(), 0.0), 0.6);
        // Later in the stance it is: 0.7 × 0.6 = 0.42.
        let mu = a.update(0.05, &stance, &v, &loaded(), 0.0);
        assert!((mu - 0.42).abs() < 1e-12, "{mu}");
        // The same stance does not count twice.
        assert!((a.update(0.06, &stance, &v, &loaded(), 0.0) - (0.42 + 0.02 * 0.01)).abs() < 1e-12);
        assert_eq!(a.slips(), 1);
        // A second leg slipping within refractory_s of the backoff is the same event: counted,
        // the coefficient unchanged but for the recovery.
        v[Leg::RearLeft] = Vector3::new(0.0, -0.2, 0.0);
        let mu = a.update(0.07, &stance, &v, &loaded(), 0.0);
        assert!((mu - (0.42 + 0.02 * 0.02)).abs() < 1e-12, "{mu}");
        assert_eq!(a.slips(), 2);
        // A third after it is a new backoff: 0.7 × 0.427.
        v[Leg::RearRight] = Vector3::new(0.0, 0.2, 0.0);
        let mu = a.update(0.4, &stance, &v, &loaded(), 0.0);
        assert!((mu - 0.7 * (0.42 + 0.02 * 0.35)).abs() < 1e-12, "{mu}");
        // Without slips it climbs back at 0.02 per second, up to the nominal.
        let v = still();
        let mu2 = a.update(5.4, &stance, &v, &loaded(), 0.0);
        assert!((mu2 - (mu + 0.02 * 5.0)).abs() < 1e-9, "{mu2}");
        assert_eq!(a.update(100.0, &stance, &v, &loaded(), 0.0), 0.6);
    }

    #[test]
    fn a_foot_that_holds_a_steep_force_raises_the_coefficient_up_to_the_nominal() {
        let mut a = FrictionAdapter::new(on(), 0.6).unwrap();
        let stance = LegMap::splat(true);
        let mut v = still();
        a.update(0.0, &stance, &v, &loaded(), 0.0);
        v[Leg::FrontRight] = Vector3::new(0.3, 0.0, 0.0);
        let low = a.update(0.05, &stance, &v, &loaded(), 0.0);
        assert!((low - 0.42).abs() < 1e-12);
        // The next stance: every foot planted, the MPC asking one of them for 0.5 of its load
        // sideways (a push being caught), and it holds: the floor gives at least 0.5.
        a.update(0.1, &LegMap::splat(false), &still(), &loaded(), 0.0);
        a.update(0.11, &stance, &still(), &loaded(), 0.0);
        let mut f = loaded();
        f[Leg::RearLeft] = Vector3::new(12.0, 16.0, 40.0);
        let mu = a.update(0.2, &stance, &still(), &f, 0.0);
        assert!((mu - 0.5).abs() < 1e-12, "{mu}");
        // Never above the nominal; a foot moving over the ground is no evidence.
        f[Leg::RearLeft] = Vector3::new(40.0, 0.0, 40.0);
        let mut moving = still();
        moving[Leg::RearLeft] = Vector3::new(0.0, 0.15, 0.0);
        moving[Leg::FrontLeft] = Vector3::new(0.0, 0.15, 0.0);
        moving[Leg::FrontRight] = Vector3::new(0.0, 0.15, 0.0);
        moving[Leg::RearRight] = Vector3::new(0.0, 0.15, 0.0);
        assert!((a.update(0.21, &stance, &moving, &f, 0.0) - (0.5 + 0.02 * 0.01)).abs() < 1e-9);
        assert_eq!(a.update(0.22, &stance, &still(), &f, 0.0), 0.6);
    }

    #[test]
    fn a_hold_raises_the_coefficient_to_its_fraction_of_the_asked_ratio() {
        // Asked (12, 16, 40) N: ratio 20 / 40 = 0.5. With the fraction 0.8 a hold shows 0.4,
        // which raises a coefficient of 0.3 to 0.4 and leaves one of 0.45 alone.
        let mut f = loaded();
        f[Leg::RearLeft] = Vector3::new(12.0, 16.0, 40.0);
        let stance = LegMap::splat(true);
        for (start, expected) in [(0.3, 0.4), (0.45, 0.45)] {
            let config = SlipConfig {
                initial_friction: Some(start),
                hold_raise_fraction: 0.8,
                recovery_per_s: 0.0,
                ..on()
            };
            let mut a = FrictionAdapter::new(config, 0.6).unwrap();
            a.update(0.0, &stance, &still(), &f, 0.0);
            let mu = a.update(0.1, &stance, &still(), &f, 0.0);
            assert!((mu - expected).abs() < 1e-12, "{start}: {mu}");
        }
        // By default the trot and the free gait raise to 0.8 of the asked ratio, the walk (and
        // `Default`) to all of it.
        use crate::gait::Gait;
        for (gait, fraction) in [(Gait::Trot, 0.8), (Gait::Free, 0.8), (Gait::Walk, 1.0)] {
            assert_eq!(
                SlipConfig::default_for(gait).hold_raise_fraction,
                fraction,
                "{gait:?}"
            );
        }
        assert_eq!(SlipConfig::default().hold_raise_fraction, 1.0);
    }

    #[test]
    fn after_a_slip_holds_raise_the_coefficient_no_higher_than_the_cap() {
        // The ratchet this cap stops: the pyramid lets the asked force's norm reach √2·μ̂, so
        // each hold used to lift μ̂ by up to √2, above the floor that had just let a foot slide.
        let capped = SlipConfig {
            hold_cap_after_slip: 0.95,
            hold_cap_recovery_per_s: 0.05,
            ..on()
        };
        let stance = LegMap::splat(true);
        let mut a = FrictionAdapter::new(capped, 0.6).unwrap();
        a.update(0.0, &stance, &still(), &loaded(), 0.0);
        let mut v = still();
        v[Leg::FrontRight] = Vector3::new(0.3, 0.0, 0.0);
        // The slip at 0.6: the cap is 0.95 × 0.6 = 0.57, the coefficient 0.42.
        assert!((a.update(0.05, &stance, &v, &loaded(), 0.0) - 0.42).abs() < 1e-12);
        // A new stance; a foot holds while asked for the pyramid's corner, √2 × 0.42 = 0.59.
        a.update(0.06, &LegMap::splat(false), &still(), &loaded(), 0.0);
        a.update(0.07, &stance, &still(), &loaded(), 0.0);
        let mut f = loaded();
        f[Leg::RearLeft] = Vector3::new(16.8, 16.8, 40.0);
        let mu = a.update(0.2, &stance, &still(), &f, 0.0);
        let cap = 0.57 + 0.05 * 0.15;
        assert!((mu - cap).abs() < 1e-9, "{mu} against the cap {cap}");
        // The cap recovers at its own rate; a hold then reaches the asked ratio again.
        let mu = a.update(0.7, &stance, &still(), &f, 0.0);
        assert!((mu - 0.594).abs() < 1e-3, "{mu}");
        // Without the cap (0) the same hold lifts it to the ratio at once.
        let mut b = FrictionAdapter::new(on(), 0.6).unwrap();
        b.update(0.0, &stance, &still(), &loaded(), 0.0);
        b.update(0.05, &stance, &v, &loaded(), 0.0);
        b.update(0.06, &LegMap::splat(false), &still(), &loaded(), 0.0);
        b.update(0.07, &stance, &still(), &loaded(), 0.0);
        assert!((b.update(0.2, &stance, &still(), &f, 0.0) - 0.594).abs() < 1e-3);
    }

    #[test]
    fn a_second_slip_of_the_same_event_leaves_the_cap_where_the_first_set_it() {
        let config = SlipConfig {
            hold_cap_after_slip: 0.95,
            refractory_s: 0.3,
            ..on()
        };
        let mut a = FrictionAdapter::new(config, 0.6).unwrap();
        let stance = LegMap::splat(true);
        a.update(0.0, &stance, &still(), &loaded(), 0.0);
        let mut v = still();
        v[Leg::FrontRight] = Vector3::new(0.3, 0.0, 0.0);
        a.update(0.05, &stance, &v, &loaded(), 0.0); // 0.6 → 0.42, cap 0.57
        v[Leg::RearLeft] = Vector3::new(0.0, 0.3, 0.0);
        a.update(0.06, &stance, &v, &loaded(), 0.0); // the same event: neither moves
        assert_eq!(a.slips(), 2);
        // A new stance whose foot holds 0.56 of its load: raised to it, not to 0.95 × 0.42.
        a.update(0.07, &LegMap::splat(false), &still(), &loaded(), 0.0);
        a.update(0.08, &stance, &still(), &loaded(), 0.0);
        let mut f = loaded();
        f[Leg::FrontLeft] = Vector3::new(22.4, 0.0, 40.0);
        let mu = a.update(0.2, &stance, &still(), &f, 0.0);
        assert!((mu - 0.56).abs() < 1e-9, "{mu}");
    }

    #[test]
    fn a_cautious_start_is_raised_by_feet_that_hold_and_ignored_when_off() {
        let cautious = SlipConfig {
            initial_friction: Some(0.3),
            ..on()
        };
        let mut a = FrictionAdapter::new(cautious.clone(), 0.6).unwrap();
        assert_eq!(a.friction_coefficient(), 0.3);
        let stance = LegMap::splat(true);
        a.update(0.0, &stance, &still(), &loaded(), 0.0);
        // Past settle_s, a planted foot holding 0.45 of its load sideways: the floor gives that.
        let mut f = loaded();
        f[Leg::FrontLeft] = Vector3::new(18.0, 0.0, 40.0);
        let mu = a.update(0.1, &stance, &still(), &f, 0.0);
        assert!((mu - 0.45).abs() < 1e-12, "{mu}");
        // A start above the nominal is the nominal; with slip handling off it means nothing.
        let start = |c: SlipConfig| FrictionAdapter::new(c, 0.6).unwrap().friction_coefficient();
        let high = SlipConfig {
            initial_friction: Some(0.9),
            ..on()
        };
        assert_eq!(start(high), 0.6);
        let off = SlipConfig {
            adapt_friction: false,
            ..cautious
        };
        assert_eq!(start(off), 0.6);
        // Out of the MPC's friction range: refused, naming the key.
        let bad = SlipConfig {
            initial_friction: Some(f64::NAN),
            ..on()
        };
        let err = FrictionAdapter::new(bad, 0.6).err().unwrap().to_string();
        assert!(err.contains("slip.initial_friction"), "{err}");
    }

    #[test]
    fn the_coefficient_never_drops_below_its_floor_and_can_be_switched_off() {
        let mut a = FrictionAdapter::new(on(), 0.6).unwrap();
        let mut v = still();
        v[Leg::FrontRight] = Vector3::new(0.5, 0.0, 0.0);
        let mut t = 0.0;
        for _ in 0..20 {
            // Lift and put down every leg: a new stance, a new slip of the front right foot.
            a.update(t, &LegMap::splat(false), &v, &loaded(), 0.0);
            a.update(t + 0.001, &LegMap::splat(true), &v, &loaded(), 0.0);
            t += 0.1;
            a.update(t, &LegMap::splat(true), &v, &loaded(), 0.0);
        }
        assert_eq!(a.slips(), 20);
        assert!((a.friction_coefficient() - 0.15).abs() < 1e-12);
        let mut off = FrictionAdapter::new(
            SlipConfig {
                adapt_friction: false,
                ..Default::default()
            },
            0.6,
        )
        .unwrap();
        assert_eq!(
            off.update(1.0, &LegMap::splat(true), &v, &loaded(), 0.0),
            0.6
        );
        assert!(SlipConfig {
            backoff: 0.0,
            ..Default::default()
        }
        .validate()
        .unwrap_err()
        .to_string()
        .contains("slip.backoff"));
    }
}
