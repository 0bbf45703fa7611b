//! The outside peer of `raisov bench frames` (`--case rapier`): the same organ, grasp and path
//! in a FEM soft body of rapier (`rapier3d-f64` 0.36, `SoftBodySolver::Fem`), the Rust
//! engine a Rust user would pick, one rapier step per path frame.
//!
//! The body: level 0 of the case (the finest mesh, one level: rapier has no multigrid) as one
//! soft body, a particle per node with raisov's lumped mass, a cell per tetrahedron, the cell
//! model `SoftBodyCellModel::NeoHookean` with the case's E and ν (rapier takes E and ν and
//! forms the same Lamé μ, λ), no structural edges, volume constraint or shape matching, no
//! collider, no gravity (the benchmark has none). The nodes of the case's fixed cap are pinned
//! particles; the grasp is taken by raisov's own frame loop, so the patch, its nodes and its
//! path are raisov's rows' own ([`raisov::runner::Replay`] drives a [`RapierStepper`]):
//! a rigid grasp's nodes (`rigid`, `node`) are pinned particles moved each frame by
//! `set_particle_kinematic_target` to `X_a + d_a`, `d_a` the displacement the grasp holds
//! node `a` at; a spring grasp (`springs`) is rapier's springs, its edges: rapier's FEM
//! solver gives an edge the energy `½ k (|x_b − x_a| − L)²`, `k = ω² / w` for its natural
//! frequency `ω` and `w` the pair's inverse mass. Each grasped node is tied to three pinned
//! particles (anchors) at `X_a + d_a + L e_i`, `e_i` the axes, `L` = [`ANCHOR_ARM`], by
//! edges of rest length `L`, `ω = √(k_a / m_a)` (so `k = k_a`, the node's mass share of the
//! 200 N/m, as raisov spreads it) and no damping: for a stretch `s` the three give
//! `½ k_a |s|² (1 + O(|s| / L))`, raisov's zero-length spring, with the full tangent `k_a I`
//! (one edge of rest length zero has the tangent `k_a n nᵀ` alone, rapier's Gauss-Newton
//! tangent, and a node near its anchor flips about it from one implicit step to the next).
//!
//! Its solver (`SoftBodySolver::Fem`, rapier's `soft_fem`): implicit Euler, linearised once
//! per substep, `(M + (h² + h β) K) Δv = h f − (h² + h β) K v` with the tangent `K` of the
//! cells' energy (its modes floored at the rest curvature), `β` rapier's Rayleigh damping of
//! the cells (`elastic_damping_ratio` 1, its default), solved by conjugate gradients
//! preconditioned by block Jacobi from zero, to a relative residual or an iteration cap;
//! `s` substeps of `h = Δt / s` per step (`num_solver_iterations`), `Δt = 1/30 s`, the path's
//! frame period, so one step is one frame. The frame's wall time is rapier's work for it: the
//! kinematic targets set, `PhysicsWorld::step` and the positions read back (`fps` from it
//! alone; raisov's own check of the frame's state, a force evaluation, is not counted).
//!
//! Its settings ([`RapierSettings::chosen`]): rapier's defaults (Rayleigh damping of the
//! cells `elastic_damping_ratio` 1, CG `linear_tolerance` 1e-5) but for three knobs, chosen
//! by a rule ([`sweep`]) that judges a setting by its mean lag against rapier's own
//! equilibria (`own lag` below; against raisov's `u*` the lag stops falling at the model
//! difference, whatever rapier does):
//!
//! 1. the particles' linear damping α (rapier's `linear_damping`, `v ← v / (1 + Δt α)` at the
//!    end of each step: mass-proportional damping, raisov's `[damping] alpha`), the one of
//!    0, 3, 10, 30, 100, 300 /s with the smallest lag, at rapier's defaults otherwise (4
//!    substeps, CG ≤ 20): rapier integrates dynamics, and the damping decides how its
//!    slowest modes follow a quasi-static pull (too little: they swing; too much: they creep);
//! 2. the substeps `s` (`num_solver_iterations`), the fewest of 1, 2, 4, 8 whose lag is
//!    within 10 % of the lag with four times as many;
//! 3. the CG cap `c` (`max_linear_iterations`), the smallest of 20, 40, 80, ... 1280 whose
//!    lag is within 10 % of the lag with four times the cap.
//!
//! Steps 2 and 3 give the cheapest setting at which more of rapier's own work no longer
//! buys a smaller lag: its best lag at the least cost (a budget rule, the most it can do in
//! raisov's frame time, would pin it to its cheapest setting wherever that alone takes longer
//! than raisov's frames, and say nothing of its lag). The constants are the rule's outcome
//! on the liver L0, neo-Hookean, rigid grasp, slow path: α = 3 /s, 4 substeps, CG ≤ 20,
//! rapier's defaults and a light damping; every case runs with them. `raisov bench frames
//! --organ liver --case NH,rigid,slow,rapier-sweep` runs the rule on that case (or any
//! other) and prints a row per setting it tries.
//!
//! The law. rapier's neo-Hookean cell is the stable neo-Hookean of Smith et al. 2018 in Kim &
//! Eberle 2020's form without the logarithm, written on the corotated stretch `S = Rᵀ F`
//! (`R` the polar rotation, so `|S|² = I_C = tr C`, `det S = J`):
//!
//! ```text
//! Ψ_rapier = μ/2 (I_C − 3) − μ (J − 1) + (λ + μ)/2 (J − 1)²
//! ```
//!
//! raisov's `neo-hookean` is `W = μ/2 (I_C − 3) − μ ln J + λ/2 (ln J)²` and its
//! `stable-neo-hookean` is Smith et al.'s with `ln(I_C + 1)` and the Lamé map
//! `μ' = 4/3 μ, λ' = λ + 5/6 μ` ([`raisov::material`]): all three agree to second order at
//! rest (the same μ, λ), none equals rapier's beyond it. The lag against raisov's static
//! equilibria `u*` therefore mixes the model difference into the lag; the row is followed by
//! a line that separates the two:
//!
//! - `lag`: `max_a |u_a − u*_a| / max_a |u*_a|` over the free nodes, rapier's frame `u`
//!   against raisov's static equilibrium of the frame (the lag raisov's rows have, by the
//!   same code: [`raisov::runner::run_frames`]);
//! - `own lag`: rapier's frame `u` against `u^R`, rapier's own equilibrium of the frame (its
//!   body run to rest with the frame's grasp held: [`RapierStepper::to_rest`]);
//! - `model`: `u^R` against `u*` (the law and rapier's corotated element against raisov's),
//!   also by [`raisov::runner::run_frames`].
//!
//! Each is the mean and the largest over the frames, as raisov's rows give theirs.

use raisov::integrate::{
    check_state, hold, Checkpoint, Constraints, Motion, RuntimeConstraints, State, Stepper, System,
};
use raisov::material::Material;
use raisov::runner::{run_frames, InteractiveSummary, Replay, RunOptions};
use raisov::scenario::Scenario;
use raisov::{Error, Result};
use rapier3d_f64::prelude::{
    PhysicsWorld, SoftBodyBuilder, SoftBodyCellModel, SoftBodyHandle, SoftBodyMaterial,
    SoftBodySolver, SoftFemParameters, SpringCoefficients, Vector,
};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Instant;

/// What rapier runs a case's frames with: the knobs of the rule ([`sweep`]), its CG tolerance
/// and the step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RapierSettings {
    /// Substeps per step (`IntegrationParameters::num_solver_iterations`).
    pub substeps: usize,
    /// Conjugate-gradient iterations at most per substep
    /// (`SoftFemParameters::max_linear_iterations`).
    pub cg_max: usize,
    /// Relative residual at which the conjugate gradients stop
    /// (`SoftFemParameters::linear_tolerance`).
    pub cg_tol: f64,
    /// Step (s): the frame period.
    pub dt: f64,
    /// The particles' linear damping α (1/s): each step ends with `v ← v / (1 + Δt α)`,
    /// rapier's `linear_damping` (mass-proportional damping, raisov's `[damping] alpha`).
    pub damping: f64,
}

/// rapier's defaults of two of the knobs: 4 substeps, 20 CG iterations.
const DEFAULT_SUBSTEPS: usize = 4;
const DEFAULT_CG: usize = 20;
/// rapier's default CG tolerance.
const DEFAULT_CG_TOL: f64 = 1e-5;

impl RapierSettings {
    /// The settings the rule of the module docs chose.
    pub fn chosen(fps: f64) -> RapierSettings {
        RapierSettings {
            substeps: CHOSEN_SUBSTEPS,
            cg_max: CHOSEN_CG,
            cg_tol: DEFAULT_CG_TOL,
            dt: 1.0 / fps,
            damping: CHOSEN_DAMPING,
        }
    }
    /// rapier's defaults (4 substeps, CG ≤ 20 to 1e-5) at the frame period.
    pub fn defaults(fps: f64) -> RapierSettings {
        RapierSettings {
            substeps: DEFAULT_SUBSTEPS,
            cg_max: DEFAULT_CG,
            cg_tol: DEFAULT_CG_TOL,
            dt: 1.0 / fps,
            damping: 0.0,
        }
    }
    /// The settings in words, for the table.
    pub fn describe(&self) -> String {
        format!(
            "{} substep(s) a frame, CG <= {} iterations to {:.0e}, linear damping {} /s",
            self.substeps, self.cg_max, self.cg_tol, self.damping
        )
    }
}

/// The substeps the rule chose.
const CHOSEN_SUBSTEPS: usize = 4;
/// The CG cap the rule chose.
const CHOSEN_CG: usize = 20;
/// The linear damping the rule chose (1/s).
const CHOSEN_DAMPING: f64 = 3.0;

/// The run to rest of [`RapierStepper::to_rest`]: steps of `REST_DT` (s; implicit Euler at a
/// step far above the body's periods is a Newton step on its static equilibrium), CG to
/// `REST_CG_TOL` within `REST_CG_MAX` iterations, until no node moves by more than
/// `REST_TOL` times the largest displacement in a step, at most `REST_STEPS` steps.
const REST_DT: f64 = 100.0;
const REST_CG_TOL: f64 = 1e-8;
const REST_CG_MAX: usize = 2000;
const REST_TOL: f64 = 1e-6;
const REST_STEPS: usize = 200;

/// What a [`RapierStepper`] records for its caller, frame by frame (a frame starts where the
/// frame loop saves the state, [`Stepper::save`], once at the start of each).
#[derive(Clone, Debug, Default)]
pub struct RapierRecord {
    /// Per frame: the wall time of rapier's work (s).
    pub wall: Vec<f64>,
    /// Per frame: the displacements after it (m, 3 per node).
    pub u: Vec<Vec<f64>>,
    /// Per frame of a run to rest: the steps it took and whether it met its rule.
    pub rest: Vec<(usize, bool)>,
    /// The free nodes (neither fixed, held nor prescribed) of the last frame.
    pub free: Vec<bool>,
}

/// The arm of a spring grasp's anchors (m): far against any stretch, so the three edges of a
/// node are its zero-length spring to a relative `|s| / L` (module docs).
pub const ANCHOR_ARM: f64 = 100.0;

/// The rapier world of a [`RapierStepper`]: one soft body, its particles the mesh's nodes
/// then three anchors per spring.
struct World {
    world: PhysicsWorld,
    body: SoftBodyHandle,
    /// The nodes of the springs, in order (the anchors of spring `j` are particles
    /// `n + 3 j + i`, along axis `i`).
    spring_nodes: Vec<u32>,
    /// Whether each mesh node's particle is pinned now.
    pinned: Vec<bool>,
}

/// A [`Stepper`] that steps the case in rapier (module docs): raisov's system and state of
/// level 0 for the frame loop's reference and checks, rapier's soft body for the steps.
pub struct RapierStepper {
    mesh: raisov::mesh::Mesh,
    sys: System,
    state: State,
    /// The system's own constraints (fixed, prescribed): the runtime ones are added to them.
    own_fixed: Vec<u32>,
    own_prescribed: Vec<(u32, Motion)>,
    young: f64,
    poisson: f64,
    settings: RapierSettings,
    /// Run each frame to rest ([`RapierStepper::to_rest`]) instead of one step.
    rest: bool,
    world: Option<World>,
    steps: u64,
    /// The state [`Stepper::save`] saved (it takes `&self`), for [`Stepper::restore`].
    saved: Mutex<Option<(State, u64)>>,
    record: Arc<Mutex<RapierRecord>>,
}

/// Lock a record whatever a panicking holder left (it holds plain numbers).
fn lock<T>(r: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    r.lock().unwrap_or_else(PoisonError::into_inner)
}

fn v3(p: [f64; 3]) -> Vector {
    Vector::new(p[0], p[1], p[2])
}

impl RapierStepper {
    /// A stepper of `sc`'s level 0 in rapier; with `rest`, each frame runs the body to rest.
    /// Errors, naming what rapier's peer does not carry: a mesh of other elements than
    /// tetrahedra, a law other than neo-Hookean and stable neo-Hookean, loads (gravity, nodal
    /// loads, pressures, tools), sliding supports, damping.
    pub fn new(
        sc: &Scenario,
        settings: RapierSettings,
        rest: bool,
    ) -> Result<(RapierStepper, Arc<Mutex<RapierRecord>>)> {
        let key = "rapier peer";
        if sc.mesh.kind != raisov::mesh::ElementKind::Tet4 {
            return Err(Error::param(
                key,
                "the mesh is of triangles: rapier's FEM soft body takes tetrahedra",
            ));
        }
        let (young, poisson) = match &sc.material {
            Material::NeoHookean(m) => young_poisson(m.lambda, m.mu),
            Material::StableNeoHookean(m) => young_poisson(m.lame_lambda, m.lame_mu),
            _ => {
                return Err(Error::param(
                    key,
                    "the law is neither neo-hookean nor stable-neo-hookean: rapier's FEM \
                     soft body has one hyperelastic law, a stable neo-Hookean",
                ))
            }
        };
        if sc.has_model_loads() || sc.gravity != [0.0; 3] || !sc.loads.is_empty() {
            return Err(Error::param(
                key,
                "the case has loads (gravity, [[load]], pressure, traction or tools): the \
                 rapier peer carries supports and grasps only",
            ));
        }
        if !sc.sliding.is_empty() {
            return Err(Error::param(
                key,
                "the case has sliding supports: rapier pins whole particles (use fixed ones)",
            ));
        }
        if sc.alpha != 0.0 {
            return Err(Error::param(
                key,
                "the case has [damping]: the rapier peer runs with rapier's own damping",
            ));
        }
        if settings.substeps == 0
            || settings.cg_max == 0
            || !(settings.dt > 0.0)
            || !(settings.damping >= 0.0)
        {
            return Err(Error::param(
                key,
                format!(
                    "substeps {}, CG cap {}, step {} s, damping {} /s: give at least one \
                     substep and one CG iteration, a positive step and a damping >= 0",
                    settings.substeps, settings.cg_max, settings.dt, settings.damping
                ),
            ));
        }
        let sys = sc.build_system()?;
        let n = sc.mesh.num_nodes();
        let mut state = State::at_rest(n);
        sys.impose(0.0, &mut state.u, &mut state.v);
        let record = Arc::new(Mutex::new(RapierRecord::default()));
        Ok((
            RapierStepper {
                mesh: sc.mesh.clone(),
                own_fixed: sys.constraints.fixed.clone(),
                own_prescribed: sys.constraints.prescribed.clone(),
                sys,
                state,
                young,
                poisson,
                settings,
                rest,
                world: None,
                steps: 0,
                saved: Mutex::new(None),
                record: record.clone(),
            },
            record,
        ))
    }

    /// The rapier world for the current constraints, its body at rest at the mesh's nodes
    /// and then moved to the current state.
    fn build(&self) -> World {
        let mesh = &self.mesh;
        let n = mesh.num_nodes();
        let mut positions: Vec<Vector> = mesh.nodes.iter().map(|&p| v3(p)).collect();
        let mut masses = self.sys.mass.clone();
        let pinned = self.pinned_mask();
        let mut pinned_ids: Vec<u32> = (0..n as u32).filter(|&a| pinned[a as usize]).collect();
        let spring_nodes: Vec<u32> = self.sys.springs.iter().map(|s| s.node).collect();
        let mut edges = Vec::with_capacity(spring_nodes.len());
        let mut softness = Vec::with_capacity(spring_nodes.len());
        for s in &self.sys.springs {
            let a = s.node as usize;
            // rapier's edge stiffness is ω² / w with w the pair's inverse mass, 1 / m_a here.
            let omega = (s.k / self.sys.mass[a]).sqrt();
            for i in 0..3 {
                let anchor = positions.len() as u32;
                // The anchors start at their rest length from the node at rest.
                positions.push(v3(anchor_at(mesh.nodes[a], [0.0; 3], i)));
                masses.push(self.sys.mass[a]);
                pinned_ids.push(anchor);
                softness.push((
                    edges.len() as u32,
                    SpringCoefficients::new(omega / std::f64::consts::TAU, 0.0),
                ));
                edges.push([s.node, anchor]);
            }
        }
        let cells: Vec<[u32; 4]> = mesh
            .cells
            .chunks_exact(4)
            .map(|c| [c[0], c[1], c[2], c[3]])
            .collect();
        let material = SoftBodyMaterial {
            young_modulus: self.young,
            poisson_ratio: self.poisson,
            ..Default::default()
        };
        let mut builder = SoftBodyBuilder::new(positions)
            .masses(masses)
            .cells(cells)
            .edges(edges)
            .cell_model(SoftBodyCellModel::NeoHookean)
            .solver(SoftBodySolver::Fem)
            .material(material)
            .pinned_particles(pinned_ids)
            .no_surface_collider()
            .gravity_scale(0.0)
            .linear_damping(self.settings.damping)
            .can_sleep(false);
        builder.edge_softness = softness;
        let mut world = PhysicsWorld::new();
        world.gravity = Vector::ZERO;
        configure(&mut world, &self.settings, false);
        let body = world.insert_soft_body(builder);
        let mut w = World {
            world,
            body,
            spring_nodes,
            pinned,
        };
        self.teleport(&mut w);
        w
    }

    /// The mesh nodes held by a constraint (fixed or prescribed).
    fn pinned_mask(&self) -> Vec<bool> {
        let n = self.sys.num_nodes();
        (0..n)
            .map(|a| self.sys.constraints.is_constrained(a))
            .collect()
    }

    /// The body moved to the current state: the particles at `X + u` with velocity `v`
    /// (the pinned ones without a velocity: they follow their targets).
    fn teleport(&self, w: &mut World) {
        let mesh = &self.mesh;
        let body = &mut w.world.soft_bodies[w.body];
        let u = &self.state.u;
        for (a, x) in mesh.nodes.iter().enumerate() {
            let p = [x[0] + u[3 * a], x[1] + u[3 * a + 1], x[2] + u[3 * a + 2]];
            body.set_particle_position(a, v3(p));
            if !w.pinned[a] {
                let v = &self.state.v[3 * a..3 * a + 3];
                body.set_particle_velocity(a, Vector::new(v[0], v[1], v[2]));
            }
        }
        for (j, s) in self.sys.springs.iter().enumerate() {
            for i in 0..3 {
                let p = anchor_at(mesh.nodes[s.node as usize], s.d, i);
                body.set_particle_position(mesh.num_nodes() + 3 * j + i, v3(p));
            }
        }
    }

    /// The world, built (again) where the springs changed since; the pinned particles set
    /// to the current constraints.
    fn world(&mut self) -> &mut World {
        let springs: Vec<u32> = self.sys.springs.iter().map(|s| s.node).collect();
        if self
            .world
            .as_ref()
            .is_none_or(|w| w.spring_nodes != springs)
        {
            self.world = Some(self.build());
        }
        let pinned = self.pinned_mask();
        let w = self.world.as_mut().expect("built above");
        if w.pinned != pinned {
            let body = &mut w.world.soft_bodies[w.body];
            for (a, (&now, was)) in pinned.iter().zip(w.pinned.iter_mut()).enumerate() {
                if now != *was {
                    body.set_particle_pinned(a, now);
                    *was = now;
                }
            }
        }
        w
    }

    /// The pinned particles' targets at the end of the coming step: each prescribed node at
    /// `X + d(t + Δt)`, each spring's anchors at `X + d + L e_i`.
    fn set_targets(&mut self, t: f64) {
        let mesh = &self.mesh;
        let Some(w) = self.world.as_mut() else {
            return;
        };
        let body = &mut w.world.soft_bodies[w.body];
        for (a, m) in &self.sys.constraints.prescribed {
            let x = mesh.nodes[*a as usize];
            let d = m.displacement(t);
            body.set_particle_kinematic_target(
                *a as usize,
                v3([x[0] + d[0], x[1] + d[1], x[2] + d[2]]),
            );
        }
        for (j, s) in self.sys.springs.iter().enumerate() {
            for i in 0..3 {
                let p = anchor_at(mesh.nodes[s.node as usize], s.d, i);
                body.set_particle_kinematic_target(mesh.num_nodes() + 3 * j + i, v3(p));
            }
        }
    }

    /// The state read back from the body: `u = x − X`, `v`; returns the largest nodal move
    /// since the last read (m).
    fn read_back(&mut self) -> f64 {
        let mesh = &self.mesh;
        let Some(w) = self.world.as_ref() else {
            return 0.0;
        };
        let body = &w.world.soft_bodies[w.body];
        let mut moved = 0.0f64;
        for (a, x) in mesh.nodes.iter().enumerate() {
            let p = body.particle_position(a);
            let v = body.particle_velocity(a);
            let u = [p.x - x[0], p.y - x[1], p.z - x[2]];
            let d = [
                u[0] - self.state.u[3 * a],
                u[1] - self.state.u[3 * a + 1],
                u[2] - self.state.u[3 * a + 2],
            ];
            moved = moved.max((d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt());
            self.state.u[3 * a..3 * a + 3].copy_from_slice(&u);
            self.state.v[3 * a..3 * a + 3].copy_from_slice(&[v.x, v.y, v.z]);
        }
        moved
    }

    /// One frame: the targets at `t + Δt`, one rapier step, the state read back; the wall
    /// time of the three (s).
    fn one_step(&mut self) -> f64 {
        let t = self.state.t + self.settings.dt;
        // Building the world (once, or where the springs changed) is set-up, not the frame.
        self.world();
        let start = Instant::now();
        self.set_targets(t);
        if let Some(w) = self.world.as_mut() {
            w.world.step();
        }
        self.read_back();
        let wall = start.elapsed().as_secs_f64();
        self.state.t = t;
        wall
    }

    /// The frame's grasp held, the body run to rest: implicit Euler steps of 100 s from zero
    /// velocity (each a Newton step on rapier's static equilibrium with the frame's targets,
    /// CG to 1e-8 within 2000 iterations), until no node moves by more than 1e-6 of the
    /// largest displacement in a step, at most 200 steps. Returns the steps and whether the
    /// rule was met.
    pub fn to_rest(&mut self) -> (usize, bool) {
        let t = self.state.t + self.settings.dt;
        let settings = self.settings;
        configure(&mut self.world().world, &settings, true);
        let mut done = (REST_STEPS, false);
        for k in 1..=REST_STEPS {
            self.set_targets(t);
            if let Some(w) = self.world.as_mut() {
                w.world.step();
                let body = &mut w.world.soft_bodies[w.body];
                for a in 0..w.pinned.len() {
                    if !w.pinned[a] {
                        body.set_particle_velocity(a, Vector::ZERO);
                    }
                }
            }
            let moved = self.read_back();
            let largest = self
                .state
                .u
                .chunks_exact(3)
                .map(|d| (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt())
                .fold(0.0f64, f64::max);
            if k > 1 && moved <= REST_TOL * largest {
                done = (k, true);
                break;
            }
        }
        self.state.v.fill(0.0);
        self.state.t = t;
        configure(&mut self.world().world, &settings, false);
        done
    }
}

/// The world's step, substeps and CG: those of `settings` for a frame, or those of the run to
/// rest ([`RapierStepper::to_rest`]).
fn configure(world: &mut PhysicsWorld, settings: &RapierSettings, rest: bool) {
    let ip = &mut world.integration_parameters;
    // No extra substeps on impacts (there are none: no collider).
    ip.soft_bodies.max_extra_substeps = 0;
    let (dt, substeps, linear_tolerance, max_linear_iterations) = if rest {
        (REST_DT, 1, REST_CG_TOL, REST_CG_MAX)
    } else {
        (
            settings.dt,
            settings.substeps,
            settings.cg_tol,
            settings.cg_max,
        )
    };
    ip.dt = dt;
    ip.num_solver_iterations = substeps;
    ip.soft_bodies.fem = SoftFemParameters {
        linear_tolerance,
        max_linear_iterations,
        ..Default::default()
    };
}

/// Anchor `i` of a spring of node `x` pulling towards the displacement `d`: `x + d + L e_i`.
fn anchor_at(x: [f64; 3], d: [f64; 3], i: usize) -> [f64; 3] {
    let mut p = [x[0] + d[0], x[1] + d[1], x[2] + d[2]];
    p[i] += ANCHOR_ARM;
    p
}

/// E and ν of the Lamé parameters λ, μ.
fn young_poisson(lambda: f64, mu: f64) -> (f64, f64) {
    (
        mu * (3.0 * lambda + 2.0 * mu) / (lambda + mu),
        lambda / (2.0 * (lambda + mu)),
    )
}

impl Stepper for RapierStepper {
    fn advance(&mut self) -> std::result::Result<(), raisov::error::Divergence> {
        let (wall, rest) = if self.rest {
            let start = Instant::now();
            let r = self.to_rest();
            (start.elapsed().as_secs_f64(), Some(r))
        } else {
            (self.one_step(), None)
        };
        self.steps += 1;
        {
            let mut r = lock(&self.record);
            let k = r.wall.len().saturating_sub(1);
            if r.wall.is_empty() {
                r.wall.push(0.0);
                r.u.push(Vec::new());
            }
            r.wall[k] += wall;
            r.u[k].clone_from(&self.state.u);
            if let Some(rest) = rest {
                if r.rest.len() <= k {
                    r.rest.resize(k + 1, (0, true));
                }
                r.rest[k] = rest;
            }
            r.free = self.pinned_mask().iter().map(|p| !p).collect();
        }
        check_state(&self.sys, &self.state, self.steps, f64::INFINITY)
    }
    fn finest(&mut self) -> (&mut System, &State) {
        (&mut self.sys, &self.state)
    }
    fn steps(&self) -> u64 {
        self.steps
    }
    fn force_evaluations(&self) -> f64 {
        0.0
    }
    fn dt(&self) -> f64 {
        self.settings.dt
    }
    fn describe(&self) -> String {
        format!(
            "rapier3d-f64 0.36 FEM soft body (SoftBodySolver::Fem: implicit Euler, stable \
             neo-Hookean cells), level 0 only, {}",
            if self.rest {
                "each frame run to rest".to_string()
            } else {
                self.settings.describe()
            }
        )
    }
    fn hold_prescribed(&mut self, values: &[[f64; 3]]) {
        hold(&mut self.sys.constraints, values);
        let k = self.own_prescribed.len().min(values.len());
        for ((_, m), &d) in self.own_prescribed[..k].iter_mut().zip(values) {
            *m = Motion::Held { d };
        }
    }
    fn state(&self) -> &State {
        &self.state
    }
    /// The held nodes become prescribed (pinned particles moved to their targets), the
    /// pinned ones held where they stand, the springs tie anchors to their nodes; nodes
    /// constrained already keep their constraint (as raisov's steppers do).
    fn set_runtime_constraints(&mut self, c: &RuntimeConstraints) {
        let n = self.sys.num_nodes();
        let mut taken = vec![false; n];
        for &a in &self.own_fixed {
            taken[a as usize] = true;
        }
        let mut prescribed = self.own_prescribed.clone();
        for (a, _) in &prescribed {
            taken[*a as usize] = true;
        }
        for &(a, d) in &c.held {
            if (a as usize) < n && !std::mem::replace(&mut taken[a as usize], true) {
                prescribed.push((a, Motion::Held { d }));
            }
        }
        for &a in c.pinned.first().map_or(&[][..], |p| &p[..]) {
            let i = a as usize;
            if i < n && !std::mem::replace(&mut taken[i], true) {
                let u = &self.state.u;
                prescribed.push((
                    a,
                    Motion::Held {
                        d: [u[3 * i], u[3 * i + 1], u[3 * i + 2]],
                    },
                ));
            }
        }
        self.sys.constraints = Constraints::new(self.own_fixed.clone(), prescribed).with_nodes(n);
        self.sys.springs = c.springs_of(0).to_vec();
        let t = self.state.t;
        self.sys.impose(t, &mut self.state.u, &mut self.state.v);
    }
    /// Saved here (the checkpoint's writer is raisov's own); the frame loop saves once at the
    /// start of each frame: a new frame of the record.
    fn save(&self, _cp: &mut Checkpoint) {
        *lock(&self.saved) = Some((self.state.clone(), self.steps));
        let mut r = lock(&self.record);
        r.wall.push(0.0);
        r.u.push(self.state.u.clone());
    }
    fn restore(&mut self, _cp: &Checkpoint) {
        let saved = lock(&self.saved).clone();
        if let Some((state, steps)) = saved {
            self.state = state;
            self.steps = steps;
            if let Some(mut w) = self.world.take() {
                self.teleport(&mut w);
                self.world = Some(w);
            }
        }
    }
    fn set_kinetic_limit(&mut self, _limit: f64) {}
}

/// What [`peer`] measured on a case.
#[derive(Clone, Debug)]
pub struct PeerRun {
    /// The settings it ran with.
    pub settings: RapierSettings,
    /// The frame loop's summary: the lag against raisov's static equilibria.
    pub summary: InteractiveSummary,
    /// Per frame, rapier's wall time (s).
    pub wall: Vec<f64>,
    /// Mean and largest over the frames of the lag against rapier's own equilibria,
    /// `max_a |u_a − u^R_a| / max_a |u^R_a|` over the free nodes.
    pub own_mean: f64,
    pub own_max: f64,
}

impl PeerRun {
    /// Frames per second of rapier's wall time, and without the slowest frame.
    pub fn fps(&self) -> (f64, f64) {
        let total: f64 = self.wall.iter().sum();
        let slowest = self.wall.iter().copied().fold(0.0, f64::max);
        let n = self.wall.len() as f64;
        (
            n / total,
            if n > 1.0 {
                (n - 1.0) / (total - slowest)
            } else {
                f64::NAN
            },
        )
    }
}

/// rapier's own equilibria of a case's frames ([`rest`]).
#[derive(Clone, Debug)]
pub struct Rest {
    /// The frame loop's summary of the run to rest: the lag of rapier's equilibria against
    /// raisov's (the model difference, module docs).
    pub summary: InteractiveSummary,
    /// Per frame, `u^R` (m, 3 per node).
    pub u: Vec<Vec<f64>>,
    /// The free nodes.
    pub free: Vec<bool>,
    /// Frames whose run to rest missed its rule, and the mean steps one took.
    pub unsettled: usize,
    pub mean_steps: f64,
}

fn in_memory() -> RunOptions<'static> {
    RunOptions {
        in_memory: true,
        ..Default::default()
    }
}

/// rapier's own equilibrium of every frame of `sc` ([`RapierStepper::to_rest`]), through
/// raisov's frame loop (its lag against raisov's static equilibria: the model difference).
pub fn rest(sc: &Scenario) -> Result<Rest> {
    let fps = sc.interactive.map_or(30.0, |i| i.fps);
    let (stepper, record) = RapierStepper::new(sc, RapierSettings::chosen(fps), true)?;
    let mut replay = Replay::new(sc, Box::new(stepper))?;
    let summary = run_frames(sc, &mut replay, in_memory())?;
    let r = lock(&record).clone();
    Ok(Rest {
        summary,
        u: r.u,
        free: r.free,
        unsettled: r.rest.iter().filter(|x| !x.1).count(),
        mean_steps: r.rest.iter().map(|x| x.0 as f64).sum::<f64>() / r.rest.len().max(1) as f64,
    })
}

/// Run `sc` (an interactive case of the frame benchmark) in rapier with `settings`: its
/// frames through raisov's frame loop (the lag against raisov's static equilibria), and the
/// lag of each against rapier's own equilibrium of the frame, `rest` ([`rest`] of `sc`).
pub fn peer(sc: &Scenario, settings: RapierSettings, rest: &Rest) -> Result<PeerRun> {
    let (stepper, record) = RapierStepper::new(sc, settings, false)?;
    let mut replay = Replay::new(sc, Box::new(stepper))?;
    let summary = run_frames(sc, &mut replay, in_memory())?;
    let frames = lock(&record).clone();
    let (mut sum, mut max, mut count) = (0.0, 0.0f64, 0usize);
    for (u, ur) in frames.u.iter().zip(&rest.u) {
        if u.len() != ur.len() || u.is_empty() {
            continue;
        }
        let rel = lag_rel(u, ur, &rest.free);
        sum += rel;
        max = max.max(rel);
        count += 1;
    }
    Ok(PeerRun {
        settings,
        summary,
        wall: frames.wall,
        own_mean: if count > 0 {
            sum / count as f64
        } else {
            f64::NAN
        },
        own_max: if count > 0 { max } else { f64::NAN },
    })
}

/// `max_a |u_a − r_a|` over the nodes `free` marks, over `max_a |r_a|` over all.
fn lag_rel(u: &[f64], r: &[f64], free: &[bool]) -> f64 {
    let norm = |x: &[f64]| (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt();
    let (mut lag, mut scale) = (0.0f64, 0.0f64);
    for a in 0..u.len() / 3 {
        let (ua, ra) = (&u[3 * a..3 * a + 3], &r[3 * a..3 * a + 3]);
        scale = scale.max(norm(ra));
        if free.get(a).copied().unwrap_or(true) {
            lag = lag.max(norm(&[ua[0] - ra[0], ua[1] - ra[1], ua[2] - ra[2]]));
        }
    }
    lag / scale.max(f64::MIN_POSITIVE)
}

/// The rule of the module docs on `sc` (`rest`: [`rest`] of `sc`), by the mean lag against
/// rapier's own equilibria: the linear damping (of 0, 3, 10, 30, 100, 300 /s) with the
/// smallest lag at rapier's defaults otherwise; then the fewest substeps (of 1, 2, 4, 8)
/// whose lag is within 10 % of the lag with four times as many (at rapier's default CG cap);
/// then the smallest CG cap (of 20, 40, 80, ... 1280) whose lag is within 10 % of the lag at
/// four times the cap. `report` gets every run, in the order run. Returns the settings
/// chosen (the largest of a ladder where none qualifies).
pub fn sweep(
    sc: &Scenario,
    rest: &Rest,
    report: &mut dyn FnMut(&PeerRun),
) -> Result<RapierSettings> {
    let fps = sc.interactive.map_or(30.0, |i| i.fps);
    let mut cache: Vec<(RapierSettings, f64)> = Vec::new();
    let mut lag = |settings: RapierSettings, report: &mut dyn FnMut(&PeerRun)| -> Result<f64> {
        if let Some((_, l)) = cache.iter().find(|(s, _)| *s == settings) {
            return Ok(*l);
        }
        let run = peer(sc, settings, rest)?;
        report(&run);
        cache.push((settings, run.own_mean));
        Ok(run.own_mean)
    };
    let mut chosen = RapierSettings::defaults(fps);
    let mut best = f64::INFINITY;
    for &alpha in &DAMPINGS {
        let l = lag(
            RapierSettings {
                damping: alpha,
                ..RapierSettings::defaults(fps)
            },
            report,
        )?;
        if l < best {
            best = l;
            chosen.damping = alpha;
        }
    }
    // Each budget knob in turn: the first rung within WITHIN of the lag at 4× the rung.
    let knobs: [(&[usize], Knob); 2] = [
        (&SUBSTEPS, |s| &mut s.substeps),
        (&CG_CAPS, |s| &mut s.cg_max),
    ];
    for (ladder, knob) in knobs {
        for (i, &rung) in ladder.iter().enumerate() {
            *knob(&mut chosen) = rung;
            let here = lag(chosen, report)?;
            let mut more = chosen;
            *knob(&mut more) = 4 * rung;
            if here <= WITHIN * lag(more, report)? || i + 1 == ladder.len() {
                break;
            }
        }
    }
    Ok(chosen)
}

/// A budget knob of [`RapierSettings`] that [`sweep`] climbs.
type Knob = fn(&mut RapierSettings) -> &mut usize;

/// The ladders of [`sweep`] and its margin.
const DAMPINGS: [f64; 6] = [0.0, 3.0, 10.0, 30.0, 100.0, 300.0];
const SUBSTEPS: [usize; 4] = [1, 2, 4, 8];
const CG_CAPS: [usize; 7] = [20, 40, 80, 160, 320, 640, 1280];
const WITHIN: f64 = 1.1;

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    /// A 4 cm cube of the benchmark's tissue (E = 5 kPa, ν = 0.45, ρ = 1060) on a 4×4×4 box
    /// of tetrahedra, fixed at its base, its top grasped at frame 1 (`grasp`: the
    /// `[[displace]]` keys of the grasp) and pulled by `pull` (m) over 0.2 s, then held
    /// 0.2 s, 30 frames a second.
    fn cube(grasp: &str, pull: [f64; 3]) -> Scenario {
        let [x, y, z] = pull;
        let text = format!(
            r#"
[mesh]
generate = "box"
size = [0.04, 0.04, 0.04]
divisions = [4, 4, 4]
[material]
law = "neo-hookean"
young = 5000.0
poisson = 0.45
density = 1060.0
[[fix]]
plane = {{ point = [0, 0, 0], normal = [0, 0, 1] }}
[[displace]]
point = [0.02, 0.02, 0.04]
start = 0.0
{grasp}
mode = "table"
table = [[0.0, 0.0, 0.0, 0.0], [0.2, {x:?}, {y:?}, {z:?}], [0.4, {x:?}, {y:?}, {z:?}]]
[run]
duration = 0.4
[interactive]
fps = 30.0
cycles = 1
"#
        );
        Scenario::from_toml(&text, Path::new("rapier-peer-test.toml")).unwrap()
    }

    /// The coupling: the grasped nodes sit on the path (`X + d(t_k)` to rounding) and the
    /// fixed base does not move, every frame; the free nodes follow the pull.
    #[test]
    fn held_nodes_follow_the_path_and_fixed_ones_stay() {
        let pull = [0.0, 0.002, 0.004];
        let sc = cube("radius = 0.012", pull);
        let settings = RapierSettings::chosen(30.0);
        let (stepper, record) = RapierStepper::new(&sc, settings, false).unwrap();
        let mut replay = Replay::new(&sc, Box::new(stepper)).unwrap();
        let fps = 30.0;
        let frames = 12;
        let motion = &sc.grasps[0].motion;
        for k in 1..=frames {
            use raisov::runner::FrameStepper;
            let t = k as f64 / fps;
            assert_eq!(replay.frame(k, t, &[]).unwrap(), None, "frame {k}");
            let d = motion.displacement(t);
            let (sys, state) = replay.stepper().finest();
            let held: Vec<u32> = sys.constraints.prescribed.iter().map(|(a, _)| *a).collect();
            assert!(held.len() >= 5, "the patch holds {} nodes", held.len());
            for &a in &held {
                let u = &state.u[3 * a as usize..3 * a as usize + 3];
                for c in 0..3 {
                    assert!(
                        (u[c] - d[c]).abs() <= 1e-12,
                        "frame {k}, node {a}: {u:?} vs {d:?}"
                    );
                }
            }
            for &a in &sys.constraints.fixed {
                assert_eq!(&state.u[3 * a as usize..3 * a as usize + 3], &[0.0; 3]);
            }
        }
        // The body follows: the free nodes moved up, none further than the grasp.
        let r = lock(&record).clone();
        let u = r.u.last().unwrap();
        let free_max = (0..u.len() / 3)
            .filter(|&a| r.free[a])
            .map(|a| u[3 * a + 2])
            .fold(f64::MIN, f64::max);
        assert!(free_max > 0.2 * pull[2] && free_max < pull[2], "{free_max}");
        assert_eq!(r.wall.len(), frames);
    }

    /// The physics: held at its base and pulled by 0.2 mm at its top (strains of a few
    /// thousandths, where rapier's law and raisov's neo-Hookean agree to first order), rapier
    /// run to rest on each frame lands within 1 % (of the largest displacement) of raisov's
    /// static equilibrium, the same on the frames held at the end; rapier's own frames are
    /// dynamic and lag behind it, and its lag against its own rest is what the frames add.
    #[test]
    fn rest_matches_raisovs_equilibrium_at_small_strain() {
        let sc = cube("radius = 0.012", [0.0, 0.0, 2e-4]);
        let rest = rest(&sc).unwrap();
        let run = peer(&sc, RapierSettings::chosen(30.0), &rest).unwrap();
        eprintln!(
            "lag {:.3e}/{:.3e}, own {:.3e}/{:.3e}, model {:.3e}/{:.3e}, rest steps {}",
            run.summary.lag_rel_mean(),
            run.summary.lag_rel_max,
            run.own_mean,
            run.own_max,
            rest.summary.lag_rel_mean(),
            rest.summary.lag_rel_max,
            rest.mean_steps,
        );
        assert_eq!(rest.unsettled, 0);
        assert_eq!(rest.summary.reference_failures, 0);
        assert!(
            rest.summary.lag_rel_max < 0.01,
            "{}",
            rest.summary.lag_rel_max
        );
        assert!(run.own_max < 1.0 && run.own_mean > 0.0);
        assert_eq!(run.wall.len(), 12);
    }

    /// A spring grasp: each grasped node is tied to its anchor by rapier's edge of stiffness
    /// k_a (its mass share of the total); at rest the spring pull balances the tissue as in
    /// raisov's static equilibrium with the same springs.
    #[test]
    fn spring_grasp_rests_at_raisovs_equilibrium() {
        let sc = cube("radius = 0.012\nstiffness = 200.0", [0.0, 0.0, 2e-4]);
        let rest = rest(&sc).unwrap();
        eprintln!(
            "springs: model {:.3e}/{:.3e}",
            rest.summary.lag_rel_mean(),
            rest.summary.lag_rel_max
        );
        assert_eq!(rest.unsettled, 0);
        assert!(
            rest.summary.lag_rel_max < 0.01,
            "{}",
            rest.summary.lag_rel_max
        );
    }

    /// What rapier's peer does not carry is refused, naming it.
    #[test]
    fn refuses_what_it_cannot_carry() {
        let mut sc = cube("radius = 0.012", [0.0, 0.0, 2e-4]);
        sc.gravity = [0.0, 0.0, -9.81];
        let e = RapierStepper::new(&sc, RapierSettings::chosen(30.0), false)
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("rapier peer") && e.contains("gravity"), "{e}");
        let sc = cube("radius = 0.012", [0.0, 0.0, 2e-4]);
        let bad = RapierSettings {
            substeps: 0,
            ..RapierSettings::chosen(30.0)
        };
        let e = RapierStepper::new(&sc, bad, false)
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("substeps 0"), "{e}");
    }
}
