//! The frame solver (`[multigrid] scheme = "newton"`): quasi-static frames by Newton steps
//! whose conjugate gradients are preconditioned by the Galerkin V-cycle of a tangent kept
//! across frames.
//!
//! An interactive frame asks for the static equilibrium `R(u) + S(u) = V` (free dofs; `S` the
//! springs) after a grasp moved a little, from the last frame's state, which was close to the
//! last equilibrium. One step ([`Stepper::advance`]) from `u`, with `g` the constrained dofs'
//! values now held ([`Stepper::hold_prescribed`], a grasp's [`RuntimeConstraints`]):
//!
//! ```text
//! Δ_C = g_C − u_C                                  (the constrained dofs' move, zero when held)
//! b_F = V_F − R_F(u) − S_F(u) − K_FC(u) Δ_C        (the move lifted to first order at u)
//! K(u) x = b_F   by at most `cg` conjugate-gradient iterations (2 `cg` where the frame
//!                changed the problem without a predicted start), preconditioned by one
//!                Galerkin V-cycle of the kept tangent K_k
//! u_F ← u_F + α x,  u_C ← g_C,   α = 1, halved while an element inverts (at most 8 times)
//! ```
//!
//! The products `K(u) p` are those of the tangent at the current state, by finite
//! differences of the forces, `(F(u + εp) − F(u)) / ε` with `F = R + S` (one force evaluation
//! each, the packed kernel's where the law has one; `εp`'s largest entry
//! [`FD_STEP`]`(max|u| + `[`FD_FLOOR`]`)`): the step is a Newton step, and the kept tangent
//! only preconditions it, so a tangent many frames old costs iterations, not accuracy.
//! (With [`NewtonFramesParams::current`] off the products are `K_k`'s own: a chord step.
//! Measured on the liver, the chord steps' lag grew as the grasp pulled, `bench/RESULTS.md`.)
//! `K_k = K(u_k) + Σ k I` is assembled at the state `u_k` of the last refresh
//! ([`DirectNewton::keep_tangent`]: the elements, the model's blocks beyond them, the springs),
//! and its V-cycle runs over level 0 and the coarser `[multigrid]` level the static solver
//! would take ([`crate::statics::newton::coarse_level`]); without one the fine level is
//! factored. The lift is the static solver's first iteration ([`crate::statics::newton`]):
//! the tangent's response to the prescribed move, so a grasp's move reaches the whole body
//! in the step that makes it, and the prescribed nodes never move alone (a patch moved ahead
//! of its neighbours inverts the elements at its edge). `K_FC Δ_C` is taken from the element
//! tangents at the current state of the elements touching a moved node. The frame
//! predictor ([`Stepper::predict`], [`crate::sim::frame`]) is the conjugate gradients' start
//! `x`, not a change of the state.
//!
//! The tangent is refreshed (assembled at the current state, the smoothed levels' Galerkin
//! operators formed again, the coarsest factor kept; the whole hierarchy rebuilt every
//! [`REBUILD_EVERY`] refreshes) before a step when
//! - the last step reduced the residual 2-norm by less than [`REFRESH_RATIO`] (`‖r_after‖ >
//!   REFRESH_RATIO ‖b‖`) and by less than the tangent's first step did
//!   ([`FRESH_FACTOR`]), the tangent having served [`MIN_AGE`] steps, and the residual is
//!   not converged ([`CONVERGED`]): the preconditioner has drifted from the tangent;
//! - a step was halved or its conjugate gradients met negative curvature (the tangent is
//!   then shifted, [`SIGMA_START`]);
//! - or [`NewtonFramesParams::max_age`] steps were made with it;
//! - or the springs changed the operator (a spring grasp taken or released).
//!
//! The operator's pattern is built once, for the stepper's own constraints. A grasp or pin
//! that changes which dofs are constrained holds them in it ([`DirectNewton::mask`]): their
//! rows and columns decoupled in the kept tangent, their prolongation rows zeroed, so that
//! the V-cycle's coarse operator is that of the other dofs, `P_Fᵀ K_FF P_F`, as a pattern
//! built for the new constraints would give; the whole hierarchy is formed again at the next
//! step on the kept patterns and symbolic factorisation (about 100 ms on the liver L0, the
//! grasp's first frame, against about 180 ms with a new pattern: `bench/RESULTS.md`). An
//! earlier variant that kept the old hierarchy's coarse level for the held problem was
//! measured and dropped (the first frames' lag 6 times larger).
//!
//! Each step evaluates the residual once at its end (kept for the next step: one force
//! evaluation a step, plus the tangent products over the moved nodes' elements counted by
//! their share of the elements). Work other than force evaluations (CG iterations, tangent
//! refreshes) is counted in [`Stepper::diagnostics`]. The state's velocities stay zero and
//! its time is the path time of the held values: frames are quasi-static. Every sum runs in a
//! fixed order: the same bits on any thread count for a fixed number of steps.

use super::newton::{DirectNewton, DirectNewtonError, Smoother};
use crate::error::{Divergence, DivergenceCause};
use crate::hierarchy::{Correspondence, Transfer};
use crate::integrate::{
    hold, Checkpoint, OwnConstraints, RuntimeConstraints, State, Stepper, System,
};
use crate::mesh::Mesh;

/// A step whose residual 2-norm falls by less than this factor of the step's right-hand side
/// has the tangent refreshed before the next step (module docs).
pub const REFRESH_RATIO: f64 = 0.5;

/// The ratio rule refreshes a tangent only after it served this many steps: a fresh one that
/// reduces the residual slowly is limited by the conjugate gradients, not by its age.
pub const MIN_AGE: usize = 3;

/// The ratio rule refreshes a tangent only where its step's ratio is this many times the
/// ratio of its first step: a ratio the fresh tangent had too is the conjugate gradients'
/// limit, which a refresh does not move.
pub const FRESH_FACTOR: f64 = 1.5;

/// Every this many refreshes the whole hierarchy is rebuilt, its coarsest factor included.
pub const REBUILD_EVERY: usize = 8;

/// A step whose residual 2-norm is below this share of the largest right-hand side since the
/// operator was built counts as converged: it does not refresh the tangent for its ratio.
pub const CONVERGED: f64 = 1e-4;

/// A frame's steps may stop once the residual 2-norm is below this share of the largest
/// right-hand side since the operator was built ([`Stepper::settled`]): far below what a
/// frame shows (`bench frames` measures lags of 1e-4 and less there).
pub const SETTLED: f64 = 1e-6;

/// The first shift of an indefinite kept tangent, relative to its mean diagonal; each
/// further truncated solve multiplies it by 10, each refresh divides it by 10.
pub const SIGMA_START: f64 = 1e-3;

/// The finite-difference step of a tangent product: the perturbation's largest entry is
/// `FD_STEP (max|u| + FD_FLOOR)` (m).
pub const FD_STEP: f64 = 1e-7;
/// See [`FD_STEP`] (m).
pub const FD_FLOOR: f64 = 1e-4;

/// Halvings of a step at most while an element inverts.
const HALVINGS: usize = 8;

/// Settings of [`NewtonFrames`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NewtonFramesParams {
    /// Conjugate-gradient iterations per step at most (twice as many in a step whose frame
    /// moved a constrained dof or a spring's anchor, without a predicted start). Default 2.
    pub cg: usize,
    /// Steps with one tangent at most before it is refreshed. Default 10.
    pub max_age: usize,
    /// The V-cycle's smoother.
    pub smoother: Smoother,
    /// Its sweeps before and after the coarse correction. Default 1.
    pub sweeps: usize,
    /// Products with the tangent at the current state (by finite differences of the forces)
    /// instead of the kept tangent's: a Newton step preconditioned by the kept V-cycle rather
    /// than a chord step. Default true.
    pub current: bool,
}

impl Default for NewtonFramesParams {
    fn default() -> Self {
        NewtonFramesParams {
            cg: 2,
            max_age: 10,
            smoother: Smoother::BlockJacobi,
            sweeps: 1,
            current: true,
        }
    }
}

/// The frame solver's stepper (module docs).
pub struct NewtonFrames {
    sys: System,
    state: State,
    /// Level 0's mesh and the coarse level's (the V-cycle's), where there is one.
    meshes: Vec<Mesh>,
    /// The link between level 0 and the coarse level (empty without one): its `down`
    /// transfer (level 0's nodes located in the coarse mesh) builds the V-cycle.
    links: Vec<Correspondence>,
    params: NewtonFramesParams,
    /// The operator's pattern for the stepper's own constraints (`base`), the run-time ones
    /// masked in it ([`DirectNewton::mask`]), and the kept tangent.
    newton: Option<DirectNewton>,
    /// The constraints the pattern is built for: the stepper's own, without run-time grasps
    /// and pins.
    base: crate::integrate::Constraints,
    /// Refresh the tangent before the next step.
    stale: bool,
    /// Steps with the kept tangent; refreshes since the last full rebuild.
    age: usize,
    since_rebuild: usize,
    /// `V − R(u) − S(u)` on free dofs at the current state (`valid`).
    r: Vec<f64>,
    valid: bool,
    /// Scratch: the targets, the lift, the right-hand side, the step, the state before it.
    target: Vec<f64>,
    lift: Vec<f64>,
    b: Vec<f64>,
    x: Vec<f64>,
    before: Vec<f64>,
    /// The springs' nodes the kept tangent was assembled with.
    spring_nodes: Vec<u32>,
    /// The elements with a constrained node.
    lift_elements: Vec<usize>,
    /// The predicted change of the next step ([`Stepper::predict`]): its CG start.
    guess: Option<Vec<f64>>,
    /// The residual ratio `‖r_after‖ / ‖b‖` of the first step with the kept tangent.
    fresh_ratio: f64,
    /// A spring's anchor moved since the last step ([`Stepper::set_runtime_constraints`]).
    anchors_moved: bool,
    /// The shift of the kept tangent's diagonal, relative to its mean (module docs).
    sigma: f64,
    /// The largest right-hand side 2-norm since the operator was built (N).
    scale: f64,
    /// The residual 2-norm at the end of the last step (N; infinite before one).
    last_residual: f64,
    steps: u64,
    evaluations: f64,
    cg_iterations: u64,
    refreshes: u64,
    halvings: u64,
    own: Option<OwnConstraints>,
}

impl NewtonFrames {
    /// The stepper of `sys` (level 0 on `mesh`) from rest, its V-cycle over `coarse` (the
    /// coarser mesh of the same body, `None`: the fine level factored).
    pub fn new(
        sys: System,
        mesh: Mesh,
        coarse: Option<Mesh>,
        params: NewtonFramesParams,
    ) -> crate::Result<Self> {
        let n = sys.num_nodes();
        let mut state = State::at_rest(n);
        sys.impose(0.0, &mut state.u, &mut state.v);
        let mut meshes = vec![mesh];
        let mut links = Vec::new();
        if let Some(c) = coarse {
            links.push(Correspondence::build(&meshes[0], &c)?);
            meshes.push(c);
        }
        let base = sys.constraints.clone();
        let mut s = NewtonFrames {
            base,
            sys,
            state,
            meshes,
            links,
            params,
            newton: None,
            stale: true,
            age: 0,
            since_rebuild: 0,
            r: vec![0.0; 3 * n],
            valid: false,
            target: vec![0.0; 3 * n],
            lift: vec![0.0; 3 * n],
            b: vec![0.0; 3 * n],
            x: vec![0.0; 3 * n],
            before: vec![0.0; 3 * n],
            spring_nodes: Vec::new(),
            lift_elements: Vec::new(),
            guess: None,
            anchors_moved: false,
            fresh_ratio: 0.0,
            sigma: 0.0,
            scale: 0.0,
            last_residual: f64::INFINITY,
            steps: 0,
            evaluations: 0.0,
            cg_iterations: 0,
            refreshes: 0,
            halvings: 0,
            own: None,
        };
        // The pattern and the first tangent now, not in the first frame.
        s.prepare()
            .and_then(|()| s.residual())
            .and_then(|()| s.refresh())
            .map_err(|d| crate::Error::param("[multigrid] scheme = \"newton\"", d.to_string()))?;
        Ok(s)
    }

    fn fail(&self, cause: DivergenceCause, element: Option<usize>) -> Divergence {
        Divergence {
            time: self.state.t,
            step: self.steps + 1,
            element,
            cause,
        }
    }

    fn solver_failure(&self, e: DirectNewtonError) -> Divergence {
        match e {
            DirectNewtonError::Inverted(f) => self.fail(
                DivergenceCause::Inverted { det_f: f.det_f },
                Some(f.element),
            ),
            e => self.fail(DivergenceCause::Solver(e.to_string()), None),
        }
    }

    /// The residual at the current state into `r`, once per state.
    fn residual(&mut self) -> Result<(), Divergence> {
        if !self.valid {
            self.sys.residual(&self.state.u, &mut self.r).map_err(|f| {
                self.fail(
                    DivergenceCause::Inverted { det_f: f.det_f },
                    Some(f.element),
                )
            })?;
            self.evaluations += 1.0;
            self.valid = true;
        }
        Ok(())
    }
}

fn norm(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum::<f64>().sqrt()
}

impl Stepper for NewtonFrames {
    fn advance(&mut self) -> Result<(), Divergence> {
        if self.newton.is_none() {
            self.prepare()?;
        }
        self.residual()?;
        if self.stale || self.age >= self.params.max_age {
            self.refresh()?;
        }
        // The constrained dofs' move Δ_C and its load −K_FC Δ_C on the free ones.
        let t = self.state.t;
        self.target.copy_from_slice(&self.state.u);
        let mut v = vec![0.0; self.target.len()];
        self.sys.impose(t, &mut self.target, &mut v);
        let mut moved = false;
        for ((l, &g), &u) in self.lift.iter_mut().zip(&self.target).zip(&self.state.u) {
            *l = g - u;
            moved |= *l != 0.0;
        }
        self.b.copy_from_slice(&self.r);
        if moved {
            self.lift_load().map_err(|f| {
                self.fail(
                    DivergenceCause::Inverted { det_f: f.det_f },
                    Some(f.element),
                )
            })?;
        }
        // The frame changed the problem: a constrained dof moved, or a spring's anchor.
        let changed = moved || std::mem::take(&mut self.anchors_moved);
        let warm = match self.guess.take() {
            Some(g) if changed => {
                self.x.copy_from_slice(&g);
                true
            }
            _ => false,
        };
        // A move met without a predicted start gets twice the iterations.
        let cg = if changed && !warm {
            2 * self.params.cg
        } else {
            self.params.cg
        };
        let solve = self.solve(warm, cg);
        self.cg_iterations += solve.iterations as u64;
        // u_F + α x, u_C = g_C; α halved while an element inverts.
        self.before.copy_from_slice(&self.state.u);
        let mut alpha = 1.0;
        let mut halvings = 0;
        loop {
            for i in 0..self.state.u.len() {
                self.state.u[i] = if !self.sys.constraints.is_constrained(i / 3) {
                    self.before[i] + alpha * self.x[i]
                } else {
                    self.target[i]
                };
            }
            match self.sys.residual(&self.state.u, &mut self.r) {
                Ok(_) => {
                    self.evaluations += 1.0;
                    break;
                }
                Err(f) => {
                    self.evaluations += 1.0;
                    if halvings == HALVINGS {
                        self.state.u.copy_from_slice(&self.before);
                        self.valid = false;
                        return Err(self.fail(
                            DivergenceCause::Inverted { det_f: f.det_f },
                            Some(f.element),
                        ));
                    }
                    halvings += 1;
                    alpha *= 0.5;
                }
            }
        }
        self.halvings += halvings as u64;
        self.valid = true;
        if let Some(i) = self.state.u.iter().position(|v| !v.is_finite()) {
            return Err(self.fail(
                DivergenceCause::NonFinite {
                    what: "displacement",
                    node: crate::error::NodeRef::index(i / 3),
                },
                None,
            ));
        }
        let (bn, rn) = (norm(&self.b), norm(&self.r));
        self.scale = self.scale.max(bn);
        self.last_residual = rn;
        if solve.truncated {
            // The kept tangent is not positive definite here: shift it.
            self.sigma = if self.sigma == 0.0 {
                SIGMA_START
            } else {
                10.0 * self.sigma
            };
            self.stale = true;
        } else {
            let ratio = if bn > 0.0 { rn / bn } else { 0.0 };
            if self.age == 0 {
                self.fresh_ratio = ratio;
            }
            if halvings > 0
                || (self.age + 1 >= MIN_AGE
                    && ratio > REFRESH_RATIO
                    && ratio > FRESH_FACTOR * self.fresh_ratio
                    && rn > CONVERGED * self.scale)
            {
                self.stale = true;
            }
        }
        self.age += 1;
        self.steps += 1;
        Ok(())
    }
    fn finest(&mut self) -> (&mut System, &State) {
        (&mut self.sys, &self.state)
    }
    fn steps(&self) -> u64 {
        self.steps
    }
    fn force_evaluations(&self) -> f64 {
        self.evaluations
    }
    fn dt(&self) -> f64 {
        0.0
    }
    fn describe(&self) -> String {
        let levels = match self.meshes.get(1) {
            Some(c) => format!(
                "Galerkin V-cycle over level 0 and a coarse level ({}/{} nodes)",
                self.meshes[0].num_nodes(),
                c.num_nodes()
            ),
            None => format!(
                "the Cholesky factor of level 0 ({} nodes)",
                self.meshes[0].num_nodes()
            ),
        };
        format!(
            "newton frames: Newton steps, at most {} CG iterations a step (tangent products by finite differences) preconditioned by the {levels} of a tangent kept across frames, {}+{} sweeps of {}",
            self.params.cg,
            self.params.sweeps,
            self.params.sweeps,
            self.params.smoother.describe()
        )
    }
    fn diagnostics(&self) -> Option<String> {
        Some(format!(
            "{} steps, {} CG iterations, {} tangent refreshes, {} step halvings",
            self.steps, self.cg_iterations, self.refreshes, self.halvings
        ))
    }
    fn diagnostics_label(&self) -> &'static str {
        "newton"
    }
    fn hold_prescribed(&mut self, values: &[[f64; 3]]) {
        hold(&mut self.sys.constraints, values);
    }
    fn state(&self) -> &State {
        &self.state
    }
    fn num_levels(&self) -> usize {
        self.meshes.len()
    }
    fn level_mesh(&self, level: usize) -> Option<&Mesh> {
        self.meshes.get(level)
    }
    fn level_links(&self) -> Option<&[Correspondence]> {
        (!self.links.is_empty()).then_some(&self.links[..])
    }
    /// Level 0 and the coarse level cut, the state carried (a new node starts with the
    /// displacement of the node it copies), the operator's pattern and hierarchy built again
    /// on the cut levels at the next step; the counters kept.
    fn cut(&mut self, cut: &crate::hierarchy::cut::HierarchyCut) -> crate::Result<()> {
        let Some(ch) = cut.levels.first() else {
            return Ok(());
        };
        crate::integrate::cut_level0(&mut self.sys, &mut self.state, &mut self.own, ch)?;
        self.base = self.sys.constraints.clone();
        self.meshes = cut.levels.iter().map(|l| l.mesh.clone()).collect();
        self.links = cut.links.clone();
        let n = 3 * self.sys.num_nodes();
        for v in [
            &mut self.r,
            &mut self.target,
            &mut self.lift,
            &mut self.b,
            &mut self.x,
            &mut self.before,
        ] {
            v.clear();
            v.resize(n, 0.0);
        }
        self.guess = None;
        self.valid = false;
        self.newton = None;
        self.spring_nodes.clear();
        Ok(())
    }
    /// The last step ended with the residual 2-norm within [`SETTLED`] of the largest
    /// right-hand side since the operator was built, and no change of the problem since.
    fn settled(&self) -> bool {
        self.valid
            && self.newton.is_some()
            && !self.anchors_moved
            && self.last_residual <= SETTLED * self.scale
    }
    fn set_runtime_constraints(&mut self, c: &RuntimeConstraints) {
        let n = self.sys.num_nodes();
        let mask = |sys: &System| -> Vec<bool> {
            (0..n).map(|a| sys.constraints.is_constrained(a)).collect()
        };
        let was = mask(&self.sys);
        let before = self.state.u.clone();
        let anchors: Vec<[f64; 3]> = self.sys.springs.iter().map(|s| s.d).collect();
        OwnConstraints::apply_runtime(&mut self.own, &mut self.sys, &mut self.state, c);
        let now = mask(&self.sys);
        // Nodes held before and now: their move is the next step's, lifted there; a node
        // newly held starts where it is held.
        for a in 0..n {
            if was[a] && now[a] {
                self.state.u[3 * a..3 * a + 3].copy_from_slice(&before[3 * a..3 * a + 3]);
            }
        }
        if now != was {
            // Another set of free dofs: held in the kept pattern (`DirectNewton::mask`), the
            // whole hierarchy built again at the next step; a new pattern where one the
            // pattern left out is free now.
            let masked = self
                .newton
                .as_mut()
                .is_some_and(|n| n.mask(&self.sys.constraints));
            if masked {
                self.lift_elements = Self::constrained_elements(&self.sys);
                self.stale = true;
                self.scale = 0.0;
                self.since_rebuild = 0;
            } else {
                self.newton = None;
            }
        }
        self.anchors_moved |= self.sys.springs.len() != anchors.len()
            || self
                .sys
                .springs
                .iter()
                .zip(&anchors)
                .any(|(s, a)| s.d != *a);
        let springs: Vec<u32> = self.sys.springs.iter().map(|s| s.node).collect();
        if springs != self.spring_nodes {
            self.stale = true;
        }
        self.valid = false;
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
        self.valid = false;
    }
    fn set_kinetic_limit(&mut self, _limit: f64) {}
    /// `R(u) + S(u)` at the current state, where the last step's residual was evaluated there
    /// and nothing changed since (a frame's observer then needs no force evaluation of its own).
    fn finest_forces(&self) -> Option<&[f64]> {
        self.valid.then(|| self.sys.last_forces())
    }
    /// The next step's conjugate gradients start from `du` (free dofs) where the step moves
    /// constrained dofs or springs' anchors: the solve's start, not a change of the state.
    fn predict(&mut self, du: &[f64]) -> bool {
        self.guess = Some(du.to_vec());
        true
    }
}

impl NewtonFrames {
    /// The step's linear solve `K x = b` (module docs): products with the tangent at the
    /// current state by finite differences of the forces, `K p ≈ (F(u + εp) − F(u)) / ε` (one
    /// force evaluation each, `F = R + S`; `F(u) = V − r` on the free rows), where
    /// [`NewtonFramesParams::products`] asks for them; the kept tangent's own otherwise, or
    /// for a product whose perturbed state inverts an element.
    fn solve(&mut self, warm: bool, cg: usize) -> super::newton::KeptSolve {
        let newton = self.newton.as_ref().expect("built before a solve");
        if !self.params.current {
            return newton
                .kept_solve::<std::convert::Infallible>(&self.b, &mut self.x, cg, warm, None)
                .unwrap_or_else(|never| match never {});
        }
        let n = self.state.u.len();
        let nf = newton.free_count();
        let umax = self.state.u.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let mut f0 = vec![0.0; nf];
        {
            let mut full = vec![0.0; n];
            for i in 0..n {
                full[i] = self.sys.f_ext[i] - self.r[i];
            }
            newton.free_values(&full, &mut f0);
        }
        let (sys, u) = (&mut self.sys, &self.state.u);
        let mut p_all = vec![0.0; n];
        let mut w = vec![0.0; n];
        let mut fw = vec![0.0; n];
        let mut fw_free = vec![0.0; nf];
        let mut evals = 0.0;
        let mut product = |p: &[f64], q: &mut [f64]| -> Result<(), std::convert::Infallible> {
            newton.all_values(p, &mut p_all);
            let pmax = p_all.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            if pmax == 0.0 {
                q.iter_mut().for_each(|v| *v = 0.0);
                return Ok(());
            }
            let eps = FD_STEP * (umax + FD_FLOOR) / pmax;
            for i in 0..n {
                w[i] = u[i] + eps * p_all[i];
            }
            evals += 1.0;
            match sys.internal_forces(&w, &mut fw) {
                Ok(()) => {
                    newton.free_values(&fw, &mut fw_free);
                    for ((q, a), b) in q.iter_mut().zip(&fw_free).zip(&f0) {
                        *q = (a - b) / eps;
                    }
                }
                Err(_) => newton.kept_product(p, q),
            }
            Ok(())
        };
        let solve = newton
            .kept_solve(&self.b, &mut self.x, cg, warm, Some(&mut product))
            .unwrap_or_else(|never| match never {});
        self.evaluations += evals;
        solve
    }

    /// `b −= K(u) Δ` over the elements touching a moved constrained dof (the lift, module
    /// docs), their element tangents at the current state; counted in force-evaluation units
    /// by their share of the elements.
    fn lift_load(&mut self) -> Result<(), crate::fem::ElementFailure> {
        let Some(topo) = self.sys.force.tangent_elements() else {
            return Ok(());
        };
        let d = 3 * topo.nodes_per_element;
        let mut ke = vec![0.0; d * d];
        let mut done = 0usize;
        for &e in &self.lift_elements {
            let el = topo.element(e);
            let dof = |q: usize| 3 * el[q / 3] as usize + q % 3;
            if !(0..d).any(|q| self.lift[dof(q)] != 0.0) {
                continue;
            }
            self.sys.force.element_tangent(e, &self.state.u, &mut ke)?;
            done += 1;
            for r in 0..d {
                let s: f64 = (0..d).map(|c| ke[r * d + c] * self.lift[dof(c)]).sum();
                self.b[dof(r)] -= s;
            }
        }
        self.sys.constraints.zero_constrained(&mut self.b);
        self.evaluations += done as f64 / topo.len().max(1) as f64;
        Ok(())
    }

    /// The elements with a constrained node (those a lift may touch).
    fn constrained_elements(sys: &System) -> Vec<usize> {
        let Some(topo) = sys.force.tangent_elements() else {
            return Vec::new();
        };
        (0..topo.len())
            .filter(|&e| {
                topo.element(e)
                    .iter()
                    .any(|&a| sys.constraints.is_constrained(a as usize))
            })
            .collect()
    }

    /// Assemble the tangent at the current state and keep it (module docs).
    fn refresh(&mut self) -> Result<(), Divergence> {
        let full = self.since_rebuild + 1 >= REBUILD_EVERY;
        let newton = self.newton.as_mut().expect("prepared before");
        let kept = newton.has_kept_tangent();
        let sigma = self.sigma;
        let r = newton.keep_tangent(
            &*self.sys.force,
            &self.sys.springs,
            &self.state.u,
            self.params.smoother,
            self.params.sweeps,
            full || !kept,
            sigma,
        );
        // A shift that served once is lowered for the next refresh.
        self.sigma = if self.sigma > SIGMA_START {
            self.sigma / 10.0
        } else {
            0.0
        };
        r.map_err(|e| self.solver_failure(e))?;
        self.since_rebuild = if full || !kept {
            0
        } else {
            self.since_rebuild + 1
        };
        self.refreshes += 1;
        self.age = 0;
        self.stale = false;
        self.spring_nodes = self.sys.springs.iter().map(|s| s.node).collect();
        Ok(())
    }

    /// The operator for the current constraints and its first tangent, at the current state.
    fn prepare(&mut self) -> Result<(), Divergence> {
        let down: Vec<Transfer> = self.links.iter().map(|l| l.down.clone()).collect();
        let mut newton =
            DirectNewton::with_levels(&*self.sys.force, &self.sys.mass, &self.base, &down)
                .map_err(|e| self.solver_failure(e))?;
        if !newton.mask(&self.sys.constraints) {
            // The stepper's own constraints no longer hold (a cut moved them): a pattern for
            // the current ones.
            self.base = self.sys.constraints.clone();
            newton = DirectNewton::with_levels(&*self.sys.force, &self.sys.mass, &self.base, &down)
                .map_err(|e| self.solver_failure(e))?;
        }
        self.newton = Some(newton);
        self.lift_elements = Self::constrained_elements(&self.sys);
        self.stale = true;
        self.scale = 0.0;
        self.since_rebuild = 0;
        Ok(())
    }
}
