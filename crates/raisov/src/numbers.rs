//! Numbers in messages: ordinary magnitudes written as usual, huge and tiny ones in
//! scientific notation. Rust's `{}` never uses an exponent, so `1e300` would print as 301
//! digits and `{:.0}` of a huge value as a wall of digits.
//!
//! Ordinary means `1e-4 <= |x| < 1e6` (and zero); NaN and infinities print as `{}` does.

/// Whether `x` prints well without an exponent.
fn ordinary(x: f64) -> bool {
    x == 0.0 || (1e-4..1e6).contains(&x.abs())
}

/// `x` exactly (the shortest text that reads back to it): as `{}` writes it where ordinary,
/// else as `{:e}` (`1e300`, `2.5e-9`).
pub fn compact(x: f64) -> String {
    if ordinary(x) || !x.is_finite() {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// `x` rounded: with `decimals` decimals where `|x| < 1e6`, else in scientific notation with
/// four significant digits (`1.235e300`).
pub fn rounded(x: f64, decimals: usize) -> String {
    if x.abs() < 1e6 || !x.is_finite() {
        format!("{x:.decimals$}")
    } else {
        format!("{x:.3e}")
    }
}

/// A point `[x, y, z]` as `(x, y, z)`, each [`compact`] after rounding to 6 significant
/// digits.
pub fn point(p: [f64; 3]) -> String {
    let r = |x: f64| compact(format!("{x:.5e}").parse().unwrap_or(x));
    format!("({}, {}, {})", r(p[0]), r(p[1]), r(p[2]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn huge_and_tiny_numbers_print_compactly() {
        assert_eq!(compact(1e300), "1e300");
        assert_eq!(compact(-2.5e-9), "-2.5e-9");
        assert_eq!(compact(0.001), "0.001");
        assert_eq!(compact(1234.5), "1234.5");
        assert_eq!(compact(0.0), "0");
        assert_eq!(compact(f64::INFINITY), "inf");
        assert_eq!(rounded(1.23456e300, 0), "1.235e300");
        assert_eq!(rounded(2.26, 1), "2.3");
        assert_eq!(rounded(36.4, 0), "36");
        assert_eq!(point([0.0123456789, -1e300, 0.0]), "(0.0123457, -1e300, 0)");
        for x in [1e300, -1e300, 1e-300, f64::MAX, f64::MIN_POSITIVE] {
            assert!(compact(x).len() <= 24, "{}", compact(x));
            assert!(rounded(x, 1).len() <= 24, "{}", rounded(x, 1));
        }
    }
}
