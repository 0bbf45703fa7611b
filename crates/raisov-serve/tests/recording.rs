//! A saved recording replays what the session did: a session driven through the WebSocket
//! protocol (spring grasps moved along targets, released, the same spot grasped again, a
//! pin taken while the tissue is deformed) is saved, replayed by the library's interactive
//! run (what `raisov run` calls), and the replay passes through the frames the session
//! showed; the recording loads wherever it is saved.

use raisov::runner::RunOptions;
use raisov::scenario::Scenario;
use raisov::sim::Budget;
use raisov_serve::protocol::{self, Command, FLAG_REST, STAT_APPLIED_SEQ};
use raisov_serve::session::{SessionConfig, Source};
use std::path::{Path, PathBuf};

mod common;
use common::{connect, hello, next_frame, next_text, send, start_session, Client, CUBE};

/// The session's spring stiffness (N/m): the viewer's default.
const STIFFNESS: f64 = 200.0;

/// Frames read so far, in order (the newest frame only reaches a client: some are skipped).
struct Seen(Vec<protocol::Frame>);

impl Seen {
    /// Read frames until one has applied `seq` (a grasp or move of this client).
    async fn until_applied(&mut self, ws: &mut Client, seq: u32) {
        loop {
            let f = next_frame(ws).await;
            let done = f.stats[STAT_APPLIED_SEQ] >= seq as f32;
            self.0.push(f);
            if done {
                return;
            }
        }
    }
    /// Read `n` more frames.
    async fn frames(&mut self, ws: &mut Client, n: usize) {
        for _ in 0..n {
            let f = next_frame(ws).await;
            self.0.push(f);
        }
    }
    /// Read frames until the simulation says it sleeps (at rest).
    async fn until_rest(&mut self, ws: &mut Client) {
        loop {
            let f = next_frame(ws).await;
            let rest = f.flags & FLAG_REST != 0;
            self.0.push(f);
            if rest {
                return;
            }
        }
    }
}

/// The scripted session: grab the top's centre, pull it up and sideways over a few targets,
/// release, grab the same spot again, pin a corner while pulling, release, rest, save. The
/// frames seen and the recording (the reply and the `--record` file).
async fn scripted_session(record: &Path) -> (Vec<protocol::Frame>, String) {
    let source = Source::from_text(CUBE, PathBuf::from("."), "cube", "cube.toml".as_ref())
        .expect("the cube scenario");
    let (addr, _task) = start_session(
        source,
        SessionConfig {
            budget: Budget::Cycles(20),
            max_fps: 200.0,
            method: None,
            record_path: Some(record.to_path_buf()),
            grab_stiffness: Some(STIFFNESS),
        },
    )
    .await;
    let mut ws = connect(&addr).await;
    hello(&mut ws).await;
    let mut seen = Seen(Vec::new());
    let centre = [0.02f32, 0.02, 0.04];
    let mut seq = 0;
    let mut next = || {
        seq += 1;
        seq
    };
    for round in 0..2 {
        let s = next();
        send(
            &mut ws,
            s,
            Command::Grab {
                point: centre,
                radius: 0.011,
            },
        )
        .await;
        seen.until_applied(&mut ws, s).await;
        for j in 1..=4 {
            let h = 0.0015 * j as f32;
            let s = next();
            let target = [centre[0] + 0.5 * h, centre[1], centre[2] + h];
            send(&mut ws, s, Command::Move { target }).await;
            seen.until_applied(&mut ws, s).await;
            seen.frames(&mut ws, 3).await;
            if round == 1 && j == 2 {
                // A pin of a corner of the top, taken while the grasp pulls the tissue.
                let s = next();
                send(
                    &mut ws,
                    s,
                    Command::Pin {
                        point: [0.04, 0.04, 0.04],
                        radius: 0.011,
                    },
                )
                .await;
                seen.frames(&mut ws, 3).await;
            }
        }
        let s = next();
        send(&mut ws, s, Command::Release).await;
        seen.frames(&mut ws, 10).await;
    }
    seen.until_rest(&mut ws).await;
    let s = next();
    send(&mut ws, s, Command::Save).await;
    let reply = loop {
        let t = next_text(&mut ws).await;
        if t.contains("\"type\":\"recording\"") {
            break t;
        }
    };
    let file = std::fs::read_to_string(record).expect("the --record file");
    assert_eq!(
        reply,
        format!(
            "{{\"type\":\"recording\",\"toml\":{}}}",
            protocol::json_string(&file)
        ),
        "the reply and the --record file differ"
    );
    (seen.0, file)
}

/// Replay a recording with the interactive run into `out`: each frame's positions (m) of the
/// surface vertices the viewer sends (the boundary nodes, ascending).
fn replay(file: &Path, out: &Path) -> Vec<Vec<[f64; 3]>> {
    let sc = Scenario::load(file).expect("the recording loads");
    let stepper = sc.stepper().expect("its stepper");
    let s = raisov::runner::run_interactive(
        &sc,
        stepper,
        RunOptions {
            out_dir: Some(out.to_path_buf()),
            ..Default::default()
        },
    )
    .expect("the recording replays");
    let mut used: Vec<u32> = sc.mesh.boundary_facets().into_iter().flatten().collect();
    used.sort_unstable();
    used.dedup();
    (1..=s.frames)
        .map(|k| {
            let vtu = out.join("frames").join(format!("{}_{k:06}.vtu", sc.name));
            let (_, u) = raisov::io::read_vtu_array(&vtu, "displacement").expect("a frame");
            used.iter()
                .map(|&a| {
                    let (x, i) = (sc.mesh.nodes[a as usize], 3 * a as usize);
                    [x[0] + u[i], x[1] + u[i + 1], x[2] + u[i + 2]]
                })
                .collect()
        })
        .collect()
}

/// The largest distance (m) between a session frame (f32) and a replayed one, per axis.
fn distance(shown: &protocol::Frame, replayed: &[[f64; 3]]) -> f64 {
    assert_eq!(shown.positions.len(), replayed.len());
    let mut d = 0.0f64;
    for (a, b) in shown.positions.iter().zip(replayed) {
        for k in 0..3 {
            d = d.max((a[k] as f64 - b[k] as f32 as f64).abs());
        }
    }
    d
}

/// The session's frames arrive as f32 (spacing 3.7e-9 m at 4 cm); the replay steps the
/// same frames with the same constraints, so it differs from the session only by the
/// rounding of a grasp's target, `g + (x − g)` (a few 1e-18 m), which stays far below
/// one f32 step.
const TOLERANCE: f64 = 1e-8;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_recorded_session_replays_to_the_same_frames() {
    let dir = tempfile::tempdir().unwrap();
    let record = dir.path().join("saved").join("cube-recorded.toml");
    std::fs::create_dir_all(record.parent().unwrap()).unwrap();
    let (shown, text) = scripted_session(&record).await;
    // What the recording says it did: two spring grasps of the same spot, each released,
    // and a pin.
    let sc = Scenario::load(&record).expect("the recording loads");
    assert_eq!(sc.grasps.len(), 2, "{text}");
    assert_eq!(sc.pins.len(), 1, "{text}");
    for g in &sc.grasps {
        assert_eq!(g.stiffness, Some(STIFFNESS), "{text}");
        assert!(g.release.is_some(), "{text}");
    }
    let frames = replay(&record, &dir.path().join("replay"));
    // Every frame the session showed is a frame of the replay, in order; the last (at rest,
    // when it was saved) is the replay's last.
    let mut k = 0;
    let mut worst = 0.0f64;
    for f in &shown {
        let (best, d) = (k..frames.len())
            .map(|j| (j, distance(f, &frames[j])))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .expect("replayed frames left");
        worst = worst.max(d);
        k = best;
    }
    let last = distance(shown.last().unwrap(), frames.last().unwrap());
    println!(
        "round trip: {} session frames against {} replayed: largest distance {worst:.3e} m, \
         last frame {last:.3e} m (tolerance {TOLERANCE:e} m)",
        shown.len(),
        frames.len()
    );
    assert!(worst <= TOLERANCE && last <= TOLERANCE, "{text}");
}

/// The recordings named the served scenario's mesh files as it did, relative to its own
/// directory: saved elsewhere, they did not load. Every path is written absolute: a
/// recording saved anywhere loads the same meshes (a mesh file with its coarser levels'
/// files, a surface meshed at load, a generated box).
#[test]
fn a_recording_loads_wherever_it_is_saved() {
    use raisov::mesh::generate::{box_tets, BoxPattern};
    let dir = tempfile::tempdir().unwrap();
    let (served, meshes) = (dir.path().join("served"), dir.path().join("meshes"));
    std::fs::create_dir_all(&served).unwrap();
    std::fs::create_dir_all(&meshes).unwrap();
    for (name, n) in [("fine.msh", 4), ("coarse.msh", 2)] {
        let m = box_tets([0.04; 3], [n; 3], BoxPattern::Six).unwrap();
        raisov::io::write_msh22(&meshes.join(name), &m).unwrap();
    }
    let surface = concat!(env!("CARGO_MANIFEST_DIR"), "/../../data/liver_surface.obj");
    std::fs::copy(surface, meshes.join("liver.obj")).unwrap();
    let material = "[material]\nlaw = \"neo-hookean\"\nyoung = 5e3\npoisson = 0.45\n\
                    [run]\nduration = 1.0\n[output]\ndir = \"out\"\n";
    let base = "[[fix]]\nplane = { point = [0, 0, 0], normal = [0, 0, 1] }\n";
    let scenarios = [
        (
            "file",
            "[mesh]\nfile = \"../meshes/fine.msh\"\n\
             [multigrid]\nscheme = \"fas\"\nfiles = [\"../meshes/coarse.msh\"]\n{base}",
        ),
        (
            "surface",
            "[mesh]\nsurface = \"../meshes/liver.obj\"\nscale = 1e-3\nnodes = 150\n",
        ),
        (
            "generated",
            "[mesh]\ngenerate = \"box\"\nsize = [0.04, 0.04, 0.04]\ndivisions = [3, 3, 3]\n{base}",
        ),
    ];
    for (name, mesh) in scenarios {
        let path = served.join(format!("{name}.toml"));
        let mesh = mesh.replace("{base}", base);
        std::fs::write(&path, format!("{mesh}{material}")).unwrap();
        let source = Source::from_scenario_file(&path).unwrap();
        let method = source.method;
        let mut rec = raisov_serve::record::Recorder::new();
        rec.push(raisov_serve::record::Event::Pin {
            point: [0.02, 0.02, 0.04],
            radius: 0.005,
        });
        rec.frame(None);
        let text = rec.scenario(&source, method, Budget::Cycles(2), 0);
        // Saved two directories away (what --record FILE or the page's download does), read
        // with another working directory's worth of relative paths nowhere.
        let saved = dir
            .path()
            .join("elsewhere")
            .join("deeper")
            .join(format!("{name}.toml"));
        std::fs::create_dir_all(saved.parent().unwrap()).unwrap();
        std::fs::write(&saved, &text).unwrap();
        let out = dir.path().join("out").join(name);
        let replayed = Scenario::load_with_out(&saved, Some(&out))
            .unwrap_or_else(|e| panic!("{name}: {e}\n{text}"));
        let original = Scenario::load_with_out(&path, Some(&out)).unwrap();
        assert_eq!(
            replayed.mesh.num_nodes(),
            original.mesh.num_nodes(),
            "{name}"
        );
        assert_eq!(replayed.mesh.nodes, original.mesh.nodes, "{name}");
        assert_eq!(replayed.pins.len(), 1, "{name}");
        for line in text
            .lines()
            .filter(|l| l.contains(".msh") || l.contains(".obj"))
        {
            let quoted = line.split('"').nth(1).unwrap();
            assert!(Path::new(quoted).is_absolute(), "{name}: {line}");
        }
        // The recording's results go to its own directory, not the served scenario's.
        assert!(!text.contains("dir = "), "{name}: {text}");
    }
}
