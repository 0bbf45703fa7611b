//! Multigrid levels of a scenario: level meshes (generated as a geometric series of node
//! counts, or read from files), constraints re-resolved on every level, and the stepper.
//!
//! Per level: fixed regions and loads are selected again on that level's mesh (a `nodes`
//! list is carried by nearest node); a prescribed displacement of level 0 goes to the node of
//! each coarser level nearest to level 0's prescribed node (paper section 3.1).

use super::scheme::{Scheme, SchemeKind};
use super::spec::{
    defaults, Accelerate, CoarseKind, MeshSpec, MultigridSpec, SmootherKind, FAS_KEYS, PAPER_KEYS,
};
use super::{build_system, err, positive, select, BoxCells, Scenario, Selector, Shape};
use crate::error::Result;
use crate::hierarchy::Correspondence;
use crate::integrate::stability::{critical_step_estimate, lambda_max_bound};
use crate::integrate::{
    energy_limit_for, Method, Motion, SingleLevel, Stepper, StepperParams, System,
};
use crate::mesh::Mesh;
use crate::multigrid::fas::{CoarseSolve, Fas, FasParams, Smoother};
use crate::multigrid::raisov::{Raisov, RaisovParams};
use crate::multigrid::Level;
use crate::statics::implicit::ImplicitScheme;
use crate::statics::nested::{NestedLevels, StartLevel};
use std::path::Path;

/// Fewest nodes of a generated level.
const MIN_LEVEL_NODES: usize = 4;

/// The resolved `[multigrid]` section.
#[derive(Clone, Debug, PartialEq)]
pub struct Multigrid {
    /// `[multigrid] scheme` with its settings: [`Scheme::Fas`], [`Scheme::RaisovPaper`] or
    /// [`Scheme::Newton`] (a multigrid's `kinetic_limit` is set from the system when the
    /// stepper is built).
    pub scheme: Scheme,
    /// The coarser levels' meshes.
    pub meshes: LevelMeshes,
    /// Integrator of each level, level 0 first.
    pub methods: Vec<Method>,
    /// Step of each level (s), level 0 first, where `level_dt` gives them.
    pub level_dt: Option<Vec<f64>>,
}

/// How the coarser levels are made, level 0 being `[mesh]`.
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

/// Check a `[multigrid]` section and resolve it; `mesh` is level 0, `surface_files` the
/// coarser levels generated from `[mesh] surface`.
#[allow(clippy::too_many_arguments)]
pub(super) fn resolve(
    mg: &MultigridSpec,
    mesh_spec: &MeshSpec,
    mesh: &Mesh,
    method: Method,
    path: &Path,
    base: &Path,
    surface_files: Option<Vec<std::path::PathBuf>>,
    interactive: bool,
) -> Result<Multigrid> {
    // Levels generated from `[mesh] surface` (checked there) are files by now.
    let meshes = match surface_files {
        Some(f) => LevelMeshes::Files(f),
        None => resolve_meshes(mg, mesh_spec, path, base)?,
    };
    let m = meshes.count();
    let methods = match &mg.level_methods {
        None => vec![method; m],
        Some(list) if list.len() == m => list.clone(),
        Some(list) => {
            return Err(err(
                path,
                format!(
                    "`multigrid.level_methods` has {} entries for {m} levels",
                    list.len()
                ),
            ))
        }
    };
    let level_dt = match &mg.level_dt {
        None => None,
        Some(d) if d.len() == m => Some(
            d.iter()
                .enumerate()
                .map(|(i, &x)| positive(path, &format!("multigrid.level_dt[{i}]"), x))
                .collect::<Result<_>>()?,
        ),
        Some(d) => {
            return Err(err(
                path,
                format!(
                    "`multigrid.level_dt` has {} entries for {m} levels",
                    d.len()
                ),
            ))
        }
    };
    let only = |keys: &[(&str, bool)], what: &str| -> Result<()> {
        match keys.iter().find(|(_, set)| *set) {
            Some((k, _)) => Err(err(path, format!("`multigrid.{k}` applies to {what} only"))),
            None => Ok(()),
        }
    };
    // The keys of FAS alone, and of RaISoV alone.
    let keys = |names: &[&'static str]| -> Vec<(&'static str, bool)> {
        names.iter().map(|k| (*k, mg.sets(k))).collect()
    };
    let fas_keys = keys(FAS_KEYS);
    let paper_keys = keys(PAPER_KEYS);
    let kind = mg.scheme_kind(interactive);
    let scheme = match kind {
        SchemeKind::RaisovPaper => {
            only(&fas_keys, "scheme = \"fas\"")?;
            let epsilon = match mg.epsilon {
                Some(e) if e >= 0.0 => e,
                Some(e) => {
                    return Err(err(
                        path,
                        format!(
                            "`multigrid.epsilon` = {}: must be >= 0 (m)",
                            crate::numbers::compact(e)
                        ),
                    ))
                }
                None => defaults::EPSILON_PER_EDGE * mesh.edge_range().0,
            };
            Scheme::RaisovPaper(RaisovParams {
                epsilon,
                reading: mg.reading.unwrap_or(defaults::READING),
                kinetic_limit: f64::INFINITY,
            })
        }
        SchemeKind::Fas => {
            only(&paper_keys, "scheme = \"raisov-paper\"")?;
            Scheme::Fas(fas_params(mg, path)?)
        }
        SchemeKind::Newton => {
            only(&paper_keys, "scheme = \"raisov-paper\"")?;
            only(&fas_keys, "scheme = \"fas\"")?;
            let mut p = crate::statics::frames::NewtonFramesParams {
                smoother: super::StaticSolve::default_smoother(mesh.kind),
                ..Default::default()
            };
            if let Some(cg) = mg.cg_per_step {
                if cg == 0 {
                    return Err(err(
                        path,
                        "`multigrid.cg_per_step` = 0: give at least 1 (conjugate-gradient iterations per Newton step, default 2)",
                    ));
                }
                p.cg = cg;
            }
            Scheme::Newton(p)
        }
        // `[multigrid] scheme` parses the words of `SchemeKind::MULTIGRID` only.
        SchemeKind::SingleLevel | SchemeKind::ImplicitEuler | SchemeKind::Bdf2 => {
            return Err(err(
                path,
                format!(
                    "`multigrid.scheme` = \"{}\": valid are \"fas\", \"raisov-paper\", \"newton\"",
                    kind.name()
                ),
            ))
        }
    };
    if kind != SchemeKind::Newton && mg.cg_per_step.is_some() {
        return Err(err(
            path,
            "`multigrid.cg_per_step` applies to scheme = \"newton\" only",
        ));
    }
    Ok(Multigrid {
        scheme,
        meshes,
        methods,
        level_dt,
    })
}

/// The FAS settings of `[multigrid]`, [`FasParams::default`] where not given.
fn fas_params(mg: &MultigridSpec, path: &Path) -> Result<FasParams> {
    let d = FasParams::default();
    if mg.coarse_iterations == Some(0) {
        return Err(err(
            path,
            "`multigrid.coarse_iterations` = 0: give at least 1 (Chebyshev iterations per coarsest visit, default 60)",
        ));
    }
    let coarse_kind = mg.coarse.unwrap_or(match d.coarse {
        CoarseSolve::Chebyshev { .. } => CoarseKind::Chebyshev,
        CoarseSolve::Explicit { .. } => CoarseKind::Explicit,
        CoarseSolve::Newton { .. } => CoarseKind::Newton,
    });
    if mg.coarse_iterations.is_some() && coarse_kind != CoarseKind::Chebyshev {
        return Err(err(
            path,
            "`multigrid.coarse_iterations` applies to coarse = \"chebyshev\" only",
        ));
    }
    if mg.coarse_time.is_some() && coarse_kind != CoarseKind::Explicit {
        return Err(err(
            path,
            "`multigrid.coarse_time` applies to coarse = \"explicit\" only",
        ));
    }
    let coarse = match coarse_kind {
        CoarseKind::Newton => CoarseSolve::Newton {
            rel_tol: defaults::COARSE_NEWTON_TOL,
        },
        CoarseKind::Explicit => CoarseSolve::Explicit {
            time: positive(
                path,
                "multigrid.coarse_time",
                mg.coarse_time.unwrap_or(defaults::COARSE_TIME),
            )?,
        },
        CoarseKind::Chebyshev => match (mg.coarse_iterations, d.coarse) {
            (Some(iterations), CoarseSolve::Chebyshev { ratio, .. }) => {
                CoarseSolve::Chebyshev { iterations, ratio }
            }
            (_, c) => c,
        },
    };
    let smoother = match (mg.smoother, d.smoother) {
        (Some(SmootherKind::Dynamics), _) => Smoother::Dynamics,
        (
            _,
            Smoother::Chebyshev {
                ratio,
                stretch,
                scaling,
            },
        ) => Smoother::Chebyshev {
            ratio,
            stretch,
            scaling: mg.scaling.unwrap_or(scaling),
        },
        (_, s) => s,
    };
    Ok(FasParams {
        pre_smooth: mg.pre_smooth.unwrap_or(d.pre_smooth),
        post_smooth: mg.post_smooth.unwrap_or(d.post_smooth),
        coarse,
        smoother,
        weights: mg.transfer.unwrap_or(d.weights),
        krylov: mg.accelerate.map_or(d.krylov, |a| a == Accelerate::Cg),
        ..d
    })
}

/// Which levels `[multigrid]` asks for.
fn resolve_meshes(
    mg: &MultigridSpec,
    mesh: &MeshSpec,
    path: &Path,
    base: &Path,
) -> Result<LevelMeshes> {
    if let Some(ln) = &mg.level_nodes {
        if mg.files.is_some() || mg.ratio.is_some() {
            return Err(err(path, "[multigrid]: `level_nodes` gives every generated level's node count; do not combine it with `files` or `ratio`"));
        }
        if mesh.generate.is_none() {
            return Err(err(path, "[multigrid]: `level_nodes` needs [mesh] generate; for mesh files list the coarser levels in `files`"));
        }
        if ln.is_empty() {
            return Err(err(
                path,
                "`multigrid.level_nodes` is empty: list level 0's node count first",
            ));
        }
        if mesh.nodes != Some(ln[0]) {
            return Err(err(
                path,
                format!(
                    "`multigrid.level_nodes[0]` = {} must equal [mesh] nodes = {:?}",
                    ln[0], mesh.nodes
                ),
            ));
        }
        if mesh.divisions.is_some() {
            return Err(err(
                path,
                "`multigrid.level_nodes` needs [mesh] `nodes`, not `divisions`",
            ));
        }
        if let Some(n) = mg.levels {
            if n != ln.len() {
                return Err(err(
                    path,
                    format!(
                        "`multigrid.levels` = {n} but `level_nodes` lists {} levels",
                        ln.len()
                    ),
                ));
            }
        }
        if ln.iter().any(|&n| n < MIN_LEVEL_NODES) {
            return Err(err(
                path,
                format!("`multigrid.level_nodes` = {ln:?}: every level needs at least {MIN_LEVEL_NODES} nodes"),
            ));
        }
        return Ok(LevelMeshes::Nodes(ln.clone()));
    }
    let ratio = match mg.ratio {
        Some(r) if !(r > 0.0 && r < 1.0) => {
            return Err(err(
                path,
                format!(
                    "`multigrid.ratio` = {}: must be in (0, 1)",
                    crate::numbers::compact(r)
                ),
            ))
        }
        Some(r) => r,
        None => defaults::LEVEL_RATIO,
    };
    match (mg.levels, &mg.files, &mesh.generate) {
        (Some(_), Some(_), _) => Err(err(path, "[multigrid]: give `levels` (generated meshes) or `files`, not both")),
        (Some(n), None, Some(_)) if n >= 1 => Ok(LevelMeshes::Ratio { levels: n, ratio }),
        (Some(_), None, Some(_)) => Err(err(path, "`multigrid.levels` must be at least 1")),
        (Some(_), None, None) => Err(err(path, "[multigrid]: `levels` needs [mesh] generate; for mesh files list the coarser levels in `files`")),
        (None, Some(_), _) if mg.ratio.is_some() => Err(err(path, "`multigrid.ratio` applies to generated levels (`levels`), not to `files`")),
        (None, Some(f), _) => Ok(LevelMeshes::Files(f.iter().map(|f| base.join(f)).collect())),
        (None, None, _) => Err(err(path, "[multigrid]: give `levels` (with [mesh] generate) or `files` (coarser levels)")),
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

/// What [`Scenario::pick_level`] returns.
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

impl Scenario {
    /// Number of levels (1 without `[multigrid]`).
    pub fn num_levels(&self) -> usize {
        self.multigrid.as_ref().map_or(1, |mg| mg.meshes.count())
    }

    /// The level meshes, finest (the scenario's mesh) first.
    pub fn level_meshes(&self) -> Result<Vec<Mesh>> {
        Ok(self
            .level_meshes_with_ids()?
            .into_iter()
            .map(|(m, _)| m)
            .collect())
    }

    /// The level meshes, finest first, each with the file ids of its nodes where it was
    /// renumbered at load (see [`Scenario::file_ids`]).
    #[allow(clippy::type_complexity)]
    pub fn level_meshes_with_ids(&self) -> Result<Vec<(Mesh, Option<Vec<u32>>)>> {
        let mut out = vec![(self.mesh.clone(), self.file_ids.clone())];
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
        let shapes = self.coarser_shapes();
        let requested = |s: &Shape| match s {
            Shape::Rectangle { nodes, .. } | Shape::Polygon { nodes, .. } => Some(*nodes),
            _ => None,
        };
        let targets: Option<Vec<usize>> = std::iter::once(&self.mesh_source.shape)
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
        let shapes = self.coarser_shapes();
        match level
            .checked_sub(1)
            .and_then(|i| shapes.get(i).map(|s| (i, s)))
        {
            Some((i, shape)) => Ok(self.build_level(shape, i)?.0),
            None => Err(crate::error::Error::param(
                "multigrid",
                format!(
                    "level {level} does not exist: this scenario has coarser levels 1 to {}",
                    shapes.len()
                ),
            )),
        }
    }

    /// The levels of a nested start through the coarser `levels` (indices, finest first, at
    /// least one; [`crate::statics::nested::start_levels`]): each one's system (the
    /// scenario's constraints and loads carried to it) and its nodes located in the next,
    /// and the fine nodes located in the first. `known`, a level's mesh already built, is
    /// used for that level; the others are built or read ([`Scenario::level_mesh`]).
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

    /// The shapes of the coarser levels (level 1 first); none without `[multigrid]`.
    fn coarser_shapes(&self) -> Vec<Shape> {
        let Some(mg) = &self.multigrid else {
            return Vec::new();
        };
        let src = &self.mesh_source;
        match &mg.meshes {
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
        let (mesh, _, ids, _) = self.mesh_source.build(shape, &self.path, &key)?;
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
                    named("mesh.file", &self.mesh_source.shape),
                    self.mesh.kind.name()
                ),
            ));
        }
        Ok((mesh, ids))
    }

    /// Fixed nodes, prescribed motions and nodal loads of this scenario on `mesh` (a level).
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
        let (fixed, sliding) =
            super::select_fixed(mesh, &fix, &self.path, &format!("level {level}: "))?;
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

    /// The system of level `level` on its mesh `mesh` (a mesh of [`Scenario::level_meshes`]):
    /// the scenario's physics with the constraints and loads of [`Scenario::constraints_on`].
    pub fn level_system(&self, mesh: &Mesh, level: usize) -> Result<System> {
        if level == 0 {
            return self.build_system();
        }
        let c = self.constraints_on(mesh, level)?;
        build_system(self, mesh, &c.fixed, &c.sliding, &c.prescribed, &c.loads)
    }

    /// Build every level (mesh, system with its own constraints, integrator, step) and the
    /// correspondences between consecutive levels.
    pub fn build_levels(&self) -> Result<(Vec<Level>, crate::multigrid::Links)> {
        let (meshes, keys): (Vec<Mesh>, Vec<Option<Vec<u32>>>) =
            self.level_meshes_with_ids()?.into_iter().unzip();
        let m = meshes.len();
        let (methods, level_dt, paper) = match &self.multigrid {
            Some(mg) => (
                mg.methods.clone(),
                mg.level_dt.clone(),
                matches!(mg.scheme, Scheme::RaisovPaper(_)),
            ),
            None => (vec![self.method; m], None, false),
        };
        let dts: Vec<f64> = match level_dt {
            Some(d) => d,
            None if paper => vec![self.dt; m],
            None => meshes
                .iter()
                .zip(&methods)
                .enumerate()
                .map(|(i, (mesh, &me))| {
                    if i == 0 {
                        self.dt
                    } else {
                        self.safety * critical_step_estimate(mesh, &self.material, self.density, me)
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
            let mut level = Level::new(mesh, sys, methods[i], dts[i], lambda_max);
            level.node_keys = node_keys;
            levels.push(level);
        }
        Ok((levels, links))
    }

    /// The scheme [`Scenario::stepper`] builds: backward Euler or BDF2 (`[integrator] method =
    /// "implicit-euler"`, `"bdf2"`; its levels, if any, precondition the Newton solves), else
    /// `[multigrid] scheme` over the levels, else `[integrator] method`'s explicit integrator
    /// on one level. A static solve (`method = "newton"`, [`Scenario::statics`]) is run by
    /// [`super::run_static`], not by a stepper: its scheme is that of its levels, or the
    /// default integrator on one level.
    pub fn scheme(&self) -> Scheme {
        match (&self.implicit, &self.multigrid) {
            (Some(i), _) => match i.scheme {
                ImplicitScheme::BackwardEuler => Scheme::ImplicitEuler,
                ImplicitScheme::Bdf2 => Scheme::Bdf2,
            },
            (None, Some(mg)) => mg.scheme,
            (None, None) => Scheme::SingleLevel(self.method),
        }
    }

    /// The stepper of [`Scenario::scheme`]: single level (explicit, or backward Euler with the
    /// levels as the Newton solver's preconditioner), or a multigrid over its levels.
    pub fn stepper(&self) -> Result<Box<dyn Stepper>> {
        // Level 0's system and the kinetic-energy ceiling of its loads.
        let level0 = || -> Result<(System, f64)> {
            let sys = self.build_system()?;
            let limit = energy_limit_for(&sys, &self.mesh, self.blowup_factor)
                + self.blowup_factor * self.model_load_work(&self.mesh);
            Ok((sys, limit))
        };
        Ok(match self.scheme() {
            Scheme::ImplicitEuler | Scheme::Bdf2 => Box::new(self.implicit_euler()?),
            Scheme::SingleLevel(method) => {
                let (sys, limit) = level0()?;
                Box::new(SingleLevel::new(
                    sys,
                    method,
                    StepperParams {
                        dt: self.dt,
                        kinetic_limit: limit,
                    },
                ))
            }
            Scheme::Newton(p) => {
                let (sys, _) = level0()?;
                let coarse = self
                    .pick_level(crate::statics::newton::coarse_level)?
                    .chosen
                    .map(|(_, m)| m);
                Box::new(crate::statics::frames::NewtonFrames::new(
                    sys,
                    self.mesh.clone(),
                    coarse,
                    p,
                )?)
            }
            Scheme::RaisovPaper(p) => {
                let (_, limit) = level0()?;
                let (levels, links) = self.build_levels()?;
                Box::new(Raisov::new(
                    levels,
                    links,
                    RaisovParams {
                        kinetic_limit: limit,
                        ..p
                    },
                ))
            }
            Scheme::Fas(p) => {
                let (_, limit) = level0()?;
                let (levels, links) = self.build_levels()?;
                Box::new(Fas::new(
                    levels,
                    links,
                    FasParams {
                        kinetic_limit: limit,
                        ..p
                    },
                ))
            }
        })
    }
}
