//! The packed element data: groups of [`LANES`] tetrahedra, structure of arrays, in the two
//! storage precisions, and their packing from the force model's flat arrays.
//!
//! - [`PGroup`] (f64, the positions kernel): corner offsets, `k = det Dm⁻¹` and the six
//!   entries of the symmetric `G = μ V0 Dm⁻¹ Dm⁻ᵀ`, 72 bytes per tetrahedron.
//! - [`Group<f32>`] (f32 storage, the displacements kernel): corner offsets, `Dm⁻¹` and
//!   `V0` rounded to f32, 56 bytes per tetrahedron.
//!
//! Corner offsets are `4 × node id` into the 32-byte node rows ([`super::Row4`]). A padding
//! lane (only in the last group of a slab) repeats the group's first element with zero
//! force: `k = 0, G = 0` or `V0 = 0`.

use super::platform::huge_page_vec;

/// Elements per SIMD group.
pub const LANES: usize = 4;

/// Bytes of element data the force pass streams per tetrahedron with f64 storage (ids, `G`,
/// `det Dm⁻¹`): 72. See [`super::Precision::bytes_per_tet`].
pub const BYTES_PER_TET: usize = std::mem::size_of::<PGroup>() / LANES;

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

/// One group of `LANES` tetrahedra of the displacements kernel, element data stored as `S`.
#[derive(Clone, Copy)]
#[repr(C)]
pub(crate) struct Group<S: Store> {
    _align: [S::Align; 0],
    /// Offsets `4 × node id` of the corners into the node rows, `idx[corner][lane]`.
    pub(super) idx: [[u32; LANES]; 4],
    /// `Dm⁻¹` row-major, `dminv[3 r + c][lane]`.
    pub(super) dminv: [[S; LANES]; 9],
    /// Reference volume (0 for padding lanes).
    pub(super) vol: [S; LANES],
}

const _: () = assert!(std::mem::size_of::<Group<f32>>() == 4 * 56);

/// One group of `LANES` tetrahedra of the positions kernel (f64 storage), structure of
/// arrays. The fields a stage reads first come first: stage A reads `idx` and `k`, stage B
/// `k`, stage C `g` and `idx`. 288 bytes, aligned to 32 (so groups straddle cache lines).
#[derive(Clone, Copy)]
#[repr(C, align(32))]
pub(crate) struct PGroup {
    /// Offsets `4 × node id` of the corners into the node rows, `idx[corner][lane]`.
    pub(super) idx: [[u32; LANES]; 4],
    /// `det Dm⁻¹ = 1 / det Dm > 0`, so that `J = det Ds · k` (0 for padding lanes).
    pub(super) k: [f64; LANES],
    /// `G = μ V0 Dm⁻¹ Dm⁻ᵀ` (symmetric): `G00, G01, G02, G11, G12, G22` (0 for padding lanes).
    pub(super) g: [[f64; LANES]; 6],
}

const _: () = assert!(std::mem::size_of::<PGroup>() == 4 * 72);

/// `V0 det Dm⁻¹ = 1/6` of every tetrahedron (the force model admits positively oriented
/// ones only), the factor of `c = (λ ln J − μ) / (6 J)`.
pub(super) const W: f64 = 1.0 / 6.0;

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

/// Groups of the positions kernel from the lanes of each group (element ids, `None` for
/// padding; [`super::layout::group_lanes`]), `cells` 4 per element, `dminv` 9 per element
/// column-major and `vol` the reference volumes. Padding lanes repeat the group's first
/// element with `k = 0` and `G = 0`: zero force.
pub(super) fn pack_position_groups(
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

/// Groups of the displacements kernel (f32 storage), arguments as
/// [`pack_position_groups`]. Padding lanes repeat the group's first element with zero
/// volume: zero force.
pub(super) fn pack_displacement_groups<S: Store>(
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
