//! The settings a scenario runs with, beside its [`Model`]: `[integrator]`
//! ([`IntegratorSettings`]: the method and its step, a static solve's [`StaticSolve`],
//! backward Euler's [`ImplicitSolve`]), `[run]` ([`RunSettings`]: how a run ends) and
//! `[output]` ([`OutputSettings`]: where and how results are written), each checked against
//! the spec with errors naming the key and what is valid.

use super::spec::{defaults, NewtonSmoother, ScenarioSpec, Stop};
use super::{err, positive, spec, ImplicitSolve, Model, SchemeKind, StaticSolver};
use crate::error::Result;
use crate::fem::Precision;
use crate::integrate::stability::{critical_step_estimate, step_too_large};
use crate::integrate::Method;
use crate::io::VtuFormat;
use crate::linalg::smoother::Smoother;
use crate::material::Material;
use crate::mesh::ElementKind;
use crate::numbers::compact;
use crate::statics::implicit::ImplicitScheme;
use std::path::{Path, PathBuf};

/// How a run ends.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StopRule {
    /// Run for this much simulated time (s).
    Duration(f64),
    /// Run until kinetic energy and residual fall below the tolerances (relative to their
    /// peaks), or until `max` simulated seconds.
    Steady {
        /// `[run] kinetic_tol`: kinetic energy below this × its peak, default 1e-8.
        kinetic_tol: f64,
        /// `[run] residual_tol`: residual norm below this × its peak, default 1e-4.
        residual_tol: f64,
        /// `[run] duration`: the cap on simulated time (s), default 60.
        max: f64,
        /// Checks (rows of `measures.csv`) without progress after which the run gives up;
        /// 0 never (see [`run`](fn@crate::runner::run)).
        stagnation: u64,
    },
}

/// Where |T − T∞| takes T∞ from (`[output] reference`).
#[derive(Clone, Debug, PartialEq, Default)]
pub enum Reference {
    /// No T∞: the |T − T∞| measures are not computed (`"none"`, the default).
    #[default]
    None,
    /// Compute the steady state first, to a tolerance far below the run's.
    Auto,
    /// A `nodal_stress.csv` written by an earlier run on the same mesh.
    File(PathBuf),
}

/// `[integrator]`: how level 0 is advanced, with `[multigrid]` ([`super::Scenario::multigrid`]) the
/// scheme's settings ([`super::Scenario::scheme`], [`super::Scenario::stepping`]).
#[derive(Clone, Debug, PartialEq)]
pub struct IntegratorSettings {
    /// `[integrator] method`: the explicit integrator of level 0 (and of every level without
    /// `[multigrid] level_methods`), default symplectic Euler; with `method = "newton"` that
    /// default, and no step is taken ([`IntegratorSettings::statics`]).
    pub method: Method,
    /// Time step (s), given or estimated.
    pub dt: f64,
    /// The estimated critical step (s) the default `dt` derives from.
    pub dt_critical_estimate: f64,
    /// `[integrator] safety`: the fraction of the estimated critical step taken where no step
    /// is given (level 0 without `dt`, coarser FAS levels without `level_dt`).
    pub safety: f64,
    /// `[integrator] method = "newton"`: solve for static equilibrium instead of integrating
    /// ([`crate::runner::run_static`]); `None` for a dynamic run.
    pub statics: Option<StaticSolve>,
    /// `[integrator] method = "implicit-euler"` or `"bdf2"`: backward Euler or BDF2
    /// ([`crate::statics::implicit`]) instead of [`crate::scenario::IntegratorSettings::method`]; `None` for the explicit
    /// integrators and the static solve.
    pub implicit: Option<ImplicitSolve>,
}

/// `[run]`: how a run ends.
#[derive(Clone, Debug, PartialEq)]
pub struct RunSettings {
    /// `[run] stop` with its duration and tolerances.
    pub stop: StopRule,
    /// `[run] blowup_factor`: the factor of the kinetic-energy ceiling that stops a diverging
    /// run ([`crate::integrate::energy_limit`]), default 1e3.
    pub blowup_factor: f64,
}

/// `[output]` (and `raisov run --out`): where and how a run writes its results.
#[derive(Clone, Debug, PartialEq)]
pub struct OutputSettings {
    /// The output directory: `raisov run --out`, else `[output] dir` relative to the
    /// scenario file, else `raisov-out/NAME` relative to the working directory.
    pub dir: PathBuf,
    /// `[output] frame_interval`: simulated time between frames (s), default 0.05; 0 writes
    /// only the first and last.
    pub frame_interval: f64,
    /// `[output] csv_every`: steps between rows of `measures.csv` (at least 1), default 1.
    pub csv_every: u64,
    /// `[output] vtu`: how the frames are stored (binary appended zlib, or ASCII).
    pub vtu: VtuFormat,
    /// `[output] reference`: where T∞ of |T − T∞| comes from; a file's path is joined to the
    /// scenario file's directory.
    pub reference: Reference,
}

/// The settings of a static solve (`method = "newton"`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StaticSolve {
    /// `[run] residual_tol`, default 1e-7. [`StaticSolver::Krylov`] stops when
    /// `‖V − R(u)‖ ≤ rel_tol · max(‖V − R(0)‖, ‖V‖)`; [`StaticSolver::Direct`] and
    /// [`StaticSolver::Multigrid`] when the largest nodal residual over free nodes is at most
    /// `rel_tol` times (the largest nodal load + the largest nodal out-of-balance force at the
    /// start, prescribed motions imposed) plus 1e-14 N.
    pub rel_tol: f64,
    /// Newton steps at most per increment (`[integrator] max_newton`, default 50).
    pub max_newton: usize,
    /// Load increments (`[integrator] increments`); `None`: 10 for [`StaticSolver::Krylov`],
    /// 1 for the others ([`StaticSolve::increments`]).
    pub increments: Option<usize>,
    /// `[integrator] solver`, default [`StaticSolver::Auto`] (resolved when the system is
    /// built: [`crate::runner::run_static`]).
    pub solver: StaticSolver,
    /// `[integrator] coarse_start`: [`StaticSolver::Multigrid`] starts from the coarse level's
    /// equilibrium, interpolated ([`crate::statics::nested::coarse_start`]). Default
    /// true for membranes, false for tetrahedra (`raisov bench equilibrium` times both starts
    /// on every case: the coarse start is the faster on the drapes, not on the livers).
    pub coarse_start: bool,
    /// `[integrator] smoother`: [`StaticSolver::Multigrid`]'s V-cycle smoother. Default
    /// [`Smoother::BlockJacobi`] for tetrahedra, [`Smoother::ColouredBlock`] for membranes
    /// (on `raisov bench equilibrium`'s cases of its kind, each is the fastest of the three or
    /// within 12 % of it, and both run in parallel; point Gauss-Seidel runs on one thread).
    pub smoother: Smoother,
}

impl StaticSolve {
    /// [`StaticSolve::smoother`]'s default for elements of `kind`.
    pub fn default_smoother(kind: ElementKind) -> Smoother {
        crate::model::default_smoother(kind)
    }

    /// The load increments for a resolved `solver`.
    pub fn increments(&self, solver: StaticSolver) -> usize {
        self.increments.unwrap_or(match solver {
            StaticSolver::Krylov => defaults::INCREMENTS,
            _ => defaults::ASSEMBLED_INCREMENTS,
        })
    }
}

/// `[integrator]` resolved against the model: the method, the step (given, or `safety`
/// times the estimated critical step), the static solve's or backward Euler's settings, and
/// the keys that do not apply to the method (errors naming them); a precision the model
/// cannot use is a note, a step far above the critical estimate a warning.
pub(super) fn resolve_integrator(
    spec: &ScenarioSpec,
    path: &Path,
    model: &Model,
    notes: &mut Vec<String>,
    warnings: &mut Vec<String>,
) -> Result<IntegratorSettings> {
    let (mesh, material, density) = (&model.mesh, &model.material, model.density);
    let tools = &model.tools;
    let (method, newton, scheme) = match spec.integrator.method {
        Some(spec::Solve::Dynamic(m)) => (m, false, None),
        Some(spec::Solve::Newton) => (defaults::METHOD, true, None),
        Some(spec::Solve::ImplicitEuler) => {
            (defaults::METHOD, false, Some(ImplicitScheme::BackwardEuler))
        }
        Some(spec::Solve::Bdf2) => (defaults::METHOD, false, Some(ImplicitScheme::Bdf2)),
        None => (defaults::METHOD, false, None),
    };
    let implicit = scheme.is_some();
    let beta = match spec.damping.beta {
        None => 0.0,
        Some(b) if !(b >= 0.0 && b.is_finite()) => {
            return Err(err(
                path,
                format!("`damping.beta` = {}: must be >= 0 (s)", compact(b)),
            ))
        }
        Some(b) if b > 0.0 && !implicit => {
            return Err(err(
                path,
                format!(
                    "`damping.beta` (stiffness-proportional damping) applies to method = \"implicit-euler\" or \"bdf2\", not \"{}\": the explicit integrators take `damping.alpha` (D = alpha M) only, and a static solve (\"newton\") has no damping",
                    if newton { "newton" } else { method.name() }
                ),
            ))
        }
        Some(b) => b,
    };
    for (k, set, applies, to) in [
        (
            "max_newton",
            spec.integrator.max_newton.is_some(),
            newton || implicit,
            "method = \"newton\", \"implicit-euler\" or \"bdf2\"",
        ),
        (
            "increments",
            spec.integrator.increments.is_some(),
            newton,
            "method = \"newton\"",
        ),
        (
            "solver",
            spec.integrator.solver.is_some(),
            newton || implicit,
            "method = \"newton\", \"implicit-euler\" or \"bdf2\"",
        ),
        (
            "coarse_start",
            spec.integrator.coarse_start.is_some(),
            newton,
            "method = \"newton\"",
        ),
        (
            "smoother",
            spec.integrator.smoother.is_some(),
            newton || implicit,
            "method = \"newton\", \"implicit-euler\" or \"bdf2\"",
        ),
        (
            "newton_tol",
            spec.integrator.newton_tol.is_some(),
            implicit,
            "method = \"implicit-euler\" or \"bdf2\" (method = \"newton\" takes `run.residual_tol`)",
        ),
    ] {
        if set && !applies {
            return Err(err(path, format!("`integrator.{k}` applies to {to}")));
        }
    }
    // `[multigrid]` keys of the explicit schemes, errors where the levels only serve the
    // Newton solver's preconditioner.
    let levels_only = |what: &str| -> Result<()> {
        if let Some(m) = &spec.multigrid {
            for (k, set) in [
                ("scheme", m.scheme.is_some()),
                ("reading", m.reading.is_some()),
                ("epsilon", m.epsilon.is_some()),
                ("pre_smooth", m.pre_smooth.is_some()),
                ("post_smooth", m.post_smooth.is_some()),
                ("coarse", m.coarse.is_some()),
                ("coarse_time", m.coarse_time.is_some()),
                ("coarse_iterations", m.coarse_iterations.is_some()),
                ("smoother", m.smoother.is_some()),
                ("transfer", m.transfer.is_some()),
                ("scaling", m.scaling.is_some()),
                ("accelerate", m.accelerate.is_some()),
                ("level_methods", m.level_methods.is_some()),
                ("level_dt", m.level_dt.is_some()),
            ] {
                if set {
                    return Err(err(
                        path,
                        format!("`multigrid.{k}` does not apply to method = \"{what}\": it takes only the levels of [multigrid] (`levels`, `ratio`, `level_nodes`, `files`)"),
                    ));
                }
            }
        }
        Ok(())
    };
    let implicit = match scheme {
        Some(scheme) => Some(resolve_implicit(
            spec,
            path,
            mesh.kind,
            &levels_only,
            scheme,
            beta,
        )?),
        None => None,
    };
    // A rate-dependent law advances its internal variables with the single-level
    // steppers (explicit and backward Euler, in plain and interactive runs, whose
    // checkpoints keep them) and is fully relaxed in a static solve; the explicit
    // multigrid schemes do not carry them.
    if matches!(material, Material::NeoHookeanVisco(_))
        && spec.multigrid.is_some()
        && !newton
        && implicit.is_none()
    {
        return Err(err(
            path,
            format!("`[multigrid]` with method = \"{}\" does not apply to law = \"neo-hookean-visco\": the explicit multigrid schemes do not advance the law's internal variables (remove [multigrid], or use method = \"implicit-euler\", whose Newton solver takes the levels, or \"newton\" for the fully relaxed equilibrium)", method.name()),
        ));
    }
    if let (false, None, Some(_)) = (newton, &implicit, &spec.multigrid) {
        if let Some(i) = tools.iter().position(|t| t.friction.is_some()) {
            return Err(err(
                path,
                format!(
                    "`tool[{i}]` has friction, which the explicit multigrid schemes of \
                     `[multigrid]` do not carry (a cycle is not a step of the tool's path \
                     on every level): run it on one level (remove `[multigrid]`), or with \
                     method = \"implicit-euler\" (whose levels only precondition its \
                     Newton solve), or remove `friction` / `static_friction` from tool[{i}]"
                ),
            ));
        }
    }
    let statics = match newton {
        true => Some(resolve_static(spec, path, model, &levels_only)?),
        false => None,
    };
    let precision = spec.integrator.precision.unwrap_or_default();
    if precision != Precision::F64
        && !(mesh.kind == ElementKind::Tet4 && matches!(material, Material::NeoHookean(_)))
    {
        notes.push(format!(
            "integrator.precision = \"{}\" applies to neo-Hookean tetrahedra only; this model runs in f64",
            precision.name()
        ));
    }
    let dt_crit = critical_step_estimate(mesh, material, density, method);
    let safety = positive(
        path,
        "integrator.safety",
        spec.integrator.safety.unwrap_or(defaults::SAFETY),
    )?;
    let dt = match spec.integrator.dt {
        Some(dt) => positive(path, "integrator.dt", dt)?,
        None => safety * dt_crit,
    };
    // FAS relaxes rather than integrates: its level-0 step is a smoother's, not bound
    // by the explicit stability limit in the same way.
    let explicit_limit = !newton
        && implicit.is_none()
        && spec
            .multigrid
            .as_ref()
            .is_none_or(|m| m.scheme == Some(SchemeKind::RaisovPaper));
    if let Some(w) = step_too_large(dt, dt_crit, method).filter(|_| explicit_limit) {
        warnings.push(format!(
            "integrator.{w} (leave `dt` out to take {} of the estimate)",
            compact(safety)
        ));
    }
    Ok(IntegratorSettings {
        method,
        dt,
        dt_critical_estimate: dt_crit,
        safety,
        statics,
        implicit,
    })
}

/// `method = "newton"` resolved against the model: the loads must settle (no sine), nothing
/// interactive or path dependent (friction), the solver and its keys.
fn resolve_static(
    spec: &ScenarioSpec,
    path: &Path,
    model: &Model,
    levels_only: &dyn Fn(&str) -> Result<()>,
) -> Result<StaticSolve> {
    let mesh = &model.mesh;
    let (tools, surface_loads) = (&model.tools, &model.surface_loads);
    let (timed_load, prescribed) = (&model.timed_load, &model.prescribed);
    let settles = surface_loads.iter().all(|s| s.time.end().is_finite())
        && timed_load.iter().all(|(_, _, f)| f.end().is_finite())
        && tools.iter().all(|t| t.motion.end().is_finite())
        && prescribed.iter().all(|(_, m)| m.end().is_finite());
    if !settles {
        return Err(err(
            path,
            "method = \"newton\" solves for the loads at their end: a `sine` time function never ends",
        ));
    }
    if spec.interactive.is_some() {
        return Err(err(
            path,
            "`[interactive]` does not apply to method = \"newton\" (a static solve)",
        ));
    }
    if let Some(i) = tools.iter().position(|t| t.friction.is_some()) {
        return Err(err(
            path,
            format!(
                "`tool[{i}]` has friction, which is path dependent (the tool's path \
                 decides where nodes stick and slip), and method = \"newton\" solves \
                 for the end state alone: step it in time with an explicit method or \
                 method = \"implicit-euler\", or remove `friction` / \
                 `static_friction` from tool[{i}]"
            ),
        ));
    }
    levels_only("newton")?;
    let solver = spec.integrator.solver.unwrap_or(defaults::STATIC_SOLVER);
    if solver == StaticSolver::Multigrid && spec.multigrid.is_none() {
        return Err(err(
            path,
            "`integrator.solver` = \"multigrid\" needs the coarser levels of a `[multigrid]` section (`levels`, `nodes` or `files`)",
        ));
    }
    let rel_tol = positive(
        path,
        "run.residual_tol",
        spec.run.residual_tol.unwrap_or(defaults::NEWTON_TOL),
    )?;
    let max_newton = spec.integrator.max_newton.unwrap_or(defaults::MAX_NEWTON);
    if max_newton == 0 {
        return Err(err(path, "`integrator.max_newton` = 0: must be at least 1"));
    }
    if spec.integrator.increments == Some(0) {
        return Err(err(path, "`integrator.increments` = 0: must be at least 1"));
    }
    if spec.integrator.smoother.is_some()
        && matches!(solver, StaticSolver::Direct | StaticSolver::Krylov)
    {
        return Err(err(
            path,
            format!(
                "`integrator.smoother` applies to solver = \"multigrid\" (or \"auto\"), not \"{}\"",
                solver.name()
            ),
        ));
    }
    if spec.integrator.coarse_start == Some(true)
        && matches!(solver, StaticSolver::Direct | StaticSolver::Krylov)
    {
        return Err(err(
            path,
            format!(
                "`integrator.coarse_start` = true applies to solver = \"multigrid\" (or \"auto\"), not \"{}\"",
                solver.name()
            ),
        ));
    }
    Ok(StaticSolve {
        rel_tol,
        max_newton,
        increments: spec.integrator.increments,
        solver,
        coarse_start: spec
            .integrator
            .coarse_start
            .unwrap_or(mesh.kind == ElementKind::Tri3),
        smoother: match spec.integrator.smoother {
            Some(NewtonSmoother::BlockJacobi) => Smoother::BlockJacobi,
            Some(NewtonSmoother::BlockGaussSeidel) => Smoother::ColouredBlock,
            Some(NewtonSmoother::GaussSeidel) => Smoother::GaussSeidel,
            None => StaticSolve::default_smoother(mesh.kind),
        },
    })
}

/// `[integrator]` of `method = "implicit-euler"` or `"bdf2"` (`scheme`) checked
/// (`levels_only` refuses the `[multigrid]` keys of the explicit schemes); `beta` the
/// resolved `[damping] beta`.
fn resolve_implicit(
    spec: &ScenarioSpec,
    path: &Path,
    kind: ElementKind,
    levels_only: &dyn Fn(&str) -> Result<()>,
    scheme: ImplicitScheme,
    beta: f64,
) -> Result<ImplicitSolve> {
    let i = &spec.integrator;
    let what = scheme.name();
    if i.dt.is_none() {
        return Err(err(
            path,
            format!("`integrator.dt` is required with method = \"{what}\": it is stable at any step, so choose the step for accuracy (e.g. 1/60 s for one step a frame at 60 Hz)"),
        ));
    }
    if i.safety.is_some() {
        return Err(err(
            path,
            format!("`integrator.safety` does not apply to method = \"{what}\" (it scales the explicit critical step; give `dt`)"),
        ));
    }
    levels_only(what)?;
    let solver = i.solver.unwrap_or(defaults::STATIC_SOLVER);
    match solver {
        StaticSolver::Krylov => {
            return Err(err(
                path,
                format!("`integrator.solver` = \"krylov\" does not apply to method = \"{what}\" (each step is solved with the assembled tangent): valid are \"auto\", \"multigrid\", \"direct\""),
            ))
        }
        StaticSolver::Multigrid if spec.multigrid.is_none() => {
            return Err(err(
                path,
                "`integrator.solver` = \"multigrid\" needs the coarser levels of a `[multigrid]` section (`levels`, `nodes` or `files`)",
            ))
        }
        StaticSolver::Direct if i.smoother.is_some() => {
            return Err(err(
                path,
                "`integrator.smoother` applies to solver = \"multigrid\" (or \"auto\"), not \"direct\"",
            ))
        }
        _ => {}
    }
    let max_newton = i
        .max_newton
        .unwrap_or(crate::statics::implicit::DEFAULT_MAX_NEWTON);
    if max_newton == 0 {
        return Err(err(path, "`integrator.max_newton` = 0: must be at least 1"));
    }
    let rel_tol = positive(
        path,
        "integrator.newton_tol",
        i.newton_tol
            .unwrap_or(crate::statics::implicit::DEFAULT_REL_TOL),
    )?;
    Ok(ImplicitSolve {
        scheme,
        beta,
        rel_tol,
        max_newton,
        solver,
        smoother: match i.smoother {
            Some(NewtonSmoother::BlockJacobi) => Smoother::BlockJacobi,
            Some(NewtonSmoother::BlockGaussSeidel) => Smoother::ColouredBlock,
            Some(NewtonSmoother::GaussSeidel) => Smoother::GaussSeidel,
            None => StaticSolve::default_smoother(kind),
        },
    })
}

/// `[run]` resolved: the stop rule and its tolerances (a static solve, `newton`, has no
/// time: its motions are taken at their end), the blow-up factor.
pub(super) fn resolve_run(spec: &ScenarioSpec, path: &Path, newton: bool) -> Result<RunSettings> {
    let duration = spec
        .run
        .duration
        .map(|d| positive(path, "run.duration", d))
        .transpose()?;
    let stop = match spec.run.stop.unwrap_or_default() {
        // A static solve has no time: the motions are taken at their end.
        _ if newton => StopRule::Duration(duration.unwrap_or(0.0)),
        Stop::Duration => {
            for (k, set) in [
                ("kinetic_tol", spec.run.kinetic_tol.is_some()),
                ("residual_tol", spec.run.residual_tol.is_some()),
                ("stagnation", spec.run.stagnation.is_some()),
            ] {
                if set {
                    return Err(err(path, format!("`run.{k}` applies to stop = \"steady\"")));
                }
            }
            StopRule::Duration(duration.ok_or_else(|| {
                err(
                    path,
                    "[run]: `duration` (s) is required when stop = \"duration\"",
                )
            })?)
        }
        Stop::Steady => StopRule::Steady {
            kinetic_tol: positive(
                path,
                "run.kinetic_tol",
                spec.run.kinetic_tol.unwrap_or(defaults::KINETIC_TOL),
            )?,
            residual_tol: positive(
                path,
                "run.residual_tol",
                spec.run.residual_tol.unwrap_or(defaults::RESIDUAL_TOL),
            )?,
            max: duration.unwrap_or(defaults::STEADY_CAP),
            stagnation: spec.run.stagnation.unwrap_or(defaults::STAGNATION),
        },
    };
    let blowup_factor = positive(
        path,
        "run.blowup_factor",
        spec.run.blowup_factor.unwrap_or(defaults::BLOWUP_FACTOR),
    )?;
    Ok(RunSettings {
        stop,
        blowup_factor,
    })
}

/// `[output]` resolved: the directory (`out`, else `dir` joined to the scenario's directory
/// `base`, else `raisov-out/NAME`), the frame interval, the rows of `measures.csv`, the VTU
/// format, and the T∞ reference (a file must exist).
pub(super) fn resolve_output(
    spec: &ScenarioSpec,
    path: &Path,
    base: &Path,
    name: &str,
    out: Option<&Path>,
) -> Result<OutputSettings> {
    let out_dir = match out {
        Some(o) => o.to_path_buf(),
        None => spec
            .output
            .dir
            .as_ref()
            .map(|d| base.join(d))
            .unwrap_or_else(|| PathBuf::from(defaults::OUTPUT_ROOT).join(name)),
    };
    let frame_interval = spec
        .output
        .frame_interval
        .unwrap_or(defaults::FRAME_INTERVAL);
    if !(frame_interval >= 0.0 && frame_interval.is_finite()) {
        return Err(err(
            path,
            format!(
                "`output.frame_interval` = {}: must be >= 0 (s)",
                compact(frame_interval)
            ),
        ));
    }
    let csv_every = spec.output.csv_every.unwrap_or(defaults::CSV_EVERY);
    if csv_every == 0 {
        return Err(err(
            path,
            "`output.csv_every` = 0: must be at least 1 (steps)",
        ));
    }
    let vtu = spec.output.vtu.unwrap_or_default();
    let reference = match spec.output.reference.clone().unwrap_or_default() {
        Reference::File(p) => {
            let p = base.join(p);
            if !p.is_file() {
                return Err(err(path, format!("`output.reference` = {}: no such file (valid: \"none\", \"auto\", or a nodal_stress.csv of an earlier run)", p.display())));
            }
            Reference::File(p)
        }
        r => r,
    };
    Ok(OutputSettings {
        dir: out_dir,
        frame_interval,
        csv_every,
        vtu,
        reference,
    })
}
