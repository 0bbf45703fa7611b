//! RaISoV, Restrict-and-Interpolate-State-or-Variation (Wu & Tendick 2004, section 2.2),
//! exactly as `docs/raisov-reading.md` reads it. One time step is one V-cycle.
//!
//! State per node `X = [u; u̇]`; `X_n^(i)` a level's state at the start of cycle n, before any
//! transfer; `ΔX^(i) = X_n^(i) − X_(n−1)^(i)` (eq. 8), its whole change over the last cycle.
//! The switches use the norm of the displacement part, in metres, against ε.
//!
//! 1. Down stroke, i = 1 … m−1, node θ of level i with host γ on level i−1 (eq. 9, 10):
//!    `d = Σ_j ω_j ΔX^(i−1)_γ,j`; if `|d| > ε`: `X^(i)_θ = Σ_j ω_j X^(i−1)_γ,j` (state),
//!    else `X^(i)_θ += d` (variation).
//! 2. Up stroke, i = m−1 … 0: if i < m−1, node θ of level i with host Γ on level i+1
//!    (eq. 11, 12): if `|ΔX^(i)_θ| > ε`: `X^(i)_θ = Σ ω X^(i+1)_Γ` (state), else
//!    `X^(i)_θ += Σ ω δX^(i+1)_Γ` (variation). Then one integrator step G on level i (eq. 13).
//!    `δX^(i+1)` by [`Reading`]:
//!    - `Paper`: eq. 8 literally, level i+1's state now minus its `X_n` (all it changed this
//!      cycle, including what was restricted down from level i);
//!    - `Correction`: the classic coarse-grid correction, level i+1's state after its whole
//!      up-stroke (its transfer from level i+2 and its own G step) minus its state before it
//!      received anything from level i+2, i.e. just after its down-stroke transfer. Every
//!      coarser level's correction thus reaches level 0 through the levels between (test
//!      `coarsest_correction_reaches_level_zero`).
//! 3. Constrained nodes are re-imposed on every level after every transfer.
//!
//! With one level this is single-level integration, bit for bit (a test).

use super::{rows, rows_mut, sub, weighted_n, Above, Diff, Field, Level, Links};
use crate::error::{Divergence, DivergenceCause};
use crate::hierarchy::Transfer;
use crate::integrate::{
    check_state, Checkpoint, OwnConstraints, RuntimeConstraints, State, Stepper, SwitchCounts,
};
use rayon::prelude::*;

/// How the up stroke reads δX^(i+1) (design note, step 2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reading {
    /// Eq. 8 literally: `δX^(i+1)` is level i+1's state now minus its `X_n`, everything it
    /// changed this cycle, including what was restricted down from level i.
    Paper,
    /// The coarse-grid correction: `δX^(i+1)` is level i+1's state after its up stroke minus
    /// its state just after its down-stroke transfer, so every coarser level's correction
    /// reaches level 0.
    Correction,
}

/// Parameters of the literal RaISoV cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RaisovParams {
    /// The switch threshold ε of eqs. 10 and 12 (m).
    pub epsilon: f64,
    /// How the up stroke reads `δX^(i+1)` (eq. 12's variation).
    pub reading: Reading,
    /// Kinetic-energy ceiling of the finest level (J), for divergence detection.
    pub kinetic_limit: f64,
}

impl RaisovParams {
    /// The switch threshold ε as a fraction of level 0's shortest edge: the default of
    /// [`RaisovParams::for_mesh`] (and of a scenario's `[multigrid] epsilon`).
    pub const EPSILON_PER_EDGE: f64 = 1e-3;

    /// The defaults for level 0's `mesh`: ε = [`RaisovParams::EPSILON_PER_EDGE`] × its
    /// shortest edge, the [`Reading::Correction`] reading, no kinetic-energy ceiling (a
    /// scenario's, and [`crate::model::Model::stepper`]'s with a blow-up factor, sets one).
    pub fn for_mesh(mesh: &crate::mesh::Mesh) -> RaisovParams {
        RaisovParams {
            epsilon: Self::EPSILON_PER_EDGE * mesh.edge_range().0,
            reading: Reading::Correction,
            kinetic_limit: f64::INFINITY,
        }
    }
}

/// The paper's multigrid time integrator.
///
/// The bookkeeping of eq. 8 rides on the strokes instead of whole-level passes: the transfer
/// that first writes a level in a cycle (the down stroke on levels 1 … m−1, the up stroke on
/// level 0) reads `X_n` from the state's buffers, keeps `ΔX` where needed, writes the new
/// state over `X_(n−1)` and swaps the two pairs of buffers, so that `X_n` is kept without a
/// copy; level 0's `ΔX`, read only before level 0 is written, is summed as `X_n − X_(n−1)` at
/// its hosts without being stored. The same bits as the literal whole-level snapshots (test
/// `fused_cycle_equals_the_literal_cycle`).
pub struct Raisov {
    /// The levels, finest (level 0) first; each takes one integrator step G per cycle (eq. 13).
    pub levels: Vec<Level>,
    /// `links[i]`: the correspondence of level i and level i+1, its `up` transfer the
    /// restriction of eqs. 9-10 (level-(i+1) nodes hosted on level i), its `down` the
    /// interpolation of eqs. 11-12 (level-i nodes hosted on level i+1).
    pub links: Links,
    /// The threshold ε, the [`Reading`] and the divergence ceiling.
    pub params: RaisovParams,
    /// Per level: `X_(n−1)` at the start of a cycle, `X_n` once the cycle's first transfer into
    /// the level has swapped it with the state (so after the down stroke the coarse levels'
    /// are `X_n`, the `Paper` reading's base).
    prev_u: Vec<Vec<f64>>,
    prev_v: Vec<Vec<f64>>,
    /// ΔX on levels 1 … m−2, written by the down stroke (level 0's is summed on the fly, the
    /// coarsest level's is never read).
    du: Vec<Vec<f64>>,
    dv: Vec<Vec<f64>>,
    /// `Correction` reading: each coarse level's state just after its down-stroke transfer
    /// (before anything came from the level above), written by that transfer.
    up_u: Vec<Vec<f64>>,
    up_v: Vec<Vec<f64>>,
    steps: u64,
    /// Counts of state / variation transfers in the last cycle (down, up).
    pub last_switches: [(usize, usize); 2],
    /// The switch counts summed over every cycle so far ([`Stepper::switch_counts`]).
    switches: SwitchCounts,
    /// Per level, its own constraints once run-time ones were added (empty before).
    own: Vec<OwnConstraints>,
    /// Per coarse level `l ≥ 1` (index `l − 1`): the node nearest to each level-0 node a
    /// run-time grasp has held, computed once.
    carried: Vec<std::collections::HashMap<u32, u32>>,
}

impl Raisov {
    /// The integrator over `levels` (finest first) with one link per consecutive pair
    /// (`links.len() + 1 == levels.len()`, asserted); `X_(n−1)` starts at each level's state.
    pub fn new(levels: Vec<Level>, links: Links, params: RaisovParams) -> Self {
        assert_eq!(links.len() + 1, levels.len());
        let m = levels.len();
        let z = |l: &Level, used: bool| vec![0.0; if used { 3 * l.num_nodes() } else { 0 }];
        let change = |i: usize| i >= 1 && i + 1 < m;
        let snap = |i: usize| i >= 1 && params.reading == Reading::Correction;
        let each = |f: &dyn Fn(usize) -> bool| -> Vec<Vec<f64>> {
            levels.iter().enumerate().map(|(i, l)| z(l, f(i))).collect()
        };
        Raisov {
            prev_u: levels.iter().map(|l| l.state.u.clone()).collect(),
            prev_v: levels.iter().map(|l| l.state.v.clone()).collect(),
            du: each(&change),
            dv: each(&change),
            up_u: each(&snap),
            up_v: each(&snap),
            links,
            params,
            levels,
            steps: 0,
            last_switches: [(0, 0); 2],
            switches: SwitchCounts::default(),
            own: Vec::new(),
            carried: Vec::new(),
        }
    }

    fn cycle(&mut self) -> Result<(), Divergence> {
        let m = self.levels.len();
        let above = Above::new(self.params.epsilon);
        let correction = self.params.reading == Reading::Correction;
        let mut sw = [(0usize, 0usize); 2];
        // Down stroke (eqs. 9, 10), i = 1 … m−1. Every node is independent: chunks in
        // parallel, the same bits on any thread count.
        for i in 1..m {
            let t = &self.links[i - 1].up; // level-i nodes hosted on level i−1
            let (fine, coarse) = self.levels.split_at_mut(i);
            let (f, c) = (&fine[i - 1], &mut coarse[0]);
            let (src_u, src_v) = (rows(&f.state.u), rows(&f.state.v));
            let (pf_u, p_u) = lower_and(&mut self.prev_u, i);
            let (pf_v, p_v) = lower_and(&mut self.prev_v, i);
            let (df_u, d_u) = lower_and(&mut self.du, i);
            let (df_v, d_v) = lower_and(&mut self.dv, i);
            // The `Correction` reading's base: the state the down stroke leaves.
            let snapshot = correction;
            let (s_u, s_v) = if snapshot {
                (rows_mut(&mut self.up_u[i]), rows_mut(&mut self.up_v[i]))
            } else {
                (&mut [][..], &mut [][..])
            };
            let level = Rows {
                u: rows_mut(&mut c.state.u),
                v: rows_mut(&mut c.state.v),
                pu: p_u,
                pv: p_v,
                du: d_u,
                dv: d_v,
                su: s_u,
                sv: s_v,
            };
            // ΔX^(i−1) at the hosts: level 0 is unchanged so far (X_n − X_(n−1) summed on the
            // fly); a coarse level's was kept when its own down-stroke transfer wrote it.
            let counts = if i == 1 {
                down(
                    t,
                    level,
                    above,
                    [Diff(src_u, pf_u), Diff(src_v, pf_v)],
                    [src_u, src_v],
                )
            } else {
                down(t, level, above, [df_u, df_v], [src_u, src_v])
            };
            sw[0].0 += counts.0;
            sw[0].1 += counts.1;
            // The transfer wrote the new state over X_(n−1): the state's buffers now hold X_n.
            std::mem::swap(&mut c.state.u, &mut self.prev_u[i]);
            std::mem::swap(&mut c.state.v, &mut self.prev_v[i]);
            let tt = c.state.t;
            c.sys.impose(tt, &mut c.state.u, &mut c.state.v);
            if snapshot {
                c.sys.impose(tt, &mut self.up_u[i], &mut self.up_v[i]);
            }
        }
        // Up stroke (eqs. 11-13), i = m−1 … 0.
        for i in (0..m).rev() {
            if i + 1 < m {
                let t = &self.links[i].down; // level-i nodes hosted on level i+1
                let (fine, coarse) = self.levels.split_at_mut(i + 1);
                let (f, c) = (&mut fine[i], &coarse[0]);
                let (p_u, pc_u) = and_upper(&mut self.prev_u, i);
                let (p_v, pc_v) = and_upper(&mut self.prev_v, i);
                let (_, sc_u) = and_upper(&mut self.up_u, i);
                let (_, sc_v) = and_upper(&mut self.up_v, i);
                let base = match self.params.reading {
                    Reading::Paper => [pc_u, pc_v],
                    Reading::Correction => [sc_u, sc_v],
                };
                let level = Rows {
                    u: rows_mut(&mut f.state.u),
                    v: rows_mut(&mut f.state.v),
                    pu: p_u,
                    pv: p_v,
                    du: rows_mut(&mut self.du[i]),
                    dv: rows_mut(&mut self.dv[i]),
                    su: &mut [][..],
                    sv: &mut [][..],
                };
                let src = [rows(&c.state.u), rows(&c.state.v)];
                let counts = up(t, level, above, i == 0, src, base);
                sw[1].0 += counts.0;
                sw[1].1 += counts.1;
                if i == 0 {
                    // As in the down stroke: the new state is in the X_(n−1) buffers.
                    std::mem::swap(&mut f.state.u, &mut self.prev_u[0]);
                    std::mem::swap(&mut f.state.v, &mut self.prev_v[0]);
                }
                let tt = f.state.t;
                f.sys.impose(tt, &mut f.state.u, &mut f.state.v);
            }
            let l = &mut self.levels[i];
            let t0 = l.state.t;
            l.integrator
                .step(&mut l.sys, &mut l.state, l.dt)
                .map_err(|f| Divergence {
                    time: t0,
                    step: self.steps + 1,
                    element: Some(f.element),
                    cause: DivergenceCause::Inverted { det_f: f.det_f },
                })?;
            l.evaluations += l.integrator.method().evaluations();
        }
        self.last_switches = sw;
        self.switches.down_state += sw[0].0 as u64;
        self.switches.down_variation += sw[0].1 as u64;
        self.switches.up_state += sw[1].0 as u64;
        self.switches.up_variation += sw[1].1 as u64;
        Ok(())
    }
}

#[cfg(test)]
impl Raisov {
    /// Per level: `X_(n−1)` as it stands (u, v) and the `Correction` snapshot (u, v; empty on
    /// level 0 and under the `Paper` reading).
    pub(super) fn bookkeeping(&self) -> Vec<[&[f64]; 4]> {
        (0..self.levels.len())
            .map(|i| {
                [
                    &self.prev_u[i][..],
                    &self.prev_v[i][..],
                    &self.up_u[i][..],
                    &self.up_v[i][..],
                ]
            })
            .collect()
    }
}

/// `(&v[i − 1], &mut v[i])`, one 3-vector per node.
fn lower_and(v: &mut [Vec<f64>], i: usize) -> (&[[f64; 3]], &mut [[f64; 3]]) {
    let (a, b) = v.split_at_mut(i);
    (rows(&a[i - 1]), rows_mut(&mut b[0]))
}

/// `(&mut v[i], &v[i + 1])`, one 3-vector per node.
fn and_upper(v: &mut [Vec<f64>], i: usize) -> (&mut [[f64; 3]], &[[f64; 3]]) {
    let (a, b) = v.split_at_mut(i + 1);
    (rows_mut(&mut a[i]), rows(&b[0]))
}

/// A level's buffers written by a stroke (or one chunk of them), one 3-vector per node: the
/// state, `X_(n−1)` (becoming `X_n`), ΔX, and the up-stroke snapshot. ΔX and the snapshot are
/// empty where the level does not keep them.
struct Rows<'a> {
    u: &'a mut [[f64; 3]],
    v: &'a mut [[f64; 3]],
    pu: &'a mut [[f64; 3]],
    pv: &'a mut [[f64; 3]],
    du: &'a mut [[f64; 3]],
    dv: &'a mut [[f64; 3]],
    su: &'a mut [[f64; 3]],
    sv: &'a mut [[f64; 3]],
}

/// `$go!(N, A, B)` with the constants of the case `(a, b, four_hosts)`: `N` = 4 or 3 hosts
/// per node, `A = a`, `B = b`. One loop per case, decided once per level, not per node.
macro_rules! by_case {
    ($case:expr, $go:ident) => {
        match $case {
            (false, false, true) => $go!(4, false, false),
            (false, true, true) => $go!(4, false, true),
            (true, false, true) => $go!(4, true, false),
            (true, true, true) => $go!(4, true, true),
            (false, false, false) => $go!(3, false, false),
            (false, true, false) => $go!(3, false, true),
            (true, false, false) => $go!(3, true, false),
            (true, true, false) => $go!(3, true, true),
        }
    };
}

/// Down-stroke transfer into one level (eqs. 9, 10): per node, ΔX = X_n − X_(n−1) where the
/// level keeps it, then the new state `Σ ω X^(i−1)` if `|Σ ω ΔX_u^(i−1)| > ε`, else
/// `X_n + Σ ω ΔX^(i−1)`, written over `X_(n−1)` (the caller swaps the buffers); the
/// snapshot, where kept, is the new state.
fn down<C: Field + Sync>(
    t: &Transfer,
    level: Rows,
    above: Above,
    d: [C; 2],
    src: [&[[f64; 3]]; 2],
) -> (usize, usize) {
    let keep = (!level.du.is_empty(), !level.su.is_empty(), t.npe == 4);
    per_chunk(level, |first, c| {
        macro_rules! go {
            ($n:literal, $d:literal, $s:literal) => {
                down_chunk::<C, $n, $d, $s>(t, first, c, above, d, src)
            };
        }
        by_case!(keep, go)
    })
}

/// [`down`] on one chunk: `N` hosts per node, `D` the level keeps ΔX, `S` the snapshot.
#[inline(always)]
fn down_chunk<C: Field, const N: usize, const D: bool, const S: bool>(
    t: &Transfer,
    first: usize,
    c: Rows,
    above: Above,
    [dfu, dfv]: [C; 2],
    [src_u, src_v]: [&[[f64; 3]]; 2],
) -> (usize, usize) {
    let n = c.u.len();
    let (ws, hs) = (&t.weights[first..first + n], &t.nodes[first..first + n]);
    let mut states = 0;
    for j in 0..n {
        let (ou, ov) = (c.u[j], c.v[j]);
        if D {
            c.du[j] = sub(ou, c.pu[j]);
            c.dv[j] = sub(ov, c.pv[j]);
        }
        let (w, h) = (&ws[j], &hs[j]);
        let [d_u] = weighted_n::<N, 1, C>(w, h, [dfu]);
        let (nu, nv) = if above.test(d_u) {
            states += 1;
            let [nu, nv] = weighted_n::<N, 2, _>(w, h, [src_u, src_v]);
            (nu, nv)
        } else {
            let [d_v] = weighted_n::<N, 1, C>(w, h, [dfv]);
            let (mut nu, mut nv) = (ou, ov);
            for q in 0..3 {
                nu[q] += d_u[q];
                nv[q] += d_v[q];
            }
            (nu, nv)
        };
        // The new state goes where X_(n−1) was; the caller swaps the buffers.
        c.pu[j] = nu;
        c.pv[j] = nv;
        if S {
            c.su[j] = nu;
            c.sv[j] = nv;
        }
    }
    (states, n - states)
}

/// Up-stroke transfer into one level (eqs. 11, 12): `X = Σ ω X^(i+1)` if the level's own
/// `|ΔX_u| > ε`, else `X += Σ ω (X^(i+1) − base)`. `finest`: the level's ΔX is `X − X_(n−1)`
/// now, and the new state is written over `X_(n−1)` (the caller swaps the buffers). The
/// snapshot, where kept, is the new state.
fn up(
    t: &Transfer,
    level: Rows,
    above: Above,
    finest: bool,
    src: [&[[f64; 3]]; 2],
    base: [&[[f64; 3]]; 2],
) -> (usize, usize) {
    // A coarse level that receives an up-stroke transfer (1 … m−2) always keeps its ΔX.
    debug_assert!(finest || !level.du.is_empty());
    let keep = (finest, !level.su.is_empty(), t.npe == 4);
    per_chunk(level, |first, c| {
        macro_rules! go {
            ($n:literal, $f:literal, $s:literal) => {
                up_chunk::<$n, $f, $s>(t, first, c, above, src, base)
            };
        }
        by_case!(keep, go)
    })
}

/// [`up`] on one chunk: `N` hosts per node; the level's own ΔX is `X − X_(n−1)` now where
/// `FINEST` (its new state then written over `X_(n−1)`), else the stored ΔX; `S` the snapshot.
#[inline(always)]
fn up_chunk<const N: usize, const FINEST: bool, const S: bool>(
    t: &Transfer,
    first: usize,
    c: Rows,
    above: Above,
    src: [&[[f64; 3]]; 2],
    base: [&[[f64; 3]]; 2],
) -> (usize, usize) {
    let n = c.u.len();
    let (ws, hs) = (&t.weights[first..first + n], &t.nodes[first..first + n]);
    let mut states = 0;
    for j in 0..n {
        let own = if FINEST {
            sub(c.u[j], c.pu[j])
        } else {
            c.du[j]
        };
        let (w, h) = (&ws[j], &hs[j]);
        let [cu, cv] = weighted_n::<N, 2, _>(w, h, src);
        let (nu, nv) = if above.test(own) {
            states += 1;
            (cu, cv)
        } else {
            let [bu, bv] = weighted_n::<N, 2, _>(w, h, base);
            let (mut nu, mut nv) = (c.u[j], c.v[j]);
            for q in 0..3 {
                nu[q] += cu[q] - bu[q];
                nv[q] += cv[q] - bv[q];
            }
            (nu, nv)
        };
        if FINEST {
            // The new state goes where X_(n−1) was; the caller swaps the buffers.
            c.pu[j] = nu;
            c.pv[j] = nv;
        } else {
            c.u[j] = nu;
            c.v[j] = nv;
        }
        if S {
            c.su[j] = nu;
            c.sv[j] = nv;
        }
    }
    (states, n - states)
}

/// `f(first node, chunk)` on every chunk of [`CHUNK`] nodes of a level, in parallel (each
/// node alone: the same bits on any thread count). `f` returns how many nodes of the chunk it
/// transferred the state of and how many a variation; returns the sums.
fn per_chunk(level: Rows, f: impl Fn(usize, Rows) -> (usize, usize) + Sync) -> (usize, usize) {
    let n = level.u.len();
    let Rows {
        u,
        v,
        pu,
        pv,
        du,
        dv,
        su,
        sv,
    } = level;
    (
        u.par_chunks_mut(CHUNK),
        v.par_chunks_mut(CHUNK),
        pu.par_chunks_mut(CHUNK),
        pv.par_chunks_mut(CHUNK),
        padded(du, n),
        padded(dv, n),
        padded(su, n),
        padded(sv, n),
    )
        .into_par_iter()
        .enumerate()
        .map(|(k, (u, v, pu, pv, du, dv, su, sv))| {
            f(
                k * CHUNK,
                Rows {
                    u,
                    v,
                    pu,
                    pv,
                    du,
                    dv,
                    su,
                    sv,
                },
            )
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
}

/// The chunks of a buffer for [`per_chunk`], or as many empty ones if the level does not keep
/// the buffer.
fn padded(
    s: &mut [[f64; 3]],
    n: usize,
) -> impl IndexedParallelIterator<Item = &mut [[f64; 3]]> + '_ {
    if s.is_empty() {
        rayon::iter::Either::Right((0..n.div_ceil(CHUNK)).into_par_iter().map(|_| &mut [][..]))
    } else {
        rayon::iter::Either::Left(s.par_chunks_mut(CHUNK))
    }
}

/// Nodes per parallel chunk of the transfers.
const CHUNK: usize = 4096;

impl Stepper for Raisov {
    fn state(&self) -> &State {
        &self.levels[0].state
    }
    fn num_levels(&self) -> usize {
        self.levels.len()
    }
    fn switch_counts(&self) -> Option<SwitchCounts> {
        Some(self.switches)
    }
    fn level_links(&self) -> Option<&[crate::hierarchy::Correspondence]> {
        Some(&self.links)
    }
    /// Every level cut and the cycle started again on the cut levels (`X_(n−1)` the carried
    /// state, as at the start of a run), the counters kept.
    fn cut(&mut self, cut: &crate::hierarchy::cut::HierarchyCut) -> crate::Result<()> {
        self.set_runtime_constraints(&RuntimeConstraints::default());
        let levels = super::take_cut_levels(&mut self.levels, cut)?;
        let mut next = Raisov::new(levels, cut.links.clone(), self.params);
        next.steps = self.steps;
        next.switches = self.switches;
        *self = next;
        Ok(())
    }
    fn level_mesh(&self, level: usize) -> Option<&crate::mesh::Mesh> {
        self.levels.get(level).map(|l| &l.mesh)
    }
    /// Level 0 takes the held and pinned nodes; each coarser level holds the node nearest to
    /// each held level-0 node (reference positions) at the same displacement, as the scenario
    /// carries prescribed points (section 3.1), and its own pinned nodes where they stand;
    /// each level takes its springs.
    fn set_runtime_constraints(&mut self, c: &RuntimeConstraints) {
        if self.own.is_empty() {
            self.own = self
                .levels
                .iter()
                .map(|l| OwnConstraints::of(&l.sys.constraints))
                .collect();
            self.carried = vec![Default::default(); self.levels.len() - 1];
        }
        let (first, coarse) = self.levels.split_at_mut(1);
        let fine = &first[0].mesh;
        let mut held = Vec::new();
        for (l, lv) in coarse.iter_mut().enumerate() {
            held.clear();
            let map = &mut self.carried[l];
            for &(a, d) in &c.held {
                let p = fine.nodes[a as usize];
                let near = *map
                    .entry(a)
                    .or_insert_with(|| lv.mesh.nearest_node(p).unwrap_or(0) as u32);
                held.push((near, d));
            }
            let pinned = c.pinned.get(l + 1).map_or(&[][..], |p| &p[..]);
            let n = lv.num_nodes();
            self.own[l + 1].apply(&mut lv.sys.constraints, &held, pinned, &lv.state.u, n);
            lv.sys.springs = c.springs_of(l + 1).to_vec();
            let t = lv.state.t;
            lv.sys.impose(t, &mut lv.state.u, &mut lv.state.v);
        }
        let lv = &mut first[0];
        let pinned = c.pinned.first().map_or(&[][..], |p| &p[..]);
        let n = lv.num_nodes();
        self.own[0].apply(&mut lv.sys.constraints, &c.held, pinned, &lv.state.u, n);
        lv.sys.springs = c.springs_of(0).to_vec();
        let t = lv.state.t;
        lv.sys.impose(t, &mut lv.state.u, &mut lv.state.v);
    }
    fn set_kinetic_limit(&mut self, limit: f64) {
        self.params.kinetic_limit = limit;
    }
    fn save(&self, cp: &mut Checkpoint) {
        let mut w = cp.writer();
        for (l, (pu, pv)) in self.levels.iter().zip(self.prev_u.iter().zip(&self.prev_v)) {
            w.state(&l.state);
            w.history(&l.sys);
            w.vector(pu);
            w.vector(pv);
        }
        w.count(self.steps);
    }
    fn restore(&mut self, cp: &Checkpoint) {
        let mut r = cp.reader();
        for (l, (pu, pv)) in self
            .levels
            .iter_mut()
            .zip(self.prev_u.iter_mut().zip(self.prev_v.iter_mut()))
        {
            r.state(&mut l.state);
            r.history(&mut l.sys);
            r.vector(pu);
            r.vector(pv);
        }
        self.steps = r.count();
    }
    fn hold_prescribed(&mut self, values: &[[f64; 3]]) {
        super::hold_on_levels(&mut self.levels, values);
    }
    fn advance(&mut self) -> Result<(), Divergence> {
        self.cycle()?;
        self.steps += 1;
        let dt = self.dt();
        for l in &mut self.levels {
            let _ = l.sys.force.accept_step(&l.state.u, dt);
        }
        let l = &self.levels[0];
        check_state(&l.sys, &l.state, self.steps, self.params.kinetic_limit)
    }
    fn finest(&mut self) -> (&mut crate::integrate::System, &crate::integrate::State) {
        let l = &mut self.levels[0];
        (&mut l.sys, &l.state)
    }
    fn steps(&self) -> u64 {
        self.steps
    }
    fn force_evaluations(&self) -> f64 {
        super::finest_equivalent_evaluations(&self.levels)
    }
    fn dt(&self) -> f64 {
        self.levels[0].dt
    }
    fn report(&self) -> String {
        super::hierarchy_report(&self.levels, &self.links)
    }
    fn describe(&self) -> String {
        let nodes: Vec<String> = self
            .levels
            .iter()
            .map(|l| l.num_nodes().to_string())
            .collect();
        format!(
            "raisov-paper (\"{}\" reading, epsilon = {:.3e} m), {} levels ({} nodes), {}, dt = {:.4e} s",
            match self.params.reading {
                Reading::Paper => "paper",
                Reading::Correction => "correction",
            },
            self.params.epsilon,
            self.levels.len(),
            nodes.join("/"),
            self.levels[0].integrator.method().name(),
            self.levels[0].dt
        )
    }
}
