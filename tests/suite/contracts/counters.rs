//! Work counters as the cost guard of issue 23: what every benchmark case does per camera
//! sample is pinned in `assets/bench/baseline.json` (written by `nimbus bench --update`),
//! so a change that doubles a pass's work (or splits a frame into a dispatch per sample)
//! fails here instead of landing silently. Counting must not change the image.

use std::path::Path;

use nimbus::bench::{self, COUNTER_MARGIN};
use nimbus::plan;
use nimbus::renderer::{render, RenderOptions};

use crate::common::gpu::{assert_no_validation_errors, context};

fn baseline() -> bench::BenchReport {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/bench/baseline.json");
    bench::load_baseline(&path).expect("the stored bench baseline")
}

#[test]
fn work_per_sample_stays_within_the_margin_of_the_stored_baseline() {
    let ctx = context();
    let report = bench::run(&ctx, None).expect("bench cases");
    assert_no_validation_errors(&ctx);
    let base = baseline();
    assert_eq!(
        base.cases.keys().collect::<Vec<_>>(),
        report.cases.keys().collect::<Vec<_>>(),
        "the bench cases changed: write a new baseline with `nimbus bench --update`"
    );
    if bench::device_family(&base.device) != bench::device_family(&report.device) {
        eprintln!(
            "the baseline was counted on '{}', this device is '{}': not judged",
            base.device, report.device
        );
        return;
    }
    let regressions = bench::regressions(&report, &base);
    assert!(
        regressions.is_empty(),
        "work counters moved past {COUNTER_MARGIN}x of assets/bench/baseline.json \
         (a cost regression, or a meant change: then `nimbus bench --update` and say why \
         in the commit):\n{}\n\n{}",
        regressions
            .iter()
            .map(|r| format!("  {r}"))
            .collect::<Vec<_>>()
            .join("\n"),
        bench::table(&report, Some(&base))
    );
}

#[test]
fn counters_are_deterministic_see_the_work_and_leave_the_image_alone() {
    let ctx = context();
    let case = bench::CASES
        .iter()
        .find(|c| c.name == "baseline-k3")
        .expect("case");
    let a = bench::run_case(&ctx, case).expect("first run");
    let b = bench::run_case(&ctx, case).expect("second run");
    assert_eq!(
        a.counters, b.counters,
        "same scene, seed and device, same counts"
    );
    assert_eq!(a.dispatches_per_frame, b.dispatches_per_frame);
    let per = &a.counters["baseline"];
    // Every camera ray of the cloud walks super-voxels and looks up density; the
    // scattering vertices send shadow rays; there are no meshes.
    assert!(per["steps"] > 1.0, "{per:?}");
    assert!(per["density"] > 1.0, "{per:?}");
    assert!(per["majorant"] > 1.0, "{per:?}");
    assert!(per["collisions"] > 0.5, "{per:?}");
    assert!(per["shadow_rays"] > 0.1, "{per:?}");
    assert!(per["shadow_steps"] >= per["shadow_rays"], "{per:?}");
    assert_eq!(per["bvh_nodes"], 0.0);

    // The counting pipelines render the same image as the plain ones.
    let scene = case.scene().expect("scene");
    let plan = plan::build(&scene, None).expect("plan");
    let plain = render(&ctx, &scene, &plan, &RenderOptions::default()).expect("plain");
    let counted = render(
        &ctx,
        &scene,
        &plan,
        &RenderOptions {
            counters: true,
            ..Default::default()
        },
    )
    .expect("counted");
    assert_no_validation_errors(&ctx);
    assert!(plain.work.is_none());
    assert_eq!(plain.image.data, counted.image.data);
    assert_eq!(plain.alpha, counted.alpha);

    // The longest invocation (a GPU dispatch's time where lanes diverge): one pixel's
    // samples (every frame), at least the mean invocation's work and at most all of it.
    let work = counted.work.expect("counted work");
    let slot = work.slot("baseline").expect("baseline slot");
    let spp = u64::from(scene.render.spp);
    assert_eq!(slot.longest[0], spp, "the most samples one invocation took");
    let invocations = slot.get("samples") / spp;
    for (i, (name, _)) in nimbus::shader_data::counters::NAMES
        .iter()
        .enumerate()
        .skip(1)
    {
        let total = slot.counts[i];
        assert!(
            slot.longest[i] * invocations >= total && slot.longest[i] <= total,
            "{name}: longest invocation {} against {total} over {invocations} invocations",
            slot.longest[i]
        );
    }
    assert!(slot.longest[1] > 0, "{:?}", slot.longest);
}

#[test]
fn restir_counts_every_stage_it_runs() {
    let ctx = context();
    let case = bench::CASES
        .iter()
        .find(|c| c.name == "restir-k3")
        .expect("case");
    let r = bench::run_case(&ctx, case).expect("restir");
    assert_no_validation_errors(&ctx);
    // Spatial reuse is off by default: its stage does not run and reports nothing.
    for stage in ["restir/initial", "restir/temporal", "restir/shade"] {
        assert!(
            r.counters.contains_key(stage),
            "{stage}: {:?}",
            r.counters.keys()
        );
    }
    // Candidates track the piecewise-constant grid (majorant fetches); shading marches
    // or tracks transmittance along the path's segments.
    assert!(r.counters["restir/initial"]["majorant"] > 1.0);
    assert!(r.counters["restir/shade"]["shadow_rays"] > 0.1);
}

#[test]
fn coherent_lanes_trace_each_workgroups_first_pixel_in_all_of_its_pixels() {
    // `nimbus profile --coherent-lanes` measures what divergence costs: every 8x8
    // workgroup traces its first pixel's samples in all its invocations, so each block of
    // the image holds that pixel's value, where the plain render's pixels differ (those
    // that see the cloud: the sky around it is one constant).
    let ctx = context();
    let case = bench::CASES
        .iter()
        .find(|c| c.name == "baseline-k1")
        .expect("case");
    let scene = case.scene().expect("scene");
    let plan = plan::build(&scene, None).expect("plan");
    let plain = render(&ctx, &scene, &plan, &RenderOptions::default()).expect("plain");
    let coherent = render(
        &ctx,
        &scene,
        &plan,
        &RenderOptions {
            coherent_lanes: true,
            ..Default::default()
        },
    )
    .expect("coherent");
    assert_no_validation_errors(&ctx);
    let w = coherent.image.width as usize;
    let h = coherent.image.height as usize;
    let first =
        |img: &nimbus::output::ImageRgb, x: usize, y: usize| img.data[(y & !7) * w + (x & !7)];
    let mut plain_differs = 0;
    for y in 0..h {
        for x in 0..w {
            assert_eq!(
                coherent.image.data[y * w + x],
                first(&coherent.image, x, y),
                "pixel ({x}, {y}) is not its workgroup's first pixel"
            );
            plain_differs += usize::from(plain.image.data[y * w + x] != first(&plain.image, x, y));
        }
    }
    assert!(
        plain_differs > w * h / 8,
        "the plain render's blocks are uniform ({plain_differs} pixels differ)"
    );
}
