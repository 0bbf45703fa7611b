//! STL surfaces, ASCII and binary.
//!
//! Binary STL: an 80-byte header, a little-endian `u32` triangle count `N`, then `N` records
//! of 50 bytes (normal, three corners as `f32` x/y/z, a 2-byte attribute). A file is read as
//! binary exactly when its size is `84 + 50 N`: the header of many binary files also starts
//! with `solid`, so the first word does not tell them apart. Otherwise it must be ASCII:
//!
//! ```text
//! solid [name]
//!   facet normal nx ny nz
//!     outer loop
//!       vertex x y z      (three times)
//!     endloop
//!   endfacet
//!   ...
//! endsolid [name]
//! ```
//!
//! (keywords case-insensitive, several `solid` blocks allowed). The stored facet normal is
//! ignored: the corner order gives the orientation. Corners with bit-identical coordinates
//! (`-0` = `+0`) are merged into one vertex, numbered by first appearance.

use std::collections::HashMap;
use std::path::Path;

use super::utf8;
use crate::io::text::{format_err, format_err_noline, parse_f64, show};
use crate::mesh::Surface;
use crate::{Error, Result};

/// Builds an indexed surface from triangle corners, merging bit-identical positions.
#[derive(Default)]
struct Merger {
    index: HashMap<[u64; 3], u32>,
    surface: Surface,
}

impl Merger {
    fn vertex(&mut self, p: [f64; 3]) -> u32 {
        // `+ 0.0` turns -0 into +0 so that the two zeros share a key.
        let key = p.map(|c| (c + 0.0).to_bits());
        let points = &mut self.surface.points;
        *self.index.entry(key).or_insert_with(|| {
            points.push(p);
            (points.len() - 1) as u32
        })
    }
    fn triangle(&mut self, corners: [[f64; 3]; 3]) {
        let t = corners.map(|p| self.vertex(p));
        self.surface.triangles.push(t);
    }
}

/// Parse the bytes of an STL file, ASCII or binary (see the module docs).
pub fn parse_stl(path: &Path, bytes: &[u8]) -> Result<Surface> {
    if bytes.len() >= 84 {
        let n = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as u64;
        if 84 + 50 * n == bytes.len() as u64 {
            return parse_binary(path, bytes);
        }
    }
    let head = bytes
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .map(|i| &bytes[i..])
        .unwrap_or(&[]);
    // A damaged binary file whose header starts with "solid" is not text: report its size.
    let text = bytes.len() < 84 || std::str::from_utf8(bytes).is_ok();
    if head.len() >= 5 && head[..5].eq_ignore_ascii_case(b"solid") && text {
        return parse_ascii(path, bytes);
    }
    let msg = if bytes.len() >= 84 {
        let n = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as u64;
        format!(
            "neither ASCII STL (not text starting with `solid`) nor binary STL (the header \
             says {n} triangles, which needs 84 + 50*{n} = {} bytes, but the file has {} bytes)",
            84 + 50 * n,
            bytes.len()
        )
    } else {
        format!(
            "not an STL file: {} bytes, does not start with `solid` (ASCII) and is shorter \
             than the 84-byte binary header",
            bytes.len()
        )
    };
    Err(format_err_noline(path, msg))
}

fn parse_binary(path: &Path, bytes: &[u8]) -> Result<Surface> {
    let mut m = Merger::default();
    for (t, rec) in bytes[84..].chunks_exact(50).enumerate() {
        let f = |k: usize| {
            let o = 12 + 4 * k;
            f32::from_le_bytes([rec[o], rec[o + 1], rec[o + 2], rec[o + 3]]) as f64
        };
        let corners = [[f(0), f(1), f(2)], [f(3), f(4), f(5)], [f(6), f(7), f(8)]];
        if let Some(c) = corners.iter().flatten().find(|c| !c.is_finite()) {
            return Err(format_err_noline(
                path,
                format!(
                    "binary STL triangle {t} (byte offset {}) has a non-finite coordinate \
                     {c}; coordinates must be finite numbers",
                    84 + 50 * t
                ),
            ));
        }
        m.triangle(corners);
    }
    Ok(m.surface)
}

/// The ASCII grammar as a small state machine over lines.
fn parse_ascii(path: &Path, bytes: &[u8]) -> Result<Surface> {
    #[derive(Clone, Copy, PartialEq, Debug)]
    enum St {
        Outside,
        InSolid,
        InFacet,
        InLoop(usize),
        LoopDone,
        FacetDone,
    }
    let text = utf8(path, bytes)?;
    let mut m = Merger::default();
    let mut st = St::Outside;
    let mut corners = [[0.0; 3]; 3];
    let mut last_line = 0;
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        last_line = line;
        let mut tok = raw.split_whitespace();
        let Some(key) = tok.next() else { continue };
        let key = key.to_ascii_lowercase();
        let expect = |what: &str| -> Error {
            format_err(
                path,
                line,
                format!("expected {what}, found {}", show(raw.trim())),
            )
        };
        st = match (st, key.as_str()) {
            (St::Outside, "solid") => St::InSolid,
            (St::Outside, _) => return Err(expect("`solid [name]`")),
            (St::InSolid, "endsolid") => St::Outside,
            (St::InSolid, "facet") => {
                if tok.next().map(|t| t.to_ascii_lowercase()).as_deref() != Some("normal") {
                    return Err(expect("`facet normal nx ny nz`"));
                }
                St::InFacet
            }
            (St::InSolid, _) => return Err(expect("`facet normal nx ny nz` or `endsolid`")),
            (St::InFacet, "outer") => St::InLoop(0),
            (St::InFacet, _) => return Err(expect("`outer loop`")),
            (St::InLoop(k), "vertex") if k < 3 => {
                for c in corners[k].iter_mut() {
                    let t = tok.next().ok_or_else(|| expect("`vertex x y z`"))?;
                    *c = parse_f64(path, line, t, "a vertex coordinate")?;
                }
                if k == 2 {
                    St::LoopDone
                } else {
                    St::InLoop(k + 1)
                }
            }
            (St::InLoop(k), _) => {
                return Err(expect(&format!(
                    "`vertex x y z` (corner {} of 3 of triangle {})",
                    k + 1,
                    m.surface.triangles.len()
                )))
            }
            (St::LoopDone, "endloop") => {
                m.triangle(corners);
                St::FacetDone
            }
            (St::LoopDone, "vertex") => {
                return Err(format_err(
                    path,
                    line,
                    format!(
                        "triangle {} has more than 3 vertices; an STL facet has exactly 3",
                        m.surface.triangles.len()
                    ),
                ))
            }
            (St::LoopDone, _) => return Err(expect("`endloop`")),
            (St::FacetDone, "endfacet") => St::InSolid,
            (St::FacetDone, _) => return Err(expect("`endfacet`")),
        };
    }
    if st != St::Outside {
        return Err(format_err(
            path,
            last_line + 1,
            "unexpected end of file inside a `solid` block; expected `endsolid`",
        ));
    }
    Ok(m.surface)
}
