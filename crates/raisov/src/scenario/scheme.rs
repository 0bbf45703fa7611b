//! The scheme a scenario resolves to and its stepper: [`Scenario::scheme`] from
//! `[integrator] method` and `[multigrid] scheme`, [`Scenario::stepping`] from `[integrator]`,
//! `[multigrid]` and `[run]`, both handed to the model's [`Model::stepper`].
//!
//! `method = "implicit-euler"` and `"bdf2"`: `solver = "auto"` takes the Galerkin V-cycle over
//! level 0 and the coarser level [`crate::statics::newton::coarse_level`] picks (the same
//! choice as the static solve's) where `[multigrid]` gives one, else sparse Cholesky;
//! `"multigrid"` without such a level, a force model without an element tangent, or a node
//! sliding along a direction other than x, y or z is an error naming the key
//! ([`Model::implicit_euler`]).

use super::{Model, Scenario, Scheme, Stepping};
use crate::error::{Error, Result};
use crate::integrate::Stepper;
use crate::statics::implicit::{ImplicitEuler, ImplicitScheme};

impl Scenario {
    /// The `[integrator] method` name as the scenario gives it (`"implicit-euler"`, `"bdf2"`
    /// and `"newton"` included).
    pub fn method_name(&self) -> &'static str {
        if let Some(imp) = &self.integrator.implicit {
            imp.scheme.name()
        } else if self.integrator.statics.is_some() {
            "newton"
        } else {
            self.integrator.method.name()
        }
    }

    /// The scheme [`Scenario::stepper`] builds: backward Euler or BDF2 (`[integrator] method =
    /// "implicit-euler"`, `"bdf2"`; its levels, if any, precondition the Newton solves), else
    /// `[multigrid] scheme` over the levels, else `[integrator] method`'s explicit integrator
    /// on one level. A static solve (`method = "newton"`, [`crate::scenario::IntegratorSettings::statics`]) is run by
    /// [`crate::runner::run_static`], not by a stepper: its scheme is that of its levels, or
    /// the default integrator on one level.
    pub fn scheme(&self) -> Scheme {
        match (&self.integrator.implicit, &self.multigrid) {
            (Some(i), _) => match i.scheme {
                ImplicitScheme::BackwardEuler => Scheme::ImplicitEuler,
                ImplicitScheme::Bdf2 => Scheme::Bdf2,
            },
            (None, Some(mg)) => mg.scheme,
            (None, None) => Scheme::SingleLevel(self.integrator.method),
        }
    }

    /// The step settings of this scenario's stepper: `[integrator] dt` (or the estimate) and
    /// `safety`, `[multigrid] level_methods` and `level_dt`, `[run] blowup_factor`, and the
    /// backward-Euler settings.
    pub fn stepping(&self) -> Stepping {
        Stepping {
            dt: self.integrator.dt,
            safety: self.integrator.safety,
            methods: match &self.multigrid {
                Some(mg) => mg.methods.clone(),
                None => vec![self.integrator.method; self.num_levels()],
            },
            level_dt: self.multigrid.as_ref().and_then(|mg| mg.level_dt.clone()),
            blowup_factor: Some(self.run.blowup_factor),
            implicit: self.integrator.implicit,
        }
    }

    /// Every level of the model with this scenario's integrators and steps, and the
    /// correspondences between consecutive levels ([`Model::build_levels`]; level 0's step on
    /// every level where the scheme is the paper's).
    pub fn build_levels(&self) -> Result<(Vec<crate::multigrid::Level>, crate::multigrid::Links)> {
        let paper = matches!(self.scheme(), Scheme::RaisovPaper(_));
        self.model.build_levels(&self.stepping(), paper)
    }

    /// The stepper of [`Scenario::scheme`] over the model ([`Model::stepper`]): single level
    /// (explicit, or backward Euler with the levels as the Newton solver's preconditioner),
    /// or a multigrid over its levels.
    pub fn stepper(&self) -> Result<Box<dyn Stepper>> {
        self.model.stepper(&self.scheme(), &self.stepping())
    }

    /// The backward-Euler or BDF2 stepper of `method = "implicit-euler"` or `"bdf2"` (module
    /// docs), with the kinetic-energy ceiling of [`Scenario::stepper`]; an error naming the
    /// key where the scenario asks for another method or the solver does not apply.
    pub fn implicit_euler(&self) -> Result<ImplicitEuler> {
        let Some(imp) = &self.integrator.implicit else {
            return Err(Error::Scenario {
                path: self.path.clone(),
                line: None,
                msg: format!(
                    "`integrator.method` = \"{}\": backward Euler needs method = \"implicit-euler\" (or \"bdf2\")",
                    self.method_name()
                ),
            });
        };
        Model::implicit_euler(
            &self.model,
            self.integrator.dt,
            imp,
            Some(self.run.blowup_factor),
        )
    }
}
