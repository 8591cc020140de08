//! A render's footprint from its plan and the scene's file headers: [`Footprint::of`]
//! (the leaf type lives in [`crate::budget`]). The renderer checks it before it
//! allocates anything; `nimbus render --explain` prints it.

use std::collections::HashSet;

use anyhow::Result;
use glam::IVec3;
use nimbus_scene::bricks::{shr, SLOT_TEXELS};
use nimbus_scene::{BrickTopology, GridSource, Scene};

use super::{
    has_density_frames, BaselinePlan, CrepuscularPlan, Integrator, RenderPlan, RestirPlan,
    MIN_AUTO_INDIRECT,
};
use crate::budget::{brick_bytes, density_slot_bound, grid_bytes, Binding, Footprint};
use crate::shader_data::scene::GpuScene;
use crate::shader_data::sparse::TexelFormat;
use crate::shader_data::sparse::{atlas_bytes, atlas_dims, atlas_slots, layer_bytes, slot_bound};
use crate::shader_data::{reservoir_bytes, FrameUniforms};

impl Footprint {
    /// The footprint of rendering `scene` with `plan`: the render targets and what the
    /// plan's integrator allocates.
    pub fn of(scene: &Scene, plan: &RenderPlan) -> Result<Footprint> {
        let file = scene.source.display().to_string();
        let mut f = Footprint::default();
        let r = &scene.render;
        let pixels = u64::from(r.width) * u64::from(r.height);
        let render = format!("{file}: [render] fields `width` x `height`");
        f.add(&render, Binding::Storage, pixels * 16);
        f.add(&render, Binding::Storage, pixels * 16);
        // The film's partial sums: per pixel on lavapipe, where a frame's samples may be
        // shared among dispatches (counted everywhere: an upper bound).
        f.add(
            &render,
            Binding::Storage,
            crate::budget::film_partial_bytes(true, pixels),
        );
        f.add(
            "frame uniforms",
            Binding::Storage,
            std::mem::size_of::<FrameUniforms>() as u64,
        );
        // Per-pixel readback of both sums, the mean and standard error computed from
        // them (src/renderer/film.rs), ReSTIR's batch sums, and the two output images.
        let batches = if super::error_batch(plan) > 1 {
            2 * pixels * 16
        } else {
            0
        };
        f.host_peak += 2 * pixels * 16 + 2 * pixels * 16 + batches + pixels * 12 * 2;
        // The AOV buffers (src/plan/aovs.rs): one-element dummies without AOVs.
        let aov = super::aovs::AovBytes::of(&plan.aov, pixels, true);
        let aovs = format!("{file}: [render] field `aovs`");
        for bytes in aov.buffers() {
            f.add(&aovs, Binding::Storage, bytes);
        }
        f.add(
            "AOV uniforms",
            Binding::Storage,
            std::mem::size_of::<crate::shader_data::AovUniformsGpu>() as u64,
        );
        // Read back: the geometric buffer, both sums (and their batch sums), and the
        // layers written.
        let slots = u64::from(plan.aov.path_slots());
        f.host_peak += aov.geometry + 2 * aov.accum + batches * slots / 2 + pixels * 4 * 12;

        match &plan.integrator {
            Integrator::Crepuscular(p) => crepuscular(scene, p, &mut f)?,
            Integrator::Baseline(p) if has_density_frames(scene) => {
                baseline_frames(scene, p, &mut f)?
            }
            Integrator::Baseline(p) => baseline(scene, p, &mut f)?,
            Integrator::Restir(p) => restir(scene, p, &mut f)?,
        }
        Ok(f)
    }
}

/// What the crepuscular pass allocates besides the render targets: its scene records
/// (a few KiB; counted so that every pass reports its footprint), the environment map
/// and its tables, and, for ME, the moment maps (16 bytes per texel, a mip chain per
/// directional light).
fn crepuscular(scene: &Scene, plan: &CrepuscularPlan, f: &mut Footprint) -> Result<()> {
    f.add_env_map(scene)?;
    f.add_meshes(scene);
    let records = GpuScene::build(scene)?;
    let bytes = std::mem::size_of_val(records.media.as_slice())
        + std::mem::size_of_val(records.medium_planes.as_slice())
        + std::mem::size_of_val(records.shapes.as_slice())
        + std::mem::size_of_val(records.lights.as_slice())
        + std::mem::size_of_val(records.gobo_planes.as_slice());
    f.add(
        format!(
            "{}: box and convex media, shapes, lights, gobos",
            scene.source.display()
        ),
        Binding::Storage,
        bytes as u64,
    );
    if plan.needs_moment_maps() {
        let size = u64::from(plan.moment_map_size);
        f.add(
            format!(
                "{}: ME moment maps, {} light(s) x {size}² texels with mips",
                scene.source.display(),
                records.lights.len()
            ),
            Binding::Storage,
            super::moment_texels_per_light(size) * records.lights.len() as u64 * 16,
        );
    }
    Ok(())
}

/// What the baseline pass allocates (see [`crate::budget`]). With `density_fetch =
/// "buffer"` the density's slots are also one storage buffer (the atlas, then one texel,
/// stays counted: an upper bound), which the device's storage-buffer range must hold.
/// `"auto"` takes the buffer on CPU devices up to `AUTO_DENSITY_BUFFER_MAX`, which every
/// device binds: counted up to that size (an upper bound on GPUs, which keep the image).
fn baseline(scene: &Scene, plan: &BaselinePlan, f: &mut Footprint) -> Result<()> {
    use crate::shader_data::sparse::density_buffer_bytes;
    f.add_meshes(scene);
    f.add_emitters(scene);
    f.add_env_map(scene)?;
    let grid = f.add_grid(scene)?;
    if let Some(g) = grid {
        let slots = g.density_slots.max(1);
        let bytes = density_buffer_bytes(slots);
        if let Some(words) = buffer_counted(plan.density_fetch, bytes) {
            f.add(
                format!(
                    "{}: [integrator.baseline] field `density_fetch` = \"{words}\" (the \
                     density's {slots} slots as one storage buffer)",
                    scene.source.display()
                ),
                Binding::Storage,
                bytes,
            );
        }
    }
    Ok(())
}

/// Whether a storage buffer of `bytes` that `fetch` may take
/// ([`crate::passes::volume_in_buffer`]) is counted, and the setting's word: always for
/// "buffer", for "auto" up to `AUTO_DENSITY_BUFFER_MAX` (the size every device binds,
/// taken on CPU devices: an upper bound on GPUs, which keep the image).
fn buffer_counted(fetch: nimbus_scene::DensityFetch, bytes: u64) -> Option<&'static str> {
    match fetch {
        nimbus_scene::DensityFetch::Buffer => Some("buffer"),
        nimbus_scene::DensityFetch::Auto
            if bytes <= crate::shader_data::sparse::AUTO_DENSITY_BUFFER_MAX =>
        {
            Some("auto")
        }
        _ => None,
    }
}

/// What the passes allocate: every density grid's resources (see [`crate::budget`]).
fn baseline_frames(scene: &Scene, plan: &BaselinePlan, f: &mut Footprint) -> Result<()> {
    let count = super::animated_grid(scene).map_or(0, |(_, g)| g.frames.len());
    for index in 0..=count {
        baseline(&super::scene_of_grid(scene, index), plan, f)?;
    }
    Ok(())
}

/// The bricks of mip `level` of a grid of topology `t` (each brick's parent at that
/// level), after growing `t` by its 26 neighbours when `dilate` (the conservative grid's
/// zeros next to density become positive).
fn level_topology(t: &BrickTopology, level: u32, dilate: bool) -> BrickTopology {
    let dims = IVec3::from_array(t.brick_dims().map(|d| d as i32));
    let mut set = HashSet::new();
    for b in &t.bricks {
        let range = if dilate { -1..=1 } else { 0..=0 };
        for z in range.clone() {
            for y in range.clone() {
                for x in range.clone() {
                    let n = *b + IVec3::new(x, y, z);
                    if n.cmpge(IVec3::ZERO).all() && n.cmplt(dims).all() {
                        set.insert(shr(n, level));
                    }
                }
            }
        }
    }
    BrickTopology {
        lattice_min: shr(t.lattice_min, level),
        lattice_max: shr(t.lattice_max, level),
        bricks: set.into_iter().collect(),
        ..t.clone()
    }
}

/// What the ReSTIR passes allocate (see [`crate::budget`]): the grid's atlases (density,
/// piecewise-constant levels, ray-march mips, and the previous frame's where density
/// frames change), sized for the largest frame at the plan's mip levels (`auto` ones at
/// the finest they can be; a level refined by content, see
/// [`super::MAX_LEVEL_EXCESS_TAU`], is finer and larger), the indirection sections,
/// reservoirs and velocity.
fn restir(scene: &Scene, p: &RestirPlan, f: &mut Footprint) -> Result<()> {
    f.add_meshes(scene);
    f.add_emitters(scene);
    f.add_env_map(scene)?;
    let Some(gf) = f.add_grid(scene)? else {
        return Ok(());
    };
    let (g, table) = (gf.medium, gf.table.clone());
    let file = scene.source.display();
    let r = &scene.render;
    let pixels = u64::from(r.width) * u64::from(r.height);
    let mut reservoirs = u64::from(p.reservoir_slots()) * pixels * reservoir_bytes(p.max_bounces);
    // The shade cache shares the reservoirs' buffer.
    if p.keeps_shade_cache(&super::AovPlan::of(scene)) {
        reservoirs += pixels * super::SHADE_CACHE_BYTES_PER_PIXEL;
    }
    f.add(
        format!("{file}: [render] `width` x `height` with [integrator] `max_bounces` = {} (ReSTIR reservoirs)", p.max_bounces),
        Binding::Storage,
        reservoirs,
    );
    let mut frames = vec![gf.density.clone()];
    let mut frame_slots = vec![gf.density_slots];
    for (i, frame) in g.frames.iter().enumerate() {
        let what = format!(
            "{table} > [[medium.frame]] #{} (frame {})",
            i + 1,
            frame.frame
        );
        let topo = BrickTopology::of(&frame.density, 1, &what)?;
        frame_slots.push(density_slot_bound(&frame.density, &topo));
        frames.push(topo);
    }
    let animated = frames.len() > 1;
    let brick = 512 * 4;
    let mut density_slots = gf.density_slots;
    let (mut pc, mut reuse, mut nee) = (0u64, 0u64, 0u64);
    let (mut kept, mut building) = (0u64, 0u64);
    let mut cells = 0u64;
    // A level chosen from the content (`auto`): counted at the finest it can be, from
    // the file headers alone.
    let mip_indirect = p.asked_levels().indirect.unwrap_or(MIN_AUTO_INDIRECT);
    let mip_reuse = p.asked_levels().reuse.unwrap_or(0);
    for (n, t) in frames.iter().enumerate() {
        let primary = level_topology(t, p.asked_levels().candidates, true);
        let indirect = level_topology(t, mip_indirect, true);
        let march_reuse = level_topology(t, mip_reuse, false);
        let march_nee = level_topology(t, mip_indirect, false);
        let slots = frame_slots[n];
        if n > 0 {
            density_slots = density_slots.max(slots);
        }
        let pc_n = (primary.bricks.len() + indirect.bricks.len()) as u64;
        pc = pc.max(pc_n);
        reuse = reuse.max(slot_bound(&march_reuse, false));
        nee = nee.max(slot_bound(&march_nee, false));
        let level_cells =
            primary.cells() + indirect.cells() + march_reuse.cells() + march_nee.cells();
        if n == 0 {
            cells = level_cells;
        }
        // Kept for the whole render: the grid, its records and every level (f32 values,
        // coordinates, indirection and layout indirection). The base density's bricks
        // are those `add_grid` counted (the pass moves them into its levels, no copy).
        kept += if n == 0 { 0 } else { brick_bytes(t) }
            + slots * (12 + 16)
            + (pc_n + (march_reuse.bricks.len() + march_nee.bricks.len()) as u64) * (brick + 12)
            + 2 * (t.cells() + level_cells) * 4;
        // While a frame is derived: its conservative copy (the bricks and neighbours).
        let conservative = level_topology(t, 0, true);
        building = building
            .max(conservative.bricks.len() as u64 * (brick + 12) + conservative.cells() * 4);
    }
    let r32 = TexelFormat::R32;
    // The march mips as f32 (what a density beyond f16's range needs), or f16 where every
    // density is the procedural cloud, whose values lie in [0, 1].
    let procedural = |s: &GridSource| matches!(s, GridSource::ProceduralCloud { .. });
    let march = if procedural(&g.density) && g.frames.iter().all(|fr| procedural(&fr.density)) {
        TexelFormat::R16
    } else {
        TexelFormat::R32
    };
    let mut atlas = |name: &str, slots: u64, format: TexelFormat| -> Result<()> {
        f.add(
            format!("{table} ({name}, atlas of {slots} bricks)"),
            Binding::Image3d(atlas_dims(atlas_slots(slots)?)),
            atlas_bytes(slots, format)?,
        );
        Ok(())
    };
    atlas("piecewise-constant levels", pc, r32)?;
    atlas("ray-march mip, reuse", reuse, march)?;
    atlas("ray-march mip, NEE", nee, march)?;
    if animated {
        atlas("previous density", density_slots, r32)?;
        atlas("ray-march mip, reuse, previous", reuse, march)?;
        // The base density's atlas (counted by `add_grid`) grows to the largest frame's.
        let base = gf.density_slots;
        if density_slots > base {
            f.add(
                format!("{table} (density atlas for the largest frame)"),
                Binding::Image3d(atlas_dims(atlas_slots(density_slots)?)),
                atlas_bytes(density_slots, r32)? - atlas_bytes(base, r32)?,
            );
        }
        cells += gf.density.cells() + level_topology(&gf.density, mip_reuse, false).cells();
    }
    // Tracking reads the piecewise-constant levels from a slot-major buffer the atlas's
    // size with `pc_fetch = "buffer"` (which the device's storage-buffer range must hold),
    // and with "auto" on CPU devices up to AUTO_DENSITY_BUFFER_MAX, which every device
    // binds: counted up to that size (an upper bound on GPUs, which keep the image alone).
    let pc_bytes = atlas_bytes(pc, r32)?;
    if let Some(words) = buffer_counted(p.settings.pc_fetch, pc_bytes) {
        f.add(
            format!(
                "{file}: [integrator.restir] field `pc_fetch` = \"{words}\" (the \
                 piecewise-constant levels, {pc} slots, as one storage buffer)"
            ),
            Binding::Storage,
            pc_bytes,
        );
    }
    // The passes read this frame's density from a buffer of its slots' quads, and the
    // ray marches their mips from one buffer of quads, with `density_fetch = "buffer"`,
    // and with "auto" on CPU devices where the larger is at most AUTO_DENSITY_BUFFER_MAX.
    // The density's slots are known here; the mips' only as an upper bound (their levels
    // may be chosen from the content), so under "auto" they count up to that maximum: the
    // estimate never falls short of what is allocated.
    let slots_of = |bricks: u64| -> Result<u64> {
        Ok(atlas_slots(bricks)?.iter().map(|&n| u64::from(n)).product())
    };
    let density_atlas_slots = slots_of(density_slots)?;
    let density_bytes = crate::shader_data::sparse::density_buffer_bytes(density_atlas_slots);
    let march_slots = slots_of(reuse)? * if animated { 2 } else { 1 } + slots_of(nee)?;
    let mut march_bytes = march_slots * crate::shader_data::sparse::MARCH_QUAD_SLOT_BYTES;
    if let Some(words) = buffer_counted(p.settings.density_fetch, density_bytes) {
        if words == "auto" {
            march_bytes = march_bytes.min(crate::shader_data::sparse::AUTO_DENSITY_BUFFER_MAX);
        }
        f.add(
            format!(
                "{file}: [integrator.restir] field `density_fetch` = \"{words}\" (the \
                 density's {density_atlas_slots} slots as one storage buffer)"
            ),
            Binding::Storage,
            density_bytes,
        );
        f.add(
            format!(
                "{file}: [integrator.restir] field `density_fetch` = \"{words}\" (the \
                 ray-march mips, at most {march_slots} slots, as one storage buffer of quads)"
            ),
            Binding::Storage,
            march_bytes,
        );
    }
    f.add(
        format!("{table} (brick indirection of the derived levels)"),
        Binding::Storage,
        cells * 4,
    );
    if let Some(v) = &g.velocity {
        // Dense over the medium's box (an OpenVDB velocity over its dense window).
        let vd = v.dims()?;
        f.add(
            format!("{table} field `velocity`"),
            Binding::Image3d(vd),
            grid_bytes(vd, 8),
        );
        f.host_peak += grid_bytes(vd, 12 + 8);
    }
    // Uploads: two atlas layers, and a chunk of the slot-major levels.
    let chunk = (crate::shader_data::sparse::SLOT_MAJOR_CHUNK_SLOTS * SLOT_TEXELS * 4) as u64;
    f.host_peak +=
        kept + building + cells * 4 + 2 * layer_bytes(pc.max(reuse).max(nee), r32)? + chunk;
    Ok(())
}
