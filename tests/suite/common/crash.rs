//! Which tests were on the device when the suite died of a signal.
//!
//! Twice the suite has died of a SIGSEGV in CI and in none of the local runs since (2026-11-28
//! with one context shared by the tests, 2026-12-03 with a context per test). cargo then
//! prints the signal and nothing else: not which test, not which thread. Every test that
//! takes a device ([`super::gpu::context`]) enters its thread's name (libtest names a test's
//! thread after the test) in a fixed table, cleared when the thread ends; a handler for
//! SIGSEGV, SIGBUS, SIGILL and SIGFPE writes the table, the faulting thread's name and its
//! backtrace to standard error with async-signal-safe calls only (atomic loads, `write`,
//! `pthread_getname_np` on the current thread, `backtrace_symbols_fd`; the unwinder is
//! loaded beforehand), then hands the signal to the handler that
//! was there before it (Rust's stack-overflow report), or to the default action (a core
//! dump where they are enabled).

use std::cell::RefCell;
use std::sync::atomic::{AtomicPtr, AtomicUsize, Ordering};
use std::sync::Once;

/// How many tests the table holds at once (libtest runs one per core by default).
const SLOTS: usize = 64;

/// The names of the tests holding a device: leaked NUL-terminated strings, null where free.
static RUNNING: [AtomicPtr<u8>; SLOTS] = [const { AtomicPtr::new(std::ptr::null_mut()) }; SLOTS];

/// The handlers that were installed before ours, by signal (index in [`SIGNALS`]).
static PREVIOUS: [AtomicUsize; 4] = [const { AtomicUsize::new(0) }; 4];
/// Their `sa_flags` (whether `PREVIOUS` holds an `sa_sigaction` or an `sa_handler`).
static PREVIOUS_FLAGS: [AtomicUsize; 4] = [const { AtomicUsize::new(0) }; 4];

const SIGNALS: [libc::c_int; 4] = [libc::SIGSEGV, libc::SIGBUS, libc::SIGILL, libc::SIGFPE];

/// Clears this thread's slot when the thread ends.
struct Entry(Option<usize>);

impl Drop for Entry {
    fn drop(&mut self) {
        if let Some(slot) = self.0.take() {
            let name = RUNNING[slot].swap(std::ptr::null_mut(), Ordering::AcqRel);
            if !name.is_null() {
                // SAFETY: `name` came from `CString::into_raw` in `enter` and was taken out
                // of the table above, so nothing else can free it; the handler may still be
                // reading it only if the process is already dying of a signal.
                drop(unsafe { std::ffi::CString::from_raw(name.cast()) });
            }
        }
    }
}

thread_local! {
    static ENTRY: RefCell<Entry> = const { RefCell::new(Entry(None)) };
}

/// Installs the handler (once per process) and enters the current thread's test in the table
/// (once per thread).
pub fn enter() {
    static INSTALL: Once = Once::new();
    INSTALL.call_once(install);
    ENTRY.with(|entry| {
        let mut entry = entry.borrow_mut();
        if entry.0.is_some() {
            return;
        }
        let name = std::thread::current()
            .name()
            .unwrap_or("(unnamed thread)")
            .replace('\0', " ");
        let raw = std::ffi::CString::new(name)
            .expect("NULs were replaced")
            .into_raw();
        for (slot, cell) in RUNNING.iter().enumerate() {
            if cell
                .compare_exchange(
                    std::ptr::null_mut(),
                    raw.cast(),
                    Ordering::AcqRel,
                    Ordering::Acquire,
                )
                .is_ok()
            {
                entry.0 = Some(slot);
                return;
            }
        }
        // A full table: this test goes unnamed in a crash report.
        // SAFETY: `raw` came from `into_raw` above and was not stored.
        drop(unsafe { std::ffi::CString::from_raw(raw) });
    });
}

fn install() {
    // backtrace(3) loads libgcc's unwinder on its first call, which is not
    // async-signal-safe: make that call here, so the handler's is not the first.
    let mut frames = [std::ptr::null_mut::<libc::c_void>(); 4];
    // SAFETY: `frames` has room for the 4 entries asked for.
    unsafe { libc::backtrace(frames.as_mut_ptr(), 4) };
    for (i, &signal) in SIGNALS.iter().enumerate() {
        // SAFETY: `action` is zeroed and then filled as sigaction(2) asks (a handler taking
        // siginfo, SA_SIGINFO | SA_ONSTACK, an emptied mask); `old` receives the previous
        // disposition. Called once, before the handler can run.
        unsafe {
            let mut action: libc::sigaction = std::mem::zeroed();
            action.sa_sigaction = handler as *const () as usize;
            action.sa_flags = libc::SA_SIGINFO | libc::SA_ONSTACK;
            libc::sigemptyset(&mut action.sa_mask);
            let mut old: libc::sigaction = std::mem::zeroed();
            if libc::sigaction(signal, &action, &mut old) == 0 {
                PREVIOUS[i].store(old.sa_sigaction, Ordering::Release);
                PREVIOUS_FLAGS[i].store(old.sa_flags as usize, Ordering::Release);
            }
        }
    }
}

/// Writes `bytes` to standard error, ignoring failures (async-signal-safe).
fn say(bytes: &[u8]) {
    // SAFETY: `bytes` is a valid slice; write(2) is async-signal-safe.
    unsafe {
        libc::write(2, bytes.as_ptr().cast(), bytes.len());
    }
}

/// The length of a NUL-terminated string, at most `limit` (async-signal-safe).
///
/// # Safety
/// `p` points at a NUL-terminated string or at least `limit` readable bytes.
unsafe fn c_len(p: *const u8, limit: usize) -> usize {
    let mut n = 0;
    // SAFETY: by the caller's contract every byte up to the NUL or `limit` is readable.
    while n < limit && unsafe { *p.add(n) } != 0 {
        n += 1;
    }
    n
}

extern "C" fn handler(signal: libc::c_int, info: *mut libc::siginfo_t, context: *mut libc::c_void) {
    let name: &[u8] = match signal {
        libc::SIGSEGV => b"SIGSEGV",
        libc::SIGBUS => b"SIGBUS",
        libc::SIGILL => b"SIGILL",
        _ => b"SIGFPE",
    };
    say(b"\n[nimbus tests] ");
    say(name);
    say(b" on thread '");
    let mut buf = [0u8; 64];
    // SAFETY: `buf` has room for the 16 bytes Linux allows a thread name, NUL included.
    if unsafe { libc::pthread_getname_np(libc::pthread_self(), buf.as_mut_ptr().cast(), 64) } == 0 {
        // SAFETY: pthread_getname_np wrote a NUL-terminated name into `buf`.
        let n = unsafe { c_len(buf.as_ptr(), buf.len()) };
        say(&buf[..n]);
    }
    say(b"' (a thread name is cut to 15 bytes; a driver's own threads have its names)\n");
    say(b"[nimbus tests] tests holding a device when it came:\n");
    for cell in &RUNNING {
        let p = cell.load(Ordering::Acquire);
        if !p.is_null() {
            say(b"[nimbus tests]   ");
            // SAFETY: a non-null slot holds a live NUL-terminated string (`enter`).
            let n = unsafe { c_len(p, 4096) };
            // SAFETY: `p` has `n` readable bytes (above).
            say(unsafe { std::slice::from_raw_parts(p, n) });
            say(b"\n");
        }
    }
    // The faulting thread's frames, after the table (a stack the fault left unreadable
    // may fault again here, which ends the process at once). backtrace_symbols_fd names
    // exported symbols only: the others print as `library(+offset)`, which addr2line
    // resolves against the same build of that library (its debug symbols package).
    say(b"[nimbus tests] backtrace of the faulting thread:\n");
    let mut frames = [std::ptr::null_mut::<libc::c_void>(); 64];
    // SAFETY: `frames` has room for 64 entries; backtrace_symbols_fd writes to fd 2
    // without allocating (glibc documents it for this use), and backtrace's unwinder
    // was loaded by `install`.
    unsafe {
        let n = libc::backtrace(frames.as_mut_ptr(), 64);
        libc::backtrace_symbols_fd(frames.as_ptr(), n, 2);
    }
    let i = SIGNALS.iter().position(|&s| s == signal).unwrap_or(0);
    let previous = PREVIOUS[i].load(Ordering::Acquire);
    let flags = PREVIOUS_FLAGS[i].load(Ordering::Acquire) as libc::c_int;
    if previous != libc::SIG_DFL && previous != libc::SIG_IGN && previous != 0 {
        if flags & libc::SA_SIGINFO != 0 {
            // SAFETY: with SA_SIGINFO the previous disposition is a three-argument handler,
            // called here with the arguments this one received.
            let f: extern "C" fn(libc::c_int, *mut libc::siginfo_t, *mut libc::c_void) =
                unsafe { std::mem::transmute(previous) };
            f(signal, info, context);
        } else {
            // SAFETY: without SA_SIGINFO it is a one-argument handler.
            let f: extern "C" fn(libc::c_int) = unsafe { std::mem::transmute(previous) };
            f(signal);
        }
    }
    // The default action (Rust's handler restores it too when the fault is not a stack
    // overflow): restore it and return, so the faulting instruction runs again and the
    // kernel ends the process with this signal (and a core where enabled).
    // A signal sent by a process (si_code <= 0) would not come again: raise it.
    // SAFETY: signal(2) with SIG_DFL and raise(3) are async-signal-safe; `info` is the
    // siginfo the kernel passed (SA_SIGINFO).
    unsafe {
        libc::signal(signal, libc::SIG_DFL);
        if !info.is_null() && (*info).si_code <= 0 {
            libc::raise(signal);
        }
    }
}

#[cfg(test)]
mod tests {
    use std::os::unix::process::ExitStatusExt;
    use std::process::Command;

    const ON_PURPOSE: &str = "NIMBUS_TEST_CRASH_ON_PURPOSE";

    /// A test that dies of a SIGSEGV on a device is named on standard error, with its
    /// thread, and the process still ends by that signal (the suite's own binary is run
    /// again on `crashes_on_purpose` alone).
    #[test]
    fn a_crash_names_the_tests_holding_a_device() {
        let exe = std::env::current_exe().expect("the test binary's path");
        let out = Command::new(exe)
            .args([
                "--exact",
                "common::crash::tests::crashes_on_purpose",
                "--ignored",
                "--nocapture",
                "--test-threads=1",
            ])
            .env(ON_PURPOSE, "1")
            .output()
            .expect("the test binary runs");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(
            out.status.signal(),
            Some(libc::SIGSEGV),
            "status {:?}, stderr:\n{stderr}",
            out.status
        );
        assert!(
            stderr.contains("[nimbus tests] SIGSEGV on thread '"),
            "no report:\n{stderr}"
        );
        assert!(
            stderr.contains("[nimbus tests]   common::crash::tests::crashes_on_purpose\n"),
            "the test is not named:\n{stderr}"
        );
        // Frames of the suite's own binary, as `path(+offset)[address]` or
        // `path(symbol+offset)[address]`.
        let exe_name = std::env::current_exe()
            .ok()
            .and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
            .expect("the test binary's name");
        let (_, trace) = stderr
            .split_once("[nimbus tests] backtrace of the faulting thread:\n")
            .unwrap_or_else(|| panic!("no backtrace:\n{stderr}"));
        assert!(
            trace
                .lines()
                .any(|l| l.contains(&exe_name) && l.contains("+0x") && l.ends_with(']')),
            "no frame of {exe_name} in the backtrace:\n{stderr}"
        );
    }

    /// Enters the table as a device-holding test does, then writes to an unmapped
    /// address; run only by `a_crash_names_the_tests_holding_a_device`.
    #[test]
    #[ignore = "dies of a SIGSEGV on purpose; a_crash_names_the_tests_holding_a_device runs it"]
    fn crashes_on_purpose() {
        if std::env::var_os(ON_PURPOSE).is_none() {
            return;
        }
        super::enter();
        let address = std::hint::black_box(16usize) as *mut u8;
        // SAFETY: not safe, on purpose: page 0 is never mapped on Linux, so this write
        // faults (the point of the test).
        unsafe { address.write_volatile(1) };
        unreachable!("the write above faults");
    }
}
