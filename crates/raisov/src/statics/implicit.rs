//! Backward (implicit) Euler and BDF2 time stepping of
//!
//! ```text
//! M ü + D u̇ + R(u) = V(t)        (M lumped, m_a per node; Rayleigh damping D = α M + β K)
//! ```
//!
//! (β K below, "Stiffness-proportional damping"; until then β = 0.)
//!
//! one step of size h from `(u_n, v_n)` at `t_n` to `t_{n+1} = t_n + h`:
//!
//! ```text
//! v_{n+1} = (u_{n+1} − u_n) / h,
//! M (v_{n+1} − v_n) / h + α M v_{n+1} + R(u_{n+1}) = V(t_{n+1})     on free dofs.
//! ```
//!
//! Substituting `v_{n+1}`, the step is a static solve with one extra zero-length spring per
//! node: `u_{n+1}` is a stationary point (a minimiser, where the step is small enough for the
//! tangent to stay positive definite) of the incremental potential
//!
//! ```text
//! Φ(u) = Σ_a ½ k_a |u_a − d_a|² + W(u) − V(t_{n+1})·u,
//! k_a = m_a (1/h² + α/h),   d_a = u_{n,a} + h v_{n,a} / (1 + α h),
//! ```
//!
//! whose gradient `k_a (u_a − d_a) + R_a(u) − V_a` is the step's residual, since
//! `k_a (u_a − d_a) = m_a [(v_{n+1} − v_n)/h + α v_{n+1}]`. Its tangent is `K(u) + diag(k_a)`
//! (free dofs): the inertia adds at least `m_a/h²` to every diagonal, so it is positive definite
//! wherever K's negative curvature (compression, buckling) stays below that, which a small
//! enough step always gives; where it does not, the solver's regularisation and line search
//! apply as in a static solve.
//!
//! Each step is solved by [`DirectNewton`] (the assembled analytic tangent, its line search on
//! Φ, the regularisation, and either sparse Cholesky reused as the CG preconditioner or CG
//! preconditioned by the Galerkin V-cycle over coarser levels, [`ImplicitParams::multigrid`]),
//! the inertia springs passed as [`Spring`]s together with the system's own run-time springs
//! ([`System::springs`]). The solver is kept from step to step, and so is its factorisation or
//! hierarchy (it preconditions the next step's systems until it stops being good enough).
//!
//! - Start: `u = d` (the last solution plus `h v_n / (1 + α h)`, the minimiser of the inertia
//!   term alone), the constrained dofs at `u_n + h v_n`; the solver's first (lifted) iteration
//!   moves them to their values at `t_{n+1}`.
//! - Stopping rule (the static solver's, [`crate::statics::newton`], its scale the run's
//!   peak): `max_a |r_a| ≤ rel_tol F_n + abs_tol` over free nodes, with
//!   `F_n = max_{k ≤ n} (max_a |V_a| + max_a |r⁰_{k,a}|)`, `r⁰_k` the residual at step k's start
//!   (constrained dofs at their values at `t_{k+1}`). At the start `u = d` that is the
//!   out-of-balance force `V − R(d)`, `M` times the acceleration the step must produce: the
//!   largest over the run so far, so that a motion dying out (a free vibration damped by the
//!   scheme, whose own `r⁰` tends to 0) is not asked for ever smaller residuals than the
//!   forces of the run can resolve. Default `rel_tol` 1e-6 ([`DEFAULT_REL_TOL`]), `abs_tol`
//!   1e-12 N. Within 100 times that threshold the line search accepts a step on the
//!   residual's decrease alone ([`DirectNewtonParams::flat_below`]): Φ's round-off can exceed
//!   the changes a Newton step makes there.
//! - A step that does not meet the rule within [`ImplicitParams::max_newton`] iterations, or
//!   whose solver fails (an element inverted at a state it had to evaluate, a factorisation that
//!   fails even regularised), stops with a [`Divergence`] and leaves the state at the last step.
//! - Velocities: `v_{n+1} = (u_{n+1} − u_n)/h` on free dofs; constrained dofs get `u = g`,
//!   `u̇ = ġ` at `t_{n+1}` ([`System::impose`]).
//! - A rate-dependent law ([`crate::material::NeoHookeanVisco`]): the step's evaluations
//!   advance its internal variables over `h` to the trial configuration (its stress and
//!   algorithmic tangent, [`crate::fem::ForceModel::set_step`]); the converged `u_{n+1}` is
//!   accepted ([`crate::fem::ForceModel::accept_step`]), a failed step is not; between steps
//!   the evaluations take the history as accepted (`Δt = 0`).
//!
//! Energy: with `α = 0` and `V` constant, multiplying the step's equation by `u_{n+1} − u_n`
//! gives `T_{n+1} − T_n + ½ |v_{n+1} − v_n|²_M = −R(u_{n+1})·(u_{n+1} − u_n) + V·(u_{n+1} − u_n)`,
//! and where W is convex along the step `R(u_{n+1})·(u_{n+1} − u_n) ≥ W(u_{n+1}) − W(u_n)`: the
//! discrete energy `T + W − V·u` does not increase (it loses at least `½|Δv|²_M` a step): the
//! scheme is dissipative, and stable at any step. It is first-order accurate: at small steps
//! its trajectory converges to the exact one (the explicit integrators' at their small stable
//! steps) with an error proportional to h.
//!
//! BDF2 ([`ImplicitScheme::Bdf2`], `method = "bdf2"`), at a constant step h:
//!
//! ```text
//! v_{n+1} = (3 u_{n+1} − 4 u_n + u_{n−1}) / (2h),
//! M (3 v_{n+1} − 4 v_n + v_{n−1}) / (2h) + α M v_{n+1} + R(u_{n+1}) = V(t_{n+1}).
//! ```
//!
//! With `h_e = 2h/3`, the base `x* = (4 u_n − u_{n−1})/3` and `v* = (4 v_n − v_{n−1})/3`:
//! `v_{n+1} = (u_{n+1} − x*)/h_e` and the acceleration is `(v_{n+1} − v*)/h_e`, so the step is
//! backward Euler's with `(u_n, v_n, h)` replaced by `(x*, v*, h_e)`: the same incremental
//! potential with
//!
//! ```text
//! k_a = m_a (1/h_e² + α/h_e),   d_a = x*_a + h_e v*_a / (1 + α h_e)
//! ```
//!
//! (without damping `d = x̂ = (4/3) u_n − (1/3) u_{n−1} + (2h/3)((4/3) v_n − (1/3) v_{n−1})`,
//! `u_{n+1} = x̂ + (4h²/9) M⁻¹ (V − R(u_{n+1}))`), the same solver, stopping rule and
//! start. The first step, and the first after the constrained nodes change (a grasp taken or
//! let go, a pin: the solver's pattern is rebuilt), is a backward-Euler step: the two-step
//! formula needs the state one step of h before. The step is the one of
//! [`ImplicitParams::dt`] for the whole run (no step change is offered). The state one step
//! before is part of [`Stepper::save`]. BDF2 is second-order accurate and A-stable (on a
//! linear problem a quadratic form of two consecutive states, its G-norm, never grows; the
//! energy `T + W − V·u` of one state can rise a little from a step to the next). Its
//! numerical damping of a mode of frequency ω is of order `(ω h)⁴` a step where backward
//! Euler's is of order `(ω h)²`: at a given step it dissipates far less of the resolved
//! modes and still damps the unresolved (stiff) ones. The tests measure both: an energy that
//! does not rise above its start beyond a small tolerance over many periods at 100 explicit
//! steps, and more of a vibration's amplitude left than backward Euler leaves at the same h.
//!
//! Stiffness-proportional damping ([`ImplicitParams::beta`], `[damping] beta`): the damping
//! force is `β K_n v_{n+1}`, `K_n = Σ_e K_e(u_n)` the elements' tangent (the material's, as
//! the law evaluates it over the step: [`crate::fem::ForceModel::element_tangent`] after
//! [`crate::fem::ForceModel::set_step`]) frozen at the step's start, instead of the exact
//! `β K(u_{n+1}) v_{n+1}`, which is no potential's gradient. With `v_{n+1} = (u − x*)/h_e`
//! (backward Euler: `x* = u_n`, `h_e = h`), the term is the gradient of the quadratic
//! `(β/2h_e) (u − x*)ᵀ K_n (u − x*)`, added to Φ; the tangent gets `+ (β/h_e) K_n` on the
//! elements' pattern. The element tangents `K_e(u_n)` are computed once per step and kept
//! (`(3 npe)²` numbers an element, checked against the available memory when the stepper is
//! built). Where `K_n` is positive semidefinite the term dissipates: with β it adds
//! `(β/h) Δuᵀ K_n Δu ≥ 0` to backward Euler's energy loss below, and Φ stays convex where it
//! was. Where `K_n` is indefinite (compression past buckling, whose geometric stiffness has
//! negative curvature) the term feeds energy into those directions, as the exact `β K(u) v`
//! does; the step's potential keeps the inertia's `m_a/h_e²`, and the solver's
//! regularisation and line search apply as in a static solve. The follower pressure's and
//! tools' tangent blocks and the springs are not part of `K_n`. A mode of frequency ω is
//! damped with the ratio `ζ = α/(2ω) + β ω/2`, up to the scheme's own numerical damping.
//!
//! Counts ([`ImplicitCounts`]): Newton iterations (tangent assemblies), conjugate-gradient
//! iterations, internal-force evaluations, strain-energy evaluations (the line search's Φ);
//! [`Stepper::force_evaluations`] counts the force and energy evaluations, each as one
//! finest-level evaluation (the tangent assemblies and CG iterations are counted apart).

use super::newton::{DirectNewton, DirectNewtonError, DirectNewtonParams, MultigridPcg};
use crate::error::{Divergence, DivergenceCause};
use crate::hierarchy::Transfer;
use crate::integrate::{
    check_state, hold, Checkpoint, OwnConstraints, RuntimeConstraints, Spring, State, Stepper,
    System,
};

/// The default relative tolerance of each step's Newton iteration (module docs).
pub const DEFAULT_REL_TOL: f64 = 1e-6;
/// The default absolute floor of each step's stopping rule (N).
pub const DEFAULT_ABS_TOL: f64 = 1e-12;
/// Below this many times the stopping threshold, the line search takes a step on the
/// residual's decrease alone ([`DirectNewtonParams::flat_below`]): where the forces of a run
/// are small (a load ramped up from zero) Φ's round-off exceeds the changes a Newton step
/// makes near the solution, and on Φ alone the iteration stalled a few times above the
/// threshold (the 1 MPa beam of the tests, at 6e-10 N).
const FLAT_BELOW: f64 = 100.0;

/// The forcing term of every Newton iteration of a step ([`DirectNewtonParams::first_forcing`]):
/// the predictor `d` starts close to the solution and the inertia makes the tangent well
/// conditioned, so each linear solve is carried to 1e-2 of its right-hand side (a few more
/// conjugate-gradient iterations) rather than Eisenstat–Walker's 0.5 start, which cost a
/// step four Newton iterations (each with its force, energy and line-search evaluations)
/// where one or two do.
const FIRST_FORCING: f64 = 1e-2;
/// The default most Newton iterations per step.
pub const DEFAULT_MAX_NEWTON: usize = 30;
/// Conjugate-gradient iterations at most per Newton system when a kept sparse factorisation
/// preconditions it (no coarser levels; [`DirectNewtonParams::pcg_max`]).
const DIRECT_PCG_MAX: usize = 20;

/// Settings of [`ImplicitEuler`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImplicitParams {
    /// Time step h (s).
    pub dt: f64,
    /// Relative part of each step's stopping rule (module docs); default [`DEFAULT_REL_TOL`].
    pub rel_tol: f64,
    /// Absolute floor of the stopping rule (N); default [`DEFAULT_ABS_TOL`].
    pub abs_tol: f64,
    /// Newton iterations at most per step; default [`DEFAULT_MAX_NEWTON`].
    pub max_newton: usize,
    /// CG preconditioned by the Galerkin V-cycle over the levels given to
    /// [`ImplicitEuler::with_levels`]; `None` (the default): sparse Cholesky, the factor
    /// reused as the CG preconditioner.
    pub multigrid: Option<MultigridPcg>,
    /// Stop when the kinetic energy exceeds this (J); default infinite.
    pub kinetic_limit: f64,
    /// The time discretisation; default [`ImplicitScheme::BackwardEuler`].
    pub scheme: ImplicitScheme,
    /// Stiffness-proportional damping β (s): `D = α M + β K_n`, `K_n` frozen at each step's
    /// start (module docs); default 0, none.
    pub beta: f64,
}

/// The time discretisation of [`ImplicitEuler`]'s steps (module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ImplicitScheme {
    /// Backward Euler, first order (`method = "implicit-euler"`).
    #[default]
    BackwardEuler,
    /// The two-step backward differentiation formula, second order (`method = "bdf2"`); its
    /// first step, and the first after the constrained nodes change, by backward Euler.
    Bdf2,
}

impl ImplicitScheme {
    /// The `[integrator] method` name.
    pub fn name(self) -> &'static str {
        match self {
            ImplicitScheme::BackwardEuler => "implicit-euler",
            ImplicitScheme::Bdf2 => "bdf2",
        }
    }
}

impl ImplicitParams {
    /// The defaults at step `dt` (s).
    pub fn new(dt: f64) -> Self {
        ImplicitParams {
            dt,
            rel_tol: DEFAULT_REL_TOL,
            abs_tol: DEFAULT_ABS_TOL,
            max_newton: DEFAULT_MAX_NEWTON,
            multigrid: None,
            kinetic_limit: f64::INFINITY,
            scheme: ImplicitScheme::BackwardEuler,
            beta: 0.0,
        }
    }
}

/// What [`ImplicitEuler`]'s steps have cost so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ImplicitCounts {
    /// Newton iterations (tangent assemblies), lifted ones included.
    pub newton: u64,
    /// The most Newton iterations of one step.
    pub max_newton_step: u64,
    /// Conjugate-gradient iterations.
    pub cg: u64,
    /// Internal-force evaluations.
    pub force_evaluations: u64,
    /// Strain-energy evaluations (the line search's Φ).
    pub energy_evaluations: u64,
    /// Numeric sparse factorisations.
    pub factorizations: u64,
    /// Galerkin hierarchies built.
    pub multigrid_setups: u64,
}

/// The constrained nodes the solver's pattern was built for.
#[derive(Clone, Debug, PartialEq)]
struct PatternKey {
    fixed: Vec<u32>,
    prescribed: Vec<u32>,
    sliding: Vec<(u32, [f64; 3])>,
}

impl PatternKey {
    fn of(sys: &System) -> Self {
        PatternKey {
            fixed: sys.constraints.fixed.clone(),
            prescribed: sys.constraints.prescribed.iter().map(|(a, _)| *a).collect(),
            sliding: sys.constraints.sliding().to_vec(),
        }
    }
}

/// Backward Euler on one mesh, each step a Newton solve of the incremental potential (module
/// docs).
pub struct ImplicitEuler {
    /// The mesh's system.
    pub sys: System,
    /// Its state.
    pub state: State,
    params: ImplicitParams,
    solver: DirectNewton,
    /// The level transfers of the multigrid preconditioner (empty without).
    down: Vec<Transfer>,
    key: PatternKey,
    /// The inertia springs of the current step, then the system's own.
    springs: Vec<Spring>,
    u: Vec<f64>,
    scratch: Vec<f64>,
    steps: u64,
    counts: ImplicitCounts,
    /// The last step's final largest nodal residual and its stopping threshold (N).
    last: (f64, f64),
    /// The stopping rule's force scale `F_n` (N, module docs).
    scale: f64,
    own: Option<OwnConstraints>,
    /// BDF2: the displacements and velocities one step before the state (empty for backward
    /// Euler).
    prev: (Vec<f64>, Vec<f64>),
    /// BDF2: whether `prev` is the state one step of h before, under the same constrained
    /// nodes (else the next step is a backward-Euler one).
    history: bool,
    /// The step's base `x*` (3 per node; BDF2 and β K damping only).
    base: Vec<f64>,
    /// β K damping: the frozen element tangents (`None` where β = 0).
    frozen: Option<stiffness::FrozenStiffness>,
    /// The h_e of the last step the solver took (0 before the first).
    solved_he: f64,
}

impl ImplicitEuler {
    /// A stepper of `sys` from rest (constraints imposed at t = 0), the Newton systems solved
    /// by sparse Cholesky.
    pub fn new(sys: System, params: ImplicitParams) -> Result<Self, DirectNewtonError> {
        Self::with_levels(sys, params, Vec::new())
    }

    /// As [`ImplicitEuler::new`], with the coarser levels of the multigrid preconditioner
    /// ([`ImplicitParams::multigrid`]): `down[l]` locates level l's nodes in level l + 1's
    /// mesh ([`DirectNewton::with_levels`]).
    pub fn with_levels(
        sys: System,
        params: ImplicitParams,
        down: Vec<Transfer>,
    ) -> Result<Self, DirectNewtonError> {
        let solver = build_solver(&sys, &down)?;
        let n = sys.num_nodes();
        let frozen = if params.beta > 0.0 {
            stiffness::FrozenStiffness::for_model(&*sys.force).map_err(DirectNewtonError::Memory)?
        } else {
            None
        };
        let bdf2 = params.scheme == ImplicitScheme::Bdf2;
        let history_len = if bdf2 { 3 * n } else { 0 };
        let mut state = State::at_rest(n);
        sys.impose(0.0, &mut state.u, &mut state.v);
        Ok(ImplicitEuler {
            key: PatternKey::of(&sys),
            sys,
            state,
            params,
            solver,
            down,
            springs: Vec::with_capacity(n),
            u: vec![0.0; 3 * n],
            scratch: vec![0.0; 3 * n],
            steps: 0,
            counts: ImplicitCounts::default(),
            last: (0.0, 0.0),
            scale: 0.0,
            own: None,
            prev: (vec![0.0; history_len], vec![0.0; history_len]),
            history: false,
            base: if bdf2 || frozen.is_some() {
                vec![0.0; 3 * n]
            } else {
                Vec::new()
            },
            frozen,
            solved_he: 0.0,
        })
    }

    /// The settings.
    pub fn params(&self) -> &ImplicitParams {
        &self.params
    }

    /// What the steps so far have cost.
    pub fn counts(&self) -> ImplicitCounts {
        self.counts
    }

    /// The last step's largest nodal residual over free nodes at its end, and the
    /// threshold of its stopping rule (N); zeros before the first step.
    pub fn last_step(&self) -> (f64, f64) {
        self.last
    }

    /// The largest nodal residual over free nodes of the backward-Euler equation
    /// `M (v − v_prev)/h + α M v + R(u) − V(t)` at the current state (`u`, `v`, `t`), `v_prev`
    /// the velocity of the step before (N). For tests and checks: one force evaluation.
    pub fn step_residual(&mut self, v_prev: &[f64]) -> f64 {
        let h = self.params.dt;
        let (sys, s) = (&mut self.sys, &self.state);
        sys.force.set_time(s.t);
        let mut r = vec![0.0; s.u.len()];
        if sys.internal_forces(&s.u, &mut r).is_err() {
            return f64::INFINITY;
        }
        let mut worst = 0.0f64;
        for a in 0..sys.num_nodes() {
            if sys.constraints.is_constrained(a) {
                continue;
            }
            let m = sys.mass[a];
            let mut norm2 = 0.0;
            for k in 0..3 {
                let i = 3 * a + k;
                let x = m * (s.v[i] - v_prev[i]) / h + sys.alpha * m * s.v[i] + r[i] - sys.f_ext[i];
                norm2 += x * x;
            }
            worst = worst.max(norm2.sqrt());
        }
        worst
    }

    /// Rebuild the solver where the constrained nodes changed since it was built.
    fn refresh_pattern(&mut self) -> Result<(), DirectNewtonError> {
        let key = PatternKey::of(&self.sys);
        if key != self.key {
            self.solver = build_solver(&self.sys, &self.down)?;
            self.key = key;
            // BDF2 restarts with a backward-Euler step.
            self.history = false;
        }
        Ok(())
    }

    /// The largest nodal force over free nodes of the step's residual at `u` (constrained dofs
    /// imposed at `t`, the inertia springs included): `r⁰` of the stopping rule; 0 where `u`
    /// inverts an element.
    fn start_residual(&mut self, t: f64) -> f64 {
        let n = self.u.len();
        let mut us = self.u.clone();
        let mut v = vec![0.0; n];
        self.sys.impose(t, &mut us, &mut v);
        let r = &mut self.scratch;
        if self.sys.force.internal_forces(&us, r).is_err() {
            return 0.0;
        }
        for sp in &self.springs {
            let i = 3 * sp.node as usize;
            let f = sp.force(&us);
            for k in 0..3 {
                r[i + k] += f[k];
            }
        }
        (0..n / 3)
            .filter(|&a| !self.sys.constraints.is_constrained(a))
            .map(|a| node_norm_diff(&self.sys.f_ext, r, a))
            .fold(0.0, f64::max)
    }
}

fn build_solver(sys: &System, down: &[Transfer]) -> Result<DirectNewton, DirectNewtonError> {
    if down.is_empty() {
        DirectNewton::new(&*sys.force, &sys.mass, &sys.constraints)
    } else {
        DirectNewton::with_levels(&*sys.force, &sys.mass, &sys.constraints, down)
    }
}

/// `|f_a − r_a|` (node a's 3-vectors).
fn node_norm_diff(f: &[f64], r: &[f64], a: usize) -> f64 {
    (0..3)
        .map(|k| (f[3 * a + k] - r[3 * a + k]).powi(2))
        .sum::<f64>()
        .sqrt()
}

impl Stepper for ImplicitEuler {
    fn advance(&mut self) -> Result<(), Divergence> {
        let h = self.params.dt;
        let t0 = self.state.t;
        let t1 = t0 + h;
        let step = self.steps + 1;
        let fail = |cause: DivergenceCause, element: Option<usize>| Divergence {
            time: t0,
            step,
            element,
            cause,
        };
        let solver_failure = |e: DirectNewtonError| match e {
            DirectNewtonError::Inverted(f) => fail(
                DivergenceCause::Inverted { det_f: f.det_f },
                Some(f.element),
            ),
            e => fail(DivergenceCause::Solver(e.to_string()), None),
        };
        self.refresh_pattern().map_err(solver_failure)?;
        // A rate-dependent law's evaluations advance its history over the step.
        self.sys.force.set_step(h);
        // BDF2 (with the state one step before): the base x* = (4 u_n − u_{n−1})/3, the
        // velocity v* = (4 v_n − v_{n−1})/3 and h_e = 2h/3; backward Euler: u_n, v_n and h.
        let bdf2 = self.params.scheme == ImplicitScheme::Bdf2 && self.history;
        let he = if bdf2 { 2.0 * h / 3.0 } else { h };
        if self.solved_he != 0.0 && he != self.solved_he {
            // The inertia's diagonal changed (BDF2 after a backward-Euler step, or back):
            // a factorisation or hierarchy kept from the other one preconditions the new
            // systems badly enough to stall the iteration at tight tolerances.
            self.solver = build_solver(&self.sys, &self.down).map_err(solver_failure)?;
        }
        self.solved_he = he;
        if bdf2 {
            let (up, vp) = &self.prev;
            let s = &self.state;
            let n = s.u.len();
            let (base, vstar) = (&mut self.base, &mut self.scratch);
            for i in 0..n {
                base[i] = (4.0 * s.u[i] - up[i]) / 3.0;
                vstar[i] = (4.0 * s.v[i] - vp[i]) / 3.0;
            }
        } else if !self.base.is_empty() {
            self.base.copy_from_slice(&self.state.u);
        }
        // β K damping: c K_e(u_n), c = β/h_e, about the base (the law's tangent over the step).
        if let Some(frozen) = self.frozen.as_mut() {
            frozen
                .freeze(
                    &*self.sys.force,
                    &self.state.u,
                    self.params.beta / he,
                    &self.base,
                )
                .map_err(|f| {
                    fail(
                        DivergenceCause::Inverted { det_f: f.det_f },
                        Some(f.element),
                    )
                })?;
        }
        // The inertia springs k_a = m_a (1/h_e² + α/h_e) at d_a = x*_a + h_e v*_a / (1 + α h_e),
        // and the start u = d (constrained dofs at u_n + h v_n).
        let alpha = self.sys.alpha;
        let c = 1.0 / (he * he) + alpha / he;
        let damp = 1.0 / (1.0 + alpha * he);
        self.springs.clear();
        let (u0, v0) = (&self.state.u, &self.state.v);
        let (xs, vs) = if bdf2 {
            (&self.base, &self.scratch)
        } else {
            (u0, v0)
        };
        for a in 0..self.sys.num_nodes() {
            let i = 3 * a;
            if self.sys.constraints.is_constrained(a) {
                for k in 0..3 {
                    self.u[i + k] = u0[i + k] + h * v0[i + k];
                }
                continue;
            }
            let d = [0, 1, 2].map(|k| xs[i + k] + he * damp * vs[i + k]);
            self.u[i..i + 3].copy_from_slice(&d);
            let m = self.sys.mass[a];
            if m > 0.0 {
                self.springs.push(Spring::linear(a as u32, m * c, d));
            }
        }
        self.springs.extend_from_slice(&self.sys.springs);
        let r0 = self.start_residual(t1);
        self.counts.force_evaluations += 1;
        let vmax = self
            .sys
            .f_ext
            .chunks_exact(3)
            .map(|f| (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt())
            .fold(0.0, f64::max);
        let scale = self.scale.max(vmax + r0);
        let params = DirectNewtonParams {
            // The solver's rule is `rel_tol max|V_a| + abs_tol`: all of F_n through abs_tol.
            rel_tol: 0.0,
            abs_tol: self.params.abs_tol + self.params.rel_tol * scale,
            flat_below: FLAT_BELOW * (self.params.abs_tol + self.params.rel_tol * scale),
            max_newton: self.params.max_newton,
            load_steps: 1,
            pcg_max: if self.params.multigrid.is_some() {
                0
            } else {
                DIRECT_PCG_MAX
            },
            multigrid: self.params.multigrid,
            first_forcing: FIRST_FORCING,
            ..Default::default()
        };
        let System {
            force,
            f_ext,
            constraints,
            ..
        } = &mut self.sys;
        let out = match &self.frozen {
            None => self.solver.solve(
                &mut **force,
                &self.springs,
                constraints,
                f_ext,
                t1,
                &mut self.u,
                params,
            ),
            Some(frozen) => self.solver.solve(
                &mut stiffness::Damped {
                    inner: &mut **force,
                    frozen,
                },
                &self.springs,
                constraints,
                f_ext,
                t1,
                &mut self.u,
                params,
            ),
        }
        .map_err(solver_failure)?;
        let c = &mut self.counts;
        c.newton += out.newton_steps as u64;
        c.max_newton_step = c.max_newton_step.max(out.newton_steps as u64);
        c.cg += out.cg_iterations as u64;
        c.force_evaluations += out.force_evaluations;
        c.energy_evaluations += out.energy_evaluations;
        c.factorizations += out.factorizations as u64;
        c.multigrid_setups += out.multigrid_setups as u64;
        self.last = (out.residual, out.target);
        self.scale = scale;
        if !out.converged {
            return Err(fail(
                DivergenceCause::NotConverged {
                    residual: out.residual,
                    target: out.target,
                    newton: out.newton_steps,
                },
                None,
            ));
        }
        let s = &mut self.state;
        if self.params.scheme == ImplicitScheme::Bdf2 {
            self.prev.0.copy_from_slice(&s.u);
            self.prev.1.copy_from_slice(&s.v);
            self.history = true;
        }
        if bdf2 {
            // v_{n+1} = (u_{n+1} − x*)/h_e = (3 u_{n+1} − 4 u_n + u_{n−1})/(2h).
            for ((u, v), (&x, &b)) in
                s.u.iter_mut()
                    .zip(s.v.iter_mut())
                    .zip(self.u.iter().zip(&self.base))
            {
                *v = (x - b) / he;
                *u = x;
            }
        } else {
            for ((u, v), &x) in s.u.iter_mut().zip(s.v.iter_mut()).zip(&self.u) {
                *v = (x - *u) / h;
                *u = x;
            }
        }
        s.t = t1;
        self.sys.impose(t1, &mut s.u, &mut s.v);
        let _ = self.sys.force.accept_step(&s.u, h);
        // Between steps (measures, frames) the stress is that of the accepted state.
        self.sys.force.set_step(0.0);
        self.steps = step;
        check_state(&self.sys, &self.state, step, self.params.kinetic_limit)
    }
    fn finest(&mut self) -> (&mut System, &State) {
        (&mut self.sys, &self.state)
    }
    fn steps(&self) -> u64 {
        self.steps
    }
    fn force_evaluations(&self) -> f64 {
        (self.counts.force_evaluations + self.counts.energy_evaluations) as f64
    }
    fn dt(&self) -> f64 {
        self.params.dt
    }
    fn describe(&self) -> String {
        format!(
            "single level, {} (Newton, {}), dt = {:.4e} s",
            self.params.scheme.name(),
            match self.down.len() {
                0 => "sparse Cholesky".to_string(),
                l => format!("CG with a Galerkin V-cycle over {} levels", l + 1),
            },
            self.params.dt
        )
    }
    fn diagnostics_label(&self) -> &'static str {
        "newton"
    }
    fn diagnostics(&self) -> Option<String> {
        let c = &self.counts;
        let per = |x: u64| x as f64 / self.steps.max(1) as f64;
        Some(format!(
            "{}: {} steps, {:.2} Newton iterations a step (at most {}), {:.1} CG \
             iterations a step, {:.1} force and {:.1} energy evaluations a step, {} \
             factorisations, {} multigrid setups",
            match self.params.scheme {
                ImplicitScheme::BackwardEuler => "implicit Euler",
                ImplicitScheme::Bdf2 => "BDF2",
            },
            self.steps,
            per(c.newton),
            c.max_newton_step,
            per(c.cg),
            per(c.force_evaluations),
            per(c.energy_evaluations),
            c.factorizations,
            c.multigrid_setups
        ))
    }
    fn hold_prescribed(&mut self, values: &[[f64; 3]]) {
        hold(&mut self.sys.constraints, values);
    }
    fn state(&self) -> &State {
        &self.state
    }
    fn set_runtime_constraints(&mut self, c: &RuntimeConstraints) {
        OwnConstraints::apply_runtime(&mut self.own, &mut self.sys, &mut self.state, c);
    }
    /// Level 0 carried to its cut mesh, the Newton solver built again on it by sparse
    /// Cholesky (the multigrid preconditioner's coarse level is not cut: a cut body's steps
    /// are solved directly), BDF2's previous step carried as the state is.
    fn cut(&mut self, cut: &crate::hierarchy::cut::HierarchyCut) -> crate::Result<()> {
        let Some(ch) = cut.levels.first() else {
            return Ok(());
        };
        crate::integrate::cut_level0(&mut self.sys, &mut self.state, &mut self.own, ch)?;
        let n = ch.mesh.num_nodes();
        self.down.clear();
        self.params.multigrid = None;
        self.solver = build_solver(&self.sys, &self.down)
            .map_err(|e| crate::Error::param("cut", e.to_string()))?;
        self.key = PatternKey::of(&self.sys);
        if !self.prev.0.is_empty() {
            self.prev = (ch.carry(&self.prev.0, 3), ch.carry(&self.prev.1, 3));
        }
        self.springs = Vec::with_capacity(n);
        self.u = vec![0.0; 3 * n];
        self.scratch = vec![0.0; 3 * n];
        if !self.base.is_empty() {
            self.base = vec![0.0; 3 * n];
        }
        if self.params.beta > 0.0 {
            self.frozen = stiffness::FrozenStiffness::for_model(&*self.sys.force)
                .map_err(|e| crate::Error::param("cut", e.to_string()))?;
        }
        self.solved_he = 0.0;
        Ok(())
    }
    fn save(&self, cp: &mut Checkpoint) {
        let mut w = cp.writer();
        w.state(&self.state);
        w.history(&self.sys);
        w.count(self.steps);
        w.number(self.scale);
        if self.params.scheme == ImplicitScheme::Bdf2 {
            w.vector(&self.prev.0);
            w.vector(&self.prev.1);
            w.number(if self.history { 1.0 } else { 0.0 });
        }
    }
    fn restore(&mut self, cp: &Checkpoint) {
        let mut r = cp.reader();
        r.state(&mut self.state);
        r.history(&mut self.sys);
        self.steps = r.count();
        self.scale = r.number();
        if self.params.scheme == ImplicitScheme::Bdf2 {
            r.vector(&mut self.prev.0);
            r.vector(&mut self.prev.1);
            self.history = r.number() != 0.0;
        }
    }
    fn set_kinetic_limit(&mut self, limit: f64) {
        self.params.kinetic_limit = limit;
    }
}

mod stiffness;

#[cfg(test)]
mod bdf2_tests;
#[cfg(test)]
mod damping_tests;
#[cfg(test)]
mod tests;
