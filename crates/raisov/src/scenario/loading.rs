//! Time functions, surface loads (`[[pressure]]`, `[[traction]]`), timed nodal loads and rigid
//! tools (`[[tool]]`) of a scenario checked once here into the model's
//! ([`crate::model::loads`]: what they act on at every level, and the force-model wrappers
//! that carry them).

use super::spec::{self, Named, TimeKind, ToolKind};
use super::{err, positive};
use crate::contact::ToolShape;
use crate::error::Result;
use crate::fem::loads::{SurfaceLoadKind, TimeFunction};
pub use crate::model::loads::{
    mean_edge, tool_stiffness, FrictionDef, SurfaceLoadDef, SurfaceSelector, ToolDef,
};
use crate::time::Motion;
use std::path::Path;

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

#[cfg(test)]
mod friction_tests;
#[cfg(test)]
mod tests;
