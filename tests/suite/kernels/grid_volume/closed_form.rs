//! The closed form on the GPU: the optical depth of regular tracking against f64
//! quadrature, and `grid_sigma_t` at voxel centres and outside the box.

use super::*;

#[test]
fn closed_form_optical_depth_matches_f64_quadrature() {
    let gpu = Gpu::new();
    let mut rng = Pcg32::new(0x6a1d_0002);
    let mut worst_overall = 0.0f64;
    for medium in media() {
        let rays = random_rays(&medium, 2000, &mut rng);
        let handle = gpu.upload(&medium);
        let queries: Vec<GpuQuery> = rays
            .iter()
            .map(|r| r.query(MODE_CLOSED_FORM, 0, 0))
            .collect();
        let results = gpu.run(&handle, &queries);
        let (mut worst_rel, mut worst_abs, mut max_depth) = (0.0f64, 0.0f64, 0.0f64);
        for (ray, result) in rays.iter().zip(&results) {
            let reference = medium.optical_depth(ray);
            let depth = f64::from(result.r0[0]);
            let error = (depth - reference).abs();
            max_depth = max_depth.max(reference);
            assert!(
                error <= (DEPTH_REL_TOL * reference).max(DEPTH_ABS_TOL),
                "{}: {} ray {ray:?}: optical depth gpu {depth} vs reference {reference}",
                medium.name,
                ray.kind
            );
            // T is exp(-depth) of the same depth (f32 exp: ~1e-7 relative).
            let t = f64::from(result.r0[1]);
            assert!(
                (t - (-depth).exp()).abs() <= 1e-6 * (-depth).exp() + 1e-7,
                "{}: T {t} vs exp(-{depth})",
                medium.name
            );
            if reference > DEPTH_ABS_TOL / DEPTH_REL_TOL {
                worst_rel = worst_rel.max(error / reference);
            } else {
                worst_abs = worst_abs.max(error);
            }
            if matches!(ray.kind, "zero-length" | "reversed" | "miss") {
                assert_eq!(depth, 0.0, "{}: {ray:?}", medium.name);
            }
        }
        println!(
            "{:<36} {} rays: max relative error {worst_rel:.2e}, max absolute error (tiny depths) \
             {worst_abs:.2e}, largest depth {max_depth:.2}",
            medium.name,
            rays.len()
        );
        worst_overall = worst_overall.max(worst_rel);
    }
    println!("closed form: max relative error over all media {worst_overall:.2e}");
    gpu.finish();
}

#[test]
fn sigma_t_equals_voxel_values_at_centres_and_zero_outside() {
    let gpu = Gpu::new();
    let mut rng = Pcg32::new(0x6a1d_0003);
    for medium in media() {
        let dims = medium.grid.dims;
        let mut points = Vec::new();
        let mut expected = Vec::new();
        // Every voxel centre of the small grids, 4096 random ones of the large.
        let total = medium.grid.voxel_count();
        for idx in 0..total.min(4096) {
            let v = if total <= 4096 {
                let i = idx as u32;
                [
                    i % dims[0],
                    (i / dims[0]) % dims[1],
                    i / (dims[0] * dims[1]),
                ]
            } else {
                [0, 1, 2].map(|a| rng.below(dims[a]))
            };
            points.push(medium.centre(v));
            expected.push(f64::from(medium.grid.get(v[0], v[1], v[2])) * f64::from(medium.scale));
        }
        // Points outside the bounds, just beyond each face and far away.
        let size = medium.size();
        for _ in 0..256 {
            let mut x =
                [0, 1, 2].map(|a| f64::from(medium.bounds_min[a]) + rng.uniform32() * size[a]);
            let axis = rng.below(3) as usize;
            x[axis] = if rng.uniform32() < 0.5 {
                f64::from(medium.bounds_min[axis]) - rng.range32(1e-3, 2.0) * size[axis]
            } else {
                f64::from(medium.bounds_max[axis]) + rng.range32(1e-3, 2.0) * size[axis]
            };
            points.push(x);
            expected.push(0.0);
        }
        // Random points inside against sample_trilinear (border half-voxels included).
        for _ in 0..1024 {
            let x = [0, 1, 2].map(|a| f64::from(medium.bounds_min[a]) + rng.uniform32() * size[a]);
            let x = x.map(|c| f64::from(c as f32));
            points.push(x);
            expected.push(medium.sigma_t(x));
        }
        let handle = gpu.upload(&medium);
        let queries: Vec<GpuQuery> = points
            .iter()
            .map(|&x| {
                Ray {
                    o: to_f32(x),
                    d: [1.0, 0.0, 0.0],
                    t0: 0.0,
                    t1: 0.0,
                    kind: "point",
                }
                .query(MODE_CLOSED_FORM, 0, 0)
            })
            .collect();
        let results = gpu.run(&handle, &queries);
        let sigma_max = f64::from(medium.sparse().params.sigma_t_max);
        let mut worst = 0.0f64;
        for ((x, want), result) in points.iter().zip(&expected).zip(&results) {
            let got = f64::from(result.r0[2]);
            let error = (got - want).abs();
            worst = worst.max(error / sigma_max.max(1e-30));
            // The f32 position is off by ~2^-24 of its coordinates, a few 1e-6 voxels;
            // sigma_t changes by at most sigma_max per voxel, hence the second term.
            assert!(
                error <= 1e-5 * want.abs() + 1e-5 * sigma_max,
                "{}: sigma_t({x:?}) gpu {got} vs {want}",
                medium.name
            );
        }
        println!(
            "{:<36} {} points: max |error| / sigma_max {worst:.2e}",
            medium.name,
            points.len()
        );
    }
    gpu.finish();
}
