//! The footprint a render is checked against before it allocates anything
//! (`nimbus::budget`) is what the passes really create, and what does not fit is refused
//! with a message naming the scene field, before any allocation.

use std::path::PathBuf;

use nimbus::budget::Footprint;
use nimbus::plan;
use nimbus_scene::FieldOverride;

use crate::common::gpu::{context, render_checked};

fn asset(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("assets/scenes")
        .join(name)
}

/// For every integrator (the box pass, the baseline, ReSTIR static and animated), the
/// estimate bounds the bytes the render created from above, and is not loose: at least
/// half of it is really allocated; a third for the procedural clouds, whose bricks are
/// bounded from their formula per super-voxel without evaluating it (at 256x160x256,
/// seed 7, the cumulus of the cloud scenes claims 4 289 slots for the 3 501 super-voxels
/// it fills, 1.2x; the `"cloud"` ellipsoid 6 468 for 2 430, 2.7x), and ReSTIR's levels
/// chosen from the content (`"auto"`, when the plan is built; the footprint reads file
/// headers only) are counted at the finest they can be (measured 2.8x for
/// cloud-restir.toml, 2.5x for cloud-logo.toml). (It counts
/// ReSTIR's half-float ray-march mips as f32 unless the density is the procedural cloud,
/// whose values lie in [0, 1], and leaves out records of a few bytes.)
#[test]
fn footprint_matches_what_the_passes_create_slow() {
    let ctx = context();
    for name in [
        "window.toml",
        "cloud.toml",
        "cloud-restir.toml",
        "plume-anim.toml",
        "cloud-logo.toml",
    ] {
        let overrides = [
            FieldOverride::new("render.width", 40),
            FieldOverride::new("render.height", 30),
            FieldOverride::new("render.frames", 1),
        ];
        let scene = nimbus_scene::load_with(&asset(name), &overrides).unwrap();
        let plan = plan::build(&scene, None).unwrap();
        let estimate = Footprint::of(&scene, &plan).unwrap().device_bytes();
        let actual = render_checked(&ctx, &scene, None).device_bytes;
        // Records the estimate leaves out: lights, uniforms, stats (< 64 KiB).
        let slack = 64 << 10;
        let least = if name.starts_with("cloud") { 3 } else { 2 };
        assert!(
            actual <= estimate + slack && least * actual >= estimate,
            "{name}: {actual} bytes allocated, {estimate} estimated"
        );
    }
}

/// A render that exceeds the device's storage-buffer range is refused before any
/// allocation, naming the scene file and the field that sets the size.
#[test]
fn oversized_buffers_are_refused_naming_the_field() {
    let ctx = context();
    let limit = u64::from(ctx.info().max_storage_buffer_range);
    // ReSTIR's reservoirs: 2 or 3 slots x (32 + 8 K) bytes per pixel; pick K and a size that
    // exceed the range while the accumulation buffers still fit.
    let side = 2048u32;
    let pixels = u64::from(side) * u64::from(side);
    assert!(
        pixels * 16 <= limit,
        "the accumulation buffers must fit for this test"
    );
    assert!(
        2 * pixels * (32 + 8 * 16) > limit,
        "the reservoirs must not"
    );
    let overrides = [
        FieldOverride::new("render.width", i64::from(side)),
        FieldOverride::new("render.height", i64::from(side)),
        FieldOverride::new("integrator.max_bounces", 16),
    ];
    let scene = nimbus_scene::load_with(&asset("cloud-restir.toml"), &overrides).unwrap();
    let plan = plan::build(&scene, None).unwrap();
    let err = match nimbus::renderer::render(&ctx, &scene, &plan, &Default::default()) {
        Ok(_) => panic!("a render beyond maxStorageBufferRange was accepted"),
        Err(e) => e.to_string(),
    };
    assert!(
        err.contains("cloud-restir.toml")
            && err.contains("max_bounces")
            && err.contains("maxStorageBufferRange"),
        "{err}"
    );
    crate::common::gpu::assert_no_validation_errors(&ctx);
}

/// The footprint of `cloud.toml` at 32x24 with `overrides`.
fn small_cloud_footprint(overrides: &[FieldOverride]) -> Footprint {
    let mut all = vec![
        FieldOverride::new("render.width", 32),
        FieldOverride::new("render.height", 24),
    ];
    all.extend_from_slice(overrides);
    let scene = nimbus_scene::load_with(&asset("cloud.toml"), &all).unwrap();
    let plan = plan::build(&scene, None).unwrap();
    Footprint::of(&scene, &plan).unwrap()
}

/// Checks that `footprint` is refused on `info` for a storage buffer beyond its range,
/// naming the scene file and `field` (`[table] field `name``).
fn assert_refused_for_the_buffer_range(
    footprint: &Footprint,
    info: &nimbus_gpu::DeviceInfo,
    field: &str,
) {
    let err = footprint
        .check(info, u64::MAX)
        .expect_err("a buffer beyond the range was accepted")
        .to_string();
    assert!(
        err.contains("cloud.toml") && err.contains(field) && err.contains("maxStorageBufferRange"),
        "{err}"
    );
}

/// `[integrator.baseline] density_fetch = "buffer"` puts the density's slots in one
/// storage buffer: on a device whose storage-buffer range cannot hold them the render is
/// refused by the footprint check (before any allocation), naming the scene file and the
/// field; `"auto"`, which takes the buffer only where every device binds it, passes.
#[test]
fn a_density_buffer_beyond_the_storage_buffer_range_is_refused_naming_the_field() {
    let ctx = context();
    let mut info = ctx.info().clone();
    // The cloud's density slots take tens of MiB; everything else of this small image
    // (the film, the sky map's 2 MiB of texels) fits 4 MiB.
    info.max_storage_buffer_range = 4 << 20;
    let footprint = |fetch: &str| {
        small_cloud_footprint(&[
            FieldOverride::new("integrator.volume", "baseline"),
            FieldOverride::new("integrator.baseline.density_fetch", fetch),
        ])
    };
    assert_refused_for_the_buffer_range(
        &footprint("buffer"),
        &info,
        "[integrator.baseline] field `density_fetch`",
    );
    // "auto" takes the buffer only up to 128 MiB, the range every Vulkan device binds: it
    // passes on a device with just that range.
    info.max_storage_buffer_range = 1 << 27;
    footprint("auto")
        .check(&info, u64::MAX)
        .expect("auto takes a buffer every device binds");
}

/// The same for ReSTIR's piecewise-constant levels (`[integrator.restir] pc_fetch`) and
/// its density (`density_fetch`): a buffer beyond the device's storage-buffer range is
/// refused before any allocation, naming the file and the field; "auto" takes it only
/// where every device binds it.
#[test]
fn restir_buffers_beyond_the_storage_buffer_range_are_refused_naming_the_field() {
    let ctx = context();
    for (field, other) in [("pc_fetch", "density_fetch"), ("density_fetch", "pc_fetch")] {
        let mut info = ctx.info().clone();
        // The other buffer stays out, so that the range refuses this one alone.
        let footprint = |fetch: &str| {
            small_cloud_footprint(&[
                FieldOverride::new("render.spp", 1),
                FieldOverride::new("integrator.volume", "restir"),
                FieldOverride::new(&format!("integrator.restir.{field}"), fetch),
                FieldOverride::new(&format!("integrator.restir.{other}"), "image"),
            ])
        };
        let bytes = |f: &Footprint| {
            f.device
                .iter()
                .find(|i| i.what.contains(&format!("field `{field}`")))
                .map(|i| i.bytes)
        };
        let buffer = footprint("buffer");
        let counted = bytes(&buffer).expect("the buffer is counted");
        assert_eq!(
            bytes(&footprint("image")),
            None,
            "{field} = \"image\" allocates no buffer"
        );
        // A range just below the buffer (everything else of this small image fits it).
        info.max_storage_buffer_range = u32::try_from(counted - 4).unwrap();
        assert_refused_for_the_buffer_range(
            &buffer,
            &info,
            &format!("[integrator.restir] field `{field}`"),
        );
        info.max_storage_buffer_range = 1 << 27;
        footprint("auto")
            .check(&info, u64::MAX)
            .expect("auto takes a buffer every device binds");
    }
}
