//! The study plot: RMSE against total GPU time on log–log axes, one polyline per
//! series, decade ticks, and a legend.
//!
//! Drawn with `plotters` into an RGB buffer and saved with `image`. Text uses the
//! DejaVu Sans subset in `crates/nimbus-study/assets/` through plotters' `ab_glyph` feature, so no
//! system font library is needed.

use std::path::Path;

use anyhow::{anyhow, Context as _, Result};
use plotters::prelude::*;
use plotters::style::FontStyle;

/// The font family name the plot registers its font under.
const FONT: &str = "nimbus-sans";
const FONT_BYTES: &[u8] = include_bytes!("../assets/DejaVuSans-subset.ttf");

const SIZE: (u32, u32) = (1100, 720);

/// Series colours: Okabe–Ito, distinguishable with colour-blindness, then a few more.
const PALETTE: [RGBColor; 10] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(0, 0, 0),
    RGBColor(140, 86, 75),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
];

/// One measured configuration on the plot.
#[derive(Clone, Debug, PartialEq)]
pub struct Point {
    pub time_ms: f64,
    pub rmse: f64,
    /// The varied knobs (spp, frames, box_samples) of this point, for its label.
    pub knobs: Vec<(String, String)>,
    /// The smallest and largest RMSE of one seed, drawn as a bar (none for one seed).
    pub rmse_range: Option<(f64, f64)>,
}

/// One polyline: configurations sharing every varied key but the knobs.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    /// The (key, value) pairs the series shares.
    pub key: Vec<(String, String)>,
    /// The keys of the series whose configurations render exactly as this one's
    /// (measured once, as this series).
    pub aliases: Vec<Vec<(String, String)>>,
    pub label: String,
    /// Ascending in time.
    pub points: Vec<Point>,
}

/// The decades 10^k covering [lo, hi] (lo, hi > 0), at least one decade wide.
pub fn decade_range(lo: f64, hi: f64) -> (i32, i32) {
    let a = lo.log10().floor() as i32;
    let b = (hi.log10().ceil() as i32).max(a + 1);
    (a, b)
}

/// A tick label for 10^k: plain decimals for 10^-3 ..= 10^4, else 10 with a
/// superscript exponent.
pub fn decade_label(k: i32) -> String {
    if (-3..=4).contains(&k) {
        let v = 10f64.powi(k);
        if k < 0 {
            format!("{v:.p$}", p = (-k) as usize)
        } else {
            format!("{v:.0}")
        }
    } else {
        const DIGITS: [char; 10] = ['⁰', '¹', '²', '³', '⁴', '⁵', '⁶', '⁷', '⁸', '⁹'];
        let exp: String = k
            .unsigned_abs()
            .to_string()
            .chars()
            .map(|c| DIGITS[c.to_digit(10).unwrap_or(0) as usize])
            .collect();
        format!("10{}{exp}", if k < 0 { "⁻" } else { "" })
    }
}

/// A tick label for m·10^k with a one-digit mantissa m: like [`decade_label`], and
/// `m×10ᵏ` where the decade is written with an exponent.
pub fn tick_label(v: f64) -> String {
    let k = v.log10().floor() as i32;
    let m = (v / 10f64.powi(k)).round() as i32;
    let (m, k) = if m >= 10 { (1, k + 1) } else { (m, k) };
    if m == 1 {
        decade_label(k)
    } else if (-3..=4).contains(&k) {
        format!(
            "{:.p$}",
            f64::from(m) * 10f64.powi(k),
            p = (-k).max(0) as usize
        )
    } else {
        format!("{m}×{}", decade_label(k))
    }
}

/// Labelled ticks for the decades 10^a ..= 10^b: the decades, plus 2·10^k and 5·10^k
/// when the axis spans at most two decades.
pub fn ticks(a: i32, b: i32) -> Vec<f64> {
    let mantissas: &[f64] = if b - a <= 2 { &[1.0, 2.0, 5.0] } else { &[1.0] };
    let mut out: Vec<f64> = (a..b)
        .flat_map(|k| mantissas.iter().map(move |m| m * 10f64.powi(k)))
        .collect();
    out.push(10f64.powi(b));
    out
}

/// Writes the plot of `series` to `path` (PNG). `knobs` are the varied knob keys, named
/// in the x-axis caption; each point is labelled with its knob values.
pub fn write_png(path: &Path, title: &str, knobs: &[&str], series: &[Series]) -> Result<()> {
    plotters::style::register_font(FONT, FontStyle::Normal, FONT_BYTES).map_err(|_| {
        anyhow!("the plot font crates/nimbus-study/assets/DejaVuSans-subset.ttf is invalid")
    })?;
    let mut buffer = vec![255u8; (SIZE.0 * SIZE.1 * 3) as usize];
    draw(&mut buffer, title, knobs, series).map_err(|e| anyhow!("drawing the plot: {e}"))?;
    image::save_buffer_with_format(
        path,
        &buffer,
        SIZE.0,
        SIZE.1,
        image::ExtendedColorType::Rgb8,
        image::ImageFormat::Png,
    )
    .context("encoding the PNG")
}

/// The outline of series `i`'s marker, radius `r` pixels around (0, 0): a circle, a
/// triangle, a square or a diamond.
fn marker(i: usize, r: i32) -> Vec<(i32, i32)> {
    let rf = f64::from(r);
    let polygon = |n: u32, phase: f64, scale: f64| -> Vec<(i32, i32)> {
        (0..n)
            .map(|k| {
                let a = phase + std::f64::consts::TAU * f64::from(k) / f64::from(n);
                (
                    (scale * rf * a.cos()).round() as i32,
                    (scale * rf * a.sin()).round() as i32,
                )
            })
            .collect()
    };
    match i % 4 {
        0 => polygon(16, 0.0, 1.0),
        1 => polygon(3, -std::f64::consts::FRAC_PI_2, 1.3),
        2 => polygon(4, std::f64::consts::FRAC_PI_4, 1.25),
        _ => polygon(4, 0.0, 1.35),
    }
}

fn draw(
    buffer: &mut [u8],
    title: &str,
    knobs: &[&str],
    series: &[Series],
) -> Result<(), Box<dyn std::error::Error>> {
    let root = BitMapBackend::with_buffer(buffer, SIZE).into_drawing_area();
    root.fill(&WHITE)?;

    let finite = |p: &&Point| p.time_ms > 0.0 && p.rmse > 0.0 && p.time_ms.is_finite();
    let points: Vec<&Point> = series
        .iter()
        .flat_map(|s| s.points.iter())
        .filter(finite)
        .collect();
    let bounds = |f: fn(&Point) -> f64| {
        points
            .iter()
            .map(|p| f(p))
            .fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            })
    };
    let (t_lo, t_hi) = if points.is_empty() {
        (1.0, 10.0)
    } else {
        bounds(|p| p.time_ms)
    };
    let (e_lo, e_hi) = if points.is_empty() {
        (1.0, 10.0)
    } else {
        bounds(|p| p.rmse)
    };
    let (tx0, tx1) = decade_range(t_lo, t_hi);
    let (ey0, ey1) = decade_range(e_lo, e_hi);
    let minors = |a: i32, b: i32| {
        (a..b)
            .flat_map(|k| (2..10).map(move |m| f64::from(m) * 10f64.powi(k)))
            .collect::<Vec<f64>>()
    };

    let x_range = (10f64.powi(tx0)..10f64.powi(tx1))
        .log_scale()
        .with_key_points(ticks(tx0, tx1))
        .with_light_points(minors(tx0, tx1));
    let y_range = (10f64.powi(ey0)..10f64.powi(ey1))
        .log_scale()
        .with_key_points(ticks(ey0, ey1))
        .with_light_points(minors(ey0, ey1));

    let mut chart = ChartBuilder::on(&root)
        .caption(title, (FONT, 24))
        .margin(20)
        .x_label_area_size(60)
        .y_label_area_size(90)
        .build_cartesian_2d(x_range, y_range)?;

    let x_desc = match knobs {
        [] => "total GPU time (ms)".to_owned(),
        [knob] => format!("total GPU time (ms) — points labelled by {knob}"),
        _ => format!("total GPU time (ms) — points labelled {}", knobs.join("/")),
    };
    let label_of = |v: &f64| tick_label(*v);
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc("RMSE  (W/(m²·sr))")
        .axis_desc_style((FONT, 20))
        .label_style((FONT, 18))
        .x_label_formatter(&label_of)
        .y_label_formatter(&label_of)
        .bold_line_style(RGBColor(200, 200, 200))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()?;

    for (i, s) in series.iter().enumerate() {
        let color = PALETTE[i % PALETTE.len()];
        let shape = marker(i, 5);
        let xy: Vec<(f64, f64)> = s.points.iter().map(|p| (p.time_ms, p.rmse)).collect();
        let front = super::metrics::pareto_front(&xy);
        let line: Vec<(f64, f64)> = front.iter().map(|&j| xy[j]).collect();
        let legend_shape = shape.clone();
        chart
            .draw_series(LineSeries::new(line.clone(), color.stroke_width(2)))?
            .label(s.label.clone())
            .legend(move |(x, y)| {
                EmptyElement::at((x, y))
                    + PathElement::new(vec![(0, 0), (28, 0)], color.stroke_width(2))
                    + Polygon::new(
                        legend_shape
                            .iter()
                            .map(|&(u, v)| (u + 14, v))
                            .collect::<Vec<_>>(),
                        color.filled(),
                    )
            });
        // The seeds' RMSE range of each point, as a bar with end ticks.
        let ranges: Vec<(f64, f64, f64)> = s
            .points
            .iter()
            .filter(|p| finite(p))
            .filter_map(|p| {
                let (lo, hi) = p.rmse_range?;
                (lo > 0.0 && hi > lo && hi.is_finite()).then_some((p.time_ms, lo, hi))
            })
            .collect();
        chart.draw_series(
            ranges.iter().map(|&(t, lo, hi)| {
                PathElement::new(vec![(t, lo), (t, hi)], color.stroke_width(1))
            }),
        )?;
        chart.draw_series(ranges.iter().flat_map(|&(t, lo, hi)| {
            [lo, hi].map(|y| {
                EmptyElement::at((t, y))
                    + PathElement::new(vec![(-4, 0), (4, 0)], color.stroke_width(1))
            })
        }))?;
        // Points on the front are filled, the ones it beats hollow.
        chart.draw_series(
            line.iter()
                .map(|&c| EmptyElement::at(c) + Polygon::new(shape.clone(), color.filled())),
        )?;
        let mut outline = shape.clone();
        outline.push(shape[0]);
        chart.draw_series(
            (0..xy.len())
                .filter(|j| !front.contains(j) && finite(&&s.points[*j]))
                .map(|j| {
                    EmptyElement::at(xy[j])
                        + PathElement::new(outline.clone(), color.stroke_width(2))
                }),
        )?;
        // Label the points with their knob values (only the first series' when there
        // are more than two: the others run through the same values in the same order).
        if i > 0 && series.len() > 2 {
            continue;
        }
        let label_style = TextStyle::from((FONT, 14).into_font()).color(&color);
        chart.draw_series(s.points.iter().filter(|p| finite(p)).map(|p| {
            let text = match p.knobs.as_slice() {
                [(k, v)] => format!("{k}={v}"),
                many => many
                    .iter()
                    .map(|(_, v)| v.as_str())
                    .collect::<Vec<_>>()
                    .join("/"),
            };
            EmptyElement::at((p.time_ms, p.rmse)) + Text::new(text, (7, -18), label_style.clone())
        }))?;
    }

    // A guide of slope -1/2, the RMSE of plain Monte Carlo against time, through the
    // first series' fastest point; cut where it would leave the y axis.
    if let Some(p0) = series
        .first()
        .and_then(|s| s.points.iter().find(|p| finite(p)))
    {
        let y_min = 10f64.powi(ey0);
        let t_end = t_hi.min(p0.time_ms * (p0.rmse / y_min).powi(2));
        if t_end > p0.time_ms {
            let guide: Vec<(f64, f64)> = (0..=32)
                .map(|i| {
                    let t = p0.time_ms * (t_end / p0.time_ms).powf(f64::from(i) / 32.0);
                    (t, p0.rmse * (p0.time_ms / t).sqrt())
                })
                .collect();
            let grey = RGBColor(110, 110, 110);
            chart
                .draw_series(DashedLineSeries::new(guide, 8, 6, grey.stroke_width(1)))?
                .label("slope −1/2 (Monte Carlo)")
                .legend(move |(x, y)| {
                    EmptyElement::at((x, y))
                        + PathElement::new(vec![(0, 0), (8, 0)], grey.stroke_width(1))
                        + PathElement::new(vec![(14, 0), (22, 0)], grey.stroke_width(1))
                });
        }
    }

    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font((FONT, 18))
        .background_style(WHITE.mix(0.9))
        .border_style(RGBColor(120, 120, 120))
        .margin(12)
        .draw()?;
    root.present()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decades_cover_the_data() {
        assert_eq!(decade_range(0.3, 80.0), (-1, 2));
        assert_eq!(decade_range(1.0, 10.0), (0, 1));
        assert_eq!(decade_range(2.0, 3.0), (0, 1));
        assert_eq!(decade_range(10.0, 10.0), (1, 2));
    }

    #[test]
    fn decade_labels() {
        assert_eq!(decade_label(-3), "0.001");
        assert_eq!(decade_label(0), "1");
        assert_eq!(decade_label(4), "10000");
        assert_eq!(decade_label(-12), "10⁻¹²");
        assert_eq!(decade_label(5), "10⁵");
        assert_eq!(tick_label(0.002), "0.002");
        assert_eq!(tick_label(50.0), "50");
        assert_eq!(tick_label(100.0), "100");
        assert_eq!(tick_label(2e-5), "2×10⁻⁵");
        assert_eq!(ticks(-3, -2), [0.001, 0.002, 0.005, 0.01]);
        assert_eq!(ticks(0, 3), [1.0, 10.0, 100.0, 1000.0]);
    }

    #[test]
    fn writes_a_png_of_the_right_size() {
        let dir = std::env::temp_dir().join(format!("nimbus-plot-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("plot.png");
        let point = |t: f64, e: f64| Point {
            time_ms: t,
            rmse: e,
            knobs: vec![("spp".to_owned(), format!("{t}"))],
            rmse_range: Some((0.8 * e, 1.25 * e)),
        };
        let series = [Series {
            key: Vec::new(),
            aliases: Vec::new(),
            label: "all".to_owned(),
            points: vec![point(1.0, 0.1), point(4.0, 0.05), point(16.0, 0.025)],
        }];
        write_png(&path, "test", &["spp"], &series).unwrap();
        let img = image::open(&path).unwrap();
        assert_eq!((img.width(), img.height()), SIZE);
        std::fs::remove_dir_all(dir).unwrap();
    }
}
