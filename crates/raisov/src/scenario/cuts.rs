//! `[[cut]]`: cuts made during a run (keys in [`super::spec`]; the cut itself in
//! [`crate::mesh::cut`], every level in [`crate::hierarchy::cut`]).
//!
//! A cut at time `s` is made before the first step that starts at or after `s` in a run in
//! time, and before frame `k(s)` ([`super::grasps::frame_of`]) in an interactive run, before
//! that frame's grasps and pins; cuts of the same step or frame in file order. The blade is
//! `quad`, or `edge` swept along `sweep`. What a cut needs: a tetrahedral mesh, a run in time
//! or an interactive run (explicit or implicit integrators, FAS, RaISoV), and no
//! pressure, traction, timed load or tool (their surfaces and nodes are not carried through
//! a cut); anything else is refused when the scenario loads.

use super::spec::{CutSpec, ScenarioSpec};
use super::{err, Scenario};
use crate::mesh::cut::Blade;
use crate::mesh::ElementKind;
use crate::numbers::compact;
use crate::Result;
use std::path::Path;

/// A cut made during the run.
#[derive(Clone, Debug, PartialEq)]
pub struct Cut {
    /// Its index in `[[cut]]`.
    pub index: usize,
    /// Made at this time (s).
    pub time: f64,
    /// The blade.
    pub blade: Blade,
}

/// The `[[cut]]` entries, checked one by one.
pub(super) fn resolve(spec: &ScenarioSpec, path: &Path) -> Result<Vec<Cut>> {
    spec.cut
        .iter()
        .enumerate()
        .map(|(i, c)| resolve_one(c, i, path))
        .collect()
}

fn resolve_one(c: &CutSpec, i: usize, path: &Path) -> Result<Cut> {
    let key = format!("cut[{i}]");
    let time = match c.time {
        None => 0.0,
        Some(s) if s >= 0.0 && s.is_finite() => s,
        Some(s) => {
            return Err(err(
                path,
                format!("`{key}.time` = {}: must be >= 0 (s)", compact(s)),
            ))
        }
    };
    let blade = match (c.quad, c.edge, c.sweep) {
        (Some(q), None, None) => Blade::quad(q),
        (None, Some([a, b]), Some(s)) => Blade::swept(a, b, s),
        _ => {
            return Err(err(
                path,
                format!("`{key}`: give either `quad` (four corners, m) or `edge` (two points, m) and `sweep` (m)"),
            ))
        }
    }
    .map_err(|e| err(path, format!("`{key}`: {e}")))?;
    Ok(Cut {
        index: i,
        time,
        blade,
    })
}

/// Whether the resolved scenario can take its cuts (module docs).
pub(super) fn check(sc: &Scenario) -> Result<()> {
    if sc.cuts.is_empty() {
        return Ok(());
    }
    let refuse = |why: &str| Err(err(&sc.path, format!("[[cut]]: {why}")));
    if sc.mesh.kind != ElementKind::Tet4 {
        return refuse("only tetrahedral meshes can be cut (this one is a triangle membrane)");
    }
    if sc.integrator.statics.is_some() {
        return refuse("a static solve (method = \"newton\") has no time to cut at: use a run in time or an [interactive] section");
    }
    if !sc.surface_loads.is_empty() || !sc.timed_load.is_empty() || !sc.tools.is_empty() {
        return refuse("pressure, traction, timed loads and tools are not carried through a cut yet: remove them, or the cuts");
    }
    Ok(())
}

/// The cuts of a run in progress (a run in time or an interactive run): the cuts by time,
/// the next one, and the levels as cut so far (from the first cut on).
pub(crate) struct RunCuts<'a> {
    cuts: Vec<&'a Cut>,
    next: usize,
    hierarchy: Option<crate::hierarchy::cut::CutHierarchy>,
}

impl<'a> RunCuts<'a> {
    /// The scenario's cuts, none made yet.
    pub(crate) fn new(sc: &'a Scenario) -> RunCuts<'a> {
        let mut cuts: Vec<&Cut> = sc.cuts.iter().collect();
        cuts.sort_by(|a, b| a.time.total_cmp(&b.time));
        RunCuts {
            cuts,
            next: 0,
            hierarchy: None,
        }
    }

    /// Make the cuts due at `t` (those at or before `t + tol`) on `stepper`, whose level 0 is
    /// the scenario's mesh as cut so far; returns whether the body's topology changed. An
    /// error names the cut.
    pub(crate) fn make_due(
        &mut self,
        sc: &Scenario,
        t: f64,
        tol: f64,
        stepper: &mut dyn crate::integrate::Stepper,
    ) -> Result<bool> {
        let mut changed = false;
        while let Some(c) = self
            .cuts
            .get(self.next)
            .copied()
            .filter(|c| c.time <= t + tol)
        {
            self.next += 1;
            let at = |e: crate::Error| {
                err(
                    &sc.path,
                    format!("cut[{}] at t = {} s: {e}", c.index, compact(t)),
                )
            };
            if self.hierarchy.is_none() {
                let mut meshes = vec![sc.mesh.clone()];
                for l in 1..stepper.num_levels() {
                    match stepper.level_mesh(l) {
                        Some(m) => meshes.push(m.clone()),
                        None => break,
                    }
                }
                let links = stepper.level_links().map(<[_]>::to_vec).unwrap_or_default();
                meshes.truncate(links.len() + 1);
                self.hierarchy =
                    Some(crate::hierarchy::cut::CutHierarchy::new(meshes, links).map_err(at)?);
            }
            let h = self.hierarchy.as_mut().expect("built above");
            let hc = h.cut(&c.blade).map_err(at)?;
            if !hc.is_identity() {
                stepper.cut(&hc).map_err(at)?;
                changed = true;
            }
        }
        Ok(changed)
    }

    /// Level 0 as cut, once a cut split an element.
    pub(crate) fn level0(&self) -> Option<&crate::mesh::cut::CutMesh> {
        self.hierarchy
            .as_ref()
            .map(|h| &h.levels()[0])
            .filter(|l| l.is_cut())
    }
}

/// What a frame of a cut body carries beyond the uncut one's: the cut mesh, each node of the
/// scenario's mesh's copies, and the cell data (the scenario's, per base element, and each
/// element's `material_fraction`).
pub(crate) struct CutFrame {
    /// Level 0's cut mesh.
    pub mesh: crate::mesh::Mesh,
    /// Per node of the scenario's mesh, its copies in the cut mesh.
    pub copies: Vec<Vec<u32>>,
    /// `fibre` (3 per element) where the scenario has a fibre field, else empty.
    pub fibre: Vec<f64>,
    /// Each element's material fraction.
    pub fraction: Vec<f64>,
    /// Each node's file id, where the scenario has them.
    pub file_ids: Option<Vec<i64>>,
}

impl CutFrame {
    /// The frame data of `level0`, the scenario's mesh as cut.
    pub(crate) fn of(sc: &Scenario, level0: &crate::mesh::cut::CutMesh) -> CutFrame {
        let mesh = level0.mesh().clone();
        let mut copies = vec![Vec::new(); sc.mesh.num_nodes()];
        for (a, &o) in level0.base_nodes().iter().enumerate() {
            copies[o as usize].push(a as u32);
        }
        let fibre = match &sc.fibres {
            Some(f) => {
                let flat = f.level0.flat();
                level0
                    .base_elements()
                    .iter()
                    .flat_map(|&e| flat[3 * e as usize..3 * e as usize + 3].iter().copied())
                    .collect()
            }
            None => Vec::new(),
        };
        let file_ids = sc.output_node_ids().map(|ids| {
            level0
                .base_nodes()
                .iter()
                .map(|&o| ids[o as usize])
                .collect()
        });
        CutFrame {
            mesh,
            copies,
            fibre,
            fraction: level0.fractions().to_vec(),
            file_ids,
        }
    }

    /// The cell fields of a frame.
    pub(crate) fn cell_fields(&self) -> Vec<crate::io::Field<'_>> {
        let mut f = Vec::new();
        if !self.fibre.is_empty() {
            f.push(crate::io::Field {
                name: "fibre",
                data: crate::io::FieldData::Vector(&self.fibre),
            });
        }
        f.push(crate::io::Field {
            name: "material_fraction",
            data: crate::io::FieldData::Scalar(&self.fraction),
        });
        f
    }
}
