//! The liver (L1 of `data/`, with L2 and L3 as FAS's coarse levels), held on the cap of its
//! top and sagging under gravity: direct Newton (analytic tangent, sparse Cholesky, 4 load
//! steps), FAS and adaptive dynamic relaxation (single level) reach one common residual criterion, the largest nodal residual over free
//! nodes at most 1e-8 of the largest nodal load, and land on the same equilibrium (1e-6 of
//! the largest displacement). Prints wall time and force evaluations of each.
//!
//! The same three on the paper's drape (10 cm square membrane, Mooney-Rivlin C1 = C2 = 1 kPa,
//! edges fixed, gravity) at 10k nodes, FAS on 5 generated levels.
//!
//! Slow (liver meshes): `cargo test -p raisov --test liver_newton_direct_vs_fas -- --ignored --nocapture`
//! (add `--release` for release timings).

use raisov::integrate::adaptive_relax::adaptive_relax;
use raisov::integrate::newton_direct::{solve_system, DirectNewtonParams};
use raisov::integrate::stability::lambda_max_bound;
use raisov::scenario::Scenario;
use std::path::Path;
use std::time::Instant;

const MESHES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../data");
const REL_TOL: f64 = 1e-8;

fn max_nodal(x: &[f64]) -> f64 {
    x.chunks(3)
        .map(|c| (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt())
        .fold(0.0, f64::max)
}

/// Direct Newton, FAS and adaptive dynamic relaxation on `sc` (FAS: its `[multigrid]`), to
/// the largest nodal residual ≤ [`REL_TOL`] × the largest nodal load; prints a table row per
/// solver and checks the three equilibria agree within 1e-6 of the largest displacement.
fn compare(name: &str, sc: &Scenario, load_steps: usize) {
    let n = sc.mesh.num_nodes();
    let mut sys = sc.build_system().unwrap();
    let vmax = max_nodal(&sys.f_ext);
    let t0 = Instant::now();
    let mut u_newton = vec![0.0; 3 * n];
    let params = DirectNewtonParams {
        rel_tol: REL_TOL,
        abs_tol: 0.0,
        load_steps,
        ..Default::default()
    };
    let out = solve_system(&mut sys, 0.0, &mut u_newton, params).unwrap();
    let newton_wall = t0.elapsed().as_secs_f64();
    assert!(out.converged, "{out:?}");

    // FAS, stopped on the same criterion (the residual check each cycle is included).
    let t0 = Instant::now();
    let mut st = sc.stepper().unwrap();
    let mut r = vec![0.0; 3 * n];
    let mut cycles = 0;
    let mut res = f64::INFINITY;
    while res > REL_TOL * vmax && cycles < 20_000 {
        st.advance().unwrap();
        cycles += 1;
        let (sys, s) = st.finest();
        let u = s.u.clone();
        sys.residual(&u, &mut r).unwrap();
        res = max_nodal(&r);
    }
    let fas_wall = t0.elapsed().as_secs_f64();
    let (_, s) = st.finest();
    let u_fas = s.u.clone();

    // Adaptive dynamic relaxation on the finest mesh alone.
    let mut sys = sc.build_system().unwrap();
    let lmax = lambda_max_bound(&sc.mesh, &sc.material, sc.density);
    let t0 = Instant::now();
    let mut u_adr = vec![0.0; 3 * n];
    let adr = adaptive_relax(
        &mut sys, &sc.mesh, lmax, 0.0, &mut u_adr, REL_TOL, 0.0, 2_000_000,
    )
    .unwrap();
    let adr_wall = t0.elapsed().as_secs_f64();
    let scale = u_newton.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
    let dist = |v: &[f64]| {
        u_newton
            .iter()
            .zip(v)
            .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()))
    };
    let (diff, diff_adr) = (dist(&u_fas), dist(&u_adr));
    println!(
        "{name} ({n} nodes), stop at max nodal residual <= {REL_TOL:e} x max nodal load ({vmax:.3e} N):\n  \
         direct Newton: {newton_wall:.2} s ({:.2} s assembling, {:.2} s factorising), {} Newton iterations ({} factorisations, {load_steps} load steps), {} force and {} energy evaluations, residual {:.2e} N\n  \
         FAS ({} levels): {fas_wall:.2} s, {cycles} cycles, {:.0} finest-equivalent force evaluations, residual {res:.2e} N\n  \
         adaptive dynamic relaxation (finest only): {adr_wall:.2} s, {} steps (force evaluations), converged {}, residual {:.2e} N\n  \
         max |u| {scale:.4e} m, max |u_newton - u_fas| {diff:.2e} m, max |u_newton - u_adr| {diff_adr:.2e} m",
        out.assembly_s,
        out.factor_s,
        out.newton_steps,
        out.factorizations,
        out.force_evaluations,
        out.energy_evaluations,
        out.residual,
        st.num_levels(),
        st.force_evaluations(),
        adr.steps,
        adr.converged,
        adr.residual
    );
    assert!(res <= REL_TOL * vmax, "FAS did not converge: {res:e} N");
    assert!(diff <= 1e-6 * scale, "equilibria differ by {diff:e} m");
    assert!(adr.converged, "adaptive relaxation: {adr:?}");
    assert!(
        diff_adr <= 1e-6 * scale,
        "ADR's equilibrium differs by {diff_adr:e} m"
    );
}

#[test]
#[ignore = "slow: liver meshes; run with --ignored"]
fn liver_direct_newton_fas_and_adr_reach_the_same_equilibrium() {
    let dir = Path::new(MESHES);
    assert!(
        dir.join("liver_L1.msh").is_file(),
        "liver meshes not found under {}",
        dir.display()
    );
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
scheme = "fas"
files = ["{d}/liver_L2.msh", "{d}/liver_L3.msh"]
"#,
        d = dir.display()
    );
    let sc = Scenario::from_toml(&text, Path::new("liver-newton.toml")).unwrap();
    compare("liver L1", &sc, 4);
}

#[test]
#[ignore = "slow: 10k-node membrane; run with --ignored"]
fn membrane_10k_direct_newton_fas_and_adr_reach_the_same_equilibrium() {
    let text = r#"
gravity = [0.0, 0.0, -9.81]
[mesh]
generate = "rectangle"
size = [0.1, 0.1]
nodes = 10000
[material]
law = "mooney-rivlin"
c1 = 1000.0
c2 = 1000.0
[[fix]]
boundary = true
[run]
duration = 1.0
[multigrid]
scheme = "fas"
levels = 5
"#;
    let sc = Scenario::from_toml(text, Path::new("drape-10k-newton.toml")).unwrap();
    compare("membrane 10k", &sc, 1);
}
