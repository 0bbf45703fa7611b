//! `raisov bench surface-check`: the cost of [`raisov::mesh::check_surface`] on surfaces of
//! long thin triangles and on the shipped organ surfaces.
//!
//! Cases: closed cones whose side and base are fans of long thin triangles around two
//! vertices of high valence ([`raisov::mesh::generate::cone_surface`], radius 5 cm, height
//! 10 cm; `cone 20k` and `cone 80k` with the axis along [`TILTED_AXIS`], `cone 20k z` along z),
//! and `data/liver_surface.obj` and `data/heart_surface.obj` as shipped. Each row gives the
//! wall time of the whole check (best of up to [`REPEATS`] runs, fewer when a run takes more
//! than a second) and the self-intersection test's work in counts that do not depend on the
//! machine ([`raisov::mesh::IntersectionWork`]): bounding-volume tests, candidate pairs
//! passed to the exact test, and exact orientation predicates evaluated.

use std::path::Path;
use std::time::Instant;

use raisov::mesh::generate::cone_surface;
use raisov::mesh::{check_surface, Surface};
use raisov::{Error, Result};

/// Axis of the tilted cones: along no coordinate axis or diagonal.
pub const TILTED_AXIS: [f64; 3] = [0.3, 0.5, 0.8];
/// Most runs timed per case.
pub const REPEATS: usize = 3;

/// A surface to check.
pub struct SurfaceCase {
    /// Short name (`--case`).
    pub name: String,
    /// The surface as read or generated (each run checks a copy).
    pub surface: Surface,
}

/// One row of the table.
#[derive(Clone, Debug)]
pub struct SurfaceRow {
    /// Case name.
    pub name: String,
    /// Triangles.
    pub triangles: usize,
    /// Best wall time of the check (s).
    pub seconds: f64,
    /// Runs timed.
    pub runs: usize,
    /// The check's verdict: `ok` or the error.
    pub verdict: String,
    /// The self-intersection test's work.
    pub work: raisov::mesh::IntersectionWork,
}

/// The cones: `(name, segments, axis)`, `segments` rim vertices, twice as many triangles.
pub fn cones(quick: bool) -> Vec<(&'static str, usize, [f64; 3])> {
    if quick {
        vec![
            ("cone 2k", 1_000, TILTED_AXIS),
            ("cone 8k", 4_000, TILTED_AXIS),
        ]
    } else {
        vec![
            ("cone 20k z", 10_000, [0.0, 0.0, 1.0]),
            ("cone 20k", 10_000, TILTED_AXIS),
            ("cone 80k", 40_000, TILTED_AXIS),
        ]
    }
}

/// The cases: the cones of [`cones`], then the liver and heart surfaces from `meshes` when
/// present (skipped with a note through `emit` when absent).
pub fn surface_cases(
    meshes: &Path,
    quick: bool,
    emit: &mut dyn FnMut(&str),
) -> Result<Vec<SurfaceCase>> {
    let mut cases = Vec::new();
    for (name, segments, axis) in cones(quick) {
        cases.push(SurfaceCase {
            name: name.to_string(),
            surface: cone_surface(segments, 0.05, 0.1, axis)?,
        });
    }
    for organ in ["liver", "heart"] {
        let f = meshes.join(format!("{organ}_surface.obj"));
        if f.exists() {
            cases.push(SurfaceCase {
                name: organ.to_string(),
                surface: raisov::io::load_surface(&f)?,
            });
        } else {
            emit(&format!("{}: absent, {organ} skipped", f.display()));
        }
    }
    Ok(cases)
}

/// Check each case's surface, timed; `emit` gets a line per case as it completes.
pub fn surface_check(cases: &[SurfaceCase], emit: &mut dyn FnMut(&str)) -> Result<Vec<SurfaceRow>> {
    let mut rows = Vec::new();
    for case in cases {
        let mut best = f64::INFINITY;
        let mut runs = 0;
        let mut verdict = String::new();
        let mut work = Default::default();
        while runs < REPEATS && (runs == 0 || best < 1.0) {
            let mut s = case.surface.clone();
            let t = Instant::now();
            let r = check_surface(&mut s);
            best = best.min(t.elapsed().as_secs_f64());
            runs += 1;
            match r {
                Ok(r) => {
                    verdict = "ok".into();
                    work = r.intersection_work;
                }
                Err(e) => verdict = e.to_string(),
            }
        }
        let row = SurfaceRow {
            name: case.name.clone(),
            triangles: case.surface.triangles.len(),
            seconds: best,
            runs,
            verdict,
            work,
        };
        emit(&format!(
            "{}: {} triangles, {:.3} s (best of {}), {} volume tests, {} candidates, {} \
             predicates: {}",
            row.name,
            row.triangles,
            row.seconds,
            row.runs,
            row.work.volume_tests,
            row.work.candidates,
            row.work.predicates,
            row.verdict
        ));
        rows.push(row);
    }
    Ok(rows)
}

/// The rows as a Markdown table.
pub fn to_markdown(rows: &[SurfaceRow]) -> String {
    let mut s = String::from(
        "| case | triangles | check (s) | volume tests | candidates | predicates | \
         predicates per triangle | verdict |\n|---|---:|---:|---:|---:|---:|---:|---|\n",
    );
    for r in rows {
        s.push_str(&format!(
            "| {} | {} | {:.3} | {} | {} | {} | {:.1} | {} |\n",
            r.name,
            r.triangles,
            r.seconds,
            r.work.volume_tests,
            r.work.candidates,
            r.work.predicates,
            r.work.predicates as f64 / r.triangles.max(1) as f64,
            r.verdict
        ));
    }
    s
}

/// Write a surface as Wavefront OBJ (`v x y z`, `f a b c` with 1-based indices).
pub fn write_obj(path: &Path, s: &Surface) -> Result<()> {
    use std::fmt::Write;
    let mut text = String::with_capacity(40 * (s.points.len() + s.triangles.len()));
    for p in &s.points {
        let _ = writeln!(text, "v {:e} {:e} {:e}", p[0], p[1], p[2]);
    }
    for t in &s.triangles {
        let _ = writeln!(text, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    std::fs::write(path, text).map_err(|e| Error::io(path, e))
}
