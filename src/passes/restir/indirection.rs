//! The brick indirection of a frame: every grid's section in the `grid_bricks[]`
//! buffer, this frame's derived levels and the previous frame's.

use anyhow::Result;

use super::volumes::DerivedVolume;
use crate::shader_data::sparse::Indirection;

/// Where each grid's indirection section starts in the `grid_bricks[]` buffer. Without
/// density frames the previous frame's sections are this frame's.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Sections {
    pub density: u32,
    pub emission: u32,
    pub temperature: u32,
    pub albedo: u32,
    pub density_prev: u32,
    pub pc_primary: u32,
    pub pc_indirect: u32,
    pub march_reuse: u32,
    pub march_reuse_prev: u32,
    pub march_nee: u32,
}

/// The indirection buffer of frame `cur` with previous frame `prev`, and its sections.
pub fn indirection(
    cur: &DerivedVolume,
    prev: &DerivedVolume,
    statics: &[nimbus_scene::bricks::Indirection; 3],
    animated: bool,
) -> Result<(Vec<u32>, Sections)> {
    let mut ind = Indirection::default();
    let density = ind.push(&cur.density_layout.indirection)?;
    let emission = ind.push(&statics[0])?;
    let temperature = ind.push(&statics[1])?;
    let albedo = ind.push(&statics[2])?;
    let density_prev = if animated {
        ind.push(&prev.density_layout.indirection)?
    } else {
        density
    };
    let pc_primary = ind.push(&cur.pc_primary_layout.indirection)?;
    let pc_indirect = ind.push(&cur.pc_indirect_layout.indirection)?;
    let march_reuse = ind.push(&cur.march_reuse_layout.indirection)?;
    let march_reuse_prev = if animated {
        ind.push(&prev.march_reuse_layout.indirection)?
    } else {
        march_reuse
    };
    let march_nee = ind.push(&cur.march_nee_layout.indirection)?;
    Ok((
        ind.finish(),
        Sections {
            density,
            emission,
            temperature,
            albedo,
            density_prev,
            pc_primary,
            pc_indirect,
            march_reuse,
            march_reuse_prev,
            march_nee,
        },
    ))
}
