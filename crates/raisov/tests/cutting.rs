//! Cutting (the virtual node algorithm on every level): physics of the cut body.

use raisov::fem::{FemModel, FemParams};
use raisov::hierarchy::cut::CutHierarchy;
use raisov::hierarchy::Correspondence;
use raisov::integrate::{Constraints, Method, System};
use raisov::material::{Material, NeoHookean};
use raisov::mesh::cut::{Blade, CutMesh};
use raisov::mesh::generate::{box_tets, BoxPattern};
use raisov::mesh::{tet_volume, ElementKind, Mesh};
use raisov::sim::{Budget, Scheme, SimulationBuilder};
use raisov::statics::newton::{solve_system, DirectNewton, DirectNewtonParams, MultigridPcg};

const G: [f64; 3] = [0.0, 0.0, -9.81];

/// A blade in the plane x = `x` over y, z in [y0, y1] × [z0, z1].
fn plane_x(x: f64, z0: f64, z1: f64) -> Blade {
    Blade::quad([[x, -1.0, z0], [x, 1.0, z0], [x, 1.0, z1], [x, -1.0, z1]]).unwrap()
}

/// Pieces of a mesh joined through shared nodes: each node's piece.
fn node_pieces(m: &Mesh) -> Vec<usize> {
    let n = m.num_nodes();
    let mut parent: Vec<usize> = (0..n).collect();
    fn find(p: &mut [usize], mut a: usize) -> usize {
        while p[a] != a {
            p[a] = p[p[a]];
            a = p[a];
        }
        a
    }
    for el in m.cells.chunks_exact(4) {
        for w in el.windows(2) {
            let (a, b) = (
                find(&mut parent, w[0] as usize),
                find(&mut parent, w[1] as usize),
            );
            parent[a.max(b)] = a.min(b);
        }
    }
    (0..n).map(|a| find(&mut parent, a)).collect()
}

#[test]
fn a_block_cut_through_drops_its_free_half_as_a_rigid_body() {
    let mesh = box_tets([0.04, 0.02, 0.02], [8, 4, 4], BoxPattern::Six).unwrap();
    let dt = 2e-4;
    let mut sim = SimulationBuilder::new(mesh)
        .fix(|p| p[0] <= 0.0)
        .gravity(G)
        .scheme(Scheme::SingleLevel(Method::SymplecticEuler))
        .dt(dt)
        .build()
        .unwrap();
    let total: f64 = sim.total_load()[2];
    let report = sim.cut(&plane_x(0.0213, -1.0, 1.0)).unwrap();
    assert!(report.split[0] > 0);
    assert!(
        (sim.total_load()[2] - total).abs() <= 1e-13 * total.abs(),
        "the weight is conserved: {total} → {}",
        sim.total_load()[2]
    );
    let m = sim.mesh().clone();
    let piece = node_pieces(&m);
    let fixed_piece = piece[(0..m.num_nodes()).find(|&a| m.nodes[a][0] <= 0.0).unwrap()];
    let free: Vec<usize> = (0..m.num_nodes())
        .filter(|&a| piece[a] != fixed_piece)
        .collect();
    assert!(!free.is_empty(), "the cut separates a free piece");
    let mass = sim.masses().to_vec();
    let m_free: f64 = free.iter().map(|&a| mass[a]).sum();
    let com = |sim: &raisov::sim::Simulation| -> f64 {
        free.iter()
            .map(|&a| mass[a] * sim.positions()[a][2])
            .sum::<f64>()
            / m_free
    };
    let z0 = com(&sim);
    let n = 400u32;
    for _ in 0..n / 40 {
        assert!(sim.step_frame(Budget::Cycles(40)).accepted);
    }
    // Symplectic Euler from rest: v_k = k h g, z_n − z_0 = h Σ_{k=1..n} v_k = g h² n(n+1)/2.
    let exact = G[2] * dt * dt * (n as f64) * (n as f64 + 1.0) / 2.0;
    let fell = com(&sim) - z0;
    assert!(
        (fell - exact).abs() <= 1e-9 * exact.abs(),
        "the free half's centre of mass fell {fell} m, free fall {exact} m"
    );
    // Rigid: its nodes moved together.
    let u = sim.displacements();
    let spread = free
        .iter()
        .map(|&a| (u[3 * a + 2] - fell).abs())
        .fold(0.0, f64::max);
    assert!(
        spread <= 1e-9 * exact.abs(),
        "the free half deformed by {spread} m"
    );
}

#[test]
fn a_cut_off_half_leaves_the_supports_carrying_only_the_fixed_halfs_weight() {
    let mesh = box_tets([0.04, 0.02, 0.02], [8, 4, 4], BoxPattern::Six).unwrap();
    let mut sim = SimulationBuilder::new(mesh)
        .fix(|p| p[0] <= 0.0)
        .gravity(G)
        .scheme(Scheme::SingleLevel(Method::SymplecticEuler))
        .damping(300.0)
        .build()
        .unwrap();
    let total = sim.total_load()[2];
    sim.cut(&plane_x(0.0213, -1.0, 1.0)).unwrap();
    let m = sim.mesh().clone();
    let piece = node_pieces(&m);
    let fixed_piece = piece[(0..m.num_nodes()).find(|&a| m.nodes[a][0] <= 0.0).unwrap()];
    // The fixed piece's weight from its elements' material: ρ g Σ f_e |T_e|.
    let fractions = sim.material_fractions();
    let volume: f64 = m
        .cells
        .chunks_exact(4)
        .zip(&fractions)
        .filter(|(el, _)| piece[el[0] as usize] == fixed_piece)
        .map(|(el, f)| {
            let p = |i: usize| m.nodes[el[i] as usize];
            f * tet_volume(p(0), p(1), p(2), p(3))
        })
        .sum();
    let weight = 1000.0 * volume * G[2];
    assert!(
        (weight / total - 0.0213 / 0.04).abs() < 0.02,
        "the fixed piece is the part left of the blade: {} of the weight",
        weight / total
    );
    for _ in 0..100 {
        assert!(sim.step_frame(Budget::Cycles(50)).accepted);
    }
    let r = sim.reactions().sum;
    assert!(
        (r[2] - weight).abs() <= 1e-6 * weight.abs(),
        "reactions {r:?} against the fixed piece's weight {weight} (the whole body's {total})"
    );
}

/// Neo-Hookean, E = 1 MPa, ν = 0.3: a beam that sags a millimetre or two under its weight.
fn stiff() -> Material {
    Material::NeoHookean(NeoHookean::from_young(1e6, 0.3))
}

/// A cantilever's system on `mesh` (fixed at x = 0, gravity), elements scaled by `fractions`.
fn cantilever(mesh: &Mesh, fractions: Option<&[f64]>) -> System {
    let mut p = FemParams::new(stiff());
    p.fractions = fractions.map(|f| f.to_vec().into());
    let fem = FemModel::new(mesh, p).unwrap();
    let mass = fem.lumped_mass();
    let n = mesh.num_nodes();
    let fixed = (0..n as u32)
        .filter(|&a| mesh.nodes[a as usize][0] <= 0.0)
        .collect();
    let mut sys = System::new(
        Box::new(fem),
        mass,
        0.0,
        vec![0.0; 3 * n],
        Constraints::new(fixed, vec![]),
    );
    sys.add_gravity(G);
    sys
}

fn newton() -> DirectNewtonParams {
    DirectNewtonParams {
        rel_tol: 1e-9,
        ..Default::default()
    }
}

/// Static equilibrium by Newton with the sparse Cholesky factor.
fn equilibrium(sys: &mut System) -> Vec<f64> {
    let mut u = vec![0.0; 3 * sys.num_nodes()];
    let out = solve_system(sys, 0.0, &mut u, newton()).unwrap();
    assert!(out.converged, "{out:?}");
    u
}

/// Mean vertical displacement of the nodes at the free end x = `l`.
fn tip_sag(mesh: &Mesh, u: &[f64], l: f64) -> f64 {
    let tip: Vec<usize> = (0..mesh.num_nodes())
        .filter(|&a| mesh.nodes[a][0] >= l - 1e-9)
        .collect();
    tip.iter().map(|&a| u[3 * a + 2]).sum::<f64>() / tip.len() as f64
}

/// The beam meshed with the notch as a real gap: the cells of the layer x in [x0, x0 + h]
/// above half the depth removed, unused nodes dropped, and the layer narrowed to its middle
/// quarter (a gap h/4 wide).
fn gapped_beam(size: [f64; 3], div: [usize; 3], x0: f64) -> Mesh {
    let full = box_tets(size, div, BoxPattern::Six).unwrap();
    let h = size[0] / div[0] as f64;
    let mut cells = Vec::new();
    for el in full.cells.chunks_exact(4) {
        let c = |k: usize| el.iter().map(|&a| full.nodes[a as usize][k]).sum::<f64>() / 4.0;
        if c(0) > x0 && c(0) < x0 + h && c(2) > 0.5 * size[2] {
            continue;
        }
        cells.extend_from_slice(el);
    }
    let mut id = vec![u32::MAX; full.num_nodes()];
    let mut nodes = Vec::new();
    // The gap narrowed to a quarter of the layer, about its middle.
    let narrow = |mut p: [f64; 3]| {
        if (p[0] - x0).abs() < 1e-9 {
            p[0] = x0 + 0.375 * h;
        } else if (p[0] - x0 - h).abs() < 1e-9 {
            p[0] = x0 + 0.625 * h;
        }
        p
    };
    for c in cells.iter_mut() {
        if id[*c as usize] == u32::MAX {
            id[*c as usize] = nodes.len() as u32;
            nodes.push(narrow(full.nodes[*c as usize]));
        }
        *c = id[*c as usize];
    }
    Mesh::new(ElementKind::Tet4, nodes, cells)
}

#[test]
fn a_notched_cantilever_sags_like_a_beam_meshed_with_the_gap() {
    let size = [0.08, 0.01, 0.02];
    let mut differences = Vec::new();
    for div in [[16, 2, 4], [32, 4, 8]] {
        let h = size[0] / div[0] as f64;
        let x0 = 0.04;
        // The cut in the middle of the reference's gap, from the top face to half the depth.
        let mut cut = CutMesh::new(box_tets(size, div, BoxPattern::Six).unwrap()).unwrap();
        let change = cut.cut(&plane_x(x0 + 0.5 * h, 0.0101, 1.0)).unwrap();
        assert!(change.split > 0);
        let mut sys = cantilever(cut.mesh(), Some(cut.fractions()));
        let u_cut = equilibrium(&mut sys);
        let sag_cut = tip_sag(cut.mesh(), &u_cut, size[0]);
        let gap = gapped_beam(size, div, x0);
        let u_gap = equilibrium(&mut cantilever(&gap, None));
        let sag_gap = tip_sag(&gap, &u_gap, size[0]);
        let plain = box_tets(size, div, BoxPattern::Six).unwrap();
        let u_plain = equilibrium(&mut cantilever(&plain, None));
        let sag_plain = tip_sag(&plain, &u_plain, size[0]);
        let d = (sag_cut - sag_gap).abs() / sag_gap.abs();
        eprintln!(
            "h = {h}: sag cut {sag_cut:.6e}, gap {sag_gap:.6e}, unnotched {sag_plain:.6e}: difference {d:.3e}"
        );
        assert!(sag_cut < sag_plain, "the notch weakens the beam");
        differences.push((d, (sag_cut - sag_plain).abs() / sag_plain.abs()));
    }
    let (fine, notch) = differences[1];
    assert!(
        fine < 0.8 * differences[0].0 && fine < 0.03 && notch > 3.0 * fine,
        "the cut and the meshed gap agree better as the mesh is refined, within 3 % at h = 2.5 mm and well below the notch's own effect (difference, effect): {differences:?}"
    );
}

/// The notched cantilever on two levels, cut by one blade.
fn notched_levels() -> (Mesh, Mesh, Blade) {
    let size = [0.08, 0.01, 0.02];
    let fine = box_tets(size, [32, 4, 8], BoxPattern::Six).unwrap();
    let coarse = box_tets(size, [16, 2, 4], BoxPattern::Six).unwrap();
    (fine, coarse, plane_x(0.04125, 0.0101, 1.0))
}

#[test]
fn no_coarse_element_ties_the_lips_of_the_wound() {
    let (fine, coarse, blade) = notched_levels();
    let link = Correspondence::build(&fine, &coarse).unwrap();
    let mut h = CutHierarchy::new(vec![fine, coarse], vec![link]).unwrap();
    let cut = h.cut(&blade).unwrap();
    let (f, c) = (&h.levels()[0], &h.levels()[1]);
    let sides = f.node_sides();
    // A fine node's host copy keeps the material of the node's own side of every cut that
    // split it.
    let bridges = |down: &raisov::hierarchy::Transfer| {
        (0..f.mesh().num_nodes())
            .filter(|&a| {
                c.sides()[down.host[a] as usize]
                    .iter()
                    .any(|&(k, s)| f.side_of(&sides, a, k) != s)
            })
            .count()
    };
    assert_eq!(bridges(&cut.links[0].down), 0);
    // The test can fail: a geometric search of the cut meshes cannot tell the copies apart.
    let searched = Correspondence::build(f.mesh(), c.mesh()).unwrap();
    assert!(
        bridges(&searched.down) > 0,
        "a geometric search puts lip nodes in the other lip's copies"
    );
}

#[test]
fn multigrid_reaches_the_single_level_equilibrium_of_the_cut_body() {
    let (fine, coarse, blade) = notched_levels();
    let link = Correspondence::build(&fine, &coarse).unwrap();
    let mut h = CutHierarchy::new(vec![fine.clone(), coarse.clone()], vec![link]).unwrap();
    let cut = h.cut(&blade).unwrap();
    let level0 = &h.levels()[0];
    let mut sys = cantilever(level0.mesh(), Some(level0.fractions()));
    let u_ref = equilibrium(&mut sys);
    let scale = u_ref.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let err = |u: &[f64]| {
        u.iter()
            .zip(&u_ref)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
            / scale
    };
    // Newton-multigrid: conjugate gradients preconditioned by the Galerkin V-cycle over the
    // cut levels' links.
    let down = vec![cut.links[0].down.clone()];
    let mut u = vec![0.0; u_ref.len()];
    let mut s = DirectNewton::with_levels(&*sys.force, &sys.mass, &sys.constraints, &down).unwrap();
    let out = s
        .solve(
            &mut *sys.force,
            &sys.springs,
            &sys.constraints,
            &sys.f_ext,
            0.0,
            &mut u,
            DirectNewtonParams {
                multigrid: Some(MultigridPcg::default()),
                ..newton()
            },
        )
        .unwrap();
    assert!(out.converged && out.multigrid_setups > 0, "{out:?}");
    assert!(err(&u) < 1e-8, "Newton-multigrid is {} away", err(&u));
    // FAS through the simulation's own cut.
    let mut sim = SimulationBuilder::new(fine)
        .levels(vec![coarse])
        .material(stiff())
        .fix(|p| p[0] <= 0.0)
        .gravity(G)
        .build()
        .unwrap();
    sim.cut(&blade).unwrap();
    assert_eq!(
        sim.mesh().cells,
        level0.mesh().cells,
        "the same cut on the same levels"
    );
    let weight = sim.total_load()[2].abs();
    let mut frames = 0;
    while sim.residual() > 1e-12 * weight && frames < 400 {
        assert!(sim.step_frame(Budget::Cycles(10)).accepted);
        frames += 1;
    }
    let e = err(sim.displacements());
    eprintln!(
        "FAS: {frames} frames of 10 cycles, residual {:.3e} N, {e:.3e} from Newton",
        sim.residual()
    );
    assert!(
        e < 1e-8,
        "FAS is {e} away from the single-level equilibrium"
    );
}

#[test]
fn a_cut_gives_the_same_bits_on_any_thread_count() {
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let (fine, coarse, blade) = notched_levels();
            let mut sim = SimulationBuilder::new(fine)
                .levels(vec![coarse])
                .fix(|p| p[0] <= 0.0)
                .gravity(G)
                .build()
                .unwrap();
            sim.step_frame(Budget::Cycles(3));
            sim.cut(&blade).unwrap();
            sim.cut(
                &Blade::swept([0.06, -1.0, 0.005], [0.06, 1.0, 0.005], [0.0, 0.0, 1.0]).unwrap(),
            )
            .unwrap();
            for _ in 0..3 {
                assert!(sim.step_frame(Budget::Cycles(3)).accepted);
            }
            (sim.mesh().cells.clone(), sim.displacements().to_vec())
        })
    };
    let (c1, u1) = run(1);
    let (c2, u2) = run(2);
    assert_eq!(c1, c2);
    assert!(u1.iter().zip(&u2).all(|(a, b)| a.to_bits() == b.to_bits()));
}

#[test]
fn the_drawn_surface_of_a_cut_body_opens_with_the_wound() {
    let mesh = box_tets([0.04, 0.02, 0.02], [8, 4, 4], BoxPattern::Six).unwrap();
    let mut sim = SimulationBuilder::new(mesh)
        .fix(|p| p[0] <= 0.0)
        .gravity(G)
        .scheme(Scheme::SingleLevel(Method::SymplecticEuler))
        .dt(2e-4)
        .build()
        .unwrap();
    let before = sim.surface_triangles().len();
    sim.cut(&plane_x(0.0213, -1.0, 1.0)).unwrap();
    let tris = sim.surface_triangles().to_vec();
    assert!(tris.len() > before, "the wound's faces are drawn");
    let n = sim.surface_positions().len();
    assert!(tris.iter().flatten().all(|&v| (v as usize) < n));
    // The wound's vertices move with their lips: after the free half fell, the drawn surface
    // reaches as low as the lowest node.
    for _ in 0..10 {
        assert!(sim.step_frame(Budget::Cycles(40)).accepted);
    }
    let low = |p: &[[f64; 3]]| p.iter().map(|x| x[2]).fold(f64::INFINITY, f64::min);
    assert!((low(sim.surface_positions()) - low(sim.positions())).abs() < 1e-12);
    assert!(low(sim.positions()) < -1e-4, "the free half fell");
}

/// A cantilever block scenario: `[[cut]]` and the run's sections in `extra`.
fn block_scenario(extra: &str) -> raisov::scenario::Scenario {
    let text = format!(
        r#"
gravity = [0, 0, -9.81]
[mesh]
generate = "box"
size = [0.04, 0.02, 0.02]
divisions = [8, 4, 4]
[material]
law = "neo-hookean"
young = 5e3
poisson = 0.45
density = 1000
[damping]
alpha = 100.0
[[fix]]
plane = {{ point = [0, 0, 0], normal = [1, 0, 0] }}
{extra}
"#
    );
    raisov::scenario::Scenario::from_toml(&text, std::path::Path::new("cut.toml")).unwrap()
}

fn temp_out(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("raisov-cutting-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// `NumberOfPoints="…"` of a VTU file.
fn vtu_points(path: &std::path::Path) -> usize {
    let text = std::fs::read(path).unwrap();
    let text = String::from_utf8_lossy(&text);
    let i = text.find("NumberOfPoints=\"").unwrap() + 16;
    text[i..].split('"').next().unwrap().parse().unwrap()
}

#[test]
fn a_scenario_cut_in_time_writes_frames_of_the_cut_body() {
    let sc = block_scenario(
        r#"
[[cut]]
time = 0.01
edge = [[0.0213, -0.01, 0.0101], [0.0213, 0.03, 0.0101]]
sweep = [0.0, 0.0, 0.02]
[run]
duration = 0.05
[output]
frame_interval = 0.02
"#,
    );
    assert_eq!(sc.cuts.len(), 1);
    let out = temp_out("time");
    let sol = raisov::runner::solve(
        &sc,
        raisov::runner::RunOptions {
            out_dir: Some(out.clone()),
            ..Default::default()
        },
    )
    .unwrap();
    let n0 = sc.mesh.num_nodes();
    assert!(sol.u.len() > 3 * n0, "the solution has the copies' nodes");
    let frames: Vec<_> = {
        let mut f: Vec<_> = std::fs::read_dir(out.join("frames"))
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        f.sort();
        f
    };
    assert_eq!(
        vtu_points(&frames[0]),
        n0,
        "the first frame is the uncut body"
    );
    assert!(
        vtu_points(frames.last().unwrap()) > n0,
        "the last frame is the cut body"
    );
    let stress = std::fs::read_to_string(out.join("nodal_stress.csv")).unwrap();
    assert_eq!(
        stress.lines().count() - 1,
        sol.u.len() / 3,
        "a row per node of the cut body"
    );
    let measures = std::fs::read_to_string(out.join("measures.csv")).unwrap();
    assert!(
        measures.lines().count() > 10,
        "the measures go on after the cut"
    );
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn an_interactive_scenario_cuts_at_its_frame() {
    let sc = block_scenario(
        r#"
[[cut]]
time = 0.1
quad = [[0.0213, -0.01, 0.0101], [0.0213, 0.03, 0.0101], [0.0213, 0.03, 0.03], [0.0213, -0.01, 0.03]]
[run]
duration = 0.2
[interactive]
fps = 20
cycles = 20
"#,
    );
    let out = temp_out("interactive");
    let sol = raisov::runner::solve(
        &sc,
        raisov::runner::RunOptions {
            out_dir: Some(out.clone()),
            ..Default::default()
        },
    )
    .unwrap();
    assert!(sol.u.len() > 3 * sc.mesh.num_nodes());
    let n0 = sc.mesh.num_nodes();
    let frame = |k: usize| out.join("frames").join(format!("{}_{k:06}.vtu", sc.name));
    assert_eq!(vtu_points(&frame(1)), n0, "frame 1 is before the cut");
    assert!(
        vtu_points(&frame(2)) > n0,
        "the cut acts before frame 2 (t = 0.1 s)"
    );
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn a_cut_the_run_cannot_take_is_refused_when_the_scenario_loads() {
    let load = |extra: &str| {
        let text = format!(
            r#"
[mesh]
generate = "box"
size = [0.04, 0.02, 0.02]
divisions = [4, 2, 2]
[material]
law = "neo-hookean"
young = 5e3
poisson = 0.45
[[fix]]
plane = {{ point = [0, 0, 0], normal = [1, 0, 0] }}
[[cut]]
edge = [[0.02, -0.01, 0.0], [0.02, 0.03, 0.0]]
sweep = [0.0, 0.0, 0.03]
{extra}
"#
        );
        raisov::scenario::Scenario::from_toml(&text, std::path::Path::new("cut.toml"))
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default()
    };
    let e = load("[integrator]\nmethod = \"newton\"");
    assert!(e.contains("[[cut]]") && e.contains("static"), "{e}");
    let e = load("[[tool]]\nshape = \"sphere\"\ncenter = [0.02, 0.01, 0.04]\nradius = 0.01\n[run]\nduration = 1");
    assert!(e.contains("tools"), "{e}");
    let bad = r#"
[mesh]
generate = "box"
size = [0.04, 0.02, 0.02]
divisions = [4, 2, 2]
[material]
law = "neo-hookean"
young = 5e3
poisson = 0.45
[[cut]]
edge = [[0.02, 0.0, 0.0], [0.02, 0.0, 0.0]]
sweep = [0.0, 0.0, 0.03]
[run]
duration = 1
"#;
    let e = raisov::scenario::Scenario::from_toml(bad, std::path::Path::new("cut.toml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("cut[0]") && e.contains("no area"), "{e}");
}

/// The block cut through at t = 0.01 s under `run` (its `[run]` and scheme sections), in
/// memory: the body was cut, and the free half fell.
fn falls_apart_under(run: &str) {
    let sc = block_scenario(&format!(
        r#"
[[cut]]
time = 0.01
edge = [[0.0213, -0.01, 0.03], [0.0213, 0.03, 0.03]]
sweep = [0.0, 0.0, -0.04]
{run}
"#
    ));
    let sol = raisov::runner::solve(
        &sc,
        raisov::runner::RunOptions {
            in_memory: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(sol.u.len() > 3 * sc.mesh.num_nodes(), "the body was cut");
    assert!(sol.u.iter().all(|v| v.is_finite()));
    let low = sol
        .u
        .chunks_exact(3)
        .map(|u| u[2])
        .fold(f64::INFINITY, f64::min);
    assert!(low < -1e-3, "the cut-off half fell {low} m");
}

#[test]
fn the_paper_cycle_runs_on_a_cut_body() {
    falls_apart_under("[run]\nduration = 0.03\n[multigrid]\nscheme = \"raisov-paper\"\nlevels = 2");
}

#[test]
fn backward_euler_runs_on_a_cut_body() {
    falls_apart_under(
        "[integrator]\nmethod = \"implicit-euler\"\ndt = 0.005\n[run]\nduration = 0.05",
    );
}

#[test]
fn the_wounds_faces_carry_no_traction_and_each_lip_averages_its_own_stress() {
    let (fine, _, blade) = notched_levels();
    let mut cut = CutMesh::new(fine.clone()).unwrap();
    cut.cut(&blade).unwrap();
    let stress = |mesh: &Mesh, fractions: Option<&[f64]>| {
        let mut sys = cantilever(mesh, fractions);
        let u = equilibrium(&mut sys);
        let mut t = vec![0.0; 9 * mesh.num_nodes()];
        sys.force.nodal_stress(&u, &mut t);
        t
    };
    let t_cut = stress(cut.mesh(), Some(cut.fractions()));
    let t_whole = stress(&fine, None);
    // The wound's nodes: the base nodes with more than one copy, in the top half.
    let mut copies = vec![Vec::new(); fine.num_nodes()];
    for (a, &o) in cut.base_nodes().iter().enumerate() {
        copies[o as usize].push(a);
    }
    let lips: Vec<usize> = (0..fine.num_nodes())
        .filter(|&o| copies[o].len() > 1 && fine.nodes[o][2] > 0.0151)
        .collect();
    assert!(!lips.is_empty());
    // σ_xx, the stress across the wound, at each lip against the uncut beam at the same place.
    let (mut on_lips, mut uncut) = (0.0, 0.0);
    for &o in &lips {
        uncut += t_whole[9 * o].abs();
        for &a in &copies[o] {
            on_lips += t_cut[9 * a].abs() / copies[o].len() as f64;
        }
    }
    let ratio = on_lips / uncut;
    eprintln!(
        "|σ_xx| on the lips / uncut: {ratio:.3} over {} nodes",
        lips.len()
    );
    assert!(
        ratio < 0.2,
        "the lips carry {ratio} of the uncut beam's bending stress"
    );
    // The two lips of a node carry their own stress: they differ.
    let o = lips[0];
    let (a, b) = (copies[o][0], copies[o][1]);
    assert!((t_cut[9 * a..9 * a + 9])
        .iter()
        .zip(&t_cut[9 * b..9 * b + 9])
        .any(|(x, y)| (x - y).abs() > 1e-3 * uncut / lips.len() as f64));
}
