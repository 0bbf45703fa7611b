use super::*;
use crate::fem::{FemModel, FemParams};
use crate::geometry::{cross, sub};
use crate::integrate::Method;
use crate::material::{lame, Material, NeoHookean, StableNeoHookean};
use crate::mesh::generate::{box_tets, BoxPattern};
use crate::multigrid::fas::{CoarseSolve, FasParams};
use crate::scenario::Scenario;
use std::path::Path;

const SIDE: f64 = 0.04;
const G: [f64; 3] = [0.0, 0.0, -9.81];

/// Compressible neo-Hookean, E = 5 kPa, ν = 0.45 (not defined for inverted elements).
fn classic_neo_hookean() -> Material {
    let (lambda, mu) = lame(5e3, 0.45);
    Material::NeoHookean(NeoHookean { lambda, mu })
}

fn cube(div: usize) -> Mesh {
    box_tets([SIDE; 3], [div; 3], BoxPattern::Six).unwrap()
}

/// A cube fixed at its base under gravity, solved by Newton at every step: each frame ends
/// at the static equilibrium (to the solver's tolerance).
fn static_cube(div: usize) -> Simulation {
    static_cube_under(div, G)
}

/// [`static_cube`] under gravity `g`.
fn static_cube_under(div: usize, g: [f64; 3]) -> Simulation {
    SimulationBuilder::new(cube(div))
        .gravity(g)
        .fix(|p| p[2] <= 0.0)
        .scheme(Scheme::Fas(FasParams {
            coarse: CoarseSolve::Newton { rel_tol: 1e-11 },
            ..FasParams::default()
        }))
        .build()
        .unwrap()
}

fn converge(sim: &mut Simulation) {
    for _ in 0..10 {
        let r = sim.step_frame(Budget::Cycles(1));
        assert!(r.accepted, "{r:?}");
        if r.residual < 1e-11 {
            break;
        }
    }
}

fn norm(x: [f64; 3]) -> f64 {
    (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt()
}

#[test]
fn grab_takes_the_surface_patch_and_holds_it_rigidly() {
    let mut sim = static_cube(4);
    let r = 0.011;
    let g = sim.grab([0.02, 0.0205, 0.05], r).unwrap();
    // The nearest surface point is straight below on the top face; the patch is the top-face
    // nodes within r of it (node spacing 1 cm: the centre and its 4 neighbours).
    let top = [0.02, 0.0205, SIDE];
    let expected: Vec<u32> = (0..sim.mesh().num_nodes() as u32)
        .filter(|&a| {
            let p = sim.mesh().nodes[a as usize];
            (p[2] - SIDE).abs() < 1e-12 && norm(crate::mesh::sub(p, top)) <= r
        })
        .collect();
    assert_eq!(expected.len(), 5);
    assert_eq!(sim.grab_nodes(g).unwrap(), &expected[..]);
    assert_eq!(sim.grab_position(g).unwrap(), top);
    let before: Vec<[f64; 3]> = sim.positions().to_vec();
    let d = [0.001, -0.002, 0.004];
    sim.move_grab(g, [top[0] + d[0], top[1] + d[1], top[2] + d[2]])
        .unwrap();
    let rep = sim.step_frame(Budget::Cycles(2));
    assert!(
        rep.accepted && rep.target_reached && rep.cycles == 2,
        "{rep:?}"
    );
    // Every grasped node moved by exactly d (to rounding of x + d − X); no other node of the
    // top face did.
    for (a, (p, q)) in before.iter().zip(sim.positions()).enumerate() {
        let moved = crate::mesh::sub(*q, *p);
        let err = norm(crate::mesh::sub(moved, d));
        if expected.contains(&(a as u32)) {
            assert!(err < 1e-15, "node {a}: moved {moved:?}");
        } else if (p[2] - SIDE).abs() < 1e-12 {
            assert!(err > 1e-5, "node {a} outside the patch moved with it");
        }
    }
    // Released nodes are free: the residual there drops at the next equilibrium.
    sim.release(g).unwrap();
    assert!(sim.grab_force(g).is_err());
    converge(&mut sim);
    for &a in &expected {
        assert!(!sim.constrained[a as usize]);
    }
}

#[test]
fn grab_force_balances_reactions_and_body_force_at_equilibrium() {
    let mut sim = static_cube(4);
    let g = sim.grab([0.02, 0.02, 0.06], 0.011).unwrap();
    let p = sim.grab_position(g).unwrap();
    sim.move_grab(g, [p[0] + 0.002, p[1], p[2] + 0.004])
        .unwrap();
    converge(&mut sim);
    assert!(sim.residual() < 1e-10, "residual {}", sim.residual());
    let f = sim.grab_force(g).unwrap();
    // Independently: Σ over the grasped nodes of V − R(u), V = m g from the lumped mass.
    // The builder's default law.
    let mut model = FemModel::new(
        sim.mesh(),
        FemParams::new(Material::StableNeoHookean(StableNeoHookean::from_young(
            5e3, 0.45,
        ))),
    )
    .unwrap();
    let mass = model.lumped_mass();
    let mut r = vec![0.0; sim.displacements().len()];
    model.internal_forces(sim.displacements(), &mut r).unwrap();
    let mut want = [0.0; 3];
    for &a in sim.grab_nodes(g).unwrap() {
        for k in 0..3 {
            want[k] += mass[a as usize] * G[k] - r[3 * a as usize + k];
        }
    }
    assert!(
        norm(crate::mesh::sub(f, want)) < 1e-12 * norm(want),
        "{f:?} {want:?}"
    );
    // Lifted and pulled along +x: the tissue pulls the tool down and back.
    assert!(f[2] < 0.0 && f[0] < 0.0, "{f:?}");
    // Equilibrium: what the tool and the supports take from the tissue is the whole load.
    let react = sim.reactions();
    let load = sim.total_load();
    let total: f64 = sim.mass.iter().sum();
    assert!((load[2] - total * G[2]).abs() < 1e-15);
    let mut imbalance = [0.0; 3];
    for k in 0..3 {
        imbalance[k] = f[k] + react.sum[k] - load[k];
    }
    // Bounded by the free nodes' residual (≤ 1e-10 N each, 64 − 21 nodes) plus rounding.
    let scale = norm(load) + norm(f);
    assert!(
        norm(imbalance) < 1e-9 * scale,
        "imbalance {imbalance:?} N, load {load:?}, grab {f:?}, supports {:?}",
        react.sum
    );
}

#[test]
fn grab_stiffness_matches_finite_differences_of_the_grab_force() {
    let mut sim = static_cube(3);
    let g = sim.grab([0.02, 0.02, 0.06], 0.01).unwrap();
    let p0 = sim.grab_position(g).unwrap();
    let x0 = [p0[0], p0[1], p0[2] + 0.004];
    sim.move_grab(g, x0).unwrap();
    converge(&mut sim);
    let k = sim.grab_stiffness(g).unwrap();
    // Warm-started again at the same state: the same tangent to the solve's tolerance.
    let k2 = sim.grab_stiffness(g).unwrap();
    let kmax = k.iter().flatten().fold(0.0f64, |a, &b| a.max(b.abs()));
    assert!(kmax > 10.0, "{k:?}");
    let h = 1e-4;
    for axis in 0..3 {
        let mut f = [[0.0; 3]; 2];
        for (s, side) in [1.0, -1.0].into_iter().enumerate() {
            let mut x = x0;
            x[axis] += side * h;
            sim.move_grab(g, x).unwrap();
            converge(&mut sim);
            f[s] = sim.grab_force(g).unwrap();
        }
        for i in 0..3 {
            let fd = (f[0][i] - f[1][i]) / (2.0 * h);
            assert!(
                (fd - k[i][axis]).abs() < 2e-3 * kmax,
                "K[{i}][{axis}] = {} against FD {fd} (max |K| {kmax})",
                k[i][axis]
            );
            assert!((k2[i][axis] - k[i][axis]).abs() < 1e-5 * kmax);
        }
    }
    // Symmetric (a conservative system) and negative definite along the diagonal.
    for i in 0..3 {
        assert!(k[i][i] < 0.0);
        for j in 0..3 {
            assert!((k[i][j] - k[j][i]).abs() < 2e-3 * kmax, "{k:?}");
        }
    }
}

#[test]
fn a_violent_move_is_recovered_and_never_poisons_the_state() {
    // The classic neo-Hookean law, whose inverted elements are rejected (the stable default
    // has finite forces there).
    let mut sim = SimulationBuilder::new(cube(3))
        .material(classic_neo_hookean())
        .scheme(Scheme::SingleLevel(Method::SymplecticEuler))
        .damping(50.0)
        .fix(|p| p[2] <= 0.0)
        .build()
        .unwrap();
    let g = sim.grab([0.02, 0.02, 0.05], 0.02).unwrap();
    for _ in 0..3 {
        assert!(sim.step_frame(Budget::Cycles(5)).accepted);
    }
    let before_u = sim.displacements().to_vec();
    let before_t = sim.time();
    let p = sim.grab_position(g).unwrap();
    // Through the fixed base: the top face would pass the bottom one.
    sim.move_grab(g, [p[0], p[1], -0.03]).unwrap();
    let rep = sim.step_frame(Budget::Cycles(5));
    assert!(rep.retries > 0, "{rep:?}");
    assert!(rep.rejection.is_some());
    assert!(sim.displacements().iter().all(|x| x.is_finite()));
    assert!(sim.velocities().iter().all(|x| x.is_finite()));
    assert!(sim.positions().iter().flatten().all(|x| x.is_finite()));
    assert!(sim.residual().is_finite());
    if rep.accepted {
        assert!(rep.target_reached);
    } else {
        // Back to the state before the frame, bit for bit, the grasp where it was.
        assert!(!rep.target_reached);
        assert_eq!(sim.displacements(), &before_u[..]);
        assert_eq!(sim.time(), before_t);
        assert_eq!(sim.grab_position(g).unwrap(), p);
    }
    // A gentle move afterwards still works.
    sim.move_grab(g, [p[0], p[1], p[2] + 0.001]).unwrap();
    let rep = sim.step_frame(Budget::Cycles(20));
    assert!(rep.accepted && rep.target_reached, "{rep:?}");
}

#[test]
fn a_small_violent_move_is_split_into_sub_moves() {
    // Explicit dynamics without damping of a 2 mm jump of a 1 cm element: the single jump
    // inverts, halves do not.
    let mut sim = SimulationBuilder::new(cube(4))
        .material(classic_neo_hookean())
        .scheme(Scheme::SingleLevel(Method::SymplecticEuler))
        .damping(100.0)
        .fix(|p| p[2] <= 0.0)
        .build()
        .unwrap();
    let g = sim.grab([0.02, 0.02, 0.05], 0.0).unwrap();
    assert_eq!(sim.grab_nodes(g).unwrap().len(), 1);
    let p = sim.grab_position(g).unwrap();
    sim.move_grab(g, [p[0], p[1], p[2] - 0.012]).unwrap();
    let rep = sim.step_frame(Budget::Cycles(64));
    assert!(rep.accepted, "{rep:?}");
    assert!(rep.retries >= 1, "{rep:?}");
    assert!(rep.target_reached);
    assert_eq!(sim.grab_position(g).unwrap(), [p[0], p[1], p[2] - 0.012]);
}

#[test]
fn pins_hold_their_patch_where_it_stands() {
    let mut sim = static_cube(4);
    let g = sim.grab([0.02, 0.02, 0.05], 0.005).unwrap();
    let p = sim.grab_position(g).unwrap();
    // Pin a corner region of the top face first (where it stands: at rest).
    let pin = sim.pin([0.0, 0.0, 0.05], 0.011).unwrap();
    let pinned = sim.pin_nodes(pin).unwrap().to_vec();
    assert!(pinned.len() >= 3);
    sim.move_grab(g, [p[0], p[1], p[2] + 0.004]).unwrap();
    converge(&mut sim);
    for &a in &pinned {
        let u = &sim.displacements()[3 * a as usize..3 * a as usize + 3];
        assert_eq!(u, &[0.0; 3][..], "pinned node {a} moved");
        assert!(sim.reactions().nodes.contains(&a));
    }
    sim.unpin(pin).unwrap();
    converge(&mut sim);
    let moved = pinned
        .iter()
        .map(|&a| {
            norm(crate::mesh::sub(
                sim.positions()[a as usize],
                sim.mesh().nodes[a as usize],
            ))
        })
        .fold(0.0, f64::max);
    assert!(moved > 1e-5, "unpinned nodes stayed: {moved} m");
}

#[test]
fn cycles_frames_give_the_same_bits_on_one_and_two_threads() {
    let run = |threads: usize, scheme: Scheme, coarse: bool, predictor: bool| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            // 34992 elements: the packed force pass runs slabs in parallel.
            let mesh = box_tets([SIDE; 3], [18; 3], BoxPattern::Six).unwrap();
            let mut b = SimulationBuilder::new(mesh)
                .gravity(G)
                .damping(30.0)
                .fix(|p| p[2] <= 0.0)
                .scheme(scheme);
            if coarse {
                b = b.levels(vec![cube(9)]);
            }
            let mut sim = b.build().unwrap();
            sim.set_predictor(predictor);
            let g = sim.grab([0.02, 0.02, 0.05], 0.006).unwrap();
            let p = sim.grab_position(g).unwrap();
            let mut out = Vec::new();
            for k in 1..=3 {
                sim.move_grab(g, [p[0], p[1], p[2] + 0.001 * k as f64])
                    .unwrap();
                let r = sim.step_frame(Budget::Cycles(3));
                assert!(r.accepted, "{r:?}");
                out.push(sim.grab_force(g).unwrap());
            }
            (sim.displacements().to_vec(), out)
        })
    };
    for (scheme, coarse, predictor) in [
        (Scheme::SingleLevel(Method::SymplecticEuler), false, false),
        (Scheme::Fas(FasParams::default()), true, false),
        (Scheme::Fas(FasParams::default()), true, true),
    ] {
        let a = run(1, scheme, coarse, predictor);
        let b = run(2, scheme, coarse, predictor);
        assert!(
            a.0 == b.0 && a.1 == b.1,
            "bits differ between 1 and 2 threads"
        );
    }
}

#[test]
fn scenario_text_builds_a_simulation_with_its_constraints() {
    let text = r#"
gravity = [0, 0, -9.81]
[mesh]
generate = "box"
size = [0.04, 0.04, 0.04]
divisions = [4, 4, 4]
[material]
law = "neo-hookean"
young = 5e3
poisson = 0.45
[[fix]]
plane = { point = [0, 0, 0], normal = [0, 0, 1] }
[multigrid]
scheme = "raisov-paper"
levels = 2
[run]
duration = 1.0
"#;
    let mut sim = Simulation::from_toml(text, ".").unwrap();
    assert!(sim.file_node_ids().is_none());
    assert_eq!(sim.stepper().num_levels(), 2);
    // The base is supported: 25 fixed nodes.
    assert_eq!(sim.reactions().nodes.len(), 25);
    let g = sim.grab([0.02, 0.02, 0.05], 0.011).unwrap();
    // Grabbing fixed nodes only is an error naming the reason.
    let e = sim.grab([0.02, 0.02, -0.01], 0.005).unwrap_err();
    assert!(e.to_string().contains("constrained already"), "{e}");
    let p = sim.grab_position(g).unwrap();
    sim.move_grab(g, [p[0], p[1], p[2] + 0.002]).unwrap();
    let r = sim.step_frame(Budget::Cycles(50));
    assert!(r.accepted, "{r:?}");
    assert!(sim.nodal_stress().iter().flatten().all(|x| x.is_finite()));
    // A wall-clock budget takes at least one step.
    let r = sim.step_frame(Budget::Millis(0.5));
    assert!(r.accepted && r.cycles >= 1, "{r:?}");
    assert!(sim.grab_force(g).unwrap()[2] < 0.0);
    // Without loads the scenario's kinetic-energy ceiling would be zero; a grasp still moves
    // explicit dynamics.
    let text = text
        .replace("gravity = [0, 0, -9.81]", "")
        .replace("[multigrid]\nscheme = \"raisov-paper\"\nlevels = 2\n", "");
    let mut dynamic = Simulation::from_toml(&text, ".").unwrap();
    assert!(dynamic.stepper().describe().starts_with("single level"));
    let g2 = dynamic.grab([0.02, 0.02, 0.05], 0.011).unwrap();
    let p2 = dynamic.grab_position(g2).unwrap();
    dynamic
        .move_grab(g2, [p2[0], p2[1], p2[2] + 0.001])
        .unwrap();
    let r = dynamic.step_frame(Budget::Cycles(20));
    assert!(r.accepted && r.retries == 0, "{r:?}");
    // Bad input: errors, no panics.
    assert!(sim.move_grab(g, [f64::NAN, 0.0, 0.0]).is_err());
    assert!(sim.grab([0.0; 3], -1.0).is_err());
}

fn levels_scenario(scheme: &str) -> Scenario {
    let text = format!(
        r#"
gravity = [0, 0, -9.81]
[mesh]
generate = "box"
size = [0.04, 0.04, 0.04]
divisions = [6, 6, 6]
[material]
law = "neo-hookean"
young = 5e3
poisson = 0.45
[[fix]]
plane = {{ point = [0, 0, 0], normal = [0, 0, 1] }}
[multigrid]
scheme = "{scheme}"
levels = 2
[run]
duration = 1.0
"#
    );
    Scenario::from_toml(&text, Path::new("./s.toml")).unwrap()
}

#[test]
fn runtime_constraints_reach_the_levels_as_the_scheme_carries_them() {
    use crate::integrate::RuntimeConstraints;
    use crate::multigrid::fas::Fas;
    use crate::multigrid::raisov::{Raisov, RaisovParams, Reading};
    use crate::multigrid::Level;
    let top = [0.02, 0.02, SIDE];
    let d = [0.0, 0.0, 0.002];
    // Level-0 grasped node, the coarse node nearest it, a pinned coarse node.
    let setup = |levels: &[Level]| {
        let a = levels[0].mesh.nearest_node(top).unwrap() as u32;
        let near = levels[1].mesh.nearest_node(top).unwrap();
        let corner = levels[1].mesh.nearest_node([0.0, 0.0, SIDE]).unwrap() as u32;
        let rc = RuntimeConstraints {
            held: vec![(a, d)],
            pinned: vec![vec![], vec![corner]],
            ..Default::default()
        };
        (a as usize, near, corner as usize, rc)
    };
    let at = |u: &[f64], a: usize| [u[3 * a], u[3 * a + 1], u[3 * a + 2]];

    // FAS: the grasp on level 0 only; the pinned coarse node held (at the restricted state).
    let (levels, links) = levels_scenario("fas").build_levels().unwrap();
    let (a, near, corner, rc) = setup(&levels);
    let mut fas = Fas::new(levels, links, FasParams::default());
    fas.set_runtime_constraints(&rc);
    for _ in 0..3 {
        fas.advance().unwrap();
    }
    assert_eq!(at(&fas.levels[0].state.u, a), d);
    let c1 = &fas.levels[1].sys.constraints;
    assert!(c1.is_constrained(corner));
    assert!(
        !c1.is_constrained(near),
        "FAS carries no grasp to coarse levels"
    );
    // Released: back to the level's own constraints.
    fas.set_runtime_constraints(&RuntimeConstraints::default());
    assert!(!fas.levels[1].sys.constraints.is_constrained(corner));
    assert!(!fas.levels[0].sys.constraints.is_constrained(a));

    // RaISoV: the grasp carried to the nearest coarse node at the same displacement; the
    // pinned coarse node held where it stood (at rest).
    let (levels, links) = levels_scenario("raisov-paper").build_levels().unwrap();
    let (a, near, corner, rc) = setup(&levels);
    let mut rs = Raisov::new(
        levels,
        links,
        RaisovParams {
            epsilon: 1e-6,
            reading: Reading::Correction,
            kinetic_limit: f64::INFINITY,
        },
    );
    rs.set_runtime_constraints(&rc);
    for _ in 0..3 {
        rs.advance().unwrap();
    }
    assert_eq!(at(&rs.levels[0].state.u, a), d);
    assert_eq!(at(&rs.levels[1].state.u, near), d);
    assert_eq!(at(&rs.levels[1].state.u, corner), [0.0; 3]);
}

#[test]
fn restore_returns_every_stepper_to_the_same_bits() {
    use crate::integrate::Checkpoint;
    let mut steppers: Vec<Box<dyn Stepper>> = vec![
        levels_scenario("fas").stepper().unwrap(),
        levels_scenario("raisov-paper").stepper().unwrap(),
    ];
    let mut single = levels_scenario("fas");
    single.multigrid = None;
    steppers.push(single.stepper().unwrap());
    for st in &mut steppers {
        for _ in 0..2 {
            st.advance().unwrap();
        }
        let mut cp = Checkpoint::default();
        st.save(&mut cp);
        let steps = st.steps();
        let run = |st: &mut Box<dyn Stepper>| {
            for _ in 0..3 {
                st.advance().unwrap();
            }
            (st.state().u.clone(), st.state().v.clone(), st.state().t)
        };
        let first = run(st);
        st.restore(&cp);
        assert_eq!(st.steps(), steps);
        let again = run(st);
        assert!(first == again, "{}: restored run differs", st.describe());
    }
}

/// The spring grasp of `static_cube(div)`'s top face, its anchor lifted by `lift` (m) and
/// converged.
fn spring_lift(div: usize, k: f64, lift: [f64; 3]) -> (Simulation, GrabId) {
    let mut sim = static_cube(div);
    let g = sim
        .grab_with([0.02, 0.02, 0.06], GrabOptions::spring(0.011, k))
        .unwrap();
    let p = sim.grab_position(g).unwrap();
    sim.move_grab(g, [p[0] + lift[0], p[1] + lift[1], p[2] + lift[2]])
        .unwrap();
    converge(&mut sim);
    (sim, g)
}

#[test]
fn spring_grab_force_is_k_times_the_lag_and_balances_at_equilibrium() {
    let k = 30.0;
    let lift = [0.002, 0.0, 0.004];
    let (sim, g) = spring_lift(4, k, lift);
    assert!(sim.residual() < 1e-10, "residual {}", sim.residual());
    let nodes = sim.grab_nodes(g).unwrap().to_vec();
    assert_eq!(nodes.len(), 5);
    // The patch nodes are free (not constrained), so the tissue resists.
    for &a in &nodes {
        assert!(!sim.constrained[a as usize]);
    }
    let f = sim.grab_force(g).unwrap();
    // Independently: k (x̄ − x_g − ō) with mass weights, x̄ the patch's mass-weighted mean.
    let x_g = sim.grab_position(g).unwrap();
    let mass: f64 = nodes.iter().map(|&a| sim.mass[a as usize]).sum();
    let grabbed = sim.grabs[&g].clone();
    let mut want = [0.0; 3];
    for (&a, o) in nodes.iter().zip(&grabbed.offsets) {
        let w = sim.mass[a as usize] / mass;
        let x = sim.positions()[a as usize];
        for j in 0..3 {
            want[j] += k * w * (x[j] - x_g[j] - o[j]);
        }
    }
    assert!(
        norm(crate::mesh::sub(f, want)) < 1e-12 * norm(want),
        "{f:?} {want:?}"
    );
    // The patch lags behind the anchor: the spring pulls the tool back and down.
    assert!(f[2] < 0.0 && f[0] < 0.0, "{f:?}");
    // At equilibrium the spring force is Σ over the patch of V − R(u) (body minus internal
    // force), computed here from an independent model.
    // The builder's default law.
    let mut model = FemModel::new(
        sim.mesh(),
        FemParams::new(Material::StableNeoHookean(StableNeoHookean::from_young(
            5e3, 0.45,
        ))),
    )
    .unwrap();
    let m = model.lumped_mass();
    let mut r = vec![0.0; sim.displacements().len()];
    model.internal_forces(sim.displacements(), &mut r).unwrap();
    let mut net = [0.0; 3];
    for &a in &nodes {
        for j in 0..3 {
            net[j] += m[a as usize] * G[j] - r[3 * a as usize + j];
        }
    }
    // Bounded by the residual on the 5 patch nodes (≤ 1e-10 N each).
    assert!(norm(crate::mesh::sub(f, net)) < 1e-9, "{f:?} {net:?}");
    // Equilibrium: spring force + support reactions = total body force.
    let react = sim.reactions();
    let load = sim.total_load();
    let imbalance: Vec<f64> = (0..3).map(|j| f[j] + react.sum[j] - load[j]).collect();
    let scale = norm(load) + norm(f);
    assert!(
        imbalance.iter().all(|x| x.abs() < 1e-9 * scale),
        "{imbalance:?} N"
    );
}

#[test]
fn a_stiff_spring_grab_approaches_the_hard_grab() {
    let lift = [0.0, 0.0, 0.004];
    let mut hard = static_cube(3);
    let g = hard.grab([0.02, 0.02, 0.06], 0.011).unwrap();
    let p = hard.grab_position(g).unwrap();
    hard.move_grab(g, [p[0], p[1], p[2] + lift[2]]).unwrap();
    converge(&mut hard);
    let f_hard = hard.grab_force(g).unwrap();
    let mut last = f64::INFINITY;
    for k in [1e2, 1e3, 1e4, 1e5] {
        let (sim, s) = spring_lift(3, k, lift);
        assert_eq!(sim.grab_nodes(s).unwrap(), hard.grab_nodes(g).unwrap());
        let f = sim.grab_force(s).unwrap();
        let err = norm(crate::mesh::sub(f, f_hard)) / norm(f_hard);
        // The spring's share of the compliance, k_t / (k + k_t), shrinks like 1/k (the
        // tissue's k_t is about 235 N/m here).
        assert!(
            err < 0.3 * last,
            "k = {k}: relative error {err} (before {last})"
        );
        last = err;
    }
    assert!(last < 3e-3, "k = 1e5 N/m: relative error {last}");
}

#[test]
fn spring_grab_stiffness_matches_finite_differences_and_the_series_coupling() {
    let k = 40.0;
    let lift = [0.0, 0.0, 0.004];
    let (mut sim, g) = spring_lift(3, k, lift);
    let kg = sim.grab_stiffness(g).unwrap();
    let kmax = kg.iter().flatten().fold(0.0f64, |a, &b| a.max(b.abs()));
    let x0 = sim.grab_position(g).unwrap();
    let h = 1e-4;
    for axis in 0..3 {
        let mut f = [[0.0; 3]; 2];
        for (s, side) in [1.0, -1.0].into_iter().enumerate() {
            let mut x = x0;
            x[axis] += side * h;
            sim.move_grab(g, x).unwrap();
            converge(&mut sim);
            f[s] = sim.grab_force(g).unwrap();
        }
        for i in 0..3 {
            let fd = (f[0][i] - f[1][i]) / (2.0 * h);
            assert!(
                (fd - kg[i][axis]).abs() < 2e-3 * kmax,
                "K[{i}][{axis}] = {} against FD {fd}",
                kg[i][axis]
            );
        }
    }
    // Softer than the spring alone along each axis (the tissue yields in series).
    for i in 0..3 {
        assert!(kg[i][i] < 0.0 && -kg[i][i] < k, "{kg:?}");
    }
    // One grasped node: the tissue's stiffness at the node, −K_t (K_t the hard grasp's
    // tangent), and the spring in series: K_s = −(k⁻¹ I + (−K_t)⁻¹)⁻¹ = k K_t (k I − K_t)⁻¹.
    let point = [0.02, 0.02, 0.06];
    // No gravity: both at rest in the reference state, so the two tangents are at the same
    // state.
    let mut hard = static_cube_under(3, [0.0; 3]);
    let gh = hard.grab(point, 0.0).unwrap();
    converge(&mut hard);
    let kt = hard.grab_stiffness(gh).unwrap();
    let mut soft = static_cube_under(3, [0.0; 3]);
    let gs = soft.grab_with(point, GrabOptions::spring(0.0, k)).unwrap();
    converge(&mut soft);
    assert_eq!(soft.grab_nodes(gs).unwrap(), hard.grab_nodes(gh).unwrap());
    let ks = soft.grab_stiffness(gs).unwrap();
    // Check K_s (k I − K_t) = k K_t, i.e. the series law.
    let mut lhs = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            let kmkt = |m: usize, j: usize| if m == j { k } else { 0.0 } - kt[m][j];
            lhs[i][j] = (0..3).map(|m| ks[i][m] * kmkt(m, j)).sum::<f64>() - k * kt[i][j];
        }
    }
    let scale = k * kt.iter().flatten().fold(0.0f64, |a, &b| a.max(b.abs()));
    for row in lhs {
        for v in row {
            assert!(v.abs() < 1e-5 * scale, "{lhs:?} against {scale}");
        }
    }
}

#[test]
fn spring_grasps_act_on_every_level_and_fas_converges_with_them() {
    let k = 30.0;
    for scheme in ["fas", "raisov-paper"] {
        let mut sim = Simulation::from_scenario(&levels_scenario(scheme)).unwrap();
        assert_eq!(sim.stepper().num_levels(), 2);
        let g = sim
            .grab_with([0.02, 0.02, 0.05], GrabOptions::spring(0.008, k))
            .unwrap();
        let p = sim.grab_position(g).unwrap();
        let target = [p[0], p[1], p[2] + 0.003];
        sim.move_grab(g, target).unwrap();
        // The springs each level gets: level 0 one per grasped node, level 1 one per carried
        // coarse node; on both, the stiffnesses sum to k and the anchors' stiffness-weighted
        // mean is the patch's (a rigid move of the patch by the grasp's move).
        let grab = sim.grabs[&g].clone();
        let mut springs = Vec::new();
        grab.springs(target, &sim.mesh.nodes, &mut springs);
        assert_eq!(springs.len(), 2);
        assert_eq!(springs[0].len(), grab.nodes.len());
        assert!(!springs[1].is_empty() && springs[1].len() <= springs[0].len());
        let mean = |s: &[crate::integrate::Spring]| {
            let kk: f64 = s.iter().map(|s| s.k).sum();
            let mut d = [0.0; 3];
            for s in s {
                for j in 0..3 {
                    d[j] += s.k * s.d[j] / kk;
                }
            }
            (kk, d)
        };
        let (k0, d0) = mean(&springs[0]);
        let (k1, d1) = mean(&springs[1]);
        assert!((k0 - k).abs() < 1e-12 * k && (k1 - k).abs() < 1e-12 * k);
        assert!(norm(crate::mesh::sub(d0, d1)) < 1e-15, "{d0:?} {d1:?}");
        if scheme == "fas" {
            // FAS reaches level 0's equilibrium with the springs on both levels.
            for _ in 0..200 {
                let r = sim.step_frame(Budget::Cycles(5));
                assert!(r.accepted, "{r:?}");
                if r.residual < 1e-9 {
                    break;
                }
            }
            assert!(sim.residual() < 1e-9, "FAS residual {}", sim.residual());
            let f = sim.grab_force(g).unwrap();
            let react = sim.reactions();
            let load = sim.total_load();
            let imbalance = (0..3)
                .map(|j| (f[j] + react.sum[j] - load[j]).abs())
                .fold(0.0, f64::max);
            assert!(imbalance < 1e-7, "{imbalance} N");
            assert!(f[2] < 0.0, "{f:?}");
        } else {
            let r = sim.step_frame(Budget::Cycles(20));
            assert!(r.accepted, "{r:?}");
            assert!(sim.positions().iter().flatten().all(|x| x.is_finite()));
        }
    }
}

/// The multigrid-preconditioned tangent solves give the direct solve's `K_g` to the solves'
/// tolerance, for a hard and a spring grasp, in a few iterations.
#[test]
fn multigrid_preconditioned_grab_stiffness_equals_the_direct_one() {
    use super::TangentPreconditioner;
    // 6³ cells over 3³ (343 and 64 nodes), Newton on the coarsest for a converged frame.
    let two_levels = || {
        SimulationBuilder::new(cube(6))
            .levels(vec![cube(3)])
            .gravity(G)
            .fix(|p| p[2] <= 0.0)
            .scheme(Scheme::Fas(FasParams {
                coarse: CoarseSolve::Newton { rel_tol: 1e-11 },
                ..FasParams::default()
            }))
            .build()
            .unwrap()
    };
    for options in [GrabOptions::hard(0.011), GrabOptions::spring(0.011, 50.0)] {
        let mut sim = two_levels();
        let g = sim.grab_with([0.02, 0.02, 0.06], options).unwrap();
        let p = sim.grab_position(g).unwrap();
        sim.move_grab(g, [p[0] + 0.001, p[1], p[2] + 0.004])
            .unwrap();
        converge(&mut sim);
        sim.set_tangent_preconditioner(TangentPreconditioner::Direct);
        let kd = sim.grab_stiffness(g).unwrap();
        let sd = sim.tangent_stats().clone();
        assert_eq!(sd.preconditioner, TangentPreconditioner::Direct);
        assert_eq!((sd.iterations, sd.setups), (0, 1), "{sd:?}");
        // Cold, so that the direct solve's solutions are not the iterative one's start.
        let mut cold = two_levels();
        let gc = cold.grab_with([0.02, 0.02, 0.06], options).unwrap();
        cold.move_grab(gc, [p[0] + 0.001, p[1], p[2] + 0.004])
            .unwrap();
        converge(&mut cold);
        assert_eq!(cold.displacements(), sim.displacements());
        let kg = cold.grab_stiffness(gc).unwrap();
        let st = cold.tangent_stats().clone();
        assert_eq!(st.preconditioner, TangentPreconditioner::Multigrid);
        assert!(st.iterations > 0 && st.iterations < 3 * 40, "{st:?}");
        let kmax = kd.iter().flatten().fold(0.0f64, |a, &b| a.max(b.abs()));
        for i in 0..3 {
            for j in 0..3 {
                // CG stops at a relative residual of 1e-9.
                assert!(
                    (kd[i][j] - kg[i][j]).abs() < 1e-6 * kmax,
                    "K[{i}][{j}]: direct {} multigrid {} ({options:?})",
                    kd[i][j],
                    kg[i][j]
                );
            }
        }
        eprintln!("{options:?}: direct {sd:?}, multigrid {st:?}");
    }
}

/// A scenario's pressure reaches the simulation's own force evaluations: a block pressed by
/// 2 kPa on its whole top face, fixed at its base and integrated at a single level (the
/// simulation evaluates the frame forces itself), settles with support reactions that balance
/// the pressure and gravity to 1e-6 of the load, as FAS over two levels (whose frame forces
/// come from the stepper) does. The pressure follows the surface: its resultant is `−p Σ n A`
/// over the deformed top triangles (the face spreads as the block is compressed, about 3 %
/// above the reference 0.8 N), not the reference face's.
#[test]
fn simulation_frames_carry_scenario_pressure() {
    let text = |extra: &str| {
        format!(
            r#"
gravity = [0.0, 0.0, -9.81]
[mesh]
generate = "box"
size = [0.02, 0.02, 0.02]
divisions = [4, 4, 4]
[material]
law = "neo-hookean"
young = 5.0e4
poisson = 0.4
density = 1000.0
[damping]
ratio = 1.0
omega = 300.0
[[fix]]
plane = {{ point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }}
[[pressure]]
group = "zmax"
value = 2000.0
[run]
duration = 1.0
{extra}
"#
        )
    };
    for (extra, frames, per_frame) in [("", 60, 200), ("[multigrid]\nlevels = 2\n", 40, 4)] {
        let mut sim = Simulation::from_toml(&text(extra), ".").unwrap();
        for _ in 0..frames {
            let rep = sim.step_frame(Budget::Cycles(per_frame));
            assert!(rep.accepted, "{extra}: {rep:?}");
        }
        let r = sim.reactions().sum;
        let v = sim.total_load();
        // The pressure's resultant on the deformed top face, −p Σ n A (n outward).
        let top = &sim.mesh().groups["zmax"];
        let x = sim.positions();
        let mut pressure = [0.0; 3];
        for f in sim.mesh().boundary_facets() {
            if f.iter().all(|a| top.contains(a)) {
                let [a, b, c] = f.map(|i| x[i as usize]);
                let n2 = cross(sub(b, a), sub(c, a));
                // Outward on the top face: the normal's z is positive.
                let sgn = if n2[2] > 0.0 { 1.0 } else { -1.0 };
                for k in 0..3 {
                    pressure[k] -= 2000.0 * 0.5 * sgn * n2[k];
                }
            }
        }
        let reference = 2000.0 * 0.02 * 0.02;
        assert!(
            -pressure[2] > reference && -pressure[2] < 1.1 * reference,
            "{extra}: the deformed face carries {pressure:?} N"
        );
        // Supports carry the loads: Σ (V − R) over supports = body force + pressure.
        for k in 0..3 {
            let balance = r[k] - v[k] - pressure[k];
            assert!(
                balance.abs() <= 1e-6 * reference,
                "{extra}: reactions {r:?} against body force {v:?} + pressure {pressure:?}: off by {balance:e} in {k}"
            );
        }
    }
}

#[test]
fn a_rejected_frame_names_its_node_in_file_numbering() {
    // A bar whose nodes the scenario renumbers (file order ≠ memory order). A frame's
    // rejection for a non-finite value names the node as the file numbers it, with its
    // reference position, as `raisov run` does (the frame said the index in memory).
    let dir = tempfile::tempdir().unwrap();
    let mesh = box_tets([0.2, 0.02, 0.02], [20, 2, 2], BoxPattern::Six).unwrap();
    let n = mesh.num_nodes();
    let perm: Vec<usize> = (0..n).map(|i| (i * 7919) % n).collect();
    let mut shuffled = mesh.clone();
    let mut inv = vec![0u32; n];
    for (new, &old) in perm.iter().enumerate() {
        shuffled.nodes[new] = mesh.nodes[old];
        inv[old] = new as u32;
    }
    for c in shuffled.cells.iter_mut() {
        *c = inv[*c as usize];
    }
    let file = dir.path().join("bar.msh");
    crate::io::gmsh::write_msh22(&file, &shuffled).unwrap();
    let text = format!(
        "[mesh]\nfile = {file:?}\n[material]\nlaw = \"neo-hookean\"\nyoung = 5e3\n\
         poisson = 0.45\n[[fix]]\nplane = {{ point = [0, 0, 0], normal = [1, 0, 0] }}\n\
         [run]\nduration = 1.0\n"
    );
    let sim = Simulation::from_toml(&text, dir.path()).unwrap();
    let ids = sim
        .file_node_ids()
        .expect("the scenario renumbered the bar")
        .to_vec();
    let a = 17;
    assert_ne!(ids[a] as usize, a);
    let d = crate::error::Divergence {
        time: 0.0,
        step: 1,
        element: None,
        cause: crate::error::DivergenceCause::NonFinite {
            what: "velocity",
            node: crate::error::NodeRef::index(a),
        },
    };
    let why = sim.described(d);
    let want = format!(
        "node {} of the mesh file (at {} m)",
        ids[a],
        crate::numbers::point(sim.mesh().nodes[a])
    );
    assert!(why.contains(&want), "{why}\nwant {want}");
}

/// `Scheme::ImplicitEuler`: a step is required; with a coarser level the Newton systems are
/// preconditioned by the Galerkin V-cycle; a grasp held through frames of one large step each
/// (a 60 Hz frame, far above the explicit critical step) stays finite and follows the grasp.
#[test]
fn implicit_euler_simulation_takes_a_grasp_at_one_large_step_a_frame() {
    let missing = SimulationBuilder::new(cube(4))
        .scheme(Scheme::ImplicitEuler)
        .build()
        .err()
        .expect("no dt");
    assert!(missing.to_string().contains("dt"), "{missing}");
    let mut sim = SimulationBuilder::new(cube(6))
        .levels(vec![cube(2)])
        .scheme(Scheme::ImplicitEuler)
        .gravity(G)
        .damping(5.0)
        .dt(1.0 / 60.0)
        .fix(|p| p[2] <= 0.0)
        .build()
        .unwrap();
    let describe = sim.stepper().describe();
    assert!(
        describe.contains("implicit-euler") && describe.contains("Galerkin V-cycle over 2 levels"),
        "{describe}"
    );
    let g = sim.grab([0.02, 0.02, SIDE], 0.01).unwrap();
    let p = sim.grab_position(g).unwrap();
    sim.move_grab(g, [p[0] + 0.005, p[1], p[2] + 0.005])
        .unwrap();
    for _ in 0..10 {
        assert!(sim.step_frame(Budget::Cycles(1)).accepted);
    }
    let q = sim.grab_position(g).unwrap();
    assert!((q[0] - p[0] - 0.005).abs() < 1e-9 && (q[2] - p[2] - 0.005).abs() < 1e-9);
    assert!(sim.displacements().iter().all(|x| x.is_finite()));
}

/// `Scheme::Bdf2` with stiffness-proportional damping: as `Scheme::ImplicitEuler`, a grasp
/// held through frames of one 60 Hz step each; β is refused with the explicit schemes.
#[test]
fn bdf2_simulation_with_stiffness_damping_takes_a_grasp_at_one_large_step_a_frame() {
    let refused = SimulationBuilder::new(cube(4))
        .stiffness_damping(1e-3)
        .build()
        .err()
        .expect("β with FAS");
    assert!(
        refused.to_string().contains("stiffness_damping")
            && refused.to_string().contains("Scheme::Bdf2"),
        "{refused}"
    );
    let mut sim = SimulationBuilder::new(cube(6))
        .levels(vec![cube(2)])
        .scheme(Scheme::Bdf2)
        .gravity(G)
        .damping(5.0)
        .stiffness_damping(2e-3)
        .dt(1.0 / 60.0)
        .fix(|p| p[2] <= 0.0)
        .build()
        .unwrap();
    let describe = sim.stepper().describe();
    assert!(
        describe.contains("bdf2") && describe.contains("Galerkin V-cycle over 2 levels"),
        "{describe}"
    );
    let g = sim.grab([0.02, 0.02, SIDE], 0.01).unwrap();
    let p = sim.grab_position(g).unwrap();
    sim.move_grab(g, [p[0] + 0.005, p[1], p[2] + 0.005])
        .unwrap();
    for _ in 0..10 {
        assert!(sim.step_frame(Budget::Cycles(1)).accepted);
    }
    let q = sim.grab_position(g).unwrap();
    assert!((q[0] - p[0] - 0.005).abs() < 1e-9 && (q[2] - p[2] - 0.005).abs() < 1e-9);
    assert!(sim.displacements().iter().all(|x| x.is_finite()));
}

/// A grasp on top of a 6-cell cube (FAS over the cube and a 3-cell level) pulled up 0.4 mm a
/// frame for 8 frames at one V-cycle a frame: the largest residual after each frame, with
/// the frame predictor off and on.
fn steady_pull_residuals(predictor: bool) -> Vec<f64> {
    let mut sim = SimulationBuilder::new(cube(6))
        .gravity(G)
        .fix(|p| p[2] <= 0.0)
        .levels(vec![cube(3)])
        .scheme(Scheme::Fas(FasParams::default()))
        .build()
        .unwrap();
    sim.set_predictor(predictor);
    converge(&mut sim);
    let g = sim.grab([0.02, 0.02, 0.04], 0.008).unwrap();
    let p = sim.grab_position(g).unwrap();
    (1..=8)
        .map(|k| {
            sim.move_grab(g, [p[0], p[1], p[2] + 4e-4 * k as f64])
                .unwrap();
            let r = sim.step_frame(Budget::Cycles(1));
            assert!(r.accepted, "{r:?}");
            r.residual
        })
        .collect()
}

/// The predictor starts a steadily pulled frame nearer its equilibrium: frame 1 has no
/// change to extrapolate (the same bits), frame 2 extrapolates frame 1's change, which fell
/// short of its move (about as good as without), and from frame 3 on every frame ends with a
/// smaller residual than without it; over frames 2-8 the mean is at most 40 % of it.
#[test]
fn the_predictor_shrinks_the_residual_of_a_steady_pull() {
    let off = steady_pull_residuals(false);
    let on = steady_pull_residuals(true);
    assert_eq!(off[0], on[0], "frame 1 has nothing to extrapolate");
    for k in 2..off.len() {
        assert!(
            on[k] < off[k],
            "frame {}: {:?} against {:?}",
            k + 1,
            on,
            off
        );
    }
    let mean = |x: &[f64]| x.iter().sum::<f64>() / x.len() as f64;
    let ratio = mean(&on[1..]) / mean(&off[1..]);
    assert!(ratio <= 0.4, "ratio {ratio}: {on:?} against {off:?}");
}

/// A held grasp is not extrapolated: frames whose grasps do not move are the same bits with
/// and without the predictor.
#[test]
fn the_predictor_leaves_a_held_grasp_alone() {
    let run = |predictor: bool| {
        let mut sim = static_cube(4);
        sim.set_predictor(predictor);
        let g = sim.grab([0.02, 0.02, 0.04], 0.011).unwrap();
        for _ in 0..3 {
            assert!(sim.step_frame(Budget::Cycles(1)).accepted);
        }
        let _ = g;
        sim.displacements().to_vec()
    };
    assert_eq!(run(false), run(true));
}

/// The Python tests caught two predictor mistakes: a frame of zero steps was predicted (the
/// tissue moved though it must not answer), and a grasp moved back the way it came was
/// extrapolated forward (the last change, not the move's direction, set the start).
#[test]
fn a_zero_step_frame_and_a_reversed_grasp_are_not_predicted() {
    let mut sim = static_cube(4);
    let g = sim.grab([0.02, 0.02, 0.04], 0.011).unwrap();
    let p = sim.grab_position(g).unwrap();
    sim.move_grab(g, [p[0], p[1], p[2] + 1e-3]).unwrap();
    assert!(sim.step_frame(Budget::Cycles(1)).accepted);
    // Zero steps: the grasped nodes go to the target, the rest of the tissue does not move.
    let u = sim.displacements().to_vec();
    sim.move_grab(g, [p[0], p[1], p[2] + 2e-3]).unwrap();
    assert!(sim.step_frame(Budget::Cycles(0)).accepted);
    let held = sim.grab_nodes(g).unwrap().to_vec();
    let after = sim.displacements();
    for a in (0..u.len() / 3).filter(|a| !held.contains(&(*a as u32))) {
        assert_eq!(after[3 * a..3 * a + 3], u[3 * a..3 * a + 3], "node {a}");
    }
    // The rule itself: a steady move repeats the last change, a reversed or turned one
    // predicts nothing, and no node is predicted further than the path moves.
    let delta = [0.0, 0.0, 1e-3, 0.0, 0.0, 5e-4];
    let up = [[0.0, 0.0, 1e-3]];
    assert_eq!(
        crate::integrate::prediction(&delta, &up, &up),
        Some(delta.to_vec())
    );
    assert_eq!(
        crate::integrate::prediction(&delta, &[[0.0, 0.0, -2e-3]], &up),
        None
    );
    assert_eq!(
        crate::integrate::prediction(&delta, &[[1e-3, 0.0, 0.0]], &up),
        None
    );
    let far = crate::integrate::prediction(&[0.0, 0.0, 4e-3], &up, &up).unwrap();
    assert!((far[2] - 1e-3).abs() < 1e-18, "{far:?}");
}

/// A rate-dependent law in the frame loop: a grasp on top of a cube fixed at its base,
/// moved 3 mm sideways in one frame and held for 3 s (15 times the longest relaxation time)
/// at one backward-Euler step of 1/60 s a frame. The force holding it relaxes: the first
/// held frame's is well above the last's, and the last equals, to 1e-4, that of the same
/// frames on the elastic law of the long-term modulus `μ∞ = μ (1 − Σ α)` (mooney-rivlin with
/// `c1 = μ∞/2`, `c2 = 0`, the same κ), whose equilibrium the relaxed tissue must reach.
/// Fas refuses the law (its cycles do not advance the internal variables).
#[test]
fn a_held_grasp_relaxes_to_the_long_term_law_in_the_frame_loop() {
    use crate::material::{MooneyRivlin, NeoHookeanVisco, Prony};
    let visco = NeoHookeanVisco {
        mu: 1e3,
        kappa: 2e4,
        prony: vec![
            Prony {
                alpha: 0.3,
                tau: 0.05,
            },
            Prony {
                alpha: 0.2,
                tau: 0.2,
            },
        ],
    };
    let relaxed = Material::MooneyRivlin(MooneyRivlin {
        c1: 0.5 * visco.long_term_mu(),
        c2: 0.0,
        kappa: visco.kappa,
    });
    let fas = SimulationBuilder::new(cube(3))
        .material(Material::NeoHookeanVisco(visco.clone()))
        .levels(vec![cube(2)])
        .scheme(Scheme::Fas(FasParams::default()))
        .fix(|p| p[2] <= 0.0)
        .build()
        .err()
        .expect("Fas refuses the visco law");
    assert!(fas.to_string().contains("Scheme::ImplicitEuler"), "{fas}");
    let forces = |m: Material| {
        let mut sim = SimulationBuilder::new(cube(4))
            .material(m)
            .scheme(Scheme::ImplicitEuler)
            .damping(10.0)
            .dt(1.0 / 60.0)
            .fix(|p| p[2] <= 0.0)
            .build()
            .unwrap();
        let g = sim.grab([0.02, 0.02, SIDE], 0.01).unwrap();
        let p = sim.grab_position(g).unwrap();
        sim.move_grab(g, [p[0] + 0.003, p[1], p[2]]).unwrap();
        (0..180)
            .map(|_| {
                let r = sim.step_frame(Budget::Cycles(1));
                assert!(r.accepted, "{r:?}");
                norm(sim.grab_force(g).unwrap())
            })
            .collect::<Vec<_>>()
    };
    let v = forces(Material::NeoHookeanVisco(visco));
    let e = forces(relaxed);
    let (first, last, elastic) = (v[0], v[179], e[179]);
    assert!(first > 1.4 * last, "{first} vs {last}");
    assert!(
        (last - elastic).abs() <= 1e-4 * elastic,
        "relaxed {last} vs long-term law {elastic}"
    );
}

/// A friction grasp (`GrabOptions::friction`: stick stiffness 100 N/m, μ = 0.5, clamp force
/// 0.1 N, so μN = 0.05 N) on top of a cube fixed at its base, every frame converged (a Newton
/// solve):
/// - pulled 0.1 mm sideways it sticks: the spring grasp's equilibrium (1e-9) and no work
///   dissipated;
/// - dragged 10 mm in 0.5 mm frames it slides: the force on the tool never exceeds μN and,
///   once sliding, stays within 2 % of it (the nodes' pulls nearly parallel); the patch
///   moves far less than the tool; and the work the tool did equals the energy stored in the
///   tissue and the grip's springs plus the work the sliding dissipated, within 0.5 % (the
///   tool's work by the trapezoid rule over the frames).
#[test]
fn a_friction_grasp_sticks_below_mu_n_and_slides_at_it() {
    let (k, mu, clamp) = (100.0, 0.5, 0.1);
    let limit = mu * clamp;
    let point = [0.02, 0.02, SIDE];
    let pull = |options: GrabOptions, steps: usize, step: f64| {
        let mut sim = static_cube_under(4, [0.0; 3]);
        let g = sim.grab_with(point, options).unwrap();
        let p = sim.grab_position(g).unwrap();
        let mut f_last = [0.0; 3];
        let mut work = 0.0;
        let mut forces = Vec::new();
        for j in 1..=steps {
            sim.move_grab(g, [p[0] + step * j as f64, p[1], p[2]])
                .unwrap();
            converge(&mut sim);
            let f = sim.grab_force(g).unwrap();
            // The tool pulls with −f; trapezoid over the frame's move along x.
            work += -0.5 * (f_last[0] + f[0]) * step;
            f_last = f;
            forces.push(norm(f));
        }
        (sim, g, work, forces)
    };
    // Sticking.
    let (stick, gs, _, fs) = pull(GrabOptions::friction(0.011, k, mu, clamp), 1, 1e-4);
    let (spring, _, _, fk) = pull(GrabOptions::spring(0.011, k), 1, 1e-4);
    assert!(fs[0] < limit, "{} vs μN {limit}", fs[0]);
    assert!((fs[0] - fk[0]).abs() <= 1e-9 * fk[0], "{fs:?} {fk:?}");
    let du = stick
        .displacements()
        .iter()
        .zip(spring.displacements())
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(du <= 1e-9 * 1e-4, "{du}");
    assert_eq!(stick.grab_dissipation(gs).unwrap(), 0.0);
    // Sliding.
    let (sim, g, work, forces) = pull(GrabOptions::friction(0.011, k, mu, clamp), 20, 5e-4);
    assert!(
        forces.iter().all(|&f| f <= limit * (1.0 + 1e-9)),
        "{forces:?}"
    );
    assert!(forces[5..].iter().all(|&f| f >= 0.98 * limit), "{forces:?}");
    let patch: f64 = sim
        .grab_nodes(g)
        .unwrap()
        .iter()
        .map(|&a| sim.displacements()[3 * a as usize])
        .fold(0.0, f64::max);
    assert!(
        patch < 0.2 * 0.01,
        "the patch moved {patch} m of the tool's 0.01 m"
    );
    let model = FemModel::new(
        sim.mesh(),
        FemParams::new(Material::StableNeoHookean(StableNeoHookean::from_young(
            5e3, 0.45,
        ))),
    )
    .unwrap();
    let u = sim.displacements();
    let stored = model.strain_energy(u) + sim.springs.iter().map(|s| s.energy(u)).sum::<f64>();
    let dissipated = sim.grab_dissipation(g).unwrap();
    eprintln!(
        "friction grasp: forces {:.5?} N (μN {limit}), patch {patch:.3e} m, tool work {work:.5e} J, stored {stored:.5e} J, dissipated {dissipated:.5e} J",
        forces
    );
    assert!(dissipated > 0.5 * work, "{dissipated} of {work}");
    assert!(
        (work - stored - dissipated).abs() <= 0.005 * work,
        "tool work {work} J, stored {stored} J, dissipated {dissipated} J"
    );
}

/// A frame that diverges without stopping the stepper is rejected. Stable neo-Hookean (the
/// builder's default law) is defined for inverted elements, and FAS's static smoother keeps
/// the velocities zero, so neither an inverted element nor the kinetic limit stops a cycle:
/// a one-node grasp lifted 4 cm over 15 frames at 2 V-cycles a frame (the frame benchmark's
/// one-node case in small) drove the cubes' residual to infinity, or a node 160 m away, and
/// those frames were accepted. Now no accepted frame has a residual that is not finite or a
/// node moved more than `DIVERGED_EXTENTS` times the cube's extent; such frames are rejected
/// (with their reason) and retried in smaller moves, or the simulation keeps the state
/// before them.
#[test]
fn a_frame_that_diverges_without_an_inverted_element_is_rejected() {
    let extent = (3.0f64).sqrt() * SIDE;
    let mut retried = 0;
    for div in [6usize, 8] {
        let mut sim = SimulationBuilder::new(cube(div))
            .fix(|p| p[2] <= 0.0)
            .levels(vec![cube(div / 2)])
            .scheme(Scheme::Fas(FasParams::default()))
            .build()
            .unwrap();
        let g = sim.grab([0.02, 0.02, SIDE], 0.0).unwrap();
        let p = sim.grab_position(g).unwrap();
        for k in 1..=15 {
            sim.move_grab(g, [p[0], p[1], p[2] + 0.04 * k as f64 / 15.0])
                .unwrap();
            let before = sim.displacements().to_vec();
            let r = sim.step_frame(Budget::Cycles(2));
            let u = sim
                .displacements()
                .chunks(3)
                .map(|x| norm([x[0], x[1], x[2]]))
                .fold(0.0f64, f64::max);
            retried += r.retries;
            if r.accepted {
                assert!(
                    sim.residual().is_finite() && u <= crate::sim::frame::DIVERGED_EXTENTS * extent,
                    "cube {div}, frame {k}: accepted with residual {} N, max |u| {u} m",
                    sim.residual()
                );
            } else {
                assert_eq!(sim.displacements(), &before[..]);
                let why = r.rejection.unwrap_or_default();
                assert!(!why.is_empty());
            }
        }
    }
    // Some tries were rejected and retried in smaller moves.
    assert!(retried > 0);
}
