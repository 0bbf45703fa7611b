//! `ln J` as the packed kernels take it: scalar reference functions and their constants.
//!
//! ```text
//! ln J = ln(1 + f) = f + f² P(f),      f = J − 1,  |f| < 2⁻⁵   (no division)
//! ln x = e ln 2 + 2 atanh s,           x = m 2^e,  m ∈ [√½, √2),  s = (m − 1)/(m + 1)
//! ```
//!
//! Nearly incompressible tissue keeps almost every element in the first range; the second
//! is branch-free (exponent split, one division) and the SIMD kernels evaluate it only for
//! groups with a lane outside the first. Both polynomials are evaluated by Estrin's scheme
//! (a short dependency chain); both are within 1 ulp of `f64::ln` on the tested sweeps (2 ulp
//! asserted). The vector versions in [`super::x86`] do the same operations lane by lane: the
//! same bits.

/// Coefficients `1/3, 1/5, ..., 1/21` of the atanh series, `p(z) = Σ LN_COEF[i] zⁱ`.
pub(super) const LN_COEF: [f64; 10] = [
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
pub(super) const LN2_HI: f64 = 6.931_471_803_691_238e-1;
pub(super) const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;

/// `Σ c[i] xⁱ`, i = 0..9, by Estrin's scheme (a short dependency chain); the SIMD kernels'
/// `estrin9` does the same operations.
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
/// a step are below it.
pub(crate) const LN_NEAR: f64 = 1.0 / 32.0;

/// `P` of `ln(1 + f) = f + f² P(f)`: `(−1)^(i+1) / (i + 2)`, i = 0..9 (terms to `f¹¹`).
pub(super) const LN1P_COEF: [f64; 10] = [
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
