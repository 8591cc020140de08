//! A grid medium as the grid passes upload it: its density in bricks with super-voxel
//! records, the static grids (emission, temperature, albedo) and the uniforms.

use super::*;

/// A grid medium ready for upload: the density in bricks (unscaled) with the slots its
/// atlas gets and their super-voxel records, the emission grid, and the uniforms.
pub struct GpuGrid {
    pub density: BrickGrid,
    /// The density's slots: every brick whose super-voxel holds density, in the order of
    /// `super_voxels`.
    pub density_layout: SparseLayout,
    /// Per density slot: (min, max, avg, 0) of sigma_t over its super-voxel.
    pub super_voxels: Vec<[f32; 4]>,
    /// The emission grid (unscaled), its slots and atlas format, if the medium emits.
    pub emission: Option<(BrickGrid, SparseLayout, TexelFormat)>,
    /// The temperature grid (R32F) and its slots, if the medium glows as a blackbody.
    pub temperature: Option<(BrickGrid, SparseLayout)>,
    /// The albedo grid, its slots and atlas format, if the medium's albedo is a grid.
    pub albedo_grid: Option<(BrickGrid, SparseLayout, TexelFormat)>,
    /// The density's p-space → world map.
    pub p_to_world: DMat4,
    /// The world box of an axis-aligned (`type = "grid"`) medium.
    pub world_box: Option<(Vec3, Vec3)>,
    /// The uniforms; the density's indirection section is first (offset 0), the
    /// emission's second, the temperature's third, the albedo's fourth (see
    /// [`GpuGrid::indirection`]).
    pub uniforms: BaselineUniformsGpu,
    /// Analytic lights (directional, point, sphere), each with its selection CDF, and
    /// the constant environment radiance.
    pub lights: Vec<LightGpu>,
    /// The directional lights' gobo half-planes (one zeroed plane without gobos: a
    /// storage buffer cannot be empty).
    pub gobo_planes: Vec<[f32; 4]>,
    pub env_radiance: Vec3,
    /// The environment map, if the environment has a `file`.
    pub env_map: Option<GpuEnvMap>,
    /// The radius of the medium's bounding sphere (light selection weights).
    pub light_radius: f32,
    /// Mean luminance of the environment map over the sphere, if there is one.
    pub env_map_luminance: Option<f32>,
    /// The emitting shapes' primitives (empty without area lights); `lights` ends with
    /// their `LIGHT_AREA` record when there are some.
    pub emitters: crate::shader_data::EmitterTable,
}

/// Whether super-voxel tracking with residual majorants `majorant_scale` x (max - min)
/// can meet a span too hot for null collisions (`GRID_EXACT_SPAN_STEPS` tentative
/// collisions on average) in any of `super_voxels` ((min, max, avg, _) of sigma_t) of a
/// grid whose p-space maps to world by `p_to_world`: the residual majorant times the
/// longest chord of a super-voxel (at most the sum of its three edge lengths) is checked
/// for each. Where none can, `SC_EXACT_SPANS` compiles the exact branches out.
pub fn needs_exact_spans(
    super_voxels: &[[f32; 4]],
    p_to_world: &DMat4,
    majorant_scale: f32,
) -> bool {
    let edges = p_to_world.x_axis.truncate().length()
        + p_to_world.y_axis.truncate().length()
        + p_to_world.z_axis.truncate().length();
    let chord = 8.0 * edges;
    let limit = f64::from(crate::shader_data::features::GRID_EXACT_SPAN_STEPS);
    super_voxels.iter().any(|v| {
        let residual = f64::from(majorant_scale) * f64::from(v[1] - v[0]);
        // A NaN bound is refused at load; count it as hot all the same.
        residual.is_nan() || residual * chord > limit
    })
}

impl GpuGrid {
    /// Whether the baseline's super-voxel tracking needs its exact branches
    /// ([`needs_exact_spans`] with the tight residual majorant).
    pub fn needs_exact_spans(&self) -> bool {
        needs_exact_spans(&self.super_voxels, &self.p_to_world, 1.0)
    }

    /// Whether a brick indirection section of the grid is two-level.
    pub fn two_level_bricks(&self) -> Result<bool> {
        Ok(self.density_layout.indirection.two_level
            || self.static_sections()?.iter().any(|s| s.two_level))
    }

    /// The indirection sections of the grids that do not change per frame: the
    /// emission's, the temperature's and the albedo's (one empty entry for a grid the
    /// medium lacks).
    pub fn static_sections(&self) -> Result<[nimbus_scene::bricks::Indirection; 3]> {
        let section = |layout: Option<&SparseLayout>| match layout {
            Some(layout) => Ok(layout.indirection.clone()),
            None => nimbus_scene::bricks::Indirection::new([1, 1, 1]),
        };
        Ok([
            section(self.emission.as_ref().map(|(_, layout, _)| layout))?,
            section(self.temperature.as_ref().map(|(_, layout)| layout))?,
            section(self.albedo_grid.as_ref().map(|(_, layout, _)| layout))?,
        ])
    }

    /// The indirection sections of the baseline: the density's (at offset 0, as
    /// `uniforms.grid.space` says), then the [`GpuGrid::static_sections`].
    pub fn indirection(&self) -> Result<Vec<u32>> {
        let mut out = Indirection::default();
        out.push(&self.density_layout.indirection)?;
        for section in &self.static_sections()? {
            out.push(section)?;
        }
        Ok(out.finish())
    }
}

impl GpuGrid {
    /// Load the scene's grid medium into bricks and build what the grid passes read.
    /// Lights are selected in proportion to the power they bring to the medium's
    /// bounding sphere (radius R): directional E·πR², point 4π·I, sphere 4π²r²·L,
    /// environment 4π²R²·L (luminance of each).
    pub fn build(scene: &Scene) -> Result<GpuGrid> {
        let Some((index, grid)) = scene.media.iter().enumerate().find_map(|(i, m)| match m {
            Medium::Grid(g) => Some((i, g)),
            _ => None,
        }) else {
            bail!("internal: the baseline pass was given no grid medium");
        };
        let what = format!(
            "{}: [[medium]] #{} > density",
            scene.source.display(),
            index + 1
        );
        // The plan loaded it to choose ReSTIR's levels: the same load and check.
        let density = match crate::plan::levels::take_density(grid, &scene.position_scale()) {
            Some(density) => density,
            None => {
                let density = BrickGrid::load(&grid.density, 1, &what)?;
                grid.check_density_bricks(&density, &scene.position_scale(), &what)?;
                density
            }
        };
        let p_to_world = grid.p_to_world(&density)?;
        let world_box = grid
            .vdb
            .is_none()
            .then_some((grid.bounds_min, grid.bounds_max));
        let scale = grid.density_scale;
        let (bricks, super_voxels): (Vec<_>, Vec<_>) = density
            .super_voxels()
            .into_iter()
            .map(|(b, v)| (b, [v[0] * scale, v[1] * scale, v[2] * scale, 0.0]))
            .unzip();
        let max_sigma = super_voxels.iter().fold(0.0f32, |m, s| m.max(s[1]));
        let density_layout = SparseLayout::new(&density, bricks, 1)?;
        let space = grid_space(&density, &density_layout, 0, p_to_world, world_box);
        let emission = match &grid.emission {
            Some(source) => {
                let what = format!(
                    "{}: [[medium]] #{} > emission",
                    scene.source.display(),
                    index + 1
                );
                let e = BrickGrid::load(source, 0, &what)?;
                let layout = SparseLayout::new(&e, e.slot_bricks(), 1)?;
                let format = if e.channels == 3 {
                    TexelFormat::Rgba32
                } else {
                    TexelFormat::R32
                };
                Some((e, layout, format))
            }
            None => None,
        };
        let temperature = match &grid.temperature {
            Some(t) => {
                let what = format!(
                    "{}: [[medium]] #{} > temperature",
                    scene.source.display(),
                    index + 1
                );
                let tg = BrickGrid::load(&t.source, 1, &what)?;
                let (max, at) = tg.max_value();
                t.check_brightest(max, &format!("lattice point {}", at + tg.origin), &what)?;
                let layout = SparseLayout::new(&tg, tg.slot_bricks(), 1)?;
                Some((tg, layout))
            }
            None => None,
        };
        // The sections follow the density's: the emission's, then the temperature's
        // (one empty entry where a grid is missing), as `indirection` lays them out. A
        // missing grid has 0 channels: grid_emission.glsl does not read it.
        let no_grid = |offset: usize| GridSpaceGpu {
            brick_dims: [1, 1, 1],
            channels: 0,
            slots_x: 1,
            slots_y: 1,
            bricks_offset: offset as u32,
            ..GridSpaceGpu::default()
        };
        let emission_offset = crate::shader_data::sparse::head_len(&density_layout.indirection);
        let emission_space = match &emission {
            Some((e, layout, _)) => grid_space(
                e,
                layout,
                emission_offset as u32,
                grid.p_to_world(e)?,
                world_box,
            ),
            None => no_grid(emission_offset),
        };
        let temperature_offset = emission_offset
            + emission.as_ref().map_or(1, |(_, layout, _)| {
                crate::shader_data::sparse::head_len(&layout.indirection)
            });
        let temperature_space = match &temperature {
            Some((t, layout)) => grid_space(
                t,
                layout,
                temperature_offset as u32,
                grid.p_to_world(t)?,
                world_box,
            ),
            None => no_grid(temperature_offset),
        };
        let albedo_grid = match &grid.albedo_grid {
            Some(source) => {
                let what = format!(
                    "{}: [[medium]] #{} > albedo",
                    scene.source.display(),
                    index + 1
                );
                let a = BrickGrid::load(source, 0, &what)?;
                let (max, at) = a.max_any_channel();
                if max > 1.0 {
                    bail!("{what}: value {max} at lattice point {at}: an albedo must be in [0, 1]");
                }
                let layout = SparseLayout::new(&a, a.slot_bricks(), 1)?;
                let format = if a.channels == 3 {
                    TexelFormat::Rgba32
                } else {
                    TexelFormat::R32
                };
                Some((a, layout, format))
            }
            None => None,
        };
        let albedo_offset = temperature_offset
            + temperature.as_ref().map_or(1, |(_, layout)| {
                crate::shader_data::sparse::head_len(&layout.indirection)
            });
        let albedo_space = match &albedo_grid {
            Some((a, layout, _)) => grid_space(
                a,
                layout,
                albedo_offset as u32,
                grid.p_to_world(a)?,
                world_box,
            ),
            None => no_grid(albedo_offset),
        };
        let pyro = grid.temperature.as_ref();
        let uniforms = BaselineUniformsGpu {
            grid: GridParamsGpu {
                bounds_min: grid.bounds_min.to_array(),
                density_scale: scale,
                bounds_max: grid.bounds_max.to_array(),
                sigma_t_max: max_sigma,
                space,
            },
            albedo: grid.albedo.to_array(),
            g: grid.g,
            emission_scale: grid.emission_scale.to_array(),
            emission: emission_space,
            temperature_offset: pyro.map_or(0.0, |t| t.offset),
            temperature_scale: pyro.map_or(0.0, |t| t.scale),
            blackbody_scale: pyro.map_or(0.0, |t| t.blackbody_scale),
            temperature: temperature_space,
            albedo_grid: albedo_space,
            env_size: [1, 1],
            ..BaselineUniformsGpu::default()
        };

        let radius = 0.5 * (grid.bounds_max - grid.bounds_min).length();
        let env_map = GpuEnvMap::load(scene)?;
        let env_map_luminance = env_map.as_ref().map(|m| m.mean_luminance);
        let mut uniforms = uniforms;
        if let Some(map) = &env_map {
            uniforms.env_size = map.size;
        }
        let emitters = crate::shader_data::EmitterTable::build(scene);
        uniforms.emitter_count = emitters.len() as u32;
        let set = LightSet::build(
            &scene.lights,
            radius,
            env_map_luminance,
            emitters.total_power,
        );
        uniforms.env_select = set.env_select;
        Ok(GpuGrid {
            emitters,
            density,
            density_layout,
            super_voxels: non_empty(&super_voxels),
            emission,
            temperature,
            albedo_grid,
            p_to_world,
            world_box,
            uniforms,
            lights: set.lights,
            gobo_planes: non_empty(&set.gobo_planes),
            env_radiance: set.env_radiance,
            env_map,
            light_radius: radius,
            env_map_luminance,
        })
    }
}
