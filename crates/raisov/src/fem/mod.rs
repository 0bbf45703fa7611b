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
//! Element tangent stiffness `K_e = ∂R_e/∂u_e` ([`FemModel::element_stiffness`], for implicit
//! solvers: [`crate::statics::newton`]): column `(b, k)` is `R_e`'s formula with
//! `P` replaced by `dP = ∂P/∂F : (e_k ⊗ ∇N_b)` from the law's tangent (equations in
//! `element.rs`); the generic path, never the packed one.
//!
//! Inversion: an element with `det F ≤ 0` (tets) or flipped against its reference normal
//! (membranes) is an [`ElementFailure`], unless the law says it is defined there
//! ([`crate::material::SolidMaterial::handles_inversion`]: stable neo-Hookean tetrahedra).
//!
//! Rate-dependent laws ([`crate::material::NeoHookeanVisco`], tetrahedra, the generic path):
//! the model keeps the internal variables per element (`visco.rs`) and evaluates each
//! element with its law over the step in progress ([`crate::material::ViscoStep`]: the
//! stress, the step potential as the element's energy, the algorithmic tangent). Who advances
//! them ([`ForceModel::set_step`], [`ForceModel::accept_step`]):
//! - explicit integrators ([`crate::integrate::SingleLevel`]): evaluations at `Δt = 0` (the
//!   history as last accepted, so a step's stages all see `H_i^n`), and after each step the
//!   new configuration accepted over the step's Δt;
//! - backward Euler ([`crate::statics::implicit`]): evaluations at the step's `h` (the
//!   recurrence to the trial configuration, its algorithmic tangent in Newton's iteration),
//!   the converged configuration accepted over `h`, and `Δt = 0` between steps;
//! - everything else (static solves, whatever the solver): `Δt = ∞`, the fully relaxed
//!   (long-term) equilibrium with `μ_∞ = μ (1 − Σ α_i)`, a model's state until it is told
//!   otherwise; the reference of an interactive frame takes the stepper's history at `Δt = 0`
//!   (the equilibrium of the frame's internal state, [`crate::scenario::interactive`]).
//!
//! The internal variables are the model's history ([`ForceModel::save_history`]): every
//! stepper's checkpoint keeps them, so a frame restored after a rejected try (the frame loop
//! of [`crate::sim`]) resumes from the history it started with.
//!
//! Fibre fields ([`FemParams::fibres`], tetrahedra of the fibre laws, the generic path): a
//! unit reference direction `a0_e` per element. Element e is evaluated with its law's `a0`
//! replaced by `a0_e` (a copy of the law's constants with that direction), in every
//! evaluation: forces, energy, tangent, Cauchy stress. The laws are written in
//! `C = FᵀF` and `a0`, so a rigid rotation `Q` of the reference mesh together with its field
//! (`X → QX`, `a0_e → Q a0_e`) leaves every element's energy unchanged. Without a field
//! every element has the law's own `a0`; the isotropic laws and the packed path have no
//! fibre and are untouched.
//!
//! Nodal stress T (paper section 3, from its reference \[11\]): element Cauchy stress `σ = F S Fᵀ / J`
//! (membranes: `J = λ3 √det C`, σ in-plane, 3x3), averaged onto nodes weighted by reference
//! element measure.
//!
//! Data layout for speed: flat arrays, `Dm⁻¹` and measures precomputed. Compressible
//! neo-Hookean tetrahedra (the benchmark work) take the packed, vectorised path of [`packed`]:
//! elements sorted into slabs and by a Morton key, slabs coloured so that one colour's slabs
//! scatter into `r` concurrently without sharing a node (fixed summation order per node).
//! Every other material and the membranes write element forces into per-element slots in
//! parallel and then gather them per node in a fixed order. Either way the result has the
//! same bits on any number of threads and no atomics are needed. The packed path can store
//! its element data (`Dm⁻¹`, volumes) in f32 ([`FemParams::precision`], [`Precision`]; tolerance
//! against f64 in [`packed`]); arithmetic and state stay f64. Element ids in
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
//! per node or, as gravity, one acceleration for all ([`NodeLoad`]). It lives with the packed
//! path, in `packed/fused.rs`.

mod element;
pub mod loads;
pub mod packed;
mod visco;

use crate::material::{
    HolzapfelGasserOgden, Material, MembraneMaterial, SolidMaterial, TiNeoHookean,
};
use crate::mesh::{ElementKind, Mesh};
use crate::{Error, Result};
pub use element::{membrane_frame, membrane_stiffness, tet_dm_inverse, tet_stiffness};
use nalgebra::{Matrix2, Matrix3, Matrix3x2, Vector3};
pub use packed::{FusedState, NodeLoad, Precision};
use rayon::prelude::*;

/// An element that cannot be evaluated: inverted (tets `det F <= 0`) or collapsed
/// (membranes: area ratio `<= 0` or normal flipped against the reference).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ElementFailure {
    /// The element's index.
    pub element: usize,
    /// `det F` (tets) or the area ratio (membranes) found there.
    pub det_f: f64,
}

/// The element structure of a force model's tangent ([`ForceModel::tangent_elements`]):
/// `nodes` nodes, elements of `nodes_per_element` nodes each, listed in `cells`.
#[derive(Clone, Copy, Debug)]
pub struct ElementTopology<'a> {
    /// Number of nodes.
    pub nodes: usize,
    /// Nodes per element (3 or 4).
    pub nodes_per_element: usize,
    /// Each element's nodes, `nodes_per_element` of them, element after element.
    pub cells: &'a [u32],
}

impl ElementTopology<'_> {
    /// Number of elements.
    pub fn len(&self) -> usize {
        self.cells.len() / self.nodes_per_element.max(1)
    }
    /// Whether there is no element.
    pub fn is_empty(&self) -> bool {
        self.cells.is_empty()
    }
    /// Element `e`'s nodes.
    pub fn element(&self, e: usize) -> &[u32] {
        let k = self.nodes_per_element;
        &self.cells[e * k..(e + 1) * k]
    }
}

/// What every integrator and solver sees of the physics (Vega FEM's `ForceModel`): internal
/// forces `R(u)`, the strain energy whose gradient they are, and their tangent
/// `K = ∂R/∂u`. Displacements and forces are flat, 3 per node.
///
/// The tangent is the sum of element blocks (the finite-element model's
/// [`ForceModel::element_tangent`], over [`ForceModel::tangent_elements`]) and of symmetric
/// blocks over a few nodes each ([`ForceModel::add_extra_tangent`]: a follower pressure's
/// triangles, a penalty tool's penetrating nodes), so that an assembled solver builds `K` on
/// the elements' pattern. Wrappers that add forces ([`loads::Loaded`],
/// [`crate::contact::Contact`]) pass their inner model's elements on and add their own
/// blocks; each block is checked against finite differences of the forces in the tests.
pub trait ForceModel: Send + Sync {
    /// Number of nodes (the vectors have 3 entries per node).
    fn num_nodes(&self) -> usize;
    /// `r = R(u)`. Fails on the lowest-numbered element that cannot be evaluated.
    fn internal_forces(&mut self, u: &[f64], r: &mut [f64]) -> Result<(), ElementFailure>;
    /// Strain energy E(u) (J).
    fn strain_energy(&self, u: &[f64]) -> f64;
    /// Nodal stress tensor T (9 per node, row-major, Pa): the measure of paper section 3.
    fn nodal_stress(&self, u: &[f64], t: &mut [f64]);
    /// The strain energy where every element is admissible: `+∞` where one is inverted or
    /// collapsed or the energy is not finite. The line searches' merit. Default:
    /// [`ForceModel::strain_energy`].
    fn admissible_energy(&self, u: &[f64]) -> f64 {
        self.strain_energy(u)
    }
    /// The elements whose tangents sum to `K` ([`ForceModel::element_tangent`]); `None` where
    /// the model has no element tangent (an assembled solver cannot take it, finite
    /// differences of the forces can). Default: none.
    fn tangent_elements(&self) -> Option<ElementTopology<'_>> {
        None
    }
    /// `K_e = ∂R_e/∂u_e` of element `e` at `u` into `out` (`(3 npe)²` entries, row-major, row
    /// and column `3 i + k` the `k`-th component of the element's `i`-th node). Called only
    /// for the elements of [`ForceModel::tangent_elements`]; the default has none.
    fn element_tangent(&self, e: usize, _u: &[f64], out: &mut [f64]) -> Result<(), ElementFailure> {
        out.iter_mut().for_each(|x| *x = 0.0);
        let _ = e;
        Ok(())
    }
    /// The tangent's blocks beyond the elements at `u`: `add(nodes, block)` for each, `block`
    /// symmetric, `(3 k)²` entries row-major over the `k` nodes (the symmetric part of a
    /// follower pressure's stiffness per loaded triangle, a penalty tool's per penetrating
    /// node), in a fixed order. Default: none.
    fn add_extra_tangent(&self, _u: &[f64], _add: &mut dyn FnMut(&[u32], &[f64])) {}
    /// `det F` of element `e` at `u` (tets), or its signed area ratio (membranes): `≤ 0`
    /// where it is inverted or collapsed. Called only for the elements of
    /// [`ForceModel::tangent_elements`]; the default has none.
    fn element_det_f(&self, _e: usize, _u: &[f64]) -> f64 {
        1.0
    }
    /// The smallest [`ForceModel::element_det_f`] over the elements of
    /// [`ForceModel::tangent_elements`] at `u`, and where (the first of equals); `(0, ∞)`
    /// without elements.
    fn min_det_f(&self, u: &[f64]) -> (usize, f64) {
        let ne = self.tangent_elements().map_or(0, |t| t.len());
        (0..ne)
            .map(|e| (e, self.element_det_f(e, u)))
            .fold((0, f64::INFINITY), |a, b| if b.1 < a.1 { b } else { a })
    }
    /// Set the time (s) at which the time-dependent loads and tools a model carries are
    /// evaluated ([`loads::Loaded`]); [`crate::integrate::System::impose`] calls it with the
    /// time it imposes the constraints at. Default: nothing depends on time.
    fn set_time(&self, _t: f64) {}
    /// Scale the loads and tool motions a model carries by `f` (static load increments);
    /// default: none carried.
    fn set_load_factor(&self, _f: f64) {}
    /// The step Δt (s) over which the force, energy and tangent evaluations of a
    /// rate-dependent law advance its internal variables from the last accepted configuration
    /// (module docs, "Rate-dependent laws"): ∞ (every model's start) is the fully relaxed
    /// law, 0 the stress with the history as last accepted. Default: no such law.
    fn set_step(&mut self, _dt: f64) {}
    /// Accept `u` as the configuration at the end of a step of `dt` (s), at the time last set
    /// ([`ForceModel::set_time`]): the one end-of-step hook. A rate-dependent law's internal
    /// variables advance to it (module docs, "Rate-dependent laws"), and path-dependent
    /// contact state (the friction anchors of [`crate::contact`]) moves on to it; the forces
    /// until the next call are those of the state accepted here. Every stepper calls it once
    /// per accepted step, on each level with that level's state. Returns whether the model
    /// has such state (its forces at `u` may differ after the call: cached residuals are
    /// stale). Default: none.
    fn accept_step(&mut self, _u: &[f64], _dt: f64) -> bool {
        false
    }
    /// Net forces of the loads and tools a model carries at `u` ([`loads::LoadReport`]);
    /// default: none.
    fn load_report(&mut self, _u: &[f64]) -> loads::LoadReport {
        loads::LoadReport::default()
    }
    /// The force the tools exert on each node at `u` into `out` (3 per node, N), the contact
    /// field of the frames; `false` (and `out` untouched) where the model carries no tools.
    fn contact_forces(&self, _u: &[f64], _out: &mut [f64]) -> bool {
        false
    }
    /// The tools' friction force on each node at `u` into `out` (3 per node, N), part of
    /// [`ForceModel::contact_forces`]; `false` (and `out` untouched) where no tool has
    /// friction ([`crate::contact`]).
    fn friction_forces(&self, _u: &[f64], _out: &mut [f64]) -> bool {
        false
    }
    /// Append the path-dependent state to `out` (checkpoints; a fixed length per model).
    /// Default: none.
    fn save_history(&self, _out: &mut Vec<f64>) {}
    /// Restore the path-dependent state from the front of `h`, as
    /// [`ForceModel::save_history`] wrote it; returns how many values it read. Default: none.
    fn load_history(&mut self, _h: &[f64]) -> usize {
        0
    }
    /// Carry the model to a cut mesh ([`crate::mesh::cut`]): the same physics on
    /// `change.mesh`, each element scaled by its material fraction, with the per-element data
    /// (fibres, internal variables) of the element it is a copy of. Default: refused, naming
    /// the model.
    fn cut(&mut self, _change: &crate::mesh::cut::TopologyChange) -> crate::Result<()> {
        Err(Error::param(
            "cut",
            "this force model cannot be cut (cutting takes the elements' own forces and gravity; pressure, traction, timed loads and tools are not carried through a cut yet)",
        ))
    }
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
    /// Wanted elements per slab of the packed neo-Hookean tetrahedron path (see [`packed`]):
    /// one slab (serial) below 2 slabs' worth, else a multiple of 4 slabs (2 colours × an
    /// even number of slabs per colour) and no more than the node numbering's band allows.
    /// The layout, hence the bits, depend on this and the mesh only, never on the thread
    /// count. Default 16384 (10k-node standard box: 4 slabs; 100k: 16; 1M: 36).
    pub slab: usize,
    /// Storage precision of the packed neo-Hookean tetrahedron data (`Dm⁻¹` and volumes in
    /// f64, or in f32 widened to f64 on load; see [`packed`] for the tolerance). Other
    /// materials and membranes, the masses, the strain energy and the stresses are f64
    /// whatever this says. Default [`Precision::F64`].
    pub precision: Precision,
    /// A fibre direction per element for the fibre laws (ti-neo-hookean, hgo): element `e`
    /// is evaluated with its law's `a0` replaced by `fibres[e]` (module docs, "Fibre
    /// fields"). `None` (the default): every element has the law's own direction.
    pub fibres: Option<ElementFibres>,
    /// The material fraction of each element, for a cut mesh ([`crate::mesh::cut`]): element
    /// `e`'s reference measure, hence its strain energy, forces, tangent and lumped mass, is
    /// `fractions[e]` times its tetrahedron's. `None` (the default): every element whole.
    pub fractions: Option<std::sync::Arc<[f64]>>,
}

/// One unit fibre direction per element, in the reference configuration (shared, cheap to
/// clone: every level's parameters carry their own).
#[derive(Clone, PartialEq)]
pub struct ElementFibres(pub std::sync::Arc<[[f64; 3]]>);

impl ElementFibres {
    /// The directions, normalised: an error naming `key` and the element where one is zero
    /// or not finite.
    pub fn normalised(dirs: &[[f64; 3]], key: &str) -> Result<ElementFibres> {
        let mut out = Vec::with_capacity(dirs.len());
        for (e, d) in dirs.iter().enumerate() {
            let a = crate::material::unit_direction(Vector3::from(*d), key).map_err(|_| {
                Error::param(
                    key,
                    format!(
                        "element {e} has fibre [{}, {}, {}], not a direction: every element needs a non-zero finite vector",
                        d[0], d[1], d[2]
                    ),
                )
            })?;
            out.push([a.x, a.y, a.z]);
        }
        Ok(ElementFibres(out.into()))
    }
    /// Number of elements.
    pub fn len(&self) -> usize {
        self.0.len()
    }
    /// Whether there is no element.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
    /// The directions, 3 numbers per element (a cell field of the outputs).
    pub fn flat(&self) -> &[f64] {
        self.0.as_flattened()
    }
}

impl std::fmt::Debug for ElementFibres {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "ElementFibres({} elements)", self.0.len())
    }
}

impl FemParams {
    /// Defaults for `material`: density 1000 kg/m³, thickness 1 mm (membranes), f64 element data.
    pub fn new(material: Material) -> Self {
        FemParams {
            material,
            density: 1000.0,
            thickness: 1e-3,
            chunk: 2048,
            slab: 16384,
            precision: Precision::F64,
            fibres: None,
            fractions: None,
        }
    }
}

/// The finite-element force model of one mesh.
pub struct FemModel {
    /// Element type of the mesh.
    pub kind: ElementKind,
    /// The physics it was built with.
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
    pack: Option<packed::TetPack>,
    /// With `pack`, the elements of a cut mesh that hold part of their tetrahedron: their
    /// forces come from the generic path, added after the pack's (ascending).
    partial: Vec<u32>,
    /// Node rows the packed kernel reads in [`FemModel::internal_forces`], filled from `u`
    /// at each force pass: `X + u` (positions kernel, f64 storage) or `u` (f32 storage).
    /// Empty without `pack`. (The fused step keeps its rows in its [`FusedState`].)
    rows: Vec<packed::Row4>,
    /// Force rows the packed kernel (or, in the fused step, the generic path) accumulates
    /// into; all zeros between passes.
    acc: Vec<packed::Row4>,
    /// Generic-path forces of the fused step (3 per node); empty with `pack`.
    acc3: Vec<f64>,
    /// The internal variables of a rate-dependent law (tetrahedra of neo-hookean-visco).
    visco: Option<visco::Visco>,
}

/// Bytes an element of a [`FemModel`] may take: its `Dm⁻¹` and measure, its node slots, its
/// packed kernel data, with room to spare.
pub const MODEL_ELEMENT_BYTES: u64 = 192;

/// Bytes a node of a [`FemModel`] may take: its reference position, its slot offsets, its
/// force and state rows, with room to spare.
pub const MODEL_NODE_BYTES: u64 = 160;

impl FemModel {
    /// Precompute reference data. Errors on a law that does not apply to the mesh's elements
    /// ([`Material::check_for`]), on an element with zero or negative reference
    /// measure, or where the model would need more memory than is available
    /// ([`MODEL_ELEMENT_BYTES`] an element, [`MODEL_NODE_BYTES`] a node).
    pub fn new(mesh: &Mesh, params: FemParams) -> Result<Self> {
        let npe = mesh.npe();
        let ne = mesh.num_elements();
        if !(params.density > 0.0 && params.density.is_finite()) {
            return Err(Error::param(
                "density",
                "must be a positive number (kg/m^3)",
            ));
        }
        params.material.check_for(mesh.kind)?;
        if let Some(f) = &params.fibres {
            if params.material.fibre().is_none() {
                return Err(Error::param(
                    "material.fibre",
                    format!(
                        "a fibre field is given, but law \"{}\" has no fibres (the fibre laws: \"ti-neo-hookean\", \"hgo\")",
                        params.material.name()
                    ),
                ));
            }
            if f.len() != ne {
                return Err(Error::param(
                    "material.fibre",
                    format!(
                        "the fibre field has {} directions for {ne} elements: one per element",
                        f.len()
                    ),
                ));
            }
            if let Some(e) =
                f.0.iter()
                    .position(|a| !((Vector3::from(*a).norm() - 1.0).abs() <= 1e-9))
            {
                let a = f.0[e];
                return Err(Error::param(
                    "material.fibre",
                    format!(
                        "element {e}'s fibre [{}, {}, {}] must be a unit vector",
                        a[0], a[1], a[2]
                    ),
                ));
            }
        }
        if mesh.kind == ElementKind::Tri3 && !(params.thickness > 0.0) {
            return Err(Error::param("thickness", "must be a positive number (m)"));
        }
        if let Some(f) = &params.fractions {
            if f.len() != ne {
                return Err(Error::param(
                    "fractions",
                    format!(
                        "{} material fractions for {ne} elements: one per element",
                        f.len()
                    ),
                ));
            }
            if let Some(e) = f.iter().position(|&v| !(v > 0.0 && v <= 1.0)) {
                return Err(Error::param(
                    "fractions",
                    format!("element {e}'s material fraction {} must be in (0, 1]", f[e]),
                ));
            }
        }
        let n = mesh.num_nodes();
        let visco_bytes = match &params.material {
            Material::NeoHookeanVisco(m) => visco::bytes_per_element(m.prony.len()),
            _ => 0,
        };
        crate::memory::check_for(
            &format!("the force model of {n} nodes and {ne} elements"),
            (ne as u64)
                .saturating_mul(MODEL_ELEMENT_BYTES.saturating_add(visco_bytes))
                .saturating_add((n as u64).saturating_mul(MODEL_NODE_BYTES)),
            "use a coarser mesh",
        )
        .map_err(|e| Error::param("mesh", e))?;
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
                    measure.push(match &params.fractions {
                        Some(f) => vol * f[e],
                        None => vol,
                    });
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
        let (pack, partial) = match (&params.material, mesh.kind) {
            (Material::NeoHookean(m), ElementKind::Tet4) => packed::TetPack::of_whole(
                m,
                &x0,
                &mesh.cells,
                &dminv,
                &measure,
                params.fractions.as_deref(),
                params.slab.max(1),
                params.precision,
            ),
            _ => (None, Vec::new()),
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
            rows: vec![packed::Row4::default(); if pack.is_some() { n } else { 0 }],
            acc: {
                let mut acc = packed::huge_page_vec(n);
                acc.resize(n, packed::Row4::default());
                acc
            },
            acc3: if pack.is_some() {
                Vec::new()
            } else {
                vec![0.0; 3 * n]
            },
            pack,
            partial,
            visco: match &params.material {
                Material::NeoHookeanVisco(m) => Some(visco::Visco::new(m.clone(), ne)),
                _ => None,
            },
            params,
        })
    }

    /// `Dm⁻¹` of every element, column-major (9 per tetrahedron, 4 per triangle).
    #[cfg(test)]
    pub(crate) fn dminv_column_major(&self) -> &[f64] {
        &self.dminv
    }

    /// Number of elements.
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

    /// Instruction set of the fast kernel (`"portable"`, `"avx2"`, `"avx512"`), if in use.
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

    /// The strain energy `E(u) = Σ_e W(F_e) |Ω_e|` (J) of a state the internal forces accept:
    /// +∞ where a tetrahedron is inverted (`det F ≤ 0`) and its law refuses that state, the
    /// condition of [`ForceModel::internal_forces`]' [`ElementFailure`]. A law written in
    /// `C = FᵀF` alone gives an inverted tetrahedron the energy of its mirror image, so
    /// [`ForceModel::strain_energy`] is finite there; a line search whose merit is Π needs this
    /// one, where inverting an element is no decrease. Membranes are never refused here: their
    /// laws see only the in-plane `C`.
    pub fn admissible_strain_energy(&self, u: &[f64]) -> f64 {
        self.energy_sum(u, true)
    }

    /// `Σ_e W(F_e) |Ω_e|` over fixed blocks of [`ENERGY_BLOCK`] elements in parallel, then the
    /// blocks' sums in order: the same bits on any thread count. `refuse`: +∞ where a
    /// tetrahedron's law refuses its `det F ≤ 0`.
    fn energy_sum(&self, u: &[f64], refuse: bool) -> f64 {
        let refuse = refuse
            && self.kind == ElementKind::Tet4
            && !self.with_element_solid(0, |m| m.handles_inversion());
        let ne = self.num_elements();
        let blocks: Vec<f64> = (0..ne.div_ceil(ENERGY_BLOCK))
            .into_par_iter()
            .map(|b| {
                (b * ENERGY_BLOCK..ne.min((b + 1) * ENERGY_BLOCK))
                    .map(|e| {
                        let (f3, det) = self.deformation(e, u);
                        if refuse && !(det > 0.0) {
                            return f64::INFINITY;
                        }
                        let w = match self.kind {
                            ElementKind::Tet4 => self.with_element_solid(e, |m| m.energy_f(&f3)),
                            ElementKind::Tri3 => {
                                let f = f3.fixed_view::<3, 2>(0, 0).into_owned();
                                let n0 = Vector3::from(self.normal0[e]);
                                with_membrane(&self.params.material, |m| m.energy_f(&f, &n0))
                            }
                        };
                        w * self.measure[e]
                    })
                    .sum::<f64>()
            })
            .collect();
        blocks.iter().sum()
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
                let p = self.with_element_solid(e, |m| m.pk1(&f3));
                p * f3.transpose() / det
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

    /// `det F` of element e (tets) or its signed area ratio (membranes).
    pub fn element_det_f(&self, e: usize, u: &[f64]) -> f64 {
        self.deformation(e, u).1
    }

    /// The number of elements with `det F ≤ 0` (tets) or a non-positive signed area ratio
    /// (membranes): inverted or collapsed.
    pub fn count_inverted(&self, u: &[f64]) -> usize {
        (0..self.num_elements())
            .filter(|&e| self.deformation(e, u).1 <= 0.0)
            .count()
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
            (Material::StableNeoHookean(m), k) => self.element_forces_with(m, m, k, e, u, out),
            (Material::TiNeoHookean(m), ElementKind::Tet4) => {
                let m = self
                    .element_fibre(e)
                    .map_or(*m, |fibre| TiNeoHookean { fibre, ..*m });
                self.tet_forces_with(&m, e, u, out)
            }
            (Material::HolzapfelGasserOgden(m), ElementKind::Tet4) => {
                let m = self
                    .element_fibre(e)
                    .map_or(*m, |fibre| HolzapfelGasserOgden { fibre, ..*m });
                self.tet_forces_with(&m, e, u, out)
            }
            (Material::NeoHookeanVisco(_), ElementKind::Tet4) => {
                let law = self
                    .visco
                    .as_ref()
                    .expect("built with the law")
                    .element_law(e);
                self.tet_forces_with(&law, e, u, out)
            }
            (
                Material::TiNeoHookean(_)
                | Material::HolzapfelGasserOgden(_)
                | Material::NeoHookeanVisco(_),
                ElementKind::Tri3,
            ) => {
                unreachable!("FemModel::new refuses solid-only laws on membranes")
            }
        }
    }

    /// Element e's fibre direction where the model has a per-element field
    /// ([`FemParams::fibres`]); `None` where every element has the law's own.
    #[inline(always)]
    fn element_fibre(&self, e: usize) -> Option<Vector3<f64>> {
        self.params
            .fibres
            .as_ref()
            .and_then(|f| f.0.get(e))
            .map(|a| Vector3::from(*a))
    }

    /// `f` of element e's solid law: the model's law (a fibre law with element e's fibre,
    /// [`FemParams::fibres`]), or for a rate-dependent one its law over the step in
    /// progress ([`crate::material::ViscoStep`]).
    fn with_element_solid<T>(&self, e: usize, f: impl FnOnce(&dyn SolidMaterial) -> T) -> T {
        if let Some(v) = &self.visco {
            if e < self.num_elements() {
                return f(&v.element_law(e));
            }
        }
        if let Some(fibre) = self.element_fibre(e) {
            match &self.params.material {
                Material::TiNeoHookean(m) => return f(&TiNeoHookean { fibre, ..*m }),
                Material::HolzapfelGasserOgden(m) => {
                    return f(&HolzapfelGasserOgden { fibre, ..*m })
                }
                _ => {}
            }
        }
        with_solid(&self.params.material, f)
    }

    /// The per-element fibre field the model was built with ([`FemParams::fibres`]).
    pub fn fibres(&self) -> Option<&ElementFibres> {
        self.params.fibres.as_ref()
    }

    /// The step (s) the force evaluations of a rate-dependent law use ([`ForceModel::set_step`];
    /// ∞: fully relaxed), `None` for other laws.
    pub fn visco_step(&self) -> Option<f64> {
        self.visco.as_ref().map(|v| v.step())
    }

    /// Forces of tetrahedron e.
    #[inline(always)]
    fn tet_forces_with<S: SolidMaterial>(
        &self,
        solid: &S,
        e: usize,
        u: &[f64],
        out: &mut [f64],
    ) -> Result<(), ElementFailure> {
        element::tet_forces(
            solid,
            &self.cells[e * 4..e * 4 + 4],
            &self.x0,
            u,
            &self.dminv[e * 9..e * 9 + 9],
            self.measure[e],
            out,
        )
        .map_err(|det_f| ElementFailure { element: e, det_f })
    }

    /// Tangent stiffness of element e, `∂R_e/∂u_e` (144 numbers for a tetrahedron, 81 for a
    /// triangle, row-major, rows and columns `3 × corner + axis`; [`tet_stiffness`]).
    pub fn element_stiffness(
        &self,
        e: usize,
        u: &[f64],
        out: &mut [f64],
    ) -> Result<(), ElementFailure> {
        let fail = |det_f| ElementFailure { element: e, det_f };
        match self.kind {
            ElementKind::Tet4 => self
                .with_element_solid(e, |m| {
                    element::tet_stiffness(
                        m,
                        &self.cells[e * 4..e * 4 + 4],
                        &self.x0,
                        u,
                        &self.dminv[e * 9..e * 9 + 9],
                        self.measure[e],
                        out,
                    )
                })
                .map_err(fail),
            ElementKind::Tri3 => with_membrane(&self.params.material, |m| {
                element::membrane_stiffness(
                    m,
                    &self.cells[e * 3..e * 3 + 3],
                    &self.x0,
                    u,
                    &self.dminv[e * 4..e * 4 + 4],
                    self.measure[e],
                    self.normal0[e],
                    out,
                )
            })
            .map_err(fail),
        }
    }

    /// Forces of element e on its nodes (3 per corner) at `u`: what the force pass scatters.
    #[cfg(test)]
    pub(crate) fn element_forces_of(
        &self,
        e: usize,
        u: &[f64],
    ) -> Result<Vec<f64>, ElementFailure> {
        let mut out = vec![0.0; 3 * self.npe()];
        self.element_forces(e, u, &mut out)?;
        Ok(out)
    }

    /// The nodes of element e (the mesh's connectivity).
    pub fn element_nodes(&self, e: usize) -> &[u32] {
        let npe = self.npe();
        &self.cells[e * npe..(e + 1) * npe]
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
            ElementKind::Tet4 => self.tet_forces_with(solid, e, u, out),
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
        Material::StableNeoHookean(m) => f(m),
        Material::TiNeoHookean(m) => f(m),
        Material::HolzapfelGasserOgden(m) => f(m),
        Material::NeoHookeanVisco(m) => f(&m.relaxed()),
    }
}

/// The membrane form of the model's law; [`FemModel::new`] refuses the solid-only laws on
/// membranes ([`Material::check_for`]), so a membrane model never reaches them.
fn with_membrane<T>(m: &Material, f: impl FnOnce(&dyn MembraneMaterial) -> T) -> T {
    match m {
        Material::StVenantKirchhoff(m) => f(m),
        Material::NeoHookean(m) => f(m),
        Material::MooneyRivlin(m) => f(m),
        Material::VerondaWestmann(m) => f(m),
        Material::StableNeoHookean(m) => f(m),
        Material::TiNeoHookean(_)
        | Material::HolzapfelGasserOgden(_)
        | Material::NeoHookeanVisco(_) => {
            unreachable!("FemModel::new refuses solid-only laws on membranes")
        }
    }
}

impl ForceModel for FemModel {
    fn num_nodes(&self) -> usize {
        self.n_nodes
    }

    fn cut(&mut self, change: &crate::mesh::cut::TopologyChange) -> crate::Result<()> {
        if self.kind != ElementKind::Tet4 {
            return Err(Error::param("cut", "only tetrahedral meshes can be cut"));
        }
        let mut params = self.params.clone();
        params.fractions = Some(change.fractions.clone().into());
        if let Some(f) = &params.fibres {
            params.fibres = Some(ElementFibres(
                change
                    .element_from
                    .iter()
                    .map(|&e| f.0[e as usize])
                    .collect(),
            ));
        }
        let mut next = FemModel::new(&change.mesh, params)?;
        if let Some(old) = &self.visco {
            next.visco = Some(visco::Visco::carried(old, &change.element_from));
        }
        *self = next;
        Ok(())
    }

    fn internal_forces(&mut self, u: &[f64], r: &mut [f64]) -> Result<(), ElementFailure> {
        if let Some(p) = &self.pack {
            packed::fill_rows(&mut self.rows, u, &self.x0, p.reads_positions());
            let ok = p.accumulate(&self.rows, &mut self.acc);
            packed::drain_rows(&mut self.acc, r);
            if !ok {
                return Err(self.fast_failure(u));
            }
            // The partial elements' forces in parallel, added in element order (the same
            // bits on any thread count).
            let this = &*self;
            let forces: Vec<Result<[f64; 12], ElementFailure>> = this
                .partial
                .par_iter()
                .with_min_len(64)
                .map(|&e| {
                    let mut out = [0.0; 12];
                    this.element_forces(e as usize, u, &mut out).map(|_| out)
                })
                .collect();
            for (&e, f) in self.partial.iter().zip(forces) {
                let f = f?;
                for (j, &a) in self.cells[4 * e as usize..4 * e as usize + 4]
                    .iter()
                    .enumerate()
                {
                    for k in 0..3 {
                        r[3 * a as usize + k] += f[3 * j + k];
                    }
                }
            }
            return Ok(());
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
        self.energy_sum(u, false)
    }

    fn admissible_energy(&self, u: &[f64]) -> f64 {
        self.admissible_strain_energy(u)
    }

    fn tangent_elements(&self) -> Option<ElementTopology<'_>> {
        Some(ElementTopology {
            nodes: self.n_nodes,
            nodes_per_element: self.npe(),
            cells: &self.cells,
        })
    }

    fn element_tangent(&self, e: usize, u: &[f64], out: &mut [f64]) -> Result<(), ElementFailure> {
        self.element_stiffness(e, u, out)
    }

    fn element_det_f(&self, e: usize, u: &[f64]) -> f64 {
        FemModel::element_det_f(self, e, u)
    }

    fn set_step(&mut self, dt: f64) {
        if let Some(v) = &mut self.visco {
            v.set_step(dt);
        }
    }

    fn accept_step(&mut self, u: &[f64], dt: f64) -> bool {
        let Some(mut v) = self.visco.take() else {
            return false;
        };
        let this = &*self;
        v.accept(dt, &|e| {
            let (f, det) = this.deformation(e, u);
            (det > 0.0).then(|| f.transpose() * f)
        });
        self.visco = Some(v);
        true
    }

    fn save_history(&self, out: &mut Vec<f64>) {
        if let Some(v) = &self.visco {
            v.save(out);
        }
    }

    fn load_history(&mut self, h: &[f64]) -> usize {
        self.visco.as_mut().map_or(0, |v| v.load(h))
    }
}

/// Elements per parallel task of [`FemModel`]'s strain energy; fixed, so the sum's order does
/// not depend on the thread count.
pub const ENERGY_BLOCK: usize = 4096;

/// `out_j = K(u) v_j` over all dofs for each `v_j` of `vs` (every row, constrained or not): the
/// model's tangent as element blocks ([`ForceModel::element_tangent`]) plus its blocks beyond
/// them ([`ForceModel::add_extra_tangent`]), applied without assembly. Elements with no
/// nonzero entry of any `v_j` are skipped (a product with a vector over a few nodes costs
/// their elements only). Sums in element order, then the extra blocks in their order: the
/// same bits on any thread count. Without element tangents the element part is zero.
pub fn tangent_products(
    model: &dyn ForceModel,
    u: &[f64],
    vs: &[&[f64]],
    outs: &mut [&mut [f64]],
) -> Result<(), ElementFailure> {
    for o in outs.iter_mut() {
        o.iter_mut().for_each(|x| *x = 0.0);
    }
    let mut ke = Vec::new();
    if let Some(topo) = model.tangent_elements() {
        let d = 3 * topo.nodes_per_element;
        ke.resize(d * d, 0.0);
        for e in 0..topo.len() {
            let el = topo.element(e);
            let dof = |q: usize| 3 * el[q / 3] as usize + q % 3;
            if !(0..d).any(|q| vs.iter().any(|v| v[dof(q)] != 0.0)) {
                continue;
            }
            model.element_tangent(e, u, &mut ke)?;
            for (v, o) in vs.iter().zip(outs.iter_mut()) {
                for r in 0..d {
                    let s: f64 = (0..d).map(|c| ke[r * d + c] * v[dof(c)]).sum();
                    o[dof(r)] += s;
                }
            }
        }
    }
    model.add_extra_tangent(u, &mut |nodes, block| {
        let d = 3 * nodes.len();
        let dof = |q: usize| 3 * nodes[q / 3] as usize + q % 3;
        for (v, o) in vs.iter().zip(outs.iter_mut()) {
            for r in 0..d {
                let s: f64 = (0..d).map(|c| block[r * d + c] * v[dof(c)]).sum();
                o[dof(r)] += s;
            }
        }
    });
    Ok(())
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
