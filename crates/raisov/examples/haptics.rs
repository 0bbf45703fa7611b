//! A haptic loop beside the simulation: the simulation thread steps frames and, through a
//! [`raisov::sim::HapticProxy`] attached to its grasp, publishes each frame's grasp
//! position, tool force and grasp stiffness; a 1 kHz thread reads the newest frame (never
//! waiting for the simulation) and renders the force extrapolated to the device's position,
//! `f = f_frame + K (x_device − x_frame)`, clamped to the device's force limit and to a
//! trusted radius. The device is scripted (a vertical sine); the simulation's grasp follows
//! it one frame late.
//!
//! Prints the haptic rate, the p99 deviation of the loop period from 1 ms, and the error of
//! the extrapolated force against the force of the next simulated frame at its grasp position
//! (and, for comparison, of holding the last frame's force). Rate and jitter depend on the
//! machine and its load.
//!
//! `cargo run --release --example haptics [-- SECONDS]` (default 2 s).

use raisov::mesh::generate::{box_tets, BoxPattern};
use raisov::sim::{Budget, HapticFrame, HapticLimits, SimulationBuilder};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

fn percentile(v: &mut [f64], p: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * p).round() as usize]
}

fn main() -> Result<(), raisov::Error> {
    let seconds: f64 = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(2.0);
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads((cores - 1).max(1))
        .build()
        .expect("a thread pool");
    let fine = box_tets([0.06, 0.06, 0.03], [8, 8, 4], BoxPattern::Six)?;
    let coarse = box_tets([0.06, 0.06, 0.03], [4, 4, 2], BoxPattern::Six)?;
    let mut sim = SimulationBuilder::new(fine)
        .levels(vec![coarse])
        .gravity([0.0, 0.0, -9.81])
        .fix(|p| p[2] <= 0.0)
        .build()?;
    let g = sim.grab([0.03, 0.03, 0.04], 0.008)?;
    let x0 = sim.grab_position(g)?;
    // The scripted device: a 4 mm vertical sine at 0.5 Hz above the grasp point.
    let device_at = move |t: f64| {
        [
            x0[0],
            x0[1],
            x0[2] + 0.002 * (1.0 - (std::f64::consts::PI * t).cos()),
        ]
    };
    // The device's limits: 2 N at most, the linear model trusted to 5 mm.
    let fmax = 2.0;
    let proxy = sim.haptic_proxy(g, HapticLimits::new(fmax, 0.005)?)?;
    // Where the device is, for the simulation to follow.
    let device = Arc::new(Mutex::new(x0));
    let stop = Arc::new(AtomicBool::new(false));

    // The haptic thread: 1 kHz, sleeping to 0.2 ms before each tick, then spinning.
    let haptic = {
        let (device, stop, proxy) = (device.clone(), stop.clone(), proxy.clone());
        std::thread::spawn(move || {
            let period = Duration::from_millis(1);
            let t0 = Instant::now();
            let mut next = t0 + period;
            let mut last = t0;
            let (mut periods, mut clamped, mut ticks, mut seen) = (Vec::new(), 0u64, 0u64, 0u64);
            while !stop.load(Ordering::Relaxed) {
                let now = Instant::now();
                if next > now + Duration::from_micros(200) {
                    std::thread::sleep(next - now - Duration::from_micros(200));
                }
                while Instant::now() < next {
                    std::hint::spin_loop();
                }
                let now = Instant::now();
                periods.push((now - last).as_secs_f64());
                last = now;
                next += period;
                if next < now {
                    next = now + period; // fell behind: do not burst
                }
                let x_dev = device_at((now - t0).as_secs_f64());
                *device.lock().unwrap_or_else(|e| e.into_inner()) = x_dev;
                let (frame, f) = proxy.sample(x_dev);
                seen = frame.seq;
                clamped += u64::from(f.force_clamped);
                std::hint::black_box(f.force); // sent to the device
                ticks += 1;
            }
            (periods, clamped, ticks, seen, t0.elapsed())
        })
    };

    // The simulation thread (this one), on the pool of cores − 1.
    let (mut extrap_err, mut hold_err, mut rel_err) = (Vec::new(), Vec::new(), Vec::new());
    let mut frame_ms = Vec::new();
    let mut prev: Option<HapticFrame> = None;
    let t0 = Instant::now();
    let mut frame = 0u64;
    pool.install(|| -> Result<(), raisov::Error> {
        while t0.elapsed().as_secs_f64() < seconds {
            let tf = Instant::now();
            let target = *device.lock().unwrap_or_else(|e| e.into_inner());
            sim.move_grab(g, target)?;
            // The frame publishes the grasp's position, force and stiffness to the proxy.
            let r = sim.step_frame(Budget::Cycles(6));
            frame_ms.push(tf.elapsed().as_secs_f64() * 1e3);
            if !r.accepted {
                eprintln!("frame {frame} rejected: {:?}", r.rejection);
            }
            let data = proxy.frame();
            // The last frame's extrapolation to this frame's grasp position (no limits),
            // against this frame's force.
            if let Some(p) = prev {
                let fx = p.extrapolate(data.position, HapticLimits::default()).force;
                let e = norm(sub(fx, data.force));
                extrap_err.push(e);
                hold_err.push(norm(sub(p.force, data.force)));
                rel_err.push(e / norm(data.force).max(1e-12));
            }
            prev = Some(data);
            frame += 1;
        }
        Ok(())
    })?;
    stop.store(true, Ordering::Relaxed);
    let (mut periods, clamped, ticks, seen, elapsed) = haptic.join().expect("haptic thread");
    let rate = ticks as f64 / elapsed.as_secs_f64();
    let mut dev: Vec<f64> = periods.iter().map(|p| (p - 1e-3).abs() * 1e3).collect();
    let p99 = percentile(&mut dev, 0.99);
    let pmax = percentile(&mut periods, 1.0) * 1e3;
    println!(
        "simulation: {} nodes, {} frames in {:.2} s ({:.1} frames/s, {:.2} ms per frame median incl. the proxy's force and stiffness), pool of {} threads",
        sim.positions().len(),
        frame,
        t0.elapsed().as_secs_f64(),
        frame as f64 / t0.elapsed().as_secs_f64(),
        percentile(&mut frame_ms, 0.5),
        (cores - 1).max(1)
    );
    println!(
        "haptic loop: {rate:.1} Hz over {:.2} s, period deviation from 1 ms p99 {p99:.3} ms (longest period {pmax:.3} ms), {clamped} of {ticks} forces clamped at {fmax} N, last frame seen {seen}",
        elapsed.as_secs_f64()
    );
    let max_f = prev.map_or(0.0, |p| norm(p.force));
    println!(
        "force error against the next frame: extrapolated f + K dx median {:.2e} N, p95 {:.2e} N, max {:.2e} N (median {:.2} % of |f|); holding the last force median {:.2e} N, max {:.2e} N; |f| at the end {max_f:.3} N",
        percentile(&mut extrap_err.clone(), 0.5),
        percentile(&mut extrap_err.clone(), 0.95),
        percentile(&mut extrap_err, 1.0),
        100.0 * percentile(&mut rel_err, 0.5),
        percentile(&mut hold_err.clone(), 0.5),
        percentile(&mut hold_err, 1.0),
    );
    Ok(())
}
