//! The media of the grid oracle: homogeneous boxes and voxel grids, with free-flight
//! sampling (delta tracking) and transmittance estimates (ratio tracking).

use anyhow::{bail, ensure};
use glam::{DMat3, DVec3};
use nimbus_scene::vdb::{read_vdb_topology, VdbGridKind};
use nimbus_scene::{
    load_grid, read_vol_header, GridMedium, GridSource, Medium, Scene, Temperature, VoxelGrid,
};

use crate::common::geometry::{homogeneous, OrientedBox, Region};
use crate::common::rng::Rng;

/// A grid medium in f64 with its grids loaded.
pub(super) struct GridF64 {
    pub(super) bounds: OrientedBox,
    lo: DVec3,
    size: DVec3,
    density: VoxelGrid,
    density_scale: f64,
    /// σ̄ = density_scale · max voxel ≥ every trilinear σt in the grid.
    pub(super) majorant: f64,
    /// Emission grid and `emission_scale`.
    pub(super) emission: Option<(VoxelGrid, DVec3)>,
    /// Temperature grid and its blackbody settings.
    pub(super) temperature: Option<Box<(VoxelGrid, Temperature)>>,
    /// Albedo grid (1 or 3 channels), multiplying the medium's albedo colour.
    pub(super) albedo_grid: Option<VoxelGrid>,
}

impl GridF64 {
    fn index_space(&self, x: DVec3, dims: [u32; 3]) -> [f64; 3] {
        let p = (x - self.lo) / self.size;
        [
            p.x * f64::from(dims[0]),
            p.y * f64::from(dims[1]),
            p.z * f64::from(dims[2]),
        ]
    }

    pub(super) fn sigma_t(&self, x: DVec3) -> f64 {
        self.density_scale
            * self
                .density
                .sample_trilinear(self.index_space(x, self.density.dims))
    }

    /// The albedo grid at x (1 where there is none).
    pub(super) fn albedo_factor(&self, x: DVec3) -> DVec3 {
        match &self.albedo_grid {
            None => DVec3::ONE,
            Some(grid) => {
                let p = self.index_space(x, grid.dims);
                if grid.channels == 3 {
                    DVec3::from_array([0, 1, 2].map(|c| grid.sample_trilinear_channel(p, c)))
                } else {
                    DVec3::splat(grid.sample_trilinear(p))
                }
            }
        }
    }

    /// Whether the medium emits (an emission grid, a temperature grid or both).
    pub(super) fn emits(&self) -> bool {
        self.emission.is_some() || self.temperature.is_some()
    }

    /// Le at x: `emission_scale` times the emission grid, plus `blackbody_scale` ·
    /// RGB(T) of the trilinear temperature (the table the renderers read, in f64).
    pub(super) fn emission(&self, x: DVec3) -> DVec3 {
        let grid_le = match &self.emission {
            None => DVec3::ZERO,
            Some((grid, scale)) => {
                let p = self.index_space(x, grid.dims);
                if grid.channels == 3 {
                    *scale
                        * DVec3::from_array([0, 1, 2].map(|c| grid.sample_trilinear_channel(p, c)))
                } else {
                    *scale * grid.sample_trilinear(p)
                }
            }
        };
        let blackbody = match &self.temperature {
            None => DVec3::ZERO,
            Some(pyro) => {
                let (grid, t) = &**pyro;
                t.radiance(grid.sample_trilinear(self.index_space(x, grid.dims)))
            }
        };
        grid_le + blackbody
    }
}

pub(super) enum MediumKind {
    Homogeneous { bounds: Region, sigma_t: f64 },
    Grid(GridF64),
}

pub(super) struct MediumF64 {
    pub(super) kind: MediumKind,
    pub(super) albedo: DVec3,
    pub(super) g: f64,
}

impl MediumF64 {
    /// Medium `medium` with its grids `loaded` (`None` for a box); `what` names it in
    /// errors.
    pub(super) fn new(
        medium: &Medium,
        loaded: Option<LoadedGrid>,
        what: &str,
    ) -> anyhow::Result<Self> {
        Ok(match (medium, loaded) {
            (Medium::Box(_) | Medium::Convex(_), _) => {
                let (Some(bounds), Some((sigma_t, albedo, g))) =
                    (Region::of(medium), homogeneous(medium))
                else {
                    bail!("{what}: internal: a homogeneous medium without a region");
                };
                MediumF64 {
                    kind: MediumKind::Homogeneous { bounds, sigma_t },
                    albedo,
                    g,
                }
            }
            (Medium::Grid(m), Some((density, emission, temperature, albedo_grid))) => {
                let (lo, hi) = (m.bounds_min.as_dvec3(), m.bounds_max.as_dvec3());
                ensure!(hi.cmpgt(lo).all(), "{what}: empty grid bounds {lo} .. {hi}");
                let density_scale = f64::from(m.density_scale);
                let max_voxel = density
                    .data
                    .iter()
                    .step_by(density.channels as usize)
                    .fold(0f64, |a, &v| a.max(f64::from(v)));
                MediumF64 {
                    kind: MediumKind::Grid(GridF64 {
                        bounds: OrientedBox::new(0.5 * (lo + hi), 0.5 * (hi - lo), DMat3::IDENTITY),
                        lo,
                        size: hi - lo,
                        density,
                        density_scale,
                        majorant: density_scale * max_voxel,
                        emission: emission.map(|e| (e, m.emission_scale.as_dvec3())),
                        temperature: match (temperature, &m.temperature) {
                            (Some(grid), Some(t)) => Some(Box::new((grid, (**t).clone()))),
                            (None, None) => None,
                            _ => bail!("{what}: internal: temperature grid not loaded"),
                        },
                        albedo_grid,
                    }),
                    albedo: m.albedo.as_dvec3(),
                    g: f64::from(m.g),
                }
            }
            (Medium::Grid(_), None) => bail!("{what}: grid not loaded"),
        })
    }

    pub(super) fn span(&self, o: DVec3, d: DVec3, t_max: f64) -> Option<(f64, f64)> {
        match &self.kind {
            MediumKind::Homogeneous { bounds, sigma_t } => {
                if *sigma_t > 0.0 {
                    bounds.clip(o, d, 0.0, t_max)
                } else {
                    None
                }
            }
            MediumKind::Grid(grid) => {
                if grid.majorant > 0.0 {
                    grid.bounds.clip(o, d, 0.0, t_max)
                } else {
                    None
                }
            }
        }
    }

    /// A collision on (t0, t1) of o + t·d: exponential in a box, delta tracking with
    /// the global majorant in a grid.
    pub(super) fn sample_collision(
        &self,
        o: DVec3,
        d: DVec3,
        t0: f64,
        t1: f64,
        rng: &mut Rng,
    ) -> Option<f64> {
        match &self.kind {
            MediumKind::Homogeneous { sigma_t, .. } => {
                let t = t0 + rng.exponential(*sigma_t);
                (t < t1).then_some(t)
            }
            MediumKind::Grid(grid) => {
                let mut t = t0;
                loop {
                    t += rng.exponential(grid.majorant);
                    if t >= t1 {
                        return None;
                    }
                    if rng.uniform() * grid.majorant < grid.sigma_t(o + t * d) {
                        return Some(t);
                    }
                }
            }
        }
    }

    /// An unbiased estimate of the transmittance over (t0, t1): exact in a box, ratio
    /// tracking with the global majorant in a grid.
    pub(super) fn transmittance(&self, o: DVec3, d: DVec3, t0: f64, t1: f64, rng: &mut Rng) -> f64 {
        match &self.kind {
            MediumKind::Homogeneous { sigma_t, .. } => (-sigma_t * (t1 - t0)).exp(),
            MediumKind::Grid(grid) => {
                let mut t = t0;
                let mut tr = 1.0;
                loop {
                    t += rng.exponential(grid.majorant);
                    if t >= t1 {
                        return tr;
                    }
                    tr *= 1.0 - grid.sigma_t(o + t * d) / grid.majorant;
                    if tr <= 0.0 {
                        return 0.0;
                    }
                }
            }
        }
    }
}

/// The density source of a grid medium at frame 0.
fn frame0_density(m: &GridMedium) -> &GridSource {
    m.frames
        .iter()
        .rev()
        .find(|f| f.frame == 0)
        .map_or(&m.density, |f| &f.density)
}

/// Loaded grids of one grid medium: density, optional emission, temperature and albedo.
pub(super) type LoadedGrid = (
    VoxelGrid,
    Option<VoxelGrid>,
    Option<VoxelGrid>,
    Option<VoxelGrid>,
);

/// Loads the grids of every grid medium (`None` for boxes), each once.
pub(super) fn load_grids(scene: &Scene) -> anyhow::Result<Vec<Option<LoadedGrid>>> {
    let source = scene.source.display();
    let mut grids = Vec::new();
    for (i, medium) in scene.media.iter().enumerate() {
        grids.push(match medium {
            Medium::Box(_) | Medium::Convex(_) => None,
            Medium::Grid(m) => {
                let what = format!("{source}: [[medium]] #{}", i + 1);
                let density = load_grid(frame0_density(m), 1, &format!("{what} > density"))?;
                // An rgb grid: a 3-channel .vol file or a vec3 .vdb grid.
                let scalar_or_rgb = |e: &GridSource, name: &str| {
                    let channels = match e {
                        GridSource::MitsubaVol { file } => read_vol_header(file)?.channels,
                        GridSource::Vdb { file, grid, .. } => {
                            let header =
                                read_vdb_topology(file, grid.as_deref(), VdbGridKind::Any, &what)?;
                            header.value_type.channels() as u32
                        }
                        _ => 1,
                    };
                    load_grid(e, channels, &format!("{what} > {name}"))
                };
                let emission = m
                    .emission
                    .as_ref()
                    .map(|e| scalar_or_rgb(e, "emission"))
                    .transpose()?;
                let albedo_grid = match &m.albedo_grid {
                    Some(a) => {
                        let grid = scalar_or_rgb(a, "albedo")?;
                        let max = grid.data.iter().fold(0.0f32, |a, &v| a.max(v));
                        ensure!(
                            max <= 1.0,
                            "{what} > albedo: value {max}: an albedo must be in [0, 1]"
                        );
                        Some(grid)
                    }
                    None => None,
                };
                let temperature =
                    match &m.temperature {
                        Some(t) => {
                            let name = format!("{what} > temperature");
                            let grid = load_grid(&t.source, 1, &name)?;
                            let (max, at) = grid.data.iter().enumerate().fold(
                                (0.0f32, 0usize),
                                |best, (i, &v)| if v > best.0 { (v, i) } else { best },
                            );
                            t.check_brightest(max, &format!("voxel {at} (x fastest)"), &name)?;
                            Some(grid)
                        }
                        None => None,
                    };
                Some((density, emission, temperature, albedo_grid))
            }
        });
    }
    Ok(grids)
}
