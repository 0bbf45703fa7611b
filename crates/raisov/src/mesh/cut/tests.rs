use super::*;
use crate::mesh::generate::{box_tets, BoxPattern};
use crate::mesh::tet_volume;

/// Connected pieces of a mesh: elements joined through shared nodes; returns each element's
/// piece and the number of pieces.
fn pieces(m: &Mesh) -> (Vec<usize>, usize) {
    let ne = m.num_elements();
    let mut c = Classes((0..ne as u32).collect());
    let mut first = vec![u32::MAX; m.num_nodes()];
    for (e, el) in m.cells.chunks_exact(4).enumerate() {
        for &a in el {
            match first[a as usize] {
                u32::MAX => first[a as usize] = e as u32,
                f => c.join(f, e as u32),
            }
        }
    }
    let roots: Vec<u32> = (0..ne as u32).map(|e| c.find(e)).collect();
    let mut ids: Vec<u32> = roots.clone();
    ids.sort_unstable();
    ids.dedup();
    let piece = roots
        .iter()
        .map(|r| ids.binary_search(r).expect("root"))
        .collect();
    (piece, ids.len())
}

/// Σ_e f_e |T_e|: the material volume.
fn material_volume(c: &CutMesh) -> f64 {
    let m = c.mesh();
    m.cells
        .chunks_exact(4)
        .zip(c.fractions())
        .map(|(el, f)| {
            let p = |i: usize| m.nodes[el[i] as usize];
            f * tet_volume(p(0), p(1), p(2), p(3))
        })
        .sum()
}

fn block() -> CutMesh {
    CutMesh::new(box_tets([0.04, 0.02, 0.02], [8, 4, 4], BoxPattern::Six).unwrap()).unwrap()
}

/// A blade through the whole block's cross-section at x = `x`, tilted a little.
fn through(x: f64) -> Blade {
    Blade::quad([
        [x - 0.001, -0.01, -0.01],
        [x + 0.001, 0.03, -0.01],
        [x + 0.001, 0.03, 0.03],
        [x - 0.001, -0.01, 0.03],
    ])
    .unwrap()
}

#[test]
fn a_cut_through_the_block_leaves_two_pieces_of_the_same_total_volume() {
    let mut c = block();
    let v0 = material_volume(&c);
    let ch = c.cut(&through(0.0213)).unwrap();
    assert!(ch.split > 0);
    let (piece, n) = pieces(c.mesh());
    assert_eq!(n, 2, "one cut through the block leaves two pieces");
    let v1 = material_volume(&c);
    assert!((v1 - v0).abs() <= 1e-15 * v0, "volume {v0} → {v1}");
    // The pieces' volumes are those of the two sides of the (snapped) plane, within the snap.
    let mut vp = [0.0; 2];
    let m = c.mesh();
    for (e, el) in m.cells.chunks_exact(4).enumerate() {
        let p = |i: usize| m.nodes[el[i] as usize];
        vp[piece[e]] += c.fractions()[e] * tet_volume(p(0), p(1), p(2), p(3));
    }
    let left = vp[0].min(vp[1]);
    let exact = 0.0213 * 0.02 * 0.02;
    assert!(
        (left - exact).abs() < 0.005 * 0.02 * 0.02,
        "left piece {left} against {exact}"
    );
    // Each base element's copies have fractions summing to 1.
    let mut sum = vec![0.0; c.base().num_elements()];
    for (e, f) in c.fractions().iter().enumerate() {
        sum[c.base_elements()[e] as usize] += f;
    }
    assert!(sum.iter().all(|s| (s - 1.0).abs() < 1e-14));
    // No piece is smaller than the snap allows.
    let min = c.fractions().iter().fold(1.0f64, |a, &b| a.min(b));
    assert!(
        min >= (SNAP / (1.0 + SNAP)).powi(3) * 0.5,
        "smallest piece {min}"
    );
}

#[test]
fn a_notch_leaves_one_piece_with_its_lips_apart() {
    let mut c = block();
    // From above the top face (z = 0.02) down to half the depth, across the whole width.
    let notch = Blade::quad([
        [0.0205, -0.01, 0.0101],
        [0.0205, 0.03, 0.0101],
        [0.0205, 0.03, 0.03],
        [0.0205, -0.01, 0.03],
    ])
    .unwrap();
    let ch = c.cut(&notch).unwrap();
    assert!(ch.split > 0);
    assert_eq!(pieces(c.mesh()).1, 1, "a notch does not separate the block");
    // Top-face nodes at the cut are doubled; bottom-face nodes are not.
    let m = c.mesh();
    let count = |z: f64| {
        let mut per: std::collections::BTreeMap<u32, usize> = Default::default();
        for (a, &o) in c.base_nodes().iter().enumerate() {
            if (m.nodes[a][2] - z).abs() < 1e-9 {
                *per.entry(o).or_default() += 1;
            }
        }
        per.values().filter(|&&n| n > 1).count()
    };
    assert!(
        count(0.02) > 0,
        "the notch's lips have their own nodes on the top face"
    );
    assert_eq!(count(0.0), 0, "the bottom face is not cut");
}

#[test]
fn crossing_cuts_leave_four_pieces() {
    let mut c = block();
    c.cut(&through(0.0213)).unwrap();
    let across = Blade::quad([
        [-0.01, 0.0093, -0.01],
        [0.05, 0.0093, -0.01],
        [0.05, 0.0093, 0.03],
        [-0.01, 0.0093, 0.03],
    ])
    .unwrap();
    c.cut(&across).unwrap();
    assert_eq!(pieces(c.mesh()).1, 4);
    let v = material_volume(&c);
    assert!((v - 0.04 * 0.02 * 0.02).abs() < 1e-15);
}

#[test]
fn a_blade_that_misses_changes_nothing() {
    let mut c = block();
    let miss = Blade::swept([0.1, 0.0, 0.0], [0.1, 0.02, 0.0], [0.0, 0.0, 0.02]).unwrap();
    let ch = c.cut(&miss).unwrap();
    assert!(ch.is_identity());
    assert_eq!(c.mesh().num_nodes(), c.base().num_nodes());
    assert_eq!(
        c.blades().len(),
        1,
        "the cut is kept to keep the levels' indices aligned"
    );
}

#[test]
fn a_bad_blade_is_refused_with_what_would_be_valid() {
    let e = Blade::swept([0.0; 3], [0.0; 3], [0.0, 0.0, 1.0]).unwrap_err();
    assert!(e.to_string().contains("no area"), "{e}");
    let e = Blade::quad([[0.0; 3], [1.0, 0.0, 0.0], [1.0, 1.0, 0.5], [0.0, 1.0, 0.0]]).unwrap_err();
    assert!(e.to_string().contains("off the plane"), "{e}");
    let e = Blade::quad([[0.0; 3], [2.0, 0.0, 0.0], [0.5, 0.5, 0.0], [0.0, 2.0, 0.0]]).unwrap_err();
    assert!(e.to_string().contains("turns back"), "{e}");
}

#[test]
fn the_clipped_tetrahedron_volumes_add_up() {
    let t = Polytope::tet();
    assert!((t.fraction() - 1.0).abs() < 1e-15);
    let phi = [0.3, -0.2, 0.5, -0.7];
    let (a, cap) = t.clip(phi);
    let (b, _) = t.clip(phi.map(|v| -v));
    assert!((a.fraction() + b.fraction() - 1.0).abs() < 1e-14);
    assert_eq!(cap.len(), 4, "two nodes each side: a quad section");
    // One node alone: a corner tetrahedron of edge fractions t_j = φ0/(φ0 − φj).
    let phi = [0.1, -1.0, -2.0, -0.5];
    let (a, _) = t.clip(phi);
    let exact: f64 = phi[1..].iter().map(|&p| 0.1 / (0.1 - p)).product();
    assert!(
        (a.fraction() - exact).abs() < 1e-15,
        "{} vs {exact}",
        a.fraction()
    );
}

#[test]
fn a_cut_models_tangent_is_its_force_derivative() {
    use crate::fem::{FemModel, FemParams};
    use crate::material::{Material, NeoHookean, StableNeoHookean};
    let mut c =
        CutMesh::new(box_tets([0.02, 0.01, 0.01], [2, 1, 1], BoxPattern::Six).unwrap()).unwrap();
    let ch = c.cut(&through(0.0113)).unwrap();
    assert!(ch.split > 0);
    for m in [
        Material::NeoHookean(NeoHookean::from_young(1e6, 0.3)),
        Material::StableNeoHookean(StableNeoHookean::from_young(1e6, 0.3)),
    ] {
        let mut p = FemParams::new(m);
        p.fractions = Some(c.fractions().to_vec().into());
        let mut fem = FemModel::new(c.mesh(), p).unwrap();
        let n = c.mesh().num_nodes();
        let u: Vec<f64> = (0..3 * n)
            .map(|i| 1e-4 * ((i * 7 % 13) as f64 - 6.0))
            .collect();
        crate::fem::tests::assert_tangent_matches_fd(&mut fem, &u, 1e-7, 1e-5, "cut");
    }
}

/// The volume a triangle surface encloses (divergence theorem), at positions `x`.
fn enclosed(s: &EmbeddedSurface, x: &[[f64; 3]]) -> f64 {
    s.triangles
        .iter()
        .map(|t| dot(x[t[0] as usize], cross(x[t[1] as usize], x[t[2] as usize])) / 6.0)
        .sum()
}

#[test]
fn the_uncut_surface_is_the_meshs_boundary() {
    let c = block();
    let s = c.surface();
    assert!(s.points.is_empty());
    let canon = |t: &[u32; 3]| {
        let i = (0..3).min_by_key(|&i| t[i]).unwrap();
        [t[i], t[(i + 1) % 3], t[(i + 2) % 3]]
    };
    let mut a: Vec<_> = s.triangles.iter().map(canon).collect();
    let mut b: Vec<_> = c.mesh().surface_triangles().iter().map(canon).collect();
    a.sort_unstable();
    b.sort_unstable();
    assert_eq!(a, b);
}

#[test]
fn the_cut_surface_closes_around_the_material() {
    // A notch across a cut: the enclosed volume is the material's.
    let mut c = block();
    c.cut(&through(0.0213)).unwrap();
    c.cut(
        &Blade::quad([
            [-0.01, 0.0093, 0.0101],
            [0.05, 0.0093, 0.0101],
            [0.05, 0.0093, 0.03],
            [-0.01, 0.0093, 0.03],
        ])
        .unwrap(),
    )
    .unwrap();
    let s = c.surface();
    let mut x = Vec::new();
    s.positions(&c.mesh().nodes, &c.mesh().cells, &mut x);
    let v = enclosed(&s, &x);
    let exact = material_volume(&c);
    assert!(
        (v - exact).abs() < 1e-12 * exact,
        "encloses {v}, material {exact}"
    );
    // Two cuts through (a notch's tip leaves T-junctions where the wound ends at a whole
    // element's face): every piece closed.
    let mut c = block();
    c.cut(&through(0.0213)).unwrap();
    c.cut(
        &Blade::quad([
            [-0.01, 0.0093, -0.01],
            [0.05, 0.0093, -0.01],
            [0.05, 0.0093, 0.03],
            [-0.01, 0.0093, 0.03],
        ])
        .unwrap(),
    )
    .unwrap();
    let s = c.surface();
    assert!(!s.points.is_empty(), "the wound has vertices of its own");
    let mut x = Vec::new();
    s.positions(&c.mesh().nodes, &c.mesh().cells, &mut x);
    let v = enclosed(&s, &x);
    let exact = material_volume(&c);
    assert!(
        (v - exact).abs() < 1e-12 * exact,
        "encloses {v}, material {exact}"
    );
    // Each edge of the surface is shared by two triangles in opposite directions, once the
    // embedded points are merged by position.
    let key = |p: [f64; 3]| p.map(|v| (v * 1e9).round() as i64);
    let mut edges: std::collections::BTreeMap<([i64; 3], [i64; 3]), i32> = Default::default();
    for t in &s.triangles {
        for i in 0..3 {
            let (a, b) = (key(x[t[i] as usize]), key(x[t[(i + 1) % 3] as usize]));
            if a == b {
                continue;
            }
            let (k, d) = if a < b { ((a, b), 1) } else { ((b, a), -1) };
            *edges.entry(k).or_default() += d;
        }
    }
    let open = edges.values().filter(|&&v| v != 0).count();
    assert_eq!(open, 0, "{open} edges are not closed");
}

#[test]
fn a_cut_neo_hookean_model_keeps_its_whole_elements_packed_and_its_forces() {
    use crate::fem::{FemModel, FemParams, ForceModel};
    use crate::material::{Material, NeoHookean};
    let mut c = block();
    c.cut(&through(0.0213)).unwrap();
    let mut p = FemParams::new(Material::NeoHookean(NeoHookean::from_young(5e3, 0.45)));
    p.fractions = Some(c.fractions().to_vec().into());
    let mut fem = FemModel::new(c.mesh(), p).unwrap();
    assert!(
        fem.fast_path().is_some(),
        "the whole elements stay on the packed kernel"
    );
    let n = c.mesh().num_nodes();
    let u: Vec<f64> = (0..3 * n)
        .map(|i| 1e-4 * ((i * 7 % 13) as f64 - 6.0))
        .collect();
    let mut r = vec![0.0; 3 * n];
    fem.internal_forces(&u, &mut r).unwrap();
    // Against every element's own forces, summed.
    let mut sum = vec![0.0; 3 * n];
    for e in 0..c.mesh().num_elements() {
        let f = fem.element_forces_of(e, &u).unwrap();
        for (j, &a) in c.mesh().cells[4 * e..4 * e + 4].iter().enumerate() {
            for k in 0..3 {
                sum[3 * a as usize + k] += f[3 * j + k];
            }
        }
    }
    let scale = sum.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let diff = r
        .iter()
        .zip(&sum)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(
        diff <= 1e-12 * scale,
        "packed and partial forces {diff} off (scale {scale})"
    );
}

#[test]
fn the_cut_surfaces_boundary_is_the_cut_meshs_boundary() {
    let mut c = block();
    c.cut(&through(0.0213)).unwrap();
    let canon = |t: &[u32; 3]| {
        let i = (0..3).min_by_key(|&i| t[i]).unwrap();
        [t[i], t[(i + 1) % 3], t[(i + 2) % 3]]
    };
    let mut a: Vec<_> = c.surface().boundary.iter().map(canon).collect();
    let mut b: Vec<_> = c.mesh().surface_triangles().iter().map(canon).collect();
    a.sort_unstable();
    b.sort_unstable();
    assert_eq!(a, b);
}
