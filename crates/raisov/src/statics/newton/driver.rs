//! The one Newton driver: load steps, the lifted first iteration, the line search, the
//! regularisation σ and the stopping rule (module docs of [`super`]), over a linear solve of
//! `(K + σ d̄ D) δ = b` on the free dofs ([`NewtonLinear`]). Its implementations: the
//! assembled tangent ([`DirectNewton`]: sparse Cholesky, factor-reuse conjugate gradients,
//! Galerkin-multigrid conjugate gradients) and matrix-free conjugate gradients
//! ([`super::MatrixFree`]: finite-difference tangent products, no matrix).

use super::search::{lifted_step, line_search, Residual};
use super::*;

/// A linear solve under the Newton driver ([`solve_with`]): the tangent at a state, then the
/// direction `(K + σ d̄ D) δ = b` over the free dofs. To add one, implement this and call
/// [`solve_with`] (`ARCHITECTURE.md`, "add a solver").
pub trait NewtonLinear {
    /// The unknowns: the free dofs and the regularisation's weights `D`.
    fn dofs(&self) -> &FreeDofs;

    /// Take the tangent at `u` (assemble it, or keep the state for products), the springs'
    /// `k I` included; with `lift = (Δ, out)`, `Δ` an increment of the constrained dofs (all
    /// dofs' layout), also `out = −(K Δ)` over the free dofs (free-index order): the load
    /// moving them puts on the free dofs, to first order. Returns `d̄`, the scale of the
    /// regularisation (the mean diagonal of `K` over the free dofs; 0 where the solve does
    /// not regularise).
    fn tangent(
        &mut self,
        model: &mut dyn ForceModel,
        springs: &[Spring],
        u: &[f64],
        lift: Option<(&[f64], &mut [f64])>,
        out: &mut DirectStatic,
    ) -> Result<f64, ElementFailure>;

    /// The Newton direction into `rhs` (free-index order) for `d.b`, with the tangent of the
    /// last [`NewtonLinear::tangent`]; `sigma` is σ, raised where `K + σ d̄ D` is not positive
    /// definite. Returns whether a preconditioner was built in this call (the provisional
    /// rule, [`NewtonLinear::after_step`]).
    #[allow(clippy::too_many_arguments)]
    fn direction(
        &mut self,
        d: Direction<'_>,
        model: &mut dyn ForceModel,
        springs: &[Spring],
        u: &[f64],
        rhs: &mut [f64],
        sigma: &mut f64,
        out: &mut DirectStatic,
    ) -> Result<bool, DirectNewtonError>;

    /// After the step along a direction: whether its preconditioner was built for it
    /// (`built_now`), whether the step was full (α = 1), and the provisional rebuilds so far.
    /// Default: nothing.
    fn after_step(&mut self, _built_now: bool, _full: bool, _rebuilds: usize) {}

    /// The regularisation σ a solve starts from (the last solve's end).
    fn sigma(&self) -> f64;

    /// Keep σ at the end of a solve for the next one.
    fn set_sigma(&mut self, sigma: f64);
}

/// The right-hand side of one Newton system and what its solve may ask for.
pub struct Direction<'a> {
    /// `b`, the free dofs' residual (plus the lift's load in a load step's first
    /// iteration), free-index order.
    pub b: &'a [f64],
    /// `‖b‖₂`.
    pub bnorm: f64,
    /// `d̄` of the tangent ([`NewtonLinear::tangent`]).
    pub dbar: f64,
    /// The solve's settings.
    pub params: DirectNewtonParams,
    /// The inexact-Newton tolerance, taken by an iterative solve ([`Forcing::eta`]).
    pub forcing: &'a mut Forcing,
}

/// Eisenstat and Walker's forcing term of the current iteration ([`Forcing::eta`]).
pub struct Forcing {
    prev_norm: Option<f64>,
    norm: f64,
    eta_prev: f64,
    tol: f64,
    max: f64,
    eta0: f64,
}

impl Forcing {
    /// η of this iteration: Eisenstat and Walker's choice 2 with its safeguard, not below
    /// what the stopping rule needs, at most [`DirectNewtonParams::first_forcing`]. An
    /// iterative solve takes it once per Newton iteration (the next iteration's safeguard
    /// starts from it); a direct one does not.
    pub fn eta(&mut self) -> f64 {
        let eta = forcing_term(
            self.prev_norm,
            self.norm,
            self.eta_prev,
            self.tol,
            self.max,
            self.eta0,
        );
        self.eta_prev = eta;
        eta
    }
}

/// Solve `R(u) = V` for `u` in place with the linear solve `lin`: `u`'s constrained dofs are
/// driven to the values `constraints` impose at time `t` (over the load steps), the free ones
/// start from `u`; the regularisation σ starts where `lin`'s last solve left it (module docs
/// of [`super`]).
#[allow(clippy::too_many_arguments)]
pub fn solve_with<L: NewtonLinear + ?Sized>(
    lin: &mut L,
    model: &mut dyn ForceModel,
    springs: &[Spring],
    constraints: &Constraints,
    f_ext: &[f64],
    t: f64,
    u: &mut [f64],
    params: DirectNewtonParams,
) -> Result<DirectStatic, DirectNewtonError> {
    let n = u.len();
    // An obliquely sliding node starts on its plane or line (`dofs.rs`).
    lin.dofs().project_all(u);
    let mut g = u.to_vec();
    let mut v = vec![0.0; n];
    constraints.impose(t, &mut g, &mut v);
    // The loads and tools the model carries are evaluated at `t` too.
    model.set_time(t);
    let u0 = u.to_vec();
    // The stopping rule's measure of a residual (its 2-norm, largest nodal norm), and of
    // the loads.
    let two = params.stop_norm == StopNorm::Two;
    let measure = |(norm, max): (f64, f64)| if two { norm } else { max };
    let vmax = if two {
        f_ext.iter().map(|x| x * x).sum::<f64>().sqrt()
    } else {
        (0..n / 3)
            .map(|a| node_norm(f_ext, a))
            .fold(0.0f64, f64::max)
    };
    let target = params.rel_tol * vmax + params.abs_tol;
    let steps = params.load_steps.max(1);
    let mut out = DirectStatic {
        target,
        ..Default::default()
    };
    let mut r = vec![0.0; n];
    let mut fint = vec![0.0; n];
    let mut trial = vec![0.0; n];
    let mut rhs = vec![0.0; lin.dofs().len()];
    let mut sigma = lin.sigma();
    let mut prev_norm: Option<f64> = None;
    let eta0 = params.first_forcing.clamp(f64::MIN_POSITIVE, 0.5);
    let mut eta_prev = eta0;
    // Residual on the free dofs at load factor s: (2-norm, largest nodal norm).
    let res = Residual {
        springs,
        constraints,
        f_ext,
    };
    {
        let mut full = u.to_vec();
        for i in 0..n {
            if fixed_dof(constraints, i) {
                full[i] = g[i];
            }
        }
        // For the record only: with a prescribed displacement this state has the
        // constrained nodes at their end and the rest at rest, which may invert elements.
        out.initial_residual = res
            .eval(model, &full, params.load_factor, &mut r, &mut fint)
            .map_or(f64::INFINITY, measure);
        out.force_evaluations += 1;
    }
    let mut lift = vec![0.0; lin.dofs().len()];
    for step in 1..=steps {
        let s = params.load_factor * step as f64 / steps as f64;
        // The constrained dofs' increment of this step, applied by the step's first
        // iteration together with the free dofs' linear response (module docs).
        let mut pending = vec![0.0; n];
        let mut lifting = false;
        for i in 0..n {
            if fixed_dof(constraints, i) {
                pending[i] = u0[i] + s * (g[i] - u0[i]) - u[i];
                lifting |= pending[i] != 0.0;
            }
        }
        let last = step == steps;
        let tol = if last {
            target
        } else {
            params.rel_tol.max(1e-6) * s * vmax + params.abs_tol
        };
        let (mut norm, mut max) = res
            .eval(model, u, s, &mut r, &mut fint)
            .map_err(DirectNewtonError::Inverted)?;
        out.force_evaluations += 1;
        out.history.clear();
        let mut pi_at: Option<f64> = None;
        // Consecutive iterations that lowered the residual by less than a tenth.
        let mut stalled = 0;
        let patient = |stalled: usize| params.stall_after == 0 || stalled < params.stall_after;
        while (lifting || measure((norm, max)) > tol)
            && out.newton_steps < params.max_newton
            && patient(stalled)
        {
            out.newton_steps += 1;
            let before = measure((norm, max));
            let clock = std::time::Instant::now();
            let dbar = lin
                .tangent(
                    model,
                    springs,
                    u,
                    lifting.then_some((&pending[..], &mut lift[..])),
                    &mut out,
                )
                .map_err(DirectNewtonError::Inverted)?;
            out.assembly_s += clock.elapsed().as_secs_f64();
            let clock = std::time::Instant::now();
            // The right-hand side: the free dofs' residual, plus the lift's load.
            let mut b = vec![0.0; lin.dofs().len()];
            lin.dofs().gather(&r, &mut b);
            let bnorm = if lifting {
                b.iter_mut().zip(&lift).for_each(|(b, l)| *b += l);
                b.iter().map(|x| x * x).sum::<f64>().sqrt()
            } else {
                norm
            };
            // The linear solve, inexact where it iterates: to η ‖b‖₂ (Eisenstat-Walker
            // choice 2, not below what the stopping rule needs), η taken where it asks.
            let mut forcing = Forcing {
                prev_norm,
                norm,
                eta_prev,
                tol,
                max: measure((norm, max)),
                eta0,
            };
            let built_now = lin.direction(
                Direction {
                    b: &b,
                    bnorm,
                    dbar,
                    params,
                    forcing: &mut forcing,
                },
                model,
                springs,
                u,
                &mut rhs,
                &mut sigma,
                &mut out,
            )?;
            eta_prev = forcing.eta_prev;
            prev_norm = Some(norm);
            out.factor_s += clock.elapsed().as_secs_f64();
            if lifting {
                lifting = false;
                out.lifted_steps += 1;
                (norm, max) = lifted_step(
                    lin, &res, model, u, &pending, s, &rhs, &mut trial, &mut r, &mut fint,
                    built_now, &mut out,
                )?;
                out.history.push(measure((norm, max)));
                continue;
            }
            (norm, max) = line_search(
                lin,
                &res,
                model,
                u,
                s,
                &rhs,
                &mut trial,
                &mut r,
                &mut fint,
                (norm, max),
                &mut pi_at,
                &mut sigma,
                params,
                built_now,
                &mut out,
            )?;
            out.history.push(measure((norm, max)));
            stalled = if measure((norm, max)) > 0.9 * before {
                stalled + 1
            } else {
                0
            };
        }
        out.residual = measure((norm, max));
        if last {
            out.converged = out.residual <= tol;
        } else if out.residual > tol {
            break;
        }
    }
    model.set_load_factor(params.load_factor);
    lin.set_sigma(sigma);
    Ok(out)
}

/// Eisenstat and Walker's choice 2 with its safeguard, not below what the stopping rule
/// needs (`tol` against the largest nodal residual `max`), at most `eta0` (the first
/// iteration's, [`DirectNewtonParams::first_forcing`]).
fn forcing_term(
    prev_norm: Option<f64>,
    norm: f64,
    eta_prev: f64,
    tol: f64,
    max: f64,
    eta0: f64,
) -> f64 {
    let mut eta = match prev_norm {
        Some(p) if p > 0.0 => 0.9 * (norm / p).powi(2),
        _ => eta0,
    };
    if 0.9 * eta_prev * eta_prev > 0.1 {
        eta = eta.max(0.9 * eta_prev * eta_prev);
    }
    eta.max(0.1 * tol / max.max(f64::MIN_POSITIVE)).min(eta0)
}

impl NewtonLinear for DirectNewton {
    fn dofs(&self) -> &FreeDofs {
        &self.dofs
    }

    fn tangent(
        &mut self,
        model: &mut dyn ForceModel,
        springs: &[Spring],
        u: &[f64],
        lift: Option<(&[f64], &mut [f64])>,
        _out: &mut DirectStatic,
    ) -> Result<f64, ElementFailure> {
        self.assemble(&*model, springs, u, lift)
    }

    /// Multigrid-preconditioned conjugate gradients ([`DirectNewtonParams::multigrid`]), or
    /// conjugate gradients preconditioned by the kept factor ([`DirectNewtonParams::pcg_max`]),
    /// and where they do not reach η (or neither applies) the sparse Cholesky factor, σ
    /// raised until `K + σ d̄ D` factors (module docs of [`super`]).
    fn direction(
        &mut self,
        d: Direction<'_>,
        _model: &mut dyn ForceModel,
        _springs: &[Spring],
        _u: &[f64],
        rhs: &mut [f64],
        sigma: &mut f64,
        out: &mut DirectStatic,
    ) -> Result<bool, DirectNewtonError> {
        let mut solved = false;
        let mut built_now = false;
        if let Some(mgp) = d.params.multigrid {
            let eta = d.forcing.eta();
            (solved, built_now) = self
                .multigrid_direction(mgp, d.b, d.bnorm, eta, d.dbar, sigma, d.params, rhs, out)?;
        } else if d.params.pcg_max > 0 && self.llt.is_some() {
            let eta = d.forcing.eta();
            solved =
                self.factor_pcg_direction(d.b, d.bnorm, eta, d.dbar, *sigma, d.params, rhs, out)?;
        }
        // Factor, raising σ until K + σ d̄ D is positive definite.
        if !solved {
            self.factor_direction(d.b, d.dbar, sigma, d.params, rhs, out)?;
        }
        Ok(built_now)
    }

    fn after_step(&mut self, built_now: bool, full: bool, rebuilds: usize) {
        self.mark_provisional(built_now, full, rebuilds);
    }

    fn sigma(&self) -> f64 {
        self.sigma
    }

    fn set_sigma(&mut self, sigma: f64) {
        self.sigma = sigma;
    }
}
