//! Physics tests of the force model.

use super::*;
use crate::material::{
    HolzapfelGasserOgden, MooneyRivlin, NeoHookean, StVenantKirchhoff, StableNeoHookean,
    TiNeoHookean, VerondaWestmann,
};
use crate::mesh::{ElementKind, Mesh};

/// Structured unit-ish box of 6 tets per cube, interior nodes jittered (irregular mesh).
pub(crate) fn jittered_box(n: usize, jitter: f64) -> Mesh {
    let idx = |i: usize, j: usize, k: usize| (i + (n + 1) * (j + (n + 1) * k)) as u32;
    let mut nodes = Vec::new();
    let h = 0.01 / n as f64;
    let mut seed = 12345u64;
    let mut rnd = || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((seed >> 11) as f64 / (1u64 << 53) as f64) - 0.5
    };
    for k in 0..=n {
        for j in 0..=n {
            for i in 0..=n {
                let interior = i > 0 && i < n && j > 0 && j < n && k > 0 && k < n;
                let mut p = [i as f64 * h, j as f64 * h, k as f64 * h];
                if interior {
                    for x in &mut p {
                        *x += jitter * h * rnd();
                    }
                }
                nodes.push(p);
            }
        }
    }
    let mut cells = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let v = [
                    idx(i, j, k),
                    idx(i + 1, j, k),
                    idx(i + 1, j + 1, k),
                    idx(i, j + 1, k),
                    idx(i, j, k + 1),
                    idx(i + 1, j, k + 1),
                    idx(i + 1, j + 1, k + 1),
                    idx(i, j + 1, k + 1),
                ];
                // Kuhn subdivision along the diagonal v0-v6.
                for t in [
                    [0, 1, 2, 6],
                    [0, 2, 3, 6],
                    [0, 3, 7, 6],
                    [0, 7, 4, 6],
                    [0, 4, 5, 6],
                    [0, 5, 1, 6],
                ] {
                    cells.extend(t.iter().map(|&q| v[q]));
                }
            }
        }
    }
    let mut m = Mesh::new(ElementKind::Tet4, nodes, cells);
    m.orient();
    m
}

/// Structured square membrane in a tilted plane (so the 3-D embedding is exercised), jittered.
pub(crate) fn jittered_membrane(n: usize, jitter: f64) -> Mesh {
    let h = 0.1 / n as f64;
    let mut seed = 999u64;
    let mut rnd = || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((seed >> 11) as f64 / (1u64 << 53) as f64) - 0.5
    };
    let (c, s) = (0.8f64, 0.6f64);
    let mut nodes = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let interior = i > 0 && i < n && j > 0 && j < n;
            let (mut x, mut y) = (i as f64 * h, j as f64 * h);
            if interior {
                x += jitter * h * rnd();
                y += jitter * h * rnd();
            }
            nodes.push([x, c * y, s * y]);
        }
    }
    let idx = |i: usize, j: usize| (i + (n + 1) * j) as u32;
    let mut cells = Vec::new();
    for j in 0..n {
        for i in 0..n {
            cells.extend([idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)]);
            cells.extend([idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)]);
        }
    }
    Mesh::new(ElementKind::Tri3, nodes, cells)
}

fn materials() -> Vec<Material> {
    vec![
        Material::StVenantKirchhoff(StVenantKirchhoff::from_young(1e4, 0.3)),
        Material::NeoHookean(NeoHookean::from_young(1e4, 0.4)),
        Material::MooneyRivlin(MooneyRivlin::new(2e3, 1e3, 5e4)),
        Material::VerondaWestmann(VerondaWestmann::new(500.0, 3.0, 5e4)),
        Material::StableNeoHookean(StableNeoHookean::from_young(1e4, 0.4)),
    ]
}

/// [`materials`], and for tetrahedra the solid-only fibre laws (fibres oblique to the axes).
fn materials_for(kind: ElementKind) -> Vec<Material> {
    let mut v = materials();
    if kind == ElementKind::Tet4 {
        let a = nalgebra::Vector3::new(1.0, 0.5, -0.3);
        v.push(Material::TiNeoHookean(
            TiNeoHookean::new(1e3, 5e4, 4e3, a).unwrap(),
        ));
        v.push(Material::HolzapfelGasserOgden(
            HolzapfelGasserOgden::new(1e3, 5e4, 2e3, 3.0, 0.1, a).unwrap(),
        ));
    }
    v
}

pub(crate) fn random_u(n: usize, amp: f64, seed: u64) -> Vec<f64> {
    let mut s = seed;
    (0..3 * n)
        .map(|_| {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            amp * (((s >> 11) as f64 / (1u64 << 53) as f64) - 0.5)
        })
        .collect()
}

fn meshes() -> Vec<(&'static str, Mesh)> {
    vec![
        ("tet", jittered_box(2, 0.3)),
        ("membrane", jittered_membrane(3, 0.3)),
    ]
}

#[test]
fn force_is_energy_gradient_for_every_element_and_material() {
    for (name, mesh) in meshes() {
        for mat in materials_for(mesh.kind) {
            let mut model = FemModel::new(&mesh, FemParams::new(mat.clone())).unwrap();
            let n = mesh.num_nodes();
            let h0 = mesh.edge_range().0;
            let u = random_u(n, 0.3 * h0, 7);
            let mut r = vec![0.0; 3 * n];
            model.internal_forces(&u, &mut r).unwrap();
            let scale = r.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
            let eps = 1e-6 * h0;
            let mut up = u.clone();
            for i in 0..3 * n {
                up[i] = u[i] + eps;
                let ep = model.strain_energy(&up);
                up[i] = u[i] - eps;
                let em = model.strain_energy(&up);
                up[i] = u[i];
                let fd = (ep - em) / (2.0 * eps);
                assert!(
                    (fd - r[i]).abs() <= 1e-5 * scale,
                    "{name}/{}: dof {i}: R = {} but dE/du = {fd}",
                    mat.name(),
                    r[i]
                );
            }
        }
    }
}

#[test]
fn rigid_motion_gives_zero_force_and_unchanged_stress() {
    let rot = nalgebra::Rotation3::from_euler_angles(0.7, -0.4, 1.9);
    for (name, mesh) in meshes() {
        for mat in materials_for(mesh.kind) {
            let mut model = FemModel::new(&mesh, FemParams::new(mat.clone())).unwrap();
            let n = mesh.num_nodes();
            let h0 = mesh.edge_range().0;
            // A deformed state, then the same state rotated and translated.
            let u = random_u(n, 0.2 * h0, 3);
            let mut u_rigid = vec![0.0; 3 * n];
            let mut u_moved = vec![0.0; 3 * n];
            let t = nalgebra::Vector3::new(0.3, -1.0, 2.0);
            for a in 0..n {
                let x = nalgebra::Vector3::from(mesh.nodes[a]);
                let d = nalgebra::Vector3::new(u[3 * a], u[3 * a + 1], u[3 * a + 2]);
                let xr = rot * x + t;
                let xm = rot * (x + d) + t;
                for k in 0..3 {
                    u_rigid[3 * a + k] = xr[k] - x[k];
                    u_moved[3 * a + k] = xm[k] - x[k];
                }
            }
            let mut r = vec![0.0; 3 * n];
            model.internal_forces(&u_rigid, &mut r).unwrap();
            let rmax = r.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
            let mut r_def = vec![0.0; 3 * n];
            model.internal_forces(&u, &mut r_def).unwrap();
            let fscale = r_def.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
            assert!(
                rmax <= 1e-9 * fscale,
                "{name}/{}: rigid force {rmax}",
                mat.name()
            );
            // Energy unchanged; Cauchy stress rotates: σ' = Q σ Qᵀ.
            let e1 = model.strain_energy(&u);
            let e2 = model.strain_energy(&u_moved);
            assert!(
                (e1 - e2).abs() <= 1e-9 * e1.abs(),
                "{name}: energy {e1} vs {e2}"
            );
            let q = rot.into_inner();
            for e in 0..model.num_elements() {
                let s1 = model.element_cauchy(e, &u);
                let s2 = model.element_cauchy(e, &u_moved);
                let diff = (q * s1 * q.transpose() - s2).norm();
                assert!(
                    diff <= 1e-8 * s1.norm().max(1e-12),
                    "{name}: stress not objective"
                );
            }
        }
    }
}

/// Patch test: an affine deformation of an irregular mesh gives uniform stress and zero net
/// force on every interior node.
#[test]
fn patch_test_affine_deformation() {
    let g = nalgebra::Matrix3::new(0.05, 0.02, -0.01, 0.0, -0.03, 0.015, 0.01, 0.0, 0.04);
    for (name, mesh) in meshes() {
        let boundary = mesh.boundary_nodes();
        for mat in materials_for(mesh.kind) {
            let mut model = FemModel::new(&mesh, FemParams::new(mat.clone())).unwrap();
            let n = mesh.num_nodes();
            let mut u = vec![0.0; 3 * n];
            for a in 0..n {
                let d = g * nalgebra::Vector3::from(mesh.nodes[a]);
                u[3 * a..3 * a + 3].copy_from_slice(d.as_slice());
            }
            let mut r = vec![0.0; 3 * n];
            model.internal_forces(&u, &mut r).unwrap();
            let fscale = r.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
            assert!(fscale > 0.0);
            let interior: Vec<usize> = (0..n)
                .filter(|a| boundary.binary_search(&(*a as u32)).is_err())
                .collect();
            assert!(
                !interior.is_empty(),
                "{name}: test mesh needs interior nodes"
            );
            for &a in &interior {
                for k in 0..3 {
                    assert!(
                        r[3 * a + k].abs() <= 1e-9 * fscale,
                        "{name}/{}: interior force",
                        mat.name()
                    );
                }
            }
            let s0 = model.element_cauchy(0, &u);
            for e in 1..model.num_elements() {
                let s = model.element_cauchy(e, &u);
                assert!(
                    (s - s0).norm() <= 1e-9 * s0.norm(),
                    "{name}: stress not uniform"
                );
            }
            let mut t = vec![0.0; 9 * n];
            model.nodal_cauchy(&u, &mut t);
            for a in 0..n {
                for i in 0..3 {
                    for j in 0..3 {
                        assert!((t[9 * a + 3 * i + j] - s0[(i, j)]).abs() <= 1e-9 * s0.norm());
                    }
                }
            }
        }
    }
}

#[test]
fn lumped_mass_sums_to_total_mass() {
    for (name, mesh) in meshes() {
        let mut p = FemParams::new(materials()[1].clone());
        p.density = 1070.0;
        p.thickness = 2e-3;
        let model = FemModel::new(&mesh, p).unwrap();
        let total: f64 = model.lumped_mass().iter().sum();
        let expect = 1070.0
            * mesh.total_measure()
            * if mesh.kind == ElementKind::Tri3 {
                2e-3
            } else {
                1.0
            };
        assert!(
            (total - expect).abs() <= 1e-12 * expect,
            "{name}: {total} vs {expect}"
        );
        assert!(model.lumped_mass().iter().all(|&m| m > 0.0));
    }
}

/// The parallel gather path equals the serial scatter reference, and gives the same bits on
/// 1 and 2 threads.
#[test]
fn parallel_forces_match_reference_and_are_thread_count_independent() {
    for mesh in [jittered_box(6, 0.3), jittered_membrane(40, 0.3)] {
        let mut p = FemParams::new(materials()[1].clone());
        // Force the parallel paths (generic tasks, packed slabs) on a small mesh.
        p.chunk = 64;
        p.slab = 64;
        let mut model = FemModel::new(&mesh, p).unwrap();
        let n = mesh.num_nodes();
        let u = random_u(n, 0.1 * mesh.edge_range().0, 11);
        let mut r_ref = vec![0.0; 3 * n];
        model.internal_forces_reference(&u, &mut r_ref).unwrap();
        let mut runs = Vec::new();
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut r = vec![0.0; 3 * n];
            pool.install(|| model.internal_forces(&u, &mut r)).unwrap();
            runs.push(r);
        }
        assert_eq!(runs[0], runs[1], "bits differ between 1 and 2 threads");
        let scale = r_ref.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
        for (a, b) in runs[0].iter().zip(&r_ref) {
            assert!((a - b).abs() <= 1e-12 * scale);
        }
    }
}

#[test]
fn inverted_element_is_reported() {
    let mesh = jittered_box(1, 0.0);
    let mut model = FemModel::new(&mesh, FemParams::new(materials()[1].clone())).unwrap();
    let n = mesh.num_nodes();
    // Mirror the whole box through x = 0: every element inverts.
    let mut u = vec![0.0; 3 * n];
    for a in 0..n {
        u[3 * a] = -2.0 * mesh.nodes[a][0];
    }
    let mut r = vec![0.0; 3 * n];
    let err = model.internal_forces(&u, &mut r).unwrap_err();
    assert!(err.det_f < 0.0);
    // Mirroring inverts the elements having volume across x; the first reported is the lowest.
    assert_eq!(err.element, 0);
}

/// Element tangent stiffness = central differences of the element forces, every law, tets and
/// membranes, at a random deformed state (1e-6 of the largest entry), and symmetric.
#[test]
fn element_stiffness_is_force_derivative_for_every_element_and_material() {
    for (name, mesh) in meshes() {
        for mat in materials_for(mesh.kind) {
            let model = FemModel::new(&mesh, FemParams::new(mat.clone())).unwrap();
            let n = mesh.num_nodes();
            let h0 = mesh.edge_range().0;
            let u = random_u(n, 0.3 * h0, 11);
            let npe = mesh.npe();
            let d = 3 * npe;
            let mut k = vec![0.0; d * d];
            let (mut fp, mut fm) = (vec![0.0; d], vec![0.0; d]);
            for e in 0..model.num_elements() {
                model.element_stiffness(e, &u, &mut k).unwrap();
                let scale = k.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
                let el: Vec<u32> = model.element_nodes(e).to_vec();
                let eps = 1e-6 * h0;
                for b in 0..npe {
                    for q in 0..3 {
                        let mut up = u.clone();
                        up[3 * el[b] as usize + q] += eps;
                        model.element_forces(e, &up, &mut fp).unwrap();
                        up[3 * el[b] as usize + q] -= 2.0 * eps;
                        model.element_forces(e, &up, &mut fm).unwrap();
                        for r in 0..d {
                            let fd = (fp[r] - fm[r]) / (2.0 * eps);
                            let an = k[r * d + 3 * b + q];
                            assert!(
                                (fd - an).abs() <= 1e-6 * scale,
                                "{name} {}: element {e} K[{r}][{}] = {an:e}, FD {fd:e}",
                                mat.name(),
                                3 * b + q
                            );
                        }
                    }
                }
                for r in 0..d {
                    for c in 0..r {
                        assert!((k[r * d + c] - k[c * d + r]).abs() <= 1e-9 * scale);
                    }
                }
            }
        }
    }
}

/// Stable neo-Hookean: a tetrahedron with its base fixed and its apex pushed through the base
/// (`det F < 0`) recovers under damped explicit dynamics (symplectic Euler at half the
/// estimated critical step): positive again and back at rest (|u| ≤ 1e-6 h). Neo-Hookean
/// refuses the same start (an element failure).
#[test]
fn stable_neo_hookean_inverted_tet_recovers() {
    use crate::integrate::{Constraints, Integrator, Method, State, SymplecticEuler, System};
    let h = 0.01;
    let mesh = Mesh::new(
        ElementKind::Tet4,
        vec![[0.0, 0.0, 0.0], [h, 0.0, 0.0], [0.0, h, 0.0], [0.0, 0.0, h]],
        vec![0, 1, 2, 3],
    );
    let mut start = State::at_rest(4);
    start.u[9..12].copy_from_slice(&[0.3 * h, 0.2 * h, -1.6 * h]);
    for (name, mat) in [
        (
            "stable",
            Material::StableNeoHookean(StableNeoHookean::from_young(1e4, 0.4)),
        ),
        (
            "neo",
            Material::NeoHookean(NeoHookean::from_young(1e4, 0.4)),
        ),
    ] {
        let mut params = FemParams::new(mat.clone());
        params.density = 1000.0;
        let model = FemModel::new(&mesh, params).unwrap();
        assert!(model.min_det_f(&start.u).1 < 0.0);
        let mass = model.lumped_mass();
        let dt = 0.5
            * crate::integrate::stability::critical_step_estimate(
                &mesh,
                &mat,
                1000.0,
                Method::SymplecticEuler,
            );
        let mut sys = System::new(
            Box::new(model),
            mass,
            1000.0,
            vec![0.0; 12],
            Constraints::new(vec![0, 1, 2], Vec::new()),
        );
        let mut s = start.clone();
        let mut se = SymplecticEuler::new(4);
        let mut failed = false;
        for _ in 0..20_000 {
            if se.step(&mut sys, &mut s, dt).is_err() {
                failed = true;
                break;
            }
        }
        if name == "neo" {
            assert!(failed, "neo-Hookean took an inverted element");
            continue;
        }
        assert!(!failed);
        let (_, det) = sys.force.min_det_f(&s.u);
        assert!(det > 0.0, "still inverted (det F = {det})");
        let umax = s.u.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
        assert!(umax <= 1e-6 * h, "not back at rest: |u| = {umax:e}");
    }
}

/// `law = "stable-neo-hookean"` in a scenario gives the law with the user's Lamé parameters,
/// and direct Newton solves a sagging block of it to the same equilibrium as neo-Hookean's
/// within the laws' difference at this strain (they agree to first order; 2 % of the sag).
#[test]
fn stable_neo_hookean_scenario_sags_like_neo_hookean() {
    use crate::statics::newton::{solve_system, DirectNewtonParams};
    let sag = |law: &str| {
        let text = format!(
            r#"
gravity = [0.0, 0.0, -9.81]
[mesh]
generate = "box"
size = [0.1, 0.03, 0.03]
nodes = 200
[material]
law = "{law}"
young = 50000.0
poisson = 0.4
density = 1000.0
[[fix]]
plane = {{ point = [0.0, 0.0, 0.0], normal = [1.0, 0.0, 0.0] }}
[run]
duration = 1.0
"#
        );
        let sc =
            crate::scenario::Scenario::from_toml(&text, std::path::Path::new("snh.toml")).unwrap();
        if law == "stable-neo-hookean" {
            let (l, m) = crate::material::lame(5e4, 0.4);
            assert_eq!(
                sc.material,
                Material::StableNeoHookean(StableNeoHookean {
                    lame_mu: m,
                    lame_lambda: l
                })
            );
        }
        let mut sys = sc.build_system().unwrap();
        let mut u = vec![0.0; 3 * sc.mesh.num_nodes()];
        let out = solve_system(&mut sys, 0.0, &mut u, DirectNewtonParams::default()).unwrap();
        assert!(out.converged, "{law}: {out:?}");
        u
    };
    let (a, b) = (sag("neo-hookean"), sag("stable-neo-hookean"));
    let scale = a.iter().fold(0.0f64, |m, &x| m.max(x.abs()));
    let diff = a
        .iter()
        .zip(&b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
    assert!(scale > 1e-4, "no sag: {scale:e}");
    assert!(diff <= 0.02 * scale, "sags differ by {diff:e} of {scale:e}");
}

/// The line search's energy refuses what the internal forces refuse: with one tetrahedron
/// inverted (a node pushed through its opposite face), neo-Hookean's `W(C)` is finite (the
/// mirror image's) but [`FemModel::admissible_strain_energy`] is +∞, as the forces fail;
/// stable neo-Hookean accepts the inverted element in both. At a valid state the two agree.
/// And the blocked parallel sum is the same bits on one thread and on two.
#[test]
fn admissible_energy_refuses_inverted_tetrahedra_like_the_forces() {
    let mesh = jittered_box(2, 0.3);
    let n = mesh.num_nodes();
    let el: Vec<usize> = mesh.cells[..4].iter().map(|&a| a as usize).collect();
    let p = |k: usize| Vector3::from(mesh.nodes[el[k]]);
    // Reflect node el[0] through the plane of the other three: element 0 inverts.
    let nrm = (p(2) - p(1)).cross(&(p(3) - p(1))).normalize();
    let shift = -2.0 * (p(0) - p(1)).dot(&nrm) * nrm;
    let mut inverted = vec![0.0; 3 * n];
    inverted[3 * el[0]..3 * el[0] + 3].copy_from_slice(shift.as_slice());
    let valid = random_u(n, 0.1 * mesh.edge_range().0, 3);
    for (mat, refused) in [
        (Material::NeoHookean(NeoHookean::from_young(1e4, 0.4)), true),
        (
            Material::StableNeoHookean(StableNeoHookean::from_young(1e4, 0.4)),
            false,
        ),
    ] {
        let mut model = FemModel::new(&mesh, FemParams::new(mat.clone())).unwrap();
        let mut r = vec![0.0; 3 * n];
        assert_eq!(
            model.internal_forces(&inverted, &mut r).is_err(),
            refused,
            "{}",
            mat.name()
        );
        let w = model.strain_energy(&inverted);
        let wa = model.admissible_strain_energy(&inverted);
        assert!(w.is_finite(), "{}: {w}", mat.name());
        if refused {
            assert_eq!(wa, f64::INFINITY, "{}", mat.name());
        } else {
            assert_eq!(wa, w, "{}", mat.name());
        }
        assert_eq!(
            model.admissible_strain_energy(&valid),
            model.strain_energy(&valid)
        );
    }
    // A mesh of several energy blocks, summed on one thread and on two.
    let big = jittered_box(14, 0.3);
    assert!(big.num_elements() > 2 * ENERGY_BLOCK);
    let model = FemModel::new(
        &big,
        FemParams::new(Material::NeoHookean(NeoHookean::from_young(1e4, 0.4))),
    )
    .unwrap();
    let u = random_u(big.num_nodes(), 0.1 * big.edge_range().0, 5);
    let on = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| model.strain_energy(&u))
    };
    assert_eq!(on(1).to_bits(), on(2).to_bits());
}

/// The tangent `model` assembles at `u` (its element blocks over
/// [`ForceModel::tangent_elements`] plus the blocks of [`ForceModel::add_extra_tangent`]), as a
/// dense matrix, against central differences (step `h`) of its [`ForceModel::internal_forces`]:
/// every entry within `tol` times the largest. Returns the largest entry of the extra blocks
/// (so a test can see that they were exercised).
pub(crate) fn assert_tangent_matches_fd(
    model: &mut dyn ForceModel,
    u: &[f64],
    h: f64,
    tol: f64,
    what: &str,
) -> f64 {
    let nd = 3 * model.num_nodes();
    let mut k = vec![0.0; nd * nd];
    if let Some(topo) = model.tangent_elements() {
        for e in 0..topo.len() {
            let nodes = topo.element(e).to_vec();
            let m = 3 * nodes.len();
            let mut ke = vec![0.0; m * m];
            model.element_tangent(e, u, &mut ke).unwrap();
            for (a, &na) in nodes.iter().enumerate() {
                for (b, &nb) in nodes.iter().enumerate() {
                    for i in 0..3 {
                        for j in 0..3 {
                            k[(3 * na as usize + i) * nd + 3 * nb as usize + j] +=
                                ke[(3 * a + i) * m + 3 * b + j];
                        }
                    }
                }
            }
        }
    }
    let mut extra_max = 0.0f64;
    model.add_extra_tangent(u, &mut |nodes, block| {
        let m = 3 * nodes.len();
        for (a, &na) in nodes.iter().enumerate() {
            for (b, &nb) in nodes.iter().enumerate() {
                for i in 0..3 {
                    for j in 0..3 {
                        let v = block[(3 * a + i) * m + 3 * b + j];
                        assert_eq!(
                            v,
                            block[(3 * b + j) * m + 3 * a + i],
                            "{what}: asymmetric block"
                        );
                        extra_max = extra_max.max(v.abs());
                        k[(3 * na as usize + i) * nd + 3 * nb as usize + j] += v;
                    }
                }
            }
        }
    });
    let scale = k.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    assert!(scale > 0.0, "{what}: zero tangent");
    let (mut rp, mut rm) = (vec![0.0; nd], vec![0.0; nd]);
    for j in 0..nd {
        let mut w = u.to_vec();
        w[j] = u[j] + h;
        model.internal_forces(&w, &mut rp).unwrap();
        w[j] = u[j] - h;
        model.internal_forces(&w, &mut rm).unwrap();
        for i in 0..nd {
            let fd = (rp[i] - rm[i]) / (2.0 * h);
            let an = k[i * nd + j];
            assert!(
                (fd - an).abs() <= tol * scale,
                "{what}: K[{i}][{j}] = {an:e}, finite differences {fd:e} (largest entry {scale:e})"
            );
        }
    }
    extra_max
}

/// The finite-element model's own tangent (no extra blocks) is the derivative of its forces,
/// assembled over its elements, on a tet box and a membrane.
#[test]
fn assembled_element_tangent_is_the_force_derivative() {
    for (name, mesh) in [
        ("tets", jittered_box(2, 0.3)),
        ("membrane", jittered_membrane(3, 0.3)),
    ] {
        let mut fem = FemModel::new(
            &mesh,
            FemParams::new(Material::NeoHookean(NeoHookean::from_young(1e4, 0.4))),
        )
        .unwrap();
        let u = random_u(mesh.num_nodes(), 3e-4, 3);
        let extra = assert_tangent_matches_fd(&mut fem, &u, 1e-8, 1e-6, name);
        assert_eq!(extra, 0.0, "{name}: no blocks beyond the elements");
    }
}
