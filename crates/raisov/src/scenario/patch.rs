//! The surface patch of `[[displace]] radius`: the nodes a grasp of radius `r` at `point`
//! takes, the same selection as [`crate::sim::Simulation::grab`] on the reference
//! configuration. `g` is the point of the surface (the boundary triangles of a tetrahedral
//! mesh, every triangle of a membrane) nearest `point`; the patch is the surface nodes `a`
//! with `|X_a − g| ≤ r`, and at least the corner of g's triangle nearest g.

use crate::mesh::Mesh;

/// The nearest surface point `g` and the patch's nodes (ascending); `None` for a mesh with
/// no surface ([`crate::geometry::surface_patch`] over [`Mesh::surface_triangles`]).
pub(crate) fn surface_patch(mesh: &Mesh, point: [f64; 3], r: f64) -> Option<([f64; 3], Vec<u32>)> {
    crate::geometry::surface_patch(&mesh.nodes, &mesh.surface_triangles(), point, r)
}
