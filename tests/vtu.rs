//! The `.vtu`, `.pvtu` files deasim writes read back: every encoding round-trips bit for bit,
//! and the test reader refuses malformed or truncated files with an error naming the file.

mod common;

use common::vtu::{read_pvtu, read_vtu, ReadError, BLOCK};
use deasim::io::vtu::{
    write_pvd, write_pvtu, write_vtu, write_vtu_as, CellType, DataArray, Encoding, VtuError,
    VtuPiece,
};
use std::collections::BTreeMap;
use std::fs;

/// Two unit hexes side by side along x (12 nodes), VTK node order.
fn two_hex_mesh() -> (Vec<[f64; 3]>, Vec<usize>) {
    let mut points = Vec::new();
    for k in 0..2 {
        for j in 0..2 {
            for i in 0..3 {
                points.push([i as f64 * 1e-3, j as f64 * 1e-3, k as f64 * 2.5e-4]);
            }
        }
    }
    let id = |i: usize, j: usize, k: usize| i + 3 * j + 6 * k;
    let mut conn = Vec::new();
    for e in 0..2 {
        conn.extend_from_slice(&[
            id(e, 0, 0),
            id(e + 1, 0, 0),
            id(e + 1, 1, 0),
            id(e, 1, 0),
            id(e, 0, 1),
            id(e + 1, 0, 1),
            id(e + 1, 1, 1),
            id(e, 1, 1),
        ]);
    }
    (points, conn)
}

/// A `.pvtu` index over two one-cell pieces: the reader finds both pieces, in order, with
/// their arrays; an index of another type or without pieces is refused.
#[test]
fn pvtu_index_lists_its_pieces() {
    let tmp = tempfile::Builder::new()
        .prefix("deasim-vtu-pvtu-")
        .tempdir()
        .unwrap();
    let dir = tmp.path();
    let (points, conn) = two_hex_mesh();
    for (r, cell) in conn.chunks(8).enumerate() {
        let phi: Vec<f64> = (0..points.len()).map(|n| (n + r) as f64).collect();
        let j = [1.0 + r as f64];
        let piece = VtuPiece {
            points: &points,
            cell_type: CellType::Hex8,
            connectivity: cell,
            point_data: vec![DataArray {
                name: "potential",
                components: 1,
                values: &phi,
            }],
            cell_data: vec![DataArray {
                name: "J",
                components: 1,
                values: &j,
            }],
        };
        write_vtu(&dir.join(format!("p{r}.vtu")), &piece).unwrap();
    }
    let index = dir.join("all.pvtu");
    let names = vec!["p0.vtu".to_string(), "p1.vtu".to_string()];
    write_pvtu(&index, &names, &[("potential", 1)], &[("J", 1)]).unwrap();
    let text = fs::read_to_string(&index).unwrap();
    assert!(text.contains("PUnstructuredGrid") && text.contains("Name=\"J\""));
    let pieces = read_pvtu(&index).unwrap();
    assert_eq!(pieces.len(), 2);
    for (r, p) in pieces.iter().enumerate() {
        assert_eq!(p.cell_data["J"].1, vec![1.0 + r as f64]);
        assert_eq!(p.point_data["potential"].1[0], r as f64);
    }
    assert!(write_pvtu(&index, &[String::new()], &[], &[]).is_err());
    fs::write(
        dir.join("bad.pvtu"),
        "<VTKFile type=\"UnstructuredGrid\"></VTKFile>",
    )
    .unwrap();
    let e = read_pvtu(&dir.join("bad.pvtu")).unwrap_err().to_string();
    assert!(
        e.contains("bad.pvtu") && e.contains("PUnstructuredGrid"),
        "{e}"
    );
}

/// Values that stress round-tripping: irrational-ish, tiny, huge, negative zero.
fn awkward(n: usize, seed: f64) -> Vec<f64> {
    (0..n)
        .map(|i| match i % 5 {
            0 => (seed + i as f64).sqrt() * std::f64::consts::PI,
            1 => -1.0 / (3.0 + i as f64) * 1e-9,
            2 => 1.234_567_890_123_456_7e300 * seed,
            3 => -0.0,
            _ => f64::MIN_POSITIVE * (i as f64 + seed),
        })
        .collect()
}

fn assert_bits_eq(a: &[f64], b: &[f64]) {
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(b) {
        assert_eq!(x.to_bits(), y.to_bits(), "{x:e} vs {y:e}");
    }
}

#[test]
fn hex_mesh_round_trip_is_exact() {
    let tmp = tempfile::Builder::new()
        .prefix("deasim-vtu-hex-")
        .tempdir()
        .unwrap();
    let dir = tmp.path();
    let path = dir.join("hex.vtu");
    let (points, conn) = two_hex_mesh();
    let disp = awkward(3 * points.len(), 1.0);
    let phi = awkward(points.len(), 2.0);
    let stress = awkward(9 * 2, 3.0);
    let id = [0.0, 1.0];
    let piece = VtuPiece {
        points: &points,
        cell_type: CellType::Hex8,
        connectivity: &conn,
        point_data: vec![
            DataArray {
                name: "displacement",
                components: 3,
                values: &disp,
            },
            DataArray {
                name: "potential <Φ> & \"quotes\"",
                components: 1,
                values: &phi,
            },
        ],
        cell_data: vec![
            DataArray {
                name: "cauchy_stress",
                components: 9,
                values: &stress,
            },
            DataArray {
                name: "element_id",
                components: 1,
                values: &id,
            },
        ],
    };
    write_vtu(&path, &piece).expect("write");
    let data = read_vtu(&path).expect("read");
    assert_eq!(data.points.len(), points.len());
    assert_bits_eq(data.points.as_flattened(), points.as_flattened());
    assert_eq!(data.connectivity, conn);
    assert_eq!(data.offsets, vec![8, 16]);
    assert_eq!(data.types, vec![12, 12]);
    assert_eq!(data.point_data.len(), 2);
    let (c, v) = &data.point_data["displacement"];
    assert_eq!(*c, 3);
    assert_bits_eq(v, &disp);
    let (c, v) = &data.point_data["potential <Φ> & \"quotes\""];
    assert_eq!(*c, 1);
    assert_bits_eq(v, &phi);
    let (c, v) = &data.cell_data["cauchy_stress"];
    assert_eq!(*c, 9);
    assert_bits_eq(v, &stress);
    assert_bits_eq(&data.cell_data["element_id"].1, &id);

    let text = fs::read_to_string(&path).expect("read text");
    assert!(text.contains(
        "<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\" \
         header_type=\"UInt64\">"
    ));
    assert!(text.contains("format=\"binary\""));
    assert!(text.contains("<Piece NumberOfPoints=\"12\" NumberOfCells=\"2\">"));
    assert!(text.contains("Name=\"potential &lt;Φ&gt; &amp; &quot;quotes&quot;\""));
    // the same piece as ASCII reads back to the same bits
    let ascii = dir.join("hex-ascii.vtu");
    write_vtu_as(&ascii, &piece, Encoding::Ascii).expect("write ascii");
    let a = read_vtu(&ascii).expect("read ascii");
    assert_bits_eq(a.points.as_flattened(), data.points.as_flattened());
    assert_eq!(
        (a.connectivity, a.offsets, a.types),
        (data.connectivity, data.offsets, data.types)
    );
    for (name, (c, v)) in &data
        .point_data
        .iter()
        .chain(&data.cell_data)
        .collect::<BTreeMap<_, _>>()
    {
        let other = a
            .point_data
            .get(*name)
            .or(a.cell_data.get(*name))
            .expect("array");
        assert_eq!(other.0, *c);
        assert_bits_eq(&other.1, v);
    }
    let text = fs::read_to_string(&ascii).expect("read text");
    assert!(text.contains(
        "<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">"
    ));
    assert!(!text.contains("nan") && !text.contains("inf"));
}

/// zlib blocks: arrays shorter than, exactly one and several blocks long read back bit for
/// bit; a field of few distinct values compresses; the header of a one-block array is as VTK writes it.
#[test]
fn compressed_arrays_round_trip_and_compress() {
    use base64::Engine as _;
    let tmp = tempfile::Builder::new()
        .prefix("deasim-vtu-zlib-")
        .tempdir()
        .unwrap();
    let dir = tmp.path();
    let (points, conn) = two_hex_mesh();
    // 4096 values of 8 bytes are exactly one 32 KiB block
    for n in [0usize, 5, BLOCK / 8, BLOCK / 8 + 1, 3 * BLOCK / 8 + 7] {
        // few distinct values, as in a uniform region (noise-like mantissas barely compress)
        let smooth: Vec<f64> = (0..n).map(|i| (i % 64) as f64 * 0.25).collect();
        let piece = VtuPiece {
            points: &points,
            cell_type: CellType::Hex8,
            connectivity: &conn,
            point_data: vec![],
            cell_data: vec![DataArray {
                name: "field",
                components: n.max(1) / 2,
                values: &smooth,
            }],
        };
        if n % 2 == 1 || n == 0 {
            continue; // the array must have two cells' worth of tuples
        }
        let z = dir.join(format!("z{n}.vtu"));
        let b = dir.join(format!("b{n}.vtu"));
        write_vtu_as(&z, &piece, Encoding::Compressed).expect("write compressed");
        write_vtu_as(&b, &piece, Encoding::Binary).expect("write binary");
        let (dz, db) = (read_vtu(&z).expect("read z"), read_vtu(&b).expect("read b"));
        assert_bits_eq(&dz.cell_data["field"].1, &smooth);
        assert_bits_eq(dz.points.as_flattened(), db.points.as_flattened());
        assert_eq!(dz.connectivity, db.connectivity);
        let text = fs::read_to_string(&z).unwrap();
        assert!(text.contains("compressor=\"vtkZLibDataCompressor\""));
        if n >= BLOCK / 8 {
            let (sz, sb) = (
                fs::metadata(&z).unwrap().len(),
                fs::metadata(&b).unwrap().len(),
            );
            assert!(sz * 2 < sb, "{n}: {sz} vs {sb}");
        }
    }
    // the header of the one-block "types" array of two hex8 cells: [1, 32768, 2, c]
    let piece = VtuPiece {
        points: &points,
        cell_type: CellType::Hex8,
        connectivity: &conn,
        point_data: vec![],
        cell_data: vec![],
    };
    let z = dir.join("types.vtu");
    write_vtu_as(&z, &piece, Encoding::Compressed).unwrap();
    let text = fs::read_to_string(&z).unwrap();
    let line = text
        .lines()
        .skip_while(|l| !l.contains("Name=\"types\""))
        .nth(1)
        .unwrap()
        .trim();
    let head = base64::engine::general_purpose::STANDARD
        .decode(&line[..44])
        .unwrap();
    let word = |i: usize| u64::from_le_bytes(head[8 * i..8 * i + 8].try_into().unwrap());
    assert_eq!((word(0), word(1), word(2)), (1, BLOCK as u64, 2));
    let data = base64::engine::general_purpose::STANDARD
        .decode(&line[44..])
        .unwrap();
    assert_eq!(data.len() as u64, word(3));
    let mut out = Vec::new();
    use std::io::Read as _;
    flate2::read::ZlibDecoder::new(&data[..])
        .read_to_end(&mut out)
        .unwrap();
    assert_eq!(out, vec![12u8, 12]);
    // every truncation and a header that lies are errors, not panics
    let full = fs::read(&z).unwrap();
    let cut = dir.join("cut.vtu");
    for k in (0..full.trim_ascii_end().len()).step_by(7) {
        fs::write(&cut, &full[..k]).unwrap();
        assert!(read_vtu(&cut).is_err(), "truncation at {k} accepted");
    }
    let lying = text.replacen(
        &line[..44],
        "AQAAAAAAAAAAgAAAAAAAAAMAAAAAAAAACgAAAAAAAAA=",
        1,
    );
    fs::write(&cut, lying).unwrap();
    assert!(read_vtu(&cut).is_err());
}

#[test]
fn tet_mesh_round_trip_is_exact() {
    let tmp = tempfile::Builder::new()
        .prefix("deasim-vtu-tet-")
        .tempdir()
        .unwrap();
    let dir = tmp.path();
    let path = dir.join("tet.vtu");
    let points = vec![
        [0.0, 0.0, 0.0],
        [1e-3, 0.0, 0.0],
        [0.0, 1e-3, 0.0],
        [0.0, 0.0, 1e-3],
        [1e-3, 1e-3, 1e-3],
    ];
    let conn = vec![0, 1, 2, 3, 1, 2, 3, 4];
    let u = awkward(15, 4.0);
    let e_field = awkward(6, 5.0);
    let piece = VtuPiece {
        points: &points,
        cell_type: CellType::Tet4,
        connectivity: &conn,
        point_data: vec![DataArray {
            name: "u",
            components: 3,
            values: &u,
        }],
        cell_data: vec![DataArray {
            name: "E",
            components: 3,
            values: &e_field,
        }],
    };
    write_vtu(&path, &piece).expect("write");
    let data = read_vtu(&path).expect("read");
    assert_bits_eq(data.points.as_flattened(), points.as_flattened());
    assert_eq!(data.connectivity, conn);
    assert_eq!(data.offsets, vec![4, 8]);
    assert_eq!(data.types, vec![10, 10]);
    assert_eq!(data.point_data["u"].0, 3);
    assert_bits_eq(&data.point_data["u"].1, &u);
    assert_eq!(data.cell_data["E"].0, 3);
    assert_bits_eq(&data.cell_data["E"].1, &e_field);
}

#[test]
fn tet10_is_vtk_quadratic_tetra() {
    let tmp = tempfile::Builder::new()
        .prefix("deasim-vtu-tet10-")
        .tempdir()
        .unwrap();
    let dir = tmp.path();
    let path = dir.join("tet10.vtu");
    let c = [
        [0.0, 0.0, 0.0],
        [1e-3, 0.0, 0.0],
        [0.0, 1e-3, 0.0],
        [0.0, 0.0, 1e-3],
    ];
    let mut points = c.to_vec();
    for [i, j] in deasim::fem::TET10_EDGES {
        points.push([0, 1, 2].map(|k| 0.5 * (c[i][k] + c[j][k])));
    }
    let conn: Vec<usize> = (0..10).collect();
    let piece = VtuPiece {
        points: &points,
        cell_type: CellType::Tet10,
        connectivity: &conn,
        point_data: vec![],
        cell_data: vec![],
    };
    write_vtu(&path, &piece).expect("write");
    let data = read_vtu(&path).expect("read");
    assert_eq!(data.types, vec![24]);
    assert_eq!(data.offsets, vec![10]);
    assert_eq!(data.connectivity, conn);
    assert_bits_eq(data.points.as_flattened(), points.as_flattened());
}

#[test]
fn empty_mesh_round_trips() {
    let tmp = tempfile::Builder::new()
        .prefix("deasim-vtu-empty-")
        .tempdir()
        .unwrap();
    let dir = tmp.path();
    let path = dir.join("empty.vtu");
    let piece = VtuPiece {
        points: &[],
        cell_type: CellType::Tet4,
        connectivity: &[],
        point_data: vec![],
        cell_data: vec![],
    };
    for encoding in [Encoding::Binary, Encoding::Compressed, Encoding::Ascii] {
        write_vtu_as(&path, &piece, encoding).expect("write");
        let data = read_vtu(&path).expect("read");
        assert!(data.points.is_empty() && data.connectivity.is_empty());
        assert!(data.offsets.is_empty() && data.types.is_empty());
    }
}

#[test]
fn reader_rejects_every_truncation() {
    let tmp = tempfile::Builder::new()
        .prefix("deasim-vtu-trunc-")
        .tempdir()
        .unwrap();
    let dir = tmp.path();
    let path = dir.join("full.vtu");
    let points = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    let conn = vec![0, 1, 2, 3];
    let phi = vec![0.5, 1.5, 2.5, 3.5];
    let piece = VtuPiece {
        points: &points,
        cell_type: CellType::Tet4,
        connectivity: &conn,
        point_data: vec![DataArray {
            name: "phi",
            components: 1,
            values: &phi,
        }],
        cell_data: vec![],
    };
    write_vtu(&path, &piece).expect("write");
    let full = fs::read(&path).expect("read");
    let body_len = full.trim_ascii_end().len();
    let cut_path = dir.join("cut.vtu");
    for cut in 0..body_len {
        fs::write(&cut_path, &full[..cut]).expect("write cut");
        let res = read_vtu(&cut_path);
        assert!(
            matches!(
                res,
                Err(ReadError::Parse { .. }) | Err(ReadError::Io { .. })
            ),
            "truncation at {cut} accepted: {res:?}"
        );
    }
}

#[test]
fn reader_rejects_malformed_input() {
    let tmp = tempfile::Builder::new()
        .prefix("deasim-vtu-malformed-")
        .tempdir()
        .unwrap();
    let dir = tmp.path();
    let path = dir.join("bad.vtu");
    let good_head = "<VTKFile type=\"UnstructuredGrid\" version=\"0.1\"><UnstructuredGrid>\
                     <Piece NumberOfPoints=\"1\" NumberOfCells=\"0\">";
    let good_tail = "<Cells><DataArray type=\"Int64\" Name=\"connectivity\"></DataArray>\
                     <DataArray type=\"Int64\" Name=\"offsets\"></DataArray>\
                     <DataArray type=\"UInt8\" Name=\"types\"></DataArray></Cells>\
                     </Piece></UnstructuredGrid></VTKFile>";
    let ok = format!(
        "{good_head}<Points><DataArray type=\"Float64\" NumberOfComponents=\"3\">\
         1 2 3</DataArray></Points>{good_tail}"
    );
    fs::write(&path, &ok).expect("write");
    let data = read_vtu(&path).expect("minimal file is valid");
    assert_eq!(data.points, vec![[1.0, 2.0, 3.0]]);

    let cases = [
        String::new(),
        "garbage".to_string(),
        "<".to_string(),
        "<VTKFile type=\"PolyData\"></VTKFile>".to_string(),
        ok.replace("1 2 3", "1 2"),
        ok.replace("1 2 3", "1 2 x"),
        ok.replace("1 2 3", "1 2 3 4"),
        ok.replace("</Points>", "</Cells>"),
        ok.replace("NumberOfPoints=\"1\"", "NumberOfPoints=\"-1\""),
        ok.replace("NumberOfPoints=\"1\"", "NumberOfPoints=1"),
        ok.replace(
            "NumberOfComponents=\"3\"",
            "NumberOfComponents=\"3\" format=\"binary\"",
        ),
        ok.replace("NumberOfComponents=\"3\"", "NumberOfComponents=\"0\""),
        ok.replace("Name=\"types\"", "Name=\"typo\""),
        ok.replace("<Points>", "<Points><Foo/>"),
        format!("{ok}<VTKFile/>"),
        ok.replace("Name=\"connectivity\"", "Name=\"&bogus;\""),
        ok.replace("NumberOfCells=\"0\"", "NumberOfCells=\"1\""),
    ];
    for (i, case) in cases.iter().enumerate() {
        fs::write(&path, case).expect("write");
        let res = read_vtu(&path);
        assert!(
            matches!(res, Err(ReadError::Parse { .. })),
            "case {i} accepted: {res:?}"
        );
        let msg = res.expect_err("checked").to_string();
        assert!(msg.contains("bad.vtu"), "{msg}");
    }

    let missing = dir.join("missing.vtu");
    assert!(matches!(read_vtu(&missing), Err(ReadError::Io { .. })));
}

// The writer's own checks: bad input is refused naming the array or the mesh.
#[test]
fn length_mismatch_is_an_error_naming_the_array() {
    let tmp = tempfile::Builder::new()
        .prefix("deasim-vtu-len-")
        .tempdir()
        .unwrap();
    let dir = tmp.path();
    let path = dir.join("bad.vtu");
    let (points, conn) = two_hex_mesh();
    let short = vec![0.0; 3 * points.len() - 1];
    let piece = VtuPiece {
        points: &points,
        cell_type: CellType::Hex8,
        connectivity: &conn,
        point_data: vec![DataArray {
            name: "displacement",
            components: 3,
            values: &short,
        }],
        cell_data: vec![],
    };
    let err = write_vtu(&path, &piece).expect_err("must fail");
    assert!(matches!(err, VtuError::LengthMismatch { .. }), "{err:?}");
    let msg = err.to_string();
    assert!(msg.contains("displacement"), "{msg}");
    assert!(msg.contains("bad.vtu"), "{msg}");
    assert!(!path.exists());

    let cell_vals = vec![1.0; 3];
    let piece = VtuPiece {
        point_data: vec![],
        cell_data: vec![DataArray {
            name: "energy",
            components: 1,
            values: &cell_vals,
        }],
        ..piece
    };
    let msg = write_vtu(&path, &piece).expect_err("must fail").to_string();
    assert!(msg.contains("energy") && msg.contains("cells"), "{msg}");
}

#[test]
fn non_finite_values_are_errors_naming_array_and_index() {
    let tmp = tempfile::Builder::new()
        .prefix("deasim-vtu-nan-")
        .tempdir()
        .unwrap();
    let dir = tmp.path();
    let path = dir.join("nan.vtu");
    let (points, conn) = two_hex_mesh();
    let mut phi = vec![1.0; points.len()];
    phi[7] = f64::NAN;
    let piece = VtuPiece {
        points: &points,
        cell_type: CellType::Hex8,
        connectivity: &conn,
        point_data: vec![DataArray {
            name: "potential",
            components: 1,
            values: &phi,
        }],
        cell_data: vec![],
    };
    match write_vtu(&path, &piece) {
        Err(VtuError::NonFinite { name, index, .. }) => {
            assert_eq!(name, "potential");
            assert_eq!(index, 7);
        }
        other => panic!("expected NonFinite, got {other:?}"),
    }
    assert!(!path.exists());

    let mut bad_points = points.clone();
    bad_points[2][1] = f64::INFINITY;
    let piece = VtuPiece {
        points: &bad_points,
        point_data: vec![],
        ..piece
    };
    match write_vtu(&path, &piece) {
        Err(VtuError::NonFinite { name, index, .. }) => {
            assert_eq!(name, "Points");
            assert_eq!(index, 7);
        }
        other => panic!("expected NonFinite, got {other:?}"),
    }
}

#[test]
fn invalid_mesh_and_names_are_errors() {
    let tmp = tempfile::Builder::new()
        .prefix("deasim-vtu-mesh-")
        .tempdir()
        .unwrap();
    let dir = tmp.path();
    let path = dir.join("m.vtu");
    let (points, conn) = two_hex_mesh();
    let base = VtuPiece {
        points: &points,
        cell_type: CellType::Hex8,
        connectivity: &conn[..12],
        point_data: vec![],
        cell_data: vec![],
    };
    assert!(matches!(
        write_vtu(&path, &base),
        Err(VtuError::InvalidMesh { .. })
    ));
    let mut bad_conn = conn.clone();
    bad_conn[3] = 12;
    let piece = VtuPiece {
        connectivity: &bad_conn,
        ..base.clone()
    };
    assert!(matches!(
        write_vtu(&path, &piece),
        Err(VtuError::InvalidMesh { .. })
    ));
    let vals = vec![0.0; 12];
    let arr = DataArray {
        name: "a",
        components: 1,
        values: &vals,
    };
    let piece = VtuPiece {
        connectivity: &conn,
        point_data: vec![arr, arr],
        ..base.clone()
    };
    assert!(matches!(
        write_vtu(&path, &piece),
        Err(VtuError::InvalidArray { .. })
    ));
    let piece = VtuPiece {
        connectivity: &conn,
        point_data: vec![DataArray { name: "", ..arr }],
        ..base.clone()
    };
    assert!(matches!(
        write_vtu(&path, &piece),
        Err(VtuError::InvalidArray { .. })
    ));
    let piece = VtuPiece {
        connectivity: &conn,
        point_data: vec![DataArray {
            components: 0,
            ..arr
        }],
        ..base
    };
    assert!(matches!(
        write_vtu(&path, &piece),
        Err(VtuError::InvalidArray { .. })
    ));
    assert!(!path.exists());
}

#[test]
fn pvd_content() {
    let tmp = tempfile::Builder::new()
        .prefix("deasim-vtu-pvd-")
        .tempdir()
        .unwrap();
    let dir = tmp.path();
    let path = dir.join("run.pvd");
    let entries = vec![
        (0.0, "run_0000.vtu".to_string()),
        (0.25, "run_0001.vtu".to_string()),
        (1e-9, "steps/run_0002.vtu".to_string()),
        (2.0, "a&b.vtu".to_string()),
    ];
    write_pvd(&path, &entries).expect("write");
    let text = fs::read_to_string(&path).expect("read");
    assert!(text.starts_with("<?xml version=\"1.0\"?>\n"));
    assert!(text.contains("<VTKFile type=\"Collection\" version=\"0.1\""));
    assert!(text.contains("<Collection>") && text.contains("</Collection>"));
    assert!(text.trim_end().ends_with("</VTKFile>"));
    let lines: Vec<&str> = text
        .lines()
        .map(str::trim)
        .filter(|l| l.starts_with("<DataSet"))
        .collect();
    assert_eq!(
        lines,
        vec![
            "<DataSet timestep=\"0\" group=\"\" part=\"0\" file=\"run_0000.vtu\"/>",
            "<DataSet timestep=\"0.25\" group=\"\" part=\"0\" file=\"run_0001.vtu\"/>",
            "<DataSet timestep=\"1e-9\" group=\"\" part=\"0\" file=\"steps/run_0002.vtu\"/>",
            "<DataSet timestep=\"2\" group=\"\" part=\"0\" file=\"a&amp;b.vtu\"/>",
        ]
    );
    let err = write_pvd(&path, &[(f64::NAN, "x.vtu".to_string())]).expect_err("nan time");
    assert!(matches!(err, VtuError::InvalidPvdEntry { index: 0, .. }));
    // The previous file is untouched by the failed write.
    assert_eq!(fs::read_to_string(&path).expect("read"), text);
}

/// A field file's piece from (name, components, values) lists: the arrays in the order
/// given, each a view of its values; written, it reads back with the names and values.
#[test]
fn fields_piece_keeps_the_arrays_in_order() {
    let (points, conn) = two_hex_mesh();
    let u: Vec<f64> = (0..3 * points.len()).map(|i| i as f64).collect();
    let phi = vec![2.5; points.len()];
    let j = vec![1.0, 1.25];
    let piece = VtuPiece::fields(
        &points,
        CellType::Hex8,
        &conn,
        &[("displacement", 3, &u), ("potential", 1, &phi)],
        &[("J", 1, &j)],
    );
    fn names<'a>(a: &[DataArray<'a>]) -> Vec<(&'a str, usize, *const f64)> {
        a.iter()
            .map(|a| (a.name, a.components, a.values.as_ptr()))
            .collect()
    }
    assert_eq!(
        names(&piece.point_data),
        [
            ("displacement", 3, u.as_ptr()),
            ("potential", 1, phi.as_ptr())
        ]
    );
    assert_eq!(names(&piece.cell_data), [("J", 1, j.as_ptr())]);
    assert_eq!(piece.connectivity, conn.as_slice());
    let tmp = tempfile::Builder::new()
        .prefix("deasim-vtu-fields-")
        .tempdir()
        .unwrap();
    let path = tmp.path().join("f.vtu");
    write_vtu_as(&path, &piece, Encoding::Ascii).expect("write");
    let text = fs::read_to_string(&path).expect("read");
    let at = |name: &str| text.find(&format!("Name=\"{name}\"")).expect(name);
    assert!(at("displacement") < at("potential") && at("potential") < at("J"));
    assert!(text.contains("1e0 1.25e0"), "{text}");
}
