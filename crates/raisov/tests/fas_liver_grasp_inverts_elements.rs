//! Regression: the FAS multigrid on the liver levels (L1, L2, L3 of `data/`) under a
//! slow grasp-and-pull inverted elements every few cycles and then stopped with "diverged ...
//! inverted element", where single-level integration ran on. Three causes, each fixed:
//! - the coarse-grid correction `P(u_c − u_c0)` was applied in full: near the grasp the coarse
//!   solve overshoots, and the fine Chebyshev smoother met the overshoot with long steps
//!   (fixed: a secant line search on the fine potential energy along the correction);
//! - the Chebyshev smoother was preconditioned by the lumped mass, so its interval was set by
//!   the stiffest sliver of a real mesh (fixed: per-node fictitious masses);
//! - the coarse levels held the node nearest the grasp at its restricted value, pinning the
//!   correction to zero where the error is largest (fixed: coarse levels hold only the fixed
//!   regions).
//!
//! Slow (liver meshes): `#[ignore]`d in the fast loop, run in CI by
//! `cargo test --workspace -- --ignored`.

use raisov::scenario::Scenario;
use std::path::Path;

const MESHES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../data");

#[test]
#[ignore = "slow: liver meshes; run in release with --ignored"]
fn fas_follows_liver_grasp_without_inverting() {
    let dir = Path::new(MESHES);
    if !dir.join("liver_L1.msh").is_file() {
        panic!("liver meshes not found under {}", dir.display());
    }
    let text = format!(
        r#"
[mesh]
file = "{d}/liver_L1.msh"
scale = 0.001
[material]
law = "neo-hookean"
young = 5000.0
poisson = 0.45
density = 1060.0
[damping]
alpha = 30.0
[[fix]]
plane = {{ point = [0.0, 0.0, 0.1995], normal = [0.0, 0.0, -1.0] }}
[[displace]]
point = [0.12, 0.07, 0.10]
mode = "table"
table = [[0.0, 0.0, 0.0, 0.0], [0.4, 0.0, -0.01, -0.017], [1.0, 0.0, -0.01, -0.017]]
[run]
duration = 1.0
[multigrid]
scheme = "fas"
files = ["{d}/liver_L2.msh", "{d}/liver_L3.msh"]
"#,
        d = dir.display()
    );
    let sc = Scenario::from_toml(&text, Path::new("liver-grasp-fas.toml")).unwrap();
    let mut st = sc.stepper().unwrap();
    // 120 cycles: the grasp moves about 2 mm.
    for k in 0..120 {
        st.advance()
            .unwrap_or_else(|d| panic!("cycle {k}: {d}; {:?}", st.diagnostics()));
    }
    let diag = st.diagnostics().unwrap();
    assert!(
        diag.contains(" 0 smoothing sweeps fell back"),
        "smoother fell back: {diag}"
    );
    let (sys, s) = st.finest();
    let mut r = vec![0.0; s.u.len()];
    let u = s.u.clone();
    let res = sys.residual(&u, &mut r).unwrap();
    // The single-level run's residual at the same point of the path is about 5e-3 N.
    assert!(res < 2e-2, "residual {res} N after 120 cycles: {diag}");
}
