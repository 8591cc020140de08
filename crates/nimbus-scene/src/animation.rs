//! Animation evaluation: the state of a scene at one frame. Camera keyframes, light
//! keyframes (`[[light.keyframe]]`) and density frames (`[[medium.frame]]`) are
//! interpolated (or, for density frames, selected) here; the types themselves are in
//! `types.rs`.

use glam::Vec3;

use crate::types::{
    reduce_degrees, Camera, CameraFrame, GridFrame, GridMedium, GridSource, Light, LightKeyframe,
    LightState, Medium, Scene, ANIMATED_TEMPORAL_LIMIT, STILL_TEMPORAL_LIMIT,
};

impl Scene {
    /// The lights at `frame` of an animation: each light with its `[[light.keyframe]]`
    /// values applied, linearly interpolated between keyframes by frame and clamped
    /// outside the keyed range (the convention of [`Camera::frame_at`]); directions are
    /// interpolated by normalized lerp, an environment's rotation as the unwrapped angle
    /// (then reduced to one turn). Equal to `self.lights` when no light is animated.
    /// Same length and order as `self.lights`.
    pub fn lights_at(&self, frame: u32) -> Vec<Light> {
        self.lights
            .iter()
            .enumerate()
            .map(|(i, light)| {
                let keys = self.light_keyframes.get(i).map_or(&[][..], Vec::as_slice);
                match light_state_at(keys, frame) {
                    Some(state) => light.with_state(state),
                    None => light.clone(),
                }
            })
            .collect()
    }

    /// Whether anything changes between frames: camera keyframes, light keyframes or
    /// density frames (`[[medium.frame]]`). A `velocity` grid alone animates nothing (it
    /// only guides ReSTIR's reprojection). Frames of a static scene only accumulate.
    pub fn is_animated(&self) -> bool {
        !self.camera.keyframes.is_empty()
            || self.lights_animated()
            || self.media.iter().any(|m| match m {
                Medium::Grid(g) => !g.frames.is_empty(),
                Medium::Box(_) | Medium::Convex(_) => false,
            })
    }

    /// ReSTIR's Q (`[integrator.restir] temporal_limit`) as asked, or for `"auto"`
    /// [`STILL_TEMPORAL_LIMIT`] where nothing moves and [`ANIMATED_TEMPORAL_LIMIT`]
    /// where something does ([`Scene::is_animated`]).
    pub fn restir_temporal_limit(&self) -> u32 {
        self.integrator
            .restir
            .temporal_limit
            .unwrap_or(if self.is_animated() {
                ANIMATED_TEMPORAL_LIMIT
            } else {
                STILL_TEMPORAL_LIMIT
            })
    }

    /// Whether any light has `[[light.keyframe]]` entries, i.e. whether
    /// [`Scene::lights_at`] may differ from `self.lights` (and between frames).
    pub fn lights_animated(&self) -> bool {
        self.light_keyframes
            .iter()
            .take(self.lights.len())
            .any(|keys| !keys.is_empty())
    }
}

/// The state of a light animated by `keys` (sorted by frame) at `frame`: linear between
/// keyframes, clamped outside, exactly a keyframe's state at its frame. `None` without
/// keyframes.
fn light_state_at(keys: &[LightKeyframe], frame: u32) -> Option<LightState> {
    let first = keys.first()?;
    if frame <= first.frame {
        return Some(first.state);
    }
    for pair in keys.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        if frame == b.frame {
            return Some(b.state);
        }
        if frame < b.frame {
            // In f64 for the angles; rounded to f32 it is the f32 quotient exactly
            // (double rounding is innocuous for one division of integers below 2^24).
            let s = f64::from(frame - a.frame) / f64::from(b.frame - a.frame);
            return Some(a.state.lerp(b.state, s));
        }
    }
    keys.last().map(|k| k.state)
}

impl LightState {
    /// Interpolates from `self` (s = 0) to `other` (s = 1): positions, colours and
    /// rotation angles (unwrapped, in f64) linearly, directions by normalized lerp
    /// (keeping `self`'s direction if the two are exactly opposite at the midpoint).
    /// Different light types give `self`. Vectors and colours use `s` rounded to f32.
    pub fn lerp(self, other: Self, s: f64) -> Self {
        let s32 = s as f32;
        match (self, other) {
            (
                Self::Directional {
                    direction: d0,
                    irradiance: e0,
                },
                Self::Directional {
                    direction: d1,
                    irradiance: e1,
                },
            ) => Self::Directional {
                direction: d0.lerp(d1, s32).try_normalize().unwrap_or(d0),
                irradiance: e0.lerp(e1, s32),
            },
            (
                Self::Point {
                    position: p0,
                    intensity: i0,
                },
                Self::Point {
                    position: p1,
                    intensity: i1,
                },
            ) => Self::Point {
                position: p0.lerp(p1, s32),
                intensity: i0.lerp(i1, s32),
            },
            (
                Self::Sphere {
                    center: c0,
                    radiance: l0,
                },
                Self::Sphere {
                    center: c1,
                    radiance: l1,
                },
            ) => Self::Sphere {
                center: c0.lerp(c1, s32),
                radiance: l0.lerp(l1, s32),
            },
            // The unwrapped angle: 350 to 370 turns by 20 degrees.
            (Self::Environment { rotation_deg: r0 }, Self::Environment { rotation_deg: r1 }) => {
                Self::Environment {
                    rotation_deg: r0 + (r1 - r0) * s,
                }
            }
            _ => self,
        }
    }
}

impl Light {
    /// The light's animatable values (always `Some`: every type animates something).
    pub fn state(&self) -> Option<LightState> {
        match self {
            Self::Directional {
                direction,
                irradiance,
                ..
            } => Some(LightState::Directional {
                direction: *direction,
                irradiance: *irradiance,
            }),
            Self::Environment { rotation_deg, .. } => Some(LightState::Environment {
                rotation_deg: f64::from(*rotation_deg),
            }),
            Self::Point {
                position,
                intensity,
            } => Some(LightState::Point {
                position: *position,
                intensity: *intensity,
            }),
            Self::Sphere {
                center, radiance, ..
            } => Some(LightState::Sphere {
                center: *center,
                radiance: *radiance,
            }),
        }
    }

    /// A copy of this light with its animatable fields set from `state`; other fields
    /// (a sphere's radius, a gobo) are kept. A `state` of a different light type
    /// changes nothing.
    pub fn with_state(&self, state: LightState) -> Light {
        let mut light = self.clone();
        match (&mut light, state) {
            (
                Self::Directional {
                    direction,
                    irradiance,
                    ..
                },
                LightState::Directional {
                    direction: d,
                    irradiance: e,
                },
            ) => {
                *direction = d;
                *irradiance = e;
            }
            (
                Self::Point {
                    position,
                    intensity,
                },
                LightState::Point {
                    position: p,
                    intensity: i,
                },
            ) => {
                *position = p;
                *intensity = i;
            }
            (
                Self::Sphere {
                    center, radiance, ..
                },
                LightState::Sphere {
                    center: c,
                    radiance: l,
                },
            ) => {
                *center = c;
                *radiance = l;
            }
            (
                Self::Environment { rotation_deg, .. },
                LightState::Environment { rotation_deg: r },
            ) => {
                *rotation_deg = reduce_degrees(r) as f32;
            }
            _ => {}
        }
        light
    }
}

impl GridMedium {
    /// Which density grid is in effect at `frame`: 0 for the base `density`, `i + 1`
    /// for `frames[i]`, the `[[medium.frame]]` entry with the largest `frame` <= the
    /// given frame (the base density before the first entry). Indexes
    /// [`GridMedium::density_sources`].
    pub fn density_index_at(&self, frame: u32) -> usize {
        self.frames
            .iter()
            .enumerate()
            .filter(|(_, f)| f.frame <= frame)
            .max_by_key(|(_, f)| f.frame)
            .map_or(0, |(i, _)| i + 1)
    }

    /// The density grid in effect at `frame` (see [`GridMedium::density_index_at`]).
    pub fn density_at(&self, frame: u32) -> &GridSource {
        match self.density_index_at(frame) {
            0 => &self.density,
            i => &self.frames[i - 1].density,
        }
    }

    /// The temperature grid in effect with density grid `index` (indexed like
    /// [`GridMedium::density_index_at`]): the latest `[[medium.frame]]` at or before it
    /// that gives a `temperature`, else the medium's own (`None` without one).
    pub fn temperature_source_at_index(&self, index: usize) -> Option<&GridSource> {
        let base = &self.temperature.as_ref()?.source;
        Some(
            self.held_at_index(index, |f| f.temperature.as_ref())
                .unwrap_or(base),
        )
    }

    /// The albedo grid in effect with density grid `index`, as
    /// [`GridMedium::temperature_source_at_index`].
    pub fn albedo_source_at_index(&self, index: usize) -> Option<&GridSource> {
        let base = self.albedo_grid.as_ref()?;
        Some(
            self.held_at_index(index, |f| f.albedo.as_ref())
                .unwrap_or(base),
        )
    }

    /// The emission grid in effect with density grid `index`, as
    /// [`GridMedium::temperature_source_at_index`].
    pub fn emission_source_at_index(&self, index: usize) -> Option<&GridSource> {
        let base = self.emission.as_ref()?;
        Some(
            self.held_at_index(index, |f| f.emission.as_ref())
                .unwrap_or(base),
        )
    }

    /// The grid `pick` gives of the latest of the first `index` frames that gives one.
    fn held_at_index<'a>(
        &'a self,
        index: usize,
        pick: impl Fn(&'a GridFrame) -> Option<&'a GridSource>,
    ) -> Option<&'a GridSource> {
        self.frames[..index.min(self.frames.len())]
            .iter()
            .rev()
            .find_map(pick)
    }

    /// Whether some `[[medium.frame]]` swaps a grid other than the density (temperature,
    /// albedo or emission).
    pub fn has_shading_frames(&self) -> bool {
        self.frames
            .iter()
            .any(|f| f.temperature.is_some() || f.albedo.is_some() || f.emission.is_some())
    }

    /// Every density grid, indexed like [`GridMedium::density_index_at`]: the base
    /// `density`, then each `[[medium.frame]]`'s in order.
    pub fn density_sources(&self) -> impl Iterator<Item = &GridSource> + '_ {
        std::iter::once(&self.density).chain(self.frames.iter().map(|f| &f.density))
    }
}

impl Camera {
    /// The camera's frame at `frame`, with keyframes linearly interpolated (clamped
    /// outside the keyed range). Without keyframes it is the static camera.
    pub fn frame_at(&self, frame: u32) -> CameraFrame {
        let (position, look_at) = self.pose_at(frame);
        let mut view = look_at - position;
        if !view.is_finite() {
            // Opposite positions near the f32 limit: their difference overflows f32.
            view = ((look_at.as_dvec3() - position.as_dvec3()) * 0.5f64.powi(64)).as_vec3();
        }
        let forward = normalize_scaled(view);
        let right = normalize_scaled(forward.cross(self.up));
        let up = right.cross(forward);
        CameraFrame {
            position,
            forward,
            right,
            up,
            tan_half_fov_x: (self.horizontal_fov_deg.to_radians() * 0.5).tan(),
        }
    }

    /// The camera's (position, look_at) at `frame`: keyframes linearly interpolated,
    /// clamped outside the keyed range; the static pose without keyframes.
    pub fn pose_at(&self, frame: u32) -> (Vec3, Vec3) {
        let keys = &self.keyframes;
        let Some(first) = keys.first() else {
            return (self.position, self.look_at);
        };
        if frame <= first.frame {
            return (first.position, first.look_at);
        }
        for pair in keys.windows(2) {
            let (a, b) = (pair[0], pair[1]);
            if frame <= b.frame {
                let s = (frame - a.frame) as f32 / (b.frame - a.frame) as f32;
                return (a.position.lerp(b.position, s), a.look_at.lerp(b.look_at, s));
            }
        }
        let last = keys[keys.len() - 1];
        (last.position, last.look_at)
    }
}

/// `v.normalize()` computed on `v` scaled by a power of two, so that its squared length
/// neither overflows (a camera 1e30 m from what it looks at: `normalize` gave zero and
/// a frame of NaN) nor underflows. Scaling by a power of two is exact: wherever
/// `normalize` itself works, the result is bit-identical.
fn normalize_scaled(v: Vec3) -> Vec3 {
    let m = v.abs().max_element();
    if !(m > 0.0 && m.is_finite()) {
        return v.normalize();
    }
    let exponent = (m.log2().floor() as i32).clamp(-126, 126);
    let scale = f32::from_bits(((127 - exponent) as u32) << 23);
    (v * scale).normalize()
}

impl CameraFrame {
    /// World-space unit direction through image-plane point (px, py) in pixels, (0, 0)
    /// the top-left corner of the image, for an image of `width` x `height`.
    pub fn ray_direction(&self, px: f32, py: f32, width: u32, height: u32) -> Vec3 {
        let tan_y = self.tan_half_fov_x * height as f32 / width as f32;
        let sx = (2.0 * px / width as f32 - 1.0) * self.tan_half_fov_x;
        let sy = (1.0 - 2.0 * py / height as f32) * tan_y;
        (self.forward + sx * self.right + sy * self.up).normalize()
    }
}
