//! How a configuration is measured: error metrics against the reference ([`measure`],
//! [`mean_metrics`]), the reference's own noise ([`ReferenceNoise`]), GPU time from the
//! timestamp scopes, what a row reports over its seeds ([`summarize`]), and the
//! equal-time comparison of series (log–log interpolation, Pareto fronts, RMSE ratios,
//! geometric means; per seed in [`equal_time_over_seeds`]).

use anyhow::{anyhow, ensure, Result};
use nimbus_gpu::ScopeResult;

use super::plot;
use super::vary::Assignment;
use nimbus::output::ImageRgb;
/// ε in the relative MSE (a − r)² / (r² + ε), as in the golden-image tests.
pub(super) const REL_MSE_EPSILON: f64 = 1e-2;
/// y(x) on the polyline through `points` (x ascending, all coordinates > 0), linear in
/// (log x, log y). `None` outside [x_first, x_last], for an empty polyline, or for a
/// non-positive x. Where several points share x = x_query, the first one's y.
fn interpolate_loglog(points: &[(f64, f64)], x: f64) -> Option<f64> {
    let (first, last) = (points.first()?, points.last()?);
    if x.is_nan() || x <= 0.0 || x < first.0 || x > last.0 {
        return None;
    }
    if let Some(p) = points.iter().find(|p| p.0 == x) {
        return Some(p.1);
    }
    let i = points.windows(2).position(|w| w[0].0 <= x && x <= w[1].0)?;
    let (a, b) = (points[i], points[i + 1]);
    // Interpolate log y linearly in log x; x_a < x < x_b here, so the span is positive.
    let t = (x.ln() - a.0.ln()) / (b.0.ln() - a.0.ln());
    Some((a.1.ln() + t * (b.1.ln() - a.1.ln())).exp())
}

/// The indices of the (time, RMSE) points that no other point beats in both: sorted
/// by time, each one with a lower RMSE than every faster point (of equal times, the
/// lower RMSE). This is the best a series buys for a given time, and the curve the
/// equal-time comparison interpolates; with one knob varied it is usually every
/// point.
pub(super) fn pareto_front(points: &[(f64, f64)]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..points.len())
        .filter(|&i| points[i].0 > 0.0 && points[i].1 > 0.0)
        .collect();
    order.sort_by(|&a, &b| {
        points[a]
            .0
            .total_cmp(&points[b].0)
            .then(points[a].1.total_cmp(&points[b].1))
    });
    let mut front = Vec::new();
    let mut best = f64::INFINITY;
    for i in order {
        if points[i].1 < best {
            best = points[i].1;
            front.push(i);
        }
    }
    front
}

/// The RMSE ratio of `other` to `baseline` at equal GPU time: at every measured time of
/// `baseline` that lies inside `other`'s time range, `other`'s RMSE interpolated there
/// ([`interpolate_loglog`]) over the baseline's RMSE. Both are (time, RMSE) with time
/// ascending. Returns (time, ratio) pairs.
fn equal_time_ratios(baseline: &[(f64, f64)], other: &[(f64, f64)]) -> Vec<(f64, f64)> {
    baseline
        .iter()
        .filter_map(|&(t, rmse)| {
            let at = interpolate_loglog(other, t)?;
            (rmse > 0.0).then(|| (t, at / rmse))
        })
        .collect()
}

/// How far outside its measured times (as a factor of time) a baseline is extrapolated.
pub(super) const MAX_EXTRAPOLATION: f64 = 4.0;

/// The RMSE at time `t` of a baseline measured at `points` (time ascending) but not at
/// times as short or long as `t`: from its nearest measured point as RMSE ∝ t^-1/2, the
/// law of an estimator whose work and samples grow together (more samples per pixel of
/// independent paths: MSE ∝ 1/samples). `None` inside the measured range, beyond
/// [`MAX_EXTRAPOLATION`] times it, or for an empty curve.
fn extrapolate(points: &[(f64, f64)], t: f64) -> Option<f64> {
    let (first, last) = (points.first()?, points.last()?);
    let near = if t > last.0 {
        last
    } else if t < first.0 {
        first
    } else {
        return None;
    };
    let factor = if t > near.0 { t / near.0 } else { near.0 / t };
    (t > 0.0 && factor <= MAX_EXTRAPOLATION).then(|| near.1 * (near.0 / t).sqrt())
}

/// The log–log slope of the last two points of `points` (RMSE against time: −1/2 for an
/// estimator whose MSE falls as 1/time).
fn last_slope(points: &[(f64, f64)]) -> Option<f64> {
    let [a, b] = points.get(points.len().checked_sub(2)?..)? else {
        return None;
    };
    (a.0 > 0.0 && b.0 > a.0 && a.1 > 0.0 && b.1 > 0.0)
        .then(|| (b.1.ln() - a.1.ln()) / (b.0.ln() - a.0.ln()))
}

/// exp(mean ln v), `None` for an empty slice or a non-positive value.
fn geometric_mean(values: &[f64]) -> Option<f64> {
    if values.is_empty() || values.iter().any(|v| v.is_nan() || *v <= 0.0) {
        return None;
    }
    Some((values.iter().map(|v| v.ln()).sum::<f64>() / values.len() as f64).exp())
}

/// The median (mean of the middle two for an even count); `None` when empty.
fn median(values: &[f64]) -> Option<f64> {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    match n {
        0 => None,
        _ if n % 2 == 1 => Some(v[n / 2]),
        _ => Some(0.5 * (v[n / 2 - 1] + v[n / 2])),
    }
}

/// How an image differs from the reference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct ErrorMetrics {
    pub(super) rmse: f64,
    pub(super) rel_mse: f64,
    pub(super) mean_rel_diff: f64,
}

/// The mean of `all`'s MSE (RMSE = sqrt of the mean MSE), relative MSE and mean
/// relative difference; `None` when empty.
pub(super) fn mean_of(all: &[ErrorMetrics]) -> Option<ErrorMetrics> {
    if all.is_empty() {
        return None;
    }
    let n = all.len() as f64;
    let sum = |f: fn(&ErrorMetrics) -> f64| all.iter().map(f).sum::<f64>() / n;
    Some(ErrorMetrics {
        rmse: sum(|m| m.rmse * m.rmse).sqrt(),
        rel_mse: sum(|m| m.rel_mse),
        mean_rel_diff: sum(|m| m.mean_rel_diff),
    })
}

/// The mean over `frames` of each frame's MSE, relative MSE and mean relative
/// difference (RMSE = sqrt of the mean MSE).
pub(super) fn mean_metrics(frames: &[ImageRgb], reference: &ImageRgb) -> Result<ErrorMetrics> {
    ensure!(!frames.is_empty(), "no frames to measure");
    let each: Vec<ErrorMetrics> = frames
        .iter()
        .map(|frame| measure(frame, reference))
        .collect::<Result<_>>()?;
    mean_of(&each).ok_or_else(|| anyhow!("no frames to measure"))
}

/// One seed's render of a configuration, measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct SeedRun {
    pub(super) seed: u64,
    pub(super) gpu_ms_per_frame: f64,
    pub(super) gpu_ms_total: f64,
    pub(super) metrics: ErrorMetrics,
}

/// What a row reports over its seeds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct SeedSummary {
    /// Median over the seeds.
    pub(super) gpu_ms_per_frame: f64,
    /// Median over the seeds.
    pub(super) gpu_ms_total: f64,
    /// Mean over the seeds of the MSE (RMSE = its sqrt), relative MSE and mean
    /// relative difference.
    pub(super) metrics: ErrorMetrics,
    /// The smallest and largest RMSE of one seed: the spread.
    pub(super) rmse_min: f64,
    pub(super) rmse_max: f64,
}

/// The summary of one configuration's seeds (see [`SeedSummary`]).
pub(super) fn summarize(runs: &[SeedRun]) -> Result<SeedSummary> {
    let all: Vec<ErrorMetrics> = runs.iter().map(|r| r.metrics).collect();
    let metrics = mean_of(&all).ok_or_else(|| anyhow!("no seeds to summarize"))?;
    let median_of = |f: fn(&SeedRun) -> f64| {
        median(&runs.iter().map(f).collect::<Vec<f64>>()).unwrap_or(f64::NAN)
    };
    let rmse = all.iter().map(|m| m.rmse);
    Ok(SeedSummary {
        gpu_ms_per_frame: median_of(|r| r.gpu_ms_per_frame),
        gpu_ms_total: median_of(|r| r.gpu_ms_total),
        metrics,
        rmse_min: rmse.clone().fold(f64::INFINITY, f64::min),
        rmse_max: rmse.fold(f64::NEG_INFINITY, f64::max),
    })
}

/// RMSE, relative MSE and mean relative difference of the means (see the
/// [`study`](super) docs) of `image` against `reference`, which must have the same size.
pub(super) fn measure(image: &ImageRgb, reference: &ImageRgb) -> Result<ErrorMetrics> {
    ensure!(
        (image.width, image.height) == (reference.width, reference.height),
        "cannot compare a {}x{} image with a {}x{} reference",
        image.width,
        image.height,
        reference.width,
        reference.height
    );
    ensure!(!image.data.is_empty(), "cannot compare empty images");
    let (mut sq, mut rel) = (0.0f64, 0.0f64);
    for (a, r) in image.data.iter().zip(&reference.data) {
        for c in 0..3 {
            let (a, r) = (f64::from(a[c]), f64::from(r[c]));
            sq += (a - r) * (a - r);
            rel += (a - r) * (a - r) / (r * r + REL_MSE_EPSILON);
        }
    }
    let n = (3 * image.data.len()) as f64;
    let (mean_a, mean_r) = (image.mean(), reference.mean());
    let diffs: Vec<f64> = (0..3)
        .filter(|&c| mean_r[c] > 0.0)
        .map(|c| (mean_a[c] - mean_r[c]) / mean_r[c])
        .collect();
    let mean_rel_diff = if diffs.is_empty() {
        0.0
    } else {
        diffs.iter().sum::<f64>() / diffs.len() as f64
    };
    Ok(ErrorMetrics {
        rmse: (sq / n).sqrt(),
        rel_mse: rel / n,
        mean_rel_diff,
    })
}

/// The reference's own noise, from its per-pixel standard error σ.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct ReferenceNoise {
    /// √(mean σ²) over pixels and channels: its share of every measured RMSE
    /// (measured² ≈ true² + this²).
    pub(super) rms_std_error: f64,
    /// mean σ / √(r² + ε), ε = [`REL_MSE_EPSILON`].
    pub(super) mean_rel_std_error: f64,
}

impl ReferenceNoise {
    pub(super) fn of(image: &ImageRgb, std_error: &ImageRgb) -> Self {
        let (mut sq, mut rel) = (0.0f64, 0.0f64);
        for (r, s) in image.data.iter().zip(&std_error.data) {
            for c in 0..3 {
                let (r, s) = (f64::from(r[c]), f64::from(s[c]));
                sq += s * s;
                rel += s / (r * r + REL_MSE_EPSILON).sqrt();
            }
        }
        let n = (3 * image.data.len()).max(1) as f64;
        Self {
            rms_std_error: (sq / n).sqrt(),
            mean_rel_std_error: rel / n,
        }
    }
}

/// A series compared with its baseline at equal GPU time.
pub(super) struct Comparison {
    pub(super) series: String,
    pub(super) baseline: String,
    /// (time ms, baseline RMSE, series RMSE at that time, ratio).
    pub(super) points: Vec<(f64, f64, f64, f64)>,
    pub(super) geo_mean: Option<f64>,
    /// The geometric-mean ratio of each seed's series against the baseline series of
    /// the same seed (empty when compared without seeds).
    pub(super) seed_geo_means: Vec<Option<f64>>,
    /// Some of `points` lie outside the baseline's measured times, the baseline's RMSE
    /// there extrapolated from its nearest point as RMSE ∝ t^-1/2 ([`extrapolate`]);
    /// with the log–log slope the baseline's own last two points measured (`None` for a
    /// baseline of one time).
    pub(super) extrapolated: Option<Option<f64>>,
}

impl Comparison {
    /// The smallest and largest per-seed geometric-mean ratio, when every seed has
    /// one.
    pub(super) fn seed_spread(&self) -> Option<(f64, f64)> {
        let all: Option<Vec<f64>> = self.seed_geo_means.iter().copied().collect();
        let all = all.filter(|a| !a.is_empty())?;
        Some((
            all.iter().copied().fold(f64::INFINITY, f64::min),
            all.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        ))
    }
}

/// [`equal_time`] of the seed-mean series `mean`, with the per-seed ratios: each
/// seed's series (`per_seed[s]`, the same series measured with seed s) against the
/// baseline series of the same seed, their geometric means in
/// [`Comparison::seed_geo_means`].
pub(super) fn equal_time_over_seeds(
    baseline: &(String, String),
    mean: &[plot::Series],
    per_seed: &[Vec<plot::Series>],
) -> Vec<Comparison> {
    let per_seed: Vec<Vec<Comparison>> = per_seed
        .iter()
        .map(|series| equal_time(baseline, series))
        .collect();
    let mut out = equal_time(baseline, mean);
    for c in &mut out {
        c.seed_geo_means = per_seed
            .iter()
            .map(|seed| {
                seed.iter()
                    .find(|s| s.series == c.series && s.baseline == c.baseline)
                    .and_then(|s| s.geo_mean)
            })
            .collect();
    }
    out
}

/// Compares every series that does not have the baseline's value with the baseline
/// series that shares all its other series keys, along both series' Pareto fronts
/// ([`pareto_front`]).
pub(super) fn equal_time(baseline: &(String, String), series: &[plot::Series]) -> Vec<Comparison> {
    let (bkey, bvalue) = baseline;
    let mut out = Vec::new();
    for s in series {
        let is_baseline = |key: &Assignment| key.iter().any(|(k, v)| k == bkey && v == bvalue);
        if is_baseline(&s.key) || s.aliases.iter().any(is_baseline) {
            continue;
        }
        let want: Assignment = s
            .key
            .iter()
            .map(|(k, v)| {
                if k == bkey {
                    (k.clone(), bvalue.clone())
                } else {
                    (k.clone(), v.clone())
                }
            })
            .collect();
        // The baseline series itself, else the one it renders as (a configuration the
        // integrator cannot tell from another is measured, and listed, once).
        let Some(base) = series
            .iter()
            .find(|b| b.key == want)
            .or_else(|| series.iter().find(|b| b.aliases.contains(&want)))
        else {
            continue;
        };
        let curve = |s: &plot::Series| -> Vec<(f64, f64)> {
            let all: Vec<(f64, f64)> = s.points.iter().map(|p| (p.time_ms, p.rmse)).collect();
            pareto_front(&all).into_iter().map(|i| all[i]).collect()
        };
        let (base_curve, curve) = (curve(base), curve(s));
        let ratios = equal_time_ratios(&base_curve, &curve);
        let mut extrapolated = None;
        let points: Vec<(f64, f64, f64, f64)> = if ratios.is_empty() {
            // The series' times fall between the baseline's (e.g. a series of one
            // time): the baseline interpolated at the series' own times instead; where
            // none does (a series slower or faster than every baseline point), the
            // baseline extrapolated there, and the comparison says so.
            let at = |interpolate: bool| -> Vec<(f64, f64, f64, f64)> {
                curve
                    .iter()
                    .filter_map(|&(t, rmse)| {
                        let base_rmse = if interpolate {
                            interpolate_loglog(&base_curve, t)?
                        } else {
                            extrapolate(&base_curve, t)?
                        };
                        (base_rmse > 0.0).then(|| (t, base_rmse, rmse, rmse / base_rmse))
                    })
                    .collect()
            };
            let inside = at(true);
            if inside.is_empty() {
                let outside = at(false);
                if !outside.is_empty() {
                    extrapolated = Some(last_slope(&base_curve));
                }
                outside
            } else {
                inside
            }
        } else {
            ratios
                .iter()
                .map(|&(t, ratio)| {
                    let base_rmse = base_curve
                        .iter()
                        .find(|p| p.0 == t)
                        .map_or(f64::NAN, |p| p.1);
                    (t, base_rmse, base_rmse * ratio, ratio)
                })
                .collect()
        };
        let values: Vec<f64> = points.iter().map(|p| p.3).collect();
        out.push(Comparison {
            series: s.label.clone(),
            baseline: base.label.clone(),
            points,
            geo_mean: geometric_mean(&values),
            seed_geo_means: Vec::new(),
            extrapolated,
        });
    }
    out
}

/// (median, sum) over frames of the root "frame" scope's GPU milliseconds.
pub(super) fn frame_gpu_ms(frames: &[Vec<ScopeResult>]) -> Result<(f64, f64)> {
    ensure!(
        !frames.is_empty(),
        "the device reported no timestamps; a study needs GPU times"
    );
    let ms: Vec<f64> = frames
        .iter()
        .map(|scopes| {
            scopes
                .iter()
                .find(|s| s.label == "frame")
                .map(|s| s.duration_ms())
                .ok_or_else(|| anyhow!("a frame has no \"frame\" timestamp scope"))
        })
        .collect::<Result<_>>()?;
    let median = median(&ms).unwrap_or(0.0);
    Ok((median, ms.iter().sum()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vary::{assignment, series_label};

    #[test]
    fn loglog_interpolation_is_exact_on_power_laws() {
        // RMSE = 3 t^-1/2 is a straight line in log-log.
        let f = |t: f64| 3.0 / t.sqrt();
        let points: Vec<(f64, f64)> = [1.0, 4.0, 100.0].iter().map(|&t| (t, f(t))).collect();
        for t in [1.0, 2.0, 3.5, 4.0, 20.0, 100.0] {
            let y = interpolate_loglog(&points, t).unwrap();
            assert!((y - f(t)).abs() < 1e-12 * f(t), "t {t}: {y} vs {}", f(t));
        }
        assert_eq!(interpolate_loglog(&points, 0.5), None);
        assert_eq!(interpolate_loglog(&points, 101.0), None);
        assert_eq!(interpolate_loglog(&points, 0.0), None);
        assert_eq!(interpolate_loglog(&[], 1.0), None);
        assert_eq!(interpolate_loglog(&[(2.0, 5.0)], 2.0), Some(5.0));
        // Geometric midpoint in x gives the geometric mean in y.
        let y = interpolate_loglog(&[(1.0, 1.0), (100.0, 4.0)], 10.0).unwrap();
        assert!((y - 2.0).abs() < 1e-12);
        // Equal times do not divide by zero.
        assert_eq!(
            interpolate_loglog(&[(1.0, 2.0), (1.0, 3.0), (2.0, 1.0)], 1.0),
            Some(2.0)
        );
    }

    #[test]
    fn equal_time_ratio_uses_baseline_times_inside_the_other_range() {
        // The baseline needs 4x the time for the same error as the other series:
        // baseline RMSE = 1/sqrt(t), other = 1/sqrt(4t) = half at equal time.
        let baseline: Vec<(f64, f64)> = [1.0, 4.0, 16.0, 64.0]
            .iter()
            .map(|&t: &f64| (t, 1.0 / t.sqrt()))
            .collect();
        let other: Vec<(f64, f64)> = [2.0, 8.0, 32.0]
            .iter()
            .map(|&t: &f64| (t, 0.5 / t.sqrt()))
            .collect();
        let ratios = equal_time_ratios(&baseline, &other);
        let times: Vec<f64> = ratios.iter().map(|r| r.0).collect();
        assert_eq!(times, [4.0, 16.0]);
        for (_, r) in &ratios {
            assert!((r - 0.5).abs() < 1e-12, "{r}");
        }
        let values: Vec<f64> = ratios.iter().map(|r| r.1).collect();
        assert!((geometric_mean(&values).unwrap() - 0.5).abs() < 1e-12);
        assert!((geometric_mean(&[2.0, 8.0]).unwrap() - 4.0).abs() < 1e-12);
        assert_eq!(geometric_mean(&[]), None);
        assert_eq!(geometric_mean(&[1.0, 0.0]), None);
        assert!(equal_time_ratios(&baseline, &[(100.0, 1.0), (200.0, 0.5)]).is_empty());
    }

    #[test]
    fn pareto_front_drops_dominated_points() {
        let points = [
            (4.0, 1.0),
            (1.0, 3.0),
            (2.0, 3.5),
            (3.0, 2.0),
            (3.0, 1.5),
            (8.0, 1.2),
        ];
        assert_eq!(pareto_front(&points), [1, 4, 0]);
        assert_eq!(pareto_front(&[]), Vec::<usize>::new());
        assert_eq!(pareto_front(&[(1.0, 0.0), (2.0, 1.0)]), [1]);
    }

    #[test]
    fn equal_time_pairs_each_series_with_its_baseline() {
        let point = |t: f64, rmse: f64| plot::Point {
            time_ms: t,
            rmse,
            knobs: Vec::new(),
            rmse_range: None,
        };
        let series = |key: &[(&str, &str)], scale: f64| plot::Series {
            key: assignment(key),
            aliases: Vec::new(),
            label: series_label(&assignment(key)),
            points: vec![point(1.0, scale), point(10.0, scale * 0.5)],
        };
        let all = [
            series(&[("box_estimator", "rm"), ("max_bounces", "1")], 1.0),
            series(&[("box_estimator", "reds"), ("max_bounces", "1")], 0.25),
            series(&[("box_estimator", "rm"), ("max_bounces", "2")], 2.0),
            series(&[("box_estimator", "reds"), ("max_bounces", "2")], 3.0),
        ];
        let c = equal_time(&("box_estimator".to_owned(), "rm".to_owned()), &all);
        assert_eq!(c.len(), 2);
        assert_eq!(c[0].baseline, "box_estimator=rm max_bounces=1");
        assert!((c[0].geo_mean.unwrap() - 0.25).abs() < 1e-12);
        assert_eq!(c[1].baseline, "box_estimator=rm max_bounces=2");
        assert!((c[1].geo_mean.unwrap() - 1.5).abs() < 1e-12);
        assert_eq!(c[1].points.len(), 2);
    }

    /// A series whose times fall between the baseline's (ReSTIR: one time per frame) is
    /// compared with the baseline interpolated in log-log at the series' own time.
    #[test]
    fn equal_time_interpolates_the_baseline_inside_its_range() {
        let point = |t: f64, rmse: f64| plot::Point {
            time_ms: t,
            rmse,
            knobs: Vec::new(),
            rmse_range: None,
        };
        let base = plot::Series {
            key: assignment(&[("volume", "baseline")]),
            aliases: Vec::new(),
            label: "volume=baseline".into(),
            // RMSE ∝ t^(-1/2): 1 at 10 ms, 0.5 at 40 ms.
            points: vec![point(10.0, 1.0), point(40.0, 0.5)],
        };
        let restir = plot::Series {
            key: assignment(&[("volume", "restir")]),
            aliases: Vec::new(),
            label: "volume=restir".into(),
            points: vec![point(20.0, 0.25)],
        };
        let c = equal_time(&("volume".into(), "baseline".into()), &[base, restir]);
        assert_eq!(c.len(), 1);
        let (t, b, r, ratio) = c[0].points[0];
        assert_eq!((t, r), (20.0, 0.25));
        assert!((b - 0.5f64.sqrt()).abs() < 1e-12, "{b}");
        assert!((ratio - 0.25 / 0.5f64.sqrt()).abs() < 1e-12);
        assert_eq!(c[0].extrapolated, None);
    }

    /// A series slower than every baseline point (ReSTIR's frame beyond the baseline's
    /// largest spp) is compared with the baseline extrapolated as RMSE ∝ t^-1/2 from its
    /// slowest point, up to [`MAX_EXTRAPOLATION`] times it, and the comparison says so
    /// with the baseline's own measured slope; farther it is not compared.
    #[test]
    fn equal_time_extrapolates_the_baseline_a_little_and_says_so() {
        let point = |t: f64, rmse: f64| plot::Point {
            time_ms: t,
            rmse,
            knobs: Vec::new(),
            rmse_range: None,
        };
        let series = |volume: &str, points: Vec<plot::Point>| plot::Series {
            key: assignment(&[("volume", volume)]),
            aliases: Vec::new(),
            label: format!("volume={volume}"),
            points,
        };
        // The baseline's slope over its last two points: 0.5 -> 0.3 over 10 -> 40 ms.
        let base = || series("baseline", vec![point(10.0, 0.5), point(40.0, 0.3)]);
        let key = ("volume".to_owned(), "baseline".to_owned());
        let c = equal_time(&key, &[base(), series("restir", vec![point(90.0, 0.1)])]);
        let (t, b, r, ratio) = c[0].points[0];
        assert_eq!((t, r), (90.0, 0.1));
        assert!((b - 0.3 * (40.0f64 / 90.0).sqrt()).abs() < 1e-12, "{b}");
        assert!((ratio - 0.1 / b).abs() < 1e-12);
        let slope = c[0].extrapolated.expect("extrapolated").expect("a slope");
        assert!(
            (slope - (0.6f64.ln() / 4.0f64.ln())).abs() < 1e-12,
            "{slope}"
        );
        // Faster than the fastest point too.
        let c = equal_time(&key, &[base(), series("restir", vec![point(5.0, 0.1)])]);
        assert!((c[0].points[0].1 - 0.5 * 2.0f64.sqrt()).abs() < 1e-12);
        // Beyond 4x: no comparison.
        let c = equal_time(&key, &[base(), series("restir", vec![point(161.0, 0.1)])]);
        assert!(c[0].points.is_empty() && c[0].geo_mean.is_none());
        assert_eq!(c[0].extrapolated, None);
        let text = crate::report::equal_time_text(
            &equal_time(&key, &[base(), series("restir", vec![point(90.0, 0.1)])]),
            Some(&key),
            1,
        );
        assert!(
            text.contains("EXTRAPOLATED") && text.contains("-0.368"),
            "{text}"
        );
    }

    #[test]
    fn a_row_is_the_mean_mse_and_median_time_over_its_seeds() {
        let run = |seed: u64, ms: f64, rmse: f64, diff: f64| SeedRun {
            seed,
            gpu_ms_per_frame: ms / 4.0,
            gpu_ms_total: ms,
            metrics: ErrorMetrics {
                rmse,
                rel_mse: 2.0 * rmse,
                mean_rel_diff: diff,
            },
        };
        let runs = [
            run(0, 10.0, 3.0, 0.1),
            run(1, 30.0, 1.0, -0.2),
            run(2, 12.0, 2.0, 0.4),
        ];
        let s = summarize(&runs).unwrap();
        // MSEs 9, 1, 4: mean 14/3; not the mean RMSE (2).
        assert!((s.metrics.rmse - (14.0f64 / 3.0).sqrt()).abs() < 1e-12);
        assert!((s.metrics.rel_mse - 4.0).abs() < 1e-12);
        assert!((s.metrics.mean_rel_diff - 0.1).abs() < 1e-12);
        assert_eq!((s.gpu_ms_total, s.gpu_ms_per_frame), (12.0, 3.0));
        assert_eq!((s.rmse_min, s.rmse_max), (1.0, 3.0));
        let one = summarize(&runs[..1]).unwrap();
        assert_eq!(
            (one.metrics.rmse, one.rmse_min, one.rmse_max),
            (3.0, 3.0, 3.0)
        );
        assert!(summarize(&[]).is_err());
    }

    /// Each seed's series is compared with the baseline series of the same seed; the
    /// spread is the smallest and largest of their geometric-mean ratios.
    #[test]
    fn equal_time_over_seeds_compares_each_seed_with_its_own_baseline() {
        let series = |value: &str, points: &[(f64, f64)]| plot::Series {
            key: assignment(&[("box_estimator", value)]),
            label: format!("box_estimator={value}"),
            aliases: Vec::new(),
            points: points
                .iter()
                .map(|&(t, rmse)| plot::Point {
                    time_ms: t,
                    rmse,
                    knobs: Vec::new(),
                    rmse_range: None,
                })
                .collect(),
        };
        let seeds = |rm: f64, reds: f64| {
            vec![
                series("rm", &[(1.0, rm), (4.0, rm / 2.0)]),
                series("reds", &[(1.0, reds), (4.0, reds / 2.0)]),
            ]
        };
        // Seed 0: reds is half of rm; seed 1: equal; seed 2: a quarter.
        let per_seed = [seeds(1.0, 0.5), seeds(2.0, 2.0), seeds(4.0, 1.0)];
        let mean = seeds(1.5, 0.75);
        let baseline = ("box_estimator".to_owned(), "rm".to_owned());
        let c = equal_time_over_seeds(&baseline, &mean, &per_seed);
        assert_eq!(c.len(), 1);
        assert!((c[0].geo_mean.unwrap() - 0.5).abs() < 1e-12);
        let got: Vec<f64> = c[0].seed_geo_means.iter().map(|g| g.unwrap()).collect();
        for (g, want) in got.iter().zip([0.5, 1.0, 0.25]) {
            assert!((g - want).abs() < 1e-12, "{got:?}");
        }
        let (lo, hi) = c[0].seed_spread().unwrap();
        assert!((lo - 0.25).abs() < 1e-12 && (hi - 1.0).abs() < 1e-12);

        // A seed without a common time range: no spread.
        let mut apart = per_seed.clone();
        apart[1][1] = series("reds", &[(100.0, 1.0)]);
        let c = equal_time_over_seeds(&baseline, &mean, &apart);
        assert_eq!(c[0].seed_geo_means[1], None);
        assert_eq!(c[0].seed_spread(), None);
        // Without seeds: no per-seed ratios.
        let c = equal_time_over_seeds(&baseline, &mean, &[]);
        assert!(c[0].seed_geo_means.is_empty() && c[0].seed_spread().is_none());
    }

    #[test]
    fn metrics_of_known_images() {
        let reference = ImageRgb {
            width: 2,
            height: 1,
            data: vec![[1.0, 2.0, 0.0], [3.0, 2.0, 0.0]],
        };
        let image = ImageRgb {
            width: 2,
            height: 1,
            data: vec![[2.0, 2.0, 0.0], [3.0, 4.0, 0.0]],
        };
        let m = measure(&image, &reference).unwrap();
        assert!((m.rmse - (5.0f64 / 6.0).sqrt()).abs() < 1e-12);
        let rel = (1.0 / (1.0 + REL_MSE_EPSILON) + 4.0 / (4.0 + REL_MSE_EPSILON)) / 6.0;
        assert!((m.rel_mse - rel).abs() < 1e-12);
        // Means: red 2.5 vs 2 (+25%), green 3 vs 2 (+50%), blue 0 vs 0 (skipped).
        assert!((m.mean_rel_diff - 0.375).abs() < 1e-12);
        assert!(measure(&ImageRgb::new(1, 2), &reference).is_err());
        assert_eq!(measure(&reference, &reference).unwrap().rmse, 0.0);
    }

    #[test]
    fn reference_noise_and_medians() {
        let image = ImageRgb {
            width: 1,
            height: 1,
            data: vec![[0.0, 0.0, 0.0]],
        };
        let se = ImageRgb {
            width: 1,
            height: 1,
            data: vec![[0.1, 0.1, 0.1]],
        };
        let n = ReferenceNoise::of(&image, &se);
        assert!((n.rms_std_error - 0.1).abs() < 1e-7);
        assert!((n.mean_rel_std_error - 1.0).abs() < 1e-6);
        assert_eq!(median(&[3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(&[4.0, 1.0, 2.0, 3.0]), Some(2.5));
        assert_eq!(median(&[]), None);
    }

    #[test]
    fn mean_metrics_averages_each_frames_error() {
        let pixel = |v: f32| ImageRgb {
            width: 1,
            height: 1,
            data: vec![[v, v, v]],
        };
        let reference = pixel(1.0);
        // Frames 3 and 0 have MSEs 4 and 1: RMSE sqrt(2.5). Not the error of the mean
        // image (1.5, RMSE 0.5), nor the mean of the frames' RMSEs (1.5).
        let m = mean_metrics(&[pixel(3.0), pixel(0.0)], &reference).unwrap();
        assert!((m.rmse - 2.5f64.sqrt()).abs() < 1e-12, "{}", m.rmse);
        assert!((m.rel_mse - 2.5 / (1.0 + REL_MSE_EPSILON)).abs() < 1e-12);
        // Mean relative differences +2 and -1.
        assert!((m.mean_rel_diff - 0.5).abs() < 1e-12);
        let message = format!("{:#}", mean_metrics(&[], &reference).unwrap_err());
        assert!(message.contains("no frames"), "{message}");
        assert!(mean_metrics(&[ImageRgb::new(2, 1)], &reference).is_err());
    }

    #[test]
    fn frame_gpu_ms_is_the_median_and_sum_of_the_frame_scope() {
        let scope = |label: &str, ms: f64| ScopeResult {
            label: label.to_owned(),
            begin_ns: 1e6,
            end_ns: 1e6 + ms * 1e6,
            children: Vec::new(),
        };
        let frames = vec![
            vec![scope("upload", 9.0), scope("frame", 1.0)],
            vec![scope("frame", 3.0)],
            vec![scope("frame", 2.0)],
        ];
        let (median, total) = frame_gpu_ms(&frames).unwrap();
        assert!((median - 2.0).abs() < 1e-9, "{median}");
        assert!((total - 6.0).abs() < 1e-9, "{total}");
        let message = format!("{:#}", frame_gpu_ms(&[]).unwrap_err());
        assert!(message.contains("no timestamps"), "{message}");
        let message = format!(
            "{:#}",
            frame_gpu_ms(&[vec![scope("frame", 1.0)], vec![scope("upload", 1.0)]]).unwrap_err()
        );
        assert!(
            message.contains("no \"frame\" timestamp scope"),
            "{message}"
        );
    }
}
