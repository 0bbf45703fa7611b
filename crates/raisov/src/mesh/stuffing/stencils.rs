//! The stencils: how a lattice tetrahedron that the surface crosses is filled.
//!
//! After warping every lattice vertex has a sign `−` (inside), `0` (on the surface) or `+`
//! (outside), and every lattice edge with ends `−` and `+` carries its cut point. The part
//! of a lattice tetrahedron kept is the convex hull of its `−` and `0` vertices and its cut
//! points: the region where the linear interpolation of the signs is `≤ 0`. Up to symmetry
//! (`I` inside, `Z` zero, `O` outside, `c_ij` the cut point on edge `ij`):
//!
//! | signs | kept polytope | tetrahedra |
//! |---|---|---|
//! | no `O`, at least one `I` | the whole tetrahedron | 1 |
//! | `Z Z Z Z` | the whole tetrahedron if its centroid is inside the surface | 0 or 1 |
//! | `I Z Z O` | `I Z Z c_IO` | 1 |
//! | `I Z O O` | `I Z c_IO1 c_IO2` | 1 |
//! | `I O O O` | `I c_IO1 c_IO2 c_IO3` | 1 |
//! | `I I Z O` | pyramid, apex `Z`, base quadrilateral `I1 I2 c_2O c_1O` | 2 |
//! | `I I I O` | prism, triangles `I1 I2 I3` and `c_1O c_2O c_3O` | 3 |
//! | `I I O O` | prism, triangles `I1 c_1O1 c_1O2` and `I2 c_2O1 c_2O2` | 3 |
//!
//! and nothing when there is no `I` (except `Z Z Z Z`). A quadrilateral lying in a lattice
//! face `(I_a, I_b, O)` is shared with the neighbouring lattice tetrahedron, so its
//! diagonal is chosen from the face alone ([`quad_diagonal`]):
//!
//! * if `I_a O` is a long edge (the face's other two edges are short), the diagonal joins
//!   the cut point on that long edge to the far lattice vertex: `I_b – c_aO`;
//! * if `I_a I_b` is the long edge (both cut points on short edges), the *parity rule*:
//!   the long edge's end with the smaller coordinate along its axis is `I_0`, and the
//!   diagonal is `I_0 – c_1O` when the sum of `I_0`'s integer coordinates (in its own grid)
//!   is even, `I_1 – c_0O` when it is odd. It depends on the long edge only, so both
//!   tetrahedra that share the face agree; the lattice tetrahedron's mirror symmetry that
//!   swaps the ends of a long edge maps one choice onto the other, so both have the same
//!   angle bounds.
//!
//! In the `I I I O` prism the two faces through `O`'s long edge both send their diagonal to
//! that edge's cut point, so the three diagonals never form a cycle. In the `I I O O` prism
//! the quadrilateral on the surface belongs to no other tetrahedron: its diagonal is the one
//! that keeps the three diagonals acyclic, the shorter one when both do. A prism whose
//! quadrilateral diagonals are acyclic splits into three tetrahedra ([`split_prism`]).

use super::lattice::{Colour, Lattice};

/// What a lattice tetrahedron holds, for [`fill`].
pub(crate) struct FillCtx<'a> {
    pub lattice: &'a Lattice,
    /// Sign of each lattice vertex after warping: −1, 0, +1.
    pub sign: &'a [i8],
    /// Mesh node of each lattice vertex with sign ≤ 0 (`u32::MAX` otherwise).
    pub vnode: &'a [u32],
    /// Mesh node of the cut point on edge `(a, b)`.
    pub cut: &'a (dyn Fn(u32, u32) -> u32 + Sync),
    /// Mesh node positions.
    pub pos: &'a [[f64; 3]],
}

/// The result of [`fill`] for the `Z Z Z Z` case, decided by the caller.
#[derive(Debug, PartialEq, Eq)]
pub(crate) enum Filled {
    Done,
    AllZero,
}

/// Emit the tetrahedra (mesh nodes, not oriented) of lattice tetrahedron `t`.
pub(crate) fn fill(ctx: &FillCtx, t: [u32; 4], out: &mut Vec<[u32; 4]>) -> Filled {
    let s = t.map(|v| ctx.sign[v as usize]);
    let ins: Vec<u32> = (0..4).filter(|&i| s[i] < 0).map(|i| t[i]).collect();
    let zer: Vec<u32> = (0..4).filter(|&i| s[i] == 0).map(|i| t[i]).collect();
    let out_v: Vec<u32> = (0..4).filter(|&i| s[i] > 0).map(|i| t[i]).collect();
    let vn = |v: u32| ctx.vnode[v as usize];
    let c = |a: u32, b: u32| (ctx.cut)(a, b);
    match (ins.len(), zer.len(), out_v.len()) {
        (0, 4, 0) => return Filled::AllZero,
        (0, _, _) => {}
        (_, _, 0) => out.push(t.map(vn)),
        (1, 2, 1) => out.push([vn(ins[0]), vn(zer[0]), vn(zer[1]), c(ins[0], out_v[0])]),
        (1, 1, 2) => out.push([
            vn(ins[0]),
            vn(zer[0]),
            c(ins[0], out_v[0]),
            c(ins[0], out_v[1]),
        ]),
        (1, 0, 3) => out.push([
            vn(ins[0]),
            c(ins[0], out_v[0]),
            c(ins[0], out_v[1]),
            c(ins[0], out_v[2]),
        ]),
        (2, 1, 1) => {
            let (a, b, o, z) = (ins[0], ins[1], out_v[0], zer[0]);
            let (x, y) = if quad_diagonal(ctx.lattice, a, b, o) == a {
                (a, b)
            } else {
                (b, a)
            };
            // Diagonal x – c(y, o): triangles (x, y, c_y) and (x, c_y, c_x).
            let (cx, cy) = (c(x, o), c(y, o));
            out.push([vn(z), vn(x), vn(y), cy]);
            out.push([vn(z), vn(x), cy, cx]);
        }
        (3, 0, 1) => {
            let o = out_v[0];
            let bottom = [0, 1, 2].map(|i| vn(ins[i]));
            let top = [0, 1, 2].map(|i| c(ins[i], o));
            let mut dir = [[false; 3]; 3];
            for i in 0..3 {
                for j in i + 1..3 {
                    let x = quad_diagonal(ctx.lattice, ins[i], ins[j], o);
                    dir[i][j] = x == ins[i];
                    dir[j][i] = !dir[i][j];
                }
            }
            split_prism(bottom, top, dir, out);
        }
        (2, 0, 2) => {
            let (i1, i2) = (ins[0], ins[1]);
            // Columns: 0 = lattice (i1 -> i2), 1 and 2 the cut points beside o1, o2.
            let bottom = [vn(i1), c(i1, out_v[0]), c(i1, out_v[1])];
            let top = [vn(i2), c(i2, out_v[0]), c(i2, out_v[1])];
            let mut dir = [[false; 3]; 3];
            for k in 1..3 {
                let from_i1 = quad_diagonal(ctx.lattice, i1, i2, out_v[k - 1]) == i1;
                dir[0][k] = from_i1;
                dir[k][0] = !from_i1;
            }
            // The surface quadrilateral: 1 -> 2 is the diagonal bottom[1] – top[2].
            let forced = if dir[0][1] && dir[2][0] {
                Some(false)
            } else if dir[1][0] && dir[0][2] {
                Some(true)
            } else {
                None
            };
            let one_to_two = forced.unwrap_or_else(|| {
                let d = |a: u32, b: u32| {
                    let (p, q) = (ctx.pos[a as usize], ctx.pos[b as usize]);
                    (0..3).map(|k| (p[k] - q[k]).powi(2)).sum::<f64>()
                };
                d(bottom[1], top[2]) <= d(bottom[2], top[1])
            });
            dir[1][2] = one_to_two;
            dir[2][1] = !one_to_two;
            split_prism(bottom, top, dir, out);
        }
        other => unreachable!("sign counts {other:?} do not add up to 4"),
    }
    Filled::Done
}

/// The lattice end of the diagonal of the quadrilateral in lattice face `(a, b, o)`
/// (`a`, `b` inside, `o` outside): `a` for the diagonal `a – c_bo`, `b` for `b – c_ao`.
/// See the module docs.
pub(crate) fn quad_diagonal(l: &Lattice, a: u32, b: u32, o: u32) -> u32 {
    if l.is_long(a, o) {
        b
    } else if l.is_long(b, o) {
        a
    } else {
        // a–b long: ids grow with the coordinates within a grid.
        let (first, second) = if a < b { (a, b) } else { (b, a) };
        let (col, c) = l.coords(first);
        debug_assert!(col == Colour::Black || col == Colour::Red);
        if (c[0] + c[1] + c[2]) % 2 == 0 {
            first
        } else {
            second
        }
    }
}

/// Split the prism with triangles `bottom` and `top` (`bottom[i]` – `top[i]` its columns)
/// into three tetrahedra whose faces on the quadrilateral `(i, j)` have the diagonal
/// `bottom[i] – top[j]` when `dir[i][j]`, else `bottom[j] – top[i]`. The directions must be
/// acyclic; with the order `p → q → r` the tetrahedra are `(b_p b_q b_r t_r)`,
/// `(b_p b_q t_q t_r)`, `(b_p t_p t_q t_r)`.
pub(crate) fn split_prism(
    bottom: [u32; 3],
    top: [u32; 3],
    dir: [[bool; 3]; 3],
    out: &mut Vec<[u32; 4]>,
) {
    // The source has both its edges outgoing, the sink none.
    let outdeg = |i: usize| (0..3).filter(|&j| j != i && dir[i][j]).count();
    let p = (0..3).find(|&i| outdeg(i) == 2);
    let r = (0..3).find(|&i| outdeg(i) == 0);
    let (Some(p), Some(r)) = (p, r) else {
        unreachable!("cyclic prism diagonals {dir:?}")
    };
    let q = 3 - p - r;
    let (bp, bq, br) = (bottom[p], bottom[q], bottom[r]);
    let (tp, tq, tr) = (top[p], top[q], top[r]);
    out.push([bp, bq, br, tr]);
    out.push([bp, bq, tq, tr]);
    out.push([bp, tp, tq, tr]);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::tet_volume;

    /// Every acyclic diagonal choice splits a prism into three positive-volume tetrahedra
    /// that fill it and carry the chosen diagonals.
    #[test]
    fn prism_split_fills_the_prism_with_the_chosen_diagonals() {
        let pos = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.1, 0.05, 1.0],
            [1.1, 0.05, 1.0],
            [0.1, 1.05, 1.0],
        ];
        let orders = [
            [0, 1, 2],
            [0, 2, 1],
            [1, 0, 2],
            [1, 2, 0],
            [2, 0, 1],
            [2, 1, 0],
        ];
        let mut vols = Vec::new();
        for ord in orders {
            let mut dir = [[false; 3]; 3];
            for a in 0..3 {
                for b in a + 1..3 {
                    dir[ord[a]][ord[b]] = true;
                }
            }
            let mut out = Vec::new();
            split_prism([0, 1, 2], [3, 4, 5], dir, &mut out);
            assert_eq!(out.len(), 3);
            let mut total = 0.0;
            for t in &out {
                let v = tet_volume(
                    pos[t[0] as usize],
                    pos[t[1] as usize],
                    pos[t[2] as usize],
                    pos[t[3] as usize],
                )
                .abs();
                assert!(v > 1e-3, "{v}");
                total += v;
            }
            vols.push(total);
            // The diagonal of quad (i, j) is an edge of some tetrahedron; its crossing one is not.
            for i in 0..3 {
                for j in 0..3 {
                    if i == j {
                        continue;
                    }
                    let (d0, d1) = (i as u32, 3 + j as u32);
                    let has = out.iter().any(|t| t.contains(&d0) && t.contains(&d1));
                    assert_eq!(has, dir[i][j], "quad {i}{j}");
                }
            }
        }
        // A sheared prism of base area 1/2 and height 1: every split fills it.
        for v in &vols {
            assert!((v - 0.5).abs() < 1e-14, "{vols:?}");
        }
    }
}
