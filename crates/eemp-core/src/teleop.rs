//! Operator commands: gamepad sticks or keys → a velocity command with a deadzone, limits and
//! a slew-rate limit, so that a jerk of the stick does not become a jerk of the trunk. The
//! same shaping runs in simulation and on the robot; device reading lives with the binary,
//! except the Linux joystick event format, which is parsed here so tests can script it.

use crate::config_error::{check_range, ConfigError};
use crate::planner::VelocityCommand;
use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TeleopConfig {
    /// Stick deflection below this fraction is zero; above it the range is rescaled to 0..1.
    pub deadzone: f64,
    /// Commands at full deflection, m/s and rad/s.
    pub max_vx_mps: f64,
    pub max_vy_mps: f64,
    pub max_yaw_rate_rps: f64,
    /// Largest rate of change of each command, m/s², m/s² and rad/s².
    pub slew_vx_mps2: f64,
    pub slew_vy_mps2: f64,
    pub slew_yaw_rps2: f64,
}

impl Default for TeleopConfig {
    fn default() -> Self {
        TeleopConfig {
            deadzone: 0.1,
            max_vx_mps: 1.0,
            max_vy_mps: 0.3,
            max_yaw_rate_rps: 1.0,
            slew_vx_mps2: 1.0,
            slew_vy_mps2: 1.0,
            slew_yaw_rps2: 2.0,
        }
    }
}

impl TeleopConfig {
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range("teleop.deadzone", self.deadzone, 0.0, 0.9)?;
        check_range("teleop.max_vx_mps", self.max_vx_mps, 0.0, 1.5)?;
        check_range("teleop.max_vy_mps", self.max_vy_mps, 0.0, 0.5)?;
        check_range("teleop.max_yaw_rate_rps", self.max_yaw_rate_rps, 0.0, 1.5)?;
        check_range("teleop.slew_vx_mps2", self.slew_vx_mps2, 0.01, 100.0)?;
        check_range("teleop.slew_vy_mps2", self.slew_vy_mps2, 0.01, 100.0)?;
        check_range("teleop.slew_yaw_rps2", self.slew_yaw_rps2, 0.01, 100.0)
    }
}

/// Stick deflections in [−1, 1]: left stick forward/left → vx/vy, right stick left → yaw rate
/// (positive = counter-clockwise, as the command).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sticks {
    pub forward: f64,
    pub left: f64,
    pub turn_left: f64,
}

/// Deadzone and rescale of one axis.
pub fn deadzone(x: f64, dz: f64) -> f64 {
    let x = if x.is_finite() {
        x.clamp(-1.0, 1.0)
    } else {
        0.0
    };
    if x.abs() <= dz {
        0.0
    } else {
        x.signum() * (x.abs() - dz) / (1.0 - dz)
    }
}

impl Sticks {
    /// The command these deflections ask for (before slew limiting).
    pub fn desired(&self, c: &TeleopConfig) -> VelocityCommand {
        VelocityCommand {
            vx_mps: deadzone(self.forward, c.deadzone) * c.max_vx_mps,
            vy_mps: deadzone(self.left, c.deadzone) * c.max_vy_mps,
            yaw_rate_rps: deadzone(self.turn_left, c.deadzone) * c.max_yaw_rate_rps,
        }
    }
}

/// Where an operator's wish comes from (a gamepad, the keyboard, a script, a test): the
/// command wished at time `t_s`, and whether the operator asked to stop.
pub trait OperatorInput {
    fn wish(&mut self, t_s: f64) -> (VelocityCommand, bool);
}

/// A gamepad through its events (tests feed them; the binary reads a joystick device).
#[derive(Clone, Debug, Default)]
pub struct Gamepad {
    pub state: PadState,
    pub mapping: PadMapping,
    pub config: TeleopConfig,
}

impl Gamepad {
    pub fn event(&mut self, e: &JsEvent) {
        self.state.apply(e, &self.mapping);
    }
}

impl OperatorInput for Gamepad {
    fn wish(&mut self, _t_s: f64) -> (VelocityCommand, bool) {
        (self.state.sticks.desired(&self.config), self.state.stop)
    }
}

/// Moves the command toward the operator's wish within the slew limits.
#[derive(Clone, Debug, PartialEq)]
pub struct CommandShaper {
    config: TeleopConfig,
    current: VelocityCommand,
}

impl CommandShaper {
    pub fn new(config: TeleopConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(CommandShaper {
            config,
            current: VelocityCommand::default(),
        })
    }

    pub fn config(&self) -> &TeleopConfig {
        &self.config
    }

    /// One step of `dt_s` toward `desired` (clamped to the limits first).
    pub fn step(&mut self, desired: VelocityCommand, dt_s: f64) -> VelocityCommand {
        let c = &self.config;
        let toward = |cur: f64, want: f64, max: f64, slew: f64| {
            let want = if want.is_finite() {
                want.clamp(-max, max)
            } else {
                0.0
            };
            cur + (want - cur).clamp(-slew * dt_s, slew * dt_s)
        };
        self.current = VelocityCommand {
            vx_mps: toward(
                self.current.vx_mps,
                desired.vx_mps,
                c.max_vx_mps,
                c.slew_vx_mps2,
            ),
            vy_mps: toward(
                self.current.vy_mps,
                desired.vy_mps,
                c.max_vy_mps,
                c.slew_vy_mps2,
            ),
            yaw_rate_rps: toward(
                self.current.yaw_rate_rps,
                desired.yaw_rate_rps,
                c.max_yaw_rate_rps,
                c.slew_yaw_rps2,
            ),
        };
        self.current
    }
}

/// One event of the Linux joystick interface (`/dev/input/jsN`, `struct js_event`: u32 time
/// in ms, i16 value, u8 type, u8 number; little endian).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct JsEvent {
    pub time_ms: u32,
    pub value: i16,
    /// 1 button, 2 axis; 0x80 flags the initial state sent on open.
    pub kind: u8,
    pub number: u8,
}

impl JsEvent {
    pub fn parse(b: &[u8; 8]) -> Self {
        JsEvent {
            time_ms: u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            value: i16::from_le_bytes([b[4], b[5]]),
            kind: b[6],
            number: b[7],
        }
    }
}

/// Axis and button numbers of a gamepad (the defaults are an Xbox-style pad on Linux's
/// joystick driver: left stick axes 0/1, right stick x axis 3; button 1 = B stops).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PadMapping {
    pub left_x: u8,
    pub left_y: u8,
    pub right_x: u8,
    /// The e-stop / quit button.
    pub stop_button: u8,
}

impl Default for PadMapping {
    fn default() -> Self {
        PadMapping {
            left_x: 0,
            left_y: 1,
            right_x: 3,
            stop_button: 1,
        }
    }
}

/// The pad's state, built from its events.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PadState {
    pub sticks: Sticks,
    pub stop: bool,
}

impl PadState {
    /// Axes read +32767 down and right; the command wants forward and left positive.
    pub fn apply(&mut self, e: &JsEvent, m: &PadMapping) {
        let v = e.value as f64 / 32767.0;
        match e.kind & !0x80 {
            2 if e.number == m.left_y => self.sticks.forward = -v,
            2 if e.number == m.left_x => self.sticks.left = -v,
            2 if e.number == m.right_x => self.sticks.turn_left = -v,
            1 if e.number == m.stop_button && e.value != 0 => self.stop = true,
            _ => {}
        }
    }
}

/// Keys → a wished command, in steps (w/s forward, a/d sideways, q/e turn, space: zero).
pub fn key_step(desired: &mut VelocityCommand, key: char) {
    match key {
        'w' => desired.vx_mps += 0.1,
        's' => desired.vx_mps -= 0.1,
        'a' => desired.vy_mps += 0.05,
        'd' => desired.vy_mps -= 0.05,
        'q' => desired.yaw_rate_rps += 0.2,
        'e' => desired.yaw_rate_rps -= 0.2,
        ' ' => *desired = VelocityCommand::default(),
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deadzone_rescales_and_the_shaper_limits_the_slew() {
        assert_eq!(deadzone(0.05, 0.1), 0.0);
        assert!((deadzone(0.55, 0.1) - 0.5).abs() < 1e-12);
        assert_eq!(deadzone(-1.0, 0.1), -1.0);
        assert_eq!(deadzone(f64::NAN, 0.1), 0.0);
        let c = TeleopConfig::default();
        let full = Sticks {
            forward: 1.0,
            left: -1.0,
            turn_left: 0.5,
        };
        let d = full.desired(&c);
        assert_eq!((d.vx_mps, d.vy_mps), (1.0, -0.3));
        assert!((d.yaw_rate_rps - 0.4 / 0.9).abs() < 1e-12);
        let mut s = CommandShaper::new(c).unwrap();
        // 1 m/s² from rest: 0.5 m/s after 0.5 s of 1 ms steps, never more.
        let mut out = VelocityCommand::default();
        for _ in 0..500 {
            out = s.step(d, 0.001);
        }
        assert!((out.vx_mps - 0.5).abs() < 1e-9);
        assert!((out.vy_mps + 0.3).abs() < 1e-9, "vy saturates at its wish");
        // A wish beyond the limits is clamped; NaN is read as zero.
        let wild = VelocityCommand {
            vx_mps: 9.0,
            vy_mps: f64::NAN,
            yaw_rate_rps: -9.0,
        };
        for _ in 0..5000 {
            out = s.step(wild, 0.001);
        }
        assert_eq!((out.vx_mps, out.vy_mps, out.yaw_rate_rps), (1.0, 0.0, -1.0));
    }

    #[test]
    fn joystick_events_move_the_sticks_and_the_stop_button_latches() {
        let m = PadMapping::default();
        let mut p = PadState::default();
        let ev = |value: i16, kind: u8, number: u8| {
            let mut b = [0u8; 8];
            b[0..4].copy_from_slice(&1234u32.to_le_bytes());
            b[4..6].copy_from_slice(&value.to_le_bytes());
            b[6] = kind;
            b[7] = number;
            JsEvent::parse(&b)
        };
        let e = ev(-32767, 2, 1);
        assert_eq!((e.time_ms, e.value, e.kind, e.number), (1234, -32767, 2, 1));
        p.apply(&e, &m); // left stick pushed up: forward
        p.apply(&ev(16384, 2 | 0x80, 3), &m); // right stick right (initial state): turn right
        assert!((p.sticks.forward - 1.0).abs() < 1e-12);
        assert!((p.sticks.turn_left + 0.5).abs() < 1e-4);
        assert!(!p.stop);
        p.apply(&ev(1, 1, 1), &m);
        assert!(p.stop);
    }

    #[test]
    fn a_scripted_gamepad_drives_the_shaper() {
        let mut pad = Gamepad::default();
        let mut shaper = CommandShaper::new(TeleopConfig::default()).unwrap();
        let push = |value: i16, number: u8| {
            let mut b = [0u8; 8];
            b[4..6].copy_from_slice(&value.to_le_bytes());
            b[6] = 2;
            b[7] = number;
            JsEvent::parse(&b)
        };
        pad.event(&push(-32767, 1)); // full forward
        let input: &mut dyn OperatorInput = &mut pad;
        let mut cmd = VelocityCommand::default();
        for k in 0..2000 {
            let (wish, stop) = input.wish(k as f64 * 0.001);
            assert!(!stop);
            cmd = shaper.step(wish, 0.001);
        }
        assert!(
            (cmd.vx_mps - 1.0).abs() < 1e-9,
            "reached full speed after 2 s at 1 m/s²"
        );
    }

    #[test]
    fn keys_step_the_wish_and_space_stops() {
        let mut d = VelocityCommand::default();
        for k in ['w', 'w', 'a', 'q', 'x'] {
            key_step(&mut d, k);
        }
        assert!((d.vx_mps - 0.2).abs() < 1e-12 && (d.vy_mps - 0.05).abs() < 1e-12);
        assert!((d.yaw_rate_rps - 0.2).abs() < 1e-12);
        key_step(&mut d, ' ');
        assert_eq!(d, VelocityCommand::default());
    }
}
