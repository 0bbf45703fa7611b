//! The grasp stiffness `K_g = ∂ grab_force / ∂ x_g` by three tangent solves on the free dofs
//! (equations in the [`super`] module docs): conjugate gradients with matrix-free products
//! `K v ≈ (R(u + ε v) − R(u − ε v)) / (2 ε)` as in [`crate::statics::krylov`],
//! warm-started from the grasp's last solutions, preconditioned by one V-cycle of the
//! linearised problem over the stepper's levels ([`TangentPreconditioner::Multigrid`], the
//! default where the stepper has more than one level; flexible conjugate gradients) or by the
//! lumped mass ([`TangentPreconditioner::Mass`]). Both stop at the same relative residual
//! (`1e-9`), so they give the same `K_g` to that tolerance (a test).
//!
//! A spring grasp ([`super::Coupling::Spring`], node springs `k_a`, `Σ k_a = k`) pulls the free
//! nodes with `S_a = k_a (x_g + o_a − X_a − u_a)` and the tool feels
//! `f = Σ_a k_a (u_a + X_a − x_g − o_a)`. Differentiating the equilibrium
//! `R(u) − V − S(u, x_g) = 0` of the free nodes and `f`, with `K_s = diag(k_a)` and
//! `B` the `3n × 3` matrix with `k_a I` in node `a`'s rows:
//!
//! ```text
//! (K_FF + K_s) X = B,      K_g = Bᵀ X − k I,
//! ```
//!
//! three solves with the operator `K + K_s`. For one grasped node this is the series law of
//! the spring and the tissue's stiffness at the node, `−K_t` (`K_t` the hard grasp's tangent):
//! `K_g = −(k⁻¹ I + (−K_t)⁻¹)⁻¹ = k K_t (k I − K_t)⁻¹` (a test); as `k → ∞` it tends to the hard
//! grasp's.

use super::tangent_mg::{Cycle, LevelOp, TangentHierarchy};
use super::{Coupling, GrabId, Simulation};
use crate::fem::ElementFailure;
use crate::{Error, Result};

/// Relative residual at which a tangent solve stops.
const CG_TOL: f64 = 1e-9;

/// The preconditioner of the tangent solves of [`Simulation::grab_stiffness`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum TangentPreconditioner {
    /// One V-cycle of the linearised problem over the stepper's levels (module docs of
    /// `tangent_mg` in the source: damped-Jacobi smoothing, rediscretised coarse tangents at
    /// the restricted state, conjugate gradients on the coarsest); the lumped mass where the
    /// stepper has one level. The default.
    #[default]
    Multigrid,
    /// The lumped mass `M⁻¹`.
    Mass,
}

/// Work of the last [`Simulation::grab_stiffness`].
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct TangentStats {
    /// Conjugate-gradient iterations of the three solves together.
    pub iterations: usize,
    /// Tangent products per level (0 the finest), each two evaluations of that level's
    /// internal forces; one entry for the mass preconditioner.
    pub products: Vec<usize>,
    /// The preconditioner used (the mass where the multigrid one was asked for but the
    /// stepper has one level).
    pub preconditioner: TangentPreconditioner,
}

impl Simulation {
    /// Choose the preconditioner of [`Simulation::grab_stiffness`]'s solves.
    pub fn set_tangent_preconditioner(&mut self, p: TangentPreconditioner) {
        self.tangent_preconditioner = p;
    }

    /// The stiffness of grasp `id` at the current state: `K_g[i][k] = ∂ f_i / ∂ x_k` with `f`
    /// its [`Simulation::grab_force`] and `x` its position (N/m; module docs). Three
    /// conjugate-gradient solves with matrix-free tangent products, each warm-started from
    /// the last call's solution; an error if an element inverts in a product (the state is
    /// at the edge of validity).
    pub fn grab_stiffness(&mut self, id: GrabId) -> Result<[[f64; 3]; 3]> {
        let g = self.grab_ref(id)?;
        let nodes = g.nodes.clone();
        let kn: Vec<f64> = (0..nodes.len()).map(|i| g.node_stiffness(i)).collect();
        let total = match g.coupling {
            Coupling::Hard => None,
            Coupling::Spring { stiffness } => Some(stiffness),
        };
        let mut warm = g.warm.clone();
        let n = 3 * self.mesh.num_nodes();
        let u = self.stepper.state().u.clone();
        let free: Vec<bool> = (0..n).map(|i| !self.constrained[i / 3]).collect();
        // The springs' stiffness per dof (every spring grasp's: they all act on free nodes).
        let mut kdiag = vec![0.0; n];
        for s in &self.springs {
            for k in 0..3 {
                kdiag[3 * s.node as usize + k] += s.k;
            }
        }
        let fail = |e: ElementFailure| {
            Error::param(
                "grab_stiffness",
                format!(
                    "element {} inverts in a tangent product (det F = {:.3e})",
                    e.element, e.det_f
                ),
            )
        };
        let multigrid = self.tangent_preconditioner == TangentPreconditioner::Multigrid
            && self.stepper.num_levels() > 1;
        if multigrid && self.tangent_hierarchy.is_none() {
            let mut meshes = vec![&self.mesh];
            for l in 1..self.stepper.num_levels() {
                if let Some(m) = self.stepper.level_mesh(l) {
                    meshes.push(m);
                }
            }
            self.tangent_hierarchy = Some(TangentHierarchy::build(&meshes, &self.params)?);
        }
        let top = LevelOp::new(u, free, kdiag, &self.mass, self.length);
        let h = if multigrid {
            self.tangent_hierarchy.as_mut()
        } else {
            None
        };
        let mut cy = Cycle::new(&mut *self.model, top, h).map_err(fail)?;
        let multigrid = cy.ops.len() > 1;
        let mut k_g = [[0.0; 3]; 3];
        let mut iterations = 0;
        let mut s = Scratch::new(n);
        for axis in 0..3 {
            let x = &mut warm[axis];
            if x.len() != n {
                *x = vec![0.0; n];
            }
            let mut b = vec![0.0; n];
            match total {
                None => {
                    // w: the unit rigid move of the grasped nodes along `axis`; b = −(K w)_F.
                    s.w.fill(0.0);
                    for &a in &nodes {
                        s.w[3 * a as usize + axis] = 1.0;
                    }
                    let w = s.w.clone();
                    cy.apply(0, &w, &mut s.q).map_err(fail)?;
                    // The operator zeroes constrained rows and adds the springs' k w, zero
                    // on the grasped (constrained) nodes: b = −(K w)_F.
                    b.iter_mut().zip(&s.q).for_each(|(b, q)| *b = -q);
                }
                Some(_) => {
                    // b = B e_axis: the springs' pull on the nodes per unit tool move.
                    for (&a, &ka) in nodes.iter().zip(&kn) {
                        b[3 * a as usize + axis] = ka;
                    }
                }
            }
            iterations += tangent_solve(&mut cy, multigrid, &b, x).map_err(fail)?;
            match total {
                None => {
                    // δu = w + x; column = −Σ_{a ∈ g} (K δu)_a, all rows (the grasped ones).
                    let du: Vec<f64> = (0..n).map(|i| s.w[i] + x[i]).collect();
                    cy.full_product(&du, &mut s.q).map_err(fail)?;
                    for &a in &nodes {
                        for (i, row) in k_g.iter_mut().enumerate() {
                            row[axis] -= s.q[3 * a as usize + i];
                        }
                    }
                }
                Some(k) => {
                    // column = Bᵀ x − k e_axis.
                    for (&a, &ka) in nodes.iter().zip(&kn) {
                        for (i, row) in k_g.iter_mut().enumerate() {
                            row[axis] += ka * x[3 * a as usize + i];
                        }
                    }
                    k_g[axis][axis] -= k;
                }
            }
        }
        let products = cy.products.clone();
        drop(cy);
        if let Some(g) = self.grabs.get_mut(&id) {
            g.warm = warm;
        }
        self.tangent_stats = TangentStats {
            iterations,
            products,
            preconditioner: if multigrid {
                TangentPreconditioner::Multigrid
            } else {
                TangentPreconditioner::Mass
            },
        };
        Ok(k_g)
    }

    /// Conjugate-gradient iterations of the last [`Simulation::grab_stiffness`] (the three
    /// solves together).
    pub fn tangent_iterations(&self) -> usize {
        self.tangent_stats.iterations
    }

    /// The work of the last [`Simulation::grab_stiffness`].
    pub fn tangent_stats(&self) -> &TangentStats {
        &self.tangent_stats
    }
}

/// Solve `A x = b` on level 0's free dofs by conjugate gradients from `x`, preconditioned by
/// one V-cycle (flexible, Polak–Ribière `β`: the cycle's finite-difference products are not
/// exactly linear) or by the lumped mass ([`crate::linalg::cg`]); returns the iterations.
fn tangent_solve(
    cy: &mut Cycle<'_>,
    multigrid: bool,
    b: &[f64],
    x: &mut [f64],
) -> std::result::Result<usize, ElementFailure> {
    use crate::linalg::cg::{solve, CgSettings, PcgEnd};
    let n = b.len();
    let bnorm = b.iter().map(|v| v * v).sum::<f64>().sqrt();
    let free = cy.ops[0].free().to_vec();
    for i in 0..n {
        if !free[i] {
            x[i] = 0.0;
        }
    }
    let settings = CgSettings {
        warm: true,
        flexible: multigrid,
        ..CgSettings::new(CG_TOL * bnorm, 20 * n.max(50))
    };
    // The product and the preconditioner both run on the cycle's levels: one at a time.
    let cy = std::cell::RefCell::new(cy);
    let end = solve(
        |p: &[f64], q: &mut [f64]| cy.borrow_mut().apply(0, p, q),
        |d: &[f64], z: &mut [f64]| {
            let mut cy = cy.borrow_mut();
            if multigrid {
                cy.vcycle(0, d, z)
            } else {
                let inv_d = cy.ops[0].inv_d();
                for i in 0..d.len() {
                    z[i] = inv_d[i] * d[i];
                }
                Ok(())
            }
        },
        b,
        x,
        settings,
        None,
    )?;
    Ok(match end {
        PcgEnd::Converged(it) | PcgEnd::Truncated(it) | PcgEnd::Negative(it, _) => it,
        PcgEnd::MaxIter => settings.max_iter,
        PcgEnd::Breakdown(_) => 0,
    })
}

/// The tangent solves' vectors.
struct Scratch {
    w: Vec<f64>,
    q: Vec<f64>,
}

impl Scratch {
    fn new(n: usize) -> Self {
        Scratch {
            w: vec![0.0; n],
            q: vec![0.0; n],
        }
    }
}
