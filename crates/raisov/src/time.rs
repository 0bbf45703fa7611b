//! Functions of time, the one vocabulary of loads, tools and prescribed displacements.
//!
//! **Time functions** ([`TimeFunction`], dimensionless factors multiplying a load's value, a
//! tool's translation or a prescribed displacement; `time = { kind = .. }` in a scenario):
//!
//! ```text
//! constant   s(t) = 1
//! ramp       s(t) = min(max(t, 0) / T, 1)                    (T the duration, s)
//! table      s(t) piecewise linear through (t_k, s_k); s_0 before the first row, the last
//!            value after the last
//! sine       s(t) = A sin(2π f t + φ)                        (A amplitude, f in Hz, φ in rad)
//! ```
//!
//! **Motions** ([`Motion`], a displacement `g(t)` in m: a prescribed node's, a tool's
//! translation): held (`g = d` from t = 0, the paper's instantaneous 3 cm lift), ramped
//! linearly over a duration then held, a table of (time, displacement) rows, linear between
//! rows and held after the last, or a vector times a [`TimeFunction`]. A scenario's
//! `[[displace]]` takes either spelling: `mode = "held" | "ramp" | "table"`, or
//! `time = { kind = .. }` for `displacement` times `s(t)`.

/// A dimensionless factor of time, `s(t)` (see the module documentation).
#[derive(Clone, Debug, PartialEq, Default)]
pub enum TimeFunction {
    /// `s = 1`.
    #[default]
    Constant,
    /// `s = min(t / duration, 1)` for t ≥ 0 (duration in s, > 0).
    Ramp {
        /// The ramp time T (s).
        duration: f64,
    },
    /// Piecewise linear through `(times[k], values[k])`, times strictly increasing (s).
    Table {
        /// The rows' times (s), strictly increasing.
        times: Vec<f64>,
        /// The factor at each time (dimensionless); the first before the first row, the last
        /// after the last.
        values: Vec<f64>,
    },
    /// `s = amplitude · sin(2π frequency t + phase)` (frequency in Hz, phase in rad).
    Sine {
        /// A (dimensionless).
        amplitude: f64,
        /// f (Hz).
        frequency: f64,
        /// φ (rad).
        phase: f64,
    },
}

impl TimeFunction {
    /// `s(t)`.
    pub fn value(&self, t: f64) -> f64 {
        match self {
            TimeFunction::Constant => 1.0,
            TimeFunction::Ramp { duration } => {
                if *duration > 0.0 {
                    (t / duration).clamp(0.0, 1.0)
                } else {
                    1.0
                }
            }
            TimeFunction::Table { times, values } => {
                let k = times.partition_point(|&x| x <= t);
                if k == 0 {
                    values[0]
                } else if k == times.len() {
                    values[k - 1]
                } else {
                    let s = (t - times[k - 1]) / (times[k] - times[k - 1]);
                    values[k - 1] + s * (values[k] - values[k - 1])
                }
            }
            TimeFunction::Sine {
                amplitude,
                frequency,
                phase,
            } => amplitude * (2.0 * std::f64::consts::PI * frequency * t + phase).sin(),
        }
    }
    /// `ds/dt` (right derivative, 1/s).
    pub fn rate(&self, t: f64) -> f64 {
        match self {
            TimeFunction::Constant => 0.0,
            TimeFunction::Ramp { duration } => {
                if *duration > 0.0 && (0.0..*duration).contains(&t) {
                    1.0 / duration
                } else {
                    0.0
                }
            }
            TimeFunction::Table { times, values } => {
                let k = times.partition_point(|&x| x <= t);
                if k == 0 || k == times.len() {
                    0.0
                } else {
                    (values[k] - values[k - 1]) / (times[k] - times[k - 1])
                }
            }
            TimeFunction::Sine {
                amplitude,
                frequency,
                phase,
            } => {
                let w = 2.0 * std::f64::consts::PI * frequency;
                amplitude * w * (w * t + phase).cos()
            }
        }
    }
    /// Largest `|s(t)|` over all t.
    pub fn max_abs(&self) -> f64 {
        match self {
            TimeFunction::Constant | TimeFunction::Ramp { .. } => 1.0,
            TimeFunction::Table { values, .. } => values.iter().fold(0.0, |m, v| m.max(v.abs())),
            TimeFunction::Sine { amplitude, .. } => amplitude.abs(),
        }
    }
    /// The time after which `s` is constant (s); infinite for a sine.
    pub fn end(&self) -> f64 {
        match self {
            TimeFunction::Constant => 0.0,
            TimeFunction::Ramp { duration } => *duration,
            TimeFunction::Table { times, .. } => *times.last().unwrap_or(&0.0),
            TimeFunction::Sine { .. } => f64::INFINITY,
        }
    }
}

/// Time law of a prescribed displacement.
#[derive(Clone, Debug, PartialEq)]
pub enum Motion {
    /// `g(t) = d` for all t ≥ 0.
    Held {
        /// Displacement (m).
        d: [f64; 3],
    },
    /// `g(t) = d · min(t / duration, 1)`.
    Ramp {
        /// Final displacement (m).
        d: [f64; 3],
        /// Ramp time (s).
        duration: f64,
    },
    /// Piecewise linear through `(times[k], values[k])`; `times` strictly increasing;
    /// before the first row the first value, after the last the last value.
    Table {
        /// Times (s), strictly increasing.
        times: Vec<f64>,
        /// Displacements (m), one per time.
        values: Vec<[f64; 3]>,
    },
    /// `g(t) = d · s(t)`.
    Function {
        /// Amplitude displacement (m).
        d: [f64; 3],
        /// The time function `s(t)`.
        f: TimeFunction,
    },
}

impl Motion {
    /// Displacement g(t).
    pub fn displacement(&self, t: f64) -> [f64; 3] {
        match self {
            Motion::Held { d } => *d,
            Motion::Ramp { d, duration } => {
                let s = if *duration > 0.0 {
                    (t / duration).clamp(0.0, 1.0)
                } else {
                    1.0
                };
                [d[0] * s, d[1] * s, d[2] * s]
            }
            Motion::Table { times, values } => {
                let k = times.partition_point(|&x| x <= t);
                if k == 0 {
                    values[0]
                } else if k == times.len() {
                    values[k - 1]
                } else {
                    let s = (t - times[k - 1]) / (times[k] - times[k - 1]);
                    let (a, b) = (values[k - 1], values[k]);
                    [
                        a[0] + s * (b[0] - a[0]),
                        a[1] + s * (b[1] - a[1]),
                        a[2] + s * (b[2] - a[2]),
                    ]
                }
            }
            Motion::Function { d, f } => {
                let s = f.value(t);
                [d[0] * s, d[1] * s, d[2] * s]
            }
        }
    }
    /// Velocity ġ(t) (right derivative).
    pub fn velocity(&self, t: f64) -> [f64; 3] {
        match self {
            Motion::Held { .. } => [0.0; 3],
            Motion::Ramp { d, duration } => {
                if *duration > 0.0 && t < *duration && t >= 0.0 {
                    [d[0] / duration, d[1] / duration, d[2] / duration]
                } else {
                    [0.0; 3]
                }
            }
            Motion::Table { times, values } => {
                let k = times.partition_point(|&x| x <= t);
                if k == 0 || k == times.len() {
                    [0.0; 3]
                } else {
                    let dt = times[k] - times[k - 1];
                    let (a, b) = (values[k - 1], values[k]);
                    [(b[0] - a[0]) / dt, (b[1] - a[1]) / dt, (b[2] - a[2]) / dt]
                }
            }
            Motion::Function { d, f } => {
                let s = f.rate(t);
                [d[0] * s, d[1] * s, d[2] * s]
            }
        }
    }
    /// Largest |g(t)| over all t (for energy scales).
    pub fn max_displacement(&self) -> f64 {
        let n = |d: &[f64; 3]| (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        match self {
            Motion::Held { d } | Motion::Ramp { d, .. } => n(d),
            Motion::Table { values, .. } => values.iter().map(n).fold(0.0, f64::max),
            Motion::Function { d, f } => n(d) * f.max_abs(),
        }
    }
    /// The time after which `g` is constant (s); infinite for a sine.
    pub fn end(&self) -> f64 {
        match self {
            Motion::Held { .. } => 0.0,
            Motion::Ramp { duration, .. } => *duration,
            Motion::Table { times, .. } => *times.last().unwrap_or(&0.0),
            Motion::Function { f, .. } => f.end(),
        }
    }
    /// The displacement of largest magnitude the motion reaches.
    pub fn extreme(&self) -> [f64; 3] {
        let n2 = |x: &[f64; 3]| x.iter().map(|v| v * v).sum::<f64>();
        match self {
            Motion::Held { d } | Motion::Ramp { d, .. } => *d,
            Motion::Table { values, .. } => values
                .iter()
                .copied()
                .max_by(|x, y| n2(x).total_cmp(&n2(y)))
                .unwrap_or([0.0; 3]),
            Motion::Function { d, f } => d.map(|x| x * f.max_abs()),
        }
    }
}
