//! Mooney-Rivlin. The paper's membrane is Mooney-Rivlin with C1 = C2 (section 3).
//!
//! Membrane, incompressible plane stress (λ3² = 1/det C):
//! ```text
//! W = C1 (I1 − 3) + C2 (I2 − 3),   I1 = tr C + 1/det C,   I2 = det C + tr C / det C
//! ∂I1/∂C = I − C⁻¹/det C,   ∂I2/∂C = det C C⁻¹ + (I − tr C C⁻¹)/det C,   S = 2 (C1 ∂I1 + C2 ∂I2)
//! ```
//! Solid, compressible (isochoric invariants Ī1 = J^(-2/3) I1, Ī2 = J^(-4/3) I2, bulk modulus κ):
//! ```text
//! W = C1 (Ī1 − 3) + C2 (Ī2 − 3) + κ/2 (J − 1)²
//! S = 2 C1 J^(-2/3) (I − I1/3 C⁻¹) + 2 C2 J^(-4/3) (I1 I − C − 2/3 I2 C⁻¹) + κ (J − 1) J C⁻¹
//! ```
//! Tangents: `dS = 2 (C1 dg1 + C2 dg2)` (+ the bulk term's) with the invariants' gradients and
//! differentials of [`super::Iso3`] (solid) and [`super::Inc2`] (membrane).
//! Small-strain shear modulus μ = 2 (C1 + C2).

use super::{MembraneMaterial, SolidMaterial};
use nalgebra::{Matrix2, Matrix3};

/// Mooney-Rivlin constants C1, C2 (Pa) and bulk modulus κ (Pa, solids only).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MooneyRivlin {
    /// C1 (Pa), the coefficient of `Ī1 − 3` (membrane: `I1 − 3`).
    pub c1: f64,
    /// C2 (Pa), the coefficient of `Ī2 − 3` (membrane: `I2 − 3`).
    pub c2: f64,
    /// Bulk modulus κ (Pa) of the solid's `κ/2 (J − 1)²`; unused by membranes.
    pub kappa: f64,
}

impl MooneyRivlin {
    /// The law with constants C1, C2 and bulk modulus κ (Pa).
    pub fn new(c1: f64, c2: f64, kappa: f64) -> Self {
        MooneyRivlin { c1, c2, kappa }
    }
}

fn invariants3(c: &Matrix3<f64>) -> (f64, f64, f64) {
    let i1 = c.trace();
    let i2 = 0.5 * (i1 * i1 - (c * c).trace());
    (i1, i2, c.determinant())
}

impl SolidMaterial for MooneyRivlin {
    fn energy(&self, c: &Matrix3<f64>) -> f64 {
        let (i1, i2, i3) = invariants3(c);
        let j = i3.sqrt();
        self.c1 * (i1 * j.powf(-2.0 / 3.0) - 3.0)
            + self.c2 * (i2 * j.powf(-4.0 / 3.0) - 3.0)
            + 0.5 * self.kappa * (j - 1.0) * (j - 1.0)
    }
    fn pk2(&self, c: &Matrix3<f64>) -> Matrix3<f64> {
        let (i1, i2, i3) = invariants3(c);
        let j = i3.sqrt();
        let cinv = c.try_inverse().unwrap_or_else(Matrix3::zeros);
        let id = Matrix3::identity();
        (id - cinv * (i1 / 3.0)) * (2.0 * self.c1 * j.powf(-2.0 / 3.0))
            + (id * i1 - c - cinv * (2.0 / 3.0 * i2)) * (2.0 * self.c2 * j.powf(-4.0 / 3.0))
            + cinv * (self.kappa * (j - 1.0) * j)
    }
    fn dpk2(&self, c: &Matrix3<f64>, dc: &Matrix3<f64>) -> Matrix3<f64> {
        let iso = super::Iso3::new(c, dc);
        (iso.dg1 * self.c1 + iso.dg2 * self.c2) * 2.0 + iso.bulk(self.kappa).1
    }
}

impl MembraneMaterial for MooneyRivlin {
    fn energy(&self, c: &Matrix2<f64>) -> f64 {
        let det = c.determinant();
        let tr = c.trace();
        self.c1 * (tr + 1.0 / det - 3.0) + self.c2 * (det + tr / det - 3.0)
    }
    fn pk2(&self, c: &Matrix2<f64>) -> Matrix2<f64> {
        let det = c.determinant();
        let tr = c.trace();
        let cinv = c.try_inverse().unwrap_or_else(Matrix2::zeros);
        let id = Matrix2::identity();
        let di1 = id - cinv / det;
        let di2 = cinv * det + (id - cinv * tr) / det;
        (di1 * self.c1 + di2 * self.c2) * 2.0
    }
    fn dpk2(&self, c: &Matrix2<f64>, dc: &Matrix2<f64>) -> Matrix2<f64> {
        let inc = super::Inc2::new(c, dc);
        (inc.dg1 * self.c1 + inc.dg2 * self.c2) * 2.0
    }
    fn thickness_stretch(&self, c: &Matrix2<f64>) -> f64 {
        1.0 / c.determinant().sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    crate::material_tests!(solid, solid, MooneyRivlin::new(1e3, 400.0, 5e4));
    crate::material_tests!(membrane, membrane, MooneyRivlin::new(1.0, 1.0, 0.0));
}
