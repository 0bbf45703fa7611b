//! [`Model::stepper`]: a model, a [`Scheme`] and the [`Stepping`] settings into the
//! [`Stepper`] that advances the model, for both front doors (a scenario's
//! [`crate::scenario::Scenario::stepper`], [`crate::sim::SimulationBuilder::build`]).
//!
//! - [`Scheme::SingleLevel`]: the explicit integrator on level 0 at [`Stepping::dt`];
//! - [`Scheme::ImplicitEuler`], [`Scheme::Bdf2`]: backward Euler or BDF2 on level 0
//!   ([`Model::implicit_euler`]), each Newton system solved by conjugate gradients
//!   preconditioned by the Galerkin V-cycle over level 0 and the coarser level
//!   [`coarse_level`] picks where the model has levels and [`ImplicitSolve::solver`] allows,
//!   else by sparse Cholesky;
//! - [`Scheme::Newton`]: the frame solver on level 0 with the coarser level [`coarse_level`]
//!   picks;
//! - [`Scheme::Fas`], [`Scheme::RaisovPaper`]: the multigrid over every level
//!   ([`Model::build_levels`]): level 0 at [`Stepping::dt`], a coarser level at its
//!   [`Stepping::level_dt`], else level 0's step ([`Scheme::RaisovPaper`], as the paper
//!   does), else [`Stepping::safety`] times its estimated critical step.
//!
//! The kinetic-energy ceiling ([`crate::integrate::energy_limit_for`]) is set where
//! [`Stepping::blowup_factor`] is given: that factor times the energy level 0's loads and
//! prescribed motions can put in, plus the work its force-model loads and tools can do
//! ([`Model::model_load_work`]).

use super::{Levels, Model, Scheme};
use crate::error::{Error, Result};
use crate::integrate::{energy_limit_for, Method, SingleLevel, Stepper, StepperParams};
use crate::linalg::smoother::Smoother;
use crate::mesh::ElementKind;
use crate::multigrid::fas::{Fas, FasParams};
use crate::multigrid::raisov::{Raisov, RaisovParams};
use crate::statics::frames::NewtonFrames;
use crate::statics::implicit::{ImplicitEuler, ImplicitParams, ImplicitScheme};
use crate::statics::newton::{coarse_level, MultigridPcg, COARSEN_LIMIT};
use crate::statics::StaticSolver;

/// The settings of backward Euler and BDF2 (`method = "implicit-euler"`, `"bdf2"`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImplicitSolve {
    /// `[integrator] method`: backward Euler or BDF2.
    pub scheme: ImplicitScheme,
    /// `[damping] beta` (s): stiffness-proportional damping, default 0.
    pub beta: f64,
    /// `[integrator] newton_tol`: each step's relative tolerance, default 1e-6
    /// ([`crate::statics::implicit::DEFAULT_REL_TOL`]; the rule in that module's docs).
    pub rel_tol: f64,
    /// `[integrator] max_newton`: Newton iterations at most per step, default 30.
    pub max_newton: usize,
    /// `[integrator] solver`: [`StaticSolver::Auto`] (default), [`StaticSolver::Multigrid`]
    /// or [`StaticSolver::Direct`], resolved when the stepper is built
    /// ([`Model::stepper`]).
    pub solver: StaticSolver,
    /// `[integrator] smoother`: the V-cycle's smoother, defaults as for `method = "newton"`.
    pub smoother: Smoother,
}

impl ImplicitSolve {
    /// The defaults of `scheme`: no stiffness damping, the tolerance and iteration cap of
    /// [`ImplicitParams::new`], [`StaticSolver::Auto`], the smoother of elements `kind`
    /// ([`default_smoother`]).
    pub fn new(scheme: ImplicitScheme, kind: ElementKind) -> ImplicitSolve {
        ImplicitSolve {
            scheme,
            beta: 0.0,
            rel_tol: crate::statics::implicit::DEFAULT_REL_TOL,
            max_newton: crate::statics::implicit::DEFAULT_MAX_NEWTON,
            solver: StaticSolver::Auto,
            smoother: default_smoother(kind),
        }
    }
}

/// The Galerkin V-cycle's smoother for elements of `kind`: [`Smoother::BlockJacobi`] for
/// tetrahedra, [`Smoother::ColouredBlock`] for membranes (on `raisov bench equilibrium`'s
/// cases of its kind, each is the fastest of the three or within 12 % of it, and both run in
/// parallel; point Gauss-Seidel runs on one thread).
pub fn default_smoother(kind: ElementKind) -> Smoother {
    match kind {
        ElementKind::Tri3 => Smoother::ColouredBlock,
        _ => Smoother::BlockJacobi,
    }
}

/// What a stepper needs beyond the model and the scheme (module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct Stepping {
    /// Level 0's step (s): given, or a fraction of its estimated critical step.
    pub dt: f64,
    /// The fraction of the estimated critical step a coarser level of an explicit multigrid
    /// takes without [`Stepping::level_dt`].
    pub safety: f64,
    /// The explicit integrator of each level, level 0 first (one per level the scheme uses).
    pub methods: Vec<Method>,
    /// The step of each level (s), level 0 first, where given.
    pub level_dt: Option<Vec<f64>>,
    /// The factor of the kinetic-energy ceiling that stops a diverging run (a scenario's
    /// `[run] blowup_factor`); `None`: no ceiling from the model (an explicit single level
    /// has none; a multigrid keeps its parameters' own `kinetic_limit`).
    pub blowup_factor: Option<f64>,
    /// The settings of [`Scheme::ImplicitEuler`] and [`Scheme::Bdf2`]; `None`: those of
    /// [`ImplicitSolve::new`].
    pub implicit: Option<ImplicitSolve>,
}

impl Model {
    /// The kinetic-energy ceiling of level 0 for `blowup_factor` (module docs); infinite
    /// without one.
    fn kinetic_ceiling(&self, sys: &crate::integrate::System, blowup: Option<f64>) -> f64 {
        match blowup {
            Some(b) => energy_limit_for(sys, &self.mesh, b) + b * self.model_load_work(&self.mesh),
            None => f64::INFINITY,
        }
    }

    /// The stepper of `scheme` over this model (module docs).
    pub fn stepper(&self, scheme: &Scheme, s: &Stepping) -> Result<Box<dyn Stepper>> {
        Ok(match *scheme {
            Scheme::ImplicitEuler | Scheme::Bdf2 => {
                let imp = s.implicit.unwrap_or_else(|| {
                    ImplicitSolve::new(scheme.implicit().unwrap_or_default(), self.mesh.kind)
                });
                Box::new(self.implicit_euler(s.dt, &imp, s.blowup_factor)?)
            }
            Scheme::SingleLevel(method) => {
                let sys = self.build_system()?;
                let limit = self.kinetic_ceiling(&sys, s.blowup_factor);
                Box::new(SingleLevel::new(
                    sys,
                    method,
                    StepperParams {
                        dt: s.dt,
                        kinetic_limit: limit,
                    },
                ))
            }
            Scheme::Newton(p) => {
                let sys = self.build_system()?;
                let coarse = self.pick_level(coarse_level)?.chosen.map(|(_, m)| m);
                Box::new(NewtonFrames::new(sys, self.mesh.clone(), coarse, p)?)
            }
            Scheme::RaisovPaper(p) => {
                let kinetic_limit = match s.blowup_factor {
                    Some(_) => self.kinetic_ceiling(&self.build_system()?, s.blowup_factor),
                    None => p.kinetic_limit,
                };
                let (levels, links) = self.build_levels(s, true)?;
                Box::new(Raisov::new(
                    levels,
                    links,
                    RaisovParams { kinetic_limit, ..p },
                ))
            }
            Scheme::Fas(p) => {
                let kinetic_limit = match s.blowup_factor {
                    Some(_) => self.kinetic_ceiling(&self.build_system()?, s.blowup_factor),
                    None => p.kinetic_limit,
                };
                let (levels, links) = self.build_levels(s, false)?;
                Box::new(Fas::new(levels, links, FasParams { kinetic_limit, ..p }))
            }
        })
    }

    /// The backward-Euler or BDF2 stepper (`imp.scheme`) of this model at step `dt` (s), the
    /// kinetic-energy ceiling of `blowup_factor` (module docs); an error naming the key where
    /// the solver does not apply: a force model without an element tangent, a node sliding
    /// along a direction other than x, y or z, [`StaticSolver::Krylov`] (matrix-free
    /// Newton-Krylov solves static problems only), [`StaticSolver::Multigrid`] without a
    /// coarser level that [`coarse_level`] accepts.
    pub fn implicit_euler(
        &self,
        dt: f64,
        imp: &ImplicitSolve,
        blowup_factor: Option<f64>,
    ) -> Result<ImplicitEuler> {
        let sys = self.build_system()?;
        let limit = self.kinetic_ceiling(&sys, blowup_factor);
        let model_err = |msg: String| Error::Scenario {
            path: self.path.clone(),
            line: None,
            msg,
        };
        let blocker = sys
            .force
            .tangent_elements()
            .is_none()
            .then_some("the force model has no element tangent");
        if imp.solver == StaticSolver::Krylov {
            return Err(model_err(format!(
                "`integrator.solver` = \"krylov\" does not apply to method = \"{}\" (each step is solved with the assembled tangent): valid are \"auto\", \"multigrid\", \"direct\"",
                imp.scheme.name()
            )));
        }
        if let Some(b) = blocker {
            return Err(model_err(format!(
                "`integrator.method` = \"{}\" does not apply: {b} (each step is solved with the assembled tangent)",
                imp.scheme.name()
            )));
        }
        let mut params = ImplicitParams::new(dt);
        params.rel_tol = imp.rel_tol;
        params.max_newton = imp.max_newton;
        params.kinetic_limit = limit;
        params.scheme = imp.scheme;
        params.beta = imp.beta;
        let mut down = Vec::new();
        if imp.solver != StaticSolver::Direct && !matches!(self.levels, Levels::Single) {
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
                    return Err(model_err(format!(
                        "`integrator.solver` = \"multigrid\": no [multigrid] level has at least 1/{COARSEN_LIMIT} of the finest level's {} nodes (levels: {:?})",
                        picked.counts[0],
                        &picked.counts[1..]
                    )));
                }
                None => {}
            }
        }
        ImplicitEuler::with_levels(sys, params, down).map_err(|e| {
            model_err(format!(
                "`integrator.method` = \"{}\": {e}",
                imp.scheme.name()
            ))
        })
    }
}
