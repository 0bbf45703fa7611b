//! The closed-surface check from the command line, on the built binary: `raisov mesh info` on
//! the cones `raisov bench surface-check --write-mesh` writes (fans of long thin triangles),
//! valid and folded, and the bench's table.

use std::process::Command;

fn raisov() -> Command {
    Command::new(env!("CARGO_BIN_EXE_raisov"))
}

/// `raisov bench surface-check --quick --write-mesh DIR`: the 2k- and 8k-triangle cones.
fn write_cones(dir: &std::path::Path) {
    let out = raisov()
        .args(["bench", "surface-check", "--quick", "--write-mesh"])
        .arg(dir)
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
}

#[test]
fn mesh_info_accepts_a_cone_of_fans_and_names_the_triangles_of_a_folded_one() {
    let dir = tempfile::tempdir().unwrap();
    write_cones(dir.path());
    let cone = dir.path().join("cone_8000.obj");
    let out = raisov().args(["mesh", "info"]).arg(&cone).output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{out:?}");
    assert!(stdout.contains("triangles       8000"), "{stdout}");
    assert!(
        stdout.contains("closed/manifold yes (no degenerate triangle, no self-intersection"),
        "{stdout}"
    );

    // Rim vertex 1000 (the file's vertex line 1003: apex, centre, then the rim) moved onto
    // the rim between rim vertices 1002 and 1003: the fans fold over themselves.
    let text = std::fs::read_to_string(&cone).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let point = |l: &str| -> [f64; 3] {
        let v: Vec<f64> = l
            .split_whitespace()
            .skip(1)
            .map(|x| x.parse().unwrap())
            .collect();
        [v[0], v[1], v[2]]
    };
    let (a, b) = (point(&lines[2 + 1002]), point(&lines[2 + 1003]));
    let r = point(&lines[2 + 1000])
        .iter()
        .map(|c| c * c)
        .sum::<f64>()
        .sqrt();
    let m = [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
    let s = r / m.iter().map(|c| c * c).sum::<f64>().sqrt();
    lines[2 + 1000] = format!("v {:e} {:e} {:e}", m[0] * s, m[1] * s, m[2] * s);
    let folded = dir.path().join("folded.obj");
    std::fs::write(&folded, lines.join("\n")).unwrap();
    let out = raisov()
        .args(["mesh", "info"])
        .arg(&folded)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    assert!(stderr.contains("folded.obj"), "{stderr}");
    assert!(stderr.contains("self-intersection: triangles "), "{stderr}");
    assert!(stderr.contains(" intersect"), "{stderr}");
}

#[test]
fn bench_surface_check_prints_the_work_of_each_case() {
    let out = raisov()
        .args(["bench", "surface-check", "--quick", "--case", "cone 2k"])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{out:?}");
    let row = stdout
        .lines()
        .find(|l| l.starts_with("| cone 2k | 2000 |"))
        .unwrap_or_else(|| panic!("no row for the cone: {stdout}"));
    assert!(row.ends_with("| ok |"), "{row}");
    // Candidates: about one per edge, far below the 1e6 pairs of the two fans.
    let cells: Vec<&str> = row.split('|').map(str::trim).collect();
    let candidates: u64 = cells[5].parse().unwrap();
    assert!(candidates > 0 && candidates < 20_000, "{row}");

    let out = raisov()
        .args(["bench", "surface-check", "--quick", "--case", "nothing"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    assert!(String::from_utf8_lossy(&out.stderr).contains("valid: cone 2k, cone 8k"));
}
