"""Reference tip deflection of Cook's membrane, linear elasticity, by scikit-fem.

Tapered panel (0,0), (48,44), (48,60), (0,44); left edge x = 0 clamped; uniform vertical
shear traction on the right edge x = 48 with total force F = 1 per unit thickness;
E = 1. Prints the vertical displacement of the top-right corner (48, 60) on structured
n x n quad grids of the domain, each quad cut into two triangles, with quadratic (P2)
triangles, in plane stress (nu = 1/3) and in plane strain (nu = 1/3, used by
tests/reference_cook.rs; and nu = 1/4 with E = 15/16, which is plane stress with nu = 1/3
exactly, a check of the plane-stress/plane-strain switch).

    python3 -m venv /tmp/skfem && /tmp/skfem/bin/pip install scikit-fem
    /tmp/skfem/bin/python cook_reference.py
"""
import numpy as np
from skfem import (MeshTri, ElementTriP2, ElementVector, Basis, FacetBasis,
                   asm, solve, condense, LinearForm)
from skfem.models.elasticity import linear_elasticity, lame_parameters


def mesh(n):
    m = MeshTri.init_tensor(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1))
    xi, eta = m.p
    x = 48.0 * xi
    y = 44.0 * xi + eta * (44.0 - 28.0 * xi)
    return MeshTri(np.vstack([x, y]), m.t)


def tip(n, E, nu, plane_stress):
    m = mesh(n)
    e = ElementVector(ElementTriP2())
    ib = Basis(m, e, intorder=4)
    lam, mu = lame_parameters(E, nu)
    if plane_stress:
        lam = 2 * lam * mu / (lam + 2 * mu)
    K = asm(linear_elasticity(lam, mu), ib)
    right = m.facets_satisfying(lambda x: np.isclose(x[0], 48.0))
    fb = FacetBasis(m, e, facets=right, intorder=4)
    tau = 1.0 / 16.0

    @LinearForm
    def traction(v, w):
        return tau * v.value[1]

    f = asm(traction, fb)
    left = ib.get_dofs(lambda x: np.isclose(x[0], 0.0))
    u = solve(*condense(K, f, D=left))
    k = np.flatnonzero(np.isclose(m.p[0], 48.0) & np.isclose(m.p[1], 60.0))[0]
    return u[ib.nodal_dofs[1, k]]


if __name__ == "__main__":
    cases = [("plane stress, nu = 1/3", 1.0, 1.0 / 3.0, True),
             ("plane strain, nu = 1/3", 1.0, 1.0 / 3.0, False),
             ("plane strain, E = 15/16, nu = 1/4", 15.0 / 16.0, 0.25, False)]
    for name, E, nu, ps in cases:
        vals = [(n, tip(n, E, nu, ps)) for n in (16, 32, 64, 128, 256)]
        print(name)
        for n, v in vals:
            print(f"  {n:4d} x {n:<4d} P2: v_tip = {v:.6f}")

# Output (scikit-fem 12.0.2):
# plane stress, nu = 1/3
#     16 x 16   P2: v_tip = 25.015813
#     32 x 32   P2: v_tip = 25.110470
#     64 x 64   P2: v_tip = 25.152089
#    128 x 128  P2: v_tip = 25.171474
#    256 x 256  P2: v_tip = 25.180708
# plane strain, nu = 1/3
#     16 x 16   P2: v_tip = 22.422399
#     32 x 32   P2: v_tip = 22.525421
#     64 x 64   P2: v_tip = 22.570573
#    128 x 128  P2: v_tip = 22.591501
#    256 x 256  P2: v_tip = 22.601389
# plane strain, E = 15/16, nu = 1/4
#     (the plane-stress values, to the printed digits)
