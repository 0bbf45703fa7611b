//! Connections: how many the server holds, and how long an idle one may stay.
//!
//! [`GuardedListener`] wraps the TCP listener that axum serves. Every accepted connection is
//! a [`GuardedStream`] with a slot in a shared table:
//!
//! - **Header timeout.** A connection must be answered (the server writes its first byte,
//!   which it does once a request's head has arrived) within [`Limits::header_timeout`] of
//!   being accepted; one that sends nothing, or a request head byte by byte, is closed then.
//! - **Idle timeout.** A connection from which nothing was read for [`Limits::idle_timeout`]
//!   is closed. The WebSocket of a live page is pinged every [`Limits::ping_every`] (a
//!   browser answers pings by itself), so only a client that stopped answering goes idle.
//! - **Counts.** At most [`Limits::per_client`] connections from one IP address and
//!   [`Limits::total`] in all (well under the 1 024 file descriptors a process usually gets).
//!   A connection beyond either count takes the place of the oldest connection of that
//!   address (or of any address, for the total) that has not been answered yet, which is
//!   closed; when every connection has been answered, the new one is closed at once.
//!
//! A closed slot wakes the task that reads its stream, which then sees an error and ends.

use std::collections::BTreeMap;
use std::future::Future;
use std::io;
use std::net::{IpAddr, SocketAddr};
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll, Waker};
use std::time::Duration;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::{TcpListener, TcpStream};
use tokio::time::{Instant, Sleep};

/// The server's limits on connections ([module docs](self)).
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    /// Time from accepting a connection to answering its first request.
    pub header_timeout: Duration,
    /// Time without a byte read from the client after which a connection is closed.
    pub idle_timeout: Duration,
    /// Interval of the WebSocket pings.
    pub ping_every: Duration,
    /// Connections from one IP address.
    pub per_client: usize,
    /// Connections in all.
    pub total: usize,
}

impl Default for Limits {
    fn default() -> Limits {
        Limits {
            header_timeout: Duration::from_secs(10),
            idle_timeout: Duration::from_secs(60),
            ping_every: Duration::from_secs(20),
            per_client: 64,
            total: 256,
        }
    }
}

/// What the table and a stream share about one connection.
#[derive(Default)]
struct SlotState {
    /// The server wrote to it (a request was answered).
    answered: AtomicBool,
    /// Closed by the table to make room.
    evicted: AtomicBool,
    /// The task that polls it, to wake on eviction.
    waker: Mutex<Option<Waker>>,
}

struct Slot {
    ip: IpAddr,
    state: Arc<SlotState>,
}

#[derive(Default)]
struct Table {
    /// By accept order (the key), so the first unanswered one is the oldest.
    slots: BTreeMap<u64, Slot>,
    next: u64,
}

impl Table {
    /// Make room for a connection from `ip`: `true` when it may be kept.
    fn admit(&mut self, ip: IpAddr, limits: &Limits) -> bool {
        let from_ip = self.slots.values().filter(|s| s.ip == ip).count();
        if from_ip >= limits.per_client && !self.evict(Some(ip)) {
            return false;
        }
        if self.slots.len() >= limits.total && !self.evict(None) {
            return false;
        }
        true
    }

    /// Close the oldest unanswered connection (of `ip`, if given).
    fn evict(&mut self, ip: Option<IpAddr>) -> bool {
        let victim = self.slots.iter().find_map(|(&k, s)| {
            let mine = ip.is_none_or(|ip| s.ip == ip);
            (mine && !s.state.answered.load(Ordering::Relaxed)).then_some(k)
        });
        let Some(k) = victim else { return false };
        if let Some(s) = self.slots.remove(&k) {
            s.state.evicted.store(true, Ordering::Relaxed);
            if let Some(w) = s.state.waker.lock().ok().and_then(|mut w| w.take()) {
                w.wake();
            }
        }
        true
    }
}

/// A TCP listener that admits connections within [`Limits`] and wraps each in a
/// [`GuardedStream`].
pub struct GuardedListener {
    inner: TcpListener,
    limits: Limits,
    table: Arc<Mutex<Table>>,
}

impl GuardedListener {
    /// Guard `inner` with `limits`.
    pub fn new(inner: TcpListener, limits: Limits) -> GuardedListener {
        GuardedListener {
            inner,
            limits,
            table: Arc::default(),
        }
    }

    /// Connections held now.
    pub fn open_connections(&self) -> usize {
        self.table.lock().map_or(0, |t| t.slots.len())
    }
}

impl axum::serve::Listener for GuardedListener {
    type Io = GuardedStream;
    type Addr = SocketAddr;

    async fn accept(&mut self) -> (GuardedStream, SocketAddr) {
        loop {
            let (stream, addr) = match self.inner.accept().await {
                Ok(s) => s,
                Err(_) => {
                    // Out of descriptors or a connection reset before it was accepted:
                    // wait a little instead of spinning.
                    tokio::time::sleep(Duration::from_millis(50)).await;
                    continue;
                }
            };
            let state = Arc::new(SlotState::default());
            let id = {
                let Ok(mut t) = self.table.lock() else {
                    continue;
                };
                if !t.admit(addr.ip(), &self.limits) {
                    continue; // dropped: closed at once
                }
                let id = t.next;
                t.next += 1;
                t.slots.insert(
                    id,
                    Slot {
                        ip: addr.ip(),
                        state: state.clone(),
                    },
                );
                id
            };
            let _ = stream.set_nodelay(true);
            let now = Instant::now();
            let stream = GuardedStream {
                inner: stream,
                id,
                table: self.table.clone(),
                state,
                header_deadline: Box::pin(tokio::time::sleep_until(
                    now + self.limits.header_timeout,
                )),
                idle_timeout: self.limits.idle_timeout,
                read_idle: Box::pin(tokio::time::sleep_until(now + self.limits.idle_timeout)),
                write_idle: Box::pin(tokio::time::sleep_until(now + self.limits.idle_timeout)),
                last_read: now,
            };
            return (stream, addr);
        }
    }

    fn local_addr(&self) -> io::Result<SocketAddr> {
        self.inner.local_addr()
    }
}

/// An accepted connection under the header and idle timeouts; its slot is freed when it is
/// dropped.
pub struct GuardedStream {
    inner: TcpStream,
    id: u64,
    table: Arc<Mutex<Table>>,
    state: Arc<SlotState>,
    header_deadline: Pin<Box<Sleep>>,
    idle_timeout: Duration,
    /// The idle deadline as seen by reads and by writes (one timer per direction: they may
    /// be polled from different tasks).
    read_idle: Pin<Box<Sleep>>,
    write_idle: Pin<Box<Sleep>>,
    last_read: Instant,
}

impl GuardedStream {
    /// `Err` when the connection must end: evicted, header timeout or idle timeout. Polls the
    /// timers (`idle` of the calling direction) so the task wakes when one runs out.
    fn expired(&mut self, cx: &mut Context<'_>, reading: bool) -> io::Result<()> {
        if self.state.evicted.load(Ordering::Relaxed) {
            return Err(io::Error::new(
                io::ErrorKind::ConnectionAborted,
                "closed to make room for a newer connection",
            ));
        }
        if let Ok(mut w) = self.state.waker.lock() {
            if !w.as_ref().is_some_and(|w| w.will_wake(cx.waker())) {
                *w = Some(cx.waker().clone());
            }
        }
        if !self.state.answered.load(Ordering::Relaxed)
            && self.header_deadline.as_mut().poll(cx).is_ready()
        {
            return Err(io::Error::new(
                io::ErrorKind::TimedOut,
                "no request within the header timeout",
            ));
        }
        let deadline = self.last_read + self.idle_timeout;
        let idle = if reading {
            &mut self.read_idle
        } else {
            &mut self.write_idle
        };
        if idle.deadline() != deadline {
            idle.as_mut().reset(deadline);
        }
        if idle.as_mut().poll(cx).is_ready() {
            return Err(io::Error::new(
                io::ErrorKind::TimedOut,
                "nothing read from the client within the idle timeout",
            ));
        }
        Ok(())
    }
}

impl AsyncRead for GuardedStream {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        let this = &mut *self;
        if let Err(e) = this.expired(cx, true) {
            return Poll::Ready(Err(e));
        }
        let before = buf.filled().len();
        let r = Pin::new(&mut this.inner).poll_read(cx, buf);
        if matches!(r, Poll::Ready(Ok(()))) && buf.filled().len() > before {
            this.last_read = Instant::now();
        }
        r
    }
}

impl AsyncWrite for GuardedStream {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        data: &[u8],
    ) -> Poll<io::Result<usize>> {
        let this = &mut *self;
        if let Err(e) = this.expired(cx, false) {
            return Poll::Ready(Err(e));
        }
        let r = Pin::new(&mut this.inner).poll_write(cx, data);
        if matches!(r, Poll::Ready(Ok(n)) if n > 0) {
            this.state.answered.store(true, Ordering::Relaxed);
        }
        r
    }

    fn poll_write_vectored(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[io::IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        let this = &mut *self;
        if let Err(e) = this.expired(cx, false) {
            return Poll::Ready(Err(e));
        }
        let r = Pin::new(&mut this.inner).poll_write_vectored(cx, bufs);
        if matches!(r, Poll::Ready(Ok(n)) if n > 0) {
            this.state.answered.store(true, Ordering::Relaxed);
        }
        r
    }

    fn is_write_vectored(&self) -> bool {
        self.inner.is_write_vectored()
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        let this = &mut *self;
        if let Err(e) = this.expired(cx, false) {
            return Poll::Ready(Err(e));
        }
        Pin::new(&mut this.inner).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_shutdown(cx)
    }
}

impl Drop for GuardedStream {
    fn drop(&mut self) {
        if let Ok(mut t) = self.table.lock() {
            t.slots.remove(&self.id);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn slot(t: &mut Table, ip: [u8; 4], answered: bool) -> Arc<SlotState> {
        let state = Arc::new(SlotState::default());
        state.answered.store(answered, Ordering::Relaxed);
        let id = t.next;
        t.next += 1;
        t.slots.insert(
            id,
            Slot {
                ip: IpAddr::from(ip),
                state: state.clone(),
            },
        );
        state
    }

    #[test]
    fn a_full_table_evicts_the_oldest_unanswered_connection_of_the_same_client() {
        let limits = Limits {
            per_client: 3,
            total: 5,
            ..Limits::default()
        };
        let mut t = Table::default();
        let a0 = slot(&mut t, [10, 0, 0, 1], true);
        let a1 = slot(&mut t, [10, 0, 0, 1], false);
        let a2 = slot(&mut t, [10, 0, 0, 1], false);
        let b0 = slot(&mut t, [10, 0, 0, 2], false);
        // A fourth from 10.0.0.1: its oldest unanswered one (a1) goes, not the answered a0
        // nor 10.0.0.2's.
        assert!(t.admit(IpAddr::from([10, 0, 0, 1]), &limits));
        assert!(a1.evicted.load(Ordering::Relaxed));
        assert!(!a0.evicted.load(Ordering::Relaxed) && !a2.evicted.load(Ordering::Relaxed));
        assert!(!b0.evicted.load(Ordering::Relaxed));
        assert_eq!(t.slots.len(), 3);
    }

    #[test]
    fn a_table_of_answered_connections_refuses_the_new_one() {
        let limits = Limits {
            per_client: 2,
            total: 3,
            ..Limits::default()
        };
        let mut t = Table::default();
        slot(&mut t, [10, 0, 0, 1], true);
        slot(&mut t, [10, 0, 0, 1], true);
        assert!(!t.admit(IpAddr::from([10, 0, 0, 1]), &limits), "per client");
        slot(&mut t, [10, 0, 0, 2], true);
        assert!(!t.admit(IpAddr::from([10, 0, 0, 3]), &limits), "in all");
        assert_eq!(t.slots.len(), 3);
    }
}
