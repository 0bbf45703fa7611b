//! Visco-hyperelastic neo-Hookean: NiftySim's "NHV" material (Taylor et al., "On modelling of
//! anisotropic viscoelasticity for soft tissue simulation: numerical solution and GPU
//! execution", Medical Image Analysis 13, 2009; NiftySim `tledMaterialNHV`), the isochoric
//! stress of NiftySim's neo-Hookean relaxed by a Prony series.
//!
//! Solids only. The elastic law (NiftySim's NH; the same as `mooney-rivlin` with `C2 = 0`,
//! `C1 = μ/2`, and as `ti-neo-hookean` with `η = 0`), with `J = √det C`,
//! `Ī1 = J^(−2/3) tr C` and `g1 = ∂Ī1/∂C` of [`super::Iso3`]:
//! ```text
//! W = μ/2 (Ī1 − 3) + κ/2 (J − 1)²,     S_iso = μ g1 = μ J^(−2/3) (I − I1/3 C⁻¹),
//!                                      S_vol = κ (J − 1) J C⁻¹
//! ```
//! Viscoelasticity: the Prony terms `(α_i, τ_i)` (relative moduli α_i ≥ 0 with `Σ α_i < 1`,
//! times τ_i > 0 in s) each carry an internal stress `H_i` (second Piola, per element) with
//! ```text
//! S = S_vol(C) + S_iso(C) − Σ_i H_i,       dH_i/dt = (α_i S_iso(C(t)) − H_i) / τ_i,   H_i(0) = 0
//! ```
//! so a step strain held from t = 0 gives `S_iso (1 − Σ α_i (1 − e^(−t/τ_i)))`: the shear
//! modulus relaxes from μ (instantaneous) to the long-term `μ_∞ = μ (1 − Σ α_i)`
//! ([`NeoHookeanVisco::long_term_mu`]); the bulk response is not relaxed (NiftySim's
//! volumetric Prony terms are not modelled).
//!
//! Recurrence over a step Δt from `t_n` to `t_{n+1}`, exact where `S_iso` is linear in time
//! over the step (the exponential integrator of the convolution), with `x_i = Δt/τ_i`,
//! `E_i = e^(−x_i)`, `γ_i = 1 − (1 − E_i)/x_i` ([`step_factors`]; γ → x/2 as x → 0, → 1 as
//! x → ∞):
//! ```text
//! H_i^{n+1} = E_i H_i^n + α_i (1 − E_i − γ_i) S_iso^n + α_i γ_i S_iso^{n+1}
//! S^{n+1}   = S_vol(C) + (1 − Σ α_i γ_i) S_iso(C) − h^n,
//! h^n       = Σ_i [E_i H_i^n + α_i (1 − E_i − γ_i) S_iso^n]          (known at the step's start)
//! ```
//! (NiftySim advances `H_i` by backward Euler, `H_i^{n+1} = (Δt α_i S_iso^{n+1} + τ_i H_i^n)/(Δt + τ_i)`,
//! first order in Δt; the recurrence here is exact for a piecewise-linear history and agrees
//! with it to O(Δt²) a step.) Over one step, with `h^n` and the factors fixed, the stress is
//! the derivative of the step potential
//! ```text
//! W_step(C) = (1 − Σ α_i γ_i) μ/2 (Ī1 − 3) + κ/2 (J − 1)² − h^n : (C − I)/2
//! ```
//! ([`ViscoStep`], a [`super::SolidMaterial`] the elements evaluate like any other law), whose
//! tangent is the algorithmic tangent of the recurrence,
//! `dS = (1 − Σ α_i γ_i) μ dg1 + dS_vol`: a Newton iteration on a backward-Euler step
//! converges quadratically. Limits: `Δt = ∞` gives `γ_i = 1`, `E_i = 0`, `h = 0`, the fully
//! relaxed (long-term) elastic law with μ_∞, whatever the history; `Δt = 0` gives
//! `γ_i = 0`, `E_i = 1`, `S = S_vol + S_iso − Σ H_i^n`, the stress with the history as last
//! accepted. Where the model keeps the `H_i`, when it advances them and what each solver
//! does with them: [`crate::fem`] ("Rate-dependent laws").

use super::{Iso3, SolidMaterial};
use nalgebra::Matrix3;

/// One Prony term: relative modulus α (≥ 0) and relaxation time τ (s, > 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Prony {
    /// Relative modulus α_i: the fraction of μ that relaxes with this term.
    pub alpha: f64,
    /// Relaxation time τ_i (s).
    pub tau: f64,
}

/// NiftySim's visco-hyperelastic neo-Hookean: shear modulus μ (instantaneous), bulk modulus
/// κ (Pa) and the Prony series of the isochoric stress.
#[derive(Clone, Debug, PartialEq)]
pub struct NeoHookeanVisco {
    /// Instantaneous shear modulus μ (Pa).
    pub mu: f64,
    /// Bulk modulus κ (Pa) of `κ/2 (J − 1)²`.
    pub kappa: f64,
    /// The Prony terms (α_i, τ_i).
    pub prony: Vec<Prony>,
}

/// `(E, γ)` of one Prony term over a step `dt` (module docs): `E = e^(−dt/τ)`,
/// `γ = 1 − (1 − E) τ/dt`; `(1, 0)` at `dt = 0`, `(0, 1)` at `dt = ∞`. Below `x = dt/τ =
/// 1e-4`, γ from its series `x/2 − x²/6 + x³/24` (the difference loses digits there).
pub fn step_factors(tau: f64, dt: f64) -> (f64, f64) {
    if dt == f64::INFINITY {
        return (0.0, 1.0);
    }
    let x = dt / tau;
    let e = (-x).exp();
    let gamma = if x < 1e-4 {
        x * (0.5 - x * (1.0 / 6.0 - x / 24.0))
    } else {
        1.0 + (-x).exp_m1() / x
    };
    (e, gamma)
}

impl NeoHookeanVisco {
    /// The law with μ, κ (Pa) and `prony`; an error naming `material.prony` (and the term)
    /// where a term has α < 0 or τ ≤ 0 or is not finite, or where `Σ α ≥ 1` (the long-term
    /// modulus μ (1 − Σ α) must stay positive), or naming `material.mu` / `material.kappa`
    /// where they are not positive.
    pub fn new(mu: f64, kappa: f64, prony: Vec<Prony>) -> crate::Result<Self> {
        for (key, v) in [("material.mu", mu), ("material.kappa", kappa)] {
            if !(v > 0.0 && v.is_finite()) {
                return Err(crate::Error::param(
                    key,
                    format!("{v} must be a positive number (Pa)"),
                ));
            }
        }
        for (i, p) in prony.iter().enumerate() {
            if !(p.alpha >= 0.0 && p.alpha.is_finite()) {
                return Err(crate::Error::param(
                    "material.prony",
                    format!(
                        "term {} = [{}, {}]: the relative modulus α must be a number >= 0",
                        i + 1,
                        p.alpha,
                        p.tau
                    ),
                ));
            }
            if !(p.tau > 0.0 && p.tau.is_finite()) {
                return Err(crate::Error::param(
                    "material.prony",
                    format!(
                        "term {} = [{}, {}]: the relaxation time τ must be a positive number (s)",
                        i + 1,
                        p.alpha,
                        p.tau
                    ),
                ));
            }
        }
        let sum: f64 = prony.iter().map(|p| p.alpha).sum();
        if !(sum < 1.0) {
            return Err(crate::Error::param(
                "material.prony",
                format!(
                    "the relative moduli sum to {sum}: need Σ α < 1 (the long-term shear modulus μ (1 − Σ α) must stay positive)"
                ),
            ));
        }
        Ok(NeoHookeanVisco { mu, kappa, prony })
    }

    /// The long-term (fully relaxed) shear modulus `μ_∞ = μ (1 − Σ α_i)` (Pa).
    pub fn long_term_mu(&self) -> f64 {
        self.mu * (1.0 - self.prony.iter().map(|p| p.alpha).sum::<f64>())
    }

    /// `S_iso = μ J^(−2/3) (I − I1/3 C⁻¹)`, the stress the Prony terms relax.
    pub fn iso_stress(&self, c: &Matrix3<f64>) -> Matrix3<f64> {
        let j = c.determinant().sqrt();
        let cinv = c.try_inverse().unwrap_or_else(Matrix3::zeros);
        (Matrix3::identity() - cinv * (c.trace() / 3.0)) * (self.mu * j.powf(-2.0 / 3.0))
    }

    /// The fully relaxed law (`Δt = ∞`): μ_∞ and κ, no history.
    pub fn relaxed(&self) -> ViscoStep {
        let scale = 1.0 - self.prony.iter().map(|p| p.alpha).sum::<f64>();
        ViscoStep {
            mu: self.mu * scale,
            kappa: self.kappa,
            h: Matrix3::zeros(),
        }
    }
}

/// The law over one step with its history fixed (module docs): `W_step`, with `mu` the
/// step's `(1 − Σ α_i γ_i) μ` and `h` the history stress `h^n` (Pa).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViscoStep {
    /// `(1 − Σ α_i γ_i) μ` (Pa).
    pub mu: f64,
    /// Bulk modulus κ (Pa).
    pub kappa: f64,
    /// The history stress `h^n` (Pa, symmetric).
    pub h: Matrix3<f64>,
}

// The arithmetic is that of `MooneyRivlin` with `C1 = μ/2`, `C2 = 0`, term by term, so that
// without relaxation (`mu` = μ, `h` = 0) the two laws give the same numbers.
impl SolidMaterial for ViscoStep {
    fn energy(&self, c: &Matrix3<f64>) -> f64 {
        let j = c.determinant().sqrt();
        0.5 * self.mu * (c.trace() * j.powf(-2.0 / 3.0) - 3.0)
            + 0.5 * self.kappa * (j - 1.0) * (j - 1.0)
            - 0.5 * (self.h.component_mul(&(c - Matrix3::identity()))).sum()
    }
    fn pk2(&self, c: &Matrix3<f64>) -> Matrix3<f64> {
        let j = c.determinant().sqrt();
        let cinv = c.try_inverse().unwrap_or_else(Matrix3::zeros);
        let id = Matrix3::identity();
        (id - cinv * (c.trace() / 3.0)) * (self.mu * j.powf(-2.0 / 3.0))
            + cinv * (self.kappa * (j - 1.0) * j)
            - self.h
    }
    fn dpk2(&self, c: &Matrix3<f64>, dc: &Matrix3<f64>) -> Matrix3<f64> {
        let iso = Iso3::new(c, dc);
        iso.dg1 * self.mu + iso.bulk(self.kappa).1
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::MooneyRivlin;

    fn history() -> Matrix3<f64> {
        Matrix3::new(120.0, -30.0, 10.0, -30.0, 80.0, 25.0, 10.0, 25.0, -60.0)
    }
    crate::material_tests!(
        solid_relaxed,
        solid,
        NeoHookeanVisco::new(
            1e3,
            5e4,
            vec![Prony {
                alpha: 0.4,
                tau: 0.1
            }]
        )
        .unwrap()
        .relaxed()
    );

    /// With a history stress the step potential's stress and tangent are still its
    /// derivatives (the reference state then carries `−h`).
    mod with_history {
        use super::*;
        use crate::material::SolidMaterial;
        #[test]
        fn stress_and_algorithmic_tangent_are_derivatives_with_history() {
            let m = ViscoStep {
                mu: 700.0,
                kappa: 5e4,
                h: history(),
            };
            let f = Matrix3::new(1.1, 0.2, -0.05, 0.03, 0.95, 0.1, -0.02, 0.07, 1.2);
            let c = f.transpose() * f;
            let s = m.pk2(&c);
            let h = 1e-6;
            for i in 0..3 {
                for j in 0..3 {
                    let mut d = Matrix3::zeros();
                    d[(i, j)] += 0.5 * h;
                    d[(j, i)] += 0.5 * h;
                    let fd = 2.0 * (m.energy(&(c + d)) - m.energy(&(c - d))) / (2.0 * h);
                    assert!((fd - s[(i, j)]).abs() <= 1e-6 * s.norm(), "S[{i}{j}]");
                }
            }
            let dc = Matrix3::new(0.3, -0.2, 0.1, -0.2, -0.5, 0.4, 0.1, 0.4, 0.2);
            let fd = (m.pk2(&(c + dc * h)) - m.pk2(&(c - dc * h))) / (2.0 * h);
            assert!((m.dpk2(&c, &dc) - fd).norm() <= 1e-6 * fd.norm());
            assert!((m.pk2(&Matrix3::identity()) + history()).norm() < 1e-9);
        }
    }

    #[test]
    fn without_relaxation_the_step_law_is_mooney_rivlin_c2_zero_to_the_bit() {
        let mu = 1.3e3;
        let step = ViscoStep {
            mu,
            kappa: 4e4,
            h: Matrix3::zeros(),
        };
        let mr = MooneyRivlin::new(mu / 2.0, 0.0, 4e4);
        let f = Matrix3::new(1.1, 0.2, -0.05, 0.03, 0.95, 0.1, -0.02, 0.07, 1.2);
        let c = f.transpose() * f;
        let dc = Matrix3::new(0.3, -0.2, 0.1, -0.2, -0.5, 0.4, 0.1, 0.4, 0.2);
        assert_eq!(step.pk2(&c), mr.pk2(&c));
        assert_eq!(step.dpk2(&c, &dc), mr.dpk2(&c, &dc));
        assert_eq!(step.energy(&c), mr.energy(&c));
    }

    #[test]
    fn step_factors_limits_and_series() {
        assert_eq!(step_factors(0.5, 0.0), (1.0, 0.0));
        assert_eq!(step_factors(0.5, f64::INFINITY), (0.0, 1.0));
        // The series and the closed form agree where both are accurate.
        for x in [2e-4, 1e-3, 0.1, 1.0, 10.0] {
            let (e, g) = step_factors(1.0, x);
            assert!((e - (-x).exp()).abs() < 1e-15);
            let exact = 1.0 - (1.0 - (-x).exp()) / x;
            assert!((g - exact).abs() <= 1e-9 * exact, "x = {x}: {g} vs {exact}");
        }
        let x: f64 = 1e-5;
        let (_, g) = step_factors(1.0, x);
        assert!((g - x / 2.0).abs() <= x * x);
    }

    #[test]
    fn bad_prony_terms_are_refused_naming_the_key() {
        let p = |alpha, tau| Prony { alpha, tau };
        for (terms, what) in [
            (vec![p(-0.1, 1.0)], "α must be a number >= 0"),
            (vec![p(0.1, 0.0)], "τ must be a positive number"),
            (vec![p(0.1, f64::NAN)], "τ must be a positive number"),
            (vec![p(0.6, 1.0), p(0.4, 2.0)], "need Σ α < 1"),
        ] {
            let e = NeoHookeanVisco::new(1e3, 5e4, terms)
                .unwrap_err()
                .to_string();
            assert!(e.contains("material.prony") && e.contains(what), "{e}");
        }
        let e = NeoHookeanVisco::new(0.0, 5e4, vec![])
            .unwrap_err()
            .to_string();
        assert!(e.contains("material.mu"), "{e}");
    }
}
