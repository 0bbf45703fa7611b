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
    if !is_surface_path(path) {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase());
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
        });
    }
    parse_surface(path, &super::read_bytes(path)?)
}

/// Parse the bytes of a surface file whose name is `path` (the extension chooses the format,
/// the name appears in errors), as [`load_surface`] does after reading the file.
pub fn parse_surface(path: &Path, bytes: &[u8]) -> Result<Surface> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    let s = match ext.as_deref() {
        Some("stl") => stl::parse_stl(path, bytes)?,
        Some("ply") => ply::parse_ply(path, bytes)?,
        _ => obj::parse_obj(path, bytes)?,
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::check_surface;
    use crate::mesh::surface_check::tests::{cube, icosphere};
    use std::fmt::Write as _;

    fn obj_text(s: &Surface) -> String {
        let mut o = String::from("# test surface\no test\n");
        for p in &s.points {
            writeln!(o, "v {:?} {:?} {:?}", p[0], p[1], p[2]).unwrap();
            writeln!(o, "vn 0 0 1").unwrap();
        }
        for t in &s.triangles {
            // Mixed corner syntaxes; all name the same vertices.
            writeln!(o, "f {} {}//1 {}/1/1", t[0] + 1, t[1] + 1, t[2] + 1).unwrap();
        }
        o
    }

    fn stl_ascii(s: &Surface) -> String {
        let mut o = String::from("solid\n");
        for t in &s.triangles {
            o += "  facet normal 0 0 0\n    outer loop\n";
            for &v in t {
                let p = s.points[v as usize];
                writeln!(o, "      vertex {:?} {:?} {:?}", p[0], p[1], p[2]).unwrap();
            }
            o += "    endloop\n  endfacet\n";
        }
        o + "endsolid\n"
    }

    /// Binary STL written by the `stl_io` crate (an independent writer), with a header that
    /// starts with "solid" as many CAD exporters write it.
    fn stl_binary(s: &Surface) -> Vec<u8> {
        let tris: Vec<stl_io::Triangle> = s
            .triangles
            .iter()
            .map(|t| stl_io::Triangle {
                normal: stl_io::Normal::new([0.0; 3]),
                vertices: t.map(|v| stl_io::Vertex::new(s.points[v as usize].map(|c| c as f32))),
            })
            .collect();
        let mut out = Vec::new();
        stl_io::write_stl(&mut out, tris.iter()).unwrap();
        out[..12].copy_from_slice(b"solid binary");
        out
    }

    fn ply_ascii(s: &Surface) -> String {
        let mut o = format!(
            "ply\nformat ascii 1.0\ncomment test\nelement vertex {}\nproperty double x\n\
             property double y\nproperty double z\nproperty uchar red\nelement face {}\n\
             property list uchar int vertex_indices\nproperty float quality\nend_header\n",
            s.points.len(),
            s.triangles.len()
        );
        for p in &s.points {
            writeln!(o, "{:?} {:?} {:?} 200", p[0], p[1], p[2]).unwrap();
        }
        for t in &s.triangles {
            writeln!(o, "3 {} {} {} 0.5", t[0], t[1], t[2]).unwrap();
        }
        o
    }

    /// Binary PLY (little- or big-endian) with skipped properties before and after the ones read, and
    /// an extra element with a list.
    fn ply_binary(s: &Surface, big_endian: bool) -> Vec<u8> {
        let mut o = format!(
            "ply\nformat binary_{}_endian 1.0\nelement vertex {}\nproperty short flag\n\
             property double x\nproperty double y\nproperty double z\nproperty float nx\n\
             element face {}\nproperty list uchar uint vertex_indices\n\
             property list int short extra\nelement edge 1\nproperty int vertex1\n\
             property int vertex2\nend_header\n",
            if big_endian { "big" } else { "little" },
            s.points.len(),
            s.triangles.len()
        )
        .into_bytes();
        macro_rules! put {
            ($x:expr) => {
                if big_endian {
                    o.extend($x.to_be_bytes())
                } else {
                    o.extend($x.to_le_bytes())
                }
            };
        }
        for p in &s.points {
            put!(7i16);
            for c in p {
                put!(c);
            }
            put!(1f32);
        }
        for t in &s.triangles {
            o.push(3);
            for v in t {
                put!(v);
            }
            put!(2i32);
            put!(1i16);
            put!(2i16);
        }
        put!(0i32);
        put!(1i32);
        o
    }

    fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> std::path::PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    }

    /// The same triangles over the same positions, and as many vertices.
    fn same_geometry(a: &Surface, b: &Surface) {
        assert_eq!(a.points.len(), b.points.len());
        assert_eq!(a.triangles.len(), b.triangles.len());
        for (s, t) in a.triangles.iter().zip(&b.triangles) {
            assert_eq!(
                s.map(|v| a.points[v as usize]),
                t.map(|v| b.points[v as usize])
            );
        }
    }

    #[test]
    fn every_format_round_trips_cube_and_icosphere() {
        let dir = tempfile::tempdir().unwrap();
        for (name, s) in [("cube", cube(-0.5, 1.0)), ("ico", icosphere(2))] {
            let v = s.enclosed_volume();
            // Text and double-precision formats give back the very same indexed surface.
            for (file, bytes) in [
                (format!("{name}.obj"), obj_text(&s).into_bytes()),
                (format!("{name}.OBJ"), obj_text(&s).into_bytes()),
                (format!("{name}_a.ply"), ply_ascii(&s).into_bytes()),
                (format!("{name}_le.ply"), ply_binary(&s, false)),
                (format!("{name}_be.ply"), ply_binary(&s, true)),
            ] {
                let got = load_surface(&write(dir.path(), &file, bytes)).unwrap();
                assert_eq!(got, s, "{file}");
                assert_eq!(got.enclosed_volume(), v, "{file}");
            }
            // STL has no vertex list: the corners merge back into the same vertices, numbered
            // by first appearance. ASCII keeps the exact positions.
            let got =
                load_surface(&write(dir.path(), &format!("{name}_a.stl"), stl_ascii(&s))).unwrap();
            same_geometry(&got, &s);
            assert_eq!(got.enclosed_volume(), v, "{name}");
            // Binary STL stores f32: the same surface at f32-rounded positions, merged back
            // into the same vertex count, closed, with the volume to f32 precision.
            let got =
                load_surface(&write(dir.path(), &format!("{name}_b.stl"), stl_binary(&s))).unwrap();
            let mut s32 = s.clone();
            for p in &mut s32.points {
                *p = p.map(|c| c as f32 as f64);
            }
            same_geometry(&got, &s32);
            assert!((got.enclosed_volume() - v).abs() < 1e-6 * v.abs(), "{name}");
            let mut g = got.clone();
            let r = check_surface(&mut g).unwrap();
            assert_eq!((r.flipped, r.components.len()), (0, 1));
        }
    }

    #[test]
    fn polygons_become_fans() {
        let dir = tempfile::tempdir().unwrap();
        let cube_quads = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 0 0 1\nv 1 0 1\nv 0 1 1\nv 1 1 1\n\
                          f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n";
        let s = load_surface(&write(dir.path(), "q.obj", cube_quads)).unwrap();
        assert_eq!(s, cube(0.0, 1.0));
        // Negative (relative) indices.
        let s = load_surface(&write(
            dir.path(),
            "r.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n",
        ))
        .unwrap();
        assert_eq!(s.triangles, vec![[0, 1, 2]]);
        let ply = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
                   property float z\nelement face 1\nproperty list uchar int vertex_index\n\
                   end_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n";
        let s = load_surface(&write(dir.path(), "q.ply", ply)).unwrap();
        assert_eq!(s.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    }

    #[test]
    fn organ_surfaces_load_and_pass_the_checks() {
        let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data");
        // Volumes from data/mesh_report.json (computed independently when the files were made).
        for (file, nv, nt, volume) in [
            ("liver_surface.obj", 4996, 9988, 1477212.8518269428),
            ("heart_surface.obj", 7778, 15552, 13865.283434250176),
        ] {
            let mut s = load_surface(&data.join(file)).unwrap();
            assert_eq!((s.points.len(), s.triangles.len()), (nv, nt), "{file}");
            let r = check_surface(&mut s).unwrap();
            assert_eq!(r.flipped, 0, "{file}");
            assert_eq!(r.components.len(), 1, "{file}");
            assert_eq!(r.unused_vertices, 0, "{file}");
            let rel = (r.enclosed_volume - volume).abs() / volume;
            assert!(rel < 1e-6, "{file}: {} vs {volume}", r.enclosed_volume);
            // Millimetres: the liver spans ~194 units, a heart ~39; both would be > 5 m.
            assert!(looks_like_mm(&r), "{file}");
        }
    }

    fn looks_like_mm(r: &crate::mesh::SurfaceReport) -> bool {
        crate::mesh::looks_like_millimetres((r.bbox_min, r.bbox_max), 1.0)
            && !crate::mesh::looks_like_millimetres((r.bbox_min, r.bbox_max), 1e-3)
    }

    fn load_err(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> String {
        let e = load_surface(&write(dir, name, bytes)).unwrap_err();
        assert!(matches!(e, Error::MeshFormat { .. }), "{e}");
        let s = e.to_string();
        assert!(s.contains(name), "{s}");
        s
    }

    #[test]
    fn reader_errors_name_file_line_and_what_is_valid() {
        let d = tempfile::tempdir().unwrap();
        let d = d.path();
        let e = load_err(
            d,
            "a.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 3\nf 1 2 9\n",
        );
        assert!(e.contains("line 6"), "{e}");
        assert!(
            e.contains("face 2 references vertex 9 but the file has 3 vertices (valid: 1..3)"),
            "{e}"
        );
        let e = load_err(d, "b.obj", "v 0 0 0\nv 1 0\n");
        assert!(
            e.contains("line 2") && e.contains("expected `v x y z`"),
            "{e}"
        );
        let e = load_err(d, "c.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n");
        assert!(e.contains("line 4") && e.contains("start at 1"), "{e}");
        let e = load_err(d, "d.obj", "v 0 0 0\ncurv 0 1 1 2\n");
        assert!(
            e.contains("line 2") && e.contains("unsupported OBJ statement `curv`"),
            "{e}"
        );
        let e = load_err(d, "e.obj", "v 0 0 0\nv 1 0 0\nf 1 2\n");
        assert!(
            e.contains("face 1 has 2 corners; a face needs at least 3"),
            "{e}"
        );
        let e = load_err(d, "f.obj", "v 0 0 x\n");
        assert!(e.contains("line 1") && e.contains("`x`"), "{e}");
        let e = load_err(d, "g.obj", "# nothing\n");
        assert!(e.contains("no triangles"), "{e}");

        let ply = |faces: &str| {
            format!(
                "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                 property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
                 end_header\n0 0 0\n1 0 0\n0 1 0\n{faces}\n"
            )
        };
        let e = load_err(d, "a.ply", ply("3 0 1 3"));
        assert!(e.contains("line 13"), "{e}");
        assert!(
            e.contains("face 0 references vertex 3 but the file has 3 vertices (valid: 0..2)"),
            "{e}"
        );
        let e = load_err(d, "b.ply", ply("3 0 1"));
        assert!(e.contains("line 13") && e.contains("face"), "{e}");
        let e = load_err(d, "c.ply", ply("3 0 1 2 7"));
        assert!(e.contains("line 13") && e.contains("has 5 values"), "{e}");
        let e = load_err(d, "d.ply", ply("3 0 1 2").replace("float z", "quad z"));
        assert!(
            e.contains("line 6") && e.contains("unknown property type `quad`"),
            "{e}"
        );
        let e = load_err(
            d,
            "e.ply",
            ply("3 0 1 2").replace("ascii", "binary_middle_endian"),
        );
        assert!(e.contains("line 2") && e.contains("valid: ascii"), "{e}");
        let e = load_err(d, "f.ply", ply("3 0 1 2").replace("property float z\n", ""));
        assert!(e.contains("no scalar property `z`"), "{e}");
        let mut bin = ply_binary(&cube(0.0, 1.0), false);
        bin.truncate(bin.len() - 20);
        let e = load_err(d, "g.ply", bin);
        assert!(e.contains("unexpected end of file"), "{e}");

        let e = load_err(
            d,
            "a.stl",
            "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n\
                                       vertex 1 0\n",
        );
        assert!(e.contains("line 5") && e.contains("`vertex x y z`"), "{e}");
        let e = load_err(
            d,
            "b.stl",
            "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n\
                                       vertex 1 0 0\nvertex 0 1 0\nendloop\n",
        );
        assert!(
            e.contains("line 8") && e.contains("expected `endsolid`"),
            "{e}"
        );
        let mut bin = stl_binary(&cube(0.0, 1.0));
        bin.pop();
        let e = load_err(d, "c.stl", bin);
        assert!(
            e.contains("header says 12 triangles") && e.contains("684 bytes") && e.contains("683"),
            "{e}"
        );

        let e = load_err(d, "x.off", "OFF\n");
        assert!(
            e.contains("`.off`") && e.contains(".obj, .stl, .ply"),
            "{e}"
        );
        let e = load_surface(&d.join("missing.obj")).unwrap_err();
        assert!(matches!(e, Error::Io { .. }) && e.to_string().contains("missing.obj"));
    }

    /// Damaged files (every truncation, scattered byte changes) give errors, never panics,
    /// and whatever still loads goes through the checks without panicking.
    #[test]
    fn damaged_files_never_panic() {
        let s = cube(0.0, 1.0);
        let files: [(&str, Vec<u8>); 5] = [
            ("x.obj", obj_text(&s).into_bytes()),
            ("x.stl", stl_ascii(&s).into_bytes()),
            ("y.stl", stl_binary(&s)),
            ("x.ply", ply_ascii(&s).into_bytes()),
            ("y.ply", ply_binary(&s, false)),
        ];
        let mut seed = 12345u64;
        for (name, bytes) in files {
            let p = Path::new(name);
            let mut variants: Vec<Vec<u8>> =
                (0..bytes.len()).map(|n| bytes[..n].to_vec()).collect();
            for _ in 0..200 {
                let mut b = bytes.clone();
                for _ in 0..3 {
                    seed = seed
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    let at = (seed >> 33) as usize % b.len();
                    b[at] = (seed >> 17) as u8;
                }
                variants.push(b);
            }
            for b in variants {
                if let Ok(mut got) = parse_surface(p, &b) {
                    let _ = check_surface(&mut got);
                }
            }
        }
    }
}
