//! A scenario run to its end in one call, its final state handed back: what `raisov run`
//! does, and what a parameter study calls once per case ([`solve`]).
//!
//! The scenario says what runs, as for `raisov run`: `method = "newton"` a static solve
//! ([`super::run_static`]), an `[interactive]` section its frames
//! ([`super::run_interactive`], through a [`crate::sim::Simulation`]),
//! anything else a run in time ([`run_with`]). With [`RunOptions::in_memory`] nothing is
//! written (no directory is created, locked or cleared); otherwise the run writes what it
//! always writes.
//!
//! The [`Solution`] holds the finest level's final state, in the scenario's node order
//! ([`crate::model::Model::file_node`] gives each node's id in the mesh file):
//!
//! ```text
//! u_a                        displacement (m)
//! T_a                        nodal Cauchy stress (Pa), row-major 3×3
//! last.reaction_fixed        Σ_{a fixed}      (R_a(u) − V_a)   the supports' force on the body (N)
//! last.reaction_prescribed   Σ_{a prescribed} (R_a(u) − V_a)   the moved nodes' (grasps') (N)
//! last.tool                  the tools' contact force on the body (N)
//! applied                    Σ_a V_a, loads and body forces (N)
//! grasp_forces[g]            Σ_{a ∈ g} (V_a − R_a(u))   the force the body exerts on grasp g (N)
//! ```
//!
//! The reactions are [`crate::metrics`]' (the force on the body), a grasp's force is
//! [`Simulation::grab_force`](crate::sim::Simulation::grab_force)'s (the force on the tool):
//! at equilibrium `reaction_fixed + reaction_prescribed + tool + applied = 0`, and a
//! grasp's force is minus its nodes' share of `reaction_prescribed`. How the run ended is [`Finished::success`]: a static solve converged, a
//! run in time reached its duration or steady state, an interactive run played every frame.
//! A run that diverges is an error ([`crate::Error::Diverged`]) as for `raisov run`.
//!
//! The same scenario gives the same bits whatever the number of threads, except where a
//! wall-clock budget (`[interactive] ms`) decides how much work a frame does.

use super::{
    run_frames, run_static_keeping, run_with, FrameStepper, InteractiveSummary, Replay, RunOptions,
    RunSummary, StaticSummary,
};
use crate::error::Result;
use crate::integrate::Stepper;
use crate::metrics::{Meter, Sample};
use crate::scenario::Scenario;

/// How a run ended: the summary of its kind.
#[derive(Clone, Debug)]
pub enum Finished {
    /// A static solve (`method = "newton"`).
    Static(StaticSummary),
    /// A run in time.
    Dynamic(RunSummary),
    /// An interactive run (`[interactive]`).
    Interactive(InteractiveSummary),
}

impl Finished {
    /// `"static"`, `"dynamic"` or `"interactive"`.
    pub fn kind(&self) -> &'static str {
        match self {
            Finished::Static(_) => "static",
            Finished::Dynamic(_) => "dynamic",
            Finished::Interactive(_) => "interactive",
        }
    }

    /// Whether the run did what it was asked: a static solve converged, a run in time
    /// reached its duration or steady state, an interactive run played all its frames
    /// without being interrupted.
    pub fn success(&self) -> bool {
        match self {
            Finished::Static(s) => s.converged(),
            Finished::Dynamic(s) => s.reason.is_success(),
            Finished::Interactive(s) => !s.interrupted && s.frames == s.frames_planned,
        }
    }

    /// How it stopped, in words (the summary's line).
    pub fn stopped(&self) -> String {
        match self {
            Finished::Static(s) if s.converged() => "converged".into(),
            Finished::Static(s) => match (&s.inverted, &s.failure) {
                (Some((e, det)), _) => {
                    format!("did not converge: element {e} inverted (det F = {det:.3e})")
                }
                (None, Some(f)) => format!("did not converge: {f}"),
                (None, None) => "did not converge: the Newton step limit was reached".into(),
            },
            Finished::Dynamic(s) => s.reason.to_string(),
            Finished::Interactive(s) if s.interrupted => {
                format!(
                    "interrupted after {} of {} frames",
                    s.frames, s.frames_planned
                )
            }
            Finished::Interactive(s) => format!("played {} frames", s.frames),
        }
    }

    /// Wall-clock time of the run (s).
    pub fn wall(&self) -> f64 {
        match self {
            Finished::Static(s) => s.wall,
            Finished::Dynamic(s) => s.wall,
            Finished::Interactive(s) => s.wall,
        }
    }
}

impl std::fmt::Display for Finished {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Finished::Static(s) => s.fmt(f),
            Finished::Dynamic(s) => s.fmt(f),
            Finished::Interactive(s) => s.fmt(f),
        }
    }
}

/// A finished run and its final state (module docs).
#[derive(Clone, Debug)]
pub struct Solution {
    /// How the run ended, with its summary.
    pub finished: Finished,
    /// The displacement of every node of the finest level, 3 per node (m).
    pub u: Vec<f64>,
    /// The nodal Cauchy stress, 9 per node, row-major (Pa).
    pub nodal_stress: Vec<f64>,
    /// The measures of the final state: residual, `max |u|`, kinetic energy, reactions, the
    /// tools' force ([`Sample`]; `step` the stepper's steps, a static solve's Newton steps;
    /// `force_evals` and `wall` of the whole run).
    pub last: Sample,
    /// The applied loads and body forces `Σ_a V_a` at the final state (N).
    pub applied: [f64; 3],
    /// Per `[[displace]]` grasp taken during an interactive run (file order), the force the
    /// tissue exerts on it at the end (N); `None` for one let go by then. Empty for other
    /// runs.
    pub grasp_forces: Vec<Option<[f64; 3]>>,
}

/// Run `sc` to its end with its own stepper (module docs).
pub fn solve(sc: &Scenario, opts: RunOptions) -> Result<Solution> {
    if sc.integrator.statics.is_some() {
        let (summary, mut stepper) = run_static_keeping(sc, opts)?;
        return Ok(finish(
            Finished::Static(summary),
            &mut stepper,
            sc,
            Vec::new(),
        ));
    }
    solve_with(sc, sc.stepper()?, opts)
}

/// [`solve`] with a stepper built already ([`Scenario::stepper`]; `raisov run` prints its
/// report first). A static scenario is solved by its own solver, `stepper` unused.
pub fn solve_with(
    sc: &Scenario,
    mut stepper: Box<dyn Stepper>,
    opts: RunOptions,
) -> Result<Solution> {
    if sc.integrator.statics.is_some() {
        return solve(sc, opts);
    }
    if sc.interactive.is_none() {
        let summary = run_with(sc, stepper.as_mut(), opts)?;
        return Ok(finish(
            Finished::Dynamic(summary),
            stepper.as_mut(),
            sc,
            Vec::new(),
        ));
    }
    let mut replay = Replay::new(sc, stepper)?;
    let summary = run_frames(sc, &mut replay, opts)?;
    let grasps = replay.grasp_forces();
    Ok(finish(
        Finished::Interactive(summary),
        replay.stepper(),
        sc,
        grasps,
    ))
}

/// The solution of a finished run: the finest level's state as it ended.
fn finish(
    finished: Finished,
    stepper: &mut dyn Stepper,
    sc: &Scenario,
    grasp_forces: Vec<Option<[f64; 3]>>,
) -> Solution {
    let _ = sc;
    // A static solve counts its Newton steps (as its `measures.csv` does).
    let (steps, evals) = match &finished {
        Finished::Static(s) => (
            s.report.newton_steps as u64,
            s.report.force_evaluations as f64,
        ),
        _ => (stepper.steps(), stepper.force_evaluations()),
    };
    let (sys, s) = stepper.finest();
    // The finest level's node count: the scenario's mesh's, or more after a cut.
    let n = sys.num_nodes();
    let mut last = Meter::new(n, None).sample(sys, s, steps);
    last.force_evals = evals;
    last.wall = finished.wall();
    let mut nodal_stress = vec![0.0; 9 * n];
    sys.force.nodal_stress(&s.u, &mut nodal_stress);
    let mut applied = sys.force.load_report(&s.u).applied;
    for (i, f) in sys.f_ext.iter().enumerate() {
        applied[i % 3] += f;
    }
    Solution {
        finished,
        u: s.u.clone(),
        nodal_stress,
        last,
        applied,
        grasp_forces,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    /// A neo-Hookean cube of 3 × 3 × 3 boxes (0.03 m) held at z = 0 under gravity, its top
    /// pressed down by 2 N in all; `extra` appended.
    fn cube(extra: &str) -> Scenario {
        let text = format!(
            r#"
name = "cube"
gravity = [0.0, 0.0, -9.81]
[mesh]
generate = "box"
size = [0.03, 0.03, 0.03]
divisions = [3, 3, 3]
[material]
law = "neo-hookean"
young = 5e3
poisson = 0.45
[[fix]]
plane = {{ point = [0, 0, 0], normal = [0, 0, 1] }}
{extra}
"#
        );
        Scenario::from_toml(&text, Path::new("cube.toml")).unwrap()
    }

    const STATIC: &str = "[integrator]\nmethod = \"newton\"\n[run]\nresidual_tol = 1e-10\n";
    const DYNAMIC: &str = "[damping]\nalpha = 200.0\n[run]\nduration = 0.02\n";

    fn in_memory(dir: &Path) -> RunOptions<'static> {
        RunOptions {
            out_dir: Some(dir.to_path_buf()),
            in_memory: true,
            ..Default::default()
        }
    }

    fn written(dir: &Path) -> RunOptions<'static> {
        RunOptions {
            out_dir: Some(dir.to_path_buf()),
            ..Default::default()
        }
    }

    /// Every entry of `dir`, recursively.
    fn entries(dir: &Path) -> Vec<std::path::PathBuf> {
        let mut v = Vec::new();
        for e in std::fs::read_dir(dir).unwrap().flatten() {
            v.push(e.path());
            if e.path().is_dir() {
                v.extend(entries(&e.path()));
            }
        }
        v
    }

    /// The nodal stress and displacement columns of `nodal_stress.csv` in `dir` (file order
    /// is the scenario's: the box is not renumbered).
    fn stress_file(dir: &Path) -> Vec<Vec<f64>> {
        std::fs::read_to_string(dir.join("nodal_stress.csv"))
            .unwrap()
            .lines()
            .skip(1)
            .map(|l| l.split(',').skip(4).map(|x| x.parse().unwrap()).collect())
            .collect()
    }

    /// A static solve kept in memory writes nothing (not even its output directory), gives
    /// the bits of the same solve written to files, and its state is an equilibrium: the
    /// reactions of the base balance gravity.
    #[test]
    fn a_static_solve_in_memory_writes_nothing_and_equals_the_written_one() {
        let sc = cube(STATIC);
        let dir = tempfile::tempdir().unwrap();
        let mem = solve(&sc, in_memory(&dir.path().join("mem"))).unwrap();
        assert!(
            !dir.path().join("mem").exists(),
            "a run in memory made its directory"
        );
        assert!(mem.finished.success(), "{}", mem.finished);
        assert_eq!(mem.finished.kind(), "static");
        assert!(mem.finished.to_string().contains("none (kept in memory)"));
        let file = solve(&sc, written(&dir.path().join("file"))).unwrap();
        assert_eq!(mem.u, file.u, "the same solve, other bits");
        assert_eq!(mem.nodal_stress, file.nodal_stress);
        // What was written is what was kept: the displacement and stress per node.
        let rows = stress_file(&dir.path().join("file"));
        assert_eq!(rows.len(), sc.mesh.num_nodes());
        for (a, row) in rows.iter().enumerate() {
            for k in 0..3 {
                let x = mem.u[3 * a + k];
                assert!((row[k] - x).abs() <= 1e-9 * x.abs().max(1e-12), "u {a} {k}");
            }
            for k in 0..9 {
                let t = mem.nodal_stress[9 * a + k];
                assert!(
                    (row[3 + k] - t).abs() <= 1e-6 * t.abs().max(1e-3),
                    "T {a} {k}"
                );
            }
        }
        // Equilibrium: the base carries the weight, F_fixed + Σ V = 0.
        let w = mem.applied;
        assert!(w[2] < 0.0, "gravity pulls down: {w:?}");
        for k in 0..3 {
            let gap = mem.last.reaction_fixed[k] + w[k];
            assert!(gap.abs() <= 1e-8 * w[2].abs(), "balance {k}: {gap:e}");
        }
        assert!(
            mem.last.residual <= 1e-9 * w[2].abs(),
            "{}",
            mem.last.residual
        );
        assert_eq!(mem.last.step as usize, mem_steps(&mem));
        assert!(mem.last.max_u > 0.0);
    }

    fn mem_steps(s: &Solution) -> usize {
        match &s.finished {
            Finished::Static(st) => st.report.newton_steps,
            _ => unreachable!(),
        }
    }

    /// A run in time kept in memory ends in the state of the same run written to files, bit
    /// for bit, and leaves an existing output directory as it was (nothing cleared).
    #[test]
    fn a_dynamic_run_in_memory_leaves_the_directory_alone() {
        let sc = cube(DYNAMIC);
        let dir = tempfile::tempdir().unwrap();
        let keep = dir.path().join("mem");
        std::fs::create_dir_all(&keep).unwrap();
        std::fs::write(keep.join("summary.txt"), "an earlier run's").unwrap();
        let mem = solve(&sc, in_memory(&keep)).unwrap();
        assert_eq!(mem.finished.kind(), "dynamic");
        assert!(mem.finished.success(), "{}", mem.finished);
        assert_eq!(
            std::fs::read_to_string(keep.join("summary.txt")).unwrap(),
            "an earlier run's"
        );
        assert_eq!(entries(&keep).len(), 1);
        let file = solve(&sc, written(&dir.path().join("file"))).unwrap();
        assert_eq!(mem.u, file.u);
        assert_eq!(mem.last.kinetic, file.last.kinetic);
        let Finished::Dynamic(d) = &file.finished else {
            panic!("{}", file.finished)
        };
        assert_eq!(d.last.max_u, mem.last.max_u);
        assert!(d.files.iter().all(|f| f.is_file()));
        assert_eq!(mem.last.time, d.simulated);
        assert!(d.simulated >= 0.02, "{}", d.simulated);
    }

    /// An interactive run with a grasp taken during it hands back the grasp's force: the
    /// tissue pulls a lifted patch down, and the patch, the base and gravity balance at the
    /// end of a held path (frames of 200 cycles settle it).
    #[test]
    fn an_interactive_run_hands_back_its_grasps_forces() {
        let sc = cube(
            "[damping]\nalpha = 300.0\n[run]\nduration = 0.5\n\
             [interactive]\nfps = 10.0\ncycles = 400\nreference = \"none\"\n\
             [[displace]]\npoint = [0.015, 0.015, 0.03]\nradius = 0.008\nstart = 0.0\n\
             table = [[0.0, 0, 0, 0], [0.2, 0, 0, 0.003], [0.5, 0, 0, 0.003]]\n",
        );
        let dir = tempfile::tempdir().unwrap();
        let s = solve(&sc, in_memory(dir.path())).unwrap();
        assert_eq!(s.finished.kind(), "interactive");
        assert!(s.finished.success(), "{}", s.finished);
        assert_eq!(s.grasp_forces.len(), 1);
        let g = s.grasp_forces[0].expect("held at the end");
        assert!(
            g[2] < 0.0,
            "the stretched tissue pulls the grasp down: {g:?}"
        );
        // The grasp's nodes are the prescribed ones: its force is minus their reaction, and
        // the base's reaction, the grasp's and gravity balance.
        for k in 0..3 {
            let scale = g[2].abs();
            assert!((g[k] + s.last.reaction_prescribed[k]).abs() <= 1e-9 * scale);
            let gap = s.last.reaction_fixed[k] - g[k] + s.applied[k];
            assert!(
                gap.abs() <= 1e-3 * scale,
                "{k}: grasp {g:?}, base {:?}, load {:?}",
                s.last.reaction_fixed,
                s.applied
            );
        }
        assert!(entries(dir.path()).is_empty(), "{:?}", entries(dir.path()));
    }
}
