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
//! (see [`crate::merge::RenderInfo`] for the keys). Channels named with a dot are the
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

/// An extra image beside the beauty: `channels` are (channel name, one value per pixel).
#[derive(Clone, Debug, PartialEq)]
pub struct Aov {
    pub name: String,
    pub channels: Vec<(String, Vec<f32>)>,
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
                planes.push((format!("{}.{channel}", aov.name), &values[..]));
            }
        }
        for (name, values) in planes {
            ensure!(
                values.len() == n,
                "cannot write {}: channel {name} has {} values for {n} pixels",
                path.display(),
                values.len()
            );
            if let Some(i) = values.iter().position(|v| !v.is_finite()) {
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
                format!("{}.{channel}", aov.name).as_str(),
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
    let layer = Layer::new(
        size,
        attributes,
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(channels.into()),
    );
    write_atomically(path, |tmp| {
        Image::from_layer(layer)
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
    Ok(Layers {
        color: image_of(&rgb),
        alpha,
        std_error: image_of(&se),
        alpha_std_error,
        aovs,
        attributes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layers_and_metadata_round_trip() {
        let dir = std::env::temp_dir().join(format!("nimbus-layers-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("layers.exr");
        let mut color = ImageRgb::new(3, 2);
        color.set(2, 1, [1.0, 2.0, 3.0]);
        let mut layers = Layers::opaque(color);
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
