//! `[mesh]` resolved into the model's [`MeshSource`]: which mesh file or generated shape a
//! scenario (and each coarser `[multigrid]` level) is built from.

use super::spec::{self, defaults, Generator, Named};
use super::{err, positive};
use crate::error::Result;
use crate::model::{BoxCells, MeshSource, Shape};
use std::path::Path;

/// Check `[mesh]` and say what it builds.
pub(super) fn resolve_mesh_source(
    m: &spec::MeshSpec,
    path: &Path,
    base: &Path,
) -> Result<MeshSource> {
    let forbid = |what: &str, keys: &[(&str, bool)]| -> Result<()> {
        match keys.iter().find(|(_, set)| *set) {
            Some((k, _)) => Err(err(path, format!("[mesh]: `{k}` does not apply to {what}"))),
            None => Ok(()),
        }
    };
    let shape = match (&m.file, m.generate) {
        (Some(_), Some(_)) => {
            return Err(err(
                path,
                "[mesh]: give either `file` or `generate`, not both",
            ))
        }
        (None, None) => {
            return Err(err(
                path,
                format!(
                    "[mesh]: missing `file` (a .msh, .node/.ele, .vtk or .vtu mesh), `surface` (a closed .obj, .stl or .ply surface to mesh) or `generate` ({})",
                    Generator::valid()
                ),
            ))
        }
        (Some(f), None) => {
            forbid(
                "`file`",
                &[
                    ("size", m.size.is_some()),
                    ("polygon", m.polygon.is_some()),
                    ("nodes", m.nodes.is_some()),
                    ("divisions", m.divisions.is_some()),
                    ("pattern", m.pattern.is_some()),
                ],
            )?;
            Shape::File(base.join(f))
        }
        (None, Some(g)) => {
            let what = format!("generate = \"{}\"", g.name());
            let need_nodes = || {
                m.nodes.ok_or_else(|| {
                    err(
                        path,
                        format!("[mesh]: {what} needs `nodes` (target node count)"),
                    )
                })
            };
            let size = |len: usize| -> Result<Vec<f64>> {
                let s = match m.size.clone() {
                    Some(spec::MeshSize::Lengths(s)) => s,
                    Some(spec::MeshSize::Length(x)) => vec![x],
                    None => {
                        return Err(err(
                            path,
                            format!("[mesh]: {what} needs `size` ({len} lengths in m)"),
                        ))
                    }
                };
                if s.len() != len || s.iter().any(|&x| !(x > 0.0)) {
                    return Err(err(
                        path,
                        format!(
                            "[mesh]: `size` = {s:?}: need {len} positive lengths (m) for {what}"
                        ),
                    ));
                }
                Ok(s)
            };
            match g {
                Generator::Rectangle => {
                    forbid(
                        &what,
                        &[
                            ("polygon", m.polygon.is_some()),
                            ("divisions", m.divisions.is_some()),
                            ("pattern", m.pattern.is_some()),
                        ],
                    )?;
                    let s = size(2)?;
                    Shape::Rectangle {
                        width: s[0],
                        height: s[1],
                        nodes: need_nodes()?,
                    }
                }
                Generator::Polygon => {
                    forbid(
                        &what,
                        &[
                            ("size", m.size.is_some()),
                            ("divisions", m.divisions.is_some()),
                            ("pattern", m.pattern.is_some()),
                        ],
                    )?;
                    let outline = m.polygon.clone().ok_or_else(|| {
                        err(
                            path,
                            "[mesh]: generate = \"polygon\" needs `polygon` = [[x, y], ...] (m)",
                        )
                    })?;
                    Shape::Polygon {
                        outline,
                        nodes: need_nodes()?,
                    }
                }
                Generator::Box => {
                    forbid(&what, &[("polygon", m.polygon.is_some())])?;
                    let s = size(3)?;
                    let cells = match (m.divisions, m.nodes) {
                        (Some(d), None) => BoxCells::Divisions(d),
                        (None, Some(n)) => BoxCells::Nodes(n),
                        _ => return Err(err(path, "[mesh]: generate = \"box\" needs exactly one of `nodes` or `divisions`")),
                    };
                    Shape::Box {
                        size: [s[0], s[1], s[2]],
                        cells,
                        pattern: m.pattern.unwrap_or(defaults::BOX_PATTERN),
                    }
                }
            }
        }
    };
    let scale = positive(path, "mesh.scale", m.scale.unwrap_or(defaults::SCALE))?;
    Ok(MeshSource {
        shape,
        scale,
        renumber_files: m.renumber.unwrap_or(defaults::RENUMBER_FILES),
        renumber_generated: m.renumber.unwrap_or(defaults::RENUMBER_GENERATED),
    })
}
