"""Calibrate the liver's Young's modulus E and Poisson ratio nu on Ray.

A "measured" displacement of points on the liver's surface is made with hidden parameters
(E = 4.2 kPa, nu = 0.43) plus noise; the study then recovers them:

1. a design of experiments: a Latin hypercube of parameter sets over E in [2, 10] kPa (log
   scale) and nu in [0.30, 0.49], each a static solve run as a Ray task;
2. an optimiser (SciPy's least_squares, trust region reflective) started from the design's
   best set, minimising the misfit sum_i |u_i(E, nu) - u_i^measured|^2 / sigma^2; each
   residual and each column of its finite-difference Jacobian is a Ray task, the columns
   solved side by side.

It prints the recovered parameters and their error against the hidden ones.

Every case is `raisov.solve(scenario, threads=1, material={...})`: one static solve of the
liver (neo-Hookean, held on the cap of its top, under gravity), no files written, the GIL
released. A task asks Ray for one CPU and runs one thread, so Ray runs as many cases at once
as it has CPUs. Tasks are retried when their worker dies (`max_retries`).

    python calibrate_ray.py                        # a local Ray instance, liver L2
    python calibrate_ray.py --quick                # L3, 16 design points: a minute or so
    python calibrate_ray.py --address auto         # the Ray cluster this machine belongs to
    python calibrate_ray.py --address ray://head:10001 --cases 256

On a cluster the scenario and its mesh travel to the workers with the job (Ray's
`runtime_env` working directory), and each worker needs `pip install raisov`; nothing else
changes. Needs `pip install "raisov[ray]"` (Ray, SciPy).
"""

import argparse
import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HIDDEN = {"young": 4200.0, "poisson": 0.43}
E_RANGE = (2000.0, 10000.0)
NU_RANGE = (0.30, 0.49)

SCENARIO = """
name = "liver-calibration"
gravity = [0.0, 0.0, -9.81]
[mesh]
file = "{mesh}"
scale = 0.001              # mm -> m
[material]
law = "neo-hookean"
young = 5000.0             # set per case
poisson = 0.45             # set per case
density = 1060.0
[[fix]]                    # the cap of the top (z >= 195 mm)
plane = {{ point = [0.0, 0.0, 0.195], normal = [0.0, 0.0, -1.0] }}
[integrator]
method = "newton"
solver = "direct"
[run]
residual_tol = 1e-8
"""


def find_data():
    """The repository's data/ folder (the liver levels)."""
    here = Path(__file__).resolve()
    for p in here.parents:
        if (p / "data" / "liver_L3.msh").is_file():
            return p / "data"
    sys.exit("calibrate_ray.py: cannot find data/liver_L3.msh above this file; run it from a clone")


def make_job_dir(level):
    """A folder with the scenario and its mesh: Ray ships it to every worker."""
    job = Path(tempfile.mkdtemp(prefix="raisov-calibration-"))
    mesh = f"liver_{level}.msh"
    shutil.copy(find_data() / mesh, job / mesh)
    (job / "liver.toml").write_text(SCENARIO.format(mesh=mesh))
    return job


def solve_case(params):
    """One static solve in the task's working directory: the surface displacements."""
    import raisov

    young, poisson = float(params[0]), float(params[1])
    s = raisov.solve("liver.toml", threads=1, material={"young": young, "poisson": poisson})
    if not s.success:
        raise RuntimeError(f"E = {young} Pa, nu = {poisson}: {s.stopped}")
    return np.asarray(s.displacements)


def measurement_points(solution, count, seed):
    """`count` surface nodes away from the held cap, chosen once by a seeded draw."""
    surface = np.unique(solution.surface_triangles)
    x = solution.rest_positions[surface]
    below = surface[x[:, 2] < 0.17]
    rng = np.random.default_rng(seed)
    return np.sort(rng.choice(below, size=count, replace=False))


def to_params(theta):
    """theta = (log E, nu) -> (E, nu)."""
    return np.array([np.exp(theta[0]), theta[1]])


def run(args):
    import ray
    from scipy.optimize import least_squares
    from scipy.stats import qmc

    level = "L3" if args.quick else args.level
    cases = args.cases or (16 if args.quick else 64)
    job = make_job_dir(level)
    t0 = time.perf_counter()
    ray.init(
        address=args.address,
        num_cpus=args.workers if args.address is None else None,
        runtime_env={"working_dir": str(job)},
        include_dashboard=False,
        log_to_driver=False,
    )
    t_init = time.perf_counter() - t0
    task = ray.remote(num_cpus=1, max_retries=3)(solve_case)

    # The measurement: the hidden parameters' displacements at the points, plus noise of
    # `noise` times the largest measured displacement.
    import raisov

    truth = raisov.solve(job / "liver.toml", material=HIDDEN)
    points = measurement_points(truth, args.points, args.seed)
    exact = np.asarray(truth.displacements)[points]
    sigma = args.noise * np.abs(exact).max()
    rng = np.random.default_rng(args.seed + 1)
    measured = exact + sigma * rng.standard_normal(exact.shape)

    def residual(u):
        return ((u[points] - measured) / sigma).ravel()

    # 1. The design of experiments, every case a task.
    t1 = time.perf_counter()
    lhs = qmc.LatinHypercube(d=2, seed=args.seed).random(cases)
    lo = np.array([np.log(E_RANGE[0]), NU_RANGE[0]])
    hi = np.array([np.log(E_RANGE[1]), NU_RANGE[1]])
    thetas = lo + lhs * (hi - lo)
    fields = ray.get([task.remote(to_params(t)) for t in thetas])
    misfits = np.array([np.sum(residual(u) ** 2) for u in fields])
    best = int(np.argmin(misfits))
    t_doe = time.perf_counter() - t1

    # 2. The optimiser; the residual and the Jacobian's columns are tasks.
    cache = {}
    evaluations = [0]

    def fields_at(thetas_):
        todo = [t for t in thetas_ if tuple(t) not in cache]
        refs = [task.remote(to_params(t)) for t in todo]
        evaluations[0] += len(refs)
        for t, u in zip(todo, ray.get(refs)):
            cache[tuple(t)] = u
        return [cache[tuple(t)] for t in thetas_]

    steps = np.array([1e-3, 1e-4])

    def fun(theta):
        return residual(fields_at([np.asarray(theta)])[0])

    def jac(theta):
        theta = np.asarray(theta)
        probes = [theta + steps[k] * np.eye(2)[k] for k in range(2)]
        base, *moved = fields_at([theta] + probes)
        r0 = residual(base)
        return np.column_stack([(residual(m) - r0) / steps[k] for k, m in enumerate(moved)])

    t2 = time.perf_counter()
    fit = least_squares(fun, thetas[best], jac=jac, bounds=(lo, hi), x_scale=[1.0, 0.05])
    t_opt = time.perf_counter() - t2
    young, poisson = to_params(fit.x)
    err_e = (young - HIDDEN["young"]) / HIDDEN["young"]
    err_nu = poisson - HIDDEN["poisson"]
    resources = ray.cluster_resources()
    ray.shutdown()
    shutil.rmtree(job, ignore_errors=True)

    report = {
        "level": level,
        "cpus": resources.get("CPU"),
        "points": int(len(points)),
        "noise_m": float(sigma),
        "design_cases": cases,
        "design_best": {"young": float(np.exp(thetas[best][0])), "poisson": float(thetas[best][1])},
        "optimiser_solves": evaluations[0],
        "optimiser_status": fit.message,
        "young": float(young),
        "poisson": float(poisson),
        "young_error_rel": float(err_e),
        "poisson_error_abs": float(err_nu),
        "chi2_per_dof": float(2 * fit.cost / (exact.size - 2)),
        "wall_ray_init_s": t_init,
        "wall_design_s": t_doe,
        "wall_optimiser_s": t_opt,
    }
    return report


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--address", default=None, help="Ray address (default: a local instance)")
    ap.add_argument("--workers", type=int, default=None, help="CPUs of the local instance")
    ap.add_argument("--level", default="L2", choices=["L0", "L1", "L2", "L3"])
    ap.add_argument("--cases", type=int, default=None, help="design points (default 64; 16 quick)")
    ap.add_argument("--points", type=int, default=40, help="measured surface points")
    ap.add_argument("--noise", type=float, default=0.005, help="noise / largest displacement")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--quick", action="store_true", help="liver L3, 16 design points")
    ap.add_argument("--json", action="store_true", help="print the report as JSON")
    args = ap.parse_args(argv)
    r = run(args)
    if args.json:
        print(json.dumps(r, indent=2))
    else:
        print(f"liver {r['level']} on {r['cpus']:.0f} CPUs, {r['points']} points, noise {r['noise_m']:.2e} m")
        print(f"design of experiments: {r['design_cases']} solves in {r['wall_design_s']:.1f} s; "
              f"best E = {r['design_best']['young']:.0f} Pa, nu = {r['design_best']['poisson']:.3f}")
        print(f"optimiser: {r['optimiser_solves']} solves in {r['wall_optimiser_s']:.1f} s ({r['optimiser_status']})")
        print(f"hidden     E = {HIDDEN['young']:.0f} Pa, nu = {HIDDEN['poisson']:.3f}")
        print(f"recovered  E = {r['young']:.0f} Pa ({100 * r['young_error_rel']:+.2f} %), "
              f"nu = {r['poisson']:.4f} ({r['poisson_error_abs']:+.4f}); chi2/dof {r['chi2_per_dof']:.2f}")
    return r


if __name__ == "__main__":
    main()
