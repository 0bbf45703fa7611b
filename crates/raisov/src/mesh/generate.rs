//! Built-in mesh generators: quality triangulations of polygons (membranes in the z = 0 plane)
//! and structured boxes of linear tetrahedra.
//!
//! * [`polygon_membrane`] / [`rectangle_membrane`]: constrained Delaunay triangulation with
//!   Ruppert-style refinement (via `spade`) at a uniform target size. The outline is first
//!   split evenly at a spacing `h`; the interior is refined with a maximum triangle area
//!   proportional to `h^2` and a minimum angle of [`MIN_ANGLE_DEG`]. `h` is searched (secant
//!   steps in log-log, safeguarded by a bracket) so that the node count is close to the
//!   requested one, typically within 1-2 % and always the closest count the search met.
//! * [`box_tets`] / [`box_tets_target`]: a structured grid of cubes (bricks) cut into 6
//!   (Kuhn/Freudenthal) or 5 (alternating) tetrahedra; both patterns are conforming.
//! * [`cone_surface`]: a closed cone whose side and base are fans of long thin triangles (a
//!   triangle surface, the shape CAD caps take).
//!
//! Every generator is deterministic: the same arguments give bit-identical meshes. Membrane
//! triangles are oriented with normal +z, tetrahedra are positive, surfaces outward.
//!
//! One concern, the built-in generators; about a third of the file is their tests.

use std::collections::BTreeMap;

use spade::{
    AngleLimit, ConstrainedDelaunayTriangulation, Point2, RefinementParameters, Triangulation,
};

use super::{cross, norm, ElementKind, Mesh, Surface};
use crate::{Error, Result};

/// Minimum angle (degrees) asked of the Delaunay refinement of membranes. Triangles keep it
/// except at polygon corners whose input angle is smaller.
pub const MIN_ANGLE_DEG: f64 = 28.0;

/// Largest node count the generators accept (ids are `u32`, and memory is finite).
pub const MAX_NODES: usize = 100_000_000;

/// Bytes a membrane node may take while it is generated (the triangulation's vertex, about
/// six half-edges and two faces, the mesh's node and triangles), with room to spare.
pub const MEMBRANE_NODE_BYTES: u64 = 512;

/// Bytes a box node may take while it is generated (its coordinates, five or six
/// tetrahedra, the groups), with room to spare.
pub const BOX_NODE_BYTES: u64 = 256;

/// A generator's memory, checked against the available memory before it allocates: an error
/// on `param` naming the mesh, its node count and both sizes.
fn generator_memory(param: &str, what: &str, nodes: u128, bytes_per_node: u64) -> Result<()> {
    let bytes = u64::try_from(nodes.saturating_mul(bytes_per_node as u128)).unwrap_or(u64::MAX);
    crate::memory::check_for(
        &format!("generating {what} of {nodes} nodes"),
        bytes,
        "ask for fewer nodes",
    )
    .map_err(|e| Error::param(param, e))
}

/// Ratio of the refinement's maximum triangle area to the area `sqrt(3)/4 h^2` of the
/// equilateral triangle with the boundary spacing `h`. Refinement leaves triangles between a
/// quarter and all of the bound, so a bound above the equilateral area gives interior edges
/// about as long as the boundary ones.
const AREA_FACTOR: f64 = 1.6;

// ---------------------------------------------------------------------------------------------
// Membranes
// ---------------------------------------------------------------------------------------------

/// Quality triangulation of the simple polygon `polygon` (vertices in order, clockwise or
/// counter-clockwise, not repeated at the end) in the z = 0 plane with about `target_nodes`
/// nodes of uniform size.
///
/// Groups: `"boundary"` (every node of the outline) and `"edge{i}"` for the polygon edge from
/// `polygon[i]` to `polygon[(i + 1) % n]` (its end corners included).
///
/// Errors: fewer than 3 vertices, non-finite coordinates, repeated consecutive vertices, zero
/// area, a self-intersecting or self-touching outline, `target_nodes` below 3 or below the
/// number of polygon vertices, or above [`MAX_NODES`].
pub fn polygon_membrane(polygon: &[[f64; 2]], target_nodes: usize) -> Result<Mesh> {
    validate_polygon(polygon)?;
    let n = polygon.len();
    if target_nodes < 3 || target_nodes < n {
        return Err(Error::param(
            "nodes",
            format!(
                "{target_nodes} is too few: need at least 3 and at least the {n} polygon vertices"
            ),
        ));
    }
    if target_nodes > MAX_NODES {
        return Err(Error::param(
            "nodes",
            format!("{target_nodes} exceeds the maximum of {MAX_NODES}"),
        ));
    }
    generator_memory(
        "nodes",
        "a membrane",
        target_nodes as u128,
        MEMBRANE_NODE_BYTES,
    )?;
    let area = polygon_area(polygon).abs();
    let perimeter: f64 = (0..n)
        .map(|i| dist2(polygon[i], polygon[(i + 1) % n]))
        .sum();

    // Spacing from the count of a hexagonal lattice: N = A / (sqrt(3)/2 h^2) + P / (2h) + 1.
    let t = target_nodes as f64;
    let a = t - 1.0;
    let b = perimeter / 2.0;
    let c = area * 2.0 / 3f64.sqrt();
    // a x^2 - b x - c = 0 with x = 1/h.
    let x = (b + (b * b + 4.0 * a * c).sqrt()) / (2.0 * a);
    let mut h = 1.0 / x;

    let tol = (0.01 * t).floor() as usize;
    let budget = 16.0 * t + 40_000.0;
    let mut spent = 0.0;
    let mut best: Option<(usize, RawTri)> = None;
    let mut below: Option<(f64, usize)> = None; // largest h with too many nodes
    let mut above: Option<(f64, usize)> = None; // smallest h with too few nodes
    let mut last: Option<(f64, usize)> = None;
    for _ in 0..40 {
        let raw = triangulate(polygon, h, target_nodes)?;
        let count = raw.nodes.len();
        spent += count as f64;
        let err = count.abs_diff(target_nodes);
        let better = match &best {
            None => true,
            Some((e, r)) => {
                (raw.complete && !r.complete) || (raw.complete == r.complete && err < *e)
            }
        };
        let complete = raw.complete;
        if better {
            best = Some((err, raw));
        }
        if complete && err <= tol {
            break;
        }
        if spent > budget {
            break;
        }
        if count > target_nodes || !complete {
            if below.is_none_or(|(hb, _)| h > hb) {
                below = Some((h, count));
            }
        } else if above.is_none_or(|(ha, _)| h < ha) {
            above = Some((h, count));
        }
        // Secant step in log-log, slope clamped to [1, 3] (2 for a pure area scaling).
        let mut slope = 2.0;
        if let Some((hl, nl)) = last {
            if hl != h && nl != count && complete {
                let s = -((count as f64).ln() - (nl as f64).ln()) / (h.ln() - hl.ln());
                if s.is_finite() {
                    slope = s.clamp(1.0, 3.0);
                }
            }
        }
        last = Some((h, count));
        let mut next = h * ((count as f64) / t).powf(1.0 / slope);
        if let (Some((hb, _)), Some((ha, _))) = (below, above) {
            // Keep strictly inside the bracket, else bisect it geometrically.
            if !(next > hb && next < ha) || next == h {
                next = (hb * ha).sqrt();
            }
            if ha / hb < 1.0 + 1e-9 {
                break;
            }
        }
        h = next;
    }
    let raw = match best {
        Some((_, raw)) if raw.complete => raw,
        _ => {
            return Err(Error::param(
                "polygon",
                "Delaunay refinement did not converge (very small corner angles?)",
            ))
        }
    };
    Ok(raw.into_mesh(n))
}

/// Quality triangulation of the rectangle `[-width/2, width/2] x [-height/2, height/2]` in the
/// z = 0 plane with about `target_nodes` nodes (see [`polygon_membrane`]).
///
/// Groups: `"boundary"`, `"edge0"`..`"edge3"` (bottom, right, top, left) and the same sides as
/// `"ymin"`, `"xmax"`, `"ymax"`, `"xmin"`.
pub fn rectangle_membrane(width: f64, height: f64, target_nodes: usize) -> Result<Mesh> {
    for (name, v) in [("width", width), ("height", height)] {
        if !(v.is_finite() && v > 0.0) {
            return Err(Error::param(
                name,
                format!("must be finite and positive, got {v}"),
            ));
        }
    }
    let (w, h) = (0.5 * width, 0.5 * height);
    let mut mesh = polygon_membrane(&[[-w, -h], [w, -h], [w, h], [-w, h]], target_nodes)?;
    for (edge, side) in [
        ("edge0", "ymin"),
        ("edge1", "xmax"),
        ("edge2", "ymax"),
        ("edge3", "xmin"),
    ] {
        let nodes = mesh.groups[edge].clone();
        mesh.groups.insert(side.to_string(), nodes);
    }
    Ok(mesh)
}

/// Twice the signed area of a polygon is `sum x_i y_{i+1} - x_{i+1} y_i`; this is the area.
fn polygon_area(p: &[[f64; 2]]) -> f64 {
    let n = p.len();
    let s: f64 = (0..n)
        .map(|i| {
            let (a, b) = (p[i], p[(i + 1) % n]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum();
    0.5 * s
}

fn dist2(a: [f64; 2], b: [f64; 2]) -> f64 {
    (b[0] - a[0]).hypot(b[1] - a[1])
}

/// Sign of the turn a -> b -> c (positive counter-clockwise).
fn orient2(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// Whether c, known collinear with segment ab, lies within its bounding box.
fn on_segment(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> bool {
    c[0] >= a[0].min(b[0])
        && c[0] <= a[0].max(b[0])
        && c[1] >= a[1].min(b[1])
        && c[1] <= a[1].max(b[1])
}

/// Whether the closed segments ab and cd share a point.
fn segments_intersect(a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2]) -> bool {
    let d1 = orient2(c, d, a);
    let d2 = orient2(c, d, b);
    let d3 = orient2(a, b, c);
    let d4 = orient2(a, b, d);
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
    {
        return true;
    }
    (d1 == 0.0 && on_segment(c, d, a))
        || (d2 == 0.0 && on_segment(c, d, b))
        || (d3 == 0.0 && on_segment(a, b, c))
        || (d4 == 0.0 && on_segment(a, b, d))
}

/// Checks that `p` is a simple polygon with non-zero area.
fn validate_polygon(p: &[[f64; 2]]) -> Result<()> {
    let n = p.len();
    if n < 3 {
        return Err(Error::param(
            "polygon",
            format!("needs at least 3 vertices, got {n}"),
        ));
    }
    if let Some(i) = p
        .iter()
        .position(|v| !(v[0].is_finite() && v[1].is_finite()))
    {
        return Err(Error::param(
            "polygon",
            format!("vertex {i} is not finite: {:?}", p[i]),
        ));
    }
    for i in 0..n {
        if p[i] == p[(i + 1) % n] {
            return Err(Error::param(
                "polygon",
                format!("vertices {i} and {} coincide", (i + 1) % n),
            ));
        }
    }
    let area = polygon_area(p);
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for v in p {
        for k in 0..2 {
            lo[k] = lo[k].min(v[k]);
            hi[k] = hi[k].max(v[k]);
        }
    }
    let diag = (hi[0] - lo[0]).hypot(hi[1] - lo[1]);
    if area.abs() <= 1e-12 * diag * diag {
        return Err(Error::param("polygon", "has zero area"));
    }
    // Adjacent edges may only share their common vertex: no fold-back onto each other.
    for i in 0..n {
        let (a, b, c) = (p[(i + n - 1) % n], p[i], p[(i + 1) % n]);
        let ab = [b[0] - a[0], b[1] - a[1]];
        let bc = [c[0] - b[0], c[1] - b[1]];
        if orient2(a, b, c) == 0.0 && ab[0] * bc[0] + ab[1] * bc[1] < 0.0 {
            return Err(Error::param(
                "polygon",
                format!("is self-intersecting: edges at vertex {i} fold back onto each other"),
            ));
        }
    }
    // Non-adjacent edges must not touch at all.
    for i in 0..n {
        let (a, b) = (p[i], p[(i + 1) % n]);
        let (blo, bhi) = (
            [a[0].min(b[0]), a[1].min(b[1])],
            [a[0].max(b[0]), a[1].max(b[1])],
        );
        for j in i + 2..n {
            if i == 0 && j == n - 1 {
                continue;
            }
            let (c, d) = (p[j], p[(j + 1) % n]);
            if c[0].max(d[0]) < blo[0]
                || c[0].min(d[0]) > bhi[0]
                || c[1].max(d[1]) < blo[1]
                || c[1].min(d[1]) > bhi[1]
            {
                continue;
            }
            if segments_intersect(a, b, c, d) {
                return Err(Error::param(
                    "polygon",
                    format!("is self-intersecting: edges {i} and {j} intersect"),
                ));
            }
        }
    }
    Ok(())
}

/// A triangulation of the polygon before it becomes a [`Mesh`].
struct RawTri {
    nodes: Vec<[f64; 3]>,
    cells: Vec<u32>,
    /// Node id of each polygon corner.
    corners: Vec<u32>,
    /// Refinement finished within its vertex budget.
    complete: bool,
}

/// Splits the outline at spacing about `h` and refines the interior to the matching area.
fn triangulate(polygon: &[[f64; 2]], h: f64, target_nodes: usize) -> Result<RawTri> {
    let n = polygon.len();
    let mut cdt = ConstrainedDelaunayTriangulation::<Point2<f64>>::new();
    let insert_err = |e: spade::InsertionError| Error::param("polygon", format!("{e:?}"));
    // Corners first (spade vertex ids 0..n), then the points splitting each edge.
    let mut corner = Vec::with_capacity(n);
    for v in polygon {
        corner.push(cdt.insert(Point2::new(v[0], v[1])).map_err(insert_err)?);
    }
    if cdt.num_vertices() != n {
        return Err(Error::param("polygon", "has repeated vertices"));
    }
    for i in 0..n {
        let (a, b) = (polygon[i], polygon[(i + 1) % n]);
        let k = ((dist2(a, b) / h).round() as usize).clamp(1, 4 * MAX_NODES);
        let mut prev = corner[i];
        for s in 1..k {
            let t = s as f64 / k as f64;
            let p = Point2::new(a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]));
            let v = cdt.insert(p).map_err(insert_err)?;
            cdt.add_constraint(prev, v);
            prev = v;
        }
        cdt.add_constraint(prev, corner[(i + 1) % n]);
    }
    let max_area = AREA_FACTOR * 3f64.sqrt() / 4.0 * h * h;
    let limit = 4 * target_nodes + 1000;
    let result = cdt.refine(
        RefinementParameters::<f64>::new()
            .exclude_outer_faces(true)
            .with_angle_limit(AngleLimit::from_deg(MIN_ANGLE_DEG))
            .with_max_allowed_area(max_area)
            .with_max_additional_vertices(limit.saturating_sub(cdt.num_vertices())),
    );
    let mut outer = vec![false; cdt.num_all_faces()];
    for f in &result.excluded_faces {
        outer[f.index()] = true;
    }
    let mut id = vec![u32::MAX; cdt.num_vertices()];
    let mut nodes = Vec::new();
    let mut cells = Vec::new();
    for face in cdt.inner_faces() {
        if outer[face.fix().index()] {
            continue;
        }
        let vs = face.vertices();
        let p = vs.map(|v| v.position());
        let ccw = (p[1].x - p[0].x) * (p[2].y - p[0].y) - (p[1].y - p[0].y) * (p[2].x - p[0].x);
        let order = if ccw >= 0.0 { [0, 1, 2] } else { [0, 2, 1] };
        for k in order {
            let vi = vs[k].fix().index();
            if id[vi] == u32::MAX {
                id[vi] = 0; // mark used; numbered below in vertex order
            }
            cells.push(vi as u32);
        }
    }
    // Number used vertices in spade's (insertion) order.
    for v in cdt.vertices() {
        let vi = v.fix().index();
        if id[vi] != u32::MAX {
            id[vi] = nodes.len() as u32;
            let p = v.position();
            nodes.push([p.x, p.y, 0.0]);
        }
    }
    for c in &mut cells {
        *c = id[*c as usize];
    }
    let corners = corner.iter().map(|v| id[v.index()]).collect();
    Ok(RawTri {
        nodes,
        cells,
        corners,
        complete: result.refinement_complete,
    })
}

impl RawTri {
    /// The mesh, with groups found by walking the outline from corner to corner.
    fn into_mesh(self, n_corners: usize) -> Mesh {
        let mut mesh = Mesh::new(ElementKind::Tri3, self.nodes, self.cells);
        // Outline adjacency: each boundary node has exactly two boundary neighbours.
        let nn = mesh.nodes.len();
        let mut nbr = vec![[u32::MAX; 2]; nn];
        for f in mesh.boundary_facets() {
            for (a, b) in [(f[0], f[1]), (f[1], f[0])] {
                let slot = &mut nbr[a as usize];
                if slot[0] == u32::MAX {
                    slot[0] = b;
                } else {
                    slot[1] = b;
                }
            }
        }
        let mut is_corner = vec![usize::MAX; nn];
        for (i, &c) in self.corners.iter().enumerate() {
            if c != u32::MAX {
                is_corner[c as usize] = i;
            }
        }
        let mut boundary: Vec<u32> = (0..nn as u32)
            .filter(|&v| nbr[v as usize][0] != u32::MAX)
            .collect();
        boundary.sort_unstable();
        // Walk from corner 0 in the direction whose first corner is corner 1.
        let start = self.corners[0];
        let walk = |first: u32| -> Vec<u32> {
            let mut path = vec![start];
            let (mut prev, mut cur) = (start, first);
            while cur != start && cur != u32::MAX && path.len() <= nn {
                path.push(cur);
                let nb = nbr[cur as usize];
                let next = if nb[0] == prev { nb[1] } else { nb[0] };
                prev = cur;
                cur = next;
            }
            path
        };
        let first_corner = |path: &[u32]| {
            path[1..]
                .iter()
                .find(|&&v| is_corner[v as usize] != usize::MAX)
                .map(|&v| is_corner[v as usize])
        };
        let mut path = walk(nbr[start as usize][0]);
        if first_corner(&path) != Some(1 % n_corners) {
            path = walk(nbr[start as usize][1]);
        }
        let mut edges: Vec<Vec<u32>> = vec![Vec::new(); n_corners];
        let mut edge = 0;
        for &v in &path {
            edges[edge].push(v);
            let c = is_corner[v as usize];
            if c != usize::MAX && v != start {
                edge = c;
                edges[edge].push(v);
            }
        }
        edges[n_corners - 1].push(start);
        let mut groups = BTreeMap::new();
        groups.insert("boundary".to_string(), boundary);
        for (i, mut e) in edges.into_iter().enumerate() {
            e.sort_unstable();
            e.dedup();
            groups.insert(format!("edge{i}"), e);
        }
        mesh.groups = groups;
        mesh
    }
}

// ---------------------------------------------------------------------------------------------
// Boxes of tetrahedra
// ---------------------------------------------------------------------------------------------

/// How each cube (brick) of a structured box is cut into tetrahedra.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BoxPattern {
    /// 6 tetrahedra around the main diagonal (Kuhn / Freudenthal); every cube is cut the same
    /// way, which is conforming.
    Six,
    /// 5 tetrahedra: a central one and four corners; the pattern is mirrored on alternate
    /// cubes (checkerboard by `i + j + k`) so the face diagonals of neighbours agree.
    Five,
}

impl BoxPattern {
    /// Tetrahedra per cube.
    pub const fn tets_per_cube(self) -> usize {
        match self {
            BoxPattern::Six => 6,
            BoxPattern::Five => 5,
        }
    }
}

/// Local corner `bits = x + 2 y + 4 z` of a unit cube.
const fn corner(x: usize, y: usize, z: usize) -> usize {
    x + 2 * y + 4 * z
}

/// Kuhn: one tet per axis permutation, the path 000 -> e_a -> e_a + e_b -> 111.
const KUHN: [[usize; 4]; 6] = {
    let perms = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    let mut out = [[0; 4]; 6];
    let mut i = 0;
    while i < 6 {
        let a = 1 << perms[i][0];
        let b = a | (1 << perms[i][1]);
        out[i] = [0, a, b, 7];
        i += 1;
    }
    out
};

/// Five tets of an "even" cube: central tet on corners 000, 110, 101, 011 and the four others.
const FIVE_EVEN: [[usize; 4]; 5] = [
    [
        corner(0, 0, 0),
        corner(1, 1, 0),
        corner(1, 0, 1),
        corner(0, 1, 1),
    ],
    [
        corner(1, 0, 0),
        corner(0, 0, 0),
        corner(1, 1, 0),
        corner(1, 0, 1),
    ],
    [
        corner(0, 1, 0),
        corner(0, 0, 0),
        corner(1, 1, 0),
        corner(0, 1, 1),
    ],
    [
        corner(0, 0, 1),
        corner(0, 0, 0),
        corner(1, 0, 1),
        corner(0, 1, 1),
    ],
    [
        corner(1, 1, 1),
        corner(1, 1, 0),
        corner(1, 0, 1),
        corner(0, 1, 1),
    ],
];

/// Mirror in x of a local corner.
const fn mirror_x(c: usize) -> usize {
    c ^ 1
}

/// Orients a local tet positively (swap the last two corners if its volume is negative).
fn positive(t: [usize; 4]) -> [usize; 4] {
    let p = |c: usize| [(c & 1) as i64, ((c >> 1) & 1) as i64, ((c >> 2) & 1) as i64];
    let (a, b, c, d) = (p(t[0]), p(t[1]), p(t[2]), p(t[3]));
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let w = [d[0] - a[0], d[1] - a[1], d[2] - a[2]];
    let det = u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
        + u[2] * (v[0] * w[1] - v[1] * w[0]);
    if det < 0 {
        [t[0], t[1], t[3], t[2]]
    } else {
        t
    }
}

/// Structured box `[0, sx] x [0, sy] x [0, sz]` with `divisions` cells per axis, each cut
/// into tetrahedra by `pattern`. Nodes are numbered x fastest, then y, then z:
/// `i + (nx + 1) (j + (ny + 1) k)`.
///
/// Groups: `"boundary"`, `"xmin"`, `"xmax"`, `"ymin"`, `"ymax"`, `"zmin"`, `"zmax"`.
///
/// Errors: a side not finite and positive, a zero division, or more than [`MAX_NODES`] nodes.
pub fn box_tets(size: [f64; 3], divisions: [usize; 3], pattern: BoxPattern) -> Result<Mesh> {
    for (k, &s) in size.iter().enumerate() {
        if !(s.is_finite() && s > 0.0) {
            return Err(Error::param(
                "size",
                format!("side {k} must be finite and positive, got {s}"),
            ));
        }
    }
    if divisions.contains(&0) {
        return Err(Error::param(
            "divisions",
            format!("must all be at least 1, got {divisions:?}"),
        ));
    }
    let [nx, ny, nz] = divisions;
    let count = (nx as u128 + 1) * (ny as u128 + 1) * (nz as u128 + 1);
    if count > MAX_NODES as u128 {
        return Err(Error::param(
            "divisions",
            format!("{divisions:?} gives {count} nodes, more than {MAX_NODES}"),
        ));
    }
    generator_memory("divisions", "a box", count, BOX_NODE_BYTES)?;
    let coords = |n: usize, s: f64| -> Vec<f64> {
        (0..=n)
            .map(|i| if i == n { s } else { i as f64 * s / n as f64 })
            .collect()
    };
    let (xs, ys, zs) = (
        coords(nx, size[0]),
        coords(ny, size[1]),
        coords(nz, size[2]),
    );
    let (px, py) = (nx + 1, ny + 1);
    let mut nodes = Vec::with_capacity(count as usize);
    for &z in &zs {
        for &y in &ys {
            for &x in &xs {
                nodes.push([x, y, z]);
            }
        }
    }
    let id = |i: usize, j: usize, k: usize| (i + px * (j + py * k)) as u32;

    let six: Vec<[usize; 4]> = KUHN.iter().map(|&t| positive(t)).collect();
    let five_even: Vec<[usize; 4]> = FIVE_EVEN.iter().map(|&t| positive(t)).collect();
    let five_odd: Vec<[usize; 4]> = FIVE_EVEN
        .iter()
        .map(|t| positive(t.map(mirror_x)))
        .collect();
    let per = pattern.tets_per_cube();
    let mut cells = Vec::with_capacity(nx * ny * nz * per * 4);
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let local = |c: usize| id(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1));
                let tets = match pattern {
                    BoxPattern::Six => &six,
                    BoxPattern::Five if (i + j + k) % 2 == 0 => &five_even,
                    BoxPattern::Five => &five_odd,
                };
                for t in tets {
                    cells.extend(t.iter().map(|&c| local(c)));
                }
            }
        }
    }

    let mut groups = BTreeMap::new();
    let face = |fix: usize, at: usize| -> Vec<u32> {
        let mut v = Vec::new();
        for k in 0..=nz {
            for j in 0..=ny {
                for i in 0..=nx {
                    if [i, j, k][fix] == at {
                        v.push(id(i, j, k));
                    }
                }
            }
        }
        v
    };
    for (axis, name) in ["x", "y", "z"].iter().enumerate() {
        groups.insert(format!("{name}min"), face(axis, 0));
        groups.insert(format!("{name}max"), face(axis, divisions[axis]));
    }
    let mut boundary: Vec<u32> = Vec::new();
    for k in 0..=nz {
        for j in 0..=ny {
            for i in 0..=nx {
                if i == 0 || i == nx || j == 0 || j == ny || k == 0 || k == nz {
                    boundary.push(id(i, j, k));
                }
            }
        }
    }
    groups.insert("boundary".to_string(), boundary);
    let mut mesh = Mesh::new(ElementKind::Tet4, nodes, cells);
    mesh.groups = groups;
    Ok(mesh)
}

/// Closed right circular cone as a triangle [`Surface`]: base centre at the origin, apex at
/// `height · axis/|axis|`, rim of `segments` vertices at `radius`. The side is a fan of
/// `segments` triangles around the apex and the base a fan of `segments` triangles around its
/// centre: long thin triangles meeting at two vertices of valence `segments`, as CAD exports
/// write the caps of cylinders and cones. Vertices: 0 the apex, 1 the base centre, `2 + i`
/// the rim vertex at angle `2π i / segments`; triangles: `i` the side triangle
/// `(rim i, rim i+1, apex)`, `segments + i` the base triangle `(rim i+1, rim i, centre)`;
/// all outward.
///
/// Errors: fewer than 3 or more than [`MAX_NODES`] segments, more than the available memory,
/// a radius or height not finite and positive, an axis not finite and non-zero.
pub fn cone_surface(segments: usize, radius: f64, height: f64, axis: [f64; 3]) -> Result<Surface> {
    if !(3..=MAX_NODES).contains(&segments) {
        return Err(Error::param(
            "segments",
            format!("{segments}: valid are 3 to {MAX_NODES}"),
        ));
    }
    for (key, v) in [("radius", radius), ("height", height)] {
        if !(v.is_finite() && v > 0.0) {
            return Err(Error::param(
                key,
                format!("{v}: must be finite and positive"),
            ));
        }
    }
    let len = norm(axis);
    if !(len.is_finite() && len > 0.0) {
        return Err(Error::param(
            "axis",
            format!("{axis:?}: must be finite and non-zero"),
        ));
    }
    // A rim vertex: its point and two triangles.
    generator_memory("segments", "a cone", segments as u128 + 2, 24 + 2 * 12)?;
    let w = axis.map(|c| c / len);
    // e1, e2, w right-handed: e1 across the coordinate axis least aligned with w.
    let k = (0..3)
        .min_by(|&a, &b| w[a].abs().total_cmp(&w[b].abs()))
        .unwrap_or(0);
    let mut ek = [0.0; 3];
    ek[k] = 1.0;
    let e1 = cross(w, ek);
    let e1 = e1.map(|c| c / norm(e1));
    let e2 = cross(w, e1);
    let mut points = Vec::with_capacity(segments + 2);
    points.push(w.map(|c| height * c));
    points.push([0.0; 3]);
    for i in 0..segments {
        let t = std::f64::consts::TAU * i as f64 / segments as f64;
        let (s, c) = t.sin_cos();
        points.push([0, 1, 2].map(|j| radius * (c * e1[j] + s * e2[j])));
    }
    let rim = |i: usize| (2 + i % segments) as u32;
    let mut triangles = Vec::with_capacity(2 * segments);
    triangles.extend((0..segments).map(|i| [rim(i), rim(i + 1), 0]));
    triangles.extend((0..segments).map(|i| [rim(i + 1), rim(i), 1]));
    Ok(Surface { points, triangles })
}

/// Divisions for [`box_tets_target`]: cells as close to cubes as the count allows, with
/// `(nx + 1)(ny + 1)(nz + 1)` nearest to `target_nodes`.
pub fn box_divisions_for_target(size: [f64; 3], target_nodes: usize) -> Result<[usize; 3]> {
    for (k, &s) in size.iter().enumerate() {
        if !(s.is_finite() && s > 0.0) {
            return Err(Error::param(
                "size",
                format!("side {k} must be finite and positive, got {s}"),
            ));
        }
    }
    if !(8..=MAX_NODES).contains(&target_nodes) {
        return Err(Error::param(
            "nodes",
            format!("must be between 8 and {MAX_NODES}, got {target_nodes}"),
        ));
    }
    let t = target_nodes as f64;
    let count = |h: f64| -> f64 { size.iter().map(|&s| (s / h).max(1.0) + 1.0).product() };
    // Continuous cell size h with prod(max(s/h, 1) + 1) = target: bisection in log h.
    let smax = size.iter().fold(0.0f64, |a, &b| a.max(b));
    let (mut lo, mut hi) = (smax / t, smax); // count(lo) >= t, count(hi) = 8 <= t
    for _ in 0..200 {
        let mid = (lo * hi).sqrt();
        if count(mid) > t {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let h = (lo * hi).sqrt();
    // Try floor/ceil (+-1) per axis; within 3 % of the target prefer the most cube-like cells,
    // else the nearest count.
    let cand = |s: f64| -> Vec<usize> {
        let x = s / h;
        let f = x.floor().max(1.0) as usize;
        let mut v: Vec<usize> = [f.saturating_sub(1), f, f + 1, f + 2]
            .into_iter()
            .filter(|&n| n >= 1)
            .collect();
        v.dedup();
        v
    };
    let (cx, cy, cz) = (cand(size[0]), cand(size[1]), cand(size[2]));
    let mut best: Option<([usize; 3], bool, f64, f64)> = None;
    for &nx in &cx {
        for &ny in &cy {
            for &nz in &cz {
                let n = [nx, ny, nz];
                let nodes = n.iter().map(|&d| d as f64 + 1.0).product::<f64>();
                let err = (nodes / t).ln().abs();
                let d: Vec<f64> = (0..3).map(|a| size[a] / n[a] as f64).collect();
                let dmax = d.iter().fold(0.0f64, |a, &b| a.max(b));
                let dmin = d.iter().fold(f64::INFINITY, |a, &b| a.min(b));
                let aspect = dmax / dmin;
                let close = err <= 0.03f64.ln_1p();
                let key_better = match &best {
                    None => true,
                    Some((_, bclose, berr, baspect)) => match (close, *bclose) {
                        (true, false) => true,
                        (false, true) => false,
                        (true, true) => aspect < *baspect || (aspect == *baspect && err < *berr),
                        (false, false) => err < *berr || (err == *berr && aspect < *baspect),
                    },
                };
                if key_better {
                    best = Some((n, close, err, aspect));
                }
            }
        }
    }
    Ok(best.map(|b| b.0).unwrap_or([1, 1, 1]))
}

/// Structured box `[0, sx] x [0, sy] x [0, sz]` with about `target_nodes` nodes, divisions
/// proportional to the sides (see [`box_divisions_for_target`] and [`box_tets`]).
///
/// Errors: a side not finite and positive, `target_nodes` below 8 or above [`MAX_NODES`].
pub fn box_tets_target(size: [f64; 3], target_nodes: usize, pattern: BoxPattern) -> Result<Mesh> {
    let divisions = box_divisions_for_target(size, target_nodes)?;
    // The user gave `nodes`, not the divisions derived from it: name that key.
    box_tets(size, divisions, pattern).map_err(|e| match e {
        Error::Param { name, msg } if name == "divisions" => Error::Param {
            name: "nodes".into(),
            msg: format!("{target_nodes} nodes take divisions {divisions:?}: {msg}"),
        },
        e => e,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{cross, sub};

    fn min_quality(m: &Mesh) -> f64 {
        (0..m.num_elements())
            .map(|e| m.element_quality(e))
            .fold(f64::INFINITY, f64::min)
    }

    fn within(count: usize, target: usize, rel: f64) -> bool {
        (count as f64 - target as f64).abs() <= rel * target as f64
    }

    /// Distance from p to the segment ab.
    fn seg_dist(p: [f64; 3], a: [f64; 2], b: [f64; 2]) -> f64 {
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let t = (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / (dx * dx + dy * dy)).clamp(0.0, 1.0);
        (p[0] - a[0] - t * dx).hypot(p[1] - a[1] - t * dy)
    }

    /// Everything a membrane of `polygon` must satisfy.
    fn check_membrane(m: &Mesh, polygon: &[[f64; 2]], qmin: f64) {
        assert_eq!(m.kind, ElementKind::Tri3);
        let area = polygon_area(polygon).abs();
        assert!(
            (m.total_measure() - area).abs() <= 1e-12 * area,
            "area {} vs {area}",
            m.total_measure()
        );
        assert!(m.used_nodes().iter().all(|&u| u));
        assert!(m.nodes.iter().all(|p| p[2] == 0.0));
        for e in 0..m.num_elements() {
            let p = m.element_points(e);
            assert!(
                cross(sub(p[1], p[0]), sub(p[2], p[0]))[2] > 0.0,
                "element {e} not +z"
            );
            assert!(!m.element_is_degenerate(e));
        }
        let q = min_quality(m);
        assert!(q >= qmin, "min quality {q} < {qmin}");
        // Conforming: every edge in one or two triangles; boundary = outline.
        assert_eq!(m.groups["boundary"], m.boundary_nodes());
        let n = polygon.len();
        let diag = {
            let (lo, hi) = m.bounding_box();
            (hi[0] - lo[0]).hypot(hi[1] - lo[1])
        };
        let mut union = Vec::new();
        for i in 0..n {
            let (a, b) = (polygon[i], polygon[(i + 1) % n]);
            let g = &m.groups[&format!("edge{i}")];
            assert!(g.windows(2).all(|w| w[0] < w[1]));
            for &v in g {
                assert!(seg_dist(m.nodes[v as usize], a, b) <= 1e-12 * diag);
            }
            // Every boundary node on this edge is in the group, both corners included.
            let on: Vec<u32> = m.groups["boundary"]
                .iter()
                .copied()
                .filter(|&v| seg_dist(m.nodes[v as usize], a, b) <= 1e-12 * diag)
                .collect();
            assert_eq!(g, &on, "edge{i}");
            for c in [a, b] {
                assert!(g.iter().any(|&v| {
                    let p = m.nodes[v as usize];
                    p[0] == c[0] && p[1] == c[1]
                }));
            }
            union.extend_from_slice(g);
        }
        union.sort_unstable();
        union.dedup();
        assert_eq!(union, m.groups["boundary"]);
    }

    #[test]
    fn box_target_errors_name_the_nodes_key_not_the_divisions() {
        // A slab so thin that the node target needs more nodes than allowed along its plane.
        let e = box_tets_target([1.0, 1.0, 1e-9], MAX_NODES, BoxPattern::Six).unwrap_err();
        let text = e.to_string();
        assert!(
            matches!(&e, Error::Param { name, .. } if name == "nodes"),
            "{text}"
        );
        assert!(text.contains("more than 100000000"), "{text}");
    }

    #[test]
    fn paper_membrane_levels() {
        // The paper's 10 cm membrane: four levels of about 186, 103, 55 and 31 nodes.
        let square = [[-0.05, -0.05], [0.05, -0.05], [0.05, 0.05], [-0.05, 0.05]];
        for t in [186, 103, 55, 31] {
            let m = rectangle_membrane(0.1, 0.1, t).unwrap();
            assert!(within(m.num_nodes(), t, 0.1), "{t}: {}", m.num_nodes());
            check_membrane(&m, &square, 0.55);
            let c = m.nearest_node([0.0, 0.0, 0.0]).unwrap() as u32;
            assert!(m.groups["boundary"].binary_search(&c).is_err());
            assert_eq!(m.groups["xmin"], m.groups["edge3"]);
            assert!(m.groups["xmin"]
                .iter()
                .all(|&v| m.nodes[v as usize][0] == -0.05));
            // Euler for a disc: T = 2N - B - 2.
            assert_eq!(
                m.num_elements(),
                2 * m.num_nodes() - m.groups["boundary"].len() - 2
            );
        }
    }

    #[test]
    fn membrane_node_counts_follow_target() {
        for t in [3000, 10000] {
            let m = rectangle_membrane(0.1, 0.05, t).unwrap();
            assert!(within(m.num_nodes(), t, 0.1), "{t}: {}", m.num_nodes());
            assert!(within(m.num_nodes(), t, 0.02), "{t}: {}", m.num_nodes());
            check_membrane(
                &m,
                &[
                    [-0.05, -0.025],
                    [0.05, -0.025],
                    [0.05, 0.025],
                    [-0.05, 0.025],
                ],
                0.55,
            );
        }
    }

    #[test]
    fn clockwise_l_shape() {
        // Clockwise, non-convex, with a collinear vertex (edges 0 and 1 in line).
        let l = [
            [0.0, 0.0],
            [0.0, 1.0],
            [0.0, 2.0],
            [1.0, 2.0],
            [1.0, 1.0],
            [2.0, 1.0],
            [2.0, 0.0],
        ];
        assert!(polygon_area(&l) < 0.0);
        for t in [40, 500, 2000] {
            let m = polygon_membrane(&l, t).unwrap();
            assert!(within(m.num_nodes(), t, 0.1), "{t}: {}", m.num_nodes());
            check_membrane(&m, &l, 0.55);
        }
    }

    #[test]
    fn sharp_polygon() {
        // A 10-degree spike: quality is limited at the spike, the rest must still hold.
        let a = 10f64.to_radians();
        let p = [[0.0, 0.0], [3.0, 0.0], [3.0, 3.0 * a.tan()], [0.0, 0.0001]];
        let m = polygon_membrane(&p, 800).unwrap();
        assert!(within(m.num_nodes(), 800, 0.1), "{}", m.num_nodes());
        check_membrane(&m, &p, 0.0);
        let star: Vec<[f64; 2]> = (0..10)
            .map(|i| {
                let r = if i % 2 == 0 { 1.0 } else { 0.4 };
                let t = std::f64::consts::PI * i as f64 / 5.0;
                [r * t.cos(), r * t.sin()]
            })
            .collect();
        let m = polygon_membrane(&star, 1500).unwrap();
        assert!(within(m.num_nodes(), 1500, 0.1), "{}", m.num_nodes());
        check_membrane(&m, &star, 0.3);
    }

    #[test]
    fn membrane_is_deterministic() {
        let p = [[0.0, 0.0], [1.0, 0.2], [0.7, 1.0], [0.2, 0.6]];
        let a = polygon_membrane(&p, 700).unwrap();
        let b = polygon_membrane(&p, 700).unwrap();
        let bits =
            |m: &Mesh| -> Vec<u64> { m.nodes.iter().flatten().map(|x| x.to_bits()).collect() };
        assert_eq!(bits(&a), bits(&b));
        assert_eq!(a.cells, b.cells);
        assert_eq!(a.groups, b.groups);
    }

    #[test]
    fn membrane_bad_input() {
        let sq = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        let bad: &[(&[[f64; 2]], usize)] = &[
            (&[[0.0, 0.0], [1.0, 0.0]], 100),             // 2 vertices
            (&[[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]], 100), // zero area
            (&[[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]], 100), // bow tie
            (&[[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [0.0, 1.0]], 100), // repeated
            (&[[0.0, 0.0], [2.0, 0.0], [1.0, 0.0], [1.0, 1.0]], 100), // fold back
            (
                &[[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [1.0, 0.0], [0.0, 2.0]],
                100,
            ), // touching
            (&[[0.0, 0.0], [f64::NAN, 0.0], [1.0, 1.0]], 100), // NaN
            (&sq, 2),                                     // target < 3
            (&sq, 3),                                     // < vertices
        ];
        for (i, (p, t)) in bad.iter().enumerate() {
            let r = polygon_membrane(p, *t);
            assert!(matches!(r, Err(Error::Param { .. })), "case {i}: {r:?}");
        }
        assert!(rectangle_membrane(0.0, 1.0, 100).is_err());
        assert!(rectangle_membrane(1.0, f64::INFINITY, 100).is_err());
        assert!(rectangle_membrane(1.0, 1.0, 2).is_err());
    }

    /// Faces of every tet, counted: returns (faces in 1 tet, faces in 2, faces in more).
    fn face_multiplicity(m: &Mesh) -> (usize, usize, usize) {
        let mut faces: Vec<[u32; 3]> = Vec::new();
        for el in m.elements() {
            for (a, b, c) in [(0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)] {
                let mut f = [el[a], el[b], el[c]];
                f.sort_unstable();
                faces.push(f);
            }
        }
        faces.sort_unstable();
        let (mut one, mut two, mut more) = (0, 0, 0);
        for run in faces.chunk_by(|a, b| a == b) {
            match run.len() {
                1 => one += 1,
                2 => two += 1,
                _ => more += 1,
            }
        }
        (one, two, more)
    }

    #[test]
    fn box_counts_volume_conformity() {
        for pattern in [BoxPattern::Six, BoxPattern::Five] {
            for (size, div) in [
                ([1.0, 1.0, 1.0], [1, 1, 1]),
                ([0.1, 0.04, 0.04], [5, 2, 2]),
                ([2.0, 3.0, 0.5], [4, 7, 3]),
                ([1.0, 1.0, 1.0], [1, 2, 3]),
            ] {
                let m = box_tets(size, div, pattern).unwrap();
                let [nx, ny, nz] = div;
                assert_eq!(m.num_nodes(), (nx + 1) * (ny + 1) * (nz + 1));
                assert_eq!(m.num_elements(), pattern.tets_per_cube() * nx * ny * nz);
                let vol = size[0] * size[1] * size[2];
                assert!((m.total_measure() - vol).abs() <= 1e-12 * vol);
                for e in 0..m.num_elements() {
                    assert!(m.element_measure(e) > 0.0, "{pattern:?} tet {e}");
                    assert!(!m.element_is_degenerate(e));
                }
                let quads = nx * ny + ny * nz + nz * nx;
                let (one, two, more) = face_multiplicity(&m);
                assert_eq!(one, 4 * quads, "{pattern:?} {div:?}");
                assert_eq!(more, 0);
                assert_eq!(2 * two + one, 4 * m.num_elements());
                assert_eq!(m.boundary_facets().len(), 4 * quads);
                assert_eq!(m.groups["boundary"], m.boundary_nodes());
                // x fastest numbering.
                assert_eq!(m.nodes[1], [size[0] / nx as f64, 0.0, 0.0]);
                assert_eq!(m.nodes[m.num_nodes() - 1], size);
                for (axis, name) in ["x", "y", "z"].iter().enumerate() {
                    let face_nodes = m.num_nodes() / (div[axis] + 1);
                    for (g, at) in [("min", 0.0), ("max", size[axis])] {
                        let nodes = &m.groups[&format!("{name}{g}")];
                        assert_eq!(nodes.len(), face_nodes);
                        assert!(nodes.iter().all(|&v| m.nodes[v as usize][axis] == at));
                    }
                }
                if size == [1.0, 1.0, 1.0] && div == [1, 1, 1] {
                    let q = min_quality(&m);
                    assert!(q > 0.7, "{pattern:?} {q}");
                }
            }
        }
    }

    #[test]
    fn box_target_counts() {
        let size = [0.1, 0.04, 0.04];
        let mut t = 100_000;
        while t >= 64 {
            let d = box_divisions_for_target(size, t).unwrap();
            let n = d.iter().map(|&x| x + 1).product::<usize>();
            assert!(within(n, t, 0.1), "{t}: {d:?} -> {n}");
            t /= 2;
        }
        for t in [1000, 10_000] {
            let m = box_tets_target(size, t, BoxPattern::Six).unwrap();
            assert!(within(m.num_nodes(), t, 0.1), "{t}: {}", m.num_nodes());
        }
        let d = box_divisions_for_target(size, 1_000_000).unwrap();
        let n = d.iter().map(|&x| x + 1).product::<usize>();
        assert!(within(n, 1_000_000, 0.02), "{d:?}");
        // Cells close to cubes.
        let h: Vec<f64> = (0..3).map(|a| size[a] / d[a] as f64).collect();
        assert!(h.iter().all(|&x| (x / h[0] - 1.0).abs() < 0.1), "{h:?}");
    }

    #[test]
    fn box_is_deterministic_and_validates() {
        let a = box_tets_target([1.0, 2.0, 3.0], 5000, BoxPattern::Five).unwrap();
        let b = box_tets_target([1.0, 2.0, 3.0], 5000, BoxPattern::Five).unwrap();
        assert_eq!(a.nodes, b.nodes);
        assert_eq!(a.cells, b.cells);
        assert_eq!(a.groups, b.groups);
        assert!(box_tets([0.0, 1.0, 1.0], [1, 1, 1], BoxPattern::Six).is_err());
        assert!(box_tets([1.0, -1.0, 1.0], [1, 1, 1], BoxPattern::Six).is_err());
        assert!(box_tets([1.0, 1.0, f64::NAN], [1, 1, 1], BoxPattern::Six).is_err());
        assert!(box_tets([1.0, 1.0, 1.0], [1, 0, 1], BoxPattern::Five).is_err());
        assert!(box_tets([1.0; 3], [1 << 20, 1 << 20, 1], BoxPattern::Five).is_err());
        assert!(box_tets_target([1.0; 3], 7, BoxPattern::Six).is_err());
        assert!(box_tets_target([1.0, 0.0, 1.0], 100, BoxPattern::Six).is_err());
    }

    /// A node count under [`MAX_NODES`] that the available memory cannot hold is refused
    /// before anything is allocated, naming the mesh and both sizes (checked where the
    /// machine has less memory than two thirds of what [`MAX_NODES`] such nodes take).
    #[test]
    fn generators_refuse_more_than_the_available_memory() {
        let Some(free) = crate::memory::available() else {
            return;
        };
        // Half as much again as fits, so that memory freed meanwhile does not change the answer.
        let nodes = free / MEMBRANE_NODE_BYTES * 3 / 2;
        if nodes <= MAX_NODES as u64 {
            let e = rectangle_membrane(0.1, 0.1, nodes as usize).unwrap_err();
            let msg = e.to_string();
            assert!(msg.contains("generating a membrane of"), "{msg}");
            assert!(msg.contains("GiB are available"), "{msg}");
        }
        let side = ((free / BOX_NODE_BYTES * 3 / 2) as f64).cbrt().ceil() as usize;
        if ((side + 1) as u128).pow(3) <= MAX_NODES as u128 {
            let e = box_tets([1.0; 3], [side; 3], BoxPattern::Six).unwrap_err();
            let msg = e.to_string();
            assert!(msg.contains("generating a box of"), "{msg}");
        }
    }
}
