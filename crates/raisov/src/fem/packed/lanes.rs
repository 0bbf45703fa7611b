//! The vector operations of the SIMD kernels' arithmetic over 4 (AVX2, `__m256d`) or 8
//! (AVX-512, `__m512d`) f64 lanes ([`Lanes`]), so that the arithmetic of
//! [`super::x86`] is written once for both widths. Each lane sees the same IEEE operations
//! whatever the width: the same bits.
//!
//! Every method is `inline(always)`, compiled into its caller's target features (a kernel
//! with `#[target_feature]`); called from elsewhere it would not inline. x86-64 only.

use std::arch::x86_64::{__m256d, __m512d, __mmask8};

/// f64 vector operations over 4 or 8 lanes.
///
/// Every method is `unsafe` with one contract: the CPU must support the instruction set of
/// the implementing type (AVX2 + FMA for `__m256d`; AVX-512F for `__m512d`), which the
/// caller establishes (in this crate: a kernel compiled with those target features and
/// chosen only where [`super::platform::Isa::supported`] reports them).
pub(super) trait Lanes: Copy {
    /// Lanes selected by a comparison.
    type Mask: Copy;
    /// [`Lanes::bits`] with every lane set.
    const FULL: u32;
    /// `x` in every lane.
    ///
    /// # Safety
    /// The CPU supports the implementing type's instruction set ([`Lanes`]).
    unsafe fn splat(x: f64) -> Self;
    /// `a + b`.
    ///
    /// # Safety
    /// The CPU supports the implementing type's instruction set ([`Lanes`]).
    unsafe fn add(a: Self, b: Self) -> Self;
    /// `a − b`.
    ///
    /// # Safety
    /// The CPU supports the implementing type's instruction set ([`Lanes`]).
    unsafe fn sub(a: Self, b: Self) -> Self;
    /// `a b`.
    ///
    /// # Safety
    /// The CPU supports the implementing type's instruction set ([`Lanes`]).
    unsafe fn mul(a: Self, b: Self) -> Self;
    /// `a / b`.
    ///
    /// # Safety
    /// The CPU supports the implementing type's instruction set ([`Lanes`]).
    unsafe fn div(a: Self, b: Self) -> Self;
    /// `a b + c`, one rounding.
    ///
    /// # Safety
    /// The CPU supports the implementing type's instruction set ([`Lanes`]).
    unsafe fn fmadd(a: Self, b: Self, c: Self) -> Self;
    /// `a b − c`, one rounding.
    ///
    /// # Safety
    /// The CPU supports the implementing type's instruction set ([`Lanes`]).
    unsafe fn fmsub(a: Self, b: Self, c: Self) -> Self;
    /// `−a` (sign bit flipped).
    ///
    /// # Safety
    /// The CPU supports the implementing type's instruction set ([`Lanes`]).
    unsafe fn neg(a: Self) -> Self;
    /// `|a|` (sign bit cleared).
    ///
    /// # Safety
    /// The CPU supports the implementing type's instruction set ([`Lanes`]).
    unsafe fn abs(a: Self) -> Self;
    /// `a > b` (ordered).
    ///
    /// # Safety
    /// The CPU supports the implementing type's instruction set ([`Lanes`]).
    unsafe fn gt(a: Self, b: Self) -> Self::Mask;
    /// `a < b` (ordered).
    ///
    /// # Safety
    /// The CPU supports the implementing type's instruction set ([`Lanes`]).
    unsafe fn lt(a: Self, b: Self) -> Self::Mask;
    /// `t` where `m`, else `f`.
    ///
    /// # Safety
    /// The CPU supports the implementing type's instruction set ([`Lanes`]).
    unsafe fn select(m: Self::Mask, t: Self, f: Self) -> Self;
    /// One bit per lane of `m`, lane 0 the lowest.
    ///
    /// # Safety
    /// The CPU supports the implementing type's instruction set ([`Lanes`]).
    unsafe fn bits(m: Self::Mask) -> u32;
    /// `(biased exponent as f64, mantissa in [1, 2))` of positive normal `x`.
    ///
    /// # Safety
    /// The CPU supports the implementing type's instruction set ([`Lanes`]).
    unsafe fn split_exponent(x: Self) -> (Self, Self);
}

/// The arithmetic methods of [`Lanes`], the same for both widths but for the intrinsics'
/// names.
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

impl Lanes for __m256d {
    type Mask = __m256d;
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

impl Lanes for __m512d {
    type Mask = __mmask8;
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
