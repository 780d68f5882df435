//! The robot description ([`RobotConfig`], loaded from `robots/<name>.toml`) and what is derived
//! from it: link inertias per leg and the composite rigid body the MPC uses.

use crate::config_error::{check_positive, check_range, ConfigError};
use crate::leg::{Leg, LegMap};
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

/// The project's A1 description, compiled in so tests and tools need no working directory.
pub const A1_TOML: &str = include_str!("../../../robots/a1.toml");

/// Friction coefficients a floor, a robot file or a controller may name (the MPC's pyramid,
/// the slip detector's floor and start).
pub const FRICTION_RANGE: [f64; 2] = [0.05, 2.0];

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RobotConfig {
    pub name: String,
    pub simulation: SimulationConfig,
    pub trunk: TrunkConfig,
    pub leg: LegConfig,
    /// How the robot's own SDK numbers its motors (the hardware codecs read this).
    #[serde(default)]
    pub sdk: SdkConfig,
    /// The controller's defaults that are this robot's tuning (not physics: outside the
    /// robot's id hash, so tables and policies keep their stamp).
    #[serde(default, skip_serializing_if = "ControlDefaults::is_empty")]
    pub control: ControlDefaults,
    /// The drives' electrical model (`[motor]`, [`crate::energy`]); without it every electrical
    /// figure is reported as absent, never from invented constants. Outside the robot's id hash:
    /// it changes what a run is charged, not how it moves.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motor: Option<crate::energy::MotorConfig>,
    /// Where the robot was read from its own MuJoCo model (a binding file, loaded by
    /// `eemp_sim::robot_model`): the legs' geometry and links as MuJoCo compiled them. `None`
    /// for a robot typed into its file (`[trunk]`, `[leg]`), whose model is generated.
    #[serde(skip)]
    pub model: Option<std::sync::Arc<ModelDescription>>,
}

/// What the controllers read from a robot's own MuJoCo model (filled by
/// `eemp_sim::robot_model`, which compiles it; this crate never reads MJCF).
#[derive(Clone, Debug, PartialEq)]
pub struct ModelDescription {
    /// The model file the binding names (the simulation compiles it with [`Self::edits`]).
    pub source: std::path::PathBuf,
    /// What the binding changes in the model for torque control.
    pub edits: ModelEdits,
    /// Each leg's geometry at zero joint angles.
    pub legs: LegMap<crate::leg_geometry::LegGeometry>,
    /// Each leg's links (abduction, thigh, calf: every body that moves with that joint), in the
    /// link frames of `kinematics::LegKinematics::link_frames`.
    pub links: LegMap<[LinkInertial; 3]>,
    /// Each leg's joint ranges (abduction, thigh, calf), rad.
    pub joint_range_rad: LegMap<[[f64; 2]; 3]>,
    /// Each leg's standing joint angles, rad.
    pub standing_pose_rad: LegMap<Vector3<f64>>,
    /// The trunk as compiled: a run's trunk-mass error or payload ([`RobotConfig::trunk`]
    /// changed) is applied to the compiled model against it.
    pub compiled_trunk: TrunkConfig,
    /// Hash of the edited model's arrays the dynamics depend on (the robot's id).
    pub digest: String,
}

/// What a binding changes in its model (`[model]` of a robot file): every leg joint's passive
/// terms (abduction, thigh, calf; `None`: the model's own) and, where the model has none, the
/// torque limits.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelEdits {
    pub damping_n_m_s_per_rad: [f64; 3],
    pub armature_kg_m2: Option<[f64; 3]>,
    pub frictionloss_nm: Option<[f64; 3]>,
    pub torque_limit_nm: Option<[f64; 3]>,
}

/// Mass, COM and inertia (about the COM) of a rigid part, in a named link frame.
#[derive(Clone, Debug, PartialEq)]
pub struct LinkInertial {
    pub mass_kg: f64,
    pub com_m: Vector3<f64>,
    pub inertia_kg_m2: Matrix3<f64>,
}

/// `[control]` in a robot file: controller settings measured for this robot, each overridden by
/// the run's own option.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ControlDefaults {
    /// The coefficient the slip detector starts from (`slip.initial_friction`) when a run does
    /// not give one: a cautious start for a robot whose first stances on a low floor throw it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub slip_initial_friction: Option<f64>,
    /// The MPC's weight on the motors' heat (`mpc.weight_heat`, 1/W) when a run does not give
    /// one: the battery-aware cost for a robot whose `[motor]` model it was tuned with.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mpc_weight_heat: Option<f64>,
    /// The MPC's bound on a foot's normal force (`mpc.f_max_n`), N, when a run does not give
    /// one; without it, the vertical force a leg holds at the standing pose within its torque
    /// limits ([`RobotConfig::mpc_f_max_n`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mpc_f_max_n: Option<f64>,
    /// Whether the controller's settings and Table II, tuned on the A1, are scaled to this
    /// robot ([`RobotScale`]). Default: yes for a robot read from its own model, no for a robot
    /// typed into its file (the A1, Go1 and Go2 keep what their tables were swept with).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scale_settings: Option<bool>,
}

impl ControlDefaults {
    pub fn is_empty(&self) -> bool {
        *self == ControlDefaults::default()
    }
}

/// The robot SDK's motor numbering: motors 3k, 3k+1, 3k+2 are (abduction, thigh, calf) of
/// `leg_order[k]`. Unitree's A1, Go1 and Go2 SDKs all use FR, FL, RR, RL (the default);
/// Menagerie's Go2 MJCF lists its bodies FL, FR, RL, RR, which is why the file says it apart
/// from the (generated) model's body order.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SdkConfig {
    /// Leg short names ("FR", "FL", "RR", "RL"), a permutation.
    #[serde(default = "unitree_leg_order")]
    pub leg_order: [String; 4],
    /// The low-level interface the robot speaks.
    #[serde(default)]
    pub protocol: LowLevelProtocol,
}

fn unitree_leg_order() -> [String; 4] {
    ["FR", "FL", "RR", "RL"].map(String::from)
}

impl Default for SdkConfig {
    fn default() -> Self {
        SdkConfig {
            leg_order: unitree_leg_order(),
            protocol: LowLevelProtocol::default(),
        }
    }
}

/// A robot's low-level interface (what `eemp hw` and `eemp sim-robot` must speak).
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum LowLevelProtocol {
    /// The A1's UDP datagrams (unitree_legged_sdk 3.3), the project's `a1_protocol`.
    #[default]
    A1Udp,
    /// unitree_sdk2's DDS topics rt/lowcmd / rt/lowstate (the Go2): `eemp_hw::wire::go2_idl`, `eemp_hw::dds`.
    Go2Dds,
    /// No codec the project can check against the real robot (the Go1's UDP wire format is
    /// known only from third-party reverse engineering): simulation only.
    None,
}

impl LowLevelProtocol {
    pub fn name(self) -> &'static str {
        match self {
            LowLevelProtocol::A1Udp => "a1-udp",
            LowLevelProtocol::Go2Dds => "go2-dds",
            LowLevelProtocol::None => "none",
        }
    }
}

/// Which robot an artifact (a table, a policy, a suite) was made for: the robot file's name and
/// a hash of its physical numbers (trunk and legs: masses, inertias, geometry, ranges, limits),
/// so an edited or another robot is told apart even under the same name.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct RobotId {
    pub name: String,
    /// FNV-1a (64 bit) of the canonical TOML of `[trunk]` and `[leg]`, 16 hex digits.
    pub physics_hash: String,
}

impl RobotId {
    /// What an artifact without a robot stamp was made for: the A1 (every artifact made
    /// before stamps existed), matched by name only.
    pub fn unstamped() -> Self {
        RobotId {
            name: "a1".into(),
            physics_hash: String::new(),
        }
    }

    /// Refuses `robot` for an artifact (`what`, e.g. the table's path) made for `self`,
    /// naming both; an unstamped artifact's empty hash matches any hash of the same name.
    pub fn check(&self, robot: &RobotConfig, what: &str) -> Result<(), String> {
        let ours = robot.id();
        let same_hash = self.physics_hash.is_empty() || self.physics_hash == ours.physics_hash;
        if self.name == ours.name && same_hash {
            return Ok(());
        }
        Err(format!(
            "{what} was made for robot '{}' (physics {}), not for '{}' (physics {}); use the \
             artifact of this robot, or --allow-robot-mismatch for an experiment",
            self.name,
            if self.physics_hash.is_empty() {
                "unstamped"
            } else {
                &self.physics_hash
            },
            ours.name,
            ours.physics_hash
        ))
    }
}

/// FNV-1a, 64 bit: a stable hash of a canonical text (never of process, platform or map order).
pub fn fnv1a64(text: &str) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in text.bytes() {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// A validated [`SdkConfig`]: the motor index of each joint.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotorOrder {
    slot: LegMap<usize>,
}

impl MotorOrder {
    pub fn new(sdk: &SdkConfig) -> Result<Self, ConfigError> {
        let mut slot = LegMap::splat(usize::MAX);
        for (k, name) in sdk.leg_order.iter().enumerate() {
            let leg = Leg::ALL
                .into_iter()
                .find(|l| l.short_name() == name)
                .ok_or_else(|| ConfigError::Invalid {
                    name: format!("sdk.leg_order[{k}]"),
                    message: format!("{name:?} is not a leg (FR, FL, RR or RL)"),
                })?;
            if slot[leg] != usize::MAX {
                return Err(ConfigError::Invalid {
                    name: "sdk.leg_order".into(),
                    message: format!(
                        "{:?} is not a permutation of FR, FL, RR, RL ({name} twice)",
                        sdk.leg_order
                    ),
                });
            }
            slot[leg] = k;
        }
        Ok(MotorOrder { slot })
    }

    /// The order of Unitree's SDKs (FR, FL, RR, RL).
    pub fn unitree() -> Self {
        Self::new(&SdkConfig::default()).expect("the default order is a permutation")
    }

    /// Motor index of `joint` (0 abduction, 1 thigh, 2 calf) of `leg`.
    pub fn index(&self, leg: Leg, joint: usize) -> usize {
        3 * self.slot[leg] + joint
    }

    /// The leg at motor-triplet `k` (its position in `leg_order`).
    pub fn slot(&self, leg: Leg) -> usize {
        self.slot[leg]
    }
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SimulationConfig {
    /// Physics time step, s.
    pub timestep_s: f64,
    /// Sliding friction coefficient of the floor.
    pub floor_friction: f64,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TrunkConfig {
    pub mass_kg: f64,
    /// Centre of mass in the trunk frame, m.
    pub com_m: [f64; 3],
    /// ixx iyy izz ixy ixz iyz about the COM, kg·m².
    pub inertia_kg_m2: [f64; 6],
    pub collision_half_size_m: [f64; 3],
}

/// Mass properties of one link, expressed for the front-left leg in the link's joint frame.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LinkConfig {
    pub mass_kg: f64,
    pub com_m: [f64; 3],
    /// ixx iyy izz ixy ixz iyz about the COM, kg·m².
    pub inertia_kg_m2: [f64; 6],
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LegConfig {
    pub hip_offset_m: [f64; 2],
    pub abduction_to_thigh_m: f64,
    pub thigh_length_m: f64,
    pub calf_length_m: f64,
    pub foot_radius_m: f64,
    pub abduction_range_rad: [f64; 2],
    /// The thigh range of the front legs (and of the rear ones unless `rear_thigh_range_rad`).
    pub thigh_range_rad: [f64; 2],
    /// The rear legs' thigh range where it differs from the front's (the Go2).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rear_thigh_range_rad: Option<[f64; 2]>,
    pub calf_range_rad: [f64; 2],
    /// Motor torque limits (abduction, thigh, calf), N·m; one number means all three.
    #[serde(deserialize_with = "per_joint")]
    pub torque_limit_nm: [f64; 3],
    pub damping: [f64; 3],
    pub armature_kg_m2: [f64; 3],
    pub frictionloss_nm: [f64; 3],
    pub standing_pose_rad: [f64; 3],
    pub hip_link: LinkConfig,
    pub thigh_link: LinkConfig,
    pub calf_link: LinkConfig,
}

/// A per-joint value written either as one number (every joint) or as [abduction, thigh, calf].
fn per_joint<'de, D: serde::Deserializer<'de>>(d: D) -> Result<[f64; 3], D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum PerJoint {
        All(f64),
        Each([f64; 3]),
    }
    Ok(match PerJoint::deserialize(d)? {
        PerJoint::All(v) => [v; 3],
        PerJoint::Each(v) => v,
    })
}

/// Which link of a leg.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinkKind {
    Hip,
    Thigh,
    Calf,
}

impl LinkConfig {
    /// This link's (com, inertia) for `leg`, mirrored from the front-left description.
    /// Mirroring y flips ixy and iyz; mirroring x (rear hips only) flips ixy and ixz.
    pub fn mirrored(&self, leg: Leg, kind: LinkKind) -> (Vector3<f64>, [f64; 6]) {
        let mut com = Vector3::from(self.com_m);
        let mut inertia = self.inertia_kg_m2;
        if leg.side_sign() < 0.0 {
            com.y = -com.y;
            inertia[3] = -inertia[3];
            inertia[5] = -inertia[5];
        }
        if kind == LinkKind::Hip && leg.front_sign() < 0.0 {
            com.x = -com.x;
            inertia[3] = -inertia[3];
            inertia[4] = -inertia[4];
        }
        (com, inertia)
    }
}

pub(crate) fn inertia_matrix(i: &[f64; 6]) -> Matrix3<f64> {
    Matrix3::new(i[0], i[3], i[4], i[3], i[1], i[5], i[4], i[5], i[2])
}

/// Mass, centre of mass and inertia of the whole robot as one rigid body, in the trunk frame.
#[derive(Clone, Debug, PartialEq)]
pub struct CompositeBody {
    pub mass_kg: f64,
    /// Whole-robot COM in the trunk frame, m.
    pub com_body: Vector3<f64>,
    /// Inertia about the COM in trunk-frame axes, kg·m².
    pub inertia_body: Matrix3<f64>,
}

/// How a robot's size compares with the A1's, the robot the defaults were tuned on: every
/// setting is scaled by its unit at equal Froude number (gravity unchanged), so a robot λ times
/// the A1's leg length and μ times its mass gets lengths × λ, times × √λ, speeds × √λ, forces
/// × μ, N/m gains × μ/λ and cost weights by the inverse squares of their quantities.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RobotScale {
    /// Leg length (thigh + shank in the leg plane) over the A1's.
    pub length: f64,
    /// Total mass over the A1's.
    pub mass: f64,
}

impl RobotScale {
    /// The factor on a quantity of `unit` (as `settings_keys::KeyDoc::unit` writes
    /// it: products of m, kg, s, N, W and rad with `·`, `/` and powers ², ³); `None` for a unit
    /// that is not a physical dimension (`1`, `bool`, `count`, `steps`, an enum's "").
    pub fn factor(&self, unit: &str) -> Option<f64> {
        if matches!(unit, "1" | "bool" | "count" | "steps" | "") {
            return None;
        }
        // Exponents of (length, mass, time).
        let base = |symbol: &str| -> Option<[i32; 3]> {
            Some(match symbol {
                "m" => [1, 0, 0],
                "kg" => [0, 1, 0],
                "s" => [0, 0, 1],
                "N" => [1, 1, -2],
                "W" => [2, 1, -3],
                "rad" | "1" => [0, 0, 0],
                _ => return None,
            })
        };
        let mut dim = [0i32; 3];
        let mut sign = 1;
        for (i, part) in unit.split('/').enumerate() {
            if i > 0 {
                sign = -1;
            }
            for factor in part.split('·') {
                let (symbol, power) = match factor.strip_suffix('²') {
                    Some(s) => (s, 2),
                    None => match factor.strip_suffix('³') {
                        Some(s) => (s, 3),
                        None => (factor, 1),
                    },
                };
                let d = base(symbol)?;
                for k in 0..3 {
                    dim[k] += sign * power * d[k];
                }
            }
        }
        let time = self.length.sqrt();
        Some(self.length.powi(dim[0]) * self.mass.powi(dim[1]) * time.powi(dim[2]))
    }
}

impl RobotConfig {
    /// This robot's size against the A1's ([`RobotScale`]).
    pub fn scale(&self) -> RobotScale {
        let a1 = RobotConfig::a1();
        let leg = |r: &RobotConfig| {
            let [l1, l2] = r.leg_geometry(Leg::FrontLeft).segment_lengths_m();
            l1 + l2
        };
        RobotScale {
            length: leg(self) / leg(&a1),
            mass: self.total_mass_kg() / a1.total_mass_kg(),
        }
    }

    /// The scale the settings are given ([`ControlDefaults::scale_settings`]), `None` where
    /// they are used as the files write them.
    pub fn settings_scale(&self) -> Option<RobotScale> {
        self.control
            .scale_settings
            .unwrap_or(self.model.is_some())
            .then(|| self.scale())
    }

    /// The A1 shipped with the project (`robots/a1.toml`).
    pub fn a1() -> Self {
        let config: RobotConfig = toml::from_str(A1_TOML).expect("robots/a1.toml parses");
        config.validate().expect("robots/a1.toml is valid");
        config
    }

    /// The robot file at `path`, loaded and validated, or the shipped A1 without one (what
    /// every `--robot` / `robot=` means).
    pub fn load_or_a1(path: Option<&std::path::Path>) -> Result<Self, ConfigError> {
        match path {
            Some(p) => Self::load(p),
            None => Ok(Self::a1()),
        }
    }

    /// Loads and validates a robot file; a value out of range is named with the file. A file
    /// that binds the robot to its own MuJoCo model (`[model]`) needs the model compiled:
    /// `eemp_sim::robot_model::load_robot` reads both kinds.
    pub fn load(path: &std::path::Path) -> Result<Self, ConfigError> {
        let value: toml::Table = crate::config_error::load_toml(path)?;
        if value.contains_key("model") {
            return Err(ConfigError::Invalid {
                name: path.display().to_string(),
                message: "binds the robot to its MuJoCo model ([model]): load it through \
                          eemp_sim::robot_model::load_robot, which compiles the model"
                    .into(),
            });
        }
        let config: RobotConfig = crate::config_error::load_toml(path)?;
        config.validate().map_err(|e| ConfigError::Invalid {
            name: path.display().to_string(),
            message: e.to_string(),
        })?;
        Ok(config)
    }

    /// The motor model of `[motor]`, if the file has one and it is valid ([`Self::validate`]
    /// refuses an invalid one by name).
    pub fn motor_model(&self) -> Option<crate::energy::MotorModel> {
        self.motor.as_ref().and_then(|m| m.resolve().ok())
    }

    pub fn validate(&self) -> Result<(), ConfigError> {
        let s = &self.simulation;
        check_range("simulation.timestep_s", s.timestep_s, 1e-5, 0.005)?;
        if let Some(mu) = self.control.slip_initial_friction {
            let [lo, hi] = FRICTION_RANGE;
            check_range("control.slip_initial_friction", mu, lo, hi)?;
        }
        check_range("simulation.floor_friction", s.floor_friction, 0.0, 5.0)?;
        if let Some(f) = self.control.mpc_f_max_n {
            check_range("control.mpc_f_max_n", f, 1.0, 5000.0)?;
        }
        if let Some(w) = self.control.mpc_weight_heat {
            check_range("control.mpc_weight_heat", w, 0.0, 1.0)?;
            if w > 0.0 && self.motor.is_none() {
                return Err(ConfigError::Invalid {
                    name: "control.mpc_weight_heat".into(),
                    message: format!("{w} weighs the motors' heat: it needs a [motor] section"),
                });
            }
        }
        check_positive("trunk.mass_kg", self.trunk.mass_kg)?;
        let l = &self.leg;
        for (name, v) in [
            ("leg.abduction_to_thigh_m", l.abduction_to_thigh_m),
            ("leg.thigh_length_m", l.thigh_length_m),
            ("leg.calf_length_m", l.calf_length_m),
            ("leg.foot_radius_m", l.foot_radius_m),
            ("leg.torque_limit_nm[abduction]", l.torque_limit_nm[0]),
            ("leg.torque_limit_nm[thigh]", l.torque_limit_nm[1]),
            ("leg.torque_limit_nm[calf]", l.torque_limit_nm[2]),
            ("leg.hip_link.mass_kg", l.hip_link.mass_kg),
            ("leg.thigh_link.mass_kg", l.thigh_link.mass_kg),
            ("leg.calf_link.mass_kg", l.calf_link.mass_kg),
        ] {
            check_positive(name, v)?;
        }
        let mut named_ranges = vec![
            ("leg.abduction_range_rad", l.abduction_range_rad),
            ("leg.thigh_range_rad", l.thigh_range_rad),
            ("leg.calf_range_rad", l.calf_range_rad),
        ];
        if let Some(r) = l.rear_thigh_range_rad {
            named_ranges.push(("leg.rear_thigh_range_rad", r));
        }
        for (name, r) in named_ranges {
            if r[0].partial_cmp(&r[1]) != Some(std::cmp::Ordering::Less) {
                return Err(ConfigError::Invalid {
                    name: name.to_string(),
                    message: format!("min {} must be below max {}", r[0], r[1]),
                });
            }
        }
        for leg in [Leg::FrontLeft, Leg::RearLeft] {
            for (j, name) in ["abduction", "thigh", "calf"].iter().enumerate() {
                let [lo, hi] = self.joint_range_rad(leg, j);
                check_range(
                    &format!("leg.standing_pose_rad[{name}]"),
                    l.standing_pose_rad[j],
                    lo,
                    hi,
                )?;
            }
        }
        MotorOrder::new(&self.sdk)?;
        if let Some(m) = &self.motor {
            m.resolve()?;
        }
        Ok(())
    }

    /// The body heights X_z the legs reach, m: from half the leg's length (a deep crouch) to the
    /// stretched leg less 2 cm (the knee must stay bent to steer the foot), foot radius added.
    pub fn body_height_range_m(&self) -> [f64; 2] {
        let [l1, l2] = self.leg_geometry(Leg::FrontLeft).segment_lengths_m();
        let l = l1 + l2;
        [
            0.5 * l + self.leg.foot_radius_m,
            l - 0.02 + self.leg.foot_radius_m,
        ]
    }

    /// Checks that body height `h` (named `name`) is within [`Self::body_height_range_m`].
    pub fn check_body_height(&self, name: &str, h: f64) -> Result<(), ConfigError> {
        let [lo, hi] = self.body_height_range_m();
        check_range(name, h, lo, hi).map_err(|e| ConfigError::Invalid {
            name: name.to_string(),
            message: format!(
                "{e} (the {} robot's legs reach [{lo:.3}, {hi:.3}] m)",
                self.name
            ),
        })
    }

    /// Joint range [min, max] of joint `j` (0 abduction, 1 thigh, 2 calf) of `leg`, rad.
    pub fn joint_range_rad(&self, leg: Leg, j: usize) -> [f64; 2] {
        if let Some(m) = &self.model {
            return m.joint_range_rad[leg][j];
        }
        let l = &self.leg;
        match j {
            0 => l.abduction_range_rad,
            1 if leg.front_sign() < 0.0 => l.rear_thigh_range_rad.unwrap_or(l.thigh_range_rad),
            1 => l.thigh_range_rad,
            _ => l.calf_range_rad,
        }
    }

    /// The three joint ranges of `leg`, rad.
    pub fn joint_ranges_rad(&self, leg: Leg) -> [[f64; 2]; 3] {
        [0, 1, 2].map(|j| self.joint_range_rad(leg, j))
    }

    /// Where this robot's per-speed table of `gait` is shipped, relative to the repository:
    /// `tables/<robot>_<gait>.toml` (what the walks, suites, teleop and `eemp hw` use unless
    /// told otherwise).
    pub fn shipped_table_path(&self, gait: crate::gait::Gait) -> std::path::PathBuf {
        std::path::PathBuf::from(format!("tables/{}_{gait}.toml", self.name))
    }

    /// This robot's [`RobotId`].
    pub fn id(&self) -> RobotId {
        #[derive(Serialize)]
        struct Physics<'a> {
            trunk: &'a TrunkConfig,
            leg: &'a LegConfig,
        }
        let text = toml::to_string(&Physics {
            trunk: &self.trunk,
            leg: &self.leg,
        })
        .expect("a robot's numbers serialise");
        let text = match &self.model {
            Some(m) => format!("{text}\nmodel = {:?}", m.digest),
            None => text,
        };
        RobotId {
            name: self.name.clone(),
            physics_hash: format!("{:016x}", fnv1a64(&text)),
        }
    }

    /// The SDK's motor numbering (validated with the file).
    pub fn motor_order(&self) -> MotorOrder {
        MotorOrder::new(&self.sdk).expect("validated with the robot file")
    }

    /// Total mass of the robot, kg.
    pub fn total_mass_kg(&self) -> f64 {
        if let Some(m) = &self.model {
            return self.trunk.mass_kg
                + Leg::ALL
                    .iter()
                    .flat_map(|leg| m.links[*leg].iter().map(|l| l.mass_kg))
                    .sum::<f64>();
        }
        let l = &self.leg;
        self.trunk.mass_kg + 4.0 * (l.hip_link.mass_kg + l.thigh_link.mass_kg + l.calf_link.mass_kg)
    }

    /// The geometry of `leg`: the model's, or the Unitree leg the file types.
    pub fn leg_geometry(&self, leg: Leg) -> crate::leg_geometry::LegGeometry {
        match &self.model {
            Some(m) => m.legs[leg].clone(),
            None => {
                let l = &self.leg;
                crate::leg_geometry::LegGeometry::unitree(
                    leg,
                    l.hip_offset_m,
                    l.abduction_to_thigh_m,
                    l.thigh_length_m,
                    l.calf_length_m,
                )
            }
        }
    }

    /// The links of `leg` (abduction, thigh, calf) in their link frames.
    pub fn leg_links(&self, leg: Leg) -> [LinkInertial; 3] {
        if let Some(m) = &self.model {
            return m.links[leg].clone();
        }
        let l = &self.leg;
        [
            (LinkKind::Hip, &l.hip_link),
            (LinkKind::Thigh, &l.thigh_link),
            (LinkKind::Calf, &l.calf_link),
        ]
        .map(|(kind, link)| {
            let (com, inertia) = link.mirrored(leg, kind);
            LinkInertial {
                mass_kg: link.mass_kg,
                com_m: com,
                inertia_kg_m2: inertia_matrix(&inertia),
            }
        })
    }

    /// Standing joint angles for every leg.
    pub fn standing_pose(&self) -> LegMap<Vector3<f64>> {
        if let Some(m) = &self.model {
            return m.standing_pose_rad;
        }
        LegMap::splat(Vector3::from(self.leg.standing_pose_rad))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn a1_total_mass_matches_reference() {
        let robot = RobotConfig::a1();
        // Reference README: total ≈ 12.5 kg.
        assert_relative_eq!(
            robot.total_mass_kg(),
            4.713 + 4.0 * (0.696 + 1.013 + 0.226),
            epsilon = 1e-12
        );
        let body = robot.composite_body(&robot.standing_pose());
        assert_relative_eq!(body.mass_kg, robot.total_mass_kg(), epsilon = 1e-12);
        // Symmetric robot: COM near the centre line, inertia positive definite.
        assert!(body.com_body.y.abs() < 0.01, "com {:?}", body.com_body);
        assert!(body.inertia_body.symmetric_eigenvalues().min() > 0.0);
    }

    #[test]
    fn validation_names_the_value_and_range() {
        let mut robot = RobotConfig::a1();
        robot.simulation.floor_friction = -0.1;
        let err = robot.validate().unwrap_err().to_string();
        assert!(
            err.contains("simulation.floor_friction") && err.contains("[0, 5]"),
            "{err}"
        );
        let mut robot = RobotConfig::a1();
        robot.simulation.timestep_s = f64::NAN;
        assert!(matches!(
            robot.validate(),
            Err(ConfigError::NotFinite { .. })
        ));
        let mut robot = RobotConfig::a1();
        robot.leg.standing_pose_rad[2] = 0.5;
        let err = robot.validate().unwrap_err().to_string();
        assert!(err.contains("standing_pose_rad[calf]"), "{err}");
    }

    const GO2_TOML: &str = include_str!("../../../robots/go2.toml");
    const GO1_TOML: &str = include_str!("../../../robots/go1.toml");

    fn parse(text: &str) -> Result<RobotConfig, String> {
        let r: RobotConfig = toml::from_str(text).map_err(|e| e.to_string())?;
        r.validate().map_err(|e| e.to_string())?;
        Ok(r)
    }

    #[test]
    // Menagerie's rounded numbers (−1.5708, −0.5236), compared as written in the file.
    #[allow(clippy::approx_constant)]
    fn the_go2_and_go1_files_say_their_per_joint_limits_ranges_and_motor_order() {
        let go2 = parse(GO2_TOML).unwrap();
        assert_eq!(go2.leg.torque_limit_nm, [23.7, 23.7, 45.43]);
        // Front and rear thighs differ on the Go2.
        assert_eq!(go2.joint_range_rad(Leg::FrontLeft, 1), [-1.5708, 3.4907]);
        assert_eq!(go2.joint_range_rad(Leg::RearRight, 1), [-0.5236, 4.5379]);
        assert_eq!(go2.joint_range_rad(Leg::RearRight, 2), [-2.7227, -0.83776]);
        // Menagerie's total ≈ 15.21 kg (6.921 + 4 × (0.678 + 1.152 + 0.241352)).
        assert_relative_eq!(go2.total_mass_kg(), 15.206408, epsilon = 1e-9);
        assert_eq!(go2.sdk.protocol, LowLevelProtocol::Go2Dds);
        // Unitree's order: FR 0–2, FL 3–5, RR 6–8, RL 9–11.
        let order = go2.motor_order();
        assert_eq!(order.index(Leg::FrontRight, 0), 0);
        assert_eq!(order.index(Leg::FrontLeft, 2), 5);
        assert_eq!(order.index(Leg::RearLeft, 1), 10);
        let go1 = parse(GO1_TOML).unwrap();
        assert_eq!(go1.leg.torque_limit_nm, [23.7, 23.7, 35.55]);
        assert_eq!(
            go1.joint_range_rad(Leg::RearLeft, 1),
            go1.leg.thigh_range_rad
        );
        // Three robots, three identities; an edited number changes the hash, not the name.
        let a1 = RobotConfig::a1();
        let ids = [a1.id(), go2.id(), go1.id()];
        assert!(ids[0] != ids[1] && ids[1] != ids[2] && ids[0] != ids[2]);
        let mut heavier = a1.clone();
        heavier.trunk.mass_kg += 0.1;
        assert_eq!(heavier.id().name, "a1");
        assert_ne!(heavier.id().physics_hash, a1.id().physics_hash);
        let e = a1.id().check(&heavier, "the trot table").unwrap_err();
        assert!(
            e.contains("the trot table") && e.contains(&a1.id().physics_hash),
            "{e}"
        );
        // An unstamped artifact is the A1's, by name.
        assert!(RobotId::unstamped().check(&heavier, "x").is_ok());
        assert!(RobotId::unstamped()
            .check(&go1, "x")
            .unwrap_err()
            .contains("'go1'"));
    }

    #[test]
    fn a_robot_file_with_a_bad_limit_or_motor_order_is_refused_naming_the_key() {
        // One number still means all three joints (files written before per-joint limits).
        let one = A1_TOML.replace(
            "torque_limit_nm = [33.5, 33.5, 33.5]",
            "torque_limit_nm = 33.5",
        );
        assert_ne!(one, A1_TOML);
        assert_eq!(parse(&one).unwrap(), RobotConfig::a1());
        for (from, to, want) in [
            (
                "torque_limit_nm = [33.5, 33.5, 33.5]",
                "torque_limit_nm = [33.5, 33.5]",
                "torque_limit_nm",
            ),
            (
                "torque_limit_nm = [33.5, 33.5, 33.5]",
                "torque_limit_nm = [33.5, 0.0, 33.5]",
                "leg.torque_limit_nm[thigh]",
            ),
            (
                "torque_limit_nm = [33.5, 33.5, 33.5]",
                "torque_limit_nm = [33.5, 33.5, -1.0]",
                "leg.torque_limit_nm[calf]",
            ),
            (
                "torque_limit_nm = [33.5, 33.5, 33.5]\n",
                "",
                "torque_limit_nm",
            ),
        ] {
            let text = A1_TOML.replace(from, to);
            assert_ne!(text, A1_TOML);
            let e = parse(&text).unwrap_err();
            assert!(e.contains(want), "{to}: {e}");
        }
        for (order, want) in [
            (r#"["FR", "FL", "RR", "FR"]"#, "not a permutation"),
            (r#"["FR", "FL", "RR", "XX"]"#, "sdk.leg_order[3]"),
        ] {
            let text = GO2_TOML.replace(
                r#"leg_order = ["FR", "FL", "RR", "RL"]"#,
                &format!("leg_order = {order}"),
            );
            let e = parse(&text).unwrap_err();
            assert!(e.contains(want), "{order}: {e}");
        }
        // A rear thigh range that excludes the standing pose is named.
        let text = GO2_TOML.replace(
            "rear_thigh_range_rad = [-0.5236, 4.5379]",
            "rear_thigh_range_rad = [1.0, 4.5379]",
        );
        let e = parse(&text).unwrap_err();
        assert!(e.contains("standing_pose_rad[thigh]"), "{e}");
    }

    #[test]
    fn unknown_fields_are_rejected() {
        let text = A1_TOML.replace("name = \"a1\"", "name = \"a1\"\nmystery = 3");
        assert!(toml::from_str::<RobotConfig>(&text).is_err());
    }
}
