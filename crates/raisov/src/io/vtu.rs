//! ParaView output: VTK XML unstructured grids (`.vtu`) and `.pvd` time collections.
//!
//! [`write_vtu`] writes one frame: the current node positions, the mesh cells (VTK types 5
//! triangle and 10 tetrahedron, same node order as [`Mesh`]) and any number of point and cell
//! fields (scalars, 3-vectors, 3x3 tensors stored row-major as 9 components). Data are ASCII
//! `Float64` written with Rust's shortest round-trip representation (`{:e}`), so values read
//! back bit-exact. [`PvdWriter`] maintains a `.pvd` collection listing frames and their
//! times, rewritten after every [`PvdWriter::add`]. Both write atomically and refuse
//! non-finite values ([`Error::Param`] naming the field and the item).

use std::io::Write;
use std::path::{Path, PathBuf};

use super::write_atomic;
use crate::mesh::{ElementKind, Mesh};
use crate::{Error, Result};

/// The values of one field, one item per node (point fields) or element (cell fields).
#[derive(Clone, Copy, Debug)]
pub enum FieldData<'a> {
    /// One value per item.
    Scalar(&'a [f64]),
    /// Three values per item (x, y, z).
    Vector(&'a [f64]),
    /// Nine values per item, a 3x3 tensor row-major.
    Tensor(&'a [f64]),
}

impl FieldData<'_> {
    /// Components per item.
    pub fn components(&self) -> usize {
        match self {
            FieldData::Scalar(_) => 1,
            FieldData::Vector(_) => 3,
            FieldData::Tensor(_) => 9,
        }
    }
    /// The flat values.
    pub fn values(&self) -> &[f64] {
        match self {
            FieldData::Scalar(v) | FieldData::Vector(v) | FieldData::Tensor(v) => v,
        }
    }
}

/// A named field.
#[derive(Clone, Copy, Debug)]
pub struct Field<'a> {
    pub name: &'a str,
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

/// Check that `values` has `items * k` finite entries.
fn check_values(name: &str, what: &str, values: &[f64], k: usize, items: usize) -> Result<()> {
    if values.len() != items * k {
        return Err(Error::param(
            name,
            format!(
                "{what} needs {items} items x {k} components = {} values, got {}",
                items * k,
                values.len()
            ),
        ));
    }
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

fn check_fields(fields: &[Field], items: usize, what: &str) -> Result<()> {
    for f in fields {
        if f.name.is_empty() {
            return Err(Error::param(what, "a field has an empty name"));
        }
        check_values(
            f.name,
            &format!("{what} `{}`", f.name),
            f.data.values(),
            f.data.components(),
            items,
        )?;
    }
    Ok(())
}

fn write_array(w: &mut dyn Write, values: &[f64], per_line: usize) -> std::io::Result<()> {
    for chunk in values.chunks(per_line.max(1)) {
        w.write_all(b"         ")?;
        for v in chunk {
            write!(w, " {v:e}")?;
        }
        w.write_all(b"\n")?;
    }
    Ok(())
}

fn write_fields(w: &mut dyn Write, tag: &str, fields: &[Field]) -> std::io::Result<()> {
    if fields.is_empty() {
        return Ok(());
    }
    writeln!(w, "      <{tag}>")?;
    for f in fields {
        let k = f.data.components();
        writeln!(
            w,
            "        <DataArray type=\"Float64\" Name=\"{}\" NumberOfComponents=\"{k}\" \
             format=\"ascii\">",
            xml_escape(f.name)
        )?;
        write_array(w, f.data.values(), k.max(3))?;
        writeln!(w, "        </DataArray>")?;
    }
    writeln!(w, "      </{tag}>")
}

/// Write one ParaView frame: `mesh`'s cells at node `positions` (one per mesh node, e.g.
/// reference positions plus displacement), with point fields (one item per node) and cell
/// fields (one item per element). Atomic; refuses non-finite values and wrong lengths with
/// [`Error::Param`].
pub fn write_vtu(
    path: &Path,
    mesh: &Mesh,
    positions: &[[f64; 3]],
    point_fields: &[Field],
    cell_fields: &[Field],
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
        ElementKind::Tri3 => (3, 5),
        ElementKind::Tet4 => (4, 10),
    };
    write_atomic(path, |w: &mut dyn Write| {
        writeln!(w, "<?xml version=\"1.0\"?>")?;
        writeln!(
            w,
            "<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">"
        )?;
        writeln!(w, "  <UnstructuredGrid>")?;
        writeln!(
            w,
            "    <Piece NumberOfPoints=\"{nn}\" NumberOfCells=\"{ne}\">"
        )?;
        write_fields(w, "PointData", point_fields)?;
        write_fields(w, "CellData", cell_fields)?;
        writeln!(w, "      <Points>")?;
        writeln!(
            w,
            "        <DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">"
        )?;
        write_array(w, positions.as_flattened(), 3)?;
        writeln!(w, "        </DataArray>")?;
        writeln!(w, "      </Points>")?;
        writeln!(w, "      <Cells>")?;
        writeln!(
            w,
            "        <DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">"
        )?;
        for el in mesh.elements() {
            w.write_all(b"         ")?;
            for v in el {
                write!(w, " {v}")?;
            }
            w.write_all(b"\n")?;
        }
        writeln!(w, "        </DataArray>")?;
        writeln!(
            w,
            "        <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">"
        )?;
        for chunk in (1..=ne).collect::<Vec<_>>().chunks(16) {
            w.write_all(b"         ")?;
            for e in chunk {
                write!(w, " {}", e * npe)?;
            }
            w.write_all(b"\n")?;
        }
        writeln!(w, "        </DataArray>")?;
        writeln!(
            w,
            "        <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">"
        )?;
        for chunk in (0..ne).collect::<Vec<_>>().chunks(32) {
            w.write_all(b"         ")?;
            for _ in chunk {
                write!(w, " {vtk_type}")?;
            }
            w.write_all(b"\n")?;
        }
        writeln!(w, "        </DataArray>")?;
        writeln!(w, "      </Cells>")?;
        writeln!(w, "    </Piece>")?;
        writeln!(w, "  </UnstructuredGrid>")?;
        writeln!(w, "</VTKFile>")
    })
}

/// A ParaView `.pvd` collection of frames, rewritten atomically after each [`add`].
///
/// [`add`]: PvdWriter::add
#[derive(Clone, Debug)]
pub struct PvdWriter {
    path: PathBuf,
    entries: Vec<(f64, String)>,
}

impl PvdWriter {
    /// A collection to be written at `path` (nothing is written until the first `add`).
    pub fn new(path: impl Into<PathBuf>) -> Self {
        PvdWriter {
            path: path.into(),
            entries: Vec::new(),
        }
    }

    /// The `.pvd` path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The frames so far: (time, file name relative to the `.pvd`).
    pub fn entries(&self) -> &[(f64, String)] {
        &self.entries
    }

    /// Add a frame at `time` (seconds) stored in `vtu_file_name_relative` (relative to the
    /// directory of the `.pvd`), and rewrite the collection.
    pub fn add(&mut self, time: f64, vtu_file_name_relative: &str) -> Result<()> {
        if !time.is_finite() {
            return Err(Error::param(
                "time",
                format!(
                    "frame {} (`{vtu_file_name_relative}`) has time {time}; refusing to write \
                     non-finite values",
                    self.entries.len()
                ),
            ));
        }
        self.entries
            .push((time, vtu_file_name_relative.to_string()));
        let entries = &self.entries;
        let res = write_atomic(&self.path, |w: &mut dyn Write| {
            writeln!(w, "<?xml version=\"1.0\"?>")?;
            writeln!(
                w,
                "<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">"
            )?;
            writeln!(w, "  <Collection>")?;
            for (t, f) in entries {
                writeln!(
                    w,
                    "    <DataSet timestep=\"{t:e}\" group=\"\" part=\"0\" file=\"{}\"/>",
                    xml_escape(f)
                )?;
            }
            writeln!(w, "  </Collection>")?;
            writeln!(w, "</VTKFile>")
        });
        if res.is_err() {
            self.entries.pop();
        }
        res
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
        write_vtu(
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
    fn vtu_triangles_and_no_fields() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.vtu");
        let m = Mesh::new(
            ElementKind::Tri3,
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            vec![0, 1, 2],
        );
        write_vtu(&p, &m, &m.nodes, &[], &[]).unwrap();
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
        assert_eq!(pvd.entries().len(), 2);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }
}
