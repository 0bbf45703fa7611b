//! The TOML scenario format. Every key, its unit and its default; unknown keys are errors.
//!
//! ```toml
//! name = "membrane-lift"          # optional; default: the file's stem
//! gravity = [0.0, 0.0, -9.81]     # m/s², default none
//!
//! [mesh]                          # one of `file` or `generate`
//! file = "liver_L3.msh"           # .msh (Gmsh 2.2/4.1), .node/.ele, .vtk, .vtu; relative to this file
//! scale = 1e-3                    # coordinate factor to metres (1e-3 for mm), default 1
//! generate = "rectangle"          # "rectangle" | "polygon" | "box"
//! size = [0.1, 0.1]               # rectangle [w, h] or box [x, y, z], m
//! polygon = [[0,0],[0.1,0],[0,0.1]]  # polygon outline, m
//! nodes = 186                     # target node count (rectangle, polygon, box)
//! divisions = [10, 4, 4]          # box: cells per side instead of `nodes`
//! pattern = 6                     # box: 5 or 6 tets per cube, default 6
//! renumber = true                 # nodes in a banded order for the force pass's memory
//!                                 # locality; default true for `file` (and the level files),
//!                                 # false for `generate` (numbered along the axes). Node ids
//!                                 # that a scenario or output shows stay the file's, and
//!                                 # results change only by round-off.
//!
//! [material]
//! law = "mooney-rivlin"           # "stvk" | "neo-hookean" | "mooney-rivlin" | "veronda-westmann"
//! young = 5e4                     # Pa   (stvk, neo-hookean), with
//! poisson = 0.4                   #      (stvk, neo-hookean)
//! c1 = 1e3                        # Pa   (mooney-rivlin, veronda-westmann)
//! c2 = 1e3                        # Pa   (mooney-rivlin)
//! gamma = 5.0                     #      (veronda-westmann)
//! kappa = 1e5                     # Pa, bulk modulus (mooney-rivlin, veronda-westmann solids)
//! density = 1000.0                # kg/m³, default 1000
//! thickness = 1e-3                # m, membranes only, default 1e-3
//!
//! [damping]                       # D = alpha M; default alpha = 0
//! alpha = 10.0                    # 1/s, or
//! ratio = 1.0                     # ζ, with
//! omega = 20.0                    # rad/s reference frequency: alpha = 2 ζ ω
//!
//! [[fix]]                         # fixed nodes; exactly one selector per entry:
//! boundary = true                 # every boundary node
//! box = { min = [..], max = [..] }          # nodes inside an axis-aligned box
//! plane = { point = [..], normal = [..] }   # nodes with (x − point)·normal ≤ 0
//! group = "boundary"              # a physical group of the mesh file
//! nodes = [0, 5, 7]               # node ids, 0-based, in file order after unused nodes are dropped
//!                                 # (whether or not [mesh] renumber reorders them in memory)
//! point = [0.0, 0.0, 0.0]         # the node nearest this point
//!
//! [[load]]                        # constant nodal force
//! at = { point = [0.1, 0.0, 0.0] } # which nodes: a selector as in [[fix]]
//! force = [0.0, 0.0, -0.1]        # N on each selected node
//!
//! [[displace]]                    # prescribed displacement of the node nearest `point`
//! point = [0.0, 0.0, 0.0]
//! displacement = [0.0, 0.0, 0.03] # m
//! mode = "held"                   # "held" (from t = 0) | "ramp" | "table"; default "held"
//! duration = 0.5                  # s, ramp
//! table = [[0.0, 0,0,0], [1.0, 0,0,0.01]]   # rows [t, dx, dy, dz], t increasing (mode "table")
//!
//! [integrator]
//! method = "symplectic-euler"     # "forward-euler" | "symplectic-euler" | "rk4" | "central-difference"
//! dt = 1e-4                       # s; default: safety × estimated critical step
//! safety = 0.5                    # fraction of the estimated critical step, default 0.5
//! precision = "f64"               # element data of the force pass: "f64" (default) | "f32-storage"
//!                                 # (Dm⁻¹ and volumes stored in f32, arithmetic and state f64;
//!                                 # fewer bytes per step on large meshes, forces within 1e-6
//!                                 # relative of f64, see fem::fast). Applies to neo-Hookean
//!                                 # tetrahedra (the packed path); elsewhere f64 with a note
//!
//! [run]
//! stop = "duration"               # "duration" | "steady"
//! duration = 1.0                  # s of simulated time (stop = "duration"); the cap for "steady"
//! kinetic_tol = 1e-8              # steady: kinetic energy below this × its peak
//! residual_tol = 1e-4             # steady: residual norm below this × its peak
//! blowup_factor = 1e3             # energy blow-up threshold factor (see integrate::stepper)
//!
//! [output]
//! dir = "raisov-out/NAME"         # default; `raisov run --out DIR` overrides
//! frame_interval = 0.05           # s between VTU frames; 0 writes only the first and last
//! csv_every = 1                   # steps between rows of measures.csv
//! vtu = "binary"                  # frame storage: "binary" (default; appended raw, zlib-
//!                                 # compressed, ParaView's own layout) | "ascii" (text);
//!                                 # `raisov run --ascii-vtu` overrides. Frames hold the
//!                                 # reference points and a `displacement` point field (the
//!                                 # active vectors: ParaView's Warp By Vector deforms them)
//! reference = "none"              # T∞ for |T − T∞|: "none" | "auto" | path to nodal_stress.csv
//!
//! [multigrid]                     # optional: integrate over a hierarchy of independent meshes
//! scheme = "fas"                  # "fas" (converges; default) | "raisov-paper" (the literal method)
//! levels = 4                      # with [mesh] generate: level count, node counts a geometric series
//! ratio = 0.5                     # node-count ratio between levels, default 0.5 (the paper's)
//! level_nodes = [186, 103, 55, 31] # or explicit node targets per generated level, level 0
//!                                 # first (must equal [mesh] nodes); instead of levels/ratio
//! files = ["L1.msh", "L2.msh"]    # or coarser levels as files (level 0 is [mesh]); same `scale`
//! reading = "correction"          # raisov-paper: "paper" | "correction", default "correction"
//! epsilon = 1e-5                  # raisov-paper: switch threshold (m), default 1e-3 × shortest edge
//! pre_smooth = 4                  # fas: ν1, default 4
//! post_smooth = 4                 # fas: ν2, default 4
//! smoother = "chebyshev"          # fas: "chebyshev" (default) | "dynamics" (damped explicit steps)
//! coarse = "chebyshev"            # fas: coarsest solve, "chebyshev" (60 iterations, default) |
//!                                 #      "explicit" (damped steps) | "newton" (Newton-Krylov)
//! scaling = "fictitious"          # fas chebyshev: preconditioner, "fictitious" (per-node fictitious
//!                                 #      masses, default) | "mass" (lumped mass)
//! transfer = "convex"            # fas: weights of R, P: "convex" (default; eq. 7 extrapolating
//!                                 #      weights clamped into the host) | "exact" (eq. 6/7 as they
//!                                 #      are) | "convex-restriction" (only R clamped)
//! accelerate = "cg"               # fas chebyshev: each V-cycle preconditions a nonlinear
//!                                 #      conjugate-gradient step with a line search on the
//!                                 #      energy, "cg" (default) | "none" (plain V-cycles)
//! coarse_time = 0.1               # fas explicit coarsest: simulated time per visit (s), default 0.1
//! coarse_iterations = 60          # fas chebyshev coarsest: iterations per visit, default 60
//! level_methods = ["rk4", "rk4"]  # per level integrator, default [integrator] method on all
//! level_dt = [1e-3, 2e-3]         # per level step (s); default: raisov-paper the level-0 step
//!                                 # on every level (the paper), fas each level's own estimate
//!
//! [interactive]                   # optional: a fixed budget per frame while the [[displace]]
//!                                 # paths move (surgical interaction); `raisov run` then writes
//!                                 # frames.csv with the lag to the static solution per frame
//! fps = 30.0                      # frames per second of the path's time, default 30
//! cycles = 4                      # steps (single level) or V-cycles (multigrid) per frame,
//!                                 # default 4; or instead
//! budget_ms = 33.0                # wall-time budget per frame (ms): as many as fit
//! reference = "newton"            # static solution per frame: "newton" (default) | "none"
//! reference_tol = 1e-6            # its relative residual, default 1e-6
//! ```

use serde::Deserialize;

#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct ScenarioSpec {
    pub name: Option<String>,
    pub gravity: Option<[f64; 3]>,
    pub mesh: MeshSpec,
    pub material: MaterialSpec,
    #[serde(default)]
    pub damping: DampingSpec,
    #[serde(default)]
    pub fix: Vec<RegionSpec>,
    #[serde(default)]
    pub load: Vec<LoadSpec>,
    #[serde(default)]
    pub displace: Vec<DisplaceSpec>,
    #[serde(default)]
    pub integrator: IntegratorSpec,
    #[serde(default)]
    pub run: RunSpec,
    #[serde(default)]
    pub output: OutputSpec,
    pub multigrid: Option<MultigridSpec>,
    pub interactive: Option<InteractiveSpec>,
}

/// `[multigrid]`: integrate over a hierarchy of independent meshes of the same object.
#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct MultigridSpec {
    pub scheme: Option<String>,
    pub levels: Option<usize>,
    pub ratio: Option<f64>,
    /// Explicit node targets of generated levels, level 0 first (= `[mesh] nodes`).
    pub level_nodes: Option<Vec<usize>>,
    pub files: Option<Vec<String>>,
    pub reading: Option<String>,
    pub epsilon: Option<f64>,
    pub pre_smooth: Option<usize>,
    pub post_smooth: Option<usize>,
    pub coarse: Option<String>,
    pub coarse_time: Option<f64>,
    pub coarse_iterations: Option<usize>,
    pub smoother: Option<String>,
    pub transfer: Option<String>,
    pub scaling: Option<String>,
    pub accelerate: Option<String>,
    pub level_methods: Option<Vec<String>>,
    pub level_dt: Option<Vec<f64>>,
}

/// `[interactive]`: a fixed budget per frame while the prescribed displacements move along
/// their paths; see [`super::interactive`].
#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct InteractiveSpec {
    pub fps: Option<f64>,
    pub cycles: Option<usize>,
    pub budget_ms: Option<f64>,
    pub reference: Option<String>,
    pub reference_tol: Option<f64>,
}

#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct MeshSpec {
    pub file: Option<String>,
    pub scale: Option<f64>,
    pub generate: Option<String>,
    pub size: Option<Vec<f64>>,
    pub polygon: Option<Vec<[f64; 2]>>,
    pub nodes: Option<usize>,
    pub divisions: Option<[usize; 3]>,
    pub pattern: Option<u32>,
    pub renumber: Option<bool>,
}

#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    pub law: String,
    pub young: Option<f64>,
    pub poisson: Option<f64>,
    pub c1: Option<f64>,
    pub c2: Option<f64>,
    pub gamma: Option<f64>,
    pub kappa: Option<f64>,
    pub density: Option<f64>,
    pub thickness: Option<f64>,
}

#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct DampingSpec {
    pub alpha: Option<f64>,
    pub ratio: Option<f64>,
    pub omega: Option<f64>,
}

#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct BoxSpec {
    pub min: [f64; 3],
    pub max: [f64; 3],
}

#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct PlaneSpec {
    pub point: [f64; 3],
    pub normal: [f64; 3],
}

/// A node selection: exactly one field set.
#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct RegionSpec {
    pub boundary: Option<bool>,
    #[serde(rename = "box")]
    pub aabb: Option<BoxSpec>,
    pub plane: Option<PlaneSpec>,
    pub group: Option<String>,
    pub nodes: Option<Vec<u32>>,
    pub point: Option<[f64; 3]>,
}

#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct LoadSpec {
    /// Which nodes: a selector table as in `[[fix]]`.
    pub at: RegionSpec,
    pub force: [f64; 3],
}

#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct DisplaceSpec {
    pub point: [f64; 3],
    pub displacement: Option<[f64; 3]>,
    pub mode: Option<String>,
    pub duration: Option<f64>,
    pub table: Option<Vec<[f64; 4]>>,
}

#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct IntegratorSpec {
    pub method: Option<String>,
    pub dt: Option<f64>,
    pub safety: Option<f64>,
    pub precision: Option<String>,
}

#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct RunSpec {
    pub stop: Option<String>,
    pub duration: Option<f64>,
    pub kinetic_tol: Option<f64>,
    pub residual_tol: Option<f64>,
    pub blowup_factor: Option<f64>,
}

#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    pub dir: Option<String>,
    pub frame_interval: Option<f64>,
    pub csv_every: Option<u64>,
    pub vtu: Option<String>,
    pub reference: Option<String>,
}
