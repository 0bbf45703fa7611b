//! The multigrid preconditioner of the tangent solves ([`super::tangent`]): one V-cycle of the
//! linearised problem `A e = d`, `A = K(u) + K_s` on the free dofs, over the stepper's levels.
//!
//! On level `l` (0 the finest) with operator `A_l`, diagonal `D_l` (the lumped mass) and
//! damping `ω_l = 4 / (3 · 1.1 λ̂_l)`, `λ̂_l` the largest eigenvalue of `D_l⁻¹ A_l` from ten
//! power iterations:
//!
//! ```text
//! z  = ω D⁻¹ d                               (one damped-Jacobi sweep from zero)
//! d_c = Pᵀ (d − A z)                         (residual restricted, P the prolongation)
//! e_c = V_{l+1}(d_c)                         (recursively; the coarsest: at most 10 CG
//!                                            iterations, to a relative residual of 0.1)
//! z += P e_c
//! z += ω D⁻¹ (d − A z)                       (post-smoothing, the same sweep)
//! ```
//!
//! The coarse operators are rediscretised: `A_c v = K_c(u_c) v + K_s,c v` with `K_c v` the
//! central difference of the coarse level's own internal forces at the restricted state
//! `u_c = R u` (`R` the state restriction, coarse nodes interpolated in the finer mesh, convex
//! weights as FAS uses them, [`crate::multigrid::fas`]) and `K_s,c = diag(Pᵀ k_s)` the springs'
//! stiffness lumped to the coarse nodes. A coarse node is held (zero correction) where the
//! finer level's constrained-node indicator, restricted by `R`, is at least ½: the supports,
//! the hard grasps and the pins, which also removes the coarse rigid modes.
//!
//! The inexact coarsest solve makes the cycle a slightly nonlinear operator, so the outer
//! conjugate gradients are the flexible variant (Polak–Ribière `β = z_{k+1}·(r_{k+1} − r_k) /
//! z_k·r_k`), which equals the plain one for a fixed symmetric preconditioner.

use crate::fem::{ElementFailure, ForceModel};
use crate::hierarchy::{Correspondence, Transfer};
use crate::mesh::Mesh;
use crate::Result;

/// Relative residual of the coarsest level's conjugate-gradient solve.
const COARSE_TOL: f64 = 1e-1;
/// Iteration cap of the coarsest solve.
const COARSE_MAX: usize = 10;
/// Power iterations for each level's `λ̂`.
const POWER: usize = 10;

/// The coarse levels as the preconditioner needs them, built once per simulation.
pub(super) struct TangentHierarchy {
    levels: Vec<Coarse>,
}

struct Coarse {
    model: Box<dyn ForceModel>,
    mass: Vec<f64>,
    length: f64,
    /// Coarse nodes in the finer mesh (state and indicator restriction).
    restrict: Transfer,
    /// Finer nodes in the coarse mesh (`P`; `Pᵀ` restricts residuals).
    prolong: Transfer,
}

impl TangentHierarchy {
    /// The coarse levels `meshes[1..]` below level 0 (`meshes[0]`), with force models from
    /// `params`.
    pub(super) fn build(
        meshes: &[&Mesh],
        params: &crate::fem::FemParams,
    ) -> Result<TangentHierarchy> {
        let mut levels = Vec::new();
        for w in meshes.windows(2) {
            let c = Correspondence::build(w[0], w[1])?;
            let model = crate::fem::FemModel::new(w[1], params.clone())?;
            let mass = model.lumped_mass();
            levels.push(Coarse {
                model: Box::new(model),
                mass,
                length: length_of(w[1]),
                restrict: c.up.convex(),
                prolong: c.down.convex(),
            });
        }
        Ok(TangentHierarchy { levels })
    }
}

/// `1e-3` of the mesh's bounding-box diagonal (m): the finite-difference length scale.
pub(super) fn length_of(mesh: &Mesh) -> f64 {
    let (lo, hi) = mesh.bounding_box();
    let l = 1e-3 * crate::mesh::norm(crate::mesh::sub(hi, lo));
    if l > 0.0 {
        l
    } else {
        1e-3
    }
}

/// `q = K(u) v` by central differences of `model`'s internal forces (all rows); `w`, `f`
/// scratch.
pub(super) fn fd_product(
    model: &mut dyn ForceModel,
    length: f64,
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
    let eps = 1e-7 * umax.max(length) / vmax;
    for i in 0..u.len() {
        w[i] = u[i] + eps * v[i];
    }
    model.internal_forces(w, f)?;
    for i in 0..u.len() {
        w[i] = u[i] - eps * v[i];
    }
    model.internal_forces(w, q)?;
    for i in 0..u.len() {
        q[i] = (f[i] - q[i]) / (2.0 * eps);
    }
    Ok(())
}

/// One level's linearised operator at a state: `A v = K(u) v + k_s v` on free dofs, zero on
/// the others.
pub(super) struct LevelOp {
    pub(super) u: Vec<f64>,
    pub(super) free: Vec<bool>,
    pub(super) kdiag: Vec<f64>,
    /// `1 / D` per dof (0 on constrained dofs).
    inv_d: Vec<f64>,
    omega: f64,
    length: f64,
    w: Vec<f64>,
    f: Vec<f64>,
    /// Cycle scratch: residual and correction.
    r: Vec<f64>,
    q: Vec<f64>,
    /// The coarse right-hand side and correction (this level's size).
    d: Vec<f64>,
    e: Vec<f64>,
}

impl LevelOp {
    pub(super) fn new(
        u: Vec<f64>,
        free: Vec<bool>,
        kdiag: Vec<f64>,
        mass: &[f64],
        length: f64,
    ) -> Self {
        let n = u.len();
        let inv_d = (0..n)
            .map(|i| {
                let m = mass[i / 3];
                if free[i] && m > 0.0 {
                    1.0 / m
                } else {
                    0.0
                }
            })
            .collect();
        let z = vec![0.0; n];
        LevelOp {
            u,
            free,
            kdiag,
            inv_d,
            omega: 0.0,
            length,
            w: z.clone(),
            f: z.clone(),
            r: z.clone(),
            q: z.clone(),
            d: z.clone(),
            e: z,
        }
    }

    /// `1 / D` per dof (the mass preconditioner).
    pub(super) fn inv_d(&self) -> &[f64] {
        &self.inv_d
    }

    /// The free dofs.
    pub(super) fn free(&self) -> &[bool] {
        &self.free
    }

    /// `q = A v`.
    pub(super) fn apply(
        &mut self,
        model: &mut dyn ForceModel,
        v: &[f64],
        q: &mut [f64],
    ) -> std::result::Result<(), ElementFailure> {
        fd_product(model, self.length, &self.u, v, q, &mut self.w, &mut self.f)?;
        for i in 0..v.len() {
            q[i] = if self.free[i] {
                q[i] + self.kdiag[i] * v[i]
            } else {
                0.0
            };
        }
        Ok(())
    }
}

/// The levels of one `grab_stiffness` call: level 0's operator and the coarse ones at the
/// restricted state.
pub(super) struct Cycle<'a> {
    pub(super) ops: Vec<LevelOp>,
    models: Vec<&'a mut dyn ForceModel>,
    links: Vec<(&'a Transfer, &'a Transfer)>,
    /// Tangent products of each level (0 the finest).
    pub(super) products: Vec<usize>,
}

impl<'a> Cycle<'a> {
    /// Restrict level 0's operator `top` (its model `fine`) down `h`'s levels.
    /// Level 0 alone when `h` is `None` (the mass preconditioner); a coarse level whose
    /// restricted state inverts an element ends the hierarchy there.
    pub(super) fn new(
        fine: &'a mut dyn ForceModel,
        top: LevelOp,
        h: Option<&'a mut TangentHierarchy>,
    ) -> std::result::Result<Cycle<'a>, ElementFailure> {
        let mut ops = vec![top];
        let mut models: Vec<&'a mut dyn ForceModel> = vec![fine];
        let mut links = Vec::new();
        let coarse = match h {
            Some(h) => &mut h.levels[..],
            None => &mut [],
        };
        for c in coarse.iter_mut() {
            let above = ops.last().expect("level 0");
            let nc = 3 * c.mass.len();
            let mut u = vec![0.0; nc];
            c.restrict
                .interpolate(&above.u, 3, &mut u)
                .expect("sizes match");
            let held: Vec<f64> = above
                .free
                .iter()
                .map(|&f| if f { 0.0 } else { 1.0 })
                .collect();
            let mut ind = vec![0.0; nc];
            c.restrict
                .interpolate(&held, 3, &mut ind)
                .expect("sizes match");
            let free: Vec<bool> = ind.iter().map(|&x| x < 0.5).collect();
            let mut kdiag = vec![0.0; nc];
            c.prolong
                .transpose_add(&above.kdiag, 3, &mut kdiag)
                .expect("sizes match");
            ops.push(LevelOp::new(u, free, kdiag, &c.mass, c.length));
            models.push(&mut *c.model);
            links.push((&c.restrict, &c.prolong));
        }
        let products = vec![0; ops.len()];
        let mut cy = Cycle {
            ops,
            models,
            links,
            products,
        };
        if cy.ops.len() > 1 {
            cy.estimate(0)?;
            for l in 1..cy.ops.len() {
                if cy.estimate(l).is_err() {
                    cy.ops.truncate(l);
                    cy.models.truncate(l);
                    cy.links.truncate(l - 1);
                    cy.products.truncate(l);
                    break;
                }
            }
        }
        Ok(cy)
    }

    /// `q = A_l v`, counted.
    pub(super) fn apply(
        &mut self,
        l: usize,
        v: &[f64],
        q: &mut [f64],
    ) -> std::result::Result<(), ElementFailure> {
        self.products[l] += 1;
        self.ops[l].apply(&mut *self.models[l], v, q)
    }

    /// `q = K(u) v` on level 0, every row (constrained ones included), no springs.
    pub(super) fn full_product(
        &mut self,
        v: &[f64],
        q: &mut [f64],
    ) -> std::result::Result<(), ElementFailure> {
        self.products[0] += 1;
        let op = &mut self.ops[0];
        fd_product(
            &mut *self.models[0],
            op.length,
            &op.u,
            v,
            q,
            &mut op.w,
            &mut op.f,
        )
    }

    /// `ω_l` from [`POWER`] power iterations on `D⁻¹ A` from a deterministic vector.
    fn estimate(&mut self, l: usize) -> std::result::Result<(), ElementFailure> {
        let n = self.ops[l].u.len();
        let mut x: Vec<f64> = (0..n)
            .map(|i| {
                if self.ops[l].free[i] {
                    crate::linalg::spectrum::start_entry(i as u64)
                } else {
                    0.0
                }
            })
            .collect();
        let mut y = vec![0.0; n];
        let inv_d = self.ops[l].inv_d.clone();
        let lambda = crate::linalg::spectrum::power_iteration(
            &mut x,
            crate::linalg::spectrum::Diagonal::InverseDof(&inv_d),
            POWER,
            &mut y,
            |x: &[f64], ax: &mut [f64]| self.apply(l, x, ax),
        )?;
        self.ops[l].omega = if lambda.is_finite() && lambda > 0.0 {
            4.0 / (3.0 * 1.1 * lambda)
        } else {
            0.0
        };
        Ok(())
    }

    /// `z = V_l(d)`: one V-cycle from level `l` (module docs).
    pub(super) fn vcycle(
        &mut self,
        l: usize,
        d: &[f64],
        z: &mut [f64],
    ) -> std::result::Result<(), ElementFailure> {
        let n = d.len();
        if l + 1 == self.ops.len() {
            return self.coarsest(l, d, z);
        }
        let omega = self.ops[l].omega;
        for i in 0..n {
            z[i] = omega * self.ops[l].inv_d[i] * d[i];
        }
        let mut q = std::mem::take(&mut self.ops[l].q);
        self.apply(l, z, &mut q)?;
        let mut r = std::mem::take(&mut self.ops[l].r);
        for i in 0..n {
            r[i] = if self.ops[l].free[i] {
                d[i] - q[i]
            } else {
                0.0
            };
        }
        let (_, prolong) = self.links[l];
        let mut dc = std::mem::take(&mut self.ops[l + 1].d);
        let mut ec = std::mem::take(&mut self.ops[l + 1].e);
        dc.fill(0.0);
        prolong.transpose_add(&r, 3, &mut dc).expect("sizes match");
        for (x, &f) in dc.iter_mut().zip(&self.ops[l + 1].free) {
            if !f {
                *x = 0.0;
            }
        }
        let res = self.vcycle(l + 1, &dc, &mut ec);
        if res.is_ok() {
            prolong.interpolate(&ec, 3, &mut r).expect("sizes match");
            for i in 0..n {
                if self.ops[l].free[i] {
                    z[i] += r[i];
                }
            }
        }
        self.ops[l + 1].d = dc;
        self.ops[l + 1].e = ec;
        // A coarse level that inverts an element in a product gives no correction.
        let res = self.apply(l, z, &mut q).map(|()| {
            for i in 0..n {
                z[i] += omega * self.ops[l].inv_d[i] * (d[i] - q[i]);
            }
        });
        self.ops[l].q = q;
        self.ops[l].r = r;
        res
    }

    /// Mass-preconditioned conjugate gradients from zero to [`COARSE_TOL`].
    fn coarsest(
        &mut self,
        l: usize,
        b: &[f64],
        x: &mut [f64],
    ) -> std::result::Result<(), ElementFailure> {
        let n = b.len();
        x.fill(0.0);
        let inv_d = self.ops[l].inv_d.clone();
        let bnorm = b.iter().map(|v| v * v).sum::<f64>().sqrt();
        let mut r = b.to_vec();
        let mut z: Vec<f64> = (0..n).map(|i| inv_d[i] * r[i]).collect();
        let mut p = z.clone();
        let mut q = vec![0.0; n];
        let mut rz: f64 = r.iter().zip(&z).map(|(a, b)| a * b).sum();
        for _ in 0..COARSE_MAX {
            let rn = r.iter().map(|v| v * v).sum::<f64>().sqrt();
            if !(rn > COARSE_TOL * bnorm) {
                break;
            }
            self.apply(l, &p, &mut q)?;
            let pq: f64 = p.iter().zip(&q).map(|(a, b)| a * b).sum();
            if !(pq > 0.0) {
                break;
            }
            let alpha = rz / pq;
            for i in 0..n {
                x[i] += alpha * p[i];
                r[i] -= alpha * q[i];
                z[i] = inv_d[i] * r[i];
            }
            let rz_new: f64 = r.iter().zip(&z).map(|(a, b)| a * b).sum();
            let beta = rz_new / rz;
            rz = rz_new;
            for i in 0..n {
                p[i] = z[i] + beta * p[i];
            }
        }
        Ok(())
    }
}
