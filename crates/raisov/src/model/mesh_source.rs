//! Which mesh file or generated shape a model's level 0 (and each coarser level it builds)
//! is made from, and the build itself: read or generate, scale to metres, renumber in the
//! banded order (module docs of [`crate::scenario`], "Node order").

use super::err;
use crate::error::Result;
use crate::io::load_mesh;
use crate::mesh::generate::{
    box_tets, box_tets_target, polygon_membrane, rectangle_membrane, BoxPattern,
};
use crate::mesh::Mesh;
use std::path::{Path, PathBuf};

/// What `[mesh]` builds; the coarser `[multigrid]` levels are built the same way.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshSource {
    /// Level 0's file or generated shape.
    pub shape: Shape,
    /// Coordinate factor to metres.
    pub scale: f64,
    /// Renumber mesh files (level files included) in the banded order.
    pub renumber_files: bool,
    /// Renumber generated meshes.
    pub renumber_generated: bool,
}

/// A mesh file or a generated shape.
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    /// A mesh file (the path joined to the scenario's directory).
    File(PathBuf),
    /// A rectangular membrane of about `nodes` nodes.
    Rectangle {
        /// Side along x (m before [`MeshSource::scale`]); centred on the origin, z = 0.
        width: f64,
        /// Side along y (m before [`MeshSource::scale`]).
        height: f64,
        /// `[mesh] nodes`: the target node count.
        nodes: usize,
    },
    /// A polygonal membrane of about `nodes` nodes.
    Polygon {
        /// `[mesh] polygon`: the outline's vertices `[x, y]` in the plane z = 0 (m before
        /// [`MeshSource::scale`]).
        outline: Vec<[f64; 2]>,
        /// `[mesh] nodes`: the target node count.
        nodes: usize,
    },
    /// A tetrahedral box.
    Box {
        /// `[mesh] size`: the sides `[x, y, z]` of `[0, x] × [0, y] × [0, z]` (m before
        /// [`MeshSource::scale`]).
        size: [f64; 3],
        /// `[mesh] nodes` or `divisions`.
        cells: BoxCells,
        /// `[mesh] pattern`: tetrahedra per cube, default 6.
        pattern: BoxPattern,
    },
}

/// How finely a generated box is cut.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BoxCells {
    /// About this many nodes.
    Nodes(usize),
    /// This many cubes per side.
    Divisions([usize; 3]),
}

impl MeshSource {
    /// Build `shape` (this source's or a coarser level's; `key` names it in messages), scale
    /// and renumber it. Returns the mesh, notes for the user, and the file ids of its nodes
    /// where it was renumbered (see [`super::Model::file_ids`]).
    #[allow(clippy::type_complexity)]
    pub fn build(
        &self,
        shape: &Shape,
        path: &Path,
        key: &str,
    ) -> Result<(Mesh, Vec<String>, Option<Vec<u32>>, Option<Vec<u64>>)> {
        let mut notes = Vec::new();
        let mut labels = None;
        let generated = |name: &str, made: Result<Mesh>| {
            made.map_err(|e| err(path, format!("`mesh.generate` = \"{name}\": {e}")))
        };
        let mut mesh = match shape {
            Shape::File(p) => {
                let loaded = load_mesh(p)
                    .map_err(|e| err(path, format!("`{key}` = \"{}\": {e}", p.display())))?;
                if !loaded.reoriented.is_empty() {
                    notes.push(format!(
                        "{}: reoriented {} inverted elements (first: {})",
                        p.display(),
                        loaded.reoriented.len(),
                        loaded.reoriented[0]
                    ));
                }
                if loaded.unused_nodes_dropped > 0 {
                    notes.push(format!(
                        "{}: dropped {} nodes used by no element",
                        p.display(),
                        loaded.unused_nodes_dropped
                    ));
                }
                labels = Some(loaded.node_ids);
                loaded.mesh
            }
            Shape::Rectangle {
                width,
                height,
                nodes,
            } => generated("rectangle", rectangle_membrane(*width, *height, *nodes))?,
            Shape::Polygon { outline, nodes } => {
                generated("polygon", polygon_membrane(outline, *nodes))?
            }
            Shape::Box {
                size,
                cells: BoxCells::Divisions(d),
                pattern,
            } => generated("box", box_tets(*size, *d, *pattern))?,
            Shape::Box {
                size,
                cells: BoxCells::Nodes(n),
                pattern,
            } => generated("box", box_tets_target(*size, *n, *pattern))?,
        };
        mesh.scale(self.scale);
        let renumber = match shape {
            Shape::File(_) => self.renumber_files,
            _ => self.renumber_generated,
        };
        let file_ids = renumber.then(|| {
            let order = mesh.spatial_order();
            mesh.renumber(&order);
            order
        });
        Ok((mesh, notes, file_ids, labels))
    }
}
