//! The grasp stiffness `K_g = ∂ grab_force / ∂ x_g` by three tangent solves on the free dofs
//! (equations in the [`super`] module docs), with the static solver's operator and
//! preconditioners ([`crate::statics::newton::DirectNewton::tangent_solves`]): the assembled
//! tangent `K` of level 0's force model (its elements, a follower pressure's and the tools'
//! blocks, the springs' `k I`), solved by conjugate gradients preconditioned by the Galerkin
//! V-cycle over level 0 and one coarser level of the stepper (the one a static solve would
//! take, [`crate::statics::newton::coarse_level`]; [`TangentPreconditioner::Multigrid`], the
//! default, warm-started from the grasp's last solutions, to a relative residual of `1e-9`),
//! or by its sparse Cholesky factor ([`TangentPreconditioner::Direct`], and where the stepper
//! has no coarser level). Both give the same `K_g` to that tolerance (a test). The products
//! with the grasped nodes' rigid moves `K w` are applied element by element over the
//! elements touching them ([`crate::fem::tangent_products`]); `K` is symmetric, so the
//! column's sum over the grasped nodes is `−wᵢᵀ K w_k − (K wᵢ)ᵀ x_k`.
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

use super::{Coupling, GrabId, Simulation};
use crate::hierarchy::Transfer;
use crate::integrate::Constraints;
use crate::statics::newton::{coarse_level, DirectNewton, DirectNewtonError, TangentSolver};
use crate::{Error, Result};

/// Relative residual at which an iterative tangent solve stops.
const CG_TOL: f64 = 1e-9;

/// The preconditioner of the tangent solves of [`Simulation::grab_stiffness`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum TangentPreconditioner {
    /// Conjugate gradients preconditioned by the Galerkin V-cycle over level 0 and one coarser
    /// level of the stepper (the static solver's); the sparse Cholesky factor where the
    /// stepper has no level it would take. The default.
    #[default]
    Multigrid,
    /// The sparse Cholesky factor of the assembled tangent: exact to rounding, one
    /// factorisation per call.
    Direct,
}

/// Work of the last [`Simulation::grab_stiffness`].
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct TangentStats {
    /// Conjugate-gradient iterations of the three solves together (0 for the direct solve).
    pub iterations: usize,
    /// Factorisations or Galerkin hierarchies built (one per call).
    pub setups: usize,
    /// The preconditioner used (the direct solve where the multigrid one was asked for but
    /// the stepper has no coarser level a static solve would take).
    pub preconditioner: TangentPreconditioner,
}

/// The assembled tangent's structure for the current constraints, kept between calls.
pub(super) struct TangentOperator {
    /// The constrained nodes it was built for.
    constrained: Vec<bool>,
    /// The level-0-to-coarse transfer of the multigrid preconditioner (`None`: direct).
    multigrid: bool,
    solver: DirectNewton,
}

impl Simulation {
    /// Choose the preconditioner of [`Simulation::grab_stiffness`]'s solves.
    pub fn set_tangent_preconditioner(&mut self, p: TangentPreconditioner) {
        if p != self.tangent_preconditioner {
            self.tangent_operator = None;
        }
        self.tangent_preconditioner = p;
    }

    /// The level-0-to-coarse transfer of the multigrid preconditioner, where the stepper has
    /// a coarser level a static solve would take.
    fn tangent_transfer(&self) -> Result<Option<Transfer>> {
        let levels = self.stepper.num_levels();
        let meshes: Vec<&crate::mesh::Mesh> = (1..levels)
            .filter_map(|l| self.stepper.level_mesh(l))
            .collect();
        let mut nodes = vec![self.mesh.num_nodes()];
        nodes.extend(meshes.iter().map(|m| m.num_nodes()));
        match coarse_level(&nodes) {
            Some(c) if c >= 1 => Ok(Some(Transfer::build(&self.mesh.nodes, meshes[c - 1])?)),
            _ => Ok(None),
        }
    }

    /// The stiffness of grasp `id` at the current state: `K_g[i][k] = ∂ f_i / ∂ x_k` with `f`
    /// its [`Simulation::grab_force`] and `x` its position (N/m; module docs). Three solves
    /// with the assembled tangent, iterative ones warm-started from the last call's
    /// solutions; an error if an element cannot be evaluated or the tangent of the free
    /// nodes is not positive definite at this state (it is at a stable equilibrium).
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
        let fail = |e: DirectNewtonError| Error::param("grab_stiffness", e.to_string());
        // The operator for the current constraints (built again where they changed).
        if self
            .tangent_operator
            .as_ref()
            .is_none_or(|op| op.constrained != self.constrained)
        {
            let fixed: Vec<u32> = (0..self.constrained.len() as u32)
                .filter(|&a| self.constrained[a as usize])
                .collect();
            let constraints = Constraints::new(fixed, Vec::new()).with_nodes(n / 3);
            let down = match self.tangent_preconditioner {
                TangentPreconditioner::Multigrid => self.tangent_transfer()?,
                TangentPreconditioner::Direct => None,
            };
            let solver = match &down {
                Some(t) => DirectNewton::with_levels(
                    &*self.model,
                    &self.mass,
                    &constraints,
                    std::slice::from_ref(t),
                ),
                None => DirectNewton::new(&*self.model, &self.mass, &constraints),
            }
            .map_err(fail)?;
            self.tangent_operator = Some(TangentOperator {
                constrained: self.constrained.clone(),
                multigrid: down.is_some(),
                solver,
            });
        }
        let multigrid = self
            .tangent_operator
            .as_ref()
            .is_some_and(|op| op.multigrid);
        let solve_with = if multigrid {
            TangentSolver::Multigrid {
                tol: CG_TOL,
                max_iter: 20 * n.max(50),
                smoother: crate::scenario::StaticSolve::default_smoother(self.mesh.kind),
            }
        } else {
            TangentSolver::Direct
        };
        // Right-hand sides: a hard grasp's −(K w_k)_F, w_k the unit rigid move of the grasped
        // nodes along k; a spring grasp's B e_k.
        let mut w = vec![vec![0.0; n]; 3];
        let mut kw = vec![vec![0.0; n]; 3];
        let mut b = vec![vec![0.0; n]; 3];
        match total {
            None => {
                for (axis, wa) in w.iter_mut().enumerate() {
                    for &a in &nodes {
                        wa[3 * a as usize + axis] = 1.0;
                    }
                }
                {
                    let vs: Vec<&[f64]> = w.iter().map(|v| v.as_slice()).collect();
                    let mut outs: Vec<&mut [f64]> =
                        kw.iter_mut().map(|v| v.as_mut_slice()).collect();
                    crate::fem::tangent_products(&*self.model, &u, &vs, &mut outs)
                        .map_err(|e| fail(DirectNewtonError::Inverted(e)))?;
                }
                // The springs' k I (of other grasps) on the moved nodes.
                for s in &self.springs {
                    for axis in 0..3 {
                        let i = 3 * s.node as usize;
                        let kwa = s.tangent_times(&u, &w[axis]);
                        for k in 0..3 {
                            kw[axis][i + k] += kwa[k];
                        }
                    }
                }
                for axis in 0..3 {
                    for i in 0..n {
                        b[axis][i] = -kw[axis][i];
                    }
                }
            }
            Some(_) => {
                for (axis, ba) in b.iter_mut().enumerate() {
                    for (&a, &ka) in nodes.iter().zip(&kn) {
                        ba[3 * a as usize + axis] = ka;
                    }
                }
            }
        }
        for x in warm.iter_mut() {
            if x.len() != n {
                *x = vec![0.0; n];
            }
        }
        let op = self.tangent_operator.as_mut().expect("built above");
        let work = {
            let mut columns: Vec<(&[f64], &mut [f64])> = b
                .iter()
                .map(|v| v.as_slice())
                .zip(warm.iter_mut().map(|v| v.as_mut_slice()))
                .collect();
            op.solver
                .tangent_solves(&*self.model, &self.springs, &u, &mut columns, solve_with)
                .map_err(fail)?
        };
        let mut k_g = [[0.0; 3]; 3];
        for axis in 0..3 {
            let x = &warm[axis];
            match total {
                None => {
                    // Column k: −Σ_{a ∈ g} (K (w_k + x_k))_a, with (K x)'s grasped rows summed
                    // as (K wᵢ)ᵀ x (K symmetric, x zero on constrained dofs).
                    for (i, row) in k_g.iter_mut().enumerate() {
                        let kww: f64 = nodes.iter().map(|&a| kw[axis][3 * a as usize + i]).sum();
                        let kwx: f64 = kw[i].iter().zip(x).map(|(p, q)| p * q).sum();
                        row[axis] = -kww - kwx;
                    }
                }
                Some(k) => {
                    // Column k: Bᵀ x − k e_k.
                    for (&a, &ka) in nodes.iter().zip(&kn) {
                        for (i, row) in k_g.iter_mut().enumerate() {
                            row[axis] += ka * x[3 * a as usize + i];
                        }
                    }
                    k_g[axis][axis] -= k;
                }
            }
        }
        if let Some(g) = self.grabs.get_mut(&id) {
            g.warm = warm;
        }
        self.tangent_stats = TangentStats {
            iterations: work.iterations,
            setups: work.setups,
            preconditioner: if multigrid {
                TangentPreconditioner::Multigrid
            } else {
                TangentPreconditioner::Direct
            },
        };
        Ok(k_g)
    }

    /// Conjugate-gradient iterations of the last [`Simulation::grab_stiffness`] (the three
    /// solves together; 0 for the direct solve).
    pub fn tangent_iterations(&self) -> usize {
        self.tangent_stats.iterations
    }

    /// The work of the last [`Simulation::grab_stiffness`].
    pub fn tangent_stats(&self) -> &TangentStats {
        &self.tangent_stats
    }
}
