//! Recording a session's grasps, pins and releases, written as a scenario `raisov run`
//! replays (interactive mode: a fixed budget per frame along the recorded paths).
//!
//! Times are wall-clock seconds since the first event, which becomes `t = 0` of the path.
//! Grasp `k`, taken at `t_k` at surface point `g_k` with radius `r_k`, becomes
//!
//! ```toml
//! [[displace]]
//! point = g_k            # the grasped surface point (m)
//! radius = r_k           # the surface patch within r_k of it (as Simulation::grab takes)
//! mode = "table"
//! table = [[t_k, 0, 0, 0], [t, dx, dy, dz], ...]   # target − g_k at the frames' times
//! ```
//!
//! sampled once per simulation frame at most every 1/60 s. Pin `j` becomes `[[fix]] box` of
//! the reference positions of the nodes it took (padded by 1 µm; on coarser levels the box
//! selects the nodes inside it). The scenario format holds a `[[displace]]` from `t = 0` to
//! the end: a recorded grasp holds its patch at zero displacement before `t_k` and at its
//! last displacement after its release; a pin is fixed from `t = 0`. `[run] duration` is
//! the last time plus 0.5 s; `[interactive]` gets the server's budget at 30 frames/s.

use crate::protocol::Method;
use crate::session::Source;
use raisov::sim::Budget;
use std::time::Instant;

/// Events kept at most (grasp samples included); later ones are dropped.
pub const MAX_EVENTS: usize = 100_000;

/// A recorded event.
#[derive(Clone, Debug, PartialEq)]
pub enum Event {
    /// A grasp taken at the surface point `point` (m) with `radius` (m).
    Grab {
        /// m
        point: [f64; 3],
        /// m
        radius: f64,
    },
    /// The grasp's target (m).
    Target([f64; 3]),
    /// The grasp let go.
    Release,
    /// A pin at `point` with `radius`; `bounds` the reference box of its nodes.
    Pin {
        /// m
        point: [f64; 3],
        /// m
        radius: f64,
        /// min, max (m)
        bounds: Bounds,
    },
}

/// Recorded events with their times.
#[derive(Clone, Debug, Default)]
pub struct Recorder {
    start: Option<Instant>,
    events: Vec<(f64, Event)>,
    last_sample: f64,
}

/// A box `(min, max)` (m).
pub type Bounds = ([f64; 3], [f64; 3]);

/// One grasp's path.
#[derive(Clone, Debug, PartialEq)]
pub struct GraspPath {
    /// Grasped surface point (m).
    pub point: [f64; 3],
    /// Radius (m).
    pub radius: f64,
    /// Rows `[t, dx, dy, dz]`, `t` strictly increasing.
    pub table: Vec<[f64; 4]>,
}

impl Recorder {
    /// An empty recording.
    pub fn new() -> Recorder {
        Recorder::default()
    }

    fn now(&mut self) -> f64 {
        let s = *self.start.get_or_insert_with(Instant::now);
        s.elapsed().as_secs_f64()
    }

    /// Record an event now.
    pub fn push(&mut self, e: Event) {
        let t = self.now();
        self.push_at(t, e);
    }

    /// Record an event at time `t` (s; not before the last one).
    pub fn push_at(&mut self, t: f64, e: Event) {
        if self.events.len() < MAX_EVENTS {
            let t = self.events.last().map_or(t, |(l, _)| t.max(*l));
            self.events.push((t, e));
        }
    }

    /// Record the held grasp's target, at most every 1/60 s.
    pub fn sample(&mut self, target: [f64; 3]) {
        let t = self.now();
        if t - self.last_sample >= 1.0 / 60.0 {
            self.last_sample = t;
            self.push_at(t, Event::Target(target));
        }
    }

    /// The events.
    pub fn events(&self) -> &[(f64, Event)] {
        &self.events
    }

    /// The grasp paths and the pins' boxes.
    pub fn paths(&self) -> (Vec<GraspPath>, Vec<Bounds>, f64) {
        let mut grasps: Vec<GraspPath> = Vec::new();
        let mut pins = Vec::new();
        let mut open = false;
        let mut end: f64 = 0.0;
        for (t, e) in &self.events {
            end = end.max(*t);
            match e {
                Event::Grab { point, radius } => {
                    grasps.push(GraspPath {
                        point: *point,
                        radius: *radius,
                        table: vec![[*t, 0.0, 0.0, 0.0]],
                    });
                    open = true;
                }
                Event::Target(x) if open => {
                    let g = grasps.last_mut().expect("open grasp");
                    let row = [*t, x[0] - g.point[0], x[1] - g.point[1], x[2] - g.point[2]];
                    let last = g.table.last_mut().expect("a first row");
                    if row[0] > last[0] {
                        g.table.push(row);
                    } else {
                        *last = [last[0], row[1], row[2], row[3]];
                    }
                }
                Event::Target(_) => {}
                Event::Release => open = false,
                Event::Pin { bounds, .. } => pins.push(*bounds),
            }
        }
        (grasps, pins, end)
    }

    /// The scenario text: the served scenario with `method`, the grasps as `[[displace]]`,
    /// the pins as `[[fix]]`, and `[interactive]` with `budget` (module docs).
    pub fn scenario(
        &self,
        source: &Source,
        method: Method,
        budget: Budget,
        nodes: usize,
    ) -> String {
        let (grasps, pins, end) = self.paths();
        let mut t = source.table_for(method);
        let f = |x: f64| toml::Value::Float(x);
        let arr = |xs: &[f64]| toml::Value::Array(xs.iter().map(|&x| f(x)).collect());
        t.insert(
            "name".into(),
            toml::Value::String(format!("{}-recorded", source.name)),
        );
        let fix = t
            .entry("fix")
            .or_insert_with(|| toml::Value::Array(Vec::new()));
        if let toml::Value::Array(fix) = fix {
            for (lo, hi) in &pins {
                let pad = 1e-6;
                let mut b = toml::Table::new();
                b.insert("min".into(), arr(&[lo[0] - pad, lo[1] - pad, lo[2] - pad]));
                b.insert("max".into(), arr(&[hi[0] + pad, hi[1] + pad, hi[2] + pad]));
                let mut e = toml::Table::new();
                e.insert("box".into(), toml::Value::Table(b));
                fix.push(toml::Value::Table(e));
            }
        }
        if let Some(toml::Value::Array(a)) = t.get("fix") {
            if a.is_empty() {
                t.remove("fix");
            }
        }
        let mut displace = Vec::new();
        for g in &grasps {
            let mut e = toml::Table::new();
            e.insert("point".into(), arr(&g.point));
            e.insert("radius".into(), f(g.radius));
            e.insert("mode".into(), toml::Value::String("table".into()));
            e.insert(
                "table".into(),
                toml::Value::Array(g.table.iter().map(|r| arr(r)).collect()),
            );
            displace.push(toml::Value::Table(e));
        }
        if !displace.is_empty() {
            t.insert("displace".into(), toml::Value::Array(displace));
        }
        let mut run = match t.remove("run") {
            Some(toml::Value::Table(r)) => r,
            _ => toml::Table::new(),
        };
        run.remove("stop");
        run.insert("duration".into(), f((end + 0.5).max(0.5)));
        t.insert("run".into(), toml::Value::Table(run));
        let mut i = toml::Table::new();
        i.insert("fps".into(), f(30.0));
        match budget {
            Budget::Cycles(c) => {
                i.insert("cycles".into(), toml::Value::Integer(c as i64));
            }
            Budget::Millis(ms) => {
                i.insert("budget_ms".into(), f(ms));
            }
        }
        t.insert("interactive".into(), toml::Value::Table(i));
        let body = toml::to_string(&t).unwrap_or_default();
        format!(
            "# Recorded by `raisov serve` ({} grasp(s), {} pin(s), {:.2} s; {} nodes at level 0,\n\
             # method {}). Replay: `raisov run FILE`. Each [[displace]] holds its patch from t = 0:\n\
             # at zero displacement before its grasp began and at its last displacement after the\n\
             # release; the pins are fixed from t = 0.\n{body}",
            grasps.len(),
            pins.len(),
            end,
            nodes,
            method.label()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_from_events() {
        let mut r = Recorder::new();
        r.push_at(
            0.0,
            Event::Grab {
                point: [1.0, 2.0, 3.0],
                radius: 0.01,
            },
        );
        r.push_at(0.1, Event::Target([1.0, 2.0, 3.5]));
        r.push_at(0.2, Event::Target([1.0, 2.5, 3.5]));
        r.push_at(0.3, Event::Release);
        r.push_at(0.35, Event::Target([9.0, 9.0, 9.0])); // no grasp open: ignored
        r.push_at(
            0.4,
            Event::Pin {
                point: [0.0; 3],
                radius: 0.0,
                bounds: ([0.0; 3], [1.0; 3]),
            },
        );
        let (g, pins, end) = r.paths();
        assert_eq!(g.len(), 1);
        assert_eq!(
            g[0].table,
            vec![
                [0.0, 0.0, 0.0, 0.0],
                [0.1, 0.0, 0.0, 0.5],
                [0.2, 0.0, 0.5, 0.5]
            ]
        );
        assert_eq!(pins, vec![([0.0; 3], [1.0; 3])]);
        assert_eq!(end, 0.4);
    }
}
