//! HTTP and WebSocket: the embedded page (`/`, `/app.js`, `/THREE-LICENSE.txt`) and `/ws`,
//! one task per connection.
//!
//! Every request passes the access checks of [`crate::access`] (Host, token, the WebSocket's
//! Origin) first, over connections admitted and timed out by [`crate::conn`].
//!
//! A connection reads client messages ([`crate::protocol::parse`]), checks that each seq
//! follows the last accepted one ([`seq_after`]), and hands them to the simulation thread
//! through its bounded queue; it writes the topology when it changes, the newest frame whenever one is
//! published (a watch slot: frames published while a send is in progress are skipped, never
//! queued), and the text replies of its own bounded queue (32; a full queue drops replies).
//! The WebSocket layer refuses messages and frames over [`MAX_MESSAGE`] bytes (closing the
//! connection): memory per client is bounded by that, the reply queue and one frame. The
//! server pings every connection's WebSocket every [`Limits::ping_every`]: a page answers
//! by itself, and a client that does not is closed by the idle timeout.

use crate::access::{self, Access};
use crate::conn::{GuardedListener, Limits};
use crate::protocol::{self, MAX_MESSAGE};
use crate::session::{Reply, Session, SessionCmd};
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::State;
use axum::http::{header, StatusCode, Uri};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::Router;
use futures_util::{SinkExt, StreamExt};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Instant;
use tokio::sync::mpsc;

/// Shared by the connections.
pub struct AppState {
    /// The simulation thread.
    pub session: Session,
    next_id: AtomicU64,
    limits: Limits,
}

/// The router of the viewer, behind the access checks of `access`.
pub fn router(session: Session, access: Access, limits: Limits) -> Router {
    let state = Arc::new(AppState {
        session,
        next_id: AtomicU64::new(1),
        limits,
    });
    Router::new()
        .route("/ws", get(ws_handler))
        .fallback(get(asset))
        .with_state(state)
        .layer(axum::middleware::from_fn_with_state(
            Arc::new(access),
            access::check,
        ))
}

/// Serve the viewer on `listener` until the process ends: connections within `limits`
/// ([`crate::conn`]), requests within `access` ([`crate::access`]).
pub async fn serve(
    listener: tokio::net::TcpListener,
    session: Session,
    access: Access,
    limits: Limits,
) -> std::io::Result<()> {
    let app = router(session, access, limits);
    axum::serve(GuardedListener::new(listener, limits), app).await
}

/// Whether `seq` follows `last` in serial-number arithmetic (RFC 1982): it is one of the
/// 2³¹ − 1 values after `last`, modulo 2³². A client's counter thus wraps from 2³² − 1 to
/// 0 and goes on; a message from the 2³¹ values before is out of order.
pub fn seq_after(seq: u32, last: u32) -> bool {
    let d = seq.wrapping_sub(last);
    d != 0 && d < 1 << 31
}

async fn asset(uri: Uri) -> Response {
    match crate::assets::get(uri.path()) {
        Some((body, ty)) => ([(header::CONTENT_TYPE, ty)], body).into_response(),
        None => (StatusCode::NOT_FOUND, "not found").into_response(),
    }
}

async fn ws_handler(ws: WebSocketUpgrade, State(state): State<Arc<AppState>>) -> Response {
    ws.max_message_size(MAX_MESSAGE)
        .max_frame_size(MAX_MESSAGE)
        .on_upgrade(move |socket| client(socket, state))
}

async fn client(socket: WebSocket, state: Arc<AppState>) {
    let id = state.next_id.fetch_add(1, Ordering::Relaxed);
    let (reply_tx, mut reply_rx) = mpsc::channel::<Reply>(32);
    let (mut sink, mut stream) = socket.split();
    if let Err(e) = state.session.send(SessionCmd::Connect {
        id,
        reply: reply_tx,
    }) {
        let _ = sink
            .send(Message::Text(protocol::error_json(e).into()))
            .await;
        return;
    }
    let mut published = state.session.published.clone();
    published.mark_changed();
    let mut topology_sent = 0u64;
    let mut last_seq: Option<u32> = None;
    let every = state.limits.ping_every;
    let mut ping = tokio::time::interval_at(tokio::time::Instant::now() + every, every);
    ping.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        tokio::select! {
            _ = ping.tick() => {
                if sink.send(Message::Ping(Default::default())).await.is_err() {
                    break;
                }
            }
            msg = stream.next() => {
                let msg = match msg {
                    None | Some(Err(_)) => break,
                    Some(Ok(m)) => m,
                };
                let error = match msg {
                    Message::Binary(b) => match protocol::parse(&b) {
                        Ok(m) if last_seq.is_some_and(|l| !seq_after(m.seq, l)) => Some(format!(
                            "out of order: seq {} after {}: dropped",
                            m.seq,
                            last_seq.unwrap_or(0)
                        )),
                        Ok(m) => {
                            last_seq = Some(m.seq);
                            state
                                .session
                                .send(SessionCmd::Client { id, msg: m, arrived: Instant::now() })
                                .err()
                                .map(str::to_string)
                        }
                        Err(e) => Some(format!("{e}: dropped")),
                    },
                    Message::Text(_) => {
                        Some("text messages are not commands (binary only, see the protocol): dropped".into())
                    }
                    Message::Close(_) => break,
                    Message::Ping(_) | Message::Pong(_) => None,
                };
                if let Some(e) = error {
                    if sink.send(Message::Text(protocol::error_json(&e).into())).await.is_err() {
                        break;
                    }
                }
            }
            r = reply_rx.recv() => {
                let Some(Reply::Text(t)) = r else { break };
                if sink.send(Message::Text(t.into())).await.is_err() {
                    break;
                }
            }
            changed = published.changed() => {
                if changed.is_err() {
                    break;
                }
                let p = published.borrow_and_update().clone();
                if p.topology_version != topology_sent {
                    topology_sent = p.topology_version;
                    let t = p.topology.as_ref().clone();
                    if sink.send(Message::Binary(t.into())).await.is_err() {
                        break;
                    }
                }
                if !p.frame.is_empty()
                    && sink.send(Message::Binary(p.frame.clone().into())).await.is_err()
                {
                    break;
                }
            }
        }
    }
    // The disconnect must arrive (it releases the client's grasp): wait for room.
    let tx = state.session.commands.clone();
    let _ = tokio::task::spawn_blocking(move || tx.send(SessionCmd::Disconnect { id })).await;
}
