//! Invariants of the multigrid schemes.

use crate::integrate::{Method, State, Stepper, SwitchCounts};
use crate::multigrid::raisov::{Raisov, RaisovParams, Reading};
use crate::scenario::Scenario;
use crate::statics::relax::dynamic::relax;
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
                * crate::integrate::stability::critical_step_estimate(
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
        let dt = 0.5 * sc.integrator.dt_critical_estimate;
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
                let (ra, rb) = (super::rows(&a), super::rows(&b));
                let [wa, wb] = weighted2(t, p, ra, rb);
                assert_eq!(
                    bits(&weighted(t, p, ra)),
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

/// The literal cycle, as the design note writes it: whole-level snapshots `X_n` and `ΔX` taken
/// before the down stroke, serial loops, `|x| > ε` by the square root. The reference for the
/// fused cycle of [`Raisov`]. `prev`: `X_(n−1)` (u, v) per level; returns the switch counts
/// and each coarse level's state after its down-stroke transfer (the `correction` reading's
/// base; empty on level 0).
#[allow(clippy::type_complexity)]
fn literal_cycle(
    levels: &mut [crate::multigrid::Level],
    links: &crate::multigrid::Links,
    params: RaisovParams,
    prev: &mut [(Vec<f64>, Vec<f64>)],
) -> ([(usize, usize); 2], Vec<(Vec<f64>, Vec<f64>)>) {
    use super::{norm3, rows, weighted, weighted2};
    let m = levels.len();
    let eps = params.epsilon;
    let start: Vec<(Vec<f64>, Vec<f64>)> = levels
        .iter()
        .map(|l| (l.state.u.clone(), l.state.v.clone()))
        .collect();
    let diff = |a: &[f64], b: &[f64]| -> Vec<f64> { a.iter().zip(b).map(|(x, y)| x - y).collect() };
    let change: Vec<(Vec<f64>, Vec<f64>)> = start
        .iter()
        .zip(prev.iter())
        .map(|(s, p)| (diff(&s.0, &p.0), diff(&s.1, &p.1)))
        .collect();
    let mut sw = [(0, 0); 2];
    let mut snap: Vec<(Vec<f64>, Vec<f64>)> = vec![(Vec::new(), Vec::new()); m];
    for i in 1..m {
        let t = &links[i - 1].up;
        let (su, sv) = (levels[i - 1].state.u.clone(), levels[i - 1].state.v.clone());
        let (du, dv) = (rows(&change[i - 1].0), rows(&change[i - 1].1));
        let c = &mut levels[i];
        for th in 0..c.num_nodes() {
            let d_u = weighted(t, th, du);
            if norm3(d_u) > eps {
                let [cu, cv] = weighted2(t, th, rows(&su), rows(&sv));
                c.state.u[3 * th..3 * th + 3].copy_from_slice(&cu);
                c.state.v[3 * th..3 * th + 3].copy_from_slice(&cv);
                sw[0].0 += 1;
            } else {
                let d_v = weighted(t, th, dv);
                for q in 0..3 {
                    c.state.u[3 * th + q] += d_u[q];
                    c.state.v[3 * th + q] += d_v[q];
                }
                sw[0].1 += 1;
            }
        }
        let tt = c.state.t;
        c.sys.impose(tt, &mut c.state.u, &mut c.state.v);
        snap[i] = (c.state.u.clone(), c.state.v.clone());
    }
    for i in (0..m).rev() {
        if i + 1 < m {
            let t = &links[i].down;
            let (cu_all, cv_all) = (levels[i + 1].state.u.clone(), levels[i + 1].state.v.clone());
            let (bu_all, bv_all) = match params.reading {
                Reading::Paper => (&start[i + 1].0, &start[i + 1].1),
                Reading::Correction => (&snap[i + 1].0, &snap[i + 1].1),
            };
            let f = &mut levels[i];
            for th in 0..f.num_nodes() {
                let own = [
                    change[i].0[3 * th],
                    change[i].0[3 * th + 1],
                    change[i].0[3 * th + 2],
                ];
                let [cu, cv] = weighted2(t, th, rows(&cu_all), rows(&cv_all));
                if norm3(own) > eps {
                    f.state.u[3 * th..3 * th + 3].copy_from_slice(&cu);
                    f.state.v[3 * th..3 * th + 3].copy_from_slice(&cv);
                    sw[1].0 += 1;
                } else {
                    let [bu, bv] = weighted2(t, th, rows(bu_all), rows(bv_all));
                    for q in 0..3 {
                        f.state.u[3 * th + q] += cu[q] - bu[q];
                        f.state.v[3 * th + q] += cv[q] - bv[q];
                    }
                    sw[1].1 += 1;
                }
            }
            let tt = f.state.t;
            f.sys.impose(tt, &mut f.state.u, &mut f.state.v);
        }
        let l = &mut levels[i];
        l.integrator.step(&mut l.sys, &mut l.state, l.dt).unwrap();
        l.evaluations += 1;
    }
    prev.clone_from_slice(&start);
    (sw, snap)
}

/// The fused cycle (ΔX and `X_n` taken by the strokes, level 0's change summed on the fly,
/// snapshots written by the transfers, `|x| > ε` without the square root) gives the same bits
/// as the literal whole-level cycle on every level, with the same switch counts: both
/// readings, tets (a ramped displacement, 3 levels) and triangles (4 and 2 levels), at an ε
/// where both branches of both strokes are taken.
#[test]
fn fused_cycle_equals_the_literal_cycle() {
    let beam = |reading: &str| {
        Scenario::from_toml(
            &format!(
                r#"
gravity = [0.0, -9.81, 0.0]
[mesh]
generate = "box"
size = [0.1, 0.04, 0.04]
nodes = 600
[material]
law = "neo-hookean"
young = 50000.0
poisson = 0.4
density = 1000.0
[[fix]]
plane = {{ point = [0.0, 0.0, 0.0], normal = [1.0, 0.0, 0.0] }}
[[displace]]
point = [0.063, 0.017, 0.023]
displacement = [0.0, 0.004, 0.0]
mode = "ramp"
duration = 0.002
[integrator]
method = "symplectic-euler"
[run]
duration = 1.0
[multigrid]
scheme = "raisov-paper"
levels = 3
reading = "{reading}"
"#
            ),
            Path::new("beam-raisov.toml"),
        )
        .unwrap()
    };
    for reading in ["paper", "correction"] {
        let membrane = |levels: usize| {
            drape(
                900,
                &format!(
                    "[multigrid]\nscheme = \"raisov-paper\"\nlevels = {levels}\nreading = \"{reading}\""
                ),
                "symplectic-euler",
            )
        };
        for (name, sc, eps_rel) in [
            ("tets", beam(reading), 2e-3),
            ("triangles", membrane(4), 1e-3),
            ("triangles, 2 levels", membrane(2), 1e-3),
        ] {
            let (levels, links) = sc.build_levels().unwrap();
            let (mut ref_levels, ref_links) = sc.build_levels().unwrap();
            let params = RaisovParams {
                epsilon: eps_rel * levels[0].mesh.edge_range().0,
                reading: if reading == "paper" {
                    Reading::Paper
                } else {
                    Reading::Correction
                },
                kinetic_limit: f64::INFINITY,
            };
            let mut prev: Vec<_> = ref_levels
                .iter()
                .map(|l| (l.state.u.clone(), l.state.v.clone()))
                .collect();
            let mut fused = Raisov::new(levels, links, params);
            let mut seen = [[false; 2]; 2];
            for cycle in 0..40 {
                fused.advance().unwrap();
                let (sw, snap) = literal_cycle(&mut ref_levels, &ref_links, params, &mut prev);
                assert_eq!(fused.last_switches, sw, "{name} {reading}: cycle {cycle}");
                // The bookkeeping too: X_n, and the snapshots the next up stroke reads.
                for (i, b) in fused.bookkeeping().into_iter().enumerate() {
                    assert!(
                        b[0] == prev[i].0 && b[1] == prev[i].1,
                        "{name} {reading}: X_n of level {i} differs after cycle {cycle}"
                    );
                    if reading == "correction" && i > 0 {
                        assert!(
                            b[2] == snap[i].0 && b[3] == snap[i].1,
                            "{name} {reading}: snapshot of level {i} differs after cycle {cycle}"
                        );
                    }
                }
                for (k, s) in sw.iter().enumerate() {
                    seen[k][0] |= s.0 > 0;
                    seen[k][1] |= s.1 > 0;
                }
                for (i, (a, b)) in fused.levels.iter().zip(&ref_levels).enumerate() {
                    assert!(
                        a.state.u == b.state.u && a.state.v == b.state.v,
                        "{name} {reading}: level {i} differs after cycle {cycle}"
                    );
                }
            }
            assert_eq!(
                seen, [[true; 2]; 2],
                "{name} {reading}: not every branch taken"
            );
            assert!(fused.levels[0].state.u.iter().any(|&x| x != 0.0));
        }
    }
}

/// `Above` decides `|x| > ε` exactly as the square root does: at random sizes, at vectors
/// whose norm is within a few ulps of ε, and for 0, NaN and infinite entries.
#[test]
fn above_decides_like_the_norm() {
    use super::{norm3, Above};
    let mut seed = 0x9e3779b97f4a7c15u64;
    let mut rnd = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    for e in [
        0.0,
        1e-300,
        3.7e-7,
        1e-3,
        0.3,
        1.0,
        7.9e150,
        1e200,
        f64::INFINITY,
    ] {
        let a = Above::new(e);
        let check = |x: [f64; 3]| {
            assert_eq!(a.test(x), norm3(x) > e, "eps {e:e}, x {x:?}");
        };
        check([0.0; 3]);
        check([f64::NAN, 0.0, 0.0]);
        check([f64::INFINITY, 0.0, 0.0]);
        for _ in 0..20_000 {
            let d = [rnd() - 0.5, rnd() - 0.5, rnd() - 0.5];
            let n = norm3(d);
            // Scaled to |x| = ε (1 ± a few ulps), and at random sizes around ε.
            let k = e / n * (1.0 + (rnd() - 0.5) * 8.0 * f64::EPSILON);
            check(d.map(|x| x * k));
            check(d.map(|x| x * e * 10f64.powf(4.0 * rnd() - 2.0)));
        }
    }
}

/// The `correction` reading is the classic coarse-grid correction: δX^(i+1) is level i+1's
/// state after its whole up-stroke minus its state before it received anything from level
/// i+2, so the coarsest level's change reaches level 0. Three levels at rest, ε so large that
/// every transfer is a variation, and G a no-op on levels 0 and 1 (Δ = 0): one cycle moves only
/// the coarsest level (by its own step δ₂), and level 0 must then hold P₀₁ P₁₂ δ₂ on its free
/// nodes (P the up-stroke interpolations), level 1 P₁₂ δ₂.
#[test]
fn coarsest_correction_reaches_level_zero() {
    use super::{rows, weighted};
    let sc = drape(
        300,
        "[multigrid]\nscheme = \"raisov-paper\"\nlevels = 3\nreading = \"correction\"",
        "symplectic-euler",
    );
    let (mut levels, links) = sc.build_levels().unwrap();
    levels[0].dt = 0.0;
    levels[1].dt = 0.0;
    let params = RaisovParams {
        epsilon: 1e30,
        reading: Reading::Correction,
        kinetic_limit: f64::INFINITY,
    };
    let mut rs = Raisov::new(levels, links, params);
    rs.advance().unwrap();
    let coarse = rs.levels[2].state.u.clone();
    let scale = coarse.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
    assert!(scale > 0.0, "the coarsest level did not move");
    for i in [1usize, 0] {
        let src = rs.levels[i + 1].state.u.clone();
        let l = &rs.levels[i];
        let mut moved = 0.0f64;
        for th in 0..l.num_nodes() {
            if l.sys.constraints.is_constrained(th) {
                continue;
            }
            let want = weighted(&rs.links[i].down, th, rows(&src));
            for q in 0..3 {
                let got = l.state.u[3 * th + q];
                moved = moved.max(got.abs());
                assert!(
                    (got - want[q]).abs() <= 1e-12 * scale,
                    "level {i} node {th}: {got:e}, the interpolated correction {:e}",
                    want[q]
                );
            }
        }
        assert!(
            moved > 0.1 * scale,
            "level {i} did not receive the correction"
        );
    }
}

/// The switch counts of [`Stepper::switch_counts`] sum every cycle's transfers: each stroke
/// transfers every node of the levels it writes once per cycle, the state fraction lies in
/// (0, 1) at an ε where both branches fire, and is 0 with ε = ∞ (the state branch of eqs. 10
/// and 12 cannot trigger).
#[test]
fn switch_counts_sum_the_cycles_and_vanish_without_a_threshold() {
    let sc = drape(
        900,
        "[multigrid]\nscheme = \"raisov-paper\"\nlevels = 3\nreading = \"correction\"",
        "symplectic-euler",
    );
    for eps_rel in [1e-3, f64::INFINITY] {
        let (levels, links) = sc.build_levels().unwrap();
        let sizes: Vec<u64> = levels.iter().map(|l| l.num_nodes() as u64).collect();
        let params = RaisovParams {
            epsilon: eps_rel * levels[0].mesh.edge_range().0,
            reading: Reading::Correction,
            kinetic_limit: f64::INFINITY,
        };
        let mut r = Raisov::new(levels, links, params);
        assert_eq!(r.switch_counts().unwrap().state_fraction(), None);
        let cycles = 40u64;
        let mut sum = SwitchCounts::default();
        for _ in 0..cycles {
            r.advance().unwrap();
            let [(ds, dv), (us, uv)] = r.last_switches;
            sum.down_state += ds as u64;
            sum.down_variation += dv as u64;
            sum.up_state += us as u64;
            sum.up_variation += uv as u64;
        }
        let c = r.switch_counts().unwrap();
        assert_eq!(c, sum);
        // Down stroke: levels 1 and 2; up stroke: levels 0 and 1.
        assert_eq!(
            c.down_state + c.down_variation,
            cycles * (sizes[1] + sizes[2])
        );
        assert_eq!(c.up_state + c.up_variation, cycles * (sizes[0] + sizes[1]));
        let f = c.state_fraction().unwrap();
        let fd = c.down_state_fraction().unwrap();
        if eps_rel.is_finite() {
            assert!(0.0 < f && f < 1.0, "state fraction {f}: {c:?}");
            assert!((0.0..=1.0).contains(&fd));
        } else {
            assert_eq!((c.down_state, c.up_state), (0, 0));
            assert_eq!((f, fd), (0.0, 0.0));
        }
    }
}

/// The default run printed three "hosts do not cover" warnings a newcomer could not act on:
/// now one note says what uncovered nodes mean and that a few are harmless, and a large share
/// is still a warning.
#[test]
fn uncovered_levels_get_one_note_not_a_warning_per_link() {
    use super::{covering_note, UNCOVERED_WARN_SHARE};
    let text = covering_note([(0, 187, 2), (1, 103, 2), (2, 55, 1)].into_iter());
    assert_eq!(text.lines().count(), 1, "{text}");
    assert!(text.starts_with("note: levels not covered"), "{text}");
    assert!(
        text.contains("2 of level 0's 187 nodes, 2 of level 1's 103 nodes and 1 of level 2's 55 nodes are a corner"),
        "{text}"
    );
    assert!(text.contains("harmless"), "{text}");
    let one = covering_note([(2, 55, 1)].into_iter());
    assert!(one.contains("1 of level 2's 55 nodes is a corner"), "{one}");
    assert_eq!(covering_note(std::iter::empty()), "");
    let many = (UNCOVERED_WARN_SHARE * 100.0) as usize + 1;
    let large = covering_note([(0, 100, many)].into_iter());
    assert!(
        large.starts_with("warning:") && large.contains("large share"),
        "{large}"
    );
}
