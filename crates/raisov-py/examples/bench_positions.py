"""Per-frame cost of reading node positions from Python, against the frame itself.

`sim.positions` is a read-only NumPy copy (n x 3 float64) taken at each read. This script
times, on the same simulation, frames alone (`step_frame(cycles=...)`), reads of
`sim.positions` alone, and frames each followed by a read, and prints the read's cost per
frame in microseconds and as a share of the frame. Build the module in release first:

    maturin develop --release -m crates/raisov-py/Cargo.toml
    python crates/raisov-py/examples/bench_positions.py [DIV] [FRAMES]

DIV: cells per side of the 4 cm cube (default 16: 4913 nodes); FRAMES (default 50).
"""

import statistics
import sys
import time

import raisov

DIV = int(sys.argv[1]) if len(sys.argv) > 1 else 16
FRAMES = int(sys.argv[2]) if len(sys.argv) > 2 else 50

SCENE = f"""
gravity = [0, 0, -9.81]
[mesh]
generate = "box"
size = [0.04, 0.04, 0.04]
divisions = [{DIV}, {DIV}, {DIV}]
[material]
law = "neo-hookean"
young = 5e3
poisson = 0.45
[[fix]]
plane = {{ point = [0, 0, 0], normal = [0, 0, 1] }}
[multigrid]
scheme = "fas"
levels = 2
[run]
duration = 1.0
"""


def main():
    sim = raisov.Simulation.from_toml(SCENE)
    g = sim.grab([0.02, 0.02, 0.05], 0.005)
    p = sim.grab_position(g)
    n = sim.num_nodes
    print(f"cube {DIV}^3 cells, {n} nodes, {sim.describe()}")
    for _ in range(3):
        sim.step_frame(cycles=1)
    frame, read, both = [], [], []
    for k in range(FRAMES):
        sim.move_grab(g, p + [0.0, 0.0, 1e-5 * k])
        t0 = time.perf_counter()
        sim.step_frame(cycles=1)
        t1 = time.perf_counter()
        x = sim.positions
        t2 = time.perf_counter()
        assert x.shape == (n, 3)
        frame.append(t1 - t0)
        read.append(t2 - t1)
        both.append(t2 - t0)
    # Reads alone, back to back (no frame in between: the cache is warm).
    alone = []
    for _ in range(FRAMES):
        t0 = time.perf_counter()
        sim.positions
        alone.append(time.perf_counter() - t0)
    med = statistics.median
    print(
        f"frame (1 cycle) {1e3 * med(frame):.3f} ms; positions read after it "
        f"{1e6 * med(read):.1f} us ({100 * med(read) / med(frame):.2f} % of the frame); "
        f"back-to-back reads {1e6 * med(alone):.1f} us; "
        f"{n * 24 / 1e6:.3f} MB copied per read (medians of {FRAMES})"
    )


if __name__ == "__main__":
    main()
