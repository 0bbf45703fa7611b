//! Scenarios: a TOML file (format and defaults in [`spec`]) resolved into a [`Model`] (the
//! body and what acts on it, the type [`crate::sim::SimulationBuilder`] builds from code as
//! well) and the settings of its run, then run with measures and ParaView output
//! ([`crate::runner`]).
//!
//! [`spec::parse`] reads the text into a [`ScenarioSpec`] whose keys with named values are
//! typed already (an unknown value is an error naming the key, its line and the valid
//! values); [`Scenario::resolve`] checks every value, applies the defaults of
//! [`spec::defaults`], builds the mesh and selects the nodes. The resolved [`Scenario`] holds
//! typed values only: [`Scenario::model`] (read through the scenario: `sc.mesh` is
//! `sc.model.mesh`), whose coarser levels are rebuilt from its mesh source, selectors and
//! [`Levels`]; the scheme and step settings ([`Scenario::scheme`], [`Scenario::stepping`])
//! that [`Model::stepper`] takes; and the run's, the output's and the interactive mode's
//! settings.
//!
//! Units are SI throughout. Paths inside a scenario are relative to the scenario file.
//!
//! Node order: a mesh read from a file is renumbered once at load ([`Mesh::spatial_order`],
//! a banded order: layers across the shortest axis, rows along the longest one; `[mesh]
//! renumber = false` keeps the file's order; level files follow the same key) so that the
//! force pass's gathers and scatters find nearby nodes near in memory; files from mesh
//! generators often number nodes in an order that jumps across the mesh (the effect on the
//! force pass is measured in `bench/RESULTS.md`, runs F and H). What the user sees keeps the
//! file's ids: `nodes = [..]` selectors, `nodal_stress.csv` (rows in file order), the
//! `file_node_id` point field of the frames, the node named by `raisov inspect`
//! ([`crate::model::Model::file_ids`]). Nor do results follow the numbering beyond round-off: the FAS
//! multigrid's power-iteration start vector, the one place where an index chose a value, is
//! keyed by the file's ids ([`crate::multigrid::Level::node_keys`]), not by the memory order.

pub mod cuts;
pub mod fibres;
pub mod grasps;
pub mod interactive;
mod levels;
pub mod loading;
mod mesh_source;
mod nodal_stress;
mod patch;
mod resolve;
mod scheme;
mod settings;
pub mod spec;
pub mod surface;

use crate::error::{Error, Result};
use crate::geometry::{norm, sub};
use crate::integrate::System;
use crate::mesh::{ElementKind, Mesh};
use crate::model::err;
use crate::model::select::select_fixed;
pub use crate::model::{
    select, BoxCells, Fixing, ImplicitSolve, LevelConstraints, LevelMeshes, Levels, MeshSource,
    Model, PickedLevel, Region, Scheme, SchemeKind, Selector, Shape, Stepping,
};
use crate::numbers::{compact, rounded};
use crate::time::Motion;
use crate::time::TimeFunction;
pub use levels::Multigrid;
use mesh_source::resolve_mesh_source;
pub(crate) use nodal_stress::mesh_index_of_file;
pub use nodal_stress::read_nodal_stress;
use resolve::{resolve_fixing, resolve_material, resolve_motion, resolve_selector, NodeIds};
pub use settings::{
    IntegratorSettings, OutputSettings, Reference, RunSettings, StaticSolve, StopRule,
};
/// Moved to [`crate::runner`]: the run in time ([`crate::runner::dynamic`]) and the static
/// solve ([`crate::runner::statics`]).
#[allow(deprecated)]
#[deprecated(since = "0.2.0", note = "use `raisov::runner`")]
pub mod run {
    pub use crate::runner::compat::describe_static;
    pub use crate::runner::compat::run;
    pub use crate::runner::compat::run_static;
    pub use crate::runner::compat::run_static_keeping;
    pub use crate::runner::compat::run_with;
    pub use crate::runner::Progress;
    pub use crate::runner::RunOptions;
    pub use crate::runner::RunSummary;
    pub use crate::runner::StaticSummary;
    pub use crate::runner::StopReason;
    pub use crate::scenario::read_nodal_stress;
}
#[allow(deprecated)]
pub use run::{
    describe_static, run, run_static, run_static_keeping, run_with, RunOptions, RunSummary,
    StaticSummary, StopReason,
};
use spec::defaults;
pub use spec::{NewtonSmoother, ScenarioSpec, StaticSolver};
use std::path::Path;

/// The multigrid schemes of `[multigrid] scheme`, now variants of the one [`Scheme`].
#[deprecated(
    note = "use `raisov::Scheme` (`Scheme::Fas`, `Scheme::RaisovPaper`, `Scheme::Newton`)"
)]
pub type MultigridScheme = Scheme;

/// A resolved scenario, ready to run.
#[derive(Clone, Debug)]
pub struct Scenario {
    /// The body and what acts on it ([`Model`]); its fields read through the scenario
    /// (`sc.mesh` is `sc.model.mesh`).
    pub model: Model,
    /// `name`, or the file's stem made valid ([`crate::io::NAME_RULE`]): it names the files
    /// under the output directory.
    pub name: String,
    /// Notes from loading (reoriented elements, dropped nodes), for the user.
    pub notes: Vec<String>,
    /// What looks wrong but is allowed: a step far above the estimated critical one, a run
    /// too long to finish, a point selector far from the mesh, a mesh whose size suggests
    /// the wrong unit.
    pub warnings: Vec<String>,
    /// `[integrator]`: the integrator, its step, or the static solve.
    pub integrator: IntegratorSettings,
    /// `[run]`: how a run ends.
    pub run: RunSettings,
    /// `[output]`: where and how a run writes its results.
    pub output: OutputSettings,
    /// `[multigrid]`: the levels and the scheme; `None` for a single level.
    pub multigrid: Option<Multigrid>,
    /// `[interactive]`: a budget per frame along the displacement paths; `None` for a plain run.
    pub interactive: Option<interactive::Interactive>,
    /// The grasps the interactive run takes and lets go ([`grasps`]): `[[displace]]` entries
    /// with `start`, `release` or `stiffness`, in file order (not in [`crate::model::Model::prescribed`]).
    pub grasps: Vec<grasps::Grasp>,
    /// `[[pin]]`: the pins the interactive run takes ([`grasps`]), in file order.
    pub pins: Vec<grasps::Pin>,
    /// `[[cut]]`: the cuts made during the run ([`cuts`]), in file order.
    pub cuts: Vec<cuts::Cut>,
    /// `[mesh] surface`: the surface the levels were generated from, written with every
    /// frame ([`surface`]); `None` for other meshes.
    pub surface: Option<surface::VisualSurface>,
}

/// A scenario reads as its model: `sc.mesh`, `sc.material`, `sc.fix`, ... are the fields
/// of [`Scenario::model`], and [`Model`]'s methods (`sc.build_system()`, `sc.level_meshes()`,
/// `sc.wrap_loads(..)`) apply to it.
impl std::ops::Deref for Scenario {
    type Target = Model;
    fn deref(&self) -> &Model {
        &self.model
    }
}

impl std::ops::DerefMut for Scenario {
    fn deref_mut(&mut self) -> &mut Model {
        &mut self.model
    }
}

fn positive(path: &Path, key: &str, v: f64) -> Result<f64> {
    if v > 0.0 && v.is_finite() {
        Ok(v)
    } else {
        Err(err(
            path,
            format!("`{key}` = {}: must be a positive number", compact(v)),
        ))
    }
}

/// The scenario's name: `name` checked against [`crate::io::NAME_RULE`] (it names the files
/// under the output directory and, by default, the directory), or, not given, the file's
/// stem made valid ([`crate::io::name_from_stem`]) with a note where that changed it.
fn scenario_name(path: &Path, given: Option<&str>) -> Result<(String, Option<String>)> {
    if let Some(name) = given {
        crate::io::check_name(name).map_err(|e| {
            err(
                path,
                format!("`name`: {e} (it names the files under the output directory)"),
            )
        })?;
        return Ok((name.to_string(), None));
    }
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let name = crate::io::name_from_stem(&stem, defaults::NAME);
    let note = (name != stem && !stem.is_empty()).then(|| {
        format!(
            "`name` not given: the file's stem {stem:?} is not a valid name ({}), so the \
             scenario is named {name:?}",
            crate::io::NAME_RULE
        )
    });
    Ok((name, note))
}

impl Scenario {
    /// Read, parse and resolve a scenario file.
    pub fn load(path: &Path) -> Result<Scenario> {
        Self::load_with_out(path, None)
    }

    /// [`crate::model::Model::load`] with the output directory `out` instead of `[output] dir` (as
    /// `raisov run --out`); the levels of `[mesh] surface` are cached under it.
    pub fn load_with_out(path: &Path, out: Option<&Path>) -> Result<Scenario> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Self::resolve_with_out(spec::parse(&text, path)?, path, out)
    }

    /// Parse and resolve scenario text; `path` names it in messages and anchors relative paths.
    pub fn from_toml(text: &str, path: &Path) -> Result<Scenario> {
        Self::resolve(spec::parse(text, path)?, path)
    }

    /// Resolve a parsed spec: check every value, apply the defaults ([`spec::defaults`]),
    /// build the mesh and select the constrained and loaded nodes.
    pub fn resolve(spec: ScenarioSpec, path: &Path) -> Result<Scenario> {
        Self::resolve_with_out(spec, path, None)
    }

    /// [`Scenario::resolve`] with the output directory `out` instead of `[output] dir`.
    pub fn resolve_with_out(
        spec: ScenarioSpec,
        path: &Path,
        out: Option<&Path>,
    ) -> Result<Scenario> {
        let base = path.parent().unwrap_or(Path::new("."));
        let (name, name_note) = scenario_name(path, spec.name.as_deref())?;
        let output = settings::resolve_output(&spec, path, base, &name, out)?;
        let out_dir = &output.dir;
        let surface_levels = match &spec.mesh.surface {
            Some(_) if spec.mesh.file.is_some() || spec.mesh.generate.is_some() => {
                return Err(err(
                    path,
                    "[mesh]: give one of `file`, `generate` or `surface`, not several",
                ))
            }
            Some(_) => Some(surface::prepare(
                &spec.mesh,
                spec.multigrid.as_ref(),
                path,
                base,
                out_dir,
            )?),
            None => None,
        };
        let mesh_source = match &surface_levels {
            Some(sl) => MeshSource {
                shape: Shape::File(sl.files[0].clone()),
                scale: 1.0,
                renumber_files: spec.mesh.renumber.unwrap_or(defaults::RENUMBER_FILES),
                renumber_generated: spec.mesh.renumber.unwrap_or(defaults::RENUMBER_GENERATED),
            },
            None => resolve_mesh_source(&spec.mesh, path, base)?,
        };
        let (mesh, mut notes, file_ids, node_labels) =
            mesh_source.build(&mesh_source.shape, path, "mesh.file")?;
        let mut warnings = Vec::new();
        let (lo, hi) = mesh.bounding_box();
        let diag = norm(sub(hi, lo));
        if !(1e-3..=20.0).contains(&diag) {
            warnings.push(format!(
                "the mesh spans {diag:.3e} m (bounding-box diagonal): {}; coordinates are \
                 multiplied by [mesh] scale = {} to get metres",
                if diag > 20.0 {
                    "millimetres read as metres? (scale = 1e-3 converts mm)"
                } else {
                    "a unit too small? (scale = 1e-3 means mm, 1e-2 cm)"
                },
                compact(mesh_source.scale)
            ));
        }
        // A point selector far outside the mesh picks a node nobody meant.
        let far = |p: [f64; 3], key: &str, warnings: &mut Vec<String>| {
            let out = (0..3)
                .map(|k| (lo[k] - p[k]).max(p[k] - hi[k]).max(0.0))
                .map(|d| d * d)
                .sum::<f64>()
                .sqrt();
            if out > 0.1 * diag {
                let near = mesh.nearest_node(p).map(|a| mesh.nodes[a]);
                warnings.push(format!(
                    "{key}: point {p:?} lies {out:.3e} m outside the mesh's bounding box \
                     (diagonal {diag:.3e} m); it selects the nearest node, at {near:?}"
                ));
            }
        };
        if let Some(sl) = &surface_levels {
            notes.splice(0..0, sl.notes.iter().cloned());
        }
        notes.splice(0..0, name_note);
        // Node-id selectors name the file's ids: into the mesh's order, once, here.
        let new_of = file_ids.as_deref().map(crate::mesh::inverse_order);
        let ids = NodeIds::new(node_labels.as_deref(), mesh.num_nodes(), &mesh_source.shape);
        let mut selector = |r: &spec::RegionSpec, key: &str| -> Result<Selector> {
            let s = resolve_selector(r, path, key)?;
            Ok(match s {
                Selector::Nodes(ns) => {
                    let ks = ids.index_of(&r.nodes.clone().unwrap_or_default(), path, key)?;
                    debug_assert_eq!(ks.len(), ns.len());
                    Selector::Nodes(match &new_of {
                        Some(new_of) => ks.iter().map(|&a| new_of[a as usize]).collect(),
                        None => ks,
                    })
                }
                Selector::Point(p) => {
                    far(p, key, &mut warnings);
                    s
                }
                s => s,
            })
        };
        let mut fix = Vec::with_capacity(spec.fix.len());
        for (i, r) in spec.fix.iter().enumerate() {
            let key = format!("fix[{i}]");
            fix.push((selector(r, &key)?, resolve_fixing(r, path, &key)?));
        }
        let mut load = Vec::with_capacity(spec.load.len());
        let mut timed_load = Vec::new();
        for (i, l) in spec.load.iter().enumerate() {
            let key = format!("load[{i}].at");
            if l.at.components.is_some() || l.at.normal.is_some() {
                return Err(err(
                    path,
                    format!("{key}: `components` and `normal` belong to [[fix]], not to a load's selector"),
                ));
            }
            let time = match &l.time {
                Some(t) => loading::resolve_time(t, path, &format!("load[{i}].time"))?,
                None => TimeFunction::Constant,
            };
            if time == TimeFunction::Constant {
                load.push((selector(&l.at, &key)?, l.force));
            } else {
                timed_load.push((selector(&l.at, &key)?, l.force, time));
            }
        }
        let mut surface_loads = Vec::new();
        for (i, s) in spec.pressure.iter().enumerate() {
            surface_loads.push(loading::resolve_surface_load(s, false, path, i)?);
        }
        for (i, s) in spec.traction.iter().enumerate() {
            surface_loads.push(loading::resolve_surface_load(s, true, path, i)?);
        }
        let mut tools = Vec::new();
        for (i, t) in spec.tool.iter().enumerate() {
            tools.push(loading::resolve_tool(t, path, i)?);
        }
        let material =
            resolve_material(&spec.material, mesh.kind, spec.interactive.is_some(), path)?;
        let fibres = fibres::resolve(
            spec.material.fibre.as_ref(),
            &mesh,
            &mesh_source.shape,
            path,
        )?;
        let density = positive(
            path,
            "material.density",
            spec.material.density.unwrap_or(defaults::DENSITY),
        )?;
        let thickness = positive(
            path,
            "material.thickness",
            spec.material.thickness.unwrap_or(defaults::THICKNESS),
        )?;
        if mesh.kind == ElementKind::Tet4 && spec.material.thickness.is_some() {
            return Err(err(
                path,
                "`material.thickness` applies to membranes only; this mesh is tetrahedral",
            ));
        }
        let alpha = match (spec.damping.alpha, spec.damping.ratio, spec.damping.omega) {
            (Some(a), None, None) if a >= 0.0 && a.is_finite() => a,
            (Some(a), None, None) => return Err(err(path, format!("`damping.alpha` = {}: must be >= 0 (1/s)", compact(a)))),
            (None, Some(z), Some(w)) => 2.0 * positive(path, "damping.ratio", z)? * positive(path, "damping.omega", w)?,
            (None, None, None) => defaults::ALPHA,
            _ => {
                return Err(err(
                    path,
                    "[damping]: give either `alpha` (1/s) or both `ratio` and `omega` (rad/s), not a mix",
                ))
            }
        };
        let gravity = spec.gravity.unwrap_or(defaults::GRAVITY);
        let (fixed, sliding) = select_fixed(&mesh, &fix, path, "")?;
        let mut loads = Vec::new();
        for (i, (s, force)) in load.iter().enumerate() {
            for n in select(&mesh, s, path, &format!("load[{i}].at"))? {
                loads.push((n, *force));
            }
        }
        let mut prescribed: Vec<(u32, Motion)> = Vec::new();
        let mut grasps = Vec::new();
        for (i, d) in spec.displace.iter().enumerate() {
            let key = format!("displace[{i}]");
            far(d.point, &key, &mut warnings);
            if grasps::is_grasp(d) {
                // Taken during the run, on the deformed surface (grasps.rs).
                let interactive = spec.interactive.is_some();
                grasps.push(grasps::resolve_grasp(d, i, path, interactive)?);
                continue;
            }
            let motion = resolve_motion(d, path, &key)?;
            if let Some(r) = d.radius {
                // A surface patch (patch.rs): the free surface nodes within `r`.
                if !(r >= 0.0 && r.is_finite()) {
                    return Err(err(
                        path,
                        format!("{key}: `radius` = {}: must be >= 0 (m)", compact(r)),
                    ));
                }
                let (g, mut nodes) = patch::surface_patch(&mesh, d.point, r)
                    .ok_or_else(|| err(path, format!("{key}: the mesh has no surface")))?;
                nodes.retain(|a| !fixed.contains(a) && !prescribed.iter().any(|(n, _)| n == a));
                if nodes.is_empty() {
                    return Err(err(path, format!("{key}: every surface node within `radius` = {r} m of {g:?} is fixed or prescribed by an earlier [[displace]]")));
                }
                prescribed.extend(nodes.into_iter().map(|a| (a, motion.clone())));
                continue;
            }
            let node = mesh
                .nearest_node(d.point)
                .ok_or_else(|| err(path, "the mesh has no nodes"))? as u32;
            if prescribed.iter().any(|(n, _)| *n == node) {
                let k = file_ids.as_ref().map_or(node, |f| f[node as usize]);
                let shown = node_labels.as_ref().map_or(k as u64, |l| l[k as usize]);
                return Err(err(path, format!("{key}: node {shown} (nearest to {:?}) is already prescribed by an earlier [[displace]]", d.point)));
            }
            prescribed.push((node, motion));
        }
        let mut pins = Vec::with_capacity(spec.pin.len());
        for (i, p) in spec.pin.iter().enumerate() {
            far(p.point, &format!("pin[{i}]"), &mut warnings);
            pins.push(grasps::resolve_pin(p, i, path, spec.interactive.is_some())?);
        }
        let mut model = Model {
            path: path.to_path_buf(),
            mesh,
            mesh_source: Some(mesh_source),
            levels: Levels::Single,
            material,
            fibres,
            density,
            thickness,
            precision: spec.integrator.precision.unwrap_or_default(),
            alpha,
            gravity,
            fix,
            load,
            timed_load,
            surface_loads,
            tools,
            fixed,
            sliding,
            loads,
            prescribed,
            file_ids,
            node_labels,
        };
        let integrator =
            settings::resolve_integrator(&spec, path, &model, &mut notes, &mut warnings)?;
        let newton = integrator.statics.is_some();
        let run = settings::resolve_run(&spec, path, newton)?;
        let (multigrid, levels) = match spec
            .multigrid
            .as_ref()
            .map(|mg| {
                let surface_files = surface_levels.as_ref().map(|sl| sl.files[1..].to_vec());
                levels::resolve(
                    mg,
                    &spec.mesh,
                    &model.mesh,
                    integrator.method,
                    path,
                    base,
                    surface_files,
                    spec.interactive.is_some(),
                )
            })
            .transpose()?
        {
            Some((mg, meshes)) => (Some(mg), Levels::Built(meshes)),
            None => (None, Levels::Single),
        };
        let interactive = spec
            .interactive
            .as_ref()
            .map(|i| interactive::Interactive::from_spec(path, i))
            .transpose()?;
        if spec.interactive.is_none() && !newton {
            let t_end = match run.stop {
                StopRule::Duration(d) => d,
                StopRule::Steady { max, .. } => max,
            };
            let dt = integrator.dt;
            let steps = t_end / dt;
            let work = steps * model.mesh.num_nodes() as f64;
            if work > TOO_LONG_WORK {
                warnings.push(format!(
                    "{steps:.3e} steps of dt = {dt:.3e} s to simulate {} s on {} nodes: \
                     about {} hours at {:.0e} node-steps/s (a fast single thread); raise \
                     `integrator.dt` or shorten `run.duration`",
                    compact(t_end),
                    model.mesh.num_nodes(),
                    rounded(work / NODE_STEPS_PER_SECOND / 3600.0, 0),
                    NODE_STEPS_PER_SECOND
                ));
            }
        }
        model.levels = levels;
        let sc = Scenario {
            model,
            name,
            notes,
            warnings,
            integrator,
            run,
            output,
            multigrid,
            interactive,
            grasps,
            pins,
            cuts: cuts::resolve(&spec, path)?,
            surface: surface_levels.map(|sl| sl.visual),
        };
        sc.check_model_loads()?;
        cuts::check(&sc)?;
        // A reference file is read (and its numbers checked) now, not when the run needs it.
        if let Reference::File(p) = &sc.output.reference {
            read_nodal_stress(p, &sc)?;
        }
        Ok(sc)
    }
}

/// Assemble a system on `mesh` with the scenario's physics and the given constraints and
/// nodal loads: [`Model::system_on`].
#[deprecated(
    since = "0.2.0",
    note = "use `Model::system_on` (`sc.model.system_on(..)`)"
)]
pub fn build_system(
    sc: &Scenario,
    mesh: &Mesh,
    fixed: &[u32],
    sliding: &[(u32, [f64; 3])],
    prescribed: &[(u32, Motion)],
    loads: &[(u32, [f64; 3])],
) -> Result<System> {
    sc.model.system_on(mesh, fixed, sliding, prescribed, loads)
}

/// Node-steps per second of a fast single thread (the standard force pass measures 2-4e7,
/// `raisov bench`): the rate behind the "too long" warning.
const NODE_STEPS_PER_SECOND: f64 = 2e7;
/// Node-steps (steps × nodes) above which a run warns that it takes too long: a day at
/// [`NODE_STEPS_PER_SECOND`].
const TOO_LONG_WORK: f64 = 24.0 * 3600.0 * NODE_STEPS_PER_SECOND;

#[cfg(test)]
mod tests;
