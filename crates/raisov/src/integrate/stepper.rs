//! Steppers: advance a simulation one time step (one integrator step on one level, or one
//! multigrid cycle) and stop with a [`Divergence`] naming the time, step, element and cause
//! instead of ever producing non-finite numbers.

use super::{Constraints, Integrator, Method, State, System};
use crate::error::{Divergence, DivergenceCause, NodeRef};

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

/// RaISoV's switch counts ([`crate::multigrid::raisov`], eqs. 10 and 12): node transfers
/// that passed the coarser (down stroke) or finer (up stroke) level's state because the
/// transferred displacement change exceeded ε, and those that passed a variation (`≤ ε`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SwitchCounts {
    /// Down-stroke transfers that passed the state (eq. 10, `|ΔX| > ε`).
    pub down_state: u64,
    /// Down-stroke transfers that passed a variation (`|ΔX| ≤ ε`).
    pub down_variation: u64,
    /// Up-stroke transfers that passed the state (eq. 12, `|ΔX| > ε`).
    pub up_state: u64,
    /// Up-stroke transfers that passed a variation (`|ΔX| ≤ ε`).
    pub up_variation: u64,
}

impl SwitchCounts {
    /// The fraction of all node transfers that passed the state (`|ΔX_u| > ε`); `None`
    /// before any transfer.
    pub fn state_fraction(&self) -> Option<f64> {
        let states = self.down_state + self.up_state;
        let all = states + self.down_variation + self.up_variation;
        (all > 0).then(|| states as f64 / all as f64)
    }
    /// The same fraction in the down stroke alone (eq. 10).
    pub fn down_state_fraction(&self) -> Option<f64> {
        let all = self.down_state + self.down_variation;
        (all > 0).then(|| self.down_state as f64 / all as f64)
    }
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
    /// The run summary's label of [`Stepper::diagnostics`]: what the counters count
    /// (`"multigrid"`, `"newton"`).
    fn diagnostics_label(&self) -> &'static str {
        "multigrid"
    }
    /// RaISoV's transfer switches (eqs. 10 and 12) summed over the steps so far; `None` for
    /// schemes without them.
    fn switch_counts(&self) -> Option<SwitchCounts> {
        None
    }
    /// The finest level's state (displacements, velocities, time), read-only.
    fn state(&self) -> &State;
    /// Number of levels (1 for single-level integration).
    fn num_levels(&self) -> usize {
        1
    }
    /// The mesh of `level` where the stepper keeps one (every level of a multigrid; `None`
    /// for single-level integration, whose caller has the mesh).
    fn level_mesh(&self, _level: usize) -> Option<&crate::mesh::Mesh> {
        None
    }
    /// Replace the run-time constraints (grasps and pins added while running) by `c`, on top
    /// of the stepper's own (the scenario's, which keep their motions). Nodes already
    /// constrained keep their own constraint. See [`RuntimeConstraints`] for how each scheme
    /// carries them to its levels.
    fn set_runtime_constraints(&mut self, c: &RuntimeConstraints);
    /// Save everything [`Stepper::advance`] reads and writes across steps into `cp` (its
    /// buffers are reused), so that [`Stepper::restore`] can undo the steps since.
    fn save(&self, cp: &mut Checkpoint);
    /// Return to the state [`Stepper::save`] saved into `cp` (constraints are not part of it).
    fn restore(&mut self, cp: &Checkpoint);
    /// Replace the kinetic-energy ceiling of divergence detection (J; infinite: none).
    fn set_kinetic_limit(&mut self, limit: f64);
    /// Add `du` (3 per level-0 node) to level 0's displacements at its free dofs, as the
    /// start of the next steps (a predictor, [`crate::sim::Simulation::set_predictor`]);
    /// `false`, and nothing changed, where the stepper's state is not a displacement
    /// field alone (dynamics, whose velocities would not match). The default: `false`.
    fn predict(&mut self, du: &[f64]) -> bool {
        let _ = du;
        false
    }
    /// The finest level's `R(u) + Σ_springs k (u_a − d)` (N, 3 per node, every row, as
    /// [`System::internal_forces`] gives it) at the current state, when the last step ended by
    /// evaluating it there; `None` when it did not (the default) or the system has changed
    /// since. A caller that needs the forces at the end of a step takes them from here instead
    /// of evaluating them again.
    fn finest_forces(&self) -> Option<&[f64]> {
        None
    }
    /// Whether the last step left the state at its equilibrium to the stepper's own
    /// tolerance, with nothing changed since, so that more steps in this frame would not move
    /// it: a [`crate::sim::Budget::Millis`] frame then stops early. `false` (the default)
    /// for steppers that do not measure it: they spend the whole budget.
    fn settled(&self) -> bool {
        false
    }
    /// The links between the levels (`[i]`: levels `i` and `i + 1`), for a stepper of several
    /// levels; `None` (the default) for one level.
    fn level_links(&self) -> Option<&[crate::hierarchy::Correspondence]> {
        None
    }
    /// Cut the body ([`crate::mesh::cut`], [`crate::hierarchy::cut`]): every level's system
    /// and state carried to its cut mesh (`cut.levels[l]`: each new node starts with the
    /// displacement and velocity of the node it copies), the links replaced by `cut.links`.
    /// Run-time constraints are dropped: the caller sets them again on the new nodes. The
    /// default refuses, naming the stepper.
    fn cut(&mut self, cut: &crate::hierarchy::cut::HierarchyCut) -> crate::Result<()> {
        let _ = cut;
        Err(crate::Error::param(
            "cut",
            format!(
                "{} cannot cut the body: cutting runs on the explicit and implicit integrators, the multigrid cycles (FAS, RaISoV) and the frame solver",
                self.describe()
            ),
        ))
    }
}

/// Constraints added at run time on top of a stepper's own ([`Stepper::set_runtime_constraints`]).
///
/// - `held`: level-0 nodes held at the given displacements (m), a grasp: prescribed points,
///   carried to coarser levels as the scheme carries prescribed points (RaISoV: to the nearest
///   node of each coarser level, held at the same displacement; FAS: not at all, a grasp is a
///   fine-level feature, see [`crate::multigrid::fas`]);
/// - `pinned[l]`: nodes of level `l` (0 the finest; levels past the end have none) held where
///   they stand when the constraints are set, like fixed regions: on every level the caller
///   names nodes for (FAS holds coarse ones at the restricted state, as its fixed regions);
/// - `springs[l]`: zero-length springs on level `l`'s nodes (spring grasps), which replace the
///   level's [`System::springs`] (levels past the end have none). They are forces, not
///   constraints: the nodes stay free.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RuntimeConstraints {
    /// Level-0 nodes and their held displacements (m).
    pub held: Vec<(u32, [f64; 3])>,
    /// Per level, nodes held where they stand.
    pub pinned: Vec<Vec<u32>>,
    /// Per level, springs from nodes to anchors.
    pub springs: Vec<Vec<super::Spring>>,
}

impl RuntimeConstraints {
    /// Level `l`'s springs (none past the end).
    pub fn springs_of(&self, l: usize) -> &[super::Spring] {
        self.springs.get(l).map_or(&[][..], |s| &s[..])
    }
}

/// A stepper's saved state ([`Stepper::save`], [`Stepper::restore`]): vectors and numbers in
/// the order the stepper writes them; the buffers are reused from one save to the next.
#[derive(Clone, Debug, Default)]
pub struct Checkpoint {
    vectors: Vec<Vec<f64>>,
    numbers: Vec<f64>,
    counts: Vec<u64>,
}

/// Writes into a [`Checkpoint`] in order.
pub(crate) struct CheckpointWriter<'a> {
    cp: &'a mut Checkpoint,
    v: usize,
}

impl Checkpoint {
    pub(crate) fn writer(&mut self) -> CheckpointWriter<'_> {
        self.numbers.clear();
        self.counts.clear();
        CheckpointWriter { cp: self, v: 0 }
    }
    pub(crate) fn reader(&self) -> CheckpointReader<'_> {
        CheckpointReader {
            cp: self,
            v: 0,
            n: 0,
            c: 0,
        }
    }
}

impl CheckpointWriter<'_> {
    pub(crate) fn vector(&mut self, x: &[f64]) {
        if self.cp.vectors.len() == self.v {
            self.cp.vectors.push(Vec::new());
        }
        let b = &mut self.cp.vectors[self.v];
        b.clear();
        b.extend_from_slice(x);
        self.v += 1;
    }
    pub(crate) fn number(&mut self, x: f64) {
        self.cp.numbers.push(x);
    }
    pub(crate) fn count(&mut self, x: u64) {
        self.cp.counts.push(x);
    }
    pub(crate) fn state(&mut self, s: &State) {
        self.vector(&s.u);
        self.vector(&s.v);
        self.number(s.t);
    }
    /// The path-dependent state of `sys`'s force model ([`crate::fem::ForceModel::save_history`]).
    pub(crate) fn history(&mut self, sys: &super::System) {
        let mut h = Vec::new();
        sys.force.save_history(&mut h);
        self.vector(&h);
    }
}

/// Reads a [`Checkpoint`] in the order it was written.
pub(crate) struct CheckpointReader<'a> {
    cp: &'a Checkpoint,
    v: usize,
    n: usize,
    c: usize,
}

impl CheckpointReader<'_> {
    pub(crate) fn vector(&mut self, x: &mut [f64]) {
        x.copy_from_slice(&self.cp.vectors[self.v]);
        self.v += 1;
    }
    pub(crate) fn number(&mut self) -> f64 {
        self.n += 1;
        self.cp.numbers[self.n - 1]
    }
    pub(crate) fn count(&mut self) -> u64 {
        self.c += 1;
        self.cp.counts[self.c - 1]
    }
    pub(crate) fn state(&mut self, s: &mut State) {
        self.vector(&mut s.u);
        self.vector(&mut s.v);
        s.t = self.number();
    }
    /// Restore what [`CheckpointWriter::history`] wrote into `sys`'s force model.
    pub(crate) fn history(&mut self, sys: &mut super::System) {
        sys.force.load_history(&self.cp.vectors[self.v]);
        self.v += 1;
    }
}

/// A level's own constraints, remembered when run-time ones are first added, so that each
/// [`Stepper::set_runtime_constraints`] rebuilds the level's [`Constraints`] from them.
#[derive(Clone, Debug)]
pub(crate) struct OwnConstraints {
    fixed: Vec<u32>,
    sliding: Vec<(u32, [f64; 3])>,
    /// The first `prescribed` entries of the level's prescribed list are its own (their
    /// motions as they stand: [`Stepper::hold_prescribed`] may have changed them).
    prescribed: usize,
}

impl OwnConstraints {
    /// [`Stepper::set_runtime_constraints`] of a single-level stepper: `sys`'s constraints
    /// rebuilt from its own ones (remembered in `own` at the first call) and `c`'s grasps and
    /// pins, level 0's springs of `c`, and the constrained values imposed on `state`.
    pub(crate) fn apply_runtime(
        own: &mut Option<OwnConstraints>,
        sys: &mut System,
        state: &mut State,
        c: &RuntimeConstraints,
    ) {
        let own = own.get_or_insert_with(|| OwnConstraints::of(&sys.constraints));
        let pinned = c.pinned.first().map_or(&[][..], |p| &p[..]);
        let n = sys.num_nodes();
        own.apply(&mut sys.constraints, &c.held, pinned, &state.u, n);
        sys.springs = c.springs_of(0).to_vec();
        let t = state.t;
        sys.impose(t, &mut state.u, &mut state.v);
    }

    pub(crate) fn of(c: &Constraints) -> Self {
        OwnConstraints {
            fixed: c.fixed.clone(),
            sliding: c.sliding().to_vec(),
            prescribed: c.prescribed.len(),
        }
    }
    /// `c` rebuilt for `n` nodes: the own fixed and prescribed nodes, then `held` at their
    /// displacements and `pinned` held at their displacement in `u` (3 per node), each node
    /// skipped where it is constrained already.
    pub(crate) fn apply(
        &self,
        c: &mut Constraints,
        held: &[(u32, [f64; 3])],
        pinned: &[u32],
        u: &[f64],
        n: usize,
    ) {
        let mut taken = vec![false; n];
        for &a in &self.fixed {
            taken[a as usize] = true;
        }
        let mut prescribed: Vec<(u32, super::Motion)> = c.prescribed[..self.prescribed].to_vec();
        for (a, _) in &prescribed {
            taken[*a as usize] = true;
        }
        for &(a, d) in held {
            if (a as usize) < n && !std::mem::replace(&mut taken[a as usize], true) {
                prescribed.push((a, super::Motion::Held { d }));
            }
        }
        for &a in pinned {
            let i = a as usize;
            if i < n && !std::mem::replace(&mut taken[i], true) {
                let d = [u[3 * i], u[3 * i + 1], u[3 * i + 2]];
                prescribed.push((a, super::Motion::Held { d }));
            }
        }
        *c = Constraints::new(self.fixed.clone(), prescribed)
            .with_sliding(&self.sliding)
            .with_nodes(n);
    }
}

/// Check a state for non-finite values and kinetic-energy blow-up; a blow-up names the node
/// of the largest kinetic energy `½ m_a |v_a|²` and its speed.
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
                cause: DivergenceCause::NonFinite {
                    what,
                    node: NodeRef::index(i / 3),
                },
            });
        }
    }
    let ke = sys.kinetic_energy(&s.v);
    if ke > kinetic_limit {
        let speed2 = |a: usize| s.v[3 * a..3 * a + 3].iter().map(|x| x * x).sum::<f64>();
        let node = (0..sys.mass.len())
            .max_by(|&a, &b| (sys.mass[a] * speed2(a)).total_cmp(&(sys.mass[b] * speed2(b))))
            .unwrap_or(0);
        return Err(Divergence {
            time: s.t,
            step,
            element: None,
            cause: DivergenceCause::EnergyBlowUp {
                kinetic: ke,
                limit: kinetic_limit,
                node: NodeRef::index(node),
                speed: speed2(node).sqrt(),
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
    /// The mesh's system.
    pub sys: System,
    /// Its state.
    pub state: State,
    /// The explicit integrator.
    pub integrator: Box<dyn Integrator>,
    /// Time step and divergence detection.
    pub params: StepperParams,
    steps: u64,
    /// The system's own constraints once run-time ones were added.
    own: Option<OwnConstraints>,
}

impl SingleLevel {
    /// A stepper of `sys` by `method` at `params.dt`, from rest.
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
            own: None,
        }
    }
}

/// Level 0 of a stepper carried through a cut ([`Stepper::cut`]): its run-time constraints
/// dropped (the caller sets them again on the new nodes) and its own forgotten, its system cut
/// ([`System::cut`]), its state carried (each new node starts with the displacement and
/// velocity of the node it copies). The steppers' cuts share it; each then rebuilds its own.
pub(crate) fn cut_level0(
    sys: &mut System,
    state: &mut State,
    own: &mut Option<OwnConstraints>,
    ch: &crate::mesh::cut::TopologyChange,
) -> crate::Result<()> {
    OwnConstraints::apply_runtime(own, sys, state, &RuntimeConstraints::default());
    *own = None;
    sys.cut(ch)?;
    state.u = ch.carry(&state.u, 3);
    state.v = ch.carry(&state.v, 3);
    Ok(())
}

impl Stepper for SingleLevel {
    fn state(&self) -> &State {
        &self.state
    }
    fn cut(&mut self, cut: &crate::hierarchy::cut::HierarchyCut) -> crate::Result<()> {
        let Some(ch) = cut.levels.first() else {
            return Ok(());
        };
        cut_level0(&mut self.sys, &mut self.state, &mut self.own, ch)?;
        self.integrator = self.integrator.method().build(ch.mesh.num_nodes());
        Ok(())
    }
    fn set_runtime_constraints(&mut self, c: &RuntimeConstraints) {
        OwnConstraints::apply_runtime(&mut self.own, &mut self.sys, &mut self.state, c);
    }
    fn set_kinetic_limit(&mut self, limit: f64) {
        self.params.kinetic_limit = limit;
    }
    fn save(&self, cp: &mut Checkpoint) {
        let mut w = cp.writer();
        w.state(&self.state);
        w.history(&self.sys);
        w.count(self.steps);
    }
    fn restore(&mut self, cp: &Checkpoint) {
        let mut r = cp.reader();
        r.state(&mut self.state);
        r.history(&mut self.sys);
        self.steps = r.count();
    }
    fn hold_prescribed(&mut self, values: &[[f64; 3]]) {
        hold(&mut self.sys.constraints, values);
    }
    /// One step of the integrator; a rate-dependent law's forces take its history as last
    /// accepted (`Δt = 0`) and the step's end is accepted over `dt`
    /// ([`crate::fem::ForceModel::accept_step`]).
    fn advance(&mut self) -> Result<(), Divergence> {
        let t = self.state.t;
        self.sys.force.set_step(0.0);
        self.integrator
            .step(&mut self.sys, &mut self.state, self.params.dt)
            .map_err(|f| Divergence {
                time: t,
                step: self.steps + 1,
                element: Some(f.element),
                cause: DivergenceCause::Inverted { det_f: f.det_f },
            })?;
        let _ = self.sys.force.accept_step(&self.state.u, self.params.dt);
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
/// every prescribed node at its largest displacement, all other nodes at rest. The limit is
/// never below `factor` times the strain energy of the body stretched uniformly by 0.1 %
/// (`u = 10⁻³ (x − x̄)`): without loads or motions the limit is not zero, and round-off
/// kinetic energy (1e-35 J) is not taken for a blow-up.
pub fn energy_limit_for(sys: &System, mesh: &crate::mesh::Mesh, factor: f64) -> f64 {
    let floor = {
        let n = mesh.nodes.len().max(1) as f64;
        let mut c = [0.0; 3];
        for p in &mesh.nodes {
            for k in 0..3 {
                c[k] += p[k] / n;
            }
        }
        let u: Vec<f64> = mesh
            .nodes
            .iter()
            .flat_map(|p| [0, 1, 2].map(|k| 1e-3 * (p[k] - c[k])))
            .collect();
        let e = sys.force.strain_energy(&u);
        if e.is_finite() {
            factor * e
        } else {
            0.0
        }
    };
    energy_limit_without_floor(sys, mesh, factor).max(floor)
}

fn energy_limit_without_floor(sys: &System, mesh: &crate::mesh::Mesh, factor: f64) -> f64 {
    let n = sys.num_nodes();
    let mut u = vec![0.0; 3 * n];
    for (a, m) in &sys.constraints.prescribed {
        let d = m.extreme();
        u[3 * *a as usize..3 * *a as usize + 3].copy_from_slice(&d);
    }
    let e_presc = sys.force.strain_energy(&u);
    let e_presc = if e_presc.is_finite() { e_presc } else { 0.0 };
    let (lo, hi) = mesh.bounding_box();
    let size = crate::mesh::norm(crate::mesh::sub(hi, lo));
    energy_limit(&sys.f_ext, size, e_presc, factor)
}

/// The frame predictor's start ([`crate::sim::frame`]): `s Δu` with
///
/// ```text
/// s = min( max(0, Σ_j g_j·g'_j / Σ_j |g'_j|²), 2, m / max_a |Δu_a| ),
/// ```
///
/// `Δu` the last frame's change of the displacements (3 per node), `g_j` and `g'_j` the move of
/// path point `j` (a grasp, a prescribed node) over this frame and over the last, `m` the
/// largest `|g_j|`: the last change scaled by how much of the last move this frame repeats (a
/// steady pull 1, a reversed or turned one 0), no node further than the path moves. `None`
/// (nothing to predict: the stepper is left alone) where `s` would be 0, or where the two
/// frames' moves do not pair up.
pub fn prediction(delta: &[f64], moves: &[[f64; 3]], last_moves: &[[f64; 3]]) -> Option<Vec<f64>> {
    if moves.len() != last_moves.len() {
        return None;
    }
    let dot = |a: &[f64; 3], b: &[f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let along: f64 = moves.iter().zip(last_moves).map(|(a, b)| dot(a, b)).sum();
    let last: f64 = last_moves.iter().map(|b| dot(b, b)).sum();
    let m = moves.iter().map(|a| dot(a, a).sqrt()).fold(0.0, f64::max);
    let largest = delta
        .chunks_exact(3)
        .map(|d| (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt())
        .fold(0.0, f64::max);
    if !(last > 0.0 && largest > 0.0 && m > 0.0 && along > 0.0) {
        return None;
    }
    let s = (along / last).min(2.0).min(m / largest);
    Some(delta.iter().map(|d| s * d).collect())
}

/// Each path point's move from `from` to `to` (m).
pub fn moves(from: &[[f64; 3]], to: &[[f64; 3]]) -> Vec<[f64; 3]> {
    from.iter()
        .zip(to)
        .map(|(a, b)| [b[0] - a[0], b[1] - a[1], b[2] - a[2]])
        .collect()
}
