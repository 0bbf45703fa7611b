//! Newton-Krylov on a [`System`]: [`NewtonSolver`] is the one Newton driver
//! ([`crate::statics::newton::solve_with`]) over matrix-free conjugate gradients
//! ([`crate::statics::newton::MatrixFree`]: tangent products by central differences of the
//! forces, preconditioned by a per-node diagonal), with a stopping rule relative to the start
//! ([`crate::statics::newton::DirectNewtonParams::relative_to_start`]) and a report in
//! 2-norms: the convenient front for reference solves and tests, whatever forces the model
//! carries. It has no iteration of its own.
//!
//! [`NewtonParams`] mean what they meant: the solve stops where `‖V − R(u)‖₂ ≤ rel_tol ×
//! max(‖V − R(u₀)‖₂, ‖V‖₂)`, `u₀` the start with the constraints imposed
//! ([`crate::statics::newton::StopNorm::Two`]); each linear solve goes to `cg_tol` of its
//! right-hand side; it stops where [`STALL_AFTER`] iterations in a row each lower the residual
//! by less than a tenth (stagnation at the finite difference's floor). The line search (Armijo on the potential, the residual where it is flat,
//! the curvature condition) and the lifted first iteration are the driver's.

use crate::fem::ElementFailure;
use crate::integrate::System;
use crate::statics::newton::{
    solve_with, DirectNewtonError, DirectNewtonParams, MatrixFree, MatrixFreeCg,
};

/// Consecutive Newton iterations that lower the residual by less than a tenth before
/// [`NewtonSolver::solve`] stops ([`DirectNewtonParams::stall_after`]): the finite-difference
/// tangent's floor, about 1e-8 of the force scale.
pub const STALL_AFTER: usize = 3;

/// Settings of [`NewtonSolver::solve`] (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NewtonParams {
    /// Stop when ‖V − R(u)‖₂ ≤ `rel_tol` × max(‖V − R(u0)‖₂, ‖V‖₂). Default 1e-7.
    pub rel_tol: f64,
    /// Newton iterations at most. Default 50.
    pub max_newton: usize,
    /// CG iterations per Newton step at most ([`MatrixFreeCg::max_iter`]). Default 20000.
    pub max_cg: usize,
    /// Each linear solve's relative residual ([`MatrixFreeCg::tolerance`]). Default 1e-4.
    pub cg_tol: f64,
    /// Displacement scale for the finite-difference step ([`MatrixFreeCg::length`], m).
    /// Default 1e-3.
    pub length: f64,
    /// The load factor of the loads the model carries, the external forces and the prescribed
    /// motions ([`DirectNewtonParams::load_factor`]); the model is set to it before the
    /// start's residual and left at it. Default 1.
    pub load_factor: f64,
}

impl Default for NewtonParams {
    fn default() -> Self {
        NewtonParams {
            rel_tol: 1e-7,
            max_newton: 50,
            max_cg: 20_000,
            cg_tol: 1e-4,
            length: 1e-3,
            load_factor: 1.0,
        }
    }
}

/// What a static solve reports: residuals, Newton steps, force evaluations, convergence.
#[derive(Clone, Debug)]
pub struct Static {
    /// Final residual norm ‖V − R(u)‖₂ over free dofs (N).
    pub residual: f64,
    /// Residual norm at the start (N).
    pub initial_residual: f64,
    /// Newton steps taken.
    pub newton_steps: usize,
    /// Force evaluations spent (2 per CG product, plus residuals).
    pub force_evaluations: u64,
    /// Whether the stopping rule held.
    pub converged: bool,
}

/// Newton with matrix-free conjugate gradients on a [`System`] (module docs): the
/// preconditioner's diagonal.
pub struct NewtonSolver {
    diag: Vec<f64>,
}

impl NewtonSolver {
    /// CG preconditioned by the lumped mass.
    pub fn new(sys: &System) -> Self {
        Self::with_diagonal(sys, &sys.mass)
    }

    /// CG preconditioned by a per-node diagonal `diag` (e.g.
    /// [`crate::statics::relax::fictitious_mass`]).
    pub fn with_diagonal(_sys: &System, diag: &[f64]) -> Self {
        NewtonSolver {
            diag: diag.to_vec(),
        }
    }

    /// Solve for `u` in place (constraints imposed at time `t`).
    pub fn solve(
        &mut self,
        sys: &mut System,
        t: f64,
        u: &mut [f64],
        params: NewtonParams,
    ) -> Result<Static, ElementFailure> {
        sys.force.set_load_factor(params.load_factor);
        let driver = DirectNewtonParams {
            max_newton: params.max_newton,
            load_factor: params.load_factor,
            stall_after: STALL_AFTER,
            ..DirectNewtonParams::relative_to_start(sys, t, u, params.rel_tol)?
        };
        let cg = MatrixFreeCg {
            max_iter: params.max_cg,
            length: params.length,
            tolerance: Some(params.cg_tol),
        };
        let System {
            force,
            mass,
            f_ext,
            constraints,
            springs,
            ..
        } = &mut *sys;
        let mut lin = MatrixFree::with_diagonal(mass, &self.diag, constraints, cg);
        let out = solve_with(
            &mut lin,
            &mut **force,
            springs,
            constraints,
            f_ext,
            t,
            u,
            driver,
        )
        .map_err(|e| match e {
            DirectNewtonError::Inverted(f) => f,
            // The matrix-free solve factors nothing and allocates no factor: only an
            // inverted element ends it.
            _ => ElementFailure {
                element: 0,
                det_f: f64::NAN,
            },
        })?;
        Ok(Static {
            residual: out.residual,
            initial_residual: out.initial_residual,
            newton_steps: out.newton_steps,
            force_evaluations: out.force_evaluations + 1,
            converged: out.converged,
        })
    }
}
