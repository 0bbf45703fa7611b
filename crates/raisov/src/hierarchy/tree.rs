//! A static, balanced k-d tree over element centroids, each carrying one non-negative scalar
//! `aux` (a search radius or an element measure); every tree node stores the bounding box of
//! its centroids and the largest `aux` below it, which gives exact pruning bounds:
//!
//! - [`CentroidTree::for_each_within`]: every item with `|p - c| <= aux` (a point inside an
//!   element lies within the element's own search radius of its centroid);
//! - [`CentroidTree::best_ratio`]: the item maximising `aux / |p - c|` (eq. 7), ties to the
//!   lowest id, found by branch and bound (`aux_max / dist(p, box)` bounds a subtree).
//!
//! Why not `kiddo`: kiddo 4's mutable tree panics when more than a bucket's worth of points
//! share a coordinate (any structured mesh), its immutable tree has had an underflow in
//! `calc_pivot` (kiddo issue #172), and neither stores the per-subtree maxima needed here.
//!
//! Layout: a complete binary tree in heap order (children of `i` are `2i+1`, `2i+2`), all
//! leaves at depth `D`, the smallest depth at which halving leaves at most [`LEAF`] items per
//! leaf. Items are permuted in place by median splits on the longest box axis (ties by id):
//! the result depends only on the input, never on the thread count. Floating-point box
//! distances never exceed the distance to any centroid inside the box (rounding is monotone),
//! so the pruning is exact, not approximate.

use rayon::prelude::*;

/// Most items in a leaf.
pub const LEAF: usize = 8;

/// One centroid with its element id and scalar.
#[derive(Clone, Copy, Debug)]
pub struct Item {
    pub c: [f64; 3],
    pub id: u32,
    pub aux: f64,
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
pub struct CentroidTree {
    items: Vec<Item>,
    nodes: Vec<Node>,
    first_leaf: usize,
}

/// Below this many items a subtree is split on the current thread.
const PAR_SPLIT: usize = 1 << 15;

fn cmp_on(axis: usize) -> impl Fn(&Item, &Item) -> std::cmp::Ordering {
    move |a, b| a.c[axis].total_cmp(&b.c[axis]).then(a.id.cmp(&b.id))
}

fn bbox(items: &[Item]) -> ([f64; 3], [f64; 3], f64) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    let mut aux = 0.0f64;
    for it in items {
        for k in 0..3 {
            lo[k] = lo[k].min(it.c[k]);
            hi[k] = hi[k].max(it.c[k]);
        }
        aux = aux.max(it.aux);
    }
    (lo, hi, aux)
}

fn longest_axis(lo: [f64; 3], hi: [f64; 3]) -> usize {
    let mut axis = 0;
    for k in 1..3 {
        if hi[k] - lo[k] > hi[axis] - lo[axis] {
            axis = k;
        }
    }
    axis
}

/// Median splits, `levels` deep, in place.
fn partition(items: &mut [Item], levels: u32) {
    if levels == 0 || items.len() < 2 {
        return;
    }
    let (lo, hi, _) = bbox(items);
    let mid = items.len() / 2;
    items.select_nth_unstable_by(mid, cmp_on(longest_axis(lo, hi)));
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

impl CentroidTree {
    /// Build from items (any order). `aux` must be finite and non-negative.
    pub fn new(mut items: Vec<Item>) -> Self {
        let n = items.len();
        if n == 0 {
            return CentroidTree {
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
                    bbox(&items[s as usize..e as usize])
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
        // Internal boxes bottom-up from their children.
        for i in (0..first_leaf).rev() {
            let (a, b) = (nodes[2 * i + 1], nodes[2 * i + 2]);
            let n = &mut nodes[i];
            for k in 0..3 {
                n.lo[k] = a.lo[k].min(b.lo[k]);
                n.hi[k] = a.hi[k].max(b.hi[k]);
            }
            n.aux = a.aux.max(b.aux);
        }
        CentroidTree {
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

    /// Call `f` on every item with `|p - c|^2 <= aux^2`, in a fixed order.
    pub fn for_each_within<F: FnMut(&Item)>(&self, p: [f64; 3], f: &mut F) {
        if !self.nodes.is_empty() {
            self.within_rec(0, p, f);
        }
    }

    fn within_rec<F: FnMut(&Item)>(&self, i: usize, p: [f64; 3], f: &mut F) {
        let n = &self.nodes[i];
        if box_dist2(p, n.lo, n.hi) > n.aux * n.aux {
            return;
        }
        if i >= self.first_leaf {
            for it in &self.items[n.start as usize..n.end as usize] {
                if dist2(p, it.c) <= it.aux * it.aux {
                    f(it);
                }
            }
        } else {
            self.within_rec(2 * i + 1, p, f);
            self.within_rec(2 * i + 2, p, f);
        }
    }

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

    fn items(n: usize) -> Vec<Item> {
        let mut s = 12345u64;
        let mut r = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        (0..n)
            .map(|i| Item {
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

    #[test]
    fn tree_queries_match_brute_force() {
        for n in [0, 1, 7, 8, 9, 100, 1000] {
            let it = items(n);
            let t = CentroidTree::new(it.clone());
            assert_eq!(t.len(), n);
            for q in [[0.3, 2.2, 1.0], [-3.0, 9.0, 0.0], [2.0, 2.0, 2.0 / 7.0]] {
                let mut got = Vec::new();
                t.for_each_within(q, &mut |x| got.push(x.id));
                got.sort_unstable();
                let want: Vec<u32> = it
                    .iter()
                    .filter(|x| dist2(q, x.c) <= x.aux * x.aux)
                    .map(|x| x.id)
                    .collect();
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
}
