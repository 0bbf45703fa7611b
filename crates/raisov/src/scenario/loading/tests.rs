//! `[[pressure]]`, `[[traction]]`, `[[tool]]` and `time = {..}` in scenarios: checks, and
//! balances of short static solves and runs.

use super::super::*;
use crate::error::Error;
use crate::runner::{run, RunOptions, StopReason};

/// A 2 cm neo-Hookean cube on a fixed base (z = 0).
const BLOCK: &str = r#"
[mesh]
generate = "box"
size = [0.02, 0.02, 0.02]
divisions = [6, 6, 6]

[material]
law = "neo-hookean"
young = 5e4
poisson = 0.4

[[fix]]
plane = { point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }
"#;

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

fn static_run(text: &str) -> (crate::runner::StaticSummary, tempfile::TempDir) {
    let sc = parse(text).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let s = crate::runner::run_static(
        &sc,
        RunOptions {
            out_dir: Some(dir.path().join("out")),
            ..Default::default()
        },
    )
    .unwrap();
    (s, dir)
}

#[test]
fn time_functions_and_surface_loads_are_checked() {
    let e = error_of(&format!(
        "{BLOCK}[[pressure]]\nvalue = 100.0\n[run]\nduration = 0.01\n"
    ));
    assert!(
        e.contains("pressure[0]: give exactly one of `group`"),
        "{e}"
    );
    let e = error_of(&format!(
        "{BLOCK}[[traction]]\ngroup = \"zmax\"\nvalue = 1.0\n[run]\nduration = 0.01\n"
    ));
    assert!(e.contains("traction[0]: needs `traction`"), "{e}");
    let e = error_of(&format!(
        "{BLOCK}[[pressure]]\ngroup = \"zmax\"\nvalue = 1.0\ntime = {{ kind = \"ramp\" }}\n[run]\nduration = 0.01\n"
    ));
    assert!(
        e.contains("pressure[0].time: kind = \"ramp\" needs `duration`"),
        "{e}"
    );
    let e = error_of(&format!(
        "{BLOCK}[[pressure]]\ngroup = \"zmax\"\nvalue = 1.0\ntime = {{ kind = \"wave\" }}\n[run]\nduration = 0.01\n"
    ));
    assert!(
        e.contains("\"constant\", \"ramp\", \"table\", \"sine\""),
        "{e}"
    );
    let e = error_of(&format!(
        "{BLOCK}[[pressure]]\ngroup = \"nope\"\nvalue = 1.0\n[run]\nduration = 0.01\n"
    ));
    assert!(e.contains("no group \"nope\""), "{e}");
    let e = error_of(&format!(
        "{BLOCK}[[displace]]\npoint = [0.01, 0.01, 0.02]\ndisplacement = [0.0, 0.0, 0.001]\nmode = \"ramp\"\ntime = {{ kind = \"sine\", frequency = 2.0 }}\n[run]\nduration = 0.01\n"
    ));
    assert!(e.contains("`mode` does not apply with `time`"), "{e}");
    let e = error_of(&format!(
        "{BLOCK}[[tool]]\nshape = \"sphere\"\ncenter = [0.0, 0.0, 0.1]\n[run]\nduration = 0.01\n"
    ));
    assert!(
        e.contains("tool[0]: shape = \"sphere\" needs `radius`"),
        "{e}"
    );
    let e = error_of(&format!(
        "{BLOCK}[[tool]]\nshape = \"sphere\"\ncenter = [0.0, 0.0, 0.1]\nradius = 0.01\npath = [[0.0, 0, 0, 0], [0.0, 0, 0, 0.01]]\n[run]\nduration = 0.01\n"
    ));
    assert!(
        e.contains("tool[0].path: times must increase strictly (0 then 0)"),
        "{e}"
    );
    let e = error_of(&format!(
        "{BLOCK}[[tool]]\nshape = \"plane\"\npoint = [0.0, 0.0, 0.1]\nnormal = [0.0, 0.0, 1.0]\nradius = 1.0\n[run]\nduration = 0.01\n"
    ));
    assert!(
        e.contains("`radius` does not apply to shape = \"plane\""),
        "{e}"
    );
    let e = error_of(&format!(
        "{BLOCK}[[pressure]]\ngroup = \"zmax\"\nvalue = 1.0\ntime = {{ kind = \"sine\", frequency = 2.0 }}\n[integrator]\nmethod = \"newton\"\n"
    ));
    assert!(e.contains("never ends"), "{e}");
    // A sine displacement resolves to the displacement times the function.
    let sc = parse(&format!(
        "{BLOCK}[[displace]]\npoint = [0.01, 0.01, 0.02]\ndisplacement = [0.0, 0.0, 0.001]\ntime = {{ kind = \"sine\", frequency = 2.0, amplitude = 0.5 }}\n[run]\nduration = 0.01\n"
    ))
    .unwrap();
    let m = &sc.prescribed[0].1;
    assert!((m.displacement(0.125)[2] - 0.0005).abs() < 1e-15);
}

/// A pressure on the top face of a block on a fixed base, static: the reactions balance the
/// applied pressure load (1e-6 relative), which is `−p A ẑ` within the follower's change
/// of area, and a pressure on the whole (closed) boundary has zero net force.
#[test]
fn reactions_balance_pressure_loads() {
    let p = 2000.0;
    let (s, _dir) = static_run(&format!(
        "{BLOCK}[[pressure]]\ngroup = \"zmax\"\nvalue = {p}\ntime = {{ kind = \"ramp\", duration = 1.0 }}\n[integrator]\nmethod = \"newton\"\n"
    ));
    assert!(s.converged(), "{s}");
    // The follower pressure's stiffness (its symmetric part) is in the assembled tangent:
    // "auto" takes the sparse direct Newton, and Newton-Krylov asked for lands on the same
    // equilibrium (the reactions within the stopping rule's 1e-7 of the load).
    assert_eq!(s.solver, crate::scenario::StaticSolver::Direct, "{s}");
    let (k, _dir2) = static_run(&format!(
        "{BLOCK}[[pressure]]\ngroup = \"zmax\"\nvalue = {p}\ntime = {{ kind = \"ramp\", duration = 1.0 }}\n[integrator]\nmethod = \"newton\"\nsolver = \"krylov\"\n"
    ));
    assert!(k.converged(), "{k}");
    assert_eq!(k.solver, crate::scenario::StaticSolver::Krylov, "{k}");
    for c in 0..3 {
        let gap = s.last.reaction_fixed[c] - k.last.reaction_fixed[c];
        assert!(
            gap.abs() <= 1e-6 * s.applied[2].abs(),
            "direct and Krylov reactions differ in {c}: {gap:e}"
        );
    }
    let a = s.applied;
    let area = 0.02 * 0.02;
    eprintln!("applied {a:?}, reactions {:?}", s.last.reaction_fixed);
    assert!(
        a[2] < 0.0 && (a[2] / (-p * area) - 1.0).abs() < 0.05,
        "{a:?}"
    );
    for k in 0..3 {
        let gap = s.last.reaction_fixed[k] + a[k];
        assert!(gap.abs() <= 1e-6 * a[2].abs(), "balance {k}: {gap:e}");
    }
    // The whole boundary: a closed surface.
    let sc = parse(&format!(
        "{BLOCK}[[pressure]]\nboundary = true\nvalue = {p}\n[run]\nduration = 0.01\n"
    ))
    .unwrap();
    let mut sys = sc.build_system().unwrap();
    let n = sc.mesh.num_nodes();
    let u: Vec<f64> = (0..3 * n).map(|i| 1e-4 * (0.37 * i as f64).sin()).collect();
    let rep = sys.force.load_report(&u);
    let total = p * 6.0 * area / 3.0;
    for k in 0..3 {
        assert!(rep.applied[k].abs() < 1e-12 * total, "{rep:?}");
    }
}

/// A sphere pushed 2 mm into the block on a fixed base, static: the contact force is equal and
/// opposite to the base reactions (1e-6 relative), pushes down, and the penetration is within
/// the penalty's `|F_a| / k` (below 10 % of the push with the default stiffness).
#[test]
fn sphere_probe_force_balances_base_reactions() {
    let probe = "[[tool]]\nshape = \"sphere\"\ncenter = [0.01, 0.01, 0.025]\nradius = 0.005\ndisplacement = [0.0, 0.0, -0.002]\ntime = { kind = \"ramp\", duration = 1.0 }\n";
    let (s, dir) = static_run(&format!(
        "{BLOCK}{probe}[integrator]\nmethod = \"newton\"\n"
    ));
    assert!(s.converged(), "{s}");
    let f = s.last.tool;
    let r = s.last.reaction_fixed;
    eprintln!(
        "tool {f:?}, base {r:?}, penetration {:e}",
        s.last.penetration
    );
    assert!(f[2] < 0.0, "{f:?}");
    for k in 0..3 {
        assert!((f[k] + r[k]).abs() <= 1e-6 * f[2].abs(), "{f:?} vs {r:?}");
    }
    assert!(s.last.penetration > 0.0 && s.last.penetration < 0.1 * 0.002);
    let text = s.to_string();
    assert!(text.contains("tool contact"), "{text}");
    let csv = std::fs::read_to_string(dir.path().join("out/measures.csv")).unwrap();
    assert!(csv
        .lines()
        .next()
        .unwrap()
        .contains("tool_fx_N,tool_fy_N,tool_fz_N"));
}

/// The same probe, dynamic with FAS multigrid (the tool on every level) to steady state: the
/// contact force matches the static solve within 1e-3 relative.
#[test]
fn sphere_probe_on_multigrid_settles_to_the_static_force() {
    let probe = "[[tool]]\nshape = \"sphere\"\ncenter = [0.01, 0.01, 0.025]\nradius = 0.005\ndisplacement = [0.0, 0.0, -0.002]\ntime = { kind = \"ramp\", duration = 0.05 }\n";
    let (s, _d1) = static_run(&format!(
        "{BLOCK}{probe}[integrator]\nmethod = \"newton\"\n"
    ));
    let sc = parse(&format!(
        "{BLOCK}{probe}[damping]\nratio = 1.0\nomega = 300.0\n[run]\nstop = \"steady\"\nduration = 2.0\nkinetic_tol = 1e-14\nresidual_tol = 1e-8\n[multigrid]\nlevels = 2\n"
    ))
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let d = run(
        &sc,
        RunOptions {
            out_dir: Some(dir.path().join("d")),
            ..Default::default()
        },
    )
    .unwrap();
    eprintln!("{d}");
    assert_eq!(d.reason, StopReason::Steady, "{d}");
    let (fs, fd) = (s.last.tool, d.last.tool);
    eprintln!("static {fs:?} dynamic {fd:?}");
    assert!(
        (fs[2] - fd[2]).abs() <= 1e-3 * fs[2].abs(),
        "{fs:?} vs {fd:?}"
    );
}

#[test]
fn unknown_tool_shape_names_the_valid_ones() {
    let e = parse(&format!(
        "{BLOCK}[[tool]]\nshape = \"cube\"\n[run]\nduration = 0.01\n"
    ))
    .unwrap_err();
    assert!(matches!(e, Error::Scenario { .. }));
    assert!(
        e.to_string().contains("\"sphere\", \"plane\", \"capsule\""),
        "{e}"
    );
}

/// The probe with single-level symplectic Euler at the default step (half the estimated
/// critical one; the default penalty stiffness leaves it stable) settles to the static force
/// within 1e-3 relative.
#[test]
fn sphere_probe_single_level_explicit_is_stable_at_the_default_step() {
    let probe = "[[tool]]\nshape = \"sphere\"\ncenter = [0.01, 0.01, 0.025]\nradius = 0.005\ndisplacement = [0.0, 0.0, -0.002]\ntime = { kind = \"ramp\", duration = 0.05 }\n";
    let (s, _d1) = static_run(&format!(
        "{BLOCK}{probe}[integrator]\nmethod = \"newton\"\n"
    ));
    let sc = parse(&format!(
        "{BLOCK}{probe}[damping]\nratio = 1.0\nomega = 300.0\n[run]\nstop = \"steady\"\nduration = 2.0\nkinetic_tol = 1e-14\nresidual_tol = 1e-8\n"
    ))
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let d = run(
        &sc,
        RunOptions {
            out_dir: Some(dir.path().join("d")),
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(d.reason, StopReason::Steady, "{d}");
    let (fs, fd) = (s.last.tool, d.last.tool);
    eprintln!("static {fs:?} explicit {fd:?} after {} steps", d.steps);
    assert!(
        (fs[2] - fd[2]).abs() <= 1e-3 * fs[2].abs(),
        "{fs:?} vs {fd:?}"
    );
}

/// `examples/probe_block.toml` and `examples/pressure_block.toml` run to steady state, and
/// their reactions balance the tool force and the pressure load (1e-5 relative).
#[test]
fn the_probe_and_pressure_examples_settle_in_balance() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples");
    let out = tempfile::tempdir().unwrap();
    for f in ["probe_block.toml", "pressure_block.toml"] {
        let sc = Scenario::load(&Path::new(dir).join(f)).unwrap_or_else(|e| panic!("{f}: {e}"));
        let s = run(
            &sc,
            RunOptions {
                out_dir: Some(out.path().join(f)),
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(s.reason, StopReason::Steady, "{f}: {s}");
        eprintln!("{s}");
        let (r, a, t) = (s.last.reaction_fixed, s.applied, s.last.tool);
        let scale = r[2].abs();
        assert!(scale > 0.05, "{f}: {r:?}");
        for k in 0..3 {
            let gap = r[k] + a[k] + t[k];
            assert!(gap.abs() <= 1e-5 * scale, "{f}: component {k}: {gap:e}");
        }
    }
}

/// The probe under the paper's RaISoV cycle (the tool on every level, each with its own
/// nodes) runs 0.2 s without diverging and pushes down. The literal cycle is not a convergent
/// solver: its force at 0.2 s is measured at 1.9 times the static one (0.82 N against
/// 0.435 N), so no closer claim is made.
#[test]
fn sphere_probe_runs_under_the_raisov_paper_cycle() {
    let probe = "[[tool]]\nshape = \"sphere\"\ncenter = [0.01, 0.01, 0.025]\nradius = 0.005\ndisplacement = [0.0, 0.0, -0.002]\ntime = { kind = \"ramp\", duration = 0.05 }\n";
    let (s, _d1) = static_run(&format!(
        "{BLOCK}{probe}[integrator]\nmethod = \"newton\"\n"
    ));
    let sc = parse(&format!(
        "{BLOCK}{probe}[damping]\nratio = 1.0\nomega = 300.0\n[run]\nduration = 0.2\n[multigrid]\nscheme = \"raisov-paper\"\nlevels = 2\n"
    ))
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let d = run(
        &sc,
        RunOptions {
            out_dir: Some(dir.path().join("d")),
            ..Default::default()
        },
    )
    .unwrap();
    let (fs, fd) = (s.last.tool, d.last.tool);
    eprintln!("static {fs:?} raisov-paper {fd:?}: {}", d.reason);
    assert_eq!(d.reason, StopReason::Duration, "{d}");
    assert!(fd[2] < 0.0 && fd[2].is_finite(), "{fd:?}");
}

/// The values of the point field `name` in an ASCII VTU file.
pub(super) fn ascii_point_field(path: &Path, name: &str) -> Vec<f64> {
    let text = std::fs::read_to_string(path).unwrap();
    let start = text
        .find(&format!("Name=\"{name}\""))
        .unwrap_or_else(|| panic!("{name} not in {}", path.display()));
    let body = &text[start..];
    let open = body.find('>').unwrap() + 1;
    let close = body.find("</DataArray>").unwrap();
    body[open..close]
        .split_whitespace()
        .map(|x| x.parse().unwrap())
        .collect()
}

/// A rigid plane pressed 0.2 mm onto the block's top (frictionless penalty, static solve):
/// the frame's `contact_pressure` times each node's tributary area sums to the tool force
/// (the plane's nodal forces are parallel, so `Σ |f_a| = |F_tool|`), only top nodes carry
/// it, and at the centre of the top it is within 15 % of the mean pressure `|F| / A_top`.
#[test]
fn plane_tool_contact_pressure_field_integrates_to_the_tool_force() {
    let tool = "[[tool]]\nshape = \"plane\"\npoint = [0.0, 0.0, 0.02]\nnormal = [0.0, 0.0, -1.0]\ndisplacement = [0.0, 0.0, -0.0002]\ntime = { kind = \"ramp\", duration = 1.0 }\n";
    let text =
        format!("{BLOCK}{tool}[integrator]\nmethod = \"newton\"\n[output]\nvtu = \"ascii\"\n");
    let (s, dir) = static_run(&text);
    assert!(s.converged(), "{s}");
    let f = s.last.tool;
    let fmag = (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
    assert!(f[2] < 0.0 && fmag > 0.0, "{f:?}");
    let frames = dir.path().join("out/frames");
    let mut files: Vec<_> = std::fs::read_dir(&frames)
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "vtu"))
        .collect();
    files.sort();
    let last = files.last().expect("a frame");
    let p = ascii_point_field(last, "contact_pressure");
    let sc = parse(&text).unwrap();
    let areas = crate::contact::tributary_areas(&sc.mesh);
    assert_eq!(p.len(), areas.len());
    let total: f64 = p.iter().zip(&areas).map(|(p, a)| p * a).sum();
    assert!((total - fmag).abs() <= 1e-6 * fmag, "{total} vs {fmag}");
    let mut centre = (f64::INFINITY, 0.0);
    for (a, x) in sc.mesh.nodes.iter().enumerate() {
        if p[a] > 0.0 {
            assert!(x[2] > 0.02 - 1e-9, "node {a} at {x:?} carries contact");
        }
        let d = (x[0] - 0.01).powi(2) + (x[1] - 0.01).powi(2) + (x[2] - 0.02).powi(2);
        if d < centre.0 {
            centre = (d, p[a]);
        }
    }
    let mean = fmag / (0.02 * 0.02);
    eprintln!("centre {} Pa, mean {mean} Pa", centre.1);
    assert!(
        (centre.1 - mean).abs() <= 0.15 * mean,
        "centre {} vs mean {mean}",
        centre.1
    );
}
