//! Running a prepared [`Study`]: the references (cached or rendered), every
//! distinct configuration rendered once per seed and measured, and the results
//! written.

use std::ops::Range;
use std::time::Instant;

use anyhow::{ensure, Context as _, Result};
use nimbus_gpu::Context;

use super::cache::{load_cached, stack, store_cached, Reference, ReferenceJob};
use super::metrics::{
    equal_time_over_seeds, frame_gpu_ms, mean_metrics, mean_of, measure, summarize, ReferenceNoise,
    SeedRun,
};
use super::report::{
    csv, equal_time_text, equivalents_text, left_out_text, markdown_table, noise_text, sig, table,
    timing_text,
};
use super::vary::{format_pairs, group_series, series_key, series_label, Assignment, KNOB_KEYS};
use super::{plot, scene_stem, Configuration, Row, Study};
use nimbus::renderer::{self, FrameSelection, RenderOptions, RenderResult};

impl Study {
    /// Renders (or loads) the references, measures every distinct configuration with
    /// every seed, writes `study.csv`, `study.md` and `study.png`, and prints the table.
    pub fn run(&self, ctx: &Context) -> Result<()> {
        let device = ctx.info().name.clone();
        let references: Vec<Reference> = self
            .references
            .iter()
            .map(|job| self.reference(ctx, job))
            .collect::<Result<_>>()?;

        let total = self.configurations.len();
        let mut rows: Vec<Row> = Vec::with_capacity(total);
        // The row of each configuration.
        let mut row_of: Vec<usize> = Vec::with_capacity(total);
        for (i, config) in self.configurations.iter().enumerate() {
            let label = config_label(&config.assignment);
            if let Some(first) = config.same_as {
                let row = row_of[first];
                eprintln!(
                    "[{}/{total}] {label}: renders exactly as {} (measured once, reported as that)",
                    i + 1,
                    config_label(&rows[row].assignment)
                );
                rows[row].equivalents.push(config.assignment.clone());
                row_of.push(row);
                continue;
            }
            let reference = &references[config.reference];
            let mut runs = Vec::with_capacity(config.seeds.len());
            for (s, &seed) in config.seeds.iter().enumerate() {
                let start = Instant::now();
                let run = self
                    .measure_seed(ctx, config, seed, reference)
                    .with_context(|| format!("configuration {label}, seed {seed}"))?;
                let m = &run.metrics;
                eprintln!(
                    "[{}/{total}] {label}, seed {seed} ({}/{}): {} ms/frame, {} ms total, RMSE {}, \
                     rel MSE {}, mean rel diff {:+.2}% ({:.1} s)",
                    i + 1,
                    s + 1,
                    config.seeds.len(),
                    sig(run.gpu_ms_per_frame, 4),
                    sig(run.gpu_ms_total, 4),
                    sig(m.rmse, 4),
                    sig(m.rel_mse, 4),
                    m.mean_rel_diff * 100.0,
                    start.elapsed().as_secs_f64()
                );
                runs.push(run);
            }
            let summary = summarize(&runs).with_context(|| format!("configuration {label}"))?;
            row_of.push(rows.len());
            rows.push(Row {
                assignment: config.assignment.clone(),
                equivalents: Vec::new(),
                reference: config.reference,
                frames: config.scene.render.frames,
                spp: config.scene.render.spp,
                box_samples: config.scene.integrator.box_samples,
                warmup: config.warmup,
                runs,
                summary,
            });
        }

        let mean_series = series(&rows, None);
        let seeds = rows.first().map_or(0, |r| r.runs.len());
        let per_seed: Vec<Vec<plot::Series>> = if seeds > 1 {
            (0..seeds).map(|s| series(&rows, Some(s))).collect()
        } else {
            Vec::new()
        };
        let comparisons = self
            .baseline
            .as_ref()
            .map(|b| equal_time_over_seeds(b, &mean_series, &per_seed));
        let (header, cells) = table(&self.varies, &rows, false);
        let (csv_header, csv_cells) = table(&self.varies, &rows, true);

        let dir = &self.out_dir;
        let csv_path = dir.join("study.csv");
        std::fs::write(&csv_path, csv(&csv_header, &csv_cells))
            .with_context(|| format!("writing {}", csv_path.display()))?;

        let table = markdown_table(&header, &cells);
        let mut noise = String::new();
        for (i, (job, reference)) in self.references.iter().zip(&references).enumerate() {
            let used: Vec<Row> = rows.iter().filter(|r| r.reference == i).cloned().collect();
            let of = (self.references.len() > 1).then(|| reference_label(job));
            noise += &noise_text(
                &reference.noise,
                job.scene.render.frames,
                &used,
                of.as_deref(),
            );
        }
        let equivalents = equivalents_text(&rows);
        let timing = timing_text(&rows);
        let left_out = left_out_text(&self.left_out);
        let equal = comparisons
            .as_ref()
            .map(|c| equal_time_text(c, self.baseline.as_ref(), seeds));
        let md_path = dir.join("study.md");
        let mut md = self.header_text(&device, &references);
        md += "\n";
        md += &table;
        for text in [&equivalents, &left_out].into_iter().flatten() {
            md += "\n";
            md += text;
        }
        md += "\n";
        md += &noise;
        if let Some(text) = &equal {
            md += "\n";
            md += text;
        }
        if let Some(text) = &timing {
            md += "\n";
            md += text;
        }
        md += "\n![RMSE versus total GPU time](study.png)\n";
        std::fs::write(&md_path, &md).with_context(|| format!("writing {}", md_path.display()))?;

        let png_path = dir.join("study.png");
        let title = format!(
            "{}: RMSE vs GPU time, {}x{}, {}",
            scene_stem(&self.scene_path),
            self.width,
            self.height,
            device
        );
        let knobs: Vec<&str> = self
            .varies
            .iter()
            .map(|v| v.key.as_str())
            .filter(|k| KNOB_KEYS.contains(k))
            .collect();
        plot::write_png(&png_path, &title, &knobs, &mean_series)
            .with_context(|| format!("writing {}", png_path.display()))?;

        print!("{table}");
        for text in [&equivalents, &left_out].into_iter().flatten() {
            print!("\n{text}");
        }
        print!("\n{noise}");
        if let Some(text) = &equal {
            print!("\n{text}");
        }
        if let Some(text) = &timing {
            print!("\n{text}");
        }
        eprintln!(
            "wrote {}, {} and {}",
            csv_path.display(),
            md_path.display(),
            png_path.display()
        );
        Ok(())
    }

    /// Renders `config` with `seed` after its warm-up and measures it against
    /// `reference`.
    fn measure_seed(
        &self,
        ctx: &Context,
        config: &Configuration,
        seed: u64,
        reference: &Reference,
    ) -> Result<SeedRun> {
        let mut scene = config.scene.clone();
        scene.render.seed = seed;
        let opts = RenderOptions {
            warmup_frames: config.warmup,
            keep_frames: self.per_frame,
            // Studies measure radiance: the alpha nobody reads would only add its cost.
            skip_alpha: true,
            // Every configuration timed at the GPU's working clocks, whatever its load.
            settle: self.settle,
            ..Default::default()
        };
        if let Some(window) = &self.window {
            return self.measure_window(ctx, config, &scene, opts, window, reference);
        }
        let result = renderer::render(ctx, &scene, &config.plan, &opts).context("rendering")?;
        let (gpu_ms_per_frame, mut gpu_ms_total) = frame_gpu_ms(&result.frame_timings)
            .with_context(|| format!("on device '{}'", ctx.info().name))?;
        let metrics = if self.per_frame {
            // The mean of the frames' own errors, at the cost of one frame.
            gpu_ms_total = gpu_ms_per_frame;
            mean_metrics(&result.frame_images, &reference.image)?
        } else {
            measure(&result.image, &reference.image)?
        };
        warn_non_finite(
            &result,
            &format!("{}, seed {seed}", config_label(&config.assignment)),
        );
        Ok(SeedRun {
            seed,
            gpu_ms_per_frame,
            gpu_ms_total,
            metrics,
        })
    }

    /// An animated scene's configuration: the scene frames of `window`, each its own
    /// image of one dispatch after the configuration's warm-up on the frames before
    /// them, each measured against its own frame of `reference`; the error is the mean
    /// of the frames' errors at the GPU time of one frame.
    fn measure_window(
        &self,
        ctx: &Context,
        config: &Configuration,
        scene: &nimbus_scene::Scene,
        opts: RenderOptions,
        window: &Range<u32>,
        reference: &Reference,
    ) -> Result<SeedRun> {
        let opts = RenderOptions {
            keep_frames: false,
            frames: FrameSelection::Each {
                frames: window.clone().collect(),
                passes: 1,
            },
            ..opts
        };
        let mut timings = Vec::new();
        let mut errors = Vec::new();
        let mut non_finite = 0;
        renderer::render_each(ctx, scene, &config.plan, &opts, &mut |result| {
            let i = errors.len();
            let frame = reference.frame(i, scene.render.height)?;
            errors.push(measure(&result.image, &frame)?);
            timings.extend(result.frame_timings.iter().cloned());
            non_finite += result.non_finite_samples;
            Ok(())
        })
        .context("rendering")?;
        ensure!(
            errors.len() == window.len(),
            "internal: {} of the window's {} frames were rendered",
            errors.len(),
            window.len()
        );
        if non_finite > 0 {
            eprintln!(
                "warning: {}, seed {}: {non_finite} sample(s) were not finite and were dropped",
                config_label(&config.assignment),
                scene.render.seed
            );
        }
        let (gpu_ms_per_frame, _) =
            frame_gpu_ms(&timings).with_context(|| format!("on device '{}'", ctx.info().name))?;
        Ok(SeedRun {
            seed: scene.render.seed,
            gpu_ms_per_frame,
            gpu_ms_total: gpu_ms_per_frame,
            metrics: mean_of(&errors).context("no frames to measure")?,
        })
    }

    /// The cached reference if its files and settings match, else a fresh render that
    /// is then cached.
    fn reference(&self, ctx: &Context, job: &ReferenceJob) -> Result<Reference> {
        if let Some(reference) = load_cached(job)? {
            eprintln!(
                "using cached reference {} ({}, rendered on {})",
                job.exr.display(),
                reference_label(job),
                reference.device
            );
            return Ok(reference);
        }
        let r = &job.scene.render;
        eprintln!(
            "rendering reference: {} frame(s) x {} spp, {}, box_estimator={}, box_samples={}, {}x{} (cache key {})",
            r.frames,
            r.spp,
            reference_label(job),
            job.scene.integrator.box_estimator.name(),
            job.scene.integrator.box_samples,
            r.width,
            r.height,
            job.key
        );
        let opts = RenderOptions {
            progress: true,
            skip_alpha: true,
            ..Default::default()
        };
        let (result, image, std_error) = match &job.window {
            None => {
                let result =
                    renderer::render(ctx, &job.scene, &job.plan, &opts).with_context(|| {
                        format!("rendering the reference ({})", reference_label(job))
                    })?;
                let (image, std_error) = (result.image.clone(), result.std_error.clone());
                (result, image, std_error)
            }
            Some(window) => {
                // One image per scene frame, each the mean of `frames` dispatches.
                let opts = RenderOptions {
                    frames: FrameSelection::Each {
                        frames: window.clone().collect(),
                        passes: r.frames,
                    },
                    ..opts
                };
                let (mut images, mut errors) = (Vec::new(), Vec::new());
                let result = renderer::render_each(ctx, &job.scene, &job.plan, &opts, &mut |r| {
                    images.push(r.image.clone());
                    errors.push(r.std_error.clone());
                    Ok(())
                })
                .with_context(|| format!("rendering the reference ({})", reference_label(job)))?;
                (result, stack(&images)?, stack(&errors)?)
            }
        };
        warn_non_finite(&result, "reference");
        let noise = ReferenceNoise::of(&image, &std_error);
        let device = ctx.info().name.clone();
        store_cached(job, &image, &noise, &device, result.wall_time.as_secs_f64())?;
        eprintln!(
            "reference rendered in {:.1} s, cached as {}",
            result.wall_time.as_secs_f64(),
            job.exr.display()
        );
        Ok(Reference {
            image,
            noise,
            device,
            cached: false,
        })
    }
}

/// A configuration's name in messages.
fn config_label(assignment: &Assignment) -> String {
    if assignment.is_empty() {
        "scene settings".to_owned()
    } else {
        format_pairs(assignment)
    }
}

/// What tells the references apart: the integrand's settings.
pub(super) fn reference_label(job: &ReferenceJob) -> String {
    format!("max_bounces={}", job.scene.integrator.max_bounces)
}

/// The series of the measured rows, each as (label, points sorted by time): of the
/// seed-mean values (median time, RMSE of the mean MSE, with the seeds' RMSE range)
/// when `seed` is `None`, else of that seed's own render.
fn series(rows: &[Row], seed: Option<usize>) -> Vec<plot::Series> {
    let assignments: Vec<Assignment> = rows.iter().map(|r| r.assignment.clone()).collect();
    group_series(&assignments)
        .into_iter()
        .map(|(key, members)| {
            let mut points: Vec<plot::Point> = members
                .iter()
                .map(|&i| {
                    let row = &rows[i];
                    let knobs: Vec<(String, String)> = row
                        .assignment
                        .iter()
                        .filter(|(k, _)| KNOB_KEYS.contains(&k.as_str()))
                        .cloned()
                        .collect();
                    let (time_ms, rmse, rmse_range) = match seed.and_then(|s| row.runs.get(s)) {
                        Some(run) => (run.gpu_ms_total, run.metrics.rmse, None),
                        None => {
                            let s = &row.summary;
                            let range = (row.runs.len() > 1).then_some((s.rmse_min, s.rmse_max));
                            (s.gpu_ms_total, s.metrics.rmse, range)
                        }
                    };
                    plot::Point {
                        time_ms,
                        rmse,
                        knobs,
                        rmse_range,
                    }
                })
                .collect();
            points.sort_by(|a, b| a.time_ms.total_cmp(&b.time_ms));
            let mut aliases: Vec<Assignment> = Vec::new();
            for &i in &members {
                for other in &rows[i].equivalents {
                    let alias = series_key(other);
                    if alias != key && !aliases.contains(&alias) {
                        aliases.push(alias);
                    }
                }
            }
            plot::Series {
                label: series_label(&key),
                key,
                aliases,
                points,
            }
        })
        .collect()
}

fn warn_non_finite(result: &RenderResult, what: &str) {
    if result.non_finite_samples > 0 {
        eprintln!(
            "warning: {what}: {} sample(s) were not finite and were dropped",
            result.non_finite_samples
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vary::assignment;
    use crate::{test_row, test_row_seeds};

    #[test]
    fn rows_become_series_sorted_by_time_with_their_knobs() {
        let rows = [
            test_row(&[("box_estimator", "rm"), ("spp", "4")], 4.0, 0.5),
            test_row(&[("box_estimator", "reds"), ("spp", "4")], 5.0, 0.2),
            test_row(&[("box_estimator", "rm"), ("spp", "1")], 1.0, 1.0),
        ];
        let all = series(&rows, None);
        assert_eq!(all.len(), 2);
        assert_eq!(all[0].key, assignment(&[("box_estimator", "rm")]));
        assert_eq!(all[0].label, "box_estimator=rm");
        let points: Vec<(f64, f64)> = all[0].points.iter().map(|p| (p.time_ms, p.rmse)).collect();
        assert_eq!(points, [(1.0, 1.0), (4.0, 0.5)]);
        assert_eq!(all[0].points[0].knobs, assignment(&[("spp", "1")]));
        assert_eq!(all[1].label, "box_estimator=reds");
        assert_eq!(all[1].points.len(), 1);
        // One seed: no range to draw, no aliases.
        assert!(all[0].points.iter().all(|p| p.rmse_range.is_none()));
        assert!(all.iter().all(|s| s.aliases.is_empty()));
    }

    /// With seeds, the series of the means carry the seeds' RMSE range and the median
    /// time; the series of one seed carry that seed's own values.
    #[test]
    fn series_of_the_seed_means_and_of_each_seed() {
        let rows = [
            test_row_seeds(&[("spp", "1")], &[(1.0, 1.0), (3.0, 2.0), (2.0, 0.5)]),
            test_row_seeds(&[("spp", "4")], &[(4.0, 0.5), (4.0, 0.25), (6.0, 1.0)]),
        ];
        let mean = series(&rows, None);
        assert_eq!(mean.len(), 1);
        let p = &mean[0].points[0];
        assert_eq!(p.time_ms, 2.0, "median time");
        assert!(
            (p.rmse - (5.25f64 / 3.0).sqrt()).abs() < 1e-12,
            "{}",
            p.rmse
        );
        assert_eq!(p.rmse_range, Some((0.5, 2.0)));
        let second = series(&rows, Some(1));
        let points: Vec<(f64, f64)> = second[0]
            .points
            .iter()
            .map(|p| (p.time_ms, p.rmse))
            .collect();
        assert_eq!(points, [(3.0, 2.0), (4.0, 0.25)]);
        assert!(second[0].points.iter().all(|p| p.rmse_range.is_none()));
    }

    /// A series whose rows other configurations render as has their series keys as
    /// aliases, so the equal-time comparison finds it under either name.
    #[test]
    fn merged_configurations_alias_their_series() {
        let mut baseline = test_row(&[("volume", "baseline"), ("temporal_limit", "4")], 1.0, 1.0);
        baseline.equivalents = vec![assignment(&[
            ("volume", "baseline"),
            ("temporal_limit", "20"),
        ])];
        let rows = [
            baseline,
            test_row(&[("volume", "restir"), ("temporal_limit", "4")], 1.0, 0.5),
            test_row(&[("volume", "restir"), ("temporal_limit", "20")], 1.0, 0.25),
        ];
        let all = series(&rows, None);
        assert_eq!(all.len(), 3);
        assert_eq!(
            all[0].aliases,
            [assignment(&[
                ("volume", "baseline"),
                ("temporal_limit", "20")
            ])]
        );
        let c = crate::metrics::equal_time(&("volume".into(), "baseline".into()), &all);
        let pairs: Vec<(&str, &str)> = c
            .iter()
            .map(|c| (c.series.as_str(), c.baseline.as_str()))
            .collect();
        assert_eq!(
            pairs,
            [
                (
                    "volume=restir temporal_limit=4",
                    "volume=baseline temporal_limit=4"
                ),
                (
                    "volume=restir temporal_limit=20",
                    "volume=baseline temporal_limit=4"
                ),
            ]
        );
        assert!((c[1].geo_mean.unwrap() - 0.25).abs() < 1e-12);
    }
}
