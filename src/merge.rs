//! What a render records about itself ([`RenderInfo`], the `nimbus/*` header attributes
//! of its EXR) and `nimbus merge`: partial renders of one scene with the same settings
//! and different seeds combined into one image.
//!
//! Each input i is an unbiased estimate x_i of the same image, from w_i samples per
//! pixel (its `samples`), with standard error s_i. The merge is their sample-weighted
//! mean x = Σ w_i x_i / W (W = Σ w_i), the mean one render of all W samples would give,
//! and since the inputs are independent (different seeds), its standard error is
//! exactly s = sqrt(Σ (w_i / W)² s_i²), per pixel and channel. Alpha and the path AOVs
//! (emission, direct, indirect, light groups, and their `<layer>_stderr` layers in
//! quadrature) merge the same way; the geometric AOVs (`Z`, `N`, `albedo`, `motion`: the
//! pixel-centre ray, the same in every part) are the first part's.
//!
//! Inputs are refused, naming the file and the attribute, when their Nimbus version,
//! scene hash (the scene file's bytes), settings hash (the effective scene after every
//! override except seed, spp and accumulated frames, plus which frame was rendered) or
//! size differ, or when two of them share a seed (they would be the same samples).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{bail, ensure, Context as _, Result};
use nimbus_scene::Scene;

use crate::hashing::{fnv1a64, FNV_OFFSET};
use crate::output::layers::{read_layers, write_layers, ExrView, Layers};
use crate::renderer::{film, RenderResult};

/// What a render records in its EXR header (as `nimbus/<key>` text attributes).
#[derive(Clone, Debug, PartialEq)]
pub struct RenderInfo {
    /// `version`: the Nimbus version.
    pub version: String,
    /// `scene`: the scene file as given (or the embedded default's name).
    pub scene: String,
    /// `scene_hash`: FNV-1a 64 of the scene file's bytes and of every file it reads
    /// ([`crate::hashing::scene_hash`]), 16 hex digits.
    pub scene_hash: String,
    /// `settings_hash`: FNV-1a 64 of the effective settings (see the module docs).
    pub settings_hash: String,
    /// `settings`: the same in words (image size, integrator and its settings, which
    /// frame, the `--set` overrides).
    pub settings: String,
    /// `seeds`: the seed, or the seeds of a merge (comma-separated).
    pub seeds: Vec<u64>,
    /// `spp`: samples per pixel per frame (0 after merging inputs that differ).
    pub spp: u32,
    /// `frames`: frames accumulated into the image.
    pub frames: u64,
    /// `samples`: samples per pixel in the image (spp × frames, summed over merges).
    pub samples: u64,
    /// `estimates`: independent estimates behind the stderr layer (frames or batches).
    pub estimates: u64,
    /// `error_batch`: frames per independent estimate (ReSTIR: batch means).
    pub error_batch: u32,
    /// `rel_error`: the relative standard error of the image (empty if unknown).
    pub rel_error: Option<f64>,
    /// `device`: the Vulkan device(s).
    pub device: String,
    /// `gpu_ms`: GPU milliseconds of the measured frames (summed over merges).
    pub gpu_ms: f64,
    /// `wall_s`: wall-clock seconds of the render (summed over merges).
    pub wall_s: f64,
    /// `stop`: why the image ended.
    pub stop: String,
}

/// The keys [`RenderInfo`] writes, in order.
pub const INFO_KEYS: [&str; 16] = [
    "version",
    "scene",
    "scene_hash",
    "settings_hash",
    "settings",
    "seeds",
    "spp",
    "frames",
    "samples",
    "estimates",
    "error_batch",
    "rel_error",
    "device",
    "gpu_ms",
    "wall_s",
    "stop",
];

/// The hash of the bytes of a scene file, as written in `scene_hash`.
pub fn content_hash(bytes: &[u8]) -> String {
    format!("{:016x}", fnv1a64(FNV_OFFSET, bytes))
}

/// The effective settings of `scene` that every part of a merge must share, in words
/// and hashed: everything in the scene except its seed, its spp, its source path and
/// (for a static scene, where they only accumulate) its frame count, plus `selection`
/// (which frame(s) the image shows).
pub fn settings_of(scene: &Scene, animated: bool, selection: &str) -> (String, String) {
    let mut normalized = scene.clone();
    normalized.source = PathBuf::new();
    normalized.render.seed = 0;
    normalized.render.spp = 0;
    if !animated {
        normalized.render.frames = 0;
    }
    let hash = content_hash(format!("{normalized:?}\n{selection}").as_bytes());
    let r = &scene.render;
    let i = &scene.integrator;
    let mut words = format!(
        "{}x{}, pixel_jitter {}, max_bounces {}, volume {:?}, box_estimator {}, \
         box_samples {}",
        r.width,
        r.height,
        r.pixel_jitter,
        i.max_bounces,
        i.volume,
        i.box_estimator.name(),
        i.box_samples
    );
    let _ = write!(words, ", restir {:?}", i.restir);
    let _ = write!(words, ", {selection}");
    (words, hash)
}

impl RenderInfo {
    /// The header attributes.
    pub fn attributes(&self) -> BTreeMap<String, String> {
        let seeds: Vec<String> = self.seeds.iter().map(u64::to_string).collect();
        let values = [
            self.version.clone(),
            self.scene.clone(),
            self.scene_hash.clone(),
            self.settings_hash.clone(),
            self.settings.clone(),
            seeds.join(","),
            self.spp.to_string(),
            self.frames.to_string(),
            self.samples.to_string(),
            self.estimates.to_string(),
            self.error_batch.to_string(),
            self.rel_error
                .map(|e| format!("{e:.6}"))
                .unwrap_or_default(),
            self.device.clone(),
            format!("{:.3}", self.gpu_ms),
            format!("{:.3}", self.wall_s),
            self.stop.clone(),
        ];
        INFO_KEYS
            .iter()
            .map(|k| k.to_string())
            .zip(values)
            .collect()
    }

    /// Reads the attributes back; `file` names the image in errors.
    pub fn from_attributes(attributes: &BTreeMap<String, String>, file: &Path) -> Result<Self> {
        let get = |key: &str| -> Result<&str> {
            attributes.get(key).map(String::as_str).with_context(|| {
                format!(
                    "{}: no header attribute nimbus/{key}; only images written by \
                     `nimbus render` (.exr) can be merged",
                    file.display()
                )
            })
        };
        fn number<T: std::str::FromStr>(file: &Path, key: &str, text: &str) -> Result<T> {
            text.trim().parse::<T>().map_err(|_| {
                anyhow::anyhow!(
                    "{}: header attribute nimbus/{key} = {text:?} is not a number",
                    file.display()
                )
            })
        }
        let seeds = get("seeds")?
            .split(',')
            .map(|s| number::<u64>(file, "seeds", s))
            .collect::<Result<Vec<_>>>()?;
        let rel_error = match get("rel_error")?.trim() {
            "" => None,
            text => Some(number(file, "rel_error", text)?),
        };
        Ok(RenderInfo {
            version: get("version")?.to_string(),
            scene: get("scene")?.to_string(),
            scene_hash: get("scene_hash")?.to_string(),
            settings_hash: get("settings_hash")?.to_string(),
            settings: get("settings")?.to_string(),
            seeds,
            spp: number(file, "spp", get("spp")?)?,
            frames: number(file, "frames", get("frames")?)?,
            samples: number(file, "samples", get("samples")?)?,
            estimates: number(file, "estimates", get("estimates")?)?,
            error_batch: number(file, "error_batch", get("error_batch")?)?,
            rel_error,
            device: get("device")?.to_string(),
            gpu_ms: number(file, "gpu_ms", get("gpu_ms")?)?,
            wall_s: number(file, "wall_s", get("wall_s")?)?,
            stop: get("stop")?.to_string(),
        })
    }
}

/// The layers of a render's result, with its metadata and its camera's view.
pub fn layers_of(result: &RenderResult, info: &RenderInfo, view: Option<ExrView>) -> Layers {
    Layers {
        color: result.image.clone(),
        alpha: result.alpha.clone(),
        std_error: result.std_error.clone(),
        alpha_std_error: result.alpha_std_error.clone(),
        aovs: result.aovs.clone(),
        attributes: info.attributes(),
        view,
    }
}

/// Writes a render's image to `path`: an `.exr` with every layer and the metadata in
/// its header, or a tonemapped `.png` with the metadata as text chunks, RGBA (straight
/// alpha) for a `transparent` render.
pub fn write_render(
    path: &Path,
    result: &RenderResult,
    info: &RenderInfo,
    display: &crate::output::Display,
    transparent: bool,
    view: Option<ExrView>,
) -> Result<()> {
    if crate::output::image_extension(path)? == "exr" {
        write_layers(path, &layers_of(result, info, view))
    } else {
        let alpha = transparent.then_some(result.alpha.as_slice());
        crate::output::write_png_with_metadata(
            path,
            &result.image,
            alpha,
            display,
            &info.attributes(),
        )
    }
}

/// One input of a merge, read from its file.
struct Part {
    path: PathBuf,
    layers: Layers,
    info: RenderInfo,
}

/// Merges the renders in `inputs` into `out` (see the module docs); returns what the
/// merged image records.
pub fn merge_files(out: &Path, inputs: &[PathBuf]) -> Result<RenderInfo> {
    ensure!(
        inputs.len() >= 2,
        "nimbus merge needs at least two input images, got {}",
        inputs.len()
    );
    // The output must not be one of the inputs: the merge would replace a part it was
    // made from (compared as files, so another spelling of the same path is caught too).
    let out_file = std::fs::canonicalize(out).ok();
    for input in inputs {
        let same = input == out
            || out_file
                .as_ref()
                .is_some_and(|o| std::fs::canonicalize(input).ok().as_ref() == Some(o));
        ensure!(
            !same,
            "--out {} is also an input: a merge never overwrites a part it reads; write it \
             to another file",
            out.display()
        );
    }
    let parts = inputs
        .iter()
        .map(|path| {
            // A directory, a device or a missing file is named as what it is (issue 24:
            // a directory was refused as "a .png", a device as "file identifier missing").
            let meta = std::fs::metadata(path)
                .with_context(|| format!("input {}: cannot read it", path.display()))?;
            ensure!(
                meta.is_file(),
                "input {}: not a regular file (a directory, pipe or device cannot be merged)",
                path.display()
            );
            let is_exr = path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
            ensure!(
                is_exr,
                "{}: nimbus merge reads the .exr images of `nimbus render` (their sums and \
                 standard errors); a .png is tonemapped to 8 bits and cannot be merged: \
                 render the parts as .exr",
                path.display()
            );
            let layers = read_layers(path)?;
            check_finite(path, &layers)?;
            let info = RenderInfo::from_attributes(&layers.attributes, path)?;
            Ok(Part {
                path: path.clone(),
                layers,
                info,
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let (layers, info) = merge(&parts)?;
    write_layers(out, &layers).with_context(|| format!("writing {}", out.display()))?;
    Ok(info)
}

/// Refuses a part with a non-finite value in any layer, naming it: `nimbus render`
/// drops non-finite samples and never writes one, so the file was changed or written by
/// something else, and a merge would spread the NaN over the result.
fn check_finite(path: &Path, layers: &Layers) -> Result<()> {
    let width = layers.color.width as usize;
    let planes: [(&str, Vec<f32>); 4] = [
        ("RGB", layers.color.data.iter().flatten().copied().collect()),
        ("A", layers.alpha.clone()),
        (
            "stderr.RGB",
            layers.std_error.data.iter().flatten().copied().collect(),
        ),
        ("stderr.A", layers.alpha_std_error.clone()),
    ];
    for (name, values) in &planes {
        let per_pixel = if name.ends_with("RGB") { 3 } else { 1 };
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            let pixel = i / per_pixel;
            bail!(
                "{}: {name} of pixel ({}, {}) is {}: not an image `nimbus render` wrote as \
                 it is (it never writes a non-finite value); refusing to merge it",
                path.display(),
                pixel % width.max(1),
                pixel / width.max(1),
                values[i]
            );
        }
    }
    Ok(())
}

/// Refuses parts that are not the same render with other seeds.
fn check_compatible(parts: &[Part]) -> Result<()> {
    let first = &parts[0];
    for part in &parts[1..] {
        let differ = |what: &str, a: &str, b: &str| -> Result<()> {
            if a != b {
                bail!(
                    "cannot merge {} with {}: their {what} differ ({a:?} vs {b:?}); only \
                     renders of the same scene with the same settings and different seeds \
                     can be merged",
                    part.path.display(),
                    first.path.display()
                );
            }
            Ok(())
        };
        differ(
            "Nimbus versions (nimbus/version)",
            &first.info.version,
            &part.info.version,
        )?;
        differ(
            "scene files (nimbus/scene_hash)",
            &first.info.scene_hash,
            &part.info.scene_hash,
        )?;
        differ(
            "settings (nimbus/settings_hash)",
            &format!("{} [{}]", first.info.settings, first.info.settings_hash),
            &format!("{} [{}]", part.info.settings, part.info.settings_hash),
        )?;
        let size = |p: &Part| format!("{}x{}", p.layers.color.width, p.layers.color.height);
        differ("image sizes", &size(first), &size(part))?;
    }
    for (i, a) in parts.iter().enumerate() {
        for b in &parts[i + 1..] {
            if let Some(seed) = a.info.seeds.iter().find(|s| b.info.seeds.contains(s)) {
                bail!(
                    "cannot merge {} with {}: both were rendered with seed {seed}, so they \
                     hold the same samples; render each part with its own --seed",
                    a.path.display(),
                    b.path.display()
                );
            }
        }
    }
    Ok(())
}

fn merge(parts: &[Part]) -> Result<(Layers, RenderInfo)> {
    check_compatible(parts)?;
    let total: u64 = parts.iter().map(|p| p.info.samples).sum();
    ensure!(total > 0, "the inputs hold no samples");
    let weights: Vec<f64> = parts
        .iter()
        .map(|p| p.info.samples as f64 / total as f64)
        .collect();
    let first = &parts[0].layers;
    let n = first.color.data.len();
    let mut out = Layers::opaque(crate::output::ImageRgb::new(
        first.color.width,
        first.color.height,
    ));
    out.alpha = vec![0.0; n];
    // The parts render one scene and camera (check_compatible): the first's view.
    out.view = first.view.clone();
    // Mean: Σ w x; variance of the mean: Σ w² s².
    let mut var = vec![[0.0f64; 4]; n];
    let mut mean = vec![[0.0f64; 4]; n];
    for (part, &w) in parts.iter().zip(&weights) {
        let l = &part.layers;
        for i in 0..n {
            let x = [
                l.color.data[i][0],
                l.color.data[i][1],
                l.color.data[i][2],
                l.alpha[i],
            ];
            let s = [
                l.std_error.data[i][0],
                l.std_error.data[i][1],
                l.std_error.data[i][2],
                l.alpha_std_error[i],
            ];
            for c in 0..4 {
                mean[i][c] += w * f64::from(x[c]);
                var[i][c] += w * w * f64::from(s[c]) * f64::from(s[c]);
            }
        }
    }
    let mut mean4 = vec![[0.0f32; 4]; n];
    let mut se4 = vec![[0.0f32; 4]; n];
    for i in 0..n {
        for c in 0..4 {
            mean4[i][c] = mean[i][c] as f32;
            se4[i][c] = var[i][c].sqrt() as f32;
        }
        out.color.data[i] = [mean4[i][0], mean4[i][1], mean4[i][2]];
        out.alpha[i] = mean4[i][3];
        out.std_error.data[i] = [se4[i][0], se4[i][1], se4[i][2]];
        out.alpha_std_error[i] = se4[i][3];
    }
    // AOVs present in every part. The geometric ones (Z, N, albedo, motion: the
    // pixel-centre ray, deterministic) are the first part's; the path estimates
    // (emission, direct, indirect, light groups) are sample-weighted like the beauty and
    // their `<layer>_stderr` layers added in quadrature, Σ w² s².
    for aov in &first.aovs {
        let mut merged = aov.clone();
        if crate::renderer::aovs::is_geometric_layer(&aov.name) {
            out.aovs.push(merged);
            continue;
        }
        let is_stderr = aov.name.ends_with(crate::renderer::aovs::STDERR_SUFFIX);
        for (channel, values) in merged.channels.iter_mut() {
            let mut acc = vec![0.0f64; values.len()];
            for (part, &w) in parts.iter().zip(&weights) {
                let Some(src) = part
                    .layers
                    .aovs
                    .iter()
                    .find(|a| a.name == aov.name)
                    .and_then(|a| a.channels.iter().find(|(c, _)| c == channel))
                else {
                    bail!(
                        "cannot merge: {} has no AOV channel {}",
                        part.path.display(),
                        aov.channel_name(channel)
                    );
                };
                for (v, s) in acc.iter_mut().zip(&src.1) {
                    let s = f64::from(*s);
                    *v += if is_stderr { w * w * s * s } else { w * s };
                }
            }
            for (v, a) in values.iter_mut().zip(acc) {
                *v = if is_stderr { a.sqrt() } else { a } as f32;
            }
        }
        out.aovs.push(merged);
    }

    let infos: Vec<&RenderInfo> = parts.iter().map(|p| &p.info).collect();
    let spp = infos[0].spp;
    let mut devices: Vec<&str> = Vec::new();
    for i in &infos {
        for d in i.device.split(", ") {
            if !devices.contains(&d) {
                devices.push(d);
            }
        }
    }
    let info = RenderInfo {
        version: infos[0].version.clone(),
        scene: infos[0].scene.clone(),
        scene_hash: infos[0].scene_hash.clone(),
        settings_hash: infos[0].settings_hash.clone(),
        settings: infos[0].settings.clone(),
        seeds: infos.iter().flat_map(|i| i.seeds.iter().copied()).collect(),
        spp: if infos.iter().all(|i| i.spp == spp) {
            spp
        } else {
            0
        },
        frames: infos.iter().map(|i| i.frames).sum(),
        samples: total,
        estimates: infos.iter().map(|i| i.estimates).sum(),
        error_batch: infos.iter().map(|i| i.error_batch).max().unwrap_or(1),
        rel_error: Some(film::relative_error(&mean4, &se4)),
        device: devices.join(", "),
        gpu_ms: infos.iter().map(|i| i.gpu_ms).sum(),
        wall_s: infos.iter().map(|i| i.wall_s).sum(),
        stop: format!("merged from {} renders", parts.len()),
    };
    out.attributes = info.attributes();
    Ok((out, info))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::output::ImageRgb;

    fn part(name: &str, seed: u64, samples: u64, value: f32, se: f32) -> Part {
        let mut layers = Layers::opaque(ImageRgb {
            width: 2,
            height: 1,
            data: vec![[value; 3]; 2],
        });
        layers.std_error.data = vec![[se; 3]; 2];
        let info = RenderInfo {
            version: "0".into(),
            scene: "s.toml".into(),
            scene_hash: "aa".into(),
            settings_hash: "bb".into(),
            settings: "2x1".into(),
            seeds: vec![seed],
            spp: 1,
            frames: samples,
            samples,
            estimates: samples,
            error_batch: 1,
            rel_error: None,
            device: "llvmpipe".into(),
            gpu_ms: 1.0,
            wall_s: 1.0,
            stop: "done".into(),
        };
        layers.attributes = info.attributes();
        Part {
            path: PathBuf::from(name),
            layers,
            info,
        }
    }

    #[test]
    fn merge_weights_by_samples_and_adds_errors_in_quadrature() {
        let (l, info) = merge(&[part("a", 1, 100, 1.0, 0.3), part("b", 2, 300, 2.0, 0.1)]).unwrap();
        // x = 0.25·1 + 0.75·2; s² = 0.25²·0.09 + 0.75²·0.01.
        assert!((l.color.data[0][0] - 1.75).abs() < 1e-6);
        let s = (0.0625f64 * 0.09 + 0.5625 * 0.01).sqrt() as f32;
        assert!((l.std_error.data[1][2] - s).abs() < 1e-6);
        assert_eq!(info.samples, 400);
        assert_eq!(info.seeds, vec![1, 2]);
        let back = RenderInfo::from_attributes(&l.attributes, Path::new("m.exr")).unwrap();
        assert_eq!(back.samples, 400);
        assert_eq!(back.stop, "merged from 2 renders");
    }

    #[test]
    fn merge_refuses_other_scenes_settings_and_shared_seeds() {
        let a = part("a.exr", 1, 10, 1.0, 0.1);
        let mut b = part("b.exr", 2, 10, 1.0, 0.1);
        b.info.scene_hash = "cc".into();
        let e = format!("{:#}", merge(&[a, b]).unwrap_err());
        assert!(e.contains("b.exr") && e.contains("scene_hash"), "{e}");

        let a = part("a.exr", 1, 10, 1.0, 0.1);
        let mut b = part("b.exr", 2, 10, 1.0, 0.1);
        b.info.settings_hash = "dd".into();
        let e = format!("{:#}", merge(&[a, b]).unwrap_err());
        assert!(e.contains("settings_hash"), "{e}");

        let e = format!(
            "{:#}",
            merge(&[
                part("a.exr", 7, 10, 1.0, 0.1),
                part("b.exr", 7, 10, 1.0, 0.1)
            ])
            .unwrap_err()
        );
        assert!(e.contains("seed 7"), "{e}");
    }

    #[test]
    fn missing_metadata_is_named() {
        let e = RenderInfo::from_attributes(&BTreeMap::new(), Path::new("plain.exr")).unwrap_err();
        let e = format!("{e:#}");
        assert!(e.contains("plain.exr") && e.contains("nimbus/"), "{e}");
    }
}
