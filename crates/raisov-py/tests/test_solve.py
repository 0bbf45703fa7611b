"""`raisov.solve`: a scenario run to its end in one call. The static solve against the frame
loop's own equilibrium, the forces balancing the load, keys set from Python, nothing written
unless asked, the same bits on any number of threads, the GIL released while it computes,
errors and unfinished runs reported."""

import os
import threading
import time
import warnings

import numpy as np
import pytest

import raisov

# A 4 cm cube (4 cells per side, 125 nodes) fixed at its base under gravity.
CUBE = """
name = "cube"
gravity = [0, 0, -9.81]
[mesh]
generate = "box"
size = [0.04, 0.04, 0.04]
divisions = [4, 4, 4]
[material]
law = "neo-hookean"
young = 5e3
poisson = 0.45
[[fix]]
plane = { point = [0, 0, 0], normal = [0, 0, 1] }
"""

STATIC = CUBE + '[integrator]\nmethod = "newton"\n[run]\nresidual_tol = 1e-11\n'
DYNAMIC = CUBE + "[damping]\nalpha = 100.0\n[run]\nduration = 0.05\n"


def scenario(tmp_path, text, name="cube.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_static_solve_is_the_equilibrium_the_frame_loop_reaches(tmp_path):
    path = scenario(tmp_path, STATIC)
    s = raisov.solve(path)
    assert s.kind == "static" and s.success, s.summary
    assert s.stopped == "converged"
    n = 125
    assert s.displacements.shape == (n, 3)
    assert s.nodal_stress.shape == (n, 3, 3)
    assert s.rest_positions.shape == (n, 3)
    np.testing.assert_array_equal(s.positions, s.rest_positions + s.displacements)
    assert not s.displacements.flags.writeable
    # The same problem solved by the Simulation's frame loop (FAS with a Newton coarse solve
    # on one level): the same equilibrium, to the two solvers' tolerances.
    sim = raisov.Simulation.from_toml(
        CUBE + '[multigrid]\nscheme = "fas"\nlevels = 1\ncoarse = "newton"\n[run]\nduration = 1.0\n'
    )
    for _ in range(30):
        if sim.step_frame(cycles=1).residual < 1e-11:
            break
    scale = np.abs(s.displacements).max()
    assert scale > 1e-4, "the cube sags"
    np.testing.assert_allclose(s.displacements, sim.displacements, rtol=0, atol=1e-8 * scale)
    np.testing.assert_allclose(s.nodal_stress, sim.nodal_stress, rtol=0, atol=1e-6 * np.abs(s.nodal_stress).max())
    # The base carries the weight: the force on the supports is the load.
    load = s.total_load
    assert load[2] < 0 and abs(load[0]) < 1e-12 and abs(load[1]) < 1e-12
    np.testing.assert_allclose(s.reaction, load, rtol=0, atol=1e-9 * abs(load[2]))
    np.testing.assert_allclose(s.reaction, sim.reactions.sum, rtol=0, atol=1e-7 * abs(load[2]))
    assert s.residual <= 1e-9 * abs(load[2])
    assert s.steps >= 2 and s.force_evaluations >= s.steps and s.wall_s > 0
    assert s.grasp_forces == []
    # Nothing was written: the folder holds the scenario only, and the run says so.
    assert sorted(os.listdir(tmp_path)) == ["cube.toml"]
    assert s.out_dir is None
    assert "none (kept in memory)" in s.summary
    np.testing.assert_array_equal(s.node_ids, np.arange(n))


def test_keys_set_scenario_values_from_python(tmp_path):
    path = scenario(tmp_path, STATIC)
    soft = raisov.solve(path)
    stiff = raisov.solve(path, material={"young": 1e4})
    # The sag scales about as 1/E (the nonlinearity stiffens the softer cube a little).
    ratio = soft.max_displacement / stiff.max_displacement
    assert 1.9 < ratio < 2.0, ratio
    # Exactly so with the load: the stresses scale with E at fixed nu, so twice the modulus
    # under twice the gravity is the same deformation.
    both = raisov.solve(path, material={"young": 1e4}, gravity=[0, 0, -2 * 9.81])
    scale = np.abs(soft.displacements).max()
    np.testing.assert_allclose(both.displacements, soft.displacements, rtol=0, atol=1e-9 * scale)
    up = raisov.solve(path, gravity=[0, 0, 9.81])
    np.testing.assert_allclose(up.total_load, -soft.total_load, rtol=1e-12)
    assert up.displacements[:, 2].max() > 0 > soft.displacements[:, 2].min()


def test_out_writes_what_raisov_run_writes(tmp_path):
    path = scenario(tmp_path, DYNAMIC)
    out = tmp_path / "results"
    s = raisov.solve(path, out=out)
    assert s.kind == "dynamic" and s.success, s.summary
    assert s.out_dir == str(out) or os.fspath(s.out_dir) == os.fspath(out)
    for f in ["measures.csv", "nodal_stress.csv", "summary.txt", "cube.pvd"]:
        assert (out / f).is_file(), f
    # The nodal stress file holds the solution's displacements (file order = node order).
    rows = np.loadtxt(out / "nodal_stress.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(rows[:, 4:7], s.displacements, rtol=1e-8, atol=1e-15)
    # In memory, the same run ends in the same bits.
    again = raisov.solve(path)
    np.testing.assert_array_equal(again.displacements, s.displacements)


def test_the_same_bits_on_any_number_of_threads(tmp_path):
    path = scenario(tmp_path, DYNAMIC)
    one = raisov.solve(path, threads=1)
    two = raisov.solve(path, threads=2)
    np.testing.assert_array_equal(one.displacements, two.displacements)
    np.testing.assert_array_equal(one.nodal_stress, two.nodal_stress)
    assert one.kinetic_energy == two.kinetic_energy


def test_the_gil_is_released_while_it_computes(tmp_path):
    # A Python thread counts while the main thread solves: with the GIL held for the whole
    # solve it could not count at all in between.
    fine = CUBE.replace("divisions = [4, 4, 4]", "divisions = [10, 10, 10]")
    path = scenario(tmp_path, fine + "[damping]\nalpha = 100.0\n[run]\nduration = 0.3\n")
    count, running = [0], [True]

    def counter():
        while running[0]:
            count[0] += 1

    t = threading.Thread(target=counter)
    t.start()
    try:
        time.sleep(0.05)
        before = count[0]
        s = raisov.solve(path, threads=1)
        during = count[0] - before
    finally:
        running[0] = False
        t.join()
    assert s.success, s.summary
    assert during > 100, f"the counter advanced {during} times during a {s.wall_s:.2f} s solve"


def test_two_threads_solve_side_by_side_with_the_same_results(tmp_path):
    path = scenario(tmp_path, DYNAMIC)
    alone = raisov.solve(path, threads=1)
    results = [None, None]

    def run(k):
        results[k] = raisov.solve(path, threads=1, material={"young": 5e3 * (1 + k)})

    ts = [threading.Thread(target=run, args=(k,)) for k in range(2)]
    for t in ts:
        t.start()
    for t in ts:
        t.join()
    np.testing.assert_array_equal(results[0].displacements, alone.displacements)
    assert results[1].max_displacement < 0.75 * results[0].max_displacement


def test_an_interactive_run_hands_back_its_grasp_force(tmp_path):
    text = CUBE + (
        "[damping]\nalpha = 300.0\n[run]\nduration = 0.5\n"
        '[interactive]\nfps = 10.0\ncycles = 400\nreference = "none"\n'
        "[[displace]]\npoint = [0.02, 0.02, 0.04]\nradius = 0.01\nstart = 0.0\n"
        "table = [[0.0, 0, 0, 0], [0.2, 0, 0, 0.003], [0.5, 0, 0, 0.003]]\n"
    )
    s = raisov.solve(scenario(tmp_path, text))
    assert s.kind == "interactive" and s.success, s.summary
    (g,) = s.grasp_forces
    assert g[2] < 0, "the stretched tissue pulls the grasp down"
    # The grasp holds the prescribed nodes: its force is theirs, and with the base's it
    # balances the load.
    np.testing.assert_allclose(g, s.prescribed_reaction, rtol=1e-9)
    np.testing.assert_allclose(s.reaction + g, s.total_load, rtol=0, atol=1e-3 * abs(g[2]))


def test_a_run_that_does_not_finish_its_job_warns_and_says_so(tmp_path):
    # Steady state asked for, with a cap far too short to reach it.
    text = CUBE + '[run]\nstop = "steady"\nduration = 0.002\n'
    with pytest.warns(RuntimeWarning, match="did not reach steady state"):
        s = raisov.solve(scenario(tmp_path, text))
    assert not s.success
    assert "did not reach steady state" in s.stopped
    assert s.displacements.shape == (125, 3), "what it computed is kept"


def test_errors_raise_with_the_library_message(tmp_path):
    with pytest.raises(FileNotFoundError) as e:
        raisov.solve(tmp_path / "missing.toml")
    assert e.value.filename.endswith("missing.toml")
    path = scenario(tmp_path, STATIC)
    with pytest.raises(ValueError, match="material.young"):
        raisov.solve(path, material={"young": -1.0})
    with pytest.raises(ValueError, match="threads = 0"):
        raisov.solve(path, threads=0)
    with pytest.raises(ValueError, match="unknown"):
        raisov.solve(path, materials={"young": 1.0})
    # A diverging run raises RuntimeError naming where it diverged.
    boom = CUBE.replace("young = 5e3", "young = 5e3\ndensity = 1e-6") + "[run]\nduration = 0.01\n"
    with pytest.raises(RuntimeError, match="diverged|unstable|inverted"):
        raisov.solve(scenario(tmp_path, boom, "boom.toml"), integrator={"dt": 1e-3})
