//! Resolving a scenario's regions, materials and motions: `[[fix]]` and `[[load]]` selectors
//! into node lists (file ids to memory order), `[material]` into a [`Material`] with its
//! parameters checked, `[[displace]]` into a [`Motion`]. Each error names the scenario file
//! and the key.

use super::{err, loading, positive, spec, Fixing, Selector, Shape};
use crate::error::Result;
use crate::geometry::norm;
use crate::material::ranges::{self, OutOfRange};
use crate::material::{
    lame, HolzapfelGasserOgden, Material, MooneyRivlin, NeoHookean, NeoHookeanVisco,
    StVenantKirchhoff, StableNeoHookean, TiNeoHookean, VerondaWestmann,
};
use crate::mesh::ElementKind;
use crate::time::Motion;
use nalgebra::Vector3;
use spec::{defaults, Law, MotionMode, Named};
use std::path::Path;

/// The file's node ids and where each sits in file order.
pub(super) struct NodeIds<'a> {
    labels: Option<&'a [u64]>,
    index: Option<std::collections::HashMap<u64, u32>>,
    n: usize,
    file: Option<&'a Path>,
}

impl<'a> NodeIds<'a> {
    pub(super) fn new(labels: Option<&'a [u64]>, n: usize, shape: &'a Shape) -> Self {
        NodeIds {
            labels,
            index: labels.map(|l| {
                l.iter()
                    .enumerate()
                    .map(|(k, &id)| (id, k as u32))
                    .collect()
            }),
            n,
            file: match shape {
                Shape::File(p) => Some(p.as_path()),
                _ => None,
            },
        }
    }
    /// The file-order position of each id; an id the mesh does not have is an error naming
    /// the valid range.
    pub(super) fn index_of(&self, ids: &[u64], path: &Path, key: &str) -> Result<Vec<u32>> {
        ids.iter()
            .map(|&id| {
                let k = match &self.index {
                    Some(m) => m.get(&id).copied(),
                    None => (id < self.n as u64).then_some(id as u32),
                };
                k.ok_or_else(|| {
                    let (lo, hi) = match self.labels {
                        Some(l) => (
                            l.iter().copied().min().unwrap_or(0),
                            l.iter().copied().max().unwrap_or(0),
                        ),
                        None => (0, self.n.saturating_sub(1) as u64),
                    };
                    let whose = match self.file {
                        Some(f) => format!("the ids of {}", f.display()),
                        None => "the generated mesh's ids".to_string(),
                    };
                    let gaps = if (hi - lo + 1) as usize != self.n {
                        format!(", {} of them used by elements", self.n)
                    } else {
                        String::new()
                    };
                    err(
                        path,
                        format!(
                            "{key}.nodes: node {id} does not exist ({whose} run {lo}..={hi}{gaps}; \
                             ids are as the file numbers them)"
                        ),
                    )
                })
            })
            .collect()
    }
}

/// What a `[[fix]]` holds: `components` or `normal`, else everything.
pub(super) fn resolve_fixing(r: &spec::RegionSpec, path: &Path, key: &str) -> Result<Fixing> {
    match (&r.components, r.normal) {
        (None, None) => Ok(Fixing::All),
        (Some(_), Some(_)) => Err(err(
            path,
            format!("{key}: give `components` or `normal`, not both"),
        )),
        (Some(c), None) => {
            let mut dirs = Vec::new();
            for name in c {
                let k = match name.as_str() {
                    "x" => 0,
                    "y" => 1,
                    "z" => 2,
                    other => {
                        return Err(err(
                            path,
                            format!("`{key}.components`: \"{other}\" is not a component (valid: \"x\", \"y\", \"z\")"),
                        ))
                    }
                };
                let mut e = [0.0; 3];
                e[k] = 1.0;
                if dirs.contains(&e) {
                    return Err(err(
                        path,
                        format!("`{key}.components`: \"{name}\" given twice"),
                    ));
                }
                dirs.push(e);
            }
            if dirs.is_empty() {
                return Err(err(path, format!("`{key}.components` is empty: list \"x\", \"y\" and/or \"z\", or leave it out to fix all three")));
            }
            Ok(if dirs.len() == 3 {
                Fixing::All
            } else {
                Fixing::Directions(dirs)
            })
        }
        (None, Some(n)) => {
            let l = norm(n);
            if !(l > 0.0) {
                return Err(err(path, format!("`{key}.normal` must be non-zero")));
            }
            Ok(Fixing::Directions(vec![[n[0] / l, n[1] / l, n[2] / l]]))
        }
    }
}
/// The one selector a `[[fix]]` or `at` table sets.
pub(super) fn resolve_selector(r: &spec::RegionSpec, path: &Path, key: &str) -> Result<Selector> {
    let mut found = Vec::new();
    if let Some(b) = r.boundary {
        if !b {
            return Err(err(
                path,
                format!("{key}: `boundary = false` selects nothing; remove the entry"),
            ));
        }
        found.push(Selector::Boundary);
    }
    if let Some(b) = &r.aabb {
        found.push(Selector::Box {
            min: b.min,
            max: b.max,
        });
    }
    if let Some(p) = &r.plane {
        if !(norm(p.normal) > 0.0) {
            return Err(err(path, format!("{key}.plane.normal must be non-zero")));
        }
        found.push(Selector::Plane {
            point: p.point,
            normal: p.normal,
        });
    }
    if let Some(g) = &r.group {
        found.push(Selector::Group(g.clone()));
    }
    if let Some(ns) = &r.nodes {
        // The ids become mesh indices in `resolve`.
        found.push(Selector::Nodes(vec![0; ns.len()]));
    }
    if let Some(p) = r.point {
        found.push(Selector::Point(p));
    }
    match found.len() {
        1 => Ok(found.pop().expect("one selector")),
        n => Err(err(path, format!("{key}: give exactly one selector of `boundary`, `box`, `plane`, `group`, `nodes`, `point` (found {n})"))),
    }
}

pub(super) fn resolve_material(
    m: &spec::MaterialSpec,
    kind: ElementKind,
    interactive: bool,
    path: &Path,
) -> Result<Material> {
    let chosen = match (m.law, interactive) {
        (Some(law), _) => law,
        (None, true) => defaults::INTERACTIVE_LAW,
        (None, false) => {
            return Err(err(
                path,
                "[material]: `law` is required (one of \"stvk\", \"neo-hookean\", \"mooney-rivlin\", \"veronda-westmann\", \"stable-neo-hookean\", \"ti-neo-hookean\", \"hgo\", \"neo-hookean-visco\"; scenarios with an [interactive] section default to \"stable-neo-hookean\")",
            ))
        }
    };
    let law = chosen.name();
    let need = |key: &str, v: Option<f64>| -> Result<f64> {
        v.ok_or_else(|| err(path, format!("[material]: law = \"{law}\" needs `{key}`")))
    };
    let given = [
        ("young", m.young.is_some()),
        ("poisson", m.poisson.is_some()),
        ("c1", m.c1.is_some()),
        ("c2", m.c2.is_some()),
        ("gamma", m.gamma.is_some()),
        ("kappa", m.kappa.is_some()),
        ("mu", m.mu.is_some()),
        ("eta", m.eta.is_some()),
        ("k1", m.k1.is_some()),
        ("k2", m.k2.is_some()),
        ("dispersion", m.dispersion.is_some()),
        ("fibre", m.fibre.is_some()),
        ("prony", m.prony.is_some()),
    ];
    // Every key given must be one of `allowed`, the law's parameters.
    let only = |allowed: &[&str]| -> Result<()> {
        for (k, set) in given {
            if set && !allowed.contains(&k) {
                let list: Vec<String> = allowed.iter().map(|a| format!("`{a}`")).collect();
                return Err(err(
                    path,
                    format!(
                        "[material]: `{k}` is not a parameter of law = \"{law}\" (its parameters: {}, `density`{})",
                        list.join(", "),
                        if kind == ElementKind::Tri3 { ", `thickness`" } else { "" }
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
            (ElementKind::Tet4, v) => in_range(path, ranges::positive("kappa", need("kappa", v)?)),
        }
    };
    let young_poisson = || -> Result<(f64, f64)> {
        let e = need("young", m.young)?;
        in_range(path, ranges::positive("young", e))?;
        in_range(path, ranges::young_poisson(e, need("poisson", m.poisson)?))
    };
    Ok(match chosen {
        Law::StVenantKirchhoff => {
            only(&["young", "poisson"])?;
            let (e, nu) = young_poisson()?;
            Material::StVenantKirchhoff(StVenantKirchhoff::from_young(e, nu))
        }
        Law::NeoHookean => {
            only(&["young", "poisson"])?;
            let (e, nu) = young_poisson()?;
            let (lambda, mu) = lame(e, nu);
            Material::NeoHookean(NeoHookean { lambda, mu })
        }
        Law::MooneyRivlin => {
            only(&["c1", "c2", "kappa"])?;
            let c1 = need("c1", m.c1)?;
            let c2 = need("c2", m.c2)?;
            in_range(path, ranges::mooney_rivlin(c1, c2))?;
            Material::MooneyRivlin(MooneyRivlin::new(c1, c2, kappa(m.kappa)?))
        }
        Law::VerondaWestmann => {
            only(&["c1", "gamma", "kappa"])?;
            let c1 = in_range(path, ranges::positive("c1", need("c1", m.c1)?))?;
            let gamma = in_range(path, ranges::positive("gamma", need("gamma", m.gamma)?))?;
            Material::VerondaWestmann(VerondaWestmann::new(c1, gamma, kappa(m.kappa)?))
        }
        Law::StableNeoHookean => {
            only(&["young", "poisson"])?;
            let (e, nu) = young_poisson()?;
            Material::StableNeoHookean(StableNeoHookean::from_young(e, nu))
        }
        Law::TiNeoHookean | Law::HolzapfelGasserOgden | Law::NeoHookeanVisco => {
            let fibre_keys: &[&str] = if chosen == Law::NeoHookeanVisco {
                &["mu", "kappa", "young", "poisson", "prony"]
            } else if chosen == Law::TiNeoHookean {
                &["mu", "kappa", "young", "poisson", "eta", "fibre"]
            } else {
                &[
                    "mu",
                    "kappa",
                    "young",
                    "poisson",
                    "k1",
                    "k2",
                    "dispersion",
                    "fibre",
                ]
            };
            only(fibre_keys)?;
            if kind == ElementKind::Tri3 {
                return Err(err(
                    path,
                    format!("[material]: law = \"{law}\" is a solid law (tetrahedra) and this mesh is a membrane; membranes take {MEMBRANE_LAWS}"),
                ));
            }
            let (mu, kappa) = match (m.mu.is_some() || m.kappa.is_some(), m.young.is_some() || m.poisson.is_some()) {
                (true, true) => return Err(err(path, format!("[material]: law = \"{law}\" takes either `mu` and `kappa` or `young` and `poisson`, not both pairs"))),
                (false, true) => {
                    let (e, nu) = young_poisson()?;
                    (e / (2.0 * (1.0 + nu)), e / (3.0 * (1.0 - 2.0 * nu)))
                }
                _ => (
                    in_range(path, ranges::positive("mu", need("mu", m.mu)?))?,
                    in_range(path, ranges::positive("kappa", need("kappa", m.kappa)?))?,
                ),
            };
            if chosen == Law::NeoHookeanVisco {
                let Some(terms) = &m.prony else {
                    return Err(err(path, format!("[material]: law = \"{law}\" needs `prony = [[alpha, tau], ...]`, the Prony terms (relative modulus alpha >= 0, relaxation time tau > 0 s)")));
                };
                let mut prony = Vec::with_capacity(terms.len());
                for (i, t) in terms.iter().enumerate() {
                    let &[alpha, tau] = t.as_slice() else {
                        return Err(err(path, format!("`material.prony`: term {} has {} numbers: each term is [alpha, tau] (relative modulus, relaxation time in s)", i + 1, t.len())));
                    };
                    prony.push(crate::material::Prony { alpha, tau });
                }
                return NeoHookeanVisco::new(mu, kappa, prony)
                    .map(Material::NeoHookeanVisco)
                    .map_err(|e| err(path, e.to_string()));
            }
            let fibre = match &m.fibre {
                None => return Err(err(path, format!("[material]: law = \"{law}\" needs `fibre = [x, y, z]`, the fibre direction (or a field: `{{ cell_data = \"NAME\" }}`, `{{ helix = {{ .. }} }}`)"))),
                Some(spec::FibreSpec::Direction(f)) => {
                    crate::material::unit_direction(Vector3::from(*f), "material.fibre")
                        .map_err(|e| err(path, e.to_string()))?
                }
                // A field (scenario::fibres) gives each element its own direction; the law's
                // own is never used.
                Some(_) => Vector3::x(),
            };
            if chosen == Law::TiNeoHookean {
                let eta = in_range(path, ranges::non_negative("eta", need("eta", m.eta)?))?;
                Material::TiNeoHookean(TiNeoHookean {
                    mu,
                    kappa,
                    eta,
                    fibre,
                })
            } else {
                let k1 = in_range(path, ranges::non_negative("k1", need("k1", m.k1)?))?;
                let k2 = in_range(path, ranges::non_negative("k2", need("k2", m.k2)?))?;
                let dispersion = in_range(path, ranges::dispersion(m.dispersion.unwrap_or(0.0)))?;
                Material::HolzapfelGasserOgden(HolzapfelGasserOgden {
                    mu,
                    kappa,
                    k1,
                    k2,
                    dispersion,
                    fibre,
                })
            }
        }
    })
}

/// A `[material]` constant out of its range ([`ranges`]) as the scenario's error:
/// ``"`material.poisson` = 0.5: must be in (-1, 0.5)"``.
fn in_range<T>(path: &Path, r: std::result::Result<T, OutOfRange>) -> Result<T> {
    r.map_err(|e| {
        err(
            path,
            format!(
                "`material.{}` = {}: {}",
                e.key,
                crate::numbers::compact(e.value),
                e.rule
            ),
        )
    })
}

/// The laws with a membrane form, as an error message lists them.
const MEMBRANE_LAWS: &str =
    "\"stvk\", \"neo-hookean\", \"mooney-rivlin\", \"veronda-westmann\" or \"stable-neo-hookean\"";

pub(super) fn resolve_motion(d: &spec::DisplaceSpec, path: &Path, key: &str) -> Result<Motion> {
    if let Some(t) = &d.time {
        for (k, set) in [
            ("mode", d.mode.is_some()),
            ("duration", d.duration.is_some()),
            ("table", d.table.is_some()),
        ] {
            if set {
                return Err(err(
                    path,
                    format!("{key}: `{k}` does not apply with `time` (the displacement times a time function)"),
                ));
            }
        }
        let disp = d.displacement.ok_or_else(|| {
            err(
                path,
                format!("{key}: `time` needs `displacement` = [dx, dy, dz] (m)"),
            )
        })?;
        return Ok(Motion::Function {
            d: disp,
            f: loading::resolve_time(t, path, &format!("{key}.time"))?,
        });
    }
    let mode = d.mode.unwrap_or(if d.table.is_some() {
        MotionMode::Table
    } else {
        MotionMode::Held
    });
    let disp = || {
        d.displacement.ok_or_else(|| {
            err(
                path,
                format!(
                    "{key}: mode = \"{}\" needs `displacement` = [dx, dy, dz] (m)",
                    mode.name()
                ),
            )
        })
    };
    let forbid = |k: &str, set: bool| -> Result<()> {
        if set {
            return Err(err(
                path,
                format!("{key}: `{k}` does not apply to mode = \"{}\"", mode.name()),
            ));
        }
        Ok(())
    };
    Ok(match mode {
        MotionMode::Held => {
            forbid("duration", d.duration.is_some())?;
            forbid("table", d.table.is_some())?;
            Motion::Held { d: disp()? }
        }
        MotionMode::Ramp => {
            forbid("table", d.table.is_some())?;
            Motion::Ramp {
                d: disp()?,
                duration: positive(
                    path,
                    &format!("{key}.duration"),
                    d.duration.ok_or_else(|| {
                        err(path, format!("{key}: mode = \"ramp\" needs `duration` (s)"))
                    })?,
                )?,
            }
        }
        MotionMode::Table => {
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
            forbid("duration", d.duration.is_some())?;
            table_motion(t, path, &format!("{key}.table"))?
        }
    })
}

/// A piecewise-linear motion from `[t, dx, dy, dz]` rows (s, m) whose times increase
/// strictly; `key` names the rows in the error.
pub(super) fn table_motion(rows: &[[f64; 4]], path: &Path, key: &str) -> Result<Motion> {
    for w in rows.windows(2) {
        if !(w[1][0] > w[0][0]) {
            return Err(err(
                path,
                format!(
                    "{key}: times must increase strictly ({} then {})",
                    w[0][0], w[1][0]
                ),
            ));
        }
    }
    Ok(Motion::Table {
        times: rows.iter().map(|r| r[0]).collect(),
        values: rows.iter().map(|r| [r[1], r[2], r[3]]).collect(),
    })
}
