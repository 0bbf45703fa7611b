//! `[multigrid]` resolved: the scheme and its settings, each level's integrator and step
//! ([`Multigrid`]), and how the coarser levels are made (the model's
//! [`LevelMeshes`]: generated as a geometric series of node counts, or read from files; what
//! each level is then made of is [`crate::model::levels`]).

use super::spec::{
    defaults, Accelerate, CoarseKind, MeshSpec, MultigridSpec, SmootherKind, FAS_KEYS, PAPER_KEYS,
};
use super::{err, positive};
use crate::error::Result;
use crate::integrate::Method;
use crate::mesh::Mesh;
use crate::model::levels::MIN_LEVEL_NODES;
use crate::model::{LevelMeshes, Scheme, SchemeKind};
use crate::multigrid::fas::{CoarseSolve, FasParams, Smoother};
use crate::multigrid::raisov::RaisovParams;
use std::path::Path;

/// The resolved `[multigrid]` section.
#[derive(Clone, Debug, PartialEq)]
pub struct Multigrid {
    /// `[multigrid] scheme` with its settings: [`Scheme::Fas`], [`Scheme::RaisovPaper`] or
    /// [`Scheme::Newton`] (a multigrid's `kinetic_limit` is set from the system when the
    /// stepper is built).
    pub scheme: Scheme,
    /// Integrator of each level, level 0 first.
    pub methods: Vec<Method>,
    /// Step of each level (s), level 0 first, where `level_dt` gives them.
    pub level_dt: Option<Vec<f64>>,
}

/// Check a `[multigrid]` section and resolve it, with how the model's coarser levels are
/// made; `mesh` is level 0, `surface_files` the coarser levels generated from `[mesh]
/// surface`.
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
) -> Result<(Multigrid, LevelMeshes)> {
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
    Ok((
        Multigrid {
            scheme,
            methods,
            level_dt,
        },
        meshes,
    ))
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
