#!/usr/bin/env python3
"""Peers of `raisov bench`: the standard explicit-dynamics work in NVIDIA Warp (CPU, f64, one
thread) and Taichi (CPU, f64, two threads), on the mesh files raisov writes.

Standard work: box 0.1 x 0.04 x 0.04 m of linear tets, nodes at x = min fixed, compressible
neo-Hookean psi = mu/2 (tr C - 3) - mu ln J + lambda/2 (ln J)^2, E = 5e4 Pa, nu = 0.4,
rho = 1000, gravity (0, -9.81, 0), no damping, lumped mass, symplectic Euler,
dt = 0.2 h_min / c, c = sqrt((lambda + 2 mu) / rho).

Each peer: one kernel per step computing element forces (F = I + Du Dm^-1,
P = mu (F - F^-T) + lambda ln J F^-T, H = -V0 P Dm^-T) scattered with atomic adds, then a node
kernel v += dt (f / m + g), u += dt v, f = 0 (fixed nodes stay at zero).
"""
import argparse
import csv
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

E, NU, RHO = 5e4, 0.4, 1000.0
MU = E / (2 * (1 + NU))
LAM = E * NU / ((1 + NU) * (1 - 2 * NU))
G = np.array([0.0, -9.81, 0.0])


def label(n):
    if n >= 1_000_000 and n % 1_000_000 == 0:
        return f"{n // 1_000_000}M"
    if n >= 1000 and n % 1000 == 0:
        return f"{n // 1000}k"
    return str(n)


def parse_sizes(s):
    out = []
    for t in s.split(","):
        t = t.strip()
        m = 1
        if t[-1] in "kK":
            m, t = 1000, t[:-1]
        elif t[-1] in "mM":
            m, t = 1_000_000, t[:-1]
        out.append(int(round(float(t) * m)))
    return out


def read_msh22(path):
    """Nodes (n x 3) and tets (m x 4, 0-based) of a Gmsh 2.2 ASCII file."""
    with open(path) as f:
        text = f.read()
    ns = text.index("$Nodes") + len("$Nodes")
    ne = text.index("$EndNodes")
    body = text[ns:ne].split("\n", 2)
    n = int(body[1])
    arr = np.array(body[2].split(), dtype=np.float64).reshape(n, 4)
    ids = arr[:, 0].astype(np.int64)
    nodes = arr[:, 1:4]
    idmap = np.full(ids.max() + 1, -1, dtype=np.int64)
    idmap[ids] = np.arange(n)
    es = text.index("$Elements") + len("$Elements")
    ee = text.index("$EndElements")
    ebody = text[es:ee].split("\n", 2)
    m = int(ebody[1])
    flat = np.array(ebody[2].split(), dtype=np.int64)
    # Fast path: every row is a tet with the same number of tags.
    ntags = flat[2]
    width = 3 + ntags + 4
    if flat.size == m * width and np.all(flat.reshape(m, width)[:, 1] == 4):
        tets = flat.reshape(m, width)[:, 3 + ntags:]
    else:
        rows, i = [], 0
        while i < flat.size:
            typ, nt = flat[i + 1], flat[i + 2]
            k = {15: 1, 1: 2, 2: 3, 4: 4}[int(typ)]
            if typ == 4:
                rows.append(flat[i + 3 + nt:i + 3 + nt + 4])
            i += 3 + nt + k
        tets = np.array(rows)
    return nodes, idmap[tets].astype(np.int32)


class Problem:
    def __init__(self, path):
        self.nodes, self.tets = read_msh22(path)
        X = self.nodes
        t = self.tets
        dm = np.stack([X[t[:, 1]] - X[t[:, 0]], X[t[:, 2]] - X[t[:, 0]],
                       X[t[:, 3]] - X[t[:, 0]]], axis=2)  # columns
        self.vol = np.linalg.det(dm) / 6.0
        assert np.all(self.vol > 0), "inverted reference tets"
        self.dminv = np.linalg.inv(dm)
        n = len(X)
        self.mass = np.zeros(n)
        for k in range(4):
            np.add.at(self.mass, t[:, k], RHO * self.vol / 4.0)
        self.inv_mass = 1.0 / self.mass
        edges = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
        hmin = min(np.linalg.norm(X[t[:, a]] - X[t[:, b]], axis=1).min() for a, b in edges)
        c = np.sqrt((LAM + 2 * MU) / RHO)
        self.dt = 0.2 * hmin / c
        self.fixed = (X[:, 0] == X[:, 0].min()).astype(np.int32)
        self.free_end = np.nonzero(X[:, 0] == X[:, 0].max())[0]
        self.n, self.ne = n, len(t)

    def check(self, u):
        return float(u[self.free_end, 1].mean()), float(np.linalg.norm(u, axis=1).max())


# ------------------------------------------------------------------------------------------
# NVIDIA Warp
# ------------------------------------------------------------------------------------------
class WarpPeer:
    name = "warp"
    desc = "NVIDIA Warp {ver} CPU, f64, 1 thread"

    def __init__(self):
        import warp as wp
        wp.config.quiet = True
        wp.init()
        self.wp = wp
        self.desc = self.desc.format(ver=wp.__version__)
        f64 = wp.float64

        @wp.kernel
        def elem_forces(u: wp.array(dtype=wp.vec3d), tets: wp.array(dtype=wp.vec4i),
                        dminv: wp.array(dtype=wp.mat33d), vol: wp.array(dtype=f64),
                        mu: f64, lam: f64, f: wp.array(dtype=wp.vec3d)):
            e = wp.tid()
            t = tets[e]
            u0 = u[t[0]]
            d1 = u[t[1]] - u0
            d2 = u[t[2]] - u0
            d3 = u[t[3]] - u0
            du = wp.mat33d(d1[0], d2[0], d3[0], d1[1], d2[1], d3[1], d1[2], d2[2], d3[2])
            B = dminv[e]
            F = wp.identity(n=3, dtype=f64) + du * B
            J = wp.determinant(F)
            FinvT = wp.transpose(wp.inverse(F))
            P = mu * (F - FinvT) + lam * wp.log(J) * FinvT
            H = (-vol[e]) * (P * wp.transpose(B))
            h1 = wp.vec3d(H[0, 0], H[1, 0], H[2, 0])
            h2 = wp.vec3d(H[0, 1], H[1, 1], H[2, 1])
            h3 = wp.vec3d(H[0, 2], H[1, 2], H[2, 2])
            wp.atomic_add(f, t[0], -(h1 + h2 + h3))
            wp.atomic_add(f, t[1], h1)
            wp.atomic_add(f, t[2], h2)
            wp.atomic_add(f, t[3], h3)

        @wp.kernel
        def update(u: wp.array(dtype=wp.vec3d), v: wp.array(dtype=wp.vec3d),
                   f: wp.array(dtype=wp.vec3d), inv_mass: wp.array(dtype=f64),
                   fixed: wp.array(dtype=wp.int32), g: wp.vec3d, dt: f64):
            i = wp.tid()
            if fixed[i] != 0:
                v[i] = wp.vec3d(f64(0.0), f64(0.0), f64(0.0))
                u[i] = wp.vec3d(f64(0.0), f64(0.0), f64(0.0))
            else:
                vi = v[i] + dt * (f[i] * inv_mass[i] + g)
                v[i] = vi
                u[i] = u[i] + dt * vi
            f[i] = wp.vec3d(f64(0.0), f64(0.0), f64(0.0))

        self.elem_forces, self.update = elem_forces, update

    def setup(self, pb):
        wp = self.wp
        d = "cpu"
        self.pb = pb
        self.u = wp.zeros(pb.n, dtype=wp.vec3d, device=d)
        self.v = wp.zeros(pb.n, dtype=wp.vec3d, device=d)
        self.f = wp.zeros(pb.n, dtype=wp.vec3d, device=d)
        self.tets = wp.array(pb.tets, dtype=wp.vec4i, device=d)
        self.dminv = wp.array(pb.dminv, dtype=wp.mat33d, device=d)
        self.vol = wp.array(pb.vol, dtype=wp.float64, device=d)
        self.im = wp.array(pb.inv_mass, dtype=wp.float64, device=d)
        self.fixed = wp.array(pb.fixed, dtype=wp.int32, device=d)
        self.g = wp.vec3d(*G)

    def steps(self, k):
        wp, pb = self.wp, self.pb
        for _ in range(k):
            wp.launch(self.elem_forces, dim=pb.ne,
                      inputs=[self.u, self.tets, self.dminv, self.vol, MU, LAM, self.f],
                      device="cpu")
            wp.launch(self.update, dim=pb.n,
                      inputs=[self.u, self.v, self.f, self.im, self.fixed, self.g, pb.dt],
                      device="cpu")
        wp.synchronize()

    def displacement(self):
        return self.u.numpy()


# ------------------------------------------------------------------------------------------
# Taichi
# ------------------------------------------------------------------------------------------
class TaichiPeer:
    name = "taichi"
    desc = "Taichi {ver} CPU, f64, 2 threads"

    def __init__(self):
        import taichi as ti
        ti.init(arch=ti.cpu, default_fp=ti.f64, cpu_max_num_threads=2, log_level=ti.WARN)
        self.ti = ti
        self.desc = self.desc.format(ver=".".join(map(str, ti.__version__)))

    def setup(self, pb):
        ti = self.ti
        self.pb = pb
        n, ne = pb.n, pb.ne
        self.u = ti.Vector.field(3, ti.f64, n)
        self.v = ti.Vector.field(3, ti.f64, n)
        self.f = ti.Vector.field(3, ti.f64, n)
        self.tets = ti.Vector.field(4, ti.i32, ne)
        self.dminv = ti.Matrix.field(3, 3, ti.f64, ne)
        self.vol = ti.field(ti.f64, ne)
        self.im = ti.field(ti.f64, n)
        self.fixed = ti.field(ti.i32, n)
        self.tets.from_numpy(pb.tets)
        self.dminv.from_numpy(pb.dminv)
        self.vol.from_numpy(pb.vol)
        self.im.from_numpy(pb.inv_mass)
        self.fixed.from_numpy(pb.fixed)
        u, v, f, tets, dminv, vol, im, fixed = (self.u, self.v, self.f, self.tets, self.dminv,
                                               self.vol, self.im, self.fixed)
        mu, lam, dt = MU, LAM, pb.dt
        g = ti.Vector(list(G), dt=ti.f64)

        @ti.kernel
        def elem_forces():
            for e in range(ne):
                t = tets[e]
                u0 = u[t[0]]
                d1 = u[t[1]] - u0
                d2 = u[t[2]] - u0
                d3 = u[t[3]] - u0
                du = ti.Matrix.cols([d1, d2, d3])
                B = dminv[e]
                F = ti.Matrix.identity(ti.f64, 3) + du @ B
                J = F.determinant()
                FinvT = F.inverse().transpose()
                P = mu * (F - FinvT) + lam * ti.log(J) * FinvT
                H = -vol[e] * (P @ B.transpose())
                h1 = ti.Vector([H[0, 0], H[1, 0], H[2, 0]])
                h2 = ti.Vector([H[0, 1], H[1, 1], H[2, 1]])
                h3 = ti.Vector([H[0, 2], H[1, 2], H[2, 2]])
                f[t[0]] += -(h1 + h2 + h3)
                f[t[1]] += h1
                f[t[2]] += h2
                f[t[3]] += h3

        @ti.kernel
        def update():
            for i in range(n):
                if fixed[i] != 0:
                    v[i] = ti.Vector([0.0, 0.0, 0.0], dt=ti.f64)
                    u[i] = ti.Vector([0.0, 0.0, 0.0], dt=ti.f64)
                else:
                    vi = v[i] + dt * (f[i] * im[i] + g)
                    v[i] = vi
                    u[i] = u[i] + dt * vi
                f[i] = ti.Vector([0.0, 0.0, 0.0], dt=ti.f64)

        self.elem_forces, self.update = elem_forces, update

    def steps(self, k):
        for _ in range(k):
            self.elem_forces()
            self.update()
        self.ti.sync()

    def displacement(self):
        return self.u.to_numpy()


def make_peers():
    peers = []
    for cls in (WarpPeer, TaichiPeer):
        try:
            peers.append(cls())
        except Exception as e:  # noqa: BLE001 - report and continue
            print(f"WARNING: {cls.name} unavailable ({type(e).__name__}: {e}); skipped")
    return peers


def best_of_3(fn, k):
    best = float("inf")
    for _ in range(3):
        t0 = time.perf_counter()
        fn(k)
        best = min(best, time.perf_counter() - t0)
    return best


def raisov_check(raisov, steps):
    out = subprocess.run([raisov, "bench", "--check", str(steps), "--sizes", "1k,10k",
                          "--precision", "f64"],
                         check=True, capture_output=True, text=True).stdout
    res = {}
    for line in out.splitlines():
        if line.startswith("check "):
            kv = dict(x.split("=") for x in line.split()[1:])
            res[kv["size"]] = (float(kv["mean_uy_free_end"]), float(kv["max_abs_u"]))
    return res


def raisov_throughput(raisov, sizes):
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "r.csv")
        subprocess.run([raisov, "bench", "--standard-only", "--sizes",
                        ",".join(label(s) for s in sizes), "--threads", "1,2",
                        "--precision", "f64", "--out", path],
                       check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        res = {}
        with open(path) as f:
            for row in csv.DictReader(f):
                res[(int(row["nodes"]), int(row["threads"]))] = float(row["node_updates_per_s"])
        return res


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--raisov", required=True)
    ap.add_argument("--meshes", required=True)
    ap.add_argument("--sizes", default="100k,1M")
    ap.add_argument("--check-steps", type=int, default=500)
    ap.add_argument("--work", type=float, default=2e7,
                    help="node-updates per timing (steps = work / nodes)")
    a = ap.parse_args()
    sizes = parse_sizes(a.sizes)
    # raisov's throughput first, before any peer loads: a loaded Taichi or Warp runtime keeps
    # threads in this process that took up to a quarter of raisov's two-thread rate when
    # raisov was timed after the correctness checks.
    print("\n== timing raisov (before loading the peers)")
    rs = raisov_throughput(a.raisov, sizes)
    peers = make_peers()
    if not peers:
        print("no peer could be loaded")

    # --- correctness: 500 steps on the 1k and 10k boxes -------------------------------------
    print(f"\n== correctness: {a.check_steps} steps, mean y-displacement of the free end and "
          "max |u| (5 significant digits must agree)")
    ref = raisov_check(a.raisov, a.check_steps)
    ok_all = True
    for lab in ("1k", "10k"):
        r = ref[lab]
        print(f"  {lab:>4}  raisov  mean_uy = {r[0]: .9e}  max|u| = {r[1]:.9e}")
        pb = Problem(os.path.join(a.meshes, f"box_{lab}.msh"))
        for p in peers:
            p.setup(pb)
            p.steps(a.check_steps)
            c = pb.check(p.displacement())
            rel = max(abs(c[0] - r[0]) / abs(r[0]), abs(c[1] - r[1]) / abs(r[1]))
            ok = rel < 5e-6
            ok_all &= ok
            print(f"  {lab:>4}  {p.name:<6}  mean_uy = {c[0]: .9e}  max|u| = {c[1]:.9e}  "
                  f"rel diff {rel:.1e}  {'OK' if ok else 'MISMATCH'}")
    print(f"  agreement to 5 digits: {'yes' if ok_all else 'NO'}")

    # --- throughput -------------------------------------------------------------------------
    print("\n== throughput (node-updates/s = nodes x steps / s, best of 3)")
    rows = []
    for s in sizes:
        lab = label(s)
        pb = Problem(os.path.join(a.meshes, f"box_{lab}.msh"))
        k = max(3, int(a.work / pb.n))
        for p in peers:
            p.setup(pb)
            p.steps(2)  # compile and warm up
            secs = best_of_3(p.steps, k)
            rows.append((lab, pb.n, pb.ne, p.desc, pb.n * k / secs))
        for t in (1, 2):
            if (pb.n, t) in rs:
                rows.append((lab, pb.n, pb.ne, f"raisov, f64, {t} thread(s)", rs[(pb.n, t)]))
    print(f"  {'size':>5} {'nodes':>8} {'tets':>8}  {'code':<36} {'node-updates/s':>15}")
    for lab, n, ne, desc, nups in rows:
        print(f"  {lab:>5} {n:>8} {ne:>8}  {desc:<36} {nups / 1e6:>13.2f} M")
    print("\n== raisov (2 threads) / peer")
    for s in sizes:
        lab = label(s)
        mine = [r for r in rows if r[0] == lab and r[3].startswith("raisov") and "2 thread" in r[3]]
        if not mine:
            continue
        for r in rows:
            if r[0] == lab and not r[3].startswith("raisov"):
                print(f"  {lab:>5}  vs {r[3]:<36} {mine[0][4] / r[4]:6.2f}x")
    return 0 if ok_all else 1


if __name__ == "__main__":
    sys.exit(main())
