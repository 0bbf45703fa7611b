//! Multigrid levels of a scenario: level meshes (generated as a geometric series of node
//! counts, or read from files), constraints re-resolved on every level, and the stepper.
//!
//! Per level: fixed regions and loads are selected again on that level's mesh (a `nodes`
//! list is carried by nearest node); a prescribed displacement of level 0 goes to the node of
//! each coarser level nearest to level 0's prescribed node (paper section 3.1).

use super::spec::{MeshSpec, MultigridSpec, RegionSpec};
use super::{build_system, critical_step_estimate, err, positive, resolve_mesh, select, Scenario};
use crate::error::Result;
use crate::hierarchy::Correspondence;
use crate::integrate::{energy_limit_for, Method, Motion, SingleLevel, Stepper, StepperParams};
use crate::mesh::Mesh;
use crate::multigrid::fas::{CoarseSolve, Fas, FasParams, Scaling, Smoother, TransferWeights};
use crate::multigrid::raisov::{Raisov, RaisovParams, Reading};
use crate::multigrid::Level;
use std::path::Path;

/// Check a `[multigrid]` section before anything is built.
pub(super) fn validate(mg: &MultigridSpec, mesh: &MeshSpec, path: &Path) -> Result<()> {
    match mg.scheme.as_deref() {
        None | Some("fas") | Some("raisov-paper") => {}
        Some(o) => {
            return Err(err(
                path,
                format!("`multigrid.scheme` = \"{o}\": valid are \"fas\", \"raisov-paper\""),
            ))
        }
    }
    if mg.coarse_iterations == Some(0) {
        return Err(err(
            path,
            "`multigrid.coarse_iterations` = 0: give at least 1 (Chebyshev iterations per coarsest visit, default 60)",
        ));
    }
    if mg.coarse_iterations.is_some() && !matches!(mg.coarse.as_deref(), None | Some("chebyshev")) {
        return Err(err(
            path,
            "`multigrid.coarse_iterations` applies to coarse = \"chebyshev\" only",
        ));
    }
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
        if ln.iter().any(|&n| n < 4) {
            return Err(err(
                path,
                format!("`multigrid.level_nodes` = {ln:?}: every level needs at least 4 nodes"),
            ));
        }
        return Ok(());
    }
    match (mg.levels, &mg.files, &mesh.generate) {
        (Some(_), Some(_), _) => return Err(err(path, "[multigrid]: give `levels` (generated meshes) or `files`, not both")),
        (Some(n), None, Some(_)) if n >= 1 => {}
        (Some(_), None, Some(_)) => return Err(err(path, "`multigrid.levels` must be at least 1")),
        (Some(_), None, None) => return Err(err(path, "[multigrid]: `levels` needs [mesh] generate; for mesh files list the coarser levels in `files`")),
        (None, Some(_), _) => {}
        (None, None, _) => return Err(err(path, "[multigrid]: give `levels` (with [mesh] generate) or `files` (coarser levels)")),
    }
    if let Some(r) = mg.ratio {
        if !(r > 0.0 && r < 1.0) {
            return Err(err(
                path,
                format!("`multigrid.ratio` = {r}: must be in (0, 1)"),
            ));
        }
    }
    if let Some(r) = mg.reading.as_deref() {
        if r != "paper" && r != "correction" {
            return Err(err(
                path,
                format!("`multigrid.reading` = \"{r}\": valid are \"paper\", \"correction\""),
            ));
        }
    }
    for (key, value, valid) in [
        (
            "coarse",
            mg.coarse.as_deref(),
            &["chebyshev", "explicit", "newton"][..],
        ),
        (
            "smoother",
            mg.smoother.as_deref(),
            &["chebyshev", "dynamics"][..],
        ),
        (
            "scaling",
            mg.scaling.as_deref(),
            &["fictitious", "mass"][..],
        ),
        (
            "transfer",
            mg.transfer.as_deref(),
            &["convex", "exact", "convex-restriction"][..],
        ),
        ("accelerate", mg.accelerate.as_deref(), &["cg", "none"][..]),
    ] {
        if let Some(v) = value {
            if !valid.contains(&v) {
                let list: Vec<String> = valid.iter().map(|x| format!("\"{x}\"")).collect();
                return Err(err(
                    path,
                    format!("`multigrid.{key}` = \"{v}\": valid are {}", list.join(", ")),
                ));
            }
        }
    }
    Ok(())
}

/// Constraints and loads of one level.
#[derive(Clone, Debug, Default)]
pub struct LevelConstraints {
    pub fixed: Vec<u32>,
    pub prescribed: Vec<(u32, Motion)>,
    pub loads: Vec<(u32, [f64; 3])>,
}

impl Scenario {
    /// Number of levels (1 without `[multigrid]`).
    pub fn num_levels(&self) -> usize {
        match &self.spec.multigrid {
            None => 1,
            Some(mg) => mg.levels.unwrap_or_else(|| match &mg.level_nodes {
                Some(ln) => ln.len(),
                None => 1 + mg.files.as_ref().map_or(0, |f| f.len()),
            }),
        }
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
        let Some(mg) = &self.spec.multigrid else {
            return Ok(out);
        };
        let base = self.path.parent().unwrap_or(Path::new("."));
        let ratio = mg.ratio.unwrap_or(0.5);
        let level = |ms: &MeshSpec| resolve_mesh(ms, &self.path, base).map(|r| (r.0, r.2));
        if let Some(files) = &mg.files {
            for f in files {
                out.push(level(&MeshSpec {
                    file: Some(f.clone()),
                    scale: self.spec.mesh.scale,
                    renumber: self.spec.mesh.renumber,
                    ..Default::default()
                })?);
            }
        } else if let Some(ln) = &mg.level_nodes {
            for &n in &ln[1..] {
                let mut ms = self.spec.mesh.clone();
                ms.nodes = Some(n);
                out.push(level(&ms)?);
            }
        } else {
            for i in 1..mg.levels.unwrap_or(1) {
                let f = ratio.powi(i as i32);
                let mut ms = self.spec.mesh.clone();
                if let Some(n) = ms.nodes {
                    ms.nodes = Some(((n as f64 * f).round() as usize).max(4));
                }
                if let Some(d) = ms.divisions {
                    let g = f.cbrt();
                    ms.divisions = Some(d.map(|x| ((x as f64 * g).round() as usize).max(1)));
                }
                out.push(level(&ms)?);
            }
        }
        Ok(out)
    }

    /// Fixed nodes, prescribed motions and nodal loads of this scenario on `mesh` (a level).
    pub fn constraints_on(&self, mesh: &Mesh, level: usize) -> Result<LevelConstraints> {
        if level == 0 {
            return Ok(LevelConstraints {
                fixed: self.fixed.clone(),
                prescribed: self.prescribed.clone(),
                loads: self.loads.clone(),
            });
        }
        let carry = |r: &RegionSpec| -> RegionSpec {
            match &r.nodes {
                // A node list names level-0 nodes: carry each to the nearest node here.
                Some(ns) => RegionSpec {
                    nodes: Some(
                        ns.iter()
                            .filter_map(|&a| self.mesh.nodes.get(a as usize))
                            .filter_map(|&p| mesh.nearest_node(p).map(|x| x as u32))
                            .collect(),
                    ),
                    ..Default::default()
                },
                None => r.clone(),
            }
        };
        let mut fixed = Vec::new();
        for (i, r) in self.spec.fix.iter().enumerate() {
            fixed.extend(select(
                mesh,
                &carry(r),
                &self.path,
                &format!("level {level}: fix[{i}]"),
            )?);
        }
        let mut loads = Vec::new();
        for (i, l) in self.spec.load.iter().enumerate() {
            for n in select(
                mesh,
                &carry(&l.at),
                &self.path,
                &format!("level {level}: load[{i}].at"),
            )? {
                loads.push((n, l.force));
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
            prescribed,
            loads,
        })
    }

    /// Per-level integrator methods.
    fn level_methods(&self, m: usize) -> Result<Vec<Method>> {
        let Some(list) = self
            .spec
            .multigrid
            .as_ref()
            .and_then(|mg| mg.level_methods.clone())
        else {
            return Ok(vec![self.method; m]);
        };
        if list.len() != m {
            return Err(err(
                &self.path,
                format!(
                    "`multigrid.level_methods` has {} entries for {m} levels",
                    list.len()
                ),
            ));
        }
        list.iter()
            .map(|s| {
                Method::ALL.into_iter().find(|x| x.name() == s).ok_or_else(|| {
                    err(&self.path, format!("`multigrid.level_methods`: \"{s}\": valid are forward-euler, symplectic-euler, rk4, central-difference"))
                })
            })
            .collect()
    }

    /// Build every level (mesh, system with its own constraints, integrator, step) and the
    /// correspondences between consecutive levels.
    pub fn build_levels(&self) -> Result<(Vec<Level>, crate::multigrid::Links)> {
        let (meshes, keys): (Vec<Mesh>, Vec<Option<Vec<u32>>>) =
            self.level_meshes_with_ids()?.into_iter().unzip();
        let m = meshes.len();
        let methods = self.level_methods(m)?;
        let mg = self.spec.multigrid.clone().unwrap_or_default();
        let scheme = mg.scheme.as_deref().unwrap_or("fas");
        let safety = self.spec.integrator.safety.unwrap_or(0.5);
        let dts: Vec<f64> = match &mg.level_dt {
            Some(d) if d.len() == m => d
                .iter()
                .enumerate()
                .map(|(i, &x)| positive(&self.path, &format!("multigrid.level_dt[{i}]"), x))
                .collect::<Result<_>>()?,
            Some(d) => {
                return Err(err(
                    &self.path,
                    format!(
                        "`multigrid.level_dt` has {} entries for {m} levels",
                        d.len()
                    ),
                ))
            }
            None if scheme == "raisov-paper" => vec![self.dt; m],
            None => meshes
                .iter()
                .zip(&methods)
                .enumerate()
                .map(|(i, (mesh, &me))| {
                    if i == 0 {
                        self.dt
                    } else {
                        safety * critical_step_estimate(mesh, &self.material, self.density, me)
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
            let c = self.constraints_on(&mesh, i)?;
            let sys = if i == 0 {
                self.build_system()?
            } else {
                build_system(self, &mesh, &c.fixed, &c.prescribed, &c.loads)?
            };
            let lambda_max = self.material.stability_modulus(mesh.kind) / self.density
                * super::max_gradient_sum(&mesh);
            let mut level = Level::new(mesh, sys, methods[i], dts[i], lambda_max);
            level.node_keys = node_keys;
            levels.push(level);
        }
        Ok((levels, links))
    }

    /// The stepper this scenario asks for: single level, or a multigrid over its levels.
    pub fn stepper(&self) -> Result<Box<dyn Stepper>> {
        let sys = self.build_system()?;
        let limit = energy_limit_for(&sys, &self.mesh, self.blowup_factor);
        let Some(mg) = &self.spec.multigrid else {
            return Ok(Box::new(SingleLevel::new(
                sys,
                self.method,
                StepperParams {
                    dt: self.dt,
                    kinetic_limit: limit,
                },
            )));
        };
        let scheme = mg.scheme.as_deref().unwrap_or("fas");
        let (levels, links) = self.build_levels()?;
        Ok(match scheme {
            "raisov-paper" => {
                let reading = match mg.reading.as_deref() {
                    Some("paper") => Reading::Paper,
                    _ => Reading::Correction,
                };
                let epsilon = match mg.epsilon {
                    Some(e) if e >= 0.0 => e,
                    Some(e) => {
                        return Err(err(
                            &self.path,
                            format!("`multigrid.epsilon` = {e}: must be >= 0 (m)"),
                        ))
                    }
                    None => 1e-3 * self.mesh.edge_range().0,
                };
                Box::new(Raisov::new(
                    levels,
                    links,
                    RaisovParams {
                        epsilon,
                        reading,
                        kinetic_limit: limit,
                    },
                ))
            }
            _ => {
                let coarse = match mg.coarse.as_deref() {
                    Some("newton") => CoarseSolve::Newton { rel_tol: 1e-6 },
                    Some("explicit") => CoarseSolve::Explicit {
                        time: positive(
                            &self.path,
                            "multigrid.coarse_time",
                            mg.coarse_time.unwrap_or(0.1),
                        )?,
                    },
                    _ => match (mg.coarse_iterations, FasParams::default().coarse) {
                        (Some(iterations), CoarseSolve::Chebyshev { ratio, .. }) => {
                            CoarseSolve::Chebyshev { iterations, ratio }
                        }
                        (_, c) => c,
                    },
                };
                let smoother = match (mg.smoother.as_deref(), FasParams::default().smoother) {
                    (Some("dynamics"), _) => Smoother::Dynamics,
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
                        scaling: match mg.scaling.as_deref() {
                            Some("mass") => Scaling::Mass,
                            Some(_) => Scaling::Fictitious,
                            None => scaling,
                        },
                    },
                    (_, s) => s,
                };
                Box::new(Fas::new(
                    levels,
                    links,
                    FasParams {
                        pre_smooth: mg.pre_smooth.unwrap_or(FasParams::default().pre_smooth),
                        post_smooth: mg.post_smooth.unwrap_or(FasParams::default().post_smooth),
                        coarse,
                        smoother,
                        weights: match mg.transfer.as_deref() {
                            Some("exact") => TransferWeights::Exact,
                            Some("convex-restriction") => TransferWeights::ConvexRestriction,
                            _ => TransferWeights::Convex,
                        },
                        krylov: match mg.accelerate.as_deref() {
                            Some("none") => false,
                            Some(_) => true,
                            None => FasParams::default().krylov,
                        },
                        kinetic_limit: limit,
                        ..FasParams::default()
                    },
                ))
            }
        })
    }
}
