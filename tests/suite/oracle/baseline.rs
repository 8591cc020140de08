//! The baseline path tracer for grid media on lavapipe: the furnace test, agreement
//! with the independent CPU delta-tracking oracle, and a golden image. Validation
//! layers are on.

use crate::common::gpu::{
    assert_means_agree, channels_beyond, context, render_checked, scene, se_of_mean,
};
use crate::common::{compare_with_golden, SAME_DEVICE};

/// A procedural cloud; `{albedo}`, `{g}`, `{bounces}`, `{scale}`, `{lights}` and the
/// camera position are filled in per test.
fn cloud_scene(
    position: &str,
    albedo: f32,
    g: f32,
    bounces: u32,
    scale: f32,
    lights: &str,
    size: (u32, u32),
) -> String {
    format!(
        r#"
[render]
width = {w}
height = {h}
frames = 32
spp = 4
seed = 11
[camera]
position = {position}
look_at = [0.0, 0.0, 0.0]
horizontal_fov_deg = 60
{lights}
[[medium]]
type = "grid"
bounds_min = [-1.0, -0.6, -1.0]
bounds_max = [1.0, 0.6, 1.0]
density = {{ procedural = "cloud", dims = [32, 20, 32], noise_seed = 3 }}
density_scale = {scale:?}
albedo = {albedo:?}
g = {g:?}
[integrator]
volume = "baseline"
max_bounces = {bounces}
"#,
        w = size.0,
        h = size.1
    )
}

/// Render `scene` on the GPU and with the CPU oracle (`nimbus_reference::grid`: delta
/// tracking and ratio tracking with one global majorant, f64; 1024 paths per pixel over
/// 4x4 footprint strata) and check that every channel's image mean agrees within 1% plus
/// 4 combined standard errors, and that at most 2% of the pixel channels differ by more
/// than 4.5 combined standard errors.
pub(crate) fn check_against_oracle(
    ctx: &nimbus_gpu::Context,
    scene: &nimbus_scene::Scene,
    seed: u64,
    label: &str,
) {
    use nimbus::output::ImageRgb;
    use nimbus_reference::grid::{render_grid_mc, GridOptions};
    let (w, h) = (scene.render.width, scene.render.height);
    let gpu = render_checked(ctx, scene, None);
    let (cpu_mean, cpu_se) = render_grid_mc(
        scene,
        &GridOptions {
            max_bounces: scene.integrator.max_bounces,
            paths: 1024,
            seed,
        },
        4,
    )
    .expect("cpu oracle");
    let cpu = ImageRgb::from_rgb_f64(w, h, &cpu_mean).unwrap();
    let cpu_se = ImageRgb::from_rgb_f64(w, h, &cpu_se).unwrap();
    let (gpu, cpu) = ((&gpu.image, &gpu.std_error), (&cpu, &cpu_se));
    assert_means_agree(&format!("{label}: gpu vs cpu"), gpu, cpu, 4.0, 0.01);
    let beyond = channels_beyond(gpu, cpu, 4.5);
    let channels = 3 * gpu.0.data.len();
    println!("  {beyond} of {channels} channels beyond 4.5 SE");
    assert!(
        beyond * 50 <= channels,
        "{label}: {beyond} channels beyond 4.5 SE"
    );
}

/// A non-absorbing cloud (albedo 1) under a constant environment of radiance 1 with
/// K = 256 renders radiance 1 everywhere, from outside and from inside the cloud: the
/// image mean is within 1% of 1 and no pixel strays beyond 5 standard errors + 2%.
/// (K is finite, so energy that needs more than 256 scatterings to leave is lost; at
/// this density that is far below 1%.)
#[test]
fn furnace_non_absorbing_cloud_under_constant_environment() {
    let ctx = context();
    let env = "[[light]]\ntype = \"environment\"\nradiance = 1.0";
    for (name, position) in [
        ("outside", "[0.2, 0.4, 2.6]"),
        ("inside", "[0.05, 0.0, 0.1]"),
    ] {
        let text = cloud_scene(position, 1.0, 0.3, 256, 12.0, env, (24, 18));
        let scene = scene(&text, &format!("furnace-{name}.toml"));
        let result = render_checked(&ctx, &scene, None);
        let mean = result.image.mean();
        println!(
            "furnace {name}: mean {mean:?}, SE {:.2e}",
            se_of_mean(&result.std_error)
        );
        for (c, m) in mean.iter().enumerate() {
            assert!((m - 1.0).abs() < 0.01, "{name}: channel {c} mean {m}");
        }
        for (px, se) in result.image.data.iter().zip(&result.std_error.data) {
            for c in 0..3 {
                let (v, s) = (f64::from(px[c]), f64::from(se[c]));
                assert!((v - 1.0).abs() <= 5.0 * s + 0.02, "{name}: pixel {v} ± {s}");
            }
        }
    }
}

/// The cloud scene at a small size against its golden (limits: `SAME_DEVICE`).
#[test]
fn golden_cloud_baseline() {
    let ctx = context();
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/scenes/cloud.toml");
    let text = std::fs::read_to_string(path).expect("cloud scene");
    // (Its path, not its name alone: the sky map is relative to it.)
    let mut scene = scene(&text, path);
    scene.render.width = 64;
    scene.render.height = 48;
    scene.render.frames = 2;
    scene.render.spp = 2;
    let result = render_checked(&ctx, &scene, None);
    compare_with_golden("cloud-baseline-64x48", &result.image, SAME_DEVICE).unwrap();
}

/// The baseline (decomposition tracking + residual ratio tracking on super-voxels)
/// converges to the independent CPU oracle (delta tracking + ratio tracking with one
/// global majorant, f64) on the cloud, single and 3-bounce, g = 0 and 0.8, with a sun,
/// a point light and a sky: image means within 1% (plus 4 combined standard errors)
/// and at most 2% of the pixel channels beyond 4.5 combined standard errors.
#[test]
fn baseline_matches_the_cpu_delta_tracking_oracle() {
    let ctx = context();
    let lights = "[[light]]\ntype = \"directional\"\ndirection = [0.5, -0.7, -0.4]\nirradiance = [3.0, 2.7, 2.4]\n\
                  [[light]]\ntype = \"point\"\nposition = [1.4, 0.9, 0.6]\nintensity = 2.0\n\
                  [[light]]\ntype = \"environment\"\nradiance = [0.2, 0.3, 0.45]";
    for (bounces, g) in [(1u32, 0.0f32), (3, 0.0), (1, 0.8), (3, 0.8)] {
        let text = cloud_scene("[0.3, 0.5, 2.4]", 0.9, g, bounces, 16.0, lights, (16, 12));
        check_against_oracle(
            &ctx,
            &scene(&text, "oracle.toml"),
            5,
            &format!("K={bounces} g={g}"),
        );
    }
}

/// Split next-event estimation (`[integrator.baseline] nee = "split"`: every delta light
/// at every vertex plus one sample of the others) converges to the CPU oracle, which
/// picks one light per vertex: a sun, a point light, a sky and a sphere light (so the
/// sample of the others chooses between two), above a reflecting floor (the surface
/// vertices' NEE), K = 1 at g = 0 and K = 3 at g = 0.8; same criteria as above.
#[test]
fn split_next_event_estimation_matches_the_cpu_oracle() {
    let ctx = context();
    let lights = "[[light]]\ntype = \"directional\"\ndirection = [0.5, -0.7, -0.4]\nirradiance = [3.0, 2.7, 2.4]\n\
                  [[light]]\ntype = \"point\"\nposition = [1.4, 0.9, 0.6]\nintensity = 2.0\n\
                  [[light]]\ntype = \"environment\"\nradiance = [0.2, 0.3, 0.45]\n\
                  [[light]]\ntype = \"sphere\"\ncenter = [-1.3, 0.8, 0.9]\nradius = 0.2\nradiance = [40.0, 30.0, 20.0]\n\
                  [[shape]]\ntype = \"quad\"\ncorner = [-1.6, -0.7, 1.6]\nedge_u = [3.2, 0.0, 0.0]\nedge_v = [0.0, 0.0, -3.2]\nalbedo = 0.5\n";
    for (bounces, g) in [(1u32, 0.0f32), (3, 0.8)] {
        let text = format!(
            "{}[integrator.baseline]\nnee = \"split\"\n",
            cloud_scene("[0.3, 0.5, 2.4]", 0.9, g, bounces, 16.0, lights, (16, 12))
        );
        let scene = scene(&text, "split.toml");
        let plan = nimbus::plan::build(&scene, None).expect("plan");
        assert!(plan.baseline().expect("the baseline").nee_split);
        check_against_oracle(&ctx, &scene, 5, &format!("split K={bounces} g={g}"));
    }
}

/// Split NEE whose other light is a constant sky alone (the default at any K with one
/// sun): the sky's NEE rides on the path's next segment, whose one walk samples the next
/// collision and estimates the sky's transmittance (SC_SKY_ALONG_PATH), and where Russian
/// roulette ends the path (from the fourth segment) the sky gets its own shadow ray. It
/// converges to the CPU oracle with a sun and a sky above a reflecting floor, K = 3 at
/// g = 0.8 and K = 6 at g = 0 (Russian roulette); same criteria as above.
#[test]
fn the_sky_along_the_path_matches_the_cpu_oracle() {
    let ctx = context();
    let lights = "[[light]]\ntype = \"directional\"\ndirection = [0.5, -0.7, -0.4]\nirradiance = [3.0, 2.7, 2.4]\n\
                  [[light]]\ntype = \"environment\"\nradiance = [0.4, 0.6, 0.9]\n\
                  [[shape]]\ntype = \"quad\"\ncorner = [-1.6, -0.7, 1.6]\nedge_u = [3.2, 0.0, 0.0]\nedge_v = [0.0, 0.0, -3.2]\nalbedo = 0.5\n";
    for (bounces, g) in [(3u32, 0.8f32), (6, 0.0)] {
        let text = cloud_scene("[0.3, 0.5, 2.4]", 0.9, g, bounces, 16.0, lights, (16, 12));
        let scene = scene(&text, "sky-along.toml");
        let plan = nimbus::plan::build(&scene, None).expect("plan");
        let baseline = plan.baseline().expect("the baseline");
        assert!(baseline.nee_split && baseline.sky_along_path);
        check_against_oracle(&ctx, &scene, 5, &format!("sky along K={bounces} g={g}"));
    }
}

/// An emitting, absorbing cloud (the absorbed-emission convention: sigma_a Le) with a
/// sun, K = 1 and K = 3: the baseline matches the CPU oracle (same criteria as above).
#[test]
fn emission_matches_the_cpu_oracle() {
    let ctx = context();
    let lights =
        "[[light]]\ntype = \"directional\"\ndirection = [0.5, -0.7, -0.4]\nirradiance = 1.0";
    for bounces in [1u32, 3] {
        let text = cloud_scene("[0.3, 0.5, 2.4]", 0.6, 0.3, bounces, 16.0, lights, (16, 12)).replace(
            "albedo = 0.6",
            "albedo = 0.6\nemission = { procedural = \"cloud\", dims = [16, 10, 16], noise_seed = 9 }\nemission_scale = [4.0, 2.0, 0.5]",
        );
        check_against_oracle(
            &ctx,
            &scene(&text, "emission.toml"),
            8,
            &format!("emission K={bounces}"),
        );
    }
}

/// An rgb emission grid (a 3-channel half-float `.vol`, each channel another cloud) with
/// a sun, K = 2: the baseline matches the CPU oracle, so every channel is read as itself.
#[test]
fn rgb_emission_vol_matches_the_cpu_oracle() {
    let ctx = context();
    let dir = crate::common::cli::scratch("baseline", "rgb-emission");
    let dims = [12u32, 8, 12];
    let clouds: Vec<_> = (0..3)
        .map(|c| nimbus_scene::procedural_cloud(dims, 11 + c))
        .collect();
    let rgb = nimbus_scene::VoxelGrid {
        dims,
        channels: 3,
        data: (0..clouds[0].data.len())
            .flat_map(|i| [0, 1, 2].map(|c| clouds[c].data[i]))
            .collect(),
    };
    let path = dir.join("rgb.vol");
    nimbus_scene::write_vol_encoded(
        &path,
        &rgb,
        glam::Vec3::ZERO,
        glam::Vec3::ONE,
        nimbus_scene::VolEncoding::F16,
    )
    .expect("write rgb.vol");
    let lights =
        "[[light]]\ntype = \"directional\"\ndirection = [0.5, -0.7, -0.4]\nirradiance = 1.0";
    let text = cloud_scene("[0.3, 0.5, 2.4]", 0.6, 0.3, 2, 16.0, lights, (16, 12)).replace(
        "albedo = 0.6",
        &format!(
            "albedo = 0.6\nemission = {{ file = {:?} }}\nemission_scale = [3.0, 2.0, 4.0]",
            path.display().to_string()
        ),
    );
    check_against_oracle(
        &ctx,
        &scene(&text, "rgb-emission.toml"),
        8,
        "rgb emission K=2",
    );
}

/// A homogeneous box medium (a fog layer) below the cloud, K = 1 and 3: the baseline's
/// mixed free flights and shadow rays match the CPU oracle.
#[test]
fn box_beside_grid_matches_the_cpu_oracle() {
    let ctx = context();
    let lights =
        "[[light]]\ntype = \"directional\"\ndirection = [0.3, -0.8, -0.4]\nirradiance = 2.0\n\
                  [[light]]\ntype = \"environment\"\nradiance = 0.3";
    for bounces in [1u32, 3] {
        let mut text = cloud_scene("[0.4, 0.2, 2.8]", 0.9, 0.4, bounces, 16.0, lights, (16, 12));
        text.push_str(
            "[[medium]]\ntype = \"box\"\ncenter = [0.0, -1.2, 0.0]\nsize = [3.0, 0.5, 3.0]\nsigma_t = 1.5\nalbedo = 0.8\n",
        );
        check_against_oracle(
            &ctx,
            &scene(&text, "box-grid.toml"),
            4,
            &format!("box+grid K={bounces}"),
        );
    }
}

/// An environment map (a sky gradient with a bright sun texel and a dark ground),
/// importance sampled in next-event estimation and seen by camera rays: the baseline
/// matches the CPU oracle at K = 1 and 3.
#[test]
fn environment_map_matches_the_cpu_oracle() {
    let dir = crate::common::cli::scratch("baseline", "envmap");
    let (w, h) = (32u32, 16u32);
    let mut sky = nimbus::output::ImageRgb::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let v = (y as f32 + 0.5) / h as f32;
            let rgb = if v > 0.6 {
                [0.05, 0.04, 0.03]
            } else {
                [0.3 + 0.4 * v, 0.45 + 0.3 * v, 0.9]
            };
            sky.set(x, y, rgb);
        }
    }
    sky.set(20, 4, [200.0, 180.0, 150.0]);
    let path = dir.join("sky.exr");
    nimbus::output::write_image(&path, &sky, 1.0).expect("write sky");
    let lights = format!(
        "[[light]]\ntype = \"environment\"\nfile = {:?}\nscale = 0.8",
        path.display().to_string()
    );
    let ctx = context();
    for bounces in [1u32, 3] {
        let text = cloud_scene(
            "[0.3, 0.4, 2.4]",
            0.9,
            0.5,
            bounces,
            16.0,
            &lights,
            (16, 12),
        );
        check_against_oracle(
            &ctx,
            &scene(&text, "envmap.toml"),
            6,
            &format!("env map K={bounces}"),
        );
    }
}

/// The baseline renders animated density (issue 26: it refused `[[medium.frame]]`, so
/// ReSTIR's motion scenes had no equal-time reference): frame k of the animated plume is
/// exactly the baseline image of the same animation with frame k's density as its only
/// grid (same seed, camera and sun keyframes), and its mean agrees with ReSTIR's.
#[test]
fn the_baseline_renders_each_frames_density() {
    use nimbus_scene::{Medium, VolumeIntegrator};
    let ctx = context();
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/scenes/plume-anim.toml");
    let mut plume = nimbus_scene::load(std::path::Path::new(path)).expect("plume");
    plume.render.width = 24;
    plume.render.height = 18;
    plume.integrator.volume = VolumeIntegrator::Baseline;
    let frame = |s: &nimbus_scene::Scene, f: u32, passes: u32| {
        crate::common::gpu::render_scene_frame(&ctx, s, f, passes).image
    };
    for k in [0u32, 2] {
        let animated = frame(&plume, k, 4);
        let mut single = plume.clone();
        if let Medium::Grid(g) = &mut single.media[0] {
            g.density = g.density_at(k).clone();
            g.frames.clear();
        }
        assert!(single.is_animated(), "the camera and sun keyframes remain");
        assert_eq!(animated.data, frame(&single, k, 4).data, "frame {k}");
    }
    let mean = |img: &nimbus::output::ImageRgb| {
        img.data
            .iter()
            .map(|p| f64::from(p[0] + p[1] + p[2]))
            .sum::<f64>()
            / (3 * img.data.len()) as f64
    };
    let baseline = mean(&frame(&plume, 3, 256));
    let mut restir = plume.clone();
    restir.integrator.volume = VolumeIntegrator::Restir;
    let restir = mean(&frame(&restir, 3, 256));
    assert!(
        (baseline / restir - 1.0).abs() < 0.03,
        "frame 3: baseline {baseline}, ReSTIR {restir}"
    );
    crate::common::gpu::assert_no_validation_errors(&ctx);
}
