//! Host elements and barycentric weights between two independent meshes (paper section 2.1).
//!
//! See the [module documentation](super) for the equations and conventions.

use std::fmt;

use rayon::prelude::*;

use super::tree::{dist2, BoxItem, PointItem, Tree};
use crate::geometry::{cross, dot, norm, sub};
use crate::mesh::{tet_volume, ElementKind, Mesh, DEGENERATE_REL};
use crate::{Error, Result};

/// A point counts as inside an element when its smallest weight is at least `-INSIDE_TOL`.
pub const INSIDE_TOL: f64 = 1e-10;

/// Relative slack on the element boxes searched (covers `INSIDE_TOL` and round-off).
const BOX_SLACK: f64 = 1e-6;

/// Membranes: element boxes are widened by this many centroid-to-vertex radii, enough for
/// every point that a triangle may host (plane distance at most one radius, and a gap
/// host's in-plane overshoot at most `d / r` times an altitude, at most two radii).
const TRI_BOX_WIDEN: f64 = 3.0;

/// Transfers with at least this many points are applied in parallel (bitwise the same).
const PAR_APPLY: usize = 1 << 14;

/// Host elements and weights of a set of points (the nodes of one level) in a target mesh:
/// `x(p_θ) = Σ_j weights[θ][j] · x(nodes[θ][j])` (eq. 6), one row per point.
#[derive(Clone, Debug, PartialEq)]
pub struct Transfer {
    /// Host element of each point in the target mesh.
    pub host: Vec<u32>,
    /// The host element's node ids (for triangles the 4th repeats the 1st, with weight 0).
    pub nodes: Vec<[u32; 4]>,
    /// Barycentric weights ω (eq. 6); they sum to 1. Below `-INSIDE_TOL` or above 1 only for
    /// the points in [`Transfer::outside`], and (slightly, see the module documentation) for
    /// membrane points in gaps between bent triangles. For triangles the 4th is 0.
    pub weights: Vec<[f64; 4]>,
    /// Nodes per element of the target mesh: 3 or 4.
    pub npe: usize,
    /// Number of nodes of the target mesh (the length, per component, of what is interpolated).
    pub target_nodes: usize,
    /// Points that lie in no element of the target; their host comes from eq. 7. Ascending.
    pub outside: Vec<u32>,
    /// Over [`Transfer::outside`], the largest of `-min ω` and `max ω - 1` (0 if none).
    pub max_extrapolation: f64,
    /// Membranes: the largest distance from a point to its host triangle's plane (the part of
    /// its position that the weights do not reproduce). 0 for tetrahedra.
    pub max_plane_distance: f64,
}

/// Per-element geometry of the target mesh.
#[derive(Clone, Copy, Debug)]
struct Geo {
    centroid: [f64; 3],
    /// Largest centroid-to-vertex distance.
    radius: f64,
    /// |area| or |volume|.
    measure: f64,
    /// Not degenerate: may host points.
    ok: bool,
}

/// A located point: host, weights, plane distance.
#[derive(Clone, Copy, Debug)]
struct Hit {
    e: u32,
    w: [f64; 4],
    plane: f64,
}

fn validate(points: &[[f64; 3]], target: &Mesh) -> Result<()> {
    let npe = target.npe();
    if !target.cells.len().is_multiple_of(npe) {
        return Err(Error::param(
            "target",
            format!(
                "connectivity length {} is not a multiple of {npe} ({})",
                target.cells.len(),
                target.kind.name()
            ),
        ));
    }
    if target.cells.is_empty() {
        return Err(Error::param("target", "mesh has no elements"));
    }
    let nn = target.nodes.len();
    if let Some(i) = target.cells.iter().position(|&n| n as usize >= nn) {
        return Err(Error::param(
            "target",
            format!(
                "element {} refers to node {} but the mesh has {nn} nodes",
                i / npe,
                target.cells[i]
            ),
        ));
    }
    if let Some(i) = target
        .nodes
        .iter()
        .position(|p| p.iter().any(|x| !x.is_finite()))
    {
        return Err(Error::param(
            "target",
            format!("node {i} has a non-finite coordinate"),
        ));
    }
    if let Some(i) = points.iter().position(|p| p.iter().any(|x| !x.is_finite())) {
        return Err(Error::param(
            "points",
            format!("point {i} has a non-finite coordinate"),
        ));
    }
    if points.len() > u32::MAX as usize {
        return Err(Error::param("points", "more than 2^32 - 1 points"));
    }
    Ok(())
}

fn element_geo(target: &Mesh) -> Vec<Geo> {
    let npe = target.npe();
    target
        .cells
        .par_chunks_exact(npe)
        .map(|el| {
            let mut c = [0.0; 3];
            for &n in el {
                let x = target.nodes[n as usize];
                for k in 0..3 {
                    c[k] += x[k];
                }
            }
            for ck in &mut c {
                *ck /= npe as f64;
            }
            let mut r2: f64 = 0.0;
            let mut h: f64 = 0.0;
            for (i, &a) in el.iter().enumerate() {
                let xa = target.nodes[a as usize];
                r2 = r2.max(dist2(xa, c));
                for &b in &el[i + 1..] {
                    h = h.max(dist2(xa, target.nodes[b as usize]));
                }
            }
            let h = h.sqrt();
            let x = |j: usize| target.nodes[el[j] as usize];
            let (measure, d) = match target.kind {
                ElementKind::Tri3 => (0.5 * norm(cross(sub(x(1), x(0)), sub(x(2), x(0)))), 2),
                ElementKind::Tet4 => (tet_volume(x(0), x(1), x(2), x(3)).abs(), 3),
            };
            Geo {
                centroid: c,
                radius: r2.sqrt(),
                measure,
                ok: h > 0.0 && measure > DEGENERATE_REL * h.powi(d),
            }
        })
        .collect()
}

/// Barycentric weights of `p` in element `el` (eq. 6) and, for triangles, the distance from
/// `p` to the triangle's plane. Sub-measures are normalised by (one reciprocal of) their sum,
/// so the weights sum to 1 up to round-off for any `p`, inside or not.
#[inline]
fn weights(kind: ElementKind, nodes: &[[f64; 3]], el: &[u32], p: [f64; 3]) -> ([f64; 4], f64) {
    let x = |j: usize| nodes[el[j] as usize];
    match kind {
        ElementKind::Tet4 => {
            let (x0, x1, x2, x3) = (x(0), x(1), x(2), x(3));
            let v = [
                tet_volume(p, x1, x2, x3),
                tet_volume(x0, p, x2, x3),
                tet_volume(x0, x1, p, x3),
                tet_volume(x0, x1, x2, p),
            ];
            let inv = 1.0 / (v[0] + v[1] + v[2] + v[3]);
            ([v[0] * inv, v[1] * inv, v[2] * inv, v[3] * inv], 0.0)
        }
        ElementKind::Tri3 => {
            let (x0, x1, x2) = (x(0), x(1), x(2));
            let n = cross(sub(x1, x0), sub(x2, x0));
            let (a, b, c) = (sub(x0, p), sub(x1, p), sub(x2, p));
            // Signed sub-areas relative to the normal: the off-plane part of p cancels, so
            // these are the coordinates of p's projection onto the plane.
            let a0 = dot(cross(b, c), n);
            let a1 = dot(cross(c, a), n);
            let a2 = dot(cross(a, b), n);
            let inv = 1.0 / (a0 + a1 + a2);
            let nn = norm(n);
            let plane = if nn > 0.0 {
                (dot(sub(p, x0), n) / nn).abs()
            } else {
                0.0
            };
            ([a0 * inv, a1 * inv, a2 * inv, 0.0], plane)
        }
    }
}

fn min_weight(w: &[f64; 4], npe: usize) -> f64 {
    w[..npe].iter().copied().fold(f64::INFINITY, f64::min)
}

/// Elements with a boundary facet (a facet that belongs to one element only).
fn boundary_elements(mesh: &Mesh) -> Vec<bool> {
    let npe = mesh.npe();
    let ne = mesh.num_elements();
    // Key: the facet's sorted node ids, then the element id, packed in a u128 (fast to sort).
    let facets_of = |e: usize| {
        let el = mesh.element(e);
        (0..npe).map(move |skip| {
            let mut f = [u32::MAX; 3];
            let mut k = 0;
            for (j, &n) in el.iter().enumerate() {
                if j != skip {
                    f[k] = n;
                    k += 1;
                }
            }
            f.sort_unstable();
            (f[0] as u128) << 96 | (f[1] as u128) << 64 | (f[2] as u128) << 32 | e as u128
        })
    };
    let mut facets: Vec<u128> = (0..ne).into_par_iter().flat_map_iter(facets_of).collect();
    // A total order (the element id is part of the key): the same result on any thread count.
    facets.par_sort_unstable();
    let mut bnd = vec![false; ne];
    let mut i = 0;
    while i < facets.len() {
        let mut j = i + 1;
        while j < facets.len() && facets[j] >> 32 == facets[i] >> 32 {
            j += 1;
        }
        if j - i == 1 {
            bnd[(facets[i] & 0xffff_ffff) as usize] = true;
        }
        i = j;
    }
    bnd
}

impl Transfer {
    /// Locate every point in `target` (see the [module documentation](super)).
    ///
    /// Errors: a target without elements, node ids out of range, non-finite coordinates, or
    /// a target whose elements are all degenerate.
    pub fn build(points: &[[f64; 3]], target: &Mesh) -> Result<Transfer> {
        validate(points, target)?;
        let kind = target.kind;
        let npe = target.npe();
        let geo = element_geo(target);
        let boxes: Vec<BoxItem> = geo
            .par_iter()
            .enumerate()
            .filter(|(_, g)| g.ok)
            .map(|(e, g)| {
                let mut lo = [f64::INFINITY; 3];
                let mut hi = [f64::NEG_INFINITY; 3];
                for &n in target.element(e) {
                    let x = target.nodes[n as usize];
                    for k in 0..3 {
                        lo[k] = lo[k].min(x[k]);
                        hi[k] = hi[k].max(x[k]);
                    }
                }
                let widen = g.radius
                    * match kind {
                        ElementKind::Tri3 => TRI_BOX_WIDEN,
                        ElementKind::Tet4 => BOX_SLACK,
                    };
                BoxItem::new(lo.map(|x| x - widen), hi.map(|x| x + widen), e as u32)
            })
            .collect();
        if boxes.is_empty() {
            return Err(Error::param("target", "every element is degenerate"));
        }
        let tree = Tree::new(boxes);

        let located: Vec<Option<Hit>> = points
            .par_iter()
            .map(|&p| {
                // Best candidate by (class, plane distance, -min weight, id); see the
                // module documentation for the two classes.
                let mut best: Option<(bool, f64, f64, Hit)> = None;
                tree.for_each_containing(p, &mut |id| {
                    let e = id as usize;
                    let (w, plane) = weights(kind, &target.nodes, target.element(e), p);
                    let mw = min_weight(&w, npe);
                    let r = geo[e].radius;
                    if plane.is_nan() || plane > r {
                        return;
                    }
                    let inside = mw >= -INSIDE_TOL;
                    if !inside && (mw.is_nan() || mw < -INSIDE_TOL - plane / r) {
                        return;
                    }
                    // Class B (membrane gaps) ranks by min weight only.
                    let pe = if !inside || plane <= 1e-9 * r {
                        0.0
                    } else {
                        plane
                    };
                    let better = match &best {
                        None => true,
                        Some((bi, bp, bw, bh)) => {
                            (inside && !bi)
                                || (inside == *bi
                                    && (pe < *bp
                                        || (pe == *bp && (mw > *bw || (mw == *bw && id < bh.e)))))
                        }
                    };
                    if better {
                        best = Some((inside, pe, mw, Hit { e: id, w, plane }));
                    }
                });
                best.map(|b| b.3)
            })
            .collect();
        drop(tree);

        let mut outside: Vec<u32> = located
            .iter()
            .enumerate()
            .filter(|(_, h)| h.is_none())
            .map(|(i, _)| i as u32)
            .collect();
        let mut hits: Vec<Hit> = Vec::with_capacity(points.len());
        let mut max_extrapolation: f64 = 0.0;
        if outside.is_empty() {
            hits.extend(located.into_iter().flatten());
        } else {
            // Eq. 7 over the non-degenerate boundary elements.
            let bnd = boundary_elements(target);
            let items: Vec<PointItem> = geo
                .iter()
                .enumerate()
                .filter(|&(e, g)| g.ok && bnd[e])
                .map(|(e, g)| PointItem {
                    c: g.centroid,
                    id: e as u32,
                    aux: g.measure,
                })
                .collect();
            if items.is_empty() {
                return Err(Error::param(
                    "target",
                    "no non-degenerate boundary element to host outside points",
                ));
            }
            let btree = Tree::new(items);
            let extra: Vec<Hit> = outside
                .par_iter()
                .map(|&i| {
                    let p = points[i as usize];
                    // Non-empty tree: always Some.
                    let e = btree.best_ratio(p).map_or(0, |b| b.0);
                    let (w, plane) = weights(kind, &target.nodes, target.element(e as usize), p);
                    Hit { e, w, plane }
                })
                .collect();
            let mut k = 0;
            for h in located {
                match h {
                    Some(h) => hits.push(h),
                    None => {
                        let h = extra[k];
                        k += 1;
                        let w = &h.w[..npe];
                        let lo = w.iter().copied().fold(f64::INFINITY, f64::min);
                        let hi = w.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                        max_extrapolation = max_extrapolation.max(-lo).max(hi - 1.0);
                        hits.push(h);
                    }
                }
            }
            outside.shrink_to_fit();
        }

        let mut t = Transfer {
            host: Vec::with_capacity(hits.len()),
            nodes: Vec::with_capacity(hits.len()),
            weights: Vec::with_capacity(hits.len()),
            npe,
            target_nodes: target.nodes.len(),
            outside,
            max_extrapolation,
            max_plane_distance: 0.0,
        };
        for h in hits {
            let el = target.element(h.e as usize);
            let nd = if npe == 4 {
                [el[0], el[1], el[2], el[3]]
            } else {
                [el[0], el[1], el[2], el[0]]
            };
            t.host.push(h.e);
            t.nodes.push(nd);
            t.weights.push(h.w);
            t.max_plane_distance = t.max_plane_distance.max(h.plane);
        }
        Ok(t)
    }

    /// The same hosts with convex weights: negative weights set to 0 and the rest divided by
    /// their sum, so every value is a convex combination of its host's corner values. Inside
    /// points (weights in `[0, 1]` up to [`INSIDE_TOL`]) are unchanged up to that tolerance;
    /// outside points take a point of their host element instead of extrapolating (eq. 7's
    /// weights reach 2-3 on the liver levels). Constants are still reproduced exactly, linear
    /// fields only inside. `max_extrapolation` of the result is 0.
    pub fn convex(&self) -> Transfer {
        let mut t = self.clone();
        for w in t.weights.iter_mut() {
            if w[..t.npe].iter().all(|&x| x >= 0.0) {
                continue;
            }
            let mut sum = 0.0;
            for x in w[..t.npe].iter_mut() {
                *x = x.max(0.0);
                sum += *x;
            }
            for x in w[..t.npe].iter_mut() {
                *x /= sum;
            }
        }
        t.max_extrapolation = 0.0;
        t
    }

    /// The same hosts, eq. 7's extrapolated weights kept where they leave `[0, 1]` by at most
    /// `limit` (linear fields reproduced there too) and made convex ([`Transfer::convex`])
    /// at the points beyond it, far outside their host.
    pub fn limited(&self, limit: f64) -> Transfer {
        let convex = self.convex();
        let mut t = self.clone();
        let mut max_extrapolation: f64 = 0.0;
        for (w, c) in t.weights.iter_mut().zip(&convex.weights) {
            let reach = w[..t.npe]
                .iter()
                .fold(0.0f64, |m, &x| m.max(-x).max(x - 1.0));
            if reach > limit {
                *w = *c;
            } else {
                max_extrapolation = max_extrapolation.max(reach);
            }
        }
        t.max_extrapolation = max_extrapolation;
        t
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.host.len()
    }

    /// Whether there are no points.
    pub fn is_empty(&self) -> bool {
        self.host.is_empty()
    }

    fn check(&self, per_target: usize, per_point: usize, comps: usize) -> Result<()> {
        if comps == 0 {
            return Err(Error::param("comps", "must be at least 1"));
        }
        if per_target != comps * self.target_nodes {
            return Err(Error::param(
                "target values",
                format!(
                    "length {per_target}, expected {comps} x {} target nodes",
                    self.target_nodes
                ),
            ));
        }
        if per_point != comps * self.len() {
            return Err(Error::param(
                "point values",
                format!(
                    "length {per_point}, expected {comps} x {} points",
                    self.len()
                ),
            ));
        }
        Ok(())
    }

    fn gather(&self, src: &[f64], comps: usize, out: &mut [f64], add: bool) {
        // Unrolled for the common cases (3-vectors on tets or triangles); the same
        // operations in the same order as the general loop, so the same bits.
        match (self.npe, comps, add) {
            (4, 3, false) => self.gather_n::<4, 3, false>(src, 3, out),
            (4, 3, true) => self.gather_n::<4, 3, true>(src, 3, out),
            (3, 3, false) => self.gather_n::<3, 3, false>(src, 3, out),
            (3, 3, true) => self.gather_n::<3, 3, true>(src, 3, out),
            _ => self.gather_any(src, comps, out, add),
        }
    }

    /// The general loop (any host count, any components): the reference the unrolled cases
    /// are tested against.
    pub(super) fn gather_any(&self, src: &[f64], comps: usize, out: &mut [f64], add: bool) {
        if add {
            self.gather_n::<0, 0, true>(src, comps, out)
        } else {
            self.gather_n::<0, 0, false>(src, comps, out)
        }
    }

    /// `N` hosts and `C` components known at compile time (0: the run-time `self.npe` and
    /// `comps`); `ADD`: add to `out` instead of setting it.
    fn gather_n<const N: usize, const C: usize, const ADD: bool>(
        &self,
        src: &[f64],
        comps: usize,
        out: &mut [f64],
    ) {
        // Evaluated inside the closure, so that `N` and `C` stay compile-time constants in
        // its body (captured values would not be, once rayon calls it).
        let (rt_npe, rt_comps) = (self.npe, comps);
        let comps = if C == 0 { rt_comps } else { C };
        let body = |(t, o): (usize, &mut [f64])| {
            let npe = if N == 0 { rt_npe } else { N };
            let comps = if C == 0 { rt_comps } else { C };
            let nd = &self.nodes[t];
            let w = &self.weights[t];
            for (c, oc) in o.iter_mut().enumerate() {
                let mut acc = 0.0;
                for j in 0..npe {
                    acc += w[j] * src[nd[j] as usize * comps + c];
                }
                if ADD {
                    *oc += acc;
                } else {
                    *oc = acc;
                }
            }
        };
        if self.len() >= PAR_APPLY {
            out.par_chunks_mut(comps).enumerate().for_each(body);
        } else {
            out.chunks_mut(comps).enumerate().for_each(body);
        }
    }

    /// `out[θ] = Σ_j ω_θj src[host node j]`, `comps` values per node (3 for a displacement):
    /// `src` has `comps × target_nodes` values, `out` `comps × len()`. No allocation.
    pub fn interpolate(&self, src: &[f64], comps: usize, out: &mut [f64]) -> Result<()> {
        self.check(src.len(), out.len(), comps)?;
        self.gather(src, comps, out, false);
        Ok(())
    }

    /// `out[θ] += Σ_j ω_θj src[host node j]`; see [`Transfer::interpolate`].
    pub fn interpolate_add(&self, src: &[f64], comps: usize, out: &mut [f64]) -> Result<()> {
        self.check(src.len(), out.len(), comps)?;
        self.gather(src, comps, out, true);
        Ok(())
    }

    /// The transpose: `out[host node j] += ω_θj src[θ]` for every point θ (in increasing θ,
    /// so the result is deterministic). `src_per_point` has `comps × len()` values,
    /// `out_per_target_node` `comps × target_nodes`. No allocation.
    pub fn transpose_add(
        &self,
        src_per_point: &[f64],
        comps: usize,
        out_per_target_node: &mut [f64],
    ) -> Result<()> {
        self.check(out_per_target_node.len(), src_per_point.len(), comps)?;
        let npe = self.npe;
        for (t, s) in src_per_point.chunks_exact(comps).enumerate() {
            let nd = &self.nodes[t];
            let w = &self.weights[t];
            for j in 0..npe {
                let o = &mut out_per_target_node[nd[j] as usize * comps..][..comps];
                for (oc, sc) in o.iter_mut().zip(s) {
                    *oc += w[j] * sc;
                }
            }
        }
        Ok(())
    }
}

/// The correspondence between a fine level and the next coarser one.
#[derive(Clone, Debug, PartialEq)]
pub struct Correspondence {
    /// Fine nodes located in the coarse mesh: interpolation P from coarse to fine.
    pub down: Transfer,
    /// Coarse nodes located in the fine mesh: the paper's restriction R (fine to coarse).
    pub up: Transfer,
    /// What the build found (coverage, extrapolation).
    pub report: CorrespondenceReport,
}

/// What [`Correspondence::build`] found.
#[derive(Clone, Debug, PartialEq)]
pub struct CorrespondenceReport {
    /// Nodes of the fine mesh.
    pub fine_nodes: usize,
    /// Nodes of the coarse mesh.
    pub coarse_nodes: usize,
    /// Fine nodes outside every coarse element (hosted by eq. 7).
    pub fine_outside: usize,
    /// Coarse nodes outside every fine element (hosted by eq. 7).
    pub coarse_outside: usize,
    /// The larger of the two transfers' [`Transfer::max_extrapolation`].
    pub max_extrapolation: f64,
    /// Membranes: the larger of the two transfers' [`Transfer::max_plane_distance`].
    pub max_plane_distance: f64,
    /// The covering condition of section 2.1 holds: `uncovered_fine_nodes == 0`.
    pub covered: bool,
    /// Fine nodes (used by some fine element) that are a corner of no coarse node's host.
    pub uncovered_fine_nodes: usize,
}

impl fmt::Display for CorrespondenceReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} fine / {} coarse nodes; outside the other mesh: {} fine, {} coarse; \
             max extrapolation {:.3e}; ",
            self.fine_nodes,
            self.coarse_nodes,
            self.fine_outside,
            self.coarse_outside,
            self.max_extrapolation
        )?;
        if self.max_plane_distance > 0.0 {
            write!(f, "max plane distance {:.3e}; ", self.max_plane_distance)?;
        }
        if self.covered {
            write!(f, "covering: yes")
        } else {
            write!(
                f,
                "covering: no ({} fine nodes are a corner of no coarse node's host)",
                self.uncovered_fine_nodes
            )
        }
    }
}

impl Correspondence {
    /// Locate the fine nodes in the coarse mesh and the coarse nodes in the fine mesh.
    pub fn build(fine: &Mesh, coarse: &Mesh) -> Result<Correspondence> {
        if fine.kind != coarse.kind {
            return Err(Error::param(
                "levels",
                format!(
                    "fine mesh is {}, coarse mesh is {}",
                    fine.kind.name(),
                    coarse.kind.name()
                ),
            ));
        }
        let down = Transfer::build(&fine.nodes, coarse)?;
        let up = Transfer::build(&coarse.nodes, fine)?;
        let mut covered = vec![false; fine.nodes.len()];
        for nd in &up.nodes {
            for &n in &nd[..up.npe] {
                covered[n as usize] = true;
            }
        }
        let uncovered = fine
            .used_nodes()
            .iter()
            .zip(&covered)
            .filter(|&(&u, &c)| u && !c)
            .count();
        let report = CorrespondenceReport {
            fine_nodes: fine.nodes.len(),
            coarse_nodes: coarse.nodes.len(),
            fine_outside: down.outside.len(),
            coarse_outside: up.outside.len(),
            max_extrapolation: down.max_extrapolation.max(up.max_extrapolation),
            max_plane_distance: down.max_plane_distance.max(up.max_plane_distance),
            covered: uncovered == 0,
            uncovered_fine_nodes: uncovered,
        };
        Ok(Correspondence { down, up, report })
    }
}
