//! St Venant-Kirchhoff: linear stress-strain in the Green-Lagrange strain `E = (C − I)/2`.
//!
//! ```text
//! W = λ/2 (tr E)² + μ E:E,        S = λ tr(E) I + 2 μ E,      dS = λ/2 tr(dC) I + μ dC
//! ```
//!
//! Membrane (plane stress, S33 = 0 eliminated): the same form with `λ* = 2λμ / (λ + 2μ)`.
//! StVK softens and fails under strong compression; use it for moderate strains.

use super::{lame, MembraneMaterial, SolidMaterial};
use nalgebra::{Matrix2, Matrix3};

/// St Venant-Kirchhoff with Lamé parameters λ, μ (Pa).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StVenantKirchhoff {
    /// Lamé λ (Pa); membranes use the plane-stress `λ* = 2λμ / (λ + 2μ)` in its place.
    pub lambda: f64,
    /// Lamé μ, the shear modulus (Pa).
    pub mu: f64,
}

impl StVenantKirchhoff {
    /// The law with the Lamé parameters of Young's modulus E (Pa) and Poisson's ratio ν
    /// ([`super::lame`]).
    pub fn from_young(young: f64, poisson: f64) -> Self {
        let (lambda, mu) = lame(young, poisson);
        StVenantKirchhoff { lambda, mu }
    }
    fn plane_stress_lambda(&self) -> f64 {
        2.0 * self.lambda * self.mu / (self.lambda + 2.0 * self.mu)
    }
}

impl SolidMaterial for StVenantKirchhoff {
    fn energy(&self, c: &Matrix3<f64>) -> f64 {
        let e = (c - Matrix3::identity()) * 0.5;
        let tr = e.trace();
        0.5 * self.lambda * tr * tr + self.mu * e.component_mul(&e).sum()
    }
    fn pk2(&self, c: &Matrix3<f64>) -> Matrix3<f64> {
        let e = (c - Matrix3::identity()) * 0.5;
        Matrix3::identity() * (self.lambda * e.trace()) + e * (2.0 * self.mu)
    }
    fn dpk2(&self, _c: &Matrix3<f64>, dc: &Matrix3<f64>) -> Matrix3<f64> {
        Matrix3::identity() * (0.5 * self.lambda * dc.trace()) + dc * self.mu
    }
}

impl MembraneMaterial for StVenantKirchhoff {
    fn energy(&self, c: &Matrix2<f64>) -> f64 {
        let e = (c - Matrix2::identity()) * 0.5;
        let tr = e.trace();
        0.5 * self.plane_stress_lambda() * tr * tr + self.mu * e.component_mul(&e).sum()
    }
    fn pk2(&self, c: &Matrix2<f64>) -> Matrix2<f64> {
        let e = (c - Matrix2::identity()) * 0.5;
        Matrix2::identity() * (self.plane_stress_lambda() * e.trace()) + e * (2.0 * self.mu)
    }
    fn dpk2(&self, _c: &Matrix2<f64>, dc: &Matrix2<f64>) -> Matrix2<f64> {
        Matrix2::identity() * (0.5 * self.plane_stress_lambda() * dc.trace()) + dc * self.mu
    }
    fn thickness_stretch(&self, _c: &Matrix2<f64>) -> f64 {
        1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    crate::material_tests!(solid, solid, StVenantKirchhoff::from_young(1e4, 0.3));
    crate::material_tests!(membrane, membrane, StVenantKirchhoff::from_young(1e4, 0.3));
}
