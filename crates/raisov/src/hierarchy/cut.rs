//! Cutting every level of a hierarchy with one blade, and the links carried through the cut.
//!
//! Each level is cut by the same blade on its own mesh ([`crate::mesh::cut`]); the cuts keep
//! the same index on every level. The links are not searched again (the copies of an element
//! occupy the same place, so a geometric search cannot tell them apart): a point keeps the
//! host element and the barycentric weights it had in the uncut meshes (eq. 6 holds
//! unchanged, the copies having the uncut element's corners), and takes, among the copies of
//! that element, the one on its own side of every cut that split it. A point's side of cut
//! `k` is the side of its material ([`CutMesh::side_of`]: the side of the elements around it
//! that cut `k` split, else the side of the cut's plane it lies on). So no coarse element
//! ties the two lips of a wound together: a fine node of one lip interpolates only coarse
//! copies holding that lip's material, and a coarse node of one lip is located in a fine copy
//! of its own lip.

use super::{Correspondence, Transfer};
use crate::mesh::cut::{Blade, CutMesh, Side, TopologyChange};
use crate::mesh::Mesh;
use crate::Result;

/// The levels of a hierarchy (finest first) as cut so far, and their uncut links.
#[derive(Clone, Debug)]
pub struct CutHierarchy {
    levels: Vec<CutMesh>,
    base_links: Vec<Correspondence>,
}

/// What one cut changed on every level, and the links between the cut levels.
#[derive(Clone, Debug)]
pub struct HierarchyCut {
    /// Per level, finest first.
    pub levels: Vec<TopologyChange>,
    /// `links[i]` connects the cut levels `i` and `i + 1`.
    pub links: Vec<Correspondence>,
}

impl HierarchyCut {
    /// Whether the blade split no element on any level.
    pub fn is_identity(&self) -> bool {
        self.levels.iter().all(|l| l.is_identity())
    }
}

impl CutHierarchy {
    /// Uncut levels (tetrahedra, finest first) and their links (`links[i]`: levels `i`,
    /// `i + 1`, as [`Correspondence::build`] made them).
    pub fn new(levels: Vec<Mesh>, links: Vec<Correspondence>) -> Result<CutHierarchy> {
        if links.len() + 1 != levels.len() {
            return Err(crate::Error::param(
                "cut",
                format!(
                    "{} levels need {} links, not {}",
                    levels.len(),
                    levels.len().saturating_sub(1),
                    links.len()
                ),
            ));
        }
        Ok(CutHierarchy {
            levels: levels
                .into_iter()
                .map(CutMesh::new)
                .collect::<Result<_>>()?,
            base_links: links,
        })
    }

    /// The levels as cut so far.
    pub fn levels(&self) -> &[CutMesh] {
        &self.levels
    }

    /// Cut every level with `blade`; the links between the cut levels.
    pub fn cut(&mut self, blade: &Blade) -> Result<HierarchyCut> {
        use rayon::prelude::*;
        let levels = self
            .levels
            .par_iter_mut()
            .map(|l| l.cut(blade))
            .collect::<Vec<_>>()
            .into_iter()
            .collect::<Result<Vec<_>>>()?;
        Ok(HierarchyCut {
            levels,
            links: self.links(),
        })
    }

    /// The links between the levels as cut now (module docs).
    pub fn links(&self) -> Vec<Correspondence> {
        let sides: Vec<Vec<Vec<Side>>> = self.levels.iter().map(|l| l.node_sides()).collect();
        self.base_links
            .iter()
            .enumerate()
            .map(|(i, base)| {
                let (fine, coarse) = (&self.levels[i], &self.levels[i + 1]);
                let down = rehost(&base.down, fine.base_nodes(), coarse, |a, k| {
                    fine.side_of(&sides[i], a, k)
                });
                let up = rehost(&base.up, coarse.base_nodes(), fine, |a, k| {
                    coarse.side_of(&sides[i + 1], a, k)
                });
                let mut report = base.report.clone();
                report.fine_nodes = fine.mesh().num_nodes();
                report.coarse_nodes = coarse.mesh().num_nodes();
                report.fine_outside = down.outside.len();
                report.coarse_outside = up.outside.len();
                Correspondence { down, up, report }
            })
            .collect()
    }
}

/// `base` (points of an uncut mesh located in the uncut `target`) carried to the cut
/// meshes: point `a` is a copy of base point `origin[a]`; its side of cut `k` is
/// `side(a, k)`.
pub fn rehost(
    base: &Transfer,
    origin: &[u32],
    target: &CutMesh,
    side: impl Fn(usize, u32) -> i8,
) -> Transfer {
    let cells = &target.mesh().cells;
    let mut host = Vec::with_capacity(origin.len());
    let mut nodes = Vec::with_capacity(origin.len());
    let mut weights = Vec::with_capacity(origin.len());
    let mut outside = Vec::new();
    for (a, &o) in origin.iter().enumerate() {
        let o = o as usize;
        let c = target.copy_for(base.host[o], |k| side(a, k));
        host.push(c as u32);
        nodes.push(std::array::from_fn(|j| cells[4 * c + j]));
        weights.push(base.weights[o]);
        if base.outside.binary_search(&(o as u32)).is_ok() {
            outside.push(a as u32);
        }
    }
    Transfer {
        host,
        nodes,
        weights,
        npe: base.npe,
        target_nodes: target.mesh().num_nodes(),
        outside,
        max_extrapolation: base.max_extrapolation,
        max_plane_distance: base.max_plane_distance,
    }
}
