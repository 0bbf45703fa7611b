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
    let imp = sc.implicit.expect("implicit settings");
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
            .as_deref()
            .is_some_and(|x| x.contains("Newton iterations a step")),
        "{d}"
    );
    let statics = format!(
        "gravity = [0.0, -9.81, 0.0]\n{}",
        cube("[integrator]\nmethod = \"newton\"\n[run]\nresidual_tol = 1e-10\n")
    );
    let s = super::run::run_static(
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
