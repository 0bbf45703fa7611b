//! Self-intersection test of a closed 2-manifold triangle surface: whether two triangles meet
//! anywhere other than in the vertices and the edge they share by index. Touching counts as
//! meeting. Every decision is exact, with Shewchuk's adaptive `orient3d` / `orient2d`
//! predicates (`robust` crate).
//!
//! **Reduction.** Triangles are closed and non-degenerate (three non-collinear vertices). Two
//! triangles sharing an edge meet elsewhere iff they are coplanar and on the same side of that
//! edge. Every other meeting is an **edge–triangle** meeting: an edge `e` and a triangle `t`
//! that have no vertex in common, with the closed segment `e` meeting the closed triangle `t`.
//!
//! * Two triangles with no common vertex meet iff an edge of one meets the other: if their
//!   planes cross, each meets the line of the two planes in a segment, and an end of the
//!   overlap of the two segments is on an edge of one triangle and in the other; if they are
//!   coplanar, their boundaries cross or one contains the other's edges.
//! * `(v, a, b)` and `(v, c, d)`, common vertex `v` only, meet elsewhere than at `v` iff
//!   segment `ab` meets `(v, c, d)` or `cd` meets `(v, a, b)`: each triangle meets a line
//!   through `v` in a segment from `v` that ends on its opposite edge; beyond `v` the two
//!   segments overlap iff they leave `v` the same way, and then the shorter one's end is on
//!   its triangle's opposite edge and in the other triangle.
//! * Conversely, an edge `e` of `s` meeting a triangle `t` with which `e` has no vertex in
//!   common is a meeting of `s` and `t` outside their common vertices (`s` and `t` share at
//!   most the vertex of `s` opposite `e`, which is not on `e`).
//!
//! So the surface intersects itself iff a pair of triangles sharing an edge overlaps, or an
//! edge meets a triangle it has no vertex in common with. The pairs sharing a vertex never
//! have to be enumerated: around a vertex of valence `k` (the apex of a fan) there are `k²/2`
//! such triangle pairs but only the `k` opposite edges to test.
//!
//! **Broad phase.** A tree over the triangles, split at the median centroid along the axis
//! of each node's oriented box on which the centroids spread widest, leaves of at most
//! [`LEAF`] triangles. Each node keeps an axis-aligned box, an oriented box (axes: the
//! eigenvectors of the covariance of its triangles' corners) and the vertices common to all
//! its triangles. Every edge descends the tree and skips a node whose triangles all have one of
//! its ends as a vertex, or whose boxes the segment misses (separating-axis test of a segment
//! and a box: the box's three axes and their cross products with the segment are complete).
//! Oriented boxes stay tight around long thin triangles whatever their direction, where
//! axis-aligned boxes of a fan all overlap near its centre. The boxes are grown by
//! [`MARGIN_REL`] times the largest coordinate magnitude `M`, and each cross-product axis's
//! test by that margin times the segment's half-length: far more than the rounding of
//! computing and testing them (a few units of `1e-16 M`), so the broad phase never drops a
//! pair that meets, and the result is exact.
//!
//! Edges are taken in order of their lowest-numbered triangle, in chunks tested in parallel;
//! the first meeting in that order is reported, so the result and the work counts do not
//! depend on the number of threads.
//!
//! One concern, the exact self-intersection test and its broad phase; about a third of the
//! file is tests.

use rayon::prelude::*;

use super::{cross, dot, sub};

/// Largest number of triangles in a leaf of the tree.
const LEAF: usize = 4;

/// Subtrees of more triangles than this are built in parallel.
const PARALLEL_BUILD: usize = 4096;

/// Growth of every bounding box, relative to the largest coordinate magnitude of the surface:
/// computing a box and testing it against a segment rounds by a few units in the last place of
/// that magnitude (about 1e-16), seven orders of magnitude below this.
pub const MARGIN_REL: f64 = 1e-9;

const NONE: u32 = u32::MAX;

/// Work of the self-intersection test, in counts that do not depend on the machine.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct IntersectionWork {
    /// Bounding-volume tests of the broad phase (tree nodes an edge visited).
    pub volume_tests: u64,
    /// Pairs passed to the exact test: edge–triangle pairs with no common vertex whose boxes
    /// overlap, and the pairs of triangles sharing an edge.
    pub candidates: u64,
    /// Exact orientation predicates evaluated (`orient3d` and `orient2d`).
    pub predicates: u64,
}

impl std::ops::AddAssign for IntersectionWork {
    fn add_assign(&mut self, o: IntersectionWork) {
        self.volume_tests += o.volume_tests;
        self.candidates += o.candidates;
        self.predicates += o.predicates;
    }
}

/// Two triangles that meet other than in their common vertices and edge.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Meeting {
    /// The lower-numbered triangle.
    pub first: usize,
    /// The other triangle.
    pub second: usize,
    /// When the two share no edge: the edge `(a, b)` of triangle `t` (one of the two) that
    /// meets the other, as `(a, b, t)`.
    pub edge: Option<(u32, u32, usize)>,
}

/// Look for a self-intersection (see the module docs) among `tris` over `points`, with `nbr`
/// the triangle across each local edge `e` (from corner `e` to corner `e + 1`) of a closed
/// 2-manifold surface. `progress(done, total)` is called about a hundred times as the edges
/// are tested, up to `done == total` when there is no meeting.
pub fn find_meeting(
    points: &[[f64; 3]],
    tris: &[[u32; 3]],
    nbr: &[[u32; 3]],
    progress: &mut dyn FnMut(usize, usize),
) -> (Option<Meeting>, IntersectionWork) {
    let mut work = IntersectionWork::default();
    // Pairs sharing an edge.
    for (t, tri) in tris.iter().enumerate() {
        for (e, &u) in nbr[t].iter().enumerate() {
            if (t as u32) < u {
                work.candidates += 1;
                let (a, b) = (tri[e], tri[(e + 1) % 3]);
                if folded_onto(&mut work.predicates, points, tri, &tris[u as usize], a, b) {
                    let m = Meeting {
                        first: t,
                        second: u as usize,
                        edge: None,
                    };
                    return (Some(m), work);
                }
            }
        }
    }
    // Edge–triangle pairs: each edge once, from its lower-numbered triangle.
    let edges: Vec<(u32, u32, u32)> = tris
        .iter()
        .enumerate()
        .flat_map(|(t, tri)| {
            (0..3).filter_map(move |e| {
                ((t as u32) < nbr[t][e]).then_some((tri[e], tri[(e + 1) % 3], t as u32))
            })
        })
        .collect();
    let tree = Tree::new(points, tris);
    let total = edges.len();
    let chunk = total.div_ceil(100).max(1024);
    progress(0, total);
    for (k, part) in edges.chunks(chunk).enumerate() {
        let found: Vec<(Option<u32>, IntersectionWork)> = part
            .par_iter()
            .map_init(Vec::new, |stack, &(a, b, _)| {
                tree.meets_edge(points, tris, a, b, stack)
            })
            .collect();
        for (_, w) in &found {
            work += *w;
        }
        if let Some((&(a, b, s), t)) = part
            .iter()
            .zip(&found)
            .find_map(|(e, (t, _))| t.map(|t| (e, t)))
        {
            let (s, t) = (s as usize, t as usize);
            let m = Meeting {
                first: s.min(t),
                second: s.max(t),
                edge: Some((a, b, s)),
            };
            return (Some(m), work);
        }
        progress((k * chunk + part.len()).min(total), total);
    }
    (None, work)
}

/// Triangles `ti` and `tj` share the edge `(a, b)`: whether they overlap beyond it (coplanar,
/// their third vertices on the same side of it).
fn folded_onto(
    n: &mut u64,
    points: &[[f64; 3]],
    ti: &[u32; 3],
    tj: &[u32; 3],
    a: u32,
    b: u32,
) -> bool {
    let third = |t: &[u32; 3]| {
        t.iter()
            .copied()
            .find(|&v| v != a && v != b)
            .unwrap_or(t[0])
    };
    let p = |v: u32| points[v as usize];
    let (pa, pb, pc, pd) = (p(a), p(b), p(third(ti)), p(third(tj)));
    if o3(n, pa, pb, pc, pd) != 0 {
        return false;
    }
    let pr = projector(pa, pb, pc);
    o2(n, pr(pa), pr(pb), pr(pc)) == o2(n, pr(pa), pr(pb), pr(pd))
}

// ---------------------------------------------------------------------------------------------
// The tree.

/// An oriented box: `centre + Σ s_k half[k] axes[k]`, `|s_k| ≤ 1`.
#[derive(Clone, Copy)]
struct Obb {
    centre: [f64; 3],
    axes: [[f64; 3]; 3],
    half: [f64; 3],
}

struct Node {
    lo: [f64; 3],
    hi: [f64; 3],
    obb: Obb,
    /// Vertices of every triangle of the node, `NONE` after the last.
    common: [u32; 3],
    /// Leaf: `items[start..start + len]`; inner node (`len == 0`): children the next node
    /// and node `start` (depth-first order).
    start: u32,
    len: u32,
}

struct Tree {
    nodes: Vec<Node>,
    items: Vec<u32>,
    margin: f64,
}

/// A triangle while the tree is built: its corners, and their sum and sum of outer products
/// relative to the surface's box centre (the moments a node's mean and covariance add up).
struct Prim {
    corners: [[f64; 3]; 3],
    sum: [f64; 3],
    /// `xx, yy, zz, xy, xz, yz`.
    outer: [f64; 6],
}

/// Leaves of a tree over `m` triangles (split in halves down to [`LEAF`] or fewer); the tree
/// has `2 leaves − 1` nodes.
fn leaves(m: usize) -> usize {
    if m <= LEAF {
        1
    } else {
        leaves(m / 2) + leaves(m - m / 2)
    }
}

/// What building the tree reads.
struct Build<'a> {
    tris: &'a [[u32; 3]],
    prims: &'a [Prim],
    origin: [f64; 3],
    margin: f64,
}

impl Build<'_> {
    /// Build the subtree of `items` (at `first` in the tree's items) into `nodes` (at `base`
    /// in the tree's nodes): its root, the left subtree, the right one. Large subtrees are
    /// built in parallel; the tree does not depend on the number of threads.
    fn build(&self, nodes: &mut [Node], base: usize, items: &mut [u32], first: usize) {
        let origin = self.origin;
        let mut sum = [0.0; 3];
        let mut outer = [0.0; 6];
        for &t in items.iter() {
            let p = &self.prims[t as usize];
            for k in 0..3 {
                sum[k] += p.sum[k];
            }
            for k in 0..6 {
                outer[k] += p.outer[k];
            }
        }
        let count = (3 * items.len()) as f64;
        let mean = sum.map(|x| x / count);
        let m = |i: usize, j: usize| {
            let k = match (i.min(j), i.max(j)) {
                (a, b) if a == b => a,
                (0, 1) => 3,
                (0, 2) => 4,
                _ => 5,
            };
            outer[k] / count - mean[i] * mean[j]
        };
        let axes = eigenvectors([0, 1, 2].map(|i| [0, 1, 2].map(|j| m(i, j))));
        // The corners' extents: in the coordinates, and along the axes (relative to `origin`);
        // the centroids' along the axes.
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        let mut smin = [f64::INFINITY; 3];
        let mut smax = [f64::NEG_INFINITY; 3];
        let mut cmin = [f64::INFINITY; 3];
        let mut cmax = [f64::NEG_INFINITY; 3];
        let mut keys: Vec<([f64; 3], u32)> = Vec::with_capacity(items.len());
        for &t in items.iter() {
            let mut c = [0.0; 3];
            for p in self.prims[t as usize].corners {
                let d = sub(p, origin);
                for k in 0..3 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                    let s = dot(axes[k], d);
                    smin[k] = smin[k].min(s);
                    smax[k] = smax[k].max(s);
                    c[k] += s / 3.0;
                }
            }
            for k in 0..3 {
                cmin[k] = cmin[k].min(c[k]);
                cmax[k] = cmax[k].max(c[k]);
            }
            keys.push((c, t));
        }
        let mid = [0, 1, 2].map(|k| 0.5 * (smin[k] + smax[k]));
        let centre =
            [0, 1, 2].map(|i| origin[i] + (0..3).map(|k| mid[k] * axes[k][i]).sum::<f64>());
        let margin = self.margin;
        let Some((root, below)) = nodes.split_first_mut() else {
            return;
        };
        root.lo = lo.map(|x| x - margin);
        root.hi = hi.map(|x| x + margin);
        root.obb = Obb {
            centre,
            axes,
            half: [0, 1, 2].map(|k| 0.5 * (smax[k] - smin[k]) + margin),
        };
        if items.len() <= LEAF {
            root.start = first as u32;
            root.len = items.len() as u32;
            let mut common = self.tris[items[0] as usize];
            for &t in &items[1..] {
                for v in &mut common {
                    if !self.tris[t as usize].contains(v) {
                        *v = NONE;
                    }
                }
            }
            root.common = packed(common);
            return;
        }
        // Split along the box axis of the widest spread of centroids, at the median centroid.
        let k = (0..3)
            .max_by(|&a, &b| (cmax[a] - cmin[a]).total_cmp(&(cmax[b] - cmin[b])))
            .unwrap_or(0);
        let half = items.len() / 2;
        keys.select_nth_unstable_by(half, |a, b| a.0[k].total_cmp(&b.0[k]).then(a.1.cmp(&b.1)));
        for (slot, (_, t)) in items.iter_mut().zip(keys) {
            *slot = t;
        }
        let parallel = items.len() > PARALLEL_BUILD;
        let (left_items, right_items) = items.split_at_mut(half);
        let (left_nodes, right_nodes) = below.split_at_mut(2 * leaves(half) - 1);
        let right = base + 1 + left_nodes.len();
        root.start = right as u32;
        if parallel {
            rayon::join(
                || self.build(left_nodes, base + 1, left_items, first),
                || self.build(right_nodes, right, right_items, first + half),
            );
        } else {
            self.build(left_nodes, base + 1, left_items, first);
            self.build(right_nodes, right, right_items, first + half);
        }
        let (l, r) = (nodes[1].common, nodes[right - base].common);
        nodes[0].common = packed(l.map(|v| if r.contains(&v) { v } else { NONE }));
    }
}

impl Tree {
    fn new(points: &[[f64; 3]], tris: &[[u32; 3]]) -> Tree {
        let big = points
            .iter()
            .flat_map(|p| p.iter())
            .fold(0.0f64, |m, c| m.max(c.abs()));
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for p in points {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let origin = [0, 1, 2].map(|k| 0.5 * (lo[k] + hi[k]));
        let prims: Vec<Prim> = tris
            .par_iter()
            .map(|t| {
                let corners = t.map(|v| points[v as usize]);
                let mut sum = [0.0; 3];
                let mut outer = [0.0; 6];
                for p in corners {
                    let d = sub(p, origin);
                    for k in 0..3 {
                        sum[k] += d[k];
                    }
                    let m = [d[0] * d[0], d[1] * d[1], d[2] * d[2]];
                    let x = [d[0] * d[1], d[0] * d[2], d[1] * d[2]];
                    for k in 0..3 {
                        outer[k] += m[k];
                        outer[3 + k] += x[k];
                    }
                }
                Prim {
                    corners,
                    sum,
                    outer,
                }
            })
            .collect();
        let mut items: Vec<u32> = (0..tris.len() as u32).collect();
        let mut nodes: Vec<Node> = (0..2 * leaves(tris.len()) - 1)
            .map(|_| placeholder())
            .collect();
        let cx = Build {
            tris,
            prims: &prims,
            origin,
            margin: MARGIN_REL * big,
        };
        cx.build(&mut nodes, 0, &mut items, 0);
        Tree {
            nodes,
            items,
            margin: cx.margin,
        }
    }

    /// The first triangle (in the tree's order) that the edge `(a, b)` meets without a common
    /// vertex, and the work done.
    fn meets_edge(
        &self,
        points: &[[f64; 3]],
        tris: &[[u32; 3]],
        a: u32,
        b: u32,
        stack: &mut Vec<u32>,
    ) -> (Option<u32>, IntersectionWork) {
        let mut work = IntersectionWork::default();
        let (p, q) = (points[a as usize], points[b as usize]);
        let lo = [0, 1, 2].map(|k| p[k].min(q[k]));
        let hi = [0, 1, 2].map(|k| p[k].max(q[k]));
        let mid = [0, 1, 2].map(|k| 0.5 * (p[k] + q[k]));
        let half = [0, 1, 2].map(|k| 0.5 * (q[k] - p[k]));
        stack.clear();
        stack.push(0);
        while let Some(i) = stack.pop() {
            work.volume_tests += 1;
            let node = &self.nodes[i as usize];
            if node.common.contains(&a) || node.common.contains(&b) {
                continue;
            }
            if (0..3).any(|k| node.hi[k] < lo[k] || hi[k] < node.lo[k]) {
                continue;
            }
            if segment_misses_box(mid, half, &node.obb, self.margin) {
                continue;
            }
            if node.len == 0 {
                stack.push(node.start);
                stack.push(i + 1);
                continue;
            }
            let s = node.start as usize;
            for &t in &self.items[s..s + node.len as usize] {
                let tri = tris[t as usize];
                if tri.contains(&a) || tri.contains(&b) {
                    continue;
                }
                work.candidates += 1;
                let [x, y, z] = tri.map(|v| points[v as usize]);
                if segment_triangle(&mut work.predicates, p, q, x, y, z) {
                    return (Some(t), work);
                }
            }
        }
        (None, work)
    }
}

/// Orthonormal axes along the eigenvectors of the symmetric matrix `a` (cyclic Jacobi
/// rotations). Any orthonormal axes bound a node; these bound it tightly. The axes are a
/// product of rotations, orthonormal to rounding whether or not the sweeps converged.
fn eigenvectors(mut a: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let scale: f64 = (0..3).map(|i| a[i][i].abs()).sum();
    for _ in 0..8 {
        let off = a[0][1].abs() + a[0][2].abs() + a[1][2].abs();
        if !(off > 1e-15 * scale) {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = if theta.abs() > 1e100 {
                0.5 / theta
            } else {
                theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt())
            };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            for row in a.iter_mut() {
                let (x, y) = (row[p], row[q]);
                row[p] = c * x - s * y;
                row[q] = s * x + c * y;
            }
            for k in 0..3 {
                let (x, y) = (a[p][k], a[q][k]);
                a[p][k] = c * x - s * y;
                a[q][k] = s * x + c * y;
            }
            for row in v.iter_mut() {
                let (x, y) = (row[p], row[q]);
                row[p] = c * x - s * y;
                row[q] = s * x + c * y;
            }
        }
    }
    [0, 1, 2].map(|k| [v[0][k], v[1][k], v[2][k]])
}

fn placeholder() -> Node {
    Node {
        lo: [0.0; 3],
        hi: [0.0; 3],
        obb: Obb {
            centre: [0.0; 3],
            axes: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            half: [0.0; 3],
        },
        common: [NONE; 3],
        start: 0,
        len: 0,
    }
}

/// The set's real vertices first, `NONE` after.
fn packed(mut v: [u32; 3]) -> [u32; 3] {
    v.sort_unstable();
    v
}

/// Whether the segment `mid ± half` misses the box (separating axes: the box's axes and their
/// cross products with the segment). The cross products' tests are grown by `margin` times the
/// segment's half-length: near a box axis the cross product is short and its test is all
/// rounding.
fn segment_misses_box(mid: [f64; 3], half: [f64; 3], b: &Obb, margin: f64) -> bool {
    let d = sub(mid, b.centre);
    let t = b.axes.map(|u| dot(u, d));
    let h = b.axes.map(|u| dot(u, half));
    let e = b.half;
    let ha = h.map(f64::abs);
    let slack = margin * (ha[0] + ha[1] + ha[2]);
    (0..3).any(|k| t[k].abs() > e[k] + ha[k])
        || (t[1] * h[2] - t[2] * h[1]).abs() > e[1] * ha[2] + e[2] * ha[1] + slack
        || (t[2] * h[0] - t[0] * h[2]).abs() > e[0] * ha[2] + e[2] * ha[0] + slack
        || (t[0] * h[1] - t[1] * h[0]).abs() > e[0] * ha[1] + e[1] * ha[0] + slack
}

// ---------------------------------------------------------------------------------------------
// Exact predicates; `n` counts the orientation predicates evaluated.

fn o3(n: &mut u64, a: [f64; 3], b: [f64; 3], c: [f64; 3], d: [f64; 3]) -> i8 {
    let p = |v: [f64; 3]| robust::Coord3D {
        x: v[0],
        y: v[1],
        z: v[2],
    };
    *n += 1;
    sign(robust::orient3d(p(a), p(b), p(c), p(d)))
}

fn o2(n: &mut u64, a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> i8 {
    let p = |v: [f64; 2]| robust::Coord { x: v[0], y: v[1] };
    *n += 1;
    sign(robust::orient2d(p(a), p(b), p(c)))
}

fn sign(x: f64) -> i8 {
    if x > 0.0 {
        1
    } else if x < 0.0 {
        -1
    } else {
        0
    }
}

/// Drop the coordinate along which the triangle's normal is largest (an affine bijection of
/// the triangle's plane onto a coordinate plane: orientations keep or all flip their sign).
fn projector(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> impl Fn([f64; 3]) -> [f64; 2] {
    let n = cross(sub(b, a), sub(c, a)).map(f64::abs);
    let k = if n[0] >= n[1] && n[0] >= n[2] {
        0
    } else if n[1] >= n[2] {
        1
    } else {
        2
    };
    move |p: [f64; 3]| [p[(k + 1) % 3], p[(k + 2) % 3]]
}

/// Whether the closed segment pq meets the closed triangle abc (non-degenerate), exactly.
fn segment_triangle(
    n: &mut u64,
    p: [f64; 3],
    q: [f64; 3],
    a: [f64; 3],
    b: [f64; 3],
    c: [f64; 3],
) -> bool {
    let sp = o3(n, a, b, c, p);
    let sq = o3(n, a, b, c, q);
    if sp * sq > 0 {
        return false;
    }
    if sp == 0 && sq == 0 {
        let pr = projector(a, b, c);
        return segment_triangle_2d(n, [pr(p), pr(q)], pr(a), pr(b), pr(c));
    }
    let s = [o3(n, p, q, a, b), o3(n, p, q, b, c), o3(n, p, q, c, a)];
    !(s.iter().any(|&x| x > 0) && s.iter().any(|&x| x < 0))
}

fn point_in_triangle_2d(n: &mut u64, p: [f64; 2], a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> bool {
    let s = [o2(n, a, b, p), o2(n, b, c, p), o2(n, c, a, p)];
    !(s.iter().any(|&x| x > 0) && s.iter().any(|&x| x < 0))
}

fn on_segment_2d(p: [f64; 2], q: [f64; 2], r: [f64; 2]) -> bool {
    // r collinear with pq: inside the segment's box.
    (0..2).all(|k| p[k].min(q[k]) <= r[k] && r[k] <= p[k].max(q[k]))
}

fn segments_2d(n: &mut u64, p: [f64; 2], q: [f64; 2], a: [f64; 2], b: [f64; 2]) -> bool {
    let (d1, d2) = (o2(n, p, q, a), o2(n, p, q, b));
    let (d3, d4) = (o2(n, a, b, p), o2(n, a, b, q));
    if d1 * d2 < 0 && d3 * d4 < 0 {
        return true;
    }
    (d1 == 0 && on_segment_2d(p, q, a))
        || (d2 == 0 && on_segment_2d(p, q, b))
        || (d3 == 0 && on_segment_2d(a, b, p))
        || (d4 == 0 && on_segment_2d(a, b, q))
}

fn segment_triangle_2d(
    n: &mut u64,
    [p, q]: [[f64; 2]; 2],
    a: [f64; 2],
    b: [f64; 2],
    c: [f64; 2],
) -> bool {
    point_in_triangle_2d(n, p, a, b, c)
        || point_in_triangle_2d(n, q, a, b, c)
        || segments_2d(n, p, q, a, b)
        || segments_2d(n, p, q, b, c)
        || segments_2d(n, p, q, c, a)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::generate::cone_surface;
    use crate::mesh::surface_check::tests::{cube, icosphere};
    use crate::mesh::Surface;
    use std::collections::HashMap;

    /// Whether two triangles meet anywhere other than in the vertices and edge they share by
    /// index, decided pair by pair: the reference the edge–triangle search must agree with.
    fn triangles_intersect(points: &[[f64; 3]], ti: &[u32; 3], tj: &[u32; 3]) -> bool {
        let n = &mut 0;
        let p = |v: u32| points[v as usize];
        let shared: Vec<u32> = ti.iter().copied().filter(|v| tj.contains(v)).collect();
        match shared.len() {
            0 => {
                let [a, b, c] = ti.map(p);
                let [d, e, f] = tj.map(p);
                segment_triangle(n, a, b, d, e, f)
                    || segment_triangle(n, b, c, d, e, f)
                    || segment_triangle(n, c, a, d, e, f)
                    || segment_triangle(n, d, e, a, b, c)
                    || segment_triangle(n, e, f, a, b, c)
                    || segment_triangle(n, f, d, a, b, c)
            }
            1 => {
                let v = shared[0];
                let others = |t: &[u32; 3]| {
                    let k = t.iter().position(|&w| w == v).unwrap_or(0);
                    (t[(k + 1) % 3], t[(k + 2) % 3])
                };
                let (a, b) = others(ti);
                let (c, d) = others(tj);
                let (pv, pa, pb, pc, pd) = (p(v), p(a), p(b), p(c), p(d));
                segment_triangle(n, pa, pb, pv, pc, pd) || segment_triangle(n, pc, pd, pv, pa, pb)
            }
            2 => folded_onto(n, points, ti, tj, shared[0], shared[1]),
            _ => true,
        }
    }

    fn neighbours(tris: &[[u32; 3]]) -> Vec<[u32; 3]> {
        let mut by_edge: HashMap<(u32, u32), Vec<u32>> = HashMap::new();
        for (t, tri) in tris.iter().enumerate() {
            for e in 0..3 {
                let (a, b) = (tri[e], tri[(e + 1) % 3]);
                by_edge
                    .entry((a.min(b), a.max(b)))
                    .or_default()
                    .push(t as u32);
            }
        }
        tris.iter()
            .enumerate()
            .map(|(t, tri)| {
                [0, 1, 2].map(|e| {
                    let (a, b) = (tri[e], tri[(e + 1) % 3]);
                    let ts = &by_edge[&(a.min(b), a.max(b))];
                    assert_eq!(ts.len(), 2, "the test surfaces are closed 2-manifolds");
                    if ts[0] == t as u32 {
                        ts[1]
                    } else {
                        ts[0]
                    }
                })
            })
            .collect()
    }

    fn search(s: &Surface) -> (Option<Meeting>, IntersectionWork) {
        find_meeting(
            &s.points,
            &s.triangles,
            &neighbours(&s.triangles),
            &mut |_, _| {},
        )
    }

    /// Deterministic uniform numbers in [0, 1).
    struct Lcg(u64);
    impl Lcg {
        fn next(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }
        /// A multiple of 1/8 in [lo, hi): exact, so that touching configurations occur.
        fn dyadic(&mut self, lo: f64, hi: f64) -> f64 {
            lo + ((self.next() * (hi - lo) * 8.0).floor()) / 8.0
        }
    }

    #[test]
    fn edge_triangle_search_agrees_with_all_pairs() {
        let mut rng = Lcg(49);
        let mut surfaces: Vec<Surface> = Vec::new();
        for _ in 0..60 {
            // A cone with a rim vertex moved around the rim, in or out, up or down: folds.
            let n = 6 + (rng.next() * 30.0) as usize;
            let mut s = cone_surface(n, 1.0, 1.0, [0.0, 0.0, 1.0]).unwrap();
            let k = 2 + (rng.next() * n as f64) as usize;
            let t = std::f64::consts::TAU * rng.next();
            let r = 0.5 + rng.next();
            s.points[k] = [r * t.cos(), r * t.sin(), rng.dyadic(-0.5, 0.5)];
            surfaces.push(s);
            // The apex moved, through the base at times.
            let mut s = cone_surface(n, 1.0, 1.0, [0.0, 0.0, 1.0]).unwrap();
            s.points[0] = [
                rng.dyadic(-1.0, 1.0),
                rng.dyadic(-1.0, 1.0),
                rng.dyadic(-1.0, 1.0),
            ];
            surfaces.push(s);
        }
        for _ in 0..60 {
            // A sphere of 80 triangles with a few vertices displaced.
            let mut s = icosphere(1);
            for _ in 0..3 {
                let v = (rng.next() * s.points.len() as f64) as usize;
                let a = rng.next();
                for c in &mut s.points[v] {
                    *c += a * (2.0 * rng.next() - 1.0);
                }
            }
            surfaces.push(s);
            // A cube with a corner moved on dyadic coordinates: coplanar folds and touching.
            let mut s = cube(0.0, 1.0);
            let v = (rng.next() * 8.0) as usize;
            let mut p = s.points[v];
            let k = (rng.next() * 3.0) as usize;
            for (j, c) in p.iter_mut().enumerate() {
                if j != k || rng.next() < 0.5 {
                    *c = rng.dyadic(-0.5, 1.5);
                }
            }
            s.points[v] = p;
            // The same far from the origin (exactly: integers plus eighths), where the boxes'
            // margin and rounding grow with the coordinates.
            let mut far = s.clone();
            for p in &mut far.points {
                for (c, o) in p.iter_mut().zip([1e5, -3e5, 2e5]) {
                    *c += o;
                }
            }
            surfaces.push(s);
            surfaces.push(far);
        }
        let (mut crossing, mut clean) = (0, 0);
        for (i, s) in surfaces.iter().enumerate() {
            let nt = s.triangles.len();
            let degenerate = s.triangles.iter().any(|t| {
                let [a, b, c] = t.map(|v| s.points[v as usize]);
                crate::mesh::norm(cross(sub(b, a), sub(c, a))) == 0.0
            });
            if degenerate {
                continue;
            }
            let all_pairs = (0..nt).any(|a| {
                (a + 1..nt)
                    .any(|b| triangles_intersect(&s.points, &s.triangles[a], &s.triangles[b]))
            });
            let (m, _) = search(s);
            assert_eq!(m.is_some(), all_pairs, "surface {i}: {m:?}");
            if let Some(m) = m {
                let (a, b) = (s.triangles[m.first], s.triangles[m.second]);
                assert!(m.first < m.second);
                assert!(triangles_intersect(&s.points, &a, &b), "surface {i}: {m:?}");
                crossing += 1;
            } else {
                clean += 1;
            }
        }
        assert!(
            crossing > 50 && clean > 50,
            "{crossing} crossing, {clean} clean"
        );
    }

    #[test]
    fn pairs_sharing_the_apex_of_a_fan_are_never_tested() {
        // The side of a cone: every pair of its triangles shares the apex. The search tests
        // each rim edge against the few triangles near it, not the fan's pairs.
        let s = cone_surface(2000, 1.0, 1.0, [0.3, 0.5, 0.8]).unwrap();
        let (m, w) = search(&s);
        assert_eq!(m, None);
        let nt = s.triangles.len() as u64;
        assert!(w.candidates < 10 * nt, "{w:?}");
        assert!(w.volume_tests < 200 * nt, "{w:?}");
    }

    #[test]
    fn triangle_pair_predicate() {
        let pts = [
            [0.0, 0.0, 0.0],   // 0
            [1.0, 0.0, 0.0],   // 1
            [0.0, 1.0, 0.0],   // 2
            [0.0, 0.0, 1.0],   // 3
            [1.0, 1.0, 0.0],   // 4
            [0.2, 0.2, -1.0],  // 5
            [0.2, 0.2, 1.0],   // 6
            [0.3, 0.3, 1.0],   // 7
            [0.5, 0.5, 0.0],   // 8: on edge (1, 2)
            [-1.0, -1.0, 0.0], // 9
            [0.25, 0.25, 0.0], // 10: inside triangle (0, 1, 2)
        ];
        let x = |a: [u32; 3], b: [u32; 3]| triangles_intersect(&pts, &a, &b);
        // Common edge, folded at a right angle: only the edge.
        assert!(!x([0, 1, 2], [0, 1, 3]));
        // Common edge, coplanar, opposite sides: only the edge. Same side: overlap.
        assert!(!x([0, 1, 2], [1, 2, 4]));
        assert!(x([0, 1, 2], [1, 2, 10]));
        // Common vertex only, planes crossing elsewhere: a segment pierces.
        assert!(x([0, 1, 2], [0, 5, 7]));
        assert!(!x([0, 1, 2], [0, 3, 9]));
        // No common vertex: a vertical triangle piercing the middle.
        assert!(x([0, 1, 2], [5, 6, 7]));
        // Touching at a point counts (vertex 8 on the edge (1, 2)).
        assert!(x([0, 1, 2], [8, 6, 7]));
        // Coplanar, one inside the other without edge crossings.
        let tiny = [[0.2, 0.2, 0.0], [0.3, 0.2, 0.0], [0.2, 0.3, 0.0]];
        let mut p2 = pts.to_vec();
        p2.extend_from_slice(&tiny);
        assert!(triangles_intersect(&p2, &[0, 1, 2], &[11, 12, 13]));
        // Disjoint.
        assert!(!x([0, 1, 2], [3, 6, 7]));
    }

    #[test]
    fn eigenvectors_are_orthonormal_and_diagonalise() {
        let a = [[4.0, 1.0, -2.0], [1.0, 3.0, 0.5], [-2.0, 0.5, 1.0]];
        let u = eigenvectors(a);
        let mul = |x: [f64; 3]| [0, 1, 2].map(|i| dot(a[i], x));
        for i in 0..3 {
            for j in 0..3 {
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((dot(u[i], u[j]) - want).abs() < 1e-14, "{u:?}");
                if i != j {
                    assert!(dot(u[i], mul(u[j])).abs() < 1e-12, "{u:?}");
                }
            }
        }
        // Already diagonal, and rank one (a single direction of spread).
        assert_eq!(
            eigenvectors([[2.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0; 3]])[0],
            [1.0, 0.0, 0.0]
        );
        let d = [1.0, 2.0, 2.0];
        let r1 = [0, 1, 2].map(|i| [0, 1, 2].map(|j| d[i] * d[j]));
        let u = eigenvectors(r1);
        assert!(
            u.iter().any(|x| (dot(*x, d).abs() - 3.0).abs() < 1e-12),
            "{u:?}"
        );
    }

    #[test]
    fn segment_box_test_keeps_touching_segments() {
        let b = Obb {
            centre: [0.0; 3],
            axes: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            half: [1.0, 1.0, 1.0],
        };
        // Touches the corner (1, 1, 1) only.
        assert!(!segment_misses_box(
            [2.0, 2.0, 1.0],
            [1.0, 1.0, 0.0],
            &b,
            0.0
        ));
        // Passes the corner diagonally at a distance: only a cross-product axis separates.
        assert!(segment_misses_box(
            [2.0, 0.0, 2.0],
            [1.0, 0.0, -1.0],
            &b,
            0.0
        ));
        // Touches the edge x = z = 1.
        assert!(!segment_misses_box(
            [1.0, 0.0, 1.0],
            [1.0, 0.0, -1.0],
            &b,
            0.0
        ));
    }
}
