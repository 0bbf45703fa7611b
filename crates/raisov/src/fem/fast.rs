//! Fast path of the force pass: compressible neo-Hookean tetrahedra.
//!
//! `P = μ (F − F⁻ᵀ) + λ ln J F⁻ᵀ`, the corner forces `R_j = V0 P Dm⁻ᵀ e_j` (j = 1..3),
//! `R_0 = −Σ R_j`: the same `R = ∂E/∂u` as the generic `P = F S(C)` path (tested against
//! [`super::FemModel::internal_forces_reference`]). Two kernels compute it.
//!
//! **Positions kernel** (f64 storage, the default). With `Ds = [x1−x0, x2−x0, x3−x0]` from
//! the current positions `x = X + u`, `F = Ds Dm⁻¹`, and since `cof(A B) = cof A cof B` and
//! `cof(Dm⁻¹) Dm⁻ᵀ = det Dm⁻¹ I`:
//!
//! ```text
//! H = V0 P Dm⁻ᵀ = Ds G + c cof Ds,   G = μ V0 Dm⁻¹ Dm⁻ᵀ,
//! J = det Ds · det Dm⁻¹,   c = (λ ln J − μ) / (6 J)
//! ```
//!
//! (`V0 det Dm⁻¹ = 1/6`: the force model admits positively oriented tetrahedra only).
//! `G` (6 entries, symmetric) and `det Dm⁻¹` are precomputed: 72 bytes per tetrahedron with
//! the 4 node offsets, 156 flops, against 96 bytes and 213 flops for `F = I + Du Dm⁻¹`,
//! `cof F`, `V0 P`, `P Dm⁻ᵀ`. The node rows the kernel reads hold `X + u`, built by the
//! force model from `u` (or advanced in place by the fused step's node update). The rounding differs from
//! the displacement form: `Ds` carries the rounding of `X + u` (an ulp of the coordinates,
//! relative `ulp(|X|) / h` to an edge of length `h`), so where the displacement form's `F − I`
//! is exact to the last bit the positions form is within about `1e-14` of the strain on the
//! meshes here; the forces match the generic path within `1e-12` of their largest entry
//! (tested). On the standard 100k box the kernel took the fused step from 40.0-40.7 M to
//! 47.0-47.2 M node-updates/s on 2 threads and from 20.5-21.0 M to 22.7-22.9 M on 1; at 1M
//! from 36.2-37.2 M to 35.4 M on 2 threads and 19.2 M to 18.7 M on 1 (2 runs each,
//! alternated): out of cache the 32-byte node rows and the node pass's extra `X` read and
//! row write cost what the kernel saves.
//!
//! **Displacements kernel** (f32 storage): `F = I + Du Dm⁻¹`, `J = det F`, `cof F = J F⁻ᵀ`,
//! `V0 P = a F + b cof F` with `a = μ V0`, `b = V0 (λ ln J − μ) / J`, `H = V0 P Dm⁻ᵀ`. It
//! reads `u` and keeps `Dm⁻¹` and `V0` per element: with `Dm⁻¹` rounded to f32, the strain
//! `Du Dm⁻¹` keeps its relative accuracy at small strain. The positions form with f32
//! storage would round `det Dm⁻¹` (hence `J`) and `G` to f32, an error of `6e-8` on `J` and on
//! the rest-state balance of `Ds G` against `c cof Ds`, larger than the strain itself in soft
//! tissue under gravity.
//!
//! `ln J` ([`ln_j`]) is the series of `ln(1 + f)`, `f = J − 1`, where `|f| < 2⁻⁵` (no
//! division; nearly incompressible tissue keeps almost every element there), else a
//! branch-free `2 atanh` series; both within 1 ulp of `f64::ln` on the tested sweeps, and
//! the AVX2 kernels evaluate the second only for groups with a lane outside. The series
//! took the fused step from 18.6 to 20.4-20.9 M node-updates/s (100k, 1 thread), 36.9-37.1
//! to 40.3-40.9 M (100k, 2 threads) and 33.3-34.0 to 36.8-36.9 M (1M, 2 threads).
//!
//! Each kernel comes portable (`run_positions`, `run_groups`: lane loops) and with AVX2 +
//! FMA intrinsics (`run_positions_avx2`, `run_groups_avx2`), the same operations and the same
//! bits. The AVX2 kernels split the work over a block of `BLK` = 4 groups into three stages,
//! (A) gather, the deformation, its cofactor and `J`, (B) the `ln J` factor, (C) `H` and the
//! scatter, so that the independent groups of a block overlap in the core; the positions
//! kernel prefetches the element data [`PREFETCH_BLOCKS`] blocks ahead into L1 and
//! [`PREFETCH_L2_BLOCKS`] ahead into L2 and, out of cache, the node and force rows a slab
//! is about to touch for the first time, from a schedule built at packing
//! ([`ROW_PREFETCH_BLOCKS`]).
//!
//! The positions kernel also comes with AVX-512 (`run_positions_avx512`, chosen by
//! `detect_isa`): two consecutive groups side by side in 8 lanes, over blocks of 2 × `BLK`
//! groups, every lane doing the same operations as in the AVX2 kernel (its arithmetic is one
//! generic code over [`Lanes`], 4 or 8 lanes) and the scatter adding the first group's rows,
//! then the second's, in the AVX2 order: the same bits (tested on every group count). On the
//! Zen 5 development VM, alternated with the AVX2 kernel (`RAISOV_ISA=avx2`), the fused step
//! ran 5-15 % faster in and out of cache (table in `bench/RESULTS.md`).
//!
//! Node rows: the kernels read node values from, and accumulate forces into, rows of 32
//! bytes `[x, y, z, 0]` ([`Row4`], aligned): one 256-bit load per corner and lane and a 4 × 4
//! transpose for the gather, a transpose and one 256-bit read-add-write per corner and lane
//! for the scatter, against two 128-bit and one 64-bit access each with 24-byte rows. In the
//! force pass alone this measured 2-8 % faster (1 thread, 10k to 1M nodes).
//!
//! Layout: elements packed in groups of [`LANES`] (structure of arrays inside a group: the
//! element data and the corner offsets `4 × node id` lane-contiguous), sorted into slabs of equal element counts (by mean node id when the node
//! numbering is banded, as for the structured boxes, so that a slab touches one contiguous
//! stretch of `u` and `r`; else along the longest axis of the mesh) and, inside a slab, in
//! strips one mean element extent wide across the axis of middle node-id growth (banded
//! numbering only: the slab is swept strip by strip along the axis of fastest-growing ids,
//! so that a node's elements are met within two strips) and by the Morton key of the
//! element centroid within a strip, the lanes of a group 16 groups apart in that order
//! ([`INTERLEAVE`]: lanes of one group then rarely share a node). The strips took the 1M
//! standard box from 14.4 to 17.2 M node-updates/s on 1 thread and from 28.8 to 33.1 M on
//! 2, the 100k box from 17.2 to 18.5 M and 35.1-35.4 to 35.8-36.8 M, the 10k box 21.1 to
//! 21.7 M (1 thread; same on 2); strips half or twice as wide, or across `x`, measured
//! slower.
//!
//! Slabs are coloured greedily so that slabs of one colour share no node; the force pass
//! runs colour by colour, the slabs of a colour in parallel, each slab scattering serially
//! into `r`. Every node thus receives its element contributions in one fixed order
//! (colour, then slab order, then element order) whatever the number of threads: the same
//! bits on 1 and 2 threads, no atomics.
//!
//! Precision ([`Precision`], chosen per model by [`super::FemParams::precision`]): f64
//! storage (`Precision::F64`, the default) runs the positions kernel on 72 bytes per
//! tetrahedron; f32 storage (`Precision::F32Storage`) runs the displacements kernel with
//! `Dm⁻¹` and the reference volume in f32 (4 × u32 offsets + 9 × f32 + 1 × f32, 56 bytes per
//! tetrahedron). The f32 values are widened exactly to f64 on load (`_mm256_cvtps_pd`,
//! `f32 as f64`) and every operation, `u`, `r`, the state and the masses stay f64, so both
//! ISAs and both thread counts give the same bits within each precision. What differs from
//! f64 is the rounding of `Dm⁻¹` and `V0` to f32 once, at packing (relative error ≤ 2⁻²⁴ ≈
//! 6e-8 per entry), which perturbs the forces by about that much times the conditioning of
//! the element, and the kernel's own rounding (above). Stated tolerance (tested in
//! `fem::tests`): on a jittered mesh, `‖R_f32 − R_f64‖₂ ≤ 1e-6 ‖R_f64‖₂` and every entry
//! within `1e-6 max|R_f64|`. Measured: 2e-8 (2-norm) and 3e-8 to 5e-8 (max entry) under
//! random deformations of 1 % to 30 % of the shortest edge; 1.2e-7 and 1.6e-7 under an
//! affine stretch, where the interior forces cancel (patch test) and f32 storage leaves a
//! residue of that size. The 500-step standard work of [`crate::bench`] on the 1k box
//! agrees with f64 to better than 5 significant digits (tested < 5e-6 relative). The lumped
//! masses, the strain energy, the stresses and the generic path keep the f64 `Dm⁻¹` and
//! volumes. It can pay only where the pass is bandwidth-bound; on the 2-vCPU Zen 4
//! development VM it is not (0.3-0.5 of the triad), and since the positions kernel it is
//! the slower of the two.

use crate::mesh::morton3;
use rayon::prelude::*;

/// Elements per SIMD group.
pub const LANES: usize = 4;

/// Bytes of element data the force pass streams per tetrahedron with f64 storage (ids, `G`,
/// `det Dm⁻¹`): 72. See [`Precision::bytes_per_tet`].
pub const BYTES_PER_TET: usize = std::mem::size_of::<PGroup>() / LANES;

/// One node's row in the force pass's node arrays: `[x, y, z, 0]`, 32 bytes, aligned so
/// that a row is one 256-bit load or store and never straddles a cache line.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(32))]
pub struct Row4(pub [f64; 4]);

/// Storage precision of the packed element data (`Dm⁻¹` and reference volume). Arithmetic,
/// displacements, forces, velocities and masses are f64 in both; see the module docs for
/// what changes and the tolerance against f64.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Precision {
    /// Everything in f64 (72 bytes of element data per tetrahedron, the positions kernel).
    /// The default.
    #[default]
    F64,
    /// `Dm⁻¹` and the reference volume stored in f32, widened to f64 on load (56 bytes per
    /// tetrahedron); arithmetic and state in f64.
    F32Storage,
}

impl Precision {
    /// Both, f64 first.
    pub const ALL: [Precision; 2] = [Precision::F64, Precision::F32Storage];

    /// The name used in scenarios, on the command line and in the benchmark table:
    /// `"f64"` or `"f32-storage"`.
    pub fn name(self) -> &'static str {
        match self {
            Precision::F64 => "f64",
            Precision::F32Storage => "f32-storage",
        }
    }

    /// Inverse of [`Precision::name`].
    pub fn from_name(s: &str) -> Option<Precision> {
        Precision::ALL.into_iter().find(|p| p.name() == s)
    }

    /// Bytes of packed element data per tetrahedron: 72 (f64) or 56 (f32 storage).
    pub fn bytes_per_tet(self) -> usize {
        match self {
            Precision::F64 => BYTES_PER_TET,
            Precision::F32Storage => std::mem::size_of::<Group<f32>>() / LANES,
        }
    }

    /// `x` as the packed path sees it: unchanged (f64) or rounded to f32.
    #[inline]
    pub fn round(self, x: f64) -> f64 {
        match self {
            Precision::F64 => x,
            Precision::F32Storage => x as f32 as f64,
        }
    }
}

/// Zero-sized alignment marker (a group is a whole number of its alignment, so that no
/// group straddles more cache lines than it must).
#[derive(Clone, Copy)]
#[repr(C, align(32))]
pub(crate) struct Align32;

/// A scalar type the displacements kernel's element data are stored in (f32); the kernels
/// load it as f64, and the AVX2 kernel keeps the widened `Dm⁻¹` and `V0` of stages A and B
/// for stage C (one conversion per entry instead of two).
pub(crate) trait Store: Copy + Send + Sync + 'static {
    /// Alignment marker of a [`Group`] of this type.
    type Align: Copy + Send + Sync;
    const ZERO: Self;
    fn from_f64(x: f64) -> Self;
    /// Exact widening to f64.
    fn get(self) -> f64;
    /// The 4 lanes widened to f64 (exactly as [`Store::get`]).
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    unsafe fn load4(p: &[Self; LANES]) -> std::arch::x86_64::__m256d;
}

impl Store for f32 {
    type Align = Align32;
    const ZERO: f32 = 0.0;
    #[inline(always)]
    fn from_f64(x: f64) -> f32 {
        x as f32
    }
    #[inline(always)]
    fn get(self) -> f64 {
        self as f64
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    unsafe fn load4(p: &[f32; LANES]) -> std::arch::x86_64::__m256d {
        use std::arch::x86_64::*;
        _mm256_cvtps_pd(_mm_loadu_ps(p.as_ptr()))
    }
}

/// One group of `LANES` tetrahedra, element data stored as `S`.
#[derive(Clone, Copy)]
#[repr(C)]
pub(crate) struct Group<S: Store> {
    _align: [S::Align; 0],
    /// Offsets `4 × node id` of the corners into the node rows, `idx[corner][lane]`.
    idx: [[u32; LANES]; 4],
    /// `Dm⁻¹` row-major, `dminv[3 r + c][lane]`.
    dminv: [[S; LANES]; 9],
    /// Reference volume (0 for padding lanes).
    vol: [S; LANES],
}

const _: () = assert!(std::mem::size_of::<Group<f32>>() == 4 * 56);

/// One group of `LANES` tetrahedra of the positions kernel (f64 storage), structure of
/// arrays. The fields a stage reads first come first: stage A reads `idx` and `k`, stage B
/// `k`, stage C `g` and `idx`. 288 bytes, aligned to 32 (so groups straddle cache lines).
#[derive(Clone, Copy)]
#[repr(C, align(32))]
pub(crate) struct PGroup {
    /// Offsets `4 × node id` of the corners into the node rows, `idx[corner][lane]`.
    idx: [[u32; LANES]; 4],
    /// `det Dm⁻¹ = 1 / det Dm > 0`, so that `J = det Ds · k` (0 for padding lanes).
    k: [f64; LANES],
    /// `G = μ V0 Dm⁻¹ Dm⁻ᵀ` (symmetric): `G00, G01, G02, G11, G12, G22` (0 for padding lanes).
    g: [[f64; LANES]; 6],
}

const _: () = assert!(std::mem::size_of::<PGroup>() == 4 * 72);

/// `V0 det Dm⁻¹ = 1/6` of every tetrahedron (the force model admits positively oriented
/// ones only), the factor of `c = (λ ln J − μ) / (6 J)`.
const W: f64 = 1.0 / 6.0;

/// The packed groups in one of the storage precisions.
enum Groups {
    /// Positions kernel.
    F64(Vec<PGroup>),
    /// Displacements kernel, `Dm⁻¹` and `V0` in f32.
    F32(Vec<Group<f32>>),
}

/// Packed neo-Hookean tetrahedra in force-pass order.
pub(crate) struct TetPack {
    mu: f64,
    lambda: f64,
    groups: Groups,
    /// Groups of slab s: `slab_ptr[s]..slab_ptr[s + 1]`, slabs stored colour by colour.
    slab_ptr: Vec<usize>,
    /// Slabs of colour c: `colour_ptr[c]..colour_ptr[c + 1]`.
    colour_ptr: Vec<usize>,
    n_nodes: usize,
    /// Instruction set of the kernel: 0 portable, 1 AVX2 + FMA.
    isa: u8,
    /// Row prefetch schedule ([`row_prefetch_schedule`]): the first block of each slab in
    /// the global block numbering, and per block the 64-byte lines of node and force rows
    /// to prefetch (`rows_pf[rows_pf_ptr[b]..rows_pf_ptr[b + 1]]`, line = node id / 2).
    block_base: Vec<usize>,
    rows_pf_ptr: Vec<u32>,
    rows_pf: Vec<u32>,
}

/// Number of slabs for `wanted` slabs' worth of elements when at most `max` fit: 1 (serial)
/// below 2, else `wanted` rounded up to a multiple of 4 and capped at `max` rounded down to
/// one (fewer than 4 when `max` is). Slabs of a band alternate between 2 colours, so a
/// multiple of 4 gives each colour an even number of slabs and the two threads of a
/// 2-core machine equal shares in every colour. Measured on the standard boxes (f64,
/// node-updates/s, 3 runs each): 10k nodes on 2 threads 33.1-36.3 M with 4 slabs against
/// 13.2-28.1 M with the 18 (9 per colour) of one slab per 2048 elements; 100k flat from 4
/// to 16 slabs. At 1M, 8-16 slabs beat the default 36 by 3-6 % before the strips (below)
/// and lose 2-7 % with them.
pub(super) fn slab_count(wanted: usize, max: usize) -> usize {
    if wanted <= 1 || max <= 1 {
        return 1;
    }
    let n = wanted.next_multiple_of(4).min(max);
    if n >= 4 {
        n - n % 4
    } else {
        n
    }
}

/// The axis along which node ids grow at the middle of the three rates, judged by the mean
/// `|∂ id / ∂x_d|` over the elements (the gradient of the node id interpolated linearly on
/// each element, `∇id = Dm⁻ᵀ Δid`) times the mean element extent along `d`: on a
/// lexicographic grid numbering (x fastest, z slowest) about 1, `n_x` and `n_x n_y`, so `y`.
/// `None` without elements or when the rates are not finite. `dminv` column-major, 9 per
/// element.
pub(super) fn strip_axis(cells: &[u32], dminv: &[f64], ext: &[f64; 3], ne: usize) -> Option<usize> {
    if ne == 0 {
        return None;
    }
    let mut g = [0.0f64; 3];
    for e in 0..ne {
        let id = |k: usize| cells[4 * e + k] as f64;
        let did = [id(1) - id(0), id(2) - id(0), id(3) - id(0)];
        for (d, gd) in g.iter_mut().enumerate() {
            // (∇id)_d = Σ_k Dm⁻¹[k][d] Δid_k; column-major: Dm⁻¹[k][d] = dminv[9e + 3d + k].
            let v: f64 = (0..3).map(|k| dminv[9 * e + 3 * d + k] * did[k]).sum();
            *gd += v.abs();
        }
    }
    let rate: [f64; 3] = std::array::from_fn(|d| g[d] * ext[d]);
    if !rate.iter().all(|r| r.is_finite()) {
        return None;
    }
    let mut axes = [0usize, 1, 2];
    axes.sort_by(|&a, &b| rate[a].total_cmp(&rate[b]).then(a.cmp(&b)));
    Some(axes[1])
}

impl TetPack {
    /// Pack the elements. `cells` 4 per element, `dminv` 9 per element column-major,
    /// `target_block` the wanted elements per slab, `precision` that of the stored `dminv`
    /// and `vol`.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn new(
        mu: f64,
        lambda: f64,
        x0: &[f64],
        cells: &[u32],
        dminv: &[f64],
        vol: &[f64],
        target_block: usize,
        precision: Precision,
    ) -> TetPack {
        let ne = vol.len();
        let n_nodes = x0.len() / 3;
        assert!(
            4 * n_nodes <= u32::MAX as usize,
            "too many nodes for u32 offsets"
        );
        // Centroids, bounding box, mean element extent per axis.
        let mut cen = vec![[0.0f64; 3]; ne];
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        let mut ext = [0.0f64; 3];
        for e in 0..ne {
            let mut emin = [f64::INFINITY; 3];
            let mut emax = [f64::NEG_INFINITY; 3];
            for k in 0..4 {
                let a = cells[4 * e + k] as usize * 3;
                for d in 0..3 {
                    let x = x0[a + d];
                    cen[e][d] += 0.25 * x;
                    emin[d] = emin[d].min(x);
                    emax[d] = emax[d].max(x);
                }
            }
            for d in 0..3 {
                lo[d] = lo[d].min(emin[d]);
                hi[d] = hi[d].max(emax[d]);
                ext[d] += emax[d] - emin[d];
            }
        }
        // Slab key: the mean node id of the element when the numbering is banded (each
        // slab then reads and writes one contiguous stretch of u and r: prefetchable), else
        // the centroid along the longest axis. Slabs at least two element "widths" thick
        // so that two colours usually suffice, about `target_block` elements each.
        let bw = (0..ne)
            .map(|e| {
                let el = &cells[4 * e..4 * e + 4];
                let (mn, mx) = el
                    .iter()
                    .fold((u32::MAX, 0), |(a, b), &c| (a.min(c), b.max(c)));
                (mx - mn) as usize
            })
            .max()
            .unwrap_or(0);
        let max_slabs_index = (n_nodes / (2 * bw.max(1))).max(1);
        let axis = (0..3)
            .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])))
            .unwrap_or(0);
        let mean_ext = if ne > 0 { ext[axis] / ne as f64 } else { 1.0 };
        let max_slabs_geo = ((hi[axis] - lo[axis]) / (2.0 * mean_ext.max(f64::MIN_POSITIVE)))
            .floor()
            .max(1.0) as usize;
        let wanted = ne.div_ceil(target_block.max(1));
        let by_index = max_slabs_index >= wanted.min(8);
        let slabs = slab_count(
            wanted,
            if by_index {
                max_slabs_index
            } else {
                max_slabs_geo
            },
        );
        let slab_key: Vec<f64> = (0..ne)
            .map(|e| {
                if by_index {
                    cells[4 * e..4 * e + 4]
                        .iter()
                        .map(|&c| c as f64)
                        .sum::<f64>()
                } else {
                    cen[e][axis]
                }
            })
            .collect();
        let mut by_axis: Vec<u32> = (0..ne as u32).collect();
        by_axis.sort_by(|&a, &b| {
            slab_key[a as usize]
                .total_cmp(&slab_key[b as usize])
                .then(a.cmp(&b))
        });
        let mut slab_of = vec![0u32; ne];
        for (rank, &e) in by_axis.iter().enumerate() {
            slab_of[e as usize] = (rank * slabs / ne.max(1)) as u32;
        }
        let q = |d: usize, x: f64| -> u64 {
            let w = hi[d] - lo[d];
            if w > 0.0 {
                (((x - lo[d]) / w) * ((1u64 << 21) - 1) as f64) as u64
            } else {
                0
            }
        };
        let key: Vec<u64> = cen
            .iter()
            .map(|c| morton3([q(0, c[0]), q(1, c[1]), q(2, c[2])]))
            .collect();
        // Strips inside a slab (banded numbering only): bands one mean element extent wide
        // across the axis along which the node id grows at the middle rate, so that a slab
        // is swept strip by strip along the axis of fastest-growing ids. A node's elements
        // then lie in its own strip and the neighbouring ones, and `u`, `r` and the element
        // data between two visits of a node stay in L2; in Morton order alone, elements
        // either side of a Morton block boundary meet again only much later.
        let strip = if by_index {
            strip_axis(cells, dminv, &ext, ne).map(|d| (d, ext[d] / ne as f64))
        } else {
            None
        };
        let strip_of = |e: usize| -> u64 {
            match strip {
                Some((d, w)) if w > 0.0 => ((cen[e][d] - lo[d]) / w) as u64,
                _ => 0,
            }
        };
        let mut order: Vec<u32> = (0..ne as u32).collect();
        order.sort_by_key(|&e| {
            let i = e as usize;
            (slab_of[i], strip_of(i), key[i], e)
        });
        // Slab ranges in `order`.
        let mut slab_range = vec![(0usize, 0usize); slabs];
        {
            let mut i = 0;
            for (s, r) in slab_range.iter_mut().enumerate() {
                let start = i;
                while i < ne && slab_of[order[i] as usize] as usize == s {
                    i += 1;
                }
                *r = (start, i);
            }
        }
        // Greedy colouring of slabs: no two slabs of one colour share a node.
        let mut node_mask = vec![0u64; n_nodes];
        let mut colour = vec![0usize; slabs];
        let mut ok = true;
        for (s, &(a, b)) in slab_range.iter().enumerate() {
            let mut forbidden = 0u64;
            for &e in &order[a..b] {
                for k in 0..4 {
                    forbidden |= node_mask[cells[4 * e as usize + k] as usize];
                }
            }
            if forbidden == u64::MAX {
                ok = false;
                break;
            }
            let c = forbidden.trailing_ones() as usize;
            colour[s] = c;
            for &e in &order[a..b] {
                for k in 0..4 {
                    node_mask[cells[4 * e as usize + k] as usize] |= 1 << c;
                }
            }
        }
        if !ok {
            // Pathological mesh: one slab, serial.
            colour.iter_mut().for_each(|c| *c = 0);
            slab_range = vec![(0, ne)];
            colour.truncate(1);
        }
        let n_colours = colour.iter().max().map_or(0, |&c| c + 1);
        let mut slab_order: Vec<usize> = (0..slab_range.len()).collect();
        slab_order.sort_by_key(|&s| (colour[s], s));
        let mut colour_ptr = vec![0usize; n_colours + 1];
        for &c in &colour {
            colour_ptr[c + 1] += 1;
        }
        for c in 0..n_colours {
            colour_ptr[c + 1] += colour_ptr[c];
        }
        // Pack groups slab by slab (padding the last group of each slab).
        let slabs_in_order: Vec<&[u32]> = slab_order
            .iter()
            .map(|&s| &order[slab_range[s].0..slab_range[s].1])
            .collect();
        let (lanes, slab_ptr) = group_lanes(&slabs_in_order);
        let groups = match precision {
            Precision::F64 => Groups::F64(pack_position_groups(&lanes, mu, cells, dminv, vol)),
            Precision::F32Storage => {
                Groups::F32(pack_displacement_groups(&lanes, cells, dminv, vol))
            }
        };
        let mut pack = TetPack {
            mu,
            lambda,
            groups,
            slab_ptr,
            colour_ptr,
            n_nodes,
            isa: detect_isa(),
            block_base: Vec::new(),
            rows_pf_ptr: Vec::new(),
            rows_pf: Vec::new(),
        };
        // Row prefetch only out of cache (it costs 3-8 % where the rows come from L3).
        let footprint = pack.bytes() + 2 * std::mem::size_of::<Row4>() * n_nodes;
        pack.set_row_prefetch(if footprint > 2 * l3_bytes() {
            ROW_PREFETCH_BLOCKS
        } else {
            0
        });
        pack
    }

    /// Build the positions kernel's row prefetch schedule `dist` blocks ahead (0: none;
    /// [`row_prefetch_schedule`]); the displacements kernel has none.
    pub(crate) fn set_row_prefetch(&mut self, dist: usize) {
        (self.block_base, self.rows_pf_ptr, self.rows_pf) = match &self.groups {
            Groups::F64(g) => {
                row_prefetch_schedule(|i| g[i].idx, &self.slab_ptr, self.n_nodes, dist)
            }
            Groups::F32(_) => (Vec::new(), Vec::new(), Vec::new()),
        };
    }

    /// Number of slabs (parallel tasks) and colours (sequential phases).
    pub(crate) fn layout(&self) -> (usize, usize) {
        (self.slab_ptr.len() - 1, self.colour_ptr.len() - 1)
    }

    /// Bytes of the packed element data.
    pub(crate) fn bytes(&self) -> usize {
        match &self.groups {
            Groups::F64(g) => std::mem::size_of_val(&g[..]),
            Groups::F32(g) => std::mem::size_of_val(&g[..]),
        }
    }

    /// Storage precision of the element data.
    pub(crate) fn precision(&self) -> Precision {
        match self.groups {
            Groups::F64(_) => Precision::F64,
            Groups::F32(_) => Precision::F32Storage,
        }
    }

    /// Whether the node rows given to [`TetPack::accumulate`] hold positions `X + u` (f64
    /// storage: the positions kernel) or displacements `u` (f32 storage).
    pub(crate) fn reads_positions(&self) -> bool {
        matches!(self.groups, Groups::F64(_))
    }

    /// `r += R` for the node rows `q`, positions or displacements as
    /// [`TetPack::reads_positions`] says (`r` must hold what is to be accumulated onto,
    /// usually zeros; the fourth entry of a row is read as nothing and stays as it is in `r`
    /// plus zeros). Returns false if some element has `J <= 0` (or NaN); `r` is then
    /// unspecified.
    pub(crate) fn accumulate(&self, q: &[Row4], r: &mut [Row4]) -> bool {
        assert!(q.len() >= self.n_nodes && r.len() >= self.n_nodes);
        let rp = SyncPtr(r.as_mut_ptr() as *mut f64);
        let n_slabs = self.slab_ptr.len() - 1;
        let mut good = true;
        for c in 0..self.colour_ptr.len() - 1 {
            let (s0, s1) = (self.colour_ptr[c], self.colour_ptr[c + 1]);
            let run = |s: usize| -> bool {
                // SAFETY: node ids were checked < n_nodes at construction, q and r have
                // n_nodes rows (asserted above), and slabs of one colour share no node, so
                // concurrent slabs write disjoint rows of r.
                unsafe { self.run_slab(s, q, rp) }
            };
            good &= if n_slabs >= 2 && s1 - s0 >= 2 {
                (s0..s1)
                    .into_par_iter()
                    .map(run)
                    .reduce(|| true, |a, b| a & b)
            } else {
                (s0..s1).map(run).fold(true, |a, b| a & b)
            };
        }
        good
    }

    /// Use kernel `isa` (0 portable, 1 AVX2, 2 AVX-512), or the widest this CPU runs if
    /// lower (tests compare the kernels).
    #[cfg(test)]
    pub(crate) fn force_isa(&mut self, isa: u8) {
        self.isa = isa.min(supported_isa());
    }

    /// `r += R` over the first `n` groups of the f64 storage's first slab only, with kernel
    /// `isa` as [`TetPack::force_isa`] (tests: every group count of the AVX-512 kernel's
    /// pairs and blocks against AVX2). False if the storage is not f64 or the slab is shorter.
    #[cfg(test)]
    pub(crate) fn run_first_groups(&self, n: usize, isa: u8, q: &[Row4], r: &mut [Row4]) -> bool {
        let Groups::F64(g) = &self.groups else {
            return false;
        };
        if n > self.slab_ptr[1] - self.slab_ptr[0] {
            return false;
        }
        let (xp, rp) = (q.as_ptr() as *const f64, r.as_mut_ptr() as *mut f64);
        let (g, mu, lambda) = (
            &g[self.slab_ptr[0]..self.slab_ptr[0] + n],
            self.mu,
            self.lambda,
        );
        let blocks = vec![0; n.div_ceil(BLK) + 1];
        let pf = (&blocks[..], &[][..]);
        // SAFETY: as `run_slab`: node ids are < n_nodes, q and r hold n_nodes rows.
        assert!(q.len() >= self.n_nodes && r.len() >= self.n_nodes);
        unsafe {
            match isa.min(supported_isa()) {
                #[cfg(target_arch = "x86_64")]
                2 => run_positions_avx512(g, pf, xp, rp, mu, lambda),
                #[cfg(target_arch = "x86_64")]
                1 => run_positions_avx2(g, pf, xp, rp, mu, lambda),
                _ => run_positions(g, xp, rp, mu, lambda),
            }
        }
    }

    /// The kernel in use: `"portable"` or `"avx2"`.
    pub(crate) fn isa(&self) -> &'static str {
        ["portable", "avx2", "avx512"][self.isa as usize]
    }

    /// The groups of slab `s`.
    #[inline]
    unsafe fn run_slab(&self, s: usize, q: &[Row4], r: SyncPtr) -> bool {
        let (a, b) = (self.slab_ptr[s], self.slab_ptr[s + 1]);
        let qp = q.as_ptr() as *const f64;
        let (mu, lambda) = (self.mu, self.lambda);
        match &self.groups {
            Groups::F64(g) => {
                #[cfg(target_arch = "x86_64")]
                if self.isa >= 1 {
                    let pf = &self.rows_pf_ptr[self.block_base[s]..=self.block_base[s + 1]];
                    let pf = (pf, &self.rows_pf[..]);
                    if self.isa == 2 {
                        return run_positions_avx512(&g[a..b], pf, qp, r.0, mu, lambda);
                    }
                    return run_positions_avx2(&g[a..b], pf, qp, r.0, mu, lambda);
                }
                run_positions(&g[a..b], qp, r.0, mu, lambda)
            }
            Groups::F32(g) => {
                #[cfg(target_arch = "x86_64")]
                if self.isa >= 1 {
                    return run_groups_avx2(&g[a..b], qp, r.0, mu, lambda);
                }
                run_groups(&g[a..b], qp, r.0, mu, lambda)
            }
        }
    }
}

/// Blocks ahead of its first use in a slab that a node row's cache line is prefetched
/// ([`row_prefetch_schedule`]), when the element data and the two row arrays together
/// exceed twice the last-level cache ([`l3_bytes`]). The hardware prefetcher follows the
/// rows' streams (one per layer of nodes a slab spans) too late out of cache: `perf` on the
/// 1M box showed the gathers and the scatters' loads at 2-3x their in-cache share of the
/// samples. Fused step, node-updates/s, alternated with the schedule off: 1M box 20.8-21.5 M
/// to 22.2-23.2 M on 1 thread (4 to 16 blocks alike) and 40.4-43.0 M to 42.3-45.5 M on 2;
/// 300k box 21.7-21.8 to 22.5-23.1 M and 42.0-45.3 to 43.4-45.6 M; but the 100k box, whose
/// rows partly stay in L3, 3-8 % slower on 1 thread, hence the footprint rule.
const ROW_PREFETCH_BLOCKS: usize = 8;

/// Size of the last-level cache (bytes): Linux's `cpu0/cache/index3/size`, else 32 MiB.
fn l3_bytes() -> usize {
    static L3: std::sync::OnceLock<usize> = std::sync::OnceLock::new();
    *L3.get_or_init(|| {
        std::fs::read_to_string("/sys/devices/system/cpu/cpu0/cache/index3/size")
            .ok()
            .and_then(|t| {
                let t = t.trim();
                let (num, mul) = match t.chars().last()? {
                    'K' => (&t[..t.len() - 1], 1 << 10),
                    'M' => (&t[..t.len() - 1], 1 << 20),
                    _ => (t, 1),
                };
                num.parse::<usize>().ok().map(|n| n * mul)
            })
            .filter(|&b| b > 0)
            .unwrap_or(32 << 20)
    })
}

/// The positions kernel's row prefetch schedule from the groups' corner offsets
/// (`idx_of(group)`, padding lanes included): for each slab, in the kernel's order (blocks
/// of [`BLK`] groups, corners, lanes), the first access in the slab to each 64-byte line of
/// the node rows (two 32-byte rows, nodes `2i` and `2i + 1`) is scheduled `dist` blocks
/// earlier (block 0 at the latest), for the node rows and the force rows alike; `dist = 0`
/// schedules nothing. Returns the first block of each slab in the global block numbering,
/// the list pointers per block and the line lists.
pub(super) fn row_prefetch_schedule(
    idx_of: impl Fn(usize) -> [[u32; LANES]; 4],
    slab_ptr: &[usize],
    n_nodes: usize,
    dist: usize,
) -> (Vec<usize>, Vec<u32>, Vec<u32>) {
    let mut block_base = Vec::with_capacity(slab_ptr.len());
    let mut stamp = vec![0u32; n_nodes.div_ceil(2)];
    let mut pairs: Vec<(u32, u32)> = Vec::new(); // (global block, line)
    let mut blocks = 0usize;
    for (s, w) in slab_ptr.windows(2).enumerate() {
        block_base.push(blocks);
        for gi in w[0]..w[1] {
            let b = ((gi - w[0]) / BLK).saturating_sub(dist);
            for corner in idx_of(gi) {
                for o in corner {
                    // Offsets are 4 × node id; a line holds two rows.
                    let line = o as usize / 8;
                    if dist > 0 && stamp[line] != s as u32 + 1 {
                        stamp[line] = s as u32 + 1;
                        pairs.push(((blocks + b) as u32, line as u32));
                    }
                }
            }
        }
        blocks += (w[1] - w[0]).div_ceil(BLK);
    }
    block_base.push(blocks);
    let mut ptr = vec![0u32; blocks + 1];
    for &(b, _) in &pairs {
        ptr[b as usize + 1] += 1;
    }
    for b in 0..blocks {
        ptr[b + 1] += ptr[b];
    }
    let mut fill: Vec<u32> = ptr.clone();
    let mut lines = vec![0u32; pairs.len()];
    for &(b, line) in &pairs {
        lines[fill[b as usize] as usize] = line;
        fill[b as usize] += 1;
    }
    (block_base, ptr, lines)
}

/// Groups per lane-interleave window: inside a slab, the elements (in Morton order) are
/// taken in windows of `INTERLEAVE × LANES`, and lane `l` of the window's `q`-th group holds
/// the window's element `l · INTERLEAVE + q` (for a full window). Neighbouring elements in
/// Morton order share nodes; were they lanes of one group, the group's scatter-adds to a
/// shared node would be a chain of read-after-write through memory (store-to-load
/// forwarding) that the core cannot overlap. 16 apart, the lanes of a group rarely share a
/// node while a window (64 elements) still touches a compact set of nodes. Measured on the
/// standard 100k box: 16.6-16.9 M node-updates/s on 1 thread and 33.6-34.6 M on 2, against
/// 14.5-14.7 M and 29.7-30.5 M with consecutive lanes (back to back, same build); at 1M
/// nodes 5 % faster. Windows of 8 or 32 groups measured between the two; separating the
/// lanes by a quarter of the slab lost locality at 1M (19 M instead of 25 M on 2 threads).
const INTERLEAVE: usize = 16;

/// The lanes of each group, slab by slab (element ids in force-pass order), lanes
/// interleaved by [`INTERLEAVE`]; `None` marks a padding lane (only in the last window of a
/// slab). Returns the lanes and the slab pointers into them.
fn group_lanes(slabs: &[&[u32]]) -> (Vec<[Option<u32>; LANES]>, Vec<usize>) {
    let ne: usize = slabs.iter().map(|s| s.len()).sum();
    let mut lanes = Vec::with_capacity(ne / LANES + slabs.len());
    let mut slab_ptr = vec![0usize];
    for slab in slabs {
        for window in slab.chunks(INTERLEAVE * LANES) {
            // Lane l of the window's group q holds element l·wg + q of the window.
            let wg = window.len().div_ceil(LANES);
            for q in 0..wg {
                lanes.push(std::array::from_fn(|l| window.get(l * wg + q).copied()));
            }
        }
        slab_ptr.push(lanes.len());
    }
    (lanes, slab_ptr)
}

/// `Dm⁻¹[r][c]` of element `e` from the column-major source.
#[inline]
fn dm_inv(dminv: &[f64], e: usize, r: usize, c: usize) -> f64 {
    dminv[9 * e + 3 * c + r]
}

/// The corner offsets `4 × node id` of a group's lanes and each lane's
/// element and reference volume; a padding lane repeats the group's first element with
/// volume 0.
fn lane_elements(
    gl: &[Option<u32>; LANES],
    cells: &[u32],
    vol: &[f64],
) -> ([[u32; LANES]; 4], [(usize, f64); LANES]) {
    let first = gl[0].expect("lane 0 of every group holds an element") as usize;
    let ev: [(usize, f64); LANES] = std::array::from_fn(|l| match gl[l] {
        Some(e) => (e as usize, vol[e as usize]),
        None => (first, 0.0),
    });
    let idx = std::array::from_fn(|k| std::array::from_fn(|l| 4 * cells[4 * ev[l].0 + k]));
    (idx, ev)
}

/// Groups of the positions kernel. Padding lanes repeat the group's first element with
/// `k = 0` and `G = 0`: zero force.
fn pack_position_groups(
    lanes: &[[Option<u32>; LANES]],
    mu: f64,
    cells: &[u32],
    dminv: &[f64],
    vol: &[f64],
) -> Vec<PGroup> {
    let mut out = huge_page_vec(lanes.len());
    out.extend(lanes.iter().map(|gl| {
        let (idx, ev) = lane_elements(gl, cells, vol);
        let mut g = PGroup {
            idx,
            k: [0.0; LANES],
            g: [[0.0; LANES]; 6],
        };
        for (l, &(e, v0)) in ev.iter().enumerate() {
            if gl[l].is_none() {
                continue; // padding lane: k = 0, G = 0
            }
            let d = |r: usize, c: usize| dm_inv(dminv, e, r, c);
            let det = d(0, 0) * (d(1, 1) * d(2, 2) - d(1, 2) * d(2, 1))
                - d(0, 1) * (d(1, 0) * d(2, 2) - d(1, 2) * d(2, 0))
                + d(0, 2) * (d(1, 0) * d(2, 1) - d(1, 1) * d(2, 0));
            debug_assert!(det > 0.0, "the force model admits positive elements only");
            g.k[l] = det;
            for (t, (m, n)) in [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]
                .into_iter()
                .enumerate()
            {
                g.g[t][l] = mu * v0 * (0..3).map(|c| d(m, c) * d(n, c)).sum::<f64>();
            }
        }
        g
    }));
    out
}

/// Groups of the displacements kernel (f32 storage). Padding lanes repeat the group's first
/// element with zero volume: zero force.
fn pack_displacement_groups<S: Store>(
    lanes: &[[Option<u32>; LANES]],
    cells: &[u32],
    dminv: &[f64],
    vol: &[f64],
) -> Vec<Group<S>> {
    let mut out = huge_page_vec(lanes.len());
    out.extend(lanes.iter().map(|gl| {
        let (idx, ev) = lane_elements(gl, cells, vol);
        let mut g = Group::<S> {
            _align: [],
            idx,
            dminv: [[S::ZERO; LANES]; 9],
            vol: [S::ZERO; LANES],
        };
        for (l, &(e, v)) in ev.iter().enumerate() {
            for r in 0..3 {
                for c in 0..3 {
                    g.dminv[3 * r + c][l] = S::from_f64(dm_inv(dminv, e, r, c));
                }
            }
            g.vol[l] = S::from_f64(v);
        }
        g
    }));
    out
}

/// An empty vector with room for `n` elements whose memory, if large, is advised for
/// transparent huge pages before anything touches it (Linux `madvise(MADV_HUGEPAGE)`; a
/// no-op elsewhere, where THP is off, or on failure). The force pass streams the element
/// data and the node rows once per step; with 4 KiB pages every 64 lines of a stream cost a
/// TLB miss, and the row prefetches a page walk. Measured on the 1M standard box with THP
/// for every allocation (`GLIBC_TUNABLES=glibc.malloc.hugetlb=1`), two pairs of runs:
/// 23.58-23.68 M to 24.27-24.42 M node-updates/s on 1 thread, 43.87-45.21 M to 45.13-45.61 M
/// on 2.
pub(crate) fn huge_page_vec<T>(n: usize) -> Vec<T> {
    let v: Vec<T> = Vec::with_capacity(n);
    #[cfg(target_os = "linux")]
    {
        const HUGE: usize = 2 << 20;
        let bytes = n * std::mem::size_of::<T>();
        if bytes >= 2 * HUGE {
            let start = (v.as_ptr() as usize).next_multiple_of(4096);
            let end = (v.as_ptr() as usize + bytes) & !4095;
            if end > start {
                // SAFETY: advice on pages of this vector's own allocation; it changes no
                // contents and its failure is harmless.
                unsafe {
                    libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
                }
            }
        }
    }
    v
}

/// The kernel to run: 2 with AVX-512F (8 lanes, [`run_positions_avx512`]) where 512-bit
/// vectors pay, 1 with AVX2 + FMA, else 0 (portable). `RAISOV_ISA=portable`, `avx2` or
/// `avx512` caps the choice, or forces AVX-512 where it was left out (for comparisons); all
/// give the same bits. AVX-512 is left out on AMD family 19h (Zen 3 and 4), which executes a
/// 512-bit operation as two 256-bit halves: an 8-lane kernel measured no faster than AVX2
/// there (`bench/RESULTS.md`). On the Zen 5 development VM it is 5-15 % faster.
fn detect_isa() -> u8 {
    #[cfg(target_arch = "x86_64")]
    let wide_pays = !half_width_512();
    #[cfg(not(target_arch = "x86_64"))]
    let wide_pays = false;
    let cap = match std::env::var("RAISOV_ISA").as_deref() {
        Ok("portable") => 0,
        Ok("avx2") => 1,
        Ok("avx512") => 2,
        _ => 1 + u8::from(wide_pays),
    };
    supported_isa().min(cap)
}

/// The widest kernel this CPU can run: 2 with AVX-512F (and AVX2 + FMA), 1 with AVX2 + FMA,
/// else 0.
fn supported_isa() -> u8 {
    #[cfg(target_arch = "x86_64")]
    {
        let avx2 = std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma");
        let avx512 = avx2 && std::is_x86_feature_detected!("avx512f");
        u8::from(avx2) + u8::from(avx512)
    }
    #[cfg(not(target_arch = "x86_64"))]
    0
}

/// Whether this is an AMD family 19h CPU (Zen 3, Zen 4), whose 512-bit operations run as
/// two 256-bit halves.
#[cfg(target_arch = "x86_64")]
fn half_width_512() -> bool {
    use std::arch::x86_64::__cpuid;
    #[allow(unused_unsafe)]
    // SAFETY: `cpuid` exists on every x86-64 CPU.
    let (v, f) = unsafe { (__cpuid(0), __cpuid(1).eax) };
    let amd = (v.ebx, v.edx, v.ecx) == (0x6874_7541, 0x6974_6e65, 0x444d_4163);
    let family = ((f >> 8) & 0xf)
        + if (f >> 8) & 0xf == 0xf {
            (f >> 20) & 0xff
        } else {
            0
        };
    amd && family == 0x19
}

#[derive(Clone, Copy)]
struct SyncPtr(*mut f64);
// SAFETY: used only for disjoint writes (slabs of one colour share no node).
unsafe impl Send for SyncPtr {}
unsafe impl Sync for SyncPtr {}

/// Gather the 4 corners of one group (`idx[corner][lane]`, offsets of 32-byte node rows)
/// as `[x; y; z]` vectors over its 4 lanes: `(cx, cy, cz)`, each `[__m256d; 4]` indexed by
/// corner. One aligned 256-bit load per corner and lane, then a 4 × 4 transpose.
#[cfg(target_arch = "x86_64")]
macro_rules! gather4 {
    ($up:expr, $idx:expr) => {{
        let zero = _mm256_setzero_pd();
        let mut cx = [zero; 4];
        let mut cy = [zero; 4];
        let mut cz = [zero; 4];
        for k in 0..4 {
            let p = |l: usize| $up.add($idx[k][l] as usize);
            let (r0, r1) = (_mm256_load_pd(p(0)), _mm256_load_pd(p(1)));
            let (r2, r3) = (_mm256_load_pd(p(2)), _mm256_load_pd(p(3)));
            let t0 = _mm256_unpacklo_pd(r0, r1); // x0 x1 z0 z1
            let t1 = _mm256_unpackhi_pd(r0, r1); // y0 y1 w0 w1
            let t2 = _mm256_unpacklo_pd(r2, r3); // x2 x3 z2 z3
            let t3 = _mm256_unpackhi_pd(r2, r3); // y2 y3 w2 w3
            cx[k] = _mm256_permute2f128_pd(t0, t2, 0x20);
            cy[k] = _mm256_permute2f128_pd(t1, t3, 0x20);
            cz[k] = _mm256_permute2f128_pd(t0, t2, 0x31);
        }
        (cx, cy, cz)
    }};
}

/// Scatter-add `h[corner][component]` (vectors over the 4 lanes of a group) into the node
/// rows `r`, corner by corner, lane by lane (the order of the portable kernels): one
/// aligned 256-bit read-add-write per corner and lane, `[hx, hy, hz, 0]`.
#[cfg(target_arch = "x86_64")]
macro_rules! scatter4 {
    ($r:expr, $idx:expr, $h:expr) => {{
        let h: [[__m256d; 3]; 4] = $h;
        let zero = _mm256_setzero_pd();
        for k in 0..4 {
            let t0 = _mm256_unpacklo_pd(h[k][0], h[k][1]); // x0 y0 x2 y2
            let t1 = _mm256_unpackhi_pd(h[k][0], h[k][1]); // x1 y1 x3 y3
            let t2 = _mm256_unpacklo_pd(h[k][2], zero); // z0 0 z2 0
            let t3 = _mm256_unpackhi_pd(h[k][2], zero); // z1 0 z3 0
            let rows = [
                _mm256_permute2f128_pd(t0, t2, 0x20),
                _mm256_permute2f128_pd(t1, t3, 0x20),
                _mm256_permute2f128_pd(t0, t2, 0x31),
                _mm256_permute2f128_pd(t1, t3, 0x31),
            ];
            for (l, row) in rows.iter().enumerate() {
                let q = $r.add($idx[k][l] as usize);
                _mm256_store_pd(q, _mm256_add_pd(_mm256_load_pd(q), *row));
            }
        }
    }};
}

/// The vector operations of the kernels' arithmetic over 4 (AVX2, `__m256d`) or 8 (AVX-512,
/// `__m512d`) f64 lanes, so that [`v4`]'s helpers are written once for both widths. Each lane
/// sees the same IEEE operations whatever the width: the same bits. Every method is
/// `inline(always)`, compiled into its caller's target features (a kernel with
/// `#[target_feature]`); called from elsewhere it would not inline.
#[cfg(target_arch = "x86_64")]
pub(super) trait Lanes: Copy {
    /// Lanes selected by a comparison.
    type Mask: Copy;
    /// [`Lanes::bits`] with every lane set.
    const FULL: u32;
    unsafe fn splat(x: f64) -> Self;
    unsafe fn add(a: Self, b: Self) -> Self;
    unsafe fn sub(a: Self, b: Self) -> Self;
    unsafe fn mul(a: Self, b: Self) -> Self;
    unsafe fn div(a: Self, b: Self) -> Self;
    /// `a b + c`, one rounding.
    unsafe fn fmadd(a: Self, b: Self, c: Self) -> Self;
    /// `a b − c`, one rounding.
    unsafe fn fmsub(a: Self, b: Self, c: Self) -> Self;
    /// `−a` (sign bit flipped).
    unsafe fn neg(a: Self) -> Self;
    /// `|a|` (sign bit cleared).
    unsafe fn abs(a: Self) -> Self;
    /// `a > b` (ordered).
    unsafe fn gt(a: Self, b: Self) -> Self::Mask;
    /// `a < b` (ordered).
    unsafe fn lt(a: Self, b: Self) -> Self::Mask;
    /// `t` where `m`, else `f`.
    unsafe fn select(m: Self::Mask, t: Self, f: Self) -> Self;
    /// One bit per lane of `m`, lane 0 the lowest.
    unsafe fn bits(m: Self::Mask) -> u32;
    /// `(biased exponent as f64, mantissa in [1, 2))` of positive normal `x`.
    unsafe fn split_exponent(x: Self) -> (Self, Self);
}

/// The arithmetic methods of [`Lanes`], the same for both widths but for the intrinsics'
/// names.
#[cfg(target_arch = "x86_64")]
macro_rules! lanes_arith {
    ($splat:ident, $add:ident, $sub:ident, $mul:ident, $div:ident, $fmadd:ident, $fmsub:ident) => {
        #[inline(always)]
        unsafe fn splat(x: f64) -> Self {
            std::arch::x86_64::$splat(x)
        }
        #[inline(always)]
        unsafe fn add(a: Self, b: Self) -> Self {
            std::arch::x86_64::$add(a, b)
        }
        #[inline(always)]
        unsafe fn sub(a: Self, b: Self) -> Self {
            std::arch::x86_64::$sub(a, b)
        }
        #[inline(always)]
        unsafe fn mul(a: Self, b: Self) -> Self {
            std::arch::x86_64::$mul(a, b)
        }
        #[inline(always)]
        unsafe fn div(a: Self, b: Self) -> Self {
            std::arch::x86_64::$div(a, b)
        }
        #[inline(always)]
        unsafe fn fmadd(a: Self, b: Self, c: Self) -> Self {
            std::arch::x86_64::$fmadd(a, b, c)
        }
        #[inline(always)]
        unsafe fn fmsub(a: Self, b: Self, c: Self) -> Self {
            std::arch::x86_64::$fmsub(a, b, c)
        }
    };
}

#[cfg(target_arch = "x86_64")]
impl Lanes for std::arch::x86_64::__m256d {
    type Mask = std::arch::x86_64::__m256d;
    const FULL: u32 = 0xf;
    lanes_arith!(
        _mm256_set1_pd,
        _mm256_add_pd,
        _mm256_sub_pd,
        _mm256_mul_pd,
        _mm256_div_pd,
        _mm256_fmadd_pd,
        _mm256_fmsub_pd
    );
    #[inline(always)]
    unsafe fn neg(a: Self) -> Self {
        use std::arch::x86_64::*;
        _mm256_xor_pd(a, _mm256_set1_pd(-0.0))
    }
    #[inline(always)]
    unsafe fn abs(a: Self) -> Self {
        use std::arch::x86_64::*;
        _mm256_andnot_pd(_mm256_set1_pd(-0.0), a)
    }
    #[inline(always)]
    unsafe fn gt(a: Self, b: Self) -> Self {
        use std::arch::x86_64::*;
        _mm256_cmp_pd(a, b, _CMP_GT_OQ)
    }
    #[inline(always)]
    unsafe fn lt(a: Self, b: Self) -> Self {
        use std::arch::x86_64::*;
        _mm256_cmp_pd(a, b, _CMP_LT_OQ)
    }
    #[inline(always)]
    unsafe fn select(m: Self, t: Self, f: Self) -> Self {
        std::arch::x86_64::_mm256_blendv_pd(f, t, m)
    }
    #[inline(always)]
    unsafe fn bits(m: Self) -> u32 {
        std::arch::x86_64::_mm256_movemask_pd(m) as u32
    }
    #[inline(always)]
    unsafe fn split_exponent(x: Self) -> (Self, Self) {
        use std::arch::x86_64::*;
        let bits = _mm256_castpd_si256(x);
        let eb = _mm256_and_si256(_mm256_srli_epi64(bits, 52), _mm256_set1_epi64x(0x7ff));
        let magic = _mm256_set1_pd(4503599627370496.0); // 2^52
        let ef = _mm256_sub_pd(
            _mm256_castsi256_pd(_mm256_or_si256(eb, _mm256_castpd_si256(magic))),
            magic,
        );
        let m = _mm256_castsi256_pd(_mm256_or_si256(
            _mm256_and_si256(bits, _mm256_set1_epi64x(0x000f_ffff_ffff_ffff)),
            _mm256_set1_epi64x(0x3ff0_0000_0000_0000),
        ));
        (ef, m)
    }
}

#[cfg(target_arch = "x86_64")]
impl Lanes for std::arch::x86_64::__m512d {
    type Mask = std::arch::x86_64::__mmask8;
    const FULL: u32 = 0xff;
    lanes_arith!(
        _mm512_set1_pd,
        _mm512_add_pd,
        _mm512_sub_pd,
        _mm512_mul_pd,
        _mm512_div_pd,
        _mm512_fmadd_pd,
        _mm512_fmsub_pd
    );
    #[inline(always)]
    unsafe fn neg(a: Self) -> Self {
        use std::arch::x86_64::*;
        _mm512_castsi512_pd(_mm512_xor_si512(
            _mm512_castpd_si512(a),
            _mm512_set1_epi64(i64::MIN),
        ))
    }
    #[inline(always)]
    unsafe fn abs(a: Self) -> Self {
        std::arch::x86_64::_mm512_abs_pd(a)
    }
    #[inline(always)]
    unsafe fn gt(a: Self, b: Self) -> Self::Mask {
        use std::arch::x86_64::*;
        _mm512_cmp_pd_mask::<_CMP_GT_OQ>(a, b)
    }
    #[inline(always)]
    unsafe fn lt(a: Self, b: Self) -> Self::Mask {
        use std::arch::x86_64::*;
        _mm512_cmp_pd_mask::<_CMP_LT_OQ>(a, b)
    }
    #[inline(always)]
    unsafe fn select(m: Self::Mask, t: Self, f: Self) -> Self {
        std::arch::x86_64::_mm512_mask_blend_pd(m, f, t)
    }
    #[inline(always)]
    unsafe fn bits(m: Self::Mask) -> u32 {
        m as u32
    }
    #[inline(always)]
    unsafe fn split_exponent(x: Self) -> (Self, Self) {
        use std::arch::x86_64::*;
        let bits = _mm512_castpd_si512(x);
        let eb = _mm512_and_si512(_mm512_srli_epi64::<52>(bits), _mm512_set1_epi64(0x7ff));
        let magic = _mm512_set1_pd(4503599627370496.0); // 2^52
        let ef = _mm512_sub_pd(
            _mm512_castsi512_pd(_mm512_or_si512(eb, _mm512_castpd_si512(magic))),
            magic,
        );
        let m = _mm512_castsi512_pd(_mm512_or_si512(
            _mm512_and_si512(bits, _mm512_set1_epi64(0x000f_ffff_ffff_ffff)),
            _mm512_set1_epi64(0x3ff0_0000_0000_0000),
        ));
        (ef, m)
    }
}

/// The kernels' arithmetic on [`Lanes`] (4 or 8 lanes, the same operations per lane).
#[cfg(target_arch = "x86_64")]
mod v4 {
    use super::Lanes;

    /// `F` (row-major, 9) from `w[k][i] = Du_ik` and `Dm⁻¹` (row-major, 9).
    #[inline(always)]
    pub(super) unsafe fn def_grad<V: Lanes>(w: &[[V; 3]; 3], d: &[V; 9]) -> [V; 9] {
        let one = V::splat(1.0);
        let fm = |i: usize, j: usize| {
            V::fmadd(
                w[2][i],
                d[6 + j],
                V::fmadd(w[1][i], d[3 + j], V::mul(w[0][i], d[j])),
            )
        };
        [
            V::add(one, fm(0, 0)),
            fm(0, 1),
            fm(0, 2),
            fm(1, 0),
            V::add(one, fm(1, 1)),
            fm(1, 2),
            fm(2, 0),
            fm(2, 1),
            V::add(one, fm(2, 2)),
        ]
    }

    /// `cof F` (row-major) and `J = det F`.
    #[inline(always)]
    pub(super) unsafe fn cof_det<V: Lanes>(f: &[V; 9]) -> ([V; 9], V) {
        let [f00, f01, f02, f10, f11, f12, f20, f21, f22] = *f;
        let c = [
            V::fmsub(f11, f22, V::mul(f12, f21)),
            V::fmsub(f12, f20, V::mul(f10, f22)),
            V::fmsub(f10, f21, V::mul(f11, f20)),
            V::fmsub(f02, f21, V::mul(f01, f22)),
            V::fmsub(f00, f22, V::mul(f02, f20)),
            V::fmsub(f01, f20, V::mul(f00, f21)),
            V::fmsub(f01, f12, V::mul(f02, f11)),
            V::fmsub(f02, f10, V::mul(f00, f12)),
            V::fmsub(f00, f11, V::mul(f01, f10)),
        ];
        let j = V::fmadd(f02, c[2], V::fmadd(f01, c[1], V::mul(f00, c[0])));
        (c, j)
    }

    /// [`super::estrin9`], the same operations.
    #[inline(always)]
    pub(super) unsafe fn estrin9<V: Lanes>(c: &[f64; 10], x: V) -> V {
        let cc = |i: usize| V::splat(c[i]);
        let x2 = V::mul(x, x);
        let x4 = V::mul(x2, x2);
        let x8 = V::mul(x4, x4);
        let q0 = V::fmadd(cc(1), x, cc(0));
        let q1 = V::fmadd(cc(3), x, cc(2));
        let q2 = V::fmadd(cc(5), x, cc(4));
        let q3 = V::fmadd(cc(7), x, cc(6));
        let q4 = V::fmadd(cc(9), x, cc(8));
        let r0 = V::fmadd(q1, x2, q0);
        let r1 = V::fmadd(q3, x2, q2);
        V::fmadd(q4, x8, V::fmadd(r1, x4, r0))
    }

    /// `ln_series` without the exponent/mantissa split: `2 s + 2 s z p(z) + e ln 2`.
    #[inline(always)]
    pub(super) unsafe fn ln_tail<V: Lanes>(s: V, e: V) -> V {
        let z = V::mul(s, s);
        let pp = estrin9(&super::LN_COEF, z);
        let two = V::splat(2.0);
        let t = V::mul(V::mul(two, s), V::mul(pp, z));
        V::add(
            V::mul(e, V::splat(super::LN2_HI)),
            V::add(
                V::mul(two, s),
                V::add(t, V::mul(e, V::splat(super::LN2_LO))),
            ),
        )
    }

    /// `H[corner][component]` from `V0 P = a F + b cof F` and `Dm⁻¹`.
    #[inline(always)]
    pub(super) unsafe fn corner_forces<V: Lanes>(
        f: &[V; 9],
        c: &[V; 9],
        a: V,
        b: V,
        d: &[V; 9],
    ) -> [[V; 3]; 4] {
        let zero = V::splat(0.0);
        let mut p = [[zero; 3]; 3];
        for i in 0..3 {
            for jj in 0..3 {
                p[i][jj] = V::fmadd(a, f[3 * i + jj], V::mul(b, c[3 * i + jj]));
            }
        }
        let mut h = [[zero; 3]; 4];
        for i in 0..3 {
            let mut acc = zero;
            for jj in 0..3 {
                let hv = V::fmadd(
                    p[i][2],
                    d[3 * jj + 2],
                    V::fmadd(p[i][1], d[3 * jj + 1], V::mul(p[i][0], d[3 * jj])),
                );
                h[jj + 1][i] = hv;
                acc = V::add(acc, hv);
            }
            h[0][i] = V::neg(acc);
        }
        h
    }

    /// `ln x` as [`super::ln_series`], the same operations.
    #[inline(always)]
    pub(super) unsafe fn ln_general<V: Lanes>(j: V) -> V {
        let one = V::splat(1.0);
        let (ef, m) = V::split_exponent(j);
        let big = V::gt(m, V::splat(std::f64::consts::SQRT_2));
        let m = V::select(big, V::mul(V::splat(0.5), m), m);
        let e = V::add(
            V::sub(ef, V::splat(1023.0)),
            V::select(big, one, V::splat(0.0)),
        );
        let s = V::div(V::sub(m, one), V::add(m, one));
        ln_tail(s, e)
    }

    /// `Ds` row-major, `ds[3 i + m] = x_(m+1),i − x_0,i`, from the corners' coordinates
    /// `(cx, cy, cz)[corner]`.
    #[inline(always)]
    pub(super) unsafe fn edges<V: Lanes>(cx: &[V; 4], cy: &[V; 4], cz: &[V; 4]) -> [V; 9] {
        let d = |c: &[V; 4], m: usize| V::sub(c[m], c[0]);
        [
            d(cx, 1),
            d(cx, 2),
            d(cx, 3),
            d(cy, 1),
            d(cy, 2),
            d(cy, 3),
            d(cz, 1),
            d(cz, 2),
            d(cz, 3),
        ]
    }

    /// The positions kernel's corner forces `H[corner][component]`:
    /// `H_i,jj = Σ_m Ds_im G_m,jj + c cof(Ds)_i,jj` for corners 1-3, corner 0 minus their sum;
    /// `gm` is `G` as a full row-major 3 × 3.
    #[inline(always)]
    pub(super) unsafe fn positions_h<V: Lanes>(
        ds: &[V; 9],
        cf: &[V; 9],
        c: V,
        gm: &[V; 9],
    ) -> [[V; 3]; 4] {
        let zero = V::splat(0.0);
        let mut h = [[zero; 3]; 4];
        for i in 0..3 {
            let mut acc = zero;
            for jj in 0..3 {
                let hv = V::fmadd(
                    ds[3 * i + 2],
                    gm[6 + jj],
                    V::fmadd(
                        ds[3 * i + 1],
                        gm[3 + jj],
                        V::fmadd(ds[3 * i], gm[jj], V::mul(c, cf[3 * i + jj])),
                    ),
                );
                h[jj + 1][i] = hv;
                acc = V::add(acc, hv);
            }
            h[0][i] = V::neg(acc);
        }
        h
    }

    /// `ln(1 + f)` as [`super::ln_near1`], the same operations.
    #[inline(always)]
    pub(super) unsafe fn ln_near1<V: Lanes>(f: V) -> V {
        let p = estrin9(&super::LN1P_COEF, f);
        let f2 = V::mul(f, f);
        V::fmadd(f2, p, f)
    }

    /// `(b, ok)`: `b = V0 (λ ln J − μ) / J` with `ln` as [`super::ln_j`], and the lanes
    /// where `J > 0` as bits ([`Lanes::bits`]). The general series (exponent split, a
    /// division) is evaluated only when some lane has `|J − 1| ≥` [`super::LN_NEAR`].
    #[inline(always)]
    pub(super) unsafe fn stress_factor<V: Lanes>(j: V, v0: V, mu: f64, lambda: f64) -> (V, u32) {
        let one = V::splat(1.0);
        let ok = V::bits(V::gt(j, V::splat(0.0)));
        let invj = V::div(one, j);
        let f = V::sub(j, one);
        let near = V::lt(V::abs(f), V::splat(super::LN_NEAR));
        let poly = ln_near1(f);
        let lnj = if V::bits(near) == V::FULL {
            poly
        } else {
            V::select(near, poly, ln_general(j))
        };
        let t = V::sub(V::mul(V::splat(lambda), lnj), V::splat(mu));
        (V::mul(V::mul(v0, t), invj), ok)
    }
}

/// Groups per block of the AVX2 kernel's loop fission.
pub(super) const BLK: usize = 4;

/// The kernel with AVX2 + FMA intrinsics, 4 lanes per group, in three stages over a block
/// of [`BLK`] groups (loop fission: each stage's dependency chain is long, the groups of a
/// block are independent, so the core overlaps them): (A) gather, `F`, `cof F`, `J`;
/// (B) `b = V0 (λ ln J − μ)/J`; (C) `V0 P`, `H`, scatter. Same operations as [`run_groups`],
/// same bits.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn run_groups_avx2<S: Store>(
    groups: &[Group<S>],
    up: *const f64,
    r: *mut f64,
    mu: f64,
    lambda: f64,
) -> bool {
    use std::arch::x86_64::*;
    let zero = _mm256_setzero_pd();
    let vmu = _mm256_set1_pd(mu);
    let mut good = 0xf;
    let mut fbuf = [[zero; 9]; BLK];
    let mut cbuf = [[zero; 9]; BLK];
    let mut jbuf = [zero; BLK];
    let mut dbuf = [[zero; 9]; BLK];
    let mut vbuf = [zero; BLK];
    let load9 = |g: &Group<S>| -> [__m256d; 9] { std::array::from_fn(|q| S::load4(&g.dminv[q])) };
    for chunk in groups.chunks(BLK) {
        for (q, g) in chunk.iter().enumerate() {
            let (cx, cy, cz) = gather4!(up, g.idx);
            // w[k][i] = Du_ik = u_{k+1,i} − u_{0,i}
            let w: [[__m256d; 3]; 3] = std::array::from_fn(|k| {
                [
                    _mm256_sub_pd(cx[k + 1], cx[0]),
                    _mm256_sub_pd(cy[k + 1], cy[0]),
                    _mm256_sub_pd(cz[k + 1], cz[0]),
                ]
            });
            let d = load9(g);
            dbuf[q] = d;
            let f = v4::def_grad(&w, &d);
            let (c, j) = v4::cof_det(&f);
            fbuf[q] = f;
            cbuf[q] = c;
            jbuf[q] = j;
        }
        for (q, g) in chunk.iter().enumerate() {
            let v0 = S::load4(&g.vol);
            vbuf[q] = v0;
            let (b, ok) = v4::stress_factor(jbuf[q], v0, mu, lambda);
            good &= ok;
            jbuf[q] = b;
        }
        for (q, g) in chunk.iter().enumerate() {
            let a = _mm256_mul_pd(vmu, vbuf[q]);
            let h = v4::corner_forces(&fbuf[q], &cbuf[q], a, jbuf[q], &dbuf[q]);
            scatter4!(r, g.idx, h);
        }
    }
    good == 0xf
}

/// Element data prefetched this many blocks of [`BLK`] groups ahead by the positions kernel.
/// Its stages read a group's lines out of order (`idx` and `k` in stage A, `k` again in B,
/// `G` in C), which the hardware prefetcher does not follow: the force pass alone on the 100k
/// standard box (1 thread) ran at 17.7-19.9 M node-evaluations/s without the software
/// prefetch and 28.2-28.5 M with it (1 block ahead 27.2 M, 4 blocks 27.7 M); at 1M, 21.0 M
/// (2 blocks) against 20.0-20.1 M (4 or 8). The displacements kernel, which reads every
/// line of a group in stage A, measured no gain from it (this session and earlier ones).
const PREFETCH_BLOCKS: usize = 2;

/// A second prefetch of the element data, into L2 only, this many blocks ahead: out of
/// cache the first, 2 blocks ahead, comes too late for part of the stream (`perf` on the 1M
/// box: loads of a group's `idx` and `G` took 2.2x their in-cache share of the samples).
/// Fused step, alternated with the build without it (node-updates/s): 1M box 20.8-21.1 M to
/// 21.6-22.4 M on 1 thread and 38.6-39.9 M to 40.0-41.8 M on 2 (4 to 8 blocks ahead alike,
/// 12 to 48 less); 10k and 100k unchanged within noise.
const PREFETCH_L2_BLOCKS: usize = 6;

/// The positions kernels' prefetches at block `bi` (of [`BLK`] groups) of a slab's `groups`:
/// the element data [`PREFETCH_BLOCKS`] blocks ahead into L1 and [`PREFETCH_L2_BLOCKS`] ahead
/// into L2, and the node and force row lines of the block's entry `(pf_ptr, pf_lines)` of
/// the row prefetch schedule ([`row_prefetch_schedule`]).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn prefetch_block(
    groups: &[PGroup],
    bi: usize,
    (pf_ptr, pf_lines): (&[u32], &[u32]),
    xp: *const f64,
    r: *mut f64,
) {
    use std::arch::x86_64::*;
    const LINES: usize = (BLK * std::mem::size_of::<PGroup>()).div_ceil(64);
    let ahead = (bi + PREFETCH_BLOCKS) * BLK;
    if ahead + BLK <= groups.len() {
        let p0 = groups.as_ptr().add(ahead) as *const i8;
        for line in 0..LINES {
            _mm_prefetch::<_MM_HINT_T0>(p0.add(64 * line));
        }
    }
    for &line in &pf_lines[pf_ptr[bi] as usize..pf_ptr[bi + 1] as usize] {
        _mm_prefetch::<_MM_HINT_T0>(xp.add(8 * line as usize) as *const i8);
        _mm_prefetch::<_MM_HINT_T0>(r.add(8 * line as usize) as *const i8);
    }
    let ahead = (bi + PREFETCH_L2_BLOCKS) * BLK;
    if ahead + BLK <= groups.len() {
        let p0 = groups.as_ptr().add(ahead) as *const i8;
        for line in 0..LINES {
            _mm_prefetch::<_MM_HINT_T1>(p0.add(64 * line));
        }
    }
}

/// The positions kernel with AVX2 + FMA intrinsics, 4 lanes per group, in three stages over
/// a block of [`BLK`] groups as [`run_groups_avx2`]: (A) gather, `Ds`, `cof Ds`, `J`;
/// (B) `c = (λ ln J − μ)/(6 J)`; (C) `H = Ds G + c cof Ds`, scatter. Same operations as
/// [`run_positions`], same bits.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn run_positions_avx2(
    groups: &[PGroup],
    pf: (&[u32], &[u32]),
    xp: *const f64,
    r: *mut f64,
    mu: f64,
    lambda: f64,
) -> bool {
    use std::arch::x86_64::*;
    let zero = _mm256_setzero_pd();
    let mut good = 0xf;
    let mut sbuf = [[zero; 9]; BLK];
    let mut cbuf = [[zero; 9]; BLK];
    let mut jbuf = [zero; BLK];
    for (bi, chunk) in groups.chunks(BLK).enumerate() {
        prefetch_block(groups, bi, pf, xp, r);
        for (q, g) in chunk.iter().enumerate() {
            let (cx, cy, cz) = gather4!(xp, g.idx);
            // Ds row-major: ds[3 i + m] = x_{m+1, i} − x_{0, i}.
            let ds = v4::edges(&cx, &cy, &cz);
            let (c, det) = v4::cof_det(&ds);
            sbuf[q] = ds;
            cbuf[q] = c;
            jbuf[q] = _mm256_mul_pd(det, _mm256_load_pd(g.k.as_ptr()));
        }
        for (q, g) in chunk.iter().enumerate() {
            // Padding lanes (k = 0): c = 0, and their J = 0 is no inversion.
            let pad = _mm256_cmp_pd(_mm256_load_pd(g.k.as_ptr()), zero, _CMP_EQ_OQ);
            let (b, ok) = v4::stress_factor(jbuf[q], _mm256_set1_pd(W), mu, lambda);
            good &= ok | _mm256_movemask_pd(pad) as u32;
            jbuf[q] = _mm256_blendv_pd(b, zero, pad);
        }
        for (q, g) in chunk.iter().enumerate() {
            let gg = |i: usize| _mm256_load_pd(g.g[i].as_ptr());
            let gm = [
                gg(0),
                gg(1),
                gg(2),
                gg(1),
                gg(3),
                gg(4),
                gg(2),
                gg(4),
                gg(5),
            ];
            let h = v4::positions_h(&sbuf[q], &cbuf[q], jbuf[q], &gm);
            scatter4!(r, g.idx, h);
        }
    }
    good == 0xf
}

/// The positions kernel with AVX-512, 8 lanes: two consecutive groups of 4 side by side
/// (lanes 0-3 the first, 4-7 the second), in the stages of [`run_positions_avx2`] over the
/// same blocks and with the same prefetches; the scatter adds the first group's rows, then the
/// second's, in [`run_positions_avx2`]'s order. Each lane does the same operations: the same
/// bits. A block's odd last group goes through [`run_positions_avx2`].
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx2,fma")]
unsafe fn run_positions_avx512(
    groups: &[PGroup],
    pf: (&[u32], &[u32]),
    xp: *const f64,
    r: *mut f64,
    mu: f64,
    lambda: f64,
) -> bool {
    use std::arch::x86_64::*;
    const SUB: usize = 2; // prefetch blocks per fission chunk
    const PAIRS: usize = SUB * BLK / 2;
    let zero = _mm512_setzero_pd();
    let mut good = 0xffu32;
    let mut sbuf = [[zero; 9]; PAIRS];
    let mut cbuf = [[zero; 9]; PAIRS];
    let mut jbuf = [zero; PAIRS];
    let mut kbuf = [zero; PAIRS];
    // `permutex2var` indices: lanes 0, 1 of each 256-bit half of `a` and of `b`, and lanes 2, 3.
    let even = _mm512_set_epi64(13, 12, 5, 4, 9, 8, 1, 0);
    let odd = _mm512_set_epi64(15, 14, 7, 6, 11, 10, 3, 2);
    // Rows `[x y z 0]` of lanes 0, 2 (or 1, 3) from the unpacked pairs, and of lanes 4, 6.
    let rows_lo = _mm512_set_epi64(11, 10, 3, 2, 9, 8, 1, 0);
    let rows_hi = _mm512_set_epi64(15, 14, 7, 6, 13, 12, 5, 4);
    let pair = |a: *const f64, b: *const f64| {
        _mm512_insertf64x4::<1>(_mm512_castpd256_pd512(_mm256_load_pd(a)), _mm256_load_pd(b))
    };
    for (ci, chunk) in groups.chunks(SUB * BLK).enumerate() {
        for bi in SUB * ci..(SUB * ci + SUB).min(groups.len().div_ceil(BLK)) {
            prefetch_block(groups, bi, pf, xp, r);
        }
        let pairs = chunk.len() / 2;
        for q in 0..pairs {
            let (ga, gb) = (&chunk[2 * q], &chunk[2 * q + 1]);
            // Corner rows of the 8 lanes, transposed to x, y, z vectors.
            let mut cx = [zero; 4];
            let mut cy = [zero; 4];
            let mut cz = [zero; 4];
            for k in 0..4 {
                let z =
                    |l: usize| pair(xp.add(ga.idx[k][l] as usize), xp.add(gb.idx[k][l] as usize));
                let (z0, z1, z2, z3) = (z(0), z(1), z(2), z(3));
                let t0 = _mm512_unpacklo_pd(z0, z1); // a0x a1x a0z a1z b0x b1x b0z b1z
                let t1 = _mm512_unpackhi_pd(z0, z1); // the same with y, w
                let t2 = _mm512_unpacklo_pd(z2, z3);
                let t3 = _mm512_unpackhi_pd(z2, z3);
                cx[k] = _mm512_permutex2var_pd(t0, even, t2);
                cy[k] = _mm512_permutex2var_pd(t1, even, t3);
                cz[k] = _mm512_permutex2var_pd(t0, odd, t2);
            }
            let ds = v4::edges(&cx, &cy, &cz);
            let (c, det) = v4::cof_det(&ds);
            let k8 = pair(ga.k.as_ptr(), gb.k.as_ptr());
            sbuf[q] = ds;
            cbuf[q] = c;
            kbuf[q] = k8;
            jbuf[q] = _mm512_mul_pd(det, k8);
        }
        for q in 0..pairs {
            // Padding lanes (k = 0): c = 0, and their J = 0 is no inversion.
            let pad = _mm512_cmp_pd_mask::<_CMP_EQ_OQ>(kbuf[q], zero);
            let (b, ok) = v4::stress_factor(jbuf[q], _mm512_set1_pd(W), mu, lambda);
            good &= ok | pad as u32;
            jbuf[q] = _mm512_mask_blend_pd(pad, b, zero);
        }
        for q in 0..pairs {
            let (ga, gb) = (&chunk[2 * q], &chunk[2 * q + 1]);
            let gg = |i: usize| pair(ga.g[i].as_ptr(), gb.g[i].as_ptr());
            let (g0, g1, g2, g3, g4, g5) = (gg(0), gg(1), gg(2), gg(3), gg(4), gg(5));
            let gm = [g0, g1, g2, g1, g3, g4, g2, g4, g5];
            let h = v4::positions_h(&sbuf[q], &cbuf[q], jbuf[q], &gm);
            // Rows [x y z 0] per corner: (lanes 0, 2), (1, 3), (4, 6), (5, 7).
            let mut rows = [[zero; 4]; 4];
            for k in 0..4 {
                let t0 = _mm512_unpacklo_pd(h[k][0], h[k][1]); // x0 y0 x2 y2 x4 y4 x6 y6
                let t1 = _mm512_unpackhi_pd(h[k][0], h[k][1]); // x1 y1 x3 y3 x5 y5 x7 y7
                let t2 = _mm512_unpacklo_pd(h[k][2], zero); // z0 0 z2 0 z4 0 z6 0
                let t3 = _mm512_unpackhi_pd(h[k][2], zero); // z1 0 z3 0 z5 0 z7 0
                rows[k] = [
                    _mm512_permutex2var_pd(t0, rows_lo, t2),
                    _mm512_permutex2var_pd(t1, rows_lo, t3),
                    _mm512_permutex2var_pd(t0, rows_hi, t2),
                    _mm512_permutex2var_pd(t1, rows_hi, t3),
                ];
            }
            let add = |q: *mut f64, row: __m256d| {
                _mm256_store_pd(q, _mm256_add_pd(_mm256_load_pd(q), row));
            };
            for (half, g) in [ga, gb].into_iter().enumerate() {
                for k in 0..4 {
                    let (e, o) = (rows[k][2 * half], rows[k][2 * half + 1]);
                    add(r.add(g.idx[k][0] as usize), _mm512_castpd512_pd256(e));
                    add(r.add(g.idx[k][1] as usize), _mm512_castpd512_pd256(o));
                    add(r.add(g.idx[k][2] as usize), _mm512_extractf64x4_pd::<1>(e));
                    add(r.add(g.idx[k][3] as usize), _mm512_extractf64x4_pd::<1>(o));
                }
            }
        }
        if chunk.len() % 2 == 1 {
            let last = &chunk[chunk.len() - 1..];
            if !run_positions_avx2(last, (&[0, 0], &[]), xp, r, mu, lambda) {
                good = 0;
            }
        }
    }
    good == 0xff
}

/// Coefficients `1/3, 1/5, ..., 1/21` of the atanh series, `p(z) = Σ LN_COEF[i] zⁱ`.
const LN_COEF: [f64; 10] = [
    1.0 / 3.0,
    1.0 / 5.0,
    1.0 / 7.0,
    1.0 / 9.0,
    1.0 / 11.0,
    1.0 / 13.0,
    1.0 / 15.0,
    1.0 / 17.0,
    1.0 / 19.0,
    1.0 / 21.0,
];
/// ln 2 split hi + lo for an accurate `e ln 2`.
const LN2_HI: f64 = 6.931_471_803_691_238e-1;
const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;

/// `Σ c[i] xⁱ`, i = 0..9, by Estrin's scheme (a short dependency chain); the AVX2 kernel's
/// `v4::estrin9` does the same operations.
#[inline(always)]
fn estrin9(c: &[f64; 10], x: f64) -> f64 {
    let x2 = x * x;
    let x4 = x2 * x2;
    let x8 = x4 * x4;
    let q0 = c[1].mul_add(x, c[0]);
    let q1 = c[3].mul_add(x, c[2]);
    let q2 = c[5].mul_add(x, c[4]);
    let q3 = c[7].mul_add(x, c[6]);
    let q4 = c[9].mul_add(x, c[8]);
    let r0 = q1.mul_add(x2, q0);
    let r1 = q3.mul_add(x2, q2);
    q4.mul_add(x8, r1.mul_add(x4, r0))
}

/// Below this `|J − 1|` the kernels take `ln J` from the series of `ln(1 + f)`,
/// [`ln_near1`] (no exponent split, no division); above it from [`ln_series`]. Soft tissue
/// is nearly incompressible (`|J − 1| ≈ (1 − 2ν) tr ε` at small strain), so most elements of
/// a step are below it; removing `ln` altogether measured 18-20 % off the fused step at 10k
/// and 100k nodes, the series keeps about half of that.
pub(crate) const LN_NEAR: f64 = 1.0 / 32.0;

/// `P` of `ln(1 + f) = f + f² P(f)`: `(−1)^(i+1) / (i + 2)`, i = 0..9 (terms to `f¹¹`).
const LN1P_COEF: [f64; 10] = [
    -1.0 / 2.0,
    1.0 / 3.0,
    -1.0 / 4.0,
    1.0 / 5.0,
    -1.0 / 6.0,
    1.0 / 7.0,
    -1.0 / 8.0,
    1.0 / 9.0,
    -1.0 / 10.0,
    1.0 / 11.0,
];

/// `ln(1 + f)` for `|f| <` [`LN_NEAR`] = 2⁻⁵: `f + f² P(f)` with `P` by Estrin's scheme. The
/// first omitted term is below `|f|¹¹/12 ≤ 2⁻⁵⁵/12` relative, `f` is exact (`J − 1` by
/// Sterbenz) and `f² P` at most `2⁻⁶ |f|`, so the error is within about half an ulp plus
/// the rounding of the last addition.
#[inline(always)]
pub(crate) fn ln_near1(f: f64) -> f64 {
    let p = estrin9(&LN1P_COEF, f);
    let f2 = f * f;
    f2.mul_add(p, f)
}

/// `ln J` as the kernels take it: [`ln_near1`]`(J − 1)` when `|J − 1| <` [`LN_NEAR`], else
/// [`ln_series`]`(J)`. Each lane's value depends on its own `J` only.
#[inline(always)]
pub(crate) fn ln_j(j: f64) -> f64 {
    let f = j - 1.0;
    if f.abs() < LN_NEAR {
        ln_near1(f)
    } else {
        ln_series(j)
    }
}

/// ln x for normal positive x, branch-free: `x = m 2^e`, `m ∈ [√½, √2)`,
/// `ln m = 2 atanh s`, `s = (m − 1)/(m + 1)`, series to `s²¹` (|s| ≤ 0.1716), evaluated
/// by Estrin's scheme.
#[inline(always)]
pub(crate) fn ln_series(x: f64) -> f64 {
    let bits = x.to_bits();
    let e = ((bits >> 52) & 0x7ff) as f64 - 1023.0;
    let m = f64::from_bits((bits & 0x000f_ffff_ffff_ffff) | 0x3ff0_0000_0000_0000);
    let big = m > std::f64::consts::SQRT_2;
    let m = if big { 0.5 * m } else { m };
    let e = e + if big { 1.0 } else { 0.0 };
    let s = (m - 1.0) / (m + 1.0);
    let z = s * s;
    let p = estrin9(&LN_COEF, z);
    let t = 2.0 * s * (p * z);
    e * LN2_HI + (2.0 * s + (t + e * LN2_LO))
}

/// Add `h[corner][component][lane]` into the force rows at `idx` (offsets into `r`),
/// corner by corner, lane by lane: the order of the AVX2 kernels' scatter.
#[inline(always)]
unsafe fn scatter_portable(r: *mut f64, idx: &[[u32; LANES]; 4], h: &[[[f64; LANES]; 3]; 4]) {
    for k in 0..4 {
        for l in 0..LANES {
            let n = idx[k][l] as usize;
            *r.add(n) += h[k][0][l];
            *r.add(n + 1) += h[k][1][l];
            *r.add(n + 2) += h[k][2][l];
        }
    }
}

/// The positions kernel, portable: per lane `Ds`, `cof Ds`, `J = det Ds · k`,
/// `c = (λ ln J − μ)/(6 J)`, `H = Ds G + c cof Ds`; the same operations as
/// [`run_positions_avx2`], the same bits.
#[inline(always)]
unsafe fn run_positions(
    groups: &[PGroup],
    x: *const f64,
    r: *mut f64,
    mu: f64,
    lambda: f64,
) -> bool {
    let mut bad = false;
    for g in groups {
        let mut h = [[[0.0f64; LANES]; 3]; 4]; // h[corner][component][lane]
        for l in 0..LANES {
            let p = |k: usize, i: usize| *x.add(g.idx[k][l] as usize + i);
            let ds: [f64; 9] = std::array::from_fn(|q| p(q % 3 + 1, q / 3) - p(0, q / 3));
            let [f00, f01, f02, f10, f11, f12, f20, f21, f22] = ds;
            let c = [
                f11.mul_add(f22, -(f12 * f21)),
                f12.mul_add(f20, -(f10 * f22)),
                f10.mul_add(f21, -(f11 * f20)),
                f02.mul_add(f21, -(f01 * f22)),
                f00.mul_add(f22, -(f02 * f20)),
                f01.mul_add(f20, -(f00 * f21)),
                f01.mul_add(f12, -(f02 * f11)),
                f02.mul_add(f10, -(f00 * f12)),
                f00.mul_add(f11, -(f01 * f10)),
            ];
            let det = f02.mul_add(c[2], f01.mul_add(c[1], f00 * c[0]));
            let j = det * g.k[l];
            // Padding lanes (k = 0): c = 0, and their J = 0 is no inversion.
            let pad = g.k[l] == 0.0;
            bad |= !(j > 0.0) && !pad;
            let inv_j = 1.0 / j;
            let b = if pad {
                0.0
            } else {
                W * (lambda * ln_j(j) - mu) * inv_j
            };
            let gv = |i: usize| g.g[i][l];
            let gm = [
                gv(0),
                gv(1),
                gv(2),
                gv(1),
                gv(3),
                gv(4),
                gv(2),
                gv(4),
                gv(5),
            ];
            for i in 0..3 {
                let mut s = 0.0;
                for jj in 0..3 {
                    let hv = ds[3 * i + 2].mul_add(
                        gm[6 + jj],
                        ds[3 * i + 1]
                            .mul_add(gm[3 + jj], ds[3 * i].mul_add(gm[jj], b * c[3 * i + jj])),
                    );
                    h[jj + 1][i][l] = hv;
                    s += hv;
                }
                h[0][i][l] = -s;
            }
        }
        scatter_portable(r, &g.idx, &h);
    }
    !bad
}

#[inline(always)]
unsafe fn run_groups<S: Store>(
    groups: &[Group<S>],
    u: *const f64,
    r: *mut f64,
    mu: f64,
    lambda: f64,
) -> bool {
    let mut bad = false;
    for g in groups {
        // Gather Du[corner-1][component][lane].
        let mut du = [[[0.0f64; LANES]; 3]; 3];
        for l in 0..LANES {
            let n0 = g.idx[0][l] as usize;
            let (a0, b0, c0) = (*u.add(n0), *u.add(n0 + 1), *u.add(n0 + 2));
            for k in 0..3 {
                let n = g.idx[k + 1][l] as usize;
                du[k][0][l] = *u.add(n) - a0;
                du[k][1][l] = *u.add(n + 1) - b0;
                du[k][2][l] = *u.add(n + 2) - c0;
            }
        }
        let mut h = [[[0.0f64; LANES]; 3]; 4]; // h[corner][component][lane]
        let mut neg = [false; LANES];
        for l in 0..LANES {
            let d = |i: usize, j: usize| g.dminv[3 * i + j][l].get();
            let w = |k: usize, i: usize| du[k][i][l];
            // F_ij = δ_ij + Σ_k Du_ik Dm⁻¹_kj, Du_ik = w(k, i).
            let fm = |i: usize, j: usize| {
                w(2, i).mul_add(d(2, j), w(1, i).mul_add(d(1, j), w(0, i) * d(0, j)))
            };
            let f00 = 1.0 + fm(0, 0);
            let f01 = fm(0, 1);
            let f02 = fm(0, 2);
            let f10 = fm(1, 0);
            let f11 = 1.0 + fm(1, 1);
            let f12 = fm(1, 2);
            let f20 = fm(2, 0);
            let f21 = fm(2, 1);
            let f22 = 1.0 + fm(2, 2);
            let c00 = f11.mul_add(f22, -(f12 * f21));
            let c01 = f12.mul_add(f20, -(f10 * f22));
            let c02 = f10.mul_add(f21, -(f11 * f20));
            let c10 = f02.mul_add(f21, -(f01 * f22));
            let c11 = f00.mul_add(f22, -(f02 * f20));
            let c12 = f01.mul_add(f20, -(f00 * f21));
            let c20 = f01.mul_add(f12, -(f02 * f11));
            let c21 = f02.mul_add(f10, -(f00 * f12));
            let c22 = f00.mul_add(f11, -(f01 * f10));
            let j = f02.mul_add(c02, f01.mul_add(c01, f00 * c00));
            neg[l] = !(j > 0.0);
            let v0 = g.vol[l].get();
            let a = mu * v0;
            let inv_j = 1.0 / j;
            let b = v0 * (lambda * ln_j(j) - mu) * inv_j;
            let p = [
                [
                    a.mul_add(f00, b * c00),
                    a.mul_add(f01, b * c01),
                    a.mul_add(f02, b * c02),
                ],
                [
                    a.mul_add(f10, b * c10),
                    a.mul_add(f11, b * c11),
                    a.mul_add(f12, b * c12),
                ],
                [
                    a.mul_add(f20, b * c20),
                    a.mul_add(f21, b * c21),
                    a.mul_add(f22, b * c22),
                ],
            ];
            for i in 0..3 {
                let mut s = 0.0;
                for jj in 0..3 {
                    // H_i,jj = Σ_k P_ik Dm⁻¹_jj,k
                    let hv =
                        p[i][2].mul_add(d(jj, 2), p[i][1].mul_add(d(jj, 1), p[i][0] * d(jj, 0)));
                    h[jj + 1][i][l] = hv;
                    s += hv;
                }
                h[0][i][l] = -s;
            }
        }
        for &n in &neg {
            bad |= n;
        }
        scatter_portable(r, &g.idx, &h);
    }
    !bad
}
