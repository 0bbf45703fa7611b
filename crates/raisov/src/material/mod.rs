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
//! Tangents, for Newton's method and element stiffness matrices: every law gives the
//! directional derivative of its stress along a symmetric `dC`,
//!
//! ```text
//! dS = ∂S/∂C : dC = 4 ∂²W/∂C∂C : dC/2          (dpk2)
//! ```
//!
//! and, in the deformation gradient, the first Piola-Kirchhoff stress and its differential
//!
//! ```text
//! P = ∂W/∂F = F S,    dP = dF S + F dS(C; dC),   dC = dFᵀ F + Fᵀ dF     (pk1, dpk1)
//! ```
//!
//! (the defaults; a law defined for inverted elements, where `C` loses the sign of `det F`,
//! overrides the `F` forms: [`StableNeoHookean`]). Identities used by the laws' tangents:
//! `d(C⁻¹) = −C⁻¹ dC C⁻¹`, `d det C = det C tr(C⁻¹ dC)`, `d ln J = tr(C⁻¹ dC)/2`.
//!
//! The valid range of each law's constants is checked in one place, [`ranges`]: the scenario
//! resolver checks `[material]`'s keys by it, `SimulationBuilder` the law it is given
//! ([`Material::validate`]).
//!
//! Each law lives in its own file; the test macro `material_tests!` checks, for every law and
//! form, that S equals twice the central finite-difference derivative of W, that dS equals
//! the central difference of S along dC, that P and dP equal the differences of W and P in F
//! (through inverted F for the laws that allow it), that the reference state is stress free,
//! and that W is invariant under rotation (W depends on C only, so this checks the wiring of
//! F → C).

use crate::mesh::ElementKind;
use nalgebra::{Matrix2, Matrix3, Matrix3x2, Vector3};

mod hgo;
mod mooney_rivlin;
mod neo_hookean;
mod neo_hookean_visco;
pub mod ranges;
mod stable_neo_hookean;
mod stvk;
mod ti_neo_hookean;
#[cfg(test)]
pub(crate) mod uniaxial_tests;
mod veronda_westmann;

pub use hgo::HolzapfelGasserOgden;
pub use mooney_rivlin::MooneyRivlin;
pub use neo_hookean::NeoHookean;
pub use neo_hookean_visco::{step_factors, NeoHookeanVisco, Prony, ViscoStep};
pub use stable_neo_hookean::StableNeoHookean;
pub use stvk::StVenantKirchhoff;
pub use ti_neo_hookean::TiNeoHookean;
pub use veronda_westmann::VerondaWestmann;

/// A 3-D hyperelastic law W(C).
pub trait SolidMaterial: Send + Sync {
    /// Strain energy per unit reference volume (Pa).
    fn energy(&self, c: &Matrix3<f64>) -> f64;
    /// Second Piola-Kirchhoff stress S = 2 ∂W/∂C (Pa).
    fn pk2(&self, c: &Matrix3<f64>) -> Matrix3<f64>;
    /// Differential of S along a symmetric `dc`: `dS = ∂S/∂C : dC` (Pa).
    fn dpk2(&self, c: &Matrix3<f64>, dc: &Matrix3<f64>) -> Matrix3<f64>;
    /// Whether W, P and dP are defined for inverted elements (`det F ≤ 0`); elements of
    /// other laws refuse such a state (an [`crate::fem::ElementFailure`]).
    fn handles_inversion(&self) -> bool {
        false
    }
    /// W as a function of F (the default: `W(FᵀF)`).
    fn energy_f(&self, f: &Matrix3<f64>) -> f64 {
        self.energy(&(f.transpose() * f))
    }
    /// First Piola-Kirchhoff stress `P = ∂W/∂F` (the default: `F S(FᵀF)`).
    fn pk1(&self, f: &Matrix3<f64>) -> Matrix3<f64> {
        f * self.pk2(&(f.transpose() * f))
    }
    /// Differential of P along `df` (the default: `dF S + F dS(C; dFᵀF + FᵀdF)`).
    fn dpk1(&self, f: &Matrix3<f64>, df: &Matrix3<f64>) -> Matrix3<f64> {
        let c = f.transpose() * f;
        let dc = df.transpose() * f + f.transpose() * df;
        df * self.pk2(&c) + f * self.dpk2(&c, &dc)
    }
    /// dP along each of `dfs`, into `out` (as long as `dfs`): what an element's tangent
    /// needs, one direction per nodal dof, at one F. The default is the C form of
    /// [`SolidMaterial::dpk1`] with C and S formed once; a law that overrides `dpk1` overrides
    /// this too (the test macro checks every law's against its `dpk1`), and a law may form
    /// more of its dS once (neo-Hookean: C⁻¹, ln J).
    fn dpk1_many(&self, f: &Matrix3<f64>, dfs: &[Matrix3<f64>], out: &mut [Matrix3<f64>]) {
        let c = f.transpose() * f;
        let s = self.pk2(&c);
        for (df, o) in dfs.iter().zip(out) {
            let dc = df.transpose() * f + f.transpose() * df;
            *o = df * s + f * self.dpk2(&c, &dc);
        }
    }
    /// The tangent `∂P/∂F` contracted with each pair of the four vectors `g`,
    /// `out[4 a + b]_ik = Σ_JL g_aJ (∂P_iJ/∂F_kL) g_bL`: a tetrahedron's stiffness block of
    /// nodes a and b per unit volume, `g` its shape-function gradients. `false` where the law
    /// has no closed form for it; the element then forms the blocks from
    /// [`SolidMaterial::dpk1_many`] (`out` untouched). A law that overrides it is checked
    /// against `dpk1` by the test macro.
    fn contract_dpk1(
        &self,
        _f: &Matrix3<f64>,
        _g: &[Vector3<f64>; 4],
        _out: &mut [Matrix3<f64>; 16],
    ) -> bool {
        false
    }
}

/// A plane-stress membrane law W(C), C the 2x2 in-plane Cauchy-Green tensor.
pub trait MembraneMaterial: Send + Sync {
    /// Strain energy per unit reference volume (Pa); the element multiplies by h·A0.
    fn energy(&self, c: &Matrix2<f64>) -> f64;
    /// In-plane second Piola-Kirchhoff stress S = 2 ∂W/∂C (Pa).
    fn pk2(&self, c: &Matrix2<f64>) -> Matrix2<f64>;
    /// Differential of S along a symmetric `dc`: `dS = ∂S/∂C : dC` (Pa).
    fn dpk2(&self, c: &Matrix2<f64>, dc: &Matrix2<f64>) -> Matrix2<f64>;
    /// Thickness stretch λ3 for the Cauchy stress `σ = F S Fᵀ / (λ3 √det C)`:
    /// `1/√det C` for incompressible laws, 1 for laws that do not model thinning.
    fn thickness_stretch(&self, c: &Matrix2<f64>) -> f64;
    /// Whether W, P and dP are defined for a triangle flipped against its reference normal.
    fn handles_inversion(&self) -> bool {
        false
    }
    /// W as a function of the 3x2 F and the reference unit normal `n0` (the default:
    /// `W(FᵀF)`, `n0` unused).
    fn energy_f(&self, f: &Matrix3x2<f64>, _n0: &Vector3<f64>) -> f64 {
        self.energy(&(f.transpose() * f))
    }
    /// `P = ∂W/∂F` (3x2; the default `F S(FᵀF)`).
    fn pk1(&self, f: &Matrix3x2<f64>, _n0: &Vector3<f64>) -> Matrix3x2<f64> {
        f * self.pk2(&(f.transpose() * f))
    }
    /// Differential of P along `df` (the default: `dF S + F dS(C; dFᵀF + FᵀdF)`).
    fn dpk1(&self, f: &Matrix3x2<f64>, _n0: &Vector3<f64>, df: &Matrix3x2<f64>) -> Matrix3x2<f64> {
        let c = f.transpose() * f;
        let dc = df.transpose() * f + f.transpose() * df;
        df * self.pk2(&c) + f * self.dpk2(&c, &dc)
    }
    /// dP along each of `dfs`, into `out` (as long as `dfs`), at one F: a triangle's nine
    /// directions. The default is the C form of [`MembraneMaterial::dpk1`] with C and S
    /// formed once; a law that overrides `dpk1` overrides this too (the test macro checks
    /// every law's against its `dpk1`).
    fn dpk1_many(
        &self,
        f: &Matrix3x2<f64>,
        _n0: &Vector3<f64>,
        dfs: &[Matrix3x2<f64>],
        out: &mut [Matrix3x2<f64>],
    ) {
        let c = f.transpose() * f;
        let s = self.pk2(&c);
        for (df, o) in dfs.iter().zip(out) {
            let dc = df.transpose() * f + f.transpose() * df;
            *o = df * s + f * self.dpk2(&c, &dc);
        }
    }
}

/// The isochoric invariants `b1 = J^(−2/3) I1`, `b2 = J^(−4/3) I2` of a 3x3 C, their
/// gradients `g1 = ∂b1/∂C`, `g2 = ∂b2/∂C`, and (given `dc`) their differentials;
/// with `J = √det C`, `t = tr(C⁻¹ dC)`, `dI1 = tr dC`, `dI2 = I1 dI1 − tr(C dC)`:
///
/// ```text
/// g1 = J^(−2/3) (I − I1/3 C⁻¹),             dg1 = −t/3 g1 + J^(−2/3) (−dI1/3 C⁻¹ + I1/3 C⁻¹dCC⁻¹)
/// g2 = J^(−4/3) (I1 I − C − 2/3 I2 C⁻¹),    dg2 = −2t/3 g2 + J^(−4/3) (dI1 I − dC − 2/3 dI2 C⁻¹ + 2/3 I2 C⁻¹dCC⁻¹)
/// ```
pub(crate) struct Iso3 {
    pub b1: f64,
    pub g1: Matrix3<f64>,
    pub db1: f64,
    pub dg1: Matrix3<f64>,
    pub dg2: Matrix3<f64>,
    pub j: f64,
    pub cinv: Matrix3<f64>,
    /// `tr(C⁻¹ dC)`.
    pub t: f64,
    /// `C⁻¹ dC C⁻¹`.
    pub cdc: Matrix3<f64>,
}

impl Iso3 {
    pub fn new(c: &Matrix3<f64>, dc: &Matrix3<f64>) -> Self {
        let id = Matrix3::identity();
        let i1 = c.trace();
        let i2 = 0.5 * (i1 * i1 - (c * c).trace());
        let j = c.determinant().sqrt();
        let cinv = c.try_inverse().unwrap_or_else(Matrix3::zeros);
        let (j23, j43) = (j.powf(-2.0 / 3.0), j.powf(-4.0 / 3.0));
        let g1 = (id - cinv * (i1 / 3.0)) * j23;
        let g2 = (id * i1 - c - cinv * (2.0 / 3.0 * i2)) * j43;
        let t = (cinv * dc).trace();
        let di1 = dc.trace();
        let di2 = i1 * di1 - (c * dc).trace();
        let cdc = cinv * dc * cinv;
        let dg1 = g1 * (-t / 3.0) + (cinv * (-di1 / 3.0) + cdc * (i1 / 3.0)) * j23;
        let dg2 = g2 * (-2.0 * t / 3.0)
            + (id * di1 - dc - cinv * (2.0 / 3.0 * di2) + cdc * (2.0 / 3.0 * i2)) * j43;
        Iso3 {
            b1: i1 * j23,
            db1: g1.component_mul(dc).sum(),
            g1,
            dg1,
            dg2,
            j,
            cinv,
            t,
            cdc,
        }
    }

    /// The bulk term `κ/2 (J − 1)²`: its stress `κ (J − 1) J C⁻¹` and differential
    /// `κ (2J − 1) J t/2 C⁻¹ − κ (J − 1) J C⁻¹dCC⁻¹`.
    pub fn bulk(&self, kappa: f64) -> (Matrix3<f64>, Matrix3<f64>) {
        let j = self.j;
        (
            self.cinv * (kappa * (j - 1.0) * j),
            self.cinv * (kappa * (2.0 * j - 1.0) * j * 0.5 * self.t)
                - self.cdc * (kappa * (j - 1.0) * j),
        )
    }
}

/// The isochoric fibre invariant `b4 = Ī4 = J^(−2/3) I4`, `I4 = a0·C a0` (the squared
/// stretch of the unit reference direction `a0`, before removing the volume change), its
/// gradient `g4 = ∂Ī4/∂C` and, along `dc`, its differentials; with `A = a0 ⊗ a0`,
/// `dI4 = a0·dC a0` and `t`, `C⁻¹dCC⁻¹` of [`Iso3`]:
///
/// ```text
/// g4 = J^(−2/3) (A − I4/3 C⁻¹),    dg4 = −t/3 g4 + J^(−2/3) (−dI4/3 C⁻¹ + I4/3 C⁻¹dCC⁻¹)
/// ```
pub(crate) struct Fib4 {
    pub b4: f64,
    pub g4: Matrix3<f64>,
    pub db4: f64,
    pub dg4: Matrix3<f64>,
}

impl Fib4 {
    /// The fibre invariant of `a0` at `c` (and along `dc`), from the `iso` of the same
    /// `c`, `dc`.
    pub fn new(iso: &Iso3, c: &Matrix3<f64>, dc: &Matrix3<f64>, a0: &Vector3<f64>) -> Self {
        let a = a0 * a0.transpose();
        let i4 = a0.dot(&(c * a0));
        let j23 = iso.j.powf(-2.0 / 3.0);
        let g4 = (a - iso.cinv * (i4 / 3.0)) * j23;
        let di4 = a0.dot(&(dc * a0));
        let dg4 = g4 * (-iso.t / 3.0) + (iso.cinv * (-di4 / 3.0) + iso.cdc * (i4 / 3.0)) * j23;
        Fib4 {
            b4: i4 * j23,
            db4: g4.component_mul(dc).sum(),
            g4,
            dg4,
        }
    }
}

/// `v / |v|`, or an error naming `key` where `v` is zero or not finite.
pub fn unit_direction(v: Vector3<f64>, key: &str) -> crate::Result<Vector3<f64>> {
    let n = v.norm();
    if n > 0.0 && n.is_finite() {
        Ok(v / n)
    } else {
        Err(crate::Error::param(
            key,
            format!(
                "[{}, {}, {}] is not a direction: give a non-zero finite vector",
                v.x, v.y, v.z
            ),
        ))
    }
}

/// The plane-stress incompressible invariants of a 2x2 C (`λ3² = 1/det C`),
/// `I1 = T + 1/D`, `I2 = D + T/D` (`T = tr C`, `D = det C`), their gradients and, along `dc`,
/// their differentials; with `t = tr(C⁻¹ dC)` (so `dD = D t`) and `dT = tr dC`:
///
/// ```text
/// g1 = I − C⁻¹/D,                 dg1 = (C⁻¹dCC⁻¹ + t C⁻¹)/D
/// g2 = D C⁻¹ + (I − T C⁻¹)/D,     dg2 = D t C⁻¹ − D C⁻¹dCC⁻¹ + (−dT C⁻¹ + T C⁻¹dCC⁻¹)/D − (I − T C⁻¹) t/D
/// ```
pub(crate) struct Inc2 {
    pub i1: f64,
    pub g1: Matrix2<f64>,
    pub di1: f64,
    pub dg1: Matrix2<f64>,
    pub dg2: Matrix2<f64>,
}

impl Inc2 {
    pub fn new(c: &Matrix2<f64>, dc: &Matrix2<f64>) -> Self {
        let id = Matrix2::identity();
        let d = c.determinant();
        let tr = c.trace();
        let cinv = c.try_inverse().unwrap_or_else(Matrix2::zeros);
        let g1 = id - cinv / d;
        let t = (cinv * dc).trace();
        let dt = dc.trace();
        let cdc = cinv * dc * cinv;
        let dg1 = (cdc + cinv * t) / d;
        let dg2 =
            cinv * (d * t) - cdc * d + (cinv * (-dt) + cdc * tr) / d - (id - cinv * tr) * (t / d);
        Inc2 {
            i1: tr + 1.0 / d,
            di1: g1.component_mul(dc).sum(),
            g1,
            dg1,
            dg2,
        }
    }
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
    /// `law = "stvk"`: St Venant-Kirchhoff, Lamé λ, μ.
    StVenantKirchhoff(StVenantKirchhoff),
    /// `law = "neo-hookean"`: Lamé λ, μ.
    NeoHookean(NeoHookean),
    /// `law = "mooney-rivlin"`: C1, C2, κ.
    MooneyRivlin(MooneyRivlin),
    /// `law = "veronda-westmann"`: c1, γ, κ.
    VerondaWestmann(VerondaWestmann),
    /// `law = "stable-neo-hookean"`: small-strain Lamé λ, μ.
    StableNeoHookean(StableNeoHookean),
    /// `law = "ti-neo-hookean"`: μ, κ, η and a fibre direction (solids only).
    TiNeoHookean(TiNeoHookean),
    /// `law = "hgo"`: μ, κ, k1, k2, dispersion and a fibre direction (solids only).
    HolzapfelGasserOgden(HolzapfelGasserOgden),
    /// `law = "neo-hookean-visco"`: μ, κ and a Prony series (solids only; per-element
    /// internal variables, [`crate::fem`]).
    NeoHookeanVisco(NeoHookeanVisco),
}

impl Material {
    /// Short name as written in scenario files.
    pub fn name(&self) -> &'static str {
        match self {
            Material::StVenantKirchhoff(_) => "stvk",
            Material::NeoHookean(_) => "neo-hookean",
            Material::MooneyRivlin(_) => "mooney-rivlin",
            Material::VerondaWestmann(_) => "veronda-westmann",
            Material::StableNeoHookean(_) => "stable-neo-hookean",
            Material::TiNeoHookean(_) => "ti-neo-hookean",
            Material::HolzapfelGasserOgden(_) => "hgo",
            Material::NeoHookeanVisco(_) => "neo-hookean-visco",
        }
    }

    /// The fibre direction of an anisotropic law (a unit vector), `None` for the isotropic
    /// ones.
    pub fn fibre(&self) -> Option<Vector3<f64>> {
        match self {
            Material::TiNeoHookean(m) => Some(m.fibre),
            Material::HolzapfelGasserOgden(m) => Some(m.fibre),
            _ => None,
        }
    }

    /// Whether the law can be used with elements of `kind`: the fibre laws are solids only,
    /// and need a unit fibre direction (their constructors normalise it). The error names
    /// the key and what would be valid.
    pub fn check_for(&self, kind: ElementKind) -> crate::Result<()> {
        if matches!(self, Material::NeoHookeanVisco(_)) && kind == ElementKind::Tri3 {
            return Err(crate::Error::param(
                "material.law",
                "\"neo-hookean-visco\" is a solid law (tetrahedra); membranes take \"stvk\", \"neo-hookean\", \"mooney-rivlin\", \"veronda-westmann\" or \"stable-neo-hookean\"",
            ));
        }
        if let Some(a) = self.fibre() {
            if kind == ElementKind::Tri3 {
                return Err(crate::Error::param(
                    "material.law",
                    format!(
                        "\"{}\" is a solid law (tetrahedra); membranes take \"stvk\", \"neo-hookean\", \"mooney-rivlin\", \"veronda-westmann\" or \"stable-neo-hookean\"",
                        self.name()
                    ),
                ));
            }
            if !((a.norm() - 1.0).abs() <= 1e-9) {
                return Err(crate::Error::param(
                    "material.fibre",
                    format!(
                        "[{}, {}, {}] must be a unit vector (the laws' constructors normalise it)",
                        a.x, a.y, a.z
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Small-strain shear modulus μ (Pa); the instantaneous one of neo-hookean-visco.
    pub fn shear_modulus(&self) -> f64 {
        match self {
            Material::StVenantKirchhoff(m) => m.mu,
            Material::NeoHookean(m) => m.mu,
            Material::MooneyRivlin(m) => 2.0 * (m.c1 + m.c2),
            Material::VerondaWestmann(m) => m.c1 * m.gamma,
            Material::StableNeoHookean(m) => m.lame_mu,
            Material::TiNeoHookean(m) => m.mu,
            Material::HolzapfelGasserOgden(m) => m.mu,
            Material::NeoHookeanVisco(m) => m.mu,
        }
    }

    /// Small-strain modulus bounding one element's stiffness, for stable time steps
    /// (`c² = modulus / ρ` in [`crate::integrate::stability`]): the energy
    /// density `λ (tr ε)² + 2μ ε:ε` is at most `(dλ + 2μ) |∇u|²` in d dimensions, the bound
    /// reached by an element's dilatation mode. Solids: `3λ + 2μ = 3K` (`3κ` for the laws with
    /// a bulk modulus). Membranes (plane stress, d = 2): `2λ* + 2μ`, `λ* = 2λμ/(λ + 2μ)`;
    /// `6μ` for the incompressible laws (λ* = 2μ). The fibre laws add their fibres'
    /// small-strain stiffness along `a0` to the deviatoric bound: `2η` (ti-neo-hookean, whose
    /// fibre energy is `η (ε_aa − tr ε/3)²` to second order) and `4 k1 (1 − 3κ_d)²` (hgo,
    /// `2 k1 (1 − 3κ_d)² (ε_aa − tr ε/3)²` in tension); hgo's exponential stiffening at
    /// large stretch is not in this bound. neo-hookean-visco: its instantaneous (unrelaxed)
    /// μ, the stiffest its elements get.
    pub fn stability_modulus(&self, kind: ElementKind) -> f64 {
        let mu = self.shear_modulus();
        match (self, kind) {
            (Material::StVenantKirchhoff(m), ElementKind::Tet4) => 3.0 * m.lambda + 2.0 * m.mu,
            (Material::NeoHookean(m), ElementKind::Tet4) => 3.0 * m.lambda + 2.0 * m.mu,
            (Material::MooneyRivlin(m), ElementKind::Tet4) => (3.0 * m.kappa).max(2.0 * mu),
            (Material::VerondaWestmann(m), ElementKind::Tet4) => (3.0 * m.kappa).max(2.0 * mu),
            (Material::TiNeoHookean(m), ElementKind::Tet4) => {
                (3.0 * m.kappa).max(2.0 * mu) + 2.0 * m.eta
            }
            (Material::HolzapfelGasserOgden(m), ElementKind::Tet4) => {
                let w = 1.0 - 3.0 * m.dispersion;
                (3.0 * m.kappa).max(2.0 * mu) + 4.0 * m.k1 * w * w
            }
            (Material::NeoHookeanVisco(m), ElementKind::Tet4) => (3.0 * m.kappa).max(2.0 * mu),
            (Material::StableNeoHookean(m), ElementKind::Tet4) => {
                3.0 * m.lame_lambda + 2.0 * m.lame_mu
            }
            (Material::StableNeoHookean(m), ElementKind::Tri3) => {
                let ls = 2.0 * m.lame_lambda * m.lame_mu / (m.lame_lambda + 2.0 * m.lame_mu);
                2.0 * ls + 2.0 * m.lame_mu
            }
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
            use nalgebra::{Matrix3, Vector3};
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
            fn tangent_is_stress_derivative() {
                let owned = $mat;
                let m: &dyn SolidMaterial = &owned;
                let dcs = [
                    Matrix3::new(0.3, -0.2, 0.1, -0.2, -0.5, 0.4, 0.1, 0.4, 0.2),
                    Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
                    Matrix3::new(0.0, 0.7, 0.0, 0.7, 0.0, 0.0, 0.0, 0.0, 0.0),
                ];
                for f in sample_f() {
                    let c = f.transpose() * f;
                    for dc in &dcs {
                        let ds = m.dpk2(&c, dc);
                        let h = 1e-6;
                        let fd = (m.pk2(&(c + dc * h)) - m.pk2(&(c - dc * h))) / (2.0 * h);
                        let scale = m.pk2(&c).norm().max(fd.norm()).max(1.0);
                        assert!(
                            (ds - fd).norm() <= 1e-6 * scale,
                            "dS = {ds} but the difference of S is {fd}"
                        );
                    }
                }
            }
            /// [`sample_f`], and an inverted F for a law that allows it.
            fn sample_f_of(m: &dyn SolidMaterial) -> Vec<Matrix3<f64>> {
                let mut fs = sample_f();
                if m.handles_inversion() {
                    fs.push(Matrix3::new(
                        -0.9, 0.1, 0.0, 0.05, 1.1, 0.2, 0.0, -0.1, 0.95,
                    ));
                }
                fs
            }
            #[test]
            fn first_piola_and_its_tangent_are_derivatives() {
                let owned = $mat;
                let m: &dyn SolidMaterial = &owned;
                let mut fs = sample_f_of(m);
                if m.handles_inversion() {
                    fs.push(Matrix3::new(0.2, 0.0, 0.0, 0.0, -0.3, 0.1, 0.0, 0.0, 0.1));
                }
                let df = Matrix3::new(0.3, -0.2, 0.1, 0.25, -0.5, 0.4, -0.1, 0.6, 0.2);
                for f in fs {
                    let p = m.pk1(&f);
                    let scale = p.norm().max(1.0);
                    let h = 1e-6;
                    for i in 0..3 {
                        for j in 0..3 {
                            let mut d = Matrix3::zeros();
                            d[(i, j)] = h;
                            let fd = (m.energy_f(&(f + d)) - m.energy_f(&(f - d))) / (2.0 * h);
                            assert!(
                                (fd - p[(i, j)]).abs() <= 1e-6 * scale,
                                "F = {f}: P[{i}{j}] = {} but dW/dF = {fd}",
                                p[(i, j)]
                            );
                        }
                    }
                    let dp = m.dpk1(&f, &df);
                    let fd = (m.pk1(&(f + df * h)) - m.pk1(&(f - df * h))) / (2.0 * h);
                    assert!(
                        (dp - fd).norm() <= 1e-6 * scale.max(fd.norm()),
                        "F = {f}: dP = {dp} but the difference of P is {fd}"
                    );
                }
            }
            #[test]
            fn tangent_of_many_directions_is_dpk1_of_each() {
                let owned = $mat;
                let m: &dyn SolidMaterial = &owned;
                // The twelve rank-one directions of a tetrahedron's dofs, and a full one.
                let g = [
                    [-1.0, -0.5, 0.2],
                    [1.0, 0.0, 0.0],
                    [0.0, 1.5, 0.3],
                    [0.0, -1.0, -0.5],
                ];
                let mut dfs = Vec::new();
                for gb in g {
                    for k in 0..3 {
                        let mut df = Matrix3::zeros();
                        for j in 0..3 {
                            df[(k, j)] = gb[j];
                        }
                        dfs.push(df);
                    }
                }
                dfs.push(Matrix3::new(
                    0.3, -0.2, 0.1, 0.25, -0.5, 0.4, -0.1, 0.6, 0.2,
                ));
                for f in sample_f_of(m) {
                    let mut out = vec![Matrix3::zeros(); dfs.len()];
                    m.dpk1_many(&f, &dfs, &mut out);
                    for (df, dp) in dfs.iter().zip(&out) {
                        let one = m.dpk1(&f, df);
                        assert!(
                            (dp - one).norm() <= 1e-12 * one.norm().max(m.pk1(&f).norm()),
                            "F = {f}, dF = {df}: dpk1_many gives {dp}, dpk1 {one}"
                        );
                    }
                }
            }
            /// Where the law contracts its tangent in closed form, each block equals the
            /// contraction of `dpk1` along the rank-one direction `e_k ⊗ g_b` with `g_a`.
            #[test]
            fn contracted_tangent_is_dpk1_contracted() {
                let owned = $mat;
                let m: &dyn SolidMaterial = &owned;
                let g = [
                    Vector3::new(-1.0, -0.5, 0.2),
                    Vector3::new(1.0, 0.0, 0.0),
                    Vector3::new(0.0, 1.5, 0.3),
                    Vector3::new(0.0, -1.0, -0.5),
                ];
                for f in sample_f_of(m) {
                    let mut out = [Matrix3::zeros(); 16];
                    if !m.contract_dpk1(&f, &g, &mut out) {
                        continue;
                    }
                    let scale = m
                        .pk1(&f)
                        .norm()
                        .max(m.dpk1(&f, &Matrix3::identity()).norm());
                    for a in 0..4 {
                        for b in 0..4 {
                            for k in 0..3 {
                                let mut df = Matrix3::zeros();
                                df.row_mut(k).copy_from(&g[b].transpose());
                                let col = m.dpk1(&f, &df) * g[a];
                                for i in 0..3 {
                                    let got = out[4 * a + b][(i, k)];
                                    assert!(
                                        (got - col[i]).abs() <= 1e-12 * scale,
                                        "F = {f}, block ({a}, {b})[{i}{k}]: {got} vs {}",
                                        col[i]
                                    );
                                }
                            }
                        }
                    }
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
            fn tangent_is_stress_derivative() {
                let owned = $mat;
                let m: &dyn MembraneMaterial = &owned;
                let dcs = [
                    Matrix2::new(0.3, -0.2, -0.2, -0.5),
                    Matrix2::new(1.0, 0.0, 0.0, 0.0),
                    Matrix2::new(0.0, 0.7, 0.7, 0.0),
                ];
                for f in sample_f() {
                    let c = f.transpose() * f;
                    for dc in &dcs {
                        let ds = m.dpk2(&c, dc);
                        let h = 1e-6;
                        let fd = (m.pk2(&(c + dc * h)) - m.pk2(&(c - dc * h))) / (2.0 * h);
                        let scale = m.pk2(&c).norm().max(fd.norm()).max(1.0);
                        assert!(
                            (ds - fd).norm() <= 1e-6 * scale,
                            "dS = {ds} but the difference of S is {fd}"
                        );
                    }
                }
            }
            /// [`sample_f`], and one flipped against n0 (x mirrored) for a law that allows it.
            fn sample_f_of(m: &dyn MembraneMaterial) -> Vec<Matrix3x2<f64>> {
                let mut fs = sample_f();
                if m.handles_inversion() {
                    fs.push(Matrix3x2::new(-0.9, 0.1, 0.05, 1.1, 0.1, -0.2));
                }
                fs
            }
            #[test]
            fn first_piola_and_its_tangent_are_derivatives() {
                let owned = $mat;
                let m: &dyn MembraneMaterial = &owned;
                let n0 = nalgebra::Vector3::new(0.0, 0.0, 1.0);
                let mut fs = sample_f_of(m);
                if m.handles_inversion() {
                    // Nearly collapsed.
                    fs.push(Matrix3x2::new(0.2, 0.0, 0.0, -0.05, 0.0, 0.1));
                }
                let df = Matrix3x2::new(0.3, -0.2, 0.25, -0.5, -0.1, 0.6);
                for f in fs {
                    let p = m.pk1(&f, &n0);
                    let scale = p.norm().max(1.0);
                    let h = 1e-6;
                    for i in 0..3 {
                        for j in 0..2 {
                            let mut d = Matrix3x2::zeros();
                            d[(i, j)] = h;
                            let fd =
                                (m.energy_f(&(f + d), &n0) - m.energy_f(&(f - d), &n0)) / (2.0 * h);
                            assert!(
                                (fd - p[(i, j)]).abs() <= 1e-6 * scale,
                                "F = {f}: P[{i}{j}] = {} but dW/dF = {fd}",
                                p[(i, j)]
                            );
                        }
                    }
                    let dp = m.dpk1(&f, &n0, &df);
                    let fd = (m.pk1(&(f + df * h), &n0) - m.pk1(&(f - df * h), &n0)) / (2.0 * h);
                    assert!(
                        (dp - fd).norm() <= 1e-6 * scale.max(fd.norm()),
                        "F = {f}: dP = {dp} but the difference of P is {fd}"
                    );
                }
            }
            #[test]
            fn tangent_of_many_directions_is_dpk1_of_each() {
                let owned = $mat;
                let m: &dyn MembraneMaterial = &owned;
                let n0 = nalgebra::Vector3::new(0.0, 0.0, 1.0);
                // The nine rank-one directions of a triangle's dofs, and a full one.
                let g = [[-1.0, -0.5], [1.0, 0.2], [0.0, 0.3]];
                let mut dfs = Vec::new();
                for gb in g {
                    for k in 0..3 {
                        let mut df = Matrix3x2::zeros();
                        df[(k, 0)] = gb[0];
                        df[(k, 1)] = gb[1];
                        dfs.push(df);
                    }
                }
                dfs.push(Matrix3x2::new(0.3, -0.2, 0.25, -0.5, -0.1, 0.6));
                for f in sample_f_of(m) {
                    let mut out = vec![Matrix3x2::zeros(); dfs.len()];
                    m.dpk1_many(&f, &n0, &dfs, &mut out);
                    for (df, dp) in dfs.iter().zip(&out) {
                        let one = m.dpk1(&f, &n0, df);
                        assert!(
                            (dp - one).norm() <= 1e-12 * one.norm().max(m.pk1(&f, &n0).norm()),
                            "F = {f}, dF = {df}: dpk1_many gives {dp}, dpk1 {one}"
                        );
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
        let mut mats: Vec<(Material, Box<dyn SolidMaterial>)> = vec![
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
        // The fibre laws, fibres normal to the plane of shear: the matrix's μ.
        let (ti, hgo) = (
            TiNeoHookean::new(1e3, 1e5, 5e3, Vector3::z()).unwrap(),
            HolzapfelGasserOgden::new(1e3, 1e5, 2e3, 3.0, 0.0, Vector3::z()).unwrap(),
        );
        mats.push((Material::TiNeoHookean(ti), Box::new(ti)));
        mats.push((Material::HolzapfelGasserOgden(hgo), Box::new(hgo)));
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
