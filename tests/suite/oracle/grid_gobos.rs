//! Gobos on directional lights in grid scenes, on lavapipe with validation layers on:
//! the baseline path tracer agrees with the independent CPU oracle (its own f64 polygon
//! test, `nimbus_reference::grid`), Volumetric ReSTIR (whose spatial and temporal reuse
//! re-evaluate the stored sun vertex from other shading points through the gobo) agrees
//! with the baseline, and a gobo that misses the scene leaves only the other lights.

use crate::common::gpu::{assert_means_agree, context, render_checked, scene, se_of_mean};
use crate::common::scenes::{LOW_CLOUD, LOW_CLOUD_CAMERA, LOW_CLOUD_FLOOR};
use crate::oracle::baseline::check_against_oracle;

/// A gobo whose prism cuts the cloud about in half (u ≈ (0.78, 0, 0.62) is
/// `Gobo::basis` of the sun's direction) and lights the floor beside the cloud's
/// shadow; a convex pentagon with a slanted edge.
const PART: &str = "gobo = [[0, -1.5], [2, -1.5], [2, 1.5], [0.3, 1.5], [-0.3, 0.2]]\n\
                    gobo_origin = [0.3, 1.0, 0.0]";
/// A gobo whose prism passes 20 m beside everything the camera sees.
const NOWHERE: &str = "gobo = [[20, 20], [21, 20], [21, 21], [20, 21]]\n\
                       gobo_origin = [0.0, 1.0, 0.0]";

/// A floor and a small cloud above it under a sun with `gobo` (or no sun when `gobo` is
/// None) and `extra` lights, rendered by `volume` with K = `bounces`.
fn gobo_scene(
    volume: &str,
    gobo: Option<&str>,
    extra: &str,
    bounces: u32,
    frames: u32,
    spp: u32,
) -> nimbus_scene::Scene {
    let sun = match gobo {
        Some(gobo) => format!(
            "[[light]]\ntype = \"directional\"\ndirection = [0.4, -1.0, -0.5]\n\
             irradiance = [1.5, 1.2, 0.9]\n{gobo}\n"
        ),
        None => String::new(),
    };
    let text = format!(
        r#"
[render]
width = 16
height = 12
frames = {frames}
spp = {spp}
seed = 17
{LOW_CLOUD_CAMERA}
{sun}
{extra}
{LOW_CLOUD}
[integrator]
volume = "{volume}"
max_bounces = {bounces}
{LOW_CLOUD_FLOOR}
"#
    );
    scene(&text, &format!("gobo-{volume}.toml"))
}

/// The baseline with a gobo'd sun on a cloud over a floor, K = 1 and 3, matches the CPU
/// oracle (image means within 1 % plus 4 combined standard errors, at most 2 % of the
/// pixel channels beyond 4.5; `baseline::check_against_oracle`). The gobo does cut the
/// light: the same sun without it is clearly brighter.
#[test]
fn baseline_gobo_matches_the_cpu_oracle() {
    let ctx = context();
    for bounces in [1u32, 3] {
        let scene = gobo_scene("baseline", Some(PART), "", bounces, 32, 4);
        check_against_oracle(&ctx, &scene, 23, &format!("gobo K={bounces}"));
    }
    let masked = render_checked(&ctx, &gobo_scene("baseline", Some(PART), "", 1, 8, 4), None);
    let open = render_checked(&ctx, &gobo_scene("baseline", Some(""), "", 1, 8, 4), None);
    let (m, o) = (masked.image.mean(), open.image.mean());
    println!("gobo mean {m:?}, without the gobo {o:?}");
    assert!(m[0] > 0.0 && m[0] < 0.8 * o[0], "{m:?} vs {o:?}");
}

/// Volumetric ReSTIR (temporal and spatial reuse, K = 2) with the same gobo renders a
/// finite image whose mean agrees with the baseline's within 3 % plus 4 combined
/// standard errors (the reuse correlates pixels and frames, so the per-pixel errors
/// understate the noise of ReSTIR's mean; the 3 % covers that at this small size).
#[test]
fn restir_gobo_mean_agrees_with_the_baseline() {
    let ctx = context();
    let restir = render_checked(&ctx, &gobo_scene("restir", Some(PART), "", 2, 128, 1), None);
    let baseline = render_checked(
        &ctx,
        &gobo_scene("baseline", Some(PART), "", 2, 64, 4),
        None,
    );
    println!(
        "restir SE {:.2e}, baseline SE {:.2e}",
        se_of_mean(&restir.std_error),
        se_of_mean(&baseline.std_error)
    );
    assert_means_agree(
        "gobo: restir vs baseline",
        (&restir.image, &restir.std_error),
        (&baseline.image, &baseline.std_error),
        4.0,
        0.03,
    );
}

/// A gobo that passes beside the scene: with the sun as the only light both integrators
/// render exactly 0 (no sample gets past the gobo); beside a constant environment the
/// image agrees with the environment alone within noise (the sun still takes its share of
/// light selection, so the random streams differ).
#[test]
fn a_gobo_beside_the_scene_is_no_sun() {
    let ctx = context();
    for (volume, frames, spp) in [("baseline", 4, 4), ("restir", 8, 1)] {
        let image = render_checked(
            &ctx,
            &gobo_scene(volume, Some(NOWHERE), "", 2, frames, spp),
            None,
        );
        assert!(
            image.image.data.iter().all(|p| *p == [0.0; 3]),
            "{volume}: {:?}",
            image.image.mean()
        );
    }
    let env = "[[light]]\ntype = \"environment\"\nradiance = [0.3, 0.4, 0.6]";
    let blocked = render_checked(
        &ctx,
        &gobo_scene("baseline", Some(NOWHERE), env, 2, 32, 4),
        None,
    );
    let no_sun = render_checked(&ctx, &gobo_scene("baseline", None, env, 2, 32, 4), None);
    assert_means_agree(
        "gobo beside the scene vs no sun",
        (&blocked.image, &blocked.std_error),
        (&no_sun.image, &no_sun.std_error),
        4.0,
        0.005,
    );
}

/// The grid passes' light records carry the same gobo as the crepuscular pass's (origin,
/// axes, half-planes), and a light without a gobo has none: two suns, the second with a
/// pentagon gobo, in both record builders.
#[test]
fn grid_light_records_carry_the_crepuscular_gobo() {
    let text = format!(
        "[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\n\
         [[light]]\ntype = \"directional\"\ndirection = [0, -1, 0]\nirradiance = 1\n\
         [[light]]\ntype = \"directional\"\ndirection = [0.4, -1.0, -0.5]\nirradiance = 2\n{PART}\n"
    );
    let s = scene(&text, "gobo-records.toml");
    let grid = nimbus::shader_data::LightSet::build(&s.lights, 1.0, None, 0.0);
    let boxes = nimbus::shader_data::GpuScene::build(&s).expect("box records");
    assert_eq!(grid.gobo_planes, boxes.gobo_planes);
    assert_eq!(grid.gobo_planes.len(), 5);
    assert_eq!(grid.lights[0].gobo_plane_count, 0);
    for (g, b) in grid.lights.iter().zip(&boxes.lights).skip(1) {
        assert_eq!(
            (g.gobo_origin, g.gobo_u, g.gobo_v),
            (b.gobo_origin, b.gobo_u, b.gobo_v)
        );
        assert_eq!(
            (g.gobo_first_plane, g.gobo_plane_count),
            (b.gobo_first_plane, b.gobo_plane_count)
        );
    }
}
