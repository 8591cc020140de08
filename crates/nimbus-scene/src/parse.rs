//! Scene file → validated [`Scene`]: one function per table of `SCENE_FORMAT.md`.

use std::path::Path;

use anyhow::Result;
use glam::{DVec2, DVec3, Vec2, Vec3};
use toml::Value;

use crate::fields::{
    non_negative, open_interval, positive_up_to, radiometric, type_name, unit_interval, Fields,
    Source,
};
use crate::files::{check_grid_dims, file_size, read_vol_header};
use crate::geometry::{convex_ccw_polygon, OrientedBox};
use crate::overrides::FieldOverride;
use crate::types::*;

/// Largest size, extent or radius in metres.
pub const MAX_LENGTH_M: f64 = 1e7;
/// Largest `sigma_t` / `density_scale` in 1/m.
pub const MAX_SIGMA_T: f64 = 1e9;
/// Most ReSTIR spatial neighbours: the shaders combine at most 17 candidates (the
/// pixel's own and 16 neighbours' reservoirs), and Talbot MIS costs (N + 1)² path
/// evaluations per pixel.
pub const MAX_SPATIAL_NEIGHBORS: u32 = 16;
/// Largest image side in pixels.
pub const MAX_IMAGE_SIDE: u32 = 16384;
/// Most pixels in an image (64 Mi).
pub const MAX_IMAGE_PIXELS: u64 = 64 << 20;

const TOP_KEYS: &[&str] = &["render", "camera", "light", "medium", "shape", "integrator"];
const RENDER_KEYS: &[&str] = &["width", "height", "frames", "spp", "seed", "pixel_jitter"];
const CAMERA_KEYS: &[&str] = &[
    "position",
    "look_at",
    "up",
    "horizontal_fov_deg",
    "keyframe",
];
const KEYFRAME_KEYS: &[&str] = &["frame", "position", "look_at"];
const LIGHT_TYPES: &[(&str, &[&str])] = &[
    (
        "directional",
        &[
            "type",
            "direction",
            "irradiance",
            "gobo",
            "gobo_origin",
            "keyframe",
        ],
    ),
    // `keyframe` is listed so that it gets a clear "cannot be animated" error.
    (
        "environment",
        &["type", "radiance", "file", "scale", "keyframe"],
    ),
    ("point", &["type", "position", "intensity", "keyframe"]),
    (
        "sphere",
        &["type", "center", "radius", "radiance", "keyframe"],
    ),
];
/// What a `[[light.keyframe]]` may set, per light type: `frame`, then the animated
/// vector (a direction or a position), then the animated colour.
const LIGHT_KEYFRAME_KEYS: &[(&str, [&str; 3])] = &[
    ("directional", ["frame", "direction", "irradiance"]),
    ("point", ["frame", "position", "intensity"]),
    ("sphere", ["frame", "center", "radiance"]),
];
/// Consecutive light keyframes whose directions have a dot product below this are
/// rejected: their normalized lerp is ill-conditioned (undefined when exactly opposite).
const MIN_KEYFRAME_DIRECTION_DOT: f32 = -0.999;
const MEDIUM_TYPES: &[(&str, &[&str])] = &[
    (
        "box",
        &[
            "type",
            "center",
            "size",
            "rotation_deg",
            "sigma_t",
            "albedo",
            "g",
        ],
    ),
    (
        "grid",
        &[
            "type",
            "bounds_min",
            "bounds_max",
            "density",
            "density_scale",
            "albedo",
            "g",
            "emission",
            "emission_scale",
            "velocity",
            "frame",
        ],
    ),
];
const SHAPE_TYPES: &[(&str, &[&str])] = &[
    ("quad", &["type", "corner", "edge_u", "edge_v", "albedo"]),
    ("box", &["type", "center", "size", "rotation_deg", "albedo"]),
    ("sphere", &["type", "center", "radius", "albedo"]),
];
const GRID_KEYS: &[&str] = &["file", "dims", "procedural", "noise_seed"];
const GRID_FRAME_KEYS: &[&str] = &["frame", "density"];
const INTEGRATOR_KEYS: &[&str] = &[
    "max_bounces",
    "volume",
    "box_estimator",
    "box_samples",
    "restir",
];
/// The fields of `[integrator.restir]`.
pub const RESTIR_KEYS: &[&str] = &[
    "candidates",
    "temporal",
    "temporal_limit",
    "spatial_neighbors",
    "spatial_radius_px",
    "spatial_rounds",
    "reuse",
    "mip_candidates",
    "mip_indirect",
    "mip_reuse",
    "final_transmittance",
];

/// Parses and validates the scene in `text`; `file` names it in errors and anchors
/// relative paths.
pub(crate) fn parse_scene(text: &str, file: &Path, overrides: &[FieldOverride]) -> Result<Scene> {
    let source = Source { file };
    let mut root: toml::Table = toml::from_str(text)
        .map_err(|e| source.error(format!("TOML syntax error: {}", e.to_string().trim_end())))?;
    crate::overrides::apply(&mut root, overrides).map_err(|e| source.error(e))?;
    let top = Fields::new(&source, "top level".into(), &root, TOP_KEYS)?;

    let render = match top.opt_table("render")? {
        Some(table) => parse_render(&source, table)?,
        None => RenderSettings::default(),
    };
    let camera_table = top
        .opt_table("camera")?
        .ok_or_else(|| source.error("missing required table [camera]"))?;
    let camera = parse_camera(&source, camera_table, render.frames)?;

    let (lights, light_keyframes) = top
        .tables("light")?
        .into_iter()
        .enumerate()
        .map(|(i, table)| parse_light(&source, i + 1, table))
        .collect::<Result<(Vec<_>, Vec<_>)>>()?;

    let mut media = Vec::new();
    let mut medium_bounds: Vec<(String, OrientedBox)> = Vec::new();
    for (i, table) in top.tables("medium")?.into_iter().enumerate() {
        let (medium, name, bounds) = parse_medium(&source, i + 1, table)?;
        media.push(medium);
        medium_bounds.push((name, bounds));
    }
    // Media must not share volume (touching is fine).
    for (i, (name_a, a)) in medium_bounds.iter().enumerate() {
        for (name_b, b) in &medium_bounds[i + 1..] {
            if a.overlaps(b) {
                return Err(source.error(format!(
                    "{name_a} and {name_b} overlap; media must not overlap"
                )));
            }
        }
    }

    let shapes = top
        .tables("shape")?
        .into_iter()
        .enumerate()
        .map(|(i, table)| parse_shape(&source, i + 1, table))
        .collect::<Result<Vec<_>>>()?;

    let integrator = match top.opt_table("integrator")? {
        Some(table) => parse_integrator(&source, table)?,
        None => Integrator::default(),
    };

    let scene = Scene {
        source: file.to_path_buf(),
        render,
        camera,
        lights,
        light_keyframes,
        media,
        shapes,
        integrator,
    };
    check_precision(&source, &scene)?;
    Ok(scene)
}

/// Refuses features and extinctions that 32-bit positions cannot resolve at the
/// scene's extent (see [`crate::precision`]). Grid densities are checked when the grid
/// is read ([`GridMedium::check_density`]).
fn check_precision(source: &Source, scene: &Scene) -> Result<()> {
    let scale = scene.position_scale();
    let fail = |table: String, field: &str, problem: String| {
        source.error(format!("{table}: field `{field}`: {problem}"))
    };
    for (i, medium) in scene.media.iter().enumerate() {
        match medium {
            Medium::Box(b) => {
                let table = format!("[[medium]] #{} (type = \"box\")", i + 1);
                if let Some(p) = scale.feature_problem(f64::from(b.size.min_element())) {
                    return Err(fail(table, "size", p));
                }
                if let Some(p) = scale.sigma_t_problem(f64::from(b.sigma_t), "sigma_t") {
                    return Err(fail(table, "sigma_t", p));
                }
            }
            Medium::Grid(g) => {
                let table = format!("[[medium]] #{} (type = \"grid\")", i + 1);
                for source_grid in g.density_sources() {
                    let Ok(dims) = source_grid.dims() else {
                        continue;
                    };
                    let voxel = (g.bounds_max - g.bounds_min) / Vec3::from(dims.map(|d| d as f32));
                    if let Some(p) = scale.feature_problem(f64::from(voxel.min_element())) {
                        return Err(fail(table, "density", format!("a voxel of {p}")));
                    }
                }
            }
        }
    }
    for (i, shape) in scene.shapes.iter().enumerate() {
        let (kind, field, size) = match shape {
            Shape::Quad { edge_u, edge_v, .. } => {
                let (field, len) = if edge_u.length() <= edge_v.length() {
                    ("edge_u", edge_u.length())
                } else {
                    ("edge_v", edge_v.length())
                };
                ("quad", field, len)
            }
            Shape::Box { size, .. } => ("box", "size", size.min_element()),
            Shape::Sphere { radius, .. } => ("sphere", "radius", *radius),
        };
        if let Some(p) = scale.feature_problem(f64::from(size)) {
            return Err(fail(
                format!("[[shape]] #{} (type = \"{kind}\")", i + 1),
                field,
                p,
            ));
        }
    }
    for (i, light) in scene.lights.iter().enumerate() {
        let (kind, field, size) = match light {
            Light::Sphere { radius, .. } => ("sphere", "radius", *radius),
            Light::Directional {
                gobo: Some(gobo), ..
            } => {
                let n = gobo.polygon.len();
                let shortest = (0..n)
                    .map(|k| (gobo.polygon[(k + 1) % n] - gobo.polygon[k]).length())
                    .fold(f32::INFINITY, f32::min);
                ("directional", "gobo", shortest)
            }
            _ => continue,
        };
        if let Some(p) = scale.feature_problem(f64::from(size)) {
            return Err(fail(
                format!("[[light]] #{} (type = \"{kind}\")", i + 1),
                field,
                p,
            ));
        }
    }
    Ok(())
}

fn parse_render(source: &Source, table: &toml::Table) -> Result<RenderSettings> {
    let f = Fields::new(source, "[render]".into(), table, RENDER_KEYS)?;
    let defaults = RenderSettings::default();
    let width = f.u32_in("width", Some(defaults.width), 1..=MAX_IMAGE_SIDE)?;
    let height = f.u32_in("height", Some(defaults.height), 1..=MAX_IMAGE_SIDE)?;
    let pixels = u64::from(width) * u64::from(height);
    if pixels > MAX_IMAGE_PIXELS {
        return Err(f.error(
            "height",
            format!("width x height = {pixels} pixels, at most {MAX_IMAGE_PIXELS} are allowed"),
        ));
    }
    Ok(RenderSettings {
        width,
        height,
        frames: f.u32_in("frames", Some(defaults.frames), 1..=1_000_000)?,
        spp: f.u32_in("spp", Some(defaults.spp), 1..=65536)?,
        seed: f.int_in("seed", Some(0), 0..=i64::MAX)? as u64,
        pixel_jitter: f.opt_bool("pixel_jitter")?.unwrap_or(defaults.pixel_jitter),
    })
}

/// Why a camera looking from `position` at `look_at` with `up` has no frame, if it
/// has none.
fn view_problem(position: Vec3, look_at: Vec3, up: Vec3) -> Option<String> {
    let view = (look_at - position).as_dvec3();
    let scale = position
        .abs()
        .max_element()
        .max(look_at.abs().max_element()) as f64;
    if view.length() <= (1e-6 * scale).max(1e-12) {
        // Points far from the origin may differ in the file and still coincide as f32.
        let resolution = scale * crate::precision::F32_EPSILON;
        return Some(if resolution > 1e-6 {
            format!(
                "`position` and `look_at` coincide or nearly so: {scale:e} m from the origin, \
                 32-bit positions are only known to {resolution:.2e} m"
            )
        } else {
            "`position` and `look_at` coincide".to_string()
        });
    }
    if view.normalize().cross(up.as_dvec3()).length() < 1e-4 {
        return Some("`up` is parallel to the view direction (look_at - position)".to_string());
    }
    None
}

fn parse_camera(source: &Source, table: &toml::Table, frames: u32) -> Result<Camera> {
    let f = Fields::new(source, "[camera]".into(), table, CAMERA_KEYS)?;
    let up = f.direction("up", Some(DVec3::Y))?.as_vec3();
    let horizontal_fov_deg =
        f.f32_with("horizontal_fov_deg", Some(60.0), open_interval(0.0, 180.0))?;

    let mut keyframes: Vec<(CameraKeyframe, String)> = Vec::new();
    for (i, key_table) in f.tables("keyframe")?.into_iter().enumerate() {
        let name = format!("[[camera.keyframe]] #{}", i + 1);
        let k = Fields::new(source, name.clone(), key_table, KEYFRAME_KEYS)?;
        let keyframe = CameraKeyframe {
            frame: k.u32_in("frame", None, 0..=u32::MAX)?,
            position: k.vec3("position", None)?,
            look_at: k.vec3("look_at", None)?,
        };
        if let Some(problem) = view_problem(keyframe.position, keyframe.look_at, up) {
            return Err(k.error("look_at", problem));
        }
        keyframes.push((keyframe, name));
    }
    keyframes.sort_by_key(|(k, _)| k.frame);
    for pair in keyframes.windows(2) {
        if pair[0].0.frame == pair[1].0.frame {
            return Err(source.error(format!(
                "{} and {}: field `frame`: both are frame {}; keyframe frames must be unique",
                pair[0].1, pair[1].1, pair[0].0.frame
            )));
        }
    }
    let keyframes: Vec<CameraKeyframe> = keyframes.into_iter().map(|(k, _)| k).collect();

    // With keyframes the static pose is optional: it defaults to the first keyframe's.
    let first = keyframes.first();
    let position = f.vec3("position", first.map(|k| k.position))?;
    let look_at = f.vec3("look_at", first.map(|k| k.look_at))?;
    if let Some(problem) = view_problem(position, look_at, up) {
        let field = if problem.contains("`up`") {
            "up"
        } else {
            "look_at"
        };
        return Err(f.error(field, problem));
    }
    let camera = Camera {
        position,
        look_at,
        up,
        horizontal_fov_deg,
        keyframes,
    };
    // Interpolated poses between keyframes must also be valid for every rendered frame.
    if let (Some(first), Some(last)) = (camera.keyframes.first(), camera.keyframes.last()) {
        let end = last.frame.min(frames.saturating_sub(1));
        for frame in first.frame..=end {
            let (position, look_at) = camera.pose_at(frame);
            if let Some(problem) = view_problem(position, look_at, up) {
                return Err(f.error(
                    "keyframe",
                    format!("at frame {frame} (interpolated): {problem}"),
                ));
            }
        }
    }
    Ok(camera)
}

/// Reads `type` and wraps `table` with the keys that type allows. Returns the type
/// and the fields, named like `[[light]] #2 (type = "point")`.
fn typed_fields<'a>(
    source: &'a Source<'a>,
    array: &str,
    index: usize,
    table: &'a toml::Table,
    types: &[(&'static str, &[&str])],
) -> Result<(&'static str, Fields<'a>)> {
    let bare = format!("[[{array}]] #{index}");
    let valid: Vec<String> = types.iter().map(|(t, _)| format!("\"{t}\"")).collect();
    let valid = valid.join(", ");
    let error = |message: String| {
        source.error(format!(
            "{bare}: field `type`: {message}; valid types: {valid}"
        ))
    };
    let kind = match table.get("type") {
        Some(Value::String(kind)) => kind.as_str(),
        Some(other) => {
            return Err(error(format!(
                "expected a string, found {}",
                type_name(other)
            )))
        }
        None => return Err(error("missing required field".into())),
    };
    let (kind, allowed) = types
        .iter()
        .find(|(t, _)| *t == kind)
        .ok_or_else(|| error(format!("unknown type \"{kind}\"")))?;
    let fields = Fields::new(
        source,
        format!("{bare} (type = \"{kind}\")"),
        table,
        allowed,
    )?;
    Ok((kind, fields))
}

/// A `[[light]]` and its `[[light.keyframe]]` entries (resolved: fields a keyframe
/// leaves out hold the light's static value).
fn parse_light(
    source: &Source,
    index: usize,
    table: &toml::Table,
) -> Result<(Light, Vec<LightKeyframe>)> {
    let (kind, f) = typed_fields(source, "light", index, table, LIGHT_TYPES)?;
    let keys = parse_light_keyframes(&f, kind)?;
    // With keyframes, the static animatable fields default to the first keyframe's.
    let first_vector = keys.first().and_then(|k| k.vector);
    let first_colour = keys.first().and_then(|k| k.colour);
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
            Light::Environment {
                radiance,
                file,
                scale,
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
    Ok((light, keyframes))
}

/// One `[[light.keyframe]]` as written: the fields it leaves out are `None`.
struct LightKeyInput {
    name: String,
    frame: u32,
    /// `direction` (normalized) / `position` / `center`.
    vector: Option<Vec3>,
    /// `irradiance` / `intensity` / `radiance`.
    colour: Option<Vec3>,
}

/// The `[[light.keyframe]]` entries of the light `f` (of type `kind`), sorted by frame,
/// frames unique. Environment lights and directional lights with a gobo take none.
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
                 directional lights without a `gobo`, point lights and sphere lights"
            ),
        )
    };
    let Some((_, allowed)) = LIGHT_KEYFRAME_KEYS.iter().find(|(t, _)| *t == kind) else {
        return Err(not_animatable(&format!("a light of type \"{kind}\"")));
    };
    if f.has("gobo") {
        return Err(not_animatable("a directional light with a `gobo`"));
    }
    let [_, vector_key, colour_key] = *allowed;
    let mut keys = Vec::with_capacity(tables.len());
    for (i, table) in tables.into_iter().enumerate() {
        let name = format!("{} > [[light.keyframe]] #{}", f.name, i + 1);
        let k = Fields::new(f.source, name.clone(), table, allowed)?;
        let frame = k.u32_in("frame", None, 0..=u32::MAX)?;
        let vector = match (k.has(vector_key), kind) {
            (false, _) => None,
            (true, "directional") => Some(k.direction(vector_key, None)?.as_vec3()),
            (true, _) => Some(k.vec3(vector_key, None)?),
        };
        let colour = match k.has(colour_key) {
            true => Some(k.color(colour_key, None, radiometric)?),
            false => None,
        };
        keys.push(LightKeyInput {
            name,
            frame,
            vector,
            colour,
        });
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
        return Ok(Vec::new()); // Environment lights: keyframes were rejected.
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
        points.push(DVec2::new(u, v));
    }
    let polygon = convex_ccw_polygon(&points)
        .map_err(|message| f.error("gobo", format!("polygon {message}")))?;
    Ok(polygon.into_iter().map(|p| p.as_vec2()).collect())
}

/// Resolves `name` (field `key`) against the scene's directory and checks that it is
/// an existing file, with extension `extension` (case-insensitive) when given.
fn existing_file(
    f: &Fields,
    key: &str,
    name: &str,
    extension: Option<&str>,
) -> Result<std::path::PathBuf> {
    if let Some(extension) = extension {
        if !name.to_ascii_lowercase().ends_with(extension) {
            return Err(f.error(key, format!("\"{name}\" must be a {extension} file")));
        }
    }
    let path = f.source.resolve(name);
    file_size(&path).map_err(|message| f.error(key, message))?;
    Ok(path)
}

/// Three lengths in (0, [`MAX_LENGTH_M`]].
fn size3(f: &Fields, key: &str) -> Result<Vec3> {
    let size = f.vec3_f64(key, None)?;
    for axis in 0..3 {
        if let Some(message) = positive_up_to(MAX_LENGTH_M)(size[axis]) {
            return Err(f.error(
                key,
                format!("component {axis} is {}, {message}", size[axis]),
            ));
        }
    }
    Ok(size.as_vec3())
}

fn parse_medium(
    source: &Source,
    index: usize,
    table: &toml::Table,
) -> Result<(Medium, String, OrientedBox)> {
    let (kind, f) = typed_fields(source, "medium", index, table, MEDIUM_TYPES)?;
    let albedo = f.color("albedo", Some(Vec3::ONE), unit_interval)?;
    let g = f.f32_with("g", Some(0.0), open_interval(-1.0, 1.0))?;
    if kind == "box" {
        let medium = BoxMedium {
            center: f.vec3("center", None)?,
            size: size3(&f, "size")?,
            rotation_deg: f.vec3("rotation_deg", Some(Vec3::ZERO))?,
            sigma_t: f.f32_in("sigma_t", None, 0.0..=MAX_SIGMA_T)?,
            albedo,
            g,
        };
        let bounds = OrientedBox::new(
            medium.center.as_dvec3(),
            medium.size.as_dvec3(),
            medium.rotation_deg.as_dvec3(),
        );
        return Ok((Medium::Box(medium), f.name, bounds));
    }

    let bounds_min = f.vec3("bounds_min", None)?;
    let bounds_max = f.vec3("bounds_max", None)?;
    for axis in 0..3 {
        let extent = f64::from(bounds_max[axis]) - f64::from(bounds_min[axis]);
        if let Some(message) = positive_up_to(MAX_LENGTH_M)(extent) {
            return Err(f.error(
                "bounds_max",
                format!(
                    "component {axis}: bounds_max - bounds_min = {extent}, {message} \
                     (bounds_min must be < bounds_max componentwise)"
                ),
            ));
        }
    }
    let density_table = f
        .opt_table("density")?
        .ok_or_else(|| f.error("density", "missing required field"))?;
    let density = parse_grid_source(&f, "density", density_table, GridChannels::Scalar)?;
    let emission = match f.opt_table("emission")? {
        Some(table) => Some(parse_grid_source(
            &f,
            "emission",
            table,
            GridChannels::Scalar,
        )?),
        None if f.has("emission_scale") => {
            return Err(f.error("emission_scale", "has no effect without `emission`"));
        }
        None => None,
    };
    let velocity = match f.opt_table("velocity")? {
        Some(table) => Some(parse_grid_source(
            &f,
            "velocity",
            table,
            GridChannels::Vector,
        )?),
        None => None,
    };

    let mut frames: Vec<(GridFrame, String)> = Vec::new();
    for (i, frame_table) in f.tables("frame")?.into_iter().enumerate() {
        let name = format!("{} > [[medium.frame]] #{}", f.name, i + 1);
        let frame_fields = Fields::new(source, name.clone(), frame_table, GRID_FRAME_KEYS)?;
        let frame = frame_fields.u32_in("frame", None, 0..=u32::MAX)?;
        let density_table = frame_fields
            .opt_table("density")?
            .ok_or_else(|| frame_fields.error("density", "missing required field"))?;
        let density = parse_grid_source(
            &frame_fields,
            "density",
            density_table,
            GridChannels::Scalar,
        )?;
        frames.push((GridFrame { frame, density }, name));
    }
    frames.sort_by_key(|(frame, _)| frame.frame);
    for pair in frames.windows(2) {
        if pair[0].0.frame == pair[1].0.frame {
            return Err(source.error(format!(
                "{} and {}: field `frame`: both are frame {}; medium frames must be unique",
                pair[0].1, pair[1].1, pair[0].0.frame
            )));
        }
    }

    let medium = GridMedium {
        bounds_min,
        bounds_max,
        density,
        density_scale: f.f32_in("density_scale", Some(1.0), 0.0..=MAX_SIGMA_T)?,
        albedo,
        g,
        emission,
        emission_scale: f.color("emission_scale", Some(Vec3::ONE), radiometric)?,
        velocity,
        frames: frames.into_iter().map(|(frame, _)| frame).collect(),
    };
    let bounds = OrientedBox::aabb(bounds_min.as_dvec3(), bounds_max.as_dvec3());
    Ok((Medium::Grid(medium), f.name, bounds))
}

/// What a grid holds per voxel.
#[derive(Clone, Copy, PartialEq, Eq)]
enum GridChannels {
    /// One float (density, emission); procedural grids allowed.
    Scalar,
    /// Three floats (velocity); files only.
    Vector,
}

impl GridChannels {
    fn count(self) -> u32 {
        match self {
            Self::Scalar => 1,
            Self::Vector => 3,
        }
    }
}

/// A grid table (`density`, `emission`, `velocity`) found as field `key` of `parent`.
fn parse_grid_source(
    parent: &Fields,
    key: &str,
    table: &toml::Table,
    channels: GridChannels,
) -> Result<GridSource> {
    let f = Fields::new(
        parent.source,
        format!("{} > {key}", parent.name),
        table,
        GRID_KEYS,
    )?;
    let dims = match f.value("dims") {
        Some(value) => Some(parse_dims(&f, value)?),
        None => None,
    };
    let file = f.opt_str("file")?;
    let procedural = f.opt_str("procedural")?;
    match (file, procedural) {
        (Some(_), Some(_)) => {
            Err(f.error("procedural", "give either `file` or `procedural`, not both"))
        }
        (None, None) => Err(f.error(
            "file",
            "missing: a grid needs `file` (raw float32 with `dims`, or .vol) or `procedural`",
        )),
        (None, Some(_)) => {
            if channels == GridChannels::Vector {
                return Err(f.error(
                    "procedural",
                    "a velocity grid must come from a file (3 float32 channels)",
                ));
            }
            f.choice("procedural", None, &[("cloud", ())])?;
            let dims = dims.ok_or_else(|| {
                f.error(
                    "dims",
                    "missing required field (procedural grids need `dims`)",
                )
            })?;
            let noise_seed = f.int_in("noise_seed", Some(0), 0..=i64::MAX)? as u64;
            Ok(GridSource::ProceduralCloud { dims, noise_seed })
        }
        (Some(name), None) => {
            if f.has("noise_seed") {
                return Err(f.error("noise_seed", "only procedural grids take a `noise_seed`"));
            }
            let path = f.source.resolve(name);
            if name.to_ascii_lowercase().ends_with(".vol") {
                let header = read_vol_header(&path).map_err(|e| f.error("file", e))?;
                if header.channels != channels.count() {
                    return Err(f.error(
                        "file",
                        format!(
                            "{}: .vol file has {} channels, expected {}",
                            path.display(),
                            header.channels,
                            channels.count()
                        ),
                    ));
                }
                if let Some(dims) = dims {
                    if dims != header.dims {
                        return Err(f.error(
                            "dims",
                            format!(
                                "{dims:?} differs from the .vol header's {:?} (dims may be left out for .vol files)",
                                header.dims
                            ),
                        ));
                    }
                }
                return Ok(GridSource::MitsubaVol { file: path });
            }
            let dims = dims.ok_or_else(|| {
                f.error(
                    "dims",
                    "missing required field (raw float32 grid files need `dims`)",
                )
            })?;
            let size = file_size(&path).map_err(|message| f.error("file", message))?;
            let voxels: u64 = dims.iter().map(|&d| u64::from(d)).product();
            let expected = voxels * u64::from(channels.count()) * 4;
            if size != expected {
                return Err(f.error(
                    "file",
                    format!(
                        "{}: expected {expected} bytes ({} x {} x {} voxels x {} channel(s) x 4 \
                         bytes of float32), found {size} bytes",
                        path.display(),
                        dims[0],
                        dims[1],
                        dims[2],
                        channels.count()
                    ),
                ));
            }
            Ok(GridSource::Raw { file: path, dims })
        }
    }
}

/// `dims = [nx, ny, nz]`.
fn parse_dims(f: &Fields, value: &Value) -> Result<[u32; 3]> {
    let expected = "expected an array of 3 integers [nx, ny, nz]";
    let items = match value {
        Value::Array(items) if items.len() == 3 => items,
        Value::Array(items) => {
            return Err(f.error(
                "dims",
                format!("{expected}, found {} elements", items.len()),
            ))
        }
        other => return Err(f.error("dims", format!("{expected}, found {}", type_name(other)))),
    };
    let mut dims = [0i64; 3];
    for (axis, item) in items.iter().enumerate() {
        dims[axis] = match item {
            Value::Integer(i) => *i,
            other => {
                return Err(f.error(
                    "dims",
                    format!("{expected}, element {axis} is {}", type_name(other)),
                ))
            }
        };
    }
    check_grid_dims(dims).map_err(|message| f.error("dims", message))
}

fn parse_shape(source: &Source, index: usize, table: &toml::Table) -> Result<Shape> {
    let (kind, f) = typed_fields(source, "shape", index, table, SHAPE_TYPES)?;
    let albedo = f.color("albedo", Some(Vec3::ZERO), unit_interval)?;
    Ok(match kind {
        "quad" => {
            let edge = |key: &str| -> Result<DVec3> {
                let v = f.vec3_f64(key, None)?;
                if v.length() == 0.0 {
                    return Err(f.error(key, "must not be the zero vector"));
                }
                if v.length() > MAX_LENGTH_M {
                    return Err(f.error(key, format!("is longer than {MAX_LENGTH_M} m")));
                }
                Ok(v)
            };
            let (edge_u, edge_v) = (edge("edge_u")?, edge("edge_v")?);
            if edge_u.cross(edge_v).length() <= 1e-6 * edge_u.length() * edge_v.length() {
                return Err(f.error("edge_v", "is parallel to `edge_u`"));
            }
            Shape::Quad {
                corner: f.vec3("corner", None)?,
                edge_u: edge_u.as_vec3(),
                edge_v: edge_v.as_vec3(),
                albedo,
            }
        }
        "box" => Shape::Box {
            center: f.vec3("center", None)?,
            size: size3(&f, "size")?,
            rotation_deg: f.vec3("rotation_deg", Some(Vec3::ZERO))?,
            albedo,
        },
        _ => Shape::Sphere {
            center: f.vec3("center", None)?,
            radius: f.f32_with("radius", None, positive_up_to(MAX_LENGTH_M))?,
            albedo,
        },
    })
}

fn parse_integrator(source: &Source, table: &toml::Table) -> Result<Integrator> {
    let f = Fields::new(source, "[integrator]".into(), table, INTEGRATOR_KEYS)?;
    let defaults = Integrator::default();
    let estimators: Vec<(&str, BoxEstimator)> =
        BoxEstimator::ALL.iter().map(|e| (e.name(), *e)).collect();
    Ok(Integrator {
        max_bounces: f.u32_in("max_bounces", Some(defaults.max_bounces), 1..=1024)?,
        volume: f.choice(
            "volume",
            Some(defaults.volume),
            &[
                ("restir", VolumeIntegrator::Restir),
                ("baseline", VolumeIntegrator::Baseline),
            ],
        )?,
        box_estimator: f.choice("box_estimator", Some(defaults.box_estimator), &estimators)?,
        box_samples: f.u32_in("box_samples", Some(defaults.box_samples), 1..=65536)?,
        restir: match f.opt_table("restir")? {
            Some(table) => parse_restir(source, table)?,
            None => defaults.restir,
        },
    })
}

fn parse_restir(source: &Source, table: &toml::Table) -> Result<RestirSettings> {
    let f = Fields::new(source, "[integrator.restir]".into(), table, RESTIR_KEYS)?;
    let d = RestirSettings::default();
    Ok(RestirSettings {
        candidates: f.u32_in("candidates", Some(d.candidates), 1..=4096)?,
        temporal: f.opt_bool("temporal")?.unwrap_or(d.temporal),
        temporal_limit: f.u32_in("temporal_limit", Some(d.temporal_limit), 1..=1024)?,
        spatial_neighbors: f.u32_in(
            "spatial_neighbors",
            Some(d.spatial_neighbors),
            0..=MAX_SPATIAL_NEIGHBORS,
        )?,
        spatial_radius_px: f.f32_in(
            "spatial_radius_px",
            Some(d.spatial_radius_px),
            0.0..=f64::from(MAX_IMAGE_SIDE),
        )?,
        spatial_rounds: f.u32_in("spatial_rounds", Some(d.spatial_rounds), 0..=16)?,
        reuse: f.choice(
            "reuse",
            Some(d.reuse),
            &[
                ("direction", ReuseMode::Direction),
                ("vertex", ReuseMode::Vertex),
            ],
        )?,
        mip_candidates: f.u32_in("mip_candidates", Some(d.mip_candidates), 0..=16)?,
        mip_indirect: f.u32_in("mip_indirect", Some(d.mip_indirect), 0..=16)?,
        mip_reuse: f.u32_in("mip_reuse", Some(d.mip_reuse), 0..=16)?,
        final_ratio_tracking: f.choice(
            "final_transmittance",
            Some(d.final_ratio_tracking),
            &[("analytic", false), ("ratio", true)],
        )?,
    })
}
