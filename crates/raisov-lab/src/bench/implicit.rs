//! `raisov bench implicit`: the cost of backward Euler and BDF2 ([`raisov::statics::implicit`])
//! per step and per simulated second on the liver L0, against explicit central differences.
//!
//! Work: the liver L0 (`data/liver_L0.msh`, millimetres scaled to metres), held on the cap of
//! its top (z ≥ 195 mm), compressible neo-Hookean (E = 5 kPa, ν = 0.45, ρ = 1060 kg/m³),
//! undamped, dropped from rest under gravity at t = 0; the state at t = 0.1 s.
//!
//! - Backward Euler at h = 1/60, 1/250 and 1/1000 s, each step's Newton systems solved by CG
//!   preconditioned by the Galerkin V-cycle over L0 and the coarser level that
//!   [`raisov::statics::newton::coarse_level`] picks of L1-L3 (the scenario's
//!   `solver = "auto"`), the default tolerance: per step the wall time, Newton iterations,
//!   CG iterations and force evaluations (internal forces and energies, finest-level units).
//!   BDF2 (`method = "bdf2"`) at the same steps, the same solver and tolerance: its rows
//!   follow backward Euler's.
//! - Central differences at its default step (0.5 × the estimated critical step).
//! - Accuracy: the relative error `max_a |u_a − u*_a| / max_a |u*_a|` of the displacements at
//!   t = 0.1 s, `u*` central differences at a quarter of that step (second order: its own
//!   error is about 1/16 of the default step's).
//! - Per simulated second: the wall time and the force evaluations; central differences is
//!   more accurate at its stable step than backward Euler at any of these steps, and no
//!   explicit run is cheaper than at its stable step, so its row is the explicit cost at any
//!   of these accuracies. The last line estimates the backward-Euler step with central
//!   differences' error, at first order from h = 1/1000 s (`h · e_cd / e_h`), and the cost per
//!   simulated second there at h = 1/1000 s's cost per step (an underestimate: smaller steps
//!   need fewer Newton iterations).

use raisov::integrate::Stepper;
use raisov::scenario::Scenario;
use raisov::{Error, Result};
use std::path::Path;
use std::time::Instant;

/// The simulated time of every run (s).
const T_END: f64 = 0.1;

/// The scenario of the work (module docs) with `integrator` as its `[integrator]` section.
fn scenario(meshes: &Path, integrator: &str, levels: bool) -> Result<Scenario> {
    let multigrid = if levels {
        "[multigrid]\nfiles = [\"liver_L1.msh\", \"liver_L2.msh\", \"liver_L3.msh\"]\n"
    } else {
        ""
    };
    let text = format!(
        r#"
gravity = [0.0, 0.0, -9.81]
[mesh]
file = "liver_L0.msh"
scale = 0.001
[material]
law = "neo-hookean"
young = 5000.0
poisson = 0.45
density = 1060.0
[[fix]]
plane = {{ point = [0.0, 0.0, 0.195], normal = [0.0, 0.0, -1.0] }}
[integrator]
{integrator}
[run]
duration = {T_END}
{multigrid}"#
    );
    Scenario::from_toml(&text, &meshes.join("bench-implicit.toml"))
}

/// One run to [`T_END`].
struct Run {
    label: String,
    h: f64,
    steps: u64,
    wall: f64,
    newton: Option<(u64, u64)>,
    evaluations: f64,
    u: Vec<f64>,
}

fn run_to_end(label: String, st: &mut dyn Stepper) -> Result<Run> {
    st.set_kinetic_limit(f64::INFINITY);
    let h = st.dt();
    let steps = (T_END / h).round() as u64;
    let clock = Instant::now();
    for _ in 0..steps {
        st.advance().map_err(Error::Diverged)?;
    }
    let wall = clock.elapsed().as_secs_f64();
    Ok(Run {
        label,
        h,
        steps,
        wall,
        newton: None,
        evaluations: st.force_evaluations(),
        u: st.state().u.clone(),
    })
}

fn rel_error(u: &[f64], reference: &[f64]) -> f64 {
    let scale = reference.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let diff = u
        .iter()
        .zip(reference)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    diff / scale.max(f64::MIN_POSITIVE)
}

/// The table of the module docs, a line at a time through `emit`; meshes from `meshes`
/// (`data/`). `quick`: h = 1/60 and 1/250 s only.
pub fn implicit(meshes: &Path, quick: bool, emit: &mut dyn FnMut(&str)) -> Result<()> {
    let cd = scenario(meshes, "method = \"central-difference\"", false)?;
    emit(&format!(
        "raisov bench implicit: liver L0 ({} nodes, {} elements) held at its top, dropped under gravity, undamped, to t = {T_END} s; {} thread(s)",
        cd.mesh.num_nodes(),
        cd.mesh.num_elements(),
        rayon::current_num_threads()
    ));
    let dt_cd = cd.integrator.dt;
    let fine = scenario(
        meshes,
        &format!("method = \"central-difference\"\ndt = {:e}", 0.25 * dt_cd),
        false,
    )?;
    emit(&format!(
        "reference: central differences at dt = {:.3e} s (a quarter of its default step)",
        0.25 * dt_cd
    ));
    let reference = run_to_end("reference".into(), &mut *fine.stepper()?)?;
    let mut runs = vec![run_to_end(
        format!("central-difference (explicit), dt = {dt_cd:.3e} s"),
        &mut *cd.stepper()?,
    )?];
    let steps: &[(u32, &str)] = if quick {
        &[(60, "1/60"), (250, "1/250")]
    } else {
        &[(60, "1/60"), (250, "1/250"), (1000, "1/1000")]
    };
    for method in ["implicit-euler", "bdf2"] {
        for &(per_second, label) in steps {
            let sc = scenario(
                meshes,
                &format!("method = \"{method}\"\ndt = {:e}", 1.0 / per_second as f64),
                true,
            )?;
            let mut st = sc.implicit_euler()?;
            emit(&format!("{method} h = {label} s: {}", st.describe()));
            let mut run = run_to_end(format!("{method}, h = {label} s"), &mut st)?;
            let c = st.counts();
            run.newton = Some((c.newton, c.cg));
            emit(&format!("  {}", st.diagnostics().unwrap_or_default()));
            runs.push(run);
        }
    }
    emit("");
    emit("| method | steps | wall ms/step | Newton/step | CG/step | force evals/step | rel. error at 0.1 s | wall s per simulated s | force evals per simulated s |");
    emit("|---|---:|---:|---:|---:|---:|---:|---:|---:|");
    for r in &runs {
        let per = |x: f64| x / r.steps.max(1) as f64;
        let (newton, cg) = match r.newton {
            Some((n, c)) => (
                format!("{:.2}", per(n as f64)),
                format!("{:.1}", per(c as f64)),
            ),
            None => ("-".into(), "-".into()),
        };
        emit(&format!(
            "| {} | {} | {:.1} | {newton} | {cg} | {:.1} | {:.2e} | {:.2} | {:.3e} |",
            r.label,
            r.steps,
            1e3 * per(r.wall),
            per(r.evaluations),
            rel_error(&r.u, &reference.u),
            r.wall / T_END,
            r.evaluations / T_END,
        ));
    }
    let e_cd = rel_error(&runs[0].u, &reference.u);
    if let Some(last) = runs
        .iter()
        .rev()
        .find(|r| r.label.starts_with("implicit-euler"))
    {
        let e_h = rel_error(&last.u, &reference.u);
        let h_match = last.h * e_cd / e_h.max(f64::MIN_POSITIVE);
        let per_step_wall = last.wall / last.steps as f64;
        let per_step_eval = last.evaluations / last.steps as f64;
        emit("");
        emit(&format!(
            "implicit Euler at central differences' error {e_cd:.2e}: h ≈ {h_match:.2e} s (first order from {}), ≈ {:.2e} s wall and {:.2e} force evaluations per simulated second at that row's cost per step; central differences: {:.2e} s and {:.2e}",
            last.label,
            per_step_wall / h_match,
            per_step_eval / h_match,
            runs[0].wall / T_END,
            runs[0].evaluations / T_END,
        ));
    }
    Ok(())
}
