//! The valid range of every law's constants, checked in one place for both front doors: the
//! scenario resolver checks `[material]`'s keys with these functions, and
//! `SimulationBuilder` checks `young_poisson`'s pair with [`young_poisson`] and any law it
//! is given with [`Material::validate`], which applies the same rules to the law's own
//! constants.
//!
//! Young's modulus `E` and Poisson's ratio `ν` are valid for `E > 0` and `−1 < ν < 1/2`;
//! for a law holding Lamé's `λ, μ` instead, that is `μ > 0` and a bulk modulus
//! `λ + 2μ/3 > 0` (with `μ > 0`, `ν = (3K − 2μ) / (2 (3K + μ))` lies in (−1, 1/2) exactly
//! where `K > 0`).

use super::{Material, NeoHookeanVisco};
use crate::mesh::ElementKind;
use crate::numbers::compact;

/// A constant of a law outside its range.
#[derive(Clone, Debug, PartialEq)]
pub struct OutOfRange {
    /// The constant, as `[material]` names it (`"poisson"`).
    pub key: &'static str,
    /// Its value.
    pub value: f64,
    /// What would be valid (`"must be in (-1, 0.5)"`).
    pub rule: String,
}

impl std::fmt::Display for OutOfRange {
    /// `poisson = 0.5: must be in (-1, 0.5)`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} = {}: {}", self.key, compact(self.value), self.rule)
    }
}

impl OutOfRange {
    fn new(key: &'static str, value: f64, rule: impl Into<String>) -> Self {
        OutOfRange {
            key,
            value,
            rule: rule.into(),
        }
    }
}

/// `v`, where it is a positive finite number.
pub fn positive(key: &'static str, v: f64) -> Result<f64, OutOfRange> {
    match v > 0.0 && v.is_finite() {
        true => Ok(v),
        false => Err(OutOfRange::new(key, v, "must be a positive number")),
    }
}

/// `v`, where it is a finite number >= 0.
pub fn non_negative(key: &'static str, v: f64) -> Result<f64, OutOfRange> {
    match v >= 0.0 && v.is_finite() {
        true => Ok(v),
        false => Err(OutOfRange::new(key, v, "must be a number >= 0")),
    }
}

/// Young's modulus (Pa, positive) and Poisson's ratio (in (−1, 0.5)), checked in that order.
pub fn young_poisson(young: f64, poisson: f64) -> Result<(f64, f64), OutOfRange> {
    let e = positive("young", young)?;
    if !(-1.0 < poisson && poisson < 0.5) {
        return Err(OutOfRange::new("poisson", poisson, "must be in (-1, 0.5)"));
    }
    Ok((e, poisson))
}

/// Mooney-Rivlin's `c1`, `c2` (Pa): both finite and >= 0, their sum > 0.
pub fn mooney_rivlin(c1: f64, c2: f64) -> Result<(), OutOfRange> {
    for (key, v) in [("c1", c1), ("c2", c2)] {
        if !(v >= 0.0 && v.is_finite()) {
            return Err(OutOfRange::new(
                key,
                v,
                "need c1, c2 >= 0 with c1 + c2 > 0 (Pa)",
            ));
        }
    }
    if !(c1 + c2 > 0.0) {
        return Err(OutOfRange::new(
            "c2",
            c2,
            format!(
                "need c1, c2 >= 0 with c1 + c2 > 0 (Pa), and c1 = {}",
                compact(c1)
            ),
        ));
    }
    Ok(())
}

/// HGO's fibre dispersion κ_d, in [0, 1/3].
pub fn dispersion(d: f64) -> Result<f64, OutOfRange> {
    match (0.0..=1.0 / 3.0).contains(&d) {
        true => Ok(d),
        false => Err(OutOfRange::new(
            "dispersion",
            d,
            "must be in [0, 1/3] (0: aligned fibres, 1/3: isotropic)",
        )),
    }
}

/// Lamé's `μ > 0` and a bulk modulus `λ + 2μ/3 > 0`, both finite (module docs: a Poisson's
/// ratio in (−1, 0.5)).
fn lame(lambda: f64, mu: f64) -> Result<(), OutOfRange> {
    positive("mu", mu)?;
    if !(lambda + 2.0 / 3.0 * mu > 0.0 && lambda.is_finite()) {
        return Err(OutOfRange::new(
            "lambda",
            lambda,
            format!(
                "need a finite bulk modulus lambda + 2 mu / 3 > 0, i.e. a Poisson's ratio in \
                 (-1, 0.5) (mu = {})",
                compact(mu)
            ),
        ));
    }
    Ok(())
}

impl Material {
    /// Every constant of the law in its range, by the rules a scenario's `[material]` is
    /// checked by (module docs; the fibre direction and the element kind are
    /// [`Material::check_for`]'s): an error naming the constant as `[material]` does
    /// (`material.kappa`), its value and what would be valid. `kind`: a membrane's
    /// Mooney-Rivlin and Veronda-Westmann laws take no `kappa`.
    pub fn validate(&self, kind: ElementKind) -> crate::Result<()> {
        let solid = kind == ElementKind::Tet4;
        let checked = match self {
            Material::StVenantKirchhoff(m) => lame(m.lambda, m.mu),
            Material::NeoHookean(m) => lame(m.lambda, m.mu),
            Material::StableNeoHookean(m) => lame(m.lame_lambda, m.lame_mu),
            Material::MooneyRivlin(m) => mooney_rivlin(m.c1, m.c2).and_then(|_| match solid {
                true => positive("kappa", m.kappa).map(|_| ()),
                false => Ok(()),
            }),
            Material::VerondaWestmann(m) => positive("c1", m.c1)
                .and_then(|_| positive("gamma", m.gamma))
                .and_then(|_| match solid {
                    true => positive("kappa", m.kappa).map(|_| ()),
                    false => Ok(()),
                }),
            Material::TiNeoHookean(m) => positive("mu", m.mu)
                .and_then(|_| positive("kappa", m.kappa))
                .and_then(|_| non_negative("eta", m.eta))
                .map(|_| ()),
            Material::HolzapfelGasserOgden(m) => positive("mu", m.mu)
                .and_then(|_| positive("kappa", m.kappa))
                .and_then(|_| non_negative("k1", m.k1))
                .and_then(|_| non_negative("k2", m.k2))
                .and_then(|_| dispersion(m.dispersion))
                .map(|_| ()),
            Material::NeoHookeanVisco(m) => {
                return NeoHookeanVisco::new(m.mu, m.kappa, m.prony.clone()).map(|_| ())
            }
        };
        checked.map_err(|e| {
            crate::Error::param(
                &format!("material.{}", e.key),
                format!("{} {} (law \"{}\")", compact(e.value), e.rule, self.name()),
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::{
        lame, HolzapfelGasserOgden, MooneyRivlin, NeoHookean, Prony, StVenantKirchhoff,
        StableNeoHookean, TiNeoHookean, VerondaWestmann,
    };
    use nalgebra::Vector3;

    /// The Lamé form of the rule admits every (E, ν) the scenario's rule admits, to the ends
    /// of the range, and refuses ν = 0.5 (λ infinite) and past it.
    #[test]
    fn lame_form_holds_the_same_poisson_range() {
        for nu in [-0.999, -0.5, 0.0, 0.3, 0.45, 0.499, 0.49999] {
            assert!(young_poisson(5e3, nu).is_ok());
            let (lambda, mu) = lame(5e3, nu);
            for m in [
                Material::NeoHookean(NeoHookean { lambda, mu }),
                Material::StVenantKirchhoff(StVenantKirchhoff::from_young(5e3, nu)),
                Material::StableNeoHookean(StableNeoHookean::from_young(5e3, nu)),
            ] {
                for kind in [ElementKind::Tet4, ElementKind::Tri3] {
                    assert!(m.validate(kind).is_ok(), "{m:?} at ν = {nu}");
                }
            }
        }
        for nu in [0.5, 0.6, 2.0] {
            assert!(young_poisson(5e3, nu).is_err());
            let m = Material::StableNeoHookean(StableNeoHookean::from_young(5e3, nu));
            let e = m.validate(ElementKind::Tet4).unwrap_err().to_string();
            assert!(e.contains("`material.lambda`"), "ν = {nu}: {e}");
        }
    }

    /// Each law built from valid constants passes; each constant out of range is named.
    #[test]
    fn every_law_names_its_constant_out_of_range() {
        let x = Vector3::x();
        let ok = [
            Material::MooneyRivlin(MooneyRivlin::new(1e3, 0.0, 1e5)),
            Material::VerondaWestmann(VerondaWestmann::new(1e3, 2.0, 1e5)),
            Material::TiNeoHookean(TiNeoHookean::new(1e3, 1e5, 0.0, x).unwrap()),
            Material::HolzapfelGasserOgden(
                HolzapfelGasserOgden::new(1e3, 1e5, 0.0, 0.0, 1.0 / 3.0, x).unwrap(),
            ),
            Material::NeoHookeanVisco(
                NeoHookeanVisco::new(
                    1e3,
                    1e5,
                    vec![Prony {
                        alpha: 0.5,
                        tau: 1.0,
                    }],
                )
                .unwrap(),
            ),
        ];
        for m in ok {
            assert!(m.validate(ElementKind::Tet4).is_ok(), "{m:?}");
        }
        // A membrane's Mooney-Rivlin and Veronda-Westmann take no kappa.
        assert!(Material::MooneyRivlin(MooneyRivlin::new(1e3, 1e3, 0.0))
            .validate(ElementKind::Tri3)
            .is_ok());
        let bad = [
            (
                Material::MooneyRivlin(MooneyRivlin::new(-1.0, 1e3, 1e5)),
                "c1",
            ),
            (
                Material::MooneyRivlin(MooneyRivlin::new(0.0, 0.0, 1e5)),
                "c2",
            ),
            (
                Material::MooneyRivlin(MooneyRivlin::new(1e3, 1e3, 0.0)),
                "kappa",
            ),
            (
                Material::VerondaWestmann(VerondaWestmann::new(1e3, 0.0, 1e5)),
                "gamma",
            ),
            (
                Material::TiNeoHookean(TiNeoHookean::new(1e3, 1e5, -1.0, x).unwrap()),
                "eta",
            ),
            (
                Material::HolzapfelGasserOgden(
                    HolzapfelGasserOgden::new(1e3, 1e5, f64::NAN, 0.0, 0.0, x).unwrap(),
                ),
                "k1",
            ),
            (
                Material::NeoHookeanVisco(NeoHookeanVisco {
                    mu: 1e3,
                    kappa: 1e5,
                    prony: vec![Prony {
                        alpha: 1.0,
                        tau: 1.0,
                    }],
                }),
                "prony",
            ),
        ];
        for (m, key) in bad {
            let e = m.validate(ElementKind::Tet4).unwrap_err().to_string();
            assert!(e.contains(&format!("`material.{key}`")), "{key}: {e}");
        }
    }
}
