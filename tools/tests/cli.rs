//! The `flem` binary of this package answers (a test target of the package, so that `cargo test`
//! builds the binary that the integration tests in tests/ (package flem-tests) run). Reference:
//! the default scene is valid (`flem check` exits 0) and the binary names its version.
use std::process::Command;

#[test]
fn flem_checks_the_default_scene_and_names_its_version() {
    let exe = env!("CARGO_BIN_EXE_flem");
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = Command::new(exe).arg("check").arg(root.join("configs/default.toml")).output().unwrap();
    assert_eq!(out.status.code(), Some(0), "flem check configs/default.toml:\n{}", String::from_utf8_lossy(&out.stderr));
    let out = Command::new(exe).arg("--version").output().unwrap();
    assert!(out.status.success() && String::from_utf8_lossy(&out.stdout).contains(env!("CARGO_PKG_VERSION")), "flem --version: {}", String::from_utf8_lossy(&out.stdout));
}
