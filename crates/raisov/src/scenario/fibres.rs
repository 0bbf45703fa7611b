//! `[material] fibre` resolved into the model's fibre field ([`crate::model::fibres`]: the
//! sources, the helix rule and the coarser levels' fields are documented there).

use super::spec::{FibreSpec, HelixSpec};
use super::{err, Shape};
use crate::error::Result;
use crate::fem::ElementFibres;
use crate::mesh::Mesh;
use crate::model::fibres::KEY;
pub use crate::model::fibres::{coarsen, FibreField, FibreRule, Helix};
use nalgebra::Vector3;
use std::path::Path;

impl Helix {
    /// The rule from its spec; errors name the key and what is valid.
    pub fn new(h: &HelixSpec, path: &Path) -> Result<Helix> {
        let need = |key: &str, v: Option<f64>| {
            v.ok_or_else(|| {
                err(
                    path,
                    format!("`{KEY}.helix` needs `{key}` (keys: `axis`, `centre`, `inner_radius`, `outer_radius`, `endo`, `epi`)"),
                )
            })
        };
        let need3 = |key: &str, v: Option<[f64; 3]>| {
            v.map(Vector3::from)
                .ok_or_else(|| err(path, format!("`{KEY}.helix` needs `{key} = [x, y, z]`")))
        };
        let axis =
            crate::material::unit_direction(need3("axis", h.axis)?, "material.fibre.helix.axis")
                .map_err(|e| err(path, e.to_string()))?;
        let centre = need3("centre", h.centre)?;
        let inner_radius = need("inner_radius", h.inner_radius)?;
        let outer_radius = need("outer_radius", h.outer_radius)?;
        let (endo, epi) = (need("endo", h.endo)?, need("epi", h.epi)?);
        if !(inner_radius >= 0.0 && outer_radius > inner_radius && outer_radius.is_finite()) {
            return Err(err(
                path,
                format!(
                    "`{KEY}.helix`: inner_radius = {}, outer_radius = {}: need 0 <= inner_radius < outer_radius (m)",
                    crate::numbers::compact(inner_radius),
                    crate::numbers::compact(outer_radius)
                ),
            ));
        }
        if !(centre.iter().all(|x| x.is_finite()) && endo.is_finite() && epi.is_finite()) {
            return Err(err(path, format!("`{KEY}.helix`: numbers must be finite")));
        }
        Ok(Helix {
            axis,
            centre,
            inner_radius,
            outer_radius,
            endo,
            epi,
        })
    }
}

/// Resolve `[material] fibre` on level 0's `mesh` (built from `shape`): `None` for a single
/// direction (the law's own) or no fibre.
pub(super) fn resolve(
    spec: Option<&FibreSpec>,
    mesh: &Mesh,
    shape: &Shape,
    path: &Path,
) -> Result<Option<FibreField>> {
    let rule = match spec {
        None | Some(FibreSpec::Direction(_)) => return Ok(None),
        Some(FibreSpec::Helix(h)) => FibreRule::Helix(Helix::new(h, path)?),
        Some(FibreSpec::CellData(array)) => {
            let file = match shape {
                Shape::File(f)
                    if f.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase())
                        == Some("vtu".into()) =>
                {
                    f.clone()
                }
                Shape::File(f) => {
                    return Err(err(
                        path,
                        format!(
                            "`{KEY}` = {{ cell_data = \"{array}\" }}: cell data is read from .vtu mesh files, and `[mesh]` reads {} (give the fibres as a .vtu file's cell data, or use `fibre = [x, y, z]` or the `helix` rule)",
                            f.display()
                        ),
                    ))
                }
                _ => {
                    return Err(err(
                        path,
                        format!(
                            "`{KEY}` = {{ cell_data = \"{array}\" }}: a generated mesh has no cell data; read a .vtu `[mesh] file`, or use `fibre = [x, y, z]` or the `helix` rule"
                        ),
                    ))
                }
            };
            FibreRule::CellData {
                file,
                array: array.clone(),
            }
        }
    };
    let level0 = match &rule {
        FibreRule::Helix(h) => h.field(mesh, path)?,
        FibreRule::CellData { file, array } => read_cell_data(file, array, mesh, path)?,
    };
    Ok(Some(FibreField { rule, level0 }))
}

/// The cell data array `array` of `file`, one unit direction per element of `mesh` (read
/// from `file`, elements in file order).
fn read_cell_data(file: &Path, array: &str, mesh: &Mesh, path: &Path) -> Result<ElementFibres> {
    let what = format!(
        "`{KEY}` = {{ cell_data = \"{array}\" }}: {}",
        file.display()
    );
    let (k, v) = crate::io::read_vtu_cell_array(file, array)
        .map_err(|e| err(path, format!("`{KEY}`: {e}")))?;
    if k != 3 {
        return Err(err(
            path,
            format!("{what}: the cell array \"{array}\" has {k} components per cell; a fibre direction has 3"),
        ));
    }
    // The element -> cell map: read again (the first read built the mesh).
    let loaded = crate::io::load_mesh(file).map_err(|e| err(path, format!("`{KEY}`: {e}")))?;
    if loaded.element_ids.len() != mesh.num_elements() {
        return Err(err(
            path,
            format!(
                "{what}: the file has {} elements, the mesh {}",
                loaded.element_ids.len(),
                mesh.num_elements()
            ),
        ));
    }
    let cells = v.len() / 3;
    let mut dirs = Vec::with_capacity(mesh.num_elements());
    for &c in &loaded.element_ids {
        let c = c as usize;
        if c >= cells {
            return Err(err(
                path,
                format!(
                    "{what}: the cell array \"{array}\" has {cells} cells, but the mesh's elements reach cell {c} (cell data of the first <Piece> only: one array for every cell)"
                ),
            ));
        }
        let a = [v[3 * c], v[3 * c + 1], v[3 * c + 2]];
        let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        if !(n > 0.0 && n.is_finite()) {
            return Err(err(
                path,
                format!(
                    "{what}: cell {c} of \"{array}\" is [{}, {}, {}], not a direction: every cell needs a non-zero finite vector",
                    a[0], a[1], a[2]
                ),
            ));
        }
        dirs.push(a);
    }
    ElementFibres::normalised(&dirs, KEY).map_err(|e| err(path, e.to_string()))
}
