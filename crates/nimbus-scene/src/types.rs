//! The validated, in-memory form of a scene file (`shared/SCENE_FORMAT.md`).
//!
//! Everything here is already checked: directions are normalized, colours expanded to
//! RGB, paths resolved against the scene file's directory, ranges validated. Code that
//! holds a [`Scene`] never re-validates.

use std::path::PathBuf;

use glam::{Mat3, Vec2, Vec3};

/// A whole scene, as loaded from one TOML file.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// The file the scene came from (`<embedded>` style names for built-in scenes).
    pub source: PathBuf,
    pub render: RenderSettings,
    pub camera: Camera,
    pub lights: Vec<Light>,
    pub media: Vec<Medium>,
    pub shapes: Vec<Shape>,
    pub integrator: Integrator,
}

/// `[render]`.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    pub frames: u32,
    pub spp: u32,
    pub seed: u64,
    /// Nimbus setting `[render] pixel_jitter` (default true): jitter camera rays over
    /// the pixel footprint (box filter). False shoots every ray through the pixel
    /// centre — the radiance at the centre instead of the footprint mean, for tests
    /// and estimator studies that need the same camera ray in every sample.
    pub pixel_jitter: bool,
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            width: 256,
            height: 256,
            frames: 1,
            spp: 1,
            seed: 0,
            pixel_jitter: true,
        }
    }
}

/// `[camera]`: a pinhole camera.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    pub position: Vec3,
    pub look_at: Vec3,
    /// Normalized.
    pub up: Vec3,
    /// Full horizontal field of view in degrees, in (0, 180).
    pub horizontal_fov_deg: f32,
    /// Sorted by `frame`, frames unique.
    pub keyframes: Vec<CameraKeyframe>,
}

/// `[[camera.keyframe]]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraKeyframe {
    pub frame: u32,
    pub position: Vec3,
    pub look_at: Vec3,
}

/// The orthonormal frame a camera renders with at one frame of an animation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraFrame {
    pub position: Vec3,
    /// Unit vector towards `look_at`.
    pub forward: Vec3,
    /// Unit vector, image right = normalize(cross(forward, up)).
    pub right: Vec3,
    /// Unit vector, image up = cross(right, forward).
    pub up: Vec3,
    /// tan(horizontal_fov / 2).
    pub tan_half_fov_x: f32,
}

/// `[[light]]`.
#[derive(Clone, Debug, PartialEq)]
pub enum Light {
    /// Collimated light. `direction` (normalized) is the direction the light travels.
    Directional {
        direction: Vec3,
        /// W/m² on a surface perpendicular to the beam.
        irradiance: Vec3,
        gobo: Option<Gobo>,
    },
    /// Environment light: `radiance` times the optional equirectangular `file`
    /// (times `scale`).
    Environment {
        radiance: Vec3,
        file: Option<PathBuf>,
        scale: Vec3,
    },
    Point {
        position: Vec3,
        /// W/sr.
        intensity: Vec3,
    },
    Sphere {
        center: Vec3,
        radius: f32,
        radiance: Vec3,
    },
}

/// A convex polygon in the plane perpendicular to a directional light's direction
/// through `origin`. Light passes only inside it.
#[derive(Clone, Debug, PartialEq)]
pub struct Gobo {
    /// Counter-clockwise (re-ordered by the loader if given clockwise), at least 3
    /// points, convex, non-zero area. Coordinates in metres along [`Gobo::basis`].
    pub polygon: Vec<Vec2>,
    pub origin: Vec3,
}

/// `[[medium]]`.
#[derive(Clone, Debug, PartialEq)]
pub enum Medium {
    Box(BoxMedium),
    Grid(GridMedium),
}

/// A homogeneous box medium.
#[derive(Clone, Debug, PartialEq)]
pub struct BoxMedium {
    pub center: Vec3,
    /// Full extents, all > 0.
    pub size: Vec3,
    /// Degrees about X, then Y, then Z.
    pub rotation_deg: Vec3,
    /// Extinction in 1/m, >= 0.
    pub sigma_t: f32,
    /// Single-scattering albedo per channel in [0, 1]; sigma_s = albedo * sigma_t.
    pub albedo: Vec3,
    /// Henyey–Greenstein asymmetry in (-1, 1).
    pub g: f32,
}

/// A heterogeneous voxel medium filling `bounds_min .. bounds_max`.
#[derive(Clone, Debug, PartialEq)]
pub struct GridMedium {
    pub bounds_min: Vec3,
    pub bounds_max: Vec3,
    pub density: GridSource,
    pub density_scale: f32,
    pub albedo: Vec3,
    pub g: f32,
    pub emission: Option<GridSource>,
    pub emission_scale: Vec3,
    pub velocity: Option<GridSource>,
    /// Sorted by `frame`.
    pub frames: Vec<GridFrame>,
}

/// Where a voxel grid comes from. Files are checked to exist (and, for raw files, to
/// have the size `dims` implies) by the loader; their contents are read later.
#[derive(Clone, Debug, PartialEq)]
pub enum GridSource {
    /// Raw little-endian float32, x fastest, then y, then z.
    Raw { file: PathBuf, dims: [u32; 3] },
    /// Mitsuba `.vol` grid file; dims come from its header.
    MitsubaVol { file: PathBuf },
    /// Deterministic procedural cloud.
    ProceduralCloud { dims: [u32; 3], noise_seed: u64 },
}

/// `[[medium.frame]]`: the density grid to use from `frame` on.
#[derive(Clone, Debug, PartialEq)]
pub struct GridFrame {
    pub frame: u32,
    pub density: GridSource,
}

/// `[[shape]]`: opaque Lambertian surfaces.
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    Quad {
        corner: Vec3,
        edge_u: Vec3,
        edge_v: Vec3,
        albedo: Vec3,
    },
    Box {
        center: Vec3,
        size: Vec3,
        rotation_deg: Vec3,
        albedo: Vec3,
    },
    Sphere {
        center: Vec3,
        radius: f32,
        albedo: Vec3,
    },
}

/// `[integrator]`.
#[derive(Clone, Debug, PartialEq)]
pub struct Integrator {
    /// K, the most scattering events on a path; >= 1.
    pub max_bounces: u32,
    pub volume: VolumeIntegrator,
    pub box_estimator: BoxEstimator,
    /// N_sample of the box-medium paper: samples along each camera ray taken by the
    /// box estimators (a Nimbus setting, `[integrator] box_samples`, default 16).
    pub box_samples: u32,
    pub restir: RestirSettings,
}

impl Default for Integrator {
    fn default() -> Self {
        Self {
            max_bounces: 1,
            volume: VolumeIntegrator::Restir,
            box_estimator: BoxEstimator::Mcwvds,
            box_samples: 16,
            restir: RestirSettings::default(),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VolumeIntegrator {
    Restir,
    Baseline,
}

/// The estimators of the box-medium paper.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BoxEstimator {
    Mcwvds,
    Reds,
    Rees,
    Rm,
    Mcds,
}

impl BoxEstimator {
    pub const ALL: [BoxEstimator; 5] = [Self::Mcwvds, Self::Reds, Self::Rees, Self::Rm, Self::Mcds];

    /// The name used in scene files.
    pub fn name(self) -> &'static str {
        match self {
            Self::Mcwvds => "mcwvds",
            Self::Reds => "reds",
            Self::Rees => "rees",
            Self::Rm => "rm",
            Self::Mcds => "mcds",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReuseMode {
    Direction,
    Vertex,
}

/// `[integrator.restir]`.
#[derive(Clone, Debug, PartialEq)]
pub struct RestirSettings {
    pub candidates: u32,
    pub temporal: bool,
    pub temporal_limit: u32,
    pub spatial_neighbors: u32,
    pub spatial_radius_px: f32,
    pub spatial_rounds: u32,
    pub reuse: ReuseMode,
    pub mip_candidates: u32,
    pub mip_indirect: u32,
    pub mip_reuse: u32,
}

impl Default for RestirSettings {
    fn default() -> Self {
        Self {
            candidates: 4,
            temporal: true,
            temporal_limit: 4,
            spatial_neighbors: 3,
            spatial_radius_px: 10.0,
            spatial_rounds: 1,
            reuse: ReuseMode::Direction,
            mip_candidates: 1,
            mip_indirect: 2,
            mip_reuse: 1,
        }
    }
}

/// Rotation matrix for `rotation_deg` = [rx, ry, rz]: about X, then Y, then Z, so
/// world = Rz · Ry · Rx · local.
pub fn rotation_xyz_deg(rotation_deg: Vec3) -> Mat3 {
    let r = rotation_deg * (std::f32::consts::PI / 180.0);
    Mat3::from_rotation_z(r.z) * Mat3::from_rotation_y(r.y) * Mat3::from_rotation_x(r.x)
}

impl Gobo {
    /// The (u, v) axes of a gobo's plane for a light travelling along `direction`
    /// (unit). They are the camera convention seen looking along the beam: u =
    /// normalize(cross(direction, up_ref)) ("right"), v = cross(u, direction) ("up"),
    /// with up_ref = +Y, or -Z when the beam is within ~2.6° of vertical
    /// (|direction.y| > 0.999), so a sun straight down has u = +X, v = -Z.
    pub fn basis(direction: Vec3) -> (Vec3, Vec3) {
        let up_ref = if direction.y.abs() > 0.999 {
            Vec3::NEG_Z
        } else {
            Vec3::Y
        };
        let u = direction.cross(up_ref).normalize();
        let v = u.cross(direction);
        (u, v)
    }
}

impl Camera {
    /// The camera's frame at `frame`, with keyframes linearly interpolated (clamped
    /// outside the keyed range). Without keyframes it is the static camera.
    pub fn frame_at(&self, frame: u32) -> CameraFrame {
        let (position, look_at) = self.pose_at(frame);
        let forward = (look_at - position).normalize();
        let right = forward.cross(self.up).normalize();
        let up = right.cross(forward);
        CameraFrame {
            position,
            forward,
            right,
            up,
            tan_half_fov_x: (self.horizontal_fov_deg.to_radians() * 0.5).tan(),
        }
    }

    /// The camera's (position, look_at) at `frame`: keyframes linearly interpolated,
    /// clamped outside the keyed range; the static pose without keyframes.
    pub fn pose_at(&self, frame: u32) -> (Vec3, Vec3) {
        let keys = &self.keyframes;
        let Some(first) = keys.first() else {
            return (self.position, self.look_at);
        };
        if frame <= first.frame {
            return (first.position, first.look_at);
        }
        for pair in keys.windows(2) {
            let (a, b) = (pair[0], pair[1]);
            if frame <= b.frame {
                let s = (frame - a.frame) as f32 / (b.frame - a.frame) as f32;
                return (a.position.lerp(b.position, s), a.look_at.lerp(b.look_at, s));
            }
        }
        let last = keys[keys.len() - 1];
        (last.position, last.look_at)
    }
}

impl CameraFrame {
    /// World-space unit direction through image-plane point (px, py) in pixels, (0, 0)
    /// the top-left corner of the image, for an image of `width` x `height`.
    pub fn ray_direction(&self, px: f32, py: f32, width: u32, height: u32) -> Vec3 {
        let tan_y = self.tan_half_fov_x * height as f32 / width as f32;
        let sx = (2.0 * px / width as f32 - 1.0) * self.tan_half_fov_x;
        let sy = (1.0 - 2.0 * py / height as f32) * tan_y;
        (self.forward + sx * self.right + sy * self.up).normalize()
    }
}
