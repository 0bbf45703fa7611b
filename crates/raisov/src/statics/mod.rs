//! Static equilibrium `R(u) = V`: the Newton solvers and the relaxation baselines.
//!
//! - [`newton`]: Newton's method with the consistent analytic tangent assembled on a fixed
//!   pattern, its systems solved by a sparse Cholesky factorisation, by conjugate gradients
//!   preconditioned with a kept factorisation, or by conjugate gradients preconditioned with a
//!   Galerkin V-cycle over the levels (Newton-multigrid); load increments, the lifted first
//!   iteration of a prescribed motion, the line search, the regularisation and the stopping
//!   rule (`max_a |r_a| ≤ rel_tol max_a |V_a| + abs_tol`);
//! - [`nested`]: the coarse start, a coarser level's equilibrium interpolated as the fine
//!   start, through levels about four times apart;
//! - [`krylov`]: matrix-free Newton-Krylov, tangent products by differences of the force
//!   model, for force models whose tangent is not assembled;
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
