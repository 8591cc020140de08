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

use glam::Vec3;
use nimbus_scene::Light;

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

/// The change of one light between two frames, 0 (none) to 1: the relative change of its
/// irradiance at `centre` or its turn as seen from there, whichever is larger.
fn light_change(prev: &Light, cur: &Light, centre: Vec3, env: f32) -> f32 {
    let power = relative(irradiance(prev, centre, env), irradiance(cur, centre, env));
    let angle = match (prev, cur) {
        (Light::Directional { direction: a, .. }, Light::Directional { direction: b, .. }) => {
            turn(*a, *b)
        }
        (Light::Point { position: a, .. }, Light::Point { position: b, .. })
        | (Light::Sphere { center: a, .. }, Light::Sphere { center: b, .. }) => {
            turn(*a - centre, *b - centre)
        }
        _ => 0.0,
    };
    power.max((angle / LIGHT_TURN_RADIANS).min(1.0))
}

/// The lights' confidence in the previous frame's reservoirs, in [0, 1]: 1 minus the
/// lights' changes weighted by their share of the irradiance at `centre` (the larger of
/// the two frames'), over [`LIGHT_CHANGE_TOLERANCE`]. `env` is an environment light's
/// irradiance (luminance). Lists of different lengths share nothing (0).
pub fn light_confidence(prev: &[Light], cur: &[Light], centre: Vec3, env: f32) -> f32 {
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
        changed += share * light_change(a, b, centre, env);
    }
    if total.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return 1.0;
    }
    (1.0 - changed / total / LIGHT_CHANGE_TOLERANCE).clamp(0.0, 1.0)
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

    #[test]
    fn unchanged_lights_keep_the_history() {
        let lights = vec![sun(Vec3::NEG_Y, 3.0), sky(0.05)];
        assert_eq!(light_confidence(&lights, &lights, Vec3::ZERO, 0.16), 1.0);
        assert_eq!(light_confidence(&[], &[], Vec3::ZERO, 0.0), 1.0);
    }

    #[test]
    fn a_sun_tripled_or_switched_off_drops_most_of_it() {
        let a = vec![sun(Vec3::NEG_Y, 1.0), sky(0.05)];
        let b = vec![sun(Vec3::NEG_Y, 3.0), sky(0.05)];
        let off = vec![sun(Vec3::NEG_Y, 0.0), sky(0.05)];
        // What stays is the sky's share of the light (0.16 of 3.16, and 2/3 of the
        // sun's 3 changed).
        let c = light_confidence(&a, &b, Vec3::ZERO, 0.16);
        assert!((c - (1.0 - 2.0 / 3.0 * 3.0 / 3.16)).abs() < 1e-5, "{c}");
        let c = light_confidence(&b, &off, Vec3::ZERO, 0.16);
        assert!((c - 0.16 / 3.16).abs() < 1e-5, "{c}");
        // Without a sky nothing stays.
        assert_eq!(light_confidence(&b[..1], &off[..1], Vec3::ZERO, 0.0), 0.0);
    }

    #[test]
    fn slow_changes_keep_most_of_it() {
        let a = vec![sun(Vec3::new(0.0, -1.0, 0.0), 3.0), sky(0.05)];
        // One degree of turn.
        let d = Vec3::new(1f32.to_radians().sin(), -1f32.to_radians().cos(), 0.0);
        let b = vec![sun(d, 3.0), sky(0.05)];
        let c = light_confidence(&a, &b, Vec3::ZERO, 0.16);
        assert!(c > 0.85 && c < 1.0, "{c}");
        // A 2 % brighter sun.
        let b = vec![sun(Vec3::NEG_Y, 3.06), sky(0.05)];
        let c = light_confidence(&a, &b, Vec3::ZERO, 0.16);
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
        let c = light_confidence(&a, &b, Vec3::ZERO, 0.0);
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
        let c = light_confidence(&a, &b, Vec3::ZERO, 0.0);
        assert!((0.0..=1.0).contains(&c), "{c}");
        assert_eq!(light_confidence(&a, &[], Vec3::ZERO, 0.0), 0.0);
    }
}
