//! The committed volume assets load through the scene format and are what their
//! generators make: the cloud is `examples/make_cloud.rs`'s (a write_vol / load_grid
//! round trip), the plume frames are each other advected by the plume's velocity
//! (`examples/make_plume.rs`).

use std::path::Path;

use nimbus_scene::{
    check_same_dims, load_grid, procedural_cloud, GridSource, Light, Medium, VolumeIntegrator,
    VoxelGrid,
};

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

/// `assets/scenes/plume-anim.toml` loads, animates its camera, sun and density, and its
/// grids (from `examples/make_plume.rs`) load, share their dims and follow the velocity.
#[test]
fn plume_animation_scene_and_its_grids_load() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let path = root.join("assets/scenes/plume-anim.toml");
    let scene = nimbus_scene::load(&path).unwrap_or_else(|e| panic!("{e:#}"));
    assert_eq!((scene.render.width, scene.render.height), (96, 72));
    assert_eq!(scene.render.frames, 4);
    assert_eq!(scene.camera.keyframes.len(), 2);
    assert_ne!(scene.camera.frame_at(0), scene.camera.frame_at(3));
    assert_eq!(scene.integrator.max_bounces, 2);
    assert_eq!(scene.integrator.volume, VolumeIntegrator::Restir);

    // One sun that turns a little, one constant sky.
    assert!(scene.lights_animated());
    assert_eq!(scene.lights.len(), 2);
    assert!(matches!(
        scene.lights[1],
        Light::Environment { file: None, .. }
    ));
    let sun = |frame| match scene.lights_at(frame)[0] {
        Light::Directional { direction, .. } => direction,
        ref other => panic!("expected the sun, got {other:?}"),
    };
    let turn = sun(0).dot(sun(3)).clamp(-1.0, 1.0).acos().to_degrees();
    assert!((2.0..20.0).contains(&turn), "the sun turns {turn} degrees");
    assert!(sun(1).dot(sun(0)) > sun(3).dot(sun(0)));

    // One grid medium with a density per frame and a velocity, all 32³.
    assert_eq!(scene.media.len(), 1);
    let Medium::Grid(medium) = &scene.media[0] else {
        panic!("expected a grid medium");
    };
    assert_eq!(medium.bounds_min, glam::Vec3::splat(-0.5));
    assert_eq!(medium.bounds_max, glam::Vec3::splat(0.5));
    assert_eq!((medium.density_scale, medium.g), (20.0, 0.3));
    assert_eq!(medium.albedo, glam::Vec3::splat(0.9));
    for frame in 0..4 {
        assert_eq!(medium.density_index_at(frame), frame as usize);
    }
    assert_eq!(medium.animation_dims("plume").unwrap(), [32, 32, 32]);

    let densities: Vec<VoxelGrid> = medium
        .density_sources()
        .enumerate()
        .map(|(i, source)| {
            load_grid(source, 1, &format!("plume frame {i}")).unwrap_or_else(|e| panic!("{e:#}"))
        })
        .collect();
    let velocity = load_grid(
        medium.velocity.as_ref().expect("a velocity grid"),
        3,
        "velocity",
    )
    .unwrap_or_else(|e| panic!("{e:#}"));
    assert_eq!(densities.len(), 4);
    assert_eq!(velocity.channels, 3);
    let mut grids: Vec<(String, [u32; 3])> = densities
        .iter()
        .enumerate()
        .map(|(i, g)| (format!("frame {i}"), g.dims))
        .collect();
    grids.push(("velocity".into(), velocity.dims));
    let grids: Vec<(&str, [u32; 3])> = grids.iter().map(|(n, d)| (n.as_str(), *d)).collect();
    check_same_dims(&grids).unwrap();

    let n = 32u32;
    for (f, density) in densities.iter().enumerate() {
        assert!(density.data.iter().all(|v| (0.0..=1.0).contains(v)));
        let max = density.data.iter().copied().fold(0.0f32, f32::max);
        assert!(max > 0.5, "frame {f}: max density {max}");
        // Zero within three voxels of every face.
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    let near_face = [i, j, k].iter().any(|&c| c < 3 || c >= n - 3);
                    if near_face {
                        assert_eq!(density.get(i, j, k), 0.0, "frame {f} voxel ({i}, {j}, {k})");
                    }
                }
            }
        }
    }
    // Mostly upward, about 0.02 m per frame.
    let count = velocity.voxel_count() as f32;
    let mean: [f32; 3] =
        std::array::from_fn(|c| velocity.data.iter().skip(c).step_by(3).sum::<f32>() / count);
    assert!((0.015..0.025).contains(&mean[1]), "mean velocity {mean:?}");
    assert!(
        mean[0].abs() < 1e-3 && mean[2].abs() < 1e-3,
        "mean velocity {mean:?}"
    );

    // Frame f + 1 is frame f advected: d_{f+1}(x) = d_f(x − v(x)), trilinear, with the
    // velocity in metres per frame converted to voxels by the scene's bounds.
    let scale: [f64; 3] = std::array::from_fn(|axis| {
        f64::from(n) / (f64::from(medium.bounds_max[axis]) - f64::from(medium.bounds_min[axis]))
    });
    for f in 0..3 {
        let (prev, next) = (&densities[f], &densities[f + 1]);
        let mut worst = 0f64;
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    let index = [i, j, k];
                    let p: [f64; 3] = std::array::from_fn(|axis| {
                        let v = f64::from(velocity.get_channel(i, j, k, axis as u32));
                        f64::from(index[axis]) + 0.5 - v * scale[axis]
                    });
                    let expected = prev.sample_trilinear(p);
                    worst = worst.max((expected - f64::from(next.get(i, j, k))).abs());
                }
            }
        }
        assert!(
            worst < 1e-6,
            "frame {} is not frame {f} advected: off by {worst}",
            f + 1
        );
    }
    // And the plume rises: the density-weighted height grows every frame.
    let height = |g: &VoxelGrid| {
        let (mut sum, mut weight) = (0f64, 0f64);
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    let d = f64::from(g.get(i, j, k));
                    sum += d * f64::from(j);
                    weight += d;
                }
            }
        }
        sum / weight
    };
    let heights: Vec<f64> = densities.iter().map(height).collect();
    assert!(
        heights.windows(2).all(|w| w[1] > w[0] + 0.3),
        "heights {heights:?}"
    );
}

/// Mitsuba's half (encoding 2) and byte (encoding 3, 0..255 as 0..1) `.vol` files load
/// through both readers (the dense one the CPU reference uses and the streamed bricks
/// the renderer uploads) with the values the encoding stores; quantized directions
/// (4) and unknown encodings are refused naming the file and the encoding.
#[test]
fn half_and_byte_vol_files_load_with_their_encodings_values() {
    use nimbus_scene::{write_vol_encoded, BrickGrid, VolEncoding};
    let dir = crate::common::TempDir::new("vol-encodings");
    let mut grid = procedural_cloud([9, 5, 7], 3);
    let max = grid.data.iter().fold(0f32, |m, &v| m.max(v));
    grid.data.iter_mut().for_each(|v| *v /= max);
    for (encoding, quantize) in [
        (
            VolEncoding::F16,
            (|v: f32| half::f16::from_f32(v).to_f32()) as fn(f32) -> f32,
        ),
        (VolEncoding::U8, |v: f32| (v * 255.0).round() / 255.0),
    ] {
        let path = dir.0.join(format!("{}.vol", encoding.name()));
        write_vol_encoded(&path, &grid, glam::Vec3::ZERO, glam::Vec3::ONE, encoding).unwrap();
        let header = nimbus_scene::read_vol_header(&path).unwrap();
        assert_eq!(header.encoding, encoding);
        let source = GridSource::MitsubaVol { file: path };
        let dense = load_grid(&source, 1, "t").unwrap();
        let bricks = BrickGrid::load(&source, 1, "t").unwrap();
        for k in 0..7u32 {
            for j in 0..5u32 {
                for i in 0..9u32 {
                    let expected = quantize(grid.get(i, j, k));
                    assert!(
                        (dense.get(i, j, k) - expected).abs() <= 1e-7,
                        "{} ({i}, {j}, {k}): {} vs {expected}",
                        encoding.name(),
                        dense.get(i, j, k)
                    );
                    let l = glam::IVec3::new(i as i32, j as i32, k as i32) - bricks.origin;
                    assert_eq!(bricks.get(l), dense.get(i, j, k));
                }
            }
        }
        // A file one byte short of its encoding's size is refused.
        let bytes = std::fs::read(match &source {
            GridSource::MitsubaVol { file } => file,
            _ => unreachable!(),
        })
        .unwrap();
        let short = dir.write("short.vol", &bytes[..bytes.len() - 1]);
        let e = format!("{:#}", nimbus_scene::read_vol_header(&short).unwrap_err());
        crate::common::assert_contains(&e, &["short.vol", encoding.name(), "found"]);
    }
    for (id, needles) in [
        (4i32, vec!["encoding 4", "quantized directions"]),
        (7, vec!["encoding 7", "float16"]),
    ] {
        let mut bytes = crate::common::vol_file([2, 2, 2], 1);
        bytes[4..8].copy_from_slice(&id.to_le_bytes());
        let path = dir.write(&format!("enc{id}.vol"), &bytes);
        let e = format!("{:#}", nimbus_scene::read_vol_header(&path).unwrap_err());
        let mut all = vec![format!("enc{id}.vol")];
        all.extend(needles.iter().map(|s| s.to_string()));
        let all: Vec<&str> = all.iter().map(String::as_str).collect();
        crate::common::assert_contains(&e, &all);
    }
}

/// A 3-channel `.vol` file is an rgb emission (the renderer's bricks hold its three
/// channels, not a mix of them); as a density it is refused, naming the field and what
/// 3-channel files are for.
#[test]
fn rgb_vol_is_an_emission_and_not_a_density() {
    use nimbus_scene::BrickGrid;
    let dir = crate::common::TempDir::new("vol-rgb");
    let dims = [6u32, 4, 5];
    let n = (dims[0] * dims[1] * dims[2]) as usize;
    let data: Vec<f32> = (0..n * 3)
        .map(|i| (i % 3) as f32 + 0.01 * (i / 3) as f32)
        .collect();
    let rgb = VoxelGrid {
        dims,
        channels: 3,
        data,
    };
    let path = dir.0.join("rgb.vol");
    nimbus_scene::write_vol(&path, &rgb, glam::Vec3::ZERO, glam::Vec3::ONE).unwrap();
    let box_ = "[[medium]]\ntype = \"grid\"\nbounds_min = [0, 0, 0]\nbounds_max = [1, 1, 1]\n";
    let ok = crate::common::parse_ok(&format!(
        "{box_}density = {{ procedural = \"cloud\", dims = [6, 4, 5] }}\nemission = {{ file = {:?} }}\n",
        path.display().to_string()
    ));
    let Medium::Grid(m) = &ok.media[0] else {
        panic!("a grid medium");
    };
    let bricks = BrickGrid::load(m.emission.as_ref().unwrap(), 0, "t").unwrap();
    assert_eq!(bricks.channels, 3);
    let l = glam::IVec3::new(2, 1, 3) - bricks.origin;
    let voxel = ((3 * dims[1] + 1) * dims[0] + 2) as usize;
    for c in 0..3 {
        assert_eq!(bricks.get_clamped(l, c), rgb.data[voxel * 3 + c as usize]);
    }
    let e = crate::common::parse_err(&format!(
        "{box_}density = {{ file = {:?} }}\n",
        path.display().to_string()
    ));
    crate::common::assert_contains(
        &e,
        &[
            "density",
            "field `file`",
            "rgb.vol",
            "3 channels",
            "a density has one channel",
        ],
    );
}
