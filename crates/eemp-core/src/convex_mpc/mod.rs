//! Convex MPC on ground-reaction forces (Di Carlo et al. 2018), the stance controller of the
//! paper's eq. (2): forces f over a horizon minimise body-state tracking error plus force effort
//! under the single-rigid-body model, subject to the friction pyramid and 0 ≤ f_min ≤ f_z ≤ f_max,
//! with forces only on feet in contact. The first step's forces are applied as τ = −Jᵀ Rᵀ f
//! (see [`crate::leg_control`]).

mod condense;
pub mod model;
pub mod qp_backend;

use crate::body_reference::BodyReference;
use crate::body_state::BodyState;
use crate::config_error::{check_range, ConfigError};
use crate::leg::{Leg, LegMap};
use crate::robot::CompositeBody;
use model::{InputMatrix, StateVector, GRAVITY, NU};
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
pub use qp_backend::{QpError, QpSolverKind};
use serde::{Deserialize, Serialize};

/// Allowed friction coefficients of the pyramid (config and [`ConvexMpc::set_friction_coefficient`]).
pub use crate::robot::FRICTION_RANGE;

/// MPC settings. Weights are on squared errors summed over the horizon.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MpcConfig {
    /// Number of prediction steps (default 10).
    pub horizon: usize,
    /// Prediction step, s (default 0.025: 10 steps look 0.25 s ahead, one swing).
    pub dt_s: f64,
    /// Friction coefficient of the pyramid constraints (below the real floor's, for margin).
    pub friction_coefficient: f64,
    /// Lower bound on the normal force of a foot in contact, N.
    pub f_min_n: f64,
    /// Upper bound on the normal force of a foot in contact, N. None: the robot file's
    /// `control.mpc_f_max_n`, else the vertical force one leg holds at the standing pose within
    /// its joints' torque limits (`RobotConfig::mpc_f_max_n`; `LocomotionController::new` fills
    /// it).
    pub f_max_n: Option<f64>,
    /// Weights on roll, pitch, yaw errors (1/rad²).
    pub weight_rpy: [f64; 3],
    /// Weights on position errors (1/m²).
    pub weight_position: [f64; 3],
    /// Weights on angular-velocity errors (s²/rad²).
    pub weight_omega: [f64; 3],
    /// Weights on linear-velocity errors (s²/m²).
    pub weight_velocity: [f64; 3],
    /// Weight on every squared force component (1/N²).
    pub weight_force: f64,
    /// Weight on the stance legs' Joule heat per horizon step (1/W): each force's heat with
    /// its components taken apart in the trunk frame ([`heat_matrix_decoupled`]; K the robot
    /// file's heat coefficients, J the leg Jacobian at the solve's configuration). 0: off (the paper's
    /// force-norm cost alone); needs a robot file with `[motor]`. `None`: the robot file's
    /// `[control] mpc_weight_heat`, else 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weight_heat: Option<f64>,
    pub solver: QpSolverKind,
    /// Leave the force variables of feet out of contact out of the QP (smaller problem) instead
    /// of bounding them to zero.
    pub drop_swing_forces: bool,
    /// Move blocking: from step `force_hold_start` on, each foot's force is held over runs of
    /// up to this many horizon steps with the same contact, one QP variable per run
    /// ([`force_blocks`]). 1: a force per step (the paper's eq. 2).
    pub force_hold_steps: usize,
    /// The first horizon step whose force may be held with the next ones; the steps before it
    /// keep a force each (step 0's is the one applied).
    pub force_hold_start: usize,
}

impl Default for MpcConfig {
    fn default() -> Self {
        MpcConfig {
            horizon: 10,
            dt_s: 0.025,
            friction_coefficient: 0.6,
            f_min_n: 0.0,
            f_max_n: None,
            // The MIT Cheetah ratios (×10): light roll/pitch, heavy height and yaw, no roll/pitch
            // rate term. Heavier roll/pitch weights made the trot sway laterally until it fell
            // (the MPC gave up lateral velocity to hold attitude on two diagonal feet).
            weight_rpy: [2.5, 2.5, 100.0],
            weight_position: [20.0, 20.0, 500.0],
            weight_omega: [0.0, 0.0, 3.0],
            weight_velocity: [2.0, 2.0, 1.0],
            weight_force: 1e-5,
            weight_heat: None,
            solver: QpSolverKind::Quadprog,
            drop_swing_forces: true,
            force_hold_steps: 1,
            force_hold_start: 2,
        }
    }
}

impl MpcConfig {
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range("mpc.horizon", self.horizon as f64, 1.0, 40.0)?;
        check_range("mpc.dt_s", self.dt_s, 0.002, 0.1)?;
        check_range(
            "mpc.friction_coefficient",
            self.friction_coefficient,
            FRICTION_RANGE[0],
            FRICTION_RANGE[1],
        )?;
        check_range("mpc.f_min_n", self.f_min_n, 0.0, 1000.0)?;
        if let Some(f) = self.f_max_n {
            check_range("mpc.f_max_n", f, self.f_min_n.max(1.0), 5000.0)?;
        }
        for (name, w) in [
            ("mpc.weight_rpy", self.weight_rpy),
            ("mpc.weight_position", self.weight_position),
            ("mpc.weight_omega", self.weight_omega),
            ("mpc.weight_velocity", self.weight_velocity),
        ] {
            for (i, v) in w.iter().enumerate() {
                check_range(&format!("{name}[{i}]"), *v, 0.0, 1e6)?;
            }
        }
        check_range("mpc.weight_force", self.weight_force, 1e-12, 1.0)?;
        check_range(
            "mpc.force_hold_steps",
            self.force_hold_steps as f64,
            1.0,
            self.horizon as f64,
        )?;
        check_range(
            "mpc.force_hold_start",
            self.force_hold_start as f64,
            1.0,
            self.horizon as f64,
        )?;
        if let Some(w) = self.weight_heat {
            check_range("mpc.weight_heat", w, 0.0, 1.0)?;
        }
        Ok(())
    }

    fn state_weights(&self) -> StateVector {
        let mut q = StateVector::zeros();
        for i in 0..3 {
            q[i] = self.weight_rpy[i];
            q[3 + i] = self.weight_position[i];
            q[6 + i] = self.weight_omega[i];
            q[9 + i] = self.weight_velocity[i];
        }
        q
    }
}

/// What the MPC is asked at one solve. All slices have one entry per horizon step
/// (step k covers time t + k·dt … t + (k+1)·dt; the reference is for the state at its end).
#[derive(Clone, Copy, Debug)]
pub struct MpcInput<'a> {
    pub body: &'a BodyState,
    pub reference: &'a [BodyReference],
    /// Foot positions (world frame, m) during each step.
    pub feet_world: &'a [LegMap<Vector3<f64>>],
    /// Which feet may push during each step (the contact schedule C_ref).
    pub contacts: &'a [LegMap<bool>],
    /// Per foot, the Joule heat a world-frame force f costs, fᵀ M f in W (M = R J K Jᵀ Rᵀ,
    /// [`heat_matrix`]), weighed by `weight_heat`; `None`: no heat term.
    pub heat: Option<&'a LegMap<Matrix3<f64>>>,
}

/// The heat the MPC charges a leg: the diagonal of the heat matrix in the trunk frame, J K Jᵀ,
/// turned back to the world frame: R diag(J K Jᵀ) Rᵀ (W/N²). Each component of the force along
/// the trunk's axes pays the heat of the torques that carry it; the cross terms are left out
/// because they pay the QP to lean each leg's force along the leg (an inward squeeze between
/// the feet, which costs no trunk motion), trading torque for friction, and the friction a
/// floor gives is what slip handling only learns by slipping. Taken in the trunk frame, so the
/// same gait is charged the same whatever its heading.
pub fn heat_matrix_decoupled(
    jacobian_body: &Matrix3<f64>,
    r_world_body: &nalgebra::UnitQuaternion<f64>,
    heat_coefficient_w_per_nm2: &[f64; 3],
) -> Matrix3<f64> {
    let k = Matrix3::from_diagonal(&Vector3::from(*heat_coefficient_w_per_nm2));
    let body = Matrix3::from_diagonal(&(jacobian_body * k * jacobian_body.transpose()).diagonal());
    let r = r_world_body.to_rotation_matrix();
    r.matrix() * body * r.matrix().transpose()
}

/// The heat matrix M of one leg: a ground force `f_world` on its foot is held by the joint
/// torques τ = −Jᵀ Rᵀ f, whose Joule heat Σⱼ kⱼ τⱼ² is fᵀ M f with M = R J K Jᵀ Rᵀ (W/N²).
pub fn heat_matrix(
    jacobian_body: &Matrix3<f64>,
    r_world_body: &nalgebra::UnitQuaternion<f64>,
    heat_coefficient_w_per_nm2: &[f64; 3],
) -> Matrix3<f64> {
    let rj = r_world_body.to_rotation_matrix().matrix() * jacobian_body;
    let k = Matrix3::from_diagonal(&Vector3::from(*heat_coefficient_w_per_nm2));
    rj * k * rj.transpose()
}

/// How a solve ended.
#[derive(Clone, Debug, PartialEq)]
pub enum MpcStatus {
    Solved,
    /// The QP failed; the last good forces were reused (feet no longer in contact get zero).
    FallbackLastGood(QpError),
    /// The QP failed and there were no good forces yet: static weight distribution.
    FallbackStatic(QpError),
}

impl MpcStatus {
    pub fn is_solved(&self) -> bool {
        matches!(self, MpcStatus::Solved)
    }
}

/// Ground-reaction forces for the first step (world frame, force of the ground on each foot, N).
#[derive(Clone, Debug, PartialEq)]
pub struct MpcSolution {
    pub forces_world: LegMap<Vector3<f64>>,
    pub status: MpcStatus,
    /// Solver iterations (see [`qp_backend::QpSolution`]).
    pub iterations: usize,
    /// Number of QP variables and constraints.
    pub qp_size: (usize, usize),
}

/// The MPC with its workspace. One per robot; no global state.
#[derive(Clone)]
pub struct ConvexMpc {
    /// [`MpcConfig::f_max_n`] as resolved, N.
    f_max_n: f64,
    config: MpcConfig,
    body: CompositeBody,
    last_good: Option<LegMap<Vector3<f64>>>,
    // Workspace, reused across solves.
    b: Vec<InputMatrix>,
    refs: Vec<StateVector>,
    h_full: DMatrix<f64>,
    g_full: DVector<f64>,
}

impl ConvexMpc {
    pub fn new(config: MpcConfig, body: CompositeBody) -> Result<Self, ConfigError> {
        config.validate()?;
        let f_max_n = config.f_max_n.ok_or_else(|| ConfigError::Invalid {
            name: "mpc.f_max_n".into(),
            message: "is unset: the robot's bound fills it (LocomotionController::new)".into(),
        })?;
        let n = config.horizon;
        Ok(ConvexMpc {
            f_max_n,
            body,
            last_good: None,
            b: Vec::with_capacity(n),
            refs: Vec::with_capacity(n),
            h_full: DMatrix::zeros(n * NU, n * NU),
            g_full: DVector::zeros(n * NU),
            config,
        })
    }

    pub fn config(&self) -> &MpcConfig {
        &self.config
    }

    /// The friction coefficient of the pyramid now.
    pub fn friction_coefficient(&self) -> f64 {
        self.config.friction_coefficient
    }

    /// Changes the pyramid's friction coefficient for the next solves (a floor found less grippy
    /// than assumed, the `slip` module); clamped to the configured range.
    pub fn set_friction_coefficient(&mut self, mu: f64) {
        self.config.friction_coefficient = mu.clamp(FRICTION_RANGE[0], FRICTION_RANGE[1]);
    }

    pub fn body(&self) -> &CompositeBody {
        &self.body
    }

    /// Solves for the ground-reaction forces. Never panics on bad numbers: a non-finite input or
    /// a failed QP gives a fallback with the reason in the status.
    pub fn solve(&mut self, input: &MpcInput) -> MpcSolution {
        let n = self.config.horizon;
        let contacts_now = input
            .contacts
            .first()
            .copied()
            .unwrap_or(LegMap::splat(false));
        if input.reference.len() != n || input.feet_world.len() != n || input.contacts.len() != n {
            return self.fallback(
                QpError::Malformed(format!("inputs must have {n} horizon steps")),
                input,
                contacts_now,
            );
        }
        let inputs_finite = input.body.is_finite()
            && input.reference.iter().all(|r| {
                r.rpy
                    .iter()
                    .chain(r.p_world.iter())
                    .chain(r.omega_world.iter())
                    .chain(r.v_world.iter())
                    .all(|v| v.is_finite())
            })
            && input
                .feet_world
                .iter()
                .all(|f| f.0.iter().all(|p| p.iter().all(|v| v.is_finite())));
        if !inputs_finite {
            return self.fallback(
                QpError::Malformed("non-finite state, reference or foot position".into()),
                input,
                contacts_now,
            );
        }

        self.condense_horizon(input);

        let blocks = force_blocks(
            input.contacts,
            self.config.force_hold_start,
            self.config.force_hold_steps,
            self.config.drop_swing_forces,
        );
        let nv = blocks.len() * 3;
        if nv == 0 {
            // No foot may push anywhere on the horizon: zero force is the only feasible answer.
            return MpcSolution {
                forces_world: LegMap::splat(Vector3::zeros()),
                status: MpcStatus::Solved,
                iterations: 0,
                qp_size: (0, 0),
            };
        }
        // A variable held over several steps collects their terms: P = Tᵀ H T, q = Tᵀ g, with T
        // the 0/1 map from the QP's variables to the horizon's forces.
        let full_index = |b: &ForceBlock, c: usize| {
            let (first, steps, col) = (b.first, b.steps, 3 * b.leg.index() + c);
            (first..first + steps).map(move |k| k * NU + col)
        };
        let mut p = vec![0.0; nv * nv];
        let mut q = vec![0.0; nv];
        for (bi, a) in blocks.iter().enumerate() {
            for ca in 0..3 {
                let i = 3 * bi + ca;
                q[i] = full_index(a, ca).map(|fi| self.g_full[fi]).sum();
                for (bj, b) in blocks.iter().enumerate() {
                    for cb in 0..3 {
                        p[i * nv + 3 * bj + cb] = full_index(a, ca)
                            .flat_map(|fi| full_index(b, cb).map(move |fj| (fi, fj)))
                            .map(|(fi, fj)| self.h_full[(fi, fj)])
                            .sum();
                    }
                }
            }
        }
        // The stance legs' heat, one 3×3 block per (step, foot in contact), as the caller gives
        // it ([`heat_matrix_decoupled`]). Still convex (each block is positive semi-definite).
        if let (Some(heat), Some(w)) = (input.heat, self.config.weight_heat) {
            if w > 0.0 {
                for (bi, b) in blocks.iter().enumerate().filter(|(_, b)| b.contact) {
                    // Held over `steps` steps, the force pays its heat at each.
                    let w = w * b.steps as f64;
                    for r in 0..3 {
                        for c in 0..3 {
                            p[(3 * bi + r) * nv + 3 * bi + c] += w * heat[b.leg][(r, c)];
                        }
                    }
                }
            }
        }
        // Feet out of contact (only present when their variables are kept): f = 0 as equality
        // rows, first, because a cone squeezed to a point is degenerate for an active-set method.
        // Feet in contact: friction pyramid (4 rows), f_z ≤ f_max, and f_z ≥ f_min when f_min > 0.
        let mu = self.config.friction_coefficient;
        let with_fmin = self.config.f_min_n > 0.0;
        let n_contact = blocks.iter().filter(|b| b.contact).count();
        let meq = 3 * (blocks.len() - n_contact);
        let m = meq + n_contact * if with_fmin { 6 } else { 5 };
        let mut g = vec![0.0; m * nv];
        let mut h = vec![0.0; m];
        let (mut r_eq, mut r_in) = (0, meq);
        for (bi, b) in blocks.iter().enumerate() {
            let (fx, fy, fz) = (3 * bi, 3 * bi + 1, 3 * bi + 2);
            if !b.contact {
                for col in [fx, fy, fz] {
                    g[r_eq * nv + col] = 1.0;
                    r_eq += 1;
                }
                continue;
            }
            for (col, sign) in [(fx, 1.0), (fx, -1.0), (fy, 1.0), (fy, -1.0)] {
                g[r_in * nv + col] = sign;
                g[r_in * nv + fz] = -mu;
                r_in += 1;
            }
            g[r_in * nv + fz] = 1.0;
            h[r_in] = self.f_max_n;
            r_in += 1;
            if with_fmin {
                g[r_in * nv + fz] = -1.0;
                h[r_in] = -self.config.f_min_n;
                r_in += 1;
            }
        }

        match qp_backend::solve(self.config.solver, &mut p, &q, &g, &h, meq) {
            Ok(sol) => {
                let mut forces = LegMap::splat(Vector3::zeros());
                for (bi, b) in blocks.iter().enumerate() {
                    if b.first == 0 {
                        forces[b.leg] =
                            Vector3::new(sol.x[3 * bi], sol.x[3 * bi + 1], sol.x[3 * bi + 2]);
                    }
                }
                self.last_good = Some(forces);
                MpcSolution {
                    forces_world: forces,
                    status: MpcStatus::Solved,
                    iterations: sol.iterations,
                    qp_size: (nv, m),
                }
            }
            Err(e) => {
                let mut s = self.fallback(e, input, contacts_now);
                s.qp_size = (nv, m);
                s
            }
        }
    }

    /// The eq. (2) cost over every step's forces, condensed: fills `h_full` and `g_full`
    /// (J = UᵀHU + 2gᵀU + const, [`condense`]).
    fn condense_horizon(&mut self, input: &MpcInput) {
        let n = self.config.horizon;
        let body = input.body;
        let rpy = body.rpy();
        let yaw = rpy.z;
        let dt = self.config.dt_s;
        let a = model::state_matrix(yaw, dt);
        let com_offset_world = body.r_world_body * self.body.com_body;

        self.b.clear();
        self.refs.clear();
        for k in 0..n {
            let r = &input.reference[k];
            let p_com = r.p_world + com_offset_world;
            let arms = LegMap::from_fn(|leg| input.feet_world[k][leg] - p_com).0;
            self.b.push(model::input_matrix(
                yaw,
                dt,
                self.body.mass_kg,
                &self.body.inertia_body,
                &arms,
            ));
            let mut x = StateVector::zeros();
            // Keep the reference yaw on the same branch as the measured yaw.
            let ref_yaw = yaw + wrap(r.rpy.z - yaw);
            x.fixed_rows_mut::<3>(0)
                .copy_from(&Vector3::new(r.rpy.x, r.rpy.y, ref_yaw));
            x.fixed_rows_mut::<3>(3).copy_from(&r.p_world);
            x.fixed_rows_mut::<3>(6).copy_from(&r.omega_world);
            x.fixed_rows_mut::<3>(9).copy_from(&r.v_world);
            x[12] = GRAVITY;
            self.refs.push(x);
        }
        let mut x0 = StateVector::zeros();
        x0.fixed_rows_mut::<3>(0).copy_from(&rpy);
        x0.fixed_rows_mut::<3>(3).copy_from(&body.p_world);
        x0.fixed_rows_mut::<3>(6).copy_from(&body.omega_world);
        x0.fixed_rows_mut::<3>(9).copy_from(&body.v_world);
        x0[12] = GRAVITY;

        condense::condense(
            &a,
            &self.b,
            &x0,
            &self.refs,
            &self.config.state_weights(),
            self.config.weight_force,
            &mut self.h_full,
            &mut self.g_full,
        );
    }

    fn fallback(&self, reason: QpError, input: &MpcInput, contacts: LegMap<bool>) -> MpcSolution {
        let (forces, status) = match &self.last_good {
            Some(last) => (
                LegMap::from_fn(|leg| {
                    if contacts[leg] {
                        last[leg]
                    } else {
                        Vector3::zeros()
                    }
                }),
                MpcStatus::FallbackLastGood(reason),
            ),
            None => (
                self.static_forces(input, contacts),
                MpcStatus::FallbackStatic(reason),
            ),
        };
        MpcSolution {
            forces_world: forces,
            status,
            iterations: 0,
            qp_size: (0, 0),
        }
    }

    /// Vertical forces that carry the weight with zero moment about the COM (minimum norm).
    pub fn static_forces(&self, input: &MpcInput, contacts: LegMap<bool>) -> LegMap<Vector3<f64>> {
        let legs: Vec<Leg> = Leg::ALL.into_iter().filter(|l| contacts[*l]).collect();
        let mut out = LegMap::splat(Vector3::zeros());
        if legs.is_empty() || !input.body.is_finite() {
            return out;
        }
        let com = input.body.p_world + input.body.r_world_body * self.body.com_body;
        let weight = self.body.mass_kg * GRAVITY;
        // Rows: Σ f_z = m g, Σ f_z (x − x_c) = 0, Σ f_z (y − y_c) = 0.
        let mut a = DMatrix::zeros(3, legs.len());
        for (j, leg) in legs.iter().enumerate() {
            let p = input.feet_world.first().map(|f| f[*leg]).unwrap_or(com);
            if !p.iter().all(|v| v.is_finite()) {
                return out;
            }
            a[(0, j)] = 1.0;
            a[(1, j)] = p.x - com.x;
            a[(2, j)] = p.y - com.y;
        }
        let rhs = DVector::from_vec(vec![weight, 0.0, 0.0]);
        let fz = a
            .clone()
            .pseudo_inverse(1e-9)
            .map(|pinv| pinv * rhs)
            .unwrap_or_else(|_| DVector::from_element(legs.len(), weight / legs.len() as f64));
        for (j, leg) in legs.iter().enumerate() {
            out[*leg] = Vector3::new(0.0, 0.0, fz[j].clamp(0.0, self.f_max_n));
        }
        out
    }
}

/// One foot's force held over `steps` horizon steps from `first`: one QP variable (3 components).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ForceBlock {
    pub leg: Leg,
    pub first: usize,
    pub steps: usize,
    /// Whether the foot may push over these steps (the same at each of them).
    pub contact: bool,
}

/// The QP's force variables (move blocking): per foot, a force for each step before
/// `hold_start` (step 0's is the one applied), then runs of up to `hold_steps` steps over which
/// the contact does not change; runs out of contact are left out when `drop_swing` is set.
/// Ordered by first step, then leg, so that `hold_steps` = 1 gives the unblocked problem of
/// eq. (2) exactly. Why hold forces: the dense QP's cost grows with the cube of its variables,
/// and forces late in the horizon, which are never applied, only need to be about right for
/// the first one to be. The steps before `hold_start` keep a force each because the near steps
/// shape the applied force most (measured: docs/notebook/2026-12-07-battery.md).
pub fn force_blocks(
    contacts: &[LegMap<bool>],
    hold_start: usize,
    hold_steps: usize,
    drop_swing: bool,
) -> Vec<ForceBlock> {
    let n = contacts.len();
    let hold = hold_steps.max(1);
    let mut blocks = Vec::new();
    for leg in Leg::ALL {
        let mut first = 0;
        while first < n {
            let contact = contacts[first][leg];
            let mut steps = 1;
            if first >= hold_start.max(1) {
                while steps < hold && first + steps < n && contacts[first + steps][leg] == contact {
                    steps += 1;
                }
            }
            if contact || !drop_swing {
                blocks.push(ForceBlock {
                    leg,
                    first,
                    steps,
                    contact,
                });
            }
            first += steps;
        }
    }
    blocks.sort_by_key(|b| (b.first, b.leg.index()));
    blocks
}

fn wrap(a: f64) -> f64 {
    (a + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI) - std::f64::consts::PI
}

#[cfg(test)]
mod tests;
