//! A haptic proxy: the tool force a device thread renders at its own rate (about 1 kHz)
//! between the simulation's frames (tens of milliseconds).
//!
//! [`Simulation::haptic_proxy`] attaches a [`HapticProxy`] to a grasp. After every frame
//! ([`Simulation::step_frame`], accepted or not) the simulation publishes the grasp's
//! state: its position `x_f` ([`Simulation::grab_position`], m), the force the tissue exerts
//! on the tool `f_f` ([`Simulation::grab_force`], N) and its stiffness
//! `K_g = ∂f/∂x` ([`Simulation::grab_stiffness`], N/m, three warm-started linear solves per
//! frame and proxy). A device thread reads the newest of these at any rate and extrapolates
//! the force to the device's position `x` to first order, within two limits:
//!
//! ```text
//! d  = x − x_f,              d' = d · min(1, r / |d|)      r = max_distance (m)
//! f  = f_f + K_g d',         f' = f · min(1, F / |f|)      F = max_force (N)
//! ```
//!
//! `f'` is [`HapticProxy::force_at`]: the force the tissue exerts on the tool (the sign of
//! `grab_force`), which is what a device renders on the user's hand; lifting a grasped patch
//! gives a force pointing down, and `K_g` (symmetric negative semi-definite at a stable
//! equilibrium) makes it grow as the device moves on. Beyond the radius `r` the linear model
//! is not trusted: the force is the one at distance `r` in the device's direction. `F` is the
//! device's force limit: a larger force keeps its direction and is scaled down to `F`. Both
//! default to infinity ([`HapticLimits::default`]); a device driver should set both. A
//! non-finite device position extrapolates nothing (`d' = 0`). When the grasp is released
//! (or the simulation dropped) the proxy publishes a frame with `held = false` and renders
//! zero force. If `grab_stiffness` fails at a frame (an element inverting in a tangent
//! product), that frame publishes `K_g = 0`: the force is held, not extrapolated.
//!
//! # Threads
//!
//! A [`HapticProxy`] is `Send + Sync` and cheap to clone (an `Arc`); reading it never takes
//! a lock and never waits for the simulation. Each published frame goes to one of two slots
//! of atomics, alternately, under a sequence number (a seqlock): the writer marks its slot
//! odd, stores the fields, marks it even, then names it the latest. A reader loads the
//! latest slot's number, the fields, and the number again, and retries when it changed; the
//! slot it reads is the one the writer is *not* filling, so a read is retried only when two
//! frames are published during it, and never waits for a writer preempted mid-write. Every
//! read returns one frame's fields together, never a mix of two frames.

use super::{GrabId, Simulation};
use crate::geometry::norm;
use crate::{Error, Result};
use std::sync::atomic::{fence, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The limits of the extrapolation (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HapticLimits {
    /// The largest force magnitude rendered (N): larger ones are scaled down to it, keeping
    /// their direction. `> 0`, infinity for none.
    pub max_force: f64,
    /// The largest extrapolation distance (m): a device farther from the frame's grasp
    /// position is extrapolated to this distance in its direction. `> 0`, infinity for none.
    pub max_distance: f64,
}

impl Default for HapticLimits {
    /// No limits (both infinite).
    fn default() -> Self {
        HapticLimits {
            max_force: f64::INFINITY,
            max_distance: f64::INFINITY,
        }
    }
}

impl HapticLimits {
    /// Limits of `max_force` (N) and `max_distance` (m), checked: each `> 0` (infinity
    /// allowed, NaN not).
    pub fn new(max_force: f64, max_distance: f64) -> Result<Self> {
        let l = HapticLimits {
            max_force,
            max_distance,
        };
        l.check()?;
        Ok(l)
    }

    fn check(&self) -> Result<()> {
        for (name, v, unit) in [
            ("max_force", self.max_force, "N"),
            ("max_distance", self.max_distance, "m"),
        ] {
            // NaN fails `v > 0`.
            if !(v > 0.0) {
                return Err(Error::param(
                    name,
                    format!("{v}: must be > 0 ({unit}; infinity for no limit)"),
                ));
            }
        }
        Ok(())
    }
}

/// One published frame of a grasp (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HapticFrame {
    /// The publication's number: 1, 2, ... in the order published.
    pub seq: u64,
    /// Whether the grasp is held; `false` after a release (all forces zero then).
    pub held: bool,
    /// The grasp position `x_f` (m).
    pub position: [f64; 3],
    /// The force the tissue exerts on the tool `f_f` (N).
    pub force: [f64; 3],
    /// `K_g[i][j] = ∂f_i / ∂x_j` (N/m).
    pub stiffness: [[f64; 3]; 3],
    /// The simulated time of the frame (s).
    pub time: f64,
    /// When the frame was published.
    pub published: Instant,
}

/// The force a device renders ([`HapticFrame::extrapolate`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HapticForce {
    /// `f'` (N; module docs).
    pub force: [f64; 3],
    /// Whether the device was farther than `max_distance` from the grasp position.
    pub distance_clamped: bool,
    /// Whether `|f|` exceeded `max_force`.
    pub force_clamped: bool,
}

impl HapticFrame {
    /// How long ago the frame was published.
    pub fn age(&self) -> Duration {
        self.published.elapsed()
    }

    /// The force at device position `x` (m) within `limits` (module docs): zero when the
    /// grasp is not held.
    pub fn extrapolate(&self, x: [f64; 3], limits: HapticLimits) -> HapticForce {
        let mut out = HapticForce {
            force: [0.0; 3],
            distance_clamped: false,
            force_clamped: false,
        };
        if !self.held {
            return out;
        }
        let mut d = [0.0; 3];
        if x.iter().all(|v| v.is_finite()) {
            d = [
                x[0] - self.position[0],
                x[1] - self.position[1],
                x[2] - self.position[2],
            ];
            let n = norm(d);
            if n > limits.max_distance {
                let s = limits.max_distance / n;
                d = d.map(|c| c * s);
                out.distance_clamped = true;
            }
        }
        let k = &self.stiffness;
        let mut f =
            [0, 1, 2].map(|i| self.force[i] + k[i][0] * d[0] + k[i][1] * d[1] + k[i][2] * d[2]);
        let n = norm(f);
        if n > limits.max_force {
            let s = limits.max_force / n;
            f = f.map(|c| c * s);
            out.force_clamped = true;
        }
        out.force = f;
        out
    }
}

/// The words of a frame: held, position (3), force (3), stiffness (9, row-major), time,
/// publication time (ns after the proxy's origin).
const WORDS: usize = 18;

/// One slot of the seqlock: `seq` is `2k + 1` while frame `k` is written into it, `2k + 2`
/// once it is complete.
struct Slot {
    seq: AtomicU64,
    words: [AtomicU64; WORDS],
}

/// What a proxy's clones and the simulation share.
pub(super) struct Shared {
    origin: Instant,
    /// The number of the newest complete frame (in slot `latest % 2`).
    latest: AtomicU64,
    slots: [Slot; 2],
    /// Serialises writers (the simulation is the only one; readers never take it).
    writer: Mutex<()>,
    max_force: AtomicU64,
    max_distance: AtomicU64,
}

/// The values of a frame to publish.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct FrameValues {
    pub(super) held: bool,
    pub(super) position: [f64; 3],
    pub(super) force: [f64; 3],
    pub(super) stiffness: [[f64; 3]; 3],
    pub(super) time: f64,
}

impl Shared {
    fn new(limits: HapticLimits) -> Shared {
        let slot = |seq| Slot {
            seq: AtomicU64::new(seq),
            words: std::array::from_fn(|_| AtomicU64::new(0)),
        };
        Shared {
            origin: Instant::now(),
            latest: AtomicU64::new(0),
            // Frame 0 (nothing held) is complete in slot 0.
            slots: [slot(2), slot(0)],
            writer: Mutex::new(()),
            max_force: AtomicU64::new(limits.max_force.to_bits()),
            max_distance: AtomicU64::new(limits.max_distance.to_bits()),
        }
    }

    /// Publish `v` as the next frame.
    pub(super) fn publish(&self, v: &FrameValues) {
        // The guard protects no data (a panic cannot leave it inconsistent).
        let _w = self
            .writer
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        let k = self.latest.load(Ordering::Relaxed) + 1;
        let slot = &self.slots[(k % 2) as usize];
        let mut w = [0u64; WORDS];
        w[0] = u64::from(v.held);
        for i in 0..3 {
            w[1 + i] = v.position[i].to_bits();
            w[4 + i] = v.force[i].to_bits();
            for j in 0..3 {
                w[7 + 3 * i + j] = v.stiffness[i][j].to_bits();
            }
        }
        w[16] = v.time.to_bits();
        w[17] = u64::try_from(self.origin.elapsed().as_nanos()).unwrap_or(u64::MAX);
        slot.seq.store(2 * k + 1, Ordering::Relaxed);
        fence(Ordering::Release);
        for (a, x) in slot.words.iter().zip(w) {
            a.store(x, Ordering::Relaxed);
        }
        slot.seq.store(2 * k + 2, Ordering::Release);
        self.latest.store(k, Ordering::Release);
    }

    fn read(&self) -> HapticFrame {
        loop {
            let k = self.latest.load(Ordering::Acquire);
            let slot = &self.slots[(k % 2) as usize];
            let s1 = slot.seq.load(Ordering::Acquire);
            if s1 != 2 * k + 2 {
                // Two frames were published since `latest` was read: read the new latest.
                std::hint::spin_loop();
                continue;
            }
            let w: [u64; WORDS] = std::array::from_fn(|i| slot.words[i].load(Ordering::Relaxed));
            fence(Ordering::Acquire);
            if slot.seq.load(Ordering::Relaxed) != s1 {
                std::hint::spin_loop();
                continue;
            }
            let f = |i: usize| f64::from_bits(w[i]);
            return HapticFrame {
                seq: k,
                held: w[0] != 0,
                position: [f(1), f(2), f(3)],
                force: [f(4), f(5), f(6)],
                stiffness: [0, 1, 2].map(|i| [0, 1, 2].map(|j| f(7 + 3 * i + j))),
                time: f(16),
                published: self.origin + Duration::from_nanos(w[17]),
            };
        }
    }

    fn limits(&self) -> HapticLimits {
        HapticLimits {
            max_force: f64::from_bits(self.max_force.load(Ordering::Relaxed)),
            max_distance: f64::from_bits(self.max_distance.load(Ordering::Relaxed)),
        }
    }

    fn set_limits(&self, l: HapticLimits) {
        self.max_force
            .store(l.max_force.to_bits(), Ordering::Relaxed);
        self.max_distance
            .store(l.max_distance.to_bits(), Ordering::Relaxed);
    }
}

/// The reading end of a grasp's published frames, for a device thread (module docs). Clones
/// share the frames and the limits.
#[derive(Clone)]
pub struct HapticProxy {
    shared: Arc<Shared>,
}

impl std::fmt::Debug for HapticProxy {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HapticProxy")
            .field("frame", &self.frame())
            .field("limits", &self.limits())
            .finish()
    }
}

impl HapticProxy {
    /// The newest published frame.
    pub fn frame(&self) -> HapticFrame {
        self.shared.read()
    }

    /// The force at device position `x` (m) from the newest frame, within the limits (N;
    /// module docs): zero when the grasp is not held.
    pub fn force_at(&self, x: [f64; 3]) -> [f64; 3] {
        self.sample(x).1.force
    }

    /// The newest frame and the force at `x` from it, with what was clamped.
    pub fn sample(&self, x: [f64; 3]) -> (HapticFrame, HapticForce) {
        let frame = self.frame();
        let force = frame.extrapolate(x, self.limits());
        (frame, force)
    }

    /// Whether the grasp is held (as of the newest frame).
    pub fn is_held(&self) -> bool {
        self.frame().held
    }

    /// How long ago the newest frame was published.
    pub fn age(&self) -> Duration {
        self.frame().age()
    }

    /// The limits of the extrapolation.
    pub fn limits(&self) -> HapticLimits {
        self.shared.limits()
    }

    /// Set the limits (for every clone); an error, changing nothing, unless each is `> 0`.
    pub fn set_limits(&self, limits: HapticLimits) -> Result<()> {
        limits.check()?;
        self.shared.set_limits(limits);
        Ok(())
    }
}

impl Simulation {
    /// A haptic proxy of grasp `id` within `limits` (module docs of [`crate::sim::haptic`]):
    /// from now on every frame publishes the grasp's position, force and stiffness to it
    /// (three warm-started solves per frame), and this call publishes the current ones. The
    /// same grasp's proxy again is a clone of the first, its limits set to `limits`. The
    /// simulation stops publishing when every clone is dropped.
    ///
    /// ```
    /// use raisov::mesh::generate::{box_tets, BoxPattern};
    /// use raisov::sim::{Budget, HapticLimits, SimulationBuilder};
    ///
    /// let mesh = box_tets([0.04; 3], [3, 3, 3], BoxPattern::Six)?;
    /// let mut sim = SimulationBuilder::new(mesh).fix(|p| p[2] <= 0.0).build()?;
    /// let g = sim.grab([0.02, 0.02, 0.05], 0.015)?;
    /// let proxy = sim.haptic_proxy(g, HapticLimits::new(5.0, 0.01)?)?;
    /// let x = sim.grab_position(g)?;
    /// sim.move_grab(g, [x[0], x[1], x[2] + 0.003])?;
    /// sim.step_frame(Budget::Cycles(8));
    /// // A device thread (here the same one) reads at any rate: the force at the frame's
    /// // position is the frame's force, and it grows as the device rises further.
    /// let frame = proxy.frame();
    /// assert_eq!(proxy.force_at(frame.position), frame.force);
    /// let above = [frame.position[0], frame.position[1], frame.position[2] + 0.001];
    /// assert!(proxy.force_at(above)[2] < frame.force[2]);
    /// # Ok::<(), raisov::Error>(())
    /// ```
    pub fn haptic_proxy(&mut self, id: GrabId, limits: HapticLimits) -> Result<HapticProxy> {
        self.grab_ref(id)?;
        limits.check()?;
        let shared = match self.haptics.get(&id) {
            Some(s) => {
                s.set_limits(limits);
                s.clone()
            }
            None => {
                let s = Arc::new(Shared::new(limits));
                self.haptics.insert(id, s.clone());
                s
            }
        };
        self.publish_haptic(id, &shared);
        Ok(HapticProxy { shared })
    }

    /// After a frame: publish every attached grasp's state, forgetting proxies nobody holds.
    pub(super) fn publish_haptics(&mut self) {
        self.haptics.retain(|_, s| Arc::strong_count(s) > 1);
        let attached: Vec<(GrabId, Arc<Shared>)> =
            self.haptics.iter().map(|(&g, s)| (g, s.clone())).collect();
        for (id, s) in attached {
            self.publish_haptic(id, &s);
        }
    }

    fn publish_haptic(&mut self, id: GrabId, s: &Shared) {
        let (Ok(position), Ok(force)) = (self.grab_position(id), self.grab_force(id)) else {
            s.publish(&FrameValues {
                time: self.time(),
                ..FrameValues::default()
            });
            return;
        };
        let stiffness = self.grab_stiffness(id).unwrap_or_default();
        s.publish(&FrameValues {
            held: true,
            position,
            force,
            stiffness,
            time: self.time(),
        });
    }

    /// A released grasp's proxy: publish `held = false` and forget it.
    pub(super) fn release_haptic(&mut self, id: GrabId) {
        if let Some(s) = self.haptics.remove(&id) {
            s.publish(&FrameValues {
                time: self.time(),
                ..FrameValues::default()
            });
        }
    }
}

impl Drop for Simulation {
    /// Every attached proxy renders zero force from now on.
    fn drop(&mut self) {
        let t = self.time();
        for s in self.haptics.values() {
            s.publish(&FrameValues {
                time: t,
                ..FrameValues::default()
            });
        }
    }
}

#[cfg(test)]
mod tests;
