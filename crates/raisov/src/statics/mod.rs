//! Static equilibrium `R(u) = V`: the Newton solvers and the relaxation baselines.
//!
//! - [`newton`]: the one Newton driver ([`newton::solve_with`]: load increments, the lifted
//!   first iteration of a prescribed motion, the line search, the regularisation and the
//!   stopping rule `max_a |r_a| ≤ rel_tol max_a |V_a| + abs_tol`) over a linear-solve trait
//!   ([`newton::NewtonLinear`]) and its implementations: the consistent analytic tangent
//!   assembled on a fixed pattern ([`newton::DirectNewton`]: sparse Cholesky, conjugate
//!   gradients preconditioned with a kept factorisation, or with a Galerkin V-cycle over the
//!   levels: Newton-multigrid) and matrix-free conjugate gradients ([`newton::MatrixFree`]:
//!   tangent products by differences of the forces, any force model);
//! - [`nested`]: the coarse start, a coarser level's equilibrium interpolated as the fine
//!   start, through levels about four times apart;
//! - [`krylov`]: Newton-Krylov on a system, the driver over matrix-free CG with a stopping
//!   rule relative to the start (reference solves, tests);
//! - [`implicit`]: backward Euler time stepping, each step the [`newton`] solve of an
//!   incremental potential (the static problem plus one inertia spring per node);
//! - [`relax`]: single-level relaxations (dynamic, adaptive dynamic, Chebyshev), the
//!   baselines and the T∞ references.
//!
//! The linear algebra they share (conjugate gradients, the Galerkin hierarchy, smoothers,
//! coarse factor) is in [`crate::linalg`].

pub mod frames;
pub mod implicit;
pub mod krylov;
pub mod nested;
pub mod newton;
pub mod relax;

/// How each Newton system of a static solve (and of a backward-Euler or BDF2 step) is solved:
/// `[integrator] solver` of a scenario.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StaticSolver {
    /// `"multigrid"` where the model has a coarser level with at least 1/32 of the finest
    /// level's nodes, else `"direct"`; `"krylov"` only where the force model has no element
    /// tangent.
    Auto,
    /// The assembled analytic tangent, conjugate gradients preconditioned by a Galerkin
    /// V-cycle over the finest level and that coarser one ([`newton::MultigridPcg`]).
    Multigrid,
    /// The assembled analytic tangent, sparse Cholesky, the factor reused as the
    /// preconditioner of conjugate gradients ([`newton`]).
    Direct,
    /// Matrix-free Newton-Krylov: finite-difference tangent products, conjugate gradients
    /// ([`newton::MatrixFree`]); covers every force.
    Krylov,
}

impl StaticSolver {
    /// Every solver, in the order messages list them.
    pub const ALL: [StaticSolver; 4] = [
        StaticSolver::Auto,
        StaticSolver::Multigrid,
        StaticSolver::Direct,
        StaticSolver::Krylov,
    ];

    /// The scenario's spelling: `"auto"`, `"multigrid"`, `"direct"`, `"krylov"`.
    pub fn name(self) -> &'static str {
        match self {
            StaticSolver::Auto => "auto",
            StaticSolver::Multigrid => "multigrid",
            StaticSolver::Direct => "direct",
            StaticSolver::Krylov => "krylov",
        }
    }
}
