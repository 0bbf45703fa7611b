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

/// Timing probe for the T∞ computations on larger meshes (not a check; run by hand).
#[test]
#[ignore]
fn probe_references() {
    for n in [3000usize, 10_000] {
        let case = drape_case(
            MeshDesc::MembraneRatio {
                nodes: n,
                levels: 4,
            },
            "probe",
            1.0,
        );
        let sc = scenario(&case, &Meth::Fas, Step::Safety(0.5)).unwrap();
        let t = std::time::Instant::now();
        let r = reference(&sc, 1000).map(|x| x.1);
        eprintln!("{n}: {r:?} in {:.1} s", t.elapsed().as_secs_f64());
    }
    if let Ok(d) = std::env::var("LIVER_DIR") {
        let files: Vec<String> = ["liver_L0.msh", "liver_L1.msh"]
            .iter()
            .map(|f| format!("{d}/{f}"))
            .collect();
        let case = Case {
            name: "liver".into(),
            mesh: MeshDesc::Files {
                files,
                scale: 0.001,
            },
            top: "gravity = [0.0, 0.0, -9.81]\n".into(),
            physics: format!("{TISSUE_MATERIAL}\n{LIVER_FIX}"),
            duration: 1.0,
        };
        let sc = scenario(&case, &Meth::Fas, Step::Safety(0.5)).unwrap();
        let t = std::time::Instant::now();
        let r = newton_reference(&sc, 1e-8, 8).map(|x| x.1);
        eprintln!("liver: {r:?} in {:.1} s", t.elapsed().as_secs_f64());
    }
}
