//! Dirichlet constraints: fixed nodes (u = 0), prescribed node displacements g(t), and
//! sliding nodes that keep `u·n = 0` along one or two unit directions `n` (a roller, a
//! symmetry plane, sliding on a plane; fixing the x, y or z component is `n` = e_x, e_y, e_z).
//! A sliding node's vectors are projected, `x ← x − (x·n) n` for each of its orthonormal
//! directions; with axis directions the fixed component becomes exactly 0 and the others are
//! left bit for bit.
//!
//! A prescribed displacement is held (applied at t = 0 and kept, the paper's instantaneous
//! 3 cm lift), ramped linearly over a duration then held, or follows a table of
//! (time, displacement) rows, linear between rows and held after the last, or is a vector
//! times a time function: a [`Motion`] ([`crate::time`], re-exported here).

pub use crate::time::Motion;

/// Fixed and prescribed nodes of one mesh.
#[derive(Clone, Debug, Default)]
pub struct Constraints {
    /// Fixed nodes (u = 0, u̇ = 0), sorted, deduplicated.
    pub fixed: Vec<u32>,
    /// Nodes with a prescribed displacement. A node both fixed and prescribed is prescribed.
    pub prescribed: Vec<(u32, Motion)>,
    /// Sliding nodes, each with orthonormal constrained directions (one entry per direction,
    /// sorted by node). A fixed or prescribed node ignores its entries.
    sliding: Vec<(u32, [f64; 3])>,
    mask: Vec<bool>,
}

impl Constraints {
    /// Constraints of `fixed` nodes and `prescribed` motions (sorted and deduplicated).
    pub fn new(mut fixed: Vec<u32>, prescribed: Vec<(u32, Motion)>) -> Self {
        fixed.sort_unstable();
        fixed.dedup();
        fixed.retain(|n| !prescribed.iter().any(|(p, _)| p == n));
        Constraints {
            fixed,
            prescribed,
            sliding: Vec::new(),
            mask: Vec::new(),
        }
    }
    /// Add sliding constraints: node `a` keeps `u·n = 0` for each `(a, n)` (`n` non-zero).
    /// The directions of one node are orthonormalized (Gram-Schmidt in the order given;
    /// a direction within 1e-9 of the span of the earlier ones is dropped); a node with three
    /// independent directions becomes fixed. Call before [`Constraints::with_nodes`].
    pub fn with_sliding(mut self, sliding: &[(u32, [f64; 3])]) -> Self {
        let mut all: Vec<(u32, [f64; 3])> = self.sliding.clone();
        all.extend_from_slice(sliding);
        all.sort_by_key(|&(a, _)| a); // stable: keeps the order of each node's directions
        let mut out: Vec<(u32, [f64; 3])> = Vec::with_capacity(all.len());
        let mut i = 0;
        while i < all.len() {
            let a = all[i].0;
            let mut basis: Vec<[f64; 3]> = Vec::new();
            while i < all.len() && all[i].0 == a {
                let mut v = all[i].1;
                let len0 = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                for b in &basis {
                    let d = v[0] * b[0] + v[1] * b[1] + v[2] * b[2];
                    if d != 0.0 {
                        for k in 0..3 {
                            v[k] -= d * b[k];
                        }
                    }
                }
                let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                if len > 1e-9 * len0 && len0 > 0.0 {
                    basis.push(if len == 1.0 {
                        v
                    } else {
                        [v[0] / len, v[1] / len, v[2] / len]
                    });
                }
                i += 1;
            }
            if basis.len() >= 3 {
                if self.fixed.binary_search(&a).is_err()
                    && !self.prescribed.iter().any(|(p, _)| *p == a)
                {
                    let at = self.fixed.partition_point(|&x| x < a);
                    self.fixed.insert(at, a);
                }
            } else {
                out.extend(basis.into_iter().map(|n| (a, n)));
            }
        }
        self.sliding = out;
        self
    }
    /// The sliding constraints: `(node, unit direction)`, sorted by node.
    pub fn sliding(&self) -> &[(u32, [f64; 3])] {
        &self.sliding
    }
    /// Remove the component along `n` of node `a`'s entries of `x`.
    #[inline]
    fn project(x: &mut [f64], a: u32, n: &[f64; 3]) {
        let i = 3 * a as usize;
        let d = x[i] * n[0] + x[i + 1] * n[1] + x[i + 2] * n[2];
        for k in 0..3 {
            if n[k] != 0.0 {
                x[i + k] -= d * n[k];
            }
        }
    }
    /// The constraints carried to a cut mesh ([`crate::mesh::cut::TopologyChange`]): every
    /// copy of a fixed, prescribed or sliding node is fixed, prescribed or sliding alike.
    pub fn carried(&self, node_from: &[u32]) -> Constraints {
        let n_old = self.mask.len();
        let mut copies: Vec<Vec<u32>> = vec![Vec::new(); n_old];
        for (a, &o) in node_from.iter().enumerate() {
            if let Some(c) = copies.get_mut(o as usize) {
                c.push(a as u32);
            }
        }
        let fixed = self
            .fixed
            .iter()
            .flat_map(|&a| copies[a as usize].iter().copied())
            .collect();
        let prescribed = self
            .prescribed
            .iter()
            .flat_map(|(a, m)| copies[*a as usize].iter().map(move |&c| (c, m.clone())))
            .collect();
        let mut sliding: Vec<(u32, [f64; 3])> = self
            .sliding
            .iter()
            .flat_map(|&(a, d)| copies[a as usize].iter().map(move |&c| (c, d)))
            .collect();
        sliding.sort_by_key(|&(a, _)| a);
        Constraints::new(fixed, prescribed)
            .with_sliding(&sliding)
            .with_nodes(node_from.len())
    }
    /// Build the per-node mask for `n` nodes.
    pub fn with_nodes(mut self, n: usize) -> Self {
        self.mask = vec![false; n];
        for &a in &self.fixed {
            self.mask[a as usize] = true;
        }
        for (a, _) in &self.prescribed {
            self.mask[*a as usize] = true;
        }
        self
    }
    /// Whether node `a` is fixed or prescribed.
    #[inline]
    pub fn is_constrained(&self, a: usize) -> bool {
        self.mask.get(a).copied().unwrap_or(false)
    }
    /// Per-node mask (true = constrained).
    pub fn mask(&self) -> &[bool] {
        &self.mask
    }
    /// Set entries of constrained nodes to zero (3 per node), and the constrained directions
    /// of sliding nodes.
    pub fn zero_constrained(&self, x: &mut [f64]) {
        for (a, n) in &self.sliding {
            Self::project(x, *a, n);
        }
        for &a in &self.fixed {
            let a = a as usize * 3;
            x[a..a + 3].fill(0.0);
        }
        for (a, _) in &self.prescribed {
            let a = *a as usize * 3;
            x[a..a + 3].fill(0.0);
        }
    }
    /// Impose u = g(t), u̇ = ġ(t) on constrained nodes.
    pub fn impose(&self, t: f64, u: &mut [f64], v: &mut [f64]) {
        for (a, n) in &self.sliding {
            Self::project(u, *a, n);
            Self::project(v, *a, n);
        }
        for &a in &self.fixed {
            let a = a as usize * 3;
            u[a..a + 3].fill(0.0);
            v[a..a + 3].fill(0.0);
        }
        for (a, m) in &self.prescribed {
            let a = *a as usize * 3;
            u[a..a + 3].copy_from_slice(&m.displacement(t));
            v[a..a + 3].copy_from_slice(&m.velocity(t));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sliding_projects_exactly_and_three_directions_fix() {
        let c = Constraints::new(vec![], vec![])
            .with_sliding(&[
                (0, [0.0, 0.0, 2.0]),
                (1, [1.0, 1.0, 0.0]),
                (2, [1.0, 0.0, 0.0]),
                (2, [0.0, 1.0, 0.0]),
                (2, [0.0, 0.0, 1.0]),
            ])
            .with_nodes(3);
        assert_eq!(c.fixed, vec![2]);
        let mut u = vec![0.1, -0.3, 0.7, 1.0, 3.0, 5.0, 1.0, 1.0, 1.0];
        let mut v = u.clone();
        c.impose(0.0, &mut u, &mut v);
        assert_eq!(&u[0..3], &[0.1, -0.3, 0.0]);
        assert!((u[3] + u[4]).abs() < 1e-15 && u[5] == 5.0);
        assert!((u[3] - (-1.0)).abs() < 1e-15, "{u:?}");
        assert_eq!(&u[6..9], &[0.0; 3]);
        assert_eq!(u, v);
    }

    #[test]
    fn ramp_and_table_motions() {
        let r = Motion::Ramp {
            d: [0.0, 0.0, 0.03],
            duration: 0.5,
        };
        assert_eq!(r.displacement(0.25), [0.0, 0.0, 0.015]);
        assert_eq!(r.displacement(2.0), [0.0, 0.0, 0.03]);
        assert_eq!(r.velocity(0.1), [0.0, 0.0, 0.06]);
        assert_eq!(r.velocity(0.6), [0.0; 3]);
        let t = Motion::Table {
            times: vec![0.0, 1.0, 2.0],
            values: vec![[0.0; 3], [0.01, 0.0, 0.0], [0.01, 0.02, 0.0]],
        };
        assert_eq!(t.displacement(0.5), [0.005, 0.0, 0.0]);
        assert_eq!(t.displacement(1.5), [0.01, 0.01, 0.0]);
        assert_eq!(t.displacement(9.0), [0.01, 0.02, 0.0]);
        assert_eq!(t.velocity(1.5), [0.0, 0.02, 0.0]);
        assert!((t.max_displacement() - (0.0005f64).sqrt()).abs() < 1e-15);
    }
}
