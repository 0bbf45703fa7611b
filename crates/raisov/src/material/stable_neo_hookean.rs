//! Stable neo-Hookean (Smith, de Goes & Kim 2018, "Stable Neo-Hookean Flesh Simulation",
//! ACM TOG 37(2); the law of SOFA's `StableNeoHookean`): no logarithm of J, so the energy and
//! the stress are finite for collapsed and inverted tetrahedra (`det F ≤ 0`) and an inverted
//! element is pushed back out instead of stopping the run.
//!
//! Solid, in d = 3 dimensions, `I_C = tr C = |F|²`, `J = det F` (signed):
//! ```text
//! W = μ'/2 (I_C − d) + λ'/2 (J − α)² − μ'/2 ln(I_C + 1) − W0,    α = 1 + d μ' / ((d + 1) λ')
//! P = μ' (1 − 1/(I_C + 1)) F + λ' (J − α) cof F
//! dP = μ' (1 − 1/(I_C + 1)) dF + 2μ' (F:dF)/(I_C + 1)² F + λ' (cof F : dF) cof F + λ' (J − α) d(cof F)
//! ```
//! with `cof F = ∂J/∂F = [f1 × f2, f2 × f0, f0 × f1]` (columns, `f_k` the columns of F) and
//! `W0` the constant that makes `W(I) = 0`. α makes the rest state stress free (paper, section
//! 3.4). In C (for `det F > 0`, `J = √det C`):
//! `S = μ' (1 − 1/(I_C + 1)) I + λ' (J − α) J C⁻¹`,
//! `dS = μ' tr dC/(I_C + 1)² I + λ' (2J − α) J t/2 C⁻¹ − λ' (J − α) J C⁻¹dCC⁻¹`, `t = tr(C⁻¹dC)`.
//!
//! Lamé mapping (paper, section 3.4, eq. 15-16; SOFA's): the law's small-strain response
//! equals linear elasticity with the user's Lamé parameters (μ, λ) when
//! `μ' = 4/3 μ`, `λ' = λ + 5/6 μ` (d = 3): linearising W at F = I gives the elasticity tensor
//! `d μ'/(d + 1) (𝕀 + 𝕋) + (λ' + 2μ'/(d + 1)² − d μ'/(d + 1)) I⊗I` (𝕋 the transpose map), so
//! `μ = d μ'/(d + 1)`, `λ = λ' + 2μ'/(d + 1)² − d μ'/(d + 1)`; for d = 2, `μ' = 3/2 μ`,
//! `λ' = λ + 2/3 μ`. Checked by the test `small_strain_matches_lame`.
//!
//! Membrane: the same law in d = 2 in the in-plane C (2x2) with `J = √det C` (the area
//! ratio), plane stress through the plane-stress Lamé constant `λ* = 2λμ/(λ + 2μ)`, mapped as
//! `μ' = 3/2 μ`, `λ' = λ* + 2/3 μ`; thickness not modelled (λ3 = 1, as
//! [`super::StVenantKirchhoff`]). A membrane in 3-D has no inside: a triangle flipped against its
//! reference normal is refused as for every other law (`handles_inversion` is false there),
//! while a collapsing one (J → 0) keeps a finite energy and stress.

use super::{lame, MembraneMaterial, SolidMaterial};
use nalgebra::{Matrix2, Matrix3, Vector3};

/// Stable neo-Hookean with the user's small-strain Lamé parameters (Pa); the law's own
/// constants follow from the Lamé mapping (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StableNeoHookean {
    /// Small-strain shear modulus μ (Pa).
    pub lame_mu: f64,
    /// Small-strain Lamé λ (Pa).
    pub lame_lambda: f64,
}

/// The law's constants in d dimensions: (μ', λ', α, W0).
#[derive(Clone, Copy)]
struct Consts {
    mu: f64,
    lambda: f64,
    alpha: f64,
    w0: f64,
}

impl Consts {
    fn new(mu: f64, lambda: f64, d: f64) -> Self {
        let alpha = 1.0 + d * mu / ((d + 1.0) * lambda);
        let w0 = 0.5 * lambda * (1.0 - alpha) * (1.0 - alpha) - 0.5 * mu * (d + 1.0).ln();
        Consts {
            mu,
            lambda,
            alpha,
            w0,
        }
    }
    fn energy(&self, ic: f64, j: f64, d: f64) -> f64 {
        0.5 * self.mu * (ic - d) + 0.5 * self.lambda * (j - self.alpha) * (j - self.alpha)
            - 0.5 * self.mu * (ic + 1.0).ln()
            - self.w0
    }
}

impl StableNeoHookean {
    /// The law whose small-strain Lamé parameters are those of Young's modulus E (Pa) and
    /// Poisson's ratio ν ([`super::lame`]).
    pub fn from_young(young: f64, poisson: f64) -> Self {
        let (lame_lambda, lame_mu) = lame(young, poisson);
        StableNeoHookean {
            lame_mu,
            lame_lambda,
        }
    }
    fn solid(&self) -> Consts {
        Consts::new(
            4.0 / 3.0 * self.lame_mu,
            self.lame_lambda + 5.0 / 6.0 * self.lame_mu,
            3.0,
        )
    }
    fn membrane(&self) -> Consts {
        let (l, m) = (self.lame_lambda, self.lame_mu);
        let ls = 2.0 * l * m / (l + 2.0 * m);
        Consts::new(1.5 * m, ls + 2.0 / 3.0 * m, 2.0)
    }
}

/// `cof F`, columns `[f1 × f2, f2 × f0, f0 × f1]`.
fn cofactor(f: &Matrix3<f64>) -> Matrix3<f64> {
    let c = |k: usize| -> Vector3<f64> { f.column(k).into() };
    Matrix3::from_columns(&[c(1).cross(&c(2)), c(2).cross(&c(0)), c(0).cross(&c(1))])
}

/// S and dS in C for any d (module docs).
macro_rules! pk2_in_c {
    ($k:expr, $c:expr, $dc:expr, $id:expr, $cinv:expr) => {{
        let k = $k;
        let ic = $c.trace();
        let j = $c.determinant().max(0.0).sqrt();
        let s = $id * (k.mu * (1.0 - 1.0 / (ic + 1.0))) + $cinv * (k.lambda * (j - k.alpha) * j);
        let ds = $dc.map(|dc| {
            let t = ($cinv * dc).trace();
            let cdc = $cinv * dc * $cinv;
            $id * (k.mu * dc.trace() / ((ic + 1.0) * (ic + 1.0)))
                + $cinv * (k.lambda * (2.0 * j - k.alpha) * j * 0.5 * t)
                - cdc * (k.lambda * (j - k.alpha) * j)
        });
        (s, ds)
    }};
}

impl SolidMaterial for StableNeoHookean {
    fn energy(&self, c: &Matrix3<f64>) -> f64 {
        self.solid()
            .energy(c.trace(), c.determinant().max(0.0).sqrt(), 3.0)
    }
    fn pk2(&self, c: &Matrix3<f64>) -> Matrix3<f64> {
        let cinv = c.try_inverse().unwrap_or_else(Matrix3::zeros);
        let no: Option<&Matrix3<f64>> = None;
        pk2_in_c!(self.solid(), c, no, Matrix3::identity(), cinv).0
    }
    fn dpk2(&self, c: &Matrix3<f64>, dc: &Matrix3<f64>) -> Matrix3<f64> {
        let cinv = c.try_inverse().unwrap_or_else(Matrix3::zeros);
        let (_, ds) = pk2_in_c!(self.solid(), c, Some(dc), Matrix3::identity(), cinv);
        ds.unwrap_or_else(Matrix3::zeros)
    }
    fn handles_inversion(&self) -> bool {
        true
    }
    fn energy_f(&self, f: &Matrix3<f64>) -> f64 {
        self.solid().energy(f.norm_squared(), f.determinant(), 3.0)
    }
    fn pk1(&self, f: &Matrix3<f64>) -> Matrix3<f64> {
        let k = self.solid();
        let ic = f.norm_squared();
        f * (k.mu * (1.0 - 1.0 / (ic + 1.0)))
            + cofactor(f) * (k.lambda * (f.determinant() - k.alpha))
    }
    fn dpk1(&self, f: &Matrix3<f64>, df: &Matrix3<f64>) -> Matrix3<f64> {
        let k = self.solid();
        let ic = f.norm_squared();
        let cof = cofactor(f);
        let c = |m: &Matrix3<f64>, i: usize| -> Vector3<f64> { m.column(i).into() };
        // d(cof F): the product rule on each cross product.
        let dcof = Matrix3::from_columns(&[
            c(df, 1).cross(&c(f, 2)) + c(f, 1).cross(&c(df, 2)),
            c(df, 2).cross(&c(f, 0)) + c(f, 2).cross(&c(df, 0)),
            c(df, 0).cross(&c(f, 1)) + c(f, 0).cross(&c(df, 1)),
        ]);
        let q = ic + 1.0;
        df * (k.mu * (1.0 - 1.0 / q))
            + f * (2.0 * k.mu * f.dot(df) / (q * q))
            + cof * (k.lambda * cof.dot(df))
            + dcof * (k.lambda * (f.determinant() - k.alpha))
    }
    /// [`SolidMaterial::dpk1`] per direction: this law's dP is in the F form.
    fn dpk1_many(&self, f: &Matrix3<f64>, dfs: &[Matrix3<f64>], out: &mut [Matrix3<f64>]) {
        for (df, o) in dfs.iter().zip(out) {
            *o = SolidMaterial::dpk1(self, f, df);
        }
    }
}

impl MembraneMaterial for StableNeoHookean {
    fn energy(&self, c: &Matrix2<f64>) -> f64 {
        self.membrane()
            .energy(c.trace(), c.determinant().max(0.0).sqrt(), 2.0)
    }
    fn pk2(&self, c: &Matrix2<f64>) -> Matrix2<f64> {
        let cinv = c.try_inverse().unwrap_or_else(Matrix2::zeros);
        let no: Option<&Matrix2<f64>> = None;
        pk2_in_c!(self.membrane(), c, no, Matrix2::identity(), cinv).0
    }
    fn dpk2(&self, c: &Matrix2<f64>, dc: &Matrix2<f64>) -> Matrix2<f64> {
        let cinv = c.try_inverse().unwrap_or_else(Matrix2::zeros);
        let (_, ds) = pk2_in_c!(self.membrane(), c, Some(dc), Matrix2::identity(), cinv);
        ds.unwrap_or_else(Matrix2::zeros)
    }
    fn thickness_stretch(&self, _c: &Matrix2<f64>) -> f64 {
        1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    crate::material_tests!(solid, solid, StableNeoHookean::from_young(1e4, 0.4));
    crate::material_tests!(membrane, membrane, StableNeoHookean::from_young(1e4, 0.4));

    /// The Lamé mapping: at small strain the stress is linear elasticity's with the user's
    /// (λ, μ), `S ≈ λ tr(E) I + 2μ E`, solid and plane-stress membrane, to 1e-5 relative.
    #[test]
    fn small_strain_matches_lame() {
        let m = StableNeoHookean::from_young(1e4, 0.4);
        let (l, mu) = (m.lame_lambda, m.lame_mu);
        let e = Matrix3::new(1.0, 0.3, -0.2, 0.3, -0.4, 0.5, -0.2, 0.5, 0.7) * 1e-7;
        let s = SolidMaterial::pk2(&m, &(Matrix3::identity() + e * 2.0));
        let lin = Matrix3::identity() * (l * e.trace()) + e * (2.0 * mu);
        assert!((s - lin).norm() <= 1e-5 * lin.norm(), "{s} vs {lin}");
        let e2 = Matrix2::new(1.0, 0.3, 0.3, -0.4) * 1e-7;
        let ls = 2.0 * l * mu / (l + 2.0 * mu);
        let s2 = MembraneMaterial::pk2(&m, &(Matrix2::identity() + e2 * 2.0));
        let lin2 = Matrix2::identity() * (ls * e2.trace()) + e2 * (2.0 * mu);
        assert!((s2 - lin2).norm() <= 1e-5 * lin2.norm(), "{s2} vs {lin2}");
    }

    /// Finite energy and stress through collapse and inversion, and the stress pushes a
    /// collapsed or inverted axis back out: `∂W/∂F11 < 0` for `F = diag(j, 1, 1)`, j ≤ 0.001
    /// (the energy falls as the axis stretches back).
    #[test]
    fn inverted_state_is_finite_and_pushes_out() {
        let m = StableNeoHookean::from_young(1e4, 0.4);
        for j in [-0.5, -1e-3, 0.0, 1e-3] {
            let f = Matrix3::new(j, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
            let w = SolidMaterial::energy_f(&m, &f);
            let p = SolidMaterial::pk1(&m, &f);
            assert!(w.is_finite() && p.iter().all(|x| x.is_finite()), "J = {j}");
            // dW/dF11 < 0: stretching the collapsed axis back lowers the energy.
            assert!(p[(0, 0)] < 0.0, "J = {j}: P11 = {}", p[(0, 0)]);
        }
    }
}
