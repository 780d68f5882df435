//! The safety layer between every controller and the robot: it sees each joint command before
//! it is sent and the last measured state, and clamps, ramps or replaces the command.
//!
//! In order, each step: watchdog (no state for `watchdog_s` → damping), e-stop (latched until
//! [`SafetyLayer::reset`]), power protection (the SDK's PowerProtect: Σ|τ·q̇| over the limit for
//! more than 5 of the last checks → damping, latched), soft start (the motor law blended from a
//! PD hold of the pose at start to the controller's command over `soft_start_s`, so a pure
//! torque controller starts from a held pose too), joint position limits, torque limits.
//! Gains are clamped, and the total torque the motor will apply (τ + K_p(q*−q) + K_d(q̇*−q̇)
//! at the last measured state) is bounded by the torque limit; a command with a NaN gets damping.
//! Every intervention is returned to the caller for its log.

use crate::config_error::{check_range, ConfigError};
use crate::leg::{Leg, LegMap};
use crate::robot::{RobotConfig, RobotScale};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// One joint's command in the motor's own terms: τ = τ_ff + K_p (q* − q) + K_d (q̇* − q̇).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct JointCommand {
    pub q: f64,
    pub dq: f64,
    pub kp: f64,
    pub kd: f64,
    pub tau: f64,
}

/// Commands for the 12 joints.
pub type RobotCommand = LegMap<[JointCommand; 3]>;

/// What the layer reads of the robot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeasuredJoints {
    pub time_s: f64,
    pub q: LegMap<Vector3<f64>>,
    pub dq: LegMap<Vector3<f64>>,
    /// Torques the motors report, N·m.
    pub tau: LegMap<Vector3<f64>>,
}

impl MeasuredJoints {
    /// Mechanical power Σ|τ·q̇| over the 12 joints, W (what PowerProtect limits).
    pub fn power_w(&self) -> f64 {
        Leg::ALL
            .iter()
            .map(|l| self.tau[*l].component_mul(&self.dq[*l]).abs().sum())
            .sum()
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SafetyConfig {
    /// No state for this long → damping mode, s.
    pub watchdog_s: f64,
    /// Mechanical power limit Σ|τ·q̇|, W (the SDK's 1000 W × factor/10).
    pub power_limit_w: f64,
    /// Blend time from the start pose into the controller's targets, s.
    pub soft_start_s: f64,
    /// Gains of the PD hold of the start pose during the soft start, N·m/rad and N·m·s/rad
    /// (Kp 40 / Kd 1 hold the A1 standing; see the model-free baseline's gains).
    pub soft_start_kp: f64,
    pub soft_start_kd: f64,
    /// Damping of the damping mode, N·m·s/rad.
    pub damping_kd: f64,
    /// A torque cap below the robot file's per-joint motor limits, N·m; none (the default):
    /// the robot file's limits (`leg.torque_limit_nm`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub torque_limit_nm: Option<f64>,
    /// Margin kept inside the joint ranges, rad.
    pub joint_margin_rad: f64,
    /// Largest position and velocity gains sent, N·m/rad and N·m·s/rad.
    pub max_kp: f64,
    pub max_kd: f64,
}

impl Default for SafetyConfig {
    fn default() -> Self {
        SafetyConfig {
            watchdog_s: 0.02,
            // PowerProtect(…, 5), as legged_control runs the A1.
            power_limit_w: 500.0,
            soft_start_s: 2.0,
            soft_start_kp: 40.0,
            soft_start_kd: 1.0,
            damping_kd: 3.0,
            torque_limit_nm: None,
            joint_margin_rad: 0.02,
            max_kp: 200.0,
            max_kd: 10.0,
        }
    }
}

/// Units of the fields scaled to a robot's size ([`SafetyConfig::for_size`]): the defaults and
/// the validation caps were chosen for the A1. The watchdog is a rate of the link and the joint
/// margin an angle: neither is scaled.
const POWER_UNIT: &str = "W";
const KP_UNIT: &str = "N·m/rad";
const KD_UNIT: &str = "N·m·s/rad";
const TORQUE_UNIT: &str = "N·m";

impl SafetyConfig {
    /// The defaults for a robot of size `size`: the A1's (its own, exactly, at λ = μ = 1) scaled
    /// by unit at equal Froude number (power × μ√λ, stiffness × μλ, damping × μλ^1.5, the soft
    /// start's time × √λ).
    pub fn for_size(size: &RobotScale) -> Self {
        let f = |unit: &str| size.factor(unit).unwrap_or(1.0);
        let a1 = SafetyConfig::default();
        SafetyConfig {
            power_limit_w: a1.power_limit_w * f(POWER_UNIT),
            soft_start_s: a1.soft_start_s * f("s"),
            soft_start_kp: a1.soft_start_kp * f(KP_UNIT),
            soft_start_kd: a1.soft_start_kd * f(KD_UNIT),
            damping_kd: a1.damping_kd * f(KD_UNIT),
            max_kp: a1.max_kp * f(KP_UNIT),
            max_kd: a1.max_kd * f(KD_UNIT),
            ..a1
        }
    }

    /// A safety file for a robot of size `size`: the keys it sets over [`SafetyConfig::for_size`]
    /// (a key it leaves out is the robot's default, not the A1's), validated for that size.
    pub fn load_for(path: &std::path::Path, size: &RobotScale) -> Result<Self, ConfigError> {
        let file: toml::Table = crate::config_error::load_toml(path)?;
        let mut tree = toml::Table::try_from(SafetyConfig::for_size(size)).map_err(|e| {
            ConfigError::Invalid {
                name: "safety".into(),
                message: e.to_string(),
            }
        })?;
        tree.extend(file);
        let config: SafetyConfig =
            toml::Value::Table(tree)
                .try_into()
                .map_err(|e: toml::de::Error| ConfigError::Parse {
                    path: path.to_path_buf(),
                    message: e.to_string(),
                })?;
        config.validate_for(size)?;
        Ok(config)
    }

    /// Validated against the A1's caps.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.validate_for(&RobotScale::A1)
    }

    /// Validated against the caps of a robot of size `size` (the A1's scaled by unit: a B2's
    /// motors and power exceed the A1's caps many times).
    pub fn validate_for(&self, size: &RobotScale) -> Result<(), ConfigError> {
        let f = |unit: &str| size.factor(unit).unwrap_or(1.0);
        check_range("safety.watchdog_s", self.watchdog_s, 0.001, 1.0)?;
        check_range(
            "safety.power_limit_w",
            self.power_limit_w,
            1.0,
            2000.0 * f(POWER_UNIT),
        )?;
        check_range("safety.soft_start_s", self.soft_start_s, 0.0, 30.0)?;
        check_range("safety.soft_start_kp", self.soft_start_kp, 0.0, self.max_kp)?;
        check_range("safety.soft_start_kd", self.soft_start_kd, 0.0, self.max_kd)?;
        check_range("safety.damping_kd", self.damping_kd, 0.0, 20.0 * f(KD_UNIT))?;
        if let Some(t) = self.torque_limit_nm {
            check_range("safety.torque_limit_nm", t, 0.0, 200.0 * f(TORQUE_UNIT))?;
        }
        check_range("safety.joint_margin_rad", self.joint_margin_rad, 0.0, 0.3)?;
        check_range("safety.max_kp", self.max_kp, 0.0, 1000.0 * f(KP_UNIT))?;
        check_range("safety.max_kd", self.max_kd, 0.0, 100.0 * f(KD_UNIT))
    }
}

/// Something the layer did, for the log.
#[derive(Clone, Debug, PartialEq)]
pub enum Intervention {
    Watchdog {
        silent_s: f64,
    },
    EStop,
    PowerProtect {
        power_w: f64,
    },
    SoftStart {
        blend: f64,
    },
    PositionClamped {
        leg: Leg,
        joint: usize,
        asked: f64,
        sent: f64,
    },
    TorqueClamped {
        leg: Leg,
        joint: usize,
        asked: f64,
        sent: f64,
    },
    GainClamped {
        leg: Leg,
        joint: usize,
        asked: [f64; 2],
    },
    /// A command held a NaN or infinity: damping for that step.
    NonFinite,
}

/// Why the robot is latched in damping mode (until `reset`; the watchdog is not latched: it
/// lets go as soon as states arrive again).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Damping {
    EStop,
    PowerProtect,
}

pub struct SafetyLayer {
    config: SafetyConfig,
    ranges: LegMap<[[f64; 2]; 3]>,
    /// Per joint (abduction, thigh, calf), N·m: the robot's, under the config's cap.
    torque_limits_nm: [f64; 3],
    start: Option<(f64, LegMap<Vector3<f64>>)>,
    last_state: Option<MeasuredJoints>,
    power_count: u32,
    latched: Option<Damping>,
}

fn damping(kd: f64) -> RobotCommand {
    LegMap::splat(
        [JointCommand {
            kd,
            ..Default::default()
        }; 3],
    )
}

impl SafetyLayer {
    pub fn new(robot: &RobotConfig, config: SafetyConfig) -> Result<Self, ConfigError> {
        config.validate_for(&robot.scale())?;
        let l = &robot.leg;
        Ok(SafetyLayer {
            ranges: LegMap::from_fn(|leg| robot.joint_ranges_rad(leg)),
            torque_limits_nm: l
                .torque_limit_nm
                .map(|t| config.torque_limit_nm.map_or(t, |cap| cap.min(t))),
            config,
            start: None,
            last_state: None,
            power_count: 0,
            latched: None,
        })
    }

    /// The latched damping state, if any.
    pub fn damping(&self) -> Option<Damping> {
        self.latched
    }

    /// Operator's e-stop (remote button, keyboard): damping until [`SafetyLayer::reset`].
    pub fn estop(&mut self) {
        self.latched = Some(Damping::EStop);
    }

    /// Clears a latched stop; the next command soft-starts again.
    pub fn reset(&mut self) {
        self.latched = None;
        self.power_count = 0;
        self.start = None;
    }

    /// A state arrived from the robot.
    pub fn observe(&mut self, state: MeasuredJoints) {
        // PowerProtect: counts up while over the limit (to 10), down otherwise; > 5 trips.
        let p = state.power_w();
        if p.is_nan() || p > self.config.power_limit_w {
            self.power_count = (self.power_count + 1).min(10);
        } else {
            self.power_count = self.power_count.saturating_sub(1);
        }
        if self.power_count > 5 && self.latched.is_none() {
            self.latched = Some(Damping::PowerProtect);
        }
        self.last_state = Some(state);
    }

    /// The command to send at `now_s` for the controller's `cmd`, and what was changed.
    pub fn filter(&mut self, now_s: f64, cmd: &RobotCommand) -> (RobotCommand, Vec<Intervention>) {
        let mut log = Vec::new();
        let c = &self.config;
        let Some(state) = self.last_state else {
            log.push(Intervention::Watchdog {
                silent_s: f64::INFINITY,
            });
            return (damping(c.damping_kd), log);
        };
        let silent = now_s - state.time_s;
        if silent > c.watchdog_s {
            log.push(Intervention::Watchdog { silent_s: silent });
            // When states come back the robot may have sagged: soft-start again from there.
            self.start = None;
            return (damping(c.damping_kd), log);
        }
        let finite = Leg::ALL.iter().all(|l| {
            cmd[*l]
                .iter()
                .all(|j| [j.q, j.dq, j.kp, j.kd, j.tau].iter().all(|v| v.is_finite()))
        });
        if !finite {
            log.push(Intervention::NonFinite);
            return (damping(c.damping_kd), log);
        }
        match self.latched {
            Some(Damping::EStop) => {
                log.push(Intervention::EStop);
                return (damping(c.damping_kd), log);
            }
            Some(Damping::PowerProtect) => {
                log.push(Intervention::PowerProtect {
                    power_w: state.power_w(),
                });
                return (damping(c.damping_kd), log);
            }
            None => {}
        }
        let (t0, q0) = *self.start.get_or_insert((now_s, state.q));
        let blend = if c.soft_start_s > 0.0 {
            ((now_s - t0) / c.soft_start_s).clamp(0.0, 1.0)
        } else {
            1.0
        };
        if blend < 1.0 {
            log.push(Intervention::SoftStart { blend });
        }
        let mut out = *cmd;
        for leg in Leg::ALL {
            for j in 0..3 {
                let o = &mut out[leg][j];
                if blend < 1.0 {
                    // (1 − b)·hold + b·command, as one motor law: the gains blend, and the
                    // targets are the gain-weighted mean (each law is linear in q and q̇).
                    let (hkp, hkd) = (c.soft_start_kp, c.soft_start_kd);
                    let kp = (1.0 - blend) * hkp + blend * o.kp;
                    let kd = (1.0 - blend) * hkd + blend * o.kd;
                    o.q = if kp > 0.0 {
                        ((1.0 - blend) * hkp * q0[leg][j] + blend * o.kp * o.q) / kp
                    } else {
                        q0[leg][j]
                    };
                    o.dq = if kd > 0.0 {
                        blend * o.kd * o.dq / kd
                    } else {
                        0.0
                    };
                    (o.kp, o.kd) = (kp, kd);
                    o.tau *= blend;
                }
                let (kp, kd) = (o.kp.clamp(0.0, c.max_kp), o.kd.clamp(0.0, c.max_kd));
                if (kp, kd) != (o.kp, o.kd) {
                    log.push(Intervention::GainClamped {
                        leg,
                        joint: j,
                        asked: [o.kp, o.kd],
                    });
                    (o.kp, o.kd) = (kp, kd);
                }
                let lim = self.torque_limits_nm[j];
                let [lo, hi] = self.ranges[leg][j];
                let (lo, hi) = (lo + c.joint_margin_rad, hi - c.joint_margin_rad);
                if o.kp > 0.0 && !(lo..=hi).contains(&o.q) {
                    let sent = o.q.clamp(lo, hi);
                    log.push(Intervention::PositionClamped {
                        leg,
                        joint: j,
                        asked: o.q,
                        sent,
                    });
                    o.q = sent;
                }
                // The motor applies τ + Kp(q* − q) + Kd(q̇* − q̇): bound that total at the last
                // measured state, first by moving q* (the PD part alone), then τ.
                let (q, dq) = (state.q[leg][j], state.dq[leg][j]);
                let damp = o.kd * (o.dq - dq);
                let pd = o.kp * (o.q - q) + damp;
                if pd.abs() > lim && o.kp > 0.0 {
                    let target = q + (lim.copysign(pd) - damp) / o.kp;
                    log.push(Intervention::PositionClamped {
                        leg,
                        joint: j,
                        asked: o.q,
                        sent: target,
                    });
                    o.q = target;
                }
                let pd = (o.kp * (o.q - q) + o.kd * (o.dq - dq)).clamp(-lim, lim);
                let (tlo, thi) = (-lim - pd, lim - pd);
                if o.tau < tlo || o.tau > thi {
                    let sent = o.tau.clamp(tlo, thi);
                    log.push(Intervention::TorqueClamped {
                        leg,
                        joint: j,
                        asked: o.tau,
                        sent,
                    });
                    o.tau = sent;
                }
            }
        }
        (out, log)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_defaults_and_caps_follow_the_robots_size() {
        assert_eq!(
            SafetyConfig::for_size(&RobotScale::A1),
            SafetyConfig::default()
        );
        // λ = 4, μ = 8: power × 8·2, stiffness × 32, damping × 64, time × 2.
        let big = RobotScale {
            length: 4.0,
            mass: 8.0,
        };
        let c = SafetyConfig::for_size(&big);
        assert!((c.power_limit_w - 500.0 * 16.0).abs() < 1e-9);
        assert!((c.soft_start_kp - 40.0 * 32.0).abs() < 1e-9);
        assert!((c.damping_kd - 3.0 * 64.0).abs() < 1e-9);
        assert!((c.soft_start_s - 4.0).abs() < 1e-12);
        assert_eq!(c.watchdog_s, SafetyConfig::default().watchdog_s);
        c.validate_for(&big).unwrap();
        // The A1's caps refuse it, naming the key.
        let err = c.validate().unwrap_err().to_string();
        assert!(err.contains("safety.power_limit_w"), "{err}");
    }

    #[test]
    fn a_safety_file_sets_only_its_keys_over_the_robots_defaults() {
        let big = RobotScale {
            length: 4.0,
            mass: 8.0,
        };
        let dir = std::env::temp_dir().join(format!("eemp-safety-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("safety.toml");
        std::fs::write(&path, "watchdog_s = 0.05\n").unwrap();
        let c = SafetyConfig::load_for(&path, &big).unwrap();
        assert_eq!(c.watchdog_s, 0.05);
        assert_eq!(c.power_limit_w, SafetyConfig::for_size(&big).power_limit_w);
        std::fs::write(&path, "watchdog_ms = 5\n").unwrap();
        let err = SafetyConfig::load_for(&path, &big).unwrap_err().to_string();
        assert!(err.contains("watchdog_ms"), "{err}");
        std::fs::remove_dir_all(&dir).ok();
    }

    fn state(t: f64, q: f64, dq: f64, tau: f64) -> MeasuredJoints {
        MeasuredJoints {
            time_s: t,
            q: LegMap::splat(Vector3::new(0.0, q, -1.8)),
            dq: LegMap::splat(Vector3::repeat(dq)),
            tau: LegMap::splat(Vector3::repeat(tau)),
        }
    }

    fn stand(q: f64, tau: f64) -> RobotCommand {
        LegMap::splat([0.0, q, -1.8].map(|q| JointCommand {
            q,
            kp: 40.0,
            kd: 1.0,
            tau,
            ..Default::default()
        }))
    }

    #[test]
    fn no_state_or_a_silent_robot_gets_damping() {
        let mut s = SafetyLayer::new(&RobotConfig::a1(), SafetyConfig::default()).unwrap();
        let (out, log) = s.filter(0.0, &stand(0.9, 0.0));
        assert_eq!(out, damping(3.0));
        assert!(matches!(log[0], Intervention::Watchdog { .. }));
        s.observe(state(0.0, 0.9, 0.0, 0.0));
        assert_ne!(s.filter(0.01, &stand(0.9, 0.0)).0, damping(3.0));
        let (out, log) = s.filter(0.05, &stand(0.9, 0.0));
        assert_eq!(out, damping(3.0));
        assert!(
            matches!(log[0], Intervention::Watchdog { silent_s } if (silent_s - 0.05).abs() < 1e-12)
        );
    }

    #[test]
    fn soft_start_blends_from_the_start_pose_and_limits_clamp() {
        let mut s = SafetyLayer::new(&RobotConfig::a1(), SafetyConfig::default()).unwrap();
        s.observe(state(0.0, 1.5, 0.0, 0.0));
        let (out, _) = s.filter(0.0, &stand(0.9, 10.0));
        assert!((out[Leg::FrontLeft][1].q - 1.5).abs() < 1e-12);
        assert_eq!(out[Leg::FrontLeft][1].tau, 0.0);
        s.observe(state(1.0, 1.2, 0.0, 0.0));
        let (out, log) = s.filter(1.0, &stand(0.9, 10.0));
        assert!(
            (out[Leg::FrontLeft][1].q - 1.2).abs() < 1e-12,
            "half way from 1.5 to 0.9"
        );
        assert!(log.iter().any(
            |i| matches!(i, Intervention::SoftStart { blend } if (*blend - 0.5).abs() < 1e-12)
        ));
        s.observe(state(3.0, 0.9, 0.0, 0.0));
        // Beyond the joint range and far from the measured 0.9 rad: the target is clamped into
        // the range, then pulled in until the PD alone gives 33.5 N·m, and the feed-forward
        // torque is cut to keep the total within the limit.
        let (out, log) = s.filter(3.0, &stand(5.0, 50.0));
        assert!((out[Leg::RearRight][1].q - (0.9 + 33.5 / 40.0)).abs() < 1e-9);
        assert_eq!(out[Leg::RearRight][1].tau, 0.0);
        assert!(log
            .iter()
            .any(|i| matches!(i, Intervention::PositionClamped { joint: 1, .. })));
        assert!(log
            .iter()
            .any(|i| matches!(i, Intervention::TorqueClamped { .. })));
        // Near the target a large feed-forward torque is cut to the limit.
        let (out, _) = s.filter(3.0, &stand(0.9, 50.0));
        assert!((out[Leg::FrontLeft][1].tau - 33.5).abs() < 1e-9);
        // A NaN anywhere: damping.
        let (out, log) = s.filter(3.0, &stand(0.9, f64::NAN));
        assert_eq!(out, damping(3.0));
        assert_eq!(log, vec![Intervention::NonFinite]);
        let mut cmd = stand(0.9, 0.0);
        cmd[Leg::RearLeft][2].kp = 5000.0;
        let (out, log) = s.filter(3.0, &cmd);
        assert_eq!(out[Leg::RearLeft][2].kp, 200.0);
        assert!(log
            .iter()
            .any(|i| matches!(i, Intervention::GainClamped { .. })));
    }

    #[test]
    fn a_torque_controller_soft_starts_from_a_held_pose() {
        let mut s = SafetyLayer::new(&RobotConfig::a1(), SafetyConfig::default()).unwrap();
        s.observe(state(0.0, 1.0, 0.0, 0.0));
        let torque_only = LegMap::splat(
            [JointCommand {
                tau: 6.0,
                ..Default::default()
            }; 3],
        );
        // At the start: the hold alone (Kp 40 at the start pose), no torque.
        let (out, _) = s.filter(0.0, &torque_only);
        let j = out[Leg::FrontLeft][1];
        assert_eq!((j.kp, j.kd, j.tau), (40.0, 1.0, 0.0));
        assert!((j.q - 1.0).abs() < 1e-12);
        // Half way: τ = 0.5·6 + 0.5·40·(1.0 − q) − 0.5·q̇ at any q, q̇.
        s.observe(state(1.0, 1.0, 0.0, 0.0));
        let (out, _) = s.filter(1.0, &torque_only);
        let j = out[Leg::FrontLeft][1];
        let law = |q: f64, dq: f64| j.tau + j.kp * (j.q - q) + j.kd * (j.dq - dq);
        for (q, dq) in [(1.0, 0.0), (0.9, 0.3), (1.1, -1.0)] {
            let want = 0.5 * 6.0 + 0.5 * 40.0 * (1.0 - q) - 0.5 * 1.0 * dq;
            assert!((law(q, dq) - want).abs() < 1e-9, "{q} {dq}");
        }
        // After the ramp the command passes unchanged.
        s.observe(state(2.5, 1.0, 0.0, 0.0));
        let (out, log) = s.filter(2.5, &torque_only);
        assert_eq!(out, torque_only);
        assert!(log.is_empty());
    }

    #[test]
    fn sustained_overpower_and_the_estop_latch_damping_until_reset() {
        let mut s = SafetyLayer::new(&RobotConfig::a1(), SafetyConfig::default()).unwrap();
        // 12 joints × 10 N·m × 5 rad/s = 600 W > 500 W: trips after 6 checks.
        for k in 0..5 {
            s.observe(state(k as f64 * 0.002, 0.9, 5.0, 10.0));
        }
        assert_eq!(s.damping(), None);
        s.observe(state(0.01, 0.9, 5.0, 10.0));
        assert_eq!(s.damping(), Some(Damping::PowerProtect));
        assert_eq!(s.filter(0.01, &stand(0.9, 0.0)).0, damping(3.0));
        s.reset();
        s.observe(state(0.012, 0.9, 0.0, 0.0));
        assert_ne!(s.filter(0.012, &stand(0.9, 0.0)).0, damping(3.0));
        s.estop();
        s.observe(state(0.014, 0.9, 0.0, 0.0));
        let (out, log) = s.filter(0.014, &stand(0.9, 0.0));
        assert_eq!(out, damping(3.0));
        assert_eq!(log, vec![Intervention::EStop]);
    }
}
