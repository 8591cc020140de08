//! The environment lighting box and convex media and surfaces in the crepuscular pass
//! (next-event estimation, shaders/box/environment.glsl), on lavapipe with validation,
//! against the CPU Monte Carlo oracle (`nimbus_reference::mc`), which reaches the same
//! light by analog escape instead: constant skies and an importance-sampled map, single
//! and multiple scattering, a floor shadowed by the medium and a sphere; and scenes
//! without an environment compile its code out.

use std::path::PathBuf;

use nimbus::output::ImageRgb;
use nimbus::plan::{self, Integrator};
use nimbus::shader_data::features::{SC_ID_HAS_ENV, SC_ID_HAS_ENV_MAP};
use nimbus_gpu::{Context, SpecValue};
use nimbus_reference::mc::{render_mc, McOptions};
use nimbus_scene::{BoxEstimator, Scene};

use crate::common::gpu::{assert_means_agree, channels_beyond, context, render_checked, scene};

/// The camera, image and sample counts every comparison here uses: 12 × 12 pixels,
/// 32 frames × 4 spp on the GPU.
const VIEW: &str = r#"
[render]
width = 12
height = 12
frames = 32
spp = 4
seed = 5
[camera]
position = [0.3, 0.9, 3.2]
look_at = [0.0, -0.2, 0.0]
horizontal_fov_deg = 60
"#;

/// A rotated box medium.
const BOX: &str = r#"
[[medium]]
type = "box"
center = [0.0, 0.0, 0.0]
size = [1.6, 1.0, 1.2]
rotation_deg = [0.0, 25.0, 0.0]
sigma_t = 2.0
albedo = [0.95, 0.9, 0.8]
g = 0.3
"#;

/// A Lambertian floor under the box and a white sphere beside it, both shadowing the
/// floor from the sky.
const FLOOR_AND_SPHERE: &str = r#"
[[shape]]
type = "quad"
corner = [-2.5, -0.5, -2.5]
edge_u = [5.0, 0.0, 0.0]
edge_v = [0.0, 0.0, 5.0]
albedo = [0.7, 0.6, 0.5]
[[shape]]
type = "sphere"
center = [0.9, 0.0, 0.9]
radius = 0.35
albedo = 0.8
"#;

/// A constant sky.
const SKY: &str = r#"
[[light]]
type = "environment"
radiance = [0.6, 0.8, 1.0]
"#;

/// A low sun, so that shadows reach across the floor.
const SUN: &str = r#"
[[light]]
type = "directional"
direction = [0.6, -0.5, -0.4]
irradiance = [1.5, 1.3, 1.0]
"#;

/// A small daylight sky (`nimbus_scene::daylight_sky`, 64 × 32 texels): a horizon-to-
/// zenith gradient over a dark ground and a sun 29° wide, 40° high, whose texels alone
/// give 2 W/m² (radiance about 10, some 50 times the sky's). Wide enough for the
/// oracle's analog escapes to find it often; bright enough that the sun region decides
/// the map's importance sampling.
fn sky_map() -> PathBuf {
    let dir = crate::common::cli::scratch("box_env", "maps");
    let path = dir.join("sky.exr");
    let (w, h) = (64, 32);
    let sun = nimbus_scene::sun_direction(40f32.to_radians(), 30f32.to_radians());
    let texels = nimbus_scene::daylight_sky(w, h, sun, 0.5, 2.0);
    exr::prelude::write_rgb_file(&path, w, h, |x, y| {
        let [r, g, b] = texels[y * w + x];
        (r, g, b)
    })
    .unwrap();
    path
}

/// The map as a `[[light]]`, at `scale`.
fn map_light(path: &std::path::Path, scale: f32) -> String {
    format!(
        "[[light]]\ntype = \"environment\"\nfile = \"{}\"\nscale = {scale}\n",
        path.display()
    )
}

/// Renders `scene` at K = `k` on the GPU (N = 8 samples along each segment) and by the
/// Monte Carlo oracle (`paths` per pixel, 4 × 4 strata), and checks that the image
/// means agree within 4 combined standard errors + 1 % and that at most 2 % of the
/// pixel channels differ by more than 4.5 combined standard errors. Returns the GPU
/// image.
fn agrees_with_the_oracle(
    ctx: &Context,
    scene: &mut Scene,
    k: u32,
    paths: u32,
    what: &str,
) -> ImageRgb {
    scene.integrator.max_bounces = k;
    // A seed per comparison, so that their errors do not correlate.
    let seed = what.bytes().map(u64::from).sum::<u64>() + u64::from(k);
    scene.render.seed = seed;
    let (w, h) = (scene.render.width, scene.render.height);
    let (cpu_mean, cpu_se) = render_mc(
        scene,
        &McOptions {
            max_bounces: k,
            paths,
            seed,
        },
        4,
    )
    .expect("cpu reference");
    let cpu = ImageRgb::from_rgb_f64(w, h, &cpu_mean).unwrap();
    let cpu_se = ImageRgb::from_rgb_f64(w, h, &cpu_se).unwrap();
    let gpu = render_checked(ctx, scene, Some(8));
    let what = format!("{what}, K = {k}: gpu vs cpu");
    let (g, c) = ((&gpu.image, &gpu.std_error), (&cpu, &cpu_se));
    assert_means_agree(&what, g, c, 4.0, 0.01);
    let channels = 3 * (w * h) as usize;
    let beyond = channels_beyond(g, c, 4.5);
    println!("{what}: {beyond} of {channels} channels beyond 4.5 SE");
    assert!(
        beyond * 50 <= channels,
        "{what}: {beyond} channels beyond 4.5 SE"
    );
    gpu.image
}

/// (a) A box medium under a constant sky, nothing else: single scattering and four
/// orders, against the oracle. The sky the camera sees around the box is exact in
/// both; the box's own glow is the environment's scattered light only.
#[test]
fn a_box_under_a_constant_sky_matches_the_oracle() {
    let ctx = context();
    let mut s = scene(&format!("{VIEW}{SKY}{BOX}"), "box-sky.toml");
    let single = agrees_with_the_oracle(&ctx, &mut s, 1, 2048, "box, constant sky");
    let multiple = agrees_with_the_oracle(&ctx, &mut s, 4, 2048, "box, constant sky");
    // More orders add light.
    assert!(multiple.mean()[0] > single.mean()[0]);
}

/// (b) The box under the daylight map, K = 1 and 3, alone and beside a sun with MCWVDS
/// and RM (the environment's estimate is the same for every estimator, the sun's is
/// not), and a convex medium (a dodecahedron) under the map at K = 2.
#[test]
fn box_and_convex_media_under_an_environment_map_match_the_oracle() {
    let ctx = context();
    let map = sky_map();
    let mut s = scene(
        &format!("{VIEW}{}{BOX}", map_light(&map, 1.0)),
        "box-map.toml",
    );
    for k in [1, 3] {
        agrees_with_the_oracle(&ctx, &mut s, k, 8192, "box, map");
    }
    let mut s = scene(
        &format!("{VIEW}{}{SUN}{BOX}", map_light(&map, 1.0)),
        "box-map-sun.toml",
    );
    for estimator in [BoxEstimator::Mcwvds, BoxEstimator::Rm] {
        s.integrator.box_estimator = estimator;
        for k in [1, 3] {
            let what = format!("box, map and sun, {}", estimator.name());
            agrees_with_the_oracle(&ctx, &mut s, k, 8192, &what);
        }
    }
    let planes = crate::oracle::render_convex::dodecahedron_planes([0.0, 0.0, 0.0], 0.7, 0.3);
    let convex =
        format!("[[medium]]\ntype = \"convex\"\n{planes}\nsigma_t = 1.7\nalbedo = 0.9\ng = 0.5\n");
    let mut s = scene(
        &format!("{VIEW}{}{convex}", map_light(&map, 1.0)),
        "convex-map.toml",
    );
    agrees_with_the_oracle(&ctx, &mut s, 2, 8192, "dodecahedron, map");
}

/// (c) A Lambertian floor under the sky, shadowed by the box and by a sphere: under the
/// constant sky (with a sun, K = 1 and 2) and under the map (K = 1 and 2). The floor's
/// sky light is what most of the image shows, so a missing shadow or a wrong cosine
/// moves the mean by far more than the tolerance.
#[test]
fn a_floor_shadowed_by_the_medium_and_a_sphere_matches_the_oracle() {
    let ctx = context();
    let mut s = scene(
        &format!("{VIEW}{SKY}{SUN}{BOX}{FLOOR_AND_SPHERE}"),
        "floor-sky.toml",
    );
    for k in [1, 2] {
        agrees_with_the_oracle(&ctx, &mut s, k, 2048, "floor, constant sky and sun");
    }
    let map = sky_map();
    let mut s = scene(
        &format!("{VIEW}{}{BOX}{FLOOR_AND_SPHERE}", map_light(&map, 1.0)),
        "floor-map.toml",
    );
    for k in [1, 2] {
        agrees_with_the_oracle(&ctx, &mut s, k, 8192, "floor, map");
    }
}

/// (d) The plan decides the environment's code: a scene without one compiles it out
/// (SC_HAS_ENV and SC_HAS_ENV_MAP false, `--explain` says so), a constant sky turns on
/// SC_HAS_ENV only, a map both, and a map beside another environment is refused.
#[test]
fn the_plan_compiles_the_environment_in_only_where_the_scene_has_one() {
    let map = sky_map();
    let features = |text: &str| {
        let s = scene(text, "plan.toml");
        let plan = plan::build(&s, None).unwrap();
        let explain = plan.explain(&s);
        let Integrator::Crepuscular(p) = plan.integrator else {
            panic!("a box scene runs the crepuscular pass")
        };
        let spec = nimbus::passes::crepuscular::specialization(&p);
        let constant = |id: u32| spec.iter().find(|(i, _)| *i == id).unwrap().1;
        (
            p.features,
            constant(SC_ID_HAS_ENV),
            constant(SC_ID_HAS_ENV_MAP),
            explain,
        )
    };
    let on = SpecValue::Bool(true);
    let off = SpecValue::Bool(false);

    let (f, env, env_map, explain) = features(&format!("{VIEW}{SUN}{BOX}"));
    assert!(!f.has_env && !f.has_env_map);
    assert_eq!((env, env_map), (off, off));
    assert!(
        explain.contains("[off]   SC_HAS_ENV ")
            && explain.contains("environment lighting compiled out"),
        "{explain}"
    );

    let (f, env, env_map, explain) = features(&format!("{VIEW}{SKY}{BOX}{FLOOR_AND_SPHERE}"));
    assert!(f.has_env && !f.has_env_map);
    assert_eq!((env, env_map), (on, off));
    assert!(
        explain.contains(
            "constant environment: seen by camera rays, lights the media and the surfaces"
        ),
        "{explain}"
    );

    let (f, env, env_map, explain) = features(&format!("{VIEW}{}{BOX}", map_light(&map, 1.0)));
    assert!(f.has_env && f.has_env_map);
    assert_eq!((env, env_map), (on, on));
    assert!(
        explain.contains("map environment: seen by camera rays, lights the media")
            && explain.contains("[on ]   SC_HAS_ENV_MAP"),
        "{explain}"
    );

    let both = scene(
        &format!("{VIEW}{SKY}{}{BOX}", map_light(&map, 1.0)),
        "both.toml",
    );
    let err = format!("{:#}", plan::build(&both, None).unwrap_err());
    assert!(
        err.contains("[[light]] #2") && err.contains("cannot be combined"),
        "{err}"
    );
}

/// The camera's background is the map interpolated between texel centres (the shaders'
/// `env_lookup_bilinear`, `EnvMap::lookup_bilinear` on the CPU), in all three integrators:
/// through empty space, every pixel of an 8 × 4 checker-like map seen at its pixel
/// centre equals the CPU's bilinear lookup along that pixel's ray (within f32 rounding),
/// and the map is coarse enough that most pixels differ from the nearest texel.
#[test]
fn the_camera_sees_the_map_interpolated_between_texel_centres() {
    let ctx = context();
    let dir = crate::common::cli::scratch("box_env", "bilinear");
    let path = dir.join("checker.exr");
    let (w, h) = (8usize, 4usize);
    let texel = |x: usize, y: usize| {
        let v = ((x + 2 * y) % 5) as f32;
        (0.1 + 0.2 * v, 0.5 - 0.05 * v, 0.05 + 0.1 * (x % 3) as f32)
    };
    exr::prelude::write_rgb_file(&path, w, h, texel).unwrap();
    let map = nimbus_scene::EnvMap::load_exr(&path, glam::Vec3::ONE).unwrap();
    let zeros = dir.join("zeros.raw");
    std::fs::write(&zeros, vec![0u8; 8 * 4]).unwrap();
    // Towards −Z (the map's middle) and towards +Z, across the seam where u wraps.
    for look_at in ["[0.3, 0.45, -1]", "[0.1, 0.3, 1]"] {
        let head = format!(
            "[render]\nwidth = 24\nheight = 16\nspp = 1\nframes = 1\npixel_jitter = false\n\
         [camera]\nposition = [0, 0, 0]\nlook_at = {look_at}\nhorizontal_fov_deg = 150\n{}",
            map_light(&path, 1.0)
        );
        let grid = format!(
            "[[medium]]\ntype = \"grid\"\nbounds_min = [5, 5, 5]\nbounds_max = [6, 6, 6]\n\
         density = {{ file = \"{}\", dims = [2, 2, 2] }}\n",
            zeros.display()
        );
        for (label, text) in [
            ("crepuscular", head.clone()),
            (
                "baseline",
                format!("{head}{grid}[integrator]\nvolume = \"baseline\"\n"),
            ),
            (
                "restir",
                format!("{head}{grid}[integrator]\nvolume = \"restir\"\n"),
            ),
        ] {
            let s = scene(&text, "bilinear.toml");
            let image = render_checked(&ctx, &s, None).image;
            let mut off_nearest = 0;
            for y in 0..16u32 {
                for x in 0..24u32 {
                    let (_, d) = crate::oracle::aovs::centre_ray(&s, 0, x, y);
                    let want = map.lookup_bilinear(d.as_dvec3());
                    let nearest = map.lookup(d.as_dvec3());
                    let got = image.data[(y * 24 + x) as usize];
                    for c in 0..3 {
                        assert!(
                        (got[c] - want[c]).abs() <= 2e-3 * want[c].max(0.05),
                        "{label} towards {look_at}: pixel ({x}, {y}) channel {c}: {} against {} (nearest {})",
                        got[c],
                        want[c],
                        nearest[c]
                    );
                    }
                    off_nearest += usize::from((want[0] - nearest[0]).abs() > 0.02);
                }
            }
            assert!(
                off_nearest > 200,
                "{label}: only {off_nearest} pixels away from the nearest texel"
            );
        }
    }
}
