//! The reference cache: a converged reference is rendered once and kept as EXR plus a
//! JSON sidecar (settings, input files, device, its own noise) under a key that hashes
//! ([`fnv1a64`]) the scene file's bytes, the contents of every file the scene reads
//! ([`scene_inputs`]), the reference settings (its integrand's `max_bounces` among
//! them), the resolution and the Nimbus version.

use std::ops::Range;
use std::path::{Path, PathBuf};

use anyhow::{anyhow, ensure, Context as _, Result};
use nimbus_scene::{Scene, VolumeIntegrator};

use super::metrics::ReferenceNoise;
use nimbus::hashing::{fnv1a64, FNV_OFFSET};
pub(super) use nimbus::hashing::{scene_inputs, InputFile};
use nimbus::output::{read_exr, write_image, ImageRgb};
use nimbus::plan::RenderPlan;

/// `$XDG_CACHE_HOME/nimbus/references`, else `$HOME/.cache/nimbus/references`.
pub(super) fn default_cache_dir() -> Result<PathBuf> {
    let from = |var: &str| {
        std::env::var_os(var)
            .map(PathBuf::from)
            .filter(|p| p.is_absolute())
    };
    if let Some(dir) = from("XDG_CACHE_HOME") {
        return Ok(dir.join("nimbus/references"));
    }
    from("HOME")
        .map(|home| home.join(".cache/nimbus/references"))
        .ok_or_else(|| {
            anyhow!("neither XDG_CACHE_HOME nor HOME is set; pass --cache-dir DIR for the reference cache")
        })
}

/// The reference render, its settings and where it is cached.
pub(super) struct ReferenceJob {
    pub(super) scene: Scene,
    pub(super) plan: RenderPlan,
    /// `key=value` lines, hashed into the cache key and stored in the sidecar.
    settings: Vec<(String, String)>,
    /// The files the scene reads, hashed into the cache key and listed in the sidecar.
    inputs: Vec<InputFile>,
    pub(super) key: String,
    pub(super) exr: PathBuf,
    sidecar: PathBuf,
    /// An animated scene's measured scene frames: the reference is one image per frame
    /// (`passes = frames` dispatches each), cached as one EXR with the frames stacked
    /// top to bottom.
    pub(super) window: Option<Range<u32>>,
}

impl ReferenceJob {
    /// The reference `scene` rendered with `plan`, cached in `cache_dir` under
    /// `{stem}-{hash}`, the hash over `scene_bytes` (the scene file), the settings and
    /// the contents of `inputs` (the files the scene reads, [`scene_inputs`]).
    pub(super) fn new(
        scene: Scene,
        plan: RenderPlan,
        scene_bytes: &[u8],
        inputs: &[InputFile],
        stem: &str,
        cache_dir: &Path,
        window: Option<Range<u32>>,
    ) -> Self {
        let r = &scene.render;
        let mut settings: Vec<(String, String)> = [
            ("nimbus_version", env!("CARGO_PKG_VERSION").to_owned()),
            ("width", r.width.to_string()),
            ("height", r.height.to_string()),
            ("frames", r.frames.to_string()),
            ("spp", r.spp.to_string()),
            (
                "box_estimator",
                scene.integrator.box_estimator.name().to_owned(),
            ),
            ("box_samples", scene.integrator.box_samples.to_string()),
            ("max_bounces", scene.integrator.max_bounces.to_string()),
            ("seed", r.seed.to_string()),
            (
                "volume",
                match scene.integrator.volume {
                    VolumeIntegrator::Restir => "restir",
                    VolumeIntegrator::Baseline => "baseline",
                }
                .to_owned(),
            ),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_owned(), v))
        .collect();
        // A static scene's key is what it was before animated references existed.
        if let Some(w) = &window {
            settings.push(("scene_frames".to_owned(), format!("{}..{}", w.start, w.end)));
        }
        let mut hash = fnv1a64(FNV_OFFSET, scene_bytes);
        for (k, v) in &settings {
            hash = fnv1a64(hash, format!("\n{k}={v}").as_bytes());
        }
        for input in inputs {
            hash = fnv1a64(
                hash,
                format!("\nfile {}={:016x}", input.role, input.hash).as_bytes(),
            );
        }
        let key = format!("{stem}-{hash:016x}");
        Self {
            exr: cache_dir.join(format!("{key}.exr")),
            sidecar: cache_dir.join(format!("{key}.json")),
            scene,
            plan,
            settings,
            inputs: inputs.to_vec(),
            key,
            window,
        }
    }
}

/// The reference image with what is known about it.
pub(super) struct Reference {
    /// An animated scene's reference holds one frame per scene frame of the window,
    /// stacked top to bottom ([`Reference::frame`]).
    pub(super) image: ImageRgb,
    pub(super) noise: ReferenceNoise,
    pub(super) device: String,
    pub(super) cached: bool,
}

impl Reference {
    /// Frame `i` of a stacked reference of frames `height` rows tall (the whole image
    /// for a static scene's reference, `i` = 0).
    pub(super) fn frame(&self, i: usize, height: u32) -> Result<ImageRgb> {
        let w = self.image.width as usize;
        let h = height as usize;
        let data = self
            .image
            .data
            .get(i * w * h..(i + 1) * w * h)
            .ok_or_else(|| anyhow!("internal: the reference has no frame {i}"))?
            .to_vec();
        Ok(ImageRgb {
            width: self.image.width,
            height,
            data,
        })
    }
}

/// Frames `images` (of equal sizes) stacked top to bottom into one image.
pub(super) fn stack(images: &[ImageRgb]) -> Result<ImageRgb> {
    let first = images
        .first()
        .ok_or_else(|| anyhow!("internal: no frames to stack"))?;
    ensure!(
        images
            .iter()
            .all(|i| (i.width, i.height) == (first.width, first.height)),
        "internal: frames of different sizes"
    );
    Ok(ImageRgb {
        width: first.width,
        height: first.height * images.len() as u32,
        data: images.iter().flat_map(|i| i.data.iter().copied()).collect(),
    })
}

/// The cached reference when both files exist and the sidecar's key matches.
pub(super) fn load_cached(job: &ReferenceJob) -> Result<Option<Reference>> {
    if !job.exr.is_file() || !job.sidecar.is_file() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(&job.sidecar)
        .with_context(|| format!("reading {}", job.sidecar.display()))?;
    let Ok(meta) = serde_json::from_str::<serde_json::Value>(&text) else {
        eprintln!(
            "warning: {} is not valid JSON; rendering the reference again",
            job.sidecar.display()
        );
        return Ok(None);
    };
    if meta["key"].as_str() != Some(job.key.as_str()) {
        eprintln!(
            "warning: {} belongs to another reference; rendering again",
            job.sidecar.display()
        );
        return Ok(None);
    }
    let image = read_exr(&job.exr)?;
    let r = &job.scene.render;
    let frames = job.window.as_ref().map_or(1, |w| w.len() as u32);
    if (image.width, image.height) != (r.width, r.height * frames) {
        eprintln!(
            "warning: {} is {}x{}, not {}x{}; rendering the reference again",
            job.exr.display(),
            image.width,
            image.height,
            r.width,
            r.height * frames
        );
        return Ok(None);
    }
    let noise = ReferenceNoise {
        rms_std_error: meta["rms_std_error"].as_f64().unwrap_or(f64::NAN),
        mean_rel_std_error: meta["mean_rel_std_error"].as_f64().unwrap_or(f64::NAN),
    };
    Ok(Some(Reference {
        image,
        noise,
        device: meta["device"].as_str().unwrap_or("unknown").to_owned(),
        cached: true,
    }))
}

/// Writes the reference EXR and its sidecar, each through a temporary file renamed
/// into place, so an interrupted run never leaves a half-written cache entry.
pub(super) fn store_cached(
    job: &ReferenceJob,
    image: &ImageRgb,
    noise: &ReferenceNoise,
    device: &str,
    wall_s: f64,
) -> Result<()> {
    let dir = job.exr.parent().unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir)
        .with_context(|| format!("--cache-dir {}: cannot create the directory", dir.display()))?;
    let tmp_exr = dir.join(format!("{}.tmp-{}.exr", job.key, std::process::id()));
    write_image(&tmp_exr, image, 1.0)?;
    std::fs::rename(&tmp_exr, &job.exr)
        .with_context(|| format!("moving {} to {}", tmp_exr.display(), job.exr.display()))?;
    let mut meta = serde_json::Map::new();
    meta.insert("key".into(), job.key.clone().into());
    meta.insert(
        "scene".into(),
        job.scene.source.display().to_string().into(),
    );
    for (k, v) in &job.settings {
        let value = match v.parse::<u64>() {
            Ok(n) => n.into(),
            Err(_) => v.clone().into(),
        };
        meta.insert(k.clone(), value);
    }
    let files: Vec<serde_json::Value> = job
        .inputs
        .iter()
        .map(|input| {
            serde_json::json!({
                "role": input.role,
                "path": input.path.display().to_string(),
                "fnv1a64": format!("{:016x}", input.hash),
            })
        })
        .collect();
    meta.insert("files".into(), files.into());
    meta.insert("device".into(), device.into());
    meta.insert("render_wall_s".into(), wall_s.into());
    meta.insert("rms_std_error".into(), noise.rms_std_error.into());
    meta.insert("mean_rel_std_error".into(), noise.mean_rel_std_error.into());
    let text = serde_json::to_string_pretty(&serde_json::Value::Object(meta))?;
    let tmp_json = dir.join(format!("{}.tmp-{}.json", job.key, std::process::id()));
    std::fs::write(&tmp_json, text).with_context(|| format!("writing {}", tmp_json.display()))?;
    std::fs::rename(&tmp_json, &job.sidecar)
        .with_context(|| format!("moving {} to {}", tmp_json.display(), job.sidecar.display()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nimbus::hashing::hash_file;

    /// A fresh, empty directory for one test.
    fn scratch(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("nimbus-study-cache-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    /// The job of a 3x2 reference of the default scene at `spp`, as if its scene file
    /// held `scene_bytes`.
    fn reference_job(dir: &Path, scene_bytes: &[u8], spp: u32) -> ReferenceJob {
        let mut scene =
            nimbus_scene::parse_str(nimbus::DEFAULT_SCENE, Path::new("window.toml")).unwrap();
        scene.render.width = 3;
        scene.render.height = 2;
        scene.render.spp = spp;
        let plan = nimbus::plan::build(&scene, None).unwrap();
        ReferenceJob::new(scene, plan, scene_bytes, &[], "window", dir, None)
    }

    /// A grid scene in `dir` that reads files: raw density, velocity and
    /// `[[medium.frame]]` density, a procedural emission (no file) and an environment
    /// map (its bytes are not checked when loading).
    fn scene_with_files(dir: &Path) -> Scene {
        std::fs::write(dir.join("d.raw"), [0u8; 32]).unwrap();
        std::fs::write(dir.join("v.raw"), [0u8; 96]).unwrap();
        std::fs::write(dir.join("f2.raw"), [1u8; 32]).unwrap();
        std::fs::write(dir.join("sky.exr"), b"sky").unwrap();
        let text = "[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\n\
            [[light]]\ntype = \"environment\"\nfile = \"sky.exr\"\n\
            [[light]]\ntype = \"directional\"\ndirection = [0, -1, 0]\nirradiance = 1\n\
            [[medium]]\ntype = \"grid\"\nbounds_min = [-1, -1, -1]\nbounds_max = [1, 1, 1]\n\
            density = { file = \"d.raw\", dims = [2, 2, 2] }\n\
            emission = { procedural = \"cloud\", dims = [2, 2, 2] }\n\
            velocity = { file = \"v.raw\", dims = [2, 2, 2] }\n\
            [[medium.frame]]\nframe = 2\ndensity = { file = \"f2.raw\", dims = [2, 2, 2] }\n";
        nimbus_scene::parse_str(text, &dir.join("files.toml")).unwrap()
    }

    fn noise() -> ReferenceNoise {
        ReferenceNoise {
            rms_std_error: 0.125,
            mean_rel_std_error: 0.0625,
        }
    }

    #[test]
    fn fnv1a64_matches_the_published_vectors() {
        assert_eq!(fnv1a64(FNV_OFFSET, b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a64(FNV_OFFSET, b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a64(FNV_OFFSET, b"foobar"), 0x8594_4171_f739_67e8);
        // Hashing in pieces is hashing the concatenation.
        assert_eq!(
            fnv1a64(fnv1a64(FNV_OFFSET, b"foo"), b"bar"),
            fnv1a64(FNV_OFFSET, b"foobar")
        );
    }

    #[test]
    fn the_key_hashes_the_scene_file_and_the_settings() {
        let dir = Path::new("cache");
        let a = reference_job(dir, b"scene a", 4);
        let names: Vec<&str> = a.settings.iter().map(|(k, _)| k.as_str()).collect();
        assert_eq!(
            names,
            [
                "nimbus_version",
                "width",
                "height",
                "frames",
                "spp",
                "box_estimator",
                "box_samples",
                "max_bounces",
                "seed",
                "volume"
            ]
        );
        assert!(a.settings.contains(&("spp".to_owned(), "4".to_owned())));
        assert!(a.settings.contains(&("width".to_owned(), "3".to_owned())));
        let mut hash = fnv1a64(FNV_OFFSET, b"scene a");
        for (k, v) in &a.settings {
            hash = fnv1a64(hash, format!("\n{k}={v}").as_bytes());
        }
        assert_eq!(a.key, format!("window-{hash:016x}"));
        assert_eq!(a.exr, dir.join(format!("{}.exr", a.key)));
        assert_eq!(a.sidecar, dir.join(format!("{}.json", a.key)));
        assert_eq!(reference_job(dir, b"scene a", 4).key, a.key);
        assert_ne!(reference_job(dir, b"scene b", 4).key, a.key);
        assert_ne!(reference_job(dir, b"scene a", 8).key, a.key);
    }

    #[test]
    fn a_file_is_hashed_in_pieces_as_a_whole() {
        let dir = scratch("hash-file");
        let path = dir.join("big.raw");
        // Over one read buffer (1 MiB), so the hash continues across reads.
        let bytes: Vec<u8> = (0..3 << 19).map(|i: u32| (i % 251) as u8).collect();
        std::fs::write(&path, &bytes).unwrap();
        assert_eq!(hash_file(&path).unwrap(), fnv1a64(FNV_OFFSET, &bytes));
        let message = format!("{:#}", hash_file(&dir.join("gone.raw")).unwrap_err());
        assert!(message.contains("gone.raw"), "{message}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn every_file_the_scene_reads_is_an_input() {
        let dir = scratch("inputs");
        let scene = scene_with_files(&dir);
        let inputs = scene_inputs(&scene).unwrap();
        let found: Vec<(&str, PathBuf, u64)> = inputs
            .iter()
            .map(|i| (i.role.as_str(), i.path.clone(), i.hash))
            .collect();
        let h = |bytes: &[u8]| fnv1a64(FNV_OFFSET, bytes);
        assert_eq!(
            found,
            [
                ("[[medium]] #1 density", dir.join("d.raw"), h(&[0; 32])),
                ("[[medium]] #1 velocity", dir.join("v.raw"), h(&[0; 96])),
                (
                    "[[medium]] #1 [[medium.frame]] #1 density",
                    dir.join("f2.raw"),
                    h(&[1; 32])
                ),
                ("[[light]] #1 file", dir.join("sky.exr"), h(b"sky")),
            ]
        );
        // Procedural grids and box scenes read no file.
        let window = nimbus_scene::parse_str(nimbus::DEFAULT_SCENE, Path::new("w.toml")).unwrap();
        assert!(scene_inputs(&window).unwrap().is_empty());
        // A file that went away after loading is an error naming where the scene uses it.
        std::fs::remove_file(dir.join("v.raw")).unwrap();
        let message = format!("{:#}", scene_inputs(&scene).unwrap_err());
        assert!(
            message.contains("[[medium]] #1 velocity") && message.contains("v.raw"),
            "{message}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// A changed grid file next to an unchanged scene file is another reference.
    #[test]
    fn the_key_hashes_the_contents_of_the_files_the_scene_reads() {
        let dir = scratch("file-key");
        let scene = scene_with_files(&dir);
        let job = |inputs: &[InputFile]| {
            let base = reference_job(&dir, b"scene", 4);
            ReferenceJob::new(
                base.scene, base.plan, b"scene", inputs, "window", &dir, None,
            )
        };
        let before = scene_inputs(&scene).unwrap();
        let key = job(&before).key;
        assert_ne!(key, reference_job(&dir, b"scene", 4).key, "files hashed");
        assert_eq!(
            job(&scene_inputs(&scene).unwrap()).key,
            key,
            "deterministic"
        );
        for (name, bytes) in [("d.raw", &[7u8; 32][..]), ("sky.exr", b"SKY")] {
            let path = dir.join(name);
            let old = std::fs::read(&path).unwrap();
            std::fs::write(&path, bytes).unwrap();
            assert_ne!(
                job(&scene_inputs(&scene).unwrap()).key,
                key,
                "{name} changed"
            );
            std::fs::write(&path, old).unwrap();
        }
        assert_eq!(job(&scene_inputs(&scene).unwrap()).key, key, "restored");
        // The same bytes in another role are another input.
        let mut swapped = before.clone();
        swapped[0].role = "[[medium]] #1 emission".into();
        assert_ne!(job(&swapped).key, key);

        // The sidecar lists the files.
        let stored = job(&before);
        store_cached(&stored, &ImageRgb::new(3, 2), &noise(), "lavapipe", 1.0).unwrap();
        let text = std::fs::read_to_string(&stored.sidecar).unwrap();
        let meta: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(meta["files"].as_array().unwrap().len(), 4, "{text}");
        assert_eq!(meta["files"][0]["role"], "[[medium]] #1 density");
        assert_eq!(
            meta["files"][0]["fnv1a64"],
            format!("{:016x}", fnv1a64(FNV_OFFSET, &[0; 32]))
        );
        assert!(meta["files"][3]["path"]
            .as_str()
            .unwrap()
            .ends_with("sky.exr"));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_stored_reference_loads_back() {
        let dir = scratch("round-trip");
        let job = reference_job(&dir, b"scene", 4);
        assert!(load_cached(&job).unwrap().is_none(), "nothing cached yet");
        let image = ImageRgb {
            width: 3,
            height: 2,
            data: (0..6).map(|i| [i as f32 * 0.25, 1.0, 1e-3]).collect(),
        };
        store_cached(&job, &image, &noise(), "lavapipe", 1.5).unwrap();
        let cached = load_cached(&job).unwrap().expect("the stored reference");
        assert_eq!(cached.image, image);
        assert_eq!(cached.noise, noise());
        assert_eq!(cached.device, "lavapipe");
        assert!(cached.cached);

        let text = std::fs::read_to_string(&job.sidecar).unwrap();
        let meta: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(meta["key"], job.key.as_str());
        assert_eq!(meta["spp"], 4);
        assert_eq!(meta["width"], 3);
        assert_eq!(meta["max_bounces"], job.scene.integrator.max_bounces);
        assert_eq!(meta["files"], serde_json::json!([]));
        assert_eq!(
            meta["box_estimator"],
            job.scene.integrator.box_estimator.name()
        );
        assert_eq!(meta["device"], "lavapipe");
        assert_eq!(meta["render_wall_s"], 1.5);
        assert_eq!(meta["rms_std_error"], 0.125);

        // The temporary files were renamed into place.
        let mut files: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        files.sort();
        assert_eq!(
            files,
            [format!("{}.exr", job.key), format!("{}.json", job.key)]
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_cache_entry_that_does_not_match_is_not_used() {
        let dir = scratch("mismatch");
        let job = reference_job(&dir, b"scene", 4);
        let image = ImageRgb::new(3, 2);
        let store = |j: &ReferenceJob, image: &ImageRgb| {
            store_cached(j, image, &noise(), "lavapipe", 1.0).unwrap();
        };

        // The EXR without its sidecar.
        store(&job, &image);
        std::fs::remove_file(&job.sidecar).unwrap();
        assert!(load_cached(&job).unwrap().is_none(), "no sidecar");

        // A sidecar that is not JSON.
        store(&job, &image);
        std::fs::write(&job.sidecar, "{ not json").unwrap();
        assert!(load_cached(&job).unwrap().is_none(), "broken sidecar");

        // The sidecar of another reference.
        let other = reference_job(&dir, b"another scene", 4);
        store(&other, &image);
        std::fs::copy(&other.sidecar, &job.sidecar).unwrap();
        assert!(load_cached(&job).unwrap().is_none(), "another key");

        // An EXR of another size.
        store(&job, &ImageRgb::new(4, 2));
        assert!(load_cached(&job).unwrap().is_none(), "another size");

        // A sidecar with only the key: noise and device unknown.
        store(&job, &image);
        std::fs::write(&job.sidecar, format!("{{\"key\": \"{}\"}}", job.key)).unwrap();
        let cached = load_cached(&job).unwrap().expect("key matches");
        assert!(cached.noise.rms_std_error.is_nan());
        assert!(cached.noise.mean_rel_std_error.is_nan());
        assert_eq!(cached.device, "unknown");

        // An EXR that cannot be read is an error naming the file.
        std::fs::write(&job.exr, b"not an EXR").unwrap();
        let message = format!("{:#}", load_cached(&job).err().expect("unreadable EXR"));
        assert!(message.contains(&job.key), "{message}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
