//! The server end to end over loopback: a WebSocket client grasps and drags a soft cube, and
//! hostile messages (garbage, wrong lengths, NaN, unknown kinds, out of order, 10 MB) are
//! answered with errors while the server keeps serving. The access checks (Host, Origin,
//! token), the connection limits and timeouts, the sleep at rest and the grasp that cannot
//! reach its target are in `hostile_clients.rs`.

use futures_util::{SinkExt, StreamExt};
use raisov::SchemeKind;
use raisov_serve::protocol::{
    self, Command, Message, STAT_FORCE, STAT_GRASP, STAT_GRASPED, STAT_HOLDER,
};
use std::time::Duration;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio_tungstenite::tungstenite::Message as Ws;

mod common;
use common::{connect, hello, next_frame, next_text, send, start};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_grasp_moves_the_grasped_nodes() {
    let (addr, _task) = start().await;
    let mut ws = connect(&addr).await;
    // The hello and the topology, in either order, before 10 s.
    let (mut hello, mut topo) = (None, None);
    tokio::time::timeout(Duration::from_secs(10), async {
        while hello.is_none() || topo.is_none() {
            match ws.next().await.expect("open").expect("a message") {
                Ws::Text(t) if t.contains("\"type\":\"hello\"") => hello = Some(t.to_string()),
                Ws::Binary(b) => {
                    if let Some(t) = protocol::decode_topology(&b) {
                        topo = Some(t);
                    }
                }
                _ => {}
            }
        }
    })
    .await
    .expect("hello and topology within 10 s");
    let (hello, topo) = (hello.unwrap(), topo.unwrap());
    assert!(hello.contains("\"type\":\"hello\""), "{hello}");
    // The cube's boundary: 98 vertices (5³ − 3³), 4·4·2·6 triangles.
    assert_eq!((topo.0, topo.1.len()), (98, 192));
    let rest = next_frame(&mut ws).await;
    assert_eq!(rest.positions.len(), 98);
    // Grasp the top face's centre, radius 5 mm: the node at (0.02, 0.02, 0.04) alone
    // (its neighbours are 1 cm away); lift it by 5 mm.
    send(
        &mut ws,
        1,
        Command::Grab {
            point: [0.02, 0.02, 0.045],
            radius: 0.005,
        },
    )
    .await;
    send(
        &mut ws,
        2,
        Command::Move {
            target: [0.02, 0.02, 0.045],
        },
    )
    .await;
    let top = rest
        .positions
        .iter()
        .position(|p| (p[0] - 0.02).abs() < 1e-6 && (p[1] - 0.02).abs() < 1e-6 && p[2] > 0.039)
        .expect("the top centre node");
    let mut last = None;
    for _ in 0..200 {
        let f = next_frame(&mut ws).await;
        if f.stats[STAT_HOLDER] >= 0.0 && (f.stats[STAT_GRASP + 2] - 0.045).abs() < 1e-6 {
            last = Some(f);
            break;
        }
    }
    let f = last.expect("a frame with the grasp at its target");
    assert_eq!(f.flags & 1, 1);
    assert_eq!(f.stats[STAT_GRASPED], 1.0);
    let p = f.positions[top];
    assert!(
        (p[2] - 0.045).abs() < 1e-6 && (p[0] - 0.02).abs() < 1e-6,
        "the grasped node follows the grasp: {p:?}"
    );
    // The stretched tissue pulls the tool down.
    assert!(f.stats[STAT_FORCE + 2] < 0.0, "force {:?}", &f.stats[5..8]);
    // A free neighbour is dragged up too, less than the grasped node.
    let near = rest
        .positions
        .iter()
        .position(|p| (p[0] - 0.03).abs() < 1e-6 && (p[1] - 0.02).abs() < 1e-6 && p[2] > 0.039)
        .unwrap();
    let dz = f.positions[near][2] - 0.04;
    assert!(dz > 0.0 && dz < 0.005, "neighbour moved {dz} m");
    // Release: the holder notice says nobody holds it.
    send(&mut ws, 3, Command::Release).await;
    loop {
        let t = next_text(&mut ws).await;
        if t.contains("\"holder\":null") {
            break;
        }
    }
    // A recording ends at the last frame stepped (crate::record): wait for a frame stepped
    // after the release, or a save that races ahead of it records the grasp still held.
    for _ in 0..200 {
        if next_frame(&mut ws).await.stats[STAT_HOLDER] < 0.0 {
            break;
        }
    }
    // The recording comes back as a scenario with the grasp as a [[displace]] with a radius.
    send(&mut ws, 4, Command::Save).await;
    let rec = loop {
        let t = next_text(&mut ws).await;
        if t.contains("\"type\":\"recording\"") {
            break t;
        }
    };
    assert!(
        rec.contains("[[displace]]") && rec.contains("radius"),
        "{rec}"
    );
    // It is a scenario `raisov run` accepts: the grasp taken and let go during the run.
    let body = rec
        .split_once("\"toml\":\"")
        .and_then(|(_, b)| b.strip_suffix("\"}"))
        .expect("the toml field");
    let text = body
        .replace("\\n", "\n")
        .replace("\\\"", "\"")
        .replace("\\\\", "\\");
    let sc = raisov::scenario::Scenario::from_toml(&text, "recorded.toml".as_ref())
        .unwrap_or_else(|e| panic!("{e}\n{text}"));
    assert_eq!((sc.grasps.len(), sc.prescribed.len()), (1, 0), "{text}");
    assert!(sc.interactive.is_some());
    let g = &sc.grasps[0];
    assert!(g.release.is_some(), "let go: {text}");
    let d = g.motion.displacement(1e9);
    assert!(
        (d[2] - 0.005).abs() < 1e-6,
        "moved to the last target: {d:?}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn hostile_messages_leave_the_server_serving() {
    let (addr, _task) = start().await;
    let mut ws = connect(&addr).await;
    hello(&mut ws).await;
    let good = protocol::encode(&Message {
        seq: 5,
        command: Command::Grab {
            point: [0.02, 0.02, 0.04],
            radius: 0.0,
        },
    });
    let mut nan = good.clone();
    nan[12..16].copy_from_slice(&f32::NAN.to_le_bytes());
    let mut unknown = good.clone();
    unknown[0] = 200;
    let hostile: Vec<(Ws, &str)> = vec![
        (
            Ws::Binary(vec![0xde, 0xad, 0xbe, 0xef, 1, 2, 3].into()),
            "shorter",
        ),
        (
            Ws::Binary((0..24).map(|i| (i * 37) as u8).collect::<Vec<u8>>().into()),
            "",
        ),
        (Ws::Binary(good[..20].to_vec().into()), "must be 24"),
        (Ws::Binary(nan.into()), "finite"),
        (Ws::Binary(unknown.into()), "unknown message kind 200"),
        (Ws::Text("{\"grab\": 1}".into()), "text messages"),
    ];
    for (m, want) in hostile {
        ws.send(m).await.unwrap();
        let e = next_text(&mut ws).await;
        assert!(e.contains("\"type\":\"error\"") && e.contains(want), "{e}");
    }
    // Moves and releases before a grasp are out of order; so is a seq that goes back.
    send(&mut ws, 10, Command::Move { target: [0.0; 3] }).await;
    assert!(next_text(&mut ws).await.contains("without a grasp"));
    send(&mut ws, 11, Command::Release).await;
    assert!(next_text(&mut ws).await.contains("without a grasp"));
    send(&mut ws, 9, Command::Reset).await;
    assert!(next_text(&mut ws).await.contains("out of order"));
    // A grasp still works on the same connection.
    send(
        &mut ws,
        12,
        Command::Grab {
            point: [0.02, 0.02, 0.04],
            radius: 0.0,
        },
    )
    .await;
    loop {
        let t = next_text(&mut ws).await;
        assert!(!t.contains("error"), "{t}");
        if t.contains("\"type\":\"holder\"") {
            break;
        }
    }
    // A second client watches: its grasp is refused while the first holds.
    let mut other = connect(&addr).await;
    hello(&mut other).await;
    send(
        &mut other,
        1,
        Command::Grab {
            point: [0.0, 0.0, 0.04],
            radius: 0.0,
        },
    )
    .await;
    loop {
        let t = next_text(&mut other).await;
        if t.contains("error") {
            assert!(t.contains("holds the grasp"), "{t}");
            break;
        }
    }
    // 10 MB in one message: the connection is closed, nothing else happens.
    let big = vec![7u8; 10 << 20];
    let _ = ws.send(Ws::Binary(big.into())).await;
    let closed = tokio::time::timeout(Duration::from_secs(10), async {
        loop {
            match ws.next().await {
                None | Some(Err(_)) | Some(Ok(Ws::Close(_))) => return true,
                Some(Ok(_)) => {}
            }
        }
    })
    .await
    .unwrap_or(false);
    assert!(closed, "a 10 MB message closes its connection");
    // The watcher keeps getting frames, and the first client's grasp was released.
    next_frame(&mut other).await;
    let mut released = false;
    for _ in 0..100 {
        let f = next_frame(&mut other).await;
        if f.stats[STAT_HOLDER] < 0.0 {
            released = true;
            break;
        }
    }
    assert!(released, "the closed client's grasp is released");
    // New connections are served, and so is the page.
    let mut third = connect(&addr).await;
    hello(&mut third).await;
    next_frame(&mut third).await;
    let mut tcp = tokio::net::TcpStream::connect(&addr).await.unwrap();
    let get = format!("GET / HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n");
    tcp.write_all(get.as_bytes()).await.unwrap();
    let mut page = String::new();
    tcp.read_to_string(&mut page).await.unwrap();
    assert!(page.starts_with("HTTP/1.1 200") && page.contains("raisov serve"));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn method_switch_keeps_the_grasp() {
    let (addr, _task) = start().await;
    let mut ws = connect(&addr).await;
    hello(&mut ws).await;
    send(
        &mut ws,
        1,
        Command::Grab {
            point: [0.02, 0.02, 0.04],
            radius: 0.0,
        },
    )
    .await;
    send(
        &mut ws,
        2,
        Command::Move {
            target: [0.02, 0.02, 0.043],
        },
    )
    .await;
    // FAS, then the frame solver, on the cube's generated levels (a second one made for them).
    for (seq, m) in [(3, SchemeKind::Fas), (4, SchemeKind::Newton)] {
        send(&mut ws, seq, Command::Method(m)).await;
        loop {
            let t = next_text(&mut ws).await;
            assert!(!t.contains("error"), "{t}");
            if t.contains("\"type\":\"method\"") {
                assert!(
                    t.contains(&format!("\"method\":{}", protocol::method_code(m))),
                    "{t}"
                );
                break;
            }
        }
        let mut ok = false;
        for _ in 0..200 {
            let f = next_frame(&mut ws).await;
            if f.stats[protocol::STAT_METHOD] == protocol::method_code(m) as f32
                && f.stats[STAT_HOLDER] >= 0.0
                && (f.stats[STAT_GRASP + 2] - 0.043).abs() < 1e-6
            {
                ok = true;
                break;
            }
        }
        assert!(
            ok,
            "after the switch to {m:?} the grasp holds at its target"
        );
    }
}
