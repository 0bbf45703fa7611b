//! Tests of the packed path: the kernels against each other (the same bits on every ISA
//! and thread count) and against the reference path, f32 storage within its stated
//! tolerance, the layout rules, the row prefetch schedule and the kernels' logarithm.

use super::layout::{self, BLK};
use super::platform::Isa;
use super::{ln, Precision, Row4, LANES};
use crate::fem::tests::{jittered_box, random_u};
use crate::fem::{FemModel, FemParams, ForceModel};
use crate::material::{Material, NeoHookean};
use crate::mesh::Mesh;

/// The packed neo-Hookean path on a larger box with several slabs and colours, in both
/// storage precisions: AVX2 and portable kernels give the same bits, 1 and 2 threads agree;
/// f64 storage equals the reference within rounding, f32 storage is within the tolerance of
/// `f32_storage_forces_within_stated_tolerance` of f64; the series logarithm is accurate.
#[test]
fn packed_kernel_paths_agree() {
    use crate::mesh::generate::{box_tets, BoxPattern};
    let mesh = box_tets([0.1, 0.04, 0.04], [20, 8, 8], BoxPattern::Five).unwrap();
    let n = mesh.num_nodes();
    let u = random_u(n, 0.2 * mesh.edge_range().0, 5);
    let mut r_ref = vec![0.0; 3 * n];
    let mut r_f64 = Vec::new();
    for precision in Precision::ALL {
        let mut p = FemParams::new(Material::NeoHookean(NeoHookean::from_young(5e4, 0.4)));
        p.slab = 128;
        p.precision = precision;
        let mut model = FemModel::new(&mesh, p).unwrap();
        assert_eq!(model.fast_precision(), Some(precision));
        let (slabs, colours, bytes) = model.fast_path().unwrap();
        assert!(
            slabs >= 4 && colours >= 2,
            "{slabs} slabs, {colours} colours"
        );
        assert!(bytes >= precision.bytes_per_tet() * model.num_elements());
        if precision == Precision::F64 {
            model.internal_forces_reference(&u, &mut r_ref).unwrap();
        }
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
        for isa in [Isa::Avx2, Isa::Portable] {
            // Widest detected first (runs[0..2]), then AVX2, then portable.
            model.pack.as_mut().unwrap().force_isa(isa);
            let mut r = vec![0.0; 3 * n];
            model.internal_forces(&u, &mut r).unwrap();
            runs.push(r);
        }
        // The row prefetch schedule (off on a mesh this small) changes no bit.
        model.pack.as_mut().unwrap().force_isa(Isa::Avx512);
        model.pack.as_mut().unwrap().set_row_prefetch(2);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let mut r = vec![0.0; 3 * n];
        pool.install(|| model.internal_forces(&u, &mut r)).unwrap();
        let name = precision.name();
        assert_eq!(runs[0], r, "{name}: the row prefetch changed the forces");
        assert_eq!(runs[0], runs[1], "{name}: 1 and 2 threads differ");
        assert_eq!(runs[0], runs[2], "{name}: widest and AVX2 kernels differ");
        assert_eq!(runs[0], runs[3], "{name}: SIMD and portable kernels differ");
        let scale = r_ref.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
        let tol = match precision {
            Precision::F64 => 1e-12,
            Precision::F32Storage => F32_STORAGE_TOL,
        };
        for (a, b) in runs[0].iter().zip(&r_ref) {
            assert!((a - b).abs() <= tol * scale, "{name}: {a} vs {b}");
        }
        match precision {
            Precision::F64 => r_f64 = runs.swap_remove(0),
            Precision::F32Storage => assert_ne!(runs[0], r_f64, "f32 storage changed nothing"),
        }
    }
    for x in [
        1e-3, 0.3, 0.7072, 1.4141, 1.4143, 0.9999999, 1.0, 1.0000001, 1.5, 2.0, 7.3, 1e5,
    ] {
        let (a, b) = (ln::ln_series(x), x.ln());
        assert!(
            (a - b).abs() <= 4e-16 * b.abs().max(1e-300) + 1e-300,
            "ln {x}: {a} vs {b}"
        );
    }
}

/// The row prefetch schedule lists every 64-byte row line a slab touches exactly once, at
/// `dist` blocks before the block that first touches it in the slab (block 0 at the
/// latest), and nothing with `dist = 0`.
#[test]
fn row_prefetch_schedule_covers_each_line_once_ahead_of_use() {
    use layout::row_prefetch_schedule;
    // 3 slabs of 10, 7 and 1 groups over 40 nodes; offsets 4 × node id.
    let slab_ptr = [0usize, 10, 17, 18];
    let idx = |g: usize| -> [[u32; LANES]; 4] {
        std::array::from_fn(|k| std::array::from_fn(|l| 4 * ((7 * g + 3 * k + 11 * l) % 40) as u32))
    };
    let dist = 2;
    let layout::RowPrefetch {
        block_base: base,
        rows_pf_ptr: ptr,
        rows_pf: lines,
    } = row_prefetch_schedule(idx, &slab_ptr, 40, dist);
    assert_eq!(base, vec![0, 3, 5, 6]);
    for s in 0..3 {
        let (g0, g1) = (slab_ptr[s], slab_ptr[s + 1]);
        let mut first = std::collections::BTreeMap::new();
        for g in g0..g1 {
            for corner in idx(g) {
                for o in corner {
                    first.entry(o / 8).or_insert((g - g0) / BLK);
                }
            }
        }
        let mut listed = std::collections::BTreeMap::new();
        for b in base[s]..base[s + 1] {
            for &line in &lines[ptr[b] as usize..ptr[b + 1] as usize] {
                assert!(
                    listed.insert(line, b - base[s]).is_none(),
                    "line {line} twice"
                );
            }
        }
        let want: std::collections::BTreeMap<u32, usize> = first
            .into_iter()
            .map(|(line, b)| (line, b.saturating_sub(dist)))
            .collect();
        assert_eq!(listed, want, "slab {s}");
    }
    let layout::RowPrefetch {
        rows_pf_ptr: ptr,
        rows_pf: lines,
        ..
    } = row_prefetch_schedule(idx, &slab_ptr, 40, 0);
    assert!(lines.is_empty() && ptr.iter().all(|&p| p == 0));
}

/// The stated tolerance of f32 storage against f64 (see the module docs of [`super`]): relative in the 2-norm of
/// the force vector, and per entry relative to the largest entry.
pub(crate) const F32_STORAGE_TOL: f64 = 1e-6;

/// f32 storage of `Dm⁻¹` and volumes against f64 storage on a jittered (irregular) mesh,
/// at small, moderate and large random deformations and an affine stretch: the force
/// vectors agree within [`F32_STORAGE_TOL`] in the relative 2-norm and per entry (relative to
/// the largest entry). Rounding one `Dm⁻¹` entry to f32 is a relative error ≤ 2⁻²⁴ ≈ 6e-8.
#[test]
fn f32_storage_forces_within_stated_tolerance() {
    let mesh = jittered_box(8, 0.4);
    let n = mesh.num_nodes();
    let h0 = mesh.edge_range().0;
    let model = |precision| {
        let mut p = FemParams::new(Material::NeoHookean(NeoHookean::from_young(5e4, 0.4)));
        p.slab = 64;
        p.precision = precision;
        FemModel::new(&mesh, p).unwrap()
    };
    let (mut m64, mut m32) = (model(Precision::F64), model(Precision::F32Storage));
    let mut stretch = vec![0.0; 3 * n];
    for a in 0..n {
        let x = mesh.nodes[a];
        stretch[3 * a] = 0.3 * x[0] + 0.05 * x[1];
        stretch[3 * a + 1] = -0.1 * x[1];
        stretch[3 * a + 2] = 0.02 * x[0] - 0.1 * x[2];
    }
    let cases = [
        ("small", random_u(n, 0.01 * h0, 21)),
        ("moderate", random_u(n, 0.1 * h0, 22)),
        ("large", random_u(n, 0.3 * h0, 23)),
        ("affine", stretch),
    ];
    for (name, u) in cases {
        let (mut a, mut b) = (vec![0.0; 3 * n], vec![0.0; 3 * n]);
        m64.internal_forces(&u, &mut a).unwrap();
        m32.internal_forces(&u, &mut b).unwrap();
        let norm = |v: &mut dyn Iterator<Item = f64>| v.map(|x| x * x).sum::<f64>().sqrt();
        let rel2 = norm(&mut a.iter().zip(&b).map(|(x, y)| x - y)) / norm(&mut a.iter().copied());
        let amax = a.iter().fold(0.0f64, |m, &x| m.max(x.abs()));
        let relmax = a
            .iter()
            .zip(&b)
            .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
            / amax;
        eprintln!("f32 storage, {name}: relative 2-norm {rel2:.2e}, max entry {relmax:.2e}");
        assert!(rel2 > 0.0, "{name}: f32 storage changed nothing");
        assert!(
            rel2 <= F32_STORAGE_TOL && relmax <= F32_STORAGE_TOL,
            "{name}: f32 storage off by {rel2:.2e} (2-norm), {relmax:.2e} (max entry)"
        );
    }
}

/// A failure in the packed path reports the original (unsorted) id of the lowest failing
/// element.
#[test]
fn packed_failure_reports_original_element() {
    use crate::mesh::generate::{box_tets, BoxPattern};
    let mesh = box_tets([0.1, 0.04, 0.04], [10, 4, 4], BoxPattern::Five).unwrap();
    for precision in Precision::ALL {
        let mut p = FemParams::new(Material::NeoHookean(NeoHookean::from_young(5e4, 0.4)));
        p.slab = 32;
        p.precision = precision;
        let model = FemModel::new(&mesh, p).unwrap();
        check_failure_report(&mesh, model);
    }
}

fn check_failure_report(mesh: &Mesh, mut model: FemModel) {
    let n = mesh.num_nodes();
    // Push one node of element 37 through its opposite face.
    let target = 37;
    let el = mesh.element(target).to_vec();
    let mut u = vec![0.0; 3 * n];
    let pts = mesh.element_points(target);
    let c: Vec<f64> = (0..3)
        .map(|d| (pts[1][d] + pts[2][d] + pts[3][d]) / 3.0)
        .collect();
    for d in 0..3 {
        u[3 * el[0] as usize + d] = 2.0 * (c[d] - pts[0][d]);
    }
    let mut r_ref = vec![0.0; 3 * n];
    let want = model.internal_forces_reference(&u, &mut r_ref).unwrap_err();
    let mut r = vec![0.0; 3 * n];
    let got = model.internal_forces(&u, &mut r).unwrap_err();
    assert_eq!(got.element, want.element);
    assert!(got.det_f < 0.0);
}

/// The slab rule: serial below two slabs' worth, else a multiple of 4 (an even number of
/// slabs in each of the 2 colours) within what the band allows; on the standard 10k box the
/// default parameters give 4 slabs in 2 colours, 2 of them per colour.
#[test]
fn slabs_come_in_fours_so_each_colour_splits_evenly() {
    use layout::slab_count;
    assert_eq!(slab_count(1, 36), 1);
    assert_eq!(slab_count(0, 36), 1);
    assert_eq!(slab_count(2, 36), 4);
    assert_eq!(slab_count(3, 36), 4);
    assert_eq!(slab_count(9, 36), 12);
    assert_eq!(slab_count(298, 36), 36);
    assert_eq!(slab_count(298, 18), 16);
    assert_eq!(slab_count(5, 3), 3);
    assert_eq!(slab_count(5, 1), 1);
    let mesh = crate::mesh::generate::box_tets_target(
        [0.1, 0.04, 0.04],
        10_000,
        crate::mesh::generate::BoxPattern::Five,
    )
    .unwrap();
    let p = FemParams::new(Material::NeoHookean(NeoHookean::from_young(5e4, 0.4)));
    let model = FemModel::new(&mesh, p).unwrap();
    let (slabs, colours, _) = model.fast_path().unwrap();
    assert_eq!((slabs, colours), (4, 2));
}

/// The strip axis of the packed path is the axis along which node ids grow at the middle
/// rate: `y` for the generator's numbering (x fastest, z slowest), and it follows the
/// numbering when the nodes are renumbered with another axis order.
#[test]
fn strips_run_across_the_axis_of_middle_id_growth() {
    use crate::mesh::generate::{box_tets, BoxPattern};
    use layout::strip_axis;
    let mesh = box_tets([0.1, 0.04, 0.04], [10, 4, 4], BoxPattern::Five).unwrap();
    let model = |m: &Mesh| {
        let p = FemParams::new(Material::NeoHookean(NeoHookean::from_young(5e4, 0.4)));
        FemModel::new(m, p).unwrap()
    };
    let axis = |m: &Mesh| {
        let fm = model(m);
        let mut ext = [0.0; 3];
        for el in m.cells.chunks_exact(4) {
            for (d, e) in ext.iter_mut().enumerate() {
                let xs = el.iter().map(|&c| m.nodes[c as usize][d]);
                let (lo, hi) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
                    (a.min(x), b.max(x))
                });
                *e += hi - lo;
            }
        }
        strip_axis(&m.cells, fm.dminv_column_major(), &ext, m.num_elements())
    };
    assert_eq!(axis(&mesh), Some(1));
    // Renumber with y fastest, then z, then x slowest: the middle rate is now z's.
    let n = mesh.num_nodes();
    let mut order: Vec<u32> = (0..n as u32).collect();
    order.sort_by(|&a, &b| {
        let (p, q) = (mesh.nodes[a as usize], mesh.nodes[b as usize]);
        (p[0], p[2], p[1]).partial_cmp(&(q[0], q[2], q[1])).unwrap()
    });
    let mut new_of = vec![0u32; n];
    for (k, &o) in order.iter().enumerate() {
        new_of[o as usize] = k as u32;
    }
    let mut other = mesh.clone();
    other.nodes = order.iter().map(|&o| mesh.nodes[o as usize]).collect();
    other.cells = mesh.cells.iter().map(|&c| new_of[c as usize]).collect();
    assert_eq!(axis(&other), Some(2));
    assert_eq!(strip_axis(&[], &[], &[1.0; 3], 0), None);
}

/// `ln J` as the kernels take it ([`ln::ln_j`]) is within 2 ulp of `f64::ln` on a sweep
/// across `|J − 1| <` [`ln::LN_NEAR`] (the `ln(1 + f)` series), at and around the
/// threshold, and beyond (the general series).
#[test]
fn kernel_log_is_within_two_ulp_near_and_far_from_one() {
    let mut worst = 0.0f64;
    let mut check = |x: f64| {
        let (a, b) = (ln::ln_j(x), x.ln());
        let ulp = (b.abs() * f64::EPSILON).max(f64::MIN_POSITIVE);
        let e = (a - b).abs() / ulp;
        worst = worst.max(e);
        assert!(e <= 2.0, "ln {x}: {a} vs {b} ({e} ulp)");
    };
    let d = ln::LN_NEAR;
    for k in 1..=20_000 {
        let f = d * (k as f64 / 20_000.0);
        for x in [1.0 + f, 1.0 - f, 1.0 + f * 1e-6, 1.0 - f * 1e-9] {
            check(x);
        }
    }
    for x in [
        1.0 + d,
        1.0 - d,
        f64::from_bits((1.0 + d).to_bits() - 1),
        0.5,
        0.9,
        1.2,
        3.0,
    ] {
        check(x);
    }
    assert!(worst > 0.0, "the sweep compared nothing");
}

/// The AVX-512 kernel runs two groups as 8 lanes and a block's odd last group through the
/// AVX2 kernel: on every group count from 1 to 4 blocks and a half, it gives the AVX2
/// kernel's bits (the same scatter order), and both the portable kernel's. On a CPU without
/// AVX-512 this compares AVX2 with itself.
#[test]
fn avx512_kernel_equals_avx2_on_every_group_count() {
    use crate::mesh::generate::{box_tets, BoxPattern};
    let mesh = box_tets([0.1, 0.04, 0.04], [20, 8, 8], BoxPattern::Five).unwrap();
    let n = mesh.num_nodes();
    let u = random_u(n, 0.2 * mesh.edge_range().0, 11);
    let mut p = FemParams::new(Material::NeoHookean(NeoHookean::from_young(5e4, 0.4)));
    p.slab = 4096;
    let model = FemModel::new(&mesh, p).unwrap();
    let pack = model.pack.as_ref().unwrap();
    let q: Vec<Row4> = (0..n)
        .map(|a| {
            let x = mesh.nodes[a];
            Row4([
                x[0] + u[3 * a],
                x[1] + u[3 * a + 1],
                x[2] + u[3 * a + 2],
                0.0,
            ])
        })
        .collect();
    let blk = BLK;
    let mut compared = 0;
    for groups in 1..=4 * blk + blk / 2 + 1 {
        let mut runs = Vec::new();
        for isa in [Isa::Avx512, Isa::Avx2, Isa::Portable] {
            let mut r = vec![Row4([0.0; 4]); n];
            assert!(
                pack.run_first_groups(groups, isa, &q, &mut r),
                "{groups} groups"
            );
            runs.push(r);
        }
        assert!(
            runs[0].iter().any(|r| r.0 != [0.0; 4]),
            "{groups} groups: no force"
        );
        for (k, name) in [(1, "AVX2"), (2, "portable")] {
            for (a, (x, y)) in runs[0].iter().zip(&runs[k]).enumerate() {
                assert_eq!(
                    x.0, y.0,
                    "{groups} groups, node {a}: widest and {name} differ"
                );
            }
        }
        compared += 1;
    }
    assert_eq!(compared, 4 * blk + blk / 2 + 1);
}

/// With every element's `|J − 1|` below [`ln::LN_NEAR`] the AVX2 kernel skips the general
/// logarithm for whole groups; it still gives the bits of the portable kernel, and the
/// forces of the reference path within rounding.
#[test]
fn near_unit_volume_change_takes_the_series_in_both_kernels() {
    use crate::mesh::generate::{box_tets, BoxPattern};
    let mesh = box_tets([0.1, 0.04, 0.04], [20, 8, 8], BoxPattern::Five).unwrap();
    let n = mesh.num_nodes();
    let u = random_u(n, 1e-3 * mesh.edge_range().0, 9);
    let mut p = FemParams::new(Material::NeoHookean(NeoHookean::from_young(5e4, 0.4)));
    p.slab = 128;
    let mut model = FemModel::new(&mesh, p).unwrap();
    let mut r_ref = vec![0.0; 3 * n];
    model.internal_forces_reference(&u, &mut r_ref).unwrap();
    let mut runs = Vec::new();
    for isa in [Isa::Avx512, Isa::Avx2, Isa::Portable] {
        model.pack.as_mut().unwrap().force_isa(isa);
        let mut r = vec![0.0; 3 * n];
        model.internal_forces(&u, &mut r).unwrap();
        runs.push(r);
    }
    assert_eq!(runs[0], runs[1], "AVX-512 and AVX2 kernels differ");
    assert_eq!(runs[0], runs[2], "SIMD and portable kernels differ");
    let scale = r_ref.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
    assert!(scale > 0.0);
    for (a, b) in runs[0].iter().zip(&r_ref) {
        assert!((a - b).abs() <= 1e-9 * scale, "{a} vs {b}");
    }
}
