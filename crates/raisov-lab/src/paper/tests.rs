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
        equilibrium: false,
    };
    let mut planned = 0;
    let mut done = 0;
    let mut plan = Vec::new();
    let mut sections = Vec::new();
    let res = run_paper(&opts, &mut |p| match p {
        Progress::Planned(n) => planned = n,
        Progress::Plan(p) => plan = p.iter().map(|(n, _)| n.to_string()).collect(),
        Progress::Section { index, of, name } => {
            sections.push(format!("start {index}/{of} {name}"))
        }
        Progress::SectionDone {
            index,
            of,
            name,
            wall,
        } => {
            assert!(wall >= 0.0);
            sections.push(format!("done {index}/{of} {name}"));
        }
        Progress::Done(_) => done += 1,
    })
    .unwrap();
    assert!(planned > 0 && done > 0);
    // Every section is announced before its first run and once more when it ends, in order.
    assert_eq!(plan, SECTIONS);
    let expected: Vec<String> = SECTIONS
        .iter()
        .enumerate()
        .flat_map(|(i, n)| {
            [
                format!("start {}/7 {n}", i + 1),
                format!("done {}/7 {n}", i + 1),
            ]
        })
        .collect();
    assert_eq!(sections, expected);
    assert_eq!(res.stages.len(), SECTIONS.len());
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
    assert!(report.contains("Early regulation and its plateau"));
    assert!(report.contains("RaISoV's switches over the lift"));
    // Every RaISoV lift run counts its switches, each fraction in [0, 1].
    for s in res.lift.iter().filter(|s| s.label.starts_with("RaISoV")) {
        let c = s.switches.expect("RaISoV counts its switches");
        if let Some(f) = c.state_fraction() {
            assert!((0.0..=1.0).contains(&f), "{}: {f}", s.label);
        }
    }
    assert!(res.lift.iter().any(|s| s.switches.is_some()));
    assert!(res.lift[0].switches.is_none(), "SLIM has no switches");
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
    // Section 3.3 with stable neo-Hookean beside the paper's law: SLIM RK4, FAS and RaISoV.
    let stable: Vec<_> = res
        .inversion
        .iter()
        .filter(|r| r.law == "stable-neo-hookean")
        .collect();
    assert_eq!(stable.len(), 3, "{:?}", res.inversion);
    for r in &res.inversion {
        // A neo-Hookean run that survived inverted nothing; every survivor was counted.
        assert_eq!(r.bisection.stable.is_some(), r.end_state.is_some(), "{r:?}");
        if r.law == "neo-hookean" {
            assert!(r.end_state.is_none_or(|e| e.0 == 0 && e.1 > 0.0), "{r:?}");
        }
    }
    let slim = |law: &str| {
        res.inversion
            .iter()
            .find(|r| r.law == law && r.method.starts_with("SLIM"))
            .and_then(|r| r.bisection.stable)
            .unwrap_or(0.0)
    };
    // Inversion does not end a stable neo-Hookean run: single-level integration survives at
    // least the pull that inverts a neo-Hookean element.
    assert!(slim("stable-neo-hookean") >= slim("neo-hookean"));
    let report = std::fs::read_to_string(dir.path().join("report.md")).unwrap();
    assert!(report.contains("| method | law | largest pull survived |"));
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

/// The plateau measure: a curve that decays at 10/s over the first tenth and 1/s after has
/// early rate 10 and late rate 1.
#[test]
fn regulation_rates_of_a_two_rate_decay() {
    let pt = |t: f64, max: f64| experiments::Pt {
        t,
        max,
        mean: max,
        residual: 0.0,
        kinetic: 0.0,
        evals: 0.0,
        wall: 0.0,
    };
    let points = (0..=100)
        .map(|k| {
            let t = k as f64 * 0.01;
            let m = if t <= 0.1 {
                (-10.0 * t).exp()
            } else {
                (-1.0f64).exp() * (-(t - 0.1)).exp()
            };
            pt(t, m)
        })
        .collect();
    let sim = experiments::Sim {
        label: "x".into(),
        dt: 0.01,
        points,
        outcome: experiments::Outcome::Completed,
        reached: None,
        residual_drop: 1.0,
        switches: None,
    };
    let (early, late) = report::regulation_rates(&sim).unwrap();
    assert!((early - 10.0).abs() < 1e-6, "{early}");
    assert!((late - 1.0).abs() < 1e-6, "{late}");
}

/// The default run's estimate, said up front, keeps the paper's own experiments (sections
/// 1-6) and section 7's quick cases within 10 minutes; the five-solver race on every case is
/// asked for (`--equilibrium`) and estimated apart.
#[test]
fn paper_default_run_is_estimated_within_ten_minutes() {
    let mut opts = PaperOptions {
        out_dir: PathBuf::from("unused"),
        quick: false,
        tiny: false,
        meshes_dir: Some(PathBuf::from("data")),
        slim_cap: None,
        equilibrium: false,
    };
    let total = |o: &PaperOptions| estimate(o).iter().map(|(_, t)| t).sum::<f64>();
    let names: Vec<&str> = estimate(&opts).iter().map(|(n, _)| *n).collect();
    assert_eq!(names, SECTIONS);
    assert!(total(&opts) <= 600.0, "{}", total(&opts));
    assert!(estimate(&opts).iter().all(|(_, t)| *t > 0.0));
    let default_eq = estimate(&opts)[6].1;
    opts.equilibrium = true;
    assert!(estimate(&opts)[6].1 > default_eq);
    opts.equilibrium = false;
    opts.quick = true;
    assert!(total(&opts) < 300.0, "{}", total(&opts));
}
