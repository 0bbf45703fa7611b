//! RaISoV, Restrict-and-Interpolate-State-or-Variation (Wu & Tendick 2004, section 2.2),
//! exactly as `../shared/design/raisov-reading.md` reads it. One time step is one V-cycle.
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
//!    - `Correction`: level i+1's state now minus its state at the start of its own up-stroke
//!      (a classic coarse-grid correction).
//! 3. Constrained nodes are re-imposed on every level after every transfer.
//!
//! With one level this is single-level integration, bit for bit (a test).

use super::{norm3, weighted, weighted2, Level, Links};
use crate::error::{Divergence, DivergenceCause};
use crate::integrate::{check_state, Stepper};
use rayon::prelude::*;

/// How the up stroke reads δX^(i+1) (design note, step 2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Reading {
    Paper,
    Correction,
}

/// Parameters of the literal RaISoV cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RaisovParams {
    /// The switch threshold ε of eqs. 10 and 12 (m).
    pub epsilon: f64,
    pub reading: Reading,
    /// Kinetic-energy ceiling of the finest level (J), for divergence detection.
    pub kinetic_limit: f64,
}

/// The paper's multigrid time integrator.
pub struct Raisov {
    pub levels: Vec<Level>,
    pub links: Links,
    pub params: RaisovParams,
    /// X_(n−1) per level (u then v, 6 per node packed as two vectors).
    prev_u: Vec<Vec<f64>>,
    prev_v: Vec<Vec<f64>>,
    /// X_n per level (start of this cycle).
    start_u: Vec<Vec<f64>>,
    start_v: Vec<Vec<f64>>,
    /// ΔX per level.
    du: Vec<Vec<f64>>,
    dv: Vec<Vec<f64>>,
    /// State at the start of each level's up-stroke (for the `Correction` reading).
    up_u: Vec<Vec<f64>>,
    up_v: Vec<Vec<f64>>,
    steps: u64,
    /// Counts of state / variation transfers in the last cycle (down, up).
    pub last_switches: [(usize, usize); 2],
}

impl Raisov {
    pub fn new(levels: Vec<Level>, links: Links, params: RaisovParams) -> Self {
        assert_eq!(links.len() + 1, levels.len());
        let z = |l: &Level| vec![0.0; 3 * l.num_nodes()];
        let prev_u: Vec<_> = levels.iter().map(|l| l.state.u.clone()).collect();
        let prev_v: Vec<_> = levels.iter().map(|l| l.state.v.clone()).collect();
        Raisov {
            start_u: prev_u.clone(),
            start_v: prev_v.clone(),
            du: levels.iter().map(z).collect(),
            dv: levels.iter().map(z).collect(),
            up_u: levels.iter().map(z).collect(),
            up_v: levels.iter().map(z).collect(),
            prev_u,
            prev_v,
            levels,
            links,
            params,
            steps: 0,
            last_switches: [(0, 0); 2],
        }
    }

    fn cycle(&mut self) -> Result<(), Divergence> {
        let m = self.levels.len();
        let eps = self.params.epsilon;
        // X_n and ΔX = X_n − X_(n−1) for every level.
        for i in 0..m {
            let l = &self.levels[i];
            start_and_change(
                (&l.state.u, &self.prev_u[i]),
                &mut self.start_u[i],
                &mut self.du[i],
            );
            start_and_change(
                (&l.state.v, &self.prev_v[i]),
                &mut self.start_v[i],
                &mut self.dv[i],
            );
        }
        let mut sw = [(0usize, 0usize); 2];
        // Down stroke (eqs. 9, 10). Every node is independent: chunks in parallel, the same
        // bits on any thread count.
        for i in 1..m {
            let t = &self.links[i - 1].up; // level-i nodes hosted on level i−1
            let (fine, coarse) = self.levels.split_at_mut(i);
            let (f, c) = (&fine[i - 1], &mut coarse[0]);
            let (du, dv) = (&self.du[i - 1], &self.dv[i - 1]);
            let (src_u, src_v) = (&f.state.u, &f.state.v);
            let counts = per_node(&mut c.state.u, &mut c.state.v, |th, u3, v3| {
                let d_u = weighted(t, th, du);
                if norm3(d_u) > eps {
                    let [cu, cv] = weighted2(t, th, src_u, src_v);
                    u3.copy_from_slice(&cu);
                    v3.copy_from_slice(&cv);
                    true
                } else {
                    let d_v = weighted(t, th, dv);
                    for q in 0..3 {
                        u3[q] += d_u[q];
                        v3[q] += d_v[q];
                    }
                    false
                }
            });
            sw[0].0 += counts.0;
            sw[0].1 += counts.1;
            let tt = c.state.t;
            c.sys.impose(tt, &mut c.state.u, &mut c.state.v);
        }
        // Up stroke (eqs. 11-13).
        for i in (0..m).rev() {
            if i + 1 < m {
                let t = &self.links[i].down; // level-i nodes hosted on level i+1
                let (fine, coarse) = self.levels.split_at_mut(i + 1);
                let (f, c) = (&mut fine[i], &coarse[0]);
                let (base_u, base_v) = match self.params.reading {
                    Reading::Paper => (&self.start_u[i + 1], &self.start_v[i + 1]),
                    Reading::Correction => (&self.up_u[i + 1], &self.up_v[i + 1]),
                };
                let own_du = &self.du[i];
                let (src_u, src_v) = (&c.state.u, &c.state.v);
                let counts = per_node(&mut f.state.u, &mut f.state.v, |th, u3, v3| {
                    let a = 3 * th;
                    let own = [own_du[a], own_du[a + 1], own_du[a + 2]];
                    let [cu, cv] = weighted2(t, th, src_u, src_v);
                    if norm3(own) > eps {
                        u3.copy_from_slice(&cu);
                        v3.copy_from_slice(&cv);
                        true
                    } else {
                        let [bu, bv] = weighted2(t, th, base_u, base_v);
                        for q in 0..3 {
                            u3[q] += cu[q] - bu[q];
                            v3[q] += cv[q] - bv[q];
                        }
                        false
                    }
                });
                sw[1].0 += counts.0;
                sw[1].1 += counts.1;
                let tt = f.state.t;
                f.sys.impose(tt, &mut f.state.u, &mut f.state.v);
            }
            let l = &mut self.levels[i];
            // Only the Correction reading reads a level's up-stroke start, and only on coarse
            // levels (as δX^(i+1) for level i).
            if i > 0 && self.params.reading == Reading::Correction {
                par_copy(&mut self.up_u[i], &l.state.u);
                par_copy(&mut self.up_v[i], &l.state.v);
            }
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
        // X_(n−1) ← X_n; the old X_(n−1) buffers become next cycle's X_n scratch.
        std::mem::swap(&mut self.prev_u, &mut self.start_u);
        std::mem::swap(&mut self.prev_v, &mut self.start_v);
        self.last_switches = sw;
        Ok(())
    }
}

/// `f(node, u, v)` on every node's 3-vectors of a level's state, in parallel chunks of
/// [`CHUNK`] nodes (each node alone: the same bits on any thread count). `f` says whether it
/// transferred the node's state (true) or a variation; returns the two counts.
fn per_node(
    u: &mut [f64],
    v: &mut [f64],
    f: impl Fn(usize, &mut [f64], &mut [f64]) -> bool + Sync,
) -> (usize, usize) {
    u.par_chunks_mut(3 * CHUNK)
        .zip(v.par_chunks_mut(3 * CHUNK))
        .enumerate()
        .map(|(k, (u, v))| {
            let mut n = (0usize, 0usize);
            for (j, (u3, v3)) in u.chunks_exact_mut(3).zip(v.chunks_exact_mut(3)).enumerate() {
                if f(k * CHUNK + j, u3, v3) {
                    n.0 += 1;
                } else {
                    n.1 += 1;
                }
            }
            n
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
}

/// `dst = src`, in parallel chunks.
fn par_copy(dst: &mut [f64], src: &[f64]) {
    dst.par_chunks_mut(3 * CHUNK)
        .zip(src.par_chunks(3 * CHUNK))
        .for_each(|(d, s)| d.copy_from_slice(s));
}

/// Nodes per parallel chunk of the transfers.
const CHUNK: usize = 4096;

/// `start = x`, `change = x − prev` in one pass, in parallel chunks.
fn start_and_change((x, prev): (&[f64], &[f64]), start: &mut [f64], change: &mut [f64]) {
    (
        start.par_chunks_mut(3 * CHUNK),
        change.par_chunks_mut(3 * CHUNK),
        x.par_chunks(3 * CHUNK),
        prev.par_chunks(3 * CHUNK),
    )
        .into_par_iter()
        .for_each(|(s, c, x, p)| {
            for k in 0..s.len() {
                s[k] = x[k];
                c[k] = x[k] - p[k];
            }
        });
}

impl Stepper for Raisov {
    fn hold_prescribed(&mut self, values: &[[f64; 3]]) {
        super::hold_on_levels(&mut self.levels, values);
    }
    fn advance(&mut self) -> Result<(), Divergence> {
        self.cycle()?;
        self.steps += 1;
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
            "raisov-paper ({:?} reading, epsilon = {:.3e} m), {} levels ({} nodes), {}, dt = {:.4e} s",
            self.params.reading,
            self.params.epsilon,
            self.levels.len(),
            nodes.join("/"),
            self.levels[0].integrator.method().name(),
            self.levels[0].dt
        )
    }
}
