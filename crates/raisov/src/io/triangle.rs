//! Triangle (2-D) and TetGen (3-D) `.node` + `.ele` pairs.
//!
//! `.node`: first line `<#points> <dimension 2|3> <#attributes> <#boundary markers 0|1>`
//! (the last two may be omitted, meaning 0), then one line per point:
//! `<id> <x> <y> [<z>] [attributes...] [<marker>]`. 2-D points get z = 0.
//!
//! `.ele`: first line `<#elements> <nodes per element> <#attributes>`, then
//! `<id> <n1> <n2> ... [attributes...]`. 3 nodes per element give triangles (membranes),
//! 4 tetrahedra; 6-node triangles and 10-node tetrahedra are read as their corners (listed
//! first in both programs).
//!
//! Numbering may start at 0 or 1 (or anywhere): elements refer to the ids the `.node` file
//! gives its points. `#` starts a comment anywhere on a line; blank lines are skipped.
//!
//! Groups: a nonzero boundary marker `m` puts the point in group `"marker m"`; the first
//! element attribute `a` (a region attribute) puts the element's nodes in `"region a"`.
//! `.face`, `.edge`, `.poly` and `.neigh` files are not read.

use std::path::Path;

use super::text::{format_err, parse_f64, parse_tok, LineReader};
use super::{append_ext, finish, read_bytes, LoadedMesh, NodeIndex, RawMesh};

use crate::Result;

/// Read `base.node` and `base.ele` (`base` without extension, e.g. `mesh.1`).
pub fn read_node_ele(base: &Path) -> Result<LoadedMesh> {
    let node_path = append_ext(base, "node");
    let ele_path = append_ext(base, "ele");
    let node_text = String::from_utf8_lossy(&read_bytes(&node_path)?).into_owned();
    let ele_text = String::from_utf8_lossy(&read_bytes(&ele_path)?).into_owned();
    let mut raw = RawMesh::default();
    let mut index = NodeIndex::default();

    // .node
    let path = node_path.as_path();
    let mut lr = LineReader::new(path, &node_text, Some('#'));
    let what = "the header `<#points> <dimension> <#attributes> <#markers>`";
    let (l, h) = lr.next(what)?;
    let t: Vec<&str> = h.split_whitespace().collect();
    if t.len() < 2 || t.len() > 4 {
        return Err(format_err(
            path,
            l,
            format!("expected {what}, found {} values", t.len()),
        ));
    }
    let n: usize = parse_tok(path, l, t[0], "the number of points")?;
    let dim: usize = parse_tok(path, l, t[1], "the dimension (2 or 3)")?;
    if dim != 2 && dim != 3 {
        return Err(format_err(
            path,
            l,
            format!("expected the dimension 2 or 3, found {dim}"),
        ));
    }
    let nattr: usize = match t.get(2) {
        Some(s) => parse_tok(path, l, s, "the number of attributes")?,
        None => 0,
    };
    let nmark: usize = match t.get(3) {
        Some(s) => parse_tok(path, l, s, "the number of boundary markers (0 or 1)")?,
        None => 0,
    };
    if nmark > 1 {
        return Err(format_err(
            path,
            l,
            format!("expected 0 or 1 boundary markers, found {nmark}"),
        ));
    }
    let per_line = 1 + dim + nattr + nmark;
    for i in 0..n {
        let what = format!("point {} of {n}", i + 1);
        let (l, s) = lr.next(&what)?;
        let t: Vec<&str> = s.split_whitespace().collect();
        if t.len() != per_line {
            return Err(format_err(
                path,
                l,
                format!(
                    "expected {per_line} values for {what} (id, {dim} coordinates, {nattr} \
                     attributes, {nmark} markers), found {}",
                    t.len()
                ),
            ));
        }
        let id: u64 = parse_tok(path, l, t[0], "a point id")?;
        let mut p = [0.0; 3];
        for (k, c) in p.iter_mut().enumerate().take(dim) {
            *c = parse_f64(path, l, t[1 + k], ["x", "y", "z"][k])?;
        }
        for a in &t[1 + dim..1 + dim + nattr] {
            parse_f64(path, l, a, "an attribute")?;
        }
        let k = raw.push_node(id, p);
        if !index.insert(id, k) {
            return Err(format_err(path, l, format!("duplicate point id {id}")));
        }
        if nmark == 1 {
            let m: i64 = parse_tok(path, l, t[per_line - 1], "a boundary marker")?;
            if m != 0 {
                raw.groups.entry(format!("marker {m}")).or_default().push(k);
            }
        }
    }

    // .ele
    let path = ele_path.as_path();
    let mut lr = LineReader::new(path, &ele_text, Some('#'));
    let what = "the header `<#elements> <nodes per element> <#attributes>`";
    let (l, h) = lr.next(what)?;
    let t: Vec<&str> = h.split_whitespace().collect();
    if t.len() < 2 || t.len() > 3 {
        return Err(format_err(
            path,
            l,
            format!("expected {what}, found {} values", t.len()),
        ));
    }
    let ne: usize = parse_tok(path, l, t[0], "the number of elements")?;
    let npe: usize = parse_tok(path, l, t[1], "the number of nodes per element")?;
    let eattr: usize = match t.get(2) {
        Some(s) => parse_tok(path, l, s, "the number of attributes")?,
        None => 0,
    };
    let corners = match npe {
        3 | 6 => 3,
        4 | 10 if dim == 3 => 4,
        4 | 10 => {
            return Err(format_err(
                path,
                l,
                format!("{npe}-node tetrahedra need 3-D points, but the .node file is 2-D"),
            ))
        }
        _ => {
            return Err(format_err(
                path,
                l,
                format!(
                "expected 3, 6 (triangles), 4 or 10 (tetrahedra) nodes per element, found {npe}"
            ),
            ))
        }
    };
    let per_line = 1 + npe + eattr;
    let mut nodes = Vec::with_capacity(npe);
    for i in 0..ne {
        let what = format!("element {} of {ne}", i + 1);
        let (l, s) = lr.next(&what)?;
        let t: Vec<&str> = s.split_whitespace().collect();
        if t.len() != per_line {
            return Err(format_err(
                path,
                l,
                format!(
                    "expected {per_line} values for {what} (id, {npe} node ids, {eattr} \
                     attributes), found {}",
                    t.len()
                ),
            ));
        }
        let id: u64 = parse_tok(path, l, t[0], "an element id")?;
        nodes.clear();
        for tok in &t[1..1 + npe] {
            let nid: u64 = parse_tok(path, l, tok, "a node id")?;
            let k = index.get(nid).ok_or_else(|| {
                format_err(
                    path,
                    l,
                    format!("element {id} refers to point {nid}, which is not in the .node file"),
                )
            })?;
            nodes.push(k);
        }
        if corners == 4 {
            raw.tets.extend_from_slice(&nodes[..4]);
            raw.tet_ids.push(id);
        } else {
            raw.tris.extend_from_slice(&nodes[..3]);
            raw.tri_ids.push(id);
        }
        for (j, a) in t[1 + npe..].iter().enumerate() {
            let v = parse_f64(path, l, a, "an element attribute")?;
            if j == 0 {
                let name = if v.fract() == 0.0 && v.abs() < 1e15 {
                    format!("region {}", v as i64)
                } else {
                    format!("region {a}")
                };
                raw.groups
                    .entry(name)
                    .or_default()
                    .extend_from_slice(&nodes);
            }
        }
    }
    let format = if dim == 2 { "triangle" } else { "tetgen" };
    finish(raw, &node_path, format)
}

#[cfg(test)]
mod tests {
    use crate::io::load_mesh;
    use crate::mesh::ElementKind;
    use crate::Error;
    use std::path::Path;

    fn pair(dir: &Path, base: &str, node: &str, ele: &str) -> std::path::PathBuf {
        std::fs::write(dir.join(format!("{base}.node")), node).unwrap();
        std::fs::write(dir.join(format!("{base}.ele")), ele).unwrap();
        dir.join(base)
    }

    #[test]
    fn triangle_2d_zero_based_with_markers() {
        let dir = tempfile::tempdir().unwrap();
        let base = pair(
            dir.path(),
            "sq.1",
            "# square\n4 2 1 1\n0 0 0 7.5 1\n1 1 0 0 1\n2 1 1 0 0\n3 0 1 0 2 # corner\n",
            "2 3 0\n0 0 1 2\n1 0 3 2\n",
        );
        for p in [
            base.clone(),
            dir.path().join("sq.1.node"),
            dir.path().join("sq.1.ele"),
        ] {
            let l = load_mesh(&p).unwrap();
            assert_eq!(l.format, "triangle");
            assert_eq!(l.mesh.kind, ElementKind::Tri3);
            assert_eq!(l.mesh.nodes[2], [1.0, 1.0, 0.0]);
            assert_eq!(l.mesh.num_elements(), 2);
            assert_eq!(l.reoriented, vec![1]);
            assert_eq!(l.mesh.groups["marker 1"], vec![0, 1]);
            assert_eq!(l.mesh.groups["marker 2"], vec![3]);
        }
    }

    #[test]
    fn tetgen_one_based_with_regions() {
        let dir = tempfile::tempdir().unwrap();
        let base = pair(
            dir.path(),
            "t",
            "6 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n5 1 1 1\n6 9 9 9\n",
            "2 4 1\n1 1 2 3 4 10\n2 2 3 5 4 -1\n",
        );
        let l = load_mesh(&base.with_extension("node")).unwrap();
        assert_eq!(l.format, "tetgen");
        assert_eq!(l.mesh.kind, ElementKind::Tet4);
        assert_eq!(l.unused_nodes_dropped, 1);
        assert_eq!(l.mesh.groups["region 10"], vec![0, 1, 2, 3]);
        assert_eq!(l.mesh.groups["region -1"], vec![1, 2, 3, 4]);
        assert!(l.mesh.total_measure() > 0.0);
        assert_eq!(l.reoriented, vec![1]);
    }

    #[test]
    fn errors_name_file_and_line() {
        let dir = tempfile::tempdir().unwrap();
        let check = |base: &Path, file: &str, line: usize, msg: &str| {
            let e = load_mesh(base).unwrap_err();
            let s = e.to_string();
            match &e {
                Error::MeshFormat { path, line: l, .. } => {
                    assert!(path.ends_with(file), "{s}");
                    assert_eq!(*l, Some(line), "{s}");
                }
                _ => panic!("{s}"),
            }
            assert!(s.contains(msg), "{s}");
        };
        let node = "3 2 0 0\n1 0 0\n2 1 0\n3 0 1\n";
        let b = pair(dir.path(), "a", node, "1 3 0\n1 1 2 4\n");
        check(&b, "a.ele", 2, "refers to point 4");
        let b = pair(dir.path(), "b", node, "1 4 0\n1 1 2 3 3\n");
        check(&b, "b.ele", 1, "need 3-D points");
        let b = pair(
            dir.path(),
            "c",
            "3 2 0 0\n1 0 0\n2 1 zero\n",
            "1 3 0\n1 1 2 3\n",
        );
        check(&b, "c.node", 3, "expected y, found `zero`");
        let b = pair(
            dir.path(),
            "d",
            "3 2 0 0\n1 0 0\n2 1 0\n",
            "1 3 0\n1 1 2 3\n",
        );
        check(
            &b,
            "d.node",
            4,
            "unexpected end of file, expected point 3 of 3",
        );
        let b = pair(dir.path(), "e", node, "2 3 0\n1 1 2 3\n2 1 2\n");
        check(&b, "e.ele", 3, "expected 4 values for element 2 of 2");
        let b = pair(
            dir.path(),
            "f",
            "3 2 0 0\n1 0 0\n1 1 0\n3 0 1\n",
            "1 3 0\n1 1 2 3\n",
        );
        check(&b, "f.node", 3, "duplicate point id 1");
        // Missing .ele names it.
        std::fs::write(dir.path().join("g.node"), node).unwrap();
        let e = load_mesh(&dir.path().join("g.node")).unwrap_err();
        assert!(
            matches!(e, Error::Io { .. }) && e.to_string().contains("g.ele"),
            "{e}"
        );
        // Collinear triangle.
        let b = pair(
            dir.path(),
            "h",
            "3 2 0 0\n1 0 0\n2 1 0\n3 2 0\n",
            "1 3 0\n1 1 2 3\n",
        );
        let e = load_mesh(&b).unwrap_err();
        assert!(matches!(e, Error::BadMesh { .. }), "{e}");
    }
}
