//! Scenario parsing, validation and short runs.

use super::spec::{defaults, Named};
use super::*;
use crate::error::Error;
use crate::fem::Precision;
use crate::integrate::Method;
use crate::material::Material;
use crate::material::StableNeoHookean;
use crate::multigrid::fas::{CoarseSolve, FasParams, Scaling, Smoother, TransferWeights};
use crate::runner::{run, RunOptions, StopReason};
use std::path::PathBuf;

const BASE: &str = r#"
[mesh]
generate = "rectangle"
size = [0.1, 0.1]
nodes = 60

[material]
law = "mooney-rivlin"
c1 = 1000.0
c2 = 1000.0

[[fix]]
boundary = true

[run]
duration = 0.01
"#;

/// A neo-Hookean cube of 4 × 4 × 4 boxes (0.04 m), held at z = 0; `extra` appended.
fn cube(extra: &str) -> String {
    format!(
        r#"
[mesh]
generate = "box"
size = [0.04, 0.04, 0.04]
divisions = [4, 4, 4]
[material]
law = "neo-hookean"
young = 5e3
poisson = 0.45
[[fix]]
plane = {{ point = [0, 0, 0], normal = [0, 0, 1] }}
{extra}
"#
    )
}

fn parse(text: &str) -> Result<Scenario> {
    Scenario::from_toml(text, Path::new("test.toml"))
}

/// The first `k` fields after the coordinates (ux, uy, uz, then the stress T row by row) of
/// every row of `out/nodal_stress.csv`, in file order.
fn nodal_stress(out: &Path, k: usize) -> Vec<f64> {
    std::fs::read_to_string(out.join("nodal_stress.csv"))
        .unwrap()
        .lines()
        .skip(1)
        .flat_map(|l| {
            l.split(',')
                .skip(4)
                .take(k)
                .map(|x| x.parse::<f64>().unwrap())
                .collect::<Vec<_>>()
        })
        .collect()
}

/// The scenario error message, asserting it names the file.
fn error_of(text: &str) -> String {
    let e = parse(text).expect_err("should fail");
    let s = e.to_string();
    assert!(
        s.starts_with("test.toml"),
        "error does not name the file: {s}"
    );
    s
}

#[test]
fn base_scenario_resolves_with_documented_defaults() {
    let sc = parse(BASE).unwrap();
    assert_eq!(sc.density, 1000.0);
    assert_eq!(sc.thickness, 1e-3);
    assert_eq!(sc.alpha, 0.0);
    assert_eq!(sc.integrator.method, Method::SymplecticEuler);
    assert!((sc.integrator.dt - 0.5 * sc.integrator.dt_critical_estimate).abs() < 1e-18);
    assert_eq!(sc.fixed.len(), sc.mesh.boundary_nodes().len());
    assert_eq!(sc.output.dir, PathBuf::from("raisov-out/test"));
    assert_eq!(sc.run.stop, StopRule::Duration(0.01));
}

/// `[integrator] precision`: default f64; "f32-storage" reaches the force model of a
/// neo-Hookean tetrahedral scenario, and a membrane scenario says it has no effect.
#[test]
fn precision_key_selects_the_storage_of_the_packed_path() {
    assert_eq!(parse(BASE).unwrap().precision, Precision::F64);
    let membrane = parse(&format!(
        "{BASE}\n[integrator]\nprecision = \"f32-storage\""
    ))
    .unwrap();
    assert_eq!(membrane.precision, Precision::F32Storage);
    assert!(
        membrane.notes.iter().any(|n| n.contains("runs in f64")),
        "{:?}",
        membrane.notes
    );
    let tets = BASE
        .replace(
            "generate = \"rectangle\"\nsize = [0.1, 0.1]\nnodes = 60",
            "generate = \"box\"\nsize = [0.1, 0.04, 0.04]\ndivisions = [5, 2, 2]",
        )
        .replace(
            "law = \"mooney-rivlin\"\nc1 = 1000.0\nc2 = 1000.0",
            "law = \"neo-hookean\"\nyoung = 5e4\npoisson = 0.4",
        );
    // The setting reaches the system's force model: different bits, within the tolerance.
    let mut forces = Vec::new();
    for (key, want) in [
        ("f64", Precision::F64),
        ("f32-storage", Precision::F32Storage),
    ] {
        let sc = parse(&format!("{tets}\n[integrator]\nprecision = \"{key}\"")).unwrap();
        assert_eq!(sc.precision, want);
        assert_eq!(sc.fem_params().precision, want);
        assert!(sc.notes.is_empty(), "{:?}", sc.notes);
        let mut sys = sc.build_system().unwrap();
        let n = sc.mesh.num_nodes();
        let u: Vec<f64> = (0..3 * n)
            .map(|i| 1e-4 * ((i * 7919 % 101) as f64 / 101.0 - 0.5))
            .collect();
        let mut r = vec![0.0; 3 * n];
        sys.force.internal_forces(&u, &mut r).unwrap();
        forces.push(r);
    }
    assert_ne!(
        forces[0], forces[1],
        "the precision did not reach the force model"
    );
    let scale = forces[0].iter().fold(0.0f64, |m, x| m.max(x.abs()));
    for (a, b) in forces[0].iter().zip(&forces[1]) {
        assert!((a - b).abs() <= 1e-6 * scale);
    }
}

#[test]
fn every_error_path_names_the_problem() {
    let cases: Vec<(String, &str)> = vec![
        (BASE.replace("nodes = 60", "nodes = 60\ncolour = 3"), "unknown field `colour`"),
        (BASE.replace("law = \"mooney-rivlin\"", "law = \"jelly\""), "valid are \"stvk\""),
        (BASE.replace("c2 = 1000.0", ""), "needs `c2`"),
        (BASE.replace("c2 = 1000.0", "c2 = 1000.0\nyoung = 3.0"), "`young` is not a parameter"),
        (BASE.replace("c2 = 1000.0", "c2 = 1000.0\nkappa = 3.0"), "`kappa` is not used by membranes"),
        (BASE.replace("size = [0.1, 0.1]", "size = [0.1, -0.1]"), "need 2 positive lengths"),
        (BASE.replace("generate = \"rectangle\"", "generate = \"sphere\""), "valid are \"rectangle\""),
        (BASE.replace("generate = \"rectangle\"\nsize = [0.1, 0.1]\nnodes = 60", "file = \"missing.msh\""), "missing.msh"),
        (BASE.replace("nodes = 60", "nodes = 4000000000"), "`mesh.generate` = \"rectangle\": invalid parameter `nodes`: 4000000000 exceeds the maximum"),
        (BASE.replace("duration = 0.01", "duration = -1.0"), "must be a positive number"),
        (BASE.replace("duration = 0.01", ""), "`duration` (s) is required"),
        (BASE.replace("duration = 0.01", "duration = 1.0\nstop = \"never\""), "valid are \"duration\", \"steady\""),
        (BASE.replace("boundary = true", "group = \"walls\""), "no group \"walls\""),
        (BASE.replace("boundary = true", "nodes = [100000]"), "does not exist"),
        (BASE.replace("boundary = true", "boundary = true\npoint = [0.0, 0.0, 0.0]"), "exactly one selector"),
        (BASE.replace("boundary = true", "box = { min = [1.0, 1.0, 1.0], max = [2.0, 2.0, 2.0] }"), "contains no node"),
        (format!("{BASE}\n[integrator]\nmethod = \"leapfrog\""), "`integrator.method` = \"leapfrog\": valid are \"forward-euler\", \"symplectic-euler\", \"rk4\", \"central-difference\""),
        (format!("{BASE}\n[integrator]\ndt = 0.0"), "`integrator.dt`"),
        (format!("{BASE}\n[integrator]\nprecision = \"f16\""), "`integrator.precision` = \"f16\": valid are \"f64\", \"f32-storage\""),
        (format!("{BASE}\n[damping]\nalpha = 1.0\nratio = 1.0"), "not a mix"),
        (format!("{BASE}\n[[displace]]\npoint = [0.0, 0.0, 0.0]\nmode = \"ramp\"\ndisplacement = [0.0, 0.0, 0.01]"), "needs `duration`"),
        (format!("{BASE}\n[[displace]]\npoint = [0.0, 0.0, 0.0]\ntable = [[1.0, 0, 0, 0], [0.5, 0, 0, 1]]"), "times must increase"),
        (format!("{BASE}\n[[displace]]\npoint = [0.0, 0.0, 0.0]\nmode = \"wiggle\"\ndisplacement = [0.0, 0.0, 0.01]"), "valid are \"held\""),
        (format!("{BASE}\n[output]\ncsv_every = 0"), "csv_every"),
        (format!("{BASE}\n[output]\nvtu = \"hdf5\""), "`output.vtu` = \"hdf5\": valid are \"binary\", \"ascii\""),
        (format!("{BASE}\n[output]\nreference = \"nowhere.csv\""), "no such file"),
        (BASE.replace("[mesh]", "[mesh]\nfile = \"x.msh\""), "either `file` or `generate`"),
        ("[mesh\n".to_string(), "test.toml, line 1"),
        (format!("{BASE}\n[multigrid]\nscheme = \"w-cycle\"\nlevels = 2"), "valid are \"fas\""),
        (format!("{BASE}\n[multigrid]\nlevels = 2\nfiles = [\"a.msh\"]"), "not both"),
        (format!("{BASE}\n[multigrid]\nscheme = \"fas\""), "give `levels`"),
        (format!("{BASE}\n[multigrid]\nlevels = 2\nratio = 2.0"), "must be in (0, 1)"),
        (format!("{BASE}\n[multigrid]\nlevels = 2\nsmoother = \"gauss\""), "valid are \"chebyshev\""),
        (format!("{BASE}\n[multigrid]\nlevels = 2\ncoarse_iterations = 0"), "`multigrid.coarse_iterations` = 0: give at least 1"),
        (format!("{BASE}\n[multigrid]\nlevels = 2\ncoarse = \"newton\"\ncoarse_iterations = 9"), "coarse = \"chebyshev\" only"),
    ];
    for (text, want) in cases {
        let msg = error_of(&text);
        assert!(msg.contains(want), "expected `{want}` in: {msg}");
    }
}

#[test]
fn unknown_key_error_gives_the_line() {
    let text = BASE.replace("nodes = 60", "nodes = 60\ncolour = 3");
    let line = text.lines().position(|l| l.starts_with("colour")).unwrap() + 1;
    match parse(&text).unwrap_err() {
        Error::Scenario { line: Some(l), .. } => assert_eq!(l, line),
        e => panic!("unexpected {e}"),
    }
}

#[test]
fn the_builtin_and_example_scenarios_resolve() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples");
    for f in [
        "membrane_lift.toml",
        "membrane_lift_multigrid.toml",
        "membrane_drape.toml",
        "membrane_drape_multigrid.toml",
        "liver_interactive.toml",
        "liver_frames.toml",
        "cantilever.toml",
        "liver_grasp.toml",
        "visco_block.toml",
    ] {
        let p = Path::new(dir).join(f);
        let sc = Scenario::load(&p).unwrap_or_else(|e| panic!("{f}: {e}"));
        assert!(sc.integrator.dt > 0.0 && sc.mesh.num_nodes() > 100, "{f}");
    }
}

/// The draping membrane settles: kinetic energy and residual fall to the steady tolerances
/// and the sag is downward, symmetric and of the size the material implies.
#[test]
fn draping_membrane_settles() {
    let body = BASE.replace("nodes = 60", "nodes = 120").replace(
        "[run]\nduration = 0.01",
        "[run]\nstop = \"steady\"\nduration = 3.0\nkinetic_tol = 1e-10\nresidual_tol = 1e-6",
    );
    let text =
        format!("gravity = [0.0, 0.0, -9.81]\n{body}\n[damping]\nratio = 1.0\nomega = 177.7\n");
    let sc = parse(&text).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let sum = run(
        &sc,
        RunOptions {
            out_dir: Some(dir.path().to_path_buf()),
            progress: None,
            stop: None,
            in_memory: false,
        },
    )
    .unwrap();
    assert_eq!(sum.reason, StopReason::Steady, "{sum}");
    let sag = sum.last.max_u;
    // Membrane theory for this material: a sag of order 2 cm (see examples/membrane_drape.toml).
    assert!((0.01..0.04).contains(&sag), "sag {sag}");
    assert!(dir.path().join("measures.csv").is_file());
    assert!(dir.path().join("test.pvd").is_file());
    let pvd = std::fs::read_to_string(dir.path().join("test.pvd")).unwrap();
    assert!(pvd.contains("frames/test_000000.vtu"));
}

/// Frames hold the reference points and the displacement (binary by default, ASCII on
/// request), and the displacement read back is the run's.
#[test]
fn frames_hold_reference_points_and_displacement() {
    for (extra, format) in [
        ("", "vtu appended zlib"),
        ("[output]\nvtu = \"ascii\"\n", "vtu ascii"),
    ] {
        let sc = parse(&format!("gravity = [0.0, 0.0, -9.81]\n{BASE}\n{extra}")).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let sum = run(
            &sc,
            RunOptions {
                out_dir: Some(dir.path().to_path_buf()),
                progress: None,
                stop: None,
                in_memory: false,
            },
        )
        .unwrap();
        let frames: Vec<_> = std::fs::read_dir(dir.path().join("frames"))
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        let last = frames.iter().max().unwrap();
        let l = crate::io::load_mesh(last).unwrap();
        assert_eq!(l.format, format);
        assert_eq!(l.mesh.nodes, sc.mesh.nodes, "reference points");
        let (k, u) = crate::io::read_vtu_array(last, "displacement").unwrap();
        assert_eq!(k, 3);
        let max_u = u
            .chunks(3)
            .map(|d| crate::mesh::norm([d[0], d[1], d[2]]))
            .fold(0.0, f64::max);
        assert_eq!(max_u, sum.last.max_u);
        assert!(max_u > 0.0);
    }
}

/// A run that blows up stops with a message naming step, time and cause, and leaves finite
/// measures on disk.
#[test]
fn diverging_run_stops_and_says_where() {
    let text = format!("{BASE}\n[integrator]\nmethod = \"symplectic-euler\"\ndt = 0.01\n[[displace]]\npoint = [0.0, 0.0, 0.0]\ndisplacement = [0.0, 0.0, 0.03]\n");
    let text = text.replace("duration = 0.01", "duration = 5.0");
    let sc = parse(&text).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let e = run(
        &sc,
        RunOptions {
            out_dir: Some(dir.path().to_path_buf()),
            progress: None,
            stop: None,
            in_memory: false,
        },
    )
    .unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, Error::Diverged(_)), "{msg}");
    assert!(
        msg.contains("diverged at t = ") && msg.contains("step"),
        "{msg}"
    );
    let csv = std::fs::read_to_string(dir.path().join("measures.csv")).unwrap();
    assert!(
        !csv.contains("NaN") && !csv.contains("inf"),
        "non-finite values written"
    );
}

/// `pick_level` meshes only the chosen level of a generated membrane: the same mesh, bit for
/// bit, as that level of `level_meshes`, chosen from the requested counts; with a function
/// that picks none, no level and no mesh.
#[test]
fn pick_level_meshes_the_chosen_generated_level_alone() {
    let text = BASE.replace("nodes = 60", "nodes = 2000")
        + "\n[multigrid]\nscheme = \"fas\"\nlevels = 6\n";
    let sc = parse(&text).unwrap();
    let all = sc.level_meshes().unwrap();
    let super::PickedLevel {
        counts,
        requested,
        chosen,
    } = sc.pick_level(crate::statics::newton::coarse_level).unwrap();
    assert_eq!(counts, vec![2000, 1000, 500, 250, 125, 63]);
    assert!(
        requested,
        "generated levels are chosen by their requested counts"
    );
    let (i, mesh) = chosen.unwrap();
    assert_eq!(i, 4, "1/16 of 2000 requested nodes is level 4's 125");
    assert_eq!(mesh.nodes, all[i].nodes);
    assert_eq!(mesh.num_elements(), all[i].num_elements());
    // The meshed counts are the requested ones within the mesher's few nodes: level 4 here
    // has 124 of 1983 nodes, one node over 1/16, where the requested 125 of 2000 is 1/16.
    for (m, want) in all.iter().zip(&counts) {
        let rel = (m.num_nodes() as f64 - *want as f64).abs() / *want as f64;
        assert!(
            rel < 0.02,
            "{} nodes meshed for {want} requested",
            m.num_nodes()
        );
    }
    assert!(sc.pick_level(|_| None).unwrap().chosen.is_none());
}

#[test]
fn level_nodes_gives_each_generated_level_its_node_count() {
    let text = format!(
        "{}\n[multigrid]\nscheme = \"fas\"\nlevel_nodes = [60, 33, 17]\n",
        BASE
    );
    let sc = parse(&text).unwrap();
    assert_eq!(sc.num_levels(), 3);
    let meshes = sc.level_meshes().unwrap();
    let counts: Vec<usize> = meshes.iter().map(|m| m.num_nodes()).collect();
    assert_eq!(counts.len(), 3);
    for (got, want) in counts.iter().zip([60usize, 33, 17]) {
        let rel = (*got as f64 - want as f64).abs() / want as f64;
        assert!(rel < 0.25, "level with target {want} nodes has {got}");
    }
    assert!(counts[0] > counts[1] && counts[1] > counts[2]);
    // Level 0 must be the [mesh] count; not with files or ratio.
    let bad = format!("{BASE}\n[multigrid]\nlevel_nodes = [50, 25]\n");
    assert!(error_of(&bad).contains("level_nodes[0]"));
    let bad = format!("{BASE}\n[multigrid]\nlevel_nodes = [60, 30]\nratio = 0.5\n");
    assert!(error_of(&bad).contains("level_nodes"));
}

/// The 0.1 x 0.04 x 0.04 m box of `divisions` cells (5 tets per cube), written to `path` as
/// Gmsh 2.2.
fn write_box(path: &Path, divisions: [usize; 3]) -> Mesh {
    let m = crate::mesh::generate::box_tets(
        [0.1, 0.04, 0.04],
        divisions,
        crate::mesh::generate::BoxPattern::Five,
    )
    .unwrap();
    crate::io::write_msh22(path, &m).unwrap();
    m
}

/// `[mesh] renumber` (the default for files) reorders the nodes in memory and nothing a user
/// sees. On a box whose node ids are shuffled, as mesh generators leave them: the same nodes
/// are fixed and loaded by file id, every file node moves as in the run that keeps the file's
/// order (to round-off: the force sums run in another order), `nodal_stress.csv` lists the
/// nodes in file order with their file positions, and reads back to the same stress.
#[test]
fn renumbered_file_mesh_moves_like_the_file_order() {
    use crate::mesh::generate::{box_tets, BoxPattern};
    let dir = tempfile::tempdir().unwrap();
    let mut m = box_tets([0.1, 0.04, 0.04], [10, 4, 4], BoxPattern::Five).unwrap();
    let n = m.num_nodes();
    m.renumber(&crate::mesh::tests::shuffled_order(n));
    crate::io::write_msh22(&dir.path().join("shuffled.msh"), &m).unwrap();
    let fixed: Vec<u32> = (0..n as u32)
        .filter(|&a| m.nodes[a as usize][0] == 0.0)
        .collect();
    let tip = m.nearest_node([0.1, 0.0, 0.0]).unwrap();
    // The scenario names nodes as the file does: Gmsh ids, from 1.
    let fixed_ids: Vec<u64> = fixed.iter().map(|&a| a as u64 + 1).collect();
    let tip_id = tip as u64 + 1;
    let scenario = |renumber: bool| {
        let text = format!(
            "[mesh]\nfile = \"shuffled.msh\"\nrenumber = {renumber}\n[material]\nlaw = \"neo-hookean\"\nyoung = 5e4\npoisson = 0.4\n[[fix]]\nnodes = {fixed_ids:?}\n[[load]]\nat = {{ nodes = [{tip_id}] }}\nforce = [0.0, -0.05, 0.0]\n[run]\nduration = 0.003\n[output]\nframe_interval = 0.0\n"
        );
        Scenario::from_toml(&text, &dir.path().join(format!("r{renumber}.toml"))).unwrap()
    };
    let (sr, sf) = (scenario(true), scenario(false));
    let ids = sr
        .file_ids
        .clone()
        .expect("files are renumbered by default");
    assert!(sf.file_ids.is_none());
    assert_ne!(ids, (0..n as u32).collect::<Vec<_>>());
    for (k, &a) in ids.iter().enumerate() {
        assert_eq!(sr.mesh.nodes[k], m.nodes[a as usize]);
    }
    let mut fixed_r: Vec<u64> = sr.fixed.iter().map(|&a| sr.file_node(a)).collect();
    fixed_r.sort_unstable();
    assert_eq!(fixed_r, fixed_ids);
    assert_eq!(sr.loads.len(), 1);
    assert_eq!(sr.file_node(sr.loads[0].0), tip_id);
    // The same motion, node by node in file order.
    let state = |sc: &Scenario| {
        let mut st = sc.stepper().unwrap();
        for _ in 0..200 {
            st.advance().unwrap();
        }
        st.finest().1.u.clone()
    };
    let (ur, uf) = (state(&sr), state(&sf));
    let scale = uf.iter().fold(0.0f64, |a, &x| a.max(x.abs()));
    assert!(scale > 1e-6, "the load moves the box: {scale}");
    for (k, &a) in ids.iter().enumerate() {
        for d in 0..3 {
            let (x, y) = (ur[3 * k + d], uf[3 * a as usize + d]);
            assert!((x - y).abs() <= 1e-9 * scale, "file node {a}: {x} vs {y}");
        }
    }
    // nodal_stress.csv: file order, file positions, same stress as the file-order run.
    let csv = |sc: &Scenario, sub: &str| {
        let out = dir.path().join(sub);
        run(
            sc,
            RunOptions {
                out_dir: Some(out.clone()),
                progress: None,
                stop: None,
                in_memory: false,
            },
        )
        .unwrap();
        out.join("nodal_stress.csv")
    };
    let (pr, pf) = (csv(&sr, "r"), csv(&sf, "f"));
    let columns = |p: &Path| -> Vec<String> {
        std::fs::read_to_string(p)
            .unwrap()
            .lines()
            .map(|l| l.split(',').take(4).collect::<Vec<_>>().join(","))
            .collect()
    };
    assert_eq!(columns(&pr), columns(&pf), "node ids and positions per row");
    let tr = read_nodal_stress(&pr, &sr).unwrap();
    let tf = read_nodal_stress(&pf, &sf).unwrap();
    let tscale = tf.iter().fold(0.0f64, |a, &x| a.max(x.abs()));
    assert!(tscale > 0.0);
    for (k, &a) in ids.iter().enumerate() {
        for q in 0..9 {
            let (x, y) = (tr[9 * k + q], tf[9 * a as usize + q]);
            assert!((x - y).abs() <= 1e-7 * tscale, "file node {a}: {x} vs {y}");
        }
    }
}

/// A `nodes = [..]` selector beyond the file's node count names the file's range, whether or
/// not the mesh is renumbered.
#[test]
fn node_selector_out_of_range_names_the_file_range() {
    let dir = tempfile::tempdir().unwrap();
    let n = write_box(&dir.path().join("b.msh"), [4, 2, 2]).num_nodes();
    for renumber in [true, false] {
        let text = format!(
            "[mesh]\nfile = \"b.msh\"\nrenumber = {renumber}\n[material]\nlaw = \"neo-hookean\"\nyoung = 5e4\npoisson = 0.4\n[[fix]]\nnodes = [{n}, 0]\n[run]\nduration = 0.01\n"
        );
        let e = Scenario::from_toml(&text, &dir.path().join("s.toml"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("fix[0].nodes: node 0 does not exist")
                && e.contains(&format!("b.msh run 1..={n}")),
            "{e}"
        );
    }
}

/// Under the FAS multigrid (the default scheme) files are renumbered too, level files
/// included, and the results follow the file's numbering, not the one in memory. FAS
/// estimates each level's `λ_max` by power iteration from a start vector that was laid out
/// in memory order, and with a fixed budget of cycles per step its results followed that
/// estimate: renumbering the liver levels moved the interactive example's mean lag from 2.0
/// to 2.4 mm, and on this test's box the displacements after 4 steps moved by 2.4e-4 of their
/// size. The start vector is now keyed by the file's node ids
/// ([`crate::multigrid::Level::node_keys`]): on shuffled files, renumbered and file-order
/// runs agree to round-off (asserted within 1e-8).
#[test]
fn fas_on_renumbered_files_follows_the_file_order_run() {
    use crate::mesh::generate::{box_tets, BoxPattern};
    let dir = tempfile::tempdir().unwrap();
    let shuffled = |name: &str, d: [usize; 3]| {
        let mut m = box_tets([0.1, 0.04, 0.04], d, BoxPattern::Five).unwrap();
        m.renumber(&crate::mesh::tests::shuffled_order(m.num_nodes()));
        crate::io::write_msh22(&dir.path().join(name), &m).unwrap();
        m
    };
    let fine = shuffled("b.msh", [10, 4, 4]);
    let coarse = shuffled("c.msh", [5, 2, 2]);
    let tip = fine.nearest_node([0.1, 0.0, 0.0]).unwrap() + 1; // Gmsh ids from 1
    let resolve = |mesh_extra: &str| {
        let text = format!(
            "[mesh]\nfile = \"b.msh\"\n{mesh_extra}\n[material]\nlaw = \"neo-hookean\"\nyoung = 5e4\npoisson = 0.4\n[[fix]]\nplane = {{ point = [0.0, 0.0, 0.0], normal = [1.0, 0.0, 0.0] }}\n[[load]]\nat = {{ nodes = [{tip}] }}\nforce = [0.0, -0.05, 0.0]\n[run]\nduration = 0.01\n[multigrid]\nfiles = [\"c.msh\"]\n"
        );
        Scenario::from_toml(&text, &dir.path().join("s.toml")).unwrap()
    };
    let (sr, sf) = (resolve(""), resolve("renumber = false"));
    let ids = sr.file_ids.clone().expect("FAS renumbers files by default");
    assert!(sf.file_ids.is_none());
    // The level file follows `[mesh] renumber`.
    let level1 = |sc: &Scenario| sc.level_meshes().unwrap()[1].nodes.clone();
    assert_ne!(level1(&sr), coarse.nodes);
    assert_eq!(level1(&sf), coarse.nodes);
    let state = |sc: &Scenario| {
        let mut st = sc.stepper().unwrap();
        for _ in 0..4 {
            st.advance().unwrap();
        }
        st.finest().1.u.clone()
    };
    let (ur, uf) = (state(&sr), state(&sf));
    let scale = uf.iter().fold(0.0f64, |a, &x| a.max(x.abs()));
    assert!(scale > 1e-6, "the load moves the box: {scale}");
    let mut worst = 0.0f64;
    for (k, &a) in ids.iter().enumerate() {
        for d in 0..3 {
            worst = worst.max((ur[3 * k + d] - uf[3 * a as usize + d]).abs());
        }
    }
    eprintln!("renumbered FAS: {:.2e} of the motion", worst / scale);
    assert!(
        worst <= 1e-8 * scale,
        "renumbered FAS off by {:.2e} of the motion",
        worst / scale
    );
}

/// The 1-based line of the first line of `text` that starts with `prefix`.
fn line_of(text: &str, prefix: &str) -> usize {
    text.lines()
        .position(|l| l.starts_with(prefix))
        .unwrap_or_else(|| panic!("no line `{prefix}`"))
        + 1
}

/// Every key that names one of a few values rejects any other with a message that names
/// the key, its line and the valid values.
#[test]
fn every_enumerated_key_rejects_an_unknown_value_naming_key_line_and_valid_values() {
    let mg = "[multigrid]\nlevels = 2\n";
    let paper = "[multigrid]\nscheme = \"raisov-paper\"\nlevels = 2\n";
    let cases: Vec<(String, &str, &str)> = vec![
        (BASE.replace("generate = \"rectangle\"", "generate = \"bogus\""), "mesh.generate", "\"rectangle\", \"polygon\", \"box\""),
        (BASE.replace("law = \"mooney-rivlin\"", "law = \"bogus\""), "material.law", "\"stvk\", \"neo-hookean\", \"mooney-rivlin\", \"veronda-westmann\", \"stable-neo-hookean\", \"ti-neo-hookean\", \"hgo\", \"neo-hookean-visco\""),
        (format!("{BASE}\n[[displace]]\npoint = [0.0, 0.0, 0.0]\ndisplacement = [0.0, 0.0, 0.01]\nmode = \"bogus\""), "displace[0].mode", "\"held\", \"ramp\", \"table\""),
        (format!("{BASE}\n[integrator]\nmethod = \"bogus\""), "integrator.method", "\"forward-euler\", \"symplectic-euler\", \"rk4\", \"central-difference\", \"newton\", \"implicit-euler\", \"bdf2\""),
        (format!("{BASE}\n[integrator]\nprecision = \"bogus\""), "integrator.precision", "\"f64\", \"f32-storage\""),
        (BASE.replace("duration = 0.01", "duration = 0.01\nstop = \"bogus\""), "run.stop", "\"duration\", \"steady\""),
        (format!("{BASE}\n[multigrid]\nscheme = \"bogus\"\nlevels = 2"), "multigrid.scheme", "\"fas\", \"raisov-paper\", \"newton\""),
        (format!("{BASE}\n{paper}reading = \"bogus\""), "multigrid.reading", "\"paper\", \"correction\""),
        (format!("{BASE}\n{mg}smoother = \"bogus\""), "multigrid.smoother", "\"chebyshev\", \"dynamics\""),
        (format!("{BASE}\n{mg}coarse = \"bogus\""), "multigrid.coarse", "\"chebyshev\", \"explicit\", \"newton\""),
        (format!("{BASE}\n{mg}scaling = \"bogus\""), "multigrid.scaling", "\"fictitious\", \"mass\""),
        (format!("{BASE}\n{mg}transfer = \"bogus\""), "multigrid.transfer", "\"convex\", \"exact\", \"convex-restriction\""),
        (format!("{BASE}\n{mg}accelerate = \"bogus\""), "multigrid.accelerate", "\"cg\", \"none\""),
        (format!("{BASE}\n{mg}level_methods = [\"rk4\", \"bogus\"]"), "multigrid.level_methods[1]", "\"forward-euler\", \"symplectic-euler\", \"rk4\", \"central-difference\""),
        (format!("{BASE}\n[interactive]\nreference = \"bogus\""), "interactive.reference", "\"newton\", \"none\""),
    ];
    for (text, key, valid) in cases {
        let msg = error_of(&text);
        let line = text.lines().position(|l| l.contains("\"bogus\"")).unwrap() + 1;
        let want = format!("test.toml, line {line}: `{key}` = \"bogus\": valid are {valid}");
        assert_eq!(msg, want);
    }
    // The box pattern is a number.
    let text = BASE.replace(
        "generate = \"rectangle\"\nsize = [0.1, 0.1]\nnodes = 60",
        "generate = \"box\"\nsize = [0.1, 0.04, 0.04]\ndivisions = [5, 2, 2]\npattern = 7",
    );
    let line = line_of(&text, "pattern");
    assert_eq!(
        error_of(&text),
        format!("test.toml, line {line}: `mesh.pattern` = 7: valid are 5 or 6 tets per cube")
    );
    // A value of the wrong type names the key too.
    let text = format!("{BASE}\n[integrator]\nmethod = 4");
    let msg = error_of(&text);
    assert!(msg.contains("`integrator.method`: invalid type"), "{msg}");
    // Unknown keys name their table.
    let text = format!("{BASE}\n[integrator]\nmethd = \"rk4\"");
    let msg = error_of(&text);
    assert!(
        msg.contains("`integrator`: unknown field `methd`, expected one of `method`"),
        "{msg}"
    );
}

/// The spellings are typed once: the alias of St Venant-Kirchhoff, and each named value
/// reads back as itself.
#[test]
fn named_values_read_back() {
    fn round_trip<T: Named + PartialEq + std::fmt::Debug>() {
        for &v in T::ALL {
            assert_eq!(T::from_name(v.name()), Some(v));
        }
        assert_eq!(T::from_name("bogus"), None);
    }
    round_trip::<Method>();
    round_trip::<Precision>();
    round_trip::<Scaling>();
    round_trip::<TransferWeights>();
    round_trip::<crate::multigrid::raisov::Reading>();
    round_trip::<spec::Law>();
    round_trip::<SchemeKind>();
    assert_eq!(
        spec::Law::from_name("st-venant-kirchhoff"),
        Some(spec::Law::StVenantKirchhoff)
    );
}

/// `nan` and `inf` anywhere are errors naming the key and its line.
#[test]
fn non_finite_numbers_are_errors_naming_the_key() {
    let cases: Vec<(String, &str, &str)> = vec![
        (format!("{BASE}\n[integrator]\ndt = nan"), "integrator.dt", "dt = nan"),
        (format!("gravity = [0.0, 0.0, -inf]\n{BASE}"), "gravity[2]", "gravity"),
        (BASE.replace("c1 = 1000.0", "c1 = inf"), "material.c1", "c1 = inf"),
        (BASE.replace("boundary = true", "box = { min = [0.0, 0.0, 0.0], max = [nan, 1.0, 1.0] }"), "fix[0].box.max[0]", "box ="),
        (format!("{BASE}\n[[load]]\nat = {{ boundary = true }}\nforce = [0.0, +inf, 0.0]"), "load[0].force[1]", "force"),
        (format!("{BASE}\n[[displace]]\npoint = [0.0, 0.0, 0.0]\ntable = [[0.0, 0, 0, 0], [1.0, 0, 0, -nan]]"), "displace[0].table[1][3]", "table"),
        (format!("{BASE}\n[multigrid]\nscheme = \"raisov-paper\"\nlevels = 2\nepsilon = inf"), "multigrid.epsilon", "epsilon"),
        (format!("{BASE}\n[interactive]\nfps = inf"), "interactive.fps", "fps"),
    ];
    for (text, key, at) in cases {
        let line = line_of(&text, at);
        assert_eq!(
            error_of(&text),
            format!("test.toml, line {line}: `{key}`: numbers must be finite (not nan or inf)")
        );
    }
}

/// `name` names files under the output directory: nothing that would reach outside it, hide,
/// hold a newline or overflow a file name; each refusal states the rule.
#[test]
fn names_that_would_write_outside_the_output_directory_are_errors() {
    let long = "a".repeat(300);
    for bad in [
        "../up", "a/b", "a\\\\b", "..", ".", "", "/abs", "a\\nb", &long,
    ] {
        let msg = error_of(&format!("name = \"{bad}\"\n{BASE}"));
        assert!(
            msg.contains("`name`") && msg.contains(crate::io::NAME_RULE),
            "{bad}: {msg}"
        );
    }
    let sc = parse(&format!("name = \"drape-2.v1\"\n{BASE}")).unwrap();
    assert_eq!(sc.output.dir, PathBuf::from("raisov-out/drape-2.v1"));
}

/// Without `name`, a file stem outside the rule becomes a valid name, with a note.
#[test]
fn a_stem_outside_the_name_rule_becomes_a_valid_default_name() {
    let sc = Scenario::from_toml(BASE, Path::new("my liver (2).toml")).unwrap();
    assert_eq!(sc.name, "my_liver__2_");
    assert!(
        sc.notes.iter().any(|n| n.contains("\"my liver (2)\"")),
        "{:?}",
        sc.notes
    );
    let sc = parse(BASE).unwrap();
    assert_eq!(sc.name, "test");
    assert!(!sc.notes.iter().any(|n| n.contains("`name`")));
}

/// Keys of one multigrid scheme, coarse solve or motion mode are errors with another.
#[test]
fn keys_of_another_setting_are_errors() {
    let cases: Vec<(String, &str)> = vec![
        (format!("{BASE}\n[multigrid]\nlevels = 2\nepsilon = 1e-4"), "`multigrid.epsilon` applies to scheme = \"raisov-paper\" only"),
        (format!("{BASE}\n[multigrid]\nscheme = \"raisov-paper\"\nlevels = 2\npre_smooth = 2"), "`multigrid.pre_smooth` applies to scheme = \"fas\" only"),
        (format!("{BASE}\n[multigrid]\nlevels = 2\ncoarse_time = 0.2"), "`multigrid.coarse_time` applies to coarse = \"explicit\" only"),
        (format!("{BASE}\n[multigrid]\nfiles = [\"a.msh\"]\nratio = 0.5"), "`multigrid.ratio` applies to generated levels"),
        (format!("{BASE}\n[[displace]]\npoint = [0.0, 0.0, 0.0]\ndisplacement = [0.0, 0.0, 0.01]\nduration = 1.0"), "`duration` does not apply to mode = \"held\""),
        (BASE.replace("nodes = 60", "nodes = 60\npattern = 5"), "`pattern` does not apply to generate = \"rectangle\""),
        (BASE.replace("duration = 0.01", "duration = 0.01\nkinetic_tol = 1e-3"), "`run.kinetic_tol` applies to stop = \"steady\""),
    ];
    for (text, want) in cases {
        let msg = error_of(&text);
        assert!(msg.contains(want), "expected `{want}` in: {msg}");
    }
}

/// The resolved multigrid settings: the FAS defaults are `FasParams::default()`, the keys
/// reach their fields, raisov-paper's ε defaults to 1e-3 of the shortest edge.
#[test]
fn multigrid_settings_resolve_to_typed_parameters() {
    let fas = |extra: &str| {
        let sc = parse(&format!("{BASE}\n[multigrid]\nlevels = 3\n{extra}")).unwrap();
        let mg = sc.multigrid.clone().unwrap();
        assert_eq!(mg.methods, vec![sc.integrator.method; 3]);
        assert_eq!(sc.num_levels(), 3);
        match mg.scheme {
            Scheme::Fas(p) => p,
            s => panic!("{s:?}"),
        }
    };
    assert_eq!(fas(""), FasParams::default());
    let p = fas("smoother = \"chebyshev\"\nscaling = \"mass\"\ntransfer = \"exact\"\naccelerate = \"none\"\ncoarse = \"explicit\"\ncoarse_time = 0.2\npre_smooth = 2\npost_smooth = 3");
    assert!(matches!(
        p.smoother,
        Smoother::Chebyshev {
            scaling: Scaling::Mass,
            ..
        }
    ));
    assert_eq!(p.weights, TransferWeights::Exact);
    assert!(!p.krylov);
    assert_eq!(p.coarse, CoarseSolve::Explicit { time: 0.2 });
    assert_eq!((p.pre_smooth, p.post_smooth), (2, 3));
    assert_eq!(
        fas("coarse = \"newton\"").coarse,
        CoarseSolve::Newton {
            rel_tol: defaults::COARSE_NEWTON_TOL
        }
    );
    assert_eq!(fas("smoother = \"dynamics\"").smoother, Smoother::Dynamics);
    let sc = parse(&format!(
        "{BASE}\n[multigrid]\nscheme = \"raisov-paper\"\nlevels = 2\nreading = \"paper\""
    ))
    .unwrap();
    match sc.multigrid.as_ref().unwrap().scheme {
        Scheme::RaisovPaper(p) => {
            assert_eq!(p.reading, crate::multigrid::raisov::Reading::Paper);
            assert_eq!(p.epsilon, 1e-3 * sc.mesh.edge_range().0);
            // The code door's defaults are the scenario's.
            let code = crate::multigrid::raisov::RaisovParams::for_mesh(&sc.mesh);
            assert_eq!(p.epsilon, code.epsilon);
        }
        s => panic!("{s:?}"),
    }
}

/// Every default the module documentation of `spec` states is the one the code applies:
/// the constants of `spec::defaults` and `FasParams::default()`.
#[test]
fn documented_defaults_are_the_applied_ones() {
    let doc: Vec<&str> = include_str!("spec.rs")
        .lines()
        .take_while(|l| l.starts_with("//!"))
        .map(|l| l.trim_start_matches("//!"))
        .collect();
    // The documentation of `key` in `[table]`: its line and the comment lines under it.
    let entry = |table: &str, key: &str| -> String {
        let start = doc
            .iter()
            .position(|l| l.starts_with(&format!(" [{table}]")))
            .unwrap_or_else(|| panic!("no [{table}]"));
        let at = doc[start..]
            .iter()
            .position(|l| l.starts_with(&format!(" {key} =")))
            .unwrap_or_else(|| panic!("no {table}.{key}"))
            + start;
        let mut text = doc[at].to_string();
        for l in &doc[at + 1..] {
            if l.trim_start().starts_with('#') {
                text.push_str(l);
            } else {
                break;
            }
        }
        text
    };
    let d = FasParams::default();
    let numbers: Vec<(&str, &str, &str, f64)> = vec![
        ("mesh", "scale", "1", defaults::SCALE),
        (
            "mesh",
            "pattern",
            "6",
            defaults::BOX_PATTERN.tets_per_cube() as f64,
        ),
        ("material", "density", "1000", defaults::DENSITY),
        ("material", "thickness", "1e-3", defaults::THICKNESS),
        ("integrator", "safety", "0.5", defaults::SAFETY),
        ("run", "duration", "60", defaults::STEADY_CAP),
        ("run", "kinetic_tol", "1e-8", defaults::KINETIC_TOL),
        ("run", "residual_tol", "1e-4", defaults::RESIDUAL_TOL),
        ("run", "blowup_factor", "1e3", defaults::BLOWUP_FACTOR),
        ("output", "frame_interval", "0.05", defaults::FRAME_INTERVAL),
        ("output", "csv_every", "1", defaults::CSV_EVERY as f64),
        ("multigrid", "ratio", "0.5", defaults::LEVEL_RATIO),
        ("multigrid", "epsilon", "1e-3", defaults::EPSILON_PER_EDGE),
        ("multigrid", "coarse_time", "0.1", defaults::COARSE_TIME),
        ("multigrid", "pre_smooth", "4", d.pre_smooth as f64),
        ("multigrid", "post_smooth", "4", d.post_smooth as f64),
        ("interactive", "fps", "30", defaults::FPS),
        ("interactive", "cycles", "4", defaults::CYCLES as f64),
        (
            "interactive",
            "reference_tol",
            "1e-8",
            defaults::REFERENCE_TOL,
        ),
    ];
    for (table, key, text, value) in numbers {
        let e = entry(table, key);
        assert!(e.contains(&format!("default {text}")), "{table}.{key}: {e}");
        assert_eq!(text.parse::<f64>().unwrap(), value, "{table}.{key}");
    }
    let CoarseSolve::Chebyshev { iterations, .. } = d.coarse else {
        panic!("the FAS default coarse solve is Chebyshev")
    };
    assert!(entry("multigrid", "coarse_iterations").contains(&format!("default {iterations}")));
    assert!(entry("multigrid", "coarse").contains(&format!("{iterations} iterations")));
    let Smoother::Chebyshev { scaling, .. } = d.smoother else {
        panic!("the FAS default smoother is Chebyshev")
    };
    let names: Vec<(&str, &str, &str)> = vec![
        ("integrator", "method", defaults::METHOD.name()),
        ("integrator", "precision", Precision::default().name()),
        ("run", "stop", spec::Stop::default().name()),
        ("output", "reference", "none"),
        ("multigrid", "scheme", defaults::SCHEME.name()),
        ("multigrid", "reading", defaults::READING.name()),
        ("multigrid", "smoother", "chebyshev"),
        ("multigrid", "coarse", "chebyshev"),
        ("multigrid", "scaling", scaling.name()),
        ("multigrid", "transfer", d.weights.name()),
        (
            "multigrid",
            "accelerate",
            if d.krylov { "cg" } else { "none" },
        ),
        (
            "interactive",
            "reference",
            spec::StaticReference::default().name(),
        ),
        ("material", "law", defaults::INTERACTIVE_LAW.name()),
    ];
    for (table, key, name) in names {
        let e = entry(table, key);
        assert!(
            e.contains(&format!("\"{name}\" (default"))
                || e.contains(&format!("default \"{name}\"")),
            "{table}.{key}: {e}"
        );
    }
    assert_eq!(Reference::default(), Reference::None);
    // The force model's own defaults agree with the scenario's.
    let sc = parse(BASE).unwrap();
    let fem = crate::fem::FemParams::new(sc.material.clone());
    assert_eq!(fem.density, defaults::DENSITY);
    assert_eq!(fem.thickness, defaults::THICKNESS);
    // And the resolved scenario applies them.
    assert_eq!(sc.integrator.safety, defaults::SAFETY);
    assert_eq!(sc.run.blowup_factor, defaults::BLOWUP_FACTOR);
    assert_eq!(sc.output.frame_interval, defaults::FRAME_INTERVAL);
    assert_eq!(sc.output.csv_every, defaults::CSV_EVERY);
    assert_eq!(sc.output.reference, Reference::None);
    assert_eq!(sc.mesh_source.as_ref().unwrap().scale, defaults::SCALE);
}

/// A slab of tetrahedra under gravity along y, its end x = 0 fixed and every node's z held
/// (`components = ["z"]`): plane strain. The held component stays exactly 0 (bit for bit),
/// the free ones move; the same on two FAS levels (the coarse level holds z too) and for a
/// tilted sliding plane (`normal`), where `u·n` stays at round-off.
#[test]
fn fixed_components_stay_exactly_and_free_ones_move() {
    let slab = |extra: &str, fix2: &str| {
        format!(
            "gravity = [0.0, -9.81, 0.0]\n[mesh]\ngenerate = \"box\"\nsize = [0.1, 0.02, 0.01]\n\
             divisions = [10, 2, 1]\n[material]\nlaw = \"neo-hookean\"\nyoung = 5e4\npoisson = 0.3\n\
             [damping]\nalpha = 50.0\n[[fix]]\nplane = {{ point = [0.0, 0.0, 0.0], normal = [1.0, 0.0, 0.0] }}\n\
             [[fix]]\nbox = {{ min = [-1.0, -1.0, -1.0], max = [1.0, 1.0, 1.0] }}\n{fix2}\n\
             [run]\nduration = 0.02\n{extra}"
        )
    };
    for extra in ["", "[multigrid]\nlevels = 2\n"] {
        let sc = parse(&slab(extra, "components = [\"z\"]")).unwrap();
        assert_eq!(sc.sliding.len(), sc.mesh.num_nodes());
        let mut st = sc.stepper().unwrap();
        for _ in 0..200 {
            st.advance().unwrap();
        }
        let u = &st.finest().1.u;
        let (mut max_xy, mut max_z) = (0.0f64, 0.0f64);
        for a in 0..sc.mesh.num_nodes() {
            max_xy = max_xy.max(u[3 * a].abs()).max(u[3 * a + 1].abs());
            max_z = max_z.max(u[3 * a + 2].abs());
        }
        assert_eq!(max_z, 0.0, "{extra}: z moved");
        assert!(max_xy > 1e-6, "{extra}: nothing moved ({max_xy})");
    }
    // Sliding on a tilted plane: u·n = 0 to round-off, the node still moves.
    let n = [0.0, 0.6, 0.8];
    let sc = parse(&slab("", &format!("normal = {n:?}"))).unwrap();
    let mut st = sc.stepper().unwrap();
    for _ in 0..200 {
        st.advance().unwrap();
    }
    let u = &st.finest().1.u;
    let umax = crate::metrics::max_displacement(u);
    assert!(umax > 1e-6);
    for a in 0..sc.mesh.num_nodes() {
        let un = u[3 * a] * n[0] + u[3 * a + 1] * n[1] + u[3 * a + 2] * n[2];
        assert!(un.abs() <= 1e-15 * umax.max(1e-3), "node {a}: u·n = {un}");
    }
    for (extra, want) in [
        (
            "components = [\"w\"]",
            "not a component (valid: \"x\", \"y\", \"z\")",
        ),
        ("components = []", "is empty"),
        ("normal = [0.0, 0.0, 0.0]", "must be non-zero"),
        (
            "components = [\"x\"]\nnormal = [1.0, 0.0, 0.0]",
            "`components` or `normal`, not both",
        ),
    ] {
        let e = error_of(&slab("", extra));
        assert!(e.contains(want), "{extra}: {e}");
    }
}

/// A TetGen pair numbered from 1: `nodes = [1]` is the file's first node, `nodes = [0]` an
/// error naming the range, and `nodal_stress.csv` lists the file's ids.
#[test]
fn node_ids_are_the_files_own() {
    let dir = tempfile::tempdir().unwrap();
    // The unit cube in 5 tetrahedra, ids 1..8; node 1 at the origin.
    let pts = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 1.0],
        [1.0, 1.0, 1.0],
        [0.0, 1.0, 1.0],
    ];
    let mut node = String::from("8 3 0 0\n");
    for (i, p) in pts.iter().enumerate() {
        node.push_str(&format!("{} {} {} {}\n", i + 1, p[0], p[1], p[2]));
    }
    std::fs::write(dir.path().join("cube.node"), node).unwrap();
    std::fs::write(
        dir.path().join("cube.ele"),
        "5 4 0\n1 1 2 4 5\n2 2 3 4 7\n3 2 5 6 7\n4 4 5 7 8\n5 2 4 5 7\n",
    )
    .unwrap();
    let text = |ids: &str| {
        format!(
            "[mesh]\nfile = \"cube.node\"\nscale = 0.01\n[material]\nlaw = \"neo-hookean\"\nyoung = 5e4\n\
             poisson = 0.3\n[[fix]]\nnodes = {ids}\n[[load]]\nat = {{ nodes = [7] }}\nforce = [0.0, 0.0, 1e-3]\n\
             [run]\nduration = 0.001\n[output]\nframe_interval = 0.0\n"
        )
    };
    let p = dir.path().join("cube.toml");
    let sc = Scenario::from_toml(&text("[1, 2, 3, 4]"), &p).unwrap();
    let mut fixed: Vec<[f64; 3]> = sc
        .fixed
        .iter()
        .map(|&a| sc.mesh.nodes[a as usize])
        .collect();
    fixed.sort_by(|a, b| a.partial_cmp(b).unwrap());
    assert!(
        fixed.iter().all(|x| x[2] == 0.0) && fixed.len() == 4,
        "{fixed:?}"
    );
    assert_eq!(sc.mesh.nodes[sc.loads[0].0 as usize], [0.01, 0.01, 0.01]);
    assert_eq!(sc.file_node(sc.loads[0].0), 7);
    let e = Scenario::from_toml(&text("[0]"), &p)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("fix[0].nodes: node 0 does not exist") && e.contains("cube.node run 1..=8"),
        "{e}"
    );
    let e = Scenario::from_toml(&text("[9]"), &p)
        .unwrap_err()
        .to_string();
    assert!(e.contains("node 9 does not exist"), "{e}");
    let out = dir.path().join("out");
    run(
        &sc,
        RunOptions {
            out_dir: Some(out.clone()),
            ..Default::default()
        },
    )
    .unwrap();
    let csv = std::fs::read_to_string(out.join("nodal_stress.csv")).unwrap();
    let ids: Vec<&str> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap())
        .collect();
    assert_eq!(ids, ["1", "2", "3", "4", "5", "6", "7", "8"]);
    // The file reads back as a reference of the same mesh.
    read_nodal_stress(&out.join("nodal_stress.csv"), &sc).unwrap();
}

/// At steady state the reactions balance the applied loads and body force:
/// `F_fixed + F_prescribed + Σ V = 0`, to 1e-6 of `|Σ V|` (the steady residual bounds it).
/// A membrane draped under gravity with its boundary fixed, and a point load; FAS.
#[test]
fn reactions_balance_the_applied_loads() {
    let text = format!(
        "gravity = [0.0, 0.0, -9.81]\n{}\n[[load]]\nat = {{ point = [0.02, 0.0, 0.0] }}\nforce = [1e-4, 0.0, -2e-3]\n\
         [damping]\nratio = 1.0\nomega = 177.7\n[multigrid]\nlevels = 3\n",
        BASE.replace(
            "duration = 0.01",
            "stop = \"steady\"\nduration = 2.0\nkinetic_tol = 1e-14\nresidual_tol = 1e-10"
        )
    );
    let sc = parse(&text).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let s = run(
        &sc,
        RunOptions {
            out_dir: Some(dir.path().to_path_buf()),
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(s.reason, StopReason::Steady, "{s}");
    let v = s.applied;
    let vn = crate::mesh::norm(v);
    assert!(vn > 1e-3, "{v:?}");
    let f = s.last.reaction_fixed;
    for k in 0..3 {
        let gap = f[k] + s.last.reaction_prescribed[k] + v[k];
        assert!(
            gap.abs() <= 1e-6 * vn,
            "component {k}: {f:?} + {v:?} = {gap:e}"
        );
    }
    // The summary and the last row of measures.csv say the same.
    assert!(s.to_string().contains("reactions       fixed"));
    let csv = std::fs::read_to_string(dir.path().join("measures.csv")).unwrap();
    let last: Vec<&str> = csv.lines().last().unwrap().split(',').collect();
    assert_eq!(last.len(), 19);
    let fz: f64 = last[11].parse().unwrap();
    assert!((fz - f[2]).abs() <= 1e-9 * f[2].abs(), "{fz} vs {}", f[2]);
}

/// Warnings: a step far above the estimated critical one, a run too long to finish, a point
/// far outside the mesh, a mesh in millimetres read as metres.
#[test]
fn absurd_settings_warn() {
    let w = |text: &str| parse(text).unwrap().warnings.join("\n");
    let s = w(&BASE.replace("[run]", "[integrator]\ndt = 1.0\n[run]"));
    assert!(s.contains("times the estimated critical step"), "{s}");
    let s = w(&BASE.replace("[run]", "[integrator]\ndt = 1e-14\n[run]"));
    assert!(s.contains("hours at"), "{s}");
    let s = w(&BASE.replace("boundary = true", "point = [5.0, 0.0, 0.0]"));
    assert!(s.contains("fix[0]: point [5.0, 0.0, 0.0] lies"), "{s}");
    let s = w(&BASE.replace("size = [0.1, 0.1]", "size = [100.0, 100.0]"));
    assert!(s.contains("millimetres read as metres"), "{s}");
    assert_eq!(w(BASE), "");
}

/// `[[displace]] radius`: a surface patch, the nodes `Simulation::grab` takes at the same
/// point and radius on the undeformed body, all with the same motion.
#[test]
fn displace_radius_prescribes_the_grab_patch() {
    let cube = |displace: &str| cube(&format!("[run]\nduration = 0.01\n{displace}"));
    for (r, want) in [(0.0, 1), (0.011, 5), (0.0145, 9)] {
        let d = format!(
            "[[displace]]\npoint = [0.02, 0.02, 0.05]\nradius = {r}\ntable = [[0.0, 0, 0, 0], [1.0, 0, 0, 0.01]]"
        );
        let sc = parse(&cube(&d)).unwrap();
        let mut nodes: Vec<u32> = sc.prescribed.iter().map(|(a, _)| *a).collect();
        nodes.sort_unstable();
        assert_eq!(nodes.len(), want, "radius {r}");
        // The top centre (0.02, 0.02, 0.04) and, from 1 cm, its 4 edge neighbours, from
        // √2 cm the 4 diagonal ones.
        for &a in &nodes {
            let x = sc.mesh.nodes[a as usize];
            let d = ((x[0] - 0.02).powi(2) + (x[1] - 0.02).powi(2)).sqrt();
            assert!((x[2] - 0.04).abs() < 1e-12 && d <= r + 1e-12, "{x:?}");
        }
        assert!(sc.prescribed.iter().all(|(_, m)| *m == sc.prescribed[0].1));
        // The same nodes as a grasp of the simulation at the same point and radius.
        let mut sim = crate::sim::Simulation::from_toml(&cube(""), ".").unwrap();
        let g = sim.grab([0.02, 0.02, 0.05], r).unwrap();
        assert_eq!(sim.grab_nodes(g).unwrap(), &nodes[..]);
    }
    // Fixed nodes are left out: a patch on the base that is all fixed is an error.
    let d =
        "[[displace]]\npoint = [0.02, 0.02, -0.01]\nradius = 0.005\ndisplacement = [0, 0, 0.001]";
    let e = error_of(&cube(d));
    assert!(e.contains("displace[0]") && e.contains("fixed"), "{e}");
    let d = "[[displace]]\npoint = [0.02, 0.02, 0.05]\nradius = -1.0\ndisplacement = [0, 0, 0.001]";
    let e = error_of(&cube(d));
    assert!(e.contains("radius") && e.contains(">= 0"), "{e}");
}

/// `[material] law` defaults to stable neo-Hookean with an `[interactive]` section and is
/// required without one; a law that is named is kept either way.
#[test]
fn interactive_scenarios_default_to_stable_neo_hookean() {
    let no_law = BASE.replace(
        "law = \"mooney-rivlin\"\nc1 = 1000.0\nc2 = 1000.0",
        "young = 5000.0\npoisson = 0.45",
    );
    assert!(!no_law.contains("law ="));
    let sc = parse(&format!("{no_law}\n[interactive]\n")).unwrap();
    match &sc.material {
        Material::StableNeoHookean(m) => {
            assert_eq!(*m, StableNeoHookean::from_young(5000.0, 0.45))
        }
        m => panic!("interactive default law: {m:?}"),
    }
    assert_eq!(defaults::INTERACTIVE_LAW, spec::Law::StableNeoHookean);
    let e = error_of(&no_law);
    assert!(e.contains("`law` is required"), "{e}");
    let named = parse(&format!("{BASE}\n[interactive]\n")).unwrap();
    assert!(matches!(named.material, Material::MooneyRivlin(_)));
}

/// The longest run of digits in `s`.
fn longest_digit_run(s: &str) -> usize {
    s.split(|c: char| !c.is_ascii_digit())
        .map(str::len)
        .max()
        .unwrap_or(0)
}

/// Warnings (and errors that echo a value) print huge values compactly: `run.duration =
/// 1e300` was printed as 301 digits, and the hours it takes as 290.
#[test]
fn huge_values_in_warnings_print_compactly() {
    let w = |text: &str| parse(text).unwrap().warnings.join("\n");
    let s = w(&BASE.replace("duration = 0.01", "duration = 1e300"));
    assert!(s.contains("to simulate 1e300 s"), "{s}");
    assert!(s.contains("e29") && s.contains(" hours at"), "{s}");
    assert!(longest_digit_run(&s) <= 6, "{s}");
    let s = w(&BASE.replace("[run]", "[integrator]\ndt = 1e300\n[run]"));
    assert!(s.contains("times the estimated critical step"), "{s}");
    assert!(longest_digit_run(&s) <= 6, "{s}");
    let s = w(&BASE.replace("nodes = 60", "nodes = 60\nscale = 1e300"));
    assert!(s.contains("[mesh] scale = 1e300"), "{s}");
    assert!(longest_digit_run(&s) <= 6, "{s}");
    // Errors that echo a value too.
    let e = error_of(&BASE.replace("duration = 0.01", "duration = -1e300"));
    assert!(
        e.contains("`run.duration` = -1e300: must be a positive number"),
        "{e}"
    );
}

/// An energy blow-up names the node holding the most kinetic energy, by its id in the mesh
/// file and its position, and its speed: it named no node.
#[test]
fn energy_blow_up_names_the_node_in_file_numbering() {
    let text = format!("{BASE}\n[integrator]\nmethod = \"symplectic-euler\"\n[[displace]]\npoint = [0.0, 0.0, 0.0]\ndisplacement = [0.0, 0.0, 0.03]\n")
        .replace("duration = 0.01", "duration = 0.01\nblowup_factor = 1e-30");
    let sc = parse(&text).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let e = run(
        &sc,
        RunOptions {
            out_dir: Some(dir.path().to_path_buf()),
            progress: None,
            stop: None,
            in_memory: false,
        },
    )
    .unwrap_err();
    let msg = e.to_string();
    let Error::Diverged(d) = e else {
        panic!("{msg}")
    };
    let crate::error::DivergenceCause::EnergyBlowUp { node, speed, .. } = d.cause else {
        panic!("{msg}")
    };
    let at = sc.mesh.nodes[node.index];
    assert_eq!(node.file_id, Some(sc.file_node(node.index as u32)), "{msg}");
    assert_eq!(node.at, Some(at), "{msg}");
    assert!(speed > 0.0, "{msg}");
    let want = format!(
        "the most kinetic energy is at node {} of the mesh file (at {} m), moving at {speed:.3e} m/s",
        sc.file_node(node.index as u32),
        crate::numbers::point(at)
    );
    assert!(msg.contains(&want), "{msg}\nwant: {want}");
}

/// A level file of triangles under a tetrahedral level 0 is an error naming the level's
/// file and key and level 0's file: it said only "fine mesh is tetrahedron, coarse mesh is
/// triangle membrane".
#[test]
fn triangles_under_tets_name_the_level_file() {
    use crate::mesh::generate::{box_tets, rectangle_membrane, BoxPattern};
    let dir = tempfile::tempdir().unwrap();
    let tets = box_tets([0.1, 0.04, 0.04], [6, 2, 2], BoxPattern::Five).unwrap();
    crate::io::write_msh22(&dir.path().join("b.msh"), &tets).unwrap();
    let tris = rectangle_membrane(0.1, 0.04, 20).unwrap();
    crate::io::write_msh22(&dir.path().join("c.msh"), &tris).unwrap();
    let text = "[mesh]\nfile = \"b.msh\"\n[material]\nlaw = \"neo-hookean\"\nyoung = 5e4\npoisson = 0.4\n[[fix]]\nplane = { point = [0.0, 0.0, 0.0], normal = [1.0, 0.0, 0.0] }\n[run]\nduration = 0.01\n[multigrid]\nfiles = [\"c.msh\"]\n";
    let e = match Scenario::from_toml(text, &dir.path().join("s.toml")) {
        Err(e) => e,
        Ok(sc) => sc.stepper().map(|_| ()).unwrap_err(),
    };
    let msg = e.to_string();
    assert!(msg.contains("s.toml"), "{msg}");
    assert!(msg.contains("`multigrid.files[0]` = \""), "{msg}");
    assert!(
        msg.contains("c.msh\": level 1 is a triangle membrane mesh"),
        "{msg}"
    );
    assert!(
        msg.contains("but level 0 (`mesh.file` = \"")
            && msg.contains("b.msh\") is a tetrahedron mesh"),
        "{msg}"
    );
}

mod fibres;
mod implicit;
mod scheme;
mod statics;
mod visco;

/// A body with no load, no motion and no gravity stays at rest: its round-off kinetic energy
/// (1e-35 J) was taken for an energy blow-up, the limit being zero without loads.
#[test]
fn a_body_without_loads_is_not_a_blow_up() {
    let sc = parse(&cube("[run]\nduration = 0.002\n")).unwrap();
    let s = run(
        &sc,
        RunOptions {
            in_memory: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(s.reason, StopReason::Duration, "{s}");
    assert!(s.last.max_u < 1e-15, "{}", s.last.max_u);
}
