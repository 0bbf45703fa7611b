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
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// A mesh file is malformed. `line` is 1-based where known.
    #[error("{path}{}: {msg}", line.map(|l| format!(", line {l}")).unwrap_or_default())]
    MeshFormat {
        /// The file.
        path: PathBuf,
        /// The 1-based line, where known.
        line: Option<usize>,
        /// What is wrong.
        msg: String,
    },
    /// A mesh is well-formed but unusable (degenerate element, unused nodes, ...).
    #[error("{path}: {msg}")]
    BadMesh {
        /// The file (or a label for a generated mesh).
        path: PathBuf,
        /// What is wrong.
        msg: String,
    },
    /// A triangle surface cannot bound a solid: degenerate triangle, open or non-manifold,
    /// not orientable, self-intersecting. The message names the triangles and vertices.
    #[error("bad surface: {msg}")]
    BadSurface {
        /// What is wrong, naming triangles and vertices.
        msg: String,
    },
    /// A scenario file is wrong: unknown key, bad value, missing file.
    #[error("{path}{}: {msg}", line.map(|l| format!(", line {l}")).unwrap_or_default())]
    Scenario {
        /// The scenario file.
        path: PathBuf,
        /// The 1-based line, where known.
        line: Option<usize>,
        /// What is wrong and what would be valid.
        msg: String,
    },
    /// A parameter given through the API is out of range.
    #[error("invalid parameter `{name}`: {msg}")]
    Param {
        /// The parameter.
        name: String,
        /// What is wrong and what would be valid.
        msg: String,
    },
    /// A simulation diverged: where, when and why.
    #[error(transparent)]
    Diverged(#[from] Divergence),
}

/// Why and where a run stopped because it blew up.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("diverged at t = {time:.6} s (step {step}){}: {cause}", element.map(|e| format!(", element {e}")).unwrap_or_default())]
pub struct Divergence {
    /// Simulated time of the failing step (s).
    pub time: f64,
    /// The failing step's number (1-based).
    pub step: u64,
    /// The element that inverted, where one did.
    pub element: Option<usize>,
    /// What blew up.
    pub cause: DivergenceCause,
}

/// What blew up.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DivergenceCause {
    /// An element's deformation gradient has `det F ≤ 0`.
    #[error("inverted element (det F = {det_f:.3e} <= 0)")]
    Inverted {
        /// Its determinant.
        det_f: f64,
    },
    /// A displacement or velocity is NaN or infinite.
    #[error("non-finite value in {what} at {node}")]
    NonFinite {
        /// Which vector (`"displacement"`, `"velocity"`).
        what: &'static str,
        /// The first node with one.
        node: NodeRef,
    },
    /// The kinetic energy passed the stepper's ceiling.
    #[error(
        "energy blow-up: kinetic energy {kinetic:.3e} J exceeds {limit:.3e} J; the most \
         kinetic energy is at {node}, moving at {speed:.3e} m/s"
    )]
    EnergyBlowUp {
        /// Kinetic energy (J).
        kinetic: f64,
        /// The ceiling (J).
        limit: f64,
        /// The node of the largest kinetic energy `½ m_a |v_a|²`.
        node: NodeRef,
        /// Its speed `|v_a|` (m/s).
        speed: f64,
    },
    /// An implicit step's Newton iteration did not meet its stopping rule
    /// ([`crate::statics::implicit`]).
    #[error(
        "the implicit step's Newton iteration stopped after {newton} iterations at a largest \
         nodal residual of {residual:.3e} N, above its target {target:.3e} N (raise \
         `integrator.max_newton` or lower `integrator.dt`)"
    )]
    NotConverged {
        /// The largest nodal residual over free nodes at the end (N).
        residual: f64,
        /// The stopping rule's threshold (N).
        target: f64,
        /// Newton iterations taken.
        newton: usize,
    },
    /// An implicit step's linear solver failed ([`crate::statics::implicit`]).
    #[error("the implicit step's solver failed: {0}")]
    Solver(String),
}

/// A node a [`Divergence`] names: its index in the stepper's mesh and, once the scenario has
/// [located](Divergence::locate) it, its id in the mesh file and its position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NodeRef {
    /// Index in the mesh (0-based, the mesh's own order).
    pub index: usize,
    /// Id in the mesh file, where known (what messages show instead of the index).
    pub file_id: Option<u64>,
    /// Reference position (m), where known.
    pub at: Option<[f64; 3]>,
}

impl NodeRef {
    /// Node `index` of the mesh, not located yet.
    pub fn index(index: usize) -> Self {
        NodeRef {
            index,
            file_id: None,
            at: None,
        }
    }
}

impl std::fmt::Display for NodeRef {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.file_id {
            Some(id) => write!(f, "node {id} of the mesh file")?,
            None => write!(f, "node {}", self.index)?,
        }
        match self.at {
            Some(p) => write!(f, " (at {} m)", crate::numbers::point(p)),
            None => Ok(()),
        }
    }
}

impl Divergence {
    /// Name the divergence's node by its id in the mesh file (`file_id` of the mesh index)
    /// and its reference position (`position` of the mesh index), as messages to the user
    /// name nodes.
    pub fn locate(
        &mut self,
        file_id: impl Fn(usize) -> u64,
        position: impl Fn(usize) -> Option<[f64; 3]>,
    ) {
        if let DivergenceCause::NonFinite { node, .. }
        | DivergenceCause::EnergyBlowUp { node, .. } = &mut self.cause
        {
            node.file_id = Some(file_id(node.index));
            node.at = position(node.index);
        }
    }
}

impl Error {
    /// An I/O error on `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
    /// An out-of-range API parameter `name`, with what is wrong and what would be valid.
    pub fn param(name: &str, msg: impl Into<String>) -> Self {
        Error::Param {
            name: name.into(),
            msg: msg.into(),
        }
    }
}
