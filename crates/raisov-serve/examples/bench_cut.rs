//! Bench of the scalpel in the live viewer (prints numbers; not a test): the liver of
//! `examples/liver_interactive.toml` (L1 finest, L2, L3) under FAS
//! served as the viewer builds it, cut the way the page cuts it from its starting view —
//! `CUTS` short blades along a horizontal line across the front of the organ's middle, each
//! the edge between two points 1 cm apart (2 mm in front of the surface) swept 2.2 cm along
//! the view direction +y — and stepped at a fixed budget of `CYCLES` V-cycles per frame.
//! Printed: each cut's wall time (what a viewer waits between two frames), the elements it
//! split per level, the surface's triangle count, and the frame time (mean of 20 frames
//! at rest) before the first cut and after the last (the first frame after it apart).
//!
//! `cargo run --release -p raisov-serve --example bench_cut [-- CUTS [CYCLES]]`

use raisov::mesh::cut::Blade;
use raisov::sim::{Budget, Simulation};
use raisov::SchemeKind;
use raisov_serve::session::Source;
use std::path::PathBuf;
use std::time::Instant;

fn frames(sim: &mut Simulation, budget: Budget, n: usize) -> f64 {
    let t = Instant::now();
    for _ in 0..n {
        let r = sim.step_frame(budget);
        assert!(r.accepted, "{r:?}");
    }
    t.elapsed().as_secs_f64() * 1e3 / n as f64
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let cuts: usize = args.first().map_or(Ok(5), |a| a.parse())?;
    let cycles: u32 = args.get(1).map_or(Ok(2), |a| a.parse())?;
    let root = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."));
    let source = Source::from_scenario_file(&root.join(raisov_serve::DEFAULT_SCENARIO))?;
    let mut sim = source.build(SchemeKind::Fas)?;
    let budget = Budget::Cycles(cycles);
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in sim.positions() {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let c = [
        0.5 * (lo[0] + hi[0]),
        0.5 * (lo[1] + hi[1]),
        0.5 * (lo[2] + hi[2]),
    ];
    println!(
        "liver: {} nodes, {} elements, {} surface triangles; FAS, {cycles} V-cycle(s) a frame",
        sim.mesh().num_nodes(),
        sim.mesh().num_elements(),
        sim.surface_triangles().len()
    );
    let before = frames(&mut sim, budget, 20);
    println!("frame before any cut: {before:.1} ms");
    // The front surface at the middle: the least y of the nodes within 1 cm of (cx, ·, cz).
    let front = sim
        .positions()
        .iter()
        .filter(|p| (p[0] - c[0]).abs() < 0.01 && (p[2] - c[2]).abs() < 0.01)
        .map(|p| p[1])
        .fold(f64::INFINITY, f64::min);
    let (y, z) = (front - 0.002, c[2]);
    for k in 0..cuts {
        let x0 = c[0] - 0.5e-2 * cuts as f64 + 1e-2 * k as f64;
        let blade = Blade::swept([x0, y, z], [x0 + 1e-2, y, z], [0.0, 0.022, 0.0])?;
        let t = Instant::now();
        let r = sim.cut(&blade)?;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        println!(
            "cut {}: {ms:.1} ms (report {:.1} ms), split per level {:?}, {} nodes, {} surface triangles",
            k + 1,
            r.seconds * 1e3,
            r.split,
            r.nodes,
            sim.surface_triangles().len()
        );
    }
    let first = frames(&mut sim, budget, 1);
    let after = frames(&mut sim, budget, 20);
    println!(
        "frame after {cuts} cut(s): the first {first:.1} ms, then {after:.1} ms ({:.2}x the \
         uncut frame)",
        after / before
    );
    Ok(())
}
