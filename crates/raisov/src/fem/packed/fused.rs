//! The fused explicit step: [`FemModel::step_symplectic_euler`] on a [`FusedState`], under
//! a [`NodeLoad`].
//!
//! ```text
//! v += Δ (M⁻¹(V − R(u)) − α v),   u += Δ v     (u = v = 0 on fixed nodes)
//! ```
//!
//! One force pass accumulating into zeroed force rows, then one node pass doing the update
//! on the node rows themselves (the configuration lives in the rows the next force pass
//! reads; `u` is derived on demand), clearing the force rows: [`SymplecticEuler`] on a
//! [`System`] with fixed (zero) constraints, to the bit on the generic path and with f32
//! storage under a per-node load, within rounding of `X` in f64 (bounds in
//! [`FemModel::step_symplectic_euler`]'s docs). The load is per node or, as gravity, one
//! acceleration for all ([`NodeLoad`]). Models off the packed path (other materials,
//! membranes) take the same step on `u` through the generic force pass.
//!
//! [`SymplecticEuler`]: crate::integrate::SymplecticEuler
//! [`System`]: crate::integrate::System

use super::{fill_rows, huge_page_vec, Row4};
use crate::fem::{ElementFailure, FemModel, ForceModel};
use rayon::prelude::*;

/// External load of the fused step ([`FemModel::step_symplectic_euler`]).
#[derive(Clone, Copy, Debug)]
pub enum NodeLoad<'a> {
    /// Forces `V`, 3 per node (N): `v += Δ (M⁻¹(V − R) − α v)`.
    Forces(&'a [f64]),
    /// The same acceleration `g` on every node (m/s², e.g. gravity, `V = M g`):
    /// `v += Δ (g − M⁻¹R − α v)`. Nothing is read per node for it: 24 bytes per node-step
    /// less than [`NodeLoad::Forces`] with `M g`, and a different rounding (`g − R/m` against
    /// `(m g − R)/m`, an ulp of the acceleration).
    Acceleration([f64; 3]),
}

impl NodeLoad<'_> {
    /// The acceleration of entry `i = 3a + k` (node `a`, component `k`) under this load and
    /// the internal force `r` at a node of inverse mass `m`: `(V_i − r) m` or `g_k − r m`.
    #[inline(always)]
    fn acceleration(self, i: usize, k: usize, r: f64, m: f64) -> f64 {
        match self {
            NodeLoad::Forces(f) => (f[i] - r) * m,
            NodeLoad::Acceleration(g) => g[k] - r * m,
        }
    }
}

/// State of the fused step ([`FemModel::step_symplectic_euler`]): velocities `v` and the
/// configuration, 3 per node. On the packed path the configuration lives in the node rows
/// the force pass reads (`X + u` in f64, `u` with f32 storage), which the node update
/// advances in place; `u` is derived from them when asked for ([`FusedState::u`]). On the
/// generic path `u` itself is advanced. Changing `u` through [`FusedState::u_mut`] rebuilds
/// the rows at the next step. A state belongs to the model that steps it (the rows hold
/// that model's reference positions).
#[derive(Clone, Debug, Default)]
pub struct FusedState {
    u: Vec<f64>,
    v: Vec<f64>,
    rows: Vec<Row4>,
    /// The rows hold the configuration (the packed path has stepped since the last
    /// change of `u`).
    rows_valid: bool,
    /// `u` lags the rows (a packed step ran since it was last derived).
    u_stale: bool,
    /// What the rows hold beyond `u`: `X`, 3 per node (f64 positions rows), or empty.
    base: Vec<f64>,
}

impl FusedState {
    /// `u` and `v` given (3 per node each).
    pub fn new(u: Vec<f64>, v: Vec<f64>) -> FusedState {
        assert!(
            u.len() == v.len() && u.len().is_multiple_of(3),
            "u and v: 3 per node each"
        );
        FusedState {
            u,
            v,
            ..Default::default()
        }
    }

    /// At rest: `u = v = 0` on `n` nodes.
    pub fn zeros(n: usize) -> FusedState {
        FusedState::new(vec![0.0; 3 * n], vec![0.0; 3 * n])
    }

    /// Displacements, 3 per node: on the packed path derived from the node rows
    /// (`(X + u) − X` in f64: within an ulp of `X` of the `u` the rows were built from).
    pub fn u(&mut self) -> &[f64] {
        if self.u_stale {
            const NB: usize = 4096;
            let base: &[f64] = &self.base;
            if base.is_empty() {
                self.u
                    .par_chunks_mut(3 * NB)
                    .zip(self.rows.par_chunks(NB))
                    .for_each(|(uc, rc)| {
                        for (ua, row) in uc.chunks_exact_mut(3).zip(rc) {
                            ua.copy_from_slice(&row.0[..3]);
                        }
                    });
            } else {
                self.u
                    .par_chunks_mut(3 * NB)
                    .zip(self.rows.par_chunks(NB).zip(base.par_chunks(3 * NB)))
                    .for_each(|(uc, (rc, bc))| {
                        for ((ua, row), xa) in
                            uc.chunks_exact_mut(3).zip(rc).zip(bc.chunks_exact(3))
                        {
                            for k in 0..3 {
                                ua[k] = row.0[k] - xa[k];
                            }
                        }
                    });
            }
            self.u_stale = false;
        }
        &self.u
    }

    /// Velocities, 3 per node.
    pub fn v(&self) -> &[f64] {
        &self.v
    }

    /// Displacements to change; the force pass's rows are rebuilt at the next step.
    pub fn u_mut(&mut self) -> &mut [f64] {
        self.u();
        self.rows_valid = false;
        &mut self.u
    }

    /// Velocities to change.
    pub fn v_mut(&mut self) -> &mut [f64] {
        &mut self.v
    }
}

/// The packed fused step's node pass, in parallel chunks: for each node `a`, `v += Δ (load
/// − α v)` with `load(3a + k, k, R, 1/m)` the acceleration the load and the force rows give,
/// then `row += Δ v`, and the force row cleared; fixed nodes get `v = 0` and their
/// reference row (`[X, 0]` with `positions`, else zeros).
#[inline(always)]
fn packed_node_pass<L: Fn(usize, usize, f64, f64) -> f64 + Sync>(
    load: L,
    (v, acc, rows): (&mut [f64], &mut [Row4], &mut [Row4]),
    (inv_mass, fixed, x0): (&[f64], &[bool], &[f64]),
    positions: bool,
    alpha: f64,
    dt: f64,
) {
    const NB: usize = 4096;
    let body =
        |a0: usize, vc: &mut [f64], rc: &mut [Row4], qc: &mut [Row4], mc: &[f64], xc: &[bool]| {
            for a in 0..mc.len() {
                let ra = &mut rc[a].0;
                let q = &mut qc[a].0;
                if xc[a] {
                    let g = 3 * (a0 + a);
                    vc[3 * a..3 * a + 3].fill(0.0);
                    *q = if positions {
                        [x0[g], x0[g + 1], x0[g + 2], 0.0]
                    } else {
                        [0.0; 4]
                    };
                } else {
                    for k in 0..3 {
                        let i = 3 * a + k;
                        let acc_i = load(3 * a0 + i, k, ra[k], mc[a]) - alpha * vc[i];
                        vc[i] += dt * acc_i;
                        q[k] += dt * vc[i];
                    }
                }
                *ra = [0.0; 4];
            }
        };
    if inv_mass.len() >= 2 * NB {
        v.par_chunks_mut(3 * NB)
            .zip(acc.par_chunks_mut(NB))
            .zip(rows.par_chunks_mut(NB))
            .zip(inv_mass.par_chunks(NB).zip(fixed.par_chunks(NB)))
            .enumerate()
            .for_each(|(c, (((vc, rc), qc), (mc, xc)))| body(c * NB, vc, rc, qc, mc, xc));
    } else {
        body(0, v, acc, rows, inv_mass, fixed);
    }
}

impl FemModel {
    /// One fused symplectic-Euler step, `v += Δ (M⁻¹(V − R(u)) − α v)`, `u += Δ v`, with
    /// `u = v = 0` on nodes where `fixed` is true; `inv_mass` per node, the load `V` as
    /// [`NodeLoad`]. On failure the state is unchanged.
    ///
    /// On the packed path the node update advances the node rows of the next force pass in
    /// place (`x += Δ v` on `x = X + u` in f64, `u += Δ v` on `u` with f32 storage) and
    /// never touches `u` ([`FusedState::u`] derives it), so that a node-step moves 64 bytes
    /// less than updating `u` and rebuilding the rows (`X` and `u` read, `u` written) with a
    /// per-node load: 281 bytes per node-step in f64 with [`NodeLoad::Acceleration`]. The
    /// result is [`crate::integrate::SymplecticEuler`] on a [`crate::integrate::System`]
    /// built from this model with those nodes fixed: the same bits on the generic path and
    /// with f32 storage (`u += Δ v` either way) under [`NodeLoad::Forces`]; in f64 the
    /// positions carry the rounding of `X` (an ulp of `|X|` per step, absolute), within
    /// `1e-11` of the largest `|u|` of the System path over 500 steps of the standard work
    /// (tested), and [`NodeLoad::Acceleration`] rounds `g − R/m` for `(m g − R)/m`.
    pub fn step_symplectic_euler(
        &mut self,
        s: &mut FusedState,
        load: NodeLoad<'_>,
        inv_mass: &[f64],
        fixed: &[bool],
        alpha: f64,
        dt: f64,
    ) -> Result<(), ElementFailure> {
        let n = self.n_nodes;
        assert!(s.u.len() == 3 * n && s.v.len() == 3 * n);
        if let NodeLoad::Forces(f) = load {
            assert!(f.len() == 3 * n, "f_ext: 3 per node");
        }
        assert!(inv_mass.len() == n && fixed.len() == n);
        let Some(p) = self.pack.as_ref().filter(|_| self.partial.is_empty()) else {
            return self.step_generic(s, load, inv_mass, fixed, alpha, dt);
        };
        let positions = p.reads_positions();
        if !s.rows_valid {
            s.u();
            if s.rows.len() != n {
                s.rows = huge_page_vec(n);
                s.rows.resize(n, Row4::default());
            }
            fill_rows(&mut s.rows, &s.u, &self.x0, positions);
            s.base = if positions {
                self.x0.clone()
            } else {
                Vec::new()
            };
            s.rows_valid = true;
        }
        if !p.accumulate(&s.rows, &mut self.acc) {
            self.acc.fill(Row4::default());
            s.u();
            return Err(self.fast_failure(&s.u));
        }
        s.u_stale = true;
        let x0: &[f64] = &self.x0;
        let FusedState { v, rows, .. } = s;
        let acc = &mut self.acc[..];
        match load {
            NodeLoad::Forces(f) => packed_node_pass(
                |i, k, r, m| NodeLoad::Forces(f).acceleration(i, k, r, m),
                (v, acc, rows),
                (inv_mass, fixed, x0),
                positions,
                alpha,
                dt,
            ),
            NodeLoad::Acceleration(g) => packed_node_pass(
                |i, k, r, m| NodeLoad::Acceleration(g).acceleration(i, k, r, m),
                (v, acc, rows),
                (inv_mass, fixed, x0),
                positions,
                alpha,
                dt,
            ),
        }
        Ok(())
    }

    /// [`FemModel::step_symplectic_euler`] on the generic element path: forces into
    /// `acc3`, then `v` and `u` updated (the same operations as the integrator's).
    fn step_generic(
        &mut self,
        s: &mut FusedState,
        load: NodeLoad<'_>,
        inv_mass: &[f64],
        fixed: &[bool],
        alpha: f64,
        dt: f64,
    ) -> Result<(), ElementFailure> {
        let mut acc3 = std::mem::take(&mut self.acc3);
        acc3.resize(3 * self.n_nodes, 0.0);
        s.u();
        let res = self.internal_forces(&s.u, &mut acc3);
        if res.is_ok() {
            s.rows_valid = false;
            const NB: usize = 4096;
            let body =
                |a0: usize, uc: &mut [f64], vc: &mut [f64], rc: &[f64], mc: &[f64], xc: &[bool]| {
                    for a in 0..mc.len() {
                        for k in 0..3 {
                            let i = 3 * a + k;
                            if xc[a] {
                                vc[i] = 0.0;
                                uc[i] = 0.0;
                            } else {
                                let acc_i =
                                    load.acceleration(3 * a0 + i, k, rc[i], mc[a]) - alpha * vc[i];
                                vc[i] += dt * acc_i;
                                uc[i] += dt * vc[i];
                            }
                        }
                    }
                };
            let FusedState { u, v, .. } = s;
            if self.n_nodes >= 2 * NB {
                u.par_chunks_mut(3 * NB)
                    .zip(v.par_chunks_mut(3 * NB))
                    .zip(acc3.par_chunks(3 * NB))
                    .zip(inv_mass.par_chunks(NB).zip(fixed.par_chunks(NB)))
                    .enumerate()
                    .for_each(|(c, (((uc, vc), rc), (mc, xc)))| body(c * NB, uc, vc, rc, mc, xc));
            } else {
                body(0, u, v, &acc3, inv_mass, fixed);
            }
        }
        self.acc3 = acc3;
        res
    }
}
