//! 3D runs are the same bits whatever `solver.threads` is (issue 38, must-show 3: "split logs
//! identical for 1 and 2 threads"). The 3D element loop runs its chunks colour by colour on the
//! pool (plugins/src/elements3d/block.rs) and the node update per fixed chunk of nodes
//! (`march3`), so every cluster's sums are in one order fixed by the mesh. Reference: the run
//! on one thread; tolerance: none (bits). Each scene cracks during the run, so the threads also
//! see the blocks reconnected after splits.
use std::path::Path;

use flem_core::output::run3::run3_in_folder;
use flem_core::scene3::Scene3;

/// Runs `text` (its files relative to `base`) with `threads` in a fresh folder: splits3.csv,
/// the displacement bits, the ledger bits, the threads used, the colours of the blocks.
fn run(text: &str, base: &Path, threads: usize, tag: &str) -> (String, Vec<[u64; 3]>, [u64; 4], usize, Vec<usize>) {
    flem_plugins::link();
    let text = text.replacen("[solver]\n", &format!("[solver]\nthreads = {threads}\n"), 1);
    let mut sc = Scene3::from_str(&text, Path::new("tests/threads3.rs scene"), base).unwrap();
    let dir = std::env::temp_dir().join(format!("flem_threads3_{}_{tag}_{threads}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let (m, _) = run3_in_folder(&mut sc, &dir).unwrap();
    let splits = std::fs::read_to_string(dir.join("splits3.csv")).unwrap_or_default();
    let _ = std::fs::remove_dir_all(&dir);
    let u = m.state.u.iter().map(|u| u.map(f64::to_bits)).collect();
    let l = &m.ledger;
    let colours = m.blocks.iter().map(|b| b.colours()).collect();
    (splits, u, [l.external_work.to_bits(), l.kinetic.to_bits(), l.strain.to_bits(), l.damping.to_bits()], m.threads(), colours)
}

/// `min_splits`: rows of splits3.csv in stage `stage` (the crack's, not the pre-cut notch's).
fn same_with_two_threads(text: &str, base: &Path, tag: &str, stage: &str, min_splits: usize) {
    let one = run(text, base, 1, tag);
    let two = run(text, base, 2, tag);
    assert_eq!(two.3, 2, "{tag}: the second run has 2 threads");
    assert!(one.4.iter().any(|&c| c > 1), "{tag}: the element loop has several colours ({:?}), so chunks run side by side", one.4);
    let n = one.0.lines().skip(1).filter(|l| l.split(',').next() == Some(stage)).count();
    eprintln!("{tag}: {n} split rows in stage {stage}, {} clusters, colours {:?}", one.1.len(), one.4);
    assert!(n >= min_splits, "{tag}: the scene cracks ({n} split rows in stage {stage})");
    assert_eq!(one.0, two.0, "{tag}: splits3.csv differs between 1 and 2 threads");
    assert!(one.1 == two.1, "{tag}: final displacements differ between 1 and 2 threads");
    assert_eq!(one.2, two.2, "{tag}: the energy ledger differs between 1 and 2 threads");
}

/// configs/3d/notched_bar.toml (bricks, h8): the crack from the notch (splits in the loaded
/// stage), the same splits3.csv and displacement bits on 1 and 2 threads.
#[test]
fn notched_bar_cracks_the_same_on_one_and_two_threads() {
    // At most 12000 steps a stage (the scene's 20000 are for the whole crack; the test needs
    // splits, not the end of the crack).
    let text = std::fs::read_to_string(crate::common::root().join("configs/3d/notched_bar.toml")).unwrap().replace("max_steps = 20000", "max_steps = 12000");
    let base = &crate::common::root().join("configs/3d");
    assert!(text.contains("max_steps = 12000"));
    same_with_two_threads(&text, base, "notched_bar_h8", "1", 2);
}

/// A box of 16^3 x 6 tetrahedra (4913 points: more than one node chunk, so the node update
/// runs on both threads too) pulled suddenly by a traction of 1 on its free end, failure
/// checked every 10 steps during the march (strength 0.9, below the static stress): it
/// cracks; the same bits on 1 and 2 threads.
#[test]
fn pulled_tetrahedral_box_cracks_the_same_on_one_and_two_threads() {
    let text = r#"
[model]
dim = 3
[mesh]
type = "box"
size = [2.0, 1.0, 1.0]
nx = 16
ny = 16
nz = 16
element = "t4"
[[material]]
young_modulus = 100.0
poisson_ratio = 0.25
density = 1.0
[solver]
max_steps = 400
[[support]]
nodes = "xmin"
fix = "xyz"
[[load]]
name = "pull"
type = "pressure"
faces = "xmax"
value = -1.0
[cracking]
at_equilibrium = false
check_every = 10
max_splits_per_check = 20
[cracking.criterion]
type = "rankine"
tensile_strength = 0.9
[cracking.separation]
type = "sigma1_nearest"
[[stage]]
levels = { pull = 1.0 }
dynamic = true
max_steps = 400
"#;
    same_with_two_threads(text, &crate::common::root(), "box_t4", "0", 5);
}
