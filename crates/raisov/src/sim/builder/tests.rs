//! The builder's checks, taken from the scenario resolver's rules (a material constant's
//! range, an explicit step above the critical estimate, visco under the multigrid schemes),
//! and the paper's cycle built from code as the scenario builds it.

use super::*;
use crate::integrate::stability::critical_step_estimate;
use crate::material::{HolzapfelGasserOgden, MooneyRivlin, NeoHookean};
use crate::mesh::generate::{box_tets, BoxPattern};
use crate::multigrid::raisov::{RaisovParams, Reading};
use crate::scenario::Scenario;
use crate::sim::Budget;

const G: [f64; 3] = [0.0, 0.0, -9.81];

fn cube(div: usize) -> Mesh {
    box_tets([0.04; 3], [div; 3], BoxPattern::Six).unwrap()
}

/// The error of a build that must fail.
fn refused(b: SimulationBuilder) -> String {
    b.build().err().expect("the build is refused").to_string()
}

/// `young_poisson(E, 0.5)` built a simulation with an infinite Lamé λ; now refused by the
/// rule the scenario's `[material] poisson` is checked by, as are ν = −1 and a non-positive
/// E. Inside the range it builds.
#[test]
fn builder_refuses_poisson_ratio_at_one_half() {
    let with = |e: f64, nu: f64| SimulationBuilder::new(cube(2)).young_poisson(e, nu);
    assert_eq!(
        refused(with(5e3, 0.5)),
        "invalid parameter `young_poisson`: poisson = 0.5: must be in (-1, 0.5)"
    );
    assert_eq!(
        refused(with(5e3, -1.0)),
        "invalid parameter `young_poisson`: poisson = -1: must be in (-1, 0.5)"
    );
    assert_eq!(
        refused(with(0.0, 0.3)),
        "invalid parameter `young_poisson`: young = 0: must be a positive number"
    );
    assert!(with(5e3, 0.499).build().is_ok());
    assert!(with(5e3, -0.99).build().is_ok());
    // A law set afterwards replaces the pair, and is checked by its own constants.
    let (lambda, mu) = crate::material::lame(5e3, 0.45);
    let law = Material::NeoHookean(NeoHookean { lambda, mu });
    assert!(with(5e3, 0.5).material(law).build().is_ok());
}

/// A law given with `material` had its constants unchecked; now each is held to the range a
/// scenario's `[material]` key is, the error naming the key.
#[test]
fn builder_refuses_a_law_with_constants_out_of_range() {
    let with = |m: Material| refused(SimulationBuilder::new(cube(2)).material(m));
    // λ + 2μ/3 < 0: a Poisson's ratio above 0.5.
    let e = with(Material::NeoHookean(NeoHookean {
        lambda: -1e4,
        mu: 1e3,
    }));
    assert!(
        e.starts_with("invalid parameter `material.lambda`: -10000 need a finite bulk modulus")
            && e.ends_with("(law \"neo-hookean\")"),
        "{e}"
    );
    let e = with(Material::NeoHookean(NeoHookean {
        lambda: 1e4,
        mu: 0.0,
    }));
    assert!(
        e.starts_with("invalid parameter `material.mu`: 0 must be a positive number"),
        "{e}"
    );
    let e = with(Material::MooneyRivlin(MooneyRivlin::new(1e3, -1.0, 1e5)));
    assert!(
        e.starts_with("invalid parameter `material.c2`: -1 need c1, c2 >= 0"),
        "{e}"
    );
    let e = with(Material::MooneyRivlin(MooneyRivlin::new(1e3, 1e3, 0.0)));
    assert!(e.starts_with("invalid parameter `material.kappa`"), "{e}");
    let hgo = |dispersion: f64| {
        Material::HolzapfelGasserOgden(
            HolzapfelGasserOgden::new(1e3, 1e5, 1e3, 1.0, dispersion, nalgebra::Vector3::x())
                .unwrap(),
        )
    };
    let e = with(hgo(0.5));
    assert!(
        e.starts_with("invalid parameter `material.dispersion`: 0.5 must be in [0, 1/3]"),
        "{e}"
    );
    assert!(SimulationBuilder::new(cube(2))
        .material(hgo(0.1))
        .build()
        .is_ok());
}

/// `Scheme::SingleLevel` with `.dt(..)` far above the estimated critical step built a
/// simulation that diverges; now refused by the rule the scenario warns by. Below twice the
/// estimate it builds; FAS (a smoother's step) and the frame solver are not bound by it, the
/// paper's cycle (explicit steps on every level) is.
#[test]
fn builder_refuses_an_explicit_step_above_twice_the_critical_estimate() {
    let mesh = cube(3);
    let material = Material::StableNeoHookean(StableNeoHookean::from_young(5e3, 0.45));
    let crit = critical_step_estimate(&mesh, &material, 1000.0, Method::SymplecticEuler);
    let with = |scheme: Scheme, dt: f64| {
        SimulationBuilder::new(mesh.clone())
            .levels(vec![cube(2)])
            .fix(|p| p[2] <= 0.0)
            .scheme(scheme)
            .dt(dt)
    };
    let single = Scheme::SingleLevel(Method::SymplecticEuler);
    assert_eq!(
        refused(with(single, 3.0 * crit)),
        format!(
            "invalid parameter `dt`: dt = {:.3e} s is 3.0 times the estimated critical step \
             {crit:.3e} s of symplectic-euler: an explicit run this coarse usually diverges \
             (leave `dt` out to take half the estimate)",
            3.0 * crit
        )
    );
    assert!(with(single, 1.9 * crit).build().is_ok());
    let paper = Scheme::RaisovPaper(RaisovParams {
        epsilon: 1e-6,
        reading: Reading::Correction,
        kinetic_limit: f64::INFINITY,
    });
    assert!(refused(with(paper, 3.0 * crit)).contains("times the estimated critical step"));
    assert!(with(Scheme::Fas(Default::default()), 3.0 * crit)
        .build()
        .is_ok());
    assert!(with(Scheme::Newton(Default::default()), 3.0 * crit)
        .build()
        .is_ok());
}

/// `Scheme::RaisovPaper` builds the paper's cycle over the levels as a scenario with
/// `scheme = "raisov-paper"` does: fed the scenario's level meshes and its resolved scheme,
/// the builder's simulation moves through the same bits frame after frame.
#[test]
fn builder_builds_the_papers_cycle_as_the_scenario_does() {
    let text = r#"
gravity = [0.0, 0.0, -9.81]
[mesh]
generate = "box"
size = [0.04, 0.04, 0.04]
divisions = [4, 4, 4]
[material]
law = "stable-neo-hookean"
young = 5e3
poisson = 0.45
[damping]
alpha = 5.0
[[fix]]
plane = { point = [0, 0, 0], normal = [0, 0, 1] }
[run]
duration = 1.0
[multigrid]
scheme = "raisov-paper"
levels = 2
"#;
    let sc = Scenario::from_toml(text, std::path::Path::new("paper.toml")).unwrap();
    assert!(matches!(sc.scheme(), Scheme::RaisovPaper(_)));
    let mut from_file = Simulation::from_scenario(&sc).unwrap();
    let meshes = sc.level_meshes().unwrap();
    let mut from_code = SimulationBuilder::new(meshes[0].clone())
        .levels(meshes[1..].to_vec())
        .young_poisson(5e3, 0.45)
        .damping(5.0)
        .gravity(G)
        .fix(|p| p[2] <= 0.0)
        .scheme(sc.scheme())
        .build()
        .unwrap();
    assert_eq!(
        from_code.stepper().describe(),
        from_file.stepper().describe()
    );
    assert!(from_code.stepper().describe().starts_with("raisov"));
    for _ in 0..4 {
        let a = from_file.step_frame(Budget::Cycles(5));
        let b = from_code.step_frame(Budget::Cycles(5));
        assert!(a.accepted && b.accepted, "{a:?} {b:?}");
        assert_eq!(from_file.positions(), from_code.positions());
    }
    // The top sinks under gravity.
    let top = from_code
        .positions()
        .iter()
        .map(|p| p[2])
        .fold(f64::NEG_INFINITY, f64::max);
    assert!(top < 0.04, "{top}");
}

/// neo-hookean-visco under the paper's cycle, as under FAS: the cycles do not advance the
/// law's internal variables (a scenario refuses `[multigrid]` with it for the same reason).
#[test]
fn builder_refuses_visco_under_the_papers_cycle() {
    let visco = crate::material::NeoHookeanVisco::new(
        1e3,
        2e4,
        vec![crate::material::Prony {
            alpha: 0.3,
            tau: 0.05,
        }],
    )
    .unwrap();
    let e = refused(
        SimulationBuilder::new(cube(3))
            .levels(vec![cube(2)])
            .material(Material::NeoHookeanVisco(visco))
            .scheme(Scheme::RaisovPaper(RaisovParams {
                epsilon: 1e-6,
                reading: Reading::Correction,
                kinetic_limit: f64::INFINITY,
            })),
    );
    assert!(e.contains("Scheme::RaisovPaper"), "{e}");
}

/// Without coarser levels the paper's cycle is its integrator's step on level 0: the same
/// bits as `Scheme::SingleLevel` at the same (default) step.
#[test]
fn the_papers_cycle_on_one_level_is_its_integrator_alone() {
    let build = |scheme: Scheme| {
        SimulationBuilder::new(cube(3))
            .gravity(G)
            .fix(|p| p[2] <= 0.0)
            .scheme(scheme)
            .build()
            .unwrap()
    };
    let mut paper = build(Scheme::RaisovPaper(RaisovParams {
        epsilon: 1e-6,
        reading: Reading::Correction,
        kinetic_limit: f64::INFINITY,
    }));
    let mut single = build(Scheme::SingleLevel(Method::SymplecticEuler));
    for _ in 0..3 {
        assert!(paper.step_frame(Budget::Cycles(5)).accepted);
        assert!(single.step_frame(Budget::Cycles(5)).accepted);
        assert_eq!(paper.positions(), single.positions());
    }
    // Gravity moved it.
    assert!(paper.displacements().iter().any(|&u| u != 0.0));
}

/// The builder ignored a thickness given for tetrahedra, where a scenario refuses
/// `[material] thickness` on a tetrahedral mesh; now refused, naming the key. A membrane
/// takes it.
#[test]
fn builder_refuses_a_thickness_on_tetrahedra() {
    assert_eq!(
        refused(SimulationBuilder::new(cube(2)).thickness(2e-3)),
        "invalid parameter `thickness`: applies to membranes (triangle meshes) only; level 0 is tetrahedral"
    );
    let membrane = crate::mesh::generate::rectangle_membrane(0.1, 0.1, 40).unwrap();
    assert!(SimulationBuilder::new(membrane)
        .thickness(2e-3)
        .fix(|p| p[0] <= 0.0)
        .build()
        .is_ok());
}

/// Both front doors build one `Model` and its stepper through `Model::stepper`: for each
/// scheme, the builder given the scenario's meshes, law and scheme settings steps to the
/// scenario's bits (the fixed nodes, the levels, the steps of each level, the coarse level
/// the Newton solvers pick and the smoother all agree; the builder's defaults for the steps
/// and the backward-Euler solver are the scenario's).
#[test]
fn every_scheme_built_from_code_steps_to_the_scenarios_bits() {
    let cases = [
        ("[multigrid]\nscheme = \"newton\"\nlevels = 3", None),
        ("[multigrid]\nscheme = \"fas\"\nlevels = 2", None),
        (
            "[integrator]\nmethod = \"implicit-euler\"\ndt = 0.02\n[multigrid]\nlevels = 3",
            Some(0.02),
        ),
        (
            "[integrator]\nmethod = \"bdf2\"\ndt = 0.02\n[multigrid]\nlevels = 3",
            Some(0.02),
        ),
        ("[integrator]\nmethod = \"symplectic-euler\"", None),
    ];
    for (scheme_keys, dt) in cases {
        let text = format!(
            r#"
gravity = [0.0, 0.0, -9.81]
[mesh]
generate = "box"
size = [0.04, 0.04, 0.04]
divisions = [6, 6, 6]
[material]
law = "stable-neo-hookean"
young = 5e3
poisson = 0.45
[[fix]]
plane = {{ point = [0, 0, 0], normal = [0, 0, 1] }}
[run]
duration = 1.0
{scheme_keys}
"#
        );
        let sc = Scenario::from_toml(&text, std::path::Path::new("doors.toml")).unwrap();
        let mut from_file = Simulation::from_scenario(&sc).unwrap();
        let meshes = sc.level_meshes().unwrap();
        let mut b = SimulationBuilder::new(meshes[0].clone())
            .levels(meshes[1..].to_vec())
            .material(sc.material.clone())
            .gravity(G)
            .fix(|p| p[2] <= 0.0)
            .scheme(sc.scheme());
        if let Some(dt) = dt {
            b = b.dt(dt);
        }
        let mut from_code = b.build().unwrap();
        assert_eq!(
            from_code.stepper().describe(),
            from_file.stepper().describe(),
            "{scheme_keys}"
        );
        assert_eq!(
            from_code.stepper().dt(),
            from_file.stepper().dt(),
            "{scheme_keys}"
        );
        for _ in 0..3 {
            let a = from_file.step_frame(Budget::Cycles(2));
            let b = from_code.step_frame(Budget::Cycles(2));
            assert!(a.accepted && b.accepted, "{scheme_keys}: {a:?} {b:?}");
            assert_eq!(
                from_file.positions(),
                from_code.positions(),
                "{scheme_keys}"
            );
        }
        // The top sinks under gravity.
        let top = from_code
            .positions()
            .iter()
            .map(|p| p[2])
            .fold(f64::NEG_INFINITY, f64::max);
        assert!(top < 0.04, "{scheme_keys}: {top}");
    }
}

/// The third way in: a `Model` assembled by hand and `Simulation::from_model` step to the
/// builder's bits for the same body (the builder is a front door to the same model), and a
/// hand-made model's fixed nodes are what its selector selects.
#[test]
fn a_model_assembled_by_hand_steps_as_the_builder_builds_it() {
    use crate::model::{Fixing, Levels, Model, Selector, Stepping};
    let (fine, coarse) = (cube(4), cube(2));
    let law = Material::StableNeoHookean(StableNeoHookean::from_young(5e3, 0.45));
    let mut model = Model::new(fine.clone(), law.clone(), "by hand");
    model.gravity = G;
    model.levels = Levels::Given(vec![coarse.clone()]);
    model.fix = vec![(
        Selector::Plane {
            point: [0.0; 3],
            normal: [0.0, 0.0, 1.0],
        },
        Fixing::All,
    )];
    model.fixed = crate::model::select::select_fixed(&model.mesh, &model.fix, &model.path, "")
        .unwrap()
        .0;
    assert_eq!(
        model.fixed.len(),
        25,
        "the bottom face of a 4x4x4 cube has 5x5 nodes"
    );
    let scheme = Scheme::Fas(Default::default());
    let critical = crate::integrate::stability::critical_step_estimate(
        &fine,
        &law,
        1000.0,
        Method::SymplecticEuler,
    );
    let stepping = Stepping {
        dt: 0.5 * critical,
        safety: 0.5,
        methods: vec![Method::SymplecticEuler; 2],
        level_dt: None,
        blowup_factor: None,
        implicit: None,
    };
    let mut by_hand = Simulation::from_model(&model, &scheme, &stepping).unwrap();
    let mut built = SimulationBuilder::new(fine)
        .levels(vec![coarse])
        .material(law)
        .gravity(G)
        .fix(|p| p[2] <= 0.0)
        .scheme(scheme)
        .build()
        .unwrap();
    for _ in 0..3 {
        assert!(by_hand.step_frame(Budget::Cycles(2)).accepted);
        assert!(built.step_frame(Budget::Cycles(2)).accepted);
        assert_eq!(by_hand.positions(), built.positions());
    }
    // Gravity moved the free nodes down and held the fixed ones.
    let moved = |a: usize| by_hand.positions()[a][2] - by_hand.mesh().nodes[a][2];
    assert!((0..by_hand.mesh().num_nodes()).all(|a| moved(a) <= 0.0));
    assert!(model.fixed.iter().all(|&a| moved(a as usize) == 0.0));
    assert!((0..by_hand.mesh().num_nodes()).any(|a| moved(a) < -1e-9));
}

/// Backward Euler built from a model refuses matrix-free Newton-Krylov, whose only use is the
/// static solve, by the message the scenario resolver gives for the same key (it took it as
/// `"auto"` without a word before).
#[test]
fn backward_euler_from_a_model_refuses_the_krylov_solver() {
    use crate::model::{ImplicitSolve, Model};
    use crate::statics::implicit::ImplicitScheme;
    use crate::statics::StaticSolver;
    let law = Material::StableNeoHookean(StableNeoHookean::from_young(5e3, 0.45));
    let model = Model::new(cube(2), law, "by hand");
    let imp = ImplicitSolve {
        solver: StaticSolver::Krylov,
        ..ImplicitSolve::new(
            ImplicitScheme::BackwardEuler,
            crate::mesh::ElementKind::Tet4,
        )
    };
    let e = model
        .implicit_euler(0.01, &imp, None)
        .err()
        .expect("refused");
    assert!(
        e.to_string().contains(
            "`integrator.solver` = \"krylov\" does not apply to method = \"implicit-euler\""
        ),
        "{e}"
    );
    let auto = ImplicitSolve::new(
        ImplicitScheme::BackwardEuler,
        crate::mesh::ElementKind::Tet4,
    );
    assert!(model.implicit_euler(0.01, &auto, None).is_ok());
}
