//! Coulomb friction of single nodes against a moving plane, in closed form: stick below
//! `μ_s N`, slip at `μ_k N` opposing the slip, the return map's dissipation, checkpoints.

use super::*;
use crate::fem::ElementFailure;

/// Nodes with no elastic force: only the tools act.
struct Free(usize);

impl ForceModel for Free {
    fn num_nodes(&self) -> usize {
        self.0
    }
    fn internal_forces(&mut self, _u: &[f64], r: &mut [f64]) -> Result<(), ElementFailure> {
        r.iter_mut().for_each(|x| *x = 0.0);
        Ok(())
    }
    fn strain_energy(&self, _u: &[f64]) -> f64 {
        0.0
    }
    fn nodal_stress(&self, _u: &[f64], t: &mut [f64]) {
        t.iter_mut().for_each(|x| *x = 0.0);
    }
}

const K: f64 = 1000.0;
const KT: f64 = 500.0;
/// Penetration (m): `N = K · DEPTH = 1 N`.
const DEPTH: f64 = 1e-3;

/// A plane (tool below `z = 0`, normal +z) moving along +x by `speed · t`, with friction
/// `(μ_s, μ_k)`, on one node at the origin held `DEPTH` inside it.
fn dragged(mu_s: f64, mu_k: f64, speed: f64) -> (Contact, Vec<f64>) {
    let tool = Tool {
        shape: ToolShape::Plane {
            point: [0.0; 3],
            normal: [0.0, 0.0, 1.0],
        },
        motion: Motion::Ramp {
            d: [speed, 0.0, 0.0],
            duration: 1.0,
        },
        stiffness: K,
        friction: Some(Friction {
            static_coefficient: mu_s,
            kinetic_coefficient: mu_k,
            stiffness: KT,
        }),
    };
    let c = Contact::new(Box::new(Free(1)), vec![0.0; 3], vec![tool]);
    (c, vec![0.0, 0.0, -DEPTH])
}

/// The tool's force on the node at time `t` (the node held).
fn force_at(c: &mut Contact, u: &[f64], t: f64) -> [f64; 3] {
    c.set_time(t);
    let mut f = [0.0; 3];
    c.contact_forces(u, &mut f);
    f
}

/// The tool drags a held node: it sticks (`f_x = k_t d`, the spring stretched by the tool's
/// travel `d`) while `k_t d ≤ μ_s N`, then slips with `|f_t| = μ_k N` along the tool's motion
/// (opposing the node's slip relative to the tool, which is −x), and stays there while the
/// drag goes on; the normal force is `K · DEPTH` throughout.
#[test]
fn a_dragged_node_sticks_below_mu_s_n_and_slips_at_mu_k_n() {
    let (mu_s, mu_k) = (0.5, 0.3);
    let n = K * DEPTH;
    let (mut c, u) = dragged(mu_s, mu_k, 1e-2);
    c.set_time(0.0);
    assert!(c.accept_step(&u, 1e-3), "friction is path dependent");
    let steps = 100;
    let stick_until = mu_s * n / KT; // tool travel at the threshold, 1e-3 m
    let mut slipped = false;
    for i in 1..=steps {
        let t = i as f64 / steps as f64;
        let d = 1e-2 * t;
        let f = force_at(&mut c, &u, t);
        assert!((f[2] - n).abs() <= 1e-12 * n, "normal {f:?}");
        assert_eq!(f[1], 0.0);
        if !slipped && d <= stick_until * (1.0 + 1e-9) {
            assert!(
                (f[0] - KT * d).abs() <= 1e-9 * KT * d,
                "step {i}: stick {} vs {}",
                f[0],
                KT * d
            );
        } else {
            slipped = true;
            assert!(
                (f[0] - mu_k * n).abs() <= 1e-12 * n,
                "step {i}: slip {} vs mu_k N = {}",
                f[0],
                mu_k * n
            );
        }
        assert!(f[0].abs() <= mu_s * n * (1.0 + 1e-12));
        c.accept_step(&u, 1e-3);
    }
    assert!(slipped);
    // Dissipation: μ_k N times the anchor's travel, the tool's travel less the spring's
    // stretch when it last stuck (k_t s = μ_k N): μ_k N (1e-2 − μ_k N / k_t), to round-off.
    let expected = mu_k * n * (1e-2 - mu_k * n / KT);
    assert!(
        (c.dissipated() - expected).abs() <= 1e-9 * expected,
        "{} vs {expected}",
        c.dissipated()
    );
}

/// Energy over a drag out and back: the work the tool's driver does, `∫ f_x dd` (trapezoids
/// over 10 µm steps, 1/80 of the stick travel), equals the spring's energy plus the
/// dissipation (0.5 % of it), the dissipation never decreases, and over the closed path the
/// driver's work is positive: slip never creates energy.
#[test]
fn friction_dissipates_in_slip_and_never_creates_energy() {
    let (mut c, u) = dragged(0.4, 0.4, 1.0);
    c.set_time(0.0);
    c.accept_step(&u, 1e-3);
    let h = 1e-5;
    let path: Vec<f64> = (0..=400)
        .map(|i| i as f64 * h)
        .chain((0..400).map(|i| 4e-3 - (i + 1) as f64 * h))
        .collect();
    let (mut work, mut last_d, mut last_w) = (0.0, 0.0, 0.0);
    let mut f_prev = force_at(&mut c, &u, 0.0)[0];
    for &d in &path[1..] {
        let f = force_at(&mut c, &u, d)[0];
        work += 0.5 * (f + f_prev) * (d - last_d);
        c.accept_step(&u, 1e-3);
        f_prev = force_at(&mut c, &u, d)[0];
        let w = c.dissipated();
        assert!(w >= last_w, "dissipation decreased: {w} < {last_w}");
        last_w = w;
        last_d = d;
    }
    let spring = f_prev * f_prev / (2.0 * KT);
    let w = c.dissipated();
    // Slip at μ N = 0.4 N: out 4 mm less 0.8 mm of stick travel, back 4 mm less the 1.6 mm
    // that turn the spring from +0.8 mm to −0.8 mm.
    assert!((w - 0.4 * (3.2e-3 + 2.4e-3)).abs() <= 1e-9, "{w}");
    assert!(work > 0.0, "{work}");
    assert!(
        (work - spring - w).abs() <= 5e-3 * w,
        "work {work} vs stored {spring} + dissipated {w}"
    );
}

/// Zero coefficients give the frictionless forces bit for bit, at every step of a drag.
#[test]
fn zero_friction_reproduces_frictionless_forces_bit_for_bit() {
    let (mut c, u) = dragged(0.0, 0.0, 1e-2);
    let tool = Tool {
        friction: None,
        ..c.tools()[0].clone()
    };
    let mut plain = Contact::new(Box::new(Free(1)), vec![0.0; 3], vec![tool]);
    for i in 0..20 {
        let t = i as f64 / 20.0;
        let (a, b) = (force_at(&mut c, &u, t), force_at(&mut plain, &u, t));
        assert_eq!(a.map(f64::to_bits), b.map(f64::to_bits), "t = {t}");
        assert_eq!(
            c.strain_energy(&u).to_bits(),
            plain.strain_energy(&u).to_bits()
        );
        c.accept_step(&u, 1e-3);
        plain.accept_step(&u, 1e-3);
    }
}

/// A checkpoint restores the anchors: the forces after a restore repeat those after the save.
#[test]
fn friction_history_round_trips_through_a_checkpoint() {
    let (mut c, u) = dragged(0.5, 0.3, 1e-2);
    for i in 0..=10 {
        c.set_time(i as f64 / 100.0);
        c.accept_step(&u, 1e-3);
    }
    let mut h = Vec::new();
    c.save_history(&mut h);
    assert_eq!(h.len(), friction::STATE + 1);
    let before = force_at(&mut c, &u, 0.2);
    for i in 11..=30 {
        c.set_time(i as f64 / 100.0);
        c.accept_step(&u, 1e-3);
    }
    assert_ne!(force_at(&mut c, &u, 0.2), before);
    assert_eq!(c.load_history(&h), h.len());
    assert_eq!(force_at(&mut c, &u, 0.2), before);
}

/// The friction tangent blocks are the derivative of the friction force (normal force held,
/// a plane): stick `k_t (I − n nᵀ)`, slip `μ_k N/|s_t| (I − n nᵀ − ŝ ŝᵀ)`, against central
/// differences of the trial force in the tangent plane.
#[test]
fn friction_tangent_is_the_force_derivative_in_stick_and_slip() {
    let fr = Friction {
        static_coefficient: 0.5,
        kinetic_coefficient: 0.3,
        stiffness: KT,
    };
    let n = [0.0, 0.0, 1.0];
    for (x, slipping) in [([2e-4, -1e-4, 0.0], false), ([2e-3, 1e-3, 0.0], true)] {
        let state = [0.0, 0.0, 0.0, 0.0, 1.0];
        let tr = fr.trial(x, [0.0; 3], n, &state).unwrap();
        assert_eq!(tr.slipping, slipping);
        let b = fr.tangent(n, &tr);
        let h = 1e-9;
        for j in 0..2 {
            let (mut xp, mut xm) = (x, x);
            xp[j] += h;
            xm[j] -= h;
            let fp = fr.trial(xp, [0.0; 3], n, &state).unwrap().force;
            let fm = fr.trial(xm, [0.0; 3], n, &state).unwrap().force;
            for i in 0..3 {
                let fd = -(fp[i] - fm[i]) / (2.0 * h);
                assert!(
                    (fd - b[3 * i + j]).abs() <= 1e-5 * KT,
                    "slip {slipping}: ({i},{j}) {fd} vs {}",
                    b[3 * i + j]
                );
            }
        }
    }
}
