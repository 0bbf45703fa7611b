//! What `raisov` leaves in its output directory, tested on the built binary: a rerun that is
//! killed or diverges leaves no older results beside its own and no temporary files stay;
//! symbolic links there are not written through; a full disk stops a run with whole rows and
//! says what was kept; names that become file names follow one rule.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn raisov() -> Command {
    Command::new(env!("CARGO_BIN_EXE_raisov"))
}

/// The rule every name is held to, as the errors state it.
const RULE: &str = "a name has 1 to 100 characters, each an ASCII letter, a digit, `-`, `_` or `.`";

/// A process id above Linux's largest (2^22): names no process.
const DEAD_PID: u32 = 4_194_304 + 11;

/// A small membrane lift (120 nodes) at `dir/NAME.toml`; `run` and `extra` are appended to
/// `[run]` and `[output]` (`frame_interval = 0.002` unless `extra` sets it), `top` before
/// `[mesh]`.
fn scenario(dir: &Path, name: &str, top: &str, run: &str, extra: &str) -> PathBuf {
    let p = dir.join(format!("{name}.toml"));
    std::fs::write(
        &p,
        format!(
            r#"{top}
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
{frames}
{extra}
"#,
            frames = if extra.contains("frame_interval") {
                ""
            } else {
                "frame_interval = 0.002"
            }
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

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn csv_rows(out: &Path) -> usize {
    std::fs::read_to_string(out.join("measures.csv"))
        .map(|t| t.lines().count().saturating_sub(1))
        .unwrap_or(0)
}

/// Every file under `dir` named as raisov's temporary files are, `.NAME.PID.N.tmp`.
fn temporaries(dir: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            if p.is_dir() {
                stack.push(p);
            } else if name.starts_with('.')
                && name.ends_with(".tmp")
                && name.split('.').count() >= 5
            {
                found.push(p);
            }
        }
    }
    found
}

/// A run killed by SIGKILL after it wrote `rows` rows.
fn run_killed(p: &Path, out: &Path, rows: usize) {
    let mut child = raisov()
        .args(["run", "--quiet", "--out"])
        .arg(out)
        .arg(p)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while csv_rows(out) < rows {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "no rows after 60 s"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    child.kill().unwrap();
    child.wait().unwrap();
}

/// A rerun into a directory that holds a finished run's results: killed by SIGKILL, or
/// diverging, it left the older `summary.txt` and `nodal_stress.csv` beside its own measures,
/// and 0-byte temporary files of killed runs piled up. Now a run removes the previous results
/// and the leftover temporaries at its start (and nothing else).
#[test]
fn rerun_killed_or_diverging_leaves_no_stale_summary_or_temporaries() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    // Three scenario files of one name: their frames and collections share names.
    let top = "name = \"stale\"";
    let short = scenario(dir.path(), "short", top, "duration = 0.002", "");
    let o = run(&short, &out);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(out.join("summary.txt").is_file() && out.join("nodal_stress.csv").is_file());
    // Leftovers of killed writers (0 bytes, as SIGKILL leaves them), and user files that look
    // alike but are not raisov's.
    let leftovers = [
        out.join(format!(".summary.txt.{DEAD_PID}.0.tmp")),
        out.join(format!("frames/.stale_000009.vtu.{DEAD_PID}.4.tmp")),
        out.join(format!(".nodal_stress.csv.{DEAD_PID}.1.tmp")),
    ];
    let users = [
        out.join("keep.tmp"),
        out.join(".mine.tmp"),
        out.join("notes.txt"),
    ];
    for f in leftovers.iter().chain(&users) {
        std::fs::write(f, "").unwrap();
    }

    // Killed: no summary or nodal stress of the earlier run stays beside the new measures.
    let long = scenario(dir.path(), "long", top, "duration = 1000.0", "");
    run_killed(&long, &out, 20);
    assert!(!out.join("summary.txt").exists(), "stale summary.txt");
    assert!(
        !out.join("nodal_stress.csv").exists(),
        "stale nodal_stress.csv"
    );
    for f in &leftovers {
        assert!(!f.exists(), "{} stayed", f.display());
    }

    // Diverging: the same.
    std::fs::write(out.join("summary.txt"), "an older summary").unwrap();
    std::fs::write(out.join("nodal_stress.csv"), "an older stress").unwrap();
    let diverging = scenario(
        dir.path(),
        "diverging",
        top,
        "duration = 5.0",
        "[integrator]\nmethod = \"symplectic-euler\"\ndt = 0.01",
    );
    let o = run(&diverging, &out);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("diverged at t = "), "{}", stderr(&o));
    assert!(!out.join("summary.txt").exists(), "stale summary.txt");
    assert!(
        !out.join("nodal_stress.csv").exists(),
        "stale nodal_stress.csv"
    );
    assert!(csv_rows(&out) >= 1);

    // Reruns killed again and again: after the next run no temporary file stays.
    for _ in 0..3 {
        run_killed(&long, &out, 5);
    }
    let o = run(&short, &out);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(temporaries(&out), Vec::<PathBuf>::new());
    for f in &users {
        assert!(f.exists(), "{} was removed", f.display());
    }
    let summary = std::fs::read_to_string(out.join("summary.txt")).unwrap();
    assert!(
        summary.contains("reached the requested duration"),
        "{summary}"
    );
}

/// A symbolic link planted at `measures.csv` or at the `.pvd` redirected the run's writes to
/// its target. Now the run refuses before writing, naming the link, and the target is
/// untouched; the output directory itself may be a link.
#[cfg(unix)]
#[test]
fn symlinked_measures_or_pvd_is_refused_and_its_target_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let p = scenario(dir.path(), "linked", "", "duration = 0.002", "");
    let target = dir.path().join("precious.txt");
    std::fs::write(&target, "precious").unwrap();
    for name in ["measures.csv", "linked.pvd", "summary.txt", "frames"] {
        let out = dir.path().join(format!("out-{name}"));
        std::fs::create_dir_all(&out).unwrap();
        std::os::unix::fs::symlink(&target, out.join(name)).unwrap();
        let o = run(&p, &out);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{name}: {err}");
        assert!(
            err.contains(&out.join(name).display().to_string())
                && err.contains("is a symbolic link")
                && err.contains("remove it"),
            "{name}: {err}"
        );
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "precious");
        if name != "measures.csv" {
            assert!(
                !out.join("measures.csv").exists(),
                "{name}: wrote before refusing"
            );
        }
        let left = std::fs::symlink_metadata(out.join(name)).unwrap();
        assert!(
            left.file_type().is_symlink(),
            "{name}: the link was replaced"
        );
    }
    // The directory itself as a link: the user's choice, written through.
    let real = dir.path().join("real");
    std::fs::create_dir_all(&real).unwrap();
    let linked = dir.path().join("linked-out");
    std::os::unix::fs::symlink(&real, &linked).unwrap();
    let o = run(&p, &linked);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(real.join("summary.txt").is_file());
}

/// A full disk cut the last row of `measures.csv` and the run did not say so. Here the file
/// size limit (`RLIMIT_FSIZE`, with SIGXFSZ ignored so that the write fails with `EFBIG` as a
/// full disk fails with `ENOSPC`) stops the writes: the run exits with status 1, names the
/// file and the reason, says how many rows it kept and the last one's step and time, and the
/// file ends with that complete row. No summary claims success.
#[cfg(target_os = "linux")]
#[test]
fn full_disk_stops_the_run_with_whole_rows_and_says_what_was_kept() {
    use std::os::unix::process::CommandExt;
    const LIMIT: u64 = 16 * 1024;
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let p = scenario(
        dir.path(),
        "full",
        "",
        "duration = 1000.0",
        "csv_every = 1\nframe_interval = 1000.0",
    );
    let mut cmd = raisov();
    cmd.args(["run", "--quiet", "--out"]).arg(&out).arg(&p);
    // SAFETY: setrlimit and signal are async-signal-safe; nothing else runs in the child.
    unsafe {
        cmd.pre_exec(|| {
            let lim = libc::rlimit {
                rlim_cur: LIMIT,
                rlim_max: LIMIT,
            };
            if libc::setrlimit(libc::RLIMIT_FSIZE, &lim) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
            Ok(())
        });
    }
    let o = cmd.output().unwrap();
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    let csv_path = out.join("measures.csv");
    assert!(
        err.contains(&csv_path.display().to_string()) && err.contains("File too large"),
        "{err}"
    );
    let csv = std::fs::read_to_string(&csv_path).unwrap();
    assert!(csv.len() as u64 <= LIMIT);
    assert!(
        csv.ends_with('\n'),
        "the last row is cut: {:?}",
        &csv[csv.len() - 80..]
    );
    let lines: Vec<&str> = csv.lines().collect();
    let columns = lines[0].split(',').count();
    assert!(lines.len() > 10, "{} lines", lines.len());
    for l in &lines {
        assert_eq!(l.split(',').count(), columns, "{l}");
    }
    let last: Vec<&str> = lines.last().unwrap().split(',').collect();
    let said = format!(
        "the file keeps its header and {} complete rows, the last with step {}, time_s {}",
        lines.len() - 1,
        last[0],
        last[1]
    );
    assert!(err.contains(&said), "expected `{said}` in: {err}");
    assert!(
        err.contains("the partial row after them was cut off"),
        "{err}"
    );
    assert!(!out.join("summary.txt").exists());
    assert!(!String::from_utf8_lossy(&o.stdout).contains("reached"));
}

/// Names that become file names: `mesh levels --name ../x` wrote outside `--out`, `a/b`
/// failed with an I/O error, `""`, `.` and a newline were accepted, 300 characters failed
/// with status 1. Now one rule, status 2 with the rule stated, for a scenario's `name` and
/// for `mesh levels --name`.
#[test]
fn bad_names_are_refused_with_status_2_and_the_rule() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("tet.obj");
    std::fs::write(
        &obj,
        "v 0 0 0\nv 0.05 0 0\nv 0 0.05 0\nv 0 0 0.05\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
    )
    .unwrap();
    let long = "a".repeat(300);
    let bad = ["../x", "a/b", "", ".", "a\nb", long.as_str()];
    for name in bad {
        let toml_name = name.replace('\n', "\\n");
        let p = scenario(
            dir.path(),
            "named",
            &format!("name = \"{toml_name}\""),
            "duration = 0.002",
            "",
        );
        let out = dir.path().join("run-out");
        for cmd in ["check", "run"] {
            let o = raisov()
                .arg(cmd)
                .args(if cmd == "run" {
                    vec!["--quiet".as_ref(), "--out".as_ref(), out.as_os_str()]
                } else {
                    vec![]
                })
                .arg(&p)
                .output()
                .unwrap();
            let err = stderr(&o);
            assert_eq!(o.status.code(), Some(2), "{cmd} {name:?}: {err}");
            assert!(
                err.contains("named.toml") && err.contains("`name`") && err.contains(RULE),
                "{cmd} {name:?}: {err}"
            );
        }
        let levels_out = dir.path().join("levels").join("out");
        let o = raisov()
            .args(["mesh", "levels", "--levels", "1", "--nodes", "200", "--out"])
            .arg(&levels_out)
            .arg("--name")
            .arg(name)
            .arg(&obj)
            .output()
            .unwrap();
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "levels {name:?}: {err}");
        assert!(
            err.contains("--name") && err.contains(RULE),
            "{name:?}: {err}"
        );
        assert!(!dir.path().join("levels").exists(), "{name:?}: wrote files");
    }
    // A valid name is written where asked.
    let o = raisov()
        .args(["mesh", "levels", "--levels", "1", "--nodes", "200", "--out"])
        .arg(dir.path().join("ok"))
        .args(["--name", "tet-1.v2"])
        .arg(&obj)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(dir.path().join("ok/tet-1.v2_L0.msh").is_file());
}
