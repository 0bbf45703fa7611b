//! The Newton system's unknowns: the free dofs, in free-index order. A dof held by the
//! constraints (a fixed or prescribed node's, a sliding node's component along x, y or z) is
//! eliminated by index ([`fixed_dof`]); the others are numbered in dof order.
//!
//! Sliding along directions other than x, y or z, by projection: a node that keeps
//! `u·n = 0` for unit directions `n` not along an axis (a symmetry plane or a roller at an
//! angle) keeps its three dofs, and every quantity of the solve is projected onto its
//! admissible motions with `P_a = I − Σ_n n nᵀ` (the constraint's own projection,
//! [`Constraints::zero_constrained`]):
//!
//! ```text
//! r_a ← P_a r_a,     K_ab ← P_a K_ab P_b,     K_aa ← P_a K_aa P_a + d̄ (I − P_a),
//! ```
//!
//! `d̄` the mean diagonal of the assembled `K`. The added `d̄ (I − P_a)` gives the constrained
//! directions a stiffness of the tangent's own scale and decouples them: on a right-hand
//! side `b = P b` the solution has `(I − P_a) δ_a = 0`, so the projected Newton system
//! `P K P δ = P r` is solved on the admissible motions, by the Cholesky factor and by the
//! multigrid-preconditioned conjugate gradients alike (the matrix-free products of
//! [`super::MatrixFree`] are projected as they are made). Steps, solutions and the states
//! taken are projected again after each solve, so a sliding node keeps `u·n = 0` to
//! rounding's last bit. Where no node slides obliquely none of this runs, and the bits are
//! those of elimination alone.

use super::*;

/// A node that slides along a direction other than x, y or z.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Oblique {
    /// The node.
    pub node: usize,
    /// The free index of each of its dofs (`usize::MAX` where one is eliminated: an axis
    /// direction of the same node).
    pub free: [usize; 3],
    /// `P_a = I − Σ n nᵀ` over its oblique directions, row-major.
    pub proj: [f64; 9],
}

/// The nodes of `constraints` that slide along a direction other than x, y or z (fixed and
/// prescribed nodes ignore their sliding entries), by node, with their free indices under
/// `free`.
fn oblique_nodes(constraints: &Constraints, free: &[usize]) -> Vec<Oblique> {
    let mut out: Vec<Oblique> = Vec::new();
    for &(node, n) in constraints.sliding() {
        let a = node as usize;
        if axis_of(n).is_some() || constraints.is_constrained(a) {
            continue;
        }
        if out.last().is_none_or(|o| o.node != a) {
            let mut proj = [0.0; 9];
            for k in 0..3 {
                proj[4 * k] = 1.0;
            }
            out.push(Oblique {
                node: a,
                free: [free[3 * a], free[3 * a + 1], free[3 * a + 2]],
                proj,
            });
        }
        let o = out.last_mut().expect("pushed above");
        for k in 0..3 {
            for l in 0..3 {
                o.proj[3 * k + l] -= n[k] * n[l];
            }
        }
    }
    out
}

/// `x_a ← P_a x_a` for node `a` (3 entries from `at`).
fn project3(proj: &[f64; 9], x: &mut [f64], at: usize) {
    let v = [x[at], x[at + 1], x[at + 2]];
    for k in 0..3 {
        x[at + k] = proj[3 * k] * v[0] + proj[3 * k + 1] * v[1] + proj[3 * k + 2] * v[2];
    }
}

/// The residual's projection onto the admissible motions of the nodes of `constraints` that
/// slide along a direction other than x, y or z ([`super::search::Residual`]).
pub(super) fn project_residual(constraints: &Constraints, r: &mut [f64]) {
    for &(node, n) in constraints.sliding() {
        if axis_of(n).is_none() {
            let i = 3 * node as usize;
            let d = r[i] * n[0] + r[i + 1] * n[1] + r[i + 2] * n[2];
            for k in 0..3 {
                r[i + k] -= d * n[k];
            }
        }
    }
}

/// The free dofs of a mesh under its constraints (module docs), with the regularisation's
/// weight per free dof.
#[derive(Clone, Debug)]
pub struct FreeDofs {
    /// Free-dof index of each dof, `usize::MAX` where constrained.
    pub(super) free: Vec<usize>,
    /// Number of free dofs.
    pub(super) nfree: usize,
    /// The nodes sliding along a direction other than x, y or z, by node.
    pub(super) oblique: Vec<Oblique>,
    /// Per node, its index in `oblique` (`u32::MAX`: none); empty where no node slides
    /// obliquely.
    pub(super) oblique_index: Vec<u32>,
    /// Regularisation weight per free dof (`m_a / mean m`, the lumped mass `D`).
    pub(super) weight: Vec<f64>,
}

impl FreeDofs {
    /// The free dofs of `nodes` nodes under `constraints`, weighted by the lumped `mass` (kg
    /// per node).
    pub fn new(nodes: usize, mass: &[f64], constraints: &Constraints) -> FreeDofs {
        let mut free = vec![usize::MAX; 3 * nodes];
        let mut nfree = 0;
        for (i, f) in free.iter_mut().enumerate() {
            if !fixed_dof(constraints, i) {
                *f = nfree;
                nfree += 1;
            }
        }
        let mean = mass.iter().sum::<f64>() / nodes.max(1) as f64;
        let mut weight = vec![1.0; nfree];
        for (i, &f) in free.iter().enumerate() {
            if f != usize::MAX && mean > 0.0 {
                weight[f] = mass[i / 3] / mean;
            }
        }
        let oblique = oblique_nodes(constraints, &free);
        let oblique_index = index_of(&oblique, nodes);
        FreeDofs {
            free,
            nfree,
            oblique,
            oblique_index,
            weight,
        }
    }

    /// The number of free dofs.
    pub fn len(&self) -> usize {
        self.nfree
    }

    /// Whether no dof is free.
    pub fn is_empty(&self) -> bool {
        self.nfree == 0
    }

    /// Whether dof `i` is free.
    pub fn is_free(&self, i: usize) -> bool {
        self.free[i] != usize::MAX
    }

    /// Whether `constraints` leave free the dofs these leave free, with the same nodes
    /// sliding obliquely.
    pub(super) fn same_oblique(&self, constraints: &Constraints) -> bool {
        oblique_nodes(constraints, &self.free) == self.oblique
    }

    /// `out[f] = x[i]` for every free dof i with free index f (`x` in all dofs' layout).
    pub fn gather(&self, x: &[f64], out: &mut [f64]) {
        for (i, &f) in self.free.iter().enumerate() {
            if f != usize::MAX {
                out[f] = x[i];
            }
        }
    }

    /// `out[i] = x[f(i)]` for every free dof i with free index f, zero on constrained dofs,
    /// projected onto the obliquely sliding nodes' planes or lines.
    pub fn scatter(&self, x: &[f64], out: &mut [f64]) {
        for (i, &f) in self.free.iter().enumerate() {
            out[i] = if f == usize::MAX { 0.0 } else { x[f] };
        }
        self.project_all(out);
    }

    /// `out = u + α δ`, `δ` over the free dofs (free-index order), projected as
    /// [`FreeDofs::scatter`].
    pub fn step_to(&self, u: &[f64], alpha: f64, delta: &[f64], out: &mut [f64]) {
        out.copy_from_slice(u);
        for (i, &f) in self.free.iter().enumerate() {
            if f != usize::MAX {
                out[i] += alpha * delta[f];
            }
        }
        self.project_all(out);
    }

    /// `Σ_i x[i] y[f(i)]` over the free dofs i, `x` in all dofs' layout, `y` over the free
    /// ones (free-index order).
    pub fn dot(&self, x: &[f64], y: &[f64]) -> f64 {
        self.free
            .iter()
            .enumerate()
            .filter(|(_, &f)| f != usize::MAX)
            .map(|(i, &f)| x[i] * y[f])
            .sum()
    }

    /// Whether a node slides along a direction other than x, y or z.
    pub(super) fn has_oblique(&self) -> bool {
        !self.oblique.is_empty()
    }

    /// `x_a ← P_a x_a` for each obliquely sliding node (`x` in all dofs' layout).
    pub fn project_all(&self, x: &mut [f64]) {
        for o in &self.oblique {
            project3(&o.proj, x, 3 * o.node);
        }
    }

    /// The same over the free dofs (free-index order); an eliminated dof stays as it is (it
    /// is orthogonal to the node's oblique directions).
    pub fn project_free(&self, x: &mut [f64]) {
        for o in &self.oblique {
            let v = o.free.map(|f| if f == usize::MAX { 0.0 } else { x[f] });
            for k in 0..3 {
                if o.free[k] != usize::MAX {
                    x[o.free[k]] =
                        o.proj[3 * k] * v[0] + o.proj[3 * k + 1] * v[1] + o.proj[3 * k + 2] * v[2];
                }
            }
        }
    }

    /// `B ← P B P` for a block over `nodes` (`(3 k)²` entries row-major), `P` block-diagonal
    /// with each obliquely sliding node's `P_a` and the identity elsewhere.
    pub(super) fn project_block(&self, nodes: &[u32], block: &mut [f64]) {
        let d = 3 * nodes.len();
        for (i, &a) in nodes.iter().enumerate() {
            let Some(o) = self.oblique_of(a as usize) else {
                continue;
            };
            // Rows 3i..3i+3 ← P_a rows; columns 3i..3i+3 ← columns P_a (P_a symmetric).
            for c in 0..d {
                let v = [
                    block[3 * i * d + c],
                    block[(3 * i + 1) * d + c],
                    block[(3 * i + 2) * d + c],
                ];
                for k in 0..3 {
                    block[(3 * i + k) * d + c] =
                        o.proj[3 * k] * v[0] + o.proj[3 * k + 1] * v[1] + o.proj[3 * k + 2] * v[2];
                }
            }
            for r in 0..d {
                let row = &mut block[r * d..(r + 1) * d];
                project3(&o.proj, row, 3 * i);
            }
        }
    }

    /// The oblique entry of node `a`, if it slides obliquely.
    fn oblique_of(&self, a: usize) -> Option<&Oblique> {
        match self.oblique_index.get(a) {
            Some(&k) if k != u32::MAX => Some(&self.oblique[k as usize]),
            _ => None,
        }
    }
}

impl DirectNewton {
    /// `K_aa += c (I − P_a)` for each obliquely sliding node: the constrained directions'
    /// stiffness (module docs).
    pub(super) fn add_normal_stiffness(&mut self, c: f64) {
        for o in &self.dofs.oblique {
            for k in 0..3 {
                for l in 0..=k {
                    let (fr, fc) = (o.free[k], o.free[l]);
                    if fr == usize::MAX || fc == usize::MAX {
                        continue;
                    }
                    let delta = if k == l { 1.0 } else { 0.0 };
                    let (i, j) = if fr >= fc { (fr, fc) } else { (fc, fr) };
                    if let Some(slot) = slot_of(&self.symbolic, i, j) {
                        self.vals[slot] += c * (delta - o.proj[3 * k + l]);
                    }
                }
            }
        }
    }
}

/// The per-node index into `oblique` (`u32::MAX` where a node does not slide obliquely);
/// empty where none does.
fn index_of(oblique: &[Oblique], nodes: usize) -> Vec<u32> {
    if oblique.is_empty() {
        return Vec::new();
    }
    let mut at = vec![u32::MAX; nodes];
    for (k, o) in oblique.iter().enumerate() {
        at[o.node] = k as u32;
    }
    at
}
