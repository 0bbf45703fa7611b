//! The tangent's sparsity pattern and the place of every element entry in it.
//!
//! The pattern is the lower triangle (row ≥ column) of `K`'s free rows and columns, compressed
//! by columns: column `j` (free dof `j`) holds, ascending, the free dofs `i ≥ j` of the nodes
//! that share an element with `j`'s node, itself included. Free dofs are numbered in dof
//! order (`3 node + component`), so each node's free dofs are consecutive in a column.
//! `slots[e d² + r d + c]` (`d` = 3 × nodes per element) is the place of element `e`'s entry
//! `(r, c)` (local dof `3 i + k` of its `i`-th node) in the pattern's values: `u32::MAX` where
//! the row or column is constrained, or the entry is above the diagonal (the lower entry of the
//! symmetric pair takes it). `diag[j]` is column `j`'s first place, its diagonal.
//!
//! [`build`] runs in three passes:
//! 1. each node's elements (a counting sort), then each node's neighbours, sorted, nodes in
//!    parallel;
//! 2. the columns, blocks of nodes in parallel, joined in order;
//! 3. the slots, elements in parallel: one binary search per (row node, column node) in the
//!    column node's first free column, every other place of the pair found from it
//!    ([`place`]).
//!
//! Each pass writes disjoint outputs, so the result is the same on any thread count.
//! [`reference`] (tests) builds the same pattern from sorted node pairs with one binary search
//! per entry.

use crate::fem::ElementTopology;
use rayon::prelude::*;

/// Nodes or elements per parallel task.
const MIN_PER_TASK: usize = 256;

/// The pattern of the free tangent and the element entries' places in it (module docs).
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) struct Pattern {
    /// Column `j` is `row_idx[col_ptr[j]..col_ptr[j + 1]]`; `nfree + 1` entries.
    pub col_ptr: Vec<usize>,
    /// Row indices (free dofs), ascending within a column.
    pub row_idx: Vec<usize>,
    /// The place of each element entry, `u32::MAX` where it has none.
    pub slots: Vec<u32>,
    /// The place of each free dof's diagonal entry.
    pub diag: Vec<u32>,
}

/// The pattern of `model`'s tangent over the free dofs (`free[i]`: dof `i`'s free index,
/// `usize::MAX` where constrained; `nfree` of them); an error where its arrays and the
/// values the caller keeps beside the slots would not fit in memory.
pub(super) fn build(
    model: &ElementTopology<'_>,
    free: &[usize],
    nfree: usize,
) -> Result<Pattern, String> {
    let n = model.nodes;
    let ne = model.len();
    let npe = if ne > 0 { model.element(0).len() } else { 0 };
    let d = 3 * npe;
    // At most one value (8 B) and row index (4 B) per element entry, its slot (4 B); each
    // node's elements and neighbours.
    crate::memory::check(
        &format!("the tangent's pattern over {ne} elements"),
        (ne * d * d) as u64 * (4 + 8 + 4) + (ne * npe) as u64 * 4 * (npe as u64 + 1),
    )?;
    // Pass 1: each node's elements, then its neighbours.
    let mut start = vec![0usize; n + 1];
    for e in 0..ne {
        for &a in model.element(e) {
            start[a as usize + 1] += 1;
        }
    }
    for a in 0..n {
        start[a + 1] += start[a];
    }
    let mut elems = vec![0u32; start[n]];
    let mut fill = start.clone();
    for e in 0..ne {
        for &a in model.element(e) {
            elems[fill[a as usize]] = e as u32;
            fill[a as usize] += 1;
        }
    }
    drop(fill);
    let neighbours: Vec<Vec<u32>> = (0..n)
        .into_par_iter()
        .with_min_len(MIN_PER_TASK)
        .map(|a| {
            let mut v = vec![a as u32];
            for &e in &elems[start[a]..start[a + 1]] {
                v.extend_from_slice(model.element(e as usize));
            }
            v.sort_unstable();
            v.dedup();
            v
        })
        .collect();
    drop(elems);
    // Pass 2: the columns, a block of nodes per task, the blocks' columns joined in order.
    let blocks: Vec<(Vec<usize>, Vec<usize>)> = (0..n.div_ceil(MIN_PER_TASK))
        .into_par_iter()
        .map(|blk| {
            let (mut lens, mut rows) = (Vec::new(), Vec::new());
            for j in 3 * blk * MIN_PER_TASK..3 * ((blk + 1) * MIN_PER_TASK).min(n) {
                let gc = free[j];
                if gc == usize::MAX {
                    continue;
                }
                let before = rows.len();
                for &b in &neighbours[j / 3] {
                    for &gr in &free[3 * b as usize..3 * b as usize + 3] {
                        if gr != usize::MAX && gr >= gc {
                            rows.push(gr);
                        }
                    }
                }
                lens.push(rows.len() - before);
            }
            (lens, rows)
        })
        .collect();
    let mut col_ptr = Vec::with_capacity(nfree + 1);
    col_ptr.push(0usize);
    let mut row_idx = Vec::with_capacity(blocks.iter().map(|b| b.1.len()).sum());
    for (lens, rows) in blocks {
        for l in lens {
            col_ptr.push(col_ptr[col_ptr.len() - 1] + l);
        }
        row_idx.extend_from_slice(&rows);
    }
    drop(neighbours);
    // Pass 3: the slots. Zeroed memory is mapped on first write, so the element chunks'
    // pages are touched by the tasks that fill them rather than by one thread beforehand.
    let mut slots = vec![0u32; ne * d * d];
    if d > 0 {
        slots
            .par_chunks_mut(d * d)
            .enumerate()
            .with_min_len(MIN_PER_TASK)
            .for_each(|(e, s)| place(model.element(e), free, &col_ptr, &row_idx, s));
    }
    let diag = col_ptr[..nfree].iter().map(|&p| p as u32).collect();
    Ok(Pattern {
        col_ptr,
        row_idx,
        slots,
        diag,
    })
}

/// One element's slots (`s`, its `d²` entries, row-major). A node's free dofs are
/// consecutive free indices, so column `gc₀ + k` (node b's k-th free dof) holds column
/// `gc₀`'s rows without its first k, which are b's own dofs `gc₀ .. gc₀ + k`: row node a's
/// first free dof is found in column `gc₀` by one binary search, at `p`, and a's j-th free
/// dof is at `p + j − k` in column `gc₀ + k`. A node other than b has all its free dofs below
/// `gc₀` (above the diagonal, no slots) or all above b's.
fn place(el: &[u32], free: &[usize], col_ptr: &[usize], row_idx: &[usize], s: &mut [u32]) {
    s.fill(u32::MAX);
    let d = 3 * el.len();
    // Each node's free dofs: (local component, free index), ascending.
    let frees = |a: u32| {
        (0..3).filter_map(move |k| {
            let g = free[3 * a as usize + k];
            (g != usize::MAX).then_some((k, g))
        })
    };
    for (cj, &b) in el.iter().enumerate() {
        let Some((_, gc0)) = frees(b).next() else {
            continue;
        };
        let rows0 = &row_idx[col_ptr[gc0]..col_ptr[gc0 + 1]];
        for (ri, &a) in el.iter().enumerate() {
            let Some((_, ga0)) = frees(a).next() else {
                continue;
            };
            if ga0 < gc0 {
                continue;
            }
            let p = rows0.partition_point(|&x| x < ga0);
            for (k, (kc, gc)) in frees(b).enumerate() {
                for (j, (kr, gr)) in frees(a).enumerate() {
                    if gr < gc {
                        continue;
                    }
                    let at = p + j - k;
                    debug_assert_eq!(
                        row_idx[col_ptr[gc] + at],
                        gr,
                        "node {a}'s free dofs in column {gc}"
                    );
                    s[(3 * ri + kr) * d + 3 * cj + kc] = (col_ptr[gc] + at) as u32;
                }
            }
        }
    }
}

/// The same pattern as [`build`], simply: the sorted, deduplicated node pairs of every
/// element, and one binary search per element entry.
#[cfg(test)]
pub(super) fn reference(model: &ElementTopology<'_>, free: &[usize], nfree: usize) -> Pattern {
    let n = model.nodes;
    let ne = model.len();
    let mut edges: Vec<(u32, u32)> = (0..n as u32).map(|a| (a, a)).collect();
    for e in 0..ne {
        let el = model.element(e);
        for &a in el {
            for &b in el {
                edges.push((a, b));
            }
        }
    }
    edges.sort_unstable();
    edges.dedup();
    let mut first = vec![0usize; n + 1];
    for &(a, _) in &edges {
        first[a as usize + 1] += 1;
    }
    for a in 0..n {
        first[a + 1] += first[a];
    }
    let mut col_ptr = vec![0usize];
    let mut row_idx = Vec::new();
    for j in 0..3 * n {
        let gc = free[j];
        if gc == usize::MAX {
            continue;
        }
        for &(_, b) in &edges[first[j / 3]..first[j / 3 + 1]] {
            for i in 3 * b as usize..3 * b as usize + 3 {
                if free[i] != usize::MAX && free[i] >= gc {
                    row_idx.push(free[i]);
                }
            }
        }
        col_ptr.push(row_idx.len());
    }
    let position = |gr: usize, gc: usize| -> u32 {
        let rows = &row_idx[col_ptr[gc]..col_ptr[gc + 1]];
        (col_ptr[gc] + rows.binary_search(&gr).expect("entry in the pattern")) as u32
    };
    let d = if ne > 0 {
        3 * model.element(0).len()
    } else {
        0
    };
    let mut slots = vec![u32::MAX; ne * d * d];
    for e in 0..ne {
        let el = model.element(e);
        for r in 0..d {
            let gr = free[3 * el[r / 3] as usize + r % 3];
            for c in 0..d {
                let gc = free[3 * el[c / 3] as usize + c % 3];
                if gr != usize::MAX && gc != usize::MAX && gr >= gc {
                    slots[e * d * d + r * d + c] = position(gr, gc);
                }
            }
        }
    }
    let diag = (0..nfree).map(|f| position(f, f)).collect();
    Pattern {
        col_ptr,
        row_idx,
        slots,
        diag,
    }
}
