//! A specialized module cut down to the code its specialization constants can reach,
//! before the driver sees it.
//!
//! Nimbus compiles features in or out with specialization constants, so each pass's
//! module holds every feature any scene can ask for: ReSTIR's temporal pass is 1.9 MB of
//! SPIR-V, of which a given scene reaches a third or less. Drivers translate the whole
//! module before their dead-code passes drop the rest, and lavapipe (Mesa 22.3) spends
//! 1.5-4.6 s per ReSTIR pipeline on that even with its shader cache warm; the validation
//! layer walks the whole module at every pipeline creation too.
//!
//! [`strip`] runs SPIRV-Tools' optimizer (Debian's static libraries, through the C++
//! wrapper `spirv_strip.cpp`) with only the passes that freeze the specialization
//! constants (already written in as defaults by [`crate::spirv::specialize`]) and remove
//! what they make dead: spec-constant folding, dead-branch elimination, aggressive dead
//! code elimination, block merging, dead functions. None of them changes what the code
//! that runs computes, so the driver builds the same program from a module 1.5-3.5x
//! smaller. On lavapipe ReSTIR's and the baseline's images stay identical to the bit;
//! the box media's differ in 1-2 % of pixels by float rounding (at most 2e-7 relative),
//! as the driver's own optimizer orders some operations differently.
//!
//! The optimizer takes 0.1-0.7 s of CPU per module, so results are kept by the input's
//! 128-bit hash: per process, up to [`CACHE_BYTES`] (a test binary or a study strips each
//! distinct module once), and on disk for later processes, up to [`DISK_BYTES`] in
//! [`disk_dir`] (a CLI render or a farm task strips only what no earlier process did;
//! a file that does not read back whole is removed and stripped again).
//! `NIMBUS_STRIP_SHADERS=0` turns the step off (for measuring it),
//! `NIMBUS_PIPELINE_TIMES=1` prints what each pipeline's strip and build took; a module
//! the optimizer refuses is handed to the driver as it is, with a warning on stderr.

use std::collections::HashMap;
use std::ffi::{c_char, c_int, CStr};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, OnceLock, PoisonError};

/// Bytes of stripped modules kept per process (least recently used go first).
pub const CACHE_BYTES: usize = 64 << 20;

extern "C" {
    fn nimbus_spirv_strip(
        words: *const u32,
        count: usize,
        out: *mut *mut u32,
        out_count: *mut usize,
        message: *mut c_char,
        message_cap: usize,
    ) -> c_int;
    fn nimbus_spirv_free(words: *mut u32);
}

/// Whether [`strip`] runs (`NIMBUS_STRIP_SHADERS=0` turns it off), read once.
pub fn enabled() -> bool {
    static ENABLED: OnceLock<bool> = OnceLock::new();
    *ENABLED.get_or_init(|| std::env::var("NIMBUS_STRIP_SHADERS").map_or(true, |v| v.trim() != "0"))
}

/// Whether each pipeline built prints its module's size before and after the strip and
/// the seconds each step took (`NIMBUS_PIPELINE_TIMES=1`), read once.
pub fn log_times() -> bool {
    static LOG: OnceLock<bool> = OnceLock::new();
    *LOG.get_or_init(|| std::env::var("NIMBUS_PIPELINE_TIMES").is_ok_and(|v| v.trim() == "1"))
}

/// The optimizer run once, uncached: the stripped module, or the optimizer's messages.
pub fn strip_uncached(words: &[u32]) -> Result<Vec<u32>, String> {
    let mut out: *mut u32 = std::ptr::null_mut();
    let mut out_count = 0usize;
    let mut message = vec![0 as c_char; 1024];
    // SAFETY: `words` is a live slice of `words.len()` u32s; `out`, `out_count` and
    // `message` (with its capacity) are valid for writes for the call; the wrapper only
    // reads the input and writes these (spirv_strip.cpp), and catches every C++
    // exception before returning.
    let status = unsafe {
        nimbus_spirv_strip(
            words.as_ptr(),
            words.len(),
            &mut out,
            &mut out_count,
            message.as_mut_ptr(),
            message.len(),
        )
    };
    if status != 0 || out.is_null() {
        // SAFETY: the wrapper NUL-terminates `message` within its capacity (it was
        // zeroed, so it is terminated even if the wrapper wrote nothing).
        let text = unsafe { CStr::from_ptr(message.as_ptr()) };
        return Err(format!(
            "status {status}: {}",
            text.to_string_lossy().trim_end()
        ));
    }
    // SAFETY: on success the wrapper set `out` to a malloc'd array of `out_count` words
    // that nothing else refers to; it is copied, then freed once by the wrapper's own
    // `free`.
    let result = unsafe {
        let copy = std::slice::from_raw_parts(out, out_count).to_vec();
        nimbus_spirv_free(out);
        copy
    };
    Ok(result)
}

/// A stripped module and when it was last used (the cache's clock).
type Entry = (Arc<Vec<u32>>, u64);

/// Process-wide results, by the input's hash.
#[derive(Default)]
struct Cache {
    entries: HashMap<(u64, u64), Entry>,
    bytes: usize,
    clock: u64,
}

fn cache() -> &'static Mutex<Cache> {
    static CACHE: OnceLock<Mutex<Cache>> = OnceLock::new();
    CACHE.get_or_init(Mutex::default)
}

/// Two independent 64-bit hashes of `words` (FNV-1a, and a multiply-xorshift chain
/// seeded with the length), both fixed by this code so that they name files on disk
/// across builds.
fn key(words: &[u32]) -> (u64, u64) {
    let mut mix: u64 = 0x9e37_79b9_7f4a_7c15 ^ words.len() as u64;
    for w in words {
        mix = (mix ^ u64::from(*w)).wrapping_mul(0xff51_afd7_ed55_8ccd);
        mix ^= mix >> 32;
    }
    (fnv64(words), mix)
}

/// `words` (a specialized module) stripped as the module docs say, from the process's
/// cache or the disk's when the same module was stripped before; `name` (the pipeline's) goes into the
/// warning when the optimizer refuses it, and then `words` comes back unchanged.
pub fn strip(name: &str, words: &[u32]) -> Arc<Vec<u32>> {
    if !enabled() {
        return Arc::new(words.to_vec());
    }
    let key = key(words);

    {
        let mut cache = cache().lock().unwrap_or_else(PoisonError::into_inner);
        cache.clock += 1;
        let now = cache.clock;
        if let Some((module, used)) = cache.entries.get_mut(&key) {
            *used = now;
            return Arc::clone(module);
        }
    }
    let from_disk = disk_dir().and_then(|dir| read_disk(dir, key));
    let module = match from_disk.map_or_else(
        || strip_uncached(words).map(|m| (m, true)),
        |m| Ok((m, false)),
    ) {
        Ok((stripped, fresh)) => {
            if let (true, Some(dir)) = (fresh, disk_dir()) {
                write_disk(dir, key, &stripped);
            }
            Arc::new(stripped)
        }
        Err(why) => {
            eprintln!(
                "[nimbus-gpu] warning: pipeline '{name}': SPIRV-Tools could not strip the \
                 specialized shader ({why}); the driver gets the whole module"
            );
            return Arc::new(words.to_vec());
        }
    };
    let mut cache = cache().lock().unwrap_or_else(PoisonError::into_inner);
    cache.clock += 1;
    let now = cache.clock;
    let size = 4 * module.len();
    if size <= CACHE_BYTES {
        if let Some((old, _)) = cache.entries.insert(key, (Arc::clone(&module), now)) {
            cache.bytes -= 4 * old.len();
        }
        cache.bytes += size;
        while cache.bytes > CACHE_BYTES {
            let Some(oldest) = cache
                .entries
                .iter()
                .min_by_key(|(_, (_, used))| *used)
                .map(|(k, _)| *k)
            else {
                break;
            };
            if let Some((gone, _)) = cache.entries.remove(&oldest) {
                cache.bytes -= 4 * gone.len();
            }
        }
    }
    module
}

/// Format of a stripped module on disk: this magic, then the key (two u64), the word
/// count (u64), the words, and an FNV-1a hash of the words (u64), all little-endian.
const DISK_MAGIC: &[u8; 8] = b"NBSTRIP1";

/// Bytes of stripped modules kept on disk; past it, the least recently used files go.
pub const DISK_BYTES: u64 = 256 << 20;

extern "C" {
    fn spvSoftwareVersionString() -> *const c_char;
}

/// Where stripped modules are kept across processes: `NIMBUS_SHADER_CACHE_DIR`, else
/// `$XDG_CACHE_HOME/nimbus/shaders`, else `$HOME/.cache/nimbus/shaders`, in a folder
/// named for the SPIRV-Tools version and this format; `NIMBUS_SHADER_CACHE=0` (or no
/// folder that can be made) keeps them in memory only. Read once.
pub fn disk_dir() -> Option<&'static Path> {
    static DIR: OnceLock<Option<PathBuf>> = OnceLock::new();
    DIR.get_or_init(|| {
        if std::env::var("NIMBUS_SHADER_CACHE").is_ok_and(|v| v.trim() == "0") {
            return None;
        }
        let env_dir = |name: &str| {
            std::env::var_os(name)
                .filter(|v| !v.is_empty())
                .map(PathBuf::from)
        };
        let root = env_dir("NIMBUS_SHADER_CACHE_DIR")
            .or_else(|| env_dir("XDG_CACHE_HOME").map(|d| d.join("nimbus").join("shaders")))
            .or_else(|| env_dir("HOME").map(|d| d.join(".cache").join("nimbus").join("shaders")))?;
        // SAFETY: SPIRV-Tools returns a pointer to a static NUL-terminated string.
        let version = unsafe { CStr::from_ptr(spvSoftwareVersionString()) }.to_string_lossy();
        let tag: String = format!("{}-{version}", String::from_utf8_lossy(DISK_MAGIC))
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '.' {
                    c
                } else {
                    '-'
                }
            })
            .collect();
        let dir = root.join(tag);
        if let Err(e) = std::fs::create_dir_all(&dir) {
            // Only a folder the user named is worth a word; the default one missing (a
            // read-only home) just costs each process its strips.
            if env_dir("NIMBUS_SHADER_CACHE_DIR").is_some() {
                eprintln!(
                    "[nimbus-gpu] warning: NIMBUS_SHADER_CACHE_DIR: cannot make {}: {e}; \
                     stripped shaders are kept in memory only",
                    dir.display()
                );
            }
            return None;
        }
        Some(dir)
    })
    .as_deref()
}

fn disk_name(key: (u64, u64)) -> String {
    format!("{:016x}{:016x}.spv", key.0, key.1)
}

/// FNV-1a over the words (each taken whole).
fn fnv64(words: &[u32]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for w in words {
        h ^= u64::from(*w);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// The stripped module stored in `dir` under `key`, if its file is whole (magic, the key
/// inside, count and hash agree); a file that is not is removed.
fn read_disk(dir: &Path, key: (u64, u64)) -> Option<Vec<u32>> {
    let path = dir.join(disk_name(key));
    let bytes = std::fs::read(&path).ok()?;
    let parse = || -> Option<Vec<u32>> {
        let u64_at = |at: usize| -> Option<u64> {
            Some(u64::from_le_bytes(bytes.get(at..at + 8)?.try_into().ok()?))
        };
        if bytes.get(..8)? != DISK_MAGIC {
            return None;
        }
        if (u64_at(8)?, u64_at(16)?) != key {
            return None;
        }
        let count = usize::try_from(u64_at(24)?).ok()?;
        let end = 32usize.checked_add(count.checked_mul(4)?)?;
        if bytes.len() != end.checked_add(8)? {
            return None;
        }
        let words: Vec<u32> = bytes[32..end]
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        (u64_at(end)? == fnv64(&words) && words.first() == Some(&0x0723_0203)).then_some(words)
    };
    let words = parse();
    match &words {
        // Most recently used first when the folder is trimmed.
        Some(_) => {
            if let Ok(f) = std::fs::File::options().append(true).open(&path) {
                let _ = f.set_modified(std::time::SystemTime::now());
            }
        }
        None => {
            let _ = std::fs::remove_file(&path);
        }
    }
    words
}

/// Stores `words` in `dir` under `key` (written to a temporary file, then renamed, so that
/// a reader never sees half a file) and trims the folder to [`DISK_BYTES`]. Failures only
/// cost the next process a strip.
fn write_disk(dir: &Path, key: (u64, u64), words: &[u32]) {
    let name = disk_name(key);
    let path = dir.join(&name);
    let mut bytes = Vec::with_capacity(40 + 4 * words.len());
    bytes.extend_from_slice(DISK_MAGIC);
    bytes.extend_from_slice(&key.0.to_le_bytes());
    bytes.extend_from_slice(&key.1.to_le_bytes());
    bytes.extend_from_slice(&(words.len() as u64).to_le_bytes());
    for w in words {
        bytes.extend_from_slice(&w.to_le_bytes());
    }
    bytes.extend_from_slice(&fnv64(words).to_le_bytes());
    static SERIAL: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let serial = SERIAL.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let temporary = dir.join(format!(".{name}.{}.{serial}.tmp", std::process::id()));
    if std::fs::write(&temporary, &bytes).is_err() || std::fs::rename(&temporary, &path).is_err() {
        let _ = std::fs::remove_file(&temporary);
        return;
    }
    trim_disk(dir, DISK_BYTES);
}

/// Removes the least recently used modules until the folder holds at most `cap` bytes of
/// them.
fn trim_disk(dir: &Path, cap: u64) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let mut files: Vec<(std::time::SystemTime, u64, PathBuf)> = entries
        .filter_map(|e| {
            let e = e.ok()?;
            let meta = e.metadata().ok()?;
            let is_module = e.file_name().to_str()?.ends_with(".spv");
            if !(meta.is_file() && is_module) {
                return None;
            }
            Some((meta.modified().ok()?, meta.len(), e.path()))
        })
        .collect();
    let mut total: u64 = files.iter().map(|(_, len, _)| len).sum();
    if total <= cap {
        return;
    }
    files.sort();
    for (_, len, path) in files {
        if total <= cap {
            break;
        }
        if std::fs::remove_file(&path).is_ok() {
            total -= len;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("nimbus-strip-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn module(n: u32) -> Vec<u32> {
        let mut words = vec![0x0723_0203, 0x0001_0500, 0, 10, 0];
        words.extend((0..n).map(|i| i.wrapping_mul(2_654_435_761)));
        words
    }

    #[test]
    fn a_module_comes_back_from_disk_as_it_was_written() {
        let dir = scratch("roundtrip");
        let words = module(1000);
        write_disk(&dir, key(&words), &words);
        assert_eq!(read_disk(&dir, key(&words)), Some(words.clone()));
        // A second module under another key stays apart.
        let other = module(999);
        assert_ne!(key(&words), key(&other));
        write_disk(&dir, key(&other), &other);
        assert_eq!(read_disk(&dir, key(&other)), Some(other));
        assert_eq!(read_disk(&dir, key(&words)), Some(words));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_damaged_or_misnamed_file_is_refused_and_removed() {
        let dir = scratch("damaged");
        let words = module(100);
        let k = key(&words);
        let path = dir.join(disk_name(k));
        write_disk(&dir, k, &words);
        let mut bytes = std::fs::read(&path).unwrap();
        // One flipped bit in the words: the hash disagrees.
        bytes[40] ^= 1;
        std::fs::write(&path, &bytes).unwrap();
        assert_eq!(read_disk(&dir, k), None);
        assert!(!path.exists(), "the damaged file is removed");
        // Cut short.
        write_disk(&dir, k, &words);
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() - 3]).unwrap();
        assert_eq!(read_disk(&dir, k), None);
        // A whole file under another module's name.
        write_disk(&dir, k, &words);
        let other = key(&module(7));
        std::fs::copy(&path, dir.join(disk_name(other))).unwrap();
        assert_eq!(read_disk(&dir, other), None);
        assert!(
            !dir.join(disk_name(other)).exists(),
            "the misnamed file is removed"
        );
        assert_eq!(read_disk(&dir, k), Some(words));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn the_folder_is_trimmed_to_its_cap_oldest_first() {
        let dir = scratch("trim");
        let mut paths = Vec::new();
        for n in 0..6u32 {
            let words = module(250 + n);
            let path = dir.join(disk_name(key(&words)));
            write_disk(&dir, key(&words), &words);
            let age = std::time::SystemTime::now()
                - std::time::Duration::from_secs(600 - 60 * u64::from(n));
            std::fs::File::options()
                .append(true)
                .open(&path)
                .unwrap()
                .set_modified(age)
                .unwrap();
            paths.push(path);
        }
        let size = std::fs::metadata(&paths[5]).unwrap().len();
        trim_disk(&dir, 3 * size);
        let kept: Vec<bool> = paths.iter().map(|p| p.exists()).collect();
        assert_eq!(
            kept,
            [false, false, false, true, true, true],
            "the three oldest go"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
