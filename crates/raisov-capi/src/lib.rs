//! A small C ABI over [`raisov::sim`] (header `include/raisov.h`): create a simulation from a
//! scenario file, grasp its surface, step frames, read node positions and the tool force,
//! free it.
//!
//! Conventions are the Rust API's, in SI units: `raisov_sim_grab_force` writes
//! `Σ_{a ∈ g} (V_a − R_a(u))`, the force the tissue exerts on the tool (N); positions are
//! `X + u` (m), 3 doubles per node in the mesh's node order.
//!
//! Errors: a function that fails returns `NULL`, a negative value or `0` as its doc says, and
//! [`raisov_last_error`] gives the message of the last failure on the calling thread. No
//! panic crosses the boundary: each entry point runs under `catch_unwind` and a panic becomes
//! an error. Null pointers are checked. A `RaisovSim` is not thread-safe: call it from one
//! thread at a time.

use raisov::sim::{Budget, GrabId, Simulation};
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

/// Run one frame of `cycles` stepper steps. Returns 1 when the frame was accepted, 0 when
/// it was rejected (the state is the one before the frame; [`raisov_last_error`] says why),
/// -1 on error.
///
/// # Safety
/// `sim` must be null or a live handle.
#[no_mangle]
pub unsafe extern "C" fn raisov_sim_step_cycles(sim: *mut RaisovSim, cycles: u32) -> i32 {
    guard(-1, || {
        // SAFETY: the caller's contract, forwarded.
        let s = unsafe { sim_mut(sim)? };
        let r = s.sim.step_frame(Budget::Cycles(cycles));
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
    })
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
        // SAFETY: null or a live handle (caller's contract).
        let s = unsafe { sim.as_ref() }.ok_or("the simulation pointer is NULL")?;
        let p = s.sim.positions().as_flattened();
        if out.is_null() {
            return Err("`out` is NULL".into());
        }
        if len < p.len() {
            return Err(format!(
                "`out` holds {len} doubles, {} needed (3 per node)",
                p.len()
            ));
        }
        // SAFETY: non-null with `len >= p.len()` writable doubles (caller's contract).
        let dst = unsafe { std::slice::from_raw_parts_mut(out, p.len()) };
        dst.copy_from_slice(p);
        Ok(p.len() as i64)
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

    fn tempfile_dir() -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("raisov-capi-test-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d
    }
}
