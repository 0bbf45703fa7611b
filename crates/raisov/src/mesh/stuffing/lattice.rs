//! The body-centred cubic (BCC) lattice: two interpenetrating cubic grids of spacing `h`.
//!
//! *Black* vertices sit at the grid points `o + h (i, j, k)`, `0 ≤ i ≤ n_x` (and so on);
//! *red* vertices at the cube centres `o + h (i + ½, j + ½, k + ½)`, `0 ≤ i < n_x`. Edges:
//!
//! * *long* edges, length `h`: between axis neighbours of one colour (black–black and
//!   red–red);
//! * *short* edges, length `(√3/2) h`: from a red vertex to the 8 black corners of its cube.
//!
//! The lattice tetrahedra: for every red–red edge (the centres of two cubes sharing a face)
//! and every one of the 4 black edges of that shared face, the tetrahedron of those two long
//! edges (they are perpendicular and skew); its other 4 edges are short. 12 tetrahedra of
//! volume `h³/12` per cube, every dihedral angle 60° or 90°. Each lattice vertex lies on
//! exactly one long edge of each tetrahedron it belongs to.
//!
//! Ids: black `(i, j, k)` is `i + (n_x+1) (j + (n_y+1) k)`; red `(i, j, k)` is
//! `n_black + i + n_x (j + n_y k)`.

/// A BCC lattice over a box.
#[derive(Clone, Debug)]
pub(crate) struct Lattice {
    /// Position of black vertex `(0, 0, 0)`.
    pub origin: [f64; 3],
    /// Long edge length.
    pub h: f64,
    /// Cubes per axis.
    pub n: [usize; 3],
}

/// The colour (sub-grid) of a lattice vertex.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Colour {
    Black,
    Red,
}

impl Lattice {
    /// Number of black vertices.
    pub fn num_black(&self) -> usize {
        (self.n[0] + 1) * (self.n[1] + 1) * (self.n[2] + 1)
    }
    /// Number of red vertices.
    pub fn num_red(&self) -> usize {
        self.n[0] * self.n[1] * self.n[2]
    }
    /// All vertices.
    pub fn num_vertices(&self) -> usize {
        self.num_black() + self.num_red()
    }

    pub fn black_id(&self, c: [usize; 3]) -> u32 {
        (c[0] + (self.n[0] + 1) * (c[1] + (self.n[1] + 1) * c[2])) as u32
    }
    pub fn red_id(&self, c: [usize; 3]) -> u32 {
        (self.num_black() + c[0] + self.n[0] * (c[1] + self.n[1] * c[2])) as u32
    }

    /// Colour and integer coordinates (within its own grid) of vertex `v`.
    pub fn coords(&self, v: u32) -> (Colour, [usize; 3]) {
        let v = v as usize;
        let nb = self.num_black();
        if v < nb {
            let (a, b) = (self.n[0] + 1, self.n[1] + 1);
            (Colour::Black, [v % a, (v / a) % b, v / (a * b)])
        } else {
            let w = v - nb;
            let (a, b) = (self.n[0], self.n[1]);
            (Colour::Red, [w % a, (w / a) % b, w / (a * b)])
        }
    }

    /// Reference (unwarped) position of vertex `v`.
    pub fn position(&self, v: u32) -> [f64; 3] {
        let (col, c) = self.coords(v);
        let s = if col == Colour::Red { 0.5 } else { 0.0 };
        [0, 1, 2].map(|d| self.origin[d] + self.h * (c[d] as f64 + s))
    }

    /// The lattice neighbours of `v` with whether the edge is long, in a fixed order
    /// (6 long edges, then 8 short ones); `None` beyond the lattice.
    pub fn neighbours(&self, v: u32) -> [Option<(u32, bool)>; 14] {
        let (col, c) = self.coords(v);
        let mut out = [None; 14];
        let ci = c.map(|x| x as i64);
        let lim = match col {
            Colour::Black => self.n.map(|x| x as i64 + 1),
            Colour::Red => self.n.map(|x| x as i64),
        };
        let mut k = 0;
        for d in 0..3 {
            for s in [-1i64, 1] {
                let mut q = ci;
                q[d] += s;
                if q[d] >= 0 && q[d] < lim[d] {
                    let q = q.map(|x| x as usize);
                    let id = match col {
                        Colour::Black => self.black_id(q),
                        Colour::Red => self.red_id(q),
                    };
                    out[k] = Some((id, true));
                }
                k += 1;
            }
        }
        for corner in 0..8 {
            let off = [
                (corner & 1) as i64,
                ((corner >> 1) & 1) as i64,
                (corner >> 2) as i64,
            ];
            let (q, ok) = match col {
                // Black (i,j,k) is a corner of the cubes (i-1..i, ...).
                Colour::Black => {
                    let q = [0, 1, 2].map(|d| ci[d] - 1 + off[d]);
                    let ok = (0..3).all(|d| q[d] >= 0 && q[d] < self.n[d] as i64);
                    (q, ok)
                }
                Colour::Red => {
                    let q = [0, 1, 2].map(|d| ci[d] + off[d]);
                    (q, true)
                }
            };
            if ok {
                let q = q.map(|x| x as usize);
                let id = match col {
                    Colour::Black => self.red_id(q),
                    Colour::Red => self.black_id(q),
                };
                out[k] = Some((id, false));
            }
            k += 1;
        }
        out
    }

    /// Whether the edge `(a, b)` (two lattice neighbours) is long: both ends of one colour.
    pub fn is_long(&self, a: u32, b: u32) -> bool {
        let nb = self.num_black() as u32;
        (a < nb) == (b < nb)
    }

    /// The lattice tetrahedra whose red–red edge starts at the red vertex of cube `c`, in a
    /// fixed order: for each axis towards the next cube, the 4 black edges of the shared
    /// face. Nodes `(r, r', p, q)`, not oriented.
    pub fn tets_of_cube(&self, c: [usize; 3], out: &mut Vec<[u32; 4]>) {
        let r = self.red_id(c);
        for a in 0..3 {
            if c[a] + 1 >= self.n[a] {
                continue;
            }
            let mut c2 = c;
            c2[a] += 1;
            let r2 = self.red_id(c2);
            let (b, d) = ((a + 1) % 3, (a + 2) % 3);
            let corner = |u: usize, w: usize| {
                let mut p = c;
                p[a] = c[a] + 1;
                p[b] = c[b] + u;
                p[d] = c[d] + w;
                self.black_id(p)
            };
            let ring = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)];
            for e in 0..4 {
                out.push([r, r2, ring[e], ring[(e + 1) % 4]]);
            }
        }
    }
}

/// Key of the undirected edge `(a, b)`.
#[inline]
pub(crate) fn edge_key(a: u32, b: u32) -> u64 {
    let (lo, hi) = if a < b { (a, b) } else { (b, a) };
    ((lo as u64) << 32) | hi as u64
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{norm, sub};
    use crate::mesh::tet_volume;

    /// Every lattice tetrahedron has volume h³/12, two perpendicular long edges of length h
    /// and four short ones of length (√3/2) h, and its edges are lattice neighbours; the
    /// neighbour lists are symmetric.
    #[test]
    fn bcc_tets_have_the_lattice_geometry() {
        let l = Lattice {
            origin: [0.3, -0.2, 0.1],
            h: 0.5,
            n: [3, 4, 2],
        };
        let mut tets = Vec::new();
        for k in 0..l.n[2] {
            for j in 0..l.n[1] {
                for i in 0..l.n[0] {
                    l.tets_of_cube([i, j, k], &mut tets);
                }
            }
        }
        // Interior red-red edges: (nx-1) ny nz + nx (ny-1) nz + nx ny (nz-1), 4 tets each.
        let [nx, ny, nz] = l.n;
        assert_eq!(
            tets.len(),
            4 * ((nx - 1) * ny * nz + nx * (ny - 1) * nz + nx * ny * (nz - 1))
        );
        for t in &tets {
            let p = t.map(|v| l.position(v));
            let v = tet_volume(p[0], p[1], p[2], p[3]).abs();
            assert!((v - l.h.powi(3) / 12.0).abs() < 1e-14, "{v}");
            for i in 0..4 {
                for j in i + 1..4 {
                    let len = norm(sub(p[i], p[j]));
                    let long = l.is_long(t[i], t[j]);
                    let want = if long { l.h } else { 0.75f64.sqrt() * l.h };
                    assert!((len - want).abs() < 1e-14);
                    assert!(l.neighbours(t[i]).contains(&Some((t[j], long))));
                    assert!(l.neighbours(t[j]).contains(&Some((t[i], long))));
                }
            }
        }
        for v in 0..l.num_vertices() as u32 {
            for (u, long) in l.neighbours(v).into_iter().flatten() {
                assert!(l.neighbours(u).contains(&Some((v, long))));
            }
        }
    }
}
