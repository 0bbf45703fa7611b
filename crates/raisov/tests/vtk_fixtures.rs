//! VTU and legacy VTK files written by other programs (meshio 5.3, VTK 9.7; see
//! `tests/data/vtk/make_fixtures.py`, which regenerates them) read to the exact points and
//! cells they were written from; raisov's own frames read back to the same points, cells and
//! fields, bit for bit and the same bytes on any thread count; broken files give errors that
//! name the file and the fault.

use std::path::{Path, PathBuf};

use raisov::io::{load_mesh, read_vtu_array, write_vtu, write_vtu_as, Field, FieldData, VtuFormat};
use raisov::mesh::{ElementKind, Mesh};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/vtk")
        .join(name)
}

/// The points and cells of `expected_*.txt` (floats in shortest round-trip text).
fn expected(name: &str) -> (Vec<[f64; 3]>, Vec<u32>) {
    let text = std::fs::read_to_string(data(name)).unwrap();
    let mut lines = text.lines();
    let np: usize = lines
        .next()
        .unwrap()
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    let pts = (0..np)
        .map(|_| {
            let v: Vec<f64> = lines
                .next()
                .unwrap()
                .split(' ')
                .map(|t| t.parse().unwrap())
                .collect();
            [v[0], v[1], v[2]]
        })
        .collect();
    let nc: usize = lines
        .next()
        .unwrap()
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    let cells: Vec<u32> = lines
        .take(nc)
        .flat_map(|l| {
            l.split(' ')
                .map(|t| t.parse::<u32>().unwrap())
                .collect::<Vec<_>>()
        })
        .collect();
    (pts, cells)
}

/// Load `path` and compare with the expected mesh: connectivity exactly, coordinates bit
/// for bit (`digits` = None) or to the relative precision of the `digits` significant digits
/// the writer printed.
fn assert_close(
    path: &Path,
    kind: ElementKind,
    pts: &[[f64; 3]],
    cells: &[u32],
    digits: Option<i32>,
) -> &'static str {
    let l = load_mesh(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(l.mesh.kind, kind, "{}", path.display());
    assert_eq!(l.unused_nodes_dropped, 0, "{}", path.display());
    assert!(
        l.reoriented.is_empty(),
        "{}: {:?}",
        path.display(),
        l.reoriented
    );
    match digits {
        None => {
            let bits = |p: &[[f64; 3]]| -> Vec<u64> {
                p.as_flattened().iter().map(|x| x.to_bits()).collect()
            };
            assert_eq!(bits(&l.mesh.nodes), bits(pts), "{}", path.display());
        }
        Some(d) => {
            let tol = 0.5 * 10f64.powi(1 - d);
            for (a, b) in l.mesh.nodes.as_flattened().iter().zip(pts.as_flattened()) {
                assert!(
                    (a - b).abs() <= tol * b.abs(),
                    "{}: {a} vs {b}",
                    path.display()
                );
            }
            assert_eq!(l.mesh.nodes.len(), pts.len());
        }
    }
    assert_eq!(l.mesh.cells, cells, "{}", path.display());
    l.format
}

fn assert_same(path: &Path, kind: ElementKind, pts: &[[f64; 3]], cells: &[u32]) -> &'static str {
    assert_close(path, kind, pts, cells, None)
}

#[test]
fn vtu_and_vtk_from_meshio_and_vtk_read_exactly() {
    let (pts, tets) = expected("expected_tet.txt");
    assert_eq!((pts.len(), tets.len()), (12, 48));
    // Writers that print fewer digits than round-trip: meshio's .vtu ASCII (12 significant
    // digits), VTK's legacy ASCII (11).
    for (file, format, digits) in [
        ("meshio_ascii.vtu", "vtu ascii", 12),
        ("vtk_51_ascii.vtk", "vtk legacy ascii", 11),
    ] {
        let got = assert_close(&data(file), ElementKind::Tet4, &pts, &tets, Some(digits));
        assert_eq!(got, format, "{file}");
    }
    for (file, format) in [
        ("meshio_base64.vtu", "vtu binary"),
        ("meshio_base64_u64.vtu", "vtu binary"),
        ("meshio_base64_zlib.vtu", "vtu binary zlib"),
        ("meshio_base64_zlib_u64.vtu", "vtu binary zlib"),
        ("vtk_ascii.vtu", "vtu ascii"),
        ("vtk_binary.vtu", "vtu binary"),
        ("vtk_binary_zlib.vtu", "vtu binary zlib"),
        ("vtk_appended_raw.vtu", "vtu appended"),
        ("vtk_appended_raw_zlib.vtu", "vtu appended zlib"),
        ("vtk_appended_base64.vtu", "vtu appended"),
        ("vtk_appended_base64_zlib.vtu", "vtu appended zlib"),
        ("meshio_51_ascii.vtk", "vtk legacy ascii"),
        ("meshio_51_binary.vtk", "vtk legacy binary"),
        ("meshio_42_binary.vtk", "vtk legacy binary"),
        ("vtk_51_binary.vtk", "vtk legacy binary"),
    ] {
        let got = assert_same(&data(file), ElementKind::Tet4, &pts, &tets);
        assert_eq!(got, format, "{file}");
    }
    let (pts, tris) = expected("expected_tri.txt");
    for file in ["meshio_tri_zlib.vtu", "meshio_tri_51_binary.vtk"] {
        assert_same(&data(file), ElementKind::Tri3, &pts, &tris);
    }
}

#[test]
fn fields_of_other_writers_read_exactly() {
    // make_fixtures.py: u = arange(3 n) * 1e-4 as Float64.
    let want: Vec<f64> = (0..36).map(|i| i as f64 * 1e-4).collect();
    for file in [
        "meshio_base64_zlib.vtu",
        "vtk_appended_raw_zlib.vtu",
        "vtk_appended_base64.vtu",
        "vtk_ascii.vtu",
    ] {
        let (k, u) = read_vtu_array(&data(file), "u").unwrap();
        assert_eq!((k, &u), (3, &want), "{file}");
    }
    let e = read_vtu_array(&data("vtk_binary.vtu"), "nope")
        .unwrap_err()
        .to_string();
    assert!(e.contains("vtk_binary.vtu") && e.contains("`nope`"), "{e}");
}

fn box_mesh() -> Mesh {
    raisov::mesh::generate::box_tets(
        [0.1, 0.03, 0.02],
        [30, 9, 6],
        raisov::mesh::generate::BoxPattern::Six,
    )
    .unwrap()
}

/// Write `mesh` with displacement, velocity, stress, integer ids and a cell field.
fn write_frame(
    path: &Path,
    m: &Mesh,
    format: VtuFormat,
) -> (Vec<f64>, Vec<f64>, Vec<i64>, Vec<f64>) {
    let n = m.num_nodes();
    let u: Vec<f64> = (0..3 * n).map(|i| (i as f64 * 0.37).sin() * 1e-3).collect();
    let s: Vec<f64> = (0..9 * n).map(|i| (i as f64).sqrt() * -1.5e3).collect();
    let ids: Vec<i64> = (0..n as i64).rev().collect();
    let j: Vec<f64> = (0..m.num_elements())
        .map(|e| 1.0 + e as f64 / 7e3)
        .collect();
    write_vtu_as(
        path,
        m,
        &m.nodes,
        &[
            Field {
                name: "displacement",
                data: FieldData::Vector(&u),
            },
            Field {
                name: "stress",
                data: FieldData::Tensor(&s),
            },
            Field {
                name: "file_node_id",
                data: FieldData::Int(&ids),
            },
        ],
        &[Field {
            name: "J",
            data: FieldData::Scalar(&j),
        }],
        format,
    )
    .unwrap();
    (u, s, ids, j)
}

#[test]
fn raisov_frames_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let m = box_mesh();
    assert!(
        m.num_nodes() * 72 > 2 * raisov::io::vtu::VTU_BLOCK_SIZE,
        "several blocks"
    );
    for (format, name) in [
        (VtuFormat::Binary, "vtu appended zlib"),
        (VtuFormat::Ascii, "vtu ascii"),
    ] {
        let p = dir.path().join(format!("f_{}.vtu", format.name()));
        let (u, s, ids, j) = write_frame(&p, &m, format);
        let got = assert_same(&p, ElementKind::Tet4, &m.nodes, &m.cells);
        assert_eq!(got, name);
        let bits = |v: &[f64]| -> Vec<u64> { v.iter().map(|x| x.to_bits()).collect() };
        let (k, u2) = read_vtu_array(&p, "displacement").unwrap();
        assert_eq!((k, bits(&u2)), (3, bits(&u)));
        let (k, s2) = read_vtu_array(&p, "stress").unwrap();
        assert_eq!((k, bits(&s2)), (9, bits(&s)));
        let (k, i2) = read_vtu_array(&p, "file_node_id").unwrap();
        assert_eq!(
            (k, i2),
            (1, ids.iter().map(|&i| i as f64).collect::<Vec<_>>())
        );
        let (k, j2) = read_vtu_array(&p, "J").unwrap();
        assert_eq!((k, bits(&j2)), (1, bits(&j)));
        let text = std::fs::read(&p).unwrap();
        let head = String::from_utf8_lossy(&text).to_string();
        assert!(
            head.contains("<PointData Vectors=\"displacement\">"),
            "{head}"
        );
        assert!(
            head.contains("type=\"Int64\" Name=\"file_node_id\""),
            "{head}"
        );
        if format == VtuFormat::Binary {
            assert!(
                head.contains("header_type=\"UInt64\" compressor=\"vtkZLibDataCompressor\""),
                "{head}"
            );
            assert!(head.contains("<AppendedData encoding=\"raw\">"), "{head}");
        }
    }
    // The binary frame is much smaller than the ASCII one.
    let size = |f: &str| std::fs::metadata(dir.path().join(f)).unwrap().len();
    assert!(size("f_binary.vtu") * 2 < size("f_ascii.vtu"));
}

#[test]
fn binary_frames_are_the_same_bytes_on_any_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let m = box_mesh();
    let mut files = Vec::new();
    for threads in [1, 3] {
        let p = dir.path().join(format!("t{threads}.vtu"));
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| write_frame(&p, &m, VtuFormat::Binary));
        files.push(std::fs::read(&p).unwrap());
    }
    assert!(files[0] == files[1], "bytes differ between 1 and 3 threads");
    // The default of write_vtu is the binary layout.
    let p = dir.path().join("d.vtu");
    write_vtu(&p, &m, &m.nodes, &[], &[]).unwrap();
    assert!(String::from_utf8_lossy(&std::fs::read(&p).unwrap()).contains("format=\"appended\""));
}

/// The error of loading `bytes` saved as `name`: must name the file and contain `want`.
fn load_err(dir: &Path, name: &str, bytes: &[u8], want: &str) {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    let e = match load_mesh(&p) {
        Ok(_) => panic!("{name}: read without error"),
        Err(e) => e.to_string(),
    };
    assert!(e.contains(name) && e.contains(want), "{name}: {e}");
}

fn replace(b: &[u8], from: &str, to: &str) -> Vec<u8> {
    let pos = b
        .windows(from.len())
        .position(|w| w == from.as_bytes())
        .unwrap_or_else(|| panic!("no {from}"));
    let mut o = b[..pos].to_vec();
    o.extend_from_slice(to.as_bytes());
    o.extend_from_slice(&b[pos + from.len()..]);
    o
}

#[test]
fn broken_files_are_named_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let raw = std::fs::read(data("vtk_appended_raw_zlib.vtu")).unwrap();
    let b64 = std::fs::read(data("meshio_base64_zlib.vtu")).unwrap();
    let plain = std::fs::read(data("meshio_base64.vtu")).unwrap();
    let ascii = std::fs::read(data("meshio_ascii.vtu")).unwrap();
    let leg = std::fs::read(data("meshio_51_binary.vtk")).unwrap();
    // Truncations anywhere before the end of what the mesh needs (`</VTKFile>`, the legacy
    // `POINT_DATA`) never panic and always name the file.
    let end_of_cells = leg.windows(10).position(|w| w == b"POINT_DATA").unwrap() - 1;
    for (name, b, end) in [
        ("raw.vtu", &raw, raw.len() - 12),
        ("b64.vtu", &b64, b64.len() - 12),
        ("plain.vtu", &plain, plain.len() - 12),
        ("leg.vtk", &leg, end_of_cells),
    ] {
        for cut in (1..end).step_by(5) {
            let p = d.join(name);
            std::fs::write(&p, &b[..cut]).unwrap();
            let e = load_mesh(&p).expect_err(name).to_string();
            assert!(e.contains(name), "{name} cut at {cut}: {e}");
        }
    }
    // Cut inside the appended data, the closing tag kept: the arrays run past the end.
    let close = raw
        .windows(15)
        .rposition(|w| w == b"</AppendedData>")
        .unwrap();
    let mut cut = raw[..close - 400].to_vec();
    cut.extend_from_slice(&raw[close..]);
    load_err(d, "cut.vtu", &cut, "truncated");
    // Sizes that disagree with the header or the piece.
    load_err(
        d,
        "np.vtu",
        &replace(&ascii, "NumberOfPoints=\"12\"", "NumberOfPoints=\"13\""),
        "`Points` holds 36 values; expected 39",
    );
    load_err(
        d,
        "nc.vtu",
        &replace(&raw, "NumberOfCells=\"14\"", "NumberOfCells=\"15\""),
        "`offsets` holds 14 values; expected 15 or 16",
    );
    load_err(
        d,
        "hdr.vtu",
        &replace(&raw, "header_type=\"UInt64\"", "header_type=\"UInt32\""),
        "",
    );
    // A corrupted zlib block.
    let mut bad = raw.clone();
    let open = raw.windows(13).position(|w| w == b"<AppendedData").unwrap();
    // `_`, then the `Points` array at offset 245: its 32-byte header, then its zlib stream.
    let at = open + raw[open..].iter().position(|&c| c == b'_').unwrap() + 1 + 245 + 32 + 20;
    bad[at] ^= 0xff;
    bad[at + 1] ^= 0xff;
    load_err(d, "zlib.vtu", &bad, "`Points`: zlib block 0 of 1");
    // Unknown and unsupported cell types.
    let types = "Name=\"types\" format=\"ascii\">\n10\n";
    for (name, t, want) in [
        ("t99.vtu", "99", "unknown cell type 99 (cell 0)"),
        ("t12.vtu", "12", "cell 0 has type 12 (hexahedron)"),
    ] {
        load_err(
            d,
            name,
            &replace(&ascii, types, &types.replace("10", t)),
            want,
        );
    }
    load_err(
        d,
        "lz4.vtu",
        &replace(&b64, "vtkZLibDataCompressor", "vtkLZ4DataCompressor"),
        "vtkLZ4DataCompressor",
    );
    load_err(
        d,
        "poly.vtu",
        &replace(&ascii, "UnstructuredGrid\"", "PolyData\""),
        "\"UnstructuredGrid\"",
    );
    load_err(
        d,
        "conn.vtu",
        &replace(
            &ascii,
            "Name=\"connectivity\" format=\"ascii\">\n0\n",
            "Name=\"connectivity\" format=\"ascii\">\n50\n",
        ),
        "is point 50, but the piece has 12 points",
    );
    load_err(
        d,
        "xml.vtu",
        &replace(&ascii, "</Points>", "</Pints>"),
        "malformed XML",
    );
    load_err(
        d,
        "b64bad.vtu",
        &replace(&plain, "format=\"binary\">\n", "format=\"binary\">\n!!!!"),
        "base64",
    );
    // Legacy 5.1 binary: cell list size wrong.
    load_err(
        d,
        "l51.vtk",
        &replace(&leg, "CELLS 15 54", "CELLS 15 55"),
        "`OFFSETS` must start at 0 and end at 55",
    );
}
