//! A small C ABI over [`raisov::sim`] (header `include/raisov.h`): create a simulation from a
//! scenario file, grasp its surface (hard or by springs), cut it with a planar blade, step
//! frames (a number of steps or a wall-time budget), read node positions, the surface a
//! renderer draws, the tool force and the grasp stiffness, hand a haptic device thread a proxy
//! of a grasp, free it.
//!
//! Conventions are the Rust API's, in SI units: `raisov_sim_grab_force` writes
//! `Σ_{a ∈ g} (V_a − R_a(u))`, the force the tissue exerts on the tool (N); positions are
//! `X + u` (m), 3 doubles per node in the mesh's node order.
//!
//! Errors: a function that fails returns `NULL`, a negative value or `0` as its doc says, and
//! [`raisov_last_error`] gives the message of the last failure on the calling thread. No
//! panic crosses the boundary: each entry point runs under `catch_unwind` and a panic becomes
//! an error. Null pointers are checked, and so is the room in every caller buffer. A
//! `RaisovSim` is not thread-safe: call it from one thread at a time. A `RaisovHaptic`
//! ([`raisov::sim::HapticProxy`]) is: any thread may read it at any time, concurrently with
//! the simulation's calls on another, and it stays valid after the simulation is freed
//! (rendering zero force from then on).

use raisov::sim::{Budget, GrabId, HapticLimits, HapticProxy, Simulation};
use std::cell::RefCell;
use std::collections::HashMap;
use std::ffi::{c_char, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};

/// An opaque simulation handle (`RaisovSim *` in C).
pub struct RaisovSim {
    sim: Simulation,
    /// Grasps by the integer handle given to C (1, 2, ...; 0 is never a grasp).
    grabs: HashMap<i64, GrabId>,
    next: i64,
}

thread_local! {
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

fn set_error(msg: impl Into<String>) {
    let msg = msg.into().replace('\0', " ");
    LAST_ERROR.with(|e| *e.borrow_mut() = CString::new(msg).unwrap_or_default());
}

fn panic_message(p: Box<dyn std::any::Any + Send>) -> String {
    let what = p
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into());
    format!("internal error (panic): {what}")
}

/// Run `f`, turning an error or a panic into the thread's last error and `fail`.
fn guard<T>(fail: T, f: impl FnOnce() -> Result<T, String>) -> T {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(v)) => v,
        Ok(Err(msg)) => {
            set_error(msg);
            fail
        }
        Err(p) => {
            set_error(panic_message(p));
            fail
        }
    }
}

/// # Safety
/// `sim` must be null or a pointer returned by [`raisov_sim_from_file`] and not yet freed,
/// not used by another thread during the call.
unsafe fn sim_mut<'a>(sim: *mut RaisovSim) -> Result<&'a mut RaisovSim, String> {
    // SAFETY: the caller's contract: null or a live, unaliased handle.
    unsafe { sim.as_mut() }.ok_or_else(|| "the simulation pointer is NULL".to_string())
}

/// # Safety
/// `p` must be null or point to 3 readable doubles.
unsafe fn read3(p: *const f64, what: &str) -> Result<[f64; 3], String> {
    if p.is_null() {
        return Err(format!("`{what}` is NULL (3 doubles expected)"));
    }
    // SAFETY: non-null, and the caller promises 3 readable doubles.
    let s = unsafe { std::slice::from_raw_parts(p, 3) };
    Ok([s[0], s[1], s[2]])
}

fn grab_id(s: &RaisovSim, grab: i64) -> Result<GrabId, String> {
    s.grabs
        .get(&grab)
        .copied()
        .ok_or_else(|| format!("no grasp {grab} (released already, or not from this simulation?)"))
}

/// The message of the last failed call on this thread (UTF-8, NUL-terminated; empty when
/// none failed). The pointer stays valid until the next failing call on this thread.
#[no_mangle]
pub extern "C" fn raisov_last_error() -> *const c_char {
    LAST_ERROR.with(|e| e.borrow().as_ptr())
}

/// Load a scenario file (raisov's TOML format); NULL on error ([`raisov_last_error`]).
///
/// # Safety
/// `path` must be null or a NUL-terminated string.
#[no_mangle]
pub unsafe extern "C" fn raisov_sim_from_file(path: *const c_char) -> *mut RaisovSim {
    guard(std::ptr::null_mut(), || {
        if path.is_null() {
            return Err("the scenario path is NULL".into());
        }
        // SAFETY: non-null and NUL-terminated by the caller's contract.
        let path = unsafe { CStr::from_ptr(path) }
            .to_str()
            .map_err(|_| "the scenario path is not UTF-8".to_string())?;
        let sim = Simulation::from_file(path).map_err(|e| e.to_string())?;
        Ok(Box::into_raw(Box::new(RaisovSim {
            sim,
            grabs: HashMap::new(),
            next: 1,
        })))
    })
}

/// Free a simulation (NULL is ignored).
///
/// # Safety
/// `sim` must be null or a pointer returned by [`raisov_sim_from_file`], not freed before;
/// it must not be used afterwards.
#[no_mangle]
pub unsafe extern "C" fn raisov_sim_free(sim: *mut RaisovSim) {
    if !sim.is_null() {
        guard((), || {
            // SAFETY: a live handle from Box::into_raw, given back once.
            drop(unsafe { Box::from_raw(sim) });
            Ok(())
        })
    }
}

/// Number of nodes, or -1 on error.
///
/// # Safety
/// `sim` must be null or a live handle.
#[no_mangle]
pub unsafe extern "C" fn raisov_sim_num_nodes(sim: *const RaisovSim) -> i64 {
    guard(-1, || {
        // SAFETY: null or a live handle (caller's contract).
        let s = unsafe { sim.as_ref() }.ok_or("the simulation pointer is NULL")?;
        Ok(s.sim.positions().len() as i64)
    })
}

/// Grasp the surface near `point` (3 doubles, m) with `radius` (m): returns the grasp's
/// handle (> 0), or -1 on error.
///
/// # Safety
/// `sim` must be null or a live handle; `point` null or 3 readable doubles.
#[no_mangle]
pub unsafe extern "C" fn raisov_sim_grab(
    sim: *mut RaisovSim,
    point: *const f64,
    radius: f64,
) -> i64 {
    guard(-1, || {
        // SAFETY: the caller's contract, forwarded.
        let (s, p) = unsafe { (sim_mut(sim)?, read3(point, "point")?) };
        let id = s.sim.grab(p, radius).map_err(|e| e.to_string())?;
        let h = s.next;
        s.next += 1;
        s.grabs.insert(h, id);
        Ok(h)
    })
}

/// Grasp the surface near `point` (3 doubles, m) with `radius` (m) by springs of total
/// stiffness `stiffness` (N/m, spread over the grasped nodes by mass; the nodes stay free):
/// returns the grasp's handle (> 0), or -1 on error.
///
/// # Safety
/// `sim` must be null or a live handle; `point` null or 3 readable doubles.
#[no_mangle]
pub unsafe extern "C" fn raisov_sim_grab_spring(
    sim: *mut RaisovSim,
    point: *const f64,
    radius: f64,
    stiffness: f64,
) -> i64 {
    guard(-1, || {
        // SAFETY: the caller's contract, forwarded.
        let (s, p) = unsafe { (sim_mut(sim)?, read3(point, "point")?) };
        let options = raisov::sim::GrabOptions::spring(radius, stiffness);
        let id = s.sim.grab_with(p, options).map_err(|e| e.to_string())?;
        let h = s.next;
        s.next += 1;
        s.grabs.insert(h, id);
        Ok(h)
    })
}

/// Make grasp `grab` a spring grasp of total stiffness `stiffness` (N/m): 0, or -1 on error.
///
/// # Safety
/// `sim` must be null or a live handle.
#[no_mangle]
pub unsafe extern "C" fn raisov_sim_set_grab_stiffness(
    sim: *mut RaisovSim,
    grab: i64,
    stiffness: f64,
) -> i32 {
    guard(-1, || {
        // SAFETY: the caller's contract, forwarded.
        let s = unsafe { sim_mut(sim)? };
        let id = grab_id(s, grab)?;
        s.sim
            .set_grab_stiffness(id, stiffness)
            .map_err(|e| e.to_string())?;
        Ok(0)
    })
}

/// Move grasp `grab` to `target` (3 doubles, m) over the next frame: 0, or -1 on error.
///
/// # Safety
/// `sim` must be null or a live handle; `target` null or 3 readable doubles.
#[no_mangle]
pub unsafe extern "C" fn raisov_sim_move_grab(
    sim: *mut RaisovSim,
    grab: i64,
    target: *const f64,
) -> i32 {
    guard(-1, || {
        // SAFETY: the caller's contract, forwarded.
        let (s, p) = unsafe { (sim_mut(sim)?, read3(target, "target")?) };
        let id = grab_id(s, grab)?;
        s.sim.move_grab(id, p).map_err(|e| e.to_string())?;
        Ok(0)
    })
}

/// Let go of grasp `grab`: 0, or -1 on error.
///
/// # Safety
/// `sim` must be null or a live handle.
#[no_mangle]
pub unsafe extern "C" fn raisov_sim_release(sim: *mut RaisovSim, grab: i64) -> i32 {
    guard(-1, || {
        // SAFETY: the caller's contract, forwarded.
        let s = unsafe { sim_mut(sim)? };
        let id = grab_id(s, grab)?;
        s.sim.release(id).map_err(|e| e.to_string())?;
        s.grabs.remove(&grab);
        Ok(0)
    })
}

/// Levels whose split elements [`RaisovCutReport::split`] lists one by one.
pub const RAISOV_CUT_MAX_LEVELS: usize = 8;

/// What [`raisov_sim_cut`] did (`RaisovCutReport` in C): [`raisov::sim::CutReport`].
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RaisovCutReport {
    /// Levels of the simulation (entries of `split` used, at most
    /// [`RAISOV_CUT_MAX_LEVELS`]).
    pub levels: u32,
    /// Elements the blade split, per level (finest first); 0 beyond `levels`.
    pub split: [u64; RAISOV_CUT_MAX_LEVELS],
    /// Elements split on every level (those beyond [`RAISOV_CUT_MAX_LEVELS`] included).
    pub split_total: u64,
    /// Level 0's nodes after the cut.
    pub nodes: i64,
    /// Level 0's elements after the cut.
    pub elements: i64,
    /// Wall time of the cut (s).
    pub seconds: f64,
}

/// Cut the body with the blade the edge `a`–`b` (3 doubles each, m) sweeps along `sweep`
/// (3 doubles, m): the quad with corners a, b, b + sweep, a + sweep, cut on every level
/// ([`Simulation::cut`]). The node and element counts change: read the counts again before
/// copying positions or the surface. A blade that misses the body changes nothing (`split`
/// all zero). Writes the report into `*out` (NULL: not wanted). 0, or -1 on error with
/// nothing changed: a degenerate blade, a membrane, loads that cannot be cut (pressure,
/// traction, timed loads, tools).
///
/// # Safety
/// `sim` must be null or a live handle; `a`, `b`, `sweep` null or 3 readable doubles each;
/// `out` null or a writable `RaisovCutReport`.
#[no_mangle]
pub unsafe extern "C" fn raisov_sim_cut(
    sim: *mut RaisovSim,
    a: *const f64,
    b: *const f64,
    sweep: *const f64,
    out: *mut RaisovCutReport,
) -> i32 {
    guard(-1, || {
        // SAFETY: the caller's contract, forwarded.
        let (s, a, b, sweep) = unsafe {
            (
                sim_mut(sim)?,
                read3(a, "a")?,
                read3(b, "b")?,
                read3(sweep, "sweep")?,
            )
        };
        let blade = raisov::mesh::cut::Blade::swept(a, b, sweep).map_err(|e| e.to_string())?;
        let r = s.sim.cut(&blade).map_err(|e| e.to_string())?;
        let mut report = RaisovCutReport {
            levels: r.split.len().min(RAISOV_CUT_MAX_LEVELS) as u32,
            split_total: r.split.iter().map(|&n| n as u64).sum(),
            nodes: r.nodes as i64,
            elements: r.elements as i64,
            seconds: r.seconds,
            ..RaisovCutReport::default()
        };
        for (o, &n) in report.split.iter_mut().zip(&r.split) {
            *o = n as u64;
        }
        // SAFETY: null or a writable report (the caller's contract).
        if let Some(out) = unsafe { out.as_mut() } {
            *out = report;
        }
        Ok(0)
    })
}

/// One frame of `budget`: 1 accepted, 0 rejected (the reason in the last error).
///
/// # Safety
/// `sim` must be null or a live handle, not used by another thread during the call.
unsafe fn step(sim: *mut RaisovSim, budget: Budget) -> Result<i32, String> {
    // SAFETY: the caller's contract, forwarded.
    let s = unsafe { sim_mut(sim)? };
    let r = s.sim.step_frame(budget);
    if r.accepted {
        Ok(1)
    } else {
        set_error(format!(
            "frame rejected after {} tries: {}",
            r.retries,
            r.rejection.unwrap_or_default()
        ));
        Ok(0)
    }
}

/// Run one frame of `cycles` stepper steps. Returns 1 when the frame was accepted, 0 when
/// it was rejected (the state is the one before the frame; [`raisov_last_error`] says why),
/// -1 on error.
///
/// # Safety
/// `sim` must be null or a live handle.
#[no_mangle]
pub unsafe extern "C" fn raisov_sim_step_cycles(sim: *mut RaisovSim, cycles: u32) -> i32 {
    // SAFETY: the caller's contract, forwarded.
    guard(-1, || unsafe { step(sim, Budget::Cycles(cycles)) })
}

/// Run one frame of `ms` milliseconds of wall time (steps until the time has passed, at
/// least one; a frame that makes the grasps' moves retries in smaller sub-moves, each with
/// its share of the time). Returns 1 (accepted), 0 (rejected, [`raisov_last_error`] says
/// why) or -1 on error (`ms` not finite and >= 0).
///
/// # Safety
/// `sim` must be null or a live handle.
#[no_mangle]
pub unsafe extern "C" fn raisov_sim_step_ms(sim: *mut RaisovSim, ms: f64) -> i32 {
    guard(-1, || {
        if !(ms.is_finite() && ms >= 0.0) {
            return Err(format!(
                "`ms` = {ms}: must be a finite number of milliseconds >= 0"
            ));
        }
        // SAFETY: the caller's contract, forwarded.
        unsafe { step(sim, Budget::Millis(ms)) }
    })
}

/// # Safety
/// `sim` must be null or a live handle (shared access only).
unsafe fn sim_ref<'a>(sim: *const RaisovSim) -> Result<&'a RaisovSim, String> {
    // SAFETY: the caller's contract: null or a live handle.
    unsafe { sim.as_ref() }.ok_or_else(|| "the simulation pointer is NULL".to_string())
}

/// Copy `src` into the caller's buffer `out` of room `len` (in `T`s), checked: returns the
/// number of values written. `what` names the values in errors.
///
/// # Safety
/// `out` must be null or point to `len` writable `T`s.
unsafe fn copy_out<T: Copy>(src: &[T], out: *mut T, len: usize, what: &str) -> Result<i64, String> {
    if out.is_null() {
        return Err("`out` is NULL".into());
    }
    if len < src.len() {
        return Err(format!(
            "`out` holds {len} values, {} needed ({what})",
            src.len()
        ));
    }
    // SAFETY: non-null with `len >= src.len()` writable values (caller's contract).
    let dst = unsafe { std::slice::from_raw_parts_mut(out, src.len()) };
    dst.copy_from_slice(src);
    Ok(src.len() as i64)
}

/// Copy the node positions (m) into `out`, 3 doubles per node: `len` is the room in `out`
/// (in doubles) and must be at least 3 × [`raisov_sim_num_nodes`]. Returns the number of
/// doubles written, or -1 on error.
///
/// # Safety
/// `sim` must be null or a live handle; `out` null or `len` writable doubles.
#[no_mangle]
pub unsafe extern "C" fn raisov_sim_positions(
    sim: *const RaisovSim,
    out: *mut f64,
    len: usize,
) -> i64 {
    guard(-1, || {
        // SAFETY: the caller's contract, forwarded.
        unsafe {
            let s = sim_ref(sim)?;
            copy_out(s.sim.positions().as_flattened(), out, len, "3 per node")
        }
    })
}

/// Number of vertices of the surface a renderer draws, or -1 on error: the visual
/// surface's when the scenario meshed one (`[mesh] surface`), else the mesh's nodes.
///
/// # Safety
/// `sim` must be null or a live handle.
#[no_mangle]
pub unsafe extern "C" fn raisov_sim_surface_vertex_count(sim: *const RaisovSim) -> i64 {
    guard(-1, || {
        // SAFETY: the caller's contract, forwarded.
        let s = unsafe { sim_ref(sim)? };
        Ok(s.sim.surface_positions().len() as i64)
    })
}

/// Copy the surface's vertex positions at the current state (m, 3 doubles per vertex,
/// [`raisov::sim::Simulation::surface_positions`]) into `out`, which holds `len` doubles (at
/// least 3 × [`raisov_sim_surface_vertex_count`]). The number of doubles written, or -1.
///
/// # Safety
/// `sim` must be null or a live handle; `out` null or `len` writable doubles.
#[no_mangle]
pub unsafe extern "C" fn raisov_sim_surface_positions(
    sim: *const RaisovSim,
    out: *mut f64,
    len: usize,
) -> i64 {
    guard(-1, || {
        // SAFETY: the caller's contract, forwarded.
        unsafe {
            let s = sim_ref(sim)?;
            copy_out(
                s.sim.surface_positions().as_flattened(),
                out,
                len,
                "3 per surface vertex",
            )
        }
    })
}

/// Number of surface triangles, or -1 on error.
///
/// # Safety
/// `sim` must be null or a live handle.
#[no_mangle]
pub unsafe extern "C" fn raisov_sim_surface_triangle_count(sim: *const RaisovSim) -> i64 {
    guard(-1, || {
        // SAFETY: the caller's contract, forwarded.
        let s = unsafe { sim_ref(sim)? };
        Ok(s.sim.surface_triangles().len() as i64)
    })
}

/// Copy the surface triangles (3 vertex indices each, 0-based into the surface's vertices,
/// counter-clockwise seen from outside) into `out`, which holds `len` indices (at least 3 ×
/// [`raisov_sim_surface_triangle_count`]). They do not change while the simulation runs.
/// The number of indices written, or -1.
///
/// # Safety
/// `sim` must be null or a live handle; `out` null or `len` writable `uint32_t`s.
#[no_mangle]
pub unsafe extern "C" fn raisov_sim_surface_triangles(
    sim: *const RaisovSim,
    out: *mut u32,
    len: usize,
) -> i64 {
    guard(-1, || {
        // SAFETY: the caller's contract, forwarded.
        unsafe {
            let s = sim_ref(sim)?;
            copy_out(
                s.sim.surface_triangles().as_flattened(),
                out,
                len,
                "3 per triangle",
            )
        }
    })
}

/// Write the force the tissue exerts on the tool of `grab` (N) into `out` (3 doubles):
/// 0, or -1 on error.
///
/// # Safety
/// `sim` must be null or a live handle; `out` null or 3 writable doubles.
#[no_mangle]
pub unsafe extern "C" fn raisov_sim_grab_force(
    sim: *const RaisovSim,
    grab: i64,
    out: *mut f64,
) -> i32 {
    guard(-1, || {
        // SAFETY: null or a live handle (caller's contract).
        let s = unsafe { sim.as_ref() }.ok_or("the simulation pointer is NULL")?;
        if out.is_null() {
            return Err("`out` is NULL (3 doubles expected)".into());
        }
        let f = s
            .sim
            .grab_force(grab_id(s, grab)?)
            .map_err(|e| e.to_string())?;
        // SAFETY: non-null with 3 writable doubles (caller's contract).
        unsafe { std::slice::from_raw_parts_mut(out, 3) }.copy_from_slice(&f);
        Ok(0)
    })
}

/// Write where grasp `grab` holds its nodes now (m) into `out` (3 doubles): 0, or -1.
///
/// # Safety
/// `sim` must be null or a live handle; `out` null or 3 writable doubles.
#[no_mangle]
pub unsafe extern "C" fn raisov_sim_grab_position(
    sim: *const RaisovSim,
    grab: i64,
    out: *mut f64,
) -> i32 {
    guard(-1, || {
        // SAFETY: null or a live handle (caller's contract).
        let s = unsafe { sim.as_ref() }.ok_or("the simulation pointer is NULL")?;
        if out.is_null() {
            return Err("`out` is NULL (3 doubles expected)".into());
        }
        let p = s
            .sim
            .grab_position(grab_id(s, grab)?)
            .map_err(|e| e.to_string())?;
        // SAFETY: non-null with 3 writable doubles (caller's contract).
        unsafe { std::slice::from_raw_parts_mut(out, 3) }.copy_from_slice(&p);
        Ok(0)
    })
}

/// Write the stiffness of grasp `grab`, `K[i][j] = d force_i / d position_j` (N/m,
/// row-major, 9 doubles) into `out`: the change of the tool force when the grasp moves and
/// the free nodes return to equilibrium (three warm-started linear solves). 0, or -1.
///
/// # Safety
/// `sim` must be null or a live handle; `out` null or 9 writable doubles.
#[no_mangle]
pub unsafe extern "C" fn raisov_sim_grab_stiffness(
    sim: *mut RaisovSim,
    grab: i64,
    out: *mut f64,
) -> i32 {
    guard(-1, || {
        // SAFETY: the caller's contract, forwarded.
        let s = unsafe { sim_mut(sim)? };
        if out.is_null() {
            return Err("`out` is NULL (9 doubles expected)".into());
        }
        let id = grab_id(s, grab)?;
        let k = s.sim.grab_stiffness(id).map_err(|e| e.to_string())?;
        // SAFETY: non-null with 9 writable doubles (caller's contract).
        unsafe { std::slice::from_raw_parts_mut(out, 9) }.copy_from_slice(k.as_flattened());
        Ok(0)
    })
}

/// A haptic proxy of one grasp (`RaisovHaptic *` in C; [`raisov::sim::HapticProxy`]): safe to
/// read from any thread at any time.
pub struct RaisovHaptic {
    proxy: HapticProxy,
}

/// One published frame of a haptic proxy (`RaisovHapticFrame` in C).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct RaisovHapticFrame {
    /// The publication's number (1, 2, ...).
    pub seq: u64,
    /// 1 while the grasp is held, 0 after a release or once the simulation is freed.
    pub held: i32,
    /// The grasp position (m).
    pub position: [f64; 3],
    /// The force the tissue exerts on the tool (N).
    pub force: [f64; 3],
    /// `K[i][j] = d force_i / d position_j` (N/m, row-major).
    pub stiffness: [f64; 9],
    /// Simulated time of the frame (s).
    pub time: f64,
    /// Seconds since the frame was published.
    pub age: f64,
}

/// The force is from a held grasp (else zero).
pub const RAISOV_HAPTIC_HELD: i32 = 1;
/// The device was farther than `max_distance` from the frame's grasp position.
pub const RAISOV_HAPTIC_DISTANCE_CLAMPED: i32 = 2;
/// The force was scaled down to `max_force`.
pub const RAISOV_HAPTIC_FORCE_CLAMPED: i32 = 4;

/// # Safety
/// `h` must be null or a live haptic handle.
unsafe fn haptic_ref<'a>(h: *const RaisovHaptic) -> Result<&'a RaisovHaptic, String> {
    // SAFETY: the caller's contract: null or a live handle.
    unsafe { h.as_ref() }.ok_or_else(|| "the haptic pointer is NULL".to_string())
}

/// A haptic proxy of grasp `grab` (module docs of [`raisov::sim::haptic`]), its force limited
/// to `max_force` (N) and its extrapolation to `max_distance` (m) from the frame's grasp
/// position (each > 0; `INFINITY` for no limit). Every frame then publishes the grasp's
/// position, force and stiffness to it. NULL on error. Free it with [`raisov_haptic_free`]
/// (before or after the simulation).
///
/// # Safety
/// `sim` must be null or a live handle.
#[no_mangle]
pub unsafe extern "C" fn raisov_sim_haptic(
    sim: *mut RaisovSim,
    grab: i64,
    max_force: f64,
    max_distance: f64,
) -> *mut RaisovHaptic {
    guard(std::ptr::null_mut(), || {
        // SAFETY: the caller's contract, forwarded.
        let s = unsafe { sim_mut(sim)? };
        let id = grab_id(s, grab)?;
        let limits = HapticLimits::new(max_force, max_distance).map_err(|e| e.to_string())?;
        let proxy = s.sim.haptic_proxy(id, limits).map_err(|e| e.to_string())?;
        Ok(Box::into_raw(Box::new(RaisovHaptic { proxy })))
    })
}

/// Write the force at device position `x[3]` (m) into `out[3]` (N): the newest frame's force
/// extrapolated, `force + K (x - position)`, within the limits. Returns a combination of
/// [`RAISOV_HAPTIC_HELD`] (else the force is zero), [`RAISOV_HAPTIC_DISTANCE_CLAMPED`] and
/// [`RAISOV_HAPTIC_FORCE_CLAMPED`], or -1 on error. Never waits for the simulation.
///
/// # Safety
/// `h` must be null or a live haptic handle; `x` null or 3 readable doubles; `out` null or 3
/// writable doubles.
#[no_mangle]
pub unsafe extern "C" fn raisov_haptic_force_at(
    h: *const RaisovHaptic,
    x: *const f64,
    out: *mut f64,
) -> i32 {
    guard(-1, || {
        // SAFETY: the caller's contract, forwarded.
        let (h, x) = unsafe { (haptic_ref(h)?, read3(x, "x")?) };
        if out.is_null() {
            return Err("`out` is NULL (3 doubles expected)".into());
        }
        let (frame, f) = h.proxy.sample(x);
        // SAFETY: non-null with 3 writable doubles (caller's contract).
        unsafe { std::slice::from_raw_parts_mut(out, 3) }.copy_from_slice(&f.force);
        let flag = |on: bool, bit: i32| if on { bit } else { 0 };
        Ok(flag(frame.held, RAISOV_HAPTIC_HELD)
            | flag(f.distance_clamped, RAISOV_HAPTIC_DISTANCE_CLAMPED)
            | flag(f.force_clamped, RAISOV_HAPTIC_FORCE_CLAMPED))
    })
}

/// Write the newest published frame into `out`: 0, or -1 on error.
///
/// # Safety
/// `h` must be null or a live haptic handle; `out` null or a writable `RaisovHapticFrame`.
#[no_mangle]
pub unsafe extern "C" fn raisov_haptic_frame(
    h: *const RaisovHaptic,
    out: *mut RaisovHapticFrame,
) -> i32 {
    guard(-1, || {
        // SAFETY: the caller's contract, forwarded.
        let h = unsafe { haptic_ref(h)? };
        if out.is_null() {
            return Err("`out` is NULL (a RaisovHapticFrame expected)".into());
        }
        let f = h.proxy.frame();
        let frame = RaisovHapticFrame {
            seq: f.seq,
            held: i32::from(f.held),
            position: f.position,
            force: f.force,
            stiffness: *f.stiffness.as_flattened().first_chunk().expect("9 values"),
            time: f.time,
            age: f.age().as_secs_f64(),
        };
        // SAFETY: non-null and writable (caller's contract).
        unsafe { out.write(frame) };
        Ok(0)
    })
}

/// Set the proxy's limits (as [`raisov_sim_haptic`]'s): 0, or -1 (nothing changed).
///
/// # Safety
/// `h` must be null or a live haptic handle.
#[no_mangle]
pub unsafe extern "C" fn raisov_haptic_set_limits(
    h: *const RaisovHaptic,
    max_force: f64,
    max_distance: f64,
) -> i32 {
    guard(-1, || {
        // SAFETY: the caller's contract, forwarded.
        let h = unsafe { haptic_ref(h)? };
        let limits = HapticLimits {
            max_force,
            max_distance,
        };
        h.proxy.set_limits(limits).map_err(|e| e.to_string())?;
        Ok(0)
    })
}

/// Free a haptic proxy (NULL is ignored); the simulation stops publishing to it.
///
/// # Safety
/// `h` must be null or a pointer returned by [`raisov_sim_haptic`], not freed before, not in
/// use by another thread; it must not be used afterwards.
#[no_mangle]
pub unsafe extern "C" fn raisov_haptic_free(h: *mut RaisovHaptic) {
    if !h.is_null() {
        guard((), || {
            // SAFETY: a live handle from Box::into_raw, given back once.
            drop(unsafe { Box::from_raw(h) });
            Ok(())
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn last_error() -> String {
        // SAFETY: the returned pointer is a NUL-terminated string owned by this thread.
        unsafe { CStr::from_ptr(raisov_last_error()) }
            .to_string_lossy()
            .into_owned()
    }

    const SCENARIO: &str = r#"
gravity = [0, 0, -9.81]
[mesh]
generate = "box"
size = [0.04, 0.04, 0.04]
divisions = [3, 3, 3]
[material]
law = "neo-hookean"
young = 5e3
poisson = 0.45
[[fix]]
plane = { point = [0, 0, 0], normal = [0, 0, 1] }
[run]
duration = 1.0
"#;

    #[test]
    fn the_c_calls_match_the_rust_api_and_report_errors() {
        let dir = tempfile_dir();
        let path = dir.join("cube.toml");
        std::fs::write(&path, SCENARIO).unwrap();
        let cpath = CString::new(path.to_str().unwrap()).unwrap();
        // The same frames through the Rust API, for comparison.
        let mut rust = Simulation::from_file(&path).unwrap();
        let rg = rust.grab([0.02, 0.02, 0.05], 0.015).unwrap();
        let start = rust.grab_position(rg).unwrap();
        let target = [start[0], start[1], start[2] + 0.003];
        rust.move_grab(rg, target).unwrap();
        for _ in 0..3 {
            assert!(rust.step_frame(Budget::Cycles(4)).accepted);
        }
        unsafe {
            let sim = raisov_sim_from_file(cpath.as_ptr());
            assert!(!sim.is_null(), "{}", last_error());
            assert_eq!(raisov_sim_num_nodes(sim), 64);
            let g = raisov_sim_grab(sim, [0.02, 0.02, 0.05].as_ptr(), 0.015);
            assert!(g > 0, "{}", last_error());
            assert_eq!(raisov_sim_move_grab(sim, g, target.as_ptr()), 0);
            for _ in 0..3 {
                assert_eq!(raisov_sim_step_cycles(sim, 4), 1, "{}", last_error());
            }
            let mut f = [0.0; 3];
            assert_eq!(raisov_sim_grab_force(sim, g, f.as_mut_ptr()), 0);
            assert_eq!(f, rust.grab_force(rg).unwrap());
            assert!(f[2] < 0.0, "{f:?}");
            let mut x = vec![0.0; 3 * 64];
            assert_eq!(raisov_sim_positions(sim, x.as_mut_ptr(), x.len()), 192);
            assert_eq!(&x[..], rust.positions().as_flattened());
            // Errors: a message, no crash.
            assert_eq!(raisov_sim_positions(sim, x.as_mut_ptr(), 10), -1);
            assert!(last_error().contains("192 needed"), "{}", last_error());
            assert_eq!(raisov_sim_grab_force(sim, 99, f.as_mut_ptr()), -1);
            assert!(last_error().contains("no grasp 99"), "{}", last_error());
            assert_eq!(raisov_sim_grab(sim, std::ptr::null(), 0.01), -1);
            assert!(last_error().contains("`point` is NULL"));
            assert_eq!(raisov_sim_grab(sim, [0.0; 3].as_ptr(), -1.0), -1);
            assert!(!last_error().is_empty());
            assert_eq!(raisov_sim_release(sim, g), 0);
            assert_eq!(raisov_sim_release(sim, g), -1);
            assert_eq!(raisov_sim_num_nodes(std::ptr::null()), -1);
            assert_eq!(raisov_sim_step_cycles(std::ptr::null_mut(), 1), -1);
            raisov_sim_free(sim);
            raisov_sim_free(std::ptr::null_mut());
            // A bad scenario: NULL and the library's message.
            let bad = dir.join("bad.toml");
            std::fs::write(&bad, SCENARIO.replace("young = 5e3", "young = -5e3")).unwrap();
            let cbad = CString::new(bad.to_str().unwrap()).unwrap();
            assert!(raisov_sim_from_file(cbad.as_ptr()).is_null());
            let want = Simulation::from_file(&bad).err().unwrap().to_string();
            assert_eq!(last_error(), want);
            assert!(raisov_sim_from_file(std::ptr::null()).is_null());
        }
        std::fs::remove_dir_all(&dir).ok();
    }

    /// The cube scenario written to a fresh file, the simulation loaded through C.
    fn c_cube(name: &str) -> (std::path::PathBuf, *mut RaisovSim) {
        let dir = tempfile_dir().join(name);
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("cube.toml");
        std::fs::write(&path, SCENARIO).unwrap();
        let cpath = CString::new(path.to_str().unwrap()).unwrap();
        // SAFETY: a NUL-terminated path.
        let sim = unsafe { raisov_sim_from_file(cpath.as_ptr()) };
        assert!(!sim.is_null(), "{}", last_error());
        (path, sim)
    }

    #[test]
    fn c_gives_the_surface_triangles_and_positions_a_renderer_draws() {
        let (path, sim) = c_cube("surface");
        let rust = Simulation::from_file(&path).unwrap();
        unsafe {
            let m = raisov_sim_surface_triangle_count(sim);
            let n = raisov_sim_surface_vertex_count(sim);
            // A 3x3x3 cube: 6 faces of 9 squares of 2 triangles; the mesh's 64 nodes.
            assert_eq!((m, n), (108, 64));
            let mut tri = vec![u32::MAX; 3 * m as usize];
            assert_eq!(
                raisov_sim_surface_triangles(sim, tri.as_mut_ptr(), tri.len()),
                3 * m
            );
            assert_eq!(&tri[..], rust.surface_triangles().as_flattened());
            assert!(tri.iter().all(|&v| (v as i64) < n));
            let mut x = vec![f64::NAN; 3 * n as usize];
            assert_eq!(
                raisov_sim_surface_positions(sim, x.as_mut_ptr(), x.len()),
                3 * n
            );
            assert_eq!(&x[..], rust.surface_positions().as_flattened());
            // Buffers too small, or NULL: an error naming the room needed, nothing written.
            let mut small = vec![7u32; 10];
            assert_eq!(
                raisov_sim_surface_triangles(sim, small.as_mut_ptr(), 10),
                -1
            );
            assert!(last_error().contains("324 needed"), "{}", last_error());
            assert!(small.iter().all(|&v| v == 7));
            assert_eq!(raisov_sim_surface_positions(sim, x.as_mut_ptr(), 5), -1);
            assert!(last_error().contains("192 needed"), "{}", last_error());
            assert_eq!(
                raisov_sim_surface_positions(sim, std::ptr::null_mut(), 999),
                -1
            );
            assert_eq!(raisov_sim_surface_triangle_count(std::ptr::null()), -1);
            raisov_sim_free(sim);
        }
    }

    #[test]
    fn c_steps_a_frame_on_a_time_budget_and_reads_the_grasp_stiffness() {
        let (path, sim) = c_cube("budget");
        let mut rust = Simulation::from_file(&path).unwrap();
        let rg = rust.grab([0.02, 0.02, 0.05], 0.015).unwrap();
        unsafe {
            let g = raisov_sim_grab(sim, [0.02, 0.02, 0.05].as_ptr(), 0.015);
            assert!(g > 0, "{}", last_error());
            // Before any frame, the same stiffness as the Rust API's at the same state.
            let mut k = [0.0; 9];
            assert_eq!(
                raisov_sim_grab_stiffness(sim, g, k.as_mut_ptr()),
                0,
                "{}",
                last_error()
            );
            let kr = rust.grab_stiffness(rg).unwrap();
            assert_eq!(&k[..], kr.as_flattened());
            assert!(k[0] < 0.0 && k[4] < 0.0 && k[8] < 0.0, "{k:?}");
            // A 2 ms frame steps (the cube sags under gravity); bad budgets are errors.
            let mut before = vec![0.0; 192];
            assert_eq!(raisov_sim_positions(sim, before.as_mut_ptr(), 192), 192);
            assert_eq!(raisov_sim_step_ms(sim, 2.0), 1, "{}", last_error());
            let mut after = vec![0.0; 192];
            assert_eq!(raisov_sim_positions(sim, after.as_mut_ptr(), 192), 192);
            assert_ne!(before, after);
            assert_eq!(raisov_sim_step_ms(sim, f64::NAN), -1);
            assert!(last_error().contains("`ms` = NaN"), "{}", last_error());
            assert_eq!(raisov_sim_step_ms(sim, -1.0), -1);
            assert_eq!(raisov_sim_step_ms(std::ptr::null_mut(), 1.0), -1);
            assert_eq!(raisov_sim_grab_stiffness(sim, g, std::ptr::null_mut()), -1);
            assert_eq!(raisov_sim_grab_stiffness(sim, 99, k.as_mut_ptr()), -1);
            raisov_sim_free(sim);
        }
    }

    #[test]
    fn c_haptic_handle_is_read_from_another_thread_and_outlives_the_simulation() {
        let (_, sim) = c_cube("haptic");
        unsafe {
            let g = raisov_sim_grab(sim, [0.02, 0.02, 0.05].as_ptr(), 0.015);
            assert!(g > 0);
            assert!(raisov_sim_haptic(sim, g, -1.0, 0.01).is_null());
            assert!(last_error().contains("max_force"), "{}", last_error());
            assert!(raisov_sim_haptic(sim, 99, 1.0, 0.01).is_null());
            let h = raisov_sim_haptic(sim, g, 2.0, f64::INFINITY);
            assert!(!h.is_null(), "{}", last_error());
            // The handle crosses to a device thread as an address (it is Send + Sync).
            let addr = h as usize;
            let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
            let device = {
                let stop = stop.clone();
                std::thread::spawn(move || {
                    let h = addr as *const RaisovHaptic;
                    let mut reads = 0u32;
                    let mut fr = RaisovHapticFrame::default();
                    while !stop.load(std::sync::atomic::Ordering::Acquire) || reads == 0 {
                        assert_eq!(raisov_haptic_frame(h, &mut fr), 0);
                        let mut f = [0.0; 3];
                        let flags = raisov_haptic_force_at(h, fr.position.as_ptr(), f.as_mut_ptr());
                        assert_eq!(flags & RAISOV_HAPTIC_HELD, RAISOV_HAPTIC_HELD);
                        // At the frame's own position: the frame's force (or a newer
                        // frame's, published between the two reads).
                        assert!(f.iter().all(|c| c.is_finite()));
                        reads += 1;
                    }
                    reads
                })
            };
            let mut target = [0.0; 3];
            assert_eq!(raisov_sim_grab_position(sim, g, target.as_mut_ptr()), 0);
            for _ in 0..4 {
                target[2] += 0.001;
                assert_eq!(raisov_sim_move_grab(sim, g, target.as_ptr()), 0);
                assert_eq!(raisov_sim_step_cycles(sim, 4), 1);
            }
            stop.store(true, std::sync::atomic::Ordering::Release);
            assert!(device.join().unwrap() > 0);
            let mut fr = RaisovHapticFrame::default();
            assert_eq!(raisov_haptic_frame(h, &mut fr), 0);
            let mut f = [0.0; 3];
            assert_eq!(raisov_sim_grab_force(sim, g, f.as_mut_ptr()), 0);
            assert_eq!((fr.held, fr.force, fr.position), (1, f, target));
            assert!(fr.force[2] < 0.0 && fr.stiffness[8] < 0.0, "{fr:?}");
            let mut out = [0.0; 3];
            assert_eq!(
                raisov_haptic_force_at(h, fr.position.as_ptr(), out.as_mut_ptr()),
                1
            );
            assert_eq!(out, fr.force);
            // 5 cm above: the force passes 2 N and is clamped.
            let far = [target[0], target[1], target[2] + 0.05];
            let flags = raisov_haptic_force_at(h, far.as_ptr(), out.as_mut_ptr());
            assert_eq!(flags, RAISOV_HAPTIC_HELD | RAISOV_HAPTIC_FORCE_CLAMPED);
            assert!(
                ((out[0] * out[0] + out[1] * out[1] + out[2] * out[2]).sqrt() - 2.0).abs() < 1e-12
            );
            assert_eq!(raisov_haptic_set_limits(h, 10.0, 0.001), 0);
            let flags = raisov_haptic_force_at(h, far.as_ptr(), out.as_mut_ptr());
            assert_eq!(flags, RAISOV_HAPTIC_HELD | RAISOV_HAPTIC_DISTANCE_CLAMPED);
            assert_eq!(raisov_haptic_set_limits(h, f64::NAN, 0.001), -1);
            assert_eq!(
                raisov_haptic_force_at(h, std::ptr::null(), out.as_mut_ptr()),
                -1
            );
            assert_eq!(
                raisov_haptic_force_at(std::ptr::null(), far.as_ptr(), out.as_mut_ptr()),
                -1
            );
            // The simulation freed first: the handle still reads, a zero force.
            raisov_sim_free(sim);
            assert_eq!(raisov_haptic_force_at(h, far.as_ptr(), out.as_mut_ptr()), 0);
            assert_eq!(out, [0.0; 3]);
            raisov_haptic_free(h);
            raisov_haptic_free(std::ptr::null_mut());
        }
    }

    /// A cut through C splits what the Rust API's same cut splits, the counts grow, the
    /// surface then has the wound's triangles; a blade that misses changes nothing; bad
    /// blades and NULLs are errors with the library's message, nothing changed.
    #[test]
    fn c_cuts_the_body_as_the_rust_api_does_and_reports_bad_blades() {
        let (path, sim) = c_cube("cut");
        let mut rust = Simulation::from_file(&path).unwrap();
        let (a, b, sweep) = ([0.021, -0.01, 0.05], [0.021, 0.05, 0.05], [0.0, 0.0, -0.03]);
        let want = rust
            .cut(&raisov::mesh::cut::Blade::swept(a, b, sweep).unwrap())
            .unwrap();
        unsafe {
            let mut r = RaisovCutReport::default();
            assert_eq!(
                raisov_sim_cut(sim, a.as_ptr(), b.as_ptr(), sweep.as_ptr(), &mut r),
                0,
                "{}",
                last_error()
            );
            assert_eq!(r.levels, 1);
            assert_eq!(r.split[0], want.split[0] as u64);
            assert!(r.split[0] > 0 && r.split_total == r.split[0]);
            assert_eq!(
                (r.nodes, r.elements),
                (want.nodes as i64, want.elements as i64)
            );
            assert!(r.nodes > 64);
            assert_eq!(raisov_sim_num_nodes(sim), r.nodes);
            let m = raisov_sim_surface_triangle_count(sim);
            assert_eq!(m, rust.surface_triangles().len() as i64);
            assert!(m > 108, "the wound's faces: {m} triangles");
            // The same frames after the same cut: the same positions.
            for _ in 0..2 {
                assert_eq!(raisov_sim_step_cycles(sim, 4), 1, "{}", last_error());
                assert!(rust.step_frame(Budget::Cycles(4)).accepted);
            }
            let mut x = vec![0.0; 3 * r.nodes as usize];
            assert_eq!(
                raisov_sim_positions(sim, x.as_mut_ptr(), x.len()),
                3 * r.nodes
            );
            assert_eq!(&x[..], rust.positions().as_flattened());
            // A blade 1 m away: nothing split, nothing changed; the report is optional.
            let far = [1.0, 1.0, 1.0];
            let far_b = [1.0, 1.04, 1.0];
            let mut miss = RaisovCutReport::default();
            assert_eq!(
                raisov_sim_cut(sim, far.as_ptr(), far_b.as_ptr(), sweep.as_ptr(), &mut miss),
                0
            );
            assert_eq!((miss.split_total, miss.nodes), (0, r.nodes));
            assert_eq!(
                raisov_sim_cut(
                    sim,
                    far.as_ptr(),
                    far_b.as_ptr(),
                    sweep.as_ptr(),
                    std::ptr::null_mut()
                ),
                0
            );
            // Errors: a blade with no area (a = b), NULLs; nothing changed.
            assert_eq!(
                raisov_sim_cut(sim, a.as_ptr(), a.as_ptr(), sweep.as_ptr(), &mut miss),
                -1
            );
            assert!(last_error().contains("blade"), "{}", last_error());
            assert_eq!(
                raisov_sim_cut(sim, a.as_ptr(), b.as_ptr(), std::ptr::null(), &mut miss),
                -1
            );
            assert!(last_error().contains("`sweep` is NULL"), "{}", last_error());
            assert_eq!(
                raisov_sim_cut(
                    std::ptr::null_mut(),
                    a.as_ptr(),
                    b.as_ptr(),
                    sweep.as_ptr(),
                    &mut miss
                ),
                -1
            );
            assert!(last_error().contains("NULL"), "{}", last_error());
            assert_eq!(raisov_sim_num_nodes(sim), r.nodes);
            raisov_sim_free(sim);
        }
    }

    fn tempfile_dir() -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("raisov-capi-test-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d
    }
}
