//! EEMP (planner + MPC + swing law) callable on a state and a command, a simulated A1 to drive
//! it with, and whole walks with their metrics.

use crate::envs::{lock, value_error};
use eemp_core::body_state::{BodyState, LegJointState, RobotState};
use eemp_core::controller::Controller;
use eemp_core::eemp::EempController;
use eemp_core::kinematics::LegKinematics;
use eemp_core::leg::{Leg, LegMap};
use eemp_core::pipeline::{ControlPipeline, Sensed};
use eemp_core::planner::VelocityCommand;
use eemp_rl::run::{Sensing, WalkDescription};
use eemp_sim::backend::{build_model, EvaluatedAt, Simulation};
use eemp_sim::walk::{eemp_controller, reset_to_start, StartPose};
use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use numpy::{AllowTypeChange, PyArray1, PyArrayLike1};
use pyo3::prelude::*;
use std::path::PathBuf;
use std::sync::Mutex;

/// Any array-like of numbers (a list, float32 or float64 array, ...), read as f64.
type Vector1<'py> = PyArrayLike1<'py, f64, AllowTypeChange>;

/// `n` finite numbers named `name`, or a ValueError saying what is wrong.
fn vector(name: &str, a: &Vector1<'_>, n: usize) -> PyResult<Vec<f64>> {
    let v: Vec<f64> = a.as_array().iter().copied().collect();
    if v.len() != n {
        return Err(value_error(format!(
            "{name} has {} values, expected {n}",
            v.len()
        )));
    }
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return Err(value_error(format!(
            "{name}[{i}] is {}: values must be finite",
            v[i]
        )));
    }
    Ok(v)
}

fn v3(v: &[f64]) -> Vector3<f64> {
    Vector3::new(v[0], v[1], v[2])
}

/// The robot state from the arrays a Python caller holds (legs in `LEG_ORDER`, joints
/// abduction, hip, knee per leg).
#[allow(clippy::too_many_arguments)]
fn robot_state(
    time_s: f64,
    p_world: &Vector1<'_>,
    quat_wxyz: &Vector1<'_>,
    v_world: &Vector1<'_>,
    omega_world: &Vector1<'_>,
    q: &Vector1<'_>,
    qd: &Vector1<'_>,
) -> PyResult<RobotState> {
    if !time_s.is_finite() {
        return Err(value_error(format!("time_s is {time_s}: must be finite")));
    }
    let quat = vector("quat_wxyz", quat_wxyz, 4)?;
    let norm = quat.iter().map(|x| x * x).sum::<f64>().sqrt();
    if (norm - 1.0).abs() > 1e-3 {
        return Err(value_error(format!(
            "quat_wxyz has norm {norm}: a unit quaternion (w, x, y, z) is expected (±1e-3)"
        )));
    }
    let (q, qd) = (vector("q", q, 12)?, vector("qd", qd, 12)?);
    Ok(RobotState {
        time_s,
        body: BodyState {
            p_world: v3(&vector("p_world", p_world, 3)?),
            r_world_body: UnitQuaternion::from_quaternion(Quaternion::new(
                quat[0], quat[1], quat[2], quat[3],
            )),
            v_world: v3(&vector("v_world", v_world, 3)?),
            omega_world: v3(&vector("omega_world", omega_world, 3)?),
        },
        joints: LegMap::from_fn(|leg| {
            let k = 3 * leg.index();
            LegJointState {
                q: v3(&q[k..k + 3]),
                qd: v3(&qd[k..k + 3]),
            }
        }),
    })
}

fn flat(m: &LegMap<Vector3<f64>>) -> Vec<f64> {
    Leg::ALL
        .iter()
        .flat_map(|l| m[*l].iter().copied())
        .collect()
}

/// The run description of an EEMP walk with these arguments: the one `eemp walk` fills, built
/// (validated, the table checked against the robot) by the same code. Without `params` or
/// `params_table`, the robot's shipped table of the gait when the working folder has it.
fn eemp_walk(
    gait: &str,
    params: Option<PathBuf>,
    params_table: Option<PathBuf>,
    table_ii: bool,
    robot: Option<PathBuf>,
    settings: Vec<String>,
) -> WalkDescription {
    WalkDescription {
        robot,
        gait: gait.into(),
        params,
        params_table,
        table_ii,
        set: settings,
        ..Default::default()
    }
}

struct ControllerState {
    controller: EempController,
    /// The A1's MuJoCo model, set to each state given: the dynamics (mass matrix, bias) the
    /// swing law needs, as the hardware runner gets them.
    model: Simulation,
    kin: LegKinematics,
    /// The control update the simulation and the robot run, on the state as given.
    pipeline: ControlPipeline,
}

/// EEMP as a function of (state, command) → joint torques, for another simulator's loop.
#[pyclass(module = "eemp._eemp", name = "EempController")]
pub struct PyEempController {
    inner: Mutex<ControllerState>,
}

#[pymethods]
impl PyEempController {
    #[new]
    #[pyo3(signature = (gait = "trot", params = None, params_table = None, robot = None, table_ii = false, settings = Vec::new()))]
    fn new(
        gait: &str,
        params: Option<PathBuf>,
        params_table: Option<PathBuf>,
        robot: Option<PathBuf>,
        table_ii: bool,
        settings: Vec<String>,
    ) -> PyResult<Self> {
        let built = eemp_walk(gait, params, params_table, table_ii, robot, settings)
            .build()
            .map_err(value_error)?;
        let (robot, spec) = (built.robot, built.spec);
        let controller = eemp_controller(&robot, &spec).map_err(value_error)?;
        let model = build_model(&robot, &Default::default())
            .and_then(|m| Simulation::with_model(m, &robot))
            .map_err(value_error)?;
        Ok(PyEempController {
            inner: Mutex::new(ControllerState {
                controller,
                model,
                kin: LegKinematics::new(&robot),
                pipeline: ControlPipeline::new(0.0, robot.scale()),
            }),
        })
    }

    /// One control step at `time_s` (seconds, increasing; call it at the physics rate, 1 kHz
    /// for the A1): trunk position (world, m), orientation (unit quaternion w, x, y, z, body
    /// to world), linear and angular velocity (world, m/s and rad/s), joint angles and rates
    /// (12, legs FR FL RR RL, joints abduction hip knee), command (v_x, v_y m/s in the heading
    /// frame, yaw rate rad/s). Returns the 12 joint torques, N·m, in the same order.
    #[allow(clippy::too_many_arguments)]
    #[pyo3(signature = (time_s, p_world, quat_wxyz, v_world, omega_world, q, qd, command = (0.0, 0.0, 0.0)))]
    fn step<'py>(
        &self,
        py: Python<'py>,
        time_s: f64,
        p_world: Vector1<'py>,
        quat_wxyz: Vector1<'py>,
        v_world: Vector1<'py>,
        omega_world: Vector1<'py>,
        q: Vector1<'py>,
        qd: Vector1<'py>,
        command: (f64, f64, f64),
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let state = robot_state(
            time_s,
            &p_world,
            &quat_wxyz,
            &v_world,
            &omega_world,
            &q,
            &qd,
        )?;
        let (vx, vy, wz) = command;
        if ![vx, vy, wz].iter().all(|x| x.is_finite()) {
            return Err(value_error(format!(
                "command {command:?} must be finite (v_x, v_y m/s, yaw rate rad/s)"
            )));
        }
        let mut g = lock(&self.inner, py);
        let s = &mut *g;
        let update = s.pipeline.update(
            &Sensed {
                seen: state,
                imu: None,
            },
            &s.kin,
            &mut s.controller,
            VelocityCommand {
                vx_mps: vx,
                vy_mps: vy,
                yaw_rate_rps: wz,
            },
            &mut EvaluatedAt(&mut s.model),
        );
        Ok(PyArray1::from_vec(py, flat(&update.output.torques)))
    }

    /// The legs in stance in the last step's plan (FR, FL, RR, RL).
    fn stance(&self, py: Python<'_>) -> Option<[bool; 4]> {
        let g = lock(&self.inner, py);
        g.controller.plan().map(|p| p.stance.0)
    }
}

/// The A1 in MuJoCo, standing in EEMP's start pose, stepped with joint torques.
#[pyclass(module = "eemp._eemp", name = "A1Sim")]
pub struct PyA1Sim {
    sim: Mutex<Simulation>,
}

impl PyA1Sim {
    fn lock(&self, py: Python<'_>) -> std::sync::MutexGuard<'_, Simulation> {
        lock(&self.sim, py)
    }
}

#[pymethods]
impl PyA1Sim {
    /// `seed` 0 starts exactly at rest; others as the walks do (a small random heading and
    /// velocity).
    #[new]
    #[pyo3(signature = (gait = "trot", seed = 0, table_ii = false))]
    fn new(gait: &str, seed: u64, table_ii: bool) -> PyResult<Self> {
        // The start pose of the EempController it pairs with: the same table (or Table II).
        let built = eemp_walk(gait, None, None, table_ii, None, Vec::new())
            .build()
            .map_err(value_error)?;
        let robot = built.robot;
        let start = StartPose::eemp(&robot, &built.spec).map_err(value_error)?;
        let mut sim = Simulation::new(&robot, &Default::default()).map_err(value_error)?;
        reset_to_start(&mut sim, &start, seed);
        Ok(PyA1Sim {
            sim: Mutex::new(sim),
        })
    }

    #[getter]
    fn timestep_s(&self, py: Python<'_>) -> f64 {
        self.lock(py).timestep_s()
    }

    /// One physics step with the 12 joint torques (N·m, clamped by the motors' limit).
    fn step(&self, py: Python<'_>, torques: Vector1<'_>) -> PyResult<()> {
        let t = vector("torques", &torques, 12)?;
        let tau = LegMap::from_fn(|leg| v3(&t[3 * leg.index()..3 * leg.index() + 3]));
        self.lock(py).step_bare(&tau);
        Ok(())
    }

    /// The simulator's true state: time_s, p_world, quat_wxyz, v_world, omega_world, q, qd
    /// (the arguments of `EempController.step`).
    fn state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
        let s = self.lock(py).ground_truth_state();
        let b = &s.body;
        let q = b.r_world_body.coords;
        let d = pyo3::types::PyDict::new(py);
        d.set_item("time_s", s.time_s)?;
        d.set_item("p_world", PyArray1::from_slice(py, b.p_world.as_slice()))?;
        d.set_item(
            "quat_wxyz",
            PyArray1::from_vec(py, vec![q.w, q.x, q.y, q.z]),
        )?;
        d.set_item("v_world", PyArray1::from_slice(py, b.v_world.as_slice()))?;
        d.set_item(
            "omega_world",
            PyArray1::from_slice(py, b.omega_world.as_slice()),
        )?;
        d.set_item("q", PyArray1::from_vec(py, flat(&s.joints.map(|_, j| j.q))))?;
        d.set_item(
            "qd",
            PyArray1::from_vec(py, flat(&s.joints.map(|_, j| j.qd))),
        )?;
        Ok(d)
    }
}

/// A walk under EEMP in the project's scenario and metrics (what `eemp walk` runs); returns
/// its summary as JSON text (the Python side makes it a dict).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (gait = "trot", speed = 0.3, duration_s = 20.0, seed = 0, lateral = 0.0, yaw_rate = 0.0, params = None, params_table = None, estimator = "ground-truth", robot = None, table_ii = false, settings = Vec::new()))]
pub fn walk_json(
    py: Python<'_>,
    gait: &str,
    speed: f64,
    duration_s: f64,
    seed: u64,
    lateral: f64,
    yaw_rate: f64,
    params: Option<PathBuf>,
    params_table: Option<PathBuf>,
    estimator: &str,
    robot: Option<PathBuf>,
    table_ii: bool,
    settings: Vec<String>,
) -> PyResult<String> {
    // Python's names for the values Python users give.
    if !(duration_s.is_finite() && duration_s > 0.0 && duration_s <= 3600.0) {
        return Err(value_error(format!(
            "duration_s {duration_s} is out of range: allowed (0, 3600]"
        )));
    }
    let built = WalkDescription {
        speed_mps: speed,
        lateral_mps: lateral,
        yaw_rate_rps: yaw_rate,
        duration_s,
        sensing: Sensing {
            estimator: estimator.into(),
            seed,
            ..Default::default()
        },
        ..eemp_walk(
            gait,
            params,
            params_table,
            table_ii,
            robot,
            settings.clone(),
        )
    }
    .build()
    .map_err(value_error)?;
    let params_table = built
        .params_table_path
        .as_ref()
        .map(|p| p.display().to_string());
    let run = py.detach(|| built.run(|_| {})).map_err(value_error)?;
    let (m, st) = (&run.metrics, &run.stats);
    Ok(serde_json::json!({
        "gait": gait,
        "speed_mps": speed,
        "estimator": estimator,
        "params_table": params_table,
        // The controller settings given (`eemp walk --set`), applied over the defaults.
        "settings": settings,
        "duration_s": st.sim_time_s,
        "fell": st.fell,
        "fell_at_s": st.fell_at_s,
        "distance_m": m.distance_m,
        "energy_j": m.energy_j,
        "cot": m.cot,
        "cot_j_per_m": m.cot_j_per_m,
        // The battery's figures under the robot file's motor model (`cot` is eq. 8's).
        "electrical": m.electrical,
        "electrical_note": m.electrical_note,
        "manipulability": m.manipulability,
        "vel_rmse_mps": m.vel_rmse_mps,
        "steps_total": run.steps.0.iter().sum::<usize>(),
        "realtime_factor": st.realtime_factor(),
        "mpc_solves": st.mpc_solves,
        "mpc_failures": st.mpc_failures,
        "estimation_vel_rmse_mps": run.estimation.vel_rmse_mps(),
    })
    .to_string())
}
