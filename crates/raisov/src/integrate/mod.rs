//! Explicit time integration of
//!
//! ```text
//! M ü + α M u̇ + R(u) = V(t)        (paper eq. 5 with Rayleigh damping D = α M)
//! ```
//!
//! written as the first-order system `X = [u; u̇]`, `Ẋ = [u̇; a(t, u, u̇)]` with
//!
//! ```text
//! a = M⁻¹ (V − R(u)) − α u̇        on free nodes,   a = 0 on constrained nodes
//! ```
//!
//! Constrained nodes (fixed, or with a prescribed displacement g(t)) get `u = g(t)`,
//! `u̇ = ġ(t)` imposed after every step and at every stage time.
//!
//! Integrators (all explicit, one [`Integrator`] interface, no allocation per step):
//! - forward Euler: `u' = u + Δ u̇`, `u̇' = u̇ + Δ a(u, u̇)`; 1 force evaluation;
//! - symplectic Euler: `u̇' = u̇ + Δ a(u, u̇)`, `u' = u + Δ u̇'`; 1 evaluation;
//! - RK4, the paper's (classic fourth order on X); 4 evaluations;
//! - central difference (explicit-FEM standard; `state.v` holds the half-step velocity
//!   `u̇_{n+1/2}`, damping treated by the trapezoidal average of the two half-step velocities):
//!   `u̇_{n+1/2} = [(1 − αΔ/2) u̇_{n−1/2} + Δ M⁻¹(V − R(u_n))] / (1 + αΔ/2)`,
//!   `u_{n+1} = u_n + Δ u̇_{n+1/2}`; 1 evaluation.

mod constraints;
pub mod stability;
mod stepper;

/// Moved to [`crate::statics::newton`] and [`crate::statics::nested`].
#[deprecated(
    since = "0.2.0",
    note = "moved to raisov::statics::newton (and statics::nested)"
)]
pub mod newton_direct {
    pub use crate::statics::nested::*;
    pub use crate::statics::newton::*;
}
/// Moved to [`crate::statics::krylov`].
#[deprecated(since = "0.2.0", note = "moved to raisov::statics::krylov")]
pub mod statics {
    pub use crate::statics::krylov::*;
    pub use crate::statics::relax::fictitious_mass;
}
/// Moved to [`crate::statics::relax::adaptive`].
#[deprecated(since = "0.2.0", note = "moved to raisov::statics::relax::adaptive")]
pub mod adaptive_relax {
    pub use crate::statics::relax::adaptive::*;
}
/// Moved to [`crate::statics::relax::chebyshev`].
#[deprecated(since = "0.2.0", note = "moved to raisov::statics::relax::chebyshev")]
pub mod chebyshev_relax {
    pub use crate::statics::relax::chebyshev::*;
}
/// Moved to [`crate::statics::relax::dynamic`].
#[deprecated(since = "0.2.0", note = "moved to raisov::statics::relax::dynamic")]
pub mod relax {
    pub use crate::statics::relax::dynamic::*;
}
/// Moved to [`crate::linalg::galerkin`].
#[deprecated(since = "0.2.0", note = "moved to raisov::linalg::galerkin")]
pub mod galerkin {
    pub use crate::linalg::galerkin::*;
}
/// Moved to [`crate::linalg::smoother`].
#[deprecated(since = "0.2.0", note = "moved to raisov::linalg::smoother")]
pub mod smoother {
    pub use crate::linalg::smoother::*;
}
/// Moved to [`crate::linalg::coarse_factor`].
#[deprecated(since = "0.2.0", note = "moved to raisov::linalg::coarse_factor")]
pub mod coarse_factor {
    pub use crate::linalg::coarse_factor::*;
}

pub use constraints::{Constraints, Motion};
pub use stepper::{
    check_state, energy_limit, energy_limit_for, hold, moves, prediction, Checkpoint,
    RuntimeConstraints, SingleLevel, Stepper, StepperParams, SwitchCounts,
};
pub(crate) use stepper::{cut_level0, OwnConstraints};

use crate::fem::{ElementFailure, ForceModel};
use rayon::prelude::*;

/// Vector length (dofs) below which the integrators' vector loops run on the calling thread.
const PAR_MIN: usize = 3 * 16_384;
/// Dofs per parallel chunk of those loops.
const PAR_CHUNK: usize = 3 * 4_096;

/// `body(offset, x)` over chunks of `x` (all of it when short), in parallel. Each element is
/// computed alone, so the bits do not depend on the thread count.
fn chunks1(x: &mut [f64], body: impl Fn(usize, &mut [f64]) + Sync) {
    if x.len() < PAR_MIN {
        body(0, x)
    } else {
        x.par_chunks_mut(PAR_CHUNK)
            .enumerate()
            .for_each(|(k, x)| body(k * PAR_CHUNK, x));
    }
}

/// [`chunks1`] over matching chunks of two vectors.
fn chunks2(x: &mut [f64], y: &mut [f64], body: impl Fn(usize, &mut [f64], &mut [f64]) + Sync) {
    if x.len() < PAR_MIN {
        body(0, x, y)
    } else {
        (x.par_chunks_mut(PAR_CHUNK), y.par_chunks_mut(PAR_CHUNK))
            .into_par_iter()
            .enumerate()
            .for_each(|(k, (x, y))| body(k * PAR_CHUNK, x, y));
    }
}

/// [`chunks1`] over matching chunks of four vectors.
fn chunks4(
    x: [&mut [f64]; 4],
    body: impl Fn(usize, &mut [f64], &mut [f64], &mut [f64], &mut [f64]) + Sync,
) {
    let [a, b, c, d] = x;
    if a.len() < PAR_MIN {
        body(0, a, b, c, d)
    } else {
        (
            a.par_chunks_mut(PAR_CHUNK),
            b.par_chunks_mut(PAR_CHUNK),
            c.par_chunks_mut(PAR_CHUNK),
            d.par_chunks_mut(PAR_CHUNK),
        )
            .into_par_iter()
            .enumerate()
            .for_each(|(k, (a, b, c, d))| body(k * PAR_CHUNK, a, b, c, d));
    }
}

/// Which explicit integrator.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Forward (explicit) Euler: `u += Δ v`, `v += Δ a(u, v)`.
    ForwardEuler,
    /// Symplectic (semi-implicit) Euler: `v += Δ a(u, v)`, then `u += Δ v`.
    SymplecticEuler,
    /// Classical fourth-order Runge–Kutta.
    Rk4,
    /// Central differences (leapfrog).
    CentralDifference,
}

impl Method {
    /// Every method, in the order the CLI lists them.
    pub const ALL: [Method; 4] = [
        Method::ForwardEuler,
        Method::SymplecticEuler,
        Method::Rk4,
        Method::CentralDifference,
    ];
    /// The method's name in scenarios and on the command line (kebab-case).
    pub fn name(self) -> &'static str {
        match self {
            Method::ForwardEuler => "forward-euler",
            Method::SymplecticEuler => "symplectic-euler",
            Method::Rk4 => "rk4",
            Method::CentralDifference => "central-difference",
        }
    }
    /// Force evaluations per step.
    pub fn evaluations(self) -> u64 {
        match self {
            Method::Rk4 => 4,
            _ => 1,
        }
    }
    /// Stability limit on `Δ ω_max` for the undamped oscillator: 2 for the symplectic
    /// schemes, 2√2 for RK4; forward Euler is unconditionally unstable undamped and needs
    /// damping (we use the same bound as a nominal value).
    pub fn stability_bound(self) -> f64 {
        match self {
            Method::Rk4 => 2.0 * std::f64::consts::SQRT_2,
            _ => 2.0,
        }
    }
    /// Build the integrator for `n` nodes.
    pub fn build(self, n: usize) -> Box<dyn Integrator> {
        match self {
            Method::ForwardEuler => Box::new(ForwardEuler::new(n)),
            Method::SymplecticEuler => Box::new(SymplecticEuler::new(n)),
            Method::Rk4 => Box::new(Rk4::new(n)),
            Method::CentralDifference => Box::new(CentralDifference::new(n)),
        }
    }
}

/// Displacement and velocity of every node, 3 per node, at time `t`.
#[derive(Clone, Debug, PartialEq)]
pub struct State {
    /// Time (s).
    pub t: f64,
    /// Displacements (m), 3 per node.
    pub u: Vec<f64>,
    /// Velocities (m/s), 3 per node.
    pub v: Vec<f64>,
}

impl State {
    /// `n` nodes at rest at t = 0.
    pub fn at_rest(n: usize) -> Self {
        State {
            t: 0.0,
            u: vec![0.0; 3 * n],
            v: vec![0.0; 3 * n],
        }
    }
}

/// Everything an integrator needs of one mesh level: the force model, lumped mass, damping,
/// external loads and constraints.
pub struct System {
    /// The internal forces `R(u)`.
    pub force: Box<dyn ForceModel>,
    /// Lumped mass per node (kg).
    pub mass: Vec<f64>,
    inv_mass: Vec<f64>,
    /// Mass-proportional damping coefficient α (1/s): D = α M.
    pub alpha: f64,
    /// Constant external force V, 3 per node (N): gravity and nodal loads.
    pub f_ext: Vec<f64>,
    /// Fixed and prescribed nodes.
    pub constraints: Constraints,
    /// Zero-length springs from nodes to anchors (run-time spring grasps,
    /// [`RuntimeConstraints::springs`]): each adds `k (u_a − d)` to `R(u)` in
    /// [`System::acceleration`], [`System::residual`] and [`System::internal_forces`].
    pub springs: Vec<Spring>,
    r: Vec<f64>,
    /// The gravity [`System::add_gravity`] added (m/s²): the part `m g` of `f_ext`.
    gravity: [f64; 3],
}

/// A zero-length spring of stiffness `k` (N/m) pulling node `node` towards the displacement
/// `d` (m), that slides beyond the force `limit` (N; ∞: a linear spring). With the stretch
/// `s = u_node − d`, `l = |s|`, `l₀ = limit / k`, it adds to the node's internal force and to
/// the potential energy
///
/// ```text
/// f = k s,               W = ½ k l²                  (l ≤ l₀: it sticks)
/// f = limit s / l,       W = limit l − ½ limit l₀    (l > l₀: it slides at its limit)
/// ```
///
/// (a convex energy, Huber's), with the tangent `k I` while it sticks and
/// `(limit / l)(I − ŝŝᵀ)` while it slides: the grip of a friction grasp (Coulomb's law on the
/// grasped node, `limit = μ N` its share of the clamp; [`crate::sim::GrabOptions::friction`]),
/// whose anchor the frame loop moves after each accepted frame so that a sliding spring
/// restarts at `l = l₀` with the same force.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spring {
    /// The node.
    pub node: u32,
    /// Stiffness (N/m), ≥ 0.
    pub k: f64,
    /// The anchor's displacement (m): the spring is relaxed at `u_node = d`.
    pub d: [f64; 3],
    /// The largest force it transmits (N, > 0); `f64::INFINITY` for a linear spring.
    pub limit: f64,
}

/// Coulomb friction between a grasper's jaws and the tissue ([`crate::sim::GrabOptions::friction`]): the
/// grasp transmits at most `μ N` (N) before its patch slides, node `a` its mass share
/// `w_a μ N`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grip {
    /// The friction coefficient μ (> 0).
    pub friction: f64,
    /// The clamp force N (N, > 0): the jaws' total normal force on the patch.
    pub clamp: f64,
}

impl Grip {
    /// `μ N` (N).
    pub fn limit(&self) -> f64 {
        self.friction * self.clamp
    }
}

impl Spring {
    /// A linear spring (no limit).
    pub fn linear(node: u32, k: f64, d: [f64; 3]) -> Spring {
        Spring {
            node,
            k,
            d,
            limit: f64::INFINITY,
        }
    }

    /// Whether it slides at `u` (its force would exceed `limit`).
    fn sliding(&self, s: &[f64; 3]) -> Option<f64> {
        if self.limit.is_finite() {
            let l = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
            (self.k * l > self.limit).then_some(l)
        } else {
            None
        }
    }

    fn stretch(&self, u: &[f64]) -> [f64; 3] {
        let i = 3 * self.node as usize;
        [u[i] - self.d[0], u[i + 1] - self.d[1], u[i + 2] - self.d[2]]
    }

    /// Its force on the node at `u` (N, the internal-force sign: `k (u_node − d)` while it
    /// sticks).
    #[inline]
    pub fn force(&self, u: &[f64]) -> [f64; 3] {
        let s = self.stretch(u);
        match self.sliding(&s) {
            None => [self.k * s[0], self.k * s[1], self.k * s[2]],
            Some(l) => {
                let c = self.limit / l;
                [c * s[0], c * s[1], c * s[2]]
            }
        }
    }

    /// Its energy at `u` (J).
    pub fn energy(&self, u: &[f64]) -> f64 {
        let s = self.stretch(u);
        match self.sliding(&s) {
            None => (0..3).map(|k| (s[k]).powi(2)).sum::<f64>() * 0.5 * self.k,
            Some(l) => self.limit * l - 0.5 * self.limit * self.limit / self.k,
        }
    }

    /// Its tangent at `u` (3x3, row-major, N/m).
    pub fn tangent(&self, u: &[f64]) -> [f64; 9] {
        let s = self.stretch(u);
        match self.sliding(&s) {
            None => {
                let k = self.k;
                [k, 0.0, 0.0, 0.0, k, 0.0, 0.0, 0.0, k]
            }
            Some(l) => {
                let c = self.limit / l;
                let n = s.map(|x| x / l);
                let mut t = [0.0; 9];
                for r in 0..3 {
                    for q in 0..3 {
                        t[3 * r + q] = c * (f64::from(u8::from(r == q)) - n[r] * n[q]);
                    }
                }
                t
            }
        }
    }

    /// `K w` for the node's 3 entries of `w`, at `u`.
    pub fn tangent_times(&self, u: &[f64], w: &[f64]) -> [f64; 3] {
        let i = 3 * self.node as usize;
        if !self.limit.is_finite() {
            return [self.k * w[i], self.k * w[i + 1], self.k * w[i + 2]];
        }
        let t = self.tangent(u);
        [0, 1, 2].map(|r| (0..3).map(|q| t[3 * r + q] * w[i + q]).sum())
    }
}

/// `r += f_s(u)` for every spring ([`Spring::force`]).
fn add_springs(springs: &[Spring], u: &[f64], r: &mut [f64]) {
    for s in springs {
        let i = 3 * s.node as usize;
        let f = s.force(u);
        for k in 0..3 {
            r[i + k] += f[k];
        }
    }
}

impl System {
    /// A system of `force`'s nodes with lumped `mass` (kg), damping `alpha` (1/s), loads `f_ext` (N, 3 per node) and `constraints`.
    pub fn new(
        force: Box<dyn ForceModel>,
        mass: Vec<f64>,
        alpha: f64,
        f_ext: Vec<f64>,
        constraints: Constraints,
    ) -> Self {
        let n = force.num_nodes();
        assert_eq!(mass.len(), n);
        assert_eq!(f_ext.len(), 3 * n);
        let inv_mass = mass
            .iter()
            .map(|&m| if m > 0.0 { 1.0 / m } else { 0.0 })
            .collect();
        System {
            force,
            mass,
            inv_mass,
            alpha,
            f_ext,
            constraints: constraints.with_nodes(n),
            springs: Vec::new(),
            r: vec![0.0; 3 * n],
            gravity: [0.0; 3],
        }
    }

    /// Number of nodes.
    pub fn num_nodes(&self) -> usize {
        self.mass.len()
    }

    /// Carry the system to a cut mesh ([`crate::mesh::cut`]): the force model cut
    /// ([`ForceModel::cut`]); the lumped masses rebuilt from the elements' material
    /// fractions, `m_a = ρ Σ_{e ∋ a} f_e |T_e| / 4` with `ρ` the system's mass over its
    /// volume (so the total mass is unchanged); gravity `m_a g` on the new masses and each
    /// nodal load on the first copy of its node; every copy of a constrained node constrained
    /// alike ([`Constraints::carried`]); each spring on the first copy of its node.
    pub fn cut(&mut self, change: &crate::mesh::cut::TopologyChange) -> crate::Result<()> {
        let m = &change.mesh;
        if m.kind != crate::mesh::ElementKind::Tet4 {
            return Err(crate::Error::param(
                "cut",
                "only tetrahedral meshes can be cut",
            ));
        }
        self.force.cut(change)?;
        let n = m.num_nodes();
        let mut share = vec![0.0; n];
        for (el, f) in m.cells.chunks_exact(4).zip(&change.fractions) {
            let p = |i: usize| m.nodes[el[i] as usize];
            let v = 0.25 * f * crate::mesh::tet_volume(p(0), p(1), p(2), p(3));
            for &a in el {
                share[a as usize] += v;
            }
        }
        let (old_mass, old_volume) = (self.mass.iter().sum::<f64>(), share.iter().sum::<f64>());
        let rho = old_mass / old_volume;
        let mass: Vec<f64> = share.iter().map(|v| rho * v).collect();
        let g = self.gravity;
        let mut first = vec![true; self.mass.len()];
        let mut f_ext = vec![0.0; 3 * n];
        for (a, &o) in change.node_from.iter().enumerate() {
            let o = o as usize;
            for k in 0..3 {
                let load = self.f_ext[3 * o + k] - self.mass[o] * g[k];
                f_ext[3 * a + k] = mass[a] * g[k] + if first[o] { load } else { 0.0 };
            }
            first[o] = false;
        }
        let mut first_copy = vec![u32::MAX; self.mass.len()];
        for (a, &o) in change.node_from.iter().enumerate().rev() {
            first_copy[o as usize] = a as u32;
        }
        for s in &mut self.springs {
            s.node = first_copy[s.node as usize];
        }
        self.constraints = self.constraints.carried(&change.node_from);
        self.inv_mass = mass
            .iter()
            .map(|&m| if m > 0.0 { 1.0 / m } else { 0.0 })
            .collect();
        self.mass = mass;
        self.f_ext = f_ext;
        self.r = vec![0.0; 3 * n];
        Ok(())
    }

    /// Add gravity `g` (m/s²) to the external forces: `V += m g` per node.
    pub fn add_gravity(&mut self, g: [f64; 3]) {
        for k in 0..3 {
            self.gravity[k] += g[k];
        }
        for (a, &m) in self.mass.iter().enumerate() {
            for k in 0..3 {
                self.f_ext[3 * a + k] += m * g[k];
            }
        }
    }

    /// `a = M⁻¹ (V − R(u)) − α v` on free nodes, 0 on constrained nodes.
    pub fn acceleration(
        &mut self,
        u: &[f64],
        v: &[f64],
        a: &mut [f64],
    ) -> Result<(), ElementFailure> {
        self.accelerate(u, Some(v), a)
    }

    /// `a = M⁻¹ (V − R(u))` (no damping term), 0 on constrained nodes.
    pub fn elastic_acceleration(&mut self, u: &[f64], a: &mut [f64]) -> Result<(), ElementFailure> {
        self.accelerate(u, None, a)
    }

    /// One force evaluation, one pass over the nodes, constrained nodes zeroed once.
    fn accelerate(
        &mut self,
        u: &[f64],
        v: Option<&[f64]>,
        a: &mut [f64],
    ) -> Result<(), ElementFailure> {
        self.force.internal_forces(u, &mut self.r)?;
        add_springs(&self.springs, u, &mut self.r);
        let (f, r, inv_mass, alpha) = (&self.f_ext, &self.r, &self.inv_mass, self.alpha);
        chunks1(a, |off, a| {
            for (j, aj) in a.iter_mut().enumerate() {
                let i = off + j;
                *aj = (f[i] - r[i]) * inv_mass[i / 3];
                if let Some(v) = v {
                    *aj -= alpha * v[i];
                }
            }
        });
        self.constraints.zero_constrained(a);
        Ok(())
    }

    /// Residual force `V − R(u)` into `out` (zero on constrained nodes); returns its 2-norm.
    pub fn residual(&mut self, u: &[f64], out: &mut [f64]) -> Result<f64, ElementFailure> {
        self.force.internal_forces(u, &mut self.r)?;
        add_springs(&self.springs, u, &mut self.r);
        for i in 0..out.len() {
            out[i] = self.f_ext[i] - self.r[i];
        }
        self.constraints.zero_constrained(out);
        Ok(out.iter().map(|x| x * x).sum::<f64>().sqrt())
    }

    /// `R(u) + Σ_springs k (u_a − d)` (N, all rows) at the state of the last
    /// [`System::residual`], [`System::acceleration`] or [`System::elastic_acceleration`]
    /// (zero before the first); the caller knows which state that was.
    pub fn last_forces(&self) -> &[f64] {
        &self.r
    }

    /// `r = R(u) + Σ_springs k (u_a − d)` (N, all rows).
    pub fn internal_forces(&mut self, u: &[f64], r: &mut [f64]) -> Result<(), ElementFailure> {
        self.force.internal_forces(u, r)?;
        add_springs(&self.springs, u, r);
        Ok(())
    }

    /// Strain energy plus the springs' energy ([`Spring::energy`]: `½ Σ k |u_a − d|²` while they
    /// stick) (J).
    pub fn stored_energy(&self, u: &[f64]) -> f64 {
        let springs: f64 = self.springs.iter().map(|s| s.energy(u)).sum();
        self.force.strain_energy(u) + springs
    }

    /// Kinetic energy ½ Σ m |v|² (J).
    pub fn kinetic_energy(&self, v: &[f64]) -> f64 {
        0.5 * self
            .mass
            .iter()
            .enumerate()
            .map(|(a, m)| {
                m * (v[3 * a] * v[3 * a]
                    + v[3 * a + 1] * v[3 * a + 1]
                    + v[3 * a + 2] * v[3 * a + 2])
            })
            .sum::<f64>()
    }

    /// Impose constrained displacements and velocities at time `t`.
    /// The force model's time-dependent loads and tools are set to time `t` too
    /// ([`ForceModel::set_time`]).
    pub fn impose(&self, t: f64, u: &mut [f64], v: &mut [f64]) {
        self.force.set_time(t);
        self.constraints.impose(t, u, v);
    }
}

/// One explicit integrator. Implementations own their scratch vectors (sized at creation) so
/// a step allocates nothing.
pub trait Integrator: Send {
    /// The method this integrator implements.
    fn method(&self) -> Method;
    /// Advance `state` by `dt`, imposing constraints at `state.t + dt`.
    fn step(&mut self, sys: &mut System, state: &mut State, dt: f64) -> Result<(), ElementFailure>;
}

/// Forward (explicit) Euler.
pub struct ForwardEuler {
    a: Vec<f64>,
}
impl ForwardEuler {
    /// Scratch for `n` nodes.
    pub fn new(n: usize) -> Self {
        ForwardEuler {
            a: vec![0.0; 3 * n],
        }
    }
}
impl Integrator for ForwardEuler {
    fn method(&self) -> Method {
        Method::ForwardEuler
    }
    fn step(&mut self, sys: &mut System, s: &mut State, dt: f64) -> Result<(), ElementFailure> {
        sys.acceleration(&s.u, &s.v, &mut self.a)?;
        let a = &self.a;
        chunks2(&mut s.u, &mut s.v, |off, u, v| {
            for j in 0..u.len() {
                u[j] += dt * v[j];
                v[j] += dt * a[off + j];
            }
        });
        s.t += dt;
        sys.impose(s.t, &mut s.u, &mut s.v);
        Ok(())
    }
}

/// Symplectic (semi-implicit) Euler.
pub struct SymplecticEuler {
    a: Vec<f64>,
}
impl SymplecticEuler {
    /// Scratch for `n` nodes.
    pub fn new(n: usize) -> Self {
        SymplecticEuler {
            a: vec![0.0; 3 * n],
        }
    }
}
impl Integrator for SymplecticEuler {
    fn method(&self) -> Method {
        Method::SymplecticEuler
    }
    fn step(&mut self, sys: &mut System, s: &mut State, dt: f64) -> Result<(), ElementFailure> {
        sys.acceleration(&s.u, &s.v, &mut self.a)?;
        let a = &self.a;
        chunks2(&mut s.u, &mut s.v, |off, u, v| {
            for j in 0..u.len() {
                v[j] += dt * a[off + j];
                u[j] += dt * v[j];
            }
        });
        s.t += dt;
        sys.impose(s.t, &mut s.u, &mut s.v);
        Ok(())
    }
}

/// Classic fourth-order Runge-Kutta on X = [u; v] (the paper's integrator).
pub struct Rk4 {
    us: Vec<f64>,
    vs: Vec<f64>,
    a: Vec<f64>,
    du: Vec<f64>,
    dv: Vec<f64>,
}
impl Rk4 {
    /// Scratch for `n` nodes.
    pub fn new(n: usize) -> Self {
        let z = vec![0.0; 3 * n];
        Rk4 {
            us: z.clone(),
            vs: z.clone(),
            a: z.clone(),
            du: z.clone(),
            dv: z,
        }
    }
}
impl Integrator for Rk4 {
    fn method(&self) -> Method {
        Method::Rk4
    }
    fn step(&mut self, sys: &mut System, s: &mut State, dt: f64) -> Result<(), ElementFailure> {
        let Rk4 { us, vs, a, du, dv } = self;
        // Stage 1 at (t, u, v).
        sys.acceleration(&s.u, &s.v, a)?;
        {
            let (u, v, a) = (&s.u, &s.v, &*a);
            chunks4([du, dv, us, vs], |off, du, dv, us, vs| {
                for j in 0..du.len() {
                    let i = off + j;
                    du[j] = v[i];
                    dv[j] = a[i];
                    us[j] = u[i] + 0.5 * dt * v[i];
                    vs[j] = v[i] + 0.5 * dt * a[i];
                }
            });
        }
        sys.impose(s.t + 0.5 * dt, us, vs);
        // Stages 2 and 3 at t + dt/2, stage 4 at t + dt.
        for (stage, (w, c)) in [(2.0, 0.5), (2.0, 1.0), (1.0, 0.0)].into_iter().enumerate() {
            sys.acceleration(us, vs, a)?;
            let (u, v, a) = (&s.u, &s.v, &*a);
            chunks4([du, dv, us, vs], |off, du, dv, us, vs| {
                for j in 0..du.len() {
                    let i = off + j;
                    let (ki_u, ki_v) = (vs[j], a[i]);
                    du[j] += w * ki_u;
                    dv[j] += w * ki_v;
                    if stage < 2 {
                        us[j] = u[i] + c * dt * ki_u;
                        vs[j] = v[i] + c * dt * ki_v;
                    }
                }
            });
            if stage < 2 {
                sys.impose(s.t + c * dt, us, vs);
            }
        }
        let (du, dv) = (&*du, &*dv);
        chunks2(&mut s.u, &mut s.v, |off, u, v| {
            for j in 0..u.len() {
                u[j] += dt / 6.0 * du[off + j];
                v[j] += dt / 6.0 * dv[off + j];
            }
        });
        s.t += dt;
        sys.impose(s.t, &mut s.u, &mut s.v);
        Ok(())
    }
}

/// Central difference (leapfrog) with half-step velocities.
pub struct CentralDifference {
    a: Vec<f64>,
}
impl CentralDifference {
    /// Scratch for `n` nodes.
    pub fn new(n: usize) -> Self {
        CentralDifference {
            a: vec![0.0; 3 * n],
        }
    }
}
impl Integrator for CentralDifference {
    fn method(&self) -> Method {
        Method::CentralDifference
    }
    fn step(&mut self, sys: &mut System, s: &mut State, dt: f64) -> Result<(), ElementFailure> {
        sys.elastic_acceleration(&s.u, &mut self.a)?;
        let h = 0.5 * sys.alpha * dt;
        let (c0, c1) = ((1.0 - h) / (1.0 + h), dt / (1.0 + h));
        let a = &self.a;
        chunks2(&mut s.u, &mut s.v, |off, u, v| {
            for j in 0..u.len() {
                v[j] = c0 * v[j] + c1 * a[off + j];
                u[j] += dt * v[j];
            }
        });
        s.t += dt;
        sys.impose(s.t, &mut s.u, &mut s.v);
        Ok(())
    }
}

#[cfg(test)]
mod tests;
