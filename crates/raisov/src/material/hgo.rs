//! Holzapfel–Gasser–Ogden: a neo-Hookean matrix with one family of collagen fibres along the
//! unit reference direction `a0` (one per law; a per-element field gives each element a copy
//! with its own: [`crate::fem`], "Fibre fields"), stiffening exponentially in
//! tension (Holzapfel, Gasser & Ogden, J. Elasticity 61, 2000), with the fibre dispersion
//! κ_d of Gasser, Ogden & Holzapfel (J. R. Soc. Interface 3, 2006), as FEBio's
//! "Holzapfel-Gasser-Ogden" material writes it for one family.
//!
//! Solids only. With `J = √det C`, `Ī1 = J^(−2/3) tr C`, `Ī4 = J^(−2/3) a0·C a0` and the fibre
//! strain `Ē = κ_d (Ī1 − 3) + (1 − 3κ_d)(Ī4 − 1)` (κ_d ∈ [0, 1/3]: 0 aligned fibres, 1/3
//! isotropic dispersion):
//! ```text
//! W = μ/2 (Ī1 − 3) + k1/(2 k2) (exp(k2 Ē²) − 1) [only where Ē > 0] + κ/2 (J − 1)²
//! S = μ g1 + 2 k1 Ē exp(k2 Ē²) gE [Ē > 0] + κ (J − 1) J C⁻¹,      gE = κ_d g1 + (1 − 3κ_d) g4
//! ```
//! (`k1/(2 k2)(exp(k2 Ē²) − 1)` is `k1 Ē²/2` at `k2 = 0`). The fibres bear load only when
//! stretched, `Ē > 0` (for κ_d = 0: `Ī4 > 1`); the switch is C¹ in C (the fibre stress is 0 at
//! `Ē = 0` from both sides), its tangent jumps there. The volumetric term is the `κ/2 (J − 1)²`
//! of the other laws here (FEBio's uncoupled materials use their own U(J); the deviatoric
//! parts agree). Tangent, with `g1`, `dg1` of [`super::Iso3`], `g4`, `dg4` of
//! [`super::Fib4`], `dgE = κ_d dg1 + (1 − 3κ_d) dg4` and `dĒ = gE : dC`:
//! ```text
//! dS = μ dg1 + 2 k1 exp(k2 Ē²) ((1 + 2 k2 Ē²) dĒ gE + Ē dgE) [Ē > 0] + (the bulk term's)
//! ```
//! Small strain: the fibre energy is `2 k1 (1 − 3κ_d)² (ε_aa − tr ε/3)²` in tension (Ē > 0),
//! so Young's modulus along the fibres is `9κG/(3κ + G)` with `G = μ + 4 k1 (1 − 3κ_d)²/3`;
//! shortened fibres add nothing. Uniaxial tension along and across the fibres in closed
//! form: `uniaxial_tests`.

use super::{Fib4, Iso3, SolidMaterial};
use nalgebra::{Matrix3, Vector3};

/// Holzapfel–Gasser–Ogden with one fibre family: μ, κ, k1 (Pa), k2, κ_d (dimensionless) and
/// the unit fibre direction `a0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HolzapfelGasserOgden {
    /// Shear modulus μ (Pa) of the matrix, the coefficient of `μ/2 (Ī1 − 3)`.
    pub mu: f64,
    /// Bulk modulus κ (Pa) of `κ/2 (J − 1)²`.
    pub kappa: f64,
    /// Fibre stiffness k1 (Pa).
    pub k1: f64,
    /// Fibre stiffening exponent k2 (dimensionless, ≥ 0).
    pub k2: f64,
    /// Fibre dispersion κ_d in [0, 1/3].
    pub dispersion: f64,
    /// The fibre direction in the reference configuration, a unit vector.
    pub fibre: Vector3<f64>,
}

impl HolzapfelGasserOgden {
    /// The law with μ, κ, k1 (Pa), k2, dispersion κ_d and fibres along `fibre` (normalised;
    /// an error naming `fibre` where it is zero or not finite).
    pub fn new(
        mu: f64,
        kappa: f64,
        k1: f64,
        k2: f64,
        dispersion: f64,
        fibre: Vector3<f64>,
    ) -> crate::Result<Self> {
        Ok(HolzapfelGasserOgden {
            mu,
            kappa,
            k1,
            k2,
            dispersion,
            fibre: super::unit_direction(fibre, "fibre")?,
        })
    }

    /// `Ē` from `Ī1`, `Ī4`.
    fn strain(&self, b1: f64, b4: f64) -> f64 {
        self.dispersion * (b1 - 3.0) + (1.0 - 3.0 * self.dispersion) * (b4 - 1.0)
    }
}

impl SolidMaterial for HolzapfelGasserOgden {
    fn energy(&self, c: &Matrix3<f64>) -> f64 {
        let j = c.determinant().sqrt();
        let j23 = j.powf(-2.0 / 3.0);
        let b1 = j23 * c.trace();
        let b4 = j23 * self.fibre.dot(&(c * self.fibre));
        let e = self.strain(b1, b4);
        let fibres = if e <= 0.0 {
            0.0
        } else if self.k2 > 0.0 {
            0.5 * self.k1 / self.k2 * (self.k2 * e * e).exp_m1()
        } else {
            0.5 * self.k1 * e * e
        };
        0.5 * self.mu * (b1 - 3.0) + fibres + 0.5 * self.kappa * (j - 1.0) * (j - 1.0)
    }
    fn pk2(&self, c: &Matrix3<f64>) -> Matrix3<f64> {
        let zero = Matrix3::zeros();
        let iso = Iso3::new(c, &zero);
        let fib = Fib4::new(&iso, c, &zero, &self.fibre);
        let mut s = iso.g1 * self.mu + iso.bulk(self.kappa).0;
        let e = self.strain(iso.b1, fib.b4);
        if e > 0.0 {
            let ge = iso.g1 * self.dispersion + fib.g4 * (1.0 - 3.0 * self.dispersion);
            s += ge * (2.0 * self.k1 * e * (self.k2 * e * e).exp());
        }
        s
    }
    fn dpk2(&self, c: &Matrix3<f64>, dc: &Matrix3<f64>) -> Matrix3<f64> {
        let iso = Iso3::new(c, dc);
        let fib = Fib4::new(&iso, c, dc, &self.fibre);
        let mut ds = iso.dg1 * self.mu + iso.bulk(self.kappa).1;
        let e = self.strain(iso.b1, fib.b4);
        if e > 0.0 {
            let (wd, wf) = (self.dispersion, 1.0 - 3.0 * self.dispersion);
            let ge = iso.g1 * wd + fib.g4 * wf;
            let dge = iso.dg1 * wd + fib.dg4 * wf;
            let de = iso.db1 * wd + fib.db4 * wf;
            let x = self.k2 * e * e;
            ds += (ge * ((1.0 + 2.0 * x) * de) + dge * e) * (2.0 * self.k1 * x.exp());
        }
        ds
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    crate::material_tests!(
        solid,
        solid,
        HolzapfelGasserOgden::new(1e3, 5e4, 2e3, 3.0, 0.0, Vector3::new(1.0, 2.0, -0.5)).unwrap()
    );
    crate::material_tests!(
        dispersed,
        solid,
        HolzapfelGasserOgden::new(1e3, 5e4, 2e3, 3.0, 0.2, Vector3::new(0.3, -0.1, 1.0)).unwrap()
    );
    crate::material_tests!(
        linear_fibres,
        solid,
        HolzapfelGasserOgden::new(1e3, 5e4, 2e3, 0.0, 0.0, Vector3::new(1.0, 0.0, 0.0)).unwrap()
    );
}
