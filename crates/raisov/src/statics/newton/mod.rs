//! Static equilibrium `R(u) = V` by Newton's method: the one Newton driver ([`solve_with`],
//! `driver.rs`) over a linear solve of each Newton system ([`NewtonLinear`]): the consistent
//! analytic tangent assembled on a fixed pattern ([`DirectNewton`]: faer's
//! supernodal/simplicial Cholesky `LLᵀ`, conjugate gradients preconditioned by a kept factor
//! or by a Galerkin V-cycle), or matrix-free conjugate gradients ([`MatrixFree`]: tangent
//! products by central differences of the forces, `matrix_free.rs`). The iteration below is
//! the driver's; what is said of `K`'s factorisation and hierarchy is the assembled solve's.
//!
//! Per Newton iteration, on the free dofs (constrained dofs hold their imposed values; nodes
//! sliding along directions other than x, y or z by projection, `dofs.rs`):
//!
//! ```text
//! (K(u) + σ d̄ D) δ = V_s − R(u),     u ← u + α δ
//! ```
//!
//! - `K = Σ_e K_e`, the element tangents of [`crate::fem::FemModel::element_stiffness`]
//!   (`∂R/∂u`, symmetric), assembled on a sparsity pattern fixed at the start (lower triangle,
//!   compressed columns); its symbolic factorisation is done once, the numeric one per
//!   iteration.
//! - Load stepping: `V_s = s V` and the prescribed displacements `u_c = u_c⁰ + s (g − u_c⁰)`
//!   for `s = 1/N, 2/N, …, 1` ([`DirectNewtonParams::load_steps`]; times λ,
//!   [`DirectNewtonParams::load_factor`]).
//! - Lifted first iteration: a load step whose constrained dofs move by `Δ_c` starts from the
//!   last state, the constrained dofs where they were, and solves
//!   `(K_ff + σ d̄ D) δ_f = r_f − K_fc Δ_c` (the free dofs' linear response to the move; `K_fc`
//!   summed from the same element matrices as `K_ff`). The new state has `u_c + Δ_c` and
//!   `u_f + α δ_f`, α the largest of 1, ½, … (12 halvings, then 0) whose state inverts no
//!   element and has a residual 2-norm at most that of the motions imposed alone (α = 0; a
//!   flat membrane's regularised first tangent can send `δ_f` far): Π is no merit function
//!   for a step that moves the constrained dofs. A prescribed
//!   displacement that would invert the elements around its node if imposed alone (the rest
//!   of the body at rest) is thus taken in one step where the linear response keeps them
//!   valid. The following iterations are the plain Newton ones below.
//! - Regularisation `σ d̄ D`: `D` the lumped mass per node over its mean, `d̄` the mean diagonal
//!   of K over free dofs, σ ≥ 0. σ starts at 0; a factorisation that fails (K not positive
//!   definite: a flat membrane's first tangent has no transverse stiffness, a buckling state
//!   is indefinite) raises σ to `max(σ_min, 10 σ)` and refactors; a full step (α = 1) divides
//!   σ by 10 (to 0 below σ_min), so near the solution the iteration is plain Newton and
//!   converges quadratically; a line search that finds no decrease raises σ by 100. The
//!   multigrid path below sets σ to 0 after a full step instead.
//! - Backtracking line search, α = 1, ½, ¼ … (at most 12 halvings), on the potential energy
//!   `Π(u) = E(u) − V_s·u` (Armijo: `Π(u + αδ) ≤ Π(u) − 10⁻⁴ α r·δ`, `r = V_s − R(u)`; δ is a
//!   descent direction since `K + σ d̄ D` is positive definite once factored), and where Π
//!   cannot tell (a change within 10⁻⁹ |Π|, its round-off near the solution, or a largest
//!   nodal residual already below [`DirectNewtonParams::flat_below`]) on the residual
//!   norm `‖r(u + αδ)‖₂`, which must fall. The residual norm alone is a poor merit function on
//!   large rotations: a linearised rotation shows up as spurious axial forces, and a soft
//!   cantilever's sag stalled under it. An inverted element counts as no decrease.
//! - Curvature condition: a step that passes Armijo's rule is also checked against the
//!   upper half of the strong Wolfe condition, `Π'(α) ≤ c₂ |Π'(0)|` with `c₂ = 0.9` and
//!   `Π'(α) = −r(u + αδ)·δ` (the residual is evaluated there anyway). A step that fails it has
//!   gone past the minimum of Π along δ and up its far side (the linearised response of a
//!   hanging body from rest swings it through its equilibrium, into states whose tangent is
//!   indefinite); it is replaced by the secant estimate of that minimum,
//!   `α ← α |Π'(0)| / (|Π'(0)| + Π'(α))` (at least α/10), at most twice per line search.
//!
//! Factorisation reuse ([`DirectNewtonParams::pcg_max`] = m > 0, inexact Newton): once a
//! factorisation `L Lᵀ` of some earlier `K + σ d̄ D` is kept, each Newton system is solved by
//! conjugate gradients on the current `K + σ d̄ D` preconditioned by `(L Lᵀ)⁻¹`, from δ = 0
//! to `‖r − (K + σ d̄ D) δ‖₂ ≤ η ‖r‖₂` with Eisenstat and Walker's choice 2,
//! `η_k = min(0.5, 0.9 (‖r_k‖/‖r_{k−1}‖)²)` (safeguarded by `0.9 η_{k−1}²`, and not below
//! what the stopping rule needs). A direction of non-positive curvature after the first
//! iteration truncates CG (Steihaug): the iterate so far still descends (`r·δ > 0`). Where m
//! iterations do not reach η, or the first direction has non-positive curvature, the
//! iteration factors at the current state as above and keeps that factor. Near the solution
//! `K` is positive definite and η → 0, so convergence stays superlinear.
//!
//! Multigrid-preconditioned Newton ([`DirectNewtonParams::multigrid`], with the levels given
//! to [`DirectNewton::with_levels`]): each Newton system is solved by conjugate gradients on
//! `K + σ d̄ D` preconditioned by one Galerkin V-cycle ([`crate::linalg::galerkin`]: coarse operators
//! `Pᵀ A P` over the hierarchy's host weights, Gauss-Seidel smoothing ([`crate::linalg::smoother`]),
//! a sparse Cholesky
//! factorisation of the coarsest level only, solved in `f32`: [`crate::linalg::coarse_factor`]), to
//! the same inexact-Newton tolerance η. A direction of non-positive curvature is not
//! truncated here: the iterate before it can be a step along a nearly singular direction,
//! thousands of times too long (the drape's first fine tangent after the coarse start: every
//! line-search trial inverted elements, and the iteration was lost), so σ is raised past the
//! shift at which that direction's curvature vanishes (σ* below) and the system solved again,
//! the hierarchy kept. As with factorisation reuse, the hierarchy built at one iteration
//! preconditions the next ones, whole or ([`MultigridPcg::keep`] false) only its coarsest
//! factorisation, the smoothed levels' Galerkin operators rebuilt from each new tangent (the
//! coarsest is only used through its factorisation); it is rebuilt at the current state where
//! [`MultigridPcg::max_iter`] iterations do not reach η, conjugate gradients going on from
//! the iterate so far (its work is kept), and before the next Newton iteration where they
//! needed more than two thirds of [`MultigridPcg::max_iter`] (`STALE_SHARE`; a hierarchy
//! built where the body hung at rest preconditions the final tangent of the liver L0 in 21
//! iterations, then misses η in 25). A hierarchy built at an iteration whose step was damped
//! (α < 1: the state is still far from the equilibrium, as a hanging body's first tangents
//! at rest are) is provisional, and is rebuilt after the first full step (α = 1) that follows,
//! once a solve ([`PROVISIONAL_REBUILDS`]): the rebuilt one is of a tangent near the final
//! one, for the last iterations, whose tolerances η are the tightest (`bench/RESULTS.md`:
//! the liver L0 takes 65 CG iterations with the rebuild, 100 without, and one Newton
//! iteration fewer; a solve whose first step is full keeps its first hierarchy). With a
//! fresh hierarchy, an iterate
//! that misses η after [`MultigridPcg::max_iter`] iterations is taken as it is (truncated
//! Newton: a descent direction while the curvature seen is positive). A first direction of
//! non-positive curvature, or a coarsest operator that does not factor, raises σ as a failed
//! factorisation does, and at least to twice the shift at which that direction p's curvature
//! would vanish, `σ* = σ − pᵀ(K + σ d̄ D)p / (d̄ pᵀDp)`. A kept hierarchy stays through that
//! (it is positive definite, built where the tangent was, and the shifted system is solved
//! with it); a fresh one is rebuilt with the new σ. A kept cycle that is not positive on a
//! residual is rebuilt, same σ. A full step (α = 1) sets σ back to 0, not σ/10: the next
//! tangent is tried unshifted, and where it is still indefinite the iterations up to the first
//! direction of non-positive curvature are all that trying costs before σ is set from that
//! direction's σ*. Divided by 10 a step, a σ raised once stayed for ten iterations on the 70k
//! mesher liver, each a regularised step converging linearly (`bench/RESULTS.md`). A
//! hierarchy built at an indefinite
//! tangent needs its coarsest operator shifted: the liver L0's, at the state where its kept
//! hierarchy first meets negative curvature from rest, factors only when shifted by its whole
//! mean diagonal, a coarse level too stiff to help. With coarser levels the fine level is
//! never factored.
//!
//! Stopping rule (that of `raisov bench equilibrium`, at the full load):
//! `max_a |r_a| ≤ rel_tol × max_a |V_a| + abs_tol`, `r_a` the residual force of free node a,
//! `V_a` the external force of node a (all nodes), `|·|` the Euclidean norm of a node's 3-vector.
//! Intermediate load steps stop at `max(rel_tol, 1e-6)` of their own scale.
//!
//! Nested iteration ([`super::nested::coarse_start`], [`super::nested::nested_start`]): the start `u` may be the
//! equilibrium of a coarser discretisation, interpolated, itself reached from coarser ones
//! (module `nested` in the source).
//!
//! Entry points: [`solve_system`] on a [`System`] whose force model has an element tangent,
//! [`solve_system_matrix_free`] on any, [`solve_with`] with a linear solve of one's own, or
//! [`DirectNewton`] for repeated solves: each solve starts from
//! the last one's kept factorisation or hierarchy and its last σ, so a frame loop that runs a
//! few Newton iterations per frame (`max_newton`) carries the regularisation a flat
//! membrane's first tangent needs from one frame to the next.

mod direction;
mod dofs;
mod driver;
mod kept;
mod linear;
mod matrix_free;
mod pattern;
mod search;
mod shift;
pub use dofs::FreeDofs;
pub use driver::{solve_with, Direction, Forcing, NewtonLinear};
pub use kept::{KeptSolve, TangentProduct};
pub use linear::{TangentSolver, TangentSolves};
pub use matrix_free::{solve_system_matrix_free, MatrixFree, MatrixFreeCg};

use crate::linalg::cg::{pcg, pcg_from, PcgEnd};
use shift::{raise_sigma, shift_needed, sigma_after_full_step};

use crate::fem::{ElementFailure, ForceModel};
use crate::hierarchy::Transfer;
use crate::integrate::{Constraints, Spring, System};
pub use crate::linalg::coarse_factor::Precision;
use crate::linalg::galerkin::{GalerkinError, GalerkinMultigrid, GalerkinSymbolic, Prolongations};
pub use crate::linalg::smoother::Smoother;
use crate::linalg::sparse::{sym_lower_matvec, Csr, SymScatter};
use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{SparseColMat, SymbolicSparseColMat};
use faer::Side;
use std::sync::Arc;

/// The line search's curvature condition: a step accepted by Armijo's rule whose slope
/// `Π'(α)` exceeds `CURVATURE × |Π'(0)|` is past the minimum along δ (module docs).
const CURVATURE: f64 = 0.9;

/// Secant steps back at most per line search (module docs).
const SECANT_STEPS: usize = 2;

/// A kept Galerkin hierarchy whose conjugate gradients converged only after more than
/// `max_iter / STALE_SHARE` iterations is rebuilt before the next Newton iteration (module
/// docs).
const STALE_SHARE: f64 = 1.5;

/// A solve rebuilds a provisional hierarchy (one built where the Newton step was damped) at
/// most this many times (module docs).
pub const PROVISIONAL_REBUILDS: usize = 1;

/// Newton-multigrid's coarse level has at most 1/`COARSEN` of the finest level's nodes where
/// the levels allow ([`coarse_level`]).
pub const COARSEN: usize = 16;

/// A level with fewer than 1/`COARSEN_LIMIT` of the finest level's nodes is not a coarse level
/// of Newton-multigrid ([`coarse_level`]).
pub const COARSEN_LIMIT: usize = 32;

/// Of levels with `nodes[l]` nodes (finest first), the coarse level of a two-level
/// Newton-multigrid: of the levels with at least 1/[`COARSEN_LIMIT`] of the finest level's
/// nodes, the finest with at most 1/[`COARSEN`] of them, else the coarsest. `None` where no
/// level qualifies.
///
/// The coarse level is factored (a sparse Cholesky factorisation of its Galerkin operator,
/// about 130 entries a row on a tetrahedral organ), whose cost grows faster than its size;
/// coarser levels make a weaker coarse correction and conjugate gradients need more
/// iterations. Deeper hierarchies' Galerkin operators grow denser than the fine one, and each
/// level's smoothing costs, so two levels (`bench/RESULTS.md`: the mesher livers with each
/// choice).
pub fn coarse_level(nodes: &[usize]) -> Option<usize> {
    let n0 = *nodes.first()?;
    let eligible = |i: &usize| nodes[*i] * COARSEN_LIMIT >= n0;
    (1..nodes.len())
        .filter(eligible)
        .find(|&i| nodes[i] * COARSEN <= n0)
        .or_else(|| (1..nodes.len()).rev().find(eligible))
}

/// Settings of the direct Newton solver (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DirectNewtonParams {
    /// Relative part of the stopping rule (of the largest nodal external force). Default 1e-10.
    pub rel_tol: f64,
    /// Absolute floor of the stopping rule (N). Default 1e-14.
    pub abs_tol: f64,
    /// Newton iterations at most, all load steps together. Default 200.
    pub max_newton: usize,
    /// Number of load steps N (≥ 1). Default 1.
    pub load_steps: usize,
    /// Smallest nonzero regularisation σ (relative to the mean diagonal). Default 1e-8.
    pub sigma_min: f64,
    /// Reuse of the factorisation: 0 factors at every iteration (plain direct Newton);
    /// m > 0 solves each Newton system by conjugate gradients preconditioned by the last
    /// factorisation, to the inexact-Newton tolerance, and refactors only when m iterations do
    /// not reach it. Default 0.
    pub pcg_max: usize,
    /// Multigrid-preconditioned conjugate gradients instead of a factorisation (module docs),
    /// over the levels of [`DirectNewton::with_levels`]; without coarser levels the fine level
    /// is the coarsest and is factored, so CG converges in one iteration. Default `None`.
    pub multigrid: Option<MultigridPcg>,
    /// Where the largest nodal residual is at most this (N), the line search counts Π as
    /// unable to tell (as within its round-off) and takes a trial whose residual 2-norm falls:
    /// near a solution whose Π is small against its round-off (an implicit time step of a
    /// body barely loaded, [`crate::statics::implicit`]) the changes of Π a Newton step makes
    /// are below it. Default 0 (Π decides wherever it can).
    pub flat_below: f64,
    /// The load factor λ of the solve: the external forces, the loads the model carries and
    /// the prescribed motions' increment are λ of their full values at its end, the load
    /// steps at `λ k / N`; the model is left at λ. Default 1.
    pub load_factor: f64,
    /// Stop after this many consecutive Newton iterations that each lower the residual by
    /// less than a tenth (stagnation: the floor a finite-difference tangent leaves,
    /// [`MatrixFree`]); 0 never. Default 0.
    pub stall_after: usize,
    /// The norm of the stopping rule (and of [`DirectStatic::residual`]): the largest nodal
    /// norm (default) or the 2-norm over the free dofs.
    pub stop_norm: StopNorm,
    /// The inexact-Newton forcing term of a solve's first iteration, and the largest any
    /// iteration takes (Eisenstat and Walker's choice 2 after it): the first linear solve
    /// reduces its residual by this factor. Default 0.5; a time step, whose start is close
    /// and whose tangent the inertia conditions well, asks for less
    /// ([`crate::statics::implicit`]).
    pub first_forcing: f64,
}

impl DirectNewtonParams {
    /// The default settings with the stopping rule relative to the start (for a problem
    /// whose loads the model carries, where the external forces say nothing): the
    /// constraints of `sys` imposed on `u` at time `t`, then the residual's 2-norm at most
    /// `rel_tol` times the larger of the residual's and the external forces' 2-norms there
    /// (`stop_norm` [`StopNorm::Two`], `rel_tol = 0`, `abs_tol` that bound). Errors: an
    /// element `u` inverts.
    pub fn relative_to_start(
        sys: &mut System,
        t: f64,
        u: &mut [f64],
        rel_tol: f64,
    ) -> Result<DirectNewtonParams, ElementFailure> {
        let mut v = vec![0.0; u.len()];
        sys.impose(t, u, &mut v);
        let r0 = sys.residual(u, &mut v)?;
        let load = sys.f_ext.iter().map(|x| x * x).sum::<f64>().sqrt();
        Ok(DirectNewtonParams {
            rel_tol: 0.0,
            abs_tol: rel_tol * r0.max(load),
            stop_norm: StopNorm::Two,
            ..Default::default()
        })
    }
}

/// The norm the stopping rule measures residuals and loads in
/// ([`DirectNewtonParams::stop_norm`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum StopNorm {
    /// `max_a |r_a| ≤ rel_tol max_a |V_a| + abs_tol`, `|·|` a node's Euclidean norm (module
    /// docs).
    #[default]
    LargestNodal,
    /// `‖r‖₂ ≤ rel_tol ‖V‖₂ + abs_tol` over the free dofs.
    Two,
}

/// Settings of the multigrid-preconditioned linear solves ([`DirectNewtonParams::multigrid`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MultigridPcg {
    /// Smoothing sweeps before and after each coarse correction. Default 2.
    pub sweeps: usize,
    /// The smoother. Default [`Smoother::GaussSeidel`].
    pub smoother: Smoother,
    /// Conjugate-gradient iterations at most per Newton system. Default 25.
    pub max_iter: usize,
    /// What a Newton iteration takes from the last hierarchy: all of it (`true`), or only its
    /// coarsest factorisation, the smoothed levels' Galerkin operators being rebuilt from the
    /// current tangent (`false`, the default).
    pub keep: bool,
    /// The precision of the coarse solve ([`crate::linalg::coarse_factor`]). Default
    /// [`Precision::Single`]: the factor computed in `f64`, rounded to `f32`.
    pub coarse_precision: Precision,
}

impl Default for MultigridPcg {
    fn default() -> Self {
        MultigridPcg {
            sweeps: 2,
            smoother: Smoother::default(),
            max_iter: 25,
            keep: false,
            coarse_precision: Precision::Single,
        }
    }
}

impl Default for DirectNewtonParams {
    fn default() -> Self {
        DirectNewtonParams {
            rel_tol: 1e-10,
            abs_tol: 1e-14,
            max_newton: 200,
            load_steps: 1,
            sigma_min: 1e-8,
            pcg_max: 0,
            multigrid: None,
            flat_below: 0.0,
            first_forcing: 0.5,
            stop_norm: StopNorm::LargestNodal,
            stall_after: 0,
            load_factor: 1.0,
        }
    }
}

/// Outcome of a direct Newton solve.
#[derive(Clone, Debug, Default)]
pub struct DirectStatic {
    /// Largest nodal residual over free nodes at the end (N; its 2-norm with
    /// [`StopNorm::Two`]).
    pub residual: f64,
    /// The same at the start, at the full load, with the constrained nodes at their
    /// prescribed values (N); infinite where that state inverts an element (a large prescribed
    /// displacement, which the load steps apply gradually).
    pub initial_residual: f64,
    /// The stopping threshold `rel_tol max|V_a| + abs_tol` (N; `rel_tol ‖V‖₂ + abs_tol` with
    /// [`StopNorm::Two`]).
    pub target: f64,
    /// Newton iterations (tangent assemblies and factorisations, retries not counted).
    pub newton_steps: usize,
    /// Numeric factorisations, retries with a larger σ included.
    pub factorizations: usize,
    /// Internal-force evaluations (residuals and line-search trials).
    pub force_evaluations: u64,
    /// Strain-energy evaluations (the line search's Π).
    pub energy_evaluations: u64,
    /// Lifted iterations: each load step's first, where it moves the constrained dofs
    /// (module docs).
    pub lifted_steps: usize,
    /// Newton iterations (not lifted) whose line search took no step: every trial failed
    /// (u kept, σ raised by 100).
    pub rejected_steps: usize,
    /// Newton iterations (not lifted) whose line search took the full step, α = 1.
    pub full_steps: usize,
    /// Conjugate-gradient iterations ([`DirectNewtonParams::pcg_max`] > 0, or
    /// [`DirectNewtonParams::multigrid`]).
    pub cg_iterations: usize,
    /// Galerkin hierarchies built ([`DirectNewtonParams::multigrid`]), retries with a larger σ
    /// included; each factors the coarsest level.
    pub multigrid_setups: usize,
    /// Of those, the ones built because the kept one was provisional (built where the step
    /// was damped) and a full step followed (module docs); at most [`PROVISIONAL_REBUILDS`].
    pub provisional_rebuilds: usize,
    /// Wall time in assembling tangents (s).
    pub assembly_s: f64,
    /// Wall time in solving the Newton systems, building their preconditioners included
    /// (s).
    pub factor_s: f64,
    /// Of [`DirectStatic::factor_s`], the time in building preconditioners: numeric
    /// factorisations, or Galerkin hierarchies (their products, smoothers and coarse
    /// factors) and their refreshes with a new tangent (s).
    pub setup_s: f64,
    /// Largest nodal residual (2-norm with [`StopNorm::Two`]) after each iteration of the
    /// last load step (N).
    pub history: Vec<f64>,
    /// Whether the stopping rule held at the full load.
    pub converged: bool,
}

/// Errors of the direct solver.
#[derive(Debug, thiserror::Error)]
pub enum DirectNewtonError {
    /// The force model has no element tangent ([`ForceModel::tangent_elements`]).
    #[error("the assembled Newton solver needs a force model with an element tangent (a finite-element model, with or without loads and tools)")]
    NotFem,
    /// A state the solver had to evaluate inverts an element.
    #[error("element {} is inverted or collapsed at a state the solver had to evaluate (det F = {:.3e})", .0.element, .0.det_f)]
    Inverted(ElementFailure),
    /// The sparse factorisation failed even with the largest regularisation.
    #[error("sparse factorisation failed: {0}")]
    Factor(String),
    /// A factor or hierarchy would not fit in the available memory ([`crate::memory`]).
    #[error("{0}")]
    Memory(String),
    /// A sliding constraint along a direction other than x, y or z. No longer returned: such
    /// a node is solved by projection (module `oblique` in the source); kept for one release.
    #[error("node {node} slides along ({:.3}, {:.3}, {:.3}): the direct Newton solver takes fixed components along x, y or z only", .dir[0], .dir[1], .dir[2])]
    SlidingNotAxis {
        /// The node.
        node: u32,
        /// Its sliding direction.
        dir: [f64; 3],
    },
    /// A level transfer does not match its finer level's node count.
    #[error("level transfer {level} locates {got} nodes, but its finer level has {expected}")]
    Levels {
        /// The transfer's index.
        level: usize,
        /// The nodes it locates.
        got: usize,
        /// The finer level's node count.
        expected: usize,
    },
}

/// The assembled tangent's structure over the free dofs, fixed for a mesh and constraint set.
pub struct DirectNewton {
    /// The free dofs and the regularisation's weights ([`FreeDofs`]).
    dofs: FreeDofs,
    /// Per element, per entry of its `(3 npe)²` matrix (row-major): the slot in `vals`, or
    /// `u32::MAX` where not assembled (a constrained dof, or above the diagonal).
    slots: Vec<u32>,
    /// The lower triangle's values in compressed columns (`symbolic`'s order), element
    /// entries summed into them in element order.
    vals: Vec<f64>,
    /// The slot in `vals` of each free dof's diagonal.
    diag: Vec<u32>,
    symbolic: SymbolicSparseColMat<usize>,
    /// The symbolic factorisation of the pattern, made at the first factorisation.
    llt_symbolic: Option<SymbolicLlt<usize>>,
    /// The last numeric factorisation, kept as the conjugate-gradient preconditioner.
    llt: Option<Llt<usize, f64>>,
    /// The interpolations of [`DirectNewton::with_levels`] (empty without), level 0's rows of
    /// masked dofs zeroed ([`DirectNewton::mask`]).
    prolongations: Arc<Prolongations>,
    /// The same, unmasked.
    base_prolongations: Arc<Prolongations>,
    /// Free dofs held at run time ([`DirectNewton::mask`]), by free index; `None`: none.
    masked: Option<Vec<bool>>,
    /// What the Galerkin hierarchies keep from one build to the next (the pattern and the
    /// prolongations are fixed).
    hierarchy_symbolic: GalerkinSymbolic,
    /// The last Galerkin hierarchy, kept as the conjugate-gradient preconditioner.
    mg: Option<GalerkinMultigrid>,
    /// Whether the kept hierarchy is provisional (module docs).
    standing: Standing,
    /// Where the lower triangle's values land in the full rows of the hierarchy's finest
    /// operator, made at the first multigrid-preconditioned solve.
    scatter: Option<SymScatter>,
    /// The regularisation σ the last solve ended with, the next one's start.
    sigma: f64,
}

impl DirectNewton {
    /// The pattern of K over the free dofs of `model` under `constraints`, the regularisation
    /// weighted by the lumped `mass` (kg per node).
    pub fn new(
        model: &dyn ForceModel,
        mass: &[f64],
        constraints: &Constraints,
    ) -> Result<Self, DirectNewtonError> {
        let topology = model.tangent_elements().ok_or(DirectNewtonError::NotFem)?;
        let dofs = FreeDofs::new(topology.nodes, mass, constraints);
        let nfree = dofs.nfree;
        // The pattern and the element entries' places in it (`pattern.rs`).
        let pattern::Pattern {
            col_ptr,
            row_idx,
            slots,
            diag,
        } = pattern::build(&topology, &dofs.free, nfree).map_err(DirectNewtonError::Memory)?;
        let nnz = row_idx.len();
        let symbolic = SymbolicSparseColMat::new_checked(nfree, nfree, col_ptr, None, row_idx);
        Ok(DirectNewton {
            dofs,
            slots,
            vals: vec![0.0; nnz],
            diag,
            symbolic,
            llt_symbolic: None,
            llt: None,
            prolongations: Arc::new(Prolongations::default()),
            base_prolongations: Arc::new(Prolongations::default()),
            masked: None,
            hierarchy_symbolic: GalerkinSymbolic::default(),
            standing: Standing::Settled,
            mg: None,
            scatter: None,
            sigma: 0.0,
        })
    }

    /// The pattern, and the interpolations for [`DirectNewtonParams::multigrid`]: `down[l]`
    /// locates level l's nodes in level l + 1's mesh (level 0 is `model`'s mesh), as
    /// [`crate::hierarchy::Correspondence::down`] does.
    pub fn with_levels(
        model: &dyn ForceModel,
        mass: &[f64],
        constraints: &Constraints,
        down: &[Transfer],
    ) -> Result<Self, DirectNewtonError> {
        let mut s = Self::new(model, mass, constraints)?;
        let mut expected = model.num_nodes();
        for (level, t) in down.iter().enumerate() {
            if t.len() != expected {
                return Err(DirectNewtonError::Levels {
                    level,
                    got: t.len(),
                    expected,
                });
            }
            expected = t.target_nodes;
        }
        let free_dofs: Vec<usize> = (0..s.dofs.free.len())
            .filter(|&i| s.dofs.free[i] != usize::MAX)
            .collect();
        s.prolongations = Arc::new(Prolongations::new(down, &free_dofs));
        s.base_prolongations = s.prolongations.clone();
        Ok(s)
    }

    /// Assemble K(u) into the pattern's values (diagonal shifts zero); returns the mean
    /// diagonal over free dofs. Element matrices are computed in parallel, a block at a time,
    /// and summed into the pattern in element order, tasks over disjoint ranges of it (the same
    /// bits on any thread count).
    ///
    /// With `lift = (Δ, out)`, `Δ` an increment of the constrained dofs (all dofs' layout, zero
    /// on free ones), also `out[f] = −Σ K_fc Δ_c` over free rows f and constrained columns c,
    /// summed in element order: the load that moving the constrained dofs by `Δ` puts on the
    /// free ones, to first order.
    fn assemble(
        &mut self,
        model: &dyn ForceModel,
        springs: &[Spring],
        u: &[f64],
        mut lift: Option<(&[f64], &mut [f64])>,
    ) -> Result<f64, ElementFailure> {
        use rayon::prelude::*;
        if let Some((_, out)) = lift.as_mut() {
            out.iter_mut().for_each(|v| *v = 0.0);
        }
        const BLOCK: usize = 4096;
        self.vals.iter_mut().for_each(|v| *v = 0.0);
        let Some(topology) = model.tangent_elements() else {
            return Ok(0.0);
        };
        let npe = topology.nodes_per_element;
        let d = 3 * npe;
        let ne = topology.len();
        let mut k = vec![0.0; BLOCK.min(ne) * d * d];
        let mut diag = 0.0;
        for first in (0..ne).step_by(BLOCK) {
            let count = BLOCK.min(ne - first);
            let ok: Result<(), ElementFailure> = k[..count * d * d]
                .par_chunks_mut(d * d)
                .enumerate()
                .try_for_each(|(j, out)| {
                    model.element_tangent(first + j, u, out)?;
                    if self.dofs.has_oblique() {
                        self.dofs.project_block(topology.element(first + j), out);
                    }
                    Ok(())
                });
            if ok.is_err() {
                // Report the lowest failing element, whatever the scheduling.
                for (j, out) in k[..count * d * d].chunks_mut(d * d).enumerate() {
                    model.element_tangent(first + j, u, out)?;
                }
            }
            // Each task sums into its own range of the pattern's values, visiting the
            // elements in order: every value gets its terms in element order, whatever the
            // number of tasks.
            let slots = &self.slots[first * d * d..(first + count) * d * d];
            let kb = &k[..count * d * d];
            let tasks = rayon::current_num_threads().max(1);
            let len = self.vals.len().div_ceil(tasks).max(1);
            self.vals
                .par_chunks_mut(len)
                .enumerate()
                .for_each(|(t, part)| {
                    let lo = (t * len) as u32;
                    for (&slot, &v) in slots.iter().zip(kb) {
                        let at = slot.wrapping_sub(lo) as usize;
                        if at < part.len() {
                            part[at] += v;
                        }
                    }
                });
            for j in 0..count {
                let e = first + j;
                let s = &self.slots[e * d * d..(e + 1) * d * d];
                let ke = &k[j * d * d..(j + 1) * d * d];
                for q in (0..d).map(|i| i * d + i) {
                    if s[q] != u32::MAX {
                        diag += ke[q].abs();
                    }
                }
                if let Some((delta, out)) = lift.as_mut() {
                    let el = topology.element(e);
                    let dof = |q: usize| 3 * el[q / 3] as usize + q % 3;
                    for c in (0..d).filter(|&c| delta[dof(c)] != 0.0) {
                        for r in 0..d {
                            let f = self.dofs.free[dof(r)];
                            if f != usize::MAX {
                                out[f] -= ke[r * d + c] * delta[dof(c)];
                            }
                        }
                    }
                }
            }
        }
        // The blocks beyond the elements (a follower pressure's, a tool's) and the springs'
        // `k I`, summed after the elements in the order the model hands them over.
        let mut projected = Vec::new();
        let mut extra = |nodes: &[u32], block: &[f64]| {
            let d = 3 * nodes.len();
            let block = if self.dofs.has_oblique() {
                projected.clear();
                projected.extend_from_slice(block);
                self.dofs.project_block(nodes, &mut projected);
                &projected[..]
            } else {
                block
            };
            let dof = |q: usize| 3 * nodes[q / 3] as usize + q % 3;
            for r in 0..d {
                let fr = self.dofs.free[dof(r)];
                for c in 0..d {
                    let v = block[r * d + c];
                    if v == 0.0 {
                        continue;
                    }
                    let fc = self.dofs.free[dof(c)];
                    if fr == usize::MAX {
                        continue;
                    }
                    if fc == usize::MAX {
                        if let Some((delta, out)) = lift.as_mut() {
                            out[fr] -= v * delta[dof(c)];
                        }
                        continue;
                    }
                    if fr < fc {
                        continue;
                    }
                    if let Some(slot) = slot_of(&self.symbolic, fr, fc) {
                        self.vals[slot] += v;
                        if fr == fc {
                            diag += v.abs();
                        }
                    }
                }
            }
        };
        model.add_extra_tangent(u, &mut extra);
        for sp in springs.iter().filter(|sp| sp.k > 0.0) {
            extra(&[sp.node], &sp.tangent(u));
        }
        let mean = diag / self.dofs.nfree.max(1) as f64;
        self.add_normal_stiffness(mean);
        Ok(mean)
    }

    /// `K + σ d̄ D` (values as assembled), lower triangle in compressed columns.
    fn matrix(&self, shift: f64) -> Result<SparseColMat<usize, f64>, String> {
        let mut vals = self.vals.clone();
        for (&d, w) in self.diag.iter().zip(&self.dofs.weight) {
            vals[d as usize] += shift * w;
        }
        Ok(SparseColMat::new(self.symbolic.clone(), vals))
    }

    /// The symbolic factorisation, made once, after checking that the factor fits in the
    /// available memory ([`crate::memory`]).
    fn prepare_factor(&mut self) -> Result<(), DirectNewtonError> {
        if self.llt_symbolic.is_some() {
            return Ok(());
        }
        let factor = |e| DirectNewtonError::Factor(format!("{e:?}"));
        let counted = faer::sparse::linalg::cholesky::factorize_symbolic_cholesky(
            self.symbolic.as_ref(),
            Side::Lower,
            Default::default(),
            Default::default(),
        )
        .map_err(factor)?;
        // The factor's values, and as much again for the numeric factorisation's workspace.
        let bytes = 16 * counted.len_val() as u64;
        crate::memory::check(
            &format!(
                "the sparse Cholesky factor of {} dofs ({} nonzeros)",
                self.dofs.nfree,
                counted.len_val()
            ),
            bytes,
        )
        .map_err(DirectNewtonError::Memory)?;
        drop(counted);
        self.llt_symbolic =
            Some(SymbolicLlt::try_new(self.symbolic.as_ref(), Side::Lower).map_err(factor)?);
        Ok(())
    }

    /// Factor `K + σ d̄ D`, keep the factor, and solve for `rhs` in place.
    fn factor_solve(&mut self, shift: f64, rhs: &mut [f64]) -> Result<(), String> {
        self.llt = None;
        let mat = self.matrix(shift)?;
        let symbolic = self
            .llt_symbolic
            .clone()
            .expect("prepare_factor before the first factorisation");
        let llt = Llt::try_new_with_symbolic(symbolic, mat.as_ref(), Side::Lower)
            .map_err(|e| format!("{e:?}"))?;
        self.llt = Some(llt);
        self.apply_factor(rhs);
        if rhs.iter().all(|x| x.is_finite()) {
            Ok(())
        } else {
            self.llt = None;
            Err("the solution is not finite".into())
        }
    }

    /// `rhs ← (L Lᵀ)⁻¹ rhs` with the kept factor.
    fn apply_factor(&self, rhs: &mut [f64]) {
        let llt = self.llt.as_ref().expect("a kept factorisation");
        let mut b = faer::Mat::<f64>::from_fn(self.dofs.nfree, 1, |i, _| rhs[i]);
        llt.solve_in_place(b.as_mut());
        for (i, r) in rhs.iter_mut().enumerate() {
            *r = b[(i, 0)];
        }
    }

    /// Solve `R(u) = V` for `u` in place: `u`'s constrained dofs are driven to the values
    /// `constraints` impose at time `t` (over the load steps), the free ones start from `u`;
    /// the regularisation σ starts where the last solve left it (module docs). The one
    /// Newton driver ([`solve_with`]) over this assembled tangent.
    #[allow(clippy::too_many_arguments)]
    pub fn solve(
        &mut self,
        model: &mut dyn ForceModel,
        springs: &[Spring],
        constraints: &Constraints,
        f_ext: &[f64],
        t: f64,
        u: &mut [f64],
        params: DirectNewtonParams,
    ) -> Result<DirectStatic, DirectNewtonError> {
        solve_with(self, model, springs, constraints, f_ext, t, u, params)
    }
}

/// Where the kept hierarchy stands with respect to the provisional rule (module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
enum Standing {
    /// Built where the Newton step was full, or already rebuilt once this solve.
    #[default]
    Settled,
    /// Built at an iteration whose step was damped.
    Damped,
    /// Damped, and a full step has followed: rebuilt at the next Newton iteration.
    Rebuild,
}

impl DirectNewton {
    /// After a Newton step: a hierarchy built at this iteration whose step was damped
    /// (`full` false: α < 1, or no step) is provisional; a provisional one kept from an
    /// earlier iteration is rebuilt after a full step (at most [`PROVISIONAL_REBUILDS`] times
    /// a solve, `done` so far), so the next iteration builds one at a state inside Newton's
    /// region of full steps (module docs).
    fn mark_provisional(&mut self, built_now: bool, full: bool, done: usize) {
        self.standing = match (built_now, full, self.standing) {
            (true, true, _) => Standing::Settled,
            (true, false, _) => Standing::Damped,
            (false, true, Standing::Damped) if done < PROVISIONAL_REBUILDS => Standing::Rebuild,
            (false, true, Standing::Damped) => Standing::Settled,
            (false, _, standing) => standing,
        };
    }
}

/// `Π(u) = E(u) + Σ ½ k |u_a − d|² − s V·u` (J, the springs' energy included); +∞ where an
/// element is inverted or the energy is not finite ([`ForceModel::admissible_energy`]).
fn potential(model: &dyn ForceModel, springs: &[Spring], u: &[f64], s: f64, f_ext: &[f64]) -> f64 {
    let e = model.admissible_energy(u);
    let w: f64 = f_ext.iter().zip(u).map(|(f, x)| f * x).sum();
    if e.is_finite() {
        e + spring_energy(springs, u) - s * w
    } else {
        f64::INFINITY
    }
}

/// `fint += f_s(u)` for every spring ([`Spring::force`]: `k (u_a − d)` while it sticks).
fn add_springs(springs: &[Spring], u: &[f64], fint: &mut [f64]) {
    for sp in springs {
        let i = 3 * sp.node as usize;
        let f = sp.force(u);
        for k in 0..3 {
            fint[i + k] += f[k];
        }
    }
}

/// `Σ ½ k |u_a − d|²` (J), a sliding spring's [`Spring::energy`].
fn spring_energy(springs: &[Spring], u: &[f64]) -> f64 {
    springs
        .iter()
        .map(|sp| {
            if sp.limit.is_finite() {
                return sp.energy(u);
            }
            let i = 3 * sp.node as usize;
            (0..3)
                .map(|k| 0.5 * sp.k * (u[i + k] - sp.d[k]).powi(2))
                .sum::<f64>()
        })
        .sum()
}

/// The place of entry `(i, j)`, `i ≥ j`, in the lower triangle's values of `pattern`; `None`
/// where the pattern has no such entry (nodes that share no element).
fn slot_of(pattern: &SymbolicSparseColMat<usize>, i: usize, j: usize) -> Option<usize> {
    let (cp, ri) = (pattern.col_ptr(), pattern.row_idx());
    let col = &ri[cp[j]..cp[j + 1]];
    col.binary_search(&i).ok().map(|k| cp[j] + k)
}

/// Whether dof `i` (3 per node) holds an imposed value. The one place that reads the
/// constraints per dof.
pub fn fixed_dof(constraints: &Constraints, i: usize) -> bool {
    let a = i / 3;
    if constraints.is_constrained(a) {
        return true;
    }
    let sliding = constraints.sliding();
    let start = sliding.partition_point(|&(n, _)| (n as usize) < a);
    sliding[start..]
        .iter()
        .take_while(|&&(n, _)| n as usize == a)
        .any(|&(_, dir)| axis_of(dir) == Some(i % 3))
}

/// The axis (0, 1, 2) a unit direction lies along, if it is ±e_x, ±e_y or ±e_z.
pub(crate) fn axis_of(dir: [f64; 3]) -> Option<usize> {
    (0..3).find(|&k| {
        (dir[k].abs() - 1.0).abs() < 1e-12 && dir.iter().map(|c| c * c).sum::<f64>() <= 1.0 + 1e-12
    })
}

/// Euclidean norm of node a's 3-vector in `x`.
fn node_norm(x: &[f64], a: usize) -> f64 {
    (x[3 * a] * x[3 * a] + x[3 * a + 1] * x[3 * a + 1] + x[3 * a + 2] * x[3 * a + 2]).sqrt()
}

/// Solve `R(u) = V` on a [`System`] (its external forces `f_ext`, springs and constraints at
/// time `t`) whose force model has an element tangent ([`ForceModel::tangent_elements`]);
/// `u` is the start and receives the equilibrium.
pub fn solve_system(
    sys: &mut System,
    t: f64,
    u: &mut [f64],
    params: DirectNewtonParams,
) -> Result<DirectStatic, DirectNewtonError> {
    let mut solver = DirectNewton::new(&*sys.force, &sys.mass, &sys.constraints)?;
    let System {
        force,
        f_ext,
        constraints,
        springs,
        ..
    } = sys;
    solver.solve(&mut **force, springs, constraints, f_ext, t, u, params)
}

#[cfg(test)]
mod tests;
