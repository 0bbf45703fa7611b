//! The inexact Newton systems' conjugate gradients (Steihaug's truncation at non-positive
//! curvature, a warm start after a rebuilt preconditioner) and Eisenstat and Walker's forcing
//! term (module docs of [`super`]).

/// How a conjugate-gradient solve ended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum PcgEnd {
    /// `‖b − A x‖₂ ≤ tol` after this many iterations.
    Converged(usize),
    /// A direction of non-positive curvature after this many iterations (≥ 1; 0 from a warm
    /// start, x the start): the iterate so far is a descent direction of the potential
    /// (`b·x > 0`), Steihaug's truncation.
    Truncated(usize),
    /// As [`PcgEnd::Truncated`], where the caller asked for the direction: that direction `p`
    /// is in the caller's buffer, its curvature `pᵀAp ≤ 0` the second field, x the iterate
    /// so far.
    Negative(usize, f64),
    /// `max_iter` iterations without reaching `tol`; x is the last iterate.
    MaxIter,
    /// Non-positive curvature (or a preconditioner that is not positive) at the first
    /// iteration. With the curvature `pᵀAp ≤ 0` of the first direction p, x is p; without
    /// (the preconditioner), x is 0.
    Breakdown(Option<f64>),
}

/// Conjugate gradients on `A x = b` preconditioned by `B` (`precond(r, z)`: `z = B r`), from
/// x = 0 to `‖b − A x‖₂ ≤ tol`, at most `max_iter` iterations (module docs); a direction of
/// non-positive curvature after the first truncates it.
pub(super) fn pcg(
    matvec: impl Fn(&[f64], &mut [f64]),
    precond: impl Fn(&[f64], &mut [f64]),
    b: &[f64],
    x: &mut [f64],
    tol: f64,
    max_iter: usize,
) -> PcgEnd {
    pcg_from(matvec, precond, b, x, false, tol, max_iter, None)
}

/// [`pcg`] from the start `x` where `warm` (an earlier solve's iterate of the same system,
/// whose curvatures were positive: a descent direction, `b·x > 0`), from 0 otherwise. From a
/// warm start, a first direction of non-positive curvature ends it `Truncated(0)`, x the
/// start. With `negative`, a direction of non-positive curvature that would truncate ends it
/// [`PcgEnd::Negative`] instead, the direction copied into `negative`.
#[allow(clippy::too_many_arguments)]
pub(super) fn pcg_from(
    matvec: impl Fn(&[f64], &mut [f64]),
    precond: impl Fn(&[f64], &mut [f64]),
    b: &[f64],
    x: &mut [f64],
    warm: bool,
    tol: f64,
    max_iter: usize,
    negative: Option<&mut Vec<f64>>,
) -> PcgEnd {
    let n = b.len();
    let mut r = b.to_vec();
    if warm {
        let mut ax = vec![0.0; n];
        matvec(x, &mut ax);
        r.iter_mut().zip(&ax).for_each(|(r, a)| *r -= a);
        if r.iter().map(|v| v * v).sum::<f64>().sqrt() <= tol {
            return PcgEnd::Converged(0);
        }
    } else {
        x.iter_mut().for_each(|v| *v = 0.0);
    }
    let mut z = vec![0.0; n];
    precond(&r, &mut z);
    let mut p = z.clone();
    let mut q = vec![0.0; n];
    let mut rz: f64 = r.iter().zip(&z).map(|(a, b)| a * b).sum();
    if rz <= 0.0 || !rz.is_finite() {
        return if warm {
            PcgEnd::Truncated(0)
        } else {
            PcgEnd::Breakdown(None)
        };
    }
    for it in 1..=max_iter {
        matvec(&p, &mut q);
        let pq: f64 = p.iter().zip(&q).map(|(a, b)| a * b).sum();
        if pq <= 0.0 || !pq.is_finite() {
            return if (it > 1 || warm) && pq.is_finite() {
                match negative {
                    Some(dir) => {
                        dir.clear();
                        dir.extend_from_slice(&p);
                        PcgEnd::Negative(it - 1, pq)
                    }
                    None => PcgEnd::Truncated(it - 1),
                }
            } else if it == 1 && pq.is_finite() {
                x.copy_from_slice(&p);
                PcgEnd::Breakdown(Some(pq))
            } else {
                PcgEnd::Breakdown(None)
            };
        }
        let alpha = rz / pq;
        for i in 0..n {
            x[i] += alpha * p[i];
            r[i] -= alpha * q[i];
        }
        if r.iter().map(|v| v * v).sum::<f64>().sqrt() <= tol {
            return PcgEnd::Converged(it);
        }
        precond(&r, &mut z);
        let rz_new: f64 = r.iter().zip(&z).map(|(a, b)| a * b).sum();
        if rz_new <= 0.0 || !rz_new.is_finite() {
            // The preconditioner is not positive on r: stop with the iterate so far.
            return PcgEnd::Truncated(it);
        }
        let beta = rz_new / rz;
        rz = rz_new;
        for i in 0..n {
            p[i] = z[i] + beta * p[i];
        }
    }
    PcgEnd::MaxIter
}

/// Eisenstat and Walker's choice 2 with its safeguard, not below what the stopping rule
/// needs (`tol` against the largest nodal residual `max`), at most 0.5.
pub(super) fn forcing_term(
    prev_norm: Option<f64>,
    norm: f64,
    eta_prev: f64,
    tol: f64,
    max: f64,
) -> f64 {
    let mut eta = match prev_norm {
        Some(p) if p > 0.0 => 0.9 * (norm / p).powi(2),
        _ => 0.5,
    };
    if 0.9 * eta_prev * eta_prev > 0.1 {
        eta = eta.max(0.9 * eta_prev * eta_prev);
    }
    eta.max(0.1 * tol / max.max(f64::MIN_POSITIVE)).min(0.5)
}
