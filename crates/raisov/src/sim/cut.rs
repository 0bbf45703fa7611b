//! The scalpel: [`Simulation::cut`] cuts the body on every level with a planar blade
//! ([`crate::mesh::cut`]: the virtual node algorithm; [`crate::hierarchy::cut`]: the links
//! through the wound) and carries the simulation over.
//!
//! What carries over: each new node starts with the displacement and velocity of the node it
//! copies (the wound opens from the current shape); grasps and pins hold every copy of their
//! nodes (a grasp across the blade's path keeps both lips in hand, as tweezers would); each
//! nodal load stays on the first copy of its node. The frame predictor starts again.
//!
//! What is drawn ([`Simulation::surface_positions`], [`Simulation::surface_triangles`]): from
//! the first cut on, the cut body's surface ([`crate::mesh::cut::CutMesh::surface`]: the
//! boundary faces within the material and the wound's faces, carried by the element copies),
//! in place of a visual surface, which would bridge the wound. Grasps and pins take their
//! patch from the cut mesh's boundary faces (the element copies' faces on each lip).

use super::Simulation;
use crate::hierarchy::cut::CutHierarchy;
use crate::mesh::cut::{Blade, EmbeddedSurface, TopologyChange};
use crate::{Error, Result};

/// What a cut keeps between cuts: the levels as cut so far.
pub(super) struct CutState {
    hierarchy: CutHierarchy,
}

/// The drawn surface of a cut body ([`crate::mesh::cut::CutMesh::surface`]) and its vertices
/// at the current state.
pub(super) struct Embedded {
    pub(super) surface: EmbeddedSurface,
    pub(super) positions: Vec<[f64; 3]>,
}

impl Embedded {
    /// Carry the vertices to the nodes' current `positions`.
    pub(super) fn update(&mut self, positions: &[[f64; 3]], cells: &[u32]) {
        self.surface
            .positions(positions, cells, &mut self.positions);
    }
}

/// What [`Simulation::cut`] did.
#[derive(Clone, Debug, PartialEq)]
pub struct CutReport {
    /// Elements the blade split, per level (finest first).
    pub split: Vec<usize>,
    /// Level 0's nodes after the cut.
    pub nodes: usize,
    /// Level 0's elements after the cut.
    pub elements: usize,
    /// Wall time of the cut (s): every level cut, the links, the stepper and the simulation
    /// carried over.
    pub seconds: f64,
    /// Of which: the levels cut and the links carried ([`crate::hierarchy::cut`]).
    pub levels_seconds: f64,
    /// Of which: the stepper carried to the cut levels ([`crate::integrate::Stepper::cut`]),
    /// beside the simulation's own model of level 0.
    pub stepper_seconds: f64,
}

impl Simulation {
    /// Cut the body with `blade` on every level (module docs); returns what it split. A blade
    /// that misses the body changes nothing. Errors, with nothing changed: a membrane, a
    /// stepper that cannot cut, a force model that cannot be cut (pressure, traction, timed
    /// loads, tools: the stepper's and the simulation's own level-0 model are the same kind,
    /// so both refuse before either changes).
    pub fn cut(&mut self, blade: &Blade) -> Result<CutReport> {
        let start = std::time::Instant::now();
        let mut state = match self.cuts.take() {
            Some(s) => s,
            None => self.cut_state()?,
        };
        let saved = state.hierarchy.clone();
        let t0 = std::time::Instant::now();
        let hc = match state.hierarchy.cut(blade) {
            Ok(hc) => hc,
            Err(e) => {
                state.hierarchy = saved;
                self.cuts = Some(state);
                return Err(e);
            }
        };
        let split = hc.levels.iter().map(|l| l.split).collect();
        let levels_seconds = t0.elapsed().as_secs_f64();
        let t1 = std::time::Instant::now();
        let mut stepper_seconds = 0.0;
        if !hc.is_identity() {
            // The stepper's levels and the simulation's own model of level 0, side by side
            // (the same force model: both take the cut or both refuse it).
            let (stepper, model) = (&mut self.stepper, &mut self.model);
            let (cut, own) = rayon::join(|| stepper.cut(&hc), || model.cut(&hc.levels[0]));
            stepper_seconds = t1.elapsed().as_secs_f64();
            if let Err(e) = cut.and(own) {
                state.hierarchy = saved;
                self.cuts = Some(state);
                self.constraints_changed();
                return Err(e);
            }
            self.carry(&hc.levels[0], &state);
        }
        self.cuts = Some(state);
        Ok(CutReport {
            split,
            nodes: self.mesh.num_nodes(),
            elements: self.mesh.num_elements(),
            seconds: start.elapsed().as_secs_f64(),
            levels_seconds,
            stepper_seconds,
        })
    }

    /// The blades cut so far, in order.
    pub fn cuts(&self) -> Vec<Blade> {
        self.cuts
            .as_ref()
            .map(|c| c.hierarchy.levels()[0].blades())
            .unwrap_or_default()
    }

    /// Level 0 as cut ([`crate::mesh::cut::CutMesh`]: each node's and element's origin in the
    /// uncut mesh), once a cut split an element.
    pub fn cut_mesh(&self) -> Option<&crate::mesh::cut::CutMesh> {
        self.cuts
            .as_ref()
            .map(|c| &c.hierarchy.levels()[0])
            .filter(|l| l.is_cut())
    }

    /// Level 0's material fraction per element (1 for an element no cut split).
    pub fn material_fractions(&self) -> Vec<f64> {
        match &self.cuts {
            Some(c) => c.hierarchy.levels()[0].fractions().to_vec(),
            None => vec![1.0; self.mesh.num_elements()],
        }
    }

    /// The uncut levels, from the stepper (level 0 this simulation's mesh).
    fn cut_state(&self) -> Result<CutState> {
        let mut meshes = vec![self.mesh.clone()];
        for l in 1..self.stepper.num_levels() {
            match self.stepper.level_mesh(l) {
                Some(m) => meshes.push(m.clone()),
                None => break,
            }
        }
        let links = match self.stepper.level_links() {
            Some(l) => l.to_vec(),
            None => Vec::new(),
        };
        if links.len() + 1 != meshes.len() {
            return Err(Error::param(
                "cut",
                format!(
                    "{} cannot cut the body: its levels' links are not available",
                    self.stepper.describe()
                ),
            ));
        }
        Ok(CutState {
            hierarchy: CutHierarchy::new(meshes, links)?,
        })
    }

    /// Carry the simulation's own parts (its model cut already) to level 0's cut mesh, after
    /// the stepper took the cut.
    fn carry(&mut self, ch: &TopologyChange, state: &CutState) {
        let n = ch.mesh.num_nodes();
        let mut copies: Vec<Vec<u32>> = vec![Vec::new(); self.mesh.num_nodes()];
        for (a, &o) in ch.node_from.iter().enumerate() {
            copies[o as usize].push(a as u32);
        }
        self.mesh = ch.mesh.clone();
        self.file_ids = self.file_ids.as_ref().map(|f| ch.carry(f, 1));
        let (sys, _) = self.stepper.finest();
        self.mass = sys.mass.clone();
        self.f_ext = sys.f_ext.clone();
        self.own = (0..n).map(|a| sys.constraints.is_constrained(a)).collect();

        self.positions = vec![[0.0; 3]; n];
        self.r = vec![0.0; 3 * n];
        self.stress = None;
        self.checkpoint = Default::default();
        self.last_delta.clear();
        self.last_moves.clear();
        self.last_grabs.clear();
        self.tangent_operator = None;
        let every = |nodes: &[u32]| -> Vec<u32> {
            let mut v: Vec<u32> = nodes
                .iter()
                .flat_map(|&a| copies[a as usize].iter().copied())
                .collect();
            v.sort_unstable();
            v
        };
        let ids: Vec<super::GrabId> = self.grabs.keys().copied().collect();
        for id in ids {
            let g = &self.grabs[&id];
            let mut nodes = Vec::new();
            let mut offsets = Vec::new();
            for (i, &a) in g.nodes.iter().enumerate() {
                for &c in &copies[a as usize] {
                    nodes.push(c);
                    offsets.push(g.offsets[i]);
                }
            }
            let mut order: Vec<usize> = (0..nodes.len()).collect();
            order.sort_by_key(|&i| nodes[i]);
            let nodes: Vec<u32> = order.iter().map(|&i| nodes[i]).collect();
            let offsets: Vec<[f64; 3]> = order.iter().map(|&i| offsets[i]).collect();
            let total: f64 = nodes.iter().map(|&a| self.mass[a as usize]).sum();
            let weights = nodes
                .iter()
                .map(|&a| match total > 0.0 {
                    true => self.mass[a as usize] / total,
                    false => 1.0 / nodes.len() as f64,
                })
                .collect();
            let coarse = self.coarse_of(&nodes);
            let g = self.grabs.get_mut(&id).expect("grasp");
            g.nodes = nodes;
            g.offsets = offsets;
            g.weights = weights;
            g.coarse = coarse;
            g.warm = Default::default();
        }
        let pins: Vec<super::PinId> = self.pins.keys().copied().collect();
        for id in pins {
            let nodes = every(&self.pins[&id].levels[0]);
            let levels = self.pin_levels(nodes);
            self.pins.get_mut(&id).expect("pin").levels = levels;
        }
        // The drawn surface: the cut body's own (a visual surface would bridge the wound).
        self.visual = None;
        let surface = state.hierarchy.levels()[0].surface();
        self.surface.clone_from(&surface.boundary);
        self.embedded = Some(Embedded {
            surface,
            positions: Vec::new(),
        });
        // The grasps and pins on the new nodes; the caches at the carried state.
        self.constraints_changed();
    }
}
