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
//! The optimizer takes 0.1-0.7 s of CPU per module, so results are kept per process by
//! the input's 128-bit hash, up to [`CACHE_BYTES`]; a test binary or a study builds each
//! distinct pipeline's module once. `NIMBUS_STRIP_SHADERS=0` turns the step off (for
//! measuring it), `NIMBUS_PIPELINE_TIMES=1` prints what each pipeline's strip and build
//! took; a module the optimizer refuses is handed to the driver as it is, with
//! a warning on stderr.

use std::collections::HashMap;
use std::ffi::{c_char, c_int, CStr};
use std::hash::{Hash, Hasher};
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

/// Two independent 64-bit hashes of `words` (FNV-1a and SipHash with fixed keys).
fn key(words: &[u32]) -> (u64, u64) {
    let mut fnv: u64 = 0xcbf2_9ce4_8422_2325;
    for w in words {
        fnv ^= u64::from(*w);
        fnv = fnv.wrapping_mul(0x0000_0100_0000_01b3);
    }
    let mut sip = std::collections::hash_map::DefaultHasher::new();
    words.hash(&mut sip);
    (fnv, sip.finish())
}

/// `words` (a specialized module) stripped as the module docs say, from the process's
/// cache when the same module was stripped before; `name` (the pipeline's) goes into the
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
    let module = match strip_uncached(words) {
        Ok(stripped) => Arc::new(stripped),
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
