//! The regularisation shift σ of the Newton systems `K + σ d̄ D` (module docs of
//! [`super`]): how far a direction of non-positive curvature needs it raised, how it falls
//! after a full step, and how the multigrid path raises it.

use super::{DirectNewtonError, DirectNewtonParams};

/// Twice the shift at which the curvature of a direction `p` of `K + σ d̄ D` would vanish,
/// `σ* = σ − pᵀ(K + σ d̄ D)p / (d̄ pᵀDp)`, `pq` that curvature, `weight` D's diagonal over the
/// free dofs (0 where `p` has no mass or `d̄ ≤ 0`).
pub(super) fn shift_needed(weight: &[f64], sigma: f64, dbar: f64, pq: f64, p: &[f64]) -> f64 {
    let pdp: f64 = p.iter().zip(weight).map(|(p, w)| p * p * w).sum();
    if dbar > 0.0 && pdp > 0.0 {
        2.0 * (sigma - pq / (dbar * pdp))
    } else {
        0.0
    }
}

/// σ after a full step (α = 1, module docs): 0 on the multigrid path, where a direction of
/// non-positive curvature costs only the conjugate-gradient iterations before it and sets σ
/// from its own curvature; elsewhere σ/10 (0 below σ_min), since each σ that turns out too
/// small there costs a failed numeric factorisation.
pub(super) fn sigma_after_full_step(sigma: f64, params: DirectNewtonParams) -> f64 {
    if params.multigrid.is_some() || sigma * 0.1 < params.sigma_min {
        0.0
    } else {
        sigma * 0.1
    }
}

/// The multigrid path's next σ after non-positive curvature: `max(10 σ, σ_min, needed)`; an
/// error past σ = 10⁶.
pub(super) fn raise_sigma(
    sigma: f64,
    sigma_min: f64,
    needed: f64,
) -> Result<f64, DirectNewtonError> {
    if sigma > 1e6 {
        return Err(DirectNewtonError::Factor(
            "the multigrid-preconditioned solve broke down at every shift".into(),
        ));
    }
    Ok((10.0 * sigma).max(sigma_min).max(needed))
}
