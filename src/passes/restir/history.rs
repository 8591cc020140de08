//! How much of the previous frame's reservoirs ReSTIR keeps when the lights change: the
//! lights' half of temporal reuse's confidence weight (the camera rays' half is per pixel,
//! in `shaders/restir/temporal.comp`).
//!
//! The temporal pass scales the previous reservoir's M (and its w_sum, so its contribution
//! weight stays) by the confidence. Any weight fixed before the samples are drawn keeps
//! Talbot MIS unbiased; what a low one removes is variance. With the history's M at Q M
//! and its targets far from this frame's (a sun switched off, turned or brightened), the
//! pixel's own candidates get 1 / (1 + Q) of the weight they deserve and the image shows
//! the old frame fading out over Q frames.
//!
//! A turning environment map (`rotation_deg` keyframes) changes the lights too: its
//! change is the share of its radiance that differs between the two turns,
//! ∫ |L_prev − L_cur| dω / (2 ∫ L dω) ∈ [0, 1] (luminance), exact for the nearest-texel
//! map at up to [`ENV_CHANGE_WIDTH`] × [`ENV_CHANGE_HEIGHT`] texels ([`EnvLuminance`]):
//! 0 for a map that is the same all around (a constant radiance, a sky that varies with
//! height only), 1 once a small sun has moved off its own place. That is the change
//! the history sees when its samples keep their world directions (`env_reuse =
//! "world"`). With `env_reuse = "map"` (the default) they turn with the map, a small
//! sun's samples stay on it, and the pass gives no table: the turn counts like a
//! directional light's, 1 at [`LIGHT_TURN_RADIANS`] (and the frame takes
//! `temporal_limit_moving`, `RestirPass::prepare`).

use glam::Vec3;
use nimbus_scene::{EnvMap, Light};

/// The weighted relative change of the lights at which the history's confidence is 0
/// (linear from 1 at no change).
pub const LIGHT_CHANGE_TOLERANCE: f32 = 1.0;

/// The turn of a light (seen from the medium's centre) that counts as a change of 1.
pub const LIGHT_TURN_RADIANS: f32 = 0.25;

/// Rec. 709 luminance.
fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

/// |a - b| / max(a, b), 0 when both are 0.
fn relative(a: f32, b: f32) -> f32 {
    let m = a.max(b);
    if m > 0.0 {
        ((a - b).abs() / m).min(1.0)
    } else {
        0.0
    }
}

/// The angle between two directions (0 when either is zero).
fn turn(a: Vec3, b: Vec3) -> f32 {
    match (a.try_normalize(), b.try_normalize()) {
        (Some(a), Some(b)) => a.dot(b).clamp(-1.0, 1.0).acos(),
        _ => 0.0,
    }
}

/// A light's irradiance at `centre` (luminance, unoccluded; an environment's `env`).
fn irradiance(light: &Light, centre: Vec3, env: f32) -> f32 {
    match light {
        Light::Directional { irradiance, .. } => luminance(*irradiance),
        Light::Environment { .. } => env,
        Light::Point {
            position,
            intensity,
        } => luminance(*intensity) / (*position - centre).length_squared().max(1e-12),
        Light::Sphere {
            center,
            radius,
            radiance,
        } => {
            let d2 = (*center - centre)
                .length_squared()
                .max(radius * radius)
                .max(1e-12);
            luminance(*radiance) * std::f32::consts::PI * radius * radius / d2
        }
    }
}

/// The smallest turn between two angles in degrees, in radians ([0, π]).
fn turn_deg(a: f32, b: f32) -> f32 {
    let d = (f64::from(b) - f64::from(a)).rem_euclid(360.0);
    d.min(360.0 - d).to_radians() as f32
}

/// The change of one light between two frames, 0 (none) to 1: the relative change of its
/// irradiance at `centre` or its turn as seen from there, whichever is larger; for a
/// turning environment map the share of its radiance that changed (`env_map`'s table,
/// or its turn as a direction's without one).
fn light_change(
    prev: &Light,
    cur: &Light,
    centre: Vec3,
    env: f32,
    env_map: Option<&EnvLuminance>,
) -> f32 {
    let power = relative(irradiance(prev, centre, env), irradiance(cur, centre, env));
    let angle = match (prev, cur) {
        (Light::Directional { direction: a, .. }, Light::Directional { direction: b, .. }) => {
            turn(*a, *b)
        }
        (Light::Point { position: a, .. }, Light::Point { position: b, .. })
        | (Light::Sphere { center: a, .. }, Light::Sphere { center: b, .. }) => {
            turn(*a - centre, *b - centre)
        }
        (
            Light::Environment {
                file: Some(_),
                rotation_deg: a,
                ..
            },
            Light::Environment {
                file: Some(_),
                rotation_deg: b,
                ..
            },
        ) => match env_map {
            Some(map) => return power.max(map.turn_change(*a, *b)),
            None => turn_deg(*a, *b),
        },
        // A constant environment is the same turned.
        _ => 0.0,
    };
    power.max((angle / LIGHT_TURN_RADIANS).min(1.0))
}

/// The lights' confidence in the previous frame's reservoirs, in [0, 1]: 1 minus the
/// lights' changes weighted by their share of the irradiance at `centre` (the larger of
/// the two frames'), over [`LIGHT_CHANGE_TOLERANCE`]. `env` is an environment light's
/// irradiance (luminance), `env_map` the luminance table of its map if it has one. Lists
/// of different lengths share nothing (0).
pub fn light_confidence(
    prev: &[Light],
    cur: &[Light],
    centre: Vec3,
    env: f32,
    env_map: Option<&EnvLuminance>,
) -> f32 {
    if prev.len() != cur.len() {
        return 0.0;
    }
    let mut total = 0.0f32;
    let mut changed = 0.0f32;
    for (a, b) in prev.iter().zip(cur) {
        let share = irradiance(a, centre, env).max(irradiance(b, centre, env));
        if !share.is_finite() {
            return 0.0;
        }
        total += share;
        changed += share * light_change(a, b, centre, env, env_map);
    }
    if total.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return 1.0;
    }
    (1.0 - changed / total / LIGHT_CHANGE_TOLERANCE).clamp(0.0, 1.0)
}

/// Most columns of the [`EnvLuminance`] table (a wider map is averaged down to it).
pub const ENV_CHANGE_WIDTH: usize = 512;
/// Most rows of the [`EnvLuminance`] table.
pub const ENV_CHANGE_HEIGHT: usize = 256;

/// An environment map's luminance for the change a turn makes: per row its solid angle
/// and its columns' radiance (luminance), averaged down to at most
/// [`ENV_CHANGE_WIDTH`] × [`ENV_CHANGE_HEIGHT`] (columns of equal width in u, each the
/// exact mean of the texels it overlaps; rows whole groups of the map's, weighted by solid
/// angle).
#[derive(Clone, Debug)]
pub struct EnvLuminance {
    width: usize,
    /// Per row: its texels' solid angle and their luminance.
    rows: Vec<(f64, Vec<f64>)>,
    /// ∫ L dω over the sphere.
    total: f64,
}

impl EnvLuminance {
    /// The table of `map` (radiance as the renderer sees it).
    pub fn new(map: &EnvMap) -> EnvLuminance {
        Self::from_texels(map.width, map.height, |i| {
            nimbus_scene::luminance(map.texels[i])
        })
    }

    /// The table of a `width` × `height` map whose texel i (row-major from the top) has
    /// luminance `luminance(i)`.
    pub fn from_texels(width: u32, height: u32, luminance: impl Fn(usize) -> f64) -> EnvLuminance {
        let (w, h) = (width as usize, height as usize);
        let width = w.clamp(1, ENV_CHANGE_WIDTH);
        let height = h.clamp(1, ENV_CHANGE_HEIGHT);
        let lum = |x: usize, y: usize| luminance(y * w + x);
        let pi = std::f64::consts::PI;
        let mut rows = Vec::with_capacity(height);
        let mut total = 0.0;
        for j in 0..height {
            // Map rows [y0, y1): whole rows, their polar band's solid angle per column.
            let (y0, y1) = (
                j * h / height,
                ((j + 1) * h / height).max(j * h / height + 1),
            );
            let band = |y: usize| (pi * y as f64 / h as f64).cos();
            let omega = 2.0 * pi * (band(y0) - band(y1.min(h))) / width as f64;
            let mut columns = vec![0.0; width];
            for (i, c) in columns.iter_mut().enumerate() {
                // Map columns overlapping [i, i + 1) / width of u, in texel units.
                let (u0, u1) = (
                    i as f64 * w as f64 / width as f64,
                    (i + 1) as f64 * w as f64 / width as f64,
                );
                let mut sum = 0.0;
                let mut weight = 0.0;
                for y in y0..y1.min(h) {
                    let row_omega = band(y) - band(y + 1);
                    let mut x = u0.floor() as usize;
                    while (x as f64) < u1 && x < w {
                        let overlap = (u1.min(x as f64 + 1.0) - u0.max(x as f64)).max(0.0);
                        sum += lum(x, y) * overlap * row_omega;
                        weight += overlap * row_omega;
                        x += 1;
                    }
                }
                *c = if weight > 0.0 { sum / weight } else { 0.0 };
            }
            total += omega * columns.iter().sum::<f64>();
            rows.push((omega, columns));
        }
        EnvLuminance { width, rows, total }
    }

    /// The share of the map's radiance that differs between its turns by `a` and `b`
    /// degrees: ∫ |L_a − L_b| dω / (2 ∫ L dω), in [0, 1] (0 for a black map). A turn
    /// shifts every row by δ = (b − a)/360 of a turn in u: k whole columns and a fraction
    /// f, and a column x then meets columns x + k and x + k + 1 in the parts 1 − f and f.
    pub fn turn_change(&self, a: f32, b: f32) -> f32 {
        if !(self.total > 0.0 && self.total.is_finite()) {
            return 0.0;
        }
        let shift = ((f64::from(b) - f64::from(a)) / 360.0).rem_euclid(1.0) * self.width as f64;
        let k = shift.floor() as usize % self.width;
        let f = shift - shift.floor();
        let mut diff = 0.0;
        for (omega, l) in &self.rows {
            let n = l.len();
            let row: f64 = (0..n)
                .map(|x| {
                    (1.0 - f) * (l[(x + k) % n] - l[x]).abs()
                        + f * (l[(x + k + 1) % n] - l[x]).abs()
                })
                .sum();
            diff += omega * row;
        }
        (diff / (2.0 * self.total)).clamp(0.0, 1.0) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sun(direction: Vec3, e: f32) -> Light {
        Light::Directional {
            direction: direction.normalize(),
            irradiance: Vec3::splat(e),
            gobo: None,
        }
    }

    fn sky(l: f32) -> Light {
        Light::Environment {
            radiance: Vec3::splat(l),
            file: None,
            scale: Vec3::ONE,
            rotation_deg: 0.0,
        }
    }

    /// A map light turned by `deg` (the file is never read here).
    fn map_sky(deg: f32) -> Light {
        Light::Environment {
            radiance: Vec3::ONE,
            file: Some("sky.exr".into()),
            scale: Vec3::ONE,
            rotation_deg: deg,
        }
    }

    /// A `w` × `h` map of luminance `f(x, y)` (grey texels).
    fn map(w: u32, h: u32, f: impl Fn(u32, u32) -> f32) -> EnvMap {
        EnvMap {
            width: w,
            height: h,
            texels: (0..w * h).map(|i| [f(i % w, i / w); 3]).collect(),
        }
    }

    #[test]
    fn unchanged_lights_keep_the_history() {
        let lights = vec![sun(Vec3::NEG_Y, 3.0), sky(0.05)];
        assert_eq!(
            light_confidence(&lights, &lights, Vec3::ZERO, 0.16, None),
            1.0
        );
        assert_eq!(light_confidence(&[], &[], Vec3::ZERO, 0.0, None), 1.0);
    }

    #[test]
    fn a_sun_tripled_or_switched_off_drops_most_of_it() {
        let a = vec![sun(Vec3::NEG_Y, 1.0), sky(0.05)];
        let b = vec![sun(Vec3::NEG_Y, 3.0), sky(0.05)];
        let off = vec![sun(Vec3::NEG_Y, 0.0), sky(0.05)];
        // What stays is the sky's share of the light (0.16 of 3.16, and 2/3 of the
        // sun's 3 changed).
        let c = light_confidence(&a, &b, Vec3::ZERO, 0.16, None);
        assert!((c - (1.0 - 2.0 / 3.0 * 3.0 / 3.16)).abs() < 1e-5, "{c}");
        let c = light_confidence(&b, &off, Vec3::ZERO, 0.16, None);
        assert!((c - 0.16 / 3.16).abs() < 1e-5, "{c}");
        // Without a sky nothing stays.
        assert_eq!(
            light_confidence(&b[..1], &off[..1], Vec3::ZERO, 0.0, None),
            0.0
        );
    }

    #[test]
    fn slow_changes_keep_most_of_it() {
        let a = vec![sun(Vec3::new(0.0, -1.0, 0.0), 3.0), sky(0.05)];
        // One degree of turn.
        let d = Vec3::new(1f32.to_radians().sin(), -1f32.to_radians().cos(), 0.0);
        let b = vec![sun(d, 3.0), sky(0.05)];
        let c = light_confidence(&a, &b, Vec3::ZERO, 0.16, None);
        assert!(c > 0.85 && c < 1.0, "{c}");
        // A 2 % brighter sun.
        let b = vec![sun(Vec3::NEG_Y, 3.06), sky(0.05)];
        let c = light_confidence(&a, &b, Vec3::ZERO, 0.16, None);
        assert!(c > 0.95 && c < 1.0, "{c}");
    }

    #[test]
    fn a_dim_light_changing_matters_little() {
        let point = |i: f32| Light::Point {
            position: Vec3::new(0.0, 5.0, 0.0),
            intensity: Vec3::splat(i),
        };
        let a = vec![sun(Vec3::NEG_Y, 10.0), point(0.0)];
        let b = vec![sun(Vec3::NEG_Y, 10.0), point(2.5)];
        // The point light adds 0.1 W/m² beside the sun's 10.
        let c = light_confidence(&a, &b, Vec3::ZERO, 0.0, None);
        assert!(c > 0.97 && c < 1.0, "{c}");
    }

    #[test]
    fn degenerate_lights_give_a_confidence_in_range() {
        let a = vec![Light::Point {
            position: Vec3::ZERO,
            intensity: Vec3::splat(1.0),
        }];
        let b = vec![Light::Point {
            position: Vec3::ZERO,
            intensity: Vec3::splat(f32::MAX),
        }];
        let c = light_confidence(&a, &b, Vec3::ZERO, 0.0, None);
        assert!((0.0..=1.0).contains(&c), "{c}");
        assert_eq!(light_confidence(&a, &[], Vec3::ZERO, 0.0, None), 0.0);
    }

    /// A constant environment turning changes nothing; a map turning counts in
    /// proportion to the share of its radiance that moved, weighted by its share of the
    /// light.
    #[test]
    fn a_turning_environment_counts_as_its_changed_share() {
        // A constant sky: its rotation is nothing.
        let mut turned = sky(0.05);
        if let Light::Environment { rotation_deg, .. } = &mut turned {
            *rotation_deg = 90.0;
        }
        assert_eq!(
            light_confidence(&[sky(0.05)], &[turned], Vec3::ZERO, 0.16, None),
            1.0
        );
        // A map that varies with height only is the same turned.
        let gradient = EnvLuminance::new(&map(64, 32, |_, y| 1.0 + y as f32));
        let c = light_confidence(
            &[map_sky(0.0)],
            &[map_sky(33.0)],
            Vec3::ZERO,
            1.0,
            Some(&gradient),
        );
        assert!((c - 1.0).abs() < 1e-6, "{c}");
        // A one-column sun on black: half a column's turn changes half of it, a whole
        // column all of it (and so does any larger turn that does not bring it back).
        let sun = EnvLuminance::new(&map(
            64,
            32,
            |x, y| if x == 10 && y == 8 { 5.0 } else { 0.0 },
        ));
        let column = 360.0 / 64.0;
        let alone = |a: f32, b: f32| {
            light_confidence(&[map_sky(a)], &[map_sky(b)], Vec3::ZERO, 1.0, Some(&sun))
        };
        assert!((alone(0.0, 0.5 * column) - 0.5).abs() < 1e-6);
        assert!((alone(0.0, -0.5 * column) - 0.5).abs() < 1e-6);
        assert_eq!(alone(0.0, column), 0.0);
        assert_eq!(alone(17.0, 17.0 + 3.0 * column), 0.0);
        // A whole turn, or 10° against −350°: the same place.
        assert_eq!(alone(0.0, 360.0), 1.0);
        assert!((alone(10.0, -350.0) - 1.0).abs() < 1e-6);
        // Beside a sun of 3 W/m² the map (1) keeps 3 / 4 of the history after its own
        // complete change.
        let c = light_confidence(
            &[sun_light(3.0), map_sky(0.0)],
            &[sun_light(3.0), map_sky(2.0 * column)],
            Vec3::ZERO,
            1.0,
            Some(&sun),
        );
        assert!((c - 0.75).abs() < 1e-6, "{c}");
        // Without a table a turn counts like a direction's: 1 at LIGHT_TURN_RADIANS.
        let quarter = LIGHT_TURN_RADIANS.to_degrees();
        let c = light_confidence(
            &[map_sky(350.0)],
            &[map_sky(350.0 + 0.5 * quarter)],
            Vec3::ZERO,
            1.0,
            None,
        );
        assert!((c - 0.5).abs() < 1e-4, "{c}");
        let c = light_confidence(&[map_sky(359.0)], &[map_sky(-359.0)], Vec3::ZERO, 1.0, None);
        assert!(
            (c - (1.0 - 2f32.to_radians() / LIGHT_TURN_RADIANS)).abs() < 1e-4,
            "{c}"
        );
    }

    /// The table's change is exact for maps it does not average (fractional shifts meet
    /// two columns) and bounded by [0, 1] for wide ones it does; a black map changes
    /// nothing.
    #[test]
    fn the_environment_change_table_is_exact_and_bounded() {
        // Two columns of 1 and 3 on 4 columns: a quarter turn moves each onto a 0
        // column: |1| + |3| + |1| + |3| over 2 (1 + 3).
        let two = EnvLuminance::new(&map(4, 2, |x, _| [1.0, 0.0, 3.0, 0.0][x as usize]));
        assert!((two.turn_change(0.0, 90.0) - 1.0).abs() < 1e-6);
        // A half turn swaps 1 and 3: |2| twice over 8.
        assert!((two.turn_change(0.0, 180.0) - 0.5).abs() < 1e-6);
        // An eighth of a turn: half of each.
        assert!((two.turn_change(0.0, 45.0) - 0.5).abs() < 1e-6);
        let wide = EnvLuminance::new(&map(2000, 700, |x, y| ((x * 7 + y * 3) % 11) as f32));
        for (a, b) in [(0.0, 0.1), (3.0, 200.0), (-10.0, 10.0)] {
            let c = wide.turn_change(a, b);
            assert!((0.0..=1.0).contains(&c), "{c}");
        }
        assert_eq!(wide.turn_change(5.0, 5.0), 0.0);
        let black = EnvLuminance::new(&map(8, 4, |_, _| 0.0));
        assert_eq!(black.turn_change(0.0, 90.0), 0.0);
    }

    fn sun_light(e: f32) -> Light {
        sun(Vec3::NEG_Y, e)
    }
}
