//! How `raisov serve` starts, tested on the built binary: whatever stops it before it serves
//! is bad input (status 2, the reason named), and a server exposed beyond loopback says so
//! and prints the token its URL carries.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn raisov() -> Command {
    Command::new(env!("CARGO_BIN_EXE_raisov"))
}

/// A 2 cm cube fixed at its base, one level: starts in well under a second.
fn cube(dir: &Path) -> std::path::PathBuf {
    let p = dir.join("cube.toml");
    std::fs::write(
        &p,
        r#"
[mesh]
generate = "box"
size = [0.02, 0.02, 0.02]
divisions = [2, 2, 2]
[material]
law = "neo-hookean"
young = 5e3
poisson = 0.45
[[fix]]
plane = { point = [0, 0, 0], normal = [0, 0, 1] }
[run]
duration = 1.0
"#,
    )
    .unwrap();
    p
}

/// Exit status and stderr of `raisov serve ARGS` that must fail before serving.
fn refused(args: &[&str]) -> (Option<i32>, String) {
    let out = raisov()
        .arg("serve")
        .args(args)
        .stdin(Stdio::null())
        .output()
        .unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn serve_startup_errors_are_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = cube(dir.path());
    let scenario = scenario.to_str().unwrap();
    let missing = dir.path().join("missing.toml");
    let (code, err) = refused(&[missing.to_str().unwrap(), "--port", "0"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("missing.toml"), "{err}");
    let weird = dir.path().join("organ.xyz");
    std::fs::write(&weird, "x").unwrap();
    let (code, err) = refused(&[weird.to_str().unwrap(), "--port", "0"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains(".toml") && err.contains(".obj"), "{err}");
    // A port that is taken.
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = taken.local_addr().unwrap().port().to_string();
    let (code, err) = refused(&[scenario, "--port", &port]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("cannot listen on"), "{err}");
    // Frame-rate caps that are not one.
    for bad in ["--max-fps=-1", "--max-fps=NaN", "--max-fps=inf"] {
        let (code, err) = refused(&[scenario, "--port", "0", bad]);
        assert_eq!(code, Some(2), "{bad}: {err}");
        assert!(
            err.contains("--max-fps") && err.contains("0 (no cap) or more"),
            "{err}"
        );
    }
    let (code, err) = refused(&[scenario, "--port", "0", "--token", "short"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("--token") && err.contains("16 to 128"),
        "{err}"
    );
    let (code, err) = refused(&[scenario, "--port", "0", "--method", "fast"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("fas, raisov, single"), "{err}");
}

#[test]
fn serve_beyond_loopback_warns_and_prints_its_token() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = cube(dir.path());
    let mut child = raisov()
        .args(["serve", "--host", "0.0.0.0", "--port", "0"])
        .arg(&scenario)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let stdout = child.stdout.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let mut text = String::new();
    let start = Instant::now();
    while !text.contains("open http") && start.elapsed() < Duration::from_secs(60) {
        if let Ok(l) = rx.recv_timeout(Duration::from_millis(200)) {
            text.push_str(&l);
            text.push('\n');
        }
    }
    let _ = child.kill();
    let _ = child.wait();
    assert!(
        text.contains("warning: listening on 0.0.0.0") && text.contains("has the token"),
        "{text}"
    );
    let url = text
        .lines()
        .find_map(|l| l.strip_prefix("open "))
        .expect("the URL");
    let token = url
        .split_whitespace()
        .next()
        .and_then(|u| u.split_once("?token="))
        .map(|(_, t)| t)
        .expect("a token in the URL");
    assert_eq!(token.len(), 32, "{url}");
    assert!(token.bytes().all(|b| b.is_ascii_hexdigit()), "{url}");
}
