//! The OpenVDB reader against files OpenVDB itself wrote (`tools/make_test_vdbs.py`):
//! every active voxel and tile, the transform, background, bounds and grid listing
//! against what OpenVDB reads back from the same file; the error cases by message.
//!
//! Two sets: `assets/test-vdb/` (committed, compact, always checked) and the full set,
//! generated into the target directory when `python3 -c "import pyopenvdb"` works
//! (`tools/install-deps.sh` installs it), skipped with a message otherwise.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common::assert_contains;
use glam::IVec3;
use nimbus_scene::{list_grids, read_vdb_grid, GridClass, SparseGrid, VdbGridKind, BRICK_VOXELS};
use serde_json::Value;

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn ivec3(v: &Value) -> IVec3 {
    let a: Vec<i32> = v
        .as_array()
        .expect("ijk array")
        .iter()
        .map(|x| x.as_i64().expect("integer") as i32)
        .collect();
    IVec3::new(a[0], a[1], a[2])
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .expect("array")
        .iter()
        .map(|x| x.as_f64().expect("number"))
        .collect()
}

/// One active item OpenVDB reported: a voxel (min == max) or a tile.
struct Item {
    min: IVec3,
    max: IVec3,
    value: Vec<f32>,
}

fn read_items(path: &Path, channels: usize) -> Vec<Item> {
    let bytes = std::fs::read(path).expect("items file");
    let rec = 24 + 4 * channels;
    assert_eq!(bytes.len() % rec, 0, "{}", path.display());
    bytes
        .chunks_exact(rec)
        .map(|r| {
            let i = |k: usize| i32::from_le_bytes(r[4 * k..4 * k + 4].try_into().unwrap());
            let f = |k: usize| f32::from_le_bytes(r[24 + 4 * k..28 + 4 * k].try_into().unwrap());
            Item {
                min: IVec3::new(i(0), i(1), i(2)),
                max: IVec3::new(i(3), i(4), i(5)),
                value: (0..channels).map(f).collect(),
            }
        })
        .collect()
}

fn same_bits(a: &[f32], b: &[f32]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

/// Checks one grid against its manifest entry.
fn check_grid(dir: &Path, file: &Path, g: &Value) {
    let name = g["name"].as_str().expect("name");
    let what = format!("{}:{name}", file.display());
    let grid = read_vdb_grid(file, Some(name), VdbGridKind::Any, "test")
        .unwrap_or_else(|e| panic!("{what}: {e:#}"));
    let ch = grid.channels();
    assert_eq!(grid.name, name);
    assert_eq!(
        grid.value_type.name(),
        g["type"].as_str().unwrap(),
        "{what}"
    );
    assert_eq!(
        grid.saved_as_half,
        g["saved_as_half"].as_bool().unwrap(),
        "{what}"
    );
    let class = match g["class"].as_str().unwrap() {
        "fog volume" => GridClass::FogVolume,
        "level set" => GridClass::LevelSet,
        "staggered" => GridClass::Staggered,
        _ => GridClass::Unknown,
    };
    assert_eq!(grid.grid_class, class, "{what}");
    assert_eq!(grid.map_type, g["map_type"].as_str().unwrap(), "{what}");
    assert_eq!(
        (grid.file_version, grid.library_version.0),
        (224, 10),
        "{what}"
    );

    // The transform: OpenVDB's images of the origin and the unit axes.
    let cols = g["index_to_world"].as_array().unwrap();
    for (c, col) in cols.iter().enumerate() {
        let want = floats(col);
        let got = grid.index_to_world.col(c).to_array();
        for r in 0..4 {
            assert!(
                (got[r] - want[r]).abs() <= 1e-12 * (1.0 + want[r].abs()),
                "{what}: index_to_world column {c}: {got:?} vs {want:?}"
            );
        }
    }
    let bg = floats(&g["background"]);
    let got_bg: Vec<f64> = grid.background[..ch]
        .iter()
        .map(|&v| f64::from(v))
        .collect();
    assert_eq!(got_bg, bg, "{what}: background");
    assert_eq!(
        grid.active_voxels,
        g["active_voxels"].as_u64().unwrap(),
        "{what}"
    );
    match &g["bbox"] {
        Value::Null => assert_eq!(grid.active_bbox, None, "{what}"),
        b => assert_eq!(
            grid.active_bbox,
            Some((ivec3(&b[0]), ivec3(&b[1]))),
            "{what}"
        ),
    }
    assert_eq!(
        grid.brick_count() as u64,
        g["leaf_count"].as_u64().unwrap(),
        "{what}"
    );
    assert_eq!(grid.values.len(), grid.brick_count() * BRICK_VOXELS * ch);

    // Every item OpenVDB reports is active here with the same bits, and the counts
    // agree, so the active sets are equal.
    let items = read_items(&dir.join(g["items"].as_str().unwrap()), ch);
    assert_eq!(items.len() as u64, g["item_count"].as_u64().unwrap());
    let mut volume = 0u64;
    for item in &items {
        let size = item.max - item.min + IVec3::ONE;
        volume += size.x as u64 * size.y as u64 * size.z as u64;
        for k in item.min.z..=item.max.z {
            for j in item.min.y..=item.max.y {
                for i in item.min.x..=item.max.x {
                    let (v, active) = grid.value_at(IVec3::new(i, j, k));
                    assert!(
                        active && same_bits(&v[..ch], &item.value),
                        "{what}: ({i}, {j}, {k}): got {:?} active {active}, OpenVDB {:?}",
                        &v[..ch],
                        item.value
                    );
                }
            }
        }
    }
    assert_eq!(volume, grid.active_voxels, "{what}: active voxels");
    check_structure(&grid, &what);
}

/// Invariants of the sparse structure itself.
fn check_structure(grid: &SparseGrid, what: &str) {
    let ch = grid.channels();
    let mut in_bricks = 0u64;
    for b in 0..grid.brick_count() {
        let o = grid.brick_origins[b];
        assert_eq!(o & IVec3::splat(7), IVec3::ZERO, "{what}: brick origin {o}");
        if b > 0 {
            let p = grid.brick_origins[b - 1];
            assert!(
                (p.z, p.y, p.x) < (o.z, o.y, o.x),
                "{what}: bricks not sorted"
            );
        }
        for z in 0..8 {
            for y in 0..8 {
                for x in 0..8 {
                    let at = SparseGrid::brick_voxel_index(x, y, z) * ch;
                    let v = &grid.brick(b)[at..at + ch];
                    if grid.brick_voxel_active(b, x, y, z) {
                        in_bricks += 1;
                    } else {
                        assert!(
                            same_bits(v, &grid.background[..ch]),
                            "{what}: inactive voxel"
                        );
                    }
                }
            }
        }
    }
    let in_tiles: u64 = grid.tiles.iter().map(|t| u64::from(t.edge).pow(3)).sum();
    assert_eq!(in_bricks + in_tiles, grid.active_voxels, "{what}");
}

fn check_error(file: &Path, f: &Value) {
    let kind = match f["kind"].as_str().unwrap() {
        "vec3" => VdbGridKind::Vec3,
        "any" => VdbGridKind::Any,
        _ => VdbGridKind::Scalar,
    };
    let grid = f["grid"].as_str();
    let expected = f["error"].as_str().unwrap();
    match read_vdb_grid(file, grid, kind, "scenes/a.toml: [[medium]] #1 > density") {
        Ok(g) => panic!(
            "{}: should fail with {expected:?}, read {:?}",
            file.display(),
            g.name
        ),
        Err(e) => {
            let message = format!("{e:#}");
            let name = file.display().to_string();
            assert_contains(
                &message,
                &["scenes/a.toml: [[medium]] #1 > density: ", &name, expected],
            );
        }
    }
}

/// Checks every file of a manifest directory; returns how many grids were compared.
fn check_dir(dir: &Path) -> usize {
    let text = std::fs::read_to_string(dir.join("manifest.json")).expect("manifest.json");
    let manifest: Value = serde_json::from_str(&text).expect("manifest JSON");
    let mut grids = 0;
    for f in manifest["files"].as_array().unwrap() {
        let file = dir.join(f["file"].as_str().unwrap());
        if f.get("error").is_some() {
            check_error(&file, f);
            continue;
        }
        let listed = list_grids(&file).unwrap_or_else(|e| panic!("{e:#}"));
        let mut want: Vec<(String, String, bool)> = f["grids"]
            .as_array()
            .unwrap()
            .iter()
            .map(|g| {
                (
                    g["name"].as_str().unwrap().to_string(),
                    g["type"].as_str().unwrap().to_string(),
                    g["saved_as_half"].as_bool().unwrap(),
                )
            })
            .collect();
        let mut got: Vec<(String, String, bool)> = listed
            .iter()
            .map(|g| (g.name.clone(), g.type_name.clone(), g.saved_as_half))
            .collect();
        want.sort();
        got.sort();
        assert_eq!(got, want, "{}: list_grids", file.display());
        for g in f["grids"].as_array().unwrap() {
            if g["type"] != "bool" {
                check_grid(dir, &file, g);
                grids += 1;
            }
        }
    }
    grids
}

#[test]
fn committed_vdb_files_read_as_openvdb_reads_them() {
    let n = check_dir(&repo_root().join("assets/test-vdb"));
    assert!(n >= 8, "only {n} grids checked");
}

/// A python3 that imports pyopenvdb (Debian's lives in /usr/bin's site packages).
fn python_with_openvdb() -> Option<PathBuf> {
    ["python3", "/usr/bin/python3"]
        .into_iter()
        .map(PathBuf::from)
        .find(|py| {
            Command::new(py)
                .args(["-c", "import pyopenvdb"])
                .output()
                .is_ok_and(|o| o.status.success())
        })
}

#[test]
fn generated_vdb_files_read_as_openvdb_reads_them() {
    let Some(python) = python_with_openvdb() else {
        eprintln!(
            "SKIPPED generated_vdb_files_read_as_openvdb_reads_them: `python3 -c \"import \
             pyopenvdb\"` fails; install python3-openvdb (tools/install-deps.sh)"
        );
        return;
    };
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("test-vdb");
    let _ = std::fs::remove_dir_all(&dir);
    let out = Command::new(&python)
        .arg(repo_root().join("tools/make_test_vdbs.py"))
        .arg(&dir)
        .output()
        .expect("run tools/make_test_vdbs.py");
    assert!(
        out.status.success(),
        "make_test_vdbs.py failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let n = check_dir(&dir);
    // Without vdb_tool (libopenvdb-tools) the zip / uncompressed variants are left out.
    let have_vdb_tool = Command::new("vdb_tool").arg("-version").output().is_ok();
    if !have_vdb_tool {
        eprintln!("note: no vdb_tool; only the Blosc files were generated and checked");
    }
    let expected = if have_vdb_tool { 21 } else { 10 };
    assert!(n >= expected, "only {n} grids checked");
}

#[test]
fn default_grid_choice() {
    let dir = repo_root().join("assets/test-vdb");
    // The only float grid.
    let g = read_vdb_grid(&dir.join("float_blosc.vdb"), None, VdbGridKind::Scalar, "t").unwrap();
    assert_eq!(g.name, "density");
    // The only vec3 grid.
    let g = read_vdb_grid(&dir.join("vec3_blosc.vdb"), None, VdbGridKind::Vec3, "t").unwrap();
    assert_eq!(g.name, "vel");
    // Several float grids: "density"; the only vec3 grid among many.
    let multi = dir.join("multi.vdb");
    let g = read_vdb_grid(&multi, None, VdbGridKind::Scalar, "t").unwrap();
    assert_eq!(g.name, "density");
    let g = read_vdb_grid(&multi, None, VdbGridKind::Vec3, "t").unwrap();
    assert_eq!(g.name, "vel");
    // No vec3 grid at all.
    let e = read_vdb_grid(&dir.join("float_blosc.vdb"), None, VdbGridKind::Vec3, "t").unwrap_err();
    assert_contains(
        &format!("{e:#}"),
        &["no vec3 grid", "the file has grids: density (float)"],
    );
    // The bool grid is listed but refused.
    let e = read_vdb_grid(&multi, Some("mask"), VdbGridKind::Scalar, "t").unwrap_err();
    assert_contains(
        &format!("{e:#}"),
        &["grid \"mask\"", "it holds bool values"],
    );
    // An instance reads its parent's tree.
    let a = read_vdb_grid(&multi, Some("density"), VdbGridKind::Scalar, "t").unwrap();
    let b = read_vdb_grid(&multi, Some("density_copy"), VdbGridKind::Scalar, "t").unwrap();
    assert_eq!(
        (a.brick_origins.clone(), a.values.clone()),
        (b.brick_origins, b.values)
    );
}

#[test]
fn listing_names_types() {
    let dir = repo_root().join("assets/test-vdb");
    let names: Vec<String> = list_grids(&dir.join("half_zip.vdb"))
        .unwrap()
        .iter()
        .map(|g| g.to_string())
        .collect();
    assert_eq!(names, ["density (float, saved as half)"]);
}

#[test]
fn sparse_memory_follows_active_voxels() {
    // tiles_blosc.vdb: voxels thousands apart and a 128³ tile; a few bricks.
    let g = read_vdb_grid(
        &repo_root().join("assets/test-vdb/tiles_blosc.vdb"),
        None,
        VdbGridKind::Scalar,
        "t",
    )
    .unwrap();
    let (lo, hi) = g.active_bbox.unwrap();
    let extent = (hi - lo + IVec3::ONE).as_i64vec3();
    assert!(extent.x * extent.y * extent.z > 1 << 36, "bbox {lo} {hi}");
    assert!(
        g.brick_count() <= 4 && g.memory_bytes() < 16 * 1024,
        "{}",
        g.memory_bytes()
    );
    assert!(g.tiles.iter().any(|t| t.edge == 128) && g.tiles.iter().any(|t| t.edge == 8));
}

#[test]
fn missing_file_and_not_a_vdb() {
    let e = read_vdb_grid(Path::new("no/such.vdb"), None, VdbGridKind::Scalar, "w").unwrap_err();
    assert_contains(&format!("{e:#}"), &["w: no/such.vdb: cannot open VDB file"]);
    let e = read_vdb_grid(
        &repo_root().join("Cargo.toml"),
        None,
        VdbGridKind::Scalar,
        "w",
    )
    .unwrap_err();
    assert_contains(&format!("{e:#}"), &["Cargo.toml: not a VDB file"]);
    let e = list_grids(Path::new("no/such.vdb")).unwrap_err();
    assert_contains(&format!("{e:#}"), &["no/such.vdb", "cannot open"]);
}
