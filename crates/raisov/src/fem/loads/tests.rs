//! Time functions, pressure and traction: closed forms and balances.

use super::*;
use crate::fem::{FemModel, FemParams};
use crate::integrate::{Constraints, System};
use crate::material::{Material, StVenantKirchhoff};
use crate::mesh::{ElementKind, Mesh};
use crate::statics::krylov::{NewtonParams, NewtonSolver};

#[test]
fn time_functions_values_and_rates() {
    let r = TimeFunction::Ramp { duration: 0.5 };
    assert_eq!(r.value(-1.0), 0.0);
    assert_eq!(r.value(0.25), 0.5);
    assert_eq!(r.value(3.0), 1.0);
    assert_eq!(r.rate(0.1), 2.0);
    assert_eq!(r.rate(0.6), 0.0);
    let t = TimeFunction::Table {
        times: vec![0.0, 1.0, 3.0],
        values: vec![0.0, 2.0, -2.0],
    };
    assert_eq!(t.value(0.5), 1.0);
    assert_eq!(t.value(2.0), 0.0);
    assert_eq!(t.value(9.0), -2.0);
    assert_eq!(t.rate(2.0), -2.0);
    assert_eq!(t.max_abs(), 2.0);
    assert_eq!(t.end(), 3.0);
    let s = TimeFunction::Sine {
        amplitude: 2.0,
        frequency: 0.25,
        phase: 0.0,
    };
    assert!((s.value(1.0) - 2.0).abs() < 1e-15);
    assert!(s.value(2.0).abs() < 1e-15);
    // The rate against a central difference.
    let h = 1e-6;
    let fd = (s.value(0.3 + h) - s.value(0.3 - h)) / (2.0 * h);
    assert!((fd - s.rate(0.3)).abs() < 1e-8, "{fd} vs {}", s.rate(0.3));
    assert!(s.end().is_infinite());
    assert_eq!(TimeFunction::Constant.value(7.0), 1.0);
}

/// A UV sphere membrane of radius `r`: `nlat` rings between the poles (odd: an equator ring),
/// `nlon` (a multiple of 4) nodes per ring, triangles with outward normals. Coordinates within
/// 1e-14 r of a coordinate plane are set to exactly 0 (the symmetry planes of the tests).
pub(crate) fn uv_sphere(r: f64, nlat: usize, nlon: usize) -> Mesh {
    let mut nodes = vec![[0.0, 0.0, r]];
    let clean = |x: f64| if x.abs() < 1e-14 * r { 0.0 } else { x };
    for i in 1..=nlat {
        let th = std::f64::consts::PI * i as f64 / (nlat + 1) as f64;
        for j in 0..nlon {
            let ph = 2.0 * std::f64::consts::PI * j as f64 / nlon as f64;
            nodes.push([
                clean(r * th.sin() * ph.cos()),
                clean(r * th.sin() * ph.sin()),
                clean(r * th.cos()),
            ]);
        }
    }
    nodes.push([0.0, 0.0, -r]);
    let south = (nodes.len() - 1) as u32;
    let ring = |i: usize, j: usize| (1 + i * nlon + j % nlon) as u32;
    let mut cells = Vec::new();
    for j in 0..nlon {
        cells.extend([0, ring(0, j), ring(0, j + 1)]);
        cells.extend([south, ring(nlat - 1, j + 1), ring(nlat - 1, j)]);
    }
    for i in 0..nlat - 1 {
        for j in 0..nlon {
            let (a, b, c, d) = (
                ring(i, j),
                ring(i, j + 1),
                ring(i + 1, j),
                ring(i + 1, j + 1),
            );
            cells.extend([a, c, d, a, d, b]);
        }
    }
    Mesh::new(ElementKind::Tri3, nodes, cells)
}

/// A geodesic sphere membrane of radius `r`: the icosahedron with vertices `(0, ±1, ±φ)` and
/// their cyclic permutations, each triangle cut into 4 `levels` times, nodes projected onto
/// the sphere; outward normals. The mesh is symmetric under `x → −x`, `y → −y`, `z → −z`, and
/// nodes on those planes have the coordinate exactly 0.
pub(crate) fn icosphere(r: f64, levels: usize) -> Mesh {
    let g = (1.0 + 5f64.sqrt()) / 2.0;
    let mut nodes: Vec<[f64; 3]> = vec![
        [-1.0, g, 0.0],
        [1.0, g, 0.0],
        [-1.0, -g, 0.0],
        [1.0, -g, 0.0],
        [0.0, -1.0, g],
        [0.0, 1.0, g],
        [0.0, -1.0, -g],
        [0.0, 1.0, -g],
        [g, 0.0, -1.0],
        [g, 0.0, 1.0],
        [-g, 0.0, -1.0],
        [-g, 0.0, 1.0],
    ];
    let mut tris: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut mid = std::collections::HashMap::new();
        let mut next = Vec::with_capacity(4 * tris.len());
        for t in &tris {
            let mut m = [0u32; 3];
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                let key = (a.min(b), a.max(b));
                m[k] = *mid.entry(key).or_insert_with(|| {
                    let (p, q) = (nodes[a as usize], nodes[b as usize]);
                    nodes.push([0, 1, 2].map(|i| 0.5 * (p[i] + q[i])));
                    (nodes.len() - 1) as u32
                });
            }
            next.extend([
                [t[0], m[0], m[2]],
                [t[1], m[1], m[0]],
                [t[2], m[2], m[1]],
                m,
            ]);
        }
        tris = next;
    }
    for p in &mut nodes {
        let l = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        *p = p.map(|x| r * x / l);
    }
    Mesh::new(
        ElementKind::Tri3,
        nodes,
        tris.into_iter().flatten().collect(),
    )
}

#[test]
fn sphere_meshes_have_outward_normals() {
    for m in [uv_sphere(1.0, 7, 16), icosphere(1.0, 2)] {
        for e in 0..m.num_elements() {
            let p = m.element_points(e);
            let n = cross(
                [p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]],
                [p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]],
            );
            let c = [0, 1, 2].map(|k| (p[0][k] + p[1][k] + p[2][k]) / 3.0);
            assert!(n[0] * c[0] + n[1] * c[1] + n[2] * c[2] > 0.0, "element {e}");
        }
    }
}

fn loaded_sphere(p: f64, mesh: &Mesh, params: FemParams) -> Loaded {
    let fem = FemModel::new(mesh, params).unwrap();
    let x0 = fem.reference_positions().to_vec();
    let tris: Vec<[u32; 3]> = mesh.elements().map(|t| [t[0], t[1], t[2]]).collect();
    Loaded::new(
        Box::new(fem),
        x0,
        vec![SurfaceLoad {
            triangles: tris,
            kind: SurfaceLoadKind::Pressure(p),
            time: TimeFunction::Constant,
        }],
        vec![],
    )
}

/// On a closed surface the pressure has zero net force for any deformation, and its force is
/// the gradient of its potential `W = −p V` (central differences).
#[test]
fn pressure_on_closed_surface_has_zero_net_force_and_is_the_gradient_of_its_work() {
    let mesh = uv_sphere(0.1, 5, 12);
    let lo = loaded_sphere(
        1e3,
        &mesh,
        FemParams::new(Material::StVenantKirchhoff(StVenantKirchhoff::from_young(
            1e5, 0.3,
        ))),
    );
    let n = mesh.num_nodes();
    let mut seed = 7u64;
    let u: Vec<f64> = (0..3 * n)
        .map(|_| {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
            1e-3 * (((seed >> 11) as f64 / (1u64 << 53) as f64) - 0.5)
        })
        .collect();
    let mut f = vec![0.0; 3 * n];
    lo.add_load_forces(&u, &mut f);
    let net: Vec<f64> = (0..3)
        .map(|k| f.iter().skip(k).step_by(3).sum::<f64>())
        .collect();
    let scale: f64 = f.iter().map(|x| x.abs()).sum();
    for c in &net {
        assert!(c.abs() < 1e-13 * scale, "net {net:?} scale {scale}");
    }
    // W = −p V: the enclosed volume of the (faceted) reference sphere.
    let w_ref = lo.add_load_forces(&vec![0.0; 3 * n], &mut vec![0.0; 3 * n]);
    let v_faceted = -w_ref / 1e3;
    let v_sphere = 4.0 / 3.0 * std::f64::consts::PI * 1e-3;
    assert!(
        v_faceted > 0.8 * v_sphere && v_faceted < v_sphere,
        "{v_faceted}"
    );
    let h = 1e-7;
    for i in [0, 5, 17, 3 * n - 1] {
        let mut up = u.clone();
        up[i] += h;
        let mut um = u.clone();
        um[i] -= h;
        let wp = lo.add_load_forces(&up, &mut vec![0.0; 3 * n]);
        let wm = lo.add_load_forces(&um, &mut vec![0.0; 3 * n]);
        let fd = (wp - wm) / (2.0 * h);
        assert!(
            (fd - f[i]).abs() < 1e-6 * f[i].abs().max(1e-3),
            "dof {i}: fd {fd} vs {}",
            f[i]
        );
    }
}

/// Traction per reference area: the total force is the traction times the area, whatever
/// the deformation; the time function scales it.
#[test]
fn traction_total_is_traction_times_area_and_follows_time() {
    let mesh = crate::mesh::generate::rectangle_membrane(0.2, 0.1, 60).unwrap();
    let fem = FemModel::new(
        &mesh,
        FemParams::new(Material::StVenantKirchhoff(StVenantKirchhoff::from_young(
            1e5, 0.3,
        ))),
    )
    .unwrap();
    let x0 = fem.reference_positions().to_vec();
    let tris: Vec<[u32; 3]> = mesh.elements().map(|t| [t[0], t[1], t[2]]).collect();
    let mut lo = Loaded::new(
        Box::new(fem),
        x0,
        vec![SurfaceLoad {
            triangles: tris,
            kind: SurfaceLoadKind::Traction([0.0, 10.0, -50.0]),
            time: TimeFunction::Ramp { duration: 2.0 },
        }],
        vec![],
    );
    let n = mesh.num_nodes();
    let u: Vec<f64> = (0..3 * n).map(|i| 1e-3 * (i as f64).sin()).collect();
    lo.set_time(1.0);
    let rep = lo.load_report(&u);
    let area = 0.2 * 0.1;
    assert!(
        (rep.applied[1] - 0.5 * 10.0 * area).abs() < 1e-12,
        "{rep:?}"
    );
    assert!(
        (rep.applied[2] + 0.5 * 50.0 * area).abs() < 1e-12,
        "{rep:?}"
    );
    assert_eq!(rep.tool, [0.0; 3]);
}

/// Thin sphere under internal pressure, small strain (StVK membrane, plane stress): radial
/// growth `u = p R² (1 − ν) / (2 E h)` and hoop stress `σ = p R / (2 h)`. Symmetry planes
/// (the nodes on x = 0 hold u_x = 0, and so on) remove the rigid modes. The faceted geodesic
/// sphere (4 subdivisions, 2562 nodes) is within 1 % of both on average, and every node but
/// the icosahedron's 12 five-valent vertices within 2 % of the radial growth.
#[test]
fn thin_sphere_internal_pressure_matches_closed_form() {
    let (r, h, e, nu) = (0.1, 1e-3, 1e6, 0.3);
    let p_in = 3.0; // Pa: strain ~1e-4
    let mesh = icosphere(r, 4);
    let mut params = FemParams::new(Material::StVenantKirchhoff(StVenantKirchhoff::from_young(
        e, nu,
    )));
    params.thickness = h;
    // Outward normals: internal pressure is a negative value (module docs).
    let model = loaded_sphere(-p_in, &mesh, params);
    let n = mesh.num_nodes();
    let mut sliding = Vec::new();
    for (a, x) in mesh.nodes.iter().enumerate() {
        for k in 0..3 {
            if x[k] == 0.0 {
                let mut d = [0.0; 3];
                d[k] = 1.0;
                sliding.push((a as u32, d));
            }
        }
    }
    let mut sys = System::new(
        Box::new(model),
        vec![1e-3; n],
        0.0,
        vec![0.0; 3 * n],
        Constraints::new(vec![], vec![]).with_sliding(&sliding),
    );
    let mut u = vec![0.0; 3 * n];
    let mut newton = NewtonSolver::new(&sys);
    let rep = newton
        .solve(
            &mut sys,
            0.0,
            &mut u,
            NewtonParams {
                rel_tol: 1e-9,
                length: r,
                ..Default::default()
            },
        )
        .unwrap();
    assert!(rep.converged, "{rep:?}");
    let u_exact = p_in * r * r * (1.0 - nu) / (2.0 * e * h);
    let radial: Vec<f64> = mesh
        .nodes
        .iter()
        .enumerate()
        .map(|(a, x)| (0..3).map(|k| x[k] * u[3 * a + k]).sum::<f64>() / r)
        .collect();
    let mean = radial.iter().sum::<f64>() / n as f64;
    let (lo, hi) = radial
        .iter()
        .fold((f64::MAX, f64::MIN), |(l, h), &x| (l.min(x), h.max(x)));
    eprintln!("u exact {u_exact:.6e}, mean {mean:.6e}, range [{lo:.6e}, {hi:.6e}]");
    assert!(
        (mean / u_exact - 1.0).abs() < 0.01,
        "mean {mean} vs {u_exact}"
    );
    // The 12 five-valent vertices of the icosahedron, where the flat facets concentrate the
    // curvature, lag (−30 %); every other node is within 2 %.
    let worst = radial[12..]
        .iter()
        .map(|x| (x / u_exact - 1.0).abs())
        .fold(0.0, f64::max);
    eprintln!("worst relative error off the 12 vertices {worst:.3e}, hi {hi:.6e}, lo {lo:.6e}");
    assert!(worst < 0.02, "{worst}");
    // Hoop stress: half the trace of the nodal Cauchy stress (two equal in-plane principal
    // stresses, none through the thickness).
    let mut t = vec![0.0; 9 * n];
    sys.force.nodal_stress(&u, &mut t);
    let sigma = p_in * r / (2.0 * h);
    let mean_hoop = (0..n)
        .map(|a| 0.5 * (t[9 * a] + t[9 * a + 4] + t[9 * a + 8]))
        .sum::<f64>()
        / n as f64;
    eprintln!("hoop exact {sigma:.6e}, mean {mean_hoop:.6e}");
    assert!(
        (mean_hoop / sigma - 1.0).abs() < 0.01,
        "{mean_hoop} vs {sigma}"
    );
}

/// The follower pressure's tangent blocks ([`ForceModel::add_extra_tangent`]) plus the
/// membrane's element blocks are the derivative of the forces on a closed sphere, where the
/// pressure is conservative (`W = −p V`) and its stiffness symmetric, at a deformed state and
/// at a load factor and time that scale the pressure.
#[test]
fn pressure_tangent_is_the_force_derivative_on_a_closed_surface() {
    let mesh = uv_sphere(0.1, 5, 12);
    let mut lo = loaded_sphere(
        -2e3,
        &mesh,
        FemParams::new(Material::StVenantKirchhoff(StVenantKirchhoff::from_young(
            1e5, 0.3,
        ))),
    );
    let u = crate::fem::tests::random_u(mesh.num_nodes(), 2e-3, 11);
    lo.set_load_factor(0.7);
    let extra = crate::fem::tests::assert_tangent_matches_fd(&mut lo, &u, 1e-8, 1e-6, "pressure");
    assert!(extra > 0.0, "the pressure's blocks were added");
    // The pressure's share alone: its blocks are the Hessian of −p V, so with the membrane's
    // blocks left out the rest of the derivative must be the element part's.
    lo.set_load_factor(0.0);
    let none = crate::fem::tests::assert_tangent_matches_fd(&mut lo, &u, 1e-8, 1e-6, "no pressure");
    assert_eq!(none, 0.0, "a zero load factor adds no pressure block");
}
