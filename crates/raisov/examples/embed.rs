//! Embedding raisov in a host loop: build a simulation from a scenario string, grasp the top
//! of a block of tissue, lift it over a few frames and print the tool force; then time the
//! API's per-frame overhead against calling the bare stepper.
//!
//! `cargo run --release --example embed [-- FRAMES CYCLES]` (default 20 frames of 4 cycles
//! for the overhead measurement).

use raisov::scenario::Scenario;
use raisov::sim::{Budget, Simulation};
use std::path::Path;
use std::time::Instant;

const SCENARIO: &str = r#"
gravity = [0, 0, -9.81]
[mesh]
generate = "box"
size = [0.06, 0.06, 0.04]
divisions = [12, 12, 8]
[material]
law = "neo-hookean"
young = 5e3
poisson = 0.45
[[fix]]
plane = { point = [0, 0, 0], normal = [0, 0, 1] }
[multigrid]
scheme = "fas"
levels = 2
[run]
duration = 1.0
"#;

fn main() -> Result<(), raisov::Error> {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let frames = args.first().copied().unwrap_or(20);
    let cycles = args.get(1).copied().unwrap_or(4) as u32;

    let mut sim = Simulation::from_toml(SCENARIO, ".")?;
    println!(
        "{} nodes; {}",
        sim.positions().len(),
        sim.stepper().describe()
    );
    let g = sim.grab([0.03, 0.03, 0.05], 0.006)?;
    let start = sim.grab_position(g)?;
    println!(
        "grasped {} nodes at {:.4?} m",
        sim.grab_nodes(g)?.len(),
        start
    );
    // Lift by 8 mm over 20 frames, then hold for 10.
    for frame in 0..30 {
        let lift = 0.008 * (frame + 1).min(20) as f64 / 20.0;
        sim.move_grab(g, [start[0], start[1], start[2] + lift])?;
        let r = sim.step_frame(Budget::Cycles(4));
        if frame % 5 == 4 {
            let f = sim.grab_force(g)?;
            println!(
                "frame {:2}: lift {:.1} mm, force on the tool [{:+.4}, {:+.4}, {:+.4}] N, residual {:.2e} N, {} cycles, {} retries",
                frame + 1,
                lift * 1e3,
                f[0],
                f[1],
                f[2],
                r.residual,
                r.cycles,
                r.retries
            );
        }
    }
    let k = sim.grab_stiffness(g)?;
    println!("grasp stiffness (N/m): {k:.1?}");
    let react = sim.reactions();
    println!(
        "supports take [{:+.4}, {:+.4}, {:+.4}] N, the load is {:+.4?} N",
        react.sum[0],
        react.sum[1],
        react.sum[2],
        sim.total_load()
    );

    // Overhead of the API over the bare stepper: the same frames (the grasp held still),
    // alternating which goes first, best of 3 rounds.
    let sc = Scenario::from_toml(SCENARIO, Path::new("./scenario.toml"))?;
    let mut bare = sc.stepper()?;
    let mut api = Simulation::from_scenario(&sc)?;
    let mut best = (f64::INFINITY, f64::INFINITY);
    for round in 0..5 {
        let mut time_api = || {
            let t = Instant::now();
            for _ in 0..frames {
                let r = api.step_frame(Budget::Cycles(cycles));
                assert!(r.accepted);
            }
            t.elapsed().as_secs_f64()
        };
        let (a, b);
        if round % 2 == 0 {
            a = time_api();
            let t = Instant::now();
            for _ in 0..frames * cycles as usize {
                bare.advance()?;
            }
            b = t.elapsed().as_secs_f64();
        } else {
            let t = Instant::now();
            for _ in 0..frames * cycles as usize {
                bare.advance()?;
            }
            b = t.elapsed().as_secs_f64();
            a = time_api();
        }
        best = (best.0.min(a), best.1.min(b));
    }
    println!(
        "overhead: {frames} frames of {cycles} cycles: API {:.3} ms/frame, bare stepper {:.3} ms/frame, overhead {:+.2} %",
        best.0 * 1e3 / frames as f64,
        best.1 * 1e3 / frames as f64,
        100.0 * (best.0 / best.1 - 1.0)
    );
    // The API's own work per frame alone: frames of no cycles (save the state, evaluate the
    // internal forces for the residual, supports and grasp forces), best of 5.
    let mut fixed = f64::INFINITY;
    for _ in 0..5 {
        let t = Instant::now();
        for _ in 0..frames {
            api.step_frame(Budget::Cycles(0));
        }
        fixed = fixed.min(t.elapsed().as_secs_f64() / frames as f64);
    }
    println!(
        "API work per frame without cycles: {:.3} ms ({:.1} % of one cycle of the bare stepper)",
        fixed * 1e3,
        100.0 * fixed / (best.1 / (frames * cycles as usize) as f64)
    );
    Ok(())
}
