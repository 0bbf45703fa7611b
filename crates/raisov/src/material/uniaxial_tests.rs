//! Closed forms of homogeneous uniaxial tension of the fibre laws, derived here from the
//! invariants and not from the laws' code, against the laws' stresses.
//!
//! For `W(Ī1, Ī4, J) = Ŵ(Ī1, Ī4) + κ/2 (J − 1)²` with fibres along `e1` and a principal
//! `F = diag(λ1, λ2, λ3)` (`J = λ1 λ2 λ3`, `I1 = Σ λi²`), the Cauchy stress is principal,
//!
//! ```text
//! σ_i = 2/J J^(−2/3) [W1 (λi² − I1/3) + W4 (δ_i1 − 1/3) λ1²] + κ (J − 1),
//! W1 = ∂Ŵ/∂Ī1, W4 = ∂Ŵ/∂Ī4   (σ = 2/J dev(W1 b̄ + W4 ā ⊗ ā) + κ (J − 1) I)
//! ```
//!
//! - ti-neo-hookean: `W1 = μ/2`, `W4 = η/2 (Ī4 − 1)`;
//! - hgo: `W1 = μ/2 + κ_d ψ'`, `W4 = (1 − 3κ_d) ψ'`, `ψ' = k1 Ē exp(k2 Ē²)` for `Ē > 0`, else 0.
//!
//! Uniaxial tension along the fibres: `λ1 = λ`, `λ2 = λ3 = t` with `σ2(t) = 0` (a 1-D root,
//! by bisection); across them (stretch along `e2`): `λ2 = λ`, `λ1`, `λ3` with `σ1 = σ3 = 0`
//! (nested bisection). The tests compare the law's `σ = F S Fᵀ / J` at those stretches with
//! the closed form, and the axial stresses along and across.

use super::*;

/// `(W1, W4)` of a fibre law at `(Ī1, Ī4)`, and its bulk modulus.
pub(crate) struct Closed {
    pub derivs: Box<dyn Fn(f64, f64) -> (f64, f64)>,
    pub kappa: f64,
}

impl Closed {
    /// The closed form of a fibre law (fibres along `e1` assumed by the callers).
    pub fn of(m: &Material) -> Closed {
        match m {
            Material::TiNeoHookean(m) => {
                let (mu, eta) = (m.mu, m.eta);
                Closed {
                    derivs: Box::new(move |_, b4| (0.5 * mu, 0.5 * eta * (b4 - 1.0))),
                    kappa: m.kappa,
                }
            }
            Material::HolzapfelGasserOgden(m) => {
                let (mu, k1, k2, kd) = (m.mu, m.k1, m.k2, m.dispersion);
                Closed {
                    derivs: Box::new(move |b1, b4| {
                        let e = kd * (b1 - 3.0) + (1.0 - 3.0 * kd) * (b4 - 1.0);
                        let dpsi = if e > 0.0 {
                            k1 * e * (k2 * e * e).exp()
                        } else {
                            0.0
                        };
                        (0.5 * mu + kd * dpsi, (1.0 - 3.0 * kd) * dpsi)
                    }),
                    kappa: m.kappa,
                }
            }
            _ => unreachable!("a fibre law"),
        }
    }

    /// The principal Cauchy stresses at `F = diag(l)`.
    pub fn cauchy(&self, l: [f64; 3]) -> [f64; 3] {
        let j = l[0] * l[1] * l[2];
        let j23 = j.powf(-2.0 / 3.0);
        let i1 = l.iter().map(|x| x * x).sum::<f64>();
        let (w1, w4) = (self.derivs)(j23 * i1, j23 * l[0] * l[0]);
        let mut s = [0.0; 3];
        for i in 0..3 {
            let fib = if i == 0 { 2.0 / 3.0 } else { -1.0 / 3.0 };
            s[i] = 2.0 / j * j23 * (w1 * (l[i] * l[i] - i1 / 3.0) + w4 * fib * l[0] * l[0])
                + self.kappa * (j - 1.0);
        }
        s
    }

    /// Uniaxial stress along the fibres at stretch `lam`: the stretches `[lam, t, t]` with
    /// `σ2 = 0`.
    pub fn along(&self, lam: f64) -> [f64; 3] {
        let t = bisect(|t| self.cauchy([lam, t, t])[1], 0.5, 2.0);
        [lam, t, t]
    }

    /// Uniaxial stress across the fibres, along `e2`, at stretch `lam`: `[l1, lam, l3]` with
    /// `σ1 = σ3 = 0`.
    pub fn across(&self, lam: f64) -> [f64; 3] {
        let l3_of = |l1: f64| bisect(|l3| self.cauchy([l1, lam, l3])[2], 0.5, 2.0);
        let l1 = bisect(|l1| self.cauchy([l1, lam, l3_of(l1)])[0], 0.5, 2.0);
        [l1, lam, l3_of(l1)]
    }
}

/// The root of an increasing `f`, bracketed from `[lo, hi]` (widened by halving `lo` and
/// doubling `hi`), to round-off.
fn bisect(f: impl Fn(f64) -> f64, mut lo: f64, mut hi: f64) -> f64 {
    for _ in 0..30 {
        if f(lo) < 0.0 {
            break;
        }
        lo *= 0.5;
    }
    for _ in 0..30 {
        if f(hi) > 0.0 {
            break;
        }
        hi *= 2.0;
    }
    assert!(f(lo) < 0.0 && f(hi) > 0.0, "not bracketed");
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if f(mid) < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The law's Cauchy stress `F S Fᵀ / J` at `F = diag(l)`.
fn law_cauchy(m: &dyn SolidMaterial, l: [f64; 3]) -> Matrix3<f64> {
    let f = Matrix3::from_diagonal(&Vector3::from(l));
    f * m.pk2(&(f.transpose() * f)) * f.transpose() / f.determinant()
}

fn ti() -> TiNeoHookean {
    TiNeoHookean::new(1e3, 5e4, 8e3, Vector3::x()).unwrap()
}

fn hgo(dispersion: f64) -> HolzapfelGasserOgden {
    HolzapfelGasserOgden::new(1e3, 5e4, 2e3, 4.0, dispersion, Vector3::x()).unwrap()
}

/// The laws' stresses equal the closed forms in uniaxial tension along and across the
/// fibres, the lateral stresses vanish there, and both laws are stiffer along the fibres.
#[test]
fn fibre_laws_match_the_uniaxial_closed_forms() {
    let laws = [
        Material::TiNeoHookean(ti()),
        Material::HolzapfelGasserOgden(hgo(0.0)),
        Material::HolzapfelGasserOgden(hgo(0.1)),
    ];
    for m in &laws {
        let closed = Closed::of(m);
        let law: &dyn SolidMaterial = match m {
            Material::TiNeoHookean(m) => m,
            Material::HolzapfelGasserOgden(m) => m,
            _ => unreachable!(),
        };
        for lam in [1.05, 1.2, 1.4] {
            let along = closed.along(lam);
            let across = closed.across(lam);
            let (sa, sc) = (closed.cauchy(along)[0], closed.cauchy(across)[1]);
            for (l, axis, s) in [(along, 0, sa), (across, 1, sc)] {
                let got = law_cauchy(law, l);
                let want = closed.cauchy(l);
                for i in 0..3 {
                    assert!(
                        (got[(i, i)] - want[i]).abs() <= 1e-10 * s,
                        "{}: λ = {lam}, stretches {l:?}: σ{i}{i} = {} but the closed form {}",
                        m.name(),
                        got[(i, i)],
                        want[i]
                    );
                    if i != axis {
                        assert!(got[(i, i)].abs() <= 1e-9 * s, "lateral {}", got[(i, i)]);
                    }
                }
                assert!((got - got.transpose()).norm() <= 1e-12 * s);
                assert!(got[(0, 1)].abs() + got[(0, 2)].abs() + got[(1, 2)].abs() <= 1e-12 * s);
            }
            assert!(
                sa > 1.2 * sc,
                "{}: λ = {lam}: along {sa} Pa, across {sc} Pa",
                m.name()
            );
        }
    }
}

/// hgo's fibres bear no compression: across the fibres (they shorten) its uniaxial stress is
/// that of its matrix alone (k1 = 0), while ti-neo-hookean's fibres resist shortening too.
#[test]
fn hgo_across_the_fibres_is_its_matrix_alone() {
    let matrix = Closed::of(&Material::HolzapfelGasserOgden(HolzapfelGasserOgden {
        k1: 0.0,
        ..hgo(0.0)
    }));
    let with = Closed::of(&Material::HolzapfelGasserOgden(hgo(0.0)));
    let ti_matrix = Closed::of(&Material::TiNeoHookean(TiNeoHookean { eta: 0.0, ..ti() }));
    let ti_with = Closed::of(&Material::TiNeoHookean(ti()));
    for lam in [1.1, 1.3] {
        let (a, b) = (with.across(lam), matrix.across(lam));
        assert!(a[0] < 1.0, "the fibres shorten: {a:?}");
        let (sa, sb) = (with.cauchy(a)[1], matrix.cauchy(b)[1]);
        assert!((sa - sb).abs() <= 1e-12 * sb, "{sa} vs {sb}");
        let (sa, sb) = (
            ti_with.cauchy(ti_with.across(lam))[1],
            ti_matrix.cauchy(ti_matrix.across(lam))[1],
        );
        assert!(sa > 1.01 * sb, "ti across {sa} vs matrix {sb}");
    }
}

/// Small strain along the fibres: Young's modulus `9κG/(3κ + G)` with the shear modulus `G`
/// stiffened by the fibres, `G = μ + 2η/3` (ti-neo-hookean) and `μ + 4 k1 (1 − 3κ_d)²/3`
/// (hgo, in tension), as the module docs state.
#[test]
fn small_strain_modulus_along_the_fibres() {
    let eps = 1e-7;
    let e_of = |g: f64, kappa: f64| 9.0 * kappa * g / (3.0 * kappa + g);
    let t = ti();
    let cases = [
        (
            Material::TiNeoHookean(t),
            e_of(t.mu + 2.0 * t.eta / 3.0, t.kappa),
        ),
        (
            Material::HolzapfelGasserOgden(hgo(0.1)),
            e_of(1e3 + 4.0 * 2e3 * 0.7 * 0.7 / 3.0, 5e4),
        ),
    ];
    for (m, want) in cases {
        let c = Closed::of(&m);
        let got = c.cauchy(c.along(1.0 + eps))[0] / eps;
        assert!(
            (got - want).abs() <= 1e-5 * want,
            "{}: {got} vs {want}",
            m.name()
        );
    }
}
