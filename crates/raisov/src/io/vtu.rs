//! ParaView output: VTK XML unstructured grids (`.vtu`) and `.pvd` time collections.
//!
//! [`write_vtu`] writes one frame: node positions, the mesh cells (VTK types 5 triangle and
//! 10 tetrahedron, same node order as [`Mesh`]) and any number of point and cell fields
//! (scalars, 3-vectors, 3x3 tensors stored row-major as 9 components, integer scalars). The
//! first 3-vector point field is marked as the active vectors (`<PointData Vectors=..>`), so
//! ParaView's *Warp By Vector* applies it without choosing: write the reference positions
//! with a `displacement` field first to see the deformed body.
//!
//! Two layouts ([`VtuFormat`]):
//! - [`VtuFormat::Binary`] (the default), ParaView's own: every array in one
//!   `<AppendedData encoding="raw">` section after a `_` marker, at the byte `offset` its
//!   `<DataArray format="appended">` names, zlib-compressed (`compressor="vtkZLibDataCompressor"`,
//!   `header_type="UInt64"`, little endian). Each array is cut into blocks of
//!   [`VTU_BLOCK_SIZE`] bytes (the last one shorter), each compressed on its own, and
//!   preceded by the header `[nblocks, block size, size of the last block if partial else 0,
//!   compressed size of each block]`, `3 + nblocks` `UInt64` values. Floats are stored as
//!   their IEEE bits (`Float64`), so values read back bit-exact. The blocks are compressed in
//!   parallel, but each one independently at a fixed level, so the bytes do not depend on the
//!   thread count.
//! - [`VtuFormat::Ascii`]: the same arrays as text (`format="ascii"`), floats in Rust's
//!   shortest round-trip representation (`{:e}`), so they also read back bit-exact.
//!
//! Cells: `connectivity` and `offsets` as `Int64`, `types` as `UInt8`. [`PvdWriter`]
//! maintains a `.pvd` collection listing frames and their times, appended in constant time
//! per [`PvdWriter::add`] (complete after each). The frames are written atomically; both
//! refuse non-finite values ([`Error::Param`]
//! naming the field and the item). [`read_vtu`](super::vtu_read::read_vtu) reads the files
//! back.

use std::borrow::Cow;
use std::io::Write;
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use super::write_atomic;
use crate::mesh::{ElementKind, Mesh};
use crate::{Error, Result};

/// Uncompressed bytes per zlib block of [`VtuFormat::Binary`] (VTK's default block size).
pub const VTU_BLOCK_SIZE: usize = 1 << 15;

/// zlib level of [`VtuFormat::Binary`] (VTK's default for `vtkZLibDataCompressor`).
const ZLIB_LEVEL: u32 = 5;

/// How [`write_vtu_as`] stores the arrays (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum VtuFormat {
    /// Appended raw binary, zlib-compressed, `UInt64` headers (ParaView's layout).
    #[default]
    Binary,
    /// ASCII text.
    Ascii,
}

impl VtuFormat {
    /// The scenario key's spelling: `"binary"` or `"ascii"`.
    pub fn name(self) -> &'static str {
        match self {
            VtuFormat::Binary => "binary",
            VtuFormat::Ascii => "ascii",
        }
    }
    /// Parse `"binary"` or `"ascii"`.
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "binary" => Some(VtuFormat::Binary),
            "ascii" => Some(VtuFormat::Ascii),
            _ => None,
        }
    }
}

/// The values of one field, one item per node (point fields) or element (cell fields).
#[derive(Clone, Copy, Debug)]
pub enum FieldData<'a> {
    /// One value per item.
    Scalar(&'a [f64]),
    /// Three values per item (x, y, z).
    Vector(&'a [f64]),
    /// Nine values per item, a 3x3 tensor row-major.
    Tensor(&'a [f64]),
    /// One integer per item (e.g. ids), written as `Int64`.
    Int(&'a [i64]),
}

impl FieldData<'_> {
    /// Components per item.
    pub fn components(&self) -> usize {
        match self {
            FieldData::Scalar(_) | FieldData::Int(_) => 1,
            FieldData::Vector(_) => 3,
            FieldData::Tensor(_) => 9,
        }
    }
    /// The number of values (items x components).
    pub fn len(&self) -> usize {
        match self {
            FieldData::Scalar(v) | FieldData::Vector(v) | FieldData::Tensor(v) => v.len(),
            FieldData::Int(v) => v.len(),
        }
    }
    /// True when there are no values.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// The float values (`None` for [`FieldData::Int`]).
    pub fn values(&self) -> Option<&[f64]> {
        match self {
            FieldData::Scalar(v) | FieldData::Vector(v) | FieldData::Tensor(v) => Some(v),
            FieldData::Int(_) => None,
        }
    }
}

/// A named field.
#[derive(Clone, Copy, Debug)]
pub struct Field<'a> {
    /// Name in the file.
    pub name: &'a str,
    /// The values.
    pub data: FieldData<'a>,
}

/// Escape text for an XML attribute value.
fn xml_escape(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            '\'' => o.push_str("&apos;"),
            c => o.push(c),
        }
    }
    o
}

/// Check that `values` has `items * k` entries, all finite.
pub(super) fn check_values(
    name: &str,
    what: &str,
    values: &[f64],
    k: usize,
    items: usize,
) -> Result<()> {
    check_len(name, what, values.len(), k, items)?;
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        return Err(Error::param(
            name,
            format!(
                "{what}: item {} component {} is {}; refusing to write non-finite values",
                i / k,
                i % k,
                values[i]
            ),
        ));
    }
    Ok(())
}

fn check_len(name: &str, what: &str, len: usize, k: usize, items: usize) -> Result<()> {
    if len != items * k {
        return Err(Error::param(
            name,
            format!(
                "{what} needs {items} items x {k} components = {} values, got {len}",
                items * k
            ),
        ));
    }
    Ok(())
}

pub(super) fn check_fields(fields: &[Field], items: usize, what: &str) -> Result<()> {
    for f in fields {
        if f.name.is_empty() {
            return Err(Error::param(what, "a field has an empty name"));
        }
        let what = format!("{what} `{}`", f.name);
        let k = f.data.components();
        match f.data.values() {
            Some(v) => check_values(f.name, &what, v, k, items)?,
            None => check_len(f.name, &what, f.data.len(), k, items)?,
        }
    }
    Ok(())
}

/// The values of one array to write.
pub(super) enum Values<'a> {
    F64(&'a [f64]),
    I64(Cow<'a, [i64]>),
    U8(Vec<u8>),
}

impl Values<'_> {
    fn vtk_type(&self) -> &'static str {
        match self {
            Values::F64(_) => "Float64",
            Values::I64(_) => "Int64",
            Values::U8(_) => "UInt8",
        }
    }
    /// Little-endian bytes.
    fn bytes(&self) -> Vec<u8> {
        match self {
            Values::F64(v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            Values::I64(v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            Values::U8(v) => v.clone(),
        }
    }
    fn write_ascii(&self, w: &mut dyn Write, per_line: usize) -> std::io::Result<()> {
        fn lines<T>(
            w: &mut dyn Write,
            v: &[T],
            per_line: usize,
            f: impl Fn(&mut dyn Write, &T) -> std::io::Result<()>,
        ) -> std::io::Result<()> {
            for chunk in v.chunks(per_line.max(1)) {
                w.write_all(b"         ")?;
                for x in chunk {
                    f(w, x)?;
                }
                w.write_all(b"\n")?;
            }
            Ok(())
        }
        match self {
            Values::F64(v) => lines(w, v, per_line, |w, x| write!(w, " {x:e}")),
            Values::I64(v) => lines(w, v, per_line, |w, x| write!(w, " {x}")),
            Values::U8(v) => lines(w, v, per_line, |w, x| write!(w, " {x}")),
        }
    }
}

/// One `<DataArray>`.
pub(super) struct Array<'a> {
    pub name: Option<&'a str>,
    pub components: usize,
    pub values: Values<'a>,
    /// Values per line in ASCII.
    pub per_line: usize,
}

impl<'a> Array<'a> {
    pub(super) fn of_field(f: &Field<'a>) -> Self {
        let k = f.data.components();
        let values = match f.data {
            FieldData::Scalar(v) | FieldData::Vector(v) | FieldData::Tensor(v) => Values::F64(v),
            FieldData::Int(v) => Values::I64(Cow::Borrowed(v)),
        };
        Array {
            name: Some(f.name),
            components: k,
            per_line: if k == 1 { 8 } else { k },
            values,
        }
    }
}

/// zlib-compress `bytes` in [`VTU_BLOCK_SIZE`] blocks and prepend the VTK `UInt64` header.
fn compress_array(bytes: &[u8]) -> Vec<u8> {
    use flate2::{write::ZlibEncoder, Compression};
    let blocks: Vec<Vec<u8>> = bytes
        .par_chunks(VTU_BLOCK_SIZE)
        .map(|b| {
            let mut e = ZlibEncoder::new(
                Vec::with_capacity(b.len() / 2),
                Compression::new(ZLIB_LEVEL),
            );
            e.write_all(b).expect("writing to a Vec cannot fail");
            e.finish().expect("writing to a Vec cannot fail")
        })
        .collect();
    let mut out =
        Vec::with_capacity(8 * (3 + blocks.len()) + blocks.iter().map(Vec::len).sum::<usize>());
    for h in [
        blocks.len() as u64,
        VTU_BLOCK_SIZE as u64,
        (bytes.len() % VTU_BLOCK_SIZE) as u64,
    ]
    .into_iter()
    .chain(blocks.iter().map(|b| b.len() as u64))
    {
        out.extend_from_slice(&h.to_le_bytes());
    }
    for b in &blocks {
        out.extend_from_slice(b);
    }
    out
}

/// Write `<DataArray>` elements of one group; binary ones append their data to `appended`.
fn write_arrays(
    w: &mut dyn Write,
    arrays: &[Array],
    format: VtuFormat,
    appended: &mut Vec<u8>,
) -> std::io::Result<()> {
    for a in arrays {
        write!(w, "        <DataArray type=\"{}\"", a.values.vtk_type())?;
        if let Some(n) = a.name {
            write!(w, " Name=\"{}\"", xml_escape(n))?;
        }
        if a.components != 1 || a.name.is_none() {
            write!(w, " NumberOfComponents=\"{}\"", a.components)?;
        }
        match format {
            VtuFormat::Ascii => {
                writeln!(w, " format=\"ascii\">")?;
                a.values.write_ascii(w, a.per_line)?;
                writeln!(w, "        </DataArray>")?;
            }
            VtuFormat::Binary => {
                writeln!(w, " format=\"appended\" offset=\"{}\"/>", appended.len())?;
                appended.extend_from_slice(&compress_array(&a.values.bytes()));
            }
        }
    }
    Ok(())
}

/// Write one ParaView frame in the default [`VtuFormat::Binary`]; see [`write_vtu_as`].
pub fn write_vtu(
    path: &Path,
    mesh: &Mesh,
    positions: &[[f64; 3]],
    point_fields: &[Field],
    cell_fields: &[Field],
) -> Result<()> {
    write_vtu_as(
        path,
        mesh,
        positions,
        point_fields,
        cell_fields,
        VtuFormat::Binary,
    )
}

/// Write one ParaView frame: `mesh`'s cells at node `positions` (one per mesh node, e.g. the
/// reference positions), with point fields (one item per node) and cell fields (one item per
/// element), in `format`. Atomic; refuses non-finite values and wrong lengths with
/// [`Error::Param`].
pub fn write_vtu_as(
    path: &Path,
    mesh: &Mesh,
    positions: &[[f64; 3]],
    point_fields: &[Field],
    cell_fields: &[Field],
    format: VtuFormat,
) -> Result<()> {
    let nn = mesh.num_nodes();
    let ne = mesh.num_elements();
    if positions.len() != nn {
        return Err(Error::param(
            "positions",
            format!(
                "expected {nn} positions (one per node), got {}",
                positions.len()
            ),
        ));
    }
    check_values("positions", "positions", positions.as_flattened(), 3, nn)?;
    check_fields(point_fields, nn, "point field")?;
    check_fields(cell_fields, ne, "cell field")?;
    if let Some(&bad) = mesh.cells.iter().find(|&&c| c as usize >= nn) {
        return Err(Error::param(
            "mesh.cells",
            format!("node id {bad} out of range ({nn} nodes)"),
        ));
    }
    let (npe, vtk_type) = match mesh.kind {
        ElementKind::Tri3 => (3, 5u8),
        ElementKind::Tet4 => (4, 10u8),
    };
    let point_arrays: Vec<Array> = point_fields.iter().map(Array::of_field).collect();
    let cell_arrays: Vec<Array> = cell_fields.iter().map(Array::of_field).collect();
    let points = [Array {
        name: None,
        components: 3,
        values: Values::F64(positions.as_flattened()),
        per_line: 3,
    }];
    let cells = [
        Array {
            name: Some("connectivity"),
            components: 1,
            values: Values::I64(Cow::Owned(mesh.cells.iter().map(|&c| c as i64).collect())),
            per_line: npe,
        },
        Array {
            name: Some("offsets"),
            components: 1,
            values: Values::I64(Cow::Owned((1..=ne).map(|e| (e * npe) as i64).collect())),
            per_line: 16,
        },
        Array {
            name: Some("types"),
            components: 1,
            values: Values::U8(vec![vtk_type; ne]),
            per_line: 32,
        },
    ];
    let active_vectors = point_fields
        .iter()
        .find(|f| matches!(f.data, FieldData::Vector(_)))
        .map(|f| f.name);
    write_vtk_xml(
        path,
        "UnstructuredGrid",
        &format!("NumberOfPoints=\"{nn}\" NumberOfCells=\"{ne}\""),
        &[
            Section {
                tag: "PointData",
                vectors: active_vectors,
                arrays: &point_arrays,
            },
            Section {
                tag: "CellData",
                vectors: None,
                arrays: &cell_arrays,
            },
            Section {
                tag: "Points",
                vectors: None,
                arrays: &points,
            },
            Section {
                tag: "Cells",
                vectors: None,
                arrays: &cells,
            },
        ],
        format,
    )
}

/// One element of a `<Piece>` holding `<DataArray>`s (`PointData`, `Points`, `Cells`, ...);
/// `vectors` names the active vectors of a data section.
pub(super) struct Section<'a> {
    pub tag: &'static str,
    pub vectors: Option<&'a str>,
    pub arrays: &'a [Array<'a>],
}

/// Write a VTK XML file of one `<Piece>` of `dataset` (`UnstructuredGrid`, `PolyData`):
/// the sections in order (those without arrays left out) in `format`, atomically.
pub(super) fn write_vtk_xml(
    path: &Path,
    dataset: &str,
    piece_attrs: &str,
    sections: &[Section],
    format: VtuFormat,
) -> Result<()> {
    write_atomic(path, |w: &mut dyn Write| {
        let mut appended = Vec::new();
        writeln!(w, "<?xml version=\"1.0\"?>")?;
        write!(
            w,
            "<VTKFile type=\"{dataset}\" version=\"1.0\" byte_order=\"LittleEndian\""
        )?;
        if format == VtuFormat::Binary {
            write!(
                w,
                " header_type=\"UInt64\" compressor=\"vtkZLibDataCompressor\""
            )?;
        }
        writeln!(w, ">")?;
        writeln!(w, "  <{dataset}>")?;
        writeln!(w, "    <Piece {piece_attrs}>")?;
        for s in sections.iter().filter(|s| !s.arrays.is_empty()) {
            match s.vectors {
                Some(v) => writeln!(w, "      <{} Vectors=\"{}\">", s.tag, xml_escape(v))?,
                None => writeln!(w, "      <{}>", s.tag)?,
            }
            write_arrays(w, s.arrays, format, &mut appended)?;
            writeln!(w, "      </{}>", s.tag)?;
        }
        writeln!(w, "    </Piece>")?;
        writeln!(w, "  </{dataset}>")?;
        if format == VtuFormat::Binary {
            writeln!(w, "  <AppendedData encoding=\"raw\">")?;
            w.write_all(b"   _")?;
            w.write_all(&appended)?;
            writeln!(w)?;
            writeln!(w, "  </AppendedData>")?;
        }
        writeln!(w, "</VTKFile>")
    })
}

/// A ParaView `.pvd` collection of frames, appended in constant time per [`add`]: the file
/// stays open, each frame's `<DataSet>` line is written over the closing tags, which follow it
/// again, so that after every `add` the file is a complete collection of the frames so far.
/// The file is opened without following a symbolic link ([`super::open_for_writing`]). When
/// a write fails (a full disk), the file is cut back to the frames before and its closing
/// tags written again, and the error says how many frames the collection keeps.
///
/// [`add`]: PvdWriter::add
#[derive(Debug)]
pub struct PvdWriter {
    path: PathBuf,
    file: Option<std::fs::File>,
    /// Where the closing tags start.
    end: u64,
    count: usize,
}

/// The closing tags of a collection.
const PVD_TAIL: &str = "  </Collection>\n</VTKFile>\n";

impl PvdWriter {
    /// A collection to be written at `path` (created, replacing any earlier one, at the
    /// first `add`).
    pub fn new(path: impl Into<PathBuf>) -> Self {
        PvdWriter {
            path: path.into(),
            file: None,
            end: 0,
            count: 0,
        }
    }

    /// The `.pvd` path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The number of frames so far.
    pub fn len(&self) -> usize {
        self.count
    }

    /// Whether no frame was added yet.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Add a frame at `time` (seconds) stored in `vtu_file_name_relative` (relative to the
    /// directory of the `.pvd`): its line and the closing tags are written at the end.
    pub fn add(&mut self, time: f64, vtu_file_name_relative: &str) -> Result<()> {
        use std::io::{Seek, SeekFrom};
        if !time.is_finite() {
            return Err(Error::param(
                "time",
                format!(
                    "frame {} (`{vtu_file_name_relative}`) has time {time}; refusing to write \
                     non-finite values",
                    self.count
                ),
            ));
        }
        if self.file.is_none() {
            let mut f = super::open_for_writing(&self.path, true)?;
            let head = "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" \
                        byte_order=\"LittleEndian\">\n  <Collection>\n";
            f.write_all(head.as_bytes())
                .map_err(|e| Error::io(&self.path, e))?;
            self.end = head.len() as u64;
            self.file = Some(f);
        }
        let line = format!(
            "    <DataSet timestep=\"{time:e}\" group=\"\" part=\"0\" file=\"{}\"/>\n",
            xml_escape(vtu_file_name_relative)
        );
        let f = self.file.as_mut().expect("opened above");
        let mut buf = line.into_bytes();
        buf.extend_from_slice(PVD_TAIL.as_bytes());
        if let Err(e) = f
            .seek(SeekFrom::Start(self.end))
            .and_then(|_| f.write_all(&buf))
        {
            // Back to the frames before: cutting frees the space the closing tags need.
            let restored = f
                .set_len(self.end)
                .and_then(|_| f.seek(SeekFrom::Start(self.end)))
                .and_then(|_| f.write_all(PVD_TAIL.as_bytes()));
            let kept = match restored {
                Ok(()) => format!("the collection keeps its {} earlier frame(s)", self.count),
                Err(e2) => format!(
                    "its closing tags could not be written again ({e2}): the collection is \
                     incomplete"
                ),
            };
            return Err(Error::io(
                &self.path,
                std::io::Error::new(e.kind(), format!("{e}; {kept}")),
            ));
        }
        self.end += (buf.len() - PVD_TAIL.len()) as u64;
        self.count += 1;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vtkio::model::{Attribute, DataSet, ElementType, Piece, VertexNumbers};

    fn two_tets() -> Mesh {
        Mesh::new(
            ElementKind::Tet4,
            vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
                [1.0, 1.0, 1.0],
            ],
            vec![0, 1, 2, 3, 1, 2, 4, 3],
        )
    }

    #[test]
    fn vtu_reads_back_with_vtkio() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("f.vtu");
        let m = two_tets();
        let pos: Vec<[f64; 3]> = m
            .nodes
            .iter()
            .map(|x| [x[0] + 0.1, x[1], x[2] - 1e-300])
            .collect();
        let s: Vec<f64> = (0..5).map(|i| i as f64 / 3.0).collect();
        let u: Vec<f64> = (0..15).map(|i| i as f64 * 1e-7).collect();
        let sig: Vec<f64> = (0..18).map(|i| -(i as f64) * 1.5e3).collect();
        let j = [1.0, 0.99];
        write_vtu_as(
            &p,
            &m,
            &pos,
            &[
                Field {
                    name: "s",
                    data: FieldData::Scalar(&s),
                },
                Field {
                    name: "u<&>",
                    data: FieldData::Vector(&u),
                },
            ],
            &[
                Field {
                    name: "stress",
                    data: FieldData::Tensor(&sig),
                },
                Field {
                    name: "J",
                    data: FieldData::Scalar(&j),
                },
            ],
            VtuFormat::Ascii,
        )
        .unwrap();
        let vtk = vtkio::Vtk::import(&p).unwrap();
        let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
            panic!("not an unstructured grid")
        };
        let Piece::Inline(piece) = pieces.into_iter().next().unwrap() else {
            panic!("no inline piece")
        };
        let pts: Vec<f64> = piece.points.cast_into().unwrap();
        assert_eq!(pts, pos.as_flattened());
        let (conn, offs) = match piece.cells.cell_verts {
            VertexNumbers::XML {
                connectivity,
                offsets,
            } => (connectivity, offsets),
            VertexNumbers::Legacy { .. } => panic!("legacy cells"),
        };
        assert_eq!(conn, vec![0, 1, 2, 3, 1, 2, 4, 3]);
        assert_eq!(offs, vec![4, 8]);
        assert_eq!(piece.cells.types.len(), 2);
        assert!(piece
            .cells
            .types
            .iter()
            .all(|&t| t == vtkio::model::CellType::Tetra));
        let find = |attrs: &[Attribute], name: &str| -> (u32, Vec<f64>) {
            for a in attrs {
                if let Attribute::DataArray(d) = a {
                    if d.name == name {
                        let k = match d.elem {
                            ElementType::Scalars { num_comp, .. } => num_comp,
                            ElementType::Vectors => 3,
                            ElementType::Tensors => 9,
                            ElementType::Generic(k) => k,
                            _ => 0,
                        };
                        return (k, d.data.clone().cast_into().unwrap());
                    }
                }
            }
            panic!("no field {name}")
        };
        assert_eq!(find(&piece.data.point, "s"), (1, s.clone()));
        assert_eq!(find(&piece.data.point, "u<&>"), (3, u.clone()));
        assert_eq!(find(&piece.data.cell, "stress"), (9, sig.clone()));
        assert_eq!(find(&piece.data.cell, "J"), (1, j.to_vec()));
    }

    #[test]
    fn binary_frame_reads_back_bit_exact() {
        use crate::io::{read_vtu, read_vtu_array};
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("b.vtu");
        let mut m = two_tets();
        m.orient(); // the reader orients; write what it will return
        let u: Vec<f64> = (0..15).map(|i| (i as f64 * 0.7).sin() * 1e-3).collect();
        let ids = [5i64, 4, 3, 2, -1];
        let j = [1.0, 0.99 + 1e-17];
        write_vtu(
            &p,
            &m,
            &m.nodes,
            &[
                Field {
                    name: "displacement",
                    data: FieldData::Vector(&u),
                },
                Field {
                    name: "id",
                    data: FieldData::Int(&ids),
                },
            ],
            &[Field {
                name: "J",
                data: FieldData::Scalar(&j),
            }],
        )
        .unwrap();
        let l = read_vtu(&p).unwrap();
        assert_eq!(l.format, "vtu appended zlib");
        assert_eq!(l.mesh.nodes, m.nodes);
        assert_eq!(l.mesh.cells, m.cells);
        assert_eq!(read_vtu_array(&p, "displacement").unwrap(), (3, u));
        assert_eq!(
            read_vtu_array(&p, "id").unwrap(),
            (1, vec![5.0, 4.0, 3.0, 2.0, -1.0])
        );
        assert_eq!(read_vtu_array(&p, "J").unwrap(), (1, j.to_vec()));
        let text = String::from_utf8_lossy(&std::fs::read(&p).unwrap()).to_string();
        assert!(
            text.contains("<PointData Vectors=\"displacement\">"),
            "{text}"
        );
        assert!(text.contains("<DataArray type=\"Int64\" Name=\"id\" format=\"appended\""));
    }

    /// The compressed layout: header `[nblocks, block, last partial, sizes..]`, each block an
    /// independent zlib stream inflating to its share of the bytes.
    #[test]
    fn compressed_header_layout() {
        use std::io::Read;
        let bytes: Vec<u8> = (0..(2 * VTU_BLOCK_SIZE + 100))
            .map(|i| (i % 251) as u8)
            .collect();
        let out = compress_array(&bytes);
        let w = |i: usize| u64::from_le_bytes(out[8 * i..8 * i + 8].try_into().unwrap()) as usize;
        assert_eq!((w(0), w(1), w(2)), (3, VTU_BLOCK_SIZE, 100));
        let mut pos = 8 * 6;
        let mut all = Vec::new();
        for b in 0..3 {
            flate2::read::ZlibDecoder::new(&out[pos..pos + w(3 + b)])
                .read_to_end(&mut all)
                .unwrap();
            pos += w(3 + b);
        }
        assert_eq!(pos, out.len());
        assert_eq!(all, bytes);
        // A whole number of blocks: the last-block field is 0.
        let out = compress_array(&bytes[..VTU_BLOCK_SIZE]);
        assert_eq!(
            &out[..24],
            &[1u64, VTU_BLOCK_SIZE as u64, 0]
                .map(u64::to_le_bytes)
                .concat()[..]
        );
    }

    #[test]
    fn vtu_triangles_and_no_fields() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.vtu");
        let m = Mesh::new(
            ElementKind::Tri3,
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            vec![0, 1, 2],
        );
        write_vtu_as(&p, &m, &m.nodes, &[], &[], VtuFormat::Ascii).unwrap();
        let vtk = vtkio::Vtk::import(&p).unwrap();
        let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
            panic!()
        };
        let Piece::Inline(piece) = pieces.into_iter().next().unwrap() else {
            panic!()
        };
        assert_eq!(piece.cells.types, vec![vtkio::model::CellType::Triangle]);
    }

    #[test]
    fn vtu_refuses_nan_and_bad_lengths() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.vtu");
        let m = two_tets();
        let mut u = vec![0.0; 15];
        u[7] = f64::NAN;
        let e = write_vtu(
            &p,
            &m,
            &m.nodes,
            &[Field {
                name: "displacement",
                data: FieldData::Vector(&u),
            }],
            &[],
        )
        .unwrap_err();
        let s = e.to_string();
        assert!(matches!(e, Error::Param { .. }), "{s}");
        assert!(
            s.contains("displacement") && s.contains("item 2 component 1"),
            "{s}"
        );
        let mut pos = m.nodes.clone();
        pos[4][2] = f64::INFINITY;
        let s = write_vtu(&p, &m, &pos, &[], &[]).unwrap_err().to_string();
        assert!(s.contains("positions") && s.contains("item 4"), "{s}");
        let s = write_vtu(
            &p,
            &m,
            &m.nodes,
            &[],
            &[Field {
                name: "J",
                data: FieldData::Scalar(&[1.0]),
            }],
        )
        .unwrap_err()
        .to_string();
        assert!(s.contains("needs 2 items"), "{s}");
        assert!(!p.exists());
    }

    #[test]
    fn pvd_lists_frames() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("run.pvd");
        let mut pvd = PvdWriter::new(&p);
        pvd.add(0.0, "frame_0000.vtu").unwrap();
        pvd.add(0.025, "frames/frame_0001.vtu").unwrap();
        assert!(pvd.add(f64::NAN, "x.vtu").is_err());
        let text = std::fs::read_to_string(&p).unwrap();
        assert!(text.contains("type=\"Collection\""), "{text}");
        assert_eq!(text.matches("<DataSet ").count(), 2, "{text}");
        assert!(text.contains("timestep=\"2.5e-2\""), "{text}");
        assert!(text.contains("file=\"frames/frame_0001.vtu\""), "{text}");
        assert_eq!(pvd.len(), 2);
        // Constant work per frame: the file grows by one line each time.
        let before = std::fs::metadata(&p).unwrap().len();
        pvd.add(0.05, "frames/frame_0002.vtu").unwrap();
        let after = std::fs::read_to_string(&p).unwrap();
        let line = "    <DataSet timestep=\"5e-2\" group=\"\" part=\"0\" file=\"frames/frame_0002.vtu\"/>\n";
        assert_eq!(after.len() as u64 - before, line.len() as u64, "{after}");
        assert!(after.contains(line), "{after}");
        assert!(after.ends_with("  </Collection>\n</VTKFile>\n"), "{after}");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }
}
