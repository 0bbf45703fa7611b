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
