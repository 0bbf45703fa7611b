//! One frame: a budget of steps, the grasps' moves, and recovery from a rejected frame.
//!
//! A frame moves every grasp from where it holds now, `p0`, to its target `p1` and runs the
//! stepper for the [`Budget`]. Try `r = 0, 1, …, max_retries` splits the move into `s = 2^r`
//! equal sub-moves: sub-move `j = 1 … s` holds the grasps at `p0 + (j/s)(p1 − p0)` for the
//! `j`-th of `s` equal parts of the budget (at least one step each, so a retried frame of
//! `Cycles(n)` with `n < s` takes `s` steps). A try is rejected when a step returns a
//! [`crate::error::Divergence`] (an inverted element, a non-finite value, an energy blow-up)
//! or when the end state inverts an element or has diverged without stopping the stepper (a
//! residual that is not finite, or a node moved more than [`DIVERGED_EXTENTS`] times the
//! body's extent: a law defined for inverted elements under a static smoother, whose
//! velocities stay zero); the stepper then returns to the state saved at
//! the start of the frame ([`crate::integrate::Stepper::save`]) and the next try begins. A
//! frame whose grasps do not move is not retried. When every try is rejected the simulation
//! stays at the state before the frame with the grasps where they were (their targets kept,
//! for the next frame to try again), and the report says `accepted: false`.
//!
//! After the frame, accepted or not, every attached [`crate::sim::HapticProxy`] gets the
//! grasp's new position, force and stiffness.
//!
//! Predictor ([`Simulation::set_predictor`]): a frame whose grasps (or a scenario's
//! prescribed displacements, its `[[displace]]` paths held at each frame's values by the
//! interactive runner) move starts, on its first try, from `u + s Δu`, `Δu` the change of
//! level 0's displacements over the last accepted frame (free nodes only), `s` how much of
//! the last frame's moves this frame repeats (`Σ g·g' / Σ |g'|²` over the grasps and the
//! prescribed points, clamped to [0, 2]) and at most `m / max_a |Δu_a|`
//! ([`crate::integrate::prediction`]): a grasp pulled at a steady speed has the tissue follow
//! at the speed it followed (`s = 1`), a reversed or turned one is not extrapolated, no node
//! is predicted to move further than the grasps move (`m` their largest move), and a held
//! grasp is not extrapolated. Nothing is predicted after a rejected frame, when the grasps
//! differ from the last frame's, or in a frame of zero steps (`Budget::Cycles(0)`: the tissue
//! does not answer).
//!
//! Only [`Budget::Millis`] makes a frame depend on the machine's speed; [`Budget::Cycles`]
//! frames give the same bits on any thread count.

use super::Simulation;
use std::time::{Duration, Instant};

/// A frame whose state moves a node further than this many times the body's extent (its
/// reference bounding box's diagonal) is rejected as diverged.
pub const DIVERGED_EXTENTS: f64 = 10.0;

/// How much work one frame may do.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Budget {
    /// This many stepper steps (one integrator step or one V-cycle each).
    Cycles(u32),
    /// Steps until this much wall time (ms) has passed since the frame began, at least one,
    /// or until the stepper has settled at the frame's equilibrium
    /// ([`crate::integrate::Stepper::settled`]: the frame solver's residual within
    /// [`crate::statics::frames::SETTLED`] of its load), whichever comes first. (A rule that
    /// starts a step only where one more like the last fits ends frames earlier, so the viewer
    /// sends more of them: measured, the browser's grasp-to-frame latency rose from 74-978 ms to
    /// 1.8-2.0 s on a 2-core machine, `bench/RESULTS.md`.)
    Millis(f64),
}

/// What a frame did.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameReport {
    /// Steps of the accepted try (0 when none was accepted).
    pub cycles: u64,
    /// Steps of the rejected tries, thrown away.
    pub rejected_cycles: u64,
    /// Tries rejected before the accepted one (or all of them).
    pub retries: u32,
    /// Whether a try was accepted; `false`: the state is the one before the frame.
    pub accepted: bool,
    /// Whether every grasp reached its target.
    pub target_reached: bool,
    /// The largest nodal residual `|V − R(u)|` over free nodes at the end of the frame (N).
    pub residual: f64,
    /// Why the last rejected try was rejected.
    pub rejection: Option<String>,
    /// Wall time of the frame, the updates of attached haptic proxies included
    /// ([`crate::sim::haptic`]: the grasp stiffness per proxy, after the budget's steps).
    pub wall: Duration,
}

impl Simulation {
    /// Run one frame (module docs of [`crate::sim::frame`]): warm-started from the last
    /// frame, the grasps moved to their targets, recovery from a rejected try.
    pub fn step_frame(&mut self, budget: Budget) -> FrameReport {
        match self.frame(budget, false) {
            Ok(report) => report,
            Err(d) => unreachable!("a frame that may be rejected returns no divergence: {d}"),
        }
    }

    /// [`Simulation::step_frame`] for a scenario's own run, taking nothing during it (a
    /// simulation built `strict`, [`Simulation::with_stepper`]): one try, the state at its end
    /// not checked, and a diverging step the caller's error (the state as it diverged).
    pub(crate) fn step_frame_strict(
        &mut self,
        budget: Budget,
    ) -> Result<FrameReport, crate::error::Divergence> {
        let strict = self.strict;
        self.frame(budget, strict)
    }

    /// The frame of [`Simulation::step_frame`]; `strict`: of
    /// [`Simulation::step_frame_strict`] (`Err` only then).
    fn frame(
        &mut self,
        budget: Budget,
        strict: bool,
    ) -> Result<FrameReport, crate::error::Divergence> {
        let start = Instant::now();
        let ids: Vec<_> = self.grabs.keys().copied().collect();
        let from: Vec<[f64; 3]> = self.grabs.values().map(|g| g.position).collect();
        let to: Vec<[f64; 3]> = self.grabs.values().map(|g| g.target).collect();
        let moving = from != to;
        // What the frame moves: the grasps, then the prescribed displacements.
        let mut this_moves = crate::integrate::moves(&from, &to);
        this_moves.extend_from_slice(&self.prescribed_moves);
        self.prescribed_moves.fill([0.0; 3]);
        let steps_any = !matches!(budget, Budget::Cycles(0));
        let before: Option<Vec<f64>> = self.predictor.then(|| self.stepper.state().u.clone());
        if !strict {
            self.stepper.save(&mut self.checkpoint);
        }
        let tries = if moving && !strict {
            self.max_retries + 1
        } else {
            1
        };
        let mut report = FrameReport {
            cycles: 0,
            rejected_cycles: 0,
            retries: 0,
            accepted: false,
            target_reached: !moving,
            residual: self.residual,
            rejection: None,
            wall: Duration::ZERO,
        };
        for attempt in 0..tries {
            // Nothing moved: `prediction` predicts nothing.
            if attempt == 0
                && steps_any
                && self.predictor
                && !self.last_delta.is_empty()
                && self.last_grabs == ids
            {
                let du =
                    crate::integrate::prediction(&self.last_delta, &this_moves, &self.last_moves);
                if let Some(du) = du {
                    self.stepper.predict(&du);
                }
            }
            let subs = 1u32 << attempt.min(16);
            let mut cycles = 0u64;
            let result = self.try_frame(budget, subs, &ids, &from, &to, start, &mut cycles);
            if strict {
                result?;
                report.cycles = cycles;
                report.accepted = true;
                report.target_reached = true;
                // Not checked: the caches follow the state as far as they can.
                let _ = self.observe();
                break;
            }
            let result = result
                .map_err(|d| self.described(d))
                .and_then(|()| {
                    self.observe().map_err(|f| {
                        format!(
                            "element {} inverted at the end of the frame (det F = {:.3e})",
                            f.element, f.det_f
                        )
                    })
                })
                .and_then(|()| self.diverged().map_or(Ok(()), Err));
            match result {
                Ok(()) => {
                    report.cycles = cycles;
                    report.accepted = true;
                    report.target_reached = true;
                    break;
                }
                Err(why) => {
                    report.rejected_cycles += cycles;
                    report.retries += 1;
                    report.rejection = Some(why);
                    self.stepper.restore(&self.checkpoint);
                    self.set_positions(&ids, &from);
                    self.apply_constraints();
                }
            }
        }
        if let Some(before) = before {
            self.last_delta.clear();
            if report.accepted {
                let u = &self.stepper.state().u;
                self.last_delta
                    .extend(u.iter().zip(&before).map(|(a, b)| a - b));
                self.last_moves = this_moves;
                self.last_grabs = ids;
            }
        }
        if report.accepted {
            // Friction grasps slide where their springs pull beyond their grip.
            self.slide_grips();
        }
        if !report.accepted {
            report.target_reached = !moving;
            // The state before the frame, which was accepted: the observation succeeds.
            let _ = self.observe();
        }
        report.residual = self.residual;
        self.publish_haptics();
        report.wall = start.elapsed();
        Ok(report)
    }

    /// Whether the observed state at a frame's end has diverged without an inverted element
    /// or a non-finite value stopping the stepper (a law defined for inverted elements, a
    /// static smoother whose velocities stay zero): a residual that is not finite, or a node
    /// displaced by more than [`DIVERGED_EXTENTS`] times the body's extent (the diagonal of
    /// its reference bounding box), which no tissue does. The reason in words, or `None`.
    fn diverged(&self) -> Option<String> {
        if !self.residual.is_finite() {
            return Some("the residual is not finite at the end of the frame: it diverged".into());
        }
        let (lo, hi) = self.mesh.bounding_box();
        let extent = crate::mesh::norm(crate::mesh::sub(hi, lo));
        let u = &self.stepper.state().u;
        let (a, d) = (0..u.len() / 3)
            .map(|a| (a, crate::mesh::norm([u[3 * a], u[3 * a + 1], u[3 * a + 2]])))
            .fold((0, 0.0f64), |b, x| if x.1 > b.1 { x } else { b });
        (d > DIVERGED_EXTENTS * extent).then(|| {
            format!(
                "node {a} moved {d:.3e} m, more than {DIVERGED_EXTENTS} times the body's extent ({extent:.3e} m): the frame diverged"
            )
        })
    }

    /// A divergence in words, its node named by its id in the mesh file and its reference
    /// position, as the scenario runner names it.
    pub(super) fn described(&self, mut d: crate::error::Divergence) -> String {
        let mesh = self.mesh();
        let ids = self.file_node_ids();
        d.locate(
            |a| ids.and_then(|f| f.get(a)).map_or(a as u64, |&i| i as u64),
            |a| mesh.nodes.get(a).copied(),
        );
        d.to_string()
    }

    fn set_positions(&mut self, ids: &[super::GrabId], p: &[[f64; 3]]) {
        for (id, &p) in ids.iter().zip(p) {
            if let Some(g) = self.grabs.get_mut(id) {
                g.position = p;
            }
        }
    }

    /// One try: `subs` sub-moves from `from` to `to`, each with its part of the budget.
    #[allow(clippy::too_many_arguments)]
    fn try_frame(
        &mut self,
        budget: Budget,
        subs: u32,
        ids: &[super::GrabId],
        from: &[[f64; 3]],
        to: &[[f64; 3]],
        start: Instant,
        cycles: &mut u64,
    ) -> Result<(), crate::error::Divergence> {
        let moving = from != to;
        let mut p = from.to_vec();
        for j in 1..=subs {
            if moving {
                let s = j as f64 / subs as f64;
                for ((p, a), b) in p.iter_mut().zip(from).zip(to) {
                    *p = if j == subs {
                        *b
                    } else {
                        [
                            a[0] + s * (b[0] - a[0]),
                            a[1] + s * (b[1] - a[1]),
                            a[2] + s * (b[2] - a[2]),
                        ]
                    };
                }
                self.set_positions(ids, &p);
                self.apply_constraints();
            }
            match budget {
                Budget::Cycles(n) => {
                    let n = n as u64;
                    let (s, j) = (subs as u64, j as u64);
                    let mut k = n * j / s - n * (j - 1) / s;
                    if n > 0 {
                        k = k.max(1);
                    }
                    for _ in 0..k {
                        self.stepper.advance()?;
                        *cycles += 1;
                    }
                }
                Budget::Millis(ms) => {
                    let until = ms.max(0.0) * 1e-3 * j as f64 / subs as f64;
                    let until = Duration::from_secs_f64(until);
                    loop {
                        self.stepper.advance()?;
                        *cycles += 1;
                        if start.elapsed() >= until || self.stepper.settled() {
                            break;
                        }
                    }
                }
            }
        }
        Ok(())
    }
}
