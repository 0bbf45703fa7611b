//! The step along a Newton direction `δ` (module docs of [`super`]): the lifted step of a
//! load step's first iteration ([`lifted_step`]: the constrained dofs moved in
//! full, the free ones by the largest `α = 1, ½, …` whose residual 2-norm is at most that of
//! the motion imposed alone) and the backtracking line search of the others
//! ([`line_search`]: Armijo on the potential `Π`, the residual 2-norm where
//! `Π` is flat, a secant step back where `Π` climbs past its minimum along `δ`), and the
//! residual both measure ([`Residual`]).

use super::*;

/// The residual of the free dofs at load factor `s`, `r = s V − R(u) − S(u)` (`S` the
/// springs; zero at the constrained dofs).
pub(super) struct Residual<'a> {
    pub springs: &'a [Spring],
    pub constraints: &'a Constraints,
    pub f_ext: &'a [f64],
}

impl Residual<'_> {
    /// `r` at `u` and load factor `s` (`fint` takes `R(u) + S(u)`; the loads and tools the
    /// model carries take the load factor too): its 2-norm and largest nodal norm.
    pub(super) fn eval(
        &self,
        model: &mut dyn ForceModel,
        u: &[f64],
        s: f64,
        r: &mut [f64],
        fint: &mut [f64],
    ) -> Result<(f64, f64), ElementFailure> {
        let n = u.len();
        model.set_load_factor(s);
        model.internal_forces(u, fint)?;
        add_springs(self.springs, u, fint);
        for i in 0..n {
            r[i] = if fixed_dof(self.constraints, i) {
                0.0
            } else {
                s * self.f_ext[i] - fint[i]
            };
        }
        dofs::project_residual(self.constraints, r);
        let two = r.iter().map(|x| x * x).sum::<f64>().sqrt();
        let max = (0..n / 3).map(|a| node_norm(r, a)).fold(0.0f64, f64::max);
        Ok((two, max))
    }
}

/// The lifted step (module docs): `u` takes the constrained dofs' `pending` move and
/// `α rhs` on the free dofs; the residual at the new state (its 2-norm and largest nodal
/// norm) left in `r`.
#[allow(clippy::too_many_arguments)]
pub(super) fn lifted_step<L: NewtonLinear + ?Sized>(
    lin: &mut L,
    res: &Residual,
    model: &mut dyn ForceModel,
    u: &mut [f64],
    pending: &[f64],
    s: f64,
    rhs: &[f64],
    trial: &mut [f64],
    r: &mut [f64],
    fint: &mut [f64],
    built_now: bool,
    out: &mut DirectStatic,
) -> Result<(f64, f64), DirectNewtonError> {
    // The constrained dofs in full, the free ones by the largest α = 1, ½, … (at most 12
    // halvings) whose state inverts no element and whose residual 2-norm is at most that
    // of the motion imposed alone (α = 0), else α = 0. Π is no merit here (the
    // constrained dofs move).
    let (mut norm, mut max) = (f64::NAN, f64::NAN);
    for (ui, p) in u.iter_mut().zip(pending) {
        *ui += p;
    }
    out.force_evaluations += 1;
    let alone = res.eval(model, u, s, r, fint);
    let bound = alone.as_ref().map_or(f64::INFINITY, |&(tn, _)| tn);
    let mut alpha = 1.0;
    let mut accepted = false;
    for _ in 0..=12 {
        lin.dofs().step_to(u, alpha, rhs, trial);
        out.force_evaluations += 1;
        if let Ok((tn, tm)) = res.eval(model, trial, s, r, fint) {
            if tn <= bound {
                u.copy_from_slice(trial);
                (norm, max) = (tn, tm);
                accepted = true;
                break;
            }
        }
        alpha *= 0.5;
    }
    lin.after_step(
        built_now,
        accepted && alpha == 1.0,
        out.provisional_rebuilds,
    );
    if !accepted {
        alone.map_err(DirectNewtonError::Inverted)?;
        (norm, max) = res
            .eval(model, u, s, r, fint)
            .map_err(DirectNewtonError::Inverted)?;
        out.force_evaluations += 1;
    }
    Ok((norm, max))
}

/// The backtracking line search along `rhs` from `u` (module docs), whose residual is
/// `now` (2-norm, largest nodal norm) and in `r`; `pi_at` the potential at `u` where a
/// line search at this load factor computed it. Returns the residual at the state taken
/// (`u` itself where no trial is accepted: σ is then raised).
#[allow(clippy::too_many_arguments)]
pub(super) fn line_search<L: NewtonLinear + ?Sized>(
    lin: &mut L,
    res: &Residual,
    model: &mut dyn ForceModel,
    u: &mut [f64],
    s: f64,
    rhs: &[f64],
    trial: &mut [f64],
    r: &mut [f64],
    fint: &mut [f64],
    now: (f64, f64),
    pi_at: &mut Option<f64>,
    sigma: &mut f64,
    params: DirectNewtonParams,
    built_now: bool,
    out: &mut DirectStatic,
) -> Result<(f64, f64), DirectNewtonError> {
    let (mut norm, mut max) = now;
    let slope = lin.dofs().dot(r, rhs);
    // Π at u: the last accepted trial's, where the last step was a line search's
    // at this load factor.
    let pi0 = match pi_at.take() {
        Some(pi) => pi,
        None => {
            out.energy_evaluations += 1;
            potential(model, res.springs, u, s, res.f_ext)
        }
    };
    let mut alpha = 1.0;
    let mut accepted = false;
    let mut secants = SECANT_STEPS;
    for _ in 0..=12 {
        lin.dofs().step_to(u, alpha, rhs, trial);
        let pi = potential(model, res.springs, trial, s, res.f_ext);
        out.energy_evaluations += 1;
        let armijo = pi <= pi0 - 1e-4 * alpha * slope;
        let flat =
            pi.is_finite() && ((pi - pi0).abs() <= 1e-9 * pi0.abs() || max <= params.flat_below);
        if !(armijo || flat) {
            alpha *= 0.5;
            continue;
        }
        out.force_evaluations += 1;
        if let Ok((tn, tm)) = res.eval(model, trial, s, r, fint) {
            if armijo && secants > 0 && slope > 0.0 {
                // Π'(α) = −r(u + αδ)·δ: past the minimum along δ and still
                // climbing steeply, step back to the secant's estimate of it.
                let climb = -lin.dofs().dot(r, rhs);
                if climb > CURVATURE * slope {
                    secants -= 1;
                    alpha = (alpha * slope / (slope + climb)).max(0.1 * alpha);
                    continue;
                }
            }
            if armijo || tn < norm {
                *pi_at = Some(pi);
                u.copy_from_slice(trial);
                norm = tn;
                max = tm;
                accepted = true;
                break;
            }
        }
        alpha *= 0.5;
    }
    lin.after_step(
        built_now,
        accepted && alpha == 1.0,
        out.provisional_rebuilds,
    );
    if accepted {
        if alpha == 1.0 {
            out.full_steps += 1;
            *sigma = sigma_after_full_step(*sigma, params);
        }
    } else {
        // Keep u; restore its residual and regularise harder.
        out.rejected_steps += 1;
        res.eval(model, u, s, r, fint)
            .map_err(DirectNewtonError::Inverted)?;
        out.force_evaluations += 1;
        *sigma = (100.0 * *sigma).max(1e3 * params.sigma_min);
    }
    Ok((norm, max))
}
