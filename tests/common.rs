//! Helpers shared by the integration tests.
use std::path::{Path, PathBuf};

use flem_core::scene::Scene;
use flem_core::solver::Simulation;

/// The repository's root (this package is tests/).
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("tests/ inside the repository").to_path_buf()
}

/// The `flem` binary of this checkout, built (or found up to date) by cargo with this test
/// binary's profile and target folder, once per test run (`dynplug::libs`): this package is not
/// the binary's, so cargo's `CARGO_BIN_EXE_flem` is not available here.
pub fn flem_exe() -> &'static Path {
    &crate::dynplug::libs().flem
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

/// One step's internal forces of a stateless model (`a`, the reference) and of a stateful one
/// (`b`) for the same pseudo-random displacement agree to `tol` relative to the largest force.
pub fn assert_same_forces(a: &Simulation, b: &mut Simulation, tol: f64) {
    let n = a.state.u.len();
    let u: Vec<[f64; 2]> = (0..n).map(|i| [1e-4 * ((i * 7919) % 13) as f64, -1e-4 * ((i * 104729) % 11) as f64]).collect();
    let (mut f1, mut f2) = (vec![[0.0; 2]; n], vec![[0.0; 2]; n]);
    a.model.internal_forces(&u, &mut f1);
    b.model.update_internal_forces(&u, &mut f2);
    let scale = f1.iter().map(|f| f[0].abs().max(f[1].abs())).fold(0.0, f64::max);
    assert!(scale > 0.0, "the reference force is zero");
    for c in 0..n {
        for d in 0..2 {
            assert!((f1[c][d] - f2[c][d]).abs() < tol * scale, "{c} {d}: {:?} {:?}", f1[c], f2[c]);
        }
    }
}

/// A deterministic field of `n` displacements in `[-amp / 2, amp / 2)`, without structure (a
/// sine hash of the index): every deformation mode of an element, hourglass modes included, is
/// in it.
pub fn scattered_field(n: usize, amp: f64) -> Vec<[f64; 2]> {
    let h = |x: f64| ((x.sin() * 43758.5453).rem_euclid(1.0) - 0.5) * amp;
    (0..n).map(|i| [h(12.9898 * i as f64 + 1.0), h(78.233 * i as f64 + 2.0)]).collect()
}

/// The area of a 2D mesh: the shoelace sum over every cell's corners (units of the mesh squared).
pub fn mesh_area(mesh: &flem_core::mesh::RawMesh) -> f64 {
    let pts = &mesh.points;
    let mut area = 0.0;
    for cell in &mesh.cells {
        let c = cell.corners();
        for k in 0..c.len() {
            let (a, b) = (pts[c[k] as usize], pts[c[(k + 1) % c.len()] as usize]);
            area += 0.5 * (a[0] * b[1] - b[0] * a[1]);
        }
    }
    area
}
