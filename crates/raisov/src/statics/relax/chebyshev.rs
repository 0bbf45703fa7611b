//! Single-level Chebyshev semi-iteration for static equilibrium `R(u) = V`: a baseline with
//! FAS's smoother's preconditioner (per-node fictitious masses `D`,
//! [`super::fictitious_mass`]) on the finest mesh alone, over an interval `[a, b]` of
//! the spectrum of `D⁻¹K` that is estimated, not fixed.
//!
//! The iteration (Saad, *Iterative Methods for Sparse Linear Systems*, Alg. 12.1, on the
//! nonlinear residual `r(u) = V − R(u)`, zero on constrained dofs):
//!
//! ```text
//! θ = (b + a)/2,  δ = (b − a)/2,  σ = θ/δ,  ρ₀ = 1/σ,  ρ_k = 1 / (2σ − ρ_{k−1})
//! d₀ = D⁻¹ r(u₀) / θ,   d_k = ρ_k ρ_{k−1} d_{k−1} + (2 ρ_k / δ) D⁻¹ r(u_k),   u_{k+1} = u_k + d_k
//! ```
//!
//! Each iteration costs one force evaluation. On a linear problem whose spectrum lies in
//! `[a, b]` the error after k iterations is at most `2 / T_k(σ)` of the start's in the energy
//! norm (`T_k` the Chebyshev polynomial): about `2 exp(−2k √(a/b))`.
//!
//! The interval:
//! - At the start (and after a failure, below) [`LANCZOS_STEPS`] steps of Lanczos on
//!   `D^{-1/2} K D^{-1/2}` at the current state, `K w` by a one-sided difference of the
//!   residual (`(r(u) − r(u + ε w)) / ε`, ε as FAS's power iteration takes it; one force
//!   evaluation each). Their Ritz values lie inside the spectrum: `b` is [`STRETCH`] times the
//!   largest (it approaches `λ_max` from below, and the body stiffens as it deforms), `a` the
//!   smallest.
//! - Every iteration, the Rayleigh quotient of the last increment `d`, the secant stiffness
//!   along it: `q = d·(r_k − r_{k+1}) / (d·D d)` (adaptive dynamic relaxation's estimate of the
//!   lowest mode, [`super::adaptive`]). Once the modes inside `[a, b]` are damped, the
//!   error, and so `d`, is made of the modes below `a`, which a Lanczos run of a few steps
//!   cannot resolve on an organ (`λ_min / λ_max` near 10⁻⁵). After each window of
//!   `⌈√(b/a)⌉` iterations (the iteration's own time scale, at most [`MAX_WINDOW`]), where the
//!   smallest positive `q` of the window is below [`LOWER_DROP`] `a`, or [`LOWER_SHARE`] `q`
//!   is above `a / LOWER_DROP` (a flat membrane at rest has no transverse stiffness, and its
//!   first quotients are near zero), `a` becomes [`LOWER_SHARE`] `q` and the recurrence
//!   restarts from the current state (`k = 0`); where an increment's `q` exceeds `b`, `b`
//!   becomes [`STRETCH`] `q` and the recurrence restarts at once.
//!
//! The four constants were chosen by one rule: the least wall time to the stopping rule below
//! summed over the liver L1 and the heart of `raisov bench equilibrium`, over a sweep of each
//! (`bench/RESULTS.md`).
//! - A step that inverts an element, or a residual that grows past [`GROWTH`] times the one
//!   at the last window's end, returns to the state at the last window's end, estimates the
//!   interval there again, doubles `b` once more for each such failure, and restarts; after
//!   [`MAX_FAILURES`] failures the last element failure is returned.
//!
//! Stops on the criterion of [`crate::statics::newton`]: the largest nodal residual over free
//! nodes at most `rel_tol × max_a |V_a| + abs_tol`. Everything is sequential over one state
//! and the force evaluations are deterministic: the same bits on any thread count.

use super::fictitious_mass;
use crate::fem::ElementFailure;
use crate::integrate::System;
use crate::linalg::spectrum::{start_entry, tridiagonal_extremes};
use crate::mesh::Mesh;
use crate::metrics::max_displacement;

/// Lanczos steps of each interval estimate (one force evaluation each).
pub const LANCZOS_STEPS: usize = 48;

/// `b` over the largest Ritz value (or the largest increment quotient).
pub const STRETCH: f64 = 1.05;

/// A window whose smallest increment quotient `q` is below this share of `a` lowers `a`.
pub const LOWER_DROP: f64 = 0.8;

/// `a` over that window's smallest `q` when it is lowered: `q` is a mean over the modes in the
/// increment, above the lowest of them.
pub const LOWER_SHARE: f64 = 0.5;

/// The longest window between checks of the interval's lower end (iterations).
pub const MAX_WINDOW: u64 = 1000;

/// A residual this many times the last window's end is taken as divergence.
pub const GROWTH: f64 = 1e3;

/// Failures (inverted elements or divergence) before giving up.
pub const MAX_FAILURES: usize = 6;

/// Outcome of [`chebyshev_relax`].
#[derive(Clone, Debug)]
pub struct ChebyshevRelaxed {
    /// Largest nodal residual over free nodes at the end (N).
    pub residual: f64,
    /// The stopping threshold (N).
    pub target: f64,
    /// Chebyshev iterations taken (one force evaluation each).
    pub iterations: u64,
    /// Force evaluations in all, the interval estimates' and the first residual included.
    pub evaluations: u64,
    /// Restarts of the recurrence (a new interval).
    pub restarts: u64,
    /// Failures recovered from (an inverted element or a growing residual).
    pub failures: u64,
    /// The interval `[a, b]` at the end (of `D⁻¹K`, dimensionless).
    pub interval: [f64; 2],
    /// Whether the residual reached the tolerance.
    pub converged: bool,
}

/// Relax `u` in place (constraints imposed at time `t`) on `sys`, whose mesh is `mesh` and
/// whose `M⁻¹K` is bounded by `lambda_max` (1/s², e.g.
/// [`crate::integrate::stability::lambda_max_bound`]; it scales the fictitious masses), spending at most
/// `max_evaluations` force evaluations (module docs).
#[allow(clippy::too_many_arguments)]
pub fn chebyshev_relax(
    sys: &mut System,
    mesh: &Mesh,
    lambda_max: f64,
    t: f64,
    u: &mut [f64],
    rel_tol: f64,
    abs_tol: f64,
    max_evaluations: u64,
) -> Result<ChebyshevRelaxed, ElementFailure> {
    let n = u.len();
    let mut v = vec![0.0; n];
    sys.impose(t, u, &mut v);
    let dm = fictitious_mass(mesh, &sys.mass, lambda_max);
    let dinv: Vec<f64> = dm
        .iter()
        .map(|&x| if x > 0.0 { 1.0 / x } else { 0.0 })
        .collect();
    let target = rel_tol * max_displacement(&sys.f_ext) + abs_tol;
    let (lo, hi) = mesh.bounding_box();
    let length = 1e-3 * crate::mesh::norm(crate::mesh::sub(hi, lo));
    let mut r = vec![0.0; n];
    let mut r_prev = vec![0.0; n];
    let mut d = vec![0.0; n];
    sys.residual(u, &mut r)?;
    let mut evaluations = 1u64;
    let mut res = max_displacement(&r);
    let mut out = ChebyshevRelaxed {
        residual: res,
        target,
        iterations: 0,
        evaluations: 0,
        restarts: 0,
        failures: 0,
        interval: [0.0; 2],
        converged: false,
    };
    if res <= target {
        out.evaluations = evaluations;
        out.converged = true;
        return Ok(out);
    }
    let mut scratch = Lanczos::new(n);
    let [mut a, mut b] = scratch.interval(sys, u, &r, &dm, length, &mut evaluations)?;
    b *= STRETCH;
    // The state at the last window's end, its residual and largest nodal residual.
    let mut checkpoint = u.to_vec();
    let mut r_check = r.clone();
    let mut res_check = res;
    let mut failure: Option<ElementFailure> = None;
    'run: while res > target && evaluations < max_evaluations {
        // One recurrence from the current state over [a, b].
        let theta = 0.5 * (b + a);
        let delta = 0.5 * (b - a);
        let sigma = theta / delta;
        let mut rho = 1.0 / sigma;
        let window = ((b / a).sqrt().ceil().max(1.0) as u64).min(MAX_WINDOW);
        let mut in_window = 0u64;
        let mut qmin = f64::INFINITY;
        let mut k = 0u64;
        loop {
            if k == 0 {
                for i in 0..n {
                    d[i] = r[i] * dinv[i / 3] / theta;
                }
            } else {
                let rho_new = 1.0 / (2.0 * sigma - rho);
                let (c0, c1) = (rho_new * rho, 2.0 * rho_new / delta);
                for i in 0..n {
                    d[i] = c0 * d[i] + c1 * r[i] * dinv[i / 3];
                }
                rho = rho_new;
            }
            for i in 0..n {
                u[i] += d[i];
            }
            std::mem::swap(&mut r, &mut r_prev);
            evaluations += 1;
            out.iterations += 1;
            k += 1;
            let step = sys.residual(u, &mut r);
            let grew = step.is_ok() && {
                res = max_displacement(&r);
                !(res <= GROWTH * res_check)
            };
            if let Err(e) = step {
                failure = Some(e);
            }
            if step.is_err() || grew {
                // Back to the last window's end, a new interval there, b doubled per failure.
                out.failures += 1;
                if out.failures as usize > MAX_FAILURES {
                    break 'run;
                }
                u.copy_from_slice(&checkpoint);
                r.copy_from_slice(&r_check);
                res = res_check;
                [a, b] = scratch.interval(sys, u, &r, &dm, length, &mut evaluations)?;
                b *= STRETCH * 2f64.powi(out.failures as i32);
                out.restarts += 1;
                continue 'run;
            }
            if res <= target || evaluations >= max_evaluations {
                break 'run;
            }
            // The secant stiffness along the increment.
            let (mut num, mut den) = (0.0, 0.0);
            for i in 0..n {
                num += d[i] * (r_prev[i] - r[i]);
                den += d[i] * d[i] * dm[i / 3];
            }
            let q = if den > 0.0 { num / den } else { 0.0 };
            if q > b {
                b = STRETCH * q;
                out.restarts += 1;
                continue 'run;
            }
            if q > 0.0 {
                qmin = qmin.min(q);
            }
            in_window += 1;
            if in_window >= window {
                checkpoint.copy_from_slice(u);
                r_check.copy_from_slice(&r);
                res_check = res;
                let moved = qmin < LOWER_DROP * a || LOWER_SHARE * qmin * LOWER_DROP > a;
                if qmin.is_finite() && moved {
                    a = LOWER_SHARE * qmin;
                    out.restarts += 1;
                    continue 'run;
                }
                in_window = 0;
                qmin = f64::INFINITY;
            }
        }
    }
    out.residual = res;
    out.evaluations = evaluations;
    out.interval = [a, b];
    out.converged = res <= target;
    match failure {
        Some(e) if out.failures as usize > MAX_FAILURES => Err(e),
        _ => Ok(out),
    }
}

/// The Lanczos run's vectors.
struct Lanczos {
    q: Vec<f64>,
    q_prev: Vec<f64>,
    w: Vec<f64>,
    trial: Vec<f64>,
    rt: Vec<f64>,
}

impl Lanczos {
    fn new(n: usize) -> Self {
        Lanczos {
            q: vec![0.0; n],
            q_prev: vec![0.0; n],
            w: vec![0.0; n],
            trial: vec![0.0; n],
            rt: vec![0.0; n],
        }
    }

    /// The smallest and largest Ritz values of [`LANCZOS_STEPS`] Lanczos steps on
    /// `D^{-1/2} K D^{-1/2}` at `u` (`r` the residual there), from a fixed pseudo-random start
    /// on the free dofs. `K w = (r(u) − r(u + ε w)) / ε`, `ε = 10⁻⁷ max(|u|_∞, length) / |w|_∞`.
    fn interval(
        &mut self,
        sys: &mut System,
        u: &[f64],
        r: &[f64],
        dm: &[f64],
        length: f64,
        evaluations: &mut u64,
    ) -> Result<[f64; 2], ElementFailure> {
        let n = u.len();
        for (i, qi) in self.q.iter_mut().enumerate() {
            *qi = start_entry(i as u64);
        }
        sys.constraints.zero_constrained(&mut self.q);
        let norm = |x: &[f64]| x.iter().map(|v| v * v).sum::<f64>().sqrt();
        let q0 = norm(&self.q);
        if q0 == 0.0 {
            return Ok([1.0, 1.0]);
        }
        self.q.iter_mut().for_each(|v| *v /= q0);
        let umax = u.iter().fold(0.0f64, |m, &x| m.max(x.abs()));
        let Lanczos {
            q,
            q_prev,
            w,
            trial,
            rt,
        } = self;
        // D^{-1/2} K D^{-1/2} q: w = D^{-1/2} q, K w by the difference, back to D^{-1/2} K w.
        let (alpha, beta) = crate::linalg::spectrum::lanczos(
            q,
            q_prev,
            w,
            LANCZOS_STEPS,
            |q: &[f64], kq: &mut [f64]| -> Result<(), ElementFailure> {
                let mut wmax = 0.0f64;
                for i in 0..n {
                    let s = dm[i / 3];
                    kq[i] = if s > 0.0 { q[i] / s.sqrt() } else { 0.0 };
                    wmax = wmax.max(kq[i].abs());
                }
                let eps = 1e-7 * umax.max(length) / wmax;
                for i in 0..n {
                    trial[i] = u[i] + eps * kq[i];
                }
                *evaluations += 1;
                sys.residual(trial, rt)?;
                for i in 0..n {
                    let s = dm[i / 3];
                    let kw = (r[i] - rt[i]) / eps;
                    kq[i] = if s > 0.0 { kw / s.sqrt() } else { 0.0 };
                }
                Ok(())
            },
        )?;
        let (lo, hi) = tridiagonal_extremes(&alpha, &beta);
        // A Ritz value at or below zero (an indefinite tangent) or above the fictitious bound's
        // reach says nothing usable about the lower end: keep a positive one.
        let hi = if hi.is_finite() && hi > 0.0 { hi } else { 1.0 };
        let lo = if lo.is_finite() && lo > 0.0 {
            lo.min(0.5 * hi)
        } else {
            1e-3 * hi
        };
        Ok([lo, hi])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrate::stability::lambda_max_bound;
    use crate::scenario::Scenario;
    use crate::statics::relax::tests::{distance_to_newton, sagging_beam};
    use std::path::Path;

    /// On a sagging soft beam (neo-Hookean, ν = 0.45, large deflection) the Chebyshev
    /// semi-iteration reaches 1e-10 of the load and the equilibrium of direct Newton, within
    /// 1e-7 of the largest displacement, and lowered its interval's lower end below the
    /// Lanczos estimate on the way.
    #[test]
    fn chebyshev_relaxation_reaches_newtons_equilibrium() {
        let sc = sagging_beam();
        let n = sc.mesh.num_nodes();
        let mut sys = sc.build_system().unwrap();
        let lmax = lambda_max_bound(&sc.mesh, &sc.material, sc.density);
        let mut u = vec![0.0; 3 * n];
        let out =
            chebyshev_relax(&mut sys, &sc.mesh, lmax, 0.0, &mut u, 1e-10, 0.0, 200_000).unwrap();
        assert!(out.converged, "{out:?}");
        // The Lanczos estimate at rest, from the same start: the run went below it.
        let mut sys = sc.build_system().unwrap();
        let rest = vec![0.0; 3 * n];
        let mut r = vec![0.0; 3 * n];
        sys.residual(&rest, &mut r).unwrap();
        let dm = fictitious_mass(&sc.mesh, &sys.mass, lmax);
        let (lo, hi) = sc.mesh.bounding_box();
        let length = 1e-3 * crate::mesh::norm(crate::mesh::sub(hi, lo));
        let [a0, _] = Lanczos::new(3 * n)
            .interval(&mut sys, &rest, &r, &dm, length, &mut 0)
            .unwrap();
        assert!(out.restarts >= 1 && out.interval[0] < a0, "{a0:e}; {out:?}");
        let d = distance_to_newton(&sc, &u);
        assert!(d <= 1e-7, "{d:e} of the largest displacement; {out:?}");
    }

    /// A flat membrane at rest has no transverse stiffness: its first increments' quotients are
    /// near zero, and the lower end taken from them made the window `√(b/a)` so long that it
    /// was never checked again (the 10k drape stalled at 1e-10 of the load for 10⁶
    /// iterations). The window is capped and the lower end rises again: a 1k drape from rest
    /// reaches 1e-8 of the load within 20 000 force evaluations.
    #[test]
    fn issue_flat_membrane_lower_end_rises_again() {
        let text = r#"
gravity = [0.0, 0.0, -9.81]
[mesh]
generate = "rectangle"
size = [0.1, 0.1]
nodes = 1000
[material]
law = "mooney-rivlin"
c1 = 1000.0
c2 = 1000.0
[[fix]]
boundary = true
[run]
duration = 1.0
"#;
        let sc = Scenario::from_toml(text, Path::new("drape-chebyshev.toml")).unwrap();
        let mut sys = sc.build_system().unwrap();
        let lmax = lambda_max_bound(&sc.mesh, &sc.material, sc.density);
        let mut u = vec![0.0; 3 * sc.mesh.num_nodes()];
        let out =
            chebyshev_relax(&mut sys, &sc.mesh, lmax, 0.0, &mut u, 1e-8, 0.0, 20_000).unwrap();
        assert!(out.converged, "{out:?}");
    }

    /// The Lanczos estimate brackets what it can see: on the beam at rest its largest Ritz
    /// value is at most the fictitious masses' bound (`λ_max(D⁻¹K) ≤ 1` at small strain) and
    /// within 5 % of the power iteration's 200-step estimate of `λ_max(D⁻¹K)`.
    #[test]
    fn lanczos_largest_ritz_value_matches_power_iteration() {
        let sc = sagging_beam();
        let n = sc.mesh.num_nodes();
        let mut sys = sc.build_system().unwrap();
        let lmax = lambda_max_bound(&sc.mesh, &sc.material, sc.density);
        let dm = fictitious_mass(&sc.mesh, &sys.mass, lmax);
        let u = vec![0.0; 3 * n];
        let mut r = vec![0.0; 3 * n];
        sys.residual(&u, &mut r).unwrap();
        let (lo, hi) = sc.mesh.bounding_box();
        let length = 1e-3 * crate::mesh::norm(crate::mesh::sub(hi, lo));
        let mut evals = 0;
        let [a, b] = Lanczos::new(3 * n)
            .interval(&mut sys, &u, &r, &dm, length, &mut evals)
            .unwrap();
        assert_eq!(evals, LANCZOS_STEPS as u64);
        // Power iteration on D⁻¹K with the same difference products.
        let mut x: Vec<f64> = (0..3 * n)
            .map(|i| ((i * 7919) % 101) as f64 - 50.0)
            .collect();
        sys.constraints.zero_constrained(&mut x);
        let (mut y, mut w) = (vec![0.0; 3 * n], vec![0.0; 3 * n]);
        let lambda = crate::linalg::spectrum::power_iteration(
            &mut x,
            crate::linalg::spectrum::Diagonal::Node(&dm),
            200,
            &mut y,
            |x: &[f64], kx: &mut [f64]| {
                let xmax = x.iter().fold(0.0f64, |m, &v| m.max(v.abs()));
                let eps = 1e-7 * length / xmax;
                for i in 0..3 * n {
                    w[i] = eps * x[i];
                }
                sys.residual(&w, kx)?;
                for i in 0..3 * n {
                    kx[i] = (r[i] - kx[i]) / eps;
                }
                Ok::<(), ElementFailure>(())
            },
        )
        .unwrap();
        assert!(b <= 1.0 + 1e-6, "largest Ritz value {b} above the bound");
        assert!(
            (b - lambda).abs() <= 0.05 * lambda,
            "Lanczos {b}, power {lambda}"
        );
        assert!(a > 0.0 && a < b, "[{a}, {b}]");
    }
}
