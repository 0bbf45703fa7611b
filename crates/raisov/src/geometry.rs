//! Geometry of 3-vectors and surfaces, shared by the meshes, the mesher, the tools and the
//! grasps: vector arithmetic, the nearest point of a triangle, and the surface patch a grasp
//! or a `[[displace]] radius` takes.
//!
//! The surface patch of radius `r` at `point`: `g` is the point of the surface triangles
//! nearest `point` (the first of equally near ones, in the triangles' order); the patch is the
//! surface nodes `a` with `|x_a − g| ≤ r`, and at least the corner of g's triangle nearest g.

#[inline]
/// `a + b`.
pub fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
#[inline]
/// `a − b`.
pub fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline]
/// `s a`.
pub fn mul(a: [f64; 3], s: f64) -> [f64; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}
#[inline]
/// `a · b`.
pub fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
#[inline]
/// `a × b`.
pub fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
#[inline]
/// Euclidean norm `|a|`.
pub fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}
#[inline]
/// `|a − b|²`.
pub fn dist2(a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = sub(a, b);
    dot(d, d)
}

/// The point of triangle `t` nearest `p` (Ericson, *Real-Time Collision Detection*, 5.1.5:
/// the Voronoi regions of the corners, then of the edges, else the face).
pub fn closest_on_triangle(p: [f64; 3], t: &[[f64; 3]; 3]) -> [f64; 3] {
    let [a, b, c] = *t;
    let ab = sub(b, a);
    let ac = sub(c, a);
    let ap = sub(p, a);
    let d1 = dot(ab, ap);
    let d2 = dot(ac, ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = sub(p, b);
    let d3 = dot(ab, bp);
    let d4 = dot(ac, bp);
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return add(a, mul(ab, v));
    }
    let cp = sub(p, c);
    let d5 = dot(ab, cp);
    let d6 = dot(ac, cp);
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return add(a, mul(ac, w));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return add(b, mul(sub(c, b), w));
    }
    let denom = 1.0 / (va + vb + vc);
    let v = vb * denom;
    let w = vc * denom;
    add(a, add(mul(ab, v), mul(ac, w)))
}

/// The surface patch of radius `r` at `point` over the triangles `surface` of the nodes at
/// `x` (module docs): the nearest surface point `g` and the patch's nodes, ascending; `None`
/// without triangles.
pub fn surface_patch(
    x: &[[f64; 3]],
    surface: &[[u32; 3]],
    point: [f64; 3],
    r: f64,
) -> Option<([f64; 3], Vec<u32>)> {
    let mut best: Option<(f64, [f64; 3], [u32; 3])> = None;
    for f in surface {
        let t = [x[f[0] as usize], x[f[1] as usize], x[f[2] as usize]];
        let q = closest_on_triangle(point, &t);
        let d = dist2(q, point);
        if best.is_none_or(|b| d < b.0) {
            best = Some((d, q, *f));
        }
    }
    let (_, g, face) = best?;
    let mut nodes: Vec<u32> = surface
        .iter()
        .flatten()
        .copied()
        .filter(|&a| dist2(x[a as usize], g) <= r * r)
        .collect();
    let nearest = *face
        .iter()
        .min_by(|&&a, &&b| dist2(x[a as usize], g).total_cmp(&dist2(x[b as usize], g)))?;
    nodes.push(nearest);
    nodes.sort_unstable();
    nodes.dedup();
    Some((g, nodes))
}
