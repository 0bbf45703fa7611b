//! `raisov bench frames`: the standard frame benchmark of the interactive loop — how fast
//! frames come and how far each leaves the tissue from its equilibrium, on organs, grasps
//! and paths defined once here.
//!
//! Work (one case = organ × law × grasp × path × frame solver):
//! - organs: the liver L0 hierarchy of `data/` (L0 16 693 nodes; FAS with L1, L2, L3),
//!   millimetres scaled to metres, held on the cap z ≥ 0.195 m; the heart L0 hierarchy
//!   (8 359 nodes; L1-L3), held on the cap within 5 mm of its highest point; with `--organ
//!   liver50k`, the liver meshed from `data/liver_surface.obj` at about 50 000 nodes on four
//!   generated levels of ratio 0.5 (FAS, the coarsest level solved by Newton-Krylov as
//!   `examples/liver_surface.toml`), held on the same cap;
//! - laws: compressible neo-Hookean and stable neo-Hookean, E = 5 kPa, ν = 0.45,
//!   ρ = 1060 kg/m³;
//! - grasps, all taken before frame 1 as the viewer takes them
//!   ([`raisov::scenario::grasps`]): the surface patch of radius 10 mm at the surface point
//!   nearest (0.12, 0.07, 0.10) m held rigidly (`rigid`); the same patch through zero-length
//!   springs of total stiffness 200 N/m, the viewer's default (`springs`); the one node there
//!   (`node`). The heart's grasp: the patch of radius 3 mm at the surface point nearest
//!   (0.033, −0.048, 0.033) m (the middle of its front);
//! - paths: the grasp pulled by (0, −0.01, −0.017) m over 0.5 s, then held 0.5 s (`slow`,
//!   30 frames), or over 0.1 s, then held 0.5 s (`fast`, 18 frames), 30 frames per second of
//!   path time; on the heart a fifth of that pull, (0, −0.002, −0.0034) m (the heart is
//!   about a fifth of the liver's size: 29 against 150 mm across);
//! - frame solvers: FAS warm started from the last frame, 1, 2 and 4 V-cycles per frame
//!   (`[interactive] cycles`), and the Newton frame solver (`[multigrid] scheme = "newton"`,
//!   [`raisov::statics::frames`]: one Newton step a frame, `newton` in the case's name), each
//!   without and with the frame predictor (`[interactive] predictor`: the frame starts from
//!   the last frame's change extrapolated, [`raisov::sim::frame`]; the Newton step's
//!   conjugate gradients start from it); and, named (`--case ...,rapier`) and built with the
//!   cargo feature `rapier`, the outside peer: rapier's FEM soft body on level 0, one implicit
//!   Euler step a frame at the settings its rule chose (module `rapier_peer`; its row's name
//!   ends in `rapier SxC aA`: S substeps of at most C CG iterations, linear damping A /s, and
//!   its table has no evaluation count or residual), followed by its lag against its own
//!   equilibria; `rapier-sweep` runs that rule instead, a row per setting.
//!
//! Per case, from [`raisov::scenario::interactive`]'s summary: frames per second of stepper
//! wall time (`fps`; `fps-1` without the slowest frame, which for the frame solver is a
//! grasp's first, where it builds its operator), the mean and largest relative lag `max_a |u_a − u*_a| / max_a |u*_a|` over the
//! free nodes, `u*` the frame's static equilibrium by the project's static Newton solver to
//! 10⁻⁸ of the frame's force scale (a frame whose reference fails is counted and has no lag),
//! force evaluations per frame in finest-level units (a count any machine reproduces), the
//! slowest frame, the residual after the last frame, and the frames rejected (every try
//! inverted an element or diverged, [`raisov::sim::frame`]: the state before it kept). A frame's wall time is the solve;
//! the viewer's own per-frame work (the surface positions and the colour scalar |u|) is
//! measured once per organ and printed beside it.
//!
//! Targets (issue: real time on the organ): the liver L0 at ≥ 60 frames/s with mean lag
//! ≤ 1 % and largest ≤ 3 %; the 50k liver at ≥ 30 frames/s; the heart at ≥ 60. Each row
//! says whether it meets them and, where it does not, what limits it: for FAS the evaluations
//! a frame could spend at the target rate at the measured cost of one; for the frame solver
//! the time a frame may take against the time spent, split into the slowest frame (a grasp's
//! first, where the operator is built) and the mean of the others.

use raisov::runner::{solve, Finished, RunOptions};
use raisov::scenario::Scenario;
use raisov::{Error, Result};
use std::path::Path;
use std::time::Instant;

/// The organs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Organ {
    /// The liver L0 hierarchy of `data/`.
    Liver,
    /// The liver meshed from its surface at about 50k nodes.
    Liver50k,
    /// The heart L0 hierarchy of `data/`.
    Heart,
}

impl Organ {
    /// The organs of a run: `liver`, `heart`, `liver50k` or `all` (the first two by default).
    pub fn parse(s: &str) -> Result<Vec<Organ>> {
        Ok(match s {
            "liver" => vec![Organ::Liver],
            "heart" => vec![Organ::Heart],
            "liver50k" => vec![Organ::Liver50k],
            "default" => vec![Organ::Liver, Organ::Heart],
            "all" => vec![Organ::Liver, Organ::Heart, Organ::Liver50k],
            _ => {
                return Err(Error::param(
                    "--organ",
                    format!("`{s}`: valid are liver, heart, liver50k, all"),
                ))
            }
        })
    }
    fn name(self) -> &'static str {
        match self {
            Organ::Liver => "liver L0",
            Organ::Liver50k => "liver 50k",
            Organ::Heart => "heart L0",
        }
    }
    /// The frames per second the issue asks of the organ.
    fn target_fps(self) -> f64 {
        match self {
            Organ::Liver50k => 30.0,
            _ => 60.0,
        }
    }
}

/// The grasps of the module docs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Grasp {
    /// The patch held rigidly.
    Rigid,
    /// The patch through springs of 200 N/m in total.
    Springs,
    /// One node held rigidly.
    Node,
}

impl Grasp {
    fn name(self) -> &'static str {
        match self {
            Grasp::Rigid => "rigid",
            Grasp::Springs => "springs",
            Grasp::Node => "node",
        }
    }
}

/// The laws of the module docs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Law {
    /// Compressible neo-Hookean.
    NeoHookean,
    /// Stable neo-Hookean.
    StableNeoHookean,
}

impl Law {
    fn key(self) -> &'static str {
        match self {
            Law::NeoHookean => "neo-hookean",
            Law::StableNeoHookean => "stable-neo-hookean",
        }
    }
    fn name(self) -> &'static str {
        match self {
            Law::NeoHookean => "NH",
            Law::StableNeoHookean => "SNH",
        }
    }
}

/// The frame solvers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Solver {
    /// FAS V-cycles over the four levels, `cycles` a frame.
    Fas,
    /// The frame solver of [`raisov::statics::frames`] (`[multigrid] scheme = "newton"`): one
    /// Newton step a frame, its Galerkin V-cycle over level 0 and the coarse level the static
    /// solver takes.
    Newton,
    /// The outside peer: rapier's FEM soft body on level 0, one implicit Euler step a frame
    /// (`rapier_peer`, built with the cargo feature `rapier`).
    Rapier,
}

/// What a run measures (module docs).
#[derive(Clone, Debug)]
pub struct FramesOptions {
    pub organs: Vec<Organ>,
    pub laws: Vec<Law>,
    pub grasps: Vec<Grasp>,
    /// `false`: the slow path; `true`: the fast one.
    pub paces: Vec<bool>,
    /// V-cycles per frame.
    pub cycles: Vec<u32>,
    /// Without and/or with the frame predictor ([`raisov::sim::Simulation::set_predictor`]).
    pub predictor: Vec<bool>,
    /// The frame solvers; the Newton frame solver runs one step a frame whatever `cycles`,
    /// rapier one step of its chosen settings.
    pub solvers: Vec<Solver>,
    /// With [`Solver::Rapier`]: instead of its chosen settings, the sweep of the rule that
    /// chose them (`rapier_peer` module docs), a row per setting.
    pub rapier_sweep: bool,
}

impl FramesOptions {
    /// Every case of the module docs on `organs`; `quick`: neo-Hookean, the patch grasps,
    /// the slow path, 2 V-cycles.
    pub fn new(organs: Vec<Organ>, quick: bool) -> FramesOptions {
        if quick {
            FramesOptions {
                organs,
                laws: vec![Law::NeoHookean],
                grasps: vec![Grasp::Rigid, Grasp::Springs],
                paces: vec![false],
                cycles: vec![2],
                predictor: vec![false, true],
                solvers: vec![Solver::Fas, Solver::Newton],
                rapier_sweep: false,
            }
        } else {
            FramesOptions {
                organs,
                laws: vec![Law::NeoHookean, Law::StableNeoHookean],
                grasps: vec![Grasp::Rigid, Grasp::Springs, Grasp::Node],
                paces: vec![false, true],
                cycles: vec![1, 2, 4],
                predictor: vec![false, true],
                solvers: vec![Solver::Fas, Solver::Newton],
                rapier_sweep: false,
            }
        }
    }
}

/// One case's result.
#[derive(Clone, Debug)]
pub struct FramesRow {
    pub case: String,
    pub solver: Solver,
    pub predictor: bool,
    pub cycles: u32,
    pub frames: usize,
    pub fps: f64,
    /// Frames per second without the slowest frame (a grasp's first frame, where the frame
    /// solver builds its operator).
    pub fps_rest: f64,
    pub lag_mean: f64,
    pub lag_max: f64,
    pub evals_per_frame: f64,
    pub slowest_ms: f64,
    pub residual: f64,
    pub reference_failures: usize,
    /// Frames rejected (every try inverted an element or diverged: the state before kept).
    pub rejected: usize,
    pub target_fps: f64,
}

impl FramesRow {
    /// Whether the row meets its organ's frame rate with mean lag ≤ 1 % and largest ≤ 3 %.
    pub fn meets(&self) -> bool {
        self.reference_failures == 0
            && self.rejected == 0
            && self.fps >= self.target_fps
            && self.lag_mean <= 0.01
            && self.lag_max <= 0.03
    }
}

/// The scenario of one case (module docs).
#[allow(clippy::too_many_arguments)]
pub fn scenario(
    meshes: &Path,
    organ: Organ,
    law: Law,
    grasp: Grasp,
    fast: bool,
    cycles: u32,
    predictor: bool,
    solver: Solver,
) -> Result<Scenario> {
    let d = meshes.display();
    let (mesh, cap, point, radius, pull, multigrid) = match organ {
        Organ::Liver => (
            format!("file = '{d}/liver_L0.msh'\nscale = 0.001"),
            0.195,
            [0.12, 0.07, 0.10],
            0.01,
            [0.0, -0.01, -0.017],
            format!(
                "scheme = \"fas\"\nfiles = ['{d}/liver_L1.msh', '{d}/liver_L2.msh', '{d}/liver_L3.msh']"
            ),
        ),
        Organ::Liver50k => (
            format!("surface = '{d}/liver_surface.obj'\nscale = 0.001\nnodes = 50000"),
            0.195,
            [0.12, 0.07, 0.10],
            0.01,
            [0.0, -0.01, -0.017],
            match solver {
                Solver::Fas | Solver::Rapier => {
                    "scheme = \"fas\"\nlevels = 4\nratio = 0.5\ncoarse = \"newton\""
                }
                Solver::Newton => "scheme = \"newton\"\nlevels = 4\nratio = 0.5",
            }
            .to_string(),
        ),
        Organ::Heart => {
            let m = raisov::io::gmsh::read_msh(&meshes.join("heart_L0.msh"))?.mesh;
            let z_top = m.nodes.iter().map(|p| p[2]).fold(f64::MIN, f64::max) * 0.001;
            (
                format!("file = '{d}/heart_L0.msh'\nscale = 0.001"),
                z_top - 0.005,
                [0.033, -0.048, 0.033],
                0.003,
                [0.0, -0.002, -0.0034],
                format!(
                    "scheme = \"fas\"\nfiles = ['{d}/heart_L1.msh', '{d}/heart_L2.msh', '{d}/heart_L3.msh']"
                ),
            )
        }
    };
    // rapier's case is FAS's: its hierarchy is only the reference solve's coarse level.
    let multigrid = match solver {
        Solver::Fas | Solver::Rapier => multigrid,
        Solver::Newton => multigrid.replacen("scheme = \"fas\"", "scheme = \"newton\"", 1),
    };
    let radius = if grasp == Grasp::Node { 0.0 } else { radius };
    let stiffness = if grasp == Grasp::Springs {
        "stiffness = 200.0\n"
    } else {
        ""
    };
    let t_pull = if fast { 0.1 } else { 0.5 };
    let duration = t_pull + 0.5;
    let [px, py, pz] = pull;
    let text = format!(
        r#"
name = "frames"
[mesh]
{mesh}
[material]
law = "{law}"
young = 5000.0
poisson = 0.45
density = 1060.0
[[fix]]
plane = {{ point = [0.0, 0.0, {cap:?}], normal = [0.0, 0.0, -1.0] }}
[[displace]]
point = [{x:?}, {y:?}, {z:?}]
radius = {radius:?}
start = 0.0
{stiffness}mode = "table"
table = [[0.0, 0.0, 0.0, 0.0], [{t_pull:?}, {px:?}, {py:?}, {pz:?}], [{duration:?}, {px:?}, {py:?}, {pz:?}]]
[integrator]
method = "symplectic-euler"
[run]
duration = {duration:?}
[multigrid]
{multigrid}
[interactive]
fps = 30.0
cycles = {cycles}
predictor = {predictor}
"#,
        law = law.key(),
        x = point[0],
        y = point[1],
        z = point[2],
    );
    Scenario::from_toml(&text, Path::new("bench-frames.toml"))
}

/// The viewer's own work after a frame on `sc`'s finest mesh (the surface positions and
/// |u| at every node), ms: the best of 20.
fn viewer_work_ms(sc: &Scenario) -> f64 {
    let mesh = &sc.mesh;
    let surface: Vec<u32> = {
        let mut on = vec![false; mesh.num_nodes()];
        for t in mesh.boundary_facets() {
            for i in t {
                on[i as usize] = true;
            }
        }
        (0..mesh.num_nodes() as u32)
            .filter(|&i| on[i as usize])
            .collect()
    };
    let u = vec![1e-3; 3 * mesh.num_nodes()];
    let mut best = f64::INFINITY;
    let mut sink = 0.0;
    for _ in 0..20 {
        let t0 = Instant::now();
        let pos: Vec<[f32; 3]> = surface
            .iter()
            .map(|&i| {
                let a = i as usize;
                let x = mesh.nodes[a];
                [
                    (x[0] + u[3 * a]) as f32,
                    (x[1] + u[3 * a + 1]) as f32,
                    (x[2] + u[3 * a + 2]) as f32,
                ]
            })
            .collect();
        let colour: Vec<f32> = surface
            .iter()
            .map(|&i| {
                let a = i as usize;
                (u[3 * a] * u[3 * a] + u[3 * a + 1] * u[3 * a + 1] + u[3 * a + 2] * u[3 * a + 2])
                    .sqrt() as f32
            })
            .collect();
        best = best.min(t0.elapsed().as_secs_f64());
        sink += (pos.len() + colour.len()) as f64;
    }
    std::hint::black_box(sink);
    1e3 * best
}

/// Whether this build runs every case `opts` asks for: the rapier peer needs the cargo
/// feature `rapier` (an error saying how to build with it).
pub fn check(opts: &FramesOptions) -> Result<()> {
    if opts.solvers.contains(&Solver::Rapier) && !cfg!(feature = "rapier") {
        return Err(Error::param(
            "--case rapier",
            "this raisov was built without the rapier peer: build it with the cargo feature \
             `rapier`, e.g. `cargo run --release -p raisov-cli --features rapier -- bench \
             frames --case NH,rigid,slow,rapier`",
        ));
    }
    Ok(())
}

/// Run the cases of `opts` on the meshes of `meshes`, a line of the table at a time to `out`
/// ([`check`] first).
pub fn frames(
    meshes: &Path,
    opts: &FramesOptions,
    out: &mut dyn FnMut(&str),
) -> Result<Vec<FramesRow>> {
    check(opts)?;
    out(&format!(
        "raisov bench frames: {} thread(s); each case's lag against its frames' static \
         equilibria to 1e-8 of the force scale",
        rayon::current_num_threads()
    ));
    let mut rows = Vec::new();
    for &organ in &opts.organs {
        let mut header = false;
        for &law in &opts.laws {
            for &grasp in &opts.grasps {
                for &fast in &opts.paces {
                    let runs: Vec<(Solver, u32, bool)> = opts
                        .solvers
                        .iter()
                        .flat_map(|&solver| {
                            let cycles = match solver {
                                Solver::Fas => opts.cycles.clone(),
                                Solver::Newton | Solver::Rapier => vec![1],
                            };
                            // rapier takes no prediction from raisov: one row.
                            let predictor = match solver {
                                Solver::Rapier => vec![false],
                                _ => opts.predictor.clone(),
                            };
                            cycles.into_iter().flat_map(move |c| {
                                predictor.clone().into_iter().map(move |p| (solver, c, p))
                            })
                        })
                        .collect();
                    for (solver, cycles, predictor) in runs {
                        let sc =
                            scenario(meshes, organ, law, grasp, fast, cycles, predictor, solver)?;
                        if !header {
                            header = true;
                            out(&format!(
                                "\n{}: {} nodes; the viewer's own work after a frame {:.2} ms",
                                organ.name(),
                                sc.mesh.num_nodes(),
                                viewer_work_ms(&sc)
                            ));
                            out(&format!(
                                "{:<35} {:>6} {:>7} {:>7} {:>9} {:>9} {:>11} {:>9} {:>11} {:>5} {:>8}  {}",
                                "case",
                                "cycles",
                                "fps",
                                "fps-1",
                                "mean lag",
                                "max lag",
                                "evals/frame",
                                "slowest",
                                "residual N",
                                "refs",
                                "rejected",
                                "goal"
                            ));
                        }
                        let case = format!(
                            "{} {} {}{}{}",
                            law.name(),
                            grasp.name(),
                            if fast { "fast" } else { "slow" },
                            match solver {
                                Solver::Fas => "",
                                Solver::Newton => " newton",
                                Solver::Rapier => " rapier",
                            },
                            if predictor { " predicted" } else { "" }
                        );
                        if solver == Solver::Rapier {
                            rows.extend(rapier_rows(&sc, organ, &case, opts.rapier_sweep, out)?);
                            continue;
                        }
                        let solution = solve(
                            &sc,
                            RunOptions {
                                in_memory: true,
                                ..Default::default()
                            },
                        )?;
                        let Finished::Interactive(s) = &solution.finished else {
                            return Err(Error::param("bench frames", "not an interactive run"));
                        };
                        if rows.iter().all(|r: &FramesRow| {
                            !r.case.starts_with(organ.name()) || r.solver != solver
                        }) {
                            out(&format!("stepper: {}", s.stepper));
                        }
                        let row = FramesRow {
                            case: format!("{} {case}", organ.name()),
                            solver,
                            predictor,
                            cycles,
                            frames: s.frames,
                            fps: s.fps(),
                            fps_rest: if s.frames > 1 && s.wall > s.wall_max {
                                (s.frames - 1) as f64 / (s.wall - s.wall_max)
                            } else {
                                f64::NAN
                            },
                            lag_mean: s.lag_rel_mean(),
                            lag_max: s.lag_rel_max,
                            evals_per_frame: s.evals_per_frame(),
                            slowest_ms: 1e3 * s.wall_max,
                            residual: s.last.map_or(f64::NAN, |l| l.residual),
                            reference_failures: s.reference_failures,
                            rejected: s.rejected_frames,
                            target_fps: organ.target_fps(),
                        };
                        let goal = if row.meets() {
                            "met".to_string()
                        } else if solver == Solver::Fas {
                            // The evaluations a frame may spend at the target rate.
                            let per_eval = 1.0 / (row.fps * row.evals_per_frame.max(1e-12));
                            format!(
                                "missed: {:.0} evals/frame fit at {} fps",
                                1.0 / (row.target_fps * per_eval),
                                row.target_fps
                            )
                        } else {
                            // The frame solver's work is its CG iterations: say what fails.
                            goal_of(&row)
                        };
                        out(&format!(
                            "{:<35} {:>6} {:>7.1} {:>7.1} {:>8.2}% {:>8.2}% {:>11.1} {:>7.1}ms {:>11.3e} {:>5} {:>8}  {goal}",
                            case,
                            cycles,
                            row.fps,
                            row.fps_rest,
                            100.0 * row.lag_mean,
                            100.0 * row.lag_max,
                            row.evals_per_frame,
                            row.slowest_ms,
                            row.residual,
                            format!("{}/{}", row.frames - row.reference_failures, row.frames),
                            row.rejected,
                        ));
                        rows.push(row);
                    }
                }
            }
        }
    }
    Ok(rows)
}

/// The goal column of a row that is not FAS's: what fails, or `met`.
pub(crate) fn goal_of(row: &FramesRow) -> String {
    if row.meets() {
        return "met".to_string();
    }
    let mut why = Vec::new();
    if row.fps < row.target_fps {
        // Where the time goes: the slowest frame (for the frame solver a grasp's first, where
        // the operator is built) against the others.
        let frames = row.frames.max(1) as f64;
        let mean_ms = 1e3 / row.fps.max(1e-12);
        let rest_ms = if row.frames > 1 {
            (mean_ms * frames - row.slowest_ms) / (frames - 1.0)
        } else {
            f64::NAN
        };
        why.push(format!(
            "{:.2}x too slow ({:.1} ms a frame fit, {:.1} spent: the slowest {:.0} ms is {:.0}% \
             of the run, the others {:.1} ms on average)",
            row.target_fps / row.fps.max(1e-12),
            1e3 / row.target_fps,
            mean_ms,
            row.slowest_ms,
            100.0 * row.slowest_ms / (mean_ms * frames),
            rest_ms,
        ));
    }
    // By how much a lag misses its bound; what bounds it is the frame's work (the steps a
    // frame takes: `--cycles`, or the frame solver's one step of at most `cg_per_step`
    // conjugate-gradient iterations).
    if row.lag_mean > 0.01 {
        why.push(format!("mean lag {:.2}x its 1% bound", row.lag_mean / 0.01));
    }
    if row.lag_max > 0.03 {
        why.push(format!("max lag {:.2}x its 3% bound", row.lag_max / 0.03));
    }
    if row.reference_failures + row.rejected > 0 {
        why.push("failed or rejected frames".to_string());
    }
    format!("missed: {}", why.join(", "))
}

/// rapier's rows of a case (`rapier_peer`): its chosen settings, or the sweep that chose
/// them; each followed by its lags against its own equilibria.
#[cfg(feature = "rapier")]
fn rapier_rows(
    sc: &Scenario,
    organ: Organ,
    case: &str,
    sweep: bool,
    out: &mut dyn FnMut(&str),
) -> Result<Vec<FramesRow>> {
    use super::rapier_peer::{self as rp, RapierSettings};
    let fps = sc.interactive.map_or(30.0, |i| i.fps);
    // rapier's own equilibria of the frames: the same for every setting.
    let rest = rp::rest(sc)?;
    let mut rows = Vec::new();
    let row_of = |run: &rp::PeerRun, out: &mut dyn FnMut(&str)| {
        let s = &run.summary;
        let (fps, fps_rest) = run.fps();
        let row = FramesRow {
            case: format!("{} {case}", organ.name()),
            solver: Solver::Rapier,
            predictor: false,
            cycles: run.settings.substeps as u32,
            frames: s.frames,
            fps,
            fps_rest,
            lag_mean: s.lag_rel_mean(),
            lag_max: s.lag_rel_max,
            evals_per_frame: f64::NAN,
            slowest_ms: 1e3 * run.wall.iter().copied().fold(0.0, f64::max),
            residual: f64::NAN,
            reference_failures: s.reference_failures,
            rejected: s.rejected_frames,
            target_fps: organ.target_fps(),
        };
        out(&format!("stepper: {}", s.stepper));
        let st = &run.settings;
        out(&format!(
            "{:<35} {:>6} {:>7.1} {:>7.1} {:>8.2}% {:>8.2}% {:>11} {:>7.1}ms {:>11} {:>5} {:>8}  {}",
            format!("{case} {}x{} a{}", st.substeps, st.cg_max, st.damping),
            "-",
            row.fps,
            row.fps_rest,
            100.0 * row.lag_mean,
            100.0 * row.lag_max,
            "-",
            row.slowest_ms,
            "-",
            format!("{}/{}", row.frames - row.reference_failures, row.frames),
            row.rejected,
            goal_of(&row),
        ));
        out(&format!(
            "  against rapier's own equilibria: mean {:.2}%, max {:.2}%",
            100.0 * run.own_mean,
            100.0 * run.own_max,
        ));
        row
    };
    out(&format!(
        "rapier's own equilibria (each frame run to rest, {:.1} implicit steps of 100 s on \
         average{}) against raisov's u*, the law's difference: mean {:.2}%, max {:.2}%",
        rest.mean_steps,
        if rest.unsettled > 0 {
            format!("; {} frames missed the rule", rest.unsettled)
        } else {
            String::new()
        },
        100.0 * rest.summary.lag_rel_mean(),
        100.0 * rest.summary.lag_rel_max
    ));
    if sweep {
        let chosen = rp::sweep(sc, &rest, &mut |run| rows.push(row_of(run, out)))?;
        out(&format!("rapier: the rule chose {}", chosen.describe()));
    } else {
        let run = rp::peer(sc, RapierSettings::chosen(fps), &rest)?;
        rows.push(row_of(&run, out));
    }
    Ok(rows)
}

/// Without the cargo feature `rapier`: refused ([`frames`] refuses before any case).
#[cfg(not(feature = "rapier"))]
fn rapier_rows(
    _sc: &Scenario,
    _organ: Organ,
    _case: &str,
    _sweep: bool,
    _out: &mut dyn FnMut(&str),
) -> Result<Vec<FramesRow>> {
    Err(Error::param(
        "--case rapier",
        "this raisov was built without the rapier peer (cargo feature `rapier`)",
    ))
}
