//! Sparse storage is invisible in the image: a small procedural cloud rendered as a tight
//! grid and as the same voxels at an offset inside a much larger grid (most of whose 8³
//! bricks are empty, so the atlas, the indirection and every walk's empty-brick skipping
//! are exercised, with the cloud cut by brick borders at other places) give the same
//! image within noise, with the baseline path tracer and with ReSTIR. The world placement
//! and the trilinear field are identical: the cloud is 0 on its outermost voxel layer, so
//! the tight grid's clamped border equals the padding's zeros. Validation layers are on.

use std::path::Path;

use nimbus_scene::{procedural_cloud, BrickGrid, VoxelGrid};

use crate::common::cli::scratch;
use crate::common::gpu::{assert_means_agree, channels_beyond, context, render_checked, scene};
use crate::common::scenes::STEEP_SUN_AND_GREY_SKY;

/// World size of one voxel (both grids).
const VOXEL: f64 = 0.1;
/// The tight grid's box starts here.
const ORIGIN: [f64; 3] = [-1.0, -0.7, -0.9];

fn write_raw(dir: &Path, name: &str, g: &VoxelGrid) -> String {
    let file = dir.join(name);
    let bytes: Vec<u8> = g.data.iter().flat_map(|v| v.to_le_bytes()).collect();
    std::fs::write(&file, bytes).unwrap();
    file.display().to_string()
}

/// The `[[medium]]` lines of grid `g` whose voxel `offset` sits at ORIGIN.
fn medium(file: &str, g: &VoxelGrid, offset: [u32; 3]) -> String {
    let lo = [0, 1, 2].map(|a| ORIGIN[a] - f64::from(offset[a]) * VOXEL);
    let hi = [0, 1, 2].map(|a| lo[a] + f64::from(g.dims[a]) * VOXEL);
    format!(
        "type = \"grid\"\nbounds_min = [{}, {}, {}]\nbounds_max = [{}, {}, {}]\n\
         density = {{ file = \"{file}\", dims = [{}, {}, {}] }}",
        lo[0], lo[1], lo[2], hi[0], hi[1], hi[2], g.dims[0], g.dims[1], g.dims[2]
    )
}

/// `tight` at voxel offset (13, 22, 9) inside a 61x45x53 grid of zeros (mostly empty
/// bricks), and that offset.
fn padded_cloud(tight: &VoxelGrid) -> (VoxelGrid, [u32; 3]) {
    let offset = [13u32, 22, 9];
    let dims = [61u32, 45, 53];
    let mut padded = VoxelGrid {
        dims,
        channels: 1,
        data: vec![0.0; dims.iter().map(|&d| d as usize).product()],
    };
    for k in 0..tight.dims[2] {
        for j in 0..tight.dims[1] {
            for i in 0..tight.dims[0] {
                let (x, y, z) = (i + offset[0], j + offset[1], k + offset[2]);
                padded.data[((z * dims[1] + y) * dims[0] + x) as usize] = tight.get(i, j, k);
            }
        }
    }
    (padded, offset)
}

/// The scene around `medium`. ReSTIR renders without temporal reuse here: its frames are
/// then independent, so the renders' standard errors are honest at 8 frames (with the
/// default temporal limit of 20 they would be batch means of 84 frames).
fn scene_text(medium: &str, volume: &str) -> String {
    // ReSTIR draws one path per pixel per frame (the plan refuses spp > 1 for it).
    let spp = if volume == "restir" { 1 } else { 2 };
    format!(
        r#"
[render]
width = 40
height = 30
frames = 8
spp = {spp}
seed = 3
[camera]
position = [0.2, 0.5, 3.2]
look_at = [0.0, 0.0, 0.0]
horizontal_fov_deg = 45
{STEEP_SUN_AND_GREY_SKY}
[[medium]]
{medium}
density_scale = 12.0
albedo = 0.85
g = 0.4
[integrator]
volume = "{volume}"
max_bounces = 2
[integrator.restir]
temporal = false
"#
    )
}

/// The tight and the padded grid render alike (every channel's mean within 4 combined
/// standard errors + 0.5 %, at most 2 % of the pixel channels beyond 4.5, the bounds of
/// vdb_render's twin test), and the padded grid is mostly empty bricks.
#[test]
fn a_grid_padded_with_empty_bricks_renders_as_the_tight_grid() {
    let ctx = context();
    let dir = scratch("grid_sparse", "padded");
    let tight = procedural_cloud([20, 14, 18], 3);
    let (padded, offset) = padded_cloud(&tight);
    let bricks = BrickGrid::from_dense(&padded).unwrap();
    let total: u32 = bricks.brick_dims.iter().product();
    assert!(
        bricks.bricks.len() * 4 < total as usize,
        "{} of {total} bricks stored: the padding must be mostly empty bricks",
        bricks.bricks.len()
    );
    let a = medium(&write_raw(&dir, "tight.raw", &tight), &tight, [0; 3]);
    let b = medium(&write_raw(&dir, "padded.raw", &padded), &padded, offset);
    for volume in ["baseline", "restir"] {
        let ra = render_checked(&ctx, &scene(&scene_text(&a, volume), "tight.toml"), None);
        let rb = render_checked(&ctx, &scene(&scene_text(&b, volume), "padded.toml"), None);
        // The cloud covers the centre: its camera ray's coverage (1 - the closed-form
        // transmittance) is far from 0 (the radiance there is a noisy estimate that can
        // land near the sky's 0.2).
        let coverage = ra.alpha[15 * 40 + 20];
        assert!(
            coverage > 0.2,
            "{volume}: the cloud is seen, coverage {coverage}"
        );
        let (ea, eb) = ((&ra.image, &ra.std_error), (&rb.image, &rb.std_error));
        assert_means_agree(&format!("{volume}: tight vs padded"), ea, eb, 4.0, 0.005);
        let beyond = channels_beyond(ea, eb, 4.5);
        let channels = 3 * ea.0.data.len();
        println!("  {beyond} of {channels} channels beyond 4.5 SE");
        assert!(
            beyond * 50 <= channels,
            "{volume}: {beyond} channels beyond 4.5 SE"
        );
    }
}

/// The baseline reads the density from the atlas image or from a storage buffer of its
/// slots (`[integrator.baseline] density_fetch`; "auto" takes the buffer on lavapipe): the
/// same values in the same arithmetic, so the same image and alpha to the bit, on a grid
/// of mostly empty bricks (indirection, empty-brick skipping) with a hot voxel (the exact
/// spans and the closed form, which read it too). The plan names the choice.
#[test]
fn the_baseline_reads_the_density_alike_from_its_atlas_image_and_its_buffer() {
    let ctx = context();
    let dir = scratch("grid_sparse", "density_fetch");
    let (mut padded, offset) = padded_cloud(&procedural_cloud([20, 14, 18], 3));
    let dims = padded.dims;
    // One hot voxel: its super-voxel's spans are tracked exactly.
    let hot = ((offset[2] + 9) * dims[1] + offset[1] + 7) * dims[0] + offset[0] + 10;
    padded.data[hot as usize] = 400.0;
    let grid = medium(&write_raw(&dir, "padded.raw", &padded), &padded, offset);
    let render = |fetch: &str| {
        let text = format!(
            "{}[integrator.baseline]\ndensity_fetch = \"{fetch}\"\n",
            scene_text(&grid, "baseline")
        );
        let scene = scene(&text, &format!("{fetch}.toml"));
        let plan = nimbus::plan::build(&scene, None).expect("plan");
        let row = plan
            .decisions
            .iter()
            .find(|d| d.name.trim() == "SC_DENSITY_BUFFER")
            .expect("an SC_DENSITY_BUFFER row");
        assert!(row.reason.contains(fetch), "{}", row.reason);
        render_checked(&ctx, &scene, None)
    };
    let image = render("image");
    for fetch in ["buffer", "auto"] {
        let other = render(fetch);
        assert_eq!(image.image.data, other.image.data, "{fetch}: RGB");
        assert_eq!(image.alpha, other.alpha, "{fetch}: alpha");
    }
    assert!(image.alpha[15 * 40 + 20] > 0.2, "the cloud is seen");
}

/// The padded cloud written to `dir` as a grid medium's lines, and a `[[medium.frame]]`
/// table that swaps another cloud in at frame 2.
fn cloud_and_frame(dir: &Path) -> (String, String) {
    let (padded, offset) = padded_cloud(&procedural_cloud([20, 14, 18], 3));
    let grid = medium(&write_raw(dir, "padded.raw", &padded), &padded, offset);
    let (other, _) = padded_cloud(&procedural_cloud([20, 14, 18], 9));
    let frames = format!(
        "[[medium.frame]]\nframe = 2\ndensity = {{ file = {:?}, dims = {:?} }}\n",
        dir.join("other.raw").display().to_string(),
        other.dims
    );
    write_raw(dir, "other.raw", &other);
    (grid, frames)
}

/// Renders ReSTIR on `grid` with `settings` (its `[integrator.restir]` lines, then any
/// tables: the frames' table follows the whole scene, so it belongs to the last medium),
/// after checking that the plan's `row` names `fetch`.
fn render_restir(
    ctx: &nimbus_gpu::Context,
    grid: &str,
    name: &str,
    settings: &str,
    row: &str,
    fetch: &str,
) -> nimbus::renderer::RenderResult {
    let text = scene_text(grid, "restir").replace("temporal = false\n", settings);
    let scene = scene(&text, &format!("{name}.toml"));
    let plan = nimbus::plan::build(&scene, None).expect("plan");
    let decision = plan
        .decisions
        .iter()
        .find(|d| d.name.trim() == row)
        .unwrap_or_else(|| panic!("an {row} row"));
    assert!(decision.reason.contains(fetch), "{}", decision.reason);
    render_checked(ctx, &scene, None)
}

/// ReSTIR's regular tracking reads the piecewise-constant levels from their atlas image
/// or from a slot-major storage buffer (`[integrator.restir] pc_fetch`; "auto" takes the
/// buffer on lavapipe): the same values, so the same image and alpha to the bit, on the
/// padded grid (empty bricks at both levels) and on density frames that swap clouds
/// (the buffer is uploaded again with each frame's levels). The plan names the choice.
#[test]
fn restir_reads_its_piecewise_constant_levels_alike_from_the_atlas_and_the_buffer() {
    let ctx = context();
    let dir = scratch("grid_sparse", "pc_fetch");
    let (grid, frames) = cloud_and_frame(&dir);
    for (name, extra) in [("static", ""), ("frames", frames.as_str())] {
        let render = |fetch: &str| {
            let settings = format!("temporal = false\npc_fetch = \"{fetch}\"\n{extra}");
            render_restir(
                &ctx,
                &grid,
                &format!("{name}-{fetch}"),
                &settings,
                "SC_PC_BUFFER",
                fetch,
            )
        };
        let image = render("image");
        for fetch in ["buffer", "auto"] {
            let other = render(fetch);
            assert_eq!(image.image.data, other.image.data, "{name}, {fetch}: RGB");
            assert_eq!(image.alpha, other.alpha, "{name}, {fetch}: alpha");
        }
        assert!(image.alpha[15 * 40 + 20] > 0.2, "{name}: the cloud is seen");
    }
}

/// ReSTIR reads this frame's density (vertices, delta-tracked walks, the walked and the
/// final closed-form transmittance) from its atlas image or from the baseline's storage
/// buffer of quads, and its ray marches read their mips from linearly filtered atlases or
/// from a buffer of quads (`[integrator.restir] density_fetch`; "auto" takes the buffers
/// on lavapipe), with regular and with delta-tracked candidates, under temporal reuse, and
/// on density frames that swap clouds (the buffers are uploaded again with each frame).
/// The density's values are the same; a march sample's trilinear weights round as the
/// sampler's do or not, so the targets may differ in their last bits: every pixel agrees
/// within 1e-4 relative but a few where that flips a selection (a march read from the
/// wrong texels flips most). The plan names the choice.
#[test]
fn restir_reads_its_density_alike_from_the_atlas_and_the_buffer() {
    let ctx = context();
    let dir = scratch("grid_sparse", "restir_density_fetch");
    let (grid, frames) = cloud_and_frame(&dir);
    // Regular tracking on the static cloud; delta tracking ("auto" under density frames),
    // whose temporal reuse also evaluates the previous frame's density, on the frames.
    for (name, extra) in [
        ("regular", "candidate_tracking = \"regular\"\n"),
        ("frames", frames.as_str()),
    ] {
        let render = |fetch: &str| {
            let settings = format!("temporal = true\ndensity_fetch = \"{fetch}\"\n{extra}");
            let row = "SC_DENSITY_BUFFER";
            render_restir(
                &ctx,
                &grid,
                &format!("{name}-{fetch}"),
                &settings,
                row,
                fetch,
            )
        };
        let image = render("image");
        let close = |a: f32, b: f32| (a - b).abs() <= 1e-4 * a.abs().max(b.abs()) + 1e-7;
        for fetch in ["buffer", "auto"] {
            let other = render(fetch);
            let apart = image
                .image
                .data
                .iter()
                .zip(&other.image.data)
                .filter(|(a, b)| (0..3).any(|c| !close(a[c], b[c])))
                .count();
            assert!(
                apart * 200 <= image.image.data.len(),
                "{name}, {fetch}: {apart} of {} pixels differ",
                image.image.data.len()
            );
            let alpha_apart = image
                .alpha
                .iter()
                .zip(&other.alpha)
                .filter(|(a, b)| !close(**a, **b))
                .count();
            assert!(
                alpha_apart * 200 <= image.alpha.len(),
                "{name}, {fetch}: {alpha_apart} alphas differ"
            );
        }
        assert!(image.alpha[15 * 40 + 20] > 0.2, "{name}: the cloud is seen");
    }
}

/// `candidate_tracking = "auto"` where the plan takes regular tracking (a static density
/// under temporal reuse whose candidates' level fits the field): a pass that reads the
/// density from its buffer of quads takes delta tracking instead
/// (`RestirPlan::with_density_buffer`: an exact lookup costs there as little as a
/// conservative-grid one) and says so; one that reads the atlas keeps regular tracking.
/// Each renders as the explicit setting does, to the bit.
#[test]
fn auto_tracking_takes_delta_tracking_where_the_density_is_read_from_its_buffer() {
    let ctx = context();
    let dir = scratch("grid_sparse", "auto_tracking");
    // A smooth blob, which the coarse grid fits (the procedural clouds' voxel-scale detail
    // does not, even at mip 0, so the plan takes delta tracking for them itself).
    let n = 24u32;
    let mut blob = VoxelGrid {
        dims: [n; 3],
        channels: 1,
        data: Vec::new(),
    };
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let r2 = [i, j, k]
                    .map(|c| (c as f32 + 0.5) / n as f32 - 0.5)
                    .iter()
                    .map(|c| c * c)
                    .sum::<f32>();
                blob.data.push((-r2 / 0.03).exp());
            }
        }
    }
    let grid = medium(&write_raw(&dir, "blob.raw", &blob), &blob, [0; 3]);
    let render = |fetch: &str, tracking: &str| {
        let settings = format!(
            "temporal = true\ndensity_fetch = \"{fetch}\"\ncandidate_tracking = \"{tracking}\"\n"
        );
        let text = scene_text(&grid, "restir").replace("temporal = false\n", &settings);
        let scene = scene(&text, &format!("{fetch}-{tracking}.toml"));
        let plan = nimbus::plan::build(&scene, None).expect("plan");
        let planned_delta = plan.restir().expect("a ReSTIR plan").candidate_delta;
        let why = plan
            .decisions
            .iter()
            .find(|d| d.name.trim() == "SC_CANDIDATE_DELTA")
            .map(|d| d.reason.clone())
            .unwrap_or_default();
        ((planned_delta, why), render_checked(&ctx, &scene, None))
    };
    let said = |r: &nimbus::renderer::RenderResult| {
        r.notes
            .iter()
            .any(|n| n.contains("candidate_tracking = \"auto\": delta tracking"))
    };
    let ((planned_delta, why), auto) = render("buffer", "auto");
    assert!(
        !planned_delta,
        "the plan takes regular tracking for this cloud: {why}"
    );
    let (_, delta) = render("buffer", "delta");
    let (_, regular) = render("buffer", "regular");
    assert!(auto.image.data == delta.image.data, "auto renders as delta");
    assert!(
        auto.image.data != regular.image.data,
        "the trackings differ"
    );
    assert!(said(&auto), "{:?}", auto.notes);
    assert!(!said(&delta), "{:?}", delta.notes);
    let (_, auto) = render("image", "auto");
    let (_, regular) = render("image", "regular");
    assert!(
        auto.image.data == regular.image.data,
        "auto renders as regular"
    );
    assert!(!said(&auto), "{:?}", auto.notes);
}
