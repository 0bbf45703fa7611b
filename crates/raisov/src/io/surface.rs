//! Triangle surface readers: Wavefront OBJ, STL (ASCII and binary), PLY (ASCII and binary).
//!
//! [`load_surface`] chooses the reader by extension:
//!
//! | extension | format |
//! |---|---|
//! | `.obj` | Wavefront OBJ: `v` and `f` statements, see [`obj`] |
//! | `.stl` | STL, ASCII or binary (told apart by the file size), see [`stl`] |
//! | `.ply` | PLY, `ascii`, `binary_little_endian` or `binary_big_endian`, see [`ply`] |
//!
//! Every reader returns an indexed [`Surface`] with the file's vertex order and the file's
//! triangle order; polygons with more than three corners become triangle fans
//! `(v0, v_i, v_(i+1))`. STL stores every triangle with its own three corners: corners with
//! bit-identical coordinates (`-0` and `+0` counted equal) become one vertex, numbered in order
//! of first appearance, so a closed STL solid reads as a closed indexed surface. Normals,
//! texture coordinates, colours and materials are ignored: orientation comes from the corner
//! order alone (see [`crate::mesh::surface_check`] for checking and repairing it).
//! Coordinates are returned as read, no unit conversion ([`Surface::scale`]).
//!
//! Errors name the file, the 1-based line for the text formats (the byte offset or the
//! triangle for binary ones), what is wrong and what would be valid.

pub mod obj;
pub mod ply;
pub mod stl;

use std::path::Path;

use crate::mesh::Surface;
use crate::{Error, Result};

/// Extensions [`load_surface`] understands.
pub const SURFACE_EXTENSIONS: &[&str] = &["obj", "stl", "ply"];

/// Whether `path` has one of the [`SURFACE_EXTENSIONS`] (case-insensitive).
pub fn is_surface_path(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| SURFACE_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
}

/// Read a triangle surface, choosing the reader by extension (see the module docs).
///
/// Errors: [`Error::Io`] when the file cannot be read, [`Error::MeshFormat`] when it is
/// malformed or has no triangles (with the 1-based line for text formats).
pub fn load_surface(path: &Path) -> Result<Surface> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    let bytes = || super::read_bytes(path);
    let s = match ext.as_deref() {
        Some("obj") => obj::parse_obj(path, &bytes()?)?,
        Some("stl") => stl::parse_stl(path, &bytes()?)?,
        Some("ply") => ply::parse_ply(path, &bytes()?)?,
        _ => {
            return Err(Error::MeshFormat {
                path: path.to_path_buf(),
                line: None,
                msg: format!(
                    "unknown surface file extension {}; valid: {}",
                    ext.map(|e| format!("`.{e}`"))
                        .unwrap_or_else(|| "(none)".into()),
                    SURFACE_EXTENSIONS
                        .iter()
                        .map(|e| format!(".{e}"))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            })
        }
    };
    if s.triangles.is_empty() {
        return Err(Error::MeshFormat {
            path: path.to_path_buf(),
            line: None,
            msg: format!(
                "no triangles in the file ({} vertices); a surface needs at least 4 triangles",
                s.points.len()
            ),
        });
    }
    Ok(s)
}

/// Text of a file as UTF-8, or an error naming the 1-based line of the first bad byte.
pub(crate) fn utf8<'a>(path: &Path, bytes: &'a [u8]) -> Result<&'a str> {
    std::str::from_utf8(bytes).map_err(|e| {
        let at = e.valid_up_to();
        let line = 1 + bytes[..at].iter().filter(|&&b| b == b'\n').count();
        super::text::format_err(
            path,
            line,
            format!("not UTF-8 text (byte {at}); expected an ASCII/UTF-8 text file"),
        )
    })
}

/// Split polygon `poly` into the fan `(p0, p_i, p_(i+1))`.
pub(crate) fn fan(poly: &[u32], out: &mut Vec<[u32; 3]>) {
    for i in 1..poly.len().saturating_sub(1) {
        out.push([poly[0], poly[i], poly[i + 1]]);
    }
}
