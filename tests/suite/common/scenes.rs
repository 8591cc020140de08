//! Scene sections (TOML text) that several tests share, each in one place: a test's own
//! literal then shows only what it varies. Each piece is whole lines without a trailing
//! newline; place it on its own line of a `format!` (`{LOW_CLOUD}`).

/// The sun and the blue sky over the ±(1, 0.6, 1) cloud of the pyro and overlap tests:
/// the sun is seen only through the medium, the sky also directly.
pub const CLOUD_SUN_AND_SKY: &str = r#"[[light]]
type = "directional"
direction = [0.5, -0.7, -0.4]
irradiance = 2.0
[[light]]
type = "environment"
radiance = [0.2, 0.3, 0.5]"#;

/// The box the oracle's clouds fill: ±(1, 0.6, 1) about the origin.
pub const CLOUD_BOUNDS: &str = "bounds_min = [-1.0, -0.6, -1.0]\nbounds_max = [1.0, 0.6, 1.0]";

/// The steep sun and grey sky of the sparse-grid and VDB twin renders.
pub const STEEP_SUN_AND_GREY_SKY: &str = r#"[[light]]
type = "directional"
direction = [0.4, -0.8, -0.5]
irradiance = 3.0
[[light]]
type = "environment"
radiance = 0.2"#;

/// The camera looking down at the small cloud above the floor (emitters, gobos).
pub const LOW_CLOUD_CAMERA: &str = r#"[camera]
position = [0.4, 1.5, 4.0]
look_at = [0.0, 0.6, 0.0]
horizontal_fov_deg = 55"#;

/// A small procedural cloud between 0.4 and 1.1 above the floor (emitters, gobos).
pub const LOW_CLOUD: &str = r#"[[medium]]
type = "grid"
bounds_min = [-0.9, 0.4, -0.8]
bounds_max = [0.7, 1.1, 0.6]
density = { procedural = "cloud", dims = [16, 8, 16], noise_seed = 5 }
density_scale = 8.0
albedo = 0.85
g = 0.3"#;

/// The 6 m floor under [`LOW_CLOUD`], facing up, albedo 0.6.
pub const LOW_CLOUD_FLOOR: &str = r#"[[shape]]
type = "quad"
corner = [-3, 0, -3]
edge_u = [0, 0, 6]
edge_v = [6, 0, 0]
albedo = 0.6"#;

/// `[render]` (8x8, 32 frames of 4 spp), a 70° camera at `position` looking at
/// `look_at`, and a directional light of irradiance 1 along `direction`: the small
/// analytic probes of boxes and convex media against quadrature.
pub fn probe_header(position: [f64; 3], look_at: [f64; 3], direction: [f64; 3]) -> String {
    format!(
        r#"[render]
width = 8
height = 8
frames = 32
spp = 4
[camera]
position = {position:?}
look_at = {look_at:?}
horizontal_fov_deg = 70
[[light]]
type = "directional"
direction = {direction:?}
irradiance = 1.0"#
    )
}
