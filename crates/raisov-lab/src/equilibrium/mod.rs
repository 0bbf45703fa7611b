//! `raisov bench equilibrium`: time to static equilibrium of five solvers, side by side, on
//! the same problems and to the same stopping rule.
//!
//! Solvers, each at its best settings by one rule: every variant listed is run and the fastest
//! that meets the stopping rule is reported, the others' wall times in its note:
//! - **direct Newton** ([`raisov::statics::newton::solve_system`]): analytic tangent,
//!   faer sparse Cholesky, backtracking line search; [`Case::load_steps`] load steps (one;
//!   the prescribed displacement in the first iteration's lift); variants: a factorisation at every
//!   iteration, or each Newton system solved by conjugate gradients preconditioned by the last
//!   factorisation, refactoring when [`NEWTON_PCG_MAX`] iterations do not reach the
//!   inexact-Newton tolerance, the latter also from the coarse start below ([`NEWTON_REUSE`]);
//! - **FAS** multigrid ([`raisov::scenario::Scenario::stepper`] with the scenario's
//!   `[multigrid] scheme = "fas"` and its defaults but the smoothing): V-cycles
//!   (Krylov-accelerated) advanced until the stopping rule holds, the rule checked after every
//!   cycle (one finest-level residual per cycle, counted in the wall time and in the force
//!   evaluations); variants: 4 (the default), 8 or 16 pre- and post-smoothing sweeps per level
//!   ([`FAS_SWEEPS`]);
//! - **adaptive dynamic relaxation** (ADR, [`raisov::statics::relax::adaptive::adaptive_relax`])
//!   on the finest mesh alone, with `λ_max` from
//!   [`raisov::integrate::stability::lambda_max_bound`]; its damping and step are set by its
//!   own rule (critical damping of the lowest mode estimated every step); variants: from rest,
//!   or from the coarse start below (the pull then in one increment);
//! - **Chebyshev** ([`raisov::statics::relax::chebyshev::chebyshev_relax`]): the Chebyshev
//!   semi-iteration on the finest mesh alone, preconditioned by FAS's smoother's per-node
//!   fictitious masses, over an interval of the spectrum estimated by Lanczos and tracked by
//!   the increments' Rayleigh quotients; its settings by its own rule (module docs there);
//!   variants as ADR's;
//! - **Newton-multigrid** (direct Newton's iteration with
//!   [`raisov::statics::newton::DirectNewtonParams::multigrid`]): each Newton system
//!   solved by conjugate gradients preconditioned by a Galerkin V-cycle
//!   ([`raisov::linalg::galerkin`]) over two of the case's levels, the finest and
//!   [`raisov::statics::newton::coarse_level`]'s (of the levels with at least 1/32
//!   of its nodes, the finest with at most 1/[`NEWTON_MG_COARSEN`], else the coarsest), [`NEWTON_MG_SWEEPS`]
//!   smoothing sweeps; variants ([`NEWTON_MG_VARIANTS`]): a Newton iteration reuses the
//!   last hierarchy's coarse factorisation with operators rebuilt from its tangent, or the
//!   whole last hierarchy, either until CG fails to converge; the smoother is node-block
//!   Gauss-Seidel over a colouring, damped node-block Jacobi, or point Gauss-Seidel (the
//!   library's default); each from rest and from the coarse start.
//!
//! The coarse start ([`raisov::statics::nested::nested_start`], nested iteration,
//! as a static scenario's): the coarsest level of
//! [`raisov::statics::nested::start_levels`] (Newton-multigrid's coarse level, or a
//! coarser one with at least 1 000 nodes), with the scenario's constraints and loads carried
//! to it, solved by direct Newton over [`Case::load_steps`] load steps, then each finer
//! level of it (about four times the nodes) from the last one's equilibrium, by
//! Newton-multigrid for Newton-multigrid and by direct Newton for the others (each baseline's
//! start made by a baseline), the finest one's equilibrium interpolated to the fine nodes as the fine
//! solve's start (one load step, or for ADR one increment); its time counts, the meshing of
//! its levels included. FAS starts from rest: its coarse levels already correct it.
//!
//! All other runs start from rest (`u = 0`). A prescribed displacement (`[[displace]]`, the pulled
//! liver), imposed at once with the rest of the body at rest, inverts the pulled node's
//! elements. Direct Newton and Newton-multigrid take it in one load step: their first
//! iteration moves the free nodes by the linear response to it (the lifted iteration of
//! [`raisov::statics::newton`]). FAS, ADR and Chebyshev take it in [`PULL_INCREMENTS`] equal
//! increments, gravity in full from the start, each increment but the last relaxed to
//! [`PULL_STAGE_TOL`] × the largest nodal load before the next. Every increment counts in the
//! figures.
//!
//! Stopping rule, common to all (that of [`raisov::statics::newton`]): the
//! largest nodal residual over free nodes `max_a |V_a − R_a(u)|` at most [`REL_TOL`] × the
//! largest nodal external load `max_a |V_a|` plus the absolute floor [`ABS_TOL`] (N), `|·|` the
//! Euclidean norm of a node's 3-vector.
//!
//! Measured per solver and case: wall time (s, the solve alone: scenario loading and mesh
//! reading are not timed; FAS's stepper construction, hierarchy included, is), iterations
//! (Newton iterations, V-cycles, relaxation steps), force evaluations in finest-level units
//! (coarse levels weighted by their node count; Newton's energy evaluations are not counted),
//! the final residual (N), whether the rule was met, the largest nodal displacement, the
//! largest nodal distance to direct Newton's equilibrium, and (in the note) the potential
//! energy `Π = E(u) − V·u` of the equilibrium reached. Equilibria agree when that distance
//! is at most [`AGREE_TOL`] × the largest displacement; a row that does not is flagged in the
//! table, not panicked on.
//!
//! Cases ([`cases`]): the liver L1 of `data/` (7547 nodes; FAS with L2 and L3), millimetres
//! scaled to metres, neo-Hookean E = 5 kPa, ν = 0.45, ρ = 1060 kg/m³, held on the cap
//! z ≥ 0.195 m, under gravity; the same liver with the node nearest (0.12, 0.07, 0.10) m also
//! pulled by (0, −0.01, −0.017) m; the liver L0 (16 693 nodes; FAS with L1, L2, L3) under
//! gravity; the heart L0 of `data/` (FAS with L1, L2, L3), the same material, held on the cap
//! within 5 mm of its highest point, under gravity; the paper's drape (10 cm square membrane,
//! Mooney-Rivlin C1 = C2 = 1 kPa, edges fixed, gravity) at 10k nodes (FAS on 5 generated
//! levels) and 100k nodes (7 levels). Quick (`--quick`): the liver L2 (FAS with L3) with and
//! without the pull, and the drape at 1k nodes on 3 levels. Run only when named
//! ([`MESHER_CASES`]): the liver meshed from `liver_surface.obj` by the project's mesher at
//! about 17k and 70k nodes, FAS on generated levels halving down to about 2000 nodes; the 70k
//! one runs each solver's variants of [`REDUCED`] only.
//!
//! [`summary_markdown`] states, per case, the fastest solver, and how much faster than every
//! other solver FAS and Newton-multigrid are (the defaults of a `[multigrid]` run to steady
//! state and of a static scenario); [`goal_markdown`] sets Newton-multigrid against
//! [`GOAL`], the time that allows (the best other solver's over [`GOAL`]) and where its
//! time went ([`Parts`]: the coarse start, the setup before its first iteration, the
//! Galerkin hierarchies, the assemblies, the CG iterations, the rest), and for each case
//! that misses it, what share of the allowed time the parts that fewer CG iterations would
//! not shorten take alone; [`frame_budgets`] runs FAS as the frame loop does, a fixed number of
//! V-cycles per frame, and reads the residual after given frames; [`newton_frame_budgets`]
//! does the same with a fixed number of Newton-multigrid iterations per frame.

mod frames;
mod summary;

pub use frames::{frame_budgets, frames_to_markdown, newton_frame_budgets, FrameRow, FRAME_MARKS};
use raisov::hierarchy::Transfer;
use raisov::integrate::hold;
use raisov::integrate::stability::lambda_max_bound;
use raisov::scenario::Scenario;
use raisov::statics::nested::{nested_start, start_levels, BetweenSolve, CoarseStart};
use raisov::statics::newton::{
    solve_system, DirectNewton, DirectNewtonParams, DirectStatic, MultigridPcg, Smoother,
};
use raisov::statics::relax::adaptive::adaptive_relax;
use raisov::statics::relax::chebyshev::chebyshev_relax;
use raisov::Scheme;
use raisov::{Error, Result};
use std::path::Path;
use std::time::Instant;
pub use summary::{goal_markdown, summary_markdown, to_markdown, GOAL};

/// Relative part of the stopping rule (of the largest nodal external load).
pub const REL_TOL: f64 = 1e-8;
/// Absolute floor of the stopping rule (N).
pub const ABS_TOL: f64 = 1e-14;
/// Agreement: largest nodal distance to Newton's equilibrium over the largest displacement.
pub const AGREE_TOL: f64 = 1e-6;
/// Increments of a prescribed displacement for FAS, ADR and Chebyshev.
pub const PULL_INCREMENTS: usize = 4;
/// Stopping rule of the intermediate increments (relative, as [`REL_TOL`]).
pub const PULL_STAGE_TOL: f64 = 1e-4;
/// Direct Newton: conjugate-gradient iterations on a kept factorisation before refactoring
/// ([`DirectNewtonParams::pcg_max`]).
pub const NEWTON_PCG_MAX: usize = 20;
/// Direct Newton's sweep: factorisation reuse (CG iterations before refactoring; 0 none),
/// and whether it starts from the coarse level's equilibrium
/// ([`raisov::statics::nested::coarse_start`], on Newton-multigrid's coarse level).
pub const NEWTON_REUSE: [(usize, bool); 3] =
    [(0, false), (NEWTON_PCG_MAX, false), (NEWTON_PCG_MAX, true)];
/// FAS's sweep: pre- and post-smoothing sweeps per level (the default is 4).
pub const FAS_SWEEPS: [usize; 3] = [4, 8, 16];
/// Newton-multigrid: its coarse level has at most 1/`NEWTON_MG_COARSEN` of the finest
/// level's nodes where the levels allow (module docs).
pub const NEWTON_MG_COARSEN: usize = raisov::statics::newton::COARSEN;
/// Newton-multigrid: smoothing sweeps before and after the coarse correction.
pub const NEWTON_MG_SWEEPS: usize = 2;
/// Newton-multigrid's variants: whether an iteration keeps the whole last hierarchy, or only
/// its coarsest factorisation ([`MultigridPcg::keep`]), and the smoother
/// ([`MultigridPcg::smoother`]: node-block Gauss-Seidel over a colouring, damped node-block
/// Jacobi, or point Gauss-Seidel), and whether it starts from the coarse start (module docs).
pub const NEWTON_MG_VARIANTS: [(bool, Smoother, bool); 12] = [
    (false, Smoother::ColouredBlock, false),
    (true, Smoother::ColouredBlock, false),
    (false, Smoother::BlockJacobi, false),
    (true, Smoother::BlockJacobi, false),
    (false, Smoother::GaussSeidel, false),
    (true, Smoother::GaussSeidel, false),
    (false, Smoother::ColouredBlock, true),
    (true, Smoother::ColouredBlock, true),
    (false, Smoother::BlockJacobi, true),
    (true, Smoother::BlockJacobi, true),
    (false, Smoother::GaussSeidel, true),
    (true, Smoother::GaussSeidel, true),
];
/// Mesher livers of at least this many nodes run the reduced sweep ([`REDUCED`]).
pub const REDUCED_FROM: usize = 50_000;
/// The reduced sweep of the largest mesher liver: the variants within 10 % of their solver's
/// fastest on the 17k mesher liver (`bench/RESULTS.md`: direct Newton without reuse took 3.7
/// times as long as with it, FAS with 4 and 8 sweeps 1.6 and 1.1 times as long as with 16,
/// Newton-multigrid keeping the whole hierarchy 1.26-1.56 times as long as keeping the coarse
/// factor), and each one's coarse start: direct Newton reusing its factorisation, FAS with
/// 16 sweeps, ADR, Newton-multigrid keeping the coarse factor with each smoother.
pub const REDUCED: &str =
    "direct Newton reuse only, FAS 16 sweeps only, Newton-multigrid keeps the coarse factor only";
/// FAS: V-cycles at most.
pub const MAX_CYCLES: u64 = 20_000;
/// ADR and Chebyshev: steps (iterations) at most, all increments together.
pub const MAX_STEPS: u64 = 1_000_000;

/// One problem of the benchmark.
pub struct Case {
    /// Short name (the table's first column).
    pub name: String,
    /// The scenario: mesh, material, constraints, loads and its `[multigrid]` for FAS.
    pub scenario: Scenario,
    /// Direct Newton's and Newton-multigrid's load steps.
    pub load_steps: usize,
    /// Run only the variants [`REDUCED`] keeps (the largest mesher liver).
    pub reduced: bool,
}

/// One solver on one case.
#[derive(Clone, Debug)]
pub struct Row {
    pub case: String,
    pub nodes: usize,
    /// `"direct Newton"`, `"FAS"`, `"ADR"`, `"Chebyshev"` or `"Newton-multigrid"`.
    pub solver: String,
    /// Wall time of the solve (s).
    pub wall_s: f64,
    /// Newton iterations, V-cycles or relaxation steps.
    pub iterations: u64,
    /// Force evaluations in finest-level units.
    pub force_evaluations: f64,
    /// Largest nodal residual over free nodes at the end (N).
    pub residual: f64,
    /// The stopping threshold (N).
    pub target: f64,
    pub converged: bool,
    /// Largest nodal displacement (m).
    pub max_u: f64,
    /// Largest nodal distance to direct Newton's equilibrium (m); `None` without one.
    pub diff_newton: Option<f64>,
    /// Details (Newton's factorisations, a failure).
    pub note: String,
    /// Where the wall time went: Newton-multigrid's rows ([`summary::goal_markdown`]).
    pub parts: Option<Parts>,
}

/// Where a Newton-multigrid solve's wall time went (s); the parts sum to its wall time.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Parts {
    /// The coarse start (nested iteration), where one was taken.
    pub start_s: f64,
    /// Before the first Newton iteration, the start aside: the level meshes, their
    /// transfers, the tangent's pattern and the prolongations.
    pub setup_s: f64,
    /// Galerkin hierarchies: the products `PᵀAP`, the smoothers, the coarse factors
    /// ([`raisov::statics::newton::DirectStatic::setup_s`]).
    pub hierarchies_s: f64,
    /// Tangent assemblies.
    pub assembly_s: f64,
    /// Conjugate-gradient iterations: V-cycles and products.
    pub cg_s: f64,
    /// The rest: residuals and energies of the line searches, the lifts, the output.
    pub rest_s: f64,
}

impl Parts {
    /// The parts in the goal table's order: start, setup, hierarchies, assemblies, CG, rest.
    pub fn all(&self) -> [f64; 6] {
        [
            self.start_s,
            self.setup_s,
            self.hierarchies_s,
            self.assembly_s,
            self.cg_s,
            self.rest_s,
        ]
    }

    /// What fewer CG iterations would not shorten: the start, the setup, the hierarchies
    /// and the assemblies (s).
    pub fn fixed_s(&self) -> f64 {
        self.start_s + self.setup_s + self.hierarchies_s + self.assembly_s
    }
}

impl Row {
    /// Whether the equilibrium agrees with Newton's ([`AGREE_TOL`]); `None` without one.
    pub fn agrees(&self) -> Option<bool> {
        self.diff_newton.map(|d| d <= AGREE_TOL * self.max_u)
    }
}

fn max_nodal(x: &[f64]) -> f64 {
    x.chunks(3)
        .map(|c| (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt())
        .fold(0.0, f64::max)
}

fn max_nodal_diff(a: &[f64], b: &[f64]) -> f64 {
    a.chunks(3)
        .zip(b.chunks(3))
        .map(|(x, y)| {
            let d = [x[0] - y[0], x[1] - y[1], x[2] - y[2]];
            (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
        })
        .fold(0.0, f64::max)
}

const LIVER_MATERIAL: &str = r#"
[material]
law = "neo-hookean"
young = 5000.0
poisson = 0.45
density = 1060.0
"#;

const LIVER_PULL: &str = r#"
[[displace]]
point = [0.12, 0.07, 0.10]
displacement = [0.0, -0.01, -0.017]
mode = "held"
"#;

fn liver(meshes: &Path, fine: usize, pull: bool) -> Result<Case> {
    let d = meshes.display();
    let coarse: Vec<String> = (fine + 1..=3)
        .map(|l| format!("'{d}/liver_L{l}.msh'"))
        .collect();
    let text = format!(
        r#"
gravity = [0.0, 0.0, -9.81]
[mesh]
file = '{d}/liver_L{fine}.msh'
scale = 0.001
{LIVER_MATERIAL}
[[fix]]
plane = {{ point = [0.0, 0.0, 0.195], normal = [0.0, 0.0, -1.0] }}
{pull_text}
[run]
duration = 1.0
[multigrid]
scheme = "fas"
files = [{files}]
"#,
        pull_text = if pull { LIVER_PULL } else { "" },
        files = coarse.join(", "),
    );
    let name = format!("liver L{fine}{}", if pull { " + pull" } else { "" });
    Ok(Case {
        scenario: Scenario::from_toml(&text, Path::new("equilibrium-liver.toml"))?,
        name,
        load_steps: 1,
        reduced: false,
    })
}

fn heart(meshes: &Path) -> Result<Case> {
    let d = meshes.display();
    let fine = meshes.join("heart_L0.msh");
    let m = raisov::io::gmsh::read_msh(&fine)?.mesh;
    let z_top = m.nodes.iter().map(|p| p[2]).fold(f64::MIN, f64::max) * 0.001;
    let text = format!(
        r#"
gravity = [0.0, 0.0, -9.81]
[mesh]
file = '{d}/heart_L0.msh'
scale = 0.001
{LIVER_MATERIAL}
[[fix]]
plane = {{ point = [0.0, 0.0, {z_cap:?}], normal = [0.0, 0.0, -1.0] }}
[run]
duration = 1.0
[multigrid]
scheme = "fas"
files = ['{d}/heart_L1.msh', '{d}/heart_L2.msh', '{d}/heart_L3.msh']
"#,
        z_cap = z_top - 0.005,
    );
    Ok(Case {
        scenario: Scenario::from_toml(&text, Path::new("equilibrium-heart.toml"))?,
        name: "heart L0".into(),
        load_steps: 1,
        reduced: false,
    })
}

/// The paper's drape at about `nodes` nodes, FAS on `levels` generated levels.
pub fn drape(nodes: usize, levels: usize) -> Result<Case> {
    let text = format!(
        r#"
gravity = [0.0, 0.0, -9.81]
[mesh]
generate = "rectangle"
size = [0.1, 0.1]
nodes = {nodes}
[material]
law = "mooney-rivlin"
c1 = 1000.0
c2 = 1000.0
[[fix]]
boundary = true
[run]
duration = 1.0
[multigrid]
scheme = "fas"
levels = {levels}
"#
    );
    let label = if nodes >= 1000 && nodes.is_multiple_of(1000) {
        format!("{}k", nodes / 1000)
    } else {
        nodes.to_string()
    };
    Ok(Case {
        scenario: Scenario::from_toml(&text, Path::new("equilibrium-drape.toml"))?,
        name: format!("membrane {label}"),
        load_steps: 1,
        reduced: false,
    })
}

/// The liver cases meshed from `liver_surface.obj` by the project's mesher, by name and level-0
/// node target: run only when named with `--case` ([`mesher_case`]).
pub const MESHER_CASES: [(&str, usize); 2] =
    [("liver mesher 17k", 17_000), ("liver mesher 70k", 70_000)];

/// The liver meshed at load from `meshes/liver_surface.obj` (millimetres) at about `nodes`
/// nodes, the same material, support and gravity as the shipped liver; FAS on generated levels
/// halving the node count down to about 2000 nodes.
pub fn mesher_case(meshes: &Path, name: &str, nodes: usize) -> Result<Case> {
    let mut levels = 1;
    while nodes >> levels >= 2000 {
        levels += 1;
    }
    let text = format!(
        r#"
gravity = [0.0, 0.0, -9.81]
[mesh]
surface = '{d}/liver_surface.obj'
scale = 0.001
nodes = {nodes}
{LIVER_MATERIAL}
[[fix]]
plane = {{ point = [0.0, 0.0, 0.195], normal = [0.0, 0.0, -1.0] }}
[run]
duration = 1.0
[multigrid]
scheme = "fas"
levels = {levels}
ratio = 0.5
"#,
        d = meshes.display(),
    );
    Ok(Case {
        scenario: Scenario::from_toml(&text, Path::new("equilibrium-liver-mesher.toml"))?,
        name: name.into(),
        load_steps: 1,
        reduced: nodes >= REDUCED_FROM,
    })
}

/// The benchmark's cases (module docs); `meshes` holds `liver_L*.msh` and `heart_L*.msh`.
pub fn cases(meshes: &Path, quick: bool) -> Result<Vec<Case>> {
    if quick {
        Ok(vec![
            liver(meshes, 2, false)?,
            liver(meshes, 2, true)?,
            drape(1000, 3)?,
        ])
    } else {
        Ok(vec![
            liver(meshes, 1, false)?,
            liver(meshes, 1, true)?,
            liver(meshes, 0, false)?,
            heart(meshes)?,
            drape(10_000, 5)?,
            drape(100_000, 7)?,
        ])
    }
}

/// The prescribed values at their end (m), in the order of the constraints; `None` if a
/// motion never settles (a sine).
fn prescribed_ends(sc: &Scenario) -> Option<Vec<[f64; 3]>> {
    sc.prescribed
        .iter()
        .map(|(_, m)| m.end().is_finite().then(|| m.displacement(m.end())))
        .collect()
}

fn scaled(v: &[[f64; 3]], s: f64) -> Vec<[f64; 3]> {
    v.iter().map(|d| [s * d[0], s * d[1], s * d[2]]).collect()
}

pub fn blank_row(case: &Case, solver: &str, target: f64) -> Row {
    Row {
        case: case.name.clone(),
        nodes: case.scenario.mesh.num_nodes(),
        solver: solver.into(),
        wall_s: 0.0,
        iterations: 0,
        force_evaluations: 0.0,
        residual: f64::NAN,
        target,
        converged: false,
        max_u: f64::NAN,
        diff_newton: None,
        note: String::new(),
        parts: None,
    }
}

/// ", pull lifted" where a Newton solve moved its constrained dofs in a lifted iteration.
fn lifted(o: &DirectStatic) -> &'static str {
    if o.lifted_steps > 0 {
        ", pull lifted"
    } else {
        ""
    }
}

/// The coarse start of every solver that takes one: the levels of
/// [`raisov::statics::nested::start_levels`] below Newton-multigrid's coarse level
/// ([`newton_mg_levels`], whose mesh `coarse` is where given), solved and interpolated into
/// `u` ([`raisov::statics::nested::nested_start`], the levels between solved by
/// `multigrid`: Newton-multigrid smoothed as a static scenario's is by default, else by
/// direct Newton); `None` where the case has no such level.
fn start_from_coarse(
    case: &Case,
    sys: &mut raisov::integrate::System,
    u: &mut [f64],
    coarse: Option<&raisov::mesh::Mesh>,
    multigrid: bool,
) -> Result<Option<CoarseStart>> {
    let sc = &case.scenario;
    let picked = sc.pick_level(raisov::statics::newton::coarse_level)?;
    let Some((c, mesh)) = picked.chosen else {
        return Ok(None);
    };
    let chain = start_levels(&picked.counts, c);
    let mut levels = sc.nested_levels(&chain, (coarse.unwrap_or(&mesh), c))?;
    let model = &mut *sys.force;
    Ok(Some(nested_start(
        &mut levels,
        0.0,
        case.load_steps,
        model,
        &sys.constraints,
        u,
        match multigrid {
            true => BetweenSolve::Multigrid(raisov::scenario::StaticSolve::default_smoother(
                sc.mesh.kind,
            )),
            false => BetweenSolve::Direct,
        },
    )))
}

/// `Π(u) = E(u) − V·u` (J): the strain energy less the external forces' work, the
/// constrained dofs at their imposed values in every state compared.
fn potential(sys: &raisov::integrate::System, u: &[f64]) -> f64 {
    sys.force.strain_energy(u) - sys.f_ext.iter().zip(u).map(|(f, x)| f * x).sum::<f64>()
}

/// What a row's note says of its coarse start.
fn start_note(start: Option<&CoarseStart>) -> String {
    start.map_or(String::new(), |s| format!("{}, ", s.describe()))
}

/// A Newton row's figures from its outcome and equilibrium `u`.
fn newton_figures(row: &mut Row, o: &DirectStatic, u: &[f64]) {
    row.iterations = o.newton_steps as u64;
    row.force_evaluations = o.force_evaluations as f64;
    row.residual = o.residual;
    row.converged = o.converged;
    row.max_u = max_nodal(u);
}

/// Direct Newton with factorisation reuse `pcg_max` (0: none); the row and the displacement.
fn newton_run(
    case: &Case,
    target: f64,
    (pcg_max, nested): (usize, bool),
) -> Result<(Row, Vec<f64>)> {
    let sc = &case.scenario;
    let mut row = blank_row(case, "direct Newton", target);
    let mut u = vec![0.0; 3 * sc.mesh.num_nodes()];
    let mut sys = sc.build_system()?;
    let t0 = Instant::now();
    let start = if nested {
        start_from_coarse(case, &mut sys, &mut u, None, false)?
    } else {
        None
    };
    let load_steps = CoarseStart::fine_load_steps(start.as_ref(), case.load_steps);
    let out = solve_system(
        &mut sys,
        0.0,
        &mut u,
        DirectNewtonParams {
            rel_tol: REL_TOL,
            abs_tol: ABS_TOL,
            load_steps,
            pcg_max,
            ..Default::default()
        },
    );
    row.wall_s = t0.elapsed().as_secs_f64();
    match out {
        Ok(o) => {
            newton_figures(&mut row, &o, &u);
            row.note = format!(
                "{}{} load step{}{}, reuse {}: {} factorisations, {} CG iterations ({:.2} s), {} energy evaluations",
                start_note(start.as_ref()),
                load_steps,
                if load_steps == 1 { "" } else { "s" },
                lifted(&o),
                if pcg_max == 0 { "none".to_string() } else { format!("{pcg_max} CG") },
                o.factorizations,
                o.cg_iterations,
                o.factor_s,
                o.energy_evaluations
            );
        }
        Err(e) => row.note = format!("failed: {e}"),
    }
    Ok((row, u))
}

/// Newton-multigrid's levels ([`newton_mg_run`]): the finest, and
/// [`raisov::statics::newton::coarse_level`]'s (none where no level qualifies; a
/// generated drape meshes only that level, [`raisov::model::Model::pick_level`]).
fn newton_mg_levels(sc: &Scenario) -> Result<Vec<raisov::mesh::Mesh>> {
    let picked = sc.pick_level(raisov::statics::newton::coarse_level)?;
    Ok(std::iter::once(sc.mesh.clone())
        .chain(picked.chosen.map(|(_, m)| m))
        .collect())
}

/// The meshes of [`newton_mg_levels`] and the transfers from each to the next.
fn newton_mg_hierarchy(sc: &Scenario) -> Result<(Vec<raisov::mesh::Mesh>, Vec<Transfer>)> {
    let meshes = newton_mg_levels(sc)?;
    let down = meshes
        .windows(2)
        .map(|w| Transfer::build(&w[0].nodes, &w[1]))
        .collect::<Result<_>>()?;
    Ok((meshes, down))
}

/// Newton with CG preconditioned by a Galerkin V-cycle over [`newton_mg_levels`] (the coarse
/// level's operator `PᵀKP` factored, the factor reused across Newton iterations while CG
/// converges, the operators rebuilt from each tangent unless `keep`; [`NEWTON_MG_SWEEPS`]
/// node-block Gauss-Seidel sweeps); the level meshes and their transfers are built in
/// the timed part, as FAS's hierarchy is.
fn newton_mg_run(
    case: &Case,
    target: f64,
    (keep, smoother, nested): (bool, Smoother, bool),
) -> Result<(Row, Vec<f64>)> {
    let sc = &case.scenario;
    let mut row = blank_row(case, "Newton-multigrid", target);
    let mut u = vec![0.0; 3 * sc.mesh.num_nodes()];
    let mut sys = sc.build_system()?;
    let t0 = Instant::now();
    let (meshes, down) = newton_mg_hierarchy(sc)?;
    let mut parts = Parts {
        setup_s: t0.elapsed().as_secs_f64(),
        ..Default::default()
    };
    let clock = Instant::now();
    let start = if nested && meshes.len() > 1 {
        start_from_coarse(case, &mut sys, &mut u, Some(&meshes[1]), true)?
    } else {
        None
    };
    parts.start_s = clock.elapsed().as_secs_f64();
    let model = &mut *sys.force;
    let load_steps = CoarseStart::fine_load_steps(start.as_ref(), case.load_steps);
    let clock = Instant::now();
    let prepared = DirectNewton::with_levels(&*model, &sys.mass, &sys.constraints, &down);
    parts.setup_s += clock.elapsed().as_secs_f64();
    let out = prepared.and_then(|mut s| {
        s.solve(
            model,
            &sys.springs,
            &sys.constraints,
            &sys.f_ext,
            0.0,
            &mut u,
            DirectNewtonParams {
                rel_tol: REL_TOL,
                abs_tol: ABS_TOL,
                load_steps,
                multigrid: Some(MultigridPcg {
                    sweeps: NEWTON_MG_SWEEPS,
                    keep,
                    smoother,
                    ..Default::default()
                }),
                ..Default::default()
            },
        )
    });
    row.wall_s = t0.elapsed().as_secs_f64();
    match out {
        Ok(o) => {
            newton_figures(&mut row, &o, &u);
            row.note = format!(
                "{} levels, {}{} load step{}{}, {NEWTON_MG_SWEEPS}+{NEWTON_MG_SWEEPS} {} sweeps, keeps {}: {} hierarchies, {} CG iterations ({:.2} s), assembly {:.2} s, {} energy evaluations",
                meshes.len(),
                start_note(start.as_ref()),
                load_steps,
                if load_steps == 1 { "" } else { "s" },
                lifted(&o),
                smoother.describe(),
                if keep { "all" } else { "the coarse factor" },
                o.multigrid_setups,
                o.cg_iterations,
                o.factor_s,
                o.assembly_s,
                o.energy_evaluations
            );
            parts.hierarchies_s = o.setup_s;
            parts.assembly_s = o.assembly_s;
            parts.cg_s = o.factor_s - o.setup_s;
            parts.rest_s = (row.wall_s - parts.fixed_s() - parts.cg_s).max(0.0);
            row.parts = Some(parts);
        }
        Err(e) => row.note = format!("failed: {e}"),
    }
    Ok((row, u))
}

/// FAS with `smooth` pre- and post-smoothing sweeps, the rule checked after every cycle.
fn fas_run(case: &Case, target: f64, smooth: usize, ends: &[[f64; 3]]) -> Result<(Row, Vec<f64>)> {
    let mut sc = case.scenario.clone();
    if let Some(mg) = sc.multigrid.as_mut() {
        if let Scheme::Fas(p) = &mut mg.scheme {
            p.pre_smooth = smooth;
            p.post_smooth = smooth;
        }
    }
    let n = sc.mesh.num_nodes();
    let stages = if ends.is_empty() { 1 } else { PULL_INCREMENTS };
    let mut row = blank_row(case, "FAS", target);
    let t0 = Instant::now();
    let out = (|| -> Result<(u64, f64, f64, Vec<f64>, usize)> {
        let mut st = sc.stepper()?;
        let mut r = vec![0.0; 3 * n];
        let mut cycles = 0u64;
        let mut res = f64::INFINITY;
        for stage in 1..=stages {
            let last = stage == stages;
            if !ends.is_empty() {
                st.hold_prescribed(&scaled(ends, stage as f64 / stages as f64));
            }
            let goal = if last {
                target
            } else {
                PULL_STAGE_TOL * (target - ABS_TOL) / REL_TOL
            };
            res = f64::INFINITY;
            while res > goal && cycles < MAX_CYCLES {
                st.advance()?;
                cycles += 1;
                let (sys, s) = st.finest();
                let u = s.u.clone();
                sys.residual(&u, &mut r)
                    .map_err(|e| Error::param("FAS", format!("{e:?}")))?;
                res = max_nodal(&r);
            }
        }
        let evals = st.force_evaluations() + cycles as f64;
        let levels = st.num_levels();
        let u = st.state().u.clone();
        Ok((cycles, evals, res, u, levels))
    })();
    row.wall_s = t0.elapsed().as_secs_f64();
    match out {
        Ok((cycles, evals, res, u, levels)) => {
            row.iterations = cycles;
            row.force_evaluations = evals;
            row.residual = res;
            row.converged = res <= target;
            row.max_u = max_nodal(&u);
            row.note = format!("{levels} levels, {smooth}+{smooth} sweeps");
            if stages > 1 {
                row.note += &format!(", pull in {stages} increments");
            }
            Ok((row, u))
        }
        Err(e) => {
            row.note = format!("failed: {e}");
            Ok((row, Vec::new()))
        }
    }
}

/// A single-level relaxation on the finest mesh: the solver of the ADR and Chebyshev rows.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Relaxer {
    /// Adaptive dynamic relaxation ([`adaptive_relax`]).
    Adr,
    /// The Chebyshev semi-iteration ([`chebyshev_relax`]).
    Chebyshev,
}

impl Relaxer {
    fn label(self) -> &'static str {
        match self {
            Relaxer::Adr => "ADR",
            Relaxer::Chebyshev => "Chebyshev",
        }
    }
}

/// One run of `relaxer` on the finest mesh, from rest or from the coarse start (`nested`);
/// a prescribed motion in [`PULL_INCREMENTS`] increments from rest.
fn relax_run(
    case: &Case,
    target: f64,
    ends: &[[f64; 3]],
    nested: bool,
    relaxer: Relaxer,
) -> Result<(Row, Vec<f64>)> {
    let sc = &case.scenario;
    let mut stages = if ends.is_empty() { 1 } else { PULL_INCREMENTS };
    let mut row = blank_row(case, relaxer.label(), target);
    let mut sys = sc.build_system()?;
    let lmax = lambda_max_bound(&sc.mesh, &sc.material, sc.density);
    let mut u = vec![0.0; 3 * sc.mesh.num_nodes()];
    let t0 = Instant::now();
    let start = if nested {
        if !ends.is_empty() {
            hold(&mut sys.constraints, ends);
        }
        start_from_coarse(case, &mut sys, &mut u, None, false)?
    } else {
        None
    };
    stages = CoarseStart::fine_load_steps(start.as_ref(), stages);
    let mut failure: Option<String> = None;
    let (mut evaluations, mut restarts) = (0u64, 0u64);
    for stage in 1..=stages {
        let last = stage == stages;
        if !ends.is_empty() {
            hold(
                &mut sys.constraints,
                &scaled(ends, stage as f64 / stages as f64),
            );
        }
        let (rel, abs) = if last {
            (REL_TOL, ABS_TOL)
        } else {
            (PULL_STAGE_TOL, 0.0)
        };
        let left = MAX_STEPS.saturating_sub(row.iterations);
        let mesh = &sc.mesh;
        // (iterations, evaluations, restarts, residual, converged)
        let out = match relaxer {
            Relaxer::Adr => adaptive_relax(&mut sys, mesh, lmax, 0.0, &mut u, rel, abs, left)
                .map(|o| (o.steps, o.steps, 0, o.residual, o.converged)),
            Relaxer::Chebyshev => {
                chebyshev_relax(&mut sys, mesh, lmax, 0.0, &mut u, rel, abs, left).map(|o| {
                    (
                        o.iterations,
                        o.evaluations,
                        o.restarts,
                        o.residual,
                        o.converged,
                    )
                })
            }
        };
        match out {
            Ok((steps, evals, rs, residual, converged)) => {
                row.iterations += steps;
                evaluations += evals;
                restarts += rs;
                row.residual = residual;
                row.converged = last && converged;
                if !converged {
                    break;
                }
            }
            Err(e) => {
                failure = Some(format!("{e:?}"));
                break;
            }
        }
    }
    row.wall_s = t0.elapsed().as_secs_f64();
    row.force_evaluations = evaluations as f64;
    row.max_u = max_nodal(&u);
    row.note = match failure {
        Some(e) => format!("failed: {e}"),
        None if stages > 1 => format!("finest only, pull in {stages} increments"),
        None => "finest only".into(),
    };
    if relaxer == Relaxer::Chebyshev && !row.note.starts_with("failed") {
        row.note += &format!(", {restarts} restarts");
    }
    if let Some(st) = &start {
        row.note = format!("{}, {}", row.note, st.describe());
    }
    Ok((row, u))
}

/// The fastest converged row of a sweep (else the first), its note extended with every
/// variant's wall time.
fn best_of(mut variants: Vec<(Row, Vec<f64>)>, label: &str) -> (Row, Vec<f64>) {
    let summary: Vec<String> = variants
        .iter()
        .map(
            |(r, _)| match (r.converged, r.note.strip_prefix("failed: ")) {
                (true, _) => format!("{:.2} s", r.wall_s),
                (false, Some(why)) => format!("{:.2} s (failed: {why})", r.wall_s),
                (false, None) => format!("{:.2} s (not converged)", r.wall_s),
            },
        )
        .collect();
    let best = variants
        .iter()
        .enumerate()
        .filter(|(_, (r, _))| r.converged)
        .min_by(|a, b| a.1 .0.wall_s.total_cmp(&b.1 .0.wall_s))
        .map_or(0, |(i, _)| i);
    let (mut row, u) = variants.swap_remove(best);
    if summary.len() > 1 {
        row.note += &format!("; {label}: {}", summary.join(", "));
    }
    (row, u)
}

/// Run the five solvers on `case`, each at its best settings by the module's rule (direct
/// Newton over [`NEWTON_REUSE`], FAS over [`FAS_SWEEPS`], Newton-multigrid over
/// [`NEWTON_MG_VARIANTS`]); a row each: direct Newton, FAS, ADR, Chebyshev, Newton-multigrid.
pub fn run_case(case: &Case, emit: &mut dyn FnMut(&str)) -> Result<Vec<Row>> {
    let sc = &case.scenario;
    let ends = prescribed_ends(sc).ok_or_else(|| {
        Error::param(
            "bench equilibrium",
            "prescribed motions must settle (no sine)",
        )
    })?;
    let target = REL_TOL * max_nodal(&sc.build_system()?.f_ext) + ABS_TOL;
    let list = |v: &[usize]| {
        v.iter()
            .map(|x| x.to_string())
            .collect::<Vec<_>>()
            .join(" / ")
    };
    let reduced = case.reduced;
    emit(&format!("{}: direct Newton ...", case.name));
    let reuse: Vec<(usize, bool)> = NEWTON_REUSE
        .into_iter()
        .filter(|&(m, _)| !reduced || m > 0)
        .collect();
    let (mut newton, u_newton) = best_of(
        reuse
            .iter()
            .map(|&m| newton_run(case, target, m))
            .collect::<Result<_>>()?,
        &format!(
            "reuse {}",
            reuse
                .iter()
                .map(|&(m, nested)| format!(
                    "{}{}",
                    if m == 0 {
                        "none".to_string()
                    } else {
                        format!("{m} CG")
                    },
                    if nested { " from the coarse start" } else { "" }
                ))
                .collect::<Vec<_>>()
                .join(" / ")
        ),
    );
    let reference = newton.converged.then_some(u_newton.as_slice());
    // The potential energy of each equilibrium, to tell which is lower where two differ.
    let probe = sc.build_system()?;
    let energy = |r: &mut Row, u: &[f64]| {
        if r.note.starts_with("failed") || u.is_empty() {
            return;
        }
        r.note += &format!("; Π = {:.9e} J", potential(&probe, u));
    };
    let compare = |r: &mut Row, u: &[f64]| {
        if r.note.starts_with("failed") || u.is_empty() {
            return;
        }
        r.diff_newton = reference.map(|un| max_nodal_diff(u, un));
        energy(r, u);
    };
    if reference.is_some() {
        newton.diff_newton = Some(0.0);
    }
    energy(&mut newton, &u_newton);
    emit(&format!("{}: FAS ...", case.name));
    let sweeps: Vec<usize> = FAS_SWEEPS
        .into_iter()
        .filter(|&k| !reduced || k == 16)
        .collect();
    let (mut fas, u_fas) = best_of(
        sweeps
            .iter()
            .map(|&k| fas_run(case, target, k, &ends))
            .collect::<Result<_>>()?,
        &format!("sweeps {}", list(&sweeps)),
    );
    compare(&mut fas, &u_fas);
    let mut relaxed = Vec::new();
    for relaxer in [Relaxer::Adr, Relaxer::Chebyshev] {
        emit(&format!("{}: {} ...", case.name, relaxer.label()));
        let (mut row, u) = best_of(
            [false, true]
                .into_iter()
                .map(|nested| relax_run(case, target, &ends, nested, relaxer))
                .collect::<Result<_>>()?,
            "from rest / from the coarse start",
        );
        compare(&mut row, &u);
        relaxed.push(row);
    }
    emit(&format!("{}: Newton-multigrid ...", case.name));
    let (mut nmg, u_nmg) = best_of(
        NEWTON_MG_VARIANTS
            .iter()
            .filter(|v| !reduced || !v.0)
            .map(|&v| newton_mg_run(case, target, v))
            .collect::<Result<_>>()?,
        if reduced {
            "keeps the coarse factor with coloured block Gauss-Seidel, block Jacobi, point Gauss-Seidel; the same three from the coarse start"
        } else {
            "keeps the coarse factor / all with coloured block Gauss-Seidel, then block Jacobi, then point Gauss-Seidel; the same six from the coarse start"
        },
    );
    compare(&mut nmg, &u_nmg);
    let mut rows = vec![newton, fas];
    rows.extend(relaxed);
    rows.push(nmg);
    Ok(rows)
}

/// Run every case ([`run_case`]); `emit` gets a progress line before each solve.
pub fn run(cases: &[Case], emit: &mut dyn FnMut(&str)) -> Result<Vec<Row>> {
    let mut rows = Vec::new();
    for c in cases {
        rows.extend(run_case(c, emit)?);
    }
    Ok(rows)
}

/// Whether every row converged and agrees with Newton's equilibrium.
pub fn all_ok(rows: &[Row]) -> bool {
    rows.iter()
        .all(|r| r.converged && r.agrees().unwrap_or(false))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data")
    }

    fn check(rows: &[Row]) {
        let table = to_markdown(rows) + &summary_markdown(rows);
        println!("{table}");
        for r in rows {
            assert!(
                r.converged,
                "{} / {}: not converged\n{table}",
                r.case, r.solver
            );
            assert!(r.residual <= r.target);
            assert_eq!(r.agrees(), Some(true), "{} / {}\n{table}", r.case, r.solver);
            // Newton-multigrid's parts are its wall time, each measured, none negative.
            if let Some(p) = r.parts {
                let all = p.all();
                assert!(all.iter().all(|&x| x >= 0.0), "{p:?}");
                assert!(
                    p.hierarchies_s > 0.0 && p.assembly_s > 0.0 && p.cg_s > 0.0,
                    "{p:?}"
                );
                let sum: f64 = all.iter().sum();
                assert!(
                    (sum - r.wall_s).abs() <= 1e-9 * r.wall_s.max(1.0),
                    "{sum} vs {}",
                    r.wall_s
                );
            }
        }
        assert!(rows
            .iter()
            .any(|r| r.solver == "Newton-multigrid" && r.parts.is_some()));
        assert!(all_ok(rows));
    }

    /// A small drape (a few seconds in debug): the machinery and the agreement.
    #[test]
    fn small_drape_solvers_agree() {
        let rows = run(&[drape(300, 2).unwrap()], &mut |_| {}).unwrap();
        assert_eq!(rows.len(), 5);
        check(&rows);
    }

    /// The 10k drape (FAS on 5 levels): the five solvers reach the common criterion and one
    /// equilibrium (1e-6 of max |u|). The liver's solvers are checked by
    /// `quick_cases_converge_and_agree` (L2, with and without the pull).
    #[test]
    #[ignore = "slow: 10k membrane; run in release with --ignored"]
    fn drape_10k_solvers_reach_one_equilibrium() {
        let rows = run(&[drape(10_000, 5).unwrap()], &mut |_| {}).unwrap();
        assert_eq!(rows.len(), 5);
        check(&rows);
    }

    /// The quick cases of `raisov bench equilibrium --quick`.
    #[test]
    #[ignore = "slow in debug: liver meshes; run in release with --ignored"]
    fn quick_cases_converge_and_agree() {
        let rows = run(&cases(&data(), true).unwrap(), &mut |_| {}).unwrap();
        check(&rows);
    }
}
