//! The frame solver (`[multigrid] scheme = "newton"`, `raisov::statics::frames`): frames that
//! go on with the grasp held reach the static solver's equilibrium, hard and spring grasps
//! and pins work, and `Budget::Cycles` frames give the same bits on any thread count.

use raisov::runner::{solve, Finished, RunOptions};
use raisov::scenario::Scenario;
use raisov::sim::{Budget, Simulation};

/// A 4 × 2 × 2 cm neo-Hookean block held at x = 0, its tip pulled by `pull` over 0.2 s and
/// held until `duration` (`grasp`: the `[[displace]]`'s extra keys, a spring's stiffness;
/// `None`: no path, grasps taken at run time); the frame solver over `levels` levels,
/// `cycles` Newton steps a frame.
fn block(duration: f64, cycles: usize, grasp: Option<&str>, levels: usize) -> Scenario {
    let displace = match grasp {
        Some(g) => format!(
            r#"[[displace]]
point = [0.04, 0.01, 0.01]
radius = 0.006
start = 0.0
{g}
mode = "table"
table = [[0.0, 0.0, 0.0, 0.0], [0.2, 0.0, 0.004, -0.006], [{duration}, 0.0, 0.004, -0.006]]"#
        ),
        None => String::new(),
    };
    let text = format!(
        r#"
name = "frames"
[mesh]
generate = "box"
size = [0.04, 0.02, 0.02]
divisions = [8, 4, 4]
[material]
law = "neo-hookean"
young = 5000.0
poisson = 0.45
density = 1000.0
[[fix]]
plane = {{ point = [0.0, 0.0, 0.0], normal = [1.0, 0.0, 0.0] }}
{displace}
[run]
duration = {duration}
[multigrid]
scheme = "newton"
levels = {levels}
[interactive]
fps = 30.0
cycles = {cycles}
reference_tol = 1e-12
"#
    );
    Scenario::from_toml(&text, std::path::Path::new("frames.toml")).unwrap()
}

/// A 4 × 2 × 2 cm neo-Hookean block held at x = 0 on two levels, `multigrid` added to its
/// `[multigrid]`, with an `[interactive]` section where `interactive`: scenario text.
fn small_block(multigrid: &str, interactive: bool) -> String {
    format!(
        "[mesh]\ngenerate = \"box\"\nsize = [0.04, 0.02, 0.02]\ndivisions = [4, 2, 2]\n\
         [material]\nlaw = \"neo-hookean\"\nyoung = 5000.0\npoisson = 0.45\n\
         [[fix]]\nplane = {{ point = [0.0, 0.0, 0.0], normal = [1.0, 0.0, 0.0] }}\n\
         [run]\nduration = 0.1\n[multigrid]\nlevels = 2\n{multigrid}\n{}",
        if interactive { "[interactive]\n" } else { "" }
    )
}

/// The largest |x|.
fn max_abs(x: &[f64]) -> f64 {
    x.iter().fold(0.0f64, |m, v| m.max(v.abs()))
}

/// The largest |a − b|.
fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()))
}

fn interactive(sc: &Scenario) -> raisov::runner::InteractiveSummary {
    let solution = solve(
        sc,
        RunOptions {
            in_memory: true,
            ..Default::default()
        },
    )
    .unwrap();
    match solution.finished {
        Finished::Interactive(s) => s,
        _ => panic!("not an interactive run"),
    }
}

/// Held after the pull, the frames converge to the frame's static equilibrium (the static
/// solver's, here to 1e-12 of the force scale) within 1e-8 of its largest displacement, for a hard
/// patch and for one on springs, on two levels and one (the fine level factored).
#[test]
fn held_frames_reach_the_static_solver_s_equilibrium() {
    for (grasp, levels) in [("", 2), ("stiffness = 50.0", 2), ("", 1)] {
        let sc = block(1.5, 3, Some(grasp), levels);
        assert!(sc
            .stepper()
            .unwrap()
            .describe()
            .starts_with("newton frames"));
        let s = interactive(&sc);
        assert_eq!(s.reference_failures, 0, "{grasp}: {:?}", s.first_failure);
        assert_eq!(s.rejected_frames, 0, "{grasp}: {:?}", s.first_rejection);
        let last = s.last.unwrap();
        assert!(last.static_max_u > 1e-3, "{grasp}: {}", last.static_max_u);
        assert!(
            last.lag_max <= 1e-8 * last.static_max_u,
            "{grasp} levels {levels}: lag {:.3e} m of max |u*| {:.3e} m",
            last.lag_max,
            last.static_max_u
        );
        // On the way, every frame within 5 % of its equilibrium (3 steps a frame).
        assert!(s.lag_rel_max <= 0.05, "{grasp}: {}", s.lag_rel_max);
    }
}

/// `Budget::Cycles` frames of a grasped body (a hard grasp moved, a pin, a spring grasp
/// moved, then released) give the same bits on 1 and 2 threads.
#[test]
fn frames_give_the_same_bits_on_any_thread_count() {
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            // The block without its path: grasps are taken at run time.
            let sc = block(0.1, 1, None, 2);
            let mut sim = Simulation::from_scenario(&sc).unwrap();
            let hard = sim.grab([0.04, 0.01, 0.02], 0.004).unwrap();
            let mut u = Vec::new();
            for k in 1..=4 {
                sim.move_grab(hard, [0.04, 0.01 + 0.001 * k as f64, 0.02])
                    .unwrap();
                let r = sim.step_frame(Budget::Cycles(2));
                assert!(r.accepted, "{:?}", r.rejection);
            }
            sim.release(hard).unwrap();
            let spring = sim
                .grab_with(
                    [0.04, 0.0, 0.0],
                    raisov::sim::GrabOptions::spring(0.004, 100.0),
                )
                .unwrap();
            for k in 1..=4 {
                sim.move_grab(spring, [0.04, -0.001 * k as f64, 0.0])
                    .unwrap();
                let r = sim.step_frame(Budget::Cycles(2));
                assert!(r.accepted, "{:?}", r.rejection);
                u.extend_from_slice(sim.displacements());
            }
            u
        })
    };
    let (u1, u2) = (run(1), run(2));
    assert!(u1.iter().any(|&x| x != 0.0));
    assert!(u1.iter().zip(&u2).all(|(a, b)| a.to_bits() == b.to_bits()));
}

/// The simulation of `sc` with the block's top tip grasped through springs of 100 N/m over
/// a 4 mm patch, the grasp's target moved 6 mm up (not yet stepped).
fn spring_pulled(sc: &Scenario) -> (Simulation, raisov::sim::GrabId) {
    let mut sim = Simulation::from_scenario(sc).unwrap();
    let g = sim
        .grab_with(
            [0.04, 0.01, 0.02],
            raisov::sim::GrabOptions::spring(0.004, 100.0),
        )
        .unwrap();
    sim.move_grab(g, [0.04, 0.01, 0.026]).unwrap();
    (sim, g)
}

/// A spring grasp held still: the frames converge to the equilibrium where the tissue's
/// reaction balances the springs' pull, which is the force the grasp reports.
#[test]
fn a_held_spring_grasp_balances_the_tissue() {
    let sc = block(0.1, 1, None, 2);
    let (mut sim, g) = spring_pulled(&sc);
    let mut last = f64::INFINITY;
    for _ in 0..60 {
        let r = sim.step_frame(Budget::Cycles(2));
        assert!(r.accepted, "{:?}", r.rejection);
        last = r.residual;
    }
    let f = sim.grab_force(g).unwrap();
    let pull = (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
    assert!(pull > 1e-2, "the springs pull {pull} N");
    // Converged: the largest nodal out-of-balance force is a tiny share of the pull.
    assert!(
        last <= 1e-8 * pull,
        "residual {last:.3e} N against a pull of {pull:.3e} N"
    );
}

/// `[multigrid] cg_per_step` belongs to the frame solver and is at least 1; FAS's keys are
/// not the frame solver's. Each error names the key.
#[test]
fn frame_solver_keys_are_checked_and_named() {
    let with = |multigrid: &str| {
        Scenario::from_toml(
            &small_block(multigrid, true),
            std::path::Path::new("keys.toml"),
        )
    };
    let e = with("scheme = \"fas\"\ncg_per_step = 3")
        .unwrap_err()
        .to_string();
    assert!(e.contains("cg_per_step") && e.contains("newton"), "{e}");
    let e = with("scheme = \"newton\"\ncg_per_step = 0")
        .unwrap_err()
        .to_string();
    assert!(e.contains("cg_per_step") && e.contains("at least 1"), "{e}");
    let e = with("scheme = \"newton\"\npre_smooth = 2")
        .unwrap_err()
        .to_string();
    assert!(e.contains("pre_smooth"), "{e}");
    let sc = with("scheme = \"newton\"\ncg_per_step = 3").unwrap();
    assert!(sc.stepper().unwrap().describe().contains("at most 3 CG"));
}

/// `SimulationBuilder` builds the frame solver too: a cube held at its base, grasped at its
/// top and lifted, held: the frames reach a residual of 1e-8 of the grasp's pull.
#[test]
fn the_builder_s_frame_solver_takes_a_grasp() {
    use raisov::mesh::generate::{box_tets, BoxPattern};
    use raisov::sim::{Scheme, SimulationBuilder};
    let fine = box_tets([0.02; 3], [6, 6, 6], BoxPattern::Six).unwrap();
    let coarse = box_tets([0.02; 3], [2, 2, 2], BoxPattern::Six).unwrap();
    let mut sim = SimulationBuilder::new(fine)
        .levels(vec![coarse])
        .fix(|p| p[2] <= 0.0)
        .scheme(Scheme::Newton(Default::default()))
        .build()
        .unwrap();
    assert!(sim.stepper().describe().starts_with("newton frames"));
    let g = sim.grab([0.01, 0.01, 0.02], 0.004).unwrap();
    for k in 1..=40 {
        let z = 0.02 + 0.002 * (k.min(5) as f64);
        sim.move_grab(g, [0.01, 0.01, z]).unwrap();
        let r = sim.step_frame(Budget::Cycles(2));
        assert!(r.accepted, "{:?}", r.rejection);
    }
    let f = sim.grab_force(g).unwrap();
    let pull = (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
    let r = sim.step_frame(Budget::Cycles(1)).residual;
    assert!(pull > 1e-3, "pull {pull}");
    assert!(r <= 1e-8 * pull, "residual {r:.3e} N, pull {pull:.3e} N");
}

/// The frame solver cuts: a notch cut half-way into the grasped block splits elements on
/// both of its levels, the grasp goes on holding the cut body, and held frames converge to
/// the cut body's equilibrium: a residual of 1e-8 of the pull, and the same displacements
/// (within 1e-8 of the largest) as FAS, run to convergence on the same cut.
#[test]
fn the_frame_solver_cuts_and_converges_on_the_cut_body() {
    let run = |fas: bool| {
        let sc = if fas {
            fas_block()
        } else {
            block(0.1, 1, None, 2)
        };
        let (mut sim, g) = spring_pulled(&sc);
        let cycles = if fas { 40 } else { 2 };
        let settle = |sim: &mut Simulation| {
            let mut last = f64::INFINITY;
            for _ in 0..60 {
                let r = sim.step_frame(Budget::Cycles(cycles));
                assert!(r.accepted, "{:?}", r.rejection);
                last = r.residual;
            }
            let f = sim.grab_force(g).unwrap();
            ((f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt(), last)
        };
        settle(&mut sim);
        // A notch from the top face down to half the height, across the width, at x = 1.5 cm.
        let blade = raisov::mesh::cut::Blade::quad([
            [0.015, -1.0, 0.01],
            [0.015, 1.0, 0.01],
            [0.015, 1.0, 1.0],
            [0.015, -1.0, 1.0],
        ])
        .unwrap();
        let report = sim.cut(&blade).unwrap();
        assert_eq!(report.split.len(), 2, "{:?}", report.split);
        assert!(report.split.iter().all(|&s| s > 0), "{:?}", report.split);
        let (pull, last) = settle(&mut sim);
        assert!(
            last <= 1e-8 * pull,
            "fas {fas}: residual {last:.3e} N against a pull of {pull:.3e} N"
        );
        sim.displacements().to_vec()
    };
    let (newton, fas) = (run(false), run(true));
    assert_eq!(newton.len(), fas.len());
    let (umax, diff) = (max_abs(&fas), max_abs_diff(&newton, &fas));
    assert!(umax > 1e-3, "max |u| {umax}");
    assert!(
        diff <= 1e-8 * umax,
        "the frame solver's cut body differs from FAS's by {diff:.3e} m (max |u| {umax:.3e} m)"
    );
}

/// [`block`] without a path under FAS (the reference of the cut test).
fn fas_block() -> Scenario {
    let text = r#"
[mesh]
generate = "box"
size = [0.04, 0.02, 0.02]
divisions = [8, 4, 4]
[material]
law = "neo-hookean"
young = 5000.0
poisson = 0.45
density = 1000.0
[[fix]]
plane = { point = [0.0, 0.0, 0.0], normal = [1.0, 0.0, 0.0] }
[run]
duration = 0.1
[multigrid]
scheme = "fas"
levels = 2
[interactive]
fps = 30.0
"#;
    Scenario::from_toml(text, std::path::Path::new("fas.toml")).unwrap()
}

/// A `Budget::Millis` frame of the frame solver stops once it has settled at the frame's
/// equilibrium instead of spending the whole budget: a minute's budget, a spring grasp moved
/// once, and the frame ends after a few dozen steps with the displacements within 1e-5 of
/// the equilibrium's largest (the frames converged after it); a held frame then takes one
/// step.
#[test]
fn a_wall_time_frame_stops_once_the_frame_solver_settles() {
    let sc = block(0.1, 1, None, 2);
    let (mut sim, _) = spring_pulled(&sc);
    let r = sim.step_frame(Budget::Millis(60_000.0));
    assert!(r.accepted, "{:?}", r.rejection);
    assert!(
        r.cycles < 200,
        "{} steps: the frame did not stop at its equilibrium",
        r.cycles
    );
    let settled = sim.displacements().to_vec();
    // Held, the next frame has nothing to do: one step.
    let r = sim.step_frame(Budget::Millis(60_000.0));
    assert_eq!(r.cycles, 1);
    for _ in 0..30 {
        sim.step_frame(Budget::Cycles(2));
    }
    let u = sim.displacements();
    let (umax, diff) = (max_abs(u), max_abs_diff(u, &settled));
    assert!(umax > 1e-3, "max |u| {umax}");
    assert!(
        diff <= 1e-5 * umax,
        "settled {diff:.3e} m from the equilibrium (max |u| {umax:.3e} m)"
    );
}

/// A body with nothing acting on it (`examples/liver_frames.toml` run on its own): its
/// forces at rest are round-off, and the reference solve of every frame counts as converged
/// instead of failing for a tolerance relative to that round-off; the frames stay at rest.
#[test]
fn an_unloaded_body_s_reference_does_not_fail() {
    let sc = Scenario::load(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../examples/liver_frames.toml"
    )))
    .unwrap();
    let s = interactive(&sc);
    assert_eq!(s.reference_failures, 0, "{:?}", s.first_failure);
    let last = s.last.unwrap();
    assert!(last.static_max_u < 1e-9, "{}", last.static_max_u);
    assert!(last.lag_max < 1e-9, "{}", last.lag_max);
}

/// Without `scheme`, an interactive scenario's levels run the frame solver, unless FAS's own
/// keys are set; a scenario without `[interactive]` keeps FAS.
#[test]
fn an_interactive_scenario_s_levels_default_to_the_frame_solver() {
    let with = |multigrid: &str, interactive: bool| {
        Scenario::from_toml(
            &small_block(multigrid, interactive),
            std::path::Path::new("default.toml"),
        )
        .unwrap()
        .stepper()
        .unwrap()
        .describe()
    };
    assert!(
        with("", true).starts_with("newton frames"),
        "{}",
        with("", true)
    );
    assert!(with("cg_per_step = 3", true).contains("at most 3 CG"));
    assert!(with("pre_smooth = 2", true).starts_with("fas"));
    assert!(with("", false).starts_with("fas"), "{}", with("", false));
}
