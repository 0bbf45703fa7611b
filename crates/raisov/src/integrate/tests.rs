//! Integrator tests on a small nonlinear tet problem.

use super::*;
use crate::fem::tests::jittered_box;
use crate::fem::{FemModel, FemParams};
use crate::material::{Material, NeoHookean};

/// A 2x2x2-cube neo-Hookean block, nodes at x = 0 fixed, with an initial velocity field.
fn block(alpha: f64) -> (System, State) {
    let mesh = jittered_box(2, 0.2);
    let model = FemModel::new(
        &mesh,
        FemParams::new(Material::NeoHookean(NeoHookean::from_young(1e4, 0.3))),
    )
    .unwrap();
    let mass = model.lumped_mass();
    let n = mesh.num_nodes();
    let fixed: Vec<u32> = (0..n as u32)
        .filter(|&a| mesh.nodes[a as usize][0] < 1e-12)
        .collect();
    let sys = System::new(
        Box::new(model),
        mass,
        alpha,
        vec![0.0; 3 * n],
        Constraints::new(fixed, vec![]),
    );
    let mut s = State::at_rest(n);
    for a in 0..n {
        let x = mesh.nodes[a];
        s.v[3 * a + 1] = 2.0 * x[0]; // bending-like velocity, 0 at the clamp
        s.v[3 * a + 2] = -100.0 * x[0] * x[1];
    }
    sys.impose(0.0, &mut s.u, &mut s.v);
    (sys, s)
}

fn total_energy(sys: &mut System, s: &State) -> f64 {
    sys.kinetic_energy(&s.v) + sys.force.strain_energy(&s.u)
}

/// A stable step for the block: 0.3 h_min / c.
fn dt_small() -> f64 {
    let (l, m) = crate::material::lame(1e4, 0.3);
    let c = ((l + 2.0 * m) / 1000.0f64).sqrt();
    0.3 * (0.01 / 2.0) * 0.6 / c
}

#[test]
fn undamped_symplectic_schemes_have_bounded_energy_drift() {
    for method in [Method::SymplecticEuler, Method::CentralDifference] {
        let (mut sys, mut s) = block(0.0);
        let dt = dt_small();
        let mut integ = method.build(sys.num_nodes());
        let e0 = total_energy(&mut sys, &s);
        let steps = 20_000;
        let mut first = 0.0;
        let mut last = 0.0;
        let window = steps / 10;
        let mut max_dev: f64 = 0.0;
        for k in 0..steps {
            integ.step(&mut sys, &mut s, dt).unwrap();
            let e = total_energy(&mut sys, &s);
            max_dev = max_dev.max((e - e0).abs() / e0);
            if k < window {
                first += e / window as f64;
            }
            if k >= steps - window {
                last += e / window as f64;
            }
        }
        // Symplectic: the energy oscillates (O(dt) for the staggered velocity) but does not drift.
        assert!(
            max_dev < 0.05,
            "{}: energy deviates {max_dev}",
            method.name()
        );
        assert!(
            (last - first).abs() / e0 < 2e-3,
            "{}: energy drifts {} -> {}",
            method.name(),
            first,
            last
        );
    }
}

/// Forward Euler gains energy without damping (the reason it needs damping): the symplectic
/// schemes above do not. Guards against the test above passing for a trivial reason.
#[test]
fn forward_euler_gains_energy_without_damping() {
    let (mut sys, mut s) = block(0.0);
    let dt = dt_small();
    let mut integ = Method::ForwardEuler.build(sys.num_nodes());
    let e0 = total_energy(&mut sys, &s);
    let mut grew = false;
    for _ in 0..2000 {
        if integ.step(&mut sys, &mut s, dt).is_err() {
            break; // it grows until an element inverts
        }
        grew |= total_energy(&mut sys, &s) > 1.05 * e0;
    }
    assert!(grew, "forward Euler did not gain energy");
}

fn error_at(method: Method, dt: f64, t_end: f64, reference: &State) -> f64 {
    let (mut sys, mut s) = block(5.0);
    let mut integ = method.build(sys.num_nodes());
    let n = (t_end / dt).round() as usize;
    for _ in 0..n {
        integ.step(&mut sys, &mut s, dt).unwrap();
    }
    s.u.iter()
        .zip(&reference.u)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// Observed order from steps `dt0` and `dt0/2` over 64 `dt_small()`.
fn observed_order(method: Method, dt0: f64) -> f64 {
    let t_end = 64.0 * dt_small();
    let (mut sys, mut reference) = block(5.0);
    let mut rk = Method::Rk4.build(sys.num_nodes());
    let fine = dt_small() / 64.0;
    for _ in 0..(t_end / fine).round() as usize {
        rk.step(&mut sys, &mut reference, fine).unwrap();
    }
    let e1 = error_at(method, dt0, t_end, &reference);
    let e2 = error_at(method, dt0 / 2.0, t_end, &reference);
    (e1 / e2).log2()
}

#[test]
fn rk4_is_fourth_order() {
    let p = observed_order(Method::Rk4, dt_small());
    assert!((3.7..4.5).contains(&p), "RK4 order {p}");
}

#[test]
fn euler_schemes_are_first_order() {
    // Forward Euler's undamped modes grow by √(1 + (ωΔ)²) per step: measure its order at a
    // step small enough for that growth to stay below the truncation error.
    for (m, dt0) in [
        (Method::ForwardEuler, dt_small() / 16.0),
        (Method::SymplecticEuler, dt_small()),
    ] {
        let p = observed_order(m, dt0);
        // Forward Euler: exactly first order. Symplectic Euler's positions are leapfrog's up to
        // an O(Δ) start-up offset (v_0 used as v_1/2), so it measures between 1 and 2.
        let range = if m == Method::ForwardEuler {
            0.8..1.3
        } else {
            0.8..2.2
        };
        assert!(range.contains(&p), "{} order {p}", m.name());
    }
}

#[test]
fn constrained_nodes_follow_their_motion() {
    let (mut sys, mut s) = block(1.0);
    let node = 26u32; // the far corner of the 3x3x3-node block
    sys.constraints = Constraints::new(
        sys.constraints.fixed.clone(),
        vec![(
            node,
            Motion::Ramp {
                d: [0.0, 0.0, 1e-3],
                duration: 0.01,
            },
        )],
    )
    .with_nodes(sys.num_nodes());
    for method in Method::ALL {
        let mut st = s.clone();
        let mut integ = method.build(sys.num_nodes());
        let dt = 1e-5;
        for _ in 0..500 {
            integ.step(&mut sys, &mut st, dt).unwrap();
        }
        let g = 1e-3 * (st.t / 0.01).min(1.0);
        assert!(
            (st.u[3 * node as usize + 2] - g).abs() < 1e-15,
            "{}",
            method.name()
        );
        for &f in &sys.constraints.fixed {
            assert_eq!(&st.u[3 * f as usize..3 * f as usize + 3], &[0.0; 3]);
        }
    }
    s.t = 0.0;
}

/// A spring with a force limit (the grip of a friction grasp): its force is the central
/// difference of its energy and its tangent the central difference of its force, both while
/// it sticks and while it slides; its force is continuous where it starts to slide; without
/// a limit it is the linear spring.
#[test]
fn sliding_spring_force_and_tangent_are_derivatives_of_its_energy() {
    let s = Spring {
        node: 1,
        k: 10.0,
        d: [0.01, -0.02, 0.005],
        limit: 0.5,
    };
    let h = 1e-7;
    for stretch in [[0.02, 0.01, -0.01], [0.1, -0.04, 0.03]] {
        let mut u = vec![0.3; 6];
        for k in 0..3 {
            u[3 + k] = s.d[k] + stretch[k];
        }
        let f = s.force(&u);
        let t = s.tangent(&u);
        for j in 0..3 {
            let (mut up, mut um) = (u.clone(), u.clone());
            up[3 + j] += h;
            um[3 + j] -= h;
            let fd = (s.energy(&up) - s.energy(&um)) / (2.0 * h);
            assert!((fd - f[j]).abs() <= 1e-7, "force {j}: {fd} vs {}", f[j]);
            let (fp, fm) = (s.force(&up), s.force(&um));
            for i in 0..3 {
                let kd = (fp[i] - fm[i]) / (2.0 * h);
                assert!(
                    (kd - t[3 * i + j]).abs() <= 1e-6,
                    "tangent {i}{j}: {kd} vs {}",
                    t[3 * i + j]
                );
            }
            let w: Vec<f64> = (0..6).map(|q| f64::from(u8::from(q == 3 + j))).collect();
            let kw = s.tangent_times(&u, &w);
            for i in 0..3 {
                assert_eq!(kw[i], t[3 * i + j]);
            }
        }
        let l = stretch.iter().map(|x| x * x).sum::<f64>().sqrt();
        let norm_f = f.iter().map(|x| x * x).sum::<f64>().sqrt();
        assert!((norm_f - (s.k * l).min(s.limit)).abs() <= 1e-15, "{norm_f}");
    }
    // Continuous where it starts to slide: at l = limit / k both branches give `limit`.
    let l0 = s.limit / s.k;
    let mut u = vec![0.0; 6];
    for (k, e) in [0.6f64, 0.8, 0.0].iter().enumerate() {
        u[3 + k] = s.d[k] + e * l0 * (1.0 + 1e-12);
    }
    let f = s.force(&u);
    assert!((f.iter().map(|x| x * x).sum::<f64>().sqrt() - s.limit).abs() <= 1e-12);
    let linear = Spring::linear(1, 10.0, s.d);
    assert_eq!(
        linear.force(&u),
        [0, 1, 2].map(|k| 10.0 * (u[3 + k] - s.d[k]))
    );
}
