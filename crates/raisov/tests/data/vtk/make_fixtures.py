"""Write the VTU / VTK fixtures read by crates/raisov/tests/vtk_fixtures.rs.

Usage (from this directory):
    python3 -m venv /tmp/venv-vtu && /tmp/venv-vtu/bin/pip install meshio numpy [vtk]
    /tmp/venv-vtu/bin/python make_fixtures.py [--check FRAME.vtu ...]

The mesh: a 3 x 2 x 2 grid of points (two unit cubes scaled by 0.1 m, coordinates shifted by
irrational-looking offsets so that no value is a short decimal), each cube cut into the six
Kuhn tetrahedra, every tetrahedron positively oriented, plus the boundary triangles of the
first cube's bottom face (lower-dimensional cells a reader must ignore), and a point and a
cell field (which a reader must skip). `expected_tet.txt` holds the points (Python's
shortest round-trip repr) and the tetrahedra, for exact comparison.

Written with meshio (inline base64 and ASCII .vtu in each of its modes, legacy .vtk 5.1
ASCII and binary, legacy 4.2 binary) and, when the `vtk` package is importable, with VTK
itself (appended raw and base64, zlib or uncompressed, inline binary, ASCII; legacy 5.1).

`--check FILE...` reads VTU frames written by raisov with meshio and prints what it found
(no assertion: a smoke check that another reader accepts them).
"""

import itertools
import sys

import meshio
import numpy as np


def mesh():
    nx, ny, nz = 3, 2, 2
    idx = {}
    pts = []
    for k, j, i in itertools.product(range(nz), range(ny), range(nx)):
        idx[i, j, k] = len(pts)
        pts.append(
            [
                0.1 * i + 1e-3 * np.sqrt(2.0) * (j + 1),
                0.1 * j - 1e-3 * np.sqrt(3.0) * (k + 1),
                0.1 * k + 1e-3 / 3.0 * (i + 1),
            ]
        )
    pts = np.array(pts, dtype=np.float64)
    tets = []
    for c in range(nx - 1):
        # Kuhn subdivision: the six paths from corner 000 to 111 of the cube.
        for perm in itertools.permutations(range(3)):
            cur = [0, 0, 0]
            path = [tuple(cur)]
            for ax in perm:
                cur[ax] = 1
                path.append(tuple(cur))
            t = [idx[c + a, b, d] for (a, b, d) in path]
            p = pts[t]
            if np.linalg.det(np.array([p[1] - p[0], p[2] - p[0], p[3] - p[0]])) < 0:
                t[2], t[3] = t[3], t[2]
            tets.append(t)
    tets = np.array(tets, dtype=np.int64)
    tris = np.array([[idx[0, 0, 0], idx[0, 1, 0], idx[1, 0, 0]],
                     [idx[1, 0, 0], idx[0, 1, 0], idx[1, 1, 0]]], dtype=np.int64)
    return pts, tets, tris


def tri_mesh():
    pts = np.array(
        [[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.1 + 1e-3 / 7.0, 0.1, 0.0], [0.0, 0.1, 0.0]]
    )
    tris = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int64)
    return pts, tris


def write_meshio(pts, tets, tris):
    m = meshio.Mesh(
        pts,
        [("tetra", tets), ("triangle", tris)],
        point_data={"u": np.arange(3 * len(pts), dtype=np.float64).reshape(-1, 3) * 1e-4},
        cell_data={"id": [np.arange(len(tets), dtype=np.int32), np.zeros(len(tris), np.int32)]},
    )
    modes = {
        "meshio_ascii.vtu": dict(binary=False),
        "meshio_base64.vtu": dict(binary=True, compression=None),
        "meshio_base64_zlib.vtu": dict(binary=True, compression="zlib"),
        "meshio_base64_u64.vtu": dict(binary=True, compression=None, header_type="UInt64"),
        "meshio_base64_zlib_u64.vtu": dict(binary=True, compression="zlib", header_type="UInt64"),
    }
    for name, kw in modes.items():
        meshio.vtu.write(name, m, **kw)
    meshio.vtk.write("meshio_51_ascii.vtk", m, binary=False, fmt_version="5.1")
    meshio.vtk.write("meshio_51_binary.vtk", m, binary=True, fmt_version="5.1")
    meshio.vtk.write("meshio_42_binary.vtk", m, binary=True, fmt_version="4.2")
    tp, tt = tri_mesh()
    meshio.vtu.write("meshio_tri_zlib.vtu", meshio.Mesh(tp, [("triangle", tt)]), binary=True)
    meshio.vtk.write("meshio_tri_51_binary.vtk", meshio.Mesh(tp, [("triangle", tt)]),
                     binary=True, fmt_version="5.1")


def write_vtk(pts, tets, tris):
    try:
        import vtk
        from vtk.util import numpy_support as ns
    except ImportError:
        print("vtk not importable: VTK-written fixtures skipped")
        return
    g = vtk.vtkUnstructuredGrid()
    p = vtk.vtkPoints()
    p.SetData(ns.numpy_to_vtk(pts, deep=True))
    g.SetPoints(p)
    for t in tets:
        g.InsertNextCell(vtk.VTK_TETRA, 4, [int(v) for v in t])
    for t in tris:
        g.InsertNextCell(vtk.VTK_TRIANGLE, 3, [int(v) for v in t])
    u = ns.numpy_to_vtk(np.arange(3 * len(pts), dtype=np.float64).reshape(-1, 3) * 1e-4, deep=True)
    u.SetName("u")
    g.GetPointData().AddArray(u)

    def xml(name, mode, compress, encode=False, header64=True):
        w = vtk.vtkXMLUnstructuredGridWriter()
        w.SetFileName(name)
        w.SetInputData(g)
        {"appended": w.SetDataModeToAppended, "binary": w.SetDataModeToBinary,
         "ascii": w.SetDataModeToAscii}[mode]()
        w.SetEncodeAppendedData(encode)
        if compress:
            w.SetCompressorTypeToZLib()
        else:
            w.SetCompressorTypeToNone()
        if header64:
            w.SetHeaderTypeToUInt64()
        else:
            w.SetHeaderTypeToUInt32()
        assert w.Write() == 1, name

    xml("vtk_appended_raw_zlib.vtu", "appended", True)
    xml("vtk_appended_raw.vtu", "appended", False, header64=False)
    xml("vtk_appended_base64_zlib.vtu", "appended", True, encode=True, header64=False)
    xml("vtk_appended_base64.vtu", "appended", False, encode=True)
    xml("vtk_binary.vtu", "binary", False)
    xml("vtk_binary_zlib.vtu", "binary", True, header64=False)
    xml("vtk_ascii.vtu", "ascii", False)
    for name, binary in [("vtk_51_binary.vtk", True), ("vtk_51_ascii.vtk", False)]:
        w = vtk.vtkUnstructuredGridWriter()
        w.SetFileName(name)
        w.SetInputData(g)
        if binary:
            w.SetFileTypeToBinary()
        else:
            w.SetFileTypeToASCII()
        assert w.Write() == 1, name


def check(files):
    for f in files:
        m = meshio.read(f)
        print(f, len(m.points), "points", [(c.type, len(c.data)) for c in m.cells],
              "point data", {k: v.shape for k, v in m.point_data.items()})


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "--check":
        check(sys.argv[2:])
        return
    pts, tets, tris = mesh()
    with open("expected_tet.txt", "w") as f:
        f.write(f"{len(pts)} points\n")
        for p in pts:
            f.write(" ".join(repr(float(x)) for x in p) + "\n")
        f.write(f"{len(tets)} tetrahedra\n")
        for t in tets:
            f.write(" ".join(str(int(v)) for v in t) + "\n")
    tp, tt = tri_mesh()
    with open("expected_tri.txt", "w") as f:
        f.write(f"{len(tp)} points\n")
        for p in tp:
            f.write(" ".join(repr(float(x)) for x in p) + "\n")
        f.write(f"{len(tt)} triangles\n")
        for t in tt:
            f.write(" ".join(str(int(v)) for v in t) + "\n")
    write_meshio(pts, tets, tris)
    write_vtk(pts, tets, tris)


if __name__ == "__main__":
    main()
