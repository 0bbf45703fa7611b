//! `method = "implicit-euler"`: the scenario runs it (single level and with the levels as the
//! Newton preconditioner) to the static solve's equilibrium, and the combinations that do not
//! apply are errors naming the key.

use super::*;

/// [`cube`] sagging under gravity, damped, by backward Euler at 10 ms (many explicit
/// critical steps), to steady state; `extra` appended to `[integrator]`.
fn implicit_cube(extra: &str, tail: &str) -> String {
    let body = cube(&format!(
        "[damping]\nalpha = 30.0\n[integrator]\nmethod = \"implicit-euler\"\ndt = 0.01\n{extra}\n[run]\nstop = \"steady\"\nduration = 5.0\nkinetic_tol = 1e-14\nresidual_tol = 1e-5\n{tail}"
    ));
    format!("gravity = [0.0, -9.81, 0.0]\n{body}")
}

#[test]
fn implicit_euler_scenario_settles_at_the_static_solution() {
    let text = implicit_cube("", "");
    let sc = parse(&text).unwrap();
    assert_eq!(sc.method_name(), "implicit-euler");
    let imp = sc.integrator.implicit.expect("implicit settings");
    assert_eq!(imp.rel_tol, crate::statics::implicit::DEFAULT_REL_TOL);
    assert_eq!(imp.max_newton, crate::statics::implicit::DEFAULT_MAX_NEWTON);
    assert!(
        sc.warnings.iter().all(|w| !w.contains("critical step")),
        "{:?}",
        sc.warnings
    );
    let st = sc.stepper().unwrap();
    assert!(
        st.describe().contains("implicit-euler"),
        "{}",
        st.describe()
    );
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
    assert!(
        d.diagnostics
            .as_ref()
            .is_some_and(|(l, x)| *l == "newton" && x.contains("Newton iterations a step")),
        "{d}"
    );
    let statics = format!(
        "gravity = [0.0, -9.81, 0.0]\n{}",
        cube("[integrator]\nmethod = \"newton\"\n[run]\nresidual_tol = 1e-10\n")
    );
    let s = crate::runner::run_static(
        &parse(&statics).unwrap(),
        RunOptions {
            out_dir: Some(dir.path().join("s")),
            ..Default::default()
        },
    )
    .unwrap();
    assert!(s.converged(), "{s}");
    let ud = nodal_stress(&dir.path().join("d"), 3);
    let us = nodal_stress(&dir.path().join("s"), 3);
    let scale = us.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let diff = ud
        .iter()
        .zip(&us)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(diff <= 1e-4 * scale, "{diff:.3e} of {scale:.3e}");
}

#[test]
fn implicit_euler_scenario_preconditions_with_the_multigrid_levels() {
    let sc = parse(&implicit_cube("", "[multigrid]\nlevels = 2\n")).unwrap();
    let mut st = sc.stepper().unwrap();
    assert!(
        st.describe().contains("Galerkin V-cycle over 2 levels"),
        "{}",
        st.describe()
    );
    for _ in 0..3 {
        st.advance().unwrap();
    }
    let direct = parse(&implicit_cube(
        "solver = \"direct\"",
        "[multigrid]\nlevels = 2\n",
    ))
    .unwrap();
    assert!(direct
        .stepper()
        .unwrap()
        .describe()
        .contains("sparse Cholesky"));
}

/// Backward Euler takes a node sliding along a direction that is not x, y or z (the
/// assembled tangent projected onto the plane, [`crate::statics::newton`]): the cube's far
/// corner slides on planes normal to (1, 1, 0), gravity pulls it across them, and after three
/// steps every sliding node still has `u·n` = 0 to 1e-15 of the largest displacement, single
/// level and with the levels as the preconditioner.
#[test]
fn implicit_euler_takes_an_oblique_sliding_plane() {
    let slide = "[[fix]]\nplane = { point = [0.04, 0.02, 0.0], normal = [-1.0, -1.0, 0.0] }\nnormal = [1.0, 1.0, 0.0]\n";
    for levels in ["", "[multigrid]\nlevels = 2\n"] {
        let sc = parse(&implicit_cube("", &format!("{levels}{slide}"))).unwrap();
        let sliding = sc.sliding.clone();
        assert!(sliding.len() >= 4, "{sliding:?}");
        let mut st = sc.stepper().unwrap();
        for _ in 0..3 {
            st.advance().unwrap();
        }
        let u = &st.state().u;
        let scale = u.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
        assert!(scale > 1e-5, "{levels}: the cube should move: {scale:e}");
        let mut across = 0.0f64;
        for &(a, n) in &sliding {
            let i = 3 * a as usize;
            let d = u[i] * n[0] + u[i + 1] * n[1] + u[i + 2] * n[2];
            assert!(d.abs() <= 1e-15 * scale, "{levels}node {a}: u·n = {d:e}");
            across = across.max(u[i].abs());
        }
        assert!(
            across > 1e-3 * scale,
            "{levels}: the corner should slide: {across:e}"
        );
    }
}

#[test]
fn implicit_euler_combinations_that_do_not_apply_name_the_key() {
    let no_dt = cube("[integrator]\nmethod = \"implicit-euler\"\n[run]\nduration = 0.1\n");
    let cases = [
        (
            no_dt,
            "`integrator.dt` is required with method = \"implicit-euler\"",
        ),
        (
            implicit_cube("solver = \"krylov\"", ""),
            "`integrator.solver` = \"krylov\" does not apply to method = \"implicit-euler\"",
        ),
        (
            implicit_cube("solver = \"multigrid\"", ""),
            "`integrator.solver` = \"multigrid\" needs the coarser levels",
        ),
        (
            implicit_cube("", "[multigrid]\nlevels = 2\nscheme = \"fas\"\n"),
            "`multigrid.scheme` does not apply to method = \"implicit-euler\"",
        ),
        (
            implicit_cube("increments = 2", ""),
            "`integrator.increments` applies to method = \"newton\"",
        ),
        (
            implicit_cube("safety = 0.5", ""),
            "`integrator.safety` does not apply to method = \"implicit-euler\"",
        ),
        (
            implicit_cube("max_newton = 0", ""),
            "`integrator.max_newton` = 0",
        ),
        (
            implicit_cube("newton_tol = -1.0", ""),
            "`integrator.newton_tol` = -1",
        ),
        (
            cube("[integrator]\nmethod = \"rk4\"\nnewton_tol = 1e-6\n[run]\nduration = 0.1\n"),
            "`integrator.newton_tol` applies to method = \"implicit-euler\"",
        ),
        (
            cube("[integrator]\nmethod = \"implicit-eulr\"\ndt = 0.01\n[run]\nduration = 0.1\n"),
            "\"implicit-euler\"",
        ),
    ];
    for (text, want) in cases {
        let msg = parse(&text).unwrap_err().to_string();
        assert!(msg.contains(want), "want {want:?} in: {msg}");
    }
}

/// [`implicit_cube`] by BDF2, with `[damping] beta` = `beta` (none where 0).
fn bdf2_cube(beta: f64, extra: &str, tail: &str) -> String {
    let text = implicit_cube(extra, tail).replace("\"implicit-euler\"", "\"bdf2\"");
    if beta > 0.0 {
        text.replace("alpha = 30.0", &format!("alpha = 30.0\nbeta = {beta:e}"))
    } else {
        text
    }
}

#[test]
fn bdf2_scenario_with_stiffness_damping_settles_at_the_static_solution() {
    let sc = parse(&bdf2_cube(2e-3, "", "")).unwrap();
    assert_eq!(sc.method_name(), "bdf2");
    let imp = sc.integrator.implicit.expect("implicit settings");
    assert_eq!(imp.scheme, crate::statics::implicit::ImplicitScheme::Bdf2);
    assert_eq!(imp.beta, 2e-3);
    let st = sc.stepper().unwrap();
    assert!(st.describe().contains("bdf2"), "{}", st.describe());
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
    assert!(
        d.diagnostics
            .as_ref()
            .is_some_and(|(l, x)| *l == "newton" && x.starts_with("BDF2")),
        "{d}"
    );
    let statics = format!(
        "gravity = [0.0, -9.81, 0.0]\n{}",
        cube("[integrator]\nmethod = \"newton\"\n[run]\nresidual_tol = 1e-10\n")
    );
    let s = crate::runner::run_static(
        &parse(&statics).unwrap(),
        RunOptions {
            out_dir: Some(dir.path().join("s")),
            ..Default::default()
        },
    )
    .unwrap();
    assert!(s.converged(), "{s}");
    let ud = nodal_stress(&dir.path().join("d"), 3);
    let us = nodal_stress(&dir.path().join("s"), 3);
    let scale = us.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let diff = ud
        .iter()
        .zip(&us)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(diff <= 1e-4 * scale, "{diff:.3e} of {scale:.3e}");
    // With the levels, as backward Euler.
    let mg = parse(&bdf2_cube(0.0, "", "[multigrid]\nlevels = 2\n")).unwrap();
    let mut st = mg.stepper().unwrap();
    assert!(st.describe().contains("bdf2") && st.describe().contains("Galerkin V-cycle"));
    for _ in 0..3 {
        st.advance().unwrap();
    }
}

#[test]
fn bdf2_and_damping_beta_combinations_that_do_not_apply_name_the_key() {
    let cases = [
        (
            cube("[integrator]\nmethod = \"bdf2\"\n[run]\nduration = 0.1\n"),
            "`integrator.dt` is required with method = \"bdf2\"",
        ),
        (
            bdf2_cube(0.0, "solver = \"krylov\"", ""),
            "`integrator.solver` = \"krylov\" does not apply to method = \"bdf2\"",
        ),
        (
            bdf2_cube(0.0, "safety = 0.5", ""),
            "`integrator.safety` does not apply to method = \"bdf2\"",
        ),
        (
            bdf2_cube(0.0, "", "[multigrid]\nlevels = 2\nscheme = \"fas\"\n"),
            "`multigrid.scheme` does not apply to method = \"bdf2\"",
        ),
        (
            cube("[damping]\nbeta = 1e-3\n[integrator]\nmethod = \"rk4\"\n[run]\nduration = 0.1\n"),
            "`damping.beta` (stiffness-proportional damping) applies to method = \"implicit-euler\" or \"bdf2\", not \"rk4\"",
        ),
        (
            cube("[damping]\nbeta = 1e-3\n[integrator]\nmethod = \"newton\"\n"),
            "not \"newton\"",
        ),
        (
            cube("[damping]\nbeta = 1e-3\n[run]\nduration = 0.1\n"),
            "not \"symplectic-euler\"",
        ),
        (
            bdf2_cube(-1.0, "", "").replace("alpha = 30.0", "alpha = 30.0\nbeta = -1.0"),
            "`damping.beta` = -1: must be >= 0 (s)",
        ),
        (
            cube("[integrator]\nmethod = \"rk4\"\nmax_newton = 3\n[run]\nduration = 0.1\n"),
            "\"implicit-euler\" or \"bdf2\"",
        ),
    ];
    for (text, want) in cases {
        let msg = parse(&text).unwrap_err().to_string();
        assert!(msg.contains(want), "want {want:?} in: {msg}");
    }
    // β = 0 is no damping, accepted with every method.
    parse(&cube(
        "[damping]\nbeta = 0.0\n[integrator]\nmethod = \"rk4\"\n[run]\nduration = 0.1\n",
    ))
    .unwrap();
}
