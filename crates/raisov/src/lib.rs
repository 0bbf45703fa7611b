//! # raisov
//!
//! Interactive soft-tissue simulation: total-Lagrangian nonlinear hyperelastic finite elements
//! (3-node membranes in 3-D, 4-node tetrahedra) with lumped mass and mass-proportional damping,
//! advanced by explicit integrators, on one mesh or on a hierarchy of independent meshes with
//! the multigrid integrator RaISoV of Wu & Tendick (2004) and a convergent full-approximation
//! multigrid built from the same ingredients.
//!
//! The equation of motion everywhere (paper, eq. 5):
//!
//! ```text
//! M ü + D u̇ + R(u) = V(t),   D = α M,
//! ```
//!
//! `u` nodal displacements (m), `M` lumped mass (kg), `R(u)` internal (elastic) forces (N),
//! `V` external forces (N). Integrators see only [`fem::ForceModel`].
//!
//! Running a scenario (a TOML file, see [`scenario::spec`]) from Rust:
//!
//! ```no_run
//! use raisov::runner::{run, RunOptions};
//! use raisov::scenario::Scenario;
//!
//! let sc = Scenario::load(std::path::Path::new("examples/cantilever.toml"))?;
//! let summary = run(&sc, RunOptions::default())?;
//! println!("{summary}");
//! # Ok::<(), raisov::Error>(())
//! ```
//!
//! Layout, in data-flow order (`ARCHITECTURE.md` has the map): [`io`] (readers and writers),
//! [`mesh`] (meshes, generators, surfaces, the tetrahedral mesher), [`material`] (strain-energy
//! functions, one per file), [`fem`] (elements, the force model, nodal stress; the packed
//! kernels in [`fem::packed`], time functions and surface loads in [`fem::loads`]), [`contact`]
//! (rigid tools in penalty contact), [`integrate`] (explicit integrators, constraints, statics,
//! stability), [`hierarchy`] (levels, host elements, weights), [`multigrid`] (RaISoV and the
//! FAS multigrid), [`metrics`], [`scenario`] (TOML scenes, typed once), [`sim`] (the frame-loop API for a
//! host program: grasps, pins, tool forces), [`runner`] (a scenario run to its end: in time,
//! static, or interactive through a `sim::Simulation`).
//!
//! What advances a simulation is named by one enum, [`Scheme`] (its kinds [`SchemeKind`]):
//! a scenario resolves to one ([`scenario::Scenario::scheme`]), and
//! [`sim::SimulationBuilder::scheme`] takes one.

// `!(x > 0.0)` is written on purpose throughout: unlike `x <= 0.0` it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
// Index loops over x, y, z components read like the equations they implement.
#![allow(clippy::needless_range_loop)]
#![warn(missing_docs)]

pub mod contact;
pub mod error;
pub mod fem;
pub mod geometry;
pub mod hierarchy;
pub mod integrate;
pub mod io;
pub mod linalg;
pub mod material;
pub mod memory;
pub mod mesh;
pub mod metrics;
pub mod model;
pub mod multigrid;
pub mod numbers;
pub mod runner;
pub mod scenario;
pub mod sim;
pub mod statics;
pub mod time;

pub use error::{Error, Result};
pub use model::{Model, Scheme, SchemeKind};
