//! Closed triangle surfaces: the input of the tetrahedral mesher and the visual surface.
//!
//! A [`Surface`] is an indexed triangle set in 3-D. Orientation: a triangle `(a, b, c)` has
//! the outward normal `(b − a) × (c − a)` (right-hand rule), so for a closed, outward-oriented
//! surface the enclosed volume
//!
//! ```text
//! V = (1/6) Σ_t  a_t · (b_t × c_t)
//! ```
//!
//! (the divergence theorem applied to x/3) is positive.

/// An indexed triangle surface, coordinates in the file's units until scaled.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Surface {
    /// Vertex positions.
    pub points: Vec<[f64; 3]>,
    /// Triangles as vertex indices, outward normal `(b − a) × (c − a)`.
    pub triangles: Vec<[u32; 3]>,
}

impl Surface {
    /// Signed enclosed volume `(1/6) Σ a · (b × c)`; positive for a closed, outward-oriented
    /// surface. Meaningless for an open surface.
    pub fn enclosed_volume(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.points[i as usize]);
                super::dot(a, super::cross(b, c)) / 6.0
            })
            .sum()
    }

    /// Axis-aligned bounding box `(min, max)`; `None` for a surface with no points.
    pub fn bounding_box(&self) -> Option<([f64; 3], [f64; 3])> {
        let first = *self.points.first()?;
        Some(self.points.iter().fold((first, first), |(lo, hi), p| {
            (
                [lo[0].min(p[0]), lo[1].min(p[1]), lo[2].min(p[2])],
                [hi[0].max(p[0]), hi[1].max(p[1]), hi[2].max(p[2])],
            )
        }))
    }

    /// Multiply every coordinate by `s` (e.g. `1e-3` for a surface in millimetres).
    pub fn scale(&mut self, s: f64) {
        for p in &mut self.points {
            for c in p.iter_mut() {
                *c *= s;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_cube_encloses_unit_volume() {
        let points = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [1.0, 1.0, 1.0],
            [0.0, 1.0, 1.0],
        ];
        let quads = [
            [0, 3, 2, 1],
            [4, 5, 6, 7],
            [0, 1, 5, 4],
            [1, 2, 6, 5],
            [2, 3, 7, 6],
            [3, 0, 4, 7],
        ];
        let triangles = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        let mut s = Surface { points, triangles };
        assert!((s.enclosed_volume() - 1.0).abs() < 1e-15);
        s.scale(2.0);
        assert!((s.enclosed_volume() - 8.0).abs() < 1e-14);
        assert_eq!(s.bounding_box(), Some(([0.0; 3], [2.0; 3])));
    }
}
