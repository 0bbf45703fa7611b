"""Throughput of independent solves: serially in one process, on two Python threads, and as
Ray tasks on 1 and 2 workers, side by side in one run; Ray's overhead per task; the bits of
every way against the serial run's; and what a cluster would give for a 10,000-case study.

Each case is one static solve of the liver (`raisov.solve`, neo-Hookean held on the cap of
its top under gravity, E varied from case to case), one thread per solve. Build the module
in release first (`pip install ./crates/raisov-py` or `maturin develop --release`), with
Ray installed (`pip install "raisov[ray]"`), and run it with nothing else running:

    python crates/raisov-py/examples/bench_ray.py [--cases 32] [--level L3]

Printed: the cases' count, the wall time of each way and its throughput (cases/s), the
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
    args = ap.parse_args()
    import ray

    tmp = tempfile.mkdtemp(prefix="raisov-bench-ray-")
    path = write_scenario(tmp, args.level)
    n = args.cases
    print(f"{n} cases: static solve of the liver {args.level} (raisov.solve, threads=1 each), "
          f"{os.cpu_count()} CPUs")

    case(path, 0)  # warm the page cache and the module
    t = time.perf_counter()
    serial = [case(path, k) for k in range(n)]
    t_serial = time.perf_counter() - t
    per_case = t_serial / n

    t = time.perf_counter()
    with ThreadPoolExecutor(2) as ex:
        threaded = list(ex.map(lambda k: case(path, k), range(n)))
    t_threads = time.perf_counter() - t

    remote_case = ray.remote(num_cpus=1)(case)
    empty = ray.remote(num_cpus=1)(lambda: None)
    ray_times, ray_same, overhead = {}, {}, {}
    for workers in (1, 2):
        ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
        ray.get([empty.remote() for _ in range(2 * workers)])  # start the workers
        t = time.perf_counter()
        ray.get([empty.remote() for _ in range(200)])
        overhead[workers] = (time.perf_counter() - t) / 200 * workers
        t = time.perf_counter()
        out = ray.get([remote_case.remote(path, k) for k in range(n)])
        ray_times[workers] = time.perf_counter() - t
        ray_same[workers] = all(np.array_equal(a, b) for a, b in zip(out, serial))
        ray.shutdown()

    same_threads = all(np.array_equal(a, b) for a, b in zip(threaded, serial))
    rows = [
        ("serial, one process", t_serial, "-", True),
        ("2 Python threads", t_threads, f"{t_serial / t_threads:.2f}x serial", same_threads),
        ("Ray, 1 worker", ray_times[1], "-", ray_same[1]),
        ("Ray, 2 workers", ray_times[2], f"{ray_times[1] / ray_times[2]:.2f}x 1 worker", ray_same[2]),
    ]
    print(f"{'way':<22} {'wall s':>8} {'cases/s':>8}  {'speed-up':<16} same bits as serial")
    for name, w, up, same in rows:
        print(f"{name:<22} {w:8.2f} {n / w:8.2f}  {up:<16} {'yes' if same else 'NO'}")
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
