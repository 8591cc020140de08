//! The velocity grid of temporal reprojection: its texels and the map from world points
//! to its texture.

use anyhow::Result;
use nimbus_scene::GridMedium;

/// Voxels a velocity may move a point per frame before Nimbus says so: more is what a
/// file of units per second read as metres per frame looks like (a Houdini `vel` at 24
/// fps moves 24 times too far), and it smears a still scene into streaks.
pub const VELOCITY_NOTE_VOXELS: f32 = 4.0;

/// The velocity grid as dense RGBA16F texels over the medium's box (an OpenVDB one over
/// its dense window, as the loader cuts it), in metres per frame (times
/// `velocity_scale`), and a note when it moves a point more than
/// [`VELOCITY_NOTE_VOXELS`] density voxels per frame.
#[allow(clippy::type_complexity)]
pub fn velocity_texels(
    grid: &GridMedium,
    label: &str,
    density_dims: [u32; 3],
) -> Result<Option<([u32; 3], Vec<u16>, Option<String>)>> {
    let Some(source) = &grid.velocity else {
        return Ok(None);
    };
    let v = nimbus_scene::load_grid(source, 3, &format!("{label} > velocity"))?;
    let scale = grid.velocity_scale;
    let texels = v
        .data
        .chunks_exact(3)
        .flat_map(|c| [c[0], c[1], c[2], 0.0].map(|x| half::f16::from_f32(x * scale).to_bits()))
        .collect();
    let speed = v
        .data
        .chunks_exact(3)
        .map(|c| glam::Vec3::new(c[0], c[1], c[2]).length() * scale)
        .fold(0.0f32, f32::max);
    let size = grid.bounds_max - grid.bounds_min;
    let voxel = (0..3)
        .map(|a| size[a] / density_dims[a].max(1) as f32)
        .fold(f32::INFINITY, f32::min);
    let voxels = speed / voxel;
    let note = (voxels > VELOCITY_NOTE_VOXELS).then(|| {
        format!(
            "{label} > velocity moves points up to {voxels:.1} voxels per frame (|v| up to \
             {speed:.3} m/frame after velocity_scale = {scale}): velocities are metres per \
             frame; if the file holds units per second (Houdini, EmberGen), set \
             velocity_scale = 1/fps (times metres per unit)"
        )
    });
    Ok(Some((v.dims, texels, note)))
}

/// Rows of the affine map from a world point to the velocity texture's coordinates: the
/// medium's box for `type = "grid"`; for `type = "vdb"` the index space of the velocity's
/// dense window (voxel `d` holds lattice point `origin + d`, or `origin + dims - 1 - d`
/// along a flipped axis) through the inverse of the medium's index-to-world transform.
pub fn velocity_uvw(grid: &GridMedium) -> [[f32; 4]; 3] {
    use glam::{DMat4, DVec3};
    let to_uvw = match (&grid.vdb, &grid.velocity) {
        (Some(placement), Some(nimbus_scene::GridSource::Vdb { window, .. })) => {
            let dims = DVec3::from_array(window.dims.map(f64::from));
            // Lattice point l -> (l - origin + 0.5) / dims, mirrored where flipped.
            let mut scale = dims.recip();
            let mut offset = (DVec3::splat(0.5) - window.origin.as_dvec3()) / dims;
            for a in 0..3 {
                if window.flip[a] {
                    scale[a] = -scale[a];
                    offset[a] = 1.0 - offset[a];
                }
            }
            DMat4::from_translation(offset)
                * DMat4::from_scale(scale)
                * placement.index_to_world.inverse()
        }
        _ => {
            let (lo, hi) = (grid.bounds_min.as_dvec3(), grid.bounds_max.as_dvec3());
            DMat4::from_scale((hi - lo).recip()) * DMat4::from_translation(-lo)
        }
    };
    let row = |r: usize| -> [f32; 4] { to_uvw.row(r).as_vec4().to_array() };
    [row(0), row(1), row(2)]
}

#[cfg(test)]
mod tests {
    use glam::{DVec3, Vec4};
    use nimbus_scene::{GridSource, Medium};

    use super::velocity_uvw;

    /// The map from world points to the velocity texture puts each dense voxel's centre
    /// at its texel centre: for an axis-aligned window with a flipped axis (the box
    /// formula the shader used before) and for a rotated grid (through the inverse
    /// index-to-world transform).
    #[test]
    fn velocity_texel_centres_map_to_their_voxels() {
        let file = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/test-vdb/multi.vdb");
        for to_world in [
            "{ scale = [2, -1, 0.5], translate = [1, 2, -3] }",
            "{ scale = [2, -1, 0.5], rotate_deg = [20, 35, -10], translate = [1, 2, -3] }",
        ] {
            let text = format!(
                "[render]\nwidth = 4\nheight = 4\n[camera]\nposition = [0, 0, 40]\n\
                 look_at = [0, 0, 0]\n[[light]]\ntype = \"environment\"\nradiance = 1\n\
                 [[medium]]\ntype = \"vdb\"\ndensity = {{ file = \"{file}\" }}\n\
                 velocity = {{ file = \"{file}\", grid = \"vel\" }}\nto_world = {to_world}\n"
            );
            let scene = nimbus_scene::parse_str(&text, std::path::Path::new("t.toml"))
                .unwrap_or_else(|e| panic!("{e:#}"));
            let Some(Medium::Grid(g)) = scene.media.first() else {
                panic!("a grid medium")
            };
            let Some(GridSource::Vdb { window, .. }) = &g.velocity else {
                panic!("a vdb velocity")
            };
            let rows = velocity_uvw(g).map(Vec4::from_array).map(|r| r.as_dvec4());
            let uvw = |x: DVec3| {
                let h = x.extend(1.0);
                DVec3::new(rows[0].dot(h), rows[1].dot(h), rows[2].dot(h))
            };
            let placement = g.vdb.as_ref().unwrap();
            let dims = DVec3::from_array(window.dims.map(f64::from));
            let (lo, hi) = (g.bounds_min.as_dvec3(), g.bounds_max.as_dvec3());
            for d in [
                [0, 0, 0],
                [1, 2, 3],
                [window.dims[0] - 1, 0, window.dims[2] - 1],
            ] {
                let d = DVec3::from_array(d.map(f64::from));
                let texel = (d + 0.5) / dims;
                // Dense voxel d holds lattice point origin + d, mirrored where flipped.
                let l = DVec3::from_array([0, 1, 2].map(|a| {
                    let o = f64::from(window.origin[a]);
                    if window.flip[a] {
                        o + dims[a] - 1.0 - d[a]
                    } else {
                        o + d[a]
                    }
                }));
                let x = (placement.index_to_world * l.extend(1.0)).truncate();
                assert!(
                    uvw(x).abs_diff_eq(texel, 1e-5),
                    "{to_world}: {d} {}",
                    uvw(x)
                );
                if !to_world.contains("rotate") {
                    assert_eq!(window.flip, [false, true, false]);
                    let centre = lo + texel * (hi - lo);
                    assert!(uvw(centre).abs_diff_eq(texel, 1e-5), "{to_world}: box {d}");
                }
            }
        }
    }
}
