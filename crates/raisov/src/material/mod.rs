//! Hyperelastic materials: strain-energy functions and their second Piola-Kirchhoff stress.
//!
//! A material knows nothing of meshes. Every law is written in the right Cauchy-Green tensor
//! `C = Fᵀ F` and gives
//!
//! ```text
//! W(C)  strain energy per unit reference volume (J/m³ = Pa)
//! S = 2 ∂W/∂C   second Piola-Kirchhoff stress (Pa), symmetric
//! ```
//!
//! Two forms:
//! - [`SolidMaterial`]: 3-D, `C` is 3x3, used by tetrahedra. Compressible laws use `J = √det C`;
//!   the element checks `det F > 0` before calling (an inverted element is reported, not fed in).
//! - [`MembraneMaterial`]: plane stress, `C` is the 2x2 in-plane tensor of a membrane lifted
//!   out of its plane. Incompressible laws eliminate the thickness stretch, `λ3² = 1 / det C`, so
//!   `I1 = tr C + 1/det C`, `I2 = det C + tr C / det C` (design note, "Model"); the reduced
//!   energy's derivative is exactly the plane-stress S.
//!
//! Each law lives in its own file; the test macro `material_tests!` checks, for every law and
//! form, that S equals twice the central finite-difference derivative of W, that the reference
//! state is stress free, and that W is invariant under rotation (W depends on C only, so this
//! checks the wiring of F → C).

use crate::mesh::ElementKind;
use nalgebra::{Matrix2, Matrix3};

mod mooney_rivlin;
mod neo_hookean;
mod stvk;
mod veronda_westmann;

pub use mooney_rivlin::MooneyRivlin;
pub use neo_hookean::NeoHookean;
pub use stvk::StVenantKirchhoff;
pub use veronda_westmann::VerondaWestmann;

/// A 3-D hyperelastic law W(C).
pub trait SolidMaterial: Send + Sync {
    /// Strain energy per unit reference volume (Pa).
    fn energy(&self, c: &Matrix3<f64>) -> f64;
    /// Second Piola-Kirchhoff stress S = 2 ∂W/∂C (Pa).
    fn pk2(&self, c: &Matrix3<f64>) -> Matrix3<f64>;
}

/// A plane-stress membrane law W(C), C the 2x2 in-plane Cauchy-Green tensor.
pub trait MembraneMaterial: Send + Sync {
    /// Strain energy per unit reference volume (Pa); the element multiplies by h·A0.
    fn energy(&self, c: &Matrix2<f64>) -> f64;
    /// In-plane second Piola-Kirchhoff stress S = 2 ∂W/∂C (Pa).
    fn pk2(&self, c: &Matrix2<f64>) -> Matrix2<f64>;
    /// Thickness stretch λ3 for the Cauchy stress `σ = F S Fᵀ / (λ3 √det C)`:
    /// `1/√det C` for incompressible laws, 1 for laws that do not model thinning.
    fn thickness_stretch(&self, c: &Matrix2<f64>) -> f64;
}

/// Lamé parameters (λ, μ) from Young's modulus E (Pa) and Poisson's ratio ν.
pub fn lame(young: f64, poisson: f64) -> (f64, f64) {
    let mu = young / (2.0 * (1.0 + poisson));
    let lambda = young * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson));
    (lambda, mu)
}

/// The materials a scenario can name; dispatches statically to each law.
#[derive(Clone, Debug, PartialEq)]
pub enum Material {
    StVenantKirchhoff(StVenantKirchhoff),
    NeoHookean(NeoHookean),
    MooneyRivlin(MooneyRivlin),
    VerondaWestmann(VerondaWestmann),
}

impl Material {
    /// Short name as written in scenario files.
    pub fn name(&self) -> &'static str {
        match self {
            Material::StVenantKirchhoff(_) => "stvk",
            Material::NeoHookean(_) => "neo-hookean",
            Material::MooneyRivlin(_) => "mooney-rivlin",
            Material::VerondaWestmann(_) => "veronda-westmann",
        }
    }

    /// Small-strain shear modulus μ (Pa).
    pub fn shear_modulus(&self) -> f64 {
        match self {
            Material::StVenantKirchhoff(m) => m.mu,
            Material::NeoHookean(m) => m.mu,
            Material::MooneyRivlin(m) => 2.0 * (m.c1 + m.c2),
            Material::VerondaWestmann(m) => m.c1 * m.gamma,
        }
    }

    /// Small-strain modulus bounding one element's stiffness, for stable time steps
    /// (`c² = modulus / ρ` in [`crate::integrate::stability`]): the energy
    /// density `λ (tr ε)² + 2μ ε:ε` is at most `(dλ + 2μ) |∇u|²` in d dimensions, the bound
    /// reached by an element's dilatation mode. Solids: `3λ + 2μ = 3K` (`3κ` for the laws with
    /// a bulk modulus). Membranes (plane stress, d = 2): `2λ* + 2μ`, `λ* = 2λμ/(λ + 2μ)`;
    /// `6μ` for the incompressible laws (λ* = 2μ).
    pub fn stability_modulus(&self, kind: ElementKind) -> f64 {
        let mu = self.shear_modulus();
        match (self, kind) {
            (Material::StVenantKirchhoff(m), ElementKind::Tet4) => 3.0 * m.lambda + 2.0 * m.mu,
            (Material::NeoHookean(m), ElementKind::Tet4) => 3.0 * m.lambda + 2.0 * m.mu,
            (Material::MooneyRivlin(m), ElementKind::Tet4) => (3.0 * m.kappa).max(2.0 * mu),
            (Material::VerondaWestmann(m), ElementKind::Tet4) => (3.0 * m.kappa).max(2.0 * mu),
            (Material::StVenantKirchhoff(m), ElementKind::Tri3) => {
                let ls = 2.0 * m.lambda * m.mu / (m.lambda + 2.0 * m.mu);
                2.0 * ls + 2.0 * m.mu
            }
            (_, ElementKind::Tri3) => 6.0 * mu,
        }
    }
}

/// Generates the standard tests of one material form:
/// `material_tests!(module_name, SolidMaterial|MembraneMaterial, expr)`.
#[cfg(test)]
#[macro_export]
macro_rules! material_tests {
    ($modname:ident, solid, $mat:expr) => {
        mod $modname {
            #[allow(unused_imports)]
            use super::*;
            use nalgebra::Matrix3;
            use $crate::material::SolidMaterial;
            fn sample_f() -> Vec<Matrix3<f64>> {
                vec![
                    Matrix3::new(1.1, 0.2, -0.05, 0.03, 0.95, 0.1, -0.02, 0.07, 1.2),
                    Matrix3::new(1.6, 0.4, 0.1, -0.2, 0.7, 0.3, 0.05, -0.1, 1.05),
                    Matrix3::new(0.8, 0.0, 0.0, 0.0, 0.9, 0.0, 0.0, 0.0, 1.3),
                ]
            }
            #[test]
            fn stress_is_energy_derivative() {
                let owned = $mat;
                let m: &dyn SolidMaterial = &owned;
                for f in sample_f() {
                    let c = f.transpose() * f;
                    let s = m.pk2(&c);
                    let scale = s.norm().max(1.0);
                    for i in 0..3 {
                        for j in 0..3 {
                            let h = 1e-6;
                            let mut d = Matrix3::zeros();
                            d[(i, j)] += 0.5 * h;
                            d[(j, i)] += 0.5 * h;
                            let fd = 2.0 * (m.energy(&(c + d)) - m.energy(&(c - d))) / (2.0 * h);
                            assert!(
                                (fd - s[(i, j)]).abs() <= 1e-6 * scale,
                                "S[{i}{j}] = {} but 2 dW/dC = {fd}",
                                s[(i, j)]
                            );
                        }
                    }
                    assert!((s - s.transpose()).norm() <= 1e-12 * scale);
                }
            }
            #[test]
            fn reference_state_is_stress_free() {
                let owned = $mat;
                let m: &dyn SolidMaterial = &owned;
                let i = Matrix3::identity();
                assert!(m.energy(&i).abs() < 1e-12);
                assert!(m.pk2(&i).norm() < 1e-9);
            }
            #[test]
            fn energy_is_rotation_invariant() {
                let owned = $mat;
                let m: &dyn SolidMaterial = &owned;
                let r = nalgebra::Rotation3::from_euler_angles(0.3, -1.1, 2.0).into_inner();
                for f in sample_f() {
                    let c1 = f.transpose() * f;
                    let rf = r * f;
                    let c2 = rf.transpose() * rf;
                    let (w1, w2) = (m.energy(&c1), m.energy(&c2));
                    assert!((w1 - w2).abs() <= 1e-12 * w1.abs().max(1.0));
                }
            }
        }
    };
    ($modname:ident, membrane, $mat:expr) => {
        mod $modname {
            #[allow(unused_imports)]
            use super::*;
            use nalgebra::{Matrix2, Matrix3x2};
            use $crate::material::MembraneMaterial;
            fn sample_f() -> Vec<Matrix3x2<f64>> {
                vec![
                    Matrix3x2::new(1.1, 0.2, 0.03, 0.95, 0.2, -0.1),
                    Matrix3x2::new(1.6, 0.4, -0.2, 0.7, 0.5, 0.3),
                    Matrix3x2::new(0.8, 0.0, 0.0, 1.4, 0.0, 0.0),
                ]
            }
            #[test]
            fn stress_is_energy_derivative() {
                let owned = $mat;
                let m: &dyn MembraneMaterial = &owned;
                for f in sample_f() {
                    let c = f.transpose() * f;
                    let s = m.pk2(&c);
                    let scale = s.norm().max(1.0);
                    for i in 0..2 {
                        for j in 0..2 {
                            let h = 1e-6;
                            let mut d = Matrix2::zeros();
                            d[(i, j)] += 0.5 * h;
                            d[(j, i)] += 0.5 * h;
                            let fd = 2.0 * (m.energy(&(c + d)) - m.energy(&(c - d))) / (2.0 * h);
                            assert!(
                                (fd - s[(i, j)]).abs() <= 1e-6 * scale,
                                "S[{i}{j}] = {} but 2 dW/dC = {fd}",
                                s[(i, j)]
                            );
                        }
                    }
                }
            }
            #[test]
            fn reference_state_is_stress_free() {
                let owned = $mat;
                let m: &dyn MembraneMaterial = &owned;
                let i = Matrix2::identity();
                assert!(m.energy(&i).abs() < 1e-12);
                assert!(m.pk2(&i).norm() < 1e-9);
            }
        }
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lame_parameters() {
        let (l, m) = lame(5e4, 0.4);
        assert!((m - 5e4 / 2.8).abs() < 1e-9);
        assert!((l - 5e4 * 0.4 / (1.4 * 0.2)).abs() < 1e-6);
    }

    /// All laws agree with linear elasticity for a small uniaxial strain (same μ).
    #[test]
    fn small_strain_shear_modulus_agrees() {
        let eps = 1e-6;
        // Simple shear: C = I + eps (e1 e2ᵀ + e2 e1ᵀ) to first order; S12 ≈ 2 μ E12 = μ eps.
        let mut c = Matrix3::identity();
        c[(0, 1)] = eps;
        c[(1, 0)] = eps;
        let mats: Vec<(Material, Box<dyn SolidMaterial>)> = vec![
            (
                Material::StVenantKirchhoff(StVenantKirchhoff::from_young(1e4, 0.3)),
                Box::new(StVenantKirchhoff::from_young(1e4, 0.3)),
            ),
            (
                Material::NeoHookean(NeoHookean::from_young(1e4, 0.3)),
                Box::new(NeoHookean::from_young(1e4, 0.3)),
            ),
            (
                Material::MooneyRivlin(MooneyRivlin::new(1e3, 500.0, 1e5)),
                Box::new(MooneyRivlin::new(1e3, 500.0, 1e5)),
            ),
            (
                Material::VerondaWestmann(VerondaWestmann::new(300.0, 5.0, 1e5)),
                Box::new(VerondaWestmann::new(300.0, 5.0, 1e5)),
            ),
        ];
        for (desc, m) in mats {
            let mu = desc.shear_modulus();
            let s = m.pk2(&c);
            assert!(
                (s[(0, 1)] - mu * eps).abs() < 1e-3 * mu * eps,
                "{}: S12 = {}, μ eps = {}",
                desc.name(),
                s[(0, 1)],
                mu * eps
            );
        }
    }
}
