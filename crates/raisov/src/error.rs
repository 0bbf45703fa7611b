//! Typed errors of the library. Every variant says where (file, line, key, element, step)
//! and what would be valid.

use std::path::PathBuf;

/// Result with the library's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong in raisov.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be opened, read or written.
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A mesh file is malformed. `line` is 1-based where known.
    #[error("{path}{}: {msg}", line.map(|l| format!(", line {l}")).unwrap_or_default())]
    MeshFormat {
        path: PathBuf,
        line: Option<usize>,
        msg: String,
    },
    /// A mesh is well-formed but unusable (degenerate element, unused nodes, ...).
    #[error("{path}: {msg}")]
    BadMesh { path: PathBuf, msg: String },
    /// A triangle surface cannot bound a solid: degenerate triangle, open or non-manifold,
    /// not orientable, self-intersecting. The message names the triangles and vertices.
    #[error("bad surface: {msg}")]
    BadSurface { msg: String },
    /// A scenario file is wrong: unknown key, bad value, missing file.
    #[error("{path}{}: {msg}", line.map(|l| format!(", line {l}")).unwrap_or_default())]
    Scenario {
        path: PathBuf,
        line: Option<usize>,
        msg: String,
    },
    /// A parameter given through the API is out of range.
    #[error("invalid parameter `{name}`: {msg}")]
    Param { name: String, msg: String },
    /// A simulation diverged: where, when and why.
    #[error(transparent)]
    Diverged(#[from] Divergence),
}

/// Why and where a run stopped because it blew up.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("diverged at t = {time:.6} s (step {step}){}: {cause}", element.map(|e| format!(", element {e}")).unwrap_or_default())]
pub struct Divergence {
    pub time: f64,
    pub step: u64,
    pub element: Option<usize>,
    pub cause: DivergenceCause,
}

/// What blew up.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DivergenceCause {
    #[error("inverted element (det F = {det_f:.3e} <= 0)")]
    Inverted { det_f: f64 },
    #[error("non-finite value in {what} at node {node}")]
    NonFinite { what: &'static str, node: usize },
    #[error("energy blow-up: kinetic energy {kinetic:.3e} J exceeds {limit:.3e} J")]
    EnergyBlowUp { kinetic: f64, limit: f64 },
}

impl Error {
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
    pub fn param(name: &str, msg: impl Into<String>) -> Self {
        Error::Param {
            name: name.into(),
            msg: msg.into(),
        }
    }
}
