//! Spectral estimates of a symmetric operator given only its products: the power iteration
//! for the largest eigenvalue of `D⁻¹A` ([`power_iteration`]), and Lanczos steps whose
//! tridiagonal matrix bounds the spectrum from inside ([`lanczos`],
//! [`tridiagonal_extremes`]). FAS's smoother, the grasp tangent's damping and the Chebyshev
//! relaxation estimate their intervals with these; every start vector is the fixed
//! pseudo-random sequence of [`start_entry`], so an estimate is the same on every run and
//! thread count.

/// The entry keyed `key` of the fixed pseudo-random start vector of the power and Lanczos
/// iterations: uniform in `[−0.5, 0.5)`, a Weyl sequence with every frequency present.
pub fn start_entry(key: u64) -> f64 {
    let h = key.wrapping_mul(0x9E37_79B9_7F4A_7C15).rotate_left(17);
    (h >> 11) as f64 / (1u64 << 53) as f64 - 0.5
}

/// The diagonal `D` of [`power_iteration`]'s `D⁻¹A`.
#[derive(Clone, Copy, Debug)]
pub enum Diagonal<'a> {
    /// `D` per node (3 dofs each), divided by.
    Node(&'a [f64]),
    /// `D⁻¹` per dof, multiplied by; a dof whose entry is 0 is left out (a constrained dof).
    InverseDof(&'a [f64]),
}

impl Diagonal<'_> {
    /// `xᵀ D x` over the dofs the diagonal keeps.
    fn norm2(&self, x: &[f64]) -> f64 {
        match self {
            Diagonal::Node(d) => (0..x.len()).map(|i| d[i / 3] * x[i] * x[i]).sum(),
            Diagonal::InverseDof(inv) => (0..x.len())
                .filter(|&i| inv[i] > 0.0)
                .map(|i| x[i] * x[i] / inv[i])
                .sum(),
        }
    }

    /// `D⁻¹ y` at dof `i`.
    fn solve(&self, i: usize, y: f64) -> f64 {
        match self {
            Diagonal::Node(d) => y / d[i / 3],
            Diagonal::InverseDof(inv) => inv[i] * y,
        }
    }
}

/// The largest eigenvalue of `D⁻¹A` by `iterations` power iterations from `x` (left with the
/// last iterate, scaled to a largest entry of 1), `apply(x, y)`: `y = A x`. Each iteration:
///
/// ```text
/// y = A x,   λ = xᵀy / xᵀDx,   x ← D⁻¹y / ‖D⁻¹y‖∞
/// ```
///
/// The Rayleigh quotient approaches the eigenvalue from below. Stops early at a zero or
/// non-finite iterate. Returns the last quotient (0 where none was formed); the caller decides
/// what a non-finite or non-positive one means.
pub fn power_iteration<E>(
    x: &mut [f64],
    diag: Diagonal<'_>,
    iterations: usize,
    y: &mut [f64],
    mut apply: impl FnMut(&[f64], &mut [f64]) -> Result<(), E>,
) -> Result<f64, E> {
    let n = x.len();
    let mut lambda = 0.0;
    for _ in 0..iterations {
        if x.iter().fold(0.0f64, |a, &b| a.max(b.abs())) == 0.0 {
            break;
        }
        apply(x, y)?;
        let xay: f64 = x.iter().zip(y.iter()).map(|(a, b)| a * b).sum();
        let xdx = diag.norm2(x);
        if xdx != 0.0 {
            lambda = xay / xdx;
        } else {
            lambda = f64::NAN;
        }
        let mut norm = 0.0f64;
        for i in 0..n {
            x[i] = diag.solve(i, y[i]);
            norm = norm.max(x[i].abs());
        }
        if norm == 0.0 || !norm.is_finite() {
            break;
        }
        x.iter_mut().for_each(|v| *v /= norm);
    }
    Ok(lambda)
}

/// At most `steps` Lanczos steps on a symmetric operator from the unit vector `q`
/// (`apply(q, w)`: `w = A q`), `q_prev` and `w` scratch of the same length:
///
/// ```text
/// w = A qⱼ − βⱼ₋₁ qⱼ₋₁ − αⱼ qⱼ,   αⱼ = qⱼ·A qⱼ,   βⱼ = ‖w‖₂,   qⱼ₊₁ = w / βⱼ
/// ```
///
/// stopping where `βⱼ ≤ 10⁻¹² |αⱼ|` (an invariant subspace) or is not finite. Returns the
/// tridiagonal matrix's diagonal α and off-diagonal β (`α.len() − 1` entries), whose
/// eigenvalues ([`tridiagonal_extremes`]) lie inside the operator's spectrum.
pub fn lanczos<E>(
    q: &mut Vec<f64>,
    q_prev: &mut Vec<f64>,
    w: &mut [f64],
    steps: usize,
    mut apply: impl FnMut(&[f64], &mut [f64]) -> Result<(), E>,
) -> Result<(Vec<f64>, Vec<f64>), E> {
    let n = q.len();
    let norm = |x: &[f64]| x.iter().map(|v| v * v).sum::<f64>().sqrt();
    q_prev.iter_mut().for_each(|v| *v = 0.0);
    let (mut alpha, mut beta) = (Vec::new(), Vec::new());
    let mut beta_prev = 0.0;
    for _ in 0..steps {
        apply(q, w)?;
        let al: f64 = w.iter().zip(q.iter()).map(|(x, y)| x * y).sum();
        for i in 0..n {
            w[i] -= al * q[i] + beta_prev * q_prev[i];
        }
        alpha.push(al);
        let be = norm(w);
        if be <= 1e-12 * al.abs() || !be.is_finite() {
            break;
        }
        beta.push(be);
        beta_prev = be;
        std::mem::swap(q_prev, q);
        for i in 0..n {
            q[i] = w[i] / be;
        }
    }
    beta.truncate(alpha.len().saturating_sub(1));
    Ok((alpha, beta))
}

/// The smallest and largest eigenvalues of the symmetric tridiagonal matrix with diagonal
/// `alpha` and off-diagonal `beta` (`alpha.len() − 1` entries), by Sturm-sequence bisection
/// inside the Gershgorin bounds.
pub fn tridiagonal_extremes(alpha: &[f64], beta: &[f64]) -> (f64, f64) {
    let m = alpha.len();
    if m == 0 {
        return (f64::NAN, f64::NAN);
    }
    let off = |i: usize| -> f64 {
        let l = if i > 0 { beta[i - 1].abs() } else { 0.0 };
        let r = if i + 1 < m { beta[i].abs() } else { 0.0 };
        l + r
    };
    let glo = (0..m)
        .map(|i| alpha[i] - off(i))
        .fold(f64::INFINITY, f64::min);
    let ghi = (0..m)
        .map(|i| alpha[i] + off(i))
        .fold(f64::NEG_INFINITY, f64::max);
    // Eigenvalues below x: sign changes of the Sturm sequence (LDLᵀ pivots below zero).
    let below = |x: f64| -> usize {
        let mut count = 0;
        let mut p = alpha[0] - x;
        if p < 0.0 {
            count += 1;
        }
        for i in 1..m {
            let pp = if p == 0.0 {
                f64::EPSILON * (ghi - glo).abs().max(1e-300)
            } else {
                p
            };
            p = alpha[i] - x - beta[i - 1] * beta[i - 1] / pp;
            if p < 0.0 {
                count += 1;
            }
        }
        count
    };
    let bisect = |k: usize| -> f64 {
        // The (k+1)-th smallest eigenvalue: the smallest x with below(x) > k.
        let (mut lo, mut hi) = (glo, ghi);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if mid <= lo || mid >= hi {
                break;
            }
            if below(mid) > k {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        0.5 * (lo + hi)
    };
    (bisect(0), bisect(m - 1))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The extremes of a tridiagonal matrix whose eigenvalues are known in closed form:
    /// `tridiag(−1, 2, −1)` of order m has `2 − 2 cos(jπ/(m+1))`, j = 1..m.
    #[test]
    fn tridiagonal_extremes_match_the_closed_form() {
        let m = 30;
        let (lo, hi) = tridiagonal_extremes(&vec![2.0; m], &vec![-1.0; m - 1]);
        let exact = |j: usize| 2.0 - 2.0 * (j as f64 * std::f64::consts::PI / (m + 1) as f64).cos();
        assert!((lo - exact(1)).abs() <= 1e-12, "{lo} against {}", exact(1));
        assert!((hi - exact(m)).abs() <= 1e-12, "{hi} against {}", exact(m));
        // A 1x1 matrix, and an uncoupled one.
        assert_eq!(tridiagonal_extremes(&[3.0], &[]), (3.0, 3.0));
        let (lo, hi) = tridiagonal_extremes(&[5.0, -1.0, 2.0], &[0.0, 0.0]);
        assert!(
            (lo + 1.0).abs() < 1e-12 && (hi - 5.0).abs() < 1e-12,
            "{lo} {hi}"
        );
    }

    /// `tridiag(−1, 2, −1)` of order n as a product.
    fn laplace(x: &[f64], y: &mut [f64]) -> Result<(), ()> {
        let n = x.len();
        for i in 0..n {
            let l = if i > 0 { x[i - 1] } else { 0.0 };
            let r = if i + 1 < n { x[i + 1] } else { 0.0 };
            y[i] = 2.0 * x[i] - l - r;
        }
        Ok(())
    }

    #[test]
    fn power_iteration_and_lanczos_find_the_largest_eigenvalue_of_a_laplacian() {
        let n = 40;
        let exact = 2.0 - 2.0 * (n as f64 * std::f64::consts::PI / (n + 1) as f64).cos();
        // D = 2 I (per node, 3 dofs each): D⁻¹A has exact / 2.
        let d = vec![2.0; n / 3 + 1];
        let mut x: Vec<f64> = (0..n as u64).map(start_entry).collect();
        let mut y = vec![0.0; n];
        let lambda = power_iteration(&mut x, Diagonal::Node(&d), 2000, &mut y, laplace).unwrap();
        assert!(lambda <= 0.5 * exact * (1.0 + 1e-12), "{lambda} from below");
        assert!(
            (lambda - 0.5 * exact).abs() < 1e-3 * exact,
            "{lambda} against {}",
            0.5 * exact
        );
        // The same with D⁻¹ per dof: the same iterates, by multiplication.
        let inv = vec![0.5; n];
        let mut x2: Vec<f64> = (0..n as u64).map(start_entry).collect();
        let l2 =
            power_iteration(&mut x2, Diagonal::InverseDof(&inv), 2000, &mut y, laplace).unwrap();
        assert!((l2 - lambda).abs() <= 1e-12 * lambda);
        // Lanczos: 20 steps bracket the spectrum from inside; n steps reach its ends.
        let mut q: Vec<f64> = (0..n as u64).map(start_entry).collect();
        let q0 = q.iter().map(|v| v * v).sum::<f64>().sqrt();
        q.iter_mut().for_each(|v| *v /= q0);
        let (mut qp, mut w) = (vec![0.0; n], vec![0.0; n]);
        let start = q.clone();
        let (a, b) = lanczos(&mut q, &mut qp, &mut w, 20, laplace).unwrap();
        let (lo, hi) = tridiagonal_extremes(&a, &b);
        let smallest = 2.0 - 2.0 * (std::f64::consts::PI / (n + 1) as f64).cos();
        assert!(
            lo >= smallest * (1.0 - 1e-9) && hi <= exact * (1.0 + 1e-12),
            "{lo} {hi}"
        );
        assert!((hi - exact).abs() < 1e-3 * exact, "{hi} against {exact}");
        let mut q = start;
        let (a, b) = lanczos(&mut q, &mut qp, &mut w, n, laplace).unwrap();
        let (lo, hi) = tridiagonal_extremes(&a, &b);
        assert!((hi - exact).abs() < 1e-9 * exact, "{hi} against {exact}");
        assert!(
            (lo - smallest).abs() < 1e-6 * smallest,
            "{lo} against {smallest}"
        );
    }
}
