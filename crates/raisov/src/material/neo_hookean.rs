//! Neo-Hookean.
//!
//! Solid, compressible (the form of the performance benchmark, issue 4):
//! ```text
//! W = μ/2 (I1 − 3) − μ ln J + λ/2 (ln J)²,      J = √det C, I1 = tr C
//! S = μ (I − C⁻¹) + λ ln J C⁻¹
//! ```
//! with the tangent (t = tr(C⁻¹ dC))
//! ```text
//! dS = μ C⁻¹dCC⁻¹ + λ t/2 C⁻¹ − λ ln J C⁻¹dCC⁻¹
//! ```
//! In F form (H = F⁻ᵀ, c = λ ln J − μ), `P = μ F + c H` and
//! `dP = μ dF + λ (H : dF) H − c H dFᵀ H`, so the tangent contracted with two vectors a, b
//! (a tetrahedron's stiffness block of two nodes per unit volume,
//! [`SolidMaterial::contract_dpk1`]) is, with `Ha`, `Hb`,
//! ```text
//! Σ_JL a_J ∂P_iJ/∂F_kL b_L = μ (a·b) δ_ik + λ (Ha)_i (Hb)_k − c (Hb)_i (Ha)_k
//! ```
//! Membrane, incompressible plane stress (λ3² = 1/det C):
//! ```text
//! W = μ/2 (tr C + 1/det C − 3),    S = μ (I − C⁻¹ / det C),   dS = μ (C⁻¹dCC⁻¹ + t C⁻¹)/det C
//! ```

use super::{lame, MembraneMaterial, SolidMaterial};
use nalgebra::{Matrix2, Matrix3, Vector3};

/// Neo-Hookean with Lamé parameters λ (bulk-like, solid only) and shear modulus μ (Pa).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NeoHookean {
    /// Lamé λ (Pa), the coefficient of `λ/2 (ln J)²`; unused by membranes.
    pub lambda: f64,
    /// Shear modulus μ (Pa).
    pub mu: f64,
}

impl NeoHookean {
    /// The law with the Lamé parameters of Young's modulus E (Pa) and Poisson's ratio ν
    /// ([`super::lame`]).
    pub fn from_young(young: f64, poisson: f64) -> Self {
        let (lambda, mu) = lame(young, poisson);
        NeoHookean { lambda, mu }
    }
}

impl SolidMaterial for NeoHookean {
    fn energy(&self, c: &Matrix3<f64>) -> f64 {
        let lnj = 0.5 * c.determinant().ln();
        0.5 * self.mu * (c.trace() - 3.0) - self.mu * lnj + 0.5 * self.lambda * lnj * lnj
    }
    fn pk2(&self, c: &Matrix3<f64>) -> Matrix3<f64> {
        let det = c.determinant();
        let lnj = 0.5 * det.ln();
        let cinv = c.try_inverse().unwrap_or_else(Matrix3::zeros);
        (Matrix3::identity() - cinv) * self.mu + cinv * (self.lambda * lnj)
    }
    fn dpk2(&self, c: &Matrix3<f64>, dc: &Matrix3<f64>) -> Matrix3<f64> {
        let lnj = 0.5 * c.determinant().ln();
        let cinv = c.try_inverse().unwrap_or_else(Matrix3::zeros);
        let cdc = cinv * dc * cinv;
        let t = (cinv * dc).trace();
        cdc * (self.mu - self.lambda * lnj) + cinv * (0.5 * self.lambda * t)
    }
    /// `dP = dF S + F dS`, with `C⁻¹`, `ln J` and S formed once for all directions.
    fn dpk1_many(&self, f: &Matrix3<f64>, dfs: &[Matrix3<f64>], out: &mut [Matrix3<f64>]) {
        let c = f.transpose() * f;
        let lnj = 0.5 * c.determinant().ln();
        let cinv = c.try_inverse().unwrap_or_else(Matrix3::zeros);
        let s = (Matrix3::identity() - cinv) * self.mu + cinv * (self.lambda * lnj);
        let (a, b) = (self.mu - self.lambda * lnj, 0.5 * self.lambda);
        for (df, o) in dfs.iter().zip(out) {
            let dc = df.transpose() * f + f.transpose() * df;
            let cdc = cinv * dc;
            let ds = cdc * cinv * a + cinv * (b * cdc.trace());
            *o = df * s + f * ds;
        }
    }
    /// The closed form of the module docs.
    fn contract_dpk1(
        &self,
        f: &Matrix3<f64>,
        g: &[Vector3<f64>; 4],
        out: &mut [Matrix3<f64>; 16],
    ) -> bool {
        let Some(finv) = f.try_inverse() else {
            return false;
        };
        let h = finv.transpose();
        let c = self.lambda * f.determinant().ln() - self.mu;
        let hg = g.map(|ga| h * ga);
        for a in 0..4 {
            for b in 0..4 {
                let (ha, hb) = (&hg[a], &hg[b]);
                out[4 * a + b] = Matrix3::from_diagonal_element(self.mu * g[a].dot(&g[b]))
                    + ha * hb.transpose() * self.lambda
                    - hb * ha.transpose() * c;
            }
        }
        true
    }
}

impl MembraneMaterial for NeoHookean {
    fn energy(&self, c: &Matrix2<f64>) -> f64 {
        0.5 * self.mu * (c.trace() + 1.0 / c.determinant() - 3.0)
    }
    fn pk2(&self, c: &Matrix2<f64>) -> Matrix2<f64> {
        let det = c.determinant();
        let cinv = c.try_inverse().unwrap_or_else(Matrix2::zeros);
        (Matrix2::identity() - cinv / det) * self.mu
    }
    fn dpk2(&self, c: &Matrix2<f64>, dc: &Matrix2<f64>) -> Matrix2<f64> {
        super::Inc2::new(c, dc).dg1 * self.mu
    }
    fn thickness_stretch(&self, c: &Matrix2<f64>) -> f64 {
        1.0 / c.determinant().sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    crate::material_tests!(solid, solid, NeoHookean::from_young(1e4, 0.4));
    crate::material_tests!(membrane, membrane, NeoHookean::from_young(1e4, 0.4));
}
