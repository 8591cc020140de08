//! Unit tests of the study's planning: options, deduplication, windows.
use super::*;
use nimbus_scene::VolumeIntegrator;

fn same_as(study: &Study) -> Vec<Option<usize>> {
    study.configurations.iter().map(|c| c.same_as).collect()
}

#[test]
fn configurations_an_integrator_cannot_tell_apart_are_rendered_once() {
    let opts = StudyOptions {
        vary: vec![
            "volume=baseline,restir".into(),
            "temporal_limit=4,20".into(),
            "box_estimator=rm,reds".into(),
        ],
        baseline: Some("volume=baseline".into()),
        ..grid_options("dedupe")
    };
    let study = Study::new(&opts).unwrap();
    // The baseline reads neither Q nor the box estimator; ReSTIR reads Q but not
    // the box estimator.
    assert_eq!(
        same_as(&study),
        [
            None,
            Some(0),
            Some(0),
            Some(0),
            None,
            Some(4),
            None,
            Some(6)
        ]
    );
    remove_scratch(&opts);

    // The box-medium pass reads neither volume nor the ReSTIR knobs.
    let opts = StudyOptions {
        vary: vec![
            "volume=restir,baseline".into(),
            "temporal_limit=4,20".into(),
            "spp=1,2".into(),
        ],
        ..grid_options("dedupe-box")
    };
    std::fs::write(&opts.scene, nimbus::DEFAULT_SCENE).unwrap();
    let study = Study::new(&opts).unwrap();
    let spp1 = Some(0);
    let spp2 = Some(1);
    assert_eq!(
        same_as(&study),
        [None, None, spp1, spp2, spp1, spp2, spp1, spp2]
    );
    remove_scratch(&opts);

    // Without spatial reuse ReSTIR reads none of its settings.
    let opts = StudyOptions {
        vary: vec![
            "spatial_neighbors=0,3".into(),
            "spatial_shift=distance,optical_depth".into(),
            "spatial_max_history=0,8".into(),
            // (The test scene's camera holds still.)
            "spatial_when=always".into(),
        ],
        ..grid_options("dedupe-spatial")
    };
    let study = Study::new(&opts).unwrap();
    assert_eq!(
        same_as(&study),
        [None, Some(0), Some(0), Some(0), None, None, None, None]
    );
    remove_scratch(&opts);
}

/// ReSTIR renders one path per pixel per frame: where `--vary spp` also varies the
/// baseline, ReSTIR's spp > 1 configurations are left out and listed (the per-frame
/// equal-time protocol: the baseline's spp raised to ReSTIR's frame time); where
/// nothing else is left, the study fails saying what sets ReSTIR's work instead.
#[test]
fn restir_with_more_than_one_spp_is_left_out_or_refused() {
    let opts = StudyOptions {
        vary: vec!["volume=baseline,restir".into(), "spp=1,4".into()],
        ..grid_options("restir-spp")
    };
    let study = Study::new(&opts).unwrap();
    let labels: Vec<String> = study
        .configurations
        .iter()
        .map(|c| format_pairs(&c.assignment))
        .collect();
    assert_eq!(
        labels,
        [
            "volume=baseline spp=1",
            "volume=baseline spp=4",
            "volume=restir spp=1"
        ]
    );
    assert_eq!(
        study.left_out,
        [vec![
            ("volume".to_owned(), "restir".to_owned()),
            ("spp".to_owned(), "4".to_owned())
        ]]
    );
    let text = report::left_out_text(&study.left_out).expect("a note");
    assert!(text.contains("- `volume=restir spp=4`"), "{text}");
    assert!(text.contains("`candidates`"), "{text}");

    let only = StudyOptions {
        vary: vec!["volume=restir".into(), "spp=2,4".into()],
        ..opts.clone()
    };
    let message = format!("{:#}", Study::new(&only).err().expect("an error"));
    for needle in [
        "volume=restir spp=2; volume=restir spp=4",
        "one path per pixel per frame",
        "candidates or frames",
    ] {
        assert!(message.contains(needle), "{needle:?}: {message}");
    }
    // A baseline scene is never left out: spp is its own knob.
    let baseline = StudyOptions {
        vary: vec!["volume=baseline".into(), "spp=2,4".into()],
        ..opts.clone()
    };
    assert_eq!(Study::new(&baseline).unwrap().configurations.len(), 2);
    remove_scratch(&opts);
}

#[test]
fn the_reference_of_a_grid_medium_is_the_baseline_with_its_own_seed() {
    let opts = StudyOptions {
        vary: vec!["volume=restir".into()],
        reference_frames: 3,
        reference_spp: 2,
        ..grid_options("reference")
    };
    let study = Study::new(&opts).unwrap();
    assert_eq!(study.references.len(), 1);
    let job = &study.references[0];
    assert_eq!(job.scene.integrator.volume, VolumeIntegrator::Baseline);
    assert_eq!((job.scene.render.frames, job.scene.render.spp), (3, 2));
    let seed = study.configurations[0].scene.render.seed;
    assert_eq!(study.configurations[0].seeds, [seed]);
    assert_eq!(job.scene.render.seed, seed ^ REFERENCE_SEED_MIX);
    assert!(job.key.starts_with("grid-"), "{}", job.key);
    assert_eq!(job.exr.parent(), opts.cache_dir.as_deref());
    assert_eq!(study.out_dir, opts.out_dir.clone().unwrap());
    remove_scratch(&opts);
}

/// Each max_bounces is compared with a reference of the same max_bounces; keys
/// that do not change the integrand share one.
#[test]
fn each_integrand_has_its_own_reference() {
    let opts = StudyOptions {
        vary: vec![
            "max_bounces=1,3".into(),
            "volume=baseline,restir".into(),
            "candidates=2,4".into(),
        ],
        ..grid_options("integrands")
    };
    let study = Study::new(&opts).unwrap();
    let refs: Vec<usize> = study.configurations.iter().map(|c| c.reference).collect();
    assert_eq!(refs, [0, 0, 0, 0, 1, 1, 1, 1]);
    let k: Vec<u32> = study
        .references
        .iter()
        .map(|r| r.scene.integrator.max_bounces)
        .collect();
    assert_eq!(k, [1, 3]);
    for (r, c) in study.references.iter().zip([0, 4]) {
        let config = &study.configurations[c].scene;
        assert_eq!(
            r.scene.integrator.max_bounces,
            config.integrator.max_bounces
        );
        assert_eq!(r.scene.integrator.volume, VolumeIntegrator::Baseline);
        assert_eq!(r.scene.render.seed, config.render.seed ^ REFERENCE_SEED_MIX);
    }
    assert_ne!(study.references[0].key, study.references[1].key);
    assert_ne!(study.references[0].exr, study.references[1].exr);
    remove_scratch(&opts);

    // Nothing that changes the integrand varied: one reference, of the scene's K.
    let opts = StudyOptions {
        vary: vec!["volume=baseline,restir".into(), "temporal_limit=1,2".into()],
        ..grid_options("one-integrand")
    };
    std::fs::write(
        &opts.scene,
        std::fs::read_to_string(&opts.scene).unwrap() + "[integrator]\nmax_bounces = 2\n",
    )
    .unwrap();
    let study = Study::new(&opts).unwrap();
    assert_eq!(study.references.len(), 1);
    assert_eq!(study.references[0].scene.integrator.max_bounces, 2);
    assert!(study.configurations.iter().all(|c| c.reference == 0));
    remove_scratch(&opts);
}

#[test]
fn seeds_follow_the_scene_seed_and_never_share_a_fold() {
    let avoid = |seed: u64| fold_seed(seed ^ REFERENCE_SEED_MIX);
    assert_eq!(derive_seeds(7, 3, avoid(7)), [7, 8, 9]);
    assert_eq!(derive_seeds(7, 1, avoid(7)), [7]);
    // A seed that folds to the reference's is skipped.
    assert_eq!(derive_seeds(10, 3, fold_seed(11)), [10, 12, 13]);
    // u64::MAX and 0 (after wrapping) both fold to 0: the second is skipped.
    assert_eq!(fold_seed(u64::MAX), fold_seed(0));
    assert_eq!(derive_seeds(u64::MAX, 3, avoid(u64::MAX)), [u64::MAX, 1, 2]);
    // Across the carry into the high half, folds of both halves can meet.
    let edge = 0xFFFF_FFF0u64;
    for seed in [0, 3, 0x5EED, edge, u64::MAX - 5, 0x5EED_0000_0000_0000] {
        let seeds = derive_seeds(seed, MAX_SEEDS, avoid(seed));
        assert_eq!(seeds.len(), MAX_SEEDS as usize);
        assert_eq!(seeds[0], seed);
        let mut folds: Vec<u32> = seeds.iter().map(|&s| fold_seed(s)).collect();
        assert!(!folds.contains(&avoid(seed)), "seed {seed}");
        folds.sort_unstable();
        folds.dedup();
        assert_eq!(
            folds.len(),
            MAX_SEEDS as usize,
            "seed {seed}: a fold repeats"
        );
    }
}

#[test]
fn every_configuration_renders_every_seed() {
    let opts = StudyOptions {
        vary: vec!["volume=baseline,restir".into()],
        seeds: 3,
        ..grid_options("seeds")
    };
    let study = Study::new(&opts).unwrap();
    let reference = study.references[0].scene.render.seed;
    for c in &study.configurations {
        assert_eq!(c.seeds, [0, 1, 2]);
        assert_eq!(c.scene.render.seed, 0);
        assert!(c
            .seeds
            .iter()
            .all(|&s| fold_seed(s) != fold_seed(reference)));
    }
    assert_eq!(study.seeds, 3);
    remove_scratch(&opts);
}

#[test]
fn warmup_covers_compilation_and_the_temporal_history() {
    let plan_of = |extra: &str| {
        let text = format!(
            "[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\n[[medium]]\ntype = \
             \"grid\"\nbounds_min = [-1, -1, -1]\nbounds_max = [1, 1, 1]\ndensity = \
             {{ procedural = \"cloud\", dims = [4, 4, 4] }}\n{extra}"
        );
        let scene = nimbus_scene::parse_str(&text, Path::new("w.toml")).unwrap();
        plan::build(&scene, None).unwrap()
    };
    let restir = |q: u32, temporal: bool| {
        plan_of(&format!(
            "[integrator.restir]\ntemporal_limit = {q}\ntemporal = {temporal}\n"
        ))
    };
    let baseline = plan_of("[integrator]\nvolume = \"baseline\"\n");
    let window = nimbus_scene::parse_str(nimbus::DEFAULT_SCENE, Path::new("w.toml")).unwrap();
    let boxes = plan::build(&window, None).unwrap();
    // At least one frame, whatever --warmup says.
    assert_eq!(warmup_frames(&boxes, 0), 1);
    assert_eq!(warmup_frames(&baseline, 0), 1);
    assert_eq!(warmup_frames(&baseline, 7), 7);
    // ReSTIR with temporal reuse: 4·Q, or more when asked.
    assert_eq!(warmup_frames(&restir(4, true), 0), 16);
    assert_eq!(warmup_frames(&restir(20, true), 16), 80);
    assert_eq!(warmup_frames(&restir(20, true), 100), 100);
    // Without temporal reuse there is no history to fill.
    assert_eq!(warmup_frames(&restir(20, false), 0), 1);

    // A per-frame study measures real-time frames: ReSTIR's temporal = "auto" keeps
    // its history, and the warm-up fills it.
    let opts = StudyOptions {
        vary: vec![
            "volume=baseline,restir".into(),
            "temporal_limit=4,20".into(),
        ],
        warmup: 0,
        per_frame: true,
        ..grid_options("warmup")
    };
    let study = Study::new(&opts).unwrap();
    let warmups: Vec<u32> = study.configurations.iter().map(|c| c.warmup).collect();
    assert_eq!(warmups, [1, 1, 16, 80]);
    // A study of the mean of the frames (a still of this static scene): "auto" renders
    // independent frames, with no history to warm up.
    let still = StudyOptions {
        per_frame: false,
        ..opts.clone()
    };
    let study = Study::new(&still).unwrap();
    let warmups: Vec<u32> = study.configurations.iter().map(|c| c.warmup).collect();
    assert_eq!(warmups, [1, 1, 1, 1]);
    remove_scratch(&opts);
}

#[test]
fn bad_options_fail_before_rendering() {
    let opts = grid_options("bad-options");
    let cases = [
        (vec!["spp=1,2", "spp=4"], None, 1, "already varied"),
        // The scene's seed is 0, so the reference's folds to 0x5EED_5EED.
        (vec!["seed=1592614637"], None, 1, "same random numbers"),
        (vec!["volume=baseline", "spp=1,2"], Some("spp=1"), 1, "knob"),
        (vec!["seed=1,2"], None, 3, "--vary seed=1,2 with --seeds 3"),
        (vec!["seed=1,2"], None, 3, "--seeds 1"),
        (vec![], None, 0, "--seeds 0: expected 1..=64"),
        (vec![], None, 65, "--seeds 65"),
    ];
    for (vary, baseline, seeds, needle) in cases {
        let bad = StudyOptions {
            vary: vary.iter().map(|v| (*v).to_owned()).collect(),
            baseline: baseline.map(str::to_owned),
            seeds,
            ..opts.clone()
        };
        let message = format!("{:#}", Study::new(&bad).err().expect("an error"));
        assert!(message.contains(needle), "{vary:?}: {message}");
    }
    remove_scratch(&opts);
}

/// The size, frame counts and varied values are the scene's fields, checked by the scene
/// parser as a file holding them would be, each error naming the flag it came from.
#[test]
fn options_the_scene_format_refuses_are_refused_naming_the_flag() {
    let opts = grid_options("scene-checks");
    let cases = [
        (
            StudyOptions {
                width: Some(0),
                ..opts.clone()
            },
            "--width 0",
        ),
        (
            StudyOptions {
                height: Some(70_000),
                ..opts.clone()
            },
            "--height 70000",
        ),
        (
            StudyOptions {
                reference_spp: 0,
                ..opts.clone()
            },
            "--reference-spp 0",
        ),
        (
            StudyOptions {
                reference_frames: 2_000_000,
                ..opts.clone()
            },
            "--reference-frames 2000000",
        ),
        (
            StudyOptions {
                vary: vec!["spatial_neighbors=4,65".into()],
                ..opts.clone()
            },
            "--vary spatial_neighbors=65",
        ),
        (
            StudyOptions {
                vary: vec!["seed=1,-3".into()],
                seeds: 1,
                ..opts.clone()
            },
            "--vary seed=-3",
        ),
    ];
    for (bad, needle) in cases {
        let message = format!("{:#}", Study::new(&bad).err().expect("an error"));
        assert!(message.contains(needle), "{needle}: {message}");
    }
    remove_scratch(&opts);
}

/// An animated study renders the warm-up's scene frames and then its window: a camera
/// whose path enters a sphere light after the scene file's own frames is refused.
#[test]
fn every_scene_frame_a_study_renders_is_checked() {
    let opts = grid_options("animated-checks");
    let scene = std::fs::read_to_string(&opts.scene).unwrap();
    let scene = scene.replace("width = 8", "frames = 2\nwidth = 8")
        + "[[camera.keyframe]]\nframe = 0\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\n\
           [[camera.keyframe]]\nframe = 1\nposition = [0, 0, 2.9]\nlook_at = [0, 0, 0]\n\
           [[camera.keyframe]]\nframe = 20\nposition = [0, 0, 1.2]\nlook_at = [0, 0, 0]\n\
           [[light]]\ntype = \"sphere\"\ncenter = [0, 0, 1.2]\nradius = 0.1\n\
           radiance = [1, 1, 1]\n";
    std::fs::write(&opts.scene, scene).unwrap();
    nimbus_scene::load(&opts.scene).expect("the file itself is valid (2 frames)");
    let animated = StudyOptions {
        per_frame: true,
        frames: 3,
        ..opts.clone()
    };
    let message = format!("{:#}", Study::new(&animated).err().expect("an error"));
    assert!(message.contains("scene frames 0.."), "{message}");
    assert!(message.contains("sphere"), "{message}");
    remove_scratch(&opts);
}

/// An animated scene is measured frame by frame against each frame's own reference:
/// without --per-frame it is refused, as is varying its frames; with it, every
/// configuration measures the frames after the longest warm-up.
#[test]
fn an_animated_scene_is_measured_frame_by_frame() {
    let opts = grid_options("animated");
    let scene = std::fs::read_to_string(&opts.scene).unwrap();
    let light = "[[light]]\ntype = \"directional\"\nirradiance = 1\n\
                 [[light.keyframe]]\nframe = 0\ndirection = [0, -1, 0]\n\
                 [[light.keyframe]]\nframe = 4\ndirection = [0, -1, 1]\n";
    std::fs::write(&opts.scene, format!("{scene}{light}")).unwrap();
    let message = format!("{:#}", Study::new(&opts).err().expect("an error"));
    assert!(
        message.contains("animated") && message.contains("--per-frame"),
        "{message}"
    );
    let per_frame = StudyOptions {
        per_frame: true,
        frames: 3,
        warmup: 2,
        ..opts.clone()
    };
    let bad = StudyOptions {
        vary: vec!["frames=1,2".into()],
        ..per_frame.clone()
    };
    let message = format!("{:#}", Study::new(&bad).err().expect("an error"));
    assert!(message.contains("--vary frames=1,2"), "{message}");
    let study = Study::new(&StudyOptions {
        vary: vec!["volume=baseline,restir".into(), "temporal_limit=3".into()],
        ..per_frame
    })
    .unwrap();
    // ReSTIR warms up 4·Q = 12 frames, so every configuration measures 12..15.
    assert_eq!(study.window, Some(12..15));
    assert!(study.references.iter().all(|r| r.window == study.window));
    remove_scratch(&opts);
}

#[test]
fn reference_seed_differs_after_folding() {
    for seed in [0, 1, 0x5EED, u64::MAX, 0x5EED_0000_0000_0000] {
        assert_ne!(fold_seed(seed), fold_seed(seed ^ REFERENCE_SEED_MIX));
    }
}
