//! What a render will allocate, known before anything is: every GPU buffer and image
//! with its size and the scene field it comes from, and the host memory at its peak.
//!
//! A leaf: [`Footprint`] and its parts know nothing of the plan, the passes or the
//! renderer. The plan computes a render's footprint (`Footprint::of`, in
//! `crate::plan::footprint`) from what the scene file and the headers of the files it
//! names say (grid dims, environment-map sizes), never the data; the renderer alone
//! calls [`Footprint::check`], which
//! compares it with the device's limits (`maxStorageBufferRange`, image dimensions,
//! `maxMemoryAllocationSize`, the device-local heap) and with the host memory budget,
//! and refuses a render that does not fit, naming the file and field, before any
//! allocation. A test compares the footprint with what the passes really create.

use std::fmt::Write as _;

use anyhow::{bail, Result};
use nimbus_gpu::DeviceInfo;
use nimbus_scene::bricks::procedural_super_voxel_test;
use nimbus_scene::{BrickTopology, GridMedium, GridSource, Light, Medium, Scene};

use crate::shader_data::sparse::{
    atlas_bytes, atlas_dims, atlas_slots, layer_bytes, slot_bound, TexelFormat,
};

/// How a GPU allocation is bound, which decides the limits it must meet.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Binding {
    Storage,
    Image3d([u32; 3]),
}

/// One GPU allocation of a render.
#[derive(Clone, Debug, PartialEq)]
pub struct Need {
    /// The scene field it comes from, e.g. `scene.toml: [[medium]] #1 field `density``.
    pub what: String,
    pub binding: Binding,
    pub bytes: u64,
}

/// The GPU allocations of a render and its peak host memory.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Footprint {
    pub device: Vec<Need>,
    /// Peak bytes the host holds for the scene's data while the render is built (grids,
    /// their derived levels, environment maps and tables, staging copies).
    pub host_peak: u64,
}

/// What [`Footprint::add_grid`] found, for what a pass adds on top.
pub struct GridFootprint<'s> {
    pub medium: &'s GridMedium,
    /// The medium's table, e.g. `scene.toml: [[medium]] #1 (type = "grid")`.
    pub table: String,
    /// The base density's bricks.
    pub density: BrickTopology,
    /// The bound of the density's slots.
    pub density_slots: u64,
}

/// An upper bound of the atlas slots of a density of topology `topo` read from `source`:
/// the bricks whose super-voxel may hold density. For the procedural cloud that is its
/// formula's own bound per super-voxel (its topology is already a bound, and growing it
/// by every neighbour would claim nearly the whole box); otherwise the stored bricks and
/// their 26 neighbours.
pub fn density_slot_bound(source: &GridSource, topo: &BrickTopology) -> u64 {
    match source {
        GridSource::ProceduralCloud {
            dims,
            noise_seed,
            kind,
        } => {
            let may_be_nonzero = procedural_super_voxel_test(*dims, *noise_seed, *kind);
            let [bx, by, bz] = topo.brick_dims().map(|d| d as i32);
            let mut n = 0u64;
            for z in 0..bz {
                for y in 0..by {
                    for x in 0..bx {
                        let b = glam::IVec3::new(x, y, z);
                        n += u64::from(may_be_nonzero(b));
                    }
                }
            }
            n
        }
        _ => slot_bound(topo, true),
    }
}

/// Bytes of the values of a grid's stored bricks.
pub fn brick_bytes(topo: &BrickTopology) -> u64 {
    topo.bricks.len() as u64 * 512 * 4 * u64::from(topo.channels.max(1))
}

/// Bytes of the film's partial-sum buffer: two vec4 per pixel where a frame's samples
/// may be shared among dispatches (a device with a loop budget), one element elsewhere.
pub fn film_partial_bytes(shared_frames: bool, pixels: u64) -> u64 {
    if shared_frames {
        pixels * 32
    } else {
        32
    }
}

/// Bytes of a `dims` grid of `bytes_per_voxel`.
pub fn grid_bytes(dims: [u32; 3], bytes_per_voxel: u64) -> u64 {
    dims.iter().map(|&d| u64::from(d)).product::<u64>() * bytes_per_voxel
}

/// Dims of mip level `level` (each halving rounds up), clamped at the 1×1×1 level.
pub fn level_dims(dims: [u32; 3], level: u32) -> [u32; 3] {
    let mut d = dims;
    for _ in 0..level {
        if d == [1, 1, 1] {
            break;
        }
        d = d.map(|n| n.div_ceil(2).max(1));
    }
    d
}

/// The environment map's size from its header, if the scene has one.
fn env_map_size(scene: &Scene) -> Result<Option<(String, [u32; 2])>> {
    for (i, light) in scene.lights.iter().enumerate() {
        if let Light::Environment {
            file: Some(file), ..
        } = light
        {
            let what = format!(
                "{}: [[light]] #{} (type = \"environment\") field `file` ({})",
                scene.source.display(),
                i + 1,
                file.display()
            );
            let size = nimbus_scene::EnvMap::read_size(file)
                .map_err(|e| anyhow::anyhow!("{what}: {e:#}"))?;
            return Ok(Some((what, size)));
        }
    }
    Ok(None)
}

impl Footprint {
    /// Adds one GPU allocation.
    pub fn add(&mut self, what: impl Into<String>, binding: Binding, bytes: u64) {
        self.device.push(Need {
            what: what.into(),
            binding,
            bytes,
        });
    }

    /// The environment map's texels and sampling tables, if the scene has a map.
    pub fn add_env_map(&mut self, scene: &Scene) -> Result<()> {
        if let Some((what, [w, h])) = env_map_size(scene)? {
            let texels = u64::from(w) * u64::from(h);
            self.add(format!("{what}: texels"), Binding::Storage, texels * 16);
            self.add(
                format!("{what}: sampling tables"),
                Binding::Storage,
                (texels + u64::from(h) * 2 + 1) * 4,
            );
            // Texels (f32 RGB) + sampler (f64 weights and CDF) + the GPU copies.
            self.host_peak += texels * (12 + 8 + 8 + 16 + 4);
        }
        Ok(())
    }

    /// The scene's meshes: one buffer of every mesh's BVH nodes and one of their leaf
    /// triangles (`crate::shader_data::meshes`), known exactly from the BVHs built when the
    /// scene loaded; at least one record each. The host holds both once more while
    /// they are uploaded (the meshes themselves are part of the loaded scene).
    pub fn add_meshes(&mut self, scene: &Scene) {
        use crate::shader_data::meshes::{mesh_counts, BVH_NODE_BYTES, MESH_TRIANGLE_BYTES};
        let (nodes, triangles) = mesh_counts(scene);
        let file = scene.source.display();
        let what = |kind: &str| format!("{file}: [[shape]] type = \"mesh\" ({kind})");
        let node_bytes = nodes.max(1) * BVH_NODE_BYTES;
        let triangle_bytes = triangles.max(1) * MESH_TRIANGLE_BYTES;
        self.add(
            what(&format!("{nodes} BVH nodes")),
            Binding::Storage,
            node_bytes,
        );
        self.add(
            what(&format!("{triangles} triangles")),
            Binding::Storage,
            triangle_bytes,
        );
        self.host_peak += node_bytes + triangle_bytes;
    }

    /// The emitter table of the scene's emitting shapes (`crate::shader_data::emitters`): one
    /// record per primitive, at least one; the host holds it once more while uploading.
    pub fn add_emitters(&mut self, scene: &Scene) {
        use crate::shader_data::emitters::{emitter_primitives, EMITTER_BYTES};
        let primitives: u64 = scene
            .shapes
            .iter()
            .map(|s| u64::from(emitter_primitives(s)))
            .sum();
        let bytes = primitives.max(1) * EMITTER_BYTES;
        self.add(
            format!(
                "{}: [[shape]] emission ({primitives} emitter primitives)",
                scene.source.display()
            ),
            Binding::Storage,
            bytes,
        );
        self.host_peak += bytes;
    }

    /// The scene's grid medium as the grid integrators upload it: the density's atlas,
    /// its super-voxel records, the emission's atlas, the indirection sections, and the
    /// host copies. Reads the grids' topology (which bricks they store: OpenVDB files up
    /// to their tree's topology, dense files scanned slab by slab) but keeps no values.
    /// Slots are bounded from above by the stored bricks' neighbourhoods. Returns what a
    /// pass adds on top.
    pub fn add_grid<'s>(&mut self, scene: &'s Scene) -> Result<Option<GridFootprint<'s>>> {
        let file = scene.source.display();
        let Some((index, g)) = scene.media.iter().enumerate().find_map(|(i, m)| match m {
            Medium::Grid(g) => Some((i, g)),
            _ => None,
        }) else {
            return Ok(None);
        };
        let kind = if g.vdb.is_some() { "vdb" } else { "grid" };
        let table = format!("{file}: [[medium]] #{} (type = \"{kind}\")", index + 1);
        let what = format!("{file}: [[medium]] #{} > density", index + 1);
        let density = BrickTopology::of(&g.density, 1, &what)?;
        let slots = density_slot_bound(&g.density, &density);
        let r32 = TexelFormat::R32;
        let atlas = atlas_bytes(slots, r32)?;
        self.add(
            format!("{table} field `density` (atlas of {slots} bricks)"),
            Binding::Image3d(atlas_dims(atlas_slots(slots)?)),
            atlas,
        );
        self.add(
            format!("{table} field `density` (super-voxels)"),
            Binding::Storage,
            slots.max(1) * 16,
        );
        let mut cells = density.cells();
        // The bricks as read, the grid's own indirection and the layout's, the
        // super-voxels (coordinates, bounds, records), one layer being uploaded and its
        // staging copy.
        self.host_peak += brick_bytes(&density)
            + 2 * density.cells() * 4
            + slots * (12 + 12 + 16)
            + 2 * layer_bytes(slots, r32)?;
        // The grids that do not change per frame, each an atlas and an indirection
        // section (one empty entry without it): emission and albedo (1 or 3 channels),
        // temperature (1, with the blackbody table).
        let statics = [
            ("emission", g.emission.as_ref(), 0),
            ("albedo", g.albedo_grid.as_ref(), 0),
            ("temperature", g.temperature.as_ref().map(|t| &t.source), 1),
        ];
        for (field, source, channels) in statics {
            let Some(source) = source else {
                cells += 1;
                continue;
            };
            let what = format!("{file}: [[medium]] #{} > {field}", index + 1);
            let e = BrickTopology::of(source, channels, &what)?;
            let slots = slot_bound(&e, false);
            let format = if e.channels == 3 {
                TexelFormat::Rgba32
            } else {
                r32
            };
            self.add(
                format!("{table} field `{field}` (atlas of {slots} bricks)"),
                Binding::Image3d(atlas_dims(atlas_slots(slots)?)),
                atlas_bytes(slots, format)?,
            );
            cells += e.cells();
            self.host_peak +=
                brick_bytes(&e) + 2 * e.cells() * 4 + slots * 12 + 2 * layer_bytes(slots, format)?;
        }
        if g.temperature.is_some() {
            let table_bytes = (nimbus_scene::blackbody::BLACKBODY_TABLE_LEN * 16) as u64;
            self.add(
                format!("{table} (blackbody table)"),
                Binding::Storage,
                table_bytes,
            );
            self.host_peak += table_bytes;
        }
        self.add(
            format!("{table} (brick indirection)"),
            Binding::Storage,
            cells * 4,
        );
        self.host_peak += cells * 4;
        Ok(Some(GridFootprint {
            medium: g,
            table,
            density,
            density_slots: slots,
        }))
    }

    /// Total device bytes.
    pub fn device_bytes(&self) -> u64 {
        self.device.iter().map(|n| n.bytes).sum()
    }

    /// Refuses what the device or the host cannot hold, naming the scene field.
    pub fn check(&self, info: &DeviceInfo, host_budget: u64) -> Result<()> {
        let mib = |b: u64| b as f64 / f64::from(1u32 << 20);
        for need in &self.device {
            let (limit, limit_name) = match need.binding {
                Binding::Storage => (
                    u64::from(info.max_storage_buffer_range),
                    "maxStorageBufferRange",
                ),
                Binding::Image3d(d) => {
                    let max = info.max_image_dimension_3d;
                    if d.iter().any(|&n| n > max) {
                        bail!(
                            "{}: a {}x{}x{} 3D texture exceeds device '{}''s \
                             maxImageDimension3D of {max} texels per axis",
                            need.what,
                            d[0],
                            d[1],
                            d[2],
                            info.name
                        );
                    }
                    (u64::MAX, "")
                }
            };
            if need.bytes > limit {
                bail!(
                    "{}: needs a {:.1} MiB buffer; device '{}' allows {:.1} MiB ({limit_name})",
                    need.what,
                    mib(need.bytes),
                    info.name,
                    mib(limit)
                );
            }
            let alloc = info.max_memory_allocation_size;
            if alloc > 0 && need.bytes > alloc {
                bail!(
                    "{}: needs a {:.1} MiB allocation; device '{}' allows {:.1} MiB \
                     (maxMemoryAllocationSize)",
                    need.what,
                    mib(need.bytes),
                    info.name,
                    mib(alloc)
                );
            }
        }
        let total = self.device_bytes();
        if info.device_local_bytes > 0 && total > info.device_local_bytes {
            let mut largest: Vec<&Need> = self.device.iter().collect();
            largest.sort_by_key(|n| std::cmp::Reverse(n.bytes));
            let mut list = String::new();
            for n in largest.iter().take(3) {
                let _ = write!(list, "\n  {:.1} MiB  {}", mib(n.bytes), n.what);
            }
            bail!(
                "this render needs {:.1} MiB of GPU memory; device '{}' has {:.1} MiB. \
                 The largest parts:{list}",
                mib(total),
                info.name,
                mib(info.device_local_bytes)
            );
        }
        // A CPU device (lavapipe) keeps its "device" memory in host memory.
        let host = self.host_peak
            + if info.device_type == nimbus_gpu::vk::PhysicalDeviceType::CPU {
                total
            } else {
                0
            };
        if host > host_budget {
            bail!(
                "this render needs about {:.1} MiB of host memory at its peak; the budget is \
                 {:.1} MiB (available memory, or NIMBUS_HOST_MEMORY_BUDGET in MiB)",
                mib(host),
                mib(host_budget)
            );
        }
        Ok(())
    }
}

/// The host memory a render may use: `NIMBUS_HOST_MEMORY_BUDGET` (MiB) if set, else
/// the `MemAvailable` of `/proc/meminfo`, else 8 GiB.
pub fn host_budget() -> Result<u64> {
    if let Ok(text) = std::env::var("NIMBUS_HOST_MEMORY_BUDGET") {
        return match text.trim().parse::<u64>() {
            Ok(mib) if mib > 0 => Ok(mib << 20),
            _ => bail!("NIMBUS_HOST_MEMORY_BUDGET={text:?}: expected a whole number of MiB > 0"),
        };
    }
    let available = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|text| {
            text.lines()
                .find_map(|l| l.strip_prefix("MemAvailable:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
        })
        .map(|kib| kib << 10);
    Ok(available.unwrap_or(8 << 30))
}

/// Fields of `/proc/self/status` in bytes (`VmHWM`, `VmRSS`, ...), if known.
fn status_bytes(field: &str) -> Option<u64> {
    let text = std::fs::read_to_string("/proc/self/status").ok()?;
    let kib = text
        .lines()
        .find_map(|l| l.strip_prefix(field)?.strip_prefix(':'))?
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse::<u64>()
        .ok()?;
    Some(kib << 10)
}

/// The peak resident memory before [`mark_host_memory`] reset the kernel's, and the
/// resident memory at that moment (0: not marked).
static PEAK_BEFORE_MARK: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
static RESIDENT_AT_MARK: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// The process's peak resident memory (`VmHWM` of `/proc/self/status`, or the peak
/// before [`mark_host_memory`] reset it where that was higher), if known.
pub fn peak_host_bytes() -> Option<u64> {
    let before = PEAK_BEFORE_MARK.load(std::sync::atomic::Ordering::Relaxed);
    Some(status_bytes("VmHWM")?.max(before))
}

/// Marks the host memory once the render is under way, so that what later frames add
/// can be told from the setup's peak: it keeps the peak so far and the resident memory
/// now, and resets the kernel's peak (`5` to `/proc/self/clear_refs`). The setup's peak
/// (the shader compiler's, on lavapipe) is larger than anything a frame holds and varies
/// between runs by tens of MiB with how the pipelines' compiles overlap in their threads,
/// which hid a leak of a few MiB a frame when two renders' peaks were compared. Once a
/// process; nothing where `/proc` says nothing. Where the peak cannot be reset,
/// [`host_growth_since_mark`] measures the resident memory at its call instead.
pub fn mark_host_memory() {
    use std::sync::atomic::Ordering::Relaxed;
    if RESIDENT_AT_MARK.load(Relaxed) != 0 {
        return;
    }
    let (Some(peak), Some(resident)) = (status_bytes("VmHWM"), status_bytes("VmRSS")) else {
        return;
    };
    let reset = std::fs::write("/proc/self/clear_refs", "5").is_ok();
    PEAK_RESET.store(reset, Relaxed);
    if reset {
        PEAK_BEFORE_MARK.store(peak, Relaxed);
    }
    RESIDENT_AT_MARK.store(resident.max(1), Relaxed);
}

/// Whether [`mark_host_memory`] reset the kernel's peak.
static PEAK_RESET: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// How far the resident memory rose above what it was at [`mark_host_memory`]: at its
/// peak since, or where the peak could not be reset, now; None if it was never marked.
pub fn host_growth_since_mark() -> Option<u64> {
    use std::sync::atomic::Ordering::Relaxed;
    let at_mark = RESIDENT_AT_MARK.load(Relaxed);
    (at_mark != 0).then_some(())?;
    let field = if PEAK_RESET.load(Relaxed) {
        "VmHWM"
    } else {
        "VmRSS"
    };
    Some(status_bytes(field)?.saturating_sub(at_mark))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn level_dims_halve_rounding_up_and_stop_at_one() {
        assert_eq!(level_dims([64, 40, 64], 0), [64, 40, 64]);
        assert_eq!(level_dims([64, 40, 64], 1), [32, 20, 32]);
        assert_eq!(level_dims([5, 3, 1], 2), [2, 1, 1]);
        assert_eq!(level_dims([5, 3, 1], 16), [1, 1, 1]);
    }
}
