//! The runners: a resolved [`Scenario`](crate::scenario::Scenario) run to its end, its
//! measures, frames and summary written (or kept in memory, [`RunOptions::in_memory`]).
//!
//! What runs is what the scenario says ([`solve()`], as `raisov run` and Python's
//! `raisov.solve`):
//!
//! - a run in time ([`dynamic`]: [`run`], [`run_with`]): the stepper advanced until the stop
//!   rule holds, `measures.csv`, the VTU frames, `nodal_stress.csv` and the summary;
//! - a static solve, `method = "newton"` ([`statics`]: [`run_static`],
//!   [`run_static_keeping`]; [`describe_static`] says what it would run);
//! - an interactive run, `[interactive]` ([`frames`], [`replay`]: [`run_interactive`],
//!   [`run_frames`]):
//!   frames of path time with a budget each, every frame stepped through a
//!   [`Simulation`](crate::sim::Simulation) ([`replay`]: [`Replay`], with the grasps, pins
//!   and cuts the scenario takes during the run), the lag to the static solution per frame,
//!   `frames.csv` and the summary.
//!
//! Every run locks its output directory and clears the previous run's results first
//! (`runner/outputs.rs`). The runners sit above [`crate::sim`] (they drive a `Simulation`) and
//! [`crate::scenario`] (the schema and its resolution); neither imports them.

pub mod dynamic;
pub mod frames;
mod outputs;
pub mod replay;
pub mod solve;
pub mod statics;

#[doc(hidden)]
pub mod compat;

pub use dynamic::{run, run_with, Progress, RunOptions, RunSummary, StopReason};
pub use frames::{
    read_frames_csv, run_frames, FrameRow, FrameStepper, InteractiveSummary, FRAMES_HEADER,
};
pub use replay::{run_interactive, Replay};
pub use solve::{solve, solve_with, Finished, Solution};
pub use statics::{describe_static, run_static, run_static_keeping, StaticSummary};
