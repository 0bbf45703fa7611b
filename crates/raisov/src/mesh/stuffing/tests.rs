//! Tests of the mesher on surfaces built here (sphere, torus, cube) with analytic volumes.

use super::*;
use crate::geometry::{norm, sub};
use crate::mesh::Surface;
use std::collections::HashMap as Map;

/// Icosphere of radius `r` centred at `c`: the icosahedron subdivided `k` times, vertices
/// pushed onto the sphere; outward triangles.
pub(crate) fn icosphere(r: f64, c: [f64; 3], k: usize) -> Surface {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut pts: Vec<[f64; 3]> = vec![
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
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
    for _ in 0..k {
        let mut mid: Map<(u32, u32), u32> = Map::new();
        let mut next = Vec::new();
        for tr in &tris {
            let mut m = [0u32; 3];
            for e in 0..3 {
                let (a, b) = (tr[e], tr[(e + 1) % 3]);
                let key = (a.min(b), a.max(b));
                m[e] = *mid.entry(key).or_insert_with(|| {
                    let (p, q) = (pts[a as usize], pts[b as usize]);
                    pts.push([0, 1, 2].map(|d| 0.5 * (p[d] + q[d])));
                    pts.len() as u32 - 1
                });
            }
            next.push([tr[0], m[0], m[2]]);
            next.push([tr[1], m[1], m[0]]);
            next.push([tr[2], m[2], m[1]]);
            next.push([m[0], m[1], m[2]]);
        }
        tris = next;
    }
    for p in &mut pts {
        let l = norm(*p);
        *p = [0, 1, 2].map(|d| c[d] + r * p[d] / l);
    }
    Surface {
        points: pts,
        triangles: tris,
    }
}

/// Torus of radii `big` (centre line) and `small` (tube) around the z axis, `nu × nv`
/// quadrilaterals split into outward triangles.
pub(crate) fn torus(big: f64, small: f64, nu: usize, nv: usize) -> Surface {
    let mut points = Vec::new();
    for i in 0..nu {
        let u = 2.0 * std::f64::consts::PI * i as f64 / nu as f64;
        for j in 0..nv {
            let v = 2.0 * std::f64::consts::PI * j as f64 / nv as f64;
            let rr = big + small * v.cos();
            points.push([rr * u.cos(), rr * u.sin(), small * v.sin()]);
        }
    }
    let id = |i: usize, j: usize| ((i % nu) * nv + (j % nv)) as u32;
    let mut triangles = Vec::new();
    for i in 0..nu {
        for j in 0..nv {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    Surface { points, triangles }
}

/// Axis-aligned box `[0, s]³`, each face split into `k × k` squares of two triangles.
pub(crate) fn cube(s: f64, k: usize) -> Surface {
    let mut points: Vec<[f64; 3]> = Vec::new();
    let mut index: Map<[i64; 3], u32> = Map::new();
    let mut triangles = Vec::new();
    let mut vid = |g: [i64; 3], points: &mut Vec<[f64; 3]>| -> u32 {
        *index.entry(g).or_insert_with(|| {
            points.push(g.map(|x| s * x as f64 / k as f64));
            points.len() as u32 - 1
        })
    };
    let k = k as i64;
    // For each axis and side, a grid on the face with outward orientation.
    for axis in 0..3 {
        for side in [0, k] {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            for a in 0..k {
                for b in 0..k {
                    let g = |da: i64, db: i64| {
                        let mut p = [0i64; 3];
                        p[axis] = side;
                        p[u] = a + da;
                        p[v] = b + db;
                        p
                    };
                    let q = [g(0, 0), g(1, 0), g(1, 1), g(0, 1)].map(|p| vid(p, &mut points));
                    // (u, v, axis) is right-handed: counter-clockwise in (u, v) faces +axis.
                    if side == k {
                        triangles.push([q[0], q[1], q[2]]);
                        triangles.push([q[0], q[2], q[3]]);
                    } else {
                        triangles.push([q[0], q[2], q[1]]);
                        triangles.push([q[0], q[3], q[2]]);
                    }
                }
            }
        }
    }
    Surface { points, triangles }
}

/// Every tetrahedron positive with dihedral angles in the guaranteed range; returns the
/// range seen.
fn assert_quality(m: &Mesh, what: &str) -> (f64, f64) {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for e in 0..m.num_elements() {
        let p = m.element_points(e);
        assert!(m.element_measure(e) > 0.0, "{what}: tet {e} not positive");
        let (a, b) = tet_dihedral_range(p[0], p[1], p[2], p[3]);
        lo = lo.min(a);
        hi = hi.max(b);
    }
    assert!(
        lo >= DIHEDRAL_BOUNDS.0 && hi <= DIHEDRAL_BOUNDS.1,
        "{what}: dihedral angles {lo:.3}..{hi:.3} outside [{}, {}]",
        DIHEDRAL_BOUNDS.0,
        DIHEDRAL_BOUNDS.1
    );
    (lo, hi)
}

/// Every node used, the boundary group is the boundary.
fn assert_clean(m: &Mesh) {
    assert!(m.used_nodes().iter().all(|&u| u));
    assert_eq!(m.groups["boundary"], m.boundary_nodes());
    assert!(m.degenerate_elements().is_empty());
}

#[test]
fn regular_tet_has_sixty_degree_dihedrals_and_bcc_tet_sixty_and_ninety() {
    let s = 1.0 / 2f64.sqrt();
    let (lo, hi) = tet_dihedral_range(
        [1.0, 0.0, -s],
        [-1.0, 0.0, -s],
        [0.0, 1.0, s],
        [0.0, -1.0, s],
    );
    assert!((lo - 70.528_779_365_509_3).abs() < 1e-9 && (hi - lo).abs() < 1e-9);
    // BCC tet: long edges (0,0,0)-(1,0,0) and (.5,.5,-.5)... as built by the lattice.
    let (lo, hi) = tet_dihedral_range(
        [0.5, 0.5, 0.5],
        [1.5, 0.5, 0.5],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
    );
    assert!(
        (lo - 60.0).abs() < 1e-9 && (hi - 90.0).abs() < 1e-9,
        "{lo} {hi}"
    );
}

/// Sphere of radius 1 at h = 0.2: positive tets, angles in the guarantee, boundary nodes on
/// the faceted sphere (distance ≤ 1e-12) and within the facets' chord error of the analytic
/// sphere, volume within 1.5 % of 4π/3.
#[test]
fn sphere_is_stuffed_with_guaranteed_angles() {
    let s = icosphere(1.0, [0.1, -0.2, 0.3], 4);
    let st = Stuffer::new(&s).unwrap();
    let (m, stats) = st.mesh(0.2).unwrap();
    assert_clean(&m);
    let (lo, hi) = assert_quality(&m, "sphere");
    assert_eq!(stats.cut_fallbacks, 0);
    let vol = m.total_measure();
    let exact = 4.0 / 3.0 * std::f64::consts::PI;
    let rel = vol / exact - 1.0;
    assert!(
        rel.abs() < 0.015,
        "volume {vol} against {exact} ({rel:+.4})"
    );
    for &b in &m.groups["boundary"] {
        let p = m.nodes[b as usize];
        assert!(st.distance(p) < 1e-12);
        let r = norm(sub(p, [0.1, -0.2, 0.3]));
        assert!((r - 1.0).abs() < 3e-3, "boundary node at radius {r}");
    }
    eprintln!(
        "sphere h=0.2: {} nodes {} tets dihedral {lo:.2}..{hi:.2} volume error {:+.3} % warped {}",
        m.num_nodes(),
        m.num_elements(),
        100.0 * rel,
        stats.warped
    );
}

/// Torus R = 1, r = 0.35 (a hole: not simply connected): volume 2π²Rr² within 3 %,
/// boundary within the chord error of the analytic torus, angles in the guarantee.
#[test]
fn torus_is_stuffed_with_guaranteed_angles() {
    let (big, small) = (1.0, 0.35);
    let s = torus(big, small, 96, 48);
    let st = Stuffer::new(&s).unwrap();
    let (m, _) = st.mesh(0.09).unwrap();
    assert_clean(&m);
    assert_quality(&m, "torus");
    let exact = 2.0 * std::f64::consts::PI.powi(2) * big * small * small;
    let rel = m.total_measure() / exact - 1.0;
    assert!(rel.abs() < 0.03, "torus volume error {rel:+.4}");
    for &b in &m.groups["boundary"] {
        let p = m.nodes[b as usize];
        let rho = (p[0] * p[0] + p[1] * p[1]).sqrt();
        let d = ((rho - big).powi(2) + p[2] * p[2]).sqrt() - small;
        assert!(d.abs() < 3e-3, "boundary node {d} off the torus");
    }
    // The hole stays open: the axis of the torus is outside the mesh.
    assert!(!st.inside([0.0, 0.0, 0.0]));
    eprintln!(
        "torus: {} nodes, volume error {:+.3} %",
        m.num_nodes(),
        100.0 * rel
    );
}

/// A cube of side 1 on round coordinates (rows of the lattice meet its edges only by the
/// offset): the quality guarantee holds at the sharp edges too; the volume is a little
/// short (edges and corners are cut), under 5 % at h = 0.1.
#[test]
fn cube_edges_are_rounded_but_angles_guaranteed() {
    let s = cube(1.0, 4);
    let st = Stuffer::new(&s).unwrap();
    for h in [0.1, 0.137] {
        let (m, _) = st.mesh(h).unwrap();
        assert_clean(&m);
        assert_quality(&m, "cube");
        let rel = m.total_measure() - 1.0;
        eprintln!(
            "cube h={h}: {} nodes, volume error {:+.3} %",
            m.num_nodes(),
            100.0 * rel
        );
        assert!(rel < 1e-12 && rel > -0.05, "cube volume error {rel}");
    }
}

/// Many placements of the lattice against spheres of several radii (every stencil case and
/// warp configuration occurs many times): the angles stay in the guaranteed range.
#[test]
fn guarantee_holds_over_many_lattice_placements() {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    let mut tets = 0;
    let mut st_k = 0u64;
    for k in 0..24 {
        // Quasi-random centres and radii.
        let f = |i: u64| (i as f64 * 0.618_033_988_749_895).fract();
        st_k += 3;
        let c = [f(st_k), f(st_k + 1), f(st_k + 2)].map(|x| 0.3 * x);
        let r = 0.5 + 0.45 * f(k as u64 * 7 + 1);
        let s = icosphere(r, c, 3);
        let st = Stuffer::new(&s).unwrap();
        let (m, _) = st.mesh(0.23 + 0.01 * f(k as u64 * 5 + 2)).unwrap();
        for e in 0..m.num_elements() {
            let p = m.element_points(e);
            assert!(m.element_measure(e) > 0.0);
            let (a, b) = tet_dihedral_range(p[0], p[1], p[2], p[3]);
            lo = lo.min(a);
            hi = hi.max(b);
        }
        tets += m.num_elements();
    }
    eprintln!("{tets} tets: dihedral {lo:.3}..{hi:.3}");
    assert!(
        lo >= DIHEDRAL_BOUNDS.0 && hi <= DIHEDRAL_BOUNDS.1,
        "{lo} {hi}"
    );
}

/// The same bits on 1 and 2 threads: nodes, cells, groups.
#[test]
fn same_bits_on_one_and_two_threads() {
    let s = torus(1.0, 0.4, 64, 32);
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| mesh_levels(&s, 3, 0.5, LevelTarget::Nodes(3000)).unwrap())
    };
    let (a, b) = (run(1), run(2));
    assert_eq!(a.len(), 3);
    for (x, y) in a.iter().zip(&b) {
        let bits = |m: &Mesh| {
            m.nodes
                .iter()
                .flat_map(|p| p.map(f64::to_bits))
                .collect::<Vec<_>>()
        };
        assert_eq!(bits(x), bits(y));
        assert_eq!(x.cells, y.cells);
        assert_eq!(x.groups, y.groups);
    }
}

/// Four levels of a sphere from 4000 nodes: node ratio 0.5 ± 0.05 per link, every level
/// in the quality guarantee, clean, volume error shrinking towards the fine level and under
/// 3 % on level 0, the report consistent with the meshes.
#[test]
fn sphere_levels_halve_the_node_count_with_guaranteed_quality() {
    let s = icosphere(0.05, [0.01, 0.0, -0.02], 4);
    let (meshes, rep) =
        mesh_levels_report(&s, 4, 0.5, LevelTarget::Nodes(4000), &mut |_| {}).unwrap();
    assert_eq!(meshes.len(), 4);
    assert_eq!(crate::hierarchy::link_reports(&meshes).unwrap().len(), 3);
    for (i, m) in meshes.iter().enumerate() {
        assert_clean(m);
        assert_quality(m, &format!("sphere level {i}"));
        let r = &rep.levels[i];
        assert_eq!(r.nodes, m.num_nodes());
        assert!(r.quality_ok());
        assert!(r.max_boundary_distance < 1e-12 * 0.05 + 1e-15);
        assert!(r.max_surface_distance < 0.5 * r.mean_edge, "{r:?}");
        if i > 0 {
            let ratio = m.num_nodes() as f64 / meshes[i - 1].num_nodes() as f64;
            assert!((ratio - 0.5).abs() <= 0.05, "level {i}: ratio {ratio}");
            assert!(r.volume_error.abs() >= rep.levels[i - 1].volume_error.abs() * 0.8);
        }
    }
    assert!((meshes[0].num_nodes() as f64 / 4000.0 - 1.0).abs() <= 0.02);
    assert!(rep.levels[0].volume_error.abs() < 0.03);
    eprintln!("{rep}");
}

/// `Size`: level 0 at the given spacing; the coarser levels follow its node count.
#[test]
fn size_target_fixes_level_zero_spacing() {
    let s = icosphere(1.0, [0.0; 3], 3);
    let (m, rep) = mesh_levels_report(&s, 2, 0.5, LevelTarget::Size(0.25), &mut |_| {}).unwrap();
    assert_eq!(rep.levels[0].h, 0.25);
    let ratio = m[1].num_nodes() as f64 / m[0].num_nodes() as f64;
    assert!((ratio - 0.5).abs() <= 0.05, "{ratio}");
    assert!(mesh_levels(&s, 0, 0.5, LevelTarget::Nodes(100)).is_err());
    assert!(mesh_levels(&s, 2, 1.5, LevelTarget::Nodes(100)).is_err());
    assert!(mesh_levels(&s, 2, 0.5, LevelTarget::Size(-1.0)).is_err());
    assert!(Stuffer::new(&Surface::default()).is_err());
}

/// A node target far beyond what a lattice can hold is refused by the lattice's limit, named
/// as such: the spacing search used to take that refusal for an empty inside, halve the
/// spacing to the end of its budget and report "no spacing down to ... leaves a tetrahedron
/// inside the surface".
#[test]
fn mesher_node_target_beyond_the_lattice_names_the_lattice_limit() {
    let s = icosphere(1.0, [0.0; 3], 2);
    let e = mesh_levels(&s, 1, 0.5, LevelTarget::Nodes(100_000_000_000)).unwrap_err();
    let msg = e.to_string();
    assert!(msg.contains("lattice vertices"), "{msg}");
    assert!(msg.contains("fewer nodes"), "{msg}");
    assert!(!msg.contains("no spacing"), "{msg}");
    // A spacing too coarse for any tetrahedron still says so.
    let e = Stuffer::new(&s).unwrap().mesh(10.0).unwrap_err();
    assert!(e.to_string().contains("no tetrahedron inside"), "{e}");
}

/// The liver surface of `data/` (millimetres), read by `io::load_surface` and scaled to
/// metres: two small levels, angles in the guarantee, node ratio 0.5 ± 0.05, volume within
/// 2 % of the enclosed volume, every boundary node on the surface.
#[test]
fn liver_surface_levels_are_guaranteed() {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data/liver_surface.obj");
    let mut s = crate::io::load_surface(&path).unwrap();
    s.scale(1e-3);
    let (m, rep) = mesh_levels_report(&s, 2, 0.5, LevelTarget::Nodes(4000), &mut |_| {}).unwrap();
    for (i, mesh) in m.iter().enumerate() {
        assert_clean(mesh);
        assert_quality(mesh, &format!("liver level {i}"));
        assert!(rep.levels[i].max_boundary_distance < 1e-12);
    }
    let ratio = m[1].num_nodes() as f64 / m[0].num_nodes() as f64;
    assert!((ratio - 0.5).abs() <= 0.05, "{ratio}");
    assert!(
        rep.levels[0].volume_error.abs() < 0.02,
        "{:?}",
        rep.levels[0]
    );
}
