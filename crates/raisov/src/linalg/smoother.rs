//! The smoothers of [`super::galerkin::GalerkinMultigrid`]'s V-cycle: one sweep on `A z = b`
//! that lowers the high-frequency error, run forward before the coarse correction and
//! backward after it, so the cycle stays symmetric.
//!
//! - [`Smoother::GaussSeidel`], the default and the reference: point Gauss-Seidel, rows in
//!   order, `z_i += (b_i − Σ_k A_ik z_k) / A_ii` (0 where `A_ii ≤ 0`), on one thread.
//! - [`Smoother::ColouredBlock`]: node-block Gauss-Seidel over a colouring. The
//!   rows of one node (its up to three free dofs) form a block `b`; blocks that share no matrix
//!   entry get the same colour (greedy, in node order). A forward sweep visits the colours in
//!   order and updates every block of a colour at once,
//!
//!   ```text
//!   z_b += D_b⁻¹ (b − A z)_b,        D_b = A_bb, the block's 3 × 3 diagonal block,
//!   ```
//!
//!   reading only other colours' values, so the blocks of a colour run in parallel and the
//!   result is the same bits on any thread count; the backward sweep visits the colours in
//!   reverse, the forward sweep's adjoint. The sweep reads the matrix from a copy whose rows
//!   are in the order it visits them ([`ColourOrder`]), front to back, rather than a colour's
//!   rows scattered over the whole matrix. The 3 × 3 solve relaxes a node's three coupled
//!   displacement components together, which the elastic operator couples strongly (the
//!   vertex-block Gauss-Seidel of Vertex Block Descent, on the Newton system). `D_b⁻¹` is the
//!   inverse by Cholesky; a block that is not positive definite falls back to the reciprocal
//!   of its positive diagonal entries (0 elsewhere), as the point sweep does.
//! - [`Smoother::BlockJacobi`]: damped node-block Jacobi, every block at once from the same
//!   `z`,
//!
//!   ```text
//!   z ← z + ω D⁻¹ (b − A z),     ω = 4 / (3 · 1.1 λ̃),
//!   ```
//!
//!   `D⁻¹` the blocks' inverses as above, `λ̃` the largest eigenvalue of `D⁻¹A` estimated by
//!   [`POWER_ITERATIONS`] power iterations from a fixed start (raised by 10 % since the
//!   estimate falls short of it): `4 / (3 λ_max)` minimises the largest factor
//!   `|1 − ω λ|` over the upper half of the spectrum, the error the coarse level cannot
//!   represent. ω is estimated when a hierarchy is built and kept when its operators are
//!   refreshed from a later Newton tangent. Rows in parallel, in memory order, the same bits
//!   on any thread count; the sweep is its own adjoint, so forward and backward are the
//!   same.

use super::sparse::{row_dot, Csr, Entry};
use rayon::prelude::*;

/// Blocks per parallel task within one colour.
const MIN_BLOCKS_PER_TASK: usize = 64;

/// Which smoother a [`super::galerkin::GalerkinMultigrid`] runs (module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Smoother {
    /// Point Gauss-Seidel on one thread (the default of
    /// [`crate::statics::newton::MultigridPcg`], and the reference; a scenario's `[integrator]
    /// smoother` defaults by element kind, [`crate::scenario::StaticSolve::smoother`]).
    #[default]
    GaussSeidel,
    /// Node-block Gauss-Seidel over a colouring, colours' blocks in parallel, reading a copy
    /// of the matrix with its rows in colour order ([`ColourOrder`]).
    ColouredBlock,
    /// Damped node-block Jacobi, rows in parallel in memory order.
    BlockJacobi,
}

impl Smoother {
    /// Its name in summaries and tables.
    pub fn describe(self) -> &'static str {
        match self {
            Smoother::GaussSeidel => "point Gauss-Seidel",
            Smoother::ColouredBlock => "coloured block Gauss-Seidel",
            Smoother::BlockJacobi => "block Jacobi",
        }
    }
}

/// Power iterations of [`Smoother::BlockJacobi`]'s estimate of `λ_max(D⁻¹A)`.
pub const POWER_ITERATIONS: usize = 8;

/// The node blocks of one level's rows and their colouring: fixed by the level's dofs and
/// its operator's pattern.
#[derive(Clone, Debug)]
pub struct Colouring {
    /// Block `k` is rows `start[k]..start[k + 1]`; `blocks + 1` entries.
    start: Vec<usize>,
    /// The blocks of each colour, ascending.
    colours: Vec<Vec<u32>>,
}

impl Colouring {
    /// The blocks of rows whose dofs (`dofs[r] = 3 node + component`, ascending) share a
    /// node, coloured greedily in node order over `a`'s pattern.
    pub fn new(a: &Csr, dofs: &[usize]) -> Colouring {
        let mut start = vec![0];
        for r in 1..dofs.len() {
            if dofs[r] / 3 != dofs[r - 1] / 3 {
                start.push(r);
            }
        }
        start.push(dofs.len());
        let nb = start.len() - 1;
        let mut block_of = vec![0u32; dofs.len()];
        for k in 0..nb {
            block_of[start[k]..start[k + 1]].fill(k as u32);
        }
        let mut colour = vec![u32::MAX; nb];
        // `seen[c] == k`: colour c is taken by a neighbour of block k.
        let mut seen: Vec<usize> = Vec::new();
        for k in 0..nb {
            for r in start[k]..start[k + 1] {
                let (cols, _) = a.row(r);
                for &j in cols {
                    let c = colour[block_of[j as usize] as usize];
                    if c != u32::MAX {
                        seen[c as usize] = k;
                    }
                }
            }
            let c = (0..seen.len()).find(|&c| seen[c] != k).unwrap_or_else(|| {
                seen.push(usize::MAX);
                seen.len() - 1
            });
            colour[k] = c as u32;
        }
        let mut colours = vec![Vec::new(); seen.len()];
        for (k, &c) in colour.iter().enumerate() {
            colours[c as usize].push(k as u32);
        }
        Colouring { start, colours }
    }

    /// Number of colours.
    pub fn colours(&self) -> usize {
        self.colours.len()
    }

    /// The inverse of each block's diagonal block (module docs), row-major in a 3 × 3 array
    /// whose leading `m × m` part is used for a block of `m` rows.
    pub fn inverses(&self, a: &Csr) -> Vec<[f64; 9]> {
        (0..self.start.len() - 1)
            .into_par_iter()
            .with_min_len(MIN_BLOCKS_PER_TASK)
            .map(|k| {
                let (r0, r1) = (self.start[k], self.start[k + 1]);
                let m = r1 - r0;
                let mut d = [0.0; 9];
                for i in 0..m {
                    let (cols, vals) = a.row(r0 + i);
                    for j in 0..m {
                        if let Ok(p) = cols.binary_search(&((r0 + j) as u32)) {
                            d[3 * i + j] = vals[p];
                        }
                    }
                }
                block_inverse(&d, m)
            })
            .collect()
    }

    /// The level's rows in the order [`Colouring::sweep`] visits them: colour by colour, each
    /// colour's blocks ascending, each block's rows ascending.
    pub fn order(&self, a: &Csr) -> ColourOrder {
        let mut row = Vec::with_capacity(a.rows);
        let mut ptr = Vec::with_capacity(a.rows + 1);
        ptr.push(0);
        let mut col = Vec::with_capacity(a.col.len());
        let mut first = Vec::with_capacity(self.colours.len());
        for blocks in &self.colours {
            let mut f = Vec::with_capacity(blocks.len());
            for &k in blocks {
                let k = k as usize;
                f.push(row.len() as u32);
                for r in self.start[k]..self.start[k + 1] {
                    row.push(r as u32);
                    col.extend_from_slice(a.row(r).0);
                    ptr.push(col.len());
                }
            }
            first.push(f);
        }
        ColourOrder {
            row,
            ptr,
            col,
            first,
        }
    }

    /// One sweep of node-block Gauss-Seidel on `a z = b`, colours ascending (`forward`) or
    /// descending; `vals` the values of `a` in `order` ([`ColourOrder::values`]), `inv` from
    /// [`Colouring::inverses`] of `a`.
    pub fn sweep<V: Entry>(
        &self,
        order: &ColourOrder,
        vals: &[V],
        inv: &[[f64; 9]],
        b: &[f64],
        z: &mut [f64],
        forward: bool,
    ) {
        let mut colours: Vec<usize> = (0..self.colours.len()).collect();
        if !forward {
            colours.reverse();
        }
        let mut delta: Vec<[f64; 3]> = Vec::new();
        for c in colours {
            let blocks = &self.colours[c];
            let zr: &[f64] = z;
            blocks
                .par_iter()
                .zip(&order.first[c])
                .with_min_len(MIN_BLOCKS_PER_TASK)
                .map(|(&k, &q0)| {
                    let (k, q0) = (k as usize, q0 as usize);
                    let (r0, r1) = (self.start[k], self.start[k + 1]);
                    let mut r = [0.0; 3];
                    for (i, ri) in r.iter_mut().enumerate().take(r1 - r0) {
                        let e = order.ptr[q0 + i]..order.ptr[q0 + i + 1];
                        *ri = b[r0 + i] - row_dot(&order.col[e.clone()], &vals[e], zr);
                    }
                    let d = &inv[k];
                    [
                        d[0] * r[0] + d[1] * r[1] + d[2] * r[2],
                        d[3] * r[0] + d[4] * r[1] + d[5] * r[2],
                        d[6] * r[0] + d[7] * r[1] + d[8] * r[2],
                    ]
                })
                .collect_into_vec(&mut delta);
            for (&k, dk) in blocks.iter().zip(&delta) {
                let k = k as usize;
                let r0 = self.start[k];
                for (i, zi) in z[r0..self.start[k + 1]].iter_mut().enumerate() {
                    *zi += dk[i];
                }
            }
        }
    }
}

/// A copy of one level's matrix pattern with its rows in the order [`Colouring::sweep`]
/// visits them ([`Colouring::order`]), so that a sweep reads the matrix front to back rather
/// than a colour's scattered rows at a time; the columns keep the level's numbering. Fixed by
/// the pattern; the values in this order are gathered by [`ColourOrder::values`] and
/// [`ColourOrder::fill`].
#[derive(Clone, Debug)]
pub struct ColourOrder {
    /// The level's row at each position of the order.
    row: Vec<u32>,
    /// Start of each ordered row's entries in `col` (and in the ordered values).
    ptr: Vec<usize>,
    /// The entries' columns.
    col: Vec<u32>,
    /// For each colour, the position of each of its blocks' first row.
    first: Vec<Vec<u32>>,
}

impl ColourOrder {
    /// The bytes a [`ColourOrder`] of a matrix with `rows` rows and `nnz` entries takes at
    /// most (a column per entry; a row index, a start and at most one block start per row).
    pub fn bytes(rows: usize, nnz: usize) -> u64 {
        (4 * nnz + 16 * rows) as u64
    }

    /// The values of `a` (whose pattern this order was made from), in this order, each
    /// converted by `round`.
    pub fn values<V: Clone>(&self, a: &Csr, round: impl Fn(f64) -> V) -> Vec<V> {
        let mut out = vec![round(0.0); self.col.len()];
        self.fill(a, round, &mut out);
        out
    }

    /// [`ColourOrder::values`] into `out`, which has their length.
    pub fn fill<V>(&self, a: &Csr, round: impl Fn(f64) -> V, out: &mut [V]) {
        for (q, &r) in self.row.iter().enumerate() {
            let src = a.row(r as usize).1;
            for (o, &v) in out[self.ptr[q]..self.ptr[q + 1]].iter_mut().zip(src) {
                *o = round(v);
            }
        }
    }

    /// `r = b − A z`, `vals` A's values in this order; rows in parallel blocks, the same bits
    /// on any thread count.
    pub fn residual<V: Entry>(&self, vals: &[V], b: &[f64], z: &[f64], r: &mut [f64]) {
        let mut ordered = vec![0.0; self.row.len()];
        ordered
            .par_chunks_mut(3 * MIN_BLOCKS_PER_TASK)
            .enumerate()
            .for_each(|(part, out)| {
                let q0 = part * 3 * MIN_BLOCKS_PER_TASK;
                for (i, o) in out.iter_mut().enumerate() {
                    let q = q0 + i;
                    let e = self.ptr[q]..self.ptr[q + 1];
                    *o = b[self.row[q] as usize] - row_dot(&self.col[e.clone()], &vals[e], z);
                }
            });
        for (&row, v) in self.row.iter().zip(ordered) {
            r[row as usize] = v;
        }
    }
}

impl Colouring {
    /// `y = D⁻¹ x` over the node blocks, `inv` from [`Colouring::inverses`].
    fn block_apply(&self, inv: &[[f64; 9]], x: &[f64], y: &mut [f64]) {
        let start = &self.start;
        y.par_chunks_mut(3 * MIN_BLOCKS_PER_TASK)
            .enumerate()
            .for_each(|(part, out)| {
                let first_row = part * 3 * MIN_BLOCKS_PER_TASK;
                let last_row = first_row + out.len();
                // The blocks are runs of consecutive rows: walk those that meet this part,
                // from the one holding its first row, writing the rows inside it.
                let mut k = start.partition_point(|&r| r <= first_row) - 1;
                while k + 1 < start.len() && start[k] < last_row {
                    let (r0, r1) = (start[k], start[k + 1]);
                    let d = &inv[k];
                    for i in 0..r1 - r0 {
                        if (first_row..last_row).contains(&(r0 + i)) {
                            let v: f64 = (0..r1 - r0).map(|j| d[3 * i + j] * x[r0 + j]).sum();
                            out[r0 + i - first_row] = v;
                        }
                    }
                    k += 1;
                }
            });
    }

    /// `ω` of [`Smoother::BlockJacobi`] for `a` (module docs), `inv` its block inverses.
    pub fn jacobi_damping(&self, a: &Csr, inv: &[[f64; 9]]) -> f64 {
        let n = a.rows;
        let mut x: Vec<f64> = (0..n)
            .map(|i| 1.0 + 0.5 * (i as f64 * 0.618).sin())
            .collect();
        let (mut ax, mut y) = (vec![0.0; n], vec![0.0; n]);
        let mut lambda = 0.0;
        for _ in 0..POWER_ITERATIONS {
            let norm = x.iter().map(|v| v * v).sum::<f64>().sqrt();
            if norm == 0.0 || !norm.is_finite() {
                break;
            }
            x.iter_mut().for_each(|v| *v /= norm);
            a.matvec(&x, &mut ax);
            self.block_apply(inv, &ax, &mut y);
            lambda = x.iter().zip(&y).map(|(a, b)| a * b).sum::<f64>();
            std::mem::swap(&mut x, &mut y);
        }
        let lambda = x.iter().map(|v| v * v).sum::<f64>().sqrt().max(lambda);
        if lambda > 0.0 && lambda.is_finite() {
            4.0 / (3.0 * 1.1 * lambda)
        } else {
            0.0
        }
    }

    /// One damped block-Jacobi sweep on `a z = b` (module docs), `vals` a's values; `zero`:
    /// `z` is 0, so the residual is `b` (no product).
    #[allow(clippy::too_many_arguments)]
    pub fn jacobi_sweep<V: Entry>(
        &self,
        a: &Csr,
        vals: &[V],
        inv: &[[f64; 9]],
        omega: f64,
        b: &[f64],
        z: &mut [f64],
        zero: bool,
    ) {
        let n = a.rows;
        let mut r = vec![0.0; n];
        if zero {
            r.copy_from_slice(b);
        } else {
            a.matvec_of(vals, z, &mut r);
            for (ri, bi) in r.iter_mut().zip(b) {
                *ri = bi - *ri;
            }
        }
        let mut d = vec![0.0; n];
        self.block_apply(inv, &r, &mut d);
        for (zi, di) in z.iter_mut().zip(&d) {
            *zi += omega * di;
        }
    }
}

/// The inverse of the leading `m × m` block of `d` (row-major 3 × 3, symmetric) by Cholesky,
/// zero-padded to 3 × 3; where that block is not positive definite, the diagonal matrix of the
/// reciprocals of its positive diagonal entries (0 elsewhere).
fn block_inverse(d: &[f64; 9], m: usize) -> [f64; 9] {
    // L Lᵀ = D, then D⁻¹ = L⁻ᵀ L⁻¹.
    let mut l = [0.0; 9];
    let mut ok = true;
    'outer: for i in 0..m {
        for j in 0..=i {
            let mut s = d[3 * i + j];
            for k in 0..j {
                s -= l[3 * i + k] * l[3 * j + k];
            }
            if i == j {
                if s <= 1e-300 || !s.is_finite() {
                    ok = false;
                    break 'outer;
                }
                l[3 * i + i] = s.sqrt();
            } else {
                l[3 * i + j] = s / l[3 * j + j];
            }
        }
    }
    let mut out = [0.0; 9];
    if !ok {
        for i in 0..m {
            let x = d[3 * i + i];
            out[3 * i + i] = if x > 0.0 { 1.0 / x } else { 0.0 };
        }
        return out;
    }
    // L⁻¹ by forward substitution, column by column.
    let mut li = [0.0; 9];
    for c in 0..m {
        for i in c..m {
            let mut s = if i == c { 1.0 } else { 0.0 };
            for k in c..i {
                s -= l[3 * i + k] * li[3 * k + c];
            }
            li[3 * i + c] = s / l[3 * i + i];
        }
    }
    for i in 0..m {
        for j in 0..m {
            out[3 * i + j] = (i.max(j)..m).map(|k| li[3 * k + i] * li[3 * k + j]).sum();
        }
    }
    out
}

/// One point Gauss-Seidel sweep on `A z = b`, rows ascending (`forward`) or descending;
/// `inv_diag[i] = 1 / A_ii`, 0 where `A_ii ≤ 0`.
pub fn gauss_seidel<V: Entry>(
    a: &Csr,
    vals: &[V],
    inv_diag: &[f64],
    b: &[f64],
    z: &mut [f64],
    forward: bool,
) {
    let mut relax = |i: usize| {
        let (c, v) = a.row_of(vals, i);
        let s = row_dot(c, v, z);
        z[i] += (b[i] - s) * inv_diag[i];
    };
    if forward {
        (0..a.rows).for_each(&mut relax);
    } else {
        (0..a.rows).rev().for_each(&mut relax);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A symmetric positive definite matrix over `n` nodes in a ring, 3 dofs each: every node
    /// coupled to its two neighbours, its own three dofs coupled strongly.
    fn ring(n: usize) -> Csr {
        let mut a = Csr {
            rows: 3 * n,
            cols: 3 * n,
            ptr: vec![0],
            ..Default::default()
        };
        for r in 0..3 * n {
            let (p, c) = (r / 3, r % 3);
            let mut row: Vec<(u32, f64)> = Vec::new();
            for q in [(p + n - 1) % n, p, (p + 1) % n] {
                for c2 in 0..3 {
                    let v = if q == p {
                        if c2 == c {
                            7.0
                        } else {
                            1.5
                        }
                    } else if c2 == c {
                        -1.0
                    } else {
                        0.25 * if (p + q) % 2 == 0 { 1.0 } else { -1.0 }
                    };
                    row.push((3 * q as u32 + c2 as u32, v));
                }
            }
            row.sort_by_key(|e| e.0);
            for (j, v) in row {
                a.col.push(j);
                a.val.push(v);
            }
            a.ptr.push(a.col.len());
        }
        a
    }

    /// The rows and columns `dofs` (ascending) of `a`.
    fn restrict(a: &Csr, dofs: &[usize]) -> Csr {
        let mut sub = Csr {
            rows: dofs.len(),
            cols: dofs.len(),
            ptr: vec![0],
            ..Default::default()
        };
        for &r in dofs {
            let (c, v) = a.row(r);
            for (&j, &x) in c.iter().zip(v) {
                if let Ok(p) = dofs.binary_search(&(j as usize)) {
                    sub.col.push(p as u32);
                    sub.val.push(x);
                }
            }
            sub.ptr.push(sub.col.len());
        }
        sub
    }

    #[test]
    fn block_inverse_inverts_and_falls_back_on_indefinite_blocks() {
        let d = [4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0];
        let inv = block_inverse(&d, 3);
        for i in 0..3 {
            for j in 0..3 {
                let s: f64 = (0..3).map(|k| d[3 * i + k] * inv[3 * k + j]).sum();
                let e = if i == j { 1.0 } else { 0.0 };
                assert!((s - e).abs() < 1e-14, "({i},{j}) {s}");
            }
        }
        // A 2 × 2 leading block.
        let inv2 = block_inverse(&d, 2);
        let det = 4.0 * 3.0 - 1.0;
        assert!((inv2[0] - 3.0 / det).abs() < 1e-15 && (inv2[1] + 1.0 / det).abs() < 1e-15);
        assert_eq!(inv2[2], 0.0);
        assert_eq!(inv2[8], 0.0);
        // Indefinite: the positive diagonal's reciprocals only.
        let bad = [1.0, 2.0, 0.0, 2.0, 1.0, 0.0, 0.0, 0.0, -1.0];
        assert_eq!(
            block_inverse(&bad, 3),
            [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0]
        );
    }

    #[test]
    fn colouring_is_proper_and_the_sweep_is_block_gauss_seidel_in_colour_order() {
        let n = 9;
        let a = ring(n);
        // Node 4 has only two free dofs.
        let dofs: Vec<usize> = (0..3 * n).filter(|&d| d != 13).collect();
        let sub = restrict(&a, &dofs);
        let col = Colouring::new(&sub, &dofs);
        // An odd ring needs three colours; no two neighbours share one.
        assert_eq!(col.colours(), 3);
        let mut colour_of = vec![0; n];
        for (c, blocks) in col.colours.iter().enumerate() {
            for &k in blocks {
                colour_of[k as usize] = c;
            }
        }
        for p in 0..n {
            assert_ne!(colour_of[p], colour_of[(p + 1) % n]);
        }
        // The sweep equals a sequential block Gauss-Seidel over the blocks in colour order.
        let inv = col.inverses(&sub);
        let b: Vec<f64> = (0..sub.rows).map(|i| (i as f64 * 0.37).sin()).collect();
        let mut z: Vec<f64> = (0..sub.rows).map(|i| (i as f64 * 0.11).cos()).collect();
        let mut zr = z.clone();
        let order = col.order(&sub);
        let vals = order.values(&sub, |v| v);
        col.sweep(&order, &vals, &inv, &b, &mut z, true);
        for blocks in &col.colours {
            for &k in blocks {
                let k = k as usize;
                let (r0, r1) = (col.start[k], col.start[k + 1]);
                let mut r = [0.0; 3];
                for i in r0..r1 {
                    let (c, v) = sub.row(i);
                    r[i - r0] = b[i]
                        - c.iter()
                            .zip(v)
                            .map(|(&j, &x)| x * zr[j as usize])
                            .sum::<f64>();
                }
                for i in 0..r1 - r0 {
                    zr[r0 + i] += (0..3).map(|j| inv[k][3 * i + j] * r[j]).sum::<f64>();
                }
            }
        }
        for (x, y) in z.iter().zip(&zr) {
            assert!((x - y).abs() < 1e-14, "{x} vs {y}");
        }
        // The colour order holds every row once, and its residual is b − A z; its values,
        // refilled from a changed matrix, follow the change.
        let mut rows = order.row.clone();
        rows.sort_unstable();
        assert_eq!(rows, (0..sub.rows as u32).collect::<Vec<_>>());
        let mut scaled = sub.clone();
        scaled.val.iter_mut().for_each(|v| *v *= 1.5);
        let mut vals2 = vals.clone();
        order.fill(&scaled, |v| v, &mut vals2);
        let (mut az, mut res) = (vec![0.0; sub.rows], vec![f64::NAN; sub.rows]);
        scaled.matvec(&z, &mut az);
        order.residual(&vals2, &b, &z, &mut res);
        for ((r, bi), azi) in res.iter().zip(&b).zip(&az) {
            assert!((r - (bi - azi)).abs() < 1e-14, "{r} vs {}", bi - azi);
        }
        // Relaxed block rows have zero residual right after their update; sweeping converges.
        let mut z = vec![0.0; sub.rows];
        let mut res = vec![0.0; sub.rows];
        for _ in 0..40 {
            col.sweep(&order, &vals, &inv, &b, &mut z, true);
            col.sweep(&order, &vals, &inv, &b, &mut z, false);
        }
        sub.matvec(&z, &mut res);
        let worst = res
            .iter()
            .zip(&b)
            .map(|(r, b)| (r - b).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-10, "residual {worst} after 40 symmetric sweeps");
    }

    /// Block Jacobi over a ring long enough that blocks straddle the parallel parts (every
    /// seventh node has two free dofs): a sweep equals `z + ω D⁻¹ (b − A z)` computed block by
    /// block, the damping is positive, and repeated sweeps converge.
    #[test]
    fn block_jacobi_sweep_is_damped_block_jacobi_and_converges() {
        let n = 301;
        let a = ring(n);
        let dofs: Vec<usize> = (0..3 * n).filter(|&d| d % 21 != 2).collect();
        let sub = restrict(&a, &dofs);
        let blocks = Colouring::new(&sub, &dofs);
        let inv = blocks.inverses(&sub);
        let omega = blocks.jacobi_damping(&sub, &inv);
        assert!(omega > 0.0 && omega < 4.0 / 3.0, "ω = {omega}");
        let b: Vec<f64> = (0..sub.rows).map(|i| (i as f64 * 0.37).sin()).collect();
        let mut z: Vec<f64> = (0..sub.rows).map(|i| (i as f64 * 0.11).cos()).collect();
        let mut r = vec![0.0; sub.rows];
        sub.matvec(&z, &mut r);
        let mut want = z.clone();
        for k in 0..blocks.start.len() - 1 {
            let (r0, r1) = (blocks.start[k], blocks.start[k + 1]);
            for i in 0..r1 - r0 {
                want[r0 + i] += omega
                    * (0..r1 - r0)
                        .map(|j| inv[k][3 * i + j] * (b[r0 + j] - r[r0 + j]))
                        .sum::<f64>();
            }
        }
        blocks.jacobi_sweep(&sub, &sub.val, &inv, omega, &b, &mut z, false);
        for (x, y) in z.iter().zip(&want) {
            assert!((x - y).abs() < 1e-14, "{x} vs {y}");
        }
        // From z = 0 the sweep that skips the product is the same sweep.
        let (mut z0, mut z1) = (vec![0.0; sub.rows], vec![0.0; sub.rows]);
        blocks.jacobi_sweep(&sub, &sub.val, &inv, omega, &b, &mut z0, false);
        blocks.jacobi_sweep(&sub, &sub.val, &inv, omega, &b, &mut z1, true);
        assert_eq!(z0, z1);
        let mut z = vec![0.0; sub.rows];
        for _ in 0..200 {
            blocks.jacobi_sweep(&sub, &sub.val, &inv, omega, &b, &mut z, false);
        }
        sub.matvec(&z, &mut r);
        let worst = r
            .iter()
            .zip(&b)
            .map(|(r, b)| (r - b).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-10, "residual {worst} after 200 sweeps");
    }
}
