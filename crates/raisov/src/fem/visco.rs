//! The internal variables of a rate-dependent law ([`crate::material::NeoHookeanVisco`]) in a
//! [`super::FemModel`]: per element (one integration point, constant strain) and Prony term
//! the stress `H_i` (6 symmetric components), per element the isochoric stress `S_iso^n` of
//! the last accepted configuration, and the history stress `h^n` of the step in progress
//! (equations in the law's module).
//!
//! - [`Visco::set_step`] fixes the step `Δt` the force evaluations use (the factors `E_i`,
//!   `γ_i` and so `h^n` and the step's `(1 − Σ α_i γ_i) μ`). `Δt = ∞`, the state of a new
//!   model, is the fully relaxed law without history.
//! - [`Visco::accept`] advances every `H_i` from the last accepted configuration to the one
//!   given, over the step it is given, and forms the next `h^n`: once per accepted step.
//!
//! Each element's update reads and writes that element's entries only, in blocks of a fixed
//! size in parallel: the same bits on any number of threads.

use crate::material::{step_factors, NeoHookeanVisco, ViscoStep};
use nalgebra::Matrix3;
use rayon::prelude::*;

/// Elements per parallel task of [`Visco::accept`] and of `h^n`'s update.
const BLOCK: usize = 1024;

/// Symmetric components `[xx, yy, zz, xy, yz, xz]`.
type Sym = [f64; 6];

fn to_sym(m: &Matrix3<f64>) -> Sym {
    [
        m[(0, 0)],
        m[(1, 1)],
        m[(2, 2)],
        0.5 * (m[(0, 1)] + m[(1, 0)]),
        0.5 * (m[(1, 2)] + m[(2, 1)]),
        0.5 * (m[(0, 2)] + m[(2, 0)]),
    ]
}

fn from_sym(s: &Sym) -> Matrix3<f64> {
    Matrix3::new(s[0], s[3], s[5], s[3], s[1], s[4], s[5], s[4], s[2])
}

/// The internal variables of one model (module docs).
#[derive(Clone, Debug)]
pub(crate) struct Visco {
    law: NeoHookeanVisco,
    /// The step of the force evaluations (s); `∞`: fully relaxed.
    dt: f64,
    /// `(1 − Σ α_i γ_i) μ` at `dt`.
    mu_step: f64,
    /// `H_i` of every element, term after term within an element.
    h: Vec<Sym>,
    /// `S_iso^n` of every element.
    s: Vec<Sym>,
    /// `h^n` of every element at `dt`; all zeros at `dt = ∞`.
    hbar: Vec<Sym>,
}

/// Bytes of internal variables an element of a law with `terms` Prony terms takes.
pub(crate) fn bytes_per_element(terms: usize) -> u64 {
    (terms as u64 + 2) * std::mem::size_of::<Sym>() as u64
}

impl Visco {
    /// `ne` elements at rest (all stresses zero), fully relaxed.
    pub fn new(law: NeoHookeanVisco, ne: usize) -> Self {
        let m = law.prony.len();
        let mu_step = law.relaxed().mu;
        Visco {
            law,
            dt: f64::INFINITY,
            mu_step,
            h: vec![[0.0; 6]; ne * m],
            s: vec![[0.0; 6]; ne],
            hbar: vec![[0.0; 6]; ne],
        }
    }

    /// The internal variables of a cut mesh's elements: element `e` copies those of
    /// `old`'s element `from[e]` (its copies share its history), at `old`'s step.
    pub fn carried(old: &Visco, from: &[u32]) -> Visco {
        let m = old.law.prony.len();
        let mut v = Visco::new(old.law.clone(), from.len());
        for (e, &f) in from.iter().enumerate() {
            let f = f as usize;
            v.h[e * m..(e + 1) * m].copy_from_slice(&old.h[f * m..(f + 1) * m]);
            v.s[e] = old.s[f];
        }
        v.set_step(old.dt);
        v
    }

    /// The step (s) the force evaluations use.
    pub fn step(&self) -> f64 {
        self.dt
    }

    /// Element `e`'s law over the step in progress.
    pub fn element_law(&self, e: usize) -> ViscoStep {
        ViscoStep {
            mu: self.mu_step,
            kappa: self.law.kappa,
            h: from_sym(&self.hbar[e]),
        }
    }

    /// `[(α_i, E_i, γ_i)]` at `dt`.
    fn factors(&self, dt: f64) -> Vec<(f64, f64, f64)> {
        self.law
            .prony
            .iter()
            .map(|p| {
                let (e, g) = step_factors(p.tau, dt);
                (p.alpha, e, g)
            })
            .collect()
    }

    /// Use `dt` (s, ≥ 0, or ∞) for the force evaluations from now on.
    pub fn set_step(&mut self, dt: f64) {
        if dt.to_bits() == self.dt.to_bits() {
            return;
        }
        self.dt = dt;
        let f = self.factors(dt);
        self.mu_step = self.law.mu * (1.0 - f.iter().map(|&(a, _, g)| a * g).sum::<f64>());
        let m = f.len();
        let (h, s) = (&self.h, &self.s);
        self.hbar
            .par_chunks_mut(BLOCK)
            .enumerate()
            .for_each(|(b, block)| {
                for (k, hb) in block.iter_mut().enumerate() {
                    let e = b * BLOCK + k;
                    *hb = history(&f, &h[e * m..(e + 1) * m], &s[e]);
                }
            });
    }

    /// Append the history (every `H_i`, then every `S_iso^n`, 6 components each) to `out`: a
    /// fixed length per model, what a checkpoint keeps. `h^n` is not saved: it follows from
    /// them and the step of the force evaluations.
    pub fn save(&self, out: &mut Vec<f64>) {
        out.reserve(6 * (self.h.len() + self.s.len()));
        for x in self.h.iter().chain(&self.s) {
            out.extend_from_slice(x);
        }
    }

    /// Restore what [`Visco::save`] wrote at the front of `src`, and form `h^n` for the step
    /// of the force evaluations; returns how many values it read.
    pub fn load(&mut self, src: &[f64]) -> usize {
        let n = 6 * (self.h.len() + self.s.len());
        let Some(src) = src.get(..n) else {
            // Not a history this model wrote: keep the variables.
            return 0;
        };
        for (x, c) in self
            .h
            .iter_mut()
            .chain(self.s.iter_mut())
            .zip(src.chunks_exact(6))
        {
            x.copy_from_slice(c);
        }
        let dt = self.dt;
        // Force `set_step` to recompute h^n from the restored history.
        self.dt = f64::NAN;
        self.set_step(dt);
        n
    }

    /// Advance the internal variables over a step `dt` (s) to the configuration whose
    /// isochoric deformation `c_of(e)` gives each element's `C` (`None`: an element that
    /// cannot be evaluated keeps its variables), then form `h^n` for the step of the force
    /// evaluations.
    pub fn accept(&mut self, dt: f64, c_of: &(dyn Fn(usize) -> Option<Matrix3<f64>> + Sync)) {
        let adv = self.factors(dt);
        let next = self.factors(self.dt);
        let m = adv.len();
        let law = &self.law;
        let hbar = &mut self.hbar;
        let h = &mut self.h;
        let s = &mut self.s;
        let step = |b: usize, hs: &mut [Sym], ss: &mut [Sym], hb: &mut [Sym]| {
            for (k, ((he, se), hbe)) in hs
                .chunks_exact_mut(m.max(1))
                .zip(ss.iter_mut())
                .zip(hb.iter_mut())
                .enumerate()
            {
                let e = b * BLOCK + k;
                if let Some(c) = c_of(e) {
                    let s1 = to_sym(&law.iso_stress(&c));
                    for (hi, &(a, ei, gi)) in he.iter_mut().zip(&adv) {
                        for q in 0..6 {
                            hi[q] = ei * hi[q] + a * (1.0 - ei - gi) * se[q] + a * gi * s1[q];
                        }
                    }
                    *se = s1;
                }
                *hbe = history(&next, he, se);
            }
        };
        if m == 0 {
            // No Prony term: no history; h^n stays zero.
            return;
        }
        h.par_chunks_mut(BLOCK * m)
            .zip(s.par_chunks_mut(BLOCK))
            .zip(hbar.par_chunks_mut(BLOCK))
            .enumerate()
            .for_each(|(b, ((hs, ss), hb))| step(b, hs, ss, hb));
    }
}

/// `h^n = Σ_i [E_i H_i + α_i (1 − E_i − γ_i) S^n]`.
fn history(f: &[(f64, f64, f64)], h: &[Sym], s: &Sym) -> Sym {
    let mut out = [0.0; 6];
    for (hi, &(a, e, g)) in h.iter().zip(f) {
        for q in 0..6 {
            out[q] += e * hi[q] + a * (1.0 - e - g) * s[q];
        }
    }
    out
}
