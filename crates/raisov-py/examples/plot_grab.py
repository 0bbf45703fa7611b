"""Grasp the top of a block of tissue, lift it 8 mm over 20 frames and hold it 10, and plot the
force the tissue exerts on the tool per frame (matplotlib, saved to a PNG).

    pip install ./crates/raisov-py matplotlib
    python crates/raisov-py/examples/plot_grab.py [out.png]
"""

import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import raisov  # noqa: E402

SCENARIO = """
gravity = [0, 0, -9.81]
[mesh]
generate = "box"
size = [0.06, 0.06, 0.04]
divisions = [12, 12, 8]
[material]
law = "neo-hookean"
young = 5e3
poisson = 0.45
[[fix]]
plane = { point = [0, 0, 0], normal = [0, 0, 1] }
[multigrid]
scheme = "fas"
levels = 2
[run]
duration = 1.0
"""


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else "plot_grab.png"
    sim = raisov.Simulation.from_toml(SCENARIO)
    print(f"{sim.num_nodes} nodes; {sim.describe()}")
    g = sim.grab([0.03, 0.03, 0.05], 0.006)
    start = sim.grab_position(g)
    lifts, forces, residuals = [], [], []
    for frame in range(30):
        lift = 0.008 * min(frame + 1, 20) / 20
        sim.move_grab(g, start + [0.0, 0.0, lift])
        report = sim.step_frame(cycles=4)
        if not report.accepted:
            print(f"frame {frame + 1} rejected: {report.rejection}")
        lifts.append(lift * 1e3)
        forces.append(sim.grab_force(g))
        residuals.append(report.residual)
    forces = np.array(forces)
    frames = np.arange(1, len(forces) + 1)
    fig, (ax, ax2) = plt.subplots(2, 1, sharex=True, figsize=(7, 6))
    for k, name in enumerate("xyz"):
        ax.plot(frames, forces[:, k], label=f"$F_{name}$")
    ax.set_ylabel("force on the tool (N)")
    ax.legend()
    ax.grid(True, alpha=0.3)
    ax2.plot(frames, lifts, color="k")
    ax2.set_ylabel("lift (mm)")
    ax2.set_xlabel("frame (4 V-cycles each)")
    ax2.grid(True, alpha=0.3)
    fig.suptitle("raisov: lifting a grasped patch")
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    print(f"final force {forces[-1]} N, residual {residuals[-1]:.2e} N; wrote {out}")


if __name__ == "__main__":
    main()
