//! The EXR of a render, for compositing and for `nimbus merge`: one part, float32,
//! lossless ZIP, with the channels
//!
//! - `R`, `G`, `B`: mean radiance in W/(m²·sr), premultiplied by `A`;
//! - `A`: coverage, 1 − the mean transmittance of the camera ray through all media
//!   (1 where an opaque surface is seen);
//! - `stderr.R`, `stderr.G`, `stderr.B`, `stderr.A`: the standard error of the mean of
//!   each of those channels, per pixel;
//! - optional AOVs as `<name>.<channel>` (e.g. `depth.Z`);
//!
//! and the render's metadata as text attributes named `nimbus/<key>` in the header
//! (see [`crate::merge::RenderInfo`] for the keys). The header also carries the standard
//! attributes compositors read ([`ExrView`]): `chromaticities` (Rec. 709 primaries, D65:
//! the renderer's linear RGB), and for a render of a camera `worldToCamera`, `worldToNDC`,
//! `screenWindowCenter` / `screenWindowWidth` and, for one frame of an animation, `frame`. Channels named with a dot are the
//! layers of OpenEXR's naming convention, which Nuke, Blender, DJV and `exrheader`
//! show as separate layers of one image.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{bail, ensure, Context as _, Result};

use super::{check_image, image_extension, write_atomically, ImageRgb};

/// Prefix of Nimbus's header attributes.
pub const ATTRIBUTE_PREFIX: &str = "nimbus/";

/// The layer of per-pixel standard errors.
pub const STDERR_LAYER: &str = "stderr";

/// Rec. 709 / sRGB primaries and the D65 white point (CIE 1931 xy): the renderer's
/// linear RGB.
pub const REC709_D65: [[f32; 2]; 4] = [[0.64, 0.33], [0.30, 0.60], [0.15, 0.06], [0.3127, 0.3290]];

/// The camera of a render as OpenEXR's standard attributes describe it (the convention of
/// RenderMan, Arnold and Nuke): matrices act on row vectors (p' = p · M, Imath's `M44f`,
/// stored row by row); camera space is left-handed, x right, y up, z forward (along the
/// view); screen space is the plane z = 1 of camera space, (x/z, y/z); NDC maps the image
/// to [0, 1]², (0, 0) at its top-left corner, after the division by w.
#[derive(Clone, Debug, PartialEq)]
pub struct ExrView {
    pub world_to_camera: [f32; 16],
    pub world_to_ndc: [f32; 16],
    /// The image's width in screen space (2 tan(horizontal fov / 2)), centred on (0, 0).
    pub screen_window_width: f32,
    /// The scene frame of one frame of an animation.
    pub frame: Option<u32>,
}

impl ExrView {
    /// The view of `camera` on a `width` × `height` image.
    pub fn of(
        camera: &nimbus_scene::CameraFrame,
        width: u32,
        height: u32,
        frame: Option<u32>,
    ) -> Self {
        let axes = [camera.right, camera.up, camera.forward];
        let mut w2c = [0.0f32; 16];
        for (j, axis) in axes.iter().enumerate() {
            for i in 0..3 {
                w2c[4 * i + j] = axis[i];
            }
            w2c[12 + j] = -axis.dot(camera.position);
        }
        w2c[15] = 1.0;
        let sw = 2.0 * camera.tan_half_fov_x;
        let sh = sw * height as f32 / width.max(1) as f32;
        // Camera to NDC: X = x / sw + z / 2, Y = -y / sh + z / 2, Z = w = z.
        let mut c2n = [0.0f32; 16];
        c2n[0] = 1.0 / sw;
        c2n[8] = 0.5;
        c2n[5] = -1.0 / sh;
        c2n[9] = 0.5;
        c2n[10] = 1.0;
        c2n[11] = 1.0;
        let mut w2n = [0.0f32; 16];
        for r in 0..4 {
            for c in 0..4 {
                w2n[4 * r + c] = (0..4).map(|k| w2c[4 * r + k] * c2n[4 * k + c]).sum();
            }
        }
        Self {
            world_to_camera: w2c,
            world_to_ndc: w2n,
            screen_window_width: sw,
            frame,
        }
    }

    /// `p` · M for a row-major 4×4 `m`, divided by w.
    pub fn transform(m: &[f32; 16], p: glam::Vec3) -> glam::Vec3 {
        let v = [p.x, p.y, p.z, 1.0];
        let out: Vec<f32> = (0..4)
            .map(|c| (0..4).map(|k| v[k] * m[4 * k + c]).sum())
            .collect();
        glam::Vec3::new(out[0], out[1], out[2]) / out[3]
    }
}

/// An extra image beside the beauty: `channels` are (channel name, one value per pixel).
/// Its channels are written as `<name>.<channel>`, or `<channel>` alone for the empty
/// name (the depth `Z`).
#[derive(Clone, Debug, PartialEq)]
pub struct Aov {
    pub name: String,
    pub channels: Vec<(String, Vec<f32>)>,
}

impl Aov {
    /// The full EXR name of its channel `channel`: `N.X`, or `Z` for the empty layer.
    pub fn channel_name(&self, channel: &str) -> String {
        if self.name.is_empty() {
            channel.to_string()
        } else {
            format!("{}.{channel}", self.name)
        }
    }
}

/// The values of the AOV channel named `full` as the EXR names it (`Z`, `N.X`,
/// `albedo.R`, `motion.Y`, `lightgroup.key.G`, ...), if `aovs` has it.
pub fn find_channel<'a>(aovs: &'a [Aov], full: &str) -> Option<&'a [f32]> {
    aovs.iter().find_map(|a| {
        a.channels
            .iter()
            .find(|(c, _)| a.channel_name(c) == full)
            .map(|(_, v)| v.as_slice())
    })
}

/// Whether a channel may hold +inf: the depth `Z` where the camera ray meets nothing.
fn may_be_infinite(full: &str) -> bool {
    full == "Z"
}

/// Everything a render's EXR holds.
#[derive(Clone, Debug, PartialEq)]
pub struct Layers {
    /// Premultiplied mean radiance.
    pub color: ImageRgb,
    /// Coverage per pixel, `color.width * color.height` values.
    pub alpha: Vec<f32>,
    /// Standard error of `color`.
    pub std_error: ImageRgb,
    /// Standard error of `alpha`.
    pub alpha_std_error: Vec<f32>,
    pub aovs: Vec<Aov>,
    /// Metadata: header attribute `nimbus/<key>` = value.
    pub attributes: BTreeMap<String, String>,
    /// The camera, as the standard attributes (none for an image of no camera).
    pub view: Option<ExrView>,
}

impl Layers {
    /// An opaque image without errors, AOVs or metadata.
    pub fn opaque(color: ImageRgb) -> Self {
        let n = color.data.len();
        Self {
            std_error: ImageRgb::new(color.width, color.height),
            color,
            alpha: vec![1.0; n],
            alpha_std_error: vec![0.0; n],
            aovs: Vec::new(),
            attributes: BTreeMap::new(),
            view: None,
        }
    }

    fn check(&self, path: &Path) -> Result<()> {
        check_image(path, &self.color)?;
        check_image(path, &self.std_error)?;
        let n = self.color.data.len();
        ensure!(
            (self.std_error.width, self.std_error.height) == (self.color.width, self.color.height),
            "cannot write {}: the stderr layer is {}x{}, the image {}x{}",
            path.display(),
            self.std_error.width,
            self.std_error.height,
            self.color.width,
            self.color.height
        );
        let mut planes: Vec<(String, &[f32])> = vec![
            ("A".into(), &self.alpha[..]),
            ("stderr.A".into(), &self.alpha_std_error[..]),
        ];
        for aov in &self.aovs {
            for (channel, values) in &aov.channels {
                planes.push((aov.channel_name(channel), &values[..]));
            }
        }
        for (name, values) in planes {
            ensure!(
                values.len() == n,
                "cannot write {}: channel {name} has {} values for {n} pixels",
                path.display(),
                values.len()
            );
            let infinite_ok = may_be_infinite(&name);
            let bad = |v: &f32| !(v.is_finite() || (infinite_ok && *v == f32::INFINITY));
            if let Some(i) = values.iter().position(bad) {
                bail!(
                    "cannot write {}: channel {name} is not finite at pixel ({}, {})",
                    path.display(),
                    i % self.color.width.max(1) as usize,
                    i / self.color.width.max(1) as usize
                );
            }
        }
        Ok(())
    }
}

/// A header text: the bytes as written (UTF-8; OpenEXR's own library stores
/// `std::string` bytes the same way).
fn text(value: &str) -> exr::prelude::Text {
    exr::prelude::Text::from_slice_unchecked(value.as_bytes())
}

/// Writes `layers` to `path` (which must end in `.exr`) atomically.
pub fn write_layers(path: &Path, layers: &Layers) -> Result<()> {
    use exr::math::Vec2;
    use exr::meta::attribute::Chromaticities;
    use exr::prelude::{
        AnyChannel, AnyChannels, AttributeValue, Encoding, FlatSamples, Image, Layer,
        LayerAttributes, WritableImage,
    };

    ensure!(
        image_extension(path)? == "exr",
        "{}: layers (alpha, stderr, AOVs) need an .exr file",
        path.display()
    );
    layers.check(path)?;
    let size = (layers.color.width as usize, layers.color.height as usize);
    let plane = |f: &dyn Fn(usize) -> f32| -> FlatSamples {
        FlatSamples::F32((0..layers.color.data.len()).map(f).collect())
    };
    let mut channels = Vec::new();
    for (c, name) in ["R", "G", "B"].into_iter().enumerate() {
        channels.push(AnyChannel::new(name, plane(&|i| layers.color.data[i][c])));
        channels.push(AnyChannel::new(
            format!("{STDERR_LAYER}.{name}").as_str(),
            plane(&|i| layers.std_error.data[i][c]),
        ));
    }
    channels.push(AnyChannel::new("A", plane(&|i| layers.alpha[i])));
    channels.push(AnyChannel::new(
        format!("{STDERR_LAYER}.A").as_str(),
        plane(&|i| layers.alpha_std_error[i]),
    ));
    for aov in &layers.aovs {
        for (channel, values) in &aov.channels {
            channels.push(AnyChannel::new(
                aov.channel_name(channel).as_str(),
                FlatSamples::F32(values.clone()),
            ));
        }
    }
    let mut attributes = LayerAttributes {
        software_name: Some(text(&format!("Nimbus {}", env!("CARGO_PKG_VERSION")))),
        ..LayerAttributes::default()
    };
    for (key, value) in &layers.attributes {
        attributes.other.insert(
            text(&format!("{ATTRIBUTE_PREFIX}{key}")),
            AttributeValue::Text(text(value)),
        );
    }
    if let Some(view) = &layers.view {
        attributes.world_to_camera = Some(view.world_to_camera);
        attributes.world_to_normalized_device = Some(view.world_to_ndc);
        attributes.screen_window_center = Vec2(0.0, 0.0);
        attributes.screen_window_width = view.screen_window_width;
        if let Some(frame) = view.frame {
            attributes.other.insert(
                text("frame"),
                AttributeValue::I32(i32::try_from(frame).unwrap_or(i32::MAX)),
            );
        }
    }
    let layer = Layer::new(
        size,
        attributes,
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(channels.into()),
    );
    let mut image = Image::from_layer(layer);
    let xy = |i: usize| Vec2(REC709_D65[i][0], REC709_D65[i][1]);
    image.attributes.chromaticities = Some(Chromaticities {
        red: xy(0),
        green: xy(1),
        blue: xy(2),
        white: xy(3),
    });
    write_atomically(path, |tmp| {
        image
            .write()
            .to_file(tmp)
            .with_context(|| format!("write EXR {}", path.display()))
    })
}

/// Reads a render's EXR: `R`, `G`, `B` are required; `A` defaults to 1 and the
/// `stderr` channels to 0 when absent; other channels named `<layer>.<channel>` become
/// AOVs; `nimbus/<key>` text attributes the metadata.
pub fn read_layers(path: &Path) -> Result<Layers> {
    use exr::prelude::{read, AttributeValue, ReadChannels as _, ReadLayers as _};

    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .with_context(|| format!("read EXR {}", path.display()))?;
    let layer = &image.layer_data;
    let (width, height) = (layer.size.width(), layer.size.height());
    let n = width * height;
    let mut planes: BTreeMap<String, Vec<f32>> = layer
        .channel_data
        .list
        .iter()
        .map(|c| {
            (
                String::from_utf8_lossy(c.name.bytes()).into_owned(),
                c.sample_data.values_as_f32().collect(),
            )
        })
        .collect();
    let mut take = |name: &str, default: Option<f32>| -> Result<Vec<f32>> {
        match (planes.remove(name), default) {
            (Some(values), _) => Ok(values),
            (None, Some(d)) => Ok(vec![d; n]),
            (None, None) => bail!("{}: no channel {name}", path.display()),
        }
    };
    let rgb = [take("R", None)?, take("G", None)?, take("B", None)?];
    let se = [
        take("stderr.R", Some(0.0))?,
        take("stderr.G", Some(0.0))?,
        take("stderr.B", Some(0.0))?,
    ];
    let alpha = take("A", Some(1.0))?;
    let alpha_std_error = take("stderr.A", Some(0.0))?;
    let image_of = |planes: &[Vec<f32>; 3]| ImageRgb {
        width: width as u32,
        height: height as u32,
        data: (0..n)
            .map(|i| [planes[0][i], planes[1][i], planes[2][i]])
            .collect(),
    };
    let mut aovs: Vec<Aov> = Vec::new();
    for (name, values) in planes {
        let (layer_name, channel) = name.rsplit_once('.').unwrap_or(("", name.as_str()));
        match aovs.iter_mut().find(|a| a.name == layer_name) {
            Some(aov) => aov.channels.push((channel.to_string(), values)),
            None => aovs.push(Aov {
                name: layer_name.to_string(),
                channels: vec![(channel.to_string(), values)],
            }),
        }
    }
    let mut attributes = BTreeMap::new();
    let all = image
        .attributes
        .other
        .iter()
        .chain(layer.attributes.other.iter());
    for (key, value) in all {
        let key = String::from_utf8_lossy(key.bytes()).into_owned();
        if let (Some(key), AttributeValue::Text(value)) =
            (key.strip_prefix(ATTRIBUTE_PREFIX), value)
        {
            attributes.insert(
                key.to_string(),
                String::from_utf8_lossy(value.bytes()).into_owned(),
            );
        }
    }
    let a = &layer.attributes;
    let view = match (a.world_to_camera, a.world_to_normalized_device) {
        (Some(world_to_camera), Some(world_to_ndc)) => Some(ExrView {
            world_to_camera,
            world_to_ndc,
            screen_window_width: a.screen_window_width,
            frame: match a.other.get(&text("frame")) {
                Some(AttributeValue::I32(f)) => u32::try_from(*f).ok(),
                _ => None,
            },
        }),
        _ => None,
    };
    Ok(Layers {
        color: image_of(&rgb),
        alpha,
        std_error: image_of(&se),
        alpha_std_error,
        aovs,
        attributes,
        view,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The view's matrices put the point looked at in the image's centre, the edges of the
    /// field of view on the image's edges (NDC x = 1 on the right, y = 0 at the top), and
    /// depth along the view axis in camera z.
    #[test]
    fn the_view_projects_as_the_camera_does() {
        let scene = nimbus_scene::parse_str(
            "[render]\nwidth = 200\nheight = 100\n[camera]\nposition = [1, 2, 3]\n\
             look_at = [1, 2, -1]\nhorizontal_fov_deg = 90\n",
            Path::new("view.toml"),
        )
        .unwrap();
        let camera = scene.camera.frame_at(0);
        let view = ExrView::of(&camera, 200, 100, Some(7));
        let near = |a: glam::Vec3, b: glam::Vec3| (a - b).abs().max_element() < 1e-5;
        let c = ExrView::transform(&view.world_to_camera, glam::Vec3::new(1.0, 2.0, -1.0));
        assert!(near(c, glam::Vec3::new(0.0, 0.0, 4.0)), "{c}");
        let ndc = |p: glam::Vec3| ExrView::transform(&view.world_to_ndc, p);
        assert!(near(
            ndc(glam::Vec3::new(1.0, 2.0, -1.0)),
            glam::Vec3::new(0.5, 0.5, 1.0)
        ));
        // 90° horizontally: at depth 4 the right edge is 4 m to the side; the image is half
        // as tall, so its top edge is 2 m up.
        assert!(near(
            ndc(glam::Vec3::new(5.0, 2.0, -1.0)),
            glam::Vec3::new(1.0, 0.5, 1.0)
        ));
        assert!(near(
            ndc(glam::Vec3::new(1.0, 4.0, -1.0)),
            glam::Vec3::new(0.5, 0.0, 1.0)
        ));
        assert!((view.screen_window_width - 2.0).abs() < 1e-6);
    }

    #[test]
    fn layers_and_metadata_round_trip() {
        let dir = std::env::temp_dir().join(format!("nimbus-layers-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("layers.exr");
        let mut color = ImageRgb::new(3, 2);
        color.set(2, 1, [1.0, 2.0, 3.0]);
        let mut layers = Layers::opaque(color);
        let camera = nimbus_scene::parse_str(
            "[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\n",
            Path::new("c.toml"),
        )
        .unwrap()
        .camera
        .frame_at(0);
        layers.view = Some(ExrView::of(&camera, 3, 2, Some(12)));
        layers.alpha[5] = 0.25;
        layers.std_error.set(2, 1, [0.1, 0.2, 0.3]);
        layers.alpha_std_error[5] = 0.01;
        layers.aovs.push(Aov {
            name: "depth".into(),
            channels: vec![("Z".into(), vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0])],
        });
        layers
            .attributes
            .insert("scene".into(), "scènes/a b.toml".into());
        layers.attributes.insert("spp".into(), "16".into());
        write_layers(&path, &layers).unwrap();
        let back = read_layers(&path).unwrap();
        assert_eq!(back, layers);
        // The plain reader sees the beauty.
        assert_eq!(super::super::read_exr(&path).unwrap(), layers.color);
        std::fs::remove_dir_all(dir).unwrap();
    }
}
