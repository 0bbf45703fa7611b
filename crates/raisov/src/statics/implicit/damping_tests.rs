//! Stiffness-proportional damping `β K_n`: the first mode of a cantilever decays at
//! `ζ = α/(2ω) + β ω/2`, the damped run settles at the static solution, the frozen term is a
//! potential's gradient.

use super::stiffness::{Damped, FrozenStiffness};
use super::tests::{beam_mesh, beam_on};
use super::*;
use crate::fem::ForceModel;
use crate::mesh::generate::{box_tets, BoxPattern};
use crate::mesh::Mesh;
use crate::statics::newton::{solve_system, DirectNewtonParams};

/// A 0.1 × 0.04 × 0.02 m cantilever (10 × 4 × 2 cells): its first (vertical, z) bending
/// mode well apart from the lateral one (twice its frequency), which a square section's
/// mesh couples to it (the tip's vertical motion then beats between them).
fn flat_beam() -> Mesh {
    box_tets([0.1, 0.04, 0.02], [10, 4, 2], BoxPattern::Six).unwrap()
}

/// The static sag of the beam under gravity `g` (m, 3 per node).
fn sag(mesh: &Mesh, g: f64) -> Vec<f64> {
    let mut sys = beam_on(mesh, 0.0, g, vec![]);
    let mut u = vec![0.0; 3 * mesh.num_nodes()];
    let r = solve_system(&mut sys, 0.0, &mut u, DirectNewtonParams::default()).unwrap();
    assert!(r.converged);
    u
}

/// The free end's vertical displacement at every step of the beam released from a tenth of
/// its sag under gravity (then off: a small vibration mostly of the first mode), `steps`
/// steps of `h` by `scheme` with damping `alpha`, `beta`.
fn released_tip(
    mesh: &Mesh,
    scheme: ImplicitScheme,
    alpha: f64,
    beta: f64,
    h: f64,
    steps: usize,
) -> Vec<f64> {
    let mut p = ImplicitParams::new(h);
    p.scheme = scheme;
    p.beta = beta;
    let mut st = ImplicitEuler::new(beam_on(mesh, alpha, 0.0, vec![]), p).unwrap();
    st.state.u = sag(mesh, 9.81).iter().map(|x| 0.1 * x).collect();
    let tip = 3 * mesh.nearest_node([0.1, 0.02, 0.01]).unwrap() + 2;
    let mut z = vec![st.state.u[tip]];
    for _ in 0..steps {
        st.advance().unwrap();
        z.push(st.state.u[tip]);
    }
    z
}

/// The damping ratio and angular frequency (rad/s) of the vibration `z` sampled every `h`:
/// the logarithmic decrement and the spacing of its maxima (each placed by the parabola
/// through its three samples), from the second maximum on (the higher modes gone).
fn modal_damping(z: &[f64], h: f64) -> (f64, f64) {
    let mut peaks = Vec::new();
    for i in 1..z.len() - 1 {
        let (a, b, c) = (z[i - 1], z[i], z[i + 1]);
        if b > a && b >= c && b > 0.0 {
            let den = a - 2.0 * b + c;
            let off = 0.5 * (a - c) / den;
            peaks.push(((i as f64 + off) * h, b - 0.25 * (a - c) * off));
        }
    }
    assert!(peaks.len() >= 4, "too few maxima: {peaks:?}");
    let (first, last) = (peaks[1], peaks[peaks.len() - 1]);
    let cycles = (peaks.len() - 2) as f64;
    let period = (last.0 - first.0) / cycles;
    let delta = (first.1 / last.1).ln() / cycles;
    let zeta = delta / (4.0 * std::f64::consts::PI.powi(2) + delta * delta).sqrt();
    (zeta, 2.0 * std::f64::consts::PI / period)
}

#[test]
fn stiffness_damping_decays_the_first_mode_at_beta_omega_over_two() {
    let mesh = flat_beam();
    let (h, steps) = (1e-3, 500);
    let (zeta0, omega) = modal_damping(
        &released_tip(&mesh, ImplicitScheme::Bdf2, 0.0, 0.0, h, steps),
        h,
    );
    // β for ζ = 0.02 in the first mode.
    let beta = 2.0 * 0.02 / omega;
    let (zeta, omega_b) = modal_damping(
        &released_tip(&mesh, ImplicitScheme::Bdf2, 0.0, beta, h, steps),
        h,
    );
    let expected = beta * omega / 2.0;
    eprintln!(
        "ω = {omega:.2} rad/s ({omega_b:.2} damped), β = {beta:.3e} s: ζ = {zeta:.5} measured, \
         {zeta0:.2e} of the scheme alone, β ω/2 = {expected:.5}"
    );
    // The scheme's own damping is small at 100 steps a period, and is subtracted.
    assert!(zeta0.abs() < 0.1 * expected, "ζ of the scheme {zeta0:.3e}");
    let rel = (zeta - zeta0 - expected).abs() / expected;
    assert!(
        rel < 0.05,
        "ζ {zeta:.5} − {zeta0:.2e} against {expected:.5}: {rel:.3}"
    );
    // Backward Euler at the same step: its own damping (ζ about ω h / 2) is larger than
    // β's here, and subtracting it leaves β ω/2 within 15 %.
    let (zeta_be0, _) = modal_damping(
        &released_tip(&mesh, ImplicitScheme::BackwardEuler, 0.0, 0.0, h, steps),
        h,
    );
    let (zeta_be, _) = modal_damping(
        &released_tip(&mesh, ImplicitScheme::BackwardEuler, 0.0, beta, h, steps),
        h,
    );
    let rel_be = (zeta_be - zeta_be0 - expected).abs() / expected;
    eprintln!("backward Euler: ζ = {zeta_be:.5}, {zeta_be0:.5} alone: off by {rel_be:.3}");
    assert!(rel_be < 0.15, "backward Euler: {rel_be:.3}");
}

#[test]
fn mass_and_stiffness_damping_add_their_modal_ratios() {
    let mesh = flat_beam();
    let (h, steps) = (1e-3, 500);
    let (zeta0, omega) = modal_damping(
        &released_tip(&mesh, ImplicitScheme::Bdf2, 0.0, 0.0, h, steps),
        h,
    );
    // ζ = 0.01 from each.
    let alpha = 2.0 * 0.01 * omega;
    let beta = 2.0 * 0.01 / omega;
    let (zeta, _) = modal_damping(
        &released_tip(&mesh, ImplicitScheme::Bdf2, alpha, beta, h, steps),
        h,
    );
    let expected = alpha / (2.0 * omega) + beta * omega / 2.0;
    let rel = (zeta - zeta0 - expected).abs() / expected;
    eprintln!("α = {alpha:.3} 1/s, β = {beta:.3e} s: ζ = {zeta:.5}, expected {expected:.5}");
    assert!(rel < 0.05, "ζ {zeta:.5} against {expected:.5}: {rel:.3}");
}

#[test]
fn stiffness_damped_runs_settle_at_the_static_equilibrium() {
    let mesh = beam_mesh([10, 2, 2]);
    let u_static = sag(&mesh, 9.81);
    let scale = u_static.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    for scheme in [ImplicitScheme::BackwardEuler, ImplicitScheme::Bdf2] {
        // β alone, about critical for the first mode.
        let mut p = ImplicitParams::new(5e-3);
        p.scheme = scheme;
        p.beta = 0.02;
        let mut st = ImplicitEuler::new(beam_on(&mesh, 0.0, 9.81, vec![]), p).unwrap();
        for _ in 0..300 {
            st.advance().unwrap();
        }
        let diff = st
            .state
            .u
            .iter()
            .zip(&u_static)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(
            diff <= 1e-5 * scale,
            "{scheme:?}: max |u − u*| = {diff:.3e} m of max |u*| = {scale:.3e} m"
        );
        assert!(st.sys.kinetic_energy(&st.state.v) < 1e-12 * st.sys.force.strain_energy(&u_static));
    }
}

#[test]
fn frozen_stiffness_forces_are_its_energy_gradient_and_its_tangent_their_derivative() {
    let mesh = beam_mesh([4, 1, 1]);
    let mut sys = beam_on(&mesh, 0.0, 0.0, vec![]);
    let n = 3 * mesh.num_nodes();
    let wave = |k: usize, s: f64| s * ((k as f64 * 0.7).sin() + 0.3);
    let u_n: Vec<f64> = (0..n).map(|k| wave(k, 1e-3)).collect();
    let base: Vec<f64> = (0..n).map(|k| wave(k + 5, 5e-4)).collect();
    let mut frozen = FrozenStiffness::for_model(&*sys.force).unwrap().unwrap();
    frozen.freeze(&*sys.force, &u_n, 250.0, &base).unwrap();
    let mut model = Damped {
        inner: &mut *sys.force,
        frozen: &frozen,
    };
    let u: Vec<f64> = (0..n).map(|k| wave(k + 11, 2e-3)).collect();
    let mut r = vec![0.0; n];
    model.internal_forces(&u, &mut r).unwrap();
    let eps = 1e-7;
    let dir: Vec<f64> = (0..n).map(|k| wave(k + 3, 1.0)).collect();
    let shifted = |s: f64| -> Vec<f64> { u.iter().zip(&dir).map(|(a, d)| a + s * d).collect() };
    let slope =
        (model.strain_energy(&shifted(eps)) - model.strain_energy(&shifted(-eps))) / (2.0 * eps);
    let rd: f64 = r.iter().zip(&dir).map(|(a, b)| a * b).sum();
    assert!(
        (slope - rd).abs() <= 1e-5 * rd.abs(),
        "dE/ds {slope:.6e} against r·d {rd:.6e}"
    );
    // The forces minus the plain model's: c K_n (u − x*), K_n summed from the element
    // tangents at u_n; and each element tangent the plain one plus c K_e(u_n).
    let c = 250.0;
    let mut plain = vec![0.0; n];
    model.inner.internal_forces(&u, &mut plain).unwrap();
    let top = model.tangent_elements().unwrap();
    let d = 3 * top.nodes_per_element;
    let mut expect = vec![0.0; n];
    let (mut kn, mut ke, mut ke_plain) = (vec![0.0; d * d], vec![0.0; d * d], vec![0.0; d * d]);
    for e in 0..top.len() {
        let el = top.element(e);
        let dof = |q: usize| 3 * el[q / 3] as usize + q % 3;
        model.inner.element_tangent(e, &u_n, &mut kn).unwrap();
        for q in 0..d {
            for p in 0..d {
                expect[dof(q)] += c * kn[q * d + p] * (u[dof(p)] - base[dof(p)]);
            }
        }
        model.element_tangent(e, &u, &mut ke).unwrap();
        model.inner.element_tangent(e, &u, &mut ke_plain).unwrap();
        for q in 0..d * d {
            let want = ke_plain[q] + c * kn[q];
            assert!(
                (ke[q] - want).abs() <= 1e-12 * want.abs().max(1.0),
                "element {e}, entry {q}: {} against {want}",
                ke[q]
            );
        }
    }
    let big = expect.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    assert!(big > 0.0);
    for i in 0..n {
        let got = r[i] - plain[i];
        assert!(
            (got - expect[i]).abs() <= 1e-9 * big,
            "dof {i}: {got:.6e} against {:.6e}",
            expect[i]
        );
    }
}
