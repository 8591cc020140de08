//! The AOV layers of a rendered image, from the buffers the shaders wrote
//! (`shaders/include/aov.glsl`, laid out by [`crate::plan::AovPlan`]).
//!
//! Names (OpenEXR's `layer.channel`; `docs/scene-format.md`, "Output layers (AOVs)"):
//! `Z` (one channel, no layer), `N.X/Y/Z`, `albedo.R/G/B`, `motion.X/Y` (geometric: the
//! image's last frame), and the path estimates `emission`, `direct`, `indirect`,
//! `lightgroup.<name>` (`.R/G/B`, the mean over the image's frames) each with its
//! standard error as the layer `<layer>_stderr` (`direct_stderr.R`, ...), computed as the
//! beauty's is ([`super::film::estimate`]: from the frames' spread, or from batch means).

use nimbus_scene::Aov as AovKind;

use super::film::{estimate, Batches, Totals};
use crate::output::layers::Aov;
use crate::plan::AovPlan;

/// The channel names of a path AOV's or colour layer's three values.
const RGB: [&str; 3] = ["R", "G", "B"];

/// The suffix of the layer of a path AOV's standard errors.
pub const STDERR_SUFFIX: &str = "_stderr";

/// The path AOVs' sums as read back: slot-major, `pixels` values per slot.
pub struct PathSums<'a> {
    pub sum: &'a [[f32; 4]],
    pub sum_sq: &'a [[f32; 4]],
    pub frames: u32,
    /// One per slot where the beauty's error comes from batch means.
    pub batches: Option<&'a [Batches]>,
}

/// A layer of `planes.len()` channels named `names`.
fn layer(name: &str, names: &[&str], planes: Vec<Vec<f32>>) -> Aov {
    Aov {
        name: name.to_string(),
        channels: names.iter().map(|c| c.to_string()).zip(planes).collect(),
    }
}

/// The layers `plan` asks for, of a `size` image: `geometry` holds
/// `AOV_GEOMETRY_VEC4S` vec4 per pixel (empty without geometric AOVs).
pub fn layers(
    plan: &AovPlan,
    size: (u32, u32),
    geometry: &[[f32; 4]],
    paths: &PathSums,
) -> Vec<Aov> {
    let pixels = size.0 as usize * size.1 as usize;
    let stride = crate::shader_data::features::AOV_GEOMETRY_VEC4S as usize;
    let geo = |vec: usize, c: usize| -> Vec<f32> {
        (0..pixels)
            .map(|i| geometry.get(i * stride + vec).map_or(0.0, |v| v[c]))
            .collect()
    };
    // The mean and standard error of path slot `slot`.
    let path = |slot: usize| -> (Vec<Vec<f32>>, Vec<Vec<f32>>) {
        let range = slot * pixels..(slot + 1) * pixels;
        let totals = Totals {
            sum: paths.sum.get(range.clone()).unwrap_or_default().to_vec(),
            sum_sq: paths.sum_sq.get(range).unwrap_or_default().to_vec(),
            frames: paths.frames,
        };
        let e = estimate(&totals, paths.batches.and_then(|b| b.get(slot)));
        let plane = |v: &[[f32; 4]], c: usize| v.iter().map(|x| x[c]).collect::<Vec<f32>>();
        (
            (0..3).map(|c| plane(&e.mean, c)).collect(),
            (0..3).map(|c| plane(&e.std_error, c)).collect(),
        )
    };
    let mut out = Vec::new();
    let push_path = |out: &mut Vec<Aov>, name: &str, slot: usize| {
        let (mean, se) = path(slot);
        out.push(layer(name, &RGB, mean));
        out.push(layer(&format!("{name}{STDERR_SUFFIX}"), &RGB, se));
    };
    for aov in &plan.asked {
        match aov {
            AovKind::Depth => out.push(layer("", &["Z"], vec![geo(0, 3)])),
            AovKind::Normal => out.push(layer(
                "N",
                &["X", "Y", "Z"],
                vec![geo(0, 0), geo(0, 1), geo(0, 2)],
            )),
            AovKind::Albedo => {
                out.push(layer("albedo", &RGB, vec![geo(1, 0), geo(1, 1), geo(1, 2)]))
            }
            AovKind::Emission => push_path(&mut out, "emission", 0),
            AovKind::Direct => push_path(&mut out, "direct", 1),
            AovKind::Indirect => push_path(&mut out, "indirect", 2),
            AovKind::LightGroups => {
                for (g, name) in plan.groups.iter().enumerate() {
                    push_path(&mut out, &format!("lightgroup.{name}"), plan.group_slot(g));
                }
            }
            AovKind::Motion => out.push(layer("motion", &["X", "Y"], vec![geo(2, 0), geo(2, 1)])),
        }
    }
    out
}

/// Whether a layer (by name) holds geometric AOVs: deterministic, the same in every part
/// of a merge (`nimbus merge` takes the first part's).
pub fn is_geometric_layer(name: &str) -> bool {
    matches!(name, "" | "N" | "albedo" | "motion")
}
