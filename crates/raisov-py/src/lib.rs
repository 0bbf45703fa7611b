//! Python bindings of [`raisov::sim`]: the module `raisov` with a `Simulation` class stepped
//! frame by frame from a Python loop, grasps and pins at run time, the tool force and its
//! stiffness, node positions as NumPy arrays.
//!
//! Conventions are the Rust API's (module docs of [`raisov::sim`]), in SI units:
//!
//! ```text
//! grab_force(g) = Σ_{a ∈ g} (V_a − R_a(u))   the force the tissue exerts on the tool (N);
//!                 a spring grasp's is its springs' pull, equal to it at equilibrium
//! reactions     = V_a − R_a(u) per support   the force the tissue exerts on its supports (N)
//! at equilibrium: Σ_g grab_force(g) + Σ_a reactions_a = total_load = Σ_all V_a
//! grab_stiffness(g) = ∂ grab_force / ∂ x_g   (3×3, N/m)
//! ```
//!
//! Every array handed to Python is a read-only copy (`flags.writeable` false): it keeps the
//! values of the moment it was read, whatever the simulation does afterwards. Errors of the
//! library become `ValueError` (bad input, scenario) or `RuntimeError` (divergence) with the
//! library's message, and a file's error the `OSError` subclass Python itself raises for it
//! (`FileNotFoundError`, `PermissionError`, ...: `errno`, `strerror` and `filename` set). A
//! frame releases the GIL while it steps; the simulation sits behind a mutex, so calls from
//! several Python threads take turns. A `HapticProxy` ([`raisov::sim::haptic`]) does not: a
//! device thread reads it while a frame steps, and releases the GIL while it reads.

use numpy::ndarray::{Array1, Array2, Array3};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3};
use pyo3::exceptions::{PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyString};
use pyo3::PyErrArguments;
use raisov::sim::{
    Budget, GrabId, GrabOptions, HapticLimits, HapticProxy as Proxy, PinId, Simulation as Sim,
};
use std::path::PathBuf;
use std::sync::{Mutex, MutexGuard};

/// The library's error as a Python exception with the same message: a file's error as the
/// `OSError` subclass of its kind ([`io_error`]), a divergence as `RuntimeError`, everything
/// else (bad input, a bad scenario) as `ValueError`.
fn to_py(e: raisov::Error) -> PyErr {
    match e {
        raisov::Error::Io { path, source } => io_error(&path, &source),
        raisov::Error::Diverged(d) => PyRuntimeError::new_err(d.to_string()),
        e => PyValueError::new_err(e.to_string()),
    }
}

/// The arguments of an `OSError`: `(errno, strerror, filename)` when the error has an errno
/// (the operating system's, or the one of its kind, from Python's `errno` module), else the
/// library's whole message.
struct OsErrorArgs {
    errno: Option<i32>,
    errno_name: Option<&'static str>,
    strerror: String,
    filename: String,
    message: String,
}

impl PyErrArguments for OsErrorArgs {
    fn arguments(self, py: Python<'_>) -> Py<PyAny> {
        let errno = self.errno.or_else(|| {
            let name = self.errno_name?;
            py.import("errno").ok()?.getattr(name).ok()?.extract().ok()
        });
        let args = match errno {
            Some(n) => (n, self.strerror, self.filename).into_pyobject(py),
            None => (self.message,).into_pyobject(py),
        };
        match args {
            Ok(t) => t.into_any().unbind(),
            Err(e) => e.into_value(py).into_any(),
        }
    }
}

/// A file's error as Python raises its own: the `OSError` subclass of the error's kind
/// (`FileNotFoundError`, `PermissionError`, `IsADirectoryError`, ...) with `errno`,
/// `strerror` and `filename` set, `str()` reading `[Errno 2] No such file or directory:
/// 'path'`. An error with no errno (a message of the library's, such as a size limit) is a
/// plain `OSError` of the library's message, which names the file.
fn io_error(path: &std::path::Path, source: &std::io::Error) -> PyErr {
    use pyo3::exceptions as x;
    use std::io::ErrorKind as K;
    let text = source.to_string();
    let strerror = match source.raw_os_error() {
        // The operating system's text without Rust's " (os error N)".
        Some(n) => text
            .strip_suffix(&format!(" (os error {n})"))
            .unwrap_or(&text)
            .to_string(),
        None => text.clone(),
    };
    let kind = source.kind();
    let errno_name = match kind {
        K::NotFound => Some("ENOENT"),
        K::PermissionDenied => Some("EACCES"),
        K::AlreadyExists => Some("EEXIST"),
        K::IsADirectory => Some("EISDIR"),
        K::NotADirectory => Some("ENOTDIR"),
        K::Interrupted => Some("EINTR"),
        K::TimedOut => Some("ETIMEDOUT"),
        K::WouldBlock => Some("EAGAIN"),
        K::BrokenPipe => Some("EPIPE"),
        K::StorageFull => Some("ENOSPC"),
        K::ReadOnlyFilesystem => Some("EROFS"),
        _ => None,
    };
    let args = OsErrorArgs {
        errno: source.raw_os_error(),
        errno_name,
        strerror,
        filename: path.display().to_string(),
        message: format!("{}: {text}", path.display()),
    };
    match kind {
        K::NotFound => PyErr::new::<x::PyFileNotFoundError, _>(args),
        K::PermissionDenied => PyErr::new::<x::PyPermissionError, _>(args),
        K::AlreadyExists => PyErr::new::<x::PyFileExistsError, _>(args),
        K::IsADirectory => PyErr::new::<x::PyIsADirectoryError, _>(args),
        K::NotADirectory => PyErr::new::<x::PyNotADirectoryError, _>(args),
        K::Interrupted => PyErr::new::<x::PyInterruptedError, _>(args),
        K::TimedOut => PyErr::new::<x::PyTimeoutError, _>(args),
        K::WouldBlock => PyErr::new::<x::PyBlockingIOError, _>(args),
        K::BrokenPipe => PyErr::new::<x::PyBrokenPipeError, _>(args),
        // Any other errno: OSError picks its subclass from the errno itself.
        _ => PyErr::new::<PyOSError, _>(args),
    }
}

/// Three finite coordinates from any iterable of numbers (list, tuple, NumPy array).
fn point3(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<[f64; 3]> {
    let mut p = [0.0; 3];
    let mut n = 0usize;
    for item in obj.try_iter()? {
        let x: f64 = item?.extract()?;
        if n < 3 {
            p[n] = x;
        }
        n += 1;
    }
    if n != 3 {
        return Err(PyValueError::new_err(format!(
            "`{what}` must have 3 coordinates (x, y, z in metres), got {n}"
        )));
    }
    Ok(p)
}

/// A Python value as a TOML value: dict → table (string keys), list / tuple / NumPy array →
/// array, bool, int, float, str.
fn to_toml(v: &Bound<'_, PyAny>, key: &str) -> PyResult<toml::Value> {
    if v.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(v.extract()?));
    }
    if v.is_instance_of::<PyInt>() {
        return Ok(toml::Value::Integer(v.extract()?));
    }
    if v.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(v.extract()?));
    }
    if v.is_instance_of::<PyString>() {
        return Ok(toml::Value::String(v.extract()?));
    }
    if let Ok(d) = v.cast::<PyDict>() {
        return Ok(toml::Value::Table(to_table(d, key)?));
    }
    // NumPy arrays and scalars: their Python equivalents.
    if v.hasattr("tolist")? {
        let plain = v.call_method0("tolist")?;
        if !plain.is(v) {
            return to_toml(&plain, key);
        }
    }
    if let Ok(items) = v.try_iter() {
        let mut a = Vec::new();
        for (i, item) in items.enumerate() {
            a.push(to_toml(&item?, &format!("{key}[{i}]"))?);
        }
        return Ok(toml::Value::Array(a));
    }
    Err(PyValueError::new_err(format!(
        "`{key}`: {} is not a scenario value (a number, string, bool, list or dict)",
        v.get_type().name()?
    )))
}

fn to_table(d: &Bound<'_, PyDict>, prefix: &str) -> PyResult<toml::Table> {
    let mut t = toml::Table::new();
    for (k, v) in d.iter() {
        let k: String = k.extract().map_err(|_| {
            PyValueError::new_err(format!("`{prefix}`: scenario keys must be strings"))
        })?;
        let key = if prefix.is_empty() {
            k.clone()
        } else {
            format!("{prefix}.{k}")
        };
        let value = to_toml(&v, &key)?;
        t.insert(k, value);
    }
    Ok(t)
}

/// Mark a freshly made array read-only (it is a copy: writing to it would change nothing).
fn read_only<'py, T>(a: Bound<'py, T>) -> PyResult<Bound<'py, T>> {
    let kw = PyDict::new(a.py());
    kw.set_item("write", false)?;
    a.as_any().call_method("setflags", (), Some(&kw))?;
    Ok(a)
}

fn vec3<'py>(py: Python<'py>, v: [f64; 3]) -> PyResult<Bound<'py, PyArray1<f64>>> {
    read_only(Array1::from(v.to_vec()).into_pyarray(py))
}

fn rows3<'py>(py: Python<'py>, rows: &[[f64; 3]]) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let flat = rows.as_flattened().to_vec();
    let a = Array2::from_shape_vec((rows.len(), 3), flat).expect("3 per row");
    read_only(a.into_pyarray(py))
}

/// A grasp of one `Simulation` (returned by `Simulation.grab`).
#[pyclass(frozen, eq, hash, module = "raisov")]
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
struct Grab {
    id: GrabId,
}

#[pymethods]
impl Grab {
    fn __repr__(&self) -> String {
        // `GrabId(3)` → `raisov.Grab(3)`.
        format!("{:?}", self.id).replacen("GrabId", "raisov.Grab", 1)
    }
}

/// A pin of one `Simulation` (returned by `Simulation.pin`).
#[pyclass(frozen, eq, hash, module = "raisov")]
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
struct Pin {
    id: PinId,
}

#[pymethods]
impl Pin {
    fn __repr__(&self) -> String {
        format!("{:?}", self.id).replacen("PinId", "raisov.Pin", 1)
    }
}

/// What a frame did (`Simulation.step_frame`).
#[pyclass(frozen, get_all, module = "raisov")]
struct FrameReport {
    /// Steps of the accepted try (0 when none was accepted).
    cycles: u64,
    /// Steps of the rejected tries, thrown away.
    rejected_cycles: u64,
    /// Tries rejected before the accepted one (or all of them).
    retries: u32,
    /// Whether a try was accepted; False: the state is the one before the frame.
    accepted: bool,
    /// Whether every grasp reached its target.
    target_reached: bool,
    /// The largest nodal residual |V − R(u)| over free nodes at the end of the frame (N).
    residual: f64,
    /// Why the last rejected try was rejected, or None.
    rejection: Option<String>,
    /// Wall time of the frame (s).
    wall_s: f64,
}

#[pymethods]
impl FrameReport {
    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        // The rejection as Python writes a str or None.
        let rejection = match &self.rejection {
            None => "None".to_string(),
            Some(r) => PyString::new(py, r).repr()?.to_string(),
        };
        Ok(format!(
            "FrameReport(cycles={}, rejected_cycles={}, retries={}, accepted={}, target_reached={}, residual={:e}, rejection={rejection}, wall_s={:e})",
            self.cycles,
            self.rejected_cycles,
            self.retries,
            if self.accepted { "True" } else { "False" },
            if self.target_reached { "True" } else { "False" },
            self.residual,
            self.wall_s
        ))
    }
}

/// The forces the tissue exerts on its supports (`Simulation.reactions`): every constrained
/// node that no grasp holds.
#[pyclass(frozen, get_all, module = "raisov")]
struct Reactions {
    /// The supported nodes, ascending (int64, shape (m,)).
    nodes: Py<PyArray1<i64>>,
    /// The force on each (N, shape (m, 3)).
    forces: Py<PyArray2<f64>>,
    /// Their sum (N, shape (3,)).
    sum: Py<PyArray1<f64>>,
}

/// One frame a haptic proxy published (`HapticProxy.frame`): the grasp's state after a
/// simulation frame.
#[pyclass(frozen, get_all, module = "raisov")]
struct HapticFrame {
    /// The publication's number: 1, 2, ... in the order published.
    seq: u64,
    /// Whether the grasp is held; False after a release (every force zero then).
    held: bool,
    /// The grasp position x_f (m, shape (3,)).
    position: Py<PyArray1<f64>>,
    /// The force the tissue exerts on the tool f_f (N, shape (3,)).
    force: Py<PyArray1<f64>>,
    /// K[i, j] = d f_i / d x_j (N/m, shape (3, 3)).
    stiffness: Py<PyArray2<f64>>,
    /// Simulated time of the frame (s).
    time: f64,
    /// Seconds since the frame was published (when it was read).
    age: f64,
}

impl HapticFrame {
    fn new(py: Python<'_>, f: &raisov::sim::HapticFrame) -> PyResult<Self> {
        Ok(HapticFrame {
            seq: f.seq,
            held: f.held,
            position: vec3(py, f.position)?.unbind(),
            force: vec3(py, f.force)?.unbind(),
            stiffness: rows3(py, &f.stiffness)?.unbind(),
            time: f.time,
            age: f.age().as_secs_f64(),
        })
    }
}

#[pymethods]
impl HapticFrame {
    fn __repr__(&self, py: Python<'_>) -> String {
        format!(
            "HapticFrame(seq={}, held={}, position={}, force={}, time={:e})",
            self.seq,
            if self.held { "True" } else { "False" },
            self.position.bind(py),
            self.force.bind(py),
            self.time
        )
    }
}

/// The force at a device position and the frame it came from (`HapticProxy.sample`).
#[pyclass(frozen, get_all, module = "raisov")]
struct HapticSample {
    /// The frame the force was extrapolated from.
    frame: Py<HapticFrame>,
    /// The force (N, shape (3,)): zero when the grasp is not held.
    force: Py<PyArray1<f64>>,
    /// Whether the device was farther than max_distance from the frame's grasp position.
    distance_clamped: bool,
    /// Whether the force was scaled down to max_force.
    force_clamped: bool,
}

/// A haptic proxy of one grasp (`Simulation.haptic_proxy`): every simulation frame publishes
/// the grasp's position x_f, force f_f and stiffness K to it; any thread reads it at any rate
/// without waiting for the simulation (the GIL is released while it reads) and gets the force
/// at the device's position x,
///
///     d = x - x_f, shortened to max_distance if longer (the linear model's trusted radius)
///     f = f_f + K d, scaled down to max_force if larger (the device's limit),
///
/// the force the tissue exerts on the tool, which the device renders on the hand.
#[pyclass(frozen, module = "raisov")]
struct HapticProxy {
    proxy: Proxy,
}

fn limits_from(
    old: HapticLimits,
    max_force: Option<f64>,
    max_distance: Option<f64>,
) -> HapticLimits {
    HapticLimits {
        max_force: max_force.unwrap_or(old.max_force),
        max_distance: max_distance.unwrap_or(old.max_distance),
    }
}

#[pymethods]
impl HapticProxy {
    /// The force at device position `x` (m) from the newest frame, within the limits (N,
    /// shape (3,)); zero when the grasp is not held.
    fn force_at<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'_, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let x = point3(x, "x")?;
        let f = py.detach(|| self.proxy.force_at(x));
        vec3(py, f)
    }

    /// The newest frame and the force at `x` from it, with what was clamped.
    fn sample(&self, py: Python<'_>, x: &Bound<'_, PyAny>) -> PyResult<HapticSample> {
        let x = point3(x, "x")?;
        let (frame, f) = py.detach(|| self.proxy.sample(x));
        Ok(HapticSample {
            frame: Py::new(py, HapticFrame::new(py, &frame)?)?,
            force: vec3(py, f.force)?.unbind(),
            distance_clamped: f.distance_clamped,
            force_clamped: f.force_clamped,
        })
    }

    /// The newest published frame.
    fn frame(&self, py: Python<'_>) -> PyResult<HapticFrame> {
        let f = py.detach(|| self.proxy.frame());
        HapticFrame::new(py, &f)
    }

    /// Whether the grasp is held (as of the newest frame).
    #[getter]
    fn held(&self) -> bool {
        self.proxy.is_held()
    }

    /// Seconds since the newest frame was published.
    #[getter]
    fn age(&self) -> f64 {
        self.proxy.age().as_secs_f64()
    }

    /// The largest force rendered (N; inf: no limit).
    #[getter]
    fn max_force(&self) -> f64 {
        self.proxy.limits().max_force
    }

    /// The largest extrapolation distance (m; inf: no limit).
    #[getter]
    fn max_distance(&self) -> f64 {
        self.proxy.limits().max_distance
    }

    /// Set either limit or both (each > 0, inf for none); ValueError, nothing changed, else.
    #[pyo3(signature = (max_force = None, max_distance = None))]
    fn set_limits(&self, max_force: Option<f64>, max_distance: Option<f64>) -> PyResult<()> {
        let l = limits_from(self.proxy.limits(), max_force, max_distance);
        self.proxy.set_limits(l).map_err(to_py)
    }

    fn __repr__(&self) -> String {
        let f = self.proxy.frame();
        let l = self.proxy.limits();
        format!(
            "raisov.HapticProxy(seq={}, held={}, max_force={}, max_distance={})",
            f.seq,
            if f.held { "True" } else { "False" },
            l.max_force,
            l.max_distance
        )
    }
}

/// A simulation stepped frame by frame: build it from a scenario file (`Simulation(path)`) or
/// text (`Simulation.from_toml(text, base_dir)`), grasp and pin the surface, step frames,
/// read positions and forces. Units are SI (m, N, s, Pa).
#[pyclass(frozen, module = "raisov")]
struct Simulation {
    inner: Mutex<Sim>,
}

impl Simulation {
    fn sim(&self) -> PyResult<MutexGuard<'_, Sim>> {
        self.inner.lock().map_err(|_| {
            PyRuntimeError::new_err(
                "the simulation is unusable: an earlier call panicked while changing it",
            )
        })
    }

    /// Cut with `blade` without the GIL; the report as a dict (`cut`).
    fn cut_with<'py>(
        &self,
        py: Python<'py>,
        blade: raisov::mesh::cut::Blade,
    ) -> PyResult<Bound<'py, PyDict>> {
        let r = py.detach(|| self.sim().map(|mut s| s.cut(&blade)))?;
        let r = r.map_err(to_py)?;
        let d = PyDict::new(py);
        d.set_item("split", r.split)?;
        d.set_item("nodes", r.nodes)?;
        d.set_item("elements", r.elements)?;
        d.set_item("seconds", r.seconds)?;
        Ok(d)
    }
}

#[pymethods]
impl Simulation {
    /// Load a scenario file (raisov's TOML format); its [run], [output] and [interactive]
    /// sections are not used. Keyword arguments set scenario keys on top of the file, one
    /// per top-level key: a dict for a table (`material={"young": 3e3}`, merged key by key),
    /// any other value replacing the key (`gravity=[0, 0, -9.81]`, `fix=[{...}]`). They are
    /// merged into the TOML document before it is parsed, so errors name the keys as for
    /// the file.
    #[new]
    #[pyo3(signature = (path, **keys))]
    fn new(py: Python<'_>, path: PathBuf, keys: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let overrides = match keys {
            Some(k) => to_table(k, "")?,
            None => toml::Table::new(),
        };
        let sim = py
            .detach(|| Sim::from_file_with(&path, &overrides))
            .map_err(to_py)?;
        Ok(Simulation {
            inner: Mutex::new(sim),
        })
    }

    /// Build from scenario text; relative paths in it (mesh files) are taken from `base_dir`.
    /// Keyword arguments set scenario keys, as for `Simulation(path, **keys)`.
    #[staticmethod]
    #[pyo3(signature = (text, base_dir = PathBuf::from("."), **keys))]
    fn from_toml(
        py: Python<'_>,
        text: String,
        base_dir: PathBuf,
        keys: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let overrides = match keys {
            Some(k) => to_table(k, "")?,
            None => toml::Table::new(),
        };
        let sim = py
            .detach(|| Sim::from_toml_with(&text, &base_dir, &overrides))
            .map_err(to_py)?;
        Ok(Simulation {
            inner: Mutex::new(sim),
        })
    }

    /// Run one frame of `cycles` stepper steps (deterministic) or of `ms` milliseconds of
    /// wall time (at least one step); exactly one of the two. Grasps move to their targets;
    /// a rejected try is retried with smaller sub-moves (`FrameReport`).
    #[pyo3(signature = (cycles = None, ms = None))]
    fn step_frame(
        &self,
        py: Python<'_>,
        cycles: Option<u32>,
        ms: Option<f64>,
    ) -> PyResult<FrameReport> {
        let budget = match (cycles, ms) {
            (Some(n), None) => Budget::Cycles(n),
            (None, Some(ms)) if ms.is_finite() && ms >= 0.0 => Budget::Millis(ms),
            (None, Some(ms)) => {
                return Err(PyValueError::new_err(format!(
                    "`ms` must be a finite number of milliseconds >= 0, got {ms}"
                )))
            }
            _ => {
                return Err(PyValueError::new_err(
                    "give exactly one of `cycles` (stepper steps) or `ms` (wall-time budget)",
                ))
            }
        };
        // The lock is taken and dropped without the GIL, so that another thread waiting for
        // the simulation while holding the GIL cannot deadlock with this one.
        let r = py.detach(|| self.sim().map(|mut s| s.step_frame(budget)))?;
        Ok(FrameReport {
            cycles: r.cycles,
            rejected_cycles: r.rejected_cycles,
            retries: r.retries,
            accepted: r.accepted,
            target_reached: r.target_reached,
            residual: r.residual,
            rejection: r.rejection,
            wall_s: r.wall.as_secs_f64(),
        })
    }

    /// Grasp the surface near `point` (m): the surface nodes within `radius` (m) of the
    /// surface point nearest `point` (at least the nearest node), from the next frame on held
    /// rigidly (`stiffness=None`, a hard grasp) or pulled by springs of total stiffness
    /// `stiffness` (N/m) spread over the nodes by mass, which leave them free to lag behind.
    /// With `friction` (μ) and `clamp` (N) as well, a friction grasp: the springs slide where
    /// they would pull harder than their share of μ × clamp (Coulomb's law on the jaws).
    #[pyo3(signature = (point, radius, stiffness = None, friction = None, clamp = None))]
    fn grab(
        &self,
        point: &Bound<'_, PyAny>,
        radius: f64,
        stiffness: Option<f64>,
        friction: Option<f64>,
        clamp: Option<f64>,
    ) -> PyResult<Grab> {
        let p = point3(point, "point")?;
        let options = match (stiffness, friction, clamp) {
            (None, None, None) => GrabOptions::hard(radius),
            (Some(k), None, None) => GrabOptions::spring(radius, k),
            (Some(k), Some(mu), Some(n)) => GrabOptions::friction(radius, k, mu, n),
            _ => return Err(PyValueError::new_err(
                "grab: a friction grasp needs stiffness (N/m), friction (μ) and clamp (N) together",
            )),
        };
        let id = self.sim()?.grab_with(p, options).map_err(to_py)?;
        Ok(Grab { id })
    }

    /// Make grasp `g` a spring grasp of total stiffness `stiffness` (N/m) from now on.
    fn set_grab_stiffness(&self, g: &Grab, stiffness: f64) -> PyResult<()> {
        self.sim()?
            .set_grab_stiffness(g.id, stiffness)
            .map_err(to_py)
    }

    /// The total spring stiffness of grasp `g` (N/m), or None for a hard grasp.
    fn grab_spring_stiffness(&self, g: &Grab) -> PyResult<Option<f64>> {
        Ok(match self.sim()?.grab_coupling(g.id).map_err(to_py)? {
            raisov::sim::Coupling::Hard => None,
            raisov::sim::Coupling::Spring { stiffness } => Some(stiffness),
        })
    }

    /// The work (J) friction grasp `g`'s sliding has dissipated so far (0 for other grasps).
    fn grab_dissipation(&self, g: &Grab) -> PyResult<f64> {
        self.sim()?.grab_dissipation(g.id).map_err(to_py)
    }

    /// Move grasp `g` to `target` (m); its nodes follow rigidly over the next frame.
    fn move_grab(&self, g: &Grab, target: &Bound<'_, PyAny>) -> PyResult<()> {
        let p = point3(target, "target")?;
        self.sim()?.move_grab(g.id, p).map_err(to_py)
    }

    /// Let go of grasp `g`: its nodes are free from now on.
    fn release(&self, g: &Grab) -> PyResult<()> {
        self.sim()?.release(g.id).map_err(to_py)
    }

    /// Where grasp `g` holds its nodes now (m, shape (3,)).
    fn grab_position<'py>(&self, py: Python<'py>, g: &Grab) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let p = self.sim()?.grab_position(g.id).map_err(to_py)?;
        vec3(py, p)
    }

    /// The grasped nodes of `g` (ascending, int64).
    fn grab_nodes<'py>(&self, py: Python<'py>, g: &Grab) -> PyResult<Bound<'py, PyArray1<i64>>> {
        let nodes: Vec<i64> = self
            .sim()?
            .grab_nodes(g.id)
            .map_err(to_py)?
            .iter()
            .map(|&a| a as i64)
            .collect();
        read_only(nodes.into_pyarray(py))
    }

    /// The force the tissue exerts on the tool of grasp `g` (N, shape (3,)): a hard grasp's
    /// Σ (V − R(u)) over its nodes, a spring grasp's spring pull k (x̄ − x_g − ō) (equal at
    /// equilibrium).
    fn grab_force<'py>(&self, py: Python<'py>, g: &Grab) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let f = self.sim()?.grab_force(g.id).map_err(to_py)?;
        vec3(py, f)
    }

    /// `d grab_force / d x_g` (N/m, shape (3, 3)): the change of the tool force when the
    /// grasp moves and the free nodes return to equilibrium; `K[i, j]` is the change of force
    /// component i per metre along axis j. Three warm-started linear solves.
    fn grab_stiffness<'py>(
        &self,
        py: Python<'py>,
        g: &Grab,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let id = g.id;
        let k = py.detach(|| self.sim().map(|mut s| s.grab_stiffness(id)))?;
        rows3(py, &k.map_err(to_py)?)
    }

    /// A haptic proxy of grasp `g` for a device thread (`HapticProxy`), its force limited to
    /// `max_force` (N) and its extrapolation to `max_distance` (m) from the frame's grasp
    /// position (each > 0; inf for no limit). From now on every frame also computes the
    /// grasp's stiffness (three linear solves) and publishes it with the position and the
    /// force; this call publishes the current ones. The same grasp's proxy again shares the
    /// first's frames and takes the new limits.
    #[pyo3(signature = (g, max_force = f64::INFINITY, max_distance = f64::INFINITY))]
    fn haptic_proxy(
        &self,
        py: Python<'_>,
        g: &Grab,
        max_force: f64,
        max_distance: f64,
    ) -> PyResult<HapticProxy> {
        let limits = HapticLimits::new(max_force, max_distance).map_err(to_py)?;
        let id = g.id;
        let proxy = py.detach(|| self.sim().map(|mut s| s.haptic_proxy(id, limits)))?;
        Ok(HapticProxy {
            proxy: proxy.map_err(to_py)?,
        })
    }

    /// Pin the surface near `point` (m): the patch `grab` would take, held where it stands.
    fn pin(&self, point: &Bound<'_, PyAny>, radius: f64) -> PyResult<Pin> {
        let p = point3(point, "point")?;
        let id = self.sim()?.pin(p, radius).map_err(to_py)?;
        Ok(Pin { id })
    }

    /// Remove pin `p`: its nodes are free from now on.
    fn unpin(&self, p: &Pin) -> PyResult<()> {
        self.sim()?.unpin(p.id).map_err(to_py)
    }

    /// The pinned nodes of `p` (ascending, int64).
    fn pin_nodes<'py>(&self, py: Python<'py>, p: &Pin) -> PyResult<Bound<'py, PyArray1<i64>>> {
        let nodes: Vec<i64> = self
            .sim()?
            .pin_nodes(p.id)
            .map_err(to_py)?
            .iter()
            .map(|&a| a as i64)
            .collect();
        read_only(nodes.into_pyarray(py))
    }

    /// Cut the body with the blade the edge `a`–`b` (m) sweeps along `sweep` (m): the quad
    /// with corners a, b, b + sweep, a + sweep (a scalpel drawn on the surface from a to b and
    /// pushed `|sweep|` deep along `sweep`), on every level (the virtual node algorithm). The
    /// node and element counts change: read `positions`, `masses()`, `surface_triangles`
    /// again. Returns `{"split": [elements split per level, finest first], "nodes": level 0's
    /// nodes after, "elements": level 0's elements after, "seconds": wall time}`; a blade
    /// that misses splits nothing and changes nothing. `ValueError` with the library's
    /// message, nothing changed: a degenerate blade, a membrane, loads that cannot be cut
    /// (pressure, traction, timed loads, tools).
    fn cut<'py>(
        &self,
        py: Python<'py>,
        a: &Bound<'_, PyAny>,
        b: &Bound<'_, PyAny>,
        sweep: &Bound<'_, PyAny>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let (a, b, sweep) = (point3(a, "a")?, point3(b, "b")?, point3(sweep, "sweep")?);
        let blade = raisov::mesh::cut::Blade::swept(a, b, sweep).map_err(to_py)?;
        self.cut_with(py, blade)
    }

    /// Cut the body with the planar, convex quad blade `corners` (4 points in order around
    /// it, m; shape (4, 3)); otherwise as `cut`.
    fn cut_quad<'py>(
        &self,
        py: Python<'py>,
        corners: &Bound<'_, PyAny>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let mut c = [[0.0; 3]; 4];
        let mut n = 0usize;
        for item in corners.try_iter()? {
            let p = point3(&item?, "corners[i]")?;
            if n < 4 {
                c[n] = p;
            }
            n += 1;
        }
        if n != 4 {
            return Err(PyValueError::new_err(format!(
                "`corners` must have 4 points (x, y, z in metres, in order around the quad), got {n}"
            )));
        }
        let blade = raisov::mesh::cut::Blade::quad(c).map_err(to_py)?;
        self.cut_with(py, blade)
    }

    /// The blades cut so far, in order: their corners (m, shape (k, 4, 3)).
    fn cuts<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let blades = self.sim()?.cuts();
        let flat: Vec<f64> = blades
            .iter()
            .flat_map(|b| b.corners.into_iter().flatten())
            .collect();
        let a = Array3::from_shape_vec((blades.len(), 4, 3), flat).expect("12 per blade");
        read_only(a.into_pyarray(py))
    }

    /// Level 0's material fraction per element (1 for an element no cut split; the copies of
    /// a split element sum to 1), float64, shape (elements,).
    fn material_fractions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let f = self.sim()?.material_fractions();
        read_only(f.into_pyarray(py))
    }

    /// The lumped nodal masses (kg, float64, shape (n,)); a read-only copy. A cut shares a
    /// node's mass among its copies by material: the total is kept.
    fn masses<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let m = self.sim()?.masses().to_vec();
        read_only(m.into_pyarray(py))
    }

    /// Retries of a rejected frame, each halving the grasps' sub-moves (default 4).
    fn set_max_retries(&self, retries: u32) -> PyResult<()> {
        self.sim()?.set_max_retries(retries);
        Ok(())
    }

    /// Number of nodes.
    #[getter]
    fn num_nodes(&self) -> PyResult<usize> {
        Ok(self.sim()?.positions().len())
    }

    /// Simulated time (s).
    #[getter]
    fn time(&self) -> PyResult<f64> {
        Ok(self.sim()?.time())
    }

    /// Current node positions X + u (m, float64, shape (n, 3)), in the mesh's node order.
    /// A read-only copy taken now: it keeps these values after later frames (read it again
    /// for the new ones).
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let s = self.sim()?;
        rows3(py, s.positions())
    }

    /// Current displacements u (m, float64, shape (n, 3)); a read-only copy, as `positions`.
    #[getter]
    fn displacements<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let s = self.sim()?;
        let u = s.displacements();
        let a = Array2::from_shape_vec((u.len() / 3, 3), u.to_vec()).expect("3 per node");
        read_only(a.into_pyarray(py))
    }

    /// Reference node positions X (m, shape (n, 3)); a read-only copy.
    #[getter]
    fn rest_positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let s = self.sim()?;
        rows3(py, &s.mesh().nodes)
    }

    /// The surface a renderer draws, at the current state (m, float64, shape (v, 3)): the
    /// visual surface's vertices when the scenario meshed one (`[mesh] surface`, carried by
    /// the simulation mesh), else the mesh's nodes (`positions`). A read-only copy, as
    /// `positions`; index it with `surface_triangles`.
    #[getter]
    fn surface_positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let s = self.sim()?;
        rows3(py, s.surface_positions())
    }

    /// The triangles of `surface_positions` (int64, shape (m, 3), 0-based vertex indices,
    /// counter-clockwise seen from outside): a tetrahedral mesh's boundary faces, a membrane's
    /// own triangles, or the visual surface's. They change only when the body is cut (`cut`:
    /// the wound's faces join them).
    #[getter]
    fn surface_triangles<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<i64>>> {
        let s = self.sim()?;
        let t = s.surface_triangles();
        let flat: Vec<i64> = t.as_flattened().iter().map(|&v| i64::from(v)).collect();
        let a = Array2::from_shape_vec((t.len(), 3), flat).expect("3 per triangle");
        read_only(a.into_pyarray(py))
    }

    /// Nodal Cauchy stress (Pa, shape (n, 3, 3)); a read-only copy.
    #[getter]
    fn nodal_stress<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let mut s = self.sim()?;
        let t = s.nodal_stress();
        let a =
            Array3::from_shape_vec((t.len(), 3, 3), t.as_flattened().to_vec()).expect("9 per node");
        read_only(a.into_pyarray(py))
    }

    /// The largest nodal residual |V − R(u)| over free nodes at the current state (N).
    #[getter]
    fn residual(&self) -> PyResult<f64> {
        Ok(self.sim()?.residual())
    }

    /// Forces the tissue exerts on its supports at the current state (`Reactions`).
    #[getter]
    fn reactions(&self, py: Python<'_>) -> PyResult<Reactions> {
        let s = self.sim()?;
        let r = s.reactions();
        let nodes: Vec<i64> = r.nodes.iter().map(|&a| a as i64).collect();
        Ok(Reactions {
            nodes: read_only(nodes.into_pyarray(py))?.unbind(),
            forces: rows3(py, r.forces)?.unbind(),
            sum: vec3(py, r.sum)?.unbind(),
        })
    }

    /// Total external load (gravity and nodal loads, N, shape (3,)).
    #[getter]
    fn total_load<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let l = self.sim()?.total_load();
        vec3(py, l)
    }

    /// The stepper's description (scheme, levels, step).
    fn describe(&self) -> PyResult<String> {
        Ok(self.sim()?.stepper().describe())
    }

    fn __repr__(&self) -> PyResult<String> {
        let s = self.sim()?;
        Ok(format!(
            "raisov.Simulation({} nodes, t = {} s; {})",
            s.positions().len(),
            s.time(),
            s.stepper().describe()
        ))
    }
}

/// A scenario run to its end by `solve`: how it ended and its final state, in the
/// scenario's node order. Forces follow the module's convention, the force the tissue
/// exerts on each thing: at equilibrium `reaction + prescribed_reaction + tool_force =
/// total_load` (the grasps of an interactive run are prescribed nodes: each grasp's force is
/// its share of `prescribed_reaction`).
#[pyclass(frozen, module = "raisov")]
struct Solution {
    kind: &'static str,
    success: bool,
    stopped: String,
    summary: String,
    steps: u64,
    force_evaluations: f64,
    wall_s: f64,
    time: f64,
    residual: f64,
    max_displacement: f64,
    kinetic_energy: f64,
    u: Vec<f64>,
    stress: Vec<f64>,
    rest: Vec<f64>,
    node_ids: Vec<i64>,
    triangles: Vec<i64>,
    reaction: [f64; 3],
    prescribed_reaction: [f64; 3],
    tool_force: [f64; 3],
    total_load: [f64; 3],
    grasp_forces: Vec<Option<[f64; 3]>>,
    out_dir: Option<PathBuf>,
}

impl Solution {
    fn new(sc: &raisov::scenario::Scenario, s: raisov::runner::Solution) -> Solution {
        let neg = |v: [f64; 3]| v.map(|x| -x);
        let n = sc.mesh.num_nodes();
        let out_dir = match &s.finished {
            raisov::runner::Finished::Static(x) => x.out_dir.clone(),
            raisov::runner::Finished::Dynamic(x) => x.out_dir.clone(),
            raisov::runner::Finished::Interactive(x) => x.out_dir.clone(),
        };
        Solution {
            kind: s.finished.kind(),
            success: s.finished.success(),
            stopped: s.finished.stopped(),
            summary: s.finished.to_string(),
            steps: s.last.step,
            force_evaluations: s.last.force_evals,
            wall_s: s.last.wall,
            time: s.last.time,
            residual: s.last.residual,
            max_displacement: s.last.max_u,
            kinetic_energy: s.last.kinetic,
            rest: sc.mesh.nodes.as_flattened().to_vec(),
            node_ids: (0..n as u32).map(|a| sc.file_node(a) as i64).collect(),
            triangles: sc
                .mesh
                .surface_triangles()
                .as_flattened()
                .iter()
                .map(|&a| i64::from(a))
                .collect(),
            u: s.u,
            stress: s.nodal_stress,
            // The metrics' reactions are the supports' force on the tissue: turned round.
            reaction: neg(s.last.reaction_fixed),
            prescribed_reaction: neg(s.last.reaction_prescribed),
            tool_force: neg(s.last.tool),
            total_load: s.applied,
            grasp_forces: s.grasp_forces,
            out_dir,
        }
    }

    fn rows<'py>(py: Python<'py>, flat: &[f64]) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let a = Array2::from_shape_vec((flat.len() / 3, 3), flat.to_vec()).expect("3 per row");
        read_only(a.into_pyarray(py))
    }
}

#[pymethods]
impl Solution {
    /// "static", "dynamic" or "interactive": what the scenario ran.
    #[getter]
    fn kind(&self) -> &'static str {
        self.kind
    }
    /// Whether the run did what it was asked: a static solve converged, a run in time
    /// reached its duration or steady state, an interactive run played all its frames.
    #[getter]
    fn success(&self) -> bool {
        self.success
    }
    /// How it stopped, in words.
    #[getter]
    fn stopped(&self) -> &str {
        &self.stopped
    }
    /// The closing summary `raisov run` prints.
    #[getter]
    fn summary(&self) -> &str {
        &self.summary
    }
    /// Newton steps of a static solve; stepper steps of a run in time or interactive run.
    #[getter]
    fn steps(&self) -> u64 {
        self.steps
    }
    /// Force evaluations of the run, in finest-level units.
    #[getter]
    fn force_evaluations(&self) -> f64 {
        self.force_evaluations
    }
    /// Wall-clock time of the run (s).
    #[getter]
    fn wall_s(&self) -> f64 {
        self.wall_s
    }
    /// Simulated time at the end (s; a static solve: the end of its prescribed motions).
    #[getter]
    fn time(&self) -> f64 {
        self.time
    }
    /// The residual norm ‖V − R(u)‖₂ over free nodes at the end (N).
    #[getter]
    fn residual(&self) -> f64 {
        self.residual
    }
    /// The largest nodal displacement |u_a| at the end (m).
    #[getter]
    fn max_displacement(&self) -> f64 {
        self.max_displacement
    }
    /// Kinetic energy at the end (J).
    #[getter]
    fn kinetic_energy(&self) -> f64 {
        self.kinetic_energy
    }
    /// Nodal displacements (m, shape (n, 3)); a read-only copy.
    #[getter]
    fn displacements<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        Self::rows(py, &self.u)
    }
    /// Node positions at rest (m, shape (n, 3)).
    #[getter]
    fn rest_positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        Self::rows(py, &self.rest)
    }
    /// Node positions at the end, rest plus displacement (m, shape (n, 3)).
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let x: Vec<f64> = self.rest.iter().zip(&self.u).map(|(x, u)| x + u).collect();
        Self::rows(py, &x)
    }
    /// The boundary triangles of the mesh, three node indices each (int64, shape (m, 3)).
    #[getter]
    fn surface_triangles<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<i64>>> {
        let a = Array2::from_shape_vec((self.triangles.len() / 3, 3), self.triangles.clone())
            .expect("3 per triangle");
        read_only(a.into_pyarray(py))
    }
    /// Each node's id in the mesh file (int64, shape (n,)).
    #[getter]
    fn node_ids<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<i64>>> {
        read_only(self.node_ids.clone().into_pyarray(py))
    }
    /// Nodal Cauchy stress (Pa, shape (n, 3, 3)).
    #[getter]
    fn nodal_stress<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let a = Array3::from_shape_vec((self.stress.len() / 9, 3, 3), self.stress.clone())
            .expect("9 per node");
        read_only(a.into_pyarray(py))
    }
    /// The force the tissue exerts on its fixed supports, summed (N, shape (3,)).
    #[getter]
    fn reaction<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        vec3(py, self.reaction)
    }
    /// The force the tissue exerts on its prescribed (moved, grasped) nodes, summed (N).
    #[getter]
    fn prescribed_reaction<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        vec3(py, self.prescribed_reaction)
    }
    /// The force the tissue exerts on the scenario's tools (N, shape (3,)).
    #[getter]
    fn tool_force<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        vec3(py, self.tool_force)
    }
    /// Loads and body forces applied, Σ V (N, shape (3,)).
    #[getter]
    fn total_load<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        vec3(py, self.total_load)
    }
    /// Per `[[displace]]` grasp taken during an interactive run (file order), the force the
    /// tissue exerts on it at the end (N, shape (3,)), None for one let go by then; an
    /// empty list for other runs.
    #[getter]
    fn grasp_forces<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<Vec<Option<Bound<'py, PyArray1<f64>>>>> {
        self.grasp_forces
            .iter()
            .map(|g| g.map(|f| vec3(py, f)).transpose())
            .collect()
    }
    /// The output directory written, or None (the default: nothing written).
    #[getter]
    fn out_dir(&self) -> Option<PathBuf> {
        self.out_dir.clone()
    }
    fn __repr__(&self) -> String {
        format!(
            "raisov.Solution({}, {} nodes, {}; {} steps, {:.3} s)",
            self.kind,
            self.node_ids.len(),
            self.stopped,
            self.steps,
            self.wall_s
        )
    }
}

/// Run a scenario file to its end and return its `Solution`: a static solve
/// (`method = "newton"`), a run in time, or an interactive run's frames, as the scenario
/// says (what `raisov run` does). Keyword arguments set scenario keys on top of the file,
/// as for `Simulation(path, **keys)`. Nothing is written unless `out` names a directory
/// (then the files `raisov run --out` writes). `threads`: the worker threads of this solve
/// (default: the process's pool; the bits are the same for any number). The GIL is
/// released while it computes, so threads can run solves side by side; Ctrl-C stops a run
/// in time at its next step (KeyboardInterrupt). A run that ends without doing what it
/// was asked (no convergence, no steady state) returns with `success` False and a
/// `RuntimeWarning`; a divergence raises `RuntimeError`, a bad scenario `ValueError`, a
/// file's error the `OSError` Python raises for it.
#[pyfunction]
#[pyo3(signature = (scenario, *, out = None, threads = None, **keys))]
fn solve(
    py: Python<'_>,
    scenario: PathBuf,
    out: Option<PathBuf>,
    threads: Option<usize>,
    keys: Option<&Bound<'_, PyDict>>,
) -> PyResult<Solution> {
    use std::sync::atomic::{AtomicBool, Ordering};
    let overrides = match keys {
        Some(k) => to_table(k, "")?,
        None => toml::Table::new(),
    };
    if threads == Some(0) {
        return Err(PyValueError::new_err(
            "threads = 0: give a positive number of threads, or None for the process's pool",
        ));
    }
    let pool = threads
        .map(|n| rayon::ThreadPoolBuilder::new().num_threads(n).build())
        .transpose()
        .map_err(|e| PyRuntimeError::new_err(format!("cannot start {threads:?} threads: {e}")))?;
    let stop = AtomicBool::new(false);
    let run = || -> raisov::Result<Solution> {
        let text =
            std::fs::read_to_string(&scenario).map_err(|e| raisov::Error::io(&scenario, e))?;
        let text = raisov::sim::overrides::merge(&text, &overrides, &scenario)?;
        let sc = raisov::scenario::Scenario::from_toml(&text, &scenario)?;
        let opts = raisov::runner::RunOptions {
            in_memory: out.is_none(),
            out_dir: out.clone(),
            stop: Some(&stop),
            progress: None,
        };
        let s = raisov::runner::solve(&sc, opts)?;
        Ok(Solution::new(&sc, s))
    };
    let run = || match &pool {
        Some(p) => p.install(run),
        None => run(),
    };
    // The solve runs on a thread of its own without the GIL; this one waits for it and
    // looks at Python's signals every 50 ms (Ctrl-C raises the stop flag).
    let result = std::thread::scope(|scope| {
        let (tx, rx) = std::sync::mpsc::channel();
        // (Behind a mutex: the waiting closure runs without the GIL and must be Sync.)
        let rx = Mutex::new(rx);
        let worker = scope.spawn(move || {
            let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(run));
            let _ = tx.send(());
            r
        });
        loop {
            let wait = py.detach(|| match rx.lock() {
                Ok(rx) => rx.recv_timeout(std::time::Duration::from_millis(50)),
                Err(_) => Err(std::sync::mpsc::RecvTimeoutError::Disconnected),
            });
            if !matches!(wait, Err(std::sync::mpsc::RecvTimeoutError::Timeout)) {
                break;
            }
            if let Err(e) = py.check_signals() {
                stop.store(true, Ordering::Relaxed);
                let _ = py.detach(|| worker.join());
                return Err(e);
            }
        }
        match py.detach(|| worker.join()) {
            Ok(Ok(r)) => r.map_err(to_py),
            _ => Err(PyRuntimeError::new_err(
                "the solve panicked (a bug: please report it)",
            )),
        }
    })?;
    if !result.success {
        let warning = py.get_type::<pyo3::exceptions::PyRuntimeWarning>();
        let msg = std::ffi::CString::new(format!("{}: {}", scenario.display(), result.stopped))
            .unwrap_or_default();
        PyErr::warn(py, &warning, &msg, 1)?;
    }
    Ok(result)
}

/// raisov: nonlinear hyperelastic soft-tissue simulation with multigrid explicit
/// integration, stepped frame by frame.
#[pymodule(name = "raisov")]
fn raisov_module(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(solve, m)?)?;
    m.add_class::<Solution>()?;
    m.add_class::<Simulation>()?;
    m.add_class::<Grab>()?;
    m.add_class::<Pin>()?;
    m.add_class::<FrameReport>()?;
    m.add_class::<Reactions>()?;
    m.add_class::<HapticProxy>()?;
    m.add_class::<HapticFrame>()?;
    m.add_class::<HapticSample>()?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
