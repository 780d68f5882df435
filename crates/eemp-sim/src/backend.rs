//! The A1 in MuJoCo: names resolved once into typed handles, ground-truth state out, torques in.
//!
//! A step is split the way MuJoCo's control callback works: [`Simulation::prepare`] (mj_step1:
//! kinematics, mass matrix, bias forces at the current state) → read the state and dynamics,
//! compute torques → [`Simulation::advance`] (mj_step2: actuation, constraints, Euler
//! integration). So the controller always sees the dynamics of the state it acts on.

use crate::mjcf::{foot_geom_name, robot_mjcf, SceneExtras};
use eemp_core::body_state::{BodyState, LegJointState, RobotState};
use eemp_core::kinematics::LegKinematics;
use eemp_core::leg::{Leg, LegMap};
use eemp_core::leg_control::{DynamicsModel, LegDynamics};
use eemp_core::robot::RobotConfig;
use mujoco_rs::prelude::*;
use nalgebra::{Matrix3, UnitQuaternion, Vector3};
use std::sync::Arc;

#[derive(Debug, thiserror::Error)]
pub enum SimError {
    #[error("MuJoCo rejected the generated model: {0}")]
    Model(String),
    #[error("the model has no {kind} named '{name}'")]
    MissingName { kind: &'static str, name: String },
    #[error("initial pose unreachable: {0}")]
    Pose(String),
}

/// A simulation's dynamic state (see [`Simulation::snapshot`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SimSnapshot {
    pub time_s: f64,
    pub qpos: Vec<f64>,
    pub qvel: Vec<f64>,
    pub qacc_warmstart: Vec<f64>,
    pub ctrl: Vec<f64>,
}

/// Indices into MuJoCo's arrays, resolved once from names.
#[derive(Clone, Debug)]
struct Handles {
    trunk_body: usize,
    trunk_geom: usize,
    floor_geom: usize,
    foot_geom: LegMap<usize>,
    foot_site: LegMap<usize>,
    calf_body: LegMap<usize>,
    thigh_body: LegMap<usize>,
    /// First qpos / qvel index of each leg's three joints, and its first actuator.
    qpos_adr: LegMap<usize>,
    dof_adr: LegMap<usize>,
    actuator: LegMap<usize>,
    /// sensordata addresses of the IMU's quaternion, gyro and accelerometer.
    imu_adr: [usize; 3],
}

#[derive(Clone)]
pub struct Simulation {
    data: MjData<Arc<MjModel>>,
    kinematics: LegKinematics,
    handles: Handles,
    nv: usize,
    mass_matrix: Vec<f64>,
    torque_limit_nm: [f64; 3],
    total_mass_kg: f64,
    foot_radius_m: f64,
}

/// Compiles the MuJoCo model of `robot` on a flat floor plus `extras`.
pub fn build_model(robot: &RobotConfig, extras: &SceneExtras) -> Result<Arc<MjModel>, SimError> {
    let xml = robot_mjcf(robot, extras);
    let Some(m) = &robot.model else {
        let model = MjModel::from_xml_string(&xml).map_err(|e| SimError::Model(e.to_string()))?;
        return Ok(Arc::new(model));
    };
    let mut spec = bound_scene_spec(robot, extras)?;
    let mut model = spec.compile().map_err(|e| SimError::Model(e.to_string()))?;
    apply_trunk_changes(&mut model, &robot.trunk, &m.compiled_trunk)?;
    Ok(Arc::new(model))
}

/// The scene of a robot read from its own model: the floor and terrain attached into its edited
/// spec, to be compiled as one (no text round trip: MuJoCo's XML writer drops some
/// default-class values, such as a class's `mass="0"`).
pub fn bound_scene_spec(robot: &RobotConfig, extras: &SceneExtras) -> Result<MjSpec, SimError> {
    let model_err = |e: &dyn std::fmt::Display| SimError::Model(e.to_string());
    let m = robot.model.as_ref().ok_or_else(|| {
        SimError::Model("the robot is typed into its file, not bound to a model".into())
    })?;
    let (mut spec, _) =
        crate::robot_model::edited_spec(&m.source, &m.edits).map_err(|e| model_err(&e))?;
    crate::robot_model::complete_for_scene(&mut spec, robot).map_err(|e| model_err(&e))?;
    if let Some(k) = extras.motor_strength_scale {
        crate::robot_model::scale_motor_strength(&mut spec, k);
    }
    let mut scene =
        MjSpec::from_xml_string(&robot_mjcf(robot, extras)).map_err(|e| model_err(&e))?;
    spec.world_body_mut()
        .attach_by_deep_copy(&mut scene, "scene_", "")
        .map_err(|e| model_err(&e))?;
    spec.geom_mut("scene_floor")
        .ok_or_else(|| SimError::Model("the scene's floor was not attached".into()))?
        .set_name("floor")
        .map_err(|e| model_err(&e))?;
    Ok(spec)
}

/// A robot read from its own model keeps the model's trunk inertial; a run's trunk-mass and
/// -inertia errors and its payload (`trunk` against the `compiled` one) change it here, as the
/// generated model writes them: mass added at the trunk's COM, inertia scaled.
fn apply_trunk_changes(
    model: &mut MjModel,
    trunk: &eemp_core::robot::TrunkConfig,
    compiled: &eemp_core::robot::TrunkConfig,
) -> Result<(), SimError> {
    if trunk == compiled {
        return Ok(());
    }
    let body = id(model, MjtObjBase::mjOBJ_BODY, "body", "trunk")?;
    let inertia_scale = trunk.inertia_kg_m2[0] / compiled.inertia_kg_m2[0];
    // SAFETY: two plain arrays of the compiled model are written in place, within their sizes,
    // before any data is made from it.
    unsafe {
        let m = model.ffi_mut();
        *m.body_mass.add(body) += trunk.mass_kg - compiled.mass_kg;
        for k in 0..3 {
            *m.body_inertia.add(3 * body + k) *= inertia_scale;
        }
    }
    Ok(())
}

fn id(
    model: &MjModel,
    kind: MjtObjBase,
    kind_name: &'static str,
    name: &str,
) -> Result<usize, SimError> {
    model
        .name_to_id(kind, name)
        .ok_or_else(|| SimError::MissingName {
            kind: kind_name,
            name: name.to_string(),
        })
}

impl Simulation {
    /// Builds the robot's model (flat floor plus `extras`) and its data.
    pub fn new(robot: &RobotConfig, extras: &SceneExtras) -> Result<Self, SimError> {
        Self::with_model(build_model(robot, extras)?, robot)
    }

    /// A simulation with its own data on a shared model (vectorised environments: one model,
    /// N datas). `robot` must be the config the model was built from.
    pub fn with_model(model: Arc<MjModel>, robot: &RobotConfig) -> Result<Self, SimError> {
        let m: &MjModel = &model;
        let trunk_body = id(m, MjtObjBase::mjOBJ_BODY, "body", "trunk")?;
        let floor_geom = id(m, MjtObjBase::mjOBJ_GEOM, "geom", "floor")?;
        let trunk_geom = id(m, MjtObjBase::mjOBJ_GEOM, "geom", "trunk_geom")?;
        let mut foot_geom = LegMap::splat(0);
        let mut foot_site = LegMap::splat(0);
        let mut calf_body = LegMap::splat(0);
        let mut thigh_body = LegMap::splat(0);
        let mut qpos_adr = LegMap::splat(0);
        let mut dof_adr = LegMap::splat(0);
        let mut actuator = LegMap::splat(0);
        for leg in Leg::ALL {
            let n = leg.short_name();
            foot_geom[leg] = id(m, MjtObjBase::mjOBJ_GEOM, "geom", &foot_geom_name(leg))?;
            foot_site[leg] = id(m, MjtObjBase::mjOBJ_SITE, "site", &format!("{n}_foot_site"))?;
            calf_body[leg] = id(m, MjtObjBase::mjOBJ_BODY, "body", &format!("{n}_calf"))?;
            thigh_body[leg] = id(m, MjtObjBase::mjOBJ_BODY, "body", &format!("{n}_thigh"))?;
            let joint = id(
                m,
                MjtObjBase::mjOBJ_JOINT,
                "joint",
                &format!("{n}_hip_joint"),
            )?;
            qpos_adr[leg] = m.jnt_qposadr()[joint] as usize;
            dof_adr[leg] = m.jnt_dofadr()[joint] as usize;
            actuator[leg] = id(
                m,
                MjtObjBase::mjOBJ_ACTUATOR,
                "actuator",
                &format!("{n}_hip"),
            )?;
            // The three joints and actuators of a leg are consecutive in the generated model.
            let calf = id(
                m,
                MjtObjBase::mjOBJ_JOINT,
                "joint",
                &format!("{n}_calf_joint"),
            )?;
            assert_eq!(
                m.jnt_dofadr()[calf] as usize,
                dof_adr[leg] + 2,
                "leg joints are consecutive"
            );
        }
        let mut imu_adr = [0usize; 3];
        for (k, name) in ["imu_quat", "imu_gyro", "imu_accel"].iter().enumerate() {
            let sid = id(m, MjtObjBase::mjOBJ_SENSOR, "sensor", name)?;
            imu_adr[k] = m.sensor_adr()[sid] as usize;
        }
        let nv = m.ffi().nv as usize;
        let data = MjData::new(model.clone());
        Ok(Simulation {
            data,
            kinematics: LegKinematics::new(robot),
            handles: Handles {
                trunk_body,
                trunk_geom,
                floor_geom,
                foot_geom,
                foot_site,
                calf_body,
                thigh_body,
                qpos_adr,
                dof_adr,
                actuator,
                imu_adr,
            },
            nv,
            mass_matrix: vec![0.0; nv * nv],
            torque_limit_nm: robot.leg.torque_limit_nm,
            total_mass_kg: robot.total_mass_kg(),
            foot_radius_m: robot.leg.foot_radius_m,
        })
    }

    /// Puts the robot at rest: trunk origin at `p_world` with yaw 0, joints at `q`. Zero velocity.
    pub fn reset(&mut self, p_world: Vector3<f64>, q: &LegMap<Vector3<f64>>) {
        self.data.reset();
        {
            let qpos = self.data.qpos_mut();
            qpos[0..3].copy_from_slice(p_world.as_slice());
            qpos[3..7].copy_from_slice(&[1.0, 0.0, 0.0, 0.0]);
        }
        for leg in Leg::ALL {
            let a = self.handles.qpos_adr[leg];
            self.data.qpos_mut()[a..a + 3].copy_from_slice(q[leg].as_slice());
        }
        self.data.forward();
    }

    /// Sets position and velocity from a [`RobotState`] (e.g. one recorded earlier) and
    /// recomputes the derived quantities.
    pub fn set_state(&mut self, state: &RobotState) {
        let b = &state.body;
        let q = b.r_world_body.coords;
        let omega_body = b.r_world_body.inverse() * b.omega_world;
        {
            let qpos = self.data.qpos_mut();
            qpos[0..3].copy_from_slice(b.p_world.as_slice());
            qpos[3..7].copy_from_slice(&[q.w, q.x, q.y, q.z]);
        }
        {
            let qvel = self.data.qvel_mut();
            qvel[0..3].copy_from_slice(b.v_world.as_slice());
            qvel[3..6].copy_from_slice(omega_body.as_slice());
        }
        for leg in Leg::ALL {
            let (a, d) = (self.handles.qpos_adr[leg], self.handles.dof_adr[leg]);
            self.data.qpos_mut()[a..a + 3].copy_from_slice(state.joints[leg].q.as_slice());
            self.data.qvel_mut()[d..d + 3].copy_from_slice(state.joints[leg].qd.as_slice());
        }
        self.data.forward();
    }

    /// Puts the model in `state`'s pose and computes body poses only (mj_kinematics): for
    /// viewers that draw a state they did not simulate (the estimate as a ghost, a trace).
    pub fn set_pose(&mut self, state: &RobotState) {
        let b = &state.body;
        let q = b.r_world_body.coords;
        let qpos = self.data.qpos_mut();
        qpos[0..3].copy_from_slice(b.p_world.as_slice());
        qpos[3..7].copy_from_slice(&[q.w, q.x, q.y, q.z]);
        for leg in Leg::ALL {
            let a = self.handles.qpos_adr[leg];
            self.data.qpos_mut()[a..a + 3].copy_from_slice(state.joints[leg].q.as_slice());
        }
        self.data.kinematics();
    }

    /// Computes kinematics, mass matrix and bias forces at the current state (mj_step1).
    pub fn prepare(&mut self) {
        self.data.step1();
        self.data
            .full_m(&mut self.mass_matrix)
            .expect("buffer is nv×nv");
    }

    /// Computes kinematics and contacts only (mj_step1 without the dense mass matrix), for
    /// controllers that do not use the dynamics (joint PD, learned policies).
    pub fn prepare_kinematics(&mut self) {
        self.data.step1();
    }

    /// The robot's leg kinematics (the same numbers the model was generated from).
    pub fn kinematics(&self) -> &LegKinematics {
        &self.kinematics
    }

    /// The shared model (a cheap handle).
    pub fn model(&self) -> Arc<MjModel> {
        self.data.model_clone()
    }

    /// Applies joint torques (clamped to the motor limit by MuJoCo's ctrlrange) and integrates
    /// one time step (mj_step2).
    pub fn advance(&mut self, torques: &LegMap<Vector3<f64>>) {
        for leg in Leg::ALL {
            let a = self.handles.actuator[leg];
            for j in 0..3 {
                self.data.ctrl_mut()[a + j] = torques[leg][j];
            }
        }
        self.data.step2();
    }

    /// One full step with constant torques (mj_step), for benchmarks and passive tests.
    pub fn step_bare(&mut self, torques: &LegMap<Vector3<f64>>) {
        for leg in Leg::ALL {
            let a = self.handles.actuator[leg];
            for j in 0..3 {
                self.data.ctrl_mut()[a + j] = torques[leg][j];
            }
        }
        self.data.step();
    }

    /// The IMU as MuJoCo simulates it (noise-free): attitude and gyro of the current state
    /// (after [`Simulation::prepare`]), accelerometer of the last completed step.
    pub fn imu(&self) -> eemp_core::estimator::ImuReading {
        let d = self.data.sensordata();
        let [q, g, a] = self.handles.imu_adr;
        eemp_core::estimator::ImuReading {
            r_world_body: UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
                d[q],
                d[q + 1],
                d[q + 2],
                d[q + 3],
            )),
            gyro_body: Vector3::new(d[g], d[g + 1], d[g + 2]),
            accel_body: Vector3::new(d[a], d[a + 1], d[a + 2]),
        }
    }

    /// Ground-truth state estimate: the simulator's own state, read without noise or delay.
    /// (A real estimator — IMU + leg kinematics — replaces this on hardware.)
    pub fn ground_truth_state(&self) -> RobotState {
        let qpos = self.data.qpos();
        let qvel = self.data.qvel();
        let r_world_body = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
            qpos[3], qpos[4], qpos[5], qpos[6],
        ));
        // MuJoCo's free joint: linear velocity in the world frame, angular velocity in the body frame.
        let omega_body = Vector3::new(qvel[3], qvel[4], qvel[5]);
        let body = BodyState {
            p_world: Vector3::new(qpos[0], qpos[1], qpos[2]),
            r_world_body,
            v_world: Vector3::new(qvel[0], qvel[1], qvel[2]),
            omega_world: r_world_body * omega_body,
        };
        let joints = LegMap::from_fn(|leg| {
            let (a, d) = (self.handles.qpos_adr[leg], self.handles.dof_adr[leg]);
            LegJointState {
                q: Vector3::new(qpos[a], qpos[a + 1], qpos[a + 2]),
                qd: Vector3::new(qvel[d], qvel[d + 1], qvel[d + 2]),
            }
        });
        RobotState {
            time_s: self.time_s(),
            body,
            joints,
        }
    }

    pub fn time_s(&self) -> f64 {
        self.data.ffi().time
    }

    pub fn timestep_s(&self) -> f64 {
        self.data.model_opt().timestep
    }

    /// Foot-sphere centres in the world frame, from MuJoCo's kinematics.
    pub fn foot_positions_world(&self) -> LegMap<Vector3<f64>> {
        LegMap::from_fn(|leg| Vector3::from(self.data.site_xpos()[self.handles.foot_site[leg]]))
    }

    /// MuJoCo's translational Jacobian of each foot site w.r.t. that leg's joints, world frame.
    pub fn foot_jacobian_world(&self, leg: Leg) -> Matrix3<f64> {
        let p = self.data.site_xpos()[self.handles.foot_site[leg]];
        let (jacp, _) = self.data.jac(true, false, &p, self.handles.calf_body[leg]);
        let d = self.handles.dof_adr[leg];
        Matrix3::from_fn(|i, j| jacp[i * self.nv + d + j])
    }

    /// Normal force the ground exerts on each foot, N, from the last constraint solve (valid
    /// after [`Simulation::advance`] or [`Simulation::step_bare`]).
    pub fn foot_normal_forces_n(&self) -> LegMap<f64> {
        let mut f = LegMap::splat(0.0);
        for (i, c) in self.data.contact().iter().enumerate() {
            for leg in Leg::ALL {
                let g = self.handles.foot_geom[leg] as i32;
                if c.geom[0] == g || c.geom[1] == g {
                    f[leg] += self.data.contact_force(i)[0].abs();
                }
            }
        }
        f
    }

    /// Which feet touch the floor (or any terrain geom) now, from MuJoCo's contact list. With
    /// the model's soft contacts a foot can touch with almost no load (see
    /// [`Simulation::foot_normal_forces_n`] for whether it carries the robot).
    pub fn foot_contacts(&self) -> LegMap<bool> {
        let mut touching = LegMap::splat(false);
        for c in self.data.contact() {
            for leg in Leg::ALL {
                let g = self.handles.foot_geom[leg] as i32;
                if c.geom[0] == g || c.geom[1] == g {
                    touching[leg] = true;
                }
            }
        }
        touching
    }

    /// Contacts between the floor and the legs away from the feet: any thigh contact, and calf
    /// contacts more than `near_foot_m` from that leg's foot centre (a knee on the ground). The
    /// lower calf touching next to a foot that sinks into the soft floor is not counted: with
    /// the model's contact softness it happens in normal stance. This is the "collision" a
    /// learned controller is penalised for (the model has no leg–leg contacts).
    pub fn leg_ground_contacts(&self, near_foot_m: f64) -> usize {
        let floor = self.handles.floor_geom as i32;
        let model = self.data.model();
        let geom_body = model.geom_bodyid();
        let mut n = 0;
        for c in self.data.contact() {
            let other = if c.geom[0] == floor {
                c.geom[1]
            } else if c.geom[1] == floor {
                c.geom[0]
            } else {
                continue;
            };
            if other < 0
                || Leg::ALL
                    .iter()
                    .any(|l| self.handles.foot_geom[*l] as i32 == other)
            {
                continue;
            }
            let body = geom_body[other as usize] as usize;
            for leg in Leg::ALL {
                if body == self.handles.calf_body[leg] {
                    let foot = Vector3::from(self.data.site_xpos()[self.handles.foot_site[leg]]);
                    if (Vector3::from(c.pos) - foot).norm() > near_foot_m {
                        n += 1;
                    }
                } else if body == self.handles.thigh_body[leg] {
                    n += 1;
                }
            }
        }
        n
    }

    /// Whether MuJoCo found a bad position, velocity or acceleration since the last call (it
    /// then silently resets the data to the model's initial pose); clears those counters.
    pub fn take_instability(&mut self) -> bool {
        let w = self.data.warning_mut();
        let mut any = false;
        for kind in [
            MjtWarning::mjWARN_BADQPOS,
            MjtWarning::mjWARN_BADQVEL,
            MjtWarning::mjWARN_BADQACC,
        ] {
            let stat = &mut w[kind as usize];
            if stat.number > 0 {
                any = true;
                stat.number = 0;
            }
        }
        any
    }

    /// Whether the trunk touches the ground (a fall for learned controllers, as in legged_gym).
    pub fn trunk_contact(&self) -> bool {
        let (floor, trunk) = (
            self.handles.floor_geom as i32,
            self.handles.trunk_geom as i32,
        );
        self.data.contact().iter().any(|c| {
            (c.geom[0] == floor && c.geom[1] == trunk) || (c.geom[1] == floor && c.geom[0] == trunk)
        })
    }

    /// Everything MuJoCo needs to continue bit for bit from here (checkpoints of training).
    pub fn snapshot(&self) -> SimSnapshot {
        SimSnapshot {
            time_s: self.time_s(),
            qpos: self.data.qpos().to_vec(),
            qvel: self.data.qvel().to_vec(),
            qacc_warmstart: self.data.qacc_warmstart().to_vec(),
            ctrl: self.data.ctrl().to_vec(),
        }
    }

    /// Restores a [`Simulation::snapshot`] of a simulation of the same model.
    pub fn restore(&mut self, s: &SimSnapshot) -> Result<(), SimError> {
        if s.qpos.len() != self.data.qpos().len()
            || s.qvel.len() != self.nv
            || s.qacc_warmstart.len() != self.nv
            || s.ctrl.len() != self.data.ctrl().len()
        {
            return Err(SimError::Pose(
                "snapshot is of a model with other dimensions".into(),
            ));
        }
        self.data.qpos_mut().copy_from_slice(&s.qpos);
        self.data.qvel_mut().copy_from_slice(&s.qvel);
        self.data
            .qacc_warmstart_mut()
            .copy_from_slice(&s.qacc_warmstart);
        self.data.ctrl_mut().copy_from_slice(&s.ctrl);
        // SAFETY: plain field write on the data this simulation owns.
        unsafe { self.data.ffi_mut().time = s.time_s };
        self.data.forward();
        // mj_forward's constraint solve overwrote the warm start: put back the one an
        // uninterrupted run would start its next step from.
        self.data
            .qacc_warmstart_mut()
            .copy_from_slice(&s.qacc_warmstart);
        Ok(())
    }

    /// Applies a force (N, world frame) at the trunk's centre of mass until changed.
    pub fn set_trunk_force(&mut self, f_world: Vector3<f64>) {
        let b = self.handles.trunk_body;
        self.data.xfrc_applied_mut()[b] = [f_world.x, f_world.y, f_world.z, 0.0, 0.0, 0.0];
    }

    /// The force [`Simulation::set_trunk_force`] last set, N, world frame.
    pub fn trunk_force(&self) -> Vector3<f64> {
        let f = self.data.xfrc_applied()[self.handles.trunk_body];
        Vector3::new(f[0], f[1], f[2])
    }

    pub fn total_mass_kg(&self) -> f64 {
        self.total_mass_kg
    }

    pub fn torque_limit_nm(&self) -> [f64; 3] {
        self.torque_limit_nm
    }

    pub fn foot_radius_m(&self) -> f64 {
        self.foot_radius_m
    }

    pub fn floor_geom(&self) -> usize {
        self.handles.floor_geom
    }

    /// Joint torques MuJoCo applied in the last step (after its ctrlrange clamp), N·m.
    pub fn applied_torques(&self) -> LegMap<Vector3<f64>> {
        let f = self.data.actuator_force();
        LegMap::from_fn(|leg| {
            let a = self.handles.actuator[leg];
            Vector3::new(f[a], f[a + 1], f[a + 2])
        })
    }

    /// Full inverse dynamics for a test: generalized forces for `qacc` at the current state.
    pub fn inverse_dynamics(&mut self, qacc: &[f64]) -> Vec<f64> {
        self.data.qacc_mut().copy_from_slice(qacc);
        self.data.inverse();
        self.data.qfrc_inverse().to_vec()
    }

    /// Raw access for tests and tools that need MuJoCo directly (rendering, terrains).
    pub fn data(&self) -> &MjData<Arc<MjModel>> {
        &self.data
    }

    pub fn data_mut(&mut self) -> &mut MjData<Arc<MjModel>> {
        &mut self.data
    }

    pub fn dof_adr(&self, leg: Leg) -> usize {
        self.handles.dof_adr[leg]
    }

    pub fn nv(&self) -> usize {
        self.nv
    }
}

impl DynamicsModel for Simulation {
    /// The leg's block of MuJoCo's mass matrix and its rows of qfrc_bias, valid after
    /// [`Simulation::prepare`].
    fn leg_dynamics(&self, leg: Leg) -> LegDynamics {
        let d = self.handles.dof_adr[leg];
        let nv = self.nv;
        let bias = self.data.qfrc_bias();
        LegDynamics {
            mass_matrix: Matrix3::from_fn(|i, j| self.mass_matrix[(d + i) * nv + d + j]),
            bias_torque: Vector3::new(bias[d], bias[d + 1], bias[d + 2]),
        }
    }
}

/// The model evaluated at each estimate the control pipeline hands it (`eemp hw`, Python): a
/// model of the robot file, set to the state and never stepped.
pub struct EvaluatedAt<'a>(pub &'a mut Simulation);

impl eemp_core::pipeline::DynamicsAt for EvaluatedAt<'_> {
    fn at(&mut self, estimate: &RobotState, full: bool) -> &dyn DynamicsModel {
        self.0.set_state(estimate);
        if full {
            self.0.prepare();
        } else {
            self.0.prepare_kinematics();
        }
        &*self.0
    }
}
