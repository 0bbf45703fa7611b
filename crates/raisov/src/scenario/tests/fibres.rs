//! The fibre laws in scenarios: their keys and errors, and a static uniaxial test of a box of
//! tetrahedra against the closed forms of `material::uniaxial_tests`.

use super::*;
use crate::material::uniaxial_tests::Closed;

/// `[material]` of the ti-neo-hookean block, with `extra` lines.
fn ti_block(extra: &str) -> String {
    format!(
        "[mesh]\ngenerate = \"box\"\nsize = [0.02, 0.01, 0.01]\ndivisions = [2, 1, 1]\n\
         [material]\nlaw = \"ti-neo-hookean\"\n{extra}\n\
         [[fix]]\nplane = {{ point = [0, 0, 0], normal = [1, 0, 0] }}\n\
         [run]\nduration = 0.01\n"
    )
}

#[test]
fn fibre_laws_are_read_with_their_fibre_normalised() {
    let sc = parse(&ti_block(
        "mu = 1e3\nkappa = 5e4\neta = 4e3\nfibre = [0.0, 3.0, 4.0]",
    ))
    .unwrap();
    let Material::TiNeoHookean(m) = &sc.material else {
        panic!("{:?}", sc.material)
    };
    assert_eq!((m.mu, m.kappa, m.eta), (1e3, 5e4, 4e3));
    assert!((m.fibre - nalgebra::Vector3::new(0.0, 0.6, 0.8)).norm() < 1e-15);

    // From young and poisson: μ = E/(2(1 + ν)), κ = E/(3(1 − 2ν)).
    let text = ti_block("young = 3e3\npoisson = 0.4\neta = 1e3\nfibre = [1, 0, 0]")
        .replace("ti-neo-hookean", "hgo")
        .replace("eta = 1e3", "k1 = 2e3\nk2 = 5.0\ndispersion = 0.1");
    let sc = parse(&text).unwrap();
    let Material::HolzapfelGasserOgden(m) = &sc.material else {
        panic!("{:?}", sc.material)
    };
    assert!((m.mu - 3e3 / 2.8).abs() < 1e-9 && (m.kappa - 3e3 / 0.6).abs() < 1e-9);
    assert_eq!((m.k1, m.k2, m.dispersion), (2e3, 5.0, 0.1));
    assert_eq!(sc.material.name(), "hgo");
    let alias = parse(&text.replace("\"hgo\"", "\"holzapfel-gasser-ogden\"")).unwrap();
    assert_eq!(alias.material, sc.material);
}

/// Each error of the fibre laws' keys names the key and what would be valid.
#[test]
fn fibre_law_errors_name_the_key_and_the_valid_values() {
    let ti = "mu = 1e3\nkappa = 5e4\neta = 4e3\nfibre = [1.0, 0.0, 0.0]";
    for (text, want) in [
        (
            ti_block(&ti.replace("[1.0, 0.0, 0.0]", "[0.0, 0.0, 0.0]")),
            "`material.fibre`: [0, 0, 0] is not a direction: give a non-zero finite vector",
        ),
        (
            ti_block(&ti.replace("fibre = [1.0, 0.0, 0.0]", "")),
            "needs `fibre = [x, y, z]`",
        ),
        (
            ti_block(&format!("{ti}\nk1 = 3.0")),
            "`k1` is not a parameter of law = \"ti-neo-hookean\" (its parameters: `mu`, `kappa`, `young`, `poisson`, `eta`, `fibre`, `density`)",
        ),
        (
            ti_block(&format!("{ti}\nyoung = 3e3")),
            "takes either `mu` and `kappa` or `young` and `poisson`, not both pairs",
        ),
        (
            ti_block(&ti.replace("eta = 4e3", "eta = -1.0")),
            "`material.eta` = -1: must be a number >= 0",
        ),
        (
            ti_block(&ti.replace("kappa = 5e4\n", "")),
            "needs `kappa`",
        ),
        (
            ti_block(&ti.replace("eta = 4e3", "k1 = 1e3\nk2 = 1.0\ndispersion = 0.5"))
                .replace("ti-neo-hookean", "hgo"),
            "`material.dispersion` = 0.5: must be in [0, 1/3]",
        ),
        (
            ti_block("young = 3e3\npoisson = 0.4\nfibre = [1, 0, 0]").replace("ti-neo-hookean", "neo-hookean"),
            "`fibre` is not a parameter of law = \"neo-hookean\" (its parameters: `young`, `poisson`, `density`)",
        ),
        (
            BASE.replace(
                "law = \"mooney-rivlin\"\nc1 = 1000.0\nc2 = 1000.0",
                "law = \"hgo\"\nmu = 1e3\nkappa = 5e4\nk1 = 1e3\nk2 = 1.0\nfibre = [1, 0, 0]",
            ),
            "law = \"hgo\" is a solid law (tetrahedra) and this mesh is a membrane; membranes take \"stvk\"",
        ),
        (
            ti_block(ti).replace("ti-neo-hookean", "fibrous"),
            "\"ti-neo-hookean\", \"hgo\"",
        ),
    ] {
        let e = error_of(&text);
        assert!(e.contains(want), "{e}\nwanted: {want}");
    }
}

/// The library refuses a fibre law on a membrane, and a fibre that is not a unit vector,
/// with an error (not a panic) naming the key.
#[test]
fn fibre_laws_on_membranes_are_refused_by_the_force_model() {
    let mesh = crate::mesh::generate::rectangle_membrane(0.1, 0.1, 30).unwrap();
    let law = crate::material::TiNeoHookean::new(1e3, 5e4, 1e3, nalgebra::Vector3::x()).unwrap();
    let e = crate::fem::FemModel::new(
        &mesh,
        crate::fem::FemParams::new(Material::TiNeoHookean(law)),
    )
    .err()
    .expect("refused");
    assert!(e.to_string().contains("material.law"), "{e}");
    let cube = crate::mesh::generate::box_tets(
        [1.0; 3],
        [1, 1, 1],
        crate::mesh::generate::BoxPattern::Six,
    )
    .unwrap();
    let bad = crate::material::TiNeoHookean {
        fibre: nalgebra::Vector3::new(2.0, 0.0, 0.0),
        ..law
    };
    let e = crate::fem::FemModel::new(
        &cube,
        crate::fem::FemParams::new(Material::TiNeoHookean(bad)),
    )
    .err()
    .expect("refused");
    assert!(e.to_string().contains("material.fibre"), "{e}");
}

/// Box `[0, 0.02] × [0, 0.01] × [0, 0.01]` of tetrahedra on rollers at x = 0, y = 0, z = 0,
/// pulled by a dead traction `p` (Pa, per reference area) on x = 0.02, solved statically:
/// its deformation is homogeneous, `x = diag(l) X`.
fn uniaxial_block(material: &str, p: f64) -> String {
    format!(
        r#"
[mesh]
generate = "box"
size = [0.02, 0.01, 0.01]
divisions = [4, 2, 2]
[material]
{material}
[[fix]]
plane = {{ point = [0, 0, 0], normal = [1, 0, 0] }}
components = ["x"]
[[fix]]
plane = {{ point = [0, 0, 0], normal = [0, 1, 0] }}
components = ["y"]
[[fix]]
plane = {{ point = [0, 0, 0], normal = [0, 0, 1] }}
components = ["z"]
[[traction]]
group = "xmax"
traction = [{p:e}, 0.0, 0.0]
[integrator]
method = "newton"
[run]
residual_tol = 1e-12
"#
    )
}

/// Uniaxial tension of a box along its fibres and across them, solved by Newton on the
/// assembled tangent: the stretches equal the closed form's at the traction the closed form
/// gives for a stretch of 1.25 (a homogeneous state, which linear tetrahedra represent
/// exactly: within 1e-8), the x-rollers' reaction balances the traction, and the same
/// traction stretches the box less along the fibres than across.
#[test]
fn uniaxial_box_matches_the_closed_form_along_and_across_the_fibres() {
    let lam = 1.25;
    let laws = [
        "law = \"ti-neo-hookean\"\nmu = 1e3\nkappa = 5e4\neta = 8e3",
        "law = \"hgo\"\nmu = 1e3\nkappa = 5e4\nk1 = 2e3\nk2 = 4.0\ndispersion = 0.1",
    ];
    for law in laws {
        let mut p_along = 0.0;
        for (fibre, along) in [("[1, 0, 0]", true), ("[0, 1, 0]", false)] {
            let spec = format!("{law}\nfibre = {fibre}");
            // The closed form (its moduli only: fibres along e1; across, stretched along e2).
            let closed = Closed::of(&parse(&uniaxial_block(&spec, 1.0)).unwrap().material);
            let (l, p) = if along {
                let l = closed.along(lam);
                (l, closed.cauchy(l)[0] * l[1] * l[2])
            } else {
                let a = closed.across(lam);
                // (fibre, load, other) = (y, x, z) of the box.
                ([a[1], a[0], a[2]], closed.cauchy(a)[1] * a[0] * a[2])
            };
            let sc = parse(&uniaxial_block(&spec, p)).unwrap();
            let (s, stepper) = crate::scenario::run_static_keeping(
                &sc,
                RunOptions {
                    in_memory: true,
                    ..Default::default()
                },
            )
            .unwrap();
            assert!(s.converged(), "{s}");
            let u = &stepper.state.u;
            let mut err: f64 = 0.0;
            for (a, x) in sc.mesh.nodes.iter().enumerate() {
                for k in 0..3 {
                    err = err.max((u[3 * a + k] - (l[k] - 1.0) * x[k]).abs());
                }
            }
            assert!(
                err <= 1e-8 * (lam - 1.0) * 0.02,
                "{law}, fibre {fibre}: u differs from the closed form by {err:e} m (stretches {l:?})"
            );
            let area = 0.01 * 0.01;
            let rx = s.last.reaction_fixed[0];
            assert!(
                (rx + p * area).abs() <= 1e-8 * p * area,
                "reaction {rx} N, traction load {} N",
                p * area
            );
            if along {
                p_along = p;
            } else {
                // The same stretch needs less traction across the fibres.
                assert!(
                    p < 0.8 * p_along,
                    "{law}: along {p_along} Pa, across {p} Pa for λ = {lam}"
                );
            }
        }
    }
}

/// `examples/fibre_block.toml` does what its comment says: stretched to 1.25 along its
/// fibres and thinned to 0.9142 (the closed form's stretches, within 1e-8 of the 5 mm).
#[test]
fn fibre_block_example_stretches_as_its_comment_says() {
    let p = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../examples/fibre_block.toml"
    ));
    let sc = Scenario::load(p).unwrap();
    let l = Closed::of(&sc.material).along(1.25);
    assert!((l[1] - 0.9142).abs() < 5e-5, "{l:?}");
    let (s, stepper) = crate::scenario::run_static_keeping(
        &sc,
        RunOptions {
            in_memory: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(s.converged(), "{s}");
    for (a, x) in sc.mesh.nodes.iter().enumerate() {
        for k in 0..3 {
            let want = (l[k] - 1.0) * x[k];
            assert!((stepper.state.u[3 * a + k] - want).abs() <= 1e-8 * 0.005);
        }
    }
}
