//! Grasps and pins taken during an interactive run: `[[displace]]` entries with `start`,
//! `release` or `stiffness`, and `[[pin]]` (keys in [`super::spec`]). They are what
//! `raisov serve` records; [`crate::runner::Replay`] replays them through a
//! [`crate::sim::Simulation`], frame by frame, as the viewer steps its own, under these rules.
//!
//! A time `s` (a grasp's `start` or `release`, a pin's `start`) acts before frame
//! `k(s) = max(1, ⌈s · fps − 10⁻⁹⌉)` ([`frame_of`]), the first frame whose path time
//! `t_k = k / fps` is at or after `s` (to within 10⁻⁹ of a frame: a time written as
//! `k / fps` is frame `k`). Before stepping frame `k` the replay
//!
//! 1. lets go of the grasps released at frame `k`: their nodes are free again;
//! 2. takes the pins of frame `k`, in file order ([`crate::sim::Simulation::pin`]: the
//!    surface patch within `radius` of the point of the deformed surface nearest `point`,
//!    unconstrained nodes only, held where it stands, on every level, to the end);
//! 3. takes the grasps of frame `k`, in file order ([`crate::sim::Simulation::grab_with`]:
//!    the patch within `radius` of the point `g` of the deformed surface nearest `point`,
//!    unconstrained nodes only, held hard or, with `stiffness = k`, pulled by zero-length
//!    springs of total stiffness `k` spread over the patch by mass); an entry whose patch is
//!    all constrained already is an error naming it and the frame;
//! 4. moves every held grasp to `g + d(t_k)`, `d` the entry's path (each node to its place
//!    on the patch moved rigidly: its offset from `g` when taken kept);
//!
//! then steps the frame ([`crate::sim::Simulation::step_frame`]) with the frame's budget:
//! `cycles`, or `budget_ms` of wall time. A rejected frame keeps the state before it and
//! the run goes on, counted in the summary. As `raisov serve` does, after a rejected frame
//! that moved a grasp each later frame is tried once, without smaller sub-moves, until a
//! frame that moves a grasp is accepted or a grasp is let go.
//!
//! The stepper is the scenario's, with no kinetic-energy ceiling (as
//! [`crate::sim::Simulation::from_scenario`] builds it): the replay of a recording made with
//! a cycle budget steps the frames the viewer stepped, with the same constraints (a grasp's
//! target `x` comes back as `g + (x − g)`, equal to within a rounding). Displacements
//! prescribed from `t = 0` (`[[displace]]` without these keys) are held at `d(t_k)` as in
//! any interactive run.

use super::spec::{DisplaceSpec, PinSpec};
use super::{err, positive};
use crate::integrate::Motion;
use crate::numbers::compact;
use crate::Result;
use std::path::Path;

/// A grasp taken during the run (`[[displace]]` with `start`, `release`, `stiffness`,
/// `friction` or `clamp_force`).
#[derive(Clone, Debug, PartialEq)]
pub struct Grasp {
    /// Its index in `[[displace]]`.
    pub index: usize,
    /// Near this point (m) the grasp point `g` is taken on the deformed surface.
    pub point: [f64; 3],
    /// The patch: surface nodes within this distance of `g` (m), at least the nearest.
    pub radius: f64,
    /// `d(t)`: the grasp holds its patch moved rigidly to `g + d(t)` (m).
    pub motion: Motion,
    /// Taken at this path time (s).
    pub start: f64,
    /// Let go at this path time (s); `None`: held to the end.
    pub release: Option<f64>,
    /// `Some(k)`: pulled by zero-length springs of total stiffness `k` (N/m, spread over the
    /// patch by mass: `crate::sim::Coupling::Spring`); `None`: held hard.
    pub stiffness: Option<f64>,
    /// A friction grasp's grip (`friction`, `clamp_force`; with `stiffness`).
    pub grip: Option<crate::integrate::Grip>,
}

/// A pin taken during the run (`[[pin]]`).
#[derive(Clone, Debug, PartialEq)]
pub struct Pin {
    /// Its index in `[[pin]]`.
    pub index: usize,
    /// m
    pub point: [f64; 3],
    /// m
    pub radius: f64,
    /// Taken at this path time (s).
    pub start: f64,
}

/// Whether a `[[displace]]` entry is a grasp taken during the run.
pub(super) fn is_grasp(d: &DisplaceSpec) -> bool {
    d.start.is_some()
        || d.release.is_some()
        || d.stiffness.is_some()
        || d.friction.is_some()
        || d.clamp_force.is_some()
}

fn time(path: &Path, key: &str, v: Option<f64>) -> Result<f64> {
    match v {
        None => Ok(0.0),
        Some(s) if s >= 0.0 && s.is_finite() => Ok(s),
        Some(s) => Err(err(
            path,
            format!("`{key}` = {}: must be >= 0 (s)", compact(s)),
        )),
    }
}

fn radius(path: &Path, key: &str, r: Option<f64>) -> Result<f64> {
    match r {
        None => Ok(0.0),
        Some(r) if r >= 0.0 && r.is_finite() => Ok(r),
        Some(r) => Err(err(
            path,
            format!("`{key}` = {}: must be >= 0 (m)", compact(r)),
        )),
    }
}

fn needs_interactive(path: &Path, what: &str) -> crate::Error {
    err(
        path,
        format!(
            "{what} is taken during the run and replayed frame by frame: the scenario needs an \
             [interactive] section"
        ),
    )
}

/// `displace[i]`, a grasp (`is_grasp`), checked; `interactive`: the scenario has an
/// `[interactive]` section.
pub(super) fn resolve_grasp(
    d: &DisplaceSpec,
    i: usize,
    path: &Path,
    interactive: bool,
) -> Result<Grasp> {
    let key = format!("displace[{i}]");
    if !interactive {
        return Err(needs_interactive(
            path,
            &format!(
                "{key} (`start`, `release`, `stiffness`, `friction` or `clamp_force`: a grasp)"
            ),
        ));
    }
    let start = time(path, &format!("{key}.start"), d.start)?;
    let release = match d.release {
        Some(r) if r.is_finite() && r > start => Some(r),
        Some(r) => {
            return Err(err(
                path,
                format!(
                    "`{key}.release` = {}: must come after `start` = {} (s)",
                    compact(r),
                    compact(start)
                ),
            ))
        }
        None => None,
    };
    let stiffness = d
        .stiffness
        .map(|k| positive(path, &format!("{key}.stiffness"), k))
        .transpose()?;
    let grip = match (d.friction, d.clamp_force) {
        (None, None) => None,
        (Some(mu), Some(n)) => {
            if stiffness.is_none() {
                return Err(err(
                    path,
                    format!("`{key}.friction` needs `{key}.stiffness` (N/m, the stiffness of the jaws' grip while it sticks): a friction grasp is a spring grasp that slides"),
                ));
            }
            Some(crate::integrate::Grip {
                friction: positive(path, &format!("{key}.friction"), mu)?,
                clamp: positive(path, &format!("{key}.clamp_force"), n)?,
            })
        }
        (Some(_), None) => {
            return Err(err(
                path,
                format!("`{key}.friction` needs `{key}.clamp_force` (N): the grasp slides beyond friction × clamp_force"),
            ))
        }
        (None, Some(_)) => {
            return Err(err(
                path,
                format!("`{key}.clamp_force` needs `{key}.friction`: the grasp slides beyond friction × clamp_force"),
            ))
        }
    };
    let still = d.displacement.is_none() && d.table.is_none() && d.time.is_none();
    let motion = if still && d.mode.is_none() && d.duration.is_none() {
        Motion::Held { d: [0.0; 3] }
    } else {
        super::resolve::resolve_motion(d, path, &key)?
    };
    Ok(Grasp {
        index: i,
        point: d.point,
        radius: radius(path, &format!("{key}.radius"), d.radius)?,
        motion,
        start,
        release,
        stiffness,
        grip,
    })
}

/// `pin[i]`, checked.
pub(super) fn resolve_pin(p: &PinSpec, i: usize, path: &Path, interactive: bool) -> Result<Pin> {
    let key = format!("pin[{i}]");
    if !interactive {
        return Err(needs_interactive(path, &key));
    }
    Ok(Pin {
        index: i,
        point: p.point,
        radius: radius(path, &format!("{key}.radius"), p.radius)?,
        start: time(path, &format!("{key}.start"), p.start)?,
    })
}

/// The frame before which a time `s` acts (module docs).
pub fn frame_of(s: f64, fps: f64) -> usize {
    (s * fps - 1e-9).ceil().max(1.0) as usize
}
