//! VTK legacy files (`.vtk`) holding an `UNSTRUCTURED_GRID`.
//!
//! ASCII files are read (versions up to 5.1, including the 5.1 `CELLS` layout with `OFFSETS`
//! and `CONNECTIVITY`) with errors naming the line; binary files of every version (keyword
//! lines in ASCII, data big-endian, `CELLS` as the count-prefixed `int` list or the 5.1
//! `OFFSETS` and `CONNECTIVITY` arrays) with errors naming the byte offset and what was
//! expected there. Sections read: `POINTS`, `CELLS`, `CELL_TYPES` (`FIELD` blocks and
//! `METADATA` blocks, which run to the next blank line, are skipped); reading stops at
//! `POINT_DATA` or `CELL_DATA`.
//!
//! Cell types: 5 (triangle) and 10 (tetrahedron) are the mesh elements; 22 (quadratic
//! triangle) and 24 (quadratic tetrahedron) are read as their corners. Cells of lower
//! dimension than the mesh are ignored (legacy VTK has no named groups, so the mesh has no
//! groups); unsupported cells of the mesh dimension (hexahedra, quads...) are an error.
//! Point ids are 0-based and the file ids reported in messages are those 0-based ids.

use std::path::Path;

use super::text::{format_err, format_err_noline, show, Tokens};
use super::{finish, read_bytes, LoadedMesh, RawMesh};
use crate::{Error, Result};

/// Dimension and name of a VTK cell type.
fn vtk_cell(t: i64) -> (Option<u8>, &'static str) {
    match t {
        1 => (Some(0), "vertex"),
        2 => (Some(0), "poly-vertex"),
        3 => (Some(1), "line"),
        4 => (Some(1), "poly-line"),
        5 => (Some(2), "triangle"),
        6 => (Some(2), "triangle strip"),
        7 => (Some(2), "polygon"),
        8 => (Some(2), "pixel"),
        9 => (Some(2), "quad"),
        10 => (Some(3), "tetrahedron"),
        11 => (Some(3), "voxel"),
        12 => (Some(3), "hexahedron"),
        13 => (Some(3), "wedge"),
        14 => (Some(3), "pyramid"),
        15 => (Some(3), "pentagonal prism"),
        16 => (Some(3), "hexagonal prism"),
        21 => (Some(1), "quadratic edge"),
        22 => (Some(2), "quadratic triangle"),
        23 => (Some(2), "quadratic quad"),
        24 => (Some(3), "quadratic tetrahedron"),
        25 => (Some(3), "quadratic hexahedron"),
        26 => (Some(3), "quadratic wedge"),
        27 => (Some(3), "quadratic pyramid"),
        _ => (None, "unknown"),
    }
}

/// The parsed pieces of an unstructured grid, before checks (legacy and XML files).
pub(crate) struct Grid {
    pub points: Vec<f64>,
    pub conn: Vec<u64>,
    /// `ncells + 1` offsets into `conn`.
    pub offsets: Vec<usize>,
    pub types: Vec<i64>,
    /// Line of each cell (ASCII only) and of each cell type.
    pub cell_lines: Option<Vec<usize>>,
    pub type_lines: Option<Vec<usize>>,
    /// How messages name the cell list and the cell types.
    pub cells_name: &'static str,
    pub types_name: &'static str,
}

const LEGACY_CELLS: &str = "`CELLS`";
const LEGACY_TYPES: &str = "`CELL_TYPES`";

/// Read a legacy `.vtk` unstructured grid (ASCII or binary).
pub fn read_vtk(path: &Path) -> Result<LoadedMesh> {
    let bytes = read_bytes(path)?;
    // The first three lines: magic, title, encoding.
    let mut lines = bytes.split(|&c| c == b'\n');
    let l1 = String::from_utf8_lossy(lines.next().unwrap_or(b""));
    if !l1
        .trim()
        .to_ascii_lowercase()
        .starts_with("# vtk datafile version")
    {
        return Err(format_err(
            path,
            1,
            format!(
                "expected `# vtk DataFile Version x.x`, found {}",
                show(l1.trim())
            ),
        ));
    }
    let _title = lines.next();
    let l3 = lines
        .next()
        .map(|l| String::from_utf8_lossy(l).trim().to_ascii_uppercase());
    match l3.as_deref() {
        Some("ASCII") => {
            let text = String::from_utf8_lossy(&bytes);
            let grid = parse_ascii(path, &text)?;
            finish(build(path, grid)?, path, "vtk legacy ascii")
        }
        Some("BINARY") => {
            let grid = parse_binary(path, &bytes)?;
            finish(build(path, grid)?, path, "vtk legacy binary")
        }
        other => Err(format_err(
            path,
            3,
            format!(
                "expected `ASCII` or `BINARY`, found {}",
                show(other.unwrap_or("end of file"))
            ),
        )),
    }
}

fn parse_ascii(path: &Path, text: &str) -> Result<Grid> {
    let mut tk = Tokens::new(path, text, 3);
    let mut points: Option<Vec<f64>> = None;
    let mut cells: Option<(Vec<u64>, Vec<usize>, Vec<usize>)> = None;
    let mut types: Option<(Vec<i64>, Vec<usize>)> = None;
    let mut have_dataset = false;
    while let Some(kw) = tk.next_opt() {
        match kw.to_ascii_uppercase().as_str() {
            "DATASET" => {
                let t = tk.next("a dataset type")?;
                if !t.eq_ignore_ascii_case("UNSTRUCTURED_GRID") {
                    return Err(tk.err(format!(
                        "only `DATASET UNSTRUCTURED_GRID` is supported, found {}",
                        show(t)
                    )));
                }
                have_dataset = true;
            }
            "FIELD" => {
                tk.next("a field name")?;
                let n: usize = tk.parse("the number of field arrays")?;
                for _ in 0..n {
                    tk.next("an array name")?;
                    let nc: usize = tk.parse("the number of components")?;
                    let nt: usize = tk.parse("the number of tuples")?;
                    tk.next("a data type")?;
                    for _ in 0..nc.saturating_mul(nt) {
                        tk.next("a field value")?;
                    }
                }
            }
            "POINTS" => {
                if !have_dataset {
                    return Err(tk.err("`POINTS` before `DATASET UNSTRUCTURED_GRID`"));
                }
                let n: usize = tk.parse("the number of points")?;
                tk.next("the point data type")?;
                let mut p = Vec::with_capacity(n.saturating_mul(3).min(1 << 28));
                for i in 0..n {
                    for c in ["x", "y", "z"] {
                        p.push(tk.f64(&format!("{c} of point {i}"))?);
                    }
                }
                points = Some(p);
            }
            "CELLS" => {
                let a: usize = tk.parse("the number of cells")?;
                let b: usize = tk.parse("the cell list size")?;
                let mut conn = Vec::new();
                let mut offsets = vec![0usize];
                let mut lines = Vec::new();
                let first = tk.next("the cell list")?;
                if first.eq_ignore_ascii_case("OFFSETS") {
                    // VTK 5.1: `CELLS nOffsets nConnectivity`.
                    tk.next("the offsets data type")?;
                    let mut offs = Vec::with_capacity(a.min(1 << 28));
                    for _ in 0..a {
                        offs.push(tk.parse::<usize>("an offset")?);
                    }
                    let kw = tk.next("`CONNECTIVITY`")?;
                    if !kw.eq_ignore_ascii_case("CONNECTIVITY") {
                        return Err(tk.err(format!("expected `CONNECTIVITY`, found {}", show(kw))));
                    }
                    tk.next("the connectivity data type")?;
                    if offs.first() != Some(&0) || offs.last() != Some(&b) {
                        return Err(tk.err(format!(
                            "offsets must start at 0 and end at {b} (the connectivity size)"
                        )));
                    }
                    let mut cell = 0;
                    for k in 0..b {
                        let v: u64 = tk.parse("a point id")?;
                        while cell + 1 < offs.len() && offs[cell] == k {
                            lines.push(tk.line);
                            cell += 1;
                        }
                        conn.push(v);
                    }
                    if offs.windows(2).any(|w| w[1] < w[0]) {
                        return Err(tk.err("offsets must not decrease"));
                    }
                    while lines.len() + 1 < offs.len() {
                        lines.push(tk.line);
                    }
                    offsets = offs;
                } else {
                    let mut tok = Some(first);
                    let mut used = 0usize;
                    for i in 0..a {
                        let t = match tok.take() {
                            Some(t) => t,
                            None => tk.next(&format!("the size of cell {i}"))?,
                        };
                        let k: usize = super::text::parse_tok(
                            path,
                            tk.line,
                            t,
                            &format!("the size of cell {i}"),
                        )?;
                        lines.push(tk.line);
                        for _ in 0..k {
                            conn.push(tk.parse("a point id")?);
                        }
                        used += 1 + k;
                        offsets.push(conn.len());
                    }
                    if used != b {
                        return Err(tk.err(format!(
                            "`CELLS {a} {b}` announces {b} numbers but the cells hold {used}"
                        )));
                    }
                }
                cells = Some((conn, offsets, lines));
            }
            "CELL_TYPES" => {
                let n: usize = tk.parse("the number of cell types")?;
                let mut t = Vec::with_capacity(n.min(1 << 28));
                let mut l = Vec::with_capacity(n.min(1 << 28));
                for _ in 0..n {
                    t.push(tk.parse::<i64>("a cell type")?);
                    l.push(tk.line);
                }
                types = Some((t, l));
            }
            "METADATA" => tk.skip_to_blank_line(),
            "POINT_DATA" | "CELL_DATA" => break,
            _ => {
                return Err(tk.err(format!(
                    "expected `DATASET`, `POINTS`, `CELLS`, `CELL_TYPES`, `POINT_DATA` or \
                     `CELL_DATA`, found {}",
                    show(kw)
                )))
            }
        }
    }
    let missing = |what: &str| format_err_noline(path, format!("no `{what}` section"));
    let points = points.ok_or_else(|| missing("POINTS"))?;
    let (conn, offsets, cell_lines) = cells.ok_or_else(|| missing("CELLS"))?;
    let (types, type_lines) = types.ok_or_else(|| missing("CELL_TYPES"))?;
    Ok(Grid {
        points,
        conn,
        offsets,
        types,
        cell_lines: Some(cell_lines),
        type_lines: Some(type_lines),
        cells_name: LEGACY_CELLS,
        types_name: LEGACY_TYPES,
    })
}

/// Bytes of a legacy binary data type.
fn legacy_size(t: &str) -> Option<usize> {
    Some(match t.to_ascii_lowercase().as_str() {
        "bit" => return None,
        "char" | "unsigned_char" => 1,
        "short" | "unsigned_short" => 2,
        "int" | "unsigned_int" | "float" | "vtktypeint32" | "vtktypeuint32" => 4,
        "long" | "unsigned_long" | "double" | "vtktypeint64" | "vtktypeuint64" | "vtkidtype" => 8,
        _ => return None,
    })
}

/// The data types [`legacy_size`] knows, for messages.
const LEGACY_TYPES_VALID: &str = "char, unsigned_char, short, unsigned_short, int, \
     unsigned_int, long, unsigned_long, float, double, vtktypeint32, vtktypeuint32, \
     vtktypeint64, vtktypeuint64, vtkIdType";

/// The section keywords of a binary file, for messages.
const LEGACY_KEYWORDS: &str =
    "`DATASET`, `POINTS`, `CELLS`, `CELL_TYPES`, `FIELD`, `METADATA`, `POINT_DATA` or `CELL_DATA`";

/// A cursor over a legacy binary file: keyword lines in ASCII, data big-endian after them.
struct BinCursor<'a> {
    path: &'a Path,
    b: &'a [u8],
    pos: usize,
}

impl<'a> BinCursor<'a> {
    fn err(&self, msg: impl Into<String>) -> Error {
        format_err_noline(
            self.path,
            format!("binary legacy VTK, byte {}: {}", self.pos, msg.into()),
        )
    }

    /// The next non-blank line, split into tokens; `None` at the end of the file. A line
    /// that is not text (binary data where a keyword line belongs) is an error saying so.
    fn line(&mut self) -> Result<Option<Vec<String>>> {
        while self.pos < self.b.len() && self.b[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        if self.pos >= self.b.len() {
            return Ok(None);
        }
        let end = self.b[self.pos..]
            .iter()
            .position(|&c| c == b'\n')
            .map_or(self.b.len(), |e| self.pos + e);
        let text = std::str::from_utf8(&self.b[self.pos..end])
            .ok()
            .filter(|t| {
                !t.chars()
                    .any(|c| c.is_control() && !c.is_ascii_whitespace())
            })
            .ok_or_else(|| {
                self.err(format!(
                    "expected a keyword line ({LEGACY_KEYWORDS}), found binary data: a count \
                     in the line before the data is wrong, or the data are not big-endian as \
                     legacy VTK requires"
                ))
            })?;
        let toks = text.split_ascii_whitespace().map(str::to_string).collect();
        self.pos = (end + 1).min(self.b.len());
        Ok(Some(toks))
    }

    /// Whether the next non-blank line starts with `kw` (any case); the cursor stays.
    fn next_is(&self, kw: &str) -> bool {
        let start = self.b[self.pos..]
            .iter()
            .position(|c| !c.is_ascii_whitespace())
            .map_or(self.b.len(), |k| self.pos + k);
        self.b
            .get(start..start + kw.len())
            .is_some_and(|w| w.eq_ignore_ascii_case(kw.as_bytes()))
    }

    /// A raw line (for METADATA), `None` at the end of the file.
    fn raw_line(&mut self) -> Option<&'a [u8]> {
        if self.pos >= self.b.len() {
            return None;
        }
        let end = self.b[self.pos..]
            .iter()
            .position(|&c| c == b'\n')
            .map_or(self.b.len(), |e| self.pos + e);
        let l = &self.b[self.pos..end];
        self.pos = (end + 1).min(self.b.len());
        Some(l)
    }

    /// `n` values of type `t`, as `f64` (`float` / `double`) or integers.
    fn values(&mut self, what: &str, n: usize, t: &str) -> Result<Vec<f64>> {
        let size = legacy_size(t).ok_or_else(|| {
            self.err(format!(
                "{what}: unsupported data type {}; supported: {LEGACY_TYPES_VALID}",
                show(t)
            ))
        })?;
        let need = n
            .checked_mul(size)
            .filter(|&k| k <= self.b.len() - self.pos);
        let Some(need) = need else {
            return Err(self.err(format!(
                "{what}: {n} values of {t} need {} bytes but the file ends after {} (truncated?)",
                n as u128 * size as u128,
                self.b.len() - self.pos
            )));
        };
        let data = &self.b[self.pos..self.pos + need];
        self.pos += need;
        let t = t.to_ascii_lowercase();
        let unsigned = t.starts_with("unsigned") || t.starts_with("vtktypeuint");
        Ok(data
            .chunks_exact(size)
            .map(|c| match (size, t.as_str()) {
                (4, "float") => f32::from_be_bytes(c.try_into().unwrap()) as f64,
                (8, "double") => f64::from_be_bytes(c.try_into().unwrap()),
                (1, _) if unsigned => c[0] as f64,
                (1, _) => c[0] as i8 as f64,
                (2, _) if unsigned => u16::from_be_bytes(c.try_into().unwrap()) as f64,
                (2, _) => i16::from_be_bytes(c.try_into().unwrap()) as f64,
                (4, _) if unsigned => u32::from_be_bytes(c.try_into().unwrap()) as f64,
                (4, _) => i32::from_be_bytes(c.try_into().unwrap()) as f64,
                (_, _) if unsigned => u64::from_be_bytes(c.try_into().unwrap()) as f64,
                (_, _) => i64::from_be_bytes(c.try_into().unwrap()) as f64,
            })
            .collect())
    }

    /// `n` non-negative integers (exact below 2^53, which bounds any real mesh).
    fn ints(&mut self, what: &str, n: usize, t: &str) -> Result<Vec<u64>> {
        if matches!(t.to_ascii_lowercase().as_str(), "float" | "double") {
            return Err(self.err(format!(
                "{what}: expected an integer type, found {}",
                show(t)
            )));
        }
        let v = self.values(what, n, t)?;
        v.iter()
            .enumerate()
            .map(|(i, &x)| {
                if (0.0..9.007_199_254_740_992e15).contains(&x) {
                    Ok(x as u64)
                } else {
                    Err(self.err(format!("{what}: value {i} is {x}; expected 0 <= id < 2^53")))
                }
            })
            .collect()
    }
}

/// Parse a binary legacy unstructured grid (any version): `CELLS nOffsets nConn` followed by
/// `OFFSETS type` and `CONNECTIVITY type` arrays (5.x) or `CELLS nCells size` followed by the
/// count-prefixed `int` list (older versions), `CELL_TYPES` as `int`, `METADATA` blocks (to
/// the next blank line) and `FIELD` arrays skipped, all data big-endian.
fn parse_binary(path: &Path, bytes: &[u8]) -> Result<Grid> {
    let mut c = BinCursor {
        path,
        b: bytes,
        pos: 0,
    };
    for _ in 0..3 {
        c.raw_line();
    }
    let tok = |t: &[String], i: usize| t.get(i).cloned().unwrap_or_default();
    let mut have_dataset = false;
    let mut points: Option<Vec<f64>> = None;
    let mut cells: Option<(Vec<u64>, Vec<usize>)> = None;
    let mut types: Option<Vec<i64>> = None;
    while let Some(t) = c.line()? {
        let kw = t[0].to_ascii_uppercase();
        let count = |c: &BinCursor, i: usize, what: &str| -> Result<usize> {
            tok(&t, i).parse().map_err(|_| {
                c.err(format!(
                    "`{kw}`: expected {what}, found {}",
                    show(&tok(&t, i))
                ))
            })
        };
        match kw.as_str() {
            "DATASET" => {
                if !tok(&t, 1).eq_ignore_ascii_case("UNSTRUCTURED_GRID") {
                    return Err(c.err(format!(
                        "only `DATASET UNSTRUCTURED_GRID` is supported, found {}",
                        show(&tok(&t, 1))
                    )));
                }
                have_dataset = true;
            }
            "POINTS" => {
                if !have_dataset {
                    return Err(c.err("`POINTS` before `DATASET UNSTRUCTURED_GRID`"));
                }
                let n = count(&c, 1, "the number of points")?;
                let p = c.values("`POINTS`", n.saturating_mul(3), &tok(&t, 2))?;
                if let Some(i) = p.iter().position(|v| !v.is_finite()) {
                    return Err(c.err(format!(
                        "point {} has a non-finite coordinate {}",
                        i / 3,
                        p[i]
                    )));
                }
                points = Some(p);
            }
            "CELLS" => {
                let a = count(&c, 1, "the number of cells")?;
                let b = count(&c, 2, "the cell list size")?;
                if c.next_is("OFFSETS") {
                    let next = c.line()?.unwrap_or_default();
                    let offs = c.ints("`OFFSETS`", a, &tok(&next, 1))?;
                    let kw2 = c.line()?.unwrap_or_default();
                    if !kw2
                        .first()
                        .is_some_and(|k| k.eq_ignore_ascii_case("CONNECTIVITY"))
                    {
                        return Err(c.err(format!(
                            "expected `CONNECTIVITY` after the offsets, found {}",
                            show(&kw2.join(" "))
                        )));
                    }
                    if offs.first() != Some(&0) || offs.last() != Some(&(b as u64)) {
                        return Err(c.err(format!(
                            "`OFFSETS` must start at 0 and end at {b} (the connectivity size)"
                        )));
                    }
                    if let Some(i) = offs.windows(2).position(|w| w[1] < w[0]) {
                        return Err(c.err(format!("`OFFSETS` decrease at cell {i}")));
                    }
                    let conn = c.ints("`CONNECTIVITY`", b, &tok(&kw2, 1))?;
                    cells = Some((conn, offs.iter().map(|&o| o as usize).collect()));
                } else {
                    let list = c.ints("`CELLS`", b, "int")?;
                    cells = Some(count_prefixed(&c, a, b, &list)?);
                }
            }
            "CELL_TYPES" => {
                let n = count(&c, 1, "the number of cell types")?;
                types = Some(
                    c.ints("`CELL_TYPES`", n, "int")?
                        .into_iter()
                        .map(|v| v as i64)
                        .collect(),
                );
            }
            "METADATA" => {
                while let Some(l) = c.raw_line() {
                    if l.iter().all(|b| b.is_ascii_whitespace()) {
                        break;
                    }
                }
            }
            "FIELD" => {
                let n = count(&c, 2, "the number of field arrays")?;
                for _ in 0..n {
                    let a = c.line()?.unwrap_or_default();
                    let nc: usize = tok(&a, 1).parse().unwrap_or(usize::MAX);
                    let nt: usize = tok(&a, 2).parse().unwrap_or(usize::MAX);
                    c.values(
                        &format!("field array {}", show(&tok(&a, 0))),
                        nc.saturating_mul(nt),
                        &tok(&a, 3),
                    )?;
                }
            }
            "POINT_DATA" | "CELL_DATA" => break,
            _ => {
                return Err(c.err(format!(
                    "expected `DATASET`, `POINTS`, `CELLS`, `CELL_TYPES`, `POINT_DATA` or \
                     `CELL_DATA`, found {}",
                    show(&t[0])
                )))
            }
        }
    }
    let missing = |what: &str| format_err_noline(path, format!("no `{what}` section"));
    let points = points.ok_or_else(|| missing("POINTS"))?;
    let (conn, offsets) = cells.ok_or_else(|| missing("CELLS"))?;
    let types = types.ok_or_else(|| missing("CELL_TYPES"))?;
    Ok(Grid {
        points,
        conn,
        offsets,
        types,
        cell_lines: None,
        type_lines: None,
        cells_name: LEGACY_CELLS,
        types_name: LEGACY_TYPES,
    })
}

/// The connectivity and offsets of the count-prefixed cell list `list` of `CELLS a b` (each
/// cell its point count, then its point ids), which must hold exactly `b` numbers.
fn count_prefixed(
    c: &BinCursor,
    a: usize,
    b: usize,
    list: &[u64],
) -> Result<(Vec<u64>, Vec<usize>)> {
    let at = format!("`CELLS {a} {b}`");
    let mut conn = Vec::with_capacity(b.saturating_sub(a));
    let mut offsets = Vec::with_capacity(a.min(b) + 1);
    offsets.push(0usize);
    let mut i = 0usize;
    for cell in 0..a {
        let Some(&k) = list.get(i) else {
            return Err(c.err(format!(
                "{at}: the list of {b} numbers ends before cell {cell} (the cell count or the \
                 list size is wrong)"
            )));
        };
        let ids = usize::try_from(k)
            .ok()
            .and_then(|k| list.get(i + 1..i.checked_add(1 + k)?))
            .ok_or_else(|| {
                c.err(format!(
                    "{at}: cell {cell} announces {k} points, more than the {} numbers left in \
                     the list (a wrong size, or little-endian data: legacy VTK is big-endian)",
                    b - i - 1
                ))
            })?;
        conn.extend_from_slice(ids);
        offsets.push(conn.len());
        i += 1 + ids.len();
    }
    if i != b {
        return Err(c.err(format!(
            "{at}: the {a} cells hold {i} numbers (counts included), not {b}"
        )));
    }
    Ok((conn, offsets))
}

/// Checks and conversion of a parsed grid.
pub(crate) fn build(path: &Path, g: Grid) -> Result<RawMesh> {
    let at = |lines: &Option<Vec<usize>>, i: usize, msg: String| -> Error {
        match lines.as_ref().and_then(|l| l.get(i)) {
            Some(&l) => format_err(path, l, msg),
            None => format_err_noline(path, msg),
        }
    };
    let ncells = g.offsets.len() - 1;
    if g.types.len() != ncells {
        return Err(at(
            &g.type_lines,
            0,
            format!(
                "{} has {} entries but {} has {ncells} cells",
                g.types_name,
                g.types.len(),
                g.cells_name
            ),
        ));
    }
    let np = g.points.len() / 3;
    let mut raw = RawMesh::default();
    for (i, p) in g.points.chunks_exact(3).enumerate() {
        raw.push_node(i as u64, [p[0], p[1], p[2]]);
    }
    let mut max_dim = 0u8;
    let mut unsupported: [Option<Error>; 4] = Default::default();
    for c in 0..ncells {
        let ids = &g.conn[g.offsets[c]..g.offsets[c + 1]];
        let t = g.types[c];
        if let Some(&bad) = ids.iter().find(|&&v| v as usize >= np) {
            return Err(at(
                &g.cell_lines,
                c,
                format!("cell {c} refers to point {bad}, but there are {np} points (0-based)"),
            ));
        }
        let (dim, name) = vtk_cell(t);
        let Some(dim) = dim else {
            return Err(at(
                &g.type_lines,
                c,
                format!("unknown cell type {t} (cell {c})"),
            ));
        };
        max_dim = max_dim.max(dim);
        let need = match t {
            5 => Some(3),
            22 => Some(6),
            10 => Some(4),
            24 => Some(10),
            _ => None,
        };
        match need {
            Some(k) if ids.len() != k => {
                return Err(at(
                    &g.cell_lines,
                    c,
                    format!(
                        "expected {k} point ids for cell type {t} ({name}), found {}",
                        ids.len()
                    ),
                ))
            }
            Some(_) if dim == 3 => {
                raw.tets.extend(ids[..4].iter().map(|&v| v as u32));
                raw.tet_ids.push(c as u64);
            }
            Some(_) => {
                raw.tris.extend(ids[..3].iter().map(|&v| v as u32));
                raw.tri_ids.push(c as u64);
            }
            None => {
                let slot = &mut unsupported[dim as usize];
                if slot.is_none() {
                    *slot = Some(at(
                        &g.type_lines,
                        c,
                        format!(
                            "cell {c} has type {t} ({name}), which raisov cannot simulate; \
                             supported: 5 (triangle), 10 (tetrahedron), 22 and 24 (read as \
                             their corners)"
                        ),
                    ));
                }
            }
        }
    }
    if max_dim >= 2 {
        if let Some(e) = unsupported[max_dim as usize].take() {
            return Err(e);
        }
    }
    Ok(raw)
}

#[cfg(test)]
mod tests {
    use crate::io::load_mesh;
    use crate::mesh::ElementKind;
    use crate::Error;

    const TET: &str = "# vtk DataFile Version 3.0
two tets
ASCII
DATASET UNSTRUCTURED_GRID
FIELD FieldData 1
TIME 1 1 double
0.5
POINTS 6 double
0 0 0  1 0 0  0 1 0
0 0 1
1 1 1
7 7 7
CELLS 4 16
4 0 1 2 3
4 1 2 4 3
3 0 1 2
1 5
CELL_TYPES 4
10
10
5
1
POINT_DATA 6
SCALARS s double 1
LOOKUP_TABLE default
0 0 0 0 0 0
";

    #[test]
    fn ascii_tets_lower_dim_ignored() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.vtk");
        std::fs::write(&p, TET).unwrap();
        let l = load_mesh(&p).unwrap();
        assert_eq!(l.format, "vtk legacy ascii");
        assert_eq!(l.mesh.kind, ElementKind::Tet4);
        assert_eq!(l.mesh.num_elements(), 2);
        assert_eq!(l.unused_nodes_dropped, 1);
        assert_eq!(l.reoriented, vec![1]);
        assert!(l.mesh.groups.is_empty());
    }

    #[test]
    fn ascii_v51_triangles() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.vtk");
        std::fs::write(
            &p,
            "# vtk DataFile Version 5.1\ntri\nASCII\nDATASET UNSTRUCTURED_GRID\n\
             POINTS 4 float\n0 0 0 1 0 0 1 1 0 0 1 0\n\
             CELLS 3 6\nOFFSETS vtktypeint64\n0 3 6\nCONNECTIVITY vtktypeint64\n0 1 2\n0 2 3\n\
             CELL_TYPES 2\n5 5\n",
        )
        .unwrap();
        let l = load_mesh(&p).unwrap();
        assert_eq!(l.mesh.kind, ElementKind::Tri3);
        assert_eq!(l.mesh.cells, vec![0, 1, 2, 0, 2, 3]);
        assert!((l.mesh.total_measure() - 1.0).abs() < 1e-15);
    }

    #[test]
    fn ascii_errors_name_line() {
        let dir = tempfile::tempdir().unwrap();
        let cases: &[(&str, &str, usize, &str)] = &[
            ("4 1 2 4 3\n", "4 1 2 9 3\n", 15, "refers to point 9"),
            (
                "CELLS 4 16\n4 0 1 2 3\n4 1 2 4 3\n",
                "CELLS 4 15\n4 0 1 2 3\n3 1 2 4\n",
                15,
                "expected 4 point ids for cell type 10",
            ),
            (
                "0 0 1\n",
                "0 zero 1\n",
                10,
                "expected y of point 3, found `zero`",
            ),
            (
                "CELL_TYPES 4\n10\n10\n",
                "CELL_TYPES 4\n10\n12\n",
                20,
                "hexahedron",
            ),
            (
                "CELL_TYPES 4\n10\n10\n",
                "CELL_TYPES 4\n10\n99\n",
                20,
                "unknown cell type 99",
            ),
            ("ASCII\n", "TEXT\n", 3, "expected `ASCII` or `BINARY`"),
            ("UNSTRUCTURED_GRID", "POLYDATA", 4, "UNSTRUCTURED_GRID"),
        ];
        for (i, (from, to, line, msg)) in cases.iter().enumerate() {
            let p = dir.path().join(format!("e{i}.vtk"));
            std::fs::write(&p, TET.replacen(from, to, 1)).unwrap();
            let e = load_mesh(&p).unwrap_err();
            let s = e.to_string();
            match e {
                Error::MeshFormat { line: l, .. } => assert_eq!(l, Some(*line), "{s}"),
                _ => panic!("{s}"),
            }
            assert!(s.contains(msg), "{s}");
        }
        // Truncated.
        let p = dir.path().join("cut.vtk");
        std::fs::write(&p, &TET[..TET.find("3 0 1 2").unwrap()]).unwrap();
        let e = load_mesh(&p).unwrap_err().to_string();
        assert!(e.contains("unexpected end of file"), "{e}");
    }

    /// A binary legacy file of one tetrahedron: `head` after the three header lines, the
    /// `POINTS` line and 4 points, the `CELLS` line and `cells` as `int`s (big-endian unless
    /// `le`), the `CELL_TYPES` line and one type 10.
    fn binary_tet(points: &str, cells: &str, ints: &[i32], le: bool, types: &str) -> Vec<u8> {
        let mut b: Vec<u8> = Vec::new();
        b.extend_from_slice(
            b"# vtk DataFile Version 3.0\nbin\nBINARY\nDATASET UNSTRUCTURED_GRID\n",
        );
        b.extend_from_slice(format!("{points}\n").as_bytes());
        for v in [0.0f64, 0., 0., 1., 0., 0., 0., 0., 1., 0., 1., 0.] {
            b.extend_from_slice(&v.to_be_bytes());
        }
        b.extend_from_slice(format!("\n{cells}\n").as_bytes());
        for v in ints {
            b.extend_from_slice(&if le { v.to_le_bytes() } else { v.to_be_bytes() });
        }
        b.extend_from_slice(format!("\n{types}\n").as_bytes());
        b.extend_from_slice(&10i32.to_be_bytes());
        b.extend_from_slice(b"\n");
        b
    }

    /// Broken binary legacy files (before VTK 5: read by `vtkio`, which said `Parse error:
    /// Alt`) are errors that name the file, say that it is binary legacy VTK, where, and
    /// what is wrong in words.
    #[test]
    fn binary_legacy_errors_say_what_is_wrong() {
        let dir = tempfile::tempdir().unwrap();
        let tet = [4, 0, 1, 2, 3];
        let good = binary_tet("POINTS 4 double", "CELLS 1 5", &tet, false, "CELL_TYPES 1");
        let cut_at = |b: &[u8], from: &str| {
            let at = b
                .windows(from.len())
                .position(|w| w == from.as_bytes())
                .unwrap();
            b[..at + from.len() + 12].to_vec()
        };
        let cases: Vec<(&str, Vec<u8>, &str)> = vec![
            (
                "cut_points.vtk",
                cut_at(&good, "POINTS 4 double\n"),
                "`POINTS`: 12 values of double need 96 bytes but the file ends after 12 (truncated?)",
            ),
            (
                "few_points.vtk",
                binary_tet("POINTS 3 double", "CELLS 1 5", &tet, false, "CELL_TYPES 1"),
                "expected a keyword line (`DATASET`, `POINTS`",
            ),
            (
                "list_size.vtk",
                binary_tet("POINTS 4 double", "CELLS 1 4", &tet, false, "CELL_TYPES 1"),
                "`CELLS 1 4`: cell 0 announces 4 points, more than the 3 numbers left",
            ),
            (
                "cell_count.vtk",
                binary_tet("POINTS 4 double", "CELLS 2 5", &tet, false, "CELL_TYPES 1"),
                "`CELLS 2 5`: the list of 5 numbers ends before cell 1",
            ),
            (
                "little_endian.vtk",
                binary_tet("POINTS 4 double", "CELLS 1 5", &tet, true, "CELL_TYPES 1"),
                "little-endian data: legacy VTK is big-endian",
            ),
            (
                "types.vtk",
                binary_tet("POINTS 4 double", "CELLS 1 5", &tet, false, "CELL_TYPES 2"),
                "`CELL_TYPES`: 2 values of int need 8 bytes but the file ends after 5",
            ),
            (
                "bit.vtk",
                binary_tet("POINTS 4 bit", "CELLS 1 5", &tet, false, "CELL_TYPES 1"),
                "unsupported data type `bit`; supported: char, unsigned_char",
            ),
            (
                "cut_cells.vtk",
                cut_at(&good, "CELLS 1 5\n"),
                "`CELLS`: 5 values of int need 20 bytes but the file ends after 12",
            ),
        ];
        for (name, bytes, want) in cases {
            let p = dir.path().join(name);
            std::fs::write(&p, &bytes).unwrap();
            let e = load_mesh(&p).expect_err(name).to_string();
            assert!(e.contains(name), "{e}");
            assert!(e.contains("binary legacy VTK, byte "), "{e}");
            assert!(e.contains(want), "{name}: {e}");
            assert!(!e.contains("Parse error"), "{e}");
        }
        let p = dir.path().join("good.vtk");
        std::fs::write(&p, &good).unwrap();
        assert_eq!(load_mesh(&p).unwrap().mesh.num_elements(), 1);
    }

    #[test]
    fn binary_legacy() {
        let mut b: Vec<u8> = Vec::new();
        b.extend_from_slice(
            b"# vtk DataFile Version 3.0\nbin\nBINARY\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 double\n",
        );
        for v in [0.0f64, 0., 0., 1., 0., 0., 0., 0., 1., 0., 1., 0.] {
            b.extend_from_slice(&v.to_be_bytes());
        }
        b.extend_from_slice(b"\nCELLS 1 5\n");
        for v in [4i32, 0, 1, 2, 3] {
            b.extend_from_slice(&v.to_be_bytes());
        }
        b.extend_from_slice(b"\nCELL_TYPES 1\n");
        b.extend_from_slice(&10i32.to_be_bytes());
        b.extend_from_slice(b"\n");
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("b.vtk");
        std::fs::write(&p, &b).unwrap();
        let l = load_mesh(&p).unwrap();
        assert_eq!(l.format, "vtk legacy binary");
        assert_eq!(l.mesh.num_elements(), 1);
        assert_eq!(l.reoriented, vec![0]);
        assert!((l.mesh.total_measure() - 1.0 / 6.0).abs() < 1e-15);
    }
}
