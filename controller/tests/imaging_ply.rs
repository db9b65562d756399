//! PLY writer and reader: round trips, the exact header, foreign files, bad input.

use proptest::prelude::*;
use scanhil_controller::imaging::ply::{
    PlyEncoding, PlyError, VERTEX_PROPERTIES, read_ply, read_ply_file, read_point_cloud,
    read_point_cloud_file, write_ply, write_ply_file,
};
use scanhil_controller::imaging::reconstruct::{GeometryModel, PointCloud, ScanPoint};

fn cloud(n: usize, model: GeometryModel) -> PointCloud {
    let points = (0..n)
        .map(|i| {
            let f = i as f64;
            ScanPoint {
                x_mm: 0.1 * f - 3.0,
                y_mm: -0.7 * f + 1.0 / 3.0,
                z_mm: -130.0 - 1e-7 * f,
                t_s: f * 5e-5,
                d_alpha_rad: 1e-3 * f.sin(),
                d_beta_rad: -2e-3 * f.cos(),
                z_meas_mm: 140.0 + f.sqrt(),
            }
        })
        .collect();
    PointCloud { model, points }
}

fn to_bytes(cloud: &PointCloud, encoding: PlyEncoding) -> Vec<u8> {
    let mut out = Vec::new();
    write_ply(&mut out, cloud, encoding).unwrap();
    out
}

const HEADER_BINARY_3: &str = "ply\n\
format binary_little_endian 1.0\n\
comment scanhil point cloud\n\
comment model small_angle\n\
comment units x y z z_meas_mm in millimetres, d_alpha_rad d_beta_rad in radians, t_s in seconds\n\
element vertex 3\n\
property double x\n\
property double y\n\
property double z\n\
property double t_s\n\
property double d_alpha_rad\n\
property double d_beta_rad\n\
property double z_meas_mm\n\
end_header\n";

#[test]
fn binary_header_is_exactly_the_spec_layout_and_rows_are_56_bytes() {
    let bytes = to_bytes(
        &cloud(3, GeometryModel::SmallAngle),
        PlyEncoding::BinaryLittleEndian,
    );
    assert!(bytes.starts_with(HEADER_BINARY_3.as_bytes()));
    assert_eq!(bytes.len(), HEADER_BINARY_3.len() + 3 * 7 * 8);
    // The first value after the header is x of point 0, little-endian.
    let first = f64::from_le_bytes(bytes[HEADER_BINARY_3.len()..][..8].try_into().unwrap());
    assert_eq!(first, -3.0);
}

#[test]
fn ascii_header_snapshot() {
    let bytes = to_bytes(
        &cloud(2, GeometryModel::ExactReflection),
        PlyEncoding::Ascii,
    );
    insta::assert_snapshot!(String::from_utf8(bytes).unwrap());
}

#[test]
fn every_encoding_round_trips_bit_exactly() {
    for encoding in [
        PlyEncoding::Ascii,
        PlyEncoding::BinaryLittleEndian,
        PlyEncoding::BinaryBigEndian,
    ] {
        for model in GeometryModel::ALL {
            let original = cloud(50, model);
            let read = read_ply(&to_bytes(&original, encoding)).unwrap();
            assert_eq!(read.encoding, encoding);
            assert_eq!(
                read.to_point_cloud().unwrap(),
                original,
                "{encoding:?} {model:?}"
            );
            assert_eq!(
                read_point_cloud(&to_bytes(&original, encoding)).unwrap(),
                original,
                "{encoding:?} {model:?}"
            );
        }
    }
}

#[test]
fn file_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("points.ply");
    let original = cloud(10, GeometryModel::SmallAngle);
    write_ply_file(&path, &original, PlyEncoding::BinaryLittleEndian).unwrap();
    let read = read_ply_file(&path).unwrap();
    assert_eq!(read.to_point_cloud().unwrap(), original);
    assert_eq!(read_point_cloud_file(&path).unwrap(), original);
    assert_eq!(read.column("z_meas_mm").unwrap().len(), 10);
}

#[test]
fn reads_a_foreign_mesh_with_floats_lists_and_crlf() {
    let mut bytes = b"ply\r\nformat binary_big_endian 1.0\r\nobj_info made elsewhere\r\n\
element vertex 2\r\nproperty float32 x\r\nproperty float y\r\nproperty float z\r\n\
property uchar red\r\nelement face 1\r\nproperty list uchar int vertex_indices\r\nend_header\r\n"
        .to_vec();
    for (x, y, z, r) in [(1.5f32, -2.0f32, 3.25f32, 200u8), (0.0, 1.0, -1.0, 7)] {
        bytes.extend(x.to_be_bytes());
        bytes.extend(y.to_be_bytes());
        bytes.extend(z.to_be_bytes());
        bytes.push(r);
    }
    bytes.push(3);
    for i in [0i32, 1, 0] {
        bytes.extend(i.to_be_bytes());
    }
    let read = read_ply(&bytes).unwrap();
    assert_eq!(read.property_names, ["x", "y", "z", "red"]);
    assert_eq!(read.count, 2);
    assert_eq!(
        read.rows().collect::<Vec<_>>(),
        [[1.5, -2.0, 3.25, 200.0], [0.0, 1.0, -1.0, 7.0]]
    );
    // Not a scanhil cloud: no model comment.
    let err = read.to_point_cloud().unwrap_err();
    assert!(err.to_string().contains("reconstruction model"), "{err}");
    let err = read_point_cloud(&bytes).unwrap_err();
    assert!(err.to_string().contains("reconstruction model"), "{err}");
}

#[test]
fn truncated_binary_data_names_the_byte_offset() {
    let bytes = to_bytes(
        &cloud(4, GeometryModel::SmallAngle),
        PlyEncoding::BinaryLittleEndian,
    );
    let cut = &bytes[..bytes.len() - 5];
    match read_ply(cut).unwrap_err() {
        PlyError::Data { offset, reason } => {
            assert_eq!(offset, HEADER_BINARY_3.len(), "{reason}");
            assert!(
                reason.contains("4 'vertex' elements of 56 bytes"),
                "{reason}"
            );
        }
        other => panic!("expected a data error, got {other}"),
    }
}

#[test]
fn bad_headers_name_their_line() {
    let cases: [(&[u8], usize, &str); 5] = [
        (b"plx\n", 1, "magic"),
        (b"ply\nformat ascii 2.0\nend_header\n", 2, "version 1.0"),
        (
            b"ply\nformat ascii 1.0\nproperty double x\nend_header\n",
            3,
            "before any element",
        ),
        (
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n",
            4,
            "unknown property type",
        ),
        (
            b"ply\nformat ascii 1.0\nelement vertex 1\n",
            4,
            "before 'end_header'",
        ),
    ];
    for (bytes, line, needle) in cases {
        match read_ply(bytes).unwrap_err() {
            PlyError::Header { line: l, reason } => {
                assert_eq!(l, line, "{reason}");
                assert!(reason.contains(needle), "{reason}");
            }
            other => panic!("expected a header error, got {other}"),
        }
    }
}

#[test]
fn ascii_bad_number_names_its_offset() {
    let text = b"ply\nformat ascii 1.0\nelement vertex 1\nproperty double x\nend_header\n1.0e\n";
    match read_ply(text).unwrap_err() {
        PlyError::Data { offset, reason } => {
            assert_eq!(offset, text.len() - 5);
            assert!(reason.contains("'1.0e' is not a number"), "{reason}");
        }
        other => panic!("expected a data error, got {other}"),
    }
}

#[test]
fn a_vertex_count_beyond_the_data_is_an_error_not_an_allocation() {
    // A count no memory could hold: what is reserved follows the bytes there are.
    let properties: String = VERTEX_PROPERTIES
        .iter()
        .map(|name| format!("property double {name}\n"))
        .collect();
    for format in ["ascii", "binary_little_endian"] {
        let text = format!(
            "ply\nformat {format} 1.0\ncomment model small_angle\nelement vertex {}\n\
             {properties}end_header\n1 2 3\n",
            usize::MAX / 2
        );
        for error in [
            read_ply(text.as_bytes()).unwrap_err(),
            read_point_cloud(text.as_bytes()).unwrap_err(),
        ] {
            match error {
                PlyError::Data { reason, .. } => assert!(
                    reason.contains("file ends inside vertex 0 t_s")
                        || reason.contains("do not fit"),
                    "{format}: {reason}"
                ),
                other => panic!("{format}: expected a data error, got {other}"),
            }
        }
    }
}

#[test]
fn rows_of_no_property_are_refused_not_counted_through() {
    // 4e10 rows that take no bytes once kept the reader busy for minutes (found by AFL++).
    for format in ["ascii", "binary_little_endian"] {
        let text = format!("ply\nformat {format} 1.0\nelement vertex 44444444444\nend_header\n");
        let started = std::time::Instant::now();
        match read_ply(text.as_bytes()).unwrap_err() {
            PlyError::Data { reason, .. } => assert!(
                reason.contains("element 'vertex' has 44444444444 rows but no property"),
                "{format}: {reason}"
            ),
            other => panic!("{format}: expected a data error, got {other}"),
        }
        // As a point cloud it lacks its coordinates before any row is read.
        assert!(read_point_cloud(text.as_bytes()).is_err());
        // Not a timing test: a reader counting through would not return within the hour.
        assert!(started.elapsed() < std::time::Duration::from_secs(60));
    }
}

proptest! {
    #[test]
    fn the_reader_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        let _ = read_ply(&bytes);
        let _ = read_point_cloud(&bytes);
    }

    #[test]
    fn the_reader_never_panics_on_mangled_valid_files(
        flip in 0usize..1000, value in any::<u8>(), cut in 0usize..1000,
    ) {
        let mut bytes = to_bytes(&cloud(3, GeometryModel::SmallAngle), PlyEncoding::Ascii);
        let i = flip % bytes.len();
        bytes[i] = value;
        bytes.truncate(cut.min(bytes.len()));
        let _ = read_ply(&bytes);
        let _ = read_point_cloud(&bytes);
    }
}
