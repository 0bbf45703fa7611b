//! Cutting a tetrahedral mesh: the virtual node algorithm (Molino, Bao & Fedkiw 2004).
//!
//! A cut is a planar [`Blade`] (the quad a straight blade sweeps). Each cut `k` has a level
//! set over the reference nodes, the signed distance to the blade's plane, pushed away from
//! zero so that no node lies on the cut:
//!
//! ```text
//! φ_k(X) = (X − p_k)·n_k,      φ̃_k = φ_k          where |φ_k| ≥ s,
//!                               φ̃_k = ±s (+ at 0)  else,      s = SNAP × mean edge length,
//! ```
//!
//! and inside each tetrahedron the cut surface is the zero set of `φ̃_k` interpolated linearly
//! from the element's four nodes: a plane piece per element, the same on both sides of every
//! shared face, so the wound is a continuous surface. The snap keeps every piece at least
//! `(SNAP / (1 + SNAP))³` of its tetrahedron (with `SNAP = 0.1`, 7.5e-4 for a piece cut off
//! one corner by a plane one edge away from the other three).
//!
//! Elements: an element (or a copy of one left by earlier cuts) is *split* by cut `k` when
//! the cut surface crosses its material — both sides keep more than `1e-9` of the
//! tetrahedron — and that cross-section overlaps the blade's quad (projected on the blade's
//! plane). A split element is replaced by two copies of the same tetrahedron, each carrying
//! the material on one side: copy `±` of an element with material `P` has the material
//! `P ∩ {±φ̃_k > 0}`, the *sides* `(k, ±)` added to its own. A cut therefore ends at element
//! faces: where the blade ends inside the body, the first element not split ties the lips
//! together (the tip of a notch).
//!
//! Nodes: every corner of every copy is a node slot; two copies of face-adjacent tetrahedra
//! share the three nodes of their common face when their materials overlap on that face (area
//! above `1e-9` of the face, the face clipped by the sides of both copies). The nodes are the
//! classes of slots this joins; a node of the uncut mesh thus becomes one node per connected
//! piece of material around it. A node outside a copy's material is a *virtual node*: it moves
//! the copy's material but carries none of its own. Each new node starts where the node it was
//! copied from is (same reference position, displacement, velocity: [`TopologyChange`]).
//! Nodes of the uncut mesh whose elements no cut has split keep one node whatever the mesh's
//! face connectivity (a non-manifold edge is not torn apart by a cut elsewhere).
//!
//! Mass and stiffness: a copy's material fraction `f = |P| / |T|` (`|T|` the tetrahedron's
//! volume) scales its element: for a linear tetrahedron the deformation gradient is constant,
//! so the strain energy of the material `P` is exactly `f |T| W(F)`, and the copy's mass
//! `ρ f |T|` is shared equally by its four nodes, as the uncut element's lumped mass is. The
//! copies of an element have fractions summing to the element's (mass and volume conserved to
//! rounding), and every copy keeps the uncut element's ratio of stiffness to mass, so however
//! small a piece, the stable explicit step is the uncut mesh's.
//!
//! Surface ([`CutMesh::surface`]): what bounds the material, for drawing and grasping: the
//! boundary faces of whole elements, and of each copy the parts of its tetrahedron's boundary
//! faces inside its material and its cut faces (the wound), each new vertex embedded in its
//! copy by barycentric weights and carried by the copy's nodes. It is a closed, outward
//! surface around each piece (its enclosed volume is the material's).
//!
//! Numbering: elements and nodes keep the uncut mesh's order, the copies of an element (of a
//! node) next to each other, so the banded order the force pass needs survives cutting.

use super::{ElementKind, Mesh};
use crate::geometry::{cross, dot, norm, sub};
use crate::{Error, Result};

/// The snap of the level set, in mean edge lengths (module docs).
pub const SNAP: f64 = 0.1;

/// A piece below this fraction of its tetrahedron (or a face overlap below this fraction of
/// the face) counts as empty.
pub const EMPTY: f64 = 1e-9;

/// A planar blade: the quad its edge sweeps, corners in order around it (m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Blade {
    /// The corners, in order around the quad.
    pub corners: [[f64; 3]; 4],
}

impl Blade {
    /// The quad swept by the blade's edge from `a`–`b` moved by `sweep` (m): corners `a`,
    /// `b`, `b + sweep`, `a + sweep`. A scalpel drawn from `a` to `b` on the surface and
    /// pushed to depth `d` along the view direction `w` is `Blade::swept(a, b, d w)`.
    pub fn swept(a: [f64; 3], b: [f64; 3], sweep: [f64; 3]) -> Result<Blade> {
        let add = |p: [f64; 3]| [p[0] + sweep[0], p[1] + sweep[1], p[2] + sweep[2]];
        Blade::quad([a, b, add(b), add(a)])
    }

    /// A quad blade: corners in order around it, in one plane (each within 1e-6 of the
    /// quad's size of the plane through them), convex, of non-zero area.
    pub fn quad(corners: [[f64; 3]; 4]) -> Result<Blade> {
        if corners.iter().flatten().any(|v| !v.is_finite()) {
            return Err(Error::param("blade", "a corner is not a finite number (m)"));
        }
        let b = Blade { corners };
        let size = (0..4)
            .map(|i| norm(sub(corners[(i + 1) % 4], corners[i])))
            .fold(0.0, f64::max);
        let n = b.raw_normal();
        let area = 0.5 * norm(n);
        if !(area > 1e-12 * size * size) || size == 0.0 {
            return Err(Error::param(
                "blade",
                "the blade's quad has no area: give two distinct edge points and a sweep not along the edge",
            ));
        }
        let n = b.normal();
        let c = b.centre();
        for (i, p) in corners.iter().enumerate() {
            let d = dot(sub(*p, c), n).abs();
            if d > 1e-6 * size {
                return Err(Error::param(
                    "blade",
                    format!(
                        "corner {i} is {d:.3e} m off the plane of the others: a blade is planar (sweep the edge along one direction)"
                    ),
                ));
            }
        }
        // Convex, in order: every turn has the same sense.
        for i in 0..4 {
            let e0 = sub(corners[(i + 1) % 4], corners[i]);
            let e1 = sub(corners[(i + 2) % 4], corners[(i + 1) % 4]);
            if dot(cross(e0, e1), n) <= 0.0 {
                return Err(Error::param(
                    "blade",
                    format!("the quad turns back at corner {}: give the corners in order around a convex quad", (i + 1) % 4),
                ));
            }
        }
        Ok(b)
    }

    /// Newell's normal (twice the area times the unit normal).
    fn raw_normal(&self) -> [f64; 3] {
        let c = &self.corners;
        cross(sub(c[2], c[0]), sub(c[3], c[1]))
    }

    /// The unit normal (the `+` side of the cut).
    pub fn normal(&self) -> [f64; 3] {
        let n = self.raw_normal();
        let l = norm(n);
        [n[0] / l, n[1] / l, n[2] / l]
    }

    /// The mean of the corners.
    pub fn centre(&self) -> [f64; 3] {
        let mut c = [0.0; 3];
        for p in &self.corners {
            for k in 0..3 {
                c[k] += 0.25 * p[k];
            }
        }
        c
    }

    /// Two unit vectors spanning the plane, `e1 × e2 = n`.
    fn frame(&self) -> ([f64; 3], [f64; 3]) {
        let n = self.normal();
        let d = sub(self.corners[1], self.corners[0]);
        let e1 = {
            let l = norm(d);
            [d[0] / l, d[1] / l, d[2] / l]
        };
        (e1, cross(n, e1))
    }
}

/// One cut: its blade and the snap length of this mesh.
#[derive(Clone, Copy, Debug)]
struct Plane {
    blade: Blade,
    point: [f64; 3],
    normal: [f64; 3],
    snap: f64,
}

impl Plane {
    /// `φ̃` at `x` (module docs).
    fn phi(&self, x: [f64; 3]) -> f64 {
        let d = dot(sub(x, self.point), self.normal);
        if d.abs() >= self.snap {
            d
        } else if d < 0.0 {
            -self.snap
        } else {
            self.snap
        }
    }
}

/// A side of a cut: the cut's index and the sign of `φ̃` the material has.
pub type Side = (u32, i8);

/// A mesh as cut so far: the uncut mesh, the cuts, and for each element of the cut mesh the
/// element of the uncut mesh it is a copy of and the sides its material keeps.
#[derive(Clone, Debug)]
pub struct CutMesh {
    base: Mesh,
    /// Face neighbours of each base element: `[e * 4 + f]`, the element across the face
    /// opposite corner `f`, or `u32::MAX` on the boundary.
    neighbours: Vec<u32>,
    snap: f64,
    planes: Vec<Plane>,
    /// Per element of the cut mesh: its base element.
    element: Vec<u32>,
    /// Per element of the cut mesh: its sides (empty for an element no cut split).
    sides: Vec<Vec<Side>>,
    /// Per element of the cut mesh: its material fraction.
    fraction: Vec<f64>,
    /// Per node of the cut mesh: its base node.
    origin: Vec<u32>,
    /// The cut mesh.
    mesh: Mesh,
}

/// What one cut changed: the new mesh, and where each of its nodes and elements comes from in
/// the mesh before the cut. A state is carried over by copying: node `a`'s displacement and
/// velocity are those of node `node_from[a]`, element `e`'s internal variables those of
/// element `element_from[e]`.
#[derive(Clone, Debug)]
pub struct TopologyChange {
    /// The mesh after the cut.
    pub mesh: Mesh,
    /// Each element's material fraction (module docs), 1 for an element no cut has split.
    pub fractions: Vec<f64>,
    /// Per new node: the node it is a copy of.
    pub node_from: Vec<u32>,
    /// Per new element: the element it is a copy of.
    pub element_from: Vec<u32>,
    /// Elements this cut split.
    pub split: usize,
}

impl TopologyChange {
    /// Whether the cut changed nothing (the blade split no element).
    pub fn is_identity(&self) -> bool {
        self.split == 0
    }

    /// A per-node array of `comps` values carried to the new nodes (each copies its origin).
    pub fn carry<T: Copy>(&self, old: &[T], comps: usize) -> Vec<T> {
        let mut out = Vec::with_capacity(self.node_from.len() * comps);
        for &o in &self.node_from {
            out.extend_from_slice(&old[o as usize * comps..o as usize * comps + comps]);
        }
        out
    }
}

/// The surface of a cut body: the boundary faces of the whole elements (their nodes), and of
/// each element copy the parts of its tetrahedron's boundary faces inside its material and its
/// cut faces (the wound), each point embedded in its copy by barycentric weights.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct EmbeddedSurface {
    /// The mesh's node count: vertex `v < nodes` is node `v`, vertex `nodes + i` is
    /// `points[i]`.
    pub nodes: usize,
    /// Embedded vertices: an element and the barycentric weights of its four corners.
    pub points: Vec<(u32, [f64; 4])>,
    /// Triangles, outward.
    pub triangles: Vec<[u32; 3]>,
    /// The cut mesh's boundary faces, whole (every face no element across it shares, the
    /// copies' included), outward: what grasps take their patch from.
    pub boundary: Vec<[u32; 3]>,
}

impl EmbeddedSurface {
    /// Positions of the vertices: the nodes' `x` first, then the embedded points in their
    /// elements (`cells` the mesh's connectivity).
    pub fn positions(&self, x: &[[f64; 3]], cells: &[u32], out: &mut Vec<[f64; 3]>) {
        out.clear();
        out.extend_from_slice(&x[..self.nodes]);
        for &(e, w) in &self.points {
            let el = &cells[4 * e as usize..4 * e as usize + 4];
            let mut p = [0.0; 3];
            for (j, &a) in el.iter().enumerate() {
                for k in 0..3 {
                    p[k] += w[j] * x[a as usize][k];
                }
            }
            out.push(p);
        }
    }

    /// Add a polygon of element `e` (corners `el`) given in reference coordinates, fanned.
    fn polygon(&mut self, e: u32, el: &[u32], poly: &Poly) {
        let mut ids: Vec<u32> = Vec::with_capacity(poly.len());
        for l in poly {
            let w = [1.0 - l[0] - l[1] - l[2], l[0], l[1], l[2]];
            let id = match w.iter().position(|&x| x == 1.0) {
                Some(j) if w.iter().filter(|&&x| x == 0.0).count() == 3 => el[j],
                _ => {
                    self.points.push((e, w));
                    (self.nodes + self.points.len() - 1) as u32
                }
            };
            if ids.last() != Some(&id) {
                ids.push(id);
            }
        }
        while ids.len() > 1 && ids.first() == ids.last() {
            ids.pop();
        }
        for i in 1..ids.len().saturating_sub(1) {
            self.triangles.push([ids[0], ids[i], ids[i + 1]]);
        }
    }
}

/// A convex polygon or polyhedron face in reference coordinates, as points.
type Poly = Vec<[f64; 3]>;

/// Clip polygon `p` to `{f ≥ 0}`, `f` given at each point by `f`; the points where an edge
/// crosses `f = 0` are appended to `cap`.
fn clip(p: &Poly, f: &dyn Fn([f64; 3]) -> f64, cap: &mut Poly) -> Poly {
    let mut out = Vec::with_capacity(p.len() + 2);
    for i in 0..p.len() {
        let (a, b) = (p[i], p[(i + 1) % p.len()]);
        let (fa, fb) = (f(a), f(b));
        if fa >= 0.0 {
            out.push(a);
        }
        if (fa >= 0.0) != (fb >= 0.0) {
            let t = fa / (fa - fb);
            let x = [
                a[0] + t * (b[0] - a[0]),
                a[1] + t * (b[1] - a[1]),
                a[2] + t * (b[2] - a[2]),
            ];
            out.push(x);
            cap.push(x);
        }
    }
    out
}

/// Twice the vector area of a polygon (Newell).
fn area_vector(p: &Poly) -> [f64; 3] {
    let mut n = [0.0; 3];
    for i in 1..p.len().saturating_sub(1) {
        let c = cross(sub(p[i], p[0]), sub(p[i + 1], p[0]));
        for k in 0..3 {
            n[k] += c[k];
        }
    }
    n
}

/// A convex polyhedron in the reference tetrahedron's coordinates `λ₁, λ₂, λ₃` (faces
/// outward), clipped by linear functions of the barycentric coordinates.
#[derive(Clone)]
struct Polytope {
    faces: Vec<Poly>,
    /// Where each face comes from: `Ok(f)` the tetrahedron's face opposite corner `f`,
    /// `Err(k)` the cut surface of cut `k` (a cap).
    tags: Vec<std::result::Result<usize, u32>>,
}

impl Polytope {
    fn tet() -> Polytope {
        let (o, x, y, z) = ([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);
        Polytope {
            faces: vec![vec![o, y, x], vec![o, x, z], vec![o, z, y], vec![x, y, z]],
            tags: vec![Ok(3), Ok(2), Ok(1), Ok(0)],
        }
    }

    /// Keep `{Σ λ_i φ_i ≥ 0}` (φ at the four corners, `λ₀ = 1 − λ₁ − λ₂ − λ₃`); returns the
    /// clipped polytope and its cap (the cross-section, outward).
    fn clip(&self, phi: [f64; 4]) -> (Polytope, Poly) {
        self.clip_tagged(phi, u32::MAX)
    }

    /// [`Polytope::clip`], its cap tagged as cut `k`.
    fn clip_tagged(&self, phi: [f64; 4], k: u32) -> (Polytope, Poly) {
        let f = |l: [f64; 3]| {
            phi[0] + l[0] * (phi[1] - phi[0]) + l[1] * (phi[2] - phi[0]) + l[2] * (phi[3] - phi[0])
        };
        let mut cap = Vec::new();
        let mut faces = Vec::with_capacity(self.faces.len() + 1);
        let mut tags = Vec::with_capacity(self.faces.len() + 1);
        for (face, &tag) in self.faces.iter().zip(&self.tags) {
            let c = clip(face, &f, &mut cap);
            if c.len() >= 3 {
                faces.push(c);
                tags.push(tag);
            }
        }
        // Order the cap's points around their centroid, outward (−∇f).
        let g = [phi[1] - phi[0], phi[2] - phi[0], phi[3] - phi[0]];
        let cap = order_around(cap, [-g[0], -g[1], -g[2]]);
        if cap.len() >= 3 {
            faces.push(cap.clone());
            tags.push(Err(k));
        }
        (Polytope { faces, tags }, cap)
    }

    /// Volume as a fraction of the reference tetrahedron's (6 × the volume).
    fn fraction(&self) -> f64 {
        let mut v = 0.0;
        for p in &self.faces {
            for i in 1..p.len() - 1 {
                v += dot(p[0], cross(p[i], p[i + 1]));
            }
        }
        v
    }
}

/// Points of a planar convex polygon ordered around their centroid so that the polygon's
/// normal points along `n`.
fn order_around(mut pts: Poly, n: [f64; 3]) -> Poly {
    if pts.len() < 3 {
        return pts;
    }
    let inv = 1.0 / pts.len() as f64;
    let mut c = [0.0; 3];
    for p in &pts {
        for k in 0..3 {
            c[k] += p[k] * inv;
        }
    }
    // A frame of the plane: e1 any direction orthogonal to n, e2 = n × e1.
    let a = if n[0].abs() < 0.9 * norm(n) {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let e1 = cross(n, a);
    let e2 = cross(n, e1);
    let angle = |p: &[f64; 3]| {
        let d = sub(*p, c);
        dot(d, e2).atan2(dot(d, e1))
    };
    pts.sort_by(|p, q| angle(p).total_cmp(&angle(q)));
    // Each crossing point comes from two faces: drop the repeats.
    let scale = pts
        .iter()
        .flatten()
        .fold(0.0f64, |m, v| m.max(v.abs()))
        .max(1.0);
    let same = |p: &[f64; 3], q: &[f64; 3]| norm(sub(*p, *q)) <= 1e-13 * scale;
    pts.dedup_by(|p, q| same(p, q));
    while pts.len() > 1 && same(&pts[0], &pts[pts.len() - 1]) {
        pts.pop();
    }
    if dot(area_vector(&pts), n) < 0.0 {
        pts.reverse();
    }
    pts
}

/// Convex polygons in 2-D overlap (separating axes), with the interior's overlap required.
fn overlap_2d(a: &[[f64; 2]], b: &[[f64; 2]]) -> bool {
    if a.len() < 3 || b.len() < 3 {
        return false;
    }
    for poly in [a, b] {
        for i in 0..poly.len() {
            let (p, q) = (poly[i], poly[(i + 1) % poly.len()]);
            let axis = [q[1] - p[1], p[0] - q[0]];
            if axis[0] == 0.0 && axis[1] == 0.0 {
                continue;
            }
            let proj = |s: &[[f64; 2]]| {
                s.iter()
                    .map(|v| v[0] * axis[0] + v[1] * axis[1])
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
                        (lo.min(x), hi.max(x))
                    })
            };
            let ((a0, a1), (b0, b1)) = (proj(a), proj(b));
            if a1 <= b0 || b1 <= a0 {
                return false;
            }
        }
    }
    true
}

/// The local corners of each face of a tetrahedron, opposite corner `f`.
const FACE: [[usize; 3]; 4] = [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]];

/// Union-find over node slots.
struct Classes(Vec<u32>);

impl Classes {
    fn find(&mut self, mut a: u32) -> u32 {
        while self.0[a as usize] != a {
            let p = self.0[self.0[a as usize] as usize];
            self.0[a as usize] = p;
            a = p;
        }
        a
    }
    /// Join, the smaller slot the root (so a class's root is its first slot).
    fn join(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
            self.0[hi as usize] = lo;
        }
    }
}

impl CutMesh {
    /// An uncut tetrahedral mesh, ready to be cut. Errors: a membrane.
    pub fn new(mesh: Mesh) -> Result<CutMesh> {
        if mesh.kind != ElementKind::Tet4 {
            return Err(Error::param(
                "cut",
                "only tetrahedral meshes can be cut (this one is a triangle membrane)",
            ));
        }
        let ne = mesh.num_elements();
        let mut faces: Vec<([u32; 3], u32)> = Vec::with_capacity(4 * ne);
        let mut edge_sum = 0.0;
        for (e, el) in mesh.cells.chunks_exact(4).enumerate() {
            for (f, c) in FACE.iter().enumerate() {
                let mut k = [el[c[0]], el[c[1]], el[c[2]]];
                k.sort_unstable();
                faces.push((k, (4 * e + f) as u32));
            }
            for i in 0..4 {
                for j in i + 1..4 {
                    edge_sum += norm(sub(mesh.nodes[el[j] as usize], mesh.nodes[el[i] as usize]));
                }
            }
        }
        faces.sort_unstable();
        let mut neighbours = vec![u32::MAX; 4 * ne];
        for w in faces.windows(2) {
            if w[0].0 == w[1].0 {
                neighbours[w[0].1 as usize] = w[1].1 / 4;
                neighbours[w[1].1 as usize] = w[0].1 / 4;
            }
        }
        let mean_edge = edge_sum / (6 * ne.max(1)) as f64;
        Ok(CutMesh {
            neighbours,
            snap: SNAP * mean_edge,
            planes: Vec::new(),
            element: (0..ne as u32).collect(),
            sides: vec![Vec::new(); ne],
            fraction: vec![1.0; ne],
            origin: (0..mesh.num_nodes() as u32).collect(),
            mesh: mesh.clone(),
            base: mesh,
        })
    }

    /// The mesh as cut so far.
    pub fn mesh(&self) -> &Mesh {
        &self.mesh
    }

    /// The uncut mesh.
    pub fn base(&self) -> &Mesh {
        &self.base
    }

    /// Each element's material fraction.
    pub fn fractions(&self) -> &[f64] {
        &self.fraction
    }

    /// Each element's base element.
    pub fn base_elements(&self) -> &[u32] {
        &self.element
    }

    /// Each node's base node.
    pub fn base_nodes(&self) -> &[u32] {
        &self.origin
    }

    /// Each element's sides (empty where no cut split it).
    pub fn sides(&self) -> &[Vec<Side>] {
        &self.sides
    }

    /// The cuts made so far.
    pub fn blades(&self) -> Vec<Blade> {
        self.planes.iter().map(|p| p.blade).collect()
    }

    /// Whether any cut split an element (each split adds an element).
    pub fn is_cut(&self) -> bool {
        self.mesh.num_elements() > self.base.num_elements()
    }

    /// `φ̃` of cut `k` at the four base nodes of base element `e`.
    fn phis(&self, k: usize, e: usize) -> [f64; 4] {
        let el = &self.base.cells[4 * e..4 * e + 4];
        std::array::from_fn(|i| self.planes[k].phi(self.base.nodes[el[i] as usize]))
    }

    /// The material polytope of an element with `sides` in base element `e`.
    fn material(&self, e: usize, sides: &[Side]) -> Polytope {
        let mut p = Polytope::tet();
        for &(k, s) in sides {
            let phi = self.phis(k as usize, e).map(|v| v * s as f64);
            p = p.clip_tagged(phi, k).0;
        }
        p
    }

    /// The side of cut `k` a node's material is on: the side of the first element (in
    /// order) with that cut among its elements' sides, else the sign of `φ̃_k` at the node.
    /// `node_sides` from [`CutMesh::node_sides`].
    pub fn side_of(&self, node_sides: &[Vec<Side>], a: usize, k: u32) -> i8 {
        if let Some(&(_, s)) = node_sides[a].iter().find(|(c, _)| *c == k) {
            return s;
        }
        self.plane_side(k, self.base.nodes[self.origin[a] as usize])
    }

    /// The side of cut `k`'s (snapped) plane a reference point `x` lies on: `1` or `-1`.
    pub fn plane_side(&self, k: u32, x: [f64; 3]) -> i8 {
        if self.planes[k as usize].phi(x) < 0.0 {
            -1
        } else {
            1
        }
    }

    /// Each node's sides: the first side of each cut among its elements' (elements in order).
    pub fn node_sides(&self) -> Vec<Vec<Side>> {
        let mut out: Vec<Vec<Side>> = vec![Vec::new(); self.mesh.num_nodes()];
        for (e, el) in self.mesh.cells.chunks_exact(4).enumerate() {
            for &(k, s) in &self.sides[e] {
                for &a in el {
                    let ns = &mut out[a as usize];
                    if !ns.iter().any(|(c, _)| *c == k) {
                        ns.push((k, s));
                    }
                }
            }
        }
        out
    }

    /// The elements of the cut mesh that are copies of base element `e` (contiguous).
    pub fn copies(&self, e: u32) -> std::ops::Range<usize> {
        let lo = self.element.partition_point(|&b| b < e);
        let hi = self.element.partition_point(|&b| b <= e);
        lo..hi
    }

    /// The copy of base element `e` whose sides agree most with a point whose side of each
    /// cut is `side(k)` (all of them, if one does; ties to the first).
    pub fn copy_for(&self, e: u32, side: impl Fn(u32) -> i8) -> usize {
        let r = self.copies(e);
        let mut best = (r.start, usize::MAX);
        for c in r {
            let misses = self.sides[c].iter().filter(|&&(k, s)| side(k) != s).count();
            if misses < best.1 {
                best = (c, misses);
            }
        }
        best.0
    }

    /// Cut by `blade`: split the elements it crosses (module docs) and rebuild the nodes.
    /// Returns what changed; a blade that misses the body changes nothing
    /// ([`TopologyChange::is_identity`]) but is kept, so that the cuts of every level of a
    /// hierarchy keep the same indices.
    pub fn cut(&mut self, blade: &Blade) -> Result<TopologyChange> {
        let k = self.planes.len() as u32;
        self.planes.push(Plane {
            blade: *blade,
            point: blade.centre(),
            normal: blade.normal(),
            snap: self.snap,
        });
        let plane = self.planes[k as usize];
        let (e1, e2) = blade.frame();
        let to2 = |x: [f64; 3]| {
            let d = sub(x, plane.point);
            [dot(d, e1), dot(d, e2)]
        };
        let quad: Vec<[f64; 2]> = blade.corners.iter().map(|&c| to2(c)).collect();
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for c in &blade.corners {
            for i in 0..3 {
                lo[i] = lo[i].min(c[i] - self.snap);
                hi[i] = hi[i].max(c[i] + self.snap);
            }
        }
        // Which elements split, and their fractions on each side.
        let ne = self.mesh.num_elements();
        let mut split: Vec<Option<(f64, f64)>> = vec![None; ne];
        for (c, s) in split.iter_mut().enumerate() {
            let e = self.element[c] as usize;
            let el = &self.base.cells[4 * e..4 * e + 4];
            let pts: [[f64; 3]; 4] = std::array::from_fn(|i| self.base.nodes[el[i] as usize]);
            if (0..3).any(|i| pts.iter().all(|p| p[i] < lo[i]) || pts.iter().all(|p| p[i] > hi[i]))
            {
                continue;
            }
            let phi = self.phis(k as usize, e);
            if phi.iter().all(|&v| v > 0.0) || phi.iter().all(|&v| v < 0.0) {
                continue;
            }
            let material = self.material(e, &self.sides[c]);
            let (plus, cap) = material.clip(phi);
            let (minus, _) = material.clip(phi.map(|v| -v));
            let (fp, fm) = (plus.fraction(), minus.fraction());
            if !(fp > EMPTY && fm > EMPTY) || cap.len() < 3 {
                continue;
            }
            let x = |l: [f64; 3]| {
                let w = [1.0 - l[0] - l[1] - l[2], l[0], l[1], l[2]];
                let mut x = [0.0; 3];
                for (j, p) in pts.iter().enumerate() {
                    for i in 0..3 {
                        x[i] += w[j] * p[i];
                    }
                }
                x
            };
            let section: Vec<[f64; 2]> = cap.iter().map(|&l| to2(x(l))).collect();
            if !overlap_2d(&quad, &section) {
                continue;
            }
            // Split the element's fraction in the ratio of its two pieces.
            let f = self.fraction[c];
            let plus = f * fp / (fp + fm);
            *s = Some((plus, f - plus));
        }
        let n_split = split.iter().filter(|s| s.is_some()).count();
        // The new elements, copies next to each other.
        let mut element_from = Vec::with_capacity(ne + n_split);
        let mut element = Vec::with_capacity(ne + n_split);
        let mut sides = Vec::with_capacity(ne + n_split);
        let mut fraction = Vec::with_capacity(ne + n_split);
        for (c, s) in split.iter().enumerate() {
            match s {
                None => {
                    element_from.push(c as u32);
                    element.push(self.element[c]);
                    sides.push(self.sides[c].clone());
                    fraction.push(self.fraction[c]);
                }
                Some((fp, fm)) => {
                    for (sign, f) in [(1i8, *fp), (-1i8, *fm)] {
                        element_from.push(c as u32);
                        element.push(self.element[c]);
                        let mut sd = self.sides[c].clone();
                        sd.push((k, sign));
                        sides.push(sd);
                        fraction.push(f);
                    }
                }
            }
        }
        if n_split == 0 {
            let n = self.mesh.num_nodes() as u32;
            return Ok(TopologyChange {
                mesh: self.mesh.clone(),
                fractions: self.fraction.clone(),
                node_from: (0..n).collect(),
                element_from,
                split: 0,
            });
        }
        // Node slots of the new elements, joined across faces where the materials overlap.
        let ne2 = element.len();
        let old_cells = &self.mesh.cells;
        // Base nodes touched by a split element: only their slots are re-joined.
        let mut affected = vec![false; self.base.num_nodes()];
        for (c, sd) in sides.iter().enumerate() {
            if !sd.is_empty() {
                for &a in &self.base.cells[4 * element[c] as usize..4 * element[c] as usize + 4] {
                    affected[a as usize] = true;
                }
            }
        }
        let mut classes = Classes((0..4 * ne2 as u32).collect());
        // Unaffected slots: all slots of the same old node join.
        let mut first_slot = vec![u32::MAX; self.mesh.num_nodes()];
        for c in 0..ne2 {
            let old = element_from[c] as usize;
            for i in 0..4 {
                let a = old_cells[4 * old + i];
                if affected[self.origin[a as usize] as usize] {
                    continue;
                }
                let slot = (4 * c + i) as u32;
                match first_slot[a as usize] {
                    u32::MAX => first_slot[a as usize] = slot,
                    f => classes.join(f, slot),
                }
            }
        }
        // Affected slots: across faces whose clipped materials overlap.
        let first_copy = |e: u32| element.partition_point(|&b| b < e);
        for c in 0..ne2 {
            let e = element[c] as usize;
            let el = &self.base.cells[4 * e..4 * e + 4];
            for (f, corners) in FACE.iter().enumerate() {
                if !corners.iter().any(|&i| affected[el[i] as usize]) {
                    continue;
                }
                let nb = self.neighbours[4 * e + f];
                if nb == u32::MAX || (nb as usize) < e {
                    continue;
                }
                let nel = &self.base.cells[4 * nb as usize..4 * nb as usize + 4];
                let face_nodes = [el[corners[0]], el[corners[1]], el[corners[2]]];
                let local_in_nb =
                    face_nodes.map(|a| nel.iter().position(|&b| b == a).expect("shared face node"));
                let mut d = first_copy(nb);
                while d < ne2 && element[d] == nb {
                    if self.face_overlap(&sides[c], &sides[d], face_nodes) {
                        for j in 0..3 {
                            classes
                                .join((4 * c + corners[j]) as u32, (4 * d + local_in_nb[j]) as u32);
                        }
                    }
                    d += 1;
                }
            }
        }
        // Number the classes: by old node, then by first slot.
        let mut roots: Vec<(u32, u32)> = Vec::new(); // (old node, root slot)
        let mut root_of = vec![0u32; 4 * ne2];
        for slot in 0..4 * ne2 as u32 {
            let r = classes.find(slot);
            root_of[slot as usize] = r;
            if r == slot {
                let c = slot as usize / 4;
                let old = old_cells[4 * element_from[c] as usize + slot as usize % 4];
                roots.push((old, slot));
            }
        }
        roots.sort_unstable();
        let mut id_of_root = vec![u32::MAX; 4 * ne2];
        for (i, &(_, r)) in roots.iter().enumerate() {
            id_of_root[r as usize] = i as u32;
        }
        let node_from: Vec<u32> = roots.iter().map(|&(o, _)| o).collect();
        // Old nodes no element uses (none in a valid mesh) would vanish: keep them.
        let cells: Vec<u32> = (0..4 * ne2)
            .map(|s| id_of_root[root_of[s] as usize])
            .collect();
        let origin: Vec<u32> = node_from.iter().map(|&o| self.origin[o as usize]).collect();
        let nodes: Vec<[f64; 3]> = origin
            .iter()
            .map(|&o| self.base.nodes[o as usize])
            .collect();
        let mut copies: Vec<Vec<u32>> = vec![Vec::new(); self.mesh.num_nodes()];
        for (a, &o) in node_from.iter().enumerate() {
            copies[o as usize].push(a as u32);
        }
        let groups = self
            .mesh
            .groups
            .iter()
            .map(|(name, ids)| {
                let mut v: Vec<u32> = ids
                    .iter()
                    .flat_map(|&a| copies[a as usize].iter().copied())
                    .collect();
                v.sort_unstable();
                (name.clone(), v)
            })
            .collect();
        let mesh = Mesh {
            kind: ElementKind::Tet4,
            nodes,
            cells,
            groups,
        };
        self.mesh = mesh.clone();
        self.element = element;
        self.sides = sides;
        self.fraction = fraction.clone();
        self.origin = origin;
        Ok(TopologyChange {
            mesh,
            fractions: fraction,
            node_from,
            element_from,
            split: n_split,
        })
    }

    /// The surface of the cut body (module docs, "Surface").
    pub fn surface(&self) -> EmbeddedSurface {
        let m = &self.mesh;
        // A copy's face is on the boundary where no copy of the base element across it
        // holds the same three nodes (the face shared): found through the base mesh's face
        // neighbours, no sort.
        let boundary: Vec<bool> = (0..m.cells.len())
            .map(|slot| {
                let (c, f) = (slot / 4, slot % 4);
                let nb = self.neighbours[4 * self.element[c] as usize + f];
                if nb == u32::MAX {
                    return true;
                }
                let el = &m.cells[4 * c..4 * c + 4];
                let face = FACE[f].map(|i| el[i]);
                !self
                    .copies(nb)
                    .any(|d| face.iter().all(|a| m.cells[4 * d..4 * d + 4].contains(a)))
            })
            .collect();
        let mut out = EmbeddedSurface {
            nodes: m.num_nodes(),
            points: Vec::new(),
            triangles: Vec::new(),
            boundary: Vec::new(),
        };
        for (e, el) in m.cells.chunks_exact(4).enumerate() {
            for (f, c) in FACE.iter().enumerate() {
                if boundary[4 * e + f] {
                    let (a, b, d) = (el[c[0]], el[c[1]], el[c[2]]);
                    // FACE[f] points away from corner f for even f; flip the odd ones.
                    out.boundary
                        .push(if f % 2 == 0 { [a, b, d] } else { [a, d, b] });
                }
            }
            if self.sides[e].is_empty() {
                // A whole element: its boundary faces, outward.
                let k = out.boundary.len();
                let faces = FACE
                    .iter()
                    .enumerate()
                    .filter(|&(f, _)| boundary[4 * e + f])
                    .count();
                out.triangles.extend_from_slice(&out.boundary[k - faces..k]);
                continue;
            }
            let p = self.material(self.element[e] as usize, &self.sides[e]);
            for (poly, tag) in p.faces.iter().zip(&p.tags) {
                let draw = match tag {
                    Ok(f) => boundary[4 * e + f],
                    Err(_) => true,
                };
                if draw {
                    out.polygon(e as u32, el, poly);
                }
            }
        }
        out
    }

    /// Whether copies with sides `sa` and `sb` of two base elements have overlapping
    /// material on their shared face (its base nodes `face`).
    fn face_overlap(&self, sa: &[Side], sb: &[Side], face: [u32; 3]) -> bool {
        if sa.is_empty() && sb.is_empty() {
            return true;
        }
        // The face in its own barycentric coordinates (w1, w2, 0), w0 = 1 − w1 − w2.
        let mut p: Poly = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let x: [[f64; 3]; 3] = face.map(|n| self.base.nodes[n as usize]);
        for &(k, s) in sa.iter().chain(sb) {
            let phi = x.map(|xi| self.planes[k as usize].phi(xi) * s as f64);
            let f = |w: [f64; 3]| phi[0] + w[0] * (phi[1] - phi[0]) + w[1] * (phi[2] - phi[0]);
            p = clip(&p, &f, &mut Vec::new());
            if p.len() < 3 {
                return false;
            }
        }
        // Area in face coordinates, the whole face 1/2.
        norm(area_vector(&p)) > 2.0 * EMPTY * 0.5
    }
}

#[cfg(test)]
mod tests;
