//! Running a prepared [`Study`]: the reference (cached or rendered), every
//! configuration rendered and measured, and the results written.

use std::time::Instant;

use anyhow::{Context as _, Result};
use nimbus_gpu::Context;

use super::cache::{load_cached, store_cached, Reference};
use super::metrics::{equal_time, frame_gpu_ms, mean_metrics, measure, ReferenceNoise};
use super::report::{csv, equal_time_text, markdown_table, noise_text, sig, table};
use super::vary::{format_pairs, group_series, series_label, Assignment, KNOB_KEYS};
use super::{plot, scene_stem, Row, Study};
use crate::renderer::{self, RenderOptions, RenderResult};

impl Study {
    /// Renders (or loads) the reference, measures every configuration, writes
    /// `study.csv`, `study.md` and `study.png`, and prints the table.
    pub fn run(&self, ctx: &Context) -> Result<()> {
        let device = ctx.info().name.clone();
        let reference = self.reference(ctx)?;

        let total = self.configurations.len();
        let mut rows = Vec::with_capacity(total);
        for (i, config) in self.configurations.iter().enumerate() {
            let label = if config.assignment.is_empty() {
                "scene settings".to_owned()
            } else {
                format_pairs(&config.assignment)
            };
            if let Some(first) = config.same_as {
                let earlier: &Row = &rows[first];
                eprintln!(
                    "[{}/{total}] {label}: renders exactly as {} (its measurement reused)",
                    i + 1,
                    format_pairs(&earlier.assignment)
                );
                let mut row = earlier.clone();
                row.assignment = config.assignment.clone();
                row.spp = config.scene.render.spp;
                rows.push(row);
                continue;
            }
            let opts = RenderOptions {
                warmup_frames: self.warmup.max(1),
                keep_frames: self.per_frame,
                ..Default::default()
            };
            let start = Instant::now();
            let result = renderer::render(ctx, &config.scene, &config.plan, &opts)
                .with_context(|| format!("rendering configuration {label}"))?;
            let (gpu_ms_per_frame, mut gpu_ms_total) = frame_gpu_ms(&result.frame_timings)
                .with_context(|| format!("configuration {label} on device '{device}'"))?;
            let metrics = if self.per_frame {
                // The mean of the frames' own errors, at the cost of one frame.
                gpu_ms_total = gpu_ms_per_frame;
                mean_metrics(&result.frame_images, &reference.image)?
            } else {
                measure(&result.image, &reference.image)?
            };
            warn_non_finite(&result, &label);
            eprintln!(
                "[{}/{total}] {label}: {} ms/frame, {} ms total, RMSE {}, rel MSE {}, mean rel diff {:+.2}% ({:.1} s)",
                i + 1,
                sig(gpu_ms_per_frame, 4),
                sig(gpu_ms_total, 4),
                sig(metrics.rmse, 4),
                sig(metrics.rel_mse, 4),
                metrics.mean_rel_diff * 100.0,
                start.elapsed().as_secs_f64()
            );
            rows.push(Row {
                assignment: config.assignment.clone(),
                frames: config.scene.render.frames,
                spp: config.scene.render.spp,
                box_samples: config.scene.integrator.box_samples,
                gpu_ms_per_frame,
                gpu_ms_total,
                metrics,
            });
        }

        let series = series(&rows);
        let comparisons = self.baseline.as_ref().map(|b| equal_time(b, &series));
        let (header, cells) = table(&self.varies, &rows, false);
        let (csv_header, csv_cells) = table(&self.varies, &rows, true);

        let dir = &self.out_dir;
        let csv_path = dir.join("study.csv");
        std::fs::write(&csv_path, csv(&csv_header, &csv_cells))
            .with_context(|| format!("writing {}", csv_path.display()))?;

        let table = markdown_table(&header, &cells);
        let noise = noise_text(&reference.noise, self.reference.scene.render.frames, &rows);
        let equal = comparisons
            .as_ref()
            .map(|c| equal_time_text(c, self.baseline.as_ref()));
        let md_path = dir.join("study.md");
        let mut md = self.header_text(&device, &reference);
        md += "\n";
        md += &table;
        md += "\n";
        md += &noise;
        if let Some(text) = &equal {
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
        plot::write_png(&png_path, &title, &knobs, &series)
            .with_context(|| format!("writing {}", png_path.display()))?;

        print!("{table}\n{noise}");
        if let Some(text) = &equal {
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

    /// The cached reference if its files and settings match, else a fresh render that
    /// is then cached.
    fn reference(&self, ctx: &Context) -> Result<Reference> {
        let job = &self.reference;
        if let Some(reference) = load_cached(job)? {
            eprintln!(
                "using cached reference {} (rendered on {})",
                job.exr.display(),
                reference.device
            );
            return Ok(reference);
        }
        let r = &job.scene.render;
        eprintln!(
            "rendering reference: {} frame(s) x {} spp, box_estimator={}, box_samples={}, {}x{} (cache key {})",
            r.frames,
            r.spp,
            job.scene.integrator.box_estimator.name(),
            job.scene.integrator.box_samples,
            r.width,
            r.height,
            job.key
        );
        let opts = RenderOptions {
            progress: true,
            ..Default::default()
        };
        let result = renderer::render(ctx, &job.scene, &job.plan, &opts)
            .context("rendering the reference")?;
        warn_non_finite(&result, "reference");
        let noise = ReferenceNoise::of(&result.image, &result.std_error);
        let device = ctx.info().name.clone();
        store_cached(
            job,
            &result.image,
            &noise,
            &device,
            result.wall_time.as_secs_f64(),
        )?;
        eprintln!(
            "reference rendered in {:.1} s, cached as {}",
            result.wall_time.as_secs_f64(),
            job.exr.display()
        );
        Ok(Reference {
            image: result.image,
            noise,
            device,
            cached: false,
        })
    }
}

/// The series of the measured rows, each as (label, points sorted by time).
fn series(rows: &[Row]) -> Vec<plot::Series> {
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
                    plot::Point {
                        time_ms: row.gpu_ms_total,
                        rmse: row.metrics.rmse,
                        knobs,
                    }
                })
                .collect();
            points.sort_by(|a, b| a.time_ms.total_cmp(&b.time_ms));
            plot::Series {
                label: series_label(&key),
                key,
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
    use crate::study::test_row;
    use crate::study::vary::assignment;

    #[test]
    fn rows_become_series_sorted_by_time_with_their_knobs() {
        let rows = [
            test_row(&[("box_estimator", "rm"), ("spp", "4")], 4.0, 0.5),
            test_row(&[("box_estimator", "reds"), ("spp", "4")], 5.0, 0.2),
            test_row(&[("box_estimator", "rm"), ("spp", "1")], 1.0, 1.0),
        ];
        let all = series(&rows);
        assert_eq!(all.len(), 2);
        assert_eq!(all[0].key, assignment(&[("box_estimator", "rm")]));
        assert_eq!(all[0].label, "box_estimator=rm");
        let points: Vec<(f64, f64)> = all[0].points.iter().map(|p| (p.time_ms, p.rmse)).collect();
        assert_eq!(points, [(1.0, 1.0), (4.0, 0.5)]);
        assert_eq!(all[0].points[0].knobs, assignment(&[("spp", "1")]));
        assert_eq!(all[1].label, "box_estimator=reds");
        assert_eq!(all[1].points.len(), 1);
    }
}
