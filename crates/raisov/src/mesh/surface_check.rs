//! Checks and repairs a triangle [`Surface`] before it is meshed.
//!
//! [`check_surface`] accepts a surface only if it can bound a solid:
//!
//! * no **degenerate** triangle: three distinct vertices and area above
//!   [`DEGENERATE_REL`]` · h²` (`h` the longest edge);
//! * **closed 2-manifold**: every edge `(a, b)` is in exactly two triangles (more: a
//!   non-manifold edge; one: a boundary edge, the surface is open), and the triangles around
//!   every vertex form a single fan (two cones meeting at a vertex are refused);
//! * **orientable**: in each connected component (triangles joined through edges) the
//!   triangles can be ordered so that every edge is used once as `a → b` and once as `b → a`;
//! * no **self-intersection**: two triangles meet only in the vertices and the edge they share
//!   by index; touching counts as meeting. Decided exactly (Shewchuk's adaptive predicates):
//!   two triangles sharing an edge overlap iff they are coplanar and on the same side of it;
//!   every other meeting is an edge meeting a triangle it has no vertex in common with, so the
//!   pairs of triangles around a vertex of high valence (a fan) are never enumerated. Each edge
//!   descends a tree of oriented boxes over the triangles (the crate-private
//!   `mesh::self_intersection` module states the rules and why they are exact).
//!
//! Repairs, written back into the surface only when every check passes:
//!
//! * **orientation**: a breadth-first search from each component's lowest-numbered triangle
//!   flips neighbours to agree with it; then each component is turned as a whole so that its
//!   normals point out of the solid. The solid is the region of odd nesting depth: a component
//!   lying inside `k` others (winding number test, valid since no two components intersect) has
//!   depth `k`; one at even depth is an outer boundary and gets a positive enclosed volume
//!   `V = (1/6) Σ a · (b × c)`; one at odd depth is a **cavity** (a void inside the solid)
//!   and gets a negative one, so that the surface's total enclosed volume is the solid's volume.
//!   Every component is kept; [`SurfaceReport::components`] lists them, with their nesting, so
//!   that a mesher meshes all the solid's pieces and leaves the cavities empty.
//!
//! The report counts the flipped triangles (relative to the input order). Vertices no triangle
//! uses are counted, not removed.
//!
//! One concern, the checks of a closed surface and its orientation, in one file (about half of
//! it tests); the self-intersection test, exact geometry with its own broad phase, is the
//! `self_intersection` module's.

use std::collections::VecDeque;

pub use super::self_intersection::IntersectionWork;
use super::self_intersection::{find_meeting, Meeting};
use super::{cross, dot, norm, sub, Surface, DEGENERATE_REL};
use crate::{Error, Result};

/// Largest extent (m) a surface of a soft-tissue organ plausibly has. A surface spanning more
/// than this in a scene in metres was most likely written in millimetres.
pub const MAX_ORGAN_EXTENT_M: f64 = 5.0;

/// Whether a bounding box whose coordinates become metres when multiplied by `scale` spans
/// more than [`MAX_ORGAN_EXTENT_M`] along some axis: then the file was most likely in
/// millimetres (a liver is about 0.2 m across, 200 in millimetres). Used to warn, never to
/// rescale silently.
pub fn looks_like_millimetres(bbox: ([f64; 3], [f64; 3]), scale: f64) -> bool {
    let (lo, hi) = bbox;
    (0..3)
        .map(|k| (hi[k] - lo[k]) * scale.abs())
        .any(|e| e > MAX_ORGAN_EXTENT_M)
}

/// One connected component of a checked surface.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceComponent {
    /// Its number of triangles.
    pub triangles: usize,
    /// Its number of vertices.
    pub vertices: usize,
    /// Its lowest-numbered triangle (identifies it).
    pub first_triangle: usize,
    /// Signed enclosed volume after orientation: positive for an outer boundary, negative for
    /// a cavity.
    pub volume: f64,
    /// How many other components enclose it.
    pub depth: usize,
    /// The component (index into [`SurfaceReport::components`]) that immediately encloses it.
    pub inside: Option<usize>,
}

impl SurfaceComponent {
    /// A void inside the solid (odd nesting depth).
    pub fn is_cavity(&self) -> bool {
        self.depth % 2 == 1
    }
}

/// What [`check_surface`] found and repaired.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceReport {
    /// Number of vertices.
    pub vertices: usize,
    /// Number of triangles.
    pub triangles: usize,
    /// Vertices no triangle uses (kept in the surface).
    pub unused_vertices: usize,
    /// Triangles whose orientation was flipped.
    pub flipped: usize,
    /// Connected components, ordered by their lowest-numbered triangle.
    pub components: Vec<SurfaceComponent>,
    /// Enclosed volume of the repaired surface: outer components minus cavities.
    pub enclosed_volume: f64,
    /// Bounding box of the used vertices.
    pub bbox_min: [f64; 3],
    /// Upper corner of the bounding box.
    pub bbox_max: [f64; 3],
    /// Work of the self-intersection test.
    pub intersection_work: IntersectionWork,
}

/// Bytes the check may take per triangle, with room to spare: the sorted edge list (48), the
/// neighbours (12), the fans' corners (12), the components, flips and oriented copy (about
/// 20), the self-intersection test's edges (18), centroids (24), items (4) and tree (fewer
/// nodes than triangles, 192 bytes each).
const CHECK_TRIANGLE_BYTES: u64 = 384;

fn bad(msg: String) -> Error {
    Error::BadSurface { msg }
}

/// Check a surface for use as a closed boundary and repair its orientation (see the module
/// docs). On success the surface's triangles are consistently oriented, normals out of the
/// solid; on error it is left unchanged and the message names the offending triangles and
/// vertices ([`Error::BadSurface`]).
pub fn check_surface(s: &mut Surface) -> Result<SurfaceReport> {
    check_surface_with_progress(s, &mut |_, _| {})
}

/// [`check_surface`], calling `progress(done, total)` about a hundred times while the
/// self-intersection test, the check's longest step, runs: `done` of the surface's `total`
/// edges tested, up to `done == total` when it finds no intersection.
pub fn check_surface_with_progress(
    s: &mut Surface,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<SurfaceReport> {
    let nt = s.triangles.len();
    let nv = s.points.len();
    if nt == 0 {
        return Err(bad(format!("no triangles ({nv} vertices)")));
    }
    if nt >= u32::MAX as usize / 3 {
        return Err(bad(format!(
            "{nt} triangles; at most {} are supported",
            u32::MAX / 3
        )));
    }
    if let Some((i, p)) = s
        .points
        .iter()
        .enumerate()
        .find(|(_, p)| p.iter().any(|c| !c.is_finite()))
    {
        return Err(bad(format!("vertex {i} has a non-finite coordinate {p:?}")));
    }
    for (t, tri) in s.triangles.iter().enumerate() {
        if let Some(&v) = tri.iter().find(|&&v| v as usize >= nv) {
            return Err(bad(format!(
                "triangle {t} references vertex {v} but the surface has {nv} vertices \
                 (valid: 0..{})",
                nv as i64 - 1
            )));
        }
    }
    crate::memory::check_for(
        &format!("checking a surface of {nt} triangles"),
        (nt as u64).saturating_mul(CHECK_TRIANGLE_BYTES),
        "simplify the surface to fewer triangles",
    )
    .map_err(bad)?;
    check_degenerate(s)?;
    let nbr = edge_neighbours(&s.triangles)?;
    let unused_vertices = check_vertex_fans(s, &nbr)?;
    let (comp_of, flip, comps) = orient_components(&s.triangles, &nbr)?;
    let tris: Vec<[u32; 3]> = s
        .triangles
        .iter()
        .zip(&flip)
        .map(|(&t, &f)| if f { [t[0], t[2], t[1]] } else { t })
        .collect();
    let (meeting, intersection_work) = find_meeting(&s.points, &s.triangles, &nbr, progress);
    if let Some(m) = meeting {
        return Err(self_intersection(&s.triangles, m));
    }

    // Volumes, nesting, final turn of each component.
    let nc = comps.len();
    let mut volume = vec![0.0; nc];
    let mut lo = vec![[f64::INFINITY; 3]; nc];
    let mut hi = vec![[f64::NEG_INFINITY; 3]; nc];
    for (t, tri) in tris.iter().enumerate() {
        let c = comp_of[t] as usize;
        let [a, b, cc] = tri.map(|i| s.points[i as usize]);
        volume[c] += dot(a, cross(b, cc)) / 6.0;
        for p in [a, b, cc] {
            for k in 0..3 {
                lo[c][k] = lo[c][k].min(p[k]);
                hi[c][k] = hi[c][k].max(p[k]);
            }
        }
    }
    let mut depth = vec![0usize; nc];
    let mut inside: Vec<Option<usize>> = vec![None; nc];
    if nc > 1 {
        for i in 0..nc {
            let p = s.points[tris[comps[i][0] as usize][0] as usize];
            for j in 0..nc {
                let boxed = (0..3).all(|k| lo[j][k] <= lo[i][k] && hi[i][k] <= hi[j][k]);
                if j == i || !boxed {
                    continue;
                }
                let w: f64 = comps[j]
                    .iter()
                    .map(|&t| {
                        let [a, b, c] = tris[t as usize].map(|v| s.points[v as usize]);
                        solid_angle(p, a, b, c)
                    })
                    .sum::<f64>()
                    / (4.0 * std::f64::consts::PI);
                if w.abs() > 0.5 {
                    depth[i] += 1;
                    if inside[i].is_none_or(|k| volume[j].abs() < volume[k].abs()) {
                        inside[i] = Some(j);
                    }
                }
            }
        }
    }
    let mut flip = flip;
    for c in 0..nc {
        let want_positive = depth[c] % 2 == 0;
        if (volume[c] > 0.0) != want_positive {
            volume[c] = -volume[c];
            for &t in &comps[c] {
                flip[t as usize] = !flip[t as usize];
            }
        }
    }
    let mut flipped = 0;
    for (t, f) in s.triangles.iter_mut().zip(&flip) {
        if *f {
            t.swap(1, 2);
            flipped += 1;
        }
    }
    let mut used = vec![false; nv];
    for t in &s.triangles {
        for &v in t {
            used[v as usize] = true;
        }
    }
    let components = (0..nc)
        .map(|c| {
            let mut vs: Vec<u32> = comps[c]
                .iter()
                .flat_map(|&t| s.triangles[t as usize])
                .collect();
            vs.sort_unstable();
            vs.dedup();
            SurfaceComponent {
                triangles: comps[c].len(),
                vertices: vs.len(),
                first_triangle: comps[c][0] as usize,
                volume: volume[c],
                depth: depth[c],
                inside: inside[c],
            }
        })
        .collect();
    let bbox_min = [0, 1, 2].map(|k| lo.iter().map(|l| l[k]).fold(f64::INFINITY, f64::min));
    let bbox_max = [0, 1, 2].map(|k| hi.iter().map(|h| h[k]).fold(f64::NEG_INFINITY, f64::max));
    Ok(SurfaceReport {
        vertices: nv,
        triangles: nt,
        unused_vertices,
        flipped,
        components,
        enclosed_volume: s.enclosed_volume(),
        bbox_min,
        bbox_max,
        intersection_work,
    })
}

fn self_intersection(tris: &[[u32; 3]], m: Meeting) -> Error {
    let (ti, tj) = (tris[m.first], tris[m.second]);
    let shared: Vec<u32> = ti.iter().copied().filter(|v| tj.contains(v)).collect();
    let how = match (m.edge, &shared[..]) {
        (None, [a, b]) => format!(
            " beyond their common edge ({a}, {b}): they are coplanar and folded onto each other"
        ),
        (Some((a, b, t)), []) => format!(": edge ({a}, {b}) of triangle {t} meets the other"),
        (Some((a, b, t)), [v, ..]) => format!(
            " other than at their common vertex {v}: edge ({a}, {b}) of triangle {t} meets \
             the other"
        ),
        (None, _) => String::new(),
    };
    bad(format!(
        "self-intersection: triangles {} (vertices {}, {}, {}) and {} (vertices {}, {}, {}) \
         intersect{how}; a surface bounding a solid must not cross or touch itself",
        m.first, ti[0], ti[1], ti[2], m.second, tj[0], tj[1], tj[2]
    ))
}

fn check_degenerate(s: &Surface) -> Result<()> {
    for (t, &[a, b, c]) in s.triangles.iter().enumerate() {
        if a == b || b == c || a == c {
            let r = if a == b || a == c { a } else { b };
            return Err(bad(format!(
                "degenerate triangle {t} (vertices {a}, {b}, {c}): vertex {r} is repeated; \
                 a triangle needs three distinct vertices"
            )));
        }
        let [pa, pb, pc] = [a, b, c].map(|i| s.points[i as usize]);
        let area = 0.5 * norm(cross(sub(pb, pa), sub(pc, pa)));
        let h = norm(sub(pb, pa))
            .max(norm(sub(pc, pb)))
            .max(norm(sub(pa, pc)));
        if area <= DEGENERATE_REL * h * h {
            return Err(bad(format!(
                "degenerate triangle {t} (vertices {a}, {b}, {c}): zero area ({area:e}, \
                 longest edge {h:e}); its corners are collinear or coincide"
            )));
        }
    }
    Ok(())
}

const NONE: u32 = u32::MAX;

/// For each triangle and local edge `e` (from corner `e` to corner `e+1`), the triangle on the
/// other side. Errors on non-manifold and boundary edges.
fn edge_neighbours(tris: &[[u32; 3]]) -> Result<Vec<[u32; 3]>> {
    let key = |a: u32, b: u32| ((a.min(b) as u64) << 32) | a.max(b) as u64;
    let mut edges: Vec<(u64, u32, u8)> = Vec::with_capacity(3 * tris.len());
    for (t, tri) in tris.iter().enumerate() {
        for e in 0..3 {
            edges.push((key(tri[e], tri[(e + 1) % 3]), t as u32, e as u8));
        }
    }
    edges.sort_unstable();
    let mut nbr = vec![[NONE; 3]; tris.len()];
    let mut boundary = 0usize;
    let mut example: Option<(u32, u8)> = None;
    for run in edges.chunk_by(|x, y| x.0 == y.0) {
        match run {
            [_] => {
                boundary += 1;
                let (_, t, e) = run[0];
                if example.is_none_or(|(t0, _)| t < t0) {
                    example = Some((t, e));
                }
            }
            [(_, t, e), (_, u, f)] => {
                nbr[*t as usize][*e as usize] = *u;
                nbr[*u as usize][*f as usize] = *t;
            }
            _ => {
                let (k, _, _) = run[0];
                let ts: Vec<String> = run.iter().map(|r| r.1.to_string()).collect();
                return Err(bad(format!(
                    "non-manifold edge ({}, {}): in {} triangles ({}); an edge of a closed \
                     surface is in exactly two",
                    k >> 32,
                    k & 0xffff_ffff,
                    run.len(),
                    ts.join(", ")
                )));
            }
        }
    }
    if let Some((t, e)) = example {
        let tri = tris[t as usize];
        return Err(bad(format!(
            "not closed: {boundary} boundary edges, e.g. edge ({}, {}) of triangle {t}; every \
             edge must be shared by exactly two triangles",
            tri[e as usize],
            tri[(e as usize + 1) % 3]
        )));
    }
    Ok(nbr)
}

fn find(parent: &mut [u32], mut x: u32) -> u32 {
    while parent[x as usize] != x {
        let p = parent[parent[x as usize] as usize];
        parent[x as usize] = p;
        x = p;
    }
    x
}

/// Every vertex's triangles must form one fan (joined through edges at that vertex). Returns
/// the number of unused vertices.
fn check_vertex_fans(s: &Surface, nbr: &[[u32; 3]]) -> Result<usize> {
    let tris = &s.triangles;
    // Corner (t, k) is 3t + k.
    let mut parent: Vec<u32> = (0..3 * tris.len() as u32).collect();
    let corner_of = |u: u32, v: u32| -> u32 {
        let k = tris[u as usize].iter().position(|&w| w == v).unwrap_or(0);
        3 * u + k as u32
    };
    for (t, tri) in tris.iter().enumerate() {
        for k in 0..3 {
            // The edges at corner k are local edges k and k+2; both contain tri[k].
            for e in [k, (k + 2) % 3] {
                let u = nbr[t][e];
                let (a, b) = (
                    find(&mut parent, 3 * t as u32 + k as u32),
                    find(&mut parent, corner_of(u, tri[k])),
                );
                if a != b {
                    parent[a.max(b) as usize] = a.min(b);
                }
            }
        }
    }
    // Per vertex: the first fan root seen and a triangle of it.
    let mut root: Vec<(u32, u32)> = vec![(NONE, NONE); s.points.len()];
    for (t, tri) in tris.iter().enumerate() {
        for (k, &v) in tri.iter().enumerate() {
            let r = find(&mut parent, 3 * t as u32 + k as u32);
            let (r0, t0) = root[v as usize];
            if r0 == NONE {
                root[v as usize] = (r, t as u32);
            } else if r0 != r {
                return Err(bad(format!(
                    "non-manifold vertex {v}: its triangles form more than one fan, e.g. \
                     triangles {t0} and {t} meet at it but are not joined through edges around \
                     it (two sheets touching at a point)"
                )));
            }
        }
    }
    Ok(root.iter().filter(|r| r.0 == NONE).count())
}

/// Components and consistent orientation by breadth-first search. Returns the component of
/// each triangle, whether each triangle is flipped relative to the input, and each
/// component's triangles (sorted).
#[allow(clippy::type_complexity)]
fn orient_components(
    tris: &[[u32; 3]],
    nbr: &[[u32; 3]],
) -> Result<(Vec<u32>, Vec<bool>, Vec<Vec<u32>>)> {
    let nt = tris.len();
    let mut comp = vec![NONE; nt];
    let mut flip = vec![false; nt];
    let mut comps: Vec<Vec<u32>> = Vec::new();
    let mut queue = VecDeque::new();
    for start in 0..nt {
        if comp[start] != NONE {
            continue;
        }
        let c = comps.len() as u32;
        let mut members = vec![start as u32];
        comp[start] = c;
        queue.push_back(start);
        while let Some(t) = queue.pop_front() {
            for e in 0..3 {
                let (a, b) = (tris[t][e], tris[t][(e + 1) % 3]);
                let u = nbr[t][e] as usize;
                // Does u use the edge in the same direction a -> b as t (in the input)?
                let same = (0..3).any(|f| tris[u][f] == a && tris[u][(f + 1) % 3] == b);
                let want = flip[t] ^ same;
                if comp[u] == NONE {
                    comp[u] = c;
                    flip[u] = want;
                    members.push(u as u32);
                    queue.push_back(u);
                } else if flip[u] != want {
                    return Err(bad(format!(
                        "not orientable: the component of triangle {start} cannot be oriented \
                         consistently (a Moebius strip or Klein bottle); conflict at edge \
                         ({a}, {b}) between triangles {t} and {u}"
                    )));
                }
            }
        }
        members.sort_unstable();
        comps.push(members);
    }
    Ok((comp, flip, comps))
}

/// Solid angle of triangle (a, b, c) seen from p (Van Oosterom and Strackee), signed by the
/// triangle's orientation.
fn solid_angle(p: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    let (a, b, c) = (sub(a, p), sub(b, p), sub(c, p));
    let (la, lb, lc) = (norm(a), norm(b), norm(c));
    let num = dot(a, cross(b, c));
    let den = la * lb * lc + dot(a, b) * lc + dot(a, c) * lb + dot(b, c) * la;
    2.0 * num.atan2(den)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Axis-aligned cube `[o, o + h]³`, 8 vertices, 12 outward triangles.
    pub(crate) fn cube(o: f64, h: f64) -> Surface {
        let points = (0..8)
            .map(|i| {
                let b = [i & 1, (i >> 1) & 1, (i >> 2) & 1];
                b.map(|x| o + h * x as f64)
            })
            .collect();
        // Quads (outward, counter-clockwise seen from outside) on the vertex numbering
        // i = x + 2y + 4z.
        let quads = [
            [0, 2, 3, 1], // z = 0
            [4, 5, 7, 6], // z = 1
            [0, 1, 5, 4], // y = 0
            [2, 6, 7, 3], // y = 1
            [0, 4, 6, 2], // x = 0
            [1, 3, 7, 5], // x = 1
        ];
        let triangles = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        Surface { points, triangles }
    }

    /// Unit icosphere: the icosahedron with each triangle split in four `levels` times, new
    /// vertices pushed onto the sphere. Outward.
    pub(crate) fn icosphere(levels: usize) -> Surface {
        let t = (1.0 + 5f64.sqrt()) / 2.0;
        let mut points: Vec<[f64; 3]> = [
            [-1.0, t, 0.0],
            [1.0, t, 0.0],
            [-1.0, -t, 0.0],
            [1.0, -t, 0.0],
            [0.0, -1.0, t],
            [0.0, 1.0, t],
            [0.0, -1.0, -t],
            [0.0, 1.0, -t],
            [t, 0.0, -1.0],
            [t, 0.0, 1.0],
            [-t, 0.0, -1.0],
            [-t, 0.0, 1.0],
        ]
        .to_vec();
        let unit = |p: [f64; 3]| {
            let n = norm(p);
            p.map(|c| c / n)
        };
        for p in &mut points {
            *p = unit(*p);
        }
        let mut triangles: Vec<[u32; 3]> = vec![
            [0, 11, 5],
            [0, 5, 1],
            [0, 1, 7],
            [0, 7, 10],
            [0, 10, 11],
            [1, 5, 9],
            [5, 11, 4],
            [11, 10, 2],
            [10, 7, 6],
            [7, 1, 8],
            [3, 9, 4],
            [3, 4, 2],
            [3, 2, 6],
            [3, 6, 8],
            [3, 8, 9],
            [4, 9, 5],
            [2, 4, 11],
            [6, 2, 10],
            [8, 6, 7],
            [9, 8, 1],
        ];
        for _ in 0..levels {
            let mut mid = std::collections::HashMap::new();
            let mut next = Vec::new();
            for &[a, b, c] in &triangles {
                let mut m = |u: u32, v: u32| {
                    *mid.entry((u.min(v), u.max(v))).or_insert_with(|| {
                        let (p, q) = (points[u as usize], points[v as usize]);
                        points.push(unit([0, 1, 2].map(|k| p[k] + q[k])));
                        points.len() as u32 - 1
                    })
                };
                let (ab, bc, ca) = (m(a, b), m(b, c), m(c, a));
                next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
            }
            triangles = next;
        }
        Surface { points, triangles }
    }

    fn err(s: &mut Surface) -> String {
        let before = s.clone();
        let e = check_surface(s).unwrap_err();
        assert!(matches!(e, Error::BadSurface { .. }), "{e}");
        assert_eq!(
            *s, before,
            "a failed check must leave the surface as it was"
        );
        e.to_string()
    }

    #[test]
    fn cube_and_icosphere_pass_unchanged() {
        let mut c = cube(0.0, 2.0);
        let before = c.clone();
        let r = check_surface(&mut c).unwrap();
        assert_eq!(c, before);
        assert_eq!(r.flipped, 0);
        assert_eq!(r.components.len(), 1);
        assert_eq!(r.components[0].triangles, 12);
        assert_eq!(r.components[0].vertices, 8);
        assert!((r.enclosed_volume - 8.0).abs() < 1e-14);
        assert_eq!((r.bbox_min, r.bbox_max), ([0.0; 3], [2.0; 3]));

        let mut s = icosphere(3);
        let r = check_surface(&mut s).unwrap();
        assert_eq!((r.vertices, r.triangles, r.flipped), (642, 1280, 0));
        // Inscribed polyhedron: below 4π/3, within the second-order chord error.
        let v = r.enclosed_volume;
        let ball = 4.0 * std::f64::consts::PI / 3.0;
        assert!(v < ball && v > 0.97 * ball, "{v}");
    }

    #[test]
    fn flipped_triangles_are_repaired_and_counted() {
        let reference = icosphere(2);
        let mut s = reference.clone();
        let flipped = [0usize, 7, 8, 100, 101, 102, 250, 319];
        for &t in &flipped {
            s.triangles[t].swap(0, 1);
        }
        let r = check_surface(&mut s).unwrap();
        assert_eq!(r.flipped, flipped.len());
        // Same triangles as the reference, up to a cyclic shift of the corners.
        for (t, (a, b)) in s.triangles.iter().zip(&reference.triangles).enumerate() {
            let rot = |x: [u32; 3], k: usize| [x[k % 3], x[(k + 1) % 3], x[(k + 2) % 3]];
            assert!(
                (0..3).any(|k| rot(*a, k) == *b),
                "triangle {t}: {a:?} vs {b:?}"
            );
        }
        assert!((r.enclosed_volume - reference.enclosed_volume()).abs() < 1e-14);

        // An inside-out surface: every triangle turned, the volume becomes positive.
        let mut inv = reference.clone();
        for t in &mut inv.triangles {
            t.swap(1, 2);
        }
        assert!(inv.enclosed_volume() < 0.0);
        let r = check_surface(&mut inv).unwrap();
        assert_eq!(r.flipped, reference.triangles.len());
        assert!((r.enclosed_volume - reference.enclosed_volume()).abs() < 1e-14);
    }

    fn union(a: &Surface, b: &Surface) -> Surface {
        let n = a.points.len() as u32;
        let mut s = a.clone();
        s.points.extend_from_slice(&b.points);
        s.triangles
            .extend(b.triangles.iter().map(|t| t.map(|v| v + n)));
        s
    }

    #[test]
    fn cavity_is_kept_and_oriented_inward() {
        // A 3 m cube with a 1 m cube void inside, both written outward.
        let mut s = union(&cube(0.0, 3.0), &cube(1.0, 1.0));
        let r = check_surface(&mut s).unwrap();
        assert_eq!(r.components.len(), 2);
        assert_eq!(r.flipped, 12, "the cavity's triangles turn inward");
        let (outer, cav) = (&r.components[0], &r.components[1]);
        assert_eq!(
            (outer.depth, outer.inside, outer.is_cavity()),
            (0, None, false)
        );
        assert_eq!((cav.depth, cav.inside, cav.is_cavity()), (1, Some(0), true));
        assert_eq!((cav.triangles, cav.first_triangle), (12, 12));
        assert!((outer.volume - 27.0).abs() < 1e-12 && (cav.volume + 1.0).abs() < 1e-12);
        assert!((r.enclosed_volume - 26.0).abs() < 1e-12);

        // Two separate solids side by side: both outer, both positive.
        let mut s = union(&cube(0.0, 1.0), &cube(2.0, 1.0));
        let r = check_surface(&mut s).unwrap();
        assert_eq!(r.flipped, 0);
        assert!(r.components.iter().all(|c| c.depth == 0 && c.volume > 0.0));
        assert!((r.enclosed_volume - 2.0).abs() < 1e-12);
    }

    #[test]
    fn open_surface_is_refused_with_an_example_edge() {
        let mut s = cube(0.0, 1.0);
        s.triangles.remove(5);
        let e = err(&mut s);
        assert!(e.contains("not closed: 3 boundary edges"), "{e}");
        assert!(
            e.contains("e.g. edge (") && e.contains("of triangle"),
            "{e}"
        );
    }

    #[test]
    fn non_manifold_edge_is_named() {
        // A fin on the cube's edge (0, 1): that edge is then in three triangles.
        let mut s = cube(0.0, 1.0);
        s.points.push([0.5, -1.0, -1.0]);
        s.triangles.push([0, 1, 8]);
        let e = err(&mut s);
        assert!(
            e.contains("non-manifold edge (0, 1): in 3 triangles"),
            "{e}"
        );
        assert!(e.contains("12"), "the fin's triangle is named: {e}");
    }

    #[test]
    fn touching_solids_are_a_non_manifold_vertex() {
        // Two cubes sharing the corner vertex 7 = (1, 1, 1) by index.
        let a = cube(0.0, 1.0);
        let b = cube(1.0, 1.0);
        let mut s = union(&a, &b);
        for t in s.triangles.iter_mut().skip(12) {
            for v in t.iter_mut() {
                if *v == 8 {
                    *v = 7; // b's vertex 0 is (1, 1, 1)
                }
            }
        }
        let e = err(&mut s);
        assert!(e.contains("non-manifold vertex 7"), "{e}");
    }

    #[test]
    fn degenerate_triangles_are_named() {
        let mut s = cube(0.0, 1.0);
        s.triangles[4] = [2, 2, 7];
        let e = err(&mut s);
        assert!(
            e.contains("degenerate triangle 4 (vertices 2, 2, 7)"),
            "{e}"
        );
        assert!(e.contains("vertex 2 is repeated"), "{e}");

        let mut s = cube(0.0, 1.0);
        s.points.push([0.5, 0.0, 0.0]); // on the edge from vertex 0 to vertex 1
        s.triangles.push([0, 1, 8]);
        let e = err(&mut s);
        assert!(
            e.contains("degenerate triangle 12 (vertices 0, 1, 8): zero area"),
            "{e}"
        );
    }

    #[test]
    fn self_intersection_names_both_triangles() {
        // Two unit cubes overlapping by half.
        let mut s = union(&cube(0.0, 1.0), &cube(0.5, 1.0));
        let e = err(&mut s);
        assert!(e.contains("self-intersection: triangles "), "{e}");
        assert!(
            e.contains(" intersect: edge (") && e.contains(" meets the other"),
            "{e}"
        );

        // One component: a cube whose top vertex is pushed down through the bottom face.
        let mut s = cube(0.0, 1.0);
        s.points[7] = [1.0, 1.0, -0.5];
        let e = err(&mut s);
        assert!(e.contains("self-intersection"), "{e}");

        // The bottom face's two triangles folded onto each other about their diagonal (0, 3):
        // vertex 1 moved, in the face's plane, to vertex 2's side.
        let mut s = cube(0.0, 1.0);
        s.points[1] = [0.25, 0.75, 0.0];
        let e = err(&mut s);
        assert!(
            e.contains(
                "triangles 0 (vertices 0, 2, 3) and 1 (vertices 0, 3, 1) intersect beyond \
                 their common edge (0, 3): they are coplanar and folded onto each other"
            ),
            "{e}"
        );
    }

    /// The cone of `2 segments` triangles, axis along `axis`, radius 5 cm, height 10 cm.
    fn cone(segments: usize, axis: [f64; 3]) -> Surface {
        crate::mesh::generate::cone_surface(segments, 0.05, 0.1, axis).unwrap()
    }

    const TILTED: [f64; 3] = [0.3, 0.5, 0.8];

    /// Work per triangle (volume tests, candidates, predicates) at `n` and `10 n` triangles:
    /// testing pairs around a fan would multiply it by 10; a tree's descent adds a few nodes
    /// per level (`log n`), and the candidates and predicates near a triangle do not grow.
    fn grows_like_log_n(small: [f64; 3], big: [f64; 3]) {
        assert!(
            big[0] < 2.5 * small[0],
            "volume tests: {small:?} -> {big:?}"
        );
        for k in 1..3 {
            assert!(big[k] < 1.5 * small[k] + 1.0, "{small:?} -> {big:?}");
        }
    }

    #[test]
    fn fan_cone_self_intersection_check_is_not_quadratic() {
        // The side and the base of a cone are fans of long thin triangles whose boxes all
        // overlap at the apex and the centre: the check once tested every pair of them
        // (20k triangles took minutes). Work per triangle must not grow with the fan.
        let mut per_triangle = Vec::new();
        for (segments, axis) in [
            (1_000, TILTED),
            (10_000, TILTED),
            (1_000, [0.0, 0.0, 1.0]),
            (10_000, [0.0, 0.0, 1.0]),
        ] {
            let mut s = cone(segments, axis);
            let before = s.clone();
            let r = check_surface(&mut s).unwrap();
            assert_eq!(s, before, "a valid outward cone is left as it is");
            assert_eq!(
                (r.triangles, r.flipped, r.components.len()),
                (2 * segments, 0, 1)
            );
            let n = segments as f64;
            let v = n / 2.0 * 0.05f64.powi(2) * (std::f64::consts::TAU / n).sin() * 0.1 / 3.0;
            assert!(
                (r.enclosed_volume - v).abs() < 1e-9 * v,
                "{} vs {v}",
                r.enclosed_volume
            );
            let w = r.intersection_work;
            let nt = r.triangles as f64;
            per_triangle.push([w.volume_tests, w.candidates, w.predicates].map(|x| x as f64 / nt));
        }
        for pair in per_triangle.chunks(2) {
            grows_like_log_n(pair[0], pair[1]);
            assert!(pair[1][1] < 10.0, "candidates per triangle: {pair:?}");
        }
    }

    /// A cylinder as CAD writes it: `segments` rim vertices at each end, the side quads
    /// split into two long thin triangles, each cap a fan around its rim vertex 0. Axis along
    /// `axis`, radius 5 cm, length 10 cm; `4 segments - 4` triangles, outward.
    fn cad_cylinder(segments: usize, axis: [f64; 3]) -> Surface {
        let c = cone(segments, axis);
        let top = c.points[0];
        let mut points: Vec<[f64; 3]> = c.points[2..].to_vec();
        points.extend(
            c.points[2..]
                .iter()
                .map(|p| [0, 1, 2].map(|k| p[k] + top[k])),
        );
        let n = segments as u32;
        let mut triangles = Vec::new();
        for i in 0..n {
            let j = (i + 1) % n;
            triangles.extend([[i, j, n + j], [i, n + j, n + i]]);
        }
        for i in 1..n - 1 {
            triangles.extend([[0, i + 1, i], [n, n + i, n + i + 1]]);
        }
        Surface { points, triangles }
    }

    #[test]
    fn cad_cylinder_of_slivers_and_fan_caps_is_checked_in_linear_work() {
        // Side slivers as long as the cylinder, tilted (their axis-aligned boxes overlap by
        // the hundred), caps fanned from one rim vertex.
        let mut per_triangle = Vec::new();
        for segments in [500, 5_000] {
            let mut s = cad_cylinder(segments, TILTED);
            let r = check_surface(&mut s).unwrap();
            assert_eq!((r.flipped, r.components.len()), (0, 1));
            let w = r.intersection_work;
            let nt = r.triangles as f64;
            per_triangle.push([w.volume_tests, w.candidates, w.predicates].map(|x| x as f64 / nt));
        }
        grows_like_log_n(per_triangle[0], per_triangle[1]);
    }

    #[test]
    fn folded_fan_is_a_self_intersection_naming_its_triangles() {
        // Rim vertex k moved along the rim past its next two neighbours: the fan folds, its
        // triangles around k cross their neighbours (at the apex's side and at the base's).
        let segments = 1_000;
        let mut s = cone(segments, TILTED);
        let k = 500;
        let rim = |s: &Surface, i: usize| s.points[2 + i % segments];
        let (a, b) = (rim(&s, k + 2), rim(&s, k + 3));
        let m = [0, 1, 2].map(|j| a[j] + b[j]);
        s.points[2 + k] = m.map(|c| c * 0.05 / norm(m));
        let e = err(&mut s);
        assert!(e.contains("self-intersection: triangles "), "{e}");
        let named: Vec<usize> = e
            .split("triangles ")
            .nth(1)
            .map(|rest| {
                rest.split(" and ")
                    .take(2)
                    .filter_map(|w| w.split(' ').next()?.parse().ok())
                    .collect()
            })
            .unwrap_or_default();
        let [i, j] = named[..] else {
            panic!("two triangles named: {e}")
        };
        // The fold is near rim vertex k: both named triangles are within three of it.
        let near = |t: usize| {
            let i = t % segments;
            (k - 3..=k + 3).contains(&i)
        };
        assert!(near(i) && near(j) && i != j, "{e}");
        let moved = (2 + k) as u32;
        assert!(
            s.triangles[i].contains(&moved) || s.triangles[j].contains(&moved),
            "one of them has the moved vertex: {e}"
        );
    }

    #[test]
    fn millimetre_hint() {
        let liver_mm = ([25.7, 60.8, 43.5], [220.0, 214.6, 200.0]);
        assert!(looks_like_millimetres(liver_mm, 1.0));
        assert!(!looks_like_millimetres(liver_mm, 1e-3));
        assert!(!looks_like_millimetres(([0.0; 3], [0.2, 0.15, 0.1]), 1.0));
    }
}
