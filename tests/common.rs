//! Helpers shared by the integration tests.
use std::path::{Path, PathBuf};

use flem_core::scene::Scene;
use flem_core::solver::Simulation;

pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A scene from TOML text (relative paths resolve against configs/).
pub fn scene(text: &str) -> Scene {
    flem_plugins::link();
    Scene::from_str(text, Path::new("<test scene>"), &root().join("configs")).unwrap_or_else(|e| panic!("{e}"))
}

pub fn sim(text: &str) -> Simulation {
    Simulation::new(scene(text)).unwrap_or_else(|e| panic!("{e}"))
}

/// Relative difference.
pub fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(f64::MIN_POSITIVE)
}
