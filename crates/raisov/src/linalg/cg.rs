//! Conjugate gradients, preconditioned by a closure: the one implementation every solver of
//! the crate calls (the Newton systems of [`crate::statics`], the grasp stiffness of
//! [`crate::sim`]).
//!
//! On `A x = b`, `A` symmetric, `B` a symmetric positive definite preconditioner
//! (`precond(r, z)`: `z = B r`), from `x₀` (0, or a warm start):
//!
//! ```text
//! r₀ = b − A x₀,  z₀ = B r₀,  p₀ = z₀
//! αₖ = rₖ·zₖ / pₖ·A pₖ,   xₖ₊₁ = xₖ + αₖ pₖ,   rₖ₊₁ = rₖ − αₖ A pₖ
//! zₖ₊₁ = B rₖ₊₁,   βₖ = rₖ₊₁·zₖ₊₁ / rₖ·zₖ,   pₖ₊₁ = zₖ₊₁ + βₖ pₖ
//! ```
//!
//! until `‖rₖ‖₂ ≤ tol`. Where `A` is not positive definite (a Newton tangent away from a
//! stable equilibrium), a direction of non-positive curvature `pᵀAp ≤ 0` ends the iteration
//! ([`PcgEnd`] says how): after the first iteration the iterate so far still descends
//! (`b·x > 0`, Steihaug's truncation), or the direction itself is handed back for the
//! caller to shift the operator. Every sum is a serial loop in index order: the same bits on
//! any thread count.

/// How a conjugate-gradient solve ended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PcgEnd {
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

/// How [`solve`] runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CgSettings {
    /// Stop at `‖b − A x‖₂ ≤ tol`.
    pub tol: f64,
    /// Iterations at most (products with `A`).
    pub max_iter: usize,
    /// Start from the given `x` (an earlier iterate of the same system) instead of 0.
    pub warm: bool,
    /// Flexible conjugate gradients: `β = max(0, z·(r − r_prev) / r_prev·z_prev)`
    /// (Polak–Ribière), for a preconditioner that is not exactly linear or symmetric (a
    /// V-cycle over finite-difference products); else `β = r·z / r_prev·z_prev`.
    pub flexible: bool,
}

impl CgSettings {
    /// From 0, not flexible.
    pub fn new(tol: f64, max_iter: usize) -> Self {
        CgSettings {
            tol,
            max_iter,
            warm: false,
            flexible: false,
        }
    }
}

/// Conjugate gradients on `A x = b` preconditioned by `B` (module docs): `matvec(x, y)`:
/// `y = A x`, `precond(r, z)`: `z = B r`, either may fail (an element inverted by a
/// finite-difference product), which ends the solve with that error, `x` the iterate so far.
/// A direction of non-positive curvature after the first iteration truncates the solve
/// (Steihaug); with `negative`, it ends [`PcgEnd::Negative`] instead, the direction copied
/// into `negative`. From a warm start, a first direction of non-positive curvature ends it
/// `Truncated(0)`, `x` the start; from 0, `Breakdown` with `x` the direction.
pub fn solve<E>(
    mut matvec: impl FnMut(&[f64], &mut [f64]) -> Result<(), E>,
    mut precond: impl FnMut(&[f64], &mut [f64]) -> Result<(), E>,
    b: &[f64],
    x: &mut [f64],
    settings: CgSettings,
    negative: Option<&mut Vec<f64>>,
) -> Result<PcgEnd, E> {
    let CgSettings {
        tol,
        max_iter,
        warm,
        flexible,
    } = settings;
    let n = b.len();
    let mut r = b.to_vec();
    if warm {
        let mut ax = vec![0.0; n];
        matvec(x, &mut ax)?;
        r.iter_mut().zip(&ax).for_each(|(r, a)| *r -= a);
        if r.iter().map(|v| v * v).sum::<f64>().sqrt() <= tol {
            return Ok(PcgEnd::Converged(0));
        }
    } else {
        x.iter_mut().for_each(|v| *v = 0.0);
    }
    let mut z = vec![0.0; n];
    precond(&r, &mut z)?;
    let mut p = z.clone();
    let mut q = vec![0.0; n];
    let mut r_prev = if flexible { r.clone() } else { Vec::new() };
    let mut rz: f64 = r.iter().zip(&z).map(|(a, b)| a * b).sum();
    if rz <= 0.0 || !rz.is_finite() {
        return Ok(if warm {
            PcgEnd::Truncated(0)
        } else {
            PcgEnd::Breakdown(None)
        });
    }
    for it in 1..=max_iter {
        matvec(&p, &mut q)?;
        let pq: f64 = p.iter().zip(&q).map(|(a, b)| a * b).sum();
        if pq <= 0.0 || !pq.is_finite() {
            return Ok(if (it > 1 || warm) && pq.is_finite() {
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
            });
        }
        let alpha = rz / pq;
        if flexible {
            r_prev.copy_from_slice(&r);
        }
        for i in 0..n {
            x[i] += alpha * p[i];
            r[i] -= alpha * q[i];
        }
        if r.iter().map(|v| v * v).sum::<f64>().sqrt() <= tol {
            return Ok(PcgEnd::Converged(it));
        }
        precond(&r, &mut z)?;
        let rz_new: f64 = r.iter().zip(&z).map(|(a, b)| a * b).sum();
        if rz_new <= 0.0 || !rz_new.is_finite() {
            // The preconditioner is not positive on r: stop with the iterate so far.
            return Ok(PcgEnd::Truncated(it));
        }
        let beta = if flexible {
            let num: f64 = (0..n).map(|i| z[i] * (r[i] - r_prev[i])).sum();
            (num / rz).max(0.0)
        } else {
            rz_new / rz
        };
        rz = rz_new;
        for i in 0..n {
            p[i] = z[i] + beta * p[i];
        }
    }
    Ok(PcgEnd::MaxIter)
}

/// Conjugate gradients on `A x = b` preconditioned by `B` (`precond(r, z)`: `z = B r`), from
/// x = 0 to `‖b − A x‖₂ ≤ tol`, at most `max_iter` iterations (module docs); a direction of
/// non-positive curvature after the first truncates it.
pub fn pcg(
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
/// whose curvatures were positive: a descent direction, `b·x > 0`), from 0 otherwise (see
/// [`solve`]).
#[allow(clippy::too_many_arguments)]
pub fn pcg_from(
    matvec: impl Fn(&[f64], &mut [f64]),
    precond: impl Fn(&[f64], &mut [f64]),
    b: &[f64],
    x: &mut [f64],
    warm: bool,
    tol: f64,
    max_iter: usize,
    negative: Option<&mut Vec<f64>>,
) -> PcgEnd {
    let settings = CgSettings {
        warm,
        ..CgSettings::new(tol, max_iter)
    };
    let end = solve(
        |x: &[f64], y: &mut [f64]| {
            matvec(x, y);
            Ok::<(), std::convert::Infallible>(())
        },
        |r: &[f64], z: &mut [f64]| {
            precond(r, z);
            Ok(())
        },
        b,
        x,
        settings,
        negative,
    );
    match end {
        Ok(end) => end,
        Err(never) => match never {},
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `tridiag(−1, 2, −1) + shift I` of order n.
    fn laplace(shift: f64) -> impl Fn(&[f64], &mut [f64]) {
        move |x: &[f64], y: &mut [f64]| {
            let n = x.len();
            for i in 0..n {
                let l = if i > 0 { x[i - 1] } else { 0.0 };
                let r = if i + 1 < n { x[i + 1] } else { 0.0 };
                y[i] = (2.0 + shift) * x[i] - l - r;
            }
        }
    }

    fn residual(a: &impl Fn(&[f64], &mut [f64]), b: &[f64], x: &[f64]) -> f64 {
        let mut ax = vec![0.0; x.len()];
        a(x, &mut ax);
        b.iter()
            .zip(&ax)
            .map(|(b, a)| (b - a) * (b - a))
            .sum::<f64>()
            .sqrt()
    }

    #[test]
    fn conjugate_gradients_solve_a_laplacian_in_at_most_n_iterations() {
        let n = 50;
        let a = laplace(0.0);
        let b: Vec<f64> = (0..n).map(|i| ((i * 37) % 11) as f64 - 5.0).collect();
        let bn = b.iter().map(|v| v * v).sum::<f64>().sqrt();
        let mut x = vec![0.0; n];
        let end = pcg(
            &a,
            |r, z| z.copy_from_slice(r),
            &b,
            &mut x,
            1e-10 * bn,
            10 * n,
        );
        let PcgEnd::Converged(it) = end else {
            panic!("{end:?}")
        };
        assert!(it <= n, "{it}");
        assert!(residual(&a, &b, &x) <= 1e-10 * bn);
        // Jacobi-preconditioned and flexible: the same solution.
        let mut y = vec![0.0; n];
        let settings = CgSettings {
            flexible: true,
            ..CgSettings::new(1e-10 * bn, 10 * n)
        };
        let end = solve(
            |x: &[f64], y: &mut [f64]| {
                a(x, y);
                Ok::<(), ()>(())
            },
            |r: &[f64], z: &mut [f64]| {
                z.iter_mut().zip(r).for_each(|(z, r)| *z = r / 2.0);
                Ok(())
            },
            &b,
            &mut y,
            settings,
            None,
        )
        .unwrap();
        assert!(matches!(end, PcgEnd::Converged(_)), "{end:?}");
        let d = x
            .iter()
            .zip(&y)
            .fold(0.0f64, |m, (p, q)| m.max((p - q).abs()));
        assert!(
            d <= 1e-8 * x.iter().fold(0.0f64, |m, v| m.max(v.abs())),
            "{d}"
        );
        // Warm from the solution: converged at once, no product needed beyond the residual.
        let mut z = x.clone();
        let end = pcg_from(
            &a,
            |r, z| z.copy_from_slice(r),
            &b,
            &mut z,
            true,
            1e-8 * bn,
            5,
            None,
        );
        assert_eq!(end, PcgEnd::Converged(0));
    }

    #[test]
    fn a_direction_of_negative_curvature_ends_the_solve_as_documented() {
        // Shifted below its smallest eigenvalue: indefinite.
        let n = 20;
        let a = laplace(-1.0);
        let b: Vec<f64> = (0..n).map(|i| ((i * 7) % 5) as f64 - 2.0).collect();
        let mut x = vec![0.0; n];
        let mut dir = Vec::new();
        let end = pcg_from(
            &a,
            |r, z| z.copy_from_slice(r),
            &b,
            &mut x,
            false,
            1e-12,
            100,
            Some(&mut dir),
        );
        match end {
            PcgEnd::Negative(it, pq) => {
                assert!(it >= 1 && pq <= 0.0);
                let mut ad = vec![0.0; n];
                a(&dir, &mut ad);
                let curv: f64 = dir.iter().zip(&ad).map(|(p, q)| p * q).sum();
                assert!((curv - pq).abs() <= 1e-9 * curv.abs().max(1.0));
                // The iterate so far descends: b·x > 0.
                assert!(b.iter().zip(&x).map(|(b, x)| b * x).sum::<f64>() > 0.0);
            }
            PcgEnd::Breakdown(Some(pq)) => assert!(pq <= 0.0),
            other => panic!("{other:?}"),
        }
        // A matrix-vector product that fails ends the solve with its error.
        let mut calls = 0;
        let out = solve(
            |x: &[f64], y: &mut [f64]| {
                calls += 1;
                if calls > 2 {
                    return Err("inverted");
                }
                laplace(0.0)(x, y);
                Ok(())
            },
            |r: &[f64], z: &mut [f64]| {
                z.copy_from_slice(r);
                Ok(())
            },
            &b,
            &mut x,
            CgSettings::new(1e-14, 100),
            None,
        );
        assert_eq!(out, Err("inverted"));
    }
}
