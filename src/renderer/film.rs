//! The statistics of an image being rendered, on the CPU: its mean, the standard error
//! of that mean per pixel and channel, and one number for the whole image, the
//! relative standard error that `--target-error` stops on.
//!
//! The GPU adds one estimate per pixel and frame to running sums ([`Totals`]: rgb and
//! alpha, and their squares). With independent frames (the path tracers: every frame
//! draws fresh random numbers), the standard error of the mean follows from those sums
//! alone. ReSTIR's frames are not independent: temporal reuse carries reservoirs from
//! one frame into the next, so the spread of the frame estimates understates the error
//! of their mean. For those renders the error comes from **batch means** ([`Batches`]):
//! consecutive frames are grouped into batches long enough that their means are nearly
//! independent, and the standard error is the spread of the batch means. With fewer
//! than two whole batches the per-frame spread stands in, and the estimate says so
//! ([`Estimate::independent`] is false).
//!
//! The relative standard error of an image ([`relative_error`]) is the root mean square
//! of the per-pixel standard errors over the mean of the image, both over all pixels and
//! the three colour channels: the expected relative RMSE against the converged image
//! when the estimator is unbiased.

/// Running sums of the frame estimates per pixel: `sum` holds Σx (rgb, alpha), `sum_sq`
/// Σx², over `frames` frames.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Totals {
    pub sum: Vec<[f32; 4]>,
    pub sum_sq: Vec<[f32; 4]>,
    pub frames: u32,
}

impl Totals {
    /// Zero sums for `pixels` pixels.
    pub fn new(pixels: usize) -> Self {
        Self {
            sum: vec![[0.0; 4]; pixels],
            sum_sq: vec![[0.0; 4]; pixels],
            frames: 0,
        }
    }

    /// Adds one frame's estimates.
    pub fn add_frame(&mut self, frame: &[[f32; 4]]) {
        for ((s, q), x) in self.sum.iter_mut().zip(&mut self.sum_sq).zip(frame) {
            for c in 0..4 {
                s[c] += x[c];
                q[c] += x[c] * x[c];
            }
        }
        self.frames += 1;
    }
}

/// Batch means of consecutive frames, for estimators whose frames are correlated.
#[derive(Clone, Debug, PartialEq)]
pub struct Batches {
    /// Frames per batch.
    pub size: u32,
    /// Σx at the end of the last whole batch.
    closed_sum: Vec<[f32; 4]>,
    /// Σ (batch mean)² over the whole batches.
    sum_sq: Vec<[f32; 4]>,
    /// Whole batches so far.
    pub count: u32,
}

impl Batches {
    pub fn new(size: u32, pixels: usize) -> Self {
        Self {
            size: size.max(1),
            closed_sum: vec![[0.0; 4]; pixels],
            sum_sq: vec![[0.0; 4]; pixels],
            count: 0,
        }
    }

    /// Whether the frame count `frames` ends a batch.
    pub fn ends_batch(&self, frames: u32) -> bool {
        frames > 0 && frames.is_multiple_of(self.size)
    }

    /// Closes a batch: `sum` is Σx over every frame so far, which must end a batch.
    pub fn close(&mut self, sum: &[[f32; 4]]) {
        let size = self.size as f32;
        for ((closed, q), s) in self.closed_sum.iter_mut().zip(&mut self.sum_sq).zip(sum) {
            for c in 0..4 {
                let batch_mean = (s[c] - closed[c]) / size;
                q[c] += batch_mean * batch_mean;
            }
            *closed = *s;
        }
        self.count += 1;
    }
}

/// The mean image and its standard error.
#[derive(Clone, Debug, PartialEq)]
pub struct Estimate {
    /// Mean over the frames (rgb, alpha).
    pub mean: Vec<[f32; 4]>,
    /// Standard error of `mean` (zero with fewer than two estimates).
    pub std_error: Vec<[f32; 4]>,
    /// Relative standard error of the whole image ([`relative_error`]); `None` with
    /// fewer than two estimates.
    pub rel_error: Option<f64>,
    /// Independent estimates behind `std_error`: frames, or whole batches.
    pub estimates: u32,
    /// False where correlated frames' own spread stands in for batch means (too few
    /// batches): `std_error` then understates the error.
    pub independent: bool,
}

/// Unbiased sample variance from Σx, Σx² of `n` values, clamped against rounding.
fn sample_variance(sum: f64, sum_sq: f64, n: f64) -> f64 {
    if n < 2.0 {
        return 0.0;
    }
    let mean = sum / n;
    ((sum_sq / n - mean * mean) * n / (n - 1.0)).max(0.0)
}

/// The mean and standard error of `totals`, from the batch means of `batches` when
/// given and at least two batches are whole, else from the frames' own spread
/// (`correlated` says whether those frames are correlated, i.e. whether batches were
/// asked for).
pub fn estimate(totals: &Totals, batches: Option<&Batches>) -> Estimate {
    let frames = f64::from(totals.frames.max(1));
    let whole = batches.filter(|b| b.count >= 2);
    let mut mean = vec![[0.0f32; 4]; totals.sum.len()];
    let mut std_error = vec![[0.0f32; 4]; totals.sum.len()];
    for (i, (s, q)) in totals.sum.iter().zip(&totals.sum_sq).enumerate() {
        for c in 0..4 {
            let m = f64::from(s[c]) / frames;
            mean[i][c] = m as f32;
            // Variance of the mean over all frames: of the frames, s²/n; of batches of
            // B frames, s_B²·B/n (Var(batch mean) ≈ σ²τ/B, Var(mean) ≈ σ²τ/n).
            let var_of_mean = match whole {
                Some(b) => {
                    let n = f64::from(b.count);
                    let closed = f64::from(b.closed_sum[i][c]) / f64::from(b.size);
                    let var = sample_variance(closed, f64::from(b.sum_sq[i][c]), n);
                    var * f64::from(b.size) / frames
                }
                None => sample_variance(f64::from(s[c]), f64::from(q[c]), frames) / frames,
            };
            std_error[i][c] = var_of_mean.sqrt() as f32;
        }
    }
    let (estimates, independent) = match (batches, whole) {
        (_, Some(b)) => (b.count, true),
        (Some(_), None) => (totals.frames, false),
        (None, None) => (totals.frames, true),
    };
    let rel_error = (estimates >= 2).then(|| relative_error(&mean, &std_error));
    Estimate {
        mean,
        std_error,
        rel_error,
        estimates,
        independent,
    }
}

/// The relative standard error of an image: sqrt(mean of se²) / mean of the image,
/// over all pixels and the r, g, b channels (alpha is left out). Infinite for a black
/// image with any error, 0 for a black image without.
pub fn relative_error(mean: &[[f32; 4]], std_error: &[[f32; 4]]) -> f64 {
    let (mut sum, mut sum_se2) = (0.0f64, 0.0f64);
    for (m, s) in mean.iter().zip(std_error) {
        for c in 0..3 {
            sum += f64::from(m[c]);
            sum_se2 += f64::from(s[c]) * f64::from(s[c]);
        }
    }
    let n = (3 * mean.len()).max(1) as f64;
    let rms = (sum_se2 / n).sqrt();
    let level = (sum / n).abs();
    if rms == 0.0 {
        0.0
    } else if level == 0.0 {
        f64::INFINITY
    } else {
        rms / level
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic stream of uniform numbers in [0, 1).
    fn lcg(state: &mut u64) -> f32 {
        *state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*state >> 40) as f32) / (1u64 << 24) as f32
    }

    #[test]
    fn independent_frames_give_the_textbook_standard_error() {
        let mut t = Totals::new(1);
        for x in [1.0f32, 2.0, 3.0, 4.0] {
            t.add_frame(&[[x, 2.0 * x, 0.0, 1.0]]);
        }
        let e = estimate(&t, None);
        assert_eq!(e.mean[0], [2.5, 5.0, 0.0, 1.0]);
        // s² = 5/3, se = sqrt(5/12).
        assert!((e.std_error[0][0] - (5.0f32 / 12.0).sqrt()).abs() < 1e-6);
        assert!((e.std_error[0][1] - 2.0 * (5.0f32 / 12.0).sqrt()).abs() < 1e-6);
        assert_eq!(e.std_error[0][3], 0.0);
        assert!(e.independent && e.estimates == 4);
    }

    #[test]
    fn one_frame_has_no_error_estimate() {
        let mut t = Totals::new(2);
        t.add_frame(&[[1.0; 4], [2.0; 4]]);
        let e = estimate(&t, None);
        assert_eq!(e.rel_error, None);
        assert_eq!(e.std_error, vec![[0.0; 4]; 2]);
    }

    #[test]
    fn batch_means_see_the_correlation_the_frames_hide() {
        // An AR(1) chain x_t = r x_{t-1} + e_t (r = 0.9): the frames' own spread
        // understates the error of their mean by about sqrt((1 + r) / (1 - r)) ≈ 4.4;
        // batch means of 64 frames recover it. Checked over many independent pixels.
        let (pixels, frames, r) = (400usize, 4096u32, 0.9f32);
        let mut t = Totals::new(pixels);
        let mut b = Batches::new(64, pixels);
        let mut state = 7u64;
        let mut x = vec![0.0f32; pixels];
        let mut frame = vec![[0.0f32; 4]; pixels];
        for _ in 0..frames {
            for p in 0..pixels {
                x[p] = r * x[p] + (lcg(&mut state) - 0.5);
                frame[p] = [10.0 + x[p]; 4];
            }
            t.add_frame(&frame);
            if b.ends_batch(t.frames) {
                b.close(&t.sum);
            }
        }
        // Stationary variance of x: (1/12) / (1 - r²); of the mean of n frames about
        // that times (1 + r) / (1 - r) / n.
        let var_x = (1.0 / 12.0) / (1.0 - f64::from(r * r));
        let truth = (var_x * f64::from((1.0 + r) / (1.0 - r)) / f64::from(frames)).sqrt();
        let rms = |e: &Estimate| {
            (e.std_error
                .iter()
                .map(|s| f64::from(s[0]).powi(2))
                .sum::<f64>()
                / pixels as f64)
                .sqrt()
        };
        let naive = estimate(&t, None);
        let batched = estimate(&t, Some(&b));
        assert!(batched.independent && batched.estimates == 64);
        assert!(rms(&naive) < 0.4 * truth, "{} vs {truth}", rms(&naive));
        let ratio = rms(&batched) / truth;
        assert!((0.85..1.15).contains(&ratio), "batch means off by {ratio}");
    }

    #[test]
    fn too_few_batches_fall_back_and_say_so() {
        let mut t = Totals::new(1);
        let mut b = Batches::new(8, 1);
        for i in 0..12 {
            t.add_frame(&[[i as f32; 4]]);
            if b.ends_batch(t.frames) {
                b.close(&t.sum);
            }
        }
        let e = estimate(&t, Some(&b));
        assert!(!e.independent);
        assert_eq!(e.estimates, 12);
        assert!(e.std_error[0][0] > 0.0);
    }

    #[test]
    fn relative_error_is_rms_error_over_the_mean_level() {
        let mean = vec![[2.0, 2.0, 2.0, 1.0], [4.0, 4.0, 4.0, 1.0]];
        let se = vec![[0.3, 0.3, 0.3, 9.0], [0.3, 0.3, 0.3, 9.0]];
        assert!((relative_error(&mean, &se) - 0.1).abs() < 1e-6);
        assert_eq!(relative_error(&[[0.0; 4]], &[[0.0; 4]]), 0.0);
        assert_eq!(relative_error(&[[0.0; 4]], &[[1.0; 4]]), f64::INFINITY);
    }
}
