//! The experiments of `raisov paper`: scenario text for every run, the measured run loop,
//! stability bisection, steady-state references, and one function per experiment.
//!
//! Every run is a scenario built from TOML text ([`scenario_toml`]) exactly as a user would
//! write it; the driver saves one such file per case and method under `scenarios/`.

use raisov::error::{Error, Result};
use raisov::integrate::stability::critical_step_estimate;
use raisov::integrate::{Method, State, Stepper, SwitchCounts};
use raisov::metrics::Meter;
use raisov::scenario::Scenario;
use raisov::statics::krylov::{NewtonParams, NewtonSolver};
use raisov::statics::relax::dynamic::relax;
use std::path::Path;
use std::time::Instant;

/// The membrane's physics, stated once (the project's reading of the paper's section 3,
/// `examples/membrane_lift.toml`): Mooney-Rivlin C1 = C2 = 1 kPa, density 1000 kg/m³,
/// thickness 1 mm, damping ratio 1 at ω = 177.7 rad/s (α = 355.4 1/s), 10 cm square, all
/// sides fixed.
pub const MEMBRANE_PHYSICS: &str = r#"[material]
law = "mooney-rivlin"
c1 = 1000.0
c2 = 1000.0
density = 1000.0
thickness = 0.001

[damping]
ratio = 1.0
omega = 177.7

[[fix]]
boundary = true
"#;

/// Soft tissue for the 3-D runs (tetrahedral block and liver): neo-Hookean E = 5 kPa,
/// ν = 0.45, density 1060 kg/m³.
pub const TISSUE_MATERIAL: &str = r#"[material]
law = "neo-hookean"
young = 5000.0
poisson = 0.45
density = 1060.0
"#;

/// How the liver is held: the cap of its top, z ≥ 195 mm in the mesh's millimetres (249 / 127 /
/// 72 / 43 nodes on L0 / L1 / L2 / L3, a patch about 100 × 60 mm). A plane at z ≥ 199.5 mm held
/// only 10 / 4 / 3 / 1 nodes, so the organ hung from points, differently on every level, and
/// single-level integration inverted an element near them under gravity.
pub const LIVER_FIX: &str =
    "[[fix]]\nplane = { point = [0.0, 0.0, 0.195], normal = [0.0, 0.0, -1.0] }\n";

/// Damping ratio 1 at the frequency of the lowest shear mode of a body of size `l` (m),
/// `ω = π √2 c_s / l` with `c_s = √(μ/ρ)` for [`TISSUE_MATERIAL`], the same rule as the
/// membrane's ω.
pub fn tissue_omega(l: f64) -> f64 {
    let mu = 5000.0 / (2.0 * 1.45);
    std::f64::consts::PI * std::f64::consts::SQRT_2 * (mu / 1060.0f64).sqrt() / l
}

/// An integration method as the experiments compare them.
#[derive(Clone, Debug, PartialEq)]
pub enum Meth {
    /// Single-level integration with this integrator (`Method::name`).
    Slim(&'static str),
    /// The project's FAS multigrid at its defaults (RK4 smoother).
    Fas,
    /// The paper's RaISoV (RK4 on every level, one step for all levels): reading and ε (m),
    /// `None` for the default 1e-3 × shortest edge.
    Raisov {
        reading: &'static str,
        epsilon: Option<f64>,
        tag: &'static str,
    },
}

impl Meth {
    /// A label for tables and legends.
    pub fn label(&self) -> String {
        match self {
            Meth::Slim(m) => format!("SLIM {m}"),
            Meth::Fas => "FAS multigrid".into(),
            Meth::Raisov {
                reading,
                epsilon,
                tag,
            } => match epsilon {
                None => format!("RaISoV {reading}, eps default"),
                Some(e) => format!("RaISoV {reading}, eps {tag} ({})", fmt_eps(*e)),
            },
        }
    }
    /// A file-name friendly key.
    pub fn key(&self) -> String {
        match self {
            Meth::Slim(m) => format!("slim-{m}"),
            Meth::Fas => "fas".into(),
            Meth::Raisov { reading, tag, .. } => format!("raisov-{reading}-{tag}"),
        }
    }
    pub fn is_multigrid(&self) -> bool {
        !matches!(self, Meth::Slim(_))
    }
    fn integrator(&self) -> &'static str {
        match self {
            Meth::Slim(m) => m,
            _ => "rk4",
        }
    }
}

/// ε as text (m); infinity where the state switch never fires.
pub fn fmt_eps(e: f64) -> String {
    if e.is_infinite() || e >= 1e6 {
        "inf: variation only".into()
    } else if e == 0.0 {
        "0: state only".into()
    } else {
        format!("{e:.1e} m")
    }
}

/// The mesh of a case.
#[derive(Clone, Debug)]
pub enum MeshDesc {
    /// 10 cm square membrane with explicit node targets per level (level 0 first).
    Membrane { level_nodes: Vec<usize> },
    /// 10 cm square membrane, `levels` levels of ratio 0.5 from `nodes`.
    MembraneRatio { nodes: usize, levels: usize },
    /// Tetrahedral block (m), `levels` levels of ratio 0.5 from `nodes`.
    Block {
        size: [f64; 3],
        nodes: usize,
        levels: usize,
    },
    /// Mesh files (absolute paths), finest first, coordinates scaled by `scale`.
    Files { files: Vec<String>, scale: f64 },
}

/// One physical case: mesh, physics text (material, damping, fixes, loads, gravity) and
/// how long it runs.
#[derive(Clone, Debug)]
pub struct Case {
    pub name: String,
    pub mesh: MeshDesc,
    /// Top-level keys (gravity), written before any table.
    pub top: String,
    /// Tables: material, damping, fix, displace.
    pub physics: String,
    /// Simulated time (s).
    pub duration: f64,
}

/// How the time step is chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Step {
    /// `dt = safety × estimated critical step` of the finest mesh for the integrator.
    Safety(f64),
    /// An explicit step (s).
    Dt(f64),
}

/// The scenario text of `case` run by `meth` with step `step`.
pub fn scenario_toml(case: &Case, meth: &Meth, step: Step) -> String {
    let mut s = String::new();
    s.push_str(&format!(
        "# raisov paper: case {}, method {}\nname = \"{}-{}\"\n{}\n",
        case.name,
        meth.label(),
        case.name,
        meth.key(),
        case.top
    ));
    let (finest, mg_mesh) = match &case.mesh {
        MeshDesc::Membrane { level_nodes } => (
            format!(
                "[mesh]\ngenerate = \"rectangle\"\nsize = [0.1, 0.1]\nnodes = {}\n",
                level_nodes[0]
            ),
            format!("level_nodes = {level_nodes:?}\n"),
        ),
        MeshDesc::MembraneRatio { nodes, levels } => (
            format!("[mesh]\ngenerate = \"rectangle\"\nsize = [0.1, 0.1]\nnodes = {nodes}\n"),
            format!("levels = {levels}\nratio = 0.5\n"),
        ),
        MeshDesc::Block {
            size,
            nodes,
            levels,
        } => (
            format!(
                "[mesh]\ngenerate = \"box\"\nsize = [{}, {}, {}]\nnodes = {nodes}\n",
                size[0], size[1], size[2]
            ),
            format!("levels = {levels}\nratio = 0.5\n"),
        ),
        MeshDesc::Files { files, scale } => (
            format!("[mesh]\nfile = {:?}\nscale = {scale}\n", files[0]),
            format!("files = {:?}\n", &files[1..]),
        ),
    };
    s.push_str(&finest);
    s.push('\n');
    s.push_str(&case.physics);
    s.push_str(&format!(
        "\n[integrator]\nmethod = \"{}\"\n",
        meth.integrator()
    ));
    match step {
        Step::Safety(f) => s.push_str(&format!("safety = {f}\n")),
        Step::Dt(dt) => s.push_str(&format!("dt = {dt:e}\n")),
    }
    s.push_str(&format!("\n[run]\nduration = {}\n", case.duration));
    match meth {
        Meth::Slim(_) => {}
        Meth::Fas => {
            s.push_str("\n[multigrid]\nscheme = \"fas\"\n");
            s.push_str(&mg_mesh);
        }
        Meth::Raisov {
            reading, epsilon, ..
        } => {
            s.push_str(&format!(
                "\n[multigrid]\nscheme = \"raisov-paper\"\nreading = \"{reading}\"\n"
            ));
            if let Some(e) = epsilon {
                // TOML has `inf`; a huge finite value says the same and reads everywhere.
                let e = if e.is_finite() { *e } else { 1e30 };
                s.push_str(&format!("epsilon = {e:e}\n"));
            }
            s.push_str(&mg_mesh);
        }
    }
    s
}

/// Resolve the scenario of `case`, `meth`, `step`.
pub fn scenario(case: &Case, meth: &Meth, step: Step) -> Result<Scenario> {
    let text = scenario_toml(case, meth, step);
    Scenario::from_toml(
        &text,
        Path::new(&format!("paper/{}-{}.toml", case.name, meth.key())),
    )
}

/// One sample of a measured run.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Pt {
    pub t: f64,
    pub max: f64,
    pub mean: f64,
    pub residual: f64,
    pub kinetic: f64,
    pub evals: f64,
    pub wall: f64,
}

/// How a measured run ended.
#[derive(Clone, Debug, PartialEq)]
pub enum Outcome {
    /// Ran the whole duration.
    Completed,
    /// Reached the target (mean |T − T∞| ≤ target × its initial value).
    Target,
    /// Steady (residual below 1e-6 of its peak and kinetic energy below 1e-12 of its peak):
    /// used to end stability tests early.
    Steady,
    /// Stopped by the wall-time cap.
    WallCap { wall: f64 },
    /// Diverged: the message names time, step, element and cause.
    Diverged { time: f64, what: String },
}

/// A measured run.
#[derive(Clone, Debug)]
pub struct Sim {
    pub label: String,
    pub dt: f64,
    pub points: Vec<Pt>,
    pub outcome: Outcome,
    /// The first sample at or below the target, when one was asked for and reached.
    pub reached: Option<Pt>,
    /// Last residual over the peak residual of the run.
    pub residual_drop: f64,
    /// RaISoV's transfer switches (eqs. 10 and 12) over the run; `None` for other methods.
    pub switches: Option<SwitchCounts>,
}

impl Sim {
    pub fn last(&self) -> Pt {
        *self.points.last().expect("at least the first sample")
    }
    pub fn diverged(&self) -> bool {
        matches!(self.outcome, Outcome::Diverged { .. })
    }
}

/// Settings of [`simulate`].
#[derive(Clone, Copy, Debug)]
pub struct SimCfg {
    /// Simulated time (s).
    pub t_end: f64,
    /// Wall-time cap (s).
    pub wall_cap: f64,
    /// About this many samples over the run.
    pub samples: u64,
    /// Stop when mean |T − T∞| ≤ this × its initial value.
    pub target: Option<f64>,
    /// Stop when steady (see [`Outcome::Steady`]).
    pub stop_steady: bool,
    /// The wall cap stops the run only once it has done at least this many force
    /// evaluations (finest-level units), and at the latest at [`HARD_CAP_FACTOR`] × the cap:
    /// a run that a comparison bounds from below needs both its wall time and its force
    /// evaluations past the other's. 0: the wall cap alone.
    pub min_evals: f64,
}

/// The hard wall-time limit of a run held past its cap by [`SimCfg::min_evals`], as a
/// multiple of the cap.
pub const HARD_CAP_FACTOR: f64 = 3.0;

/// Run `stepper` (whose finest level is `sc`'s mesh) and measure |T − T∞| against `t_inf`
/// (when given). Nothing non-finite is kept: a diverged run's series ends at its last finite
/// sample.
pub fn simulate(
    sc: &Scenario,
    stepper: &mut dyn Stepper,
    label: &str,
    t_inf: Option<&[f64]>,
    cfg: SimCfg,
) -> Sim {
    let n = sc.mesh.num_nodes();
    let mut meter = Meter::new(n, t_inf.map(|t| t.to_vec()));
    let dt = stepper.dt();
    let total = (cfg.t_end / dt).ceil().max(1.0) as u64;
    let every = (total / cfg.samples.max(1)).max(1);
    let start = Instant::now();
    // Seconds spent measuring (stress and residual samples), kept out of the wall time: a
    // method that takes many cheap steps is sampled more often and must not pay for it.
    let mut measuring = 0.0;
    let take = |stepper: &mut dyn Stepper, meter: &mut Meter, wall: f64| -> Pt {
        let evals = stepper.force_evaluations();
        let steps = stepper.steps();
        let (sys, s) = stepper.finest();
        let x = meter.sample(sys, s, steps);
        Pt {
            t: x.time,
            max: x.stress_err_max,
            mean: x.stress_err_mean,
            residual: x.residual,
            kinetic: x.kinetic,
            evals,
            wall,
        }
    };
    let p0 = take(stepper, &mut meter, 0.0);
    let finite = |p: &Pt| {
        p.residual.is_finite()
            && p.kinetic.is_finite()
            && (t_inf.is_none() || (p.max.is_finite() && p.mean.is_finite()))
    };
    let mut points = vec![p0];
    let (mut res_peak, mut ke_peak) = (p0.residual, p0.kinetic);
    let target = cfg.target.map(|f| f * p0.mean);
    let mut outcome = Outcome::Completed;
    let mut reached = None;
    if let Some(tg) = target {
        if p0.mean <= tg {
            reached = Some(p0);
            outcome = Outcome::Target;
        }
    }
    while reached.is_none() && stepper.steps() < total {
        if let Err(d) = stepper.advance() {
            outcome = Outcome::Diverged {
                time: d.time,
                what: d.to_string(),
            };
            break;
        }
        let k = stepper.steps();
        let wall = start.elapsed().as_secs_f64() - measuring;
        if k.is_multiple_of(every)
            || k == total
            || target.is_some() && k.is_multiple_of(every.min(10))
        {
            let t0 = Instant::now();
            let p = take(stepper, &mut meter, wall);
            measuring += t0.elapsed().as_secs_f64();
            if !finite(&p) {
                outcome = Outcome::Diverged {
                    time: p.t,
                    what: format!("non-finite measure at t = {:.6} s (step {k})", p.t),
                };
                break;
            }
            res_peak = res_peak.max(p.residual);
            ke_peak = ke_peak.max(p.kinetic);
            if k.is_multiple_of(every) || k == total {
                points.push(p);
            }
            if let Some(tg) = target {
                if p.mean <= tg {
                    if points.last() != Some(&p) {
                        points.push(p);
                    }
                    reached = Some(p);
                    outcome = Outcome::Target;
                    break;
                }
            }
            if cfg.stop_steady
                && p.residual <= 1e-6 * res_peak
                && p.kinetic <= 1e-12 * ke_peak.max(f64::MIN_POSITIVE)
            {
                points.push(p);
                outcome = Outcome::Steady;
                break;
            }
        }
        if wall > cfg.wall_cap
            && (stepper.force_evaluations() >= cfg.min_evals
                || wall > HARD_CAP_FACTOR * cfg.wall_cap)
        {
            let p = take(stepper, &mut meter, wall);
            if finite(&p) {
                points.push(p);
            }
            outcome = Outcome::WallCap { wall };
            break;
        }
    }
    let last = *points.last().expect("first sample");
    Sim {
        label: label.to_string(),
        dt,
        points,
        outcome,
        reached,
        residual_drop: last.residual / res_peak.max(f64::MIN_POSITIVE),
        switches: stepper.switch_counts(),
    }
}

/// Result of [`bisect_stable`].
#[derive(Clone, Debug, PartialEq)]
pub struct Bisection {
    /// Largest value found stable (None: even `lo` was unstable).
    pub stable: Option<f64>,
    /// Smallest value found unstable (None: even `hi` was stable).
    pub unstable: Option<f64>,
    /// Every test, in order: (value, stable).
    pub tests: Vec<(f64, bool)>,
}

/// Largest stable value in `[lo, hi]` by geometric bisection, assuming stability is
/// monotone (stable below a threshold): tests `lo`, `hi`, then `iters` midpoints.
pub fn bisect_stable(
    lo: f64,
    hi: f64,
    iters: usize,
    mut stable: impl FnMut(f64) -> Result<bool>,
) -> Result<Bisection> {
    let mut tests = Vec::new();
    let ok_lo = stable(lo)?;
    tests.push((lo, ok_lo));
    if !ok_lo {
        return Ok(Bisection {
            stable: None,
            unstable: Some(lo),
            tests,
        });
    }
    let ok_hi = stable(hi)?;
    tests.push((hi, ok_hi));
    if ok_hi {
        return Ok(Bisection {
            stable: Some(hi),
            unstable: None,
            tests,
        });
    }
    let (mut a, mut b) = (lo, hi);
    for _ in 0..iters {
        let m = (a * b).sqrt();
        let ok = stable(m)?;
        tests.push((m, ok));
        if ok {
            a = m;
        } else {
            b = m;
        }
    }
    Ok(Bisection {
        stable: Some(a),
        unstable: Some(b),
        tests,
    })
}

/// The steady-state nodal stress T∞ of `sc` (its finest mesh) and a note on how it was
/// computed. Small meshes: [`Scenario::steady_reference`] (dynamic relaxation to 1e-10).
/// Large meshes (more than `relax_max_nodes`): dynamic relaxation on the coarsest level of
/// `sc`'s hierarchy, interpolated up level by level with a Newton-Krylov solve on each
/// (the finest to 1e-8 of the load scale).
pub fn reference(sc: &Scenario, relax_max_nodes: usize) -> Result<(Vec<f64>, String)> {
    if sc.mesh.num_nodes() <= relax_max_nodes || sc.multigrid.is_none() {
        return sc.steady_reference();
    }
    let start = Instant::now();
    let fail = |what: String| Error::param("reference", what);
    let (mut levels, links) = sc.build_levels()?;
    let m = levels.len();
    let t = sc.motion_end();
    let dt_relax = {
        let l = &levels[m - 1];
        0.5 * critical_step_estimate(&l.mesh, &sc.material, sc.density, Method::SymplecticEuler)
    };
    let mut s = State::at_rest(levels[m - 1].num_nodes());
    s.t = t;
    let r = relax(&mut levels[m - 1].sys, s, dt_relax, 1e-8, 2_000_000).map_err(|f| {
        fail(format!(
            "coarsest relaxation inverted element {}",
            f.element
        ))
    })?;
    let mut u = r.state.u;
    let mut notes = vec![format!(
        "coarsest level ({} nodes) relaxed to {:.1e} in {} steps",
        levels[m - 1].num_nodes(),
        r.residual / r.initial_residual.max(f64::MIN_POSITIVE),
        r.steps
    )];
    for l in (0..m - 1).rev() {
        let mut fine = vec![0.0; 3 * levels[l].num_nodes()];
        links[l].down.interpolate(&u, 3, &mut fine)?;
        let lv = &mut levels[l];
        let mut solver = NewtonSolver::new(&lv.sys);
        let p = NewtonParams {
            rel_tol: if l == 0 { 1e-8 } else { 1e-5 },
            max_newton: if l == 0 { 40 } else { 15 },
            ..Default::default()
        };
        let st = solver.solve(&mut lv.sys, t, &mut fine, p).map_err(|f| {
            fail(format!(
                "Newton on level {l} inverted element {}",
                f.element
            ))
        })?;
        notes.push(format!(
            "level {l} ({} nodes): Newton residual {:.2e} N ({:.1e} of start{})",
            lv.num_nodes(),
            st.residual,
            st.residual / st.initial_residual.max(f64::MIN_POSITIVE),
            if st.converged { "" } else { ", not converged" }
        ));
        u = fine;
    }
    let n = levels[0].num_nodes();
    let mut tt = vec![0.0; 9 * n];
    levels[0].sys.force.nodal_stress(&u, &mut tt);
    notes.push(format!("{:.1} s", start.elapsed().as_secs_f64()));
    Ok((tt, format!("T_inf: {}", notes.join("; "))))
}

/// T∞ of a solid by Newton-Krylov on the finest mesh (CG preconditioned by the per-node
/// fictitious masses), the loads applied in `increments` equal steps from rest, each solved to
/// 1e-5 of its residual scale and the last to `rel_tol`; prescribed motions are at their end
/// values throughout. Returns T∞, a note, and whether the last solve converged. An inverting
/// Newton step is an error (the caller falls back to relaxation).
pub fn newton_reference(
    sc: &Scenario,
    rel_tol: f64,
    increments: usize,
) -> Result<(Vec<f64>, String, bool)> {
    let start = Instant::now();
    let mut sys = sc.build_system()?;
    let n = sys.num_nodes();
    let load = sys.f_ext.clone();
    let mut u = vec![0.0; 3 * n];
    let mut solver = NewtonSolver::new(&sys);
    let t = sc.motion_end();
    let mut last = None;
    for k in 1..=increments.max(1) {
        let f = k as f64 / increments.max(1) as f64;
        for (e, l) in sys.f_ext.iter_mut().zip(&load) {
            *e = f * l;
        }
        let p = NewtonParams {
            rel_tol: if k == increments.max(1) {
                rel_tol
            } else {
                1e-5
            },
            ..Default::default()
        };
        let st = solver.solve(&mut sys, t, &mut u, p).map_err(|f| {
            Error::param(
                "reference",
                format!(
                    "Newton step {k}/{increments} inverted element {}",
                    f.element
                ),
            )
        })?;
        last = Some(st);
    }
    let st = last.expect("at least one increment");
    let mut tt = vec![0.0; 9 * n];
    sys.force.nodal_stress(&u, &mut tt);
    Ok((
        tt,
        format!(
            "T_inf by Newton-Krylov on the finest mesh, load in {increments} increments: residual {:.2e} N ({:.1e} of the load), {} force evaluations, {:.1} s{}",
            st.residual,
            st.residual / load.iter().map(|x| x * x).sum::<f64>().sqrt().max(f64::MIN_POSITIVE),
            st.force_evaluations,
            start.elapsed().as_secs_f64(),
            if st.converged { "" } else { " (NOT converged)" }
        ),
        st.converged,
    ))
}

/// T∞ by dynamic relaxation of the finest mesh with a wall-time budget (the number of steps
/// is set from the measured cost of one force evaluation). Returns T∞, a note, and whether
/// the residual fell below `rel_tol` of its scale.
pub fn relax_reference(
    sc: &Scenario,
    rel_tol: f64,
    budget: f64,
) -> Result<(Vec<f64>, String, bool)> {
    let start = Instant::now();
    let mut sys = sc.build_system()?;
    let n = sys.num_nodes();
    let mut r = vec![0.0; 3 * n];
    let u0 = vec![0.0; 3 * n];
    let t0 = Instant::now();
    let _ = sys.residual(&u0, &mut r);
    let _ = sys.residual(&u0, &mut r);
    let per_eval = (t0.elapsed().as_secs_f64() / 2.0).max(1e-7);
    let max_steps = ((budget / per_eval) as u64).max(100);
    let mut s = State::at_rest(n);
    s.t = sc.motion_end();
    let dt =
        0.5 * critical_step_estimate(&sc.mesh, &sc.material, sc.density, Method::SymplecticEuler);
    let rr = relax(&mut sys, s, dt, rel_tol, max_steps).map_err(|f| {
        Error::param(
            "reference",
            format!("relaxation inverted element {}", f.element),
        )
    })?;
    let mut tt = vec![0.0; 9 * n];
    sys.force.nodal_stress(&rr.state.u, &mut tt);
    let rel = rr.residual / rr.initial_residual.max(f64::MIN_POSITIVE);
    Ok((
        tt,
        format!(
            "T_inf by dynamic relaxation of the finest mesh: residual {rel:.1e} of its start after {} steps, {:.1} s{}",
            rr.steps,
            start.elapsed().as_secs_f64(),
            if rr.converged { String::new() } else { format!(" (NOT converged to {rel_tol:.0e} within the {budget:.0} s budget)") }
        ),
        rr.converged,
    ))
}

/// T∞ by FAS V-cycles on the scenario's own hierarchy (the scenario must use the FAS
/// multigrid), until the finest residual `‖f_ext − R(u)‖₂` (free nodes) falls below
/// `rel_tol` of the load `‖f_ext‖₂`, within `wall_cap` seconds. Used where the Newton-Krylov
/// ladder of [`fn@reference`] costs more than `raisov paper`'s budget (membranes above
/// [`super::REFERENCE_MAX_NODES`] nodes). The equilibrium is that of the finest mesh's
/// discrete equations, the one every method converges to (FAS reaches SLIM's equilibrium to
/// 1e-8, `multigrid::tests`); how FAS gets there does not enter T∞. Returns T∞, a note, and
/// the residual reached relative to the load (the tolerance was met when it is ≤ `rel_tol`).
pub fn fas_reference(
    sc: &Scenario,
    rel_tol: f64,
    wall_cap: f64,
) -> Result<(Vec<f64>, String, f64)> {
    let start = Instant::now();
    let mut st = sc.stepper()?;
    let fail = |what: String| Error::param("reference", what);
    let (n, load) = {
        let (sys, _) = st.finest();
        let load = sys.f_ext.iter().map(|x| x * x).sum::<f64>().sqrt();
        (sys.num_nodes(), load.max(f64::MIN_POSITIVE))
    };
    let mut r = vec![0.0; 3 * n];
    let mut res;
    loop {
        st.advance()
            .map_err(|d| fail(format!("FAS cycle diverged: {d}")))?;
        let (sys, s) = st.finest();
        res = sys
            .residual(&s.u, &mut r)
            .map_err(|f| fail(format!("inverted element {}", f.element)))?;
        if !res.is_finite() {
            return Err(fail("non-finite residual".into()));
        }
        if res <= rel_tol * load || start.elapsed().as_secs_f64() > wall_cap {
            break;
        }
    }
    let converged = res <= rel_tol * load;
    let cycles = st.steps();
    let (sys, s) = st.finest();
    let mut tt = vec![0.0; 9 * n];
    sys.force.nodal_stress(&s.u, &mut tt);
    Ok((
        tt,
        format!(
            "T_inf by FAS V-cycles on the same hierarchy: residual {res:.2e} N ({:.1e} of the load) after {cycles} cycles, {:.1} s{}",
            res / load,
            start.elapsed().as_secs_f64(),
            if converged {
                String::new()
            } else {
                format!(" (NOT converged to {rel_tol:.0e} within {wall_cap:.0} s)")
            }
        ),
        res / load,
    ))
}

/// Mean over nodes of the Frobenius norm of `a − b` (nodal 3 × 3 tensors, 9 entries each).
pub fn mean_norm_diff(a: &[f64], b: &[f64]) -> f64 {
    let n = (a.len() / 9).max(1) as f64;
    a.chunks_exact(9)
        .zip(b.chunks_exact(9))
        .map(|(x, y)| {
            x.iter()
                .zip(y)
                .map(|(p, q)| (p - q) * (p - q))
                .sum::<f64>()
                .sqrt()
        })
        .sum::<f64>()
        / n
}
