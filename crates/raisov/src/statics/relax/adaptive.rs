//! Adaptive dynamic relaxation (Joldes, Wittek & Miller 2011, "An adaptive dynamic relaxation
//! method for solving nonlinear finite element problems. Application to brain shift
//! estimation", Int. J. Numer. Meth. Biomed. Engng 27): a single-level baseline for static
//! equilibrium, critically damped on the lowest mode, estimated on the fly.
//!
//! Central differences on `D ü + c D u̇ + R(u) = V` with fictitious per-node masses `D`
//! ([`super::fictitious_mass`], so that `λ_max(D⁻¹K) ≤ 1` at small strain) and the
//! fictitious step `h = 1`:
//!
//! ```text
//! u_{n+1} = u_n + β (u_n − u_{n−1}) + α D⁻¹ (V − R(u_n)),   α = 2h² / (2 + c h),  β = (2 − c h) / (2 + c h)
//! ```
//!
//! with the damping `c = 2 ω₀` critical for the lowest mode, its frequency from the
//! Rayleigh quotient of the last increment (the secant stiffness along it):
//! `ω₀² = Δu·(r_{n−1} − r_n) / (Δu·D Δu)`, `Δu = u_n − u_{n−1}`, `r = V − R` on free dofs,
//! clamped to `[0, 1]` (λ_max's bound); recomputed every step. Stops on the criterion of
//! [`crate::statics::newton`]: the largest nodal residual over free nodes at most
//! `rel_tol × max_a |V_a| + abs_tol`.

use super::fictitious_mass;
use crate::fem::ElementFailure;
use crate::integrate::System;
use crate::mesh::Mesh;
use crate::metrics::max_displacement;

/// Outcome of [`adaptive_relax`].
#[derive(Clone, Debug)]
pub struct AdaptiveRelaxed {
    /// Largest nodal residual over free nodes at the end (N).
    pub residual: f64,
    /// The stopping threshold (N).
    pub target: f64,
    /// Steps taken (one force evaluation each).
    pub steps: u64,
    /// The last estimate of the lowest mode's ω₀ (in units of the fictitious step).
    pub omega: f64,
    /// Whether the residual reached the tolerance.
    pub converged: bool,
}

/// Relax `u` in place (constraints imposed at time `t`) on `sys`, whose mesh is `mesh` and
/// whose `M⁻¹K` is bounded by `lambda_max` (1/s²; e.g.
/// [`crate::integrate::stability::lambda_max_bound`]).
#[allow(clippy::too_many_arguments)]
pub fn adaptive_relax(
    sys: &mut System,
    mesh: &Mesh,
    lambda_max: f64,
    t: f64,
    u: &mut [f64],
    rel_tol: f64,
    abs_tol: f64,
    max_steps: u64,
) -> Result<AdaptiveRelaxed, ElementFailure> {
    let n = u.len();
    let mut v = vec![0.0; n];
    sys.impose(t, u, &mut v);
    let d = fictitious_mass(mesh, &sys.mass, lambda_max);
    let target = rel_tol * max_displacement(&sys.f_ext) + abs_tol;
    let mut r = vec![0.0; n];
    let mut r_prev = vec![0.0; n];
    let mut u_prev = u.to_vec();
    let mut next = vec![0.0; n];
    sys.residual(u, &mut r)?;
    let mut res = max_displacement(&r);
    let mut omega2 = 0.0f64;
    let mut steps = 0;
    while res > target && steps < max_steps {
        let c = 2.0 * omega2.sqrt();
        let (alpha, beta) = (2.0 / (2.0 + c), (2.0 - c) / (2.0 + c));
        for i in 0..n {
            let push = if d[i / 3] > 0.0 { r[i] / d[i / 3] } else { 0.0 };
            next[i] = u[i] + beta * (u[i] - u_prev[i]) + alpha * push;
        }
        u_prev.copy_from_slice(u);
        u.copy_from_slice(&next);
        sys.impose(t, u, &mut v);
        std::mem::swap(&mut r, &mut r_prev);
        sys.residual(u, &mut r)?;
        steps += 1;
        res = max_displacement(&r);
        // Rayleigh quotient of the secant stiffness along the last increment.
        let (mut num, mut den) = (0.0, 0.0);
        for i in 0..n {
            let du = u[i] - u_prev[i];
            num += du * (r_prev[i] - r[i]);
            den += du * du * d[i / 3];
        }
        if den > 0.0 {
            omega2 = (num / den).clamp(0.0, 1.0);
        }
    }
    Ok(AdaptiveRelaxed {
        residual: res,
        target,
        steps,
        omega: omega2.sqrt(),
        converged: res <= target,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrate::stability::lambda_max_bound;
    use crate::statics::relax::tests::{distance_to_newton, sagging_beam};

    /// On a sagging soft beam (neo-Hookean, ν = 0.45, large deflection) adaptive dynamic
    /// relaxation reaches 1e-10 of the load and the equilibrium of direct Newton, within 1e-7
    /// of the largest displacement.
    #[test]
    fn adaptive_relaxation_reaches_newtons_equilibrium() {
        let sc = sagging_beam();
        let mut sys = sc.build_system().unwrap();
        let lmax = lambda_max_bound(&sc.mesh, &sc.material, sc.density);
        let mut u = vec![0.0; 3 * sc.mesh.num_nodes()];
        let out =
            adaptive_relax(&mut sys, &sc.mesh, lmax, 0.0, &mut u, 1e-10, 0.0, 200_000).unwrap();
        assert!(out.converged, "{out:?}");
        let d = distance_to_newton(&sc, &u);
        assert!(d <= 1e-7, "{d:e} of the largest displacement; {out:?}");
    }
}
