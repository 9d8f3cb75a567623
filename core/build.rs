//! Records the compiler version (`FLEM_RUSTC_VERSION`): the dynamic plugin loader shows the
//! host's and each plugin's (the SDK compiles this crate too, so a plugin carries its own).
fn main() {
    let rustc = std::env::var("RUSTC").unwrap_or_else(|_| "rustc".into());
    let v = std::process::Command::new(&rustc)
        .arg("--version")
        .output()
        .ok()
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "rustc (unknown version)".into());
    println!("cargo:rustc-env=FLEM_RUSTC_VERSION={v}");
    // Only the compiler decides the output. No `rerun-if-changed=build.rs`: a changed build
    // script is rebuilt and rerun anyway, and the path is relative to the package, so for
    // flem-core-unit (tests/unit/core, which compiles this file from core/) it named a file
    // that does not exist, which cargo takes as changed: the harness was recompiled by every
    // cargo command (20 s of a fresh clone's CI).
    println!("cargo:rerun-if-env-changed=RUSTC");
}
