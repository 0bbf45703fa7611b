//! What a newcomer meets first: the README's "Two commands" against what the repository
//! declares and what the default run prints.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn read(rel: &str) -> String {
    let p = repo().join(rel);
    std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// The README's section under `## title`, up to the next `## `.
fn readme_section(title: &str) -> String {
    let readme = read("README.md");
    let head = format!("## {title}\n");
    let start = readme
        .find(&head)
        .unwrap_or_else(|| panic!("README has no section {head:?}"))
        + head.len();
    let rest = &readme[start..];
    rest[..rest.find("\n## ").unwrap_or(rest.len())].to_string()
}

/// `rust-version = "X"` of the workspace's Cargo.toml.
fn declared_rust_version() -> String {
    let toml = read("Cargo.toml");
    let line = toml
        .lines()
        .find(|l| l.trim_start().starts_with("rust-version"))
        .expect("Cargo.toml declares rust-version");
    line.split('"').nth(1).expect("quoted version").to_string()
}

/// The default run: `raisov run --quiet --out DIR` with no scenario.
fn default_run(out: &Path) -> Output {
    let o = Command::new(env!("CARGO_BIN_EXE_raisov"))
        .args(["run", "--quiet", "--out"])
        .arg(out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    o
}

#[test]
fn readme_rust_version_is_cargo_tomls() {
    let declared = declared_rust_version();
    let section = readme_section("Two commands");
    let said = section
        .split("Rust (")
        .nth(1)
        .and_then(|s| s.split(" or newer)").next())
        .expect("the README's Two commands say \"Rust (X or newer)\"");
    assert_eq!(
        said, declared,
        "README says Rust {said}, Cargo.toml's rust-version is {declared}"
    );
}

#[test]
fn readme_node_counts_are_what_the_default_run_prints() {
    let dir = tempfile::tempdir().unwrap();
    let o = default_run(&dir.path().join("out"));
    let stdout = String::from_utf8(o.stdout).unwrap();
    // "integration     fas multigrid, 4 levels (187/103/55/30 nodes), ..."
    let printed = stdout
        .split("levels (")
        .nth(1)
        .and_then(|s| s.split(" nodes)").next())
        .unwrap_or_else(|| panic!("no level counts in:\n{stdout}"));
    let section = readme_section("Two commands");
    // The first "a/b/c/d nodes" of the section.
    let said = section
        .split(" nodes")
        .find_map(|s| {
            let w = s.rsplit(['(', ' ']).next()?;
            (w.split('/').count() == 4 && w.split('/').all(|n| n.parse::<usize>().is_ok()))
                .then_some(w)
        })
        .expect("the README's Two commands quote the default run's level node counts");
    assert_eq!(
        said, printed,
        "README says {said} nodes, the default run prints {printed}"
    );
}

#[test]
fn default_run_explains_uncovered_levels_once() {
    let dir = tempfile::tempdir().unwrap();
    let o = default_run(&dir.path().join("out"));
    let stderr = String::from_utf8(o.stderr).unwrap();
    assert!(!stderr.contains("hosts do not cover"), "{stderr}");
    assert_eq!(
        stderr.matches("note: levels not covered").count(),
        1,
        "{stderr}"
    );
    // It names the counts per level and says whether to worry.
    assert!(stderr.contains("of level 0's 187 nodes"), "{stderr}");
    assert!(stderr.contains("harmless"), "{stderr}");
    assert!(!stderr.contains("warning"), "{stderr}");
}
