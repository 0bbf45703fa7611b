//! The performance benchmark (`raisov bench`): the standard explicit-dynamics work and a
//! STREAM-like triad measured in the same run as the roofline.
//!
//! Standard work: box 0.1 x 0.04 x 0.04 m of linear tetrahedra (5 per cube, nodes x fastest
//! in the file the peers read; raisov renumbers it at load as it does any mesh file,
//! [`standard_box_loaded`]),
//! nodes at x = 0 fixed; compressible neo-Hookean
//! `ψ = μ/2 (tr C − 3) − μ ln J + λ/2 (ln J)²`, E = 5e4 Pa, ν = 0.4, ρ = 1000 kg/m³,
//! gravity (0, −9.81, 0), no damping, lumped mass, symplectic Euler,
//! `Δ = 0.2 h_min / c`, `c = √((λ + 2μ)/ρ)`. A node-update is one node advanced one step.
//!
//! Precision: the standard-work rows are measured for each [`Precision`] asked for
//! ([`BenchOptions::precisions`]): `f64` (everything f64) and `f32-storage` (`Dm⁻¹` and
//! volumes stored in f32, arithmetic and state f64; tolerance in [`raisov::fem::packed`]).
//!
//! Bytes moved per tet-step *by design* (compulsory traffic if every array is streamed once
//! per step): the packed element data ([`Precision::bytes_per_tet`]: 72 B in f64: 4 ids,
//! the 6 entries of `G = μ V0 Dm⁻¹ Dm⁻ᵀ`, `det Dm⁻¹`; 56 B with f32 storage: 4 ids, 9
//! `Dm⁻¹` entries, the volume) plus, per node ([`bytes_per_node_step`]), the force pass
//! reading the node row (32 B) and reading and writing the accumulator row (64 B), and the
//! node pass reading `v` (24 B), the accumulator row (32 B), the node row (32 B), `1/m`
//! (8 B) and the fixed flag (1 B), and writing `v` (24 B), the accumulator row (32 B) and
//! the node row (32 B): 281 B per node, in f64 (rows `X + u`) and with f32 storage (rows
//! `u`) alike. The node row is the configuration itself, advanced in place, and gravity a
//! uniform acceleration ([`NodeLoad::Acceleration`]): nothing else is read per node.
//! Rows are 32 bytes (`[x, y, z, 0]`). Achieved bandwidth = bytes × tets × steps/s. The memory roof
//! is a triad `a = b + s c` (24 B per entry, STREAM counting) on arrays of the same total size
//! as the model's data, on the same number of threads, best of 3.
//!
//! Floating-point operations per tet-step *by design*, counted in the kernel's source (a fused
//! multiply-add counts 2, a division 1; comparisons, blends, sign flips, shuffles and
//! conversions 0), [`flops_per_tet`]: in f64 (the positions kernel) 156 for the force (`Ds`
//! 9, `cof Ds` and `det Ds` 32, `J` 1, `(λ ln J − μ)/(6 J)` with the near-1 series 30,
//! `H = Ds G + c cof Ds` 63, `R_0` 9, the scatter 12); with f32 storage (the displacements
//! kernel) 213 (`Du` 9, `F` 48, `cof F` and `J` 32, `V0 (λ ln J − μ)/J` 30, `V0 P` and `H`
//! 82, the scatter 12); plus
//! [`FLOPS_PER_NODE_STEP`] = 24 per node for the update (8 per component), spread over the
//! tetrahedra. The compute roof is the f64 fused-multiply-add peak of the same threads,
//! measured in the same run ([`fma_peak`]). The roofline fraction is the achieved rate over
//! the attainable one, `min(compute roof, memory roof)`: the larger of the two fractions, and
//! the lower roof is the one that binds. Zen 4's two extra add pipes are not in the peak (it
//! counts FMAs only, as rooflines do), so the compute fraction of a kernel with many plain
//! adds and multiplies reads low.
//!
//! Further rows: the integrators through the generic [`System`] path (symplectic Euler,
//! central difference, RK4), one RaISoV V-cycle over [`VCYCLE_LEVELS`] levels at node
//! ratio [`VCYCLE_RATIO`] against one single-level step (cost ratio; the node-count ratio
//! `Σ rⁱ` is the ideal) and the levels' single steps timed alone (eq. 14's first term: the
//! rest of the cycle is the mapping), the membrane, the correspondence build of one level pair
//! (≥ 1M-node fine level); and peak memory per node of the largest box, read right after the
//! standard-work rows so that the larger hierarchy rows do not count.
//!
//! One concern, `raisov bench`: the rows share the standard work, the timing rule and the
//! roofline bookkeeping, so they stay in one file.

mod api;
pub mod cut;
pub mod frames;
mod implicit;
#[cfg(feature = "rapier")]
pub mod rapier_peer;
pub use api::api;
pub use implicit::implicit;
pub mod surface_check;

use raisov::fem::{FemModel, FemParams, FusedState, NodeLoad, Precision};
use raisov::hierarchy::Correspondence;
use raisov::integrate::{Constraints, Method, SingleLevel, State, Stepper, StepperParams, System};
use raisov::material::{Material, NeoHookean};
use raisov::mesh::generate::{box_tets_target, rectangle_membrane, BoxPattern};
use raisov::mesh::Mesh;
use raisov::multigrid::raisov::{Raisov, RaisovParams, Reading};
use raisov::multigrid::Level;
use raisov::{Error, Result};
use rayon::prelude::*;
use std::time::Instant;

/// Box size of the standard work (m).
pub const BOX: [f64; 3] = [0.1, 0.04, 0.04];
/// Levels and node ratio of the V-cycle cost row.
pub const VCYCLE_LEVELS: usize = 4;
pub const VCYCLE_RATIO: f64 = 0.5;
/// Gravity of the standard work (m/s²).
pub const GRAVITY: [f64; 3] = [0.0, -9.81, 0.0];
/// Node-side bytes per node-step of the fused step, by design (see the module docs): 281,
/// whatever the precision (the rows hold `X + u` in f64, `u` with f32 storage).
pub fn bytes_per_node_step(_precision: Precision) -> usize {
    281
}

/// Floating-point operations per tetrahedron of one force pass of the packed neo-Hookean
/// kernels, by design (see the module docs; the near-1 logarithm series): 156 for the
/// positions kernel (f64), 213 for the displacements kernel (f32 storage).
pub fn flops_per_tet(precision: Precision) -> usize {
    match precision {
        Precision::F64 => 156,
        Precision::F32Storage => 213,
    }
}
/// Floating-point operations per node of the fused step's node update, by design:
/// `v += Δ ((V − R)/m − α v)`, `u += Δ v`, 8 per component.
pub const FLOPS_PER_NODE_STEP: usize = 24;

/// The standard box with about `nodes` nodes (5 tets per cube, nodes numbered x fastest):
/// the mesh `raisov bench --write-mesh` writes for the peers.
pub fn standard_box(nodes: usize) -> Result<Mesh> {
    box_tets_target(BOX, nodes, BoxPattern::Five)
}

/// [`standard_box`] as raisov loads that file (`raisov run` renumbers a mesh file's nodes by
/// default): renumbered once by [`Mesh::spatial_order`]. Every row of the benchmark and the
/// correctness check run on it; the node-updates and the checked values are those of the
/// file's numbering (the free-end mean sums the same nodes in another order).
pub fn standard_box_loaded(nodes: usize) -> Result<Mesh> {
    let mut mesh = standard_box(nodes)?;
    let order = mesh.spatial_order();
    mesh.renumber(&order);
    Ok(mesh)
}

/// The standard material: neo-Hookean, E = 5e4 Pa, ν = 0.4.
pub fn standard_material() -> NeoHookean {
    NeoHookean::from_young(5e4, 0.4)
}

/// The standard work on one mesh, advanced by the fused symplectic-Euler step.
pub struct StandardWork {
    pub model: FemModel,
    pub mass: Vec<f64>,
    pub inv_mass: Vec<f64>,
    pub f_ext: Vec<f64>,
    pub fixed: Vec<bool>,
    /// Nodes at x = max (the free end).
    pub free_end: Vec<u32>,
    pub dt: f64,
    /// Displacements and velocities.
    pub state: FusedState,
    pub steps: usize,
}

/// Mean y-displacement of the free end and the largest |u| (the correctness check).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Check {
    pub nodes: usize,
    pub steps: usize,
    pub precision: Precision,
    pub mean_uy_free_end: f64,
    pub max_abs_u: f64,
}

impl StandardWork {
    /// Fixed nodes: x = min; free end: x = max; gravity (0, −9.81, 0). Element data in f64.
    pub fn new(mesh: &Mesh) -> Result<StandardWork> {
        Self::with_precision(mesh, Precision::F64)
    }

    /// As [`StandardWork::new`], the element data stored in `precision`.
    pub fn with_precision(mesh: &Mesh, precision: Precision) -> Result<StandardWork> {
        let m = standard_material();
        let mut p = FemParams::new(Material::NeoHookean(m));
        p.density = 1000.0;
        p.precision = precision;
        let model = FemModel::new(mesh, p)?;
        let mass = model.lumped_mass();
        let inv_mass: Vec<f64> = mass
            .iter()
            .map(|&m| if m > 0.0 { 1.0 / m } else { 0.0 })
            .collect();
        let g = GRAVITY;
        let f_ext: Vec<f64> = mass
            .iter()
            .flat_map(|&m| [m * g[0], m * g[1], m * g[2]])
            .collect();
        let (lo, hi) = mesh.bounding_box();
        let fixed: Vec<bool> = mesh.nodes.iter().map(|p| p[0] == lo[0]).collect();
        let free_end: Vec<u32> = (0..mesh.num_nodes() as u32)
            .filter(|&a| mesh.nodes[a as usize][0] == hi[0])
            .collect();
        let c = ((m.lambda + 2.0 * m.mu) / 1000.0).sqrt();
        let dt = 0.2 * mesh.edge_range().0 / c;
        let n = mesh.num_nodes();
        Ok(StandardWork {
            model,
            mass,
            inv_mass,
            f_ext,
            fixed,
            free_end,
            dt,
            state: FusedState::zeros(n),
            steps: 0,
        })
    }

    pub fn num_nodes(&self) -> usize {
        self.mass.len()
    }

    /// Advance `k` fused steps.
    pub fn advance(&mut self, k: usize) -> Result<()> {
        for _ in 0..k {
            self.model
                .step_symplectic_euler(
                    &mut self.state,
                    NodeLoad::Acceleration(GRAVITY),
                    &self.inv_mass,
                    &self.fixed,
                    0.0,
                    self.dt,
                )
                .map_err(|f| {
                    Error::param(
                        "bench",
                        format!("element {} inverted (det F = {})", f.element, f.det_f),
                    )
                })?;
            self.steps += 1;
        }
        Ok(())
    }

    /// A [`System`] with the same physics and element-data precision (for the integrator
    /// rows).
    pub fn system(&self, mesh: &Mesh) -> Result<System> {
        let mut p = FemParams::new(Material::NeoHookean(standard_material()));
        p.density = 1000.0;
        p.precision = self.model.params.precision;
        let model = FemModel::new(mesh, p)?;
        let fixed: Vec<u32> = (0..self.num_nodes() as u32)
            .filter(|&a| self.fixed[a as usize])
            .collect();
        Ok(System::new(
            Box::new(model),
            self.mass.clone(),
            0.0,
            self.f_ext.clone(),
            Constraints::new(fixed, vec![]),
        ))
    }

    pub fn check(&mut self) -> Check {
        let n = self.free_end.len().max(1) as f64;
        let u = self.state.u();
        let mean = self
            .free_end
            .iter()
            .map(|&a| u[3 * a as usize + 1])
            .sum::<f64>()
            / n;
        let max = u
            .chunks_exact(3)
            .map(|d| (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt())
            .fold(0.0, f64::max);
        Check {
            nodes: self.num_nodes(),
            steps: self.steps,
            precision: self.model.params.precision,
            mean_uy_free_end: mean,
            max_abs_u: max,
        }
    }
}

/// Bytes moved per tet-step by design for a mesh of `nodes` nodes and `tets` tetrahedra,
/// the element data stored in `precision`.
pub fn bytes_per_tet_step(nodes: usize, tets: usize, precision: Precision) -> f64 {
    precision.bytes_per_tet() as f64
        + bytes_per_node_step(precision) as f64 * nodes as f64 / tets.max(1) as f64
}

/// Floating-point operations per tet-step by design for a mesh of `nodes` nodes and `tets`
/// tetrahedra, the element data stored in `precision` (module docs).
pub fn flops_per_tet_step(nodes: usize, tets: usize, precision: Precision) -> f64 {
    flops_per_tet(precision) as f64 + FLOPS_PER_NODE_STEP as f64 * nodes as f64 / tets.max(1) as f64
}

/// The f64 fused-multiply-add peak of the current rayon pool (GFLOP/s, 2 flops per lane per
/// FMA): every thread runs 12 independent chains `a = a b + c` on 4-lane AVX2 vectors (on
/// CPUs without AVX2 + FMA, `a b + c` unfused on scalars, 2 flops each), best of 3.
pub fn fma_peak() -> f64 {
    const ITERS: usize = 1 << 23;
    let mut best = f64::INFINITY;
    let mut flops = 0.0;
    for rep in 0..4 {
        let t = Instant::now();
        let per_thread: Vec<(f64, f64)> = rayon::broadcast(|_| fma_chains(ITERS));
        let dt = t.elapsed().as_secs_f64();
        std::hint::black_box(&per_thread);
        flops = per_thread.iter().map(|p| p.1).sum();
        if rep > 0 {
            best = best.min(dt);
        }
    }
    flops / best / 1e9
}

/// 12 independent FMA chains, `iters` steps each: (a value that depends on all of them, the
/// flops done).
fn fma_chains(iters: usize) -> (f64, f64) {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU has AVX2 and FMA.
        return unsafe { fma_chains_avx2(iters) };
    }
    let (b, c) = (std::hint::black_box(0.999_999), std::hint::black_box(1e-7));
    let mut a = [1.0f64; 12];
    for _ in 0..iters {
        for x in a.iter_mut() {
            *x = *x * b + c;
        }
    }
    (a.iter().sum(), (iters * 12 * 2) as f64)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn fma_chains_avx2(iters: usize) -> (f64, f64) {
    use std::arch::x86_64::*;
    let b = _mm256_set1_pd(std::hint::black_box(0.999_999));
    let c = _mm256_set1_pd(std::hint::black_box(1e-7));
    let mut a = [_mm256_set1_pd(1.0); 12];
    for _ in 0..iters {
        for x in a.iter_mut() {
            *x = _mm256_fmadd_pd(*x, b, c);
        }
    }
    let mut s = [0.0; 4];
    let sum = a
        .iter()
        .fold(_mm256_setzero_pd(), |s, &x| _mm256_add_pd(s, x));
    // SAFETY: `s` holds 4 entries.
    unsafe { _mm256_storeu_pd(s.as_mut_ptr(), sum) };
    (s.iter().sum(), (iters * 12 * 4 * 2) as f64)
}

/// STREAM-like triad `a = b + s c` on three arrays of `footprint` bytes in all, on the
/// current rayon pool, best of 3 (GB/s, 24 B per entry).
pub fn triad(footprint: usize) -> f64 {
    let n = (footprint / 24).max(1 << 12);
    let mut a = vec![0.0f64; n];
    let b: Vec<f64> = (0..n).map(|i| i as f64).collect();
    let c: Vec<f64> = (0..n).map(|i| 0.5 * i as f64).collect();
    // Repeat small arrays so each timing lasts at least ~20 ms worth of traffic.
    let reps = ((1usize << 28) / (24 * n)).max(1);
    let chunk = 1 << 13;
    let mut best = f64::INFINITY;
    for rep in 0..4 {
        let t = Instant::now();
        for r in 0..reps {
            let s = 1.0 + r as f64 * 1e-9;
            a.par_chunks_mut(chunk)
                .zip(b.par_chunks(chunk))
                .zip(c.par_chunks(chunk))
                .for_each(|((a, b), c)| {
                    for i in 0..a.len() {
                        a[i] = b[i] + s * c[i];
                    }
                });
        }
        let dt = t.elapsed().as_secs_f64();
        if rep > 0 {
            best = best.min(dt);
        }
    }
    std::hint::black_box(&a);
    24.0 * n as f64 * reps as f64 / best / 1e9
}

/// Peak resident memory of this process (VmHWM, bytes), if readable.
pub fn peak_memory() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// One row of the benchmark table.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Row {
    pub case: String,
    pub nodes: usize,
    pub elements: usize,
    pub threads: usize,
    pub precision: &'static str,
    pub steps_per_s: Option<f64>,
    pub node_updates_per_s: Option<f64>,
    pub bytes_per_tet_step: Option<f64>,
    pub gb_per_s: Option<f64>,
    pub roofline_gb_per_s: Option<f64>,
    /// Achieved bandwidth over the triad's (the memory roof).
    pub triad_fraction: Option<f64>,
    /// Floating-point rate by design (flops per tet-step × tets × steps/s).
    pub gflop_per_s: Option<f64>,
    /// The measured FMA peak of the same threads (the compute roof).
    pub peak_gflop_per_s: Option<f64>,
    /// `gflop_per_s` over `peak_gflop_per_s`.
    pub peak_fraction: Option<f64>,
    /// Achieved over attainable, `min(compute roof, memory roof)`: the larger of
    /// `triad_fraction` and `peak_fraction`.
    pub roofline_fraction: Option<f64>,
    /// Free-form value for rows that are not throughputs (seconds, bytes per node).
    pub value: Option<f64>,
    pub unit: &'static str,
    pub note: String,
}

/// What the benchmark measures.
#[derive(Clone, Debug)]
pub struct BenchOptions {
    /// Node counts of the standard boxes.
    pub sizes: Vec<usize>,
    /// Thread counts.
    pub threads: Vec<usize>,
    /// Small and short (CI smoke).
    pub quick: bool,
    /// Only the standard-work rows.
    pub standard_only: bool,
    /// Storage precisions of the standard-work rows (the other rows are f64).
    pub precisions: Vec<Precision>,
}

/// Parse `f64,f32-storage` (`f32` is short for `f32-storage`).
pub fn parse_precisions(s: &str) -> Result<Vec<Precision>> {
    s.split(',')
        .map(|t| {
            let t = t.trim();
            let t = if t == "f32" { "f32-storage" } else { t };
            Precision::from_name(t).ok_or_else(|| {
                Error::param(
                    "precision",
                    format!("cannot read `{t}`: valid are f64, f32-storage (or f32)"),
                )
            })
        })
        .collect()
}

/// Parse `1k,10k,100k,1M` (also plain numbers).
pub fn parse_sizes(s: &str) -> Result<Vec<usize>> {
    s.split(',')
        .map(|t| {
            let t = t.trim();
            let (num, mul) = match t.chars().last() {
                Some('k' | 'K') => (&t[..t.len() - 1], 1_000.0),
                Some('m' | 'M') => (&t[..t.len() - 1], 1_000_000.0),
                _ => (t, 1.0),
            };
            num.parse::<f64>()
                .ok()
                .filter(|x| *x > 0.0)
                .map(|x| (x * mul).round() as usize)
                .ok_or_else(|| Error::param("sizes", format!("cannot read `{t}`")))
        })
        .collect()
}

/// Size label: 1000 → `1k`, 1000000 → `1M`.
pub fn size_label(n: usize) -> String {
    if n >= 1_000_000 && n.is_multiple_of(1_000_000) {
        format!("{}M", n / 1_000_000)
    } else if n >= 1000 && n.is_multiple_of(1000) {
        format!("{}k", n / 1000)
    } else {
        n.to_string()
    }
}

fn pool(t: usize) -> Result<rayon::ThreadPool> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(t)
        .build()
        .map_err(|e| Error::param("threads", e.to_string()))
}

/// Steps per timing so that one timing is about `work` node-updates.
fn steps_for(nodes: usize, work: f64, min: usize) -> usize {
    ((work / nodes as f64) as usize).max(min)
}

/// Best of 3 seconds for `f`.
fn best_of_3(mut f: impl FnMut() -> Result<()>) -> Result<f64> {
    let mut best = f64::INFINITY;
    for _ in 0..3 {
        let t = Instant::now();
        f()?;
        best = best.min(t.elapsed().as_secs_f64());
    }
    Ok(best)
}

/// The correctness check: `steps` (500 by convention) fused steps of the standard work on
/// a box of `nodes` nodes, element data in `precision`.
pub fn check(nodes: usize, steps: usize, precision: Precision) -> Result<Check> {
    let mesh = standard_box_loaded(nodes)?;
    let mut w = StandardWork::with_precision(&mesh, precision)?;
    w.advance(steps)?;
    Ok(w.check())
}

/// Run the benchmark; `emit` sees each row as it is measured.
pub fn run(opts: &BenchOptions, emit: &mut dyn FnMut(&Row)) -> Result<Vec<Row>> {
    let mut rows = Vec::new();
    let mut push = |r: Row, rows: &mut Vec<Row>| {
        emit(&r);
        rows.push(r);
    };
    let work = if opts.quick { 2e5 } else { 3e7 };
    let max_nodes = opts.sizes.iter().copied().max().unwrap_or(1000);
    let mut largest = 0;
    for &size in &opts.sizes {
        let mesh = standard_box_loaded(size)?;
        let (nodes, tets) = (mesh.num_nodes(), mesh.num_elements());
        largest = largest.max(nodes);
        let steps = steps_for(nodes, work, 3);
        // One precision at a time (one model in memory), its thread counts in turn.
        for &precision in &opts.precisions {
            let mut w = StandardWork::with_precision(&mesh, precision)?;
            let bpt = bytes_per_tet_step(nodes, tets, precision);
            let footprint =
                tets * precision.bytes_per_tet() + nodes * bytes_per_node_step(precision) / 2;
            for &t in &opts.threads {
                let p = pool(t)?;
                let (secs, roof, peak) = p.install(|| -> Result<(f64, f64, f64)> {
                    w.advance(steps.div_ceil(4))?; // warm-up
                    let s = best_of_3(|| w.advance(steps))?;
                    Ok((s, triad(footprint), fma_peak()))
                })?;
                let sps = steps as f64 / secs;
                let gbs = bpt * tets as f64 * sps / 1e9;
                let gflops = flops_per_tet_step(nodes, tets, precision) * tets as f64 * sps / 1e9;
                let (tf, pf) = (gbs / roof, gflops / peak);
                push(
                    Row {
                        case: STANDARD_CASE.into(),
                        nodes,
                        elements: tets,
                        threads: t,
                        precision: precision.name(),
                        steps_per_s: Some(sps),
                        node_updates_per_s: Some(nodes as f64 * sps),
                        bytes_per_tet_step: Some(bpt),
                        gb_per_s: Some(gbs),
                        roofline_gb_per_s: Some(roof),
                        triad_fraction: Some(tf),
                        gflop_per_s: Some(gflops),
                        peak_gflop_per_s: Some(peak),
                        peak_fraction: Some(pf),
                        roofline_fraction: Some(tf.max(pf)),
                        unit: "",
                        note: match (w.model.fast_kernel_isa(), w.model.fast_path()) {
                            (Some(isa), Some((slabs, colours, _))) => {
                                format!("{isa} kernel, {slabs} slabs, {colours} colours")
                            }
                            _ => String::new(),
                        },
                        ..Default::default()
                    },
                    &mut rows,
                );
            }
        }
    }
    if opts.standard_only {
        return Ok(rows);
    }
    if let Some(hwm) = peak_memory() {
        push(
            Row {
                case: "peak memory (VmHWM) per node of the largest box".into(),
                nodes: largest,
                value: Some(hwm as f64 / largest.max(1) as f64),
                unit: "B/node",
                note: format!(
                    "VmHWM {:.1} MiB after the standard boxes, before the other rows",
                    hwm as f64 / 1048576.0
                ),
                ..Default::default()
            },
            &mut rows,
        );
    }
    // Integrators through the generic System path, on the size nearest 100k.
    let isize = *opts
        .sizes
        .iter()
        .min_by_key(|&&s| (s as i64 - 100_000).abs())
        .unwrap_or(&1000);
    {
        let mesh = standard_box_loaded(isize)?;
        let (nodes, tets) = (mesh.num_nodes(), mesh.num_elements());
        let w = StandardWork::new(&mesh)?;
        for method in [
            Method::SymplecticEuler,
            Method::CentralDifference,
            Method::Rk4,
        ] {
            let mut sys = w.system(&mesh)?;
            let mut integ = method.build(nodes);
            let mut state = State::at_rest(nodes);
            let steps = steps_for(nodes, work / method.evaluations() as f64, 3);
            for &t in &opts.threads {
                let p = pool(t)?;
                let secs = p.install(|| -> Result<f64> {
                    let mut go = |k: usize| -> Result<()> {
                        for _ in 0..k {
                            integ.step(&mut sys, &mut state, w.dt).map_err(|f| {
                                Error::param("bench", format!("element {} inverted", f.element))
                            })?;
                        }
                        Ok(())
                    };
                    go(steps.div_ceil(4))?;
                    best_of_3(|| go(steps))
                })?;
                let sps = steps as f64 / secs;
                push(
                    Row {
                        case: format!("box tet NH {} (System)", method.name()),
                        nodes,
                        elements: tets,
                        threads: t,
                        precision: "f64",
                        steps_per_s: Some(sps),
                        node_updates_per_s: Some(nodes as f64 * sps),
                        unit: "",
                        note: format!("{} force passes/step", method.evaluations()),
                        ..Default::default()
                    },
                    &mut rows,
                );
            }
        }
    }
    // Multigrid: one RaISoV V-cycle against one single-level step (both symplectic Euler
    // through System), 4 levels of the standard box at node ratio r = 0.5.
    {
        let mut meshes = Vec::with_capacity(VCYCLE_LEVELS);
        for i in 0..VCYCLE_LEVELS {
            meshes.push(standard_box_loaded(
                (isize as f64 * VCYCLE_RATIO.powi(i as i32)).round() as usize,
            )?);
        }
        let mut links = Vec::with_capacity(VCYCLE_LEVELS - 1);
        for i in 0..VCYCLE_LEVELS - 1 {
            links.push(Correspondence::build(&meshes[i], &meshes[i + 1])?);
        }
        let fine = StandardWork::new(&meshes[0])?;
        let (nodes, tets) = (meshes[0].num_nodes(), meshes[0].num_elements());
        let sizes: Vec<usize> = meshes.iter().map(|m| m.num_nodes()).collect();
        let mut single = SingleLevel::new(
            fine.system(&meshes[0])?,
            Method::SymplecticEuler,
            StepperParams {
                dt: fine.dt,
                kinetic_limit: f64::INFINITY,
            },
        );
        // Eq. 14 splits the cycle's cost into the levels' steps and the mapping: the coarse
        // levels' single steps, timed alone, give the first part.
        let mut alone = Vec::with_capacity(VCYCLE_LEVELS - 1);
        for mesh in &meshes[1..] {
            let w = StandardWork::new(mesh)?;
            alone.push(SingleLevel::new(
                w.system(mesh)?,
                Method::SymplecticEuler,
                StepperParams {
                    dt: fine.dt,
                    kinetic_limit: f64::INFINITY,
                },
            ));
        }
        let mut levels = Vec::with_capacity(VCYCLE_LEVELS);
        for mesh in meshes {
            let w = StandardWork::new(&mesh)?;
            let sys = w.system(&mesh)?;
            let m = standard_material();
            let lambda_max = Material::NeoHookean(m).stability_modulus(mesh.kind) / 1000.0
                * raisov::integrate::stability::max_gradient_sum(&mesh);
            levels.push(Level::new(
                mesh,
                sys,
                Method::SymplecticEuler,
                fine.dt,
                lambda_max,
            ));
        }
        let h = levels[0].mesh.edge_range().0;
        let mut cycle = Raisov::new(
            levels,
            links,
            RaisovParams {
                epsilon: 1e-3 * h,
                reading: Reading::Correction,
                kinetic_limit: f64::INFINITY,
            },
        );
        let steps = steps_for(nodes, work / 4.0, 3);
        let ideal: f64 = sizes.iter().map(|&n| n as f64).sum::<f64>() / sizes[0] as f64;
        // Per thread count: the small coarse levels scale worse over threads than the fine
        // one, so the ratio depends on it.
        for &t in &opts.threads {
            let (s1, sv, sl) = pool(t)?.install(|| -> Result<(f64, f64, f64)> {
                let diverged = |d: raisov::error::Divergence| Error::param("bench", d.to_string());
                let go = |st: &mut dyn Stepper, k: usize| -> Result<()> {
                    for _ in 0..k {
                        st.advance().map_err(diverged)?;
                    }
                    Ok(())
                };
                go(&mut single, steps.div_ceil(4))?;
                go(&mut cycle, steps.div_ceil(4))?;
                let s1 = best_of_3(|| go(&mut single, steps))?;
                let sv = best_of_3(|| go(&mut cycle, steps))?;
                let mut sl = s1;
                for st in alone.iter_mut() {
                    go(st, steps.div_ceil(4))?;
                    sl += best_of_3(|| go(st, steps))?;
                }
                Ok((s1, sv, sl))
            })?;
            push(
                Row {
                    case: format!(
                        "RaISoV V-cycle / single step ({VCYCLE_LEVELS} levels, r = {VCYCLE_RATIO})"
                    ),
                    nodes,
                    elements: tets,
                    threads: t,
                    precision: "f64",
                    value: Some(sv / s1),
                    unit: "x",
                    note: format!(
                        "levels {sizes:?} nodes, node-count ratio {ideal:.3}; symplectic Euler (System)"
                    ),
                    ..Default::default()
                },
                &mut rows,
            );
            push(
                Row {
                    case: format!("RaISoV levels' steps alone / single step ({VCYCLE_LEVELS} levels)"),
                    nodes,
                    elements: tets,
                    threads: t,
                    precision: "f64",
                    value: Some(sl / s1),
                    unit: "x",
                    note: "each level's single step timed on its own, summed: the cycle without the mapping (eq. 14's first term)".into(),
                    ..Default::default()
                },
                &mut rows,
            );
        }
    }
    // Membrane, ~100k nodes (generic element path), same fused step.
    {
        let target = if opts.quick { 5_000 } else { 100_000 };
        let mesh = rectangle_membrane(0.1, 0.1, target)?;
        let (nodes, tris) = (mesh.num_nodes(), mesh.num_elements());
        let m = standard_material();
        let mut p = FemParams::new(Material::NeoHookean(m));
        p.density = 1000.0;
        p.thickness = 1e-3;
        let mut model = FemModel::new(&mesh, p)?;
        let mass = model.lumped_mass();
        let inv_mass: Vec<f64> = mass.iter().map(|&m| 1.0 / m).collect();
        let f_ext: Vec<f64> = mass.iter().flat_map(|&m| [0.0, -9.81 * m, 0.0]).collect();
        let (lo, _) = mesh.bounding_box();
        let fixed: Vec<bool> = mesh.nodes.iter().map(|p| p[0] == lo[0]).collect();
        let c = (4.0 * m.mu / 1000.0).sqrt();
        let dt = 0.2 * mesh.edge_range().0 / c;
        let mut state = FusedState::zeros(nodes);
        let steps = steps_for(nodes, work, 3);
        for &t in &opts.threads {
            let pl = pool(t)?;
            let secs = pl.install(|| -> Result<f64> {
                let mut go = |k: usize| -> Result<()> {
                    for _ in 0..k {
                        model
                            .step_symplectic_euler(
                                &mut state,
                                NodeLoad::Forces(&f_ext),
                                &inv_mass,
                                &fixed,
                                0.0,
                                dt,
                            )
                            .map_err(|f| {
                                Error::param("bench", format!("triangle {} collapsed", f.element))
                            })?;
                    }
                    Ok(())
                };
                go(steps.div_ceil(4))?;
                best_of_3(|| go(steps))
            })?;
            let sps = steps as f64 / secs;
            push(
                Row {
                    case: "membrane tri NH symplectic-euler (fused)".into(),
                    nodes,
                    elements: tris,
                    threads: t,
                    precision: "f64",
                    steps_per_s: Some(sps),
                    node_updates_per_s: Some(nodes as f64 * sps),
                    unit: "",
                    note: "generic element path".into(),
                    ..Default::default()
                },
                &mut rows,
            );
        }
    }
    // Hierarchy correspondence of one level pair (fine ≈ largest size, coarse ≈ half).
    {
        let fine_n = if opts.quick {
            max_nodes.min(10_000)
        } else {
            max_nodes.max(1_000_000)
        };
        let fine = standard_box_loaded(fine_n)?;
        let coarse = standard_box_loaded(fine_n / 2)?;
        let t = opts.threads.iter().copied().max().unwrap_or(1);
        let secs = pool(t)?.install(|| -> Result<f64> {
            let t0 = Instant::now();
            let c = Correspondence::build(&fine, &coarse)?;
            std::hint::black_box(&c);
            Ok(t0.elapsed().as_secs_f64())
        })?;
        push(
            Row {
                case: "hierarchy Correspondence::build".into(),
                nodes: fine.num_nodes(),
                elements: fine.num_elements(),
                threads: t,
                precision: "f64",
                value: Some(secs),
                unit: "s",
                note: format!("coarse {} nodes, single run", coarse.num_nodes()),
                ..Default::default()
            },
            &mut rows,
        );
    }
    Ok(rows)
}

/// Case name of the standard-work rows.
pub const STANDARD_CASE: &str = "box tet NH symplectic-euler (fused)";

/// The performance goals that can be judged from one run's rows, one line each: per-node
/// time from the smallest box of at least 5k nodes (the "10k" box) to the largest, per
/// thread count and precision (goal: within 30 %), the roofline fraction (achieved over
/// `min(FMA peak, triad roof)`, naming the roof that binds) per size from 50k nodes up, the
/// sizes the goal names (100k and 1M; goal: at least 0.5), and the V-cycle cost ratio (the
/// paper's eq. 14: at most 2).
/// The goal of 5x the best peer needs the peers' numbers: `bench/peers/run.sh` prints it.
pub fn goals(rows: &[Row]) -> Vec<String> {
    let verdict = |ok: bool| if ok { "holds" } else { "not met" };
    let std_rows: Vec<&Row> = rows.iter().filter(|r| r.case == STANDARD_CASE).collect();
    let mut keys: Vec<(usize, &str)> = std_rows.iter().map(|r| (r.threads, r.precision)).collect();
    keys.sort_unstable();
    keys.dedup();
    let mut out = Vec::new();
    for &(t, p) in &keys {
        let mine: Vec<&&Row> = std_rows
            .iter()
            .filter(|r| r.threads == t && r.precision == p && r.node_updates_per_s.is_some())
            .collect();
        let small = mine
            .iter()
            .filter(|r| r.nodes >= 5000)
            .min_by_key(|r| r.nodes);
        let large = mine.iter().max_by_key(|r| r.nodes);
        if let (Some(a), Some(b)) = (small, large) {
            if b.nodes > a.nodes {
                let ratio =
                    a.node_updates_per_s.unwrap_or(0.0) / b.node_updates_per_s.unwrap_or(1.0);
                out.push(format!(
                    "per-node time, {} over {} nodes, {t} thread(s), {p}: {ratio:.2}x (goal <= 1.30: {})",
                    b.nodes,
                    a.nodes,
                    verdict(ratio <= 1.3)
                ));
            }
        }
        let fr: Vec<String> = mine
            .iter()
            .filter(|r| r.nodes >= 50_000)
            .filter_map(|r| r.roofline_fraction.map(|f| (r, f)))
            .map(|(r, f)| {
                // The lower roof binds: the one whose fraction is the larger.
                let roof = match (r.triad_fraction, r.peak_fraction) {
                    (Some(m), Some(c)) if c > m => "compute",
                    _ => "memory",
                };
                format!(
                    "{} nodes {f:.2} ({roof} roof, {})",
                    r.nodes,
                    verdict(f >= 0.5)
                )
            })
            .collect();
        if !fr.is_empty() {
            out.push(format!(
                "fraction of the roofline min(FMA peak, triad), {t} thread(s), {p} (goal >= 0.5): {}",
                fr.join(", ")
            ));
        }
    }
    for r in rows.iter().filter(|r| r.case.starts_with("RaISoV V-cycle")) {
        if let Some(v) = r.value {
            // Eq. 14's two terms where the bench timed the levels alone.
            let split = rows
                .iter()
                .find(|a| {
                    a.case.starts_with("RaISoV levels' steps alone") && a.threads == r.threads
                })
                .and_then(|a| a.value)
                .map(|l| format!("; the levels' steps alone {l:.2}, the mapping {:.2}", v - l))
                .unwrap_or_default();
            out.push(format!(
                "V-cycle over single step, {} thread(s): {v:.2} (eq. 14: <= 2: {}{split})",
                r.threads,
                verdict(v <= 2.0)
            ));
        }
    }
    out
}

fn opt(x: Option<f64>, f: impl Fn(f64) -> String) -> String {
    x.map(f).unwrap_or_else(|| "-".into())
}

const COLUMNS: usize = 17;

const HEADER: [&str; COLUMNS] = [
    "case",
    "nodes",
    "elements",
    "threads",
    "precision",
    "steps/s",
    "node-updates/s",
    "B/tet-step",
    "GB/s",
    "triad GB/s",
    "triad fraction",
    "GFLOP/s",
    "FMA peak GFLOP/s",
    "peak fraction",
    "roofline fraction",
    "value",
    "note",
];

fn cells(r: &Row) -> [String; COLUMNS] {
    [
        r.case.clone(),
        r.nodes.to_string(),
        r.elements.to_string(),
        if r.threads > 0 {
            r.threads.to_string()
        } else {
            "-".into()
        },
        r.precision.to_string(),
        opt(r.steps_per_s, |x| format!("{x:.1}")),
        opt(r.node_updates_per_s, |x| format!("{:.2}M", x / 1e6)),
        opt(r.bytes_per_tet_step, |x| format!("{x:.0}")),
        opt(r.gb_per_s, |x| format!("{x:.1}")),
        opt(r.roofline_gb_per_s, |x| format!("{x:.1}")),
        opt(r.triad_fraction, |x| format!("{x:.2}")),
        opt(r.gflop_per_s, |x| format!("{x:.1}")),
        opt(r.peak_gflop_per_s, |x| format!("{x:.1}")),
        opt(r.peak_fraction, |x| format!("{x:.2}")),
        opt(r.roofline_fraction, |x| format!("{x:.2}")),
        opt(r.value, |x| format!("{x:.4} {}", r.unit)),
        r.note.clone(),
    ]
}

/// The table as aligned text.
pub fn to_text(rows: &[Row]) -> String {
    let body: Vec<[String; COLUMNS]> = rows.iter().map(cells).collect();
    let mut w = HEADER.map(|h| h.len());
    for c in &body {
        for (k, s) in c.iter().enumerate() {
            w[k] = w[k].max(s.chars().count());
        }
    }
    let line = |c: &[String]| -> String {
        c.iter()
            .enumerate()
            .map(|(k, s)| format!("{s:<width$}", width = w[k]))
            .collect::<Vec<_>>()
            .join("  ")
            .trim_end()
            .to_string()
    };
    let mut out = line(&HEADER.map(String::from));
    out.push('\n');
    for c in &body {
        out.push_str(&line(c));
        out.push('\n');
    }
    out
}

/// The table as Markdown, followed by the [`goals`] as a list.
pub fn to_markdown(rows: &[Row]) -> String {
    let mut out = format!("| {} |\n", HEADER.join(" | "));
    out.push_str(&format!("|{}\n", "---|".repeat(HEADER.len())));
    for r in rows {
        out.push_str(&format!("| {} |\n", cells(r).join(" | ")));
    }
    let g = goals(rows);
    if !g.is_empty() {
        out.push_str("\nGoals judged from this run:\n\n");
        for line in g {
            out.push_str(&format!("- {line}\n"));
        }
    }
    out
}

/// The table as CSV (raw numbers, no unit suffixes).
pub fn to_csv(rows: &[Row]) -> String {
    let mut out = String::from(
        "case,nodes,elements,threads,precision,steps_per_s,node_updates_per_s,\
         bytes_per_tet_step,gb_per_s,triad_gb_per_s,triad_fraction,gflop_per_s,\
         peak_gflop_per_s,peak_fraction,roofline_fraction,value,unit,note\n",
    );
    let o = |x: Option<f64>| x.map(|v| format!("{v:.6e}")).unwrap_or_default();
    for r in rows {
        out.push_str(&format!(
            "\"{}\",{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},\"{}\"\n",
            r.case,
            r.nodes,
            r.elements,
            r.threads,
            r.precision,
            o(r.steps_per_s),
            o(r.node_updates_per_s),
            o(r.bytes_per_tet_step),
            o(r.gb_per_s),
            o(r.roofline_gb_per_s),
            o(r.triad_fraction),
            o(r.gflop_per_s),
            o(r.peak_gflop_per_s),
            o(r.peak_fraction),
            o(r.roofline_fraction),
            o(r.value),
            r.unit,
            r.note
        ));
    }
    out
}

#[cfg(test)]
mod tests;
