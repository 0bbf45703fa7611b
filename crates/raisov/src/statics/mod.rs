//! Static equilibrium `R(u) = V`: the Newton solvers and the relaxation baselines.
//!
//! - [`newton`]: the one Newton driver ([`newton::solve_with`]: load increments, the lifted
//!   first iteration of a prescribed motion, the line search, the regularisation and the
//!   stopping rule `max_a |r_a| ≤ rel_tol max_a |V_a| + abs_tol`) over a linear-solve trait
//!   ([`newton::NewtonLinear`]) and its implementations: the consistent analytic tangent
//!   assembled on a fixed pattern ([`newton::DirectNewton`]: sparse Cholesky, conjugate
//!   gradients preconditioned with a kept factorisation, or with a Galerkin V-cycle over the
//!   levels: Newton-multigrid) and matrix-free conjugate gradients ([`newton::MatrixFree`]:
//!   tangent products by differences of the forces, any force model);
//! - [`nested`]: the coarse start, a coarser level's equilibrium interpolated as the fine
//!   start, through levels about four times apart;
//! - [`krylov`]: Newton-Krylov on a system, the driver over matrix-free CG with a stopping
//!   rule relative to the start (reference solves, tests);
//! - [`implicit`]: backward Euler time stepping, each step the [`newton`] solve of an
//!   incremental potential (the static problem plus one inertia spring per node);
//! - [`relax`]: single-level relaxations (dynamic, adaptive dynamic, Chebyshev), the
//!   baselines and the T∞ references.
//!
//! The linear algebra they share (conjugate gradients, the Galerkin hierarchy, smoothers,
//! coarse factor) is in [`crate::linalg`].

pub mod frames;
pub mod implicit;
pub mod krylov;
pub mod nested;
pub mod newton;
pub mod relax;

/// How each Newton system of a static solve (and of a backward-Euler or BDF2 step) is solved:
/// `[integrator] solver` of a scenario.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StaticSolver {
    /// `"multigrid"` where the model has a coarser level with at least 1/32 of the finest
    /// level's nodes, else `"direct"`; `"krylov"` only where the force model has no element
    /// tangent.
    Auto,
    /// The assembled analytic tangent, conjugate gradients preconditioned by a Galerkin
    /// V-cycle over the finest level and that coarser one ([`newton::MultigridPcg`]).
    Multigrid,
    /// The assembled analytic tangent, sparse Cholesky, the factor reused as the
    /// preconditioner of conjugate gradients ([`newton`]).
    Direct,
    /// Matrix-free Newton-Krylov: finite-difference tangent products, conjugate gradients
    /// ([`newton::MatrixFree`]); covers every force.
    Krylov,
}

impl StaticSolver {
    /// Every solver, in the order messages list them.
    pub const ALL: [StaticSolver; 4] = [
        StaticSolver::Auto,
        StaticSolver::Multigrid,
        StaticSolver::Direct,
        StaticSolver::Krylov,
    ];

    /// The scenario's spelling: `"auto"`, `"multigrid"`, `"direct"`, `"krylov"`.
    pub fn name(self) -> &'static str {
        match self {
            StaticSolver::Auto => "auto",
            StaticSolver::Multigrid => "multigrid",
            StaticSolver::Direct => "direct",
            StaticSolver::Krylov => "krylov",
        }
    }
}

/// What the levels offer Newton-multigrid ([`StaticSolver::resolve`]).
#[derive(Clone, Debug, PartialEq)]
pub enum CoarseOffer {
    /// No coarser levels.
    NoLevels,
    /// Coarser levels, none of which qualifies (why, in words).
    NoneQualifies(String),
    /// A coarse level qualifies ([`newton::coarse_level`]).
    Qualifies,
}

impl StaticSolver {
    /// The `auto` policy: the solver that runs where `self` was asked for, for a force model
    /// with (`has_tangent`) or without an element tangent and the levels' `offer`, and why
    /// where `"auto"` chose (`""` otherwise). `"auto"` takes `"multigrid"` where a coarse
    /// level qualifies, `"direct"` where not, `"krylov"` where the model has no element
    /// tangent. An error, in words, where an assembled solver was asked for and does not
    /// apply.
    pub fn resolve(
        self,
        has_tangent: bool,
        offer: &CoarseOffer,
    ) -> Result<(StaticSolver, String), String> {
        let auto = self == StaticSolver::Auto;
        let took = |solver: StaticSolver, why: &str| {
            (
                solver,
                format!("solver \"auto\" took \"{}\": {why}", solver.name()),
            )
        };
        if self == StaticSolver::Krylov {
            return Ok((self, String::new()));
        }
        if !has_tangent {
            let why = "the force model has no element tangent";
            return match auto {
                true => Ok(took(StaticSolver::Krylov, why)),
                false => Err(format!(
                    "`integrator.solver` = \"{}\" does not apply: {why}; valid here: \"krylov\" or \"auto\"",
                    self.name()
                )),
            };
        }
        match (self, offer) {
            (StaticSolver::Direct, _) => Ok((self, String::new())),
            (_, CoarseOffer::Qualifies) => Ok((StaticSolver::Multigrid, String::new())),
            (StaticSolver::Auto, CoarseOffer::NoLevels) => {
                Ok(took(StaticSolver::Direct, "no [multigrid] levels"))
            }
            (StaticSolver::Auto, CoarseOffer::NoneQualifies(why)) => {
                Ok(took(StaticSolver::Direct, why))
            }
            (_, CoarseOffer::NoLevels) => Err(
                "`integrator.solver` = \"multigrid\" needs the coarser levels of a `[multigrid]` section (`levels`, `nodes` or `files`)".into(),
            ),
            (_, CoarseOffer::NoneQualifies(why)) => {
                Err(format!("`integrator.solver` = \"multigrid\": {why}"))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The `auto` policy: multigrid where a coarse level qualifies, direct where not, Krylov
    /// only without an element tangent; an assembled solver asked for where it cannot run is
    /// an error naming the key, and one asked for where it can runs as asked.
    #[test]
    fn auto_takes_multigrid_then_direct_then_krylov() {
        use StaticSolver::*;
        let none = CoarseOffer::NoneQualifies("too small".into());
        let ok = |asked: StaticSolver, tangent: bool, offer: &CoarseOffer| {
            asked.resolve(tangent, offer).unwrap()
        };
        assert_eq!(
            ok(Auto, true, &CoarseOffer::Qualifies),
            (Multigrid, String::new())
        );
        let (s, why) = ok(Auto, true, &none);
        assert_eq!(s, Direct);
        assert!(why.contains("took \"direct\": too small"), "{why}");
        let (s, why) = ok(Auto, true, &CoarseOffer::NoLevels);
        assert_eq!(s, Direct);
        assert!(why.contains("no [multigrid] levels"), "{why}");
        let (s, why) = ok(Auto, false, &CoarseOffer::Qualifies);
        assert_eq!(s, Krylov);
        assert!(why.contains("no element tangent"), "{why}");
        assert_eq!(ok(Direct, true, &CoarseOffer::Qualifies).0, Direct);
        assert_eq!(ok(Krylov, true, &CoarseOffer::Qualifies).0, Krylov);
        assert_eq!(ok(Multigrid, true, &CoarseOffer::Qualifies).0, Multigrid);
        for (asked, tangent, offer, says) in [
            (
                Direct,
                false,
                CoarseOffer::Qualifies,
                "valid here: \"krylov\" or \"auto\"",
            ),
            (Multigrid, true, none.clone(), "\"multigrid\": too small"),
            (
                Multigrid,
                true,
                CoarseOffer::NoLevels,
                "needs the coarser levels",
            ),
        ] {
            let e = asked.resolve(tangent, &offer).unwrap_err();
            assert!(e.contains("`integrator.solver`") && e.contains(says), "{e}");
        }
    }
}
