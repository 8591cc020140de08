//! What 32-bit float positions can resolve, and the scenes that stay inside it.
//!
//! The renderer computes every position in f32: a point the renderer computes is known
//! to about one unit in the last place of its largest coordinate. A scene reaching `R`
//! metres from the origin (its *extent*: camera positions, media, shapes, positioned
//! lights) therefore has a **position resolution** δ = R · 2⁻²³. Two things go wrong
//! below it, and both render wrong images silently rather than failing:
//!
//! - **Features** (a box's size, a voxel, a quad edge, a sphere's radius, a gobo edge)
//!   much smaller than δ are misplaced by a large fraction of themselves. Every feature
//!   must span at least [`MIN_FEATURE_RESOLUTIONS`] = 256 resolutions (0.4 % error).
//! - **Optical depth** across a position error: where a medium's extinction jumps
//!   (a box medium's faces, a grid's boundary voxels, a steep step between voxels),
//!   a point misplaced by δ misjudges the optical depth to the boundary by σt · δ.
//!   Nimbus requires σt · δ ≤ [`MAX_OPTICAL_RESOLUTION`] = 1/256 (0.4 % in
//!   transmittance), i.e. a mean free path of at least 256 resolutions. In a trilinear
//!   grid a ramp is not a jump: light enters where the optical depth from clear space
//!   reaches ~1, and the extinction there is what is checked
//!   ([`grid_effective_sigma_t`]); an opaque interior is never reached.
//!
//! A scene outside these limits is refused before anything is allocated, with the
//! largest value that would render right and the farthest point that sets δ, so the
//! remedy (move the scene closer to the origin, scale it, lower σt) is plain.

use glam::Vec3;

use crate::types::{Light, Medium, Scene, Shape};
use crate::volume::VoxelGrid;

/// f32 epsilon (2⁻²³): the relative spacing of f32 values.
pub const F32_EPSILON: f64 = f32::EPSILON as f64;
/// A feature must span at least this many position resolutions.
pub const MIN_FEATURE_RESOLUTIONS: f64 = 256.0;
/// Largest σt · δ (optical depth across one position resolution).
pub const MAX_OPTICAL_RESOLUTION: f64 = 1.0 / 256.0;

/// A scene's extent and the farthest point that sets it.
#[derive(Clone, Debug, PartialEq)]
pub struct PositionScale {
    /// R: the largest absolute coordinate of any point the renderer computes, in metres.
    pub extent: f64,
    /// What sets `extent`, e.g. "`[camera]` field `position`".
    pub farthest: String,
}

impl PositionScale {
    /// δ = R · 2⁻²³ in metres.
    pub fn resolution(&self) -> f64 {
        self.extent * F32_EPSILON
    }

    /// The smallest feature size that renders right, in metres.
    pub fn min_feature(&self) -> f64 {
        MIN_FEATURE_RESOLUTIONS * self.resolution()
    }

    /// The largest extinction (1/m) at a jump that renders right.
    pub fn max_sigma_t(&self) -> f64 {
        MAX_OPTICAL_RESOLUTION / self.resolution()
    }

    /// Why a feature of `size` metres cannot be rendered, if it cannot.
    pub fn feature_problem(&self, size: f64) -> Option<String> {
        (size < self.min_feature()).then(|| {
            format!(
                "{size:.3e} m is below what 32-bit positions resolve in this scene: it reaches \
                 {:.3e} m from the origin ({}), where positions are known to {:.2e} m, and \
                 features must span at least {MIN_FEATURE_RESOLUTIONS} of those ({:.2e} m); \
                 move the scene closer to the origin or shrink its extent",
                self.extent,
                self.farthest,
                self.resolution(),
                self.min_feature()
            )
        })
    }

    /// Why an extinction of `sigma_t` (1/m) at a jump cannot be rendered, if it cannot.
    pub fn sigma_t_problem(&self, sigma_t: f64, what: &str) -> Option<String> {
        (sigma_t > self.max_sigma_t()).then(|| {
            format!(
                "{what} {sigma_t:e} /m gives a mean free path of {:.2e} m, below what 32-bit \
                 positions resolve in this scene (it reaches {:.3e} m from the origin ({}), \
                 where positions are known to {:.2e} m); at most {:.3e} /m renders right \
                 here: lower the extinction, or move the scene closer to the origin",
                1.0 / sigma_t,
                self.extent,
                self.farthest,
                self.resolution(),
                self.max_sigma_t()
            )
        })
    }
}

/// The largest absolute coordinate of `points` (max-norm), with `what` if it is larger
/// than `best`.
fn widen(best: &mut (f64, String), what: impl FnOnce() -> String, points: &[Vec3]) {
    let m = points
        .iter()
        .map(|p| f64::from(p.abs().max_element()))
        .fold(0.0, f64::max);
    if m > best.0 {
        *best = (m, what());
    }
}

impl Scene {
    /// The scene's extent R (see the module docs): camera positions of every keyframe,
    /// the bounding boxes of media and shapes, positioned lights and gobo planes.
    pub fn position_scale(&self) -> PositionScale {
        // A floor so that a scene at the origin still has a positive resolution.
        let mut best = (1e-30, "the origin".to_string());
        let cam = &self.camera;
        widen(
            &mut best,
            || "[camera] field `position`".into(),
            &[cam.position],
        );
        for (i, k) in cam.keyframes.iter().enumerate() {
            widen(
                &mut best,
                || format!("[[camera.keyframe]] #{} field `position`", i + 1),
                &[k.position],
            );
        }
        // Each names the field that places it, so a refusal says what to change.
        for (i, medium) in self.media.iter().enumerate() {
            let (field, corners) = match medium {
                Medium::Box(b) => {
                    let r = Vec3::splat(0.5 * b.size.length());
                    ("field `center`", vec![b.center - r, b.center + r])
                }
                Medium::Convex(c) => {
                    let (lo, hi) = c.polyhedron.bounds();
                    ("field `planes`", vec![lo.as_vec3(), hi.as_vec3()])
                }
                Medium::Grid(g) if g.vdb.is_some() => (
                    "field `density` placed by its transform and `to_world`",
                    vec![g.bounds_min, g.bounds_max],
                ),
                Medium::Grid(g) => (
                    "fields `bounds_min` / `bounds_max`",
                    vec![g.bounds_min, g.bounds_max],
                ),
            };
            widen(
                &mut best,
                || format!("[[medium]] #{} {field}", i + 1),
                &corners,
            );
        }
        for (i, shape) in self.shapes.iter().enumerate() {
            let (field, corners) = match shape {
                Shape::Quad {
                    corner,
                    edge_u,
                    edge_v,
                    ..
                } => (
                    "field `corner`",
                    vec![
                        *corner,
                        *corner + *edge_u,
                        *corner + *edge_v,
                        *corner + *edge_u + *edge_v,
                    ],
                ),
                Shape::Box { center, size, .. } => {
                    let r = Vec3::splat(0.5 * size.length());
                    ("field `center`", vec![*center - r, *center + r])
                }
                Shape::Sphere { center, radius, .. } => (
                    "field `center`",
                    vec![
                        *center - Vec3::splat(*radius),
                        *center + Vec3::splat(*radius),
                    ],
                ),
                Shape::Mesh { mesh, .. } => {
                    let (lo, hi) = mesh.bounds();
                    ("field `file` placed by `to_world`", vec![lo, hi])
                }
            };
            widen(
                &mut best,
                || format!("[[shape]] #{} {field}", i + 1),
                &corners,
            );
        }
        let frames = self.render.frames.max(1);
        let light_sets: Vec<(Option<u32>, Vec<Light>)> = if self.lights_animated() {
            (0..frames.min(4096))
                .map(|f| (Some(f), self.lights_at(f)))
                .collect()
        } else {
            vec![(None, self.lights.clone())]
        };
        for (frame, lights) in &light_sets {
            for (i, light) in lights.iter().enumerate() {
                let (field, points) = match light {
                    Light::Point { position, .. } => ("position", vec![*position]),
                    Light::Sphere { center, radius, .. } => (
                        "center",
                        vec![
                            *center - Vec3::splat(*radius),
                            *center + Vec3::splat(*radius),
                        ],
                    ),
                    Light::Directional {
                        gobo: Some(gobo), ..
                    } => ("gobo_origin", vec![gobo.origin]),
                    _ => continue,
                };
                let keyed = self.light_keyframes.get(i).is_some_and(|k| !k.is_empty());
                widen(
                    &mut best,
                    || match frame {
                        Some(f) if keyed => format!(
                            "[[light]] #{} field `{field}` at frame {f}, from its \
                             [[light.keyframe]] entries",
                            i + 1
                        ),
                        _ => format!("[[light]] #{} field `{field}`", i + 1),
                    },
                    &points,
                );
            }
        }
        PositionScale {
            extent: best.0,
            farthest: best.1,
        }
    }
}

/// The largest extinction where light enters a grid (see the module docs). Light enters
/// from clear space: along every row of voxels in each of the 6 axis directions, from
/// the face (outside is vacuum; the density is constant from the face to the first
/// centre) and from every voxel thin enough to let light in from the side
/// (σ · h < 1/100), the trilinear density is integrated until the optical depth reaches
/// one, and the extinction there is what a position error multiplies. A dense interior
/// is never reached, so it does not count; a row that never reaches depth one is thin
/// and counts its largest extinction. `scale` is `density_scale`; `voxel` the voxel size
/// in metres per axis. Returns σ_eff and the voxel (i, j, k) nearest where it occurs.
pub fn grid_effective_sigma_t(grid: &VoxelGrid, scale: f64, voxel: [f64; 3]) -> (f64, [u32; 3]) {
    let dims = grid.dims.map(|d| d as usize);
    let at = |ijk: [usize; 3]| {
        scale * f64::from(grid.data[(ijk[2] * dims[1] + ijk[1]) * dims[0] + ijk[0]])
    };
    let mut best = (0.0f64, [0u32; 3]);
    let mut consider = |sigma: f64, ijk: [usize; 3]| {
        if sigma > best.0 {
            best = (sigma, ijk.map(|v| v as u32));
        }
    };
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let n = dims[axis];
        let h = voxel[axis];
        for a in 0..dims[u] {
            for b in 0..dims[v] {
                let cell = |m: usize| {
                    let mut ijk = [0usize; 3];
                    ijk[axis] = m;
                    ijk[u] = a;
                    ijk[v] = b;
                    ijk
                };
                for forward in [true, false] {
                    let index = |step: usize| if forward { step } else { n - 1 - step };
                    // From the face: a constant half voxel of the first centre's value.
                    let first = at(cell(index(0)));
                    let mut tau = first * 0.5 * h;
                    let mut entered = tau >= 1.0;
                    if entered {
                        consider(first, cell(index(0)));
                    }
                    let mut row_max = first;
                    for step in 1..n {
                        let (sa, sb) = (at(cell(index(step - 1))), at(cell(index(step))));
                        row_max = row_max.max(sb);
                        // A voxel thin enough to let light in from the side: start over.
                        if sa * h < 0.01 {
                            tau = 0.0;
                            entered = false;
                        }
                        let segment = 0.5 * (sa + sb) * h;
                        if !entered && tau + segment >= 1.0 {
                            // Linear density sa -> sb over h: depth r = 1 - tau is reached
                            // where sigma = sqrt(sa^2 + 2 (sb - sa) r / h).
                            let r = 1.0 - tau;
                            let sigma = (sa * sa + 2.0 * (sb - sa) * r / h).max(0.0).sqrt();
                            consider(sigma.min(sa.max(sb)), cell(index(step)));
                            entered = true;
                        }
                        tau += segment;
                    }
                    if !entered && tau < 1.0 {
                        // Thin all the way: every extinction of the row is seen.
                        consider(row_max, cell(index(0)));
                    }
                }
            }
        }
    }
    best
}

/// Refuses features and extinctions that 32-bit positions cannot resolve at the
/// scene's extent (see [`crate::precision`]). Grid densities are checked when the grid
/// is read ([`GridMedium::check_density`](crate::GridMedium::check_density)).
pub(crate) fn check_scene(source: &crate::fields::Source, scene: &Scene) -> anyhow::Result<()> {
    let scale = scene.position_scale();
    let fail = |table: String, field: &str, problem: String| {
        source.error(format!("{table}: field `{field}`: {problem}"))
    };
    for (i, medium) in scene.media.iter().enumerate() {
        match medium {
            Medium::Box(b) => {
                let table = format!("[[medium]] #{} (type = \"box\")", i + 1);
                if let Some(p) = scale.feature_problem(f64::from(b.size.min_element())) {
                    return Err(fail(table, "size", p));
                }
                if let Some(p) = scale.sigma_t_problem(f64::from(b.sigma_t), "sigma_t") {
                    return Err(fail(table, "sigma_t", p));
                }
            }
            Medium::Convex(c) => {
                let table = format!("[[medium]] #{} (type = \"convex\")", i + 1);
                let width = c.polyhedron.width();
                if let Some(p) = scale.feature_problem(width) {
                    return Err(fail(
                        table,
                        "planes",
                        format!("its width across a face, {p}"),
                    ));
                }
                if let Some(p) = scale.sigma_t_problem(f64::from(c.sigma_t), "sigma_t") {
                    return Err(fail(table, "sigma_t", p));
                }
            }
            Medium::Grid(g) => {
                let kind = if g.vdb.is_some() { "vdb" } else { "grid" };
                let table = format!("[[medium]] #{} (type = \"{kind}\")", i + 1);
                for source_grid in g.density_sources() {
                    let Ok(dims) = source_grid.dims() else {
                        continue;
                    };
                    let voxel = (g.bounds_max - g.bounds_min) / Vec3::from(dims.map(|d| d as f32));
                    if let Some(p) = scale.feature_problem(f64::from(voxel.min_element())) {
                        let placed = if g.vdb.is_some() {
                            " (its transform times `to_world`)"
                        } else {
                            ""
                        };
                        return Err(fail(table, "density", format!("a voxel{placed} of {p}")));
                    }
                }
            }
        }
    }
    for (i, shape) in scene.shapes.iter().enumerate() {
        let (kind, field, size) = match shape {
            Shape::Quad { edge_u, edge_v, .. } => {
                let (field, len) = if edge_u.length() <= edge_v.length() {
                    ("edge_u", edge_u.length())
                } else {
                    ("edge_v", edge_v.length())
                };
                ("quad", field, len)
            }
            Shape::Box { size, .. } => ("box", "size", size.min_element()),
            Shape::Sphere { radius, .. } => ("sphere", "radius", *radius),
            // The mesh as a whole (its largest extent): triangles finer than the
            // resolution are merely approximated.
            Shape::Mesh { mesh, .. } => {
                let (lo, hi) = mesh.bounds();
                ("mesh", "file", (hi - lo).max_element())
            }
        };
        if let Some(p) = scale.feature_problem(f64::from(size)) {
            let p = if kind == "mesh" {
                format!("its extent after `to_world`, {p}")
            } else {
                p
            };
            return Err(fail(
                format!("[[shape]] #{} (type = \"{kind}\")", i + 1),
                field,
                p,
            ));
        }
    }
    for (i, light) in scene.lights.iter().enumerate() {
        let (kind, field, size) = match light {
            Light::Sphere { radius, .. } => ("sphere", "radius", *radius),
            Light::Directional {
                gobo: Some(gobo), ..
            } => {
                let n = gobo.polygon.len();
                let shortest = (0..n)
                    .map(|k| (gobo.polygon[(k + 1) % n] - gobo.polygon[k]).length())
                    .fold(f32::INFINITY, f32::min);
                ("directional", "gobo", shortest)
            }
            _ => continue,
        };
        if let Some(p) = scale.feature_problem(f64::from(size)) {
            return Err(fail(
                format!("[[light]] #{} (type = \"{kind}\")", i + 1),
                field,
                p,
            ));
        }
    }
    Ok(())
}

impl crate::types::GridMedium {
    /// Checks a loaded density grid of this medium before the renderer uses it:
    /// σt = `density_scale` × voxel must stay within [`crate::MAX_SIGMA_T`] (so it is
    /// finite in f32 too), and the grid's effective extinction
    /// ([`grid_effective_sigma_t`]) must be resolvable at the scene's `scale`. `what`
    /// names the grid in errors, e.g. `scene.toml: [[medium]] #1 > density`.
    pub fn check_density(
        &self,
        density: &VoxelGrid,
        scale: &PositionScale,
        what: &str,
    ) -> anyhow::Result<()> {
        let s = f64::from(self.density_scale);
        let (max_index, max_value) = density
            .data
            .iter()
            .enumerate()
            .fold((0, 0.0f32), |m, (i, v)| if *v > m.1 { (i, *v) } else { m });
        let sigma_max = s * f64::from(max_value);
        if sigma_max > crate::MAX_SIGMA_T {
            let [nx, ny, _] = density.dims.map(|d| d as usize);
            let (i, j, k) = (max_index % nx, (max_index / nx) % ny, max_index / (nx * ny));
            anyhow::bail!(
                "{what}: voxel ({i}, {j}, {k}) = {max_value:e} times density_scale {s:e} is \
                 sigma_t = {sigma_max:e} /m, above the largest extinction {:e} /m",
                crate::MAX_SIGMA_T
            );
        }
        let size = self.bounds_max - self.bounds_min;
        let voxel = [0, 1, 2].map(|a| f64::from(size[a]) / f64::from(density.dims[a].max(1)));
        let (sigma, [i, j, k]) = grid_effective_sigma_t(density, s, voxel);
        if let Some(problem) = scale.sigma_t_problem(sigma, "the extinction where light enters it")
        {
            anyhow::bail!(
                "{what} (with density_scale {s:e}): near voxel ({i}, {j}, {k}), {problem}"
            );
        }
        Ok(())
    }
}

impl crate::types::GridMedium {
    /// The world length of one lattice step of the density along each index axis: the
    /// box's size over the dims for `type = "grid"` (`dims` of the density), the
    /// transform's for `type = "vdb"`.
    pub fn voxel_size(&self, dims: [u32; 3]) -> [f64; 3] {
        match &self.vdb {
            Some(v) => v.voxel_size(),
            None => {
                let size = self.bounds_max - self.bounds_min;
                [0, 1, 2].map(|a| f64::from(size[a]) / f64::from(dims[a].max(1)))
            }
        }
    }

    /// The affine map from the p-space of `grid` (a density, emission or velocity grid of
    /// this medium, loaded into bricks) to world space: for `type = "grid"` the box
    /// `bounds_min .. bounds_max` over the grid's dims; for `type = "vdb"` the grid's own
    /// transform, then `to_world` (lattice point `l` sits at `index_to_world · (l +
    /// origin)`).
    pub fn p_to_world(&self, grid: &crate::BrickGrid) -> anyhow::Result<glam::DMat4> {
        use glam::{DMat4, DVec3};
        match (&self.vdb, grid.file_transform) {
            (Some(v), Some(file)) => Ok(v.to_world
                * file
                * DMat4::from_translation(grid.origin.as_dvec3() - DVec3::splat(0.5))),
            (None, None) => {
                let dims = (grid.lattice_max + 1).as_dvec3();
                let size = (self.bounds_max - self.bounds_min).as_dvec3();
                Ok(DMat4::from_translation(self.bounds_min.as_dvec3())
                    * DMat4::from_scale(size / dims))
            }
            _ => anyhow::bail!("internal: a grid of a different medium type"),
        }
    }

    /// [`GridMedium::check_density`](crate::GridMedium::check_density) on a density loaded into bricks: the same two
    /// rules, computed on the stored bricks only. Voxels in messages are the grid's own
    /// (absolute) index coordinates.
    pub fn check_density_bricks(
        &self,
        density: &crate::BrickGrid,
        scale: &PositionScale,
        what: &str,
    ) -> anyhow::Result<()> {
        let s = f64::from(self.density_scale);
        let (max_value, at) = density.max_value();
        let sigma_max = s * f64::from(max_value);
        if sigma_max > crate::MAX_SIGMA_T {
            let ijk = density.origin + at;
            anyhow::bail!(
                "{what}: voxel ({}, {}, {}) = {max_value:e} times density_scale {s:e} is \
                 sigma_t = {sigma_max:e} /m, above the largest extinction {:e} /m",
                ijk.x,
                ijk.y,
                ijk.z,
                crate::MAX_SIGMA_T
            );
        }
        let dims = (density.lattice_max + 1)
            .to_array()
            .map(|d| d.max(1) as u32);
        let voxel = self.voxel_size(dims);
        let (sigma, at) = crate::bricks::effective_sigma_t(density, s, voxel);
        if let Some(problem) = scale.sigma_t_problem(sigma, "the extinction where light enters it")
        {
            let ijk = density.origin + at;
            anyhow::bail!(
                "{what} (with density_scale {s:e}): near voxel ({}, {}, {}), {problem}",
                ijk.x,
                ijk.y,
                ijk.z
            );
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scale(extent: f64) -> PositionScale {
        PositionScale {
            extent,
            farthest: "[camera] field `position`".into(),
        }
    }

    #[test]
    fn limits_follow_the_extent() {
        let s = scale(1.0);
        assert!((s.resolution() - 1.1920929e-7).abs() < 1e-13);
        assert!(s.feature_problem(1e-3).is_none());
        let m = s.feature_problem(1e-5).expect("too small");
        assert!(
            m.contains("[camera] field `position`") && m.contains("3.05e-5"),
            "{m}"
        );
        assert!(s.sigma_t_problem(3e4, "sigma_t").is_none());
        let m = s.sigma_t_problem(1e9, "sigma_t").expect("too dense");
        assert!(m.contains("at most 3.277e4 /m"), "{m}");
        // A camera 2e19 m away leaves no room for a 1 m box.
        assert!(scale(2e19).feature_problem(1.0).is_some());
    }

    #[test]
    fn effective_sigma_of_a_hot_voxel_is_its_ramp() {
        let mut grid = VoxelGrid {
            dims: [5, 5, 5],
            channels: 1,
            data: vec![0.5; 125],
        };
        grid.data[2 + 5 * (2 + 5 * 2)] = 1e6;
        let (sigma, ijk) = grid_effective_sigma_t(&grid, 1.0, [0.1; 3]);
        assert_eq!(ijk, [2, 2, 2]);
        // Two clear voxels (depth 0.025 + 0.05) before the ramp into the hot one.
        let r = 1.0 - (0.5 * 0.5 * 0.1 + 0.5 * 0.1);
        let ramp = (0.25 + 2.0 * (1e6 - 0.5) * r / 0.1f64).sqrt();
        assert!((sigma - ramp).abs() < 1e-6 * ramp, "{sigma} {ramp}");
        // A dense interior behind an opaque shell is never reached: a 5³ block of 1e6
        // inside a grid whose outer shell is already opaque (1e3 over 0.1 m) counts the
        // shell's entry, not the interior.
        let mut shell = VoxelGrid {
            dims: [7, 7, 7],
            channels: 1,
            data: vec![1e3; 343],
        };
        for k in 1..6 {
            for j in 1..6 {
                for i in 1..6 {
                    shell.data[i + 7 * (j + 7 * k)] = 1e6;
                }
            }
        }
        assert_eq!(grid_effective_sigma_t(&shell, 1.0, [0.1; 3]).0, 1e3);
        // A uniform grid's boundary jumps from vacuum to its full density.
        let uniform = VoxelGrid {
            dims: [3, 3, 3],
            channels: 1,
            data: vec![2.0; 27],
        };
        assert_eq!(grid_effective_sigma_t(&uniform, 10.0, [1.0; 3]).0, 20.0);
    }
}
