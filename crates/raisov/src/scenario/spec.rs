//! The TOML scenario format. Every key, its unit and its default; unknown keys are errors,
//! and so are unknown values of the keys that name one of a few values (the message names
//! the key, its line and the valid values), numbers that are not finite (`nan`, `inf`) and
//! values outside their range. The defaults are the constants of [`defaults`] (and, for the
//! FAS settings, [`crate::multigrid::fas::FasParams::default`]).
//!
//! ```toml
//! name = "membrane-lift"          # optional; default: the file's stem, characters outside
//!                                 # the rule replaced by `_`. 1 to 100 ASCII letters,
//!                                 # digits, `-`, `_`, `.`, not starting with `.`
//!                                 # (crate::io::NAME_RULE): it names the files written
//!                                 # under the output directory
//! gravity = [0.0, 0.0, -9.81]     # m/s², default none
//!
//! [mesh]                          # one of `file`, `generate` or `surface`
//! file = "liver_L3.msh"           # .msh (Gmsh 2.2/4.1), .node/.ele, .vtk, .vtu; relative to this file
//! scale = 1e-3                    # coordinate factor to metres (1e-3 for mm), default 1
//! surface = "liver.obj"           # closed triangle surface (.obj, .stl, .ply), relative to this
//!                                 # file: checked (orientation repaired), meshed at load by
//!                                 # isosurface stuffing (crate::mesh::stuffing), one level, or
//!                                 # `[multigrid] levels`; the levels are cached as Gmsh 2.2
//!                                 # files in `cache/` under the output directory, keyed by a
//!                                 # hash of the surface's bytes and the meshing parameters,
//!                                 # and read back on a rerun. Frames then also hold the surface
//!                                 # (`frames/NAME_surface_NNNNNN.vtp`, `NAME_surface.pvd`)
//! size = 0.005                    # surface: lattice spacing (m, after `scale`) of level 0, or
//! nodes = 20000                   # surface: level 0's target node count (one of the two)
//! generate = "rectangle"          # "rectangle" | "polygon" | "box"
//! size = [0.1, 0.1]               # rectangle [w, h] or box [x, y, z], m
//! polygon = [[0,0],[0.1,0],[0,0.1]]  # polygon outline, m
//! nodes = 186                     # target node count (rectangle, polygon, box)
//! divisions = [10, 4, 4]          # box: cells per side instead of `nodes`
//! pattern = 6                     # box: 5 or 6 tets per cube, default 6
//! renumber = true                 # nodes in a banded order for the force pass's memory
//!                                 # locality; default true for `file` and `surface` (and the
//!                                 # level files),
//!                                 # false for `generate` (numbered along the axes). Node ids
//!                                 # that a scenario or output shows stay the file's, and
//!                                 # results change only by round-off.
//!
//! [material]
//! law = "mooney-rivlin"           # "stvk" (or "st-venant-kirchhoff") | "neo-hookean" |
//!                                 # "mooney-rivlin" | "veronda-westmann" | "stable-neo-hookean"
//!                                 # | "ti-neo-hookean" | "hgo" (or "holzapfel-gasser-ogden")
//!                                 # | "neo-hookean-visco";
//!                                 # required, except with an [interactive] section: there
//!                                 # default "stable-neo-hookean" (finite energy and forces
//!                                 # for inverted elements, so a hard grasp recovers)
//! young = 5e4                     # Pa   (stvk, neo-hookean, stable-neo-hookean), with
//! poisson = 0.4                   #      (stvk, neo-hookean, stable-neo-hookean)
//! c1 = 1e3                        # Pa   (mooney-rivlin, veronda-westmann)
//! c2 = 1e3                        # Pa   (mooney-rivlin)
//! gamma = 5.0                     #      (veronda-westmann)
//! kappa = 1e5                     # Pa, bulk modulus (mooney-rivlin, veronda-westmann solids;
//!                                 # ti-neo-hookean, hgo, neo-hookean-visco with `mu`)
//! mu = 1e3                        # Pa, shear modulus (ti-neo-hookean, hgo, neo-hookean-visco), with
//!                                 # `kappa`; or `young` and `poisson` instead of both
//! eta = 5e3                       # Pa, fibre stiffness (ti-neo-hookean)
//! k1 = 2e3                        # Pa, fibre stiffness (hgo)
//! k2 = 5.0                        # fibre stiffening exponent (hgo)
//! dispersion = 0.0                # fibre dispersion κ_d in [0, 1/3] (hgo), default 0
//! fibre = [1.0, 0.0, 0.0]         # fibre direction (ti-neo-hookean, hgo; solids only),
//!                                 # normalised, the same in every element; or a field, one
//!                                 # direction per element (rules: crate::scenario::fibres):
//! fibre = { cell_data = "fibre" } # the 3-component cell data array of this name of a .vtu
//!                                 # `[mesh] file`, one per cell, each normalised; or
//! fibre = { helix = { axis = [0, 0, 1], centre = [0, 0, 0], inner_radius = 0.02,
//!           outer_radius = 0.03, endo = 60.0, epi = -60.0 } }
//!                                 # the helix-angle rule through a wall about `axis` (m,
//!                                 # degrees): at depth t = clamp((r − inner)/(outer − inner),
//!                                 # 0, 1), θ = endo + t (epi − endo), fibre = cos θ e_circ +
//!                                 # sin θ e_axis at each element's centroid. Coarser
//!                                 # [multigrid] levels get their own field (same module)
//! prony = [[0.5, 0.1]]            # neo-hookean-visco (solids only, with `mu` and `kappa` or
//!                                 # `young` and `poisson`, the instantaneous moduli): Prony
//!                                 # terms [α, τ], α >= 0 with Σ α < 1, τ > 0 s; the shear
//!                                 # modulus relaxes to μ (1 − Σ α). Static solves (newton)
//!                                 # find the fully relaxed equilibrium; not with
//!                                 # [interactive], nor with [multigrid] on an explicit method
//! density = 1000.0                # kg/m³, default 1000
//! thickness = 1e-3                # m, membranes only, default 1e-3
//!
//! [damping]                       # D = alpha M + beta K; default alpha = beta = 0
//! alpha = 10.0                    # 1/s, or
//! ratio = 1.0                     # ζ, with
//! omega = 20.0                    # rad/s reference frequency: alpha = 2 ζ ω
//! beta = 1e-3                     # s, stiffness-proportional: "implicit-euler" and "bdf2"
//!                                 # only (K frozen at each step's start, statics::implicit);
//!                                 # an error with the explicit methods and "newton". A mode
//!                                 # of frequency ω gets ζ = alpha/(2ω) + beta ω/2
//!
//! [[fix]]                         # fixed nodes; exactly one selector per entry, and what
//!                                 # is held (default: all three components):
//! components = ["z"]              # hold only these of "x", "y", "z" (a roller; a z-clamped
//!                                 # slab of tets is plane strain), or
//! normal = [0.0, 0.0, 1.0]        # hold only the displacement along this direction: the
//!                                 # nodes slide on the plane normal to it (a symmetry plane)
//! boundary = true                 # every boundary node
//! box = { min = [..], max = [..] }          # nodes inside an axis-aligned box
//! plane = { point = [..], normal = [..] }   # nodes with (x − point)·normal ≤ 0
//! group = "boundary"              # a physical group of the mesh file
//! nodes = [1, 5, 7]               # node ids as the mesh file numbers them (Gmsh, Triangle and
//!                                 # TetGen files their own ids, often from 1; VTK files and
//!                                 # generated meshes by position from 0); an id the mesh lacks
//!                                 # is an error naming the valid range. Outputs use the same ids
//! point = [0.0, 0.0, 0.0]         # the node nearest this point
//!
//! [[load]]                        # nodal force
//! at = { point = [0.1, 0.0, 0.0] } # which nodes: a selector as in [[fix]]
//! force = [0.0, 0.0, -0.1]        # N on each selected node
//! time = { kind = "ramp", duration = 0.5 }  # optional time function, default constant:
//!                                 # the force times s(t) (crate::time::TimeFunction):
//!                                 # kind = "constant" | "ramp" (duration, s: s = min(t/T, 1))
//!                                 # | "table" (table = [[t, s], ...], t increasing, linear
//!                                 # between rows, held after the last) | "sine" (frequency,
//!                                 # Hz; amplitude, default 1; phase, rad, default 0:
//!                                 # s = A sin(2π f t + φ))
//!
//! [[displace]]                    # prescribed displacement of the node nearest `point`
//! point = [0.0, 0.0, 0.0]
//! displacement = [0.0, 0.0, 0.03] # m
//! mode = "held"                   # "held" (from t = 0) | "ramp" | "table"; default "table"
//!                                 # where `table` is given, else "held"
//! duration = 0.5                  # s, ramp
//! table = [[0.0, 0,0,0], [1.0, 0,0,0.01]]   # rows [t, dx, dy, dz], t increasing (mode "table")
//! radius = 0.01                   # m, optional: prescribe a surface patch instead of one node:
//!                                 # the surface nodes within `radius` of the surface point
//!                                 # nearest `point` (at least the nearest node), as
//!                                 # sim::Simulation::grab selects them; fixed nodes and nodes of
//!                                 # an earlier [[displace]] are left out. All move together
//! time = { kind = "sine", frequency = 2.0 } # instead of `mode`: `displacement` times s(t)
//! start = 1.2                     # s, [interactive] only: a grasp taken during the run, as
//!                                 # `raisov serve` takes one: from the first frame at or
//!                                 # after `start` (default 0), the surface patch within
//!                                 # `radius` (default 0: one node) of the point g of the
//!                                 # *deformed* surface nearest `point`, free nodes only,
//!                                 # moved rigidly to g + d(t), d the path above (default:
//!                                 # held where taken); free before. Any of `start`,
//!                                 # `release`, `stiffness` makes the entry such a grasp
//!                                 # (rules: scenario::grasps)
//! release = 2.5                   # s, after `start`: let go from the first frame at or after
//!                                 # it, the nodes free again; default: held to the end
//! stiffness = 200.0               # N/m: pull the patch by zero-length springs of this total
//!                                 # stiffness (sim::Coupling::Spring) instead of holding it
//! friction = 0.4                  # with `stiffness` and `clamp_force`: a friction grasp
//! clamp_force = 2.0               # (sim::GrabOptions::friction): the jaws' friction
//!                                 # coefficient μ and clamp force N (N); the patch slides
//!                                 # where it pulls harder than μ N
//!
//! [[pin]]                         # [interactive] only: a pin taken during the run, as
//!                                 # `raisov serve` pins (scenario::grasps): the patch a grasp
//!                                 # would take near `point` within `radius`, held where it
//!                                 # stands, on every level, from the first frame at or
//!                                 # after `start` to the end
//! point = [0.04, 0.04, 0.04]      # m
//! radius = 0.01                   # m, default 0
//! start = 0.8                     # s, default 0
//!
//! [[cut]]                         # a scalpel's cut (crate::mesh::cut, every level): the
//!                                 # elements the blade crosses split along it, the wound's
//!                                 # faces free; tetrahedra, runs in time or interactive
//!                                 # (scenario::cuts)
//! time = 0.5                      # s, default 0: before the first step (the first frame, in an
//!                                 # interactive run) at or after it
//! edge = [[0.02, -0.01, 0.05], [0.02, 0.05, 0.05]]  # m: the blade's edge ...
//! sweep = [0.0, 0.0, -0.03]       # m: ... swept along this, giving the quad edge, edge + sweep
//! # quad = [[..], [..], [..], [..]]  # m: or the blade's quad itself (planar, convex, in order)
//!
//! [[pressure]]                    # follower pressure on surface triangles (crate::fem::loads):
//! group = "zmax"                  # the boundary triangles (tets) or elements (membranes) whose
//!                                 # three nodes are in this group, or
//! point = [0.01, 0.01, 0.02]      # those within `radius` (m) of `point` (a patch), or
//! radius = 0.006
//! boundary = true                 # the whole boundary (membranes: every element)
//! value = 2000.0                  # Pa; acts on the side the normals point to: on a tet mesh
//!                                 # the normals point out, so a positive value pushes into the
//!                                 # body; on a membrane the node order sets the side
//! time = { kind = "ramp", duration = 0.05 }   # optional, as for [[load]]
//!
//! [[traction]]                    # fixed traction per reference area, the same selectors
//! group = "xmax"
//! traction = [0.0, 0.0, -100.0]   # Pa
//! time = { .. }                   # optional
//!
//! [[tool]]                        # rigid tool, penalty contact (crate::contact)
//! shape = "sphere"                # "sphere" (center, radius) | "plane" (point, normal pointing
//!                                 # out of the tool) | "capsule" (a, b: the axis ends; radius)
//! center = [0.01, 0.01, 0.025]    # m
//! radius = 0.005                  # m
//! displacement = [0.0, 0.0, -0.002] # m, the tool's translation, times `time` (default
//! time = { kind = "ramp", duration = 0.05 }  # constant), or instead
//! path = [[0.0, 0,0,0], [1.0, 0,0,-0.002]]   # rows [t, dx, dy, dz], piecewise linear
//! stiffness = 2000.0              # N/m; default 4 × the material's stability modulus × the
//!                                 # mean edge length of the level it acts on
//! friction = 0.3                  # Coulomb coefficient (static = kinetic); default 0,
//!                                 # frictionless. Or static_friction = 0.5 with
//!                                 # kinetic_friction = 0.3 (<= static; default static)
//! friction_stiffness = 2000.0     # N/m, the tangential stick spring; default `stiffness`.
//!                                 # Friction is path dependent: single-level explicit
//!                                 # methods and "implicit-euler" only; an error with
//!                                 # "newton" and with [multigrid] explicit schemes
//!
//! [integrator]
//! method = "symplectic-euler"     # "forward-euler" | "symplectic-euler" | "rk4" |
//!                                 # "central-difference" | "implicit-euler" | "bdf2" |
//!                                 # "newton";
//!                                 # default "symplectic-euler". "implicit-euler": backward
//!                                 # Euler (statics::implicit), each step a Newton solve of
//!                                 # M(v'-v)/h + alpha M v' + R(u') = V by `solver` ("auto":
//!                                 # "multigrid" where [multigrid] gives a level with >= 1/32
//!                                 # of the nodes, else "direct"; not "krylov"), at most
//!                                 # `max_newton` (default 30) iterations a step to
//!                                 # `newton_tol` (default 1e-6) of the largest nodal load
//!                                 # plus the step's starting out-of-balance force; stable at
//!                                 # any step and dissipative, first-order accurate; `dt` is
//!                                 # required; of [multigrid] only the levels (the V-cycle
//!                                 # preconditions the Newton systems). "bdf2": the same
//!                                 # with the two-step backward differentiation formula,
//!                                 # second-order accurate, far less numerical damping (its
//!                                 # first step by backward Euler; `dt` constant); the same
//!                                 # keys as "implicit-euler". "newton": no dynamics, the static
//!                                 # equilibrium R(u) = V with the motions at their end, by
//!                                 # Newton's method (`solver`) to `[run] residual_tol`
//!                                 # (default 1e-7): the largest nodal residual relative to
//!                                 # the largest nodal load plus the starting out-of-balance
//!                                 # force (plus 1e-14 N), whatever the solver; `dt`
//!                                 # and the other [run] keys are not used;
//!                                 # of [multigrid] only the levels (its other keys are
//!                                 # errors); not with [interactive]. Exit status 3 if it does not converge
//! solver = "auto"                 # newton: "auto" (default) | "multigrid" | "direct" |
//!                                 # "krylov" (StaticSolver): "auto" is "multigrid" where
//!                                 # [multigrid] gives a level with >= 1/32 of the nodes, else
//!                                 # "direct" (pressure, tools and springs are in the
//!                                 # assembled tangent; tilted sliding planes projected)
//! max_newton = 50                 # newton: Newton steps at most per increment, default 50;
//!                                 # implicit-euler, bdf2: per step, default 30
//! newton_tol = 1e-6               # implicit-euler, bdf2: each step's relative tolerance
//! increments = 10                 # newton: loads and prescribed displacements applied in
//!                                 # this many equal increments, default 10 for "krylov",
//!                                 # 1 for "direct" and "multigrid" (whose first iteration
//!                                 # of an increment lifts the prescribed motion: the free
//!                                 # nodes follow it linearly)
//! coarse_start = true             # newton, "multigrid" (also as "auto"'s choice): start the
//!                                 # fine iteration from the coarse level's equilibrium,
//!                                 # interpolated (nested iteration; the coarse level solved by
//!                                 # direct Newton over `increments`, the fine in one), default
//!                                 # true for membranes (the 100k drape from flat about 3x
//!                                 # faster), false for tetrahedra (the liver no faster; both
//!                                 # by `raisov bench equilibrium`), see
//!                                 # statics::nested::coarse_start
//! smoother = "block-jacobi"       # newton, "multigrid" (also as "auto"'s choice): the
//!                                 # V-cycle's smoother, "block-jacobi" (default for
//!                                 # tetrahedra) | "block-gauss-seidel" (coloured; default for
//!                                 # membranes) | "gauss-seidel" (point, one thread)
//! dt = 1e-4                       # s; default: safety × estimated critical step
//!                                 # (crate::integrate::stability)
//! safety = 0.5                    # fraction of the estimated critical step, default 0.5
//! precision = "f64"               # element data of the force pass: "f64" (default) | "f32-storage"
//!                                 # (Dm⁻¹ and volumes stored in f32, arithmetic and state f64;
//!                                 # fewer bytes per step on large meshes, forces within 1e-6
//!                                 # relative of f64, see fem::packed). Applies to neo-Hookean
//!                                 # tetrahedra (the packed path); elsewhere f64 with a note
//!
//! [run]
//! stop = "duration"               # "duration" (default) | "steady"
//! duration = 1.0                  # s of simulated time (stop = "duration", required); the cap
//!                                 # for "steady", default 60
//! kinetic_tol = 1e-8              # steady: kinetic energy below this × its peak, default 1e-8
//! residual_tol = 1e-4             # steady: residual norm below this × its peak, default 1e-4
//! stagnation = 1000               # steady: give up after this many rows of measures.csv
//!                                 # without progress (the steady measure not 0.1 % below its
//!                                 # best), counted once the motions end; 0 never. Default 1000
//! blowup_factor = 1e3             # energy blow-up threshold factor (see integrate::stepper),
//!                                 # default 1e3
//!
//! [output]
//! dir = "raisov-out/NAME"         # relative to this file; default raisov-out/NAME relative to
//!                                 # the working directory; `raisov run --out DIR` overrides
//! frame_interval = 0.05           # s between VTU frames, default 0.05; 0 writes only the
//!                                 # first and last
//! csv_every = 1                   # steps between rows of measures.csv, default 1
//! vtu = "binary"                  # frame storage: "binary" (default; appended raw, zlib-
//!                                 # compressed, ParaView's own layout) | "ascii" (text);
//!                                 # `raisov run --ascii-vtu` overrides. Frames hold the
//!                                 # reference points and a `displacement` point field (the
//!                                 # active vectors: ParaView's Warp By Vector deforms them)
//! reference = "none"              # T∞ for |T − T∞|: "none" (default) | "auto" | path to an
//!                                 # earlier run's nodal_stress.csv
//!
//! [multigrid]                     # optional: integrate over a hierarchy of independent meshes
//! scheme = "fas"                  # "fas" (default; converges) | "raisov-paper" (the literal method)
//!                                 # | "newton" (the frame solver; the default with [interactive]
//!                                 # unless FAS's own keys are set)
//! levels = 4                      # with [mesh] generate or surface: level count, node counts
//!                                 # a geometric series (surface without [multigrid]: 1 level)
//! ratio = 0.5                     # node-count ratio between levels, default 0.5 (the paper's)
//! level_nodes = [186, 103, 55, 31] # or explicit node targets per generated level, level 0
//!                                 # first (must equal [mesh] nodes); instead of levels/ratio
//! files = ["L1.msh", "L2.msh"]    # or coarser levels as files (level 0 is [mesh]); same `scale`
//! reading = "correction"          # raisov-paper: "paper" | "correction", default "correction"
//! epsilon = 1e-5                  # raisov-paper: switch threshold (m), default 1e-3 × shortest edge
//! pre_smooth = 4                  # fas: ν1, default 4
//! post_smooth = 4                 # fas: ν2, default 4
//! smoother = "chebyshev"          # fas: "chebyshev" (default) | "dynamics" (damped explicit steps)
//! coarse = "chebyshev"            # fas: coarsest solve, "chebyshev" (default; 60 iterations) |
//!                                 #      "explicit" (damped steps) | "newton" (Newton-Krylov to
//!                                 #      a relative residual of 1e-6)
//! scaling = "fictitious"          # fas chebyshev: preconditioner, "fictitious" (default; per-node
//!                                 #      fictitious masses) | "mass" (lumped mass)
//! transfer = "convex"             # fas: weights of R, P: "convex" (default; eq. 7 extrapolating
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
//!                                 # (safety × its estimated critical step)
//!                                 # The keys marked fas or raisov-paper are errors with the
//!                                 # other scheme.
//!
//! [interactive]                   # optional: a fixed budget per frame while the [[displace]]
//!                                 # paths move (surgical interaction); `raisov run` then writes
//!                                 # frames.csv with the lag to the static solution per frame
//! fps = 30.0                      # frames per second of the path's time, default 30
//! cycles = 4                      # steps (single level) or V-cycles (multigrid) per frame,
//!                                 # default 4; or instead
//! budget_ms = 33.0                # wall-time budget per frame (ms): as many as fit
//! reference = "newton"            # static solution per frame: "newton" (default) | "none"
//! reference_tol = 1e-8            # its largest nodal residual over the frame's force scale
//!                                 # (the largest load, spring pull or out-of-balance force),
//!                                 # default 1e-8
//! lag_tol = 0.05                  # "keeps up with real time" needs every frame's lag within
//!                                 # this fraction of max |u*| (and the frame rate), default 0.05
//! predictor = true                # start a frame whose grasps move from the last frame's
//!                                 # change, extrapolated (crate::sim::frame); default true
//! ```

use super::Reference;
use crate::error::{Error, Result};
use crate::fem::Precision;
use crate::integrate::Method;
use crate::io::VtuFormat;
use crate::mesh::generate::BoxPattern;
use crate::model::SchemeKind;
use crate::multigrid::fas::{Scaling, TransferWeights};
use crate::multigrid::raisov::Reading;
pub use crate::statics::StaticSolver;
use serde::de::{Deserializer, Error as _};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// The default of every scenario key that has one (the FAS settings default to
/// [`crate::multigrid::fas::FasParams::default`]). The module documentation lists them per key.
pub mod defaults {
    use super::{Law, SchemeKind, StaticSolver};
    use crate::integrate::Method;
    use crate::mesh::generate::BoxPattern;
    use crate::multigrid::raisov::Reading;

    /// `name` where the scenario file has no stem.
    pub const NAME: &str = "scenario";
    /// `[mesh] scale`: coordinates are in metres.
    pub const SCALE: f64 = 1.0;
    /// `[mesh] pattern`: 6 tetrahedra per cube (Kuhn).
    pub const BOX_PATTERN: BoxPattern = BoxPattern::Six;
    /// `[mesh] renumber` for mesh files (level files included).
    pub const RENUMBER_FILES: bool = true;
    /// `[mesh] renumber` for generated meshes (numbered along the axes already).
    pub const RENUMBER_GENERATED: bool = false;
    /// `[material] law` of a scenario with an `[interactive]` section (elsewhere `law` is
    /// required): the stable neo-Hookean law, defined for inverted elements.
    pub const INTERACTIVE_LAW: Law = Law::StableNeoHookean;
    /// `[material] density` (kg/m³).
    pub const DENSITY: f64 = 1000.0;
    /// `[material] thickness` of membranes (m).
    pub const THICKNESS: f64 = 1e-3;
    /// `[damping] alpha` (1/s): undamped.
    pub const ALPHA: f64 = 0.0;
    /// `gravity` (m/s²): none.
    pub const GRAVITY: [f64; 3] = [0.0; 3];
    /// `[integrator] increments` of `method = "newton"` with `solver = "krylov"`.
    pub const INCREMENTS: usize = 10;
    /// `[integrator] increments` of `method = "newton"` with `solver = "direct"` or
    /// `"multigrid"` (their line search and regularisation globalise a single step).
    pub const ASSEMBLED_INCREMENTS: usize = 1;
    /// `[integrator] solver` of `method = "newton"`.
    pub const STATIC_SOLVER: StaticSolver = StaticSolver::Auto;
    /// `[integrator] max_newton` of `method = "newton"`.
    pub const MAX_NEWTON: usize = 50;
    /// The relative residual of `method = "newton"` (`[run] residual_tol` sets it).
    pub const NEWTON_TOL: f64 = 1e-7;
    /// `[integrator] method`.
    pub const METHOD: Method = Method::SymplecticEuler;
    /// `[multigrid] scheme` of a scenario without `[interactive]` (with it, the frame
    /// solver, unless FAS's own keys are set).
    pub const SCHEME: SchemeKind = SchemeKind::Fas;
    /// `[integrator] safety`: the fraction of the estimated critical step taken where no
    /// `dt` is given (and on the coarser FAS levels without `level_dt`).
    pub const SAFETY: f64 = 0.5;
    /// `[run] duration` with `stop = "steady"`: the cap on simulated time (s).
    pub const STEADY_CAP: f64 = 60.0;
    /// `[run] kinetic_tol`.
    pub const KINETIC_TOL: f64 = 1e-8;
    /// `[run] residual_tol`.
    pub const RESIDUAL_TOL: f64 = 1e-4;
    /// `[run] stagnation` (checks, i.e. rows of `measures.csv`).
    pub const STAGNATION: u64 = 1000;
    /// `[run] blowup_factor`.
    pub const BLOWUP_FACTOR: f64 = 1e3;
    /// The directory under which `[output] dir` defaults to `OUTPUT_ROOT/NAME`.
    pub const OUTPUT_ROOT: &str = "raisov-out";
    /// `[output] frame_interval` (s).
    pub const FRAME_INTERVAL: f64 = 0.05;
    /// `[output] csv_every` (steps).
    pub const CSV_EVERY: u64 = 1;
    /// `[multigrid] ratio` of node counts between generated levels (the paper's).
    pub const LEVEL_RATIO: f64 = 0.5;
    /// `[multigrid] reading` of raisov-paper.
    pub const READING: Reading = Reading::Correction;
    /// `[multigrid] epsilon` of raisov-paper, as a fraction of the shortest edge of level 0.
    pub const EPSILON_PER_EDGE: f64 = crate::multigrid::raisov::RaisovParams::EPSILON_PER_EDGE;
    /// `[multigrid] coarse_time` of the explicit coarsest solve (s per visit).
    pub const COARSE_TIME: f64 = 0.1;
    /// Relative residual of `[multigrid] coarse = "newton"`.
    pub const COARSE_NEWTON_TOL: f64 = 1e-6;
    /// `[interactive] fps`.
    pub const FPS: f64 = 30.0;
    /// `[interactive] cycles` per frame.
    pub const CYCLES: usize = 4;
    /// `[interactive] reference_tol`.
    pub const REFERENCE_TOL: f64 = 1e-8;
    /// `[interactive] lag_tol`: the relative lag within which a fast run keeps up.
    pub const LAG_TOL: f64 = 0.05;
    /// `[interactive] predictor`.
    pub const PREDICTOR: bool = true;
}

/// A closed set of values that a scenario key names by string.
pub trait Named: Sized + Copy + 'static {
    /// Every value, in the order messages list them.
    const ALL: &'static [Self];
    /// The scenario's spelling.
    fn name(self) -> &'static str;
    /// Other accepted spellings.
    fn aliases(self) -> &'static [&'static str] {
        &[]
    }
    /// The value spelled `s`.
    fn from_name(s: &str) -> Option<Self> {
        Self::ALL
            .iter()
            .copied()
            .find(|v| v.name() == s || v.aliases().contains(&s))
    }
    /// The valid spellings, quoted: `"a", "b"`.
    fn valid() -> String {
        let names: Vec<String> = Self::ALL
            .iter()
            .map(|v| format!("\"{}\"", v.name()))
            .collect();
        names.join(", ")
    }
}

/// Messages of value errors start with this; [`parse`] writes the key before it.
const VALUE_ERROR: &str = "= ";

/// `Deserialize` from the name ([`Named`]): an unknown name is an error listing the valid ones.
macro_rules! deserialize_named {
    ($($t:ty),+) => {$(
        impl<'de> Deserialize<'de> for $t {
            fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
                let s = String::deserialize(d)?;
                <$t as Named>::from_name(&s).ok_or_else(|| {
                    D::Error::custom(format!(
                        "{VALUE_ERROR}\"{s}\": valid are {}",
                        <$t as Named>::valid()
                    ))
                })
            }
        }
    )+};
}

/// An enum of named values: the type, its [`Named`] spelling and `Deserialize`.
macro_rules! named_enum {
    (
        $(#[$meta:meta])*
        pub enum $name:ident {
            $($(#[$vmeta:meta])* $var:ident = $s:literal $(| $alias:literal)*,)+
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq)]
        pub enum $name {
            $($(#[$vmeta])* $var,)+
        }
        impl Named for $name {
            const ALL: &'static [Self] = &[$($name::$var),+];
            fn name(self) -> &'static str {
                match self {
                    $($name::$var => $s,)+
                }
            }
            fn aliases(self) -> &'static [&'static str] {
                match self {
                    $($name::$var => &[$($alias),*],)+
                }
            }
        }
        deserialize_named!($name);
    };
}

named_enum! {
    /// `[mesh] generate`.
    pub enum Generator {
        /// A rectangular membrane `size = [w, h]`, centred on the origin.
        Rectangle = "rectangle",
        /// A membrane inside `polygon`.
        Polygon = "polygon",
        /// A tetrahedral box `size = [x, y, z]`.
        Box = "box",
    }
}

/// `[integrator] solver`: the one [`StaticSolver`] of [`crate::statics`].
impl Named for StaticSolver {
    const ALL: &'static [Self] = &StaticSolver::ALL;
    fn name(self) -> &'static str {
        StaticSolver::name(self)
    }
}

named_enum! {
    /// `[integrator] smoother` of `solver = "multigrid"`: the Galerkin V-cycle's smoother
    /// ([`crate::linalg::smoother::Smoother`]).
    pub enum NewtonSmoother {
        /// Damped node-block Jacobi, rows in parallel; the default for tetrahedra.
        BlockJacobi = "block-jacobi",
        /// Node-block Gauss-Seidel over a colouring, each colour's blocks in parallel; the
        /// default for membranes.
        BlockGaussSeidel = "block-gauss-seidel",
        /// Point Gauss-Seidel on one thread.
        GaussSeidel = "gauss-seidel",
    }
}

named_enum! {
    /// `[material] law`.
    pub enum Law {
        /// `"stvk"` or `"st-venant-kirchhoff"`: St Venant-Kirchhoff, from `young` and
        /// `poisson` ([`crate::material::StVenantKirchhoff`]).
        StVenantKirchhoff = "stvk" | "st-venant-kirchhoff",
        /// `"neo-hookean"`: compressible neo-Hookean, from `young` and `poisson`
        /// ([`crate::material::NeoHookean`]).
        NeoHookean = "neo-hookean",
        /// `"mooney-rivlin"`: from `c1`, `c2` and, for solids, `kappa`
        /// ([`crate::material::MooneyRivlin`]).
        MooneyRivlin = "mooney-rivlin",
        /// `"veronda-westmann"`: from `c1`, `gamma` and, for solids, `kappa`
        /// ([`crate::material::VerondaWestmann`]).
        VerondaWestmann = "veronda-westmann",
        /// `"stable-neo-hookean"`: from `young` and `poisson`, finite for inverted elements
        /// ([`crate::material::StableNeoHookean`]); the default with `[interactive]`.
        StableNeoHookean = "stable-neo-hookean",
        /// `"ti-neo-hookean"`: NiftySim's transversely isotropic neo-Hookean, from `mu` and
        /// `kappa` (or `young` and `poisson`), `eta` and `fibre`; solids only
        /// ([`crate::material::TiNeoHookean`]).
        TiNeoHookean = "ti-neo-hookean",
        /// `"hgo"` or `"holzapfel-gasser-ogden"`: one fibre family, from `mu` and `kappa` (or
        /// `young` and `poisson`), `k1`, `k2`, `dispersion` (default 0) and `fibre`; solids
        /// only ([`crate::material::HolzapfelGasserOgden`]).
        HolzapfelGasserOgden = "hgo" | "holzapfel-gasser-ogden",
        /// `"neo-hookean-visco"`: NiftySim's visco-hyperelastic neo-Hookean, from `mu` and
        /// `kappa` (or `young` and `poisson`, the instantaneous moduli) and `prony`; solids
        /// only ([`crate::material::NeoHookeanVisco`]).
        NeoHookeanVisco = "neo-hookean-visco",
    }
}

named_enum! {
    /// `[[displace]] mode`.
    pub enum MotionMode {
        /// At `displacement` from t = 0.
        Held = "held",
        /// Linearly from 0 to `displacement` over `duration`, then held.
        Ramp = "ramp",
        /// Piecewise linear through the rows of `table`.
        Table = "table",
    }
}

named_enum! {
    /// `time = { kind = .. }`: the time function of a load, a prescribed displacement or a
    /// tool path ([`crate::time::TimeFunction`]).
    pub enum TimeKind {
        /// `s = 1`.
        Constant = "constant",
        /// `s = min(t / duration, 1)`.
        Ramp = "ramp",
        /// Piecewise linear through the rows `[t, s]` of `table`.
        Table = "table",
        /// `s = amplitude sin(2π frequency t + phase)`.
        Sine = "sine",
    }
}

named_enum! {
    /// `[[tool]] shape`.
    pub enum ToolKind {
        /// `center`, `radius`.
        Sphere = "sphere",
        /// `point`, `normal` (pointing out of the tool).
        Plane = "plane",
        /// `a`, `b` (the segment's ends), `radius`.
        Capsule = "capsule",
    }
}

named_enum! {
    /// `[run] stop`.
    #[derive(Default)]
    pub enum Stop {
        /// After `duration` seconds.
        #[default]
        Duration = "duration",
        /// At steady state, or at the `duration` cap.
        Steady = "steady",
    }
}

/// `[multigrid] scheme`: a kind of the one [`super::Scheme`], spelled `"fas"`,
/// `"raisov-paper"` or `"newton"` ([`SchemeKind::MULTIGRID`]; the single-level kinds are
/// named by `[integrator] method`).
impl Named for SchemeKind {
    const ALL: &'static [Self] = &SchemeKind::MULTIGRID;
    fn name(self) -> &'static str {
        SchemeKind::name(self)
    }
}

/// The words of `[multigrid] scheme`, now the kinds of the one scheme enum.
#[deprecated(note = "use `raisov::SchemeKind` (the kinds of the one `raisov::Scheme`)")]
pub type Scheme = SchemeKind;

named_enum! {
    /// `[multigrid] smoother` (fas).
    pub enum SmootherKind {
        /// `"chebyshev"` (default): Chebyshev iteration on `D⁻¹(F − R(u))`, D by `scaling`
        /// ([`crate::multigrid::fas::Smoother::Chebyshev`]).
        Chebyshev = "chebyshev",
        /// `"dynamics"`: damped explicit steps of the level's integrator
        /// ([`crate::multigrid::fas::Smoother::Dynamics`]).
        Dynamics = "dynamics",
    }
}

named_enum! {
    /// `[multigrid] coarse` (fas).
    pub enum CoarseKind {
        /// `"chebyshev"` (default): `coarse_iterations` Chebyshev iterations per visit.
        Chebyshev = "chebyshev",
        /// `"explicit"`: damped explicit steps over `coarse_time` per visit.
        Explicit = "explicit",
        /// `"newton"`: Newton-Krylov to a relative residual of 1e-6.
        Newton = "newton",
    }
}

named_enum! {
    /// `[multigrid] accelerate` (fas).
    pub enum Accelerate {
        /// Nonlinear conjugate gradients preconditioned by the V-cycle.
        Cg = "cg",
        /// Plain V-cycles.
        None = "none",
    }
}

named_enum! {
    /// `[interactive] reference`.
    #[derive(Default)]
    pub enum StaticReference {
        /// Solve for the static solution of each frame (the static solve's Newton solver).
        #[default]
        Newton = "newton",
        /// No reference: no lag.
        None = "none",
    }
}

/// `[integrator] method`: an explicit integrator, or the static Newton solve.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Solve {
    /// Explicit dynamics with this integrator.
    Dynamic(Method),
    /// `"newton"`: static equilibrium `R(u) = V` by Newton's method, its linear solver by
    /// `solver` ([`StaticSolver`]).
    Newton,
    /// `"implicit-euler"`: backward Euler dynamics, each step a Newton solve
    /// ([`crate::statics::implicit`]), its linear solver by `solver`.
    ImplicitEuler,
    /// `"bdf2"`: the two-step backward differentiation formula, each step a Newton solve as
    /// `"implicit-euler"`'s ([`crate::statics::implicit::ImplicitScheme::Bdf2`]).
    Bdf2,
}

impl Named for Solve {
    const ALL: &'static [Self] = &[
        Solve::Dynamic(Method::ForwardEuler),
        Solve::Dynamic(Method::SymplecticEuler),
        Solve::Dynamic(Method::Rk4),
        Solve::Dynamic(Method::CentralDifference),
        Solve::Newton,
        Solve::ImplicitEuler,
        Solve::Bdf2,
    ];
    fn name(self) -> &'static str {
        match self {
            Solve::Dynamic(m) => m.name(),
            Solve::Newton => "newton",
            Solve::ImplicitEuler => "implicit-euler",
            Solve::Bdf2 => "bdf2",
        }
    }
}

impl Named for Method {
    const ALL: &'static [Self] = &Method::ALL;
    fn name(self) -> &'static str {
        Method::name(self)
    }
}

impl Named for Precision {
    const ALL: &'static [Self] = &Precision::ALL;
    fn name(self) -> &'static str {
        Precision::name(self)
    }
}

impl Named for Reading {
    const ALL: &'static [Self] = &[Reading::Paper, Reading::Correction];
    fn name(self) -> &'static str {
        match self {
            Reading::Paper => "paper",
            Reading::Correction => "correction",
        }
    }
}

impl Named for Scaling {
    const ALL: &'static [Self] = &[Scaling::Fictitious, Scaling::Mass];
    fn name(self) -> &'static str {
        match self {
            Scaling::Fictitious => "fictitious",
            Scaling::Mass => "mass",
        }
    }
}

impl Named for TransferWeights {
    const ALL: &'static [Self] = &[
        TransferWeights::Convex,
        TransferWeights::Exact,
        TransferWeights::ConvexRestriction,
    ];
    fn name(self) -> &'static str {
        match self {
            TransferWeights::Convex => "convex",
            TransferWeights::Exact => "exact",
            TransferWeights::ConvexRestriction => "convex-restriction",
        }
    }
}

impl Named for VtuFormat {
    const ALL: &'static [Self] = &[VtuFormat::Binary, VtuFormat::Ascii];
    fn name(self) -> &'static str {
        VtuFormat::name(self)
    }
}

deserialize_named!(
    Solve,
    StaticSolver,
    Method,
    Precision,
    SchemeKind,
    Reading,
    Scaling,
    TransferWeights,
    VtuFormat
);

/// `[mesh] pattern`: the number of tetrahedra per cube.
pub fn box_pattern(tets_per_cube: u32) -> Option<BoxPattern> {
    [BoxPattern::Five, BoxPattern::Six]
        .into_iter()
        .find(|p| p.tets_per_cube() as u32 == tets_per_cube)
}

impl<'de> Deserialize<'de> for BoxPattern {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        let n = u32::deserialize(d)?;
        box_pattern(n).ok_or_else(|| {
            D::Error::custom(format!("{VALUE_ERROR}{n}: valid are 5 or 6 tets per cube"))
        })
    }
}

/// `[output] reference`: `"none"`, `"auto"` or a path (relative to the scenario file; joined
/// to its directory and checked when the scenario is resolved).
impl<'de> Deserialize<'de> for Reference {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        Ok(match s.as_str() {
            "none" => Reference::None,
            "auto" => Reference::Auto,
            _ => Reference::File(PathBuf::from(s)),
        })
    }
}

/// A scenario file as written: the keys of the module documentation, typed. [`parse`] reads
/// it; [`super::Scenario::resolve`] checks and resolves it.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioSpec {
    /// `name`: names the files written under the output directory; default the file's stem,
    /// characters outside [`crate::io::NAME_RULE`] replaced by `_`.
    pub name: Option<String>,
    /// `gravity` (m/s²); default none.
    pub gravity: Option<[f64; 3]>,
    /// `[mesh]`: one of `file`, `generate` or `surface`.
    pub mesh: MeshSpec,
    /// `[material]`: the law and its parameters.
    pub material: MaterialSpec,
    /// `[damping]`; default undamped.
    #[serde(default)]
    pub damping: DampingSpec,
    /// `[[fix]]`: fixed nodes, or held directions.
    #[serde(default)]
    pub fix: Vec<RegionSpec>,
    /// `[[load]]`: nodal forces.
    #[serde(default)]
    pub load: Vec<LoadSpec>,
    /// `[[displace]]`: prescribed displacements.
    #[serde(default)]
    pub displace: Vec<DisplaceSpec>,
    /// `[[pin]]`: pins taken during an interactive run (what the viewer records).
    #[serde(default)]
    pub pin: Vec<PinSpec>,
    /// `[[cut]]`: cuts made during the run.
    #[serde(default)]
    pub cut: Vec<CutSpec>,
    /// `[[pressure]]`: follower pressures on surface triangles.
    #[serde(default)]
    pub pressure: Vec<SurfaceLoadSpec>,
    /// `[[traction]]`: fixed tractions per reference area.
    #[serde(default)]
    pub traction: Vec<SurfaceLoadSpec>,
    /// `[[tool]]`: rigid tools in penalty contact, frictionless or with Coulomb friction.
    #[serde(default)]
    pub tool: Vec<ToolSpec>,
    /// `[integrator]`: the time integrator, or the static solve.
    #[serde(default)]
    pub integrator: IntegratorSpec,
    /// `[run]`: when the run stops.
    #[serde(default)]
    pub run: RunSpec,
    /// `[output]`: where and how the results are written.
    #[serde(default)]
    pub output: OutputSpec,
    /// `[multigrid]`: a hierarchy of meshes of the same object; `None`: one level.
    pub multigrid: Option<MultigridSpec>,
    /// `[interactive]`: a fixed budget per frame along the `[[displace]]` paths; `None`
    /// for a plain run.
    pub interactive: Option<InteractiveSpec>,
}

/// `[multigrid]`: integrate over a hierarchy of independent meshes of the same object.
#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct MultigridSpec {
    /// `scheme`: `"fas"`, `"raisov-paper"` or `"newton"`; without it
    /// [`MultigridSpec::scheme_kind`] decides.
    pub scheme: Option<SchemeKind>,
    /// `levels`: the level count, level 0 included, with `[mesh] generate` or `surface`; node
    /// counts a geometric series of ratio `ratio`.
    pub levels: Option<usize>,
    /// `ratio`: the node-count ratio between generated levels, in (0, 1); default 0.5.
    pub ratio: Option<f64>,
    /// `level_nodes`: explicit node targets of generated levels, level 0 first (= `[mesh]
    /// nodes`); instead of `levels` and `ratio`.
    pub level_nodes: Option<Vec<usize>>,
    /// `files`: the coarser levels' mesh files, level 1 first, relative to the scenario file;
    /// read with `[mesh] scale` and `renumber`.
    pub files: Option<Vec<String>>,
    /// `reading` (raisov-paper): how the up stroke reads δX, `"paper"` or `"correction"`
    /// (default).
    pub reading: Option<Reading>,
    /// `epsilon` (raisov-paper): the switch threshold ε (m) of eqs. 10 and 12, at least 0;
    /// default 1e-3 × level 0's shortest edge.
    pub epsilon: Option<f64>,
    /// `cg_per_step` (newton): conjugate-gradient iterations per Newton step, at least 1;
    /// default 2.
    pub cg_per_step: Option<usize>,
    /// `pre_smooth` (fas): ν1, smoothing steps per level before the coarse correction; default 4.
    pub pre_smooth: Option<usize>,
    /// `post_smooth` (fas): ν2, smoothing steps per level after it; default 4.
    pub post_smooth: Option<usize>,
    /// `coarse` (fas): the coarsest level's solve; default `"chebyshev"`.
    pub coarse: Option<CoarseKind>,
    /// `coarse_time` (fas, `coarse = "explicit"`): simulated time per visit (s); default 0.1.
    pub coarse_time: Option<f64>,
    /// `coarse_iterations` (fas, `coarse = "chebyshev"`): iterations per visit, at least 1;
    /// default 60.
    pub coarse_iterations: Option<usize>,
    /// `smoother` (fas): `"chebyshev"` (default) or `"dynamics"`.
    pub smoother: Option<SmootherKind>,
    /// `transfer` (fas): the weights of R and P; default `"convex"`.
    pub transfer: Option<TransferWeights>,
    /// `scaling` (fas, Chebyshev smoother): the diagonal preconditioner; default
    /// `"fictitious"`.
    pub scaling: Option<Scaling>,
    /// `accelerate` (fas, Chebyshev smoother): `"cg"` (default) or `"none"`.
    pub accelerate: Option<Accelerate>,
    /// `level_methods`: the integrator of each level, level 0 first; default `[integrator]
    /// method` on every level.
    pub level_methods: Option<Vec<Method>>,
    /// `level_dt`: the step of each level (s), level 0 first; default: raisov-paper level 0's
    /// step on every level, fas each level's `safety` × its estimated critical step.
    pub level_dt: Option<Vec<f64>>,
}

/// The keys of `[multigrid]` only FAS (`scheme = "fas"`) takes.
pub const FAS_KEYS: &[&str] = &[
    "pre_smooth",
    "post_smooth",
    "coarse",
    "coarse_time",
    "coarse_iterations",
    "smoother",
    "scaling",
    "transfer",
    "accelerate",
];
/// The keys of `[multigrid]` only the paper's cycle (`scheme = "raisov-paper"`) takes.
pub const PAPER_KEYS: &[&str] = &["reading", "epsilon"];
/// The keys of `[multigrid]` only the frame solver (`scheme = "newton"`) takes.
pub const NEWTON_KEYS: &[&str] = &["cg_per_step"];

impl MultigridSpec {
    /// Whether the section sets `key` (one of [`FAS_KEYS`], [`PAPER_KEYS`] or
    /// [`NEWTON_KEYS`]; false for any other name).
    pub fn sets(&self, key: &str) -> bool {
        match key {
            "pre_smooth" => self.pre_smooth.is_some(),
            "post_smooth" => self.post_smooth.is_some(),
            "coarse" => self.coarse.is_some(),
            "coarse_time" => self.coarse_time.is_some(),
            "coarse_iterations" => self.coarse_iterations.is_some(),
            "smoother" => self.smoother.is_some(),
            "scaling" => self.scaling.is_some(),
            "transfer" => self.transfer.is_some(),
            "accelerate" => self.accelerate.is_some(),
            "reading" => self.reading.is_some(),
            "epsilon" => self.epsilon.is_some(),
            "cg_per_step" => self.cg_per_step.is_some(),
            _ => false,
        }
    }

    /// The scheme the section runs: `scheme`, or without it the frame solver where the
    /// scenario is interactive (`[interactive]`, or served by the viewer) and the section sets
    /// `cg_per_step` or none of FAS's own keys ([`FAS_KEYS`]), else FAS ([`defaults::SCHEME`]).
    /// The one rule of the resolver and the viewer.
    pub fn scheme_kind(&self, interactive: bool) -> SchemeKind {
        let fas_set = FAS_KEYS.iter().any(|k| self.sets(k));
        self.scheme
            .unwrap_or(if interactive && (self.cg_per_step.is_some() || !fas_set) {
                SchemeKind::Newton
            } else {
                defaults::SCHEME
            })
    }
}

/// `[interactive]`: a fixed budget per frame while the prescribed displacements move along
/// their paths; see [`super::interactive`].
#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct InteractiveSpec {
    /// `fps`: frames per second of path time; default 30.
    pub fps: Option<f64>,
    /// `cycles`: steps (single level) or V-cycles (multigrid) per frame, at least 1; default
    /// 4. Not with `budget_ms`.
    pub cycles: Option<usize>,
    /// `budget_ms`: the wall-time budget per frame (ms): as many steps as fit, at least one.
    pub budget_ms: Option<f64>,
    /// `reference`: the static solution per frame, `"newton"` (default) or `"none"`.
    pub reference: Option<StaticReference>,
    /// `reference_tol`: the reference solve's largest nodal residual relative to the frame's
    /// force scale (the largest nodal load, spring pull, or out-of-balance force from rest or
    /// at the start); default 1e-8.
    pub reference_tol: Option<f64>,
    /// `lag_tol`: the largest relative lag `lag_max / max|u*|` of a run that keeps up with
    /// real time; default 0.05.
    pub lag_tol: Option<f64>,
    /// `predictor`: start each frame whose grasps move from the last frame's change,
    /// extrapolated ([`crate::sim::Simulation::set_predictor`]); default true.
    pub predictor: Option<bool>,
}

/// `[mesh] size`: one length (`surface`: the lattice spacing) or several (`generate`).
#[derive(Clone, Debug, PartialEq)]
pub enum MeshSize {
    /// `size = 0.005`.
    Length(f64),
    /// `size = [0.1, 0.1]`.
    Lengths(Vec<f64>),
}

impl<'de> Deserialize<'de> for MeshSize {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Raw {
            One(f64),
            Many(Vec<f64>),
        }
        match Raw::deserialize(d) {
            Ok(Raw::One(x)) => Ok(MeshSize::Length(x)),
            Ok(Raw::Many(v)) => Ok(MeshSize::Lengths(v)),
            Err(_) => Err(D::Error::custom(format!(
                "{VALUE_ERROR}not a length: valid are a number (m, `surface`) or a list of \
                 numbers (m, `generate`)"
            ))),
        }
    }
}

/// `[mesh]`: level 0's mesh file, surface or generated shape.
#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct MeshSpec {
    /// `file`: a mesh file (.msh Gmsh 2.2/4.1, .node/.ele, .vtk, .vtu), relative to the
    /// scenario file.
    pub file: Option<String>,
    /// `scale`: the factor from the file's or generator's coordinates to metres (1e-3 for
    /// mm); default 1.
    pub scale: Option<f64>,
    /// `surface`: a closed triangle surface (.obj, .stl, .ply), relative to the scenario file,
    /// meshed at load (see the module docs).
    pub surface: Option<String>,
    /// `generate`: `"rectangle"`, `"polygon"` or `"box"`.
    pub generate: Option<Generator>,
    /// `size`: `surface`: level 0's lattice spacing (m, after `scale`); `generate`: the
    /// rectangle's `[w, h]` or the box's `[x, y, z]` (m).
    pub size: Option<MeshSize>,
    /// `polygon`: the outline `[[x, y], ...]` of `generate = "polygon"` (m).
    pub polygon: Option<Vec<[f64; 2]>>,
    /// `nodes`: the target node count of `generate` (rectangle, polygon, box), or of `surface`'s
    /// level 0 (instead of `size`).
    pub nodes: Option<usize>,
    /// `divisions`: cubes per side of `generate = "box"`, instead of `nodes`.
    pub divisions: Option<[usize; 3]>,
    /// `pattern`: tetrahedra per cube of `generate = "box"`, 5 or 6; default 6.
    pub pattern: Option<BoxPattern>,
    /// `renumber`: number the nodes in a banded order; default true for `file` and `surface`,
    /// false for `generate`.
    pub renumber: Option<bool>,
}

/// `[material] fibre`: one direction, or a direction per element (rules:
/// `crate::scenario::fibres`).
#[derive(Clone, Debug, PartialEq)]
pub enum FibreSpec {
    /// `fibre = [x, y, z]`: the same direction in every element (normalised, non-zero).
    Direction([f64; 3]),
    /// `fibre = { cell_data = "fibre" }`: a 3-component cell data array of the `.vtu` mesh
    /// file, one direction per cell (normalised, non-zero).
    CellData(String),
    /// `fibre = { helix = { .. } }`: the helix-angle rule through a wall about an axis.
    Helix(HelixSpec),
}

/// `fibre = { helix = { axis, centre, inner_radius, outer_radius, endo, epi } }`; every key
/// required (checked when resolved, naming the missing one).
#[derive(Clone, Debug, Deserialize, PartialEq, Default)]
#[serde(deny_unknown_fields)]
pub struct HelixSpec {
    /// `axis = [x, y, z]`: the wall's axis direction (normalised, non-zero).
    pub axis: Option<[f64; 3]>,
    /// `centre = [x, y, z]` (m, after `[mesh] scale`): a point on the axis.
    pub centre: Option<[f64; 3]>,
    /// `inner_radius` (m, ≥ 0): the distance from the axis where the depth is 0 (endocardium).
    pub inner_radius: Option<f64>,
    /// `outer_radius` (m, > `inner_radius`): where the depth is 1 (epicardium).
    pub outer_radius: Option<f64>,
    /// `endo` (degrees): the helix angle at depth 0.
    pub endo: Option<f64>,
    /// `epi` (degrees): the helix angle at depth 1.
    pub epi: Option<f64>,
}

impl<'de> Deserialize<'de> for FibreSpec {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct Table {
            cell_data: Option<String>,
            helix: Option<HelixSpec>,
        }
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Raw {
            Direction([f64; 3]),
            Table(Table),
        }
        const VALID: &str = "valid are [x, y, z] (one direction), { cell_data = \"NAME\" } (a \
             3-component cell array of the .vtu mesh file) or { helix = { axis = [..], centre = \
             [..], inner_radius = .., outer_radius = .., endo = .., epi = .. } } (degrees)";
        match Raw::deserialize(d) {
            Ok(Raw::Direction(a)) => Ok(FibreSpec::Direction(a)),
            Ok(Raw::Table(Table {
                cell_data: Some(name),
                helix: None,
            })) => Ok(FibreSpec::CellData(name)),
            Ok(Raw::Table(Table {
                cell_data: None,
                helix: Some(h),
            })) => Ok(FibreSpec::Helix(h)),
            Ok(Raw::Table(_)) => Err(D::Error::custom(format!(
                "{VALUE_ERROR}a table with one of `cell_data` or `helix`: {VALID}"
            ))),
            Err(_) => Err(D::Error::custom(format!(
                "{VALUE_ERROR}not a fibre direction or field: {VALID}"
            ))),
        }
    }
}

/// `[material]`: the law and its parameters.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    /// `law`: required, except with `[interactive]` (default `"stable-neo-hookean"`).
    pub law: Option<Law>,
    /// `young`: Young's modulus E (Pa) of stvk, neo-hookean and stable-neo-hookean.
    pub young: Option<f64>,
    /// `poisson`: Poisson's ratio ν, in (−1, 0.5), with `young`.
    pub poisson: Option<f64>,
    /// `c1` (Pa): mooney-rivlin's C1, veronda-westmann's c1.
    pub c1: Option<f64>,
    /// `c2` (Pa): mooney-rivlin's C2.
    pub c2: Option<f64>,
    /// `gamma`: veronda-westmann's γ (dimensionless).
    pub gamma: Option<f64>,
    /// `kappa`: the bulk modulus κ (Pa) of mooney-rivlin and veronda-westmann solids; required
    /// there, an error for membranes. With `mu`, the bulk modulus of the fibre laws.
    pub kappa: Option<f64>,
    /// `mu`: the matrix shear modulus μ (Pa) of ti-neo-hookean and hgo, with `kappa` (or
    /// `young` and `poisson` instead of both).
    pub mu: Option<f64>,
    /// `eta`: ti-neo-hookean's fibre stiffness η (Pa, ≥ 0).
    pub eta: Option<f64>,
    /// `k1`: hgo's fibre stiffness (Pa, ≥ 0).
    pub k1: Option<f64>,
    /// `k2`: hgo's fibre stiffening exponent (dimensionless, ≥ 0).
    pub k2: Option<f64>,
    /// `dispersion`: hgo's fibre dispersion κ_d in [0, 1/3]; default 0 (aligned fibres).
    pub dispersion: Option<f64>,
    /// `fibre`: the fibre direction of ti-neo-hookean and hgo in the reference
    /// configuration: `[x, y, z]` in every element, or a field ([`FibreSpec`]).
    pub fibre: Option<FibreSpec>,
    /// `prony = [[α, τ], ...]`: neo-hookean-visco's Prony terms, relative modulus α ≥ 0 (with
    /// Σ α < 1) and relaxation time τ > 0 (s) each.
    pub prony: Option<Vec<Vec<f64>>>,
    /// `density` (kg/m³); default 1000.
    pub density: Option<f64>,
    /// `thickness` of membranes (m); default 1e-3.
    pub thickness: Option<f64>,
}

/// `[damping]`: Rayleigh damping `D = α M + β K`; default α = β = 0.
#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct DampingSpec {
    /// `alpha` (1/s); or `ratio` with `omega` instead.
    pub alpha: Option<f64>,
    /// `ratio`: the damping ratio ζ, with `omega`: α = 2 ζ ω.
    pub ratio: Option<f64>,
    /// `omega`: the reference angular frequency ω (rad/s) of `ratio`.
    pub omega: Option<f64>,
    /// `beta` (s): stiffness-proportional damping, implicit methods only.
    pub beta: Option<f64>,
}

/// `box = { min = [..], max = [..] }`: an axis-aligned box.
#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct BoxSpec {
    /// `min`: the lower corner (m).
    pub min: [f64; 3],
    /// `max`: the upper corner (m).
    pub max: [f64; 3],
}

/// `plane = { point = [..], normal = [..] }`: a half-space.
#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct PlaneSpec {
    /// `point`: a point of the plane (m).
    pub point: [f64; 3],
    /// `normal`: non-zero; the nodes selected are those it points away from.
    pub normal: [f64; 3],
}

/// A node selection: exactly one field set.
#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct RegionSpec {
    /// `boundary = true`: every boundary node.
    pub boundary: Option<bool>,
    /// `box`: the nodes inside an axis-aligned box.
    #[serde(rename = "box")]
    pub aabb: Option<BoxSpec>,
    /// `plane`: the nodes with `(x − point)·normal ≤ 0`.
    pub plane: Option<PlaneSpec>,
    /// `group`: the nodes of a physical group of the mesh file.
    pub group: Option<String>,
    /// `nodes`: node ids as the mesh file numbers them (VTK files and generated meshes: by
    /// position from 0).
    pub nodes: Option<Vec<u64>>,
    /// `point`: the node nearest this point (m).
    pub point: Option<[f64; 3]>,
    /// `[[fix]]` only: the components held, `["x", "z"]`; default all three.
    pub components: Option<Vec<String>>,
    /// `[[fix]]` only: hold the displacement along this direction (sliding on the plane
    /// normal to it).
    pub normal: Option<[f64; 3]>,
}

/// `[[load]]`: a force on each node of a selection.
#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct LoadSpec {
    /// Which nodes: a selector table as in `[[fix]]`.
    pub at: RegionSpec,
    /// `force`: the force on each selected node (N).
    pub force: [f64; 3],
    /// The force's time function; default constant.
    pub time: Option<TimeSpec>,
}

/// `time = { kind = "ramp", duration = 0.5 }` and the like: a time function.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimeSpec {
    /// `kind`: `"constant"`, `"ramp"`, `"table"` or `"sine"`.
    pub kind: TimeKind,
    /// ramp: s.
    pub duration: Option<f64>,
    /// table: rows `[t, s]`.
    pub table: Option<Vec<[f64; 2]>>,
    /// sine: default 1.
    pub amplitude: Option<f64>,
    /// sine: Hz.
    pub frequency: Option<f64>,
    /// sine: rad, default 0.
    pub phase: Option<f64>,
}

/// `[[pressure]]` (`value`, Pa) or `[[traction]]` (`traction`, Pa): on a physical group, on
/// the patch within `radius` of `point`, or on the whole boundary.
#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct SurfaceLoadSpec {
    /// `group`: the boundary triangles (tets) or elements (membranes) whose three nodes are
    /// in this physical group.
    pub group: Option<String>,
    /// `point` (m), with `radius`: the triangles whose three nodes are within `radius` of it.
    pub point: Option<[f64; 3]>,
    /// `radius` (m) of the patch around `point`.
    pub radius: Option<f64>,
    /// `boundary = true`: the whole boundary (membranes: every element).
    pub boundary: Option<bool>,
    /// `[[pressure]]`: Pa.
    pub value: Option<f64>,
    /// `[[traction]]`: Pa, per reference area.
    pub traction: Option<[f64; 3]>,
    /// `time`: the time function of `value` or `traction`; default constant.
    pub time: Option<TimeSpec>,
}

/// `[[tool]]`: a rigid tool in penalty contact with the body.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ToolSpec {
    /// `shape`: `"sphere"`, `"plane"` or `"capsule"`.
    pub shape: ToolKind,
    /// `center` (sphere): the centre (m).
    pub center: Option<[f64; 3]>,
    /// `radius` (sphere, capsule): m.
    pub radius: Option<f64>,
    /// `point` (plane): a point of the plane (m).
    pub point: Option<[f64; 3]>,
    /// `normal` (plane): pointing out of the tool; non-zero, made unit.
    pub normal: Option<[f64; 3]>,
    /// `a` (capsule): one end of the axis (m).
    pub a: Option<[f64; 3]>,
    /// `b` (capsule): the other end of the axis (m).
    pub b: Option<[f64; 3]>,
    /// `displacement`: the tool's translation (m), times `time`; or `path` instead.
    pub displacement: Option<[f64; 3]>,
    /// `time`: the time function of `displacement`; default constant.
    pub time: Option<TimeSpec>,
    /// `path`: rows `[t, dx, dy, dz]` (s, m), the translation, piecewise linear.
    pub path: Option<Vec<[f64; 4]>>,
    /// `stiffness`: the penalty stiffness (N/m); default 4 × the material's stability modulus
    /// × the mean edge length of the level it acts on.
    pub stiffness: Option<f64>,
    /// `friction`: one Coulomb coefficient μ ≥ 0, static and kinetic; default frictionless.
    pub friction: Option<f64>,
    /// `static_friction`: μ_s ≥ 0 (instead of `friction`).
    pub static_friction: Option<f64>,
    /// `kinetic_friction`: μ_k, `0 ≤ μ_k ≤ μ_s`; default μ_s. Needs `static_friction`.
    pub kinetic_friction: Option<f64>,
    /// `friction_stiffness`: the tangential stick stiffness k_t (N/m); default the penalty
    /// stiffness.
    pub friction_stiffness: Option<f64>,
}

/// `[[displace]]`: a prescribed displacement of the node nearest `point`, or of a
/// surface patch.
#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct DisplaceSpec {
    /// `point` (m): the node nearest it is prescribed (with `radius`, a surface patch).
    pub point: [f64; 3],
    /// `radius` (m), optional: prescribe the surface nodes within `radius` of the surface
    /// point nearest `point` (at least the nearest node), all moving together.
    pub radius: Option<f64>,
    /// `displacement` (m): the held value, the ramp's end, or the vector that `time`'s s(t)
    /// multiplies.
    pub displacement: Option<[f64; 3]>,
    /// `mode`: `"held"`, `"ramp"` or `"table"`; default `"table"` where `table` is given,
    /// else `"held"`.
    pub mode: Option<MotionMode>,
    /// `duration` (s) of `mode = "ramp"`.
    pub duration: Option<f64>,
    /// `table` (`mode = "table"`): rows `[t, dx, dy, dz]` (s, m), t strictly increasing.
    pub table: Option<Vec<[f64; 4]>>,
    /// `displacement` times this time function (instead of `mode`).
    pub time: Option<TimeSpec>,
    /// A grasp taken at this path time (s), interactive runs only.
    pub start: Option<f64>,
    /// A grasp let go at this path time (s).
    pub release: Option<f64>,
    /// A spring grasp of this total stiffness (N/m).
    pub stiffness: Option<f64>,
    /// A friction grasp's friction coefficient μ (with `stiffness` and `clamp_force`).
    pub friction: Option<f64>,
    /// A friction grasp's clamp force N (N).
    pub clamp_force: Option<f64>,
}

/// `[[pin]]`: a pin taken during an interactive run.
#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct PinSpec {
    /// `point`: the pin takes the surface nearest this point (m), on the deformed surface.
    pub point: [f64; 3],
    /// `radius`: and the surface nodes within this distance of it (m); default 0 (the nearest
    /// node alone).
    pub radius: Option<f64>,
    /// `start`: the path time (s) at which the pin is taken, held where the patch stands;
    /// default 0.
    pub start: Option<f64>,
}

/// `[[cut]]`: a cut made during the run ([`crate::scenario::cuts`]).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CutSpec {
    /// `time` (s): made before the first step (frame) at or after it; default 0.
    pub time: Option<f64>,
    /// `edge`: the blade's edge (m), swept along `sweep`.
    pub edge: Option<[[f64; 3]; 2]>,
    /// `sweep` (m): how the edge moves; the blade is the quad `a, b, b + sweep, a + sweep`.
    pub sweep: Option<[f64; 3]>,
    /// `quad`: the blade's quad itself (m), instead of `edge` and `sweep`.
    pub quad: Option<[[f64; 3]; 4]>,
}

/// `[integrator]`: the time integrator, or the static solve.
#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct IntegratorSpec {
    /// `method`: an explicit integrator, `"implicit-euler"`, `"bdf2"` or `"newton"` (static); default
    /// `"symplectic-euler"`.
    pub method: Option<Solve>,
    /// `solver` (newton): `"auto"` (default), `"multigrid"`, `"direct"` or `"krylov"`.
    pub solver: Option<StaticSolver>,
    /// `dt`: the time step (s); default `safety` × the estimated critical step.
    pub dt: Option<f64>,
    /// `max_newton`: newton, Newton steps at most per increment, at least 1, default 50;
    /// implicit-euler, per time step, default 30.
    pub max_newton: Option<usize>,
    /// `newton_tol` (implicit-euler): each step's relative tolerance, default 1e-6.
    pub newton_tol: Option<f64>,
    /// `increments` (newton): equal load increments, at least 1; default 10 for `"krylov"`,
    /// 1 for `"direct"` and `"multigrid"`.
    pub increments: Option<usize>,
    /// `coarse_start` (newton, multigrid): start from the coarse level's equilibrium,
    /// interpolated; default true for membranes, false for tetrahedra.
    pub coarse_start: Option<bool>,
    /// `smoother` (newton, multigrid): the V-cycle's smoother; default `"block-jacobi"` for
    /// tetrahedra, `"block-gauss-seidel"` for membranes.
    pub smoother: Option<NewtonSmoother>,
    /// `safety`: the fraction of the estimated critical step taken without `dt`; default 0.5.
    pub safety: Option<f64>,
    /// `precision`: the force pass's element data, `"f64"` (default) or `"f32-storage"`.
    pub precision: Option<Precision>,
}

/// `[run]`: when the run stops.
#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct RunSpec {
    /// `stop`: `"duration"` (default) or `"steady"`.
    pub stop: Option<Stop>,
    /// `duration` (s): the simulated time, required with `stop = "duration"`; the cap with
    /// `"steady"`, default 60.
    pub duration: Option<f64>,
    /// `kinetic_tol` (steady): kinetic energy below this × its peak; default 1e-8.
    pub kinetic_tol: Option<f64>,
    /// `residual_tol`: steady, the residual norm below this × its peak, default 1e-4;
    /// `method = "newton"`, the relative residual, default 1e-7.
    pub residual_tol: Option<f64>,
    /// `stagnation` (steady): checks (rows of `measures.csv`) without progress, once the
    /// motions end, before the run gives up; 0 never. Default 1000.
    pub stagnation: Option<u64>,
    /// `blowup_factor`: the factor of the kinetic-energy ceiling that stops a diverging run
    /// ([`crate::integrate::energy_limit`]); default 1e3.
    pub blowup_factor: Option<f64>,
}

/// `[output]`: where and how the results are written.
#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    /// `dir`: the output directory, relative to the scenario file; default `raisov-out/NAME`
    /// relative to the working directory.
    pub dir: Option<String>,
    /// `frame_interval`: simulated time between frames (s); default 0.05, 0 writes only the
    /// first and last.
    pub frame_interval: Option<f64>,
    /// `csv_every`: steps between rows of `measures.csv`, at least 1; default 1.
    pub csv_every: Option<u64>,
    /// `vtu`: frame storage, `"binary"` (default) or `"ascii"`.
    pub vtu: Option<VtuFormat>,
    /// `reference`: T∞ for |T − T∞|, `"none"` (default), `"auto"` or the path (relative to the
    /// scenario file) of an earlier run's `nodal_stress.csv`.
    pub reference: Option<Reference>,
}

/// Parse scenario text. Errors name `path`, the line and the key (`integrator.method`), and
/// for a key with named values the valid ones; a number that is not finite is an error too.
pub fn parse(text: &str, path: &Path) -> Result<ScenarioSpec> {
    let line_of = |offset: usize| text[..offset.min(text.len())].matches('\n').count() + 1;
    let spec: ScenarioSpec = serde_path_to_error::deserialize(toml::Deserializer::new(text))
        .map_err(|e| {
            let key = e.path().to_string();
            let e = e.into_inner();
            let msg = e.message().trim();
            // An unknown field's path ends in the field: name the table it is in.
            let key = if msg.starts_with("unknown field") {
                key.rsplit_once('.').map_or("", |(t, _)| t).to_string()
            } else {
                key
            };
            let msg = match (key.as_str(), msg.strip_prefix(VALUE_ERROR)) {
                ("" | ".", _) => msg.to_string(),
                (k, Some(rest)) => format!("`{k}` = {rest}"),
                (k, None) => format!("`{k}`: {msg}"),
            };
            Error::Scenario {
                path: path.to_path_buf(),
                line: e.span().map(|s| line_of(s.start)),
                msg,
            }
        })?;
    if let Some((key, span)) = non_finite(text) {
        return Err(Error::Scenario {
            path: path.to_path_buf(),
            line: span.map(|s| line_of(s.start)),
            msg: format!("`{key}`: numbers must be finite (not nan or inf)"),
        });
    }
    Ok(spec)
}

/// The key path and span of the first number in `text` that is not finite.
fn non_finite(text: &str) -> Option<(String, Option<std::ops::Range<usize>>)> {
    use toml_edit::{Item, Value};
    fn value(v: &Value, key: String) -> Option<(String, Option<std::ops::Range<usize>>)> {
        match v {
            Value::Float(f) if !f.value().is_finite() => Some((key, f.span())),
            Value::Array(a) => a
                .iter()
                .enumerate()
                .find_map(|(i, v)| value(v, format!("{key}[{i}]"))),
            Value::InlineTable(t) => t.iter().find_map(|(k, v)| value(v, join(&key, k))),
            _ => None,
        }
    }
    fn item(it: &Item, key: String) -> Option<(String, Option<std::ops::Range<usize>>)> {
        match it {
            Item::Value(v) => value(v, key),
            Item::Table(t) => table(t, &key),
            Item::ArrayOfTables(a) => a
                .iter()
                .enumerate()
                .find_map(|(i, t)| table(t, &format!("{key}[{i}]"))),
            Item::None => None,
        }
    }
    fn table(t: &toml_edit::Table, key: &str) -> Option<(String, Option<std::ops::Range<usize>>)> {
        t.iter().find_map(|(k, it)| item(it, join(key, k)))
    }
    fn join(a: &str, b: &str) -> String {
        if a.is_empty() {
            b.to_string()
        } else {
            format!("{a}.{b}")
        }
    }
    let doc = toml_edit::ImDocument::parse(text).ok()?;
    table(doc.as_table(), "")
}
