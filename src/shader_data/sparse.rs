//! Sparse grids as the shaders read them (`shaders/include/grid.glsl`): a
//! [`nimbus_scene::BrickGrid`] laid out as slots of 9³ texels (a brick and its high-side
//! apron) in one 3D atlas image, a two-level indirection section (brick → slot) in the shared
//! `grid_bricks[]` buffer, and the [`GridSpaceGpu`] record that says where its index space
//! sits in the world. Atlases are uploaded one layer of slots at a time, so the host never
//! holds a whole atlas.
//!
//! Limits (lavapipe's, and Vulkan's minimum maxImageDimension3D on larger devices): an
//! atlas has at most 455 slots per axis (4095 texels); [`atlas_slots`] refuses more. Its
//! x and y slot counts are powers of two (at most 256), so a shader finds a slot's texels
//! with shifts and masks: `grid_slot_origin` runs on every density lookup, and integer
//! division is slow on GPUs and scalarized on lavapipe (8 lanes x 5 divisions a lookup).

use anyhow::{bail, Result};
use glam::{DMat3, DMat4, DVec3, IVec3};
use nimbus_gpu::{vk, Context, Image};
use nimbus_scene::bricks::{SLOT_EDGE, SLOT_TEXELS};
use nimbus_scene::BrickGrid;

use super::GridSpaceGpu;

/// Bytes per texel of the baseline's density buffer ([`SparseLayout::slot_major_quads`]).
pub const DENSITY_QUAD_BYTES: u64 = 16;
/// Texels per axis of a slot of the baseline's density buffer: from `8b - 1` to `8b + 8`.
pub const DENSITY_SLOT_EDGE: u32 = 10;
/// Texels per slot of the baseline's density buffer.
pub const DENSITY_SLOT_TEXELS: usize = 1000;

/// The largest density buffer `density_fetch = "auto"` takes (on CPU devices): 128 MiB,
/// the storage-buffer range every Vulkan device binds (lavapipe's too), so the footprint
/// knows without a device whether "auto" allocates it.
pub const AUTO_DENSITY_BUFFER_MAX: u64 = 1 << 27;

/// Bytes of the baseline's density buffer for `slots` slots (at least one quad).
pub fn density_buffer_bytes(slots: u64) -> u64 {
    (slots * DENSITY_SLOT_TEXELS as u64 * DENSITY_QUAD_BYTES).max(DENSITY_QUAD_BYTES)
}

/// Most slots along one axis of an atlas: 455 × 9 = 4095 texels.
pub const MAX_ATLAS_SLOTS_PER_AXIS: u32 = 455;

/// The texel format of an atlas.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TexelFormat {
    /// R32F: densities, scalar emission, piecewise-constant levels.
    R32,
    /// R16F: the ray-march mips where every value fits a half float.
    R16,
    /// RGBA32F: rgb emission (alpha 0).
    Rgba32,
}

impl TexelFormat {
    pub fn vk(self) -> vk::Format {
        match self {
            TexelFormat::R32 => vk::Format::R32_SFLOAT,
            TexelFormat::R16 => vk::Format::R16_SFLOAT,
            TexelFormat::Rgba32 => vk::Format::R32G32B32A32_SFLOAT,
        }
    }

    /// Bytes per texel.
    pub fn bytes(self) -> u64 {
        match self {
            TexelFormat::R32 => 4,
            TexelFormat::R16 => 2,
            TexelFormat::Rgba32 => 16,
        }
    }
}

/// Most slots along x or y: the largest power of two within [`MAX_ATLAS_SLOTS_PER_AXIS`].
pub const MAX_ATLAS_SLOTS_XY: u32 = 256;

/// Slots per axis of an atlas of `n` slots (at least 1): x and y powers of two, grown
/// (the smaller first) until x · y · max(x, y) ≥ n, so the atlas is about a cube; z what
/// is left.
pub fn atlas_slots(n: u64) -> Result<[u32; 3]> {
    let n = n.max(1);
    let max_xy = u64::from(MAX_ATLAS_SLOTS_XY);
    let (mut x, mut y) = (1u64, 1u64);
    while x * y * x.max(y) < n && (x < max_xy || y < max_xy) {
        if x <= y {
            x *= 2;
        } else {
            y *= 2;
        }
    }
    let z = n.div_ceil(x * y);
    if z > u64::from(MAX_ATLAS_SLOTS_PER_AXIS) {
        bail!(
            "{n} bricks of 8³ voxels do not fit one 3D atlas ({MAX_ATLAS_SLOTS_XY} x \
             {MAX_ATLAS_SLOTS_XY} x {MAX_ATLAS_SLOTS_PER_AXIS} slots of 9³ texels at most)"
        );
    }
    Ok([x as u32, y as u32, z as u32])
}

/// Atlas texel dims for `slots` per axis.
pub fn atlas_dims(slots: [u32; 3]) -> [u32; 3] {
    slots.map(|s| s * SLOT_EDGE as u32)
}

/// Bytes of an atlas of `n` slots in `format`.
pub fn atlas_bytes(n: u64, format: TexelFormat) -> Result<u64> {
    let dims = atlas_dims(atlas_slots(n)?);
    Ok(dims.iter().map(|&d| u64::from(d)).product::<u64>() * format.bytes())
}

/// Which bricks of a grid get a slot, in slot order, and the indirection to them.
#[derive(Clone, Debug, PartialEq)]
pub struct SparseLayout {
    /// Primed brick coordinates, slot `first_slot + i` holding `bricks[i]`.
    pub bricks: Vec<IVec3>,
    /// The slot of this grid's first brick (grids can share an atlas).
    pub first_slot: u32,
    /// Per brick of `brick_dims` its slot or `NO_BRICK`
    /// ([`nimbus_scene::bricks::indirection`]: one- or two-level).
    pub indirection: nimbus_scene::bricks::Indirection,
    pub brick_dims: [u32; 3],
    /// Slots per axis of the atlas.
    pub slots: [u32; 3],
    /// Each slot's high-x apron holds the occupancy of its brick instead of the neighbour's
    /// values ([`write_occupancy`]): the piecewise-constant levels, which are read without
    /// interpolation and skip empty blocks inside a brick.
    pub occupancy: bool,
}

/// Writes the occupancy of a slot's brick (`texels`: the slot's 9³ values, x fastest, one
/// channel) into its high-x apron, which a piecewise-constant read never takes (it reads
/// the brick's own voxels, texels 0..8 per axis): texel (8, 0, 0) becomes the mask of the
/// brick's 2³ blocks of 4³ voxels, bit x + 2y + 4z set where any voxel of block (x, y, z)
/// is > 0 (or NaN, which validation refuses before). An integer below 256 is an exact
/// float, so the image and the buffer hold it alike. `pc_track`
/// (shaders/restir/pc_tracking.glsl) crosses empty blocks in one step.
pub fn write_occupancy(texels: &mut [f32]) {
    let e = SLOT_EDGE as usize;
    debug_assert_eq!(texels.len(), SLOT_TEXELS);
    let mut mask = 0u32;
    for z in 0..8 {
        for y in 0..8 {
            for x in 0..8 {
                let v = texels[(z * e + y) * e + x];
                if v > 0.0 || v.is_nan() {
                    mask |= 1 << ((x >> 2) + 2 * (y >> 2) + 4 * (z >> 2));
                }
            }
        }
    }
    texels[8] = mask as f32;
}

/// A slot's values of `grid`'s brick `b` (first channel, times `scale`) as `layout`
/// holds them: with its occupancy where the layout keeps one.
fn layout_slot_values(
    layout: &SparseLayout,
    grid: &BrickGrid,
    b: IVec3,
    scale: f32,
    scratch: &mut Vec<f32>,
    out: &mut Vec<f32>,
) {
    scratch.clear();
    grid.slot_texels(b, scale, scratch);
    let start = out.len();
    out.extend(scratch.iter().step_by(grid.channels as usize));
    if layout.occupancy {
        write_occupancy(&mut out[start..]);
    }
}

impl SparseLayout {
    /// `bricks` of `grid` (each inside its indirection) in slot order, in an atlas of its
    /// own with at least `min_slots` slots (animated grids share one atlas size over their
    /// frames).
    pub fn new(grid: &BrickGrid, bricks: Vec<IVec3>, min_slots: u64) -> Result<SparseLayout> {
        let slots = atlas_slots((bricks.len() as u64).max(min_slots))?;
        SparseLayout::new_at(grid, bricks, 0, slots)
    }

    /// `bricks` of `grid` in slots `first_slot ..` of an atlas of `slots` per axis.
    pub fn new_at(
        grid: &BrickGrid,
        bricks: Vec<IVec3>,
        first_slot: u32,
        slots: [u32; 3],
    ) -> Result<SparseLayout> {
        let capacity = slots.iter().map(|&s| u64::from(s)).product::<u64>();
        if u64::from(first_slot) + bricks.len() as u64 > capacity {
            bail!(
                "internal: {} bricks from slot {first_slot} overflow an atlas of {slots:?} slots",
                bricks.len()
            );
        }
        let mut indirection = nimbus_scene::bricks::Indirection::new(grid.brick_dims)?;
        for (i, b) in bricks.iter().enumerate() {
            indirection.set(*b, first_slot + i as u32)?;
        }
        Ok(SparseLayout {
            bricks,
            first_slot,
            indirection,
            brick_dims: grid.brick_dims,
            slots,
            occupancy: false,
        })
    }

    /// The same layout with each slot's occupancy in its apron ([`write_occupancy`]): for
    /// one-channel grids read without interpolation.
    pub fn with_occupancy(self, grid: &BrickGrid) -> Result<SparseLayout> {
        if grid.channels != 1 {
            bail!("internal: occupancy aprons are for one-channel grids");
        }
        Ok(SparseLayout {
            occupancy: true,
            ..self
        })
    }

    /// Atlas texel dims.
    pub fn atlas_dims(&self) -> [u32; 3] {
        atlas_dims(self.slots)
    }

    /// Uploads `grid`'s slot texels (times `scale`) into `atlas` (made with
    /// [`SparseLayout::atlas_dims`] and `format`); see [`upload_atlas`].
    pub fn upload(
        &self,
        ctx: &Context,
        atlas: &Image,
        grid: &BrickGrid,
        scale: f32,
        format: TexelFormat,
    ) -> Result<()> {
        upload_atlas(ctx, atlas, self.slots, &[(self, grid, scale)], format)
    }

    /// The slots of `bricks` as the baseline's density buffer holds them (`grid.glsl`,
    /// NIMBUS_DENSITY_BUFFER): per slot [`DENSITY_SLOT_EDGE`]³ texels from lattice point
    /// `8b - 1` (the brick, its high-side apron and a low-side one, so that every dual cell
    /// of a point of the brick's super-voxel lies in its slot), x fastest, each a quad of
    /// the texel and its +x, +y and +x+y neighbours (clamped to the slot's last texel), so
    /// that a trilinear lookup is two 16-byte loads ([`DENSITY_QUAD_BYTES`] per texel).
    /// Values are the first channel's `get_clamped`, times `scale`: the atlas's values.
    pub fn slot_major_quads(
        grid: &BrickGrid,
        bricks: &[IVec3],
        scale: f32,
        out: &mut Vec<[f32; 4]>,
    ) {
        let e9 = SLOT_EDGE as usize;
        let e = DENSITY_SLOT_EDGE as usize;
        let mut nine = Vec::with_capacity(SLOT_TEXELS);
        let mut texels = vec![0f32; e * e * e];
        for b in bricks {
            nine.clear();
            Self::slot_major_texels(grid, std::slice::from_ref(b), scale, &mut nine);
            let low = *b * 8 - IVec3::ONE;
            for z in 0..e {
                for y in 0..e {
                    for x in 0..e {
                        texels[(z * e + y) * e + x] = if x > 0 && y > 0 && z > 0 {
                            nine[((z - 1) * e9 + y - 1) * e9 + x - 1]
                        } else {
                            let l = low + IVec3::new(x as i32, y as i32, z as i32);
                            grid.get_clamped(l, 0) * scale
                        };
                    }
                }
            }
            push_quads(&texels, e, out);
        }
    }

    /// The first-channel values of `bricks` (consecutive slots of this layout), each
    /// slot's 9^3 values x fastest, times `scale`, appended to `out`.
    pub fn slot_major_texels(grid: &BrickGrid, bricks: &[IVec3], scale: f32, out: &mut Vec<f32>) {
        let mut texels = Vec::with_capacity(SLOT_TEXELS * grid.channels as usize);
        for b in bricks {
            texels.clear();
            grid.slot_texels(*b, scale, &mut texels);
            out.extend(texels.iter().step_by(grid.channels as usize));
        }
    }

    /// The whole atlas's texels (small grids and tests; [`upload_atlas`] never holds
    /// them all).
    pub fn atlas_texels(&self, grid: &BrickGrid, scale: f32, format: TexelFormat) -> Vec<u8> {
        let mut out = Vec::new();
        let mut layer = Vec::new();
        for z in 0..self.slots[2] {
            layer_texels(self.slots, z, &[(self, grid, scale)], format, &mut layer);
            out.extend_from_slice(&layer);
        }
        out
    }
}

/// One part of an atlas: a layout, its grid and the scale of its texels.
pub type AtlasPart<'a> = (&'a SparseLayout, &'a BrickGrid, f32);

/// The texels of slot layer `z` of an atlas of `slots` per axis holding `parts` (slots no
/// part holds are 0), into `out`.
fn layer_texels(
    slots: [u32; 3],
    z: u32,
    parts: &[AtlasPart],
    format: TexelFormat,
    out: &mut Vec<u8>,
) {
    let [sx, sy, _] = slots.map(|s| s as usize);
    let e = SLOT_EDGE as usize;
    let (w, h) = (sx * e, sy * e);
    let texel = format.bytes() as usize;
    out.clear();
    out.resize(w * h * e * texel, 0);
    let mut texels = Vec::with_capacity(SLOT_TEXELS * 3);
    for y in 0..sy {
        for x in 0..sx {
            let slot = ((z as usize * sy + y) * sx + x) as u32;
            let found = parts.iter().find_map(|(layout, grid, scale)| {
                let i = slot.checked_sub(layout.first_slot)? as usize;
                layout
                    .bricks
                    .get(i)
                    .map(|b| (*b, *grid, *scale, layout.occupancy))
            });
            let Some((b, grid, scale, occupancy)) = found else {
                continue;
            };
            texels.clear();
            grid.slot_texels(b, scale, &mut texels);
            if occupancy {
                write_occupancy(&mut texels);
            }
            let ch = grid.channels as usize;
            for (n, v) in texels.chunks_exact(ch).enumerate() {
                let (i, j, k) = (n % e, (n / e) % e, n / (e * e));
                let at = ((k * h + y * e + j) * w + x * e + i) * texel;
                write_texel(&mut out[at..at + texel], v, format);
            }
        }
    }
}

/// Bytes of a slot-major R32 buffer of `slots` slots ([`upload_slot_major`]; at least one
/// texel, so that a buffer can always be bound).
pub fn slot_major_bytes(slots: u64) -> u64 {
    (slots * SLOT_TEXELS as u64 * 4).max(4)
}

/// Slots per upload of [`upload_slot_major`] (1.5 MB): the host never holds more than a
/// chunk.
pub const SLOT_MAJOR_CHUNK_SLOTS: usize = 512;

/// Uploads the slot texels of `parts` (first channel, R32) into `buffer` slot after slot
/// from slot 0, each slot's 9³ texels x fastest (`float pc_texels[slot * 729 + texel]`,
/// the ReSTIR passes' piecewise-constant levels on CPU devices): the atlas's values
/// without its image addressing. Slots no part holds keep what the buffer held.
pub fn upload_slot_major(
    ctx: &Context,
    buffer: &nimbus_gpu::Buffer,
    parts: &[AtlasPart],
) -> Result<()> {
    const CHUNK: usize = SLOT_MAJOR_CHUNK_SLOTS;
    let mut texels = Vec::with_capacity(SLOT_TEXELS * 3);
    let mut out: Vec<f32> = Vec::with_capacity(CHUNK * SLOT_TEXELS);
    for (layout, grid, scale) in parts {
        for (c, bricks) in layout.bricks.chunks(CHUNK).enumerate() {
            out.clear();
            for b in bricks {
                layout_slot_values(layout, grid, *b, *scale, &mut texels, &mut out);
            }
            let slot = u64::from(layout.first_slot) + (c * CHUNK) as u64;
            ctx.upload_buffer(
                buffer,
                slot * SLOT_TEXELS as u64 * 4,
                bytemuck::cast_slice(&out),
            )?;
        }
    }
    Ok(())
}

/// Appends the quads of a slot of `e`^3 texels (x fastest): per texel, it and its +x, +y
/// and +x+y neighbours, clamped to the slot's last texel.
fn push_quads(texels: &[f32], e: usize, out: &mut Vec<[f32; 4]>) {
    let at = |x: usize, y: usize, z: usize| texels[(z * e + y) * e + x];
    for z in 0..e {
        for y in 0..e {
            let y1 = (y + 1).min(e - 1);
            for x in 0..e {
                let x1 = (x + 1).min(e - 1);
                out.push([at(x, y, z), at(x1, y, z), at(x, y1, z), at(x1, y1, z)]);
            }
        }
    }
}

/// Bytes per slot of a ray-march mip's buffer of quads ([`upload_march_quads`]).
pub const MARCH_QUAD_SLOT_BYTES: u64 = SLOT_TEXELS as u64 * 16;

/// Uploads the march mip `grid`'s slots of `layout` into `buffer` as ReSTIR's ray marches
/// read them where SC_MARCH_BUFFER (`restir/transmittance.glsl`): from slot `base` on,
/// slot after slot, each slot's 9^3 texels x fastest, each a quad of the texel and its
/// +x, +y and +x+y neighbours in the slot (clamped to its last texel), so that a linearly
/// filtered sample is two 16-byte loads. Values are the atlas's: rounded through a half
/// float where the atlas is `TexelFormat::R16`. A chunk of slots at a time.
pub fn upload_march_quads(
    ctx: &Context,
    buffer: &nimbus_gpu::Buffer,
    base: u64,
    layout: &SparseLayout,
    grid: &BrickGrid,
    format: TexelFormat,
) -> Result<()> {
    const CHUNK: usize = SLOT_MAJOR_CHUNK_SLOTS;
    let e = SLOT_EDGE as usize;
    let mut scratch = Vec::with_capacity(SLOT_TEXELS * 3);
    let mut nine: Vec<f32> = Vec::with_capacity(SLOT_TEXELS);
    let mut out: Vec<[f32; 4]> = Vec::with_capacity(CHUNK * SLOT_TEXELS);
    for (c, bricks) in layout.bricks.chunks(CHUNK).enumerate() {
        out.clear();
        for b in bricks {
            nine.clear();
            layout_slot_values(layout, grid, *b, 1.0, &mut scratch, &mut nine);
            if format == TexelFormat::R16 {
                for v in &mut nine {
                    *v = half::f16::from_f32(*v).to_f32();
                }
            }
            push_quads(&nine, e, &mut out);
        }
        let slot = base + u64::from(layout.first_slot) + (c * CHUNK) as u64;
        ctx.upload_buffer(
            buffer,
            slot * MARCH_QUAD_SLOT_BYTES,
            bytemuck::cast_slice(&out),
        )?;
    }
    Ok(())
}

/// Uploads the slot texels of `parts` into `atlas` (`slots` per axis, `format`), one layer
/// of slots at a time; slots no part holds are 0.
pub fn upload_atlas(
    ctx: &Context,
    atlas: &Image,
    slots: [u32; 3],
    parts: &[AtlasPart],
    format: TexelFormat,
) -> Result<()> {
    let [w, h, _] = atlas_dims(slots);
    let mut layer = Vec::new();
    for z in 0..slots[2] {
        layer_texels(slots, z, parts, format, &mut layer);
        ctx.upload_image_region(
            atlas,
            [0, 0, z * SLOT_EDGE as u32],
            [w, h, SLOT_EDGE as u32],
            &layer,
        )?;
    }
    Ok(())
}

fn write_texel(out: &mut [u8], v: &[f32], format: TexelFormat) {
    match format {
        TexelFormat::R32 => out.copy_from_slice(&v[0].to_le_bytes()),
        TexelFormat::R16 => out.copy_from_slice(&half::f16::from_f32(v[0]).to_bits().to_le_bytes()),
        TexelFormat::Rgba32 => {
            for c in 0..4 {
                let x = if v.len() == 1 {
                    if c < 3 {
                        v[0]
                    } else {
                        0.0
                    }
                } else {
                    v.get(c).copied().unwrap_or(0.0)
                };
                out[4 * c..4 * c + 4].copy_from_slice(&x.to_le_bytes());
            }
        }
    }
}

/// The [`GridSpaceGpu`] of `grid` laid out as `layout`, its indirection at
/// `bricks_offset`, p-space mapped to the world by `p_to_world`. `world_box` is the exact
/// world box of a grid known to be axis-aligned (a `type = "grid"` medium's bounds);
/// without it a transform whose linear part is a positive diagonal is axis-aligned too,
/// with the box it maps the p-space box to.
pub fn grid_space(
    grid: &BrickGrid,
    layout: &SparseLayout,
    bricks_offset: u32,
    p_to_world: DMat4,
    world_box: Option<(glam::Vec3, glam::Vec3)>,
) -> GridSpaceGpu {
    let linear = DMat3::from_mat4(p_to_world);
    let diagonal = [
        linear.x_axis.y,
        linear.x_axis.z,
        linear.y_axis.x,
        linear.y_axis.z,
        linear.z_axis.x,
        linear.z_axis.y,
    ]
    .iter()
    .all(|v| *v == 0.0)
        && linear.x_axis.x > 0.0
        && linear.y_axis.y > 0.0
        && linear.z_axis.z > 0.0;
    let map = |p: DVec3| (p_to_world * p.extend(1.0)).truncate().as_vec3();
    let (box_min, box_max) = match world_box {
        Some(b) => b,
        None => (map(grid.index_min), map(grid.index_max)),
    };
    let inverse = p_to_world.inverse();
    let row = |r: usize| inverse.row(r).as_vec4().to_array();
    GridSpaceGpu {
        world_to_index_x: row(0),
        world_to_index_y: row(1),
        world_to_index_z: row(2),
        box_min: box_min.to_array(),
        axis_aligned: u32::from(world_box.is_some() || diagonal),
        box_max: box_max.to_array(),
        bricks_offset: layout.indirection.tagged_offset(bricks_offset),
        index_min: grid.index_min.as_vec3().to_array(),
        slots_x: layout.slots[0],
        index_max: grid.index_max.as_vec3().to_array(),
        slots_y: layout.slots[1],
        lattice_min: grid.lattice_min.to_array(),
        channels: grid.channels,
        lattice_max: grid.lattice_max.to_array(),
        _pad0: 0,
        brick_dims: layout.brick_dims,
        _pad1: 0,
    }
}

/// The indirection sections of a pass, concatenated into one `grid_bricks[]` buffer:
/// every section's head first (a one-level section whole, a two-level one's top table),
/// then the two-level sections' leaf tables. A section's offset so depends only on the
/// heads before it, which depend only on the grids' dims: an animated grid's sections
/// keep their offsets from frame to frame while its occupied nodes change.
#[derive(Clone, Debug, Default)]
pub struct Indirection {
    entries: Vec<u32>,
    /// Two-level sections' leaf tables: (section offset, head length, leaf entries).
    pending: Vec<(usize, usize, Vec<u32>)>,
    total: u64,
}

impl Indirection {
    /// Appends a section; returns the offset the shaders read it at (tagged two-level
    /// where it is: [`nimbus_scene::bricks::Indirection::tagged_offset`]).
    pub fn push(&mut self, section: &nimbus_scene::bricks::Indirection) -> Result<u32> {
        self.total += section.len() as u64;
        if self.total >= u64::from(nimbus_scene::bricks::indirection::TWO_LEVEL) {
            bail!("the grids' brick indirection sections exceed 2^31 entries");
        }
        let offset = self.entries.len();
        let head = head_len(section);
        self.entries.extend_from_slice(&section.entries[..head]);
        if head < section.len() {
            self.pending
                .push((offset, head, section.entries[head..].to_vec()));
        }
        Ok(section.tagged_offset(offset as u32))
    }

    /// The buffer: the heads, then the leaf tables, each top entry pointing at its
    /// table relative to its section's offset.
    pub fn finish(mut self) -> Vec<u32> {
        for (offset, head, leaves) in std::mem::take(&mut self.pending) {
            let at = self.entries.len();
            for e in &mut self.entries[offset..offset + head] {
                if *e != nimbus_scene::bricks::NO_BRICK {
                    *e = (at + (*e as usize - head) - offset) as u32;
                }
            }
            self.entries.extend(leaves);
        }
        self.entries
    }
}

/// Entries of a section's head: all of a one-level one, a two-level one's top table.
pub fn head_len(section: &nimbus_scene::bricks::Indirection) -> usize {
    if section.two_level {
        nimbus_scene::bricks::indirection::top_cells(section.dims) as usize
    } else {
        section.len()
    }
}

/// Bytes of one layer of slots of an atlas of `n` slots: what [`SparseLayout::upload`]
/// holds at once (and its staging buffer again).
pub fn layer_bytes(n: u64, format: TexelFormat) -> Result<u64> {
    let [sx, sy, _] = atlas_slots(n)?;
    Ok(u64::from(sx) * u64::from(sy) * SLOT_TEXELS as u64 * format.bytes())
}

/// An upper bound of the slots a grid of topology `topo` gets: its bricks and their 26
/// neighbours (`all_neighbours`: the super-voxels of a density), or their 7 lower
/// neighbours (whose aprons reach into them: the slots of any other grid).
pub fn slot_bound(topo: &nimbus_scene::BrickTopology, all_neighbours: bool) -> u64 {
    let dims = topo.brick_dims().map(|d| d as i32);
    let range = if all_neighbours { -1..=1 } else { -1..=0 };
    let mut set = std::collections::HashSet::new();
    for b in &topo.bricks {
        for z in range.clone() {
            for y in range.clone() {
                for x in range.clone() {
                    let n = *b + IVec3::new(x, y, z);
                    if n.cmpge(IVec3::ZERO).all() && n.cmplt(IVec3::from_array(dims)).all() {
                        set.insert(n);
                    }
                }
            }
        }
    }
    set.len() as u64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_occupancy_apron_masks_the_bricks_nonempty_blocks_of_4_cubed() {
        let e = SLOT_EDGE as usize;
        let at = |x: usize, y: usize, z: usize| (z * e + y) * e + x;
        let mut texels = vec![0f32; SLOT_TEXELS];
        // The high-x apron's neighbour values are not occupancy.
        for z in 0..e {
            for y in 0..e {
                texels[at(8, y, z)] = 7.0;
            }
        }
        write_occupancy(&mut texels);
        assert_eq!(texels[at(8, 0, 0)], 0.0, "an empty brick masks nothing");
        // One voxel in block (1, 0, 1) (bit 1 + 4 = 5), one in block (0, 1, 0) (bit 2), a
        // negative value (not > 0) in block (1, 1, 1).
        texels[at(5, 3, 4)] = 0.25;
        texels[at(0, 7, 0)] = 1e-30;
        texels[at(7, 7, 7)] = -1.0;
        write_occupancy(&mut texels);
        assert_eq!(texels[at(8, 0, 0)], ((1u32 << 5) | (1 << 2)) as f32);
        // Nothing else moved: the brick's voxels and the rest of the apron.
        assert_eq!(texels[at(5, 3, 4)], 0.25);
        assert_eq!(texels[at(8, 1, 0)], 7.0);
        assert_eq!(texels[at(8, 0, 1)], 7.0);
        // Every block occupied: all 8 bits, an exact float.
        for z in (0..8).step_by(4) {
            for y in (0..8).step_by(4) {
                for x in (0..8).step_by(4) {
                    texels[at(x + 3, y, z + 1)] = 2.0;
                }
            }
        }
        write_occupancy(&mut texels);
        assert_eq!(texels[at(8, 0, 0)] as u32, 255);
    }

    #[test]
    fn atlas_slots_hold_every_slot_in_power_of_two_rows() {
        for n in [1u64, 2, 7, 8, 9, 65, 512, 600, 4097, 100_000, 3_000_000] {
            let [x, y, z] = atlas_slots(n).expect("fits");
            assert!(x.is_power_of_two() && y.is_power_of_two(), "{n}: {x} x {y}");
            assert!(x <= MAX_ATLAS_SLOTS_XY && y <= MAX_ATLAS_SLOTS_XY);
            assert!(z <= MAX_ATLAS_SLOTS_PER_AXIS);
            let capacity = u64::from(x) * u64::from(y) * u64::from(z);
            assert!(capacity >= n, "{n}: {x} x {y} x {z}");
            // Never more than one spare layer of slots, and no long thin atlas.
            assert!(
                capacity < n + u64::from(x) * u64::from(y),
                "{n}: {x} x {y} x {z}"
            );
            assert!(x <= 2 * y && y <= 2 * x, "{n}: {x} x {y}");
        }
        assert!(atlas_slots(256 * 256 * 455 + 1).is_err());
    }
}
