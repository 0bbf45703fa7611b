//! The grasp stiffness `K_g = ∂ grab_force / ∂ x_g` by three tangent solves on the free dofs
//! (equations in the [`super`] module docs): conjugate gradients preconditioned by the lumped
//! mass, with matrix-free products `K v ≈ (R(u + ε v) − R(u − ε v)) / (2 ε)` as in
//! [`crate::integrate::statics`], warm-started from the grasp's last solutions.
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
use crate::fem::ElementFailure;
use crate::{Error, Result};

/// Relative residual at which a tangent solve stops.
const CG_TOL: f64 = 1e-9;

impl Simulation {
    /// `q = K(u) v` by central differences of the internal forces (all rows).
    fn tangent_product(
        &mut self,
        u: &[f64],
        v: &[f64],
        q: &mut [f64],
        w: &mut [f64],
        f: &mut [f64],
    ) -> std::result::Result<(), ElementFailure> {
        let vmax = v.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
        if vmax == 0.0 {
            q.fill(0.0);
            return Ok(());
        }
        let umax = u.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
        let eps = 1e-7 * umax.max(self.length) / vmax;
        for i in 0..u.len() {
            w[i] = u[i] + eps * v[i];
        }
        self.model.internal_forces(w, f)?;
        for i in 0..u.len() {
            w[i] = u[i] - eps * v[i];
        }
        self.model.internal_forces(w, q)?;
        for i in 0..u.len() {
            q[i] = (f[i] - q[i]) / (2.0 * eps);
        }
        Ok(())
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
        let inv_m: Vec<f64> = (0..n)
            .map(|i| {
                let m = self.mass[i / 3];
                if free[i] && m > 0.0 {
                    1.0 / m
                } else {
                    0.0
                }
            })
            .collect();
        let mut s = Scratch::new(n);
        let fail = |e: ElementFailure| {
            Error::param(
                "grab_stiffness",
                format!(
                    "element {} inverts in a tangent product (det F = {:.3e})",
                    e.element, e.det_f
                ),
            )
        };
        let mut k_g = [[0.0; 3]; 3];
        let mut iterations = 0;
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
                    self.tangent_product(&u, &w, &mut s.q, &mut s.scratch, &mut s.f)
                        .map_err(fail)?;
                    for i in 0..n {
                        b[i] = if free[i] { -s.q[i] } else { 0.0 };
                    }
                }
                Some(_) => {
                    // b = B e_axis: the springs' pull on the nodes per unit tool move.
                    for (&a, &ka) in nodes.iter().zip(&kn) {
                        b[3 * a as usize + axis] = ka;
                    }
                }
            }
            iterations += self
                .tangent_solve(&u, &free, &kdiag, &inv_m, &b, x, &mut s)
                .map_err(fail)?;
            match total {
                None => {
                    // δu = w + x; column = −Σ_{a ∈ g} (K δu)_a.
                    let du: Vec<f64> = (0..n).map(|i| s.w[i] + x[i]).collect();
                    self.tangent_product(&u, &du, &mut s.q, &mut s.scratch, &mut s.f)
                        .map_err(fail)?;
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
        if let Some(g) = self.grabs.get_mut(&id) {
            g.warm = warm;
        }
        self.tangent_iterations = iterations;
        Ok(k_g)
    }

    /// Conjugate-gradient iterations of the last [`Simulation::grab_stiffness`] (the three
    /// solves together).
    pub fn tangent_iterations(&self) -> usize {
        self.tangent_iterations
    }

    /// Solve `(K_FF + K_s) x = b` on the free dofs (`K_s` the springs' diagonal `kdiag`) by
    /// conjugate gradients from `x`, preconditioned by `inv_m`; returns the iterations.
    #[allow(clippy::too_many_arguments)]
    fn tangent_solve(
        &mut self,
        u: &[f64],
        free: &[bool],
        kdiag: &[f64],
        inv_m: &[f64],
        b: &[f64],
        x: &mut [f64],
        s: &mut Scratch,
    ) -> std::result::Result<usize, ElementFailure> {
        let n = u.len();
        let bnorm = b.iter().map(|v| v * v).sum::<f64>().sqrt();
        for i in 0..n {
            if !free[i] {
                x[i] = 0.0;
            }
        }
        // d = b − A x.
        self.operator(u, free, kdiag, x, s)?;
        for i in 0..n {
            s.d[i] = b[i] - s.q[i];
            s.z[i] = inv_m[i] * s.d[i];
        }
        s.p.copy_from_slice(&s.z);
        let mut rz: f64 = s.d.iter().zip(&s.z).map(|(a, b)| a * b).sum();
        let mut it = 0;
        while it < 20 * n.max(50) {
            let dn = s.d.iter().map(|v| v * v).sum::<f64>().sqrt();
            if !(dn > CG_TOL * bnorm) {
                break;
            }
            let p = std::mem::take(&mut s.p);
            self.operator(u, free, kdiag, &p, s)?;
            s.p = p;
            it += 1;
            let pq: f64 = s.p.iter().zip(&s.q).map(|(a, b)| a * b).sum();
            if !(pq > 0.0) {
                break;
            }
            let alpha = rz / pq;
            for i in 0..n {
                x[i] += alpha * s.p[i];
                s.d[i] -= alpha * s.q[i];
                s.z[i] = inv_m[i] * s.d[i];
            }
            let rz_new: f64 = s.d.iter().zip(&s.z).map(|(a, b)| a * b).sum();
            let beta = rz_new / rz;
            rz = rz_new;
            for i in 0..n {
                s.p[i] = s.z[i] + beta * s.p[i];
            }
        }
        Ok(it)
    }

    /// `s.q = (K + K_s) v` on the free dofs, zero on the others.
    fn operator(
        &mut self,
        u: &[f64],
        free: &[bool],
        kdiag: &[f64],
        v: &[f64],
        s: &mut Scratch,
    ) -> std::result::Result<(), ElementFailure> {
        self.tangent_product(u, v, &mut s.q, &mut s.scratch, &mut s.f)?;
        for i in 0..u.len() {
            s.q[i] = if free[i] {
                s.q[i] + kdiag[i] * v[i]
            } else {
                0.0
            };
        }
        Ok(())
    }
}

/// The tangent solves' vectors.
struct Scratch {
    w: Vec<f64>,
    q: Vec<f64>,
    scratch: Vec<f64>,
    f: Vec<f64>,
    d: Vec<f64>,
    z: Vec<f64>,
    p: Vec<f64>,
}

impl Scratch {
    fn new(n: usize) -> Self {
        let z = vec![0.0; n];
        Scratch {
            w: z.clone(),
            q: z.clone(),
            scratch: z.clone(),
            f: z.clone(),
            d: z.clone(),
            z: z.clone(),
            p: z,
        }
    }
}
