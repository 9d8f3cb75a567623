//! The implicit (Newton) view of an element block, for the implicit plastic check
//! (`flem-plugins/src/check/newton.rs`, docs/materials.md "Implicit plastic check").
//!
//! What: a copy of a block's elements and law with Gauss-point stress and history of its own
//! (from zero, never read from the explicit run), which, at trial displacements `u` of the
//! clusters, updates every point from its last *committed* state with the strain increment
//! `deps = Bbar (u_e - u_e,committed)` (the law's `update`, as the explicit step does), adds
//! the element forces `f_e = sum_gp Bbar^T sigma w det J t` and hands out the element tangent
//! `K_e = sum_gp Bbar^T D_alg Bbar w det J t` with `D_alg` the law's consistent tangent
//! (`MaterialLaw::tangent`; a law without one: the elastic moduli, [`TangentKind::Elastic`]).
//! `commit` makes the last trial the new start (an accepted load increment).
//!
//! The same kinematics as the stateful block (`stateful.rs`): small strain, plane strain
//! `dezz = 0`, B-bar (mean dilatation) for Q4 when the block uses it. A block with large
//! strain or incompatible modes is refused by name; a stateless (linear elastic) block is its
//! element stiffness ([`Linear`]). Outside the explicit step: nothing here runs in the hot loop.
//! The view of a block with a law: `element::implicit_law` (apart, so that `block` can name
//! the trait without the laws).

/// Which tangent a block hands out.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TangentKind {
    /// The consistent tangent of the law's update (quadratic convergence).
    Consistent,
    /// The elastic moduli: the law has no tangent (`MaterialLaw::tangent` answered false);
    /// Newton then converges linearly at best.
    Elastic,
}

/// A block as the Newton solver sees it.
pub trait ImplicitBlock: Send {
    /// Forces and tangents at cluster displacements `u` from the committed state: adds each
    /// element's force into `f` (by cluster) and calls `k(conn, ke)` with its `2N x 2N`
    /// row-major tangent (dofs x0 y0 x1 y1 ...). `conn` is the current connectivity of the
    /// model's block this one was made from, element after element (`N` clusters each).
    fn evaluate(&mut self, conn: &[u32], u: &[[f64; 2]], f: &mut [[f64; 2]], k: &mut dyn FnMut(&[u32], &[f64]));
    /// The last `evaluate` becomes the committed state.
    fn commit(&mut self);
    /// The tangent it hands out (the law's name goes with it in messages).
    fn tangent(&self) -> TangentKind;
    /// The tangent is symmetric (Cholesky applies).
    fn symmetric(&self) -> bool;
    /// Per element: a committed point has yielded so far (the law's plastic state is not 0).
    fn yielded(&self, out: &mut Vec<bool>);
    /// Committed stress `[sxx, syy, sxy, szz]` of every Gauss point (element-major); empty
    /// for a linear block.
    fn stress(&self) -> &[[f64; 4]];
}

/// A stateless (linear elastic) block: its element stiffnesses (`Block::stiffness`), `f = K u`.
pub struct Linear {
    n2: usize,
    k: Vec<f64>,
}

impl Linear {
    /// `k`: the `2N x 2N` row-major stiffness of each element, one after the other.
    pub fn new(nodes_per_elem: usize, k: Vec<f64>) -> Self {
        Linear { n2: 2 * nodes_per_elem, k }
    }
}

impl ImplicitBlock for Linear {
    fn evaluate(&mut self, conn_all: &[u32], u: &[[f64; 2]], f: &mut [[f64; 2]], k: &mut dyn FnMut(&[u32], &[f64])) {
        let n2 = self.n2;
        for i in 0..self.k.len() / (n2 * n2) {
            let conn = &conn_all[i * n2 / 2..(i + 1) * n2 / 2];
            let ke = &self.k[i * n2 * n2..(i + 1) * n2 * n2];
            for r in 0..n2 {
                let mut s = 0.0;
                for c in 0..n2 {
                    s += ke[r * n2 + c] * u[conn[c / 2] as usize][c % 2];
                }
                f[conn[r / 2] as usize][r % 2] += s;
            }
            k(conn, ke);
        }
    }
    fn commit(&mut self) {}
    fn tangent(&self) -> TangentKind {
        TangentKind::Consistent
    }
    fn symmetric(&self) -> bool {
        true
    }
    fn yielded(&self, out: &mut Vec<bool>) {
        out.extend(std::iter::repeat_n(false, self.k.len() / (self.n2 * self.n2)));
    }
    fn stress(&self) -> &[[f64; 4]] {
        &[]
    }
}
