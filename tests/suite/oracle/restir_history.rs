//! ReSTIR's temporal history under change (issues 24 and 26): what a frame shows comes
//! from that frame's medium, lights and camera. A density that vanishes, or a sun that
//! goes out, leaves nothing of itself one frame later, and a moving camera's frames keep
//! the mean of the static scene of each frame.

use nimbus::output::ImageRgb;
use nimbus::plan;
use nimbus::renderer::{render, FrameSelection, RenderOptions};
use nimbus_scene::Scene;

use crate::common::cli::scratch;
use crate::common::gpu::{assert_no_validation_errors, context, scene};

/// Scene frame `frame` of `s`, one dispatch, after `warmup` frames of history (the frames
/// just before it), with seed `seed`.
fn frame_image(
    ctx: &nimbus_gpu::Context,
    s: &Scene,
    frame: u32,
    warmup: u32,
    seed: u64,
) -> ImageRgb {
    let mut s = s.clone();
    s.render.seed = seed;
    let plan = plan::build(&s, None).expect("plan");
    let opts = RenderOptions {
        frames: FrameSelection::Each {
            frames: vec![frame],
            passes: 1,
        },
        warmup_frames: warmup,
        ..Default::default()
    };
    let r = render(ctx, &s, &plan, &opts).expect("render");
    assert_eq!(r.non_finite_samples, 0);
    r.image
}

/// Checks that ReSTIR's frame 6 of `s` (after frames 0-5 of history), averaged over 12
/// seeds, has the image mean `expected` (the baseline's converged mean of that frame's
/// static scene) within 4 standard errors of the seeds' mean plus 0.5 %.
fn assert_frame6_mean(ctx: &nimbus_gpu::Context, s: &Scene, expected: f64, label: &str) {
    let means: Vec<f64> = (1..=12)
        .map(|seed| mean(&frame_image(ctx, s, 6, 6, seed)))
        .collect();
    let n = means.len() as f64;
    let m = means.iter().sum::<f64>() / n;
    let var = means.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0);
    let se = (var / n).sqrt();
    println!("{label}: frame 6 mean {m} +- {se} (12 seeds), baseline {expected}");
    assert!(
        (m - expected).abs() <= 4.0 * se + 0.005 * expected,
        "{label}: ReSTIR's frame 6 mean {m} +- {se} (12 seeds) against the baseline's {expected}"
    );
}

/// The mean of all channels of all pixels.
fn mean(image: &ImageRgb) -> f64 {
    image
        .data
        .iter()
        .map(|p| f64::from(p[0] + p[1] + p[2]))
        .sum::<f64>()
        / (3 * image.data.len()) as f64
}

/// The mean of a scene's render (a converged reference: the baseline's, at its spp).
fn render_mean(ctx: &nimbus_gpu::Context, s: &Scene) -> f64 {
    let plan = plan::build(s, None).expect("plan");
    mean(
        &render(ctx, s, &plan, &RenderOptions::default())
            .expect("render")
            .image,
    )
}

/// Root mean square difference of two images (all channels).
fn rmse(a: &ImageRgb, b: &ImageRgb) -> f64 {
    let sum: f64 = a
        .data
        .iter()
        .zip(&b.data)
        .flat_map(|(p, q)| (0..3).map(move |c| f64::from(p[c] - q[c]).powi(2)))
        .sum();
    (sum / (3 * a.data.len()) as f64).sqrt()
}

/// Counter `counter` of pass `slot` per sample over the frames of `s` after `warmup`
/// frames (`nimbus profile --counters`'s numbers).
fn work_per_sample(
    ctx: &nimbus_gpu::Context,
    s: &Scene,
    warmup: u32,
    slot: &str,
    counter: &str,
) -> f64 {
    let plan = plan::build(s, None).expect("plan");
    let opts = RenderOptions {
        warmup_frames: warmup,
        counters: true,
        ..Default::default()
    };
    let r = render(ctx, s, &plan, &opts).expect("render");
    r.work
        .expect("counts")
        .slot(slot)
        .unwrap_or_else(|| panic!("{slot} counters"))
        .per_sample(counter)
}

/// Writes an 8³ raw grid of `value` and returns its path as a TOML string.
fn grid_file(name: &str, value: f32) -> String {
    let path = scratch("restir-history", name).join("density.raw");
    std::fs::write(&path, bytemuck::cast_slice::<f32, u8>(&[value; 512])).expect("write grid");
    format!("{:?}", path.display().to_string())
}

const CAMERA: &str = r#"
[camera]
position = [0.0, 0.0, 3.0]
look_at = [0.0, 0.0, 0.0]
horizontal_fov_deg = 50
"#;

/// A unit cube of density 2 at frame 0 is gone from frame 1 on: frame 1 shows the sky
/// alone, in every pixel. The history held paths through the cube, and its Talbot weights
/// (the previous frame's target of this frame's sky paths is T = 0.14 of theirs) gave
/// this frame's own samples 1 / (1 + 20 T) of their weight: pixels were off by up to
/// 0.15 on a sky of 0.05.
#[test]
fn vanished_density_shows_nothing_one_frame_later() {
    let ctx = context();
    let ones = grid_file("ones", 1.0);
    let zeros = grid_file("zeros", 0.0);
    let text = format!(
        "[render]\nwidth = 32\nheight = 24\nframes = 2\n{CAMERA}\n\
         [[light]]\ntype = \"directional\"\ndirection = [0.3, -1.0, -0.2]\nirradiance = 3.0\n\
         [[light]]\ntype = \"environment\"\nradiance = 0.05\n\
         [[medium]]\ntype = \"grid\"\nbounds_min = [-0.5, -0.5, -0.5]\nbounds_max = [0.5, 0.5, 0.5]\n\
         density = {{ file = {ones}, dims = [8, 8, 8] }}\ndensity_scale = 2.0\nalbedo = 0.9\n\
         [[medium.frame]]\nframe = 1\ndensity = {{ file = {zeros}, dims = [8, 8, 8] }}\n"
    );
    let s = scene(&text, "vanished.toml");
    for seed in [1, 2] {
        let image = frame_image(&ctx, &s, 1, 1, seed);
        let worst = image
            .data
            .iter()
            .flat_map(|p| p.iter().map(|v| (v - 0.05).abs()))
            .fold(0.0f32, f32::max);
        // The sky's own candidates are exact (1e-6); what remains is the silhouette's
        // pixels, where the previous camera ray grazed the cube.
        assert!(
            worst <= 2.5e-3,
            "seed {seed}: a pixel of frame 1 is {worst} off the sky 0.05"
        );
    }
    assert_no_validation_errors(&ctx);
}

fn sun_scene(keyed: bool, sky: f32) -> String {
    let ones = grid_file("sun-ones", 1.0);
    let keys = if keyed {
        "[[light.keyframe]]\nframe = 0\nirradiance = 3.0\n\
         [[light.keyframe]]\nframe = 1\nirradiance = 0.0\n"
    } else {
        ""
    };
    let irradiance = if keyed { 3.0 } else { 0.0 };
    format!(
        "[render]\nwidth = 32\nheight = 24\nframes = 2\n{CAMERA}\n\
         [[light]]\ntype = \"directional\"\ndirection = [0.3, -1.0, -0.2]\nirradiance = {irradiance}\n\
         {keys}\
         [[light]]\ntype = \"environment\"\nradiance = {sky}\n\
         [[medium]]\ntype = \"grid\"\nbounds_min = [-0.5, -0.5, -0.5]\nbounds_max = [0.5, 0.5, 0.5]\n\
         density = {{ file = {ones}, dims = [8, 8, 8] }}\ndensity_scale = 2.0\nalbedo = 0.9\n"
    )
}

/// A sun of irradiance 3 goes out at frame 1 under a sky of 0.05: frame 1 is the cube lit
/// by the sky alone. The history's sun paths are worth nothing now, and its weight starved
/// this frame's sky paths: RMS error 0.0068-0.0085 against the converged sky-lit cube
/// (4 seeds), twice a history-free first frame's 0.0032-0.0037. With the lights' history
/// confidence (0 here) it is 0.0030-0.0035.
#[test]
fn a_sun_that_goes_out_leaves_nothing_behind() {
    let ctx = context();
    let animated = scene(&sun_scene(true, 0.05), "sun-out.toml");
    let mut dark = scene(&sun_scene(false, 0.05), "sun-off.toml");
    dark.render.frames = 256;
    let plan = plan::build(&dark, None).expect("plan");
    let reference = render(&ctx, &dark, &plan, &RenderOptions::default())
        .expect("render")
        .image;
    let errors: Vec<f64> = (1..=3)
        .map(|seed| rmse(&frame_image(&ctx, &animated, 1, 1, seed), &reference))
        .collect();
    let worst = errors.iter().copied().fold(0.0, f64::max);
    assert!(
        worst < 0.005,
        "frame 1's RMS errors against the sky-lit cube: {errors:?}"
    );
    assert_no_validation_errors(&ctx);
}

/// The lights, cloud and integrator of the moving-camera tests (a sun, a sky, a
/// procedural cloud, K = 2).
const DOLLY_BODY: &str =
    "[[light]]\ntype = \"directional\"\ndirection = [0.6, -0.5, -0.6]\nirradiance = 4.0\n\
     [[light]]\ntype = \"environment\"\nradiance = [0.25, 0.35, 0.55]\n\
     [[medium]]\ntype = \"grid\"\nbounds_min = [-1.0, -0.6, -1.0]\nbounds_max = [1.0, 0.6, 1.0]\n\
     density = { procedural = \"cloud\", dims = [32, 20, 32], noise_seed = 7 }\n\
     density_scale = 12.0\nalbedo = 0.9\n\
     [integrator]\nmax_bounces = 2\n";

/// A camera dollying towards a procedural cloud and turning around it (8 frames), under
/// a sun and a sky: the mean of frame 6 over 12 seeds (its history from frame 0 on)
/// agrees with the baseline's converged mean of that frame's static scene. Temporal
/// reuse shifts paths between the two frames' pixels by their depth past where each
/// pixel's ray enters the medium; a shift with a Jacobian other than 1, or weights that
/// depended on the samples, would bias it. The check's power: 12 seeds give a standard
/// error of 0.5 % of the mean, so it catches biases of about 3 % (storing the reused
/// path without its shift biases this frame by 1.4 %, which it does not catch).
#[test]
fn a_moving_camera_keeps_each_frames_mean() {
    let ctx = context();
    let body = DOLLY_BODY;
    let animated = format!(
        "[render]\nwidth = 24\nheight = 18\nframes = 8\n\
         [camera]\nhorizontal_fov_deg = 55\n\
         [[camera.keyframe]]\nframe = 0\nposition = [0.0, 0.3, 2.6]\nlook_at = [0.0, 0.0, 0.0]\n\
         [[camera.keyframe]]\nframe = 6\nposition = [0.5, 0.3, 1.5]\nlook_at = [0.0, 0.0, 0.0]\n\
         {body}"
    );
    let reference = format!(
        "[render]\nwidth = 24\nheight = 18\nframes = 1\nspp = 4096\n\
         [camera]\nhorizontal_fov_deg = 55\nposition = [0.5, 0.3, 1.5]\nlook_at = [0.0, 0.0, 0.0]\n\
         {}volume = \"baseline\"\n",
        body
    );
    let expected = render_mean(&ctx, &scene(&reference, "dolly-ref.toml"));
    // The defaults (temporal reuse aligned at each pixel's motion point, and spatial reuse
    // on the frames whose camera or density moved), the paper's reprojection of x_1,
    // and spatial reuse by the optical-depth shift on the pixels whose history is short
    // (the camera's motion drops it).
    let spatial = "[integrator.restir]\nspatial_neighbors = 3\nspatial_radius_px = 4\nspatial_when = \"always\"\n\
                   spatial_shift = \"optical_depth\"\nspatial_max_history = 8\n";
    let anchored = "[integrator.restir]\nspatial_neighbors = 3\nspatial_radius_px = 4\nspatial_when = \"always\"\n\
                    spatial_anchor = true\nspatial_feature_tolerance = 0.3\n";
    for (label, extra) in [
        ("defaults", ""),
        (
            "the paper's reprojection",
            "[integrator.restir]\ntemporal_reprojection = \"path\"\n",
        ),
        (
            "temporal reuse by the optical-depth shift, a long history",
            "[integrator.restir]\ntemporal_shift = \"optical_depth\"\ntemporal_limit_moving = 20\n",
        ),
        (
            "the optical-depth shift under the paper's reprojection",
            "[integrator.restir]\ntemporal_shift = \"optical_depth\"\ntemporal_reprojection = \"path\"\n",
        ),
        (
            "spatial and temporal reuse, both by the exact optical-depth shift",
            "[integrator.restir]\nspatial_neighbors = 3\nspatial_radius_px = 4\nspatial_when = \"always\"\n\
             spatial_shift = \"optical_depth_exact\"\ntemporal_shift = \"optical_depth\"\n",
        ),
        ("temporal + short-history spatial", spatial),
        (
            "temporal + spatial with depth anchors and the neighbour test",
            anchored,
        ),
    ] {
        let s = scene(&format!("{animated}{extra}"), "dolly.toml");
        assert_frame6_mean(&ctx, &s, expected, label);
    }
    assert_no_validation_errors(&ctx);
}

/// `temporal_limit_moving`: Q is the moving frames' where the camera moved, the density
/// frame changed or (with `env_reuse = "map"`) the environment map turned, and
/// `temporal_limit` on the others, chosen per frame. Below, the camera
/// (or the density) moves on frames 1-6 and holds still on frame 7, so (Q, Q moving) =
/// (20, 2) renders frame 6 as (2, 20) does (Q = 2 on every frame, the smaller of the two),
/// and frame 7 unlike it (its last frame takes Q = 20 against 2); (20, 20) renders frame 6
/// otherwise.
#[test]
fn the_moving_frames_temporal_limit_applies_where_the_camera_or_the_density_moved() {
    let ctx = context();
    let lights =
        "[[light]]\ntype = \"directional\"\ndirection = [0.6, -0.5, -0.6]\nirradiance = 4.0\n\
         [[light]]\ntype = \"environment\"\nradiance = [0.25, 0.35, 0.55]\n\
         [integrator]\nmax_bounces = 2\n";
    let medium = |frames: bool| {
        let cloud = |seed: u32| {
            format!("{{ procedural = \"cloud\", dims = [32, 20, 32], noise_seed = {seed} }}")
        };
        let mut m = format!(
            "[[medium]]\ntype = \"grid\"\nbounds_min = [-1.0, -0.6, -1.0]\nbounds_max = [1.0, 0.6, 1.0]\n\
             density = {}\ndensity_scale = 12.0\nalbedo = 0.9\n",
            cloud(7)
        );
        if frames {
            for f in 1..=6 {
                m += &format!(
                    "[[medium.frame]]\nframe = {f}\ndensity = {}\n",
                    cloud(7 + f)
                );
            }
        }
        m
    };
    let moving_camera = format!(
        "[camera]\nhorizontal_fov_deg = 55\n\
         [[camera.keyframe]]\nframe = 0\nposition = [0.0, 0.3, 2.6]\nlook_at = [0.0, 0.0, 0.0]\n\
         [[camera.keyframe]]\nframe = 6\nposition = [0.5, 0.3, 1.5]\nlook_at = [0.0, 0.0, 0.0]\n\
         {lights}{}",
        medium(false)
    );
    let moving_density = format!(
        "[camera]\nhorizontal_fov_deg = 55\nposition = [0.0, 0.3, 2.6]\nlook_at = [0.0, 0.0, 0.0]\n\
         {lights}{}",
        medium(true)
    );
    // An environment map turning 5° a frame over frames 0-6 under env_reuse = "map", whose
    // reused samples turn with it (with "world" its turn is a light's change alone).
    let map = scratch("restir_history", "turning-map").join("sky.exr");
    let (w, h) = (32, 16);
    let sun = nimbus_scene::sun_direction(35f32.to_radians(), 50f32.to_radians());
    let texels = nimbus_scene::daylight_sky(w, h, sun, 8f64.to_radians(), 3.0);
    exr::prelude::write_rgb_file(&map, w, h, |x, y| {
        let [r, g, b] = texels[y * w + x];
        (r, g, b)
    })
    .unwrap();
    let turning_map = format!(
        "[camera]\nhorizontal_fov_deg = 55\nposition = [0.0, 0.3, 2.6]\nlook_at = [0.0, 0.0, 0.0]\n\
         [[light]]\ntype = \"environment\"\nfile = \"{}\"\n\
         [[light.keyframe]]\nframe = 0\nrotation_deg = 0\n[[light.keyframe]]\nframe = 6\nrotation_deg = 30\n\
         [integrator]\nmax_bounces = 2\n{}",
        map.display(),
        medium(false)
    );
    for (label, body, extra) in [
        ("camera", moving_camera, ""),
        ("density", moving_density, ""),
        ("map", turning_map.clone(), "env_reuse = \"map\"\n"),
    ] {
        let with = |q: u32, q_moving: u32| {
            scene(
                &format!(
                    "[render]\nwidth = 16\nheight = 12\nframes = 8\n{body}\
                     [integrator.restir]\ntemporal_limit = {q}\ntemporal_limit_moving = {q_moving}\n{extra}"
                ),
                "q-moving.toml",
            )
        };
        let (short_moving, short, long) = (with(20, 2), with(2, 20), with(20, 20));
        let plan = plan::build(&short_moving, None).expect("plan");
        let p = plan.restir().expect("a ReSTIR plan");
        assert_eq!(
            (p.temporal_limit, p.temporal_limit_moving),
            (20, 2),
            "{label}"
        );
        let frame6 = |s: &Scene| frame_image(&ctx, s, 6, 6, 3);
        let a = frame6(&short_moving);
        assert!(
            a.data == frame6(&short).data,
            "{label}: frames 1-6 moved, Q = 2 on each"
        );
        assert!(
            rmse(&a, &frame6(&long)) > 0.0,
            "{label}: Q = 20 renders frame 6 otherwise"
        );
        let frame7 = |s: &Scene| frame_image(&ctx, s, 7, 7, 3);
        assert!(
            rmse(&frame7(&short_moving), &frame7(&short)) > 0.0,
            "{label}: frame 7 held still, Q = 20 there against 2"
        );
    }
    // Under env_reuse = "world" a turning map is no moving frame: Q = 20 throughout.
    let world = scene(
        &format!(
            "[render]\nwidth = 16\nheight = 12\nframes = 8\n{turning_map}\
             [integrator.restir]\ntemporal_limit = 20\ntemporal_limit_moving = 2\nenv_reuse = \"world\"\n"
        ),
        "q-moving.toml",
    );
    let plan = plan::build(&world, None).expect("plan");
    let p = plan.restir().expect("a ReSTIR plan");
    assert_eq!((p.temporal_limit, p.temporal_limit_moving), (20, 20));
    assert_no_validation_errors(&ctx);
}

/// `spatial_when`, chosen per frame from the two frames alone: under a still camera, the
/// default `"camera_or_density"` runs spatial reuse on the frames whose density frame
/// changed (frames 1-3 below) and not where it holds (frame 4), `"camera_moves"` on
/// none, `"always"` on all. Without temporal reuse a frame's image is its own candidates
/// and, where the frame runs it, its spatial reuse: so frame 1 renders as `"always"`
/// renders it and unlike `"camera_moves"`, and frames 0 and 4 the other way round.
#[test]
fn camera_or_density_runs_spatial_reuse_on_the_frames_whose_density_changed() {
    let ctx = context();
    let cloud = |seed: u32| {
        format!("{{ procedural = \"cloud\", dims = [32, 20, 32], noise_seed = {seed} }}")
    };
    let mut body = format!(
        "[render]\nwidth = 16\nheight = 12\nframes = 6\n\
         [camera]\nhorizontal_fov_deg = 55\nposition = [0.0, 0.3, 2.6]\nlook_at = [0.0, 0.0, 0.0]\n\
         [[light]]\ntype = \"directional\"\ndirection = [0.6, -0.5, -0.6]\nirradiance = 4.0\n\
         [[light]]\ntype = \"environment\"\nradiance = [0.25, 0.35, 0.55]\n\
         [integrator]\nmax_bounces = 2\n\
         [[medium]]\ntype = \"grid\"\nbounds_min = [-1.0, -0.6, -1.0]\nbounds_max = [1.0, 0.6, 1.0]\n\
         density = {}\ndensity_scale = 12.0\nalbedo = 0.9\n",
        cloud(7)
    );
    for f in 1..=3 {
        body += &format!(
            "[[medium.frame]]\nframe = {f}\ndensity = {}\n",
            cloud(7 + f)
        );
    }
    let with = |when: &str| {
        scene(
            &format!(
                "{body}[integrator.restir]\ntemporal = false\nspatial_neighbors = 3\n\
                 spatial_radius_px = 4\n{when}"
            ),
            "spatial-when.toml",
        )
    };
    let (default, camera, always) = (
        with(""),
        with("spatial_when = \"camera_moves\"\n"),
        with("spatial_when = \"always\"\n"),
    );
    let frame = |s: &Scene, f: u32| frame_image(&ctx, s, f, f, 5);
    for (f, spatial) in [(0, false), (1, true), (4, false)] {
        let d = frame(&default, f);
        let (same, other) = if spatial {
            (&always, &camera)
        } else {
            (&camera, &always)
        };
        assert!(
            d.data == frame(same, f).data,
            "frame {f}: spatial reuse {}",
            if spatial { "runs" } else { "does not run" }
        );
        assert!(
            rmse(&d, &frame(other, f)) > 0.0,
            "frame {f}: spatial reuse changes the image"
        );
    }
    assert_no_validation_errors(&ctx);
}

/// Camera, sun and density changing together (issue 26): the camera dollies and turns,
/// the sun turns by 30°, and the density is swapped for another cloud at frames 3 and 5.
/// ReSTIR's defaults (temporal reuse with its confidence weights, spatial reuse on the
/// frames whose camera or density moved) keep frame 6's mean over 12 seeds at the baseline's
/// converged mean of frame 6's static scene: nothing of the old frames' density, light
/// or view biases it.
#[test]
fn camera_sun_and_density_changing_together_keep_each_frames_mean() {
    let ctx = context();
    let medium = |seed: u32| {
        format!(
            "density = {{ procedural = \"cloud\", dims = [32, 20, 32], noise_seed = {seed} }}\n"
        )
    };
    let grid = "[[medium]]\ntype = \"grid\"\nbounds_min = [-1.0, -0.6, -1.0]\n\
                bounds_max = [1.0, 0.6, 1.0]\ndensity_scale = 12.0\nalbedo = 0.9\n";
    let sky = "[[light]]\ntype = \"environment\"\nradiance = [0.25, 0.35, 0.55]\n";
    let animated = format!(
        "[render]\nwidth = 24\nheight = 18\nframes = 8\n\
         [camera]\nhorizontal_fov_deg = 55\n\
         [[camera.keyframe]]\nframe = 0\nposition = [0.0, 0.3, 2.6]\nlook_at = [0.0, 0.0, 0.0]\n\
         [[camera.keyframe]]\nframe = 6\nposition = [0.5, 0.3, 1.5]\nlook_at = [0.0, 0.0, 0.0]\n\
         [[light]]\ntype = \"directional\"\nirradiance = 4.0\n\
         [[light.keyframe]]\nframe = 0\ndirection = [0.6, -0.5, -0.6]\n\
         [[light.keyframe]]\nframe = 6\ndirection = [-0.2, -0.6, -0.77]\n\
         {sky}{grid}{}\
         [[medium.frame]]\nframe = 3\n{}\
         [[medium.frame]]\nframe = 5\n{}\
         [integrator]\nmax_bounces = 2\n",
        medium(7),
        medium(8),
        medium(9)
    );
    let reference = format!(
        "[render]\nwidth = 24\nheight = 18\nframes = 1\nspp = 4096\n\
         [camera]\nhorizontal_fov_deg = 55\nposition = [0.5, 0.3, 1.5]\nlook_at = [0.0, 0.0, 0.0]\n\
         [[light]]\ntype = \"directional\"\nirradiance = 4.0\ndirection = [-0.2, -0.6, -0.77]\n\
         {sky}{grid}{}\
         [integrator]\nmax_bounces = 2\nvolume = \"baseline\"\n",
        medium(9)
    );
    let expected = render_mean(&ctx, &scene(&reference, "together-ref.toml"));
    let s = scene(&animated, "together.toml");
    let restir = plan::build(&s, None).expect("plan");
    assert!(
        restir.restir().is_some_and(|p| p.spatial_neighbors > 0),
        "the defaults reuse spatially under a moving camera"
    );
    assert_frame6_mean(&ctx, &s, expected, "camera, sun and density");
    assert_no_validation_errors(&ctx);
}

/// `candidates_settled`: a static scene's frames draw M = 4 candidates until Q = 2 frames
/// in a row kept their target, then 1, with the history's cap of Q·M = 8 candidates
/// kept. Frame 1 (one frame in a row) renders as without it, frame 2 (two) otherwise; a
/// settled frame (6) keeps the baseline's converged mean over 12 seeds (the choice
/// depends on the frames alone, never on the samples). And the settled frames do less
/// work: the initial pass's tracking steps per sample fall from 2.78 to 1.60 (a pixel's
/// fixed walks stay, its candidates' fall by 4x).
#[test]
fn settled_frames_draw_fewer_candidates_and_keep_the_mean() {
    let ctx = context();
    let ones = grid_file("settled-ones", 1.0);
    let body = format!(
        "{CAMERA}\n\
         [[light]]\ntype = \"directional\"\ndirection = [0.3, -1.0, -0.2]\nirradiance = 3.0\n\
         [[light]]\ntype = \"environment\"\nradiance = 0.05\n\
         [[medium]]\ntype = \"grid\"\nbounds_min = [-0.5, -0.5, -0.5]\nbounds_max = [0.5, 0.5, 0.5]\n\
         density = {{ file = {ones}, dims = [8, 8, 8] }}\ndensity_scale = 2.0\nalbedo = 0.9\n\
         [integrator]\nmax_bounces = 2\n"
    );
    let with = |settled: u32| {
        scene(
            &format!(
                "[render]\nwidth = 32\nheight = 24\nframes = 8\n{body}\
                 [integrator.restir]\ntemporal = true\ntemporal_limit = 2\ncandidates = 4\n\
                 candidates_settled = {settled}\n"
            ),
            "settled.toml",
        )
    };
    let (settled, full) = (with(1), with(4));
    let plan = plan::build(&settled, None).expect("plan");
    assert_eq!(plan.restir().unwrap().candidates_settled(), Some(1));
    assert_eq!(
        plan::build(&full, None)
            .unwrap()
            .restir()
            .unwrap()
            .candidates_settled(),
        None
    );
    assert!(
        frame_image(&ctx, &settled, 1, 1, 3).data == frame_image(&ctx, &full, 1, 1, 3).data,
        "frame 1: one frame in a row, M = 4"
    );
    assert!(
        rmse(
            &frame_image(&ctx, &settled, 2, 2, 3),
            &frame_image(&ctx, &full, 2, 2, 3)
        ) > 0.0,
        "frame 2: Q frames in a row, M = 1"
    );
    // The work per sample of 8 frames after 4, all settled, against M = 4 throughout.
    let initial_steps = |s: &Scene| work_per_sample(&ctx, s, 4, "restir/initial", "steps");
    let (settled_steps, full_steps) = (initial_steps(&settled), initial_steps(&full));
    assert!(
        settled_steps < 0.7 * full_steps && settled_steps > 0.1 * full_steps,
        "tracking steps per sample in the initial pass: {settled_steps} settled, {full_steps} with M = 4"
    );
    let mut reference = scene(
        &format!(
            "[render]\nwidth = 32\nheight = 24\nframes = 1\nspp = 4096\n{body}volume = \"baseline\"\n"
        ),
        "settled-ref.toml",
    );
    reference.render.frames = 1;
    let expected = render_mean(&ctx, &reference);
    assert_frame6_mean(&ctx, &settled, expected, "settled M = 1 from frame 2");
    assert_no_validation_errors(&ctx);
}

/// A sun turning by 30° over a still camera and a still cloud (issue 26's moving sun):
/// the temporal pass takes the pixel itself as its neighbour, at the camera's full
/// confidence, without walking to the motion point or marching the two frames' centre
/// rays (`history_static` = 2: only the lights changed). Frame 6's mean over 12 seeds
/// stays at the baseline's converged mean of frame 6's static scene: the choice depends on
/// the two frames alone, and the history's light confidence still discounts the sun's
/// old paths.
#[test]
fn a_sun_turning_over_a_still_camera_keeps_each_frames_mean() {
    let ctx = context();
    let body = "[camera]\nhorizontal_fov_deg = 55\nposition = [0.0, 0.3, 2.6]\nlook_at = [0.0, 0.0, 0.0]\n\
         [[light]]\ntype = \"environment\"\nradiance = [0.25, 0.35, 0.55]\n\
         [[medium]]\ntype = \"grid\"\nbounds_min = [-1.0, -0.6, -1.0]\nbounds_max = [1.0, 0.6, 1.0]\n\
         density = { procedural = \"cloud\", dims = [32, 20, 32], noise_seed = 7 }\n\
         density_scale = 12.0\nalbedo = 0.9\n";
    let animated = format!(
        "[render]\nwidth = 24\nheight = 18\nframes = 8\n{body}\
         [[light]]\ntype = \"directional\"\nirradiance = 4.0\n\
         [[light.keyframe]]\nframe = 0\ndirection = [0.6, -0.5, -0.6]\n\
         [[light.keyframe]]\nframe = 6\ndirection = [-0.2, -0.6, -0.77]\n\
         [integrator]\nmax_bounces = 2\n"
    );
    let reference = format!(
        "[render]\nwidth = 24\nheight = 18\nframes = 1\nspp = 4096\n{body}\
         [[light]]\ntype = \"directional\"\nirradiance = 4.0\ndirection = [-0.2, -0.6, -0.77]\n\
         [integrator]\nmax_bounces = 2\nvolume = \"baseline\"\n"
    );
    let expected = render_mean(&ctx, &scene(&reference, "sun-turning-ref.toml"));
    let s = scene(&animated, "sun-turning.toml");
    assert_frame6_mean(&ctx, &s, expected, "a sun turning over a still camera");
    assert_no_validation_errors(&ctx);
}

/// The shade cache: on a still frame whose temporal stage keeps a pixel's path, final
/// shading reuses the F it evaluated for that path on the previous frame. F is a function
/// of the path and the scene alone (closed-form transmittance), so the images are the
/// cache-less ones bit for bit: on still frames, on the first still frame after the camera
/// moved (whose previous frame shaded the spatial pass's output, not the history: no
/// reuse), and on the moving frames. The shading's work per sample on a still scene falls
/// to a fraction (most pixels keep their path).
#[test]
fn still_frames_reuse_the_shaded_f_of_kept_paths_and_render_the_same_images() {
    let ctx = context();
    let body = DOLLY_BODY;
    // Still on frames 0-2, moving on 3-4 (spatial reuse runs there), still from 5 on.
    let animated = |cache: bool| {
        format!(
            "[render]\nwidth = 24\nheight = 18\nframes = 8\n\
             [camera]\nhorizontal_fov_deg = 55\n\
             [[camera.keyframe]]\nframe = 0\nposition = [0.0, 0.3, 2.6]\nlook_at = [0.0, 0.0, 0.0]\n\
             [[camera.keyframe]]\nframe = 2\nposition = [0.0, 0.3, 2.6]\nlook_at = [0.0, 0.0, 0.0]\n\
             [[camera.keyframe]]\nframe = 4\nposition = [0.4, 0.3, 2.0]\nlook_at = [0.0, 0.0, 0.0]\n\
             {body}[integrator.restir]\nshade_cache = {cache}\n"
        )
    };
    let (on, off) = (
        scene(&animated(true), "cache-on.toml"),
        scene(&animated(false), "cache-off.toml"),
    );
    let aov = plan::AovPlan::of(&on);
    assert!(plan::build(&on, None)
        .unwrap()
        .restir()
        .unwrap()
        .keeps_shade_cache(&aov));
    assert!(!plan::build(&off, None)
        .unwrap()
        .restir()
        .unwrap()
        .keeps_shade_cache(&aov));
    for frame in [2, 4, 5, 7] {
        assert!(
            frame_image(&ctx, &on, frame, frame, 5).data
                == frame_image(&ctx, &off, frame, frame, 5).data,
            "frame {frame}: the cached F must render the image the evaluated F renders"
        );
    }
    // A still scene: the shading's shadow-ray steps per sample over 8 frames after 8.
    let still = |cache: bool| {
        scene(
            &format!(
                "[render]\nwidth = 24\nheight = 18\nframes = 8\n\
                 [camera]\nhorizontal_fov_deg = 55\nposition = [0.0, 0.3, 2.6]\nlook_at = [0.0, 0.0, 0.0]\n\
                 {body}[integrator.restir]\ntemporal = true\nshade_cache = {cache}\n"
            ),
            "cache-still.toml",
        )
    };
    let shade_steps = |s: &Scene| work_per_sample(&ctx, s, 8, "restir/shade", "shadow_steps");
    let (cached, evaluated) = (shade_steps(&still(true)), shade_steps(&still(false)));
    println!("shadow steps per sample in shading: {cached} cached, {evaluated} evaluated");
    assert!(
        evaluated > 0.0 && cached < 0.3 * evaluated,
        "shadow steps per sample in shading: {cached} with the cache, {evaluated} without"
    );
    assert_no_validation_errors(&ctx);
}

/// `still_target = "initial"`: a still frame's temporal reuse resamples each reservoir by
/// its own stored target (the fresh sample's initial target, the history's whatever it
/// kept), under the constant MIS weights M_i / ΣM, so it evaluates no target at all: the
/// temporal pass of a still scene marches no shadow ray. Frame 6 of a camera that holds
/// still, moves (spatial reuse runs there) and holds still again, whose first still frames
/// combine histories holding the reuse target with fresh samples holding the initial one,
/// keeps the baseline's mean over 12 seeds: with the delta-tracked candidates' target,
/// and with regular tracking's T* in it and the NEE segments marched on mip 3, far from
/// the reuse target.
#[test]
fn still_frames_combine_with_the_initial_target_and_keep_each_frames_mean() {
    let ctx = context();
    let body = DOLLY_BODY;
    let still = |target: &str| {
        scene(
            &format!(
                "[render]\nwidth = 24\nheight = 18\nframes = 8\n\
                 [camera]\nhorizontal_fov_deg = 55\nposition = [0.0, 0.3, 2.6]\nlook_at = [0.0, 0.0, 0.0]\n\
                 {body}[integrator.restir]\ntemporal = true\nstill_target = \"{target}\"\n"
            ),
            "still-target.toml",
        )
    };
    let builds = |s: &Scene| {
        plan::build(s, None)
            .expect("plan")
            .restir()
            .expect("restir")
            .still_initial_target()
    };
    assert!(builds(&still("initial")) && !builds(&still("reuse")));
    // "auto": the initial target where the candidates are delta tracked.
    let auto = plan::build(&still("auto"), None).expect("plan");
    let auto = auto.restir().expect("restir");
    assert_eq!(auto.still_initial_target(), auto.candidate_delta);
    let temporal_steps = |s: &Scene| work_per_sample(&ctx, s, 8, "restir/temporal", "shadow_steps");
    let (initial, reuse) = (
        temporal_steps(&still("initial")),
        temporal_steps(&still("reuse")),
    );
    println!(
        "shadow steps per sample in the still temporal pass: {initial} initial, {reuse} reuse"
    );
    assert!(
        initial == 0.0 && reuse > 0.0,
        "shadow steps per sample in the still temporal pass: {initial} with the initial target, {reuse} with the reuse target"
    );
    // Still on frames 0-2, moving on 3-4, still from 5 on; frame 6 against the baseline's
    // converged mean at the last camera.
    let reference = format!(
        "[render]\nwidth = 24\nheight = 18\nframes = 1\nspp = 4096\n\
         [camera]\nhorizontal_fov_deg = 55\nposition = [0.4, 0.3, 2.0]\nlook_at = [0.0, 0.0, 0.0]\n\
         {body}volume = \"baseline\"\n"
    );
    let expected = render_mean(&ctx, &scene(&reference, "still-target-ref.toml"));
    for (label, extra) in [
        ("delta-tracked candidates", ""),
        (
            "regular tracking, NEE on mip 3",
            "candidate_tracking = \"regular\"\nmip_indirect = 3\n",
        ),
    ] {
        let s = scene(
            &format!(
                "[render]\nwidth = 24\nheight = 18\nframes = 8\n\
                 [camera]\nhorizontal_fov_deg = 55\n\
                 [[camera.keyframe]]\nframe = 0\nposition = [0.0, 0.3, 2.6]\nlook_at = [0.0, 0.0, 0.0]\n\
                 [[camera.keyframe]]\nframe = 2\nposition = [0.0, 0.3, 2.6]\nlook_at = [0.0, 0.0, 0.0]\n\
                 [[camera.keyframe]]\nframe = 4\nposition = [0.4, 0.3, 2.0]\nlook_at = [0.0, 0.0, 0.0]\n\
                 {body}[integrator.restir]\nstill_target = \"initial\"\n{extra}"
            ),
            "still-target-dolly.toml",
        );
        assert!(builds(&s), "{label}");
        assert_frame6_mean(&ctx, &s, expected, label);
    }
    assert_no_validation_errors(&ctx);
}
