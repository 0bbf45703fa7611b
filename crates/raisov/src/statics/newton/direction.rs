//! The Newton direction: `(K + σ d̄ D) δ = b` on the free dofs, `b` the residual (plus the
//! lift's load in a load step's first iteration), solved one of three ways (module docs of
//! [`super`]):
//!
//! - [`DirectNewton::multigrid_direction`]: conjugate gradients preconditioned by the Galerkin
//!   V-cycle ([`DirectNewtonParams::multigrid`]), to the inexact-Newton tolerance `η ‖b‖₂`;
//!   the hierarchy kept across iterations, rebuilt where it fails or has grown stale, σ raised
//!   past a direction of non-positive curvature;
//! - [`DirectNewton::factor_pcg_direction`]: conjugate gradients preconditioned by the last
//!   factorisation ([`DirectNewtonParams::pcg_max`] > 0), to `η ‖b‖₂`;
//! - [`DirectNewton::factor_direction`]: the sparse Cholesky factorisation, σ raised ×10 until
//!   `K + σ d̄ D` factors (the reference, and the fallback of the factor-reuse solve).

use super::*;

impl DirectNewton {
    /// The direction by multigrid-preconditioned conjugate gradients into `rhs` (module
    /// docs): `(solved, built_now)`, whether a direction was found and whether the hierarchy
    /// was built in this call. `sigma_io` is σ, raised where the operator is not positive.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn multigrid_direction(
        &mut self,
        mgp: MultigridPcg,
        b: &[f64],
        bnorm: f64,
        eta: f64,
        dbar: f64,
        sigma_io: &mut f64,
        params: DirectNewtonParams,
        rhs: &mut [f64],
        out: &mut DirectStatic,
    ) -> Result<(bool, bool), DirectNewtonError> {
        let mut sigma = *sigma_io;
        let mut solved = false;
        let mut built_now = false;
        let scatter = self.scatter.get_or_insert_with(|| {
            SymScatter::new(
                self.dofs.nfree,
                self.symbolic.col_ptr(),
                self.symbolic.row_idx(),
            )
        });
        if self.standing == Standing::Rebuild {
            // Counted only where the provisional hierarchy is still kept: one the
            // stale rule dropped at the same step is rebuilt anyway.
            self.standing = Standing::Settled;
            if self.mg.take().is_some() {
                out.provisional_rebuilds += 1;
            }
        }
        let mut warm = false;
        let mut stale = false;
        // A direction of non-positive curvature met after the first.
        let mut negative: Vec<f64> = Vec::new();
        while !solved {
            let shift = sigma * dbar;
            let full = |out: &mut Csr| {
                scatter.fill(&self.vals, out);
                for (&d, w) in self.diag.iter().zip(&self.dofs.weight) {
                    out.val[scatter.position(d as usize)] += shift * w;
                }
            };
            let reused = self.mg.is_some();
            // The current matrix: the hierarchy's finest operator, unless the
            // whole earlier hierarchy is kept.
            let mut current = None;
            match (self.mg.as_mut(), mgp.keep) {
                (Some(mg), false) => {
                    let clock = std::time::Instant::now();
                    full(mg.finest_mut());
                    mg.refresh();
                    out.setup_s += clock.elapsed().as_secs_f64();
                }
                (Some(_), true) => {
                    let mut a = scatter.pattern.clone();
                    full(&mut a);
                    current = Some(a);
                }
                (None, _) => {
                    let clock = std::time::Instant::now();
                    let mut a = scatter.pattern.clone();
                    full(&mut a);
                    out.multigrid_setups += 1;
                    let built = GalerkinMultigrid::new(
                        a,
                        self.prolongations.clone(),
                        mgp.sweeps,
                        mgp.smoother,
                        mgp.coarse_precision,
                        &mut self.hierarchy_symbolic,
                    );
                    out.setup_s += clock.elapsed().as_secs_f64();
                    self.mg = match built {
                        Ok(mg) => {
                            built_now = true;
                            Some(mg)
                        }
                        Err(GalerkinError::Memory(m)) => return Err(DirectNewtonError::Memory(m)),
                        Err(GalerkinError::Factor(_)) => None,
                    };
                }
            }
            let end = match &self.mg {
                Some(mg) => pcg_from(
                    |x, y| current.as_ref().unwrap_or(mg.matrix()).matvec(x, y),
                    |r, z| mg.apply(r, z),
                    b,
                    rhs,
                    std::mem::take(&mut warm),
                    eta * bnorm,
                    mgp.max_iter,
                    Some(&mut negative),
                ),
                None => PcgEnd::Breakdown(None),
            };
            if let PcgEnd::Converged(it) = end {
                // A kept hierarchy close to missing η is rebuilt before the
                // next Newton iteration, not after it has failed one.
                stale = reused && STALE_SHARE * it as f64 > mgp.max_iter as f64;
            }
            match end {
                PcgEnd::Converged(it) | PcgEnd::Truncated(it) => {
                    out.cg_iterations += it;
                    solved = true;
                }
                PcgEnd::MaxIter if !reused => {
                    out.cg_iterations += mgp.max_iter;
                    solved = true;
                }
                PcgEnd::Negative(it, pq) => {
                    // Not Steihaug's truncation (module docs): the iterate before
                    // this direction can be a huge step along a nearly singular
                    // one. Raise σ past the shift at which p's curvature vanishes
                    // and solve again, the hierarchy kept (its operators take the
                    // new shift).
                    out.cg_iterations += it;
                    let needed = shift_needed(&self.dofs.weight, sigma, dbar, pq, &negative);
                    sigma = raise_sigma(sigma, params.sigma_min, needed)?;
                }
                PcgEnd::Breakdown(None) if reused => {
                    // The kept cycle is not positive on this residual: rebuild
                    // it at the current state, same σ.
                    self.mg = None;
                }
                PcgEnd::MaxIter if reused => {
                    // Rebuild the hierarchy at the current state, same σ, and
                    // go on from the iterate so far.
                    out.cg_iterations += mgp.max_iter;
                    self.mg = None;
                    warm = true;
                }
                _ => {
                    // A fresh hierarchy's breakdown, or a first direction of
                    // non-positive curvature: raise σ. A kept hierarchy stays (it
                    // is positive definite, built where K was); one built at this
                    // indefinite state would need its coarsest operator shifted.
                    if !reused {
                        self.mg = None;
                    }
                    // Each new σ costs a hierarchy: jump past the first
                    // direction's σ* at once.
                    let needed = match end {
                        PcgEnd::Breakdown(Some(pq)) => {
                            shift_needed(&self.dofs.weight, sigma, dbar, pq, rhs)
                        }
                        _ => 0.0,
                    };
                    sigma = raise_sigma(sigma, params.sigma_min, needed)?;
                }
            }
        }
        if stale {
            self.mg = None;
        }
        *sigma_io = sigma;
        Ok((solved, built_now))
    }

    /// The direction by conjugate gradients preconditioned by the kept factorisation into
    /// `rhs` (module docs): whether they reached `η ‖b‖₂` within
    /// [`DirectNewtonParams::pcg_max`] iterations.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn factor_pcg_direction(
        &self,
        b: &[f64],
        bnorm: f64,
        eta: f64,
        dbar: f64,
        sigma: f64,
        params: DirectNewtonParams,
        rhs: &mut [f64],
        out: &mut DirectStatic,
    ) -> Result<bool, DirectNewtonError> {
        let mut solved = false;
        let a = self
            .matrix(sigma * dbar)
            .map_err(DirectNewtonError::Factor)?;
        match pcg(
            |x, y| sym_lower_matvec(&a, x, y),
            |r, z| {
                z.copy_from_slice(r);
                self.apply_factor(z);
            },
            b,
            rhs,
            eta * bnorm,
            params.pcg_max,
        ) {
            PcgEnd::Converged(it) | PcgEnd::Truncated(it) | PcgEnd::Negative(it, _) => {
                out.cg_iterations += it;
                solved = true;
            }
            PcgEnd::MaxIter | PcgEnd::Breakdown(_) => out.cg_iterations += params.pcg_max,
        }
        Ok(solved)
    }

    /// The direction by a sparse Cholesky factorisation into `rhs`, raising σ (`sigma_io`)
    /// ×10 until `K + σ d̄ D` factors (module docs).
    pub(super) fn factor_direction(
        &mut self,
        b: &[f64],
        dbar: f64,
        sigma_io: &mut f64,
        params: DirectNewtonParams,
        rhs: &mut [f64],
        out: &mut DirectStatic,
    ) -> Result<(), DirectNewtonError> {
        self.prepare_factor()?;
        let mut sigma = *sigma_io;
        let mut solved = false;
        while !solved {
            rhs.copy_from_slice(b);
            out.factorizations += 1;
            let clock = std::time::Instant::now();
            let factored = self.factor_solve(sigma * dbar, rhs);
            out.setup_s += clock.elapsed().as_secs_f64();
            match factored {
                Ok(()) => {
                    solved = true;
                }
                Err(e) => {
                    if sigma > 1e6 {
                        return Err(DirectNewtonError::Factor(e));
                    }
                    sigma = (10.0 * sigma).max(params.sigma_min);
                }
            }
        }
        *sigma_io = sigma;
        Ok(())
    }
}
