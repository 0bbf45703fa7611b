//! Matrix-free conjugate gradients under the Newton driver (Newton-Krylov): no matrix is
//! assembled; each product with the tangent is a central difference of the forces,
//!
//! ```text
//! K(u) p ≈ (R(u + ε p) − R(u − ε p)) / (2 ε),    ε = 10⁻⁷ max(‖u‖∞, ℓ) / ‖p‖∞,
//! ```
//!
//! `R` the internal forces with the springs', at the load factor of the iteration, `ℓ` the
//! length scale [`MatrixFreeCg::length`] (the product's largest node move is 10⁻⁷ of the
//! displacements' scale). Two force evaluations a product; it covers every force a model
//! carries, with or without an element tangent. Conjugate gradients preconditioned by a
//! per-node diagonal `M⁻¹` (the lumped mass, or any positive per-node weights such as
//! [`crate::statics::relax::fictitious_mass`]) solve `K δ = b` to the driver's inexact-Newton
//! tolerance `η ‖b‖₂` (or a fixed one, [`MatrixFreeCg::tolerance`]), at most
//! [`MatrixFreeCg::max_iter`] iterations (the last iterate taken
//! past them: truncated Newton). Nothing is factored, so nothing is regularised (`d̄ = 0`):
//! a direction of non-positive curvature after the first iteration truncates the solve
//! (Steihaug: the iterate so far descends), and at the first one that direction itself, the
//! preconditioned residual `M⁻¹ b`, is the step's direction, the line search choosing its
//! length. A load step's lift `−K Δ_c` is one product. The finite difference limits the
//! attainable residual to about 10⁻⁸ of the force scale; the driver's line search and
//! stopping rule are those of every linear solve ([`super::solve_with`]).

use super::*;
use crate::linalg::cg::{solve as cg_solve, CgSettings};

/// Settings of [`MatrixFree`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MatrixFreeCg {
    /// Conjugate-gradient iterations at most per Newton system. Default 20 000.
    pub max_iter: usize,
    /// The length scale `ℓ` of the finite-difference step (m, module docs). Default 1e-3.
    pub length: f64,
    /// A fixed relative tolerance of each linear solve, `‖b − K δ‖₂ ≤ tolerance ‖b‖₂`,
    /// instead of the driver's inexact-Newton term η; `None` (the default): η.
    pub tolerance: Option<f64>,
}

impl Default for MatrixFreeCg {
    fn default() -> Self {
        MatrixFreeCg {
            max_iter: 20_000,
            length: 1e-3,
            tolerance: None,
        }
    }
}

/// Matrix-free conjugate gradients (module docs): a [`NewtonLinear`] for [`solve_with`].
pub struct MatrixFree {
    dofs: FreeDofs,
    /// `1 / diag` per free dof (free-index order).
    inv_diag: Vec<f64>,
    settings: MatrixFreeCg,
    /// The state of the last [`NewtonLinear::tangent`].
    at: Vec<f64>,
    /// Scratch, all dofs' layout: the product's direction, its states and forces.
    dir: Vec<f64>,
    w: Vec<f64>,
    plus: Vec<f64>,
    minus: Vec<f64>,
    sigma: f64,
}

impl MatrixFree {
    /// The free dofs of `constraints` over `mass.len()` nodes, conjugate gradients
    /// preconditioned by the lumped `mass` (kg per node).
    pub fn new(mass: &[f64], constraints: &Constraints, settings: MatrixFreeCg) -> MatrixFree {
        MatrixFree::with_diagonal(mass, mass, constraints, settings)
    }

    /// The same, preconditioned by the per-node diagonal `diag` (e.g.
    /// [`crate::statics::relax::fictitious_mass`]); `mass` weighs nothing here but the
    /// driver's record of the free dofs.
    pub fn with_diagonal(
        mass: &[f64],
        diag: &[f64],
        constraints: &Constraints,
        settings: MatrixFreeCg,
    ) -> MatrixFree {
        let nodes = mass.len();
        let dofs = FreeDofs::new(nodes, mass, constraints);
        let mut inv_diag = vec![0.0; dofs.len()];
        for (i, &f) in dofs.free.iter().enumerate() {
            if f != usize::MAX && diag[i / 3] > 0.0 {
                inv_diag[f] = 1.0 / diag[i / 3];
            }
        }
        let z = vec![0.0; 3 * nodes];
        MatrixFree {
            dofs,
            inv_diag,
            settings,
            at: z.clone(),
            dir: z.clone(),
            w: z.clone(),
            plus: z.clone(),
            minus: z,
            sigma: 0.0,
        }
    }
}

/// `q = K(u) d` (all dofs' layout) by the central difference of the module docs; `w`,
/// `plus` scratch. Two force evaluations, counted in `evals`.
#[allow(clippy::too_many_arguments)]
fn product(
    model: &mut dyn ForceModel,
    springs: &[Spring],
    u: &[f64],
    d: &[f64],
    q: &mut [f64],
    w: &mut [f64],
    plus: &mut [f64],
    length: f64,
    evals: &mut u64,
) -> Result<(), ElementFailure> {
    let dmax = d.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
    if dmax == 0.0 {
        q.iter_mut().for_each(|x| *x = 0.0);
        return Ok(());
    }
    let umax = u.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
    let eps = 1e-7 * umax.max(length) / dmax;
    for i in 0..u.len() {
        w[i] = u[i] + eps * d[i];
    }
    model.internal_forces(w, plus)?;
    add_springs(springs, w, plus);
    for i in 0..u.len() {
        w[i] = u[i] - eps * d[i];
    }
    model.internal_forces(w, q)?;
    add_springs(springs, w, q);
    *evals += 2;
    for i in 0..u.len() {
        q[i] = (plus[i] - q[i]) / (2.0 * eps);
    }
    Ok(())
}

impl NewtonLinear for MatrixFree {
    fn dofs(&self) -> &FreeDofs {
        &self.dofs
    }

    fn tangent(
        &mut self,
        model: &mut dyn ForceModel,
        springs: &[Spring],
        u: &[f64],
        lift: Option<(&[f64], &mut [f64])>,
        out: &mut DirectStatic,
    ) -> Result<f64, ElementFailure> {
        self.at.copy_from_slice(u);
        if let Some((delta, lifted)) = lift {
            let length = self.settings.length;
            product(
                model,
                springs,
                u,
                delta,
                &mut self.dir,
                &mut self.w,
                &mut self.plus,
                length,
                &mut out.force_evaluations,
            )?;
            self.dofs.project_all(&mut self.dir);
            self.dofs.gather(&self.dir, lifted);
            lifted.iter_mut().for_each(|v| *v = -*v);
        }
        Ok(0.0)
    }

    fn direction(
        &mut self,
        d: Direction<'_>,
        model: &mut dyn ForceModel,
        springs: &[Spring],
        _u: &[f64],
        rhs: &mut [f64],
        _sigma: &mut f64,
        out: &mut DirectStatic,
    ) -> Result<bool, DirectNewtonError> {
        let eta = match self.settings.tolerance {
            Some(tol) => tol,
            None => d.forcing.eta(),
        };
        let max_iter = self.settings.max_iter;
        let length = self.settings.length;
        let MatrixFree {
            dofs,
            inv_diag,
            at,
            dir,
            w,
            plus,
            minus,
            ..
        } = self;
        let evals = &mut out.force_evaluations;
        let end = cg_solve(
            |p: &[f64], q: &mut [f64]| {
                dofs.scatter(p, dir);
                product(model, springs, at, dir, minus, w, plus, length, evals)?;
                dofs.project_all(minus);
                dofs.gather(minus, q);
                Ok(())
            },
            |r: &[f64], z: &mut [f64]| {
                for ((z, r), m) in z.iter_mut().zip(r).zip(inv_diag.iter()) {
                    *z = m * r;
                }
                dofs.project_free(z);
                Ok(())
            },
            d.b,
            rhs,
            CgSettings::new(eta * d.bnorm, max_iter),
            None,
        )
        .map_err(DirectNewtonError::Inverted)?;
        out.cg_iterations += match end {
            PcgEnd::Converged(it) | PcgEnd::Truncated(it) | PcgEnd::Negative(it, _) => it,
            PcgEnd::MaxIter => max_iter,
            // Non-positive curvature along the first direction, `M⁻¹ b`: it is the step's
            // direction (`rhs` holds it; zero where the preconditioner was not positive).
            PcgEnd::Breakdown(_) => 1,
        };
        Ok(false)
    }

    fn sigma(&self) -> f64 {
        self.sigma
    }

    fn set_sigma(&mut self, sigma: f64) {
        self.sigma = sigma;
    }
}

/// Solve `R(u) = V` on a [`System`] (its external forces, springs and constraints at time
/// `t`) by Newton with matrix-free conjugate gradients preconditioned by the per-node `diag`
/// (the lumped mass where `None`); `u` is the start and receives the equilibrium. Any force
/// model, with or without an element tangent.
pub fn solve_system_matrix_free(
    sys: &mut System,
    diag: Option<&[f64]>,
    t: f64,
    u: &mut [f64],
    params: DirectNewtonParams,
    cg: MatrixFreeCg,
) -> Result<DirectStatic, DirectNewtonError> {
    let System {
        force,
        mass,
        f_ext,
        constraints,
        springs,
        ..
    } = sys;
    let mut lin = MatrixFree::with_diagonal(mass, diag.unwrap_or(mass), constraints, cg);
    solve_with(
        &mut lin,
        &mut **force,
        springs,
        constraints,
        f_ext,
        t,
        u,
        params,
    )
}
