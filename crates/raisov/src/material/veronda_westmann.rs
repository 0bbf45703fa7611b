//! Veronda-Westmann: an exponential soft-tissue law (Fung-type stiffening; Veronda & Westmann
//! 1970, skin).
//!
//! Membrane, incompressible plane stress (I1, I2 as in [`super::MooneyRivlin`]):
//! ```text
//! W = c1 (exp(γ (I1 − 3)) − 1) − c1 γ / 2 (I2 − 3)
//! S = 2 [c1 γ exp(γ (I1 − 3)) ∂I1/∂C − c1 γ / 2 ∂I2/∂C]
//! ```
//! Solid, compressible: the same in the isochoric invariants Ī1, Ī2 plus κ/2 (J − 1)².
//! Tangent, with `w1 = c1 γ exp(γ (I1 − 3))`, `w2 = −c1 γ / 2` and the invariants' gradients
//! `g` and differentials of [`super::Iso3`] / [`super::Inc2`]:
//! `dS = 2 (γ w1 (g1 : dC) g1 + w1 dg1 + w2 dg2)` (+ the bulk term's for solids).
//! Small-strain shear modulus μ = c1 γ.

use super::{MembraneMaterial, SolidMaterial};
use nalgebra::{Matrix2, Matrix3};

/// Veronda-Westmann constants c1 (Pa), γ (dimensionless) and bulk modulus κ (Pa, solids).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VerondaWestmann {
    /// c1 (Pa), the scale of `c1 (exp(γ (I1 − 3)) − 1) − c1 γ / 2 (I2 − 3)`.
    pub c1: f64,
    /// γ (dimensionless), the exponential stiffening rate.
    pub gamma: f64,
    /// Bulk modulus κ (Pa) of the solid's `κ/2 (J − 1)²`; unused by membranes.
    pub kappa: f64,
}

impl VerondaWestmann {
    /// The law with constants c1 (Pa), γ and bulk modulus κ (Pa).
    pub fn new(c1: f64, gamma: f64, kappa: f64) -> Self {
        VerondaWestmann { c1, gamma, kappa }
    }
}

impl SolidMaterial for VerondaWestmann {
    fn energy(&self, c: &Matrix3<f64>) -> f64 {
        let i1 = c.trace();
        let i2 = 0.5 * (i1 * i1 - (c * c).trace());
        let j = c.determinant().sqrt();
        let b1 = i1 * j.powf(-2.0 / 3.0);
        let b2 = i2 * j.powf(-4.0 / 3.0);
        self.c1 * ((self.gamma * (b1 - 3.0)).exp() - 1.0) - 0.5 * self.c1 * self.gamma * (b2 - 3.0)
            + 0.5 * self.kappa * (j - 1.0) * (j - 1.0)
    }
    fn pk2(&self, c: &Matrix3<f64>) -> Matrix3<f64> {
        let i1 = c.trace();
        let i2 = 0.5 * (i1 * i1 - (c * c).trace());
        let j = c.determinant().sqrt();
        let cinv = c.try_inverse().unwrap_or_else(Matrix3::zeros);
        let id = Matrix3::identity();
        let j23 = j.powf(-2.0 / 3.0);
        let j43 = j.powf(-4.0 / 3.0);
        let b1 = i1 * j23;
        let db1 = (id - cinv * (i1 / 3.0)) * j23;
        let db2 = (id * i1 - c - cinv * (2.0 / 3.0 * i2)) * j43;
        let w1 = self.c1 * self.gamma * (self.gamma * (b1 - 3.0)).exp();
        let w2 = -0.5 * self.c1 * self.gamma;
        (db1 * w1 + db2 * w2) * 2.0 + cinv * (self.kappa * (j - 1.0) * j)
    }
    fn dpk2(&self, c: &Matrix3<f64>, dc: &Matrix3<f64>) -> Matrix3<f64> {
        let iso = super::Iso3::new(c, dc);
        let w1 = self.c1 * self.gamma * (self.gamma * (iso.b1 - 3.0)).exp();
        let w2 = -0.5 * self.c1 * self.gamma;
        (iso.g1 * (self.gamma * w1 * iso.db1) + iso.dg1 * w1 + iso.dg2 * w2) * 2.0
            + iso.bulk(self.kappa).1
    }
}

impl MembraneMaterial for VerondaWestmann {
    fn energy(&self, c: &Matrix2<f64>) -> f64 {
        let det = c.determinant();
        let tr = c.trace();
        let i1 = tr + 1.0 / det;
        let i2 = det + tr / det;
        self.c1 * ((self.gamma * (i1 - 3.0)).exp() - 1.0) - 0.5 * self.c1 * self.gamma * (i2 - 3.0)
    }
    fn pk2(&self, c: &Matrix2<f64>) -> Matrix2<f64> {
        let det = c.determinant();
        let tr = c.trace();
        let i1 = tr + 1.0 / det;
        let cinv = c.try_inverse().unwrap_or_else(Matrix2::zeros);
        let id = Matrix2::identity();
        let di1 = id - cinv / det;
        let di2 = cinv * det + (id - cinv * tr) / det;
        let w1 = self.c1 * self.gamma * (self.gamma * (i1 - 3.0)).exp();
        let w2 = -0.5 * self.c1 * self.gamma;
        (di1 * w1 + di2 * w2) * 2.0
    }
    fn dpk2(&self, c: &Matrix2<f64>, dc: &Matrix2<f64>) -> Matrix2<f64> {
        let inc = super::Inc2::new(c, dc);
        let w1 = self.c1 * self.gamma * (self.gamma * (inc.i1 - 3.0)).exp();
        let w2 = -0.5 * self.c1 * self.gamma;
        (inc.g1 * (self.gamma * w1 * inc.di1) + inc.dg1 * w1 + inc.dg2 * w2) * 2.0
    }
    fn thickness_stretch(&self, c: &Matrix2<f64>) -> f64 {
        1.0 / c.determinant().sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    crate::material_tests!(solid, solid, VerondaWestmann::new(300.0, 2.0, 5e4));
    crate::material_tests!(membrane, membrane, VerondaWestmann::new(300.0, 2.0, 0.0));
}
