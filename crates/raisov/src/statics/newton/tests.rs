//! Direct Newton and Newton-multigrid: equilibria, convergence, lifted pulls, reuse.

use super::*;
use crate::scenario::Scenario;
use crate::statics::nested::*;
use std::path::Path;

/// A soft neo-Hookean beam (ν = 0.45) clamped at x = 0, sagging under gravity, with
/// `extra` appended (a `[multigrid]` section).
fn beam(extra: &str) -> Scenario {
    let text = format!(
        r#"
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
plane = {{ point = [0.0, 0.0, 0.0], normal = [1.0, 0.0, 0.0] }}
[integrator]
method = "symplectic-euler"
[run]
duration = 1.0
{extra}
"#
    );
    Scenario::from_toml(&text, Path::new("beam-newton.toml")).unwrap()
}

/// A Mooney-Rivlin membrane (C1 = C2 = 1 kPa) fixed on its boundary, sagging under gravity
/// from flat (a singular first tangent).
fn drape(extra: &str) -> Scenario {
    drape_sized(186, extra)
}

/// [`drape`] with about `nodes` nodes.
fn drape_sized(nodes: usize, extra: &str) -> Scenario {
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
method = "symplectic-euler"
[run]
duration = 1.0
{extra}
"#
    );
    Scenario::from_toml(&text, Path::new("drape-newton.toml")).unwrap()
}

/// The beam (FAS over 3 levels, two load steps) and the drape (FAS over `drape_levels`
/// levels, one load step): name, scenario, load steps.
fn beam_and_drape(drape_levels: usize) -> [(&'static str, Scenario, usize); 2] {
    [
        ("beam", beam("[multigrid]\nscheme = \"fas\"\nlevels = 3"), 2),
        (
            "membrane",
            drape(&format!(
                "[multigrid]\nscheme = \"fas\"\nlevels = {drape_levels}"
            )),
            1,
        ),
    ]
}

/// `sc`'s levels, the index of Newton-multigrid's coarse level ([`coarse_level`]) and the
/// transfer from the finest level to it.
fn coarse_pair(sc: &Scenario) -> (Vec<crate::mesh::Mesh>, usize, Vec<Transfer>) {
    let meshes = sc.level_meshes().unwrap();
    let nodes: Vec<usize> = meshes.iter().map(|m| m.num_nodes()).collect();
    let c = coarse_level(&nodes).expect("a coarse level");
    let down = vec![Transfer::build(&meshes[0].nodes, &meshes[c]).unwrap()];
    (meshes, c, down)
}

/// The largest displacement of `reference` and the largest difference of `u` from it.
fn max_diff(reference: &[f64], u: &[f64]) -> (f64, f64) {
    let scale = reference.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
    let err = reference
        .iter()
        .zip(u)
        .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
    (scale, err)
}

fn newton(sc: &Scenario, params: DirectNewtonParams) -> (Vec<f64>, DirectStatic) {
    let mut sys = sc.build_system().unwrap();
    let mut u = vec![0.0; 3 * sc.mesh.num_nodes()];
    let out = solve_system(&mut sys, 0.0, &mut u, params).unwrap();
    (u, out)
}

/// Near the solution the residual falls quadratically: once it is below 1e-2 of the load,
/// each iteration's (relative) residual is at most 100 × the square of the previous one,
/// down to the round-off floor (1e-11 of the load). Measured, largest nodal residual over
/// the largest nodal load: beam 1.6e-3, 7.9e-5, 4.8e-10, 1.0e-12; membrane (from flat)
/// 5.2e-2, 1.4e-3, 3.3e-8, 3.1e-13. And the solve converges to 1e-10 of the load.
#[test]
fn direct_newton_converges_quadratically() {
    for (name, sc, steps) in [("beam", beam(""), 2), ("membrane", drape(""), 1)] {
        let params = DirectNewtonParams {
            load_steps: steps,
            ..Default::default()
        };
        let (_, out) = newton(&sc, params);
        assert!(out.converged, "{name}: {out:?}");
        let vmax = (out.target - params.abs_tol) / params.rel_tol;
        let e: Vec<f64> = out.history.iter().map(|r| r / vmax).collect();
        let mut checked = 0;
        for w in e.windows(2) {
            if w[0] < 1e-2 && w[1] > 1e-11 {
                assert!(
                    w[1] <= 100.0 * w[0] * w[0],
                    "{name}: residual ratios {e:?} are not quadratic"
                );
                checked += 1;
            }
        }
        assert!(
            checked >= 1,
            "{name}: no iteration near the solution: {e:?}"
        );
    }
}

/// The beam with its tip node pushed 1.5 cm sideways into it, held from t = 0.
fn pushed_beam() -> Scenario {
    beam(
        r#"
[[displace]]
point = [0.1, 0.03, 0.03]
displacement = [0.0, -0.015, 0.0]
mode = "held"
"#,
    )
}

/// A prescribed displacement that would invert elements if applied at once (the tip node
/// of the beam pushed 1.5 cm into it, sideways) is applied over the load steps: the solve converges,
/// the node sits at its prescribed value, and only the start's record is infinite.
#[test]
fn direct_newton_applies_a_large_prescribed_displacement_over_its_load_steps() {
    let sc = pushed_beam();
    let (node, _) = sc.prescribed[0];
    let mut u = vec![0.0; 3 * sc.mesh.num_nodes()];
    u[3 * node as usize + 1] = -0.015;
    let inverted = sc
        .build_system()
        .unwrap()
        .residual(&u, &mut vec![0.0; u.len()]);
    assert!(inverted.is_err(), "the jump should invert an element");
    let (u, out) = newton(
        &sc,
        DirectNewtonParams {
            load_steps: 10,
            ..Default::default()
        },
    );
    assert!(out.converged, "{out:?}");
    assert_eq!(out.initial_residual, f64::INFINITY);
    assert!((u[3 * node as usize + 1] + 0.015).abs() < 1e-15);
}

/// The jump that inverts an element when imposed alone is taken in one load step: the
/// lifted first iteration moves the free nodes with the pulled one, and the equilibrium is
/// the ten-step one (displacements within 1e-9 of the largest), with factorisations and
/// with the multigrid-free CG reuse alike.
#[test]
fn direct_newton_lifts_a_large_prescribed_displacement_in_one_step() {
    let sc = pushed_beam();
    let (stepped, _) = newton(
        &sc,
        DirectNewtonParams {
            load_steps: 10,
            ..Default::default()
        },
    );
    let umax = stepped.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    for pcg_max in [0, 20] {
        let (u, out) = newton(
            &sc,
            DirectNewtonParams {
                pcg_max,
                ..Default::default()
            },
        );
        assert!(out.converged, "{out:?}");
        assert_eq!(out.lifted_steps, 1);
        let gap = u
            .iter()
            .zip(&stepped)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(
            gap <= 1e-9 * umax,
            "pcg_max {pcg_max}: gap {gap:e} of {umax:e}"
        );
    }
}

/// Fixed components reach the direct solver: with every node's z held (plane strain) and
/// gravity along −y, the beam sags in y, z stays exactly 0, and the free components'
/// residual converges. A tilted sliding plane (every node keeps `u·n = 0`, `n` along
/// (0, 1, 1)) is solved by projection: the beam sags within the plane, `u·n` stays 0 to
/// 1e-15 of the sag, and the stopping rule holds.
#[test]
fn direct_newton_holds_fixed_components_and_tilted_planes() {
    let mut held = beam(
        "[[fix]]\nbox = { min = [-1.0, -1.0, -1.0], max = [1.0, 1.0, 1.0] }\ncomponents = [\"z\"]",
    );
    held.gravity = [0.0, -9.81, 0.0];
    let (u, out) = newton(&held, DirectNewtonParams::default());
    assert!(out.converged, "{out:?}");
    let max_y = u.chunks(3).map(|c| c[1].abs()).fold(0.0, f64::max);
    assert!(max_y > 1e-4, "the beam should sag in y: {max_y:e}");
    assert!(u.chunks(3).all(|c| c[2] == 0.0), "z moved");

    let tilted = beam("[[fix]]\nbox = { min = [-1.0, -1.0, -1.0], max = [1.0, 1.0, 1.0] }\nnormal = [0.0, 1.0, 1.0]");
    let (u, out) = newton(&tilted, DirectNewtonParams::default());
    assert!(out.converged, "{out:?}");
    let sag = u.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
    assert!(sag > 1e-4, "the beam should sag within the plane: {sag:e}");
    let s = std::f64::consts::FRAC_1_SQRT_2;
    let off = u
        .chunks(3)
        .map(|c| (s * c[1] + s * c[2]).abs())
        .fold(0.0, f64::max);
    assert!(off <= 1e-15 * sag, "u·n = {off:e} against a sag of {sag:e}");
}

/// A block held by three symmetry planes (x = 0, y = 0, z = 0 slide along their normals)
/// stretched by a body force (a neo-Hookean octant model, strains about 0.3), then the whole
/// problem turned by a rotation `Q` (nodes, sliding normals, body force): every plane is then
/// oblique, and the direct solver, which eliminates the axis components of the first and
/// projects those of the second (module `oblique`), finds `Q u` to 1e-9 of the largest
/// displacement; so does Newton-multigrid. Newton-Krylov (matrix-free, projected) on the
/// rotated problem agrees to 1e-8 of it.
#[test]
fn oblique_symmetry_planes_solve_as_the_axis_ones_rotated() {
    let text = r#"
gravity = [9.81, 4.9, -19.6]
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
normal = [1.0, 0.0, 0.0]
[[fix]]
plane = { point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }
normal = [0.0, 1.0, 0.0]
[[fix]]
plane = { point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }
normal = [0.0, 0.0, 1.0]
[multigrid]
scheme = "fas"
levels = 3
[run]
duration = 1.0
"#;
    let axis = Scenario::from_toml(text, Path::new("octant.toml")).unwrap();
    // Q: a rotation by 0.7 rad about (1, 2, 3)/√14 (Rodrigues).
    let k = [1.0 / 14f64.sqrt(), 2.0 / 14f64.sqrt(), 3.0 / 14f64.sqrt()];
    let (sn, cs) = 0.7f64.sin_cos();
    let mut q = [[0.0; 3]; 3];
    for (i, row) in q.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            let kx = [[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]];
            *v = if i == j { cs } else { 0.0 } + sn * kx[i][j] + (1.0 - cs) * k[i] * k[j];
        }
    }
    let turn = |x: [f64; 3]| -> [f64; 3] {
        std::array::from_fn(|i| q[i][0] * x[0] + q[i][1] * x[1] + q[i][2] * x[2])
    };
    let mut turned = axis.clone();
    turned
        .model
        .mesh
        .nodes
        .iter_mut()
        .for_each(|x| *x = turn(*x));
    turned
        .model
        .sliding
        .iter_mut()
        .for_each(|(_, n)| *n = turn(*n));
    turned.model.gravity = turn(axis.gravity);
    assert!(turned.sliding.iter().all(|&(_, n)| axis_of(n).is_none()));

    let params = DirectNewtonParams {
        load_steps: 2,
        ..Default::default()
    };
    let (u, out) = newton(&axis, params);
    assert!(out.converged, "axis planes: {out:?}");
    let expected: Vec<f64> = u.chunks(3).flat_map(|c| turn([c[0], c[1], c[2]])).collect();
    let (ut, out) = newton(&turned, params);
    assert!(out.converged, "oblique planes: {out:?}");
    let (scale, err) = max_diff(&expected, &ut);
    assert!(scale > 5e-3, "the block should stretch: {scale:e}");
    assert!(err <= 1e-9 * scale, "direct: {err:e} of {scale:e}");
    for &(a, n) in &turned.sliding {
        let i = 3 * a as usize;
        let d = ut[i] * n[0] + ut[i + 1] * n[1] + ut[i + 2] * n[2];
        assert!(d.abs() <= 1e-15 * scale, "node {a}: u·n = {d:e}");
    }

    // Newton-multigrid over the rotated levels.
    let (meshes, c, _) = coarse_pair(&turned);
    let coarse: Vec<[f64; 3]> = meshes[c].nodes.iter().map(|x| turn(*x)).collect();
    let coarse_mesh = crate::mesh::Mesh {
        nodes: coarse,
        ..meshes[c].clone()
    };
    let down = vec![Transfer::build(&turned.mesh.nodes, &coarse_mesh).unwrap()];
    let mut sys = turned.build_system().unwrap();
    let mut um = vec![0.0; ut.len()];
    let mut mg =
        DirectNewton::with_levels(&*sys.force, &sys.mass, &sys.constraints, &down).unwrap();
    let System {
        force,
        f_ext,
        constraints,
        springs,
        ..
    } = &mut sys;
    let mgp = DirectNewtonParams {
        multigrid: Some(MultigridPcg::default()),
        ..params
    };
    let out = mg
        .solve(&mut **force, springs, constraints, f_ext, 0.0, &mut um, mgp)
        .unwrap();
    assert!(out.converged, "multigrid: {out:?}");
    assert!(out.cg_iterations > 0, "{out:?}");
    let (_, err) = max_diff(&expected, &um);
    assert!(err <= 1e-9 * scale, "multigrid: {err:e} of {scale:e}");

    // Newton with matrix-free conjugate gradients on the rotated problem.
    let mut sys = turned.build_system().unwrap();
    let mut uf = vec![0.0; ut.len()];
    let out = solve_system_matrix_free(
        &mut sys,
        None,
        0.0,
        &mut uf,
        params,
        MatrixFreeCg::default(),
    )
    .unwrap();
    assert!(out.converged, "matrix-free: {out:?}");
    let (_, err) = max_diff(&expected, &uf);
    eprintln!("matrix-free {out:?}: {err:e} of {scale:e}");
    assert!(err <= 1e-8 * scale, "matrix-free: {err:e} of {scale:e}");

    // Newton-Krylov on the rotated problem.
    let mut sys = turned.build_system().unwrap();
    let mut uk = vec![0.0; ut.len()];
    let st = crate::statics::krylov::NewtonSolver::new(&sys)
        .solve(
            &mut sys,
            0.0,
            &mut uk,
            crate::statics::krylov::NewtonParams {
                rel_tol: 1e-10,
                ..Default::default()
            },
        )
        .unwrap();
    let (_, err) = max_diff(&expected, &uk);
    eprintln!("krylov {st:?}: {err:e} of {scale:e}");
    assert!(err <= 1e-8 * scale, "krylov: {err:e} of {scale:e} ({st:?})");
}

/// Reusing a factorisation as the conjugate-gradient preconditioner (inexact Newton)
/// lands on the same equilibrium as refactoring at every iteration, displacements within
/// 1e-8 of the largest, meets the same stopping rule, and factors fewer times than it
/// iterates: the beam (2 load steps) and the membrane from flat.
#[test]
fn factorisation_reuse_reaches_the_same_equilibrium_with_fewer_factorisations() {
    for (name, sc, steps) in [("beam", beam(""), 2), ("membrane", drape(""), 1)] {
        let plain = DirectNewtonParams {
            load_steps: steps,
            ..Default::default()
        };
        let (u_plain, out_plain) = newton(&sc, plain);
        let (u_reuse, out_reuse) = newton(
            &sc,
            DirectNewtonParams {
                pcg_max: 20,
                ..plain
            },
        );
        assert!(
            out_plain.converged && out_reuse.converged,
            "{name}: {out_reuse:?}"
        );
        assert!(out_reuse.residual <= out_reuse.target);
        assert!(
            out_reuse.cg_iterations > 0,
            "{name}: no CG step: {out_reuse:?}"
        );
        assert!(
            out_reuse.factorizations < out_reuse.newton_steps,
            "{name}: {} factorisations for {} iterations",
            out_reuse.factorizations,
            out_reuse.newton_steps
        );
        let (scale, err) = max_diff(&u_plain, &u_reuse);
        assert!(err <= 1e-8 * scale, "{name}: {err:e} of {scale:e}");
    }
}

/// Direct Newton and FAS land on the same equilibrium, displacements within 1e-8 of the
/// largest: the sagging beam (tets, 3 levels) and the draped membrane (4 levels).
/// Newton with CG preconditioned by the Galerkin V-cycle over generated levels reaches
/// plain direct Newton's equilibrium (1e-8 of max |u|) under the same stopping rule,
/// without factoring the finest level.
#[test]
fn multigrid_preconditioned_newton_reaches_the_direct_equilibrium() {
    let cases = beam_and_drape(3);
    for (name, sc, steps) in cases {
        let plain = DirectNewtonParams {
            load_steps: steps,
            ..Default::default()
        };
        let (u_plain, out_plain) = newton(&sc, plain);
        assert!(out_plain.converged, "{name}: {out_plain:?}");
        let meshes = sc.level_meshes().unwrap();
        let down: Vec<Transfer> = meshes
            .windows(2)
            .map(|w| Transfer::build(&w[0].nodes, &w[1]).unwrap())
            .collect();
        let solve = |keep: bool, smoother: Smoother, coarse_precision: Precision| {
            let mut sys = sc.build_system().unwrap();
            let mut u = vec![0.0; 3 * sc.mesh.num_nodes()];
            let model = &mut *sys.force;
            let mut s =
                DirectNewton::with_levels(&*model, &sys.mass, &sys.constraints, &down).unwrap();
            let out = s
                .solve(
                    model,
                    &sys.springs,
                    &sys.constraints,
                    &sys.f_ext,
                    0.0,
                    &mut u,
                    DirectNewtonParams {
                        multigrid: Some(MultigridPcg {
                            sweeps: 2,
                            smoother,
                            max_iter: 1000,
                            keep,
                            coarse_precision,
                        }),
                        ..plain
                    },
                )
                .unwrap();
            (u, out)
        };
        // The coarse solve in f32 (the default) and its f64 reference.
        for (keep, smoother, precision) in [
            (false, Smoother::ColouredBlock, Precision::Single),
            (true, Smoother::ColouredBlock, Precision::Single),
            (false, Smoother::GaussSeidel, Precision::Single),
            (false, Smoother::BlockJacobi, Precision::Single),
            (true, Smoother::BlockJacobi, Precision::Single),
            (false, Smoother::BlockJacobi, Precision::Double),
        ] {
            let (u_mg, out_mg) = solve(keep, smoother, precision);
            assert!(
                out_mg.converged,
                "{name}, keep {keep}, {smoother:?}, {precision:?}: {out_mg:?}"
            );
            assert!(out_mg.residual <= out_mg.target);
            assert_eq!(
                out_mg.factorizations, 0,
                "{name}: the fine level was factored"
            );
            assert!(out_mg.cg_iterations > 0);
            let (scale, err) = max_diff(&u_plain, &u_mg);
            assert!(
                err <= 1e-8 * scale,
                "{name}, keep {keep}, {smoother:?}, {precision:?}: {err:e} of {scale:e}"
            );
        }
    }
}

#[test]
fn direct_newton_and_fas_agree() {
    let cases = beam_and_drape(4);
    for (name, sc, steps) in cases {
        let params = DirectNewtonParams {
            rel_tol: 1e-12,
            load_steps: steps,
            ..Default::default()
        };
        let (u_newton, out) = newton(&sc, params);
        assert!(out.converged, "{name}: {out:?}");
        let scale = u_newton.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
        let mut st = sc.stepper().unwrap();
        let mut err = f64::INFINITY;
        for _ in 0..5000 {
            st.advance().unwrap();
            let (_, s) = st.finest();
            err =
                s.u.iter()
                    .zip(&u_newton)
                    .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()))
                    / scale;
            if err < 1e-9 {
                break;
            }
        }
        assert!(
            err < 1e-8,
            "{name}: FAS ends {err:e} (relative) from Newton's"
        );
    }
}

/// Nested iteration: from the coarse level's equilibrium, interpolated, Newton-multigrid
/// reaches the cold start's equilibrium (1e-8 of the largest displacement) in fewer fine
/// Newton iterations; the start holds the constrained dofs at their imposed values and
/// inverts no element. Measured (fine Newton iterations from rest, from the coarse start):
/// beam over two load steps 29 and 7; membrane from flat 12 and 7.
#[test]
fn coarse_start_reaches_the_same_equilibrium_in_fewer_fine_iterations() {
    let cases = beam_and_drape(3);
    for (name, sc, steps) in cases {
        let (meshes, c, down) = coarse_pair(&sc);
        let solve = |nested: bool| {
            let mut sys = sc.build_system().unwrap();
            let mut u = vec![0.0; 3 * sc.mesh.num_nodes()];
            let model = &mut *sys.force;
            let mut load_steps = steps;
            if nested {
                let mut coarse = sc.level_system(&meshes[c], c).unwrap();
                let start = coarse_start(
                    &mut coarse,
                    0.0,
                    steps,
                    &down[0],
                    model,
                    &sys.constraints,
                    &mut u,
                );
                assert!(start.applied, "{name}: {start:?}");
                assert!(start.coarse.as_ref().unwrap().converged);
                assert!(model.min_det_f(&u).1 > 0.0);
                for a in 0..u.len() / 3 {
                    if sys.constraints.is_constrained(a) {
                        assert_eq!(&u[3 * a..3 * a + 3], &[0.0; 3], "{name}: node {a}");
                    }
                }
                assert!(u.iter().any(|&x| x != 0.0));
                load_steps = 1;
            }
            let mut s =
                DirectNewton::with_levels(&*model, &sys.mass, &sys.constraints, &down).unwrap();
            let out = s
                .solve(
                    model,
                    &sys.springs,
                    &sys.constraints,
                    &sys.f_ext,
                    0.0,
                    &mut u,
                    DirectNewtonParams {
                        load_steps,
                        multigrid: Some(MultigridPcg {
                            max_iter: 1000,
                            ..Default::default()
                        }),
                        ..Default::default()
                    },
                )
                .unwrap();
            assert!(out.converged, "{name}, nested {nested}: {out:?}");
            (u, out)
        };
        let (u_cold, cold) = solve(false);
        let (u_warm, warm) = solve(true);
        eprintln!(
            "{name}: cold {} fine iterations, coarse start {}",
            cold.newton_steps, warm.newton_steps
        );
        assert!(
            warm.newton_steps < cold.newton_steps,
            "{name}: {} !< {}",
            warm.newton_steps,
            cold.newton_steps
        );
        let (scale, err) = max_diff(&u_cold, &u_warm);
        assert!(err <= 1e-8 * scale, "{name}: {err:e} of {scale:e}");
    }
}

/// The start through a level between ([`nested_start`] over [`start_levels`]: a drape of
/// about 3 000 nodes through its 750-node level from its 188-node one): every level's solve
/// converges, the start holds the fixed boundary and inverts nothing, and the fine
/// Newton-multigrid iteration from it lands on direct Newton's equilibrium (1e-8 of the
/// largest displacement) in no more Newton iterations than from the coarse level alone,
/// and fewer than from flat. Measured: 15 from flat, 8 from the coarse level, 7 through the
/// level between.
#[test]
fn start_through_a_level_between_lands_on_the_equilibrium_in_fewer_fine_iterations() {
    let sc = drape_sized(3000, "[multigrid]\nscheme = \"fas\"\nlevels = 5");
    let nodes: Vec<usize> = sc
        .level_meshes()
        .unwrap()
        .iter()
        .map(|m| m.num_nodes())
        .collect();
    let (meshes, c, down) = coarse_pair(&sc);
    let chain = start_levels(&nodes, c);
    assert_eq!(chain.len(), 2, "{nodes:?}: {chain:?}");
    let (u_ref, _) = newton(
        &sc,
        DirectNewtonParams {
            rel_tol: 1e-10,
            ..Default::default()
        },
    );
    let solve = |levels: Option<&[usize]>| {
        let mut sys = sc.build_system().unwrap();
        let mut u = vec![0.0; 3 * sc.mesh.num_nodes()];
        let model = &mut *sys.force;
        if let Some(levels) = levels {
            let mut nested = sc.nested_levels(levels, (&meshes[c], c)).unwrap();
            assert_eq!(nested.between.len(), levels.len() - 1);
            let start = nested_start(
                &mut nested,
                0.0,
                1,
                model,
                &sys.constraints,
                &mut u,
                BetweenSolve::Multigrid(Smoother::ColouredBlock),
            );
            assert!(start.applied, "{start:?}");
            assert!(start.coarse.as_ref().unwrap().converged);
            assert_eq!(start.between.len(), levels.len() - 1);
            assert!(start.between.iter().all(|o| o.converged), "{start:?}");
            assert!(model.min_det_f(&u).1 > 0.0);
            for a in 0..u.len() / 3 {
                if sys.constraints.is_constrained(a) {
                    assert_eq!(&u[3 * a..3 * a + 3], &[0.0; 3], "node {a}");
                }
            }
        }
        let mut s = DirectNewton::with_levels(&*model, &sys.mass, &sys.constraints, &down).unwrap();
        let out = s
            .solve(
                model,
                &sys.springs,
                &sys.constraints,
                &sys.f_ext,
                0.0,
                &mut u,
                DirectNewtonParams {
                    rel_tol: 1e-10,
                    multigrid: Some(MultigridPcg {
                        smoother: Smoother::ColouredBlock,
                        ..Default::default()
                    }),
                    ..Default::default()
                },
            )
            .unwrap();
        assert!(out.converged, "{levels:?}: {out:?}");
        let (scale, err) = max_diff(&u_ref, &u);
        assert!(err <= 1e-8 * scale, "{levels:?}: {err:e} of {scale:e}");
        out.newton_steps
    };
    let cold = solve(None);
    let single = solve(Some(&[c]));
    let through = solve(Some(&chain));
    eprintln!("fine Newton iterations: from flat {cold}, from the coarse level {single}, through {chain:?} {through}");
    assert!(
        through <= single && through < cold,
        "{cold}, {single}, {through}"
    );
}

/// A frame loop runs one Newton-multigrid iteration per call of [`DirectNewton::solve`] on
/// the draped membrane from flat. Each call used to start from σ = 0: the flat first tangent
/// broke down, the regularised step failed its line search, and the σ raised for the next
/// iteration was lost with the call, so the membrane never left flat (residual 1.0 of the
/// load, frame after frame). σ is now carried from call to call: the loop converges, within
/// 40 calls, to the equilibrium of one whole solve (1e-8 of the largest displacement).
#[test]
fn one_newton_iteration_per_frame_leaves_the_flat_membrane() {
    let sc = drape("[multigrid]\nscheme = \"fas\"\nlevels = 3");
    let (_, _, down) = coarse_pair(&sc);
    let mut sys = sc.build_system().unwrap();
    let f = sys.f_ext.clone();
    let model = &mut *sys.force;
    let params = DirectNewtonParams {
        multigrid: Some(MultigridPcg::default()),
        ..Default::default()
    };
    let mut whole = vec![0.0; f.len()];
    let out = DirectNewton::with_levels(&*model, &sys.mass, &sys.constraints, &down)
        .unwrap()
        .solve(
            model,
            &sys.springs,
            &sys.constraints,
            &f,
            0.0,
            &mut whole,
            params,
        )
        .unwrap();
    assert!(out.converged, "{out:?}");
    let mut frames =
        DirectNewton::with_levels(&*model, &sys.mass, &sys.constraints, &down).unwrap();
    let mut u = vec![0.0; f.len()];
    let mut calls = 0;
    let mut last = None;
    while calls < 40 {
        calls += 1;
        let o = frames
            .solve(
                model,
                &sys.springs,
                &sys.constraints,
                &f,
                0.0,
                &mut u,
                DirectNewtonParams {
                    max_newton: 1,
                    ..params
                },
            )
            .unwrap();
        let done = o.converged;
        last = Some(o);
        if done {
            break;
        }
    }
    assert!(last.as_ref().unwrap().converged, "{calls} calls: {last:?}");
    let (scale, err) = max_diff(&whole, &u);
    assert!(
        err <= 1e-8 * scale,
        "{err:.3e} of {scale:.3e} after {calls} calls"
    );
}

/// Conjugate gradients stopped at their iteration limit and started again from their iterate
/// (a Newton-multigrid solve whose kept hierarchy missed η, rebuilt) keep the work done: they
/// reach the tolerance in fewer iterations than from zero, at the same solution, and a start
/// that already meets it takes none.
#[test]
fn conjugate_gradients_from_their_own_iterate_keep_the_work_done() {
    // A shifted 1-D Laplacian (condition number about 9), Jacobi-preconditioned.
    let n = 200;
    let matvec = |x: &[f64], y: &mut [f64]| {
        for i in 0..n {
            let left = if i > 0 { x[i - 1] } else { 0.0 };
            let right = if i + 1 < n { x[i + 1] } else { 0.0 };
            y[i] = 2.5 * x[i] - left - right;
        }
    };
    let precond = |r: &[f64], z: &mut [f64]| z.iter_mut().zip(r).for_each(|(z, r)| *z = r / 2.5);
    let b: Vec<f64> = (0..n).map(|i| (i as f64 * 0.1).sin() + 0.5).collect();
    let tol = 1e-8 * b.iter().map(|v| v * v).sum::<f64>().sqrt();
    let mut cold = vec![0.0; n];
    let PcgEnd::Converged(k_cold) = pcg(matvec, precond, &b, &mut cold, tol, 1000) else {
        panic!("no convergence from zero");
    };
    let mut x = vec![0.0; n];
    assert_eq!(pcg(matvec, precond, &b, &mut x, tol, 8), PcgEnd::MaxIter);
    let PcgEnd::Converged(k_warm) = pcg_from(matvec, precond, &b, &mut x, true, tol, 1000, None)
    else {
        panic!("no convergence from the iterate");
    };
    assert!(
        k_warm + 5 <= k_cold,
        "{k_warm} iterations from the iterate, {k_cold} from zero"
    );
    let gap = x
        .iter()
        .zip(&cold)
        .map(|(a, c)| (a - c).abs())
        .fold(0.0, f64::max);
    let xmax = cold.iter().map(|v| v.abs()).fold(0.0, f64::max);
    assert!(
        gap <= 1e-6 * xmax,
        "the two solutions differ by {gap:e} of {xmax:e}"
    );
    assert_eq!(
        pcg_from(matvec, precond, &b, &mut x, true, tol, 1000, None),
        PcgEnd::Converged(0)
    );
}

/// The two-level rule: the finest level with at most 1/16 of the nodes, else the coarsest, of
/// the levels with at least 1/32 of them. Before, the 70k-node mesher liver took its 8 765-node
/// level (the coarsest with at least 1/16), whose factor made each CG iteration twice as dear
/// as with its 4 344-node level.
#[test]
fn coarse_level_is_the_finest_with_at_most_a_sixteenth_of_the_nodes() {
    // The shipped liver L0: no level has as few as 1/16 of its nodes; the coarsest.
    assert_eq!(coarse_level(&[16693, 7547, 3764, 2088]), Some(3));
    // The mesher's 70k and 17k livers.
    assert_eq!(
        coarse_level(&[70633, 35204, 17359, 8765, 4344, 2186]),
        Some(4)
    );
    assert_eq!(coarse_level(&[17160, 8582, 4283, 2143, 1056]), Some(4));
    // A level below 1/32 does not qualify; one level halving qualifies.
    assert_eq!(coarse_level(&[70633, 2000]), None);
    assert_eq!(coarse_level(&[1000, 500]), Some(1));
    assert_eq!(coarse_level(&[1000]), None);
    assert_eq!(coarse_level(&[]), None);
}

/// The nested start's levels: about a quarter of the nodes apart, the coarsest with at
/// least 1 000 nodes (or the coarse level's count).
#[test]
fn start_levels_step_down_by_about_four() {
    // The 100k drape's requested counts: 25k, 6.25k, 1.56k; its coarse level is the 6.25k.
    let drape = [100000, 50000, 25000, 12500, 6250, 3125, 1563];
    assert_eq!(coarse_level(&drape), Some(4));
    assert_eq!(start_levels(&drape, 4), vec![2, 4, 6]);
    // The 10k drape: the coarse level (625 nodes) is the coarsest, and 2.5k above it.
    let drape = [10000, 5000, 2500, 1250, 625];
    assert_eq!(start_levels(&drape, 4), vec![2, 4]);
    // The shipped liver L0: the coarse level alone (L2 is not 3 times L3's nodes).
    assert_eq!(start_levels(&[16693, 7547, 3764, 2088], 3), vec![3]);
    // Levels halving down to 1 056 nodes, the coarse level: the 4 283-node level above it.
    assert_eq!(
        start_levels(&[17160, 8582, 4283, 2143, 1056], 4),
        vec![2, 4]
    );
    // A fine level less than 3 times the coarse one: the coarse level alone.
    assert_eq!(start_levels(&[1000, 500], 1), vec![1]);
    assert!(start_levels(&[1000], 0).is_empty());
    assert!(start_levels(&[1000, 500], 2).is_empty());
}

/// The tangent's pattern built node by node and element by element in parallel
/// (`pattern::build`) is the simple reference's, slot for slot, on a beam with a clamped end,
/// a roller (one component held) and a plane of nodes held along x (two free dofs each),
/// and on a drape fixed on its boundary.
#[test]
fn tangent_pattern_matches_the_reference() {
    let roller = r#"
[[fix]]
plane = { point = [0.1, 0.0, 0.0], normal = [-1.0, 0.0, 0.0] }
components = ["z"]
[[fix]]
plane = { point = [0.05, 0.0, 0.0], normal = [-1.0, 0.0, 0.0] }
normal = [1.0, 0.0, 0.0]
"#;
    for (sc, rollers) in [(beam(roller), true), (drape(""), false)] {
        let mut sys = sc.build_system().unwrap();
        let constraints = sys.constraints.clone();
        let model = &mut *sys.force;
        let s = DirectNewton::new(&*model, &sys.mass, &constraints).unwrap();
        let partial = (0..s.dofs.free.len() / 3)
            .filter(|&a| {
                let held = (0..3)
                    .filter(|&k| s.dofs.free[3 * a + k] == usize::MAX)
                    .count();
                held == 1 || held == 2
            })
            .count();
        assert_eq!(
            partial > 0,
            rollers,
            "{partial} nodes with some components held"
        );
        let elements = model.tangent_elements().unwrap();
        let fast = pattern::build(&elements, &s.dofs.free, s.dofs.nfree).unwrap();
        let simple = pattern::reference(&elements, &s.dofs.free, s.dofs.nfree);
        assert_eq!(fast.col_ptr, simple.col_ptr);
        assert_eq!(fast.row_idx, simple.row_idx);
        assert_eq!(fast.diag, simple.diag);
        assert_eq!(fast.slots, simple.slots);
        assert!(fast.slots.iter().any(|&x| x != u32::MAX));
    }
}

/// The drape's fine Newton-multigrid solve from the coarse start. Its first tangent is
/// indefinite (the interpolated coarse shape leaves the fine mesh slack in places), and
/// conjugate gradients met negative curvature at their second direction. Steihaug's
/// truncation took the first iterate, a step along a nearly singular direction thousands of
/// times too long: every line-search trial inverted elements, the iteration was lost (14
/// energy evaluations, and its hierarchy, built at a rejected step, rebuilt after the next;
/// 10k drape: 10 fine iterations, 100k: 9).
/// Such a direction now raises σ past the shift at which its curvature vanishes and the
/// system is solved again: no step is rejected, and the solve ends at the equilibrium of the
/// solve from rest.
#[test]
fn negative_curvature_after_the_coarse_start_raises_the_shift_instead_of_a_truncated_jump() {
    let sc = drape_sized(2000, "[multigrid]\nscheme = \"fas\"\nlevels = 5");
    let (meshes, c, down) = coarse_pair(&sc);
    let mut sys = sc.build_system().unwrap();
    let model = &mut *sys.force;
    let mut u = vec![0.0; 3 * sc.mesh.num_nodes()];
    let mut coarse = sc.level_system(&meshes[c], c).unwrap();
    let start = coarse_start(
        &mut coarse,
        0.0,
        1,
        &down[0],
        model,
        &sys.constraints,
        &mut u,
    );
    assert!(start.applied, "{start:?}");
    let params = DirectNewtonParams {
        multigrid: Some(MultigridPcg {
            smoother: Smoother::ColouredBlock,
            ..Default::default()
        }),
        ..Default::default()
    };
    let out = DirectNewton::with_levels(&*model, &sys.mass, &sys.constraints, &down)
        .unwrap()
        .solve(
            model,
            &sys.springs,
            &sys.constraints,
            &sys.f_ext,
            0.0,
            &mut u,
            params,
        )
        .unwrap();
    assert!(out.converged, "{out:?}");
    assert_eq!(out.rejected_steps, 0, "{out:?}");
    let mut rest = vec![0.0; u.len()];
    let cold = DirectNewton::with_levels(&*model, &sys.mass, &sys.constraints, &down)
        .unwrap()
        .solve(
            model,
            &sys.springs,
            &sys.constraints,
            &sys.f_ext,
            0.0,
            &mut rest,
            params,
        )
        .unwrap();
    assert!(cold.converged, "{cold:?}");
    let (scale, err) = max_diff(&rest, &u);
    assert!(err <= 1e-8 * scale, "{err:e} of {scale:e}");
}

/// Asked for it, conjugate gradients hand back the direction of non-positive curvature that
/// would truncate them, with its curvature `pᵀAp`, and keep the iterate before it; the same
/// solve without the buffer is Steihaug's truncation at the same iterate.
#[test]
fn conjugate_gradients_return_the_direction_of_negative_curvature() {
    // diag(4, 2, 1, −1): from b = (1, 1, 1, 1) and Jacobi on |A|, the first direction has
    // positive curvature (4·(1/4)² + 2·(1/2)² + 1 − 1 = 0.75), a later one not.
    let d = [4.0, 2.0, 1.0, -1.0];
    let matvec = |x: &[f64], y: &mut [f64]| (0..4).for_each(|i| y[i] = d[i] * x[i]);
    let precond = |r: &[f64], z: &mut [f64]| (0..4).for_each(|i| z[i] = r[i] / d[i].abs());
    let b = [1.0; 4];
    let mut dir = Vec::new();
    let mut x = vec![0.0; 4];
    let end = pcg_from(
        matvec,
        precond,
        &b,
        &mut x,
        false,
        1e-12,
        50,
        Some(&mut dir),
    );
    let PcgEnd::Negative(it, pq) = end else {
        panic!("{end:?}");
    };
    assert!(it >= 1);
    assert_eq!(dir.len(), 4);
    let curvature: f64 = (0..4).map(|i| d[i] * dir[i] * dir[i]).sum();
    assert!(pq <= 0.0 && (curvature - pq).abs() <= 1e-12 * curvature.abs().max(1.0));
    let mut y = vec![0.0; 4];
    assert_eq!(
        pcg_from(matvec, precond, &b, &mut y, false, 1e-12, 50, None),
        PcgEnd::Truncated(it)
    );
    assert_eq!(x, y);
    // The iterate descends: b·x > 0.
    assert!(b.iter().zip(&x).map(|(b, x)| b * x).sum::<f64>() > 0.0);
}

/// Regression: on the multigrid path a σ raised at an indefinite tangent was divided by 10 a
/// full step, so it regularised up to ten more iterations (the 70k mesher liver: σ = 0.26 at its
/// third iteration, 0 only at its fourteenth, each step in between converging linearly). A
/// full step now sets it back to 0 there; the factorisation path, where each σ that turns out
/// too small costs a failed factorisation, still divides it by 10. One Newton iteration a call
/// on the flat drape, whose first tangent needs σ > 0, shows each call's σ.
#[test]
fn issue_multigrid_shift_lingers_after_full_steps() {
    let sc = drape("[multigrid]\nscheme = \"fas\"\nlevels = 3");
    let (_, _, down) = coarse_pair(&sc);
    let mut sys = sc.build_system().unwrap();
    let f = sys.f_ext.clone();
    let model = &mut *sys.force;
    // (σ after the call, whether its step was full) per call, until converged.
    let mut frames = |multigrid: Option<MultigridPcg>| {
        let mut s = DirectNewton::with_levels(&*model, &sys.mass, &sys.constraints, &down).unwrap();
        let mut u = vec![0.0; f.len()];
        let mut calls = Vec::new();
        for _ in 0..60 {
            let params = DirectNewtonParams {
                max_newton: 1,
                multigrid,
                pcg_max: if multigrid.is_some() { 0 } else { 20 },
                ..Default::default()
            };
            let o = s
                .solve(
                    model,
                    &sys.springs,
                    &sys.constraints,
                    &f,
                    0.0,
                    &mut u,
                    params,
                )
                .unwrap();
            calls.push((s.sigma, o.full_steps == 1));
            if o.converged {
                return calls;
            }
        }
        panic!("not converged in 60 calls: {calls:?}");
    };
    let mg = frames(Some(MultigridPcg::default()));
    assert!(
        mg.iter().any(|&(sigma, _)| sigma > 0.0),
        "the flat drape's first tangents need σ > 0: {mg:?}"
    );
    for (k, &(sigma, full)) in mg.iter().enumerate() {
        if full {
            assert_eq!(sigma, 0.0, "call {k}: σ left after a full step: {mg:?}");
        }
    }
    let direct = frames(None);
    assert!(
        direct.iter().any(|&(sigma, full)| full && sigma > 0.0),
        "the factorisation path divides σ by 10 a full step: {direct:?}"
    );
}
