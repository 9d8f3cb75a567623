//! The zero-free force pass (issue 24, session 11): a one-block model's element pass does not
//! zero the force array first; the pack holding each cluster's first contribution zeroes it
//! just before it adds (`Block::set_internal_forces_pool`, `element::block`'s `FirstWriters`).
//!
//! Reference: the additive pass of the same block into an array zeroed first, one thread (what
//! `Model::internal_forces` did before). Tolerance: none (bit equality, the sign of every zero
//! included). The array handed to the zero-free pass is filled with garbage first (NaN, -0.0,
//! large values), so a cluster it does not write, or writes without the right first writer,
//! shows.
use flem_core::element::model::Model;
use flem_core::element::Plane;
use flem_core::mesh::{CellKind, Rectangle, ValidationOptions};
use flem_core::scene::MaterialCfg;
use flem_core::solver::{NoOutput, Simulation};

use crate::common::{root, scene};

fn bits(v: &[[f64; 2]]) -> Vec<[u64; 2]> {
    v.iter().map(|x| [x[0].to_bits(), x[1].to_bits()]).collect()
}

/// Pseudo-random displacement fields of `n` clusters at reference positions `x`: random
/// everywhere; random on the right half and +0.0 / -0.0 on the left (so that many element
/// forces are signed zeros); -0.0 everywhere.
fn fields(x: &[[f64; 2]]) -> Vec<Vec<[f64; 2]>> {
    let mut k = 0u64;
    let mut rnd = move || {
        k += 1;
        flem_core::cracking::weibull::uniform(0x2545_F491_4F6C_DD1Du64, k) - 0.5
    };
    let random: Vec<[f64; 2]> = x.iter().map(|_| [1e-3 * rnd(), 1e-3 * rnd()]).collect();
    let half: Vec<[f64; 2]> =
        x.iter().zip(&random).enumerate().map(|(i, (p, u))| if p[0] < 0.5 * x.iter().map(|q| q[0]).fold(0.0, f64::max) { [if i % 2 == 0 { 0.0 } else { -0.0 }, -0.0] } else { *u }).collect();
    vec![random, half, vec![[-0.0; 2]; x.len()]]
}

/// Zeroes then adds with the block's additive pass on one thread (the reference).
fn zero_then_add(m: &Model, u: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let mut f = vec![[0.0; 2]; u.len()];
    m.blocks[0].add_internal_forces_pool(u, &mut f, None);
    f
}

/// Checks the model's passes (`internal_forces`, `update_internal_forces`) against
/// [`zero_then_add`] on 1 to 4 threads, from garbage-filled arrays; returns how many force
/// components are a signed zero whose sign a pass that stored the first contribution instead
/// of adding it onto +0.0 would get wrong (the fields must exercise them).
fn check_model(m: &mut Model, name: &str) -> usize {
    assert!(m.zero_free(), "{name}: a one-block elastic model takes the zero-free pass");
    let x = m.cluster_x0();
    let mut negative_zeros = 0;
    for (j, u) in fields(&x).iter().enumerate() {
        m.set_threads(1).unwrap();
        let want = bits(&zero_then_add(m, u));
        // A bare store gives what adding onto -0.0 gives (-0.0 + v == v, bit for bit).
        let mut bare = vec![[-0.0; 2]; u.len()];
        m.blocks[0].add_internal_forces_pool(u, &mut bare, None);
        negative_zeros += bits(&bare).iter().zip(&want).flat_map(|(a, b)| [(a[0], b[0]), (a[1], b[1])]).filter(|(a, b)| a != b).count();
        let mut f = vec![[f64::NAN; 2]; u.len()];
        assert!(m.blocks[0].set_internal_forces_pool(u, &mut f, None), "{name}: the block takes the zero-free pass");
        assert!(bits(&f) == want, "{name}, field {j}: the zero-free pass differs from zeroing then adding");
        for t in 1..=4 {
            m.set_threads(t).unwrap();
            for call in 0..2 {
                let garbage = [f64::NAN, -0.0, 1e300, -7.5][(call + t) % 4];
                let mut f = vec![[garbage, -garbage]; u.len()];
                m.internal_forces(u, &mut f);
                assert!(bits(&f) == want, "{name}, field {j}, {t} threads: internal_forces differs from zeroing then adding");
                let mut f = vec![[-garbage, garbage]; u.len()];
                m.update_internal_forces(u, &mut f);
                assert!(bits(&f) == want, "{name}, field {j}, {t} threads: update_internal_forces differs from zeroing then adding");
            }
        }
    }
    negative_zeros
}

/// Q4, T3 and QM6 rectangles of 12 800 to 25 600 elements (64 and more chunks in several
/// regions, so that two to four threads run the dataflow), plus a point of no element (a
/// cluster the pass must zero from its list).
#[test]
fn zero_free_pass_equals_zeroing_then_adding() {
    flem_plugins::link();
    let mut negative_zeros = 0;
    for (cell, kind) in [(CellKind::Q4, "q4"), (CellKind::T3, "t3"), (CellKind::Q4, "qm6")] {
        let mut mesh = Rectangle::new(2.0, 1.0, 160, 80, cell).build().unwrap();
        mesh.validate(ValidationOptions::Reorient).unwrap();
        mesh.points.push([3.0, 3.0]);
        let mat = MaterialCfg { element: Some(kind.into()), ..MaterialCfg::elastic(100.0, 0.3, 1.0) };
        let mut m = Model::new(mesh, &[mat], Plane::Strain, "<test>").unwrap();
        negative_zeros += check_model(&mut m, kind);
    }
    assert!(negative_zeros > 0, "the fields must give first contributions of -0.0 (where a bare store differs)");
}

/// A model of two blocks (two regions), a co-rotational one and a stateful one keep zeroing
/// then adding (no zero-free pass).
#[test]
fn zero_free_pass_only_for_one_stateless_block() {
    let base = "[mesh]\ntype = \"rectangle\"\nwidth = 2.0\nheight = 1.0\nnx = 8\nny = 4\n[[material]]\nyoung_modulus = 100.0\npoisson_ratio = 0.3\ndensity = 1.0\n[[stage]]\nmax_steps = 1\n";
    assert!(Simulation::new(scene(base)).unwrap().model.zero_free());
    for (what, text) in
        [("co-rotational", base.replace("density = 1.0\n", "density = 1.0\ncorotational = true\n")), ("stateful", base.replace("[[stage]]", "[solver]\nlarge_strain = true\n[[stage]]"))]
    {
        let sim = Simulation::new(scene(&text)).unwrap_or_else(|e| panic!("{what}: {e}"));
        assert!(!sim.model.zero_free(), "{what}: no zero-free pass");
    }
    let mut mesh = Rectangle::new(2.0, 1.0, 8, 4, CellKind::Q4).build().unwrap();
    mesh.validate(ValidationOptions::Reorient).unwrap();
    for (e, r) in mesh.cell_region.iter_mut().enumerate() {
        *r = if e % 2 == 0 { "a" } else { "b" }.into();
    }
    let m = Model::new(mesh, &[MaterialCfg::elastic(100.0, 0.3, 1.0)], Plane::Strain, "<test>").unwrap();
    assert_eq!(m.blocks.len(), 2);
    assert!(!m.zero_free(), "two blocks: no zero-free pass");
}

/// A scene that splits: the tension crack scene (configs/verification/tension_crack.toml)
/// refined to 48 x 96 Q4, loaded suddenly above sigma_t, failure checked every 10 steps (it
/// cracks: the first writers are refreshed after each split). After the run the zero-free pass
/// still equals zeroing then adding, on 1 to 4 threads, at the run's displacements and at the
/// test fields.
#[test]
fn zero_free_pass_equals_zeroing_then_adding_after_splits() {
    let base = std::fs::read_to_string(root().join("configs/verification/tension_crack.toml")).unwrap();
    let base = base.replace("nx = 4\nny = 8", "nx = 48\nny = 96").replace("[cracking]\n", "[cracking]\nat_equilibrium = false\n");
    let stages = base.find("[[stage]]").unwrap();
    let text = format!("{}[[stage]]\nname = \"sudden\"\nlevels = {{ pull = 1.2 }}\ndynamic = true\nmax_steps = 400\n", &base[..stages]);
    let mut sim = Simulation::new(scene(&text)).unwrap_or_else(|e| panic!("{e}"));
    let n0 = sim.model.topo.n_clusters();
    sim.run(&mut NoOutput).unwrap_or_else(|e| panic!("{e}"));
    assert!(sim.model.topo.n_clusters() > n0 + 10, "the scene must split for the test to cover the refresh");
    let u = sim.state.u.clone();
    for t in 1..=4 {
        sim.model.set_threads(t).unwrap();
        let mut f = vec![[f64::NAN; 2]; u.len()];
        sim.model.internal_forces(&u, &mut f);
        assert!(bits(&f) == bits(&zero_then_add(&sim.model, &u)), "{t} threads: forces after splits differ from zeroing then adding");
    }
    check_model(&mut sim.model, "tension crack after splits");
}
