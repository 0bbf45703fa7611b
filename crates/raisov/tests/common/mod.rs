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
