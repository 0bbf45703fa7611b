//! What a scenario's runs share of its mesh and its references: the stress a run is compared
//! against (`[output] reference`, an earlier run's `nodal_stress.csv`, read by
//! [`read_nodal_stress`]; `T∞` by dynamic relaxation, [`Scenario::steady_reference`]), the
//! file order of the nodes, and a divergence's node named as messages name nodes
//! ([`Scenario::locate`]). The runners themselves are [`crate::runner`]'s.

use super::Scenario;
use crate::error::{Error, Result};
use crate::integrate::State;
use crate::statics::relax::dynamic::relax;
use std::path::Path;

impl Scenario {
    /// Name the node of `d` (of the stepper's finest level, this scenario's mesh) as
    /// messages to the user name nodes: by its id in the mesh file
    /// ([`crate::model::Model::file_node`]), with its position.
    pub fn locate(&self, d: &mut crate::error::Divergence) {
        let n = self.mesh.num_nodes();
        d.locate(
            |a| match a < n {
                true => self.file_node(a as u32),
                false => a as u64,
            },
            |a| self.mesh.nodes.get(a).copied(),
        );
    }

    /// The time after which every prescribed motion, load and tool is constant.
    pub fn motion_end(&self) -> f64 {
        self.prescribed
            .iter()
            .map(|(_, m)| m.end())
            .fold(self.loads_end(), f64::max)
    }

    /// Steady-state nodal stress T∞ with the constraints at their final values, by dynamic
    /// relaxation to a residual of 1e-10 of the load scale.
    pub fn steady_reference(&self) -> Result<(Vec<f64>, String)> {
        let mut sys = self.build_system()?;
        let n = sys.num_nodes();
        let mut s = State::at_rest(n);
        s.t = self.motion_end();
        let dt = 0.5 * self.integrator.dt_critical_estimate.min(self.integrator.dt);
        let r = relax(&mut sys, s, dt, 1e-10, 2_000_000).map_err(|f| {
            Error::Diverged(crate::error::Divergence {
                time: 0.0,
                step: 0,
                element: Some(f.element),
                cause: crate::error::DivergenceCause::Inverted { det_f: f.det_f },
            })
        })?;
        let mut t = vec![0.0; 9 * n];
        sys.force.nodal_stress(&r.state.u, &mut t);
        let note = format!(
            "T_inf by dynamic relaxation: residual {:.3e} N ({:.1e} of start) after {} steps{}",
            r.residual,
            r.residual / r.initial_residual.max(f64::MIN_POSITIVE),
            r.steps,
            if r.converged {
                ""
            } else {
                " (NOT converged to 1e-10)"
            }
        );
        Ok((t, note))
    }
}

/// The mesh index of each node in file order (the inverse of [`crate::model::Model::file_ids`]; the
/// identity where the mesh keeps the file's order).
pub(crate) fn mesh_index_of_file(file_ids: Option<&[u32]>, n: usize) -> Vec<usize> {
    match file_ids {
        Some(f) => crate::mesh::inverse_order(f)
            .into_iter()
            .map(|k| k as usize)
            .collect(),
        None => (0..n).collect(),
    }
}

/// Read a `nodal_stress.csv` written by an earlier run on the mesh of `sc`; its `node` column
/// holds the file's ids ([`crate::model::Model::file_node`]). Every number must be finite.
pub fn read_nodal_stress(path: &Path, sc: &Scenario) -> Result<Vec<f64>> {
    let n = sc.mesh.num_nodes();
    let at = mesh_index_of_file(sc.file_ids.as_deref(), n);
    let position: std::collections::HashMap<u64, usize> = (0..n)
        .map(|k| {
            let id = sc.node_labels.as_ref().map_or(k as u64, |l| l[k]);
            (id, at[k])
        })
        .collect();
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let bad = |line: usize, msg: String| Error::Scenario {
        path: path.to_path_buf(),
        line: Some(line),
        msg,
    };
    let mut t = vec![f64::NAN; 9 * n];
    let mut rows = 0;
    for (i, line) in text.lines().enumerate().skip(1) {
        if line.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != 16 {
            return Err(bad(
                i + 1,
                format!(
                    "expected 16 columns (node, x, y, z, ux, uy, uz, T00..T22), found {}",
                    f.len()
                ),
            ));
        }
        let id: u64 = f[0]
            .trim()
            .parse()
            .map_err(|_| bad(i + 1, format!("bad node id `{}`", f[0])))?;
        let a = *position.get(&id).ok_or_else(|| {
            bad(
                i + 1,
                format!("node {id} is not a node of this mesh ({n} nodes, ids as in its file)"),
            )
        })?;
        for (col, field) in f.iter().enumerate().skip(1) {
            let x: f64 = field
                .trim()
                .parse()
                .map_err(|_| bad(i + 1, format!("bad number `{field}` in column {}", col + 1)))?;
            if !x.is_finite() {
                return Err(bad(
                    i + 1,
                    format!(
                        "column {} is `{field}`: numbers must be finite (not nan or inf)",
                        col + 1
                    ),
                ));
            }
            if col >= 7 {
                t[9 * a + col - 7] = x;
            }
        }
        rows += 1;
    }
    if rows != n {
        return Err(bad(
            text.lines().count(),
            format!("has {rows} nodes, this mesh has {n}"),
        ));
    }
    Ok(t)
}
