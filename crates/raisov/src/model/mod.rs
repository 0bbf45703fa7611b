//! The model: the body and what acts on it, typed once. Both front doors produce one: the
//! scenario resolver from a TOML file ([`crate::scenario::Scenario::model`]) and
//! [`crate::sim::SimulationBuilder`] from code; [`Model::stepper`] turns it, with a [`Scheme`]
//! and the [`Stepping`] settings, into the [`crate::integrate::Stepper`] that advances it.
//!
//! A model is level 0's mesh (metres) and how its coarser levels are made ([`Levels`]); the
//! physics (material and fibre field, density, membrane thickness, the mass-proportional
//! damping α, gravity); the fixed regions and nodal loads as selectors ([`select()`]), selected
//! again on every level's mesh, with their selection on level 0; the prescribed motions; and
//! the loads a force model carries (surface loads, timed nodal loads, rigid tools:
//! [`loads`]). Every level's system is
//!
//! ```text
//! M ü + α M u̇ + R(u) = V,        V = M g + Σ nodal loads,
//! ```
//!
//! `R` the element forces of the level's mesh wrapped with the level's own surface loads,
//! timed loads and tools (SI units; `u` the displacement from the reference positions).
//!
//! Files: `select.rs` the selectors, `mesh_source.rs` how a mesh is read or generated,
//! `levels.rs` the coarser levels (meshes, constraints and systems per level, the levels of a
//! multigrid), `loads.rs` the force-model loads per level, `fibres.rs` the fibre fields per
//! level, `scheme.rs` the one [`Scheme`], `stepper.rs` [`Model::stepper`].

pub mod fibres;
pub mod levels;
pub mod loads;
pub mod mesh_source;
pub mod scheme;
pub mod select;
pub mod stepper;

use crate::error::{Error, Result};
use crate::fem::{FemModel, FemParams, Precision};
use crate::integrate::{Constraints, System};
use crate::material::Material;
use crate::mesh::{ElementKind, Mesh};
use crate::time::{Motion, TimeFunction};
pub use levels::{LevelConstraints, LevelMeshes, PickedLevel};
pub use mesh_source::{BoxCells, MeshSource, Shape};
pub use scheme::{Scheme, SchemeKind};
pub use select::{select, Fixing, Region, Selector};
use std::path::{Path, PathBuf};
pub use stepper::{default_smoother, ImplicitSolve, Stepping};

/// How a model's coarser levels are made.
#[derive(Clone, Debug)]
pub enum Levels {
    /// Level 0 alone.
    Single,
    /// Meshes given in code, next-coarser first ([`crate::sim::SimulationBuilder::levels`]).
    Given(Vec<Mesh>),
    /// Made like level 0 from [`Model::mesh_source`] (a scenario's `[multigrid]` levels).
    Built(LevelMeshes),
}

/// The body and what acts on it (module docs).
#[derive(Clone, Debug)]
pub struct Model {
    /// Where the model came from, for messages: the scenario file (relative paths in it are
    /// relative to its directory), or `SimulationBuilder` for a model built in code.
    pub path: PathBuf,
    /// Level 0's mesh, in metres (`[mesh] scale` applied), nodes in the order of
    /// [`Model::file_ids`].
    pub mesh: Mesh,
    /// How [`Model::mesh`] was made (a scenario's `[mesh]`), and so how coarser levels
    /// [`Levels::Built`] are made; `None` for a mesh given in code.
    pub mesh_source: Option<MeshSource>,
    /// The coarser levels of a hierarchy, if any.
    pub levels: Levels,
    /// `[material]`: the law and its constants.
    pub material: Material,
    /// `[material] fibre` as a field, one direction per element ([`crate::scenario::fibres`]); `None` for
    /// one direction (the law's own) or a law without fibres.
    pub fibres: Option<fibres::FibreField>,
    /// `[material] density` (kg/m³), default 1000.
    pub density: f64,
    /// `[material] thickness` of membranes (m), default 1e-3.
    pub thickness: f64,
    /// `[integrator] precision`: storage precision of the packed tetrahedron data.
    pub precision: Precision,
    /// `[damping]`: the mass-proportional damping `D = α M`, α in 1/s (`alpha`, or
    /// `2 ζ ω` from `ratio` and `omega`); default 0.
    pub alpha: f64,
    /// `gravity` (m/s²), default zero.
    pub gravity: [f64; 3],
    /// `[[fix]]` selectors and what each holds, selected again on every multigrid level.
    pub fix: Vec<(Selector, Fixing)>,
    /// `[[load]]` selectors and the force on each selected node (N), constant in time.
    pub load: Vec<(Selector, [f64; 3])>,
    /// `[[load]]` entries with a time function: selector, force per node (N), `s(t)`; carried
    /// by the force model ([`loads`]).
    pub timed_load: Vec<(Selector, [f64; 3], TimeFunction)>,
    /// `[[pressure]]` and `[[traction]]` ([`loads`]).
    pub surface_loads: Vec<loads::SurfaceLoadDef>,
    /// `[[tool]]`: rigid tools in penalty contact ([`crate::contact`]).
    pub tools: Vec<loads::ToolDef>,
    /// The nodes `fix` selects on [`Model::mesh`] with all components held.
    pub fixed: Vec<u32>,
    /// The nodes `fix` selects with some directions held: `(node, unit direction)`.
    pub sliding: Vec<(u32, [f64; 3])>,
    /// The nodes `load` selects on [`Model::mesh`], each with its force.
    pub loads: Vec<(u32, [f64; 3])>,
    /// `[[displace]]`: each prescribed node of [`Model::mesh`] and its motion (m); the
    /// nodes of a patch (`radius`) share one motion.
    pub prescribed: Vec<(u32, Motion)>,
    /// `[mesh] renumber`: node `k` of [`Model::mesh`] is node `file_ids[k]` of the file
    /// (its position in file order after unused nodes are dropped; the id the file gives it
    /// is [`Model::node_labels`]); `None` where the mesh keeps the file's order.
    pub file_ids: Option<Vec<u32>>,
    /// The id the mesh file gives each node, in file order (index as in
    /// [`Model::file_ids`]); `None` for generated meshes, whose ids are the 0-based
    /// positions. `nodes = [..]` selectors and the outputs use these ids.
    pub node_labels: Option<Vec<u64>>,
}

/// An error of the model's source (`path`: the scenario file, or `SimulationBuilder`).
pub(crate) fn err(path: &Path, msg: impl Into<String>) -> Error {
    Error::Scenario {
        path: path.to_path_buf(),
        line: None,
        msg: msg.into(),
    }
}

impl Model {
    /// A model of `mesh` alone with `material` and the defaults of
    /// [`crate::sim::SimulationBuilder`]'s physics: density 1000 kg/m³, membrane thickness
    /// 1 mm, no damping, no gravity, nothing fixed or loaded; `path` names it in messages.
    pub fn new(mesh: Mesh, material: Material, path: impl Into<PathBuf>) -> Model {
        Model {
            path: path.into(),
            mesh,
            mesh_source: None,
            levels: Levels::Single,
            material: material.clone(),
            fibres: None,
            density: 1000.0,
            thickness: 1e-3,
            precision: FemParams::new(material).precision,
            alpha: 0.0,
            gravity: [0.0; 3],
            fix: Vec::new(),
            load: Vec::new(),
            timed_load: Vec::new(),
            surface_loads: Vec::new(),
            tools: Vec::new(),
            fixed: Vec::new(),
            sliding: Vec::new(),
            loads: Vec::new(),
            prescribed: Vec::new(),
            file_ids: None,
            node_labels: None,
        }
    }

    /// The file's id of node `a` of [`Model::mesh`] (see [`Model::file_ids`] and
    /// [`Model::node_labels`]).
    pub fn file_node(&self, a: u32) -> u64 {
        let k = self.file_ids.as_ref().map_or(a, |f| f[a as usize]);
        self.node_labels
            .as_ref()
            .map_or(k as u64, |l| l[k as usize])
    }

    /// The file's id of every node of [`Model::mesh`], where it differs from the node's
    /// position (a renumbered mesh, or a file whose ids are not 0, 1, 2, ...).
    pub fn output_node_ids(&self) -> Option<Vec<i64>> {
        let n = self.mesh.num_nodes();
        let ids: Vec<i64> = (0..n as u32).map(|a| self.file_node(a) as i64).collect();
        (ids.iter().enumerate().any(|(a, &id)| id != a as i64)).then_some(ids)
    }

    /// FE parameters of this model on [`Model::mesh`] (its fibre field included).
    pub fn fem_params(&self) -> FemParams {
        let mut p = FemParams::new(self.material.clone());
        p.density = self.density;
        p.thickness = self.thickness;
        p.precision = self.precision;
        p.fibres = self.fibres.as_ref().map(|f| f.level0.clone());
        p
    }

    /// The cell fields every frame of [`Model::mesh`] carries: `fibre` (3 per element)
    /// where the material has a fibre field.
    pub fn cell_fields(&self) -> Vec<crate::io::Field<'_>> {
        self.fibres
            .iter()
            .map(|f| crate::io::Field {
                name: "fibre",
                data: crate::io::FieldData::Vector(f.level0.flat()),
            })
            .collect()
    }

    /// FE parameters of this model on `mesh`, level 0 or a coarser level: the fibre field
    /// on that mesh ([`fibres::FibreField::on`]).
    pub fn fem_params_on(&self, mesh: &Mesh) -> Result<FemParams> {
        let mut p = self.fem_params();
        if let Some(f) = &self.fibres {
            p.fibres = Some(f.on(&self.mesh, mesh, &self.path)?);
        }
        Ok(p)
    }

    /// Assemble the system M ü + α M u̇ + R(u) = V of the finest mesh.
    pub fn build_system(&self) -> Result<System> {
        self.system_on(
            &self.mesh,
            &self.fixed,
            &self.sliding,
            &self.prescribed,
            &self.loads,
        )
    }

    /// Assemble a system on `mesh` (level 0 or a coarser level) with the model's physics
    /// (material, density, damping, gravity, the force-model loads selected on `mesh`) and
    /// the given constraints and nodal loads.
    pub fn system_on(
        &self,
        mesh: &Mesh,
        fixed: &[u32],
        sliding: &[(u32, [f64; 3])],
        prescribed: &[(u32, Motion)],
        loads: &[(u32, [f64; 3])],
    ) -> Result<System> {
        let fem = FemModel::new(mesh, self.fem_params_on(mesh)?)?;
        let mass = fem.lumped_mass();
        let n = mesh.num_nodes();
        let x0 = fem.reference_positions().to_vec();
        let force = self.wrap_loads(mesh, x0, Box::new(fem))?;
        let mut sys = System::new(
            force,
            mass,
            self.alpha,
            vec![0.0; 3 * n],
            Constraints::new(fixed.to_vec(), prescribed.to_vec()).with_sliding(sliding),
        );
        sys.add_gravity(self.gravity);
        for &(a, f) in loads {
            for k in 0..3 {
                sys.f_ext[3 * a as usize + k] += f[k];
            }
        }
        Ok(sys)
    }

    /// Total mass (kg).
    pub fn total_mass(&self) -> f64 {
        self.mesh.total_measure().abs()
            * self.density
            * if self.mesh.kind == ElementKind::Tri3 {
                self.thickness
            } else {
                1.0
            }
    }
}
