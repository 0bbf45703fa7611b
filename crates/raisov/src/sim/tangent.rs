//! The grasp stiffness `K_g = ∂ grab_force / ∂ x_g` by three tangent solves on the free dofs
//! (equations in the [`super`] module docs): conjugate gradients preconditioned by the lumped
//! mass, with matrix-free products `K v ≈ (R(u + ε v) − R(u − ε v)) / (2 ε)` as in
//! [`crate::integrate::statics`], warm-started from the grasp's last solutions.

use super::{GrabId, Simulation};
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
        let mut warm = g.warm.clone();
        let n = 3 * self.mesh.num_nodes();
        let u = self.stepper.state().u.clone();
        let free: Vec<bool> = (0..n).map(|i| !self.constrained[i / 3]).collect();
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
        let z0 = vec![0.0; n];
        let (mut wv, mut q, mut scratch, mut f) = (z0.clone(), z0.clone(), z0.clone(), z0.clone());
        let (mut d, mut z, mut p) = (z0.clone(), z0.clone(), z0.clone());
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
        for axis in 0..3 {
            // w: the unit rigid move of the grasped nodes along `axis`.
            wv.fill(0.0);
            for &a in &nodes {
                wv[3 * a as usize + axis] = 1.0;
            }
            let x = &mut warm[axis];
            if x.len() != n {
                *x = vec![0.0; n];
            }
            // b = −(K w)_F; residual d = b − K_FF x.
            self.tangent_product(&u, &wv, &mut q, &mut scratch, &mut f)
                .map_err(fail)?;
            let mut bnorm = 0.0f64;
            for i in 0..n {
                d[i] = if free[i] { -q[i] } else { 0.0 };
                bnorm += d[i] * d[i];
                if !free[i] {
                    x[i] = 0.0;
                }
            }
            let bnorm = bnorm.sqrt();
            self.tangent_product(&u, x, &mut q, &mut scratch, &mut f)
                .map_err(fail)?;
            for i in 0..n {
                if free[i] {
                    d[i] -= q[i];
                }
            }
            for i in 0..n {
                z[i] = inv_m[i] * d[i];
            }
            p.copy_from_slice(&z);
            let mut rz: f64 = d.iter().zip(&z).map(|(a, b)| a * b).sum();
            for _ in 0..20 * n.max(50) {
                let dn = d.iter().map(|v| v * v).sum::<f64>().sqrt();
                if !(dn > CG_TOL * bnorm) {
                    break;
                }
                self.tangent_product(&u, &p, &mut q, &mut scratch, &mut f)
                    .map_err(fail)?;
                for i in 0..n {
                    if !free[i] {
                        q[i] = 0.0;
                    }
                }
                let pq: f64 = p.iter().zip(&q).map(|(a, b)| a * b).sum();
                if !(pq > 0.0) {
                    break;
                }
                let alpha = rz / pq;
                for i in 0..n {
                    x[i] += alpha * p[i];
                    d[i] -= alpha * q[i];
                }
                for i in 0..n {
                    z[i] = inv_m[i] * d[i];
                }
                let rz_new: f64 = d.iter().zip(&z).map(|(a, b)| a * b).sum();
                let beta = rz_new / rz;
                rz = rz_new;
                for i in 0..n {
                    p[i] = z[i] + beta * p[i];
                }
            }
            // δu = w + x; column = −Σ_{a ∈ g} (K δu)_a.
            for i in 0..n {
                scratch[i] = wv[i] + x[i];
            }
            let du = scratch.clone();
            self.tangent_product(&u, &du, &mut q, &mut scratch, &mut f)
                .map_err(fail)?;
            for &a in &nodes {
                for (i, row) in k_g.iter_mut().enumerate() {
                    row[axis] -= q[3 * a as usize + i];
                }
            }
        }
        if let Some(g) = self.grabs.get_mut(&id) {
            g.warm = warm;
        }
        Ok(k_g)
    }
}
