//! Invariants of the multigrid schemes.

use crate::integrate::relax::relax;
use crate::integrate::{Method, State, Stepper};
use crate::multigrid::raisov::{Raisov, RaisovParams, Reading};
use crate::scenario::Scenario;
use std::path::Path;

fn drape(nodes: usize, multigrid: &str, method: &str) -> Scenario {
    let text = format!(
        r#"
gravity = [0.0, 0.0, -9.81]
[mesh]
generate = "rectangle"
size = [0.1, 0.1]
nodes = {nodes}
[material]
law = "mooney-rivlin"
c1 = 1000.0
c2 = 1000.0
[damping]
ratio = 1.0
omega = 177.7
[[fix]]
boundary = true
[integrator]
method = "{method}"
[run]
duration = 1.0
{multigrid}
"#
    );
    Scenario::from_toml(&text, Path::new("mg-test.toml")).unwrap()
}

/// One level: the paper's V-cycle is single-level integration, bit for bit.
#[test]
fn one_level_raisov_is_slim_bit_for_bit() {
    for method in ["rk4", "symplectic-euler"] {
        let slim = drape(120, "", method);
        let mg = drape(
            120,
            "[multigrid]\nscheme = \"raisov-paper\"\nlevels = 1",
            method,
        );
        let mut a = slim.stepper().unwrap();
        let mut b = mg.stepper().unwrap();
        for _ in 0..200 {
            a.advance().unwrap();
            b.advance().unwrap();
        }
        let (_, sa) = a.finest();
        let sa = sa.clone();
        let (_, sb) = b.finest();
        assert_eq!(sa.u, sb.u, "{method}: displacements differ");
        assert_eq!(sa.v, sb.v, "{method}: velocities differ");
        assert_eq!(sa.t, sb.t);
    }
}

/// The fine level's equilibrium (at rest) is a fixed point of the literal cycle under both
/// readings once every level sits at its own equilibrium: nothing moves.
#[test]
fn equilibrium_is_a_fixed_point_of_raisov() {
    for reading in ["paper", "correction"] {
        let sc = drape(
            120,
            &format!("[multigrid]\nscheme = \"raisov-paper\"\nlevels = 3\nreading = \"{reading}\""),
            "symplectic-euler",
        );
        let (mut levels, links) = sc.build_levels().unwrap();
        // Every level at its own static equilibrium (single-level relaxation to round-off).
        let mut eq = Vec::new();
        for l in levels.iter_mut() {
            let dt = 0.5
                * crate::scenario::critical_step_estimate(
                    &l.mesh,
                    &sc.material,
                    sc.density,
                    Method::SymplecticEuler,
                );
            let n = l.num_nodes();
            let r = relax(&mut l.sys, State::at_rest(n), dt, 1e-13, 2_000_000).unwrap();
            assert!(r.converged);
            l.state.u.copy_from_slice(&r.state.u);
            eq.push(r.state.u);
        }
        // X_n = X_(n-1) at the start: the cycle should leave everything in place.
        let params = RaisovParams {
            epsilon: 1e-3 * sc.mesh.edge_range().0,
            reading: if reading == "paper" {
                Reading::Paper
            } else {
                Reading::Correction
            },
            kinetic_limit: f64::INFINITY,
        };
        let mut rs2 = Raisov::new(levels, links, params);
        for _ in 0..20 {
            rs2.advance().unwrap();
        }
        let scale = eq[0].iter().fold(0.0f64, |a, &b| a.max(b.abs()));
        let drift = rs2.levels[0]
            .state
            .u
            .iter()
            .zip(&eq[0])
            .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
        assert!(
            drift <= 1e-9 * scale,
            "{reading}: equilibrium drifts by {drift:e} (scale {scale:e})"
        );
    }
}

/// The convergent multigrid reaches single-level integration's equilibrium on the same mesh,
/// displacements within 1e-8 relative.
#[test]
fn fas_converges_to_slim_equilibrium() {
    for coarse in ["explicit", "newton"] {
        let sc = drape(
            186,
            &format!("[multigrid]\nscheme = \"fas\"\nlevels = 4\ncoarse = \"{coarse}\""),
            "symplectic-euler",
        );
        // SLIM's equilibrium: single-level dynamic relaxation to 1e-12 of the load.
        let mut sys = sc.build_system().unwrap();
        let dt = 0.5 * sc.dt_critical_estimate;
        let r = relax(
            &mut sys,
            State::at_rest(sc.mesh.num_nodes()),
            dt,
            1e-12,
            5_000_000,
        )
        .unwrap();
        assert!(r.converged, "reference did not converge");
        let u_ref = r.state.u;
        let scale = u_ref.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
        let mut st = sc.stepper().unwrap();
        let mut err = f64::INFINITY;
        for _ in 0..3000 {
            st.advance().unwrap();
            let (_, s) = st.finest();
            err =
                s.u.iter()
                    .zip(&u_ref)
                    .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()))
                    / scale;
            if err < 1e-9 {
                break;
            }
        }
        assert!(
            err < 1e-8,
            "{coarse}: FAS ends {err:e} (relative) from SLIM's equilibrium"
        );
    }
}

/// A soft tetrahedral beam clamped at x = 0 and sagging under gravity, over three independent
/// generated levels, solved by FAS with `accelerate`.
fn sagging_beam_fas(accelerate: &str) -> Scenario {
    let text = format!(
        r#"
gravity = [0.0, 0.0, -9.81]
[mesh]
generate = "box"
size = [0.1, 0.03, 0.03]
nodes = 400
[material]
law = "neo-hookean"
young = 5000.0
poisson = 0.45
density = 1060.0
[[fix]]
plane = {{ point = [0.0, 0.0, 0.0], normal = [1.0, 0.0, 0.0] }}
[integrator]
method = "symplectic-euler"
[run]
duration = 1.0
[multigrid]
scheme = "fas"
levels = 3
accelerate = "{accelerate}"
"#
    );
    Scenario::from_toml(&text, Path::new("beam-fas.toml")).unwrap()
}

/// The V-cycle as the preconditioner of nonlinear CG (`accelerate = "cg"`, the default) needs
/// at most 3/4 of the cycles of plain V-cycles to bring the residual of a large-deflection sag
/// (soft beam, ν = 0.45) below 1e-8 of its start (measured 44 against 74), and both reach the
/// same equilibrium. The gain is larger on non-nested levels (the liver: a slow test).
#[test]
fn cg_acceleration_saves_fas_cycles_on_a_sagging_beam() {
    let mut cycles = Vec::new();
    let mut finals = Vec::new();
    for acc in ["cg", "none"] {
        let sc = sagging_beam_fas(acc);
        let mut st = sc.stepper().unwrap();
        let r0 = {
            let (sys, s) = st.finest();
            let mut r = vec![0.0; s.u.len()];
            let u = s.u.clone();
            sys.residual(&u, &mut r).unwrap()
        };
        let mut k = 0;
        loop {
            st.advance().unwrap();
            k += 1;
            let (sys, s) = st.finest();
            let mut r = vec![0.0; s.u.len()];
            let u = s.u.clone();
            if sys.residual(&u, &mut r).unwrap() < 1e-8 * r0 || k == 2000 {
                finals.push(u);
                break;
            }
        }
        cycles.push(k);
    }
    assert!(cycles[0] < 2000, "cg: no convergence in 2000 cycles");
    assert!(
        4 * cycles[0] <= 3 * cycles[1],
        "cg {} cycles, plain {} cycles",
        cycles[0],
        cycles[1]
    );
    let scale = finals[1].iter().fold(0.0f64, |a, &b| a.max(b.abs()));
    let diff = finals[0]
        .iter()
        .zip(&finals[1])
        .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
    assert!(scale > 1e-3, "the beam should sag by millimetres: {scale}");
    assert!(
        diff < 1e-6 * scale,
        "cg and plain cycles differ by {diff:e}"
    );
}

/// Residual reuse in the FAS cycle (a residual computed once at a state serves every later
/// user at that state) saves force evaluations and changes no bit: the same cycles with and
/// without it give identical states, on a drape under gravity and on a lift ramped over the
/// first cycles (a prescribed value that moves between cycles makes the last residual stale),
/// with the finest state read between cycles as `raisov run` does.
#[test]
fn fas_residual_reuse_changes_no_bit_and_saves_evaluations() {
    use crate::multigrid::fas::{Fas, FasParams};
    let lift = "[[displace]]\npoint = [0.0, 0.0, 0.0]\ndisplacement = [0.0, 0.0, 0.01]\n\
                mode = \"ramp\"\nduration = 0.05\n";
    for (case, extra) in [("drape", ""), ("ramped lift", lift)] {
        let sc = drape(
            400,
            &format!("[multigrid]\nscheme = \"fas\"\nlevels = 3\n{extra}"),
            "symplectic-euler",
        );
        let run = |reuse: bool| {
            let (levels, links) = sc.build_levels().unwrap();
            let mut st = Fas::new(
                levels,
                links,
                FasParams {
                    reuse_residuals: reuse,
                    ..FasParams::default()
                },
            );
            let mut trace = Vec::new();
            for k in 0..40 {
                st.advance().unwrap();
                if k % 7 == 0 {
                    let (_, s) = st.finest();
                    trace.push(s.u.clone());
                }
            }
            let (_, s) = st.finest();
            trace.push(s.u.clone());
            (trace, st.force_evaluations())
        };
        let (plain, plain_evals) = run(false);
        let (reused, reused_evals) = run(true);
        assert_eq!(plain, reused, "{case}: reuse changed the states");
        assert!(
            reused_evals < 0.9 * plain_evals,
            "{case}: {reused_evals} evaluations with reuse, {plain_evals} without"
        );
    }
}

/// The literal cycle's transfers run in parallel chunks of nodes: on a mesh of several chunks
/// the states after some cycles are the same bits on one and on two threads.
#[test]
fn raisov_cycle_same_bits_on_one_and_two_threads() {
    let sc = drape(
        9000,
        "[multigrid]\nscheme = \"raisov-paper\"\nlevels = 3",
        "rk4",
    );
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let mut st = sc.stepper().unwrap();
                for _ in 0..5 {
                    st.advance().unwrap();
                }
                let (_, s) = st.finest();
                (s.u.clone(), s.v.clone())
            })
    };
    let (u1, v1) = run(1);
    let (u2, v2) = run(2);
    assert!(u1.iter().any(|&x| x != 0.0));
    assert_eq!(u1, u2, "displacements differ between 1 and 2 threads");
    assert_eq!(v1, v2, "velocities differ between 1 and 2 threads");
}

/// The per-point host sums of the RaISoV strokes (`weighted`, unrolled for 4 or 3 hosts, and
/// `weighted2`, two fields in one pass) give the same bits as `Transfer::interpolate`, which
/// is itself tested against the general loop: on tets and on triangles, both directions.
#[test]
fn stroke_host_sums_equal_interpolate() {
    use super::{weighted, weighted2};
    use crate::hierarchy::Correspondence;
    use crate::mesh::generate::{box_tets, rectangle_membrane, BoxPattern};
    let pairs = [
        (
            box_tets([0.1, 0.04, 0.04], [12, 5, 5], BoxPattern::Five).unwrap(),
            box_tets([0.1, 0.04, 0.04], [7, 3, 3], BoxPattern::Five).unwrap(),
        ),
        (
            rectangle_membrane(0.1, 0.1, 400).unwrap(),
            rectangle_membrane(0.1, 0.1, 150).unwrap(),
        ),
    ];
    for (fine, coarse) in &pairs {
        let c = Correspondence::build(fine, coarse).unwrap();
        for (t, target) in [(&c.down, coarse), (&c.up, fine)] {
            let field = |k: f64| -> Vec<f64> {
                (0..3 * target.num_nodes())
                    .map(|i| (k * i as f64 + 0.3).sin())
                    .collect()
            };
            let (a, b) = (field(0.7), field(1.3));
            let (mut ia, mut ib) = (vec![0.0; 3 * t.len()], vec![0.0; 3 * t.len()]);
            t.interpolate(&a, 3, &mut ia).unwrap();
            t.interpolate(&b, 3, &mut ib).unwrap();
            let bits = |x: &[f64]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            for p in 0..t.len() {
                let [wa, wb] = weighted2(t, p, &a, &b);
                assert_eq!(
                    bits(&weighted(t, p, &a)),
                    bits(&ia[3 * p..3 * p + 3]),
                    "npe {}",
                    t.npe
                );
                assert_eq!(bits(&wa), bits(&ia[3 * p..3 * p + 3]));
                assert_eq!(bits(&wb), bits(&ib[3 * p..3 * p + 3]));
            }
        }
    }
}
