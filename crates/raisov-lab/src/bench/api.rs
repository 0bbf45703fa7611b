//! `raisov bench api`: the embedding API's frame overhead and grasp-stiffness solves.

use raisov::{Error, Result};
use std::time::Instant;

/// The embedding API's figures (`raisov bench api`): the frame overhead of
/// [`raisov::sim::Simulation::step_frame`] over the bare stepper doing the same steps, and the
/// cost of [`raisov::sim::Simulation::grab_stiffness`] (conjugate-gradient iterations and
/// wall time, cold and warm-started from the previous frame's solutions) with the direct and
/// the multigrid preconditioner side by side.
///
/// Work: a cube of side 4 cm, `div³` cells of 6 tetrahedra, fixed at its base, under gravity,
/// compressible neo-Hookean (E = 5 kPa, ν = 0.45), FAS over 2 levels (one V-cycle per step).
/// The bare stepper and the simulation are built from the same scenario and advanced side by
/// side, frame after frame (`cycles` steps each, alternating which goes first), so frame `k`
/// of both does the same steps from the same state; the overhead is the ratio of the two
/// totals minus one. What the simulation adds per frame: saving the state for recovery and
/// observing the end state (node positions, the residual and the support forces from the
/// internal forces that the stepper's last sweep evaluated there, [`raisov::integrate::Stepper::finest_forces`]);
/// a frame of no steps (`Budget::Cycles(0)`) does exactly that and is timed alone (median of
/// 21), a figure the machine's noise disturbs less than the difference of two totals.
pub fn api(div: usize, frames: usize, emit: &mut dyn FnMut(&str)) -> Result<()> {
    use raisov::sim::{Budget, GrabOptions, Simulation};
    let text = format!(
        r#"
gravity = [0, 0, -9.81]
[mesh]
generate = "box"
size = [0.04, 0.04, 0.04]
divisions = [{div}, {div}, {div}]
[material]
law = "neo-hookean"
young = 5e3
poisson = 0.45
[[fix]]
plane = {{ point = [0, 0, 0], normal = [0, 0, 1] }}
[multigrid]
scheme = "fas"
levels = 2
[run]
duration = 1.0
"#
    );
    let sc = raisov::scenario::Scenario::from_toml(&text, std::path::Path::new("bench-api.toml"))?;
    emit(&format!(
        "raisov bench api: cube {div}^3 cells, {} nodes, FAS 2 levels, {} thread(s)",
        sc.mesh.num_nodes(),
        rayon::current_num_threads()
    ));
    for cycles in [1u32, 4] {
        let mut bare = sc.stepper()?;
        bare.set_kinetic_limit(f64::INFINITY);
        let mut sim = Simulation::from_scenario(&sc)?;
        let (mut t_bare, mut t_sim) = (0.0f64, 0.0f64);
        let mut ratios = Vec::with_capacity(frames);
        for frame in 0..frames {
            let mut run_bare = || -> Result<f64> {
                let t = Instant::now();
                for _ in 0..cycles {
                    bare.advance().map_err(Error::Diverged)?;
                }
                Ok(t.elapsed().as_secs_f64())
            };
            let mut run_sim = || -> Result<f64> {
                let t = Instant::now();
                let r = sim.step_frame(Budget::Cycles(cycles));
                let dt = t.elapsed().as_secs_f64();
                if !r.accepted {
                    return Err(Error::param("bench api", "a frame was rejected"));
                }
                Ok(dt)
            };
            let (b, s) = if frame % 2 == 0 {
                let b = run_bare()?;
                (b, run_sim()?)
            } else {
                let s = run_sim()?;
                (run_bare()?, s)
            };
            // The first frames warm the caches and the λ_max estimates.
            if frame >= 2 {
                t_bare += b;
                t_sim += s;
                ratios.push(s / b);
            }
        }
        // Same steps, same bits.
        if bare.state().u != sim.displacements() {
            return Err(Error::param(
                "bench api",
                "the simulation and the bare stepper diverged",
            ));
        }
        // The fixed cost of a frame alone: a frame of no steps saves the recovery checkpoint
        // and observes the state (positions, forces from the stepper, residual, reactions),
        // all a frame adds to its steps. Median of 21.
        let mut fixed: Vec<f64> = (0..21)
            .map(|_| {
                let t = Instant::now();
                sim.step_frame(Budget::Cycles(0));
                t.elapsed().as_secs_f64()
            })
            .collect();
        fixed.sort_by(f64::total_cmp);
        let fixed_ms = 1e3 * fixed[fixed.len() / 2];
        ratios.sort_by(f64::total_cmp);
        let median = ratios[ratios.len() / 2];
        let n = ratios.len() as f64;
        emit(&format!(
            "  frames of {cycles} cycle(s), {} timed: bare stepper {:.3} ms/frame, Simulation::step_frame {:.3} ms/frame; overhead {:+.2} % (totals), median of per-frame ratios {:+.2} %; fixed cost of a frame (Cycles(0)) {fixed_ms:.3} ms = {:.2} % of the bare frame",
            ratios.len(),
            1e3 * t_bare / n,
            1e3 * t_sim / n,
            100.0 * (t_sim / t_bare - 1.0),
            100.0 * (median - 1.0),
            100.0 * fixed_ms / (1e3 * t_bare / n)
        ));
    }
    // grab_stiffness: cold, then warm-started from the previous frame's solutions, with each
    // preconditioner on the same states (two simulations stepped alike).
    use raisov::sim::TangentPreconditioner as Tp;
    for (label, options) in [
        ("hard grasp", GrabOptions::hard(0.011)),
        ("spring grasp, k = 50 N/m", GrabOptions::spring(0.011, 50.0)),
    ] {
        let mut sims = Vec::new();
        for p in [Tp::Direct, Tp::Multigrid] {
            let mut sim = Simulation::from_scenario(&sc)?;
            sim.set_tangent_preconditioner(p);
            sims.push(sim);
        }
        let mut line = Vec::new();
        let mut kzz = Vec::new();
        let mut nodes = 0;
        for sim in &mut sims {
            let g = sim.grab_with([0.02, 0.02, 0.05], options)?;
            nodes = sim.grab_nodes(g)?.len();
            let p = sim.grab_position(g)?;
            let mut lift = 0.0;
            for _ in 0..10 {
                lift += 0.0004;
                sim.move_grab(g, [p[0], p[1], p[2] + lift])?;
                sim.step_frame(Budget::Cycles(4));
            }
            let t = Instant::now();
            let k0 = sim.grab_stiffness(g)?;
            let (cold_ms, cold_it) = (1e3 * t.elapsed().as_secs_f64(), sim.tangent_iterations());
            let cold_setups = sim.tangent_stats().setups;
            let mut warm = Vec::new();
            for _ in 0..3 {
                lift += 0.0004;
                sim.move_grab(g, [p[0], p[1], p[2] + lift])?;
                sim.step_frame(Budget::Cycles(4));
                let t = Instant::now();
                sim.grab_stiffness(g)?;
                warm.push((1e3 * t.elapsed().as_secs_f64(), sim.tangent_iterations()));
            }
            let (wm, wi) = warm.iter().fold((0.0, 0), |(a, b), (c, d)| (a + c, b + d));
            line.push(format!(
                "{:?}: cold {cold_it} iterations in {cold_ms:.1} ms ({cold_setups} factorisation or hierarchy), warm {:.0} iterations in {:.1} ms",
                sim.tangent_stats().preconditioner,
                wi as f64 / 3.0,
                wm / 3.0
            ));
            kzz.push(k0[2][2]);
        }
        emit(&format!(
            "  grab_stiffness, {label} ({nodes} nodes; 3 solves, warm: mean of 3 frames): {}; K_zz = {:.3} / {:.3} N/m",
            line.join("; "),
            kzz[0],
            kzz[1]
        ));
    }
    Ok(())
}
