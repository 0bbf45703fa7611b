//! Steppers: advance a simulation one time step (one integrator step on one level, or one
//! multigrid cycle) and stop with a [`Divergence`] naming the time, step, element and cause
//! instead of ever producing non-finite numbers.

use super::{Integrator, Method, State, System};
use crate::error::{Divergence, DivergenceCause};

/// Divergence detection and time step of a stepper.
#[derive(Clone, Debug, PartialEq)]
pub struct StepperParams {
    /// Time step Δ (s).
    pub dt: f64,
    /// Energy blow-up: stop when kinetic energy exceeds this (J). Default: infinite; the
    /// scenario sets it from [`energy_limit`].
    pub kinetic_limit: f64,
}

/// A kinetic-energy ceiling that no physical run reaches: `factor` times the work the loads
/// can do over the body's size (`Σ|V| L`) plus the strain energy of the prescribed
/// displacements applied alone, `e_prescribed`. Default factor 1e3.
pub fn energy_limit(f_ext: &[f64], size: f64, e_prescribed: f64, factor: f64) -> f64 {
    let work: f64 = f_ext
        .chunks_exact(3)
        .map(|f| (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt())
        .sum::<f64>()
        * size;
    factor * (work + e_prescribed).max(f64::MIN_POSITIVE)
}

/// Something that advances a simulation by one step of size `dt` and exposes its finest
/// level. Single-level integration and every multigrid cycle implement it.
pub trait Stepper: Send {
    /// Advance one step (one integrator step, or one V-cycle).
    fn advance(&mut self) -> Result<(), Divergence>;
    /// The finest level's system and state.
    fn finest(&mut self) -> (&mut System, &State);
    /// Steps taken so far.
    fn steps(&self) -> u64;
    /// Force evaluations so far, in units of one finest-level evaluation.
    fn force_evaluations(&self) -> f64;
    /// Time step (s).
    fn dt(&self) -> f64;
    /// A short description (method, levels).
    fn describe(&self) -> String;
    /// Setup report for the user (multigrid: levels and correspondences, with warnings).
    fn report(&self) -> String {
        String::new()
    }
    /// Hold the scenario's `k`-th prescribed node at `values[k]` (m) from now on, on every level
    /// the scheme carries it to (interactive mode: the grasp position sampled once per frame).
    fn hold_prescribed(&mut self, values: &[[f64; 3]]);
    /// Counters worth reporting after a run (multigrid: skipped or dropped corrections).
    fn diagnostics(&self) -> Option<String> {
        None
    }
}

/// Check a state for non-finite values and kinetic-energy blow-up.
pub fn check_state(
    sys: &System,
    s: &State,
    step: u64,
    kinetic_limit: f64,
) -> Result<(), Divergence> {
    for (what, x) in [("displacement", &s.u), ("velocity", &s.v)] {
        if let Some(i) = x.iter().position(|v| !v.is_finite()) {
            return Err(Divergence {
                time: s.t,
                step,
                element: None,
                cause: DivergenceCause::NonFinite { what, node: i / 3 },
            });
        }
    }
    let ke = sys.kinetic_energy(&s.v);
    if ke > kinetic_limit {
        return Err(Divergence {
            time: s.t,
            step,
            element: None,
            cause: DivergenceCause::EnergyBlowUp {
                kinetic: ke,
                limit: kinetic_limit,
            },
        });
    }
    Ok(())
}

/// Set prescribed motion `k` of `c` to `Held { values[k] }` (extra values are ignored).
pub fn hold(c: &mut super::Constraints, values: &[[f64; 3]]) {
    for ((_, m), &d) in c.prescribed.iter_mut().zip(values) {
        *m = super::Motion::Held { d };
    }
}

/// Single-level integration (SLIM): one integrator step per time step on one mesh.
pub struct SingleLevel {
    pub sys: System,
    pub state: State,
    pub integrator: Box<dyn Integrator>,
    pub params: StepperParams,
    steps: u64,
}

impl SingleLevel {
    pub fn new(sys: System, method: Method, params: StepperParams) -> Self {
        let n = sys.num_nodes();
        let mut state = State::at_rest(n);
        sys.impose(0.0, &mut state.u, &mut state.v);
        SingleLevel {
            sys,
            state,
            integrator: method.build(n),
            params,
            steps: 0,
        }
    }
}

impl Stepper for SingleLevel {
    fn hold_prescribed(&mut self, values: &[[f64; 3]]) {
        hold(&mut self.sys.constraints, values);
    }
    fn advance(&mut self) -> Result<(), Divergence> {
        let t = self.state.t;
        self.integrator
            .step(&mut self.sys, &mut self.state, self.params.dt)
            .map_err(|f| Divergence {
                time: t,
                step: self.steps + 1,
                element: Some(f.element),
                cause: DivergenceCause::Inverted { det_f: f.det_f },
            })?;
        self.steps += 1;
        check_state(
            &self.sys,
            &self.state,
            self.steps,
            self.params.kinetic_limit,
        )
    }
    fn finest(&mut self) -> (&mut System, &State) {
        (&mut self.sys, &self.state)
    }
    fn steps(&self) -> u64 {
        self.steps
    }
    fn force_evaluations(&self) -> f64 {
        (self.steps * self.integrator.method().evaluations()) as f64
    }
    fn dt(&self) -> f64 {
        self.params.dt
    }
    fn describe(&self) -> String {
        format!(
            "single level, {}, dt = {:.4e} s",
            self.integrator.method().name(),
            self.params.dt
        )
    }
}

/// [`energy_limit`] for a system on `mesh`: the prescribed motions' strain energy is that of
/// every prescribed node at its largest displacement, all other nodes at rest.
pub fn energy_limit_for(sys: &System, mesh: &crate::mesh::Mesh, factor: f64) -> f64 {
    let n = sys.num_nodes();
    let mut u = vec![0.0; 3 * n];
    for (a, m) in &sys.constraints.prescribed {
        let d = match m {
            super::Motion::Held { d } | super::Motion::Ramp { d, .. } => *d,
            super::Motion::Table { values, .. } => values
                .iter()
                .copied()
                .max_by(|x, y| {
                    x.iter()
                        .map(|v| v * v)
                        .sum::<f64>()
                        .total_cmp(&y.iter().map(|v| v * v).sum::<f64>())
                })
                .unwrap_or([0.0; 3]),
        };
        u[3 * *a as usize..3 * *a as usize + 3].copy_from_slice(&d);
    }
    let e_presc = sys.force.strain_energy(&u);
    let e_presc = if e_presc.is_finite() { e_presc } else { 0.0 };
    let (lo, hi) = mesh.bounding_box();
    let size = crate::mesh::norm(crate::mesh::sub(hi, lo));
    energy_limit(&sys.f_ext, size, e_presc, factor)
}
