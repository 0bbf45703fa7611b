//! Grasps and pins: surface patches selected on the deformed surface, the constraints they
//! give the stepper, and the tool force (conventions in the [`super`] module docs).

use super::{GrabId, PinId, Simulation};
use crate::geometry::sub;
pub use crate::integrate::Grip;
use crate::integrate::{RuntimeConstraints, Spring};
use crate::{Error, Result};
use std::collections::BTreeMap;

/// A grasp: level-0 nodes held rigidly at their offsets from the grasp point.
#[derive(Clone, Debug)]
pub(super) struct Grab {
    /// Grasped nodes, ascending.
    pub(super) nodes: Vec<u32>,
    /// Each node's position minus the grasp point when grasped (m).
    pub(super) offsets: Vec<[f64; 3]>,
    /// Where the grasp holds its nodes now (m).
    pub(super) position: [f64; 3],
    /// Where [`Simulation::move_grab`] asked it to go (m).
    pub(super) target: [f64; 3],
    /// The last tangent solutions per axis (warm starts of `grab_stiffness`), empty before.
    pub(super) warm: [Vec<f64>; 3],
    /// How the grasp holds its nodes.
    pub(super) coupling: Coupling,
    /// Each node's share of a spring grasp's stiffness, `w_a = m_a / Σ_b m_b` (lumped
    /// masses; Σ w = 1).
    pub(super) weights: Vec<f64>,
    /// Per coarser level `l + 1`, its nodes nearest the grasped nodes: each coarse node with
    /// the indices (into `nodes`) of the level-0 nodes carried to it.
    pub(super) coarse: Vec<Vec<(u32, Vec<usize>)>>,
    /// A friction grasp's grip ([`GrabOptions::friction`]); `None`: the springs never slide.
    pub(super) grip: Option<Grip>,
    /// The work the grip's sliding dissipated so far (J).
    pub(super) dissipated: f64,
}

/// How a grasp holds its patch of the surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Coupling {
    /// Each grasped node is held exactly at its place on the rigidly moved patch (a
    /// prescribed displacement on every level the scheme carries grasps to).
    Hard,
    /// Each grasped node `a` is pulled to its place `x_g + o_a` by a zero-length spring of
    /// stiffness `w_a k`, `w_a = m_a / Σ_b m_b` its lumped-mass share of the patch: the springs
    /// together pull with `k (x_g + ō − x̄)` (N), `x̄ = Σ w_a x_a` and `ō = Σ w_a o_a`, so `k` is
    /// the stiffness the tool feels when the patch moves rigidly. The nodes stay free, so the
    /// tissue can resist and slip behind the tool.
    Spring {
        /// `k` (N/m), finite and > 0.
        stiffness: f64,
    },
}

/// The options of [`Simulation::grab_with`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GrabOptions {
    /// The patch: surface nodes within this distance (m) of the grasp point (at least one).
    pub radius: f64,
    /// How the patch is held.
    pub coupling: Coupling,
    /// A friction grasp's grip (with [`Coupling::Spring`] only); `None`: no sliding.
    pub grip: Option<Grip>,
}

impl GrabOptions {
    /// A hard grasp of the patch within `radius` (m), as [`Simulation::grab`].
    pub fn hard(radius: f64) -> Self {
        GrabOptions {
            radius,
            coupling: Coupling::Hard,
            grip: None,
        }
    }
    /// A spring grasp of the patch within `radius` (m), of total stiffness `stiffness` (N/m).
    pub fn spring(radius: f64, stiffness: f64) -> Self {
        GrabOptions {
            radius,
            coupling: Coupling::Spring { stiffness },
            grip: None,
        }
    }
    /// A friction grasp: the spring grasp of `stiffness` (N/m, the stick stiffness of the
    /// jaws on the tissue) whose springs slide where they would pull harder than their share
    /// of `friction × clamp` (μ N, N): Coulomb's law per grasped node, the grasp's force
    /// bounded by `μ N` ([`crate::integrate::Spring`]; module docs of [`crate::sim`]).
    pub fn friction(radius: f64, stiffness: f64, friction: f64, clamp: f64) -> Self {
        GrabOptions {
            radius,
            coupling: Coupling::Spring { stiffness },
            grip: Some(Grip { friction, clamp }),
        }
    }
}

fn check_grip(options: &GrabOptions) -> Result<()> {
    let Some(grip) = options.grip else {
        return Ok(());
    };
    if !matches!(options.coupling, Coupling::Spring { .. }) {
        return Err(Error::param(
            "grip",
            "a friction grasp needs a spring coupling (the jaws' stick stiffness): use GrabOptions::friction(radius, stiffness, friction, clamp)",
        ));
    }
    for (name, v, unit) in [
        ("friction", grip.friction, ""),
        ("clamp", grip.clamp, " (N)"),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(Error::param(
                name,
                format!("{v}: must be finite and > 0{unit}"),
            ));
        }
    }
    Ok(())
}

fn check_stiffness(k: f64) -> Result<()> {
    if k.is_finite() && k > 0.0 {
        Ok(())
    } else {
        Err(Error::param(
            "stiffness",
            format!("{k}: must be finite and > 0 (N/m)"),
        ))
    }
}

impl Grab {
    /// The held displacement of each grasped node with the grasp at `p`: `p + o_a − X_a`.
    fn held(&self, p: [f64; 3], reference: &[[f64; 3]], out: &mut Vec<(u32, [f64; 3])>) {
        for (&a, o) in self.nodes.iter().zip(&self.offsets) {
            let x = reference[a as usize];
            out.push((
                a,
                [p[0] + o[0] - x[0], p[1] + o[1] - x[1], p[2] + o[2] - x[2]],
            ));
        }
    }

    /// The stiffness of node `i` of `nodes` (N/m): `w_i k` for a spring grasp, 0 for a hard
    /// one.
    pub(super) fn node_stiffness(&self, i: usize) -> f64 {
        match self.coupling {
            Coupling::Hard => 0.0,
            Coupling::Spring { stiffness } => stiffness * self.weights[i],
        }
    }

    /// The force (N) node `i`'s spring transmits before it slides: `w_i μ N` for a friction
    /// grasp, ∞ otherwise.
    fn node_limit(&self, i: usize) -> f64 {
        self.grip
            .map_or(f64::INFINITY, |g| g.limit() * self.weights[i])
    }

    /// A spring grasp's springs with the grasp at `p`: level 0's (one per grasped node,
    /// anchored at its held displacement) into `out[0]`, and each coarser level's, one per
    /// carried coarse node with the summed stiffness `k_c = Σ k_a` and the stiffness-weighted
    /// mean anchor `d_c = Σ k_a d_a / k_c`, into `out[l]`.
    pub(super) fn springs(&self, p: [f64; 3], reference: &[[f64; 3]], out: &mut Vec<Vec<Spring>>) {
        if out.len() < 1 + self.coarse.len() {
            out.resize(1 + self.coarse.len(), Vec::new());
        }
        let mut held = Vec::with_capacity(self.nodes.len());
        self.held(p, reference, &mut held);
        for (i, &(a, d)) in held.iter().enumerate() {
            out[0].push(Spring {
                node: a,
                k: self.node_stiffness(i),
                d,
                limit: self.node_limit(i),
            });
        }
        for (l, level) in self.coarse.iter().enumerate() {
            for (c, fine) in level {
                let mut k = 0.0;
                let mut limit = 0.0;
                let mut d = [0.0; 3];
                for &i in fine {
                    let ki = self.node_stiffness(i);
                    k += ki;
                    limit += self.node_limit(i);
                    for j in 0..3 {
                        d[j] += ki * held[i].1[j];
                    }
                }
                if k > 0.0 {
                    out[l + 1].push(Spring {
                        node: *c,
                        k,
                        d: d.map(|x| x / k),
                        limit,
                    });
                }
            }
        }
    }
}

/// A pin: nodes held where they stand, on every level.
#[derive(Clone, Debug)]
pub(super) struct Pin {
    /// Per level (0 the finest), the pinned nodes.
    pub(super) levels: Vec<Vec<u32>>,
}

fn check_point(name: &str, p: [f64; 3]) -> Result<()> {
    if p.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(Error::param(name, format!("{p:?}: must be finite (m)")))
    }
}

impl Simulation {
    /// The surface point nearest `point` (deformed configuration) and the free surface nodes
    /// within `radius` of it, at least the nearest one.
    fn patch(&self, point: [f64; 3], radius: f64, what: &str) -> Result<([f64; 3], Vec<u32>)> {
        check_point("point", point)?;
        if !(radius >= 0.0 && radius.is_finite()) {
            return Err(Error::param(
                "radius",
                format!("{radius}: must be finite and >= 0 (m)"),
            ));
        }
        let Some((g, mut nodes)) =
            crate::geometry::surface_patch(&self.positions, &self.surface, point, radius)
        else {
            return Err(Error::param(what, "the mesh has no surface"));
        };
        let sprung = self.sprung();
        nodes.retain(|&a| !self.constrained[a as usize] && !sprung[a as usize]);
        if nodes.is_empty() {
            return Err(Error::param(
                what,
                format!(
                    "every surface node within {radius} m of {g:?} is constrained already (fixed, grasped or pinned)"
                ),
            ));
        }
        Ok((g, nodes))
    }

    /// Grasp the surface near `point` (m) hard: the surface nodes within `radius` (m) of the
    /// surface point nearest `point`, at least the nearest node, held rigidly from the next
    /// frame on (module docs). Nodes constrained or grasped already are left out; an error if
    /// none is left, or for a non-finite point or a negative radius.
    /// [`Simulation::grab_with`] takes a spring coupling instead.
    pub fn grab(&mut self, point: [f64; 3], radius: f64) -> Result<GrabId> {
        self.grab_with(point, GrabOptions::hard(radius))
    }

    /// Grasp the surface near `point` (m) with `options`: the patch of [`Simulation::grab`],
    /// held hard or by springs ([`Coupling`]); an error also for a spring stiffness that is
    /// not finite and positive.
    ///
    /// ```
    /// use raisov::mesh::generate::{box_tets, BoxPattern};
    /// use raisov::sim::{Budget, GrabOptions, SimulationBuilder};
    ///
    /// let mesh = box_tets([0.04; 3], [3, 3, 3], BoxPattern::Six)?;
    /// let mut sim = SimulationBuilder::new(mesh).fix(|p| p[2] <= 0.0).build()?;
    /// // A 20 N/m spring grasp of the top face, its anchor lifted by 5 mm.
    /// let g = sim.grab_with([0.02, 0.02, 0.05], GrabOptions::spring(0.015, 20.0))?;
    /// let p = sim.grab_position(g)?;
    /// sim.move_grab(g, [p[0], p[1], p[2] + 0.005])?;
    /// for _ in 0..20 {
    ///     sim.step_frame(Budget::Cycles(4));
    /// }
    /// // The tissue resists: the patch rises by less than the anchor, and the spring pulls
    /// // the tool down by k times the lag.
    /// let f = sim.grab_force(g)?;
    /// assert!(f[2] < 0.0 && f[2] > -20.0 * 0.005, "{f:?}");
    /// # Ok::<(), raisov::Error>(())
    /// ```
    pub fn grab_with(&mut self, point: [f64; 3], options: GrabOptions) -> Result<GrabId> {
        if let Coupling::Spring { stiffness } = options.coupling {
            check_stiffness(stiffness)?;
        }
        check_grip(&options)?;
        let (g, nodes) = self.patch(point, options.radius, "grab")?;
        let offsets = nodes
            .iter()
            .map(|&a| sub(self.positions[a as usize], g))
            .collect();
        let mass: f64 = nodes.iter().map(|&a| self.mass[a as usize]).sum();
        let weights = nodes
            .iter()
            .map(|&a| {
                if mass > 0.0 {
                    self.mass[a as usize] / mass
                } else {
                    1.0 / nodes.len() as f64
                }
            })
            .collect();
        let coarse = self.coarse_of(&nodes);
        let id = GrabId(self.next_id);
        self.next_id += 1;
        self.grabs.insert(
            id,
            Grab {
                nodes,
                offsets,
                position: g,
                target: g,
                warm: Default::default(),
                coupling: options.coupling,
                weights,
                coarse,
                grip: options.grip,
                dissipated: 0.0,
            },
        );
        self.constraints_changed();
        Ok(id)
    }

    /// Make grasp `id` a spring grasp of total stiffness `stiffness` (N/m; [`Coupling`]),
    /// from now on; a hard grasp lets its nodes go free on their springs. An error for a
    /// stiffness that is not finite and positive.
    pub fn set_grab_stiffness(&mut self, id: GrabId, stiffness: f64) -> Result<()> {
        check_stiffness(stiffness)?;
        let g = self.grab_mut(id)?;
        g.coupling = Coupling::Spring { stiffness };
        g.warm = Default::default();
        self.constraints_changed();
        Ok(())
    }

    /// How grasp `id` holds its patch.
    pub fn grab_coupling(&self, id: GrabId) -> Result<Coupling> {
        Ok(self.grab_ref(id)?.coupling)
    }

    /// Move grasp `id` to `target` (m): its nodes follow rigidly over the next frame
    /// (recovery may leave it short of the target: [`super::FrameReport::target_reached`]).
    pub fn move_grab(&mut self, id: GrabId, target: [f64; 3]) -> Result<()> {
        check_point("target", target)?;
        self.grab_mut(id)?.target = target;
        Ok(())
    }

    /// Let go of grasp `id`: its nodes are free from now on.
    pub fn release(&mut self, id: GrabId) -> Result<()> {
        self.grabs.remove(&id).ok_or_else(|| no_grab(id))?;
        self.release_haptic(id);
        self.constraints_changed();
        Ok(())
    }

    /// Where grasp `id` holds its nodes now (m).
    pub fn grab_position(&self, id: GrabId) -> Result<[f64; 3]> {
        Ok(self.grab_ref(id)?.position)
    }

    /// The grasped nodes of `id` (level 0, ascending).
    pub fn grab_nodes(&self, id: GrabId) -> Result<&[u32]> {
        Ok(&self.grab_ref(id)?.nodes)
    }

    /// The force the tissue exerts on the tool of grasp `id` at the current state (N; module
    /// docs): a hard grasp's `Σ_{a ∈ id} (V_a − R_a(u))`, a spring grasp's spring force
    /// `Σ_a k_a (x_a − x_g − o_a) = k (x̄ − x_g − ō)` ([`Coupling::Spring`]), which equals
    /// `Σ_{a ∈ id} (V_a − R_a(u))` at equilibrium.
    pub fn grab_force(&self, id: GrabId) -> Result<[f64; 3]> {
        let g = self.grab_ref(id)?;
        let mut f = [0.0; 3];
        match g.coupling {
            Coupling::Hard => {
                for &a in &g.nodes {
                    let x = self.net(a as usize);
                    for k in 0..3 {
                        f[k] += x[k];
                    }
                }
            }
            Coupling::Spring { .. } => {
                for (i, (&a, o)) in g.nodes.iter().zip(&g.offsets).enumerate() {
                    let (ka, x) = (g.node_stiffness(i), self.positions[a as usize]);
                    let s = [0, 1, 2].map(|k| x[k] - g.position[k] - o[k]);
                    // A friction grasp's sliding spring pulls with its limit.
                    let l = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
                    let limit = g.node_limit(i);
                    let c = if ka * l > limit { limit / l } else { ka };
                    for k in 0..3 {
                        f[k] += c * s[k];
                    }
                }
            }
        }
        Ok(f)
    }

    /// Pin the surface near `point` (m): the patch [`Simulation::grab`] would take, held
    /// where it stands on every level from now on.
    pub fn pin(&mut self, point: [f64; 3], radius: f64) -> Result<PinId> {
        let (_, nodes) = self.patch(point, radius, "pin")?;
        let levels = self.pin_levels(nodes);
        let id = PinId(self.next_id);
        self.next_id += 1;
        self.pins.insert(id, Pin { levels });
        self.constraints_changed();
        Ok(id)
    }

    /// Remove pin `id`: its nodes are free from now on.
    pub fn unpin(&mut self, id: PinId) -> Result<()> {
        self.pins
            .remove(&id)
            .ok_or_else(|| Error::param("pin", format!("no pin {} (removed already?)", id.0)))?;
        self.constraints_changed();
        Ok(())
    }

    /// The pinned nodes of `id` on level 0 (ascending).
    pub fn pin_nodes(&self, id: PinId) -> Result<&[u32]> {
        self.pins
            .get(&id)
            .map(|p| &p.levels[0][..])
            .ok_or_else(|| Error::param("pin", format!("no pin {} (removed already?)", id.0)))
    }

    /// Per coarser level, its nodes nearest the level-0 `nodes` of a grasp, each with the
    /// indices (into `nodes`) carried to it.
    pub(super) fn coarse_of(&self, nodes: &[u32]) -> Vec<Vec<(u32, Vec<usize>)>> {
        let mut coarse = Vec::new();
        for l in 1..self.stepper.num_levels() {
            let Some(m) = self.stepper.level_mesh(l) else {
                break;
            };
            let mut carried: BTreeMap<u32, Vec<usize>> = BTreeMap::new();
            for (i, &a) in nodes.iter().enumerate() {
                if let Some(c) = m.nearest_node(self.mesh.nodes[a as usize]) {
                    carried.entry(c as u32).or_default().push(i);
                }
            }
            coarse.push(carried.into_iter().collect());
        }
        coarse
    }

    /// A pin's nodes per level: the level-0 `nodes`, and each coarser level's nodes nearest
    /// them.
    pub(super) fn pin_levels(&self, nodes: Vec<u32>) -> Vec<Vec<u32>> {
        let mut levels = Vec::new();
        for l in 1..self.stepper.num_levels() {
            let Some(m) = self.stepper.level_mesh(l) else {
                break;
            };
            let mut near: Vec<u32> = nodes
                .iter()
                .filter_map(|&a| m.nearest_node(self.mesh.nodes[a as usize]))
                .map(|x| x as u32)
                .collect();
            near.sort_unstable();
            near.dedup();
            levels.push(near);
        }
        levels.insert(0, nodes);
        levels
    }

    pub(super) fn grab_ref(&self, id: GrabId) -> Result<&Grab> {
        self.grabs.get(&id).ok_or_else(|| no_grab(id))
    }

    fn grab_mut(&mut self, id: GrabId) -> Result<&mut Grab> {
        self.grabs.get_mut(&id).ok_or_else(|| no_grab(id))
    }

    /// Grasps or pins were added or removed: hand the stepper the new set now (a pin holds
    /// where the nodes stand now), refresh the constrained mask and the supports.
    pub(super) fn constraints_changed(&mut self) {
        self.apply_constraints();
        let n = self.mesh.num_nodes();
        self.constrained.clone_from(&self.own);
        for g in self.grabs.values() {
            if g.coupling == Coupling::Hard {
                for &a in &g.nodes {
                    self.constrained[a as usize] = true;
                }
            }
        }
        for p in self.pins.values() {
            for &a in &p.levels[0] {
                self.constrained[a as usize] = true;
            }
        }
        debug_assert_eq!(self.constrained.len(), n);
        self.supports();
        // Imposing the grasps moved no node (they hold where they stand until a frame moves
        // them), so this evaluation finds what the last one found, with the new masks.
        let _ = self.observe();
    }

    /// Give the stepper the run-time constraints with every grasp at its `position`.
    pub(super) fn apply_constraints(&mut self) {
        let mut c = RuntimeConstraints::default();
        for g in self.grabs.values() {
            match g.coupling {
                Coupling::Hard => g.held(g.position, &self.mesh.nodes, &mut c.held),
                Coupling::Spring { .. } => g.springs(g.position, &self.mesh.nodes, &mut c.springs),
            }
        }
        self.springs = c.springs_of(0).to_vec();
        for p in self.pins.values() {
            if c.pinned.len() < p.levels.len() {
                c.pinned.resize(p.levels.len(), Vec::new());
            }
            for (l, nodes) in p.levels.iter().enumerate() {
                c.pinned[l].extend_from_slice(nodes);
            }
        }
        self.stepper.set_runtime_constraints(&c);
    }
}

impl Simulation {
    /// After an accepted frame: each friction grasp's sliding springs (stretch `l` beyond
    /// `l₀ = limit / k`) have their anchors moved along the stretch to `l₀` behind their node,
    /// so the next frame starts from the same forces with the slide taken (the return map of
    /// Coulomb's law); the work `limit (l − l₀)` is dissipated. Returns whether any moved.
    pub(super) fn slide_grips(&mut self) -> bool {
        let u = &self.stepper.state().u;
        let reference = &self.mesh.nodes;
        let mut moved = false;
        for g in self.grabs.values_mut() {
            if g.grip.is_none() || g.coupling == Coupling::Hard {
                continue;
            }
            let p = g.position;
            for i in 0..g.nodes.len() {
                let (ka, limit) = (g.node_stiffness(i), g.node_limit(i));
                let a = g.nodes[i] as usize;
                let x = reference[a];
                let o = g.offsets[i];
                // Stretch s = u_a − d_a, d_a = p + o − X_a.
                let s = [0, 1, 2].map(|k| u[3 * a + k] - (p[k] + o[k] - x[k]));
                let l = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
                if ka * l <= limit {
                    continue;
                }
                let l0 = limit / ka;
                // New anchor d' = u_a − l₀ ŝ, offset o' = d' − p + X_a.
                g.offsets[i] = [0, 1, 2].map(|k| u[3 * a + k] - l0 * s[k] / l - p[k] + x[k]);
                g.dissipated += limit * (l - l0);
                moved = true;
            }
        }
        if moved {
            self.apply_constraints();
        }
        moved
    }

    /// The work (J) friction grasp `id`'s sliding has dissipated so far
    /// ([`GrabOptions::friction`]); 0 for other grasps.
    pub fn grab_dissipation(&self, id: GrabId) -> Result<f64> {
        Ok(self.grab_ref(id)?.dissipated)
    }

    /// Grasp `id`'s grip, if it is a friction grasp.
    pub fn grab_grip(&self, id: GrabId) -> Result<Option<Grip>> {
        Ok(self.grab_ref(id)?.grip)
    }

    /// Level-0 nodes held by a spring grasp.
    pub(super) fn sprung(&self) -> Vec<bool> {
        let mut s = vec![false; self.mesh.num_nodes()];
        for g in self.grabs.values() {
            if g.coupling != Coupling::Hard {
                for &a in &g.nodes {
                    s[a as usize] = true;
                }
            }
        }
        s
    }
}

fn no_grab(id: GrabId) -> Error {
    Error::param("grab", format!("no grasp {} (released already?)", id.0))
}
