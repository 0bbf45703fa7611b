//! neo-hookean-visco (`material::NeoHookeanVisco`): its keys and errors, the stress relaxation
//! of a homogeneous block after a step strain against the closed form of the Prony series,
//! creep under a held traction against the small-strain closed form, the long-term limit of a
//! static solve, α = 0 against the elastic law to the bit, the algorithmic tangent against
//! differences of the forces, and the same bits on one and two threads.

use super::*;
use crate::fem::{FemModel, FemParams, ForceModel};
use crate::material::{NeoHookeanVisco, Prony};
use crate::mesh::generate::{box_tets, BoxPattern};
use nalgebra::Matrix3;

/// A box `[0, 0.02] × [0, 0.01] × [0, 0.01]` of `divisions` with `material` lines, on rollers
/// at x = 0, y = 0, z = 0, and `rest` (loads, integrator, run).
fn block(material: &str, divisions: [usize; 3], rest: &str) -> String {
    format!(
        r#"
[mesh]
generate = "box"
size = [0.02, 0.01, 0.01]
divisions = [{}, {}, {}]
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
{rest}
"#,
        divisions[0], divisions[1], divisions[2]
    )
}

const VISCO: &str =
    "law = \"neo-hookean-visco\"\nmu = 1e3\nkappa = 2e4\nprony = [[0.3, 0.05], [0.2, 0.5]]";

#[test]
fn visco_law_is_read_and_bad_keys_are_named() {
    let run = "[run]\nduration = 0.01";
    let sc = parse(&block(VISCO, [2, 1, 1], run)).unwrap();
    let Material::NeoHookeanVisco(m) = &sc.material else {
        panic!("{:?}", sc.material)
    };
    assert_eq!((m.mu, m.kappa), (1e3, 2e4));
    assert_eq!(
        m.prony,
        vec![
            Prony {
                alpha: 0.3,
                tau: 0.05
            },
            Prony {
                alpha: 0.2,
                tau: 0.5
            }
        ]
    );
    assert!((m.long_term_mu() - 500.0).abs() < 1e-12);
    let base = "law = \"neo-hookean-visco\"\nmu = 1e3\nkappa = 2e4";
    let cases: Vec<(String, &str)> = vec![
        (format!("{base}\nprony = [[-0.1, 1.0]]"), "`material.prony`: term 1 = [-0.1, 1]: the relative modulus α must be a number >= 0"),
        (format!("{base}\nprony = [[0.1, 1.0], [0.2, 0.0]]"), "term 2 = [0.2, 0]: the relaxation time τ must be a positive number (s)"),
        (format!("{base}\nprony = [[0.6, 1.0], [0.4, 2.0]]"), "the relative moduli sum to 1: need Σ α < 1"),
        (base.to_string(), "law = \"neo-hookean-visco\" needs `prony = [[alpha, tau], ...]`"),
        (format!("{base}\nprony = [[0.1, 1.0]]\nfibre = [1, 0, 0]"), "`fibre` is not a parameter of law = \"neo-hookean-visco\" (its parameters: `mu`, `kappa`, `young`, `poisson`, `prony`, `density`)"),
        (format!("{base}\nprony = [[0.1, 1.0, 3.0]]"), "`material.prony`: term 1 has 3 numbers: each term is [alpha, tau]"),
    ];
    for (mat, want) in cases {
        let Err(e) = parse(&block(&mat, [2, 1, 1], run)) else {
            panic!("accepted; wanted: {want}")
        };
        let e = e.to_string();
        assert!(e.contains(want), "{e}\nwanted: {want}");
    }
    // On the neo-hookean law `prony` is not a key.
    let e = parse(&block(
        "law = \"neo-hookean\"\nyoung = 3e3\npoisson = 0.4\nprony = [[0.1, 1.0]]",
        [2, 1, 1],
        run,
    ))
    .err()
    .unwrap()
    .to_string();
    assert!(
        e.contains("`prony` is not a parameter of law = \"neo-hookean\""),
        "{e}"
    );
    // Solvers that do not carry the internal variables are refused, naming the section.
    let e = parse(&block(
        VISCO,
        [2, 1, 1],
        "[run]\nduration = 0.01\n[multigrid]\nlevels = 2",
    ))
    .err()
    .unwrap()
    .to_string();
    assert!(e.contains("`[multigrid]` with method = \"symplectic-euler\" does not apply to law = \"neo-hookean-visco\""), "{e}");
    // Interactive frames on one level carry the internal variables (their checkpoints
    // keep them); with an explicit multigrid scheme they are refused as above.
    parse(&format!(
        "{}\n[interactive]\nfps = 30.0",
        pulled(VISCO, "method = \"symplectic-euler\"", [2, 1, 1])
    ))
    .unwrap();
    // Membranes.
    let mesh = crate::mesh::generate::rectangle_membrane(0.1, 0.1, 30).unwrap();
    let law = NeoHookeanVisco::new(1e3, 5e4, vec![]).unwrap();
    let e = FemModel::new(&mesh, FemParams::new(Material::NeoHookeanVisco(law)))
        .err()
        .expect("refused");
    assert!(e.to_string().contains("material.law"), "{e}");
}

/// The model of a 2 × 1 × 1 box of `law` and the homogeneous displacement `(F − I) X`.
fn homogeneous(law: Material, f: Matrix3<f64>) -> (FemModel, Vec<f64>, Vec<usize>) {
    let mesh = box_tets([0.02, 0.01, 0.01], [2, 1, 1], BoxPattern::Six).unwrap();
    let u: Vec<f64> = mesh
        .nodes
        .iter()
        .flat_map(|x| {
            let y = (f - Matrix3::identity()) * nalgebra::Vector3::from(*x);
            [y.x, y.y, y.z]
        })
        .collect();
    let xmax = (0..mesh.num_nodes())
        .filter(|&a| (mesh.nodes[a][0] - 0.02).abs() < 1e-12)
        .collect();
    (FemModel::new(&mesh, FemParams::new(law)).unwrap(), u, xmax)
}

/// `Σ R_x` over the nodes `xmax`: the force holding the x = 0.02 face (N).
fn reaction(model: &mut FemModel, u: &[f64], xmax: &[usize]) -> f64 {
    let mut r = vec![0.0; u.len()];
    model.internal_forces(u, &mut r).unwrap();
    xmax.iter().map(|&a| r[3 * a]).sum()
}

/// A homogeneous stretch `F = diag(1.3, 0.9, 0.95)` applied over the first step and held: the
/// force on the x = 0.02 face (area A = 1e-4 m²) is `A (F S)_xx` with, for `t ≥ Δt`,
///
/// ```text
/// S(t) = S_vol + S_iso (1 − Σ_i α_i [1 − e^(−(t − Δt)/τ_i) (1 − γ_i(Δt))])
/// ```
///
/// the closed form of the Prony series for a strain ramped linearly over `[0, Δt]` (which is
/// what the recurrence takes a step strain for; `γ_i(Δt) = 1 − τ_i (1 − e^(−Δt/τ_i))/Δt`). The
/// recurrence is exact for that history, so the reactions agree to round-off: within 1e-10 of
/// the instantaneous force, both with the backward-Euler order (evaluations at Δt, then
/// accepted) and the explicit one (accepted, then evaluated at Δt = 0). The force relaxes
/// from its instantaneous value towards the long-term one (μ_∞ = 500 Pa).
#[test]
fn stress_relaxation_after_a_step_strain_matches_the_prony_closed_form() {
    let Material::NeoHookeanVisco(law) = parse(&block(VISCO, [2, 1, 1], "[run]\nduration = 0.01"))
        .unwrap()
        .model
        .material
    else {
        unreachable!()
    };
    let f = Matrix3::from_diagonal(&nalgebra::Vector3::new(1.3, 0.9, 0.95));
    let c = f.transpose() * f;
    let s_iso = law.iso_stress(&c);
    let j = f.determinant();
    let s_vol = c.try_inverse().unwrap() * (law.kappa * (j - 1.0) * j);
    let dt = 0.01;
    let closed = |t: f64| {
        let relaxed: f64 = law
            .prony
            .iter()
            .map(|p| {
                let (_, g) = crate::material::step_factors(p.tau, dt);
                p.alpha * (1.0 - (-(t - dt) / p.tau).exp() * (1.0 - g))
            })
            .sum();
        1e-4 * (f * (s_vol + s_iso * (1.0 - relaxed)))[(0, 0)]
    };
    let instantaneous = closed(dt);
    for explicit in [false, true] {
        let (mut model, u, xmax) = homogeneous(Material::NeoHookeanVisco(law.clone()), f);
        let mut worst: f64 = 0.0;
        let mut last = f64::INFINITY;
        for n in 1..=200 {
            let t = n as f64 * dt;
            let r = if explicit {
                model.accept_step(&u, dt);
                model.set_step(0.0);
                reaction(&mut model, &u, &xmax)
            } else {
                model.set_step(dt);
                let r = reaction(&mut model, &u, &xmax);
                model.accept_step(&u, dt);
                r
            };
            worst = worst.max((r - closed(t)).abs());
            assert!(r < last, "t = {t}: the force must relax");
            last = r;
        }
        eprintln!(
            "relaxation, explicit = {explicit}: worst |reaction − closed form| {worst:.3e} N of {instantaneous:.3e} N"
        );
        assert!(
            worst <= 1e-10 * instantaneous,
            "explicit = {explicit}: worst {worst:e} N of {instantaneous:e} N"
        );
        // After 2 s (4 τ of the slow term) it is close to the long-term force.
        let long = 1e-4 * (f * (s_vol + s_iso * 0.5))[(0, 0)];
        assert!(
            (last - long).abs() < 0.03 * (instantaneous - long),
            "{last} vs {long}"
        );
    }
}

/// Static solves find the fully relaxed equilibrium: the uniaxial block under a dead traction
/// solved by Newton with neo-hookean-visco has the displacements of the elastic law with
/// μ_∞ = μ (1 − Σ α) (mooney-rivlin with c1 = μ_∞/2, c2 = 0: the same neo-Hookean), within
/// 1e-9 of the tip displacement.
#[test]
fn static_solve_of_a_visco_law_is_the_long_term_equilibrium() {
    let newton = "[[traction]]\ngroup = \"xmax\"\ntraction = [300.0, 0.0, 0.0]\n\
                  [integrator]\nmethod = \"newton\"\n[run]\nresidual_tol = 1e-12";
    let solve = |mat: &str| {
        let sc = parse(&block(mat, [4, 2, 2], newton)).unwrap();
        let (s, st) = crate::runner::run_static_keeping(
            &sc,
            RunOptions {
                in_memory: true,
                ..Default::default()
            },
        )
        .unwrap();
        assert!(s.converged(), "{s}");
        st.state.u.clone()
    };
    let visco = solve(VISCO);
    let elastic = solve("law = \"mooney-rivlin\"\nc1 = 250.0\nc2 = 0.0\nkappa = 2e4");
    let tip = visco.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    assert!(tip > 1e-3, "the block stretches: {tip}");
    let diff = visco
        .iter()
        .zip(&elastic)
        .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
    assert!(diff <= 1e-9 * tip, "{diff:e} vs tip {tip:e}");
    // The instantaneous law (mu = 1e3) would stretch it about half as much.
    let stiff = solve("law = \"mooney-rivlin\"\nc1 = 500.0\nc2 = 0.0\nkappa = 2e4");
    let tip_stiff = stiff.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    assert!(tip_stiff < 0.6 * tip, "{tip_stiff} vs {tip}");
}

/// Final displacements of `steps` steps of the scenario `text`.
fn run_steps(text: &str, steps: usize) -> Vec<f64> {
    let sc = parse(text).unwrap();
    let mut st = sc.stepper().unwrap();
    for _ in 0..steps {
        st.advance().unwrap();
    }
    st.state().u.clone()
}

/// A grasp pulling the middle of the x = 0.02 face by 3 mm over 0.05 s and holding it, with `integrator`.
fn pulled(material: &str, integrator: &str, divisions: [usize; 3]) -> String {
    block(
        material,
        divisions,
        &format!(
            "[[displace]]\npoint = [0.02, 0.005, 0.005]\nradius = 0.004\ndisplacement = [0.003, 0.0, 0.0]\nmode = \"ramp\"\nduration = 0.05\n\
             [damping]\nalpha = 20.0\n[integrator]\n{integrator}\n[run]\nduration = 0.2"
        ),
    )
}

/// With every α = 0 the law is the elastic neo-Hookean (mooney-rivlin with c1 = μ/2, c2 = 0):
/// the same displacements, to the bit, after explicit, backward-Euler and BDF2 steps.
#[test]
fn zero_alpha_runs_are_the_elastic_neo_hookean_to_the_bit() {
    let visco =
        "law = \"neo-hookean-visco\"\nmu = 1e3\nkappa = 2e4\nprony = [[0.0, 0.05], [0.0, 0.5]]";
    let elastic = "law = \"mooney-rivlin\"\nc1 = 500.0\nc2 = 0.0\nkappa = 2e4";
    for (integrator, steps) in [
        ("method = \"symplectic-euler\"\ndt = 2e-4", 300),
        ("method = \"implicit-euler\"\ndt = 0.01", 8),
        ("method = \"bdf2\"\ndt = 0.01", 8),
    ] {
        let a = run_steps(&pulled(visco, integrator, [4, 2, 2]), steps);
        let b = run_steps(&pulled(elastic, integrator, [4, 2, 2]), steps);
        assert!(a.iter().any(|x| *x != 0.0));
        assert_eq!(a, b, "{integrator}");
    }
}

/// Backward Euler's Newton iteration uses the algorithmic tangent of the recurrence: with a
/// history from a few accepted steps of different strains, each element's tangent at a trial
/// state equals the central difference of the forces (step 1e-8 of the element size) within
/// 1e-6 of the tangent's largest entry.
#[test]
fn algorithmic_tangent_is_the_difference_of_the_step_forces() {
    let law = NeoHookeanVisco::new(
        1e3,
        2e4,
        vec![
            Prony {
                alpha: 0.3,
                tau: 0.05,
            },
            Prony {
                alpha: 0.2,
                tau: 0.5,
            },
        ],
    )
    .unwrap();
    let mesh = box_tets([0.02, 0.01, 0.01], [2, 1, 1], BoxPattern::Six).unwrap();
    let mut model = FemModel::new(&mesh, FemParams::new(Material::NeoHookeanVisco(law))).unwrap();
    let field = |s: f64| -> Vec<f64> {
        mesh.nodes
            .iter()
            .flat_map(|x| {
                [
                    s * (0.3 * x[0] + 0.1 * x[1] * x[1] / 0.01),
                    s * (-0.1 * x[1] + 0.05 * x[0]),
                    s * (0.08 * x[2] + 0.2 * x[0] * x[1] / 0.02),
                ]
            })
            .collect()
    };
    let dt = 0.02;
    for s in [0.5, 1.0, 0.7] {
        model.accept_step(&field(s), dt);
    }
    model.set_step(dt);
    let u = field(1.2);
    let n = u.len();
    let h = 1e-8 * 0.01;
    let mut k = vec![0.0; 144];
    let (mut rp, mut rm) = (vec![0.0; n], vec![0.0; n]);
    for e in 0..model.num_elements() {
        model.element_stiffness(e, &u, &mut k).unwrap();
        let scale = k.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        let nodes: Vec<usize> = model.element_nodes(e).iter().map(|&a| a as usize).collect();
        for (cb, &b) in nodes.iter().enumerate() {
            for kk in 0..3 {
                let (mut up, mut um) = (u.clone(), u.clone());
                up[3 * b + kk] += h;
                um[3 * b + kk] -= h;
                // The element's own forces: the reference pass restricted to it.
                element_forces(&model, e, &up, &mut rp);
                element_forces(&model, e, &um, &mut rm);
                for (ca, &a) in nodes.iter().enumerate() {
                    for i in 0..3 {
                        let fd = (rp[3 * a + i] - rm[3 * a + i]) / (2.0 * h);
                        let an = k[(3 * ca + i) * 12 + 3 * cb + kk];
                        assert!(
                            (fd - an).abs() <= 1e-6 * scale,
                            "element {e}, ({ca},{i})-({cb},{kk}): {an} vs {fd}"
                        );
                    }
                }
            }
        }
    }
}

/// The forces of element `e` alone at `u`, scattered into `r` (all nodes).
fn element_forces(model: &FemModel, e: usize, u: &[f64], r: &mut [f64]) {
    // The difference of the whole model's forces with and without the element is noisier
    // than the element's own; its tangent (the quantity tested) is the element's.
    let nodes = model.element_nodes(e);
    r.iter_mut().for_each(|x| *x = 0.0);
    let k = model.element_forces_of(e, u).unwrap();
    for (c, &a) in nodes.iter().enumerate() {
        for i in 0..3 {
            r[3 * a as usize + i] += k[3 * c + i];
        }
    }
}

/// Creep under a held load (small strain): a dead traction σ = 2 Pa on the x = 0.02 face,
/// applied at t = 0 and held, with one Prony term (α = 0.5, τ = 0.2 s), solved by backward
/// Euler at Δt = 5 ms. The axial strain follows the standard linear solid's creep,
///
/// ```text
/// ε(t) = σ/(9κ) + σ/3 J(t),   J(t) = 1/μ_∞ − (1/μ_∞ − 1/μ) e^(−t/τ_c),   τ_c = τ μ/μ_∞
/// ```
///
/// from the instantaneous compliance to the long-term one: from t = 0.1 s on, within 1.5 % of
/// the creep `ε(∞) − ε(0)` (the time discretisation of the scheme and the start's inertial
/// transient, damped by α = 200 1/s).
#[test]
fn creep_under_a_held_traction_approaches_the_long_term_compliance() {
    let (mu, kappa, alpha, tau, sigma) = (1e3, 2e4, 0.5, 0.2, 2.0);
    let mat = format!(
        "law = \"neo-hookean-visco\"\nmu = {mu:e}\nkappa = {kappa:e}\nprony = [[{alpha}, {tau}]]\ndensity = 100.0"
    );
    let text = block(
        &mat,
        [2, 1, 1],
        &format!(
            "[[traction]]\ngroup = \"xmax\"\ntraction = [{sigma:e}, 0.0, 0.0]\n\
             [damping]\nalpha = 200.0\n[integrator]\nmethod = \"implicit-euler\"\ndt = 5e-3\n\
             newton_tol = 1e-9\n[run]\nduration = 2.0"
        ),
    );
    let sc = parse(&text).unwrap();
    let tip = (0..sc.mesh.num_nodes())
        .find(|&a| (sc.mesh.nodes[a][0] - 0.02).abs() < 1e-12)
        .unwrap();
    let mut st = sc.stepper().unwrap();
    let mu_inf = mu * (1.0 - alpha);
    let tau_c = tau * mu / mu_inf;
    let eps = |t: f64| {
        sigma / (9.0 * kappa)
            + sigma / 3.0 * (1.0 / mu_inf - (1.0 / mu_inf - 1.0 / mu) * (-t / tau_c).exp())
    };
    let creep = eps(f64::INFINITY) - eps(0.0);
    let mut worst: f64 = 0.0;
    for n in 1..=400 {
        st.advance().unwrap();
        let t = n as f64 * 5e-3;
        if t >= 0.1 - 1e-9 {
            let got = st.state().u[3 * tip] / 0.02;
            worst = worst.max((got - eps(t)).abs() / creep);
        }
    }
    eprintln!(
        "creep: worst |ε − closed form| from t = 0.1 s: {worst:.4e} of the creep {creep:.4e}"
    );
    assert!(worst <= 0.015, "worst {worst:.4} of the creep");
}

/// The same bits on one and two threads: explicit and backward-Euler runs of a block of
/// 2592 tetrahedra (three blocks of the internal variables' parallel update).
#[test]
fn visco_runs_have_the_same_bits_on_one_and_two_threads() {
    for (integrator, steps) in [
        ("method = \"symplectic-euler\"\ndt = 1e-4", 40),
        ("method = \"implicit-euler\"\ndt = 0.01", 3),
    ] {
        let text = pulled(VISCO, integrator, [12, 6, 6]);
        let on = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| run_steps(&text, steps))
        };
        assert_eq!(on(1), on(2), "{integrator}");
    }
}

/// Checkpoints keep the internal variables (what the frame loop restores a rejected frame
/// from): steps taken after restoring a checkpoint are the same bits as those taken after
/// it was saved, on an explicit integrator and on backward Euler. Without the history in the
/// checkpoint the restored run relaxes from the later history and differs.
#[test]
fn a_restored_checkpoint_holds_the_visco_internal_variables() {
    use crate::integrate::Checkpoint;
    for (integrator, steps) in [
        ("method = \"symplectic-euler\"\ndt = 2e-4", 100),
        ("method = \"implicit-euler\"\ndt = 0.01", 3),
    ] {
        let sc = parse(&pulled(VISCO, integrator, [4, 2, 2])).unwrap();
        let mut st = sc.stepper().unwrap();
        for _ in 0..steps {
            st.advance().unwrap();
        }
        let mut cp = Checkpoint::default();
        st.save(&mut cp);
        let run = |st: &mut Box<dyn crate::integrate::Stepper>| {
            for _ in 0..steps {
                st.advance().unwrap();
            }
            st.state().u.clone()
        };
        let first = run(&mut st);
        st.restore(&cp);
        let again = run(&mut st);
        assert!(first.iter().any(|x| *x != 0.0));
        assert_eq!(first, again, "{integrator}");
    }
}

/// Creep in interactive frames (one frame = ten backward-Euler steps of 5 ms, the frame
/// clock's 50 ms): each frame's reference is the static equilibrium at the frame's internal
/// state (the stepper's viscous stresses held), which the heavily damped tissue follows
/// closely: every frame's lag is within 2 % of max |u*|. Against the fully relaxed
/// equilibrium (the reference a model without the stepper's history would solve) the early
/// frames would lag by up to a third (the compliance grows by μ/μ∞ = 2 here); the last
/// frame, 5 relaxation times on, is within 1e-2 of the closed form's long-term strain.
#[test]
fn interactive_creep_is_measured_against_the_frame_s_internal_state() {
    let (mu, kappa, alpha, tau, sigma) = (1e3, 2e4, 0.5, 0.1, 2.0);
    let mat = format!(
        "law = \"neo-hookean-visco\"\nmu = {mu:e}\nkappa = {kappa:e}\nprony = [[{alpha}, {tau}]]\ndensity = 100.0"
    );
    let text = block(
        &mat,
        [2, 1, 1],
        &format!(
            "[[traction]]\ngroup = \"xmax\"\ntraction = [{sigma:e}, 0.0, 0.0]\n\
             [damping]\nalpha = 200.0\n[integrator]\nmethod = \"implicit-euler\"\ndt = 5e-3\n\
             newton_tol = 1e-9\n[run]\nduration = 1.0\n\
             [interactive]\nfps = 20.0\ncycles = 10\npredictor = false"
        ),
    );
    let sc = parse(&text).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut replay = crate::runner::Replay::new(&sc, sc.stepper().unwrap()).unwrap();
    let s = crate::runner::run_frames(
        &sc,
        &mut replay,
        RunOptions {
            out_dir: Some(dir.path().to_path_buf()),
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!((s.frames, s.reference_failures), (20, 0));
    assert!(s.lag_rel_max <= 0.02, "worst lag {:.4}", s.lag_rel_max);
    let mu_inf = mu * (1.0 - alpha);
    let eps_inf = sigma / (9.0 * kappa) + sigma / (3.0 * mu_inf);
    let tip = (0..sc.mesh.num_nodes())
        .find(|&a| (sc.mesh.nodes[a][0] - 0.02).abs() < 1e-12)
        .unwrap();
    let got = replay.simulation().displacements()[3 * tip] / 0.02;
    assert!(
        (got - eps_inf).abs() <= 1e-2 * eps_inf,
        "{got} vs long-term {eps_inf}"
    );
}
