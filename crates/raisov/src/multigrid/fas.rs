//! The project's convergent multigrid: a full approximation scheme (FAS) built from the
//! paper's ingredients (independent levels, host weights both ways, explicit damped
//! integrators as smoothers, coarse changes carried up as variations). Not in the paper; see
//! `docs/raisov-reading.md`, "A multigrid that converges".
//!
//! One step is one V-cycle from level 0, recursively on level l with equation
//! `R_l(u) = F_l` (`F_0 = V`, the real loads):
//!
//! ```text
//! 1. ν1 smoothing sweeps on level l                              (pre-smoothing)
//! 2. u_c0 = R u_l          each coarse node interpolated from its fine host (state restriction)
//! 3. r_l = F_l − R_l(u_l);  F_c = R_c(u_c0) + Pᵀ r_l            (τ-correction: the coarse level
//!                                                              works on the fine level's error)
//! 4. level l+1: recurse; the coarsest level takes Chebyshev sweeps, explicit damped steps at
//!    its own larger stable step from rest, or a Newton-Krylov solve (the paper's section 4)
//! 5. u_l += s P (u_c − u_c0)                                     (variation carried up)
//! 6. ν2 smoothing sweeps on level l                              (post-smoothing)
//! ```
//!
//! The smoother is a Chebyshev iteration on `D⁻¹(F − R(u))` (default; `D` per-node fictitious
//! masses, [`Scaling`]) or the level's explicit damped dynamics (the paper's G).
//!
//! What makes it hold on real meshes (the liver levels; see the regression test
//! `fas_liver_grasp_inverts_elements`):
//! - step 2 uses convex weights ([`TransferWeights`]): eq. 7's extrapolating weights (up to
//!   2–3 on the liver) can invert coarse elements; where `R u_l` still inverts one (a boundary
//!   layer that the two meshes resolve differently), `u_c0` is the coarse level's own last
//!   solution instead: any valid `u_c0` keeps the fixed point below;
//! - step 5 takes `s` from a secant line search on the fine potential energy along `P e`,
//!   `s = g0 / (g0 − g1)`, `g0 = r(u)·Pe`, `g1 = r(u + Pe)·Pe`, at most 1, halved while an
//!   element would invert; a correction that does not descend (`g0 ≤ 0`) is dropped;
//! - a coarse level that fails (an inverted element) gives no correction that cycle, and the
//!   run goes on; [`Stepper::diagnostics`] counts each of these events.
//!
//! **Krylov acceleration** (`FasParams::krylov`, default; Chebyshev smoother only). On
//! independent, non-nested meshes the coarse levels do not reproduce the fine operator (their
//! boundaries differ by an element, coarser linear tetrahedra lock more, the coarsest solve is
//! partial): on the liver levels the line search wanted 3–4 times each coarse correction, and
//! plain V-cycles reduced the residual by about 1.2x per thousands of cycles. So each cycle is
//! used as the preconditioner of a nonlinear conjugate-gradient step (Polak–Ribière) on the fine
//! potential energy `Π`, whose gradient is `−r`:
//!
//! ```text
//! z_k = V(u_k) − u_k                          (one V-cycle: the preconditioned residual)
//! β_k = max(0, z_k·(r_k − r_{k−1}) / (z_{k−1}·r_{k−1})),   p_k = z_k + β_k p_{k−1}
//! u_{k+1} = u_k + s p_k,   s from the secant line search on Π along p_k (at most 10)
//! ```
//!
//! With `β = 0` and `s = 1` this is the plain cycle. A direction that does not descend
//! (`r_k·p_k ≤ 0`) restarts the recurrence from the plain cycle's result; a new prescribed
//! value ([`Stepper::hold_prescribed`]) restarts it too. The fixed point is unchanged (at
//! `r = 0`, `z = 0`). Cost: one fine residual and one or two line-search evaluations more per
//! cycle. The measured effect on the liver levels is in `bench/RESULTS.md`.
//!
//! Coarse levels hold their *fixed* nodes at the restricted values (the correction is zero
//! there) and leave prescribed points free: a grasp is a fine-level feature, and pinning the
//! nearest coarse node would zero the correction where the error is largest; level 0 keeps its
//! real constraints (`P e` is zeroed on them). At a fixed point `r_0 = 0`, so
//! `F_c = R_c(u_c0)`, the coarse solution is `u_c0` and the correction vanishes: level 0 sits
//! exactly on SLIM's equilibrium (a test). Constraints added at run time
//! ([`Stepper::set_runtime_constraints`]) follow the same rule: pins join the held nodes of
//! every level, grasps join level 0's prescribed points only. The fine velocity is kept across
//! the correction; coarse levels start each visit at rest. Per-cycle work is O(n): each
//! level's work is proportional to its nodes.
//!
//! **Residual reuse** (`FasParams::reuse_residuals`, default). Several steps of a cycle need
//! the residual at a state another step has just evaluated; each is evaluated once:
//! - a Chebyshev sweep ends by evaluating `r(u)` (its inversion check): the restriction (step
//!   3), the next sweep and the conjugate-gradient step reuse it;
//! - the line searches end at an evaluated state: the post-smoothing and the next cycle start
//!   from it;
//! - the coarse residual at `u_c0` is `F_c − R_c(u_c0) = Pᵀ r_l` from the coarse internal
//!   forces step 3 evaluates anyway, formed exactly as `residual` forms it;
//! - `λ_max` re-estimates start from the last power iterate (5 iterations instead of 20) with
//!   one-sided differences from the known `r(u)`.
//!
//! A prescribed value that moves, [`Stepper::hold_prescribed`] and [`Stepper::finest`] (which
//! hands out the system) invalidate the fine residual. The states are the same bits with and
//! without reuse (a test); reuse only saves force evaluations, which `raisov run` and
//! `raisov paper` count.
//!
//! One file for one concern, the FAS V-cycle: its steps share the level buffers and the
//! residual bookkeeping above, so they are not split.

use super::{Level, Links};
use crate::error::{Divergence, DivergenceCause};
use crate::fem::ElementFailure;
use crate::hierarchy::Transfer;
use crate::integrate::{
    check_state, Checkpoint, Constraints, Motion, OwnConstraints, RuntimeConstraints, State,
    Stepper,
};
use crate::statics::krylov::{NewtonParams, NewtonSolver};

/// The smoother G on each level.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Smoother {
    /// Explicit damped dynamics: the level's integrator at its own step (the paper's G).
    Dynamics,
    /// Chebyshev polynomial iteration on `D⁻¹ (F − R(u))` ([`Scaling`] picks `D`) over the
    /// upper part `[b / ratio, b]` of the spectrum of `D⁻¹K`, `b = stretch λ_max` with `λ_max`
    /// from power iteration (> 1 leaves room for stiffening and for the estimate, which
    /// approaches from below). Each iteration
    /// costs one force evaluation and damps every mode in the interval; this is the smoother
    /// multigrid needs (dynamics damps all modes alike at α/2).
    Chebyshev {
        /// `b` over the interval's lower end.
        ratio: f64,
        /// `b / λ_max`.
        stretch: f64,
        /// The diagonal `D`.
        scaling: Scaling,
    },
}

/// The diagonal `D` that preconditions the Chebyshev smoother and coarse solve, `D⁻¹(F − R(u))`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Scaling {
    /// The lumped mass: `M⁻¹K`, the spectrum explicit dynamics sees. On graded meshes or
    /// meshes with slivers `λ_max` comes from the worst element and most of the mesh's
    /// high-frequency modes fall below the smoothing interval.
    Mass,
    /// Per-node fictitious masses (dynamic relaxation's, Underwood 1983): `D_a = Σ_{e∋a} c² G_e
    /// M_e,a`, the element-wise bound `K_e ≤ c² G_e M_e` ([`crate::fem::gradient_sums`])
    /// summed at the node, so that `λ_max(D⁻¹K) ≤ 1` at small strain and every node smooths at
    /// its own stable step (a Jacobi-type smoother). Equal to `λ_max M` on uniform meshes.
    Fictitious,
}

/// How the coarsest level solves its problem.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CoarseSolve {
    /// Explicit damped steps from rest for this much simulated time (s) at the level's step.
    Explicit {
        /// Simulated time (s).
        time: f64,
    },
    /// This many Chebyshev iterations over `[λ_max / ratio, λ_max]`.
    Chebyshev {
        /// Iterations per visit.
        iterations: usize,
        /// `λ_max` over the interval's lower end.
        ratio: f64,
    },
    /// Matrix-free Newton-Krylov to this relative residual.
    Newton {
        /// Relative residual at which Newton stops.
        rel_tol: f64,
    },
}

impl std::fmt::Display for CoarseSolve {
    /// In words, as `raisov check` and the stepper's description show it.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        use crate::numbers::compact;
        match *self {
            CoarseSolve::Explicit { time } => {
                write!(f, "explicit damped steps over {} s", compact(time))
            }
            CoarseSolve::Chebyshev { iterations, ratio } => write!(
                f,
                "{iterations} Chebyshev iterations over [lambda_max / {}, lambda_max]",
                compact(ratio)
            ),
            CoarseSolve::Newton { rel_tol } => write!(
                f,
                "Newton-Krylov to a relative residual of {}",
                compact(rel_tol)
            ),
        }
    }
}

/// Which weights carry state and corrections between levels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TransferWeights {
    /// The paper's eq. 6/7 weights both ways, extrapolating for nodes outside the other mesh.
    Exact,
    /// Convex weights ([`crate::hierarchy::Transfer::convex`]) for the state restriction
    /// `u_c0 = R u_f` only; `P` and `Pᵀ` exact.
    ConvexRestriction,
    /// Convex weights for `R`, `P` and `Pᵀ`.
    Convex,
}

/// Longest step `s` of the line searches along a coarse correction `P e` (in units of `P e`)
/// and along a conjugate direction. Coarse levels are stiffer than the fine one, so the best
/// step along `P e` is often 2–4.
const MAX_CORRECTION_STEP: f64 = 10.0;

/// Parameters of the FAS cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FasParams {
    /// Pre-smoothing steps ν1 per level. Default 4.
    pub pre_smooth: usize,
    /// Post-smoothing steps ν2 per level. Default 4.
    pub post_smooth: usize,
    /// Coarsest-level solve. Default Chebyshev, 60 iterations over [λ_max/1000, λ_max].
    pub coarse: CoarseSolve,
    /// Smoother. Default Chebyshev on `D⁻¹(F − R(u))`, `D` the per-node fictitious masses,
    /// over [1.2 λ_max / 100, 1.2 λ_max] with λ_max(D⁻¹K) from power iteration (drape of
    /// `examples/membrane_drape_multigrid.toml`, 1000 nodes: 1301 force evaluations to steady
    /// state, against 1730 with `D = M`).
    pub smoother: Smoother,
    /// Transfer weights. Default [`TransferWeights::Convex`].
    pub weights: TransferWeights,
    /// Use each V-cycle as the preconditioner of a nonlinear conjugate-gradient step on the
    /// fine potential energy ([`Fas`] docs, "Krylov acceleration"); Chebyshev smoother only.
    /// Default true.
    pub krylov: bool,
    /// Kinetic-energy ceiling of the finest level (J), for divergence detection.
    pub kinetic_limit: f64,
    /// Reuse a residual already computed at the same state, loads and constraints instead of
    /// evaluating it again ([`Fas`] docs, "Residual reuse"); the bits are the same either way.
    /// Default true; false is the reference path a test compares against.
    pub reuse_residuals: bool,
}

impl Default for FasParams {
    fn default() -> Self {
        FasParams {
            pre_smooth: 4,
            post_smooth: 4,
            coarse: CoarseSolve::Chebyshev {
                iterations: 60,
                ratio: 1000.0,
            },
            smoother: Smoother::Chebyshev {
                ratio: 100.0,
                stretch: 1.2,
                scaling: Scaling::Fictitious,
            },
            weights: TransferWeights::Convex,
            krylov: true,
            kinetic_limit: f64::INFINITY,
            reuse_residuals: true,
        }
    }
}

/// The FAS multigrid stepper.
pub struct Fas {
    /// The levels, 0 the finest.
    pub levels: Vec<Level>,
    /// The correspondence of each level with the next coarser one.
    pub links: Links,
    /// The cycle's parameters.
    pub params: FasParams,
    /// State restriction `R` per link (coarse nodes in the fine mesh).
    restrict: Vec<Transfer>,
    /// Interpolation `P` per link (fine nodes in the coarse mesh); `Pᵀ` restricts residuals.
    prolong: Vec<Transfer>,
    /// Restricted state u_c0 per level (unused for level 0).
    u0: Vec<Vec<f64>>,
    /// Residual scratch per level.
    r: Vec<Vec<f64>>,
    /// Diagonal preconditioner `D` per level, one value per node ([`Scaling`]).
    diag: Vec<Vec<f64>>,
    /// Small-strain bound on `λ_max(D⁻¹K)` per level.
    bound: Vec<f64>,
    /// Chebyshev direction per level.
    d: Vec<Vec<f64>>,
    /// Power-iteration estimate of λ_max(D⁻¹K) per level (0 = not yet estimated).
    lambda: Vec<f64>,
    /// The last power iterate per level (the next estimate's start; zero = none yet).
    eig: Vec<Vec<f64>>,
    /// State saved before smoothing, to fall back from an inverting Chebyshev sweep.
    saved: Vec<Vec<f64>>,
    /// Smoothing sweeps that fell back to Jacobi steps (an element would have inverted).
    pub fallbacks: u64,
    /// Cycle number of each level's last λ estimate.
    visits: Vec<u64>,
    /// Coarse corrections dropped because even 1/32 of them would invert a fine element.
    pub dropped_corrections: u64,
    /// Coarse visits skipped because both `R u_f` and the coarse level's last solution
    /// inverted a coarse element.
    pub skipped_coarse: u64,
    /// Coarse visits that failed (an element inverted on a coarser level): no correction.
    pub failed_coarse: u64,
    last_coarse_failure: Option<String>,
    /// Coarse visits that started from the coarse level's own last solution because `R u_f`
    /// inverted a coarse element.
    pub own_base: u64,
    /// The coarse level and element of the last restriction that inverted.
    last_inverting_restriction: Option<(usize, ElementFailure)>,
    newton: Option<NewtonSolver>,
    steps: u64,
    /// Nonlinear-CG acceleration state: u_k, r_k, previous direction, z·r of the last cycle.
    kry_u: Vec<f64>,
    kry_r: Vec<f64>,
    kry_p: Vec<f64>,
    kry_rprev: Vec<f64>,
    kry_zr: f64,
    /// Per level: `r[l]` holds `R_l(u_l)` at the level's current state, loads and constraints
    /// (see "Residual reuse" in the [`Fas`] docs).
    fresh: Vec<bool>,
    /// Per level, its own constraints once run-time ones were added (empty before).
    own: Vec<OwnConstraints>,
}

/// Cycles between re-estimates of each level's λ_max.
const REESTIMATE: u64 = 10;
/// Power iterations of a level's first estimate.
const POWER_ITERATIONS: usize = 20;
/// Power iterations of a re-estimate, which starts from the last estimate's vector.
const POWER_ITERATIONS_WARM: usize = 5;

/// Largest eigenvalue of `D⁻¹K(u)` on free dofs by power iteration with one-sided
/// finite-difference products `K x ≈ (r(u) − r(u + εx)) / ε`, `r0 = r(u)` given (`r` the
/// residual `F − R`). Starts from `x` when it is nonzero (the last estimate's vector: a
/// re-estimate needs only [`POWER_ITERATIONS_WARM`] iterations), else from a deterministic
/// vector with every frequency present, a Weyl sequence over the dofs in the file's node
/// order ([`Level::node_keys`]; renumbering at load then changes the estimate only by
/// round-off), and leaves the last iterate there. Power iteration
/// approaches from below; the caller's `stretch` covers that, and an inverting sweep falls
/// back to safe steps. Not capped by the small-strain bound: stretched hyperelastic elements
/// are stiffer. Uses `y` and `w` as scratch.
#[allow(clippy::too_many_arguments)]
fn estimate_lambda_max(
    lv: &mut Level,
    diag: &[f64],
    bound: f64,
    r0: &[f64],
    x: &mut [f64],
    y: &mut [f64],
    w: &mut [f64],
    step: u64,
    t: f64,
) -> Result<f64, Divergence> {
    let n = x.len();
    let warm = x.iter().any(|&v| v != 0.0);
    if !warm {
        for (i, xi) in x.iter_mut().enumerate() {
            // Keyed by the file's node ids where the mesh was renumbered, so that the vector
            // of a physical node, and the estimate, do not follow the numbering in memory.
            let key = lv
                .node_keys
                .as_ref()
                .map_or(i, |k| 3 * k[i / 3] as usize + i % 3);
            *xi = crate::linalg::spectrum::start_entry(key as u64);
        }
    }
    lv.sys.constraints.zero_constrained(x);
    let umax = lv.state.u.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
    let (lo, hi) = lv.mesh.bounding_box();
    let length = 1e-3 * crate::mesh::norm(crate::mesh::sub(hi, lo));
    let iterations = if warm {
        POWER_ITERATIONS_WARM
    } else {
        POWER_ITERATIONS
    };
    let lambda = crate::linalg::spectrum::power_iteration(
        x,
        crate::linalg::spectrum::Diagonal::Node(diag),
        iterations,
        y,
        |x: &[f64], kx: &mut [f64]| {
            // K x ≈ (r(u) − r(u + εx)) / ε
            let xmax = x.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
            let eps = 1e-7 * umax.max(length) / xmax;
            for i in 0..n {
                w[i] = lv.state.u[i] + eps * x[i];
            }
            lv.sys.residual(w, kx).map_err(|f| diverged(step, t, f))?;
            lv.evaluations += 1;
            for i in 0..n {
                kx[i] = (r0[i] - kx[i]) / eps;
            }
            Ok(())
        },
    )?;
    Ok(if lambda.is_finite() && lambda > 0.0 {
        lambda
    } else {
        // Restart cold next time.
        x.iter_mut().for_each(|v| *v = 0.0);
        bound
    })
}

fn diverged(step: u64, time: f64, f: ElementFailure) -> Divergence {
    Divergence {
        time,
        step,
        element: Some(f.element),
        cause: DivergenceCause::Inverted { det_f: f.det_f },
    }
}

impl Fas {
    /// Coarse levels' constraints become "hold at the restricted value" (set every visit).
    pub fn new(mut levels: Vec<Level>, links: Links, params: FasParams) -> Self {
        assert_eq!(links.len() + 1, levels.len());
        for l in levels.iter_mut().skip(1) {
            let c = &l.sys.constraints;
            // Only fixed regions: a prescribed point is a fine-level feature; holding the
            // nearest coarse node would pin the correction to zero exactly where the error is
            // largest (around a grasp). The fine level enforces it (P e is zeroed there).
            let mut nodes: Vec<u32> = c.fixed.clone();
            nodes.sort_unstable();
            nodes.dedup();
            let held = nodes
                .into_iter()
                .map(|a| (a, Motion::Held { d: [0.0; 3] }))
                .collect();
            // Sliding directions stay: the coarse state approximates the fine one, whose
            // constrained components are zero.
            let sliding = c.sliding().to_vec();
            l.sys.constraints = Constraints::new(vec![], held)
                .with_sliding(&sliding)
                .with_nodes(l.num_nodes());
        }
        let m = levels.len();
        let n0 = 3 * levels[0].num_nodes();
        let newton = match params.coarse {
            CoarseSolve::Newton { .. } => Some(NewtonSolver::new(&levels[m - 1].sys)),
            _ => None,
        };
        let (restrict, prolong) = links
            .iter()
            .map(|c| match params.weights {
                TransferWeights::Exact => (c.up.clone(), c.down.clone()),
                TransferWeights::ConvexRestriction => (c.up.convex(), c.down.clone()),
                TransferWeights::Convex => (c.up.convex(), c.down.convex()),
            })
            .unzip();
        let scaling = match params.smoother {
            Smoother::Chebyshev { scaling, .. } => scaling,
            Smoother::Dynamics => Scaling::Mass,
        };
        let (diag, bound) = levels
            .iter()
            .map(|l| match scaling {
                Scaling::Mass => (l.sys.mass.clone(), l.lambda_max),
                Scaling::Fictitious => (
                    crate::statics::relax::fictitious_mass(&l.mesh, &l.sys.mass, l.lambda_max),
                    1.0,
                ),
            })
            .unzip();
        Fas {
            restrict,
            diag,
            bound,
            prolong,
            u0: levels
                .iter()
                .map(|l| vec![0.0; 3 * l.num_nodes()])
                .collect(),
            r: levels
                .iter()
                .map(|l| vec![0.0; 3 * l.num_nodes()])
                .collect(),
            d: levels
                .iter()
                .map(|l| vec![0.0; 3 * l.num_nodes()])
                .collect(),
            lambda: vec![0.0; levels.len()],
            eig: levels
                .iter()
                .map(|l| vec![0.0; 3 * l.num_nodes()])
                .collect(),
            saved: levels
                .iter()
                .map(|l| vec![0.0; 3 * l.num_nodes()])
                .collect(),
            fallbacks: 0,
            visits: vec![u64::MAX; levels.len()],
            dropped_corrections: 0,
            skipped_coarse: 0,
            last_inverting_restriction: None,
            own_base: 0,
            failed_coarse: 0,
            last_coarse_failure: None,
            levels,
            links,
            params,
            newton,
            steps: 0,
            kry_u: vec![0.0; n0],
            kry_r: vec![0.0; n0],
            kry_p: vec![0.0; n0],
            kry_rprev: vec![0.0; n0],
            kry_zr: 0.0,
            fresh: vec![false; m],
            own: Vec::new(),
        }
    }

    /// Whether `r[l]` may be used as `R_l(u_l)` without evaluating it.
    fn known(&self, l: usize) -> bool {
        self.params.reuse_residuals && self.fresh[l]
    }

    fn smooth(&mut self, l: usize, steps: usize, t: f64) -> Result<(), Divergence> {
        match self.params.smoother {
            Smoother::Dynamics => self.dynamics(l, steps, t),
            Smoother::Chebyshev { ratio, stretch, .. } => {
                self.chebyshev(l, steps, ratio, stretch, t)
            }
        }
    }

    /// Chebyshev iteration for `R_l(u) = F_l` preconditioned by `D⁻¹` (Saad, Alg. 12.1),
    /// eigenvalue interval `[b/ratio, b]`, `b = stretch λ_max`. Velocities are left at zero.
    fn chebyshev(
        &mut self,
        l: usize,
        iterations: usize,
        ratio: f64,
        stretch: f64,
        t: f64,
    ) -> Result<(), Divergence> {
        let step_no = self.steps + 1;
        let mut known = self.known(l);
        self.fresh[l] = false;
        let lv = &mut self.levels[l];
        let r = &mut self.r[l];
        let d = &mut self.d[l];
        if self.lambda[l] == 0.0
            || self.steps.is_multiple_of(REESTIMATE) && self.visits[l] != self.steps
        {
            self.visits[l] = self.steps;
            if !known {
                lv.sys
                    .residual(&lv.state.u, r)
                    .map_err(|f| diverged(step_no, t, f))?;
                lv.evaluations += 1;
                // The reference path evaluates it again for the first sweep.
                known = self.params.reuse_residuals;
            }
            let est = estimate_lambda_max(
                lv,
                &self.diag[l],
                self.bound[l],
                r,
                &mut self.eig[l],
                d,
                &mut self.saved[l],
                step_no,
                t,
            )?;
            self.lambda[l] = est;
        }
        let b = stretch * self.lambda[l];
        self.saved[l].copy_from_slice(&lv.state.u);
        let diag = &self.diag[l];
        if chebyshev_sweeps(lv, diag, r, d, iterations, b, ratio, known).is_err() {
            // Large residuals (a sudden lift) or a thin element can make the long
            // Chebyshev steps invert an element: restore and take the conservative
            // damped-Jacobi steps u += r/(D b). (Stopping at the last valid iterate
            // instead, a lower-degree Chebyshev polynomial, cost the liver 1.7x the
            // cycles.)
            self.fallbacks += 1;
            let mut b_safe = 4.0 * b.max(stretch * self.bound[l]);
            let mut attempt = 0;
            loop {
                lv.state.u.copy_from_slice(&self.saved[l]);
                match chebyshev_sweeps(lv, diag, r, d, iterations, b_safe, 1.0, false) {
                    Ok(()) => break,
                    Err(f) if attempt >= 4 => return Err(diverged(step_no, t, f)),
                    Err(_) => {
                        attempt += 1;
                        b_safe *= 2.0;
                    }
                }
            }
            // The state was stiffer than estimated: estimate again next visit.
            self.lambda[l] = 0.0;
        }
        lv.state.v.iter_mut().for_each(|x| *x = 0.0);
        lv.state.t = t;
        // A no-op on u: the sweeps started from imposed values and move no constrained node
        // (the residual is zero there), so `r` still holds R(u).
        let (tt, st) = (t, &mut lv.state);
        lv.sys.impose(tt, &mut st.u, &mut st.v);
        self.fresh[l] = true;
        Ok(())
    }
}

/// `iterations` Chebyshev sweeps for `R(u) = F` with preconditioner `D⁻¹` (`diag`, per node)
/// over `[b/ratio, b]` (Saad, Alg. 12.1); `ratio = 1` is damped Jacobi `u += r / (D b)`.
/// `known`: `r` already holds the residual at `lv.state.u` (not evaluated again). Uses `d` as
/// scratch; on success `r` holds the residual at the final state. An evaluation that finds an
/// inverted element counts as one.
#[allow(clippy::too_many_arguments)]
fn chebyshev_sweeps(
    lv: &mut Level,
    diag: &[f64],
    r: &mut [f64],
    d: &mut [f64],
    iterations: usize,
    b: f64,
    ratio: f64,
    known: bool,
) -> Result<(), ElementFailure> {
    {
        let a = b / ratio;
        let theta = 0.5 * (b + a);
        let delta = 0.5 * (b - a);
        let sigma = if delta > 0.0 {
            theta / delta
        } else {
            f64::INFINITY
        };
        let mut rho = 1.0 / sigma;
        for k in 0..iterations {
            if k > 0 || !known {
                lv.evaluations += 1;
                lv.sys.residual(&lv.state.u, r)?;
            }
            if k == 0 || delta == 0.0 {
                for i in 0..r.len() {
                    d[i] = r[i] / (diag[i / 3] * theta);
                }
            } else {
                let rho_new = 1.0 / (2.0 * sigma - rho);
                let c0 = rho_new * rho;
                let c1 = 2.0 * rho_new / delta;
                for i in 0..r.len() {
                    d[i] = c0 * d[i] + c1 * r[i] / diag[i / 3];
                }
                rho = rho_new;
            }
            for i in 0..r.len() {
                lv.state.u[i] += d[i];
            }
        }
        // Check the final state here, where an inversion can still be undone; the residual is
        // the next user's (restriction, line search, next sweep).
        if iterations > 0 || !known {
            lv.evaluations += 1;
            lv.sys.residual(&lv.state.u, r)?;
        }
        Ok(())
    }
}

impl Fas {
    fn dynamics(&mut self, l: usize, steps: usize, t: f64) -> Result<(), Divergence> {
        let step_no = self.steps + 1;
        self.fresh[l] = false;
        let lv = &mut self.levels[l];
        for _ in 0..steps {
            lv.integrator
                .step(&mut lv.sys, &mut lv.state, lv.dt)
                .map_err(|f| diverged(step_no, t, f))?;
            lv.evaluations += lv.integrator.method().evaluations();
            if l > 0 {
                // Coarse levels solve at the frozen time of the visit.
                lv.state.t = t;
            }
        }
        Ok(())
    }

    fn coarsest(&mut self, l: usize, t: f64) -> Result<(), Divergence> {
        match self.params.coarse {
            CoarseSolve::Explicit { time } => {
                let k = (time / self.levels[l].dt).ceil().max(1.0) as usize;
                self.dynamics(l, k, t)
            }
            CoarseSolve::Chebyshev { iterations, ratio } => {
                self.chebyshev(l, iterations, ratio, 1.2, t)
            }
            CoarseSolve::Newton { rel_tol } => {
                self.fresh[l] = false;
                let lv = &mut self.levels[l];
                let solver = self.newton.as_mut().expect("built for Newton");
                let p = NewtonParams {
                    rel_tol,
                    max_newton: 10,
                    ..Default::default()
                };
                let mut u = std::mem::take(&mut lv.state.u);
                let res = solver.solve(&mut lv.sys, t, &mut u, p);
                lv.state.u = u;
                match res {
                    Ok(s) => {
                        lv.evaluations += s.force_evaluations;
                        Ok(())
                    }
                    // An inverting Newton step is no divergence of the run: keep u_c0.
                    Err(_) => {
                        let u0 = &self.u0[l];
                        lv.state.u.copy_from_slice(u0);
                        Ok(())
                    }
                }
            }
        }
    }

    fn visit(&mut self, l: usize, t: f64) -> Result<(), Divergence> {
        let m = self.levels.len();
        if l + 1 == m {
            return self.coarsest(l, t);
        }
        let step_no = self.steps + 1;
        self.smooth(l, self.params.pre_smooth, t)?;
        // Restrict the state and build the coarse right-hand side.
        {
            let known = self.known(l);
            let (fine, coarse) = self.levels.split_at_mut(l + 1);
            let (f, c) = (&mut fine[l], &mut coarse[0]);
            self.restrict[l]
                .interpolate(&f.state.u, 3, &mut self.u0[l + 1])
                .expect("sizes match");
            if !known {
                f.sys
                    .residual(&f.state.u, &mut self.r[l])
                    .map_err(|e| diverged(step_no, t, e))?;
                f.evaluations += 1;
                self.fresh[l] = true;
            }
            // F_c = R_c(u_c0) + Pᵀ r_f. Any valid u_c0 keeps the fixed point (r_f = 0 gives
            // u_c = u_c0 and no correction); R u_f is the natural one, but where the fine field
            // is far from affine over a coarse element (a boundary layer at a support that the
            // two meshes resolve differently) it can invert that element. Then the coarse
            // level starts from its own last solution instead (a valid state: it came out of
            // a solve, zero on the first visit); only if that fails too is the visit skipped.
            // The coarse internal forces at u_c0 go to r[l+1] first: they give F_c and then
            // the coarse residual at u_c0, the first coarse sweep's.
            self.fresh[l + 1] = false;
            let (r_fine, r_coarse) = self.r.split_at_mut(l + 1);
            let q = &mut r_coarse[0];
            c.evaluations += 1;
            if let Err(e) = c.sys.internal_forces(&self.u0[l + 1], q) {
                self.last_inverting_restriction = Some((l + 1, e));
                self.u0[l + 1].copy_from_slice(&c.state.u);
                c.evaluations += 1;
                if c.sys.internal_forces(&self.u0[l + 1], q).is_err() {
                    self.skipped_coarse += 1;
                    return self.smooth(l, self.params.post_smooth, t);
                }
                self.own_base += 1;
            }
            let fc = &mut c.sys.f_ext;
            fc.copy_from_slice(q);
            // Hold coarse constrained nodes at u_c0.
            let u0c = &self.u0[l + 1];
            for (a, mo) in c.sys.constraints.prescribed.iter_mut() {
                let k = 3 * *a as usize;
                *mo = Motion::Held {
                    d: [u0c[k], u0c[k + 1], u0c[k + 2]],
                };
            }
            c.state.u.copy_from_slice(u0c);
            c.state.v.iter_mut().for_each(|x| *x = 0.0);
            c.state.t = t;
            self.prolong[l]
                .transpose_add(&r_fine[l], 3, fc)
                .expect("sizes match");
            // The coarse residual at u_c0, F_c − R_c(u_c0), exactly as `residual` forms it.
            for (q, f) in q.iter_mut().zip(fc.iter()) {
                *q = f - *q;
            }
            c.sys.constraints.zero_constrained(q);
            self.fresh[l + 1] = true;
        }
        if let Err(d) = self.visit(l + 1, t) {
            // A coarse level that inverts an element must not stop the run: that cycle has
            // no coarse correction on this level (the fine level is untouched so far).
            self.failed_coarse += 1;
            self.last_coarse_failure = Some(d.to_string());
            let c = &mut self.levels[l + 1];
            c.state.u.copy_from_slice(&self.u0[l + 1]);
        }
        self.fresh[l + 1] = false;
        // Carry the coarse change up as a variation, u += s P (u_c − u_c0), with s from a
        // secant line search on the fine potential energy Π along p = P e: Π'(s) = −r(u + s p)·p,
        // so s* = g0 / (g0 − g1) with g0 = r(u)·p, g1 = r(u + p)·p (exact for a quadratic Π;
        // free, since r(u + p) is evaluated anyway to check for inversion). A correction that
        // does not descend (g0 ≤ 0) is dropped; s is halved while it would invert an element.
        {
            let (fine, coarse) = self.levels.split_at_mut(l + 1);
            let (f, c) = (&mut fine[l], &coarse[0]);
            let e = &mut self.r[l + 1];
            for k in 0..e.len() {
                e[k] = c.state.u[k] - self.u0[l + 1][k];
            }
            // P e into the fine direction scratch, with constrained nodes left alone.
            let pe = &mut self.d[l];
            self.prolong[l].interpolate(e, 3, pe).expect("sizes match");
            f.sys.constraints.zero_constrained(pe);
            // self.r[l] still holds the fine residual at u (computed for the restriction).
            let g0: f64 = self.r[l].iter().zip(pe.iter()).map(|(a, b)| a * b).sum();
            self.saved[l].copy_from_slice(&f.state.u);
            let step = if g0 > 0.0 {
                secant_search(f, &self.saved[l], pe, g0, &mut self.r[l], 0.04)
            } else {
                None
            };
            self.fresh[l] = matches!(step, Some((_, true)));
            if step.is_none() {
                f.state.u.copy_from_slice(&self.saved[l]);
                self.dropped_corrections += 1;
            }
        }
        self.smooth(l, self.params.post_smooth, t)
    }
}

impl Fas {
    /// One V-cycle used as the preconditioner of a nonlinear conjugate-gradient step on the
    /// fine potential energy (Polak-Ribière): `z = V(u) − u`, `p = z + β p_prev`,
    /// `β = max(0, z·(r − r_prev) / (z_prev·r_prev))`, then a secant line search along `p`.
    fn krylov_cycle(&mut self, t: f64) -> Result<(), Divergence> {
        let step_no = self.steps + 1;
        let n = self.levels[0].state.u.len();
        {
            let known = self.known(0);
            let f = &mut self.levels[0];
            self.kry_u.copy_from_slice(&f.state.u);
            if known {
                self.kry_r.copy_from_slice(&self.r[0]);
            } else {
                f.sys
                    .residual(&f.state.u, &mut self.kry_r)
                    .map_err(|e| diverged(step_no, t, e))?;
                f.evaluations += 1;
                // The pre-smoothing's first residual.
                self.r[0].copy_from_slice(&self.kry_r);
                self.fresh[0] = true;
            }
        }
        self.visit(0, t)?;
        let f = &mut self.levels[0];
        // z = V(u) − u into the scratch d[0].
        let z = &mut self.d[0];
        for k in 0..n {
            z[k] = f.state.u[k] - self.kry_u[k];
        }
        f.sys.constraints.zero_constrained(z);
        let zr: f64 = z.iter().zip(&self.kry_r).map(|(a, b)| a * b).sum();
        let mut beta = 0.0;
        if self.kry_zr > 0.0 {
            let num: f64 = (0..n)
                .map(|k| z[k] * (self.kry_r[k] - self.kry_rprev[k]))
                .sum();
            beta = (num / self.kry_zr).max(0.0);
        }
        for k in 0..n {
            self.kry_p[k] = z[k] + beta * self.kry_p[k];
        }
        let p = &self.kry_p;
        let g0: f64 = p.iter().zip(&self.kry_r).map(|(a, b)| a * b).sum();
        if g0 <= 0.0 || zr <= 0.0 {
            // Not a descent direction: restart from the plain cycle's result.
            self.kry_zr = 0.0;
            self.kry_p.iter_mut().for_each(|x| *x = 0.0);
            return Ok(());
        }
        self.kry_rprev.copy_from_slice(&self.kry_r);
        self.kry_zr = zr;
        // Secant line search from u_k along p; s = 1 with β = 0 is the plain cycle.
        let step = secant_search(f, &self.kry_u, &self.kry_p, g0, &mut self.r[0], 1e-3);
        self.fresh[0] = matches!(step, Some((_, true)));
        if step.is_none() {
            // Give up the acceleration this cycle: back to u_k plus z.
            for k in 0..n {
                f.state.u[k] = self.kry_u[k] + self.d[0][k];
            }
            self.fresh[0] = false;
            self.kry_zr = 0.0;
            self.kry_p.iter_mut().for_each(|x| *x = 0.0);
        }
        Ok(())
    }
}

/// Secant line search on the fine potential energy `Π` along `p` from `base`, with
/// `Π'(s) = −r(base + s p)·p` and `g0 = r(base)·p > 0`: tries `s = 1`, then the secant's zero
/// `s* = s g0 / (g0 − g_s)` (at most [`MAX_CORRECTION_STEP`]) unless it is within 20 % of `s`;
/// a longer step that inverts an element falls back to the last valid one, a shorter one is
/// halved until it is valid. Leaves `lv.state.u = base + s p` and returns `s` and whether `r`
/// holds the residual there, or `None` (state undefined) once `s` falls below `min_step`.
/// Uses `r` as scratch.
fn secant_search(
    lv: &mut Level,
    base: &[f64],
    p: &[f64],
    g0: f64,
    r: &mut [f64],
    min_step: f64,
) -> Option<(f64, bool)> {
    let set = |u: &mut [f64], s: f64| {
        for k in 0..p.len() {
            u[k] = base[k] + s * p[k];
        }
    };
    let mut s = 1.0;
    let mut searched = false;
    // The last valid step when trying a longer one.
    let mut fallback: Option<f64> = None;
    loop {
        set(&mut lv.state.u, s);
        lv.evaluations += 1;
        if lv.sys.residual(&lv.state.u, r).is_ok() {
            if searched {
                return Some((s, true));
            }
            searched = true;
            let gs: f64 = r.iter().zip(p).map(|(a, b)| a * b).sum();
            // Π'(0) = −g0 < 0, Π'(s) = −gs: the secant's zero. Coarse levels are stiffer than
            // the fine one (coarser linear tetrahedra lock, their coarsest solve is partial),
            // so the best step along a coarse correction is often well above 1.
            let s_opt = if g0 - gs > 0.0 {
                (s * g0 / (g0 - gs)).min(MAX_CORRECTION_STEP)
            } else {
                s
            };
            if (s_opt - s).abs() <= 0.2 * s {
                return Some((s, true));
            }
            if s_opt > s {
                fallback = Some(s);
            }
            s = s_opt;
            continue;
        }
        if let Some(good) = fallback.take() {
            // The longer step inverts an element: take the last valid one.
            set(&mut lv.state.u, good);
            return Some((good, false));
        }
        s *= 0.5;
        if s < min_step {
            return None;
        }
    }
}

impl Stepper for Fas {
    fn state(&self) -> &State {
        &self.levels[0].state
    }
    fn num_levels(&self) -> usize {
        self.levels.len()
    }
    fn level_mesh(&self, level: usize) -> Option<&crate::mesh::Mesh> {
        self.levels.get(level).map(|l| &l.mesh)
    }
    fn level_links(&self) -> Option<&[crate::hierarchy::Correspondence]> {
        Some(&self.links)
    }
    /// Every level cut and the cycle rebuilt on the cut levels (its spectral estimates made
    /// again), the states carried, the counters kept.
    fn cut(&mut self, cut: &crate::hierarchy::cut::HierarchyCut) -> crate::Result<()> {
        self.set_runtime_constraints(&RuntimeConstraints::default());
        let mut levels = super::take_cut_levels(&mut self.levels, cut)?;
        for lv in levels.iter_mut().skip(1) {
            // `Fas::new` turned the coarse fixed regions into held points: back to fixed,
            // as it takes them.
            let c = &lv.sys.constraints;
            let fixed = c.prescribed.iter().map(|(a, _)| *a).collect();
            lv.sys.constraints = Constraints::new(fixed, vec![])
                .with_sliding(c.sliding())
                .with_nodes(lv.num_nodes());
        }
        let mut next = Fas::new(levels, cut.links.clone(), self.params);
        next.steps = self.steps;
        next.fallbacks = self.fallbacks;
        next.dropped_corrections = self.dropped_corrections;
        next.skipped_coarse = self.skipped_coarse;
        next.failed_coarse = self.failed_coarse;
        next.own_base = self.own_base;
        *self = next;
        Ok(())
    }
    /// Level 0 takes the held (grasped) and pinned nodes; a coarse level takes its pinned nodes
    /// as it takes its fixed regions, held at the restricted state every visit. Grasps stay on
    /// level 0 (see the module docs). Each level takes its springs (a changed set of
    /// stiffnesses makes the level estimate its λ_max again).
    fn set_runtime_constraints(&mut self, c: &RuntimeConstraints) {
        if self.own.is_empty() {
            self.own = self
                .levels
                .iter()
                .map(|l| OwnConstraints::of(&l.sys.constraints))
                .collect();
        }
        for (l, (lv, own)) in self.levels.iter_mut().zip(&self.own).enumerate() {
            let held = if l == 0 { &c.held[..] } else { &[] };
            let pinned = c.pinned.get(l).map_or(&[][..], |p| &p[..]);
            let n = lv.num_nodes();
            own.apply(&mut lv.sys.constraints, held, pinned, &lv.state.u, n);
            let springs = c.springs_of(l);
            let stiffer = springs.len() != lv.sys.springs.len()
                || springs
                    .iter()
                    .zip(&lv.sys.springs)
                    .any(|(a, b)| a.node != b.node || a.k != b.k);
            if stiffer {
                // Springs change the operator: estimate λ_max again at the next visit.
                self.lambda[l] = 0.0;
            }
            lv.sys.springs = springs.to_vec();
            let t = lv.state.t;
            lv.sys.impose(t, &mut lv.state.u, &mut lv.state.v);
        }
        self.fresh.iter_mut().for_each(|f| *f = false);
        // A new problem: restart the conjugate directions.
        self.kry_zr = 0.0;
        self.kry_p.iter_mut().for_each(|x| *x = 0.0);
    }
    fn set_kinetic_limit(&mut self, limit: f64) {
        self.params.kinetic_limit = limit;
    }
    /// `r[0]` holds the residual at level 0's state exactly when `fresh[0]`, and the system's
    /// forces were evaluated in the same call ([`crate::integrate::System::residual`]);
    /// nothing evaluates level 0 at another state after it without clearing `fresh[0]`.
    fn finest_forces(&self) -> Option<&[f64]> {
        self.fresh[0].then(|| self.levels[0].sys.last_forces())
    }
    fn save(&self, cp: &mut Checkpoint) {
        let mut w = cp.writer();
        for l in &self.levels {
            w.state(&l.state);
            w.history(&l.sys);
        }
        for e in &self.eig {
            w.vector(e);
        }
        for (&lambda, &visit) in self.lambda.iter().zip(&self.visits) {
            w.number(lambda);
            w.count(visit);
        }
        for x in [&self.kry_u, &self.kry_r, &self.kry_p, &self.kry_rprev] {
            w.vector(x);
        }
        w.number(self.kry_zr);
        w.count(self.steps);
    }
    fn restore(&mut self, cp: &Checkpoint) {
        let mut r = cp.reader();
        for l in &mut self.levels {
            r.state(&mut l.state);
            r.history(&mut l.sys);
        }
        for e in &mut self.eig {
            r.vector(e);
        }
        for (lambda, visit) in self.lambda.iter_mut().zip(&mut self.visits) {
            *lambda = r.number();
            *visit = r.count();
        }
        for x in [
            &mut self.kry_u,
            &mut self.kry_r,
            &mut self.kry_p,
            &mut self.kry_rprev,
        ] {
            r.vector(x);
        }
        self.kry_zr = r.number();
        self.steps = r.count();
        // The residual scratch belongs to the abandoned steps.
        self.fresh.iter_mut().for_each(|f| *f = false);
    }
    /// Level 0 only: coarse levels carry no prescribed points (see the module docs).
    /// With a static smoother (Chebyshev) only: level 0's displacement is the state.
    fn predict(&mut self, du: &[f64]) -> bool {
        if matches!(self.params.smoother, Smoother::Dynamics) {
            return false;
        }
        let l = &mut self.levels[0];
        let mut d = du.to_vec();
        l.sys.constraints.zero_constrained(&mut d);
        for (u, d) in l.state.u.iter_mut().zip(&d) {
            *u += d;
        }
        self.fresh.iter_mut().for_each(|f| *f = false);
        self.kry_zr = 0.0;
        self.kry_p.iter_mut().for_each(|x| *x = 0.0);
        true
    }
    fn hold_prescribed(&mut self, values: &[[f64; 3]]) {
        crate::integrate::hold(&mut self.levels[0].sys.constraints, values);
        self.fresh[0] = false;
        // A new problem: restart the conjugate directions.
        self.kry_zr = 0.0;
        self.kry_p.iter_mut().for_each(|x| *x = 0.0);
    }
    fn advance(&mut self) -> Result<(), Divergence> {
        let t0 = self.levels[0].state.t;
        let t1 = t0 + self.dt();
        // Static smoothers solve the equilibrium at the cycle's end time; dynamics integrates
        // level 0 from t0 (coarse levels frozen at t0).
        let t = match self.params.smoother {
            Smoother::Dynamics => t0,
            Smoother::Chebyshev { .. } => {
                let l = &mut self.levels[0];
                self.kry_u.copy_from_slice(&l.state.u);
                l.state.t = t1;
                let st = &mut l.state;
                l.sys.impose(t1, &mut st.u, &mut st.v);
                if st.u != self.kry_u {
                    // A prescribed motion moved: the last residual is stale.
                    self.fresh[0] = false;
                }
                t1
            }
        };
        if self.levels.len() == 1 {
            self.coarsest(0, t)?;
        } else if self.params.krylov && matches!(self.params.smoother, Smoother::Chebyshev { .. }) {
            self.krylov_cycle(t)?;
        } else {
            self.visit(0, t)?;
        }
        self.levels[0].state.t = t1;
        self.steps += 1;
        for (l, fresh) in self.levels.iter_mut().zip(&mut self.fresh) {
            if l.sys.force.accept_step(&l.state.u, t1 - t0) {
                // The committed state changed the forces: the cached residual is stale.
                *fresh = false;
            }
        }
        let l = &self.levels[0];
        check_state(&l.sys, &l.state, self.steps, self.params.kinetic_limit)
    }
    fn finest(&mut self) -> (&mut crate::integrate::System, &crate::integrate::State) {
        // The caller may change loads or constraints.
        self.fresh[0] = false;
        let l = &mut self.levels[0];
        (&mut l.sys, &l.state)
    }
    fn steps(&self) -> u64 {
        self.steps
    }
    fn force_evaluations(&self) -> f64 {
        super::finest_equivalent_evaluations(&self.levels)
    }
    fn dt(&self) -> f64 {
        self.levels[0].dt * (self.params.pre_smooth + self.params.post_smooth).max(1) as f64
    }
    fn report(&self) -> String {
        super::hierarchy_report(&self.levels, &self.links)
    }
    fn diagnostics(&self) -> Option<String> {
        Some(
            format!(
                "{} coarse visits from the coarse level's last solution (R u_f inverted a coarse \
             element), {} skipped, {} coarse corrections dropped (no descent, or inverting a fine element), \
             {} smoothing sweeps fell back to Jacobi steps, {} coarse visits failed{}",
                self.own_base,
                self.skipped_coarse,
                self.dropped_corrections,
                self.fallbacks,
                self.failed_coarse,
                match &self.last_coarse_failure {
                    Some(d) => format!(" (last: {d})"),
                    None => String::new(),
                }
            ) + &match self.last_inverting_restriction {
                Some((l, e)) => format!(
                    "; last inverting restriction: level {l}, element {} (det F = {:.3e})",
                    e.element, e.det_f
                ),
                None => String::new(),
            } + &format!(
                "; force evaluations per level (own size): {}",
                self.levels
                    .iter()
                    .map(|l| l.evaluations.to_string())
                    .collect::<Vec<_>>()
                    .join("/")
            ),
        )
    }
    fn describe(&self) -> String {
        let nodes: Vec<String> = self
            .levels
            .iter()
            .map(|l| l.num_nodes().to_string())
            .collect();
        format!(
            "fas multigrid, {} levels ({} nodes), nu1 = {}, nu2 = {}, coarsest level by {}, {}, fine dt = {:.4e} s",
            self.levels.len(),
            nodes.join("/"),
            self.params.pre_smooth,
            self.params.post_smooth,
            self.params.coarse,
            self.levels[0].integrator.method().name(),
            self.levels[0].dt
        )
    }
}
