//! The static solve of a scenario (`[integrator] method = "newton"`): `R(u) = V` with the
//! prescribed motions at their end, by the one Newton driver
//! ([`crate::statics::newton::solve_with`]) over one of three linear solves ([`StaticSolver`]):
//!
//! - `"multigrid"`: the assembled analytic tangent `K`, each Newton system `K δu = V − R(u)`
//!   solved by conjugate gradients preconditioned by a Galerkin V-cycle over the finest level
//!   and one coarser `[multigrid]` level ([`crate::statics::newton::coarse_level`]);
//! - `"direct"`: the same tangent factored by sparse Cholesky, the factor reused as the
//!   preconditioner of conjugate gradients while they converge in 20 iterations;
//! - `"krylov"`: matrix-free conjugate gradients, tangent products by central differences
//!   of the forces, preconditioned by the per-node fictitious masses
//!   ([`crate::statics::newton::MatrixFree`]).
//!
//! All three share the driver: a line search on the energy, Eisenstat-Walker tolerances for
//! the inner solves, and for the assembled ones a diagonal regularisation `σ d̄ D` where `K`
//! is not positive definite (a flat membrane's first tangent). They stop when
//! the largest nodal residual over free nodes is at most `residual_tol` times (the largest
//! nodal load + the largest nodal out-of-balance force at the start, the prescribed motions
//! imposed and the free nodes where they are; where that state inverts an element, the force
//! of the largest fraction ½, ¼, … of the motions that does not, over that fraction) plus
//! 1e-14 N. They start with the prescribed nodes at rest; each increment's first
//! iteration moves them with the free nodes' linear response (the lifted iteration of
//! [`crate::statics::newton`]). `"auto"` ([`StaticSolver::resolve`], the policy beside the
//! solvers) takes `"multigrid"` where a coarse level qualifies, `"direct"` where not, and `"krylov"` only where the force model has no element
//! tangent (every model a scenario builds has one: pressure, traction, tools and spring
//! grasps add their blocks to it, and a node sliding along a direction that is not x, y or z
//! is solved by projection, [`crate::statics::newton`]).
//!
//! With `[integrator] coarse_start` (default: membranes yes, tetrahedra no) `"multigrid"`
//! starts from a coarser level's equilibrium, interpolated (nested iteration,
//! [`crate::statics::nested::nested_start`] over the levels of
//! [`crate::statics::nested::start_levels`]): the coarsest of them, with the
//! scenario's constraints and loads carried to it, is solved by direct Newton over the
//! increments, each finer one by Newton-multigrid from the last one's equilibrium, the fine
//! level then in one increment. The stopping rule's starting out-of-balance force
//! is that of the rest state, as without it.

use super::dynamic::{write_balance, write_nodal_stress, Frames};
use super::outputs::{write_output, OutDir};
use super::RunOptions;
use crate::error::{Error, Result};
use crate::integrate::{Stepper, System};
use crate::metrics::{Meter, Sample};
use crate::scenario::{Scenario, StaticSolve, StaticSolver};
use crate::statics::krylov::Static;
use crate::statics::nested::{nested_start, start_levels, BetweenSolve, CoarseStart, NestedLevels};
use crate::statics::newton::{
    coarse_level, solve_system_matrix_free, DirectNewton, DirectNewtonError, DirectNewtonParams,
    DirectStatic, MatrixFreeCg, MultigridPcg,
};
use crate::statics::CoarseOffer;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Absolute floor of the assembled solvers' stopping rule (N).
const ABS_TOL: f64 = 1e-14;
/// Conjugate-gradient iterations preconditioned by a kept factor before `"direct"`
/// refactors ([`DirectNewtonParams::pcg_max`]).
const DIRECT_PCG_MAX: usize = 20;

/// What a static solve (`method = "newton"`) reports.
#[derive(Clone, Debug)]
pub struct StaticSummary {
    /// The scenario's name ([`Scenario::name`]).
    pub name: String,
    /// Nodes of the mesh.
    pub nodes: usize,
    /// Elements of the mesh.
    pub elements: usize,
    /// The linear solver that ran (`"auto"` resolved).
    pub solver: StaticSolver,
    /// The solver's own report: residuals, Newton steps, force evaluations, convergence.
    /// `"krylov"`: residual 2-norms; `"direct"`, `"multigrid"`: largest nodal residuals.
    pub report: Static,
    /// `[run] residual_tol` ([`StaticSolve::rel_tol`]).
    pub rel_tol: f64,
    /// `"direct"`, `"multigrid"`: the residual to reach (N); `"krylov"`: none.
    pub target: Option<f64>,
    /// What the solver says of its work (conjugate-gradient iterations, factorisations,
    /// hierarchies); why it chose its solver where `"auto"` was asked for.
    pub detail: String,
    /// Why an assembled solve stopped early other than on an inverted element (a
    /// factorisation that failed at every shift).
    pub failure: Option<String>,
    /// Load increments.
    pub increments: usize,
    /// The element that inverted, where the solve stopped on one.
    pub inverted: Option<(usize, f64)>,
    /// Wall-clock time of the solve, the first sample and frame included (s).
    pub wall: f64,
    /// The state solved for: reactions and `max |u|` ([`crate::metrics::Sample`]).
    pub last: Sample,
    /// The applied loads and body forces, `Σ_a V_a` (N), at the solution: the reactions
    /// balance it at equilibrium ([`crate::metrics`]).
    pub applied: [f64; 3],
    /// The output directory; `None` for a solve in memory ([`RunOptions::in_memory`]).
    pub out_dir: Option<PathBuf>,
}

impl StaticSummary {
    /// Whether the residual reached the tolerance.
    pub fn converged(&self) -> bool {
        self.inverted.is_none() && self.failure.is_none() && self.report.converged
    }
}

impl std::fmt::Display for StaticSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let r = &self.report;
        writeln!(f, "scenario        {} (static)", self.name)?;
        writeln!(
            f,
            "mesh            {} nodes, {} elements",
            self.nodes, self.elements
        )?;
        let how = match self.solver {
            StaticSolver::Krylov => {
                "Newton-Krylov: matrix-free CG (finite-difference tangent products)"
            }
            StaticSolver::Direct => "Newton, assembled tangent, sparse Cholesky (reused by CG)",
            _ => "Newton, assembled tangent, CG preconditioned by a Galerkin V-cycle",
        };
        writeln!(
            f,
            "solve           {how}, {} load increment{}",
            self.increments,
            if self.increments == 1 { "" } else { "s" }
        )?;
        if !self.detail.is_empty() {
            writeln!(f, "                {}", self.detail)?;
        }
        match (self.inverted, &self.failure) {
            (Some((e, det)), _) => writeln!(
                f,
                "stopped         did not converge: element {e} would invert (det F = {det:.3e})"
            )?,
            (None, Some(why)) => writeln!(f, "stopped         did not converge: {why}")?,
            (None, None) if r.converged && self.target.is_some() => writeln!(
                f,
                "stopped         converged: largest nodal residual {:.3e} N <= {:.3e} N \
                 ({:.1e} of the largest nodal load + starting out-of-balance force, \
                 + {ABS_TOL:.0e} N)",
                r.residual,
                self.target.unwrap_or(0.0),
                self.rel_tol
            )?,
            (None, None) if self.target.is_some() => writeln!(
                f,
                "stopped         did not converge: largest nodal residual {:.3e} N > {:.3e} N \
                 (`integrator.max_newton` reached)",
                r.residual,
                self.target.unwrap_or(0.0),
            )?,
            (None, None) => writeln!(
                f,
                "stopped         did not converge: largest nodal residual {:.3e} N",
                r.residual
            )?,
        }
        writeln!(f, "newton steps    {}", r.newton_steps)?;
        writeln!(
            f,
            "residual        {:.4e} N (start {:.4e} N), largest nodal",
            r.residual, r.initial_residual
        )?;
        writeln!(f, "force evals     {}", r.force_evaluations)?;
        writeln!(f, "wall time       {:.3} s", self.wall)?;
        writeln!(f, "max |u|         {:.4e} m", self.last.max_u)?;
        write_balance(f, &self.last, self.applied)?;
        write_output(f, self.out_dir.as_deref())
    }
}

/// Solve a scenario with `method = "newton"` for static equilibrium `R(u) = V`, the
/// prescribed motions at their end ([`Scenario::motion_end`]), from the undeformed state in
/// `increments` steps of the loads and prescribed displacements (`k / increments` of them,
/// `k = 1..increments`), each warm-started from the last, by the solver of
/// [`StaticSolve::solver`] (module docs). Writes what [`super::run_with`] writes:
/// `measures.csv` (the start and the solution), two frames, `nodal_stress.csv` and
/// `summary.txt` with the solver's convergence report.
pub fn run_static(sc: &Scenario, opts: RunOptions) -> Result<StaticSummary> {
    run_static_keeping(sc, opts).map(|(summary, _)| summary)
}

/// [`run_static`], handing back the stepper that holds the solution as well.
pub fn run_static_keeping(
    sc: &Scenario,
    opts: RunOptions,
) -> Result<(StaticSummary, crate::integrate::SingleLevel)> {
    let settings = static_settings(sc)?;
    let out = OutDir::lock(sc, &opts)?;
    out.prepare(&sc.name)?;
    let n = sc.mesh.num_nodes();
    let mut stepper = crate::integrate::SingleLevel::new(
        sc.build_system()?,
        sc.integrator.method,
        crate::integrate::StepperParams {
            dt: sc.integrator.dt,
            kinetic_limit: f64::INFINITY,
        },
    );
    let plan = plan(sc, &settings, &mut stepper.sys)?;
    let increments = settings.increments(plan.solver);
    let mut meter = Meter::new(n, None);
    let mut frames = Frames::new(sc, &out)?;
    let mut rows = out.measures(sc.has_friction())?;
    let start = Instant::now();
    let first = meter.sample(&mut stepper.sys, &stepper.state, 0);
    rows.push(&first)?;
    frames.write(sc, &mut stepper)?;
    rows.flush()?;
    let t = sc.motion_end();
    let solved = {
        let (sys, s) = (&mut stepper.sys, &mut stepper.state);
        s.t = t;
        let mut u = s.u.clone();
        let solved = match plan.solver {
            StaticSolver::Krylov => {
                let diag = crate::statics::relax::fictitious_mass(&sc.mesh, &sys.mass, 1.0);
                let (lo, hi) = sc.mesh.bounding_box();
                let length = 1e-3 * crate::mesh::norm(crate::mesh::sub(hi, lo));
                newton(
                    &settings,
                    increments,
                    Linear::MatrixFree { diag, length },
                    None,
                    sys,
                    t,
                    &mut u,
                )
            }
            _ => {
                let mut start = match (&plan.coarse, plan.start.is_empty()) {
                    (Some((mesh, level)), false) => {
                        Some(sc.nested_levels(&plan.start, (mesh, *level))?)
                    }
                    _ => None,
                };
                newton(
                    &settings,
                    increments,
                    Linear::Assembled(plan.down.as_deref()),
                    start.as_mut(),
                    sys,
                    t,
                    &mut u,
                )
            }
        };
        s.u.copy_from_slice(&u);
        s.v.iter_mut().for_each(|x| *x = 0.0);
        solved
    };
    let Solved {
        mut report,
        inverted,
        target,
        failure,
        detail,
    } = solved;
    if inverted.is_some() {
        report.residual = stepper
            .sys
            .residual(&stepper.state.u, &mut vec![0.0; 3 * n])
            .unwrap_or(f64::NAN);
    }
    let detail = [plan.why, detail]
        .into_iter()
        .filter(|x| !x.is_empty())
        .collect::<Vec<_>>()
        .join("; ");
    let wall = start.elapsed().as_secs_f64();
    let mut last = meter.sample(&mut stepper.sys, &stepper.state, report.newton_steps as u64);
    last.force_evals = report.force_evaluations as f64;
    last.wall = wall;
    rows.push(&last)?;
    frames.write(sc, &mut stepper)?;
    rows.flush()?;
    let applied = {
        let (sys, s) = stepper.finest();
        if out.dir().is_some() {
            let mut tn = vec![0.0; 9 * n];
            sys.force.nodal_stress(&s.u, &mut tn);
            write_nodal_stress(&out.path("nodal_stress.csv"), sc, &s.u, &tn, None)?;
        }
        let mut v = sys.force.load_report(&s.u).applied;
        for (i, f) in sys.f_ext.iter().enumerate() {
            v[i % 3] += f;
        }
        v
    };
    let summary = StaticSummary {
        name: sc.name.clone(),
        nodes: n,
        elements: sc.mesh.num_elements(),
        solver: plan.solver,
        report,
        rel_tol: settings.rel_tol,
        target,
        detail,
        failure,
        increments,
        inverted,
        wall,
        last,
        applied,
        out_dir: out.dir().map(Path::to_path_buf),
    };
    let text = summary.to_string();
    out.write("summary.txt", |w| writeln!(w, "{text}"))?;
    Ok((summary, stepper))
}

/// What [`run_static`] would run, resolved as it resolves it (`raisov check`): the solver
/// (and why, where `"auto"` chose), the levels, the smoother, the coarse start, the load
/// increments and the stopping rule. An error where the scenario is not a static solve or an
/// assembled solver was asked for and does not apply.
pub fn describe_static(sc: &Scenario) -> Result<String> {
    let settings = static_settings(sc)?;
    let mut sys = sc.build_system()?;
    let plan = plan(sc, &settings, &mut sys)?;
    let increments = settings.increments(plan.solver);
    let mut s = format!(
        "newton (static equilibrium), solver \"{}\"",
        plan.solver.name()
    );
    if !plan.why.is_empty() {
        s += &format!(": {}", plan.why);
    }
    if plan.solver == StaticSolver::Multigrid {
        s += &format!(
            "; {} smoothing; coarse start {}",
            settings.smoother.describe(),
            if settings.coarse_start { "yes" } else { "no" }
        );
        if !plan.start.is_empty() {
            let levels: Vec<String> = plan
                .start
                .iter()
                .rev()
                .map(|&l| {
                    format!(
                        "{l} ({}{} nodes)",
                        if plan.start_requested { "about " } else { "" },
                        plan.start_nodes.get(l).copied().unwrap_or(0)
                    )
                })
                .collect();
            s += &format!(" (through levels {})", levels.join(", "));
        }
    }
    s += &format!(
        "; {increments} load increment{}, at most {} Newton steps each; residual_tol {:e}",
        if increments == 1 { "" } else { "s" },
        settings.max_newton,
        settings.rel_tol
    );
    Ok(s)
}

/// The scenario's static-solve settings; an error where it is not a static solve.
fn static_settings(sc: &Scenario) -> Result<StaticSolve> {
    sc.integrator.statics.ok_or_else(|| Error::Scenario {
        path: sc.path.clone(),
        line: None,
        msg: "not a static solve: `[integrator] method` is not \"newton\"".into(),
    })
}

/// The solver a static solve runs, and the level transfers of `"multigrid"`.
struct Plan {
    solver: StaticSolver,
    /// `"multigrid"`: the finest level's nodes located in the coarse level's mesh.
    down: Option<Vec<crate::hierarchy::Transfer>>,
    /// `"multigrid"`: the coarse level's mesh and its index among the levels.
    coarse: Option<(crate::mesh::Mesh, usize)>,
    /// `"multigrid"` with the coarse start: the levels it passes through ([`start_levels`]),
    /// finest first.
    start: Vec<usize>,
    /// Every level's node count, finest first ([`crate::scenario::PickedLevel::counts`]),
    /// for the start's description.
    start_nodes: Vec<usize>,
    /// Whether those counts are the requested ones of generated levels, not meshed counts.
    start_requested: bool,
    /// Why `"auto"` chose as it did (empty where the solver was asked for).
    why: String,
}

impl Plan {
    /// `solver` on level 0 alone: no levels, no start, no reason given.
    fn of(solver: StaticSolver) -> Plan {
        Plan {
            solver,
            down: None,
            coarse: None,
            start: Vec::new(),
            start_nodes: Vec::new(),
            start_requested: false,
            why: String::new(),
        }
    }
}

/// Resolve [`StaticSolve::solver`] against the built system (module docs); an error where an
/// assembled solver was asked for and does not apply, naming the key and why.
fn plan(sc: &Scenario, settings: &StaticSolve, sys: &mut System) -> Result<Plan> {
    let asked = settings.solver;
    let has_tangent = sys.force.tangent_elements().is_some();
    // The levels are meshed only where Newton-multigrid may run.
    let wants_levels = matches!(asked, StaticSolver::Auto | StaticSolver::Multigrid);
    let picked = match (wants_levels && has_tangent, &sc.multigrid) {
        (true, Some(_)) => Some(sc.pick_level(coarse_level)?),
        _ => None,
    };
    let offer = match &picked {
        None => CoarseOffer::NoLevels,
        Some(p) if p.chosen.is_some() => CoarseOffer::Qualifies,
        Some(p) => CoarseOffer::NoneQualifies(format!(
            "no [multigrid] level has at least 1/{} of the finest level's {} nodes (levels: {:?})",
            crate::statics::newton::COARSEN_LIMIT,
            p.counts[0],
            &p.counts[1..]
        )),
    };
    let (solver, why) = asked
        .resolve(has_tangent, &offer)
        .map_err(|msg| Error::Scenario {
            path: sc.path.clone(),
            line: None,
            msg,
        })?;
    let Some((picked, (c, coarse))) = picked.and_then(|p| p.chosen.clone().map(|ch| (p, ch)))
    else {
        return Ok(Plan {
            why,
            ..Plan::of(solver)
        });
    };
    if solver != StaticSolver::Multigrid {
        return Ok(Plan {
            why,
            ..Plan::of(solver)
        });
    }
    let nodes = picked.counts;
    let down = crate::hierarchy::Transfer::build(&sc.mesh.nodes, &coarse)?;
    // The coarse levels carry no pressure, traction, timed load or tool: a start from their
    // equilibrium would be one of another problem.
    let loaded = sc.has_model_loads();
    let start = match settings.coarse_start && !loaded {
        true => start_levels(&nodes, c),
        false => Vec::new(),
    };
    let why = format!(
        "levels of {} and {} nodes{}{}",
        sc.mesh.num_nodes(),
        coarse.num_nodes(),
        if asked == StaticSolver::Auto {
            " (solver \"auto\")"
        } else {
            ""
        },
        if settings.coarse_start && loaded {
            "; no coarse start (the loads and tools act on the finest level)"
        } else {
            ""
        }
    );
    Ok(Plan {
        solver: StaticSolver::Multigrid,
        down: Some(vec![down]),
        coarse: Some((coarse, c)),
        start,
        start_requested: picked.requested,
        start_nodes: nodes,
        why,
    })
}

/// What a solver returns to [`run_static`].
struct Solved {
    report: Static,
    inverted: Option<(usize, f64)>,
    target: Option<f64>,
    failure: Option<String>,
    detail: String,
}

/// The largest nodal internal force over the nodes that are not fixed or prescribed, with the
/// prescribed motions at time `t` and the free nodes at `u` (the out-of-balance force a
/// displacement-driven solve starts from). Where that state inverts an element (a large
/// prescribed displacement, which the solver's lifted first iteration takes), the motions'
/// fraction f = ½, ¼, … (at most 20 halvings) that inverts none gives it, times 1/f (its
/// linear extrapolation); 0 where none does.
pub(crate) fn prescribed_force_scale(sys: &mut System, t: f64, u: &[f64]) -> f64 {
    let n = u.len();
    let (mut ug, mut v, mut f) = (u.to_vec(), vec![0.0; n], vec![0.0f64; n]);
    sys.constraints.impose(t, &mut ug, &mut v);
    let model = &mut *sys.force;
    model.set_time(t);
    let mut fraction = 1.0;
    let mut trial = ug.clone();
    for _ in 0..=20 {
        if model.internal_forces(&trial, &mut f).is_ok() {
            return (0..n / 3)
                .filter(|&a| !sys.constraints.is_constrained(a))
                .map(|a| (f[3 * a].powi(2) + f[3 * a + 1].powi(2) + f[3 * a + 2].powi(2)).sqrt())
                .fold(0.0, f64::max)
                / fraction;
        }
        fraction *= 0.5;
        for i in 0..n {
            trial[i] = u[i] + fraction * (ug[i] - u[i]);
        }
    }
    0.0
}

/// The linear solve under the Newton driver of a static solve.
enum Linear<'a> {
    /// The assembled tangent: sparse Cholesky, or with levels CG preconditioned by the
    /// Galerkin V-cycle over them.
    Assembled(Option<&'a [crate::hierarchy::Transfer]>),
    /// Matrix-free CG preconditioned by the per-node `diag`, finite-difference steps of
    /// `length` (m).
    MatrixFree { diag: Vec<f64>, length: f64 },
}

/// The one Newton driver ([`crate::statics::newton::solve_with`]) over `linear`.
fn newton(
    settings: &StaticSolve,
    increments: usize,
    linear: Linear,
    start: Option<&mut NestedLevels>,
    sys: &mut System,
    t: f64,
    u: &mut [f64],
) -> Solved {
    let down = match &linear {
        Linear::Assembled(down) => *down,
        Linear::MatrixFree { .. } => None,
    };
    // The solve starts with the constrained nodes at rest (a `"held"` motion is already
    // imposed on the initial state): its lifted first iteration moves them to their values
    // together with the free nodes' linear response.
    for a in 0..u.len() / 3 {
        if sys.constraints.is_constrained(a) {
            u[3 * a..3 * a + 3].iter_mut().for_each(|x| *x = 0.0);
        }
    }
    let scale = prescribed_force_scale(sys, t, u);
    let start = match (start, down) {
        (Some(levels), Some(_)) => Some(nested_start(
            levels,
            t,
            increments,
            &*sys.force,
            &sys.constraints,
            u,
            BetweenSolve::Multigrid(settings.smoother),
        )),
        _ => None,
    };
    let start_note = start
        .as_ref()
        .map_or(String::new(), |s| format!("{}; ", s.describe()));
    let params = DirectNewtonParams {
        rel_tol: settings.rel_tol,
        abs_tol: ABS_TOL + settings.rel_tol * scale,
        max_newton: settings.max_newton.saturating_mul(increments),
        load_steps: CoarseStart::fine_load_steps(start.as_ref(), increments),
        pcg_max: match linear {
            Linear::Assembled(None) => DIRECT_PCG_MAX,
            _ => 0,
        },
        multigrid: down.map(|_| MultigridPcg {
            smoother: settings.smoother,
            ..Default::default()
        }),
        ..Default::default()
    };
    let matrix_free = matches!(linear, Linear::MatrixFree { .. });
    let out: std::result::Result<DirectStatic, DirectNewtonError> = match linear {
        Linear::MatrixFree { diag, length } => {
            let cg = MatrixFreeCg {
                length,
                ..Default::default()
            };
            solve_system_matrix_free(sys, Some(&diag), t, u, params, cg)
        }
        Linear::Assembled(down) => {
            let System {
                force,
                mass,
                f_ext,
                constraints,
                springs,
                ..
            } = sys;
            match down {
                Some(d) => DirectNewton::with_levels(&**force, mass, constraints, d),
                None => DirectNewton::new(&**force, mass, constraints),
            }
            .and_then(|mut s| s.solve(&mut **force, springs, constraints, f_ext, t, u, params))
        }
    };
    let failed = |failure: Option<String>, inverted: Option<(usize, f64)>| Solved {
        report: Static {
            residual: f64::NAN,
            initial_residual: f64::NAN,
            newton_steps: 0,
            force_evaluations: 0,
            converged: false,
        },
        inverted,
        target: Some(f64::NAN),
        failure,
        detail: String::new(),
    };
    match out {
        Ok(o) => Solved {
            report: Static {
                residual: o.residual,
                initial_residual: o.initial_residual,
                newton_steps: o.newton_steps,
                force_evaluations: o.force_evaluations,
                converged: o.converged,
            },
            inverted: None,
            target: Some(o.target),
            failure: None,
            detail: if matrix_free {
                format!(
                    "{} CG iterations (finite-difference products)",
                    o.cg_iterations
                )
            } else if down.is_some() {
                format!(
                    "{start_note}{} smoothing, {} CG iterations, {} hierarchies",
                    settings.smoother.describe(),
                    o.cg_iterations,
                    o.multigrid_setups
                )
            } else {
                format!(
                    "{} factorisations, {} CG iterations",
                    o.factorizations, o.cg_iterations
                )
            },
        },
        Err(DirectNewtonError::Inverted(e)) => failed(None, Some((e.element, e.det_f))),
        Err(e) => failed(Some(e.to_string()), None),
    }
}
