//! `raisov bench` and its suites: each command runs its benchmark of `raisov_lab` and prints
//! its table; `main.rs` parses the arguments and dispatches here.

use crate::{BadArgs, BadInput, EXIT_NOT_CONVERGED};
use anyhow::{Context, Result};
use raisov::io::write_msh22;
use std::path::PathBuf;

/// `raisov bench frames`: the table of `raisov_lab::bench::frames` on stdout, a line per case
/// as it finishes.
pub(crate) fn cmd_bench_frames(
    quick: bool,
    meshes: Option<PathBuf>,
    case: Vec<String>,
    organ: &str,
    cycles: Vec<u32>,
) -> anyhow::Result<i32> {
    use raisov_lab::bench::frames::{self as fr, Grasp, Law, Organ, Solver};
    let meshes = meshes.unwrap_or_else(|| PathBuf::from("data"));
    let mut opts = fr::FramesOptions::new(Organ::parse(organ).map_err(BadInput)?, quick);
    let words: Vec<String> = case.iter().map(|w| w.trim().to_lowercase()).collect();
    for w in &words {
        if ![
            "nh",
            "snh",
            "rigid",
            "springs",
            "node",
            "slow",
            "fast",
            "fas",
            "newton",
            "rapier",
            "rapier-sweep",
        ]
        .contains(&w.as_str())
        {
            return Err(BadInput(raisov::Error::param(
                "--case",
                format!(
                    "`{w}`: valid words are NH, SNH, rigid, springs, node, slow, fast, fas, newton, \
                     rapier, rapier-sweep"
                ),
            ))
            .into());
        }
    }
    let has = |w: &str| words.iter().any(|x| x == w);
    let laws: Vec<Law> = [("nh", Law::NeoHookean), ("snh", Law::StableNeoHookean)]
        .into_iter()
        .filter(|(w, _)| has(w))
        .map(|(_, l)| l)
        .collect();
    if !laws.is_empty() {
        opts.laws = laws;
    }
    let grasps: Vec<Grasp> = [
        ("rigid", Grasp::Rigid),
        ("springs", Grasp::Springs),
        ("node", Grasp::Node),
    ]
    .into_iter()
    .filter(|(w, _)| has(w))
    .map(|(_, g)| g)
    .collect();
    if !grasps.is_empty() {
        opts.grasps = grasps;
    }
    let paces: Vec<bool> = [("slow", false), ("fast", true)]
        .into_iter()
        .filter(|(w, _)| has(w))
        .map(|(_, p)| p)
        .collect();
    if !paces.is_empty() {
        opts.paces = paces;
    }
    if !cycles.is_empty() {
        opts.cycles = cycles;
    }
    // `rapier-sweep`: rapier's row by the sweep of the rule that chose its settings.
    opts.rapier_sweep = has("rapier-sweep");
    let solvers: Vec<Solver> = [
        ("fas", Solver::Fas),
        ("newton", Solver::Newton),
        ("rapier", Solver::Rapier),
    ]
    .into_iter()
    .filter(|(w, _)| has(w) || (*w == "rapier" && opts.rapier_sweep))
    .map(|(_, s)| s)
    .collect();
    if !solvers.is_empty() {
        opts.solvers = solvers;
    }
    fr::check(&opts).map_err(BadInput)?;
    fr::frames(&meshes, &opts, &mut |line| println!("{line}"))
        .map_err(BadInput)
        .with_context(|| {
            format!(
                "raisov bench frames (organ meshes from {})",
                meshes.display()
            )
        })?;
    Ok(0)
}

/// `raisov bench equilibrium`: the table of `raisov_lab::equilibrium` on stdout, progress
/// on stderr; exit status 3 if a solver missed the stopping rule or an equilibrium disagrees.
pub(crate) fn cmd_bench_surface_check(
    quick: bool,
    meshes: Option<PathBuf>,
    only: Vec<String>,
    write_mesh: Option<PathBuf>,
) -> Result<()> {
    use raisov_lab::bench::surface_check as sc;
    if let Some(dir) = write_mesh {
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        for (_, segments, axis) in sc::cones(quick) {
            let s = raisov::mesh::generate::cone_surface(segments, 0.05, 0.1, axis)?;
            let tilt = if axis == [0.0, 0.0, 1.0] { "_z" } else { "" };
            let f = dir.join(format!("cone_{}{tilt}.obj", s.triangles.len()));
            sc::write_obj(&f, &s)?;
            println!("wrote {}", f.display());
        }
        return Ok(());
    }
    let meshes = meshes.unwrap_or_else(|| PathBuf::from("data"));
    let mut cases = sc::surface_cases(&meshes, quick, &mut |l| eprintln!("{l}"))
        .map_err(BadInput)
        .with_context(|| format!("loading the cases (surfaces from {})", meshes.display()))?;
    if !only.is_empty() {
        let names: Vec<String> = cases.iter().map(|c| c.name.clone()).collect();
        if let Some(bad) = only.iter().find(|o| !names.contains(o)) {
            bad_args!("--case {bad:?}: no such case; valid: {}", names.join(", "));
        }
        cases.retain(|c| only.contains(&c.name));
    }
    println!(
        "raisov bench surface-check{}: {} thread(s)",
        if quick { " --quick" } else { "" },
        rayon::current_num_threads()
    );
    let rows = sc::surface_check(&cases, &mut |l| eprintln!("{l}"))?;
    println!("{}", sc::to_markdown(&rows));
    Ok(())
}

pub(crate) fn cmd_bench_equilibrium(
    quick: bool,
    meshes: Option<PathBuf>,
    only: Vec<String>,
) -> Result<i32> {
    use raisov_lab::equilibrium;
    let meshes = meshes.unwrap_or_else(|| PathBuf::from("data"));
    let mut cases = equilibrium::cases(&meshes, quick)
        .map_err(BadInput)
        .with_context(|| format!("loading the cases (meshes from {})", meshes.display()))?;
    if !only.is_empty() {
        let mut names: Vec<String> = cases.iter().map(|c| c.name.clone()).collect();
        if !quick {
            names.extend(equilibrium::MESHER_CASES.iter().map(|(n, _)| n.to_string()));
        }
        if let Some(bad) = only.iter().find(|o| !names.contains(o)) {
            return Err(BadInput(raisov::Error::param(
                "--case",
                format!("no case named {bad:?}; valid: {}", names.join(", ")),
            ))
            .into());
        }
        cases.retain(|c| only.contains(&c.name));
        for (name, nodes) in equilibrium::MESHER_CASES {
            if !quick && only.iter().any(|o| o == name) {
                eprintln!("{name}: meshing liver_surface.obj ...");
                cases.push(
                    equilibrium::mesher_case(&meshes, name, nodes)
                        .map_err(BadInput)
                        .with_context(|| format!("meshing the case {name:?}"))?,
                );
            }
        }
    }
    println!(
        "raisov bench equilibrium{}: {} thread(s)",
        if quick { " --quick" } else { "" },
        rayon::current_num_threads()
    );
    let rows = equilibrium::run(&cases, &mut |line| eprintln!("{line}"))?;
    println!("{}", equilibrium::to_markdown(&rows));
    println!("{}", equilibrium::summary_markdown(&rows));
    println!("{}", equilibrium::goal_markdown(&rows));
    let mut frames = Vec::new();
    for c in cases.iter().filter(|c| c.scenario.prescribed.is_empty()) {
        eprintln!("{}: FAS frames ...", c.name);
        frames.extend(equilibrium::frame_budgets(c, &[1, 4])?);
        eprintln!("{}: Newton-multigrid frames ...", c.name);
        frames.extend(equilibrium::newton_frame_budgets(c, &[1, 2])?);
    }
    println!("{}", equilibrium::frames_to_markdown(&frames));
    if equilibrium::all_ok(&rows) {
        Ok(0)
    } else {
        eprintln!("warning: a solver missed the stopping rule or its equilibrium disagrees with direct Newton's (see the table)");
        Ok(EXIT_NOT_CONVERGED)
    }
}

#[allow(clippy::too_many_arguments)]
pub(crate) fn cmd_bench(
    sizes: &str,
    threads: Vec<usize>,
    quick: bool,
    out: Option<PathBuf>,
    write_mesh: Option<PathBuf>,
    check: Option<usize>,
    standard_only: bool,
    precision: &str,
) -> Result<()> {
    use raisov_lab::bench;
    let precisions = bench::parse_precisions(precision).context("--precision")?;
    let sizes = if quick && sizes == "1k,10k,100k,1M" {
        vec![1000, 10_000]
    } else {
        bench::parse_sizes(sizes)?
    };
    if threads.is_empty() || threads.contains(&0) {
        bad_args!("--threads: give positive thread counts, e.g. 1,2");
    }
    if let Some(dir) = write_mesh {
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        for &n in &sizes {
            let mesh = bench::standard_box(n)?;
            let f = dir.join(format!("box_{}.msh", bench::size_label(n)));
            write_msh22(&f, &mesh)?;
            println!(
                "wrote {}: {} nodes, {} tets",
                f.display(),
                mesh.num_nodes(),
                mesh.num_elements()
            );
        }
        return Ok(());
    }
    if let Some(steps) = check {
        for &n in &sizes {
            for &p in &precisions {
                let c = bench::check(n, steps, p)?;
                print_check(n, &c);
            }
        }
        return Ok(());
    }
    if let Some(o) = &out {
        match o.extension().and_then(|e| e.to_str()) {
            Some("csv" | "md") => {}
            _ => bad_args!("{}: --out must end in .csv or .md", o.display()),
        }
    }
    eprintln!(
        "raisov bench: sizes {:?}, threads {:?}, precision {}{}",
        sizes,
        threads,
        precisions
            .iter()
            .map(|p| p.name())
            .collect::<Vec<_>>()
            .join(","),
        if quick { ", quick" } else { "" }
    );
    let rows = bench::run(
        &bench::BenchOptions {
            sizes: sizes.clone(),
            threads,
            quick,
            standard_only,
            precisions: precisions.clone(),
        },
        &mut |r| {
            eprintln!(
                "  {} | {} nodes | {} threads | {} | {}",
                r.case,
                r.nodes,
                r.threads,
                r.precision,
                r.node_updates_per_s
                    .map(|x| format!("{:.2}M node-updates/s", x / 1e6))
                    .or(r.value.map(|v| format!("{v:.4} {}", r.unit)))
                    .unwrap_or_default()
            )
        },
    )?;
    println!("{}", bench::to_text(&rows));
    let goals = bench::goals(&rows);
    if !goals.is_empty() {
        println!("Goals judged from this run (5x the best peer: bash bench/peers/run.sh):");
        for line in goals {
            println!("  {line}");
        }
        println!();
    }
    let steps = if quick { 50 } else { 500 };
    for &n in sizes.iter().filter(|&&n| n <= 10_000) {
        for &p in &precisions {
            let c = bench::check(n, steps, p)?;
            print_check(n, &c);
        }
    }
    if let Some(o) = out {
        let text = if o.extension().and_then(|e| e.to_str()) == Some("md") {
            bench::to_markdown(&rows)
        } else {
            bench::to_csv(&rows)
        };
        raisov::io::write_atomic(&o, |w| w.write_all(text.as_bytes()))
            .with_context(|| format!("writing {}", o.display()))?;
        eprintln!("wrote {}", o.display());
    }
    Ok(())
}

/// One line of the standard-work correctness check (the numbers the peers must match).
fn print_check(n: usize, c: &raisov_lab::bench::Check) {
    println!(
        "check size={} nodes={} steps={} precision={} mean_uy_free_end={:.9e} max_abs_u={:.9e}",
        raisov_lab::bench::size_label(n),
        c.nodes,
        c.steps,
        c.precision.name(),
        c.mean_uy_free_end,
        c.max_abs_u
    );
}

/// `raisov bench cut`: the lines of `raisov_lab::bench::cut` on stdout.
pub(crate) fn cmd_bench_cut(quick: bool, meshes: Option<PathBuf>) -> Result<i32> {
    let meshes = meshes.unwrap_or_else(|| PathBuf::from("data"));
    raisov_lab::bench::cut::cut(&meshes, quick, &mut |line| println!("{line}"))
        .map_err(BadInput)
        .with_context(|| format!("the liver meshes from {}", meshes.display()))?;
    Ok(0)
}
