//! Node selections of a model: the selectors of its fixed regions and loads, selected again
//! on every level's own mesh ([`select`]), and what a fixed region holds ([`Fixing`]).

use super::err;
use crate::error::Result;
use crate::geometry::{dot, norm, sub};
use crate::mesh::Mesh;
use std::path::Path;
use std::sync::Arc;

/// A node selection of `[[fix]]` or `[[load]] at`.
#[derive(Clone, Debug, PartialEq)]
pub enum Selector {
    /// Every boundary node.
    Boundary,
    /// The nodes inside an axis-aligned box (m).
    Box {
        /// The lower corner (m).
        min: [f64; 3],
        /// The upper corner (m).
        max: [f64; 3],
    },
    /// The nodes with `(x − point)·normal ≤ 0`; `normal` is non-zero.
    Plane {
        /// A point of the plane (m).
        point: [f64; 3],
        /// The plane's normal, pointing away from the selected side.
        normal: [f64; 3],
    },
    /// A physical group of the mesh file.
    Group(String),
    /// Nodes of [`super::Model::mesh`] by index (the file's ids mapped to the mesh's order).
    Nodes(Vec<u32>),
    /// The node nearest this point.
    Point([f64; 3]),
    /// The nodes whose reference position (m) the predicate accepts (a region given in code:
    /// [`crate::sim::SimulationBuilder::fix`]).
    Region(Region),
}

/// A predicate on reference positions (m), selecting nodes on every level.
#[derive(Clone)]
pub struct Region(pub Arc<dyn Fn([f64; 3]) -> bool + Send + Sync>);

impl std::fmt::Debug for Region {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Region(..)")
    }
}

impl PartialEq for Region {
    /// The same predicate (one `Arc`).
    fn eq(&self, other: &Region) -> bool {
        Arc::ptr_eq(&self.0, &other.0)
    }
}

/// Which displacement components a `[[fix]]` holds at zero.
#[derive(Clone, Debug, PartialEq)]
pub enum Fixing {
    /// All three: the node is fixed.
    All,
    /// `u·n = 0` along each unit direction (`components = ["x", "z"]` gives e_x, e_z; `normal`
    /// one direction): rollers, symmetry planes, sliding on a plane.
    Directions(Vec<[f64; 3]>),
}

/// The fixed nodes and the sliding directions `fix` selects on `mesh` (`level` names it in
/// messages: empty for level 0).
#[allow(clippy::type_complexity)]
pub(crate) fn select_fixed(
    mesh: &Mesh,
    fix: &[(Selector, Fixing)],
    path: &Path,
    level: &str,
) -> Result<(Vec<u32>, Vec<(u32, [f64; 3])>)> {
    let (mut fixed, mut sliding) = (Vec::new(), Vec::new());
    for (i, (s, how)) in fix.iter().enumerate() {
        let nodes = select(mesh, s, path, &format!("{level}fix[{i}]"))?;
        match how {
            Fixing::All => fixed.extend(nodes),
            Fixing::Directions(dirs) => {
                for a in nodes {
                    sliding.extend(dirs.iter().map(|&n| (a, n)));
                }
            }
        }
    }
    Ok((fixed, sliding))
}

/// Every id of a `nodes = [..]` selector names a node of a mesh of `n` nodes.
pub(crate) fn check_node_ids(ns: &[u32], n: usize, path: &Path, key: &str) -> Result<()> {
    match ns.iter().find(|&&a| a as usize >= n) {
        Some(&bad) => Err(err(
            path,
            format!(
                "{key}.nodes: node {bad} does not exist (valid: 0..{})",
                n.saturating_sub(1)
            ),
        )),
        None => Ok(()),
    }
}

/// The nodes `s` selects on `mesh`; errors if none or a missing group.
pub fn select(mesh: &Mesh, s: &Selector, path: &Path, key: &str) -> Result<Vec<u32>> {
    let (lo, hi) = mesh.bounding_box();
    let tol = 1e-9 * norm(sub(hi, lo)).max(f64::MIN_POSITIVE);
    let all = 0..mesh.num_nodes() as u32;
    let sel: Vec<u32> = match s {
        Selector::Boundary => mesh.boundary_nodes(),
        Selector::Box { min, max } => all
            .filter(|&a| {
                let p = mesh.nodes[a as usize];
                (0..3).all(|k| p[k] >= min[k] - tol && p[k] <= max[k] + tol)
            })
            .collect(),
        Selector::Plane { point, normal } => {
            let nn = norm(*normal);
            all.filter(|&a| dot(sub(mesh.nodes[a as usize], *point), *normal) / nn <= tol)
                .collect()
        }
        Selector::Group(g) => mesh.groups.get(g).cloned().ok_or_else(|| {
            let names: Vec<&str> = mesh.groups.keys().map(|s| s.as_str()).collect();
            err(
                path,
                format!(
                    "{key}: no group \"{g}\" in the mesh (groups: {})",
                    if names.is_empty() {
                        "none".to_string()
                    } else {
                        names.join(", ")
                    }
                ),
            )
        })?,
        Selector::Nodes(ns) => {
            check_node_ids(ns, mesh.num_nodes(), path, key)?;
            ns.clone()
        }
        Selector::Region(r) => all.filter(|&a| (r.0)(mesh.nodes[a as usize])).collect(),
        Selector::Point(p) => vec![mesh
            .nearest_node(*p)
            .ok_or_else(|| err(path, "the mesh has no nodes"))?
            as u32],
    };
    if sel.is_empty() {
        return Err(err(path, format!("{key}: the selection contains no node")));
    }
    Ok(sel)
}
