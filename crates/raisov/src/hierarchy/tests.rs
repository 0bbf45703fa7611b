use std::collections::HashMap;

use super::*;
use crate::geometry::{cross, dot, norm, sub};
use crate::mesh::{tet_volume, tri_area, ElementKind, Mesh};

/// xorshift64: deterministic pseudo-random numbers in [0, 1).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.next()
    }
}

/// Structured tetrahedra of the box `[lo, hi]` with `n` cells per axis, 6 (Kuhn) tets per
/// cube, positive. Interior nodes moved by up to `perturb` cell sizes (seeded).
fn box_tets(n: [usize; 3], lo: [f64; 3], hi: [f64; 3], perturb: f64, seed: u64) -> Mesh {
    let mut rng = Rng(seed);
    let h = [0, 1, 2].map(|k| (hi[k] - lo[k]) / n[k] as f64);
    let id = |i: usize, j: usize, k: usize| (i + (n[0] + 1) * (j + (n[1] + 1) * k)) as u32;
    let mut nodes = Vec::with_capacity((n[0] + 1) * (n[1] + 1) * (n[2] + 1));
    for k in 0..=n[2] {
        for j in 0..=n[1] {
            for i in 0..=n[0] {
                let ijk = [i, j, k];
                let interior = (0..3).all(|b| ijk[b] > 0 && ijk[b] < n[b]);
                let mut x = [0.0; 3];
                for a in 0..3 {
                    x[a] = lo[a] + h[a] * ijk[a] as f64;
                    if perturb > 0.0 && interior {
                        x[a] += perturb * h[a] * rng.range(-1.0, 1.0);
                    }
                }
                nodes.push(x);
            }
        }
    }
    let perms = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    let mut cells = Vec::with_capacity(6 * 4 * n[0] * n[1] * n[2]);
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                for p in perms {
                    let mut c = [i, j, k];
                    let mut t = [id(c[0], c[1], c[2]); 4];
                    for (s, &axis) in p.iter().enumerate() {
                        c[axis] += 1;
                        t[s + 1] = id(c[0], c[1], c[2]);
                    }
                    let x = |q: u32| nodes[q as usize];
                    if tet_volume(x(t[0]), x(t[1]), x(t[2]), x(t[3])) < 0.0 {
                        t.swap(2, 3);
                    }
                    cells.extend_from_slice(&t);
                }
            }
        }
    }
    Mesh::new(ElementKind::Tet4, nodes, cells)
}

/// Structured triangles of a (u, v) grid mapped through `f`, interior nodes perturbed.
fn grid_tris(n: usize, perturb: f64, seed: u64, f: impl Fn(f64, f64) -> [f64; 3]) -> Mesh {
    let mut rng = Rng(seed);
    let h = 1.0 / n as f64;
    let mut nodes = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (mut u, mut v) = (i as f64 * h, j as f64 * h);
            if i > 0 && i < n && j > 0 && j < n {
                u += perturb * h * rng.range(-1.0, 1.0);
                v += perturb * h * rng.range(-1.0, 1.0);
            }
            nodes.push(f(u, v));
        }
    }
    let id = |i: usize, j: usize| (i + (n + 1) * j) as u32;
    let mut cells = Vec::new();
    for j in 0..n {
        for i in 0..n {
            // Alternate the diagonal for a less regular pattern.
            if (i + j) % 2 == 0 {
                cells.extend([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                cells.extend([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            } else {
                cells.extend([id(i, j), id(i + 1, j), id(i, j + 1)]);
                cells.extend([id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
    }
    Mesh::new(ElementKind::Tri3, nodes, cells)
}

fn plane(u: f64, v: f64) -> [f64; 3] {
    [u, v, 0.0]
}

/// Reference position of point θ from its weights.
fn reproduced(t: &Transfer, target: &Mesh, th: usize) -> [f64; 3] {
    let mut x = [0.0; 3];
    for j in 0..t.npe {
        let y = target.nodes[t.nodes[th][j] as usize];
        for k in 0..3 {
            x[k] += t.weights[th][j] * y[k];
        }
    }
    x
}

fn diag(m: &Mesh) -> f64 {
    let (lo, hi) = m.bounding_box();
    norm(sub(hi, lo))
}

/// Largest |Σ ω x − p| relative to the target's bounding-box diagonal, and largest
/// |Σ ω − 1|.
fn reproduction_error(points: &[[f64; 3]], target: &Mesh, t: &Transfer) -> (f64, f64) {
    let mut e: f64 = 0.0;
    let mut s: f64 = 0.0;
    for (th, &p) in points.iter().enumerate() {
        e = e.max(norm(sub(reproduced(t, target, th), p)));
        let sum: f64 = t.weights[th][..t.npe].iter().sum();
        s = s.max((sum - 1.0).abs());
        assert_eq!(t.host[th] as usize * t.npe, {
            // The stored nodes are the host's.
            let el = target.element(t.host[th] as usize);
            assert_eq!(&t.nodes[th][..t.npe], el);
            t.host[th] as usize * t.npe
        });
    }
    (e / diag(target), s)
}

/// Brute-force eq. 7 over the boundary elements: (element, ratio), ties to the lowest id.
fn brute_eq7(target: &Mesh, p: [f64; 3]) -> u32 {
    let bnd: Vec<[u32; 3]> = target.boundary_facets();
    let npe = target.npe();
    let mut keys: std::collections::HashSet<Vec<u32>> = std::collections::HashSet::new();
    for f in &bnd {
        let mut k: Vec<u32> = f.iter().copied().filter(|&x| x != u32::MAX).collect();
        k.sort_unstable();
        keys.insert(k);
    }
    let mut best = (u32::MAX, f64::NEG_INFINITY);
    for e in 0..target.num_elements() {
        let el = target.element(e);
        let is_bnd = (0..npe).any(|skip| {
            let mut k: Vec<u32> = (0..npe).filter(|&j| j != skip).map(|j| el[j]).collect();
            k.sort_unstable();
            keys.contains(&k)
        });
        if !is_bnd {
            continue;
        }
        let mut c = [0.0; 3];
        for &n in el {
            for (ck, xk) in c.iter_mut().zip(target.nodes[n as usize]) {
                *ck += xk;
            }
        }
        c = c.map(|x| x / npe as f64);
        let d = sub(p, c);
        let g2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        let r = target.element_measure(e).abs() / g2.sqrt();
        if r > best.1 {
            best = (e as u32, r);
        }
    }
    best.0
}

#[test]
fn tet_inside_points_are_reproduced() {
    let m = box_tets([4, 3, 5], [0.0; 3], [1.0, 0.8, 1.2], 0.25, 7);
    let mut rng = Rng(99);
    let pts: Vec<[f64; 3]> = (0..2000)
        .map(|_| [rng.next(), 0.8 * rng.next(), 1.2 * rng.next()])
        .chain(m.nodes.iter().copied())
        .collect();
    let t = Transfer::build(&pts, &m).unwrap();
    assert!(t.outside.is_empty(), "{:?}", t.outside);
    assert_eq!(t.max_extrapolation, 0.0);
    let (e, s) = reproduction_error(&pts, &m, &t);
    assert!(e < 1e-14, "{e}");
    assert!(s < 1e-14, "{s}");
    for w in &t.weights {
        assert!(w
            .iter()
            .all(|x| (-INSIDE_TOL..=1.0 + INSIDE_TOL).contains(x)));
    }
}

#[test]
fn tet_outside_points_follow_eq7_and_are_reproduced() {
    let m = box_tets([3, 3, 3], [0.0; 3], [1.0; 3], 0.2, 3);
    let mut rng = Rng(5);
    let mut pts = Vec::new();
    while pts.len() < 300 {
        let p = [0, 1, 2].map(|_| rng.range(-0.4, 1.4));
        if p.iter().any(|&x| !(0.0..=1.0).contains(&x)) {
            pts.push(p);
        }
    }
    let t = Transfer::build(&pts, &m).unwrap();
    assert_eq!(t.outside, (0..300).collect::<Vec<u32>>());
    let (e, s) = reproduction_error(&pts, &m, &t);
    assert!(e < 1e-13, "{e}");
    assert!(s < 1e-13, "{s}");
    let mut ext: f64 = 0.0;
    for (i, &p) in pts.iter().enumerate() {
        assert_eq!(t.host[i], brute_eq7(&m, p), "point {i}");
        let w = &t.weights[i];
        ext = ext
            .max(-w.iter().copied().fold(f64::INFINITY, f64::min))
            .max(w.iter().copied().fold(f64::NEG_INFINITY, f64::max) - 1.0);
    }
    assert_eq!(t.max_extrapolation, ext);
    assert!(ext > 0.0);
}

/// Paper Fig. 2, right: P equidistant from the centroids of a large and a small boundary
/// triangle is hosted by the larger one; also when the small one's centroid is a bit closer.
#[test]
fn eq7_prefers_the_larger_of_two_equidistant_elements() {
    // Triangle 0 (p1, p2, p3): area 1.125; triangle 1 (p2, p4, p5): area 0.5; they share p2.
    let m = Mesh::new(
        ElementKind::Tri3,
        vec![
            [-1.5, 0.0, 0.0],
            [0.0, 0.0, 0.0],
            [-0.75, -1.5, 0.0],
            [1.0, 0.0, 0.0],
            [0.5, -1.0, 0.0],
        ],
        vec![0, 1, 2, 1, 3, 4],
    );
    let centroid = |e: usize| {
        let el = m.element(e);
        [0, 1, 2].map(|k| el.iter().map(|&n| m.nodes[n as usize][k]).sum::<f64>() / 3.0)
    };
    let (c0, c1) = (centroid(0), centroid(1));
    // On the perpendicular bisector of c0 c1, above both triangles.
    let mid = [0.5 * (c0[0] + c1[0]), 0.5 * (c0[1] + c1[1]), 0.0];
    let d = sub(c1, c0);
    let p = [mid[0] - 2.0 * d[1], mid[1] + 2.0 * d[0], 0.0];
    assert!(p[1] > 0.0);
    let (g0, g1) = (norm(sub(p, c0)), norm(sub(p, c1)));
    assert!((g0 - g1).abs() < 1e-12);
    // Slightly closer to the small triangle's centroid: nearest-centroid would pick it.
    let q = [p[0] + 0.2, p[1], 0.0];
    assert!(norm(sub(q, c1)) < norm(sub(q, c0)));
    // Just outside the small triangle and far from the large one: the small one wins.
    let r = [1.0, 0.05, 0.0];
    let pts = [p, q, r];
    let t = Transfer::build(&pts, &m).unwrap();
    assert_eq!(t.outside, vec![0, 1, 2]);
    assert_eq!(t.host, vec![0, 0, 1]);
    assert!((tri_area(m.nodes[0], m.nodes[1], m.nodes[2]) - 1.125).abs() < 1e-12);
    let (e, _) = reproduction_error(&pts, &m, &t);
    assert!(e < 1e-14);
}

/// f(x) = a + B x, `comps` = 3, at the nodes of a mesh.
fn linear_field(nodes: &[[f64; 3]]) -> Vec<f64> {
    let a = [0.3, -1.2, 2.0];
    let b = [[1.5, -0.7, 0.2], [0.1, 2.5, -1.1], [-0.4, 0.9, 3.3]];
    nodes
        .iter()
        .flat_map(|x| [0, 1, 2].map(|i| a[i] + dot(b[i], *x)))
        .collect()
}

fn assert_linear_reproduced(t: &Transfer, target: &Mesh, points: &[[f64; 3]]) {
    let src = linear_field(&target.nodes);
    let want = linear_field(points);
    let mut out = vec![0.0; 3 * points.len()];
    t.interpolate(&src, 3, &mut out).unwrap();
    let err = out
        .iter()
        .zip(&want)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(err < 1e-12, "{err}");
    // interpolate_add adds the same.
    let mut out2 = vec![1.0; 3 * points.len()];
    t.interpolate_add(&src, 3, &mut out2).unwrap();
    for (a, b) in out2.iter().zip(&out) {
        assert_eq!(*a, 1.0 + b);
    }
}

#[test]
fn linear_fields_are_reproduced_both_ways() {
    // Coarse box slightly smaller and shifted: some fine nodes fall outside it and are
    // extrapolated, which a linear field survives exactly too.
    let fine = box_tets([6, 5, 6], [0.0; 3], [1.0; 3], 0.2, 11);
    let coarse = box_tets([3, 3, 4], [0.02, -0.01, 0.0], [0.97, 1.0, 1.03], 0.2, 12);
    let c = Correspondence::build(&fine, &coarse).unwrap();
    assert!(c.report.fine_outside > 0 && c.report.coarse_outside > 0);
    assert_linear_reproduced(&c.down, &coarse, &fine.nodes);
    assert_linear_reproduced(&c.up, &fine, &coarse.nodes);
    println!("{}", c.report);
}

#[test]
fn transpose_is_the_adjoint_of_interpolate() {
    let fine = box_tets([5, 4, 4], [0.0; 3], [1.0; 3], 0.2, 21);
    let coarse = box_tets([3, 2, 3], [0.0; 3], [1.0; 3], 0.2, 22);
    let c = Correspondence::build(&fine, &coarse).unwrap();
    let mut rng = Rng(77);
    for t in [&c.down, &c.up] {
        for comps in [1, 3] {
            let a: Vec<f64> = (0..comps * t.target_nodes)
                .map(|_| rng.range(-1.0, 1.0))
                .collect();
            let b: Vec<f64> = (0..comps * t.len()).map(|_| rng.range(-1.0, 1.0)).collect();
            let mut pa = vec![0.0; b.len()];
            t.interpolate(&a, comps, &mut pa).unwrap();
            let mut ptb = vec![0.0; a.len()];
            t.transpose_add(&b, comps, &mut ptb).unwrap();
            let lhs: f64 = pa.iter().zip(&b).map(|(x, y)| x * y).sum();
            let rhs: f64 = a.iter().zip(&ptb).map(|(x, y)| x * y).sum();
            assert!(
                (lhs - rhs).abs() < 1e-12 * lhs.abs().max(1.0),
                "{lhs} {rhs}"
            );
        }
    }
}

#[test]
fn planar_membrane_two_resolutions() {
    let fine = grid_tris(9, 0.25, 1, plane);
    let coarse = grid_tris(6, 0.25, 2, plane);
    let c = Correspondence::build(&fine, &coarse).unwrap();
    assert_eq!(c.report.fine_outside, 0);
    assert_eq!(c.report.coarse_outside, 0);
    assert!(c.report.max_plane_distance < 1e-15);
    let (e, s) = reproduction_error(&fine.nodes, &coarse, &c.down);
    assert!(e < 1e-14 && s < 1e-14, "{e} {s}");
    let (e, s) = reproduction_error(&coarse.nodes, &fine, &c.up);
    assert!(e < 1e-14 && s < 1e-14, "{e} {s}");
    assert_linear_reproduced(&c.down, &coarse, &fine.nodes);
    assert_linear_reproduced(&c.up, &fine, &coarse.nodes);
    for w in c.down.weights.iter().chain(&c.up.weights) {
        assert_eq!(w[3], 0.0);
    }
    println!("{}", c.report);
}

#[test]
fn curved_membrane_two_resolutions() {
    // A quarter cylinder of radius 1 and length 1.
    let cyl = |u: f64, v: f64| {
        let a = u * std::f64::consts::FRAC_PI_2;
        [a.cos(), a.sin(), v]
    };
    let fine = grid_tris(12, 0.2, 3, cyl);
    let coarse = grid_tris(7, 0.2, 4, cyl);
    let c = Correspondence::build(&fine, &coarse).unwrap();
    println!("{}", c.report);
    // Every node projects into a triangle of the other mesh.
    assert_eq!(c.report.fine_outside, 0);
    assert_eq!(c.report.coarse_outside, 0);
    // The off-plane distance is at most the sagitta of the longest chord (angle span of a
    // perturbed coarse cell < 2.5 cells).
    let sag = 1.0 - (2.5 / 7.0 * std::f64::consts::FRAC_PI_2 / 2.0).cos();
    assert!(c.report.max_plane_distance > 0.0 && c.report.max_plane_distance < sag);
    // The weights reproduce the projection: the residual is along the host's normal.
    for (th, &p) in fine.nodes.iter().enumerate() {
        let x = reproduced(&c.down, &coarse, th);
        let el = coarse.element(c.down.host[th] as usize);
        let y = |j: usize| coarse.nodes[el[j] as usize];
        let n = cross(sub(y(1), y(0)), sub(y(2), y(0)));
        let r = sub(p, x);
        assert!(norm(cross(r, n)) <= 1e-12 * norm(n), "node {th}");
        assert!(norm(r) <= c.down.max_plane_distance * (1.0 + 1e-12) + 1e-15);
    }
}

#[test]
fn same_bits_on_one_or_many_threads() {
    // Large enough for the parallel paths of the tree and the transfer.
    let fine = box_tets([18, 17, 19], [0.0; 3], [1.0; 3], 0.2, 31);
    let coarse = box_tets([13, 12, 13], [0.01; 3], [0.99, 1.01, 1.0], 0.2, 32);
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| Correspondence::build(&fine, &coarse).unwrap())
    };
    let a = run(1);
    let b = run(4);
    assert!(a.report.fine_outside > 0);
    assert_eq!(a, b);
    let bits =
        |t: &Transfer| -> Vec<u64> { t.weights.iter().flatten().map(|x| x.to_bits()).collect() };
    assert_eq!(bits(&a.down), bits(&b.down));
    assert_eq!(bits(&a.up), bits(&b.up));
    // Parallel interpolation gives the same bits as well.
    let src = linear_field(&coarse.nodes);
    let mut o1 = vec![0.0; 3 * fine.nodes.len()];
    let mut o4 = o1.clone();
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| a.down.interpolate(&src, 3, &mut o1).unwrap());
    a.down.interpolate(&src, 3, &mut o4).unwrap();
    assert!(o1.iter().zip(&o4).all(|(x, y)| x.to_bits() == y.to_bits()));
}

#[test]
fn hierarchy_validates_and_reports() {
    let l0 = box_tets([6, 6, 6], [0.0; 3], [1.0; 3], 0.2, 41);
    let l1 = box_tets([5, 4, 5], [0.0; 3], [1.0; 3], 0.2, 42);
    let l2 = box_tets([3, 3, 3], [0.0; 3], [1.0; 3], 0.2, 43);
    let h = Hierarchy::new(vec![l0.clone(), l1.clone(), l2.clone()]).unwrap();
    assert_eq!(h.len(), 3);
    assert_eq!(h.links.len(), 2);
    let r = h.report();
    println!("{r}");
    assert!(r.contains("level 2: 64 nodes, 162 elements"), "{r}");
    assert!(r.contains("link 1-2"), "{r}");
    assert_eq!(Hierarchy::new(vec![l2.clone()]).unwrap().links.len(), 0);

    assert!(Hierarchy::new(vec![]).is_err());
    let e = Hierarchy::new(vec![l2.clone(), l0.clone()]).unwrap_err();
    assert!(e.to_string().contains("more nodes"), "{e}");
    let tri = grid_tris(3, 0.0, 1, plane);
    let e = Hierarchy::new(vec![l0.clone(), tri.clone()]).unwrap_err();
    assert!(e.to_string().contains("triangle"), "{e}");
    assert!(Correspondence::build(&l0, &tri).is_err());
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let m = box_tets([2, 2, 2], [0.0; 3], [1.0; 3], 0.0, 1);
    let mut bad = m.clone();
    bad.cells[5] = 10_000;
    assert!(Transfer::build(&[[0.5; 3]], &bad).is_err());
    let mut bad = m.clone();
    bad.cells.pop();
    assert!(Transfer::build(&[[0.5; 3]], &bad).is_err());
    let mut bad = m.clone();
    bad.cells.clear();
    assert!(Transfer::build(&[[0.5; 3]], &bad).is_err());
    assert!(Transfer::build(&[[f64::NAN, 0.0, 0.0]], &m).is_err());
    // All elements degenerate.
    let mut flat = m.clone();
    for p in &mut flat.nodes {
        p[2] = 0.0;
    }
    assert!(Transfer::build(&[[0.5; 3]], &flat).is_err());

    let t = Transfer::build(&[[0.5; 3], [0.1; 3]], &m).unwrap();
    assert!(Transfer::build(&[], &m).unwrap().is_empty());
    let src = vec![0.0; 3 * m.nodes.len()];
    let mut out = vec![0.0; 6];
    assert!(t.interpolate(&src, 3, &mut out).is_ok());
    assert!(t.interpolate(&src, 2, &mut out).is_err());
    assert!(t.interpolate(&src[1..], 3, &mut out).is_err());
    assert!(t.interpolate_add(&src, 3, &mut out[1..]).is_err());
    assert!(t.interpolate(&src, 0, &mut out).is_err());
    let mut back = vec![0.0; 3 * m.nodes.len()];
    assert!(t.transpose_add(&out, 3, &mut back).is_ok());
    assert!(t.transpose_add(&out[1..], 3, &mut back).is_err());
}

/// Minimal Gmsh 2.2 ASCII reader for the tests: nodes and 4-node tetrahedra (type 4).
fn read_gmsh22_tets(path: &str) -> Option<Mesh> {
    let text = std::fs::read_to_string(path).ok()?;
    let mut lines = text.lines();
    let mut ids: HashMap<u64, u32> = HashMap::new();
    let mut nodes = Vec::new();
    let mut cells = Vec::new();
    while let Some(l) = lines.next() {
        match l.trim() {
            "$Nodes" => {
                let n: usize = lines.next()?.trim().parse().ok()?;
                for _ in 0..n {
                    let v: Vec<f64> = lines
                        .next()?
                        .split_whitespace()
                        .map(|s| s.parse().unwrap())
                        .collect();
                    ids.insert(v[0] as u64, nodes.len() as u32);
                    nodes.push([v[1], v[2], v[3]]);
                }
            }
            "$Elements" => {
                let n: usize = lines.next()?.trim().parse().ok()?;
                for _ in 0..n {
                    let v: Vec<u64> = lines
                        .next()?
                        .split_whitespace()
                        .map(|s| s.parse().unwrap())
                        .collect();
                    if v[1] == 4 {
                        let first = 3 + v[2] as usize;
                        cells.extend(v[first..first + 4].iter().map(|i| ids[i]));
                    }
                }
            }
            _ => {}
        }
    }
    let mut m = Mesh::new(ElementKind::Tet4, nodes, cells);
    m.orient();
    Some(m)
}

#[test]
fn liver_levels_0_and_1() {
    let p0 = concat!(env!("CARGO_MANIFEST_DIR"), "/../../data/liver_L0.msh");
    let p1 = concat!(env!("CARGO_MANIFEST_DIR"), "/../../data/liver_L1.msh");
    let (Some(l0), Some(l1)) = (read_gmsh22_tets(p0), read_gmsh22_tets(p1)) else {
        panic!("liver levels missing from data/ ({p0}, {p1})");
    };
    let t0 = std::time::Instant::now();
    let c = Correspondence::build(&l0, &l1).unwrap();
    let dt = t0.elapsed();
    println!(
        "liver L0: {} nodes, {} tets; L1: {} nodes, {} tets; built in {:.3} s",
        l0.num_nodes(),
        l0.num_elements(),
        l1.num_nodes(),
        l1.num_elements(),
        dt.as_secs_f64()
    );
    println!("liver L0-L1: {}", c.report);
    let (e, s) = reproduction_error(&l0.nodes, &l1, &c.down);
    println!("down: position error {e:.2e} of the diagonal, |sum w - 1| {s:.2e}");
    assert!(e < 1e-12 && s < 1e-12);
    let (e, s) = reproduction_error(&l1.nodes, &l0, &c.up);
    println!("up:   position error {e:.2e} of the diagonal, |sum w - 1| {s:.2e}");
    assert!(e < 1e-12 && s < 1e-12);
    println!(
        "boundary nodes: L0 {}, L1 {}",
        l0.boundary_nodes().len(),
        l1.boundary_nodes().len()
    );
    let ext = |t: &Transfer| {
        let mut v: Vec<f64> = t
            .outside
            .iter()
            .map(|&i| {
                let w = &t.weights[i as usize];
                (-w.iter().copied().fold(f64::INFINITY, f64::min))
                    .max(w.iter().copied().fold(f64::NEG_INFINITY, f64::max) - 1.0)
            })
            .collect();
        v.sort_by(f64::total_cmp);
        let above = |x: f64| v.iter().filter(|&&e| e > x).count();
        format!(
            "median {:.3e}, > 0.1: {}, > 0.5: {}, > 1: {}",
            v.get(v.len() / 2).copied().unwrap_or(0.0),
            above(0.1),
            above(0.5),
            above(1.0)
        )
    };
    println!(
        "extrapolation of outside fine nodes (down): {}",
        ext(&c.down)
    );
    println!("extrapolation of outside coarse nodes (up): {}", ext(&c.up));
    assert_linear_reproduced(&c.down, &l1, &l0.nodes);
    assert_linear_reproduced(&c.up, &l0, &l1.nodes);
}

/// Convex weights: outside points get a point of their eq. 7 host (weights in [0, 1], summing
/// to 1, so constants are reproduced and nothing is amplified); inside points are unchanged.
#[test]
fn convex_weights_clamp_outside_points_only() {
    let m = box_tets([3, 3, 3], [0.0; 3], [1.0; 3], 0.2, 3);
    let mut rng = Rng(9);
    let pts: Vec<[f64; 3]> = (0..400)
        .map(|_| [0, 1, 2].map(|_| rng.range(-0.4, 1.4)))
        .collect();
    let t = Transfer::build(&pts, &m).unwrap();
    assert!(t.max_extrapolation > 0.1 && t.outside.len() > 50);
    let c = t.convex();
    assert_eq!(c.host, t.host);
    assert_eq!(c.max_extrapolation, 0.0);
    for i in 0..pts.len() {
        let w = &c.weights[i];
        assert!(w.iter().all(|&x| (0.0..=1.0).contains(&x)), "{i}: {w:?}");
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-14);
        if t.outside.binary_search(&(i as u32)).is_err() && t.weights[i].iter().all(|&x| x >= 0.0) {
            assert_eq!(*w, t.weights[i], "inside point {i} changed");
        }
    }
    // A constant field is reproduced exactly, values stay within the host's range.
    let ones = vec![1.0; m.num_nodes()];
    let mut out = vec![0.0; pts.len()];
    c.interpolate(&ones, 1, &mut out).unwrap();
    assert!(out.iter().all(|&v| (v - 1.0).abs() < 1e-14));
}

/// The unrolled interpolation (3-vectors on 4 or 3 hosts, set or add) gives the same bits as
/// the general loop it replaced, on tets and on triangles, large enough to run in parallel.
#[test]
fn unrolled_interpolation_equals_the_general_loop() {
    let tets = (
        box_tets([28, 27, 29], [0.0; 3], [1.0; 3], 0.2, 41),
        box_tets([13, 12, 13], [0.01; 3], [0.99, 1.01, 1.0], 0.2, 42),
    );
    let tris = (
        grid_tris(130, 0.25, 43, plane),
        grid_tris(40, 0.25, 44, plane),
    );
    for (fine, coarse) in [tets, tris] {
        let c = Correspondence::build(&fine, &coarse).unwrap();
        for (t, target) in [(&c.down, &coarse), (&c.up, &fine)] {
            let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
            let src: Vec<f64> = (0..3 * target.nodes.len())
                .map(|_| rng.range(-1.0, 1.0))
                .collect();
            let base: Vec<f64> = (0..3 * t.len()).map(|_| rng.range(-1.0, 1.0)).collect();
            for add in [false, true] {
                let (mut fast, mut reference) = (base.clone(), base.clone());
                if add {
                    t.interpolate_add(&src, 3, &mut fast).unwrap();
                } else {
                    t.interpolate(&src, 3, &mut fast).unwrap();
                }
                t.gather_any(&src, 3, &mut reference, add);
                assert!(
                    fast.iter()
                        .zip(&reference)
                        .all(|(a, b)| a.to_bits() == b.to_bits()),
                    "npe {} add {add}",
                    t.npe
                );
            }
        }
    }
}
