//! Rigid analytic tools (sphere, plane, capsule) moving along a path, in penalty contact with
//! the nodes of the body, frictionless or with regularised Coulomb friction.
//!
//! A tool is a rigid shape translated by `d(t)` (a [`Motion`]: held, ramp, table or a time
//! function times a vector). For a node at `x = X + u` its signed distance `φ(x)` (positive
//! outside the tool) and outward unit normal `n(x)` are
//!
//! ```text
//! sphere  (centre c, radius r):        φ = |x − c| − r,            n = (x − c)/|x − c|
//! plane   (point p, unit normal m):    φ = (x − p)·m,               n = m   (the tool is φ < 0)
//! capsule (segment a–b, radius r):     q = a + clamp((x−a)·(b−a)/|b−a|², 0, 1)(b − a),
//!                                      φ = |x − q| − r,            n = (x − q)/|x − q|
//! ```
//!
//! with `c, p, a, b` moved by `d(t)`. A penetrating node (`φ < 0`) feels the penalty force
//!
//! ```text
//! f_a = −k φ n,        energy ½ k φ²
//! ```
//!
//! (normal only without friction). The penalty is part of the force model ([`Contact`] wraps
//! one: its internal force is `R(u) − F_tools(u, t)`, its energy `E(u) + Σ ½ k φ²`), so
//! explicit integrators, the FAS multigrid (each level with its own nodes in contact) and the
//! static Newton solve (its finite-difference tangent includes the penalty stiffness) all see
//! it. The contact force reported is `F_tool = Σ_a f_a`, the force the tool exerts on the body;
//! at equilibrium `F_fixed + F_prescribed + F_tool + Σ V = 0` ([`crate::metrics`]).
//!
//! Friction ([`Friction`]: static and kinetic coefficients `μ_s ≥ μ_k`, tangential stiffness
//! `k_t`; the scenario's default `k_t = k`) adds to a penetrating node's normal force
//! `N = k |φ|` a tangential force from a stick spring to an anchor `z` in the tool's frame,
//! with a return map (regularised Coulomb law, details in [`friction`]):
//!
//! ```text
//! s_t = (I − n nᵀ)(x − z − d(t))                     slip vector (N as last committed)
//! stick  k_t |s_t| ≤ μ N:   f_t = −k_t s_t           (μ = μ_s, or μ_k while slipping)
//! slip   k_t |s_t| > μ N:   f_t = −μ_k N s_t/|s_t|,   and on commit z moves along s_t until
//!                           k_t |s_t| = μ_k N; the energy μ_k N |Δz| is dissipated
//! ```
//!
//! The anchors are path dependent: they are committed once per accepted step
//! ([`ForceModel::accept_step`]: explicit steps, backward Euler steps; the multigrid steppers
//! commit every level), saved in checkpoints ([`ForceModel::save_history`]), and between two
//! commits every force evaluation uses the same committed anchors. Scenarios give friction to
//! the finest level only (coarse levels' tools are frictionless: backward Euler's levels only
//! precondition its Newton solve) and refuse it for static solves and the explicit multigrid
//! schemes, whose iterations are not steps of the tool's path. A node entering contact is
//! anchored where it stands at the commit (it carries no friction force before); one leaving
//! contact loses its anchor. `F_tool` includes the friction force; `F_friction = Σ_a f_t` is
//! reported on its own. The friction spring's energy (`½ k_t |s_t|²`, continued linearly in
//! slip) is part of the model's energy with the normal force held; the tangent adds
//! `k_t (I − n nᵀ)` per stuck node, `μ_k N/|s_t| (I − n nᵀ − ŝ ŝᵀ)` per slipping one.
//!
//! Penalty stiffness: default `k = 4 M ℓ̄`, `M` the material's stability modulus
//! ([`crate::material::Material::stability_modulus`], 3K for solids: the stiffest small-strain
//! mode of an element) and `ℓ̄` the mean edge length of the mesh the tool acts on. The
//! contact spring's frequency `√(k/m_a)` then stays well below the mesh's highest elastic
//! frequency (measured on a 6³-cell neo-Hookean block, ν = 0.4: about 0.45 of it, which raises
//! the highest frequency by about 10 %; the default `dt`, half the estimated critical step,
//! keeps its margin). A node pressed by a force `F` penetrates `|F|/k`: the penetration
//! tolerance is the user's choice of `k` (`stiffness`, N/m; a stiffer one needs a smaller
//! `dt` with explicit integrators).

//!
//! The `contact_pressure` field of frames ([`nominal_pressure`]) is the nominal contact
//! pressure `p_a = |f_a| / A_a` (Pa), `A_a` the node's tributary area on the reference
//! boundary: a third of every boundary triangle (tetrahedral meshes) or element (membranes)
//! it is a corner of.

pub mod friction;

pub use friction::Friction;

use crate::fem::loads::LoadReport;
use crate::fem::{ElementFailure, ForceModel};
use crate::geometry::{add, dot, sub};
use crate::mesh::{ElementKind, Mesh};
use crate::time::Motion;
use std::sync::atomic::{AtomicU64, Ordering};

/// Each node's tributary area on the reference boundary (m²): a third of the area of every
/// boundary triangle (tets) or element (membranes) it is a corner of; zero inside.
pub fn tributary_areas(mesh: &Mesh) -> Vec<f64> {
    let mut area = vec![0.0; mesh.num_nodes()];
    let tris: Vec<[u32; 3]> = match mesh.kind {
        ElementKind::Tet4 => mesh.boundary_facets(),
        ElementKind::Tri3 => mesh.elements().map(|e| [e[0], e[1], e[2]]).collect(),
    };
    for t in tris {
        let [a, b, c] = t.map(|i| mesh.nodes[i as usize]);
        let third = crate::mesh::tri_area(a, b, c) / 3.0;
        for i in t {
            area[i as usize] += third;
        }
    }
    area
}

/// The nominal contact pressure per node (Pa): `|f_a| / A_a` for the nodal contact forces
/// `f` (3 per node, N) and the tributary areas of [`tributary_areas`]; zero where `A_a = 0`.
pub fn nominal_pressure(forces: &[f64], areas: &[f64], out: &mut [f64]) {
    for ((p, f), &a) in out.iter_mut().zip(forces.chunks_exact(3)).zip(areas) {
        let m = (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
        *p = if a > 0.0 { m / a } else { 0.0 };
    }
}

/// The shape of a rigid tool in its reference position (m).
#[derive(Clone, Debug, PartialEq)]
pub enum ToolShape {
    /// A ball: `φ = |x − center| − radius`.
    Sphere {
        /// Centre c (m).
        center: [f64; 3],
        /// Radius r (m).
        radius: f64,
    },
    /// The tool occupies `(x − point)·normal < 0`; `normal` is a unit vector.
    Plane {
        /// A point p of the plane (m).
        point: [f64; 3],
        /// Unit normal m, pointing out of the tool.
        normal: [f64; 3],
    },
    /// The points within `radius` of the segment a–b: `φ = |x − q| − radius`, `q` the
    /// segment's point nearest x.
    Capsule {
        /// One end of the axis (m).
        a: [f64; 3],
        /// The other end of the axis (m).
        b: [f64; 3],
        /// Radius r (m).
        radius: f64,
    },
}

/// A rigid tool: its shape, its translation `d(t)` and its penalty stiffness `k` (N/m).
#[derive(Clone, Debug, PartialEq)]
pub struct Tool {
    /// The shape at `d = 0`.
    pub shape: ToolShape,
    /// The translation `d(t)` (m) of every point of the shape.
    pub motion: Motion,
    /// Penalty stiffness k (N/m): a node penetrating by `−φ` feels `−k φ n`.
    pub stiffness: f64,
    /// Coulomb friction; `None`: frictionless.
    pub friction: Option<Friction>,
}

/// Distance and normal from the nearest point `q` of a core (point or segment) of radius `r`.
fn round(x: [f64; 3], q: [f64; 3], r: f64) -> Option<(f64, [f64; 3])> {
    let v = sub(x, q);
    let l = dot(v, v).sqrt();
    if l >= r {
        return None;
    }
    // A node exactly on the core has no normal; push it along +z.
    let n = if l > 0.0 {
        v.map(|c| c / l)
    } else {
        [0.0, 0.0, 1.0]
    };
    Some((l - r, n))
}

impl ToolShape {
    /// `(φ, n)` of a point `x` inside the shape translated by `d` (see the module
    /// documentation); `None` outside (φ ≥ 0).
    pub fn penetration(&self, x: [f64; 3], d: [f64; 3]) -> Option<(f64, [f64; 3])> {
        match self {
            ToolShape::Sphere { center, radius } => round(x, add(*center, d), *radius),
            ToolShape::Plane { point, normal } => {
                let phi = dot(sub(x, add(*point, d)), *normal);
                (phi < 0.0).then_some((phi, *normal))
            }
            ToolShape::Capsule { a, b, radius } => {
                let (a, b) = (add(*a, d), add(*b, d));
                let ab = sub(b, a);
                let l2 = dot(ab, ab);
                let s = if l2 > 0.0 {
                    (dot(sub(x, a), ab) / l2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                round(x, add(a, ab.map(|c| c * s)), *radius)
            }
        }
    }
}

impl ToolShape {
    /// The Hessian of `½ φ²` at a point `x` inside the shape translated by `d`,
    /// `∇φ ∇φᵀ + φ ∇²φ` with `∇φ = n` (module docs): a plane's `n nᵀ`; a sphere's (and a
    /// capsule's caps') `n nᵀ + φ (I − n nᵀ) / ρ`, `ρ = |x − q|`; a capsule's side,
    /// `n nᵀ + φ (I − t tᵀ − n nᵀ) / ρ` with `t` its unit axis. At `ρ = 0` the curvature
    /// term is left out. `None` outside.
    pub fn penetration_hessian(&self, x: [f64; 3], d: [f64; 3]) -> Option<[[f64; 3]; 3]> {
        let (phi, n) = self.penetration(x, d)?;
        let mut h = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                h[i][j] = n[i] * n[j];
            }
        }
        let (rho, axis) = match self {
            ToolShape::Plane { .. } => return Some(h),
            ToolShape::Sphere { .. } => (phi + self.radius(), None),
            ToolShape::Capsule { a, b, .. } => {
                let (a, b) = (add(*a, d), add(*b, d));
                let ab = sub(b, a);
                let l2 = dot(ab, ab);
                let s = if l2 > 0.0 {
                    dot(sub(x, a), ab) / l2
                } else {
                    0.0
                };
                let side = l2 > 0.0 && s > 0.0 && s < 1.0;
                let t = ab.map(|c| c / l2.sqrt());
                (phi + self.radius(), side.then_some(t))
            }
        };
        if rho > 0.0 {
            for i in 0..3 {
                for j in 0..3 {
                    let id = if i == j { 1.0 } else { 0.0 };
                    let tt = axis.map_or(0.0, |t| t[i] * t[j]);
                    h[i][j] += phi * (id - tt - n[i] * n[j]) / rho;
                }
            }
        }
        Some(h)
    }

    /// The radius of a sphere or capsule (0 for a plane).
    fn radius(&self) -> f64 {
        match self {
            ToolShape::Sphere { radius, .. } | ToolShape::Capsule { radius, .. } => *radius,
            ToolShape::Plane { .. } => 0.0,
        }
    }
}

impl Tool {
    /// The penalty's stiffness blocks `k ∇²(½ φ²)` (3 × 3, row-major) of the nodes `x0 + u`
    /// inside the tool at time `t`, each handed to `add(node, block)`, nodes ascending.
    pub fn add_tangent(
        &self,
        x0: &[f64],
        u: &[f64],
        t: f64,
        factor: f64,
        add: &mut dyn FnMut(&[u32], &[f64]),
    ) {
        let d = self.offset(t, factor);
        let k = self.stiffness;
        for (a, (p, w)) in x0.chunks_exact(3).zip(u.chunks_exact(3)).enumerate() {
            let x = [p[0] + w[0], p[1] + w[1], p[2] + w[2]];
            if let Some(h) = self.shape.penetration_hessian(x, d) {
                let mut block = [0.0; 9];
                for i in 0..3 {
                    for j in 0..3 {
                        block[3 * i + j] = k * h[i][j];
                    }
                }
                add(&[a as u32], &block);
            }
        }
    }

    /// The translation at time `t` scaled by `factor` (static increments).
    pub fn offset(&self, t: f64, factor: f64) -> [f64; 3] {
        self.motion.displacement(t).map(|c| c * factor)
    }

    /// Add the penalty forces on the nodes `x0 + u` at time `t` into `f` (3 per node);
    /// returns the penalty energy (J), the net force on the body (N) and the deepest
    /// penetration (m).
    pub fn add_forces(
        &self,
        x0: &[f64],
        u: &[f64],
        t: f64,
        factor: f64,
        f: &mut [f64],
    ) -> (f64, [f64; 3], f64) {
        let d = self.offset(t, factor);
        let k = self.stiffness;
        let (mut e, mut net, mut pen) = (0.0, [0.0; 3], 0.0f64);
        for (a, (p, w)) in x0.chunks_exact(3).zip(u.chunks_exact(3)).enumerate() {
            let x = [p[0] + w[0], p[1] + w[1], p[2] + w[2]];
            if let Some((phi, n)) = self.shape.penetration(x, d) {
                for c in 0..3 {
                    let fc = -k * phi * n[c];
                    f[3 * a + c] += fc;
                    net[c] += fc;
                }
                e += 0.5 * k * phi * phi;
                pen = pen.max(-phi);
            }
        }
        (e, net, pen)
    }

    /// The contact force on each node (3 per node, N) at `u` and time `t`: the frame field.
    pub fn nodal_forces(&self, x0: &[f64], u: &[f64], t: f64, f: &mut [f64]) {
        self.add_forces(x0, u, t, 1.0, f);
    }

    /// For each node of `x0 + u` inside the tool at time `t` (nodes ascending):
    /// `visit(node, x − d, n, N, trial)` with the normal force magnitude `N = k |φ|` and the
    /// friction law at the committed `state` ([`friction::STATE`] per node; `trial` `None`
    /// without friction or an anchor).
    fn each_contact(
        &self,
        x0: &[f64],
        u: &[f64],
        t: f64,
        factor: f64,
        state: &[f64],
        mut visit: impl FnMut(usize, [f64; 3], [f64; 3], f64, Option<friction::Trial>),
    ) {
        let d = self.offset(t, factor);
        for (a, (p, w)) in x0.chunks_exact(3).zip(u.chunks_exact(3)).enumerate() {
            let x = [p[0] + w[0], p[1] + w[1], p[2] + w[2]];
            if let Some((phi, n)) = self.shape.penetration(x, d) {
                let normal = -self.stiffness * phi;
                let trial = self.friction.and_then(|fr| {
                    fr.trial(x, d, n, &state[friction::STATE * a..][..friction::STATE])
                });
                visit(a, sub(x, d), n, normal, trial);
            }
        }
    }

    /// Add the friction forces at `u` and time `t` from the committed `state` into `f`
    /// (3 per node); returns the friction springs' energy (J) and the net friction force (N).
    pub fn add_friction_forces(
        &self,
        x0: &[f64],
        u: &[f64],
        t: f64,
        factor: f64,
        state: &[f64],
        f: &mut [f64],
    ) -> (f64, [f64; 3]) {
        let (mut e, mut net) = (0.0, [0.0; 3]);
        if self.friction.is_none() {
            return (e, net);
        }
        self.each_contact(x0, u, t, factor, state, |a, _, _, _, trial| {
            if let Some(tr) = trial {
                for c in 0..3 {
                    f[3 * a + c] += tr.force[c];
                    net[c] += tr.force[c];
                }
                e += tr.energy;
            }
        });
        (e, net)
    }

    /// Commit the friction `state` at `u` and time `t` (module documentation); returns the
    /// energy dissipated by slip (J).
    pub fn commit_friction(
        &self,
        x0: &[f64],
        u: &[f64],
        t: f64,
        factor: f64,
        state: &mut [f64],
    ) -> f64 {
        let Some(fr) = self.friction else {
            return 0.0;
        };
        let mut touched = vec![None; x0.len() / 3];
        self.each_contact(x0, u, t, factor, state, |a, p, _, normal, trial| {
            touched[a] = Some((p, normal, trial));
        });
        let mut w = 0.0;
        for (st, c) in state.chunks_exact_mut(friction::STATE).zip(touched) {
            w += friction::commit(&fr, st, c);
        }
        w
    }
}

/// Default penalty stiffness `k = 4 · modulus · ℓ̄` (N/m) for a mesh of mean edge length
/// `mean_edge` (m) and a material stability modulus `modulus` (Pa).
pub fn default_stiffness(modulus: f64, mean_edge: f64) -> f64 {
    4.0 * modulus * mean_edge
}

/// A force model with rigid tools in penalty contact on top (see the module documentation).
/// The time is the one [`crate::integrate::System::impose`] last set
/// ([`ForceModel::set_time`]).
pub struct Contact {
    inner: Box<dyn ForceModel>,
    /// Reference positions, 3 per node.
    x0: Vec<f64>,
    tools: Vec<Tool>,
    /// Per tool, its friction state ([`friction::STATE`] per node; empty without friction).
    state: Vec<Vec<f64>>,
    /// Energy dissipated by friction so far (J).
    dissipated: f64,
    /// Time (f64 bits).
    time: AtomicU64,
    /// Factor of the tools' translations (f64 bits; static increments).
    factor: AtomicU64,
    /// Scratch, 3 per node.
    f: Vec<f64>,
}

impl Contact {
    /// Wrap `inner` (reference positions `x0`, 3 per node) with `tools`.
    pub fn new(inner: Box<dyn ForceModel>, x0: Vec<f64>, tools: Vec<Tool>) -> Self {
        let n = inner.num_nodes();
        assert_eq!(x0.len(), 3 * n);
        let state = tools
            .iter()
            .map(|t| match t.friction {
                Some(_) => friction::FREE.repeat(n),
                None => Vec::new(),
            })
            .collect();
        Contact {
            inner,
            x0,
            tools,
            state,
            dissipated: 0.0,
            time: AtomicU64::new(0f64.to_bits()),
            factor: AtomicU64::new(1f64.to_bits()),
            f: vec![0.0; 3 * n],
        }
    }

    /// The tools.
    pub fn tools(&self) -> &[Tool] {
        &self.tools
    }

    /// The time the tools are placed at (s).
    pub fn time(&self) -> f64 {
        f64::from_bits(self.time.load(Ordering::Relaxed))
    }

    /// The energy dissipated by friction over the committed steps so far (J, ≥ 0).
    pub fn dissipated(&self) -> f64 {
        self.dissipated
    }

    /// Whether a tool has friction.
    pub fn has_friction(&self) -> bool {
        self.tools.iter().any(|t| t.friction.is_some())
    }

    /// The tools' forces on the body (normal and friction) added into `f` (3 per node);
    /// returns the penalty and friction energy (J), the net force (N), the deepest penetration
    /// (m) and the net friction force (N).
    pub fn add_tool_forces(&self, u: &[f64], f: &mut [f64]) -> (f64, [f64; 3], f64, [f64; 3]) {
        let t = self.time();
        let g = f64::from_bits(self.factor.load(Ordering::Relaxed));
        let (mut e, mut net, mut pen, mut fric) = (0.0, [0.0; 3], 0.0f64, [0.0; 3]);
        for (tool, state) in self.tools.iter().zip(&self.state) {
            let (te, tf, tp) = tool.add_forces(&self.x0, u, t, g, f);
            let (fe, ff) = tool.add_friction_forces(&self.x0, u, t, g, state, f);
            e += te + fe;
            for d in 0..3 {
                net[d] += tf[d] + ff[d];
                fric[d] += ff[d];
            }
            pen = pen.max(tp);
        }
        (e, net, pen, fric)
    }
}

impl ForceModel for Contact {
    fn num_nodes(&self) -> usize {
        self.inner.num_nodes()
    }

    fn internal_forces(&mut self, u: &[f64], r: &mut [f64]) -> Result<(), ElementFailure> {
        self.inner.internal_forces(u, r)?;
        let mut f = std::mem::take(&mut self.f);
        f.iter_mut().for_each(|x| *x = 0.0);
        self.add_tool_forces(u, &mut f);
        for (ri, fi) in r.iter_mut().zip(&f) {
            *ri -= fi;
        }
        self.f = f;
        Ok(())
    }

    fn strain_energy(&self, u: &[f64]) -> f64 {
        let (e, ..) = self.add_tool_forces(u, &mut vec![0.0; u.len()]);
        self.inner.strain_energy(u) + e
    }

    fn admissible_energy(&self, u: &[f64]) -> f64 {
        let inner = self.inner.admissible_energy(u);
        if !inner.is_finite() {
            return f64::INFINITY;
        }
        let (e, ..) = self.add_tool_forces(u, &mut vec![0.0; u.len()]);
        inner + e
    }

    fn tangent_elements(&self) -> Option<crate::fem::ElementTopology<'_>> {
        self.inner.tangent_elements()
    }

    fn element_tangent(&self, e: usize, u: &[f64], out: &mut [f64]) -> Result<(), ElementFailure> {
        self.inner.element_tangent(e, u, out)
    }

    fn add_extra_tangent(&self, u: &[f64], add: &mut dyn FnMut(&[u32], &[f64])) {
        self.inner.add_extra_tangent(u, add);
        let t = self.time();
        let g = f64::from_bits(self.factor.load(Ordering::Relaxed));
        for (tool, state) in self.tools.iter().zip(&self.state) {
            tool.add_tangent(&self.x0, u, t, g, add);
            if let Some(fr) = tool.friction {
                tool.each_contact(&self.x0, u, t, g, state, |a, _, n, _, trial| {
                    if let Some(tr) = trial {
                        add(&[a as u32], &fr.tangent(n, &tr));
                    }
                });
            }
        }
    }

    fn element_det_f(&self, e: usize, u: &[f64]) -> f64 {
        self.inner.element_det_f(e, u)
    }

    fn nodal_stress(&self, u: &[f64], t: &mut [f64]) {
        self.inner.nodal_stress(u, t)
    }

    fn set_time(&self, t: f64) {
        self.time.store(t.to_bits(), Ordering::Relaxed);
        self.inner.set_time(t);
    }

    fn set_load_factor(&self, f: f64) {
        self.factor.store(f.to_bits(), Ordering::Relaxed);
        self.inner.set_load_factor(f);
    }

    fn set_step(&mut self, dt: f64) {
        self.inner.set_step(dt);
    }

    fn load_report(&mut self, u: &[f64]) -> LoadReport {
        let mut rep = self.inner.load_report(u);
        let mut f = std::mem::take(&mut self.f);
        f.iter_mut().for_each(|x| *x = 0.0);
        let (_, net, pen, fric) = self.add_tool_forces(u, &mut f);
        self.f = f;
        for d in 0..3 {
            rep.tool[d] += net[d];
            rep.friction[d] += fric[d];
        }
        rep.max_penetration = rep.max_penetration.max(pen);
        rep
    }

    fn contact_forces(&self, u: &[f64], out: &mut [f64]) -> bool {
        out.iter_mut().for_each(|x| *x = 0.0);
        self.add_tool_forces(u, out);
        true
    }

    fn friction_forces(&self, u: &[f64], out: &mut [f64]) -> bool {
        if !self.has_friction() {
            return self.inner.friction_forces(u, out);
        }
        out.iter_mut().for_each(|x| *x = 0.0);
        let t = self.time();
        let g = f64::from_bits(self.factor.load(Ordering::Relaxed));
        for (tool, state) in self.tools.iter().zip(&self.state) {
            tool.add_friction_forces(&self.x0, u, t, g, state, out);
        }
        true
    }

    fn accept_step(&mut self, u: &[f64], dt: f64) -> bool {
        let inner = self.inner.accept_step(u, dt);
        let t = self.time();
        let g = f64::from_bits(self.factor.load(Ordering::Relaxed));
        for (tool, state) in self.tools.iter().zip(&mut self.state) {
            self.dissipated += tool.commit_friction(&self.x0, u, t, g, state);
        }
        inner || self.has_friction()
    }

    fn save_history(&self, out: &mut Vec<f64>) {
        self.inner.save_history(out);
        if self.has_friction() {
            for s in &self.state {
                out.extend_from_slice(s);
            }
            out.push(self.dissipated);
        }
    }

    fn load_history(&mut self, h: &[f64]) -> usize {
        let mut k = self.inner.load_history(h);
        if self.has_friction() {
            for s in &mut self.state {
                let len = s.len();
                s.copy_from_slice(&h[k..k + len]);
                k += len;
            }
            self.dissipated = h[k];
            k += 1;
        }
        k
    }
}

#[cfg(test)]
mod friction_tests;
#[cfg(test)]
mod tests;
