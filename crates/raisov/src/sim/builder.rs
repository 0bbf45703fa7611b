//! [`SimulationBuilder`]: a [`Simulation`] from meshes and physics in code, no scenario file.

use super::Simulation;
use crate::integrate::stability::{lambda_max_bound, step_too_large};
use crate::integrate::Method;
use crate::material::{ranges, Material, StableNeoHookean};
use crate::mesh::Mesh;
use crate::model::select::select_fixed;
use crate::model::{Fixing, ImplicitSolve, Levels, Model, Region, Scheme, Selector, Stepping};
use crate::{Error, Result};
use std::sync::Arc;

/// A fixed region: a predicate on reference positions (m), selected on every level.
type RegionFn = Box<dyn Fn([f64; 3]) -> bool + Send + Sync>;

/// Builds a [`Simulation`] from a mesh (or a hierarchy of meshes) and physics given in code.
///
/// Defaults (SI units): the stable neo-Hookean law ([`StableNeoHookean`]: finite energy and
/// forces for inverted elements, so an interactive grasp that inverts some recovers) with
/// Young's modulus 5 kPa and Poisson ratio 0.45 (soft tissue), density 1000 kg/m³, membrane thickness 1 mm, no gravity, no damping
/// (α = 0 1/s; the quasi-static schemes need none), nothing fixed, [`Scheme::Newton`] (the
/// frame solver) with [`crate::statics::frames::NewtonFramesParams::default`] and the
/// smoother the static solver takes for the mesh's elements (measured against FAS, it keeps
/// the tissue far closer to each frame's equilibrium at a higher frame rate:
/// `bench/RESULTS.md`), the time step half the estimated critical step of each level (for
/// the explicit schemes; [`Scheme::RaisovPaper`] takes level 0's step on every level, as the
/// paper does; its settings' defaults for a mesh are
/// [`crate::multigrid::raisov::RaisovParams::for_mesh`], a scenario's too).
///
/// What it builds is a [`Model`] (the meshes, the physics, the fixed regions as
/// [`Selector::Region`]s selected on every level), stepped by [`Model::stepper`]: the model
/// and the stepper a scenario of the same body gives, to the bits.
///
/// [`SimulationBuilder::build`] checks what a scenario's resolver checks, by the same rules:
/// the material's constants ([`crate::material::ranges`]: Poisson's ratio in (−1, 0.5),
/// ...), and an explicit step ([`Scheme::SingleLevel`], [`Scheme::RaisovPaper`]) given by
/// [`SimulationBuilder::dt`] above twice the estimated critical step
/// ([`crate::integrate::stability::step_too_large`]; a scenario warns, the builder refuses).
///
/// ```
/// use raisov::mesh::generate::{box_tets, BoxPattern};
/// use raisov::sim::{Budget, Scheme, SimulationBuilder};
/// use raisov::integrate::Method;
///
/// let fine = box_tets([0.1, 0.02, 0.02], [10, 2, 2], BoxPattern::Six)?;
/// let coarse = box_tets([0.1, 0.02, 0.02], [5, 1, 1], BoxPattern::Six)?;
/// // A cantilever under gravity, clamped at x = 0, on two levels.
/// let mut sim = SimulationBuilder::new(fine)
///     .levels(vec![coarse])
///     .young_poisson(20e3, 0.4)
///     .gravity([0.0, 0.0, -9.81])
///     .fix(|p| p[0] <= 0.0)
///     .build()?;
/// let report = sim.step_frame(Budget::Cycles(20));
/// assert!(report.accepted && report.cycles == 20);
/// // The tip sags.
/// let tip = sim.positions().iter().map(|p| p[2]).fold(f64::INFINITY, f64::min);
/// assert!(tip < 0.0);
/// // The same mesh with explicit dynamics instead.
/// let mesh = box_tets([0.1, 0.02, 0.02], [10, 2, 2], BoxPattern::Six)?;
/// let dyn_sim = SimulationBuilder::new(mesh)
///     .scheme(Scheme::SingleLevel(Method::SymplecticEuler))
///     .damping(20.0)
///     .fix(|p| p[0] <= 0.0)
///     .build()?;
/// assert!(dyn_sim.stepper().describe().starts_with("single level"));
/// # Ok::<(), raisov::Error>(())
/// ```
pub struct SimulationBuilder {
    mesh: Mesh,
    coarse: Vec<Mesh>,
    material: Material,
    density: f64,
    thickness: f64,
    /// [`SimulationBuilder::thickness`] was called.
    thickness_set: bool,
    gravity: [f64; 3],
    alpha: f64,
    beta: f64,
    fixed: Vec<RegionFn>,
    scheme: Scheme,
    dt: Option<f64>,
    /// The pair [`SimulationBuilder::young_poisson`] was given, checked at build.
    young_poisson: Option<(f64, f64)>,
}

impl SimulationBuilder {
    /// Start from level 0's mesh (reference positions in m), with the defaults above.
    pub fn new(mesh: Mesh) -> Self {
        let smoother = crate::scenario::StaticSolve::default_smoother(mesh.kind);
        SimulationBuilder {
            mesh,
            coarse: Vec::new(),
            material: Material::StableNeoHookean(StableNeoHookean::from_young(5e3, 0.45)),
            density: 1000.0,
            thickness: 1e-3,
            thickness_set: false,
            gravity: [0.0; 3],
            alpha: 0.0,
            beta: 0.0,
            fixed: Vec::new(),
            scheme: Scheme::Newton(crate::statics::frames::NewtonFramesParams {
                smoother,
                ..Default::default()
            }),
            dt: None,
            young_poisson: None,
        }
    }
    /// Coarser levels for the multigrid, next-coarser first (independent meshes of the same
    /// body, not nested; see [`crate::hierarchy`]).
    pub fn levels(mut self, coarse: Vec<Mesh>) -> Self {
        self.coarse = coarse;
        self
    }
    /// The material law; its constants are checked at build ([`Material::validate`]).
    pub fn material(mut self, m: Material) -> Self {
        self.material = m;
        self.young_poisson = None;
        self
    }
    /// The default law (stable neo-Hookean) from Young's modulus (Pa) and Poisson's ratio
    /// (the usual Lamé mapping); [`Self::material`] sets any other law, e.g. the classic
    /// compressible [`crate::material::NeoHookean`]. Checked at build as a scenario's
    /// `young` and `poisson` are ([`ranges::young_poisson`]: E > 0, ν in (−1, 0.5)).
    pub fn young_poisson(mut self, young: f64, poisson: f64) -> Self {
        self.material = Material::StableNeoHookean(StableNeoHookean::from_young(young, poisson));
        self.young_poisson = Some((young, poisson));
        self
    }
    /// Mass density (kg/m³).
    pub fn density(mut self, rho: f64) -> Self {
        self.density = rho;
        self
    }
    /// Membrane thickness (m); refused at build on tetrahedra, as a scenario refuses
    /// `[material] thickness` there.
    pub fn thickness(mut self, h: f64) -> Self {
        self.thickness = h;
        self.thickness_set = true;
        self
    }
    /// Gravity (m/s²).
    pub fn gravity(mut self, g: [f64; 3]) -> Self {
        self.gravity = g;
        self
    }
    /// Mass-proportional damping α (1/s): `D = α M`.
    pub fn damping(mut self, alpha: f64) -> Self {
        self.alpha = alpha;
        self
    }
    /// Stiffness-proportional damping β (s): `D = α M + β K`, `K` frozen at each step's start
    /// ([`crate::statics::implicit`]); [`Scheme::ImplicitEuler`] and [`Scheme::Bdf2`] only.
    pub fn stiffness_damping(mut self, beta: f64) -> Self {
        self.beta = beta;
        self
    }
    /// Fix the nodes whose reference position satisfies `region` (u = 0), on every level.
    pub fn fix(mut self, region: impl Fn([f64; 3]) -> bool + Send + Sync + 'static) -> Self {
        self.fixed.push(Box::new(region));
        self
    }
    /// The scheme.
    pub fn scheme(mut self, s: Scheme) -> Self {
        self.scheme = s;
        self
    }
    /// Level 0's time step (s) instead of half the estimated critical step; an explicit step
    /// above twice the estimate is refused at build.
    pub fn dt(mut self, dt: f64) -> Self {
        self.dt = Some(dt);
        self
    }

    /// Build: a force model and system per level, the correspondences, the stepper.
    /// Errors: a non-positive density, thickness or step, a thickness given for tetrahedra,
    /// negative damping, a material
    /// constant out of its range, an explicit step above twice the estimated critical step,
    /// a fixed region that selects no node on some level, a mesh the force model rejects.
    pub fn build(self) -> Result<Simulation> {
        for (name, v) in [
            ("density", self.density),
            ("thickness", self.thickness),
            ("dt", self.dt.unwrap_or(1.0)),
        ] {
            if !(v > 0.0 && v.is_finite()) {
                return Err(Error::param(name, format!("{v}: must be positive")));
            }
        }
        if self.thickness_set && self.mesh.kind == crate::mesh::ElementKind::Tet4 {
            return Err(Error::param(
                "thickness",
                "applies to membranes (triangle meshes) only; level 0 is tetrahedral",
            ));
        }
        if !(self.alpha >= 0.0 && self.alpha.is_finite()) {
            return Err(Error::param(
                "damping",
                format!("{}: must be >= 0 (1/s)", self.alpha),
            ));
        }
        match self.young_poisson {
            Some((young, poisson)) => {
                ranges::young_poisson(young, poisson)
                    .map_err(|e| Error::param("young_poisson", e.to_string()))?;
            }
            None => self.material.validate(self.mesh.kind)?,
        }
        if matches!(self.material, Material::NeoHookeanVisco(_))
            && matches!(
                self.scheme,
                Scheme::Fas(_) | Scheme::RaisovPaper(_) | Scheme::Newton(_)
            )
        {
            let name = match self.scheme {
                Scheme::Fas(_) => "Scheme::Fas: the multigrid cycles do",
                Scheme::RaisovPaper(_) => "Scheme::RaisovPaper: the multigrid cycles do",
                _ => "Scheme::Newton: the frame solver's quasi-static steps do",
            };
            return Err(Error::param(
                "material",
                format!("neo-hookean-visco does not run on {name} not advance the law's internal variables (use Scheme::ImplicitEuler, which takes the levels as its preconditioner, or Scheme::SingleLevel)"),
            ));
        }
        let method = match &self.scheme {
            Scheme::SingleLevel(m) => *m,
            Scheme::Fas(_)
            | Scheme::RaisovPaper(_)
            | Scheme::ImplicitEuler
            | Scheme::Bdf2
            | Scheme::Newton(_) => Method::SymplecticEuler,
        };
        if self.scheme.implicit().is_some() && self.dt.is_none() {
            return Err(Error::param(
                "dt",
                format!("Scheme::{:?} needs a step: it is stable at any step, so choose it for accuracy (e.g. 1/60 s)", self.scheme),
            ));
        }
        if !(self.beta >= 0.0 && self.beta.is_finite()) {
            return Err(Error::param(
                "stiffness_damping",
                format!("{}: must be >= 0 (s)", self.beta),
            ));
        }
        if self.beta > 0.0 && self.scheme.implicit().is_none() {
            return Err(Error::param(
                "stiffness_damping",
                format!("β = {} s applies to Scheme::ImplicitEuler and Scheme::Bdf2 only (the explicit integrators and FAS take `damping`, D = α M)", self.beta),
            ));
        }
        // The model: what a scenario's resolver would make of the same mesh and physics.
        let kind = self.mesh.kind;
        let mut model = Model::new(self.mesh, self.material.clone(), "SimulationBuilder");
        model.density = self.density;
        model.thickness = self.thickness;
        model.alpha = self.alpha;
        model.gravity = self.gravity;
        if !self.coarse.is_empty() {
            model.levels = Levels::Given(self.coarse);
        }
        if !self.fixed.is_empty() {
            let regions = self.fixed;
            let any = Region(Arc::new(move |p| regions.iter().any(|r| r(p))));
            model.fix = vec![(Selector::Region(any), Fixing::All)];
            model.fixed = select_fixed(&model.mesh, &model.fix, &model.path, "")?.0;
        }
        // Level 0's step: given (an explicit one checked), else half the estimated critical
        // step; a coarser explicit level takes half its own.
        let lambda_max = lambda_max_bound(&model.mesh, &self.material, self.density);
        let critical = method.stability_bound() / lambda_max.sqrt();
        let dt = match self.dt {
            Some(dt) => {
                if let Some(w) =
                    step_too_large(dt, critical, method).filter(|_| self.scheme.explicit_step())
                {
                    return Err(Error::param(
                        "dt",
                        format!("{w} (leave `dt` out to take half the estimate)"),
                    ));
                }
                dt
            }
            None => 0.5 * critical,
        };
        let stepping = Stepping {
            dt,
            safety: 0.5,
            methods: vec![method; model.num_levels()],
            level_dt: None,
            blowup_factor: None,
            implicit: self.scheme.implicit().map(|scheme| ImplicitSolve {
                beta: self.beta,
                ..ImplicitSolve::new(scheme, kind)
            }),
        };
        let stepper = model.stepper(&self.scheme, &stepping)?;
        Simulation::of_model(&model, stepper)
    }
}

#[cfg(test)]
mod tests;
