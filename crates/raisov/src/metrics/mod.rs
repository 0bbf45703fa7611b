//! Measures of a run (paper section 3; design note "Measures").
//!
//! Per sample: time, kinetic energy `½ Σ m |u̇|²`, residual norm `‖V − R(u)‖₂` over free
//! nodes, `max |u|`, and, when a steady-state reference `T∞` is known, the max and mean over
//! non-fixed nodes of `|T − T∞|` (Frobenius norm of the nodal stress tensor difference, Pa).

use crate::error::Result;
use crate::integrate::{State, System};
use crate::io::write_atomic;
use std::path::Path;

/// One row of the measures CSV.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sample {
    pub step: u64,
    pub time: f64,
    pub kinetic: f64,
    pub residual: f64,
    pub max_u: f64,
    /// max |T − T∞| over non-fixed nodes (NaN when no reference).
    pub stress_err_max: f64,
    /// mean |T − T∞| over non-fixed nodes (NaN when no reference).
    pub stress_err_mean: f64,
    /// Force evaluations so far, in finest-level units.
    pub force_evals: f64,
    /// Wall time since the start of the run (s).
    pub wall: f64,
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

/// Largest nodal displacement magnitude.
pub fn max_displacement(u: &[f64]) -> f64 {
    u.chunks_exact(3)
        .map(|d| (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt())
        .fold(0.0, f64::max)
}

/// Computes samples; owns scratch so sampling allocates nothing after creation.
pub struct Meter {
    residual: Vec<f64>,
    stress: Vec<f64>,
    /// Steady-state nodal stress T∞ (9 per node), if known.
    pub t_inf: Option<Vec<f64>>,
}

impl Meter {
    pub fn new(n: usize, t_inf: Option<Vec<f64>>) -> Self {
        Meter {
            residual: vec![0.0; 3 * n],
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
        }
    }

    /// The nodal stress of the last sample (9 per node), valid after a sample with a reference.
    pub fn last_stress(&self) -> &[f64] {
        &self.stress
    }
}

/// Header of the measures CSV.
pub const CSV_HEADER: &str =
    "step,time_s,kinetic_J,residual_N,max_u_m,stress_err_max_Pa,stress_err_mean_Pa,force_evals,wall_s";

/// Write samples as CSV, atomically. Missing stress errors are written as empty fields.
pub fn write_csv(path: &Path, rows: &[Sample]) -> Result<()> {
    write_atomic(path, |w| {
        writeln!(w, "{CSV_HEADER}")?;
        let opt = |x: f64| {
            if x.is_finite() {
                format!("{x:.9e}")
            } else {
                String::new()
            }
        };
        for r in rows {
            writeln!(
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
        }
        Ok(())
    })
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
