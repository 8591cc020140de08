//! The output layers (AOVs) a render writes beside the beauty: [`AovPlan`].
//!
//! The scene (`[render] aovs`, overridden by `nimbus render --aovs`) asks for them; the
//! plan decides what the shaders compute (`SC_AOV_GEOMETRY`, `SC_AOV_PATHS`,
//! `SC_AOV_GROUPS`), which light groups exist and in which slots of the path-AOV buffers
//! each estimate lies. A render that asks for none has every constant off and binds
//! one-element dummies: it renders the same image at the same cost.
//!
//! Buffers (`src/shader_data/contract/bindings.rs`, `shaders/include/aov.glsl`):
//! - `AOV_GEOMETRY`: `AOV_GEOMETRY_VEC4S` vec4 per pixel, (N, Z), (albedo, 0),
//!   (motion, 0, 0), overwritten by every frame;
//! - `AOV_ACCUM`, `AOV_ACCUM_SQ`: per path slot and pixel, the sum over frames of the
//!   frame's estimate (rgb) and of its square, slot-major: slots 0, 1, 2 are emission,
//!   direct and indirect (with [`AovPlan::paths`]), then one slot per light group;
//! - `AOV_PARTIAL`: a frame's partial sums per slot while its samples are shared among
//!   dispatches (per pixel only on a device with a loop budget).

use nimbus_scene::{Aov, Light, Medium, Scene, DEFAULT_LIGHT_GROUP};

use super::Decision;
use crate::shader_data::{features, LightGpu, LIGHT_AREA};

/// Which AOVs a render writes and how the shaders lay them out.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct AovPlan {
    /// The AOVs asked for, in [`Aov::ALL`] order.
    pub asked: Vec<Aov>,
    /// Depth, normal, albedo or motion asked: the pixel-centre ray is traced each frame.
    pub geometry: bool,
    /// Emission, direct or indirect asked: all three are estimated (slots 0..3).
    pub paths: bool,
    /// The light groups written (lightgroups asked): named groups in order of first
    /// appearance among the lights, then `default` where anything falls into it.
    pub groups: Vec<String>,
}

impl AovPlan {
    /// The AOVs of `scene` (`[render] aovs`, after any `--aovs` override).
    pub fn of(scene: &Scene) -> AovPlan {
        let asked = scene.render.aovs.clone();
        let has = |a: Aov| asked.contains(&a);
        let geometry = asked.iter().any(|a| a.is_geometric());
        let paths = has(Aov::Emission) || has(Aov::Direct) || has(Aov::Indirect);
        let groups = if has(Aov::LightGroups) {
            scene_groups(scene)
        } else {
            Vec::new()
        };
        AovPlan {
            asked,
            geometry,
            paths,
            groups,
        }
    }

    /// Whether any AOV is written.
    pub fn any(&self) -> bool {
        !self.asked.is_empty()
    }

    pub fn wants(&self, aov: Aov) -> bool {
        self.asked.contains(&aov)
    }

    /// Path-AOV slots per pixel: emission, direct, indirect (with [`Self::paths`]) and one
    /// per light group.
    pub fn path_slots(&self) -> u32 {
        3 * u32::from(self.paths) + self.groups.len() as u32
    }

    /// The slot of light group `g`.
    pub fn group_slot(&self, g: usize) -> usize {
        3 * usize::from(self.paths) + g
    }

    /// `SC_AOV_GROUPS`: light groups written (0: none).
    pub fn group_count(&self) -> u32 {
        self.groups.len() as u32
    }

    fn index_of(&self, name: &str) -> u32 {
        self.groups.iter().position(|g| g == name).unwrap_or(0) as u32
    }

    /// The group index of the `default` group (media emission, emitting shapes, lights
    /// without `group`); 0 without light groups.
    pub fn default_group(&self) -> u32 {
        self.index_of(DEFAULT_LIGHT_GROUP)
    }

    /// The group index of the scene's environment light (the first one's; 0 without
    /// light groups or environment).
    pub fn env_group(&self, scene: &Scene) -> u32 {
        scene
            .lights
            .iter()
            .position(|l| matches!(l, Light::Environment { .. }))
            .map_or(self.default_group(), |i| {
                self.index_of(scene.light_group(i))
            })
    }

    /// Sets the `group` of light records built from `scene`'s lights in order with the
    /// environment left out (`LightSet::build`, `GpuScene::build`; an area record's group
    /// is `default`). Every pass that uploads light records calls it.
    pub fn assign_groups(&self, scene: &Scene, records: &mut [LightGpu]) {
        if self.groups.is_empty() {
            return;
        }
        let mut analytic = scene
            .lights
            .iter()
            .enumerate()
            .filter(|(_, l)| !matches!(l, Light::Environment { .. }))
            .map(|(i, _)| self.index_of(scene.light_group(i)));
        for record in records.iter_mut() {
            record.group = if record.r#type == LIGHT_AREA {
                self.default_group()
            } else {
                analytic.next().unwrap_or(self.default_group())
            };
        }
    }

    /// The EXR layers the render writes, by name, for `--explain`.
    pub fn layer_names(&self) -> Vec<String> {
        let mut out = Vec::new();
        for aov in &self.asked {
            match aov {
                Aov::Depth => out.push("Z".to_string()),
                Aov::Normal => out.push("N.X/Y/Z".to_string()),
                Aov::Albedo => out.push("albedo.R/G/B".to_string()),
                Aov::Emission => out.push("emission.R/G/B (+ emission_stderr)".to_string()),
                Aov::Direct => out.push("direct.R/G/B (+ direct_stderr)".to_string()),
                Aov::Indirect => out.push("indirect.R/G/B (+ indirect_stderr)".to_string()),
                Aov::LightGroups => out.extend(
                    self.groups
                        .iter()
                        .map(|g| format!("lightgroup.{g}.R/G/B (+ lightgroup.{g}_stderr)")),
                ),
                Aov::Motion => out.push("motion.X/Y".to_string()),
            }
        }
        out
    }

    /// The plan's decision row for `--explain`.
    pub fn decision(&self) -> Decision {
        if !self.any() {
            return Decision::new(
                "output layers (AOVs)",
                false,
                "none asked ([render] aovs, --aovs): no AOV is computed or bound".to_string(),
            );
        }
        let mut what = Vec::new();
        if self.geometry {
            what.push("the pixel-centre ray traced once per frame");
        }
        if self.paths {
            what.push("emission/direct/indirect split from every sample");
        }
        if !self.groups.is_empty() {
            what.push("light groups split from every sample");
        }
        Decision::new(
            "output layers (AOVs)",
            true,
            format!("{} ({})", self.layer_names().join(", "), what.join("; ")),
        )
    }
}

/// The light groups of `scene`: named groups in order of first appearance, then
/// `default` if anything falls into it (a light without `group`, an emitting medium or
/// shape) or no light names a group.
fn scene_groups(scene: &Scene) -> Vec<String> {
    let mut groups: Vec<String> = Vec::new();
    let mut default = false;
    for i in 0..scene.lights.len() {
        let g = scene.light_group(i);
        if g == DEFAULT_LIGHT_GROUP {
            default = true;
        } else if !groups.iter().any(|x| x == g) {
            groups.push(g.to_string());
        }
    }
    let emitting_medium = scene.media.iter().any(|m| match m {
        Medium::Grid(g) => g.emission.is_some() || g.temperature.is_some(),
        _ => false,
    });
    let emitting_shape = scene
        .shapes
        .iter()
        .any(|s| s.emission().max_element() > 0.0);
    if default || emitting_medium || emitting_shape || groups.is_empty() {
        groups.push(DEFAULT_LIGHT_GROUP.to_string());
    }
    groups
}

/// Bytes of the AOV buffers of a render: 16-byte dummies for what it does not ask for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AovBytes {
    /// The geometric AOVs (`AOV_GEOMETRY_VEC4S` vec4 per pixel).
    pub geometry: u64,
    /// Each of the path AOVs' sum and sum of squares (a vec4 per slot and pixel).
    pub accum: u64,
    /// Their partial sums while a frame's samples are shared among dispatches.
    pub partial: u64,
}

impl AovBytes {
    /// The buffers of `aov` for `pixels`; `shared_frames`: the device has a loop budget
    /// (a frame's samples may be shared among dispatches).
    pub fn of(aov: &AovPlan, pixels: u64, shared_frames: bool) -> AovBytes {
        let slots = u64::from(aov.path_slots());
        let geometry = if aov.geometry {
            pixels * 16 * u64::from(features::AOV_GEOMETRY_VEC4S)
        } else {
            16
        };
        let accum = (pixels * slots * 16).max(16);
        let partial = if shared_frames { accum } else { 16 };
        AovBytes {
            geometry,
            accum,
            partial,
        }
    }

    /// Every buffer's bytes: geometry, sums, sums of squares, partial sums.
    pub fn buffers(&self) -> [u64; 4] {
        [self.geometry, self.accum, self.accum, self.partial]
    }
}
