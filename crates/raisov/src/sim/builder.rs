//! [`SimulationBuilder`]: a [`Simulation`] from meshes and physics in code, no scenario file.

use super::Simulation;
use crate::fem::{FemModel, FemParams};
use crate::hierarchy::{Correspondence, Transfer};
use crate::integrate::{Constraints, Method, SingleLevel, Stepper, StepperParams, System};
use crate::material::{Material, StableNeoHookean};
use crate::mesh::Mesh;
use crate::multigrid::fas::{Fas, FasParams};
use crate::multigrid::Level;
use crate::statics::implicit::{ImplicitEuler, ImplicitParams, ImplicitScheme};
use crate::statics::newton::{coarse_level, MultigridPcg};
use crate::{Error, Result};

/// How the builder's simulation advances.
#[derive(Clone, Debug, PartialEq)]
pub enum Scheme {
    /// The FAS multigrid over the levels ([`crate::multigrid::fas`]): each step is one
    /// V-cycle towards the static equilibrium (one level: the coarsest solve alone).
    Fas(FasParams),
    /// Explicit dynamics on level 0 alone with this integrator, one step per cycle (coarser
    /// levels are ignored).
    SingleLevel(Method),
    /// Backward Euler on level 0 ([`crate::statics::implicit`]), one step per cycle at
    /// [`SimulationBuilder::dt`] (required: any step is stable; choose it for accuracy). With
    /// coarser levels each Newton system is solved by conjugate gradients preconditioned by
    /// the Galerkin V-cycle over level 0 and the coarser level
    /// [`crate::statics::newton::coarse_level`] picks; without, by sparse Cholesky.
    ImplicitEuler,
    /// BDF2 on level 0 ([`crate::statics::implicit::ImplicitScheme::Bdf2`]), otherwise as
    /// [`Scheme::ImplicitEuler`]: second order, far less numerical damping.
    Bdf2,
    /// The frame solver on level 0 ([`crate::statics::frames`]): each step one Newton step
    /// toward the static equilibrium, its conjugate gradients preconditioned by the Galerkin
    /// V-cycle (over level 0 and the coarser level [`crate::statics::newton::coarse_level`]
    /// picks; without one, level 0 factored) of a tangent kept across frames. The default,
    /// with [`crate::statics::frames::NewtonFramesParams::default`] (its smoother the one the
    /// static solver takes for the mesh's elements): measured against FAS, it keeps the tissue
    /// far closer to each frame's equilibrium at a higher frame rate (`bench/RESULTS.md`).
    Newton(crate::statics::frames::NewtonFramesParams),
}

impl Scheme {
    /// The implicit scheme, where this is one.
    fn implicit(&self) -> Option<ImplicitScheme> {
        match self {
            Scheme::ImplicitEuler => Some(ImplicitScheme::BackwardEuler),
            Scheme::Bdf2 => Some(ImplicitScheme::Bdf2),
            _ => None,
        }
    }
}

/// A fixed region: a predicate on reference positions (m), selected on every level.
type Region = Box<dyn Fn([f64; 3]) -> bool>;

/// Builds a [`Simulation`] from a mesh (or a hierarchy of meshes) and physics given in code.
///
/// Defaults (SI units): the stable neo-Hookean law ([`StableNeoHookean`]: finite energy and
/// forces for inverted elements, so an interactive grasp that inverts some recovers) with
/// Young's modulus 5 kPa and Poisson ratio 0.45 (soft tissue), density 1000 kg/m³, membrane thickness 1 mm, no gravity, no damping
/// (α = 0 1/s; the quasi-static schemes need none), nothing fixed, [`Scheme::Newton`] (the
/// frame solver) with its defaults, the time step half the estimated critical step of each
/// level (for the explicit schemes).
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
    gravity: [f64; 3],
    alpha: f64,
    beta: f64,
    fixed: Vec<Region>,
    scheme: Scheme,
    dt: Option<f64>,
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
            gravity: [0.0; 3],
            alpha: 0.0,
            beta: 0.0,
            fixed: Vec::new(),
            scheme: Scheme::Newton(crate::statics::frames::NewtonFramesParams {
                smoother,
                ..Default::default()
            }),
            dt: None,
        }
    }
    /// Coarser levels for the multigrid, next-coarser first (independent meshes of the same
    /// body, not nested; see [`crate::hierarchy`]).
    pub fn levels(mut self, coarse: Vec<Mesh>) -> Self {
        self.coarse = coarse;
        self
    }
    /// The material law.
    pub fn material(mut self, m: Material) -> Self {
        self.material = m;
        self
    }
    /// The default law (stable neo-Hookean) from Young's modulus (Pa) and Poisson's ratio
    /// (the usual Lamé mapping); [`Self::material`] sets any other law, e.g. the classic
    /// compressible [`crate::material::NeoHookean`].
    pub fn young_poisson(mut self, young: f64, poisson: f64) -> Self {
        self.material = Material::StableNeoHookean(StableNeoHookean::from_young(young, poisson));
        self
    }
    /// Mass density (kg/m³).
    pub fn density(mut self, rho: f64) -> Self {
        self.density = rho;
        self
    }
    /// Membrane thickness (m); ignored for tetrahedra.
    pub fn thickness(mut self, h: f64) -> Self {
        self.thickness = h;
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
    pub fn fix(mut self, region: impl Fn([f64; 3]) -> bool + 'static) -> Self {
        self.fixed.push(Box::new(region));
        self
    }
    /// The scheme.
    pub fn scheme(mut self, s: Scheme) -> Self {
        self.scheme = s;
        self
    }
    /// Level 0's time step (s) instead of half the estimated critical step.
    pub fn dt(mut self, dt: f64) -> Self {
        self.dt = Some(dt);
        self
    }

    /// Build: a force model and system per level, the correspondences, the stepper.
    /// Errors: a non-positive density, thickness or step, negative damping, a fixed region
    /// that selects no node on some level, a mesh the force model rejects.
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
        if !(self.alpha >= 0.0 && self.alpha.is_finite()) {
            return Err(Error::param(
                "damping",
                format!("{}: must be >= 0 (1/s)", self.alpha),
            ));
        }
        if matches!(self.material, Material::NeoHookeanVisco(_))
            && matches!(self.scheme, Scheme::Fas(_) | Scheme::Newton(_))
        {
            let name = if matches!(self.scheme, Scheme::Fas(_)) {
                "Scheme::Fas: the multigrid cycles do"
            } else {
                "Scheme::Newton: the frame solver's quasi-static steps do"
            };
            return Err(Error::param(
                "material",
                format!("neo-hookean-visco does not run on {name} not advance the law's internal variables (use Scheme::ImplicitEuler, which takes the levels as its preconditioner, or Scheme::SingleLevel)"),
            ));
        }
        let mut params = FemParams::new(self.material.clone());
        params.density = self.density;
        params.thickness = self.thickness;
        let method = match &self.scheme {
            Scheme::SingleLevel(m) => *m,
            Scheme::Fas(_) | Scheme::ImplicitEuler | Scheme::Bdf2 | Scheme::Newton(_) => {
                Method::SymplecticEuler
            }
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
        let mut meshes = vec![self.mesh.clone()];
        if matches!(self.scheme, Scheme::Fas(_)) {
            meshes.extend(self.coarse.iter().cloned());
        }
        let mut levels = Vec::with_capacity(meshes.len());
        for (l, mesh) in meshes.into_iter().enumerate() {
            let fixed: Vec<u32> = (0..mesh.num_nodes() as u32)
                .filter(|&a| self.fixed.iter().any(|r| r(mesh.nodes[a as usize])))
                .collect();
            if !self.fixed.is_empty() && fixed.is_empty() {
                return Err(Error::param(
                    "fix",
                    format!("the fixed regions select no node of level {l}"),
                ));
            }
            let fem = FemModel::new(&mesh, params.clone())?;
            let mass = fem.lumped_mass();
            let n = mesh.num_nodes();
            let mut sys = System::new(
                Box::new(fem),
                mass,
                self.alpha,
                vec![0.0; 3 * n],
                Constraints::new(fixed, vec![]),
            );
            sys.add_gravity(self.gravity);
            let lambda_max = self.material.stability_modulus(mesh.kind) / self.density
                * crate::fem::gradient_sums(&mesh)
                    .into_iter()
                    .fold(0.0, f64::max);
            let critical = method.stability_bound() / lambda_max.sqrt();
            let dt = match self.dt {
                Some(dt) if l == 0 => dt,
                _ => 0.5 * critical,
            };
            levels.push(Level::new(mesh, sys, method, dt, lambda_max));
        }
        let stepper: Box<dyn Stepper> = match self.scheme {
            Scheme::SingleLevel(m) => {
                let l = levels.pop().expect("one level");
                Box::new(SingleLevel::new(
                    l.sys,
                    m,
                    StepperParams {
                        dt: l.dt,
                        kinetic_limit: f64::INFINITY,
                    },
                ))
            }
            Scheme::ImplicitEuler | Scheme::Bdf2 => {
                let l = levels.pop().expect("one level");
                let mut params = ImplicitParams::new(l.dt);
                params.scheme = self.scheme.implicit().unwrap_or_default();
                params.beta = self.beta;
                let counts: Vec<usize> = std::iter::once(&self.mesh)
                    .chain(&self.coarse)
                    .map(|m| m.num_nodes())
                    .collect();
                let mut down = Vec::new();
                if let Some(c) = coarse_level(&counts) {
                    down.push(Transfer::build(&self.mesh.nodes, &self.coarse[c - 1])?);
                    params.multigrid = Some(MultigridPcg {
                        smoother: crate::scenario::StaticSolve::default_smoother(self.mesh.kind),
                        ..Default::default()
                    });
                }
                Box::new(
                    ImplicitEuler::with_levels(l.sys, params, down)
                        .map_err(|e| Error::param("scheme", e.to_string()))?,
                )
            }
            Scheme::Newton(p) => {
                let l = levels.pop().expect("one level");
                let counts: Vec<usize> = std::iter::once(&self.mesh)
                    .chain(&self.coarse)
                    .map(|m| m.num_nodes())
                    .collect();
                let coarse = coarse_level(&counts).map(|c| self.coarse[c - 1].clone());
                Box::new(crate::statics::frames::NewtonFrames::new(
                    l.sys,
                    self.mesh.clone(),
                    coarse,
                    p,
                )?)
            }
            Scheme::Fas(p) => {
                let mut links = Vec::with_capacity(levels.len() - 1);
                for w in levels.windows(2) {
                    links.push(Correspondence::build(&w[0].mesh, &w[1].mesh)?);
                }
                Box::new(Fas::new(levels, links, p))
            }
        };
        Simulation::assemble(stepper, self.mesh, None, params)
    }
}
