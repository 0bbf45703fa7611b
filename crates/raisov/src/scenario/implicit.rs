//! `method = "implicit-euler"` and `"bdf2"`: [`Scenario::implicit`]'s solver resolved against
//! the built system into an [`ImplicitEuler`] stepper (its scheme, and `[damping] beta`). `solver = "auto"` takes the Galerkin V-cycle over
//! level 0 and the coarser level [`coarse_level`] picks (the same choice as the static
//! solve's) where `[multigrid]` gives one, else sparse Cholesky; `"multigrid"` without such a
//! level, a force model without an element tangent, or a node sliding along a direction other
//! than x, y or z is an error naming the key.

use super::{Scenario, StaticSolver};
use crate::error::{Error, Result};
use crate::integrate::energy_limit_for;
use crate::statics::implicit::{ImplicitEuler, ImplicitParams};
use crate::statics::newton::{axis_of, coarse_level, MultigridPcg, COARSEN_LIMIT};

impl Scenario {
    /// The `[integrator] method` name as the scenario gives it (`"implicit-euler"`, `"bdf2"`
    /// and `"newton"` included).
    pub fn method_name(&self) -> &'static str {
        if let Some(imp) = &self.implicit {
            imp.scheme.name()
        } else if self.statics.is_some() {
            "newton"
        } else {
            self.method.name()
        }
    }

    /// The backward-Euler or BDF2 stepper of `method = "implicit-euler"` or `"bdf2"` (module
    /// docs), with the
    /// kinetic-energy ceiling of [`Scenario::stepper`]; an error naming the key where the
    /// scenario asks for another method or the solver does not apply.
    pub fn implicit_euler(&self) -> Result<ImplicitEuler> {
        let Some(imp) = &self.implicit else {
            return Err(Error::Scenario {
                path: self.path.clone(),
                line: None,
                msg: format!(
                    "`integrator.method` = \"{}\": backward Euler needs method = \"implicit-euler\" (or \"bdf2\")",
                    self.method_name()
                ),
            });
        };
        let sys = self.build_system()?;
        let limit = energy_limit_for(&sys, &self.mesh, self.blowup_factor)
            + self.blowup_factor * self.model_load_work(&self.mesh);
        let scenario_err = |msg: String| Error::Scenario {
            path: self.path.clone(),
            line: None,
            msg,
        };
        let blocker = if sys.force.tangent_elements().is_none() {
            Some("the force model has no element tangent".to_string())
        } else {
            sys.constraints
                .sliding()
                .iter()
                .find(|&&(_, d)| axis_of(d).is_none())
                .map(|&(a, _)| {
                    format!(
                        "node {} slides along a direction that is not x, y or z",
                        self.file_node(a)
                    )
                })
        };
        if let Some(b) = blocker {
            return Err(scenario_err(format!(
                "`integrator.method` = \"{}\" does not apply: {b} (each step is solved with the assembled tangent)",
                imp.scheme.name()
            )));
        }
        let mut params = ImplicitParams::new(self.dt);
        params.rel_tol = imp.rel_tol;
        params.max_newton = imp.max_newton;
        params.kinetic_limit = limit;
        params.scheme = imp.scheme;
        params.beta = imp.beta;
        let mut down = Vec::new();
        if imp.solver != StaticSolver::Direct && self.multigrid.is_some() {
            let picked = self.pick_level(coarse_level)?;
            match picked.chosen {
                Some((_, coarse)) => {
                    down.push(crate::hierarchy::Transfer::build(
                        &self.mesh.nodes,
                        &coarse,
                    )?);
                    params.multigrid = Some(MultigridPcg {
                        smoother: imp.smoother,
                        ..Default::default()
                    });
                }
                None if imp.solver == StaticSolver::Multigrid => {
                    return Err(scenario_err(format!(
                        "`integrator.solver` = \"multigrid\": no [multigrid] level has at least 1/{COARSEN_LIMIT} of the finest level's {} nodes (levels: {:?})",
                        picked.counts[0],
                        &picked.counts[1..]
                    )));
                }
                None => {}
            }
        }
        ImplicitEuler::with_levels(sys, params, down).map_err(|e| {
            scenario_err(format!(
                "`integrator.method` = \"{}\": {e}",
                imp.scheme.name()
            ))
        })
    }
}
