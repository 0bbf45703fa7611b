//! Linear algebra under the solvers: sparse matrices ([`sparse`]), conjugate gradients
//! ([`cg`]), spectral estimates ([`spectrum`]: the power iteration and Lanczos), and the
//! algebraic multigrid of an assembled symmetric matrix over the levels' host weights
//! ([`galerkin`]: Galerkin coarse operators `Pᵀ A P`, [`smoother`]s, the coarsest level's
//! factorisation [`coarse_factor`]).
//!
//! Nothing here knows about meshes, materials or constraints beyond what a matrix and a
//! transfer between levels carry; [`crate::statics`] and [`crate::sim`] build the matrices
//! and call these.

pub mod cg;
pub mod coarse_factor;
pub mod galerkin;
pub mod smoother;
pub mod sparse;
pub mod spectrum;

pub use cg::{pcg, pcg_from, PcgEnd};
pub use sparse::{sym_lower_matvec, Csr, SymScatter};
