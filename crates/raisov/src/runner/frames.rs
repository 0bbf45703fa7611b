//! Interactive mode: a fixed budget per frame while the grasp moves (surgical interaction is
//! quasi-static: the instrument moves, the tissue follows).
//!
//! Frame `k = 1..N` stands for path time `t_k = k / fps`, `N = ⌈duration · fps − 10⁻⁹⌉` (a
//! duration written as a whole number of frames over `fps` is that number). At each frame
//! every `[[displace]]` node is set to its path position `d(t_k)` and held there (the
//! instrument is sampled once per frame, as a haptic or visual loop does), then the stepper
//! gets its budget: `cycles` steps (single level) or V-cycles (multigrid), or steps until
//! `budget_ms` of wall time have passed since the frame began (at least one, fewer where the
//! frame solver has settled: [`crate::sim::Budget::Millis`]; the count per frame then depends
//! on the machine's speed, and `frames.csv` records it: `cycles` is the reproducible choice). Every frame is
//! stepped through a [`Simulation`](crate::sim::Simulation), as a host program or the viewer
//! steps its own ([`super::Replay`], [`crate::sim::frame`]), with the grasps, pins and cuts the
//! scenario takes during the run, if any ([`crate::scenario::grasps`]). The *lag* of the
//! frame is the distance to the static solution `u*_k` with the same constraints (the
//! grasps, pins and springs of the frame included), `R(u*_k) = V`, by the static solve's own
//! assembled Newton solver (Newton-multigrid over the `[multigrid]` levels, else direct
//! Newton; Newton-Krylov where the model has no element tangent), warm-started from
//! `u*_{k−1}`, to `max_a |r_a| ≤ reference_tol · F` (default 1e-8; `F` the frame's force
//! scale: the largest nodal load, spring pull, or out-of-balance force from rest or at the
//! start). With a rate-dependent law the reference holds the stepper's internal variables at
//! the frame's end (the equilibrium of the tissue's current relaxation, not the fully relaxed
//! one):
//!
//! ```text
//! lag_max = max_a |u_a − u*_a|,   lag_rms = sqrt(mean_a |u_a − u*_a|²),   a free nodes,
//! lag_rel = lag_max / max_a |u*_a|.
//! ```
//!
//! The frame rate counts the stepper's own wall time only (not the reference solve nor the
//! output): `fps = frames / Σ frame wall`. Each frame's force evaluations are counted in
//! units of one finest-level evaluation ([`Stepper::force_evaluations`]), a count any
//! machine reproduces beside the wall time. The run *keeps up with real time* when that rate
//! is at least `fps` and every frame's relative lag `lag_rel` is within `lag_tol` (default
//! 5 %): fast frames far from the static solution do not count. A reference solve that fails
//! (an inverted element, or a residual above `reference_tol` times the larger of the external
//! load and the largest starting residual of the run's reference solves) is reported with its frame;
//! that frame's lag is not measured (empty in `frames.csv`) and the summary says so instead
//! of quoting a lag against it; without a reference the summary does not claim to keep up.
//!
//! With `predictor = true` a frame whose prescribed displacements or grasps move starts from
//! `u + s Δu`, `Δu` the last frame's change of level 0's displacements at the free nodes, `s`
//! how much of the last frame's path move this frame repeats, at most the path's largest move
//! over `max_a |Δu_a|` ([`crate::sim::frame`], [`crate::integrate::prediction`]); only FAS
//! with its static smoother and the frame solver take a prediction ([`Stepper::predict`]),
//! other steppers run as without it. A scenario that takes nothing during the run keeps the
//! scenario's kinetic-energy ceiling, and a diverging step ends its run with
//! [`Error::Diverged`]; one with grasps, pins or cuts rejects and retries a diverging frame
//! instead, as the viewer does ([`crate::sim::frame`]).
//!
//! The output directory is locked and cleared of the previous run's results as in
//! [`super::dynamic`]; `frames.csv` is streamed (one row per frame, flushed per frame, ending
//! at a row boundary whatever fails: [`crate::io::RowFile`]) and the summary keeps running totals only, so memory does not
//! grow with the number of frames. [`RunOptions::stop`] ends the run after the current frame
//! with a summary that says it was interrupted. Under the output directory:
//! `frames.csv`, `NAME.pvd` + `frames/*.vtu` (reference points with
//! fields `displacement`, `static` and `lag`, and `file_node_id` where a node's id in the mesh
//! file differs from its position; format per `[output] vtu`), with `[mesh] surface` also
//! `NAME_surface.pvd` + `frames/NAME_surface_*.vtp` (the surface with its interpolated
//! `displacement`, see [`crate::scenario::surface`]), `summary.txt`.

use super::outputs::{write_output, OutDir};
use super::statics::prescribed_force_scale;
use super::RunOptions;
use crate::error::{Error, Result};
use crate::integrate::System;
use crate::integrate::{hold, Stepper};
use crate::io::{write_vtu_as, Field, FieldData, PvdWriter, RowFile};
use crate::scenario::interactive::{Budget, Interactive};
use crate::scenario::{Scenario, StopRule};
use crate::statics::newton::{
    coarse_level, fixed_dof, solve_system_matrix_free, DirectNewton, DirectNewtonError,
    DirectNewtonParams, MatrixFreeCg, MultigridPcg,
};
use crate::statics::relax::fictitious_mass;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// One frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameRow {
    /// The frame's number k, from 1.
    pub frame: usize,
    /// Path time `t_k` (s).
    pub time: f64,
    /// Steps or cycles run in this frame.
    pub steps: u64,
    /// Wall time of those steps (s).
    pub wall: f64,
    /// Residual norm `|V − R(u)|` after the frame (N).
    pub residual: f64,
    /// Largest |u| (m).
    pub max_u: f64,
    /// Lag to the static solution: largest and RMS nodal distance (m); NaN without reference.
    pub lag_max: f64,
    /// `lag_rms = sqrt(mean_a |u_a − u*_a|²)` over the free nodes (m); NaN without reference.
    pub lag_rms: f64,
    /// Largest |u*| of the static solution (m).
    pub static_max_u: f64,
    /// Force evaluations of this frame, in finest-level units ([`Stepper::force_evaluations`]).
    pub force_evals: f64,
}

impl FrameRow {
    /// `lag_max / max|u*|`.
    pub fn lag_rel(&self) -> f64 {
        self.lag_max / self.static_max_u.max(f64::MIN_POSITIVE)
    }
}

/// What an interactive run reports: running totals over the frames, not the frames
/// themselves (those are in `frames.csv`).
#[derive(Clone, Debug)]
pub struct InteractiveSummary {
    /// The scenario's name ([`Scenario::name`]).
    pub name: String,
    /// The stepper's description: method, levels, `dt` ([`Stepper::describe`]).
    pub stepper: String,
    /// Nodes of the finest level.
    pub nodes: usize,
    /// The resolved `[interactive]` settings the run used.
    pub settings: Interactive,
    /// Frames run.
    pub frames: usize,
    /// Frames the path asked for.
    pub frames_planned: usize,
    /// Σ frame wall time of the stepper (s).
    pub wall: f64,
    /// The longest frame's wall time (s).
    pub wall_max: f64,
    /// Σ force evaluations of the frames, in finest-level units.
    pub force_evals: f64,
    /// Over the frames with a reference: the count, Σ lag_max, max lag_max, max lag_rel.
    pub lag_frames: usize,
    /// Σ lag_max over those frames (m).
    pub lag_sum: f64,
    /// The largest lag_max of those frames (m).
    pub lag_max: f64,
    /// The largest lag_rel of those frames (`lag_max / max|u*|`).
    pub lag_rel_max: f64,
    /// Σ lag_rel over those frames.
    pub lag_rel_sum: f64,
    /// The last frame.
    pub last: Option<FrameRow>,
    /// Frames whose reference solve failed, and what the first failure was.
    pub reference_failures: usize,
    /// The first reference solve's failure, with its frame; `None` if none failed.
    pub first_failure: Option<String>,
    /// [`RunOptions::stop`] ended the run early.
    pub interrupted: bool,
    /// With grasps or pins taken during the run ([`crate::scenario::grasps`]): frames rejected (the
    /// state before each kept).
    pub rejected_frames: usize,
    /// The first rejection, with its frame; `None` if none was rejected.
    pub first_rejection: Option<String>,
    /// The output directory; `None` for a run in memory ([`RunOptions::in_memory`]).
    pub out_dir: Option<PathBuf>,
    /// The reference's solver: `"Newton-multigrid"`, `"direct Newton"` or
    /// `"Newton-Krylov"` (module docs); empty without a reference.
    pub reference_solver: &'static str,
}

impl InteractiveSummary {
    /// Frames per second of stepper wall time.
    pub fn fps(&self) -> f64 {
        self.frames as f64 / self.wall.max(1e-12)
    }
    /// Mean `lag_rel` over the frames with a reference; NaN where no frame has one.
    pub fn lag_rel_mean(&self) -> f64 {
        if self.lag_frames == 0 {
            return f64::NAN;
        }
        self.lag_rel_sum / self.lag_frames as f64
    }
    /// Mean force evaluations per frame (finest-level units).
    pub fn evals_per_frame(&self) -> f64 {
        self.force_evals / self.frames.max(1) as f64
    }
    /// Mean and largest `lag_max` over the frames with a reference (m), and the largest
    /// relative lag; NaN where no frame has one.
    pub fn lag(&self) -> (f64, f64, f64) {
        if self.lag_frames == 0 {
            return (f64::NAN, f64::NAN, f64::NAN);
        }
        (
            self.lag_sum / self.lag_frames as f64,
            self.lag_max,
            self.lag_rel_max,
        )
    }
    /// Whether the run kept up with real time: fast enough, every frame's lag measured and
    /// within [`Interactive::lag_tol`].
    pub fn keeps_up(&self) -> bool {
        self.settings.reference
            && self.reference_failures == 0
            && self.lag_frames == self.frames
            && self.frames > 0
            && self.fps() >= self.settings.fps
            && self.lag_rel_max <= self.settings.lag_tol
    }
    fn add(&mut self, row: &FrameRow) {
        self.frames += 1;
        self.wall += row.wall;
        self.wall_max = self.wall_max.max(row.wall);
        self.force_evals += row.force_evals;
        if row.lag_max.is_finite() {
            self.lag_frames += 1;
            self.lag_sum += row.lag_max;
            self.lag_max = self.lag_max.max(row.lag_max);
            self.lag_rel_max = self.lag_rel_max.max(row.lag_rel());
            self.lag_rel_sum += row.lag_rel();
        }
        self.last = Some(*row);
    }
}

impl std::fmt::Display for InteractiveSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let s = &self.settings;
        writeln!(f, "scenario        {} (interactive)", self.name)?;
        writeln!(f, "mesh            {} nodes", self.nodes)?;
        writeln!(f, "integration     {}", self.stepper)?;
        let budget = match s.budget {
            Budget::Cycles(c) => format!("{c} steps/cycles per frame"),
            Budget::Wall(w) => format!("{:.1} ms of wall time per frame", w * 1e3),
        };
        writeln!(
            f,
            "frames          {} of {} at {} fps of path time, {budget}",
            self.frames, self.frames_planned, s.fps
        )?;
        if self.interrupted {
            writeln!(
                f,
                "stopped         interrupted (by a signal) after frame {}",
                self.frames
            )?;
        }
        if self.rejected_frames > 0 {
            writeln!(
                f,
                "rejected        {} frames, each kept at the state before it; first: {}",
                self.rejected_frames,
                self.first_rejection.as_deref().unwrap_or("?")
            )?;
        }
        let fps = self.fps();
        let verdict = if !s.reference {
            "lag not measured (reference = \"none\"): cannot tell whether it keeps up".to_string()
        } else if self.reference_failures > 0 {
            "reference solve failed: cannot tell whether it keeps up".to_string()
        } else if self.keeps_up() {
            format!(
                "keeps up with real time: at least {} fps with every lag within {:.1} % of max |u*|",
                s.fps,
                100.0 * s.lag_tol
            )
        } else if fps < s.fps {
            format!("slower than real time ({} fps)", s.fps)
        } else {
            format!(
                "fast enough, but lags more than {:.1} % of max |u*|: does not keep up",
                100.0 * s.lag_tol
            )
        };
        writeln!(
            f,
            "frame rate      {fps:.1} fps of stepper wall time ({verdict})"
        )?;
        if self.frames > 0 {
            writeln!(
                f,
                "work            {:.1} force evaluations per frame (finest-level units); slowest frame {:.1} ms",
                self.evals_per_frame(),
                1e3 * self.wall_max
            )?;
        }
        if s.reference {
            writeln!(
                f,
                "reference       {}, each frame to {:.0e} of its force scale",
                self.reference_solver, s.reference_tol
            )?;
            if self.reference_failures > 0 {
                writeln!(
                    f,
                    "reference       FAILED in {} of {} frames; first: {}",
                    self.reference_failures,
                    self.frames,
                    self.first_failure.as_deref().unwrap_or("?")
                )?;
            }
            if self.lag_frames > 0 {
                let (mean, max, rel) = self.lag();
                writeln!(
                    f,
                    "lag             mean {:.3e} m, max {:.3e} m over {} frames with a reference; relative to max |u*|: mean {:.2} %, worst {:.2} %",
                    mean,
                    max,
                    self.lag_frames,
                    100.0 * self.lag_rel_mean(),
                    100.0 * rel
                )?;
            }
            if let Some(last) = self.last.filter(|l| l.lag_max.is_finite()) {
                writeln!(
                    f,
                    "last frame      lag {:.3e} m ({:.2} % of max |u*| = {:.3e} m)",
                    last.lag_max,
                    100.0 * last.lag_rel(),
                    last.static_max_u
                )?;
            }
        }
        write_output(f, self.out_dir.as_deref())
    }
}

/// The error of an interactive run of a scenario without `[interactive]`.
pub(super) fn no_interactive(sc: &Scenario) -> Error {
    Error::Scenario {
        path: sc.path.clone(),
        line: None,
        msg: "no [interactive] section".into(),
    }
}

/// The path duration: `[run] duration` (or the `steady` cap).
fn duration(sc: &Scenario) -> f64 {
    match sc.run.stop {
        StopRule::Duration(d) => d,
        StopRule::Steady { max, .. } => max,
    }
}

/// What steps the frames of an interactive run: a [`super::Replay`] of the scenario through a
/// [`Simulation`](crate::sim::Simulation) ([`super::run_interactive`]), or another stepper of
/// the same frames (a benchmark's peer).
pub trait FrameStepper {
    /// The stepper: after each frame the run reads its finest level, steps and force
    /// evaluations.
    fn stepper(&mut self) -> &mut dyn Stepper;
    /// Frame `k` at path time `t`: the displacements prescribed from `t = 0` held at
    /// `values` ([`Stepper::hold_prescribed`]), then the frame's budget. `Ok(None)`: the frame
    /// was accepted; `Ok(Some(why))`: rejected, the state before it kept, the run goes on;
    /// `Err`: the run ends ([`Error::Diverged`] is given the frame's time and the node's
    /// place by the run).
    fn frame(&mut self, k: usize, t: f64, values: &[[f64; 3]]) -> Result<Option<String>>;
    /// Level 0 as cut ([`crate::scenario::cuts`]), once a cut split an element; `None` (the default)
    /// for a body never cut.
    fn cut_mesh(&self) -> Option<&crate::mesh::cut::CutMesh> {
        None
    }
}

/// Run the scenario interactively, its frames stepped by `frames` ([`FrameStepper`]; whose
/// finest level is the scenario's mesh). Errors: the scenario has no `[interactive]`
/// section, an error of `frames` (a diverging stepper, with step and element; a grasp or
/// pin that finds no free node), a reference solve that inverts an element, or an output
/// file that cannot be written.
pub fn run_frames(
    sc: &Scenario,
    frames: &mut dyn FrameStepper,
    mut opts: RunOptions,
) -> Result<InteractiveSummary> {
    let Some(settings) = sc.interactive else {
        return Err(no_interactive(sc));
    };
    let grasps = !sc.grasps.is_empty() || !sc.pins.is_empty();
    let out = OutDir::lock(sc, &opts)?;
    out.prepare(&sc.name)?;
    let mut n = sc.mesh.num_nodes();
    // The cut body's mesh and cell data, from the first cut on ([`crate::scenario::cuts`]).
    let mut cut: Option<crate::scenario::cuts::CutFrame> = None;
    // (A duration written as a whole number of frames over fps is that number of frames.)
    let frames_n = (duration(sc) * settings.fps - 1e-9).ceil().max(1.0) as usize;
    // The reference system, its solver and solution.
    let mut ref_sys = sc.build_system()?;
    let mut reference = if settings.reference {
        Some(Reference::new(sc, &ref_sys)?)
    } else {
        None
    };
    // A rate-dependent law's reference takes the stepper's internal variables each frame.
    let rate_dependent = matches!(sc.material, crate::material::Material::NeoHookeanVisco(_));
    let mut history = Vec::new();
    // The largest starting residual of the run's reference solves (N; the solver's norm).
    let mut ref_scale = 0.0f64;
    let mut u_star = vec![0.0; 3 * n];
    let mut r = vec![0.0; 3 * n];
    let mut values = vec![[0.0; 3]; sc.prescribed.len()];
    let mut free: Vec<bool> = (0..n)
        .map(|a| !ref_sys.constraints.is_constrained(a))
        .collect();
    let mut summary = InteractiveSummary {
        name: sc.name.clone(),
        stepper: frames.stepper().describe(),
        nodes: n,
        settings,
        frames: 0,
        frames_planned: frames_n,
        wall: 0.0,
        wall_max: 0.0,
        force_evals: 0.0,
        lag_frames: 0,
        lag_sum: 0.0,
        lag_max: 0.0,
        lag_rel_max: 0.0,
        lag_rel_sum: 0.0,
        last: None,
        reference_failures: 0,
        first_failure: None,
        interrupted: false,
        rejected_frames: 0,
        first_rejection: None,
        out_dir: out.dir().map(Path::to_path_buf),
        reference_solver: reference.as_ref().map_or("", Reference::name),
    };
    let mut rows = FrameRows::create(&out.path("frames.csv"), out.dir().is_some())?;
    // `out/frames`; none for a run in memory, which writes no frame.
    let frames_dir = match out.dir() {
        Some(d) => {
            let f = d.join("frames");
            std::fs::create_dir_all(&f).map_err(|e| Error::io(&f, e))?;
            Some(f)
        }
        None => None,
    };
    let mut surface_frames = match (&sc.surface, out.dir()) {
        (Some(v), Some(d)) => Some(crate::scenario::surface::SurfaceFrames::new(
            v,
            &sc.mesh,
            d,
            &sc.name,
            sc.output.vtu,
        )?),
        _ => None,
    };
    let mut pvd = PvdWriter::new(out.path(&format!("{}.pvd", sc.name)));
    let mut lag = vec![0.0; 3 * n];
    let mut file_node_id: Option<Vec<i64>> = sc.output_node_ids();
    for k in 1..=frames_n {
        if opts
            .stop
            .is_some_and(|f| f.load(std::sync::atomic::Ordering::Relaxed))
        {
            summary.interrupted = true;
            break;
        }
        let t = k as f64 / settings.fps;
        for (v, (_, m)) in values.iter_mut().zip(&sc.prescribed) {
            *v = m.displacement(t);
        }
        let before = frames.stepper().steps();
        let evals_before = frames.stepper().force_evaluations();
        let start = Instant::now();
        match frames.frame(k, t, &values) {
            Ok(None) => {}
            Ok(Some(why)) => {
                summary.rejected_frames += 1;
                summary
                    .first_rejection
                    .get_or_insert_with(|| format!("frame {k} (t = {t:.4} s): {why}"));
            }
            Err(e) => {
                rows.flush()?;
                return Err(match e {
                    Error::Diverged(mut d) => {
                        sc.locate(&mut d);
                        // The stepper's own clock counts its pseudo-time steps; the user's
                        // clock is the path time of the frame.
                        d.time = t;
                        Error::Diverged(d)
                    }
                    e => e,
                });
            }
        }
        let wall = start.elapsed().as_secs_f64();
        let recut = frames.cut_mesh().and_then(|cm| {
            let same = cut.as_ref().is_some_and(|c| {
                c.mesh.num_nodes() == cm.mesh().num_nodes()
                    && c.mesh.num_elements() == cm.mesh().num_elements()
            });
            (!same).then(|| crate::scenario::cuts::CutFrame::of(sc, cm))
        });
        if let Some(c) = recut {
            // The body was cut: the frames carry its mesh from now on. The static reference
            // is the uncut body's, so the lag is not measured after a cut.
            n = c.mesh.num_nodes();
            reference = None;
            u_star = vec![0.0; 3 * n];
            r = vec![0.0; 3 * n];
            lag = vec![0.0; 3 * n];
            free = vec![true; n];
            file_node_id.clone_from(&c.file_ids);
            surface_frames = None;
            cut = Some(c);
        }
        let stepper = frames.stepper();
        let total_steps = stepper.steps();
        let frame_evals = stepper.force_evaluations() - evals_before;
        let mut reference_ok = reference.is_some();
        if let Some(reference) = reference.as_mut() {
            if rate_dependent {
                // The equilibrium of the frame's internal state: the stepper's history, held
                // (Δt = 0: the viscous stresses as accepted at the frame's end).
                let (sys, _) = stepper.finest();
                history.clear();
                sys.force.save_history(&mut history);
                ref_sys.force.load_history(&history);
                ref_sys.force.set_step(0.0);
            }
            if grasps {
                // The constraints and springs of the frame, grasps and pins included.
                let (sys, _) = stepper.finest();
                ref_sys.constraints.clone_from(&sys.constraints);
                ref_sys.springs.clone_from(&sys.springs);
                for (a, f) in free.iter_mut().enumerate() {
                    *f = !ref_sys.constraints.is_constrained(a);
                }
            }
            hold(&mut ref_sys.constraints, &values);
            let solved = reference.solve(&mut ref_sys, t, &mut u_star, settings.reference_tol);
            if let Ok(st) = &solved {
                ref_scale = ref_scale.max(st.initial_residual);
            }
            let failure = match solved {
                // Converged by its own rule, or within `reference_tol` of the largest start
                // of the run: a frame whose static problem did not change starts converged,
                // and a rule relative to its own start would ask for round-off.
                Ok(st) if st.converged || st.residual <= settings.reference_tol * ref_scale => None,
                Ok(st) => Some(format!(
                    "frame {k} (t = {t:.4} s): the static solve ({}) stopped at a residual of \
                     {:.2e} N after {} Newton steps (asked: {:.2e} N)",
                    reference.name(),
                    st.residual,
                    st.newton_steps,
                    st.target
                )),
                Err(why) => Some(format!("frame {k} (t = {t:.4} s): the static solve {why}")),
            };
            if let Some(msg) = failure {
                reference_ok = false;
                summary.reference_failures += 1;
                summary.first_failure.get_or_insert(msg);
            }
        }
        let (sys, s) = stepper.finest();
        let residual = sys.residual(&s.u, &mut r).unwrap_or(f64::NAN);
        let (mut lag_max, mut lag_sq, mut count, mut max_u, mut static_max_u) =
            (0.0f64, 0.0, 0usize, 0.0f64, 0.0f64);
        for a in 0..n {
            let u = [s.u[3 * a], s.u[3 * a + 1], s.u[3 * a + 2]];
            max_u = max_u.max(crate::mesh::norm(u));
            let us = [u_star[3 * a], u_star[3 * a + 1], u_star[3 * a + 2]];
            static_max_u = static_max_u.max(crate::mesh::norm(us));
            let d = crate::mesh::sub(u, us);
            lag[3 * a..3 * a + 3].copy_from_slice(&d);
            if free[a] {
                let dn = crate::mesh::norm(d);
                lag_max = lag_max.max(dn);
                lag_sq += dn * dn;
                count += 1;
            }
        }
        let (lag_max, lag_rms) = if reference_ok {
            (lag_max, (lag_sq / count.max(1) as f64).sqrt())
        } else {
            (f64::NAN, f64::NAN)
        };
        let row = FrameRow {
            frame: k,
            time: t,
            steps: total_steps - before,
            wall,
            residual,
            max_u,
            lag_max,
            lag_rms,
            static_max_u: if reference_ok { static_max_u } else { f64::NAN },
            force_evals: frame_evals,
        };
        rows.push(&row)?;
        summary.add(&row);
        if let Some(frames_dir) = &frames_dir {
            let file = format!("{}_{:06}.vtu", sc.name, k);
            let mut fields = vec![Field {
                name: "displacement",
                data: FieldData::Vector(&s.u),
            }];
            if reference_ok {
                fields.push(Field {
                    name: "static",
                    data: FieldData::Vector(&u_star),
                });
                fields.push(Field {
                    name: "lag",
                    data: FieldData::Vector(&lag),
                });
            }
            if let Some(ids) = &file_node_id {
                fields.push(Field {
                    name: "file_node_id",
                    data: FieldData::Int(ids),
                });
            }
            let (mesh, cells) = match &cut {
                Some(c) => (&c.mesh, c.cell_fields()),
                None => (&sc.mesh, sc.cell_fields()),
            };
            write_vtu_as(
                &frames_dir.join(&file),
                mesh,
                &mesh.nodes,
                &fields,
                &cells,
                sc.output.vtu,
            )?;
            pvd.add(t, &format!("frames/{file}"))?;
            if let Some(sf) = &mut surface_frames {
                sf.write(t, k, &s.u)?;
            }
        }
        rows.flush()?;
        if let Some(p) = opts.progress.as_mut() {
            let sample = crate::metrics::Sample {
                step: total_steps,
                time: t,
                kinetic: 0.0,
                residual,
                max_u,
                stress_err_max: f64::NAN,
                stress_err_mean: f64::NAN,
                force_evals: stepper.force_evaluations(),
                wall,
                reaction_fixed: [f64::NAN; 3],
                reaction_prescribed: [f64::NAN; 3],
                tool: [f64::NAN; 3],
                penetration: f64::NAN,
                friction: [f64::NAN; 3],
            };
            p(k as f64 / frames_n as f64, &sample);
        }
    }
    rows.flush()?;
    let text = summary.to_string();
    out.write("summary.txt", |w| writeln!(w, "{text}"))?;
    Ok(summary)
}

/// The static solve each frame's lag is measured against (module docs): the assembled Newton
/// solver of a static solve's `solver = "auto"` — Newton-multigrid over level 0 and the coarse
/// level [`coarse_level`] picks where `[multigrid]` gives one, else sparse Cholesky with its
/// factor kept as the conjugate-gradient preconditioner — warm-started from the last frame's
/// solution, to `max_a |r_a| ≤ reference_tol · F` with `F` the frame's force scale
/// ([`problem_scale`]: the largest nodal load, out-of-balance force from rest or at the
/// start, spring pull; 10⁻¹⁴ N where there is none), at most 50 Newton steps;
/// matrix-free CG under the same driver and rule where the force model has no element
/// tangent.
enum Reference {
    Assembled {
        /// Built for the constrained dofs `mask`; rebuilt when a grasp or pin changes them.
        newton: Option<(Box<DirectNewton>, Vec<bool>)>,
        /// Level 0's nodes in the coarse level: the Galerkin V-cycle's; empty: Cholesky.
        down: Vec<crate::hierarchy::Transfer>,
        smoother: crate::statics::newton::Smoother,
    },
    /// A force model without element tangents: matrix-free CG preconditioned by `diag`.
    MatrixFree { diag: Vec<f64> },
}

/// What a reference solve reports, in its solver's norm (N).
struct ReferenceSolve {
    converged: bool,
    residual: f64,
    initial_residual: f64,
    target: f64,
    newton_steps: usize,
}

/// The force scale of a frame's reference solve (N): the largest of the nodal external load,
/// the out-of-balance force from rest (the motions at `t`, the model's pressures and tools),
/// the springs' pull at rest `k |d|` and the out-of-balance force at the warm start `u` with
/// the motions at `t` (what the frame changed). Zero only for a body with nothing on it
/// that starts at rest.
fn problem_scale(sys: &mut System, t: f64, u: &[f64]) -> f64 {
    let n = u.len();
    let node = |x: &[f64], a: usize| {
        (x[3 * a].powi(2) + x[3 * a + 1].powi(2) + x[3 * a + 2].powi(2)).sqrt()
    };
    let loads = (0..n / 3).map(|a| node(&sys.f_ext, a)).fold(0.0, f64::max);
    let from_rest = prescribed_force_scale(sys, t, &vec![0.0; n]);
    let springs = sys
        .springs
        .iter()
        .map(|s| (s.k * (s.d[0].powi(2) + s.d[1].powi(2) + s.d[2].powi(2)).sqrt()).min(s.limit))
        .fold(0.0, f64::max);
    let (mut g, mut v, mut r) = (u.to_vec(), vec![0.0; n], vec![0.0; n]);
    sys.constraints.impose(t, &mut g, &mut v);
    sys.force.set_time(t);
    let start = match sys.residual(&g, &mut r) {
        Ok(_) => (0..n / 3).map(|a| node(&r, a)).fold(0.0, f64::max),
        Err(_) => 0.0,
    };
    loads.max(from_rest).max(springs).max(start)
}

/// A frame whose force scale ([`problem_scale`]) is below this (N) has nothing acting on
/// the body: its residual left at rest is round-off, and the reference solve asks for an
/// absolute 1e-14 N instead of a share of it.
const UNLOADED: f64 = 1e-12;

/// Factorisation reuses of the direct reference solve before it refactors (as the static
/// solve's `"direct"`).
const REFERENCE_PCG_MAX: usize = 20;

/// Newton steps at most per reference solve (from the last frame's solution a solve takes a
/// few).
const REFERENCE_MAX_NEWTON: usize = 50;

impl Reference {
    fn new(sc: &Scenario, sys: &System) -> Result<Reference> {
        if sys.force.tangent_elements().is_none() {
            let diag = fictitious_mass(&sc.mesh, &sys.mass, 1.0);
            return Ok(Reference::MatrixFree { diag });
        }
        let mut down = Vec::new();
        if sc.multigrid.is_some() {
            if let Some((_, coarse)) = sc.pick_level(coarse_level)?.chosen {
                down.push(crate::hierarchy::Transfer::build(&sc.mesh.nodes, &coarse)?);
            }
        }
        Ok(Reference::Assembled {
            newton: None,
            down,
            smoother: crate::scenario::StaticSolve::default_smoother(sc.mesh.kind),
        })
    }

    fn name(&self) -> &'static str {
        match self {
            Reference::Assembled { down, .. } if down.is_empty() => "direct Newton",
            Reference::Assembled { .. } => "Newton-multigrid",
            Reference::MatrixFree { .. } => "Newton-Krylov",
        }
    }

    /// Solve `sys` at time `t` from `u` (the last frame's solution) in place; the assembled
    /// solver is built again where the frame's grasps or pins changed the constrained dofs.
    /// `Err`: why it could not (an inverted element, a failed factorisation), in words.
    fn solve(
        &mut self,
        sys: &mut System,
        t: f64,
        u: &mut [f64],
        tol: f64,
    ) -> std::result::Result<ReferenceSolve, String> {
        // The rule has no absolute floor but where nothing loads the body (a force scale
        // below UNLOADED N: round-off of a body at rest): a tolerance below round-off fails,
        // as it should.
        let scale = problem_scale(sys, t, u);
        let target = if scale > UNLOADED { tol * scale } else { 1e-14 };
        let mut params = DirectNewtonParams {
            rel_tol: 0.0,
            abs_tol: target,
            // Near a solution whose energy is small against its round-off (an unloaded body
            // let go), the line search takes a falling residual.
            flat_below: 100.0 * target,
            max_newton: REFERENCE_MAX_NEWTON,
            ..Default::default()
        };
        let n = u.len();
        let out = match self {
            Reference::MatrixFree { diag } => {
                solve_system_matrix_free(sys, Some(diag), t, u, params, MatrixFreeCg::default())
            }
            Reference::Assembled {
                newton,
                down,
                smoother,
            } => {
                let mask: Vec<bool> = (0..n).map(|i| fixed_dof(&sys.constraints, i)).collect();
                if newton.as_ref().is_none_or(|(_, m)| *m != mask) {
                    let built = if down.is_empty() {
                        DirectNewton::new(&*sys.force, &sys.mass, &sys.constraints)
                    } else {
                        DirectNewton::with_levels(&*sys.force, &sys.mass, &sys.constraints, down)
                    };
                    let built = built.map_err(|e| format!("could not start: {e}"))?;
                    *newton = Some((Box::new(built), mask));
                }
                let Some((solver, _)) = newton.as_mut() else {
                    unreachable!("built above")
                };
                if down.is_empty() {
                    params.pcg_max = REFERENCE_PCG_MAX;
                } else {
                    params.multigrid = Some(MultigridPcg {
                        smoother: *smoother,
                        ..Default::default()
                    });
                }
                let System {
                    force,
                    constraints,
                    springs,
                    f_ext,
                    ..
                } = sys;
                solver.solve(&mut **force, springs, constraints, f_ext, t, u, params)
            }
        };
        match out {
            Ok(o) => Ok(ReferenceSolve {
                converged: o.converged,
                residual: o.residual,
                initial_residual: o.initial_residual,
                target: o.target,
                newton_steps: o.newton_steps,
            }),
            Err(DirectNewtonError::Inverted(f)) => Err(format!(
                "inverted element {} (det F = {:.3e})",
                f.element, f.det_f
            )),
            Err(e) => Err(format!("failed: {e}")),
        }
    }
}

/// `frames.csv`: one row per frame.
pub const FRAMES_HEADER: &str =
    "frame,time_s,steps,wall_s,residual_N,max_u_m,lag_max_m,lag_rms_m,static_max_u_m,lag_rel,force_evals";

/// `frames.csv` written as the frames come ([`RowFile`]).
struct FrameRows(RowFile);

impl FrameRows {
    /// `write`: to `path`; else counted and dropped (a run in memory).
    fn create(path: &Path, write: bool) -> Result<FrameRows> {
        Ok(FrameRows(if write {
            RowFile::create(path, FRAMES_HEADER)?
        } else {
            RowFile::discard(path, FRAMES_HEADER)?
        }))
    }
    fn push(&mut self, r: &FrameRow) -> Result<()> {
        let opt = |x: f64| {
            if x.is_finite() {
                format!("{x:.9e}")
            } else {
                String::new()
            }
        };
        let line = format!(
            "{},{:.6},{},{:.6e},{:.9e},{:.9e},{},{},{},{},{:.6e}",
            r.frame,
            r.time,
            r.steps,
            r.wall,
            r.residual,
            r.max_u,
            opt(r.lag_max),
            opt(r.lag_rms),
            opt(r.static_max_u),
            opt(r.lag_rel()),
            r.force_evals
        );
        self.0.push(line.as_bytes())
    }
    fn flush(&mut self) -> Result<()> {
        self.0.flush()
    }
}

/// The rows of a `frames.csv` (lags NaN where the file has none).
pub fn read_frames_csv(path: &Path) -> Result<Vec<FrameRow>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let num = |j: usize| -> Result<f64> {
            let x = f.get(j).copied().unwrap_or("");
            if x.is_empty() {
                return Ok(f64::NAN);
            }
            x.parse().map_err(|_| Error::Scenario {
                path: path.to_path_buf(),
                line: Some(i + 1),
                msg: format!("bad number `{x}` in column {}", j + 1),
            })
        };
        out.push(FrameRow {
            frame: num(0)? as usize,
            time: num(1)?,
            steps: num(2)? as u64,
            wall: num(3)?,
            residual: num(4)?,
            max_u: num(5)?,
            lag_max: num(6)?,
            lag_rms: num(7)?,
            static_max_u: num(8)?,
            force_evals: num(10)?,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::runner::run_interactive;

    /// The paper's membrane, centre node pulled 1 cm along a path over 0.2 s, 6 frames.
    fn scenario(multigrid: &str, interactive: &str) -> Scenario {
        scenario_for(0.2, multigrid, interactive)
    }

    /// [`scenario`] run for `duration` (s): the path held after 0.2 s.
    fn scenario_for(duration: f64, multigrid: &str, interactive: &str) -> Scenario {
        let text = scenario_text(duration, multigrid, interactive);
        Scenario::from_toml(&text, Path::new("interactive-test.toml")).unwrap()
    }

    /// Run `sc` interactively into a temporary directory: its summary and `frames.csv`.
    fn played(sc: &Scenario) -> (InteractiveSummary, Vec<FrameRow>) {
        let dir = tempfile::tempdir().unwrap();
        let s = run_interactive(
            sc,
            sc.stepper().unwrap(),
            RunOptions {
                out_dir: Some(dir.path().to_path_buf()),
                ..Default::default()
            },
        )
        .unwrap();
        let rows = read_frames_csv(&dir.path().join("frames.csv")).unwrap();
        (s, rows)
    }

    /// The text of [`scenario_for`].
    fn scenario_text(duration: f64, multigrid: &str, interactive: &str) -> String {
        format!(
            r#"
[mesh]
generate = "rectangle"
size = [0.1, 0.1]
nodes = 120
[material]
law = "mooney-rivlin"
c1 = 1000.0
c2 = 1000.0
[damping]
ratio = 1.0
omega = 177.7
[[fix]]
boundary = true
[[displace]]
point = [0.0, 0.0, 0.0]
mode = "table"
table = [[0.0, 0.0, 0.0, 0.0], [0.2, 0.0, 0.0, 0.01]]
[run]
duration = {duration}
{multigrid}
[interactive]
fps = 30.0
{interactive}
"#
        )
    }

    /// The reference a frame's lag is measured against is the static solve's equilibrium:
    /// the last frame's `u*` (the path at its end, held) against `method = "newton"` on the
    /// same scenario, to 1e-8 of the solution, on one level and with `[multigrid]` levels
    /// (the reference then Newton-multigrid). With Newton-Krylov as the reference, a frame's
    /// solve could stall at its start (liver_interactive, frame 5: "a relative residual of
    /// 1.00e0 after 3 Newton steps") and the frame had no lag.
    #[test]
    fn the_reference_is_the_static_solve_s_equilibrium() {
        for multigrid in ["", "[multigrid]\nlevels = 3\n"] {
            let sc = scenario_for(0.3, multigrid, "cycles = 2");
            let (s, rows) = played(&sc);
            assert_eq!(s.reference_failures, 0, "{s}");
            let last = rows.last().unwrap();
            let text = format!(
                "{}[integrator]\nmethod = \"newton\"\n[run]\nresidual_tol = 1e-11\n",
                scenario_text(0.3, multigrid, "")
                    .replace("[interactive]\nfps = 30.0\n", "")
                    .replace("[run]\nduration = 0.3\n", "")
            );
            let stat = Scenario::from_toml(&text, Path::new("static.toml")).unwrap();
            let sol = crate::runner::run_static(
                &stat,
                RunOptions {
                    in_memory: true,
                    ..Default::default()
                },
            )
            .unwrap();
            assert!(sol.converged(), "{sol}");
            let want = sol.last.max_u;
            assert!(want > 5e-3, "the lifted membrane: {want}");
            assert!(
                (last.static_max_u - want).abs() <= 1e-8 * want,
                "{multigrid:?}: reference max |u*| {} vs static {want}",
                last.static_max_u
            );
        }
    }

    /// `predictor = true` on a path prescribed from `t = 0`: a 4 cm cube of neo-Hookean
    /// tissue fixed at its base, a patch of its top pulled up 4 mm over 0.3 s (9 frames),
    /// FAS over 2 levels, 1 V-cycle a frame. Frame 1 is the same bits (it extrapolates the
    /// rest before it), and the mean lag over the path is at most half the lag without.
    #[test]
    fn the_predictor_shrinks_the_lag_of_a_prescribed_path() {
        let cube = |predictor: bool| {
            let text = format!(
                r#"
[mesh]
generate = "box"
size = [0.04, 0.04, 0.04]
divisions = [6, 6, 6]
[material]
law = "neo-hookean"
young = 5e3
poisson = 0.45
[[fix]]
plane = {{ point = [0, 0, 0], normal = [0, 0, 1] }}
[[displace]]
point = [0.02, 0.02, 0.04]
radius = 0.008
mode = "table"
table = [[0.0, 0, 0, 0], [0.3, 0, 0, 0.004]]
[multigrid]
scheme = "fas"
levels = 2
[run]
duration = 0.3
[interactive]
cycles = 1
predictor = {predictor}
"#
            );
            Scenario::from_toml(&text, Path::new("predictor.toml")).unwrap()
        };
        let (off, rows_off) = played(&cube(false));
        let (on, rows_on) = played(&cube(true));
        assert!(on.settings.predictor && !off.settings.predictor);
        assert_eq!(rows_on[0].lag_max, rows_off[0].lag_max);
        assert_eq!((on.lag_frames, off.lag_frames), (9, 9));
        let ratio = on.lag_rel_mean() / off.lag_rel_mean();
        assert!(
            ratio <= 0.5,
            "mean lag {} with the predictor, {} without: {:?} {:?}",
            on.lag_rel_mean(),
            off.lag_rel_mean(),
            rows_on.iter().map(|r| r.lag_rel()).collect::<Vec<_>>(),
            rows_off.iter().map(|r| r.lag_rel()).collect::<Vec<_>>()
        );
    }

    /// The reference solve failed on every frame after a path stopped moving (on a cube held
    /// for 36 of 45 frames): its rule was relative to the frame's own start, which is already
    /// converged when the static problem did not change. It is now relative to the largest
    /// start of the run as well, so every frame has a lag.
    #[test]
    fn the_reference_does_not_fail_once_the_path_holds_still() {
        // The membrane's path over 0.2 s (6 frames), then held for 0.3 s more (9 frames).
        let sc = scenario_for(0.5, "", "cycles = 8");
        let (s, _) = played(&sc);
        assert_eq!(s.frames, 15);
        assert_eq!(s.reference_failures, 0, "{:?}", s.first_failure);
        assert_eq!(s.lag_frames, s.frames);
        // Held still, the stepper settles towards the held static solution.
        let last = s.last.unwrap();
        assert!(last.lag_rel() < 0.5, "{last:?}");
    }

    fn lags(multigrid: &str, cycles: usize) -> Vec<FrameRow> {
        let sc = scenario(multigrid, &format!("cycles = {cycles}"));
        let dir = std::env::temp_dir().join(format!(
            "raisov-interactive-{}-{cycles}-{}",
            multigrid.len(),
            std::process::id()
        ));
        let s = run_interactive(
            &sc,
            sc.stepper().unwrap(),
            RunOptions {
                out_dir: Some(dir.clone()),
                ..Default::default()
            },
        )
        .unwrap();
        let rows = read_frames_csv(&dir.join("frames.csv")).unwrap();
        assert_eq!(rows.len(), s.frames);
        let last = rows.last().unwrap();
        let lag = s.last.unwrap().lag_max;
        assert!(
            (lag - last.lag_max).abs() <= 1e-9 * lag,
            "{lag} vs {last:?}"
        );
        // The summary's verdict agrees with its bound.
        let text = s.to_string();
        assert_eq!(
            text.contains("keeps up with real time"),
            s.fps() >= 30.0 && s.lag_rel_max <= 0.05,
            "{text}"
        );
        let _ = std::fs::remove_dir_all(&dir);
        rows
    }

    /// More work per frame, less lag; with enough, the multigrid sits on the static solution
    /// of every frame (the lag is the reference solve's own tolerance).
    #[test]
    fn lag_shrinks_with_budget_and_vanishes_for_fas() {
        let fas = "[multigrid]\nscheme = \"fas\"\nlevels = 3";
        let few = lags(fas, 1);
        let many = lags(fas, 60);
        assert_eq!(few.len(), 6);
        for (a, b) in few.iter().zip(&many) {
            assert!(b.lag_max < a.lag_max, "frame {}: {b:?} vs {a:?}", a.frame);
            assert_eq!(a.static_max_u, b.static_max_u);
        }
        let last = many.last().unwrap();
        // The grasp itself is 1 cm; the static solution moves it exactly.
        assert!((last.static_max_u - 0.01).abs() < 1e-12);
        assert!(last.lag_rel() < 1e-4, "{last:?}");
        // Single level: damped dynamics lags far behind with a few steps per frame.
        let slim = lags("", 4);
        assert!(slim.last().unwrap().lag_rel() > 0.1);
    }

    /// A reference solve that cannot reach its tolerance is reported with its frame; no lag
    /// is quoted against it and the run does not claim to keep up. Without a reference it
    /// does not claim to either.
    #[test]
    fn failed_reference_is_reported_not_measured_against() {
        let run = |extra: &str| {
            let sc = scenario("", &format!("cycles = 2\n{extra}"));
            played(&sc)
        };
        let (s, rows) = run("reference_tol = 1e-30");
        assert_eq!(s.reference_failures, 6);
        assert_eq!(s.lag_frames, 0);
        assert!(rows.iter().all(|r| r.lag_max.is_nan()));
        let text = s.to_string();
        assert!(
            text.contains("reference       FAILED in 6 of 6 frames; first: frame 1"),
            "{text}"
        );
        assert!(text.contains("cannot tell whether it keeps up"), "{text}");
        assert!(
            !text.contains("keeps up with real time") && !text.contains("lag             mean")
        );
        assert!(!s.keeps_up());
        let (s, _) = run("reference = \"none\"");
        let text = s.to_string();
        assert!(text.contains("lag not measured"), "{text}");
        assert!(!s.keeps_up());
    }
}
