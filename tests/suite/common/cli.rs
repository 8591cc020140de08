//! Running the real `nimbus` binary from tests.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Run `nimbus ARGS` with validation layers on (any validation error fails it).
pub fn nimbus(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .args(args)
        .env("NIMBUS_VALIDATION", "1")
        .output()
        .expect("run nimbus")
}

/// Lossy UTF-8 of a command's output.
pub fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// A fresh, empty directory `<target tmp>/<group>/<name>` for one test's files.
pub fn scratch(group: &str, name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(group)
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch dir");
    dir
}
