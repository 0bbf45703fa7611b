//! Element kernels: reference data and the internal forces of one element.
//!
//! Tetrahedron: `F = Ds Dm⁻¹`, `P = F S(C)`, `H = V0 P Dm⁻ᵀ`; the forces R on nodes 1..3 are
//! the columns of H and node 0 gets `−Σ`. Membrane: the same with a 3x2 `F` and the measure
//! `h A0`. These are `∂E/∂x` of `E = V0 W(C)`, checked against finite differences in tests.
//!
//! Element tangent stiffness `K_e = ∂R_e/∂u_e` (12x12 or 9x9, symmetric): moving node b along
//! axis k changes `F` by `dF = e_k ⊗ g_b` with `g_b` row `b−1` of `Dm⁻¹` (b ≥ 1) and
//! `g_0 = −Σ_b g_b`; then `dH = V0 dP Dm⁻ᵀ` with `dP = ∂P/∂F : dF` from the law
//! ([`SolidMaterial::dpk1`]; an element asks for all its directions at once,
//! [`SolidMaterial::dpk1_many`], [`MembraneMaterial::dpk1_many`]), and the column `(b, k)` of
//! `K_e` is `dR` assembled from `dH` as `R` from `H`. Equivalently the tetrahedron's block of
//! nodes a and b is `K_ab,ik = V0 Σ_JL g_aJ (∂P_iJ/∂F_kL) g_bL`, which a law with a closed
//! form of that contraction gives at once ([`SolidMaterial::contract_dpk1`], neo-Hookean).
//! Checked against central differences of the element forces in tests.

use crate::geometry::{cross, dot, norm, sub};
use crate::material::{MembraneMaterial, SolidMaterial};
use nalgebra::{Matrix2, Matrix3, Matrix3x2, Vector3};

/// `Dm⁻¹` (3x3) and the volume of a positive tetrahedron; `None` if degenerate or negative.
pub fn tet_dm_inverse(p: &[[f64; 3]]) -> Option<(Matrix3<f64>, f64)> {
    let c = |k: usize| Vector3::from(sub(p[k], p[0]));
    let dm = Matrix3::from_columns(&[c(1), c(2), c(3)]);
    let det = dm.determinant();
    let scale = [1, 2, 3]
        .iter()
        .map(|&k| norm(sub(p[k], p[0])))
        .fold(0.0, f64::max);
    if !(det > 1e-12 * scale.powi(3)) {
        return None;
    }
    Some((dm.try_inverse()?, det / 6.0))
}

/// Membrane reference frame: `Dm⁻¹` (2x2) in the triangle's own orthonormal frame
/// `(e1 along x1−x0, e2 = n × e1)`, its area and unit normal. `None` if degenerate.
pub fn membrane_frame(p: &[[f64; 3]]) -> Option<(Matrix2<f64>, f64, [f64; 3])> {
    let a = sub(p[1], p[0]);
    let b = sub(p[2], p[0]);
    let n = cross(a, b);
    let twice_area = norm(n);
    let la = norm(a);
    if !(twice_area > 1e-12 * (la * la + dot(b, b))) {
        return None;
    }
    let n = [n[0] / twice_area, n[1] / twice_area, n[2] / twice_area];
    let e1 = [a[0] / la, a[1] / la, a[2] / la];
    let e2 = cross(n, e1);
    let dm = Matrix2::new(la, dot(b, e1), 0.0, dot(b, e2));
    Some((dm.try_inverse()?, 0.5 * twice_area, n))
}

#[inline(always)]
fn node(x0: &[f64], u: &[f64], a: u32) -> Vector3<f64> {
    let a = a as usize * 3;
    Vector3::new(x0[a] + u[a], x0[a + 1] + u[a + 1], x0[a + 2] + u[a + 2])
}

/// Internal forces of one tetrahedron (12 numbers). `Err(det F)` if inverted.
#[inline(always)]
pub fn tet_forces<M: SolidMaterial + ?Sized>(
    m: &M,
    el: &[u32],
    x0: &[f64],
    u: &[f64],
    dminv: &[f64],
    vol: f64,
    out: &mut [f64],
) -> Result<(), f64> {
    let p0 = node(x0, u, el[0]);
    let ds = Matrix3::from_columns(&[
        node(x0, u, el[1]) - p0,
        node(x0, u, el[2]) - p0,
        node(x0, u, el[3]) - p0,
    ]);
    let dminv = Matrix3::from_column_slice(dminv);
    let f = ds * dminv;
    let det = f.determinant();
    if !(det > 0.0 || (m.handles_inversion() && det.is_finite())) {
        return Err(det);
    }
    let h = m.pk1(&f) * dminv.transpose() * vol;
    let mut s0 = Vector3::zeros();
    for j in 0..3 {
        let col = h.column(j);
        out[3 + 3 * j] = col[0];
        out[4 + 3 * j] = col[1];
        out[5 + 3 * j] = col[2];
        s0 += col;
    }
    out[0] = -s0[0];
    out[1] = -s0[1];
    out[2] = -s0[2];
    Ok(())
}

/// Internal forces of one membrane triangle (9 numbers). `Err(signed area ratio)` if the
/// triangle collapsed or flipped against its reference normal.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn membrane_forces<M: MembraneMaterial + ?Sized>(
    m: &M,
    el: &[u32],
    x0: &[f64],
    u: &[f64],
    dminv: &[f64],
    measure: f64,
    normal0: [f64; 3],
    out: &mut [f64],
) -> Result<(), f64> {
    let p0 = node(x0, u, el[0]);
    let ds = Matrix3x2::from_columns(&[node(x0, u, el[1]) - p0, node(x0, u, el[2]) - p0]);
    let dminv = Matrix2::from_column_slice(dminv);
    let f = ds * dminv;
    let n = f.column(0).cross(&f.column(1));
    let n0 = Vector3::from(normal0);
    let det = n.dot(&n0);
    if !(det > 0.0 || (m.handles_inversion() && det.is_finite())) {
        return Err(det);
    }
    let h = m.pk1(&f, &n0) * dminv.transpose() * measure;
    let mut s0 = Vector3::zeros();
    for j in 0..2 {
        let col = h.column(j);
        out[3 + 3 * j] = col[0];
        out[4 + 3 * j] = col[1];
        out[5 + 3 * j] = col[2];
        s0 += col;
    }
    out[0] = -s0[0];
    out[1] = -s0[1];
    out[2] = -s0[2];
    Ok(())
}

/// `R` of one element from `H` (columns: nodes 1..; node 0 gets `−Σ`), `N − 1` columns.
#[inline(always)]
fn scatter_h<const C: usize>(h: &nalgebra::SMatrix<f64, 3, C>, out: &mut [f64]) {
    let mut s0 = Vector3::zeros();
    for j in 0..C {
        let col = h.column(j);
        out[3 + 3 * j] = col[0];
        out[4 + 3 * j] = col[1];
        out[5 + 3 * j] = col[2];
        s0 += col;
    }
    out[0] = -s0[0];
    out[1] = -s0[1];
    out[2] = -s0[2];
}

/// Tangent stiffness of one tetrahedron, `K[(3a + i) * 12 + 3b + k] = ∂R_(a,i)/∂u_(b,k)`
/// (144 numbers, row-major; module docs). `Err(det F)` if inverted and the law refuses it.
pub fn tet_stiffness<M: SolidMaterial + ?Sized>(
    m: &M,
    el: &[u32],
    x0: &[f64],
    u: &[f64],
    dminv: &[f64],
    vol: f64,
    out: &mut [f64],
) -> Result<(), f64> {
    let p0 = node(x0, u, el[0]);
    let ds = Matrix3::from_columns(&[
        node(x0, u, el[1]) - p0,
        node(x0, u, el[2]) - p0,
        node(x0, u, el[3]) - p0,
    ]);
    let dminv = Matrix3::from_column_slice(dminv);
    let f = ds * dminv;
    let det = f.determinant();
    if !(det > 0.0 || (m.handles_inversion() && det.is_finite())) {
        return Err(det);
    }
    let g = |b: usize| -> nalgebra::RowVector3<f64> {
        if b == 0 {
            -(dminv.row(0) + dminv.row(1) + dminv.row(2))
        } else {
            dminv.row(b - 1).into_owned()
        }
    };
    let gv: [Vector3<f64>; 4] = std::array::from_fn(|b| g(b).transpose());
    let mut blocks = [Matrix3::zeros(); 16];
    if m.contract_dpk1(&f, &gv, &mut blocks) {
        // K_(a,i),(b,k) = V Σ_JL g_aJ ∂P_iJ/∂F_kL g_bL.
        for (ab, blk) in blocks.iter().enumerate() {
            let (a, b) = (ab / 4, ab % 4);
            for i in 0..3 {
                for k in 0..3 {
                    out[(3 * a + i) * 12 + 3 * b + k] = vol * blk[(i, k)];
                }
            }
        }
        return Ok(());
    }
    let mut dfs = [Matrix3::zeros(); 12];
    for b in 0..4 {
        let gb = g(b);
        for k in 0..3 {
            dfs[3 * b + k].row_mut(k).copy_from(&gb);
        }
    }
    let mut dps = [Matrix3::zeros(); 12];
    m.dpk1_many(&f, &dfs, &mut dps);
    let mut col = [0.0; 12];
    let dmt = dminv.transpose() * vol;
    for (q, dp) in dps.iter().enumerate() {
        let dh = dp * dmt;
        scatter_h::<3>(&dh, &mut col);
        for (r, v) in col.iter().enumerate() {
            out[r * 12 + q] = *v;
        }
    }
    Ok(())
}

/// Tangent stiffness of one membrane triangle (81 numbers, row-major, as [`tet_stiffness`]).
#[allow(clippy::too_many_arguments)]
pub fn membrane_stiffness<M: MembraneMaterial + ?Sized>(
    m: &M,
    el: &[u32],
    x0: &[f64],
    u: &[f64],
    dminv: &[f64],
    measure: f64,
    normal0: [f64; 3],
    out: &mut [f64],
) -> Result<(), f64> {
    let p0 = node(x0, u, el[0]);
    let ds = Matrix3x2::from_columns(&[node(x0, u, el[1]) - p0, node(x0, u, el[2]) - p0]);
    let dminv = Matrix2::from_column_slice(dminv);
    let f = ds * dminv;
    let n0 = Vector3::from(normal0);
    let det = f.column(0).cross(&f.column(1)).dot(&n0);
    if !(det > 0.0 || (m.handles_inversion() && det.is_finite())) {
        return Err(det);
    }
    let g = |b: usize| -> nalgebra::RowVector2<f64> {
        if b == 0 {
            -(dminv.row(0) + dminv.row(1))
        } else {
            dminv.row(b - 1).into_owned()
        }
    };
    let mut dfs = [Matrix3x2::zeros(); 9];
    for b in 0..3 {
        let gb = g(b);
        for k in 0..3 {
            dfs[3 * b + k].row_mut(k).copy_from(&gb);
        }
    }
    let mut dps = [Matrix3x2::zeros(); 9];
    m.dpk1_many(&f, &n0, &dfs, &mut dps);
    let mut col = [0.0; 9];
    let dmt = dminv.transpose() * measure;
    for (q, dp) in dps.iter().enumerate() {
        let dh = dp * dmt;
        scatter_h::<2>(&dh, &mut col);
        for (r, v) in col.iter().enumerate() {
            out[r * 9 + q] = *v;
        }
    }
    Ok(())
}
