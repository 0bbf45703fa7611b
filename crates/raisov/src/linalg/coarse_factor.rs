//! The coarsest Galerkin level's sparse Cholesky factorisation, the exact coarse solve of
//! [`super::galerkin`]'s V-cycle.
//!
//! ```text
//! A_c + σ d̄ I = L Lᵀ,        z_c = (L Lᵀ)⁻¹ b_c
//! ```
//!
//! `A_c` the coarsest Galerkin operator, `d̄` its mean diagonal, σ the smallest of
//! [`FIRST_SHIFT`] = 10⁻¹², 10⁻⁶, 10⁻⁴, …, 10⁶ at which it factors (faer's supernodal or
//! simplicial `LLᵀ` after a fill-reducing ordering). The ladder starts just above 0: a
//! Galerkin operator `PᵀAP` is singular to rounding wherever `P`'s columns are nearly
//! dependent, as on the liver L1's and the heart's coarsest levels, whose last pivots rounded
//! to or below zero unshifted, and each failed try is a whole numeric factorisation. A shift of
//! 10⁻¹² `d̄` lifts such pivots and changes the coarse solve far less than the factor's
//! rounding to `f32` does; 10⁻⁶ `d̄` already moves the soft, near-rigid modes the coarse level
//! is there for (the liver L0's conjugate gradients took 69 iterations against 65).
//!
//! [`Precision::Single`] (the default) solves in `f32`: the two triangular solves read the
//! whole factor per V-cycle (4.2 M values for the liver L1's 2 088-node coarsest level), and
//! single precision halves that traffic. Its factor is computed in `f32` at the first shift,
//! where that factors: the factorisation's dense supernode updates then move half the bytes and
//! run twice the lanes per instruction. Cholesky is backward stable, so the computed `L̃` is
//! the exact factor of a matrix within a small multiple of `10⁻⁷ |L̃||L̃ᵀ|` of
//! `A_c + σ d̄ I`, as the `f64` factor rounded to `f32` is; `L̃` has a positive diagonal, so
//! `L̃ L̃ᵀ` is symmetric positive definite whatever `A_c`'s conditioning, and the V-cycle stays
//! a symmetric positive definite preconditioner, within far less than what conjugate
//! gradients' inexact-Newton tolerance asks of it. Where a pivot is not positive in `f32`
//! (an operator singular to rounding, whose last pivots `f32`'s round-off decides, or an
//! indefinite one) the ladder runs in `f64` and its factor is rounded to `f32`.
//! [`Precision::Double`] is the reference: factored and solved in `f64`.
//!
//! Every factorisation runs on one thread: the same bits on any thread count.

use super::sparse::Csr;

/// Why the coarsest level could not be factored.
#[derive(Debug, thiserror::Error)]
pub enum FactorError {
    /// The Cholesky factor would not fit in the available memory ([`crate::memory`]); the
    /// message names both sizes.
    #[error("{0}")]
    Memory(String),
    /// The coarsest operator does not factor, even shifted.
    #[error("{0}")]
    Factor(String),
}
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, LltRef, SymbolicCholesky};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMat, SymbolicSparseColMatRef};
use faer::{Conj, Par, Side};
use std::sync::Arc;

/// The first diagonal shift, relative to the mean diagonal, the coarsest operator is factored
/// with (module docs).
pub const FIRST_SHIFT: f64 = 1e-12;

/// The coarsest level's symbolic factorisation (its ordering and the factor's pattern), kept
/// across numeric factorisations on the same pattern.
pub type CoarseSymbolic = Arc<SymbolicCholesky<usize>>;

/// The precision of the coarse solve (module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Precision {
    /// Factored in `f32` at the first shift where every pivot is positive there, else in
    /// `f64` and rounded to `f32`; solved in `f32` (the default).
    #[default]
    Single,
    /// Factored and solved in `f64` (the reference).
    Double,
}

/// The factor's values in the precision of its solves.
enum Values {
    Single(Vec<f32>),
    Double(Vec<f64>),
}

/// A sparse Cholesky factorisation of a coarsest operator.
pub(crate) struct CoarseFactor {
    symbolic: CoarseSymbolic,
    values: Values,
    /// The shift it needed to factor, relative to the operator's mean diagonal.
    pub shift: f64,
}

impl CoarseFactor {
    /// Sparse Cholesky of `a` (its lower triangle), shifting the diagonal by `σ d̄` (`d̄` the
    /// mean diagonal; σ = [`FIRST_SHIFT`] = 10⁻¹², then 10⁻⁶, 10⁻⁴, …, 10⁶) until it factors.
    /// Each try is a whole numeric factorisation (an indefinite operator's failing pivot comes
    /// late), so the shift rises a hundredfold a try (the liver L0's coarsest operator at an
    /// indefinite state factors only at 1); [`Precision::Single`] tries the first shift in
    /// `f32` before the ladder in `f64` (module docs). `symbolic`, from an earlier call on the
    /// same pattern, is reused where given and filled in where not, after checking that the
    /// factor fits in the available memory ([`FactorError::Memory`]).
    pub fn new(
        a: &Csr,
        symbolic: &mut Option<CoarseSymbolic>,
        precision: Precision,
    ) -> Result<Self, FactorError> {
        let n = a.rows;
        let diag = a.diagonal();
        let dbar = diag.iter().map(|d| d.abs()).sum::<f64>() / n.max(1) as f64;
        // The lower triangle in compressed columns: column j is row j's entries from the
        // diagonal on (A is symmetric), row indices ascending, the diagonal first.
        let mut col_ptr = Vec::with_capacity(n + 1);
        col_ptr.push(0usize);
        let mut row_idx = Vec::with_capacity(a.col.len() / 2 + n);
        let mut vals = Vec::with_capacity(a.col.len() / 2 + n);
        let mut diag_at = Vec::with_capacity(n);
        for j in 0..n {
            let (c, v) = a.row(j);
            let start = c.partition_point(|&k| (k as usize) < j);
            if c.get(start) != Some(&(j as u32)) {
                return Err(FactorError::Factor(
                    "the coarsest Galerkin operator lacks a diagonal entry".into(),
                ));
            }
            diag_at.push(vals.len());
            row_idx.extend(c[start..].iter().map(|&k| k as usize));
            vals.extend_from_slice(&v[start..]);
            col_ptr.push(row_idx.len());
        }
        let pattern = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
        let fail = |e: &dyn std::fmt::Debug| FactorError::Factor(format!("{e:?}"));
        let symbolic = match symbolic {
            Some(s) => s.clone(),
            None => {
                let s = factorize_symbolic_cholesky(
                    pattern.as_ref(),
                    Side::Lower,
                    Default::default(),
                    Default::default(),
                )
                .map_err(|e| fail(&e))?;
                // The factor's values, and as much again for the numeric factorisation's
                // workspace.
                crate::memory::check(
                    &format!(
                        "the coarsest Galerkin level's Cholesky factor ({n} dofs, {} nonzeros)",
                        s.len_val()
                    ),
                    16 * s.len_val() as u64,
                )
                .map_err(FactorError::Memory)?;
                symbolic.insert(Arc::new(s)).clone()
            }
        };
        // Where the factor is to be solved in `f32`, it is first computed in `f32`, at the
        // first shift (module docs).
        if precision == Precision::Single {
            let v: Vec<f32> = shifted(&vals, &diag_at, FIRST_SHIFT * dbar)
                .map(|x| x as f32)
                .collect();
            if let Some(l) = numeric(&symbolic, pattern.as_ref(), &v).map_err(|e| fail(&e))? {
                return Ok(CoarseFactor {
                    symbolic,
                    values: Values::Single(l),
                    shift: FIRST_SHIFT,
                });
            }
        }
        let mut sigma = FIRST_SHIFT;
        let l = loop {
            let v: Vec<f64> = shifted(&vals, &diag_at, sigma * dbar).collect();
            if let Some(l) = numeric(&symbolic, pattern.as_ref(), &v).map_err(|e| fail(&e))? {
                break l;
            }
            if sigma >= 1e6 {
                return Err(FactorError::Factor(
                    "the coarsest Galerkin operator does not factor even shifted by 1e6 times \
                     its mean diagonal"
                        .into(),
                ));
            }
            sigma = if sigma < 1e-6 { 1e-6 } else { 100.0 * sigma };
        };
        let values = match precision {
            Precision::Double => Values::Double(l),
            Precision::Single => Values::Single(l.iter().map(|&x| x as f32).collect()),
        };
        Ok(CoarseFactor {
            symbolic,
            values,
            shift: sigma,
        })
    }

    /// `z = (L Lᵀ)⁻¹ b`.
    pub fn solve(&self, b: &[f64], z: &mut [f64]) {
        match &self.values {
            Values::Double(l) => {
                let mut m = faer::Mat::<f64>::from_fn(b.len(), 1, |i, _| b[i]);
                self.solve_in_place(l, m.as_mut());
                z.iter_mut().enumerate().for_each(|(i, zi)| *zi = m[(i, 0)]);
            }
            Values::Single(l) => {
                let mut m = faer::Mat::<f32>::from_fn(b.len(), 1, |i, _| b[i] as f32);
                self.solve_in_place(l, m.as_mut());
                z.iter_mut()
                    .enumerate()
                    .for_each(|(i, zi)| *zi = m[(i, 0)] as f64);
            }
        }
    }

    fn solve_in_place<T: faer::traits::ComplexField>(&self, l: &[T], rhs: faer::MatMut<'_, T>) {
        let par = Par::Seq;
        let mut scratch = MemBuffer::new(self.symbolic.solve_in_place_scratch::<T>(1, par));
        LltRef::<'_, usize, T>::new(&self.symbolic, l).solve_in_place_with_conj(
            Conj::No,
            rhs,
            par,
            MemStack::new(&mut scratch),
        );
    }
}

/// The lower triangle's values with `shift` added at the diagonal entries `diag_at`
/// (ascending).
fn shifted<'a>(
    vals: &'a [f64],
    diag_at: &'a [usize],
    shift: f64,
) -> impl Iterator<Item = f64> + 'a {
    let mut next = diag_at.iter().peekable();
    vals.iter().enumerate().map(move |(k, &v)| {
        if next.peek() == Some(&&k) {
            next.next();
            v + shift
        } else {
            v
        }
    })
}

/// The numeric Cholesky factor of `vals` on `pattern`, in the precision `T`, on one thread (the
/// same bits on any thread count); `None` where a pivot is not positive.
fn numeric<T: faer::traits::ComplexField + Default + Copy>(
    symbolic: &SymbolicCholesky<usize>,
    pattern: SymbolicSparseColMatRef<'_, usize>,
    vals: &[T],
) -> Result<Option<Vec<T>>, faer::dyn_stack::mem::AllocError> {
    let par = Par::Seq;
    let mut scratch =
        MemBuffer::try_new(symbolic.factorize_numeric_llt_scratch::<T>(par, Default::default()))?;
    let mut l = vec![T::default(); symbolic.len_val()];
    let ok = symbolic
        .factorize_numeric_llt::<T>(
            &mut l,
            SparseColMatRef::new(pattern, vals),
            Side::Lower,
            Default::default(),
            par,
            MemStack::new(&mut scratch),
            Default::default(),
        )
        .is_ok();
    Ok(ok.then_some(l))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 1-D Laplacian of `n` points plus `c` on the diagonal.
    fn laplace(n: usize, c: f64) -> Csr {
        let mut a = crate::linalg::galerkin::tests::laplace(n);
        for i in 0..n {
            let (cols, _) = a.row(i);
            let k = a.ptr[i] + cols.iter().position(|&j| j as usize == i).unwrap();
            a.val[k] += c;
        }
        a
    }

    /// The Neumann Laplacian of a path of `n` points: constants are its kernel.
    fn neumann(n: usize) -> Csr {
        let mut a = laplace(n, 0.0);
        for r in [0, n - 1] {
            let k = a.ptr[r] + a.row(r).0.iter().position(|&j| j as usize == r).unwrap();
            a.val[k] = 1.0;
        }
        a
    }

    fn norm(x: impl Iterator<Item = f64>) -> f64 {
        x.map(|v| v * v).sum::<f64>().sqrt()
    }

    /// A positive definite operator factors at the first shift, and the double-precision
    /// factor solves `(A + 10⁻¹² d̄ I) z = b` to round-off; the rounded one to the `f32` solve's
    /// round-off amplified by `A`'s conditioning (κ ≈ 4·10², so well within 10⁻⁴), and both
    /// reuse one symbolic factorisation.
    #[test]
    fn single_precision_solve_is_within_its_round_off_of_the_double_one() {
        let n = 40;
        let a = laplace(n, 0.0);
        let b: Vec<f64> = (0..n).map(|i| 1.0 + (i as f64 * 0.37).sin()).collect();
        let mut symbolic = None;
        let double = CoarseFactor::new(&a, &mut symbolic, Precision::Double).unwrap();
        assert!(symbolic.is_some());
        let single = CoarseFactor::new(&a, &mut symbolic, Precision::Single).unwrap();
        assert_eq!((double.shift, single.shift), (FIRST_SHIFT, FIRST_SHIFT));
        let (mut zd, mut zs) = (vec![0.0; n], vec![0.0; n]);
        double.solve(&b, &mut zd);
        single.solve(&b, &mut zs);
        let dbar = a.diagonal().iter().sum::<f64>() / n as f64;
        let mut az = vec![0.0; n];
        a.matvec(&zd, &mut az);
        for (y, z) in az.iter_mut().zip(&zd) {
            *y += FIRST_SHIFT * dbar * z;
        }
        let bnorm = norm(b.iter().copied());
        let res = norm(az.iter().zip(&b).map(|(x, y)| x - y));
        assert!(res < 1e-12 * bnorm, "double residual {res}");
        let znorm = norm(zd.iter().copied());
        let diff = norm(zd.iter().zip(&zs).map(|(x, y)| x - y));
        assert!(diff < 1e-4 * znorm, "single differs by {diff} of {znorm}");
        assert!(diff > 0.0, "the single-precision solve is not rounded");
    }

    /// Single precision factors in `f32` where every pivot is positive there: its factor is
    /// not the double one rounded, yet within `f32`'s round-off amplified by the pivots'
    /// growth of it; an operator singular to rounding falls back to the double ladder, whose
    /// first shift works, and its factor is the double one rounded.
    #[test]
    fn single_precision_factors_in_f32_and_falls_back_to_the_double_ladder() {
        let n = 40;
        let values = |f: &CoarseFactor| match &f.values {
            Values::Single(l) => l.clone(),
            Values::Double(_) => panic!("a single-precision factor holds f64 values"),
        };
        let double_l = |f: &CoarseFactor| match &f.values {
            Values::Double(l) => l.clone(),
            Values::Single(_) => panic!("a double-precision factor holds f32 values"),
        };
        let a = laplace(n, 0.0);
        let mut symbolic = None;
        let double = CoarseFactor::new(&a, &mut symbolic, Precision::Double).unwrap();
        let single = CoarseFactor::new(&a, &mut symbolic, Precision::Single).unwrap();
        let (ld, ls) = (double_l(&double), values(&single));
        let lmax = ld.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let gap = ld
            .iter()
            .zip(&ls)
            .fold(0.0f64, |m, (d, s)| m.max((d - *s as f64).abs()));
        assert!(
            ld.iter().zip(&ls).any(|(d, s)| *d as f32 != *s),
            "the single factor is the double one rounded"
        );
        assert!(gap < 1e-5 * lmax, "f32 factor {gap:e} from the f64 one");
        let b = neumann(n);
        let single = CoarseFactor::new(&b, &mut None, Precision::Single).unwrap();
        let double = CoarseFactor::new(&b, &mut None, Precision::Double).unwrap();
        assert_eq!((single.shift, double.shift), (FIRST_SHIFT, FIRST_SHIFT));
        let rounded: Vec<f32> = double_l(&double).iter().map(|&x| x as f32).collect();
        assert_eq!(
            values(&single),
            rounded,
            "not the f64 ladder's factor, rounded"
        );
    }

    /// An indefinite operator factors once shifted enough: the shift is the first of 10⁻¹²,
    /// 10⁻⁶, 10⁻⁴, … (of the mean diagonal) that makes it positive definite.
    #[test]
    fn indefinite_operator_factors_with_the_smallest_shift_that_works() {
        // Eigenvalues of the Laplacian part lie in (0, 4); adding −0.5 leaves the lowest
        // one, about 2 − 2 cos(π/41) − 0.5 < 0, negative, and a shift σ d̄ (d̄ = 1.5) must
        // exceed about 0.5: σ = 1 is the first that does.
        let a = laplace(40, -0.5);
        let f = CoarseFactor::new(&a, &mut None, Precision::Single).unwrap();
        assert!((f.shift - 1.0).abs() < 1e-12, "shift {}", f.shift);
    }

    /// A positive semidefinite operator, singular as a Galerkin operator with nearly dependent
    /// columns is to rounding, factors at the first shift: a path's Neumann Laplacian, whose
    /// constants it maps to 0. Unshifted, the last pivot is rounding's to decide.
    #[test]
    fn coarse_operator_singular_to_rounding_factors_at_the_first_shift() {
        let n = 40;
        let a = neumann(n);
        let ones = vec![1.0; n];
        let mut a1 = vec![0.0; n];
        a.matvec(&ones, &mut a1);
        assert!(a1.iter().all(|&v| v == 0.0), "not singular: {a1:?}");
        let f = CoarseFactor::new(&a, &mut None, Precision::Double).unwrap();
        assert_eq!(f.shift, FIRST_SHIFT);
    }
}
