//! The WebSocket protocol between `raisov serve` and its page: binary little-endian messages.
//!
//! # Client → server
//!
//! Every message is one binary WebSocket message of an exact length:
//!
//! ```text
//! offset 0   u8   kind
//! offset 1   u8×3 zero
//! offset 4   u32  seq: increasing per connection, modulo 2^32 (a message whose seq is not
//!                 one of the 2^31 - 1 values after the last accepted one is out of order
//!                 and dropped; the counter wraps from 2^32 - 1 to 0)
//! offset 8   payload, by kind (f32 unless said):
//!   1 grab     point x y z (m), radius (m)           24 bytes in all
//!   2 move     target x y z (m)                      20
//!   3 release  —                                      8
//!   4 pin      point x y z (m), radius (m)           24
//!   5 reset    —                                      8
//!   6 method   u32: 0 FAS, 1 RaISoV (paper), 2 single level, 3 frame solver   12
//!              (code i: the raisov::SchemeKind METHODS[i])
//!   7 colour   u32: 0 displacement magnitude (m), 1 von Mises stress (Pa)  12
//!   8 save     — (reply: a text message with the recorded scenario)  8
//!   9 cut      edge point a x y z, edge point b x y z, sweep x y z (m)  44
//! ```
//!
//! A cut is the planar blade `raisov::mesh::cut::Blade::swept(a, b, sweep)`: the quad with
//! corners `a`, `b`, `b + sweep`, `a + sweep`, a scalpel drawn on the surface from `a` to `b`
//! and pushed to the depth `|sweep|` along `sweep`'s direction.
//!
//! A message of another length, an unknown kind, a non-zero pad, a non-finite or
//! out-of-range number (|x| > [`MAX_COORD`] m, radius outside `[0, MAX_RADIUS]` m, a cut's
//! sweep of length 0 or above [`MAX_DEPTH`] m, a cut's edge points `a = b`) is answered with
//! an error (a text message `{"type":"error","message":…}`) and dropped; so is a text
//! message, and anything longer than [`MAX_MESSAGE`] bytes closes the connection.
//!
//! # Server → client
//!
//! Binary messages start with a 4-byte magic:
//!
//! ```text
//! topology  "RSVT"  u32 vertex count n, u32 triangle count m, then u32 × 3m vertex indices
//!                   (sent once per connection, and after a method switch, a reset or a
//!                   cut that split elements: n and m change with every cut)
//! frame     "RSVF"  u32 frame number, u32 n, u32 flags (bit 0: a grasp is held, bit 1: the
//!                   scalar is stress, bit 2: at rest, the simulation sleeps until a command
//!                   arrives, bit 3: the grasp cannot reach its target, bit 4: the scheme
//!                   diverged and the simulation waits), f32 × 18 stats
//!                   (STAT_* indices), f32 × 3n surface positions (m), f32 × n scalar
//!                   (m or Pa): 88 + 16 n bytes
//! ```
//!
//! Text messages are small JSON objects: `hello` (client id, methods, the frame budget
//! `{"ms": …}` or `{"cycles": …}`, the frame-rate cap `max_fps`), `error`, `holder` (who holds
//! the grasp), `pins` (every pin's point and radius, m: sent on connect and whenever they
//! change), `recording` (the scenario TOML), `cut` (to every client after a cut: the client
//! that cut, the elements split per level `split`, level 0's `nodes` and `elements` after
//! it, its wall time `ms`, the cuts so far `cuts`, and the surface's `vertices` and
//! `triangles`, the counts of the topology message that follows; a blade that missed splits
//! nothing and is not counted).

use raisov::SchemeKind;
use thiserror::Error;

/// The largest client message accepted by the WebSocket layer (bytes); larger ones close
/// the connection before they are buffered whole.
pub const MAX_MESSAGE: usize = 4096;
/// The largest coordinate a client may send (m).
pub const MAX_COORD: f32 = 100.0;
/// The largest grasp or pin radius (m).
pub const MAX_RADIUS: f32 = 1.0;
/// The longest sweep of a cut (m): the deepest a blade is pushed.
pub const MAX_DEPTH: f32 = 0.5;

/// Magic of a topology message.
pub const TOPOLOGY_MAGIC: &[u8; 4] = b"RSVT";
/// Magic of a frame message.
pub const FRAME_MAGIC: &[u8; 4] = b"RSVF";
/// Bytes before the positions of a frame message.
pub const FRAME_HEADER: usize = 16 + 4 * STATS;
/// Number of f32 stats in a frame.
pub const STATS: usize = 18;

/// Frame flag: a grasp is held.
pub const FLAG_HELD: u32 = 1;
/// Frame flag: the scalar is the von Mises stress (else the displacement magnitude).
pub const FLAG_STRESS: u32 = 2;
/// Frame flag: at rest; the simulation sleeps until a command arrives (no frames follow).
pub const FLAG_REST: u32 = 4;
/// Frame flag: the held grasp cannot reach its target (it holds where it was).
pub const FLAG_STUCK: u32 = 8;
/// Frame flag: the scheme diverged with no grasp moving; the simulation waits for a command.
pub const FLAG_DIVERGED: u32 = 16;

/// Stat index: simulation frames per second (frames of the simulation thread, 1 s window).
pub const STAT_SIM_FPS: usize = 0;
/// Stat index: largest nodal residual over free nodes at the end of the frame (N).
pub const STAT_RESIDUAL: usize = 1;
/// Stat index: stepper cycles of the frame.
pub const STAT_CYCLES: usize = 2;
/// Stat index: wall time of the frame's stepping (ms).
pub const STAT_FRAME_MS: usize = 3;
/// Stat index: time from the arrival of the newest applied grasp message to the end of the
/// frame that applied it (ms); the server-side part of the input lag.
pub const STAT_INPUT_LAG_MS: usize = 4;
/// Stat index: grasp force x, y, z (N): the force the tissue exerts on the tool.
pub const STAT_FORCE: usize = 5;
/// Stat index: grasp position x, y, z (m).
pub const STAT_GRASP: usize = 8;
/// Stat index: the largest scalar of the frame (m or Pa).
pub const STAT_SCALAR_MAX: usize = 11;
/// Stat index: the method ([`method_code`]).
pub const STAT_METHOD: usize = 12;
/// Stat index: the seq of the holder's newest message applied in this frame (exact in f32
/// up to 2^24).
pub const STAT_APPLIED_SEQ: usize = 13;
/// Stat index: the client id holding the grasp, −1 for none.
pub const STAT_HOLDER: usize = 14;
/// Stat index: the grasped node count.
pub const STAT_GRASPED: usize = 15;
/// Stat index: the frame's rejected tries ([`raisov::sim::FrameReport::retries`]).
pub const STAT_REJECTED_TRIES: usize = 16;
/// Stat index: steps of the frame's rejected tries, thrown away
/// ([`raisov::sim::FrameReport::rejected_cycles`]).
pub const STAT_REJECTED_STEPS: usize = 17;

/// The schemes the page offers, in wire-code order: code `i` is `METHODS[i]`.
pub const METHODS: [SchemeKind; 4] = [
    SchemeKind::Fas,
    SchemeKind::RaisovPaper,
    SchemeKind::SingleLevel,
    SchemeKind::Newton,
];

/// The wire code of a scheme: its place in [`METHODS`]. Backward Euler and BDF2 are served
/// as the page's single level (code 2): a scenario integrated by them runs on level 0, its
/// levels preconditioning the Newton solves (`session::Source::table_for`).
pub fn method_code(k: SchemeKind) -> u32 {
    match k {
        SchemeKind::Fas => 0,
        SchemeKind::RaisovPaper => 1,
        SchemeKind::SingleLevel | SchemeKind::ImplicitEuler | SchemeKind::Bdf2 => 2,
        SchemeKind::Newton => 3,
    }
}

/// The scheme of a wire code, `None` past [`METHODS`].
pub fn method_from_code(c: u32) -> Option<SchemeKind> {
    METHODS.get(c as usize).copied()
}

/// The name the page shows for a scheme (the label of its [`method_code`]).
pub fn method_label(k: SchemeKind) -> &'static str {
    match method_code(k) {
        0 => "FAS multigrid",
        1 => "RaISoV (paper)",
        3 => "frame solver (Newton)",
        _ => "single level",
    }
}

/// The simulation scheme the viewer runs, by its old names.
#[deprecated(
    note = "the protocol speaks `raisov::SchemeKind`: `METHODS`, `method_code`, \
                     `method_from_code`, `method_label`"
)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// [`SchemeKind::Fas`].
    Fas,
    /// [`SchemeKind::RaisovPaper`].
    Raisov,
    /// [`SchemeKind::SingleLevel`].
    Single,
    /// [`SchemeKind::Newton`].
    Newton,
}

#[allow(deprecated)]
impl Method {
    /// Every method, in code order.
    pub const ALL: [Method; 4] = [Method::Fas, Method::Raisov, Method::Single, Method::Newton];
    /// The wire code ([`method_code`]).
    pub fn code(self) -> u32 {
        method_code(self.into())
    }
    /// The method of a wire code ([`method_from_code`]).
    pub fn from_code(c: u32) -> Option<Method> {
        Method::ALL.get(c as usize).copied()
    }
    /// The name the page shows ([`method_label`]).
    pub fn label(self) -> &'static str {
        method_label(self.into())
    }
}

#[allow(deprecated)]
impl From<Method> for SchemeKind {
    fn from(m: Method) -> SchemeKind {
        match m {
            Method::Fas => SchemeKind::Fas,
            Method::Raisov => SchemeKind::RaisovPaper,
            Method::Single => SchemeKind::SingleLevel,
            Method::Newton => SchemeKind::Newton,
        }
    }
}

/// What the colour map shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Colour {
    /// |u| (m).
    Displacement,
    /// von Mises stress (Pa).
    Stress,
}

/// A client's command.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Command {
    /// Grasp the surface near `point` within `radius`.
    Grab {
        /// m
        point: [f32; 3],
        /// m
        radius: f32,
    },
    /// Move the held grasp to `target`.
    Move {
        /// m
        target: [f32; 3],
    },
    /// Let go.
    Release,
    /// Pin the surface near `point`.
    Pin {
        /// m
        point: [f32; 3],
        /// m
        radius: f32,
    },
    /// Back to the rest state, no grasp, no pins.
    Reset,
    /// Switch the scheme (one of [`METHODS`]).
    Method(SchemeKind),
    /// Switch the colour map.
    Colour(Colour),
    /// Send back the recorded scenario.
    Save,
    /// Cut with the blade the edge `a`–`b` sweeps along `sweep` (module docs).
    Cut {
        /// Edge point a (m).
        a: [f32; 3],
        /// Edge point b (m).
        b: [f32; 3],
        /// The sweep (m): direction and depth.
        sweep: [f32; 3],
    },
}

/// A command with its sequence number.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Message {
    /// Per-connection sequence number.
    pub seq: u32,
    /// The command.
    pub command: Command,
}

/// Why a client message was dropped.
#[derive(Debug, Error, PartialEq)]
pub enum ProtocolError {
    /// Shorter than a header.
    #[error("message of {0} bytes: shorter than the 8-byte header (kind, 3 zero bytes, seq)")]
    Short(usize),
    /// Unknown kind byte.
    #[error("unknown message kind {0}: valid are 1 grab, 2 move, 3 release, 4 pin, 5 reset, 6 method, 7 colour, 8 save, 9 cut")]
    UnknownKind(u8),
    /// Wrong length for the kind.
    #[error("{kind} message of {got} bytes: must be {want}")]
    Length {
        /// kind name
        kind: &'static str,
        /// received
        got: usize,
        /// expected
        want: usize,
    },
    /// Non-zero padding.
    #[error("bytes 1..4 of the header must be zero")]
    Padding,
    /// A number out of range.
    #[error("{what} = {value}: {why}")]
    Value {
        /// which field
        what: &'static str,
        /// value received
        value: f32,
        /// what is valid
        why: &'static str,
    },
    /// An unknown method or colour code.
    #[error("{what} code {code}: valid are {valid}")]
    Code {
        /// which field
        what: &'static str,
        /// value received
        code: u32,
        /// valid codes
        valid: &'static str,
    },
}

fn kind_name(kind: u8) -> Option<(&'static str, usize)> {
    Some(match kind {
        1 => ("grab", 24),
        2 => ("move", 20),
        3 => ("release", 8),
        4 => ("pin", 24),
        5 => ("reset", 8),
        6 => ("method", 12),
        7 => ("colour", 12),
        8 => ("save", 8),
        9 => ("cut", 44),
        _ => return None,
    })
}

fn f32_at(b: &[u8], at: usize) -> f32 {
    f32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

fn coords(b: &[u8], what: &'static str) -> Result<[f32; 3], ProtocolError> {
    coords_at(b, 8, what)
}

/// Three coordinates from byte `at`: finite, |x| <= [`MAX_COORD`].
fn coords_at(b: &[u8], at: usize, what: &'static str) -> Result<[f32; 3], ProtocolError> {
    let p = [f32_at(b, at), f32_at(b, at + 4), f32_at(b, at + 8)];
    for &x in &p {
        if !x.is_finite() {
            return Err(ProtocolError::Value {
                what,
                value: x,
                why: "must be finite",
            });
        }
        if x.abs() > MAX_COORD {
            return Err(ProtocolError::Value {
                what,
                value: x,
                why: "out of range (|x| <= 100 m)",
            });
        }
    }
    Ok(p)
}

fn radius(b: &[u8]) -> Result<f32, ProtocolError> {
    let r = f32_at(b, 20);
    if !(r.is_finite() && (0.0..=MAX_RADIUS).contains(&r)) {
        return Err(ProtocolError::Value {
            what: "radius",
            value: r,
            why: "must be finite, in [0, 1] m",
        });
    }
    Ok(r)
}

/// A cut's edge and sweep (module docs): edge points within [`MAX_COORD`] and apart, a sweep
/// of finite components and length in `(0, MAX_DEPTH]`.
fn cut(b: &[u8]) -> Result<Command, ProtocolError> {
    let a = coords_at(b, 8, "cut edge point a")?;
    let e = coords_at(b, 20, "cut edge point b")?;
    if a == e {
        return Err(ProtocolError::Value {
            what: "cut edge length |b - a|",
            value: 0.0,
            why: "the edge points a and b must differ (m)",
        });
    }
    let sweep = [f32_at(b, 32), f32_at(b, 36), f32_at(b, 40)];
    if let Some(&x) = sweep.iter().find(|x| !x.is_finite()) {
        return Err(ProtocolError::Value {
            what: "cut sweep",
            value: x,
            why: "must be finite",
        });
    }
    let depth = sweep
        .iter()
        .map(|&x| (x as f64).powi(2))
        .sum::<f64>()
        .sqrt() as f32;
    if !(depth > 0.0 && depth <= MAX_DEPTH) {
        return Err(ProtocolError::Value {
            what: "cut sweep length (depth)",
            value: depth,
            why: "must be in (0, 0.5] m",
        });
    }
    Ok(Command::Cut { a, b: e, sweep })
}

/// Parse one client message (module docs).
pub fn parse(b: &[u8]) -> Result<Message, ProtocolError> {
    if b.len() < 8 {
        return Err(ProtocolError::Short(b.len()));
    }
    let kind = b[0];
    let (name, want) = kind_name(kind).ok_or(ProtocolError::UnknownKind(kind))?;
    if b.len() != want {
        return Err(ProtocolError::Length {
            kind: name,
            got: b.len(),
            want,
        });
    }
    if b[1..4] != [0, 0, 0] {
        return Err(ProtocolError::Padding);
    }
    let seq = u32_at(b, 4);
    let command = match kind {
        1 => Command::Grab {
            point: coords(b, "grab point")?,
            radius: radius(b)?,
        },
        2 => Command::Move {
            target: coords(b, "move target")?,
        },
        3 => Command::Release,
        4 => Command::Pin {
            point: coords(b, "pin point")?,
            radius: radius(b)?,
        },
        5 => Command::Reset,
        6 => {
            let c = u32_at(b, 8);
            Command::Method(method_from_code(c).ok_or(ProtocolError::Code {
                what: "method",
                code: c,
                valid: "0 FAS, 1 RaISoV, 2 single level, 3 frame solver",
            })?)
        }
        7 => Command::Colour(match u32_at(b, 8) {
            0 => Colour::Displacement,
            1 => Colour::Stress,
            c => {
                return Err(ProtocolError::Code {
                    what: "colour",
                    code: c,
                    valid: "0 displacement, 1 stress",
                })
            }
        }),
        8 => Command::Save,
        9 => cut(b)?,
        _ => unreachable!("kind_name covers the kinds"),
    };
    Ok(Message { seq, command })
}

/// Encode a client message (the page's format; for tests and the bench client).
pub fn encode(m: &Message) -> Vec<u8> {
    let (kind, payload): (u8, Vec<f32>) = match m.command {
        Command::Grab { point, radius } => (1, vec![point[0], point[1], point[2], radius]),
        Command::Move { target } => (2, target.to_vec()),
        Command::Release => (3, vec![]),
        Command::Pin { point, radius } => (4, vec![point[0], point[1], point[2], radius]),
        Command::Reset => (5, vec![]),
        Command::Method(x) => (6, vec![f32::from_bits(method_code(x))]),
        Command::Colour(c) => (
            7,
            vec![f32::from_bits(match c {
                Colour::Displacement => 0,
                Colour::Stress => 1,
            })],
        ),
        Command::Save => (8, vec![]),
        Command::Cut { a, b, sweep } => (9, [a, b, sweep].concat()),
    };
    let mut b = vec![kind, 0, 0, 0];
    b.extend_from_slice(&m.seq.to_le_bytes());
    for x in payload {
        b.extend_from_slice(&x.to_le_bytes());
    }
    b
}

/// Encode the topology message.
pub fn encode_topology(n: usize, triangles: &[[u32; 3]]) -> Vec<u8> {
    let mut b = Vec::with_capacity(12 + 12 * triangles.len());
    b.extend_from_slice(TOPOLOGY_MAGIC);
    b.extend_from_slice(&(n as u32).to_le_bytes());
    b.extend_from_slice(&(triangles.len() as u32).to_le_bytes());
    for t in triangles {
        for &i in t {
            b.extend_from_slice(&i.to_le_bytes());
        }
    }
    b
}

/// A decoded frame (tests, the bench client).
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// Frame number.
    pub number: u32,
    /// Flags (module docs).
    pub flags: u32,
    /// Stats (`STAT_*`).
    pub stats: [f32; STATS],
    /// Surface positions (m).
    pub positions: Vec<[f32; 3]>,
    /// Scalar per vertex.
    pub scalar: Vec<f32>,
}

/// Encode a frame message.
pub fn encode_frame(
    number: u32,
    flags: u32,
    stats: &[f32; STATS],
    positions: &[[f32; 3]],
    scalar: &[f32],
) -> Vec<u8> {
    debug_assert_eq!(positions.len(), scalar.len());
    let n = positions.len();
    let mut b = Vec::with_capacity(FRAME_HEADER + 16 * n);
    b.extend_from_slice(FRAME_MAGIC);
    b.extend_from_slice(&number.to_le_bytes());
    b.extend_from_slice(&(n as u32).to_le_bytes());
    b.extend_from_slice(&flags.to_le_bytes());
    for s in stats {
        b.extend_from_slice(&s.to_le_bytes());
    }
    for p in positions {
        for x in p {
            b.extend_from_slice(&x.to_le_bytes());
        }
    }
    for s in scalar {
        b.extend_from_slice(&s.to_le_bytes());
    }
    b
}

/// Decode a frame message; `None` if it is not one.
pub fn decode_frame(b: &[u8]) -> Option<Frame> {
    if b.len() < FRAME_HEADER || &b[0..4] != FRAME_MAGIC {
        return None;
    }
    let number = u32_at(b, 4);
    let n = u32_at(b, 8) as usize;
    let flags = u32_at(b, 12);
    if b.len() != FRAME_HEADER + 16 * n {
        return None;
    }
    let mut stats = [0.0; STATS];
    for (i, s) in stats.iter_mut().enumerate() {
        *s = f32_at(b, 16 + 4 * i);
    }
    let pos_at = FRAME_HEADER;
    let positions = (0..n)
        .map(|i| {
            let o = pos_at + 12 * i;
            [f32_at(b, o), f32_at(b, o + 4), f32_at(b, o + 8)]
        })
        .collect();
    let sc_at = pos_at + 12 * n;
    let scalar = (0..n).map(|i| f32_at(b, sc_at + 4 * i)).collect();
    Some(Frame {
        number,
        flags,
        stats,
        positions,
        scalar,
    })
}

/// Decode a topology message: vertex count and triangles.
pub fn decode_topology(b: &[u8]) -> Option<(usize, Vec<[u32; 3]>)> {
    if b.len() < 12 || &b[0..4] != TOPOLOGY_MAGIC {
        return None;
    }
    let n = u32_at(b, 4) as usize;
    let m = u32_at(b, 8) as usize;
    if b.len() != 12 + 12 * m {
        return None;
    }
    let tris = (0..m)
        .map(|i| {
            let o = 12 + 12 * i;
            [u32_at(b, o), u32_at(b, o + 4), u32_at(b, o + 8)]
        })
        .collect();
    Some((n, tris))
}

/// A JSON string literal of `s`.
pub fn json_string(s: &str) -> String {
    let mut o = String::with_capacity(s.len() + 2);
    o.push('"');
    for c in s.chars() {
        match c {
            '"' => o.push_str("\\\""),
            '\\' => o.push_str("\\\\"),
            '\n' => o.push_str("\\n"),
            '\r' => o.push_str("\\r"),
            '\t' => o.push_str("\\t"),
            c if (c as u32) < 0x20 => o.push_str(&format!("\\u{:04x}", c as u32)),
            c => o.push(c),
        }
    }
    o.push('"');
    o
}

/// The text of an error message to a client.
pub fn error_json(msg: &str) -> String {
    format!("{{\"type\":\"error\",\"message\":{}}}", json_string(msg))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_every_kind() {
        let cmds = [
            Command::Grab {
                point: [0.1, -0.2, 0.3],
                radius: 0.01,
            },
            Command::Move {
                target: [1.0, 2.0, -3.0],
            },
            Command::Release,
            Command::Pin {
                point: [0.0, 0.0, 0.0],
                radius: 0.0,
            },
            Command::Reset,
            Command::Method(SchemeKind::RaisovPaper),
            Command::Colour(Colour::Stress),
            Command::Save,
            Command::Cut {
                a: [0.01, 0.02, 0.03],
                b: [-0.01, 0.02, 0.03],
                sweep: [0.0, 0.0, -0.02],
            },
        ];
        for (i, c) in cmds.into_iter().enumerate() {
            let m = Message {
                seq: 1000 + i as u32,
                command: c,
            };
            assert_eq!(parse(&encode(&m)), Ok(m));
        }
    }

    /// The wire codes and page labels stay as they were, now on `raisov::SchemeKind`:
    /// code i is `METHODS[i]`; backward Euler and BDF2 are served as the single level.
    #[test]
    #[allow(deprecated)]
    fn method_codes_and_labels_are_unchanged_on_the_one_scheme_kind() {
        let table = [
            (0, SchemeKind::Fas, "FAS multigrid", Method::Fas),
            (1, SchemeKind::RaisovPaper, "RaISoV (paper)", Method::Raisov),
            (2, SchemeKind::SingleLevel, "single level", Method::Single),
            (
                3,
                SchemeKind::Newton,
                "frame solver (Newton)",
                Method::Newton,
            ),
        ];
        for (code, kind, label, old) in table {
            assert_eq!(METHODS[code as usize], kind);
            assert_eq!(method_code(kind), code);
            assert_eq!(method_from_code(code), Some(kind));
            assert_eq!(method_label(kind), label);
            // The deprecated enum reads the same.
            assert_eq!(SchemeKind::from(old), kind);
            assert_eq!((old.code(), old.label()), (code, label));
            assert_eq!(Method::from_code(code), Some(old));
        }
        for kind in [SchemeKind::ImplicitEuler, SchemeKind::Bdf2] {
            assert_eq!(method_code(kind), 2);
            assert_eq!(method_label(kind), "single level");
        }
        assert_eq!(method_from_code(4), None);
    }

    /// A bad method code's error listed codes 0 to 2 only; code 3, the frame solver, is
    /// valid too.
    #[test]
    fn a_bad_method_code_lists_the_frame_solver() {
        let mut m = encode(&Message {
            seq: 1,
            command: Command::Method(SchemeKind::Newton),
        });
        assert_eq!(
            parse(&m).map(|m| m.command),
            Ok(Command::Method(SchemeKind::Newton))
        );
        m[8] = 4;
        assert_eq!(
            parse(&m),
            Err(ProtocolError::Code {
                what: "method",
                code: 4,
                valid: "0 FAS, 1 RaISoV, 2 single level, 3 frame solver",
            })
        );
    }

    #[test]
    fn hostile_messages_are_errors() {
        let good = encode(&Message {
            seq: 1,
            command: Command::Grab {
                point: [0.1, 0.2, 0.3],
                radius: 0.01,
            },
        });
        assert_eq!(parse(&[]), Err(ProtocolError::Short(0)));
        assert_eq!(parse(&good[..7]), Err(ProtocolError::Short(7)));
        assert!(matches!(
            parse(&good[..23]),
            Err(ProtocolError::Length { want: 24, .. })
        ));
        let mut long = good.clone();
        long.push(0);
        assert!(matches!(parse(&long), Err(ProtocolError::Length { .. })));
        let mut bad = good.clone();
        bad[0] = 99;
        assert_eq!(parse(&bad), Err(ProtocolError::UnknownKind(99)));
        let mut bad = good.clone();
        bad[2] = 1;
        assert_eq!(parse(&bad), Err(ProtocolError::Padding));
        for (at, v) in [(8, f32::NAN), (12, f32::INFINITY), (16, 1e6), (20, -1.0)] {
            let mut bad = good.clone();
            bad[at..at + 4].copy_from_slice(&v.to_le_bytes());
            assert!(
                matches!(parse(&bad), Err(ProtocolError::Value { .. })),
                "{v} at {at}"
            );
        }
        let mut m = encode(&Message {
            seq: 1,
            command: Command::Method(SchemeKind::Fas),
        });
        m[8] = 7;
        assert!(matches!(parse(&m), Err(ProtocolError::Code { .. })));
        // Garbage of every short length never panics.
        let mut x = 12345u32;
        for len in 0..64 {
            let g: Vec<u8> = (0..len)
                .map(|_| {
                    x = x.wrapping_mul(1664525).wrapping_add(1013904223);
                    (x >> 24) as u8
                })
                .collect();
            let _ = parse(&g);
        }
    }

    /// A cut of 44 bytes parses to its edge and sweep; each field out of range is refused,
    /// naming the field.
    #[test]
    fn a_cut_message_parses_and_each_bad_field_is_refused() {
        let cut = Command::Cut {
            a: [0.01, 0.0, 0.04],
            b: [0.03, 0.0, 0.04],
            sweep: [0.0, 0.0, -0.02],
        };
        let good = encode(&Message {
            seq: 7,
            command: cut,
        });
        assert_eq!(good.len(), 44);
        assert_eq!(
            parse(&good),
            Ok(Message {
                seq: 7,
                command: cut
            })
        );
        assert!(matches!(
            parse(&good[..40]),
            Err(ProtocolError::Length {
                kind: "cut",
                got: 40,
                want: 44
            })
        ));
        let field = |at: usize, v: f32| {
            let mut bad = good.clone();
            bad[at..at + 4].copy_from_slice(&v.to_le_bytes());
            match parse(&bad) {
                Err(ProtocolError::Value { what, .. }) => what,
                other => panic!("{v} at {at}: {other:?}"),
            }
        };
        // Edge point a (bytes 8..20), b (20..32): finite and within MAX_COORD.
        assert_eq!(field(8, f32::NAN), "cut edge point a");
        assert_eq!(field(16, 1e3), "cut edge point a");
        assert_eq!(field(20, f32::NEG_INFINITY), "cut edge point b");
        assert_eq!(field(28, -101.0), "cut edge point b");
        // The sweep (32..44): finite, of length in (0, MAX_DEPTH].
        assert_eq!(field(32, f32::INFINITY), "cut sweep");
        assert_eq!(field(40, f32::NAN), "cut sweep");
        assert_eq!(field(40, 0.0), "cut sweep length (depth)");
        assert_eq!(field(40, -0.6), "cut sweep length (depth)");
        let mut deepest = good.clone();
        deepest[40..44].copy_from_slice(&(-MAX_DEPTH).to_le_bytes());
        assert!(parse(&deepest).is_ok(), "a sweep of MAX_DEPTH is valid");
        // a = b: no edge.
        let same = encode(&Message {
            seq: 7,
            command: Command::Cut {
                a: [0.01, 0.0, 0.04],
                b: [0.01, 0.0, 0.04],
                sweep: [0.0, 0.0, -0.02],
            },
        });
        assert!(matches!(
            parse(&same),
            Err(ProtocolError::Value {
                what: "cut edge length |b - a|",
                ..
            })
        ));
        let e = parse(&same).unwrap_err().to_string();
        assert!(e.contains("must differ"), "{e}");
    }

    #[test]
    fn frame_and_topology_round_trip() {
        let mut stats = [0.0f32; STATS];
        stats[STAT_RESIDUAL] = 1.5e-3;
        stats[STAT_FORCE + 2] = -0.25;
        let pos = vec![[0.0, 1.0, 2.0], [3.0, 4.0, 5.0]];
        let sc = vec![0.5, 0.25];
        let b = encode_frame(7, 1, &stats, &pos, &sc);
        assert_eq!(b.len(), FRAME_HEADER + 16 * 2);
        let f = decode_frame(&b).unwrap();
        assert_eq!((f.number, f.flags, f.stats), (7, 1, stats));
        assert_eq!((f.positions, f.scalar), (pos, sc));
        assert!(decode_frame(&b[..b.len() - 1]).is_none());
        let tris = vec![[0, 1, 2], [2, 1, 3]];
        let t = encode_topology(4, &tris);
        assert_eq!(decode_topology(&t), Some((4, tris)));
        assert_eq!(json_string("a\"b\n"), "\"a\\\"b\\n\"");
    }
}
