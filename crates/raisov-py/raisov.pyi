"""raisov: nonlinear hyperelastic soft-tissue simulation with multigrid explicit integration,
stepped frame by frame. SI units (m, N, s, Pa).

Every array returned is a read-only float64 (or int64) copy taken when it is read: it keeps its
values after later frames.
"""

from os import PathLike
from typing import Any, Iterable, Optional, Union

import numpy as np
import numpy.typing as npt

__version__: str

Point = Union[Iterable[float], npt.NDArray[np.float64]]

class Grab:
    """A grasp of one Simulation (returned by Simulation.grab)."""

class Pin:
    """A pin of one Simulation (returned by Simulation.pin)."""

class FrameReport:
    """What a frame did."""

    cycles: int
    """Steps of the accepted try (0 when none was accepted)."""
    rejected_cycles: int
    """Steps of the rejected tries, thrown away."""
    retries: int
    """Tries rejected before the accepted one (or all of them)."""
    accepted: bool
    """Whether a try was accepted; False: the state is the one before the frame."""
    target_reached: bool
    """Whether every grasp reached its target."""
    residual: float
    """Largest nodal residual |V - R(u)| over free nodes at the end of the frame (N)."""
    rejection: Optional[str]
    """Why the last rejected try was rejected."""
    wall_s: float
    """Wall time of the frame (s)."""

class Reactions:
    """Forces the tissue exerts on its supports (constrained nodes no grasp holds)."""

    nodes: npt.NDArray[np.int64]
    """Supported nodes, ascending, shape (m,)."""
    forces: npt.NDArray[np.float64]
    """Force on each (N), shape (m, 3)."""
    sum: npt.NDArray[np.float64]
    """Their sum (N), shape (3,)."""

class HapticFrame:
    """One frame a haptic proxy published: the grasp's state after a simulation frame."""

    seq: int
    """Publication number: 1, 2, ... in the order published."""
    held: bool
    """Whether the grasp is held; False after a release (every force zero then)."""
    position: npt.NDArray[np.float64]
    """The grasp position x_f (m), shape (3,)."""
    force: npt.NDArray[np.float64]
    """The force the tissue exerts on the tool f_f (N), shape (3,)."""
    stiffness: npt.NDArray[np.float64]
    """K[i, j] = d f_i / d x_j (N/m), shape (3, 3)."""
    time: float
    """Simulated time of the frame (s)."""
    age: float
    """Seconds since the frame was published (when it was read)."""

class HapticSample:
    """The force at a device position and the frame it came from."""

    frame: HapticFrame
    force: npt.NDArray[np.float64]
    """The force (N), shape (3,); zero when the grasp is not held."""
    distance_clamped: bool
    """The device was farther than max_distance from the frame's grasp position."""
    force_clamped: bool
    """The force was scaled down to max_force."""

class HapticProxy:
    """A haptic proxy of one grasp (Simulation.haptic_proxy). Every simulation frame publishes
    the grasp's position x_f, force f_f and stiffness K; any thread reads it at any rate
    without waiting for the simulation (the GIL is released while it reads) and gets, for the
    device position x:

        d = x - x_f, shortened to max_distance if longer (the linear model's trusted radius)
        f = f_f + K d, scaled down to max_force if larger (the device's limit)

    f is the force the tissue exerts on the tool (what the device renders on the hand)."""

    def force_at(self, x: Point) -> npt.NDArray[np.float64]:
        """The force at device position x (m) from the newest frame (N), shape (3,)."""
    def sample(self, x: Point) -> HapticSample:
        """The newest frame, the force at x from it, and what was clamped."""
    def frame(self) -> HapticFrame:
        """The newest published frame."""
    def set_limits(
        self, max_force: Optional[float] = None, max_distance: Optional[float] = None
    ) -> None:
        """Set either limit or both (each > 0, inf for none); ValueError otherwise."""
    @property
    def held(self) -> bool:
        """Whether the grasp is held (as of the newest frame)."""
    @property
    def age(self) -> float:
        """Seconds since the newest frame was published."""
    @property
    def max_force(self) -> float:
        """The largest force rendered (N; inf: no limit)."""
    @property
    def max_distance(self) -> float:
        """The largest extrapolation distance (m; inf: no limit)."""

class Simulation:
    """A simulation stepped frame by frame.

    Sign conventions: grab_force(g) = sum over the grasped nodes of (V - R(u)), the force the
    tissue exerts on the tool; at equilibrium sum of grab forces + reactions.sum = total_load.
    """

    def __init__(self, path: Union[str, PathLike[str]], **keys: Any) -> None:
        """Load a scenario file (raisov's TOML format). Keyword arguments set scenario keys on
        top of the file, one per top-level key: a dict for a table, merged key by key
        (material={"young": 3e3}, damping={"alpha": 10}), any other value replacing the key
        (gravity=[0, 0, -9.81]). They are merged into the TOML document before it is parsed,
        so errors read as for the same keys in the file. Raises ValueError (bad scenario) with
        the library's message, or the OSError subclass Python raises for the file
        (FileNotFoundError, PermissionError, IsADirectoryError, ...) with errno, strerror and
        filename set."""
    @staticmethod
    def from_toml(
        text: str, base_dir: Union[str, PathLike[str]] = ".", **keys: Any
    ) -> Simulation:
        """Build from scenario text; relative paths in it are taken from base_dir. Keyword
        arguments set scenario keys as for Simulation(path, **keys)."""
    def step_frame(
        self, cycles: Optional[int] = None, ms: Optional[float] = None
    ) -> FrameReport:
        """One frame of `cycles` steps or `ms` milliseconds of wall time (exactly one)."""
    def grab(
        self,
        point: Point,
        radius: float,
        stiffness: Optional[float] = None,
        friction: Optional[float] = None,
        clamp: Optional[float] = None,
    ) -> Grab:
        """Grasp the surface patch within `radius` (m) of the surface point nearest `point`:
        held rigidly (stiffness=None) or pulled by springs of total stiffness `stiffness`
        (N/m, spread over the nodes by mass), which leave the nodes free to lag behind. With
        `friction` (mu) and `clamp` (N) too, a friction grasp: the springs slide where they
        would pull harder than their share of mu x clamp."""
    def grab_dissipation(self, g: Grab) -> float:
        """The work (J) friction grasp g's sliding has dissipated so far (0 otherwise)."""
    def set_grab_stiffness(self, g: Grab, stiffness: float) -> None:
        """Make g a spring grasp of total stiffness `stiffness` (N/m) from now on."""
    def grab_spring_stiffness(self, g: Grab) -> Optional[float]:
        """The total spring stiffness of g (N/m), or None for a hard grasp."""
    def move_grab(self, g: Grab, target: Point) -> None:
        """Move grasp g to target (m) over the next frame."""
    def release(self, g: Grab) -> None: ...
    def grab_position(self, g: Grab) -> npt.NDArray[np.float64]:
        """Where g holds its nodes now (m), shape (3,)."""
    def grab_nodes(self, g: Grab) -> npt.NDArray[np.int64]: ...
    def grab_force(self, g: Grab) -> npt.NDArray[np.float64]:
        """Force the tissue exerts on the tool of g (N), shape (3,): a hard grasp's sum of
        V - R(u) over its nodes, a spring grasp's spring pull k (mean x - x_g - mean offset),
        equal at equilibrium."""
    def grab_stiffness(self, g: Grab) -> npt.NDArray[np.float64]:
        """d grab_force / d grasp position (N/m), shape (3, 3): K[i, j] = dF_i / dx_j."""
    def haptic_proxy(
        self, g: Grab, max_force: float = ..., max_distance: float = ...
    ) -> HapticProxy:
        """A haptic proxy of grasp g for a device thread, its force limited to max_force (N)
        and its extrapolation to max_distance (m) (each > 0; default inf, no limit). Every
        frame then also computes the grasp's stiffness (three linear solves) and publishes
        it with the position and the force; this call publishes the current ones."""
    def pin(self, point: Point, radius: float) -> Pin:
        """Pin the patch grab would take, where it stands."""
    def unpin(self, p: Pin) -> None: ...
    def pin_nodes(self, p: Pin) -> npt.NDArray[np.int64]: ...
    def cut(self, a: Point, b: Point, sweep: Point) -> dict[str, Any]:
        """Cut the body with the blade the edge a-b (m) sweeps along sweep (m): the quad a, b,
        b + sweep, a + sweep, on every level. Returns {"split": [elements split per level],
        "nodes": int, "elements": int, "seconds": float}; a blade that misses changes nothing.
        Node and element counts change: read positions, masses(), surface_triangles again.
        ValueError (nothing changed): a degenerate blade, a membrane, loads that cannot be cut
        (pressure, traction, timed loads, tools)."""
    def cut_quad(self, corners: Iterable[Point]) -> dict[str, Any]:
        """Cut with a planar convex quad blade, corners (4, 3) in order around it (m); as cut."""
    def cuts(self) -> npt.NDArray[np.float64]:
        """The blades cut so far, in order: corners (m), shape (k, 4, 3)."""
    def material_fractions(self) -> npt.NDArray[np.float64]:
        """Level 0's material fraction per element (1 where no cut split it)."""
    def masses(self) -> npt.NDArray[np.float64]:
        """Lumped nodal masses (kg), shape (n,)."""
    def set_max_retries(self, retries: int) -> None: ...
    def describe(self) -> str: ...
    @property
    def num_nodes(self) -> int: ...
    @property
    def time(self) -> float:
        """Simulated time (s)."""
    @property
    def positions(self) -> npt.NDArray[np.float64]:
        """Node positions X + u (m), shape (n, 3): a read-only copy taken now."""
    @property
    def displacements(self) -> npt.NDArray[np.float64]:
        """Displacements u (m), shape (n, 3): a read-only copy taken now."""
    @property
    def rest_positions(self) -> npt.NDArray[np.float64]:
        """Reference positions X (m), shape (n, 3)."""
    @property
    def surface_positions(self) -> npt.NDArray[np.float64]:
        """The surface a renderer draws, now (m), shape (v, 3): the visual surface's vertices
        when the scenario meshed one ([mesh] surface), else the mesh's nodes. A read-only
        copy taken now."""
    @property
    def surface_triangles(self) -> npt.NDArray[np.int64]:
        """The triangles of surface_positions, shape (m, 3): 0-based vertex indices,
        counter-clockwise seen from outside. They change only when the body is cut."""
    @property
    def nodal_stress(self) -> npt.NDArray[np.float64]:
        """Nodal Cauchy stress (Pa), shape (n, 3, 3)."""
    @property
    def residual(self) -> float:
        """Largest nodal residual over free nodes (N)."""
    @property
    def reactions(self) -> Reactions: ...
    @property
    def total_load(self) -> npt.NDArray[np.float64]:
        """Total external load: gravity and nodal loads (N), shape (3,)."""

class Solution:
    """A scenario run to its end by `solve`: how it ended and its final state, in the
    scenario's node order. Forces are those the tissue exerts on each thing: at equilibrium
    reaction + prescribed_reaction + tool_force = total_load (an interactive run's grasps are
    prescribed nodes)."""

    @property
    def kind(self) -> str:
        """"static", "dynamic" or "interactive": what the scenario ran."""
    @property
    def success(self) -> bool:
        """A static solve converged, a run in time reached its duration or steady state, an
        interactive run played all its frames."""
    @property
    def stopped(self) -> str:
        """How it stopped, in words."""
    @property
    def summary(self) -> str:
        """The closing summary `raisov run` prints."""
    @property
    def steps(self) -> int:
        """Newton steps of a static solve; stepper steps otherwise."""
    @property
    def force_evaluations(self) -> float:
        """Force evaluations of the run, in finest-level units."""
    @property
    def wall_s(self) -> float:
        """Wall-clock time of the run (s)."""
    @property
    def time(self) -> float:
        """Simulated time at the end (s)."""
    @property
    def residual(self) -> float:
        """Residual norm ||V - R(u)||_2 over free nodes at the end (N)."""
    @property
    def max_displacement(self) -> float:
        """Largest nodal displacement at the end (m)."""
    @property
    def kinetic_energy(self) -> float:
        """Kinetic energy at the end (J)."""
    @property
    def displacements(self) -> npt.NDArray[np.float64]:
        """Nodal displacements (m, shape (n, 3))."""
    @property
    def rest_positions(self) -> npt.NDArray[np.float64]:
        """Node positions at rest (m, shape (n, 3))."""
    @property
    def positions(self) -> npt.NDArray[np.float64]:
        """Node positions at the end (m, shape (n, 3))."""
    @property
    def surface_triangles(self) -> npt.NDArray[np.int64]:
        """Boundary triangles, three node indices each (shape (m, 3))."""
    @property
    def node_ids(self) -> npt.NDArray[np.int64]:
        """Each node's id in the mesh file (shape (n,))."""
    @property
    def nodal_stress(self) -> npt.NDArray[np.float64]:
        """Nodal Cauchy stress (Pa, shape (n, 3, 3))."""
    @property
    def reaction(self) -> npt.NDArray[np.float64]:
        """The force the tissue exerts on its fixed supports, summed (N, shape (3,))."""
    @property
    def prescribed_reaction(self) -> npt.NDArray[np.float64]:
        """The force the tissue exerts on its prescribed (moved, grasped) nodes (N)."""
    @property
    def tool_force(self) -> npt.NDArray[np.float64]:
        """The force the tissue exerts on the scenario's tools (N)."""
    @property
    def total_load(self) -> npt.NDArray[np.float64]:
        """Loads and body forces applied (N)."""
    @property
    def grasp_forces(self) -> list[Optional[npt.NDArray[np.float64]]]:
        """Per [[displace]] grasp taken during an interactive run, its force at the end (N),
        None for one let go; empty for other runs."""
    @property
    def out_dir(self) -> Optional[str]:
        """The output directory written, or None (nothing written)."""

def solve(
    scenario: Union[str, PathLike[str]],
    *,
    out: Optional[Union[str, PathLike[str]]] = None,
    threads: Optional[int] = None,
    **keys: Any,
) -> Solution:
    """Run a scenario file to its end, as `raisov run` does (a static solve, a run in time,
    or an interactive run's frames), and return its Solution. Keyword arguments set scenario
    keys (a dict per table). Nothing is written unless `out` names a directory. `threads`:
    this solve's threads (default: the process's pool); the bits are the same for any
    number. Releases the GIL while it computes; Ctrl-C stops a run in time at its next step.
    A run that does not do what it was asked returns with success False and a
    RuntimeWarning; a divergence raises RuntimeError, a bad scenario ValueError, a file's
    error the OSError Python raises for it."""
