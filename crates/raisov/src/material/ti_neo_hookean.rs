//! Transversely isotropic neo-Hookean: NiftySim's "TI" material (Taylor et al., "On modelling
//! of anisotropic viscoelasticity for soft tissue simulation: numerical solution and GPU
//! execution", Medical Image Analysis 13, 2009; NiftySim `tledMaterialTI`), a neo-Hookean
//! matrix reinforced along one fibre direction `a0` (a unit vector of the reference
//! configuration; a per-element field gives each element a copy of the law with its own
//! `a0`: [`crate::fem`], "Fibre fields").
//!
//! Solids only. With `J = √det C`, `Ī1 = J^(−2/3) tr C`, `Ī4 = J^(−2/3) a0·C a0`,
//! `A = a0 ⊗ a0`:
//! ```text
//! W = μ/2 (Ī1 − 3) + η/4 (Ī4 − 1)² + κ/2 (J − 1)²
//! S = μ J^(−2/3) (I − I1/3 C⁻¹) + η (Ī4 − 1) J^(−2/3) (A − I4/3 C⁻¹) + κ (J − 1) J C⁻¹
//! ```
//! This S is, term by term, the stress NiftySim's `tledMaterialTI::ComputeSPKStress` computes
//! from its parameters (M, K, E, a) = (μ, κ, η, a0), so NiftySim's η carries over unchanged;
//! the energy it is the derivative of has `η/4 (Ī4 − 1)²` (a law written
//! `η/2 (Ī4 − 1)²` has twice this stress: halve its η). The fibre term acts in tension and
//! compression alike. Tangent, with the gradients and differentials of [`super::Iso3`]
//! (`g1`, `dg1`) and [`super::Fib4`] (`g4`, `dg4`, `dĪ4 = g4 : dC`):
//! ```text
//! dS = μ dg1 + η (dĪ4 g4 + (Ī4 − 1) dg4) + (the bulk term's, [`super::Iso3::bulk`])
//! ```
//! Small strain: the fibre energy is `η (ε_aa − tr ε/3)²` to second order (ε_aa = a0·ε a0),
//! so Young's modulus along the fibres is `9κG/(3κ + G)` with `G = μ + 2η/3`. Uniaxial
//! tension along and across the fibres in closed form: `uniaxial_tests`.

use super::{Fib4, Iso3, SolidMaterial};
use nalgebra::{Matrix3, Vector3};

/// NiftySim's transversely isotropic neo-Hookean: shear modulus μ, bulk modulus κ, fibre
/// stiffness η (Pa) and the unit fibre direction `a0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TiNeoHookean {
    /// Shear modulus μ (Pa) of the matrix, the coefficient of `μ/2 (Ī1 − 3)`.
    pub mu: f64,
    /// Bulk modulus κ (Pa) of `κ/2 (J − 1)²`.
    pub kappa: f64,
    /// Fibre stiffness η (Pa), the coefficient of `η/4 (Ī4 − 1)²`.
    pub eta: f64,
    /// The fibre direction in the reference configuration, a unit vector.
    pub fibre: Vector3<f64>,
}

impl TiNeoHookean {
    /// The law with μ, κ, η (Pa) and fibres along `fibre` (normalised; an error naming
    /// `fibre` where it is zero or not finite).
    pub fn new(mu: f64, kappa: f64, eta: f64, fibre: Vector3<f64>) -> crate::Result<Self> {
        Ok(TiNeoHookean {
            mu,
            kappa,
            eta,
            fibre: super::unit_direction(fibre, "fibre")?,
        })
    }
}

impl SolidMaterial for TiNeoHookean {
    fn energy(&self, c: &Matrix3<f64>) -> f64 {
        let j = c.determinant().sqrt();
        let j23 = j.powf(-2.0 / 3.0);
        let b1 = j23 * c.trace();
        let b4 = j23 * self.fibre.dot(&(c * self.fibre));
        0.5 * self.mu * (b1 - 3.0)
            + 0.25 * self.eta * (b4 - 1.0) * (b4 - 1.0)
            + 0.5 * self.kappa * (j - 1.0) * (j - 1.0)
    }
    fn pk2(&self, c: &Matrix3<f64>) -> Matrix3<f64> {
        let zero = Matrix3::zeros();
        let iso = Iso3::new(c, &zero);
        let fib = Fib4::new(&iso, c, &zero, &self.fibre);
        iso.g1 * self.mu + fib.g4 * (self.eta * (fib.b4 - 1.0)) + iso.bulk(self.kappa).0
    }
    fn dpk2(&self, c: &Matrix3<f64>, dc: &Matrix3<f64>) -> Matrix3<f64> {
        let iso = Iso3::new(c, dc);
        let fib = Fib4::new(&iso, c, dc, &self.fibre);
        iso.dg1 * self.mu
            + (fib.g4 * fib.db4 + fib.dg4 * (fib.b4 - 1.0)) * self.eta
            + iso.bulk(self.kappa).1
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    crate::material_tests!(
        solid,
        solid,
        TiNeoHookean::new(1e3, 5e4, 4e3, Vector3::new(1.0, 2.0, -0.5)).unwrap()
    );

    #[test]
    fn zero_fibre_is_refused_naming_the_key() {
        let e = TiNeoHookean::new(1e3, 5e4, 4e3, Vector3::zeros()).unwrap_err();
        assert!(e.to_string().contains("fibre"), "{e}");
    }
}
