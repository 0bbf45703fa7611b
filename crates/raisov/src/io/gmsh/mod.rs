//! Gmsh MSH files.
//!
//! Reading ([`read_msh`]): the version and encoding are taken from `$MeshFormat`.
//!
//! * MSH 2.x (2.0, 2.1, 2.2), ASCII and binary: hand-written reader. Sections `$MeshFormat`,
//!   `$PhysicalNames`, `$Nodes`, `$Elements`; every other section is skipped. An element's
//!   first tag is its physical group (0 or no tags: none).
//! * MSH 4.1, ASCII and binary: parsed by `mshio`; an element's physical groups are those of
//!   its geometric entity in `$Entities`, named through `$PhysicalNames` (read here, as mshio
//!   ignores it).
//!
//! Physical groups become [`Mesh::groups`] under their name, or `"physical N"` when unnamed.
//! Supported mesh elements: triangles (type 2) and tetrahedra (type 4); 6-node triangles
//! (9) and 10-node tetrahedra (11) are read as their corner nodes. Elements of lower
//! dimension than the mesh (boundary triangles, lines, points) and of unsupported types
//! below the mesh dimension only contribute to groups.
//!
//! Writing ([`write_msh22`]): MSH 2.2 ASCII. The mesh elements carry physical tag 1
//! (`"domain"`); every group is written as 1-node point elements (type 15) of its own
//! physical tag and name, so that a write/read round trip keeps the groups.
//!
//! One concern, the Gmsh format (both versions, both encodings, the writer), in one file
//! because reading and writing share the element-type table and the group rules; about a
//! third of it is tests.

use std::collections::{BTreeMap, HashMap};
use std::io::Write;
use std::path::Path;

use super::text::{format_err, format_err_noline, parse_f64, parse_tok, show, LineReader};
use super::{finish, read_bytes, write_atomic, LoadedMesh, NodeIndex, RawMesh};
use crate::mesh::{ElementKind, Mesh};
use crate::{Error, Result};

/// What raisov knows about a Gmsh element type.
#[derive(Clone, Copy, Debug)]
struct GmshType {
    nodes: usize,
    dim: u8,
    name: &'static str,
    /// The linear kind it is read as (corner nodes first), if supported as a mesh element.
    kind: Option<ElementKind>,
}

fn gmsh_type(code: i64) -> Option<GmshType> {
    use ElementKind::*;
    let t = |nodes, dim, name, kind| {
        Some(GmshType {
            nodes,
            dim,
            name,
            kind,
        })
    };
    match code {
        1 => t(2, 1, "2-node line", None),
        2 => t(3, 2, "3-node triangle", Some(Tri3)),
        3 => t(4, 2, "4-node quadrangle", None),
        4 => t(4, 3, "4-node tetrahedron", Some(Tet4)),
        5 => t(8, 3, "8-node hexahedron", None),
        6 => t(6, 3, "6-node prism", None),
        7 => t(5, 3, "5-node pyramid", None),
        8 => t(3, 1, "3-node line", None),
        9 => t(6, 2, "6-node triangle", Some(Tri3)),
        10 => t(9, 2, "9-node quadrangle", None),
        11 => t(10, 3, "10-node tetrahedron", Some(Tet4)),
        12 => t(27, 3, "27-node hexahedron", None),
        13 => t(18, 3, "18-node prism", None),
        14 => t(14, 3, "14-node pyramid", None),
        15 => t(1, 0, "1-node point", None),
        16 => t(8, 2, "8-node quadrangle", None),
        17 => t(20, 3, "20-node hexahedron", None),
        18 => t(15, 3, "15-node prism", None),
        19 => t(13, 3, "13-node pyramid", None),
        20 => t(9, 2, "9-node triangle", None),
        21 => t(10, 2, "10-node triangle", None),
        22 => t(12, 2, "12-node triangle", None),
        23 => t(15, 2, "15-node triangle", None),
        24 => t(15, 2, "15-node triangle", None),
        25 => t(21, 2, "21-node triangle", None),
        26 => t(4, 1, "4-node line", None),
        27 => t(5, 1, "5-node line", None),
        28 => t(6, 1, "6-node line", None),
        29 => t(20, 3, "20-node tetrahedron", None),
        30 => t(35, 3, "35-node tetrahedron", None),
        31 => t(56, 3, "56-node tetrahedron", None),
        _ => None,
    }
}

/// Collects elements of any dimension, keeps the mesh elements and the physical groups.
#[derive(Default)]
struct Collector {
    raw: RawMesh,
    max_dim: u8,
    /// First unsupported element per dimension: (line, message).
    unsupported: [Option<(Option<usize>, String)>; 4],
    /// Node indices per (dimension, physical tag).
    physical: BTreeMap<(i32, i32), Vec<u32>>,
}

impl Collector {
    /// Add one element (node indices already resolved).
    fn add(
        &mut self,
        code: i64,
        dim: u8,
        id: u64,
        nodes: &[u32],
        physical: &[i32],
        line: Option<usize>,
    ) {
        let ty = gmsh_type(code);
        self.max_dim = self.max_dim.max(dim);
        match ty.and_then(|t| t.kind) {
            Some(ElementKind::Tet4) => {
                self.raw.tets.extend_from_slice(&nodes[..4]);
                self.raw.tet_ids.push(id);
            }
            Some(ElementKind::Tri3) => {
                self.raw.tris.extend_from_slice(&nodes[..3]);
                self.raw.tri_ids.push(id);
            }
            None => {
                let slot = &mut self.unsupported[dim.min(3) as usize];
                if slot.is_none() {
                    let name = ty.map(|t| t.name).unwrap_or("unknown");
                    *slot = Some((
                        line,
                        format!(
                            "element {id} has type {code} ({name}), which raisov cannot \
                             simulate; supported: 2 (triangle), 4 (tetrahedron), 9 and 11 \
                             (read as their corners)"
                        ),
                    ));
                }
            }
        }
        for &p in physical.iter().filter(|&&p| p != 0) {
            self.physical
                .entry((dim as i32, p))
                .or_default()
                .extend_from_slice(nodes);
        }
    }

    fn into_raw(mut self, path: &Path, names: &HashMap<(i32, i32), String>) -> Result<RawMesh> {
        if self.max_dim >= 2 {
            if let Some((line, msg)) = self.unsupported[self.max_dim as usize].take() {
                return Err(Error::MeshFormat {
                    path: path.to_path_buf(),
                    line,
                    msg,
                });
            }
        }
        for ((dim, tag), nodes) in self.physical {
            let name = names
                .get(&(dim, tag))
                .cloned()
                .unwrap_or_else(|| format!("physical {tag}"));
            self.raw.groups.entry(name).or_default().extend(nodes);
        }
        Ok(self.raw)
    }
}

/// The `$MeshFormat` header: version string, file type (0 ASCII, 1 binary).
fn header(path: &Path, bytes: &[u8]) -> Result<(String, i32)> {
    let head = String::from_utf8_lossy(&bytes[..bytes.len().min(512)]);
    let mut lr = LineReader::new(path, &head, None);
    let (l1, first) = lr.next("`$MeshFormat`")?;
    if first != "$MeshFormat" {
        return Err(format_err(
            path,
            l1,
            format!("expected `$MeshFormat`, found {}", show(first)),
        ));
    }
    let (l2, fmt) = lr.next("`version file-type data-size`")?;
    let mut it = fmt.split_whitespace();
    let version = it.next().unwrap_or("").to_string();
    let ft = it.next().ok_or_else(|| {
        format_err(
            path,
            l2,
            "expected `version file-type data-size` after `$MeshFormat`",
        )
    })?;
    let file_type: i32 = parse_tok(path, l2, ft, "file type 0 (ASCII) or 1 (binary)")?;
    if file_type != 0 && file_type != 1 {
        return Err(format_err(
            path,
            l2,
            format!("expected file type 0 (ASCII) or 1 (binary), found {file_type}"),
        ));
    }
    if let Some(ds) = it.next() {
        if ds != "8" {
            return Err(format_err(
                path,
                l2,
                format!("data size {} is not supported, only 8 (double)", show(ds)),
            ));
        }
    }
    Ok((version, file_type))
}

/// Read a Gmsh `.msh` file (2.x or 4.1, ASCII or binary). See the module docs.
pub fn read_msh(path: &Path) -> Result<LoadedMesh> {
    let bytes = read_bytes(path)?;
    let (version, file_type) = header(path, &bytes)?;
    let binary = file_type == 1;
    if version.starts_with("2.") || version == "2" {
        if binary {
            let raw = read_msh2_binary(path, &bytes)?;
            finish(raw, path, "gmsh 2.2 binary")
        } else {
            let text = String::from_utf8_lossy(&bytes);
            let raw = read_msh2_ascii(path, &text)?;
            finish(raw, path, "gmsh 2.2 ascii")
        }
    } else if version == "4.1" {
        let raw = read_msh41(path, &bytes, binary)?;
        finish(
            raw,
            path,
            if binary {
                "gmsh 4.1 binary"
            } else {
                "gmsh 4.1 ascii"
            },
        )
    } else {
        Err(format_err(
            path,
            2,
            format!(
                "MSH version {} is not supported; use 2.2 or 4.1 (e.g. `gmsh -format msh22`)",
                show(&version)
            ),
        ))
    }
}

/// Parse the body of `$PhysicalNames` (after its header line) up to `$EndPhysicalNames`.
fn parse_physical_names(lr: &mut LineReader) -> Result<HashMap<(i32, i32), String>> {
    let path = lr.path;
    let (l, c) = lr.next("the number of physical names")?;
    let n: usize = parse_tok(path, l, c, "the number of physical names")?;
    let mut names = HashMap::new();
    for i in 0..n {
        let what = format!("physical name {} of {n} (`dim tag \"name\"`)", i + 1);
        let (l, s) = lr.next(&what)?;
        if s.starts_with('$') {
            return Err(format_err(
                path,
                l,
                format!("expected {what}, found {}", show(s)),
            ));
        }
        let mut it = s.splitn(3, char::is_whitespace);
        let dim: i32 = parse_tok(path, l, it.next().unwrap_or(""), "a dimension")?;
        let tag: i32 = parse_tok(path, l, it.next().unwrap_or("").trim(), "a physical tag")?;
        let rest = it.next().unwrap_or("").trim();
        let name = match (rest.find('"'), rest.rfind('"')) {
            (Some(a), Some(b)) if b > a => &rest[a + 1..b],
            _ => {
                return Err(format_err(
                    path,
                    l,
                    format!("expected a quoted name, found {}", show(rest)),
                ))
            }
        };
        names.insert((dim, tag), name.to_string());
    }
    let (l, e) = lr.next("`$EndPhysicalNames`")?;
    if e != "$EndPhysicalNames" {
        return Err(format_err(
            path,
            l,
            format!(
                "expected `$EndPhysicalNames` after {n} names, found {}",
                show(e)
            ),
        ));
    }
    Ok(names)
}

fn expect_end(lr: &mut LineReader, end: &str, after: &str) -> Result<()> {
    let (l, s) = lr.next(&format!("`{end}`"))?;
    if s != end {
        return Err(format_err(
            lr.path,
            l,
            format!("expected `{end}` after {after}, found {}", show(s)),
        ));
    }
    Ok(())
}

/// MSH 2.x ASCII.
fn read_msh2_ascii(path: &Path, text: &str) -> Result<RawMesh> {
    let mut lr = LineReader::new(path, text, None);
    let mut col = Collector::default();
    let mut index = NodeIndex::default();
    let mut names = HashMap::new();
    let mut have_nodes = false;
    while let Some((l, s)) = lr.next_opt() {
        match s {
            "$MeshFormat" => {
                lr.next("the format line")?;
                expect_end(&mut lr, "$EndMeshFormat", "the format line")?;
            }
            "$PhysicalNames" => names = parse_physical_names(&mut lr)?,
            "$Nodes" => {
                let (l, c) = lr.next("the number of nodes")?;
                let n: usize = parse_tok(path, l, c, "the number of nodes")?;
                for i in 0..n {
                    let what = format!("node {} of {n} (`id x y z`)", i + 1);
                    let (l, s) = lr.next(&what)?;
                    let t: Vec<&str> = s.split_whitespace().collect();
                    if t.len() != 4 {
                        return Err(format_err(
                            path,
                            l,
                            format!("expected {what}, found {} values", t.len()),
                        ));
                    }
                    let id: u64 = parse_tok(path, l, t[0], "a node id")?;
                    let p = [
                        parse_f64(path, l, t[1], "x")?,
                        parse_f64(path, l, t[2], "y")?,
                        parse_f64(path, l, t[3], "z")?,
                    ];
                    let k = col.raw.push_node(id, p);
                    if !index.insert(id, k) {
                        return Err(format_err(path, l, format!("duplicate node id {id}")));
                    }
                }
                expect_end(&mut lr, "$EndNodes", &format!("{n} nodes"))?;
                have_nodes = true;
            }
            "$Elements" => {
                if !have_nodes {
                    return Err(format_err(path, l, "`$Elements` before `$Nodes`"));
                }
                let (l, c) = lr.next("the number of elements")?;
                let n: usize = parse_tok(path, l, c, "the number of elements")?;
                let mut nodes = Vec::new();
                for i in 0..n {
                    let what = format!(
                        "element {} of {n} (`id type ntags tags... nodes...`)",
                        i + 1
                    );
                    let (l, s) = lr.next(&what)?;
                    let t: Vec<&str> = s.split_whitespace().collect();
                    if t.len() < 3 || t[0].starts_with('$') {
                        return Err(format_err(
                            path,
                            l,
                            format!("expected {what}, found {}", show(s)),
                        ));
                    }
                    let id: u64 = parse_tok(path, l, t[0], "an element id")?;
                    let code: i64 = parse_tok(path, l, t[1], "an element type")?;
                    let ntags: usize = parse_tok(path, l, t[2], "the number of tags")?;
                    let Some(ty) = gmsh_type(code) else {
                        return Err(format_err(
                            path,
                            l,
                            format!("unknown element type {code} (element {id})"),
                        ));
                    };
                    let found = t.len().saturating_sub(3 + ntags);
                    if t.len() < 3 + ntags || found != ty.nodes {
                        return Err(format_err(
                            path,
                            l,
                            format!(
                                "expected {} node ids for element type {code} after {ntags} \
                                 tags, found {found}",
                                ty.nodes
                            ),
                        ));
                    }
                    let physical: i32 = if ntags > 0 {
                        parse_tok(path, l, t[3], "a physical tag")?
                    } else {
                        0
                    };
                    for tag in &t[4.min(3 + ntags)..3 + ntags] {
                        parse_tok::<i64>(path, l, tag, "an integer tag")?;
                    }
                    nodes.clear();
                    for tok in &t[3 + ntags..] {
                        let nid: u64 = parse_tok(path, l, tok, "a node id")?;
                        let k = index.get(nid).ok_or_else(|| {
                            format_err(
                                path,
                                l,
                                format!(
                                    "element {id} refers to node {nid}, which is not in $Nodes"
                                ),
                            )
                        })?;
                        nodes.push(k);
                    }
                    col.add(code, ty.dim, id, &nodes, &[physical], Some(l));
                }
                expect_end(&mut lr, "$EndElements", &format!("{n} elements"))?;
            }
            "$NOD" | "$ELM" => {
                return Err(format_err(
                    path,
                    l,
                    "MSH version 1 is not supported; use 2.2 or 4.1",
                ))
            }
            other if other.starts_with('$') && !other.contains(char::is_whitespace) => {
                let end = format!("$End{}", &other[1..]);
                loop {
                    let (_, s) = lr.next(&format!("`{end}`"))?;
                    if s == end {
                        break;
                    }
                }
            }
            other => {
                return Err(format_err(
                    path,
                    l,
                    format!(
                        "expected a section header like `$Nodes`, found {}",
                        show(other)
                    ),
                ))
            }
        }
    }
    col.into_raw(path, &names)
}

/// A cursor over the bytes of a binary MSH 2.2 file.
struct Bin<'a> {
    path: &'a Path,
    b: &'a [u8],
    pos: usize,
    little: bool,
}

impl<'a> Bin<'a> {
    fn err(&self, msg: impl std::fmt::Display) -> Error {
        format_err_noline(self.path, format!("byte {}: {msg}", self.pos))
    }
    /// Next text line (without the newline), skipping blank lines.
    fn line(&mut self, what: &str) -> Result<&'a str> {
        loop {
            if self.pos >= self.b.len() {
                return Err(self.err(format!("unexpected end of file, expected {what}")));
            }
            let rest = &self.b[self.pos..];
            let end = rest.iter().position(|&c| c == b'\n').unwrap_or(rest.len());
            self.pos += (end + 1).min(rest.len());
            let s = std::str::from_utf8(&rest[..end])
                .map_err(|_| self.err(format!("expected {what}, found binary data")))?
                .trim();
            if !s.is_empty() {
                return Ok(s);
            }
        }
    }
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8]> {
        if self.b.len() - self.pos < n {
            return Err(self.err(format!("unexpected end of file, expected {what}")));
        }
        let s = &self.b[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }
    fn i32(&mut self, what: &str) -> Result<i32> {
        let s: [u8; 4] = self.take(4, what)?.try_into().unwrap_or([0; 4]);
        Ok(if self.little {
            i32::from_le_bytes(s)
        } else {
            i32::from_be_bytes(s)
        })
    }
    fn f64(&mut self, what: &str) -> Result<f64> {
        let s: [u8; 8] = self.take(8, what)?.try_into().unwrap_or([0; 8]);
        let v = if self.little {
            f64::from_le_bytes(s)
        } else {
            f64::from_be_bytes(s)
        };
        if !v.is_finite() {
            return Err(self.err(format!("{what} is not finite ({v})")));
        }
        Ok(v)
    }
    fn expect_line(&mut self, want: &str) -> Result<()> {
        let at = self.pos;
        let s = self.line(&format!("`{want}`"))?;
        if s != want {
            self.pos = at;
            return Err(self.err(format!("expected `{want}`, found {}", show(s))));
        }
        Ok(())
    }
}

/// MSH 2.2 binary: text section headers and counts, binary node and element records.
fn read_msh2_binary(path: &Path, bytes: &[u8]) -> Result<RawMesh> {
    let mut b = Bin {
        path,
        b: bytes,
        pos: 0,
        little: true,
    };
    b.expect_line("$MeshFormat")?;
    b.line("the format line")?;
    let one = b.take(4, "the binary integer 1")?;
    b.little = match one {
        [1, 0, 0, 0] => true,
        [0, 0, 0, 1] => false,
        _ => return Err(b.err("expected the binary integer 1 after the format line")),
    };
    b.expect_line("$EndMeshFormat")?;
    let mut col = Collector::default();
    let mut index = NodeIndex::default();
    let mut names = HashMap::new();
    let mut have_nodes = false;
    loop {
        // Skip whitespace to the next section, or stop at the end.
        while b.pos < bytes.len() && bytes[b.pos].is_ascii_whitespace() {
            b.pos += 1;
        }
        if b.pos >= bytes.len() {
            break;
        }
        let s = b.line("a section header")?;
        match s {
            "$PhysicalNames" => {
                let start = b.pos;
                let end_tag = b"$EndPhysicalNames";
                let end = find(&bytes[start..], end_tag)
                    .map(|e| start + e + end_tag.len())
                    .ok_or_else(|| b.err("`$EndPhysicalNames` missing"))?;
                let first_line = 1 + bytes[..start].iter().filter(|&&c| c == b'\n').count();
                let text = String::from_utf8_lossy(&bytes[start..end]);
                let mut lr = LineReader::new(path, &text, None).with_first_line(first_line);
                names = parse_physical_names(&mut lr)?;
                b.pos = end;
            }
            "$Nodes" => {
                let c = b.line("the number of nodes")?;
                let n: usize = c.parse().map_err(|_| {
                    b.err(format!("expected the number of nodes, found {}", show(c)))
                })?;
                for _ in 0..n {
                    let id = b.i32("a node id")?;
                    let p = [b.f64("x")?, b.f64("y")?, b.f64("z")?];
                    let k = col.raw.push_node(id as u64, p);
                    if id < 0 || !index.insert(id as u64, k) {
                        return Err(b.err(format!("bad or duplicate node id {id}")));
                    }
                }
                b.expect_line("$EndNodes")?;
                have_nodes = true;
            }
            "$Elements" => {
                if !have_nodes {
                    return Err(b.err("`$Elements` before `$Nodes`"));
                }
                let c = b.line("the number of elements")?;
                let n: usize = c.parse().map_err(|_| {
                    b.err(format!(
                        "expected the number of elements, found {}",
                        show(c)
                    ))
                })?;
                let mut done = 0usize;
                let mut nodes = Vec::new();
                let mut tags = Vec::new();
                while done < n {
                    let code = b.i32("an element type")? as i64;
                    let follow = b.i32("the number of elements of this type")?;
                    let ntags = b.i32("the number of tags")?;
                    let Some(ty) = gmsh_type(code) else {
                        return Err(b.err(format!("unknown element type {code}")));
                    };
                    if follow < 0 || ntags < 0 || done + follow as usize > n {
                        return Err(b.err(format!(
                            "bad element block header: {follow} elements, {ntags} tags"
                        )));
                    }
                    for _ in 0..follow {
                        let id = b.i32("an element id")?;
                        tags.clear();
                        for _ in 0..ntags {
                            tags.push(b.i32("an element tag")?);
                        }
                        nodes.clear();
                        for _ in 0..ty.nodes {
                            let nid = b.i32("a node id")?;
                            let k =
                                index.get(nid as u64).filter(|_| nid >= 0).ok_or_else(|| {
                                    b.err(format!(
                                        "element {id} refers to node {nid}, which is not in $Nodes"
                                    ))
                                })?;
                            nodes.push(k);
                        }
                        let physical = tags.first().copied().unwrap_or(0);
                        col.add(code, ty.dim, id as u64, &nodes, &[physical], None);
                    }
                    done += follow as usize;
                }
                b.expect_line("$EndElements")?;
            }
            other if other.starts_with('$') => {
                let end_tag = format!("$End{}", &other[1..]);
                let e = find(&bytes[b.pos..], end_tag.as_bytes())
                    .ok_or_else(|| b.err(format!("`{end_tag}` missing")))?;
                b.pos += e + end_tag.len();
            }
            other => {
                return Err(b.err(format!(
                    "expected a section header like `$Nodes`, found {}",
                    show(other)
                )))
            }
        }
    }
    col.into_raw(path, &names)
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

/// Turn an mshio error into (1-based line for ASCII files, message).
fn describe_mshio_error(
    e: &mshio::MshParserError<&[u8]>,
    bytes: &[u8],
    binary: bool,
) -> (Option<usize>, String) {
    let offset = e
        .backtrace
        .first()
        .map(|(s, _)| (s.as_ptr() as usize).wrapping_sub(bytes.as_ptr() as usize))
        .filter(|&o| o <= bytes.len());
    // Outermost first: contexts say where the parser was, the last one what it wanted.
    let bt = e.filtered_backtrace();
    let mut contexts: Vec<&str> = bt.iter().rev().filter_map(|(_, k)| k.context()).collect();
    let kinds: Vec<String> = bt
        .iter()
        .filter(|(_, k)| k.context().is_none())
        .map(|(_, k)| k.to_string().trim_end_matches('.').to_string())
        .collect();
    let mut msg = match contexts.pop() {
        Some(what) => format!("expected {what}"),
        None => "unexpected content".to_string(),
    };
    if !contexts.is_empty() {
        msg = format!("{msg} (in {})", contexts.join(" > "));
    }
    if !kinds.is_empty() {
        msg = format!("{msg}: {}", kinds.join("; "));
    }
    let line = match (offset, binary) {
        (Some(o), false) => Some(1 + bytes[..o].iter().filter(|&&c| c == b'\n').count()),
        (Some(o), true) => {
            msg = format!("byte {o}: {msg}");
            None
        }
        (None, _) => None,
    };
    (line, msg)
}

/// MSH 4.1 through mshio, plus `$PhysicalNames` read here.
fn read_msh41(path: &Path, bytes: &[u8], binary: bool) -> Result<RawMesh> {
    let parsed = std::panic::catch_unwind(|| {
        mshio::parse_msh_bytes(bytes).map_err(|e| describe_mshio_error(&e, bytes, binary))
    });
    let msh = match parsed {
        Ok(Ok(m)) => m,
        Ok(Err((line, msg))) => {
            return Err(Error::MeshFormat {
                path: path.to_path_buf(),
                line,
                msg,
            })
        }
        Err(_) => {
            return Err(format_err_noline(
                path,
                "the MSH 4.1 parser failed on this file (unsupported feature?)",
            ))
        }
    };

    // Physical names: a small ASCII section even in binary files.
    let mut names = HashMap::new();
    let tag = b"$PhysicalNames";
    let mut from = 0;
    while let Some(p) = find(&bytes[from..], tag) {
        let p = from + p;
        if p == 0 || bytes[p - 1] == b'\n' {
            let end_tag = b"$EndPhysicalNames";
            let end = find(&bytes[p..], end_tag)
                .map(|e| p + e + end_tag.len())
                .unwrap_or(bytes.len());
            let first_line = 1 + bytes[..p].iter().filter(|&&c| c == b'\n').count();
            let text = String::from_utf8_lossy(&bytes[p..end]);
            let mut lr = LineReader::new(path, &text, None).with_first_line(first_line);
            lr.next("`$PhysicalNames`")?;
            names = parse_physical_names(&mut lr)?;
            break;
        }
        from = p + tag.len();
    }

    // Entity -> physical tags.
    let mut entity_phys: HashMap<(i32, i32), Vec<i32>> = HashMap::new();
    if let Some(ent) = &msh.data.entities {
        for p in &ent.points {
            entity_phys.insert((0, p.tag), p.physical_tags.clone());
        }
        for c in &ent.curves {
            entity_phys.insert((1, c.tag), c.physical_tags.clone());
        }
        for s in &ent.surfaces {
            entity_phys.insert((2, s.tag), s.physical_tags.clone());
        }
        for v in &ent.volumes {
            entity_phys.insert((3, v.tag), v.physical_tags.clone());
        }
    }

    let mut col = Collector::default();
    let mut index = NodeIndex::default();
    if let Some(nodes) = &msh.data.nodes {
        let mut next_tag = nodes.min_node_tag;
        for block in &nodes.node_blocks {
            let tags: Option<Vec<u64>> = block.node_tags.as_ref().map(|m| {
                let mut t = vec![0u64; block.nodes.len()];
                for (&tag, &i) in m {
                    if let Some(slot) = t.get_mut(i) {
                        *slot = tag;
                    }
                }
                t
            });
            for (i, nd) in block.nodes.iter().enumerate() {
                let id = match &tags {
                    Some(t) => t[i],
                    None => {
                        next_tag += 1;
                        next_tag - 1
                    }
                };
                let p = [nd.x, nd.y, nd.z];
                if p.iter().any(|v| !v.is_finite()) {
                    return Err(format_err_noline(
                        path,
                        format!("node {id} has a non-finite coordinate"),
                    ));
                }
                let k = col.raw.push_node(id, p);
                if !index.insert(id, k) {
                    return Err(format_err_noline(path, format!("duplicate node id {id}")));
                }
            }
        }
    }
    if let Some(elements) = &msh.data.elements {
        let mut nodes = Vec::new();
        for block in &elements.element_blocks {
            let code = block.element_type as i64;
            let ty = gmsh_type(code);
            let dim = ty
                .map(|t| t.dim)
                .unwrap_or(block.entity_dim.clamp(0, 3) as u8);
            let physical = entity_phys
                .get(&(block.entity_dim, block.entity_tag))
                .cloned()
                .unwrap_or_default();
            for el in &block.elements {
                if let Some(t) = ty {
                    if el.nodes.len() != t.nodes {
                        return Err(format_err_noline(
                            path,
                            format!(
                                "expected {} node ids for element type {code}, found {}",
                                t.nodes,
                                el.nodes.len()
                            ),
                        ));
                    }
                }
                nodes.clear();
                for &nid in &el.nodes {
                    let k = index.get(nid).ok_or_else(|| {
                        format_err_noline(
                            path,
                            format!(
                                "element {} refers to node {nid}, which is not in $Nodes",
                                el.element_tag
                            ),
                        )
                    })?;
                    nodes.push(k);
                }
                col.add(code, dim, el.element_tag, &nodes, &physical, None);
            }
        }
    }
    col.into_raw(path, &names)
}

/// Write `mesh` as Gmsh MSH 2.2 ASCII (atomically). The elements get physical tag 1
/// `"domain"`; group `i` (in name order) is written as point elements with physical tag
/// `i + 2` and the group's name (`"` in names becomes `'`).
pub fn write_msh22(path: &Path, mesh: &Mesh) -> Result<()> {
    for (i, p) in mesh.nodes.iter().enumerate() {
        if let Some(c) = p.iter().position(|v| !v.is_finite()) {
            return Err(Error::param(
                "mesh.nodes",
                format!("node {i} coordinate {c} is {}", p[c]),
            ));
        }
    }
    let nn = mesh.nodes.len();
    if let Some(&bad) = mesh.cells.iter().find(|&&c| c as usize >= nn) {
        return Err(Error::param(
            "mesh.cells",
            format!("node id {bad} out of range ({nn} nodes)"),
        ));
    }
    for (name, members) in &mesh.groups {
        if let Some(&bad) = members.iter().find(|&&c| c as usize >= nn) {
            return Err(Error::param(
                "mesh.groups",
                format!("group `{name}` has node id {bad}, out of range ({nn} nodes)"),
            ));
        }
    }
    let (dim, code) = match mesh.kind {
        ElementKind::Tri3 => (2, 2),
        ElementKind::Tet4 => (3, 4),
    };
    write_atomic(path, |w: &mut dyn Write| {
        writeln!(w, "$MeshFormat\n2.2 0 8\n$EndMeshFormat")?;
        writeln!(w, "$PhysicalNames\n{}", 1 + mesh.groups.len())?;
        writeln!(w, "{dim} 1 \"domain\"")?;
        for (i, name) in mesh.groups.keys().enumerate() {
            writeln!(w, "0 {} \"{}\"", i + 2, name.replace('"', "'"))?;
        }
        writeln!(w, "$EndPhysicalNames")?;
        writeln!(w, "$Nodes\n{nn}")?;
        for (i, p) in mesh.nodes.iter().enumerate() {
            writeln!(w, "{} {:e} {:e} {:e}", i + 1, p[0], p[1], p[2])?;
        }
        writeln!(w, "$EndNodes")?;
        let ne = mesh.num_elements();
        let ng: usize = mesh.groups.values().map(Vec::len).sum();
        writeln!(w, "$Elements\n{}", ne + ng)?;
        let mut id = 0usize;
        for el in mesh.elements() {
            id += 1;
            write!(w, "{id} {code} 2 1 1")?;
            for &v in el {
                write!(w, " {}", v + 1)?;
            }
            writeln!(w)?;
        }
        for (i, members) in mesh.groups.values().enumerate() {
            for &v in members {
                id += 1;
                writeln!(w, "{id} 15 2 {t} {t} {}", v + 1, t = i + 2)?;
            }
        }
        writeln!(w, "$EndElements")
    })
}

#[cfg(test)]
mod tests;
