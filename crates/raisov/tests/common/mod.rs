//! Scenarios shared by the integration tests.

use raisov::scenario::Scenario;
use std::path::Path;

/// The organ meshes of `data/`.
const MESHES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../data");

/// The liver L1 of `data/` (millimetres scaled to metres; neo-Hookean, E = 5 kPa, ν = 0.45,
/// ρ = 1060 kg/m³), held on the cap of its top (z ≥ 0.195 m) and sagging under gravity, with
/// the L2 and L3 as its `[multigrid]` files and `multigrid` added to that section (e.g.
/// `scheme = "fas"`). `name` names the scenario's file in errors. Panics where the meshes are
/// missing.
pub fn liver_l1_sag(multigrid: &str, name: &str) -> Scenario {
    let dir = Path::new(MESHES);
    if !dir.join("liver_L1.msh").is_file() {
        panic!("liver meshes not found under {}", dir.display());
    }
    let text = format!(
        r#"
gravity = [0.0, 0.0, -9.81]
[mesh]
file = "{d}/liver_L1.msh"
scale = 0.001
[material]
law = "neo-hookean"
young = 5000.0
poisson = 0.45
density = 1060.0
[[fix]]
plane = {{ point = [0.0, 0.0, 0.195], normal = [0.0, 0.0, -1.0] }}
[run]
duration = 1.0
[multigrid]
{multigrid}
files = ["{d}/liver_L2.msh", "{d}/liver_L3.msh"]
"#,
        d = dir.display()
    );
    Scenario::from_toml(&text, Path::new(name)).unwrap()
}

/// The static equilibrium of `sc` from rest at `rel_tol = 1e-8`: Newton-multigrid over the
/// transfers `down` with `multigrid`, or direct Newton reusing its factorisation for 20 CG
/// iterations (`None`), the reference. Panics where it does not converge.
#[allow(dead_code)]
pub fn newton_from_rest(
    sc: &Scenario,
    down: &[raisov::hierarchy::Transfer],
    multigrid: Option<raisov::statics::newton::MultigridPcg>,
) -> (Vec<f64>, raisov::statics::newton::DirectStatic) {
    use raisov::statics::newton::{DirectNewton, DirectNewtonParams};
    let mut sys = sc.build_system().unwrap();
    let f = sys.f_ext.clone();
    let model = &mut *sys.force;
    let mut newton = match multigrid {
        Some(_) => DirectNewton::with_levels(&*model, &sys.mass, &sys.constraints, down),
        None => DirectNewton::new(&*model, &sys.mass, &sys.constraints),
    }
    .unwrap();
    let params = DirectNewtonParams {
        rel_tol: 1e-8,
        pcg_max: if multigrid.is_some() { 0 } else { 20 },
        multigrid,
        ..Default::default()
    };
    let mut u = vec![0.0; 3 * sc.mesh.num_nodes()];
    let out = newton
        .solve(
            model,
            &sys.springs,
            &sys.constraints,
            &f,
            0.0,
            &mut u,
            params,
        )
        .unwrap();
    assert!(out.converged, "{out:?}");
    (u, out)
}

/// The largest `|u − reference|` and the largest `|reference|`.
#[allow(dead_code)]
pub fn max_diff(u: &[f64], reference: &[f64]) -> (f64, f64) {
    let scale = reference.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let err = reference
        .iter()
        .zip(u)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    (err, scale)
}
