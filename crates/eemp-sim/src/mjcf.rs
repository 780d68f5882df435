//! The MuJoCo model (MJCF) of a robot, generated from its [`RobotConfig`] so that the simulator
//! and the controllers read the same numbers.
//!
//! Modelling choices (beyond Menagerie's A1): torque-controlled `motor` actuators with the
//! config's per-joint torque limits (`general` actuators with gain k under a motor-strength error); one capsule per thigh and calf and a box trunk as collision shapes;
//! robot geoms collide with the floor only (no leg–leg contacts: the planner never crosses legs,
//! and it saves collision checks); the floor has contact priority, so its friction is the one
//! used by every foot (that is what makes `floor_friction` the knob for slippery ground);
//! elliptic friction cones with impratio 100 and stiff foot contacts (Menagerie's solimp); an IMU
//! (attitude, gyro, accelerometer) at the trunk origin.

use eemp_core::leg::Leg;
use eemp_core::robot::{LinkConfig, LinkKind, RobotConfig};
use std::fmt::Write;

/// Extra scene content (terrain) inserted into the world body.
#[derive(Clone, Debug, Default)]
pub struct SceneExtras {
    pub world_geoms_xml: String,
    /// Inside `<asset>` (height fields).
    pub assets_xml: String,
    /// Height of the flat floor plane, m (lowered under a height field).
    pub floor_z_m: f64,
    /// Torque the simulated motors deliver per commanded N·m (a torque-constant error; their
    /// maximum scales with it); `None`: exactly as commanded.
    pub motor_strength_scale: Option<f64>,
}

fn v3(v: [f64; 3]) -> String {
    format!("{} {} {}", v[0], v[1], v[2])
}

fn inertial(link: &LinkConfig, leg: Leg, kind: LinkKind) -> String {
    let (com, i) = link.mirrored(leg, kind);
    format!(
        r#"<inertial mass="{}" pos="{} {} {}" fullinertia="{} {} {} {} {} {}"/>"#,
        link.mass_kg, com.x, com.y, com.z, i[0], i[1], i[2], i[3], i[4], i[5]
    )
}

/// Name of the foot geom of `leg` (also used for contact detection).
pub fn foot_geom_name(leg: Leg) -> String {
    format!("{}_foot", leg.short_name())
}

const FLOOR_ASSETS: &str = r#"<texture name="floor_checker" type="2d" builtin="checker" width="256" height="256" rgb1="0.85 0.85 0.85" rgb2="0.62 0.62 0.68"/><material name="floor" texture="floor_checker" texrepeat="4 4" texuniform="true"/>"#;
/// The light, floor and terrain of every scene (inside `<worldbody>`).
fn world(robot: &RobotConfig, extras: &SceneExtras) -> String {
    format!(
        r#"    <light name="sun" pos="0 0 4" dir="0 0 -1" directional="true"/>
    <geom name="floor" type="plane" size="0 0 0.05" pos="0 0 {floor_z}" contype="1" conaffinity="1" priority="1" condim="3" friction="{mu} 0.02 0.01" solimp="0.015 1 0.031" material="floor"/>
{extras}"#,
        floor_z = extras.floor_z_m,
        mu = robot.simulation.floor_friction,
        extras = extras.world_geoms_xml,
    )
}

/// The floor and terrain around a robot read from its own model (`robot_model`),
/// with no robot: attached into the robot's world, which gets the options and IMU sensors
/// (`backend::build_model`).
pub fn scene_without_robot(robot: &RobotConfig, extras: &SceneExtras) -> String {
    format!(
        r#"<mujoco model="scene">
  <compiler angle="radian" autolimits="true"/>
  <asset>{FLOOR_ASSETS}{assets}</asset>
  <worldbody>
{world}  </worldbody>
</mujoco>
"#,
        assets = extras.assets_xml,
        world = world(robot, extras),
    )
}

/// The MJCF text of `robot` standing on a flat floor, plus `extras`, generated from its file.
/// A robot read from its own model is compiled from that model instead
/// (`backend::build_model`); for it this is the scene without the robot.
pub fn robot_mjcf(robot: &RobotConfig, extras: &SceneExtras) -> String {
    if robot.model.is_some() {
        return scene_without_robot(robot, extras);
    }
    let l = &robot.leg;
    let s = &robot.simulation;
    let t = &robot.trunk;
    let mut legs = String::new();
    for leg in Leg::ALL {
        let n = leg.short_name();
        let (fx, sy) = (leg.front_sign(), leg.side_sign());
        let joint = |name: &str, axis: &str, range: [f64; 2], j: usize| {
            format!(
                r#"<joint name="{n}_{name}_joint" axis="{axis}" range="{} {}" damping="{}" armature="{}" frictionloss="{}"/>"#,
                range[0], range[1], l.damping[j], l.armature_kg_m2[j], l.frictionloss_nm[j]
            )
        };
        write!(
            legs,
            r#"
      <body name="{n}_hip" pos="{} {} 0">
        {}
        {}
        <body name="{n}_thigh" pos="0 {} 0">
          {}
          {}
          <geom name="{n}_thigh_geom" type="capsule" size="0.015" fromto="0 0 0 0 0 {}"/>
          <body name="{n}_calf" pos="0 0 {}">
            {}
            {}
            <geom name="{n}_calf_geom" type="capsule" size="0.01" fromto="0 0 0 0 0 {}"/>
            <geom name="{foot}" type="sphere" size="{}" pos="0 0 {}"/>
            <site name="{n}_foot_site" pos="0 0 {}" size="0.005"/>
          </body>
        </body>
      </body>"#,
            fx * l.hip_offset_m[0],
            sy * l.hip_offset_m[1],
            inertial(&l.hip_link, leg, LinkKind::Hip),
            joint("hip", "1 0 0", robot.joint_range_rad(leg, 0), 0),
            sy * l.abduction_to_thigh_m,
            inertial(&l.thigh_link, leg, LinkKind::Thigh),
            joint("thigh", "0 1 0", robot.joint_range_rad(leg, 1), 1),
            -(l.thigh_length_m - 0.01),
            -l.thigh_length_m,
            inertial(&l.calf_link, leg, LinkKind::Calf),
            joint("calf", "0 1 0", robot.joint_range_rad(leg, 2), 2),
            -(l.calf_length_m - l.foot_radius_m),
            l.foot_radius_m,
            -l.calf_length_m,
            -l.calf_length_m,
            foot = foot_geom_name(leg),
        )
        .unwrap();
    }
    let mut actuators = String::new();
    for leg in Leg::ALL {
        for (k, j) in ["hip", "thigh", "calf"].into_iter().enumerate() {
            let n = leg.short_name();
            let lim = l.torque_limit_nm[k];
            match extras.motor_strength_scale {
                // A motor is a general actuator with gain 1; a weaker or stronger one has gain k
                // (MuJoCo's actuator force is then k·ctrl, so the applied torques say so too).
                Some(k) => writeln!(
                    actuators,
                    r#"    <general name="{n}_{j}" joint="{n}_{j}_joint" gainprm="{k}" ctrllimited="true" ctrlrange="{} {lim}"/>"#,
                    -lim
                ),
                None => writeln!(
                    actuators,
                    r#"    <motor name="{n}_{j}" joint="{n}_{j}_joint" ctrlrange="{} {lim}"/>"#,
                    -lim
                ),
            }
            .unwrap();
        }
    }
    let c = t.com_m;
    let i = t.inertia_kg_m2;
    // `<quality>`: videos are rendered by a software rasteriser (Mesa's llvmpipe) where there is
    // no GPU; a 1024² shadow map without multisampling renders a 480×320 frame about 3× faster
    // than MuJoCo's defaults (4096², 4 samples), and the picture looks the same at that size.
    format!(
        r#"<mujoco model="{name}">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{dt}" integrator="Euler" cone="elliptic" impratio="100"/>
  <default>
    <geom contype="1" conaffinity="0" condim="3" rgba="0.3 0.3 0.35 1"/>
  </default>
  <visual><global offwidth="1280" offheight="720"/><quality shadowsize="1024" offsamples="0"/></visual>
  <asset><texture name="floor_checker" type="2d" builtin="checker" width="256" height="256" rgb1="0.85 0.85 0.85" rgb2="0.62 0.62 0.68"/><material name="floor" texture="floor_checker" texrepeat="4 4" texuniform="true"/>{assets}</asset>
  <worldbody>
    <light name="sun" pos="0 0 4" dir="0 0 -1" directional="true"/>
    <geom name="floor" type="plane" size="0 0 0.05" pos="0 0 {floor_z}" contype="1" conaffinity="1" priority="1" condim="3" friction="{mu} 0.02 0.01" solimp="0.015 1 0.031" material="floor"/>
{extras}
    <body name="trunk" pos="0 0 0.3">
      <freejoint name="root"/>
      <inertial mass="{tm}" pos="{cx} {cy} {cz}" fullinertia="{i0} {i1} {i2} {i3} {i4} {i5}"/>
      <geom name="trunk_geom" type="box" size="{half}"/>
      <site name="imu" pos="0 0 0" size="0.01"/>
      <camera name="track" mode="trackcom" pos="0.4 -1.6 0.5" xyaxes="1 0.25 0 -0.1 0.3 1"/>{legs}
    </body>
  </worldbody>
  <actuator>
{actuators}  </actuator>
  <sensor>
    <framequat name="imu_quat" objtype="site" objname="imu"/>
    <gyro name="imu_gyro" site="imu"/>
    <accelerometer name="imu_accel" site="imu"/>
  </sensor>
</mujoco>
"#,
        name = robot.name,
        dt = s.timestep_s,
        mu = s.floor_friction,
        extras = extras.world_geoms_xml,
        assets = extras.assets_xml,
        floor_z = extras.floor_z_m,
        tm = t.mass_kg,
        cx = c[0],
        cy = c[1],
        cz = c[2],
        i0 = i[0],
        i1 = i[1],
        i2 = i[2],
        i3 = i[3],
        i4 = i[4],
        i5 = i[5],
        half = v3(t.collision_half_size_m),
    )
}
