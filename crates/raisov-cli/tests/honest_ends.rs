//! How `raisov run` ends, tested on the built binary: exit codes, real signals, the output
//! lock, bad numbers in a reference file; and `raisov bench equilibrium` without its meshes.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn raisov() -> Command {
    Command::new(env!("CARGO_BIN_EXE_raisov"))
}

/// A small membrane lift (120 nodes); `run` and `extra` are appended.
fn scenario(dir: &Path, name: &str, run: &str, extra: &str) -> PathBuf {
    let p = dir.join(format!("{name}.toml"));
    std::fs::write(
        &p,
        format!(
            r#"
[mesh]
generate = "rectangle"
size = [0.1, 0.1]
nodes = 120
[material]
law = "mooney-rivlin"
c1 = 1000.0
c2 = 1000.0
[damping]
ratio = 1.0
omega = 177.7
[[fix]]
boundary = true
[[displace]]
point = [0.0, 0.0, 0.0]
displacement = [0.0, 0.0, 0.01]
mode = "ramp"
duration = 0.01
[run]
{run}
[output]
frame_interval = 0.002
{extra}
"#
        ),
    )
    .unwrap();
    p
}

fn run(p: &Path, out: &Path) -> Output {
    raisov()
        .args(["run", "--quiet", "--out"])
        .arg(out)
        .arg(p)
        .output()
        .unwrap()
}

/// Every file under `dir` whose name ends in `.tmp`.
fn tmp_files(dir: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.to_string_lossy().ends_with(".tmp") {
                found.push(p);
            }
        }
    }
    found
}

fn csv_rows(out: &Path) -> usize {
    std::fs::read_to_string(out.join("measures.csv"))
        .map(|t| t.lines().count().saturating_sub(1))
        .unwrap_or(0)
}

/// Start a long run, wait until it has written some rows, and send it `signal`; it stops at a
/// step boundary with exit status 130, a summary that says so, its measures and no temp files.
/// While it runs, a second run on the same directory is refused by the lock.
fn interrupt_with(signal: &str) {
    let dir = tempfile::tempdir().unwrap();
    let p = scenario(dir.path(), "long", "duration = 1000.0", "");
    let out = dir.path().join("out");
    let mut child = raisov()
        .args(["run", "--quiet", "--out"])
        .arg(&out)
        .arg(&p)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while csv_rows(&out) < 20 {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "no rows after 60 s"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    // The lock: a second run on the same directory stops at once, naming it.
    let second = run(&p, &out);
    let err = String::from_utf8_lossy(&second.stderr);
    assert_eq!(second.status.code(), Some(1), "{err}");
    assert!(
        err.contains(".raisov.lock") && err.contains(&out.display().to_string()),
        "{err}"
    );
    let status = Command::new("kill")
        .args([signal, &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let start = Instant::now();
    let code = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s.code();
        }
        assert!(start.elapsed() < Duration::from_secs(30), "did not stop");
        std::thread::sleep(Duration::from_millis(20));
    };
    let o = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(code, Some(130), "{stderr}");
    let summary = std::fs::read_to_string(out.join("summary.txt")).unwrap();
    assert!(summary.contains("interrupted"), "{summary}");
    assert!(String::from_utf8_lossy(&o.stdout).contains("interrupted"));
    let rows = csv_rows(&out);
    assert!(rows >= 20, "{rows} rows");
    // The last row is the state the run stopped in, and the PVD is complete.
    let pvd = std::fs::read_to_string(out.join("long.pvd")).unwrap();
    assert!(pvd.trim_end().ends_with("</VTKFile>"), "{pvd}");
    assert!(out.join("nodal_stress.csv").is_file());
    assert_eq!(tmp_files(&out), Vec::<PathBuf>::new());
    // The lock is released: a rerun may write there (and clears the old frames).
    let frames_before = std::fs::read_dir(out.join("frames")).unwrap().count();
    assert!(frames_before > 2);
    let short = scenario(dir.path(), "long", "duration = 0.002", "");
    let o = run(&short, &out);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let frames = std::fs::read_dir(out.join("frames")).unwrap().count();
    let pvd = std::fs::read_to_string(out.join("long.pvd")).unwrap();
    assert_eq!(frames, pvd.matches("<DataSet ").count(), "{pvd}");
    assert!(frames < frames_before, "{frames} of {frames_before}");
}

#[test]
fn sigint_stops_at_a_step_boundary_with_status_130() {
    interrupt_with("-INT");
}

#[test]
fn sigterm_stops_at_a_step_boundary_with_status_130() {
    interrupt_with("-TERM");
}

/// `stop = "steady"` that reaches its cap says so and exits with 3; so does stagnation.
#[test]
fn not_steady_exits_with_3() {
    let dir = tempfile::tempdir().unwrap();
    let p = scenario(dir.path(), "cap", "stop = \"steady\"\nduration = 0.02", "");
    let o = run(&p, &dir.path().join("cap"));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(3), "{err}");
    assert!(err.contains("did not reach steady state"), "{err}");
    let summary = std::fs::read_to_string(dir.path().join("cap/summary.txt")).unwrap();
    assert!(
        summary.contains("did not reach steady state: hit the time cap"),
        "{summary}"
    );
    // An undamped membrane never settles: one check without progress ends it.
    let p = scenario(
        dir.path(),
        "stag",
        "stop = \"steady\"\nduration = 5.0\nstagnation = 1",
        "",
    );
    let text = std::fs::read_to_string(&p)
        .unwrap()
        .replace("ratio = 1.0\nomega = 177.7", "alpha = 0.0");
    std::fs::write(&p, text).unwrap();
    let o = run(&p, &dir.path().join("stag"));
    assert_eq!(o.status.code(), Some(3));
    let summary = std::fs::read_to_string(dir.path().join("stag/summary.txt")).unwrap();
    assert!(summary.contains("no progress in 1 checks"), "{summary}");
}

/// A reference CSV with `nan` is an error of `raisov check` (exit 2) naming file and line.
#[test]
fn nan_in_reference_csv_is_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("ref.csv");
    let mut text = String::from("node,x,y,z,ux,uy,uz,T00,T01,T02,T10,T11,T12,T20,T21,T22\n");
    text.push_str("0,0,0,0,0,0,0,1,0,0,0,1,0,0,0,1\n");
    text.push_str("1,0,0,0,0,0,0,NaN,0,0,0,1,0,0,0,1\n");
    std::fs::write(&csv, text).unwrap();
    let p = scenario(
        dir.path(),
        "nan",
        "duration = 0.01",
        "reference = \"ref.csv\"",
    );
    let o = raisov().arg("check").arg(&p).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("ref.csv, line 3") && err.contains("finite"),
        "{err}"
    );
    // The same for `inf` in the scenario itself.
    let bad = dir.path().join("inf.toml");
    let text = std::fs::read_to_string(&p)
        .unwrap()
        .replace("c2 = 1000.0", "c2 = inf");
    std::fs::write(&bad, text).unwrap();
    let o = raisov().arg("check").arg(&bad).output().unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("finite"));
}

/// `raisov bench equilibrium` without its meshes is bad input (status 2), naming the file.
#[test]
fn bench_equilibrium_without_meshes_is_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let out = raisov()
        .args(["bench", "equilibrium", "--quick", "--meshes"])
        .arg(dir.path().join("none"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("liver_L2.msh"), "{err}");
}

/// The mesh tools on a missing file are bad input (status 2), naming the file and saying the
/// operating system's error once: they exited with status 1 and repeated it.
#[test]
fn mesh_tools_on_a_missing_file_are_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let msh = dir.path().join("none.msh");
    let obj = dir.path().join("none.obj");
    let runs: [Vec<&std::ffi::OsStr>; 3] = [
        vec!["mesh".as_ref(), "info".as_ref(), msh.as_os_str()],
        vec!["mesh".as_ref(), "info".as_ref(), obj.as_os_str()],
        vec![
            "mesh".as_ref(),
            "levels".as_ref(),
            obj.as_os_str(),
            "--out".as_ref(),
            dir.path().as_os_str(),
        ],
    ];
    for args in runs {
        let out = raisov().args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains("none."), "{args:?}: {err}");
        assert_eq!(err.matches("os error").count(), 1, "{args:?}: {err}");
    }
}

/// Arguments a command checks itself are bad input (status 2), as clap's own are: `raisov
/// mesh generate` without `--size`, of an unknown kind or to an unknown format exited with 1.
#[test]
fn mesh_generate_with_bad_arguments_is_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let msh = dir.path().join("m.msh");
    let txt = dir.path().join("m.txt");
    let msh = msh.to_str().unwrap();
    let runs: [(&[&str], &str); 4] = [
        (&["rectangle", "--nodes", "50", "-o", msh], "--size W,H"),
        (&["rectangle", "--size", "1,1", "-o", msh], "--nodes N"),
        (
            &["sphere", "--nodes", "50", "-o", msh],
            "valid are rectangle",
        ),
        (
            &[
                "box",
                "--nodes",
                "50",
                "--size",
                "1,1,1",
                "-o",
                txt.to_str().unwrap(),
            ],
            "must end in .msh",
        ),
    ];
    for (args, want) in runs {
        let out = raisov()
            .args(["mesh", "generate"])
            .args(args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err}");
    }
}

/// `raisov --help` documents the exit codes.
#[test]
fn help_lists_exit_codes() {
    let o = raisov().arg("--help").output().unwrap();
    let text = String::from_utf8_lossy(&o.stdout);
    for want in [
        "Exit status",
        "130",
        "not converged",
        "bad input",
        "diverged",
    ] {
        assert!(text.contains(want), "{want}: {text}");
    }
}

/// SIGKILL cannot be caught: the directory still holds the rows up to the last flushed
/// frame, a complete PVD, and the kernel has dropped the lock, so a rerun may write there.
#[test]
fn sigkill_leaves_rows_up_to_the_last_frame_and_no_lock() {
    let dir = tempfile::tempdir().unwrap();
    let p = scenario(dir.path(), "killed", "duration = 1000.0", "");
    let out = dir.path().join("out");
    let mut child = raisov()
        .args(["run", "--quiet", "--out"])
        .arg(&out)
        .arg(&p)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while csv_rows(&out) < 20 {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "no rows after 60 s"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    child.kill().unwrap();
    let status = child.wait().unwrap();
    assert_eq!(status.code(), None, "killed by a signal");
    let csv = std::fs::read_to_string(out.join("measures.csv")).unwrap();
    assert!(csv.ends_with('\n'), "rows end whole at a flush");
    let rows = csv.lines().count() - 1;
    assert!(rows >= 20, "{rows}");
    let pvd = std::fs::read_to_string(out.join("killed.pvd")).unwrap();
    assert!(pvd.trim_end().ends_with("</VTKFile>"), "{pvd}");
    let short = scenario(dir.path(), "killed", "duration = 0.002", "");
    let o = run(&short, &out);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// `raisov check` of a static scenario says what `raisov run` would solve: the solver as
/// `"auto"` resolves it, the smoother, the coarse start, the increments; no time step. It
/// printed the dynamic integrator and FAS's stepper, which a static solve does not run. The
/// coarse start's levels are named with their node counts (requested, for generated levels).
#[test]
fn check_of_a_static_scenario_names_its_solver_and_smoother() {
    let dir = tempfile::tempdir().unwrap();
    let p = scenario(
        dir.path(),
        "static",
        "residual_tol = 1e-8",
        "[integrator]\nmethod = \"newton\"\nsmoother = \"block-jacobi\"\n[multigrid]\nlevels = 2\n",
    );
    let o = raisov().arg("check").arg(&p).output().unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert_eq!(o.status.code(), Some(0), "{out}");
    assert!(
        out.contains("newton (static equilibrium), solver \"multigrid\"")
            && out.contains("(solver \"auto\")")
            && out.contains("block Jacobi smoothing")
            && out.contains("coarse start yes (through levels 1 (about 60 nodes))")
            && out.contains("1 load increment"),
        "{out}"
    );
    assert!(!out.contains("dt =") && !out.contains("stepping"), "{out}");
}

/// What `raisov serve` records when the same spot is grasped twice: `raisov run` refused
/// it with status 2 (two `[[displace]]` prescribing the same nodes). Grasps taken and let go
/// during the run, by springs, and a pin, run to the end with status 0.
#[test]
fn a_recording_that_grasps_the_same_spot_twice_runs() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("recorded.toml");
    let grasp = |start: f64, release: f64| {
        format!(
            "[[displace]]\npoint = [0.02, 0.02, 0.04]\nradius = 0.011\nstiffness = 200.0\n\
             start = {start}\nrelease = {release}\n\
             table = [[{start}, 0, 0, 0], [{release}, 0.001, 0, 0.003]]\n"
        )
    };
    std::fs::write(
        &p,
        format!(
            "[mesh]\ngenerate = \"box\"\nsize = [0.04, 0.04, 0.04]\ndivisions = [4, 4, 4]\n\
             [material]\nlaw = \"neo-hookean\"\nyoung = 5e3\npoisson = 0.45\n\
             [damping]\nalpha = 50.0\n\
             [[fix]]\nplane = {{ point = [0, 0, 0], normal = [0, 0, 1] }}\n\
             {}{}\
             [[pin]]\npoint = [0.04, 0.04, 0.04]\nradius = 0.011\nstart = 0.5\n\
             [run]\nduration = 0.8\n\
             [interactive]\nfps = 30.0\ncycles = 20\nreference = \"none\"\n",
            grasp(0.1, 0.3),
            grasp(0.4, 0.6)
        ),
    )
    .unwrap();
    let o = run(&p, &dir.path().join("out"));
    let text = String::from_utf8_lossy(&o.stdout);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{text}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(text.contains("frames          24 of 24"), "{text}");
    let o = raisov().arg("check").arg(&p).output().unwrap();
    let text = String::from_utf8_lossy(&o.stdout);
    assert_eq!(text.matches("\ngrasp ").count(), 2, "{text}");
    assert!(
        text.contains("pulled by springs of 200 N/m, let go at 0.3 s")
            && text.contains(
                "\npin           near (0.04, 0.04, 0.04) m, radius 0.011 m, taken at 0.5 s"
            ),
        "{text}"
    );
}
