//! The reference cache: a converged reference is rendered once and kept as EXR plus a
//! JSON sidecar (settings, device, its own noise) under a key that hashes
//! ([`fnv1a64`]) the scene file's bytes, the reference settings, the resolution and the
//! Nimbus version.

use std::path::{Path, PathBuf};

use anyhow::{anyhow, Context as _, Result};
use nimbus_scene::{Scene, VolumeIntegrator};

use super::metrics::ReferenceNoise;
use crate::output::{read_exr, write_image, ImageRgb};
use crate::plan::RenderPlan;

/// FNV-1a, 64 bit, over `bytes`, continuing from `hash` (start with [`FNV_OFFSET`]).
pub(crate) fn fnv1a64(mut hash: u64, bytes: &[u8]) -> u64 {
    for &b in bytes {
        hash ^= u64::from(b);
        hash = hash.wrapping_mul(0x0000_0100_0000_01B3);
    }
    hash
}

/// The FNV-1a 64 offset basis.
pub(crate) const FNV_OFFSET: u64 = 0xCBF2_9CE4_8422_2325;

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
    pub(super) key: String,
    pub(super) exr: PathBuf,
    sidecar: PathBuf,
}

impl ReferenceJob {
    /// The reference `scene` rendered with `plan`, cached in `cache_dir` under
    /// `{stem}-{hash}`, the hash over `scene_bytes` (the scene file) and the settings.
    pub(super) fn new(
        scene: Scene,
        plan: RenderPlan,
        scene_bytes: &[u8],
        stem: &str,
        cache_dir: &Path,
    ) -> Self {
        let r = &scene.render;
        let settings: Vec<(String, String)> = [
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
        let mut hash = fnv1a64(FNV_OFFSET, scene_bytes);
        for (k, v) in &settings {
            hash = fnv1a64(hash, format!("\n{k}={v}").as_bytes());
        }
        let key = format!("{stem}-{hash:016x}");
        Self {
            exr: cache_dir.join(format!("{key}.exr")),
            sidecar: cache_dir.join(format!("{key}.json")),
            scene,
            plan,
            settings,
            key,
        }
    }
}

/// The reference image with what is known about it.
pub(super) struct Reference {
    pub(super) image: ImageRgb,
    pub(super) noise: ReferenceNoise,
    pub(super) device: String,
    pub(super) cached: bool,
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
    if (image.width, image.height) != (r.width, r.height) {
        eprintln!(
            "warning: {} is {}x{}, not {}x{}; rendering the reference again",
            job.exr.display(),
            image.width,
            image.height,
            r.width,
            r.height
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
            nimbus_scene::parse_str(crate::DEFAULT_SCENE, Path::new("window.toml")).unwrap();
        scene.render.width = 3;
        scene.render.height = 2;
        scene.render.spp = spp;
        let plan = crate::plan::build(&scene, None).unwrap();
        ReferenceJob::new(scene, plan, scene_bytes, "window", dir)
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
