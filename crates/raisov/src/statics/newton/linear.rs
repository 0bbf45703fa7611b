//! Linear solves with the assembled tangent outside Newton's iteration: `K_FF x_j = b_j` for
//! a few right-hand sides at one state (the grasp stiffness of [`crate::sim`]), with the Newton
//! driver's own operator — the element blocks, the model's blocks beyond them
//! ([`ForceModel::add_extra_tangent`]) and the springs' `k I` — and its preconditioners: the
//! sparse Cholesky factor of `K_FF` (exact to rounding), or conjugate gradients preconditioned
//! by the Galerkin V-cycle over [`DirectNewton::with_levels`]' levels.

use super::*;

/// How [`DirectNewton::tangent_solves`] solves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TangentSolver {
    /// Sparse Cholesky of `K_FF`, factored once per call.
    Direct,
    /// Conjugate gradients from the given start, preconditioned by one Galerkin V-cycle
    /// (built once per call), to a residual of `tol ‖b‖₂`, at most `max_iter` iterations.
    Multigrid {
        /// Relative residual.
        tol: f64,
        /// Iterations at most per right-hand side.
        max_iter: usize,
        /// The V-cycle's smoother.
        smoother: Smoother,
    },
}

/// The work of one [`DirectNewton::tangent_solves`].
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct TangentSolves {
    /// Conjugate-gradient iterations, all right-hand sides together (0 for the direct solve).
    pub iterations: usize,
    /// Factorisations or Galerkin hierarchies built.
    pub setups: usize,
}

impl DirectNewton {
    /// Assemble `K(u)` of `model` plus the `springs`' `k I` on the pattern, then solve
    /// `K_FF x_j = b_j` over the free dofs for each pair `(b_j, x_j)` of `columns` (all dofs'
    /// layout; `b_j`'s constrained entries are ignored, `x_j` is the start of an iterative
    /// solve and its constrained entries are set to zero).
    ///
    /// Errors: an element the tangent cannot be evaluated at ([`DirectNewtonError::Inverted`]);
    /// a tangent that is not positive definite (a factorisation that fails, or conjugate
    /// gradients meeting a direction of non-positive curvature: [`DirectNewtonError::Factor`]);
    /// a factor or hierarchy too large for the memory ([`DirectNewtonError::Memory`]). An
    /// iterative solve that reaches `max_iter` keeps its iterate; the iterations say so.
    pub fn tangent_solves(
        &mut self,
        model: &dyn ForceModel,
        springs: &[Spring],
        u: &[f64],
        columns: &mut [(&[f64], &mut [f64])],
        solver: TangentSolver,
    ) -> Result<TangentSolves, DirectNewtonError> {
        self.assemble(model, springs, u, None)
            .map_err(DirectNewtonError::Inverted)?;
        let nf = self.dofs.nfree;
        let mut out = TangentSolves::default();
        let mut b = vec![0.0; nf];
        let mut x = vec![0.0; nf];
        match solver {
            TangentSolver::Direct => {
                self.prepare_factor()?;
                for (j, (bj, xj)) in columns.iter_mut().enumerate() {
                    self.dofs.gather(bj, &mut b);
                    self.dofs.project_free(&mut b);
                    if j == 0 {
                        self.factor_solve(0.0, &mut b).map_err(|e| {
                            DirectNewtonError::Factor(format!(
                                "the tangent is not positive definite at this state ({e})"
                            ))
                        })?;
                        out.setups += 1;
                    } else {
                        self.apply_factor(&mut b);
                    }
                    self.dofs.scatter(&b, xj);
                }
                // The factor of this state is not a Newton iteration's: drop it.
                self.llt = None;
            }
            TangentSolver::Multigrid {
                tol,
                max_iter,
                smoother,
            } => {
                let scatter = self.scatter.get_or_insert_with(|| {
                    SymScatter::new(nf, self.symbolic.col_ptr(), self.symbolic.row_idx())
                });
                let mut a = scatter.pattern.clone();
                scatter.fill(&self.vals, &mut a);
                let mg = self.hierarchy(a, MultigridPcg::default().sweeps, smoother)?;
                out.setups += 1;
                for (bj, xj) in columns.iter_mut() {
                    self.dofs.gather(bj, &mut b);
                    self.dofs.gather(xj, &mut x);
                    self.dofs.project_free(&mut b);
                    self.dofs.project_free(&mut x);
                    let bnorm = b.iter().map(|v| v * v).sum::<f64>().sqrt();
                    let end = pcg_from(
                        |p, q| mg.matrix().matvec(p, q),
                        |r, z| mg.apply(r, z),
                        &b,
                        &mut x,
                        true,
                        tol * bnorm,
                        max_iter,
                        None,
                    );
                    match end {
                        PcgEnd::Converged(it) | PcgEnd::Truncated(it) => out.iterations += it,
                        PcgEnd::MaxIter => out.iterations += max_iter,
                        PcgEnd::Negative(..) | PcgEnd::Breakdown(_) => {
                            return Err(DirectNewtonError::Factor(
                                "the tangent is not positive definite at this state \
                                 (conjugate gradients met a direction of non-positive \
                                 curvature)"
                                    .into(),
                            ))
                        }
                    }
                    self.dofs.scatter(&x, xj);
                }
            }
        }
        Ok(out)
    }

    /// Whether dof `i` is free.
    pub fn is_free(&self, i: usize) -> bool {
        self.dofs.is_free(i)
    }
}
