//! Scene files that must load, and what they load as.

use crate::common::*;
use glam::{Vec2, Vec3};
use nimbus_scene::*;

#[test]
fn minimal_scene_gets_every_default() {
    let scene = parse(CAMERA).unwrap();
    assert_eq!(scene.source, std::path::Path::new(SCENE));
    assert_eq!(scene.render, RenderSettings::default());
    assert_eq!(scene.render.width, 256);
    assert_eq!(scene.render.height, 256);
    assert_eq!(scene.render.frames, 1);
    assert_eq!(scene.render.spp, 1);
    assert_eq!(scene.render.seed, 0);
    assert_eq!(scene.camera.up, Vec3::Y);
    assert_eq!(scene.camera.horizontal_fov_deg, 60.0);
    assert!(scene.camera.keyframes.is_empty());
    assert!(scene.lights.is_empty() && scene.media.is_empty() && scene.shapes.is_empty());
    assert_eq!(scene.integrator, Integrator::default());
    assert_eq!(scene.integrator.max_bounces, 1);
    assert_eq!(scene.integrator.volume, VolumeIntegrator::Restir);
    assert_eq!(scene.integrator.box_estimator, BoxEstimator::Mcwvds);
    assert_eq!(scene.integrator.box_samples, 16);
    let restir = &scene.integrator.restir;
    assert_eq!(restir.candidates, 4);
    assert_eq!(restir.temporal, None, "temporal = \"auto\" by default");
    assert_eq!(
        restir.temporal_limit, None,
        "temporal_limit = \"auto\" by default"
    );
    assert_eq!(scene.restir_temporal_limit(), STILL_TEMPORAL_LIMIT);
    assert_eq!(restir.temporal_limit_moving, 2);
    assert_eq!(restir.spatial_neighbors, 3);
    assert_eq!(restir.spatial_when, SpatialWhen::CameraOrDensity);
    assert_eq!(restir.temporal_history, HistoryMode::Temporal);
    assert_eq!(restir.nee, NeeMode::Auto);
    assert_eq!(restir.direct, DirectMode::EachWalk);
    assert_eq!(restir.candidate_tracking, CandidateTracking::Auto);
    assert_eq!(restir.target, TargetScalar::Sum);
    assert_eq!(restir.camera_emission, CameraEmission::Stratified);
    assert_eq!(restir.temporal_reprojection, TemporalReprojection::Aligned);
    assert_eq!(restir.temporal_shift, TemporalShift::Anchor);
    assert_eq!(restir.spatial_radius_px, None);
    assert_eq!(restir.spatial_rounds, 1);
    assert_eq!(restir.reuse, ReuseMode::Direction);
    assert_eq!(
        (restir.mip_candidates, restir.mip_indirect, restir.mip_reuse),
        (1, None, None)
    );
}

#[test]
fn mip_levels_are_numbers_or_auto() {
    let text = format!("{CAMERA}[integrator.restir]\nmip_indirect = 2\nmip_reuse = \"auto\"\n");
    let restir = parse(&text).unwrap().integrator.restir;
    assert_eq!((restir.mip_indirect, restir.mip_reuse), (Some(2), None));
}

#[test]
fn temporal_is_a_boolean_or_auto() {
    for (value, expected) in [
        ("true", Some(true)),
        ("false", Some(false)),
        ("\"auto\"", None),
    ] {
        let text = format!("{CAMERA}[integrator.restir]\ntemporal = {value}\n");
        assert_eq!(
            parse(&text).unwrap().integrator.restir.temporal,
            expected,
            "{value}"
        );
    }
}

#[test]
fn optional_defaults_of_lights_media_and_shapes() {
    let scene = parse_ok(
        r#"
[[light]]
type = "directional"
direction = [0, -2, 0]
irradiance = 3
[[medium]]
type = "box"
center = [0, 0, 0]
size = [1, 1, 1]
sigma_t = 2
[[shape]]
type = "sphere"
center = [5, 0, 0]
radius = 1
"#,
    );
    assert_eq!(
        scene.lights[0],
        Light::Directional {
            direction: Vec3::NEG_Y,
            irradiance: Vec3::splat(3.0),
            gobo: None
        }
    );
    assert_eq!(
        scene.media[0],
        Medium::Box(BoxMedium {
            center: Vec3::ZERO,
            size: Vec3::ONE,
            rotation_deg: Vec3::ZERO,
            sigma_t: 2.0,
            albedo: Vec3::ONE,
            g: 0.0
        })
    );
    assert_eq!(
        scene.shapes[0],
        Shape::Sphere {
            center: Vec3::new(5.0, 0.0, 0.0),
            radius: 1.0,
            albedo: Vec3::ZERO,
            emission: Vec3::ZERO,
        }
    );
}

#[test]
fn full_scene_with_every_table_and_field() {
    let dir = TempDir::new("full");
    dir.write("volumes/density.raw", &raw_floats(4 * 3 * 2));
    dir.write("volumes/frame5.raw", &raw_floats(2 * 2 * 2));
    dir.write("volumes/emission.vol", &vol_file([2, 3, 4], 1));
    dir.write("volumes/velocity.raw", &raw_floats(4 * 3 * 2 * 3));
    dir.write("sky.EXR", b"not really an exr; only existence is checked");
    let text = r#"
[render]
width = 320
height = 200
frames = 8
spp = 4
seed = 42
pixel_jitter = false

[camera]
position = [0, 1, 10]
look_at = [0, 1, 0]
up = [0, 2, 0]
horizontal_fov_deg = 45.5

[[camera.keyframe]]
frame = 7
position = [1, 1, 10]
look_at = [0, 1, 0]

[[camera.keyframe]]
frame = 0
position = [-1, 1, 10]
look_at = [0, 1, 0]

[[light]]
type = "directional"
direction = [0, -1, 0]
irradiance = [1, 2, 3]
gobo = [[-1, -1], [1, -1], [1, 1], [-1, 1]]
gobo_origin = [0, 5, 0]

[[light]]
type = "environment"
radiance = [0.1, 0.2, 0.3]
file = "sky.EXR"
scale = 2

[[light]]
type = "point"
position = [0, 3, 0]
intensity = 100

[[light]]
type = "sphere"
center = [0, 8, 0]
radius = 0.5
radiance = [5, 5, 4]

[[medium]]
type = "box"
center = [0, 0, 0]
size = [1, 2, 3]
rotation_deg = [0, 45, 0]
sigma_t = 0.5
albedo = [0.9, 0.8, 0.7]
g = 0.99

[[medium]]
type = "grid"
bounds_min = [3, 0, 0]
bounds_max = [4, 1, 1]
density = { file = "volumes/density.raw", dims = [4, 3, 2] }
density_scale = 20
albedo = 0.5
g = -0.3
emission = { file = "volumes/emission.vol" }
emission_scale = [1, 0.5, 0.25]
velocity = { file = "volumes/velocity.raw", dims = [4, 3, 2] }

[[medium.frame]]
frame = 5
density = { file = "volumes/frame5.raw", dims = [2, 2, 2] }

[[medium.frame]]
frame = 2
density = { procedural = "cloud", dims = [8, 8, 8], noise_seed = 7 }

[[medium]]
type = "grid"
bounds_min = [-10, -10, -10]
bounds_max = [-9, -9, -9]
density = { procedural = "cloud", dims = [16, 16, 16] }

[[shape]]
type = "quad"
corner = [-5, -1, -5]
edge_u = [10, 0, 0]
edge_v = [0, 0, 10]
albedo = 0.5

[[shape]]
type = "box"
center = [0, 3, 3]
size = [1, 1, 1]
rotation_deg = [10, 20, 30]
albedo = [0.1, 0.2, 0.3]

[[shape]]
type = "sphere"
center = [3, 3, 3]
radius = 0.25

[integrator]
max_bounces = 8
volume = "baseline"
box_estimator = "rees"
box_samples = 48

[integrator.restir]
candidates = 16
temporal = false
temporal_limit = 20
temporal_limit_moving = 6
spatial_neighbors = 5
spatial_radius_px = 30.5
spatial_when = "always"
spatial_rounds = 2
spatial_max_history = 2.5
spatial_feature_tolerance = 0.25
spatial_anchor = true
shade_cache = false
still_target = "reuse"
reuse = "vertex"
mip_candidates = 2
mip_indirect = 3
mip_reuse = 0
final_transmittance = "ratio"
nee = "split"
direct = "escape"
candidate_tracking = "regular"
pc_fetch = "buffer"
density_fetch = "image"
target = "max"
camera_emission = "reservoir"
temporal_reprojection = "path"
temporal_shift = "optical_depth"
mis = "pairwise"
spatial_shift = "optical_depth"
env_reuse = "world"
emission = "folded"
temporal_history = "temporal"
sigma_star_floor = 0.125
[integrator.baseline]
nee = "one"
density_fetch = "image"
"#;
    let scene_path = dir.write("scene.toml", text.as_bytes());
    let scene = load(&scene_path).unwrap_or_else(|e| panic!("{e:#}"));
    let volumes = dir.0.join("volumes");

    assert_eq!(
        scene.render,
        RenderSettings {
            width: 320,
            height: 200,
            frames: 8,
            spp: 4,
            seed: 42,
            pixel_jitter: false,
            transparent_background: false,
            aovs: Vec::new(),
        }
    );
    let camera = &scene.camera;
    assert_eq!(camera.up, Vec3::Y);
    assert_eq!(camera.horizontal_fov_deg, 45.5);
    assert_eq!(
        camera.keyframes,
        vec![
            CameraKeyframe {
                frame: 0,
                position: Vec3::new(-1.0, 1.0, 10.0),
                look_at: Vec3::new(0.0, 1.0, 0.0)
            },
            CameraKeyframe {
                frame: 7,
                position: Vec3::new(1.0, 1.0, 10.0),
                look_at: Vec3::new(0.0, 1.0, 0.0)
            },
        ]
    );

    assert_eq!(scene.lights.len(), 4);
    assert_eq!(
        scene.lights[0],
        Light::Directional {
            direction: Vec3::NEG_Y,
            irradiance: Vec3::new(1.0, 2.0, 3.0),
            gobo: Some(Gobo {
                polygon: vec![
                    Vec2::new(-1.0, -1.0),
                    Vec2::new(1.0, -1.0),
                    Vec2::new(1.0, 1.0),
                    Vec2::new(-1.0, 1.0)
                ],
                origin: Vec3::new(0.0, 5.0, 0.0),
            }),
        }
    );
    assert_eq!(
        scene.lights[1],
        Light::Environment {
            radiance: Vec3::new(0.1, 0.2, 0.3),
            file: Some(dir.0.join("sky.EXR")),
            scale: Vec3::splat(2.0),
            rotation_deg: 0.0,
        }
    );
    assert_eq!(
        scene.lights[2],
        Light::Point {
            position: Vec3::new(0.0, 3.0, 0.0),
            intensity: Vec3::splat(100.0)
        }
    );
    assert_eq!(
        scene.lights[3],
        Light::Sphere {
            center: Vec3::new(0.0, 8.0, 0.0),
            radius: 0.5,
            radiance: Vec3::new(5.0, 5.0, 4.0)
        }
    );

    assert_eq!(
        scene.media[0],
        Medium::Box(BoxMedium {
            center: Vec3::ZERO,
            size: Vec3::new(1.0, 2.0, 3.0),
            rotation_deg: Vec3::new(0.0, 45.0, 0.0),
            sigma_t: 0.5,
            albedo: Vec3::new(0.9, 0.8, 0.7),
            g: 0.99,
        })
    );
    assert_eq!(
        scene.media[1],
        Medium::Grid(GridMedium {
            bounds_min: Vec3::new(3.0, 0.0, 0.0),
            bounds_max: Vec3::new(4.0, 1.0, 1.0),
            density: GridSource::Raw {
                file: volumes.join("density.raw"),
                dims: [4, 3, 2]
            },
            density_scale: 20.0,
            albedo: Vec3::splat(0.5),
            g: -0.3,
            emission: Some(GridSource::MitsubaVol {
                file: volumes.join("emission.vol")
            }),
            emission_scale: Vec3::new(1.0, 0.5, 0.25),
            temperature: None,
            albedo_grid: None,
            velocity: Some(GridSource::Raw {
                file: volumes.join("velocity.raw"),
                dims: [4, 3, 2]
            }),
            velocity_scale: 1.0,
            frames: vec![
                GridFrame {
                    frame: 2,
                    density: GridSource::ProceduralCloud {
                        dims: [8, 8, 8],
                        noise_seed: 7,
                        kind: Default::default(),
                    },
                    temperature: None,
                    albedo: None,
                    emission: None,
                },
                GridFrame {
                    frame: 5,
                    density: GridSource::Raw {
                        file: volumes.join("frame5.raw"),
                        dims: [2, 2, 2]
                    },
                    temperature: None,
                    albedo: None,
                    emission: None,
                },
            ],
            vdb: None,
        })
    );
    let Medium::Grid(defaults) = &scene.media[2] else {
        panic!("third medium should be a grid");
    };
    assert_eq!(
        defaults.density,
        GridSource::ProceduralCloud {
            dims: [16, 16, 16],
            noise_seed: 0,
            kind: Default::default(),
        }
    );
    assert_eq!(defaults.density_scale, 1.0);
    assert_eq!(defaults.albedo, Vec3::ONE);
    assert_eq!(defaults.g, 0.0);
    assert_eq!(defaults.emission, None);
    assert_eq!(defaults.emission_scale, Vec3::ONE);
    assert_eq!(defaults.velocity, None);
    assert!(defaults.frames.is_empty());

    assert_eq!(
        scene.shapes,
        vec![
            Shape::Quad {
                corner: Vec3::new(-5.0, -1.0, -5.0),
                edge_u: Vec3::new(10.0, 0.0, 0.0),
                edge_v: Vec3::new(0.0, 0.0, 10.0),
                albedo: Vec3::splat(0.5),
                emission: Vec3::ZERO,
            },
            Shape::Box {
                center: Vec3::new(0.0, 3.0, 3.0),
                size: Vec3::ONE,
                rotation_deg: Vec3::new(10.0, 20.0, 30.0),
                albedo: Vec3::new(0.1, 0.2, 0.3),
                emission: Vec3::ZERO,
            },
            Shape::Sphere {
                center: Vec3::new(3.0, 3.0, 3.0),
                radius: 0.25,
                albedo: Vec3::ZERO,
                emission: Vec3::ZERO,
            },
        ]
    );

    assert_eq!(
        scene.integrator,
        Integrator {
            max_bounces: 8,
            volume: VolumeIntegrator::Baseline,
            box_estimator: BoxEstimator::Rees,
            box_samples: 48,
            moment_map_size: 256,
            restir: RestirSettings {
                candidates: 16,
                candidates_settled: 1,
                temporal: Some(false),
                temporal_limit: Some(20),
                temporal_limit_moving: 6,
                spatial_neighbors: 5,
                spatial_radius_px: Some(30.5),
                spatial_when: SpatialWhen::Always,
                spatial_rounds: 2,
                reuse: ReuseMode::Vertex,
                mip_candidates: 2,
                mip_indirect: Some(3),
                mip_reuse: Some(0),
                final_ratio_tracking: true,
                mis: MisMode::Pairwise,
                spatial_shift: SpatialShift::OpticalDepth,
                env_reuse: EnvReuse::World,
                fold_emission: true,
                spatial_max_history: 2.5,
                spatial_feature_tolerance: 0.25,
                spatial_anchor: true,
                shade_cache: false,
                still_target: StillTarget::Reuse,
                temporal_history: HistoryMode::Temporal,
                sigma_star_floor: 0.125,
                nee: NeeMode::Split,
                direct: DirectMode::Escape,
                candidate_tracking: CandidateTracking::Regular,
                pc_fetch: DensityFetch::Buffer,
                density_fetch: DensityFetch::Image,
                target: TargetScalar::Max,
                camera_emission: CameraEmission::Reservoir,
                temporal_reprojection: TemporalReprojection::Path,
                temporal_shift: TemporalShift::OpticalDepth,
            },
            baseline: BaselineSettings {
                nee: NeeMode::One,
                density_fetch: DensityFetch::Image,
            },
        }
    );
}

#[test]
fn colours_accept_a_scalar_or_three_numbers() {
    let scene = parse_ok(
        r#"
[[light]]
type = "point"
position = [0, 0, 0]
intensity = 2
[[light]]
type = "point"
position = [0, 0, 0]
intensity = [1, 2.5, 3]
[[light]]
type = "environment"
radiance = 0.25
"#,
    );
    let intensity = |i: usize| match &scene.lights[i] {
        Light::Point { intensity, .. } => *intensity,
        other => panic!("expected a point light, got {other:?}"),
    };
    assert_eq!(intensity(0), Vec3::splat(2.0));
    assert_eq!(intensity(1), Vec3::new(1.0, 2.5, 3.0));
    assert_eq!(
        scene.lights[2],
        Light::Environment {
            radiance: Vec3::splat(0.25),
            file: None,
            scale: Vec3::ONE,
            rotation_deg: 0.0,
        }
    );
}

#[test]
fn environment_file_alone_has_unit_radiance() {
    let dir = TempDir::new("env");
    dir.write("env/sky.exr", b"x");
    let scene_path = dir.write(
        "scene.toml",
        format!("{CAMERA}[[light]]\ntype = \"environment\"\nfile = \"env/sky.exr\"\n").as_bytes(),
    );
    let scene = load(&scene_path).unwrap();
    assert_eq!(
        scene.lights[0],
        Light::Environment {
            radiance: Vec3::ONE,
            file: Some(dir.0.join("env/sky.exr")),
            scale: Vec3::ONE,
            rotation_deg: 0.0,
        }
    );
}

#[test]
fn relative_paths_resolve_against_the_scene_directory() {
    let dir = TempDir::new("relative");
    dir.write("data/grid.raw", &raw_floats(8));
    let absolute = dir.write("elsewhere/abs.vol", &vol_file([1, 1, 1], 1));
    let text = format!(
        r#"{CAMERA}
[[medium]]
type = "grid"
bounds_min = [0, 0, 0]
bounds_max = [1, 1, 1]
density = {{ file = "data/grid.raw", dims = [2, 2, 2] }}
[[medium.frame]]
frame = 1
density = {{ file = "{}" }}
"#,
        absolute.display()
    );
    // Parsed as if it lived in `dir/scenes/`: relative paths would miss.
    let nested = dir.0.join("scenes").join("scene.toml");
    let error = format!("{:#}", parse_str(&text, &nested).unwrap_err());
    assert_contains(
        &error,
        &["scene.toml", "field `file`", "scenes/data/grid.raw"],
    );

    let scene = parse_str(&text, &dir.0.join("scene.toml")).unwrap();
    let Medium::Grid(grid) = &scene.media[0] else {
        panic!("expected a grid");
    };
    assert_eq!(
        grid.density,
        GridSource::Raw {
            file: dir.0.join("data/grid.raw"),
            dims: [2, 2, 2]
        }
    );
    assert_eq!(
        grid.frames[0].density,
        GridSource::MitsubaVol { file: absolute }
    );
}

#[test]
fn g_close_to_one_is_accepted() {
    for g in ["0.99", "-0.99", "0.999999"] {
        parse_ok(&format!(
            "[[medium]]\ntype = \"box\"\ncenter = [0,0,0]\nsize = [1,1,1]\nsigma_t = 1\ng = {g}\n"
        ));
    }
}

#[test]
fn touching_media_are_accepted() {
    let scene = parse_ok(
        r#"
[[medium]]
type = "box"
center = [0, 0, 0]
size = [1, 1, 1]
sigma_t = 1
[[medium]]
type = "box"
center = [1, 0, 0]
size = [1, 1, 1]
sigma_t = 1
[[medium]]
type = "box"
center = [0.1, 0.7, 0.3]
size = [0.2, 0.4, 0.6]
sigma_t = 1
[[medium]]
type = "box"
center = [1, 1, 1]
size = [1, 1, 1]
rotation_deg = [0, 0, 90]
sigma_t = 1
"#,
    );
    assert_eq!(scene.media.len(), 4);
}

#[test]
fn rotated_boxes_that_only_look_overlapping_are_accepted() {
    // The 45° box is the diamond |x| + |y| <= √0.5 ≈ 0.707: its axis-aligned bounds
    // contain the small box's corner (0.5, 0.5), the diamond itself does not.
    parse_ok(
        r#"
[[medium]]
type = "box"
center = [0, 0, 0]
size = [1, 1, 1]
rotation_deg = [0, 0, 45]
sigma_t = 1
[[medium]]
type = "box"
center = [0.6, 0.6, 0]
size = [0.2, 0.2, 0.2]
sigma_t = 1
"#,
    );
}

#[test]
fn collinear_gobo_points_are_accepted() {
    let scene = parse_ok(
        r#"
[[light]]
type = "directional"
direction = [0, -1, 0]
irradiance = 1
gobo = [[0, 0], [1, 0], [2, 0], [2, 1], [0, 1]]
"#,
    );
    let Light::Directional {
        gobo: Some(gobo), ..
    } = &scene.lights[0]
    else {
        panic!("expected a directional light with a gobo");
    };
    assert_eq!(gobo.polygon.len(), 5);
    assert_eq!(gobo.origin, Vec3::ZERO);
}

#[test]
fn clockwise_gobo_is_reordered_counter_clockwise() {
    let scene = parse_ok(
        r#"
[[light]]
type = "directional"
direction = [1, -1, 0]
irradiance = 1
gobo = [[0, 0], [0, 1], [1, 1], [1, 0]]
"#,
    );
    let Light::Directional {
        gobo: Some(gobo),
        direction,
        ..
    } = &scene.lights[0]
    else {
        panic!("expected a directional light with a gobo");
    };
    assert!((direction.length() - 1.0).abs() < 1e-6);
    assert_eq!(
        gobo.polygon,
        vec![
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.0, 1.0),
            Vec2::new(0.0, 0.0)
        ]
    );
    let twice_area: f32 = (0..4)
        .map(|i| gobo.polygon[i].perp_dot(gobo.polygon[(i + 1) % 4]))
        .sum();
    assert!(twice_area > 0.0, "polygon must be counter-clockwise");
}

#[test]
fn keyframes_are_sorted_and_may_replace_the_static_pose() {
    let scene = parse(
        r#"
[render]
frames = 30
[camera]
[[camera.keyframe]]
frame = 20
position = [0, 0, 20]
look_at = [0, 0, 0]
[[camera.keyframe]]
frame = 0
position = [0, 0, 1]
look_at = [0, 0, 0]
[[camera.keyframe]]
frame = 10
position = [0, 0, 10]
look_at = [0, 0, 0]
"#,
    )
    .unwrap();
    let frames: Vec<u32> = scene.camera.keyframes.iter().map(|k| k.frame).collect();
    assert_eq!(frames, vec![0, 10, 20]);
    assert_eq!(scene.camera.position, Vec3::new(0.0, 0.0, 1.0));
    assert_eq!(scene.camera.look_at, Vec3::ZERO);
}

#[test]
fn integers_are_accepted_as_floats() {
    let scene = parse_ok("[integrator.restir]\nspatial_radius_px = 4\n");
    assert_eq!(scene.integrator.restir.spatial_radius_px, Some(4.0));
    let scene = parse_ok("[integrator.restir]\nspatial_radius_px = \"auto\"\n");
    assert_eq!(scene.integrator.restir.spatial_radius_px, None);
    assert_eq!(auto_spatial_radius_px(1920), 10.0);
    assert_eq!(auto_spatial_radius_px(960), 5.0);
    assert_eq!(auto_spatial_radius_px(160), MIN_AUTO_SPATIAL_RADIUS_PX);
    assert_eq!(scene.integrator.restir.candidates, 4);
}

#[test]
fn convex_medium_loads_normalized_with_its_polyhedron() {
    let scene = parse_ok(&format!(
        "{}albedo = 0.5\ng = 0.2\n",
        dodecahedron([1.0, 0.0, -2.0], 0.8, 1.5)
    ));
    let Medium::Convex(m) = &scene.media[0] else {
        panic!("expected a convex medium, got {:?}", scene.media[0]);
    };
    assert_eq!(m.planes.len(), 12);
    assert_eq!((m.sigma_t, m.albedo, m.g), (1.5, Vec3::splat(0.5), 0.2));
    for p in &m.planes {
        let n = Vec3::new(p[0], p[1], p[2]);
        assert!((n.length() - 1.0).abs() < 1e-6, "{p:?}");
        // Every face is at the inradius from the centre.
        let d = p[3] - n.dot(Vec3::new(1.0, 0.0, -2.0));
        assert!((d - 0.8).abs() < 1e-5, "{p:?}");
    }
    let poly = &m.polyhedron;
    assert_eq!(
        (poly.vertices.len(), poly.faces.len(), poly.edges.len()),
        (20, 12, 30)
    );
    assert!((poly.width() - 1.6).abs() < 1e-5);
    assert!((poly.centroid() - glam::DVec3::new(1.0, 0.0, -2.0)).length() < 1e-6);
    // A box beside it (the dodecahedron reaches 1.176 r = 0.94 above its centre).
    parse_ok(&format!(
        "{}[[medium]]\ntype = \"box\"\ncenter = [1, 2, -2]\nsize = [1, 0.4, 1]\nsigma_t = 1\n",
        dodecahedron([1.0, 0.0, -2.0], 0.8, 1.5)
    ));
}

/// A `.vol` density without `bounds_min` / `bounds_max` fills its header's bounding box
/// (issue 24: the bounds were required and the header's box ignored); given bounds place
/// it instead.
#[test]
fn a_vol_density_without_bounds_takes_its_header_box() {
    let dir = TempDir::new("vol-bounds");
    let mut bytes = vol_file([2, 3, 4], 1);
    for (i, v) in [-1.0f32, -2.0, -3.0, 1.0, 2.0, 3.5].iter().enumerate() {
        bytes[24 + 4 * i..28 + 4 * i].copy_from_slice(&v.to_le_bytes());
    }
    dir.write("box.vol", &bytes);
    let path = dir.0.join("scene.toml");
    let parse = |bounds: &str| {
        let text = format!(
            "{CAMERA}[[medium]]\ntype = \"grid\"\n{bounds}density = {{ file = \"box.vol\" }}\n"
        );
        match nimbus_scene::parse_str(&text, &path) {
            Ok(s) => s,
            Err(e) => panic!("{e:#}"),
        }
    };
    let grid = |s: &nimbus_scene::Scene| match &s.media[0] {
        Medium::Grid(g) => (g.bounds_min, g.bounds_max),
        other => panic!("{other:?}"),
    };
    assert_eq!(
        grid(&parse("")),
        (Vec3::new(-1.0, -2.0, -3.0), Vec3::new(1.0, 2.0, 3.5))
    );
    assert_eq!(
        grid(&parse("bounds_min = [0, 0, 0]\nbounds_max = [1, 1, 1]\n")),
        (Vec3::ZERO, Vec3::ONE)
    );
    let error = format!(
        "{:#}",
        nimbus_scene::parse_str(
            &format!(
                "{CAMERA}[[medium]]\ntype = \"grid\"\nbounds_max = [1, 1, 1]\ndensity = {{ file = \"box.vol\" }}\n"
            ),
            &path
        )
        .unwrap_err()
    );
    assert_contains(
        &error,
        &["field `bounds_min`", "give both bounds or neither"],
    );
}
