//! Grasps and pins: surface patches selected on the deformed surface, the constraints they
//! give the stepper, and the tool force (conventions in the [`super`] module docs).

use super::{GrabId, PinId, Simulation};
use crate::integrate::RuntimeConstraints;
use crate::mesh::{dot, sub};
use crate::{Error, Result};

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
}

/// A pin: nodes held where they stand, on every level.
#[derive(Clone, Debug)]
pub(super) struct Pin {
    /// Per level (0 the finest), the pinned nodes.
    pub(super) levels: Vec<Vec<u32>>,
}

/// The point of triangle `(a, b, c)` nearest to `p` (Ericson, Real-Time Collision
/// Detection, 5.1.5).
fn closest_on_triangle(p: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [f64; 3] {
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let at = |s: f64, t: f64| {
        [
            a[0] + s * ab[0] + t * ac[0],
            a[1] + s * ab[1] + t * ac[1],
            a[2] + s * ab[2] + t * ac[2],
        ]
    };
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return at(d1 / (d1 - d3), 0.0);
    }
    let cp = sub(p, c);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return at(0.0, d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return [
            b[0] + w * (c[0] - b[0]),
            b[1] + w * (c[1] - b[1]),
            b[2] + w * (c[2] - b[2]),
        ];
    }
    let denom = 1.0 / (va + vb + vc);
    at(vb * denom, vc * denom)
}

fn dist2(a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = sub(a, b);
    dot(d, d)
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
        let x = &self.positions;
        let mut best = (f64::INFINITY, [0.0; 3], [0u32; 3]);
        for f in &self.surface {
            let q =
                closest_on_triangle(point, x[f[0] as usize], x[f[1] as usize], x[f[2] as usize]);
            let d = dist2(q, point);
            if d < best.0 {
                best = (d, q, *f);
            }
        }
        let (_, g, face) = best;
        if !best.0.is_finite() {
            return Err(Error::param(what, "the mesh has no surface"));
        }
        let mut nodes: Vec<u32> = self
            .surface
            .iter()
            .flatten()
            .copied()
            .filter(|&a| dist2(x[a as usize], g) <= radius * radius)
            .collect();
        // At least the node of the nearest face nearest to the grasp point.
        let nearest = *face
            .iter()
            .min_by(|&&a, &&b| dist2(x[a as usize], g).total_cmp(&dist2(x[b as usize], g)))
            .expect("three corners");
        nodes.push(nearest);
        nodes.sort_unstable();
        nodes.dedup();
        nodes.retain(|&a| !self.constrained[a as usize]);
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

    /// Grasp the surface near `point` (m): the surface nodes within `radius` (m) of the
    /// surface point nearest `point`, at least the nearest node, held rigidly from the next
    /// frame on (module docs). Nodes constrained already are left out; an error if none is
    /// left, or for a non-finite point or a negative radius.
    pub fn grab(&mut self, point: [f64; 3], radius: f64) -> Result<GrabId> {
        let (g, nodes) = self.patch(point, radius, "grab")?;
        let offsets = nodes
            .iter()
            .map(|&a| sub(self.positions[a as usize], g))
            .collect();
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
            },
        );
        self.constraints_changed();
        Ok(id)
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

    /// The force the tissue exerts on the tool of grasp `id` at the current state,
    /// `Σ_{a ∈ id} (V_a − R_a(u))` (N; module docs).
    pub fn grab_force(&self, id: GrabId) -> Result<[f64; 3]> {
        let g = self.grab_ref(id)?;
        let mut f = [0.0; 3];
        for &a in &g.nodes {
            let x = self.net(a as usize);
            for k in 0..3 {
                f[k] += x[k];
            }
        }
        Ok(f)
    }

    /// Pin the surface near `point` (m): the patch [`Simulation::grab`] would take, held
    /// where it stands on every level from now on.
    pub fn pin(&mut self, point: [f64; 3], radius: f64) -> Result<PinId> {
        let (_, nodes) = self.patch(point, radius, "pin")?;
        let mut levels = vec![nodes.clone()];
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

    pub(super) fn grab_ref(&self, id: GrabId) -> Result<&Grab> {
        self.grabs.get(&id).ok_or_else(|| no_grab(id))
    }

    fn grab_mut(&mut self, id: GrabId) -> Result<&mut Grab> {
        self.grabs.get_mut(&id).ok_or_else(|| no_grab(id))
    }

    /// Grasps or pins were added or removed: hand the stepper the new set now (a pin holds
    /// where the nodes stand now), refresh the constrained mask and the supports.
    fn constraints_changed(&mut self) {
        self.apply_constraints();
        let n = self.mesh.num_nodes();
        self.constrained.clone_from(&self.own);
        for g in self.grabs.values() {
            for &a in &g.nodes {
                self.constrained[a as usize] = true;
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
            g.held(g.position, &self.mesh.nodes, &mut c.held);
        }
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

fn no_grab(id: GrabId) -> Error {
    Error::param("grab", format!("no grasp {} (released already?)", id.0))
}
