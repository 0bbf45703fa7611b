//! Tetrahedral meshes of a closed triangle surface by isosurface stuffing (Labelle &
//! Shewchuk 2007, *Isosurface Stuffing: Fast Tetrahedral Meshes with Good Dihedral Angles*),
//! and multigrid levels of them ([`mesh_levels`]).
//!
//! The domain is `{p : f(p) ≤ 0}` for an implicit function `f`, here the surface's signed
//! inside/outside indicator: `f < 0` where the winding number of the surface is non-zero
//! (see `distance` for the exact test). The algorithm:
//!
//! 1. **Lattice.** A body-centred cubic lattice of spacing `h` (long edge `h`, short edge
//!    `(√3/2) h`) covering the surface's bounding box with a margin of at least `1.5 h`
//!    (`lattice`); `f`'s sign at every lattice vertex (by rows along `x`).
//! 2. **Cut points.** On every lattice edge whose ends have opposite strict signs, the
//!    point where the edge crosses the surface (segment–triangle intersection; of several,
//!    the one nearest the inside end).
//! 3. **Warp.** A cut point *violates* an end `v` of its edge `e` when it lies within
//!    `α |e|` of `v`, `α = α_long = 0.24046` on long edges and `α = α_short = 0.35332` on
//!    short ones. In increasing vertex id, each vertex violated by a cut point that still
//!    exists moves to the nearest such cut point and becomes a zero vertex; the cut points
//!    on its other edges disappear (their edges no longer change sign).
//! 4. **Fill.** Every lattice tetrahedron with an inside vertex is filled by its stencil
//!    (`stencils`): its part with interpolated `f ≤ 0`, split into 1 to 3 tetrahedra with
//!    quadrilateral diagonals chosen from the lattice face alone, so neighbours agree.
//!
//! **Guarantee** (the paper's theorem for these `α`): every output tetrahedron has all its
//! dihedral angles in `[10.7°, 164.8°]`, whatever the surface (the bound depends only on
//! where the cut points lie on their edges, not on the surface's smoothness). The surface
//! is approximated: the mesh boundary interpolates it through the cut points and warped
//! vertices (every boundary node lies on the surface); features smaller than about `h`
//! are rounded or lost, and sharp edges and corners are cut.
//!
//! Output: a [`Mesh`] of positive [`ElementKind::Tet4`], nodes without unused ones, a group
//! `"boundary"` with the boundary nodes. Deterministic: the same bits on any number of
//! threads (parallel loops write disjoint, ordered results; the warp runs in id order).
//!
//! The lattice is offset by fixed irrational fractions of `h` from the bounding box so that
//! lattice rows rarely pass through surface vertices of meshes built on round coordinates.

pub(crate) mod distance;
pub(crate) mod lattice;
mod levels;
pub(crate) mod stencils;

#[cfg(test)]
mod tests;

pub use levels::{
    mesh_levels, mesh_levels_report, tet_dihedral_range, LevelReport, LevelTarget, LevelsReport,
};

use crate::geometry::{norm, sub};
use crate::mesh::{tet_volume, ElementKind, Mesh, Surface};
use crate::{Error, Result};
use distance::SurfaceField;
use lattice::{edge_key, Lattice};
use rayon::prelude::*;
use std::collections::HashMap;
use stencils::{fill, FillCtx, Filled};

/// Version of the meshes this mesher makes, part of the cache key of scenarios that mesh a
/// surface at load (`scenario::surface`): increase it whenever the output for the same input
/// changes, so that cached levels are meshed again.
pub const MESHER_VERSION: u32 = 1;

/// Bytes a lattice vertex may take while meshing: its sign, its node number, its slot in
/// the used-node map.
pub const LATTICE_VERTEX_BYTES: u64 = 9;

/// Bytes an inside lattice vertex may take while meshing: its position twice (lattice and
/// mesh), about eight output tetrahedra of 16 bytes three times (per row, flattened, the
/// mesh's cells), with room to spare.
pub const INSIDE_VERTEX_BYTES: u64 = 512;

/// Warping threshold on long edges, as a fraction of the edge length.
pub const ALPHA_LONG: f64 = 0.24046;
/// Warping threshold on short edges, as a fraction of the edge length.
pub const ALPHA_SHORT: f64 = 0.35332;
/// The guaranteed range of dihedral angles, degrees.
pub const DIHEDRAL_BOUNDS: (f64, f64) = (10.7, 164.8);

/// Lattice offset from the bounding box, fractions of `h` (fractional parts of multiples
/// of the golden ratio).
const OFFSET: [f64; 3] = [0.618_033_988_7, 0.236_067_977_5, 0.854_101_966_2];

/// What a stuffing run did, besides the mesh.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StuffStats {
    /// Lattice spacing (long edge) `h`, m.
    pub h: f64,
    /// Lattice vertices.
    pub lattice_vertices: usize,
    /// Lattice edges crossing the surface.
    pub cut_edges: usize,
    /// Vertices warped onto a cut point.
    pub warped: usize,
    /// Cut edges whose crossing was not found by the exact intersection (segment grazing
    /// an edge of the surface), placed at the edge's midpoint instead.
    pub cut_fallbacks: usize,
    /// Spacings tried by the search of [`mesh_levels`] for this level (0: none, `h` given).
    pub searched: usize,
}

/// A surface prepared for stuffing at any spacing (the BVH and bounding box built once).
#[derive(Clone, Debug)]
pub struct Stuffer {
    field: SurfaceField,
    /// The surface's enclosed volume, m³ (or the file's unit cubed).
    pub enclosed_volume: f64,
}

impl Stuffer {
    /// Check the surface (non-empty, indices in range, finite coordinates) and build the
    /// search structures.
    pub fn new(surface: &Surface) -> Result<Stuffer> {
        if surface.triangles.is_empty() {
            return Err(Error::param("surface", "the surface has no triangles"));
        }
        let np = surface.points.len();
        for (i, t) in surface.triangles.iter().enumerate() {
            if let Some(&bad) = t.iter().find(|&&v| v as usize >= np) {
                return Err(Error::param(
                    "surface",
                    format!("triangle {i} has vertex {bad}, out of range ({np} points)"),
                ));
            }
        }
        if let Some(i) = surface
            .points
            .iter()
            .position(|p| p.iter().any(|x| !x.is_finite()))
        {
            return Err(Error::param(
                "surface",
                format!("point {i} has a non-finite coordinate"),
            ));
        }
        Ok(Stuffer {
            field: SurfaceField::new(surface),
            enclosed_volume: surface.enclosed_volume(),
        })
    }

    /// Distance from `p` to the surface.
    pub fn distance(&self, p: [f64; 3]) -> f64 {
        self.field.distance(p)
    }

    /// Whether `p` is inside the surface (non-zero winding number).
    pub fn inside(&self, p: [f64; 3]) -> bool {
        self.field.inside(p)
    }

    /// The surface's bounding box.
    pub fn bounding_box(&self) -> ([f64; 3], [f64; 3]) {
        (self.field.lo, self.field.hi)
    }

    /// The lattice of spacing `h` over the surface.
    fn lattice(&self, h: f64) -> Lattice {
        let (lo, hi) = (self.field.lo, self.field.hi);
        let origin = [0, 1, 2].map(|d| lo[d] - (1.5 + OFFSET[d]) * h);
        let n = [0, 1, 2].map(|d| ((hi[d] + 1.5 * h - origin[d]) / h).ceil().max(1.0) as usize);
        Lattice { origin, h, n }
    }

    /// Mesh the inside of the surface with lattice spacing `h` (see the module docs).
    ///
    /// Errors: `h` not positive and finite, a lattice of more than 2·10⁹ vertices, more
    /// memory than is available (see `stuff`), or a surface that encloses no tetrahedron at
    /// this spacing.
    pub fn mesh(&self, h: f64) -> Result<(Mesh, StuffStats)> {
        let raw = self.stuff(h)?.ok_or_else(|| {
            Error::param(
                "h",
                format!(
                    "lattice spacing {h:.3e} leaves no tetrahedron inside the surface; use a \
                     smaller spacing (more nodes)"
                ),
            )
        })?;
        let stats = raw.stats.clone();
        Ok((raw.into_mesh(), stats))
    }

    /// The nodes and tetrahedra of [`Stuffer::mesh`] without the mesh's groups; `None` where
    /// no tetrahedron lies inside the surface at this spacing.
    ///
    /// Errors: `h` not positive and finite, a lattice of more than 2·10⁹ vertices, or more
    /// memory than is available, checked before the signs are formed:
    /// [`LATTICE_VERTEX_BYTES`] a lattice vertex and [`INSIDE_VERTEX_BYTES`] an inside one,
    /// their number estimated from the enclosed volume.
    pub(crate) fn stuff(&self, h: f64) -> Result<Option<Stuffed>> {
        if !(h > 0.0) || !h.is_finite() {
            return Err(Error::param(
                "h",
                format!("lattice spacing {h} must be positive"),
            ));
        }
        let l = self.lattice(h);
        let nv = l.num_black() as f64 + l.num_red() as f64;
        if nv > 2e9 {
            return Err(Error::param(
                "h",
                format!(
                    "lattice spacing {h:.3e} gives {nv:.3e} lattice vertices over the surface's \
                     bounding box; use a larger spacing (or fewer nodes)"
                ),
            ));
        }
        // Before the signs: the inside's lattice vertices estimated from the enclosed volume
        // (a BCC lattice has 2 vertices per h³), with a tenth to spare.
        let inside = 1.1 * 2.0 * self.enclosed_volume.abs() / (h * h * h);
        crate::memory::check_for(
            &format!(
                "meshing at lattice spacing {h:.3e} ({nv:.3e} lattice vertices, about \
                 {inside:.3e} inside)"
            ),
            (nv * LATTICE_VERTEX_BYTES as f64 + inside * INSIDE_VERTEX_BYTES as f64) as u64,
            "ask for fewer nodes (`nodes`) or a larger spacing (`size`)",
        )
        .map_err(|e| Error::param("h", e))?;
        let mut sign = self.signs(&l);
        let cuts = self.cut_points(&l, &sign);
        let mut stats = StuffStats {
            h,
            lattice_vertices: l.num_vertices(),
            cut_edges: cuts.len(),
            cut_fallbacks: cuts.iter().filter(|c| c.2).count(),
            ..Default::default()
        };
        let cut_t: HashMap<u64, f64> = cuts.iter().map(|&(k, t, _)| (k, t)).collect();
        let warped = warp(&l, &mut sign, &cut_t);
        stats.warped = warped.len();

        // Mesh nodes: lattice vertices with sign <= 0 in id order, then the surviving cut
        // points in edge-key order.
        let mut pos: Vec<[f64; 3]> = Vec::new();
        let mut vnode = vec![u32::MAX; l.num_vertices()];
        for v in 0..l.num_vertices() {
            if sign[v] <= 0 {
                vnode[v] = pos.len() as u32;
                pos.push(
                    warped
                        .get(&(v as u32))
                        .copied()
                        .unwrap_or_else(|| l.position(v as u32)),
                );
            }
        }
        let mut cut_node: HashMap<u64, u32> = HashMap::with_capacity(cuts.len());
        for &(k, t, _) in &cuts {
            let (a, b) = ((k >> 32) as u32, k as u32);
            if sign[a as usize] * sign[b as usize] == -1 {
                cut_node.insert(k, pos.len() as u32);
                pos.push(lerp(l.position(a), l.position(b), t));
            }
        }
        let cut_of = |a: u32, b: u32| -> u32 {
            *cut_node
                .get(&edge_key(a, b))
                .expect("a sign change without a cut point")
        };
        let ctx = FillCtx {
            lattice: &l,
            sign: &sign,
            vnode: &vnode,
            cut: &cut_of,
            pos: &pos,
        };
        let [nx, ny, nz] = l.n;
        let field = &self.field;
        let rows: Vec<Vec<[u32; 4]>> = (0..ny * nz)
            .into_par_iter()
            .map(|row| {
                let (j, k) = (row % ny, row / ny);
                let mut lat = Vec::with_capacity(12);
                let mut out = Vec::new();
                for i in 0..nx {
                    lat.clear();
                    l.tets_of_cube([i, j, k], &mut lat);
                    for &t in &lat {
                        let s = t.map(|v| ctx.sign[v as usize]);
                        if s.iter().all(|&x| x > 0) {
                            continue;
                        }
                        if fill(&ctx, t, &mut out) == Filled::AllZero {
                            let p = t.map(|v| pos[vnode[v as usize] as usize]);
                            let c =
                                [0, 1, 2].map(|d| (p[0][d] + p[1][d] + p[2][d] + p[3][d]) / 4.0);
                            if field.inside(c) {
                                out.push(t.map(|v| vnode[v as usize]));
                            }
                        }
                    }
                }
                for t in &mut out {
                    let p = t.map(|v| pos[v as usize]);
                    if tet_volume(p[0], p[1], p[2], p[3]) < 0.0 {
                        t.swap(2, 3);
                    }
                }
                out
            })
            .collect();
        let tets: Vec<[u32; 4]> = rows.into_iter().flatten().collect();
        if tets.is_empty() {
            return Ok(None);
        }
        // Drop unused nodes, keeping the order.
        let mut used = vec![u32::MAX; pos.len()];
        for t in &tets {
            for &v in t {
                used[v as usize] = 0;
            }
        }
        let mut nodes = Vec::new();
        for (i, u) in used.iter_mut().enumerate() {
            if *u == 0 {
                *u = nodes.len() as u32;
                nodes.push(pos[i]);
            }
        }
        let cells: Vec<u32> = tets
            .iter()
            .flat_map(|t| t.map(|v| used[v as usize]))
            .collect();
        Ok(Some(Stuffed {
            nodes,
            cells,
            stats,
        }))
    }

    /// Sign of `f` at every lattice vertex: −1 inside, +1 outside.
    fn signs(&self, l: &Lattice) -> Vec<i8> {
        let [nx, ny, nz] = l.n;
        let h = l.h;
        let o = l.origin;
        // Candidate triangles per row: black rows (j, k) in 0..=ny x 0..=nz, then red rows.
        let nbr = (ny + 1) * (nz + 1);
        let mut rows: Vec<Vec<u32>> = vec![Vec::new(); nbr + ny * nz];
        for (t, (lo, hi)) in self.field.triangle_yz_boxes().enumerate() {
            for (shift, cnt, base) in [(0.0, [ny + 1, nz + 1], 0), (0.5, [ny, nz], nbr)] {
                let r = |x: f64, d: usize, up: bool| -> Option<usize> {
                    let u = (x - o[d + 1]) / h - shift;
                    let v = if up { u.ceil() } else { u.floor() };
                    if up {
                        Some(v.max(0.0) as usize)
                    } else if v < 0.0 {
                        None
                    } else {
                        Some((v as usize).min(cnt[d] - 1))
                    }
                };
                let (Some(j1), Some(k1)) = (r(hi[0], 0, false), r(hi[1], 1, false)) else {
                    continue;
                };
                let (j0, k0) = (
                    r(lo[0], 0, true).unwrap_or(0),
                    r(lo[1], 1, true).unwrap_or(0),
                );
                for k in k0..=k1 {
                    for j in j0..=j1 {
                        rows[base + j + cnt[0] * k].push(t as u32);
                    }
                }
            }
        }
        let mut sign = vec![1i8; l.num_vertices()];
        let (black, red) = sign.split_at_mut(l.num_black());
        let field = &self.field;
        let run = |chunk: &mut [i8], row: usize, red: bool| {
            let (j, k, x0, cnt, sh) = if red {
                let r = row - nbr;
                (r % ny, r / ny, o[0] + 0.5 * h, nx, 0.5)
            } else {
                (row % (ny + 1), row / (ny + 1), o[0], nx + 1, 0.0)
            };
            let y = o[1] + (j as f64 + sh) * h;
            let z = o[2] + (k as f64 + sh) * h;
            let mut w = Vec::with_capacity(cnt);
            field.row_winding([y, z], &rows[row], x0, h, cnt, &mut w);
            for (s, w) in chunk.iter_mut().zip(&w) {
                *s = if *w != 0 { -1 } else { 1 };
            }
        };
        black
            .par_chunks_mut(nx + 1)
            .enumerate()
            .for_each(|(row, c)| run(c, row, false));
        red.par_chunks_mut(nx)
            .enumerate()
            .for_each(|(row, c)| run(c, nbr + row, true));
        sign
    }

    /// Cut points: `(edge key, t from the lower id, fallback used)` for every lattice edge
    /// with a sign change, in increasing key order.
    fn cut_points(&self, l: &Lattice, sign: &[i8]) -> Vec<(u64, f64, bool)> {
        let field = &self.field;
        (0..l.num_vertices() as u32)
            .into_par_iter()
            .flat_map_iter(|v| {
                let mut found = Vec::new();
                let sv = sign[v as usize];
                let mut ts = Vec::new();
                for (u, _) in l.neighbours(v).into_iter().flatten() {
                    if u <= v || sign[u as usize] == sv {
                        continue;
                    }
                    // From the inside end to the outside end.
                    let (a, b) = if sv < 0 { (v, u) } else { (u, v) };
                    let (pa, pb) = (l.position(a), l.position(b));
                    let mut t = None;
                    for tol in [1e-12, 1e-7] {
                        field.segment_crossings(pa, pb, tol, &mut ts);
                        if let Some(m) = ts.iter().copied().min_by(|x, y| x.total_cmp(y)) {
                            t = Some(m);
                            break;
                        }
                    }
                    let fallback = t.is_none();
                    let t_in = t.unwrap_or(0.5);
                    // Convert to the parameter from the lower id (v).
                    let t_low = if a == v { t_in } else { 1.0 - t_in };
                    found.push((edge_key(v, u), t_low, fallback));
                }
                found.sort_by_key(|x| x.0);
                found
            })
            .collect()
    }
}

/// A stuffed mesh before its groups are built.
pub(crate) struct Stuffed {
    pub nodes: Vec<[f64; 3]>,
    pub cells: Vec<u32>,
    pub stats: StuffStats,
}

impl Stuffed {
    /// The mesh with its `"boundary"` group.
    pub fn into_mesh(self) -> Mesh {
        let mut mesh = Mesh::new(ElementKind::Tet4, self.nodes, self.cells);
        let b = mesh.boundary_nodes();
        mesh.groups.insert("boundary".into(), b);
        mesh
    }
}

fn lerp(a: [f64; 3], b: [f64; 3], t: f64) -> [f64; 3] {
    [0, 1, 2].map(|d| a[d] + t * (b[d] - a[d]))
}

/// The warp step (module docs, step 3): moves violated vertices to cut points in
/// increasing id, sets their sign to 0, and returns their new positions.
fn warp(l: &Lattice, sign: &mut [i8], cut_t: &HashMap<u64, f64>) -> HashMap<u32, [f64; 3]> {
    let short = 0.75f64.sqrt();
    // Candidates: an end within alpha of one of its edge's cut points.
    let mut cand: Vec<u32> = Vec::new();
    for (&k, &t) in cut_t {
        let (a, b) = ((k >> 32) as u32, k as u32);
        let alpha = if l.is_long(a, b) {
            ALPHA_LONG
        } else {
            ALPHA_SHORT
        };
        if t < alpha {
            cand.push(a);
        }
        if 1.0 - t < alpha {
            cand.push(b);
        }
    }
    cand.sort_unstable();
    cand.dedup();
    let mut moved = HashMap::new();
    for v in cand {
        let sv = sign[v as usize];
        if sv == 0 {
            continue;
        }
        let mut best: Option<(f64, [f64; 3])> = None;
        for (u, long) in l.neighbours(v).into_iter().flatten() {
            if sign[u as usize] != -sv {
                continue;
            }
            let Some(&t) = cut_t.get(&edge_key(v, u)) else {
                continue;
            };
            let t_v = if v < u { t } else { 1.0 - t };
            let (alpha, len) = if long {
                (ALPHA_LONG, l.h)
            } else {
                (ALPHA_SHORT, short * l.h)
            };
            if t_v < alpha && best.is_none_or(|b| t_v * len < b.0) {
                let (lo, hi) = if v < u { (v, u) } else { (u, v) };
                best = Some((t_v * len, lerp(l.position(lo), l.position(hi), t)));
            }
        }
        if let Some((_, p)) = best {
            sign[v as usize] = 0;
            moved.insert(v, p);
        }
    }
    moved
}

/// Mean edge length of a tetrahedral mesh (over element edges, shared ones counted per
/// element).
pub fn mean_edge(mesh: &Mesh) -> f64 {
    let mut s = 0.0;
    let mut n = 0usize;
    for el in mesh.elements() {
        for i in 0..el.len() {
            for j in i + 1..el.len() {
                s += norm(sub(mesh.nodes[el[i] as usize], mesh.nodes[el[j] as usize]));
                n += 1;
            }
        }
    }
    if n > 0 {
        s / n as f64
    } else {
        0.0
    }
}
