//! Mesh levels and the correspondence between them (Wu & Tendick 2004, section 2.1).
//!
//! Levels `0` (finest) … `m−1` (coarsest) are independent meshes of one domain: no node need
//! be shared. Every node `p_θ` of a level gets a *host element* on each neighbouring level and
//! barycentric weights `ω` that reproduce its reference position (eq. 6):
//!
//! ```text
//! p_θ = Σ_{j=1..npe} ω_j p_{γ,j},     ω_j = A_j / A (triangles),  V_j / V (tetrahedra),
//! ```
//!
//! `A_j`, `V_j` the sub-triangle or sub-tetrahedron with `p_θ` in place of corner `j`. The
//! sub-measures are divided by their sum (equal to `A` or `V` in exact arithmetic), so the
//! weights sum to 1 up to round-off and reproduce `p_θ` up to round-off, inside or not.
//!
//! A point lying in no element of the other mesh is hosted by the *boundary* element (one with
//! a facet on the mesh boundary) that maximises (eq. 7)
//!
//! ```text
//! m_k / γ_θ,k,    γ_θ,k = ‖p_θ − (1/npe) Σ_l p_{k,l}‖,
//! ```
//!
//! `m_k` the element's measure (its mass, for one density), `γ` the distance to its centroid;
//! the weights are then the barycentric coordinates in that element and may be negative or
//! exceed 1 (extrapolation).
//!
//! Conventions:
//! - Inside means every weight `≥ −`[`INSIDE_TOL`] (signed sub-volumes for tetrahedra).
//!   Among several hosts (a point on a shared facet) the one with the largest smallest weight
//!   wins, ties to the lowest element id. Degenerate elements host nothing.
//! - Membranes (triangles in 3-D, possibly curved): a point is tested against a triangle in
//!   the triangle's own plane, i.e. its orthogonal projection; a triangle qualifies if the
//!   projection is inside and the point is within the triangle's centroid-to-vertex radius of
//!   the plane. Preference: smallest plane distance (below `1e-9` of the radius counts as 0),
//!   then largest smallest weight, then lowest id. The weights reproduce the projection; the
//!   off-plane part is not represented ([`Transfer::max_plane_distance`] reports it). Eq. 7
//!   weights of a membrane point are likewise those of its projection.
//! - Membrane gaps: on a curved membrane a point of the other level can lie off every
//!   triangle's in-plane extent although it is on the surface (above a convex ridge, its
//!   projections fall just beyond the shared edge of both faces). The projection then misses
//!   by at most about `d sin φ` (`d` the plane distance, `φ` the bend angle), so when no
//!   triangle contains the projection, a triangle whose smallest weight is at least
//!   `−INSIDE_TOL − d / r` (`r` its centroid-to-vertex radius) hosts the point instead (the
//!   largest smallest weight wins, ties to the lowest id). Such points are not counted as
//!   outside; their weights are slightly negative (of order `d / r`). Tetrahedra have `d = 0`,
//!   so this never applies to them.
//! - Search: static k-d trees, one over element bounding boxes (a point inside an element is
//!   in its box; triangle boxes are widened by three centroid-to-vertex radii for the plane
//!   distance), one over boundary-element centroids with, per subtree, the largest measure
//!   (bounding `m_k / γ` for eq. 7, searched by branch and bound). Both queries are exact,
//!   `O(log n)` per point for ordinary meshes, and run in parallel over points; each point's
//!   result is independent of the others and of the visiting order, so the output is the same
//!   bits on any number of threads.
//! - Covering (section 2.1): "the hosting elements for the vertices in S(i) cover S(i−1)":
//!   every fine node is a corner of the fine host of at least one coarse node.
//!   [`CorrespondenceReport`] counts the fine nodes for which this fails.
//! - [`Correspondence::down`] (fine nodes in the coarse mesh) is the interpolation `P` from
//!   coarse to fine; [`Correspondence::up`] (coarse nodes in the fine mesh) is the paper's
//!   restriction `R`. [`Transfer::transpose_add`] applies `Pᵀ` (to restrict forces).

mod correspondence;
pub mod cut;
mod tree;

/// The covering report of each link of `levels` (finest first): `[i]` is level `i` (fine)
/// against level `i + 1` (coarse), the correspondence the multigrid set-up builds, without
/// building the whole hierarchy. `raisov mesh levels` prints them under its level table.
pub fn link_reports(levels: &[Mesh]) -> Result<Vec<CorrespondenceReport>> {
    levels
        .windows(2)
        .map(|w| Correspondence::build(&w[0], &w[1]).map(|c| c.report))
        .collect()
}

#[cfg(test)]
mod tests;

pub use correspondence::{Correspondence, CorrespondenceReport, Transfer, INSIDE_TOL};

use crate::mesh::Mesh;
use crate::{Error, Result};

/// Levels of independent meshes, finest first, and the correspondence between neighbours.
#[derive(Clone, Debug)]
pub struct Hierarchy {
    /// Meshes, level 0 the finest.
    pub levels: Vec<Mesh>,
    /// `links[i]` connects level `i` (fine) and level `i + 1` (coarse).
    pub links: Vec<Correspondence>,
}

impl Hierarchy {
    /// Check the levels and build every link.
    ///
    /// Errors: no level, levels of different element kinds, a coarser level with more nodes
    /// than the finer one before it (equal counts are accepted), or a mesh that
    /// [`Transfer::build`] rejects.
    pub fn new(levels: Vec<Mesh>) -> Result<Hierarchy> {
        let Some(first) = levels.first() else {
            return Err(Error::param("levels", "at least one level is required"));
        };
        for (i, m) in levels.iter().enumerate() {
            if m.kind != first.kind {
                return Err(Error::param(
                    "levels",
                    format!(
                        "level {i} is a {} mesh but level 0 is a {} mesh",
                        m.kind.name(),
                        first.kind.name()
                    ),
                ));
            }
            if m.num_elements() == 0 {
                return Err(Error::param("levels", format!("level {i} has no elements")));
            }
        }
        for (i, w) in levels.windows(2).enumerate() {
            if w[1].num_nodes() > w[0].num_nodes() {
                return Err(Error::param(
                    "levels",
                    format!(
                        "level {} ({} nodes) is coarser than level {i} ({} nodes) but has more \
                         nodes; order levels finest first",
                        i + 1,
                        w[1].num_nodes(),
                        w[0].num_nodes()
                    ),
                ));
            }
        }
        let links = levels
            .windows(2)
            .enumerate()
            .map(|(i, w)| {
                Correspondence::build(&w[0], &w[1])
                    .map_err(|e| Error::param("levels", format!("link {i}-{}: {e}", i + 1)))
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Hierarchy { levels, links })
    }

    /// Number of levels.
    pub fn len(&self) -> usize {
        self.levels.len()
    }

    /// Always false: a hierarchy has at least one level.
    pub fn is_empty(&self) -> bool {
        self.levels.is_empty()
    }

    /// One line per level (nodes, elements, ratio to the finer level) and per link.
    pub fn report(&self) -> String {
        let mut s = format!(
            "{} level(s) of {} meshes\n",
            self.levels.len(),
            self.levels[0].kind.name()
        );
        for (i, m) in self.levels.iter().enumerate() {
            s += &format!(
                "  level {i}: {} nodes, {} elements",
                m.num_nodes(),
                m.num_elements()
            );
            if i > 0 {
                s += &format!(
                    " (node ratio {:.3})",
                    m.num_nodes() as f64 / self.levels[i - 1].num_nodes() as f64
                );
            }
            s += "\n";
        }
        for (i, l) in self.links.iter().enumerate() {
            s += &format!("  link {i}-{}: {}\n", i + 1, l.report);
        }
        s
    }
}
