//! The committed volume assets load through the scene format and are what their
//! generator (`examples/make_cloud.rs`) makes: a write_vol / load_grid round trip.

use std::path::Path;

use nimbus_scene::{load_grid, procedural_cloud, GridSource};

#[test]
fn committed_cloud_asset_is_the_procedural_cloud() {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/volumes/cloud-48x32x48.vol");
    let grid = load_grid(&GridSource::MitsubaVol { file: path }, 1, "asset").expect("asset loads");
    let expected = procedural_cloud([48, 32, 48], 7);
    assert_eq!(grid.dims, expected.dims);
    assert_eq!(grid.channels, 1);
    assert!(
        grid.data.iter().zip(&expected.data).all(|(a, b)| a.to_bits() == b.to_bits()),
        "assets/volumes/cloud-48x32x48.vol differs from procedural_cloud([48, 32, 48], 7): \
         regenerate it with `cargo run --example make_cloud -- assets/volumes/cloud-48x32x48.vol 48 32 48 7`"
    );
}

#[test]
fn write_vol_round_trips() {
    let dir = std::env::temp_dir().join(format!("nimbus-vol-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("small.vol");
    let grid = procedural_cloud([9, 5, 7], 3);
    nimbus_scene::write_vol(&path, &grid, glam::Vec3::ZERO, glam::Vec3::ONE).unwrap();
    let back = load_grid(&GridSource::MitsubaVol { file: path }, 1, "small").unwrap();
    assert_eq!(back, grid);
    let _ = std::fs::remove_dir_all(&dir);
}
