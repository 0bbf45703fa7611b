//! Nested iteration (a coarse start): the fine Newton iteration starts from the equilibrium of
//! a coarser discretisation of the same body, interpolated.
//!
//! ```text
//! R_H(u_H) = V_H            (the coarse level's static problem, its own mesh, constraints, loads)
//! u_h⁰     = I_H^h u_H      (u_h⁰(θ) = Σ_j ω_θj u_H(j), the host weights of the fine nodes)
//! ```
//!
//! The fine nodes outside the coarse mesh ([`Transfer::outside`]: where the fine surface
//! bulges out of the coarse one) are not interpolated: their displacement is the discrete
//! harmonic extension of the inside nodes', [`HARMONIC_SWEEPS`] Jacobi sweeps of
//! `u_a ← mean of u_b over a's mesh neighbours b`, from the convex interpolation
//! ([`Transfer::convex`]). Extrapolated weights (2-3 at the liver's surface) and the convex
//! ones alike move such nodes millimetres away from their neighbours and invert fine
//! elements (30 of the liver L0's 79 680 from its L2 level). Where the coarse mesh cannot
//! resolve a boundary layer (a node of the fixed cap between free nodes that the coarse
//! field moves by millimetres) fine elements still invert (4 on the liver L0); up to
//! [`REPAIR_ROUNDS`] rounds add their nodes and their neighbours to the extended set, then
//! up to [`SHRINK_ROUNDS`] rounds halve the displacement of the free nodes of the elements
//! still inverted (a sliver at the fixed cap whose free corner the extension moves past
//! the plane of its three held ones).
//!
//! `R_H` is the coarse mesh's own discretisation (rediscretised, not Galerkin), so `u_h⁰`
//! differs from the fine equilibrium by the discretisation error of the coarse mesh: the
//! large, smooth part of the displacement (a sag under gravity, a drape's shape, the field of
//! a pull) is in place before the first fine tangent, and the fine iteration has only that
//! difference left to remove, mostly in Newton's quadratic phase. The coarse problem (the
//! level of [`super::newton::coarse_level`]: 1/16 of the nodes or fewer where the levels allow), is
//! solved by direct Newton with
//! factorisation reuse ([`COARSE_PCG_MAX`]) to [`COARSE_REL_TOL`], over the caller's load
//! steps; the fine iteration then takes the full load in one step.
//!
//! Through several levels ([`nested_start`], the levels of [`start_levels`]: each
//! about a quarter of the next finer one's nodes where the levels allow, the coarsest with
//! at least 1 000 nodes or as many as the coarse level):
//!
//! ```text
//! R_m(u_m) = V_m                        the coarsest level, direct Newton, from rest
//! R_l(u_l) = V_l,  u_l⁰ = I_{l+1}^l u_{l+1}   l = m−1, …, 1: Newton-multigrid over l, l+1
//! u_h⁰     = I_1^h u_1
//! ```
//!
//! the interpolation at each level as at the fine one below. Each level starts within its
//! coarser neighbour's discretisation error of its own equilibrium, which it reaches in a
//! few Newton iterations on a quarter of the finer level's nodes; the fine iteration starts
//! within the finest start level's error, not the coarse level's (the 100k drape: 5 fine
//! Newton iterations through 25k, 6k and 1.5k levels, 8 from 6k alone; `bench/RESULTS.md`).
//! The levels between are solved to [`BETWEEN_REL_TOL`].
//!
//! The constrained dofs of every level take their imposed values, and keep them through the
//! harmonic extension below. The start is not taken (`u` is left as it was) where a level's
//! solve fails or does not converge, or where an interpolation inverts an element
//! (`det F ≤ 0`) of the level it reaches.

use super::newton::{
    solve_system, DirectNewton, DirectNewtonError, DirectNewtonParams, DirectStatic, MultigridPcg,
    Smoother,
};
use crate::fem::ForceModel;
use crate::hierarchy::Transfer;
use crate::integrate::{Constraints, System};

/// Relative stopping rule of the coarse solve (of its largest nodal external force).
pub const COARSE_REL_TOL: f64 = 1e-6;

/// Conjugate-gradient iterations on a kept factorisation before the coarse solve refactors
/// ([`DirectNewtonParams::pcg_max`]). A coarse drape's first iterations from flat, with a
/// nearly singular regularised tangent, miss η with any kept factor, so each one spent all of
/// them before refactoring; a coarse factorisation costs about as much as a few of these solves
/// (`bench/RESULTS.md`: 20, 10, 5, 2 and 0 on the 100k drape's 6 188-node level).
pub const COARSE_PCG_MAX: usize = 5;

/// Relative stopping rule of the solves of the levels between the coarsest and the fine one
/// ([`nested_start`]; of each level's largest nodal external force).
pub const BETWEEN_REL_TOL: f64 = 1e-6;

/// Consecutive levels of a nested start, and the fine level and the finest of them, are at
/// least `NESTED_GAP` times apart in node count ([`start_levels`]).
pub const NESTED_GAP: usize = 3;

/// A nested start's coarsest level has at least `START_MIN_NODES` nodes, or as many as
/// Newton-multigrid's coarse level where that has fewer ([`start_levels`]).
pub const START_MIN_NODES: usize = 1000;

/// Of levels with `nodes[l]` nodes (finest first) and Newton-multigrid's coarse level
/// `coarse` ([`super::newton::coarse_level`]), the levels a nested start passes through ([`nested_start`]),
/// finest first. The last, solved first by direct Newton, is the coarsest level with at
/// least [`START_MIN_NODES`] nodes or as many as `coarse`; above it, each is the coarsest
/// level with at least [`NESTED_GAP`] times the nodes of the one below and at most
/// 1/[`NESTED_GAP`] of the fine level's. Empty where `coarse` is not a coarser level.
///
/// The fine iteration started from a finer level's equilibrium has less discretisation
/// error left to remove, and each level but the coarsest is solved by Newton-multigrid over
/// itself and the next one, from that one's equilibrium (`bench/RESULTS.md`: the 100k drape
/// through 25k, 6k and 1.5k levels against from its 6k level alone).
pub fn start_levels(nodes: &[usize], coarse: usize) -> Vec<usize> {
    let (Some(&n0), Some(&nc)) = (nodes.first(), nodes.get(coarse)) else {
        return Vec::new();
    };
    if coarse == 0 {
        return Vec::new();
    }
    let floor = nc.min(START_MIN_NODES);
    let Some(bottom) = (1..nodes.len()).rev().find(|&l| nodes[l] >= floor) else {
        return Vec::new();
    };
    let mut out = vec![bottom];
    let mut last = nodes[bottom];
    while let Some(l) = (1..*out.last().expect("one"))
        .rev()
        .find(|&l| nodes[l] >= NESTED_GAP * last && nodes[l] * NESTED_GAP <= n0)
    {
        out.push(l);
        last = nodes[l];
    }
    out.reverse();
    out
}

/// What [`coarse_start`] did.
#[derive(Clone, Debug, Default)]
pub struct CoarseStart {
    /// The coarse solve's outcome (`None` where it failed before an outcome).
    pub coarse: Option<DirectStatic>,
    /// The outcomes of the solves of the levels between ([`nested_start`]), coarsest first.
    pub between: Vec<DirectStatic>,
    /// The node counts of the start's levels, coarsest first.
    pub nodes: Vec<usize>,
    /// Whether `u` now holds the interpolated coarse equilibrium.
    pub applied: bool,
    /// Why not, where not.
    pub skipped: Option<String>,
    /// Wall time of the coarse solve and the interpolation (s).
    pub wall_s: f64,
}

impl CoarseStart {
    /// The fine solve's load steps: one after a start that was taken (the coarse solve
    /// applied the `requested` ones), else `requested`.
    pub fn fine_load_steps(start: Option<&CoarseStart>, requested: usize) -> usize {
        if start.is_some_and(|s| s.applied) {
            1
        } else {
            requested
        }
    }

    /// One line for a summary: the coarse solve's Newton iterations and wall time, or why the
    /// start was not taken.
    pub fn describe(&self) -> String {
        if self.applied {
            let between: String = self
                .between
                .iter()
                .zip(self.nodes.iter().skip(1))
                .map(|(o, n)| format!(", then {} on {n} nodes", o.newton_steps))
                .collect();
            format!(
                "coarse start: {} Newton iterations on {} nodes{between} ({:.3} s)",
                self.coarse.as_ref().map_or(0, |o| o.newton_steps),
                self.nodes.first().copied().unwrap_or(0),
                self.wall_s
            )
        } else {
            format!(
                "coarse start not taken: {}",
                self.skipped.as_deref().unwrap_or("")
            )
        }
    }
}

/// Solve `coarse` at time `t` over `load_steps` load steps from rest, and where that
/// succeeds write its equilibrium, interpolated at the fine nodes by `fine_in_coarse` (the
/// fine nodes located in the coarse mesh), into the fine displacement `u`, the values
/// `fine_constraints` impose at `t` on the constrained dofs (module docs). `fine` checks
/// that the start inverts no element. [`nested_start`] with no level between.
pub fn coarse_start(
    coarse: &mut System,
    t: f64,
    load_steps: usize,
    fine_in_coarse: &Transfer,
    fine: &dyn ForceModel,
    fine_constraints: &Constraints,
    u: &mut [f64],
) -> CoarseStart {
    start_through(
        coarse,
        &mut [],
        t,
        load_steps,
        fine_in_coarse,
        fine,
        fine_constraints,
        u,
        BetweenSolve::Direct,
    )
}

/// A level between the fine level and the coarsest one of a nested start ([`nested_start`]).
pub struct StartLevel {
    /// Its static problem: its own mesh, the scenario's constraints and loads carried to it.
    pub system: System,
    /// Its nodes located in the next coarser level of the start.
    pub down: Transfer,
}

/// How a nested start solves the levels between its coarsest and the fine one
/// ([`nested_start`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BetweenSolve {
    /// Newton-multigrid over the level and the next coarser one of the start, with this
    /// smoother (the other settings [`MultigridPcg`]'s defaults): the static scenarios'.
    Multigrid(Smoother),
    /// Direct Newton, its factorisation reused by conjugate gradients as the coarsest level's
    /// is ([`COARSE_PCG_MAX`]): a start made by direct Newton alone, as the equilibrium
    /// bench gives its direct Newton.
    Direct,
}

/// The levels of a nested start ([`nested_start`]).
pub struct NestedLevels {
    /// The coarsest level's static problem, solved first, by direct Newton.
    pub coarsest: System,
    /// The levels between the fine and the coarsest one, finest first.
    pub between: Vec<StartLevel>,
    /// The fine nodes located in the finest level of the start (the first of `between`, or
    /// `coarsest` where `between` is empty).
    pub fine_in_first: Transfer,
}

/// Nested iteration over several levels (module docs): `levels.coarsest` solved by direct
/// Newton over `load_steps` load steps from rest; then each level of `levels.between`
/// (finest first, each one's [`StartLevel::down`] locating its nodes in the next coarser
/// level, the last one's in the coarsest), coarsest first, started from the coarser
/// equilibrium interpolated and solved in one load step to [`BETWEEN_REL_TOL`] as `solve`
/// says; the last equilibrium is interpolated at the fine nodes into
/// `u` as in [`coarse_start`]. The start is not taken where any level's solve fails or does
/// not converge, or where an interpolation inverts an element of the level it reaches.
pub fn nested_start(
    levels: &mut NestedLevels,
    t: f64,
    load_steps: usize,
    fine: &dyn ForceModel,
    fine_constraints: &Constraints,
    u: &mut [f64],
    solve: BetweenSolve,
) -> CoarseStart {
    let NestedLevels {
        coarsest,
        between,
        fine_in_first,
    } = levels;
    start_through(
        coarsest,
        between,
        t,
        load_steps,
        fine_in_first,
        fine,
        fine_constraints,
        u,
        solve,
    )
}

/// [`nested_start`] over its levels' parts.
#[allow(clippy::too_many_arguments)]
fn start_through(
    coarsest: &mut System,
    between: &mut [StartLevel],
    t: f64,
    load_steps: usize,
    fine_in_first: &Transfer,
    fine: &dyn ForceModel,
    fine_constraints: &Constraints,
    u: &mut [f64],
    solve: BetweenSolve,
) -> CoarseStart {
    let clock = std::time::Instant::now();
    let mut out = CoarseStart {
        nodes: std::iter::once(coarsest.mass.len())
            .chain(between.iter().rev().map(|l| l.system.mass.len()))
            .collect(),
        ..Default::default()
    };
    let mut uc = vec![0.0; coarsest.mass.len() * 3];
    let solved = solve_system(
        coarsest,
        t,
        &mut uc,
        DirectNewtonParams {
            rel_tol: COARSE_REL_TOL,
            load_steps: load_steps.max(1),
            pcg_max: COARSE_PCG_MAX,
            ..Default::default()
        },
    );
    let converged = match solved {
        Err(e) => {
            out.skipped = Some(format!("the coarse solve failed: {e}"));
            false
        }
        Ok(o) => {
            if !o.converged {
                out.skipped = Some(format!(
                    "the coarse solve did not converge ({} Newton iterations, residual {:.3e} N)",
                    o.newton_steps, o.residual
                ));
            }
            let c = o.converged;
            out.coarse = Some(o);
            c
        }
    };
    if converged {
        match climb(between, t, uc, solve, &mut out) {
            Err(why) => out.skipped = Some(why),
            Ok(ub) => match interpolate(&ub, fine_in_first, fine, fine_constraints, t) {
                Err(why) => out.skipped = Some(why),
                Ok(start) => {
                    u.copy_from_slice(&start);
                    out.applied = true;
                }
            },
        }
    }
    out.wall_s = clock.elapsed().as_secs_f64();
    out
}

/// The levels of `between`, coarsest first, each started from the coarser level's
/// equilibrium `uc` interpolated and solved as `solve` says ([`nested_start`]); the
/// finest one's equilibrium (`uc` itself where `between` is empty), or why not.
fn climb(
    between: &mut [StartLevel],
    t: f64,
    mut uc: Vec<f64>,
    solve: BetweenSolve,
    out: &mut CoarseStart,
) -> Result<Vec<f64>, String> {
    for level in between.iter_mut().rev() {
        let System {
            force,
            f_ext,
            constraints,
            mass,
            springs,
            ..
        } = &mut level.system;
        let model = &mut **force;
        if model.tangent_elements().is_none() {
            return Err(DirectNewtonError::NotFem.to_string());
        }
        let mut ul = interpolate(&uc, &level.down, model, constraints, t)?;
        let params = DirectNewtonParams {
            rel_tol: BETWEEN_REL_TOL,
            ..Default::default()
        };
        let o = match solve {
            BetweenSolve::Multigrid(smoother) => DirectNewton::with_levels(
                model,
                mass,
                constraints,
                std::slice::from_ref(&level.down),
            )
            .and_then(|mut s| {
                let multigrid = Some(MultigridPcg {
                    smoother,
                    ..Default::default()
                });
                let p = DirectNewtonParams {
                    multigrid,
                    ..params
                };
                s.solve(model, springs, constraints, f_ext, t, &mut ul, p)
            }),
            BetweenSolve::Direct => {
                DirectNewton::new(model, mass, constraints).and_then(|mut s| {
                    let p = DirectNewtonParams {
                        pcg_max: COARSE_PCG_MAX,
                        ..params
                    };
                    s.solve(model, springs, constraints, f_ext, t, &mut ul, p)
                })
            }
        }
        .map_err(|e| {
            format!(
                "the solve of a {}-node level failed: {e}",
                model.num_nodes()
            )
        })?;
        let converged = o.converged;
        let (steps, residual) = (o.newton_steps, o.residual);
        out.between.push(o);
        if !converged {
            return Err(format!(
                "the solve of a {}-node level did not converge ({steps} Newton iterations, residual {residual:.3e} N)",
                model.num_nodes()
            ));
        }
        uc = ul;
    }
    Ok(uc)
}

/// The coarser equilibrium `uc` interpolated at the nodes `into` locates in it, onto the
/// level of `model`, the values `constraints` impose at `t` on its constrained dofs, its
/// nodes outside the coarser mesh extended harmonically and inverted elements repaired
/// (module docs); an error where the result still inverts an element.
fn interpolate(
    uc: &[f64],
    into: &Transfer,
    model: &dyn ForceModel,
    constraints: &Constraints,
    t: f64,
) -> Result<Vec<f64>, String> {
    let n = 3 * into.len();
    let mut start = vec![0.0; n];
    into.convex()
        .interpolate(uc, 3, &mut start)
        .map_err(|e| format!("interpolation: {e}"))?;
    let mut v = vec![0.0; n];
    constraints.impose(t, &mut start, &mut v);
    repair(model, constraints, &into.outside, &mut start);
    constraints.impose(t, &mut start, &mut v);
    let (e, det) = model.min_det_f(&start);
    if det > 0.0 && start.iter().all(|x| x.is_finite()) {
        Ok(start)
    } else {
        Err(format!(
            "the interpolated coarse equilibrium inverts element {e} of the {}-node level (det F = {det:.3e})",
            model.num_nodes()
        ))
    }
}

/// Jacobi sweeps of each harmonic extension.
pub const HARMONIC_SWEEPS: usize = 30;

/// Rounds of repair of inverted elements by harmonic extension.
pub const REPAIR_ROUNDS: usize = 4;

/// Rounds of repair of inverted elements by halving their free nodes' displacements.
pub const SHRINK_ROUNDS: usize = 10;

/// The harmonic extension over the `outside` nodes, then up to [`REPAIR_ROUNDS`] rounds that
/// add the nodes of the elements still inverted, and their neighbours, to the extended set,
/// then up to [`SHRINK_ROUNDS`] halvings of the free nodes of the elements still inverted
/// (module docs); the nodes `held` constrains keep their values.
fn repair(fine: &dyn ForceModel, held: &Constraints, outside: &[u32], u: &mut [f64]) {
    let n = u.len() / 3;
    let Some(elements) = fine.tangent_elements() else {
        return;
    };
    let graph = node_graph(&elements, n);
    let mut set = vec![false; n];
    for &a in outside {
        set[a as usize] = true;
    }
    for round in 0..=REPAIR_ROUNDS {
        if round > 0 {
            let inverted: Vec<usize> = (0..elements.len())
                .filter(|&e| fine.element_det_f(e, u) <= 0.0)
                .collect();
            if inverted.is_empty() {
                return;
            }
            for e in inverted {
                for &a in elements.element(e) {
                    set[a as usize] = true;
                    for &b in graph.neighbours(a as usize) {
                        set[b as usize] = true;
                    }
                }
            }
        }
        let nodes: Vec<usize> = (0..n)
            .filter(|&a| set[a] && !held.is_constrained(a))
            .collect();
        harmonic(&graph, &nodes, u);
    }
    for _ in 0..SHRINK_ROUNDS {
        let inverted: Vec<usize> = (0..elements.len())
            .filter(|&e| fine.element_det_f(e, u) <= 0.0)
            .collect();
        if inverted.is_empty() {
            return;
        }
        let mut shrink = vec![false; n];
        for e in inverted {
            for &a in elements.element(e) {
                shrink[a as usize] = !held.is_constrained(a as usize);
            }
        }
        for (a, _) in shrink.iter().enumerate().filter(|(_, &s)| s) {
            u[3 * a..3 * a + 3].iter_mut().for_each(|x| *x *= 0.5);
        }
    }
}

/// The mesh graph: each node's neighbours (nodes sharing an element), sorted.
struct Graph {
    ptr: Vec<usize>,
    adj: Vec<u32>,
}

impl Graph {
    fn neighbours(&self, a: usize) -> &[u32] {
        &self.adj[self.ptr[a]..self.ptr[a + 1]]
    }
}

fn node_graph(elements: &crate::fem::ElementTopology<'_>, n: usize) -> Graph {
    let mut lists: Vec<Vec<u32>> = vec![Vec::new(); n];
    for e in 0..elements.len() {
        let nodes = elements.element(e);
        for &a in nodes {
            lists[a as usize].extend(nodes.iter().filter(|&&b| b != a));
        }
    }
    let mut ptr = Vec::with_capacity(n + 1);
    ptr.push(0);
    let mut adj = Vec::new();
    for mut l in lists {
        l.sort_unstable();
        l.dedup();
        adj.extend(l);
        ptr.push(adj.len());
    }
    Graph { ptr, adj }
}

/// [`HARMONIC_SWEEPS`] Jacobi sweeps of `u_a ← mean of u_b over a's neighbours b` over
/// `nodes`, the others held.
fn harmonic(graph: &Graph, nodes: &[usize], u: &mut [f64]) {
    let mut next = vec![[0.0; 3]; nodes.len()];
    for _ in 0..HARMONIC_SWEEPS {
        for (m, &a) in next.iter_mut().zip(nodes) {
            let list = graph.neighbours(a);
            let mut s = [0.0; 3];
            for &b in list {
                for k in 0..3 {
                    s[k] += u[3 * b as usize + k];
                }
            }
            let c = list.len().max(1) as f64;
            *m = s.map(|x| x / c);
        }
        for (m, &a) in next.iter().zip(nodes) {
            u[3 * a..3 * a + 3].copy_from_slice(m);
        }
    }
}
