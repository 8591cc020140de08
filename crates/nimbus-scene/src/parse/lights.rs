//! `[[light]]` tables and their `[[light.keyframe]]` entries.

use anyhow::Result;
use glam::{DVec2, Vec2, Vec3};
use toml::Value;

use super::*;
use crate::fields::{non_negative, positive_up_to, radiometric, type_name, Fields, Source};

pub(super) const LIGHT_TYPES: &[(&str, &[&str])] = &[
    (
        "directional",
        &[
            "type",
            "direction",
            "irradiance",
            "gobo",
            "gobo_origin",
            "keyframe",
            "group",
        ],
    ),
    (
        "environment",
        &[
            "type",
            "radiance",
            "file",
            "scale",
            "rotation_deg",
            "keyframe",
            "group",
        ],
    ),
    (
        "point",
        &["type", "position", "intensity", "keyframe", "group"],
    ),
    (
        "sphere",
        &["type", "center", "radius", "radiance", "keyframe", "group"],
    ),
];
/// What a `[[light.keyframe]]` may set, per light type: `frame`, then the animated
/// vector (a direction or a position) and the animated colour, or an environment's
/// animated angle.
pub(super) const LIGHT_KEYFRAME_KEYS: &[(&str, &[&str])] = &[
    ("directional", &["frame", "direction", "irradiance"]),
    ("environment", &["frame", "rotation_deg"]),
    ("point", &["frame", "position", "intensity"]),
    ("sphere", &["frame", "center", "radiance"]),
];
/// Consecutive light keyframes whose directions have a dot product below this are
/// rejected: their normalized lerp is ill-conditioned (undefined when exactly opposite).
const MIN_KEYFRAME_DIRECTION_DOT: f32 = -0.999;

/// A `[[light]]`, its `[[light.keyframe]]` entries (resolved: fields a keyframe leaves
/// out hold the light's static value) and its light `group`.
pub(super) fn parse_light(
    source: &Source,
    index: usize,
    table: &toml::Table,
) -> Result<(Light, Vec<LightKeyframe>, Option<String>)> {
    let (kind, f) = typed_fields(source, "light", index, table, LIGHT_TYPES)?;
    let group = parse_light_group(&f)?;
    let keys = parse_light_keyframes(&f, kind)?;
    // With keyframes, the static animatable fields default to the first keyframe's.
    let first_vector = keys.first().and_then(|k| k.vector);
    let first_colour = keys.first().and_then(|k| k.colour);
    let first_angle = keys.first().and_then(|k| k.angle);
    let light = match kind {
        "directional" => {
            let direction = f.direction("direction", first_vector.map(|v| v.as_dvec3()))?;
            let irradiance = f.color("irradiance", first_colour, radiometric)?;
            let gobo = match f.value("gobo") {
                Some(value) => Some(Gobo {
                    polygon: parse_gobo_polygon(&f, value)?,
                    origin: f.vec3("gobo_origin", Some(Vec3::ZERO))?,
                }),
                None if f.has("gobo_origin") => {
                    return Err(f.error("gobo_origin", "has no effect without `gobo`"));
                }
                None => None,
            };
            Light::Directional {
                direction: direction.as_vec3(),
                irradiance,
                gobo,
            }
        }
        "environment" => {
            let file = match f.opt_str("file")? {
                Some(name) => Some(existing_file(&f, "file", name, Some(".exr"))?),
                None => None,
            };
            if file.is_none() && !f.has("radiance") {
                return Err(f.error(
                    "radiance",
                    "missing: an environment light needs `radiance`, `file`, or both",
                ));
            }
            let radiance = f.color("radiance", Some(Vec3::ONE), radiometric)?;
            let scale = f.color("scale", Some(Vec3::ONE), non_negative)?;
            // What the renderer sees is the product; a map's texels are checked with
            // the same limit when the map is read.
            let product = radiance.as_dvec3() * scale.as_dvec3();
            if let Some(message) = radiometric(product.max_element()) {
                return Err(f.error(
                    "scale",
                    format!(
                        "radiance {radiance} times scale {scale} is {product} W/(m²·sr): {message}"
                    ),
                ));
            }
            // Any finite angle, reduced to within one turn exactly (as a box's).
            let rotation_deg =
                reduce_degrees(f.angle_deg("rotation_deg", first_angle.or(Some(0.0)))?);
            Light::Environment {
                radiance,
                file,
                scale,
                rotation_deg: rotation_deg as f32,
            }
        }
        "point" => Light::Point {
            position: f.vec3("position", first_vector)?,
            intensity: f.color("intensity", first_colour, radiometric)?,
        },
        _ => Light::Sphere {
            center: f.vec3("center", first_vector)?,
            radius: f.f32_with("radius", None, positive_up_to(MAX_LENGTH_M))?,
            radiance: f.color("radiance", first_colour, radiometric)?,
        },
    };
    let keyframes = resolve_light_keyframes(&f, &light, &keys)?;
    Ok((light, keyframes, group))
}

/// `group`: a light group name, written into EXR channel names
/// (`lightgroup.<name>.R`): 1 to 64 ASCII letters, digits, `_` or `-`.
fn parse_light_group(f: &Fields) -> Result<Option<String>> {
    let Some(name) = f.opt_str("group")? else {
        return Ok(None);
    };
    let valid = !name.is_empty()
        && name.len() <= 64
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
    if !valid {
        return Err(f.error(
            "group",
            format!(
                "\"{name}\" is not a light group name: 1 to 64 ASCII letters, digits, `_` or \
                 `-` (it becomes the EXR layer lightgroup.<name>)"
            ),
        ));
    }
    Ok(Some(name.to_string()))
}

/// One `[[light.keyframe]]` as written: the fields it leaves out are `None`.
struct LightKeyInput {
    name: String,
    frame: u32,
    /// `direction` (normalized) / `position` / `center`.
    vector: Option<Vec3>,
    /// `irradiance` / `intensity` / `radiance`.
    colour: Option<Vec3>,
    /// An environment's `rotation_deg`, as written (not reduced).
    angle: Option<f64>,
}

/// The `[[light.keyframe]]` entries of the light `f` (of type `kind`), sorted by frame,
/// frames unique. Directional lights with a gobo take none.
fn parse_light_keyframes(f: &Fields, kind: &str) -> Result<Vec<LightKeyInput>> {
    let tables = f.tables("keyframe")?;
    if tables.is_empty() {
        return Ok(Vec::new());
    }
    let not_animatable = |what: &str| {
        f.error(
            "keyframe",
            format!(
                "[[light.keyframe]] #1: {what} cannot be animated; keyframes are for \
                 directional lights without a `gobo`, environment, point and sphere lights"
            ),
        )
    };
    let Some((_, allowed)) = LIGHT_KEYFRAME_KEYS.iter().find(|(t, _)| *t == kind) else {
        return Err(not_animatable(&format!("a light of type \"{kind}\"")));
    };
    if f.has("gobo") {
        return Err(not_animatable("a directional light with a `gobo`"));
    }
    let mut keys = Vec::with_capacity(tables.len());
    for (i, table) in tables.into_iter().enumerate() {
        let name = format!("{} > [[light.keyframe]] #{}", f.name, i + 1);
        let k = Fields::new(f.source, name.clone(), table, allowed)?;
        let frame = k.u32_in("frame", None, 0..=u32::MAX)?;
        let mut key = LightKeyInput {
            name,
            frame,
            vector: None,
            colour: None,
            angle: None,
        };
        match *allowed {
            [_, "rotation_deg"] => {
                if k.has("rotation_deg") {
                    key.angle = Some(k.angle_deg("rotation_deg", None)?);
                }
            }
            [_, vector_key, colour_key] => {
                key.vector = match (k.has(vector_key), kind) {
                    (false, _) => None,
                    (true, "directional") => Some(k.direction(vector_key, None)?.as_vec3()),
                    (true, _) => Some(k.vec3(vector_key, None)?),
                };
                if k.has(colour_key) {
                    key.colour = Some(k.color(colour_key, None, radiometric)?);
                }
            }
            _ => return Err(not_animatable(&format!("a light of type \"{kind}\""))),
        }
        keys.push(key);
    }
    keys.sort_by_key(|k| k.frame);
    for pair in keys.windows(2) {
        if pair[0].frame == pair[1].frame {
            return Err(f.source.error(format!(
                "{} and {}: field `frame`: both are frame {}; keyframe frames must be unique",
                pair[0].name, pair[1].name, pair[0].frame
            )));
        }
    }
    Ok(keys)
}

/// Completes `keys` with `light`'s static values and checks that consecutive
/// directions can be interpolated.
fn resolve_light_keyframes(
    f: &Fields,
    light: &Light,
    keys: &[LightKeyInput],
) -> Result<Vec<LightKeyframe>> {
    let Some(base) = light.state() else {
        return Ok(Vec::new());
    };
    let keyframes: Vec<LightKeyframe> = keys
        .iter()
        .map(|k| {
            let state = match base {
                LightState::Directional {
                    direction,
                    irradiance,
                } => LightState::Directional {
                    direction: k.vector.unwrap_or(direction),
                    irradiance: k.colour.unwrap_or(irradiance),
                },
                LightState::Point {
                    position,
                    intensity,
                } => LightState::Point {
                    position: k.vector.unwrap_or(position),
                    intensity: k.colour.unwrap_or(intensity),
                },
                LightState::Sphere { center, radiance } => LightState::Sphere {
                    center: k.vector.unwrap_or(center),
                    radiance: k.colour.unwrap_or(radiance),
                },
                LightState::Environment { rotation_deg } => LightState::Environment {
                    rotation_deg: k.angle.unwrap_or(rotation_deg),
                },
            };
            LightKeyframe {
                frame: k.frame,
                state,
            }
        })
        .collect();
    for (i, pair) in keyframes.windows(2).enumerate() {
        let (
            LightState::Directional { direction: a, .. },
            LightState::Directional { direction: b, .. },
        ) = (pair[0].state, pair[1].state)
        else {
            continue;
        };
        let dot = a.dot(b);
        if dot < MIN_KEYFRAME_DIRECTION_DOT {
            let describe = |k: &LightKeyInput, d: Vec3| {
                let origin = match k.vector {
                    Some(_) => "",
                    None => " (the light's `direction`, which the keyframe leaves out)",
                };
                format!("[{}, {}, {}] at frame {}{origin}", d.x, d.y, d.z, k.frame)
            };
            return Err(f.source.error(format!(
                "{} and {}: field `direction`: the directions {} and {} are nearly opposite \
                 (dot product {dot} < {MIN_KEYFRAME_DIRECTION_DOT}), so the direction between \
                 them is undefined; add a keyframe in between",
                keys[i].name,
                keys[i + 1].name,
                describe(&keys[i], a),
                describe(&keys[i + 1], b),
            )));
        }
    }
    Ok(keyframes)
}

/// `gobo`: a list of `[u, v]` forming a convex polygon, returned counter-clockwise.
fn parse_gobo_polygon(f: &Fields, value: &Value) -> Result<Vec<Vec2>> {
    let Value::Array(items) = value else {
        return Err(f.error(
            "gobo",
            format!(
                "expected an array of [u, v] points, found {}",
                type_name(value)
            ),
        ));
    };
    let mut points = Vec::with_capacity(items.len());
    for (i, item) in items.iter().enumerate() {
        let [u, v] = crate::fields::parse_numbers::<2>(item)
            .map_err(|message| f.error("gobo", format!("point {i}: {message}")))?;
        // Lengths are at most MAX_LENGTH_M: the renderer's f32 inside test multiplies two
        // coordinates, which overflows for points near 1e20 m and more.
        if u.abs().max(v.abs()) > MAX_LENGTH_M {
            return Err(f.error(
                "gobo",
                format!("point {i} is [{u:e}, {v:e}]: each coordinate must be within ±{MAX_LENGTH_M:e} m"),
            ));
        }
        points.push(DVec2::new(u, v));
    }
    let polygon = convex_ccw_polygon(&points)
        .map_err(|message| f.error("gobo", format!("polygon {message}")))?;
    Ok(polygon.into_iter().map(|p| p.as_vec2()).collect())
}
