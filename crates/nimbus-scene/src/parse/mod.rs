//! Scene file → validated [`Scene`]: one function per table of `docs/scene-format.md`.

use std::path::Path;

use anyhow::Result;
use glam::{DVec3, Vec3};
use toml::Value;

use crate::convex::Solid;
use crate::fields::{
    open_interval, positive_up_to, radiometric, type_name, unit_interval, Fields, Source,
};
use crate::files::file_size;
use crate::geometry::convex_ccw_polygon;
use crate::overrides::FieldOverride;
use crate::types::*;

mod lights;
mod media;
mod mesh;
mod vdb;

use lights::parse_light;
use media::parse_medium;

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
const RENDER_KEYS: &[&str] = &[
    "width",
    "height",
    "frames",
    "spp",
    "seed",
    "pixel_jitter",
    "transparent_background",
    "aovs",
];
const CAMERA_KEYS: &[&str] = &[
    "position",
    "look_at",
    "up",
    "horizontal_fov_deg",
    "keyframe",
];
const KEYFRAME_KEYS: &[&str] = &["frame", "position", "look_at"];
const SHAPE_TYPES: &[(&str, &[&str])] = &[
    (
        "quad",
        &["type", "corner", "edge_u", "edge_v", "albedo", "emission"],
    ),
    (
        "box",
        &[
            "type",
            "center",
            "size",
            "rotation_deg",
            "albedo",
            "emission",
        ],
    ),
    (
        "sphere",
        &["type", "center", "radius", "albedo", "emission"],
    ),
    ("mesh", mesh::MESH_KEYS),
];
const INTEGRATOR_KEYS: &[&str] = &[
    "max_bounces",
    "volume",
    "box_estimator",
    "box_samples",
    "moment_map_size",
    "restir",
    "baseline",
];
/// The fields of `[integrator.baseline]`.
pub const BASELINE_KEYS: &[&str] = &["nee", "density_fetch"];
/// The fields of `[integrator.restir]`.
pub const RESTIR_KEYS: &[&str] = &[
    "candidates",
    "candidates_settled",
    "temporal",
    "temporal_limit",
    "temporal_limit_moving",
    "spatial_neighbors",
    "spatial_radius_px",
    "spatial_when",
    "spatial_rounds",
    "reuse",
    "mip_candidates",
    "mip_indirect",
    "mip_reuse",
    "final_transmittance",
    "mis",
    "spatial_shift",
    "env_reuse",
    "emission",
    "spatial_max_history",
    "spatial_feature_tolerance",
    "spatial_anchor",
    "shade_cache",
    "still_target",
    "temporal_history",
    "sigma_star_floor",
    "nee",
    "direct",
    "candidate_tracking",
    "pc_fetch",
    "density_fetch",
    "target",
    "camera_emission",
    "temporal_reprojection",
    "temporal_shift",
];

/// One table of the scene format and every field the parser accepts in it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TableFields {
    /// The table as `docs/scene-format.md` heads it: `[render]`, `[[light]] type =
    /// "point"`, `[[light.keyframe]] of a "sphere" light`, `grid source`, ...
    pub table: String,
    pub fields: Vec<&'static str>,
}

/// Every table of the scene format with the fields the parser accepts in it, from the
/// same lists the parser checks unknown fields against (so the reference
/// documentation can be tested against them).
pub fn scene_tables() -> Vec<TableFields> {
    let table = |name: &str, fields: &[&'static str]| TableFields {
        table: name.to_string(),
        fields: fields.to_vec(),
    };
    let mut tables = vec![
        table("top level", TOP_KEYS),
        table("[render]", RENDER_KEYS),
        table("[camera]", CAMERA_KEYS),
        table("[[camera.keyframe]]", KEYFRAME_KEYS),
    ];
    for (kind, fields) in lights::LIGHT_TYPES {
        tables.push(table(&format!("[[light]] type = \"{kind}\""), fields));
    }
    for (kind, fields) in lights::LIGHT_KEYFRAME_KEYS {
        let article = if kind.starts_with(['a', 'e', 'i', 'o', 'u']) {
            "an"
        } else {
            "a"
        };
        tables.push(table(
            &format!("[[light.keyframe]] of {article} \"{kind}\" light"),
            fields,
        ));
    }
    for (kind, fields) in media::MEDIUM_TYPES {
        tables.push(table(&format!("[[medium]] type = \"{kind}\""), fields));
    }
    tables.push(table("grid source", media::GRID_KEYS));
    tables.push(table("[[medium.frame]]", media::GRID_FRAME_KEYS));
    for (kind, fields) in SHAPE_TYPES {
        tables.push(table(&format!("[[shape]] type = \"{kind}\""), fields));
    }
    tables.push(table("[integrator]", INTEGRATOR_KEYS));
    tables.push(table("[integrator.restir]", RESTIR_KEYS));
    tables.push(table("[integrator.baseline]", BASELINE_KEYS));
    tables
}

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

    let mut lights = Vec::new();
    let mut light_keyframes = Vec::new();
    let mut light_groups = Vec::new();
    let mut group_names: Vec<String> = Vec::new();
    for (i, table) in top.tables("light")?.into_iter().enumerate() {
        let (light, keys, group) = parse_light(&source, i + 1, table)?;
        if let Some(name) = &group {
            if !group_names.contains(name) {
                group_names.push(name.clone());
            }
            // Named groups and `default` (which a scene may need for its other lights,
            // its emitting media and shapes) together.
            let named = group_names
                .iter()
                .filter(|g| g.as_str() != DEFAULT_LIGHT_GROUP)
                .count();
            if named >= MAX_LIGHT_GROUPS {
                return Err(source.error(format!(
                    "[[light]] #{}: field `group`: \"{name}\" is light group {} of the scene \
                     besides \"{DEFAULT_LIGHT_GROUP}\"; at most {} named groups are allowed \
                     ({MAX_LIGHT_GROUPS} with \"{DEFAULT_LIGHT_GROUP}\")",
                    i + 1,
                    named,
                    MAX_LIGHT_GROUPS - 1
                )));
            }
        }
        lights.push(light);
        light_keyframes.push(keys);
        light_groups.push(group);
    }

    let mut media = Vec::new();
    let mut medium_bounds: Vec<(String, Solid)> = Vec::new();
    for (i, table) in top.tables("medium")?.into_iter().enumerate() {
        let (medium, name, bounds) = parse_medium(&source, i + 1, table)?;
        media.push(medium);
        medium_bounds.push((name, bounds));
    }
    // Which media share volume (touching is not sharing): the integrators decide what
    // they render.
    let mut overlaps = Vec::new();
    for (i, (_, a)) in medium_bounds.iter().enumerate() {
        for (j, (_, b)) in medium_bounds.iter().enumerate().skip(i + 1) {
            if a.overlaps(b) {
                overlaps.push((i, j));
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
        light_groups,
        media,
        overlaps,
        shapes,
        integrator,
    };
    crate::precision::check_scene(&source, &scene)?;
    check_camera_outside_sphere_lights(&source, &scene)?;
    Ok(scene)
}

/// A sphere light emits outwards only, so nothing inside one is lit by it; a camera
/// inside one would still see its inner side (issue 24: radiance 4 in view, the cloud
/// beside the camera at 0.06). Refused at every frame the camera or the light moves to,
/// naming the light: an environment light is light from all around.
fn check_camera_outside_sphere_lights(source: &Source, scene: &Scene) -> Result<()> {
    let frames = if scene.camera.keyframes.is_empty() && !scene.lights_animated() {
        1
    } else {
        scene.render.frames
    };
    let has_sphere = scene
        .lights
        .iter()
        .any(|l| matches!(l, Light::Sphere { .. }));
    if !has_sphere {
        return Ok(());
    }
    for frame in 0..frames {
        let eye = scene.camera.frame_at(frame).position;
        let lights = if scene.lights_animated() {
            scene.lights_at(frame)
        } else {
            scene.lights.clone()
        };
        for (i, light) in lights.iter().enumerate() {
            if let Light::Sphere { center, radius, .. } = light {
                let d = (eye - *center).length();
                if d < *radius {
                    return Err(source.error(format!(
                        "[[light]] #{} (type = \"sphere\"): the camera is inside it at frame \
                         {frame} ({d} m from its centre {:?}, radius {radius}); a sphere \
                         light emits outwards only, so nothing inside it is lit by it: for \
                         light from all around use type = \"environment\"",
                        i + 1,
                        center.to_array()
                    )));
                }
            }
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
        transparent_background: f
            .opt_bool("transparent_background")?
            .unwrap_or(defaults.transparent_background),
        aovs: parse_aovs(&f)?,
    })
}

/// `[render] aovs`: an array of AOV names ([`Aov::parse_list`]).
fn parse_aovs(f: &Fields) -> Result<Vec<Aov>> {
    let Some(value) = f.value("aovs") else {
        return Ok(Vec::new());
    };
    let Value::Array(items) = value else {
        return Err(f.error(
            "aovs",
            format!(
                "expected an array of AOV names such as [\"depth\", \"normal\"], found {}; \
                 valid names: {}",
                type_name(value),
                Aov::valid_names()
            ),
        ));
    };
    let mut names = Vec::with_capacity(items.len());
    for item in items {
        match item {
            Value::String(s) => names.push(s.as_str()),
            other => {
                return Err(f.error(
                    "aovs",
                    format!(
                        "expected AOV names (strings), found {}; valid names: {}",
                        type_name(other),
                        Aov::valid_names()
                    ),
                ))
            }
        }
    }
    Aov::parse_list(names).map_err(|message| f.error("aovs", message))
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
pub(super) fn typed_fields<'a>(
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

/// Resolves `name` (field `key`) against the scene's directory and checks that it is
/// an existing file, with extension `extension` (case-insensitive) when given.
pub(super) fn existing_file(
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
pub(super) fn size3(f: &Fields, key: &str) -> Result<Vec3> {
    let size = f.vec3_f64(key, None)?;
    let size32 = size.as_vec3();
    for axis in 0..3 {
        // The f32 the renderer sees must pass too (1e-46 rounds to 0).
        let problem = positive_up_to(MAX_LENGTH_M)(size[axis])
            .or_else(|| positive_up_to(MAX_LENGTH_M)(f64::from(size32[axis])));
        if let Some(message) = problem {
            return Err(f.error(
                key,
                format!(
                    "component {axis} is {} ({} as a 32-bit float), {message}",
                    size[axis], size32[axis]
                ),
            ));
        }
    }
    Ok(size32)
}

fn parse_shape(source: &Source, index: usize, table: &toml::Table) -> Result<Shape> {
    let (kind, f) = typed_fields(source, "shape", index, table, SHAPE_TYPES)?;
    let albedo = f.color("albedo", Some(Vec3::ZERO), unit_interval)?;
    // An area light's radiance; zero (the default) for a shape that does not emit.
    let emission = f.color("emission", Some(Vec3::ZERO), radiometric)?;
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
                emission,
            }
        }
        "box" => Shape::Box {
            center: f.vec3("center", None)?,
            size: size3(&f, "size")?,
            rotation_deg: f.angles_deg("rotation_deg", Some(DVec3::ZERO))?.as_vec3(),
            albedo,
            emission,
        },
        "sphere" => Shape::Sphere {
            center: f.vec3("center", None)?,
            radius: f.f32_with("radius", None, positive_up_to(MAX_LENGTH_M))?,
            albedo,
            emission,
        },
        _ => mesh::parse_mesh_shape(&f, albedo, emission)?,
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
        moment_map_size: moment_map_size(&f, defaults.moment_map_size)?,
        restir: match f.opt_table("restir")? {
            Some(table) => parse_restir(source, table)?,
            None => defaults.restir,
        },
        baseline: match f.opt_table("baseline")? {
            Some(table) => parse_baseline(source, table)?,
            None => defaults.baseline,
        },
    })
}

fn nee_choice(f: &Fields, default: NeeMode) -> Result<NeeMode> {
    f.choice(
        "nee",
        Some(default),
        &[
            ("auto", NeeMode::Auto),
            ("one", NeeMode::One),
            ("split", NeeMode::Split),
        ],
    )
}

/// The choices of every `*_fetch` field (`density_fetch`, `pc_fetch`).
const FETCH_CHOICES: &[(&str, DensityFetch)] = &[
    ("auto", DensityFetch::Auto),
    ("image", DensityFetch::Image),
    ("buffer", DensityFetch::Buffer),
];

fn parse_baseline(source: &Source, table: &toml::Table) -> Result<BaselineSettings> {
    let f = Fields::new(source, "[integrator.baseline]".into(), table, BASELINE_KEYS)?;
    let d = BaselineSettings::default();
    Ok(BaselineSettings {
        nee: nee_choice(&f, d.nee)?,
        density_fetch: f.choice("density_fetch", Some(d.density_fetch), FETCH_CHOICES)?,
    })
}

fn parse_restir(source: &Source, table: &toml::Table) -> Result<RestirSettings> {
    let f = Fields::new(source, "[integrator.restir]".into(), table, RESTIR_KEYS)?;
    let d = RestirSettings::default();
    Ok(RestirSettings {
        candidates: f.u32_in("candidates", Some(d.candidates), 1..=4096)?,
        candidates_settled: f.u32_in("candidates_settled", Some(d.candidates_settled), 1..=4096)?,
        temporal: f.bool_or_auto("temporal", d.temporal)?,
        temporal_limit: f.u32_or_auto("temporal_limit", d.temporal_limit, 1..=1024)?,
        temporal_limit_moving: f.u32_in(
            "temporal_limit_moving",
            Some(d.temporal_limit_moving),
            1..=1024,
        )?,
        spatial_neighbors: f.u32_in(
            "spatial_neighbors",
            Some(d.spatial_neighbors),
            0..=MAX_SPATIAL_NEIGHBORS,
        )?,
        spatial_radius_px: f.f32_or_auto(
            "spatial_radius_px",
            d.spatial_radius_px,
            0.0..=f64::from(MAX_IMAGE_SIDE),
        )?,
        spatial_when: f.choice(
            "spatial_when",
            Some(d.spatial_when),
            &[
                ("always", SpatialWhen::Always),
                ("camera_moves", SpatialWhen::CameraMoves),
                ("camera_or_density", SpatialWhen::CameraOrDensity),
            ],
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
        mip_indirect: f.u32_or_auto("mip_indirect", d.mip_indirect, 0..=16)?,
        mip_reuse: f.u32_or_auto("mip_reuse", d.mip_reuse, 0..=16)?,
        final_ratio_tracking: f.choice(
            "final_transmittance",
            Some(d.final_ratio_tracking),
            &[("analytic", false), ("ratio", true)],
        )?,
        mis: f.choice(
            "mis",
            Some(d.mis),
            &[("talbot", MisMode::Talbot), ("pairwise", MisMode::Pairwise)],
        )?,
        fold_emission: f.choice(
            "emission",
            Some(d.fold_emission),
            &[("separate", false), ("folded", true)],
        )?,
        spatial_max_history: f.f32_in(
            "spatial_max_history",
            Some(d.spatial_max_history),
            0.0..=1025.0,
        )?,
        spatial_feature_tolerance: f.f32_in(
            "spatial_feature_tolerance",
            Some(d.spatial_feature_tolerance),
            0.0..=1.0,
        )?,
        spatial_anchor: f.opt_bool("spatial_anchor")?.unwrap_or(d.spatial_anchor),
        shade_cache: f.opt_bool("shade_cache")?.unwrap_or(d.shade_cache),
        still_target: f.choice(
            "still_target",
            Some(d.still_target),
            &[
                ("auto", StillTarget::Auto),
                ("initial", StillTarget::Initial),
                ("reuse", StillTarget::Reuse),
            ],
        )?,
        spatial_shift: f.choice(
            "spatial_shift",
            Some(d.spatial_shift),
            &[
                ("distance", SpatialShift::Distance),
                ("optical_depth", SpatialShift::OpticalDepth),
                ("optical_depth_exact", SpatialShift::ExactOpticalDepth),
            ],
        )?,
        env_reuse: f.choice(
            "env_reuse",
            Some(d.env_reuse),
            &[("map", EnvReuse::Map), ("world", EnvReuse::World)],
        )?,
        temporal_history: f.choice(
            "temporal_history",
            Some(d.temporal_history),
            &[
                ("spatial", HistoryMode::Spatial),
                ("temporal", HistoryMode::Temporal),
            ],
        )?,
        sigma_star_floor: f.f32_in("sigma_star_floor", Some(d.sigma_star_floor), 0.0..=1.0)?,
        nee: nee_choice(&f, d.nee)?,
        direct: f.choice(
            "direct",
            Some(d.direct),
            &[
                ("each_walk", DirectMode::EachWalk),
                ("escape", DirectMode::Escape),
            ],
        )?,
        candidate_tracking: f.choice(
            "candidate_tracking",
            Some(d.candidate_tracking),
            &[
                ("auto", CandidateTracking::Auto),
                ("delta", CandidateTracking::Delta),
                ("regular", CandidateTracking::Regular),
            ],
        )?,
        pc_fetch: f.choice("pc_fetch", Some(d.pc_fetch), FETCH_CHOICES)?,
        density_fetch: f.choice("density_fetch", Some(d.density_fetch), FETCH_CHOICES)?,
        target: f.choice(
            "target",
            Some(d.target),
            &[
                ("luminance", TargetScalar::Luminance),
                ("sum", TargetScalar::Sum),
                ("max", TargetScalar::Max),
            ],
        )?,
        camera_emission: f.choice(
            "camera_emission",
            Some(d.camera_emission),
            &[
                ("reservoir", CameraEmission::Reservoir),
                ("stratified", CameraEmission::Stratified),
            ],
        )?,
        temporal_reprojection: f.choice(
            "temporal_reprojection",
            Some(d.temporal_reprojection),
            &[
                ("path", TemporalReprojection::Path),
                ("aligned", TemporalReprojection::Aligned),
            ],
        )?,
        temporal_shift: f.choice(
            "temporal_shift",
            Some(d.temporal_shift),
            &[
                ("anchor", TemporalShift::Anchor),
                ("optical_depth", TemporalShift::OpticalDepth),
            ],
        )?,
    })
}

/// `moment_map_size`: a power of two in 16..=4096 (the moment maps' mip chain halves it).
fn moment_map_size(f: &Fields, default: u32) -> Result<u32> {
    let size = f.u32_in("moment_map_size", Some(default), 16..=4096)?;
    if !size.is_power_of_two() {
        return Err(f.error("moment_map_size", format!("{size} is not a power of two")));
    }
    Ok(size)
}
