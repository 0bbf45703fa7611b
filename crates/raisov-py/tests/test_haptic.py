"""The haptic proxy from Python: its force extrapolates the frame's to the device position
as the next equilibrium has it, it clamps to the device's limits, and another Python thread
reads it while frames step, never waiting for them."""

import threading
import time

import numpy as np
import pytest

import raisov
from test_sim import converge, static_cube


# Newton's relative tolerance per visit stalls near 5e-9 N here; 2e-8 N is 1e-5 of the force
# changes compared below.
TOL = 2e-8


def lifted_cube():
    sim = static_cube()
    g = sim.grab([0.02, 0.02, 0.06], 0.011)
    sim.move_grab(g, sim.grab_position(g) + [0.0, 0.0, 0.004])
    converge(sim, TOL)
    return sim, g


def test_haptic_force_at_a_displaced_device_matches_the_next_equilibrium():
    sim, g = lifted_cube()
    proxy = sim.haptic_proxy(g)
    f0 = proxy.frame()
    assert f0.held and f0.seq >= 1
    np.testing.assert_array_equal(f0.position, sim.grab_position(g))
    np.testing.assert_array_equal(f0.force, sim.grab_force(g))
    assert f0.stiffness.shape == (3, 3)
    # Move the device 0.2 mm along each axis; the simulation follows to equilibrium. The
    # frame's first-order prediction f0 + K d captures the change to 1 % (the rest is
    # O(|d|^2)); the proxy then holds the new frame.
    for axis in range(3):
        d = np.zeros(3)
        d[axis] = 2e-4
        x = f0.position + d
        predicted = f0.force + f0.stiffness @ d
        sim.move_grab(g, x)
        converge(sim, TOL)
        actual = sim.grab_force(g)
        change = np.linalg.norm(actual - f0.force)
        assert change > 1e-3, change
        assert np.linalg.norm(actual - predicted) < 0.01 * change, (actual, predicted)
        np.testing.assert_array_equal(proxy.force_at(x), actual)
        sim.move_grab(g, f0.position)
        converge(sim, TOL)


def test_haptic_force_is_clamped_to_the_device_limit_and_the_trusted_radius():
    sim, g = lifted_cube()
    proxy = sim.haptic_proxy(g, max_force=10.0, max_distance=0.001)
    assert (proxy.max_force, proxy.max_distance) == (10.0, 0.001)
    f = proxy.frame()
    # 5 mm above the frame's grasp position: extrapolated from 1 mm only.
    s = proxy.sample(f.position + [0.0, 0.0, 0.005])
    assert s.distance_clamped and not s.force_clamped
    np.testing.assert_allclose(s.force, f.force + f.stiffness @ [0.0, 0.0, 0.001], rtol=1e-12)
    # A device limit below the force: the same direction, scaled down to the limit.
    limit = 0.5 * np.linalg.norm(s.force)
    proxy.set_limits(max_force=limit)
    assert proxy.max_distance == 0.001
    c = proxy.sample(f.position + [0.0, 0.0, 0.005])
    assert c.force_clamped and c.distance_clamped
    assert np.linalg.norm(c.force) == pytest.approx(limit, rel=1e-12)
    np.testing.assert_allclose(c.force / limit, s.force / np.linalg.norm(s.force), rtol=1e-12)
    for bad in [dict(max_force=0.0), dict(max_distance=-1.0), dict(max_force=float("nan"))]:
        with pytest.raises(ValueError, match="must be > 0"):
            proxy.set_limits(**bad)
    assert proxy.max_force == limit
    with pytest.raises(ValueError, match="max_force"):
        sim.haptic_proxy(g, max_force=-1.0)
    with pytest.raises(ValueError, match="3 coordinates"):
        proxy.force_at([0.0, 0.0])
    # Released: not held, no force.
    sim.release(g)
    assert not proxy.held
    np.testing.assert_array_equal(proxy.force_at(f.position), [0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="no grasp"):
        sim.haptic_proxy(g)


def test_a_device_thread_is_not_blocked_by_a_long_frame():
    sim, g = lifted_cube()
    proxy = sim.haptic_proxy(g, max_force=5.0)
    x = proxy.frame().position + [0.0, 0.0, 0.0005]
    stop = threading.Event()
    reads = []  # (time, seq) of every read
    errors = []  # what failed on the device thread (pytest sees only the main thread's)

    def read():
        s = proxy.sample(x)
        assert s.frame.held and np.all(np.isfinite(s.force))
        assert np.linalg.norm(s.force) <= 5.0 * (1 + 1e-12)
        reads.append((time.perf_counter(), s.frame.seq))

    def device():
        try:
            while not stop.is_set():
                read()
                time.sleep(0.0005)
            read()  # one more after the frames
        except BaseException as e:  # noqa: BLE001 - reported below
            errors.append(e)

    t = threading.Thread(target=device)
    t.start()
    try:
        # A 300 ms frame (the simulation's lock held throughout, the GIL released): the
        # device keeps reading during it.
        sim.move_grab(g, proxy.frame().position + [0.0, 0.0, 0.0002])
        start = time.perf_counter()
        rep = sim.step_frame(ms=300.0)
        end = time.perf_counter()
        assert rep.accepted
        for _ in range(3):
            sim.step_frame(cycles=1)
    finally:
        stop.set()
        t.join()
    if errors:
        raise errors[0]
    during = [seq for when, seq in reads if start < when < end]
    assert len(during) >= 20, f"{len(during)} reads during a {1e3 * (end - start):.0f} ms frame"
    seqs = [seq for _, seq in reads]
    assert seqs == sorted(seqs), seqs
    assert seqs[-1] == proxy.frame().seq > seqs[0], (seqs[0], seqs[-1])
    np.testing.assert_array_equal(proxy.frame().force, sim.grab_force(g))
