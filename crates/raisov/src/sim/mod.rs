//! The library's front door for a host program: a [`Simulation`] that a render or game loop
//! steps once per frame, with grasps, pins and tool forces at run time.
//!
//! ```
//! use raisov::mesh::generate::{box_tets, BoxPattern};
//! use raisov::sim::{Budget, SimulationBuilder};
//!
//! // A 4 cm cube of soft tissue, fixed at its base (z = 0), default material and scheme.
//! let mesh = box_tets([0.04; 3], [3, 3, 3], BoxPattern::Six)?;
//! let mut sim = SimulationBuilder::new(mesh).fix(|p| p[2] <= 0.0).build()?;
//! // Grasp the top face around its centre and lift it by 5 mm over a few frames.
//! let g = sim.grab([0.02, 0.02, 0.05], 0.015)?;
//! let start = sim.grab_position(g)?;
//! sim.move_grab(g, [start[0], start[1], start[2] + 0.005])?;
//! for _ in 0..5 {
//!     let report = sim.step_frame(Budget::Cycles(4));
//!     assert!(report.accepted);
//! }
//! let f = sim.grab_force(g)?;
//! assert!(f[2] < 0.0, "the stretched tissue pulls the tool down: {f:?}");
//! # Ok::<(), raisov::Error>(())
//! ```
//!
//! The default material of [`SimulationBuilder`] is the stable neo-Hookean law
//! ([`crate::material::StableNeoHookean`], E = 5 kPa, ν = 0.45): its energy and forces stay
//! finite when a grasp inverts elements, so the state recovers instead of failing. Scenarios
//! with an `[interactive]` section default to it too (`[material] law`).
//!
//! # Equations and sign conventions
//!
//! The crate's equation of motion ([`crate::fem`]): `M ü + D u̇ + R(u) = V`, `R = ∂E/∂u` the
//! internal force resisting deformation, `V` the external (body and nodal) loads. A
//! constrained node `a` is moved by a constraint force `T_a` (the tool's or the support's
//! force on the tissue): `M_a ü_a + D_a u̇_a + R_a(u) = V_a + T_a`. At rest
//! (`ü = u̇ = 0`), `T_a = R_a(u) − V_a`, and by Newton's third law the tissue pushes on
//! the constraint with `−T_a = V_a − R_a(u)`. So, in newtons:
//!
//! ```text
//! grab_force(g)  = Σ_{a ∈ g} (V_a − R_a(u))       the force the tissue exerts on the tool
//! reactions()_a  =  V_a − R_a(u)                  the force the tissue exerts on support a
//! residual       = max_{a free} |V_a − R_a(u)|    (N), zero at equilibrium
//! ```
//!
//! Lifting a grasped patch stretches the tissue, which pulls the tool back down: `grab_force`
//! points against the displacement. Since `Σ_all R_a = 0` (internal forces are invariant
//! under translation), at equilibrium the constraints take the whole load:
//! `Σ_g grab_force(g) + Σ_a reactions()_a = Σ_all V_a` (gravity and nodal loads), a test.
//! Before equilibrium (a frame that stops early, or explicit dynamics), `V − R` on a
//! constrained row is the quasi-static part of the constraint force: inertia and damping of
//! the constrained nodes themselves are not included.
//!
//! `grab_stiffness(g)` is `K_g = ∂ grab_force / ∂ x_g`, the change of the tool force when
//! the grasp moves rigidly by `δx` and the free nodes return to equilibrium: with `K` the
//! tangent stiffness `∂R/∂u`, `w` the unit rigid move of the grasped nodes along axis `k`
//! (zero elsewhere) and `F` the free dofs,
//!
//! ```text
//! K_FF x = −(K w)_F,     δu = w + x,     column k of K_g = −Σ_{a ∈ g} (K δu)_a,
//! ```
//!
//! three solves with the static solver's assembled tangent (conjugate gradients preconditioned
//! by its Galerkin V-cycle, each warm-started from the grasp's previous solution, or its sparse
//! Cholesky factor: [`tangent::TangentPreconditioner`]; a spring grasp's in series with its
//! springs: [`tangent`]). `K_g` is symmetric negative semi-definite at a stable equilibrium; a haptic loop
//! extrapolates between frames with `f ≈ f_frame + K_g (x_device − x_frame)`: a
//! [`HapticProxy`] ([`haptic`], [`Simulation::haptic_proxy`]) publishes `f_frame`, `K_g`
//! and `x_frame` after every frame for a device thread to read at any rate.
//!
//! # Grasps and pins
//!
//! [`Simulation::grab`] takes the point of the deformed surface nearest `point` (the boundary
//! triangles of a tetrahedral mesh, every triangle of a membrane) and the surface nodes within
//! `radius` of it (at least the nearest one), leaving out nodes that are constrained already.
//! Each grasped node keeps its offset from the grasp point: moving the grasp to `x` holds
//! node `a` at position `x + (x_a − g)`, `g` the grasp point and `x_a` the node's position
//! when grasped (a rigid translation). A hard grasp ([`Coupling::Hard`], the default of
//! [`Simulation::grab`]) prescribes that position; a spring grasp
//! ([`Simulation::grab_with`] and [`Coupling::Spring`], stiffness `k` in N/m) pulls node `a`
//! towards it with a zero-length spring of stiffness `k_a = k m_a / Σ_b m_b` and leaves it
//! free, so the tissue can resist: the springs are forces `S_a` added to `V_a` on level 0, and
//! every coarser level gets, for each of its nodes nearest grasped nodes, one spring of the
//! summed stiffness anchored at their stiffness-weighted mean displacement
//! ([`crate::integrate::RuntimeConstraints::springs`]). The tool force of a spring grasp is
//! the springs' pull, `grab_force = Σ_a k_a (x_a − x − o_a) = k (x̄ − x − ō)` (bars: mass
//! weighted means over the patch), which at equilibrium is `Σ_{a ∈ g} (V_a − R_a(u))` as for
//! a hard grasp, and the balance above holds unchanged. Under explicit dynamics a node spring
//! adds `k_a / m_a` to the squared frequencies: a spring stiffer than the time step allows
//! makes frames diverge (and be rejected), so keep `k_a Δt² / m_a` well below 4. A friction
//! grasp ([`GrabOptions::friction`], [`Grip`]: friction coefficient μ, clamp force N) is a
//! spring grasp whose node springs transmit at most `w_a μ N` (`w_a` the node's mass share):
//! beyond it a spring slides at its limit ([`crate::integrate::Spring`], in the force, energy
//! and tangent every solver sees), and after each accepted frame its anchor moves along the
//! stretch to `l₀ = w_a μ N / k_a` behind the node (the return map of Coulomb's law: the same
//! force, the slide taken), dissipating `w_a μ N (l − l₀)` ([`Simulation::grab_dissipation`]).
//! So `|grab_force| ≤ μ N`, with equality while every node slides the same way. A pin holds its patch where it stands. Grasps are
//! prescribed points of level 0 and pins are fixed regions (each level-0 pinned node carried
//! to the nearest node of every coarser level), taken to the levels by the scheme as it takes
//! the scenario's ([`crate::integrate::RuntimeConstraints`]). A new grasp position takes
//! effect in the next frame.
//!
//! # Frames, borrowing and recovery
//!
//! [`Simulation::step_frame`] runs the stepper for a [`Budget`] (a number of steps, or wall
//! time), warm-started from the last frame. The reads ([`Simulation::positions`],
//! [`Simulation::displacements`], [`Simulation::reactions`], ...) borrow the simulation and
//! hold until the next call that steps or changes constraints. A frame that diverges, produces
//! non-finite values or inverts an element is rejected: the state before the frame is
//! restored and the frame is retried with the grasps moving in 2, 4, ... sub-moves (see
//! [`frame`]); if every try fails the simulation stays at the state before the frame, the
//! grasps where they were, and the [`FrameReport`] says so.
//!
//! # Node order and units
//!
//! Nodes are in the mesh's in-memory order; a scenario may renumber a mesh read from a file
//! ([`Simulation::file_node_ids`] maps back). Everything is SI: metres, newtons, seconds,
//! pascals, kilograms.

mod builder;
mod cut;
pub mod frame;
mod grab;
pub mod haptic;
pub mod overrides;
pub mod tangent;

pub use crate::model::Scheme;
pub use builder::SimulationBuilder;
pub use cut::CutReport;
pub use frame::{Budget, FrameReport};
pub use grab::{Coupling, GrabOptions, Grip};
pub use haptic::{HapticForce, HapticFrame, HapticLimits, HapticProxy};
/// Moved to [`crate::runner::replay`].
#[allow(deprecated)]
#[deprecated(since = "0.2.0", note = "use `raisov::runner::replay`")]
pub mod replay {
    pub use crate::runner::compat::replay_run_interactive as run_interactive;
    pub use crate::runner::Replay;
}
/// Moved to [`mod@crate::runner::solve`].
#[allow(deprecated)]
#[deprecated(since = "0.2.0", note = "use `raisov::runner::solve`")]
pub mod solve {
    pub use crate::runner::compat::solve;
    pub use crate::runner::compat::solve_with;
    pub use crate::runner::Finished;
    pub use crate::runner::Solution;
}
#[allow(deprecated)]
pub use solve::{solve, solve_with, Finished, Solution};
pub use tangent::{TangentPreconditioner, TangentStats};

use crate::fem::{FemModel, ForceModel};
use crate::integrate::{Checkpoint, Stepper};
use crate::mesh::Mesh;
use crate::model::{Model, Stepping};
use crate::scenario::Scenario;
use crate::{Error, Result};
use grab::{Grab, Pin};
use std::collections::BTreeMap;
use std::path::Path;

/// Identifies a grasp of one [`Simulation`] ([`Simulation::grab`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct GrabId(u64);

/// Identifies a pin of one [`Simulation`] ([`Simulation::pin`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct PinId(u64);

/// The forces the tissue exerts on its supports: every constrained node that no grasp holds
/// (fixed regions, prescribed points of a scenario, pins), `V − R(u)` per node (N).
#[derive(Clone, Copy, Debug)]
pub struct Reactions<'a> {
    /// The supported nodes, ascending.
    pub nodes: &'a [u32],
    /// The force on each (N), in the order of `nodes`.
    pub forces: &'a [[f64; 3]],
    /// Their sum (N).
    pub sum: [f64; 3],
}

/// A simulation driven frame by frame (module docs: conventions, borrowing, recovery).
pub struct Simulation {
    stepper: Box<dyn Stepper>,
    mesh: Mesh,
    file_ids: Option<Vec<u32>>,
    /// The simulation's own force model of level 0 (forces, stresses and tangent products
    /// without touching the stepper's).
    model: Box<dyn ForceModel>,
    mass: Vec<f64>,
    f_ext: Vec<f64>,
    /// Level-0 nodes constrained by the stepper's own constraints.
    own: Vec<bool>,
    /// Surface triangles for grasps and pins (boundary faces, or a membrane's triangles).
    surface: Vec<[u32; 3]>,
    grabs: BTreeMap<GrabId, Grab>,
    pins: BTreeMap<PinId, Pin>,
    next_id: u64,
    /// Level-0 nodes constrained now (own, grasped, pinned).
    constrained: Vec<bool>,
    positions: Vec<[f64; 3]>,
    /// `R(u) + Σ_springs k_a (u_a − d_a)` at the current state, 3 per node: the internal
    /// forces minus the springs' pull `S` ([`crate::integrate::System::internal_forces`]).
    r: Vec<f64>,
    /// Level 0's springs of the spring grasps, as the stepper has them.
    springs: Vec<crate::integrate::Spring>,
    residual: f64,
    support_nodes: Vec<u32>,
    support_forces: Vec<[f64; 3]>,
    stress: Option<Vec<[f64; 9]>>,
    checkpoint: Checkpoint,
    /// The frame predictor ([`frame`] module docs), and what it extrapolates: the last
    /// accepted frame's change of level 0's displacements (empty: none), each grasp's move
    /// in that frame, and its grasps.
    predictor: bool,
    last_delta: Vec<f64>,
    last_moves: Vec<[f64; 3]>,
    last_grabs: Vec<GrabId>,
    /// The scenario's prescribed displacements held now (its `[[displace]]` paths from
    /// `t = 0`, in file order), and their move since the last frame: with the grasps' moves,
    /// what the frame predictor extrapolates from.
    prescribed: Vec<[f64; 3]>,
    prescribed_moves: Vec<[f64; 3]>,
    /// A scenario's own run, taking nothing during it (`runner::replay`): the stepper keeps
    /// its kinetic-energy ceiling, and a frame is neither checked at its end nor retried.
    strict: bool,
    /// Retries of a rejected frame (each halving the grasps' sub-moves). Default 4.
    max_retries: u32,
    /// The work of the last `grab_stiffness`.
    tangent_stats: TangentStats,
    /// The preconditioner of `grab_stiffness`'s solves.
    tangent_preconditioner: TangentPreconditioner,
    /// The assembled tangent's structure of `grab_stiffness`, kept while the constraints
    /// stay the same.
    tangent_operator: Option<tangent::TangentOperator>,
    /// The visual surface carried by level 0, when the mesh came from one.
    visual: Option<Visual>,
    /// The haptic proxies attached to grasps, published after every frame.
    haptics: BTreeMap<GrabId, std::sync::Arc<haptic::Shared>>,
    /// The levels as cut so far ([`Simulation::cut`]); `None` before the first cut.
    cuts: Option<cut::CutState>,
    /// The cut body's drawn surface, from the first cut on.
    embedded: Option<cut::Embedded>,
}

/// A visual surface embedded in level 0: `x(p) = p + Σ_j ω_j u_j` over its host element.
struct Visual {
    surface: crate::mesh::Surface,
    transfer: crate::hierarchy::Transfer,
    /// Interpolated displacement, 3 per vertex (scratch).
    u: Vec<f64>,
    positions: Vec<[f64; 3]>,
}

impl Simulation {
    /// Load a scenario file (the TOML format of [`crate::scenario::spec`]) and build its
    /// stepper; the scenario's `[run]`, `[output]` and `[interactive]` sections are not used,
    /// nor the grasps and pins its interactive run takes ([`crate::scenario::grasps`]).
    pub fn from_file(path: impl AsRef<Path>) -> Result<Simulation> {
        Self::from_scenario(&Scenario::load(path.as_ref())?)
    }

    /// Build from scenario text; relative paths in it (mesh files) are taken from `base_dir`.
    ///
    /// ```
    /// let text = r#"
    /// [mesh]
    /// generate = "box"
    /// size = [0.04, 0.04, 0.04]
    /// divisions = [3, 3, 3]
    /// [material]
    /// law = "neo-hookean"
    /// young = 5e3
    /// poisson = 0.45
    /// [[fix]]
    /// plane = { point = [0, 0, 0], normal = [0, 0, 1] }
    /// [run]
    /// duration = 1.0
    /// "#;
    /// let sim = raisov::sim::Simulation::from_toml(text, ".")?;
    /// assert_eq!(sim.positions().len(), 64);
    /// # Ok::<(), raisov::Error>(())
    /// ```
    pub fn from_toml(text: &str, base_dir: impl AsRef<Path>) -> Result<Simulation> {
        let path = base_dir.as_ref().join("scenario.toml");
        Self::from_scenario(&Scenario::from_toml(text, &path)?)
    }

    /// Build from a resolved scenario. The scenario's kinetic-energy ceiling (`[run]
    /// blowup_factor`) is not used: it is set from the loads and prescribed motions and knows
    /// nothing of the work run-time grasps do; a frame is rejected on a non-finite value or an
    /// inverted element instead, as with [`SimulationBuilder`].
    pub fn from_scenario(sc: &Scenario) -> Result<Simulation> {
        Self::with_stepper(sc, sc.stepper()?, false)
    }

    /// [`Simulation::from_scenario`] with the scenario's `stepper`, built already. `strict`:
    /// the scenario's own run, which takes nothing during it (`runner::replay`): the stepper
    /// keeps the scenario's kinetic-energy ceiling, and frames are stepped by
    /// [`Simulation::step_frame_strict`].
    pub(crate) fn with_stepper(
        sc: &Scenario,
        mut stepper: Box<dyn Stepper>,
        strict: bool,
    ) -> Result<Simulation> {
        if !strict {
            stepper.set_kinetic_limit(f64::INFINITY);
        }
        let mut sim = Self::of_model(&sc.model, stepper)?;
        if let Some(i) = &sc.interactive {
            sim.set_predictor(i.predictor);
        }
        sim.strict = strict;
        if let Some(vs) = &sc.surface {
            let transfer = crate::hierarchy::Transfer::build(&vs.surface.points, &sc.mesh)?;
            let nv = vs.surface.points.len();
            sim.visual = Some(Visual {
                surface: vs.surface.clone(),
                transfer,
                u: vec![0.0; 3 * nv],
                positions: vs.surface.points.clone(),
            });
            sim.update_visual();
        }
        Ok(sim)
    }

    /// A simulation of `model` stepped by `scheme` with the step settings `stepping`
    /// ([`Model::stepper`]; the front door both [`SimulationBuilder`] and
    /// [`Simulation::from_scenario`] go through). As there, a frame is rejected on a
    /// non-finite value or an inverted element; the stepper's kinetic-energy ceiling is that of
    /// `stepping` ([`Stepping::blowup_factor`]).
    pub fn from_model(model: &Model, scheme: &Scheme, stepping: &Stepping) -> Result<Simulation> {
        Self::of_model(model, model.stepper(scheme, stepping)?)
    }

    /// A simulation of `model` advanced by `stepper`, built from it: the stepper's level 0 is
    /// the model's mesh, the simulation's own force model (frame forces where the stepper has
    /// none, stress, tangents) carries the same physics and loads.
    pub(crate) fn of_model(model: &Model, stepper: Box<dyn Stepper>) -> Result<Simulation> {
        let mut sim = Self::assemble(
            stepper,
            model.mesh.clone(),
            model.file_ids.clone(),
            model.fem_params(),
        )?;
        // Where the paths start (the stepper holds the prescribed nodes there from rest).
        sim.prescribed = model
            .prescribed
            .iter()
            .map(|(_, m)| m.displacement(0.0))
            .collect();
        sim.prescribed_moves = vec![[0.0; 3]; sim.prescribed.len()];
        if model.has_model_loads() {
            // The stepper's level 0 carries the model's pressure, traction, timed loads and
            // tools in its force model; the simulation's own evaluations carry the same.
            let fem = FemModel::new(&model.mesh, model.fem_params())?;
            let x0 = fem.reference_positions().to_vec();
            sim.model = model.wrap_loads(&model.mesh, x0, Box::new(fem))?;
        }
        Ok(sim)
    }

    /// Carry the visual surface (if any) to the current displacement.
    fn update_visual(&mut self) {
        let u = &self.stepper.state().u;
        if let Some(v) = self.visual.as_mut() {
            if v.transfer.interpolate(u, 3, &mut v.u).is_ok() {
                for (i, p) in v.positions.iter_mut().enumerate() {
                    let x = v.surface.points[i];
                    *p = [
                        x[0] + v.u[3 * i],
                        x[1] + v.u[3 * i + 1],
                        x[2] + v.u[3 * i + 2],
                    ];
                }
            }
        }
    }

    /// The parts every constructor has: a stepper whose level 0 is `mesh`, and a force model
    /// of the same mesh and physics, `params`.
    pub(crate) fn assemble(
        mut stepper: Box<dyn Stepper>,
        mesh: Mesh,
        file_ids: Option<Vec<u32>>,
        params: crate::fem::FemParams,
    ) -> Result<Simulation> {
        let model: Box<dyn ForceModel> = Box::new(FemModel::new(&mesh, params.clone())?);
        let n = mesh.num_nodes();
        let (sys, _) = stepper.finest();
        let f_ext = sys.f_ext.clone();
        let mass = sys.mass.clone();
        let own = (0..n).map(|a| sys.constraints.is_constrained(a)).collect();
        let surface = mesh.surface_triangles();
        let mut sim = Simulation {
            stepper,
            file_ids,
            model,
            mass,
            f_ext,
            constrained: Vec::new(),
            own,
            surface,
            grabs: BTreeMap::new(),
            pins: BTreeMap::new(),
            next_id: 0,
            positions: vec![[0.0; 3]; n],
            r: vec![0.0; 3 * n],
            springs: Vec::new(),
            residual: 0.0,
            support_nodes: Vec::new(),
            support_forces: Vec::new(),
            stress: None,
            checkpoint: Checkpoint::default(),
            predictor: true,
            last_delta: Vec::new(),
            last_moves: Vec::new(),
            last_grabs: Vec::new(),
            prescribed: Vec::new(),
            prescribed_moves: Vec::new(),
            strict: false,
            max_retries: 4,
            tangent_stats: TangentStats::default(),
            tangent_preconditioner: TangentPreconditioner::default(),
            tangent_operator: None,
            mesh,
            visual: None,
            haptics: BTreeMap::new(),
            cuts: None,
            embedded: None,
        };
        sim.constrained = sim.own.clone();
        sim.supports();
        sim.observe().map_err(|f| {
            Error::param(
                "initial state",
                format!(
                    "element {} is inverted (det F = {:.3e})",
                    f.element, f.det_f
                ),
            )
        })?;
        Ok(sim)
    }

    /// Retries of a rejected frame, each halving the grasps' sub-moves (default 4: down to
    /// 16 sub-moves). 0 rejects a failing frame at once.
    pub fn set_max_retries(&mut self, retries: u32) {
        self.max_retries = retries;
    }

    /// Start each frame whose grasps move from the last frame's change, extrapolated
    /// ([`frame`] module docs); on by default (a scenario's `[interactive] predictor`). A
    /// stepper that cannot take a prediction ([`crate::integrate::Stepper::predict`])
    /// ignores it.
    pub fn set_predictor(&mut self, on: bool) {
        self.predictor = on;
        self.last_delta.clear();
    }

    /// Whether frames start from a prediction ([`Simulation::set_predictor`]).
    pub fn predictor(&self) -> bool {
        self.predictor
    }

    /// Retries of a rejected frame ([`Simulation::set_max_retries`]).
    pub fn max_retries(&self) -> u32 {
        self.max_retries
    }

    /// The stepper (for what this API does not cover: its description, diagnostics).
    pub fn stepper(&self) -> &dyn Stepper {
        &*self.stepper
    }

    /// The stepper, to read its finest level after a frame (the runners).
    pub(crate) fn stepper_mut(&mut self) -> &mut dyn Stepper {
        &mut *self.stepper
    }

    /// Hold the scenario's prescribed displacements (its `[[displace]]` paths from `t = 0`,
    /// in file order) at `values` (m) from now on ([`Stepper::hold_prescribed`]); their move
    /// since the last values counts, with the grasps' moves, in the next frame's predictor
    /// ([`frame`] module docs).
    pub(crate) fn hold_prescribed(&mut self, values: &[[f64; 3]]) {
        for ((m, p), v) in self
            .prescribed_moves
            .iter_mut()
            .zip(&mut self.prescribed)
            .zip(values)
        {
            *m = [v[0] - p[0], v[1] - p[1], v[2] - p[2]];
            *p = *v;
        }
        self.stepper.hold_prescribed(values);
    }

    /// Level 0's mesh (reference configuration).
    pub fn mesh(&self) -> &Mesh {
        &self.mesh
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.stepper.state().t
    }

    /// Current node positions `X + u` (m), in the mesh's node order.
    pub fn positions(&self) -> &[[f64; 3]] {
        &self.positions
    }

    /// The surface a viewer draws, at the current state (m): the visual surface's vertices
    /// when the mesh was meshed from a surface (`[mesh] surface`, carried barycentrically by
    /// level 0), else the mesh's own node positions ([`Simulation::positions`]); from the
    /// first cut on ([`Simulation::cut`]), the cut body's surface: the nodes' positions
    /// followed by the wound's embedded vertices. Pair it with
    /// [`Simulation::surface_triangles`], and read both again after a cut.
    pub fn surface_positions(&self) -> &[[f64; 3]] {
        match (&self.embedded, &self.visual) {
            (Some(e), _) => &e.positions,
            (None, Some(v)) => &v.positions,
            (None, None) => &self.positions,
        }
    }

    /// The triangles of [`Simulation::surface_positions`], outward: the visual surface's, or
    /// the mesh's boundary faces (a membrane's own triangles); after a cut, the cut body's
    /// boundary within its material and the wound's faces.
    pub fn surface_triangles(&self) -> &[[u32; 3]] {
        match (&self.embedded, &self.visual) {
            (Some(e), _) => &e.surface.triangles,
            (None, Some(v)) => &v.surface.triangles,
            (None, None) => &self.surface,
        }
    }

    /// Current displacements `u` (m), 3 per node.
    pub fn displacements(&self) -> &[f64] {
        &self.stepper.state().u
    }

    /// Current velocities `u̇` (m/s), 3 per node (zero under the static smoothers of FAS).
    pub fn velocities(&self) -> &[f64] {
        &self.stepper.state().v
    }

    /// The file's id of each node where the scenario renumbered the mesh at load (node `a` is
    /// node `file_node_ids()[a]` of the file), else `None` (the ids are the file's).
    pub fn file_node_ids(&self) -> Option<&[u32]> {
        self.file_ids.as_deref()
    }

    /// Nodal Cauchy stress (Pa, 9 per node, row-major), computed on first call after a step.
    pub fn nodal_stress(&mut self) -> &[[f64; 9]] {
        let n = self.mesh.num_nodes();
        let (model, u) = (&self.model, &self.stepper.state().u);
        self.stress.get_or_insert_with(|| {
            let mut t = vec![0.0; 9 * n];
            model.nodal_stress(u, &mut t);
            t.chunks_exact(9)
                .map(|c| c.try_into().expect("9 entries"))
                .collect()
        })
    }

    /// The largest nodal residual force `|V − R(u)|` over free nodes (N) at the current state.
    pub fn residual(&self) -> f64 {
        self.residual
    }

    /// Forces the tissue exerts on its supports at the current state (module docs).
    pub fn reactions(&self) -> Reactions<'_> {
        let mut sum = [0.0; 3];
        for f in &self.support_forces {
            for k in 0..3 {
                sum[k] += f[k];
            }
        }
        Reactions {
            nodes: &self.support_nodes,
            forces: &self.support_forces,
            sum,
        }
    }

    /// Lumped mass per node (kg), in the mesh's node order.
    pub fn masses(&self) -> &[f64] {
        &self.mass
    }

    /// Total external load `Σ V` (N): gravity and nodal loads.
    pub fn total_load(&self) -> [f64; 3] {
        let mut s = [0.0; 3];
        for f in self.f_ext.chunks_exact(3) {
            for k in 0..3 {
                s[k] += f[k];
            }
        }
        s
    }

    /// After a state change: positions, `R(u) − S(u)`, the residual and the support forces.
    /// Fails (changing nothing but these caches) on an inverted element.
    ///
    /// The forces come from the stepper when its last step ended by evaluating them at the
    /// current state ([`crate::integrate::Stepper::finest_forces`]: FAS with the Chebyshev
    /// smoother, whose last sweep or line search evaluates the fine residual at the state it
    /// returns, and checks it for inversion there); the same model and state give the same
    /// bits, so this only saves one force evaluation per frame. Otherwise they are evaluated
    /// here, which checks the state for inverted elements.
    fn observe(&mut self) -> std::result::Result<(), crate::fem::ElementFailure> {
        self.stress = None;
        let u = &self.stepper.state().u;
        match self.stepper.finest_forces() {
            Some(r) => self.r.copy_from_slice(r),
            None => {
                self.model.set_time(self.stepper.state().t);
                self.model.internal_forces(u, &mut self.r)?;
                for s in &self.springs {
                    let i = 3 * s.node as usize;
                    let f = s.force(u);
                    for k in 0..3 {
                        self.r[i + k] += f[k];
                    }
                }
            }
        }
        for (a, p) in self.positions.iter_mut().enumerate() {
            let x = self.mesh.nodes[a];
            *p = [x[0] + u[3 * a], x[1] + u[3 * a + 1], x[2] + u[3 * a + 2]];
        }
        let mut res = 0.0f64;
        for (a, c) in self.constrained.iter().enumerate() {
            if !c {
                let f = self.net(a);
                res = res.max((f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt());
            }
        }
        self.residual = res;
        for (i, &a) in self.support_nodes.iter().enumerate() {
            self.support_forces[i] = self.net(a as usize);
        }
        self.update_visual();
        if let Some(e) = self.embedded.as_mut() {
            e.update(&self.positions, &self.mesh.cells);
        }
        Ok(())
    }

    /// `V_a + S_a − R_a(u)` of node `a` at the last observed state, `S` the springs' force
    /// (zero but on the nodes of spring grasps).
    fn net(&self, a: usize) -> [f64; 3] {
        let i = 3 * a;
        let (f, r) = (&self.f_ext[i..i + 3], &self.r[i..i + 3]);
        [f[0] - r[0], f[1] - r[1], f[2] - r[2]]
    }

    /// The supported nodes: constrained, not grasped.
    fn supports(&mut self) {
        let mut grasped = vec![false; self.mesh.num_nodes()];
        for g in self.grabs.values() {
            for &a in &g.nodes {
                grasped[a as usize] = true;
            }
        }
        self.support_nodes = (0..self.mesh.num_nodes() as u32)
            .filter(|&a| self.constrained[a as usize] && !grasped[a as usize])
            .collect();
        self.support_forces = vec![[0.0; 3]; self.support_nodes.len()];
    }
}

#[cfg(test)]
mod tests;
