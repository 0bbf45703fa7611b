//! Per-element fibre fields of the fibre laws (`[material] fibre`, ti-neo-hookean and hgo):
//! one unit reference direction per element of each level, which the force model gives that
//! element's law ([`crate::fem::FemParams::fibres`]).
//!
//! Sources (`fibre = [x, y, z]`, the same in every element, needs no field):
//! - `fibre = { cell_data = "NAME" }`: the 3-component cell data array `NAME` of the `.vtu`
//!   `[mesh] file` (the first `<Piece>`), one direction per cell, each normalised; a mesh
//!   element takes its cell's (lower-dimensional cells hold data too and are skipped). Errors
//!   name the file, the array and the cell: no such array, not 3 components, fewer values
//!   than the mesh's cells, a zero or non-finite direction. Other mesh formats (Gmsh,
//!   legacy VTK, Triangle/TetGen, `surface`) carry no cell data here: an error says so.
//! - `fibre = { helix = { axis, centre, inner_radius, outer_radius, endo, epi } }`: the
//!   rule-based fibres of a wall about an axis (the helix-angle model of the myocardium on an
//!   idealised ventricle or vessel). With the unit axis `a` through `c`, an element's
//!   centroid `p`, `d = p − c`, the radial vector `ρ = d − (d·a) a`, `r = |ρ|`,
//!   `e_r = ρ / r`, `e_circ = a × e_r`:
//!   ```text
//!   t = clamp((r − r_in) / (r_out − r_in), 0, 1),   θ = endo + t (epi − endo),
//!   a0 = cos θ e_circ + sin θ a
//!   ```
//!   a unit vector orthogonal to `e_r` (θ in degrees as given). A centroid on the axis
//!   (`r ≤ 1e-9 r_out`) has no circumferential direction: an error naming the element.
//!   Radii: `0 ≤ r_in < r_out`, finite.
//!
//! Every level of a hierarchy (`[multigrid]`) has its own field, one direction per element
//! of that level:
//! - helix: the rule at each of the level's element centroids;
//! - cell data: from level 0's field by the principal eigenvector of the volume-weighted
//!   structure tensor `T = Σ V_f a_f ⊗ a_f` over the level-0 elements f hosted by the coarse
//!   element (the element hosting f's centroid, as the level transfers locate points:
//!   [`crate::hierarchy::Transfer`], a centroid outside the coarse mesh going to its nearest
//!   element). `T` is sign-free (`a` and `−a` are the same fibre); the eigenvector's sign is
//!   chosen with a non-negative product with the first hosted element's direction. A coarse
//!   element hosting no centroid takes the direction of the level-0 element hosting its own
//!   centroid. A uniform field stays uniform on every level (to rounding).
//!
//! With a field, the law's own direction ([`crate::material::Material::fibre`]) is a
//! placeholder (`e_1`) that no element uses.
//!
//! Coarse fields only build the coarse levels' force models: they precondition or accelerate
//! the solve of level 0, whose field is the one given.

use super::err;
use crate::error::Result;
use crate::fem::ElementFibres;
use crate::hierarchy::Transfer;
use crate::mesh::Mesh;
use nalgebra::{Matrix3, SymmetricEigen, Vector3};
use std::path::{Path, PathBuf};

/// A resolved per-element fibre field: its rule and its directions on level 0.
#[derive(Clone, Debug, PartialEq)]
pub struct FibreField {
    /// Where the directions come from.
    pub rule: FibreRule,
    /// One unit direction per element of [`super::Model::mesh`].
    pub level0: ElementFibres,
}

/// The source of a fibre field (module docs).
#[derive(Clone, Debug, PartialEq)]
pub enum FibreRule {
    /// `fibre = { cell_data = .. }`: the array `array` of the mesh file `file`.
    CellData {
        /// The `.vtu` mesh file.
        file: PathBuf,
        /// The cell data array's name.
        array: String,
    },
    /// `fibre = { helix = .. }`.
    Helix(Helix),
}

/// The helix-angle rule (module docs): fibres about `axis` through `centre`, at the angle
/// `endo` (degrees) at `inner_radius` turning linearly in depth to `epi` at `outer_radius`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Helix {
    /// Unit axis direction.
    pub axis: Vector3<f64>,
    /// A point of the axis (m).
    pub centre: Vector3<f64>,
    /// Distance from the axis of depth 0 (m).
    pub inner_radius: f64,
    /// Distance from the axis of depth 1 (m), above `inner_radius`.
    pub outer_radius: f64,
    /// Helix angle at depth 0 (degrees).
    pub endo: f64,
    /// Helix angle at depth 1 (degrees).
    pub epi: f64,
}

/// The key the errors name.
pub(crate) const KEY: &str = "material.fibre";

impl Helix {
    /// The fibre at `p` (module docs); `None` on the axis (`r ≤ 1e-9 r_out`).
    pub fn direction(&self, p: [f64; 3]) -> Option<[f64; 3]> {
        let d = Vector3::from(p) - self.centre;
        let rho = d - self.axis * d.dot(&self.axis);
        let r = rho.norm();
        if !(r > 1e-9 * self.outer_radius) {
            return None;
        }
        let e_circ = self.axis.cross(&(rho / r));
        let t = ((r - self.inner_radius) / (self.outer_radius - self.inner_radius)).clamp(0.0, 1.0);
        let theta = (self.endo + t * (self.epi - self.endo)).to_radians();
        let a = e_circ * theta.cos() + self.axis * theta.sin();
        Some([a.x, a.y, a.z])
    }

    /// The rule at every element centroid of `mesh`; an error naming the first element whose
    /// centroid lies on the axis.
    pub fn field(&self, mesh: &Mesh, path: &Path) -> Result<ElementFibres> {
        let dirs = centroids(mesh)
            .into_iter()
            .enumerate()
            .map(|(e, c)| {
                self.direction(c).ok_or_else(|| {
                    err(
                        path,
                        format!(
                            "`{KEY}.helix`: element {e}'s centroid [{}, {}, {}] lies on the axis, where the circumferential direction is undefined: move the axis (`centre`, `axis`) off the mesh",
                            c[0], c[1], c[2]
                        ),
                    )
                })
            })
            .collect::<Result<Vec<_>>>()?;
        ElementFibres::normalised(&dirs, KEY).map_err(|e| err(path, e.to_string()))
    }
}

/// Element centroids of `mesh`.
pub(crate) fn centroids(mesh: &Mesh) -> Vec<[f64; 3]> {
    mesh.elements()
        .map(|el| {
            let mut c = [0.0; 3];
            for &a in el {
                let x = mesh.nodes[a as usize];
                for k in 0..3 {
                    c[k] += x[k];
                }
            }
            c.map(|v| v / el.len() as f64)
        })
        .collect()
}

impl std::fmt::Display for FibreField {
    /// In words, e.g. "the helix rule about the axis (0, 0, 1) through (-0.03, 0.01, 0) m,
    /// 60 deg at r = 0.03 m to -60 deg at r = 0.04 m, one direction per element".
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let c = crate::numbers::compact;
        let v = |x: &Vector3<f64>| format!("({}, {}, {})", c(x.x), c(x.y), c(x.z));
        match &self.rule {
            FibreRule::Helix(h) => write!(
                f,
                "the helix rule about the axis {} through {} m, {} deg at r = {} m to {} deg at r = {} m",
                v(&h.axis),
                v(&h.centre),
                c(h.endo),
                c(h.inner_radius),
                c(h.epi),
                c(h.outer_radius)
            )?,
            FibreRule::CellData { file, array } => write!(
                f,
                "the cell data \"{array}\" of {}",
                file.file_name().map_or(file.display().to_string(), |n| n.to_string_lossy().into_owned())
            )?,
        }
        write!(f, ", one direction per element")
    }
}

impl FibreField {
    /// The field on `mesh`: level 0's where `mesh` is `level0_mesh` (same nodes and
    /// elements), else the rule of the module docs for a coarser level.
    pub fn on(&self, level0_mesh: &Mesh, mesh: &Mesh, path: &Path) -> Result<ElementFibres> {
        if mesh.cells == level0_mesh.cells && mesh.nodes == level0_mesh.nodes {
            return Ok(self.level0.clone());
        }
        match &self.rule {
            FibreRule::Helix(h) => h.field(mesh, path),
            FibreRule::CellData { .. } => coarsen(level0_mesh, &self.level0, mesh)
                .map_err(|e| err(path, format!("`{KEY}` on a coarser level: {e}"))),
        }
    }
}

/// A coarse mesh's field from the fine one's (module docs: structure tensors).
pub fn coarsen(fine: &Mesh, field: &ElementFibres, coarse: &Mesh) -> Result<ElementFibres> {
    let fine_c = centroids(fine);
    let located = Transfer::build(&fine_c, coarse)?;
    let nc = coarse.num_elements();
    let mut tensor = vec![Matrix3::<f64>::zeros(); nc];
    let mut first: Vec<Option<Vector3<f64>>> = vec![None; nc];
    for (f, &host) in located.host.iter().enumerate() {
        let a = Vector3::from(field.0[f]);
        let c = host as usize;
        tensor[c] += a * a.transpose() * fine.element_measure(f).abs();
        first[c].get_or_insert(a);
    }
    let empty: Vec<usize> = (0..nc).filter(|&c| first[c].is_none()).collect();
    let fallback = if empty.is_empty() {
        None
    } else {
        let coarse_c = centroids(coarse);
        let pts: Vec<[f64; 3]> = empty.iter().map(|&c| coarse_c[c]).collect();
        Some(Transfer::build(&pts, fine)?)
    };
    let mut dirs = Vec::with_capacity(nc);
    let mut fallback_hosts = fallback.iter().flat_map(|t| t.host.iter());
    for c in 0..nc {
        let Some(a1) = first[c] else {
            let host = *fallback_hosts.next().expect("one per empty element") as usize;
            dirs.push(field.0[host]);
            continue;
        };
        let eig = SymmetricEigen::new(tensor[c]);
        let i = (0..3)
            .max_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]))
            .expect("three eigenvalues");
        let mut v: Vector3<f64> = eig.eigenvectors.column(i).into_owned();
        if v.dot(&a1) < 0.0 {
            v = -v;
        }
        dirs.push([v.x, v.y, v.z]);
    }
    ElementFibres::normalised(&dirs, KEY)
}
