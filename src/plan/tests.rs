//! Unit tests of the render plan: limits, features and refusals.

use std::path::Path;

use super::*;

fn scene(extra: &str) -> Scene {
    let text = format!(
        "[camera]\nposition = [0, 0, 30]\nlook_at = [0, 0, 0]\n{extra}\n[integrator]\nbox_estimator = \"rees\"\n"
    );
    nimbus_scene::parse_str(&text, Path::new("plan.toml")).expect("parses")
}

#[test]
fn too_many_lights_or_media_are_errors_naming_the_table() {
    let lights =
        "[[light]]\ntype = \"directional\"\ndirection = [0, -1, 0]\nirradiance = 1\n".repeat(17);
    let err = build(&scene(&lights), None).unwrap_err().to_string();
    assert!(
        err.contains("plan.toml") && err.contains("[[light]]") && err.contains("at most 16"),
        "{err}"
    );

    let media: String = (0..17)
        .map(|i| {
            format!(
                "[[medium]]\ntype = \"box\"\ncenter = [{}, 0, 0]\nsize = [1, 1, 1]\nsigma_t = 1\n",
                2 * i
            )
        })
        .collect();
    let err = build(&scene(&media), None).unwrap_err().to_string();
    assert!(
        err.contains("plan.toml") && err.contains("[[medium]]") && err.contains("at most 16"),
        "{err}"
    );
}

#[test]
fn features_follow_the_scene() {
    let plain = build(&scene(""), None).unwrap();
    let f = plain.crepuscular().unwrap().features;
    assert!(!f.has_media && !f.has_shapes && !f.has_gobos && !f.has_env && f.pixel_jitter);

    let gobo = scene(
        "[[light]]\ntype = \"directional\"\ndirection = [0, -1, 0]\nirradiance = 1\ngobo = [[0, 0], [1, 0], [0, 1]]\n\
         [[medium]]\ntype = \"box\"\ncenter = [0, 0, 0]\nsize = [1, 1, 1]\nsigma_t = 1\n",
    );
    let plan = build(&gobo, Some(7)).unwrap();
    let p = plan.crepuscular().unwrap();
    assert!(p.features.has_gobos && p.features.has_media);
    assert_eq!(p.samples_along_ray, 7);
    assert_eq!(p.estimator, BoxEstimator::Rees);
    assert!(plan.explain(&gobo).contains("[on ]   SC_HAS_GOBOS"));
}

#[test]
fn grid_scenes_name_what_the_baseline_does_not_take() {
    let grid = |i: u32| {
        format!(
            "[[medium]]\ntype = \"grid\"\nbounds_min = [{x}, 0, 0]\nbounds_max = [{y}, 1, 1]\n\
             density = {{ procedural = \"cloud\", dims = [4, 4, 4] }}\n",
            x = 2 * i,
            y = 2 * i + 1
        )
    };
    let text = |body: &str, volume: &str| {
        format!(
            "[camera]\nposition = [0, 0, 30]\nlook_at = [0, 0, 0]\n{body}\n[integrator]\nvolume = \"{volume}\"\n"
        )
    };
    let err = |body: &str, volume: &str| {
        let scene =
            nimbus_scene::parse_str(&text(body, volume), Path::new("grid.toml")).expect("parses");
        build(&scene, None).unwrap_err().to_string()
    };
    let restir =
        nimbus_scene::parse_str(&text(&grid(0), "restir"), Path::new("grid.toml")).expect("parses");
    let plan = build(&restir, None).unwrap();
    let r = plan.restir().expect("restir plan");
    assert!(plan.baseline().is_none() && !r.has_emission && !r.vertex_reuse);
    assert_eq!(
        (r.settings.candidates, r.temporal_limit, r.spatial_neighbors),
        (4, nimbus_scene::STILL_TEMPORAL_LIMIT, 0)
    );
    // A camera that never moves over a still density takes Q alone (whatever the moving
    // frames' Q says); one with keyframes the smaller of the two on its moving frames,
    // and --explain says so.
    assert_eq!(r.temporal_limit_moving, nimbus_scene::STILL_TEMPORAL_LIMIT);
    let q_moving = |keys: bool, q: u32, q_moving: u32| {
        let camera = if keys {
            "[[camera.keyframe]]\nframe = 0\nposition = [0, 0, 30]\nlook_at = [0, 0, 0]\n\
             [[camera.keyframe]]\nframe = 4\nposition = [1, 0, 30]\nlook_at = [0, 0, 0]\n"
        } else {
            ""
        };
        let body = format!(
            "[render]\nframes = 8\n{camera}{}[integrator.restir]\ntemporal_limit = {q}\n\
             temporal_limit_moving = {q_moving}\n",
            grid(0)
        );
        let scene = nimbus_scene::parse_str(&text(&body, "restir"), Path::new("grid.toml"))
            .expect("parses");
        let plan = build(&scene, None).unwrap();
        let r = plan.restir().unwrap();
        let temporal = plan
            .decisions
            .iter()
            .find(|d| d.name == "pass restir temporal")
            .map(|d| d.reason.clone())
            .unwrap();
        (
            r.temporal_limit,
            r.temporal_limit_moving,
            r.settings.temporal_limit_moving,
            temporal.contains("on frames whose camera or density moved"),
        )
    };
    assert_eq!(q_moving(false, 20, 3), (20, 20, 2, false));
    assert_eq!(q_moving(false, 20, 5), q_moving(false, 20, 3));
    assert_eq!(q_moving(true, 20, 3), (20, 3, 3, true));
    assert_eq!(q_moving(true, 2, 3), (2, 2, 3, false));
    let e = err(&format!("{}{}", grid(0), grid(1)), "restir");
    assert!(
        e.contains("[[medium]] #2") && e.contains("Volumetric ReSTIR"),
        "{e}"
    );
    let e = err(&format!("{}{}", grid(0), grid(1)), "baseline");
    assert!(
        e.contains("[[medium]] #2") && e.contains("one grid medium"),
        "{e}"
    );
    let gobo = "[[light]]\ntype = \"directional\"\ndirection = [0, -1, 0]\nirradiance = 1\ngobo = [[0, 0], [1, 0], [0, 1]]\n";
    // Both grid integrators take a gobo'd directional light, with SC_HAS_GOBOS on.
    for volume in ["baseline", "restir"] {
        let scene = nimbus_scene::parse_str(
            &text(&format!("{}{gobo}", grid(0)), volume),
            Path::new("grid.toml"),
        )
        .expect("parses");
        let plan = build(&scene, None).unwrap();
        let has_gobos = match volume {
            "baseline" => plan.baseline().unwrap().has_gobos,
            _ => plan.restir().unwrap().has_gobos,
        };
        assert!(has_gobos, "{volume}");
        assert!(
            plan.explain(&scene).contains("[on ]   SC_HAS_GOBOS"),
            "{volume}"
        );
    }

    let ok = nimbus_scene::parse_str(&text(&grid(0), "baseline"), Path::new("grid.toml")).unwrap();
    let plan = build(&ok, None).unwrap();
    assert!(plan.crepuscular().is_none());
    let b = plan.baseline().unwrap();
    assert!(!b.has_emission && !b.has_env && !b.has_env_map && !b.has_boxes && !b.has_gobos);
    assert!(plan.explain(&ok).contains("[off]   SC_HAS_GOBOS"));
    assert!(plan
        .explain(&ok)
        .contains("[on ] pass baseline path tracer"));
}

/// Spatial reuse's neighbour test and depth anchors reach the plan where spatial reuse
/// runs, and --explain names them; without spatial reuse they are the defaults (the plan
/// is the same whatever they say).
#[test]
fn the_neighbour_test_and_depth_anchors_follow_spatial_reuse() {
    let grid = "[[medium]]\ntype = \"grid\"\nbounds_min = [0, 0, 0]\nbounds_max = [1, 1, 1]\n\
                density = { procedural = \"cloud\", dims = [4, 4, 4] }\n[integrator]\nvolume = \"restir\"\n";
    let plan_of = |restir: &str| {
        let scene = nimbus_scene::parse_str(
            &format!(
                "[camera]\nposition = [0, 0, 30]\nlook_at = [0, 0, 0]\n{grid}[integrator.restir]\n{restir}\n"
            ),
            Path::new("grid.toml"),
        )
        .expect("parses");
        let plan = build(&scene, None).unwrap();
        (plan.clone(), plan.explain(&scene))
    };
    let keys = "spatial_feature_tolerance = 0.25\nspatial_anchor = true\n";
    let (on, explain) = plan_of(&format!("spatial_when = \"always\"\n{keys}"));
    let r = on.restir().unwrap();
    assert_eq!(
        (
            r.settings.spatial_feature_tolerance,
            r.settings.spatial_anchor
        ),
        (0.25, true)
    );
    assert!(
        explain.contains("whose T~ differs by 0.25 or more")
            && explain.contains("past where each pixel's centre ray enters the medium"),
        "{explain}"
    );
    let (plain, explain) = plan_of("spatial_when = \"always\"\n");
    assert!(!explain.contains("T~ differs") && !explain.contains("centre ray enters"));
    let r = plain.restir().unwrap();
    assert_eq!(
        (
            r.settings.spatial_feature_tolerance,
            r.settings.spatial_anchor
        ),
        (0.0, false)
    );
    // A still camera plans no spatial pass (spatial_when = "camera_moves"): the keys are
    // read by nothing, and the plan is the one without them.
    let (off, _) = plan_of(keys);
    let (default, _) = plan_of("");
    assert_eq!(
        format!("{:?}", effective_plan(&off)),
        format!("{:?}", effective_plan(&default))
    );
}

/// The baseline takes a velocity grid (it only guides ReSTIR's reprojection: issue 24,
/// it was refused as "animated density") and density frames (one pass per grid,
/// `passes::baseline_frames`).
#[test]
fn the_baseline_takes_a_velocity_grid_and_density_frames() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/volumes");
    let text = |frames: &str| {
        format!(
            "[render]\nframes = 2\n[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\n\
             [[light]]\ntype = \"environment\"\nradiance = 1\n\
             [[medium]]\ntype = \"grid\"\nbounds_min = [-0.5, -0.5, -0.5]\nbounds_max = [0.5, 0.5, 0.5]\n\
             density = {{ file = \"{dir}/plume-f0.vol\" }}\n\
             velocity = {{ file = \"{dir}/plume-velocity.vol\" }}\n{frames}\
             [integrator]\nvolume = \"baseline\"\n"
        )
    };
    let parse = |t: &str| nimbus_scene::parse_str(t, Path::new("plan.toml")).expect("parses");
    build(&parse(&text("")), None).expect("a velocity grid");
    let frames =
        format!("[[medium.frame]]\nframe = 1\ndensity = {{ file = \"{dir}/plume-f1.vol\" }}\n");
    build(&parse(&text(&frames)), None).expect("density frames");
}

/// `spatial_when = "camera_or_density"` (the default) plans the spatial pass where the
/// density has frames under a still camera (the animated plume, where the history is weak)
/// and explains the trigger; `"camera_moves"` plans none there; neither plans one for a
/// static scene under a still camera.
#[test]
fn spatial_reuse_follows_the_density_frames_under_camera_or_density() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/volumes");
    let text = |frames: &str, when: &str| {
        format!(
            "[render]\nframes = 2\n[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\n\
             [[light]]\ntype = \"environment\"\nradiance = 1\n\
             [[medium]]\ntype = \"grid\"\nbounds_min = [-0.5, -0.5, -0.5]\nbounds_max = [0.5, 0.5, 0.5]\n\
             density = {{ file = \"{dir}/plume-f0.vol\" }}\n{frames}\
             [integrator.restir]\nspatial_neighbors = 3\n{when}"
        )
    };
    let frames =
        format!("[[medium.frame]]\nframe = 1\ndensity = {{ file = \"{dir}/plume-f1.vol\" }}\n");
    let plan = |frames: &str, when: &str| {
        let scene =
            nimbus_scene::parse_str(&text(frames, when), Path::new("plan.toml")).expect("parses");
        let plan = build(&scene, None).expect("plan");
        let explain = plan.explain(&scene);
        (spatial_on(plan.restir().expect("ReSTIR")), explain)
    };
    let (on, explain) = plan(&frames, "");
    assert!(on, "{explain}");
    assert!(
        explain.contains("on frames whose camera or density frame changed"),
        "{explain}"
    );
    let (on, explain) = plan("", "");
    assert!(!on, "{explain}");
    assert!(
        explain.contains("neither the camera nor the density moves"),
        "{explain}"
    );
    let (on, explain) = plan(&frames, "spatial_when = \"camera_moves\"\n");
    assert!(!on, "{explain}");
    assert!(plan(&frames, "spatial_when = \"always\"\n").0);
    assert!(plan("", "spatial_when = \"always\"\n").0);
}

/// `temporal = "auto"` (the default): temporal reuse for frames that are images, none
/// for the still of a static scene (whose independent frames converge faster), and an
/// animated scene's frames are images whatever the render asks; `true` and `false` are
/// kept, and the candidates' tracking follows (delta tracking where each frame stands on
/// its candidates).
#[test]
fn temporal_auto_follows_what_the_render_makes_of_its_frames() {
    let text = |restir: &str, camera_keys: bool| {
        let keys = if camera_keys {
            "[[camera.keyframe]]\nframe = 0\nposition = [0, 0, 30]\nlook_at = [0, 0, 0]\n\
             [[camera.keyframe]]\nframe = 4\nposition = [1, 0, 30]\nlook_at = [0, 0, 0]\n"
        } else {
            ""
        };
        format!(
            "[render]\nframes = 8\n[camera]\nposition = [0, 0, 30]\nlook_at = [0, 0, 0]\n{keys}\
             [[medium]]\ntype = \"grid\"\nbounds_min = [0, 0, 0]\nbounds_max = [1, 1, 1]\n\
             density = {{ procedural = \"cloud\", dims = [4, 4, 4] }}\n\
             [integrator]\nvolume = \"restir\"\n[integrator.restir]\n{restir}\n"
        )
    };
    let decide = |restir: &str, camera_keys: bool, product: Product| {
        let scene =
            nimbus_scene::parse_str(&text(restir, camera_keys), Path::new("t.toml")).unwrap();
        let plan = build_for(&scene, None, product).unwrap();
        let r = plan.restir().unwrap().clone();
        let row = plan
            .decisions
            .iter()
            .find(|d| d.name == "pass restir temporal")
            .unwrap()
            .clone();
        assert_eq!(row.enabled, r.temporal);
        assert_eq!(r.settings.temporal, Some(r.temporal));
        (
            r.temporal,
            r.candidate_delta,
            row.reason.contains("temporal = \"auto\""),
        )
    };
    let (on, delta, auto) = decide("", false, Product::Still);
    assert!(
        !on && delta && auto,
        "a static still: independent frames, delta-tracked"
    );
    assert!(decide("", false, Product::Frames).0);
    assert!(
        decide("temporal = \"auto\"", true, Product::Still).0,
        "an animation"
    );
    let (on, _, auto) = decide("temporal = true", false, Product::Still);
    assert!(on && !auto);
    assert!(!decide("temporal = false", false, Product::Frames).0);
    // `build` plans frames that are images.
    let scene = nimbus_scene::parse_str(&text("", false), Path::new("t.toml")).unwrap();
    assert!(build(&scene, None).unwrap().restir().unwrap().temporal);
}

/// `temporal_limit = "auto"` (the default): the long history where nothing moves, the
/// motion benchmarks' Q where anything does (camera, light or density keyframes), and
/// the plan, `--explain` and the study's effective scene say which.
#[test]
fn auto_temporal_limit_follows_the_scene() {
    let grid = "[[medium]]\ntype = \"grid\"\nbounds_min = [0, 0, 0]\nbounds_max = [1, 1, 1]\n\
                density = { procedural = \"cloud\", dims = [4, 4, 4] }\n";
    let camera_keys = "[[camera.keyframe]]\nframe = 0\nposition = [0, 0, 30]\nlook_at = [0, 0, 0]\n\
                       [[camera.keyframe]]\nframe = 4\nposition = [1, 0, 30]\nlook_at = [0, 0, 0]\n";
    let sun_keys = "[[light]]\ntype = \"directional\"\ndirection = [0, -1, 0]\nirradiance = 1\n\
                    [[light.keyframe]]\nframe = 0\ndirection = [0, -1, 0]\n\
                    [[light.keyframe]]\nframe = 4\ndirection = [1, -1, 0]\n";
    let q = |body: &str, restir: &str| {
        let text = format!(
            "[render]\nframes = 8\n[camera]\nposition = [0, 0, 30]\nlook_at = [0, 0, 0]\n\
             {body}{grid}[integrator]\nvolume = \"restir\"\n[integrator.restir]\n{restir}\n"
        );
        let scene = nimbus_scene::parse_str(&text, Path::new("q.toml")).unwrap();
        let plan = build(&scene, None).unwrap();
        let r = plan.restir().unwrap().clone();
        let row = reason_of(&plan, "pass restir temporal");
        assert_eq!(r.settings.temporal_limit, Some(r.temporal_limit));
        assert_eq!(
            effective_scene(&scene, &plan)
                .integrator
                .restir
                .temporal_limit,
            Some(r.temporal_limit),
            "\"auto\" and the Q it resolves to render the same"
        );
        (r.temporal_limit, r.temporal_limit_moving, row)
    };
    let (still, still_moving, row) = q("", "");
    assert_eq!(
        (still, still_moving),
        (nimbus_scene::STILL_TEMPORAL_LIMIT, still)
    );
    assert!(
        row.contains(&format!("Q = {still} (temporal_limit = \"auto\""))
            && row.contains("where nothing moves"),
        "{row}"
    );
    let (camera, camera_moving, row) = q(camera_keys, "");
    assert_eq!(
        (camera, camera_moving),
        (nimbus_scene::ANIMATED_TEMPORAL_LIMIT, 2)
    );
    assert!(row.contains("where something moves"), "{row}");
    assert_eq!(
        q(sun_keys, "").0,
        nimbus_scene::ANIMATED_TEMPORAL_LIMIT,
        "a turning sun alone"
    );
    let (asked, _, row) = q("", "temporal_limit = 7");
    assert_eq!(asked, 7);
    assert!(!row.contains("\"auto\""), "{row}");
    assert_eq!(q(camera_keys, "temporal_limit = \"auto\"").0, camera);
}

/// `candidates_settled`: the plan reports it where it takes effect (temporal reuse on, a
/// settled M below M), `--explain` says so on the initial pass's row, and the study's
/// effective scene folds the values that take no effect into M.
#[test]
fn candidates_settled_is_explained_where_it_takes_effect() {
    let plan_of = |restir: &str| {
        let text = format!(
            "[render]\nframes = 8\n[camera]\nposition = [0, 0, 30]\nlook_at = [0, 0, 0]\n\
             [[medium]]\ntype = \"grid\"\nbounds_min = [0, 0, 0]\nbounds_max = [1, 1, 1]\n\
             density = {{ procedural = \"cloud\", dims = [4, 4, 4] }}\n\
             [integrator]\nvolume = \"restir\"\n[integrator.restir]\n{restir}\n"
        );
        let scene = nimbus_scene::parse_str(&text, Path::new("s.toml")).unwrap();
        let plan = build(&scene, None).unwrap();
        let r = plan.restir().unwrap().clone();
        let row = reason_of(&plan, "pass restir initial");
        let effective = effective_scene(&scene, &plan)
            .integrator
            .restir
            .candidates_settled;
        (r.candidates_settled(), row, effective, error_batch(&plan))
    };
    let (settled, row, effective, batch) = plan_of("");
    assert_eq!((settled, effective), (Some(1), 1));
    // The error estimate's batches follow the settled frames' Q (240): 4 (240 + 1).
    assert_eq!(batch, 964);
    assert!(
        row.contains("(1 once the history is full, after 60 frames in a row")
            && row.contains("cap of 240 candidates"),
        "{row}"
    );
    let (settled, row, effective, batch) = plan_of("candidates_settled = 4");
    assert_eq!((settled, effective, batch), (None, 4, 244));
    assert!(!row.contains("once the history is full"), "{row}");
    assert_eq!(plan_of("candidates_settled = 9").2, 4, "more than M is M");
    assert_eq!(
        plan_of("temporal = false").0,
        None,
        "no history, nothing settles"
    );
}

/// The settled M keeps the history's cap of Q·M candidates; nothing changes where
/// the frame is not settled or the settled M is not fewer.
#[test]
fn settled_candidates_keep_the_history_cap() {
    assert_eq!(settled_candidates(4, 60, None), (4, 60));
    assert_eq!(settled_candidates(4, 60, Some(1)), (1, 240));
    assert_eq!(settled_candidates(4, 60, Some(2)), (2, 120));
    assert_eq!(settled_candidates(4, 5, Some(3)), (3, 7)); // 20 / 3, rounded
    assert_eq!(settled_candidates(4, 60, Some(4)), (4, 60));
    assert_eq!(settled_candidates(4, 60, Some(9)), (4, 60));
    assert_eq!(settled_candidates(4096, 1024, Some(1)), (1, 4_194_304));
}

/// The reason `--explain` gives on `plan`'s decision row `name`.
fn reason_of(plan: &RenderPlan, name: &str) -> String {
    plan.decisions
        .iter()
        .find(|d| d.name == name)
        .unwrap_or_else(|| panic!("no decision row {name}"))
        .reason
        .clone()
}
