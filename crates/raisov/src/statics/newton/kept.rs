//! The tangent kept across solves: `K_k = K(u_k)` assembled once at a state `u_k` (the
//! elements, the model's blocks beyond them and the springs' `k I`, as a Newton iteration
//! assembles it) with its Galerkin V-cycle over [`DirectNewton::with_levels`]' levels (the
//! coarsest level factored; without coarser levels the fine level itself), then used for
//! many truncated solves `K_k x = b` at later states: the chord (lagged-tangent) Newton
//! iteration of the frame solver ([`crate::statics::frames`]). A refresh at a new state
//! assembles `K` there again and either rebuilds the whole hierarchy or forms the smoothed
//! levels' Galerkin operators again and keeps the coarsest factor
//! ([`GalerkinMultigrid::refresh`]: the cycle stays symmetric and positive definite where the
//! new operators are).

use super::*;

/// `product(p, q)`: `q = K p` over the free dofs ([`DirectNewton::kept_solve`]).
pub type TangentProduct<'a, E> = &'a mut dyn FnMut(&[f64], &mut [f64]) -> Result<(), E>;

/// What [`DirectNewton::kept_solve`] did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KeptSolve {
    /// Conjugate-gradient iterations.
    pub iterations: usize,
    /// The solve met a direction of non-positive curvature (the iterate before it kept:
    /// Steihaug's truncation; none at all at the first iteration).
    pub truncated: bool,
}

impl DirectNewton {
    /// Assemble `K(u)` of `model` plus the `springs`' `k I` and keep it with its Galerkin
    /// V-cycle (`sweeps` sweeps of `smoother` before and after the coarse correction) for
    /// [`DirectNewton::kept_solve`].
    /// The diagonal is shifted by `shift` times its mean, weighted by the lumped mass as the
    /// Newton iteration's regularisation is (`K + σ d̄ D`). `full`: build the hierarchy anew, its coarsest factor included; otherwise, where one is
    /// kept, form the smoothed levels' operators again and keep the coarsest factor.
    ///
    /// Errors: an element the tangent cannot be evaluated at; a coarsest operator that does
    /// not factor even shifted; a hierarchy too large for the memory.
    #[allow(clippy::too_many_arguments)]
    pub fn keep_tangent(
        &mut self,
        model: &dyn ForceModel,
        springs: &[Spring],
        u: &[f64],
        smoother: Smoother,
        sweeps: usize,
        full: bool,
        shift: f64,
    ) -> Result<(), DirectNewtonError> {
        let mean = self
            .assemble(model, springs, u, None)
            .map_err(DirectNewtonError::Inverted)?;
        if shift > 0.0 {
            for (&d, w) in self.diag.iter().zip(&self.dofs.weight) {
                self.vals[d as usize] += shift * mean * w;
            }
        }
        self.decouple_masked(mean);
        let nf = self.dofs.nfree;
        let scatter = self.scatter.get_or_insert_with(|| {
            SymScatter::new(nf, self.symbolic.col_ptr(), self.symbolic.row_idx())
        });
        if let (false, Some(mg)) = (full, self.mg.as_mut()) {
            scatter.fill(&self.vals, mg.finest_mut());
            mg.refresh();
            return Ok(());
        }
        let mut a = scatter.pattern.clone();
        scatter.fill(&self.vals, &mut a);
        let mg = self.hierarchy(a, sweeps, smoother)?;
        self.mg = Some(mg);
        Ok(())
    }

    /// The Galerkin hierarchy of `a` (the free dofs' tangent, full rows) over the levels of
    /// [`DirectNewton::with_levels`], its coarsest level factored in `f32`.
    pub(super) fn hierarchy(
        &mut self,
        a: Csr,
        sweeps: usize,
        smoother: Smoother,
    ) -> Result<GalerkinMultigrid, DirectNewtonError> {
        GalerkinMultigrid::new(
            a,
            self.prolongations.clone(),
            sweeps,
            smoother,
            Precision::Single,
            &mut self.hierarchy_symbolic,
        )
        .map_err(|e| match e {
            GalerkinError::Memory(m) => DirectNewtonError::Memory(m),
            GalerkinError::Factor(f) => DirectNewtonError::Factor(format!(
                "the tangent's coarsest level does not factor at this state ({f})"
            )),
        })
    }

    /// Hold the free dofs that `constraints` constrain beyond the pattern's own (grasps and
    /// pins taken at run time) without a new pattern: in the kept tangent their rows and
    /// columns are decoupled (a diagonal of the mean, nothing else), their prolongation rows
    /// zeroed ([`Prolongations::masked`]), and [`DirectNewton::kept_solve`] keeps them at zero,
    /// so the solve is that of the other dofs and the V-cycle's coarse operator is
    /// `P_Fᵀ K_FF P_F`, as with a pattern built for the new constraints, while the pattern,
    /// the Galerkin products' and the coarse factor's symbolic phases are kept. The kept
    /// tangent is dropped: the next [`DirectNewton::keep_tangent`] builds the whole hierarchy.
    /// `false`, nothing changed, where a dof the pattern left out is free under
    /// `constraints`, or the nodes sliding along directions other than x, y or z are not the
    /// pattern's (the caller builds a new pattern).
    pub fn mask(&mut self, constraints: &Constraints) -> bool {
        if (0..self.dofs.free.len())
            .any(|i| self.dofs.free[i] == usize::MAX && !fixed_dof(constraints, i))
        {
            return false;
        }
        if !self.dofs.same_oblique(constraints) {
            return false;
        }
        let mut masked = vec![false; self.dofs.nfree];
        for (i, &f) in self.dofs.free.iter().enumerate() {
            if f != usize::MAX && fixed_dof(constraints, i) {
                masked[f] = true;
            }
        }
        if masked.iter().any(|&m| m) {
            self.prolongations = Arc::new(self.base_prolongations.masked(&masked));
            self.masked = Some(masked);
        } else {
            self.prolongations = self.base_prolongations.clone();
            self.masked = None;
        }
        self.mg = None;
        true
    }

    /// Decouple the masked dofs in the assembled values ([`DirectNewton::mask`]): their
    /// entries zero, their diagonal `diagonal`.
    fn decouple_masked(&mut self, diagonal: f64) {
        let Some(masked) = &self.masked else { return };
        let (cp, ri) = (self.symbolic.col_ptr(), self.symbolic.row_idx());
        for j in 0..self.dofs.nfree {
            for k in cp[j]..cp[j + 1] {
                let i = ri[k];
                if masked[i] || masked[j] {
                    self.vals[k] = if i == j { diagonal } else { 0.0 };
                }
            }
        }
    }

    /// Whether a tangent is kept ([`DirectNewton::keep_tangent`]).
    pub fn has_kept_tangent(&self) -> bool {
        self.mg.is_some()
    }

    /// At most `max_iter` conjugate-gradient iterations on `K x = b` over the free dofs,
    /// preconditioned by the kept V-cycle, from `x = 0` (`warm`: from `x`). `b` and `x` in all
    /// dofs' layout (`b`'s constrained entries ignored, `x`'s set to zero). `product(p, q)`:
    /// `q = K p` over the free dofs (free-index order, [`DirectNewton::free_count`] entries);
    /// `None`: the kept tangent `K_k` itself. Without a kept tangent `x` is zero and nothing is
    /// done. An error of `product` ends the solve, `x` the iterate so far.
    pub fn kept_solve<E>(
        &self,
        b: &[f64],
        x: &mut [f64],
        max_iter: usize,
        warm: bool,
        product: Option<TangentProduct<'_, E>>,
    ) -> Result<KeptSolve, E> {
        let Some(mg) = &self.mg else {
            x.iter_mut().for_each(|v| *v = 0.0);
            return Ok(KeptSolve {
                iterations: 0,
                truncated: false,
            });
        };
        let nf = self.dofs.nfree;
        let mut bf = vec![0.0; nf];
        let mut xf = vec![0.0; nf];
        self.dofs.gather(b, &mut bf);
        if warm {
            self.dofs.gather(x, &mut xf);
        }
        let masked = self.masked.as_deref();
        let zero_masked = |v: &mut [f64]| {
            if let Some(m) = masked {
                for (v, &m) in v.iter_mut().zip(m) {
                    if m {
                        *v = 0.0;
                    }
                }
            }
        };
        zero_masked(&mut bf);
        zero_masked(&mut xf);
        // Obliquely sliding nodes: the solve on their admissible motions (`oblique.rs`).
        self.dofs.project_free(&mut bf);
        self.dofs.project_free(&mut xf);
        let settings = crate::linalg::cg::CgSettings {
            warm,
            ..crate::linalg::cg::CgSettings::new(0.0, max_iter)
        };
        // Without a product of the caller's, the kept tangent's own.
        let mut own = |p: &[f64], q: &mut [f64]| -> Result<(), E> {
            mg.matrix().matvec(p, q);
            Ok(())
        };
        let product: TangentProduct<'_, E> = match product {
            Some(f) => f,
            None => &mut own,
        };
        // The masked dofs stay at zero: their rows of every product are dropped.
        let mut held = |p: &[f64], q: &mut [f64]| -> Result<(), E> {
            product(p, q)?;
            zero_masked(q);
            self.dofs.project_free(q);
            Ok(())
        };
        let end = crate::linalg::cg::solve(
            &mut held,
            |r: &[f64], z: &mut [f64]| {
                mg.apply(r, z);
                zero_masked(z);
                self.dofs.project_free(z);
                Ok(())
            },
            &bf,
            &mut xf,
            settings,
            None,
        );
        let end = match end {
            Ok(e) => e,
            Err(e) => {
                self.dofs.scatter(&xf, x);
                return Err(e);
            }
        };
        let (iterations, truncated) = match end {
            PcgEnd::Converged(it) => (it, false),
            PcgEnd::MaxIter => (max_iter, false),
            PcgEnd::Truncated(it) | PcgEnd::Negative(it, _) => (it, true),
            PcgEnd::Breakdown(_) => {
                xf.iter_mut().for_each(|v| *v = 0.0);
                (1, true)
            }
        };
        self.dofs.scatter(&xf, x);
        Ok(KeptSolve {
            iterations,
            truncated,
        })
    }

    /// `q = K_k p` over the free dofs with the kept tangent (zero without one).
    pub fn kept_product(&self, p: &[f64], q: &mut [f64]) {
        match &self.mg {
            Some(mg) => mg.matrix().matvec(p, q),
            None => q.iter_mut().for_each(|v| *v = 0.0),
        }
    }

    /// The number of free dofs.
    pub fn free_count(&self) -> usize {
        self.dofs.nfree
    }

    /// `out[f] = x[i]` for every free dof i with free index f (`x` in all dofs' layout).
    pub fn free_values(&self, x: &[f64], out: &mut [f64]) {
        self.dofs.gather(x, out);
    }

    /// `out[i] = x[f(i)]` for every free dof i, zero on constrained dofs.
    pub fn all_values(&self, x: &[f64], out: &mut [f64]) {
        self.dofs.scatter(x, out);
    }
}
