//! The static solve of a scenario (`method = "newton"`): its equilibrium against the dynamic
//! run's, the three solvers on one equilibrium, a pull in one increment, and the Newton
//! settings' defaults and errors.

use super::*;

/// `method = "newton"` solves the static problem the dynamic run settles to: a membrane
/// whose centre is lifted 1 cm, against FAS run to steady state. The lifted node's reaction
/// agrees to 1e-5 relative, the displacements to 1e-7 m, and the reactions balance.
#[test]
fn newton_static_solve_matches_the_steady_dynamic_run() {
    let lift = "[[displace]]\npoint = [0.0, 0.0, 0.0]\ndisplacement = [0.0, 0.0, 0.01]\n";
    let dynamic = format!(
        "{}{lift}[damping]\nratio = 1.0\nomega = 177.7\n[multigrid]\nlevels = 3\n",
        BASE.replace(
            "duration = 0.01",
            "stop = \"steady\"\nduration = 2.0\nkinetic_tol = 1e-16\nresidual_tol = 1e-10"
        )
    );
    let statics = format!(
        "{}{lift}[integrator]\nmethod = \"newton\"\n",
        BASE.replace("duration = 0.01", "residual_tol = 1e-9")
    );
    let dir = tempfile::tempdir().unwrap();
    let opts = |sub: &str| RunOptions {
        out_dir: Some(dir.path().join(sub)),
        ..Default::default()
    };
    let d = run(&parse(&dynamic).unwrap(), opts("d")).unwrap();
    assert_eq!(d.reason, StopReason::Steady, "{d}");
    let sc = parse(&statics).unwrap();
    let s = crate::runner::run_static(&sc, opts("s")).unwrap();
    assert!(s.converged(), "{s}");
    let text = s.to_string();
    assert!(
        text.contains("converged") && text.contains("newton steps"),
        "{text}"
    );
    let (rd, rs) = (d.last.reaction_prescribed, s.last.reaction_prescribed);
    assert!(
        rs[2] > 0.0,
        "the membrane pulls the lifted node down: {rs:?}"
    );
    for k in 0..3 {
        assert!((rd[k] - rs[k]).abs() <= 1e-5 * rs[2], "{rd:?} vs {rs:?}");
        let gap = s.last.reaction_fixed[k] + rs[k] + s.applied[k];
        assert!(gap.abs() <= 1e-6 * rs[2], "balance {k}: {gap:e}");
    }
    let read = |sub: &str| nodal_stress(&dir.path().join(sub), 3);
    for (a, b) in read("d").iter().zip(read("s")) {
        assert!((a - b).abs() <= 1e-7, "{a} vs {b}");
    }
    // A static solve is told apart from a dynamic one's settings.
    let e = error_of(&format!("{statics}[interactive]\n"));
    assert!(e.contains("does not apply to method = \"newton\""), "{e}");
    let e = error_of(&format!("{BASE}[integrator]\nincrements = 3\n"));
    assert!(e.contains("applies to method = \"newton\""), "{e}");
    let e = error_of(&format!(
        "{statics}[multigrid]\nlevels = 2\nscheme = \"fas\"\n"
    ));
    assert!(
        e.contains("`multigrid.scheme` does not apply to method = \"newton\""),
        "{e}"
    );
    let e = error_of(&format!("{BASE}[integrator]\nsolver = \"direct\"\n"));
    assert!(
        e.contains("`integrator.solver` applies to method = \"newton\""),
        "{e}"
    );
    let e = error_of(&format!(
        "{BASE}[integrator]\nsmoother = \"block-jacobi\"\n"
    ));
    assert!(
        e.contains("`integrator.smoother` applies to method = \"newton\""),
        "{e}"
    );
}

/// `[integrator] solver`: the three static solvers land on one equilibrium of the lifted
/// membrane (reactions within 1e-9 of the lift's, nodal stresses within 1e-9 of their
/// largest), and `"auto"` takes `"multigrid"` with `[multigrid]` levels, `"direct"` without.
#[test]
fn static_solvers_reach_one_equilibrium() {
    let lift = "[[displace]]\npoint = [0.0, 0.0, 0.0]\ndisplacement = [0.0, 0.0, 0.01]\n";
    let base = BASE.replace("duration = 0.01", "residual_tol = 1e-10");
    let text = |solver: &str, levels: bool| {
        let (solver, extra) = solver.split_once('+').unwrap_or((solver, ""));
        format!(
            "{base}{lift}[integrator]\nmethod = \"newton\"\n{extra}{}{}",
            if solver.is_empty() {
                String::new()
            } else {
                format!("solver = \"{solver}\"\n")
            },
            if levels {
                "[multigrid]\nlevels = 3\n"
            } else {
                ""
            }
        )
    };
    let dir = tempfile::tempdir().unwrap();
    let solve = |solver: &str, levels: bool| {
        let sc = parse(&text(solver, levels)).unwrap();
        let sub = format!("{solver}-{levels}");
        let s = crate::runner::run_static(
            &sc,
            RunOptions {
                out_dir: Some(dir.path().join(&sub)),
                ..Default::default()
            },
        )
        .unwrap();
        assert!(s.converged(), "{s}");
        let stress = nodal_stress(&dir.path().join(&sub), 12);
        (s, stress)
    };
    let (krylov, t_k) = solve("krylov", false);
    assert_eq!(krylov.solver, StaticSolver::Krylov);
    let (direct, t_d) = solve("", false);
    assert_eq!(direct.solver, StaticSolver::Direct, "{direct}");
    assert_eq!(direct.increments, 1);
    let (mg, t_m) = solve("", true);
    assert_eq!(mg.solver, StaticSolver::Multigrid, "{mg}");
    assert!(
        mg.to_string()
            .contains("CG preconditioned by a Galerkin V-cycle"),
        "{mg}"
    );
    // The coarse start (nested iteration): the default on this membrane; and without it.
    assert!(
        mg.to_string().contains("coarse start: ")
            && mg.to_string().contains("Newton iterations on "),
        "{mg}"
    );
    let (cold, t_c) = solve("+coarse_start = false\n", true);
    assert_eq!(cold.solver, StaticSolver::Multigrid, "{cold}");
    assert!(!cold.to_string().contains("coarse start"), "{cold}");
    // `[integrator] smoother`: coloured block Gauss-Seidel by default on a membrane; the
    // other two land on the same equilibrium.
    assert!(
        mg.to_string()
            .contains("coloured block Gauss-Seidel smoothing"),
        "{mg}"
    );
    let (jacobi, t_j) = solve("+smoother = \"block-jacobi\"\n", true);
    assert!(
        jacobi.to_string().contains("block Jacobi smoothing"),
        "{jacobi}"
    );
    let (point, t_p) = solve("+smoother = \"gauss-seidel\"\n", true);
    assert!(
        point.to_string().contains("point Gauss-Seidel smoothing"),
        "{point}"
    );
    let scale = krylov.last.reaction_prescribed[2];
    assert!(scale > 0.0, "{krylov}");
    let smax = t_k.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    for (name, s, t) in [
        ("direct", &direct, &t_d),
        ("multigrid", &mg, &t_m),
        ("multigrid from rest", &cold, &t_c),
        ("multigrid, block Jacobi", &jacobi, &t_j),
        ("multigrid, point Gauss-Seidel", &point, &t_p),
    ] {
        for k in 0..3 {
            let (a, b) = (
                krylov.last.reaction_prescribed[k],
                s.last.reaction_prescribed[k],
            );
            assert!(
                (a - b).abs() <= 1e-9 * scale,
                "{name} reaction {k}: {a:e} vs {b:e}"
            );
            // Equilibrium: the fixed and prescribed reactions balance (no loads).
            let gap = s.last.reaction_fixed[k] + s.last.reaction_prescribed[k] + s.applied[k];
            assert!(gap.abs() <= 1e-9 * scale, "{name} balance {k}: {gap:e}");
        }
        assert_eq!(t.len(), t_k.len());
        let worst = t
            .iter()
            .zip(&t_k)
            .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
        assert!(
            worst <= 1e-9 * smax,
            "{name}: stress off by {worst:e} of {smax:e}"
        );
    }
    // Asked for where it cannot run: a clear error naming the key.
    let e = error_of(&text("multigrid", false));
    assert!(
        e.contains("needs the coarser levels of a `[multigrid]` section"),
        "{e}"
    );
    let e = error_of(&text("direct+coarse_start = true\n", true));
    assert!(
        e.contains("`integrator.coarse_start` = true applies to solver = \"multigrid\""),
        "{e}"
    );
    let e = error_of(&text("direct+smoother = \"block-jacobi\"\n", true));
    assert!(
        e.contains("`integrator.smoother` applies to solver = \"multigrid\""),
        "{e}"
    );
    let e = error_of(&text("+smoother = \"jacobi\"\n", true));
    assert!(
        e.contains("integrator.smoother")
            && e.contains("\"block-jacobi\"")
            && e.contains("\"gauss-seidel\""),
        "{e}"
    );
}

/// A node sliding along a direction that is not x, y or z no longer sends `solver = "auto"`
/// to Newton-Krylov: the cube's far corner slides on planes normal to (1, 1, 0) under
/// gravity across them; "auto" takes "direct" (and "multigrid" with levels), and both land on
/// Newton-Krylov's equilibrium: the supports' reaction within 1e-9 of the weight, balancing
/// it to 1e-9, the nodal displacements and stresses within 1e-9 of the largest.
#[test]
fn oblique_sliding_takes_the_assembled_solvers() {
    let slide = "[[fix]]\nplane = { point = [0.04, 0.02, 0.0], normal = [-1.0, -1.0, 0.0] }\nnormal = [1.0, 1.0, 0.0]\n";
    let text = |solver: &str, levels: &str| {
        format!(
            "gravity = [0.0, -9.81, 0.0]\n{}",
            cube(&format!(
                "{slide}[integrator]\nmethod = \"newton\"\n{solver}\n[run]\nresidual_tol = 1e-10\n{levels}"
            ))
        )
    };
    let dir = tempfile::tempdir().unwrap();
    let solve = |name: &str, solver: &str, levels: &str| {
        let sc = parse(&text(solver, levels)).unwrap();
        let s = crate::runner::run_static(
            &sc,
            RunOptions {
                out_dir: Some(dir.path().join(name)),
                ..Default::default()
            },
        )
        .unwrap();
        assert!(s.converged(), "{name}: {s}");
        (s, nodal_stress(&dir.path().join(name), 12))
    };
    let (krylov, t_k) = solve("krylov", "solver = \"krylov\"", "");
    assert_eq!(krylov.solver, StaticSolver::Krylov);
    let (direct, t_d) = solve("direct", "", "");
    assert_eq!(direct.solver, StaticSolver::Direct, "{direct}");
    let (mg, t_m) = solve("multigrid", "", "[multigrid]\nlevels = 2\n");
    assert_eq!(mg.solver, StaticSolver::Multigrid, "{mg}");
    let weight = krylov.applied[1].abs();
    assert!(weight > 0.0, "{krylov}");
    let umax = t_k
        .chunks(12)
        .flat_map(|c| &c[..3])
        .fold(0.0f64, |a, x| a.max(x.abs()));
    let smax = t_k
        .chunks(12)
        .flat_map(|c| &c[3..])
        .fold(0.0f64, |a, x| a.max(x.abs()));
    for (name, s, t) in [("direct", &direct, &t_d), ("multigrid", &mg, &t_m)] {
        for k in 0..3 {
            let (a, b) = (krylov.last.reaction_fixed[k], s.last.reaction_fixed[k]);
            assert!(
                (a - b).abs() <= 1e-9 * weight,
                "{name} reaction {k}: {a:e} vs {b:e}"
            );
            let gap = s.last.reaction_fixed[k] + s.applied[k];
            assert!(gap.abs() <= 1e-9 * weight, "{name} balance {k}: {gap:e}");
        }
        for (x, y) in t.chunks(12).zip(t_k.chunks(12)) {
            for k in 0..12 {
                let bound = if k < 3 { umax } else { smax };
                assert!(
                    (x[k] - y[k]).abs() <= 1e-9 * bound,
                    "{name} field {k}: {} vs {}",
                    x[k],
                    y[k]
                );
            }
        }
    }
}

/// A static pull that inverts the elements around its node when imposed alone (the rest of
/// the beam at rest), with no load: the default one increment takes it (the solver's lifted
/// first iteration), against a stopping target scaled by the pull's extrapolated
/// out-of-balance force (not the bare 1e-14 N floor, which nothing reaches), and lands on the
/// equilibrium of eight increments: the pulled node's reaction within 1e-8, balanced by the
/// fixed end's.
#[test]
fn static_pull_that_inverts_when_imposed_alone_converges_in_one_increment() {
    let text = |increments: usize| {
        format!(
            r#"
[mesh]
generate = "box"
size = [0.1, 0.03, 0.03]
nodes = 300
[material]
law = "neo-hookean"
young = 5000.0
poisson = 0.45
density = 1060.0
[[fix]]
plane = {{ point = [0.0, 0.0, 0.0], normal = [1.0, 0.0, 0.0] }}
[[displace]]
point = [0.1, 0.03, 0.03]
displacement = [0.0, -0.015, 0.0]
[integrator]
method = "newton"
solver = "direct"
{}
[run]
residual_tol = 1e-11
"#,
            if increments == 1 {
                String::new()
            } else {
                format!("increments = {increments}")
            }
        )
    };
    let dir = tempfile::tempdir().unwrap();
    let solve = |increments: usize| {
        let sc = parse(&text(increments)).unwrap();
        crate::runner::run_static(
            &sc,
            RunOptions {
                out_dir: Some(dir.path().join(increments.to_string())),
                ..Default::default()
            },
        )
        .unwrap()
    };
    let one = solve(1);
    let eight = solve(8);
    assert_eq!(one.increments, 1);
    assert!(one.converged(), "{one}");
    assert!(eight.converged(), "{eight}");
    let target = one.target.unwrap();
    assert!(target > 1e-12, "target {target:e} N is the bare floor");
    let scale = eight.last.reaction_prescribed[1].abs();
    assert!(scale > 0.0, "{eight}");
    for k in 0..3 {
        let (a, b) = (
            one.last.reaction_prescribed[k],
            eight.last.reaction_prescribed[k],
        );
        assert!(
            (a - b).abs() <= 1e-8 * scale,
            "reaction {k}: {a:e} vs {b:e}"
        );
        let gap = one.last.reaction_fixed[k] + a;
        assert!(
            gap.abs() <= 1e-8 * scale,
            "balance {k}: {gap:e} of {scale:e}, {one}"
        );
    }
}

/// `[integrator] smoother` defaults by element kind: block Jacobi on tetrahedra, coloured
/// block Gauss-Seidel on membranes; a value given is taken as given.
#[test]
fn newton_smoother_defaults_by_element_kind() {
    use crate::linalg::smoother::Smoother;
    let cube = |extra: &str| cube(&format!("[integrator]\nmethod = \"newton\"\n{extra}"));
    let smoother = |text: &str| parse(text).unwrap().integrator.statics.unwrap().smoother;
    assert_eq!(smoother(&cube("")), Smoother::BlockJacobi);
    assert_eq!(
        smoother(&cube("smoother = \"gauss-seidel\"")),
        Smoother::GaussSeidel
    );
    let membrane = BASE.replace("duration = 0.01", "residual_tol = 1e-8");
    assert_eq!(
        smoother(&format!("{membrane}[integrator]\nmethod = \"newton\"\n")),
        Smoother::ColouredBlock
    );
    assert_eq!(
        smoother(&format!(
            "{membrane}[integrator]\nmethod = \"newton\"\nsmoother = \"block-jacobi\"\n"
        )),
        Smoother::BlockJacobi
    );
}
