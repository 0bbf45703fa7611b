//! Total-Lagrangian finite elements and the force model every integrator sees.
//!
//! Equation of motion (paper, eq. 5), sign convention of the whole crate:
//!
//! ```text
//! M ü + D u̇ + R(u) = V,     R(u) = ∂E/∂u,   E(u) = Σ_e V0_e W(C_e)
//! ```
//!
//! `R` is the internal force *resisting* deformation (the energy gradient); the force a node
//! feels from the material is `−R`.
//!
//! Elements (linear, constant strain), reference data precomputed once:
//! - tetrahedron: `F = Ds Dm⁻¹` with `Ds = [x1−x0, x2−x0, x3−x0]` (current) and `Dm` the same
//!   in the reference; `R_j = V0 P Dm⁻ᵀ e_j` for j = 1..3, `R_0 = −Σ R_j`, `P = F S`;
//! - membrane triangle in 3-D: `Dm` is the 2x2 reference edge matrix in the triangle's own
//!   orthonormal frame, `F = Ds Dm⁻¹` is 3x2, `C = FᵀF` 2x2, `P = F S` 3x2, measure `h A0`.
//!
//! Nodal stress T (paper section 3, from [11]): element Cauchy stress `σ = F S Fᵀ / J`
//! (membranes: `J = λ3 √det C`, σ in-plane, 3x3), averaged onto nodes weighted by reference
//! element measure.
//!
//! Data layout for speed: flat arrays, `Dm⁻¹` and measures precomputed. Compressible
//! neo-Hookean tetrahedra (the benchmark work) take the packed, vectorised path of [`fast`]:
//! elements sorted into slabs and by a Morton key, slabs coloured so that one colour's slabs
//! scatter into `r` concurrently without sharing a node (fixed summation order per node).
//! Every other material and the membranes write element forces into per-element slots in
//! parallel and then gather them per node in a fixed order. Either way the result has the
//! same bits on any number of threads and no atomics are needed. The packed path can store
//! its element data (`Dm⁻¹`, volumes) in f32 ([`FemParams::precision`], [`Precision`]; tolerance
//! against f64 in [`fast`]); arithmetic and state stay f64. Element ids in
//! [`ElementFailure`] and every public method are the mesh's original ids.
//!
//! The packed path reads 32-byte node rows (`X + u` for the f64 positions kernel, `u` with
//! f32 storage) and accumulates into 32-byte force rows; `internal_forces` fills the former
//! from `u` and copies the latter out (two node passes around the force pass).
//!
//! Fused explicit step ([`FemModel::step_symplectic_euler`], state in a [`FusedState`]): one
//! force pass accumulating into zeroed force rows, then one node pass doing
//! `v += Δ (M⁻¹(V − R) − α v)` and `x += Δ v` on the node rows themselves (the configuration
//! lives in the rows the next force pass reads; `u` is derived on demand), clearing the
//! force rows: [`crate::integrate::SymplecticEuler`] on a [`crate::integrate::System`] with
//! fixed (zero) constraints, to the bit on the generic path and with f32 storage under a
//! per-node load, within rounding of `X` in f64 (bounds in the method's docs). The load is
//! per node or, as gravity, one acceleration for all ([`NodeLoad`]).

mod element;
pub mod fast;

use crate::material::{Material, MembraneMaterial, SolidMaterial};
use crate::mesh::{ElementKind, Mesh};
use crate::{Error, Result};
pub use element::{membrane_frame, tet_dm_inverse};
pub use fast::Precision;
use nalgebra::{Matrix2, Matrix3, Matrix3x2, Vector3};
use rayon::prelude::*;

/// An element that cannot be evaluated: inverted (tets `det F <= 0`) or collapsed
/// (membranes: area ratio `<= 0` or normal flipped against the reference).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ElementFailure {
    pub element: usize,
    pub det_f: f64,
}

/// What integrators see of the physics (Vega FEM's `ForceModel`): internal forces R(u) and
/// the strain energy whose gradient they are. Displacements and forces are flat, 3 per node.
pub trait ForceModel: Send {
    /// Number of nodes (the vectors have 3 entries per node).
    fn num_nodes(&self) -> usize;
    /// `r = R(u)`. Fails on the lowest-numbered element that cannot be evaluated.
    fn internal_forces(&mut self, u: &[f64], r: &mut [f64]) -> Result<(), ElementFailure>;
    /// Strain energy E(u) (J).
    fn strain_energy(&self, u: &[f64]) -> f64;
    /// Nodal stress tensor T (9 per node, row-major, Pa): the measure of paper section 3.
    fn nodal_stress(&self, u: &[f64], t: &mut [f64]);
}

/// Parameters of an FE model.
#[derive(Clone, Debug, PartialEq)]
pub struct FemParams {
    /// Material law and constants.
    pub material: Material,
    /// Mass density ρ (kg/m³). Default 1000.
    pub density: f64,
    /// Membrane thickness h (m); ignored for tetrahedra. Default 1e-3.
    pub thickness: f64,
    /// Elements per parallel task of the generic force pass; below 2 tasks' worth it runs
    /// serially. Default 2048.
    pub chunk: usize,
    /// Wanted elements per slab of the packed neo-Hookean tetrahedron path (see [`fast`]):
    /// one slab (serial) below 2 slabs' worth, else a multiple of 4 slabs (2 colours × an
    /// even number of slabs per colour) and no more than the node numbering's band allows.
    /// The layout, hence the bits, depend on this and the mesh only, never on the thread
    /// count. Default 16384 (10k-node standard box: 4 slabs; 100k: 16; 1M: 36).
    pub slab: usize,
    /// Storage precision of the packed neo-Hookean tetrahedron data (`Dm⁻¹` and volumes in
    /// f64, or in f32 widened to f64 on load; see [`fast`] for the tolerance). Other
    /// materials and membranes, the masses, the strain energy and the stresses are f64
    /// whatever this says. Default [`Precision::F64`].
    pub precision: Precision,
}

impl FemParams {
    pub fn new(material: Material) -> Self {
        FemParams {
            material,
            density: 1000.0,
            thickness: 1e-3,
            chunk: 2048,
            slab: 16384,
            precision: Precision::F64,
        }
    }
}

/// The finite-element force model of one mesh.
pub struct FemModel {
    pub kind: ElementKind,
    pub params: FemParams,
    n_nodes: usize,
    cells: Vec<u32>,
    /// Reference node positions, 3 per node.
    x0: Vec<f64>,
    /// Dm⁻¹ per element: 9 (tet, column-major) or 4 (membrane, column-major).
    dminv: Vec<f64>,
    /// Reference measure per element: volume, or h·A0 for membranes.
    measure: Vec<f64>,
    /// Reference unit normal per membrane element (empty for tets).
    normal0: Vec<[f64; 3]>,
    /// Node → element slots (CSR): slots `node_ptr[n]..node_ptr[n+1]` of `node_slots` index
    /// into `elem_forces`.
    node_ptr: Vec<u32>,
    node_slots: Vec<u32>,
    /// Per-element-corner force scratch (3 per slot); empty when `pack` is used.
    elem_forces: Vec<f64>,
    /// Packed neo-Hookean tetrahedra (the fast path), if the model qualifies.
    pack: Option<fast::TetPack>,
    /// Node rows the packed kernel reads in [`FemModel::internal_forces`], filled from `u`
    /// at each force pass: `X + u` (positions kernel, f64 storage) or `u` (f32 storage).
    /// Empty without `pack`. (The fused step keeps its rows in its [`FusedState`].)
    rows: Vec<fast::Row4>,
    /// Force rows the packed kernel (or, in the fused step, the generic path) accumulates
    /// into; all zeros between passes.
    acc: Vec<fast::Row4>,
    /// Generic-path forces of the fused step (3 per node); empty with `pack`.
    acc3: Vec<f64>,
}

/// External load of the fused step ([`FemModel::step_symplectic_euler`]).
#[derive(Clone, Copy, Debug)]
pub enum NodeLoad<'a> {
    /// Forces `V`, 3 per node (N): `v += Δ (M⁻¹(V − R) − α v)`.
    Forces(&'a [f64]),
    /// The same acceleration `g` on every node (m/s², e.g. gravity, `V = M g`):
    /// `v += Δ (g − M⁻¹R − α v)`. Nothing is read per node for it: 24 bytes per node-step
    /// less than [`NodeLoad::Forces`] with `M g`, and a different rounding (`g − R/m` against
    /// `(m g − R)/m`, an ulp of the acceleration).
    Acceleration([f64; 3]),
}

impl NodeLoad<'_> {
    /// The acceleration of entry `i = 3a + k` (node `a`, component `k`) under this load and
    /// the internal force `r` at a node of inverse mass `m`: `(V_i − r) m` or `g_k − r m`.
    #[inline(always)]
    fn acceleration(self, i: usize, k: usize, r: f64, m: f64) -> f64 {
        match self {
            NodeLoad::Forces(f) => (f[i] - r) * m,
            NodeLoad::Acceleration(g) => g[k] - r * m,
        }
    }
}

/// State of the fused step ([`FemModel::step_symplectic_euler`]): velocities `v` and the
/// configuration, 3 per node. On the packed path the configuration lives in the node rows
/// the force pass reads (`X + u` in f64, `u` with f32 storage), which the node update
/// advances in place; `u` is derived from them when asked for ([`FusedState::u`]). On the
/// generic path `u` itself is advanced. Changing `u` through [`FusedState::u_mut`] rebuilds
/// the rows at the next step. A state belongs to the model that steps it (the rows hold
/// that model's reference positions).
#[derive(Clone, Debug, Default)]
pub struct FusedState {
    u: Vec<f64>,
    v: Vec<f64>,
    rows: Vec<fast::Row4>,
    /// The rows hold the configuration (the packed path has stepped since the last
    /// change of `u`).
    rows_valid: bool,
    /// `u` lags the rows (a packed step ran since it was last derived).
    u_stale: bool,
    /// What the rows hold beyond `u`: `X`, 3 per node (f64 positions rows), or empty.
    base: Vec<f64>,
}

impl FusedState {
    /// `u` and `v` given (3 per node each).
    pub fn new(u: Vec<f64>, v: Vec<f64>) -> FusedState {
        assert!(
            u.len() == v.len() && u.len().is_multiple_of(3),
            "u and v: 3 per node each"
        );
        FusedState {
            u,
            v,
            ..Default::default()
        }
    }

    /// At rest: `u = v = 0` on `n` nodes.
    pub fn zeros(n: usize) -> FusedState {
        FusedState::new(vec![0.0; 3 * n], vec![0.0; 3 * n])
    }

    /// Displacements, 3 per node: on the packed path derived from the node rows
    /// (`(X + u) − X` in f64: within an ulp of `X` of the `u` the rows were built from).
    pub fn u(&mut self) -> &[f64] {
        if self.u_stale {
            const NB: usize = 4096;
            let base: &[f64] = &self.base;
            if base.is_empty() {
                self.u
                    .par_chunks_mut(3 * NB)
                    .zip(self.rows.par_chunks(NB))
                    .for_each(|(uc, rc)| {
                        for (ua, row) in uc.chunks_exact_mut(3).zip(rc) {
                            ua.copy_from_slice(&row.0[..3]);
                        }
                    });
            } else {
                self.u
                    .par_chunks_mut(3 * NB)
                    .zip(self.rows.par_chunks(NB).zip(base.par_chunks(3 * NB)))
                    .for_each(|(uc, (rc, bc))| {
                        for ((ua, row), xa) in
                            uc.chunks_exact_mut(3).zip(rc).zip(bc.chunks_exact(3))
                        {
                            for k in 0..3 {
                                ua[k] = row.0[k] - xa[k];
                            }
                        }
                    });
            }
            self.u_stale = false;
        }
        &self.u
    }

    /// Velocities, 3 per node.
    pub fn v(&self) -> &[f64] {
        &self.v
    }

    /// Displacements to change; the force pass's rows are rebuilt at the next step.
    pub fn u_mut(&mut self) -> &mut [f64] {
        self.u();
        self.rows_valid = false;
        &mut self.u
    }

    /// Velocities to change.
    pub fn v_mut(&mut self) -> &mut [f64] {
        &mut self.v
    }
}

/// Node `a`'s row from `u` and `x0` (3 per node, `a` counted in those slices):
/// `[X_a + u_a, 0]` (`positions`) or `[u_a, 0]`.
#[inline(always)]
fn node_row(u: &[f64], x0: &[f64], a: usize, positions: bool) -> fast::Row4 {
    let i = 3 * a;
    fast::Row4(if positions {
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

/// The packed fused step's node pass, in parallel chunks: for each node `a`, `v += Δ (load
/// − α v)` with `load(3a + k, k, R, 1/m)` the acceleration the load and the force rows give,
/// then `row += Δ v`, and the force row cleared; fixed nodes get `v = 0` and their
/// reference row (`[X, 0]` with `positions`, else zeros).
#[inline(always)]
fn packed_node_pass<L: Fn(usize, usize, f64, f64) -> f64 + Sync>(
    load: L,
    (v, acc, rows): (&mut [f64], &mut [fast::Row4], &mut [fast::Row4]),
    (inv_mass, fixed, x0): (&[f64], &[bool], &[f64]),
    positions: bool,
    alpha: f64,
    dt: f64,
) {
    const NB: usize = 4096;
    let body = |a0: usize,
                vc: &mut [f64],
                rc: &mut [fast::Row4],
                qc: &mut [fast::Row4],
                mc: &[f64],
                xc: &[bool]| {
        for a in 0..mc.len() {
            let ra = &mut rc[a].0;
            let q = &mut qc[a].0;
            if xc[a] {
                let g = 3 * (a0 + a);
                vc[3 * a..3 * a + 3].fill(0.0);
                *q = if positions {
                    [x0[g], x0[g + 1], x0[g + 2], 0.0]
                } else {
                    [0.0; 4]
                };
            } else {
                for k in 0..3 {
                    let i = 3 * a + k;
                    let acc_i = load(3 * a0 + i, k, ra[k], mc[a]) - alpha * vc[i];
                    vc[i] += dt * acc_i;
                    q[k] += dt * vc[i];
                }
            }
            *ra = [0.0; 4];
        }
    };
    if inv_mass.len() >= 2 * NB {
        v.par_chunks_mut(3 * NB)
            .zip(acc.par_chunks_mut(NB))
            .zip(rows.par_chunks_mut(NB))
            .zip(inv_mass.par_chunks(NB).zip(fixed.par_chunks(NB)))
            .enumerate()
            .for_each(|(c, (((vc, rc), qc), (mc, xc)))| body(c * NB, vc, rc, qc, mc, xc));
    } else {
        body(0, v, acc, rows, inv_mass, fixed);
    }
}

/// `rows[a] = [X_a + u_a, 0]` (`positions`) or `[u_a, 0]`, in parallel chunks.
fn fill_rows(rows: &mut [fast::Row4], u: &[f64], x0: &[f64], positions: bool) {
    const NB: usize = 4096;
    let body = |(rc, (uc, xc)): (&mut [fast::Row4], (&[f64], &[f64]))| {
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
fn drain_rows(acc: &mut [fast::Row4], r: &mut [f64]) {
    const NB: usize = 4096;
    let body = |(ac, rc): (&mut [fast::Row4], &mut [f64])| {
        for (row, ra) in ac.iter_mut().zip(rc.chunks_exact_mut(3)) {
            ra.copy_from_slice(&row.0[..3]);
            *row = fast::Row4::default();
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

impl FemModel {
    /// Precompute reference data. Errors on an element with zero or negative reference measure.
    pub fn new(mesh: &Mesh, params: FemParams) -> Result<Self> {
        let npe = mesh.npe();
        let ne = mesh.num_elements();
        if !(params.density > 0.0 && params.density.is_finite()) {
            return Err(Error::param(
                "density",
                "must be a positive number (kg/m^3)",
            ));
        }
        if mesh.kind == ElementKind::Tri3 && !(params.thickness > 0.0) {
            return Err(Error::param("thickness", "must be a positive number (m)"));
        }
        let mut dminv = Vec::with_capacity(ne * if npe == 4 { 9 } else { 4 });
        let mut measure = Vec::with_capacity(ne);
        let mut normal0 = Vec::new();
        for e in 0..ne {
            let p = mesh.element_points(e);
            match mesh.kind {
                ElementKind::Tet4 => {
                    let (inv, vol) = tet_dm_inverse(&p).ok_or_else(|| {
                        Error::param(
                            "mesh",
                            format!("element {e} is degenerate or inverted in the reference"),
                        )
                    })?;
                    dminv.extend_from_slice(inv.as_slice());
                    measure.push(vol);
                }
                ElementKind::Tri3 => {
                    let (inv, area, n) = membrane_frame(&p).ok_or_else(|| {
                        Error::param("mesh", format!("triangle {e} is degenerate"))
                    })?;
                    dminv.extend_from_slice(inv.as_slice());
                    measure.push(area * params.thickness);
                    normal0.push(n);
                }
            }
        }
        // CSR node -> slots, slots in increasing order (element-major) for determinism.
        let n = mesh.num_nodes();
        let mut count = vec![0u32; n + 1];
        for &c in &mesh.cells {
            count[c as usize + 1] += 1;
        }
        for i in 0..n {
            count[i + 1] += count[i];
        }
        let node_ptr = count.clone();
        let mut fill = count;
        let mut node_slots = vec![0u32; mesh.cells.len()];
        for (slot, &c) in mesh.cells.iter().enumerate() {
            let k = &mut fill[c as usize];
            node_slots[*k as usize] = slot as u32;
            *k += 1;
        }
        let x0: Vec<f64> = mesh.nodes.iter().flatten().copied().collect();
        assert!(
            mesh.cells.iter().all(|&c| (c as usize) < n),
            "node id out of range"
        );
        let pack = match (&params.material, mesh.kind) {
            (Material::NeoHookean(m), ElementKind::Tet4) => Some(fast::TetPack::new(
                m.mu,
                m.lambda,
                &x0,
                &mesh.cells,
                &dminv,
                &measure,
                params.slab.max(1),
                params.precision,
            )),
            _ => None,
        };
        let elem_forces = if pack.is_some() {
            Vec::new()
        } else {
            vec![0.0; mesh.cells.len() * 3]
        };
        Ok(FemModel {
            kind: mesh.kind,
            n_nodes: n,
            cells: mesh.cells.clone(),
            x0,
            dminv,
            measure,
            normal0,
            node_ptr,
            node_slots,
            elem_forces,
            rows: vec![fast::Row4::default(); if pack.is_some() { n } else { 0 }],
            acc: {
                let mut acc = fast::huge_page_vec(n);
                acc.resize(n, fast::Row4::default());
                acc
            },
            acc3: if pack.is_some() {
                Vec::new()
            } else {
                vec![0.0; 3 * n]
            },
            pack,
            params,
        })
    }

    /// `Dm⁻¹` of every element, column-major (9 per tetrahedron, 4 per triangle).
    #[cfg(test)]
    pub(crate) fn dminv_column_major(&self) -> &[f64] {
        &self.dminv
    }

    pub fn num_elements(&self) -> usize {
        self.measure.len()
    }

    /// Whether the packed neo-Hookean tetrahedron path is in use, and its layout
    /// (slabs, colours, bytes of packed element data).
    pub fn fast_path(&self) -> Option<(usize, usize, usize)> {
        self.pack.as_ref().map(|p| {
            let (s, c) = p.layout();
            (s, c, p.bytes())
        })
    }

    /// Instruction set of the fast kernel (`"portable"`, `"avx2"`), if in use.
    pub fn fast_kernel_isa(&self) -> Option<&'static str> {
        self.pack.as_ref().map(|p| p.isa())
    }

    /// Storage precision of the fast path's element data, if the fast path is in use
    /// ([`FemParams::precision`] has no effect otherwise).
    pub fn fast_precision(&self) -> Option<Precision> {
        self.pack.as_ref().map(|p| p.precision())
    }

    /// `det F` of tet e as the fast kernel computes it (`F = I + Du Dm⁻¹` with `Dm⁻¹` in the
    /// pack's precision, same operations, same bits), for reporting failures of the fast path.
    fn fast_det(&self, e: usize, u: &[f64]) -> f64 {
        let el = &self.cells[e * 4..e * 4 + 4];
        let prec = self.fast_precision().unwrap_or_default();
        let d = |i: usize, j: usize| prec.round(self.dminv[9 * e + 3 * j + i]);
        let a0 = el[0] as usize * 3;
        let w = |k: usize, i: usize| u[el[k + 1] as usize * 3 + i] - u[a0 + i];
        let fm = |i: usize, j: usize| {
            w(2, i).mul_add(d(2, j), w(1, i).mul_add(d(1, j), w(0, i) * d(0, j)))
        };
        let f = [
            [1.0 + fm(0, 0), fm(0, 1), fm(0, 2)],
            [fm(1, 0), 1.0 + fm(1, 1), fm(1, 2)],
            [fm(2, 0), fm(2, 1), 1.0 + fm(2, 2)],
        ];
        let c00 = f[1][1].mul_add(f[2][2], -(f[1][2] * f[2][1]));
        let c01 = f[1][2].mul_add(f[2][0], -(f[1][0] * f[2][2]));
        let c02 = f[1][0].mul_add(f[2][1], -(f[1][1] * f[2][0]));
        f[0][2].mul_add(c02, f[0][1].mul_add(c01, f[0][0] * c00))
    }

    /// The lowest-numbered element the fast kernel rejects (a parallel search; the same
    /// element on any thread count).
    fn fast_failure(&self, u: &[f64]) -> ElementFailure {
        (0..self.num_elements())
            .into_par_iter()
            .map(|e| (e, self.fast_det(e, u)))
            .find_first(|&(_, d)| !(d > 0.0))
            .map(|(element, det_f)| ElementFailure { element, det_f })
            .unwrap_or(ElementFailure {
                element: 0,
                det_f: f64::NAN,
            })
    }

    /// One fused symplectic-Euler step, `v += Δ (M⁻¹(V − R(u)) − α v)`, `u += Δ v`, with
    /// `u = v = 0` on nodes where `fixed` is true; `inv_mass` per node, the load `V` as
    /// [`NodeLoad`]. On failure the state is unchanged.
    ///
    /// On the packed path the node update advances the node rows of the next force pass in
    /// place (`x += Δ v` on `x = X + u` in f64, `u += Δ v` on `u` with f32 storage) and
    /// never touches `u` ([`FusedState::u`] derives it), so that a node-step moves 64 bytes
    /// less than updating `u` and rebuilding the rows (`X` and `u` read, `u` written) with a
    /// per-node load: 281 bytes per node-step in f64 with [`NodeLoad::Acceleration`]. The
    /// result is [`crate::integrate::SymplecticEuler`] on a [`crate::integrate::System`]
    /// built from this model with those nodes fixed: the same bits on the generic path and
    /// with f32 storage (`u += Δ v` either way) under [`NodeLoad::Forces`]; in f64 the
    /// positions carry the rounding of `X` (an ulp of `|X|` per step, absolute), within
    /// `1e-11` of the largest `|u|` of the System path over 500 steps of the standard work
    /// (tested), and [`NodeLoad::Acceleration`] rounds `g − R/m` for `(m g − R)/m`.
    pub fn step_symplectic_euler(
        &mut self,
        s: &mut FusedState,
        load: NodeLoad<'_>,
        inv_mass: &[f64],
        fixed: &[bool],
        alpha: f64,
        dt: f64,
    ) -> Result<(), ElementFailure> {
        let n = self.n_nodes;
        assert!(s.u.len() == 3 * n && s.v.len() == 3 * n);
        if let NodeLoad::Forces(f) = load {
            assert!(f.len() == 3 * n, "f_ext: 3 per node");
        }
        assert!(inv_mass.len() == n && fixed.len() == n);
        let Some(p) = &self.pack else {
            return self.step_generic(s, load, inv_mass, fixed, alpha, dt);
        };
        let positions = p.reads_positions();
        if !s.rows_valid {
            s.u();
            if s.rows.len() != n {
                s.rows = fast::huge_page_vec(n);
                s.rows.resize(n, fast::Row4::default());
            }
            fill_rows(&mut s.rows, &s.u, &self.x0, positions);
            s.base = if positions {
                self.x0.clone()
            } else {
                Vec::new()
            };
            s.rows_valid = true;
        }
        if !p.accumulate(&s.rows, &mut self.acc) {
            self.acc.fill(fast::Row4::default());
            s.u();
            return Err(self.fast_failure(&s.u));
        }
        s.u_stale = true;
        let x0: &[f64] = &self.x0;
        let FusedState { v, rows, .. } = s;
        let acc = &mut self.acc[..];
        match load {
            NodeLoad::Forces(f) => packed_node_pass(
                |i, k, r, m| NodeLoad::Forces(f).acceleration(i, k, r, m),
                (v, acc, rows),
                (inv_mass, fixed, x0),
                positions,
                alpha,
                dt,
            ),
            NodeLoad::Acceleration(g) => packed_node_pass(
                |i, k, r, m| NodeLoad::Acceleration(g).acceleration(i, k, r, m),
                (v, acc, rows),
                (inv_mass, fixed, x0),
                positions,
                alpha,
                dt,
            ),
        }
        Ok(())
    }

    /// [`FemModel::step_symplectic_euler`] on the generic element path: forces into
    /// `acc3`, then `v` and `u` updated (the same operations as the integrator's).
    fn step_generic(
        &mut self,
        s: &mut FusedState,
        load: NodeLoad<'_>,
        inv_mass: &[f64],
        fixed: &[bool],
        alpha: f64,
        dt: f64,
    ) -> Result<(), ElementFailure> {
        let mut acc3 = std::mem::take(&mut self.acc3);
        acc3.resize(3 * self.n_nodes, 0.0);
        s.u();
        let res = self.internal_forces(&s.u, &mut acc3);
        if res.is_ok() {
            s.rows_valid = false;
            const NB: usize = 4096;
            let body =
                |a0: usize, uc: &mut [f64], vc: &mut [f64], rc: &[f64], mc: &[f64], xc: &[bool]| {
                    for a in 0..mc.len() {
                        for k in 0..3 {
                            let i = 3 * a + k;
                            if xc[a] {
                                vc[i] = 0.0;
                                uc[i] = 0.0;
                            } else {
                                let acc_i =
                                    load.acceleration(3 * a0 + i, k, rc[i], mc[a]) - alpha * vc[i];
                                vc[i] += dt * acc_i;
                                uc[i] += dt * vc[i];
                            }
                        }
                    }
                };
            let FusedState { u, v, .. } = s;
            if self.n_nodes >= 2 * NB {
                u.par_chunks_mut(3 * NB)
                    .zip(v.par_chunks_mut(3 * NB))
                    .zip(acc3.par_chunks(3 * NB))
                    .zip(inv_mass.par_chunks(NB).zip(fixed.par_chunks(NB)))
                    .enumerate()
                    .for_each(|(c, (((uc, vc), rc), (mc, xc)))| body(c * NB, uc, vc, rc, mc, xc));
            } else {
                body(0, u, v, &acc3, inv_mass, fixed);
            }
        }
        self.acc3 = acc3;
        res
    }

    fn npe(&self) -> usize {
        self.kind.nodes_per_element()
    }

    /// Lumped mass per node (kg): ρ × element measure shared equally by its nodes.
    pub fn lumped_mass(&self) -> Vec<f64> {
        let npe = self.npe();
        let mut m = vec![0.0; self.n_nodes];
        for (e, el) in self.cells.chunks_exact(npe).enumerate() {
            let share = self.params.density * self.measure[e] / npe as f64;
            for &a in el {
                m[a as usize] += share;
            }
        }
        m
    }

    /// Reference measure per element (volume, or h·A0 for membranes).
    pub fn element_measures(&self) -> &[f64] {
        &self.measure
    }

    /// Reference node positions, 3 per node.
    pub fn reference_positions(&self) -> &[f64] {
        &self.x0
    }

    /// Deformation gradient of element e (membranes: 3x2 in the first two columns, third
    /// column zero) and its determinant-like measure (tets `det F`; membranes the signed area
    /// ratio against the reference normal).
    fn deformation(&self, e: usize, u: &[f64]) -> (Matrix3<f64>, f64) {
        let npe = self.npe();
        let el = &self.cells[e * npe..(e + 1) * npe];
        let x = |k: usize| -> Vector3<f64> {
            let a = el[k] as usize * 3;
            Vector3::new(
                self.x0[a] + u[a],
                self.x0[a + 1] + u[a + 1],
                self.x0[a + 2] + u[a + 2],
            )
        };
        match self.kind {
            ElementKind::Tet4 => {
                let x0 = x(0);
                let ds = Matrix3::from_columns(&[x(1) - x0, x(2) - x0, x(3) - x0]);
                let dminv = Matrix3::from_column_slice(&self.dminv[e * 9..e * 9 + 9]);
                let f = ds * dminv;
                let det = f.determinant();
                (f, det)
            }
            ElementKind::Tri3 => {
                let x0 = x(0);
                let ds = Matrix3x2::from_columns(&[x(1) - x0, x(2) - x0]);
                let dminv = Matrix2::from_column_slice(&self.dminv[e * 4..e * 4 + 4]);
                let f = ds * dminv;
                let n = f.column(0).cross(&f.column(1));
                let n0 = Vector3::from(self.normal0[e]);
                let det = n.dot(&n0);
                (
                    Matrix3::from_columns(&[
                        f.column(0).into(),
                        f.column(1).into(),
                        Vector3::zeros(),
                    ]),
                    det,
                )
            }
        }
    }

    /// Cauchy stress of element e (3x3; in-plane for membranes).
    pub fn element_cauchy(&self, e: usize, u: &[f64]) -> Matrix3<f64> {
        let (f3, det) = self.deformation(e, u);
        match self.kind {
            ElementKind::Tet4 => {
                let c = f3.transpose() * f3;
                let s = with_solid(&self.params.material, |m| m.pk2(&c));
                f3 * s * f3.transpose() / det
            }
            ElementKind::Tri3 => {
                let f = f3.fixed_view::<3, 2>(0, 0).into_owned();
                let c = f.transpose() * f;
                let (s, l3) = with_membrane(&self.params.material, |m| {
                    (m.pk2(&c), m.thickness_stretch(&c))
                });
                f * s * f.transpose() / (l3 * c.determinant().max(0.0).sqrt())
            }
        }
    }

    /// Nodal stress tensor T (9 per node, row-major): element Cauchy stresses averaged onto
    /// nodes weighted by reference measure (paper section 3; design note "Measures").
    pub fn nodal_cauchy(&self, u: &[f64], t: &mut [f64]) {
        let npe = self.npe();
        t.iter_mut().for_each(|x| *x = 0.0);
        let mut w = vec![0.0; self.n_nodes];
        for e in 0..self.num_elements() {
            let s = self.element_cauchy(e, u);
            let m = self.measure[e];
            for &a in &self.cells[e * npe..(e + 1) * npe] {
                let a = a as usize;
                w[a] += m;
                for i in 0..3 {
                    for j in 0..3 {
                        t[a * 9 + i * 3 + j] += m * s[(i, j)];
                    }
                }
            }
        }
        for (a, &wa) in w.iter().enumerate() {
            if wa > 0.0 {
                for x in &mut t[a * 9..a * 9 + 9] {
                    *x /= wa;
                }
            }
        }
    }

    /// Smallest `det F` over elements (tets) or signed area ratio (membranes), and where.
    pub fn min_det_f(&self, u: &[f64]) -> (usize, f64) {
        (0..self.num_elements())
            .map(|e| (e, self.deformation(e, u).1))
            .fold((0, f64::INFINITY), |a, b| if b.1 < a.1 { b } else { a })
    }

    /// Reference implementation of R(u): serial, element by element, scattered straight into
    /// `r`. The fast path [`ForceModel::internal_forces`] is tested against it.
    pub fn internal_forces_reference(
        &self,
        u: &[f64],
        r: &mut [f64],
    ) -> Result<(), ElementFailure> {
        r.iter_mut().for_each(|x| *x = 0.0);
        let npe = self.npe();
        let mut buf = [0.0; 12];
        for e in 0..self.num_elements() {
            self.element_forces(e, u, &mut buf[..npe * 3])?;
            for (k, &a) in self.cells[e * npe..(e + 1) * npe].iter().enumerate() {
                for d in 0..3 {
                    r[a as usize * 3 + d] += buf[k * 3 + d];
                }
            }
        }
        Ok(())
    }

    /// Forces of element e on its nodes (3 per corner) into `out`.
    #[inline]
    fn element_forces(&self, e: usize, u: &[f64], out: &mut [f64]) -> Result<(), ElementFailure> {
        match (&self.params.material, self.kind) {
            (Material::StVenantKirchhoff(m), k) => self.element_forces_with(m, m, k, e, u, out),
            (Material::NeoHookean(m), k) => self.element_forces_with(m, m, k, e, u, out),
            (Material::MooneyRivlin(m), k) => self.element_forces_with(m, m, k, e, u, out),
            (Material::VerondaWestmann(m), k) => self.element_forces_with(m, m, k, e, u, out),
        }
    }

    #[inline(always)]
    fn element_forces_with<S: SolidMaterial, M: MembraneMaterial>(
        &self,
        solid: &S,
        membrane: &M,
        kind: ElementKind,
        e: usize,
        u: &[f64],
        out: &mut [f64],
    ) -> Result<(), ElementFailure> {
        match kind {
            ElementKind::Tet4 => element::tet_forces(
                solid,
                &self.cells[e * 4..e * 4 + 4],
                &self.x0,
                u,
                &self.dminv[e * 9..e * 9 + 9],
                self.measure[e],
                out,
            )
            .map_err(|det_f| ElementFailure { element: e, det_f }),
            ElementKind::Tri3 => element::membrane_forces(
                membrane,
                &self.cells[e * 3..e * 3 + 3],
                &self.x0,
                u,
                &self.dminv[e * 4..e * 4 + 4],
                self.measure[e],
                self.normal0[e],
                out,
            )
            .map_err(|det_f| ElementFailure { element: e, det_f }),
        }
    }
}

fn with_solid<T>(m: &Material, f: impl FnOnce(&dyn SolidMaterial) -> T) -> T {
    match m {
        Material::StVenantKirchhoff(m) => f(m),
        Material::NeoHookean(m) => f(m),
        Material::MooneyRivlin(m) => f(m),
        Material::VerondaWestmann(m) => f(m),
    }
}

fn with_membrane<T>(m: &Material, f: impl FnOnce(&dyn MembraneMaterial) -> T) -> T {
    match m {
        Material::StVenantKirchhoff(m) => f(m),
        Material::NeoHookean(m) => f(m),
        Material::MooneyRivlin(m) => f(m),
        Material::VerondaWestmann(m) => f(m),
    }
}

impl ForceModel for FemModel {
    fn num_nodes(&self) -> usize {
        self.n_nodes
    }

    fn internal_forces(&mut self, u: &[f64], r: &mut [f64]) -> Result<(), ElementFailure> {
        if let Some(p) = &self.pack {
            fill_rows(&mut self.rows, u, &self.x0, p.reads_positions());
            let ok = p.accumulate(&self.rows, &mut self.acc);
            drain_rows(&mut self.acc, r);
            return if ok {
                Ok(())
            } else {
                Err(self.fast_failure(u))
            };
        }
        let npe = self.npe();
        let chunk = self.params.chunk.max(1);
        let mut ef = std::mem::take(&mut self.elem_forces);
        let this = &*self;
        // Pass 1: element forces into per-element slots (independent writes).
        let result = if this.num_elements() >= 2 * chunk {
            ef.par_chunks_mut(chunk * npe * 3)
                .enumerate()
                .map(|(ci, block)| {
                    for (k, out) in block.chunks_exact_mut(npe * 3).enumerate() {
                        this.element_forces(ci * chunk + k, u, out)?;
                    }
                    Ok(())
                })
                .reduce(
                    || Ok(()),
                    // Keep the lowest failing element, whatever the scheduling.
                    |a: Result<(), ElementFailure>, b| match (a, b) {
                        (Err(x), Err(y)) => Err(if x.element <= y.element { x } else { y }),
                        (Err(x), _) | (_, Err(x)) => Err(x),
                        _ => Ok(()),
                    },
                )
        } else {
            ef.chunks_exact_mut(npe * 3)
                .enumerate()
                .try_for_each(|(e, out)| this.element_forces(e, u, out))
        };
        // Pass 2: gather per node in fixed slot order.
        let gather = |(n, rn): (usize, &mut [f64])| {
            let (mut a, mut b, mut c) = (0.0, 0.0, 0.0);
            for &s in &this.node_slots[this.node_ptr[n] as usize..this.node_ptr[n + 1] as usize] {
                let s = s as usize * 3;
                a += ef[s];
                b += ef[s + 1];
                c += ef[s + 2];
            }
            rn[0] = a;
            rn[1] = b;
            rn[2] = c;
        };
        if result.is_ok() {
            if this.num_elements() >= 2 * chunk {
                r.par_chunks_mut(3)
                    .enumerate()
                    .with_min_len(1024)
                    .for_each(gather);
            } else {
                r.chunks_mut(3).enumerate().for_each(gather);
            }
        }
        self.elem_forces = ef;
        result
    }

    fn nodal_stress(&self, u: &[f64], t: &mut [f64]) {
        self.nodal_cauchy(u, t)
    }

    fn strain_energy(&self, u: &[f64]) -> f64 {
        (0..self.num_elements())
            .map(|e| {
                let (f3, _) = self.deformation(e, u);
                let w = match self.kind {
                    ElementKind::Tet4 => {
                        let c = f3.transpose() * f3;
                        with_solid(&self.params.material, |m| m.energy(&c))
                    }
                    ElementKind::Tri3 => {
                        let f = f3.fixed_view::<3, 2>(0, 0).into_owned();
                        let c = f.transpose() * f;
                        with_membrane(&self.params.material, |m| m.energy(&c))
                    }
                };
                w * self.measure[e]
            })
            .sum()
    }
}

/// Per element `G_e = npe Σ_a |∇N_a|²` (1/m²; 0 for a degenerate element): the element's
/// small-strain stiffness is bounded by `c² G_e` times its lumped mass, `K_e ≤ c² G_e M_e`.
pub fn gradient_sums(mesh: &Mesh) -> Vec<f64> {
    (0..mesh.num_elements())
        .map(|e| {
            let p = mesh.element_points(e);
            // Rows of Dm⁻¹ are ∇N_1.. ; ∇N_0 = −Σ.
            match mesh.kind {
                ElementKind::Tet4 => match tet_dm_inverse(&p) {
                    Some((inv, _)) => {
                        let g0 = -(inv.row(0) + inv.row(1) + inv.row(2));
                        4.0 * (g0.norm_squared()
                            + (0..3).map(|i| inv.row(i).norm_squared()).sum::<f64>())
                    }
                    None => 0.0,
                },
                ElementKind::Tri3 => match membrane_frame(&p) {
                    Some((inv, _, _)) => {
                        let g0 = -(inv.row(0) + inv.row(1));
                        3.0 * (g0.norm_squared()
                            + (0..2).map(|i| inv.row(i).norm_squared()).sum::<f64>())
                    }
                    None => 0.0,
                },
            }
        })
        .collect()
}

#[cfg(test)]
pub(crate) mod tests;
