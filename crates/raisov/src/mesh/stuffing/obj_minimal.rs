//! A minimal Wavefront OBJ reader (`v x y z` and `f a b c ...` lines only), used by the
//! mesher's tests and `raisov mesh levels` until the project's surface readers
//! (`crate::io`) replace it.

use crate::mesh::Surface;
use crate::{Error, Result};
use std::path::Path;

/// Read the `v` and `f` lines of an OBJ file: vertex positions, faces as 1-based (or
/// negative, relative) vertex indices, `a/b/c` forms reduced to the position index,
/// polygons fanned into triangles from their first vertex. Other lines are ignored.
pub fn read_obj_minimal(path: &Path) -> Result<Surface> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let bad = |line: usize, msg: String| Error::MeshFormat {
        path: path.to_path_buf(),
        line: Some(line),
        msg,
    };
    let mut s = Surface::default();
    for (ln, line) in text.lines().enumerate() {
        let ln = ln + 1;
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let c: Vec<f64> = it
                    .take(3)
                    .map(|x| x.parse::<f64>())
                    .collect::<std::result::Result<_, _>>()
                    .map_err(|e| bad(ln, format!("vertex coordinate: {e}")))?;
                if c.len() != 3 {
                    return Err(bad(ln, "a vertex needs 3 coordinates".into()));
                }
                s.points.push([c[0], c[1], c[2]]);
            }
            Some("f") => {
                let n = s.points.len() as i64;
                let idx: Vec<u32> = it
                    .map(|w| {
                        let first = w.split('/').next().unwrap_or("");
                        let i: i64 = first
                            .parse()
                            .map_err(|e| bad(ln, format!("face index `{w}`: {e}")))?;
                        let k = if i < 0 { n + i } else { i - 1 };
                        if k < 0 || k >= n {
                            return Err(bad(
                                ln,
                                format!("face index {i} out of range (1..={n} vertices so far)"),
                            ));
                        }
                        Ok(k as u32)
                    })
                    .collect::<Result<_>>()?;
                if idx.len() < 3 {
                    return Err(bad(ln, "a face needs at least 3 vertices".into()));
                }
                for k in 1..idx.len() - 1 {
                    s.triangles.push([idx[0], idx[k], idx[k + 1]]);
                }
            }
            _ => {}
        }
    }
    if s.triangles.is_empty() {
        return Err(Error::MeshFormat {
            path: path.to_path_buf(),
            line: None,
            msg: "no faces (`f` lines) found".into(),
        });
    }
    Ok(s)
}
