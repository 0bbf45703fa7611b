//! A static, balanced k-d tree over element data, two kinds of items:
//!
//! - [`BoxItem`]: an element's bounding box (f32, rounded outwards); every tree node stores
//!   the union of its items' boxes, and [`Tree::for_each_containing`] visits every item whose
//!   box contains a point (a point inside an element lies in the element's box);
//! - [`PointItem`]: an element's centroid and a non-negative scalar (its measure); every tree
//!   node stores the box of its centroids and the largest scalar below it, and
//!   [`Tree::best_ratio`] finds the item maximising `aux / |p - c|` (eq. 7), ties to the
//!   lowest id, by branch and bound (`aux_max / dist(p, box)` bounds a subtree).
//!
//! Why not `kiddo`: kiddo 4's mutable tree panics when more than a bucket's worth of points
//! share a coordinate (any structured mesh), its immutable tree has had an underflow in
//! `calc_pivot` (kiddo issue #172), and neither stores boxes or per-subtree maxima.
//!
//! Layout: a complete binary tree in heap order (children of `i` are `2i+1`, `2i+2`), all
//! leaves at depth `D`, the smallest depth at which halving leaves at most [`LEAF`] items per
//! leaf. Items are permuted in place by median splits of their centres on the longest axis
//! (ties by id): the result depends only on the input, never on the thread count. Box tests
//! are exact (outward rounding), and floating-point box distances never exceed the distance to
//! any centroid inside the box (rounding is monotone), so the pruning is exact.

use rayon::prelude::*;

/// Most items in a leaf.
pub const LEAF: usize = 8;

/// What the tree needs from an item.
pub trait TreeItem: Copy + Send + Sync {
    /// Centre coordinate on `axis` (the split key).
    fn key(&self, axis: usize) -> f64;
    fn id(&self) -> u32;
    /// Bounds that the tree nodes enclose.
    fn bounds(&self) -> ([f64; 3], [f64; 3]);
    /// Scalar whose maximum the tree nodes keep.
    fn aux(&self) -> f64;
}

/// An element's bounding box, in f32 rounded outwards.
#[derive(Clone, Copy, Debug)]
pub struct BoxItem {
    pub lo: [f32; 3],
    pub hi: [f32; 3],
    pub id: u32,
}

impl BoxItem {
    /// The f32 box enclosing `[lo, hi]`.
    pub fn new(lo: [f64; 3], hi: [f64; 3], id: u32) -> Self {
        let down = |x: f64| {
            let y = x as f32;
            if y as f64 > x {
                y.next_down()
            } else {
                y
            }
        };
        let up = |x: f64| {
            let y = x as f32;
            if (y as f64) < x {
                y.next_up()
            } else {
                y
            }
        };
        BoxItem {
            lo: lo.map(down),
            hi: hi.map(up),
            id,
        }
    }
    #[inline]
    fn contains(&self, p: [f64; 3]) -> bool {
        (0..3).all(|k| self.lo[k] as f64 <= p[k] && p[k] <= self.hi[k] as f64)
    }
}

impl TreeItem for BoxItem {
    fn key(&self, axis: usize) -> f64 {
        0.5 * (self.lo[axis] as f64 + self.hi[axis] as f64)
    }
    fn id(&self) -> u32 {
        self.id
    }
    fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        (self.lo.map(f64::from), self.hi.map(f64::from))
    }
    fn aux(&self) -> f64 {
        0.0
    }
}

/// A centroid with its element id and scalar.
#[derive(Clone, Copy, Debug)]
pub struct PointItem {
    pub c: [f64; 3],
    pub id: u32,
    pub aux: f64,
}

impl TreeItem for PointItem {
    fn key(&self, axis: usize) -> f64 {
        self.c[axis]
    }
    fn id(&self) -> u32 {
        self.id
    }
    fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        (self.c, self.c)
    }
    fn aux(&self) -> f64 {
        self.aux
    }
}

#[derive(Clone, Copy, Debug)]
struct Node {
    lo: [f64; 3],
    hi: [f64; 3],
    aux: f64,
    start: u32,
    end: u32,
}

/// See the module documentation.
#[derive(Clone, Debug)]
pub struct Tree<I> {
    items: Vec<I>,
    nodes: Vec<Node>,
    first_leaf: usize,
}

/// Below this many items a subtree is split on the current thread.
const PAR_SPLIT: usize = 1 << 15;

/// Union of the items' bounds and their largest `aux`.
fn bounds_of<I: TreeItem>(items: &[I]) -> ([f64; 3], [f64; 3], f64) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    let mut aux = 0.0f64;
    for it in items {
        let (a, b) = it.bounds();
        for k in 0..3 {
            lo[k] = lo[k].min(a[k]);
            hi[k] = hi[k].max(b[k]);
        }
        aux = aux.max(it.aux());
    }
    (lo, hi, aux)
}

/// Median splits of the centres, `levels` deep, in place.
fn partition<I: TreeItem>(items: &mut [I], levels: u32) {
    if levels == 0 || items.len() < 2 {
        return;
    }
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for it in items.iter() {
        for k in 0..3 {
            lo[k] = lo[k].min(it.key(k));
            hi[k] = hi[k].max(it.key(k));
        }
    }
    let mut axis = 0;
    for k in 1..3 {
        if hi[k] - lo[k] > hi[axis] - lo[axis] {
            axis = k;
        }
    }
    let mid = items.len() / 2;
    items.select_nth_unstable_by(mid, |a, b| {
        a.key(axis)
            .total_cmp(&b.key(axis))
            .then(a.id().cmp(&b.id()))
    });
    let (l, r) = items.split_at_mut(mid);
    if l.len() + r.len() >= PAR_SPLIT {
        rayon::join(|| partition(l, levels - 1), || partition(r, levels - 1));
    } else {
        partition(l, levels - 1);
        partition(r, levels - 1);
    }
}

/// Squared distance from `p` to the box `[lo, hi]` (0 inside).
#[inline]
fn box_dist2(p: [f64; 3], lo: [f64; 3], hi: [f64; 3]) -> f64 {
    let mut d2 = 0.0;
    for k in 0..3 {
        let d = if p[k] < lo[k] {
            lo[k] - p[k]
        } else if p[k] > hi[k] {
            p[k] - hi[k]
        } else {
            0.0
        };
        d2 += d * d;
    }
    d2
}

#[inline]
fn in_box(p: [f64; 3], lo: [f64; 3], hi: [f64; 3]) -> bool {
    (0..3).all(|k| lo[k] <= p[k] && p[k] <= hi[k])
}

/// Squared distance between two points.
#[inline]
pub fn dist2(a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
}

/// `m / gamma` of eq. 7, infinite at the centroid itself.
#[inline]
pub fn ratio(m: f64, gamma2: f64) -> f64 {
    if gamma2 > 0.0 {
        m / gamma2.sqrt()
    } else {
        f64::INFINITY
    }
}

impl<I: TreeItem> Tree<I> {
    /// Build from items (any order). `aux` must be finite and non-negative.
    pub fn new(mut items: Vec<I>) -> Self {
        let n = items.len();
        if n == 0 {
            return Tree {
                items,
                nodes: Vec::new(),
                first_leaf: 0,
            };
        }
        let mut depth = 0u32;
        while n.div_ceil(1usize << depth) > LEAF {
            depth += 1;
        }
        partition(&mut items, depth);
        let count = (1usize << (depth + 1)) - 1;
        let first_leaf = (1usize << depth) - 1;
        // Ranges top-down (the same halving as `partition`).
        let mut ranges = vec![(0u32, 0u32); count];
        ranges[0] = (0, n as u32);
        for i in 0..first_leaf {
            let (s, e) = ranges[i];
            let mid = s + (e - s) / 2;
            ranges[2 * i + 1] = (s, mid);
            ranges[2 * i + 2] = (mid, e);
        }
        let mut nodes: Vec<Node> = ranges
            .par_iter()
            .enumerate()
            .map(|(i, &(s, e))| {
                let (lo, hi, aux) = if i >= first_leaf {
                    bounds_of(&items[s as usize..e as usize])
                } else {
                    ([0.0; 3], [0.0; 3], 0.0)
                };
                Node {
                    lo,
                    hi,
                    aux,
                    start: s,
                    end: e,
                }
            })
            .collect();
        // Internal bounds bottom-up from the children.
        for i in (0..first_leaf).rev() {
            let (a, b) = (nodes[2 * i + 1], nodes[2 * i + 2]);
            let n = &mut nodes[i];
            for k in 0..3 {
                n.lo[k] = a.lo[k].min(b.lo[k]);
                n.hi[k] = a.hi[k].max(b.hi[k]);
            }
            n.aux = a.aux.max(b.aux);
        }
        Tree {
            items,
            nodes,
            first_leaf,
        }
    }

    /// Number of items.
    #[cfg(test)]
    pub fn len(&self) -> usize {
        self.items.len()
    }
}

impl Tree<BoxItem> {
    /// Call `f` on every item whose box contains `p`, in a fixed order.
    pub fn for_each_containing<F: FnMut(u32)>(&self, p: [f64; 3], f: &mut F) {
        if !self.nodes.is_empty() {
            self.containing_rec(0, p, f);
        }
    }

    fn containing_rec<F: FnMut(u32)>(&self, i: usize, p: [f64; 3], f: &mut F) {
        let n = &self.nodes[i];
        if !in_box(p, n.lo, n.hi) {
            return;
        }
        if i >= self.first_leaf {
            for it in &self.items[n.start as usize..n.end as usize] {
                if it.contains(p) {
                    f(it.id);
                }
            }
        } else {
            self.containing_rec(2 * i + 1, p, f);
            self.containing_rec(2 * i + 2, p, f);
        }
    }
}

impl Tree<PointItem> {
    /// The item maximising `aux / |p - c|` (infinite at `c == p`), ties to the lowest id:
    /// `(id, ratio)`, or `None` for an empty tree.
    pub fn best_ratio(&self, p: [f64; 3]) -> Option<(u32, f64)> {
        if self.nodes.is_empty() {
            return None;
        }
        let mut best = (u32::MAX, f64::NEG_INFINITY);
        self.ratio_rec(0, p, &mut best);
        Some(best)
    }

    fn ratio_rec(&self, i: usize, p: [f64; 3], best: &mut (u32, f64)) {
        let n = &self.nodes[i];
        // Strict: a subtree that can only tie is still visited (ties go to the lowest id).
        if ratio(n.aux, box_dist2(p, n.lo, n.hi)) < best.1 {
            return;
        }
        if i >= self.first_leaf {
            for it in &self.items[n.start as usize..n.end as usize] {
                let r = ratio(it.aux, dist2(p, it.c));
                if r > best.1 || (r == best.1 && it.id < best.0) {
                    *best = (it.id, r);
                }
            }
        } else {
            let (a, b) = (2 * i + 1, 2 * i + 2);
            let da = box_dist2(p, self.nodes[a].lo, self.nodes[a].hi);
            let db = box_dist2(p, self.nodes[b].lo, self.nodes[b].hi);
            let (first, second) = if db < da { (b, a) } else { (a, b) };
            self.ratio_rec(first, p, best);
            self.ratio_rec(second, p, best);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rng(seed: u64) -> impl FnMut() -> f64 {
        let mut s = seed;
        move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    fn points(n: usize) -> Vec<PointItem> {
        let mut r = rng(12345);
        (0..n)
            .map(|i| PointItem {
                // Coarse coordinates: many shared values on each axis.
                c: [
                    (r() * 5.0).floor(),
                    (r() * 5.0).floor(),
                    (r() * 50.0).floor() / 7.0,
                ],
                id: i as u32,
                aux: r() * 2.0,
            })
            .collect()
    }

    fn boxes(n: usize) -> Vec<BoxItem> {
        let mut r = rng(777);
        (0..n)
            .map(|i| {
                let lo = [(r() * 5.0).floor(), r() * 5.0, (r() * 50.0).floor() / 7.0];
                let hi = [lo[0] + r(), lo[1] + 2.0 * r(), lo[2] + 0.1];
                BoxItem::new(lo, hi, i as u32)
            })
            .collect()
    }

    const QUERIES: [[f64; 3]; 4] = [
        [0.3, 2.2, 1.0],
        [-3.0, 9.0, 0.0],
        [2.0, 2.0, 2.0 / 7.0],
        [1.5, 3.1, 4.0 / 7.0],
    ];

    #[test]
    fn tree_queries_match_brute_force() {
        for n in [0, 1, 7, 8, 9, 100, 1000] {
            let it = points(n);
            let t = Tree::new(it.clone());
            assert_eq!(t.len(), n);
            let bx = boxes(n);
            let tb = Tree::new(bx.clone());
            for q in QUERIES {
                let mut got = Vec::new();
                tb.for_each_containing(q, &mut |id| got.push(id));
                got.sort_unstable();
                let want: Vec<u32> = bx.iter().filter(|b| b.contains(q)).map(|b| b.id).collect();
                assert_eq!(got, want);
                let mut bb = None::<(u32, f64)>;
                for x in &it {
                    let r = ratio(x.aux, dist2(q, x.c));
                    if bb.is_none_or(|b| r > b.1) {
                        bb = Some((x.id, r));
                    }
                }
                assert_eq!(t.best_ratio(q), bb);
            }
        }
    }

    #[test]
    fn f32_boxes_round_outwards() {
        let b = BoxItem::new([0.1, -0.1, 1e-9], [0.3, 1.0 / 3.0, 123.456789], 0);
        assert!(b.contains([0.1, -0.1, 1e-9]));
        assert!(b.contains([0.3, 1.0 / 3.0, 123.456789]));
    }
}
