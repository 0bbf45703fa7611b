//! Mesh readers and result writers.
//!
//! Reading ([`load_mesh`], dispatch on the file extension):
//!
//! | extension | format |
//! |---|---|
//! | `.msh` | Gmsh MSH 2.2 (ASCII, binary) and 4.1 (ASCII, binary), see [`gmsh`] |
//! | `.node` / `.ele` | Triangle (2-D) and TetGen (3-D) node + element pair, see [`triangle`] |
//! | `.vtk` | VTK legacy unstructured grid (ASCII, binary; versions up to 5.1), see [`vtk`] |
//! | `.vtu` | VTK XML unstructured grid (ASCII, inline base64, appended raw or base64; zlib or uncompressed), see [`vtu_read`] |
//!
//! A Triangle/TetGen pair can also be given by its base name (`mesh.1` for `mesh.1.node` +
//! `mesh.1.ele`).
//!
//! Every reader produces the same thing: the highest-dimensional supported elements become
//! the mesh (tetrahedra if there are any, else triangles); lower-dimensional elements (Gmsh
//! boundary triangles of a tet mesh, lines, points) only contribute their nodes to named
//! groups. Nodes not used by any mesh element are dropped and the rest renumbered compactly
//! (in file order); group members that were dropped are removed from their group (the group
//! itself is kept, even if it ends up empty). The mesh is then oriented ([`Mesh::orient`])
//! and rejected if any element is degenerate. Coordinates are returned as read (no unit
//! conversion; see [`Mesh::scale`]).
//!
//! Triangle surfaces (the mesher's input) are read by [`load_surface`]: Wavefront OBJ, STL
//! and PLY, see [`surface`].
//!
//! Writing: [`write_msh22`] (Gmsh 2.2 ASCII), [`write_vtu`] / [`write_vtu_as`] (binary
//! appended zlib by default, ASCII on request, see [`vtu`]), [`write_vtp`] (surfaces, the
//! same encodings, see [`vtp`]) and [`PvdWriter`] (ParaView, appended in place). The file
//! writers go through [`write_atomic`]: the file appears complete or not at all. None of
//! them writes a non-finite number. [`OutputLock`] keeps two runs out of one directory.
//! Streamed CSV files ([`RowFile`]) end at a row boundary and say what they kept when a write
//! fails. No writer writes through a symbolic link ([`output`]); [`sweep_temporaries`]
//! removes the temporary files a killed writer left. Names that become file names follow one
//! rule ([`check_name`], [`names`]).

pub mod gmsh;
pub mod names;
pub mod output;
mod rows;
pub mod surface;
mod text;
pub mod triangle;
pub mod vtk;
pub mod vtp;
pub mod vtu;
pub mod vtu_read;

use std::collections::{BTreeMap, HashMap};
use std::io::Write;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

pub use gmsh::write_msh22;
pub use names::{check_name, name_from_stem, NAME_RULE};
pub use output::{open_for_writing, refuse_link, sweep_temporaries};
pub use rows::RowFile;
pub use surface::{is_surface_path, load_surface, parse_surface, SURFACE_EXTENSIONS};
pub use vtp::write_vtp;
pub use vtu::{write_vtu, write_vtu_as, Field, FieldData, PvdWriter, VtuFormat};
pub use vtu_read::{read_vtp, read_vtu, read_vtu_array, read_vtu_cell_array};

use crate::mesh::{ElementKind, Mesh};
use crate::{Error, Result};

/// Extensions [`load_mesh`] understands.
pub const MESH_EXTENSIONS: &[&str] = &["msh", "node", "ele", "vtk", "vtu"];

/// A mesh read from a file, with what the reader did to it.
#[derive(Clone, Debug)]
pub struct LoadedMesh {
    /// The mesh.
    pub mesh: Mesh,
    /// The format that was read, e.g. `"gmsh 2.2 ascii"`, `"tetgen"`, `"vtk legacy ascii"`.
    pub format: &'static str,
    /// Elements (final numbering) whose node order was flipped by [`Mesh::orient`].
    pub reoriented: Vec<usize>,
    /// Nodes in the file that no mesh element uses, dropped before renumbering.
    pub unused_nodes_dropped: usize,
    /// The id the file gives each node of [`LoadedMesh::mesh`] (Gmsh, Triangle and TetGen
    /// files number their nodes themselves, often from 1; VTK formats by position from 0).
    pub node_ids: Vec<u64>,
    /// The id the file gives each element of [`LoadedMesh::mesh`], in the mesh's element
    /// order (VTK formats: the cell's position from 0 among all cells, lower-dimensional
    /// ones included, so the index of its cell data; Gmsh: the element tag).
    pub element_ids: Vec<u64>,
}

/// Read a mesh, choosing the reader by extension (see the module docs).
///
/// Errors: [`Error::Io`] when the file cannot be read, [`Error::MeshFormat`] when it is
/// malformed (with the 1-based line for text formats), [`Error::BadMesh`] when it is empty or
/// has a degenerate element.
pub fn load_mesh(path: &Path) -> Result<LoadedMesh> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    match ext.as_deref() {
        Some("msh") => gmsh::read_msh(path),
        Some("node") | Some("ele") => triangle::read_node_ele(&path.with_extension("")),
        Some("vtk") => vtk::read_vtk(path),
        Some("vtu") => vtu_read::read_vtu(path),
        _ => {
            let node = append_ext(path, "node");
            let ele = append_ext(path, "ele");
            if node.is_file() && ele.is_file() {
                return triangle::read_node_ele(path);
            }
            Err(Error::MeshFormat {
                path: path.to_path_buf(),
                line: None,
                msg: format!(
                    "unknown mesh file extension {}; valid: {} (or the base name of a \
                     .node/.ele pair)",
                    ext.map(|e| format!("`.{e}`"))
                        .unwrap_or_else(|| "(none)".into()),
                    MESH_EXTENSIONS
                        .iter()
                        .map(|e| format!(".{e}"))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            })
        }
    }
}

/// `path` with `.ext` appended (not replacing an existing extension).
pub(crate) fn append_ext(path: &Path, ext: &str) -> std::path::PathBuf {
    let mut s = path.as_os_str().to_owned();
    s.push(".");
    s.push(ext);
    s.into()
}

/// Read a whole file, mapping the error to [`Error::Io`] naming the path.
pub(crate) fn read_bytes(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|e| Error::io(path, e))
}

/// Write `path` atomically: `f` writes into a temporary file `.NAME.PID.N.tmp` in the same
/// directory (created new, so never through a symbolic link), which is then renamed over
/// `path` (replacing a link there rather than writing through it). On any error, the final
/// flush's included, the temporary file is removed and `path` is left as it was; a process
/// killed in between leaves the temporary file to [`sweep_temporaries`]. (Atomic for
/// readers; the data is not fsynced.)
pub fn write_atomic(
    path: &Path,
    f: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let name = path.file_name().ok_or_else(|| {
        Error::io(
            path,
            std::io::Error::new(std::io::ErrorKind::InvalidInput, "not a file path"),
        )
    })?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let tmp = dir.join(format!(
        ".{}.{}.{}.tmp",
        name.to_string_lossy(),
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let res = (|| {
        let file = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp)?;
        let mut w = std::io::BufWriter::new(file);
        f(&mut w)?;
        w.flush()?;
        drop(w);
        std::fs::rename(&tmp, path)
    })();
    res.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::io(path, e)
    })
}

/// An advisory lock on an output directory: the file `.raisov.lock` in it, locked
/// exclusively (`flock` on Unix, `LockFileEx` on Windows) for as long as the value lives.
/// The kernel drops the lock when the process dies, however it dies; the file itself stays.
#[derive(Debug)]
pub struct OutputLock {
    _file: std::fs::File,
    path: std::path::PathBuf,
}

impl OutputLock {
    /// The lock file's name inside the directory.
    pub const FILE: &'static str = ".raisov.lock";

    /// Lock `dir` (created if missing). Errors, naming the directory and the lock file, when
    /// another process holds it.
    pub fn acquire(dir: &Path) -> Result<OutputLock> {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        let path = dir.join(Self::FILE);
        let file = std::fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&path)
            .map_err(|e| Error::io(&path, e))?;
        match file.try_lock() {
            Ok(()) => Ok(OutputLock { _file: file, path }),
            Err(std::fs::TryLockError::WouldBlock) => Err(Error::io(
                &path,
                std::io::Error::new(
                    std::io::ErrorKind::WouldBlock,
                    format!(
                        "another run is writing to the output directory {} (it holds the lock \
                         file {}); wait for it, or give this run another directory (`--out`)",
                        dir.display(),
                        path.display()
                    ),
                ),
            )),
            Err(std::fs::TryLockError::Error(e)) => Err(Error::io(&path, e)),
        }
    }

    /// The lock file.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

/// What every reader produces before the common post-processing in [`finish`].
#[derive(Default, Debug)]
pub(crate) struct RawMesh {
    /// Node positions in file order.
    pub nodes: Vec<[f64; 3]>,
    /// The id each node has in the file (for messages).
    pub node_ids: Vec<u64>,
    /// Tetrahedra, 4 node indices (into `nodes`) each.
    pub tets: Vec<u32>,
    /// Their ids in the file.
    pub tet_ids: Vec<u64>,
    /// Triangles, 3 node indices each.
    pub tris: Vec<u32>,
    pub tri_ids: Vec<u64>,
    /// Named node sets, indices into `nodes` (any order, duplicates allowed).
    pub groups: BTreeMap<String, Vec<u32>>,
}

impl RawMesh {
    /// Add a node with file id `id`; returns its index. Duplicate ids are the caller's
    /// business (see [`NodeIndex`]).
    pub fn push_node(&mut self, id: u64, p: [f64; 3]) -> u32 {
        self.nodes.push(p);
        self.node_ids.push(id);
        (self.nodes.len() - 1) as u32
    }
}

/// Map from file node ids to node indices.
#[derive(Default, Debug)]
pub(crate) struct NodeIndex {
    map: HashMap<u64, u32>,
}

impl NodeIndex {
    /// Register id -> index; false if the id was already there.
    pub fn insert(&mut self, id: u64, index: u32) -> bool {
        self.map.insert(id, index).is_none()
    }
    pub fn get(&self, id: u64) -> Option<u32> {
        self.map.get(&id).copied()
    }
}

/// Common post-processing: choose the element kind, drop unused nodes, renumber groups,
/// orient, check for degenerate elements.
pub(crate) fn finish(raw: RawMesh, path: &Path, format: &'static str) -> Result<LoadedMesh> {
    let bad = |msg: String| Error::BadMesh {
        path: path.to_path_buf(),
        msg,
    };
    let (kind, cells, elem_ids) = if !raw.tets.is_empty() {
        (ElementKind::Tet4, raw.tets, raw.tet_ids)
    } else if !raw.tris.is_empty() {
        (ElementKind::Tri3, raw.tris, raw.tri_ids)
    } else {
        return Err(bad(format!(
            "no triangles or tetrahedra in the file ({} nodes)",
            raw.nodes.len()
        )));
    };
    let n = raw.nodes.len();
    let mut used = vec![false; n];
    for &c in &cells {
        let c = c as usize;
        if c >= n {
            // Readers check ids; this guards against a reader bug.
            return Err(bad(format!("element refers to node index {c} of {n}")));
        }
        used[c] = true;
    }
    let mut new_index = vec![u32::MAX; n];
    let mut old_of_new: Vec<u32> = Vec::new();
    for (i, _) in used.iter().enumerate().filter(|(_, &u)| u) {
        new_index[i] = old_of_new.len() as u32;
        old_of_new.push(i as u32);
    }
    let nodes: Vec<[f64; 3]> = old_of_new.iter().map(|&o| raw.nodes[o as usize]).collect();
    let cells: Vec<u32> = cells.iter().map(|&c| new_index[c as usize]).collect();
    let groups = raw
        .groups
        .into_iter()
        .map(|(name, members)| {
            let mut v: Vec<u32> = members
                .into_iter()
                .filter_map(|m| new_index.get(m as usize).copied())
                .filter(|&m| m != u32::MAX)
                .collect();
            v.sort_unstable();
            v.dedup();
            (name, v)
        })
        .collect();
    let mut mesh = Mesh {
        kind,
        nodes,
        cells,
        groups,
    };
    let reoriented = mesh.orient().reoriented;
    if let Some(&e) = mesh.degenerate_elements().first() {
        let file_nodes: Vec<String> = mesh
            .element(e)
            .iter()
            .map(|&v| raw.node_ids[old_of_new[v as usize] as usize].to_string())
            .collect();
        let what = match kind {
            ElementKind::Tri3 => "area",
            ElementKind::Tet4 => "volume",
        };
        return Err(bad(format!(
            "degenerate {} {e} (id {} in the file, nodes {}): {what} {:e}, longest edge {:e}",
            kind.name(),
            elem_ids.get(e).copied().unwrap_or(e as u64),
            file_nodes.join(" "),
            mesh.element_measure(e),
            mesh.element_max_edge(e),
        )));
    }
    let node_ids = old_of_new
        .iter()
        .map(|&o| raw.node_ids[o as usize])
        .collect();
    Ok(LoadedMesh {
        node_ids,
        element_ids: elem_ids,
        unused_nodes_dropped: n - mesh.nodes.len(),
        mesh,
        format,
        reoriented,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn missing_file_names_path() {
        let dir = tempfile::tempdir().unwrap();
        for name in ["nope.msh", "nope.vtk", "nope.node"] {
            let p = dir.path().join(name);
            let e = load_mesh(&p).unwrap_err();
            assert!(matches!(e, Error::Io { .. }), "{e}");
            assert!(e.to_string().contains(name), "{e}");
        }
    }

    #[test]
    fn unknown_extension_lists_valid_ones() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("mesh.stl");
        std::fs::write(&p, "solid x\n").unwrap();
        let e = load_mesh(&p).unwrap_err().to_string();
        assert!(
            e.contains("`.stl`") && e.contains(".msh") && e.contains(".vtk"),
            "{e}"
        );
        assert!(e.contains(".node") && e.contains(".ele"), "{e}");
    }

    #[test]
    fn degenerate_element_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("flat.msh");
        std::fs::write(
            &p,
            "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n5\n1 0 0 0\n2 1 0 0\n3 0 1 0\n\
             4 0 0 1\n5 1 1 0\n$EndNodes\n$Elements\n2\n7 4 2 1 1 1 2 3 4\n8 4 2 1 1 1 2 3 5\n\
             $EndElements\n",
        )
        .unwrap();
        let e = load_mesh(&p).unwrap_err();
        assert!(matches!(e, Error::BadMesh { .. }), "{e}");
        let s = e.to_string();
        assert!(s.contains("degenerate tetrahedron 1"), "{s}");
        assert!(s.contains("id 8") && s.contains("nodes 1 2 3 5"), "{s}");
        assert!(s.contains("volume ") && s.contains("0e0"), "{s}");
    }

    #[test]
    fn output_lock_excludes_a_second_holder() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("run");
        let a = OutputLock::acquire(&out).unwrap();
        let e = OutputLock::acquire(&out).unwrap_err().to_string();
        assert!(
            e.contains("another run") && e.contains(OutputLock::FILE),
            "{e}"
        );
        assert!(e.contains(&out.display().to_string()), "{e}");
        drop(a);
        OutputLock::acquire(&out).unwrap();
    }

    #[test]
    fn write_atomic_replaces_and_cleans_up() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("out.txt");
        write_atomic(&p, |w| w.write_all(b"one")).unwrap();
        write_atomic(&p, |w| w.write_all(b"two")).unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "two");
        let e = write_atomic(&p, |w| {
            w.write_all(b"three")?;
            Err(std::io::Error::other("boom"))
        })
        .unwrap_err();
        assert!(e.to_string().contains("boom"), "{e}");
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "two");
        let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(names.len(), 1, "temporary file left behind");
    }

    #[test]
    fn unused_nodes_dropped_and_groups_renumbered() {
        let mut raw = RawMesh::default();
        for (i, p) in [
            [9.0, 9.0, 9.0],
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
        ]
        .into_iter()
        .enumerate()
        {
            raw.push_node(i as u64 + 1, p);
        }
        raw.tris = vec![1, 3, 2]; // clockwise seen from +z: gets flipped
        raw.tri_ids = vec![1];
        raw.groups.insert("g".into(), vec![0, 2, 2]);
        let l = finish(raw, Path::new("x"), "test").unwrap();
        assert_eq!(l.unused_nodes_dropped, 1);
        assert_eq!(l.node_ids, vec![2, 3, 4]);
        assert_eq!(l.mesh.nodes.len(), 3);
        assert_eq!(l.mesh.groups["g"], vec![1]);
        assert_eq!(l.reoriented, vec![0]);
        assert_eq!(l.mesh.cells, vec![0, 1, 2]);
    }
}
