//! The server against hostile and idle clients, with real sockets: web pages of other sites,
//! DNS rebinding, a server exposed beyond loopback without its token, floods of idle
//! sockets, clients that stop answering, a message counter that wraps; and the simulation
//! thread that sleeps when nobody needs frames and keeps its frame rate when a grasp cannot
//! reach its target.

use futures_util::{SinkExt, StreamExt};
use raisov_serve::conn::Limits;
use raisov_serve::protocol::{self, Command, FLAG_REST, FLAG_STUCK, STAT_REJECTED_TRIES};
use std::time::{Duration, Instant};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use tokio_tungstenite::tungstenite::http::HeaderValue;
use tokio_tungstenite::tungstenite::Message as Ws;

mod common;
use common::{connect, hello, next_frame, next_text, send, start, start_with, CUBE};

/// `GET path` with these extra header lines on a new connection: the status line and the
/// whole response.
async fn get(addr: &str, path: &str, host: &str, extra: &str) -> (String, String) {
    let mut tcp = TcpStream::connect(addr).await.unwrap();
    let req = format!("GET {path} HTTP/1.1\r\nHost: {host}\r\n{extra}Connection: close\r\n\r\n");
    tcp.write_all(req.as_bytes()).await.unwrap();
    let mut resp = String::new();
    tokio::time::timeout(Duration::from_secs(10), tcp.read_to_string(&mut resp))
        .await
        .expect("an answer within 10 s")
        .unwrap();
    let status = resp.lines().next().unwrap_or("").to_string();
    (status, resp)
}

/// A WebSocket handshake with `origin` (if any) and `host`: `Ok` when upgraded, else the
/// HTTP status.
async fn ws_with(addr: &str, path: &str, host: &str, origin: Option<&str>) -> Result<(), u16> {
    let mut req = format!("ws://{addr}{path}").into_client_request().unwrap();
    req.headers_mut()
        .insert("host", HeaderValue::from_str(host).unwrap());
    if let Some(o) = origin {
        req.headers_mut()
            .insert("origin", HeaderValue::from_str(o).unwrap());
    }
    match tokio_tungstenite::connect_async(req).await {
        Ok(_) => Ok(()),
        Err(tokio_tungstenite::tungstenite::Error::Http(r)) => Err(r.status().as_u16()),
        Err(e) => panic!("handshake: {e}"),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_web_page_of_another_site_cannot_open_the_websocket() {
    let (addr, _task) = start().await;
    // The server's own page may; so may a program that sends no Origin.
    assert_eq!(
        ws_with(&addr, "/ws", &addr, Some(&format!("http://{addr}"))).await,
        Ok(())
    );
    assert_eq!(ws_with(&addr, "/ws", &addr, None).await, Ok(()));
    // Another site's page, open in the same browser, may not.
    for origin in ["http://evil.example", "https://evil.example:8080", "null"] {
        assert_eq!(
            ws_with(&addr, "/ws", &addr, Some(origin)).await,
            Err(403),
            "{origin}"
        );
    }
    // The refusal says why, in words.
    let (status, body) = get(&addr, "/ws", &addr, "Origin: http://evil.example\r\n").await;
    assert!(status.contains("403"), "{status}");
    assert!(body.contains("only this server's own page"), "{body}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn dns_rebinding_is_refused_by_the_host_check() {
    let (addr, _task) = start().await;
    let port = addr.rsplit(':').next().unwrap();
    // A page of evil.example whose name now resolves to 127.0.0.1 sends its own Host.
    let (status, body) = get(&addr, "/", &format!("evil.example:{port}"), "").await;
    assert!(status.contains("403"), "{status}");
    assert!(body.contains("is not this server"), "{body}");
    let rebound = format!("evil.example:{port}");
    assert_eq!(
        ws_with(&addr, "/ws", &rebound, Some(&format!("http://{rebound}"))).await,
        Err(403)
    );
    // The loopback names on the right port are served.
    for host in [
        format!("localhost:{port}"),
        addr.clone(),
        format!("[::1]:{port}"),
    ] {
        let (status, _) = get(&addr, "/", &host, "").await;
        assert!(status.contains("200"), "{host}: {status}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_server_bound_beyond_loopback_needs_its_token() {
    let (bound, _task, access) = start_with(CUBE, "0.0.0.0:0", None, Limits::default()).await;
    let token = access
        .token()
        .expect("a token for a non-loopback bind")
        .to_string();
    let addr = format!("127.0.0.1:{}", bound.port());
    let host = format!("my-machine.lan:{}", bound.port());
    // Without the token, or with another, nothing: not the page, not the WebSocket.
    let (status, body) = get(&addr, "/", &host, "").await;
    assert!(
        status.contains("403") && body.contains("needs its token"),
        "{body}"
    );
    let wrong = "0123456789abcdef0123456789abcdef";
    let (status, _) = get(&addr, &format!("/?token={wrong}"), &host, "").await;
    assert!(status.contains("403"), "{status}");
    assert_eq!(ws_with(&addr, "/ws", &host, None).await, Err(403));
    // The printed URL opens the page and sets the cookie the page's requests carry.
    let (status, resp) = get(&addr, &format!("/?token={token}"), &host, "").await;
    assert!(status.contains("200"), "{status}");
    let cookie = format!("raisov_token_{}={token}", bound.port());
    assert!(
        resp.lines()
            .any(|l| l.to_ascii_lowercase().starts_with("set-cookie:")
                && l.contains(&cookie)
                && l.contains("HttpOnly")
                && l.contains("SameSite=Strict")),
        "{resp}"
    );
    let (status, _) = get(&addr, "/app.js", &host, &format!("Cookie: {cookie}\r\n")).await;
    assert!(status.contains("200"), "{status}");
    // The WebSocket with the cookie, from the page of the same host.
    let mut req = format!("ws://{addr}/ws").into_client_request().unwrap();
    let h = req.headers_mut();
    h.insert("host", HeaderValue::from_str(&host).unwrap());
    h.insert(
        "origin",
        HeaderValue::from_str(&format!("http://{host}")).unwrap(),
    );
    h.insert("cookie", HeaderValue::from_str(&cookie).unwrap());
    let (mut ws, _) = tokio_tungstenite::connect_async(req)
        .await
        .expect("upgraded");
    hello(&mut ws).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_flood_of_idle_sockets_does_not_starve_the_page() {
    let limits = Limits {
        header_timeout: Duration::from_millis(1500),
        ..Limits::default()
    };
    let (bound, _task, _) = start_with(CUBE, "127.0.0.1:0", None, limits).await;
    let addr = bound.to_string();
    // 1 100 sockets that never send a byte (more than the 1 024 descriptors a process
    // usually has, and more than the server holds).
    let mut idle = Vec::new();
    for _ in 0..1100 {
        match TcpStream::connect(&addr).await {
            Ok(s) => idle.push(s),
            Err(_) => break, // the test process's own descriptors ran out
        }
    }
    assert!(idle.len() > 300, "opened {}", idle.len());
    // The page is still served, at once.
    let t = Instant::now();
    let (status, _) = get(&addr, "/", &addr, "").await;
    assert!(status.contains("200"), "{status}");
    assert!(t.elapsed() < Duration::from_secs(5), "{:?}", t.elapsed());
    // Every idle socket is closed by the server: by the count, or by the header timeout.
    let closed = tokio::time::timeout(Duration::from_secs(10), async {
        let mut n = 0;
        for s in &mut idle {
            let mut b = [0u8; 1];
            if matches!(s.read(&mut b).await, Ok(0) | Err(_)) {
                n += 1;
            }
        }
        n
    })
    .await
    .expect("the idle sockets are closed within 10 s");
    assert_eq!(closed, idle.len());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_that_stops_answering_pings_is_closed() {
    let limits = Limits {
        idle_timeout: Duration::from_millis(1200),
        ping_every: Duration::from_millis(300),
        ..Limits::default()
    };
    let (bound, _task, _) = start_with(CUBE, "127.0.0.1:0", None, limits).await;
    let addr = bound.to_string();
    // A live client reads (and so answers the pings): still served after 3 idle timeouts.
    let mut live = connect(&addr).await;
    // A dead one: the handshake, then silence.
    let mut dead = TcpStream::connect(&addr).await.unwrap();
    let req = format!(
        "GET /ws HTTP/1.1\r\nHost: {addr}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n\
         Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n"
    );
    dead.write_all(req.as_bytes()).await.unwrap();
    let t = Instant::now();
    while t.elapsed() < Duration::from_millis(3600) {
        let _ = tokio::time::timeout(Duration::from_millis(100), live.next()).await;
    }
    send(&mut live, 1, Command::Reset).await;
    next_frame(&mut live).await;
    // The dead client's connection was closed: reading it drains what was sent, then ends.
    let ended = tokio::time::timeout(Duration::from_secs(5), async {
        let mut b = vec![0u8; 1 << 16];
        loop {
            match dead.read(&mut b).await {
                Ok(0) | Err(_) => return true,
                Ok(_) => {}
            }
        }
    })
    .await
    .unwrap_or(false);
    assert!(ended, "the silent client was not closed");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_message_counter_wrapping_past_u32_max_is_not_locked_out() {
    let (addr, _task) = start().await;
    let mut ws = connect(&addr).await;
    hello(&mut ws).await;
    let grab = Command::Grab {
        point: [0.02, 0.02, 0.04],
        radius: 0.0,
    };
    send(&mut ws, u32::MAX - 1, grab).await;
    assert!(next_text(&mut ws).await.contains("\"type\":\"holder\""));
    for seq in [u32::MAX, 0, 1] {
        send(
            &mut ws,
            seq,
            Command::Move {
                target: [0.02, 0.02, 0.041],
            },
        )
        .await;
    }
    send(&mut ws, 2, Command::Release).await;
    // Every one was accepted: the next text is the release's holder notice, no error.
    let t = next_text(&mut ws).await;
    assert!(t.contains("\"holder\":null"), "{t}");
    // A seq from before the wrap is still out of order.
    send(&mut ws, u32::MAX, Command::Reset).await;
    assert!(next_text(&mut ws).await.contains("out of order"));
}

/// The number of the next frame, and whether it carries `flag`, waiting at most `wait`.
async fn frame_within(ws: &mut common::Client, wait: Duration) -> Option<protocol::Frame> {
    tokio::time::timeout(wait, next_frame(ws)).await.ok()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_idle_viewer_stops_stepping_until_a_command_arrives() {
    let (addr, _task) = start().await;
    let mut ws = connect(&addr).await;
    // The cube carries no load: at rest from the start. Within a second a frame says so…
    let rest = tokio::time::timeout(Duration::from_secs(10), async {
        loop {
            let f = next_frame(&mut ws).await;
            if f.flags & FLAG_REST != 0 {
                return f;
            }
        }
    })
    .await
    .expect("a frame at rest");
    // …and no frame follows (at 200 frames/s, a stepping thread would send ~200).
    assert!(frame_within(&mut ws, Duration::from_secs(1))
        .await
        .is_none());
    // A grasp wakes it: frames flow and the grasp moves the cube.
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
            target: [0.02, 0.02, 0.042],
        },
    )
    .await;
    let f = frame_within(&mut ws, Duration::from_secs(5))
        .await
        .expect("frames again after a command");
    assert!(f.number > rest.number && f.flags & FLAG_REST == 0);
    // With nobody connected it sleeps too: a client connecting after a second gets the
    // frame it left, numbered within a few frames of it.
    send(&mut ws, 3, Command::Release).await;
    let mut last = f.number;
    while let Some(f) = frame_within(&mut ws, Duration::from_millis(500)).await {
        last = f.number;
    }
    drop(ws);
    tokio::time::sleep(Duration::from_secs(1)).await;
    let mut again = connect(&addr).await;
    let f = next_frame(&mut again).await;
    assert!(
        f.number <= last + 3,
        "the thread stepped with nobody connected: frame {} after {last}",
        f.number
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_grasp_that_cannot_reach_its_target_is_reported_and_frames_keep_flowing() {
    let (addr, _task) = start().await;
    let mut holder = connect(&addr).await;
    let mut watcher = connect(&addr).await;
    hello(&mut holder).await;
    hello(&mut watcher).await;
    // Grasp the top centre node and push it 6 cm down, through the fixed base: the
    // neo-Hookean cube inverts on the way, whatever the sub-moves.
    send(
        &mut holder,
        1,
        Command::Grab {
            point: [0.02, 0.02, 0.04],
            radius: 0.0,
        },
    )
    .await;
    send(
        &mut holder,
        2,
        Command::Move {
            target: [0.02, 0.02, -0.02],
        },
    )
    .await;
    let msg = loop {
        let t = next_text(&mut holder).await;
        if t.contains("error") {
            break t;
        }
    };
    assert!(
        msg.contains("cannot reach") && msg.contains("inverted"),
        "{msg}"
    );
    // That frame tried 1, 2, 4, 8 and 16 sub-moves and threw each try away.
    let first = tokio::time::timeout(Duration::from_secs(10), async {
        loop {
            let f = next_frame(&mut watcher).await;
            if f.stats[STAT_REJECTED_TRIES] > 0.0 {
                return f;
            }
        }
    })
    .await
    .expect("the rejected frame");
    assert_eq!(first.stats[STAT_REJECTED_TRIES], 5.0);
    // Frames carry the flag and the grasp holds where it was (0.04 m up).
    let mut stuck = 0;
    for _ in 0..20 {
        let f = next_frame(&mut watcher).await;
        if f.flags & FLAG_STUCK != 0 {
            stuck += 1;
            assert!((f.stats[protocol::STAT_GRASP + 2] - 0.04).abs() < 1e-6);
            assert_eq!(
                f.stats[STAT_REJECTED_TRIES], 0.0,
                "no retries while it holds"
            );
        }
    }
    assert!(stuck > 0);
    // A new unreachable target costs one try, not five: the other viewers' frames keep
    // their rate.
    send(
        &mut holder,
        3,
        Command::Move {
            target: [0.02, 0.02, -0.03],
        },
    )
    .await;
    let again = tokio::time::timeout(Duration::from_secs(10), async {
        loop {
            let f = next_frame(&mut watcher).await;
            if f.stats[STAT_REJECTED_TRIES] > 0.0 {
                return f;
            }
        }
    })
    .await
    .expect("the second rejected frame");
    assert_eq!(again.stats[STAT_REJECTED_TRIES], 1.0);
    // Back within reach: the grasp moves again and the flag clears.
    send(
        &mut holder,
        4,
        Command::Move {
            target: [0.02, 0.02, 0.042],
        },
    )
    .await;
    let moved = tokio::time::timeout(Duration::from_secs(10), async {
        loop {
            let f = next_frame(&mut watcher).await;
            if f.flags & FLAG_STUCK == 0 && (f.stats[protocol::STAT_GRASP + 2] - 0.042).abs() < 1e-6
            {
                return true;
            }
        }
    })
    .await
    .unwrap_or(false);
    assert!(moved, "the grasp follows a reachable target again");
    let _ = holder.send(Ws::Close(None)).await;
}
