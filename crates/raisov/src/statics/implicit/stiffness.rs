//! Stiffness-proportional damping of an implicit step, `β K_n v_{n+1}` with `K_n` frozen at
//! the step's start (the module docs of [`super`]): the elements' tangents `K_e(u_n)`, scaled
//! by `c = β / h_e`, kept per element, and a force model that adds
//!
//! ```text
//! E_β(u) = ½ c Σ_e (u − x*)_eᵀ K_e(u_n) (u − x*)_e,   R_β(u) = c K_n (u − x*),   K_β = c K_n
//! ```
//!
//! to the model it wraps (`x*` the step's base: `u_n` for backward Euler). Only the elements'
//! tangents ([`ForceModel::element_tangent`], the material's) enter `K_n`; the blocks beyond
//! them (a follower pressure's, a tool's) and the springs do not.

use crate::fem::{loads, ElementFailure, ElementTopology, ForceModel};

/// `c K_e(u_n)` per element and the base `x*` of the current step.
pub(super) struct FrozenStiffness {
    /// Entries per element matrix, `(3 npe)²`.
    d2: usize,
    /// `c K_e(u_n)`, element after element, row-major.
    k: Vec<f64>,
    /// The base `x*` (3 per node).
    base: Vec<f64>,
}

impl FrozenStiffness {
    /// Room for `model`'s element tangents, after checking that they fit in the available
    /// memory; `None` where the model has no element tangent.
    pub(super) fn for_model(model: &dyn ForceModel) -> Result<Option<Self>, String> {
        let Some(top) = model.tangent_elements() else {
            return Ok(None);
        };
        let d = 3 * top.nodes_per_element;
        let entries = (top.len() as u64).saturating_mul((d * d) as u64);
        crate::memory::check(
            &format!(
                "the frozen element tangents of stiffness-proportional damping ({} elements)",
                top.len()
            ),
            entries.saturating_mul(8),
        )?;
        Ok(Some(FrozenStiffness {
            d2: d * d,
            k: vec![0.0; entries as usize],
            base: vec![0.0; 3 * top.nodes],
        }))
    }

    /// Freeze `c K_e(u)` of every element of `model`, the base at `base`.
    pub(super) fn freeze(
        &mut self,
        model: &dyn ForceModel,
        u: &[f64],
        c: f64,
        base: &[f64],
    ) -> Result<(), ElementFailure> {
        use rayon::prelude::*;
        self.base.copy_from_slice(base);
        let d2 = self.d2;
        let ok: Result<(), ElementFailure> =
            self.k
                .par_chunks_mut(d2)
                .enumerate()
                .try_for_each(|(e, out)| {
                    model.element_tangent(e, u, out)?;
                    out.iter_mut().for_each(|x| *x *= c);
                    Ok(())
                });
        if ok.is_err() {
            // The lowest failing element, whatever the scheduling.
            for (e, out) in self.k.chunks_mut(d2).enumerate() {
                model.element_tangent(e, u, out)?;
            }
        }
        Ok(())
    }

    /// `f(element nodes, c K_e, (u − x*)_e)` for every element, in element order.
    fn each(
        &self,
        top: &ElementTopology<'_>,
        u: &[f64],
        mut f: impl FnMut(&[u32], &[f64], &[f64]),
    ) {
        let d = 3 * top.nodes_per_element;
        let mut du = vec![0.0; d];
        for (e, ke) in self.k.chunks_exact(self.d2).enumerate() {
            let el = top.element(e);
            for (q, x) in du.iter_mut().enumerate() {
                let i = 3 * el[q / 3] as usize + q % 3;
                *x = u[i] - self.base[i];
            }
            f(el, ke, &du);
        }
    }

    /// `r += c K_n (u − x*)` over the elements, in element order.
    fn add_forces(&self, top: &ElementTopology<'_>, u: &[f64], r: &mut [f64]) {
        let d = 3 * top.nodes_per_element;
        self.each(top, u, |el, ke, du| {
            for (row, kr) in ke.chunks_exact(d).enumerate() {
                let f: f64 = kr.iter().zip(du).map(|(k, x)| k * x).sum();
                r[3 * el[row / 3] as usize + row % 3] += f;
            }
        });
    }

    /// `½ c (u − x*)ᵀ K_n (u − x*)` (J), in element order.
    fn energy(&self, top: &ElementTopology<'_>, u: &[f64]) -> f64 {
        let d = 3 * top.nodes_per_element;
        let mut sum = 0.0;
        self.each(top, u, |_, ke, du| {
            for (kr, &xr) in ke.chunks_exact(d).zip(du) {
                sum += xr * kr.iter().zip(du).map(|(k, x)| k * x).sum::<f64>();
            }
        });
        0.5 * sum
    }
}

/// `inner` with the frozen damping term added to its forces, energy and element tangents
/// (module docs); everything else is `inner`'s.
pub(super) struct Damped<'a> {
    pub(super) inner: &'a mut dyn ForceModel,
    pub(super) frozen: &'a FrozenStiffness,
}

impl ForceModel for Damped<'_> {
    fn num_nodes(&self) -> usize {
        self.inner.num_nodes()
    }
    fn internal_forces(&mut self, u: &[f64], r: &mut [f64]) -> Result<(), ElementFailure> {
        self.inner.internal_forces(u, r)?;
        if let Some(top) = self.inner.tangent_elements() {
            self.frozen.add_forces(&top, u, r);
        }
        Ok(())
    }
    fn strain_energy(&self, u: &[f64]) -> f64 {
        let e = self.inner.strain_energy(u);
        e + self
            .inner
            .tangent_elements()
            .map_or(0.0, |top| self.frozen.energy(&top, u))
    }
    fn nodal_stress(&self, u: &[f64], t: &mut [f64]) {
        self.inner.nodal_stress(u, t)
    }
    fn admissible_energy(&self, u: &[f64]) -> f64 {
        let e = self.inner.admissible_energy(u);
        if !e.is_finite() {
            return f64::INFINITY;
        }
        e + self
            .inner
            .tangent_elements()
            .map_or(0.0, |top| self.frozen.energy(&top, u))
    }
    fn tangent_elements(&self) -> Option<ElementTopology<'_>> {
        self.inner.tangent_elements()
    }
    fn element_tangent(&self, e: usize, u: &[f64], out: &mut [f64]) -> Result<(), ElementFailure> {
        self.inner.element_tangent(e, u, out)?;
        let d2 = self.frozen.d2;
        for (o, k) in out.iter_mut().zip(&self.frozen.k[e * d2..(e + 1) * d2]) {
            *o += k;
        }
        Ok(())
    }
    fn add_extra_tangent(&self, u: &[f64], add: &mut dyn FnMut(&[u32], &[f64])) {
        self.inner.add_extra_tangent(u, add)
    }
    fn element_det_f(&self, e: usize, u: &[f64]) -> f64 {
        self.inner.element_det_f(e, u)
    }
    fn min_det_f(&self, u: &[f64]) -> (usize, f64) {
        self.inner.min_det_f(u)
    }
    fn set_time(&self, t: f64) {
        self.inner.set_time(t)
    }
    fn set_load_factor(&self, f: f64) {
        self.inner.set_load_factor(f)
    }
    fn set_step(&mut self, dt: f64) {
        self.inner.set_step(dt)
    }
    fn accept_step(&mut self, u: &[f64], dt: f64) -> bool {
        self.inner.accept_step(u, dt)
    }
    fn load_report(&mut self, u: &[f64]) -> loads::LoadReport {
        self.inner.load_report(u)
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
}
