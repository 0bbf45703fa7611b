//! Scenarios: a TOML file (format and defaults in [`spec`]) resolved into a mesh, a
//! [`System`] and run settings, then run with measures and ParaView output ([`run`]).
//!
//! Units are SI throughout. Paths inside a scenario are relative to the scenario file.
//!
//! Node order: a mesh read from a file is renumbered once at load ([`Mesh::spatial_order`],
//! a banded order: layers across the shortest axis, rows along the longest one; `[mesh]
//! renumber = false` keeps the file's order; level files follow the same key) so that the
//! force pass's gathers and scatters find nearby nodes near in memory; files from mesh
//! generators often number nodes in an order that jumps across the mesh. Measured when
//! renumbering came in (Morton order then; force pass, node-evaluations/s, 1 thread,
//! alternated): liver L0 20.7-20.9 M as numbered in the file, 22.8-22.9 M renumbered; heart
//! L0 22.8-23.0 M and 24.2-24.3 M; the standard 100k box with its nodes shuffled at random,
//! 2 threads, 29.7-30.0 M and 37.5-38.0 M (40.6 M as generated). The liver grasp example on
//! liver L0 (0.2 s): 4.19-4.24 s against 4.56-4.62 s on 1 thread, the same printed results.
//! The banded order replaced Morton's when the 1M box, shuffled, ran at 11.1 M
//! node-updates/s in Morton order and 20.1 M banded (1 thread; 100k: 21.5 M and 24.8 M;
//! liver and heart L0 within 3 % of each other). What the user sees
//! keeps the file's ids: `nodes = [..]` selectors, `nodal_stress.csv` (rows in file order),
//! the `file_node_id` point field of the frames, the node named by `raisov inspect`
//! ([`Scenario::file_ids`]). Nor do results follow the numbering beyond round-off: the FAS
//! multigrid's power-iteration start vector, the one place where an index chose a value,
//! is keyed by the file's ids ([`crate::multigrid::Level::node_keys`]). Before, FAS kept the
//! file's order, since renumbering the liver levels had moved the interactive example's mean
//! lag from 2.0 to 2.4 mm through that vector.

pub mod interactive;
mod levels;
pub mod run;
pub mod spec;

use crate::error::{Error, Result};
use crate::fem::{FemModel, FemParams, Precision};
use crate::integrate::{Constraints, Method, Motion, System};
use crate::io::{load_mesh, VtuFormat};
use crate::material::{
    lame, Material, MooneyRivlin, NeoHookean, StVenantKirchhoff, VerondaWestmann,
};
use crate::mesh::generate::{
    box_tets, box_tets_target, polygon_membrane, rectangle_membrane, BoxPattern,
};
use crate::mesh::{dot, norm, sub, ElementKind, Mesh};
pub use levels::LevelConstraints;
pub use run::{run, run_with, RunOptions, RunSummary, StopReason};
pub use spec::ScenarioSpec;
use std::path::{Path, PathBuf};

/// How a run ends.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StopRule {
    /// Run for this much simulated time (s).
    Duration(f64),
    /// Run until kinetic energy and residual fall below the tolerances (relative to their
    /// peaks), or until `max` simulated seconds.
    Steady {
        kinetic_tol: f64,
        residual_tol: f64,
        max: f64,
    },
}

/// Where |T − T∞| takes T∞ from.
#[derive(Clone, Debug, PartialEq)]
pub enum Reference {
    None,
    /// Compute the steady state first, to a tolerance far below the run's.
    Auto,
    /// A `nodal_stress.csv` written by an earlier run on the same mesh.
    File(PathBuf),
}

/// A resolved scenario, ready to run.
#[derive(Clone, Debug)]
pub struct Scenario {
    pub name: String,
    pub path: PathBuf,
    pub mesh: Mesh,
    /// Notes from loading (reoriented elements, dropped nodes), for the user.
    pub notes: Vec<String>,
    pub material: Material,
    pub density: f64,
    pub thickness: f64,
    pub alpha: f64,
    pub gravity: [f64; 3],
    pub fixed: Vec<u32>,
    pub loads: Vec<(u32, [f64; 3])>,
    pub prescribed: Vec<(u32, Motion)>,
    /// `[mesh] renumber`: node `k` of [`Scenario::mesh`] is node `file_ids[k]` of the file
    /// (in file order after unused nodes are dropped, the ids `nodes = [..]` selectors and
    /// the outputs use); `None` where the mesh keeps the file's order.
    pub file_ids: Option<Vec<u32>>,
    pub method: Method,
    /// Time step (s), given or estimated.
    pub dt: f64,
    /// The estimated critical step (s) the default `dt` derives from.
    pub dt_critical_estimate: f64,
    /// `[integrator] precision`: storage precision of the packed tetrahedron data.
    pub precision: Precision,
    pub stop: StopRule,
    pub blowup_factor: f64,
    pub out_dir: PathBuf,
    pub frame_interval: f64,
    pub csv_every: u64,
    /// `[output] vtu`: how the frames are stored (binary appended zlib, or ASCII).
    pub vtu: VtuFormat,
    pub reference: Reference,
    /// `[interactive]`: a budget per frame along the displacement paths; `None` for a plain run.
    pub interactive: Option<interactive::Interactive>,
    /// The parsed file, for what is re-resolved per multigrid level.
    pub spec: ScenarioSpec,
}

fn err(path: &Path, msg: impl Into<String>) -> Error {
    Error::Scenario {
        path: path.to_path_buf(),
        line: None,
        msg: msg.into(),
    }
}

fn positive(path: &Path, key: &str, v: f64) -> Result<f64> {
    if v > 0.0 && v.is_finite() {
        Ok(v)
    } else {
        Err(err(
            path,
            format!("`{key}` = {v}: must be a positive number"),
        ))
    }
}

impl Scenario {
    /// Read, parse and resolve a scenario file.
    pub fn load(path: &Path) -> Result<Scenario> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Self::from_toml(&text, path)
    }

    /// Parse and resolve scenario text; `path` names it in messages and anchors relative paths.
    pub fn from_toml(text: &str, path: &Path) -> Result<Scenario> {
        let spec: ScenarioSpec = toml::from_str(text).map_err(|e| {
            let line = e.span().map(|s| text[..s.start].matches('\n').count() + 1);
            Error::Scenario {
                path: path.to_path_buf(),
                line,
                msg: e.message().trim().to_string(),
            }
        })?;
        Self::resolve(spec, path)
    }

    /// Resolve a parsed spec.
    pub fn resolve(spec: ScenarioSpec, path: &Path) -> Result<Scenario> {
        let base = path.parent().unwrap_or(Path::new("."));
        let name = spec.name.clone().unwrap_or_else(|| {
            path.file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "scenario".into())
        });
        let (mesh, mut notes, file_ids) = resolve_mesh(&spec.mesh, path, base)?;
        // Node-id selectors name file ids: into the mesh's order, once, here (the stored spec
        // then names the mesh's nodes, as the per-level constraints expect).
        let mut spec = spec;
        if let Some(order) = &file_ids {
            let new_of = crate::mesh::inverse_order(order);
            let map = |r: &mut spec::RegionSpec, key: &str| -> Result<()> {
                if let Some(ns) = &mut r.nodes {
                    check_node_ids(ns, mesh.num_nodes(), path, key)?;
                    ns.iter_mut().for_each(|a| *a = new_of[*a as usize]);
                }
                Ok(())
            };
            for (i, r) in spec.fix.iter_mut().enumerate() {
                map(r, &format!("fix[{i}]"))?;
            }
            for (i, l) in spec.load.iter_mut().enumerate() {
                map(&mut l.at, &format!("load[{i}].at"))?;
            }
        }
        if let Some(mg) = &spec.multigrid {
            levels::validate(mg, &spec.mesh, path)?;
        }
        let material = resolve_material(&spec.material, mesh.kind, path)?;
        let density = positive(
            path,
            "material.density",
            spec.material.density.unwrap_or(1000.0),
        )?;
        let thickness = positive(
            path,
            "material.thickness",
            spec.material.thickness.unwrap_or(1e-3),
        )?;
        if mesh.kind == ElementKind::Tet4 && spec.material.thickness.is_some() {
            return Err(err(
                path,
                "`material.thickness` applies to membranes only; this mesh is tetrahedral",
            ));
        }
        let alpha = match (spec.damping.alpha, spec.damping.ratio, spec.damping.omega) {
            (Some(a), None, None) if a >= 0.0 && a.is_finite() => a,
            (Some(a), None, None) => return Err(err(path, format!("`damping.alpha` = {a}: must be >= 0 (1/s)"))),
            (None, Some(z), Some(w)) => 2.0 * positive(path, "damping.ratio", z)? * positive(path, "damping.omega", w)?,
            (None, None, None) => 0.0,
            _ => {
                return Err(err(
                    path,
                    "[damping]: give either `alpha` (1/s) or both `ratio` and `omega` (rad/s), not a mix",
                ))
            }
        };
        let gravity = spec.gravity.unwrap_or([0.0; 3]);
        let mut fixed = Vec::new();
        for (i, r) in spec.fix.iter().enumerate() {
            let sel = select(&mesh, r, path, &format!("fix[{i}]"))?;
            fixed.extend(sel);
        }
        let mut loads = Vec::new();
        for (i, l) in spec.load.iter().enumerate() {
            for n in select(&mesh, &l.at, path, &format!("load[{i}].at"))? {
                loads.push((n, l.force));
            }
        }
        let mut prescribed: Vec<(u32, Motion)> = Vec::new();
        for (i, d) in spec.displace.iter().enumerate() {
            let key = format!("displace[{i}]");
            let node = mesh
                .nearest_node(d.point)
                .ok_or_else(|| err(path, "the mesh has no nodes"))? as u32;
            let motion = resolve_motion(d, path, &key)?;
            if prescribed.iter().any(|(n, _)| *n == node) {
                let shown = file_ids.as_ref().map_or(node, |f| f[node as usize]);
                return Err(err(path, format!("{key}: node {shown} (nearest to {:?}) is already prescribed by an earlier [[displace]]", d.point)));
            }
            prescribed.push((node, motion));
        }
        let method = match spec.integrator.method.as_deref() {
            None => Method::SymplecticEuler,
            Some(m) => Method::ALL
                .into_iter()
                .find(|x| x.name() == m)
                .ok_or_else(|| err(path, format!("`integrator.method` = \"{m}\": valid are forward-euler, symplectic-euler, rk4, central-difference")))?,
        };
        let precision = match spec.integrator.precision.as_deref() {
            None => Precision::F64,
            Some(p) => Precision::from_name(p).ok_or_else(|| {
                err(
                    path,
                    format!("`integrator.precision` = \"{p}\": valid are \"f64\", \"f32-storage\""),
                )
            })?,
        };
        if precision != Precision::F64
            && !(mesh.kind == ElementKind::Tet4 && matches!(material, Material::NeoHookean(_)))
        {
            notes.push(format!(
                "integrator.precision = \"{}\" applies to neo-Hookean tetrahedra only; this model runs in f64",
                precision.name()
            ));
        }
        let dt_crit = critical_step_estimate(&mesh, &material, density, method);
        let safety = positive(
            path,
            "integrator.safety",
            spec.integrator.safety.unwrap_or(0.5),
        )?;
        let dt = match spec.integrator.dt {
            Some(dt) => positive(path, "integrator.dt", dt)?,
            None => safety * dt_crit,
        };
        let duration = spec
            .run
            .duration
            .map(|d| positive(path, "run.duration", d))
            .transpose()?;
        let stop = match spec.run.stop.as_deref().unwrap_or("duration") {
            "duration" => StopRule::Duration(duration.ok_or_else(|| {
                err(
                    path,
                    "[run]: `duration` (s) is required when stop = \"duration\"",
                )
            })?),
            "steady" => StopRule::Steady {
                kinetic_tol: positive(
                    path,
                    "run.kinetic_tol",
                    spec.run.kinetic_tol.unwrap_or(1e-8),
                )?,
                residual_tol: positive(
                    path,
                    "run.residual_tol",
                    spec.run.residual_tol.unwrap_or(1e-4),
                )?,
                max: duration.unwrap_or(60.0),
            },
            other => {
                return Err(err(
                    path,
                    format!("`run.stop` = \"{other}\": valid are \"duration\", \"steady\""),
                ))
            }
        };
        let blowup_factor = positive(
            path,
            "run.blowup_factor",
            spec.run.blowup_factor.unwrap_or(1e3),
        )?;
        let out_dir = spec
            .output
            .dir
            .as_ref()
            .map(|d| base.join(d))
            .unwrap_or_else(|| PathBuf::from("raisov-out").join(&name));
        let frame_interval = spec.output.frame_interval.unwrap_or(0.05);
        if !(frame_interval >= 0.0 && frame_interval.is_finite()) {
            return Err(err(
                path,
                format!("`output.frame_interval` = {frame_interval}: must be >= 0 (s)"),
            ));
        }
        let interactive = spec
            .interactive
            .as_ref()
            .map(|i| interactive::Interactive::from_spec(path, i))
            .transpose()?;
        let csv_every = spec.output.csv_every.unwrap_or(1);
        if csv_every == 0 {
            return Err(err(
                path,
                "`output.csv_every` = 0: must be at least 1 (steps)",
            ));
        }
        let vtu = match spec.output.vtu.as_deref() {
            None => VtuFormat::Binary,
            Some(v) => VtuFormat::parse(v).ok_or_else(|| {
                err(
                    path,
                    format!("`output.vtu` = \"{v}\": valid are \"binary\", \"ascii\""),
                )
            })?,
        };
        let reference = match spec.output.reference.as_deref() {
            None | Some("none") => Reference::None,
            Some("auto") => Reference::Auto,
            Some(p) => {
                let p = base.join(p);
                if !p.is_file() {
                    return Err(err(path, format!("`output.reference` = {}: no such file (valid: \"none\", \"auto\", or a nodal_stress.csv of an earlier run)", p.display())));
                }
                Reference::File(p)
            }
        };
        Ok(Scenario {
            name,
            path: path.to_path_buf(),
            mesh,
            notes,
            material,
            density,
            thickness,
            alpha,
            gravity,
            fixed,
            loads,
            prescribed,
            file_ids,
            method,
            dt,
            dt_critical_estimate: dt_crit,
            precision,
            stop,
            blowup_factor,
            out_dir,
            frame_interval,
            csv_every,
            vtu,
            reference,
            interactive,
            spec,
        })
    }

    /// The file's id of node `a` of [`Scenario::mesh`] (see [`Scenario::file_ids`]).
    pub fn file_node(&self, a: u32) -> u32 {
        self.file_ids.as_ref().map_or(a, |f| f[a as usize])
    }

    /// FE parameters of this scenario.
    pub fn fem_params(&self) -> FemParams {
        let mut p = FemParams::new(self.material.clone());
        p.density = self.density;
        p.thickness = self.thickness;
        p.precision = self.precision;
        p
    }

    /// Assemble the system M ü + α M u̇ + R(u) = V of the finest mesh.
    pub fn build_system(&self) -> Result<System> {
        build_system(self, &self.mesh, &self.fixed, &self.prescribed, &self.loads)
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

/// Assemble a system on `mesh` with the scenario's physics (material, density, damping,
/// gravity) and the given constraints and nodal loads.
pub fn build_system(
    sc: &Scenario,
    mesh: &Mesh,
    fixed: &[u32],
    prescribed: &[(u32, Motion)],
    loads: &[(u32, [f64; 3])],
) -> Result<System> {
    let fem = FemModel::new(mesh, sc.fem_params())?;
    let mass = fem.lumped_mass();
    let n = mesh.num_nodes();
    let mut sys = System::new(
        Box::new(fem),
        mass,
        sc.alpha,
        vec![0.0; 3 * n],
        Constraints::new(fixed.to_vec(), prescribed.to_vec()),
    );
    sys.add_gravity(sc.gravity);
    for &(a, f) in loads {
        for k in 0..3 {
            sys.f_ext[3 * a as usize + k] += f[k];
        }
    }
    Ok(sys)
}

/// Estimated critical time step `bound / ω_max` (`bound` = 2 for the symplectic schemes,
/// 2√2 for RK4), with the element-wise upper bound on the highest frequency of lumped-mass
/// linear elements
///
/// ```text
/// ω_max² ≤ max_e  npe c² Σ_a |∇N_a|²,     c² = Material::stability_modulus / ρ
/// ```
///
/// (the element stiffness is at most `P V Σ|∇N_a|²` in norm and each node carries `ρV/npe`).
/// Hyperelastic laws stiffen under large stretch, hence the scenario's safety factor on top.
pub fn critical_step_estimate(
    mesh: &Mesh,
    material: &Material,
    density: f64,
    method: Method,
) -> f64 {
    let c2 = material.stability_modulus(mesh.kind) / density;
    method.stability_bound() / (c2 * max_gradient_sum(mesh)).sqrt()
}

/// `max_e npe Σ_a |∇N_a|²` over the elements (1/m²).
pub fn max_gradient_sum(mesh: &Mesh) -> f64 {
    crate::fem::gradient_sums(mesh)
        .into_iter()
        .fold(0.0, f64::max)
}

/// Smallest element altitude: tets `3V / max face area`, triangles `2A / max edge`.
pub fn min_altitude(mesh: &Mesh) -> f64 {
    let mut h = f64::INFINITY;
    for e in 0..mesh.num_elements() {
        let p = mesh.element_points(e);
        let a = match mesh.kind {
            ElementKind::Tri3 => {
                let area = crate::mesh::tri_area(p[0], p[1], p[2]);
                2.0 * area / mesh.element_max_edge(e)
            }
            ElementKind::Tet4 => {
                let v = crate::mesh::tet_volume(p[0], p[1], p[2], p[3]).abs();
                let fmax = [(0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)]
                    .iter()
                    .map(|&(i, j, k)| crate::mesh::tri_area(p[i], p[j], p[k]))
                    .fold(0.0, f64::max);
                3.0 * v / fmax
            }
        };
        h = h.min(a);
    }
    h
}

/// The mesh of `[mesh]`, notes for the user, and the file ids of its nodes where `renumber`
/// (default: true for files, false for generated meshes) reordered them (see
/// [`Scenario::file_ids`]).
#[allow(clippy::type_complexity)]
fn resolve_mesh(
    m: &spec::MeshSpec,
    path: &Path,
    base: &Path,
) -> Result<(Mesh, Vec<String>, Option<Vec<u32>>)> {
    let mut notes = Vec::new();
    let mut mesh = match (&m.file, &m.generate) {
        (Some(_), Some(_)) => return Err(err(path, "[mesh]: give either `file` or `generate`, not both")),
        (None, None) => return Err(err(path, "[mesh]: missing `file` (a .msh, .node/.ele, .vtk or .vtu mesh) or `generate` (\"rectangle\", \"polygon\", \"box\")")),
        (Some(f), None) => {
            for (k, set) in [("size", m.size.is_some()), ("polygon", m.polygon.is_some()), ("nodes", m.nodes.is_some()), ("divisions", m.divisions.is_some()), ("pattern", m.pattern.is_some())] {
                if set {
                    return Err(err(path, format!("[mesh]: `{k}` applies to `generate`, not to `file`")));
                }
            }
            let p = base.join(f);
            let loaded = load_mesh(&p).map_err(|e| err(path, format!("[mesh] file = \"{f}\": {e}")))?;
            if !loaded.reoriented.is_empty() {
                notes.push(format!("{}: reoriented {} inverted elements (first: {})", p.display(), loaded.reoriented.len(), loaded.reoriented[0]));
            }
            if loaded.unused_nodes_dropped > 0 {
                notes.push(format!("{}: dropped {} nodes used by no element", p.display(), loaded.unused_nodes_dropped));
            }
            loaded.mesh
        }
        (None, Some(g)) => {
            let nodes = m.nodes;
            let need_nodes = || nodes.ok_or_else(|| err(path, format!("[mesh]: generate = \"{g}\" needs `nodes` (target node count)")));
            let size = |len: usize| -> Result<Vec<f64>> {
                let s = m.size.clone().ok_or_else(|| err(path, format!("[mesh]: generate = \"{g}\" needs `size` ({len} lengths in m)")))?;
                if s.len() != len || s.iter().any(|&x| !(x > 0.0)) {
                    return Err(err(path, format!("[mesh]: `size` = {s:?}: need {len} positive lengths (m) for generate = \"{g}\"")));
                }
                Ok(s)
            };
            match g.as_str() {
                "rectangle" => {
                    let s = size(2)?;
                    rectangle_membrane(s[0], s[1], need_nodes()?)?
                }
                "polygon" => {
                    let poly = m.polygon.as_ref().ok_or_else(|| err(path, "[mesh]: generate = \"polygon\" needs `polygon` = [[x, y], ...] (m)"))?;
                    polygon_membrane(poly, need_nodes()?)?
                }
                "box" => {
                    let s = size(3)?;
                    let pattern = match m.pattern.unwrap_or(6) {
                        6 => BoxPattern::Six,
                        5 => BoxPattern::Five,
                        p => return Err(err(path, format!("[mesh]: `pattern` = {p}: valid are 5 or 6 tets per cube"))),
                    };
                    match (m.divisions, nodes) {
                        (Some(d), None) => box_tets([s[0], s[1], s[2]], d, pattern)?,
                        (None, Some(n)) => box_tets_target([s[0], s[1], s[2]], n, pattern)?,
                        _ => return Err(err(path, "[mesh]: generate = \"box\" needs exactly one of `nodes` or `divisions`")),
                    }
                }
                other => return Err(err(path, format!("[mesh]: generate = \"{other}\": valid are \"rectangle\", \"polygon\", \"box\""))),
            }
        }
    };
    if let Some(s) = m.scale {
        mesh.scale(positive(path, "mesh.scale", s)?);
    }
    let file_ids = m.renumber.unwrap_or(m.file.is_some()).then(|| {
        let order = mesh.spatial_order();
        mesh.renumber(&order);
        order
    });
    Ok((mesh, notes, file_ids))
}

/// Every id of a `nodes = [..]` selector names a node of a mesh of `n` nodes.
fn check_node_ids(ns: &[u32], n: usize, path: &Path, key: &str) -> Result<()> {
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

fn resolve_material(m: &spec::MaterialSpec, kind: ElementKind, path: &Path) -> Result<Material> {
    let need = |key: &str, v: Option<f64>| -> Result<f64> {
        v.ok_or_else(|| {
            err(
                path,
                format!("[material]: law = \"{}\" needs `{key}`", m.law),
            )
        })
    };
    let forbid = |keys: &[(&str, bool)]| -> Result<()> {
        for (k, set) in keys {
            if *set {
                return Err(err(
                    path,
                    format!(
                        "[material]: `{k}` is not a parameter of law = \"{}\"",
                        m.law
                    ),
                ));
            }
        }
        Ok(())
    };
    let kappa = |v: Option<f64>| -> Result<f64> {
        match (kind, v) {
            (ElementKind::Tri3, None) => Ok(0.0),
            (ElementKind::Tri3, Some(_)) => Err(err(path, "[material]: `kappa` is not used by membranes (they are incompressible in plane stress)")),
            (ElementKind::Tet4, v) => positive(path, "material.kappa", need("kappa", v)?),
        }
    };
    let young_poisson = || -> Result<(f64, f64)> {
        let e = positive(path, "material.young", need("young", m.young)?)?;
        let nu = need("poisson", m.poisson)?;
        if !(-1.0 < nu && nu < 0.5) {
            return Err(err(
                path,
                format!("`material.poisson` = {nu}: must be in (-1, 0.5)"),
            ));
        }
        Ok((e, nu))
    };
    Ok(match m.law.as_str() {
        "stvk" | "st-venant-kirchhoff" => {
            forbid(&[("c1", m.c1.is_some()), ("c2", m.c2.is_some()), ("gamma", m.gamma.is_some()), ("kappa", m.kappa.is_some())])?;
            let (e, nu) = young_poisson()?;
            Material::StVenantKirchhoff(StVenantKirchhoff::from_young(e, nu))
        }
        "neo-hookean" => {
            forbid(&[("c1", m.c1.is_some()), ("c2", m.c2.is_some()), ("gamma", m.gamma.is_some()), ("kappa", m.kappa.is_some())])?;
            let (e, nu) = young_poisson()?;
            let (lambda, mu) = lame(e, nu);
            Material::NeoHookean(NeoHookean { lambda, mu })
        }
        "mooney-rivlin" => {
            forbid(&[("young", m.young.is_some()), ("poisson", m.poisson.is_some()), ("gamma", m.gamma.is_some())])?;
            let c1 = need("c1", m.c1)?;
            let c2 = need("c2", m.c2)?;
            if !(c1 + c2 > 0.0 && c1 >= 0.0 && c2 >= 0.0) {
                return Err(err(path, format!("[material]: c1 = {c1}, c2 = {c2}: need c1, c2 >= 0 with c1 + c2 > 0 (Pa)")));
            }
            Material::MooneyRivlin(MooneyRivlin::new(c1, c2, kappa(m.kappa)?))
        }
        "veronda-westmann" => {
            forbid(&[("young", m.young.is_some()), ("poisson", m.poisson.is_some()), ("c2", m.c2.is_some())])?;
            let c1 = positive(path, "material.c1", need("c1", m.c1)?)?;
            let gamma = positive(path, "material.gamma", need("gamma", m.gamma)?)?;
            Material::VerondaWestmann(VerondaWestmann::new(c1, gamma, kappa(m.kappa)?))
        }
        other => {
            return Err(err(path, format!("`material.law` = \"{other}\": valid are \"stvk\", \"neo-hookean\", \"mooney-rivlin\", \"veronda-westmann\"")))
        }
    })
}

fn resolve_motion(d: &spec::DisplaceSpec, path: &Path, key: &str) -> Result<Motion> {
    let mode = d
        .mode
        .as_deref()
        .unwrap_or(if d.table.is_some() { "table" } else { "held" });
    let disp = || {
        d.displacement.ok_or_else(|| {
            err(
                path,
                format!("{key}: mode = \"{mode}\" needs `displacement` = [dx, dy, dz] (m)"),
            )
        })
    };
    Ok(match mode {
        "held" => Motion::Held { d: disp()? },
        "ramp" => Motion::Ramp {
            d: disp()?,
            duration: positive(
                path,
                &format!("{key}.duration"),
                d.duration.ok_or_else(|| {
                    err(path, format!("{key}: mode = \"ramp\" needs `duration` (s)"))
                })?,
            )?,
        },
        "table" => {
            let t = d.table.as_ref().ok_or_else(|| {
                err(
                    path,
                    format!("{key}: mode = \"table\" needs `table` = [[t, dx, dy, dz], ...]"),
                )
            })?;
            if t.is_empty() {
                return Err(err(path, format!("{key}.table is empty")));
            }
            if d.displacement.is_some() {
                return Err(err(
                    path,
                    format!("{key}: give `table` or `displacement`, not both"),
                ));
            }
            for w in t.windows(2) {
                if !(w[1][0] > w[0][0]) {
                    return Err(err(
                        path,
                        format!(
                            "{key}.table: times must increase strictly ({} then {})",
                            w[0][0], w[1][0]
                        ),
                    ));
                }
            }
            Motion::Table {
                times: t.iter().map(|r| r[0]).collect(),
                values: t.iter().map(|r| [r[1], r[2], r[3]]).collect(),
            }
        }
        other => {
            return Err(err(
                path,
                format!("{key}: mode = \"{other}\": valid are \"held\", \"ramp\", \"table\""),
            ))
        }
    })
}

/// Resolve a node selection; errors if it selects nothing or names a missing group/node.
pub fn select(mesh: &Mesh, r: &spec::RegionSpec, path: &Path, key: &str) -> Result<Vec<u32>> {
    let set = [
        r.boundary.is_some(),
        r.aabb.is_some(),
        r.plane.is_some(),
        r.group.is_some(),
        r.nodes.is_some(),
        r.point.is_some(),
    ]
    .iter()
    .filter(|&&b| b)
    .count();
    if set != 1 {
        return Err(err(path, format!("{key}: give exactly one selector of `boundary`, `box`, `plane`, `group`, `nodes`, `point` (found {set})")));
    }
    let (lo, hi) = mesh.bounding_box();
    let tol = 1e-9 * norm(sub(hi, lo)).max(f64::MIN_POSITIVE);
    let all = 0..mesh.num_nodes() as u32;
    let sel: Vec<u32> = if let Some(b) = r.boundary {
        if !b {
            return Err(err(
                path,
                format!("{key}: `boundary = false` selects nothing; remove the entry"),
            ));
        }
        mesh.boundary_nodes()
    } else if let Some(b) = &r.aabb {
        all.filter(|&a| {
            let p = mesh.nodes[a as usize];
            (0..3).all(|k| p[k] >= b.min[k] - tol && p[k] <= b.max[k] + tol)
        })
        .collect()
    } else if let Some(pl) = &r.plane {
        let nn = norm(pl.normal);
        if !(nn > 0.0) {
            return Err(err(path, format!("{key}.plane.normal must be non-zero")));
        }
        all.filter(|&a| dot(sub(mesh.nodes[a as usize], pl.point), pl.normal) / nn <= tol)
            .collect()
    } else if let Some(g) = &r.group {
        mesh.groups.get(g).cloned().ok_or_else(|| {
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
        })?
    } else if let Some(ns) = &r.nodes {
        check_node_ids(ns, mesh.num_nodes(), path, key)?;
        ns.clone()
    } else if let Some(p) = r.point {
        vec![mesh
            .nearest_node(p)
            .ok_or_else(|| err(path, "the mesh has no nodes"))? as u32]
    } else {
        unreachable!("exactly one selector is set")
    };
    if sel.is_empty() {
        return Err(err(path, format!("{key}: the selection contains no node")));
    }
    Ok(sel)
}

#[cfg(test)]
mod tests;
