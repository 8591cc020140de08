//! The validated, in-memory form of a scene file (`docs/scene-format.md`).
//!
//! Everything here is already checked: directions are normalized, colours expanded to
//! RGB, paths resolved against the scene file's directory, ranges validated. Code that
//! holds a [`Scene`] never re-validates. What a scene is at one frame of an animation
//! (keyframes interpolated, density frames chosen) is evaluated in `animation.rs`.

use std::path::PathBuf;

use glam::{DMat3, DMat4, IVec3, Mat3, Vec2, Vec3};

/// A whole scene, as loaded from one TOML file.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// The file the scene came from (`<embedded>` style names for built-in scenes).
    pub source: PathBuf,
    pub render: RenderSettings,
    pub camera: Camera,
    pub lights: Vec<Light>,
    /// `[[light.keyframe]]` entries, indexed like `lights`: `light_keyframes[i]` animates
    /// `lights[i]` (sorted by `frame`, frames unique). The loader gives every light an
    /// entry (empty when it is not animated); a light past the end of this list (all of
    /// them when it is empty, e.g. in a scene built in code) is not animated. Use
    /// [`Scene::lights_at`] rather than reading it directly.
    pub light_keyframes: Vec<Vec<LightKeyframe>>,
    /// `[[light]] group`, indexed like `lights`: the light group of each light (`None`:
    /// the `default` group). A light past the end of this list (all of them when it is
    /// empty, e.g. in a scene built in code) is in the default group. Use
    /// [`Scene::light_group`].
    pub light_groups: Vec<Option<String>>,
    pub media: Vec<Medium>,
    /// Pairs `(i, j)`, i < j, of `media` indices that share volume (their extinctions
    /// add there): found by the loader's exact test, which lets touching media be.
    /// Integrators that take only disjoint media refuse a scene with any. A scene built
    /// in code lists its own (empty: none).
    pub overlaps: Vec<(usize, usize)>,
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
    /// Nimbus setting `[render] transparent_background` (default false): camera rays
    /// that leave the scene see nothing instead of the environment, so the image is the
    /// foreground alone, premultiplied by its alpha, ready to composite over a plate.
    /// The environment still lights the scene.
    pub transparent_background: bool,
    /// Nimbus setting `[render] aovs` (default none): the output layers (AOVs) written
    /// beside the beauty, in [`Aov::ALL`] order, each once.
    pub aovs: Vec<Aov>,
}

/// An output layer beside the beauty (`[render] aovs`, `nimbus render --aovs`). The
/// layers each writes are named in `docs/scene-format.md`, "Output layers (AOVs)".
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Aov {
    /// `Z`: camera-space depth of the first surface or of the point where the camera
    /// ray's transmittance falls to 0.5.
    Depth,
    /// `N.X N.Y N.Z`: world-space normal there.
    Normal,
    /// `albedo.R/G/B`: surface albedo or single-scattering albedo there.
    Albedo,
    /// `emission.R/G/B`: emitted radiance seen with no scattering in between.
    Emission,
    /// `direct.R/G/B`: light scattered exactly once.
    Direct,
    /// `indirect.R/G/B`: everything else.
    Indirect,
    /// `lightgroup.<name>.R/G/B` per light group.
    LightGroups,
    /// `motion.X motion.Y`: screen-space motion in pixels per frame.
    Motion,
}

impl Aov {
    /// Every AOV, in the order they are written.
    pub const ALL: [Aov; 8] = [
        Aov::Depth,
        Aov::Normal,
        Aov::Albedo,
        Aov::Emission,
        Aov::Direct,
        Aov::Indirect,
        Aov::LightGroups,
        Aov::Motion,
    ];

    /// The name `[render] aovs` and `--aovs` take.
    pub fn name(self) -> &'static str {
        match self {
            Aov::Depth => "depth",
            Aov::Normal => "normal",
            Aov::Albedo => "albedo",
            Aov::Emission => "emission",
            Aov::Direct => "direct",
            Aov::Indirect => "indirect",
            Aov::LightGroups => "lightgroups",
            Aov::Motion => "motion",
        }
    }

    /// Whether it is geometric (from the pixel-centre camera ray, overwritten each frame)
    /// rather than a path estimate accumulated like the beauty.
    pub fn is_geometric(self) -> bool {
        matches!(self, Aov::Depth | Aov::Normal | Aov::Albedo | Aov::Motion)
    }

    /// The valid names, for messages: every AOV's, then `all`.
    pub fn valid_names() -> String {
        let mut names: Vec<String> = Aov::ALL
            .iter()
            .map(|a| format!("\"{}\"", a.name()))
            .collect();
        names.push("\"all\"".to_string());
        names.join(", ")
    }

    /// Parses a list of names (`all` stands for every AOV) into AOVs in [`Aov::ALL`]
    /// order, each once; the error names the unknown one and lists the valid names.
    pub fn parse_list<'a>(names: impl IntoIterator<Item = &'a str>) -> Result<Vec<Aov>, String> {
        let mut picked = Vec::new();
        for name in names {
            let name = name.trim();
            if name == "all" {
                picked.extend(Aov::ALL);
                continue;
            }
            match Aov::ALL.iter().find(|a| a.name() == name) {
                Some(a) => picked.push(*a),
                None => {
                    return Err(format!(
                        "unknown AOV \"{name}\"; valid names: {}",
                        Aov::valid_names()
                    ))
                }
            }
        }
        picked.sort();
        picked.dedup();
        Ok(picked)
    }
}

/// The light group of lights without `group` (and of media emission and emitting
/// shapes).
pub const DEFAULT_LIGHT_GROUP: &str = "default";

/// Most light groups of a scene (named ones and `default` together).
pub const MAX_LIGHT_GROUPS: usize = 8;

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            width: 256,
            height: 256,
            frames: 1,
            spp: 1,
            seed: 0,
            pixel_jitter: true,
            transparent_background: false,
            aovs: Vec::new(),
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
    /// (times `scale`), the map turned about world +Y by `rotation_deg`
    /// ([`EnvRotation`](crate::EnvRotation) says how).
    Environment {
        radiance: Vec3,
        file: Option<PathBuf>,
        scale: Vec3,
        /// Degrees about +Y, right-handed (positive turns +X towards −Z), within one
        /// turn: [−360, 360] ([`reduce_degrees`]). Turns nothing of a constant radiance.
        rotation_deg: f32,
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

/// `[[light.keyframe]]`: a light's animatable values at `frame`. Complete: fields the
/// keyframe leaves out hold the light's static value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightKeyframe {
    pub frame: u32,
    /// Of the same type as the light it animates.
    pub state: LightState,
}

/// The animatable fields of a light (directional lights with a gobo are not
/// animatable; an environment light animates its rotation only).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightState {
    Directional {
        /// Normalized.
        direction: Vec3,
        irradiance: Vec3,
    },
    Point {
        position: Vec3,
        intensity: Vec3,
    },
    Sphere {
        center: Vec3,
        radiance: Vec3,
    },
    Environment {
        /// Degrees as written, NOT reduced to one turn, so that keyframes 350 and 370
        /// interpolate through 360 (a 20° turn); [`Light::with_state`] reduces it.
        rotation_deg: f64,
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
    /// A homogeneous convex polyhedron (`type = "convex"`).
    Convex(ConvexMedium),
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

/// A homogeneous medium filling a convex polyhedron: the intersection of the
/// half-spaces n·x <= d of `planes`. Build one with [`ConvexMedium::new`], which
/// checks the polyhedron.
#[derive(Clone, Debug, PartialEq)]
pub struct ConvexMedium {
    /// [nx, ny, nz, d] with a unit normal (normalized on load, d scaled alike) as the
    /// renderer sees them (f32); 4..=64 of them.
    pub planes: Vec<[f32; 4]>,
    /// The polyhedron of `planes` (widened to f64): its vertices, faces and edges.
    pub polyhedron: crate::convex::ConvexPolyhedron,
    /// Extinction in 1/m, >= 0.
    pub sigma_t: f32,
    /// Single-scattering albedo per channel in [0, 1]; sigma_s = albedo * sigma_t.
    pub albedo: Vec3,
    /// Henyey–Greenstein asymmetry in (-1, 1).
    pub g: f32,
}

impl ConvexMedium {
    /// The medium of the half-spaces `planes` ([nx, ny, nz, d]: n·x <= d), or why they
    /// do not bound one: fewer than 4 or more than 64 planes, a zero normal, an
    /// unbounded, empty or flat region. The normals are normalized (d scaled alike) and
    /// rounded to f32; the polyhedron is that of the rounded planes.
    pub fn new(planes: &[[f64; 4]], sigma_t: f32, albedo: Vec3, g: f32) -> Result<Self, String> {
        use crate::convex::{ConvexPolyhedron, MAX_CONVEX_PLANES, MIN_CONVEX_PLANES};
        if !(MIN_CONVEX_PLANES..=MAX_CONVEX_PLANES).contains(&planes.len()) {
            return Err(format!(
                "{} planes; a convex medium takes {MIN_CONVEX_PLANES} to {MAX_CONVEX_PLANES}",
                planes.len()
            ));
        }
        let unit = ConvexPolyhedron::new(planes)?;
        let rounded: Vec<[f32; 4]> = unit
            .planes
            .iter()
            .map(|(n, d)| [n.x as f32, n.y as f32, n.z as f32, *d as f32])
            .collect();
        let widened: Vec<[f64; 4]> = rounded.iter().map(|p| p.map(f64::from)).collect();
        let polyhedron = ConvexPolyhedron::new(&widened)?;
        Ok(Self {
            planes: rounded,
            polyhedron,
            sigma_t,
            albedo,
            g,
        })
    }
}

/// A heterogeneous voxel medium filling the box `bounds_min .. bounds_max`: `type =
/// "grid"`, or `type = "vdb"` (`vdb` is `Some`, every source a [`GridSource::Vdb`] with
/// the same [`VdbWindow`]), whose box is then its window's voxels in the world.
#[derive(Clone, Debug, PartialEq)]
pub struct GridMedium {
    pub bounds_min: Vec3,
    pub bounds_max: Vec3,
    pub density: GridSource,
    pub density_scale: f32,
    /// The single-scattering albedo: this colour (1 with `albedo_grid`) times the
    /// albedo grid's value, if there is one.
    pub albedo: Vec3,
    /// `albedo` given as a grid source: 1 channel (grey) or 3 (rgb), values in [0, 1].
    pub albedo_grid: Option<GridSource>,
    pub g: f32,
    pub emission: Option<GridSource>,
    pub emission_scale: Vec3,
    /// Blackbody emission (pyro shading), added to the emission grid's.
    pub temperature: Option<Box<Temperature>>,
    pub velocity: Option<GridSource>,
    /// The velocity grid's values times this are metres per frame (1: the file holds
    /// metres per frame; 1/24 for metres per second at 24 frames per second).
    pub velocity_scale: f32,
    /// Sorted by `frame`.
    pub frames: Vec<GridFrame>,
    /// `type = "vdb"`: where its index space sits (every source is then
    /// [`GridSource::Vdb`]); `None` for `type = "grid"`.
    pub vdb: Option<Box<VdbPlacement>>,
}

/// A grid medium's `temperature` and how it glows: Le(x) = `blackbody_scale` ·
/// RGB(T(x)) ([`crate::blackbody`]), T(x) = `offset` + `scale` · (the trilinear
/// temperature grid at x) kelvin, in the absorbed-emission convention of `emission`.
#[derive(Clone, Debug, PartialEq)]
pub struct Temperature {
    /// A scalar grid (values finite and ≥ 0) on the medium's box, like `emission`.
    pub source: GridSource,
    /// `temperature_offset`, kelvin.
    pub offset: f32,
    /// `temperature_scale`, kelvin per grid unit (≥ 0).
    pub scale: f32,
    /// `blackbody_scale` (≥ 0).
    pub blackbody_scale: f32,
}

/// Where a `type = "vdb"` medium sits, read from its files when the scene loads.
#[derive(Clone, Debug, PartialEq)]
pub struct VdbPlacement {
    /// The scene's `to_world` (identity without one), applied after each grid's own
    /// index-to-world transform.
    pub to_world: DMat4,
    /// The density grid's index-to-world transform with `to_world` applied (column
    /// vectors): voxel (i, j, k)'s value sits at `index_to_world · (i, j, k, 1)`. Every
    /// `[[medium.frame]]` density, the emission and the velocity share it. Any invertible
    /// affine map (rotated, mirrored or sheared).
    pub index_to_world: DMat4,
    /// Inclusive index-space bounds of the density's active voxels, over every frame.
    /// The medium's extent is this box grown by one voxel (where trilinear filtering
    /// reaches).
    pub active_bbox: (IVec3, IVec3),
}

impl VdbPlacement {
    /// The world length of one index step along each index axis.
    pub fn voxel_size(&self) -> [f64; 3] {
        [
            self.index_to_world.x_axis.truncate().length(),
            self.index_to_world.y_axis.truncate().length(),
            self.index_to_world.z_axis.truncate().length(),
        ]
    }
}

/// Which procedural cloud a `procedural` grid is.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ProceduralKind {
    /// `"cloud"`: a noisy ellipsoid (`procedural.rs`), the test cloud.
    #[default]
    Cloud,
    /// `"cumulus"`: a cumulus congestus of puffs, billows and wisps (`cumulus.rs`).
    Cumulus,
}

/// Where a voxel grid comes from. Files are checked to exist (and, for raw files, to
/// have the size `dims` implies) by the loader; their contents are read later.
#[derive(Clone, Debug, PartialEq)]
pub enum GridSource {
    /// Raw little-endian float32, x fastest, then y, then z.
    Raw { file: PathBuf, dims: [u32; 3] },
    /// Mitsuba `.vol` grid file; dims come from its header.
    MitsubaVol { file: PathBuf },
    /// Deterministic procedural cloud of `kind`.
    ProceduralCloud {
        dims: [u32; 3],
        noise_seed: u64,
        kind: ProceduralKind,
    },
    /// One grid of an OpenVDB file (`type = "vdb"` media): the one named `grid`, else the
    /// file's only grid of the kind needed, else (scalars) the one named "density". It
    /// loads as the dense grid `window` cuts out of it.
    Vdb {
        file: PathBuf,
        grid: Option<String>,
        window: Box<VdbWindow>,
    },
}

/// The dense grid a `type = "vdb"` medium's grids load into: the lattice points of the
/// density's active bounding box (over every frame) grown by one voxel, so that the
/// trilinear field falls to the background 0 at its faces. Dense voxel `d` (cell-centred
/// in the medium's `bounds_min .. bounds_max`) holds the grid's voxel `origin + d`, with
/// axis `a` reversed (`origin + dims − 1 − d`) where `flip[a]` (a negative scale).
#[derive(Clone, Debug, PartialEq)]
pub struct VdbWindow {
    pub origin: IVec3,
    pub dims: [u32; 3],
    pub flip: [bool; 3],
    /// Maps the vectors of a vec3 (velocity) grid from the file's world to the scene's:
    /// the linear part of `to_world`.
    pub vector_map: DMat3,
}

/// `[[medium.frame]]`: the density grid to use from `frame` on, and optionally the
/// temperature, albedo and emission grids (each `None`: the last one given at or before
/// it holds, else the medium's own).
#[derive(Clone, Debug, PartialEq)]
pub struct GridFrame {
    pub frame: u32,
    pub density: GridSource,
    pub temperature: Option<GridSource>,
    pub albedo: Option<GridSource>,
    pub emission: Option<GridSource>,
}

/// `[[shape]]`: opaque Lambertian surfaces. Each may emit: `emission` (W/(m²·sr), zero
/// for none) makes it a Lambertian area light, one-sided for a quad (towards
/// edge_u × edge_v) and a mesh triangle (towards its counter-clockwise normal), outwards
/// for a box or a sphere.
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    Quad {
        corner: Vec3,
        edge_u: Vec3,
        edge_v: Vec3,
        albedo: Vec3,
        emission: Vec3,
    },
    Box {
        center: Vec3,
        size: Vec3,
        rotation_deg: Vec3,
        albedo: Vec3,
        emission: Vec3,
    },
    Sphere {
        center: Vec3,
        radius: f32,
        albedo: Vec3,
        emission: Vec3,
    },
    /// A triangle mesh, loaded with its BVH when the scene loads and shared by every
    /// copy of the scene.
    Mesh {
        mesh: std::sync::Arc<crate::mesh::MeshShape>,
        albedo: Vec3,
        emission: Vec3,
    },
}

impl Shape {
    /// The `type` name of the shape in scene files.
    pub fn type_name(&self) -> &'static str {
        match self {
            Shape::Quad { .. } => "quad",
            Shape::Box { .. } => "box",
            Shape::Sphere { .. } => "sphere",
            Shape::Mesh { .. } => "mesh",
        }
    }

    /// The radiance it emits (W/(m²·sr)); zero for a shape that does not emit.
    pub fn emission(&self) -> Vec3 {
        match self {
            Shape::Quad { emission, .. }
            | Shape::Box { emission, .. }
            | Shape::Sphere { emission, .. }
            | Shape::Mesh { emission, .. } => *emission,
        }
    }

    /// Whether it is an area light (some channel of its emission is positive).
    pub fn emits(&self) -> bool {
        self.emission().max_element() > 0.0
    }
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
    /// Texels along each side of the ME estimator's moment shadow maps (a power of two,
    /// `[integrator] moment_map_size`, default 256).
    pub moment_map_size: u32,
    pub restir: RestirSettings,
    pub baseline: BaselineSettings,
}

impl Default for Integrator {
    fn default() -> Self {
        Self {
            max_bounces: 1,
            volume: VolumeIntegrator::Restir,
            box_estimator: BoxEstimator::Mcwvds,
            box_samples: 16,
            moment_map_size: 256,
            restir: RestirSettings::default(),
            baseline: BaselineSettings::default(),
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
    /// Moment-based estimation of the visibility ratio (Peters et al. 2017) times the
    /// analytic unoccluded term: deterministic and approximate by design.
    Me,
}

impl BoxEstimator {
    pub const ALL: [BoxEstimator; 6] = [
        Self::Mcwvds,
        Self::Reds,
        Self::Rees,
        Self::Rm,
        Self::Mcds,
        Self::Me,
    ];
    /// The estimators that converge to the exact single-scattering image (all but ME).
    pub const EXACT: [BoxEstimator; 5] =
        [Self::Mcwvds, Self::Reds, Self::Rees, Self::Rm, Self::Mcds];

    /// The name used in scene files.
    pub fn name(self) -> &'static str {
        match self {
            Self::Mcwvds => "mcwvds",
            Self::Reds => "reds",
            Self::Rees => "rees",
            Self::Rm => "rm",
            Self::Mcds => "mcds",
            Self::Me => "me",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReuseMode {
    Direction,
    Vertex,
}

/// How ReSTIR's spatial reuse weights the reservoirs it combines (`mis`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MisMode {
    /// Talbot's multiple importance sampling over every (sample, pixel) pair, as the
    /// paper does: (N + 1)² target evaluations for N neighbours.
    Talbot,
    /// Pairwise MIS (Bitterli 2022): each neighbour against the pixel's own reservoir
    /// only, 3N target evaluations.
    Pairwise,
}

/// `temporal_limit = "auto"` in a scene where nothing moves: with nothing to make the
/// history stale, a longer one lowers each frame's error (docs/restir.md, "Q on still
/// scenes": MSE ratio to the baseline at equal time 0.18 -> 0.10 at g = 0.8, K = 3, going
/// from Q = 20 to 60, lower on every static benchmark).
pub const STILL_TEMPORAL_LIMIT: u32 = 60;

/// `temporal_limit = "auto"` in a scene with keyframes or density frames: what measured
/// best on the motion benchmarks (docs/restir.md, "Q in motion"; a turning sun kept the
/// long history better than Q = 4).
pub const ANIMATED_TEMPORAL_LIMIT: u32 = 20;

/// The smallest automatic spatial radius: below it the neighbours would round to the
/// pixel itself.
pub const MIN_AUTO_SPATIAL_RADIUS_PX: f32 = 1.5;

/// `spatial_radius_px = "auto"` at `width` pixels: 10 px at 1920 (the paper's), in
/// proportion to the width, at least [`MIN_AUTO_SPATIAL_RADIUS_PX`].
pub fn auto_spatial_radius_px(width: u32) -> f32 {
    (10.0 * width as f32 / 1920.0).max(MIN_AUTO_SPATIAL_RADIUS_PX)
}

/// On which frames ReSTIR's spatial reuse runs (`spatial_when`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpatialWhen {
    /// Every frame (the paper's).
    Always,
    /// Frames whose camera differs from the previous frame's: where the temporal history
    /// is weak (measured: docs/restir.md, "Spatial reuse in motion").
    CameraMoves,
    /// Frames whose camera or density frame differs from the previous frame's: the
    /// history is weak under both (measured on the animated plume: docs/restir.md,
    /// "Spatial reuse where the density changes").
    CameraOrDensity,
}

/// How ReSTIR's spatial reuse moves a path's first vertex x_1 to another pixel's camera
/// ray (`spatial_shift`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpatialShift {
    /// The paper's direction reuse: x_1 keeps its distance z_1 from the camera.
    Distance,
    /// x_1 keeps its optical depth τ_1 through the conservative piecewise-constant grid
    /// (the Exp(1) draw of regular tracking, replayed along the other ray), so it stays
    /// in the medium; the Jacobian is the ratio of the two rays' σ* at the vertices.
    OpticalDepth,
    /// x_1 keeps its exact optical depth through the grid's own trilinear density (the
    /// closed-form integral, inverted along the other ray), as `temporal_shift =
    /// "optical_depth"` does between frames; the Jacobian is the ratio of σ_t at the
    /// vertices, continuous along a ray where σ* jumps between coarse cells.
    ExactOpticalDepth,
}

/// Where a reused path keeps the direction of its environment sample (`env_reuse`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EnvReuse {
    /// In the map's own frame: as the map turns, the reused direction turns with it, so a
    /// sample of a small sun keeps its sun (a rotation: Jacobian 1).
    Map,
    /// In the world: a reused direction stays put while the map turns under it (the
    /// paper's direction reuse).
    World,
}

/// Which reservoir of a frame becomes the next frame's temporal history
/// (`temporal_history`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HistoryMode {
    /// The spatial stage's output (the paper's Algorithm 1).
    Spatial,
    /// The temporal stage's output, before spatial reuse: spatially reused samples then
    /// do not circulate back into the history, which keeps their correlation from
    /// building up over frames.
    Temporal,
}

/// How paths end in a light (`nee` of `[integrator.restir]` and `[integrator.baseline]`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NeeMode {
    /// Each integrator's measured choice: ReSTIR splits where the scene's lights are
    /// directional or point lights and an environment (a sun and a sky); the baseline
    /// splits at K = 1 where one delta light shares the scene with other lights.
    Auto,
    /// The paper's: each vertex samples one light, chosen by power, so a selected path
    /// is lit by the sun or by the sky and its colour is theirs.
    One,
    /// Each vertex adds every delta (directional, point) light to one sample of the
    /// other lights: a path carries the mix of sun and sky light its vertex receives
    /// (ReSTIR: far less colour noise under a scalar target; only for scenes whose other
    /// lights are the environment alone), and no sample is spent choosing between them
    /// (the baseline: half the per-sample variance under a sun and a sky).
    Split,
}

/// Where the baseline reads the density's values from (`density_fetch`), and ReSTIR's
/// tracking its piecewise-constant levels (`pc_fetch`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DensityFetch {
    /// A storage buffer on CPU devices (lavapipe), the atlas image on GPUs.
    Auto,
    /// The 3D atlas image, by texelFetch.
    Image,
    /// A storage buffer of the atlas's slots (refused where it exceeds the device's
    /// largest storage-buffer binding).
    Buffer,
}

/// `[integrator.baseline]`: the settings of the baseline path tracer for grid media.
#[derive(Clone, Debug, PartialEq)]
pub struct BaselineSettings {
    /// How next-event estimation picks its lights (`nee`).
    pub nee: NeeMode,
    /// Where the density's values are read from (`density_fetch`).
    pub density_fetch: DensityFetch,
}

impl Default for BaselineSettings {
    fn default() -> Self {
        Self {
            nee: NeeMode::Auto,
            density_fetch: DensityFetch::Auto,
        }
    }
}

/// Where ReSTIR's candidates include the path that sees straight through the medium (the
/// camera ray's end: the environment, an emitting sphere or shape) (`direct`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DirectMode {
    /// Every walk adds it as a candidate with probability 1 and target L·T* (T* of the
    /// whole camera segment through the piecewise-constant grid): never a rare event.
    EachWalk,
    /// The paper's: only a walk that escapes the camera segment (probability T*) adds it,
    /// with weight L. Where the light seen behind the medium is very bright (a sun behind
    /// a cloud), an escape through a dense part is a rare event with weight L·T/T*.
    Escape,
}

/// How ReSTIR's initial candidates find their medium vertices (`candidate_tracking`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CandidateTracking {
    /// Chosen by the plan: `Delta` where each frame leans on its candidates (temporal
    /// reuse off, or a density that changes from frame to frame) or where the candidates'
    /// coarse level misses the field (its marched optical depth error above
    /// 0.1), `Regular` otherwise (docs/restir.md, "Candidates by delta tracking").
    Auto,
    /// The baseline's free-flight sampling: decomposition tracking on the exact density
    /// (residual delta tracking per super-voxel). A vertex's density is σ_t(z)·T(z), the
    /// target's own, so a candidate carries no tracking ratio; the walked transmittance T
    /// of the selected path alone is computed (closed form), once per dispatch.
    Delta,
    /// The paper's (sec. 4.1): regular tracking through the conservative piecewise-constant
    /// grid at `mip_candidates` / `mip_indirect`, each candidate weighted by
    /// (σ_s/σ*)·(T*/T) relative to its target (heavier tails; cheaper per walk).
    Regular,
}

/// How ReSTIR's target function p̂ makes a scalar of a path's RGB contribution (`target`).
/// Any positive, positively homogeneous function of the channels keeps every estimate
/// unbiased; they differ in which paths a pixel selects where the light has hues.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TargetScalar {
    /// Rec. 709 luminance (the paper's): blue carries 7 % of the weight, so a path lit in
    /// blue alone is selected rarely and weighted up to 14x.
    Luminance,
    /// r + g + b: every channel's contribution over p̂ stays at most 1.
    Sum,
    /// max(r, g, b): as `Sum`, at most 1 per channel, and the brightest channel decides.
    Max,
}

/// Where ReSTIR estimates the medium emission its camera rays see directly
/// (`camera_emission`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CameraEmission {
    /// As every other path (the paper's): emission at a walk's first vertex is a candidate
    /// (or, folded, part of its NEE candidate), resampled and reused.
    Reservoir,
    /// Apart from the reservoirs, in final shading: 8 samples along the pixel's camera ray
    /// stratified in the distribution σ_t·T of its collisions (exact inversion of the
    /// closed-form optical depth). A pixel's colour then
    /// no longer hinges on whether its one selected path is the fire's glow or light
    /// scattered in the smoke.
    Stratified,
}

/// Which target functions the temporal reuse of a still frame resamples with
/// (`still_target`). Both are unbiased: the two samples' MIS weights there are constant
/// (M_i / ΣM), and under constant weights each sample may keep a target of its own.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StillTarget {
    /// `Initial` where the candidates are delta tracked (their target has the walked
    /// segments' exact transmittance), `Reuse` where regular tracking's T* is in it.
    Auto,
    /// Each reservoir's own: the fresh sample's initial target (what the initial pass
    /// selected it by) and the history's stored one. A still frame's temporal reuse
    /// evaluates no target.
    Initial,
    /// The reuse passes' target (every segment's T~ ray marched on `mip_reuse`), evaluated
    /// for each frame's fresh sample.
    Reuse,
}

/// How temporal reuse finds a pixel's previous-frame neighbour and moves its path
/// (`temporal_reprojection`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TemporalReprojection {
    /// The paper's: the neighbour is where the selected path's first vertex x_1 was (velocity
    /// resampling where it has none); the reused path keeps its sub-pixel position and its
    /// depth past where the two pixels' centre rays enter the medium.
    Path,
    /// The neighbour is where the pixel's motion point (its centre ray's point at optical
    /// depth 1 through the conservative grid) was; the reused path's sub-pixel position is
    /// translated so that the previous ray through that point becomes this pixel's centre
    /// ray, and its depth is kept past the point: a path found near it keeps its world-space
    /// vertices under a moving camera.
    Aligned,
}

/// How temporal reuse moves a reused path's first medium vertex x_1 from the previous
/// frame's camera ray onto this frame's (`temporal_shift`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TemporalShift {
    /// x_1 keeps its depth past the two rays' anchors (the motion point under
    /// `temporal_reprojection = "aligned"`, where the rays enter the medium under
    /// `"path"`): a translation along the ray, Jacobian 1.
    Anchor,
    /// x_1 keeps its optical depth from the camera through the grid's own density, on the
    /// frames whose density is the previous frame's (the anchors elsewhere): both frames'
    /// camera segments then carry one transmittance, and the Jacobian is the ratio of
    /// sigma_t at the two vertices. Only where the grid is the only medium.
    OpticalDepth,
}

/// `[integrator.restir]`.
#[derive(Clone, Debug, PartialEq)]
pub struct RestirSettings {
    pub candidates: u32,
    /// M on the frames whose temporal history is full (`candidates_settled`): from the
    /// Q-th frame in a row on which nothing changed (camera, lights, density), the history
    /// holds Q·M candidates' worth, each frame's own M adds 1/(Q+1) of it, and a frame of
    /// fewer candidates costs less; the history's cap stays Q·M candidates, so its length
    /// is kept. The choice is made per frame from the frames alone, so the estimator stays
    /// unbiased. At most `candidates` (a larger value is `candidates`).
    pub candidates_settled: u32,
    /// Temporal reuse from the second frame on (`temporal`); `None` (`"auto"`, the
    /// default): on wherever each frame is a product (an animation, real-time frames,
    /// a profile or a per-frame study), off where the product is a still of a static
    /// scene, the mean of its frames, which independent frames make converge faster
    /// (the plan decides: `nimbus::plan::Product`).
    pub temporal: Option<bool>,
    /// Q: the previous frame's M is clamped to Q·M (`temporal_limit`); `None` (`"auto"`,
    /// the default): [`STILL_TEMPORAL_LIMIT`] in a scene where nothing moves (no
    /// keyframes, no density frames: nothing ever makes the history stale, and a longer
    /// one measured better on every static benchmark), [`ANIMATED_TEMPORAL_LIMIT`]
    /// otherwise (`Scene::temporal_limit` resolves it).
    pub temporal_limit: Option<u32>,
    /// Q on the frames whose camera moved, whose density frame changed or (under
    /// `env_reuse = "map"`) whose environment map turned (`temporal_limit_moving`): the temporal limit there is the smaller of this and
    /// `temporal_limit`. Motion leaves the history's targets further from this frame's,
    /// and a shorter history measured better there.
    pub temporal_limit_moving: u32,
    pub spatial_neighbors: u32,
    /// Pixels; `None` (`"auto"`, the default): 10 px at 1920 pixels wide, in proportion
    /// to the width (the paper's angular radius), at least [`MIN_AUTO_SPATIAL_RADIUS_PX`].
    pub spatial_radius_px: Option<f32>,
    /// On which frames spatial reuse runs (`spatial_when`).
    pub spatial_when: SpatialWhen,
    pub spatial_rounds: u32,
    pub reuse: ReuseMode,
    pub mip_candidates: u32,
    /// The mip level of the candidates' scattered segments and their light transmittance,
    /// and the one the reuse passes ray march their targets on (`mip_indirect`,
    /// `mip_reuse`); `None` (`"auto"`, the default) chooses each from the volume's content
    /// when it is loaded: the coarsest level whose marched transmittance stays close to
    /// the true one (see `nimbus_scene::bricks::march_errors`).
    pub mip_indirect: Option<u32>,
    pub mip_reuse: Option<u32>,
    /// Final shading by ratio tracking (`final_transmittance = "ratio"`) instead of the
    /// closed-form trilinear transmittance (`"analytic"`, the default).
    pub final_ratio_tracking: bool,
    /// Spatial reuse's MIS weights (`mis`).
    pub mis: MisMode,
    /// Emission of medium vertices: its own candidates, or folded into each vertex's
    /// split-NEE candidate (`emission = "folded"`).
    pub fold_emission: bool,
    /// How spatial reuse moves x_1 between pixels (`spatial_shift`).
    pub spatial_shift: SpatialShift,
    /// Where reused environment samples keep their direction (`env_reuse`).
    pub env_reuse: EnvReuse,
    /// Spatial reuse only on pixels whose reservoir after temporal reuse holds an M below
    /// this many times `candidates` (the history was dropped or is short: first frames,
    /// disocclusions, changed light); 0: on every pixel (`spatial_max_history`).
    pub spatial_max_history: f32,
    /// Spatial reuse leaves out a neighbour whose centre camera ray ends on another
    /// shape or emitting sphere, or whose ray-marched T~ differs from the pixel's by this
    /// relative change or more (a deterministic test of the two pixels, so unbiased);
    /// 0: every neighbour is combined (`spatial_feature_tolerance`, in [0, 1]).
    pub spatial_feature_tolerance: f32,
    /// Spatial reuse moves x_1 between pixels by its depth past where each pixel's
    /// centre ray enters the medium, as temporal reuse does (`spatial_anchor`).
    pub spatial_anchor: bool,
    /// Final shading reuses the F it evaluated for a pixel's path on the previous frame
    /// where a still frame's temporal reuse kept that path (`shade_cache`): the same
    /// images at a fraction of the shading.
    pub shade_cache: bool,
    /// The target function of a still frame's temporal reuse (`still_target`).
    pub still_target: StillTarget,
    /// What the next frame reuses temporally (`temporal_history`).
    pub temporal_history: HistoryMode,
    /// σ* of candidate generation is at least this fraction of the largest density in
    /// the voxel's 3×3×3 neighbourhood (`sigma_star_floor`, in [0, 1]; 0 = the paper's
    /// conservative grid). It bounds the ratio σ_t / σ* of the candidates' weights by
    /// 1 / floor, cutting their heavy tail, and stays unbiased (σ* > 0 where σ_t > 0).
    pub sigma_star_floor: f32,
    /// How paths end in a light (`nee`).
    pub nee: NeeMode,
    /// How candidates include the camera ray's end (`direct`; regular tracking only:
    /// delta-tracked walks add it where they escape, with weight L exactly).
    pub direct: DirectMode,
    /// How the candidates' walks find their medium vertices (`candidate_tracking`).
    pub candidate_tracking: CandidateTracking,
    /// Where regular tracking reads the piecewise-constant levels from (`pc_fetch`): the
    /// same choices as the baseline's `density_fetch`.
    pub pc_fetch: DensityFetch,
    /// Where the passes read the full-resolution density from (`density_fetch`): the
    /// same choices as the baseline's.
    pub density_fetch: DensityFetch,
    /// The target function's scalar of a path's RGB contribution (`target`).
    pub target: TargetScalar,
    /// Where the camera rays' directly seen emission is estimated (`camera_emission`).
    pub camera_emission: CameraEmission,
    /// How temporal reuse finds the previous frame's pixel and moves its path there
    /// (`temporal_reprojection`).
    pub temporal_reprojection: TemporalReprojection,
    /// How temporal reuse moves a reused path's x_1 onto this frame's camera ray
    /// (`temporal_shift`).
    pub temporal_shift: TemporalShift,
}

/// The defaults are what measured best at equal GPU time on the benchmark scenes
/// (docs/restir.md): Q = 60 where nothing moves and 20 in an animation, with the
/// pre-spatial history, spatial reuse on the frames whose camera or density moved, and
/// the mip levels, next-event estimation and the candidates' tracking chosen from the
/// scene.
/// The paper's algorithm is `temporal_limit = 4`, `spatial_neighbors = 3`,
/// `temporal_history = "spatial"`, `mip_indirect = 2`, `mip_reuse = 1`, `nee = "one"`,
/// `direct = "escape"`, `candidate_tracking = "regular"`, `target = "luminance"`,
/// `camera_emission = "reservoir"`, `temporal_reprojection = "path"`.
impl Default for RestirSettings {
    fn default() -> Self {
        Self {
            candidates: 4,
            candidates_settled: 1,
            temporal: None,
            temporal_limit: None,
            temporal_limit_moving: 2,
            spatial_neighbors: 3,
            spatial_radius_px: None,
            spatial_when: SpatialWhen::CameraOrDensity,
            spatial_rounds: 1,
            reuse: ReuseMode::Direction,
            mip_candidates: 1,
            mip_indirect: None,
            mip_reuse: None,
            final_ratio_tracking: false,
            mis: MisMode::Talbot,
            spatial_shift: SpatialShift::Distance,
            env_reuse: EnvReuse::Map,
            fold_emission: false,
            spatial_max_history: 0.0,
            spatial_feature_tolerance: 0.0,
            spatial_anchor: false,
            shade_cache: true,
            still_target: StillTarget::Auto,
            temporal_history: HistoryMode::Temporal,
            sigma_star_floor: 0.0,
            nee: NeeMode::Auto,
            direct: DirectMode::EachWalk,
            candidate_tracking: CandidateTracking::Auto,
            pc_fetch: DensityFetch::Auto,
            density_fetch: DensityFetch::Auto,
            target: TargetScalar::Sum,
            camera_emission: CameraEmission::Stratified,
            temporal_reprojection: TemporalReprojection::Aligned,
            temporal_shift: TemporalShift::Anchor,
        }
    }
}

/// An angle in degrees past one turn reduced to within one, exactly (f64 `%`, sign
/// kept); an angle within one turn (|a| <= 360) is returned bit for bit. Rotations are
/// applied in f32, whose sine of a huge argument is noise unrelated to the f64 one.
pub fn reduce_degrees(a: f64) -> f64 {
    if a.abs() > 360.0 {
        a % 360.0
    } else {
        a
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

impl Scene {
    /// The light group of `lights[index]`: its `group`, or [`DEFAULT_LIGHT_GROUP`].
    pub fn light_group(&self, index: usize) -> &str {
        self.light_groups
            .get(index)
            .and_then(|g| g.as_deref())
            .unwrap_or(DEFAULT_LIGHT_GROUP)
    }
}
