//! Packed force pass of compressible neo-Hookean tetrahedra (the benchmark work), and the
//! fused explicit step built on it.
//!
//! `P = μ (F − F⁻ᵀ) + λ ln J F⁻ᵀ`, the corner forces `R_j = V0 P Dm⁻ᵀ e_j` (j = 1..3),
//! `R_0 = −Σ R_j`: the same `R = ∂E/∂u` as the generic `P = F S(C)` path (tested against
//! [`super::FemModel::internal_forces_reference`]). Two kernels compute it.
//!
//! **Positions kernel** (f64 storage, the default). With `Ds = [x1−x0, x2−x0, x3−x0]` from
//! the current positions `x = X + u`, `F = Ds Dm⁻¹`, and since `cof(A B) = cof A cof B` and
//! `cof(Dm⁻¹) Dm⁻ᵀ = det Dm⁻¹ I`:
//!
//! ```text
//! H = V0 P Dm⁻ᵀ = Ds G + c cof Ds,   G = μ V0 Dm⁻¹ Dm⁻ᵀ,
//! J = det Ds · det Dm⁻¹,   c = (λ ln J − μ) / (6 J)
//! ```
//!
//! (`V0 det Dm⁻¹ = 1/6`: the force model admits positively oriented tetrahedra only).
//! `G` (6 entries, symmetric) and `det Dm⁻¹` are precomputed: 72 bytes per tetrahedron with
//! the 4 node offsets, 156 flops, against 96 bytes and 213 flops for `F = I + Du Dm⁻¹`,
//! `cof F`, `V0 P`, `P Dm⁻ᵀ`. The node rows the kernel reads hold `X + u`, built by the
//! force model from `u` (or advanced in place by the fused step's node update). The
//! rounding differs from the displacement form: `Ds` carries the rounding of `X + u` (an ulp
//! of the coordinates, relative `ulp(|X|) / h` to an edge of length `h`), so where the
//! displacement form's `F − I` is exact to the last bit the positions form is within about
//! `1e-14` of the strain on the meshes here; the forces match the generic path within
//! `1e-12` of their largest entry (tested).
//!
//! **Displacements kernel** (f32 storage): `F = I + Du Dm⁻¹`, `J = det F`, `cof F = J F⁻ᵀ`,
//! `V0 P = a F + b cof F` with `a = μ V0`, `b = V0 (λ ln J − μ) / J`, `H = V0 P Dm⁻ᵀ`. It
//! reads `u` and keeps `Dm⁻¹` and `V0` per element: with `Dm⁻¹` rounded to f32, the strain
//! `Du Dm⁻¹` keeps its relative accuracy at small strain. The positions form with f32
//! storage would round `det Dm⁻¹` (hence `J`) and `G` to f32, an error of `6e-8` on `J` and on
//! the rest-state balance of `Ds G` against `c cof Ds`, larger than the strain itself in soft
//! tissue under gravity.
//!
//! `ln J` is a series (`ln.rs`): of `ln(1 + f)`, `f = J − 1`, where `|f| < 2⁻⁵`, else a
//! branch-free `2 atanh` series; both within 1 ulp of `f64::ln` on the tested sweeps.
//!
//! Each kernel comes portable (`portable.rs`: lane loops) and with AVX2 + FMA intrinsics, the
//! positions kernel also with AVX-512 in 8 lanes (`x86.rs`), all with the same operations per
//! element and the same bits; the widest that pays on the CPU is picked at run time
//! (`platform.rs`; `RAISOV_ISA=portable`, `avx2` or `avx512` overrides it).
//!
//! Node rows: the kernels read node values from, and accumulate forces into, rows of 32
//! bytes `[x, y, z, 0]` ([`Row4`], aligned), so that a corner of a lane is one 256-bit
//! access.
//!
//! Layout (`layout.rs`): elements packed in groups of [`LANES`] (structure of arrays inside
//! a group, `groups.rs`), sorted into slabs, strips and Morton order; slabs coloured so that the
//! slabs of one colour share no node and scatter into `r` concurrently. Every node receives
//! its element contributions in one fixed order whatever the number of threads: the same
//! bits on any thread count, no atomics.
//!
//! Precision ([`Precision`], chosen per model by [`super::FemParams::precision`]): f64
//! storage (`Precision::F64`, the default) runs the positions kernel on 72 bytes per
//! tetrahedron; f32 storage (`Precision::F32Storage`) runs the displacements kernel with
//! `Dm⁻¹` and the reference volume in f32 (4 × u32 offsets + 9 × f32 + 1 × f32, 56 bytes per
//! tetrahedron). The f32 values are widened exactly to f64 on load (`_mm256_cvtps_pd`,
//! `f32 as f64`) and every operation, `u`, `r`, the state and the masses stay f64, so all
//! ISAs and thread counts give the same bits within each precision. What differs from
//! f64 is the rounding of `Dm⁻¹` and `V0` to f32 once, at packing (relative error ≤ 2⁻²⁴ ≈
//! 6e-8 per entry), which perturbs the forces by about that much times the conditioning of
//! the element, and the kernel's own rounding (above). Stated tolerance (tested in
//! `fem::packed::tests`): on a jittered mesh, `‖R_f32 − R_f64‖₂ ≤ 1e-6 ‖R_f64‖₂` and every
//! entry within `1e-6 max|R_f64|`. The deviations the test meets (it prints them): 2e-8
//! (2-norm) and 3e-8 to 5e-8 (max entry) under random deformations of 1 % to 30 % of the
//! shortest edge; 1.2e-7 and 1.6e-7 under an affine stretch, where the interior forces
//! cancel (patch test) and f32 storage leaves a residue of that size. The 500-step standard
//! work of the benchmark (`raisov bench`, crate `raisov-lab`) on the 1k box agrees with f64 to better than 5 significant digits (tested < 5e-6 relative). The lumped masses, the
//! strain energy, the stresses and the generic path keep the f64 `Dm⁻¹` and volumes. f32
//! storage can pay only where the force pass is bandwidth-bound, and its kernel does more
//! arithmetic than the positions kernel (213 flops against 156 per tetrahedron).
//!
//! The fused explicit step ([`FemModel::step_symplectic_euler`], [`FusedState`],
//! [`NodeLoad`]) is in `fused.rs`.
//!
//! [`FemModel::step_symplectic_euler`]: super::FemModel::step_symplectic_euler
//!
//! Files of this module, one concern each:
//! - `mod.rs`: `TetPack` (packing and the parallel force pass), [`Row4`], [`Precision`],
//!   the node rows' fill and drain;
//! - `groups.rs`: the packed element data and their packing;
//! - `layout.rs`: slabs, strips, colouring, lane interleave, the row prefetch schedule;
//! - `ln.rs`: `ln J` as the kernels take it;
//! - `portable.rs`: the portable kernels, the reference of the SIMD ones;
//! - `lanes.rs`: the `Lanes` vector operations over 4 and 8 f64 lanes (x86-64 only);
//! - `x86.rs`: the AVX2 and AVX-512 kernels (x86-64 only);
//! - `platform.rs`: instruction set (`Isa`, `RAISOV_ISA`), cache size, huge pages;
//! - `fused.rs`: the fused explicit step;
//! - `tests.rs`: the kernels against each other and the reference path.

mod fused;
mod groups;
#[cfg(target_arch = "x86_64")]
mod lanes;
mod layout;
mod ln;
mod platform;
mod portable;
#[cfg(test)]
mod tests;
#[cfg(target_arch = "x86_64")]
mod x86;

pub use fused::{FusedState, NodeLoad};
pub use groups::{BYTES_PER_TET, LANES};
pub(crate) use platform::huge_page_vec;

use groups::{pack_displacement_groups, pack_position_groups, Group, PGroup};
use layout::RowPrefetch;
use platform::Isa;
use rayon::prelude::*;

/// One node's row in the force pass's node arrays: `[x, y, z, 0]`, 32 bytes, aligned so
/// that a row is one 256-bit load or store and never straddles a cache line.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(32))]
pub struct Row4(pub [f64; 4]);

/// Storage precision of the packed element data (`Dm⁻¹` and reference volume). Arithmetic,
/// displacements, forces, velocities and masses are f64 in both; see the module docs for
/// what changes and the tolerance against f64.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Precision {
    /// Everything in f64 (72 bytes of element data per tetrahedron, the positions kernel).
    /// The default.
    #[default]
    F64,
    /// `Dm⁻¹` and the reference volume stored in f32, widened to f64 on load (56 bytes per
    /// tetrahedron); arithmetic and state in f64.
    F32Storage,
}

impl Precision {
    /// Both, f64 first.
    pub const ALL: [Precision; 2] = [Precision::F64, Precision::F32Storage];

    /// The name used in scenarios, on the command line and in the benchmark table:
    /// `"f64"` or `"f32-storage"`.
    pub fn name(self) -> &'static str {
        match self {
            Precision::F64 => "f64",
            Precision::F32Storage => "f32-storage",
        }
    }

    /// Inverse of [`Precision::name`].
    pub fn from_name(s: &str) -> Option<Precision> {
        Precision::ALL.into_iter().find(|p| p.name() == s)
    }

    /// Bytes of packed element data per tetrahedron: 72 (f64) or 56 (f32 storage).
    pub fn bytes_per_tet(self) -> usize {
        match self {
            Precision::F64 => BYTES_PER_TET,
            Precision::F32Storage => std::mem::size_of::<Group<f32>>() / LANES,
        }
    }

    /// `x` as the packed path sees it: unchanged (f64) or rounded to f32.
    #[inline]
    pub fn round(self, x: f64) -> f64 {
        match self {
            Precision::F64 => x,
            Precision::F32Storage => x as f32 as f64,
        }
    }
}

/// The packed groups in one of the storage precisions.
enum Groups {
    /// Positions kernel.
    F64(Vec<PGroup>),
    /// Displacements kernel, `Dm⁻¹` and `V0` in f32.
    F32(Vec<Group<f32>>),
}

/// Packed neo-Hookean tetrahedra in force-pass order.
pub(crate) struct TetPack {
    mu: f64,
    lambda: f64,
    groups: Groups,
    /// Groups of slab s: `slab_ptr[s]..slab_ptr[s + 1]`, slabs stored colour by colour.
    slab_ptr: Vec<usize>,
    /// Slabs of colour c: `colour_ptr[c]..colour_ptr[c + 1]`.
    colour_ptr: Vec<usize>,
    n_nodes: usize,
    /// Instruction set of the kernel.
    isa: Isa,
    /// Row prefetch schedule of the positions kernel ([`layout::row_prefetch_schedule`]).
    rows_pf: RowPrefetch,
}

/// A pointer to the force rows shared by the slabs of one colour.
#[derive(Clone, Copy)]
struct SyncPtr(*mut f64);
// SAFETY: used only for disjoint writes (slabs of one colour share no node).
unsafe impl Send for SyncPtr {}
unsafe impl Sync for SyncPtr {}

impl TetPack {
    /// The pack of a neo-Hookean mesh's whole elements, and the elements left out: those of
    /// a cut mesh holding part of their tetrahedron (`fractions` below 1), which the force
    /// pass evaluates on the generic path beside the pack (its volumetric term takes an
    /// element's volume from `det Dm⁻¹`, which a fraction does not scale). No pack where no
    /// element is whole. Arguments as [`TetPack::new`], `measure` the scaled volumes.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn of_whole(
        law: &crate::material::NeoHookean,
        x0: &[f64],
        cells: &[u32],
        dminv: &[f64],
        measure: &[f64],
        fractions: Option<&[f64]>,
        target_block: usize,
        precision: Precision,
    ) -> (Option<TetPack>, Vec<u32>) {
        let ne = measure.len();
        let partial: Vec<u32> = match fractions {
            Some(f) => (0..ne as u32).filter(|&e| f[e as usize] < 1.0).collect(),
            None => Vec::new(),
        };
        if partial.len() == ne {
            return (None, Vec::new());
        }
        let pack = |cells: &[u32], dminv: &[f64], measure: &[f64]| {
            TetPack::new(
                law.mu,
                law.lambda,
                x0,
                cells,
                dminv,
                measure,
                target_block,
                precision,
            )
        };
        if partial.is_empty() {
            return (Some(pack(cells, dminv, measure)), partial);
        }
        let mut whole = vec![true; ne];
        for &e in &partial {
            whole[e as usize] = false;
        }
        fn keep<T: Copy>(v: &[T], stride: usize, whole: &[bool]) -> Vec<T> {
            v.chunks_exact(stride)
                .zip(whole)
                .filter(|(_, &w)| w)
                .flat_map(|(c, _)| c.iter().copied())
                .collect()
        }
        let p = pack(
            &keep(cells, 4, &whole),
            &keep(dminv, 9, &whole),
            &keep(measure, 1, &whole),
        );
        (Some(p), partial)
    }

    /// Pack the elements. `cells` 4 per element, `dminv` 9 per element column-major,
    /// `target_block` the wanted elements per slab, `precision` that of the stored `dminv`
    /// and `vol`.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn new(
        mu: f64,
        lambda: f64,
        x0: &[f64],
        cells: &[u32],
        dminv: &[f64],
        vol: &[f64],
        target_block: usize,
        precision: Precision,
    ) -> TetPack {
        let ne = vol.len();
        let n_nodes = x0.len() / 3;
        assert!(
            4 * n_nodes <= u32::MAX as usize,
            "too many nodes for u32 offsets"
        );
        let order = layout::force_pass_order(x0, cells, dminv, ne, target_block);
        let lanes = &order.lanes;
        let groups = match precision {
            Precision::F64 => Groups::F64(pack_position_groups(lanes, mu, cells, dminv, vol)),
            Precision::F32Storage => {
                Groups::F32(pack_displacement_groups(lanes, cells, dminv, vol))
            }
        };
        let mut pack = TetPack {
            mu,
            lambda,
            groups,
            slab_ptr: order.slab_ptr,
            colour_ptr: order.colour_ptr,
            n_nodes,
            isa: Isa::detect(),
            rows_pf: RowPrefetch::default(),
        };
        // Row prefetch only out of cache (it slows the pass where the rows come from L3).
        let footprint = pack.bytes() + 2 * std::mem::size_of::<Row4>() * n_nodes;
        pack.set_row_prefetch(if footprint > 2 * platform::l3_bytes() {
            layout::ROW_PREFETCH_BLOCKS
        } else {
            0
        });
        pack
    }

    /// Build the positions kernel's row prefetch schedule `dist` blocks ahead (0: none;
    /// [`layout::row_prefetch_schedule`]); the displacements kernel has none.
    pub(crate) fn set_row_prefetch(&mut self, dist: usize) {
        self.rows_pf = match &self.groups {
            Groups::F64(g) => {
                layout::row_prefetch_schedule(|i| g[i].idx, &self.slab_ptr, self.n_nodes, dist)
            }
            Groups::F32(_) => RowPrefetch::default(),
        };
    }

    /// Number of slabs (parallel tasks) and colours (sequential phases).
    pub(crate) fn layout(&self) -> (usize, usize) {
        (self.slab_ptr.len() - 1, self.colour_ptr.len() - 1)
    }

    /// Bytes of the packed element data.
    pub(crate) fn bytes(&self) -> usize {
        match &self.groups {
            Groups::F64(g) => std::mem::size_of_val(&g[..]),
            Groups::F32(g) => std::mem::size_of_val(&g[..]),
        }
    }

    /// Storage precision of the element data.
    pub(crate) fn precision(&self) -> Precision {
        match self.groups {
            Groups::F64(_) => Precision::F64,
            Groups::F32(_) => Precision::F32Storage,
        }
    }

    /// Whether the node rows given to [`TetPack::accumulate`] hold positions `X + u` (f64
    /// storage: the positions kernel) or displacements `u` (f32 storage).
    pub(crate) fn reads_positions(&self) -> bool {
        matches!(self.groups, Groups::F64(_))
    }

    /// `r += R` for the node rows `q`, positions or displacements as
    /// [`TetPack::reads_positions`] says (`r` must hold what is to be accumulated onto,
    /// usually zeros; the fourth entry of a row is read as nothing and stays as it is in `r`
    /// plus zeros). Returns false if some element has `J <= 0` (or NaN); `r` is then
    /// unspecified.
    pub(crate) fn accumulate(&self, q: &[Row4], r: &mut [Row4]) -> bool {
        assert!(q.len() >= self.n_nodes && r.len() >= self.n_nodes);
        let rp = SyncPtr(r.as_mut_ptr() as *mut f64);
        let n_slabs = self.slab_ptr.len() - 1;
        let mut good = true;
        for c in 0..self.colour_ptr.len() - 1 {
            let (s0, s1) = (self.colour_ptr[c], self.colour_ptr[c + 1]);
            let run = |s: usize| -> bool {
                // SAFETY: node ids were checked < n_nodes at construction, q and r have
                // n_nodes rows (asserted above), and slabs of one colour share no node, so
                // concurrent slabs write disjoint rows of r.
                unsafe { self.run_slab(s, q, rp) }
            };
            good &= if n_slabs >= 2 && s1 - s0 >= 2 {
                (s0..s1)
                    .into_par_iter()
                    .map(run)
                    .reduce(|| true, |a, b| a & b)
            } else {
                (s0..s1).map(run).fold(true, |a, b| a & b)
            };
        }
        good
    }

    /// Use kernel `isa`, or the widest this CPU runs if lower (tests compare the kernels).
    #[cfg(test)]
    pub(crate) fn force_isa(&mut self, isa: Isa) {
        self.isa = isa.min(Isa::supported());
    }

    /// `r += R` over the first `n` groups of the f64 storage's first slab only, with kernel
    /// `isa` as [`TetPack::force_isa`] (tests: every group count of the AVX-512 kernel's
    /// pairs and blocks against AVX2). False if the storage is not f64 or the slab is shorter.
    #[cfg(test)]
    pub(crate) fn run_first_groups(&self, n: usize, isa: Isa, q: &[Row4], r: &mut [Row4]) -> bool {
        let Groups::F64(g) = &self.groups else {
            return false;
        };
        if n > self.slab_ptr[1] - self.slab_ptr[0] {
            return false;
        }
        let (xp, rp) = (q.as_ptr() as *const f64, r.as_mut_ptr() as *mut f64);
        let (g, mu, lambda) = (
            &g[self.slab_ptr[0]..self.slab_ptr[0] + n],
            self.mu,
            self.lambda,
        );
        #[cfg(target_arch = "x86_64")]
        let blocks = vec![0; n.div_ceil(layout::BLK) + 1];
        #[cfg(target_arch = "x86_64")]
        let pf = (&blocks[..], &[][..]);
        assert!(q.len() >= self.n_nodes && r.len() >= self.n_nodes);
        // SAFETY: as `run_slab`: node ids are < n_nodes, q and r hold n_nodes rows, the
        // empty prefetch schedule has an entry per block, and the kernel runs only where
        // `Isa::supported` reports its instructions.
        unsafe {
            match isa.min(Isa::supported()) {
                #[cfg(target_arch = "x86_64")]
                Isa::Avx512 => x86::run_positions_avx512(g, pf, xp, rp, mu, lambda),
                #[cfg(target_arch = "x86_64")]
                Isa::Avx2 => x86::run_positions_avx2(g, pf, xp, rp, mu, lambda),
                _ => portable::run_positions(g, xp, rp, mu, lambda),
            }
        }
    }

    /// The kernel in use: `"portable"`, `"avx2"` or `"avx512"`.
    pub(crate) fn isa(&self) -> &'static str {
        self.isa.name()
    }

    /// `r += R` over the groups of slab `s`, with the kernel of [`TetPack::isa`]; false if
    /// some element has `J <= 0` (or NaN).
    ///
    /// # Safety
    /// - `q` has at least `n_nodes` rows and `r` points to at least `n_nodes` rows (four
    ///   f64 each, 32-byte aligned, as [`Row4`]), valid for reads and writes.
    /// - No other thread reads or writes the rows of `r` that slab `s` touches during the
    ///   call (slabs of one colour share no node, so the slabs of one colour may run
    ///   concurrently).
    #[inline]
    unsafe fn run_slab(&self, s: usize, q: &[Row4], r: SyncPtr) -> bool {
        let (a, b) = (self.slab_ptr[s], self.slab_ptr[s + 1]);
        let qp = q.as_ptr() as *const f64;
        let (mu, lambda) = (self.mu, self.lambda);
        match &self.groups {
            Groups::F64(g) => {
                #[cfg(target_arch = "x86_64")]
                if self.isa >= Isa::Avx2 {
                    let pf = &self.rows_pf.rows_pf_ptr
                        [self.rows_pf.block_base[s]..=self.rows_pf.block_base[s + 1]];
                    let pf = (pf, &self.rows_pf.rows_pf[..]);
                    if self.isa == Isa::Avx512 {
                        return x86::run_positions_avx512(&g[a..b], pf, qp, r.0, mu, lambda);
                    }
                    return x86::run_positions_avx2(&g[a..b], pf, qp, r.0, mu, lambda);
                }
                portable::run_positions(&g[a..b], qp, r.0, mu, lambda)
            }
            Groups::F32(g) => {
                #[cfg(target_arch = "x86_64")]
                if self.isa >= Isa::Avx2 {
                    return x86::run_groups_avx2(&g[a..b], qp, r.0, mu, lambda);
                }
                portable::run_groups(&g[a..b], qp, r.0, mu, lambda)
            }
        }
    }
}

/// Node `a`'s row from `u` and `x0` (3 per node, `a` counted in those slices):
/// `[X_a + u_a, 0]` (`positions`) or `[u_a, 0]`.
#[inline(always)]
fn node_row(u: &[f64], x0: &[f64], a: usize, positions: bool) -> Row4 {
    let i = 3 * a;
    Row4(if positions {
        [
            x0[i] + u[i],
            x0[i + 1] + u[i + 1],
            x0[i + 2] + u[i + 2],
            0.0,
        ]
    } else {
        [u[i], u[i + 1], u[i + 2], 0.0]
    })
}

/// `rows[a] = [X_a + u_a, 0]` (`positions`) or `[u_a, 0]`, in parallel chunks.
pub(super) fn fill_rows(rows: &mut [Row4], u: &[f64], x0: &[f64], positions: bool) {
    const NB: usize = 4096;
    let body = |(rc, (uc, xc)): (&mut [Row4], (&[f64], &[f64]))| {
        for (a, row) in rc.iter_mut().enumerate() {
            *row = node_row(uc, xc, a, positions);
        }
    };
    if rows.len() >= 2 * NB {
        rows.par_chunks_mut(NB)
            .zip(u.par_chunks(3 * NB).zip(x0.par_chunks(3 * NB)))
            .for_each(body);
    } else {
        body((rows, (u, x0)));
    }
}

/// `r[3a + k] = acc[a][k]` and `acc[a] = 0`, in parallel chunks.
pub(super) fn drain_rows(acc: &mut [Row4], r: &mut [f64]) {
    const NB: usize = 4096;
    let body = |(ac, rc): (&mut [Row4], &mut [f64])| {
        for (row, ra) in ac.iter_mut().zip(rc.chunks_exact_mut(3)) {
            ra.copy_from_slice(&row.0[..3]);
            *row = Row4::default();
        }
    };
    if acc.len() >= 2 * NB {
        acc.par_chunks_mut(NB)
            .zip(r.par_chunks_mut(3 * NB))
            .for_each(body);
    } else {
        body((acc, r));
    }
}
