//! `raisov serve`: a live viewer in the browser. A simulation thread steps a
//! [`raisov::sim::Simulation`] frame after frame ([`session`]); an HTTP + WebSocket server
//! ([`server`]) serves the embedded page ([`assets`]) and streams binary frames of the surface
//! ([`protocol`]); a person grasps, drags, pins and switches the method from the page, and the
//! session can be saved as a scenario `raisov run` replays ([`record`]).
//!
//! ```no_run
//! use raisov_serve::{session::{Session, SessionConfig, Source}, serve_blocking};
//! use raisov::sim::Budget;
//! let source = Source::from_scenario_file("examples/liver_interactive.toml".as_ref())?;
//! let config = SessionConfig { budget: Budget::Cycles(2), max_fps: 60.0, method: None, record_path: None, grab_stiffness: None };
//! serve_blocking(source, config, "127.0.0.1", 8080, None, |url, _| println!("open {url}"))?;
//! # Ok::<(), raisov_serve::ServeError>(())
//! ```

pub mod access;
pub mod assets;
pub mod conn;
pub mod protocol;
pub mod record;
pub mod server;
pub mod session;

use std::path::PathBuf;
use thiserror::Error;

/// Errors of the viewer.
#[derive(Debug, Error)]
pub enum ServeError {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// the file
        path: PathBuf,
        /// why
        source: std::io::Error,
    },
    /// The scenario or surface is not usable.
    #[error("{0}")]
    Scenario(String),
    /// The library's error (loading, building the simulation).
    #[error(transparent)]
    Raisov(#[from] raisov::Error),
    /// The address could not be bound.
    #[error("cannot listen on {addr}: {source}")]
    Bind {
        /// host:port
        addr: String,
        /// why
        source: std::io::Error,
    },
}

/// Start the simulation thread, bind `host:port` (port 0: any free port), call `ready` with
/// the page's URL (with the token where one is required) and the access rules, and serve
/// until the process ends. `token`: require this token even on loopback
/// ([`access::Access::for_bound`]; one is made for a non-loopback address).
pub fn serve_blocking(
    source: session::Source,
    config: session::SessionConfig,
    host: &str,
    port: u16,
    token: Option<String>,
    ready: impl FnOnce(&str, &access::Access),
) -> Result<(), ServeError> {
    let session = session::Session::spawn(source, config)?;
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .map_err(|e| ServeError::Scenario(format!("cannot start the async runtime: {e}")))?;
    rt.block_on(async move {
        let addr = format!("{host}:{port}");
        let listener =
            tokio::net::TcpListener::bind(&addr)
                .await
                .map_err(|e| ServeError::Bind {
                    addr: addr.clone(),
                    source: e,
                })?;
        let local = listener.local_addr().map_err(|e| ServeError::Bind {
            addr: addr.clone(),
            source: e,
        })?;
        let access = access::Access::for_bound(local, token).map_err(ServeError::Scenario)?;
        let shown = if local.ip().is_unspecified() {
            format!("http://127.0.0.1:{}/", local.port())
        } else if local.is_ipv6() {
            format!("http://[{}]:{}/", local.ip(), local.port())
        } else {
            format!("http://{local}/")
        };
        let shown = match access.token() {
            Some(t) => format!("{shown}?token={t}"),
            None => shown,
        };
        ready(&shown, &access);
        server::serve(listener, session, access, conn::Limits::default())
            .await
            .map_err(|e| ServeError::Bind { addr, source: e })
    })
}

/// The options of `raisov serve`.
#[derive(Clone, Debug)]
pub struct ServeArgs {
    /// A scenario (`.toml`) or a closed surface (`.obj`, `.stl`, `.ply`); `None`: the shipped
    /// liver ([`DEFAULT_SCENARIO`]).
    pub target: Option<PathBuf>,
    /// Address to bind (a loopback address unless the user chooses to expose the viewer).
    pub host: String,
    /// The token clients must present; `None`: none on loopback, a new one otherwise.
    pub token: Option<String>,
    /// Port (0: any free port).
    pub port: u16,
    /// Open the page in the system's browser.
    pub open: bool,
    /// V-cycles (multigrid) or steps (single level) per frame instead of `budget_ms`.
    pub cycles: Option<u32>,
    /// Wall time per frame (ms).
    pub budget_ms: f64,
    /// Frame-rate cap of the simulation thread (1/s, 0: none).
    pub max_fps: f64,
    /// Start with this method: "newton", "fas", "raisov" or "single".
    pub method: Option<String>,
    /// `save` also writes the recorded scenario here.
    pub record: Option<PathBuf>,
    /// Surface coordinates × scale = metres.
    pub scale: f64,
    /// Level-0 node target when meshing a surface.
    pub nodes: usize,
    /// Total stiffness of the grasp's coupling springs (N/m); 0 holds the patch rigidly.
    pub grab_stiffness: f64,
}

/// The scenario served without an argument: the liver grasp of `examples/` (levels L1–L3 of
/// `data/`), found relative to the working directory or, failing that, to the source tree
/// this binary was built from.
pub const DEFAULT_SCENARIO: &str = "examples/liver_interactive.toml";

/// Resolve the target, print the URL, serve until the process ends.
pub fn run(args: &ServeArgs) -> Result<(), ServeError> {
    let target = match &args.target {
        Some(p) => p.clone(),
        None => {
            let here = PathBuf::from(DEFAULT_SCENARIO);
            if here.is_file() {
                here
            } else {
                PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join(DEFAULT_SCENARIO)
            }
        }
    };
    let ext = target
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let source = match ext.as_deref() {
        Some("toml") => session::Source::from_scenario_file(&target)?,
        Some("obj" | "stl" | "ply") => {
            session::Source::from_surface(&target, args.scale, args.nodes)?
        }
        _ => {
            return Err(ServeError::Scenario(format!(
                "{}: give a scenario (.toml) or a closed surface (.obj, .stl, .ply)",
                target.display()
            )))
        }
    };
    let method = match args.method.as_deref() {
        None => None,
        Some("fas") => Some(raisov::SchemeKind::Fas),
        Some("raisov") => Some(raisov::SchemeKind::RaisovPaper),
        Some("single") => Some(raisov::SchemeKind::SingleLevel),
        Some("newton") => Some(raisov::SchemeKind::Newton),
        Some(m) => {
            return Err(ServeError::Scenario(format!(
                "--method {m}: valid are newton, fas, raisov, single"
            )))
        }
    };
    if !(args.max_fps >= 0.0 && args.max_fps.is_finite()) {
        return Err(ServeError::Scenario(format!(
            "--max-fps {}: must be a frame rate of 0 (no cap) or more, in frames per second",
            args.max_fps
        )));
    }
    if !(args.budget_ms > 0.0 && args.budget_ms.is_finite()) {
        return Err(ServeError::Scenario(format!(
            "--budget-ms {}: must be a positive number of milliseconds",
            args.budget_ms
        )));
    }
    let budget = match args.cycles {
        Some(0) => {
            return Err(ServeError::Scenario(
                "--cycles 0: must be at least 1".into(),
            ));
        }
        Some(c) => raisov::sim::Budget::Cycles(c),
        None => raisov::sim::Budget::Millis(args.budget_ms),
    };
    let config = session::SessionConfig {
        budget,
        max_fps: args.max_fps,
        method,
        record_path: args.record.clone(),
        grab_stiffness: match args.grab_stiffness {
            0.0 => None,
            k if k > 0.0 && k.is_finite() => Some(k),
            k => {
                return Err(ServeError::Scenario(format!(
                "--grab-stiffness {k}: must be a positive stiffness in N/m, or 0 for a rigid hold"
            )))
            }
        },
    };
    println!("raisov serve: {} ({})", source.name, target.display());
    let open = args.open;
    serve_blocking(
        source,
        config,
        &args.host,
        args.port,
        args.token.clone(),
        |url, access| {
            if !access.loopback() {
                println!(
                    "warning: listening on {}, beyond this machine: whoever can reach it and \
                     has the token can drive the simulation and see the organ's surface",
                    args.host
                );
                println!("         from another machine, put this machine's address in the URL");
            }
            println!("open {url}  (Shift+drag grasps, Ctrl+click pins, Ctrl+C stops)");
            if open {
                let _ = std::process::Command::new("xdg-open").arg(url).spawn();
            }
        },
    )
}
