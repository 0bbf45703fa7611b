//! Newton-Krylov on a [`System`]: [`NewtonSolver`] is the one Newton driver
//! ([`crate::statics::newton::solve_with`]) over matrix-free conjugate gradients
//! ([`crate::statics::newton::MatrixFree`]: tangent products by central differences of the
//! forces, preconditioned by a per-node diagonal), with a stopping rule relative to the start
//! ([`crate::statics::newton::DirectNewtonParams::relative_to_start`]) and a report in
//! 2-norms: the convenient front for reference solves and tests, whatever forces the model
//! carries. It has no iteration of its own.
//!
//! [`NewtonParams`]: the solve stops where the largest nodal residual is at most
//! `rel_tol × max(‖V − R(u₀)‖₂, ‖V‖₂)`, `u₀` the start with the constraints imposed (until
//! 0.2.0 the residual's 2-norm, at least the largest nodal norm, had to be); each linear solve
//! goes to the driver's Eisenstat-Walker tolerance (`cg_tol` is no longer used); the line
//! search and the lifted first iteration are the driver's.

use crate::fem::ElementFailure;
use crate::integrate::System;
use crate::statics::newton::{
    solve_with, DirectNewtonError, DirectNewtonParams, MatrixFree, MatrixFreeCg,
};

/// Settings of [`NewtonSolver::solve`] (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NewtonParams {
    /// Stop when the largest nodal residual is at most `rel_tol` × max(‖V − R(u0)‖₂, ‖V‖₂).
    /// Default 1e-7.
    pub rel_tol: f64,
    /// Newton iterations at most. Default 50.
    pub max_newton: usize,
    /// CG iterations per Newton step at most ([`MatrixFreeCg::max_iter`]). Default 20000.
    pub max_cg: usize,
    /// No longer used (module docs). Default 1e-4.
    pub cg_tol: f64,
    /// Displacement scale for the finite-difference step ([`MatrixFreeCg::length`], m).
    /// Default 1e-3.
    pub length: f64,
}

impl Default for NewtonParams {
    fn default() -> Self {
        NewtonParams {
            rel_tol: 1e-7,
            max_newton: 50,
            max_cg: 20_000,
            cg_tol: 1e-4,
            length: 1e-3,
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
        let driver = DirectNewtonParams {
            max_newton: params.max_newton,
            ..DirectNewtonParams::relative_to_start(sys, t, u, params.rel_tol)?
        };
        let r0 = sys.residual(u, &mut vec![0.0; u.len()])?;
        let cg = MatrixFreeCg {
            max_iter: params.max_cg,
            length: params.length,
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
        let residual = sys.residual(u, &mut vec![0.0; u.len()])?;
        Ok(Static {
            residual,
            initial_residual: r0,
            newton_steps: out.newton_steps,
            force_evaluations: out.force_evaluations + 3,
            converged: out.converged,
        })
    }
}
