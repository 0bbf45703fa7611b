//! Reference value: the static tip deflection of a slender tetrahedral cantilever under its
//! own weight against Euler-Bernoulli, `w = q L⁴ / (8 E I)` with `q = ρ g A`, approaching it
//! as the mesh is refined (linear tetrahedra are stiff in bending; their error falls as h²).
//!
//! Slow (dynamic relaxation to 1e-9 of the load): `#[ignore]`d in the fast loop, run in CI by
//! `cargo test --release -- --ignored`.

use raisov::fem::{FemModel, FemParams};
use raisov::integrate::relax::relax;
use raisov::integrate::{Constraints, Method, State, System};
use raisov::material::{Material, NeoHookean};
use raisov::mesh::generate::{box_tets, BoxPattern};

const L: f64 = 0.1;
const H: f64 = 0.01;
const E: f64 = 1.0e7;
const RHO: f64 = 1000.0;
const G: f64 = 9.81;

/// Mean tip deflection (nodes at x = L) of the n_x × n × n mesh at static equilibrium.
fn tip_deflection(n: usize) -> f64 {
    let mesh = box_tets([L, H, H], [10 * n, n, n], BoxPattern::Six).unwrap();
    let mat = Material::NeoHookean(NeoHookean::from_young(E, 0.3));
    let mut p = FemParams::new(mat.clone());
    p.density = RHO;
    let fem = FemModel::new(&mesh, p).unwrap();
    let mass = fem.lumped_mass();
    let nn = mesh.num_nodes();
    let fixed = mesh.groups["xmin"].clone();
    let mut sys = System::new(Box::new(fem), mass, 0.0, vec![0.0; 3 * nn], Constraints::new(fixed, vec![]));
    sys.add_gravity([0.0, -G, 0.0]);
    let dt = 0.5 * raisov::scenario::critical_step_estimate(&mesh, &mat, RHO, Method::SymplecticEuler);
    let r = relax(&mut sys, State::at_rest(nn), dt, 1e-9, 5_000_000).unwrap();
    assert!(r.converged, "relaxation did not converge: residual {}", r.residual);
    let tip = &mesh.groups["xmax"];
    -tip.iter().map(|&a| r.state.u[3 * a as usize + 1]).sum::<f64>() / tip.len() as f64
}

#[test]
#[ignore = "slow reference value; run with --release -- --ignored"]
fn cantilever_tip_deflection_approaches_euler_bernoulli() {
    let q = RHO * G * H * H;
    let i = H.powi(4) / 12.0;
    let w_eb = q * L.powi(4) / (8.0 * E * i);
    let mut errors = Vec::new();
    for n in [2, 4, 6] {
        let w = tip_deflection(n);
        let err = (w - w_eb).abs() / w_eb;
        println!("{}x{n}x{n}: tip {w:.6e} m, Euler-Bernoulli {w_eb:.6e} m, error {:.2}%", 10 * n, 100.0 * err);
        errors.push(err);
    }
    assert!(errors.windows(2).all(|w| w[1] < w[0]), "error does not fall with refinement: {errors:?}");
    assert!(*errors.last().unwrap() < 0.05, "finest mesh off by {:.1}%", 100.0 * errors.last().unwrap());
}
