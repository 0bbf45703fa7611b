//! The one [`Scheme`]: the scheme each scenario's stepper is named by
//! ([`Scenario::scheme`]), the words of `[multigrid] scheme` as [`SchemeKind`]s, and the
//! checks the resolver shares with `SimulationBuilder` (a material constant's range, the
//! explicit step), whose messages read as they did before they were shared.

use super::*;
use crate::integrate::stability::critical_step_estimate;

/// Each way a scenario picks its stepper gives the `Scheme` the stepper is built from: the
/// explicit integrator without levels, backward Euler and BDF2 (levels or not), and each
/// word of `[multigrid] scheme`, with its resolved settings.
#[test]
fn every_scenario_names_its_stepper_by_the_one_scheme() {
    let scheme = |extra: &str| parse(&cube(&format!("{extra}\n[run]\nduration = 1.0"))).unwrap();
    assert_eq!(scheme("").scheme(), Scheme::SingleLevel(defaults::METHOD));
    assert_eq!(
        scheme("[integrator]\nmethod = \"rk4\"").scheme(),
        Scheme::SingleLevel(Method::Rk4)
    );
    for (method, want) in [
        ("implicit-euler", Scheme::ImplicitEuler),
        ("bdf2", Scheme::Bdf2),
    ] {
        let sc = scheme(&format!(
            "[integrator]\nmethod = \"{method}\"\ndt = 0.01\n[multigrid]\nlevels = 2"
        ));
        assert_eq!(sc.scheme(), want);
        assert_eq!(sc.scheme().kind().name(), method);
    }
    for kind in SchemeKind::MULTIGRID {
        let sc = scheme(&format!(
            "[multigrid]\nscheme = \"{}\"\nlevels = 2",
            kind.name()
        ));
        let mg = sc.multigrid.as_ref().unwrap();
        assert_eq!(sc.scheme(), mg.scheme);
        assert_eq!(sc.scheme().kind(), kind);
    }
    // The resolved settings travel in the scheme: FAS's keys, the paper's epsilon.
    let sc = scheme("[multigrid]\nscheme = \"fas\"\nlevels = 2\npre_smooth = 7");
    assert!(matches!(sc.scheme(), Scheme::Fas(p) if p.pre_smooth == 7));
    let sc = scheme("[multigrid]\nscheme = \"raisov-paper\"\nlevels = 2\nepsilon = 2e-5");
    assert!(matches!(sc.scheme(), Scheme::RaisovPaper(p) if p.epsilon == 2e-5));
    // Only the multigrid kinds are words of `[multigrid] scheme`.
    let e = error_of(&cube(
        "[multigrid]\nscheme = \"implicit-euler\"\nlevels = 2\n[run]\nduration = 1.0",
    ));
    assert!(
        e.contains("valid are \"fas\", \"raisov-paper\", \"newton\""),
        "{e}"
    );
}

/// The deprecated names still name the one enum, for a release.
#[test]
#[allow(deprecated)]
fn the_old_scheme_names_are_aliases_of_the_one_scheme() {
    let old: MultigridScheme = MultigridScheme::Fas(crate::multigrid::fas::FasParams::default());
    assert_eq!(old.kind(), SchemeKind::Fas);
    assert_eq!(spec::Scheme::RaisovPaper, SchemeKind::RaisovPaper);
    assert_eq!(
        <spec::Scheme as Named>::from_name("newton"),
        Some(SchemeKind::Newton)
    );
}

/// Poisson's ratio 0.5 is refused with the message the resolver gave before the rule moved
/// to `material::ranges`; the builder's refusal of the same pair comes from the same rule.
#[test]
fn poisson_ratio_at_one_half_is_refused_by_both_front_doors() {
    let text = cube("[run]\nduration = 1.0").replace("poisson = 0.45", "poisson = 0.5");
    assert_eq!(
        error_of(&text),
        "test.toml: `material.poisson` = 0.5: must be in (-1, 0.5)"
    );
    let built = crate::sim::SimulationBuilder::new(
        crate::mesh::generate::box_tets([0.04; 3], [2; 3], crate::mesh::generate::BoxPattern::Six)
            .unwrap(),
    )
    .young_poisson(5e3, 0.5)
    .build();
    let e = built.err().expect("ν = 0.5 refused").to_string();
    assert_eq!(
        e,
        "invalid parameter `young_poisson`: poisson = 0.5: must be in (-1, 0.5)"
    );
}

/// The other constants' messages, unchanged by the move: a negative `eta`, a dispersion
/// above 1/3 (tests/fibres.rs), a non-positive `young`, `kappa`, `c1` and `gamma`.
#[test]
fn material_range_messages_read_as_before() {
    let with = |material: &str| {
        let text = cube("[run]\nduration = 1.0").replace(
            "law = \"neo-hookean\"\nyoung = 5e3\npoisson = 0.45",
            material,
        );
        error_of(&text)
    };
    for (material, msg) in [
        (
            "law = \"neo-hookean\"\nyoung = -5e3\npoisson = 0.45",
            "`material.young` = -5000: must be a positive number",
        ),
        (
            "law = \"mooney-rivlin\"\nc1 = 1e3\nc2 = 0.0\nkappa = 0.0",
            "`material.kappa` = 0: must be a positive number",
        ),
        (
            "law = \"veronda-westmann\"\nc1 = 1e3\ngamma = -1.0\nkappa = 1e5",
            "`material.gamma` = -1: must be a positive number",
        ),
        (
            "law = \"neo-hookean\"\nyoung = 5e3\npoisson = -1.0",
            "`material.poisson` = -1: must be in (-1, 0.5)",
        ),
    ] {
        let e = with(material);
        assert_eq!(e, format!("test.toml: {msg}"), "{material}");
    }
    // Mooney-Rivlin's pair names the constant out of range and the rule of both.
    let e = with("law = \"mooney-rivlin\"\nc1 = 1e3\nc2 = -1.0\nkappa = 1e5");
    assert_eq!(
        e,
        "test.toml: `material.c2` = -1: need c1, c2 >= 0 with c1 + c2 > 0 (Pa)"
    );
    let e = with("law = \"mooney-rivlin\"\nc1 = 0.0\nc2 = 0.0\nkappa = 1e5");
    assert!(
        e.contains("`material.c2` = 0: need c1, c2 >= 0 with c1 + c2 > 0 (Pa), and c1 = 0"),
        "{e}"
    );
}

/// The step warning, now composed from `stability::step_too_large`, reads word for word as
/// before; the paper's cycle is bound by it too, FAS is not.
#[test]
fn a_step_far_above_the_critical_estimate_warns_as_before() {
    let sc = parse(&cube("[integrator]\ndt = 1e-2\n[run]\nduration = 1.0")).unwrap();
    let crit = critical_step_estimate(&sc.mesh, &sc.material, sc.density, sc.integrator.method);
    assert_eq!(sc.integrator.dt_critical_estimate, crit);
    assert_eq!(
        sc.warnings,
        vec![format!(
            "integrator.dt = {:.3e} s is {} times the estimated critical step {:.3e} s of \
             symplectic-euler: an explicit run this coarse usually diverges (leave `dt` out \
             to take 0.5 of the estimate)",
            1e-2,
            crate::numbers::rounded(1e-2 / crit, 1),
            crit
        )]
    );
    let warned = |scheme: &str| {
        !parse(&cube(&format!(
            "[integrator]\ndt = 1e-2\n[run]\nduration = 1.0\n[multigrid]\nlevels = 2\nscheme = \"{scheme}\""
        )))
        .unwrap()
        .warnings
        .is_empty()
    };
    assert!(warned("raisov-paper"));
    assert!(!warned("fas"));
}
