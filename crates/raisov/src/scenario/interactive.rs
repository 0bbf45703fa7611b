//! The `[interactive]` section, resolved: frames per second of path time, the work per frame
//! ([`Budget`]), the static reference's settings and the frame predictor ([`Interactive`]).
//! The frames themselves are run by [`crate::runner::frames`] (the lag, `frames.csv`, the
//! summary), each stepped through a [`crate::sim::Simulation`] ([`crate::runner::replay`]).

use super::spec::{defaults, InteractiveSpec, StaticReference};
use super::{err, positive};
use crate::error::Result;
use std::path::Path;

/// Work per frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Budget {
    /// This many steps (single level) or V-cycles (multigrid) per frame.
    Cycles(usize),
    /// As many as fit in this wall time (s) per frame, at least one; fewer once the stepper
    /// has settled at the frame's equilibrium ([`crate::integrate::Stepper::settled`]).
    Wall(f64),
}

/// The resolved `[interactive]` section.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interactive {
    /// Frames per second of path time. Default 30.
    pub fps: f64,
    /// Default 4 cycles.
    pub budget: Budget,
    /// Solve for the static solution of each frame (default true).
    pub reference: bool,
    /// The reference solve's residual relative to the frame's force scale (module docs).
    /// Default 1e-8.
    pub reference_tol: f64,
    /// The largest relative lag (`lag_max / max|u*|`) under which a run that is fast enough
    /// keeps up with real time. Default 0.05.
    pub lag_tol: f64,
    /// Frames with grasps start from the extrapolated last change
    /// ([`crate::sim::Simulation::set_predictor`]). Default true.
    pub predictor: bool,
}

impl Interactive {
    pub(crate) fn from_spec(path: &Path, s: &InteractiveSpec) -> Result<Interactive> {
        let fps = positive(path, "interactive.fps", s.fps.unwrap_or(defaults::FPS))?;
        let budget = match (s.cycles, s.budget_ms) {
            (Some(_), Some(_)) => {
                return Err(err(
                    path,
                    "[interactive]: give either `cycles` or `budget_ms`, not both",
                ))
            }
            (_, Some(ms)) => Budget::Wall(positive(path, "interactive.budget_ms", ms)? * 1e-3),
            (Some(0), None) => {
                return Err(err(path, "`interactive.cycles` = 0: must be at least 1"))
            }
            (c, None) => Budget::Cycles(c.unwrap_or(defaults::CYCLES)),
        };
        let reference = s.reference.unwrap_or_default() == StaticReference::Newton;
        let reference_tol = positive(
            path,
            "interactive.reference_tol",
            s.reference_tol.unwrap_or(defaults::REFERENCE_TOL),
        )?;
        let lag_tol = positive(
            path,
            "interactive.lag_tol",
            s.lag_tol.unwrap_or(defaults::LAG_TOL),
        )?;
        Ok(Interactive {
            fps,
            budget,
            reference,
            reference_tol,
            lag_tol,
            predictor: s.predictor.unwrap_or(defaults::PREDICTOR),
        })
    }
}

/// Moved to [`crate::runner`] ([`crate::runner::frames`]): the frame runner, its rows and
/// summary.
#[doc(hidden)]
#[allow(deprecated)]
#[deprecated(since = "0.2.0", note = "use `raisov::runner::frames`")]
pub mod moved {
    pub use crate::runner::compat::read_frames_csv;
    pub use crate::runner::compat::run_frames;
    pub use crate::runner::compat::run_interactive;
    pub use crate::runner::FrameRow;
    pub use crate::runner::FrameStepper;
    pub use crate::runner::InteractiveSummary;
    pub use crate::runner::FRAMES_HEADER;
}
#[allow(deprecated)]
pub use moved::{
    read_frames_csv, run_frames, run_interactive, FrameRow, FrameStepper, InteractiveSummary,
    FRAMES_HEADER,
};

#[cfg(test)]
mod tests {
    use crate::scenario::Scenario;
    use std::path::Path;

    #[test]
    fn bad_interactive_keys_are_named() {
        for (extra, want) in [
            (
                "cycles = 2\nbudget_ms = 10.0",
                "either `cycles` or `budget_ms`",
            ),
            ("cycles = 0", "`interactive.cycles` = 0"),
            ("fps = -1.0", "interactive.fps"),
            ("reference = \"exact\"", "valid are \"newton\", \"none\""),
        ] {
            let text = format!(
                "[mesh]\ngenerate = \"rectangle\"\nsize = [0.1, 0.1]\nnodes = 40\n[material]\nlaw = \"stvk\"\nyoung = 1e4\npoisson = 0.3\n[[fix]]\nboundary = true\n[run]\nduration = 0.1\n[interactive]\n{extra}\n"
            );
            let e = Scenario::from_toml(&text, Path::new("bad.toml"))
                .err()
                .unwrap_or_else(|| panic!("{extra}: accepted"))
                .to_string();
            assert!(e.contains(want), "{extra}: {e}");
        }
    }
}
