"""Throughput of independent solves: serially in one process, on two Python threads, and as
Ray tasks on 1 and 2 workers, side by side in one run; Ray's overhead per task; the bits of
every way against the serial run's; and what a cluster would give for a 10,000-case study.

Each case is one static solve of the liver (`raisov.solve`, neo-Hookean held on the cap of
its top under gravity, E varied from case to case), one thread per solve. Build the module
in release first (`pip install ./crates/raisov-py` or `maturin develop --release`), with
Ray installed (`pip install "raisov[ray]"`), and run it with nothing else running:

    python crates/raisov-py/examples/bench_ray.py [--cases 32] [--level L3]

Each way runs `--repeat` times (default 3), the ways taking turns, and the medians are
compared. Printed: the cases' count, the wall time of each way (median and range) and its throughput (cases/s), the
speed-up of 2 workers over 1 (threads: 2 over serial), the mean solve time, Ray's overhead
per task (an empty task's round trip, and Ray's time per case less the serial solve time),
whether each way gave the serial run's bits, and the estimate of a 10,000-case study of the
liver L1 on 100 machines from the measured L1 solve time and the overhead.
"""

import argparse
import os
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

import raisov

SCENARIO = """
name = "liver-bench"
gravity = [0.0, 0.0, -9.81]
[mesh]
file = "{mesh}"
scale = 0.001
[material]
law = "neo-hookean"
young = 5000.0
poisson = 0.45
density = 1060.0
[[fix]]
plane = {{ point = [0.0, 0.0, 0.195], normal = [0.0, 0.0, -1.0] }}
[integrator]
method = "newton"
solver = "direct"
[run]
residual_tol = 1e-8
"""


def data_dir():
    for p in Path(__file__).resolve().parents:
        if (p / "data" / "liver_L3.msh").is_file():
            return p / "data"
    raise SystemExit("bench_ray.py: cannot find data/liver_L3.msh; run it from a clone")


def write_scenario(folder, level):
    p = Path(folder) / f"liver_{level}.toml"
    p.write_text(SCENARIO.format(mesh=(data_dir() / f"liver_{level}.msh").as_posix()))
    return str(p)


def young(k):
    return 3000.0 + 100.0 * k


def case(path, k):
    s = raisov.solve(path, threads=1, material={"young": young(k)})
    assert s.success, s.stopped
    return np.asarray(s.displacements)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", type=int, default=32)
    ap.add_argument("--level", default="L3", choices=["L0", "L1", "L2", "L3"])
    ap.add_argument("--study-cases", type=int, default=10000)
    ap.add_argument("--machines", type=int, default=100)
    ap.add_argument("--repeat", type=int, default=3, help="runs of each way (medians)")
    args = ap.parse_args()
    import ray

    tmp = tempfile.mkdtemp(prefix="raisov-bench-ray-")
    path = write_scenario(tmp, args.level)
    n = args.cases
    print(f"{n} cases: static solve of the liver {args.level} (raisov.solve, threads=1 each), "
          f"{os.cpu_count()} CPUs")

    case(path, 0)  # warm the page cache and the module
    remote_case = ray.remote(num_cpus=1)(case)
    empty = ray.remote(num_cpus=1)(lambda: None)
    walls = {"serial": [], "threads": [], 1: [], 2: []}
    same = {"threads": True, 1: True, 2: True}
    overhead = {1: [], 2: []}
    serial = None
    # Each way `repeat` times, the ways taking turns: a neighbour's load on the machine
    # falls on all of them alike; the medians are compared.
    for _ in range(args.repeat):
        t = time.perf_counter()
        got = [case(path, k) for k in range(n)]
        walls["serial"].append(time.perf_counter() - t)
        serial = serial if serial is not None else got

        t = time.perf_counter()
        with ThreadPoolExecutor(2) as ex:
            threaded = list(ex.map(lambda k: case(path, k), range(n)))
        walls["threads"].append(time.perf_counter() - t)
        same["threads"] &= all(np.array_equal(a, b) for a, b in zip(threaded, serial))

        for workers in (1, 2):
            ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
            ray.get([empty.remote() for _ in range(2 * workers)])  # start the workers
            t = time.perf_counter()
            ray.get([empty.remote() for _ in range(200)])
            overhead[workers].append((time.perf_counter() - t) / 200 * workers)
            t = time.perf_counter()
            out = ray.get([remote_case.remote(path, k) for k in range(n)])
            walls[workers].append(time.perf_counter() - t)
            same[workers] &= all(np.array_equal(a, b) for a, b in zip(out, serial))
            ray.shutdown()

    med = {k: float(np.median(v)) for k, v in walls.items()}
    t_serial, t_threads, ray_times = med["serial"], med["threads"], {1: med[1], 2: med[2]}
    per_case = t_serial / n
    overhead = {k: float(np.median(v)) for k, v in overhead.items()}
    ray_same = {1: same[1], 2: same[2]}
    spread = {k: f"{min(v):.2f}-{max(v):.2f}" for k, v in walls.items()}
    same_threads = same["threads"]
    rows = [
        ("serial, one process", t_serial, "-", True),
        ("2 Python threads", t_threads, f"{t_serial / t_threads:.2f}x serial", same_threads),
        ("Ray, 1 worker", ray_times[1], "-", ray_same[1]),
        ("Ray, 2 workers", ray_times[2], f"{ray_times[1] / ray_times[2]:.2f}x 1 worker", ray_same[2]),
    ]
    keys = ["serial", "threads", 1, 2]
    print(f"medians of {args.repeat} runs each (the ways taking turns)")
    print(f"{'way':<22} {'wall s':>8} {'range':>11} {'cases/s':>8}  {'speed-up':<16} same bits as serial")
    for key, (name, w, up, ok) in zip(keys, rows):
        print(f"{name:<22} {w:8.2f} {spread[key]:>11} {n / w:8.2f}  {up:<16} {'yes' if ok else 'NO'}")
    print(f"mean solve time {per_case * 1e3:.1f} ms; Ray overhead per task: empty task "
          f"{overhead[1] * 1e3:.2f} ms (1 worker), {overhead[2] * 1e3:.2f} ms (2 workers); "
          f"Ray per case less the solve {1e3 * (ray_times[1] / n - per_case):+.2f} ms "
          f"({100 * (ray_times[1] / n - per_case) / per_case:+.1f} % of the solve)")

    # The study on paper: the liver L1 solve measured here, one case per core.
    l1 = write_scenario(tmp, "L1")
    t = time.perf_counter()
    case(l1, 0)
    t_l1 = time.perf_counter() - t
    o = max(overhead[1], 0.0)
    speedup = ray_times[1] / ray_times[2]
    for cores in (2, 16):
        slots = args.machines * cores
        waves = -(-args.study_cases // slots)
        wall = waves * (t_l1 + o)
        print(f"on paper: {args.study_cases} liver L1 solves ({t_l1:.2f} s each here) on "
              f"{args.machines} machines of {cores} cores: {waves} waves, about "
              f"{wall / 60:.1f} min (one machine like this, at the 2-worker throughput "
              f"measured above: {args.study_cases * (t_l1 + o) / speedup / 3600:.1f} h)")


if __name__ == "__main__":
    main()
