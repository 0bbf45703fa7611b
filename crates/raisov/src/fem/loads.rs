//! External loads that depend on time or on the configuration, and the force-model wrapper
//! that carries them to every integrator, every multigrid level and the static solve (the
//! rigid tools of [`crate::contact`] wrap a force model the same way).
//!
//! Loads scale with a time function ([`crate::time::TimeFunction`], re-exported here).
//!
//! **Surface pressure** (a follower load) on triangles `(x1, x2, x3)` in the *current*
//! configuration `x = X + u`, recomputed at every force evaluation:
//!
//! ```text
//! f_a = −p(t)/3 · (x2 − x1) × (x3 − x1) / 2        for each node a of the triangle
//! ```
//!
//! The pressure acts on the side the triangle's normal `(x2 − x1) × (x3 − x1)` points to: on
//! the boundary of a tetrahedral mesh the normals point out of the body, so a positive
//! pressure pushes into the body (a pressure on the wall of a cavity pushes the wall away
//! from the cavity); on a membrane the node order fixes the side (internal pressure of a
//! balloon whose triangles face outwards is a negative value). Its work potential is
//! `W = −p Σ_tri x1·(x2 × x3)/6 = −p V(u)`, `V` the volume the triangles enclose with the
//! origin; its gradient is the force above exactly on a closed surface (on an open surface up
//! to terms along the boundary edges: a follower pressure on an open surface has no
//! potential). The net force of a pressure on a closed surface is zero. The energy the model
//! reports ([`ForceModel::strain_energy`], the merit of line searches) therefore counts the
//! pressure as a dead load frozen at the last force evaluation `u*`:
//! `E(w) − F_p(u*)·w`, whose gradient along a search direction is the pressure force at
//! `u*`, the linearization the solvers' steps are built on.
//!
//! **Traction**: a fixed vector `t(t)` (Pa) per *reference* area, `f_a = t A0/3` on each node of
//! each triangle of reference area `A0`; potential `W = f·u`.
//!
//! **Timed nodal loads**: a force per node times a time function.
//!
//! [`Loaded`] wraps a [`ForceModel`]: its internal force is `R(u) − F_loads(u, t)`,
//! so that every integrator's `M ü + D u̇ + R = V` and every residual `V − R` include the
//! loads, the reactions ([`crate::metrics::reactions`]) balance them, and each multigrid level
//! that carries its own [`Loaded`] (the loads selected on that level's own surface) has the
//! same loads. The time is the one [`crate::integrate::System::impose`] last set
//! ([`ForceModel::set_time`]): the time of the state being stepped.

use super::{ElementFailure, ForceModel};
use crate::geometry::cross;
pub use crate::time::TimeFunction;
use std::sync::atomic::{AtomicU64, Ordering};

/// What a surface load does per unit area.
#[derive(Clone, Debug, PartialEq)]
pub enum SurfaceLoadKind {
    /// Follower pressure (Pa) on the side the normals point to.
    Pressure(f64),
    /// Fixed traction (Pa) per reference area.
    Traction([f64; 3]),
}

/// A pressure or traction on triangles of one mesh, times a time function.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceLoad {
    /// Node triples of the loaded triangles (normals by node order, see the module docs).
    pub triangles: Vec<[u32; 3]>,
    /// The pressure (Pa) or traction (Pa per reference area) at `s = 1`.
    pub kind: SurfaceLoadKind,
    /// `s(t)`, the factor of `kind`'s value.
    pub time: TimeFunction,
}

/// A force (N) on each of some nodes, times a time function.
#[derive(Clone, Debug, PartialEq)]
pub struct TimedNodalLoad {
    /// The loaded nodes (indices into the mesh's nodes, from 0).
    pub nodes: Vec<u32>,
    /// The force on each node at `s = 1` (N).
    pub force: [f64; 3],
    /// `s(t)`, the factor of `force`.
    pub time: TimeFunction,
}

/// Net forces of the loads and tools of a model at one state (N), and the deepest tool
/// penetration (m).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LoadReport {
    /// `Σ_a F_a` of the surface and timed nodal loads.
    pub applied: [f64; 3],
    /// The force the tools exert on the body, all tools together.
    pub tool: [f64; 3],
    /// The largest penetration of a node into a tool (m; 0 without contact).
    pub max_penetration: f64,
    /// The tangential (friction) part of `tool` ([`crate::contact`]; zero without friction).
    pub friction: [f64; 3],
}

/// A force model with surface loads and timed nodal loads on top (see the module
/// documentation).
pub struct Loaded {
    inner: Box<dyn ForceModel>,
    /// Reference positions, 3 per node.
    x0: Vec<f64>,
    surface: Vec<SurfaceLoad>,
    /// Per traction load: its nodal force per unit traction factor (3 per node entry, with
    /// node ids), precomputed from the reference areas.
    traction: Vec<Vec<(u32, [f64; 3])>>,
    nodal: Vec<TimedNodalLoad>,
    /// Time (f64 bits).
    time: AtomicU64,
    /// Load factor (f64 bits).
    factor: AtomicU64,
    /// Scratch: the load forces of one evaluation (3 per node).
    f: Vec<f64>,
    /// The pressure forces of the last [`ForceModel::internal_forces`] (3 per node).
    frozen: Vec<f64>,
}

impl Loaded {
    /// Wrap `inner` (reference positions `x0`, 3 per node).
    pub fn new(
        inner: Box<dyn ForceModel>,
        x0: Vec<f64>,
        surface: Vec<SurfaceLoad>,
        nodal: Vec<TimedNodalLoad>,
    ) -> Self {
        let n = inner.num_nodes();
        assert_eq!(x0.len(), 3 * n);
        let traction = surface
            .iter()
            .map(|s| match s.kind {
                SurfaceLoadKind::Traction(tr) => {
                    let mut out = Vec::with_capacity(3 * s.triangles.len());
                    for t in &s.triangles {
                        let p = |k: usize| {
                            let i = 3 * t[k] as usize;
                            [x0[i], x0[i + 1], x0[i + 2]]
                        };
                        let (a, b, c) = (p(0), p(1), p(2));
                        let e1 = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
                        let e2 = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
                        let nn = cross(e1, e2);
                        let area = 0.5 * (nn[0] * nn[0] + nn[1] * nn[1] + nn[2] * nn[2]).sqrt();
                        let f = tr.map(|x| x * area / 3.0);
                        for &a in t {
                            out.push((a, f));
                        }
                    }
                    out
                }
                SurfaceLoadKind::Pressure(_) => Vec::new(),
            })
            .collect();
        Loaded {
            inner,
            x0,
            surface,
            traction,
            nodal,
            time: AtomicU64::new(0f64.to_bits()),
            factor: AtomicU64::new(1f64.to_bits()),
            f: vec![0.0; 3 * n],
            frozen: vec![0.0; 3 * n],
        }
    }

    /// The time the loads are evaluated at (s).
    pub fn time(&self) -> f64 {
        f64::from_bits(self.time.load(Ordering::Relaxed))
    }

    fn factor(&self) -> f64 {
        f64::from_bits(self.factor.load(Ordering::Relaxed))
    }

    /// The load forces `F_loads(u, t)` (surface and timed nodal loads, not tools) added into
    /// `f` (3 per node); returns the potential `W` of those loads (pressure: `−p V`, see the
    /// module documentation).
    pub fn add_load_forces(&self, u: &[f64], f: &mut [f64]) -> f64 {
        self.add_pressure_forces(u, f) + self.add_dead_forces(u, f)
    }

    fn position(&self, u: &[f64], a: u32) -> [f64; 3] {
        let i = 3 * a as usize;
        [
            self.x0[i] + u[i],
            self.x0[i + 1] + u[i + 1],
            self.x0[i + 2] + u[i + 2],
        ]
    }

    /// The follower pressures' forces added into `f`; returns `W = −p V`.
    fn add_pressure_forces(&self, u: &[f64], f: &mut [f64]) -> f64 {
        let t = self.time();
        let g = self.factor();
        let mut work = 0.0;
        for s in &self.surface {
            let SurfaceLoadKind::Pressure(p) = s.kind else {
                continue;
            };
            let p = p * g * s.time.value(t);
            for tri in &s.triangles {
                let (a, b, c) = (
                    self.position(u, tri[0]),
                    self.position(u, tri[1]),
                    self.position(u, tri[2]),
                );
                let e1 = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
                let e2 = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
                let nn = cross(e1, e2);
                let fa = nn.map(|v| -p * v / 6.0);
                for &k in tri {
                    let i = 3 * k as usize;
                    for d in 0..3 {
                        f[i + d] += fa[d];
                    }
                }
                let bc = cross(b, c);
                work -= p * (a[0] * bc[0] + a[1] * bc[1] + a[2] * bc[2]) / 6.0;
            }
        }
        work
    }

    /// The symmetric part of the follower pressures' stiffness, one `9 × 9` block per loaded
    /// triangle handed to `add` (module docs of [`super::ForceModel`]). With
    /// `n = x₁×x₂ + x₂×x₃ + x₃×x₁` (twice the area vector) and `e₁ = x₂ − x₃`,
    /// `e₂ = x₃ − x₁`, `e₃ = x₁ − x₂`, `∂n/∂x_b = −[e_b]×`, so each node's force
    /// `f_a = −p n / 6` has `∂f_a/∂x_b = (p/6) [e_b]×`; the internal force carries `−f`, and
    /// the symmetric part of its block `(a, b)` is `(p/12) [e_a − e_b]×` (zero on the
    /// diagonal). On a closed surface the skew parts cancel between neighbouring triangles
    /// and this is the whole tangent; on an open one the boundary edges' terms are left out,
    /// which the Newton iteration's exact residual tolerates.
    fn add_pressure_tangent(&self, u: &[f64], add: &mut dyn FnMut(&[u32], &[f64])) {
        let t = self.time();
        let g = self.factor();
        let skew = |e: [f64; 3]| [[0.0, -e[2], e[1]], [e[2], 0.0, -e[0]], [-e[1], e[0], 0.0]];
        let mut block = [0.0; 81];
        for s in &self.surface {
            let SurfaceLoadKind::Pressure(p) = s.kind else {
                continue;
            };
            let p = p * g * s.time.value(t);
            if p == 0.0 {
                continue;
            }
            for tri in &s.triangles {
                let x = tri.map(|a| self.position(u, a));
                let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
                let e = [sub(x[1], x[2]), sub(x[2], x[0]), sub(x[0], x[1])];
                for a in 0..3 {
                    for b in 0..3 {
                        let m = skew(sub(e[a], e[b]));
                        for i in 0..3 {
                            for j in 0..3 {
                                block[(3 * a + i) * 9 + 3 * b + j] = p / 12.0 * m[i][j];
                            }
                        }
                    }
                }
                add(tri, &block);
            }
        }
    }

    /// The tractions' and timed nodal loads' forces added into `f`; returns `W = F·u`.
    fn add_dead_forces(&self, u: &[f64], f: &mut [f64]) -> f64 {
        let t = self.time();
        let g = self.factor();
        let mut work = 0.0;
        for (s, tr) in self.surface.iter().zip(&self.traction) {
            let st = g * s.time.value(t);
            for &(k, fk) in tr {
                let i = 3 * k as usize;
                for d in 0..3 {
                    f[i + d] += st * fk[d];
                    work += st * fk[d] * u[i + d];
                }
            }
        }
        for l in &self.nodal {
            let s = g * l.time.value(t);
            for &k in &l.nodes {
                let i = 3 * k as usize;
                for d in 0..3 {
                    f[i + d] += s * l.force[d];
                    work += s * l.force[d] * u[i + d];
                }
            }
        }
        work
    }
}

impl ForceModel for Loaded {
    fn num_nodes(&self) -> usize {
        self.inner.num_nodes()
    }

    fn internal_forces(&mut self, u: &[f64], r: &mut [f64]) -> Result<(), ElementFailure> {
        self.inner.internal_forces(u, r)?;
        let mut f = std::mem::take(&mut self.f);
        let mut frozen = std::mem::take(&mut self.frozen);
        frozen.iter_mut().for_each(|x| *x = 0.0);
        self.add_pressure_forces(u, &mut frozen);
        f.copy_from_slice(&frozen);
        self.frozen = frozen;
        self.add_dead_forces(u, &mut f);
        for (ri, fi) in r.iter_mut().zip(&f) {
            *ri -= fi;
        }
        self.f = f;
        Ok(())
    }

    fn strain_energy(&self, u: &[f64]) -> f64 {
        let mut f = vec![0.0; u.len()];
        let w = self.add_dead_forces(u, &mut f);
        let wp: f64 = self.frozen.iter().zip(u).map(|(a, b)| a * b).sum();
        self.inner.strain_energy(u) - w - wp
    }

    fn admissible_energy(&self, u: &[f64]) -> f64 {
        let e = self.inner.admissible_energy(u);
        if !e.is_finite() {
            return f64::INFINITY;
        }
        let mut f = vec![0.0; u.len()];
        let w = self.add_dead_forces(u, &mut f);
        let wp: f64 = self.frozen.iter().zip(u).map(|(a, b)| a * b).sum();
        e - w - wp
    }

    fn tangent_elements(&self) -> Option<super::ElementTopology<'_>> {
        self.inner.tangent_elements()
    }

    fn element_tangent(&self, e: usize, u: &[f64], out: &mut [f64]) -> Result<(), ElementFailure> {
        self.inner.element_tangent(e, u, out)
    }

    fn add_extra_tangent(&self, u: &[f64], add: &mut dyn FnMut(&[u32], &[f64])) {
        self.inner.add_extra_tangent(u, add);
        self.add_pressure_tangent(u, add);
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

    fn accept_step(&mut self, u: &[f64], dt: f64) -> bool {
        self.inner.accept_step(u, dt)
    }

    fn contact_forces(&self, u: &[f64], out: &mut [f64]) -> bool {
        self.inner.contact_forces(u, out)
    }

    fn friction_forces(&self, u: &[f64], out: &mut [f64]) -> bool {
        self.inner.friction_forces(u, out)
    }

    fn save_history(&self, out: &mut Vec<f64>) {
        self.inner.save_history(out)
    }

    fn load_history(&mut self, h: &[f64]) -> usize {
        self.inner.load_history(h)
    }

    fn load_report(&mut self, u: &[f64]) -> LoadReport {
        let mut rep = self.inner.load_report(u);
        let mut f = std::mem::take(&mut self.f);
        f.iter_mut().for_each(|x| *x = 0.0);
        self.add_load_forces(u, &mut f);
        for (i, x) in f.iter().enumerate() {
            rep.applied[i % 3] += x;
        }
        self.f = f;
        rep
    }
}

/// The triangles of `mesh` whose three nodes all lie in `nodes`: boundary faces of a
/// tetrahedral mesh (outward normals), or elements of a membrane (their own node order).
pub fn triangles_within(mesh: &crate::mesh::Mesh, nodes: &[u32]) -> Vec<[u32; 3]> {
    let mut inside = vec![false; mesh.num_nodes()];
    for &a in nodes {
        if let Some(x) = inside.get_mut(a as usize) {
            *x = true;
        }
    }
    let all = |t: &[u32]| t.iter().all(|&a| inside[a as usize]);
    match mesh.kind {
        crate::mesh::ElementKind::Tet4 => mesh
            .boundary_facets()
            .into_iter()
            .filter(|t| all(t))
            .collect(),
        crate::mesh::ElementKind::Tri3 => mesh
            .elements()
            .filter(|t| all(t))
            .map(|t| [t[0], t[1], t[2]])
            .collect(),
    }
}

/// The nodes within `radius` of `point` (m): a surface patch selector (with
/// [`triangles_within`], the boundary triangles of the patch).
pub fn nodes_within(mesh: &crate::mesh::Mesh, point: [f64; 3], radius: f64) -> Vec<u32> {
    (0..mesh.num_nodes() as u32)
        .filter(|&a| {
            let p = mesh.nodes[a as usize];
            let d = [p[0] - point[0], p[1] - point[1], p[2] - point[2]];
            d[0] * d[0] + d[1] * d[1] + d[2] * d[2] <= radius * radius
        })
        .collect()
}

#[cfg(test)]
mod tests;
