//! The surface patch of `[[displace]] radius`: the nodes a grasp of radius `r` at `point`
//! takes, the same selection as [`crate::sim::Simulation::grab`] on the reference
//! configuration. `g` is the point of the surface (the boundary triangles of a tetrahedral
//! mesh, every triangle of a membrane) nearest `point`; the patch is the surface nodes `a`
//! with `|X_a − g| ≤ r`, and at least the corner of g's triangle nearest g.

use crate::mesh::stuffing::distance::closest_on_triangle;
use crate::mesh::{dot, sub, ElementKind, Mesh};

/// The nearest surface point `g` and the patch's nodes (ascending); `None` for a mesh with
/// no surface.
pub(crate) fn surface_patch(mesh: &Mesh, point: [f64; 3], r: f64) -> Option<([f64; 3], Vec<u32>)> {
    let surface: Vec<[u32; 3]> = match mesh.kind {
        ElementKind::Tet4 => mesh.boundary_facets(),
        ElementKind::Tri3 => mesh.elements().map(|e| [e[0], e[1], e[2]]).collect(),
    };
    let x = &mesh.nodes;
    let d2 = |a: [f64; 3], b: [f64; 3]| {
        let d = sub(a, b);
        dot(d, d)
    };
    let mut best: Option<(f64, [f64; 3], [u32; 3])> = None;
    for f in &surface {
        let t = [x[f[0] as usize], x[f[1] as usize], x[f[2] as usize]];
        let q = closest_on_triangle(point, &t);
        let d = d2(q, point);
        if best.is_none_or(|b| d < b.0) {
            best = Some((d, q, *f));
        }
    }
    let (_, g, face) = best?;
    let mut nodes: Vec<u32> = surface
        .iter()
        .flatten()
        .copied()
        .filter(|&a| d2(x[a as usize], g) <= r * r)
        .collect();
    let nearest = *face
        .iter()
        .min_by(|&&a, &&b| d2(x[a as usize], g).total_cmp(&d2(x[b as usize], g)))?;
    nodes.push(nearest);
    nodes.sort_unstable();
    nodes.dedup();
    Some((g, nodes))
}
