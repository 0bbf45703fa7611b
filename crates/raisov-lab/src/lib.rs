//! # raisov-lab
//!
//! The experiments run around the [`raisov`] library, kept out of it: they use only its
//! public API.
//!
//! - [`paper`]: `raisov paper`, the experiments of Wu & Tendick (2004) reproduced, with CSV
//!   series, PNG and SVG plots and a Markdown report that sets each claim beside what was
//!   measured;
//! - [`mod@bench`]: `raisov bench`, the performance benchmark of the standard explicit-dynamics
//!   work and its roofline;
//! - [`equilibrium`]: `raisov bench equilibrium`, time to static equilibrium of direct Newton,
//!   FAS multigrid, adaptive dynamic relaxation, single-level Chebyshev and Newton-multigrid on
//!   the same problems and stopping rule;
//! - [`plot`]: the line charts (plotters, with an embedded font: no system font library).

// `!(x > 0.0)` is written on purpose throughout: unlike `x <= 0.0` it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
// Index loops over x, y, z components read like the equations they implement.
#![allow(clippy::needless_range_loop)]

pub mod bench;
pub mod equilibrium;
pub mod paper;
pub mod plot;
