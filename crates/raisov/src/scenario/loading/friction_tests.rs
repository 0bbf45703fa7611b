//! Coulomb friction of `[[tool]]`s in scenarios: the keys' checks, a block sheared by a
//! rigid plane pressed on its top and dragged sideways (stick below `μ_s N`, slip at
//! `μ_k N`) on each stepper, stick and slip side by side under a dragged sphere, the same bits
//! on 1 and 2 threads, and `friction = 0` bit for bit frictionless.

use super::super::*;
use crate::runner::{run, solve, RunOptions, StopReason};

/// A 2 cm neo-Hookean cube on a fixed base (z = 0), 4³ cells, critically damped.
const BLOCK: &str = r#"
[mesh]
generate = "box"
size = [0.02, 0.02, 0.02]
divisions = [4, 4, 4]

[material]
law = "neo-hookean"
young = 5e4
poisson = 0.4

[damping]
ratio = 1.0
omega = 300.0

[[fix]]
plane = { point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }
"#;

/// A plane over the whole top (the tool above z = 0.02), pressed 1 mm down over 0.05 s, then
/// dragged 1 mm along +x over 0.1 s and held; `keys` adds the friction keys.
fn plane_drag(keys: &str, more: &str) -> String {
    format!(
        "{BLOCK}[[tool]]\nshape = \"plane\"\npoint = [0.0, 0.0, 0.02]\nnormal = [0.0, 0.0, -1.0]\n\
         path = [[0.0, 0.0, 0.0, 0.0], [0.05, 0.0, 0.0, -0.001], [0.15, 0.001, 0.0, -0.001]]\n\
         {keys}\n[run]\nstop = \"steady\"\nduration = 1.0\nkinetic_tol = 1e-10\n\
         residual_tol = 1e-6\n{more}"
    )
}

fn parse(text: &str) -> Result<Scenario> {
    Scenario::from_toml(text, Path::new("test.toml"))
}

fn error_of(text: &str) -> String {
    let e = parse(text).expect_err("should fail");
    let s = e.to_string();
    assert!(
        s.starts_with("test.toml"),
        "error does not name the file: {s}"
    );
    s
}

/// Run in memory; the final state and measures.
fn solved(text: &str) -> crate::runner::Solution {
    let sc = parse(text).unwrap();
    solve(
        &sc,
        RunOptions {
            in_memory: true,
            ..Default::default()
        },
    )
    .unwrap_or_else(|e| panic!("{e}"))
}

/// `(|F_t|, |F_n|)`: the friction force's magnitude and the normal part of the tool force.
fn split(s: &crate::metrics::Sample) -> (f64, f64) {
    let (t, f) = (s.tool, s.friction);
    let ft = (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
    let n = [t[0] - f[0], t[1] - f[1], t[2] - f[2]];
    (ft, (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt())
}

/// The mean x displacement of the top nodes (z = 0.02).
fn top_ux(text: &str, u: &[f64]) -> f64 {
    let sc = parse(text).unwrap();
    let top: Vec<usize> = (0..sc.mesh.num_nodes())
        .filter(|&a| sc.mesh.nodes[a][2] > 0.02 - 1e-9)
        .collect();
    top.iter().map(|&a| u[3 * a]).sum::<f64>() / top.len() as f64
}

#[test]
fn friction_keys_are_checked_and_name_the_tool() {
    let tool = "[[tool]]\nshape = \"plane\"\npoint = [0.0, 0.0, 0.02]\nnormal = [0.0, 0.0, -1.0]\n";
    let run = "[run]\nduration = 0.01\n";
    let e = error_of(&format!("{BLOCK}{tool}friction = -0.1\n{run}"));
    assert!(
        e.contains("`tool[0].friction` = -0.1") && e.contains(">= 0"),
        "{e}"
    );
    let e = error_of(&format!(
        "{BLOCK}{tool}static_friction = 0.2\nkinetic_friction = 0.3\n{run}"
    ));
    assert!(
        e.contains("tool[0]: `kinetic_friction` = 0.3 exceeds `static_friction` = 0.2"),
        "{e}"
    );
    let e = error_of(&format!(
        "{BLOCK}{tool}friction = 0.2\nstatic_friction = 0.3\n{run}"
    ));
    assert!(e.contains("tool[0]: give `friction`"), "{e}");
    let e = error_of(&format!("{BLOCK}{tool}kinetic_friction = 0.3\n{run}"));
    assert!(
        e.contains("`kinetic_friction` needs `static_friction`"),
        "{e}"
    );
    let e = error_of(&format!("{BLOCK}{tool}friction_stiffness = 1e3\n{run}"));
    assert!(
        e.contains("tool[0]: `friction_stiffness` needs `friction`"),
        "{e}"
    );
    let e = error_of(&format!(
        "{BLOCK}{tool}friction = 0.2\nfriction_stiffness = 0.0\n{run}"
    ));
    assert!(e.contains("`tool[0].friction_stiffness` = 0"), "{e}");
    let e = error_of(&format!(
        "{BLOCK}{tool}friction = 0.2\n[integrator]\nmethod = \"newton\"\n"
    ));
    assert!(
        e.contains("`tool[0]` has friction") && e.contains("implicit-euler"),
        "{e}"
    );
    // μ_k defaults to μ_s.
    let sc = parse(&format!("{BLOCK}{tool}static_friction = 0.4\n{run}")).unwrap();
    let f = sc.tools[0].friction.unwrap();
    assert_eq!((f.static_coefficient, f.kinetic_coefficient), (0.4, 0.4));
}

/// μ = 1 holds the top: it moves with the plane (its mean x displacement within 2 % of the
/// plane's 1 mm), the friction force points along the drag, stays below `μ_s N`, and
/// balances the base's reaction along x (1e-3 of `|F_t|`).
#[test]
fn plane_dragged_block_sticks_below_mu_s_n() {
    let text = plane_drag("friction = 1.0", "");
    let s = solved(&text);
    let (ft, n) = split(&s.last);
    let ux = top_ux(&text, &s.u);
    eprintln!("stick: F_t {ft} N, N {n} N, top u_x {ux}");
    assert!(n > 0.5, "{n}");
    assert!(s.last.friction[0] > 0.0, "{:?}", s.last.friction);
    assert!(ft < 1.0 * n, "{ft} vs mu_s N = {n}");
    assert!((ux - 1e-3).abs() <= 0.02e-3, "{ux}");
    let r = s.last.reaction_fixed[0];
    assert!(
        (r + s.last.tool[0]).abs() <= 1e-3 * ft,
        "{r} vs {}",
        s.last.tool[0]
    );
}

/// `static_friction = 0.15`, `kinetic_friction = 0.1`: the shear the drag needs exceeds
/// `μ_s N`, the top slips (it keeps less than half of the plane's travel) and the friction
/// force is `μ_k N` along the drag (1e-3 absolute on the ratio), with single-level symplectic
/// Euler and with backward Euler (its `[multigrid]` levels preconditioning the Newton solve,
/// friction on the fine level); the explicit multigrid schemes refuse friction, naming the
/// tool.
#[test]
fn plane_dragged_block_slips_at_mu_k_n_on_explicit_and_implicit_steppers() {
    let keys = "static_friction = 0.15\nkinetic_friction = 0.1";
    for (what, more) in [
        ("symplectic euler", ""),
        (
            "implicit euler",
            "[integrator]\nmethod = \"implicit-euler\"\ndt = 2e-3\n",
        ),
        (
            "implicit euler, levels",
            "[integrator]\nmethod = \"implicit-euler\"\ndt = 2e-3\n[multigrid]\nlevels = 2\n",
        ),
    ] {
        let text = plane_drag(keys, more);
        let s = solved(&text);
        let (ft, n) = split(&s.last);
        let ux = top_ux(&text, &s.u);
        eprintln!(
            "{what}: F_t {ft} N, N {n} N, ratio {}, top u_x {ux}",
            ft / n
        );
        assert!(s.last.friction[0] > 0.0, "{what}: {:?}", s.last.friction);
        assert!(ux < 0.5e-3, "{what}: {ux}");
        assert!((ft / n - 0.1).abs() <= 1e-3, "{what}: {ft} / {n}");
    }
    for scheme in ["fas", "raisov-paper"] {
        let e = error_of(&plane_drag(
            keys,
            &format!("[multigrid]\nlevels = 2\nscheme = \"{scheme}\"\n"),
        ));
        assert!(
            e.contains("`tool[0]` has friction") && e.contains("[multigrid]"),
            "{e}"
        );
    }
}

/// A sphere (radius 1 cm) pressed 1.5 mm into the top (8 × 8 cells across it) and dragged
/// 2 mm along x: during the drag there are steps whose contact patch has nodes slipping
/// (`|f_t| = μ_k N_a`, 1e-9) and nodes stuck (`|f_t| < μ_k N_a`) side by side, and no node
/// ever carries more than `μ_s N_a`; the same bits on 1 and 2 threads.
#[test]
fn sphere_drag_sticks_and_slips_in_one_patch_with_the_same_bits_on_1_and_2_threads() {
    const END: f64 = 0.25;
    let text = format!(
        "{}[[tool]]\nshape = \"sphere\"\ncenter = [0.008, 0.01, 0.03]\nradius = 0.01\n\
         path = [[0.0, 0.0, 0.0, 0.0], [0.05, 0.0, 0.0, -0.0015], [0.25, 0.002, 0.0, -0.0015]]\n\
         static_friction = 0.6\nkinetic_friction = 0.4\n[run]\nduration = {END}\n",
        BLOCK.replace("[4, 4, 4]", "[8, 8, 4]")
    );
    let in_pool = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let sc = parse(&text).unwrap();
                let mut stepper = sc.stepper().unwrap();
                let (mut mixed, mut most) = (0, (0, 0));
                while stepper.state().t < END - 1e-12 {
                    stepper.advance().unwrap();
                    let (sys, st) = stepper.finest();
                    let n = st.u.len();
                    let (mut c, mut f) = (vec![0.0; n], vec![0.0; n]);
                    assert!(sys.force.contact_forces(&st.u, &mut c));
                    assert!(sys.force.friction_forces(&st.u, &mut f));
                    let (slip, stick) = count(&c, &f);
                    if slip > 0 && stick > 0 {
                        mixed += 1;
                        most = most.max((slip.min(stick), slip));
                    }
                }
                (stepper.state().u.clone(), mixed, most)
            })
    };
    let (u1, mixed, most) = in_pool(1);
    let (u2, _, _) = in_pool(2);
    assert!(
        u1.iter().zip(&u2).all(|(a, b)| a.to_bits() == b.to_bits()),
        "displacements differ between 1 and 2 threads"
    );
    eprintln!("{mixed} steps with stick and slip side by side; at most {most:?}");
    assert!(mixed > 0);
}

/// `(slipping, stuck)` nodes of contact forces `c` with friction part `f`, each checked
/// against `|f_t| ≤ μ_s N_a` (μ_s = 0.6, μ_k = 0.4).
fn count(c: &[f64], f: &[f64]) -> (usize, usize) {
    let (mut slip, mut stick) = (0, 0);
    for (c, ft) in c.chunks_exact(3).zip(f.chunks_exact(3)) {
        let fn_: Vec<f64> = (0..3).map(|k| c[k] - ft[k]).collect();
        let n = (fn_[0] * fn_[0] + fn_[1] * fn_[1] + fn_[2] * fn_[2]).sqrt();
        let t = (ft[0] * ft[0] + ft[1] * ft[1] + ft[2] * ft[2]).sqrt();
        if n == 0.0 || t == 0.0 {
            continue;
        }
        // The law bounds |f_t| by μ N with N as last committed, which lags the current
        // normal force by one step: 1 % slack.
        assert!(t <= 0.6 * n * 1.01, "{t} > mu_s {n}");
        if (t - 0.4 * n).abs() <= 1e-2 * n {
            slip += 1;
        } else if t < 0.4 * n {
            stick += 1;
        }
    }
    (slip, stick)
}

/// `friction = 0` is frictionless contact: the same measures (less the wall time) and frames,
/// bit for bit, and no friction columns or field.
#[test]
fn zero_friction_runs_bit_for_bit_as_frictionless() {
    let out = tempfile::tempdir().unwrap();
    let mut csv = Vec::new();
    for (k, keys) in ["", "friction = 0.0"].iter().enumerate() {
        let sc = parse(&plane_drag(keys, "[output]\nvtu = \"ascii\"\n")).unwrap();
        let dir = out.path().join(k.to_string());
        run(
            &sc,
            RunOptions {
                out_dir: Some(dir.clone()),
                ..Default::default()
            },
        )
        .unwrap();
        let text = std::fs::read_to_string(dir.join("measures.csv")).unwrap();
        assert!(
            !text.contains("friction"),
            "{}",
            text.lines().next().unwrap()
        );
        // Drop the wall-time column (9th).
        let rows: Vec<String> = text
            .lines()
            .map(|l| {
                l.split(',')
                    .enumerate()
                    .filter(|(i, _)| *i != 8)
                    .map(|(_, x)| x)
                    .collect::<Vec<_>>()
                    .join(",")
            })
            .collect();
        csv.push(rows);
    }
    assert_eq!(csv[0], csv[1]);
}

/// With friction, `measures.csv` ends with `friction_x_N,friction_y_N,friction_z_N` and the
/// frames carry `friction_force`, whose sum is the last row's friction force.
#[test]
fn friction_force_is_written_to_measures_and_frames() {
    let text = plane_drag(
        "friction = 0.3",
        "[output]\nvtu = \"ascii\"\ncsv_every = 1\n",
    );
    let sc = parse(&text).unwrap();
    let out = tempfile::tempdir().unwrap();
    let s = run(
        &sc,
        RunOptions {
            out_dir: Some(out.path().join("o")),
            ..Default::default()
        },
    )
    .unwrap();
    let csv = std::fs::read_to_string(out.path().join("o/measures.csv")).unwrap();
    assert!(
        csv.lines()
            .next()
            .unwrap()
            .ends_with("penetration_m,friction_x_N,friction_y_N,friction_z_N"),
        "{}",
        csv.lines().next().unwrap()
    );
    let frames = out.path().join("o/frames");
    let mut files: Vec<_> = std::fs::read_dir(&frames)
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "vtu"))
        .collect();
    files.sort();
    let f = super::tests::ascii_point_field(files.last().unwrap(), "friction_force");
    let sum: f64 = f.iter().step_by(3).sum();
    let want = s.last.friction[0];
    eprintln!("frame sum {sum}, measures {want}");
    assert!(
        want > 0.0 && (sum - want).abs() <= 1e-6 * want,
        "{sum} vs {want}"
    );
}

/// `examples/friction_drag.toml` runs to steady state with the top slipped and the friction
/// force at `μ_k N` (0.3; 1e-3 on the ratio), balanced by the base's reaction (1e-3).
#[test]
fn the_friction_drag_example_slips_at_mu_k_n() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples");
    let sc = Scenario::load(&Path::new(dir).join("friction_drag.toml")).unwrap();
    let out = tempfile::tempdir().unwrap();
    let s = run(
        &sc,
        RunOptions {
            out_dir: Some(out.path().join("o")),
            ..Default::default()
        },
    )
    .unwrap();
    eprintln!("{s}");
    assert_eq!(s.reason, StopReason::Steady, "{s}");
    let (ft, n) = split(&s.last);
    eprintln!("F_t {ft} N, N {n} N, ratio {}", ft / n);
    assert!(s.last.friction[0] > 0.0);
    assert!((ft / n - 0.3).abs() <= 1e-3, "{ft} / {n}");
    let (r, t) = (s.last.reaction_fixed, s.last.tool);
    for k in 0..3 {
        assert!((r[k] + t[k]).abs() <= 1e-3 * n, "{r:?} vs {t:?}");
    }
}
