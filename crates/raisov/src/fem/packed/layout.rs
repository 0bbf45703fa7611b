//! Force-pass order of the packed elements: slabs, strips, colours, lane interleave and the
//! row prefetch schedule.
//!
//! Elements are sorted into slabs of equal element counts: by mean node id when the node
//! numbering is banded, as for the structured boxes, so that a slab touches one contiguous
//! stretch of `u` and `r`; else along the longest axis of the mesh. Inside a slab they are
//! sorted into strips one mean element extent wide across the axis of middle node-id growth
//! ([`strip_axis`]; banded numbering only: the slab is swept strip by strip along the axis
//! of fastest-growing ids, so that a node's elements are met within two strips), and by the
//! Morton key of the element centroid within a strip. Groups of [`LANES`] are then formed
//! with the lanes of a group [`INTERLEAVE`] groups apart in that order, so that the lanes of
//! one group rarely share a node.
//!
//! Slabs are coloured greedily so that slabs of one colour share no node; the force pass
//! runs colour by colour, the slabs of a colour in parallel, each slab scattering serially
//! into `r`. Every node thus receives its element contributions in one fixed order
//! (colour, then slab order, then element order) whatever the number of threads: the same
//! bits on any thread count, no atomics. The order depends on the mesh and the wanted slab
//! size only.
//!
//! Out of cache the positions kernel prefetches the node and force rows a slab is about to
//! touch for the first time, from a schedule built here ([`row_prefetch_schedule`]).

use super::groups::LANES;
use crate::mesh::morton3;

/// Groups per block of the kernels' loop fission ([`super::x86`]), the unit of the
/// prefetch distances.
pub(crate) const BLK: usize = 4;

/// Blocks ahead of its first use in a slab that a node row's cache line is prefetched
/// ([`row_prefetch_schedule`]), when the element data and the two row arrays together
/// exceed twice the last-level cache ([`super::platform::l3_bytes`]). Out of cache the
/// hardware prefetcher follows the rows' streams (one per layer of nodes a slab spans) too
/// late; where the rows partly stay in the last-level cache the schedule costs more than it
/// saves, hence the footprint rule.
pub(super) const ROW_PREFETCH_BLOCKS: usize = 8;

/// Groups per lane-interleave window: inside a slab, the elements (in Morton order) are
/// taken in windows of `INTERLEAVE × LANES`, and lane `l` of the window's `q`-th group holds
/// the window's element `l · INTERLEAVE + q` (for a full window). Neighbouring elements in
/// Morton order share nodes; were they lanes of one group, the group's scatter-adds to a
/// shared node would be a chain of read-after-write through memory (store-to-load
/// forwarding) that the core cannot overlap. 16 apart, the lanes of a group rarely share a
/// node while a window (64 elements) still touches a compact set of nodes.
const INTERLEAVE: usize = 16;

/// Number of slabs for `wanted` slabs' worth of elements when at most `max` fit: 1 (serial)
/// below 2, else `wanted` rounded up to a multiple of 4 and capped at `max` rounded down to
/// one (fewer than 4 when `max` is). Slabs of a band alternate between 2 colours, so a
/// multiple of 4 gives each colour an even number of slabs and the two threads of a
/// 2-core machine equal shares in every colour.
pub(super) fn slab_count(wanted: usize, max: usize) -> usize {
    if wanted <= 1 || max <= 1 {
        return 1;
    }
    let n = wanted.next_multiple_of(4).min(max);
    if n >= 4 {
        n - n % 4
    } else {
        n
    }
}

/// The axis along which node ids grow at the middle of the three rates, judged by the mean
/// `|∂ id / ∂x_d|` over the elements (the gradient of the node id interpolated linearly on
/// each element, `∇id = Dm⁻ᵀ Δid`) times the mean element extent along `d`: on a
/// lexicographic grid numbering (x fastest, z slowest) about 1, `n_x` and `n_x n_y`, so `y`.
/// `None` without elements or when the rates are not finite. `dminv` column-major, 9 per
/// element.
pub(super) fn strip_axis(cells: &[u32], dminv: &[f64], ext: &[f64; 3], ne: usize) -> Option<usize> {
    if ne == 0 {
        return None;
    }
    let mut g = [0.0f64; 3];
    for e in 0..ne {
        let id = |k: usize| cells[4 * e + k] as f64;
        let did = [id(1) - id(0), id(2) - id(0), id(3) - id(0)];
        for (d, gd) in g.iter_mut().enumerate() {
            // (∇id)_d = Σ_k Dm⁻¹[k][d] Δid_k; column-major: Dm⁻¹[k][d] = dminv[9e + 3d + k].
            let v: f64 = (0..3).map(|k| dminv[9 * e + 3 * d + k] * did[k]).sum();
            *gd += v.abs();
        }
    }
    let rate: [f64; 3] = std::array::from_fn(|d| g[d] * ext[d]);
    if !rate.iter().all(|r| r.is_finite()) {
        return None;
    }
    let mut axes = [0usize, 1, 2];
    axes.sort_by(|&a, &b| rate[a].total_cmp(&rate[b]).then(a.cmp(&b)));
    Some(axes[1])
}

/// The force-pass order of the elements ([`force_pass_order`]).
pub(super) struct Order {
    /// The lanes of each group (element ids, `None` for a padding lane), slab by slab,
    /// slabs colour by colour.
    pub(super) lanes: Vec<[Option<u32>; LANES]>,
    /// Groups of slab s: `slab_ptr[s]..slab_ptr[s + 1]`.
    pub(super) slab_ptr: Vec<usize>,
    /// Slabs of colour c: `colour_ptr[c]..colour_ptr[c + 1]`.
    pub(super) colour_ptr: Vec<usize>,
}

/// Order the `ne` tetrahedra (`cells` 4 per element, `x0` the reference positions, 3 per
/// node, `dminv` 9 per element column-major) for the force pass, about `target_block`
/// elements per slab: slabs, strips, Morton order, colours and lane interleave as the
/// module docs say.
pub(super) fn force_pass_order(
    x0: &[f64],
    cells: &[u32],
    dminv: &[f64],
    ne: usize,
    target_block: usize,
) -> Order {
    let n_nodes = x0.len() / 3;
    // Centroids, bounding box, mean element extent per axis.
    let mut cen = vec![[0.0f64; 3]; ne];
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    let mut ext = [0.0f64; 3];
    for e in 0..ne {
        let mut emin = [f64::INFINITY; 3];
        let mut emax = [f64::NEG_INFINITY; 3];
        for k in 0..4 {
            let a = cells[4 * e + k] as usize * 3;
            for d in 0..3 {
                let x = x0[a + d];
                cen[e][d] += 0.25 * x;
                emin[d] = emin[d].min(x);
                emax[d] = emax[d].max(x);
            }
        }
        for d in 0..3 {
            lo[d] = lo[d].min(emin[d]);
            hi[d] = hi[d].max(emax[d]);
            ext[d] += emax[d] - emin[d];
        }
    }
    // Slab key: the mean node id of the element when the numbering is banded (each
    // slab then reads and writes one contiguous stretch of u and r: prefetchable), else
    // the centroid along the longest axis. Slabs at least two element "widths" thick
    // so that two colours usually suffice, about `target_block` elements each.
    let bw = (0..ne)
        .map(|e| {
            let el = &cells[4 * e..4 * e + 4];
            let (mn, mx) = el
                .iter()
                .fold((u32::MAX, 0), |(a, b), &c| (a.min(c), b.max(c)));
            (mx - mn) as usize
        })
        .max()
        .unwrap_or(0);
    let max_slabs_index = (n_nodes / (2 * bw.max(1))).max(1);
    let axis = (0..3)
        .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])))
        .unwrap_or(0);
    let mean_ext = if ne > 0 { ext[axis] / ne as f64 } else { 1.0 };
    let max_slabs_geo = ((hi[axis] - lo[axis]) / (2.0 * mean_ext.max(f64::MIN_POSITIVE)))
        .floor()
        .max(1.0) as usize;
    let wanted = ne.div_ceil(target_block.max(1));
    let by_index = max_slabs_index >= wanted.min(8);
    let slabs = slab_count(
        wanted,
        if by_index {
            max_slabs_index
        } else {
            max_slabs_geo
        },
    );
    let slab_key: Vec<f64> = (0..ne)
        .map(|e| {
            if by_index {
                cells[4 * e..4 * e + 4]
                    .iter()
                    .map(|&c| c as f64)
                    .sum::<f64>()
            } else {
                cen[e][axis]
            }
        })
        .collect();
    let mut by_axis: Vec<u32> = (0..ne as u32).collect();
    by_axis.sort_by(|&a, &b| {
        slab_key[a as usize]
            .total_cmp(&slab_key[b as usize])
            .then(a.cmp(&b))
    });
    let mut slab_of = vec![0u32; ne];
    for (rank, &e) in by_axis.iter().enumerate() {
        slab_of[e as usize] = (rank * slabs / ne.max(1)) as u32;
    }
    let q = |d: usize, x: f64| -> u64 {
        let w = hi[d] - lo[d];
        if w > 0.0 {
            (((x - lo[d]) / w) * ((1u64 << 21) - 1) as f64) as u64
        } else {
            0
        }
    };
    let key: Vec<u64> = cen
        .iter()
        .map(|c| morton3([q(0, c[0]), q(1, c[1]), q(2, c[2])]))
        .collect();
    // Strips inside a slab (banded numbering only): bands one mean element extent wide
    // across the axis along which the node id grows at the middle rate, so that a slab
    // is swept strip by strip along the axis of fastest-growing ids. A node's elements
    // then lie in its own strip and the neighbouring ones, and `u`, `r` and the element
    // data between two visits of a node stay in L2; in Morton order alone, elements
    // either side of a Morton block boundary meet again only much later.
    let strip = if by_index {
        strip_axis(cells, dminv, &ext, ne).map(|d| (d, ext[d] / ne as f64))
    } else {
        None
    };
    let strip_of = |e: usize| -> u64 {
        match strip {
            Some((d, w)) if w > 0.0 => ((cen[e][d] - lo[d]) / w) as u64,
            _ => 0,
        }
    };
    let mut order: Vec<u32> = (0..ne as u32).collect();
    order.sort_by_key(|&e| {
        let i = e as usize;
        (slab_of[i], strip_of(i), key[i], e)
    });
    // Slab ranges in `order`.
    let mut slab_range = vec![(0usize, 0usize); slabs];
    {
        let mut i = 0;
        for (s, r) in slab_range.iter_mut().enumerate() {
            let start = i;
            while i < ne && slab_of[order[i] as usize] as usize == s {
                i += 1;
            }
            *r = (start, i);
        }
    }
    // Greedy colouring of slabs: no two slabs of one colour share a node.
    let mut node_mask = vec![0u64; n_nodes];
    let mut colour = vec![0usize; slabs];
    let mut ok = true;
    for (s, &(a, b)) in slab_range.iter().enumerate() {
        let mut forbidden = 0u64;
        for &e in &order[a..b] {
            for k in 0..4 {
                forbidden |= node_mask[cells[4 * e as usize + k] as usize];
            }
        }
        if forbidden == u64::MAX {
            ok = false;
            break;
        }
        let c = forbidden.trailing_ones() as usize;
        colour[s] = c;
        for &e in &order[a..b] {
            for k in 0..4 {
                node_mask[cells[4 * e as usize + k] as usize] |= 1 << c;
            }
        }
    }
    if !ok {
        // Pathological mesh: one slab, serial.
        colour.iter_mut().for_each(|c| *c = 0);
        slab_range = vec![(0, ne)];
        colour.truncate(1);
    }
    let n_colours = colour.iter().max().map_or(0, |&c| c + 1);
    let mut slab_order: Vec<usize> = (0..slab_range.len()).collect();
    slab_order.sort_by_key(|&s| (colour[s], s));
    let mut colour_ptr = vec![0usize; n_colours + 1];
    for &c in &colour {
        colour_ptr[c + 1] += 1;
    }
    for c in 0..n_colours {
        colour_ptr[c + 1] += colour_ptr[c];
    }
    // Groups slab by slab (padding the last group of each slab).
    let slabs_in_order: Vec<&[u32]> = slab_order
        .iter()
        .map(|&s| &order[slab_range[s].0..slab_range[s].1])
        .collect();
    let (lanes, slab_ptr) = group_lanes(&slabs_in_order);
    Order {
        lanes,
        slab_ptr,
        colour_ptr,
    }
}

/// The lanes of each group, slab by slab (element ids in force-pass order), lanes
/// interleaved by [`INTERLEAVE`]; `None` marks a padding lane (only in the last window of a
/// slab). Returns the lanes and the slab pointers into them.
fn group_lanes(slabs: &[&[u32]]) -> (Vec<[Option<u32>; LANES]>, Vec<usize>) {
    let ne: usize = slabs.iter().map(|s| s.len()).sum();
    let mut lanes = Vec::with_capacity(ne / LANES + slabs.len());
    let mut slab_ptr = vec![0usize];
    for slab in slabs {
        for window in slab.chunks(INTERLEAVE * LANES) {
            // Lane l of the window's group q holds element l·wg + q of the window.
            let wg = window.len().div_ceil(LANES);
            for q in 0..wg {
                lanes.push(std::array::from_fn(|l| window.get(l * wg + q).copied()));
            }
        }
        slab_ptr.push(lanes.len());
    }
    (lanes, slab_ptr)
}

/// The row prefetch schedule of the positions kernel: per slab, the first block in the
/// global block numbering (`block_base`), and per block the 64-byte lines of node and force
/// rows to prefetch (`rows_pf[rows_pf_ptr[b]..rows_pf_ptr[b + 1]]`, line = node id / 2).
#[derive(Clone, Debug, Default)]
pub(super) struct RowPrefetch {
    pub(super) block_base: Vec<usize>,
    pub(super) rows_pf_ptr: Vec<u32>,
    pub(super) rows_pf: Vec<u32>,
}

/// The positions kernel's row prefetch schedule from the groups' corner offsets
/// (`idx_of(group)`, padding lanes included): for each slab, in the kernel's order (blocks
/// of [`BLK`] groups, corners, lanes), the first access in the slab to each 64-byte line of
/// the node rows (two 32-byte rows, nodes `2i` and `2i + 1`) is scheduled `dist` blocks
/// earlier (block 0 at the latest), for the node rows and the force rows alike; `dist = 0`
/// schedules nothing. Returns the first block of each slab in the global block numbering,
/// the list pointers per block and the line lists.
pub(super) fn row_prefetch_schedule(
    idx_of: impl Fn(usize) -> [[u32; LANES]; 4],
    slab_ptr: &[usize],
    n_nodes: usize,
    dist: usize,
) -> RowPrefetch {
    let mut block_base = Vec::with_capacity(slab_ptr.len());
    let mut stamp = vec![0u32; n_nodes.div_ceil(2)];
    let mut pairs: Vec<(u32, u32)> = Vec::new(); // (global block, line)
    let mut blocks = 0usize;
    for (s, w) in slab_ptr.windows(2).enumerate() {
        block_base.push(blocks);
        for gi in w[0]..w[1] {
            let b = ((gi - w[0]) / BLK).saturating_sub(dist);
            for corner in idx_of(gi) {
                for o in corner {
                    // Offsets are 4 × node id; a line holds two rows.
                    let line = o as usize / 8;
                    if dist > 0 && stamp[line] != s as u32 + 1 {
                        stamp[line] = s as u32 + 1;
                        pairs.push(((blocks + b) as u32, line as u32));
                    }
                }
            }
        }
        blocks += (w[1] - w[0]).div_ceil(BLK);
    }
    block_base.push(blocks);
    let mut ptr = vec![0u32; blocks + 1];
    for &(b, _) in &pairs {
        ptr[b as usize + 1] += 1;
    }
    for b in 0..blocks {
        ptr[b + 1] += ptr[b];
    }
    let mut fill: Vec<u32> = ptr.clone();
    let mut lines = vec![0u32; pairs.len()];
    for &(b, line) in &pairs {
        lines[fill[b as usize] as usize] = line;
        fill[b as usize] += 1;
    }
    RowPrefetch {
        block_base,
        rows_pf_ptr: ptr,
        rows_pf: lines,
    }
}
