//! Reading VTK XML unstructured grids (`.vtu`).
//!
//! Read: `<VTKFile type="UnstructuredGrid">` with one or more `<Piece>`s (concatenated, the
//! point ids of each piece shifted by the points before it), their `<Points>` and the
//! `connectivity`, `offsets` and `types` arrays of `<Cells>`; point and cell data are
//! skipped. Cell types are handled as in [legacy VTK](super::vtk): 5 (triangle) and 10
//! (tetrahedron) are the mesh elements, 22 and 24 are read as their corners, cells of lower
//! dimension are ignored.
//!
//! Every `<DataArray>` storage VTK defines is read:
//! - `format="ascii"`: whitespace-separated numbers;
//! - `format="binary"`: base64 text inline;
//! - `format="appended"`: at byte (`encoding="raw"`) or character (`encoding="base64"`)
//!   `offset` after the `_` that opens `<AppendedData>`;
//!
//! each one uncompressed (a header holding the byte count, then the bytes) or, with
//! `compressor="vtkZLibDataCompressor"` on `<VTKFile>`, zlib-compressed (a header
//! `[nblocks, block size, size of the last block if partial else 0, compressed size of each
//! block]`, then the compressed blocks). Header words are `header_type` (`UInt32`, the
//! default, or `UInt64`), all numbers in `byte_order` (`LittleEndian` or `BigEndian`). Base64
//! headers are accepted both encoded on their own and encoded together with the data (VTK and
//! meshio encode them separately, others jointly). Value types: `Int8` to `UInt64`,
//! `Float32`, `Float64`. `offsets` may list the end of each cell (VTK) or also the leading 0.
//!
//! Sizes are checked before anything is allocated for them: `NumberOfPoints` and
//! `NumberOfCells` (and the connectivity length, the last of `offsets`) against the memory
//! available ([`crate::memory`]); then each array's size as its header announces it (the
//! byte count, or the zlib blocks' inflated sizes) against what those counts allow for its
//! type (`NumberOfPoints × 3` point coordinates, `NumberOfCells` types and offsets, or one
//! more offset, the last offset's connectivity entries), before its data are decoded or
//! inflated; ASCII values are counted before they are stored. Each zlib block is inflated
//! through a bound of its announced size plus one byte, so a stream that inflates to more
//! stops there.
//!
//! Every inconsistency (truncated data, a size that disagrees with `NumberOfPoints` /
//! `NumberOfCells` or with the header, a block that does not inflate to its stated size, an
//! unknown type or compressor, a cell referring to a missing point) is an
//! [`Error::MeshFormat`](crate::Error::MeshFormat) naming the file, the line of the element
//! at fault where there is one, and what was expected.

use std::io::Read;
use std::path::Path;

use base64::engine::general_purpose::{GeneralPurpose, GeneralPurposeConfig};
use base64::engine::DecodePaddingMode;
use base64::Engine;
use roxmltree::{Document, Node};

use super::text::{format_err, show};
use super::vtk::{build, Grid};
use super::{finish, read_bytes, LoadedMesh};
use crate::Result;

/// Base64 that accepts padding or none, and non-zero trailing bits.
const B64: GeneralPurpose = GeneralPurpose::new(
    &base64::alphabet::STANDARD,
    GeneralPurposeConfig::new()
        .with_decode_padding_mode(DecodePaddingMode::Indifferent)
        .with_decode_allow_trailing_bits(true),
);

/// Bytes a point may take while a `.vtu` is read and built into a mesh: its coordinates as
/// stored (at most 24), as `f64` (24), in the grid (24), the mesh's node, file id and
/// renumbering (about 40), with room to spare.
const POINT_BYTES: u64 = 160;
/// Bytes a cell may take while read: its offset and type as stored (at most 16), as `i128`
/// (32), as `u64` and `i64` (16), in the grid (16), with room to spare.
const CELL_BYTES: u64 = 96;
/// Bytes a connectivity entry may take while read: as stored (at most 8), as `i128` (16), as
/// `u64` (8), in the grid (8), in the mesh (4), with room to spare.
const CONN_BYTES: u64 = 48;

/// What a memory refusal while reading suggests.
const READ_REMEDY: &str =
    "the file's declared counts are wrong, or the mesh is too large for this machine";

/// Parse the XML part of `bytes`.
fn parse_xml<'x>(path: &Path, xml: &'x str) -> Result<Document<'x>> {
    Document::parse(xml).map_err(|e| {
        let p = e.pos();
        format_err(path, p.row as usize, format!("malformed XML: {e}"))
    })
}

/// Read the point or cell data array `name` of the first `<Piece>` of a `.vtu` file (or a
/// `.vtp` file, its polygons as the cells):
/// (components per item, values as `f64`, integers converted). Any storage the module docs
/// list; errors as for [`read_vtu`], and when there is no such array.
pub fn read_vtu_array(path: &Path, name: &str) -> Result<(usize, Vec<f64>)> {
    read_data_array(path, name, &["PointData", "CellData"])
}

/// [`read_vtu_array`] of the cell data only (`<CellData>`; a point array of the same name is
/// not taken): (components per cell, values), one item per cell of the first `<Piece>`.
pub fn read_vtu_cell_array(path: &Path, name: &str) -> Result<(usize, Vec<f64>)> {
    read_data_array(path, name, &["CellData"])
}

/// The array `name` of the first of `groups` (`"PointData"`, `"CellData"`) of the first
/// `<Piece>` that has one.
fn read_data_array(path: &Path, name: &str, groups: &[&str]) -> Result<(usize, Vec<f64>)> {
    let bytes = read_bytes(path)?;
    let (xml, appended) = split_appended(path, &bytes)?;
    let doc = parse_xml(path, &xml)?;
    let cx = Context::new(path, &doc, appended, &["UnstructuredGrid", "PolyData"])?;
    let root = doc.root_element();
    let poly = root.attribute("type") == Some("PolyData");
    let grid = child(
        &cx,
        root,
        if poly { "PolyData" } else { "UnstructuredGrid" },
    )?;
    let piece = child(&cx, grid, "Piece")?;
    let np = cx.count_attr(piece, "NumberOfPoints")?;
    let nc = cx.count_attr(
        piece,
        if poly {
            "NumberOfPolys"
        } else {
            "NumberOfCells"
        },
    )?;
    for (group, items) in [("PointData", np), ("CellData", nc)] {
        if !groups.contains(&group) {
            continue;
        }
        let Some(g) = piece.children().find(|n| n.has_tag_name(group)) else {
            continue;
        };
        if let Some(a) = g
            .children()
            .find(|n| n.has_tag_name("DataArray") && n.attribute("Name") == Some(name))
        {
            let k = match a.attribute("NumberOfComponents") {
                None => 1,
                Some(s) => s
                    .trim()
                    .parse::<usize>()
                    .ok()
                    .filter(|&k| k > 0)
                    .ok_or_else(|| {
                        cx.err(
                            a,
                            format!("`NumberOfComponents` = {}: expected a count", show(s)),
                        )
                    })?,
            };
            let v = cx.read_f64(a, name, &[items.saturating_mul(k)])?;
            return Ok((k, v));
        }
    }
    Err(cx.err(
        piece,
        format!(
            "no {} data array named {}",
            if groups.len() == 1 {
                "cell"
            } else {
                "point or cell"
            },
            show(name)
        ),
    ))
}

/// Read the points and triangles of the first `<Piece>` of a VTK XML PolyData file (`.vtp`,
/// as [`crate::io::write_vtp`] writes it): `<Points>` and the `connectivity` and `offsets`
/// of `<Polys>`, every polygon a triangle. Any storage the module docs list; errors name the
/// file and line, and a polygon that is not a triangle.
pub fn read_vtp(path: &Path) -> Result<crate::mesh::Surface> {
    let bytes = read_bytes(path)?;
    let (xml, appended) = split_appended(path, &bytes)?;
    let doc = parse_xml(path, &xml)?;
    let cx = Context::new(path, &doc, appended, &["PolyData"])?;
    let grid = child(&cx, doc.root_element(), "PolyData")?;
    let piece = child(&cx, grid, "Piece")?;
    let np = cx.count_attr(piece, "NumberOfPoints")?;
    let nt = cx.count_attr(piece, "NumberOfPolys")?;
    let pts_el = child(&cx, piece, "Points")?;
    let pts = pts_el
        .children()
        .find(|n| n.has_tag_name("DataArray"))
        .ok_or_else(|| cx.err(pts_el, "`<Points>` has no `<DataArray>`"))?;
    let points = cx.read_f64(pts, "Points", &[3 * np])?;
    let polys = child(&cx, piece, "Polys")?;
    let named = |name: &str| {
        polys
            .children()
            .find(|n| n.has_tag_name("DataArray") && n.attribute("Name") == Some(name))
            .ok_or_else(|| {
                cx.err(
                    polys,
                    format!("`<Polys>` has no `<DataArray Name=\"{name}\">`"),
                )
            })
    };
    let offs_el = named("offsets")?;
    let offs = cx.read_u64(offs_el, "offsets", &[nt])?;
    if let Some(t) = (0..nt).find(|&t| offs[t] != 3 * (t as u64 + 1)) {
        return Err(cx.err(
            offs_el,
            format!("polygon {t} is not a triangle (`offsets` = {})", offs[t]),
        ));
    }
    let conn_el = named("connectivity")?;
    let conn = cx.read_u64(conn_el, "connectivity", &[3 * nt])?;
    if let Some((c, &bad)) = conn.iter().enumerate().find(|(_, &v)| v >= np as u64) {
        return Err(cx.err(
            conn_el,
            format!("`connectivity` value {c} is point {bad}, but there are {np} points"),
        ));
    }
    Ok(crate::mesh::Surface {
        points: points.chunks(3).map(|c| [c[0], c[1], c[2]]).collect(),
        triangles: conn
            .chunks(3)
            .map(|c| [c[0] as u32, c[1] as u32, c[2] as u32])
            .collect(),
    })
}

/// Read a `.vtu` file (see the module docs).
pub fn read_vtu(path: &Path) -> Result<LoadedMesh> {
    let bytes = read_bytes(path)?;
    let (xml, appended) = split_appended(path, &bytes)?;
    let doc = parse_xml(path, &xml)?;
    let cx = Context::new(path, &doc, appended, &["UnstructuredGrid"])?;
    let root = doc.root_element();
    let grid = child(&cx, root, "UnstructuredGrid")?;
    let pieces: Vec<Node> = grid
        .children()
        .filter(|n| n.has_tag_name("Piece"))
        .collect();
    if pieces.is_empty() {
        return Err(cx.err(grid, "`<UnstructuredGrid>` has no `<Piece>`"));
    }
    let mut all = Grid {
        points: Vec::new(),
        conn: Vec::new(),
        offsets: vec![0],
        types: Vec::new(),
        cell_lines: None,
        type_lines: None,
        cells_name: "`offsets`",
        types_name: "`types`",
    };
    for piece in pieces {
        let base = (all.points.len() / 3) as u64;
        let np = cx.count_attr(piece, "NumberOfPoints")?;
        let nc = cx.count_attr(piece, "NumberOfCells")?;
        cx.check_memory(
            piece,
            &format!("reading {np} points and {nc} cells"),
            (base as u128 + np as u128) * POINT_BYTES as u128 + nc as u128 * CELL_BYTES as u128,
        )?;
        let pts_el = child(&cx, piece, "Points")?;
        let pts = pts_el
            .children()
            .find(|n| n.has_tag_name("DataArray"))
            .ok_or_else(|| cx.err(pts_el, "`<Points>` has no `<DataArray>`"))?;
        let comps = match pts.attribute("NumberOfComponents") {
            None => 1,
            Some(s) => s.trim().parse::<usize>().map_err(|_| {
                cx.err(
                    pts,
                    format!("`NumberOfComponents` = {}: expected a count", show(s)),
                )
            })?,
        };
        if comps != 3 {
            return Err(cx.err(
                pts,
                format!("the points have {comps} components; expected 3 (x, y, z)"),
            ));
        }
        let points = cx.read_f64(pts, "Points", &[3 * np])?;
        if let Some(i) = points.iter().position(|v| !v.is_finite()) {
            return Err(cx.err(
                pts,
                format!(
                    "point {} has a non-finite coordinate {}",
                    base as usize + i / 3,
                    points[i]
                ),
            ));
        }
        let cells = child(&cx, piece, "Cells")?;
        let named = |name: &str| {
            cells
                .children()
                .find(|n| n.has_tag_name("DataArray") && n.attribute("Name") == Some(name))
                .ok_or_else(|| {
                    cx.err(
                        cells,
                        format!("`<Cells>` has no `<DataArray Name=\"{name}\">`"),
                    )
                })
        };
        let offs_el = named("offsets")?;
        let mut offs = cx.read_u64(offs_el, "offsets", &[nc, nc + 1])?;
        if offs.len() == nc + 1 {
            if offs[0] != 0 {
                return Err(cx.err(
                    offs_el,
                    format!(
                        "`offsets` has {} values for {nc} cells but does not start with 0",
                        nc + 1
                    ),
                ));
            }
            offs.remove(0);
        }
        if let Some(c) = offs
            .iter()
            .zip(std::iter::once(&0).chain(offs.iter()))
            .position(|(b, a)| b < a)
        {
            return Err(cx.err(
                offs_el,
                format!(
                    "`offsets` decrease at cell {c} ({} after {})",
                    offs[c],
                    if c == 0 { 0 } else { offs[c - 1] }
                ),
            ));
        }
        let total = offs.last().copied().unwrap_or(0) as usize;
        cx.check_memory(
            offs_el,
            &format!("reading {total} connectivity entries (the last of `offsets`)"),
            (all.conn.len() as u128 + total as u128) * CONN_BYTES as u128,
        )?;
        let conn_el = named("connectivity")?;
        let conn = cx.read_u64(conn_el, "connectivity", &[total])?;
        let types_el = named("types")?;
        let types = cx.read_u64(types_el, "types", &[nc])?;
        if let Some((c, &bad)) = conn.iter().enumerate().find(|(_, &v)| v >= np as u64) {
            return Err(cx.err(
                conn_el,
                format!(
                    "`connectivity` value {c} is point {bad}, but the piece has {np} points \
                     (0-based)"
                ),
            ));
        }
        let start = all.conn.len();
        all.points.extend_from_slice(&points);
        all.conn.extend(conn.iter().map(|&v| v + base));
        all.offsets.extend(offs.iter().map(|&o| start + o as usize));
        all.types
            .extend(types.iter().map(|&t| t.min(i64::MAX as u64) as i64));
    }
    finish(build(path, all)?, path, cx.format_name())
}

/// Split the file into XML text (with the appended data cut out, the element left empty)
/// and the appended bytes after the `_` marker (`None` without `<AppendedData>`).
fn split_appended<'b>(path: &Path, bytes: &'b [u8]) -> Result<(String, Option<&'b [u8]>)> {
    let text = |b: &[u8]| -> Result<String> {
        String::from_utf8(b.to_vec()).map_err(|e| {
            let at = e.utf8_error().valid_up_to();
            let line = b[..at].iter().filter(|&&c| c == b'\n').count() + 1;
            format_err(path, line, "the XML part is not UTF-8 text")
        })
    };
    let Some(open) = find(bytes, b"<AppendedData", 0) else {
        return Ok((text(bytes)?, None));
    };
    let line = bytes[..open].iter().filter(|&&c| c == b'\n').count() + 1;
    let gt = find(bytes, b">", open)
        .ok_or_else(|| format_err(path, line, "`<AppendedData` tag is not closed"))?;
    if bytes[gt - 1] == b'/' {
        return Ok((text(bytes)?, None));
    }
    let close = rfind(bytes, b"</AppendedData>")
        .filter(|&c| c > gt)
        .ok_or_else(|| {
            format_err(
                path,
                line,
                "`<AppendedData>` is never closed by `</AppendedData>` (truncated file?)",
            )
        })?;
    let body = &bytes[gt + 1..close];
    let Some(us) = body.iter().position(|&c| !c.is_ascii_whitespace()) else {
        return Err(format_err(path, line, "`<AppendedData>` is empty"));
    };
    if body[us] != b'_' {
        return Err(format_err(
            path,
            line,
            format!(
                "`<AppendedData>` must start with `_`, found byte 0x{:02x}",
                body[us]
            ),
        ));
    }
    let mut xml = text(&bytes[..gt + 1])?;
    xml.push_str(&text(&bytes[close..])?);
    Ok((xml, Some(&body[us + 1..])))
}

/// The text directly inside `n` (VTK puts `<InformationKey>` elements after the values).
fn own_text(n: Node) -> String {
    n.children()
        .filter(|c| c.is_text())
        .filter_map(|c| c.text())
        .collect::<Vec<_>>()
        .join(" ")
}

fn find(hay: &[u8], needle: &[u8], from: usize) -> Option<usize> {
    hay.get(from..)?
        .windows(needle.len())
        .position(|w| w == needle)
        .map(|p| p + from)
}

fn rfind(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).rposition(|w| w == needle)
}

fn child<'a, 'i>(cx: &Context, node: Node<'a, 'i>, tag: &str) -> Result<Node<'a, 'i>> {
    node.children()
        .find(|n| n.has_tag_name(tag))
        .ok_or_else(|| {
            cx.err(
                node,
                format!("`<{}>` has no `<{tag}>`", node.tag_name().name()),
            )
        })
}

/// Storage of the appended section.
#[derive(Clone, Copy, PartialEq)]
enum Encoding {
    Raw,
    Base64,
}

/// Value types.
#[derive(Clone, Copy, Debug)]
enum Ty {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
    F32,
    F64,
}

impl Ty {
    fn parse(s: &str) -> Option<Ty> {
        Some(match s {
            "Int8" | "Char" => Ty::I8,
            "UInt8" | "UChar" => Ty::U8,
            "Int16" => Ty::I16,
            "UInt16" => Ty::U16,
            "Int32" => Ty::I32,
            "UInt32" => Ty::U32,
            "Int64" => Ty::I64,
            "UInt64" => Ty::U64,
            "Float32" => Ty::F32,
            "Float64" => Ty::F64,
            _ => return None,
        })
    }
    fn size(self) -> usize {
        match self {
            Ty::I8 | Ty::U8 => 1,
            Ty::I16 | Ty::U16 => 2,
            Ty::I32 | Ty::U32 | Ty::F32 => 4,
            Ty::I64 | Ty::U64 | Ty::F64 => 8,
        }
    }
    fn is_float(self) -> bool {
        matches!(self, Ty::F32 | Ty::F64)
    }
}

/// Decoded values: floats, or integers as `i128` (holds every `Int64` and `UInt64`).
enum Vals {
    F(Vec<f64>),
    I(Vec<i128>),
}

/// What the declared counts allow an array to hold.
struct Limit<'t> {
    /// Values.
    values: usize,
    /// Bytes of those values as stored.
    bytes: usize,
    /// The array's type, as the file names it.
    ty: &'t str,
}

/// File-wide settings and the appended data.
struct Context<'a> {
    path: &'a Path,
    doc: &'a Document<'a>,
    big_endian: bool,
    /// Bytes per header word (4 or 8).
    header: usize,
    zlib: bool,
    appended: Option<(&'a [u8], Encoding)>,
    /// The storages met, for the format name.
    seen: std::cell::Cell<[bool; 3]>,
}

impl<'a> Context<'a> {
    fn new(
        path: &'a Path,
        doc: &'a Document<'a>,
        appended: Option<&'a [u8]>,
        types: &[&str],
    ) -> Result<Self> {
        let root = doc.root_element();
        let at = |n: Node, msg: String| {
            format_err(path, doc.text_pos_at(n.range().start).row as usize, msg)
        };
        if !root.has_tag_name("VTKFile") {
            return Err(at(
                root,
                format!(
                    "the root element is `<{}>`; expected `<VTKFile>`",
                    root.tag_name().name()
                ),
            ));
        }
        match root.attribute("type") {
            Some(t) if types.contains(&t) => {}
            other => {
                return Err(at(
                    root,
                    format!(
                        "`<VTKFile type=..>` is {}; only {} is read",
                        show(other.unwrap_or("(missing)")),
                        types
                            .iter()
                            .map(|t| format!("\"{t}\""))
                            .collect::<Vec<_>>()
                            .join(" or ")
                    ),
                ))
            }
        }
        let big_endian = match root.attribute("byte_order") {
            None | Some("LittleEndian") => false,
            Some("BigEndian") => true,
            Some(o) => {
                return Err(at(
                    root,
                    format!(
                        "`byte_order` = {}: valid are \"LittleEndian\", \"BigEndian\"",
                        show(o)
                    ),
                ))
            }
        };
        let header = match root.attribute("header_type") {
            None | Some("UInt32") => 4,
            Some("UInt64") => 8,
            Some(h) => {
                return Err(at(
                    root,
                    format!(
                        "`header_type` = {}: valid are \"UInt32\", \"UInt64\"",
                        show(h)
                    ),
                ))
            }
        };
        let zlib = match root.attribute("compressor") {
            None | Some("") => false,
            Some("vtkZLibDataCompressor") => true,
            Some(c) => {
                return Err(at(
                    root,
                    format!(
                        "`compressor` = {}: only \"vtkZLibDataCompressor\" (zlib) or none is \
                         read; re-save the file uncompressed or with zlib",
                        show(c)
                    ),
                ))
            }
        };
        let appended = match appended {
            None => None,
            Some(data) => {
                let el = root
                    .descendants()
                    .find(|n| n.has_tag_name("AppendedData"))
                    .expect("split_appended found the element");
                let enc = match el.attribute("encoding") {
                    Some("raw") => Encoding::Raw,
                    Some("base64") => Encoding::Base64,
                    other => {
                        return Err(at(
                            el,
                            format!(
                                "`<AppendedData encoding=..>` is {}; valid are \"raw\", \"base64\"",
                                show(other.unwrap_or("(missing)"))
                            ),
                        ))
                    }
                };
                Some((data, enc))
            }
        };
        Ok(Context {
            path,
            doc,
            big_endian,
            header,
            zlib,
            appended,
            seen: std::cell::Cell::new([false; 3]),
        })
    }

    fn line(&self, n: Node) -> usize {
        self.doc.text_pos_at(n.range().start).row as usize
    }

    fn err(&self, n: Node, msg: impl Into<String>) -> crate::Error {
        format_err(self.path, self.line(n), msg)
    }

    fn format_name(&self) -> &'static str {
        let [ascii, binary, appended] = self.seen.get();
        let z = self.zlib && (binary || appended);
        match (ascii, binary, appended, z) {
            (true, false, false, _) => "vtu ascii",
            (false, true, false, false) => "vtu binary",
            (false, true, false, true) => "vtu binary zlib",
            (false, false, true, false) => "vtu appended",
            (false, false, true, true) => "vtu appended zlib",
            _ => "vtu",
        }
    }

    /// Refuse reading what needs `bytes` (counted from the declared sizes) where the
    /// memory available cannot hold it ([`crate::memory`]).
    fn check_memory(&self, n: Node, what: &str, bytes: u128) -> Result<()> {
        let bytes = u64::try_from(bytes).unwrap_or(u64::MAX);
        crate::memory::check_for(what, bytes, READ_REMEDY).map_err(|e| self.err(n, e))
    }

    /// A non-negative count attribute.
    fn count_attr(&self, n: Node, name: &str) -> Result<usize> {
        let s = n
            .attribute(name)
            .ok_or_else(|| self.err(n, format!("`<{}>` has no `{name}`", n.tag_name().name())))?;
        s.trim()
            .parse()
            .map_err(|_| self.err(n, format!("`{name}` = {}: expected a count", show(s))))
    }

    fn read_f64(&self, n: Node, what: &str, expect: &[usize]) -> Result<Vec<f64>> {
        Ok(match self.read(n, what, expect)? {
            Vals::F(v) => v,
            Vals::I(v) => v.into_iter().map(|x| x as f64).collect(),
        })
    }

    /// Non-negative integers.
    fn read_u64(&self, n: Node, what: &str, expect: &[usize]) -> Result<Vec<u64>> {
        match self.read(n, what, expect)? {
            Vals::F(_) => Err(self.err(
                n,
                format!(
                    "`{what}` is `{}`; expected an integer type",
                    n.attribute("type").unwrap_or("")
                ),
            )),
            Vals::I(v) => v
                .iter()
                .enumerate()
                .map(|(i, &x)| {
                    u64::try_from(x).map_err(|_| {
                        self.err(n, format!("`{what}` value {i} is {x}; expected >= 0"))
                    })
                })
                .collect(),
        }
    }

    /// Read a `<DataArray>` holding one of `expect` values in all.
    fn read(&self, n: Node, what: &str, expect: &[usize]) -> Result<Vals> {
        let tys = n.attribute("type").unwrap_or("(missing)");
        let ty = Ty::parse(tys).ok_or_else(|| {
            self.err(
                n,
                format!(
                    "`{what}` has type {}; valid are Int8, UInt8, Int16, UInt16, Int32, UInt32, \
                     Int64, UInt64, Float32, Float64",
                    show(tys)
                ),
            )
        })?;
        // What the declared counts allow, checked against memory before anything is decoded:
        // the values as stored, as `i128` or `f64`, and the caller's copy.
        let most = expect.iter().copied().max().unwrap_or(0);
        let limit = Limit {
            values: most,
            bytes: most.checked_mul(ty.size()).ok_or_else(|| {
                self.err(
                    n,
                    format!("`{what}`: {most} values of {tys} overflow the address space"),
                )
            })?,
            ty: tys,
        };
        self.check_memory(
            n,
            &format!("reading `{what}` ({most} values)"),
            most as u128 * (ty.size() as u128 + 24),
        )?;
        let want = |len: usize| -> Result<()> {
            if expect.contains(&len) {
                Ok(())
            } else {
                Err(self.err(
                    n,
                    format!(
                        "`{what}` holds {len} values; expected {}",
                        expect
                            .iter()
                            .map(|e| e.to_string())
                            .collect::<Vec<_>>()
                            .join(" or ")
                    ),
                ))
            }
        };
        let format = n.attribute("format").unwrap_or("(missing)");
        let mut seen = self.seen.get();
        let bytes = match format {
            "ascii" => {
                seen[0] = true;
                self.seen.set(seen);
                // Counted before they are stored.
                let text = own_text(n);
                want(text.split_ascii_whitespace().count())?;
                return self.parse_ascii(n, what, ty, &text);
            }
            "binary" => {
                seen[1] = true;
                let text: Vec<u8> = own_text(n)
                    .bytes()
                    .filter(|c| !c.is_ascii_whitespace())
                    .collect();
                self.decode_base64(n, what, &text, &limit)?
            }
            "appended" => {
                seen[2] = true;
                let Some((data, enc)) = self.appended else {
                    return Err(self.err(
                        n,
                        format!("`{what}` is appended but the file has no `<AppendedData>`"),
                    ));
                };
                let off = self.count_attr(n, "offset")?;
                let rest = data.get(off..).ok_or_else(|| {
                    self.err(
                        n,
                        format!(
                            "`{what}` has offset {off} but the appended data hold only {} bytes \
                             (truncated file?)",
                            data.len()
                        ),
                    )
                })?;
                match enc {
                    Encoding::Raw => self.decode_raw(n, what, rest, &limit)?,
                    Encoding::Base64 => self.decode_base64(n, what, rest, &limit)?,
                }
            }
            other => {
                return Err(self.err(
                    n,
                    format!(
                        "`{what}` has format {}; valid are \"ascii\", \"binary\", \"appended\"",
                        show(other)
                    ),
                ))
            }
        };
        self.seen.set(seen);
        let size = ty.size();
        if bytes.len() % size != 0 {
            return Err(self.err(
                n,
                format!(
                    "`{what}` holds {} bytes, not a whole number of {tys} values ({size} bytes)",
                    bytes.len()
                ),
            ));
        }
        want(bytes.len() / size)?;
        Ok(self.convert(ty, &bytes))
    }

    fn parse_ascii(&self, n: Node, what: &str, ty: Ty, text: &str) -> Result<Vals> {
        let bad = |i: usize, tok: &str| {
            self.err(
                n,
                format!(
                    "`{what}` value {i}: expected a number of type {ty:?}, found {}",
                    show(tok)
                ),
            )
        };
        if ty.is_float() {
            text.split_ascii_whitespace()
                .enumerate()
                .map(|(i, t)| t.parse::<f64>().map_err(|_| bad(i, t)))
                .collect::<Result<_>>()
                .map(Vals::F)
        } else {
            text.split_ascii_whitespace()
                .enumerate()
                .map(|(i, t)| t.parse::<i128>().map_err(|_| bad(i, t)))
                .collect::<Result<_>>()
                .map(Vals::I)
        }
    }

    /// A header word at `bytes[i * header..]`.
    fn word(&self, bytes: &[u8], i: usize) -> u64 {
        let b = &bytes[i * self.header..(i + 1) * self.header];
        match (self.header, self.big_endian) {
            (4, false) => u32::from_le_bytes(b.try_into().unwrap()) as u64,
            (4, true) => u32::from_be_bytes(b.try_into().unwrap()) as u64,
            (_, false) => u64::from_le_bytes(b.try_into().unwrap()),
            (_, true) => u64::from_be_bytes(b.try_into().unwrap()),
        }
    }

    /// The header length (bytes) given its first word, and the stored data length from the
    /// whole header.
    fn header_len(&self, first: u64) -> Option<usize> {
        if self.zlib {
            (first as usize).checked_add(3)?.checked_mul(self.header)
        } else {
            Some(self.header)
        }
    }

    /// The array's length in bytes as the header announces it: the byte count, or for zlib
    /// the blocks' inflated sizes (`(nblocks − 1) × block size + last block size`).
    fn announced_len(&self, n: Node, what: &str, header: &[u8]) -> Result<usize> {
        if !self.zlib {
            return usize::try_from(self.word(header, 0))
                .map_err(|_| self.err(n, format!("`{what}`: header size overflows")));
        }
        let nb = self.word(header, 0) as usize;
        let bs = self.word(header, 1) as usize;
        let last = self.word(header, 2) as usize;
        if nb > 0 && bs == 0 {
            return Err(self.err(n, format!("`{what}`: block size 0 in the header")));
        }
        if last > bs {
            return Err(self.err(
                n,
                format!("`{what}`: last block size {last} exceeds the block size {bs}"),
            ));
        }
        match nb {
            0 => Ok(0),
            _ => (nb - 1)
                .checked_mul(bs)
                .and_then(|t| t.checked_add(if last == 0 { bs } else { last }))
                .ok_or_else(|| self.err(n, format!("`{what}`: header sizes overflow"))),
        }
    }

    /// The announced length, refused where it exceeds what the declared counts allow (before
    /// any data is decoded or inflated).
    fn checked_len(&self, n: Node, what: &str, header: &[u8], limit: &Limit) -> Result<usize> {
        let len = self.announced_len(n, what, header)?;
        if len > limit.bytes {
            return Err(self.err(
                n,
                format!(
                    "`{what}`: the header announces {len} bytes{}, but {} values of {} (what \
                     the piece's declared counts allow) take {} bytes; refused without {}",
                    if self.zlib { " inflated" } else { "" },
                    limit.values,
                    limit.ty,
                    limit.bytes,
                    if self.zlib {
                        "inflating it"
                    } else {
                        "reading it"
                    }
                ),
            ));
        }
        Ok(len)
    }

    fn stored_len(&self, n: Node, what: &str, header: &[u8]) -> Result<usize> {
        if self.zlib {
            let nb = self.word(header, 0) as usize;
            let mut sum = 0usize;
            for b in 0..nb {
                sum = sum
                    .checked_add(self.word(header, 3 + b) as usize)
                    .ok_or_else(|| self.err(n, format!("`{what}`: block sizes overflow")))?;
            }
            Ok(sum)
        } else {
            Ok(self.word(header, 0) as usize)
        }
    }

    /// Header + data, raw bytes from the start of `rest`.
    fn decode_raw(&self, n: Node, what: &str, rest: &[u8], limit: &Limit) -> Result<Vec<u8>> {
        let trunc = |need: usize| {
            self.err(
                n,
                format!(
                    "`{what}`: the appended data end after {} bytes, {need} needed (truncated \
                     file?)",
                    rest.len()
                ),
            )
        };
        if rest.len() < self.header {
            return Err(trunc(self.header));
        }
        let hl = self
            .header_len(self.word(rest, 0))
            .filter(|&h| h <= rest.len())
            .ok_or_else(|| {
                self.err(
                    n,
                    format!(
                        "`{what}`: the header announces {} blocks, more than the file holds \
                         (truncated or not compressed?)",
                        self.word(rest, 0)
                    ),
                )
            })?;
        let header = &rest[..hl];
        let total = self.checked_len(n, what, header, limit)?;
        let dl = self.stored_len(n, what, header)?;
        let data = rest
            .get(hl..hl.saturating_add(dl))
            .ok_or_else(|| trunc(hl.saturating_add(dl)))?;
        self.inflate(n, what, header, data, total)
    }

    /// Header + data in base64 from the start of `text` (whitespace removed), the header
    /// encoded on its own or together with the data.
    fn decode_base64(&self, n: Node, what: &str, text: &[u8], limit: &Limit) -> Result<Vec<u8>> {
        let chars = |bytes: usize| bytes.div_ceil(3) * 4;
        let dec = |t: &[u8], part: &str| -> Result<Vec<u8>> {
            B64.decode(t)
                .map_err(|e| self.err(n, format!("`{what}`: bad base64 in the {part}: {e}")))
        };
        let get = |len: usize, part: &str| -> Result<&[u8]> {
            text.get(..len).ok_or_else(|| {
                self.err(
                    n,
                    format!(
                        "`{what}`: the base64 text ends after {} characters, {len} needed for \
                         the {part} (truncated file?)",
                        text.len()
                    ),
                )
            })
        };
        let first = dec(get(chars(self.header), "header")?, "header")?;
        if first.len() < self.header {
            return Err(self.err(n, format!("`{what}`: the header is cut short")));
        }
        let hl = self
            .header_len(self.word(&first, 0))
            .filter(|&h| h <= text.len() && chars(h) <= text.len())
            .ok_or_else(|| {
                self.err(
                    n,
                    format!(
                        "`{what}`: the header announces {} blocks, more than the text holds \
                         (truncated or not compressed?)",
                        self.word(&first, 0)
                    ),
                )
            })?;
        let hc = chars(hl);
        let head = dec(&text[..hc], "header")?;
        if head.len() < hl {
            return Err(self.err(n, format!("`{what}`: the header is cut short")));
        }
        let header = &head[..hl];
        let total = self.checked_len(n, what, header, limit)?;
        let dl = self.stored_len(n, what, header)?;
        if dl > text.len() {
            return Err(self.err(
                n,
                format!(
                    "`{what}`: the header announces {dl} bytes but the base64 text holds only \
                     {} characters (truncated file?)",
                    text.len()
                ),
            ));
        }
        let separate = hl % 3 != 0 && text[hc - 1] == b'=';
        let data = if separate {
            let rest = &text[hc..];
            let need = chars(dl);
            let t = rest.get(..need).ok_or_else(|| {
                self.err(
                    n,
                    format!(
                        "`{what}`: the base64 data end after {} characters, {need} needed \
                         (truncated file?)",
                        rest.len()
                    ),
                )
            })?;
            dec(t, "data")?
        } else {
            let all = dec(get(chars(hl.saturating_add(dl)), "data")?, "data")?;
            all[hl.min(all.len())..].to_vec()
        };
        if data.len() < dl {
            return Err(self.err(
                n,
                format!("`{what}`: {} data bytes, the header says {dl}", data.len()),
            ));
        }
        self.inflate(n, what, header, &data[..dl], total)
    }

    /// The array's bytes: `data` as they are, or its zlib blocks inflated to the `total`
    /// bytes the header announces ([`Context::checked_len`]), each block read through a
    /// bound of its announced size, so that a stream inflating to more stops there.
    fn inflate(
        &self,
        n: Node,
        what: &str,
        header: &[u8],
        data: &[u8],
        total: usize,
    ) -> Result<Vec<u8>> {
        if !self.zlib {
            return Ok(data.to_vec());
        }
        let nb = self.word(header, 0) as usize;
        let bs = self.word(header, 1) as usize;
        let last = self.word(header, 2) as usize;
        // A zlib stream inflates at most ~1032:1; refuse sizes no data could produce before
        // allocating.
        if total / 1032 > data.len() + 1 {
            return Err(self.err(
                n,
                format!(
                    "`{what}`: the header announces {total} bytes from {} compressed bytes",
                    data.len()
                ),
            ));
        }
        // One byte of room past `total`: a block inflating to more stops at its bound plus
        // one byte, which then fits without growing the buffer.
        let mut out = Vec::with_capacity(total.saturating_add(1));
        let mut pos = 0usize;
        for b in 0..nb {
            let c = self.word(header, 3 + b) as usize;
            let want = if b + 1 == nb && last != 0 { last } else { bs };
            let block = &data[pos..pos + c];
            pos += c;
            let before = out.len();
            flate2::read::ZlibDecoder::new(block)
                .take(want as u64 + 1)
                .read_to_end(&mut out)
                .map_err(|e| {
                    self.err(
                        n,
                        format!("`{what}`: zlib block {b} of {nb} does not inflate: {e}"),
                    )
                })?;
            let got = out.len() - before;
            if got > want {
                return Err(self.err(
                    n,
                    format!(
                        "`{what}`: zlib block {b} of {nb} inflates to more than the {want} bytes \
                         the header says (inflating stopped there)"
                    ),
                ));
            }
            if got < want {
                return Err(self.err(
                    n,
                    format!(
                        "`{what}`: zlib block {b} of {nb} inflates to {got} bytes; the header \
                         says {want}"
                    ),
                ));
            }
        }
        Ok(out)
    }

    fn convert(&self, ty: Ty, b: &[u8]) -> Vals {
        macro_rules! conv {
            ($t:ty, $n:expr, $wrap:ident, $as:ty) => {
                Vals::$wrap(
                    b.chunks_exact($n)
                        .map(|c| {
                            let a: [u8; $n] = c.try_into().unwrap();
                            (if self.big_endian {
                                <$t>::from_be_bytes(a)
                            } else {
                                <$t>::from_le_bytes(a)
                            }) as $as
                        })
                        .collect(),
                )
            };
        }
        match ty {
            Ty::I8 => conv!(i8, 1, I, i128),
            Ty::U8 => conv!(u8, 1, I, i128),
            Ty::I16 => conv!(i16, 2, I, i128),
            Ty::U16 => conv!(u16, 2, I, i128),
            Ty::I32 => conv!(i32, 4, I, i128),
            Ty::U32 => conv!(u32, 4, I, i128),
            Ty::I64 => conv!(i64, 8, I, i128),
            Ty::U64 => conv!(u64, 8, I, i128),
            Ty::F32 => conv!(f32, 4, F, f64),
            Ty::F64 => conv!(f64, 8, F, f64),
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::io::load_mesh;
    use std::io::Write;
    use std::sync::OnceLock;

    /// A `.vtu` of one tetrahedron: `NumberOfPoints` = `np`, the `<Points>` array `points`
    /// (a whole `<DataArray>` element), cells in ASCII with `offsets`, and the raw appended
    /// bytes `appended` where not empty; `root` is added to `<VTKFile>`'s attributes.
    fn vtu(root: &str, np: &str, points: &str, offsets: &str, appended: &[u8]) -> Vec<u8> {
        let mut f = format!(
            "<?xml version=\"1.0\"?>\n\
             <VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" \
             header_type=\"UInt32\"{root}>\n\
             <UnstructuredGrid>\n<Piece NumberOfPoints=\"{np}\" NumberOfCells=\"1\">\n\
             <Points>\n{points}\n</Points>\n<Cells>\n\
             <DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">0 1 2 3</DataArray>\n\
             <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">{offsets}</DataArray>\n\
             <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">10</DataArray>\n\
             </Cells>\n</Piece>\n</UnstructuredGrid>\n"
        )
        .into_bytes();
        if !appended.is_empty() {
            f.extend_from_slice(b"<AppendedData encoding=\"raw\">\n_");
            f.extend_from_slice(appended);
            f.extend_from_slice(b"\n</AppendedData>\n");
        }
        f.extend_from_slice(b"</VTKFile>\n");
        f
    }

    const ZLIB: &str = " compressor=\"vtkZLibDataCompressor\"";
    const APPENDED_POINTS: &str = "<DataArray type=\"Float64\" Name=\"Points\" \
                                   NumberOfComponents=\"3\" format=\"appended\" offset=\"0\"/>";

    /// Bytes the bomb inflates to.
    const BOMB: usize = 256 << 20;

    /// A zlib stream of [`BOMB`] zero bytes (about 256 KiB), made once.
    fn bomb() -> &'static [u8] {
        static Z: OnceLock<Vec<u8>> = OnceLock::new();
        Z.get_or_init(|| {
            let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::best());
            let zeros = vec![0u8; 1 << 20];
            for _ in 0..BOMB >> 20 {
                e.write_all(&zeros).unwrap();
            }
            e.finish().unwrap()
        })
    }

    /// A VTK zlib header of one block of `size` inflated and `compressed` bytes, then `data`.
    fn one_block(size: usize, compressed: usize, data: &[u8]) -> Vec<u8> {
        let mut b = Vec::new();
        for w in [1, size, 0, compressed] {
            b.extend_from_slice(&(w as u32).to_le_bytes());
        }
        b.extend_from_slice(data);
        b
    }

    /// The error of loading `bytes` saved as `name`.
    fn load_err(name: &str, bytes: &[u8]) -> String {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        match load_mesh(&p) {
            Ok(_) => panic!("{name}: read without error"),
            Err(e) => e.to_string(),
        }
    }

    /// A 256 KiB file whose `Points` header announces a 256 MiB zlib block for 4 points is
    /// refused from the header, naming the file and the array, before any byte is inflated:
    /// it was inflated in full (1 GiB from a 1.1 MB file) and only then found too long.
    #[test]
    fn vtu_zlib_bomb_is_refused_before_inflating() {
        let z = bomb();
        assert!(z.len() < BOMB / 500, "{} compressed bytes", z.len());
        // Appended raw.
        let f = vtu(
            ZLIB,
            "4",
            APPENDED_POINTS,
            "4",
            &one_block(BOMB, z.len(), z),
        );
        let e = load_err("bomb.vtu", &f);
        assert!(e.contains("bomb.vtu"), "{e}");
        assert!(
            e.contains(&format!(
                "`Points`: the header announces {BOMB} bytes inflated"
            )),
            "{e}"
        );
        assert!(
            e.contains("12 values of Float64") && e.contains("take 96 bytes"),
            "{e}"
        );
        assert!(e.contains("refused without inflating it"), "{e}");
        // Inline base64, the header encoded on its own as VTK does.
        use base64::Engine;
        let b64 = base64::engine::general_purpose::STANDARD;
        let head = one_block(BOMB, z.len(), &[]);
        let inline = format!(
            "<DataArray type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\" \
             format=\"binary\">{}{}</DataArray>",
            b64.encode(&head),
            b64.encode(z)
        );
        let e = load_err("bomb64.vtu", &vtu(ZLIB, "4", &inline, "4", &[]));
        assert!(e.contains("bomb64.vtu") && e.contains("`Points`"), "{e}");
        assert!(e.contains("refused without inflating it"), "{e}");
    }

    /// A header that announces the 96 bytes 4 points take, in front of a stream that
    /// inflates to 256 MiB: the block is inflated through a bound of 97 bytes and refused.
    #[test]
    fn vtu_zlib_stream_longer_than_its_header_stops_at_the_header_size() {
        let z = bomb();
        let f = vtu(ZLIB, "4", APPENDED_POINTS, "4", &one_block(96, z.len(), z));
        let e = load_err("long.vtu", &f);
        assert!(e.contains("long.vtu"), "{e}");
        assert!(
            e.contains(
                "`Points`: zlib block 0 of 1 inflates to more than the 96 bytes the header says"
            ),
            "{e}"
        );
    }

    /// Uncompressed data whose header announces more than the declared counts allow are
    /// refused from the header, raw and base64.
    #[test]
    fn vtu_uncompressed_size_beyond_the_declared_counts_is_refused() {
        let mut raw = (1u32 << 30).to_le_bytes().to_vec();
        raw.extend_from_slice(&[0; 96]);
        let e = load_err("big.vtu", &vtu("", "4", APPENDED_POINTS, "4", &raw));
        assert!(
            e.contains("big.vtu")
                && e.contains("`Points`: the header announces 1073741824 bytes, but 12 values")
                && e.contains("refused without reading it"),
            "{e}"
        );
    }

    /// Declared counts beyond the memory available are refused before any array is read,
    /// naming the file, the counts and the memory; so is a connectivity size (the last of
    /// `offsets`) beyond it.
    #[test]
    fn vtu_counts_beyond_memory_are_refused_before_reading() {
        if crate::memory::available().is_none() {
            return;
        }
        let e = load_err(
            "huge.vtu",
            &vtu("", "1000000000000000", APPENDED_POINTS, "4", &[]),
        );
        assert!(e.contains("huge.vtu"), "{e}");
        assert!(
            e.contains("reading 1000000000000000 points and 1 cells needs"),
            "{e}"
        );
        assert!(e.contains("GiB are available"), "{e}");
        let points = "<DataArray type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\" \
                      format=\"ascii\">0 0 0 1 0 0 0 1 0 0 0 1</DataArray>";
        let e = load_err("conn.vtu", &vtu("", "4", points, "1000000000000000", &[]));
        assert!(
            e.contains("conn.vtu")
                && e.contains("reading 1000000000000000 connectivity entries")
                && e.contains("GiB are available"),
            "{e}"
        );
        // The same file with its real offset reads.
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("ok.vtu");
        std::fs::write(&p, vtu("", "4", points, "4", &[])).unwrap();
        assert_eq!(load_mesh(&p).unwrap().mesh.num_elements(), 1);
    }
}
