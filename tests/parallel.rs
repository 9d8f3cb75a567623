//! The parallel step (issue 9): results are bit-identical whatever `solver.threads` is.
//!
//! Reference: the same scene run with one thread. Tolerance: none (bit equality of every
//! displacement and velocity, of the ledger, and of the split log). The meshes are large enough
//! that the element loop has many coloured chunks and the node update several node chunks, so
//! the threads really share the work; the cracking scene splits during the run, so the
//! schedule is also exercised after `remap`.
use flem_core::cracking::SplitEvent;
use flem_core::element::kernel::Dataflow;
use flem_core::mesh::topology::SplitRecord;
use flem_core::solver::{Observer, Simulation};

use crate::common::{root, scene};

#[derive(Default)]
struct Splits(Vec<(u64, u32, u32, Vec<u32>)>);
impl Observer for Splits {
    fn splits(&mut self, _s: &Simulation, _r: &SplitRecord, ev: &[SplitEvent]) -> flem_core::Result<()> {
        self.0.extend(ev.iter().map(|e| (e.step, e.point.0, e.new_cluster.0, e.edges.iter().map(|x| x.0).collect())));
        Ok(())
    }
}

fn bits(v: &[[f64; 2]]) -> Vec<[u64; 2]> {
    v.iter().map(|x| [x[0].to_bits(), x[1].to_bits()]).collect()
}

/// Runs `text` with `threads` and returns (u bits, v bits, ledger bits, split log, threads used).
fn run(text: &str, threads: usize) -> (Vec<[u64; 2]>, Vec<[u64; 2]>, [u64; 4], Vec<(u64, u32, u32, Vec<u32>)>, usize) {
    run_with(text, threads, Dataflow::Auto)
}

/// `run` with the force pass's dataflow set (`Model::set_dataflow`); checks that the blocks
/// still run it after the run's splits.
fn run_with(text: &str, threads: usize, d: Dataflow) -> (Vec<[u64; 2]>, Vec<[u64; 2]>, [u64; 4], Vec<(u64, u32, u32, Vec<u32>)>, usize) {
    let text = text.replacen("[solver]\n", &format!("[solver]\nthreads = {threads}\n"), 1);
    let mut sim = Simulation::new(scene(&text)).unwrap_or_else(|e| panic!("{e}"));
    sim.model.set_dataflow(d);
    let mut log = Splits::default();
    sim.run(&mut log).unwrap_or_else(|e| panic!("{e}"));
    if d == Dataflow::Local {
        assert!(sim.model.blocks.iter().all(|b| b.dataflow_local(sim.state.u.len()) == Some(true)), "the local dataflow is kept through the run");
    }
    let l = &sim.ledger;
    (bits(&sim.state.u), bits(&sim.state.v), [l.external_work.to_bits(), l.kinetic.to_bits(), l.strain.to_bits(), l.damping.to_bits()], log.0, sim.model.threads())
}

/// The tension crack scene (configs/verification/tension_crack.toml) refined to 48 x 96 Q4
/// (4608 elements, 4753 points: 64 element chunks in 4 regions, 2 node chunks) and loaded suddenly above
/// sigma_t for 600 steps, failure checked every 10 steps: it cracks (59 splits), and threads = 2 gives the same bits and the same splits.
#[test]
fn tension_crack_is_bit_identical_with_two_threads() {
    let base = std::fs::read_to_string(root().join("configs/verification/tension_crack.toml")).unwrap();
    let base = base.replace("nx = 4\nny = 8", "nx = 48\nny = 96").replace("[cracking]\n", "[cracking]\nat_equilibrium = false\n");
    let stages = base.find("[[stage]]").unwrap();
    let text = format!("{}[[stage]]\nname = \"sudden\"\nlevels = {{ pull = 1.2 }}\ndynamic = true\nmax_steps = 600\n", &base[..stages]);
    let one = run(&text, 1);
    assert!(!one.3.is_empty(), "the scene must crack for the test to cover splits");
    // Both dataflows (session 29; `Auto` runs the phases on a block this small).
    for d in [Dataflow::Phases, Dataflow::Local] {
        let two = run_with(&text, 2, d);
        assert_eq!((one.4, two.4), (1, 2));
        assert_eq!(one.3, two.3, "{d:?}: split log differs between 1 and 2 threads");
        assert!(one.0 == two.0, "{d:?}: displacements differ between 1 and 2 threads");
        assert!(one.1 == two.1, "{d:?}: velocities differ");
        assert_eq!(one.2, two.2, "{d:?}: ledger differs");
    }
}

/// A plain elastic scene (the default bar refined to 160 x 32 Q4, a `q4_closed` and a T3 version)
/// marched to equilibrium: the same bits with 1, 2 and 3 threads.
#[test]
fn elastic_scene_is_bit_identical_whatever_the_threads() {
    for (element, cell) in [("q4", "q4"), ("q4_closed", "q4"), ("t3", "t3")] {
        let text = format!(
            "[mesh]\ntype = \"rectangle\"\nwidth = 10.0\nheight = 1.0\nnx = 160\nny = 32\nelement = \"{cell}\"\n[[material]]\nyoung_modulus = 1000.0\npoisson_ratio = 0.25\ndensity = 1.0\nelement = \"{element}\"\n[solver]\ntolerance = 1e-4\n[[support]]\nnodes = \"left\"\nfix = \"x\"\n[[support]]\nnodes = \"bottom_left\"\nfix = \"xy\"\n[[load]]\nname = \"pull\"\ntype = \"traction\"\nedges = \"right\"\nvalue = [1.0, 0.0]\n[[stage]]\nlevels = {{ pull = 1.0 }}\nmax_steps = 3000\n"
        );
        let one = run(&text, 1);
        assert!(one.0.iter().any(|u| f64::from_bits(u[0]) > 0.0), "{element}: the bar must deform");
        for t in [2, 3] {
            let other = run(&text, t);
            assert_eq!(other.4, t);
            assert!(one.0 == other.0 && one.1 == other.1, "{element}: state differs between 1 and {t} threads");
            assert_eq!(one.2, other.2, "{element}: ledger differs between 1 and {t} threads");
        }
    }
}

/// The element pass alone (issue 24, session 10: the chunks run as regions, the lead chunks
/// first; session 29: or region by region, `Dataflow::Local`) on a 2 x 1 rectangle of 320 x 160 Q4 (51 200 elements: 100 chunks of 512 in 6
/// regions, whose trailing chunks wait for the next region's lead chunks) and its T3 version
/// (102 400 elements, 200 chunks in 12 regions), pseudo-random displacements, five calls each:
/// the forces are the same bits with 1, 2, 3 and 4 threads. Reference: one thread (bits).
#[test]
fn element_pass_over_many_regions_is_bit_identical_whatever_the_threads() {
    for element in ["q4", "t3"] {
        let text = format!("[mesh]\ntype = \"rectangle\"\nwidth = 2.0\nheight = 1.0\nnx = 320\nny = 160\nelement = \"{element}\"\n[[material]]\nyoung_modulus = 100.0\npoisson_ratio = 0.3\ndensity = 1.0\n[[stage]]\nmax_steps = 1\n");
        let mut sim = Simulation::new(scene(&text)).unwrap_or_else(|e| panic!("{e}"));
        let n = sim.state.u.len();
        let mut k = 0u64;
        let mut rnd = move || {
            k += 1;
            flem_core::cracking::weibull::uniform(0x9E37_79B9_7F4A_7C15u64, k) - 0.5
        };
        let us: Vec<Vec<[f64; 2]>> = (0..5).map(|_| (0..n).map(|_| [1e-3 * rnd(), 1e-3 * rnd()]).collect()).collect();
        let forces = |sim: &Simulation| {
            us.iter()
                .map(|u| {
                    let mut f = vec![[0.0; 2]; n];
                    sim.model.internal_forces(u, &mut f);
                    bits(&f)
                })
                .collect::<Vec<_>>()
        };
        sim.model.set_threads(1).unwrap();
        let one = forces(&sim);
        assert!(one[0].iter().any(|f| f64::from_bits(f[0]) != 0.0), "{element}: the forces must not vanish");
        for t in [2, 3, 4] {
            sim.model.set_threads(t).unwrap();
            assert_eq!(sim.model.threads(), t);
            // Both dataflows (session 29): the lead chunks first, or region by region.
            for d in [Dataflow::Auto, Dataflow::Phases, Dataflow::Local] {
                sim.model.set_dataflow(d);
                assert!(forces(&sim) == one, "{element}: forces differ between 1 and {t} threads ({d:?})");
            }
        }
    }
}

/// `solver.threads`: 0 means one per core; an absurd count is refused naming the key.
#[test]
fn threads_key_is_validated() {
    let text = "[mesh]\ntype = \"rectangle\"\nwidth = 1.0\nheight = 1.0\nnx = 2\nny = 2\n[[material]]\nyoung_modulus = 1.0\npoisson_ratio = 0.3\ndensity = 1.0\n[solver]\n[[stage]]\nmax_steps = 1\n";
    let (.., used) = run(text, 0);
    assert_eq!(used, std::thread::available_parallelism().map_or(1, |n| n.get()));
    flem_plugins::link();
    let err = flem_core::scene::Scene::from_str(&text.replace("[solver]\n", "[solver]\nthreads = 5000\n"), std::path::Path::new("t.toml"), &root().join("configs")).err().expect("refused");
    assert!(err.to_string().contains("solver.threads"), "{err}");
}
