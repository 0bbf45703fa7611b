//! The levels of a model: each coarser level's mesh (given in code, generated as a geometric
//! series of node counts, or read from files), constraints and loads selected again on every
//! level, each level's system, and the levels of a multigrid.
//!
//! Per level: fixed regions and loads are selected again on that level's mesh (a `nodes`
//! list is carried by nearest node); a prescribed displacement of level 0 goes to the node of
//! each coarser level nearest to level 0's prescribed node (paper section 3.1).

use super::select::select_fixed;
use super::{err, select, BoxCells, Levels, Model, Selector, Shape, Stepping};
use crate::error::Result;
use crate::hierarchy::Correspondence;
use crate::integrate::stability::{critical_step_estimate, lambda_max_bound};
use crate::integrate::System;
use crate::mesh::Mesh;
use crate::multigrid::Level;
use crate::statics::nested::{NestedLevels, StartLevel};
use crate::time::Motion;

/// Fewest nodes of a generated level.
pub(crate) const MIN_LEVEL_NODES: usize = 4;

/// How a scenario's coarser levels are made, level 0 being `[mesh]`.
#[derive(Clone, Debug, PartialEq)]
pub enum LevelMeshes {
    /// `levels` generated levels, node counts (or divisions) shrinking by `ratio` per level.
    Ratio {
        /// `[multigrid] levels`: the number of levels, level 0 included.
        levels: usize,
        /// `[multigrid] ratio`, in (0, 1): level i has `ratio^i` times level 0's node target
        /// (a box given by `divisions`: `ratio^(i/3)` times its divisions); default 0.5.
        ratio: f64,
    },
    /// Generated levels of these node targets, level 0 first.
    Nodes(Vec<usize>),
    /// Mesh files of levels 1.. (paths joined to the scenario's directory).
    Files(Vec<std::path::PathBuf>),
}

impl LevelMeshes {
    /// Number of levels, level 0 included.
    pub fn count(&self) -> usize {
        match self {
            LevelMeshes::Ratio { levels, .. } => *levels,
            LevelMeshes::Nodes(n) => n.len(),
            LevelMeshes::Files(f) => 1 + f.len(),
        }
    }
}

/// Constraints and loads of one level.
#[derive(Clone, Debug, Default)]
pub struct LevelConstraints {
    /// Nodes with all three components held at zero.
    pub fixed: Vec<u32>,
    /// Nodes with held directions: `(node, unit direction)`.
    pub sliding: Vec<(u32, [f64; 3])>,
    /// Prescribed nodes and their motions (m): on a coarser level the node nearest each of
    /// level 0's prescribed nodes.
    pub prescribed: Vec<(u32, Motion)>,
    /// Nodes with a constant nodal load and its force (N).
    pub loads: Vec<(u32, [f64; 3])>,
}

/// `shape` with `nodes` nodes (a generated shape; files stay).
fn with_nodes(shape: &Shape, nodes: usize) -> Shape {
    let mut s = shape.clone();
    match &mut s {
        Shape::Rectangle { nodes: n, .. }
        | Shape::Polygon { nodes: n, .. }
        | Shape::Box {
            cells: BoxCells::Nodes(n),
            ..
        } => *n = nodes,
        Shape::Box { .. } | Shape::File(_) => {}
    }
    s
}

/// What [`Model::pick_level`] returns.
#[derive(Clone, Debug)]
pub struct PickedLevel {
    /// The node counts the choice was made from, finest first: the meshes' own for mesh
    /// files, the requested ones for generated membranes.
    pub counts: Vec<usize>,
    /// Whether `counts` are requested counts (generated membranes), not meshed ones.
    pub requested: bool,
    /// The chosen coarser level (1 or more) and its mesh; `None` where none was chosen.
    pub chosen: Option<(usize, Mesh)>,
}

impl Model {
    /// Number of levels, level 0 included.
    pub fn num_levels(&self) -> usize {
        match &self.levels {
            Levels::Single => 1,
            Levels::Given(meshes) => 1 + meshes.len(),
            Levels::Built(meshes) => meshes.count(),
        }
    }

    /// The level meshes, finest (the model's mesh) first.
    pub fn level_meshes(&self) -> Result<Vec<Mesh>> {
        Ok(self
            .level_meshes_with_ids()?
            .into_iter()
            .map(|(m, _)| m)
            .collect())
    }

    /// The level meshes, finest first, each with the file ids of its nodes where it was
    /// renumbered at load (see [`Model::file_ids`]).
    #[allow(clippy::type_complexity)]
    pub fn level_meshes_with_ids(&self) -> Result<Vec<(Mesh, Option<Vec<u32>>)>> {
        let mut out = vec![(self.mesh.clone(), self.file_ids.clone())];
        if let Levels::Given(meshes) = &self.levels {
            out.extend(meshes.iter().map(|m| (m.clone(), None)));
            return Ok(out);
        }
        for (i, shape) in self.coarser_shapes().into_iter().enumerate() {
            out.push(self.build_level(&shape, i)?);
        }
        Ok(out)
    }

    /// Of the coarser levels, the one `pick` chooses from the node counts of all levels
    /// (finest first), with its mesh; and those node counts. A choice of level 0, or past
    /// the coarsest level, chooses none. Mesh files are all read, as their node counts are
    /// known only then. Generated membranes (`rectangle`, `polygon`) are
    /// chosen by their requested node counts (`mesh.nodes` and the coarser levels' targets),
    /// and only the chosen level is meshed: meshing all of them costs about as much as the
    /// finest level again. The requested counts also make the choice independent of the
    /// mesher's few nodes more or less: with `ratio = 0.5`, level 4 is requested at exactly
    /// 1/16 of the nodes, and meshed at 124 of 1 983 for 125 of 2 000 requested.
    pub fn pick_level(&self, pick: impl Fn(&[usize]) -> Option<usize>) -> Result<PickedLevel> {
        if let Levels::Given(meshes) = &self.levels {
            let counts: Vec<usize> = std::iter::once(&self.mesh)
                .chain(meshes)
                .map(|m| m.num_nodes())
                .collect();
            let chosen = pick(&counts)
                .filter(|&i| i > 0 && i <= meshes.len())
                .map(|i| (i, meshes[i - 1].clone()));
            return Ok(PickedLevel {
                counts,
                requested: false,
                chosen,
            });
        }
        let shapes = self.coarser_shapes();
        let Some(source) = &self.mesh_source else {
            return Ok(PickedLevel {
                counts: vec![self.mesh.num_nodes()],
                requested: false,
                chosen: None,
            });
        };
        let requested = |s: &Shape| match s {
            Shape::Rectangle { nodes, .. } | Shape::Polygon { nodes, .. } => Some(*nodes),
            _ => None,
        };
        let targets: Option<Vec<usize>> = std::iter::once(&source.shape)
            .chain(&shapes)
            .map(requested)
            .collect();
        if let Some(counts) = targets {
            let chosen = match pick(&counts).filter(|&i| i > 0 && i <= shapes.len()) {
                Some(i) => Some((i, self.build_level(&shapes[i - 1], i - 1)?.0)),
                None => None,
            };
            return Ok(PickedLevel {
                counts,
                requested: true,
                chosen,
            });
        }
        let meshes = self.level_meshes()?;
        let counts: Vec<usize> = meshes.iter().map(|m| m.num_nodes()).collect();
        let chosen = pick(&counts)
            .filter(|&i| i > 0)
            .and_then(|i| meshes.into_iter().nth(i).map(|m| (i, m)));
        Ok(PickedLevel {
            counts,
            requested: false,
            chosen,
        })
    }

    /// The mesh of coarser level `level` (1 or more) alone: generated, or read from its file.
    /// An error where there is no such level.
    pub fn level_mesh(&self, level: usize) -> Result<Mesh> {
        if let Levels::Given(meshes) = &self.levels {
            if let Some(m) = level.checked_sub(1).and_then(|i| meshes.get(i)) {
                return Ok(m.clone());
            }
        }
        let shapes = self.coarser_shapes();
        match level
            .checked_sub(1)
            .and_then(|i| shapes.get(i).map(|s| (i, s)))
        {
            Some((i, shape)) => Ok(self.build_level(shape, i)?.0),
            None => Err(crate::error::Error::param(
                "multigrid",
                format!(
                    "level {level} does not exist: this model has coarser levels 1 to {}",
                    self.num_levels() - 1
                ),
            )),
        }
    }

    /// The levels of a nested start through the coarser `levels` (indices, finest first, at
    /// least one; [`crate::statics::nested::start_levels`]): each one's system (the
    /// model's constraints and loads carried to it) and its nodes located in the next,
    /// and the fine nodes located in the first. `known`, a level's mesh already built, is
    /// used for that level; the others are built or read ([`Model::level_mesh`]).
    pub fn nested_levels(&self, levels: &[usize], known: (&Mesh, usize)) -> Result<NestedLevels> {
        let meshes = levels
            .iter()
            .map(|&l| match l == known.1 {
                true => Ok(known.0.clone()),
                false => self.level_mesh(l),
            })
            .collect::<Result<Vec<Mesh>>>()?;
        let Some((coarsest, _)) = meshes.split_last() else {
            return Err(crate::error::Error::param(
                "multigrid",
                "a nested start needs at least one coarser level",
            ));
        };
        let fine_in_first = crate::hierarchy::Transfer::build(&self.mesh.nodes, &meshes[0])?;
        let between = meshes
            .windows(2)
            .zip(levels)
            .map(|(w, &l)| {
                Ok(StartLevel {
                    system: self.level_system(&w[0], l)?,
                    down: crate::hierarchy::Transfer::build(&w[0].nodes, &w[1])?,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(NestedLevels {
            coarsest: self.level_system(coarsest, *levels.last().expect("checked"))?,
            between,
            fine_in_first,
        })
    }

    /// The shapes of the coarser levels built from [`Model::mesh_source`] (level 1 first);
    /// none for [`Levels::Single`] and [`Levels::Given`].
    fn coarser_shapes(&self) -> Vec<Shape> {
        let (Levels::Built(meshes), Some(src)) = (&self.levels, &self.mesh_source) else {
            return Vec::new();
        };
        match meshes {
            LevelMeshes::Files(files) => files.iter().map(|f| Shape::File(f.clone())).collect(),
            LevelMeshes::Nodes(ln) => ln[1..].iter().map(|&n| with_nodes(&src.shape, n)).collect(),
            LevelMeshes::Ratio { levels, ratio } => (1..*levels)
                .map(|i| {
                    let f = ratio.powi(i as i32);
                    match &src.shape {
                        Shape::Rectangle { nodes, .. }
                        | Shape::Polygon { nodes, .. }
                        | Shape::Box {
                            cells: BoxCells::Nodes(nodes),
                            ..
                        } => with_nodes(
                            &src.shape,
                            ((*nodes as f64 * f).round() as usize).max(MIN_LEVEL_NODES),
                        ),
                        Shape::Box {
                            size,
                            cells: BoxCells::Divisions(d),
                            pattern,
                        } => {
                            let g = f.cbrt();
                            Shape::Box {
                                size: *size,
                                cells: BoxCells::Divisions(
                                    d.map(|x| ((x as f64 * g).round() as usize).max(1)),
                                ),
                                pattern: *pattern,
                            }
                        }
                        Shape::File(_) => unreachable!("`levels` needs [mesh] generate"),
                    }
                })
                .collect(),
        }
    }

    /// The mesh of coarser level `i` (0: level 1) of shape `shape`, with its file ids. A
    /// level file of another element kind than level 0 (triangles under tetrahedra) is an
    /// error naming that file and level 0's.
    fn build_level(&self, shape: &Shape, i: usize) -> Result<(Mesh, Option<Vec<u32>>)> {
        let key = match shape {
            Shape::File(_) => format!("multigrid.files[{i}]"),
            _ => "mesh".to_string(),
        };
        let Some(source) = &self.mesh_source else {
            return Err(err(
                &self.path,
                format!("level {}: no mesh source to build it from", i + 1),
            ));
        };
        let (mesh, _, ids, _) = source.build(shape, &self.path, &key)?;
        if mesh.kind != self.mesh.kind {
            let named = |key: &str, shape: &Shape| match shape {
                Shape::File(p) => format!("`{key}` = \"{}\"", p.display()),
                _ => "generated from [mesh]".to_string(),
            };
            return Err(err(
                &self.path,
                format!(
                    "{}: level {} is a {} mesh but level 0 ({}) is a {} mesh; every level must \
                     have level 0's element kind",
                    named(&key, shape),
                    i + 1,
                    mesh.kind.name(),
                    named("mesh.file", &source.shape),
                    self.mesh.kind.name()
                ),
            ));
        }
        Ok((mesh, ids))
    }

    /// Fixed nodes, prescribed motions and nodal loads of this model on `mesh` (a level).
    pub fn constraints_on(&self, mesh: &Mesh, level: usize) -> Result<LevelConstraints> {
        if level == 0 {
            return Ok(LevelConstraints {
                fixed: self.fixed.clone(),
                sliding: self.sliding.clone(),
                prescribed: self.prescribed.clone(),
                loads: self.loads.clone(),
            });
        }
        let carry = |s: &Selector| -> Selector {
            match s {
                // A node list names level-0 nodes: carry each to the nearest node here.
                Selector::Nodes(ns) => Selector::Nodes(
                    ns.iter()
                        .filter_map(|&a| self.mesh.nodes.get(a as usize))
                        .filter_map(|&p| mesh.nearest_node(p).map(|x| x as u32))
                        .collect(),
                ),
                s => s.clone(),
            }
        };
        let fix: Vec<(Selector, super::Fixing)> = self
            .fix
            .iter()
            .map(|(s, f)| (carry(s), f.clone()))
            .collect();
        let (fixed, sliding) = select_fixed(mesh, &fix, &self.path, &format!("level {level}: "))?;
        let mut loads = Vec::new();
        for (i, (s, force)) in self.load.iter().enumerate() {
            for n in select(
                mesh,
                &carry(s),
                &self.path,
                &format!("level {level}: load[{i}].at"),
            )? {
                loads.push((n, *force));
            }
        }
        let mut prescribed: Vec<(u32, Motion)> = Vec::new();
        for (a, m) in &self.prescribed {
            let p = self.mesh.nodes[*a as usize];
            let n = mesh.nearest_node(p).expect("non-empty mesh") as u32;
            if !prescribed.iter().any(|(x, _)| *x == n) {
                prescribed.push((n, m.clone()));
            }
        }
        Ok(LevelConstraints {
            fixed,
            sliding,
            prescribed,
            loads,
        })
    }

    /// The system of level `level` on its mesh `mesh` (a mesh of [`Model::level_meshes`]):
    /// the model's physics with the constraints and loads of [`Model::constraints_on`].
    pub fn level_system(&self, mesh: &Mesh, level: usize) -> Result<System> {
        if level == 0 {
            return self.build_system();
        }
        let c = self.constraints_on(mesh, level)?;
        self.system_on(mesh, &c.fixed, &c.sliding, &c.prescribed, &c.loads)
    }

    /// Build every level (mesh, system with its own constraints, integrator, step) and the
    /// correspondences between consecutive levels: level `i` steps with `s.methods[i]` at
    /// `s.level_dt[i]` where given, else level 0 at `s.dt` and a coarser level at `s.dt`
    /// (`paper`: the paper's cycle) or `s.safety` times its estimated critical step.
    pub fn build_levels(
        &self,
        s: &Stepping,
        paper: bool,
    ) -> Result<(Vec<Level>, crate::multigrid::Links)> {
        let (meshes, keys): (Vec<Mesh>, Vec<Option<Vec<u32>>>) =
            self.level_meshes_with_ids()?.into_iter().unzip();
        let m = meshes.len();
        if s.methods.len() < m {
            return Err(err(
                &self.path,
                format!("{} levels but {} integrators", m, s.methods.len()),
            ));
        }
        let dts: Vec<f64> = match &s.level_dt {
            Some(d) => d.clone(),
            None if paper => vec![s.dt; m],
            None => meshes
                .iter()
                .zip(&s.methods)
                .enumerate()
                .map(|(i, (mesh, &me))| {
                    if i == 0 {
                        s.dt
                    } else {
                        s.safety * critical_step_estimate(mesh, &self.material, self.density, me)
                    }
                })
                .collect(),
        };
        let mut links = Vec::with_capacity(m.saturating_sub(1));
        for i in 0..m.saturating_sub(1) {
            links.push(Correspondence::build(&meshes[i], &meshes[i + 1])?);
        }
        let mut levels = Vec::with_capacity(m);
        for (i, (mesh, node_keys)) in meshes.into_iter().zip(keys).enumerate() {
            let sys = self.level_system(&mesh, i)?;
            let lambda_max = lambda_max_bound(&mesh, &self.material, self.density);
            let mut level = Level::new(mesh, sys, s.methods[i], dts[i], lambda_max);
            level.node_keys = node_keys;
            levels.push(level);
        }
        Ok((levels, links))
    }
}
