//! `raisov check SCENARIO`: what a scenario would run, in words. Every value is written in
//! the scenario's own terms and SI units (a material by its law and moduli, a motion by how
//! it moves, a stopping rule by when it stops), never as the library's internal structures.

use raisov::material::Material;
use raisov::numbers::{compact, point};
use raisov::scenario::interactive::{Budget, Interactive};
use raisov::scenario::StopRule;
use raisov::time::Motion;
use raisov::time::TimeFunction;

/// Rounded to 4 significant digits, written compactly (`5000`, `0.45`, `1.552e4`).
fn num(x: f64) -> String {
    compact(format!("{x:.3e}").parse().unwrap_or(x))
}

/// Young's modulus and Poisson's ratio of Lamé parameters `(λ, μ)`.
fn young_poisson(lambda: f64, mu: f64) -> (f64, f64) {
    (
        mu * (3.0 * lambda + 2.0 * mu) / (lambda + mu),
        lambda / (2.0 * (lambda + mu)),
    )
}

/// A material: its law as the scenario names it and its moduli (Pa).
pub fn material(m: &Material) -> String {
    let lame = |lambda: f64, mu: f64| {
        let (e, nu) = young_poisson(lambda, mu);
        format!(
            "{}: Young's modulus {} Pa, Poisson's ratio {} (Lame lambda {} Pa, shear modulus mu {} Pa)",
            m.name(),
            num(e),
            num(nu),
            num(lambda),
            num(mu)
        )
    };
    let bulk = |kappa: f64| {
        if kappa > 0.0 {
            format!("bulk modulus kappa {} Pa", num(kappa))
        } else {
            "no bulk term (incompressible membrane)".to_string()
        }
    };
    match m {
        Material::StVenantKirchhoff(p) => lame(p.lambda, p.mu),
        Material::NeoHookean(p) => lame(p.lambda, p.mu),
        Material::StableNeoHookean(p) => lame(p.lame_lambda, p.lame_mu),
        Material::MooneyRivlin(p) => format!(
            "{}: c1 {} Pa, c2 {} Pa, {}",
            m.name(),
            num(p.c1),
            num(p.c2),
            bulk(p.kappa)
        ),
        Material::VerondaWestmann(p) => format!(
            "{}: c1 {} Pa, gamma {}, {}",
            m.name(),
            num(p.c1),
            num(p.gamma),
            bulk(p.kappa)
        ),
        Material::TiNeoHookean(p) => format!(
            "{}: mu {} Pa, fibre eta {} Pa along {}, {}",
            m.name(),
            num(p.mu),
            num(p.eta),
            point(p.fibre.into()),
            bulk(p.kappa)
        ),
        Material::NeoHookeanVisco(p) => format!(
            "{}: mu {} Pa (long-term {} Pa), Prony [alpha, tau s] {}, {}",
            m.name(),
            num(p.mu),
            num(p.long_term_mu()),
            p.prony
                .iter()
                .map(|t| format!("[{}, {}]", num(t.alpha), num(t.tau)))
                .collect::<Vec<_>>()
                .join(" "),
            bulk(p.kappa)
        ),
        Material::HolzapfelGasserOgden(p) => format!(
            "{}: mu {} Pa, fibre k1 {} Pa, k2 {}, dispersion {} along {}, {}",
            m.name(),
            num(p.mu),
            num(p.k1),
            num(p.k2),
            num(p.dispersion),
            point(p.fibre.into()),
            bulk(p.kappa)
        ),
    }
}

/// [`material`] with the scenario's fibre field, where it has one, in place of the law's
/// single direction ("along the helix rule ...").
pub fn material_with(
    m: &Material,
    fibres: Option<&raisov::scenario::fibres::FibreField>,
) -> String {
    let text = material(m);
    match (fibres, m.fibre()) {
        (Some(f), Some(a)) => text.replacen(
            &format!("along {}", point(a.into())),
            &format!("along {f}"),
            1,
        ),
        _ => text,
    }
}

/// A vector `(x, y, z)` with its unit, or "none" when zero.
pub fn vector_or_none(v: [f64; 3], unit: &str) -> String {
    if v == [0.0; 3] {
        "none".to_string()
    } else {
        format!("{} {unit}", point(v))
    }
}

/// Seconds as "1 s", "0.5 s".
fn secs(t: f64) -> String {
    format!("{} s", num(t))
}

/// A list of times (s): all of them up to 6, else the first three, "...", the last.
fn times(t: &[f64]) -> String {
    if t.len() <= 6 {
        t.iter().map(|&x| num(x)).collect::<Vec<_>>().join(", ")
    } else {
        format!(
            "{}, {}, {}, ..., {}",
            num(t[0]),
            num(t[1]),
            num(t[2]),
            num(t[t.len() - 1])
        )
    }
}

/// A time function `s(t)` in words, for "d times ...".
fn time_function(f: &TimeFunction) -> String {
    match f {
        TimeFunction::Constant => "held from the start".to_string(),
        TimeFunction::Ramp { duration } => format!("ramped up over {}", secs(*duration)),
        TimeFunction::Table { times: t, values } => format!(
            "times a factor piecewise linear in time through {} points (t = {} s; factors {})",
            t.len(),
            times(t),
            times(values)
        ),
        TimeFunction::Sine {
            amplitude,
            frequency,
            phase,
        } => {
            let amp = if *amplitude == 1.0 {
                String::new()
            } else {
                format!("{} ", num(*amplitude))
            };
            if *phase == 0.0 {
                format!("times {amp}sin(2 pi f t), f = {} Hz", num(*frequency))
            } else {
                format!(
                    "times {amp}sin(2 pi f t + phi), f = {} Hz, phi = {} rad",
                    num(*frequency),
                    num(*phase)
                )
            }
        }
    }
}

/// A prescribed displacement's time law.
pub fn motion(m: &Motion) -> String {
    match m {
        Motion::Held { d } => format!("displaced by {} m from the start", point(*d)),
        Motion::Ramp { d, duration } => format!(
            "displaced by {} m, ramped up over {}",
            point(*d),
            secs(*duration)
        ),
        Motion::Table { times: t, values } => {
            let last = values.last().copied().unwrap_or([0.0; 3]);
            format!(
                "displaced piecewise linearly in time through {} points (t = {} s), ending at {} m",
                t.len(),
                times(t),
                point(last)
            )
        }
        Motion::Function { d, f } => format!("displaced by {} m {}", point(*d), time_function(f)),
    }
}

/// When a run stops.
pub fn stop(s: &StopRule) -> String {
    match *s {
        StopRule::Duration(t) => format!("after {} of simulated time", secs(t)),
        StopRule::Steady {
            kinetic_tol,
            residual_tol,
            max,
            stagnation,
        } => {
            let give_up = if stagnation == 0 {
                "never gives up early".to_string()
            } else {
                format!("gives up after {stagnation} checks without progress")
            };
            format!(
                "at steady state (kinetic energy below {} and residual below {} of their peaks), \
                 at most {} of simulated time; {give_up}",
                num(kinetic_tol),
                num(residual_tol),
                secs(max)
            )
        }
    }
}

/// An interactive run's frame loop.
pub fn interactive(i: &Interactive) -> String {
    let budget = match i.budget {
        Budget::Cycles(1) => "1 step per frame".to_string(),
        Budget::Cycles(n) => format!("{n} steps per frame"),
        Budget::Wall(s) => format!("{} ms of wall time per frame", num(s * 1e3)),
    };
    let reference = if i.reference {
        format!(
            "each frame compared with its static solution (solved to {} of the frame's largest force); \
             keeps up while the lag stays under {} % of the static displacement",
            num(i.reference_tol),
            num(100.0 * i.lag_tol)
        )
    } else {
        "no static reference".to_string()
    };
    let predictor = if i.predictor {
        "; each frame whose path moves starts from the last frame's change, extrapolated"
    } else {
        ""
    };
    format!("{} frames/s, {budget}; {reference}{predictor}", num(i.fps))
}

#[cfg(test)]
mod tests {
    use super::*;
    use raisov::material::{lame, NeoHookean};

    #[test]
    fn young_and_poisson_come_back_from_lame() {
        let (l, m) = lame(5e3, 0.45);
        let text = material(&Material::NeoHookean(NeoHookean { lambda: l, mu: m }));
        assert!(
            text.starts_with("neo-hookean: Young's modulus 5000 Pa, Poisson's ratio 0.45"),
            "{text}"
        );
    }
}
