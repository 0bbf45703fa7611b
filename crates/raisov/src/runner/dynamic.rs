//! Running a scenario: step, measure, write.
//!
//! The output directory is locked for the run ([`crate::io::OutputLock`], `.raisov.lock`):
//! a second run on the same directory stops with an error naming it. Files written under it:
//! - `measures.csv`: one row per `csv_every` steps ([`crate::metrics::CSV_HEADER`]), the
//!   reactions and the tools' contact force and penetration included, and with friction the
//!   friction force (`friction_x_N..`, [`crate::metrics::CSV_FRICTION`]) ([`crate::metrics`]), streamed as the rows come and flushed with every
//!   frame: a killed run leaves the rows up to its last frame. Nothing of it is kept in memory;
//!   the steady-state test keeps the peaks and the best value so far;
//! - `NAME.pvd` + `frames/NAME_NNNNNN.vtu`: ParaView time series, points in the reference
//!   configuration with point fields `displacement` (m; the active vectors, so *Warp By
//!   Vector* shows the deformed body), `velocity` (m/s), `stress` (nodal Cauchy T, Pa),
//!   `contact_force` (N per node, the force the `[[tool]]`s exert; scenarios with tools) and
//!   `contact_pressure` (Pa, its magnitude over the node's tributary boundary area), with
//!   friction `friction_force` (N per node, the tangential part of `contact_force`), and
//!   `file_node_id` (`Int64`, each point's node id in the mesh file) where that differs from
//!   its position (`[mesh] renumber` reordered the nodes, or the file numbers from 1); binary appended zlib or ASCII per `[output] vtu`
//!   ([`crate::io::vtu`]);
//! - with `[mesh] surface`, `NAME_surface.pvd` + `frames/NAME_surface_NNNNNN.vtp`: the input
//!   surface embedded in the finest level, its reference points with the interpolated
//!   `displacement`, one file per volume frame ([`crate::scenario::surface`]);
//! - `nodal_stress.csv`: the final nodal stress per node, in file order, `node` the file's id
//!   (usable as a later run's `output.reference`);
//! - `summary.txt`: what the closing summary says, how the run stopped included.
//!
//! Frames, `nodal_stress.csv` and `summary.txt` are written atomically (temp file + rename:
//! a failed write removes its temp file, one that a killed run left is swept by the next run);
//! the `.pvd` collections are appended in place ([`crate::io::PvdWriter`]). No output is
//! written through a symbolic link: one at an output's name is an error naming it
//! ([`crate::io::output`]). A failed write (a full disk) stops the run with an error naming
//! the file, the operating system's reason and what the file keeps (`measures.csv`: its
//! complete rows, the last one's step and time; [`crate::io::RowFile`]); no summary is
//! written then.
//!
//! How a run stops ([`StopReason`]): after `duration`; at steady state (`stop = "steady"`:
//! kinetic energy and residual below their tolerances times their peaks, once every
//! prescribed motion has ended); `stop = "steady"` without reaching it, at the time cap or
//! when the steady measure `m = max(KE / (kinetic_tol · KE_peak), |r| / (residual_tol ·
//! |r|_peak))` has not fallen below `(1 − 1e-3)` times its best value for `stagnation`
//! checks in a row (a check is a row of `measures.csv`; counted after the motions end); or
//! when [`RunOptions::stop`] is raised (`raisov run` raises it on SIGINT and SIGTERM): the
//! run ends at the next step boundary, writes its last row, frame, `nodal_stress.csv` and a
//! summary that says it was interrupted.
//!
//! A run first clears what the previous run left (`runner/outputs.rs`): once it holds the lock it
//! removes `measures.csv`, `frames.csv`, `nodal_stress.csv` and `summary.txt`, this
//! scenario's `.pvd` collections and numbered frames, and the temporary files of killed
//! writers, so that a run killed or diverging early never leaves an older summary beside its
//! own measures; everything else stays, the level cache `cache/` and other scenarios' frames
//! included. A `reference` file is read before that (it may be the last run's
//! `nodal_stress.csv`).
//!
//! A diverging run writes what it measured up to the last finite state, then returns
//! [`Error::Diverged`] naming time, step, element and cause. Nothing non-finite is written.

use super::outputs::{write_output, OutDir};
use crate::error::{Error, Result};
use crate::integrate::Stepper;
use crate::io::{write_atomic, write_vtu_as, Field, FieldData, PvdWriter, VtuFormat};
use crate::metrics::{Meter, Sample};
use crate::scenario::surface::SurfaceFrames;
use crate::scenario::{mesh_index_of_file, read_nodal_stress, Reference, Scenario, StopRule};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Why a run ended normally.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StopReason {
    /// The requested duration was simulated.
    Duration,
    /// Kinetic energy and residual fell below their tolerances.
    Steady,
    /// `stop = "steady"` but the cap on simulated time came first.
    NotSteadyBeforeCap,
    /// `stop = "steady"` but the steady measure made no progress for this many checks.
    Stagnated(u64),
    /// [`RunOptions::stop`] was raised (SIGINT, SIGTERM).
    Interrupted,
}

impl StopReason {
    /// Whether the run did what it was asked: the duration, or steady state.
    pub fn is_success(self) -> bool {
        matches!(self, StopReason::Duration | StopReason::Steady)
    }
}

impl std::fmt::Display for StopReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            StopReason::Duration => f.write_str("reached the requested duration"),
            StopReason::Steady => f.write_str("reached steady state"),
            StopReason::NotSteadyBeforeCap => {
                f.write_str("did not reach steady state: hit the time cap (`run.duration`)")
            }
            StopReason::Stagnated(n) => write!(
                f,
                "did not reach steady state: no progress in {n} checks (`run.stagnation`)"
            ),
            StopReason::Interrupted => f.write_str("interrupted (by a signal) before the end"),
        }
    }
}

/// Progress callback: the fraction done (0..1) and the latest sample.
pub type Progress<'a> = &'a mut dyn FnMut(f64, &Sample);

/// Options of a run.
#[derive(Default)]
pub struct RunOptions<'a> {
    /// Output directory; default the scenario's.
    pub out_dir: Option<PathBuf>,
    /// Called after every sample.
    pub progress: Option<Progress<'a>>,
    /// Raised from outside (a signal handler): the run stops at the next step boundary and
    /// reports [`StopReason::Interrupted`].
    pub stop: Option<&'a std::sync::atomic::AtomicBool>,
    /// Keep the results in memory only: no file is written, no directory is created,
    /// locked or cleared, and `out_dir` is not used. The summary (and, through [`super::solve()`],
    /// the final state) is all the run leaves.
    pub in_memory: bool,
}

/// What a finished run reports.
#[derive(Clone, Debug)]
pub struct RunSummary {
    /// The scenario's name ([`Scenario::name`]).
    pub name: String,
    /// The stepper's description: method, levels, `dt` ([`Stepper::describe`]).
    pub stepper: String,
    /// Nodes of the finest level.
    pub nodes: usize,
    /// Elements of the finest level.
    pub elements: usize,
    /// Steps taken ([`Stepper::steps`]).
    pub steps: u64,
    /// Simulated time at the end (s).
    pub simulated: f64,
    /// Wall-clock time of the time loop, its samples and frames included (s).
    pub wall: f64,
    /// `steps / wall` (1/s).
    pub steps_per_second: f64,
    /// Force evaluations in finest-level units ([`Stepper::force_evaluations`]).
    pub force_evaluations: f64,
    /// How the run stopped.
    pub reason: StopReason,
    /// The last row of `measures.csv`.
    pub last: Sample,
    /// The output directory; `None` for a run in memory ([`RunOptions::in_memory`]).
    pub out_dir: Option<PathBuf>,
    /// The files written: `measures.csv`, the `.pvd` collection(s) and `nodal_stress.csv`;
    /// none for a run in memory.
    pub files: Vec<PathBuf>,
    /// Where T∞ came from (`[output] reference`); `None` without one.
    pub reference_note: Option<String>,
    /// The stepper's closing counters ([`Stepper::diagnostics`]) under their label
    /// ([`Stepper::diagnostics_label`]).
    pub diagnostics: Option<(&'static str, String)>,
    /// Rows written to `measures.csv`.
    pub rows: u64,
    /// The applied loads and body forces, `Σ_a V_a` (N): the reactions balance it at
    /// equilibrium ([`crate::metrics`]).
    pub applied: [f64; 3],
}

impl std::fmt::Display for RunSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "scenario        {}", self.name)?;
        writeln!(
            f,
            "mesh            {} nodes, {} elements",
            self.nodes, self.elements
        )?;
        writeln!(f, "integration     {}", self.stepper)?;
        writeln!(
            f,
            "stopped         {} at t = {:.6} s",
            self.reason, self.simulated
        )?;
        writeln!(f, "steps           {}", self.steps)?;
        writeln!(
            f,
            "force evals     {:.0} (finest-level units)",
            self.force_evaluations
        )?;
        writeln!(f, "wall time       {:.3} s", self.wall)?;
        writeln!(f, "steps/s         {:.1}", self.steps_per_second)?;
        writeln!(f, "kinetic energy  {:.4e} J", self.last.kinetic)?;
        writeln!(f, "residual        {:.4e} N", self.last.residual)?;
        writeln!(f, "max |u|         {:.4e} m", self.last.max_u)?;
        write_balance(f, &self.last, self.applied)?;
        if self.last.stress_err_max.is_finite() {
            writeln!(
                f,
                "|T - T_inf|     max {:.4e} Pa, mean {:.4e} Pa",
                self.last.stress_err_max, self.last.stress_err_mean
            )?;
        }
        if let Some(n) = &self.reference_note {
            writeln!(f, "reference       {n}")?;
        }
        if let Some((label, d)) = &self.diagnostics {
            writeln!(f, "{label:<16}{d}")?;
        }
        write_output(f, self.out_dir.as_deref())
    }
}

/// The summary lines of the reactions, the applied loads and the tools' contact force: what
/// balances at equilibrium.
pub(super) fn write_balance(
    f: &mut std::fmt::Formatter<'_>,
    last: &Sample,
    applied: [f64; 3],
) -> std::fmt::Result {
    let v = |x: [f64; 3]| format!("[{:.4e}, {:.4e}, {:.4e}] N", x[0], x[1], x[2]);
    writeln!(f, "reactions       fixed {}", v(last.reaction_fixed))?;
    writeln!(
        f,
        "                prescribed {}",
        v(last.reaction_prescribed)
    )?;
    writeln!(
        f,
        "applied loads   {} (loads, surface loads and body force)",
        v(applied)
    )?;
    if last.tool != [0.0; 3] || last.penetration > 0.0 {
        writeln!(
            f,
            "tool contact    {} (on the body), penetration {:.4e} m",
            v(last.tool),
            last.penetration
        )?;
    }
    Ok(())
}

/// One row per node in file order, the `node` column its file id ([`crate::model::Model::file_node`]).
/// A cut body (`copies`: each node of the scenario's mesh's copies, whose `u` and `t` these
/// are) has a row per copy, in the order of the copies, each with its node's id: the stress
/// of each lip averaged over its own side.
pub(super) fn write_nodal_stress(
    path: &Path,
    sc: &Scenario,
    u: &[f64],
    t: &[f64],
    copies: Option<&[Vec<u32>]>,
) -> Result<()> {
    let x0 = &sc.mesh.nodes;
    let at = mesh_index_of_file(sc.file_ids.as_deref(), x0.len());
    let rows: Vec<(usize, usize)> = at
        .iter()
        .enumerate()
        .flat_map(|(k, &o)| match copies {
            Some(c) => c[o].iter().map(|&a| (k, a as usize)).collect::<Vec<_>>(),
            None => vec![(k, o)],
        })
        .collect();
    write_atomic(path, |w| {
        writeln!(w, "node,x,y,z,ux,uy,uz,T00,T01,T02,T10,T11,T12,T20,T21,T22")?;
        for &(k, a) in &rows {
            let p = x0[at[k]];
            let id = sc.node_labels.as_ref().map_or(k as u64, |l| l[k]);
            write!(
                w,
                "{id},{:e},{:e},{:e},{:e},{:e},{:e}",
                p[0],
                p[1],
                p[2],
                u[3 * a],
                u[3 * a + 1],
                u[3 * a + 2]
            )?;
            for k in 0..9 {
                write!(w, ",{:e}", t[9 * a + k])?;
            }
            writeln!(w)?;
        }
        Ok(())
    })
}

/// Writes VTU frames (and the visual surface's VTP frames) and the PVD collections.
pub(super) struct Frames<'a> {
    /// `out/frames`; `None` for a run in memory, which writes no frame.
    dir: Option<PathBuf>,
    name: String,
    pvd: PvdWriter,
    count: usize,
    format: VtuFormat,
    stress: Vec<f64>,
    /// The tools' force on each node (N), the `contact_force` field of scenarios with tools.
    contact: Vec<f64>,
    /// Its friction part (N), the `friction_force` field of scenarios with friction.
    friction: Vec<f64>,
    /// The nominal contact pressure per node (Pa), the `contact_pressure` field, and the
    /// tributary boundary areas it divides by (computed at the first frame with tools).
    pressure: Vec<f64>,
    areas: Option<Vec<f64>>,
    /// Each point's node id in the mesh file, where the scenario renumbered the nodes.
    file_ids: Option<Vec<i64>>,
    surface: Option<SurfaceFrames<'a>>,
    /// The cut body's mesh and cell data, from the first cut on ([`crate::scenario::cuts`]).
    cut: Option<crate::scenario::cuts::CutFrame>,
}

impl<'a> Frames<'a> {
    pub(super) fn new(sc: &'a Scenario, out: &OutDir) -> Result<Self> {
        let (name, format) = (sc.name.as_str(), sc.output.vtu);
        let dir = match out.dir() {
            Some(out) => {
                let dir = out.join("frames");
                std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
                Some(dir)
            }
            None => None,
        };
        let surface = match (&sc.surface, out.dir()) {
            (Some(v), Some(out)) => Some(SurfaceFrames::new(v, &sc.mesh, out, name, format)?),
            _ => None,
        };
        // A run in memory allocates no frame buffers.
        let n = if dir.is_some() {
            sc.mesh.num_nodes()
        } else {
            0
        };
        Ok(Frames {
            surface,
            dir,
            name: name.to_string(),
            pvd: PvdWriter::new(out.path(&format!("{name}.pvd"))),
            count: 0,
            format,
            stress: vec![0.0; 9 * n],
            contact: vec![0.0; 3 * n],
            friction: vec![0.0; if sc.has_friction() { 3 * n } else { 0 }],
            pressure: vec![0.0; n],
            areas: None,
            file_ids: sc.output_node_ids(),
            cut: None,
        })
    }

    /// The body was cut: later frames carry the cut mesh (a series whose points and cells
    /// change, each frame file complete in itself, as ParaView reads a PVD collection); the
    /// visual surface, which would bridge the wound, is no longer written.
    pub(super) fn cut(&mut self, cut: crate::scenario::cuts::CutFrame) {
        let n = if self.dir.is_some() {
            cut.mesh.num_nodes()
        } else {
            0
        };
        self.stress = vec![0.0; 9 * n];
        self.contact = vec![0.0; 3 * n];
        if !self.friction.is_empty() {
            self.friction = vec![0.0; 3 * n];
        }
        self.pressure = vec![0.0; n];
        self.areas = None;
        self.file_ids.clone_from(&cut.file_ids);
        self.surface = None;
        self.cut = Some(cut);
    }
    pub(super) fn write(&mut self, sc: &Scenario, stepper: &mut dyn Stepper) -> Result<()> {
        let Some(dir) = &self.dir else {
            return Ok(());
        };
        let (sys, s) = stepper.finest();
        sys.force.nodal_stress(&s.u, &mut self.stress);
        let contact = sys.force.contact_forces(&s.u, &mut self.contact);
        let friction =
            !self.friction.is_empty() && sys.force.friction_forces(&s.u, &mut self.friction);
        let mesh = self.cut.as_ref().map_or(&sc.mesh, |c| &c.mesh);
        if contact {
            let areas = self
                .areas
                .get_or_insert_with(|| crate::contact::tributary_areas(mesh));
            crate::contact::nominal_pressure(&self.contact, areas, &mut self.pressure);
        }
        let file = format!("{}_{:06}.vtu", self.name, self.count);
        let mut fields = vec![
            Field {
                name: "displacement",
                data: FieldData::Vector(&s.u),
            },
            Field {
                name: "velocity",
                data: FieldData::Vector(&s.v),
            },
            Field {
                name: "stress",
                data: FieldData::Tensor(&self.stress),
            },
        ];
        if contact {
            fields.push(Field {
                name: "contact_force",
                data: FieldData::Vector(&self.contact),
            });
            fields.push(Field {
                name: "contact_pressure",
                data: FieldData::Scalar(&self.pressure),
            });
        }
        if friction {
            fields.push(Field {
                name: "friction_force",
                data: FieldData::Vector(&self.friction),
            });
        }
        if let Some(ids) = self.file_ids.as_deref() {
            fields.push(Field {
                name: "file_node_id",
                data: FieldData::Int(ids),
            });
        }
        let cells = match &self.cut {
            Some(c) => c.cell_fields(),
            None => sc.cell_fields(),
        };
        write_vtu_as(
            &dir.join(&file),
            mesh,
            &mesh.nodes,
            &fields,
            &cells,
            self.format,
        )?;
        self.pvd.add(s.t, &format!("frames/{file}"))?;
        if let Some(sf) = &mut self.surface {
            sf.write(s.t, self.count, &s.u)?;
        }
        self.count += 1;
        Ok(())
    }
}

/// Run a scenario with its own stepper.
pub fn run(sc: &Scenario, opts: RunOptions) -> Result<RunSummary> {
    let mut stepper = sc.stepper()?;
    run_with(sc, stepper.as_mut(), opts)
}

/// Run a scenario with a given stepper (single level or multigrid) whose finest level is the
/// scenario's mesh.
pub fn run_with(
    sc: &Scenario,
    stepper: &mut dyn Stepper,
    mut opts: RunOptions,
) -> Result<RunSummary> {
    let out = OutDir::lock(sc, &opts)?;
    let n = sc.mesh.num_nodes();
    // Read before the directory is cleared: it may be the last run's `nodal_stress.csv`.
    let (t_inf, reference_note) = match &sc.output.reference {
        Reference::File(p) => (
            Some(read_nodal_stress(p, sc)?),
            Some(format!("T_inf from {}", p.display())),
        ),
        _ => (None, None),
    };
    out.prepare(&sc.name)?;
    let (t_inf, reference_note) = match &sc.output.reference {
        Reference::Auto => {
            let (t, note) = sc.steady_reference()?;
            (Some(t), Some(note))
        }
        _ => (t_inf, reference_note),
    };
    let mut meter = Meter::new(n, t_inf);
    let mut frames = Frames::new(sc, &out)?;
    let mut cuts = crate::scenario::cuts::RunCuts::new(sc);
    let mut rows = out.measures(sc.has_friction())?;
    let start = Instant::now();
    let dt = stepper.dt();
    let (t_end, steady) = match sc.run.stop {
        StopRule::Duration(d) => (d, None),
        StopRule::Steady {
            kinetic_tol,
            residual_tol,
            max,
            stagnation,
        } => (max, Some((kinetic_tol, residual_tol, stagnation))),
    };
    let total_steps = (t_end / dt).ceil() as u64;
    let frame_every = if sc.output.frame_interval > 0.0 {
        ((sc.output.frame_interval / dt).round() as u64).max(1)
    } else {
        u64::MAX
    };
    let sample = |stepper: &mut dyn Stepper, meter: &mut Meter| {
        let steps = stepper.steps();
        let evals = stepper.force_evaluations();
        let (sys, s) = stepper.finest();
        let mut row = meter.sample(sys, s, steps);
        row.force_evals = evals;
        row.wall = start.elapsed().as_secs_f64();
        row
    };
    let interrupted = || {
        opts.stop
            .is_some_and(|f| f.load(std::sync::atomic::Ordering::Relaxed))
    };
    let mut last = sample(stepper, &mut meter);
    rows.push(&last)?;
    frames.write(sc, stepper)?;
    rows.flush()?;
    let mut framed = stepper.steps();
    let (mut ke_peak, mut res_peak) = (last.kinetic, last.residual);
    let (mut best, mut since_best) = (f64::INFINITY, 0u64);
    let motion_end = sc.motion_end();
    let mut reason = StopReason::Duration;
    let mut result = Ok(());
    while stepper.steps() < total_steps {
        if interrupted() {
            reason = StopReason::Interrupted;
            break;
        }
        match cuts.make_due(sc, stepper.state().t, 1e-9 * dt, stepper) {
            Ok(true) => {
                let cut =
                    crate::scenario::cuts::CutFrame::of(sc, cuts.level0().expect("a cut was made"));
                // |T − T∞| compares with the uncut body's nodes: not measured after a cut.
                meter = Meter::new(cut.mesh.num_nodes(), None);
                frames.cut(cut);
            }
            Ok(false) => {}
            Err(e) => {
                result = Err(e);
                break;
            }
        }
        if let Err(mut d) = stepper.advance() {
            if frames.cut.is_none() {
                sc.locate(&mut d);
            }
            result = Err(Error::Diverged(d));
            break;
        }
        let k = stepper.steps();
        let end = k == total_steps;
        if k.is_multiple_of(sc.output.csv_every) || end {
            let row = sample(stepper, &mut meter);
            ke_peak = ke_peak.max(row.kinetic);
            res_peak = res_peak.max(row.residual);
            rows.push(&row)?;
            last = row;
            if let Some(p) = opts.progress.as_mut() {
                p(k as f64 / total_steps as f64, &row);
            }
            if let Some((kt, rt, stagnation)) = steady {
                if row.time >= motion_end {
                    let m = (row.kinetic / (kt * ke_peak)).max(row.residual / (rt * res_peak));
                    if m <= 1.0 {
                        reason = StopReason::Steady;
                        break;
                    }
                    if m < (1.0 - 1e-3) * best {
                        (best, since_best) = (m, 0);
                    } else {
                        since_best += 1;
                        if stagnation > 0 && since_best >= stagnation {
                            reason = StopReason::Stagnated(stagnation);
                            break;
                        }
                    }
                }
            }
        }
        if k.is_multiple_of(frame_every) || end {
            frames.write(sc, stepper)?;
            rows.flush()?;
            framed = k;
        }
    }
    if steady.is_some() && reason == StopReason::Duration && result.is_ok() {
        reason = StopReason::NotSteadyBeforeCap;
    }
    let k = stepper.steps();
    if result.is_ok() {
        if last.step != k {
            last = sample(stepper, &mut meter);
            rows.push(&last)?;
        }
        if framed != k {
            frames.write(sc, stepper)?;
        }
    }
    rows.flush()?;
    let wall = start.elapsed().as_secs_f64();
    result?;
    let stress_path = out.path("nodal_stress.csv");
    let copies = frames.cut.as_ref().map(|c| &c.copies[..]);
    let applied = {
        let (sys, s) = stepper.finest();
        if out.dir().is_some() {
            let mut t = vec![0.0; s.u.len() * 3];
            sys.force.nodal_stress(&s.u, &mut t);
            write_nodal_stress(&stress_path, sc, &s.u, &t, copies)?;
        }
        let mut v = sys.force.load_report(&s.u).applied;
        for (i, f) in sys.f_ext.iter().enumerate() {
            v[i % 3] += f;
        }
        v
    };
    let summary = RunSummary {
        name: sc.name.clone(),
        stepper: stepper.describe(),
        nodes: frames.cut.as_ref().map_or(n, |c| c.mesh.num_nodes()),
        elements: frames
            .cut
            .as_ref()
            .map_or(sc.mesh.num_elements(), |c| c.mesh.num_elements()),
        steps: stepper.steps(),
        simulated: last.time,
        wall,
        steps_per_second: stepper.steps() as f64 / wall.max(1e-9),
        force_evaluations: stepper.force_evaluations(),
        reason,
        last,
        out_dir: out.dir().map(Path::to_path_buf),
        files: match out.dir() {
            Some(_) => {
                let mut f = vec![
                    rows.path().to_path_buf(),
                    frames.pvd.path().to_path_buf(),
                    stress_path,
                ];
                f.extend(frames.surface.as_ref().map(|s| s.pvd_path().to_path_buf()));
                f
            }
            None => Vec::new(),
        },
        reference_note,
        diagnostics: stepper
            .diagnostics()
            .map(|d| (stepper.diagnostics_label(), d)),
        rows: rows.rows(),
        applied,
    };
    let text = summary.to_string();
    out.write("summary.txt", |w| writeln!(w, "{text}"))?;
    Ok(summary)
}
