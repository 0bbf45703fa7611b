use super::*;
use crate::io::load_mesh;

const LIVER: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../data/liver_L3.msh");

fn write(dir: &Path, name: &str, content: &[u8]) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, content).unwrap();
    p
}

fn line_of(e: &Error) -> Option<usize> {
    match e {
        Error::MeshFormat { line, .. } => *line,
        _ => panic!("not a format error: {e}"),
    }
}

fn two_tets() -> Mesh {
    let mut m = Mesh::new(
        ElementKind::Tet4,
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [1.0, 1.0, 1.0 / 3.0],
        ],
        vec![0, 1, 2, 3, 1, 2, 3, 4],
    );
    m.orient();
    m.groups.insert("fixed".into(), vec![0, 1]);
    m.groups.insert("load \"top\"".into(), vec![4]);
    m
}

#[test]
fn msh22_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("m.msh");
    let m = two_tets();
    write_msh22(&p, &m).unwrap();
    let l = load_mesh(&p).unwrap();
    assert_eq!(l.format, "gmsh 2.2 ascii");
    assert_eq!(l.mesh.kind, ElementKind::Tet4);
    assert_eq!(l.mesh.nodes, m.nodes);
    assert_eq!(l.mesh.cells, m.cells);
    assert!(l.reoriented.is_empty());
    assert_eq!(l.unused_nodes_dropped, 0);
    assert_eq!(l.mesh.groups["fixed"], vec![0, 1]);
    assert_eq!(l.mesh.groups["load 'top'"], vec![4]);
    assert_eq!(l.mesh.groups["domain"], vec![0, 1, 2, 3, 4]);
}

#[test]
fn write_refuses_nan() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("m.msh");
    let mut m = two_tets();
    m.nodes[2][1] = f64::NAN;
    let e = write_msh22(&p, &m).unwrap_err();
    assert!(matches!(e, Error::Param { .. }), "{e}");
    assert!(!p.exists());
}

#[test]
fn reads_liver() {
    let l = load_mesh(Path::new(LIVER)).unwrap();
    assert_eq!(l.format, "gmsh 2.2 ascii");
    assert_eq!(l.mesh.kind, ElementKind::Tet4);
    assert_eq!(l.mesh.num_nodes(), 2088);
    assert_eq!(l.mesh.num_elements(), 8429);
    assert_eq!(l.unused_nodes_dropped, 0);
    assert_eq!(l.mesh.groups["boundary"].len(), 1252);
    assert_eq!(l.mesh.groups["volume"].len(), 2088);
    assert!(l.mesh.total_measure() > 0.0);
    assert_eq!(l.mesh.boundary_nodes(), l.mesh.groups["boundary"]);
}

#[test]
fn msh22_lower_dim_only_feed_groups_and_unused_dropped() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(
        dir.path(),
        "a.msh",
        b"$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Comments\nanything\n$EndComments\n\
          $Nodes\n5\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n9 5 5 5\n$EndNodes\n\
          $Elements\n4\n1 15 2 7 1 9\n2 2 2 3 1 1 2 3\n3 1 0 2 4\n4 4 2 0 1 1 3 2 4\n\
          $EndElements\n",
    );
    let l = load_mesh(&p).unwrap();
    assert_eq!(l.mesh.num_elements(), 1);
    assert_eq!(l.reoriented, vec![0]);
    assert_eq!(l.unused_nodes_dropped, 1);
    assert_eq!(l.mesh.groups["physical 3"], vec![0, 1, 2]);
    // Group member dropped with its unused node; the group stays.
    assert_eq!(l.mesh.groups["physical 7"], Vec::<u32>::new());
    assert_eq!(l.mesh.groups.len(), 2);
}

#[test]
fn msh22_triangles_only_give_membrane() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(
        dir.path(),
        "t.msh",
        b"$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 1 1 0\n\
          4 0 1 0\n$EndNodes\n$Elements\n3\n1 2 0 1 2 3\n2 2 0 1 3 4\n3 1 0 1 2\n$EndElements\n",
    );
    let l = load_mesh(&p).unwrap();
    assert_eq!(l.mesh.kind, ElementKind::Tri3);
    assert_eq!(l.mesh.num_elements(), 2);
    assert!(l.mesh.groups.is_empty());
}

#[test]
fn msh22_errors_name_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let head = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n\
                3 0 1 0\n4 0 0 1\n$EndNodes\n";
    let cases: &[(&str, usize, &str)] = &[
        (
            "$Elements\n1\n1 4 2 1 1 1 2 3\n$EndElements\n",
            13,
            "expected 4 node ids for element type 4 after 2 tags, found 3",
        ),
        (
            "$Elements\n1\n1 4 2 1 1 1 2 3 7\n$EndElements\n",
            13,
            "refers to node 7",
        ),
        (
            "$Elements\n1\n1 4 2 1 1 1 2 3 x\n$EndElements\n",
            13,
            "expected a node id, found `x`",
        ),
        (
            "$Elements\n2\n1 4 2 1 1 1 2 3 4\n",
            14,
            "unexpected end of file",
        ),
        (
            "$Elements\n1\n1 99 0 1\n$EndElements\n",
            13,
            "unknown element type 99",
        ),
        (
            "$Elements\n1\n1 4 2 1 1 1 2 3 4\n$EndNodes\n",
            14,
            "expected `$EndElements`",
        ),
    ];
    for (i, (tail, line, msg)) in cases.iter().enumerate() {
        let p = write(
            dir.path(),
            &format!("e{i}.msh"),
            format!("{head}{tail}").as_bytes(),
        );
        let e = load_mesh(&p).unwrap_err();
        let s = e.to_string();
        assert_eq!(line_of(&e), Some(*line), "{s}");
        assert!(s.contains(msg) && s.contains(&format!("e{i}.msh")), "{s}");
    }
    // Bad number in the nodes, truncated nodes, hexahedra.
    let p = write(
        dir.path(),
        "n.msh",
        b"$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n2\n1 0 0 0\n2 1 0.0.1 0\n",
    );
    let e = load_mesh(&p).unwrap_err();
    assert_eq!(line_of(&e), Some(7), "{e}");
    assert!(e.to_string().contains("expected y, found `0.0.1`"), "{e}");
    let p = write(
        dir.path(),
        "tr.msh",
        b"$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n3\n1 0 0 0\n2 1 0 0\n",
    );
    let e = load_mesh(&p).unwrap_err();
    assert_eq!(line_of(&e), Some(8), "{e}");
    assert!(e.to_string().contains("node 3 of 3"), "{e}");
    let p = write(
        dir.path(),
        "nan.msh",
        b"$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n1\n1 0 nan 0\n$EndNodes\n",
    );
    let e = load_mesh(&p).unwrap_err();
    assert_eq!(line_of(&e), Some(6), "{e}");
    let p = write(
        dir.path(),
        "hex.msh",
        format!("{head}$Elements\n1\n1 5 0 1 2 3 4 1 2 3 4\n$EndElements\n").as_bytes(),
    );
    let e = load_mesh(&p).unwrap_err();
    assert_eq!(line_of(&e), Some(13), "{e}");
    assert!(e.to_string().contains("8-node hexahedron"), "{e}");
    let p = write(
        dir.path(),
        "v3.msh",
        b"$MeshFormat\n3.0 0 8\n$EndMeshFormat\n",
    );
    assert!(load_mesh(&p)
        .unwrap_err()
        .to_string()
        .contains("version `3.0`"));
    let p = write(dir.path(), "empty.msh", b"");
    assert!(load_mesh(&p)
        .unwrap_err()
        .to_string()
        .contains("$MeshFormat"));
    let p = write(
        dir.path(),
        "nothing.msh",
        b"$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n0\n$EndNodes\n",
    );
    let e = load_mesh(&p).unwrap_err();
    assert!(matches!(e, Error::BadMesh { .. }), "{e}");
}

const MSH41_ASCII: &str = "$MeshFormat
4.1 0 8
$EndMeshFormat
$PhysicalNames
2
2 5 \"bottom\"
3 6 \"solid body\"
$EndPhysicalNames
$Entities
0 0 1 1
1 0 0 0 1 1 0 1 5 0
1 0 0 0 1 1 1 1 6 0
$EndEntities
$Nodes
2 5 1 5
2 1 0 3
1
2
3
0 0 0
1 0 0
0 1 0
3 1 0 2
4
5
0 0 1
1 1 1
$EndNodes
$Elements
2 3 1 3
2 1 2 1
1 1 2 3
3 1 4 2
2 1 2 3 4
3 2 3 4 5
$EndElements
";

#[test]
fn msh41_ascii() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "a41.msh", MSH41_ASCII.as_bytes());
    let l = load_mesh(&p).unwrap();
    assert_eq!(l.format, "gmsh 4.1 ascii");
    assert_eq!(l.mesh.kind, ElementKind::Tet4);
    assert_eq!(l.mesh.num_nodes(), 5);
    assert_eq!(l.mesh.num_elements(), 2);
    assert_eq!(l.mesh.groups["bottom"], vec![0, 1, 2]);
    assert_eq!(l.mesh.groups["solid body"], vec![0, 1, 2, 3, 4]);
    assert!(l.mesh.total_measure() > 0.0);
}

#[test]
fn msh41_ascii_errors() {
    let dir = tempfile::tempdir().unwrap();
    // Unknown node in an element.
    let bad = MSH41_ASCII.replace("3 2 3 4 5\n", "3 2 3 4 9\n");
    let p = write(dir.path(), "b1.msh", bad.as_bytes());
    let e = load_mesh(&p).unwrap_err().to_string();
    assert!(e.contains("element 3 refers to node 9"), "{e}");
    // Bad number: the line is found from the parser's position.
    let bad = MSH41_ASCII.replace("1 1 1\n", "1 x 1\n");
    let p = write(dir.path(), "b2.msh", bad.as_bytes());
    let e = load_mesh(&p).unwrap_err();
    assert_eq!(line_of(&e), Some(27), "{e}");
    // Truncated.
    let cut = &MSH41_ASCII[..MSH41_ASCII.find("3 1 4 2").unwrap()];
    let p = write(dir.path(), "b3.msh", cut.as_bytes());
    let e = load_mesh(&p).unwrap_err();
    assert!(matches!(e, Error::MeshFormat { .. }), "{e}");
}

/// Build a binary MSH 4.1 file by the format specification.
fn msh41_binary() -> Vec<u8> {
    let mut b: Vec<u8> = Vec::new();
    let sz = |b: &mut Vec<u8>, v: u64| b.extend_from_slice(&v.to_le_bytes());
    let int = |b: &mut Vec<u8>, v: i32| b.extend_from_slice(&v.to_le_bytes());
    let dbl = |b: &mut Vec<u8>, v: f64| b.extend_from_slice(&v.to_le_bytes());
    b.extend_from_slice(b"$MeshFormat\n4.1 1 8\n");
    int(&mut b, 1);
    b.extend_from_slice(b"\n$EndMeshFormat\n");
    b.extend_from_slice(b"$PhysicalNames\n1\n3 7 \"tissue\"\n$EndPhysicalNames\n");
    b.extend_from_slice(b"$Entities\n");
    for n in [0u64, 0, 0, 1] {
        sz(&mut b, n);
    }
    int(&mut b, 1); // volume tag
    for v in [0.0, 0.0, 0.0, 1.0, 1.0, 1.0] {
        dbl(&mut b, v);
    }
    sz(&mut b, 1);
    int(&mut b, 7);
    sz(&mut b, 0);
    b.extend_from_slice(b"\n$EndEntities\n$Nodes\n");
    for n in [1u64, 4, 10, 13] {
        sz(&mut b, n);
    }
    int(&mut b, 3);
    int(&mut b, 1);
    int(&mut b, 0);
    sz(&mut b, 4);
    for t in [10u64, 11, 12, 13] {
        sz(&mut b, t);
    }
    for p in [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ] {
        for v in p {
            dbl(&mut b, v);
        }
    }
    b.extend_from_slice(b"\n$EndNodes\n$Elements\n");
    for n in [1u64, 1, 1, 1] {
        sz(&mut b, n);
    }
    int(&mut b, 3);
    int(&mut b, 1);
    int(&mut b, 4);
    sz(&mut b, 1);
    for t in [1u64, 10, 12, 11, 13] {
        sz(&mut b, t);
    }
    b.extend_from_slice(b"\n$EndElements\n");
    b
}

#[test]
fn msh41_binary_reads() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "b41.msh", &msh41_binary());
    let l = load_mesh(&p).unwrap();
    assert_eq!(l.format, "gmsh 4.1 binary");
    assert_eq!(l.mesh.num_nodes(), 4);
    assert_eq!(l.mesh.num_elements(), 1);
    assert_eq!(l.reoriented, vec![0]);
    assert!((l.mesh.total_measure() - 1.0 / 6.0).abs() < 1e-15);
    assert_eq!(l.mesh.groups["tissue"], vec![0, 1, 2, 3]);
    // Truncated binary: an error, no panic.
    let full = msh41_binary();
    let p = write(dir.path(), "b41t.msh", &full[..full.len() - 30]);
    let e = load_mesh(&p).unwrap_err();
    assert!(matches!(e, Error::MeshFormat { .. }), "{e}");
}

#[test]
fn msh22_binary_reads() {
    let mut b: Vec<u8> = Vec::new();
    let int = |b: &mut Vec<u8>, v: i32| b.extend_from_slice(&v.to_le_bytes());
    b.extend_from_slice(b"$MeshFormat\n2.2 1 8\n");
    int(&mut b, 1);
    b.extend_from_slice(b"\n$EndMeshFormat\n$PhysicalNames\n1\n2 3 \"skin\"\n$EndPhysicalNames\n");
    b.extend_from_slice(b"$Nodes\n4\n");
    for (i, p) in [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ]
    .iter()
    .enumerate()
    {
        int(&mut b, i as i32 + 1);
        for v in p {
            b.extend_from_slice(&f64::to_le_bytes(*v));
        }
    }
    b.extend_from_slice(b"\n$EndNodes\n$Elements\n2\n");
    for v in [2, 1, 2, 1, 3, 3, 1, 2, 3] {
        int(&mut b, v);
    }
    for v in [4, 1, 2, 2, 0, 0, 1, 2, 3, 4] {
        int(&mut b, v);
    }
    b.extend_from_slice(b"\n$EndElements\n");
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "b22.msh", &b);
    let l = load_mesh(&p).unwrap();
    assert_eq!(l.format, "gmsh 2.2 binary");
    assert_eq!(l.mesh.num_elements(), 1);
    assert_eq!(l.mesh.groups["skin"], vec![0, 1, 2]);
    let p = write(dir.path(), "b22t.msh", &b[..b.len() - 25]);
    let e = load_mesh(&p).unwrap_err();
    assert!(e.to_string().contains("unexpected end of file"), "{e}");
}
