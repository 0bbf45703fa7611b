//! Multigrid integration over a hierarchy of independent meshes.
//!
//! Two schemes behind the same [`Stepper`](crate::integrate::Stepper) interface as
//! single-level integration (SLIM):
//! - [`raisov::Raisov`]: the paper's RaISoV V-cycle (Wu & Tendick 2004, eqs. 8-13), exactly as
//!   `docs/raisov-reading.md` reads it, with both up-stroke readings;
//! - [`fas::Fas`]: the project's own full-approximation-scheme multigrid built from the same
//!   ingredients (host weights both ways, explicit damped integrators as smoothers, coarse
//!   changes carried up as variations), which converges to SLIM's equilibrium.
//!
//! Every level is a full [`System`] (`M ü + α M u̇ + R(u) = V` on that mesh) with its own
//! constraints: fixed regions re-selected on every level, a prescribed displacement of level 0
//! carried to the nearest node of each coarser level (paper section 3.1).

pub mod fas;
pub mod raisov;

use crate::hierarchy::Correspondence;
#[cfg(test)]
use crate::hierarchy::Transfer;
use crate::integrate::{Integrator, Method, State, System};
use crate::mesh::Mesh;

/// One level: its mesh, system, state and integrator.
pub struct Level {
    /// The level's mesh.
    pub mesh: Mesh,
    /// Its system.
    pub sys: System,
    /// Its state.
    pub state: State,
    /// Its explicit integrator (smoother or single-level stepping).
    pub integrator: Box<dyn Integrator>,
    /// This level's time step (s).
    pub dt: f64,
    /// Upper bound on the largest eigenvalue of M⁻¹K at small strain (1/s²), from
    /// [`crate::integrate::stability::max_gradient_sum`]: `λ_max ≤ c² max_e npe Σ|∇N_a|²`.
    pub lambda_max: f64,
    /// Force evaluations so far on this level.
    pub evaluations: u64,
    /// The file's id of each node where the mesh was renumbered at load (node `a` of `mesh`
    /// is node `node_keys[a]` of the file), else `None` (ids are the file's). What should not
    /// depend on the numbering in memory is keyed by these: FAS's power-iteration start
    /// vector.
    pub node_keys: Option<Vec<u32>>,
}

impl Level {
    /// A level at rest with time step `dt` (s) and the small-strain bound `lambda_max` (1/s²).
    pub fn new(mesh: Mesh, sys: System, method: Method, dt: f64, lambda_max: f64) -> Self {
        let n = mesh.num_nodes();
        let mut state = State::at_rest(n);
        sys.impose(0.0, &mut state.u, &mut state.v);
        Level {
            mesh,
            sys,
            state,
            integrator: method.build(n),
            dt,
            lambda_max,
            evaluations: 0,
            node_keys: None,
        }
    }
    /// Number of nodes.
    pub fn num_nodes(&self) -> usize {
        self.mesh.num_nodes()
    }

    /// Carry the level to its cut mesh (`change`): the system ([`System::cut`]), the state
    /// (each new node a copy of its node), the integrator, the node keys and the mesh.
    pub fn cut(&mut self, change: &crate::mesh::cut::TopologyChange) -> crate::Result<()> {
        self.sys.cut(change)?;
        let n = change.mesh.num_nodes();
        self.state.u = change.carry(&self.state.u, 3);
        self.state.v = change.carry(&self.state.v, 3);
        self.integrator = self.integrator.method().build(n);
        self.node_keys = self.node_keys.as_ref().map(|k| change.carry(k, 1));
        self.mesh = change.mesh.clone();
        Ok(())
    }
}

/// A multigrid stepper's levels taken out and carried to their cut meshes ([`Level::cut`]),
/// for the stepper to be built again on them; an error for a cut of another number of
/// levels, the levels put back. A level that fails leaves the levels before it cut: the
/// stepper is not to be stepped again (a force model that cannot be cut refuses on every
/// level alike, before anything changed).
pub(crate) fn take_cut_levels(
    levels: &mut Vec<Level>,
    cut: &crate::hierarchy::cut::HierarchyCut,
) -> crate::Result<Vec<Level>> {
    let mut taken = std::mem::take(levels);
    match cut_levels(&mut taken, cut) {
        Ok(()) => Ok(taken),
        Err(e) => {
            *levels = taken;
            Err(e)
        }
    }
}

fn cut_levels(
    levels: &mut [Level],
    cut: &crate::hierarchy::cut::HierarchyCut,
) -> crate::Result<()> {
    if cut.levels.len() != levels.len() || cut.links.len() + 1 != levels.len() {
        return Err(crate::Error::param(
            "cut",
            format!(
                "the cut has {} levels for the stepper's {}",
                cut.levels.len(),
                levels.len()
            ),
        ));
    }
    // The levels are independent: in parallel (each level's result is the same bits).
    use rayon::prelude::*;
    levels
        .par_iter_mut()
        .zip(cut.levels.par_iter())
        .map(|(lv, ch)| lv.cut(ch))
        .collect::<Vec<_>>()
        .into_iter()
        .collect()
}

/// A node field read by the host sums, one 3-vector per node: a stored vector, or the
/// difference of two.
pub(crate) trait Field: Copy {
    fn at(self, node: usize) -> [f64; 3];
}
impl Field for &[[f64; 3]] {
    #[inline(always)]
    fn at(self, node: usize) -> [f64; 3] {
        self[node]
    }
}
/// `x − y`, node by node, never stored (the same bits as summing a stored `x − y`).
#[derive(Clone, Copy)]
pub(crate) struct Diff<'a>(pub &'a [[f64; 3]], pub &'a [[f64; 3]]);
impl Field for Diff<'_> {
    #[inline(always)]
    fn at(self, node: usize) -> [f64; 3] {
        sub(self.0[node], self.1[node])
    }
}

pub(crate) use crate::geometry::sub;

/// A flat field (3 entries per node) as one 3-vector per node.
pub(crate) fn rows(s: &[f64]) -> &[[f64; 3]] {
    let (r, rest) = s.as_chunks::<3>();
    debug_assert!(rest.is_empty());
    r
}

/// [`rows`], mutable.
pub(crate) fn rows_mut(s: &mut [f64]) -> &mut [[f64; 3]] {
    let (r, rest) = s.as_chunks_mut::<3>();
    debug_assert!(rest.is_empty());
    r
}

/// Node-wise weighted sum `Σ_j ω_j src[host_j]` of one 3-vector field at point `p` of `t`
/// (summed over the hosts in order, from zero).
#[cfg(test)]
pub(crate) fn weighted<S: Field>(t: &Transfer, p: usize, src: S) -> [f64; 3] {
    let (w, h) = (&t.weights[p], &t.nodes[p]);
    if t.npe == 4 {
        weighted_n::<4, 1, S>(w, h, [src])[0]
    } else {
        weighted_n::<3, 1, S>(w, h, [src])[0]
    }
}

/// [`weighted`] of two fields at once (one pass over the hosts; the same bits as two calls).
#[cfg(test)]
pub(crate) fn weighted2<S: Field>(t: &Transfer, p: usize, a: S, b: S) -> [[f64; 3]; 2] {
    let (w, h) = (&t.weights[p], &t.nodes[p]);
    if t.npe == 4 {
        weighted_n::<4, 2, S>(w, h, [a, b])
    } else {
        weighted_n::<3, 2, S>(w, h, [a, b])
    }
}

/// `Σ_j w_j src[nodes_j]` over the first `N` hosts (unrolled) of `F` fields, summed from zero
/// over the hosts in order: [`weighted`] and [`weighted2`] at one point, given its weights
/// and hosts.
#[inline(always)]
pub(crate) fn weighted_n<const N: usize, const F: usize, S: Field>(
    w: &[f64; 4],
    nodes: &[u32; 4],
    src: [S; F],
) -> [[f64; 3]; F] {
    let mut out = [[0.0; 3]; F];
    for j in 0..N {
        let a = nodes[j] as usize;
        for (o, s) in out.iter_mut().zip(src) {
            let x = s.at(a);
            o[0] += w[j] * x[0];
            o[1] += w[j] * x[1];
            o[2] += w[j] * x[2];
        }
    }
    out
}

/// `|x|`: the reference for [`Above`].
#[cfg(test)]
pub(crate) fn norm3(x: [f64; 3]) -> f64 {
    (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt()
}

/// `|x| > eps` as a comparison of `|x|²` against a threshold, without the square root: the
/// same decision as `norm3(x) > eps` for every `x` (NaN included), since the rounded square
/// root is monotone and [`Above::new`] finds the largest `s` with `√s ≤ eps`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Above(f64);
impl Above {
    pub(crate) fn new(eps: f64) -> Above {
        if eps.is_nan() || eps < 0.0 {
            // √s > eps for every s ≥ 0 (and for no NaN).
            return Above(-1.0);
        }
        if eps == f64::INFINITY {
            return Above(f64::INFINITY);
        }
        let up = |s: f64| f64::from_bits(s.to_bits() + 1);
        let down = |s: f64| f64::from_bits(s.to_bits() - 1);
        let mut s = eps * eps;
        while s > 0.0 && s.sqrt() > eps {
            s = down(s);
        }
        while s < f64::MAX && up(s).sqrt() <= eps {
            s = up(s);
        }
        Above(s)
    }
    #[inline(always)]
    pub(crate) fn test(self, x: [f64; 3]) -> bool {
        x[0] * x[0] + x[1] * x[1] + x[2] * x[2] > self.0
    }
}

/// Force evaluations over all levels in finest-level units: `Σ_i evals_i n_i / n_0`.
pub fn finest_equivalent_evaluations(levels: &[Level]) -> f64 {
    let n0 = levels[0].num_nodes() as f64;
    levels
        .iter()
        .map(|l| l.evaluations as f64 * l.num_nodes() as f64 / n0)
        .sum()
}

/// Hold level 0's `k`-th prescribed node at `values[k]`, and the node of each coarser level
/// that carries it (the nearest node to its reference position, section 3.1).
pub(crate) fn hold_on_levels(levels: &mut [Level], values: &[[f64; 3]]) {
    crate::integrate::hold(&mut levels[0].sys.constraints, values);
    let points: Vec<[f64; 3]> = levels[0]
        .sys
        .constraints
        .prescribed
        .iter()
        .map(|(a, _)| levels[0].mesh.nodes[*a as usize])
        .collect();
    for lv in levels.iter_mut().skip(1) {
        for (p, &d) in points.iter().zip(values) {
            let Some(n) = lv.mesh.nearest_node(*p) else {
                continue;
            };
            for (a, m) in lv.sys.constraints.prescribed.iter_mut() {
                if *a as usize == n {
                    *m = crate::time::Motion::Held { d };
                }
            }
        }
    }
}

/// Links between consecutive levels: `links[i]` joins level i (fine) and i+1 (coarse).
pub type Links = Vec<Correspondence>;

/// Levels and correspondences, one line each, then, where the paper's covering condition
/// (section 2.1) fails on some link, one paragraph saying what that means: a `note:` while the
/// uncovered nodes are at most [`UNCOVERED_WARN_SHARE`] of every level's, else a `warning:`.
///
/// Covering: a fine node is covered when it is a corner of the fine element that hosts some
/// node of the next coarser level. Restricting a state interpolates the fine state at the
/// coarse nodes, so an uncovered node's own value does not enter it; residual forces are
/// restricted by the transpose of the interpolation, in which every fine node takes part, so
/// FAS converges to the single-level equilibrium with or without uncovered nodes. The paper's
/// RaISoV cycle transfers states and variations only: there an uncovered node's own motion
/// reaches the coarser levels only through its neighbours.
pub fn hierarchy_report(levels: &[Level], links: &Links) -> String {
    let mut out = String::new();
    for (i, l) in levels.iter().enumerate() {
        out += &format!(
            "level {i}: {} nodes, {} elements, dt = {:.4e} s, {}\n",
            l.num_nodes(),
            l.mesh.num_elements(),
            l.dt,
            l.integrator.method().name()
        );
    }
    for (i, c) in links.iter().enumerate() {
        out += &format!("link {i}-{}: {}\n", i + 1, c.report);
    }
    out += &covering_note(
        links
            .iter()
            .enumerate()
            .filter(|(_, c)| !c.report.covered)
            .map(|(i, c)| (i, levels[i].num_nodes(), c.report.uncovered_fine_nodes)),
    );
    out
}

/// The share of a level's nodes left uncovered above which [`hierarchy_report`] warns.
pub const UNCOVERED_WARN_SHARE: f64 = 0.1;

/// The paragraph of [`hierarchy_report`] for the uncovered links `(fine level, its nodes,
/// uncovered nodes)`; empty where there are none.
fn covering_note(uncovered: impl Iterator<Item = (usize, usize, usize)>) -> String {
    let links: Vec<(usize, usize, usize)> = uncovered.collect();
    if links.is_empty() {
        return String::new();
    }
    let parts: Vec<String> = links
        .iter()
        .map(|(level, nodes, u)| format!("{u} of level {level}'s {nodes} nodes"))
        .collect();
    let list = match parts.as_slice() {
        [one] => one.clone(),
        [init @ .., last] => format!("{} and {last}", init.join(", ")),
        [] => String::new(),
    };
    let verb = if links.len() == 1 && links[0].2 == 1 {
        "is"
    } else {
        "are"
    };
    let large = links
        .iter()
        .any(|&(_, n, u)| u as f64 > UNCOVERED_WARN_SHARE * n as f64);
    let (head, verdict) = if large {
        (
            "warning",
            "That is a large share: a coarse level much coarser than its neighbour (raise \
             `ratio` or its `level_nodes`) or levels that do not overlap.",
        )
    } else {
        (
            "note",
            "A few such nodes are usual for independent meshes and harmless.",
        )
    };
    format!(
        "{head}: levels not covered (\"covering: no\" above): {list} {verb} a corner of no \
         element hosting a node of the next coarser level, so restricting the state skips \
         them. FAS (the default) restricts residual forces through every node and converges \
         to the same equilibrium as one level; with scheme = \"raisov-paper\" their own \
         motion reaches the coarser levels only through their neighbours. {verdict}\n"
    )
}

#[cfg(test)]
mod tests;
