//! The QP solvers the MPC can use. Both solve
//!   minimise ½ xᵀ P x + qᵀ x   subject to   G₁ x = h₁ (the first `meq` rows),  G₂ x ≤ h₂
//! with P dense symmetric positive definite (row-major, n×n) and G dense (row-major, m×n).

use serde::{Deserialize, Serialize};

/// Which QP solver the MPC calls.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum QpSolverKind {
    /// Dense dual active-set method of Goldfarb & Idnani (crate `quadprog`). Starts from the
    /// unconstrained optimum and adds violated constraints, so a standing robot far from its
    /// friction limits solves in one Cholesky factorisation.
    #[default]
    Quadprog,
    /// Interior-point conic solver (crate `clarabel`), sparse LDLᵀ.
    Clarabel,
}

impl std::str::FromStr for QpSolverKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "quadprog" => Ok(QpSolverKind::Quadprog),
            "clarabel" => Ok(QpSolverKind::Clarabel),
            other => Err(format!(
                "unknown QP solver '{other}': allowed quadprog, clarabel"
            )),
        }
    }
}

/// Why a QP solve failed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum QpError {
    #[error("QP is infeasible")]
    Infeasible,
    #[error("QP Hessian is not positive definite")]
    NotPositiveDefinite,
    #[error("QP solver stopped without a solution: {0}")]
    NotConverged(String),
    #[error("QP solution contains NaN or infinity")]
    NonFinite,
    #[error("QP data is malformed: {0}")]
    Malformed(String),
}

/// A solved QP: the minimiser and how many iterations it took (active-set additions for
/// quadprog, interior-point iterations for clarabel).
#[derive(Clone, Debug, PartialEq)]
pub struct QpSolution {
    pub x: Vec<f64>,
    pub iterations: usize,
}

/// Solves the QP with the chosen solver. `p` is consumed as scratch space.
pub fn solve(
    kind: QpSolverKind,
    p: &mut [f64],
    q: &[f64],
    g: &[f64],
    h: &[f64],
    meq: usize,
) -> Result<QpSolution, QpError> {
    if meq > h.len() {
        return Err(QpError::Malformed(format!(
            "meq {meq} exceeds the {} constraint rows",
            h.len()
        )));
    }
    let solution = match kind {
        QpSolverKind::Quadprog => solve_quadprog(p, q, g, h, meq),
        QpSolverKind::Clarabel => solve_clarabel(p, q, g, h, meq),
    }?;
    if solution.x.iter().all(|v| v.is_finite()) {
        Ok(solution)
    } else {
        Err(QpError::NonFinite)
    }
}

fn solve_quadprog(
    p: &mut [f64],
    q: &[f64],
    g: &[f64],
    h: &[f64],
    meq: usize,
) -> Result<QpSolution, QpError> {
    match quadprog::solve_qp(p, q, g, h, meq, false) {
        Ok(sol) => Ok(QpSolution {
            x: sol.sol,
            iterations: sol.iter,
        }),
        Err(quadprog::Error::Infeasible) => Err(QpError::Infeasible),
        Err(quadprog::Error::NotPositiveDefinite) => Err(QpError::NotPositiveDefinite),
        Err(e) => Err(QpError::Malformed(e.to_string())),
    }
}

fn solve_clarabel(
    p: &[f64],
    q: &[f64],
    g: &[f64],
    h: &[f64],
    meq: usize,
) -> Result<QpSolution, QpError> {
    use clarabel::algebra::CscMatrix;
    use clarabel::solver::{
        DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
    };
    let n = q.len();
    let m = h.len();
    // Upper triangle of P, column by column.
    let (mut colptr, mut rowval, mut nzval) = (vec![0usize], Vec::new(), Vec::new());
    for j in 0..n {
        for i in 0..=j {
            let v = p[i * n + j];
            if v != 0.0 {
                rowval.push(i);
                nzval.push(v);
            }
        }
        colptr.push(rowval.len());
    }
    let p_csc = CscMatrix::new(n, n, colptr, rowval, nzval);
    let (mut colptr, mut rowval, mut nzval) = (vec![0usize], Vec::new(), Vec::new());
    for j in 0..n {
        for i in 0..m {
            let v = g[i * n + j];
            if v != 0.0 {
                rowval.push(i);
                nzval.push(v);
            }
        }
        colptr.push(rowval.len());
    }
    let g_csc = CscMatrix::new(m, n, colptr, rowval, nzval);
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .max_iter(50)
        .presolve_enable(false)
        .build()
        .map_err(|e| QpError::Malformed(e.to_string()))?;
    let mut cones = Vec::with_capacity(2);
    if meq > 0 {
        cones.push(SupportedConeT::ZeroConeT(meq));
    }
    if m > meq {
        cones.push(SupportedConeT::NonnegativeConeT(m - meq));
    }
    let mut solver = DefaultSolver::new(&p_csc, q, &g_csc, h, &cones, settings)
        .map_err(|e| QpError::Malformed(e.to_string()))?;
    solver.solve();
    match solver.solution.status {
        SolverStatus::Solved | SolverStatus::AlmostSolved => Ok(QpSolution {
            x: solver.solution.x.clone(),
            iterations: solver.solution.iterations as usize,
        }),
        SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible => {
            Err(QpError::Infeasible)
        }
        other => Err(QpError::NotConverged(format!("{other:?}"))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    /// min (x−3)² + (y−2)² s.t. x + y ≤ 4, x ≥ 0: optimum (2.5, 1.5) by hand (project onto x+y=4).
    #[test]
    fn both_solvers_find_the_hand_worked_optimum() {
        for kind in [QpSolverKind::Quadprog, QpSolverKind::Clarabel] {
            let mut p = vec![2.0, 0.0, 0.0, 2.0];
            let q = [-6.0, -4.0];
            let g = [1.0, 1.0, -1.0, 0.0];
            let h = [4.0, 0.0];
            let sol = solve(kind, &mut p, &q, &g, &h, 0).unwrap();
            assert_relative_eq!(sol.x[0], 2.5, epsilon = 1e-6);
            assert_relative_eq!(sol.x[1], 1.5, epsilon = 1e-6);
        }
    }

    /// min x² + y² s.t. x + y = 2 (equality), y ≤ 0.5: optimum (1.5, 0.5).
    #[test]
    fn equality_rows_are_honoured() {
        for kind in [QpSolverKind::Quadprog, QpSolverKind::Clarabel] {
            let mut p = vec![2.0, 0.0, 0.0, 2.0];
            let sol = solve(
                kind,
                &mut p,
                &[0.0, 0.0],
                &[1.0, 1.0, 0.0, 1.0],
                &[2.0, 0.5],
                1,
            )
            .unwrap();
            assert_relative_eq!(sol.x[0], 1.5, epsilon = 1e-6);
            assert_relative_eq!(sol.x[1], 0.5, epsilon = 1e-6);
        }
    }

    #[test]
    fn infeasible_problems_are_reported_not_panicked() {
        for kind in [QpSolverKind::Quadprog, QpSolverKind::Clarabel] {
            let mut p = vec![1.0];
            // x ≤ −1 and −x ≤ −1 (x ≥ 1).
            let res = solve(kind, &mut p, &[0.0], &[1.0, -1.0], &[-1.0, -1.0], 0);
            assert!(res.is_err(), "{kind:?} gave {res:?}");
        }
    }
}
