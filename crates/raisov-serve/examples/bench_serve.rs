//! Bench of the live viewer (prints numbers; not a test):
//!
//! 1. The simulation thread's frame rate and lag on the grasp path of
//!    `examples/liver_interactive.toml` — the surface point nearest (0.12, 0.07, 0.10) m
//!    grasped (radius 0: one node) and pulled by (0, −0.01, −0.017) m over 0.5 s, then held,
//!    30 frames per second of path time for 1 s — on the liver hierarchy L0/L1/L2/L3 of
//!    `data/` (FAS), at a fixed budget of `CYCLES` V-cycles per frame. A frame's time is
//!    `step_frame` plus reading and encoding the surface (what the server's thread does). The
//!    lag of frame k is `max_a |u_a − u*_a| / max_a |u*_a|` over free nodes, `u*` the static
//!    solution with the grasped node at its frame position (Newton-Krylov, relative residual
//!    1e-6, warm-started from the previous frame).
//! 2. Over loopback: bytes per frame on the wire, and the latency from sending a move to the
//!    first frame whose applied seq includes it (40 moves, 50 ms apart, on L0 with the same
//!    budget).
//!
//! 3. With `--organ NODES`: the same path and budget on a liver meshed at load from
//!    `data/liver_surface.obj` (level 0 of about NODES nodes, four levels of ratio 0.5,
//!    FAS with a Newton-Krylov coarsest solve as `examples/liver_surface.toml`, or
//!    `--coarse chebyshev`, held on the same cap), in place of the shipped levels: the
//!    ≈ 50k-node organ of the live viewer's goal is `--organ 50000` (item 2 is skipped).
//!
//! 4. With `--scheme newton`: the frame solver (`SchemeKind::Newton`, the viewer's default) in
//!    place of FAS, `CYCLES` its Newton steps per frame, in every item.
//!
//! `cargo run --release -p raisov-serve --example bench_serve [-- CYCLES] [--scheme fas|newton] [--organ NODES [--coarse newton|chebyshev]]`

use futures_util::{SinkExt, StreamExt};
use raisov::integrate::hold;
use raisov::scenario::Scenario;
use raisov::sim::{Budget, Simulation};
use raisov::statics::krylov::{NewtonParams, NewtonSolver};
use raisov::statics::relax::fictitious_mass;
use raisov::SchemeKind;
use raisov_serve::protocol::{self, Command, Message};
use raisov_serve::session::{Session, SessionConfig, Source};
use std::path::PathBuf;
use std::time::{Duration, Instant};
use tokio_tungstenite::tungstenite::Message as Ws;

/// Material, support, integrator and run length shared by both organs.
const PHYSICS: &str = r#"
[material]
law = "neo-hookean"
young = 5000.0
poisson = 0.45
density = 1060.0
[damping]
alpha = 30.0
[[fix]]
plane = { point = [0.0, 0.0, 0.195], normal = [0.0, 0.0, -1.0] }
[integrator]
method = "symplectic-euler"
[run]
duration = 1.0
"#;

/// The shipped liver levels L0..L3 (items 1 and 2) under `scheme`.
fn liver(scheme: &str) -> String {
    format!(
        r#"
name = "liver-L0"
[mesh]
file = "../data/liver_L0.msh"
scale = 0.001
{PHYSICS}
[multigrid]
scheme = "{scheme}"
files = ["../data/liver_L1.msh", "../data/liver_L2.msh", "../data/liver_L3.msh"]
"#
    )
}

const POINT: [f64; 3] = [0.12, 0.07, 0.10];
const PULL: [f64; 3] = [0.0, -0.01, -0.017];

fn path(t: f64) -> [f64; 3] {
    let s = (t / 0.5).min(1.0);
    [PULL[0] * s, PULL[1] * s, PULL[2] * s]
}

fn examples_dir() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples"))
}

/// The liver meshed at load from its surface, level 0 of about `nodes` nodes, FAS with the
/// coarsest solve `coarse`, or the frame solver (item 3).
fn organ(nodes: usize, coarse: &str, scheme: &str) -> String {
    let coarse = if scheme == "fas" {
        format!("coarse = \"{coarse}\"")
    } else {
        String::new()
    };
    format!(
        r#"
name = "liver-surface-{nodes}"
[mesh]
surface = "../data/liver_surface.obj"
scale = 0.001
nodes = {nodes}
{PHYSICS}
[multigrid]
scheme = "{scheme}"
levels = 4
ratio = 0.5
{coarse}
"#
    )
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut cycles: u32 = 2;
    let mut scheme = "fas".to_string();
    let (mut organ_nodes, mut coarse) = (None, "newton".to_string());
    let mut it = args.iter();
    while let Some(a) = it.next() {
        if a == "--scheme" {
            scheme = it.next().ok_or("--scheme needs fas | newton")?.clone();
            if scheme != "fas" && scheme != "newton" {
                return Err(format!("--scheme {scheme}: valid are fas, newton").into());
            }
        } else if a == "--organ" {
            organ_nodes = Some(it.next().ok_or("--organ needs a node count")?.parse()?);
        } else if a == "--coarse" {
            coarse = it
                .next()
                .ok_or("--coarse needs newton | chebyshev")?
                .clone();
        } else {
            cycles = a.parse()?;
        }
    }
    let (method, what, steps) = if scheme == "fas" {
        (SchemeKind::Fas, "FAS".to_string(), "V-cycles")
    } else {
        (
            SchemeKind::Newton,
            "the frame solver".to_string(),
            "Newton steps",
        )
    };
    let mut scene = liver(&scheme);
    let mut label = format!("liver L0..L3 ({what}");
    if let Some(nodes) = organ_nodes {
        scene = organ(nodes, &coarse, &scheme);
        let solver = if scheme == "fas" {
            format!("FAS, coarsest solve {coarse}")
        } else {
            what
        };
        label = format!("liver meshed from data/liver_surface.obj, 4 levels ({solver}");
    }
    let base = examples_dir();
    rayon::ThreadPoolBuilder::new()
        .stack_size(8 << 20)
        .build_global()
        .ok();
    let threads = rayon::current_num_threads();
    // --- 1. the simulation thread on the path ---
    let (fps, lag_mean, lag_max, n_nodes) =
        rayon::scope(|_| sim_thread(&scene, &base, cycles)).map_err(|e| e.to_string())?;
    println!(
        "{label}, {n_nodes} nodes at L0, {threads} threads), {cycles} {steps}/frame, 30 frames:"
    );
    println!("  simulation thread: {fps:.1} frames/s (step_frame + surface read + encoding)");
    println!(
        "  lag to the static solution: mean {:.2} %, max {:.2} % of the static max |u|",
        100.0 * lag_mean,
        100.0 * lag_max
    );
    if organ_nodes.is_some() {
        // The wire figures are those of the shipped levels' run: bytes grow as 88 + 16 n for
        // n surface vertices and the latency is bounded by the frame time measured above.
        return Ok(());
    }
    // --- 2. over loopback ---
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()?;
    let (bytes, lat) = rt.block_on(wire(&scene, &base, cycles, method))?;
    let mut sorted = lat.clone();
    sorted.sort_by(f64::total_cmp);
    let mean = lat.iter().sum::<f64>() / lat.len().max(1) as f64;
    println!(
        "  wire: {bytes} bytes per frame; move → frame showing it: mean {mean:.1} ms, median {:.1} ms, max {:.1} ms ({} moves)",
        sorted[sorted.len() / 2],
        sorted[sorted.len() - 1],
        lat.len()
    );
    Ok(())
}

/// Frames per second, mean and max relative lag, node count.
fn sim_thread(
    scene: &str,
    base: &std::path::Path,
    cycles: u32,
) -> Result<(f64, f64, f64, usize), String> {
    let e = |x: raisov::Error| x.to_string();
    let mut sim = Simulation::from_toml(scene, base).map_err(e)?;
    let g = raisov_serve::session::grab_tool(&mut sim, POINT, 0.0, None).map_err(e)?;
    let start = sim.grab_position(g).map_err(e)?;
    let node = sim.grab_nodes(g).map_err(e)?[0] as usize;
    let x_node = sim.mesh().nodes[node];
    // The reference: the same scenario with the grasped node prescribed (nearest node of its
    // own reference position: itself).
    let with_displace = format!(
        "{scene}\n[[displace]]\npoint = [{}, {}, {}]\ndisplacement = [0.0, 0.0, 0.0]\n",
        x_node[0], x_node[1], x_node[2]
    );
    let sc = Scenario::from_toml(&with_displace, &base.join("bench.toml")).map_err(e)?;
    assert_eq!(sc.prescribed[0].0 as usize, node, "the same node order");
    let mut sys = sc.build_system().map_err(e)?;
    let diag = fictitious_mass(&sc.mesh, &sys.mass, 1.0);
    let mut newton = NewtonSolver::with_diagonal(&sys, &diag);
    let n = sc.mesh.num_nodes();
    let mut u_star = vec![0.0; 3 * n];
    let free: Vec<bool> = (0..n).map(|a| !sys.constraints.is_constrained(a)).collect();
    let used: Vec<u32> = {
        let mut v: Vec<u32> = sim.surface_triangles().iter().flatten().copied().collect();
        v.sort_unstable();
        v.dedup();
        v
    };
    let mut wall = Duration::ZERO;
    let (mut lag_sum, mut lag_max) = (0.0, 0.0f64);
    let frames = 30;
    for k in 1..=frames {
        let t = k as f64 / 30.0;
        let d = path(t);
        sim.move_grab(g, [start[0] + d[0], start[1] + d[1], start[2] + d[2]])
            .map_err(e)?;
        let t0 = Instant::now();
        let r = sim.step_frame(Budget::Cycles(cycles));
        // What the server's thread does with a frame: read, convert, encode.
        let pos = sim.surface_positions();
        let p32: Vec<[f32; 3]> = used
            .iter()
            .map(|&v| {
                let x = pos[v as usize];
                [x[0] as f32, x[1] as f32, x[2] as f32]
            })
            .collect();
        let s32 = vec![0.0f32; p32.len()];
        let msg = protocol::encode_frame(k, 1, &[0.0; protocol::STATS], &p32, &s32);
        std::hint::black_box(&msg);
        wall += t0.elapsed();
        if !r.accepted {
            return Err(format!("frame {k} rejected: {:?}", r.rejection));
        }
        hold(&mut sys.constraints, &[d]);
        newton
            .solve(
                &mut sys,
                t,
                &mut u_star,
                NewtonParams {
                    rel_tol: 1e-6,
                    ..Default::default()
                },
            )
            .map_err(|f| format!("reference solve inverted element {}", f.element))?;
        let u = sim.displacements();
        let (mut lag, mut umax) = (0.0f64, 0.0f64);
        for a in 0..n {
            let us = [u_star[3 * a], u_star[3 * a + 1], u_star[3 * a + 2]];
            umax = umax.max(norm(us));
            if free[a] {
                let dd = [u[3 * a] - us[0], u[3 * a + 1] - us[1], u[3 * a + 2] - us[2]];
                lag = lag.max(norm(dd));
            }
        }
        let rel = lag / umax.max(1e-300);
        lag_sum += rel;
        lag_max = lag_max.max(rel);
    }
    Ok((
        frames as f64 / wall.as_secs_f64(),
        lag_sum / frames as f64,
        lag_max,
        n,
    ))
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// Bytes per frame and the latencies (ms) of 40 moves.
async fn wire(
    scene: &str,
    base: &std::path::Path,
    cycles: u32,
    method: SchemeKind,
) -> Result<(usize, Vec<f64>), Box<dyn std::error::Error>> {
    let source = Source::from_text(scene, base.to_path_buf(), "liver", "bench.toml".as_ref())?;
    let session = Session::spawn(
        source,
        SessionConfig {
            grab_stiffness: None,
            budget: Budget::Cycles(cycles),
            max_fps: 0.0,
            method: Some(method),
            record_path: None,
        },
    )?;
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await?;
    let addr = listener.local_addr()?;
    let access = raisov_serve::access::Access::for_bound(addr, None)?;
    tokio::spawn(async move {
        let limits = raisov_serve::conn::Limits::default();
        let _ = raisov_serve::server::serve(listener, session, access, limits).await;
    });
    let (mut ws, _) = tokio_tungstenite::connect_async(format!("ws://{addr}/ws")).await?;
    let send =
        |seq: u32, command: Command| Ws::Binary(protocol::encode(&Message { seq, command }).into());
    ws.send(send(
        1,
        Command::Grab {
            point: [POINT[0] as f32, POINT[1] as f32, POINT[2] as f32],
            radius: 0.0,
        },
    ))
    .await?;
    let mut bytes = 0;
    let mut grasp = None;
    // The grasp point from the first frame that holds it.
    while grasp.is_none() {
        if let Some(Ok(Ws::Binary(b))) = ws.next().await {
            if let Some(f) = protocol::decode_frame(&b) {
                bytes = b.len();
                if f.stats[protocol::STAT_HOLDER] >= 0.0 {
                    let s = protocol::STAT_GRASP;
                    grasp = Some([f.stats[s], f.stats[s + 1], f.stats[s + 2]]);
                }
            }
        }
    }
    let g = grasp.unwrap_or([0.0; 3]);
    let mut lat = Vec::new();
    for k in 0..40u32 {
        let seq = 2 + k;
        let d = path((k + 1) as f64 / 40.0 * 0.5);
        let target = [g[0] + d[0] as f32, g[1] + d[1] as f32, g[2] + d[2] as f32];
        let sent = Instant::now();
        ws.send(send(seq, Command::Move { target })).await?;
        loop {
            match tokio::time::timeout(Duration::from_secs(30), ws.next()).await? {
                Some(Ok(Ws::Binary(b))) => {
                    if let Some(f) = protocol::decode_frame(&b) {
                        bytes = b.len();
                        if f.stats[protocol::STAT_APPLIED_SEQ] as u32 >= seq {
                            lat.push(sent.elapsed().as_secs_f64() * 1e3);
                            break;
                        }
                    }
                }
                Some(Ok(_)) => {}
                other => return Err(format!("connection ended: {other:?}").into()),
            }
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    Ok((bytes, lat))
}
