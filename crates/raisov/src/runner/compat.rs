//! The runners' functions at the paths they had before [`crate::runner`] (0.1:
//! `scenario::{run, run_with, run_static, run_static_keeping, describe_static}`,
//! `scenario::interactive::{run_interactive, run_frames, read_frames_csv}`,
//! `sim::{solve, solve_with}`, `sim::replay::run_interactive`), deprecated, for one release.
//! Each calls its new path.

#![allow(deprecated)]

use super::{InteractiveSummary, RunOptions, RunSummary, Solution, StaticSummary};
use crate::error::Result;
use crate::integrate::{Checkpoint, Stepper};
use crate::scenario::Scenario;
use std::path::Path;

/// [`crate::runner::run`].
#[deprecated(since = "0.2.0", note = "use `raisov::runner::run`")]
pub fn run(sc: &Scenario, opts: RunOptions) -> Result<RunSummary> {
    super::run(sc, opts)
}

/// [`crate::runner::run_with`].
#[deprecated(since = "0.2.0", note = "use `raisov::runner::run_with`")]
pub fn run_with(sc: &Scenario, stepper: &mut dyn Stepper, opts: RunOptions) -> Result<RunSummary> {
    super::run_with(sc, stepper, opts)
}

/// [`crate::runner::run_static`].
#[deprecated(since = "0.2.0", note = "use `raisov::runner::run_static`")]
pub fn run_static(sc: &Scenario, opts: RunOptions) -> Result<StaticSummary> {
    super::run_static(sc, opts)
}

/// [`crate::runner::run_static_keeping`].
#[deprecated(since = "0.2.0", note = "use `raisov::runner::run_static_keeping`")]
pub fn run_static_keeping(
    sc: &Scenario,
    opts: RunOptions,
) -> Result<(StaticSummary, crate::integrate::SingleLevel)> {
    super::run_static_keeping(sc, opts)
}

/// [`crate::runner::describe_static`].
#[deprecated(since = "0.2.0", note = "use `raisov::runner::describe_static`")]
pub fn describe_static(sc: &Scenario) -> Result<String> {
    super::describe_static(sc)
}

/// [`crate::runner::run_interactive`] with a borrowed stepper: the frames are stepped by a
/// stepper built from the scenario ([`Scenario::stepper`]) that starts from `stepper`'s state
/// ([`Stepper::save`], [`Stepper::restore`]) and hands its final state back to it, the
/// prescribed displacements held at the last frame's values. `stepper` must be the
/// scenario's; its count of force evaluations is not advanced.
#[deprecated(
    since = "0.2.0",
    note = "use `raisov::runner::run_interactive`, which takes the stepper by value"
)]
pub fn run_interactive(
    sc: &Scenario,
    stepper: &mut dyn Stepper,
    opts: RunOptions,
) -> Result<InteractiveSummary> {
    let mut own = sc.stepper()?;
    let mut cp = Checkpoint::default();
    stepper.save(&mut cp);
    own.restore(&cp);
    let mut replay = super::Replay::new(sc, own)?;
    let summary = super::run_frames(sc, &mut replay, opts)?;
    let own = super::FrameStepper::stepper(&mut replay);
    own.save(&mut cp);
    stepper.restore(&cp);
    if let Some(last) = &summary.last {
        let values: Vec<[f64; 3]> = sc
            .prescribed
            .iter()
            .map(|(_, m)| m.displacement(last.time))
            .collect();
        stepper.hold_prescribed(&values);
    }
    Ok(summary)
}

/// [`crate::runner::run_frames`].
#[deprecated(since = "0.2.0", note = "use `raisov::runner::run_frames`")]
pub fn run_frames(
    sc: &Scenario,
    frames: &mut dyn super::FrameStepper,
    opts: RunOptions,
) -> Result<InteractiveSummary> {
    super::run_frames(sc, frames, opts)
}

/// [`crate::runner::read_frames_csv`].
#[deprecated(since = "0.2.0", note = "use `raisov::runner::read_frames_csv`")]
pub fn read_frames_csv(path: &Path) -> Result<Vec<super::FrameRow>> {
    super::read_frames_csv(path)
}

/// [`crate::runner::run_interactive`] (it was `sim::replay::run_interactive`).
#[deprecated(since = "0.2.0", note = "use `raisov::runner::run_interactive`")]
pub fn replay_run_interactive(
    sc: &Scenario,
    stepper: Box<dyn Stepper>,
    opts: RunOptions,
) -> Result<InteractiveSummary> {
    super::run_interactive(sc, stepper, opts)
}

/// [`crate::runner::solve`].
#[deprecated(since = "0.2.0", note = "use `raisov::runner::solve`")]
pub fn solve(sc: &Scenario, opts: RunOptions) -> Result<Solution> {
    super::solve(sc, opts)
}

/// [`crate::runner::solve_with`].
#[deprecated(since = "0.2.0", note = "use `raisov::runner::solve_with`")]
pub fn solve_with(sc: &Scenario, stepper: Box<dyn Stepper>, opts: RunOptions) -> Result<Solution> {
    super::solve_with(sc, stepper, opts)
}
