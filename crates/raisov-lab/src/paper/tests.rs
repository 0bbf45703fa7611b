//! `raisov paper` in a tiny configuration, and the stability bisection on a known threshold.

use super::*;

/// Symplectic Euler on the undamped oscillator ẍ = −ω² x is stable iff dt < 2/ω.
fn oscillator_stable(omega: f64, dt: f64) -> bool {
    let (mut x, mut v) = (1.0f64, 0.0f64);
    for _ in 0..20_000 {
        v -= dt * omega * omega * x;
        x += dt * v;
        if !(x.abs() < 1e6) {
            return false;
        }
    }
    true
}

#[test]
fn bisection_finds_the_symplectic_euler_threshold() {
    let omega = 7.0;
    let b = bisect_stable(0.01, 10.0, 12, |dt| Ok(oscillator_stable(omega, dt))).unwrap();
    let (s, u) = (b.stable.unwrap(), b.unstable.unwrap());
    assert!(s < 2.0 / omega && u > 2.0 / omega, "{s} {u}");
    assert!(u / s < 1.005, "bracket {s}..{u}");
    assert_eq!(b.tests.len(), 14);
    // Out-of-range ends are reported as such.
    let b = bisect_stable(1.0, 10.0, 5, |dt| Ok(oscillator_stable(omega, dt))).unwrap();
    assert_eq!((b.stable, b.unstable), (None, Some(1.0)));
    let b = bisect_stable(0.01, 0.1, 5, |dt| Ok(oscillator_stable(omega, dt))).unwrap();
    assert_eq!((b.stable, b.unstable), (Some(0.1), None));
}

#[test]
fn every_scenario_text_resolves() {
    let lift = lift_case(&[40, 22, 12], 0.03, 0.1);
    for m in [
        Meth::Slim("rk4"),
        Meth::Fas,
        Meth::Raisov {
            reading: "paper",
            epsilon: Some(f64::INFINITY),
            tag: "best",
        },
    ] {
        let sc = scenario(&lift, &m, Step::Safety(0.5)).unwrap();
        assert_eq!(sc.num_levels(), if m.is_multigrid() { 3 } else { 1 });
    }
}

#[test]
fn tiny_paper_run_writes_report_plots_and_csv() {
    let dir = tempfile::tempdir().unwrap();
    let opts = PaperOptions {
        out_dir: dir.path().to_path_buf(),
        quick: true,
        tiny: true,
        meshes_dir: None,
        slim_cap: None,
    };
    let mut planned = 0;
    let mut done = 0;
    let res = run_paper(&opts, &mut |p| match p {
        Progress::Planned(n) => planned = n,
        Progress::Done(_) => done += 1,
    })
    .unwrap();
    assert!(planned > 0 && done > 0);
    for f in [
        "report.md",
        "fig5_left_lift.png",
        "fig5_left_lift.svg",
        "fig5_right_drape.png",
        "fig5_right_drape.svg",
        "time_to_steady.png",
        "time_to_steady.svg",
        "fig5_lift.csv",
        "fig5_drape.csv",
        "stability.csv",
        "inversion.csv",
        "cost.csv",
        "steady_state.csv",
        "eps_sweep.csv",
    ] {
        let p = dir.path().join(f);
        assert!(p.is_file(), "{f} missing");
        assert!(std::fs::metadata(&p).unwrap().len() > 0, "{f} empty");
    }
    let report = std::fs::read_to_string(dir.path().join("report.md")).unwrap();
    assert!(report.contains("| claim | paper | measured | holds? |"));
    assert!(report.contains("liver skipped"));
    for f in ["fig5_lift.csv", "stability.csv", "steady_state.csv"] {
        let t = std::fs::read_to_string(dir.path().join(f)).unwrap();
        for field in t.split([',', '\n']) {
            let x = field.trim().to_ascii_lowercase();
            assert!(
                !matches!(x.as_str(), "nan" | "inf" | "-inf" | "+inf"),
                "{f} has a non-finite field"
            );
        }
    }
    assert!(res.files.iter().all(|f| f.is_file()));
    // No temporary files left behind.
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains("tmp"))
        .collect();
    assert!(leftovers.is_empty());
}

/// Above [`REFERENCE_MAX_NODES`] a membrane's T∞ comes from FAS cycles instead of the
/// Newton-Krylov ladder; both must give the same equilibrium.
#[test]
fn fas_reference_matches_the_newton_ladder() {
    let n = 1500;
    let case = drape_case(
        MeshDesc::MembraneRatio {
            nodes: n,
            levels: deep_levels(n),
        },
        "drape",
        1.0,
    );
    let sc = scenario(&case, &Meth::Fas, Step::Safety(0.5)).unwrap();
    assert_eq!(sc.num_levels(), 2);
    let (t_newton, note) = reference(&sc, 1000).unwrap();
    assert!(note.contains("Newton"), "{note}");
    let (t_fas, note, rel) = fas_reference(&sc, FAS_REFERENCE_TOL, 60.0).unwrap();
    assert!(rel <= FAS_REFERENCE_TOL, "{note}");
    let scale = mean_norm_diff(&t_newton, &vec![0.0; t_newton.len()]);
    assert!(scale > 0.0);
    let d = mean_norm_diff(&t_fas, &t_newton) / scale;
    assert!(
        d < 1e-5,
        "FAS and Newton T_inf differ by {d:.2e} of mean |T_inf|"
    );
}

/// CSV fields holding a comma or a quote are quoted (RFC 4180: inner quotes doubled); method
/// labels such as "RaISoV correction, eps best (1.0e-3 m)" hold commas.
#[test]
fn csv_fields_with_commas_are_quoted() {
    use super::report::q;
    assert_eq!(q("SLIM rk4"), "SLIM rk4");
    assert_eq!(
        q("RaISoV correction, eps best (1.0e-3 m)"),
        "\"RaISoV correction, eps best (1.0e-3 m)\""
    );
    assert_eq!(q("a \"b\""), "\"a \"\"b\"\"\"");
}
