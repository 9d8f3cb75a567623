//! Co-rotational element blocks: `[[material]] corotational = true`.
//!
//! What: every element's motion is split into a best-fit rigid rotation and a small local
//! deformation; the linear kernel acts on the local deformation and its forces are rotated
//! back. A rigidly rotated or translated element therefore carries no stress whatever the
//! angle (the linear kernel would see a 90-degree rotation as a strain of order 1), which is
//! what fragments that tumble after separation need.
//!
//! How (per element, reference corners `X`, current `x = X + u`, centroids removed):
//! `theta = atan2(sum X~ x x~, sum X~ . x~)` (the rotation minimising `sum |R X~ - x~|^2`,
//! exact for a rigid motion), `u_loc = R^T x~ - X~`, `f = R K u_loc` with the unchanged
//! linear kernel, stress `R sigma(u_loc) R^T`. The variation of `R` with `u` is neglected in
//! the force (the usual element-independent co-rotational simplification): forces sum to zero
//! exactly; moment balance holds to second order in the local strain.
//!
//! Why a separate block type: the linear `ElementBlock` pass stays as it is (the co-rotational
//! pass is its own function, `ElementBlock::corot_body`, calling the same element kernel); the
//! choice is made once per block when the model is built, never inside the element loop.
//! It is a separate `Block` impl wrapping `ElementBlock` (issue 4).
//!
//! How it runs (ours, session 21): pack by pack with the linear block's own blocked kernel
//! (`ElementBlock::corot_body`): the rotation and the local displacements of the pack's 8
//! elements as loops over the lanes (`frame`, the arithmetic of `local`, in a loop that vectorises), then
//! `Blocked::forces` on the local displacements, the forces rotated back and added in element
//! order, compiled for the widest vector unit of the CPU (the same bits from each). Before, each
//! element called the one-element reference `Blocked::force_ref` (shape gradients, Jacobian
//! and its inverse at every Gauss point, every step): `flem bench laws`, case `corotational`,
//! 176 ns per element-update against 47 ns after, the linear kernel 17-35 ns in the same runs
//! (Q4, 1e5 elements, one thread). The two agree to round-off, not bit for bit (the blocked
//! kernel folds D, the thickness and the Gauss weights into its packs): the co-rotational
//! scenes' trajectories differ by round-off that grows once pieces break loose (the paper's
//! direct shear scenes: the same splits at the
//! same steps in `direct_shear_stop`, `_steps` and `_fine`; in `direct_shear` one split of the
//! 2235 stage at another step, the stages' split counts unchanged; energy residuals 1.07e-3 ->
//! 1.06e-3, `_steps` 3.9e-6 -> 8.2e-6). `add_internal_forces_reference` keeps the old pass as
//! the tests' reference (`corotational_blocked_pass_matches_the_reference`: 1e-12).
//! `strain_energy` (the ledger) still evaluates `force_ref` on the local displacements: the
//! energy and the forces come from the two kernels, equal to round-off.
//! One thread: co-rotational blocks have no chunk schedule.
//!
//! Energy and stable step: `Model::strain_energy` uses each co-rotational element's local
//! energy; the stable-step power iteration probes with tiny displacements (the tangent).
use crate::element::block::{Block, ElementBlock, Simd};
use crate::element::kernel::Blocked;
use crate::element::{self, Material};
use crate::ids::ElemId;
use crate::mesh::CellKind;

/// The best-fit rotations `(cos, sin)` of `W` elements whose reference corners are `x0` and
/// current corners `x` (`[corner][dim][lane]`), and their local displacements `R^T x~ - X~`
/// (the module doc's formulas, centroids removed), written into `cs`, `sn`, `ul`. One function for `CorotBlock::local`
/// (`W = 1`) and for a pack of `ElementBlock::corot_body` (`W = LANES`), so the two passes see
/// the same local displacements bit for bit; a loop over the lanes without a branch (a
/// select) so that it vectorises.
#[inline(always)]
pub(crate) fn frame<const N: usize, const W: usize>(x0: &[[[f64; W]; 2]; N], x: &[[[f64; W]; 2]; N], cs: &mut [f64; W], sn: &mut [f64; W], ul: &mut [[[f64; W]; 2]; N]) {
    let inv = 1.0 / N as f64;
    for l in 0..W {
        let (mut c0, mut c1) = ([0.0; 2], [0.0; 2]);
        for a in 0..N {
            for d in 0..2 {
                c0[d] += inv * x0[a][d][l];
                c1[d] += inv * x[a][d][l];
            }
        }
        let (mut sx, mut dx) = (0.0, 0.0);
        for a in 0..N {
            let (p, q) = ([x0[a][0][l] - c0[0], x0[a][1][l] - c0[1]], [x[a][0][l] - c1[0], x[a][1][l] - c1[1]]);
            sx += p[0] * q[1] - p[1] * q[0];
            dx += p[0] * q[0] + p[1] * q[1];
        }
        let r = (sx * sx + dx * dx).sqrt();
        let pos = r > 0.0;
        let rd = if pos { r } else { 1.0 };
        let (c, s) = (if pos { dx / rd } else { 1.0 }, if pos { sx / rd } else { 0.0 });
        for a in 0..N {
            let q = [x[a][0][l] - c1[0], x[a][1][l] - c1[1]];
            // R^T q - X~
            ul[a][0][l] = c * q[0] + s * q[1] - (x0[a][0][l] - c0[0]);
            ul[a][1][l] = -s * q[0] + c * q[1] - (x0[a][1][l] - c0[1]);
        }
        cs[l] = c;
        sn[l] = s;
    }
}

/// An [`ElementBlock`] with co-rotational kinematics.
pub struct CorotBlock<S: Blocked<N>, const N: usize>(pub ElementBlock<S, N>);

impl<S: Blocked<N>, const N: usize> CorotBlock<S, N> {
    /// Rotation `(cos, sin)` and local displacements of local element `i`.
    #[inline(always)]
    fn local(&self, i: usize, u: &[[f64; 2]]) -> ([f64; 2], [[f64; 2]; N]) {
        let b = &self.0;
        let c = &b.conn[i];
        let x0 = &b.x[i];
        let x0l: [[[f64; 1]; 2]; N] = std::array::from_fn(|a| [[x0[a][0]], [x0[a][1]]]);
        let xl: [[[f64; 1]; 2]; N] = std::array::from_fn(|a| {
            let ua = u[c[a] as usize];
            [[x0[a][0] + ua[0]], [x0[a][1] + ua[1]]]
        });
        let (mut cs, mut sn, mut ul) = ([0.0; 1], [0.0; 1], [[[0.0; 1]; 2]; N]);
        frame(&x0l, &xl, &mut cs, &mut sn, &mut ul);
        ([cs[0], sn[0]], std::array::from_fn(|a| [ul[a][0][0], ul[a][1][0]]))
    }

    /// The co-rotational forces element by element with the one-element reference kernel
    /// (`Blocked::force_ref`), `f[c] +=`: the reference of the blocked pass
    /// (`Block::add_internal_forces_range`) in the tests, equal to it to round-off, not bit for
    /// bit (the blocked kernel folds D, the thickness and the Gauss weights into its packs).
    pub fn add_internal_forces_reference(&self, range: std::ops::Range<usize>, u: &[[f64; 2]], f: &mut [[f64; 2]]) {
        let b = &self.0;
        let t = b.mat.thickness;
        for i in range {
            let (r, ul) = self.local(i, u);
            let fl = S::force_ref(&b.x[i], &ul, &b.d, t);
            let c = &b.conn[i];
            for a in 0..N {
                let fa = &mut f[c[a] as usize];
                fa[0] += r[0] * fl[a][0] - r[1] * fl[a][1];
                fa[1] += r[1] * fl[a][0] + r[0] * fl[a][1];
            }
        }
    }

    fn rotate_stress(r: [f64; 2], s: [f64; 3]) -> [f64; 3] {
        let (c, n) = (r[0], r[1]);
        let (xx, yy, xy) = (s[0], s[1], s[2]);
        [c * c * xx - 2.0 * c * n * xy + n * n * yy, n * n * xx + 2.0 * c * n * xy + c * c * yy, c * n * (xx - yy) + (c * c - n * n) * xy]
    }
}

impl<S: Blocked<N>, const N: usize> Block for CorotBlock<S, N> {
    fn kind(&self) -> CellKind {
        self.0.kind()
    }
    fn nodes_per_elem(&self) -> usize {
        N
    }
    fn len(&self) -> usize {
        self.0.len()
    }
    fn material(&self) -> &Material {
        self.0.material()
    }
    fn region(&self) -> &str {
        self.0.region()
    }
    fn elems(&self) -> &[ElemId] {
        self.0.elems()
    }
    fn conn(&self, i: usize) -> &[u32] {
        self.0.conn(i)
    }
    fn remap(&mut self, i: usize, a: usize, cluster: u32) {
        self.0.remap(i, a, cluster)
    }
    fn add_internal_forces(&self, u: &[[f64; 2]], f: &mut [[f64; 2]]) {
        self.add_internal_forces_range(0..self.len(), u, f)
    }
    /// On the calling thread (co-rotational blocks have no chunk schedule): the same sums in
    /// the same order whatever the pool.
    fn add_internal_forces_pool(&self, u: &[[f64; 2]], f: &mut [[f64; 2]], _pool: Option<&rayon::ThreadPool>) {
        self.add_internal_forces_range(0..self.len(), u, f)
    }
    fn prepare(&mut self, _n_clusters: usize) {
        self.0.prepare_packs()
    }
    fn memory_bytes(&self) -> usize {
        self.0.memory_bytes()
    }
    /// The blocked kernel on each pack's local displacements (`ElementBlock::corot_body`), with
    /// the widest vector unit of this CPU (the same bits from each).
    fn add_internal_forces_range(&self, range: std::ops::Range<usize>, u: &[[f64; 2]], f: &mut [[f64; 2]]) {
        // `Simd::best` is one this CPU has, so the pass runs.
        let ran = self.0.corot_forces_simd(range, u, f, Simd::best());
        debug_assert!(ran, "Simd::best is detected");
    }
    fn add_mass(&self, m: &mut [f64]) {
        self.0.add_mass(m)
    }
    fn corner_stress(&self, u: &[[f64; 2]], first: &[u32], out: &mut [[f64; 3]]) {
        let b = &self.0;
        for i in 0..self.len() {
            let (r, ul) = self.local(i, u);
            let base = first[b.elems[i].idx()] as usize;
            for a in 0..N {
                out[base + a] = Self::rotate_stress(r, b.stress_local(i, &ul, element::corner_xi::<S, N>(a)));
            }
        }
    }
    fn gauss_stress(&self, u: &[[f64; 2]], first: &[u32], out: &mut [[f64; 3]]) {
        let b = &self.0;
        for i in 0..self.len() {
            let (r, ul) = self.local(i, u);
            let base = first[b.elems[i].idx()] as usize;
            for (g, &(xi, _)) in S::GAUSS.iter().enumerate() {
                out[base + g] = Self::rotate_stress(r, b.stress_local(i, &ul, xi));
            }
        }
    }
    fn stress_at(&self, i: usize, u: &[[f64; 2]], xi: [f64; 2]) -> [f64; 3] {
        let (r, ul) = self.local(i, u);
        Self::rotate_stress(r, self.0.stress_local(i, &ul, xi))
    }
    fn mean_stress(&self, i: usize, u: &[[f64; 2]]) -> [f64; 3] {
        let (r, ul) = self.local(i, u);
        let (mut wsum, mut acc) = (0.0, [0.0; 3]);
        for &(xi, w) in S::GAUSS {
            let si = self.0.stress_local(i, &ul, xi);
            for k in 0..3 {
                acc[k] += w * si[k];
            }
            wsum += w;
        }
        Self::rotate_stress(r, [acc[0] / wsum, acc[1] / wsum, acc[2] / wsum])
    }
    fn stiffness(&self, i: usize, k: &mut [f64]) {
        self.0.stiffness(i, k)
    }
    fn coords(&self, i: usize) -> &[[f64; 2]] {
        self.0.coords(i)
    }
    fn max_omega_bound(&self) -> f64 {
        self.0.max_omega_bound()
    }
    fn element(&self) -> &'static str {
        self.0.element()
    }
    fn isoparametric(&self) -> bool {
        self.0.isoparametric()
    }
    fn strain_energy(&self, u: &[[f64; 2]]) -> Option<f64> {
        let b = &self.0;
        let mut e = 0.0;
        for i in 0..self.len() {
            let (_, ul) = self.local(i, u);
            let fl = S::force_ref(&b.x[i], &ul, &b.d, b.mat.thickness);
            for a in 0..N {
                e += 0.5 * (ul[a][0] * fl[a][0] + ul[a][1] * fl[a][1]);
            }
        }
        Some(e)
    }
}
