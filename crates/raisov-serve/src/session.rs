//! The simulation thread: one [`Simulation`] stepped frame after frame at a fixed budget,
//! warm-started from the previous frame, driven by the clients' commands; each frame is
//! encoded once ([`crate::protocol`]) and published as the newest frame only (a
//! `tokio::sync::watch` slot: a slow client skips frames, it never queues them).
//!
//! Frame `k`: apply the queued commands (the holder's newest move target wins), run
//! `step_frame(budget)`, read the surface positions `x_v` (f32) and the scalar
//! `s_v = |x_v − X_v|` (displacement magnitude, m) or the von Mises stress
//! `σ_vm = sqrt(3/2 s:s)`, `s = σ − tr(σ)/3 I` (Pa, from the nodal Cauchy stress), then publish.
//! Only the vertices that the surface triangles use are sent, renumbered in ascending order.
//! The sim-thread rate is an exponential average of the frame intervals (weight 0.1); with
//! `max_fps > 0` a frame that ends early sleeps until `1/max_fps` has passed since it began.
//!
//! Method switch, reset: the simulation is rebuilt from the scenario text of the method
//! ([`Source::text_for`]), from rest; a method switch then pins the recorded pins again at
//! their points and grasps again at the held grasp's first point, moved to its target.
//!
//! Cut: a client's cut is the blade `Blade::swept(a, b, sweep)`, cut on every level by
//! [`Simulation::cut`]. A cut that split elements changes the surface (its vertex and
//! triangle counts, the wound's faces): the topology is rebuilt and sent to every client
//! before the next frame, and every client is told what the cut split (a `cut` message). A
//! cut that missed changes nothing; one the simulation refuses (loads that cannot be cut:
//! pressure, traction, timed loads, tools) is answered with an error naming why, nothing
//! changed. The displacement colour stays `|x − X|` across cuts at the nodes (`X` the
//! reference position, which the copies of a node share); the wound's vertices, and a visual
//! surface's, are measured from where they were when the topology was built. The stress
//! colour needs a surface of mesh nodes only: none after a cut (the wound's vertices are not
//! nodes), when the displacement is shown.
//!
//! A reset goes back to the uncut body. A method switch cuts the new simulation with the
//! blades of the old one ([`Simulation::cuts`]), in order, so the wound stays; a method that
//! cannot cut them is refused with an error, the old simulation kept.
//!
//! Recording ([`crate::record`]): every command that grasps, lets go, pins or cuts is recorded
//! before the frame it acts on, and every frame stepped with the held grasp's target in it;
//! a reset or a method switch starts the recording again (with the cuts, pins and grasp a
//! switch takes again).
//!
//! Sleep: the thread steps only while somebody needs frames. With no client connected and no
//! grasp held it waits for a command; so it does once the state is at rest, when for
//! [`REST_FRAMES`] frames in a row no surface vertex moved more than [`REST_MOTION`] times
//! the surface's bounding-box diagonal and no grasp was moving (unless the scenario has
//! loads or tools that change with time, [`Source::timed`]). The last frame before it sleeps
//! carries the "at rest" flag; any command or a new client wakes it.
//!
//! A grasp that cannot reach its target: a frame whose every try is rejected (an element
//! inverts on the way, [`raisov::sim::frame`]) leaves the grasp where it was. The holder is
//! told once (an error naming why) and the grasp's target is set back to where it holds, so
//! the next frames are ordinary frames; until a grasp move succeeds again each new target is
//! tried once, without the retries of smaller sub-moves, so the frames of every viewer keep
//! their rate. Frames carry the "stuck" flag meanwhile.
//!
//! Divergence: a frame rejected while no grasp moves means the scheme itself blew up (RaISoV
//! as the paper reads it does so on organ hierarchies, growing from rounding errors: see
//! `bench/RESULTS.md`). The state before the frame is kept, every client is told which
//! element inverted and what to do (reset, or switch the method), frames carry the
//! "diverged" flag, and the thread sleeps until a command arrives instead of retrying the
//! same frame for ever.

use crate::protocol::{
    self, Colour, Command, STATS, STAT_APPLIED_SEQ, STAT_CYCLES, STAT_FORCE, STAT_FRAME_MS,
    STAT_GRASP, STAT_GRASPED, STAT_HOLDER, STAT_INPUT_LAG_MS, STAT_METHOD, STAT_RESIDUAL,
    STAT_SCALAR_MAX, STAT_SIM_FPS,
};
use crate::record::{Event, Recorder};
use crate::ServeError;
use raisov::mesh::cut::Blade;
use raisov::scenario::spec::{MultigridSpec, FAS_KEYS, NEWTON_KEYS, PAPER_KEYS};
use raisov::sim::{Budget, GrabId, GrabOptions, Simulation};
use raisov::SchemeKind;
use std::path::{Path, PathBuf};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::{mpsc, watch};

/// Frames in a row without motion after which the simulation sleeps (module docs).
pub const REST_FRAMES: u32 = 30;
/// The motion per frame, as a fraction of the surface's bounding-box diagonal, below which
/// a frame counts as at rest.
pub const REST_MOTION: f64 = 1e-6;

/// The scenario the server runs, as a TOML table, and the method it names.
#[derive(Clone, Debug)]
pub struct Source {
    /// The scenario without `[[displace]]`, `[[pin]]`, `[[cut]]` (the clients grasp, pin and
    /// cut) and `[interactive]`.
    pub table: toml::Table,
    /// Relative paths of the scenario are taken from here.
    pub base_dir: PathBuf,
    /// The scenario's name (the file stem or its `name`).
    pub name: String,
    /// The scheme the scenario names, as the page offers it (one of [`protocol::METHODS`]).
    pub method: SchemeKind,
}

impl Source {
    /// A scenario file (the TOML of `raisov run`).
    pub fn from_scenario_file(path: &Path) -> Result<Source, ServeError> {
        let text = std::fs::read_to_string(path).map_err(|e| ServeError::Io {
            path: path.to_path_buf(),
            source: e,
        })?;
        let base = path
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_else(|| PathBuf::from("."));
        // The scenario's default name, as `raisov run` makes it (raisov::io::name_from_stem).
        let stem = raisov::io::name_from_stem(
            &path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default(),
            "scenario",
        );
        Self::from_text(&text, base, &stem, path)
    }

    /// Scenario text; `path` names it in messages.
    pub fn from_text(
        text: &str,
        base_dir: PathBuf,
        stem: &str,
        path: &Path,
    ) -> Result<Source, ServeError> {
        let mut table: toml::Table = text.parse().map_err(|e: toml::de::Error| {
            ServeError::Scenario(format!("{}: {}", path.display(), e.message()))
        })?;
        // What the clients do (and a recording's replay of it) is not served.
        table.remove("displace");
        table.remove("pin");
        table.remove("cut");
        table.remove("interactive");
        // The scheme a viewer's frames run: the resolver's own rule for an interactive
        // scenario (`MultigridSpec::scheme_kind`); backward Euler on one level, its levels
        // preconditioning the Newton solves. A `[multigrid]` the resolver would refuse is
        // offered as FAS, and the resolver then says what is wrong with it.
        let method = match table.get("multigrid") {
            _ if implicit(&table) => SchemeKind::SingleLevel,
            None => SchemeKind::SingleLevel,
            Some(mg) => mg
                .clone()
                .try_into::<MultigridSpec>()
                .map_or(SchemeKind::Fas, |mg| mg.scheme_kind(true)),
        };
        let name = table
            .get("name")
            .and_then(|v| v.as_str())
            .unwrap_or(stem)
            .to_string();
        Ok(Source {
            table,
            base_dir,
            name,
            method,
        })
    }

    /// A closed triangle surface meshed at load (`[mesh] surface`): `nodes` at level 0,
    /// three levels under the frame solver (`scheme = "newton"`), coordinates times `scale` in m, neo-Hookean liver-like tissue
    /// (E = 5 kPa, ν = 0.45, ρ = 1060 kg/m³, α = 30 1/s), held on the top 5 % of its height.
    pub fn from_surface(path: &Path, scale: f64, nodes: usize) -> Result<Source, ServeError> {
        let s = raisov::io::load_surface(path)?;
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for p in &s.points {
            lo = lo.min(p[2] * scale);
            hi = hi.max(p[2] * scale);
        }
        let cap = hi - 0.05 * (hi - lo);
        let abs = std::fs::canonicalize(path).map_err(|e| ServeError::Io {
            path: path.to_path_buf(),
            source: e,
        })?;
        // The scenario's name: the stem within the name rule (raisov::io::NAME_RULE).
        let stem = raisov::io::name_from_stem(
            &path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default(),
            "surface",
        );
        let text = format!(
            "name = {name}\n[mesh]\nsurface = {file}\nscale = {scale:e}\nnodes = {nodes}\n\
             [material]\nlaw = \"neo-hookean\"\nyoung = 5000.0\npoisson = 0.45\ndensity = 1060.0\n\
             [damping]\nalpha = 30.0\n\
             [[fix]]\nplane = {{ point = [0.0, 0.0, {cap:e}], normal = [0.0, 0.0, -1.0] }}\n\
             [run]\nduration = 1.0\n\
             [multigrid]\nscheme = \"newton\"\nlevels = 3\n",
            name = protocol::json_string(&stem),
            file = protocol::json_string(&abs.display().to_string()),
        );
        let base = abs
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_else(|| PathBuf::from("."));
        Self::from_text(&text, base, &stem, path)
    }

    /// The scenario table for `method`: `[multigrid] scheme = "newton"`, `"fas"` or
    /// `"raisov-paper"` (the keys of the other two schemes dropped), or no `[multigrid]`
    /// (single level).
    ///
    /// A scenario integrated by backward Euler or BDF2 (`[integrator] method =
    /// "implicit-euler"` or `"bdf2"`) is served as `SchemeKind::SingleLevel` with its `[multigrid]`
    /// levels kept (they precondition its Newton solves); switched to a multigrid method, it
    /// drops its integrator keys ([`IMPLICIT_ONLY`]) and `[damping] beta`, and is stepped at
    /// the scheme's own step (the frame solver's frames are quasi-static).
    pub fn table_for(&self, method: SchemeKind) -> toml::Table {
        let mut t = self.table.clone();
        match method {
            // A backward-Euler scenario keeps its levels: they precondition its Newton solves.
            k if !k.is_multigrid() && implicit(&t) => {}
            k if !k.is_multigrid() => {
                t.remove("multigrid");
            }
            _ => {
                if implicit(&t) {
                    // The explicit schemes take their own stable step: the keys of backward
                    // Euler do not apply to them.
                    if let Some(toml::Value::Table(i)) = t.get_mut("integrator") {
                        for k in IMPLICIT_ONLY {
                            i.remove(*k);
                        }
                    }
                    // Stiffness-proportional damping is the implicit schemes' only.
                    if let Some(toml::Value::Table(d)) = t.get_mut("damping") {
                        d.remove("beta");
                    }
                }
                let mg = t
                    .entry("multigrid")
                    .or_insert_with(|| toml::Value::Table(toml::Table::new()));
                if let toml::Value::Table(mg) = mg {
                    let generated = self
                        .table
                        .get("mesh")
                        .is_some_and(|m| m.get("generate").is_some() || m.get("surface").is_some());
                    let has_levels = ["levels", "files", "level_nodes"]
                        .iter()
                        .any(|k| mg.contains_key(*k));
                    if generated && !has_levels {
                        // A one-level scenario: generate a second, coarser level.
                        mg.insert("levels".into(), toml::Value::Integer(2));
                    }
                    let drop: &[&[&str]] = match method {
                        SchemeKind::Fas => &[PAPER_KEYS, NEWTON_KEYS],
                        SchemeKind::Newton => &[PAPER_KEYS, FAS_KEYS],
                        _ => &[FAS_KEYS, NEWTON_KEYS],
                    };
                    mg.insert("scheme".into(), toml::Value::String(method.name().into()));
                    for k in drop.iter().copied().flatten() {
                        mg.remove(*k);
                    }
                }
            }
        }
        t
    }

    /// Whether the scenario has loads or tools that change with time (a `time` key in a
    /// `[[load]]`, `[[pressure]]` or `[[traction]]`, or any `[[tool]]`): then the state is
    /// never taken to be at rest.
    pub fn timed(&self) -> bool {
        if self.table.contains_key("tool") {
            return true;
        }
        ["load", "pressure", "traction"].iter().any(|k| {
            self.table
                .get(*k)
                .and_then(|v| v.as_array())
                .is_some_and(|a| a.iter().any(|t| t.get("time").is_some()))
        })
    }

    /// The scenario text for `method` ([`Source::table_for`]).
    pub fn text_for(&self, method: SchemeKind) -> String {
        toml::to_string(&self.table_for(method)).unwrap_or_default()
    }

    /// Build the simulation of `method`.
    pub fn build(&self, method: SchemeKind) -> Result<Simulation, ServeError> {
        Ok(Simulation::from_toml(
            &self.text_for(method),
            &self.base_dir,
        )?)
    }
}

/// The one place a client's grasp becomes a simulation grasp: the surface patch within
/// `radius` (m) of `point`, pulled towards the cursor by springs of total stiffness
/// `stiffness` (N/m, spread over the patch by mass, so the tissue can resist and lag), or held
/// rigidly when `stiffness` is `None`.
pub fn grab_tool(
    sim: &mut Simulation,
    point: [f64; 3],
    radius: f64,
    stiffness: Option<f64>,
) -> raisov::Result<GrabId> {
    match stiffness {
        Some(k) => sim.grab_with(point, GrabOptions::spring(radius, k)),
        None => sim.grab(point, radius),
    }
}

/// Settings of the simulation thread.
#[derive(Clone, Debug)]
pub struct SessionConfig {
    /// Work per frame.
    pub budget: Budget,
    /// Cap on the frame rate (1/s); 0 for none.
    pub max_fps: f64,
    /// The method to start with (default: the scenario's).
    pub method: Option<SchemeKind>,
    /// Where `save` also writes the recorded scenario.
    pub record_path: Option<PathBuf>,
    /// Total stiffness of the grasp's coupling springs (N/m); `None` holds the patch rigidly.
    pub grab_stiffness: Option<f64>,
}

/// A message to one client (text) or a notice for all.
#[derive(Clone, Debug)]
pub enum Reply {
    /// A JSON text message.
    Text(String),
}

/// What the simulation thread publishes: the topology and the newest frame.
#[derive(Debug)]
pub struct Published {
    /// The topology message ([`protocol::encode_topology`]).
    pub topology: Arc<Vec<u8>>,
    /// Changes whenever the topology is rebuilt (method switch, reset).
    pub topology_version: u64,
    /// The frame message ([`protocol::encode_frame`]); empty before the first frame.
    pub frame: Vec<u8>,
    /// Who holds the grasp (client id), if anyone.
    pub holder: Option<u64>,
    /// The method running now.
    pub method: SchemeKind,
}

/// A command to the simulation thread.
#[derive(Debug)]
pub enum SessionCmd {
    /// A client connected; its replies go to `reply` (bounded: a full queue drops replies).
    Connect {
        /// client id
        id: u64,
        /// its reply queue
        reply: mpsc::Sender<Reply>,
    },
    /// A client went away (its grasp is released).
    Disconnect {
        /// client id
        id: u64,
    },
    /// A parsed client message.
    Client {
        /// client id
        id: u64,
        /// the message
        msg: protocol::Message,
        /// when it arrived
        arrived: Instant,
    },
    /// Stop the thread.
    Shutdown,
}

/// Handle on a running simulation thread.
pub struct Session {
    /// Commands in (bounded).
    pub commands: SyncSender<SessionCmd>,
    /// The newest frame out.
    pub published: watch::Receiver<Arc<Published>>,
    /// The scenario's name.
    pub name: String,
    /// Surface vertex and triangle counts.
    pub counts: (usize, usize),
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Session {
    /// Start the thread: build the simulation (errors come back here), then step.
    pub fn spawn(source: Source, config: SessionConfig) -> Result<Session, ServeError> {
        let (tx, rx) = std::sync::mpsc::sync_channel(1024);
        let (ready_tx, ready_rx) = std::sync::mpsc::channel();
        let name = source.name.clone();
        let thread = std::thread::Builder::new()
            .name("raisov-sim".into())
            .spawn(move || {
                let method = config.method.unwrap_or(source.method);
                match Worker::new(source, config, method) {
                    Ok((mut w, published_rx)) => {
                        let _ = ready_tx.send(Ok((published_rx, w.counts())));
                        // On a worker of rayon's pool, the force passes' parallel loops
                        // start at once instead of waking the pool each time.
                        rayon::scope(|_| w.run(rx));
                    }
                    Err(e) => {
                        let _ = ready_tx.send(Err(e));
                    }
                }
            })
            .map_err(|e| {
                ServeError::Scenario(format!("cannot start the simulation thread: {e}"))
            })?;
        let (published, counts) = ready_rx
            .recv()
            .map_err(|_| ServeError::Scenario("the simulation thread stopped".into()))??;
        Ok(Session {
            commands: tx,
            published,
            name,
            counts,
            thread: Some(thread),
        })
    }

    /// Send a command; `Err` with a message when the queue is full or the thread is gone.
    pub fn send(&self, cmd: SessionCmd) -> Result<(), &'static str> {
        match self.commands.try_send(cmd) {
            Ok(()) => Ok(()),
            Err(TrySendError::Full(_)) => Err("the simulation is busy: message dropped"),
            Err(TrySendError::Disconnected(_)) => Err("the simulation thread has stopped"),
        }
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        let _ = self.commands.send(SessionCmd::Shutdown);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The held grasp.
struct Held {
    client: u64,
    id: GrabId,
    /// The point the client grasped (m) and the radius, for a rebuild.
    point: [f64; 3],
    radius: f64,
    target: [f64; 3],
}

struct Worker {
    source: Source,
    config: SessionConfig,
    method: SchemeKind,
    sim: Simulation,
    /// Surface vertices the triangles use (indices of `surface_positions`).
    used: Vec<u32>,
    rest: Vec<[f64; 3]>,
    /// Whether `used` indexes mesh nodes (stress available).
    nodal: bool,
    colour: Colour,
    published: watch::Sender<Arc<Published>>,
    topology: Arc<Vec<u8>>,
    topology_version: u64,
    clients: Vec<(u64, mpsc::Sender<Reply>)>,
    held: Option<Held>,
    pins: Vec<([f64; 3], f64)>,
    /// The cuts that split elements, as the clients sent them (edge a, edge b, sweep; m), in
    /// order: the recording's `[[cut]]`s after a method switch.
    cuts: Vec<([f64; 3], [f64; 3], [f64; 3])>,
    /// Level 0's nodes before any cut.
    uncut_nodes: usize,
    recorder: Recorder,
    frame: u32,
    fps: f64,
    last_end: Option<Instant>,
    applied_seq: u32,
    input_lag_ms: f32,
    /// Arrival of the newest holder message not yet shown in a frame.
    pending: Option<(u32, Instant)>,
    positions32: Vec<[f32; 3]>,
    /// The last frame's positions, to measure the motion of the next one.
    previous32: Vec<[f32; 3]>,
    scalar: Vec<f32>,
    /// The largest surface motion of the last frame (m).
    moved: f64,
    /// The rest tolerance on `moved` (m): [`REST_MOTION`] times the bounding-box diagonal.
    rest_motion: f64,
    /// Frames in a row at rest.
    still: u32,
    /// The last frame published says the thread sleeps.
    resting: bool,
    /// The held grasp could not reach its target (module docs).
    stuck: bool,
    /// The simulation's retries of a rejected frame, restored when the grasp moves again.
    retries: u32,
    /// The scenario has loads or tools that change with time.
    timed: bool,
    /// The scheme diverged with no grasp moving (module docs); cleared by any command.
    diverged: bool,
}

impl Worker {
    fn new(
        source: Source,
        config: SessionConfig,
        method: SchemeKind,
    ) -> Result<(Worker, watch::Receiver<Arc<Published>>), ServeError> {
        let sim = source.build(method)?;
        let uncut_nodes = sim.mesh().num_nodes();
        let retries = sim.max_retries();
        let timed = source.timed();
        let (tx, rx) = watch::channel(Arc::new(Published {
            topology: Arc::new(Vec::new()),
            topology_version: 0,
            frame: Vec::new(),
            holder: None,
            method,
        }));
        let mut w = Worker {
            source,
            config,
            method,
            sim,
            used: Vec::new(),
            rest: Vec::new(),
            nodal: false,
            colour: Colour::Displacement,
            published: tx,
            topology: Arc::new(Vec::new()),
            topology_version: 0,
            clients: Vec::new(),
            held: None,
            pins: Vec::new(),
            cuts: Vec::new(),
            uncut_nodes,
            recorder: Recorder::new(),
            frame: 0,
            fps: 0.0,
            last_end: None,
            applied_seq: 0,
            input_lag_ms: 0.0,
            pending: None,
            positions32: Vec::new(),
            previous32: Vec::new(),
            scalar: Vec::new(),
            moved: f64::INFINITY,
            rest_motion: 0.0,
            still: 0,
            resting: false,
            stuck: false,
            retries,
            timed,
            diverged: false,
        };
        w.new_topology();
        w.publish(None);
        Ok((w, rx))
    }

    fn counts(&self) -> (usize, usize) {
        (self.used.len(), self.sim.surface_triangles().len())
    }

    /// The surface's used vertices, renumbered triangles, rest positions.
    fn new_topology(&mut self) {
        let tris = self.sim.surface_triangles();
        let mut used: Vec<u32> = tris.iter().flatten().copied().collect();
        used.sort_unstable();
        used.dedup();
        let n_all = self.sim.surface_positions().len();
        let mut map = vec![u32::MAX; n_all];
        for (k, &v) in used.iter().enumerate() {
            map[v as usize] = k as u32;
        }
        let local: Vec<[u32; 3]> = tris
            .iter()
            .map(|t| [map[t[0] as usize], map[t[1] as usize], map[t[2] as usize]])
            .collect();
        let pos = self.sim.surface_positions();
        self.nodal = std::ptr::eq(pos.as_ptr(), self.sim.positions().as_ptr());
        // The leading surface vertices that are mesh nodes: all of them without a visual
        // surface; a cut body's surface lists the nodes first, then the wound's vertices.
        let n = self.sim.positions().len();
        let nodes = match self.nodal || (!self.sim.cuts().is_empty() && pos.len() >= n) {
            true => n,
            false => 0,
        };
        // The reference positions X = x − u of those nodes; other vertices where they are now.
        let u = self.sim.displacements();
        self.rest = used
            .iter()
            .map(|&v| {
                let (x, v) = (pos[v as usize], v as usize);
                match v < nodes {
                    true => [x[0] - u[3 * v], x[1] - u[3 * v + 1], x[2] - u[3 * v + 2]],
                    false => x,
                }
            })
            .collect();
        self.topology = Arc::new(protocol::encode_topology(used.len(), &local));
        self.topology_version += 1;
        self.used = used;
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for p in &self.rest {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let diag = (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum::<f64>().sqrt();
        self.rest_motion = REST_MOTION * if diag.is_finite() { diag } else { 0.0 };
        self.previous32.clear();
        self.still = 0;
    }

    /// Whether somebody needs the next frame (module docs: sleep).
    fn needed(&self) -> bool {
        if self.diverged || (self.clients.is_empty() && self.held.is_none()) {
            return false;
        }
        self.timed || self.still < REST_FRAMES
    }

    fn run(&mut self, rx: Receiver<SessionCmd>) {
        loop {
            let start = Instant::now();
            loop {
                match rx.try_recv() {
                    Ok(SessionCmd::Shutdown) => return,
                    Ok(c) => self.handle(c),
                    Err(std::sync::mpsc::TryRecvError::Empty) => break,
                    Err(std::sync::mpsc::TryRecvError::Disconnected) => return,
                }
            }
            if !self.needed() {
                if !self.resting && !self.clients.is_empty() {
                    // Tell the viewers why no frames follow.
                    self.resting = true;
                    self.publish(None);
                }
                self.resting = true;
                match rx.recv() {
                    Ok(SessionCmd::Shutdown) | Err(_) => return,
                    Ok(c) => self.handle(c),
                }
                self.resting = false;
                self.still = 0;
                self.last_end = None;
                continue;
            }
            let moving = self
                .held
                .as_ref()
                .is_some_and(|h| self.sim.grab_position(h.id).is_ok_and(|p| p != h.target));
            let target = self.held.as_ref().map(|h| h.target);
            let report = self.sim.step_frame(self.config.budget);
            self.recorder.frame(target);
            if moving {
                self.grasp_outcome(&report);
            } else if !report.accepted {
                self.diverged = true;
                let why = report
                    .rejection
                    .as_deref()
                    .unwrap_or("the frame was rejected");
                let why = why.strip_prefix("diverged ").unwrap_or(why);
                let hint = if self.method == SchemeKind::RaisovPaper {
                    " (the paper's scheme does not settle on organ hierarchies: it grows from \
                     rounding errors at every step tried)"
                } else {
                    ""
                };
                let m = format!(
                    "{} diverged {why}{hint}: the state before it is kept and the simulation \
                     waits; press reset to start again from rest, or switch the method",
                    protocol::method_label(self.method)
                );
                self.broadcast(protocol::error_json(&m));
            }
            self.publish(Some(&report));
            self.still = if self.moved <= self.rest_motion && !moving && report.accepted {
                self.still.saturating_add(1)
            } else {
                0
            };
            if self.config.max_fps > 0.0 {
                let period = Duration::from_secs_f64(1.0 / self.config.max_fps);
                let elapsed = start.elapsed();
                if elapsed < period {
                    match rx.recv_timeout(period - elapsed) {
                        Ok(SessionCmd::Shutdown) => return,
                        Ok(c) => self.handle(c),
                        Err(RecvTimeoutError::Timeout) => {}
                        Err(RecvTimeoutError::Disconnected) => return,
                    }
                }
            }
        }
    }

    /// After a frame that moved the held grasp: when it was rejected, tell the holder (once),
    /// hold the grasp where it is and try later targets without retries; when it was
    /// accepted, restore the retries (module docs).
    fn grasp_outcome(&mut self, report: &raisov::sim::FrameReport) {
        let Some(h) = self.held.as_mut() else { return };
        if report.accepted {
            if self.stuck {
                self.stuck = false;
                self.sim.set_max_retries(self.retries);
            }
            return;
        }
        let at = self.sim.grab_position(h.id).unwrap_or(h.target);
        let wanted = h.target;
        h.target = at;
        let (g, client) = (h.id, h.client);
        let _ = self.sim.move_grab(g, at);
        if !self.stuck {
            self.stuck = true;
            self.sim.set_max_retries(0);
            let why = report
                .rejection
                .as_deref()
                .unwrap_or("the frame was rejected");
            let mm = |p: [f64; 3]| {
                format!(
                    "({:.1}, {:.1}, {:.1}) mm",
                    p[0] * 1e3,
                    p[1] * 1e3,
                    p[2] * 1e3
                )
            };
            self.error(
                client,
                format!(
                    "the grasp cannot reach {} ({why}): it holds at {}; move it back towards \
                     the organ, or release",
                    mm(wanted),
                    mm(at)
                ),
            );
        }
    }

    fn reply(&mut self, id: u64, text: String) {
        if let Some((_, tx)) = self.clients.iter().find(|(c, _)| *c == id) {
            // A full queue (a client that does not read) drops the reply.
            let _ = tx.try_send(Reply::Text(text));
        }
    }

    fn broadcast(&mut self, text: String) {
        for (_, tx) in &self.clients {
            let _ = tx.try_send(Reply::Text(text.clone()));
        }
    }

    fn error(&mut self, id: u64, msg: impl AsRef<str>) {
        self.reply(id, protocol::error_json(msg.as_ref()));
    }

    /// The pins as a text message: `{"type":"pins","pins":[[x, y, z, r], …]}` (m).
    fn pins_json(&self) -> String {
        let pins: Vec<String> = self
            .pins
            .iter()
            .map(|(p, r)| {
                format!(
                    "[{},{},{},{}]",
                    json_number(p[0]),
                    json_number(p[1]),
                    json_number(p[2]),
                    json_number(*r)
                )
            })
            .collect();
        format!("{{\"type\":\"pins\",\"pins\":[{}]}}", pins.join(","))
    }

    fn holder_notice(&mut self) {
        let h = self
            .held
            .as_ref()
            .map_or("null".to_string(), |h| h.client.to_string());
        self.broadcast(format!("{{\"type\":\"holder\",\"holder\":{h}}}"));
    }

    fn handle(&mut self, cmd: SessionCmd) {
        match cmd {
            SessionCmd::Connect { id, reply } => {
                // At most a few hundred clients: beyond that a connection gets no replies.
                if self.clients.len() < 256 {
                    self.clients.push((id, reply));
                }
                let methods: Vec<String> = protocol::METHODS
                    .iter()
                    .map(|&m| protocol::json_string(protocol::method_label(m)))
                    .collect();
                let budget = match self.config.budget {
                    Budget::Cycles(c) => format!("{{\"cycles\":{c}}}"),
                    Budget::Millis(ms) => format!("{{\"ms\":{}}}", json_number(ms)),
                };
                let hello = format!(
                    "{{\"type\":\"hello\",\"client\":{id},\"name\":{},\"methods\":[{}],\"method\":{},\"holder\":{},\"stress\":{},\"budget\":{budget},\"max_fps\":{}}}",
                    protocol::json_string(&self.source.name),
                    methods.join(","),
                    protocol::method_code(self.method),
                    self.held.as_ref().map_or("null".to_string(), |h| h.client.to_string()),
                    self.nodal,
                    json_number(self.config.max_fps),
                );
                self.reply(id, hello);
                let pins = self.pins_json();
                self.reply(id, pins);
            }
            SessionCmd::Disconnect { id } => {
                self.clients.retain(|(c, _)| *c != id);
                if self.held.as_ref().is_some_and(|h| h.client == id) {
                    self.release();
                }
            }
            SessionCmd::Client { id, msg, arrived } => {
                self.still = 0;
                self.diverged = false;
                self.command(id, msg, arrived);
            }
            SessionCmd::Shutdown => {}
        }
    }

    fn release(&mut self) {
        if self.stuck {
            self.stuck = false;
            self.sim.set_max_retries(self.retries);
        }
        if let Some(h) = self.held.take() {
            let _ = self.sim.release(h.id);
            self.recorder.push(Event::Release);
            self.holder_notice();
        }
    }

    fn command(&mut self, id: u64, msg: protocol::Message, arrived: Instant) {
        let f64p = |p: [f32; 3]| [p[0] as f64, p[1] as f64, p[2] as f64];
        let holds = self.held.as_ref().map(|h| h.client);
        match msg.command {
            Command::Grab { point, radius } => {
                if let Some(h) = holds {
                    if h != id {
                        self.error(id, format!("client {h} holds the grasp: one at a time"));
                    } else {
                        self.error(id, "grab while holding a grasp: release it first");
                    }
                    return;
                }
                let (point, radius) = (f64p(point), radius as f64);
                match grab_tool(&mut self.sim, point, radius, self.config.grab_stiffness) {
                    Ok(g) => {
                        let at = self.sim.grab_position(g).unwrap_or(point);
                        self.held = Some(Held {
                            client: id,
                            id: g,
                            point,
                            radius,
                            target: at,
                        });
                        self.recorder.push(Event::Grab {
                            point,
                            at,
                            radius,
                            stiffness: self.config.grab_stiffness,
                        });
                        self.pending = Some((msg.seq, arrived));
                        self.holder_notice();
                    }
                    Err(e) => self.error(id, format!("grab: {e}")),
                }
            }
            Command::Move { target } => {
                let Some(h) = self.held.as_mut().filter(|h| h.client == id) else {
                    self.error(id, "move without a grasp held by this client: dropped");
                    return;
                };
                let t = f64p(target);
                h.target = t;
                let g = h.id;
                match self.sim.move_grab(g, t) {
                    Ok(()) => self.pending = Some((msg.seq, arrived)),
                    Err(e) => self.error(id, format!("move: {e}")),
                }
            }
            Command::Release => {
                if holds != Some(id) {
                    self.error(id, "release without a grasp held by this client: dropped");
                    return;
                }
                self.release();
            }
            Command::Pin { point, radius } => {
                let (p, r) = (f64p(point), radius as f64);
                match self.sim.pin(p, r) {
                    Ok(_) => {
                        self.pins.push((p, r));
                        let pins = self.pins_json();
                        self.broadcast(pins);
                        self.recorder.push(Event::Pin {
                            point: p,
                            radius: r,
                        });
                    }
                    Err(e) => self.error(id, format!("pin: {e}")),
                }
            }
            Command::Reset => {
                self.held = None;
                self.pins.clear();
                self.recorder = Recorder::new();
                self.rebuild(id, self.method, false);
                self.holder_notice();
                let pins = self.pins_json();
                self.broadcast(pins);
            }
            Command::Method(m) => {
                if m != self.method {
                    self.rebuild(id, m, true);
                }
            }
            Command::Colour(c) => {
                if c == Colour::Stress && !self.nodal {
                    self.error(
                        id,
                        "stress is shown where the surface's vertices are the mesh's nodes only (no visual surface, no cut): showing displacement",
                    );
                } else {
                    self.colour = c;
                }
            }
            Command::Save => {
                let text = self.recorder.scenario(
                    &self.source,
                    self.method,
                    self.config.budget,
                    self.uncut_nodes,
                );
                if let Some(path) = &self.config.record_path {
                    if let Err(e) = std::fs::write(path, &text) {
                        let m = format!("writing {}: {e}", path.display());
                        self.error(id, m);
                    }
                }
                self.reply(
                    id,
                    format!(
                        "{{\"type\":\"recording\",\"toml\":{}}}",
                        protocol::json_string(&text)
                    ),
                );
            }
            Command::Cut { a, b, sweep } => self.cut(id, f64p(a), f64p(b), f64p(sweep)),
        }
    }

    /// A client's cut (module docs): the blade the edge `a`–`b` sweeps along `sweep` (m).
    fn cut(&mut self, id: u64, a: [f64; 3], b: [f64; 3], sweep: [f64; 3]) {
        let report = Blade::swept(a, b, sweep).and_then(|blade| self.sim.cut(&blade));
        match report {
            Ok(r) => {
                if r.split.iter().any(|&s| s > 0) {
                    self.cuts.push((a, b, sweep));
                    self.recorder.push(Event::Cut { a, b, sweep });
                    self.new_topology();
                }
                let split: Vec<String> = r.split.iter().map(usize::to_string).collect();
                let (vertices, triangles) = self.counts();
                let m = format!(
                    "{{\"type\":\"cut\",\"client\":{id},\"split\":[{}],\"nodes\":{},\"elements\":{},\"ms\":{},\"cuts\":{},\"vertices\":{vertices},\"triangles\":{triangles}}}",
                    split.join(","),
                    r.nodes,
                    r.elements,
                    json_number(r.seconds * 1e3),
                    self.cuts.len()
                );
                self.broadcast(m);
            }
            Err(e) => self.error(id, format!("cut: {e}")),
        }
    }

    /// Rebuild the simulation with `method`; `keep` re-applies the cuts, the pins and the
    /// grasp (a method that cannot cut the body again is refused, the old simulation kept).
    /// The recording starts again with them (the frames before were of another simulation).
    fn rebuild(&mut self, id: u64, method: SchemeKind, keep: bool) {
        let built = self.source.build(method).map_err(|e| e.to_string());
        let built = match (built, keep) {
            (Ok(mut sim), true) => {
                let uncut = sim.mesh().num_nodes();
                let blades = self.sim.cuts();
                let n = blades.len();
                match blades.iter().try_for_each(|b| sim.cut(b).map(|_| ())) {
                    Ok(()) => Ok((sim, uncut)),
                    Err(e) => Err(format!(
                        "the body has {n} cut(s) and {} cannot take them ({e}): staying with {}; \
                         reset to switch to it with the body uncut",
                        protocol::method_label(method),
                        protocol::method_label(self.method)
                    )),
                }
            }
            (Ok(sim), false) => {
                let uncut = sim.mesh().num_nodes();
                Ok((sim, uncut))
            }
            (Err(e), _) => Err(e),
        };
        match built {
            Ok((sim, uncut_nodes)) => {
                self.sim = sim;
                self.uncut_nodes = uncut_nodes;
                if !keep {
                    self.cuts.clear();
                }
                self.recorder = Recorder::new();
                self.retries = self.sim.max_retries();
                self.stuck = false;
                self.method = method;
                self.new_topology();
                if keep {
                    for &(a, b, sweep) in &self.cuts {
                        self.recorder.push(Event::Cut { a, b, sweep });
                    }
                    let pins = std::mem::take(&mut self.pins);
                    for (p, r) in pins {
                        if self.sim.pin(p, r).is_ok() {
                            self.pins.push((p, r));
                            self.recorder.push(Event::Pin {
                                point: p,
                                radius: r,
                            });
                        }
                    }
                    if let Some(h) = self.held.take() {
                        match grab_tool(
                            &mut self.sim,
                            h.point,
                            h.radius,
                            self.config.grab_stiffness,
                        ) {
                            Ok(g) => {
                                let at = self.sim.grab_position(g).unwrap_or(h.point);
                                self.recorder.push(Event::Grab {
                                    point: h.point,
                                    at,
                                    radius: h.radius,
                                    stiffness: self.config.grab_stiffness,
                                });
                                let _ = self.sim.move_grab(g, h.target);
                                self.held = Some(Held { id: g, ..h });
                            }
                            Err(e) => {
                                self.error(h.client, format!("grab again after the switch: {e}"));
                                self.holder_notice();
                            }
                        }
                    }
                }
                let m = format!(
                    "{{\"type\":\"method\",\"method\":{},\"stress\":{}}}",
                    protocol::method_code(method),
                    self.nodal
                );
                self.broadcast(m);
                if keep {
                    let pins = self.pins_json();
                    self.broadcast(pins);
                }
            }
            Err(e) => self.error(
                id,
                format!("switching to {}: {e}", protocol::method_label(method)),
            ),
        }
    }

    fn publish(&mut self, report: Option<&raisov::sim::FrameReport>) {
        let now = Instant::now();
        if let (Some(last), Some(_)) = (self.last_end, report) {
            let dt = now.duration_since(last).as_secs_f64();
            if dt > 0.0 {
                let f = 1.0 / dt;
                self.fps = if self.fps == 0.0 {
                    f
                } else {
                    0.9 * self.fps + 0.1 * f
                };
            }
        }
        self.last_end = Some(now);
        if let Some((seq, at)) = self.pending.take() {
            self.applied_seq = seq;
            self.input_lag_ms = now.duration_since(at).as_secs_f32() * 1e3;
        }
        let pos = self.sim.surface_positions();
        std::mem::swap(&mut self.previous32, &mut self.positions32);
        self.positions32.clear();
        self.scalar.clear();
        for (k, &v) in self.used.iter().enumerate() {
            let x = pos[v as usize];
            self.positions32
                .push([x[0] as f32, x[1] as f32, x[2] as f32]);
            let r = self.rest[k];
            let d = [x[0] - r[0], x[1] - r[1], x[2] - r[2]];
            self.scalar
                .push((d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() as f32);
        }
        self.moved = if self.previous32.len() == self.positions32.len() {
            let mut m = 0.0f64;
            for (a, b) in self.positions32.iter().zip(&self.previous32) {
                let d2: f64 = (0..3).map(|k| ((a[k] - b[k]) as f64).powi(2)).sum();
                m = m.max(d2);
            }
            m.sqrt()
        } else {
            f64::INFINITY
        };
        let stress = self.colour == Colour::Stress && self.nodal;
        if stress {
            let s = self.sim.nodal_stress();
            for (k, &v) in self.used.iter().enumerate() {
                self.scalar[k] = von_mises(&s[v as usize]) as f32;
            }
        }
        let mut stats = [0.0f32; STATS];
        stats[STAT_SIM_FPS] = self.fps as f32;
        stats[STAT_RESIDUAL] = self.sim.residual() as f32;
        if let Some(r) = report {
            stats[STAT_CYCLES] = r.cycles as f32;
            stats[protocol::STAT_REJECTED_TRIES] = r.retries as f32;
            stats[protocol::STAT_REJECTED_STEPS] = r.rejected_cycles as f32;
            stats[STAT_FRAME_MS] = r.wall.as_secs_f32() * 1e3;
        }
        stats[STAT_INPUT_LAG_MS] = self.input_lag_ms;
        stats[STAT_HOLDER] = -1.0;
        if let Some(h) = &self.held {
            let f = self.sim.grab_force(h.id).unwrap_or([0.0; 3]);
            let p = self.sim.grab_position(h.id).unwrap_or([0.0; 3]);
            for k in 0..3 {
                stats[STAT_FORCE + k] = f[k] as f32;
                stats[STAT_GRASP + k] = p[k] as f32;
            }
            stats[STAT_HOLDER] = h.client as f32;
            stats[STAT_GRASPED] = self.sim.grab_nodes(h.id).map_or(0, |n| n.len()) as f32;
        }
        stats[STAT_SCALAR_MAX] = self.scalar.iter().copied().fold(0.0, f32::max);
        stats[STAT_METHOD] = protocol::method_code(self.method) as f32;
        stats[STAT_APPLIED_SEQ] = self.applied_seq as f32;
        let flag = |on: bool, f: u32| if on { f } else { 0 };
        let flags = flag(self.held.is_some(), protocol::FLAG_HELD)
            | flag(stress, protocol::FLAG_STRESS)
            | flag(self.resting, protocol::FLAG_REST)
            | flag(self.stuck, protocol::FLAG_STUCK)
            | flag(self.diverged, protocol::FLAG_DIVERGED);
        self.frame = self.frame.wrapping_add(1);
        let frame =
            protocol::encode_frame(self.frame, flags, &stats, &self.positions32, &self.scalar);
        let published = Published {
            topology: self.topology.clone(),
            topology_version: self.topology_version,
            frame,
            holder: self.held.as_ref().map(|h| h.client),
            method: self.method,
        };
        self.published.send_replace(Arc::new(published));
    }
}

/// A finite number as JSON (non-finite ones, which JSON lacks, as `null`).
fn json_number(x: f64) -> String {
    if x.is_finite() {
        format!("{x:e}")
    } else {
        "null".into()
    }
}

/// von Mises stress of a Cauchy stress (row-major 3×3), Pa.
pub fn von_mises(s: &[f64; 9]) -> f64 {
    let tr = (s[0] + s[4] + s[8]) / 3.0;
    let mut q = 0.0;
    for i in 0..3 {
        for j in 0..3 {
            let d = s[3 * i + j] - if i == j { tr } else { 0.0 };
            q += d * d;
        }
    }
    (1.5 * q).sqrt()
}

/// The `[integrator]` keys of backward Euler, dropped when such a scenario is switched to an
/// explicit scheme in the viewer ([`Source::table_for`]).
pub const IMPLICIT_ONLY: &[&str] = &[
    "method",
    "dt",
    "newton_tol",
    "max_newton",
    "solver",
    "smoother",
];

/// Whether the scenario asks for backward Euler or BDF2 (`[integrator] method =
/// "implicit-euler"` or `"bdf2"`).
fn implicit(t: &toml::Table) -> bool {
    matches!(
        t.get("integrator")
            .and_then(|i| i.get("method"))
            .and_then(|m| m.as_str()),
        Some("implicit-euler" | "bdf2")
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use raisov::sim::Budget;

    /// A scenario whose `[multigrid]` names no scheme is served with the frame solver, unless
    /// it sets FAS's own keys; the frame solver's table drops the keys of the other schemes.
    #[test]
    fn levels_without_a_scheme_are_served_with_the_frame_solver() {
        let cube = |multigrid: &str| {
            let text = format!(
                "[mesh]\ngenerate = \"box\"\nsize = [0.04, 0.04, 0.04]\ndivisions = [4, 4, 4]\n\
                 [material]\nlaw = \"neo-hookean\"\nyoung = 5e3\npoisson = 0.45\n\
                 [[fix]]\nplane = {{ point = [0, 0, 0], normal = [0, 0, 1] }}\n\
                 [run]\nduration = 1.0\n[multigrid]\nlevels = 2\n{multigrid}\n"
            );
            Source::from_text(&text, PathBuf::from("."), "cube", Path::new("cube.toml")).unwrap()
        };
        let src = cube("");
        assert_eq!(src.method, SchemeKind::Newton);
        let sim = src.build(SchemeKind::Newton).unwrap();
        assert!(sim.stepper().describe().starts_with("newton frames"));
        assert_eq!(cube("coarse = \"newton\"").method, SchemeKind::Fas);
        let t = cube("cg_per_step = 3\nreading = \"paper\"").table_for(SchemeKind::Newton);
        let mg = t.get("multigrid").and_then(|m| m.as_table()).unwrap();
        assert!(mg.contains_key("cg_per_step") && !mg.contains_key("reading"));
        let t = cube("cg_per_step = 3").table_for(SchemeKind::Fas);
        let mg = t.get("multigrid").and_then(|m| m.as_table()).unwrap();
        assert!(!mg.contains_key("cg_per_step"));
    }

    /// The viewer serves the scheme the resolver resolves for the same `[multigrid]` of an
    /// interactive scenario: one rule (`MultigridSpec::scheme_kind`), not a copy of it.
    #[test]
    fn the_viewer_serves_the_scheme_the_resolver_resolves() {
        for multigrid in [
            "",
            "coarse = \"newton\"",
            "smoother = \"dynamics\"\npre_smooth = 2",
            "cg_per_step = 3",
            "scheme = \"fas\"",
            "scheme = \"raisov-paper\"",
            "scheme = \"newton\"",
        ] {
            let text = format!(
                "[mesh]\ngenerate = \"box\"\nsize = [0.04, 0.04, 0.04]\ndivisions = [4, 4, 4]\n\
                 [material]\nlaw = \"neo-hookean\"\nyoung = 5e3\npoisson = 0.45\n\
                 [[fix]]\nplane = {{ point = [0, 0, 0], normal = [0, 0, 1] }}\n\
                 [run]\nduration = 0.1\n[multigrid]\nlevels = 2\n{multigrid}\n"
            );
            let served =
                Source::from_text(&text, PathBuf::from("."), "cube", Path::new("cube.toml"))
                    .unwrap()
                    .method;
            let resolved = raisov::scenario::Scenario::from_toml(
                &format!("{text}[interactive]\nfps = 30\n"),
                Path::new("cube.toml"),
            )
            .unwrap()
            .scheme()
            .kind();
            assert_eq!(served, resolved, "{multigrid:?}");
        }
    }

    /// Each word of `[multigrid] scheme` is served as its `SchemeKind`, and each kind's
    /// table names it by the same word.
    #[test]
    fn every_scheme_word_is_served_as_its_kind() {
        for kind in SchemeKind::MULTIGRID {
            let text = format!(
                "[mesh]\ngenerate = \"box\"\nsize = [0.04, 0.04, 0.04]\ndivisions = [4, 4, 4]\n\
                 [material]\nlaw = \"neo-hookean\"\nyoung = 5e3\npoisson = 0.45\n\
                 [run]\nduration = 1.0\n[multigrid]\nlevels = 2\nscheme = \"{}\"\n",
                kind.name()
            );
            let src = Source::from_text(&text, PathBuf::from("."), "cube", Path::new("cube.toml"))
                .unwrap();
            assert_eq!(src.method, kind);
            for other in SchemeKind::MULTIGRID {
                let t = src.table_for(other);
                let word = t["multigrid"]["scheme"].as_str();
                assert_eq!(word, Some(other.name()));
            }
            assert!(!src
                .table_for(SchemeKind::SingleLevel)
                .contains_key("multigrid"));
        }
    }

    /// A BDF2 scenario with stiffness-proportional damping is served as backward Euler's
    /// (one level, its levels the preconditioner); switched to FAS it drops `damping.beta`,
    /// which the explicit schemes refuse.
    #[test]
    fn a_bdf2_scenario_with_stiffness_damping_is_served_and_switches_without_beta() {
        let text = r#"
gravity = [0.0, 0.0, -9.81]
[mesh]
generate = "box"
size = [0.04, 0.04, 0.04]
divisions = [4, 4, 4]
[material]
law = "stable-neo-hookean"
young = 5e3
poisson = 0.45
[damping]
alpha = 5.0
beta = 1e-3
[[fix]]
plane = { point = [0, 0, 0], normal = [0, 0, 1] }
[integrator]
method = "bdf2"
dt = 0.0166666666666667
[multigrid]
levels = 2
[run]
duration = 1.0
"#;
        let src =
            Source::from_text(text, PathBuf::from("."), "cube", Path::new("cube.toml")).unwrap();
        assert_eq!(src.method, SchemeKind::SingleLevel);
        let mut sim = src.build(SchemeKind::SingleLevel).unwrap();
        assert!(sim.stepper().describe().contains("bdf2"));
        for _ in 0..2 {
            let r = sim.step_frame(Budget::Cycles(1));
            assert!(r.accepted, "{r:?}");
        }
        let t = src.table_for(SchemeKind::Fas);
        let d = t.get("damping").and_then(|d| d.as_table()).unwrap();
        assert!(!d.contains_key("beta") && d.contains_key("alpha"));
        let sim = src.build(SchemeKind::Fas).unwrap();
        assert!(!sim.stepper().describe().contains("bdf2"));
    }

    /// A backward-Euler scenario with `[multigrid]` levels was refused by the viewer: it
    /// served every scenario with levels as FAS, whose `multigrid.scheme` backward Euler
    /// refuses. It is served on one level with its levels kept (the preconditioner), and the
    /// viewer's switch to FAS or RaISoV steps it explicitly.
    #[test]
    fn an_implicit_euler_scenario_with_levels_is_served() {
        let text = r#"
gravity = [0.0, 0.0, -9.81]
[mesh]
generate = "box"
size = [0.04, 0.04, 0.04]
divisions = [6, 6, 6]
[material]
law = "stable-neo-hookean"
young = 5e3
poisson = 0.45
[[fix]]
plane = { point = [0, 0, 0], normal = [0, 0, 1] }
[integrator]
method = "implicit-euler"
dt = 0.0166666666666667
solver = "multigrid"
[multigrid]
levels = 2
[run]
duration = 1.0
"#;
        let src =
            Source::from_text(text, PathBuf::from("."), "cube", Path::new("cube.toml")).unwrap();
        assert_eq!(src.method, SchemeKind::SingleLevel);
        let t = src.table_for(SchemeKind::SingleLevel);
        assert!(
            t.contains_key("multigrid"),
            "the levels precondition the solves"
        );
        let mut sim = src.build(SchemeKind::SingleLevel).unwrap();
        assert!(sim.stepper().describe().contains("implicit-euler"));
        let r = sim.step_frame(Budget::Cycles(1));
        assert!(r.accepted, "{r:?}");
        // One step of 1/60 s: the cube sags under gravity.
        assert!(sim.displacements().chunks(3).any(|u| u[2] < -1e-7));
        for m in [SchemeKind::Fas, SchemeKind::RaisovPaper] {
            let t = src.table_for(m);
            let i = t.get("integrator").and_then(|i| i.as_table());
            assert!(i.is_none_or(|i| IMPLICIT_ONLY.iter().all(|k| !i.contains_key(*k))));
            let sim = src.build(m).unwrap();
            assert!(!sim.stepper().describe().contains("implicit"), "{m:?}");
        }
    }
}
