//! Backward Euler: dissipation, first-order convergence to a fine explicit reference, the
//! static limit, each step's equation, failures reported, the multigrid preconditioner.

use super::*;
use crate::fem::{FemModel, FemParams};
use crate::integrate::stability::critical_step_estimate;
use crate::integrate::{Constraints, Method, SingleLevel, StepperParams};
use crate::material::{Material, NeoHookean};
use crate::mesh::generate::{box_tets, BoxPattern};
use crate::mesh::Mesh;
use crate::statics::newton::{solve_system, DirectNewtonParams};
use crate::time::Motion;

pub(super) const YOUNG: f64 = 1e6;
pub(super) const RHO: f64 = 1000.0;

pub(super) fn material() -> Material {
    Material::NeoHookean(NeoHookean::from_young(YOUNG, 0.3))
}

/// A 0.1 × 0.02 × 0.02 m neo-Hookean cantilever (E = 1 MPa, ν = 0.3, ρ = 1000 kg/m³) on
/// `div` cells, clamped at x = 0, with damping `alpha` and gravity `g` along −z.
pub(super) fn beam_on(mesh: &Mesh, alpha: f64, g: f64, prescribed: Vec<(u32, Motion)>) -> System {
    let mut p = FemParams::new(material());
    p.density = RHO;
    let model = FemModel::new(mesh, p).unwrap();
    let mass = model.lumped_mass();
    let n = mesh.num_nodes();
    let fixed: Vec<u32> = (0..n as u32)
        .filter(|&a| mesh.nodes[a as usize][0] < 1e-12)
        .collect();
    let mut sys = System::new(
        Box::new(model),
        mass,
        alpha,
        vec![0.0; 3 * n],
        Constraints::new(fixed, prescribed),
    );
    sys.add_gravity([0.0, 0.0, -g]);
    sys
}

pub(super) fn beam_mesh(div: [usize; 3]) -> Mesh {
    box_tets([0.1, 0.02, 0.02], div, BoxPattern::Six).unwrap()
}

/// The explicit (symplectic Euler) critical step estimate of the beam.
pub(super) fn explicit_step(mesh: &Mesh) -> f64 {
    critical_step_estimate(mesh, &material(), RHO, Method::SymplecticEuler)
}

/// `T + W − V·u` (J).
pub(super) fn energy(sys: &System, s: &State) -> f64 {
    let work: f64 = sys.f_ext.iter().zip(&s.u).map(|(f, u)| f * u).sum();
    sys.kinetic_energy(&s.v) + sys.force.strain_energy(&s.u) - work
}

/// A bending velocity field, zero at the clamp.
pub(super) fn kick(mesh: &Mesh, s: &mut State) {
    for (a, x) in mesh.nodes.iter().enumerate() {
        s.v[3 * a + 2] = 0.5 * (x[0] / 0.1).powi(2);
        s.v[3 * a + 1] = 0.2 * x[0] / 0.1;
    }
}

#[test]
fn implicit_euler_dissipates_a_free_vibration_and_is_stable_at_100_explicit_steps() {
    let mesh = beam_mesh([10, 2, 2]);
    let crit = explicit_step(&mesh);
    for factor in [1.0, 100.0] {
        let dt = factor * crit;
        let mut st =
            ImplicitEuler::new(beam_on(&mesh, 0.0, 0.0, vec![]), ImplicitParams::new(dt)).unwrap();
        kick(&mesh, &mut st.state);
        let e0 = energy(&st.sys, &st.state);
        let mut prev = e0;
        for k in 0..60 {
            st.advance().unwrap();
            let e = energy(&st.sys, &st.state);
            // Non-increasing, up to the Newton tolerance's share.
            assert!(
                e <= prev + 1e-6 * e0,
                "dt = {factor} explicit steps, step {k}: energy rose {prev:.6e} -> {e:.6e}"
            );
            prev = e;
        }
        assert!(prev.is_finite() && prev > 0.0);
        if factor > 1.0 {
            // 60 steps of 100 explicit steps: the vibration is mostly damped out.
            assert!(prev < 0.5 * e0, "energy {prev:.3e} of {e0:.3e} left");
        }
    }
}

/// The beam of [`beam_on`] (10 × 2 × 2 cells, undamped) under a nodal load on every node
/// that rises smoothly from 0 to 4 mN along `3τ² − 2τ³`, τ = t / 30 ms (a table of 61 rows,
/// linear between them), then stays: a load this smooth excites the high modes little, so that
/// the steps below are in backward Euler's first-order regime (a load switched on at once
/// excites every mode, and the order measured over these steps is about 0.86, the stiff modes
/// still far from it).
pub(super) fn smooth_load_system(method: &str) -> System {
    let rows: Vec<String> = (0..=60)
        .map(|k| {
            let tau = k as f64 / 60.0;
            format!("[{:e}, {:e}]", 0.03 * tau, tau * tau * (3.0 - 2.0 * tau))
        })
        .collect();
    let text = format!(
        r#"
[mesh]
generate = "box"
size = [0.1, 0.02, 0.02]
divisions = [10, 2, 2]
[material]
law = "neo-hookean"
young = {YOUNG:e}
poisson = 0.3
density = {RHO:e}
[[fix]]
plane = {{ point = [0.0, 0.0, 0.0], normal = [1.0, 0.0, 0.0] }}
[[load]]
at = {{ box = {{ min = [-1.0, -1.0, -1.0], max = [1.0, 1.0, 1.0] }} }}
force = [0.0, 0.0, -4e-3]
time = {{ kind = "table", table = [{}] }}
[integrator]
method = "{method}"
{}
[run]
duration = 0.05
"#,
        rows.join(", "),
        if method == "implicit-euler" {
            "dt = 1e-3"
        } else {
            ""
        }
    );
    crate::scenario::Scenario::from_toml(&text, std::path::Path::new("first-order.toml"))
        .unwrap()
        .build_system()
        .unwrap()
}

/// The displacements at `t_end` by `scheme` at `steps` steps, each step's Newton iteration
/// to `rel_tol`.
pub(super) fn implicit_run(
    scheme: ImplicitScheme,
    t_end: f64,
    steps: usize,
    rel_tol: f64,
) -> Vec<f64> {
    let mut p = ImplicitParams::new(t_end / steps as f64);
    p.scheme = scheme;
    p.rel_tol = rel_tol;
    let mut st = ImplicitEuler::new(smooth_load_system("implicit-euler"), p).unwrap();
    for _ in 0..steps {
        st.advance().unwrap();
    }
    assert!((st.state.t - t_end).abs() < 1e-12);
    st.state.u.clone()
}

/// The displacements at `t_end` of [`smooth_load_system`] by RK4 at a quarter of its
/// critical step estimate.
pub(super) fn rk4_reference(t_end: f64) -> Vec<f64> {
    let mesh = beam_mesh([10, 2, 2]);
    let dt_ref = 0.25 * critical_step_estimate(&mesh, &material(), RHO, Method::Rk4);
    let n_ref = (t_end / dt_ref).ceil() as usize;
    let mut reference = SingleLevel::new(
        smooth_load_system("rk4"),
        Method::Rk4,
        StepperParams {
            dt: t_end / n_ref as f64,
            kinetic_limit: f64::INFINITY,
        },
    );
    for _ in 0..n_ref {
        reference.advance().unwrap();
    }
    reference.state.u.clone()
}

#[test]
fn implicit_euler_converges_at_first_order_to_a_fine_rk4_reference() {
    let t_end = 0.05; // about half the first bending period
    let u_ref = rk4_reference(t_end);
    let scale = u_ref.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    assert!(scale > 1e-4, "the beam should bend: {scale:.3e} m");
    let errors: Vec<f64> = [50, 100, 200, 400]
        .into_iter()
        .map(|n| {
            let u = implicit_run(ImplicitScheme::BackwardEuler, t_end, n, DEFAULT_REL_TOL);
            u.iter()
                .zip(&u_ref)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .collect();
    let orders: Vec<f64> = errors.windows(2).map(|w| (w[0] / w[1]).log2()).collect();
    eprintln!("errors at t = {t_end} s: {errors:?} m; measured orders {orders:?}");
    for (k, &p) in orders.iter().enumerate() {
        assert!(
            (0.85..=1.15).contains(&p),
            "measured order {p:.3} between refinements {k} and {}: errors {errors:?}",
            k + 1
        );
    }
    // The finest error is small against the deflection itself.
    assert!(
        errors[3] < 0.05 * scale,
        "errors {errors:?}, deflection {scale:.3e}"
    );
}

#[test]
fn damped_implicit_euler_settles_at_the_static_equilibrium() {
    let mesh = beam_mesh([10, 2, 2]);
    let mut sys = beam_on(&mesh, 0.0, 9.81, vec![]);
    let mut u_static = vec![0.0; 3 * mesh.num_nodes()];
    let r = solve_system(&mut sys, 0.0, &mut u_static, DirectNewtonParams::default()).unwrap();
    assert!(r.converged);
    // Damped about critically for the first mode; a step of 5 ms, 50 explicit steps or more.
    let mut st = ImplicitEuler::new(
        beam_on(&mesh, 100.0, 9.81, vec![]),
        ImplicitParams::new(5e-3),
    )
    .unwrap();
    for _ in 0..300 {
        st.advance().unwrap();
    }
    let scale = u_static.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let diff = st
        .state
        .u
        .iter()
        .zip(&u_static)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(
        diff <= 1e-5 * scale,
        "max |u − u*| = {diff:.3e} m of max |u*| = {scale:.3e} m"
    );
    assert!(st.sys.kinetic_energy(&st.state.v) < 1e-12 * st.sys.force.strain_energy(&u_static));
}

#[test]
fn each_implicit_step_satisfies_the_backward_euler_equation() {
    let mesh = beam_mesh([8, 2, 2]);
    // The far end's corner pulled up along a ramp: the lifted iteration every step.
    let tip = mesh.nearest_node([0.1, 0.02, 0.02]).expect("a node") as u32;
    let pull = Motion::Ramp {
        d: [0.0, 0.0, 0.004],
        duration: 0.02,
    };
    let mut st = ImplicitEuler::new(
        beam_on(&mesh, 30.0, 9.81, vec![(tip, pull)]),
        ImplicitParams::new(2e-3),
    )
    .unwrap();
    kick(&mesh, &mut st.state);
    let mut worst = 0.0f64;
    for _ in 0..20 {
        let v_prev = st.state.v.clone();
        st.advance().unwrap();
        let (_, target) = st.last_step();
        let r = st.step_residual(&v_prev);
        assert!(
            r <= target * (1.0 + 1e-9) + 1e-12,
            "t = {:.3}: residual {r:.3e} N above the target {target:.3e} N",
            st.state.t
        );
        worst = worst.max(r / target);
    }
    // The pulled node follows its motion.
    let i = 3 * tip as usize;
    assert!((st.state.u[i + 2] - 0.004).abs() < 1e-15);
    assert!(worst <= 1.0 + 1e-9);
}

#[test]
fn an_implicit_step_that_does_not_converge_is_reported_and_not_taken() {
    let mesh = beam_mesh([8, 2, 2]);
    let mut p = ImplicitParams::new(0.05);
    p.max_newton = 1;
    p.rel_tol = 1e-12;
    let mut st = ImplicitEuler::new(beam_on(&mesh, 0.0, 9.81, vec![]), p).unwrap();
    let before = st.state.clone();
    let e = st.advance().unwrap_err();
    assert!(
        matches!(e.cause, DivergenceCause::NotConverged { newton: 1, .. }),
        "{e}"
    );
    assert!(e.to_string().contains("integrator.max_newton"), "{e}");
    assert_eq!(st.state, before);
    assert_eq!(st.steps(), 0);
}

#[test]
fn multigrid_preconditioned_implicit_steps_match_the_direct_ones() {
    let fine = beam_mesh([16, 4, 4]);
    let coarse = beam_mesh([4, 1, 1]);
    let down = Transfer::build(&fine.nodes, &coarse).unwrap();
    let mut p = ImplicitParams::new(4e-3);
    p.rel_tol = 1e-9;
    let mut direct = ImplicitEuler::new(beam_on(&fine, 10.0, 9.81, vec![]), p).unwrap();
    p.multigrid = Some(MultigridPcg::default());
    let mut mg =
        ImplicitEuler::with_levels(beam_on(&fine, 10.0, 9.81, vec![]), p, vec![down]).unwrap();
    for _ in 0..10 {
        direct.advance().unwrap();
        mg.advance().unwrap();
    }
    let scale = direct.state.u.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let diff = direct
        .state
        .u
        .iter()
        .zip(&mg.state.u)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(diff <= 1e-6 * scale, "{diff:.3e} of {scale:.3e}");
    assert!(mg.counts().cg > 0 && mg.counts().multigrid_setups > 0);
    assert!(mg.describe().contains("Galerkin V-cycle over 2 levels"));
}

#[test]
fn implicit_euler_rebuilds_its_pattern_when_a_grasp_is_added() {
    let mesh = beam_mesh([8, 2, 2]);
    let mut st = ImplicitEuler::new(
        beam_on(&mesh, 20.0, 9.81, vec![]),
        ImplicitParams::new(5e-3),
    )
    .unwrap();
    st.advance().unwrap();
    let tip = mesh.nearest_node([0.1, 0.01, 0.01]).unwrap() as u32;
    st.set_runtime_constraints(&RuntimeConstraints {
        held: vec![(tip, [0.0, 0.0, 0.002])],
        ..Default::default()
    });
    for _ in 0..5 {
        st.advance().unwrap();
    }
    let i = 3 * tip as usize;
    assert_eq!(st.state.u[i + 2], 0.002);
    assert_eq!(st.state.v[i + 2], 0.0);
}
