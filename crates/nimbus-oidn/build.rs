//! Finds the folder holding libOpenImageDenoise.so the same way the `oidn` crate does
//! (OIDN_DIR first, then pkg-config), so that this crate's tests and examples get an rpath to it
//! and dependents can read it as DEP_NIMBUS_OIDN_LIBDIR for their own binaries. The
//! `oidn` crate links the library but gives no rpath: without one, a binary would need
//! LD_LIBRARY_PATH, and the install deliberately leaves the system's loader paths alone.

use std::path::PathBuf;

fn main() {
    println!("cargo:rerun-if-env-changed=OIDN_DIR");
    println!("cargo:rerun-if-env-changed=PKG_CONFIG_PATH");
    let libdir = match std::env::var_os("OIDN_DIR").filter(|dir| !dir.is_empty()) {
        Some(dir) => PathBuf::from(dir).join("lib"),
        None => match pkg_config::Config::new()
            .cargo_metadata(false)
            .probe("OpenImageDenoise")
        {
            Ok(library) => match library.link_paths.first() {
                Some(dir) => dir.clone(),
                None => return,
            },
            // The `oidn` crate's own build script fails with the explanation; repeating
            // it here would only double the message.
            Err(_) => return,
        },
    };
    for kind in ["tests", "examples"] {
        println!(
            "cargo:rustc-link-arg-{kind}=-Wl,-rpath,{}",
            libdir.display()
        );
    }
    println!("cargo:libdir={}", libdir.display());
}
