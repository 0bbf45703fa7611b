//! PLY (Stanford polygon file) surfaces.
//!
//! Header: `ply`, `format ascii|binary_little_endian|binary_big_endian 1.0`, `comment` and
//! `obj_info` lines, `element NAME COUNT` each followed by its `property TYPE NAME` or
//! `property list COUNT_TYPE ITEM_TYPE NAME` lines, `end_header`. Scalar types: `char`/`int8`,
//! `uchar`/`uint8`, `short`/`int16`, `ushort`/`uint16`, `int`/`int32`, `uint`/`uint32`,
//! `float`/`float32`, `double`/`float64`.
//!
//! Read: the `vertex` element's `x`, `y`, `z` (any scalar type) and the `face` element's
//! `vertex_indices` (or `vertex_index`) list, 0-based, polygons split into fans. Every other
//! element and property is skipped by its declared type (lists by their count).

use std::path::Path;

use super::fan;
use crate::io::text::{format_err, format_err_noline, show};
use crate::mesh::Surface;
use crate::Result;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(s: &str) -> Option<Scalar> {
        Some(match s {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }
    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }
    fn is_int(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }
}

const TYPES: &str = "char, uchar, short, ushort, int, uint, float, double (or int8, uint8, \
                     int16, uint16, int32, uint32, float32, float64)";

#[derive(Debug)]
enum Prop {
    Scalar(Scalar, String),
    List(Scalar, Scalar, String),
}

#[derive(Debug)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Prop>,
    /// Header line of the `element` statement.
    line: usize,
}

#[derive(Clone, Copy, PartialEq)]
enum Format {
    Ascii,
    Le,
    Be,
}

/// What a property is to the surface.
#[derive(Clone, Copy, PartialEq)]
enum Role {
    Coord(usize),
    Indices,
    Skip,
}

/// Parse the bytes of a PLY file (see the module docs).
pub fn parse_ply(path: &Path, bytes: &[u8]) -> Result<Surface> {
    // Header: text lines up to and including `end_header`.
    let mut pos = 0;
    let mut line = 0;
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        if pos >= bytes.len() {
            return Err(format_err(
                path,
                line + 1,
                "unexpected end of file in the header; expected `end_header`",
            ));
        }
        let end = bytes[pos..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |e| pos + e);
        let raw = std::str::from_utf8(&bytes[pos..end])
            .map_err(|_| format_err(path, line + 1, "header line is not ASCII text"))?;
        pos = (end + 1).min(bytes.len());
        line += 1;
        let mut tok = raw.split_whitespace();
        let key = tok.next().unwrap_or("");
        if line == 1 {
            if key != "ply" {
                return Err(format_err(
                    path,
                    1,
                    format!(
                        "expected `ply` as the first line, found {}",
                        show(raw.trim())
                    ),
                ));
            }
            continue;
        }
        match key {
            "" | "comment" | "obj_info" => {}
            "format" => {
                format = Some(match tok.next() {
                    Some("ascii") => Format::Ascii,
                    Some("binary_little_endian") => Format::Le,
                    Some("binary_big_endian") => Format::Be,
                    other => {
                        return Err(format_err(
                            path,
                            line,
                            format!(
                                "unknown PLY format {}; valid: ascii, binary_little_endian, \
                                 binary_big_endian",
                                show(other.unwrap_or(""))
                            ),
                        ))
                    }
                })
            }
            "element" => {
                let (Some(name), Some(count)) = (tok.next(), tok.next()) else {
                    return Err(format_err(path, line, "expected `element NAME COUNT`"));
                };
                let count = count.parse().map_err(|_| {
                    format_err(
                        path,
                        line,
                        format!(
                            "element `{name}`: count {} is not a non-negative integer",
                            show(count)
                        ),
                    )
                })?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    props: Vec::new(),
                    line,
                });
            }
            "property" => {
                let Some(el) = elements.last_mut() else {
                    return Err(format_err(path, line, "`property` before any `element`"));
                };
                let ty = |s: Option<&str>| {
                    s.and_then(Scalar::parse).ok_or_else(|| {
                        format_err(
                            path,
                            line,
                            format!(
                                "unknown property type {}; valid: {TYPES}",
                                show(s.unwrap_or(""))
                            ),
                        )
                    })
                };
                let p = match tok.next() {
                    Some("list") => {
                        let c = ty(tok.next())?;
                        let i = ty(tok.next())?;
                        if !c.is_int() {
                            return Err(format_err(
                                path,
                                line,
                                "a list's count type must be an integer type",
                            ));
                        }
                        Prop::List(c, i, tok.next().unwrap_or("").to_string())
                    }
                    s => Prop::Scalar(ty(s)?, tok.next().unwrap_or("").to_string()),
                };
                el.props.push(p);
            }
            "end_header" => break,
            k => {
                return Err(format_err(
                    path,
                    line,
                    format!(
                        "unknown header statement {}; valid: format, element, property, \
                         comment, obj_info, end_header",
                        show(k)
                    ),
                ))
            }
        }
    }
    let format = format.ok_or_else(|| {
        format_err(
            path,
            line,
            "no `format` line in the header; expected e.g. `format ascii 1.0`",
        )
    })?;
    let find = |name: &str| elements.iter().position(|e| e.name == name);
    let vi = find("vertex")
        .ok_or_else(|| format_err_noline(path, "no `vertex` element in the header"))?;
    let fi = find("face").ok_or_else(|| {
        format_err_noline(
            path,
            "no `face` element in the header (triangle strips are not read); expected \
             `element face N` with `property list uchar int vertex_indices`",
        )
    })?;
    // Roles of every property of every element.
    let mut roles: Vec<Vec<Role>> = Vec::new();
    for (k, el) in elements.iter().enumerate() {
        let mut r = vec![Role::Skip; el.props.len()];
        if k == vi {
            for (c, axis) in ["x", "y", "z"].iter().enumerate() {
                let j = el
                    .props
                    .iter()
                    .position(|p| matches!(p, Prop::Scalar(_, n) if n == axis))
                    .ok_or_else(|| {
                        format_err(
                            path,
                            el.line,
                            format!("element `vertex` has no scalar property `{axis}`"),
                        )
                    })?;
                r[j] = Role::Coord(c);
            }
        }
        if k == fi {
            let j = el
                .props
                .iter()
                .position(|p| {
                    matches!(p, Prop::List(_, _, n) if n == "vertex_indices" || n == "vertex_index")
                })
                .ok_or_else(|| {
                    format_err(
                        path,
                        el.line,
                        "element `face` has no list property `vertex_indices`; expected \
                         `property list uchar int vertex_indices`",
                    )
                })?;
            if let Prop::List(_, item, _) = el.props[j] {
                if !item.is_int() {
                    return Err(format_err(
                        path,
                        el.line,
                        "face `vertex_indices` must have an integer item type (int or uint)",
                    ));
                }
            }
            r[j] = Role::Indices;
        }
        roles.push(r);
    }
    let nv = elements[vi].count;
    if nv > bytes.len() || nv > u32::MAX as usize {
        return Err(format_err(
            path,
            elements[vi].line,
            format!(
                "the header declares {nv} vertices but the file has only {} bytes \
                 (and at most {} vertices are supported)",
                bytes.len(),
                u32::MAX
            ),
        ));
    }
    let mut points = vec![[0.0; 3]; nv];
    let mut triangles = Vec::new();
    let mut body = Body {
        path,
        bytes,
        pos,
        line,
        format,
        tokens: Vec::new(),
        tok_idx: 0,
    };
    let mut poly: Vec<u32> = Vec::new();
    for (k, el) in elements.iter().enumerate() {
        if el.props.is_empty() && format != Format::Ascii {
            continue; // nothing stored
        }
        if el.count > bytes.len() {
            return Err(format_err(
                path,
                el.line,
                format!(
                    "element `{}` declares {} items but the file has only {} bytes",
                    el.name,
                    el.count,
                    bytes.len()
                ),
            ));
        }
        for item in 0..el.count {
            body.begin_item()?;
            for (j, p) in el.props.iter().enumerate() {
                let what = || format!("element `{}` {item}", el.name);
                match (p, roles[k][j]) {
                    (Prop::Scalar(t, _), Role::Coord(c)) => {
                        let v = body.value(*t, &what)?;
                        if !v.is_finite() {
                            return Err(
                                body.err(format!("vertex {item} has a non-finite coordinate {v}"))
                            );
                        }
                        points[item][c] = v;
                    }
                    (Prop::Scalar(t, _), _) => {
                        body.value(*t, &what)?;
                    }
                    (Prop::List(ct, it, _), role) => {
                        let n = body.count(*ct, &what)?;
                        poly.clear();
                        for _ in 0..n {
                            let v = body.value(*it, &what)?;
                            if role == Role::Indices {
                                if v < 0.0 || v >= nv as f64 {
                                    return Err(body.err(format!(
                                        "face {item} references vertex {v} but the file has \
                                         {nv} vertices (valid: 0..{})",
                                        nv as i64 - 1
                                    )));
                                }
                                poly.push(v as u32);
                            }
                        }
                        if role == Role::Indices {
                            if n < 3 {
                                return Err(body.err(format!(
                                    "face {item} has {n} vertices; a face needs at least 3"
                                )));
                            }
                            fan(&poly, &mut triangles);
                        }
                    }
                }
            }
            body.end_item(&el.name, item)?;
        }
    }
    Ok(Surface { points, triangles })
}

/// The data after the header, read as ASCII tokens (one element per line) or binary.
struct Body<'a> {
    path: &'a Path,
    bytes: &'a [u8],
    pos: usize,
    /// Last line read (ASCII).
    line: usize,
    format: Format,
    tokens: Vec<&'a str>,
    tok_idx: usize,
}

impl<'a> Body<'a> {
    fn err(&self, msg: String) -> crate::Error {
        match self.format {
            Format::Ascii => format_err(self.path, self.line, msg),
            _ => format_err_noline(self.path, format!("byte {}: {msg}", self.pos)),
        }
    }

    /// ASCII: read the next non-blank line as the item's tokens.
    fn begin_item(&mut self) -> Result<()> {
        if self.format != Format::Ascii {
            return Ok(());
        }
        loop {
            if self.pos >= self.bytes.len() {
                return Err(format_err(
                    self.path,
                    self.line + 1,
                    "unexpected end of file; the header declares more elements",
                ));
            }
            let end = self.bytes[self.pos..]
                .iter()
                .position(|&b| b == b'\n')
                .map_or(self.bytes.len(), |e| self.pos + e);
            let raw = std::str::from_utf8(&self.bytes[self.pos..end])
                .map_err(|_| format_err(self.path, self.line + 1, "line is not ASCII text"))?;
            self.pos = (end + 1).min(self.bytes.len());
            self.line += 1;
            self.tokens = raw.split_whitespace().collect();
            self.tok_idx = 0;
            if !self.tokens.is_empty() {
                return Ok(());
            }
        }
    }

    fn end_item(&mut self, name: &str, item: usize) -> Result<()> {
        if self.format == Format::Ascii && self.tok_idx < self.tokens.len() {
            return Err(self.err(format!(
                "element `{name}` {item} has {} values but its properties take {}",
                self.tokens.len(),
                self.tok_idx
            )));
        }
        Ok(())
    }

    fn value(&mut self, t: Scalar, what: &dyn Fn() -> String) -> Result<f64> {
        match self.format {
            Format::Ascii => {
                let Some(&tok) = self.tokens.get(self.tok_idx) else {
                    return Err(self.err(format!(
                        "{} has {} values; its properties take more",
                        what(),
                        self.tokens.len()
                    )));
                };
                self.tok_idx += 1;
                let v = if t.is_int() {
                    tok.parse::<i64>().ok().map(|v| v as f64)
                } else {
                    tok.parse::<f64>().ok()
                };
                v.ok_or_else(|| {
                    self.err(format!(
                        "{}: expected {} value, found {}",
                        what(),
                        if t.is_int() { "an integer" } else { "a number" },
                        show(tok)
                    ))
                })
            }
            _ => {
                let n = t.size();
                if self.pos + n > self.bytes.len() {
                    return Err(self.err(format!(
                        "unexpected end of file in {}; the header declares more data",
                        what()
                    )));
                }
                let mut b = [0u8; 8];
                b[..n].copy_from_slice(&self.bytes[self.pos..self.pos + n]);
                if self.format == Format::Be {
                    b[..n].reverse();
                }
                self.pos += n;
                Ok(match t {
                    Scalar::I8 => b[0] as i8 as f64,
                    Scalar::U8 => b[0] as f64,
                    Scalar::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
                    Scalar::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
                    Scalar::I32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
                    Scalar::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
                    Scalar::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
                    Scalar::F64 => f64::from_le_bytes(b),
                })
            }
        }
    }

    fn count(&mut self, t: Scalar, what: &dyn Fn() -> String) -> Result<usize> {
        let v = self.value(t, what)?;
        if v < 0.0 {
            return Err(self.err(format!("{}: negative list count {v}", what())));
        }
        Ok(v as usize)
    }
}
