//! Time functions, surface loads (`[[pressure]]`, `[[traction]]`), timed nodal loads and rigid
//! tools (`[[tool]]`) of a scenario: checked once here, then selected on each level's own mesh
//! and carried by the force-model wrappers [`Loaded`] (loads, [`crate::fem::loads`]) and
//! [`Contact`] (tools, [`crate::contact`]).
//!
//! On every multigrid level the loads act on that level's own surface: a surface load's
//! triangles are those of the level's boundary (or membrane elements) whose three nodes the
//! same selector picks on that level (a group of the level's file, the patch within `radius`
//! of `point`, or the whole boundary); a timed nodal load's selector is applied again on the
//! level (a `nodes` list carried to the nearest node); a tool acts on the level's own nodes,
//! its default penalty stiffness from the level's own mean edge length.

use super::spec::{self, Named, TimeKind, ToolKind};
use super::{err, positive, select, Scenario, Selector};
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

/// The friction keys of `[[tool]]` entry `key` checked: `friction`, or `static_friction`
/// with an optional `kinetic_friction`, and `friction_stiffness`. A zero coefficient is
/// frictionless contact (`None`).
fn resolve_friction(t: &spec::ToolSpec, path: &Path, key: &str) -> Result<Option<FrictionDef>> {
    let coefficient = |k: &str, v: f64| -> Result<f64> {
        if v >= 0.0 && v.is_finite() {
            Ok(v)
        } else {
            Err(err(
                path,
                format!("`{key}.{k}` = {v}: must be a friction coefficient, a finite number >= 0"),
            ))
        }
    };
    let (mu_s, mu_k) = match (t.friction, t.static_friction, t.kinetic_friction) {
        (None, None, None) => {
            if t.friction_stiffness.is_some() {
                return Err(err(
                    path,
                    format!("{key}: `friction_stiffness` needs `friction` (or `static_friction`)"),
                ));
            }
            return Ok(None);
        }
        (Some(m), None, None) => {
            let m = coefficient("friction", m)?;
            (m, m)
        }
        (Some(_), _, _) => {
            return Err(err(
                path,
                format!(
                    "{key}: give `friction` (static = kinetic) or `static_friction` with \
                     `kinetic_friction`, not both"
                ),
            ))
        }
        (None, None, Some(_)) => {
            return Err(err(
                path,
                format!("{key}: `kinetic_friction` needs `static_friction` (μ_s >= μ_k)"),
            ))
        }
        (None, Some(s), k) => {
            let s = coefficient("static_friction", s)?;
            let k = match k {
                Some(k) => coefficient("kinetic_friction", k)?,
                None => s,
            };
            if k > s {
                return Err(err(
                    path,
                    format!(
                        "{key}: `kinetic_friction` = {k} exceeds `static_friction` = {s}; \
                         the kinetic coefficient must be at most the static one"
                    ),
                ));
            }
            (s, k)
        }
    };
    let stiffness = match t.friction_stiffness {
        Some(k) => Some(positive(path, &format!("{key}.friction_stiffness"), k)?),
        None => None,
    };
    Ok((mu_s > 0.0).then_some(FrictionDef {
        static_coefficient: mu_s,
        kinetic_coefficient: mu_k,
        stiffness,
    }))
}

/// `time = {..}` checked: the keys its kind needs and no others.
pub fn resolve_time(t: &spec::TimeSpec, path: &Path, key: &str) -> Result<TimeFunction> {
    let kind = t.kind;
    let forbid = |k: &str, set: bool| -> Result<()> {
        if set {
            return Err(err(
                path,
                format!("{key}: `{k}` does not apply to kind = \"{}\"", kind.name()),
            ));
        }
        Ok(())
    };
    let sine_keys = t.amplitude.is_some() || t.frequency.is_some() || t.phase.is_some();
    Ok(match kind {
        TimeKind::Constant => {
            forbid("duration", t.duration.is_some())?;
            forbid("table", t.table.is_some())?;
            forbid("amplitude/frequency/phase", sine_keys)?;
            TimeFunction::Constant
        }
        TimeKind::Ramp => {
            forbid("table", t.table.is_some())?;
            forbid("amplitude/frequency/phase", sine_keys)?;
            let d = t
                .duration
                .ok_or_else(|| err(path, format!("{key}: kind = \"ramp\" needs `duration` (s)")))?;
            TimeFunction::Ramp {
                duration: positive(path, &format!("{key}.duration"), d)?,
            }
        }
        TimeKind::Table => {
            forbid("duration", t.duration.is_some())?;
            forbid("amplitude/frequency/phase", sine_keys)?;
            let rows = t.table.as_ref().ok_or_else(|| {
                err(
                    path,
                    format!("{key}: kind = \"table\" needs `table` = [[t, s], ...]"),
                )
            })?;
            if rows.is_empty() {
                return Err(err(path, format!("{key}.table is empty")));
            }
            for w in rows.windows(2) {
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
            TimeFunction::Table {
                times: rows.iter().map(|r| r[0]).collect(),
                values: rows.iter().map(|r| r[1]).collect(),
            }
        }
        TimeKind::Sine => {
            forbid("duration", t.duration.is_some())?;
            forbid("table", t.table.is_some())?;
            let f = t.frequency.ok_or_else(|| {
                err(
                    path,
                    format!("{key}: kind = \"sine\" needs `frequency` (Hz)"),
                )
            })?;
            TimeFunction::Sine {
                amplitude: t.amplitude.unwrap_or(1.0),
                frequency: positive(path, &format!("{key}.frequency"), f)?,
                phase: t.phase.unwrap_or(0.0),
            }
        }
    })
}

/// `[[pressure]]` (`traction = false`) or `[[traction]]` entry `i` checked.
pub fn resolve_surface_load(
    s: &spec::SurfaceLoadSpec,
    traction: bool,
    path: &Path,
    i: usize,
) -> Result<SurfaceLoadDef> {
    let key = format!("{}[{i}]", if traction { "traction" } else { "pressure" });
    let on = match (&s.group, s.point, s.radius, s.boundary) {
        (Some(g), None, None, None) => SurfaceSelector::Group(g.clone()),
        (None, Some(point), Some(r), None) => SurfaceSelector::Patch {
            point,
            radius: positive(path, &format!("{key}.radius"), r)?,
        },
        (None, None, None, Some(true)) => SurfaceSelector::Boundary,
        _ => {
            return Err(err(
                path,
                format!(
                    "{key}: give exactly one of `group` = \"name\", `point` = [x, y, z] with \
                     `radius` (m), or `boundary` = true"
                ),
            ))
        }
    };
    let kind = match (traction, s.value, s.traction) {
        (false, Some(p), None) => SurfaceLoadKind::Pressure(p),
        (true, None, Some(t)) => SurfaceLoadKind::Traction(t),
        (false, _, _) => {
            return Err(err(
                path,
                format!("{key}: needs `value` (Pa) and no `traction`"),
            ))
        }
        (true, _, _) => {
            return Err(err(
                path,
                format!("{key}: needs `traction` = [tx, ty, tz] (Pa) and no `value`"),
            ))
        }
    };
    let time = match &s.time {
        Some(t) => resolve_time(t, path, &format!("{key}.time"))?,
        None => TimeFunction::Constant,
    };
    Ok(SurfaceLoadDef { on, kind, time })
}

/// `[[tool]]` entry `i` checked.
pub fn resolve_tool(t: &spec::ToolSpec, path: &Path, i: usize) -> Result<ToolDef> {
    let key = format!("tool[{i}]");
    let need = |k: &str, v: Option<[f64; 3]>| {
        v.ok_or_else(|| {
            err(
                path,
                format!(
                    "{key}: shape = \"{}\" needs `{k}` = [x, y, z]",
                    t.shape.name()
                ),
            )
        })
    };
    let radius = || -> Result<f64> {
        let r = t.radius.ok_or_else(|| {
            err(
                path,
                format!("{key}: shape = \"{}\" needs `radius` (m)", t.shape.name()),
            )
        })?;
        positive(path, &format!("{key}.radius"), r)
    };
    let forbid = |k: &str, set: bool| -> Result<()> {
        if set {
            return Err(err(
                path,
                format!(
                    "{key}: `{k}` does not apply to shape = \"{}\"",
                    t.shape.name()
                ),
            ));
        }
        Ok(())
    };
    let shape = match t.shape {
        ToolKind::Sphere => {
            for (k, set) in [
                ("point", t.point.is_some()),
                ("normal", t.normal.is_some()),
                ("a", t.a.is_some()),
                ("b", t.b.is_some()),
            ] {
                forbid(k, set)?;
            }
            ToolShape::Sphere {
                center: need("center", t.center)?,
                radius: radius()?,
            }
        }
        ToolKind::Plane => {
            for (k, set) in [
                ("center", t.center.is_some()),
                ("radius", t.radius.is_some()),
                ("a", t.a.is_some()),
                ("b", t.b.is_some()),
            ] {
                forbid(k, set)?;
            }
            let n = need("normal", t.normal)?;
            let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            if !(l > 0.0) {
                return Err(err(path, format!("{key}.normal must be non-zero")));
            }
            ToolShape::Plane {
                point: need("point", t.point)?,
                normal: n.map(|x| x / l),
            }
        }
        ToolKind::Capsule => {
            for (k, set) in [
                ("center", t.center.is_some()),
                ("point", t.point.is_some()),
                ("normal", t.normal.is_some()),
            ] {
                forbid(k, set)?;
            }
            ToolShape::Capsule {
                a: need("a", t.a)?,
                b: need("b", t.b)?,
                radius: radius()?,
            }
        }
    };
    let motion = match (&t.path, t.displacement) {
        (Some(_), Some(_)) => {
            return Err(err(
                path,
                format!("{key}: give `path` or `displacement` (with `time`), not both"),
            ))
        }
        (Some(rows), None) => {
            if t.time.is_some() {
                return Err(err(path, format!("{key}: `time` does not apply to `path`")));
            }
            if rows.is_empty() {
                return Err(err(path, format!("{key}.path is empty")));
            }
            super::resolve::table_motion(rows, path, &format!("{key}.path"))?
        }
        (None, Some(d)) => Motion::Function {
            d,
            f: match &t.time {
                Some(ts) => resolve_time(ts, path, &format!("{key}.time"))?,
                None => TimeFunction::Constant,
            },
        },
        (None, None) => {
            if t.time.is_some() {
                return Err(err(
                    path,
                    format!("{key}: `time` needs `displacement` = [dx, dy, dz] (m)"),
                ));
            }
            Motion::Held { d: [0.0; 3] }
        }
    };
    let stiffness = match t.stiffness {
        Some(k) => Some(positive(path, &format!("{key}.stiffness"), k)?),
        None => None,
    };
    Ok(ToolDef {
        shape,
        motion,
        stiffness,
        friction: resolve_friction(t, path, &key)?,
    })
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
pub fn tool_stiffness(sc: &Scenario, mesh: &Mesh, t: &ToolDef) -> f64 {
    t.stiffness.unwrap_or_else(|| {
        default_stiffness(sc.material.stability_modulus(mesh.kind), mean_edge(mesh))
    })
}

impl Scenario {
    /// Whether a tool has friction (path-dependent contact: `measures.csv` has the friction
    /// columns, the frames the `friction_force` field).
    pub fn has_friction(&self) -> bool {
        self.tools.iter().any(|t| t.friction.is_some())
    }

    /// Whether the scenario has loads or tools that a [`Loaded`] or [`Contact`] force model
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

    /// A bound on the work the loads and tools of this scenario can do on `mesh` (J), for the
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
    fn surface_triangles(&self, mesh: &Mesh, i: usize) -> Result<Vec<[u32; 3]>> {
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
    /// scenario's mesh (at load time, not when the run starts).
    pub(super) fn check_model_loads(&self) -> Result<()> {
        for i in 0..self.surface_loads.len() {
            self.surface_triangles(&self.mesh, i)?;
        }
        for (i, (sel, _, _)) in self.timed_load.iter().enumerate() {
            select(&self.mesh, sel, &self.path, &format!("load[{i}].at"))?;
        }
        Ok(())
    }

    /// Wrap `fem` (a force model on `mesh`, reference positions `x0`) with the scenario's
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

#[cfg(test)]
mod friction_tests;
#[cfg(test)]
mod tests;
