//! The loads a model's force model carries: surface loads (`[[pressure]]`, `[[traction]]`),
//! timed nodal loads and rigid tools (`[[tool]]`), selected on each level's own mesh and
//! carried by the force-model wrappers [`Loaded`] (loads, [`crate::fem::loads`]) and
//! [`Contact`] (tools, [`crate::contact`]); a scenario's are checked once by
//! [`crate::scenario::loading`].
//!
//! On every multigrid level the loads act on that level's own surface: a surface load's
//! triangles are those of the level's boundary (or membrane elements) whose three nodes the
//! same selector picks on that level (a group of the level's file, the patch within `radius`
//! of `point`, or the whole boundary); a timed nodal load's selector is applied again on the
//! level (a `nodes` list carried to the nearest node); a tool acts on the level's own nodes,
//! its default penalty stiffness from the level's own mean edge length.

use super::{err, select, Model, Selector};
use crate::contact::{default_stiffness, Contact, Friction, Tool, ToolShape};
use crate::error::Result;
use crate::fem::loads::{
    nodes_within, triangles_within, Loaded, SurfaceLoad, SurfaceLoadKind, TimeFunction,
    TimedNodalLoad,
};
use crate::fem::ForceModel;
use crate::mesh::Mesh;
use crate::time::Motion;
use std::path::Path;

/// Which surface a `[[pressure]]` or `[[traction]]` acts on.
#[derive(Clone, Debug, PartialEq)]
pub enum SurfaceSelector {
    /// A physical group of the mesh file (its nodes; the triangles with all three in it).
    Group(String),
    /// The nodes within `radius` (m) of `point`.
    Patch {
        /// `point` (m).
        point: [f64; 3],
        /// `radius` (m), positive.
        radius: f64,
    },
    /// The whole boundary (membranes: every element).
    Boundary,
}

/// A resolved `[[pressure]]` or `[[traction]]`.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceLoadDef {
    /// The loaded surface: `group`, `point` with `radius`, or `boundary`.
    pub on: SurfaceSelector,
    /// `value` (pressure, Pa) or `traction` (Pa per reference area).
    pub kind: SurfaceLoadKind,
    /// `time`, default constant.
    pub time: TimeFunction,
}

/// A resolved `[[tool]]`: the penalty stiffness `None` takes the default on each level.
#[derive(Clone, Debug, PartialEq)]
pub struct ToolDef {
    /// `shape` with its keys (a plane's `normal` made unit).
    pub shape: ToolShape,
    /// The translation (m): `displacement` times `time`, or `path`; held at zero without
    /// either.
    pub motion: Motion,
    /// `stiffness` (N/m); `None`: 4 × the material's stability modulus × the level's mean
    /// edge length ([`tool_stiffness`]).
    pub stiffness: Option<f64>,
    /// Coulomb friction; `None` frictionless (also for a zero coefficient).
    pub friction: Option<FrictionDef>,
}

/// A tool's resolved friction keys.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrictionDef {
    /// μ_s (`friction` or `static_friction`).
    pub static_coefficient: f64,
    /// μ_k ≤ μ_s (`friction` or `kinetic_friction`, default μ_s).
    pub kinetic_coefficient: f64,
    /// `friction_stiffness` (N/m); `None`: the tool's penalty stiffness.
    pub stiffness: Option<f64>,
}

/// The nodes `on` selects on `mesh` (errors name `key`).
fn surface_nodes(mesh: &Mesh, on: &SurfaceSelector, path: &Path, key: &str) -> Result<Vec<u32>> {
    Ok(match on {
        SurfaceSelector::Group(g) => select(mesh, &Selector::Group(g.clone()), path, key)?,
        SurfaceSelector::Patch { point, radius } => nodes_within(mesh, *point, *radius),
        SurfaceSelector::Boundary => (0..mesh.num_nodes() as u32).collect(),
    })
}

/// Mean edge length of `mesh` (m), over every element edge.
pub fn mean_edge(mesh: &Mesh) -> f64 {
    let npe = mesh.npe();
    let (mut sum, mut count) = (0.0, 0usize);
    for el in mesh.elements() {
        for i in 0..npe {
            for j in i + 1..npe {
                let (a, b) = (mesh.nodes[el[i] as usize], mesh.nodes[el[j] as usize]);
                sum += crate::mesh::norm(crate::mesh::sub(a, b));
                count += 1;
            }
        }
    }
    if count > 0 {
        sum / count as f64
    } else {
        0.0
    }
}

/// The penalty stiffness of tool `t` on `mesh` (N/m).
pub fn tool_stiffness(model: &Model, mesh: &Mesh, t: &ToolDef) -> f64 {
    t.stiffness.unwrap_or_else(|| {
        default_stiffness(model.material.stability_modulus(mesh.kind), mean_edge(mesh))
    })
}

impl Model {
    /// Whether a tool has friction (path-dependent contact: `measures.csv` has the friction
    /// columns, the frames the `friction_force` field).
    pub fn has_friction(&self) -> bool {
        self.tools.iter().any(|t| t.friction.is_some())
    }

    /// Whether the model has loads or tools that a [`Loaded`] or [`Contact`] force model
    /// carries.
    pub fn has_model_loads(&self) -> bool {
        !(self.timed_load.is_empty() && self.surface_loads.is_empty() && self.tools.is_empty())
    }

    /// The time after which every load and tool is constant (s; infinite with a sine).
    pub fn loads_end(&self) -> f64 {
        let a = self.timed_load.iter().map(|(_, _, f)| f.end());
        let b = self.surface_loads.iter().map(|s| s.time.end());
        let c = self.tools.iter().map(|t| t.motion.end());
        a.chain(b).chain(c).fold(0.0, f64::max)
    }

    /// A bound on the work the loads and tools of this model can do on `mesh` (J), for the
    /// energy blow-up threshold: `Σ |p| max|s| A` (surface loads over their area) times the
    /// mesh's size, plus `k d²` per node a tool can reach (its largest travel `d`).
    pub fn model_load_work(&self, mesh: &Mesh) -> f64 {
        let (lo, hi) = mesh.bounding_box();
        let size = crate::mesh::norm(crate::mesh::sub(hi, lo));
        let mut w = 0.0;
        for s in &self.surface_loads {
            let nodes = surface_nodes(mesh, &s.on, &self.path, "").unwrap_or_default();
            let area: f64 = triangles_within(mesh, &nodes)
                .iter()
                .map(|t| {
                    let p = t.map(|a| mesh.nodes[a as usize]);
                    crate::mesh::tri_area(p[0], p[1], p[2])
                })
                .sum();
            let mag = match &s.kind {
                SurfaceLoadKind::Pressure(p) => p.abs(),
                SurfaceLoadKind::Traction(t) => crate::mesh::norm(*t),
            };
            w += mag * s.time.max_abs() * area * size;
        }
        for (sel, f, tf) in &self.timed_load {
            let n = select(mesh, sel, &self.path, "").map_or(0, |v| v.len());
            w += n as f64 * crate::mesh::norm(*f) * tf.max_abs() * size;
        }
        for t in &self.tools {
            let d = t.motion.max_displacement().max(size);
            w += tool_stiffness(self, mesh, t) * d * d * mesh.num_nodes() as f64;
        }
        w
    }

    /// The triangles surface load `i` acts on, on `mesh`; an error if none.
    pub(crate) fn surface_triangles(&self, mesh: &Mesh, i: usize) -> Result<Vec<[u32; 3]>> {
        let s = &self.surface_loads[i];
        let key = match s.kind {
            SurfaceLoadKind::Pressure(_) => format!("pressure[{i}]"),
            SurfaceLoadKind::Traction(_) => format!(
                "traction[{}]",
                i - self
                    .surface_loads
                    .iter()
                    .filter(|x| matches!(x.kind, SurfaceLoadKind::Pressure(_)))
                    .count()
            ),
        };
        let nodes = surface_nodes(mesh, &s.on, &self.path, &key)?;
        let triangles = triangles_within(mesh, &nodes);
        if triangles.is_empty() {
            return Err(err(
                &self.path,
                format!(
                    "{key}: selects no surface triangle on a mesh of {} nodes (a triangle \
                     needs all three nodes selected; a patch needs a larger `radius`)",
                    mesh.num_nodes()
                ),
            ));
        }
        Ok(triangles)
    }

    /// Check that every surface load selects triangles and every timed load nodes on the
    /// model's mesh (at load time, not when the run starts).
    pub(crate) fn check_model_loads(&self) -> Result<()> {
        for i in 0..self.surface_loads.len() {
            self.surface_triangles(&self.mesh, i)?;
        }
        for (i, (sel, _, _)) in self.timed_load.iter().enumerate() {
            select(&self.mesh, sel, &self.path, &format!("load[{i}].at"))?;
        }
        Ok(())
    }

    /// Wrap `fem` (a force model on `mesh`, reference positions `x0`) with the model's
    /// surface loads, timed nodal loads and tools selected on `mesh` (see the module
    /// documentation); `fem` itself where there are none.
    pub fn wrap_loads(
        &self,
        mesh: &Mesh,
        x0: Vec<f64>,
        fem: Box<dyn ForceModel>,
    ) -> Result<Box<dyn ForceModel>> {
        if !self.has_model_loads() {
            return Ok(fem);
        }
        let coarse = !std::ptr::eq(mesh, &self.mesh) && mesh.num_nodes() != self.mesh.num_nodes();
        let mut surface = Vec::with_capacity(self.surface_loads.len());
        for (i, s) in self.surface_loads.iter().enumerate() {
            surface.push(SurfaceLoad {
                triangles: self.surface_triangles(mesh, i)?,
                kind: s.kind.clone(),
                time: s.time.clone(),
            });
        }
        let mut nodal = Vec::with_capacity(self.timed_load.len());
        for (i, (sel, force, time)) in self.timed_load.iter().enumerate() {
            let sel = match sel {
                Selector::Nodes(ns) if coarse => Selector::Nodes(
                    ns.iter()
                        .filter_map(|&a| self.mesh.nodes.get(a as usize))
                        .filter_map(|&p| mesh.nearest_node(p).map(|x| x as u32))
                        .collect(),
                ),
                s => s.clone(),
            };
            nodal.push(TimedNodalLoad {
                nodes: select(mesh, &sel, &self.path, &format!("timed load {i}"))?,
                force: *force,
                time: time.clone(),
            });
        }
        let tools: Vec<Tool> = self
            .tools
            .iter()
            .map(|t| Tool {
                shape: t.shape.clone(),
                motion: t.motion.clone(),
                stiffness: tool_stiffness(self, mesh, t),
                // Friction is a fine-level feature: coarse levels' tools are frictionless.
                friction: t.friction.filter(|_| !coarse).map(|f| {
                    let k = tool_stiffness(self, mesh, t);
                    Friction {
                        static_coefficient: f.static_coefficient,
                        kinetic_coefficient: f.kinetic_coefficient,
                        stiffness: f.stiffness.unwrap_or(k),
                    }
                }),
            })
            .collect();
        let loaded: Box<dyn ForceModel> = if surface.is_empty() && nodal.is_empty() {
            fem
        } else {
            Box::new(Loaded::new(fem, x0.clone(), surface, nodal))
        };
        Ok(if tools.is_empty() {
            loaded
        } else {
            Box::new(Contact::new(loaded, x0, tools))
        })
    }
}
