//! f64 building blocks shared by the two CPU Monte Carlo oracles,
//! [`crate::mc`] (box media) and [`crate::grid`] (grid media).
//!
//! Random numbers, direction sampling, ray–box/quad/sphere tests, the scene's shapes
//! and gobos in f64, camera rays, running moments and the threading over paths and
//! pixels. None of it is shared with the GPU passes or with the quadrature reference
//! ([`crate::quadrature`]): the oracles stay independent of what they check.

use std::f64::consts::PI;
use std::sync::atomic::{AtomicUsize, Ordering};

use anyhow::ensure;
use glam::{DMat3, DVec2, DVec3, Vec3};
use nimbus_scene::{Gobo, Scene, Shape};

use crate::mc::{McEstimate, McImage};

// ---------------------------------------------------------------------------------------
// Random numbers: xoshiro256** (Blackman & Vigna), seeded through SplitMix64.

/// One step of SplitMix64.
fn splitmix64(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

pub(crate) struct Rng {
    s: [u64; 4],
}

impl Rng {
    /// Stream `stream` of `seed`: distinct streams of one seed start from distinct
    /// SplitMix64 states (the map stream → state is injective).
    pub(crate) fn new(seed: u64, stream: u64) -> Self {
        let mut mix = seed;
        let mut state = splitmix64(&mut mix) ^ stream.wrapping_mul(0xD1B5_4A32_D192_ED03);
        let s = [
            splitmix64(&mut state),
            splitmix64(&mut state),
            splitmix64(&mut state),
            splitmix64(&mut state),
        ];
        Self { s }
    }

    pub(crate) fn next_u64(&mut self) -> u64 {
        let s = &mut self.s;
        let result = s[1].wrapping_mul(5).rotate_left(7).wrapping_mul(9);
        let t = s[1] << 17;
        s[2] ^= s[0];
        s[3] ^= s[1];
        s[1] ^= s[2];
        s[0] ^= s[3];
        s[2] ^= t;
        s[3] = s[3].rotate_left(45);
        result
    }

    /// Uniform in [0, 1), 53 random bits.
    pub(crate) fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Exponential with rate `rate` > 0 (1 − u ∈ (0, 1], so the log is finite).
    pub(crate) fn exponential(&mut self, rate: f64) -> f64 {
        -(1.0 - self.uniform()).ln() / rate
    }
}

// ---------------------------------------------------------------------------------------
// Sampling.

/// Henyey–Greenstein phase function; `cos_theta` between the travel directions before
/// and after scattering, |g| < 1 so the base is ≥ (1 − |g|)² > 0.
pub(crate) fn phase_hg(cos_theta: f64, g: f64) -> f64 {
    let base = 1.0 + g * g - 2.0 * g * cos_theta;
    (1.0 - g * g) / (4.0 * PI * base * base.sqrt())
}

/// Two unit vectors completing unit `n` to a right-handed orthonormal basis (Duff et
/// al. 2017); sign(0) is taken as +1, so 1/(sign + n.z) has |sign + n.z| ≥ 1.
fn orthonormal_basis(n: DVec3) -> (DVec3, DVec3) {
    let sign = 1f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        DVec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// The unit direction with cosine `cos_theta` to `axis` and azimuth 2π·u.
pub(crate) fn direction_around(axis: DVec3, cos_theta: f64, u: f64) -> DVec3 {
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let phi = 2.0 * PI * u;
    let (t, b) = orthonormal_basis(axis);
    (sin_theta * phi.cos() * t + sin_theta * phi.sin() * b + cos_theta * axis).normalize()
}

/// Samples a new travel direction from the HG lobe around travel direction `d`.
/// Inverts the CDF P(μ) = (1−g²)/(2g)·[(1+g²−2gμ)^{−1/2} − 1/(1+g)] = u (its base
/// 1 − g + 2gu is in [1 − |g|, 1 + |g|], > 0); |g| < 1e-4 uses the isotropic limit.
pub(crate) fn sample_hg(d: DVec3, g: f64, rng: &mut Rng) -> DVec3 {
    let (u1, u2) = (rng.uniform(), rng.uniform());
    let cos_theta = if g.abs() < 1e-4 {
        1.0 - 2.0 * u1
    } else {
        let q = (1.0 - g * g) / (1.0 - g + 2.0 * g * u1);
        ((1.0 + g * g - q * q) / (2.0 * g)).clamp(-1.0, 1.0)
    };
    direction_around(d, cos_theta, u2)
}

/// Samples a cosine-distributed direction around unit `n` (pdf cosθ/π).
pub(crate) fn sample_cosine(n: DVec3, rng: &mut Rng) -> DVec3 {
    let (u1, u2) = (rng.uniform(), rng.uniform());
    direction_around(n, (1.0 - u1).sqrt(), u2)
}

/// Uniform on the unit sphere (pdf 1/(4π)).
pub(crate) fn sample_sphere(rng: &mut Rng) -> DVec3 {
    let (u1, u2) = (rng.uniform(), rng.uniform());
    direction_around(DVec3::Z, 1.0 - 2.0 * u1, u2)
}

// ---------------------------------------------------------------------------------------
// Geometry, in f64.

/// Rotation about X, then Y, then Z by `deg`: world = Rz·Ry·Rx·local.
pub(crate) fn rotation_f64(deg: Vec3) -> DMat3 {
    let r = deg.as_dvec3() * (PI / 180.0);
    DMat3::from_rotation_z(r.z) * DMat3::from_rotation_y(r.y) * DMat3::from_rotation_x(r.x)
}

/// A box, world = center + R·local, local ∈ [−half, half].
pub(crate) struct OrientedBox {
    center: DVec3,
    half: DVec3,
    /// R (columns are the local axes in world space).
    rotation: DMat3,
}

impl OrientedBox {
    pub(crate) fn new(center: DVec3, half: DVec3, rotation: DMat3) -> Self {
        Self {
            center,
            half,
            rotation,
        }
    }

    /// A box as the scene gives it: center, full size and rotation in degrees.
    pub(crate) fn from_scene(center: Vec3, size: Vec3, rotation_deg: Vec3) -> Self {
        Self::new(
            center.as_dvec3(),
            0.5 * size.as_dvec3(),
            rotation_f64(rotation_deg),
        )
    }

    /// The parameter range (t_in, t_out) where the line o + t·d is inside the closed box,
    /// with the local axis of the entry face: intersection of the three slabs in the
    /// local frame (R is a rotation, so t is the same there). A local direction
    /// component of 0 keeps the line in that slab iff its coordinate is.
    pub(crate) fn line_range(&self, o: DVec3, d: DVec3) -> Option<(f64, f64, usize)> {
        let o_l = self.rotation.transpose() * (o - self.center);
        let d_l = self.rotation.transpose() * d;
        let (mut t_in, mut t_out, mut axis_in) = (f64::NEG_INFINITY, f64::INFINITY, 0);
        for axis in 0..3 {
            let h = self.half[axis];
            if d_l[axis] == 0.0 {
                if o_l[axis].abs() > h {
                    return None;
                }
                continue;
            }
            let a = (-h - o_l[axis]) / d_l[axis];
            let b = (h - o_l[axis]) / d_l[axis];
            let (near, far) = (a.min(b), a.max(b));
            if near > t_in {
                t_in = near;
                axis_in = axis;
            }
            t_out = t_out.min(far);
        }
        (t_in <= t_out).then_some((t_in, t_out, axis_in))
    }

    /// The part of o + t·d, t ∈ [t_min, t_max], inside the box, if longer than zero.
    pub(crate) fn span(&self, o: DVec3, d: DVec3, t_min: f64, t_max: f64) -> Option<(f64, f64)> {
        let (t_in, t_out, _) = self.line_range(o, d)?;
        let (a, b) = (t_in.max(t_min), t_out.min(t_max));
        (a < b).then_some((a, b))
    }
}

/// Nearest t > 0 where o + t·d (|d| = 1) meets the sphere's surface. Geometric
/// solution: closest approach along the ray, then the half chord.
pub(crate) fn hit_sphere(center: DVec3, radius: f64, o: DVec3, d: DVec3) -> Option<f64> {
    let to_center = center - o;
    let t_mid = to_center.dot(d);
    let closest_sq = (to_center - t_mid * d).length_squared();
    let half_chord_sq = radius * radius - closest_sq;
    if half_chord_sq < 0.0 {
        return None;
    }
    let half_chord = half_chord_sq.sqrt();
    if t_mid - half_chord > 0.0 {
        Some(t_mid - half_chord)
    } else if t_mid + half_chord > 0.0 {
        Some(t_mid + half_chord)
    } else {
        None
    }
}

enum Geometry {
    /// A parallelogram corner + a·edge_u + b·edge_v, a, b ∈ [0, 1].
    Quad {
        corner: DVec3,
        edge_u: DVec3,
        edge_v: DVec3,
        /// Unit normal (either side).
        normal: DVec3,
    },
    Box(OrientedBox),
    Sphere {
        center: DVec3,
        radius: f64,
    },
}

/// An opaque two-sided Lambertian shape of the scene, in f64.
pub(crate) struct Surface {
    geometry: Geometry,
    pub(crate) albedo: DVec3,
}

impl Surface {
    pub(crate) fn from_shape(shape: &Shape) -> Self {
        match *shape {
            Shape::Quad {
                corner,
                edge_u,
                edge_v,
                albedo,
            } => Surface {
                geometry: Geometry::Quad {
                    corner: corner.as_dvec3(),
                    edge_u: edge_u.as_dvec3(),
                    edge_v: edge_v.as_dvec3(),
                    normal: edge_u.as_dvec3().cross(edge_v.as_dvec3()).normalize(),
                },
                albedo: albedo.as_dvec3(),
            },
            Shape::Box {
                center,
                size,
                rotation_deg,
                albedo,
            } => Surface {
                geometry: Geometry::Box(OrientedBox::from_scene(center, size, rotation_deg)),
                albedo: albedo.as_dvec3(),
            },
            Shape::Sphere {
                center,
                radius,
                albedo,
            } => Surface {
                geometry: Geometry::Sphere {
                    center: center.as_dvec3(),
                    radius: f64::from(radius),
                },
                albedo: albedo.as_dvec3(),
            },
        }
    }

    /// The nearest intersection of o + t·d (|d| = 1) with t > 0: t and a unit normal of
    /// either orientation.
    pub(crate) fn hit(&self, o: DVec3, d: DVec3) -> Option<(f64, DVec3)> {
        match self.geometry {
            Geometry::Quad {
                corner,
                edge_u,
                edge_v,
                normal,
            } => {
                // Möller–Trumbore with the parallelogram's (a, b) ∈ [0, 1]² test.
                let p = d.cross(edge_v);
                let det = edge_u.dot(p);
                if det == 0.0 {
                    return None;
                }
                let s = o - corner;
                let a = s.dot(p) / det;
                let q = s.cross(edge_u);
                let b = d.dot(q) / det;
                let t = edge_v.dot(q) / det;
                ((0.0..=1.0).contains(&a) && (0.0..=1.0).contains(&b) && t > 0.0)
                    .then_some((t, normal))
            }
            Geometry::Box(ref bounds) => {
                let (t_in, t_out, axis) = bounds.line_range(o, d)?;
                if t_in > 0.0 {
                    Some((t_in, bounds.rotation.col(axis)))
                } else if t_out > 0.0 {
                    // From inside: the exit face, whichever axis it is.
                    let x = bounds.rotation.transpose() * (o + t_out * d - bounds.center);
                    let ratio = x.abs() / bounds.half;
                    let axis = if ratio.x >= ratio.y && ratio.x >= ratio.z {
                        0
                    } else if ratio.y >= ratio.z {
                        1
                    } else {
                        2
                    };
                    Some((t_out, bounds.rotation.col(axis)))
                } else {
                    None
                }
            }
            Geometry::Sphere { center, radius } => {
                let t = hit_sphere(center, radius, o, d)?;
                Some((t, (o + t * d - center) / radius))
            }
        }
    }
}

/// Offset that lifts a point off a surface (relative to its coordinates' size).
pub(crate) fn surface_offset(x: DVec3) -> f64 {
    1e-9 * (1.0 + x.abs().max_element())
}

/// A directional light's gobo in f64.
pub(crate) struct GoboF64 {
    origin: DVec3,
    u: DVec3,
    v: DVec3,
    /// Counter-clockwise convex polygon.
    polygon: Vec<DVec2>,
}

impl GoboF64 {
    /// The gobo `g` of a directional light travelling along `direction`.
    pub(crate) fn new(direction: Vec3, g: &Gobo) -> Self {
        let (u, v) = Gobo::basis(direction);
        Self {
            origin: g.origin.as_dvec3(),
            u: u.as_dvec3(),
            v: v.as_dvec3(),
            polygon: g.polygon.iter().map(|p| p.as_dvec2()).collect(),
        }
    }

    /// Whether x projects inside the polygon (boundary included): left of every edge.
    pub(crate) fn lets_through(&self, x: DVec3) -> bool {
        let q = DVec2::new((x - self.origin).dot(self.u), (x - self.origin).dot(self.v));
        let n = self.polygon.len();
        (0..n).all(|i| {
            let (a, b) = (self.polygon[i], self.polygon[(i + 1) % n]);
            (b - a).perp_dot(q - a) >= 0.0
        })
    }
}

// ---------------------------------------------------------------------------------------
// Camera rays.

/// Camera rays of frame 0 in f64, with `CameraFrame::ray_direction`'s convention.
pub(crate) struct CameraRays {
    pub(crate) position: DVec3,
    forward: DVec3,
    right: DVec3,
    up: DVec3,
    tan_x: f64,
    tan_y: f64,
    width: f64,
    height: f64,
}

impl CameraRays {
    pub(crate) fn new(scene: &Scene) -> Self {
        let (position, look_at) = scene.camera.pose_at(0);
        let (position, look_at) = (position.as_dvec3(), look_at.as_dvec3());
        let forward = (look_at - position).normalize();
        let right = forward.cross(scene.camera.up.as_dvec3()).normalize();
        let up = right.cross(forward);
        let (width, height) = (
            f64::from(scene.render.width),
            f64::from(scene.render.height),
        );
        let tan_x = (f64::from(scene.camera.horizontal_fov_deg).to_radians() * 0.5).tan();
        Self {
            position,
            forward,
            right,
            up,
            tan_x,
            tan_y: tan_x * height / width,
            width,
            height,
        }
    }

    /// Unit direction through image-plane point (px, py) in pixels, (0, 0) the top left.
    pub(crate) fn direction(&self, px: f64, py: f64) -> DVec3 {
        let sx = (2.0 * px / self.width - 1.0) * self.tan_x;
        let sy = (1.0 - 2.0 * py / self.height) * self.tan_y;
        (self.forward + sx * self.right + sy * self.up).normalize()
    }
}

// ---------------------------------------------------------------------------------------
// Moments and threading.

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

/// `work(0..count)` on up to `available_parallelism` threads taking items from a
/// shared counter; the results in item order, whatever the thread count.
fn in_parallel<T: Send>(count: usize, work: impl Fn(usize) -> T + Sync) -> Vec<T> {
    let threads = std::thread::available_parallelism()
        .map_or(1, |t| t.get())
        .min(count);
    let next = AtomicUsize::new(0);
    let mut done: Vec<(usize, T)> = std::thread::scope(|s| {
        let workers: Vec<_> = (0..threads)
            .map(|_| {
                s.spawn(|| {
                    let mut done = Vec::new();
                    loop {
                        let i = next.fetch_add(1, Ordering::Relaxed);
                        if i >= count {
                            return done;
                        }
                        done.push((i, work(i)));
                    }
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| {
                w.join()
                    .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
            })
            .collect()
    });
    done.sort_by_key(|(i, _)| *i);
    done.into_iter().map(|(_, t)| t).collect()
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

/// A scene for the oracles' unit tests: a camera at (0, 0, 5) looking at the origin,
/// `size` pixels, `fov_deg` horizontal field of view, default integrator settings.
#[cfg(test)]
pub(crate) fn test_scene(
    media: Vec<nimbus_scene::Medium>,
    shapes: Vec<Shape>,
    lights: Vec<nimbus_scene::Light>,
    size: (u32, u32),
    fov_deg: f32,
) -> Scene {
    Scene {
        source: std::path::PathBuf::from("<test>"),
        light_keyframes: Vec::new(),
        render: nimbus_scene::RenderSettings {
            width: size.0,
            height: size.1,
            ..nimbus_scene::RenderSettings::default()
        },
        camera: nimbus_scene::Camera {
            position: Vec3::new(0.0, 0.0, 5.0),
            look_at: Vec3::ZERO,
            up: Vec3::Y,
            horizontal_fov_deg: fov_deg,
            keyframes: Vec::new(),
        },
        lights,
        media,
        shapes,
        integrator: nimbus_scene::Integrator::default(),
    }
}
