//! Sparse matrices: compressed rows ([`Csr`], column indices ascending within a row), their
//! products in a fixed order, and the scatter of a symmetric matrix's lower triangle
//! (compressed columns, as faer keeps it) into full rows ([`SymScatter`]).
//!
//! Every product is split into row blocks that are independent and each row is accumulated
//! in a fixed order (`row_dot`): the same bits on any thread count.

use faer::sparse::SparseColMat;
use rayon::prelude::*;

/// Rows per parallel block of the products.
const ROW_BLOCK: usize = 512;

/// Full entries per task of [`SymScatter::fill`].
const FILL_BLOCK: usize = 1 << 14;

/// A stored matrix value: `f64`, or `f32` for the smoothers' copy (module docs); read as `f64`.
pub trait Entry: Copy + Send + Sync {
    /// The value in double precision.
    fn get(self) -> f64;
}

impl Entry for f64 {
    #[inline(always)]
    fn get(self) -> f64 {
        self
    }
}

impl Entry for f32 {
    #[inline(always)]
    fn get(self) -> f64 {
        self as f64
    }
}

/// `Σ_k v_k x_{c_k}`, one sparse row times a dense vector: four partial sums over the entries
/// `k ≡ 0, 1, 2, 3 (mod 4)`, added as `(s₀ + s₁) + (s₂ + s₃)`. The order is fixed by the row
/// alone (the same bits on any thread count); four sums instead of one keep four additions in
/// flight rather than waiting on each one's result.
#[inline(always)]
pub(crate) fn row_dot<V: Entry>(cols: &[u32], vals: &[V], x: &[f64]) -> f64 {
    let mut s = [0.0f64; 4];
    let (c4, v4) = (cols.chunks_exact(4), vals.chunks_exact(4));
    let (ct, vt) = (c4.remainder(), v4.remainder());
    for (c, v) in c4.zip(v4) {
        for q in 0..4 {
            s[q] += v[q].get() * x[c[q] as usize];
        }
    }
    for (q, (&c, &v)) in ct.iter().zip(vt).enumerate() {
        s[q] += v.get() * x[c as usize];
    }
    (s[0] + s[1]) + (s[2] + s[3])
}

/// A sparse matrix in compressed rows, column indices ascending within a row.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Csr {
    /// Number of rows.
    pub rows: usize,
    /// Number of columns.
    pub cols: usize,
    /// Start of each row in `col` and `val`; `rows + 1` entries.
    pub ptr: Vec<usize>,
    /// Column of each entry.
    pub col: Vec<u32>,
    /// Value of each entry.
    pub val: Vec<f64>,
}

impl Csr {
    /// The full symmetric matrix whose lower triangle `a` holds in compressed columns (row
    /// indices ascending within a column, as faer keeps them).
    pub fn from_sym_lower(a: &SparseColMat<usize, f64>) -> Csr {
        let scatter = SymScatter::new(a.nrows(), a.symbolic().col_ptr(), a.symbolic().row_idx());
        let mut c = scatter.pattern.clone();
        scatter.fill(a.val(), &mut c);
        c
    }

    /// Row `i`: its columns and values.
    #[inline]
    pub(crate) fn row(&self, i: usize) -> (&[u32], &[f64]) {
        self.row_of(&self.val, i)
    }

    /// Row i's columns and its entries of `vals`, values on this pattern (`self.val` or a
    /// rounded copy of it).
    #[inline(always)]
    pub(crate) fn row_of<'a, V>(&'a self, vals: &'a [V], i: usize) -> (&'a [u32], &'a [V]) {
        let r = self.ptr[i]..self.ptr[i + 1];
        (&self.col[r.clone()], &vals[r])
    }

    /// `y = A x`.
    pub fn matvec(&self, x: &[f64], y: &mut [f64]) {
        self.matvec_of(&self.val, x, y)
    }

    /// `y = A x` with `vals` for A's values on this pattern.
    pub(crate) fn matvec_of<V: Entry>(&self, vals: &[V], x: &[f64], y: &mut [f64]) {
        y.par_chunks_mut(ROW_BLOCK)
            .enumerate()
            .for_each(|(b, out)| {
                for (j, yi) in out.iter_mut().enumerate() {
                    let (c, v) = self.row_of(vals, b * ROW_BLOCK + j);
                    *yi = row_dot(c, v, x);
                }
            });
    }

    /// `y += A x`, serial.
    pub(crate) fn matvec_add(&self, x: &[f64], y: &mut [f64]) {
        for (i, yi) in y.iter_mut().enumerate().take(self.rows) {
            let (c, v) = self.row(i);
            *yi += c
                .iter()
                .zip(v)
                .map(|(&k, &a)| a * x[k as usize])
                .sum::<f64>();
        }
    }

    /// The transpose.
    pub fn transpose(&self) -> Csr {
        let mut ptr = vec![0usize; self.cols + 1];
        for &c in &self.col {
            ptr[c as usize + 1] += 1;
        }
        for i in 0..self.cols {
            ptr[i + 1] += ptr[i];
        }
        let mut next = ptr[..self.cols].to_vec();
        let mut col = vec![0u32; self.col.len()];
        let mut val = vec![0.0; self.col.len()];
        for i in 0..self.rows {
            let (c, v) = self.row(i);
            for (&k, &a) in c.iter().zip(v) {
                let s = &mut next[k as usize];
                col[*s] = i as u32;
                val[*s] = a;
                *s += 1;
            }
        }
        Csr {
            rows: self.cols,
            cols: self.rows,
            ptr,
            col,
            val,
        }
    }

    /// `self · b`, rows in parallel blocks, each row accumulated in a fixed order.
    pub(crate) fn product(&self, b: &Csr) -> Csr {
        let blocks: Vec<(Vec<usize>, Vec<u32>, Vec<f64>)> = (0..self.rows.div_ceil(ROW_BLOCK))
            .into_par_iter()
            .map(|blk| {
                let mut acc = vec![0.0; b.cols];
                let mut mark = vec![usize::MAX; b.cols];
                let mut lens = Vec::new();
                let mut cols = Vec::new();
                let mut vals = Vec::new();
                let mut row_cols: Vec<u32> = Vec::new();
                for i in blk * ROW_BLOCK..((blk + 1) * ROW_BLOCK).min(self.rows) {
                    row_cols.clear();
                    let (c, v) = self.row(i);
                    for (&j, &a) in c.iter().zip(v) {
                        let (bc, bv) = b.row(j as usize);
                        for (&k, &w) in bc.iter().zip(bv) {
                            let k = k as usize;
                            if mark[k] != i {
                                mark[k] = i;
                                acc[k] = 0.0;
                                row_cols.push(k as u32);
                            }
                            acc[k] += a * w;
                        }
                    }
                    row_cols.sort_unstable();
                    lens.push(row_cols.len());
                    for &k in &row_cols {
                        cols.push(k);
                        vals.push(acc[k as usize]);
                    }
                }
                (lens, cols, vals)
            })
            .collect();
        let mut ptr = Vec::with_capacity(self.rows + 1);
        ptr.push(0);
        let mut col = Vec::new();
        let mut val = Vec::new();
        for (lens, c, v) in blocks {
            for l in lens {
                ptr.push(ptr.last().unwrap() + l);
            }
            col.extend(c);
            val.extend(v);
        }
        Csr {
            rows: self.rows,
            cols: b.cols,
            ptr,
            col,
            val,
        }
    }

    /// The values of `self · b` on `out`'s pattern, that of [`Csr::product`] of the same
    /// two patterns (`b`'s values `b_vals`): the same sums in the same order, so the same
    /// bits, without finding the pattern again.
    pub(crate) fn product_values(&self, b: &Csr, b_vals: &[f64], out: &Csr) -> Vec<f64> {
        debug_assert_eq!(out.rows, self.rows);
        let mut val = vec![0.0; out.col.len()];
        let mut parts = Vec::with_capacity(self.rows.div_ceil(ROW_BLOCK));
        let mut rest = &mut val[..];
        for r0 in (0..self.rows).step_by(ROW_BLOCK) {
            let r1 = (r0 + ROW_BLOCK).min(self.rows);
            let (head, tail) = std::mem::take(&mut rest).split_at_mut(out.ptr[r1] - out.ptr[r0]);
            parts.push((r0, r1, head));
            rest = tail;
        }
        parts.into_par_iter().for_each(|(r0, r1, part)| {
            let mut acc = vec![0.0; b.cols];
            let base = out.ptr[r0];
            for i in r0..r1 {
                let (c, v) = self.row(i);
                for (&j, &a) in c.iter().zip(v) {
                    let (bc, bv) = b.row_of(b_vals, j as usize);
                    for (&k, &w) in bc.iter().zip(bv) {
                        acc[k as usize] += a * w;
                    }
                }
                for q in out.ptr[i]..out.ptr[i + 1] {
                    let k = out.col[q] as usize;
                    part[q - base] = acc[k];
                    acc[k] = 0.0;
                }
            }
        });
        val
    }

    /// The pattern alone: no values.
    pub(crate) fn pattern(&self) -> Csr {
        Csr {
            rows: self.rows,
            cols: self.cols,
            ptr: self.ptr.clone(),
            col: self.col.clone(),
            val: Vec::new(),
        }
    }

    /// The diagonal (0 where absent).
    pub(crate) fn diagonal(&self) -> Vec<f64> {
        (0..self.rows)
            .map(|i| {
                let (c, v) = self.row(i);
                c.binary_search(&(i as u32)).map_or(0.0, |k| v[k])
            })
            .collect()
    }
}

/// Where each entry of a symmetric matrix's lower triangle (compressed columns, row indices
/// ascending within a column) lands in the full matrix's compressed rows: assembled values
/// are copied into a [`Csr`] of the full pattern without building it again, each full entry
/// gathering its lower entry (in parallel, the same bits on any thread count).
#[derive(Clone, Debug)]
pub struct SymScatter {
    /// The full matrix's pattern (values zero).
    pub pattern: Csr,
    /// Per lower entry k at (row i, column j): its position in row i.
    lower: Vec<u32>,
    /// Per full entry: the lower entry whose value it takes.
    source: Vec<u32>,
}

impl SymScatter {
    /// The scatter of the lower-triangle pattern `(col_ptr, row_idx)` of an `n × n` matrix.
    pub fn new(n: usize, cp: &[usize], ri: &[usize]) -> SymScatter {
        let mut ptr = vec![0usize; n + 1];
        for j in 0..n {
            for &i in &ri[cp[j]..cp[j + 1]] {
                ptr[i + 1] += 1;
                if i != j {
                    ptr[j + 1] += 1;
                }
            }
        }
        for i in 0..n {
            ptr[i + 1] += ptr[i];
        }
        let nnz = ptr[n];
        let mut next = ptr[..n].to_vec();
        let mut col = vec![0u32; nnz];
        let mut lower = vec![0u32; ri.len()];
        let mut source = vec![0u32; nnz];
        // Columns in ascending order: row i receives its columns j < i first (from column j),
        // then, from column i, the diagonal and the columns above it, ascending.
        for j in 0..n {
            for k in cp[j]..cp[j + 1] {
                let i = ri[k];
                col[next[i]] = j as u32;
                lower[k] = next[i] as u32;
                source[next[i]] = k as u32;
                next[i] += 1;
                if i != j {
                    col[next[j]] = i as u32;
                    source[next[j]] = k as u32;
                    next[j] += 1;
                }
            }
        }
        SymScatter {
            pattern: Csr {
                rows: n,
                cols: n,
                ptr,
                col,
                val: vec![0.0; nnz],
            },
            lower,
            source,
        }
    }

    /// `out`'s values (of [`SymScatter::pattern`]) from the lower triangle's values `v`.
    pub fn fill(&self, v: &[f64], out: &mut Csr) {
        out.val
            .par_chunks_mut(FILL_BLOCK)
            .zip(self.source.par_chunks(FILL_BLOCK))
            .for_each(|(o, src)| {
                for (o, &k) in o.iter_mut().zip(src) {
                    *o = v[k as usize];
                }
            });
    }

    /// The position in the full rows of lower entry `k` (its own row's copy).
    pub fn position(&self, k: usize) -> usize {
        self.lower[k] as usize
    }
}

/// `y = A x` for a symmetric `A` stored as its lower triangle in compressed columns.
pub fn sym_lower_matvec(a: &SparseColMat<usize, f64>, x: &[f64], y: &mut [f64]) {
    y.iter_mut().for_each(|v| *v = 0.0);
    let cp = a.symbolic().col_ptr();
    let ri = a.symbolic().row_idx();
    let val = a.val();
    for j in 0..x.len() {
        let xj = x[j];
        let mut acc = 0.0;
        for k in cp[j]..cp[j + 1] {
            let i = ri[k];
            let v = val[k];
            if i == j {
                acc += v * xj;
            } else {
                y[i] += v * xj;
                acc += v * x[i];
            }
        }
        y[j] += acc;
    }
}
