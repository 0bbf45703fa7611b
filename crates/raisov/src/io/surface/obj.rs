//! Wavefront OBJ surfaces.
//!
//! Read: `v x y z [w]` (a trailing `w` or vertex colour is ignored) and `f` with corners
//! `i`, `i/t`, `i//n` or `i/t/n`, where `i` is the 1-based vertex index or a negative index
//! counted back from the last vertex defined so far (`-1` = the latest). Polygons with `k > 3`
//! corners become `k − 2` fan triangles. Ignored: `vt`, `vn`, `vp`, `g`, `o`, `s`, `usemtl`,
//! `mtllib`, `mg`, `l` and `p` (lines and points are not surface), comments (`#`). Free-form
//! geometry (`curv`, `surf`, `cstype`, ...) is refused: it would be surface this reader
//! cannot triangulate.

use std::path::Path;

use super::{fan, utf8};
use crate::io::text::{format_err, parse_f64, show};
use crate::mesh::Surface;
use crate::Result;

/// Statements that carry nothing a triangle surface needs.
const IGNORED: &[&str] = &[
    "vt",
    "vn",
    "vp",
    "g",
    "o",
    "s",
    "usemtl",
    "mtllib",
    "mg",
    "l",
    "p",
    "lod",
    "bevel",
    "c_interp",
    "d_interp",
    "shadow_obj",
    "trace_obj",
    "maplib",
    "usemap",
];

/// Parse the bytes of an OBJ file (see the module docs).
pub fn parse_obj(path: &Path, bytes: &[u8]) -> Result<Surface> {
    let text = utf8(path, bytes)?;
    let mut points: Vec<[f64; 3]> = Vec::new();
    // Corners as 0-based vertex indices, checked against the vertex count at the end (an OBJ
    // face may name a vertex defined further down), with the face's line and number.
    let mut faces: Vec<(usize, usize, Vec<i64>)> = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let l = raw.split('#').next().unwrap_or("").trim();
        let mut tok = l.split_whitespace();
        let Some(key) = tok.next() else { continue };
        match key {
            "v" => {
                let mut p = [0.0; 3];
                for (k, c) in p.iter_mut().enumerate() {
                    let t = tok.next().ok_or_else(|| {
                        format_err(
                            path,
                            line,
                            format!(
                                "vertex {} has {k} coordinates; expected `v x y z`",
                                points.len() + 1
                            ),
                        )
                    })?;
                    *c = parse_f64(path, line, t, "a vertex coordinate")?;
                }
                points.push(p);
            }
            "f" | "fo" => {
                let face = faces.len() + 1;
                let mut corners = Vec::new();
                for t in tok {
                    let idx = t.split('/').next().unwrap_or("");
                    let v: i64 = idx.parse().map_err(|_| {
                        format_err(
                            path,
                            line,
                            format!(
                                "face {face}: corner {} is not a vertex index; expected `i`, \
                                 `i/t`, `i//n` or `i/t/n` with i a non-zero integer",
                                show(t)
                            ),
                        )
                    })?;
                    let v0 = match v {
                        0 => {
                            return Err(format_err(
                                path,
                                line,
                                format!(
                                    "face {face} references vertex 0; OBJ vertex indices start \
                                     at 1 (or count back from -1)"
                                ),
                            ))
                        }
                        v if v > 0 => v - 1,
                        v => {
                            let back = points.len() as i64 + v;
                            if back < 0 {
                                return Err(format_err(
                                    path,
                                    line,
                                    format!(
                                        "face {face} references vertex {v} but only {} vertices \
                                         are defined before it (valid: -1..-{})",
                                        points.len(),
                                        points.len()
                                    ),
                                ));
                            }
                            back
                        }
                    };
                    corners.push(v0);
                }
                if corners.len() < 3 {
                    return Err(format_err(
                        path,
                        line,
                        format!(
                            "face {face} has {} corners; a face needs at least 3",
                            corners.len()
                        ),
                    ));
                }
                faces.push((line, face, corners));
            }
            k if IGNORED.contains(&k) => {}
            k => {
                return Err(format_err(
                    path,
                    line,
                    format!(
                        "unsupported OBJ statement {}; this reader takes `v` and `f` (and \
                         ignores {})",
                        show(k),
                        IGNORED.join(", ")
                    ),
                ))
            }
        }
    }
    let n = points.len();
    if n > u32::MAX as usize {
        return Err(crate::io::text::format_err_noline(
            path,
            format!("{n} vertices; at most {} are supported", u32::MAX),
        ));
    }
    let mut triangles = Vec::new();
    let mut poly = Vec::new();
    for (line, face, corners) in faces {
        poly.clear();
        for v in corners {
            if v as usize >= n {
                return Err(format_err(
                    path,
                    line,
                    format!(
                        "face {face} references vertex {} but the file has {n} vertices \
                         (valid: 1..{n})",
                        v + 1
                    ),
                ));
            }
            poly.push(v as u32);
        }
        fan(&poly, &mut triangles);
    }
    Ok(Surface { points, triangles })
}
