//! The implicit plastic check (issue 37): Newton with the consistent tangents of the laws
//! (`flem-plugins/src/check/newton.rs`) on the verification scenes, beside FLEM and against
//! the closed forms. docs/materials.md, "Implicit plastic check".
use flem_core::ids::PointId;
use flem_core::plugin::check::{NewtonRow, PlasticCheck};
use flem_core::solver::{Observer, Simulation};
use flem_plugins::check::newton::NewtonCheck;

use crate::common::{rel, root, sim};

fn config(name: &str) -> String {
    std::fs::read_to_string(root().join("configs/verification").join(name)).unwrap()
}

/// FLEM's load-settlement curve: (settlement, |reaction_y| / b) at every history row.
struct Curve {
    pts: Vec<PointId>,
    rows: Vec<(f64, f64)>,
}
impl Observer for Curve {
    fn history(&mut self, s: &Simulation, _stage: usize) -> flem_core::Result<()> {
        let c = s.model.topo.point_clusters[self.pts[0].idx()][0].idx();
        self.rows.push((-s.state.u[c][1], s.reaction(&self.pts)[1].abs()));
        Ok(())
    }
}

/// Quadratic convergence of the table: in every increment, each iteration whose residual is
/// in (1e-9, 1e-2) is followed by one below `k r^2`, and increments take few iterations.
fn assert_quadratic(table: &[NewtonRow], k: f64) {
    for w in table.windows(2) {
        let (a, b) = (w[0], w[1]);
        if a.increment == b.increment && a.residual < 1e-2 && a.residual > 1e-9 {
            assert!(b.residual <= k * a.residual * a.residual, "increment {}: residual {:.3e} after {:.3e}: not quadratic", a.increment, b.residual, a.residual);
        }
    }
}

fn print_table(table: &[NewtonRow], every: usize) {
    for r in table.iter().filter(|r| r.increment % every == 0 || r.increment == 1) {
        eprintln!("  increment {:3} (level {:.4}) iteration {} residual {:.3e}", r.increment, r.level, r.iteration, r.residual);
    }
}

/// configs/verification/strip_footing.toml (Tresca, c = 1, smooth rigid footing, half-width
/// b = 1, 64 x 48 Q4 with B-bar): FLEM's load-settlement curve (the footing pushed at
/// constant velocity, local damping) and Newton's on the same mesh and law, the footing's
/// settlement prescribed at each of FLEM's history rows. References: Prandtl's limit pressure
/// (2 + pi) c = 5.1416 (Prandtl 1920) for both at the plateau (3 %), and Newton's static
/// equilibrium for FLEM's curve (1 % at the plateau, the last row). Newton converges
/// quadratically (the residual table; the consistent tangent of the Tresca return).
#[test]
fn footing_newton_beside_flem_and_prandtl() {
    let mut s = sim(&config("strip_footing.toml"));
    let pts = s.model.node_set("footing", "test", "test").unwrap();
    let mut curve = Curve { pts: pts.clone(), rows: Vec::new() };
    s.run(&mut curve).unwrap_or_else(|e| panic!("{e}"));
    let fix = s.state.fix.clone();
    let nc = s.model.topo.n_clusters();
    let foot: Vec<usize> = pts.iter().map(|p| s.model.topo.point_clusters[p.idx()][0].idx()).collect();
    let mut newton = NewtonCheck::new();
    let mut table = Vec::new();
    let zero = vec![[0.0; 2]; nc];
    let prandtl = 2.0 + std::f64::consts::PI;
    let mut last = (0.0, 0.0);
    for &(d, q_flem) in &curve.rows {
        let mut up = vec![[0.0; 2]; nc];
        for &c in &foot {
            up[c][1] = -d;
        }
        let st = newton.advance(&s.model, &fix, &zero, &up, 2).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(st.tangent, "consistent");
        let q = foot.iter().map(|&c| newton.internal_force()[c][1]).sum::<f64>().abs();
        eprintln!("settlement {d:.5}: FLEM {q_flem:.4}, Newton {q:.4} ({:+.2} %), {} increments, {} iterations, {}", 100.0 * (q_flem - q) / q, st.increments, st.iterations, st.factorisation);
        table.extend(st.table.iter().map(|r| NewtonRow { increment: table.len() + r.increment, ..*r }));
        last = (q_flem, q);
    }
    print_table(&table, 5);
    let (q_flem, q) = last;
    assert!(rel(q_flem, q) < 0.01, "plateau: FLEM {q_flem} vs Newton {q}");
    assert!(rel(q, prandtl) < 0.03 && rel(q_flem, prandtl) < 0.03, "plateau: FLEM {q_flem}, Newton {q} vs Prandtl {prandtl}");
    assert_quadratic(&table, 1e3);
}
