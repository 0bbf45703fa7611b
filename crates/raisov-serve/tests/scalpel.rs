//! The scalpel over the protocol: a cut message splits the cube's elements and every client
//! gets the cut body's topology (more vertices and triangles) before its next frame; a grasp
//! on one lip pulls the wound open; a method switch keeps the wound (every method cuts it
//! again), a reset heals the body; a cut the simulation cannot take is refused with the
//! reason, a blade that misses changes nothing; the recording writes the cut.

use futures_util::StreamExt;
use raisov::sim::Budget;
use raisov::SchemeKind;
use raisov_serve::protocol::{self, Command};
use raisov_serve::session::{SessionConfig, Source};
use std::path::PathBuf;
use std::time::Duration;
use tokio_tungstenite::tungstenite::Message as Ws;

mod common;
use common::{connect, next_frame, send, start, start_session, Client, CUBE};

/// The uncut cube's surface: 98 vertices, 192 triangles.
const UNCUT: (usize, usize) = (98, 192);

/// A vertical blade in the plane x = 21 mm, drawn across the top (y from −5 to 45 mm, 5 mm
/// above the top face) and pushed 25 mm down: a notch through the upper half of the cube.
fn notch() -> Command {
    Command::Cut {
        a: [0.021, -0.005, 0.045],
        b: [0.021, 0.045, 0.045],
        sweep: [0.0, 0.0, -0.025],
    }
}

/// Read messages until `f` takes one (within 20 s).
async fn until<T>(ws: &mut Client, mut f: impl FnMut(&Ws) -> Option<T>) -> T {
    tokio::time::timeout(Duration::from_secs(20), async {
        loop {
            match ws.next().await {
                Some(Ok(m)) => {
                    if let Some(t) = f(&m) {
                        return t;
                    }
                }
                other => panic!("connection ended: {other:?}"),
            }
        }
    })
    .await
    .expect("the message within 20 s")
}

/// The next topology: vertex count and triangle count.
async fn next_topology(ws: &mut Client) -> (usize, usize) {
    until(ws, |m| match m {
        Ws::Binary(b) => protocol::decode_topology(b).map(|(n, t)| (n, t.len())),
        _ => None,
    })
    .await
}

/// Connect: the client once it has the hello and the first topology (in either order), and
/// that topology's counts.
async fn open(addr: &str) -> (Client, (usize, usize)) {
    let mut ws = connect(addr).await;
    let (mut hello, mut topo) = (false, None);
    while !hello || topo.is_none() {
        until(&mut ws, |m| match m {
            Ws::Text(t) if t.contains("\"type\":\"hello\"") => {
                hello = true;
                Some(())
            }
            Ws::Binary(b) => protocol::decode_topology(b).map(|(n, t)| {
                topo = Some((n, t.len()));
            }),
            _ => None,
        })
        .await;
    }
    (ws, topo.unwrap())
}

/// The next text message of `kind` and the next topology, which the server may send in
/// either order (the reply and the published frame travel on separate channels).
async fn text_and_topology(ws: &mut Client, kind: &str) -> (String, (usize, usize)) {
    let tag = format!("\"type\":\"{kind}\"");
    let (mut text, mut topo) = (None, None);
    while text.is_none() || topo.is_none() {
        until(ws, |m| match m {
            Ws::Text(t) if t.contains(&tag) => {
                text = Some(t.to_string());
                Some(())
            }
            Ws::Binary(b) => protocol::decode_topology(b).map(|(n, t)| {
                topo = Some((n, t.len()));
            }),
            _ => None,
        })
        .await;
    }
    (text.unwrap(), topo.unwrap())
}

/// The next text message of `kind` (`"cut"`, `"error"`, …).
async fn next_of(ws: &mut Client, kind: &str) -> String {
    let tag = format!("\"type\":\"{kind}\"");
    until(ws, |m| match m {
        Ws::Text(t) if t.contains(&tag) => Some(t.to_string()),
        _ => None,
    })
    .await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_cut_message_splits_elements_and_every_client_gets_the_cut_topology() {
    let (addr, _task) = start().await;
    let (mut a, topo) = open(&addr).await;
    assert_eq!(topo, UNCUT);
    let (mut b, topo) = open(&addr).await;
    assert_eq!(topo, UNCUT);
    let rest = next_frame(&mut a).await;

    send(&mut a, 1, notch()).await;
    let (report, topo_a) = text_and_topology(&mut a, "cut").await;
    assert!(report.contains("\"cuts\":1"), "{report}");
    let split: usize = report
        .split("\"split\":[")
        .nth(1)
        .and_then(|r| r.split([',', ']']).next())
        .and_then(|x| x.parse().ok())
        .expect("split count");
    assert!(split > 0, "the notch split no element: {report}");
    // Both clients get the cut body's surface: the wound's faces add vertices and
    // triangles; the next frame has the new vertex count.
    let mut first = Vec::new();
    for (k, ws) in [&mut a, &mut b].into_iter().enumerate() {
        let (n, m) = if k == 0 {
            topo_a
        } else {
            next_topology(ws).await
        };
        assert!(
            n > UNCUT.0 && m > UNCUT.1,
            "cut topology {n} vertices, {m} triangles"
        );
        assert!(
            report.contains(&format!("\"vertices\":{n},\"triangles\":{m}")),
            "the cut reply names the topology's counts: {report}"
        );
        let f = next_frame(ws).await;
        assert_eq!(f.positions.len(), n);
        first.push(f);
    }
    let cut = first.swap_remove(0);
    // The copies of the nodes on the blade's path sit where their originals are (the cube
    // is at rest, no gravity): pairs of vertices at one point.
    let pairs = pairs_at_one_point(&cut.positions);
    assert!(!pairs.is_empty(), "no node was copied");
    assert!(rest.positions.len() < cut.positions.len());

    // The grasp works on the cut body: take the left lip's top edge (x = 15 mm) and pull it
    // 6 mm to −x; the copies on the left lip follow, their twins on the right lip stay, and
    // the wound opens.
    send(
        &mut a,
        2,
        Command::Grab {
            point: [0.015, 0.02, 0.04],
            radius: 0.007,
        },
    )
    .await;
    send(
        &mut a,
        3,
        Command::Move {
            target: [0.009, 0.02, 0.04],
        },
    )
    .await;
    let mut opened = 0.0f32;
    for _ in 0..400 {
        let f = next_frame(&mut a).await;
        opened = pairs
            .iter()
            .map(|&(i, j)| dist(f.positions[i], f.positions[j]))
            .fold(0.0, f32::max);
        if opened > 1e-3 {
            break;
        }
    }
    assert!(
        opened > 1e-3,
        "the lips of the wound part by {opened} m (want > 1 mm)"
    );

    // The recording writes the cut as the client sent it.
    send(&mut a, 4, Command::Save).await;
    let rec = next_of(&mut a, "recording").await;
    assert!(rec.contains("[[cut]]"), "{rec}");
    assert!(rec.contains("1 cut(s)"), "{rec}");
}

/// A method switch keeps the wound: FAS, the frame solver and RaISoV take the blades again,
/// giving the same surface; a cut on RaISoV cuts it further; a reset heals the body.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_method_switch_keeps_the_wound_and_a_reset_heals_it() {
    let (addr, _task) = start().await;
    let (mut ws, topo) = open(&addr).await;
    assert_eq!(topo, UNCUT);
    send(&mut ws, 1, notch()).await;
    let cut = next_topology(&mut ws).await;
    assert!(cut.0 > UNCUT.0);

    for (seq, m) in [
        (2, SchemeKind::Fas),
        (3, SchemeKind::Newton),
        (4, SchemeKind::RaisovPaper),
    ] {
        send(&mut ws, seq, Command::Method(m)).await;
        let (t, topo) = text_and_topology(&mut ws, "method").await;
        assert!(
            t.contains(&format!("\"method\":{}", protocol::method_code(m))),
            "{t}"
        );
        assert_eq!(topo, cut, "the wound after the switch to {m:?}");
    }
    // A second notch, across the first, on RaISoV.
    send(
        &mut ws,
        5,
        Command::Cut {
            a: [-0.005, 0.011, 0.045],
            b: [0.045, 0.011, 0.045],
            sweep: [0.0, 0.0, -0.02],
        },
    )
    .await;
    let (r, twice) = text_and_topology(&mut ws, "cut").await;
    assert!(r.contains("\"cuts\":2"), "{r}");
    assert!(twice.0 > cut.0, "{twice:?} after {cut:?}");

    send(&mut ws, 6, Command::Reset).await;
    assert_eq!(
        next_topology(&mut ws).await,
        UNCUT,
        "a reset heals the body"
    );
}

/// A cut of a body under a timed load (which the library cannot carry through a cut) is
/// answered with the library's reason, nothing changed; a blade that misses the body changes
/// nothing either.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_cut_the_simulation_cannot_take_is_refused_with_the_reason() {
    let scenario = format!(
        "{CUBE}\n[[load]]\nat = {{ point = [0.02, 0.02, 0.04] }}\nforce = [0.0, 0.0, -0.001]\n\
         time = {{ kind = \"ramp\", duration = 0.5 }}\n"
    );
    let source = Source::from_text(&scenario, PathBuf::from("."), "cube", "cube.toml".as_ref())
        .expect("the cube scenario");
    let (addr, _task) = start_session(
        source,
        SessionConfig {
            grab_stiffness: None,
            budget: Budget::Cycles(2),
            max_fps: 200.0,
            method: None,
            record_path: None,
        },
    )
    .await;
    let (mut ws, topo) = open(&addr).await;
    assert_eq!(topo, UNCUT);
    send(&mut ws, 1, notch()).await;
    let e = next_of(&mut ws, "error").await;
    assert!(
        e.contains("cut: ") && e.contains("cannot be cut") && e.contains("timed loads"),
        "{e}"
    );
    // A blade 1 m away misses: a cut report of nothing split, no new topology.
    send(
        &mut ws,
        2,
        Command::Cut {
            a: [1.0, 0.0, 1.0],
            b: [1.0, 0.04, 1.0],
            sweep: [0.0, 0.0, -0.02],
        },
    )
    .await;
    let r = next_of(&mut ws, "cut").await;
    assert!(
        r.contains("\"cuts\":0") && r.contains("\"split\":[0]"),
        "{r}"
    );
    let again = tokio::time::timeout(Duration::from_secs(1), next_topology(&mut ws)).await;
    assert!(
        again.is_err(),
        "a refused cut or a blade that missed sent a topology"
    );
}

/// A session with a cut, saved (`--record`) and replayed by the library's interactive run
/// (what `raisov run` calls): the replay makes the cut, its last frame on the cut mesh.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_recorded_cut_replays_with_the_cut() {
    let dir = tempfile::tempdir().unwrap();
    let record = dir.path().join("recorded.toml");
    let source = Source::from_text(CUBE, PathBuf::from("."), "cube", "cube.toml".as_ref())
        .expect("the cube scenario");
    let (addr, _task) = start_session(
        source,
        SessionConfig {
            grab_stiffness: None,
            budget: Budget::Cycles(20),
            max_fps: 200.0,
            method: None,
            record_path: Some(record.clone()),
        },
    )
    .await;
    let (mut ws, _) = open(&addr).await;
    for _ in 0..3 {
        next_frame(&mut ws).await;
    }
    send(&mut ws, 1, notch()).await;
    let (r, _) = text_and_topology(&mut ws, "cut").await;
    let nodes: usize = r
        .split("\"nodes\":")
        .nth(1)
        .and_then(|x| x.split(',').next())
        .and_then(|x| x.parse().ok())
        .expect("the cut's node count");
    for _ in 0..3 {
        next_frame(&mut ws).await;
    }
    send(&mut ws, 2, Command::Save).await;
    let saved = next_of(&mut ws, "recording").await;
    assert!(saved.contains("[[cut]]"), "{saved}");
    let sc = raisov::scenario::Scenario::load(&record).expect("the recording loads");
    let stepper = sc.stepper().expect("its stepper");
    let out = dir.path().join("out");
    let s = raisov::runner::run_interactive(
        &sc,
        stepper,
        raisov::runner::RunOptions {
            out_dir: Some(out.clone()),
            ..Default::default()
        },
    )
    .expect("the recording replays");
    let last = out
        .join("frames")
        .join(format!("{}_{:06}.vtu", sc.name, s.frames));
    let (_, u) = raisov::io::read_vtu_array(&last, "displacement").expect("the last frame");
    assert_eq!(
        u.len() / 3,
        nodes,
        "the replay's last frame is on the cut mesh"
    );
    assert!(nodes > 125);
}

fn dist(p: [f32; 3], q: [f32; 3]) -> f32 {
    ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
}

/// Pairs of vertices at one point (within 1 µm).
fn pairs_at_one_point(p: &[[f32; 3]]) -> Vec<(usize, usize)> {
    let mut v = Vec::new();
    for i in 0..p.len() {
        for j in i + 1..p.len() {
            if dist(p[i], p[j]) < 1e-6 {
                v.push((i, j));
            }
        }
    }
    v
}
