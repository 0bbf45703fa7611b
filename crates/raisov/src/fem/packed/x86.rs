//! The SIMD kernels: AVX2 + FMA (4 lanes, both storage precisions) and AVX-512 (8 lanes,
//! the positions kernel), with the same operations per lane as [`super::portable`] and
//! hence the same bits.
//!
//! The kernels split the work over a block of [`BLK`] groups into three stages, so that the
//! independent groups of a block overlap in the core (loop fission: each stage's dependency
//! chain is long):
//!
//! ```text
//! positions kernel      (A) gather, Ds, cof Ds, J = det Ds · det Dm⁻¹
//!                       (B) c = (λ ln J − μ) / (6 J)
//!                       (C) H = Ds G + c cof Ds, scatter
//! displacements kernel  (A) gather, F = I + Du Dm⁻¹, cof F, J = det F
//!                       (B) b = V0 (λ ln J − μ) / J
//!                       (C) V0 P = a F + b cof F (a = μ V0), H = V0 P Dm⁻ᵀ, scatter
//! ```
//!
//! `ln J` is [`super::ln`]'s, the general series evaluated only for groups with a lane
//! where `|J − 1| ≥` [`super::ln::LN_NEAR`]. The positions kernel prefetches the element
//! data [`PREFETCH_BLOCKS`] blocks ahead into L1 and [`PREFETCH_L2_BLOCKS`] ahead into L2,
//! and the node and force rows of the row prefetch schedule
//! ([`super::layout::row_prefetch_schedule`]).
//!
//! The AVX-512 positions kernel puts two consecutive groups side by side in 8 lanes, over
//! blocks of 2 × [`BLK`] groups; every lane does the AVX2 kernel's operations (the
//! arithmetic is one generic code over [`Lanes`]) and the scatter adds the first group's
//! rows, then the second's, in the AVX2 order: the same bits on every group count.
//!
//! Node rows are 32 bytes `[x, y, z, 0]` ([`super::Row4`], aligned): one 256-bit load per
//! corner and lane and a 4 × 4 transpose for the gather, a transpose and one 256-bit
//! read-add-write per corner and lane for the scatter. x86-64 only.

use super::groups::{Group, PGroup, Store, W};
use super::lanes::Lanes;
use super::layout::BLK;
use std::arch::x86_64::*;

/// Gather the 4 corners of one group (`idx[corner][lane]`, offsets of 32-byte node rows)
/// as `[x; y; z]` vectors over its 4 lanes: `(cx, cy, cz)`, each `[__m256d; 4]` indexed by
/// corner. One aligned 256-bit load per corner and lane, then a 4 × 4 transpose. Expands to
/// unsafe code: the caller's contract covers `$up` and the offsets.
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
/// aligned 256-bit read-add-write per corner and lane, `[hx, hy, hz, 0]`. Expands to unsafe
/// code: the caller's contract covers `$r` and the offsets.
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

/// The kernels' arithmetic on [`Lanes`] (4 or 8 lanes, the same operations per lane as the
/// portable kernels). Every function has the contract of [`Lanes`]'s methods.
mod arith {
    use super::super::ln::{LN1P_COEF, LN2_HI, LN2_LO, LN_COEF, LN_NEAR};
    use super::Lanes;

    /// `F` (row-major, 9) from `w[k][i] = Du_ik` and `Dm⁻¹` (row-major, 9).
    ///
    /// # Safety
    /// The CPU supports `V`'s instruction set ([`Lanes`]).
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
    ///
    /// # Safety
    /// The CPU supports `V`'s instruction set ([`Lanes`]).
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

    /// `Σ c[i] xⁱ`, i = 0..9, by Estrin's scheme: the operations of [`super::super::ln`]'s
    /// scalar `estrin9`.
    ///
    /// # Safety
    /// The CPU supports `V`'s instruction set ([`Lanes`]).
    #[inline(always)]
    unsafe fn estrin9<V: Lanes>(c: &[f64; 10], x: V) -> V {
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

    /// [`super::super::ln::ln_series`] without the exponent/mantissa split:
    /// `2 s + 2 s z p(z) + e ln 2`.
    ///
    /// # Safety
    /// The CPU supports `V`'s instruction set ([`Lanes`]).
    #[inline(always)]
    unsafe fn ln_tail<V: Lanes>(s: V, e: V) -> V {
        let z = V::mul(s, s);
        let pp = estrin9(&LN_COEF, z);
        let two = V::splat(2.0);
        let t = V::mul(V::mul(two, s), V::mul(pp, z));
        V::add(
            V::mul(e, V::splat(LN2_HI)),
            V::add(V::mul(two, s), V::add(t, V::mul(e, V::splat(LN2_LO)))),
        )
    }

    /// `H[corner][component]` from `V0 P = a F + b cof F` and `Dm⁻¹`.
    ///
    /// # Safety
    /// The CPU supports `V`'s instruction set ([`Lanes`]).
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

    /// `ln x` as [`super::super::ln::ln_series`], the same operations.
    ///
    /// # Safety
    /// The CPU supports `V`'s instruction set ([`Lanes`]).
    #[inline(always)]
    unsafe fn ln_general<V: Lanes>(j: V) -> V {
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
    ///
    /// # Safety
    /// The CPU supports `V`'s instruction set ([`Lanes`]).
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
    ///
    /// # Safety
    /// The CPU supports `V`'s instruction set ([`Lanes`]).
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

    /// `ln(1 + f)` as [`super::super::ln::ln_near1`], the same operations.
    ///
    /// # Safety
    /// The CPU supports `V`'s instruction set ([`Lanes`]).
    #[inline(always)]
    unsafe fn ln_near1<V: Lanes>(f: V) -> V {
        let p = estrin9(&LN1P_COEF, f);
        let f2 = V::mul(f, f);
        V::fmadd(f2, p, f)
    }

    /// `(b, ok)`: `b = V0 (λ ln J − μ) / J` with `ln` as [`super::super::ln::ln_j`], and the
    /// lanes where `J > 0` as bits ([`Lanes::bits`]). The general series (exponent split, a
    /// division) is evaluated only when some lane has `|J − 1| ≥` [`LN_NEAR`].
    ///
    /// # Safety
    /// The CPU supports `V`'s instruction set ([`Lanes`]).
    #[inline(always)]
    pub(super) unsafe fn stress_factor<V: Lanes>(j: V, v0: V, mu: f64, lambda: f64) -> (V, u32) {
        let one = V::splat(1.0);
        let ok = V::bits(V::gt(j, V::splat(0.0)));
        let invj = V::div(one, j);
        let f = V::sub(j, one);
        let near = V::lt(V::abs(f), V::splat(LN_NEAR));
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

/// The displacements kernel with AVX2 + FMA intrinsics, 4 lanes per group, in three stages
/// over a block of [`BLK`] groups: (A) gather, `F`, `cof F`, `J`;
/// (B) `b = V0 (λ ln J − μ)/J`; (C) `V0 P`, `H`, scatter. Same operations as
/// [`super::portable::run_groups`], same bits. Reads displacement rows at `up`, adds into
/// the force rows at `r`; false if some lane has `J <= 0` (or NaN).
///
/// # Safety
/// - The CPU supports AVX2 and FMA.
/// - Every corner offset `idx[k][l]` of `groups` is `4 a` for a node `a` with a row behind
///   both `up` and `r` (rows of four f64, 32-byte aligned, as [`super::Row4`]): `up` valid
///   for reads and `r` for reads and writes of those rows.
/// - No other thread writes the rows read through `up`, or reads or writes the rows of `r`
///   these groups touch, during the call.
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn run_groups_avx2<S: Store>(
    groups: &[Group<S>],
    up: *const f64,
    r: *mut f64,
    mu: f64,
    lambda: f64,
) -> bool {
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
            let f = arith::def_grad(&w, &d);
            let (c, j) = arith::cof_det(&f);
            fbuf[q] = f;
            cbuf[q] = c;
            jbuf[q] = j;
        }
        for (q, g) in chunk.iter().enumerate() {
            let v0 = S::load4(&g.vol);
            vbuf[q] = v0;
            let (b, ok) = arith::stress_factor(jbuf[q], v0, mu, lambda);
            good &= ok;
            jbuf[q] = b;
        }
        for (q, g) in chunk.iter().enumerate() {
            let a = _mm256_mul_pd(vmu, vbuf[q]);
            let h = arith::corner_forces(&fbuf[q], &cbuf[q], a, jbuf[q], &dbuf[q]);
            scatter4!(r, g.idx, h);
        }
    }
    good == 0xf
}

/// Element data prefetched this many blocks of [`BLK`] groups ahead by the positions kernel.
/// Its stages read a group's lines out of order (`idx` and `k` in stage A, `k` again in B,
/// `G` in C), which the hardware prefetcher does not follow. The displacements kernel reads
/// every line of a group in stage A and has no software prefetch.
const PREFETCH_BLOCKS: usize = 2;

/// A second prefetch of the element data, into L2 only, this many blocks ahead: out of
/// cache the first, [`PREFETCH_BLOCKS`] ahead, comes too late for part of the stream.
const PREFETCH_L2_BLOCKS: usize = 6;

/// The positions kernels' prefetches at block `bi` (of [`BLK`] groups) of a slab's `groups`:
/// the element data [`PREFETCH_BLOCKS`] blocks ahead into L1 and [`PREFETCH_L2_BLOCKS`] ahead
/// into L2, and the node and force row lines of the block's entry `(pf_ptr, pf_lines)` of
/// the row prefetch schedule ([`super::layout::row_prefetch_schedule`]).
///
/// # Safety
/// - `pf_ptr` has entries `bi` and `bi + 1`, delimiting a range of `pf_lines`.
/// - Every line `i` listed there has rows `2i` (and `2i + 1`, if it exists) behind both `xp`
///   and `r` (rows of four f64): the pointer arithmetic stays inside those arrays.
///   (Prefetches themselves never fault.)
#[inline(always)]
unsafe fn prefetch_block(
    groups: &[PGroup],
    bi: usize,
    (pf_ptr, pf_lines): (&[u32], &[u32]),
    xp: *const f64,
    r: *mut f64,
) {
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
/// [`super::portable::run_positions`], same bits. Reads position rows `X + u` at `xp`, adds
/// into the force rows at `r`; `pf` is the slab's row prefetch schedule (`pf.0` one entry
/// per block of `groups` and one more). False if some non-padding lane has `J <= 0` (or NaN).
///
/// # Safety
/// - The CPU supports AVX2 and FMA.
/// - Every corner offset of `groups` is `4 a` for a node `a` with a row behind both `xp`
///   and `r` (rows of four f64, 32-byte aligned, as [`super::Row4`]): `xp` valid for reads
///   and `r` for reads and writes of those rows.
/// - `pf` has `groups.len().div_ceil(BLK) + 1` pointers into its lines, and the lines
///   satisfy [`prefetch_block`]'s contract.
/// - No other thread writes the rows read through `xp`, or reads or writes the rows of `r`
///   these groups touch, during the call.
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn run_positions_avx2(
    groups: &[PGroup],
    pf: (&[u32], &[u32]),
    xp: *const f64,
    r: *mut f64,
    mu: f64,
    lambda: f64,
) -> bool {
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
            let ds = arith::edges(&cx, &cy, &cz);
            let (c, det) = arith::cof_det(&ds);
            sbuf[q] = ds;
            cbuf[q] = c;
            jbuf[q] = _mm256_mul_pd(det, _mm256_load_pd(g.k.as_ptr()));
        }
        for (q, g) in chunk.iter().enumerate() {
            // Padding lanes (k = 0): c = 0, and their J = 0 is no inversion.
            let pad = _mm256_cmp_pd(_mm256_load_pd(g.k.as_ptr()), zero, _CMP_EQ_OQ);
            let (b, ok) = arith::stress_factor(jbuf[q], _mm256_set1_pd(W), mu, lambda);
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
            let h = arith::positions_h(&sbuf[q], &cbuf[q], jbuf[q], &gm);
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
///
/// # Safety
/// [`run_positions_avx2`]'s contract, and the CPU supports AVX-512F.
#[target_feature(enable = "avx512f,avx2,fma")]
pub(super) unsafe fn run_positions_avx512(
    groups: &[PGroup],
    pf: (&[u32], &[u32]),
    xp: *const f64,
    r: *mut f64,
    mu: f64,
    lambda: f64,
) -> bool {
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
            let ds = arith::edges(&cx, &cy, &cz);
            let (c, det) = arith::cof_det(&ds);
            let k8 = pair(ga.k.as_ptr(), gb.k.as_ptr());
            sbuf[q] = ds;
            cbuf[q] = c;
            kbuf[q] = k8;
            jbuf[q] = _mm512_mul_pd(det, k8);
        }
        for q in 0..pairs {
            // Padding lanes (k = 0): c = 0, and their J = 0 is no inversion.
            let pad = _mm512_cmp_pd_mask::<_CMP_EQ_OQ>(kbuf[q], zero);
            let (b, ok) = arith::stress_factor(jbuf[q], _mm512_set1_pd(W), mu, lambda);
            good &= ok | pad as u32;
            jbuf[q] = _mm512_mask_blend_pd(pad, b, zero);
        }
        for q in 0..pairs {
            let (ga, gb) = (&chunk[2 * q], &chunk[2 * q + 1]);
            let gg = |i: usize| pair(ga.g[i].as_ptr(), gb.g[i].as_ptr());
            let (g0, g1, g2, g3, g4, g5) = (gg(0), gg(1), gg(2), gg(3), gg(4), gg(5));
            let gm = [g0, g1, g2, g1, g3, g4, g2, g4, g5];
            let h = arith::positions_h(&sbuf[q], &cbuf[q], jbuf[q], &gm);
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
