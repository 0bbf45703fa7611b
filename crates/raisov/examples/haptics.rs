//! A haptic loop beside the simulation (the SOFA `LCPForceFeedback` pattern): the simulation
//! thread publishes each frame's grasp position, tool force and grasp stiffness through a
//! lock-free triple buffer; a 1 kHz thread reads the newest frame, extrapolates the force to
//! the device's position, `f = f_frame + K (x_device − x_frame)`, renders it through a
//! virtual coupling spring (stiffness `k_c`: the rendered stiffness is `K` in series with
//! `k_c`, `K_vc = K (I − K / k_c)⁻¹`) and clamps it. The device is scripted (a vertical
//! sine); the simulation's grasp follows it one frame late.
//!
//! Prints the haptic rate, the p99 deviation of the loop period from 1 ms, and the error of
//! the extrapolated force against the force of the next simulated frame at its grasp position
//! (and, for comparison, of holding the last frame's force). Rate and jitter depend on the
//! machine and its load.
//!
//! `cargo run --release --example haptics [-- SECONDS]` (default 2 s).

use raisov::mesh::generate::{box_tets, BoxPattern};
use raisov::sim::{Budget, SimulationBuilder};
use std::cell::UnsafeCell;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicU8, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// A single-producer single-consumer triple buffer: the writer fills its own slot and swaps
/// it with the shared middle one; the reader swaps its slot with the middle one when the
/// middle holds something new. Neither ever waits.
struct TripleBuffer<T> {
    slots: [UnsafeCell<T>; 3],
    /// Index of the middle slot, with [`FRESH`] set when the writer published into it.
    middle: AtomicU8,
}

const FRESH: u8 = 4;

// The slots are accessed by one writer and one reader, each owning a different index.
unsafe impl<T: Send> Sync for TripleBuffer<T> {}

struct Writer<T> {
    buf: Arc<TripleBuffer<T>>,
    idx: u8,
}

struct Reader<T> {
    buf: Arc<TripleBuffer<T>>,
    idx: u8,
}

fn triple_buffer<T: Clone>(init: T) -> (Writer<T>, Reader<T>) {
    let buf = Arc::new(TripleBuffer {
        slots: [
            UnsafeCell::new(init.clone()),
            UnsafeCell::new(init.clone()),
            UnsafeCell::new(init),
        ],
        middle: AtomicU8::new(1),
    });
    (
        Writer {
            buf: buf.clone(),
            idx: 0,
        },
        Reader { buf, idx: 2 },
    )
}

impl<T> Writer<T> {
    fn publish(&mut self, value: T) {
        // SAFETY: slot `idx` belongs to the writer until it swaps it away below.
        unsafe { *self.buf.slots[self.idx as usize].get() = value };
        let old = self.buf.middle.swap(self.idx | FRESH, Ordering::AcqRel);
        self.idx = old & 3;
    }
}

impl<T> Reader<T> {
    fn read(&mut self) -> &T {
        if self.buf.middle.load(Ordering::Relaxed) & FRESH != 0 {
            let old = self.buf.middle.swap(self.idx, Ordering::AcqRel);
            self.idx = old & 3;
        }
        // SAFETY: slot `idx` belongs to the reader until its next swap.
        unsafe { &*self.buf.slots[self.idx as usize].get() }
    }
}

/// What the simulation publishes per frame.
#[derive(Clone, Copy, Debug, Default)]
struct FrameData {
    frame: u64,
    x: [f64; 3],
    f: [f64; 3],
    k: [[f64; 3]; 3],
}

/// A device position shared as three atomics (written by the haptic thread).
struct SharedPoint([AtomicU64; 3]);
impl SharedPoint {
    fn store(&self, p: [f64; 3]) {
        for (a, x) in self.0.iter().zip(p) {
            a.store(x.to_bits(), Ordering::Relaxed);
        }
    }
    fn load(&self) -> [f64; 3] {
        [0, 1, 2].map(|k| f64::from_bits(self.0[k].load(Ordering::Relaxed)))
    }
}

fn mat_vec(a: &[[f64; 3]; 3], x: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| a[i][0] * x[0] + a[i][1] * x[1] + a[i][2] * x[2])
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

/// `K (I − K / k_c)⁻¹`: `K` in series with a coupling spring `k_c` (N/m).
fn coupled(k: &[[f64; 3]; 3], kc: f64) -> [[f64; 3]; 3] {
    let mut a = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            a[i][j] = f64::from(i == j) - k[i][j] / kc;
        }
    }
    let inv = nalgebra::Matrix3::from_fn(|i, j| a[i][j])
        .try_inverse()
        .unwrap_or_else(nalgebra::Matrix3::identity);
    let km = nalgebra::Matrix3::from_fn(|i, j| k[i][j]) * inv;
    [0, 1, 2].map(|i| [0, 1, 2].map(|j| km[(i, j)]))
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
    let (mut writer, mut reader) = triple_buffer(FrameData {
        x: x0,
        ..Default::default()
    });
    let device = Arc::new(SharedPoint(
        [0, 1, 2].map(|k| AtomicU64::new(x0[k].to_bits())),
    ));
    let stop = Arc::new(AtomicBool::new(false));
    let (kc, fmax) = (500.0, 2.0);

    // The haptic thread: 1 kHz, sleeping to 0.2 ms before each tick, then spinning.
    let haptic = {
        let (device, stop) = (device.clone(), stop.clone());
        std::thread::spawn(move || {
            let period = Duration::from_millis(1);
            let t0 = Instant::now();
            let mut next = t0 + period;
            let mut last = t0;
            let (mut periods, mut clamped, mut ticks) = (Vec::new(), 0u64, 0u64);
            let mut frames_seen = 0u64;
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
                let t = (now - t0).as_secs_f64();
                let x_dev = device_at(t);
                device.store(x_dev);
                let fr = *reader.read();
                frames_seen = fr.frame;
                let kvc = coupled(&fr.k, kc);
                let dx = sub(x_dev, fr.x);
                let kd = mat_vec(&kvc, dx);
                let mut f = [fr.f[0] + kd[0], fr.f[1] + kd[1], fr.f[2] + kd[2]];
                let n = norm(f);
                if n > fmax {
                    f = f.map(|c| c * fmax / n);
                    clamped += 1;
                }
                std::hint::black_box(f); // sent to the device
                ticks += 1;
            }
            (periods, clamped, ticks, frames_seen, t0.elapsed())
        })
    };

    // The simulation thread (this one), on the pool of cores − 1.
    let (mut extrap_err, mut hold_err, mut rel_err) = (Vec::new(), Vec::new(), Vec::new());
    let mut frame_ms = Vec::new();
    let mut prev: Option<FrameData> = None;
    let t0 = Instant::now();
    let mut frame = 0u64;
    pool.install(|| -> Result<(), raisov::Error> {
        while t0.elapsed().as_secs_f64() < seconds {
            let tf = Instant::now();
            sim.move_grab(g, device.load())?;
            let r = sim.step_frame(Budget::Cycles(6));
            let data = FrameData {
                frame,
                x: sim.grab_position(g)?,
                f: sim.grab_force(g)?,
                k: sim.grab_stiffness(g)?,
            };
            frame_ms.push(tf.elapsed().as_secs_f64() * 1e3);
            if !r.accepted {
                eprintln!("frame {frame} rejected: {:?}", r.rejection);
            }
            writer.publish(data);
            // The last frame's extrapolation to this frame's grasp position, against this
            // frame's force.
            if let Some(p) = prev {
                let kd = mat_vec(&p.k, sub(data.x, p.x));
                let fx = [p.f[0] + kd[0], p.f[1] + kd[1], p.f[2] + kd[2]];
                let e = norm(sub(fx, data.f));
                extrap_err.push(e);
                hold_err.push(norm(sub(p.f, data.f)));
                rel_err.push(e / norm(data.f).max(1e-12));
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
        "simulation: {} nodes, {} frames in {:.2} s ({:.1} frames/s, {:.2} ms per frame median incl. force and stiffness), pool of {} threads",
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
    let max_f = prev.map_or(0.0, |p| norm(p.f));
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
