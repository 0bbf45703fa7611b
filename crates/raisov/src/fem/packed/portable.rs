//! The portable kernels: the force pass as plain lane loops, on any CPU, and the simple
//! reference the SIMD kernels of [`super::x86`] are tested against (the same operations in
//! the same order, hence the same bits).
//!
//! Positions kernel (f64 storage), per lane, from the corner positions `x = X + u`:
//!
//! ```text
//! Ds = [x1 − x0, x2 − x0, x3 − x0],   J = det Ds · det Dm⁻¹,   c = (λ ln J − μ) / (6 J)
//! H = Ds G + c cof Ds,   G = μ V0 Dm⁻¹ Dm⁻ᵀ;   R_j += H e_j (j = 1..3),   R_0 −= Σ_j H e_j
//! ```
//!
//! Displacements kernel (f32 storage), per lane, from the corner displacements `u`:
//!
//! ```text
//! F = I + Du Dm⁻¹,   J = det F,   V0 P = a F + b cof F,   a = μ V0,   b = V0 (λ ln J − μ) / J
//! H = V0 P Dm⁻ᵀ
//! ```
//!
//! `ln J` is [`super::ln::ln_j`]. The scatter adds corner by corner, lane by lane, the order
//! of the SIMD kernels' scatter.

use super::groups::{Group, PGroup, Store, LANES, W};
use super::ln::ln_j;

/// Add `h[corner][component][lane]` into the force rows at `idx` (offsets into `r`),
/// corner by corner, lane by lane: the order of the SIMD kernels' scatter.
///
/// # Safety
/// `r` is valid for reads and writes of three f64 at every offset of `idx`, and no other
/// thread accesses them during the call.
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
/// [`super::x86::run_positions_avx2`], the same bits. Reads position rows `X + u` at `x`,
/// adds into the force rows at `r`; false if some non-padding lane has `J <= 0` (or NaN).
///
/// # Safety
/// - Every corner offset of `groups` is `4 a` for a node `a` with a row behind both `x` and
///   `r` (rows of four f64, as [`super::Row4`]): `x` valid for reads and `r` for reads and
///   writes of those rows.
/// - No other thread writes the rows read through `x`, or reads or writes the rows of `r`
///   these groups touch, during the call.
#[inline(always)]
pub(super) unsafe fn run_positions(
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

/// The displacements kernel, portable: per lane `F = I + Du Dm⁻¹`, `cof F`, `J = det F`,
/// `V0 P = a F + b cof F`, `H = V0 P Dm⁻ᵀ`; the same operations as
/// [`super::x86::run_groups_avx2`], the same bits. Reads displacement rows at `u`, adds into
/// the force rows at `r`; false if some lane has `J <= 0` (or NaN).
///
/// # Safety
/// As [`run_positions`], with the displacement rows at `u` in place of the position rows.
#[inline(always)]
pub(super) unsafe fn run_groups<S: Store>(
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
