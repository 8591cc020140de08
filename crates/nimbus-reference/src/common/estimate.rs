//! Monte Carlo estimates: what the Monte Carlo oracles return, running moments over
//! paths, and the loops over paths and pixels that every such oracle runs.

use anyhow::ensure;
use glam::DVec3;
use nimbus_scene::Scene;

use super::camera::CameraRays;
use super::parallel::in_parallel;
use super::rng::Rng;

/// A Monte Carlo estimate: per-channel mean and standard error of the mean.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct McEstimate {
    pub mean: [f64; 3],
    /// sqrt(sample variance / paths).
    pub std_error: [f64; 3],
}

/// A rendered image: (mean, standard error) per pixel, row-major from the top left.
pub type McImage = (Vec<[f64; 3]>, Vec<[f64; 3]>);

/// Running moments over paths (Welford's update, Chan et al.'s merge), so a constant
/// estimate has a standard error of exactly 0.
#[derive(Clone, Copy, Default)]
pub(crate) struct Moments {
    pub(crate) n: u64,
    mean: DVec3,
    /// Σ (l − mean)².
    m2: DVec3,
}

impl Moments {
    pub(crate) fn add(&mut self, l: DVec3) {
        self.n += 1;
        let delta = l - self.mean;
        self.mean += delta / self.n as f64;
        self.m2 += delta * (l - self.mean);
    }

    pub(crate) fn merge(&mut self, other: &Moments) {
        if other.n == 0 {
            return;
        }
        let (a, b) = (self.n as f64, other.n as f64);
        let n = a + b;
        let delta = other.mean - self.mean;
        self.mean += delta * (b / n);
        self.m2 += other.m2 + delta * delta * (a * b / n);
        self.n += other.n;
    }

    /// Mean and sqrt(s²/n) with the unbiased sample variance s² (n ≥ 2).
    pub(crate) fn estimate(&self) -> McEstimate {
        let n = self.n as f64;
        let variance = (self.m2 / (n - 1.0)).max(DVec3::ZERO);
        McEstimate {
            mean: self.mean.to_array(),
            std_error: (variance / n).to_array().map(f64::sqrt),
        }
    }
}

/// What an oracle accumulates over paths: mergeable, and an estimate at the end.
pub(crate) trait PathSums: Default + Send {
    fn merge(&mut self, other: &Self);
    fn estimate(&self) -> McEstimate;
}

impl PathSums for Moments {
    fn merge(&mut self, other: &Self) {
        Moments::merge(self, other);
    }

    fn estimate(&self) -> McEstimate {
        Moments::estimate(self)
    }
}

/// Checks that `paths` can give a standard error; `what` names the oracle in the error.
pub(crate) fn check_paths(paths: u32, what: &str) -> anyhow::Result<()> {
    ensure!(
        paths >= 2,
        "{what}: at least 2 paths are needed for a standard error, got {paths}"
    );
    Ok(())
}

/// The unit direction of the camera ray origin + t·dir, or an error naming `what` when
/// there is none.
pub(crate) fn unit_ray(origin: DVec3, dir: DVec3, what: &str) -> anyhow::Result<DVec3> {
    let d = dir.normalize_or_zero();
    ensure!(
        d != DVec3::ZERO && d.is_finite() && origin.is_finite(),
        "{what}: bad camera ray origin {origin}, direction {dir}"
    );
    Ok(d)
}

/// `paths` paths along one camera ray, in chunks of `chunk_paths` shared among
/// threads; path i uses stream i of `seed` (`trace` adds it to the sums), and chunks
/// are merged in order.
pub(crate) fn radiance_paths<S: PathSums>(
    paths: u32,
    seed: u64,
    chunk_paths: u32,
    trace: impl Fn(&mut S, &mut Rng) + Sync,
) -> S {
    let chunks = paths.div_ceil(chunk_paths) as usize;
    let done = in_parallel(chunks, |c| {
        let first = c as u32 * chunk_paths;
        let last = (first + chunk_paths).min(paths);
        let mut sums = S::default();
        for path in first..last {
            let mut rng = Rng::new(seed, u64::from(path));
            trace(&mut sums, &mut rng);
        }
        sums
    });
    let mut total = S::default();
    for sums in &done {
        total.merge(sums);
    }
    total
}

/// Checks what [`render_paths`] needs of `scene`, `paths` and `footprint`; `what`
/// names the oracle in the errors.
pub(crate) fn check_render(
    scene: &Scene,
    paths: u32,
    footprint: u32,
    what: &str,
) -> anyhow::Result<()> {
    if let Some(strata) = footprint.checked_mul(footprint).filter(|&s| s > 0) {
        ensure!(
            paths.is_multiple_of(strata),
            "{what}: paths per pixel ({paths}) must be a multiple of footprint² = {strata}"
        );
    }
    ensure!(
        scene.camera.keyframes.is_empty() || scene.render.frames <= 1,
        "{}: animated cameras are not supported by the {what} (it renders frame 0 only)",
        scene.source.display()
    );
    Ok(())
}

/// Renders frame 0: mean and standard error per pixel, row-major from the top left.
/// Path i of a pixel uses its own stream of `seed` and goes through stratum
/// i mod footprint² of a footprint × footprint grid over the pixel, jittered uniformly
/// within it; footprint 0 sends every path through the pixel centre. `trace` follows
/// the camera ray (origin, unit direction) and adds the path to the sums. Rows are
/// shared among threads; the result does not depend on the thread count.
pub(crate) fn render_paths<S: PathSums>(
    scene: &Scene,
    paths: u32,
    seed: u64,
    footprint: u32,
    trace: impl Fn(&mut S, DVec3, DVec3, &mut Rng) + Sync,
) -> McImage {
    let strata = footprint.checked_mul(footprint).filter(|&s| s > 0);
    let camera = CameraRays::new(scene);
    let (width, height) = (scene.render.width, scene.render.height);

    // One pixel: paths through jittered strata of its footprint, one stream per path.
    let pixel = |x: u32, y: u32| -> S {
        let pixel_index = u64::from(y) * u64::from(width) + u64::from(x);
        let mut sums = S::default();
        for path in 0..paths {
            let mut rng = Rng::new(seed, (pixel_index << 32) | u64::from(path));
            let (px, py) = match strata {
                None => (f64::from(x) + 0.5, f64::from(y) + 0.5),
                Some(strata) => {
                    let s = path % strata;
                    let (sx, sy) = (s % footprint, s / footprint);
                    let f = f64::from(footprint);
                    (
                        f64::from(x) + (f64::from(sx) + rng.uniform()) / f,
                        f64::from(y) + (f64::from(sy) + rng.uniform()) / f,
                    )
                }
            };
            let d = camera.direction(px, py);
            trace(&mut sums, camera.position, d, &mut rng);
        }
        sums
    };

    let rows = in_parallel(height as usize, |y| {
        (0..width).map(|x| pixel(x, y as u32)).collect::<Vec<S>>()
    });
    let (mut mean, mut std_error) = (Vec::new(), Vec::new());
    for sums in rows.into_iter().flatten() {
        let e = sums.estimate();
        mean.push(e.mean);
        std_error.push(e.std_error);
    }
    (mean, std_error)
}
