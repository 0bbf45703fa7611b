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
//!   by index. Candidate pairs come from a bounding-volume hierarchy over the triangles' boxes;
//!   each pair is decided exactly with Shewchuk's adaptive `orient3d` / `orient2d` predicates
//!   (`robust` crate), touching counts as intersecting. Two non-coplanar triangles with no common
//!   vertex intersect iff an edge of one meets the other (closed segment–triangle test); with
//!   one common vertex `v`, `(v, a, b)` and `(v, c, d)` meet elsewhere iff segment `ab` meets
//!   the second or `cd` meets the first; with a common edge they overlap iff they are coplanar
//!   and on the same side of that edge.
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
//! One concern, the checks of a closed surface, in one file; about a third of it is tests.

use std::collections::VecDeque;

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

/// Work of the self-intersection test, in counts that do not depend on the machine.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct IntersectionWork {
    /// Bounding-volume tests of the broad phase.
    pub volume_tests: u64,
    /// Pairs the broad phase passed to the exact test.
    pub candidates: u64,
    /// Exact orientation predicates evaluated (`orient3d` and `orient2d`).
    pub predicates: u64,
}

/// About how many times [`check_surface_with_progress`] reports its progress.
const PROGRESS_CALLS: usize = 100;

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
/// self-intersection test, the check's longest step, runs (`done` of `total` items tested;
/// the last call has `done == total`).
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
    let intersection_work = check_self_intersections(&s.points, &tris, progress)?;

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

// ---------------------------------------------------------------------------------------------
// Self-intersections.

/// A bounding-volume hierarchy over boxes: leaves of at most 4, split at the median centroid
/// along the longest axis.
struct Bvh {
    nodes: Vec<BvhNode>,
    items: Vec<u32>,
}

struct BvhNode {
    lo: [f64; 3],
    hi: [f64; 3],
    /// Leaf: `items[start..start + len]`; inner node (len == 0): children `start`, `start + 1`.
    start: u32,
    len: u32,
}

impl Bvh {
    fn new(boxes: &[([f64; 3], [f64; 3])]) -> Bvh {
        let mut bvh = Bvh {
            nodes: Vec::with_capacity(boxes.len() / 2 + 1),
            items: (0..boxes.len() as u32).collect(),
        };
        bvh.nodes.push(BvhNode {
            lo: [0.0; 3],
            hi: [0.0; 3],
            start: 0,
            len: 0,
        });
        bvh.build(0, 0, boxes.len(), boxes);
        bvh
    }

    fn build(&mut self, node: usize, start: usize, end: usize, boxes: &[([f64; 3], [f64; 3])]) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        let mut clo = [f64::INFINITY; 3];
        let mut chi = [f64::NEG_INFINITY; 3];
        for &i in &self.items[start..end] {
            let (l, h) = boxes[i as usize];
            for k in 0..3 {
                lo[k] = lo[k].min(l[k]);
                hi[k] = hi[k].max(h[k]);
                let c = 0.5 * (l[k] + h[k]);
                clo[k] = clo[k].min(c);
                chi[k] = chi[k].max(c);
            }
        }
        self.nodes[node].lo = lo;
        self.nodes[node].hi = hi;
        if end - start <= 4 {
            self.nodes[node].start = start as u32;
            self.nodes[node].len = (end - start) as u32;
            return;
        }
        let axis = (0..3)
            .max_by(|&a, &b| (chi[a] - clo[a]).total_cmp(&(chi[b] - clo[b])))
            .unwrap_or(0);
        let mid = (start + end) / 2;
        let centre = |i: &u32| {
            let (l, h) = boxes[*i as usize];
            l[axis] + h[axis]
        };
        self.items[start..end].select_nth_unstable_by(mid - start, |a, b| {
            centre(a).total_cmp(&centre(b)).then(a.cmp(b))
        });
        let left = self.nodes.len();
        for _ in 0..2 {
            self.nodes.push(BvhNode {
                lo: [0.0; 3],
                hi: [0.0; 3],
                start: 0,
                len: 0,
            });
        }
        self.nodes[node].start = left as u32;
        self.build(left, start, mid, boxes);
        self.build(left + 1, mid, end, boxes);
    }

    /// Items whose boxes overlap `(lo, hi)` (closed), appended to `out`.
    /// Returns the number of nodes tested.
    fn query(&self, lo: [f64; 3], hi: [f64; 3], stack: &mut Vec<u32>, out: &mut Vec<u32>) -> u64 {
        stack.clear();
        stack.push(0);
        let mut tested = 0;
        while let Some(n) = stack.pop() {
            tested += 1;
            let node = &self.nodes[n as usize];
            if (0..3).any(|k| node.hi[k] < lo[k] || hi[k] < node.lo[k]) {
                continue;
            }
            if node.len > 0 {
                let s = node.start as usize;
                out.extend_from_slice(&self.items[s..s + node.len as usize]);
            } else {
                stack.push(node.start);
                stack.push(node.start + 1);
            }
        }
        tested
    }
}

fn check_self_intersections(
    points: &[[f64; 3]],
    tris: &[[u32; 3]],
    progress: &mut dyn FnMut(usize, usize),
) -> Result<IntersectionWork> {
    let boxes: Vec<([f64; 3], [f64; 3])> = tris
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| points[i as usize]);
            (
                [0, 1, 2].map(|k| a[k].min(b[k]).min(c[k])),
                [0, 1, 2].map(|k| a[k].max(b[k]).max(c[k])),
            )
        })
        .collect();
    let bvh = Bvh::new(&boxes);
    let mut stack = Vec::new();
    let mut cand = Vec::new();
    let mut work = IntersectionWork::default();
    let n = &mut work.predicates;
    let step = tris.len().div_ceil(PROGRESS_CALLS).max(1);
    for (i, ti) in tris.iter().enumerate() {
        if i % step == 0 {
            progress(i, tris.len());
        }
        cand.clear();
        work.volume_tests += bvh.query(boxes[i].0, boxes[i].1, &mut stack, &mut cand);
        cand.retain(|&j| j as usize > i);
        cand.sort_unstable();
        work.candidates += cand.len() as u64;
        for &j in &cand {
            let tj = &tris[j as usize];
            if triangles_intersect(n, points, ti, tj) {
                let shared: Vec<String> = ti
                    .iter()
                    .filter(|v| tj.contains(v))
                    .map(|v| v.to_string())
                    .collect();
                let how = if shared.is_empty() {
                    String::new()
                } else {
                    format!(
                        " other than at their common vertex {}",
                        shared.join(" and ")
                    )
                };
                return Err(bad(format!(
                    "self-intersection: triangles {i} (vertices {}, {}, {}) and {j} (vertices \
                     {}, {}, {}) intersect{how}; a surface bounding a solid must not cross or \
                     touch itself",
                    ti[0], ti[1], ti[2], tj[0], tj[1], tj[2]
                )));
            }
        }
    }
    progress(tris.len(), tris.len());
    Ok(work)
}

fn o3(n: &mut u64, a: [f64; 3], b: [f64; 3], c: [f64; 3], d: [f64; 3]) -> i8 {
    let p = |v: [f64; 3]| robust::Coord3D {
        x: v[0],
        y: v[1],
        z: v[2],
    };
    *n += 1;
    sign(robust::orient3d(p(a), p(b), p(c), p(d)))
}

fn o2(n: &mut u64, a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> i8 {
    let p = |v: [f64; 2]| robust::Coord { x: v[0], y: v[1] };
    *n += 1;
    sign(robust::orient2d(p(a), p(b), p(c)))
}

fn sign(x: f64) -> i8 {
    if x > 0.0 {
        1
    } else if x < 0.0 {
        -1
    } else {
        0
    }
}

/// Drop the coordinate along which the triangle's normal is largest.
fn projector(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> impl Fn([f64; 3]) -> [f64; 2] {
    let n = cross(sub(b, a), sub(c, a)).map(f64::abs);
    let k = if n[0] >= n[1] && n[0] >= n[2] {
        0
    } else if n[1] >= n[2] {
        1
    } else {
        2
    };
    move |p: [f64; 3]| [p[(k + 1) % 3], p[(k + 2) % 3]]
}

/// Whether two triangles meet anywhere other than in the vertices and edge they share by
/// index (exact).
fn triangles_intersect(n: &mut u64, points: &[[f64; 3]], ti: &[u32; 3], tj: &[u32; 3]) -> bool {
    let p = |v: u32| points[v as usize];
    let shared: Vec<u32> = ti.iter().copied().filter(|v| tj.contains(v)).collect();
    match shared.len() {
        0 => {
            let [a, b, c] = ti.map(p);
            let [d, e, f] = tj.map(p);
            // Quick reject: one triangle strictly on one side of the other's plane.
            let s = [o3(n, a, b, c, d), o3(n, a, b, c, e), o3(n, a, b, c, f)];
            if s.iter().all(|&x| x > 0) || s.iter().all(|&x| x < 0) {
                return false;
            }
            let s = [o3(n, d, e, f, a), o3(n, d, e, f, b), o3(n, d, e, f, c)];
            if s.iter().all(|&x| x > 0) || s.iter().all(|&x| x < 0) {
                return false;
            }
            segment_triangle(n, a, b, d, e, f)
                || segment_triangle(n, b, c, d, e, f)
                || segment_triangle(n, c, a, d, e, f)
                || segment_triangle(n, d, e, a, b, c)
                || segment_triangle(n, e, f, a, b, c)
                || segment_triangle(n, f, d, a, b, c)
        }
        1 => {
            let v = shared[0];
            let others = |t: &[u32; 3]| {
                let k = t.iter().position(|&w| w == v).unwrap_or(0);
                (t[(k + 1) % 3], t[(k + 2) % 3])
            };
            let (a, b) = others(ti);
            let (c, d) = others(tj);
            let (pv, pa, pb, pc, pd) = (p(v), p(a), p(b), p(c), p(d));
            segment_triangle(n, pa, pb, pv, pc, pd) || segment_triangle(n, pc, pd, pv, pa, pb)
        }
        2 => {
            let c = ti
                .iter()
                .copied()
                .find(|v| !tj.contains(v))
                .unwrap_or(ti[0]);
            let d = tj
                .iter()
                .copied()
                .find(|v| !ti.contains(v))
                .unwrap_or(tj[0]);
            let (a, b) = (p(shared[0]), p(shared[1]));
            let (pc, pd) = (p(c), p(d));
            if o3(n, a, b, pc, pd) != 0 {
                return false;
            }
            let pr = projector(a, b, pc);
            o2(n, pr(a), pr(b), pr(pc)) == o2(n, pr(a), pr(b), pr(pd))
        }
        _ => true,
    }
}

/// Whether the closed segment pq meets the closed triangle abc (non-degenerate), exactly.
fn segment_triangle(
    n: &mut u64,
    p: [f64; 3],
    q: [f64; 3],
    a: [f64; 3],
    b: [f64; 3],
    c: [f64; 3],
) -> bool {
    let sp = o3(n, a, b, c, p);
    let sq = o3(n, a, b, c, q);
    if sp * sq > 0 {
        return false;
    }
    if sp == 0 && sq == 0 {
        let pr = projector(a, b, c);
        return segment_triangle_2d(n, pr(p), pr(q), pr(a), pr(b), pr(c));
    }
    let s = [o3(n, p, q, a, b), o3(n, p, q, b, c), o3(n, p, q, c, a)];
    !(s.iter().any(|&x| x > 0) && s.iter().any(|&x| x < 0))
}

fn point_in_triangle_2d(n: &mut u64, p: [f64; 2], a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> bool {
    let s = [o2(n, a, b, p), o2(n, b, c, p), o2(n, c, a, p)];
    !(s.iter().any(|&x| x > 0) && s.iter().any(|&x| x < 0))
}

fn on_segment_2d(p: [f64; 2], q: [f64; 2], r: [f64; 2]) -> bool {
    // r collinear with pq: inside the segment's box.
    (0..2).all(|k| p[k].min(q[k]) <= r[k] && r[k] <= p[k].max(q[k]))
}

fn segments_2d(n: &mut u64, p: [f64; 2], q: [f64; 2], a: [f64; 2], b: [f64; 2]) -> bool {
    let (d1, d2) = (o2(n, p, q, a), o2(n, p, q, b));
    let (d3, d4) = (o2(n, a, b, p), o2(n, a, b, q));
    if d1 * d2 < 0 && d3 * d4 < 0 {
        return true;
    }
    (d1 == 0 && on_segment_2d(p, q, a))
        || (d2 == 0 && on_segment_2d(p, q, b))
        || (d3 == 0 && on_segment_2d(a, b, p))
        || (d4 == 0 && on_segment_2d(a, b, q))
}

fn segment_triangle_2d(
    n: &mut u64,
    p: [f64; 2],
    q: [f64; 2],
    a: [f64; 2],
    b: [f64; 2],
    c: [f64; 2],
) -> bool {
    point_in_triangle_2d(n, p, a, b, c)
        || point_in_triangle_2d(n, q, a, b, c)
        || segments_2d(n, p, q, a, b)
        || segments_2d(n, p, q, b, c)
        || segments_2d(n, p, q, c, a)
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
        assert!(e.contains(" intersect"), "{e}");

        // One component: a cube whose top vertex is pushed down through the bottom face.
        let mut s = cube(0.0, 1.0);
        s.points[7] = [1.0, 1.0, -0.5];
        let e = err(&mut s);
        assert!(e.contains("self-intersection"), "{e}");
    }

    #[test]
    fn triangle_pair_predicate() {
        let pts = [
            [0.0, 0.0, 0.0],   // 0
            [1.0, 0.0, 0.0],   // 1
            [0.0, 1.0, 0.0],   // 2
            [0.0, 0.0, 1.0],   // 3
            [1.0, 1.0, 0.0],   // 4
            [0.2, 0.2, -1.0],  // 5
            [0.2, 0.2, 1.0],   // 6
            [0.3, 0.3, 1.0],   // 7
            [0.5, 0.5, 0.0],   // 8: on edge (1, 2)
            [-1.0, -1.0, 0.0], // 9
            [0.25, 0.25, 0.0], // 10: inside triangle (0, 1, 2)
        ];
        let x = |a: [u32; 3], b: [u32; 3]| triangles_intersect(&mut 0, &pts, &a, &b);
        // Common edge, folded at a right angle: only the edge.
        assert!(!x([0, 1, 2], [0, 1, 3]));
        // Common edge, coplanar, opposite sides: only the edge. Same side: overlap.
        assert!(!x([0, 1, 2], [1, 2, 4]));
        assert!(x([0, 1, 2], [1, 2, 10]));
        // Common vertex only, planes crossing elsewhere: a segment pierces.
        assert!(x([0, 1, 2], [0, 5, 7]));
        assert!(!x([0, 1, 2], [0, 3, 9]));
        // No common vertex: a vertical triangle piercing the middle.
        assert!(x([0, 1, 2], [5, 6, 7]));
        // Touching at a point counts (vertex 8 on the edge (1, 2)).
        assert!(x([0, 1, 2], [8, 6, 7]));
        // Coplanar, one inside the other without edge crossings.
        let tiny = [[0.2, 0.2, 0.0], [0.3, 0.2, 0.0], [0.2, 0.3, 0.0]];
        let mut p2 = pts.to_vec();
        p2.extend_from_slice(&tiny);
        assert!(triangles_intersect(&mut 0, &p2, &[0, 1, 2], &[11, 12, 13]));
        // Disjoint.
        assert!(!x([0, 1, 2], [3, 6, 7]));
    }

    #[test]
    fn millimetre_hint() {
        let liver_mm = ([25.7, 60.8, 43.5], [220.0, 214.6, 200.0]);
        assert!(looks_like_millimetres(liver_mm, 1.0));
        assert!(!looks_like_millimetres(liver_mm, 1e-3));
        assert!(!looks_like_millimetres(([0.0; 3], [0.2, 0.15, 0.1]), 1.0));
    }
}
