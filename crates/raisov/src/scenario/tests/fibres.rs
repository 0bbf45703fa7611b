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
            let (s, stepper) = crate::runner::run_static_keeping(
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
    let (s, stepper) = crate::runner::run_static_keeping(
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

// ---- Per-element fibre fields (scenario::fibres) ----

use crate::io::{write_vtu, write_vtu_as, Field, FieldData, VtuFormat};
use crate::mesh::generate::{box_tets, BoxPattern};
use crate::scenario::fibres::Helix;
use nalgebra::{Matrix3, Rotation3, Vector3};

/// A generic rotation (no axis special).
fn rotation() -> Matrix3<f64> {
    *Rotation3::from_euler_angles(0.3, -0.5, 0.8).matrix()
}

/// The box `[0, 0.02] × [0, 0.01] × [0, 0.01]` of `divisions`, rotated by `q`.
fn rotated_box(q: &Matrix3<f64>, divisions: [usize; 3]) -> crate::mesh::Mesh {
    let mut m = box_tets([0.02, 0.01, 0.01], divisions, BoxPattern::Six).unwrap();
    for x in &mut m.nodes {
        let y = q * Vector3::from(*x);
        *x = [y.x, y.y, y.z];
    }
    m
}

/// Write `mesh` as `dir/name` with the cell array `fibre` of `fibre(e)` per element.
fn write_with_fibres(
    dir: &Path,
    name: &str,
    mesh: &crate::mesh::Mesh,
    fibre: impl Fn(usize) -> [f64; 3],
) -> std::path::PathBuf {
    let p = dir.join(name);
    let f: Vec<f64> = (0..mesh.num_elements()).flat_map(&fibre).collect();
    write_vtu(
        &p,
        mesh,
        &mesh.nodes,
        &[],
        &[Field {
            name: "fibre",
            data: FieldData::Vector(&f),
        }],
    )
    .unwrap();
    p
}

/// A static test of the box `file` rotated by `q`: rollers on its three faces through the
/// origin (normals `q e_k`), a force `f` along `q e_1` on each node of the face
/// `X·q e_1 = 0.02`.
fn rotated_pull(file: &str, q: &Matrix3<f64>, material: &str, f: f64, extra: &str) -> String {
    let v = |x: Vector3<f64>| format!("[{:e}, {:e}, {:e}]", x.x, x.y, x.z);
    let n = |k: usize| q.column(k).into_owned();
    let fix = |k: usize| {
        format!(
            "[[fix]]\nplane = {{ point = [0, 0, 0], normal = {} }}\nnormal = {}\n",
            v(n(k)),
            v(n(k))
        )
    };
    format!(
        "[mesh]\nfile = \"{file}\"\n[material]\n{material}\n{}{}{}\
         [[load]]\nat = {{ plane = {{ point = {}, normal = {} }} }}\nforce = {}\n\
         [integrator]\nmethod = \"newton\"\n[run]\nresidual_tol = 1e-12\n{extra}",
        fix(0),
        fix(1),
        fix(2),
        v(n(0) * 0.02),
        v(-n(0)),
        v(n(0) * f),
    )
}

/// Solve `text` (a scenario in `dir`) statically; its level-0 displacement.
fn solve_in(dir: &Path, text: &str) -> (Scenario, Vec<f64>) {
    let sc = Scenario::from_toml(text, &dir.join("test.toml")).unwrap();
    let (s, stepper) = crate::runner::run_static_keeping(
        &sc,
        RunOptions {
            in_memory: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(s.converged(), "{s}");
    let u = stepper.state.u.clone();
    (sc, u)
}

/// A field read from cell data that is the same direction everywhere (unnormalised, as a
/// user may write it) gives the bits of `fibre = [x, y, z]`.
#[test]
fn a_constant_cell_data_field_gives_the_bits_of_the_constant_key() {
    let dir = tempfile::tempdir().unwrap();
    let q = rotation();
    let mesh = rotated_box(&q, [4, 2, 2]);
    let a = q * Vector3::new(2.0, 0.5, -1.0);
    write_with_fibres(dir.path(), "box.vtu", &mesh, |_| [a.x, a.y, a.z]);
    for law in [
        "law = \"ti-neo-hookean\"\nmu = 1e3\nkappa = 5e4\neta = 8e3",
        "law = \"hgo\"\nmu = 1e3\nkappa = 5e4\nk1 = 2e3\nk2 = 4.0\ndispersion = 0.1",
    ] {
        let constant = format!("{law}\nfibre = [{:e}, {:e}, {:e}]", a.x, a.y, a.z);
        let field = format!("{law}\nfibre = {{ cell_data = \"fibre\" }}");
        let (sc_c, u_c) = solve_in(
            dir.path(),
            &rotated_pull("box.vtu", &q, &constant, 0.02, ""),
        );
        let (sc_f, u_f) = solve_in(dir.path(), &rotated_pull("box.vtu", &q, &field, 0.02, ""));
        assert!(sc_c.fibres.is_none());
        assert_eq!(
            sc_f.fibres.as_ref().unwrap().level0.len(),
            mesh.num_elements()
        );
        assert!(u_c.iter().any(|&x| x.abs() > 1e-4), "it deforms");
        let bits = |u: &[f64]| u.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&u_c), bits(&u_f), "{law}");
    }
}

/// The uniaxial closed forms hold for a box rotated by a generic rotation Q with its fibre
/// field rotated with it (read as cell data, `a` and `−3a` in alternate cells: the fibre is
/// sign- and length-free), along the fibres and across: at the closed form's homogeneous
/// state `x = Q diag(λ) Qᵀ X` every element's Cauchy stress is `Q diag(σ, 0, 0) Qᵀ` (the
/// closed form's uniaxial stress along `Q e_1`), the interior nodes are in equilibrium, and
/// the forces on the loaded face sum to the closed form's traction times its area: the field
/// reaches every element's law, in the element's own frame.
#[test]
fn rotated_box_and_field_match_the_uniaxial_closed_form() {
    use crate::fem::{FemModel, ForceModel};
    let dir = tempfile::tempdir().unwrap();
    let q = rotation();
    let mesh = rotated_box(&q, [4, 2, 2]);
    let lam = 1.25;
    for law in [
        "law = \"ti-neo-hookean\"\nmu = 1e3\nkappa = 5e4\neta = 8e3",
        "law = \"hgo\"\nmu = 1e3\nkappa = 5e4\nk1 = 2e3\nk2 = 4.0\ndispersion = 0.1",
    ] {
        for along in [true, false] {
            let a = q.column(if along { 0 } else { 1 }).into_owned();
            let file = format!("box_{along}.vtu");
            write_with_fibres(dir.path(), &file, &mesh, |e| {
                let s = if e % 2 == 0 { 1.0 } else { -3.0 };
                [s * a.x, s * a.y, s * a.z]
            });
            let closed = Closed::of(
                &parse(&uniaxial_block(&format!("{law}\nfibre = [1, 0, 0]"), 1.0))
                    .unwrap()
                    .material,
            );
            // Stretches in the box's frame (load, second, third) and the Cauchy stress along
            // the load.
            let (l, sigma) = if along {
                let l = closed.along(lam);
                (l, closed.cauchy(l)[0])
            } else {
                let a = closed.across(lam);
                ([a[1], a[0], a[2]], closed.cauchy(a)[1])
            };
            let text = format!(
                "[mesh]\nfile = \"{file}\"\n[material]\n{law}\nfibre = {{ cell_data = \"fibre\" }}\n[run]\nduration = 0.01\n"
            );
            let sc = Scenario::from_toml(&text, &dir.path().join("test.toml")).unwrap();
            let mut model = FemModel::new(&sc.mesh, sc.fem_params()).unwrap();
            let g =
                q * Matrix3::from_diagonal(&Vector3::from(l)) * q.transpose() - Matrix3::identity();
            let u: Vec<f64> = sc
                .mesh
                .nodes
                .iter()
                .flat_map(|x| {
                    let w = g * Vector3::from(*x);
                    [w.x, w.y, w.z]
                })
                .collect();
            let want = q * Matrix3::from_diagonal(&Vector3::new(sigma, 0.0, 0.0)) * q.transpose();
            for e in 0..sc.mesh.num_elements() {
                let s = model.element_cauchy(e, &u);
                assert!(
                    (s - want).norm() <= 1e-9 * sigma,
                    "{law}, along {along}, element {e}: {s} against {want}"
                );
            }
            let mut r = vec![0.0; u.len()];
            model.internal_forces(&u, &mut r).unwrap();
            let n1 = q.column(0).into_owned();
            let mut face = Vector3::zeros();
            let scale = sigma * 0.01 * 0.01;
            for (k, x) in sc.mesh.nodes.iter().enumerate() {
                let f = Vector3::new(r[3 * k], r[3 * k + 1], r[3 * k + 2]);
                let y = q.transpose() * Vector3::from(*x);
                let on = |c: f64, v: f64| (c - v).abs() < 1e-9;
                let boundary = (0..3).any(|i| on(y[i], 0.0))
                    || on(y[0], 0.02)
                    || on(y[1], 0.01)
                    || on(y[2], 0.01);
                if on(y[0], 0.02) {
                    face += f;
                } else if !boundary {
                    assert!(f.norm() <= 1e-9 * scale, "interior node {k}: {f}");
                }
            }
            // The face's internal forces balance the load: the nominal traction σ λ2 λ3 on
            // the reference area, along Q e_1.
            let p = sigma * l[1] * l[2] * 0.01 * 0.01;
            assert!(
                (face - n1 * p).norm() <= 1e-9 * p,
                "{law}: face {face} against {p}"
            );
        }
    }
}

/// Objectivity: rotating the mesh, its (non-uniform) fibre field and the displacement by
/// one rotation Q leaves the strain energy unchanged and rotates the nodal forces, so their
/// norms are unchanged too; both fibre laws, element by element.
#[test]
fn rotating_mesh_field_and_motion_together_leaves_energy_and_force_norms_unchanged() {
    use crate::fem::{ElementFibres, FemModel, FemParams, ForceModel};
    use crate::material::{HolzapfelGasserOgden, TiNeoHookean};
    let q = rotation();
    let mesh = box_tets([0.02, 0.01, 0.01], [4, 2, 3], BoxPattern::Six).unwrap();
    let helix = Helix {
        axis: Vector3::new(0.2, 0.1, 1.0).normalize(),
        centre: Vector3::new(-0.03, 0.004, 0.0),
        inner_radius: 0.03,
        outer_radius: 0.05,
        endo: 60.0,
        epi: -60.0,
    };
    let field = helix.field(&mesh, Path::new("t.toml")).unwrap();
    let mut rotated = mesh.clone();
    for x in &mut rotated.nodes {
        let y = q * Vector3::from(*x);
        *x = [y.x, y.y, y.z];
    }
    let rotated_field: Vec<[f64; 3]> = field
        .0
        .iter()
        .map(|a| {
            let b = q * Vector3::from(*a);
            [b.x, b.y, b.z]
        })
        .collect();
    let rotated_field = ElementFibres::normalised(&rotated_field, "fibre").unwrap();
    // A smooth non-homogeneous motion with fibres stretched in some elements, shortened in others.
    let u: Vec<f64> = mesh
        .nodes
        .iter()
        .flat_map(|x| {
            [
                0.15 * x[0] + 3.0 * x[1] * x[2],
                -0.05 * x[1] + 2.0 * x[0] * x[0],
                0.1 * x[2] - 4.0 * x[0] * x[1],
            ]
        })
        .collect();
    let ur: Vec<f64> = u
        .chunks(3)
        .flat_map(|v| {
            let w = q * Vector3::new(v[0], v[1], v[2]);
            [w.x, w.y, w.z]
        })
        .collect();
    for law in [
        Material::TiNeoHookean(TiNeoHookean::new(1e3, 5e4, 8e3, Vector3::x()).unwrap()),
        Material::HolzapfelGasserOgden(
            HolzapfelGasserOgden::new(1e3, 5e4, 2e3, 4.0, 0.1, Vector3::x()).unwrap(),
        ),
    ] {
        let model = |m: &crate::mesh::Mesh, f: &ElementFibres| {
            let mut p = FemParams::new(law.clone());
            p.fibres = Some(f.clone());
            FemModel::new(m, p).unwrap()
        };
        let mut a = model(&mesh, &field);
        let mut b = model(&rotated, &rotated_field);
        let (ea, eb) = (a.strain_energy(&u), b.strain_energy(&ur));
        assert!(ea > 0.0 && (ea - eb).abs() <= 1e-12 * ea, "{ea} vs {eb}");
        // The field matters: the law's own fibre (e1 everywhere) stores another energy.
        let plain = FemModel::new(&mesh, FemParams::new(law.clone())).unwrap();
        assert!((plain.strain_energy(&u) - ea).abs() > 1e-3 * ea);
        let n = mesh.num_nodes();
        let (mut ra, mut rb) = (vec![0.0; 3 * n], vec![0.0; 3 * n]);
        a.internal_forces(&u, &mut ra).unwrap();
        b.internal_forces(&ur, &mut rb).unwrap();
        let scale = ra.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        for k in 0..n {
            let fa = Vector3::new(ra[3 * k], ra[3 * k + 1], ra[3 * k + 2]);
            let fb = Vector3::new(rb[3 * k], rb[3 * k + 1], rb[3 * k + 2]);
            assert!((fa.norm() - fb.norm()).abs() <= 1e-12 * scale);
            assert!((q * fa - fb).norm() <= 1e-12 * scale, "node {k}");
        }
        // The tangent is rotated as well: K' = Q K Qᵀ block by block, element 0.
        let (mut ka, mut kb) = (vec![0.0; 144], vec![0.0; 144]);
        a.element_stiffness(0, &u, &mut ka).unwrap();
        b.element_stiffness(0, &ur, &mut kb).unwrap();
        let kmax = ka.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        for i in 0..4 {
            for j in 0..4 {
                let blk = |k: &[f64]| Matrix3::from_fn(|r, c| k[(3 * i + r) * 12 + 3 * j + c]);
                assert!((q * blk(&ka) * q.transpose() - blk(&kb)).norm() <= 1e-10 * kmax);
            }
        }
    }
}

/// The helix rule at points of a tilted wall against its formula: unit fibres orthogonal to
/// the radial direction, at the angle `endo` on the inner radius (and inside it), `epi` on the
/// outer one (and outside), their mean half way; none on the axis.
#[test]
fn helix_rule_gives_the_formula_s_directions() {
    let axis = Vector3::new(1.0, 1.0, 2.0).normalize();
    let centre = Vector3::new(0.1, -0.2, 0.3);
    let spec = crate::scenario::spec::HelixSpec {
        axis: Some([2.0, 2.0, 4.0]),
        centre: Some([0.1, -0.2, 0.3]),
        inner_radius: Some(0.02),
        outer_radius: Some(0.03),
        endo: Some(60.0),
        epi: Some(-45.0),
    };
    let h = Helix::new(&spec, Path::new("t.toml")).unwrap();
    assert!((h.axis - axis).norm() < 1e-15);
    let e_r = axis.cross(&Vector3::new(0.0, 0.0, 1.0)).normalize();
    let e_circ = axis.cross(&e_r);
    for (r, theta) in [
        (0.02, 60.0),
        (0.01, 60.0),
        (0.03, -45.0),
        (0.04, -45.0),
        (0.025, 7.5),
    ] {
        for s in [-0.01, 0.0, 0.05] {
            let p = centre + axis * s + e_r * r;
            let a = Vector3::from(h.direction([p.x, p.y, p.z]).unwrap());
            let t: f64 = f64::to_radians(theta);
            assert!((a.norm() - 1.0).abs() < 1e-15);
            assert!(a.dot(&e_r).abs() < 1e-15, "radial part at r = {r}");
            assert!((a.dot(&e_circ) - t.cos()).abs() < 1e-14, "r = {r}");
            assert!((a.dot(&axis) - t.sin()).abs() < 1e-14, "r = {r}");
        }
    }
    let on = centre + axis * 0.3;
    assert_eq!(h.direction([on.x, on.y, on.z]), None);
}

/// The multigrid hierarchies reach the single-level equilibrium (Newton, residual 1e-10)
/// with a fibre field: the helix rule on generated levels, and cell data of a `.vtu` file
/// carried to a coarser level file by the structure tensor. The coarse fields only
/// precondition; level 0 is the given field.
#[test]
fn hierarchies_with_a_fibre_field_reach_the_single_level_equilibrium() {
    let dir = tempfile::tempdir().unwrap();
    let law = "law = \"hgo\"\nmu = 1e3\nkappa = 5e4\nk1 = 2e3\nk2 = 4.0";
    let helix = "fibre = { helix = { axis = [0, 0, 1], centre = [-0.03, 0.005, 0], inner_radius = 0.03, outer_radius = 0.04, endo = 60.0, epi = -60.0 } }";
    let generated = |levels: &str| {
        format!(
            "[mesh]\ngenerate = \"box\"\nsize = [0.01, 0.02, 0.01]\ndivisions = [4, 8, 4]\n\
             [material]\n{law}\n{helix}\n\
             [[fix]]\nplane = {{ point = [0, 0, 0], normal = [0, 1, 0] }}\n\
             [[load]]\nat = {{ plane = {{ point = [0, 0.02, 0], normal = [0, -1, 0] }} }}\nforce = [0, 0.03, 0.002]\n\
             [integrator]\nmethod = \"newton\"\n[run]\nresidual_tol = 1e-10\n{levels}"
        )
    };
    let (sc1, u1) = solve_in(dir.path(), &generated(""));
    let (sc3, u3) = solve_in(dir.path(), &generated("[multigrid]\nlevels = 3\n"));
    assert_eq!(sc3.num_levels(), 3);
    // Every level has its own field, the rule at its own centroids.
    let meshes = sc3.level_meshes().unwrap();
    for m in &meshes[1..] {
        let f = sc3.fem_params_on(m).unwrap().fibres.unwrap();
        assert_eq!(f.len(), m.num_elements());
    }
    let close = |a: &[f64], b: &[f64], what: &str| {
        let scale = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let d = a
            .iter()
            .zip(b)
            .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
        assert!(
            scale > 1e-4 && d <= 1e-7 * scale,
            "{what}: {d:e} of {scale:e}"
        );
    };
    assert_eq!(sc1.mesh.nodes, sc3.mesh.nodes);
    close(&u1, &u3, "helix, 3 generated levels");

    // Cell data: the same field as cell data of level 0's file, a coarser level file.
    let fine = box_tets([0.01, 0.02, 0.01], [4, 8, 4], BoxPattern::Six).unwrap();
    let f0 = sc1.fibres.as_ref().unwrap().level0.clone();
    write_with_fibres(dir.path(), "fine.vtu", &fine, |e| f0.0[e]);
    let coarse = box_tets([0.01, 0.02, 0.01], [2, 4, 2], BoxPattern::Five).unwrap();
    write_vtu(
        &dir.path().join("coarse.vtu"),
        &coarse,
        &coarse.nodes,
        &[],
        &[],
    )
    .unwrap();
    let from_file = |levels: &str| {
        generated(levels)
            .replace(
                "generate = \"box\"\nsize = [0.01, 0.02, 0.01]\ndivisions = [4, 8, 4]",
                "file = \"fine.vtu\"",
            )
            .replace(helix, "fibre = { cell_data = \"fibre\" }")
    };
    let (scf, uf) = solve_in(dir.path(), &from_file(""));
    let (scf2, uf2) = solve_in(
        dir.path(),
        &from_file("[multigrid]\nfiles = [\"coarse.vtu\"]\n"),
    );
    assert_eq!(scf2.num_levels(), 2);
    // The file's nodes are renumbered: compare node by node through the positions.
    let by_position = |sc: &Scenario, u: &[f64]| {
        let mut rows: Vec<([u64; 3], [f64; 3])> = sc
            .mesh
            .nodes
            .iter()
            .enumerate()
            .map(|(a, x)| (x.map(f64::to_bits), [u[3 * a], u[3 * a + 1], u[3 * a + 2]]))
            .collect();
        rows.sort_by_key(|a| a.0);
        rows.into_iter().flat_map(|r| r.1).collect::<Vec<f64>>()
    };
    close(
        &by_position(&sc1, &u1),
        &by_position(&scf, &uf),
        "cell data against the rule",
    );
    close(&uf, &uf2, "cell data, a coarser file level");
    let coarse_field = scf2
        .fem_params_on(&scf2.level_meshes().unwrap()[1])
        .unwrap()
        .fibres
        .unwrap();
    assert_eq!(coarse_field.len(), coarse.num_elements());
}

/// The structure-tensor rule keeps a uniform field uniform (to rounding, either sign given)
/// and gives every coarse element a unit direction.
#[test]
fn coarsening_a_uniform_field_keeps_its_direction() {
    let fine = box_tets([0.02, 0.01, 0.01], [8, 4, 4], BoxPattern::Six).unwrap();
    let coarse = box_tets([0.021, 0.011, 0.0095], [3, 2, 1], BoxPattern::Five).unwrap();
    let a = Vector3::new(0.3, -0.4, 0.5).normalize();
    let dirs: Vec<[f64; 3]> = (0..fine.num_elements())
        .map(|e| {
            if e % 3 == 0 {
                [-a.x, -a.y, -a.z]
            } else {
                [a.x, a.y, a.z]
            }
        })
        .collect();
    let field = crate::fem::ElementFibres::normalised(&dirs, "fibre").unwrap();
    // A level finer than the field's has elements hosting no centroid: they take the
    // direction of the element hosting their own centroid.
    let finer = box_tets([0.02, 0.01, 0.01], [12, 6, 6], BoxPattern::Five).unwrap();
    for coarse in [coarse, finer] {
        let c = crate::scenario::fibres::coarsen(&fine, &field, &coarse).unwrap();
        assert_eq!(c.len(), coarse.num_elements());
        for d in c.0.iter() {
            let d = Vector3::from(*d);
            assert!((d.norm() - 1.0).abs() < 1e-14);
            assert!(1.0 - d.dot(&a).abs() < 1e-14, "{d:?}");
        }
    }
}

/// Bad fibre fields are refused with an error naming the key, the file, the array, the cell
/// or the element, and what is valid.
#[test]
fn bad_fibre_fields_are_refused_naming_what_is_wrong() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = box_tets([0.02, 0.01, 0.01], [2, 1, 1], BoxPattern::Six).unwrap();
    let ne = mesh.num_elements();
    let write = |name: &str, k: usize, value: &dyn Fn(usize) -> f64| {
        let f: Vec<f64> = (0..ne * k).map(value).collect();
        let data = if k == 3 {
            FieldData::Vector(&f)
        } else {
            FieldData::Scalar(&f)
        };
        write_vtu_as(
            &dir.path().join(name),
            &mesh,
            &mesh.nodes,
            &[],
            &[Field {
                name: "fibre",
                data,
            }],
            VtuFormat::Ascii,
        )
        .unwrap();
    };
    write("one.vtu", 1, &|_| 1.0);
    write("zero.vtu", 3, &|i| if i / 3 == 5 { 0.0 } else { 1.0 });
    write("nan.vtu", 3, &|i| if i == 3 * 4 + 1 { 7.25 } else { 1.0 });
    let nan = dir.path().join("nan.vtu");
    let text = std::fs::read_to_string(&nan)
        .unwrap()
        .replace("7.25e0", "nan");
    std::fs::write(&nan, text).unwrap();
    crate::io::write_msh22(&dir.path().join("box.msh"), &mesh).unwrap();
    let ti = "law = \"ti-neo-hookean\"\nmu = 1e3\nkappa = 5e4\neta = 4e3";
    let scenario = |mesh: &str, fibre: &str| {
        format!("[mesh]\n{mesh}\n[material]\n{ti}\nfibre = {fibre}\n[[fix]]\nplane = {{ point = [0, 0, 0], normal = [1, 0, 0] }}\n[run]\nduration = 0.01\n")
    };
    let file = |f: &str| format!("file = \"{f}\"");
    let boxed = "generate = \"box\"\nsize = [0.02, 0.01, 0.01]\ndivisions = [2, 1, 1]";
    let helix = |inner: &str, outer: &str, centre: &str| {
        format!("{{ helix = {{ axis = [0, 0, 1], centre = {centre}, inner_radius = {inner}, outer_radius = {outer}, endo = 60.0, epi = -60.0 }} }}")
    };
    // The centroid of element 3 of the generated box (not renumbered).
    let c3 = {
        let el = mesh.element(3);
        let mut c = [0.0; 3];
        for &a in el {
            for k in 0..3 {
                c[k] += mesh.nodes[a as usize][k] / 4.0;
            }
        }
        format!("[{:e}, {:e}, 0.0]", c[0], c[1])
    };
    for (text, want) in [
        (
            scenario(&file("one.vtu"), "{ cell_data = \"fibre\" }"),
            "one.vtu: the cell array \"fibre\" has 1 components per cell; a fibre direction has 3",
        ),
        (
            scenario(&file("one.vtu"), "{ cell_data = \"sheet\" }"),
            "no cell data array named `sheet`",
        ),
        (
            scenario(&file("zero.vtu"), "{ cell_data = \"fibre\" }"),
            "zero.vtu: cell 5 of \"fibre\" is [0, 0, 0], not a direction",
        ),
        (
            scenario(&file("nan.vtu"), "{ cell_data = \"fibre\" }"),
            "nan.vtu: cell 4 of \"fibre\" is [1, NaN, 1], not a direction",
        ),
        (
            scenario(&file("box.msh"), "{ cell_data = \"fibre\" }"),
            "cell data is read from .vtu mesh files",
        ),
        (
            scenario(boxed, "{ cell_data = \"fibre\" }"),
            "a generated mesh has no cell data",
        ),
        (
            scenario(boxed, "\"cells\""),
            "`material.fibre` = not a fibre direction or field: valid are [x, y, z]",
        ),
        (
            scenario(boxed, "[1.0, 0.0]"),
            "not a fibre direction or field",
        ),
        (
            scenario(boxed, "{ cell_data = \"a\", helix = {} }"),
            "a table with one of `cell_data` or `helix`",
        ),
        (
            scenario(boxed, "{ helix = { axis = [0, 0, 1] } }"),
            "`material.fibre.helix` needs `centre = [x, y, z]`",
        ),
        (
            scenario(boxed, &helix("0.03", "0.02", "[0, 0, 0]")),
            "inner_radius = 0.03, outer_radius = 0.02: need 0 <= inner_radius < outer_radius",
        ),
        (
            scenario(boxed, &helix("-0.01", "0.02", "[0, 0, 0]")),
            "need 0 <= inner_radius < outer_radius",
        ),
        (
            scenario(boxed, &helix("0.0", "0.02", &c3)),
            "element 3's centroid",
        ),
        (
            scenario(
                boxed,
                &helix("0.0", "0.02", "[0, 0, 0]").replace("[0, 0, 1]", "[0, 0, 0]"),
            ),
            "`material.fibre.helix.axis`: [0, 0, 0] is not a direction",
        ),
        (
            scenario(boxed, "{ helix = { axis = [0, 0, 1], twist = 3 } }"),
            "not a fibre direction or field",
        ),
    ] {
        let e = Scenario::from_toml(&text, &dir.path().join("test.toml"))
            .expect_err(want)
            .to_string();
        assert!(e.contains("test.toml"), "{e}");
        assert!(e.contains(want), "{e}\nwanted: {want}");
    }
    // A field given to a law without fibres is refused by the force model.
    let mut p = crate::fem::FemParams::new(Material::NeoHookean(crate::material::NeoHookean {
        lambda: 1e4,
        mu: 1e3,
    }));
    p.fibres =
        Some(crate::fem::ElementFibres::normalised(&vec![[1.0, 0.0, 0.0]; ne], "fibre").unwrap());
    let e = crate::fem::FemModel::new(&mesh, p)
        .err()
        .expect("refused")
        .to_string();
    assert!(
        e.contains("material.fibre") && e.contains("has no fibres"),
        "{e}"
    );
    let law = crate::material::TiNeoHookean::new(1e3, 5e4, 1e3, Vector3::x()).unwrap();
    let mut p = crate::fem::FemParams::new(Material::TiNeoHookean(law));
    p.fibres = Some(
        crate::fem::ElementFibres::normalised(&vec![[1.0, 0.0, 0.0]; ne - 1], "fibre").unwrap(),
    );
    let e = crate::fem::FemModel::new(&mesh, p)
        .err()
        .expect("refused")
        .to_string();
    assert!(
        e.contains(&format!("{} directions for {ne} elements", ne - 1)),
        "{e}"
    );
}

/// A run writes the field as the cell data `fibre` of its frames (ParaView shows it), and
/// the frames of a single fibre direction carry none (unchanged outputs).
#[test]
fn frames_carry_the_fibre_field_as_cell_data() {
    let dir = tempfile::tempdir().unwrap();
    let text = "[mesh]\ngenerate = \"box\"\nsize = [0.01, 0.02, 0.01]\ndivisions = [2, 4, 2]\n\
         [material]\nlaw = \"ti-neo-hookean\"\nmu = 1e3\nkappa = 5e4\neta = 4e3\n\
         fibre = { helix = { axis = [0, 0, 1], centre = [-0.03, 0.005, 0], inner_radius = 0.03, outer_radius = 0.04, endo = 60.0, epi = -60.0 } }\n\
         [[fix]]\nplane = { point = [0, 0, 0], normal = [0, 1, 0] }\n\
         [[load]]\nat = { plane = { point = [0, 0.02, 0], normal = [0, -1, 0] } }\nforce = [0, 0.01, 0]\n\
         [integrator]\nmethod = \"newton\"\n[run]\nresidual_tol = 1e-9\n";
    for (name, text) in [("field", text.to_string()), ("constant", text.replace("fibre = { helix = { axis = [0, 0, 1], centre = [-0.03, 0.005, 0], inner_radius = 0.03, outer_radius = 0.04, endo = 60.0, epi = -60.0 } }", "fibre = [1, 0, 0]"))] {
        let sc = Scenario::from_toml(&text, &dir.path().join(format!("{name}.toml"))).unwrap();
        let out = dir.path().join(format!("out-{name}"));
        let s = crate::runner::run_static(
            &sc,
            RunOptions {
                out_dir: Some(out.clone()),
                ..Default::default()
            },
        )
        .unwrap();
        assert!(s.converged(), "{s}");
        let frame = std::fs::read_dir(out.join("frames"))
            .unwrap()
            .map(|e| e.unwrap().path())
            .find(|p| p.extension().is_some_and(|e| e == "vtu"))
            .expect("a frame");
        let got = crate::io::read_vtu_cell_array(&frame, "fibre");
        match &sc.fibres {
            Some(f) => assert_eq!(got.unwrap(), (3, f.level0.flat().to_vec())),
            None => assert!(got.is_err()),
        }
    }
}

/// A fibre-field scenario gives the same bits on one thread and two (the multigrid levels
/// and their coarse fields included).
#[test]
fn a_fibre_field_run_has_the_same_bits_on_one_and_two_threads() {
    let dir = tempfile::tempdir().unwrap();
    let text = "[mesh]\ngenerate = \"box\"\nsize = [0.01, 0.02, 0.01]\ndivisions = [3, 6, 3]\n\
         [material]\nlaw = \"hgo\"\nmu = 1e3\nkappa = 5e4\nk1 = 2e3\nk2 = 4.0\n\
         fibre = { helix = { axis = [0, 0, 1], centre = [-0.03, 0.005, 0], inner_radius = 0.03, outer_radius = 0.04, endo = 60.0, epi = -60.0 } }\n\
         [[fix]]\nplane = { point = [0, 0, 0], normal = [0, 1, 0] }\n\
         [[load]]\nat = { plane = { point = [0, 0.02, 0], normal = [0, -1, 0] } }\nforce = [0, 0.03, 0.002]\n\
         [integrator]\nmethod = \"newton\"\n[run]\nresidual_tol = 1e-10\n[multigrid]\nlevels = 2\n";
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| solve_in(dir.path(), text).1)
    };
    let (a, b) = (run(1), run(2));
    assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
}

/// `examples/fibre_wall.toml` does what its comment says: the helix fibres turn the pulled
/// face (its endocardial edge 0.29 mm down, its epicardial edge 0.47 mm up, the face 1.5 mm
/// around), and fibres that are circumferential everywhere do not (0.8 mm around, the edges'
/// z-motions within 0.003 mm).
#[test]
fn fibre_wall_example_twists_as_its_comment_says() {
    let p = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../examples/fibre_wall.toml"
    ));
    let text = std::fs::read_to_string(p).unwrap();
    let run = |text: &str| {
        let sc = Scenario::from_toml(text, p).unwrap();
        let (s, stepper) = crate::runner::run_static_keeping(
            &sc,
            RunOptions {
                in_memory: true,
                ..Default::default()
            },
        )
        .unwrap();
        assert!(s.converged(), "{s}");
        let u = &stepper.state.u;
        // Means over the pulled face's endocardial (x = 0) and epicardial (x = 1 cm) edges.
        let edge = |x: f64, k: usize| {
            let v: Vec<f64> = (0..sc.mesh.num_nodes())
                .filter(|&a| {
                    let y = sc.mesh.nodes[a];
                    (y[1] - 0.02).abs() < 1e-9 && (y[0] - x).abs() < 1e-9
                })
                .map(|a| u[3 * a + k])
                .collect();
            v.iter().sum::<f64>() / v.len() as f64
        };
        let means = [edge(0.0, 1), edge(0.01, 1), edge(0.0, 2), edge(0.01, 2)];
        (sc, means)
    };
    let (sc, [y_endo, y_epi, z_endo, z_epi]) = run(&text);
    assert_eq!(sc.num_levels(), 2);
    assert!(sc.fibres.is_some());
    assert!(
        (0.5 * (y_endo + y_epi) - 1.5e-3).abs() < 0.05e-3,
        "{y_endo} {y_epi}"
    );
    assert!((z_endo + 0.29e-3).abs() < 0.005e-3, "{z_endo}");
    assert!((z_epi - 0.47e-3).abs() < 0.005e-3, "{z_epi}");
    let (_, [y0, y1, z0, z1]) = run(&text.replace(
        "fibre = { helix = { axis = [0.0, 0.0, 1.0], centre = [-0.03, 0.01, 0.0], inner_radius = 0.03, outer_radius = 0.04, endo = 60.0, epi = -60.0 } }",
        "fibre = [0.0, 1.0, 0.0]",
    ));
    assert!((0.5 * (y0 + y1) - 0.8e-3).abs() < 0.05e-3, "{y0} {y1}");
    assert!(
        (z0 - z1).abs() < 0.0035e-3 && (z0 - z1).abs() > 0.0025e-3,
        "{z0} {z1}"
    );
}
