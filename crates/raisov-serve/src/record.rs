//! Recording a session's grasps, pins, releases and cuts, written as a scenario `raisov run`
//! replays frame for frame ([`raisov::scenario::grasps`]).
//!
//! The time of a recording is the session's frame count: the recording starts with the
//! simulation (built, reset, or rebuilt by a method switch), each command acts before the
//! next frame the simulation steps, and frame `k` (the `k`-th `step_frame` since the start)
//! is path time `t_k = k / fps`. `fps` is the session's own frame rate over the recording
//! (frame intervals of more than 0.5 s, when the simulation slept, left out), to three
//! significant digits, 30 when fewer than two frames were stepped; every time written is a
//! whole frame, `k / fps` as the replay computes it. Frames the simulation did not step (it
//! sleeps at rest) are not part of the recording, so the replay steps the same frames the
//! viewer stepped, in the same order, with the same budget.
//!
//! Grasp `j`, taken before frame `G` at the point `p` the client sent (the grasp point `g`
//! is the surface point nearest it), with radius `r`, let go before frame `R`, becomes
//!
//! ```toml
//! [[displace]]
//! point = p              # m
//! radius = r             # m
//! start = G / fps        # s
//! release = R / fps      # s; absent while held at the end
//! stiffness = k          # N/m, the session's --grab-stiffness; absent for a rigid hold
//! table = [[t, dx, dy, dz], ...]   # the target x_k − g of every frame it was held, as rows
//!                        # at the frames where it changed and the frame before each change
//!                        # (linear between rows: exact at every frame)
//! ```
//!
//! and pin `i`, taken before frame `P` at the point `p` with radius `r`, `[[pin]]` with
//! `point`, `radius` and `start = P / fps`. A cut made before frame `C` with the edge `a`–`b`
//! and the sweep `s` the client sent (the blade `Blade::swept(a, b, s)`) becomes
//!
//! ```toml
//! [[cut]]
//! time = C / fps         # s
//! edge = [a, b]          # m
//! sweep = s              # m
//! ```
//!
//! in the order made (a cut changes the body the next one cuts). Only cuts that split an
//! element are recorded (one that missed changed nothing). A grasp let go before any frame stepped is not
//! written (it held nothing; a hard one did stop its patch, setting its velocity to zero,
//! which the replay then does not); nor is anything after the last frame stepped. Within
//! one frame the replay lets go, then pins, then grasps (`raisov::scenario::grasps`): a
//! session that pinned after grasping an overlapping patch between the same two frames
//! replays with the pin taken first. `[run] duration`
//! is `F / fps`, `F` the frames stepped; `[interactive]` gets `fps`, the session's budget
//! (`cycles`, or `budget_ms`: a wall-time budget gives the replay as many cycles as fit on
//! its machine, so only `cycles` replays the frames exactly), the served scenario's
//! `predictor` where it gives one, and `reference = "none"` (the
//! session solved no reference either). The scenario's steady-state and static-solve keys
//! go (a recording runs its frames), and so does `[output] dir` (the replay writes to its own
//! default, `raisov-out/NAME-recorded`).
//!
//! Paths: every file the served scenario names (`[mesh] file` and `surface`, `[multigrid]
//! files`, `[output] reference`) is written absolute (joined to the served scenario's
//! directory, made canonical), so the recording loads wherever it is saved, downloaded from
//! the page or written by `--record FILE`, on the same machine. A generated mesh
//! (`[mesh] generate`) names no file.
//!
//! At most [`MAX_EVENTS`] events are kept; the recording then ends at the frame the last one
//! acted on (the header says so).

use crate::protocol;
use crate::session::Source;
use raisov::sim::Budget;
use raisov::SchemeKind;
use std::path::Path;
use std::time::Instant;

/// Events kept at most (a grasp's target changes included); the recording ends there.
pub const MAX_EVENTS: usize = 100_000;

/// A recorded event; it acts before a frame.
#[derive(Clone, Debug, PartialEq)]
pub enum Event {
    /// A grasp taken near `point` (m, as the client sent it), grasp point `at` (m).
    Grab {
        /// m
        point: [f64; 3],
        /// The grasp point: the surface point nearest `point` when taken (m).
        at: [f64; 3],
        /// m
        radius: f64,
        /// The springs' total stiffness (N/m); `None`: held rigidly.
        stiffness: Option<f64>,
    },
    /// The held grasp's target from this frame on (m).
    Target([f64; 3]),
    /// The grasp let go.
    Release,
    /// A pin near `point` with `radius` (m).
    Pin {
        /// m
        point: [f64; 3],
        /// m
        radius: f64,
    },
    /// A cut with the blade the edge `a`–`b` sweeps along `sweep` (m).
    Cut {
        /// m
        a: [f64; 3],
        /// m
        b: [f64; 3],
        /// m
        sweep: [f64; 3],
    },
}

/// Recorded events with the frames they act before.
#[derive(Clone, Debug, Default)]
pub struct Recorder {
    /// Frames stepped since the recording began.
    frames: u64,
    events: Vec<(u64, Event)>,
    /// The open grasp's last recorded target.
    target: Option<[f64; 3]>,
    /// The recording ended here (frames) when the events filled up.
    full: Option<u64>,
    /// Σ of the frame intervals up to 0.5 s (s), and their count.
    wall: f64,
    intervals: u64,
    last_frame: Option<Instant>,
}

/// One grasp as recorded.
#[derive(Clone, Debug, PartialEq)]
pub struct GraspPath {
    /// The point the client sent (m).
    pub point: [f64; 3],
    /// Radius (m).
    pub radius: f64,
    /// Springs' total stiffness (N/m), `None` for a rigid hold.
    pub stiffness: Option<f64>,
    /// Taken before this frame.
    pub start: u64,
    /// Let go before this frame; `None`: held to the end.
    pub release: Option<u64>,
    /// Rows `(frame, target − grasp point)` (m), frames increasing (module docs).
    pub table: Vec<(u64, [f64; 3])>,
}

/// One pin as recorded.
#[derive(Clone, Debug, PartialEq)]
pub struct PinAt {
    /// m
    pub point: [f64; 3],
    /// m
    pub radius: f64,
    /// Taken before this frame.
    pub start: u64,
}

/// One cut as recorded.
#[derive(Clone, Debug, PartialEq)]
pub struct CutAt {
    /// Edge point a (m).
    pub a: [f64; 3],
    /// Edge point b (m).
    pub b: [f64; 3],
    /// The sweep (m).
    pub sweep: [f64; 3],
    /// Made before this frame.
    pub start: u64,
}

/// What a recording holds: its grasps, pins and cuts and the frames stepped.
#[derive(Clone, Debug, PartialEq)]
pub struct Paths {
    /// The grasps, in the order taken.
    pub grasps: Vec<GraspPath>,
    /// The pins, in the order taken.
    pub pins: Vec<PinAt>,
    /// The cuts, in the order made.
    pub cuts: Vec<CutAt>,
    /// Frames stepped (the replay's frame count).
    pub frames: u64,
}

impl Recorder {
    /// An empty recording.
    pub fn new() -> Recorder {
        Recorder::default()
    }

    /// Record an event acting before the next frame.
    pub fn push(&mut self, e: Event) {
        if self.full.is_some() {
            return;
        }
        let next = self.frames + 1;
        match e {
            Event::Grab { .. } => self.target = None,
            Event::Release => {
                // A grasp let go before any frame held it is left out.
                let grab = self
                    .events
                    .iter()
                    .rposition(|(_, e)| matches!(e, Event::Grab { .. }));
                if let Some(i) = grab.filter(|&i| self.events[i].0 == next) {
                    self.events.remove(i);
                    self.target = None;
                    return;
                }
            }
            _ => {}
        }
        self.add(next, e);
    }

    fn add(&mut self, frame: u64, e: Event) {
        if self.events.len() >= MAX_EVENTS {
            self.full = Some(self.frames);
        } else {
            self.events.push((frame, e));
        }
    }

    /// A frame was stepped; `target`: the held grasp's target in that frame.
    pub fn frame(&mut self, target: Option<[f64; 3]>) {
        if self.full.is_some() {
            return;
        }
        let now = Instant::now();
        if let Some(last) = self.last_frame {
            let dt = now.duration_since(last).as_secs_f64();
            if dt <= 0.5 {
                self.wall += dt;
                self.intervals += 1;
            }
        }
        self.last_frame = Some(now);
        if let Some(x) = target {
            if self.target != Some(x) {
                self.target = Some(x);
                self.add(self.frames + 1, Event::Target(x));
            }
        }
        if self.full.is_none() {
            self.frames += 1;
        }
    }

    /// The events with the frames they act before.
    pub fn events(&self) -> &[(u64, Event)] {
        &self.events
    }

    /// The frame rate the times are written at (module docs).
    pub fn fps(&self) -> f64 {
        if self.intervals < 1 || self.wall <= 0.0 {
            return 30.0;
        }
        let fps = self.intervals as f64 / self.wall;
        format!("{fps:.2e}").parse().unwrap_or(30.0)
    }

    /// The grasps, pins and cuts that acted on a frame stepped, and the frames stepped.
    pub fn paths(&self) -> Paths {
        let frames = self.full.unwrap_or(self.frames);
        let mut grasps: Vec<GraspPath> = Vec::new();
        let mut pins = Vec::new();
        let mut cuts = Vec::new();
        // The open grasp: its index and grasp point, and its last target's row.
        let mut open: Option<(usize, [f64; 3])> = None;
        for (k, e) in self.events.iter().filter(|(k, _)| *k <= frames) {
            let k = *k;
            match e {
                Event::Grab {
                    point,
                    at,
                    radius,
                    stiffness,
                } => {
                    grasps.push(GraspPath {
                        point: *point,
                        radius: *radius,
                        stiffness: *stiffness,
                        start: k,
                        release: None,
                        table: Vec::new(),
                    });
                    open = Some((grasps.len() - 1, *at));
                }
                Event::Target(x) => {
                    let Some((j, at)) = open else { continue };
                    let d = [x[0] - at[0], x[1] - at[1], x[2] - at[2]];
                    let table = &mut grasps[j].table;
                    if let Some(&(last, before)) = table.last() {
                        if last + 1 < k {
                            // Held at `before` up to the frame before this change.
                            table.push((k - 1, before));
                        }
                    }
                    table.push((k, d));
                }
                Event::Release => {
                    if let Some((j, _)) = open.take() {
                        grasps[j].release = Some(k);
                    }
                }
                Event::Pin { point, radius } => pins.push(PinAt {
                    point: *point,
                    radius: *radius,
                    start: k,
                }),
                Event::Cut { a, b, sweep } => cuts.push(CutAt {
                    a: *a,
                    b: *b,
                    sweep: *sweep,
                    start: k,
                }),
            }
        }
        Paths {
            grasps,
            pins,
            cuts,
            frames,
        }
    }

    /// The scenario text: the served scenario with `method`, its paths absolute, the grasps as
    /// `[[displace]]`, the pins as `[[pin]]`, the cuts as `[[cut]]`, and `[interactive]` with
    /// `budget` (module docs); `nodes` (level 0's, uncut) goes into the header.
    pub fn scenario(
        &self,
        source: &Source,
        method: SchemeKind,
        budget: Budget,
        nodes: usize,
    ) -> String {
        let paths = self.paths();
        let fps = self.fps();
        let time = |k: u64| k as f64 / fps;
        let mut t = source.table_for(method);
        absolute_paths(&mut t, &source.base_dir);
        let f = toml::Value::Float;
        let arr = |xs: &[f64]| toml::Value::Array(xs.iter().map(|&x| f(x)).collect());
        // (A name has at most 100 characters: raisov::io::NAME_RULE.)
        const SUFFIX: &str = "-recorded";
        let name: String = source.name.chars().take(100 - SUFFIX.len()).collect();
        t.insert(
            "name".into(),
            toml::Value::String(format!("{name}{SUFFIX}")),
        );
        let mut displace = Vec::new();
        for g in &paths.grasps {
            let mut e = toml::Table::new();
            e.insert("point".into(), arr(&g.point));
            e.insert("radius".into(), f(g.radius));
            e.insert("start".into(), f(time(g.start)));
            if let Some(r) = g.release {
                e.insert("release".into(), f(time(r)));
            }
            if let Some(k) = g.stiffness {
                e.insert("stiffness".into(), f(k));
            }
            if !g.table.is_empty() {
                let rows = g
                    .table
                    .iter()
                    .map(|(k, d)| arr(&[time(*k), d[0], d[1], d[2]]))
                    .collect();
                e.insert("table".into(), toml::Value::Array(rows));
            }
            displace.push(toml::Value::Table(e));
        }
        t.remove("displace");
        if !displace.is_empty() {
            t.insert("displace".into(), toml::Value::Array(displace));
        }
        let pins: Vec<toml::Value> = paths
            .pins
            .iter()
            .map(|p| {
                let mut e = toml::Table::new();
                e.insert("point".into(), arr(&p.point));
                e.insert("radius".into(), f(p.radius));
                e.insert("start".into(), f(time(p.start)));
                toml::Value::Table(e)
            })
            .collect();
        t.remove("pin");
        if !pins.is_empty() {
            t.insert("pin".into(), toml::Value::Array(pins));
        }
        let cuts: Vec<toml::Value> = paths
            .cuts
            .iter()
            .map(|c| {
                let mut e = toml::Table::new();
                e.insert("time".into(), f(time(c.start)));
                e.insert(
                    "edge".into(),
                    toml::Value::Array(vec![arr(&c.a), arr(&c.b)]),
                );
                e.insert("sweep".into(), arr(&c.sweep));
                toml::Value::Table(e)
            })
            .collect();
        t.remove("cut");
        if !cuts.is_empty() {
            t.insert("cut".into(), toml::Value::Array(cuts));
        }
        if let Some(toml::Value::Table(i)) = t.get_mut("integrator") {
            if i.get("method").and_then(|m| m.as_str()) == Some("newton") {
                // The viewer stepped the scenario's dynamics, not a static solve.
                for k in [
                    "method",
                    "solver",
                    "max_newton",
                    "increments",
                    "coarse_start",
                    "smoother",
                ] {
                    i.remove(k);
                }
            }
        }
        let mut run = match t.remove("run") {
            Some(toml::Value::Table(r)) => r,
            _ => toml::Table::new(),
        };
        for k in ["stop", "kinetic_tol", "residual_tol", "stagnation"] {
            run.remove(k);
        }
        run.insert("duration".into(), f(time(paths.frames.max(1))));
        t.insert("run".into(), toml::Value::Table(run));
        if let Some(toml::Value::Table(o)) = t.get_mut("output") {
            o.remove("dir");
        }
        // The served scenario's frame predictor, which the session's frames ran with.
        let predictor = t
            .get("interactive")
            .and_then(|i| i.get("predictor"))
            .cloned();
        let mut i = toml::Table::new();
        i.insert("fps".into(), f(fps));
        if let Some(p) = predictor {
            i.insert("predictor".into(), p);
        }
        match budget {
            Budget::Cycles(c) => {
                i.insert("cycles".into(), toml::Value::Integer(c as i64));
            }
            Budget::Millis(ms) => {
                i.insert("budget_ms".into(), f(ms));
            }
        }
        i.insert("reference".into(), toml::Value::String("none".into()));
        t.insert("interactive".into(), toml::Value::Table(i));
        let body = toml::to_string(&t).unwrap_or_default();
        let ended = if self.full.is_some() {
            format!("\n# The recording ended there: it holds {MAX_EVENTS} events at most.")
        } else {
            String::new()
        };
        format!(
            "# Recorded by `raisov serve` ({} grasp(s), {} pin(s), {} cut(s); {} frames at {fps}\n\
             # per second of path time; {} nodes at level 0 before any cut, method {}).{ended}\n\
             # Replay: `raisov run FILE` steps the viewer's frames again, grasps, pins and cuts\n\
             # taken and let go before the frames they were (raisov::scenario::grasps).\n{body}",
            paths.grasps.len(),
            paths.pins.len(),
            paths.cuts.len(),
            paths.frames,
            nodes,
            protocol::method_label(method)
        )
    }
}

/// The file paths of a scenario table made absolute: joined to `base` (the scenario's
/// directory) where relative, made canonical where the file exists (module docs).
pub fn absolute_paths(t: &mut toml::Table, base: &Path) {
    let fix = |v: &mut toml::Value| {
        if let toml::Value::String(s) = v {
            let p = base.join(&*s);
            let p = std::fs::canonicalize(&p)
                .or_else(|_| std::path::absolute(&p))
                .unwrap_or(p);
            *s = p.to_string_lossy().into_owned();
        }
    };
    if let Some(toml::Value::Table(m)) = t.get_mut("mesh") {
        for k in ["file", "surface"] {
            if let Some(v) = m.get_mut(k) {
                fix(v);
            }
        }
    }
    if let Some(toml::Value::Array(files)) = t
        .get_mut("multigrid")
        .and_then(|m| m.as_table_mut())
        .and_then(|m| m.get_mut("files"))
    {
        files.iter_mut().for_each(fix);
    }
    if let Some(v) = t
        .get_mut("output")
        .and_then(|o| o.as_table_mut())
        .and_then(|o| o.get_mut("reference"))
    {
        if !matches!(v.as_str(), Some("none" | "auto")) {
            fix(v);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grab(x: f64) -> Event {
        Event::Grab {
            point: [x, 0.0, 0.0],
            at: [x, 0.0, 0.5],
            radius: 0.01,
            stiffness: Some(200.0),
        }
    }

    /// Rows at the frames where the target changed and the frame before each change, a
    /// grasp let go before any frame left out, pins at their frames, nothing past the last
    /// frame.
    #[test]
    fn paths_are_frames_exact() {
        let mut r = Recorder::new();
        r.frame(None); // frame 1
        r.push(grab(1.0)); // before frame 2
        r.frame(Some([1.0, 0.0, 0.5])); // 2
        r.frame(Some([1.0, 0.0, 0.5])); // 3
        r.frame(Some([1.0, 0.0, 0.5])); // 4
        r.frame(Some([1.0, 0.0, 1.5])); // 5: changed
        r.frame(Some([1.0, 1.0, 1.5])); // 6: changed
        r.push(Event::Release); // before 7
        r.push(Event::Pin {
            point: [0.0; 3],
            radius: 0.0,
        });
        r.push(grab(2.0)); // before 7, let go before any frame: left out
        r.push(Event::Release);
        r.frame(None); // 7
        r.push(grab(3.0)); // before 8: after the last frame, left out
        let p = r.paths();
        assert_eq!(p.frames, 7);
        assert_eq!(p.grasps.len(), 1, "{p:?}");
        let g = &p.grasps[0];
        assert_eq!((g.start, g.release), (2, Some(7)));
        assert_eq!(
            g.table,
            vec![
                (2, [0.0, 0.0, 0.0]),
                (4, [0.0, 0.0, 0.0]),
                (5, [0.0, 0.0, 1.0]),
                (6, [0.0, 1.0, 1.0])
            ]
        );
        assert_eq!(
            p.pins,
            vec![PinAt {
                point: [0.0; 3],
                radius: 0.0,
                start: 7
            }]
        );
    }

    /// A cut made before frame 3 (of 4 stepped) is written as `[[cut]]` with `time = 3 / fps`,
    /// its edge and sweep as the client sent them; a cut after the last frame is not.
    #[test]
    fn cuts_are_written_as_cut_entries_at_their_frames() {
        let source = Source::from_text(
            "[mesh]\ngenerate = \"box\"\nsize = [0.04, 0.04, 0.04]\ndivisions = [2, 2, 2]\n\
             [material]\nlaw = \"neo-hookean\"\nyoung = 5e3\npoisson = 0.45\n\
             [[cut]]\ntime = 0.0\nedge = [[0, 0, 0], [1, 0, 0]]\nsweep = [0, 0, 1]\n",
            std::path::PathBuf::from("."),
            "cube",
            Path::new("cube.toml"),
        )
        .unwrap();
        assert!(
            !source.table.contains_key("cut"),
            "the served scenario's cuts are not served (the clients cut)"
        );
        let mut r = Recorder::new();
        r.frame(None);
        r.frame(None);
        let (a, b, sweep) = ([0.01, 0.0, 0.04], [0.03, 0.04, 0.04], [0.0, 0.0, -0.02]);
        r.push(Event::Cut { a, b, sweep });
        r.frame(None);
        r.frame(None);
        r.push(Event::Cut { a: b, b: a, sweep });
        let p = r.paths();
        assert_eq!(
            p.cuts,
            vec![CutAt {
                a,
                b,
                sweep,
                start: 3
            }]
        );
        let text = r.scenario(&source, SchemeKind::SingleLevel, Budget::Cycles(2), 27);
        assert!(text.contains("1 cut(s)"), "{text}");
        let t: toml::Table = text.parse().unwrap();
        let cuts = t["cut"].as_array().unwrap();
        assert_eq!(cuts.len(), 1, "{text}");
        let c = cuts[0].as_table().unwrap();
        let fps = r.fps();
        assert_eq!(c["time"].as_float(), Some(3.0 / fps));
        let v = |x: &toml::Value| -> Vec<f64> {
            x.as_array()
                .unwrap()
                .iter()
                .map(|y| y.as_float().unwrap())
                .collect()
        };
        let edge = c["edge"].as_array().unwrap();
        assert_eq!((v(&edge[0]), v(&edge[1])), (a.to_vec(), b.to_vec()));
        assert_eq!(v(&c["sweep"]), sweep.to_vec());
        assert_eq!(c.len(), 3, "time, edge, sweep: {c:?}");
    }

    /// The events fill up: the recording ends at the frame where they did.
    #[test]
    fn a_full_recording_ends_where_it_filled() {
        let mut r = Recorder::new();
        r.push(grab(0.0));
        for k in 0..MAX_EVENTS + 10 {
            r.frame(Some([k as f64, 0.0, 0.0]));
        }
        let p = r.paths();
        assert_eq!(p.frames as usize, MAX_EVENTS - 1);
        assert!(p.grasps[0].table.last().unwrap().0 <= p.frames);
    }
}
