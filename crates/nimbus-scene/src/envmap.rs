//! Environment maps: loading, the direction ↔ (u, v) mapping of `docs/scene-format.md`,
//! lookup, and importance-sampling tables (CPU side; the GPU mirrors [`EnvMap::lookup`]
//! and consumes [`EnvSampler::to_gpu_tables`]).
//!
//! # Mapping
//! Equirectangular, +Y up. A direction d maps to
//! u = 0.5 + atan2(d.x, −d.z) / (2π), v = acos(d.y) / π, so −Z is u = 0.5, +X is
//! u = 0.75, +Y is v = 0 (the top row) and −Y is v = 1. Texel (x, y) covers
//! u ∈ [x/W, (x+1)/W), v ∈ [y/H, (y+1)/H); with θ = πv and φ = 2π(u − 0.5) the
//! texel's solid angle is (2π/W)·(cos(πy/H) − cos(π(y+1)/H)).
//!
//! # Sampling
//! [`EnvSampler`] is pbrt's `PiecewiseConstant2D` over the unit (u, v) square with
//! weight w(x, y) = luminance(texel) · sin θ_y, θ_y = π(y + 0.5)/H the row-centre
//! polar angle and luminance = 0.2126 R + 0.7152 G + 0.0722 B. The solid-angle pdf
//! is p(u, v) / (2π² sin θ) with θ = πv of the direction itself, so it integrates
//! to exactly 1 over the sphere. Every texel with non-zero radiance has non-zero
//! weight (texels are non-negative, sin θ_y > 0), so L / pdf is an unbiased
//! estimator of ∫ L dω.
//!
//! # Rotation
//! An environment light's `rotation_deg` θ turns the map about world +Y, right-handed:
//! positive θ turns +X towards −Z. World direction d sees the map at
//! d_map = R_y(−θ) d = (d.x cos θ − d.z sin θ, d.y, d.x sin θ + d.z cos θ), i.e.
//! u = frac(0.5 + atan2(d.x, −d.z) / (2π) + θ / 360°) and v unchanged: what the
//! unrotated map shows at u₀ appears at u₀ − θ/360° ([`EnvRotation`]). Sampling draws
//! d_map from the map's tables and returns R_y(θ) d_map; a rotation preserves solid
//! angle, so the pdf is the map's pdf of d_map.

use std::f64::consts::PI;
use std::path::Path;

use anyhow::{anyhow, bail, Context, Result};
use glam::{DVec3, Vec3};

/// Largest accepted map width in texels.
pub const MAX_ENVMAP_WIDTH: u32 = 16384;
/// Largest accepted map height in texels.
pub const MAX_ENVMAP_HEIGHT: u32 = 8192;

/// Rec. 709 luminance of a linear RGB colour.
pub fn luminance(c: [f32; 3]) -> f64 {
    0.2126 * c[0] as f64 + 0.7152 * c[1] as f64 + 0.0722 * c[2] as f64
}

/// Maps a direction to equirectangular (u, v): u = 0.5 + atan2(d.x, −d.z)/(2π),
/// v = acos(d.y)/π.
///
/// `d` need not be normalized. Returns u ∈ [0, 1) (u = 1, reached by d = +Z with
/// d.x = +0, wraps to 0) and v ∈ [0, 1]. At the poles atan2(0, 0) gives u ∈ {0, 0.5},
/// harmless since every u is the same point there. A zero or non-finite `d` maps to
/// (0.5, 0), i.e. +Y, so the result is never NaN.
pub fn direction_to_uv(d: DVec3) -> (f64, f64) {
    let len = d.length();
    if !(len > 0.0 && len.is_finite()) {
        return (0.5, 0.0);
    }
    // Clamp cos θ so rounding in the normalization cannot push acos out of its domain.
    let cos_theta = (d.y / len).clamp(-1.0, 1.0);
    let v = cos_theta.acos() / PI;
    let mut u = 0.5 + d.x.atan2(-d.z) / (2.0 * PI);
    if u >= 1.0 {
        u -= 1.0;
    }
    (u.max(0.0), v)
}

/// The inverse of [`direction_to_uv`]: the unit direction with φ = 2π(u − 0.5),
/// θ = πv, d = (sin θ sin φ, cos θ, −sin θ cos φ).
///
/// u wraps (any real u is accepted; u and u + 1 give the same direction); v is
/// clamped to [0, 1], and v = 0 / v = 1 return exactly +Y / −Y.
pub fn uv_to_direction(u: f64, v: f64) -> DVec3 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    if v == 0.0 {
        return DVec3::Y;
    }
    if v == 1.0 {
        return DVec3::NEG_Y;
    }
    let theta = PI * v;
    let phi = 2.0 * PI * (u - 0.5);
    let (sin_theta, cos_theta) = theta.sin_cos();
    let (sin_phi, cos_phi) = phi.sin_cos();
    DVec3::new(sin_theta * sin_phi, cos_theta, -sin_theta * cos_phi)
}

/// A turn of an environment map about world +Y by θ (see the module docs): cos θ and
/// sin θ, exact at multiples of 90°.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnvRotation {
    pub cos: f64,
    pub sin: f64,
}

impl EnvRotation {
    /// No turn.
    pub const IDENTITY: EnvRotation = EnvRotation { cos: 1.0, sin: 0.0 };

    /// The turn by `degrees` (any finite value; a non-finite one gives no turn). The
    /// angle is reduced to [0°, 360°) and then to within 45° of a multiple of 90°
    /// exactly (f64 `rem_euclid` and a Sterbenz subtraction), so 90° is exactly (0, 1)
    /// and 180° exactly (−1, 0).
    pub fn from_degrees(degrees: f64) -> EnvRotation {
        if !degrees.is_finite() {
            return Self::IDENTITY;
        }
        let r = degrees.rem_euclid(360.0);
        let quadrant = (r / 90.0).round();
        // |rest| <= 45; exact: r and 90 q are within a factor of 2 of each other (or q = 0).
        let rest = r - 90.0 * quadrant;
        let (s, c) = rest.to_radians().sin_cos();
        let (sin, cos) = match quadrant as i64 {
            1 => (c, -s),
            2 => (-s, -c),
            3 => (-c, s),
            _ => (s, c), // 0 and 4 (r just below 360 rounds up to a full turn)
        };
        // + 0.0 turns a −0 into +0, so that 0° and 180° give exactly (±1, +0).
        EnvRotation {
            cos: cos + 0.0,
            sin: sin + 0.0,
        }
    }

    /// Whether the turn is exactly none.
    pub fn is_identity(self) -> bool {
        self == Self::IDENTITY
    }

    /// The map's direction of world direction `d`: R_y(−θ) d. Identity returns `d`
    /// unchanged (bit for bit).
    pub fn world_to_map(self, d: DVec3) -> DVec3 {
        if self.is_identity() {
            return d;
        }
        let (c, s) = (self.cos, self.sin);
        DVec3::new(c * d.x - s * d.z, d.y, s * d.x + c * d.z)
    }

    /// The world direction of the map's direction `d`: R_y(θ) d (the inverse of
    /// [`world_to_map`](Self::world_to_map)).
    pub fn map_to_world(self, d: DVec3) -> DVec3 {
        if self.is_identity() {
            return d;
        }
        let (c, s) = (self.cos, self.sin);
        DVec3::new(c * d.x + s * d.z, d.y, c * d.z - s * d.x)
    }
}

/// The turn of the environment map among `lights` (the environment light with a
/// `file`; a scene has at most one that renders), identity without one: a constant
/// environment looks the same turned.
pub fn environment_rotation(lights: &[crate::Light]) -> EnvRotation {
    lights
        .iter()
        .find_map(|l| match l {
            crate::Light::Environment {
                file: Some(_),
                rotation_deg,
                ..
            } => Some(EnvRotation::from_degrees(f64::from(*rotation_deg))),
            _ => None,
        })
        .unwrap_or(EnvRotation::IDENTITY)
}

/// The texel (x, y) containing (u, v) on a `width`×`height` map: x = ⌊uW⌋ wrapped
/// into [0, W), y = ⌊vH⌋ clamped to [0, H − 1] (so v = 1 is the bottom row).
fn texel_of_uv(u: f64, v: f64, width: u32, height: u32) -> (u32, u32) {
    let x = ((u * width as f64).floor() as i64).rem_euclid(width as i64) as u32;
    let y = ((v * height as f64).floor() as i64).clamp(0, height as i64 - 1) as u32;
    (x, y)
}

/// sin θ of a direction (need not be normalized): √(x² + z²) / |d|; 0 for a zero or
/// non-finite `d`.
fn sin_theta_of(d: DVec3) -> f64 {
    let len = d.length();
    if !(len > 0.0 && len.is_finite()) {
        return 0.0;
    }
    (d.x * d.x + d.z * d.z).sqrt() / len
}

/// An equirectangular radiance map (W/(m²·sr), linear RGB, already multiplied by the
/// light's colour).
#[derive(Clone, Debug, PartialEq)]
pub struct EnvMap {
    pub width: u32,
    pub height: u32,
    /// Row-major, `width·height` texels; row 0 is the top (v = 0, +Y).
    pub texels: Vec<[f32; 3]>,
}

impl EnvMap {
    /// A constant map: one texel of `radiance`.
    pub fn constant(radiance: Vec3) -> EnvMap {
        EnvMap {
            width: 1,
            height: 1,
            texels: vec![radiance.to_array()],
        }
    }

    /// The width and height of an environment map from its EXR header, checked like
    /// [`EnvMap::load_exr`] checks them (R, G, B channels; 1×1 ..=
    /// [`MAX_ENVMAP_WIDTH`]×[`MAX_ENVMAP_HEIGHT`]), without reading any pixels.
    pub fn read_size(path: &Path) -> Result<[u32; 2]> {
        let name = path.display();
        let meta = exr::meta::MetaData::read_from_file(path, false)
            .with_context(|| format!("{name}: cannot read EXR header"))?;
        let header = meta
            .headers
            .first()
            .ok_or_else(|| anyhow!("{name}: EXR file has no layers"))?;
        let has = |c: &str| header.channels.list.iter().any(|ch| ch.name == *c);
        if !(has("R") && has("G") && has("B")) {
            let found: Vec<String> = header
                .channels
                .list
                .iter()
                .map(|ch| ch.name.to_string())
                .collect();
            bail!(
                "{name}: the first EXR layer has no R, G, B channels (found {})",
                found.join(", ")
            );
        }
        let (w, h) = (header.layer_size.width(), header.layer_size.height());
        if w == 0 || h == 0 || w > MAX_ENVMAP_WIDTH as usize || h > MAX_ENVMAP_HEIGHT as usize {
            bail!(
                "{name}: environment map is {w}×{h}; must be between 1×1 and \
                 {MAX_ENVMAP_WIDTH}×{MAX_ENVMAP_HEIGHT}"
            );
        }

        Ok([w as u32, h as u32])
    }

    /// Reads the R, G, B channels of the first layer of an equirectangular EXR (any
    /// sample type: half, float or uint, converted to f32; alpha ignored) and
    /// multiplies every texel by `scale` (for a scene light, `radiance · scale`).
    ///
    /// Errors, each naming the file: unreadable file; no R, G and B channels in the
    /// first layer; size outside 1×1 ..= [`MAX_ENVMAP_WIDTH`]×[`MAX_ENVMAP_HEIGHT`];
    /// a negative or non-finite `scale`; a NaN, infinite or negative texel (the message
    /// names pixel (x, y), the channel and the value), or one that overflows f32 once
    /// scaled.
    pub fn load_exr(path: &Path, scale: Vec3) -> Result<EnvMap> {
        let name = path.display();
        if !scale.to_array().iter().all(|s| s.is_finite() && *s >= 0.0) {
            bail!("{name}: environment scale {scale} must be finite and >= 0");
        }

        // Check the channels and size from the header before decoding any pixels.
        let [w, h] = EnvMap::read_size(path)?;
        let (w, h) = (w as usize, h as usize);

        let image = exr::prelude::read_first_rgba_layer_from_file(
            path,
            |size, _| {
                (
                    size.width(),
                    vec![[0.0f32; 3]; size.width() * size.height()],
                )
            },
            |(w, px): &mut (usize, Vec<[f32; 3]>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                px[pos.y() * *w + pos.x()] = [r, g, b];
            },
        )
        .with_context(|| format!("{name}: cannot read EXR pixels"))?;
        let (read_w, mut texels) = image.layer_data.channel_data.pixels;
        if read_w != w || texels.len() != w * h {
            bail!("{name}: EXR layer size changed between header and pixels");
        }

        // Validate each texel, then apply the scale.
        let s = scale.to_array();
        for (i, t) in texels.iter_mut().enumerate() {
            let (x, y) = (i % w, i / w);
            for (c, channel) in ["R", "G", "B"].iter().enumerate() {
                let value = t[c];
                if !value.is_finite() || value < 0.0 {
                    bail!(
                        "{name}: pixel ({x}, {y}) channel {channel} is {value}; \
                         radiance must be finite and >= 0"
                    );
                }
                let scaled = value * s[c];
                if f64::from(scaled) > crate::MAX_RADIOMETRIC {
                    bail!(
                        "{name}: pixel ({x}, {y}) channel {channel} = {value} times the \
                         light's radiance x scale {} is {:e} W/(m²·sr), above the largest \
                         radiometric input {:e}",
                        s[c],
                        f64::from(value) * f64::from(s[c]),
                        crate::MAX_RADIOMETRIC
                    );
                }
                t[c] = scaled;
            }
        }
        Ok(EnvMap {
            width: w as u32,
            height: h as u32,
            texels,
        })
    }

    /// The texel (x, y) a direction falls in (see [`direction_to_uv`]).
    pub fn texel_of(&self, d: DVec3) -> (u32, u32) {
        let (u, v) = direction_to_uv(d);
        texel_of_uv(u, v, self.width, self.height)
    }

    /// Radiance seen along direction `d` (the direction light travels *from*, i.e. the
    /// escaping ray's direction).
    ///
    /// Filter: nearest texel, i.e. a box over the texel containing (u, v): x = ⌊uW⌋
    /// wrapped, y = ⌊vH⌋ clamped to the last row. No interpolation, so the lookup is
    /// exactly the piecewise-constant function the sampler's weights are built from.
    /// The shader must use the same rule.
    pub fn lookup(&self, d: DVec3) -> [f32; 3] {
        let (x, y) = self.texel_of(d);
        self.texels[(y * self.width + x) as usize]
    }

    /// The background a camera ray sees along `d`: the map interpolated bilinearly
    /// between texel centres (wrapping in u, clamped at the poles' rows), so a smooth sky
    /// shows no texel rows. Only the camera's own escaping rays see it: light that
    /// reaches the scene keeps [`EnvMap::lookup`], the piecewise-constant function the
    /// sampler's pdf follows (no estimator mixes the two). The shader's
    /// `env_lookup_bilinear` follows this rule.
    pub fn lookup_bilinear(&self, d: DVec3) -> [f32; 3] {
        let (u, v) = direction_to_uv(d);
        let (w, h) = (i64::from(self.width), i64::from(self.height));
        let x = u * w as f64 - 0.5;
        let y = (v * h as f64 - 0.5).clamp(0.0, (h - 1) as f64);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let at = |x: i64, y: i64| {
            let t = self.texels[(y.min(h - 1) * w + x.rem_euclid(w)) as usize];
            t.map(f64::from)
        };
        let mut out = [0f32; 3];
        for (c, o) in out.iter_mut().enumerate() {
            let top = at(x0, y0)[c] * (1.0 - fx) + at(x0 + 1, y0)[c] * fx;
            let bottom = at(x0, y0 + 1)[c] * (1.0 - fx) + at(x0 + 1, y0 + 1)[c] * fx;
            *o = (top * (1.0 - fy) + bottom * fy) as f32;
        }
        out
    }
}

/// Importance-sampling tables for an [`EnvMap`] (pbrt's `PiecewiseConstant2D`), all in
/// f64 on the CPU.
///
/// Weights w(x, y) = luminance · sin θ_y (see the module docs). Rows are picked from
/// the marginal CDF with `u[1]`, then the column within the row from that row's
/// conditional CDF with `u[0]`, each continuous (linear inside a texel).
///
/// An all-black map (every weight 0) is sampled as if every texel had luminance 1
/// (weights sin θ_y, close to uniform on the sphere): `sample` and `pdf` stay
/// consistent and finite, [`is_black`](Self::is_black) is true and
/// [`integral`](Self::integral) is 0, so a renderer can skip the light instead.
/// A row whose weights are all 0 gets a uniform conditional CDF; the marginal never
/// picks it.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvSampler {
    width: u32,
    height: u32,
    /// w(x, y) row-major, the function being sampled (fallback weights when black).
    func: Vec<f64>,
    /// ∫ func over the unit (u, v) square = Σ func / (W·H); > 0.
    func_integral: f64,
    /// H + 1 entries, 0 .. 1.
    marginal_cdf: Vec<f64>,
    /// H rows of W + 1 entries, each 0 .. 1.
    conditional_cdf: Vec<f64>,
    /// Σ luminance·sin θ_y / (W·H) of the map itself (0 for a black map).
    integral: f64,
}

/// The largest f64 below 1, where a sample in [0, 1) is clamped.
const ONE_MINUS_EPSILON: f64 = 1.0 - f64::EPSILON / 2.0;

/// Fills `cdf` (n + 1 entries) from non-negative `func` (n entries): the running
/// sum divided by the total, cdf[0] = 0, cdf[n] = 1 exactly; uniform when the total
/// is 0. Returns the sum.
fn build_cdf(func: &[f64], cdf: &mut [f64]) -> f64 {
    let n = func.len();
    cdf[0] = 0.0;
    for i in 0..n {
        cdf[i + 1] = cdf[i] + func[i];
    }
    let total = cdf[n];
    if total > 0.0 {
        for c in cdf[1..n].iter_mut() {
            *c /= total;
        }
    } else {
        for (i, c) in cdf.iter_mut().enumerate() {
            *c = i as f64 / n as f64;
        }
    }
    cdf[n] = 1.0;
    total
}

/// Samples the piecewise-linear inverse of `cdf`: the segment o with
/// cdf[o] <= u < cdf[o + 1] (never a zero-width one) and the fraction du ∈ [0, 1)
/// of u inside it.
fn sample_cdf(cdf: &[f64], u: f64) -> (usize, f64) {
    let u = u.clamp(0.0, ONE_MINUS_EPSILON);
    let n = cdf.len() - 1;
    // Find the last segment start <= u; cdf[0] = 0 <= u so the index is >= 0.
    let o = cdf[..n].partition_point(|&c| c <= u) - 1;
    let width = cdf[o + 1] - cdf[o];
    let du = if width > 0.0 {
        ((u - cdf[o]) / width).min(ONE_MINUS_EPSILON)
    } else {
        0.0
    };
    (o, du)
}

impl EnvSampler {
    /// Builds the tables for `map`.
    ///
    /// # Panics
    /// If `map.texels.len() != width·height` (a hand-built, malformed map).
    pub fn new(map: &EnvMap) -> EnvSampler {
        let (w, h) = (map.width as usize, map.height as usize);
        assert_eq!(
            map.texels.len(),
            w * h,
            "EnvMap texel count != width·height"
        );

        // Weight each texel by luminance times the row-centre sin θ.
        let sin_theta_row = |y: usize| (PI * (y as f64 + 0.5) / h as f64).sin();
        let mut func = Vec::with_capacity(w * h);
        for y in 0..h {
            let s = sin_theta_row(y);
            for x in 0..w {
                func.push(luminance(map.texels[y * w + x]) * s);
            }
        }
        let integral = func.iter().sum::<f64>() / (w * h) as f64;

        // Fall back to unit luminance for an all-black map.
        if integral <= 0.0 {
            for y in 0..h {
                let s = sin_theta_row(y);
                func[y * w..(y + 1) * w].fill(s);
            }
        }

        // Build one conditional CDF per row and the marginal CDF over row sums.
        let mut conditional_cdf = vec![0.0; h * (w + 1)];
        let mut row_sums = vec![0.0; h];
        for y in 0..h {
            row_sums[y] = build_cdf(
                &func[y * w..(y + 1) * w],
                &mut conditional_cdf[y * (w + 1)..(y + 1) * (w + 1)],
            );
        }
        let mut marginal_cdf = vec![0.0; h + 1];
        let total = build_cdf(&row_sums, &mut marginal_cdf);

        EnvSampler {
            width: map.width,
            height: map.height,
            func,
            func_integral: total / (w * h) as f64,
            marginal_cdf,
            conditional_cdf,
            integral,
        }
    }

    pub fn width(&self) -> u32 {
        self.width
    }

    pub fn height(&self) -> u32 {
        self.height
    }

    /// ∫∫ luminance · sin θ_y du dv over the unit square (= Σ w / (W·H)); 2π² times
    /// this approximates ∫ luminance dω (midpoint sin θ per row). 0 for a black map.
    pub fn integral(&self) -> f64 {
        self.integral
    }

    /// True when every texel is black and the uniform-luminance fallback is in use.
    pub fn is_black(&self) -> bool {
        self.integral <= 0.0
    }

    /// The marginal CDF over rows: `height + 1` entries from 0 to 1.
    pub fn marginal_cdf(&self) -> &[f64] {
        &self.marginal_cdf
    }

    /// Row `y`'s conditional CDF over columns: `width + 1` entries from 0 to 1.
    pub fn conditional_cdf(&self, y: u32) -> &[f64] {
        let n = self.width as usize + 1;
        &self.conditional_cdf[y as usize * n..(y as usize + 1) * n]
    }

    /// Density over the unit (u, v) square of texel (x, y).
    fn pdf_uv_texel(&self, x: u32, y: u32) -> f64 {
        self.func[(y * self.width + x) as usize] / self.func_integral
    }

    /// Samples a direction from `u` ∈ [0, 1)² (`u[1]` picks the row, `u[0]` the
    /// column). Returns the unit direction and its solid-angle pdf
    /// p(u, v) / (2π² sin θ); the pdf is 0 only at an exact pole (sin θ = 0), and the
    /// sample must then be discarded.
    pub fn sample(&self, u: [f64; 2]) -> (DVec3, f64) {
        // Sample the row from the marginal, then the column from its conditional.
        let (y, dv) = sample_cdf(&self.marginal_cdf, u[1]);
        let (x, du) = sample_cdf(self.conditional_cdf(y as u32), u[0]);
        let uu = (x as f64 + du) / self.width as f64;
        let vv = (y as f64 + dv) / self.height as f64;
        let dir = uv_to_direction(uu, vv);

        // Convert the (u, v) density to solid angle: dω = 2π² sin θ du dv.
        let sin_theta = sin_theta_of(dir);
        if sin_theta <= 0.0 {
            return (dir, 0.0);
        }
        let pdf = self.pdf_uv_texel(x as u32, y as u32) / (2.0 * PI * PI * sin_theta);
        (dir, pdf)
    }

    /// The solid-angle pdf of [`sample`](Self::sample) returning `dir` (need not be
    /// normalized): p(u, v) / (2π² sin θ), 0 where sin θ = 0 or the texel's weight is 0.
    pub fn pdf(&self, dir: DVec3) -> f64 {
        let sin_theta = sin_theta_of(dir);
        if sin_theta <= 0.0 {
            return 0.0;
        }
        let (u, v) = direction_to_uv(dir);
        let (x, y) = texel_of_uv(u, v, self.width, self.height);
        self.pdf_uv_texel(x, y) / (2.0 * PI * PI * sin_theta)
    }

    /// The `u` for which [`sample`](Self::sample) returns `dir` (up to rounding), for
    /// directions in texels of non-zero weight; elsewhere some `u` mapping to the
    /// texel's edge.
    pub fn invert(&self, dir: DVec3) -> [f64; 2] {
        let (u, v) = direction_to_uv(dir);
        let (x, y) = texel_of_uv(u, v, self.width, self.height);
        // Invert the row choice, then the column choice, linearly within the texel.
        let m = &self.marginal_cdf;
        let fy = (v * self.height as f64 - y as f64).clamp(0.0, 1.0);
        let u1 = m[y as usize] + fy * (m[y as usize + 1] - m[y as usize]);
        let c = self.conditional_cdf(y);
        let fx = (u * self.width as f64 - x as f64).clamp(0.0, 1.0);
        let u0 = c[x as usize] + fx * (c[x as usize + 1] - c[x as usize]);
        [u0, u1]
    }

    /// The tables for a shader, as f32:
    /// - `marginal_cdf`: `height + 1` entries; entry y is P(row < y); `m[0] = 0`, `m[H] = 1`.
    /// - `conditional_cdf`: `height` rows of `width + 1` entries, row y at offset
    ///   y·(width + 1); entry x of row y is P(column < x | row y); each row starts at 0
    ///   and ends at 1.
    ///
    /// A shader samples exactly like [`sample`](Self::sample): binary-search the last
    /// entry <= u in [0, H) (resp. [0, W)) and interpolate linearly. The (u, v) pdf of
    /// texel (x, y) is `W·H·(m[y+1] − m[y])·(c[y][x+1] − c[y][x])`. Rounding to f32 is
    /// monotone, so every table stays non-decreasing, but differences of f32 CDF
    /// entries near 1 have only ~6e-8 absolute precision: a texel with probability
    /// below that can collapse to zero width and never be sampled on the GPU.
    pub fn to_gpu_tables(&self) -> (Vec<f32>, Vec<f32>) {
        let marginal = self.marginal_cdf.iter().map(|&c| c as f32).collect();
        let conditional = self.conditional_cdf.iter().map(|&c| c as f32).collect();
        (marginal, conditional)
    }
}
