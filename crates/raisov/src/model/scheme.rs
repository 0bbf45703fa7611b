//! The one name of a stepper: [`Scheme`], what advances a simulation and its settings, and
//! [`SchemeKind`], the same without settings.
//!
//! Both front doors produce a [`Scheme`]: the scenario resolver from `[multigrid] scheme` and
//! `[integrator] method` ([`crate::scenario::Multigrid::scheme`],
//! [`crate::scenario::Scenario::scheme`]), and [`crate::sim::SimulationBuilder::scheme`] from
//! code. The TOML words of `[multigrid] scheme` name [`SchemeKind`]s
//! ([`crate::scenario::spec`]), and the viewer's protocol maps its wire codes to and from
//! them (`raisov_serve::protocol`).

use crate::integrate::Method;
use crate::multigrid::fas::FasParams;
use crate::multigrid::raisov::RaisovParams;
use crate::statics::frames::NewtonFramesParams;
use crate::statics::implicit::ImplicitScheme;

/// What advances a simulation, with its settings.
///
/// The multigrid schemes ([`Scheme::Fas`], [`Scheme::RaisovPaper`], [`Scheme::Newton`]) are
/// those of `[multigrid] scheme`; the single-level ones those of `[integrator] method`
/// without `[multigrid]` (an explicit integrator) or with its levels as the Newton solver's
/// preconditioner (`"implicit-euler"`, `"bdf2"`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Scheme {
    /// The FAS multigrid over the levels ([`crate::multigrid::fas`], `scheme = "fas"`): each
    /// step is one V-cycle towards the static equilibrium (one level: the coarsest solve
    /// alone).
    Fas(FasParams),
    /// The paper's RaISoV cycle over the levels ([`crate::multigrid::raisov`], `scheme =
    /// "raisov-paper"`): each step one explicit integrator step per level, every level at
    /// level 0's step (a scenario's `[multigrid] level_dt` gives each level its own).
    RaisovPaper(RaisovParams),
    /// The frame solver on level 0 ([`crate::statics::frames`], `scheme = "newton"`): each
    /// step one Newton step toward the static equilibrium, its conjugate gradients
    /// preconditioned by the Galerkin V-cycle (over level 0 and the coarser level
    /// [`crate::statics::newton::coarse_level`] picks; without one, level 0 factored) of a
    /// tangent kept across frames.
    Newton(NewtonFramesParams),
    /// Explicit dynamics on level 0 alone with this integrator, one step per cycle (coarser
    /// levels are not used).
    SingleLevel(Method),
    /// Backward Euler on level 0 ([`crate::statics::implicit`], `method =
    /// "implicit-euler"`), one step per cycle at a step that must be given (any step is
    /// stable; choose it for accuracy). With coarser levels each Newton system is solved by
    /// conjugate gradients preconditioned by the Galerkin V-cycle over level 0 and the coarser
    /// level [`crate::statics::newton::coarse_level`] picks; without, by sparse Cholesky.
    ImplicitEuler,
    /// BDF2 on level 0 ([`ImplicitScheme::Bdf2`], `method = "bdf2"`), otherwise as
    /// [`Scheme::ImplicitEuler`]: second order, far less numerical damping.
    Bdf2,
}

impl Scheme {
    /// The kind of scheme, without its settings.
    pub fn kind(&self) -> SchemeKind {
        match self {
            Scheme::Fas(_) => SchemeKind::Fas,
            Scheme::RaisovPaper(_) => SchemeKind::RaisovPaper,
            Scheme::Newton(_) => SchemeKind::Newton,
            Scheme::SingleLevel(_) => SchemeKind::SingleLevel,
            Scheme::ImplicitEuler => SchemeKind::ImplicitEuler,
            Scheme::Bdf2 => SchemeKind::Bdf2,
        }
    }

    /// The implicit scheme of [`Scheme::ImplicitEuler`] and [`Scheme::Bdf2`]; `None` for the
    /// others.
    pub fn implicit(&self) -> Option<ImplicitScheme> {
        match self {
            Scheme::ImplicitEuler => Some(ImplicitScheme::BackwardEuler),
            Scheme::Bdf2 => Some(ImplicitScheme::Bdf2),
            _ => None,
        }
    }

    /// Whether level 0 is advanced by explicit integrator steps of the given step, so that
    /// the step is bound by the explicit stability limit
    /// ([`crate::integrate::stability::step_too_large`]): [`Scheme::SingleLevel`] and
    /// [`Scheme::RaisovPaper`]. FAS relaxes rather than integrates (its level-0 step is a
    /// smoother's), and the frame solver and the implicit schemes are stable at any step.
    pub fn explicit_step(&self) -> bool {
        matches!(self, Scheme::SingleLevel(_) | Scheme::RaisovPaper(_))
    }
}

/// The kind of a [`Scheme`], without its settings: what `[multigrid] scheme` names, and
/// what the viewer switches between.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SchemeKind {
    /// [`Scheme::Fas`].
    Fas,
    /// [`Scheme::RaisovPaper`].
    RaisovPaper,
    /// [`Scheme::Newton`].
    Newton,
    /// [`Scheme::SingleLevel`].
    SingleLevel,
    /// [`Scheme::ImplicitEuler`].
    ImplicitEuler,
    /// [`Scheme::Bdf2`].
    Bdf2,
}

impl SchemeKind {
    /// Every kind, the multigrid ones first.
    pub const ALL: [SchemeKind; 6] = [
        SchemeKind::Fas,
        SchemeKind::RaisovPaper,
        SchemeKind::Newton,
        SchemeKind::SingleLevel,
        SchemeKind::ImplicitEuler,
        SchemeKind::Bdf2,
    ];

    /// The kinds over a hierarchy of levels: the values of `[multigrid] scheme`.
    pub const MULTIGRID: [SchemeKind; 3] =
        [SchemeKind::Fas, SchemeKind::RaisovPaper, SchemeKind::Newton];

    /// The kind's name: the word of `[multigrid] scheme` (`"fas"`, `"raisov-paper"`,
    /// `"newton"`) or of `[integrator] method` (`"implicit-euler"`, `"bdf2"`);
    /// `"single-level"` for an explicit integrator on one level (which `[integrator] method`
    /// names by the integrator).
    pub fn name(self) -> &'static str {
        match self {
            SchemeKind::Fas => "fas",
            SchemeKind::RaisovPaper => "raisov-paper",
            SchemeKind::Newton => "newton",
            SchemeKind::SingleLevel => "single-level",
            SchemeKind::ImplicitEuler => "implicit-euler",
            SchemeKind::Bdf2 => "bdf2",
        }
    }

    /// Whether the kind runs over a hierarchy of levels (one of [`SchemeKind::MULTIGRID`]).
    pub fn is_multigrid(self) -> bool {
        SchemeKind::MULTIGRID.contains(&self)
    }
}
