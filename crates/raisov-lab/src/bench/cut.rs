//! `raisov bench cut`: what a scalpel costs ([`raisov::sim::Simulation::cut`]: the virtual
//! node algorithm on every level) and whether the cut body keeps running.
//!
//! Work:
//! - **One cut across the liver L0 hierarchy** (`data/liver_L{0,1,2,3}.msh`, millimetres
//!   scaled to metres; FAS over the four levels), held on the cap z ≥ 0.195 m, E = 5 kPa,
//!   ν = 0.45, ρ = 1060 kg/m³, each law (neo-Hookean, stable neo-Hookean), 2 V-cycles a
//!   frame; the frame benchmark's spring grasp (200 N/m, the 10 mm patch nearest
//!   (0.12, 0.07, 0.10) m) pulled (0, −1, −1.7) cm over twenty frames, then held while twenty
//!   frames are timed; then a blade
//!   with a 3 cm edge along x, centred under the middle of the liver's lower surface, swept
//!   3 cm up into it, cuts every level; twenty frames are timed after it. A second cut, 1 cm
//!   beside the first and parallel to it, is timed too (the first builds the levels' face
//!   adjacency once). Printed: the elements split per level, the nodes and elements after,
//!   the cut's wall time, and the frame rate before and after with its ratio (target: the cut
//!   within one frame budget, 16 ms, and the frame rate after within 10 % of before).
//! - **1 000 random cuts on the liver L1 hierarchy** (L1, L2, L3; FAS; stable neo-Hookean)
//!   with gravity and a spring grasp of 200 N/m pulled 1 cm down: each blade has an edge of
//!   1 to 3 cm in a random direction through a random boundary node, swept 0.5 to 3 cm along
//!   a random direction across the edge (a fixed seed: the same blades on every run); after
//!   each cut two frames of 2 V-cycles. Counted as failures: a cut or frame that panics, a
//!   cut refused, a frame rejected (an element inverted, a value not finite: the state
//!   before it kept), a position that is not finite, and a total mass that moved by more
//!   than 10⁻¹⁰ of itself (`MASS_TOL`: rounding). Printed: the failures by kind (target 0),
//!   the largest relative change of the total mass, the cuts that split an element, the
//!   mesh's growth, and the cut time's median and largest.

use raisov::mesh::cut::Blade;
use raisov::scenario::Scenario;
use raisov::sim::{Budget, GrabOptions, Simulation};
use raisov::{Error, Result};
use std::path::Path;
use std::time::Instant;

/// The organ scenario: level files `levels` (first the finest), `law`, gravity (m/s², along
/// z), the cap held.
fn scenario(meshes: &Path, levels: &[&str], law: &str, gravity: f64) -> Result<Scenario> {
    let coarse: Vec<String> = levels[1..].iter().map(|l| format!("\"{l}\"")).collect();
    let text = format!(
        r#"
gravity = [0.0, 0.0, {gravity:?}]
[mesh]
file = "{fine}"
scale = 0.001
[material]
law = "{law}"
young = 5000.0
poisson = 0.45
density = 1060.0
[[fix]]
plane = {{ point = [0.0, 0.0, 0.195], normal = [0.0, 0.0, -1.0] }}
[run]
duration = 1.0
[multigrid]
scheme = "fas"
files = [{coarse}]
"#,
        fine = levels[0],
        coarse = coarse.join(", ")
    );
    Scenario::from_toml(&text, &meshes.join("bench-cut.toml"))
}

/// Mean wall time of `frames` frames of 2 V-cycles (ms), and the rejected ones.
fn frame_ms(sim: &mut Simulation, frames: usize) -> (f64, usize) {
    let mut rejected = 0;
    let t0 = Instant::now();
    for _ in 0..frames {
        if !sim.step_frame(Budget::Cycles(2)).accepted {
            rejected += 1;
        }
    }
    (t0.elapsed().as_secs_f64() * 1e3 / frames as f64, rejected)
}

/// A blade along x at `y`, its edge 3 cm long centred on `x`, from 5 mm below `z` swept 3 cm
/// up.
fn blade_at(x: f64, y: f64, z: f64) -> Result<Blade> {
    Blade::swept(
        [x - 0.015, y, z - 0.005],
        [x + 0.015, y, z - 0.005],
        [0.0, 0.0, 0.035],
    )
}

/// The one-cut part (module docs).
fn one_cut(meshes: &Path, out: &mut dyn FnMut(&str)) -> Result<()> {
    let levels = [
        "liver_L0.msh",
        "liver_L1.msh",
        "liver_L2.msh",
        "liver_L3.msh",
    ];
    for law in ["neo-hookean", "stable-neo-hookean"] {
        let sc = scenario(meshes, &levels, law, 0.0)?;
        let mut sim = Simulation::from_scenario(&sc)?;
        // The frame benchmark's spring grasp, pulled (0, -1, -1.7) cm over 20 frames.
        let g = sim.grab_with([0.12, 0.07, 0.10], GrabOptions::spring(0.01, 200.0))?;
        let p = sim.grab_position(g)?;
        for k in 1..=20 {
            let s = k as f64 / 20.0;
            sim.move_grab(g, [p[0], p[1] - 0.01 * s, p[2] - 0.017 * s])?;
            sim.step_frame(Budget::Cycles(2));
        }
        let m = sim.mesh();
        let (lo, hi) = m.nodes.iter().fold(
            ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
            |(mut lo, mut hi), p| {
                for k in 0..3 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
                (lo, hi)
            },
        );
        let (cx, cy) = (0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]));
        // The lower surface under the middle: the lowest node within 5 mm of the vertical.
        let bottom = m
            .nodes
            .iter()
            .filter(|p| (p[0] - cx).hypot(p[1] - cy) < 0.005)
            .map(|p| p[2])
            .fold(f64::INFINITY, f64::min);
        let (n0, e0) = (m.num_nodes(), m.num_elements());
        let (before, rej0) = frame_ms(&mut sim, 20);
        let first = sim.cut(&blade_at(cx, cy, bottom)?)?;
        let (after, rej1) = frame_ms(&mut sim, 20);
        let second = sim.cut(&blade_at(cx, cy + 0.01, bottom)?)?;
        let (after2, rej2) = frame_ms(&mut sim, 20);
        out(&format!(
            "liver L0 hierarchy, {law}: {n0} nodes, {e0} elements; 2 V-cycles a frame"
        ));
        for (name, r) in [("first cut: ", &first), ("second cut:", &second)] {
            out(&format!(
                "  {name} split {:?} elements (L0..L3), {} ms (levels and links {}, stepper {}, simulation {}); now {} nodes, {} elements",
                r.split,
                fmt_ms(r.seconds),
                fmt_ms(r.levels_seconds),
                fmt_ms(r.stepper_seconds),
                fmt_ms(r.seconds - r.levels_seconds - r.stepper_seconds),
                r.nodes,
                r.elements
            ));
        }
        out(&format!(
            "  frames: {:.1} ms before ({:.1} fps), {:.1} ms after one cut ({:.1} fps, ratio {:.2}), {:.1} ms after two ({:.1} fps); rejected {}/{}/{} of 20",
            before,
            1e3 / before,
            after,
            1e3 / after,
            before / after,
            after2,
            1e3 / after2,
            rej0,
            rej1,
            rej2
        ));
        let worst = first.seconds.max(second.seconds) * 1e3;
        out(&format!(
            "  goal: cut <= 16 ms: {} ({:.1} ms); frame rate after within 10 %: {} ({:+.1} %)",
            if worst <= 16.0 { "met" } else { "NOT met" },
            worst,
            if after <= 1.1 * before {
                "met"
            } else {
                "NOT met"
            },
            100.0 * (before / after - 1.0)
        ));
    }
    Ok(())
}

fn fmt_ms(s: f64) -> String {
    format!("{:.1}", s * 1e3)
}

/// xorshift64*: the random blades' numbers, the same on every machine.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next()
    }
    fn unit(&mut self) -> [f64; 3] {
        loop {
            let v = [
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
            ];
            let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            if l > 0.1 && l <= 1.0 {
                return v.map(|x| x / l);
            }
        }
    }
}

/// A total mass that moved by more than this, relative, counts as a failure: the rounding of
/// summing 10⁵ masses (`n ε ≈ 10⁻¹¹`) with room for the random walk of a thousand cuts'
/// recomputations (each cut rebuilds the masses from the fractions, the density from the
/// total before it).
const MASS_TOL: f64 = 1e-10;

/// The random-cuts part (module docs).
fn random_cuts(meshes: &Path, cuts: usize, out: &mut dyn FnMut(&str)) -> Result<()> {
    let sc = scenario(
        meshes,
        &["liver_L1.msh", "liver_L2.msh", "liver_L3.msh"],
        "stable-neo-hookean",
        -9.81,
    )?;
    let mut sim = Simulation::from_scenario(&sc)?;
    let (n0, e0) = (sim.mesh().num_nodes(), sim.mesh().num_elements());
    let g = sim.grab_with([0.12, 0.07, 0.10], GrabOptions::spring(0.01, 200.0))?;
    let p = sim.grab_position(g)?;
    sim.move_grab(g, [p[0], p[1], p[2] - 0.01])?;
    frame_ms(&mut sim, 10);
    let mass0: f64 = sim.masses().iter().sum();
    let boundary: Vec<[f64; 3]> = {
        let m = sim.mesh();
        let mut on = vec![false; m.num_nodes()];
        for t in m.surface_triangles() {
            for i in t {
                on[i as usize] = true;
            }
        }
        (0..m.num_nodes())
            .filter(|&a| on[a])
            .map(|a| m.nodes[a])
            .collect()
    };
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let (mut panics, mut refused, mut rejected, mut nan, mut mass_moved) = (0, 0, 0, 0, 0);
    let mut first_failure: Option<String> = None;
    let mut splitting = 0;
    let mut max_drift = 0.0f64;
    let mut times = Vec::with_capacity(cuts);
    let t_all = Instant::now();
    for i in 0..cuts {
        let c = boundary[(rng.next() * boundary.len() as f64) as usize % boundary.len()];
        let d = rng.unit();
        let half = 0.5 * rng.range(0.01, 0.03);
        let a = [c[0] - half * d[0], c[1] - half * d[1], c[2] - half * d[2]];
        let b = [c[0] + half * d[0], c[1] + half * d[1], c[2] + half * d[2]];
        // A sweep direction across the edge.
        let w = rng.unit();
        let k = w[0] * d[0] + w[1] * d[1] + w[2] * d[2];
        let mut s = [w[0] - k * d[0], w[1] - k * d[1], w[2] - k * d[2]];
        let l = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
        if l < 1e-3 {
            s = [d[1], -d[0], 0.0];
        }
        let l = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
        let depth = rng.range(0.005, 0.03);
        let sweep = s.map(|x| x / l * depth);
        let mut note = |kind: &str, msg: String| {
            first_failure.get_or_insert_with(|| format!("cut {i}: {kind}: {msg}"));
        };
        let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            let blade = Blade::swept(a, b, sweep)?;
            let r = sim.cut(&blade)?;
            let (_, rej) = frame_ms(&mut sim, 2);
            Ok::<_, Error>((r, rej))
        }));
        match result {
            Err(_) => {
                panics += 1;
                note("panic", String::new());
                break;
            }
            Ok(Err(e)) => {
                refused += 1;
                note("refused", e.to_string());
            }
            Ok(Ok((r, rej))) => {
                times.push(r.seconds);
                if r.split.iter().any(|&s| s > 0) {
                    splitting += 1;
                }
                if rej > 0 {
                    rejected += 1;
                    note("frame rejected", format!("{rej} of 2"));
                }
            }
        }
        if sim.positions().iter().flatten().any(|v| !v.is_finite()) {
            nan += 1;
            note("not finite", String::new());
        }
        let mass: f64 = sim.masses().iter().sum();
        let drift = (mass - mass0).abs() / mass0;
        max_drift = max_drift.max(drift);
        if drift > MASS_TOL {
            mass_moved += 1;
            note("mass", format!("{mass} kg against {mass0} kg"));
        }
    }
    times.sort_by(f64::total_cmp);
    let failures = panics + refused + rejected + nan + mass_moved;
    out(&format!(
        "liver L1 hierarchy, stable-neo-hookean, spring grasp pulled 1 cm, gravity: {cuts} random cuts in {:.1} s",
        t_all.elapsed().as_secs_f64()
    ));
    out(&format!(
        "  {splitting} cuts split elements; mesh {n0} → {} nodes, {e0} → {} elements",
        sim.mesh().num_nodes(),
        sim.mesh().num_elements()
    ));
    if !times.is_empty() {
        out(&format!(
            "  cut time: median {:.1} ms, largest {:.1} ms",
            times[times.len() / 2] * 1e3,
            times[times.len() - 1] * 1e3
        ));
    }
    out(&format!(
        "  total mass: largest relative change {max_drift:.1e} over the cuts (rounding; a failure above {MASS_TOL:.0e})"
    ));
    out(&format!(
        "  failures: {failures} (panics {panics}, refused {refused}, frames rejected {rejected}, not finite {nan}, mass moved {mass_moved}); target 0: {}",
        if failures == 0 { "met" } else { "NOT met" }
    ));
    if let Some(f) = first_failure {
        out(&format!("  first failure: {f}"));
    }
    Ok(())
}

/// Run the benchmark on the meshes of `meshes` (`data/`); `quick`: 100 random cuts instead of
/// 1 000. Lines go to `out`.
pub fn cut(meshes: &Path, quick: bool, out: &mut dyn FnMut(&str)) -> Result<()> {
    one_cut(meshes, out)?;
    random_cuts(meshes, if quick { 100 } else { 1000 }, out)
}
