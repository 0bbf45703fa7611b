//! Multigrid levels: independent stuffed meshes whose node counts form a geometric series.
//!
//! Level `i` targets `n_i = n_0 rᶦ` nodes (`r` the ratio, e.g. ½). The node count of a
//! stuffed mesh scales like `h⁻³` with the lattice spacing, so each level's spacing is found
//! by a secant iteration on `ln n(ln h)`,
//!
//! ```text
//! h_{k+1} = h_k (n(h_k) / n_i)^{1/b_k},   b_k = −Δ ln n / Δ ln h   (b_0 = 3),
//! ```
//!
//! until `|n / n_i − 1| ≤` [`COUNT_TOLERANCE`] (the closest of at most [`MAX_SEARCH`] meshes
//! otherwise). With [`LevelTarget::Size`] level 0 uses that spacing and `n_0` is its count.

use super::distance::SurfaceField;
use super::{mean_edge, StuffStats, Stuffed, Stuffer, DIHEDRAL_BOUNDS};
use crate::geometry::{cross, dot, norm, sub};
use crate::mesh::{tet_radius_ratio, Mesh, Surface};
use crate::{Error, Result};
use rayon::prelude::*;
use std::fmt;

/// Relative node-count tolerance of the spacing search.
pub const COUNT_TOLERANCE: f64 = 0.01;
/// Most meshes tried per level by the spacing search.
pub const MAX_SEARCH: usize = 14;

/// What fixes the finest level.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LevelTarget {
    /// About this many nodes on level 0.
    Nodes(usize),
    /// Lattice spacing (long edge) of level 0, in the surface's units.
    Size(f64),
}

/// Geometry and quality of one level.
#[derive(Clone, Debug, PartialEq)]
pub struct LevelReport {
    /// Level index, 0 the finest.
    pub level: usize,
    /// Lattice spacing `h`.
    pub h: f64,
    /// Number of nodes.
    pub nodes: usize,
    /// Number of tetrahedra.
    pub tets: usize,
    /// Node count over the finer level's (level 0: 1).
    pub ratio: f64,
    /// The node count the spacing search aimed at.
    pub target_nodes: usize,
    /// Smallest and largest dihedral angle, degrees.
    pub min_dihedral: f64,
    /// Largest dihedral angle, degrees.
    pub max_dihedral: f64,
    /// Smallest radius ratio `3 r_in / R_circ`.
    pub min_radius_ratio: f64,
    /// Tetrahedra with volume ≤ 0 (none expected).
    pub non_positive: usize,
    /// Total volume (m³).
    pub volume: f64,
    /// `volume / enclosed volume − 1`.
    pub volume_error: f64,
    /// Largest distance from a boundary node to the surface.
    pub max_boundary_distance: f64,
    /// Largest distance from a surface vertex to the mesh boundary (how far the boundary
    /// strays from the surface where the lattice cuts corners and thin parts).
    pub max_surface_distance: f64,
    /// Mean element edge length.
    pub mean_edge: f64,
    /// The stuffing's own counters.
    pub stats: StuffStats,
}

/// The levels' reports and the surface's volume. The links' covering condition is the
/// hierarchy's concern: [`crate::hierarchy::link_reports`].
#[derive(Clone, Debug, PartialEq)]
pub struct LevelsReport {
    /// Volume enclosed by the surface (m³).
    pub enclosed_volume: f64,
    /// One report per level, finest first.
    pub levels: Vec<LevelReport>,
}

/// Smallest and largest dihedral angle of the tetrahedron, degrees.
pub fn tet_dihedral_range(a: [f64; 3], b: [f64; 3], c: [f64; 3], d: [f64; 3]) -> (f64, f64) {
    let p = [a, b, c, d];
    // Face normals, all outward (or all inward) whatever the orientation; `faces[k]` is the
    // face opposite vertex `opp[k]`.
    let faces = [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]];
    let n = faces.map(|f| {
        let v = cross(sub(p[f[1]], p[f[0]]), sub(p[f[2]], p[f[0]]));
        let l = norm(v);
        if l > 0.0 {
            v.map(|x| x / l)
        } else {
            [0.0; 3]
        }
    });
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for i in 0..4 {
        for j in i + 1..4 {
            let ang = (-dot(n[i], n[j])).clamp(-1.0, 1.0).acos().to_degrees();
            lo = lo.min(ang);
            hi = hi.max(ang);
        }
    }
    (lo, hi)
}

/// Independent meshes of the inside of `surface`, finest first, node counts in the
/// geometric series `n_0 ratioᶦ` (see the module docs). Convenience wrapper of
/// [`mesh_levels_report`] without the report.
pub fn mesh_levels(
    surface: &Surface,
    levels: usize,
    ratio: f64,
    target: LevelTarget,
) -> Result<Vec<Mesh>> {
    Ok(mesh_levels_report(surface, levels, ratio, target, &mut |_| {})?.0)
}

/// [`mesh_levels`] with the report of every level and link; `progress` is called with a
/// short message before each level and before the links are checked.
///
/// Errors: `levels` 0, `ratio` outside `(0, 1]`, a target of fewer than 4 nodes or a
/// non-positive size, a surface the stuffer rejects, or a level the surface cannot hold.
pub fn mesh_levels_report(
    surface: &Surface,
    levels: usize,
    ratio: f64,
    target: LevelTarget,
    progress: &mut dyn FnMut(&str),
) -> Result<(Vec<Mesh>, LevelsReport)> {
    if levels == 0 {
        return Err(Error::param("levels", "at least one level is required"));
    }
    if !(ratio > 0.0 && ratio <= 1.0) {
        return Err(Error::param(
            "ratio",
            format!("node ratio {ratio} per level must be in (0, 1]"),
        ));
    }
    match target {
        LevelTarget::Nodes(n) if n < 4 => {
            return Err(Error::param(
                "nodes",
                format!("{n} nodes: at least 4 are needed"),
            ))
        }
        LevelTarget::Size(h) if !(h > 0.0 && h.is_finite()) => {
            return Err(Error::param("size", format!("size {h} must be positive")))
        }
        _ => {}
    }
    let stuffer = Stuffer::new(surface)?;
    let vol = stuffer.enclosed_volume.abs();
    let mut meshes: Vec<Mesh> = Vec::new();
    let mut reports: Vec<LevelReport> = Vec::new();
    let mut h_prev = 0.0;
    for i in 0..levels {
        progress(&format!("level {i}"));
        let (mesh, stats, target_nodes) = match (i, target) {
            (0, LevelTarget::Size(h)) => {
                let (m, s) = stuffer.mesh(h).map_err(|e| as_key(e, "size", 0))?;
                let n = m.num_nodes();
                (m, s, n)
            }
            _ => {
                let n_target = match target {
                    LevelTarget::Nodes(n) => n as f64 * ratio.powi(i as i32),
                    LevelTarget::Size(_) => reports[0].nodes as f64 * ratio.powi(i as i32),
                };
                let guess = if i == 0 {
                    // A BCC lattice has 2 vertices per h³.
                    (2.0 * vol.max(f64::MIN_POSITIVE) / n_target).cbrt()
                } else {
                    h_prev * (1.0 / ratio).cbrt()
                };
                let (m, s) = search_spacing(&stuffer, n_target, guess, i)?;
                (m, s, n_target.round() as usize)
            }
        };
        h_prev = stats.h;
        let rep = level_report(
            &stuffer,
            surface,
            i,
            &mesh,
            stats,
            target_nodes,
            reports.last(),
        );
        meshes.push(mesh);
        reports.push(rep);
    }
    Ok((
        meshes,
        LevelsReport {
            enclosed_volume: stuffer.enclosed_volume,
            levels: reports,
        },
    ))
}

/// The stuffer's refusal of a spacing (its parameter `h`) under the caller's key, `nodes` or
/// `size`, and the level: the spacing is the levels' choice, not the caller's.
fn as_key(e: Error, key: &str, level: usize) -> Error {
    match e {
        Error::Param { msg, .. } => Error::param(key, format!("level {level}: {msg}")),
        e => e,
    }
}

/// Stuff at spacings from `guess` until the node count is within [`COUNT_TOLERANCE`] of
/// `target` (module docs).
fn search_spacing(
    stuffer: &Stuffer,
    target: f64,
    guess: f64,
    level: usize,
) -> Result<(Mesh, StuffStats)> {
    let mut h = guess;
    let mut best: Option<(f64, Stuffed)> = None;
    let mut prev: Option<(f64, f64)> = None;
    let mut tried = 0;
    for _ in 0..MAX_SEARCH {
        tried += 1;
        let st = match stuffer.stuff(h).map_err(|e| as_key(e, "nodes", level))? {
            Some(x) => x,
            None if best.is_none() => {
                // Nothing inside at this spacing: refine.
                h *= 0.5;
                continue;
            }
            None => {
                return Err(Error::param(
                    "nodes",
                    format!(
                        "level {level}: lattice spacing {h:.3e} leaves no tetrahedron inside \
                         the surface; ask for more nodes"
                    ),
                ))
            }
        };
        let n = st.nodes.len() as f64;
        let err = (n / target - 1.0).abs();
        let done = err <= COUNT_TOLERANCE;
        let (lh, ln) = (h.ln(), n.ln());
        let mut b = 3.0;
        if let Some((ph, pn)) = prev {
            let est = -(ln - pn) / (lh - ph);
            if est.is_finite() {
                b = est.clamp(1.5, 4.5);
            }
        }
        prev = Some((lh, ln));
        if best.as_ref().is_none_or(|x| err < x.0) {
            best = Some((err, st));
        }
        if done {
            break;
        }
        h *= (n / target).powf(1.0 / b);
    }
    match best {
        Some((_, mut st)) => {
            st.stats.searched = tried;
            let s = st.stats.clone();
            Ok((st.into_mesh(), s))
        }
        None => Err(Error::param(
            "nodes",
            format!(
                "level {level}: no spacing down to {h:.3e} leaves a tetrahedron inside the surface"
            ),
        )),
    }
}

fn level_report(
    stuffer: &Stuffer,
    surface: &Surface,
    level: usize,
    m: &Mesh,
    stats: StuffStats,
    target_nodes: usize,
    finer: Option<&LevelReport>,
) -> LevelReport {
    let ne = m.num_elements();
    let per: Vec<(f64, f64, f64, f64)> = (0..ne)
        .into_par_iter()
        .map(|e| {
            let p = m.element_points(e);
            let (lo, hi) = tet_dihedral_range(p[0], p[1], p[2], p[3]);
            let rr = tet_radius_ratio(p[0], p[1], p[2], p[3]);
            (lo, hi, rr, m.element_measure(e))
        })
        .collect();
    let min_dihedral = per.iter().map(|x| x.0).fold(f64::INFINITY, f64::min);
    let max_dihedral = per.iter().map(|x| x.1).fold(f64::NEG_INFINITY, f64::max);
    let min_radius_ratio = per.iter().map(|x| x.2).fold(f64::INFINITY, f64::min);
    let non_positive = per.iter().filter(|x| !(x.3 > 0.0)).count();
    let volume: f64 = per.iter().map(|x| x.3).sum();
    let boundary = m.groups.get("boundary").cloned().unwrap_or_default();
    let max_boundary_distance = boundary
        .par_iter()
        .map(|&v| stuffer.distance(m.nodes[v as usize]))
        .reduce(|| 0.0, f64::max);
    let skin = SurfaceField::new(&Surface {
        points: m.nodes.clone(),
        triangles: m.boundary_facets(),
    });
    let max_surface_distance = surface
        .points
        .par_iter()
        .map(|&p| skin.distance(p))
        .reduce(|| 0.0, f64::max);
    let enclosed = stuffer.enclosed_volume.abs();
    LevelReport {
        level,
        h: stats.h,
        nodes: m.num_nodes(),
        tets: ne,
        ratio: finer.map_or(1.0, |f| m.num_nodes() as f64 / f.nodes as f64),
        target_nodes,
        min_dihedral,
        max_dihedral,
        min_radius_ratio,
        non_positive,
        volume,
        volume_error: volume / enclosed - 1.0,
        max_boundary_distance,
        max_surface_distance,
        mean_edge: mean_edge(m),
        stats,
    }
}

impl LevelReport {
    /// Whether the dihedral angles lie in the guaranteed range and every tet is positive.
    pub fn quality_ok(&self) -> bool {
        self.non_positive == 0
            && self.min_dihedral >= DIHEDRAL_BOUNDS.0
            && self.max_dihedral <= DIHEDRAL_BOUNDS.1
    }
}

impl fmt::Display for LevelsReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "level  nodes    tets     ratio  h          mean edge  dihedral min..max  radius ratio  volume error  boundary->surface  surface->boundary"
        )?;
        for r in &self.levels {
            writeln!(
                f,
                "L{:<5} {:<8} {:<8} {:<6} {:<10.4e} {:<10.4e} {:>6.2}..{:<6.2}°     {:<13.4} {:>+8.3} %    {:.1e} ({:.0e} edge)   {:.2e} ({:.2} edge)",
                r.level,
                r.nodes,
                r.tets,
                if r.level == 0 { "-".to_string() } else { format!("{:.3}", r.ratio) },
                r.h,
                r.mean_edge,
                r.min_dihedral,
                r.max_dihedral,
                r.min_radius_ratio,
                100.0 * r.volume_error,
                r.max_boundary_distance,
                r.max_boundary_distance / r.mean_edge,
                r.max_surface_distance,
                r.max_surface_distance / r.mean_edge,
            )?;
        }
        writeln!(
            f,
            "enclosed volume of the surface: {:.6e}",
            self.enclosed_volume
        )?;
        Ok(())
    }
}
