//! What a study writes: the results table as CSV and Markdown, numbers to a few
//! significant digits ([`sig`]), and the texts of study.md (header with the protocol,
//! the configurations measured as another, the references' noise, the equal-time
//! comparison).

use std::fmt::Write as _;

use super::cache::Reference;
use super::metrics::{Comparison, ReferenceNoise, MAX_EXTRAPOLATION, REL_MSE_EPSILON};
use super::run::reference_label;
use super::vary::{format_pairs, Assignment, Vary, KNOB_KEYS};
use super::{Row, Study, WARMUP_PER_TEMPORAL_LIMIT};

/// One field of a CSV row (RFC 4180): quoted when it holds a comma, quote or line
/// break, with quotes doubled.
fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_owned()
    }
}

/// A CSV document: the header, then one line per row.
pub(super) fn csv(header: &[String], rows: &[Vec<String>]) -> String {
    let line = |fields: &[String]| {
        let f: Vec<String> = fields.iter().map(|f| csv_field(f)).collect();
        f.join(",") + "\n"
    };
    let mut out = line(header);
    for row in rows {
        out += &line(row);
    }
    out
}

/// A Markdown table with padded columns (readable as plain text too); numeric-looking
/// columns are right-aligned.
pub(super) fn markdown_table(header: &[String], rows: &[Vec<String>]) -> String {
    let widths: Vec<usize> = (0..header.len())
        .map(|i| {
            rows.iter()
                .map(|r| r[i].chars().count())
                .chain([header[i].chars().count(), 3])
                .max()
                .unwrap_or(3)
        })
        .collect();
    let numeric: Vec<bool> = (0..header.len())
        .map(|i| !rows.is_empty() && rows.iter().all(|r| r[i].parse::<f64>().is_ok()))
        .collect();
    let cell = |text: &str, i: usize| {
        if numeric[i] {
            format!("{text:>w$}", w = widths[i])
        } else {
            format!("{text:<w$}", w = widths[i])
        }
    };
    let mut out = String::new();
    let row_line = |cells: Vec<String>| format!("| {} |\n", cells.join(" | "));
    out += &row_line(header.iter().enumerate().map(|(i, h)| cell(h, i)).collect());
    out += &row_line(
        widths
            .iter()
            .zip(&numeric)
            .map(|(&w, &num)| {
                if num {
                    format!("{}:", "-".repeat(w - 1))
                } else {
                    "-".repeat(w)
                }
            })
            .collect(),
    );
    for r in rows {
        out += &row_line(r.iter().enumerate().map(|(i, c)| cell(c, i)).collect());
    }
    out
}

/// `x` with `digits` significant digits, without exponent for moderate magnitudes.
pub(super) fn sig(x: f64, digits: usize) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let magnitude = x.abs().log10().floor() as i32;
    if !(-4..6).contains(&magnitude) {
        return format!("{x:.p$e}", p = digits.saturating_sub(1));
    }
    let decimals = (digits as i32 - 1 - magnitude).max(0) as usize;
    format!("{x:.decimals$}")
}

/// The results table, one line per distinct configuration: varied keys,
/// frames/spp/box_samples, the warm-up frames and seeds, then the measurements over the
/// seeds (median GPU times; RMSE of the mean MSE with the smallest and largest RMSE of
/// one seed; mean relative MSE and mean relative difference). `full` gives every digit
/// (for the CSV); otherwise 4 significant digits.
pub(super) fn table(varies: &[Vary], rows: &[Row], full: bool) -> (Vec<String>, Vec<Vec<String>>) {
    let varied: Vec<&str> = varies
        .iter()
        .map(|v| v.key.as_str())
        .filter(|k| !KNOB_KEYS.contains(k))
        .collect();
    let mut header: Vec<String> = varied.iter().map(|k| (*k).to_owned()).collect();
    header.extend(
        [
            "frames",
            "spp",
            "box_samples",
            "warmup",
            "seeds",
            "gpu_ms_per_frame",
            "gpu_ms_total",
            "rmse",
            "rmse_min",
            "rmse_max",
            "rel_mse",
            "mean_rel_diff",
        ]
        .map(str::to_owned),
    );
    let num = |x: f64| if full { format!("{x}") } else { sig(x, 4) };
    let cells = rows
        .iter()
        .map(|row| {
            let mut cells: Vec<String> = varied
                .iter()
                .map(|k| {
                    row.assignment
                        .iter()
                        .find(|(key, _)| key == k)
                        .map(|(_, v)| v.clone())
                        .unwrap_or_default()
                })
                .collect();
            let s = &row.summary;
            cells.extend([
                row.frames.to_string(),
                row.spp.to_string(),
                row.box_samples.to_string(),
                row.warmup.to_string(),
                row.runs.len().to_string(),
                num(s.gpu_ms_per_frame),
                num(s.gpu_ms_total),
                num(s.metrics.rmse),
                num(s.rmse_min),
                num(s.rmse_max),
                num(s.metrics.rel_mse),
                num(s.metrics.mean_rel_diff),
            ]);
            cells
        })
        .collect();
    (header, cells)
}

impl Study {
    /// The first lines of study.md: scene, device, resolution, references, and the
    /// protocol (seeds, warm-up, what the numbers are).
    pub(super) fn header_text(&self, device: &str, references: &[Reference]) -> String {
        let mut out = String::new();
        let _ = writeln!(out, "# Accuracy versus GPU time\n");
        let _ = writeln!(out, "- scene: `{}`", self.scene_path.display());
        let _ = writeln!(out, "- device: {device}");
        let _ = writeln!(out, "- resolution: {}x{}", self.width, self.height);
        let varied: Vec<String> = self
            .varies
            .iter()
            .map(|v| format!("`{}={}`", v.key, v.values.join(",")))
            .collect();
        if !varied.is_empty() {
            let _ = writeln!(out, "- varied: {}", varied.join(", "));
        }
        for (job, reference) in self.references.iter().zip(references) {
            let r = &job.scene.render;
            let _ = writeln!(
                out,
                "- reference: {} frame(s) x {} spp, {}, box_estimator = {}, box_samples = {}, seed {}; {} `{}`{}",
                r.frames,
                r.spp,
                reference_label(job).replace('=', " = "),
                job.scene.integrator.box_estimator.name(),
                job.scene.integrator.box_samples,
                r.seed,
                if reference.cached { "cached" } else { "rendered now and cached as" },
                job.exr.display(),
                if reference.device == device {
                    String::new()
                } else {
                    format!(" (rendered on {})", reference.device)
                }
            );
        }
        if let Some(w) = &self.window {
            let _ = writeln!(
                out,
                "- animated scene: every configuration measures scene frames {}..{} (after \
                 the longest warm-up), each against the reference of that scene frame (its \
                 frames x spp above are per scene frame); each configuration warms up on \
                 the scene frames just before them",
                w.start,
                w.end - 1
            );
        }
        if self.references.len() > 1 {
            let _ = writeln!(
                out,
                "- each configuration is measured against the reference of its own \
                 max_bounces (it changes the integrand; estimators, volume, spp, frames, \
                 seeds and the ReSTIR knobs do not)"
            );
        }
        let seeds = if self.seeds > 1 {
            format!(
                "{} seeds, derived from the scene's seed: each row gives the mean over the \
                 seeds of the MSE (rmse = its sqrt), rel_mse and mean_rel_diff, the median \
                 GPU times, and rmse_min / rmse_max, the smallest and largest RMSE of one \
                 seed: the spread of the Monte Carlo error (and the timing noise) from seed \
                 to seed; two rows whose ranges overlap are not told apart by these seeds",
                self.seeds
            )
        } else {
            "1 seed per configuration (no spread measured; --seeds N renders N)".to_owned()
        };
        let _ = writeln!(out, "- seeds: {seeds}");
        let _ = writeln!(
            out,
            "- warm-up (column warmup): frames rendered before the measured ones and not \
             measured: at least 1 (the first frame may include shader compilation), at \
             least {WARMUP_PER_TEMPORAL_LIMIT}·Q for Volumetric ReSTIR with temporal reuse \
             (Q = temporal_limit; its history reaches steady state only after a few Q \
             frames), at least --warmup ({})",
            self.warmup
        );
        let _ = writeln!(
            out,
            "- settle: {} ms of arithmetic load on the device right before each render's \
             measured frames, so that a GPU is timed at its working clocks (--settle-ms; \
             never on a CPU device)",
            self.settle.as_millis()
        );
        let (total, errors) = if self.per_frame {
            (
                "the time of one frame (total)",
                "each measured frame's own error against the reference, averaged over the \
                 frames (RMSE = sqrt of the mean MSE)",
            )
        } else {
            (
                "sum over frames (total)",
                "the error of the mean over the frames against the reference",
            )
        };
        let _ = writeln!(
            out,
            "- GPU time: the \"frame\" timestamp scope, median over frames (per frame) and \
             {total}; errors: {errors}, over all pixels and channels; rel_mse = mean \
             (a−r)²/(r²+{REL_MSE_EPSILON}); mean_rel_diff = mean over channels of (mean a − \
             mean r)/mean r"
        );
        out
    }
}

/// How far apart the GPU times of one configuration's seeds may be before the study
/// says the device changed state between renders.
pub(super) const SEED_TIME_SPREAD: f64 = 1.5;

/// Warnings about the GPU times themselves; `None` when they look like one device state.
///
/// Two signs that a render was timed in another state of the device than its neighbours
/// (a GPU's idle clocks, a pipeline the driver was still optimising): one
/// configuration's seeds whose median frame times differ by more than
/// [`SEED_TIME_SPREAD`]x, and a configuration with r times the samples per pixel of one
/// that differs from it in nothing else, which costs less than 1 + (r - 1) / 10 times as
/// much (the work grew r-fold, so the time must grow unless a frame's fixed cost is over
/// 9 samples').
/// On an H200 without `--settle-ms` both showed: the baseline's 1-spp frame took 0.78 ms
/// for one seed and 3.06 ms for the next, and 4 spp 13.5 ms against 16 spp 12.7 ms.
pub(super) fn timing_text(rows: &[Row]) -> Option<String> {
    let mut lines = Vec::new();
    for row in rows {
        let ms: Vec<f64> = row.runs.iter().map(|r| r.gpu_ms_per_frame).collect();
        let (lo, hi) = ms.iter().fold((f64::INFINITY, 0.0_f64), |(lo, hi), &t| {
            (lo.min(t), hi.max(t))
        });
        if ms.len() > 1 && lo > 0.0 && hi > SEED_TIME_SPREAD * lo {
            lines.push(format!(
                "- `{}`: its seeds took {} to {} ms a frame ({:.1}x)",
                format_pairs(&row.assignment),
                sig(lo, 4),
                sig(hi, 4),
                hi / lo
            ));
        }
    }
    // Rows equal but for spp, by their other settings.
    let without_spp = |row: &Row| -> Assignment {
        row.assignment
            .iter()
            .filter(|(k, _)| k != "spp")
            .cloned()
            .collect()
    };
    for (i, a) in rows.iter().enumerate() {
        for b in &rows[i + 1..] {
            let (fewer, more) = if a.spp < b.spp { (a, b) } else { (b, a) };
            if fewer.spp == more.spp
                || fewer.frames != more.frames
                || without_spp(a) != without_spp(b)
            {
                continue;
            }
            let (t_fewer, t_more) = (
                fewer.summary.gpu_ms_per_frame,
                more.summary.gpu_ms_per_frame,
            );
            // r times the samples cost at least 1 + (r - 1) / 10 times as much unless a
            // frame's fixed cost is over 9 samples' (no integrator here comes close).
            let r = f64::from(more.spp) / f64::from(fewer.spp.max(1));
            if t_more < t_fewer * (1.0 + (r - 1.0) / 10.0) {
                lines.push(format!(
                    "- `{}` ({} ms a frame) costs {:.2}x `{}` ({} ms): {} spp against {}",
                    format_pairs(&more.assignment),
                    sig(t_more, 4),
                    t_more / t_fewer,
                    format_pairs(&fewer.assignment),
                    sig(t_fewer, 4),
                    more.spp,
                    fewer.spp
                ));
            }
        }
    }
    if lines.is_empty() {
        return None;
    }
    let mut out = String::new();
    let _ = writeln!(
        out,
        "WARNING: these GPU times were not all taken in one state of the device (a GPU's \
         clocks between renders, a pipeline its driver was still optimising, or other \
         work on a CPU device's cores), so the equal-time comparisons above mix states. \
         On a GPU keep --settle-ms (500 by default: a load that raises its clocks before \
         each render's measured frames); on a CPU device measure on a quiet machine with \
         more frames. Compare with a run where this warning is absent.\n"
    );
    for line in lines {
        let _ = writeln!(out, "{line}");
    }
    Some(out)
}

/// The configurations that render exactly as another (the integrator does not read
/// the setting they differ in), each line `X renders as Y`; `None` when there are none.
pub(super) fn equivalents_text(rows: &[Row]) -> Option<String> {
    let lines: Vec<String> = rows
        .iter()
        .flat_map(|row| {
            row.equivalents.iter().map(move |e| {
                format!(
                    "- `{}` renders as `{}`",
                    format_pairs(e),
                    format_pairs(&row.assignment)
                )
            })
        })
        .collect();
    if lines.is_empty() {
        return None;
    }
    let mut out = String::new();
    let _ = writeln!(
        out,
        "Configurations measured once: the integrator does not read the settings they \
         differ in, so they render the same image; each is reported as the row it renders \
         as.\n"
    );
    for line in lines {
        let _ = writeln!(out, "{line}");
    }
    Some(out)
}

/// The configurations left out because they ask Volumetric ReSTIR for spp > 1
/// (`Study::left_out`); `None` when there are none.
pub(super) fn left_out_text(left_out: &[Assignment]) -> Option<String> {
    if left_out.is_empty() {
        return None;
    }
    let mut out = String::from(
        "Left out: Volumetric ReSTIR renders one path per pixel per frame (its work per frame \
         is set by `candidates`), so `--vary spp` varies only the other integrators' work \
         (the baseline's spp raised towards ReSTIR's frame time) and these are not rendered:\n",
    );
    for a in left_out {
        let _ = writeln!(out, "- `{}`", format_pairs(a));
    }
    Some(out)
}

/// The reference's own noise, and a warning when it is not small against the
/// errors measured with it (`rows`). `of` names the reference when there are several.
pub(super) fn noise_text(
    noise: &ReferenceNoise,
    frames: u32,
    rows: &[Row],
    of: Option<&str>,
) -> String {
    let mut out = String::new();
    let what = of.map_or_else(
        || "Reference noise".to_owned(),
        |of| format!("Reference noise ({of})"),
    );
    if frames < 2 {
        let _ = writeln!(
            out,
            "{what}: unknown (the reference has {frames} frame; its standard error needs \
             at least 2)."
        );
        return out;
    }
    let _ = writeln!(
        out,
        "{what}: mean relative standard error {}, RMS standard error {}.",
        sig(noise.mean_rel_std_error, 3),
        sig(noise.rms_std_error, 3)
    );
    let min_rmse = rows
        .iter()
        .map(|r| r.summary.metrics.rmse)
        .fold(f64::INFINITY, f64::min);
    if min_rmse.is_finite() && min_rmse > 0.0 {
        let q = noise.rms_std_error / min_rmse;
        if q > 0.1 {
            let _ = writeln!(
                out,
                "WARNING: the reference is not converged enough for this study: its RMS \
                 standard error is {:.0}% of the smallest RMSE measured ({}), so it \
                 accounts for about {:.0}% of that configuration's MSE. Raise \
                 --reference-frames (the standard error falls as 1/sqrt(frames)).",
                q * 100.0,
                sig(min_rmse, 3),
                (q * q).min(1.0) * 100.0
            );
        } else {
            let _ = writeln!(
                out,
                "It is {:.1}% of the smallest RMSE measured ({}): small enough.",
                q * 100.0,
                sig(min_rmse, 3)
            );
        }
    }
    out
}

/// The equal-time section of study.md; `seeds` renders per configuration.
pub(super) fn equal_time_text(
    comparisons: &[Comparison],
    baseline: Option<&(String, String)>,
    seeds: usize,
) -> String {
    let mut out = String::new();
    let name = baseline.map_or(String::new(), |(k, v)| format!("{k}={v}"));
    let _ = writeln!(out, "## Equal-time RMSE ratio against {name}\n");
    let _ = writeln!(
        out,
        "RMSE of the series over RMSE of the baseline at the baseline's measured GPU times \
         (series interpolated linearly in log RMSE over log time; when the series' times \
         all fall between the baseline's, the baseline interpolated at the series' times); \
         below 1 means more accurate for the same GPU time, and the MSE ratio is its \
         square.\n"
    );
    if seeds > 1 {
        let _ = writeln!(
            out,
            "The table and the ratio are those of the seed-mean series (RMSE of the mean \
             MSE over the {seeds} seeds, median GPU time). The spread after them is the \
             smallest and largest geometric-mean ratio of one seed: each seed's series \
             against the baseline series of the same seed, with that seed's own times. \
             It is how much the ratio moves from seed to seed; a spread that holds 1 \
             means these seeds do not show which series is better.\n"
        );
    }
    if comparisons.is_empty() {
        let _ = writeln!(out, "No other series to compare.");
        return out;
    }
    let header: Vec<String> = [
        "series",
        "baseline",
        "gpu_ms_total",
        "baseline_rmse",
        "series_rmse",
        "ratio",
    ]
    .map(str::to_owned)
    .to_vec();
    let mut rows = Vec::new();
    let mut summary = Vec::new();
    for c in comparisons {
        for &(t, b, s, ratio) in &c.points {
            rows.push(vec![
                c.series.clone(),
                c.baseline.clone(),
                sig(t, 4),
                sig(b, 4),
                sig(s, 4),
                sig(ratio, 3),
            ]);
        }
        let spread = match c.seed_spread() {
            Some((lo, hi)) => format!(
                " (per seed {}–{} over {} seeds)",
                sig(lo, 3),
                sig(hi, 3),
                c.seed_geo_means.len()
            ),
            None if !c.seed_geo_means.is_empty() => {
                " (per seed: no spread, some seeds' times do not overlap the baseline's)".to_owned()
            }
            None => String::new(),
        };
        let extrapolated = match c.extrapolated {
            None => String::new(),
            Some(slope) => format!(
                "; EXTRAPOLATED: the series' times lie outside the baseline's, and the \
                 baseline's RMSE there is that of its nearest measured point times \
                 (t_point / t)^1/2 (at most {}x away in time; the slope of its last two \
                 points is {}, the law's -0.5): measure the baseline at the series' time \
                 to confirm",
                MAX_EXTRAPOLATION,
                slope.map_or("-".to_owned(), |s| sig(s, 3))
            ),
        };
        summary.push(match c.geo_mean {
            Some(g) => format!(
                "- {} vs {}: geometric mean RMSE ratio {}{spread} over {} time(s){extrapolated}",
                c.series,
                c.baseline,
                sig(g, 3),
                c.points.len()
            ),
            None => format!(
                "- {} vs {}: no common GPU time range (the series' times do not overlap the \
                 baseline's, nor lie within {MAX_EXTRAPOLATION}x of its measured times)",
                c.series, c.baseline
            ),
        });
    }
    if !rows.is_empty() {
        out += &markdown_table(&header, &rows);
        out += "\n";
    }
    for line in summary {
        let _ = writeln!(out, "{line}");
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vary::{self, parse_vary};
    use crate::{grid_options, remove_scratch, test_row, test_row_seeds, StudyOptions};

    #[test]
    fn csv_quotes_only_when_needed() {
        assert_eq!(csv_field("rm"), "rm");
        assert_eq!(csv_field("a,b"), "\"a,b\"");
        assert_eq!(csv_field("say \"hi\""), "\"say \"\"hi\"\"\"");
        let header = vec!["spp".to_owned(), "rmse".to_owned()];
        let rows = vec![
            vec!["1".to_owned(), format!("{}", 0.125)],
            vec!["4".to_owned(), format!("{}", 1e-7)],
        ];
        assert_eq!(csv(&header, &rows), "spp,rmse\n1,0.125\n4,0.0000001\n");
    }

    #[test]
    fn markdown_table_aligns_columns() {
        let header = vec!["box_estimator".to_owned(), "rmse".to_owned()];
        let rows = vec![vec!["rm".to_owned(), "0.5".to_owned()]];
        assert_eq!(
            markdown_table(&header, &rows),
            "| box_estimator | rmse |\n| ------------- | ---: |\n| rm            |  0.5 |\n"
        );
    }

    #[test]
    fn sig_keeps_significant_digits() {
        assert_eq!(sig(1234.567, 4), "1235");
        assert_eq!(sig(0.012345, 3), "0.0123");
        assert_eq!(sig(2.0, 3), "2.00");
        assert_eq!(sig(1.5e-7, 3), "1.50e-7");
        assert_eq!(sig(0.0, 3), "0");
    }

    #[test]
    fn the_table_has_a_column_per_varied_series_key() {
        let varies = [
            parse_vary("box_estimator=rm,reds").unwrap(),
            parse_vary("spp=1,4").unwrap(),
        ];
        let rows = [
            test_row(&[("box_estimator", "rm"), ("spp", "1")], 1.0 / 3.0, 0.5),
            test_row(&[("box_estimator", "reds"), ("spp", "4")], 12.0, 1e-7),
        ];
        let (header, cells) = table(&varies, &rows, false);
        assert_eq!(
            header,
            [
                "box_estimator",
                "frames",
                "spp",
                "box_samples",
                "warmup",
                "seeds",
                "gpu_ms_per_frame",
                "gpu_ms_total",
                "rmse",
                "rmse_min",
                "rmse_max",
                "rel_mse",
                "mean_rel_diff"
            ]
        );
        assert_eq!(
            cells[0],
            [
                "rm", "2", "1", "8", "1", "1", "0.1667", "0.3333", "0.5000", "0.5000", "0.5000",
                "0.5000", "0.5000"
            ]
        );
        assert_eq!(
            cells[1][..8],
            ["reds", "2", "1", "8", "1", "1", "6.000", "12.00"]
        );
        assert_eq!(cells[1][8], "1.000e-7");
        let (full_header, full) = table(&varies, &rows, true);
        assert_eq!(full_header, header);
        assert_eq!(full[0][7], format!("{}", 1.0 / 3.0));
        assert_eq!(full[1][8], "0.0000001");
    }

    /// A row of several seeds: the mean MSE, median times and the RMSE range.
    #[test]
    fn the_table_reports_the_seeds_mean_and_spread() {
        let varies = [parse_vary("spp=1,4").unwrap()];
        let mut row = test_row_seeds(&[("spp", "1")], &[(3.0, 0.3), (1.0, 0.4), (2.0, 0.0)]);
        row.warmup = 80;
        let (header, cells) = table(&varies, &[row], true);
        let cell = |name: &str| {
            let i = header.iter().position(|h| h == name).unwrap();
            cells[0][i].clone()
        };
        assert_eq!(cell("warmup"), "80");
        assert_eq!(cell("seeds"), "3");
        assert_eq!(cell("gpu_ms_total"), "2");
        assert_eq!(cell("gpu_ms_per_frame"), "1");
        let rmse: f64 = cell("rmse").parse().unwrap();
        assert!((rmse - (0.25f64 / 3.0).sqrt()).abs() < 1e-12, "{rmse}");
        assert_eq!(
            (cell("rmse_min"), cell("rmse_max")),
            ("0".into(), "0.4".into())
        );
        let rel: f64 = cell("rel_mse").parse().unwrap();
        assert!((rel - 0.7 / 3.0).abs() < 1e-12, "{rel}");
    }

    #[test]
    fn equivalent_configurations_are_listed_once_as_what_they_render_as() {
        let mut row = test_row(&[("volume", "baseline"), ("temporal_limit", "4")], 1.0, 1.0);
        assert_eq!(equivalents_text(std::slice::from_ref(&row)), None);
        row.equivalents = vec![
            vary::assignment(&[("volume", "baseline"), ("temporal_limit", "20")]),
            vary::assignment(&[("volume", "baseline"), ("temporal_limit", "80")]),
        ];
        let text = equivalents_text(&[row]).unwrap();
        assert!(
            text.contains(
                "- `volume=baseline temporal_limit=20` renders as `volume=baseline \
                 temporal_limit=4`\n"
            ),
            "{text}"
        );
        assert_eq!(text.matches(" renders as ").count(), 2, "{text}");
    }

    #[test]
    fn noise_text_warns_when_the_reference_is_noisy() {
        let noise = |rms: f64| ReferenceNoise {
            rms_std_error: rms,
            mean_rel_std_error: 0.01,
        };
        let rows = [test_row(&[], 1.0, 0.2), test_row(&[], 2.0, 0.1)];
        let noise_text =
            |n: &ReferenceNoise, frames: u32, rows: &[Row]| noise_text(n, frames, rows, None);
        let text = noise_text(&noise(0.001), 1, &rows);
        assert!(text.starts_with("Reference noise: unknown"), "{text}");
        assert!(text.contains("has 1 frame"), "{text}");
        let text = noise_text(&noise(0.001), 2, &rows);
        assert!(
            text.contains("mean relative standard error 0.0100, RMS standard error 0.00100."),
            "{text}"
        );
        assert!(
            text.contains("It is 1.0% of the smallest RMSE measured (0.100)"),
            "{text}"
        );
        assert!(!text.contains("WARNING"), "{text}");
        let text = noise_text(&noise(0.05), 2, &rows);
        assert!(text.contains("WARNING"), "{text}");
        assert!(text.contains("its RMS standard error is 50%"), "{text}");
        assert!(
            text.contains("about 25% of that configuration's MSE"),
            "{text}"
        );
        // No positive RMSE: nothing to compare with.
        assert_eq!(noise_text(&noise(0.05), 2, &[]).lines().count(), 1);
        // Several references: each is named.
        let text = super::noise_text(&noise(0.001), 2, &rows, Some("max_bounces=2"));
        assert!(
            text.starts_with("Reference noise (max_bounces=2): mean"),
            "{text}"
        );
    }

    #[test]
    fn equal_time_text_tabulates_and_summarises_each_comparison() {
        let baseline = ("box_estimator".to_owned(), "rm".to_owned());
        let comparisons = [
            Comparison {
                series: "box_estimator=reds".into(),
                baseline: "box_estimator=rm".into(),
                points: vec![(1.0, 1.0, 0.25, 0.25), (10.0, 0.5, 0.125, 0.25)],
                geo_mean: Some(0.25),
                seed_geo_means: Vec::new(),
                extrapolated: None,
            },
            Comparison {
                series: "box_estimator=mcds".into(),
                baseline: "box_estimator=rm".into(),
                points: Vec::new(),
                geo_mean: None,
                seed_geo_means: Vec::new(),
                extrapolated: None,
            },
        ];
        let text = equal_time_text(&comparisons, Some(&baseline), 1);
        assert!(!text.contains("per seed"), "{text}");
        assert!(
            text.starts_with("## Equal-time RMSE ratio against box_estimator=rm\n"),
            "{text}"
        );
        assert!(text.contains("| series "), "{text}");
        assert!(
            text.contains(
                "box_estimator=reds vs box_estimator=rm: geometric mean RMSE ratio 0.250 \
                 over 2 time(s)"
            ),
            "{text}"
        );
        assert!(
            text.contains("box_estimator=mcds vs box_estimator=rm: no common GPU time range"),
            "{text}"
        );
        let table_rows = text
            .lines()
            .filter(|l| l.starts_with("| box_estimator="))
            .count();
        assert_eq!(table_rows, 2, "{text}");
        let none = equal_time_text(&[], Some(&baseline), 1);
        assert!(none.contains("No other series to compare."), "{none}");
        assert!(!none.contains('|'), "{none}");

        // With seeds: the spread of the per-seed ratios, and what it means.
        let mut with_seeds = comparisons;
        with_seeds[0].seed_geo_means = vec![Some(0.3), Some(0.2), Some(0.25)];
        with_seeds[1].seed_geo_means = vec![Some(0.3), None, Some(0.25)];
        let text = equal_time_text(&with_seeds, Some(&baseline), 3);
        assert!(
            text.contains("ratio 0.250 (per seed 0.200–0.300 over 3 seeds) over 2 time(s)"),
            "{text}"
        );
        assert!(text.contains("seed-mean series"), "{text}");
        assert!(text.contains("a spread that holds 1"), "{text}");
        assert!(
            text.contains("mcds vs box_estimator=rm: no common"),
            "{text}"
        );
    }

    #[test]
    fn header_text_describes_the_scene_device_references_and_protocol() {
        let opts = StudyOptions {
            vary: vec![
                "volume=baseline".into(),
                "spp=1,4".into(),
                "max_bounces=1,2".into(),
            ],
            reference_frames: 3,
            seeds: 3,
            warmup: 5,
            ..grid_options("header")
        };
        let study = Study::new(&opts).unwrap();
        let reference = |device: &str, cached: bool| Reference {
            image: nimbus::output::ImageRgb::new(8, 6),
            noise: ReferenceNoise {
                rms_std_error: 0.0,
                mean_rel_std_error: 0.0,
            },
            device: device.to_owned(),
            cached,
        };
        let fresh = [reference("gpu", false), reference("gpu", false)];
        let text = study.header_text("gpu", &fresh);
        assert!(text.starts_with("# Accuracy versus GPU time\n"), "{text}");
        assert!(
            text.contains(&format!("- scene: `{}`", opts.scene.display())),
            "{text}"
        );
        assert!(text.contains("- device: gpu\n"), "{text}");
        assert!(text.contains("- resolution: 8x6\n"), "{text}");
        assert!(
            text.contains("- varied: `volume=baseline`, `spp=1,4`, `max_bounces=1,2`\n"),
            "{text}"
        );
        for k in [1, 2] {
            assert!(
                text.contains(&format!(
                    "- reference: 3 frame(s) x 1 spp, max_bounces = {k}, box_estimator"
                )),
                "{text}"
            );
        }
        assert_eq!(text.matches("rendered now and cached as `").count(), 2);
        assert!(text.contains("reference of its own max_bounces"), "{text}");
        assert!(text.contains("- seeds: 3 seeds, derived"), "{text}");
        assert!(text.contains("rmse_min / rmse_max"), "{text}");
        assert!(
            text.contains("at least 4·Q for Volumetric ReSTIR"),
            "{text}"
        );
        assert!(text.contains("at least --warmup (5)"), "{text}");
        assert!(text.contains("sum over frames (total)"), "{text}");
        let cached = [reference("other gpu", true), reference("gpu", true)];
        let text = study.header_text("gpu", &cached);
        assert!(text.contains("; cached `"), "{text}");
        assert_eq!(text.matches("` (rendered on other gpu)\n").count(), 1);
        remove_scratch(&opts);

        let opts = StudyOptions {
            per_frame: true,
            warmup: 0,
            ..grid_options("header-per-frame")
        };
        let study = Study::new(&opts).unwrap();
        let text = study.header_text("gpu", &[reference("gpu", true)]);
        assert!(!text.contains("- varied"), "{text}");
        assert!(!text.contains("its own max_bounces"), "{text}");
        assert!(text.contains("- seeds: 1 seed per configuration"), "{text}");
        assert!(text.contains("the time of one frame (total)"), "{text}");
        assert!(text.contains("- settle: 0 ms of arithmetic load"), "{text}");
        remove_scratch(&opts);
    }

    #[test]
    fn timing_text_flags_times_of_two_device_states() {
        // The H200's baseline at 960x540 without settling (2026-11-28): per seed, total
        // ms of 2 frames (per frame half of it).
        let spp = |v: &str, runs: &[(f64, f64)]| {
            let mut row = test_row_seeds(&[("volume", "baseline"), ("spp", v)], runs);
            row.spp = v.parse().unwrap();
            row.summary = crate::metrics::summarize(&row.runs).unwrap();
            row
        };
        let steady = [
            spp("1", &[(1.56, 0.1), (1.6, 0.1), (1.58, 0.1)]),
            spp("4", &[(5.0, 0.05), (5.1, 0.05), (5.2, 0.05)]),
            spp("16", &[(19.0, 0.03), (19.5, 0.03), (19.2, 0.03)]),
        ];
        assert_eq!(timing_text(&steady), None);

        let mixed = [
            spp("1", &[(1.56, 0.1), (6.12, 0.1), (7.13, 0.1)]),
            spp("4", &[(27.1, 0.05), (27.0, 0.05), (24.2, 0.05)]),
            spp("16", &[(28.6, 0.03), (25.4, 0.03), (24.3, 0.03)]),
        ];
        let text = timing_text(&mixed).expect("a warning");
        assert!(text.starts_with("WARNING"), "{text}");
        assert!(
            text.contains(
                "- `volume=baseline spp=1`: its seeds took 0.7800 to 3.565 ms a frame (4.6x)"
            ),
            "{text}"
        );
        assert!(
            text.contains("- `volume=baseline spp=16` (12.70 ms a frame) costs 0.94x `volume=baseline spp=4` (13.50 ms): 16 spp against 4"),
            "{text}"
        );
        // 16 spp against 1 spp grew 7.3-fold: no line for that pair.
        assert_eq!(text.matches(" costs ").count(), 1, "{text}");

        // Rows that differ in more than spp are not compared.
        let mut other = spp("16", &[(2.0, 0.03)]);
        other.assignment = vary::assignment(&[("volume", "restir"), ("spp", "16")]);
        assert_eq!(timing_text(&[steady[0].clone(), other]), None);
    }
}
