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

/// [`crate::runner::solve()`].
#[deprecated(since = "0.2.0", note = "use `raisov::runner::solve`")]
pub fn solve(sc: &Scenario, opts: RunOptions) -> Result<Solution> {
    super::solve(sc, opts)
}

/// [`crate::runner::solve_with`].
#[deprecated(since = "0.2.0", note = "use `raisov::runner::solve_with`")]
pub fn solve_with(sc: &Scenario, stepper: Box<dyn Stepper>, opts: RunOptions) -> Result<Solution> {
    super::solve_with(sc, stepper, opts)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The old `scenario::interactive::run_interactive` (a borrowed stepper) plays the same
    /// frames as [`crate::runner::run_interactive`] and leaves the run's final state in the
    /// stepper it was given.
    #[test]
    fn the_borrowing_run_interactive_plays_the_same_frames_and_hands_the_state_back() {
        let text = r#"
[mesh]
generate = "rectangle"
size = [0.1, 0.1]
nodes = 60
[material]
law = "mooney-rivlin"
c1 = 1000.0
c2 = 1000.0
[[fix]]
boundary = true
[[displace]]
point = [0.0, 0.0, 0.0]
mode = "table"
table = [[0.0, 0.0, 0.0, 0.0], [0.2, 0.0, 0.0, 0.01]]
[multigrid]
scheme = "fas"
levels = 2
[run]
duration = 0.2
[interactive]
cycles = 2
"#;
        let sc = Scenario::from_toml(text, Path::new("compat.toml")).unwrap();
        let mem = || RunOptions {
            in_memory: true,
            ..Default::default()
        };
        let mut replay = super::super::Replay::new(&sc, sc.stepper().unwrap()).unwrap();
        let new = super::super::run_frames(&sc, &mut replay, mem()).unwrap();
        let mut st = sc.stepper().unwrap();
        let old = run_interactive(&sc, st.as_mut(), mem()).unwrap();
        assert_eq!(new.frames, 6);
        assert_eq!(new.last.map(|r| r.lag_max), old.last.map(|r| r.lag_max));
        assert_eq!(
            &st.state().u,
            &super::super::FrameStepper::stepper(&mut replay).state().u
        );
        assert!(st.state().u.iter().any(|&x| x != 0.0));
    }
}
