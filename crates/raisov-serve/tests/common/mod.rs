//! What the server's tests share: the soft cube, a server on loopback, a WebSocket client.

#![allow(dead_code)] // each test file uses some of these

use futures_util::{SinkExt, StreamExt};
use raisov::sim::Budget;
use raisov::SchemeKind;
use raisov_serve::access::Access;
use raisov_serve::conn::Limits;
use raisov_serve::protocol::{self, Command, Message};
use raisov_serve::session::{Session, SessionConfig, Source};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;
use tokio_tungstenite::tungstenite::Message as Ws;

/// A 4 cm cube of soft tissue (E = 5 kPa, ν = 0.45) fixed at its base, one level of
/// explicit dynamics (damped) — small enough for a debug test.
pub const CUBE: &str = r#"
name = "cube"
[mesh]
generate = "box"
size = [0.04, 0.04, 0.04]
divisions = [4, 4, 4]
[material]
law = "neo-hookean"
young = 5e3
poisson = 0.45
[damping]
alpha = 50.0
[[fix]]
plane = { point = [0, 0, 0], normal = [0, 0, 1] }
[run]
duration = 1.0
"#;

/// The cube served on loopback at any free port, default limits: its `host:port`.
pub async fn start() -> (String, tokio::task::JoinHandle<()>) {
    let (addr, task, _) = start_with(CUBE, "127.0.0.1:0", None, Limits::default()).await;
    (format!("127.0.0.1:{}", addr.port()), task)
}

/// `scenario` served on `bind` with `limits`, a token where `token` or the address needs
/// one: the bound address, the server task and the access rules.
pub async fn start_with(
    scenario: &str,
    bind: &str,
    token: Option<String>,
    limits: Limits,
) -> (SocketAddr, tokio::task::JoinHandle<()>, Access) {
    let source = Source::from_text(scenario, PathBuf::from("."), "cube", "cube.toml".as_ref())
        .expect("the cube scenario");
    assert_eq!(source.method, SchemeKind::SingleLevel);
    let session = Session::spawn(
        source,
        SessionConfig {
            grab_stiffness: None,
            budget: Budget::Cycles(20),
            max_fps: 200.0,
            method: None,
            record_path: None,
        },
    )
    .expect("session");
    let listener = tokio::net::TcpListener::bind(bind).await.unwrap();
    let addr = listener.local_addr().unwrap();
    let access = Access::for_bound(addr, token).unwrap();
    let served = access.clone();
    let task = tokio::spawn(async move {
        raisov_serve::server::serve(listener, session, served, limits)
            .await
            .unwrap();
    });
    (addr, task, access)
}

/// `source` served on loopback at any free port with `config`, default limits: its
/// `host:port` and the server task.
pub async fn start_session(
    source: Source,
    config: SessionConfig,
) -> (String, tokio::task::JoinHandle<()>) {
    let session = Session::spawn(source, config).expect("session");
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let access = Access::for_bound(addr, None).unwrap();
    let task = tokio::spawn(async move {
        raisov_serve::server::serve(listener, session, access, Limits::default())
            .await
            .unwrap();
    });
    (format!("127.0.0.1:{}", addr.port()), task)
}

pub type Client =
    tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

pub async fn connect(addr: &str) -> Client {
    let (ws, _) = tokio_tungstenite::connect_async(format!("ws://{addr}/ws"))
        .await
        .expect("connect");
    ws
}

pub async fn send(ws: &mut Client, seq: u32, command: Command) {
    ws.send(Ws::Binary(
        protocol::encode(&Message { seq, command }).into(),
    ))
    .await
    .unwrap();
}

/// The next text message (frames skipped), within 10 s.
pub async fn next_text(ws: &mut Client) -> String {
    tokio::time::timeout(Duration::from_secs(10), async {
        loop {
            match ws.next().await {
                Some(Ok(Ws::Text(t))) => return t.to_string(),
                Some(Ok(_)) => {}
                other => panic!("connection ended: {other:?}"),
            }
        }
    })
    .await
    .expect("a text message within 10 s")
}

/// The next frame, within 10 s.
pub async fn next_frame(ws: &mut Client) -> protocol::Frame {
    tokio::time::timeout(Duration::from_secs(10), async {
        loop {
            match ws.next().await {
                Some(Ok(Ws::Binary(b))) => {
                    if let Some(f) = protocol::decode_frame(&b) {
                        return f;
                    }
                }
                Some(Ok(_)) => {}
                other => panic!("connection ended: {other:?}"),
            }
        }
    })
    .await
    .expect("a frame within 10 s")
}

/// The hello and the pins that follow it on connect: the hello.
pub async fn hello(ws: &mut Client) -> String {
    let h = next_text(ws).await;
    assert!(h.contains("\"type\":\"hello\""), "{h}");
    let p = next_text(ws).await;
    assert!(p.contains("\"type\":\"pins\""), "{p}");
    h
}
