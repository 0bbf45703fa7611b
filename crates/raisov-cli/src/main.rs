//! `raisov`: run soft-tissue scenarios, inspect and generate meshes.

mod check;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use raisov::io::{load_mesh, write_msh22, write_vtu};
use raisov::mesh::generate::{box_tets, box_tets_target, polygon_membrane, rectangle_membrane};
use raisov::mesh::Mesh;
use raisov::runner::RunOptions;
use raisov::scenario::spec::{box_pattern, defaults};
use raisov::scenario::Scenario;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};

/// The paper's membrane, lifted 3 cm at its centre, solved to steady state by the FAS multigrid
/// over the paper's four levels (the fastest to steady state, measured): the built-in default.
const BUILTIN: &str = include_str!("../../../examples/membrane_lift_multigrid.toml");

/// Exit status: the run diverged, or something failed while running (writing output, the
/// output directory locked by another run).
const EXIT_FAILED: i32 = 1;
/// Exit status: bad input (scenario, mesh, command line).
const EXIT_BAD_INPUT: i32 = 2;
/// Exit status: `stop = "steady"` did not reach steady state (time cap or stagnation).
const EXIT_NOT_CONVERGED: i32 = 3;
/// Exit status: interrupted by SIGINT or SIGTERM (128 + 2, the shell's convention for SIGINT).
const EXIT_INTERRUPTED: i32 = 130;

#[derive(Parser)]
#[command(
    name = "raisov",
    version,
    about = "Nonlinear FEM soft-tissue simulation with multigrid explicit integration (Wu & Tendick 2004)",
    after_help = "Exit status:\n  0    ok\n  1    the run diverged, or failed while running (output not writable, output directory locked by another run)\n  2    bad input (scenario, mesh file, command line)\n  3    not converged: stop = \"steady\" did not reach steady state (time cap or stagnation)\n  130  interrupted by SIGINT (Ctrl-C) or SIGTERM: stopped at a step boundary, measures and summary written"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

/// Benchmarks other than the standard work.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum BenchSuite {
    /// The embedding API (`raisov_lab::bench::api`).
    Api,
    /// Time to static equilibrium: direct Newton, FAS, adaptive dynamic relaxation,
    /// single-level Chebyshev and Newton-multigrid on the liver, the liver pulled, the heart and the drapes
    /// (`raisov_lab::equilibrium`).
    Equilibrium,
    /// The closed-surface check (self-intersections) on fans of long thin triangles and the
    /// organ surfaces (`raisov_lab::bench::surface_check`).
    SurfaceCheck,
    /// Backward Euler on the liver L0 with the multigrid preconditioner at h = 1/60, 1/250
    /// and 1/1000 s against central differences (`raisov_lab::bench::implicit`; --quick:
    /// without 1/1000 s).
    Implicit,
    /// Cutting: one 3 cm cut across the liver L0 hierarchy (its time, the frame rate before
    /// and after) and 1 000 random cuts on the liver L1 hierarchy with gravity and a grasp
    /// (failures counted; `raisov_lab::bench::cut`; --quick: 100 cuts).
    Cut,
    /// The frame benchmark of the interactive loop: frames/s, lag to each frame's static
    /// equilibrium and force evaluations per frame on the liver and heart hierarchies,
    /// grasped and pulled (`raisov_lab::bench::frames`; --quick: neo-Hookean, patch grasps,
    /// the slow path, 2 V-cycles).
    Frames,
}

#[derive(Subcommand)]
enum Cmd {
    /// Run a scenario (TOML). Without SCENARIO, runs the built-in membrane lift (FAS multigrid).
    Run {
        /// Scenario file; omit for the built-in default (examples/membrane_lift_multigrid.toml).
        scenario: Option<PathBuf>,
        /// Output directory (overrides [output] dir).
        #[arg(long)]
        out: Option<PathBuf>,
        /// No progress bar.
        #[arg(long, short)]
        quiet: bool,
        /// Write the VTU frames as ASCII text (overrides [output] vtu; default binary,
        /// zlib-compressed).
        #[arg(long)]
        ascii_vtu: bool,
    },
    /// Parse and resolve a scenario, print what it would run, and exit.
    Check { scenario: PathBuf },
    /// Performance benchmark of the standard explicit-dynamics work (see `raisov_lab::bench`);
    /// `raisov bench api`: the embedding API's frame overhead and grasp-stiffness solves;
    /// `raisov bench equilibrium`: time to static equilibrium of five solvers;
    /// `raisov bench surface-check`: the closed-surface check on cones and organ surfaces;
    /// `raisov bench implicit`: backward Euler's cost per step and per simulated second;
    /// `raisov bench frames`: the interactive loop's frame rate and lag on organs.
    Bench {
        /// `api`: the embedding API's figures instead (`raisov_lab::bench::api`; --quick: a
        /// small cube); `equilibrium`: direct Newton, FAS, adaptive dynamic relaxation,
        /// single-level Chebyshev and Newton-multigrid to one stopping rule (`raisov_lab::equilibrium`; --quick: liver L2 and a 1k drape;
        /// exit status 3 if a solver misses the rule or an equilibrium disagrees).
        #[arg(value_enum)]
        suite: Option<BenchSuite>,
        /// Box sizes in nodes, e.g. 1k,10k,100k,1M.
        #[arg(long, default_value = "1k,10k,100k,1M")]
        sizes: String,
        /// Thread counts.
        #[arg(long, value_delimiter = ',', default_value = "1,2")]
        threads: Vec<usize>,
        /// Small sizes and few steps (CI smoke test).
        #[arg(long)]
        quick: bool,
        /// Also write the table to FILE (.csv or .md).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Write the standard boxes of --sizes to DIR/box_<size>.msh (Gmsh 2.2) and exit;
        /// `surface-check`: the cones to DIR/cone_<triangles>.obj.
        #[arg(long)]
        write_mesh: Option<PathBuf>,
        /// Only the correctness check: STEPS steps on the boxes of --sizes, then exit.
        #[arg(long)]
        check: Option<usize>,
        /// Only the standard-work rows (no integrator, V-cycle, membrane, hierarchy, memory rows).
        #[arg(long)]
        standard_only: bool,
        /// Storage precisions of the element data for the standard-work rows and the
        /// correctness check: f64 and/or f32-storage (`f32` for short: Dm⁻¹ and volumes in
        /// f32, arithmetic and state in f64). The other rows are f64.
        #[arg(long, default_value = "f64,f32")]
        precision: String,
        /// `equilibrium` and `implicit`: directory with liver_L*.msh (and heart_L*.msh); `surface-check`: with
        /// liver_surface.obj and heart_surface.obj; default `data` (relative to the working
        /// directory).
        #[arg(long)]
        meshes: Option<PathBuf>,
        /// `equilibrium`: only the cases with these names (comma-separated, e.g.
        /// "liver L0,membrane 100k"); default all but the liver meshed from its surface
        /// ("liver mesher 17k", "liver mesher 70k"), which run only when named;
        /// `surface-check`: e.g. "cone 80k,liver".
        /// `frames`: only the cases with these words (comma-separated, of NH, SNH,
        /// rigid, springs, node, slow, fast, fas, newton, rapier; each kind given narrows
        /// that kind; `rapier`, a solver word not among the defaults, is the outside peer,
        /// rapier's FEM soft body, and `rapier-sweep` runs the rule that chose its settings:
        /// both need the cargo feature `rapier`).
        #[arg(long, value_delimiter = ',')]
        case: Vec<String>,
        /// `frames`: the organs, one of liver, heart, liver50k, all (default: liver and heart).
        #[arg(long, default_value = "default")]
        organ: String,
        /// `frames`: V-cycles per frame (default 1,2,4; --quick 2).
        #[arg(long, value_delimiter = ',')]
        cycles: Vec<u32>,
    },
    /// Reproduce the paper's experiments (Wu & Tendick 2004): CSV, PNG/SVG plots, report.md.
    Paper {
        /// Output directory.
        #[arg(long, default_value = "raisov-out/paper")]
        out: PathBuf,
        /// Smaller hierarchies and fewer bisection steps (CI smoke test); no 100k-node runs.
        #[arg(long)]
        quick: bool,
        /// Directory with liver_L0..L3.msh; default `data` (relative to the working
        /// directory). The liver is skipped with a note if the files are absent.
        #[arg(long)]
        meshes: Option<PathBuf>,
        /// No progress bar.
        #[arg(long, short)]
        quiet: bool,
        /// Let single-level symplectic Euler run up to SECONDS of wall time in the
        /// time-to-steady runs (default: until 6x FAS's time and evaluations), so that it
        /// reaches steady state on the 100k membrane too (about 6 minutes there).
        #[arg(long, value_name = "SECONDS")]
        slim_cap: Option<f64>,
        /// Section 7 on every case of `raisov bench equilibrium` (the liver L1 and L0, the
        /// liver pulled, the heart, the 10k and 100k drapes; the run says how long up front);
        /// default its quick cases (the liver L2 and a 1k drape).
        #[arg(long)]
        equilibrium: bool,
    },
    /// Mesh tools.
    Mesh {
        #[command(subcommand)]
        cmd: MeshCmd,
    },
    /// Live viewer: serve the page, grab and drag the organ in the browser (Shift+drag grasps,
    /// Ctrl+click pins). Without an argument, the liver of examples/liver_interactive.toml.
    Serve {
        /// A scenario (.toml) or a closed surface (.obj, .stl, .ply), meshed at load.
        target: Option<PathBuf>,
        /// Port (0: any free port).
        #[arg(long, default_value_t = 8080)]
        port: u16,
        /// Address to bind (127.0.0.1: this machine only). Any other address exposes the
        /// viewer to the network: clients must then present a token (printed in the URL).
        #[arg(long, default_value = "127.0.0.1")]
        host: String,
        /// The token clients must present (16-128 letters, digits, '-', '_'); default: a
        /// random one where --host is not a loopback address, none on loopback.
        #[arg(long)]
        token: Option<String>,
        /// Open the page in the system's browser (else only print the URL).
        #[arg(long)]
        open: bool,
        /// V-cycles (multigrid) or steps (single level) per frame, instead of --budget-ms.
        #[arg(long)]
        cycles: Option<u32>,
        /// Wall time of the simulation per frame (ms).
        #[arg(long, default_value_t = 25.0)]
        budget_ms: f64,
        /// Cap on the simulation's frame rate (1/s; 0: none).
        #[arg(long, default_value_t = 60.0)]
        max_fps: f64,
        /// Start with this method: newton (the frame solver), fas, raisov or single (default: the scenario's).
        #[arg(long)]
        method: Option<String>,
        /// Also write the recorded scenario here when the page saves it.
        #[arg(long)]
        record: Option<PathBuf>,
        /// Surface coordinates times this are metres (a surface argument).
        #[arg(long, default_value_t = 1.0)]
        scale: f64,
        /// Level-0 node target when meshing a surface argument.
        #[arg(long, default_value_t = 8000)]
        nodes: usize,
        /// Total stiffness of the springs coupling the grasped patch to the cursor (N/m);
        /// 0 holds the patch rigidly.
        #[arg(long, default_value_t = 200.0)]
        grab_stiffness: f64,
    },
}

#[derive(Subcommand)]
enum MeshCmd {
    /// Counts, measure, element quality, inverted or degenerate elements, groups; for a
    /// triangle surface (.obj, .stl, .ply): closedness, components, volume, orientation repair.
    Info { file: PathBuf },
    /// Generate a membrane or a tetrahedral box and write it (.msh Gmsh 2.2, or .vtu).
    Generate {
        /// rectangle | polygon | box
        kind: String,
        /// Output file: .msh or .vtu
        #[arg(long, short)]
        out: PathBuf,
        /// Target node count.
        #[arg(long)]
        nodes: Option<usize>,
        /// Sizes in m: rectangle W,H; box X,Y,Z.
        #[arg(long, value_delimiter = ',')]
        size: Vec<f64>,
        /// Polygon vertices x1,y1,x2,y2,... (m).
        #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
        polygon: Vec<f64>,
        /// Box divisions NX,NY,NZ instead of --nodes.
        #[arg(long, value_delimiter = ',')]
        divisions: Vec<usize>,
        /// Box: 5 or 6 tets per cube (the default of a scenario's `[mesh] pattern`).
        #[arg(long, default_value_t = defaults::BOX_PATTERN.tets_per_cube() as u32)]
        pattern: u32,
    },
    /// Tetrahedral multigrid levels of a closed surface (OBJ, STL, PLY) by isosurface
    /// stuffing: writes DIR/NAME_L0.msh ... (Gmsh 2.2) and prints each level's quality.
    Levels {
        /// Closed triangle surface (.obj, .stl, .ply); checked, orientation repaired.
        surface: PathBuf,
        /// Number of levels.
        #[arg(long, default_value_t = 4)]
        levels: usize,
        /// Node count of each level over the finer one's.
        #[arg(long, default_value_t = 0.5)]
        ratio: f64,
        /// Nodes of level 0 (default 30000 when --size is not given).
        #[arg(long, conflicts_with = "size")]
        nodes: Option<usize>,
        /// Lattice spacing of level 0 (m, after --scale) instead of --nodes.
        #[arg(long)]
        size: Option<f64>,
        /// Multiply the surface's coordinates by S first (0.001 for millimetres).
        #[arg(long, default_value_t = 1.0)]
        scale: f64,
        /// Output directory.
        #[arg(long, short)]
        out: PathBuf,
        /// Base name of the files: 1 to 100 ASCII letters, digits, `-`, `_`, `.`, not starting
        /// with `.` (default: the surface's file stem without `_surface`, other characters
        /// replaced by `_`).
        #[arg(long)]
        name: Option<String>,
        /// No progress bar.
        #[arg(long, short)]
        quiet: bool,
    },
}

fn main() {
    let cli = Cli::parse();
    // Commands run on pool workers ([`on_pool`]): give them the main thread's stack size.
    // (An error means the pool exists already; the default one is then used.)
    let _ = rayon::ThreadPoolBuilder::new()
        .stack_size(8 << 20)
        .build_global();
    match real_main(cli) {
        Ok(code) => std::process::exit(code),
        Err(e) => {
            eprintln!("error: {}", message_of(&e));
            std::process::exit(exit_code_of(&e));
        }
    }
}

/// The error and its causes, joined by ": " as `{:#}` joins them, a cause left out where the
/// message before it already ends with it (an I/O error names its OS error in its own text).
fn message_of(e: &anyhow::Error) -> String {
    let mut out = String::new();
    for c in e.chain() {
        let text = c.to_string();
        if out.is_empty() {
            out = text;
        } else if !out.ends_with(&text) {
            out.push_str(": ");
            out.push_str(&text);
        }
    }
    out
}

/// A command-line argument, or an input a command checks itself, that is not valid: exit
/// status 2, like [`BadInput`].
#[derive(Debug)]
struct BadArgs(String);

impl std::fmt::Display for BadArgs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for BadArgs {}

/// Return a [`BadArgs`] error with a formatted message (exit status 2).
macro_rules! bad_args {
    ($($arg:tt)*) => {
        return Err(BadArgs(format!($($arg)*)).into())
    };
}

// After `bad_args!`, which it uses.
mod bench;

/// A failure to read the input (the scenario or its files): exit status 2.
#[derive(Debug)]
struct BadInput(raisov::Error);

impl std::fmt::Display for BadInput {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.0.fmt(f)
    }
}

impl std::error::Error for BadInput {}

/// The exit status of an error (see [`EXIT_BAD_INPUT`] and the others).
fn exit_code_of(e: &anyhow::Error) -> i32 {
    use raisov::Error as E;
    for c in e.chain() {
        if c.is::<BadInput>() || c.is::<BadArgs>() {
            return EXIT_BAD_INPUT;
        }
        if let Some(r) = c.downcast_ref::<E>() {
            return match r {
                E::Scenario { .. }
                | E::MeshFormat { .. }
                | E::BadMesh { .. }
                | E::BadSurface { .. }
                | E::Param { .. } => EXIT_BAD_INPUT,
                E::Io { .. } | E::Diverged(_) => EXIT_FAILED,
            };
        }
    }
    EXIT_FAILED
}

/// A flag raised by the first SIGINT or SIGTERM; a second one exits at once with status 130.
fn stop_flag() -> Result<std::sync::Arc<std::sync::atomic::AtomicBool>> {
    let flag = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    #[cfg(unix)]
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register_conditional_shutdown(sig, EXIT_INTERRUPTED, flag.clone())
            .context("installing the signal handler")?;
        signal_hook::flag::register(sig, flag.clone()).context("installing the signal handler")?;
    }
    Ok(flag)
}

/// Run `f` on a worker thread of rayon's global pool. Every force pass of a simulation is a
/// parallel loop; started from the main thread, each one hands its work to the pool and
/// sleeps until it is done (a futex wake-up and a context switch per force evaluation), which
/// cost the liver's FAS run (about 60 evaluations of 2-17k nodes per cycle) 17 % of its wall
/// time. From a worker the loops start at once. `raisov bench` times on its own pools.
fn on_pool<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    rayon::scope(|_| f())
}

fn real_main(cli: Cli) -> Result<i32> {
    let ok = |r: Result<()>| r.map(|()| 0);
    match cli.cmd {
        Cmd::Serve {
            target,
            port,
            host,
            token,
            open,
            cycles,
            budget_ms,
            max_fps,
            method,
            record,
            scale,
            nodes,
            grab_stiffness,
        } => {
            // Whatever stops the viewer before it serves is its input: exit status 2.
            raisov_serve::run(&raisov_serve::ServeArgs {
                target,
                host,
                token,
                port,
                open,
                cycles,
                budget_ms,
                max_fps,
                method,
                record,
                scale,
                nodes,
                grab_stiffness,
            })
            .map_err(|e| BadArgs(e.to_string()))?;
            Ok(0)
        }
        Cmd::Run {
            scenario,
            out,
            quiet,
            ascii_vtu,
        } => on_pool(|| cmd_run(scenario, out, quiet, ascii_vtu)),
        Cmd::Check { scenario } => ok(cmd_check(&scenario)),
        Cmd::Bench {
            suite: Some(BenchSuite::Api),
            quick,
            ..
        } => on_pool(|| {
            let (div, frames) = if quick { (6, 10) } else { (16, 40) };
            raisov_lab::bench::api(div, frames, &mut |line| println!("{line}"))?;
            Ok(0)
        }),
        Cmd::Bench {
            suite: Some(BenchSuite::Equilibrium),
            quick,
            meshes,
            case,
            ..
        } => on_pool(|| bench::cmd_bench_equilibrium(quick, meshes, case)),
        Cmd::Bench {
            suite: Some(BenchSuite::Implicit),
            quick,
            meshes,
            ..
        } => on_pool(|| {
            let meshes = meshes.unwrap_or_else(|| PathBuf::from("data"));
            raisov_lab::bench::implicit(&meshes, quick, &mut |line| println!("{line}"))
                .map_err(BadInput)
                .with_context(|| format!("the liver meshes from {}", meshes.display()))?;
            Ok(0)
        }),
        Cmd::Bench {
            suite: Some(BenchSuite::Cut),
            quick,
            meshes,
            ..
        } => on_pool(|| bench::cmd_bench_cut(quick, meshes)),
        Cmd::Bench {
            suite: Some(BenchSuite::Frames),
            quick,
            meshes,
            case,
            organ,
            cycles,
            ..
        } => on_pool(|| bench::cmd_bench_frames(quick, meshes, case, &organ, cycles)),
        Cmd::Bench {
            suite: Some(BenchSuite::SurfaceCheck),
            quick,
            meshes,
            case,
            write_mesh,
            ..
        } => ok(bench::cmd_bench_surface_check(
            quick, meshes, case, write_mesh,
        )),
        Cmd::Bench {
            suite: None,
            sizes,
            threads,
            quick,
            out,
            write_mesh,
            check,
            standard_only,
            precision,
            meshes: _,
            case: _,
            organ: _,
            cycles: _,
        } => ok(bench::cmd_bench(
            &sizes,
            threads,
            quick,
            out,
            write_mesh,
            check,
            standard_only,
            &precision,
        )),
        Cmd::Paper {
            out,
            quick,
            meshes,
            quiet,
            slim_cap,
            equilibrium,
        } => ok(on_pool(|| {
            cmd_paper(&PaperArgs {
                out,
                quick,
                meshes,
                quiet,
                slim_cap,
                equilibrium,
            })
        })),
        Cmd::Mesh {
            cmd: MeshCmd::Info { file },
        } => ok(cmd_mesh_info(&file)),
        Cmd::Mesh {
            cmd:
                MeshCmd::Generate {
                    kind,
                    out,
                    nodes,
                    size,
                    polygon,
                    divisions,
                    pattern,
                },
        } => ok(cmd_generate(
            &kind, &out, nodes, &size, &polygon, &divisions, pattern,
        )),
        Cmd::Mesh {
            cmd:
                MeshCmd::Levels {
                    surface,
                    levels,
                    ratio,
                    nodes,
                    size,
                    scale,
                    out,
                    name,
                    quiet,
                },
        } => ok(on_pool(|| {
            cmd_mesh_levels(&LevelsArgs {
                surface,
                levels,
                ratio,
                nodes,
                size,
                scale,
                out,
                name,
                quiet,
            })
        })),
    }
}

/// The scenario at `path` (or the built-in one), its output directory `out` where given
/// (generated surface levels are cached under it).
fn load_scenario(path: Option<&Path>, out: Option<&Path>) -> Result<Scenario> {
    let sc = match path {
        Some(p) => Scenario::load_with_out(p, out),
        None => {
            let name = Path::new("examples/membrane_lift_multigrid.toml (built-in)");
            raisov::scenario::spec::parse(BUILTIN, name)
                .and_then(|spec| Scenario::resolve_with_out(spec, name, out))
        }
    };
    sc.map_err(|e| BadInput(e).into())
}

fn cmd_run(
    scenario: Option<PathBuf>,
    out: Option<PathBuf>,
    quiet: bool,
    ascii_vtu: bool,
) -> Result<i32> {
    let stop = stop_flag()?;
    let mut sc = load_scenario(scenario.as_deref(), out.as_deref())?;
    if ascii_vtu {
        sc.output.vtu = raisov::io::VtuFormat::Ascii;
    }
    for n in &sc.notes {
        eprintln!("note: {n}");
    }
    for w in &sc.warnings {
        eprintln!("warning: {w}");
    }
    let show = !quiet && std::io::stderr().is_terminal();
    let bar = if show {
        ProgressBar::new(1000)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:40} {percent:>3}% {msg}")
            .expect("valid template"),
    );
    if sc.integrator.statics.is_some() {
        eprintln!(
            "solving {} for static equilibrium ({} nodes, {} elements, newton)",
            sc.name,
            sc.mesh.num_nodes(),
            sc.mesh.num_elements()
        );
    } else {
        eprintln!(
            "running {} ({} nodes, {} elements, {}, dt = {:.3e} s)",
            sc.name,
            sc.mesh.num_nodes(),
            sc.mesh.num_elements(),
            sc.method_name(),
            sc.integrator.dt
        );
    }
    let mut progress = |f: f64, s: &raisov::metrics::Sample| {
        bar.set_position((f * 1000.0) as u64);
        bar.set_message(format!(
            "t = {:.4} s  KE = {:.2e} J  |r| = {:.2e} N",
            s.time, s.kinetic, s.residual
        ));
    };
    if sc.integrator.statics.is_some() {
        let opts = RunOptions {
            out_dir: out,
            ..Default::default()
        };
        let s = raisov::runner::solve(&sc, opts)
            .with_context(|| format!("static solve of {} stopped", sc.name))?;
        println!("{}", s.finished);
        if !s.finished.success() {
            eprintln!("raisov: {}: the static solve did not converge", sc.name);
            return Ok(EXIT_NOT_CONVERGED);
        }
        return Ok(0);
    }
    let stepper = sc
        .stepper()
        .map_err(BadInput)
        .with_context(|| format!("{}: building the simulation", sc.path.display()))?;
    eprint!("{}", stepper.report());
    let opts = RunOptions {
        out_dir: out,
        progress: Some(&mut progress),
        stop: Some(&stop),
        ..Default::default()
    };
    // An [interactive] scenario plays its paths frame by frame (its grasps and pins taken
    // during the run included); any other runs in time.
    let res = raisov::runner::solve_with(&sc, stepper, opts).map(|s| {
        use raisov::runner::Finished;
        use raisov::runner::StopReason as R;
        let code = match &s.finished {
            Finished::Interactive(i) if i.interrupted => EXIT_INTERRUPTED,
            Finished::Dynamic(d) => match d.reason {
                R::Duration | R::Steady => 0,
                R::NotSteadyBeforeCap | R::Stagnated(_) => EXIT_NOT_CONVERGED,
                R::Interrupted => EXIT_INTERRUPTED,
            },
            _ => 0,
        };
        (s.finished.to_string(), code)
    });
    bar.finish_and_clear();
    let (summary, code) = res.with_context(|| format!("run of {} stopped", sc.name))?;
    println!("{summary}");
    match code {
        EXIT_NOT_CONVERGED => eprintln!("raisov: {}: did not reach steady state", sc.name),
        EXIT_INTERRUPTED => eprintln!(
            "raisov: {}: interrupted; what was measured is written",
            sc.name
        ),
        _ => {}
    }
    Ok(code)
}

/// The options of `raisov paper`.
struct PaperArgs {
    out: PathBuf,
    quick: bool,
    meshes: Option<PathBuf>,
    quiet: bool,
    slim_cap: Option<f64>,
    equilibrium: bool,
}

/// Seconds as "40 s", "3 min" or "1 h 5 min" (estimates, rounded).
fn duration_words(s: f64) -> String {
    let m = (s / 60.0).round() as u64;
    if s < 90.0 {
        format!("{:.0} s", s.max(1.0))
    } else if m < 60 {
        format!("{m} min")
    } else {
        format!("{} h {} min", m / 60, m % 60)
    }
}

fn cmd_paper(a: &PaperArgs) -> Result<()> {
    use raisov_lab::paper::{estimate, run_paper, PaperOptions, Progress};
    let PaperArgs {
        out,
        quick,
        meshes,
        quiet,
        slim_cap,
        equilibrium,
    } = a;
    let (quick, quiet, slim_cap) = (*quick, *quiet, *slim_cap);
    if let Some(c) = slim_cap {
        if !(c.is_finite() && c > 0.0) {
            bad_args!("--slim-cap {c}: give a positive number of seconds");
        }
    }
    let meshes = meshes.clone().unwrap_or_else(|| PathBuf::from("data"));
    let opts = PaperOptions {
        out_dir: out.clone(),
        quick,
        tiny: false,
        meshes_dir: Some(meshes),
        slim_cap,
        equilibrium: *equilibrium,
    };
    let show = !quiet && std::io::stderr().is_terminal();
    let bar = if show {
        ProgressBar::new(1)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} runs  {wide_msg}",
        )
        .expect("valid template"),
    );
    eprintln!(
        "raisov paper: {} run into {}",
        if quick { "quick" } else { "full" },
        out.display()
    );
    // Section lines go above the bar on a terminal, else straight to stderr.
    let say = |line: String| {
        if show {
            bar.println(line);
        } else if !quiet {
            eprintln!("{line}");
        }
    };
    let res = run_paper(&opts, &mut |p| match p {
        Progress::Planned(n) => bar.set_length(n),
        Progress::Plan(sections) => {
            let total: f64 = sections.iter().map(|(_, t)| t).sum();
            eprintln!(
                "estimated {} on a 2-core machine (more on a busy one): {}",
                duration_words(total),
                sections
                    .iter()
                    .enumerate()
                    .map(|(i, (n, t))| format!("{} {n} {}", i + 1, duration_words(*t)))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
            if !opts.equilibrium {
                let every = PaperOptions {
                    equilibrium: true,
                    ..opts.clone()
                };
                eprintln!(
                    "section 7 runs the quick cases of the five-solver race; --equilibrium runs \
                     every case (about {} more)",
                    duration_words(estimate(&every)[6].1 - estimate(&opts)[6].1)
                );
            }
        }
        Progress::Section { index, of, name } => {
            let est = estimate(&opts)[index - 1].1;
            say(format!(
                "[{index}/{of}] {name} (about {}) ...",
                duration_words(est)
            ));
        }
        Progress::SectionDone {
            index,
            of,
            name,
            wall,
        } => say(format!("[{index}/{of}] {name}: done in {wall:.0} s")),
        Progress::Done(what) => {
            if !show && !quiet {
                eprintln!("[{:>4}] {what}", bar.position() + 1);
            }
            if bar.position() + 1 >= bar.length().unwrap_or(0) {
                bar.set_length(bar.position() + 2);
            }
            bar.inc(1);
            bar.set_message(what.to_string());
        }
    });
    bar.finish_and_clear();
    let res = res.context("raisov paper stopped")?;
    for n in &res.notes {
        eprintln!("note: {n}");
    }
    println!(
        "wrote {} files under {} in {:.1} s; see {}",
        res.files.len(),
        out.display(),
        res.wall,
        out.join("report.md").display()
    );
    Ok(())
}

fn cmd_check(path: &Path) -> Result<()> {
    use std::fmt::Write as _;
    let sc = Scenario::load(path).map_err(BadInput)?;
    let sys = sc.build_system().map_err(BadInput)?;
    // The report is written whole at the end (a closed pipe ends it quietly).
    let mut out = String::new();
    let mut line = |label: &str, text: &str| {
        let _ = writeln!(out, "{label:<13} {text}");
    };
    line("scenario", &format!("{} ({})", sc.name, path.display()));
    for n in &sc.notes {
        line("note", n);
    }
    for w in &sc.warnings {
        line("warning", w);
    }
    line(
        "mesh",
        &format!(
            "{} nodes, {} {} elements",
            sc.mesh.num_nodes(),
            sc.mesh.num_elements(),
            sc.mesh.kind.name()
        ),
    );
    line(
        "material",
        &check::material_with(&sc.material, sc.fibres.as_ref()),
    );
    line(
        "density",
        &format!(
            "{} kg/m^3, total mass {:.4e} kg",
            sc.density,
            sys.mass.iter().sum::<f64>()
        ),
    );
    line(
        "damping",
        &if sc.alpha == 0.0 {
            "none".to_string()
        } else {
            format!("alpha = {} 1/s (D = alpha M)", sc.alpha)
        },
    );
    line("gravity", &check::vector_or_none(sc.gravity, "m/s^2"));
    line("fixed nodes", &sc.fixed.len().to_string());
    line("loads", &format!("{} nodes", sc.loads.len()));
    for (a, m) in &sc.prescribed {
        line(
            "prescribed",
            &format!(
                "node {} at {} m: {}",
                sc.file_node(*a),
                raisov::numbers::point(sc.mesh.nodes[*a as usize]),
                check::motion(m)
            ),
        );
    }
    // (Six significant digits, as points are shown.)
    let compact = |x: f64| raisov::numbers::compact(format!("{x:.5e}").parse().unwrap_or(x));
    for g in &sc.grasps {
        let held = match g.stiffness {
            Some(k) => format!("pulled by springs of {} N/m", compact(k)),
            None => "held hard".into(),
        };
        let until = g.release.map_or("to the end".into(), |r| {
            format!("let go at {} s", compact(r))
        });
        line(
            "grasp",
            &format!(
                "near {} m, radius {} m, taken at {} s, {held}, {until}; grasp point {}",
                raisov::numbers::point(g.point),
                compact(g.radius),
                compact(g.start),
                check::motion(&g.motion)
            ),
        );
    }
    for p in &sc.pins {
        line(
            "pin",
            &format!(
                "near {} m, radius {} m, taken at {} s",
                raisov::numbers::point(p.point),
                compact(p.radius),
                compact(p.start)
            ),
        );
    }
    for c in &sc.cuts {
        let [a, b, q, d] = c.blade.corners;
        line(
            "cut",
            &format!(
                "at {} s, the blade {} {} {} {} m",
                compact(c.time),
                raisov::numbers::point(a),
                raisov::numbers::point(b),
                raisov::numbers::point(q),
                raisov::numbers::point(d)
            ),
        );
    }
    if sc.integrator.statics.is_some() {
        // A static solve: no time stepping, no stop rule, no FAS stepper.
        let how = raisov::runner::describe_static(&sc).map_err(BadInput)?;
        line("integrator", &how);
    } else {
        let integrator = match &sc.integrator.implicit {
            Some(imp) => format!(
                "{}, dt = {:.4e} s ({} explicit critical steps), Newton to newton_tol = {:e} in at most {} iterations a step, solver \"{}\", precision {}{}",
                imp.scheme.name(),
                sc.integrator.dt,
                raisov::numbers::rounded(sc.integrator.dt / sc.integrator.dt_critical_estimate, 1),
                imp.rel_tol,
                imp.max_newton,
                raisov::scenario::spec::Named::name(imp.solver),
                sc.precision.name(),
                if imp.beta > 0.0 {
                    format!(", stiffness damping beta = {:e} s (K frozen at each step's start)", imp.beta)
                } else {
                    String::new()
                }
            ),
            None => format!(
                "{}, dt = {:.4e} s (estimated critical {:.4e} s), precision {}",
                sc.integrator.method.name(),
                sc.integrator.dt,
                sc.integrator.dt_critical_estimate,
                sc.precision.name()
            ),
        };
        line("integrator", &integrator);
        line("stop", &check::stop(&sc.run.stop));
        if let Some(i) = &sc.interactive {
            line("interactive", &check::interactive(i));
        }
        let stepper = sc
            .stepper()
            .map_err(BadInput)
            .with_context(|| format!("{}: building the simulation", sc.path.display()))?;
        line("stepping", &stepper.describe());
        out += &stepper.report();
    }
    let _ = writeln!(out, "{:<13} {}", "output", sc.output.dir.display());
    out += "ok\n";
    write_stdout(&out)
}

/// Write `text` to standard output; a reader that closed the pipe (`raisov check | head`)
/// ends the output quietly.
fn write_stdout(text: &str) -> Result<()> {
    use std::io::Write as _;
    let mut stdout = std::io::stdout().lock();
    match stdout
        .write_all(text.as_bytes())
        .and_then(|()| stdout.flush())
    {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        r => Ok(r.context("writing to standard output")?),
    }
}

fn cmd_mesh_info(file: &Path) -> Result<()> {
    if raisov::io::is_surface_path(file) {
        return cmd_surface_info(file);
    }
    let loaded = load_mesh(file).map_err(BadInput)?;
    let s = loaded.mesh.stats();
    let unit = if s.kind == raisov::mesh::ElementKind::Tri3 {
        "area"
    } else {
        "volume"
    };
    println!("file            {} ({})", file.display(), loaded.format);
    println!("elements        {} {}", s.elements, s.kind.name());
    println!(
        "nodes           {} ({} on the boundary)",
        s.nodes, s.boundary_nodes
    );
    println!("{unit:<15} {:.6e}", s.measure);
    println!("bounding box    {:?} .. {:?}", s.bbox_min, s.bbox_max);
    println!("edge length     {:.4e} .. {:.4e}", s.min_edge, s.max_edge);
    println!(
        "quality         min {:.3}, mean {:.3} (1 = equilateral/regular)",
        s.quality_min, s.quality_mean
    );
    println!("reoriented      {}", loaded.reoriented.len());
    println!("unused nodes    {} dropped", loaded.unused_nodes_dropped);
    println!("inverted        {}", s.inverted.len());
    println!("degenerate      {}", s.degenerate.len());
    for (g, n) in &s.groups {
        println!("group           \"{g}\": {n} nodes");
    }
    Ok(())
}

/// Surfaces of more triangles than this show a progress bar while they are checked.
const SURFACE_PROGRESS_TRIANGLES: usize = 50_000;

/// [`raisov::mesh::check_surface`], with a progress bar on stderr for surfaces of more than
/// [`SURFACE_PROGRESS_TRIANGLES`] triangles (unless `quiet` or stderr is not a terminal).
fn check_surface_shown(
    s: &mut raisov::mesh::Surface,
    quiet: bool,
) -> raisov::Result<raisov::mesh::SurfaceReport> {
    let bar = if quiet
        || s.triangles.len() <= SURFACE_PROGRESS_TRIANGLES
        || !std::io::stderr().is_terminal()
    {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(1)
    };
    bar.set_style(
        ProgressStyle::with_template("checking the surface {bar:30} {percent}% [{elapsed}]")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let r = raisov::mesh::check_surface_with_progress(s, &mut |done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    });
    bar.finish_and_clear();
    r
}

/// `mesh info` for a triangle surface (.obj, .stl, .ply): counts, the checks, the repair.
fn cmd_surface_info(file: &Path) -> Result<()> {
    let mut s = raisov::io::load_surface(file).map_err(BadInput)?;
    println!("file            {} (triangle surface)", file.display());
    println!("vertices        {}", s.points.len());
    println!("triangles       {}", s.triangles.len());
    let r = match check_surface_shown(&mut s, false) {
        Ok(r) => r,
        Err(e) => {
            println!("closed/manifold no");
            bad_args!("{}: {e}", file.display())
        }
    };
    println!(
        "closed/manifold yes (no degenerate triangle, no self-intersection, {} unused vertices)",
        r.unused_vertices
    );
    println!("components      {}", r.components.len());
    for (i, c) in r.components.iter().enumerate() {
        let kind = match (c.is_cavity(), c.inside) {
            (true, Some(k)) => format!("cavity inside component {k}"),
            (false, Some(k)) => format!("solid inside the cavity of component {k}"),
            _ => "outer boundary".into(),
        };
        println!(
            "  component {i}   {} triangles, {} vertices, volume {:.6e}, {kind}",
            c.triangles, c.vertices, c.volume
        );
    }
    println!("enclosed volume {:.6e}", r.enclosed_volume);
    println!("bounding box    {:?} .. {:?}", r.bbox_min, r.bbox_max);
    println!("flipped         {} triangles reoriented", r.flipped);
    if raisov::mesh::looks_like_millimetres((r.bbox_min, r.bbox_max), 1.0) {
        println!(
            "note            spans more than {} units: if these are millimetres, scale by 1e-3 \
             for metres",
            raisov::mesh::surface_check::MAX_ORGAN_EXTENT_M
        );
    }
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn cmd_generate(
    kind: &str,
    out: &Path,
    nodes: Option<usize>,
    size: &[f64],
    polygon: &[f64],
    divisions: &[usize],
    pattern: u32,
) -> Result<()> {
    let mesh: Mesh = match kind {
        "rectangle" => {
            let [w, h] = size[..] else {
                bad_args!("rectangle needs --size W,H (m)")
            };
            rectangle_membrane(
                w,
                h,
                nodes.ok_or_else(|| BadArgs("rectangle needs --nodes N".into()))?,
            )?
        }
        "polygon" => {
            if polygon.len() < 6 || !polygon.len().is_multiple_of(2) {
                bad_args!(
                    "polygon needs --polygon x1,y1,x2,y2,x3,y3[,...] (at least 3 vertices, m)"
                );
            }
            let pts: Vec<[f64; 2]> = polygon.chunks(2).map(|c| [c[0], c[1]]).collect();
            polygon_membrane(
                &pts,
                nodes.ok_or_else(|| BadArgs("polygon needs --nodes N".into()))?,
            )?
        }
        "box" => {
            let [x, y, z] = size[..] else {
                bad_args!("box needs --size X,Y,Z (m)")
            };
            let Some(pat) = box_pattern(pattern) else {
                bad_args!("--pattern {pattern}: valid are 5 or 6")
            };
            match (nodes, divisions) {
                (Some(n), []) => box_tets_target([x, y, z], n, pat)?,
                (None, &[a, b, c]) => box_tets([x, y, z], [a, b, c], pat)?,
                _ => bad_args!("box needs exactly one of --nodes N or --divisions NX,NY,NZ"),
            }
        }
        other => bad_args!("unknown mesh kind `{other}`: valid are rectangle, polygon, box"),
    };
    match out.extension().and_then(|e| e.to_str()) {
        Some("msh") => write_msh22(out, &mesh)?,
        Some("vtu") => write_vtu(out, &mesh, &mesh.nodes, &[], &[])?,
        _ => bad_args!(
            "{}: output must end in .msh (Gmsh 2.2) or .vtu (ParaView)",
            out.display()
        ),
    }
    let s = mesh.stats();
    println!(
        "wrote {}: {} nodes, {} {} elements, quality min {:.3} mean {:.3}",
        out.display(),
        s.nodes,
        s.elements,
        s.kind.name(),
        s.quality_min,
        s.quality_mean
    );
    Ok(())
}

/// Arguments of `raisov mesh levels`.
struct LevelsArgs {
    surface: PathBuf,
    levels: usize,
    ratio: f64,
    nodes: Option<usize>,
    size: Option<f64>,
    scale: f64,
    out: PathBuf,
    name: Option<String>,
    quiet: bool,
}

fn cmd_mesh_levels(a: &LevelsArgs) -> Result<()> {
    use raisov::mesh::stuffing::{mesh_levels_report, LevelTarget};
    let t0 = std::time::Instant::now();
    if !(a.scale > 0.0 && a.scale.is_finite()) {
        bad_args!("--scale {}: must be positive", a.scale);
    }
    // Checked before the (long) meshing: the files are OUT/NAME_L0.msh, ...
    let name = match &a.name {
        Some(n) => match raisov::io::check_name(n) {
            Ok(()) => n.clone(),
            Err(e) => bad_args!("--name: {e} (it names the files NAME_L0.msh, ... under --out)"),
        },
        None => {
            let stem = a
                .surface
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            let stem = stem.strip_suffix("_surface").unwrap_or(&stem);
            raisov::io::name_from_stem(stem, "surface")
        }
    };
    let mut surface = raisov::io::load_surface(&a.surface).map_err(BadInput)?;
    surface.scale(a.scale);
    let check = check_surface_shown(&mut surface, a.quiet)
        .with_context(|| format!("{}: not a closed surface to mesh", a.surface.display()))?;
    let diag = raisov::mesh::norm(raisov::mesh::sub(check.bbox_max, check.bbox_min));
    println!(
        "surface {}: {} points, {} triangles, {} component(s), bounding box diagonal {:.4e} m, \
         enclosed volume {:.4e} m^3",
        a.surface.display(),
        surface.points.len(),
        surface.triangles.len(),
        check.components.len(),
        diag,
        check.enclosed_volume
    );
    if check.flipped > 0 {
        eprintln!(
            "note: reoriented {} triangles so that the normals point out of the solid",
            check.flipped
        );
    }
    if raisov::mesh::looks_like_millimetres((check.bbox_min, check.bbox_max), 1.0) {
        eprintln!(
            "warning: the surface spans more than {} m after --scale {}; if its coordinates \
             are millimetres, pass --scale 0.001",
            raisov::mesh::surface_check::MAX_ORGAN_EXTENT_M,
            raisov::numbers::compact(a.scale)
        );
    }
    let target = match (a.nodes, a.size) {
        (Some(n), None) => LevelTarget::Nodes(n),
        (None, Some(h)) => LevelTarget::Size(h),
        (None, None) => LevelTarget::Nodes(30_000),
        (Some(_), Some(_)) => bad_args!("give --nodes or --size, not both"),
    };
    let bar = if a.quiet || !std::io::stderr().is_terminal() {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(a.levels as u64 + 1)
    };
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} {msg} [{elapsed}]")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let mut step = 0u64;
    let (meshes, report) = mesh_levels_report(&surface, a.levels, a.ratio, target, &mut |msg| {
        bar.set_position(step);
        bar.set_message(msg.to_string());
        step += 1;
    })?;
    let t_levels = t0.elapsed().as_secs_f64();
    bar.set_message("links");
    let links = raisov::hierarchy::link_reports(&meshes)?;
    bar.finish_and_clear();
    let t_mesh = t0.elapsed().as_secs_f64();
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    for (i, m) in meshes.iter().enumerate() {
        let f = a.out.join(format!("{name}_L{i}.msh"));
        write_msh22(&f, m)?;
        println!("wrote {}", f.display());
    }
    print!("{report}");
    for (i, l) in links.iter().enumerate() {
        println!("link {i}-{}: {l}", i + 1);
    }
    let bad: Vec<usize> = report
        .levels
        .iter()
        .filter(|r| !r.quality_ok())
        .map(|r| r.level)
        .collect();
    if !bad.is_empty() {
        eprintln!("warning: levels {bad:?} have dihedral angles outside the guaranteed range");
    }
    println!(
        "time: {t_levels:.2} s to read and mesh the {} levels, {t_mesh:.2} s with the links' \
         correspondence, {:.2} s in all with the files ({} threads)",
        a.levels,
        t0.elapsed().as_secs_f64(),
        rayon::current_num_threads(),
    );
    Ok(())
}
