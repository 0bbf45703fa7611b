//! Measures of a run (paper section 3; design note "Measures").
//!
//! Per sample: time, kinetic energy `½ Σ m |u̇|²`, residual norm `‖V − R(u)‖₂` over free
//! nodes, `max |u|`, and, when a steady-state reference `T∞` is known, the max and mean over
//! non-fixed nodes of `|T − T∞|` (Frobenius norm of the nodal stress tensor difference, Pa),
//! and the reactions: the force the supports exert on the body,
//!
//! ```text
//! F_fixed = Σ_{a fixed} P_a (R_a(u) − V_a),   F_prescribed = Σ_{a prescribed} (R_a(u) − V_a),
//! ```
//!
//! `P_a` the projection onto the constrained directions of node `a` (all three for a fixed
//! node, the normals of a sliding one). At equilibrium the free nodes satisfy `R = V` and
//! `Σ_a R_a = 0` (internal forces are self-equilibrated), so `F_fixed + F_prescribed + Σ_a V_a
//! = 0`: the reactions balance the applied loads and body forces. (The inertia of a moving
//! prescribed node, `M g̈`, is not included.) Surface loads and tools are part of the force
//! model ([`crate::fem::loads::Loaded`], `R` there includes `−F_loads − F_tool`), so the
//! balance reads `F_fixed + F_prescribed + F_tool + Σ_a V_a + Σ_a F_loads,a = 0`, with
//! `F_tool` the force the tools exert on the body ([`crate::contact`]), reported per sample
//! with the deepest penetration.

use crate::error::{Error, Result};
use crate::integrate::{State, System};
use crate::io::{write_atomic, RowFile};
use std::io::Write;
use std::path::Path;

/// One row of the measures CSV.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sample {
    /// Step number.
    pub step: u64,
    /// Time (s).
    pub time: f64,
    /// Kinetic energy (J).
    pub kinetic: f64,
    /// Residual norm ‖V − R(u)‖ over free nodes (N).
    pub residual: f64,
    /// Largest nodal displacement |u| (m).
    pub max_u: f64,
    /// max |T − T∞| over non-fixed nodes (NaN when no reference).
    pub stress_err_max: f64,
    /// mean |T − T∞| over non-fixed nodes (NaN when no reference).
    pub stress_err_mean: f64,
    /// Force evaluations so far, in finest-level units.
    pub force_evals: f64,
    /// Wall time since the start of the run (s).
    pub wall: f64,
    /// Reaction at the fixed nodes and fixed components, `F_fixed` (N).
    pub reaction_fixed: [f64; 3],
    /// Reaction at the prescribed nodes, `F_prescribed` (N).
    pub reaction_prescribed: [f64; 3],
    /// The force the tools exert on the body, `F_tool` (N).
    pub tool: [f64; 3],
    /// The deepest penetration of a node into a tool (m).
    pub penetration: f64,
    /// The tangential (friction) part of `tool`, `F_friction` (N); zero without friction.
    pub friction: [f64; 3],
}

/// `max |T − T∞|` and mean over nodes where `mask` is false (free nodes).
pub fn stress_error(t: &[f64], t_inf: &[f64], mask: &[bool]) -> (f64, f64) {
    let mut max: f64 = 0.0;
    let mut sum = 0.0;
    let mut count = 0usize;
    for (a, &constrained) in mask.iter().enumerate() {
        if constrained {
            continue;
        }
        let d: f64 = (0..9)
            .map(|k| (t[9 * a + k] - t_inf[9 * a + k]).powi(2))
            .sum::<f64>()
            .sqrt();
        max = max.max(d);
        sum += d;
        count += 1;
    }
    (max, if count > 0 { sum / count as f64 } else { 0.0 })
}

/// Largest nodal magnitude of a per-node 3-vector field (a displacement, a force).
pub fn max_displacement(u: &[f64]) -> f64 {
    u.chunks_exact(3)
        .map(|d| (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt())
        .fold(0.0, f64::max)
}

/// Computes samples; owns scratch so sampling allocates nothing after creation.
pub struct Meter {
    residual: Vec<f64>,
    internal: Vec<f64>,
    stress: Vec<f64>,
    /// Steady-state nodal stress T∞ (9 per node), if known.
    pub t_inf: Option<Vec<f64>>,
}

impl Meter {
    /// A meter for `n` nodes, with the steady-state nodal stress `t_inf` (9 per node) when known.
    pub fn new(n: usize, t_inf: Option<Vec<f64>>) -> Self {
        Meter {
            residual: vec![0.0; 3 * n],
            internal: vec![0.0; 3 * n],
            stress: vec![0.0; 9 * n],
            t_inf,
        }
    }

    /// Measure `state` of `sys`.
    pub fn sample(&mut self, sys: &mut System, s: &State, step: u64) -> Sample {
        let residual = sys.residual(&s.u, &mut self.residual).unwrap_or(f64::NAN);
        let (em, ea) = match &self.t_inf {
            Some(t_inf) => {
                sys.force.nodal_stress(&s.u, &mut self.stress);
                stress_error(&self.stress, t_inf, sys.constraints.mask())
            }
            None => (f64::NAN, f64::NAN),
        };
        let (reaction_fixed, reaction_prescribed) = reactions(sys, &s.u, &mut self.internal);
        let lr = sys.force.load_report(&s.u);
        Sample {
            step,
            time: s.t,
            kinetic: sys.kinetic_energy(&s.v),
            residual,
            max_u: max_displacement(&s.u),
            stress_err_max: em,
            stress_err_mean: ea,
            force_evals: 0.0,
            wall: 0.0,
            reaction_fixed,
            reaction_prescribed,
            tool: lr.tool,
            penetration: lr.max_penetration,
            friction: lr.friction,
        }
    }

    /// The nodal stress of the last sample (9 per node), valid after a sample with a reference.
    pub fn last_stress(&self) -> &[f64] {
        &self.stress
    }
}

/// The reactions `(F_fixed, F_prescribed)` of `sys` at `u` (see the module documentation);
/// `scratch` holds 3 per node. Zero where an element is inverted.
pub fn reactions(sys: &mut System, u: &[f64], scratch: &mut [f64]) -> ([f64; 3], [f64; 3]) {
    if sys.force.internal_forces(u, scratch).is_err() {
        return ([0.0; 3], [0.0; 3]);
    }
    let c = &sys.constraints;
    let f = &sys.f_ext;
    let at = |a: usize| -> [f64; 3] {
        [
            scratch[3 * a] - f[3 * a],
            scratch[3 * a + 1] - f[3 * a + 1],
            scratch[3 * a + 2] - f[3 * a + 2],
        ]
    };
    let add = |s: &mut [f64; 3], r: [f64; 3]| {
        for k in 0..3 {
            s[k] += r[k];
        }
    };
    let (mut fixed, mut prescribed) = ([0.0; 3], [0.0; 3]);
    for &a in &c.fixed {
        add(&mut fixed, at(a as usize));
    }
    for &(a, n) in c.sliding() {
        if c.is_constrained(a as usize) {
            continue;
        }
        let r = at(a as usize);
        let rn = r[0] * n[0] + r[1] * n[1] + r[2] * n[2];
        add(&mut fixed, [rn * n[0], rn * n[1], rn * n[2]]);
    }
    for (a, _) in &c.prescribed {
        add(&mut prescribed, at(*a as usize));
    }
    (fixed, prescribed)
}

/// Header of the measures CSV.
pub const CSV_HEADER: &str =
    "step,time_s,kinetic_J,residual_N,max_u_m,stress_err_max_Pa,stress_err_mean_Pa,force_evals,wall_s,\
reaction_fixed_x_N,reaction_fixed_y_N,reaction_fixed_z_N,\
reaction_prescribed_x_N,reaction_prescribed_y_N,reaction_prescribed_z_N,\
tool_fx_N,tool_fy_N,tool_fz_N,penetration_m";

/// The columns [`CSV_HEADER`] ends with for scenarios with friction: `F_friction` (N).
pub const CSV_FRICTION: &str = ",friction_x_N,friction_y_N,friction_z_N";

/// The measures CSV's header, with the friction columns where `friction`.
pub fn csv_header(friction: bool) -> String {
    if friction {
        format!("{CSV_HEADER}{CSV_FRICTION}")
    } else {
        CSV_HEADER.to_string()
    }
}

/// One CSV row of `r` (no newline), with the friction columns where `friction`. Missing
/// stress errors are empty fields.
fn csv_row(w: &mut dyn Write, r: &Sample, friction: bool) -> std::io::Result<()> {
    let opt = |x: f64| {
        if x.is_finite() {
            format!("{x:.9e}")
        } else {
            String::new()
        }
    };
    write!(
        w,
        "{},{:.9e},{:.9e},{},{:.9e},{},{},{},{:.6}",
        r.step,
        r.time,
        r.kinetic,
        opt(r.residual),
        r.max_u,
        opt(r.stress_err_max),
        opt(r.stress_err_mean),
        r.force_evals,
        r.wall
    )?;
    for x in r
        .reaction_fixed
        .iter()
        .chain(&r.reaction_prescribed)
        .chain(&r.tool)
        .chain([&r.penetration])
    {
        write!(w, ",{}", opt(*x))?;
    }
    if friction {
        for x in r.friction {
            write!(w, ",{}", opt(x))?;
        }
    }
    Ok(())
}

/// Write samples as CSV, atomically, with the friction columns where `friction`.
pub fn write_csv(path: &Path, rows: &[Sample], friction: bool) -> Result<()> {
    write_atomic(path, |w| {
        writeln!(w, "{}", csv_header(friction))?;
        for r in rows {
            csv_row(w, r, friction)?;
            writeln!(w)?;
        }
        Ok(())
    })
}

/// `measures.csv` written as the rows come ([`RowFile`]): the header at creation, each
/// [`CsvStream::push`] buffered, [`CsvStream::flush`] hands the rows so far to the operating
/// system (a process killed after a flush leaves them in the file). Nothing is kept in memory
/// but the buffer. The file only ever ends at a row boundary; a failed write says what it
/// kept.
pub struct CsvStream {
    file: RowFile,
    /// The row being formatted.
    line: Vec<u8>,
    /// Whether the rows have the friction columns.
    friction: bool,
}

impl CsvStream {
    /// Create (truncate) `path` and write the header (with the friction columns where
    /// `friction`); never through a symbolic link.
    pub fn create(path: &Path, friction: bool) -> Result<CsvStream> {
        Ok(CsvStream {
            file: RowFile::create(path, &csv_header(friction))?,
            line: Vec::with_capacity(512),
            friction,
        })
    }
    /// Rows formatted and dropped, no file written ([`RowFile::discard`]).
    pub fn discard(path: &Path, friction: bool) -> Result<CsvStream> {
        Ok(CsvStream {
            file: RowFile::discard(path, &csv_header(friction))?,
            line: Vec::with_capacity(512),
            friction,
        })
    }
    /// Append one row.
    pub fn push(&mut self, r: &Sample) -> Result<()> {
        self.line.clear();
        csv_row(&mut self.line, r, self.friction).map_err(|e| Error::io(self.file.path(), e))?;
        self.file.push(&self.line)
    }
    /// Write the buffered rows to the file.
    pub fn flush(&mut self) -> Result<()> {
        self.file.flush()
    }
    /// Rows written so far.
    pub fn rows(&self) -> u64 {
        self.file.rows()
    }
    /// The file.
    pub fn path(&self) -> &Path {
        self.file.path()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stress_error_skips_constrained_nodes() {
        let t = vec![1.0; 27];
        let mut t_inf = vec![1.0; 27];
        t_inf[0] = 4.0; // node 0 differs by 3 in one component
        t_inf[9 + 4] = 0.0; // node 1 differs by 1
        let (mx, mean) = stress_error(&t, &t_inf, &[false, false, false]);
        assert_eq!(mx, 3.0);
        assert!((mean - 4.0 / 3.0).abs() < 1e-15);
        let (mx, mean) = stress_error(&t, &t_inf, &[true, false, false]);
        assert_eq!(mx, 1.0);
        assert!((mean - 0.5).abs() < 1e-15);
    }
}
