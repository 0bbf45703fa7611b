//! The implicit function of a triangle surface: inside/outside, surface crossings of a
//! segment, distance to the surface.
//!
//! * Inside: the winding number `w(p) = Σ_c sign(n_x,c)` over the triangles `c` crossed by
//!   the ray from `p` towards `+x` (`n` the triangle's normal `(b − a) × (c − a)`): `+1`
//!   inside a closed outward surface, `0` outside, `−1` inside an inward one; `p` is inside
//!   when `w ≠ 0`. For a whole lattice row along `x` the crossings are computed once and
//!   sorted ([`SurfaceField::row_winding`]). A ray through an edge or a vertex of the
//!   surface is resolved by a symbolic perturbation of the ray's `(y, z)` by
//!   `(ε, ε²)`: an edge function that is exactly 0 takes the sign of the perturbation, and
//!   is computed from the edge's end points in a fixed order, so the two triangles sharing
//!   an edge see opposite signs and exactly one of them (or, at a fold, both or neither)
//!   counts the crossing.
//! * Crossings of a segment: ray–triangle intersection (Möller–Trumbore) over a bounding
//!   volume hierarchy (BVH) of the triangles.
//! * Distance: closest point on each triangle (Ericson, *Real-Time Collision Detection*,
//!   5.1.5), branch and bound over the BVH.
//!
//! The BVH splits at the median centroid along the longest axis of the centroids' box
//! (ties by triangle id), leaves of up to [`LEAF`] triangles: it depends on the triangles
//! only, so every query is deterministic.

use crate::geometry::closest_on_triangle;
use crate::geometry::{cross, dot, sub};
use crate::mesh::Surface;

/// Most triangles in a BVH leaf.
const LEAF: usize = 4;

#[derive(Clone, Debug)]
struct Node {
    lo: [f64; 3],
    hi: [f64; 3],
    /// Leaf: `count > 0`, triangles `tri[first..first+count]`; inner: children `first`,
    /// `first + 1`... stored as `left = first`, `right = second`.
    first: u32,
    second: u32,
    count: u32,
}

/// A triangle surface prepared for queries.
#[derive(Clone, Debug)]
pub(crate) struct SurfaceField {
    /// Triangle corners.
    tris: Vec<[[f64; 3]; 3]>,
    /// Triangle vertex ids (for the canonical edge order).
    ids: Vec<[u32; 3]>,
    nodes: Vec<Node>,
    /// Triangle order of the leaves.
    order: Vec<u32>,
    pub lo: [f64; 3],
    pub hi: [f64; 3],
}

fn bbox_of(ps: impl Iterator<Item = [f64; 3]>) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in ps {
        for d in 0..3 {
            lo[d] = lo[d].min(p[d]);
            hi[d] = hi[d].max(p[d]);
        }
    }
    (lo, hi)
}

impl SurfaceField {
    /// Build the BVH. The surface must have at least one triangle and valid indices
    /// (checked by the caller).
    pub fn new(s: &Surface) -> SurfaceField {
        let tris: Vec<[[f64; 3]; 3]> = s
            .triangles
            .iter()
            .map(|t| t.map(|i| s.points[i as usize]))
            .collect();
        let cent: Vec<[f64; 3]> = tris
            .iter()
            .map(|t| [0, 1, 2].map(|d| (t[0][d] + t[1][d] + t[2][d]) / 3.0))
            .collect();
        let mut order: Vec<u32> = (0..tris.len() as u32).collect();
        let mut nodes = Vec::new();
        let (lo, hi) = bbox_of(tris.iter().flat_map(|t| t.iter().copied()));
        build(&tris, &cent, &mut order, 0, &mut nodes);
        SurfaceField {
            tris,
            ids: s.triangles.clone(),
            nodes,
            order,
            lo,
            hi,
        }
    }

    /// The winding numbers of the points `x0 + i dx`, `i = 0..count`, of the row
    /// `yz = (y, z)` (see the module docs), one per point; the candidate triangles are
    /// `cand`.
    pub fn row_winding(
        &self,
        yz: [f64; 2],
        cand: &[u32],
        x0: f64,
        dx: f64,
        count: usize,
        out: &mut Vec<i32>,
    ) {
        let mut cross: Vec<(f64, i32)> = Vec::new();
        for &t in cand {
            if let Some(c) = self.row_crossing(t as usize, yz[0], yz[1]) {
                cross.push(c);
            }
        }
        cross.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        // w(x) = sum of the signs of the crossings with x_c > x.
        let mut w: i32 = cross.iter().map(|c| c.1).sum();
        let mut k = 0;
        out.clear();
        for i in 0..count {
            let x = x0 + i as f64 * dx;
            while k < cross.len() && cross[k].0 <= x {
                w -= cross[k].1;
                k += 1;
            }
            out.push(w);
        }
    }

    /// Every triangle's bounding box in `(y, z)`, from which the caller collects the
    /// candidate triangles of each row for [`Self::row_winding`].
    pub fn triangle_yz_boxes(&self) -> impl Iterator<Item = ([f64; 2], [f64; 2])> + '_ {
        self.tris.iter().map(|t| {
            let lo = [
                t[0][1].min(t[1][1]).min(t[2][1]),
                t[0][2].min(t[1][2]).min(t[2][2]),
            ];
            let hi = [
                t[0][1].max(t[1][1]).max(t[2][1]),
                t[0][2].max(t[1][2]).max(t[2][2]),
            ];
            (lo, hi)
        })
    }

    /// Where the line `(y, z)` along `x` crosses triangle `t` and the crossing's sign
    /// `sign(n_x)`, under the perturbation of the module docs.
    fn row_crossing(&self, t: usize, y: f64, z: f64) -> Option<(f64, i32)> {
        let p = self.tris[t];
        let id = self.ids[t];
        let q = [y, z];
        // Edge function of the directed edge (u -> v) at q, from the canonical order.
        let edge = |u: usize, v: usize| -> f64 {
            let (a, b, flip) = if id[u] < id[v] {
                (u, v, false)
            } else {
                (v, u, true)
            };
            let (pa, pb) = ([p[a][1], p[a][2]], [p[b][1], p[b][2]]);
            let d = [pb[0] - pa[0], pb[1] - pa[1]];
            let mut e = d[0] * (q[1] - pa[1]) - d[1] * (q[0] - pa[0]);
            if e == 0.0 {
                // q + (ε, ε²): d × (ε, ε²) = d0 ε² − d1 ε.
                e = if d[1] != 0.0 { -d[1] } else { d[0] };
            }
            if flip {
                -e
            } else {
                e
            }
        };
        let (e0, e1, e2) = (edge(1, 2), edge(2, 0), edge(0, 1));
        let inside_pos = e0 > 0.0 && e1 > 0.0 && e2 > 0.0;
        let inside_neg = e0 < 0.0 && e1 < 0.0 && e2 < 0.0;
        if !(inside_pos || inside_neg) {
            return None;
        }
        let s = if inside_pos { 1 } else { -1 };
        let sum = e0 + e1 + e2;
        let x = (e0 * p[0][0] + e1 * p[1][0] + e2 * p[2][0]) / sum;
        Some((x, s))
    }

    /// Parameters `t ∈ [0, 1]` where the segment `a → b` crosses the surface, with tolerance
    /// `tol` on the barycentric coordinates; unsorted.
    pub fn segment_crossings(&self, a: [f64; 3], b: [f64; 3], tol: f64, out: &mut Vec<f64>) {
        out.clear();
        let d = sub(b, a);
        let inv = d.map(|x| 1.0 / x);
        let mut stack = vec![0u32];
        while let Some(n) = stack.pop() {
            let node = &self.nodes[n as usize];
            if !slab_hit(a, inv, node.lo, node.hi) {
                continue;
            }
            if node.count > 0 {
                for &t in &self.order[node.first as usize..(node.first + node.count) as usize] {
                    if let Some(s) = seg_tri(a, d, &self.tris[t as usize], tol) {
                        out.push(s);
                    }
                }
            } else {
                stack.push(node.first);
                stack.push(node.second);
            }
        }
    }

    /// Distance from `p` to the surface.
    pub fn distance(&self, p: [f64; 3]) -> f64 {
        let mut best = f64::INFINITY;
        let mut stack = vec![0u32];
        while let Some(n) = stack.pop() {
            let node = &self.nodes[n as usize];
            if box_dist2(p, node.lo, node.hi) >= best {
                continue;
            }
            if node.count > 0 {
                for &t in &self.order[node.first as usize..(node.first + node.count) as usize] {
                    let c = closest_on_triangle(p, &self.tris[t as usize]);
                    let q = sub(p, c);
                    best = best.min(dot(q, q));
                }
            } else {
                let (l, r) = (node.first, node.second);
                let dl = box_dist2(p, self.nodes[l as usize].lo, self.nodes[l as usize].hi);
                let dr = box_dist2(p, self.nodes[r as usize].lo, self.nodes[r as usize].hi);
                // Nearer child last, so it is searched first.
                if dl < dr {
                    stack.push(r);
                    stack.push(l);
                } else {
                    stack.push(l);
                    stack.push(r);
                }
            }
        }
        best.sqrt()
    }

    /// Whether `p` is inside (winding number along `+x` non-zero).
    pub fn inside(&self, p: [f64; 3]) -> bool {
        let mut w = 0;
        let mut stack = vec![0u32];
        while let Some(n) = stack.pop() {
            let node = &self.nodes[n as usize];
            if p[1] < node.lo[1]
                || p[1] > node.hi[1]
                || p[2] < node.lo[2]
                || p[2] > node.hi[2]
                || p[0] > node.hi[0]
            {
                continue;
            }
            if node.count > 0 {
                for &t in &self.order[node.first as usize..(node.first + node.count) as usize] {
                    if let Some((x, s)) = self.row_crossing(t as usize, p[1], p[2]) {
                        if x > p[0] {
                            w += s;
                        }
                    }
                }
            } else {
                stack.push(node.first);
                stack.push(node.second);
            }
        }
        w != 0
    }
}

fn build(
    tris: &[[[f64; 3]; 3]],
    cent: &[[f64; 3]],
    order: &mut [u32],
    offset: usize,
    nodes: &mut Vec<Node>,
) -> u32 {
    let (lo, hi) = bbox_of(order.iter().flat_map(|&t| tris[t as usize].iter().copied()));
    let me = nodes.len() as u32;
    nodes.push(Node {
        lo,
        hi,
        first: offset as u32,
        second: 0,
        count: order.len() as u32,
    });
    if order.len() <= LEAF {
        return me;
    }
    let (clo, chi) = bbox_of(order.iter().map(|&t| cent[t as usize]));
    let axis = (0..3)
        .max_by(|&a, &b| {
            (chi[a] - clo[a])
                .total_cmp(&(chi[b] - clo[b]))
                .then(b.cmp(&a))
        })
        .unwrap_or(0);
    order.sort_by(|&a, &b| {
        cent[a as usize][axis]
            .total_cmp(&cent[b as usize][axis])
            .then(a.cmp(&b))
    });
    let mid = order.len() / 2;
    let (left, right) = order.split_at_mut(mid);
    let l = build(tris, cent, left, offset, nodes);
    let r = build(tris, cent, right, offset + mid, nodes);
    let n = &mut nodes[me as usize];
    n.first = l;
    n.second = r;
    n.count = 0;
    me
}

/// Whether the segment `a + t d`, `t ∈ [0, 1]`, meets the box (`inv = 1/d`).
fn slab_hit(a: [f64; 3], inv: [f64; 3], lo: [f64; 3], hi: [f64; 3]) -> bool {
    let mut t0: f64 = 0.0;
    let mut t1: f64 = 1.0;
    for k in 0..3 {
        if inv[k].is_infinite() {
            if a[k] < lo[k] || a[k] > hi[k] {
                return false;
            }
            continue;
        }
        let (mut ta, mut tb) = ((lo[k] - a[k]) * inv[k], (hi[k] - a[k]) * inv[k]);
        if ta > tb {
            std::mem::swap(&mut ta, &mut tb);
        }
        // Slack for round-off on boxes of zero width.
        let slack = 1e-12 * (tb - ta).abs().max(1e-300);
        t0 = t0.max(ta - slack);
        t1 = t1.min(tb + slack);
        if t0 > t1 {
            return false;
        }
    }
    true
}

/// Möller–Trumbore: the parameter `t ∈ [0, 1]` where `a + t d` meets the triangle, with
/// barycentric tolerance `tol`.
fn seg_tri(a: [f64; 3], d: [f64; 3], t: &[[f64; 3]; 3], tol: f64) -> Option<f64> {
    let e1 = sub(t[1], t[0]);
    let e2 = sub(t[2], t[0]);
    let pv = cross(d, e2);
    let det = dot(e1, pv);
    if det == 0.0 {
        return None;
    }
    let inv = 1.0 / det;
    let tv = sub(a, t[0]);
    let u = dot(tv, pv) * inv;
    if u < -tol || u > 1.0 + tol {
        return None;
    }
    let qv = cross(tv, e1);
    let v = dot(d, qv) * inv;
    if v < -tol || u + v > 1.0 + tol {
        return None;
    }
    let s = dot(e2, qv) * inv;
    (-tol..=1.0 + tol).contains(&s).then_some(s.clamp(0.0, 1.0))
}

fn box_dist2(p: [f64; 3], lo: [f64; 3], hi: [f64; 3]) -> f64 {
    let mut s = 0.0;
    for k in 0..3 {
        let d = if p[k] < lo[k] {
            lo[k] - p[k]
        } else if p[k] > hi[k] {
            p[k] - hi[k]
        } else {
            0.0
        };
        s += d * d;
    }
    s
}
