//! Files of other tools: PLY point clouds and height-map surfaces.

use std::path::Path;

use nalgebra::{Point3, Vector3};
use scanhil_controller::imaging::ply::{PlyEncoding, read_ply, read_point_cloud, write_ply};
use scanhil_controller::imaging::reconstruct::PointCloud;
use scanhil_scene::surface::height_map::{HeightField, HeightGrid};

use crate::{repository_root, select};

/// A PLY file: read as vertices and as a point cloud, the two readers agreeing; a point cloud
/// written again (binary) and read back bit for bit.
pub fn ply(data: &[u8]) {
    let vertices = read_ply(data);
    let cloud = read_point_cloud(data);
    if let Ok(vertices) = &vertices {
        assert_eq!(vertices.rows().count(), vertices.count);
        for name in &vertices.property_names {
            assert_eq!(vertices.column(name).map(|c| c.len()), Some(vertices.count));
        }
    }
    let via_vertices = vertices.as_ref().ok().map(|v| v.to_point_cloud());
    assert_eq!(
        cloud.is_ok(),
        matches!(via_vertices, Some(Ok(_))),
        "the readers disagree: {cloud:?} against {via_vertices:?}"
    );
    let Ok(cloud) = cloud else {
        return;
    };
    let written = binary(&cloud);
    let again = read_point_cloud(&written).expect("a written cloud reads back");
    assert_eq!(again.model, cloud.model);
    assert_eq!(binary(&again), written, "written and read back differently");
}

/// `cloud` as a binary PLY file.
fn binary(cloud: &PointCloud) -> Vec<u8> {
    let mut bytes = Vec::new();
    write_ply(&mut bytes, cloud, PlyEncoding::BinaryLittleEndian).expect("a Vec takes it");
    bytes
}

/// A height-map file (byte 0: CSV or PNG) as a scene's surface loads it, then placed in space,
/// its height taken and a ray cast down onto it.
pub fn surfaces(data: &[u8]) {
    let Some((format, bytes)) = select(data, 2) else {
        return;
    };
    let name = ["fuzz.csv", "fuzz.png"][format];
    let origin = repository_root().join("fixtures/surfaces").join(name);
    let Ok(grid) = HeightGrid::from_bytes(bytes, Path::new(&origin), 2.0) else {
        return;
    };
    assert!(
        grid.cols >= 2 && grid.rows >= 2,
        "{}x{}",
        grid.cols,
        grid.rows
    );
    assert_eq!(grid.heights_mm.len(), grid.cols * grid.rows);
    let field = HeightField::new(grid, 0.1, 0.0, 0.0, -120.0);
    for (x_mm, y_mm) in [(0.0, 0.0), (0.05, -0.05), (1e6, -1e6)] {
        let _ = field.height_at(x_mm, y_mm);
        let origin = Point3::new(x_mm, y_mm, 0.0);
        let down = Vector3::new(0.01, -0.02, -1.0).normalize();
        if let Some(hit) = field.intersect(&origin, &down, 1e4) {
            assert!(hit.t_mm >= 0.0, "a hit behind the ray: {hit:?}");
        }
    }
}
