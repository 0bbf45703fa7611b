//! ParaView output of triangle surfaces: VTK XML PolyData (`.vtp`).
//!
//! [`write_vtp`] writes one frame: `<Points>` (the given positions, e.g. the reference
//! positions of a surface), `<Polys>` (the triangles as `connectivity` and `offsets`,
//! `Int64`) and point fields. The storage, the encodings and the conventions are those of
//! the volume frames ([`super::vtu`]): [`VtuFormat::Binary`] (appended raw, zlib-compressed,
//! `UInt64` headers) or [`VtuFormat::Ascii`], floats bit-exact, the first 3-vector point
//! field the active vectors (so *Warp By Vector* applies a `displacement` field). Atomic;
//! non-finite values, wrong lengths and triangle corners out of range are refused
//! ([`Error::Param`]).

use std::borrow::Cow;
use std::path::Path;

use super::vtu::{check_fields, check_values, write_vtk_xml, Array, Section, Values};
use super::{Field, FieldData, VtuFormat};
use crate::{Error, Result};

/// Write one PolyData frame: `triangles` over `points`, with point fields (one item per
/// point), in `format`.
pub fn write_vtp(
    path: &Path,
    points: &[[f64; 3]],
    triangles: &[[u32; 3]],
    point_fields: &[Field],
    format: VtuFormat,
) -> Result<()> {
    let np = points.len();
    let nt = triangles.len();
    check_values("points", "points", points.as_flattened(), 3, np)?;
    check_fields(point_fields, np, "point field")?;
    if let Some((t, &bad)) = triangles
        .iter()
        .enumerate()
        .find_map(|(t, c)| c.iter().find(|&&v| v as usize >= np).map(|v| (t, v)))
    {
        return Err(Error::param(
            "triangles",
            format!("triangle {t} has corner {bad}, out of range ({np} points)"),
        ));
    }
    let point_arrays: Vec<Array> = point_fields.iter().map(Array::of_field).collect();
    let pts = [Array {
        name: None,
        components: 3,
        values: Values::F64(points.as_flattened()),
        per_line: 3,
    }];
    let polys = [
        Array {
            name: Some("connectivity"),
            components: 1,
            values: Values::I64(Cow::Owned(
                triangles.as_flattened().iter().map(|&c| c as i64).collect(),
            )),
            per_line: 3,
        },
        Array {
            name: Some("offsets"),
            components: 1,
            values: Values::I64(Cow::Owned((1..=nt).map(|t| (3 * t) as i64).collect())),
            per_line: 16,
        },
    ];
    let active_vectors = point_fields
        .iter()
        .find(|f| matches!(f.data, FieldData::Vector(_)))
        .map(|f| f.name);
    write_vtk_xml(
        path,
        "PolyData",
        &format!(
            "NumberOfPoints=\"{np}\" NumberOfVerts=\"0\" NumberOfLines=\"0\" \
             NumberOfStrips=\"0\" NumberOfPolys=\"{nt}\""
        ),
        &[
            Section {
                tag: "PointData",
                vectors: active_vectors,
                arrays: &point_arrays,
            },
            Section {
                tag: "Points",
                vectors: None,
                arrays: &pts,
            },
            Section {
                tag: "Polys",
                vectors: None,
                arrays: &polys,
            },
        ],
        format,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::{read_vtp, read_vtu_array};
    use crate::mesh::Surface;

    fn tetra() -> Surface {
        Surface {
            points: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 1e-300],
                [0.0, 1.0 / 3.0, 0.0],
                [0.0, 0.0, -2.5],
            ],
            triangles: vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]],
        }
    }

    /// Both storages read back bit-exact: points, triangles, the displacement field.
    #[test]
    fn vtp_reads_back_bit_exact_in_both_formats() {
        let dir = tempfile::tempdir().unwrap();
        let s = tetra();
        let u: Vec<f64> = (0..12).map(|i| (i as f64 * 0.3).sin() * 1e-3).collect();
        for format in [VtuFormat::Binary, VtuFormat::Ascii] {
            let p = dir.path().join(format!("s_{}.vtp", format.name()));
            let f = [Field {
                name: "displacement",
                data: FieldData::Vector(&u),
            }];
            write_vtp(&p, &s.points, &s.triangles, &f, format).unwrap();
            assert_eq!(read_vtp(&p).unwrap(), s);
            assert_eq!(read_vtu_array(&p, "displacement").unwrap(), (3, u.clone()));
            let text = String::from_utf8_lossy(&std::fs::read(&p).unwrap()).to_string();
            assert!(
                text.contains("<PointData Vectors=\"displacement\">"),
                "{text}"
            );
            assert!(text.contains("NumberOfPolys=\"4\""), "{text}");
            assert_eq!(
                text.contains("compressor=\"vtkZLibDataCompressor\""),
                format == VtuFormat::Binary
            );
        }
    }

    #[test]
    fn vtp_refuses_bad_input() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.vtp");
        let s = tetra();
        let e = write_vtp(&p, &s.points, &[[0, 1, 4]], &[], VtuFormat::Binary)
            .unwrap_err()
            .to_string();
        assert!(e.contains("triangle 0 has corner 4"), "{e}");
        let u = vec![f64::NAN; 12];
        let f = [Field {
            name: "displacement",
            data: FieldData::Vector(&u),
        }];
        let e = write_vtp(&p, &s.points, &s.triangles, &f, VtuFormat::Ascii)
            .unwrap_err()
            .to_string();
        assert!(e.contains("displacement") && e.contains("item 0"), "{e}");
        assert!(!p.exists());
    }
}
