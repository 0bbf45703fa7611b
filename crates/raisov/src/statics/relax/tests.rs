//! The relaxations' shared test problem and the fictitious masses' bound.

use super::fictitious_mass;
use crate::fem::tests::jittered_box;
use crate::fem::{FemModel, FemParams, ForceModel};
use crate::material::{Material, NeoHookean};

/// The per-node fictitious masses bound the small-strain stiffness, `xᵀKx ≤ xᵀDx` for every x
/// (the element bound summed), on a jittered mesh with poorly shaped elements, and the bound
/// is not vacuous: some x reaches a fair fraction of it.
#[test]
fn fictitious_masses_bound_the_stiffness() {
    for jitter in [0.0, 0.4] {
        let mesh = jittered_box(3, jitter);
        let mat = Material::NeoHookean(NeoHookean::from_young(1e4, 0.3));
        let mut model = FemModel::new(&mesh, FemParams::new(mat.clone())).unwrap();
        let mass = model.lumped_mass();
        let rho = 1000.0; // FemParams default density
        let lambda_max = mat.stability_modulus(mesh.kind) / rho
            * crate::integrate::stability::max_gradient_sum(&mesh);
        let d = fictitious_mass(&mesh, &mass, lambda_max);
        let n = 3 * mesh.num_nodes();
        let (mut rp, mut rm) = (vec![0.0; n], vec![0.0; n]);
        let mut seed = 7u64;
        let mut best: f64 = 0.0;
        for trial in 0..40 {
            // Random vectors, and localised ones (one node) where slivers bite.
            let x: Vec<f64> = (0..n)
                .map(|i| {
                    seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
                    let r = (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
                    if trial % 2 == 0 || i / 3 == trial % mesh.num_nodes() {
                        r
                    } else {
                        0.0
                    }
                })
                .collect();
            let eps = 1e-9;
            let up: Vec<f64> = x.iter().map(|v| eps * v).collect();
            let um: Vec<f64> = x.iter().map(|v| -eps * v).collect();
            model.internal_forces(&up, &mut rp).unwrap();
            model.internal_forces(&um, &mut rm).unwrap();
            let xkx: f64 = (0..n).map(|i| x[i] * (rp[i] - rm[i]) / (2.0 * eps)).sum();
            let xdx: f64 = (0..n).map(|i| d[i / 3] * x[i] * x[i]).sum();
            assert!(xkx <= xdx * (1.0 + 1e-6), "jitter {jitter}: {xkx} > {xdx}");
            best = best.max(xkx / xdx);
        }
        assert!(best > 0.05, "jitter {jitter}: bound vacuous ({best})");
    }
}

/// A soft neo-Hookean beam (10 x 3 x 3 cm, ν = 0.45, E = 5 kPa, 300 nodes) held at x = 0,
/// sagging far under gravity: the single-level relaxations' test problem.
pub(crate) fn sagging_beam() -> crate::scenario::Scenario {
    let text = r#"
gravity = [0.0, 0.0, -9.81]
[mesh]
generate = "box"
size = [0.1, 0.03, 0.03]
nodes = 300
[material]
law = "neo-hookean"
young = 5000.0
poisson = 0.45
density = 1060.0
[[fix]]
plane = { point = [0.0, 0.0, 0.0], normal = [1.0, 0.0, 0.0] }
[run]
duration = 1.0
"#;
    crate::scenario::Scenario::from_toml(text, std::path::Path::new("sagging-beam.toml")).unwrap()
}

/// Direct Newton's equilibrium of `sc` to 1e-12 of the load (two load steps), and the
/// largest nodal distance of `u` from it over its largest displacement component.
pub(crate) fn distance_to_newton(sc: &crate::scenario::Scenario, u: &[f64]) -> f64 {
    use crate::statics::newton::{solve_system, DirectNewtonParams};
    let mut sys = sc.build_system().unwrap();
    let mut u_newton = vec![0.0; u.len()];
    let params = DirectNewtonParams {
        rel_tol: 1e-12,
        load_steps: 2,
        ..Default::default()
    };
    assert!(
        solve_system(&mut sys, 0.0, &mut u_newton, params)
            .unwrap()
            .converged
    );
    let scale = u_newton.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
    let diff = u
        .iter()
        .zip(&u_newton)
        .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
    diff / scale
}
