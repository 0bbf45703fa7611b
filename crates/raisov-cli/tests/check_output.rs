//! `raisov check` speaks words: run on every scenario in `examples/` and on scenarios that
//! reach the other materials, motions, schemes and budgets, no line shows one of the
//! library's internal structures (`Some(..)`, `Steady { .. }`, `Duration(1.0)`, `a::b`,
//! `[0.0, 1.0]`), and a few fields read as a user writes them.

use std::path::{Path, PathBuf};
use std::process::Command;

fn examples() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
    let mut v: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    v.sort();
    assert!(v.len() >= 10, "examples/ holds {} scenarios", v.len());
    v
}

/// `raisov check path` run in `cwd` (relative output and cache directories land there): its
/// standard output, after checking that it succeeded.
fn check(path: &Path, cwd: &Path) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_raisov"))
        .arg("check")
        .arg(path)
        .current_dir(cwd)
        .output()
        .unwrap();
    let stdout = String::from_utf8(out.stdout).unwrap();
    assert!(
        out.status.success(),
        "{}: status {:?}\n{stdout}\n{}",
        path.display(),
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.ends_with("ok\n"), "{stdout}");
    stdout
}

/// What in `line` looks like a Rust `Debug` rendering, if anything: `Some(`/`None`, a path
/// `a::b`, braces of a struct, a CamelCase name applied to `(` or `{` (`Duration(1.0)`,
/// `Steady {`), or a float written with a trailing `.0` in a list (`[0.0, -9.81, 0.0]`).
fn debug_looking(line: &str) -> Option<String> {
    for bad in ["Some(", "None", "::", "{ ", " }", ".0,", ".0]", ".0)"] {
        if line.contains(bad) {
            return Some(format!("`{bad}`"));
        }
    }
    for (i, c) in line.char_indices() {
        let rest = &line[i..];
        let opens = c == '(' || rest.starts_with(" {");
        if !opens {
            continue;
        }
        let word: String = line[..i]
            .chars()
            .rev()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
            .collect::<Vec<_>>()
            .into_iter()
            .rev()
            .collect();
        let camel = word.chars().next().is_some_and(|c| c.is_ascii_uppercase())
            && word.chars().any(|c| c.is_ascii_lowercase());
        if camel {
            return Some(format!(
                "`{word}` applied to `{}`",
                &rest[..1 + rest.starts_with(' ') as usize]
            ));
        }
    }
    None
}

fn assert_words(name: &str, text: &str) {
    for line in text.lines() {
        if let Some(why) = debug_looking(line) {
            panic!("{name}: a Debug structure ({why}) in\n{line}\n\nwhole output:\n{text}");
        }
    }
}

/// The value of the line labelled `label` (the text after the label's column).
fn field<'a>(text: &'a str, label: &str) -> &'a str {
    text.lines()
        .find_map(|l| {
            l.strip_prefix(label)
                .filter(|r| r.starts_with(' '))
                .map(str::trim)
        })
        .unwrap_or_else(|| panic!("no `{label}` line in\n{text}"))
}

#[test]
fn the_debug_detector_catches_what_check_used_to_print() {
    for old in [
        "material      NeoHookean(NeoHookean { lambda: 576923.0769230769, mu: 384615.3846153846 })",
        "stop          Steady { kinetic_tol: 1e-8, residual_tol: 0.0001, max: 1.0, stagnation: 1000 }",
        "stop          Duration(1.0)",
        "gravity       [0.0, -9.81, 0.0] m/s^2",
        "interactive   Interactive { fps: 30.0, budget: Cycles(2), reference: true }",
        "prescribed    node 147 at [-0.0005, 0.0025, 0.0]: Held { d: [0.0, 0.0, 0.03] }",
        "stepping      fas multigrid, coarsest Newton { rel_tol: 1e-6 }",
        "x             Some(3)",
    ] {
        assert!(debug_looking(old).is_some(), "{old}");
    }
    for fine in [
        "material      neo-hookean: Young's modulus 5000 Pa, Poisson's ratio 0.45 (Lame lambda 15520 Pa, shear modulus mu 1724 Pa)",
        "damping       alpha = 30 1/s (D = alpha M)",
        "density       1000 kg/m^3, total mass 4.0000e-2 kg",
        "gravity       (0, -9.81, 0) m/s^2",
    ] {
        assert_eq!(debug_looking(fine), None, "{fine}");
    }
}

#[test]
fn check_prints_words_not_debug_structures_for_every_example() {
    let cwd = tempfile::tempdir().unwrap();
    for path in examples() {
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let text = check(&path, cwd.path());
        assert_words(&name, &text);
        match name.as_str() {
            "liver_grasp.toml" => {
                assert_eq!(
                    field(&text, "material"),
                    "neo-hookean: Young's modulus 5000 Pa, Poisson's ratio 0.45 (Lame lambda 15520 Pa, shear modulus mu 1724 Pa)"
                );
                assert_eq!(field(&text, "gravity"), "none");
                assert_eq!(field(&text, "stop"), "after 1 s of simulated time");
                assert!(
                    field(&text, "prescribed").ends_with(
                        "m: displaced piecewise linearly in time through 3 points (t = 0, 0.4, 1 s), ending at (0, -0.01, -0.017) m"
                    ),
                    "{text}"
                );
            }
            "cantilever.toml" => {
                assert_eq!(field(&text, "gravity"), "(0, -9.81, 0) m/s^2");
                assert_eq!(
                    field(&text, "stop"),
                    "at steady state (kinetic energy below 1e-8 and residual below 0.0001 of their peaks), at most 1 s of simulated time; gives up after 1000 checks without progress"
                );
                assert_eq!(field(&text, "damping"), "alpha = 60 1/s (D = alpha M)");
            }
            "liver_interactive.toml" => {
                assert!(
                    field(&text, "interactive").starts_with("30 frames/s, 1 step per frame;"),
                    "{text}"
                );
                assert!(
                    field(&text, "stepping")
                        .contains("newton frames: Newton steps, at most 2 CG iterations a step"),
                    "{text}"
                );
            }
            "fibre_block.toml" => {
                assert_eq!(
                    field(&text, "material"),
                    "ti-neo-hookean: mu 1000 Pa, fibre eta 8000 Pa along (1, 0, 0), bulk modulus kappa 50000 Pa"
                );
            }
            "fibre_wall.toml" => {
                assert_eq!(
                    field(&text, "material"),
                    "hgo: mu 1000 Pa, fibre k1 2000 Pa, k2 5, dispersion 0 along the helix rule about the axis (0, 0, 1) through (-0.03, 0.01, 0) m, 60 deg at r = 0.03 m to -60 deg at r = 0.04 m, one direction per element, bulk modulus kappa 50000 Pa"
                );
            }
            "visco_block.toml" => {
                assert_eq!(
                    field(&text, "material"),
                    "neo-hookean-visco: mu 1000 Pa (long-term 500 Pa), Prony [alpha, tau s] [0.3, 0.05] [0.2, 0.5], bulk modulus kappa 20000 Pa"
                );
            }
            "membrane_lift.toml" => {
                assert!(
                    field(&text, "prescribed")
                        .ends_with("m: displaced by (0, 0, 0.03) m from the start"),
                    "{text}"
                );
                assert_eq!(
                    field(&text, "material"),
                    "mooney-rivlin: c1 1000 Pa, c2 1000 Pa, no bulk term (incompressible membrane)"
                );
            }
            _ => {}
        }
    }
}

/// A 2 cm box of 2 cells per side fixed at its base; `extra` is appended.
fn box_scenario(dir: &Path, name: &str, extra: &str) -> PathBuf {
    let p = dir.join(format!("{name}.toml"));
    std::fs::write(
        &p,
        format!(
            r#"
[mesh]
generate = "box"
size = [0.02, 0.02, 0.02]
divisions = [2, 2, 2]
[[fix]]
plane = {{ point = [0, 0, 0], normal = [0, 0, 1] }}
{extra}
"#
        ),
    )
    .unwrap();
    p
}

#[test]
fn check_prints_words_for_the_other_materials_motions_schemes_and_budgets() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            "veronda",
            r#"
[material]
law = "veronda-westmann"
c1 = 1e3
gamma = 5.0
kappa = 1e5
[[displace]]
point = [0.02, 0.02, 0.02]
displacement = [0, 0, 0.002]
mode = "ramp"
duration = 0.5
[[displace]]
point = [0.0, 0.02, 0.02]
displacement = [0, 0, 0.001]
time = { kind = "sine", frequency = 2.0 }
[multigrid]
scheme = "raisov-paper"
levels = 2
reading = "paper"
[run]
duration = 1.0
"#,
        ),
        (
            "stable",
            r#"
[material]
law = "stable-neo-hookean"
young = 5e3
poisson = 0.45
[[displace]]
point = [0.02, 0.02, 0.02]
displacement = [0, 0, 0.002]
[interactive]
budget_ms = 20.0
reference = "none"
[multigrid]
levels = 2
coarse = "explicit"
[run]
duration = 1.0
"#,
        ),
        (
            "stvk",
            r#"
[material]
law = "stvk"
young = 5e4
poisson = 0.3
[[displace]]
point = [0.02, 0.02, 0.02]
displacement = [0, 0, 0.002]
time = { kind = "table", table = [[0.0, 0.0], [0.5, 1.0]] }
[run]
stop = "steady"
duration = 2.0
"#,
        ),
    ];
    for (name, extra) in cases {
        let text = check(&box_scenario(dir.path(), name, extra), dir.path());
        assert_words(name, &text);
        match name {
            "veronda" => {
                assert_eq!(
                    field(&text, "material"),
                    "veronda-westmann: c1 1000 Pa, gamma 5, bulk modulus kappa 100000 Pa"
                );
                assert!(
                    text.contains("displaced by (0, 0, 0.002) m, ramped up over 0.5 s"),
                    "{text}"
                );
                assert!(
                    text.contains("displaced by (0, 0, 0.001) m times sin(2 pi f t), f = 2 Hz"),
                    "{text}"
                );
                assert!(
                    field(&text, "stepping").starts_with("raisov-paper (\"paper\" reading"),
                    "{text}"
                );
            }
            "stable" => {
                assert!(
                    field(&text, "material").starts_with(
                        "stable-neo-hookean: Young's modulus 5000 Pa, Poisson's ratio 0.45"
                    ),
                    "{text}"
                );
                assert!(
                    field(&text, "interactive").ends_with(
                        "20 ms of wall time per frame; no static reference; each frame whose \
                             path moves starts from the last frame's change, extrapolated"
                    ),
                    "{text}"
                );
                assert!(
                    field(&text, "stepping")
                        .contains("coarsest level by explicit damped steps over 0.1 s"),
                    "{text}"
                );
            }
            _ => {
                assert!(
                    field(&text, "material").starts_with("stvk: Young's modulus 50000 Pa"),
                    "{text}"
                );
                assert!(
                    text.contains("times a factor piecewise linear in time through 2 points (t = 0, 0.5 s; factors 0, 1)"),
                    "{text}"
                );
            }
        }
    }
}
