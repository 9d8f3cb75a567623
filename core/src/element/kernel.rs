//! Blocked internal-force kernels (issue 9) and their deterministic parallel schedule.
//!
//! **Layout.** A block's elements are grouped in packs of [`LANES`] consecutive elements. A pack
//! stores, per field, one array of `LANES` values (structure of arrays inside the pack), so the
//! force computation is one loop over the lanes that the compiler vectorises. Per element it
//! holds only what the geometry fixes:
//! - Q4: the Jacobian is linear in the natural coordinates, `dx/dxi = a + eta h`,
//!   `dx/deta = b + xi h` (with `a, b, h` the three corner combinations of x and y: 6 values),
//!   plus `1 / det J` at the 4 Gauss points: 10 f64 = 80 bytes.
//! - T3: the constant Jacobian (4 values) and `1 / det J`: 5 f64 = 40 bytes.
//!
//! With `adj J = det J * J^-1`, the force of a Gauss point is
//! `f_a = w t (adj J^T dN_a)^T sigma`, `sigma = D (adj J grad_xi u) / det J`,
//! which is exactly `element::internal_force` rearranged (equal to round-off, tested to
//! 1e-12 relative). The thickness and the Gauss weight are folded into the D matrix.
//!
//! **Schedule.** Packs are grouped in chunks of consecutive packs (the chunk size depends on
//! the block size only, never on the thread count). Chunks are coloured greedily so that two
//! chunks of one colour share no cluster. A step runs the colours in order; the chunks of one
//! colour may run on different threads because they write disjoint clusters, and inside a
//! chunk elements are scattered in their local order. Every cluster therefore receives its
//! contributions in the same order (colour, then element) whatever the number of threads: the
//! result is bit-identical to one thread. A split only re-points corners at new clusters whose
//! elements shared the parent cluster before, so the colouring stays valid after `remap`.
//!
//! **Threads, node update, measurement.** A step gathers `u` for a pack, computes its 8
//! elements as one vectorised loop and scatters. The chunks of one colour run on the rayon pool
//! of `solver.threads` (`Model::pool`; 0 = all cores, 1 = no pool). The node update
//! (`solver/mod.rs`) adds its ledger sums per fixed 4096-node chunk (`NODE_CHUNK`), so whole
//! runs, not only the forces, are bit-identical to one thread (tests/parallel.rs).
//! `element::internal_force` stays the reference. `flem bench step` (`tools/src/bench.rs`)
//! measures it all (JSON); figures of one session against Akantu are in `docs/perf/README.md`.
use crate::element::{Dmat, Shape, Q4, T3};

/// Elements per pack (the width of the vectorised loop: two AVX2 or one AVX-512 register).
pub const LANES: usize = 8;

/// The element-kind trait: everything the core needs of an element kind (docs/elements.md).
///
/// From [`Shape`]: nodes (`N`, the cell type `KIND`, whose edges are the fans' and the splits'),
/// shape functions and their natural corners (the nodal-stress rule, `element::corner_xi`), Gauss
/// points (lumped mass, nonlocal input). Here: the internal force in the blocked pack form
/// (`pack`, `forces`; the hot loop, monomorphised per block), and with defaults that are the plain
/// isoparametric element: the reference force, the element stiffness (implicit check, stable-step
/// bound) and the stress at a natural point. An element with internal (condensed) fields, such as
/// the incompatible-mode quadrilateral `qm6` (plugins/src/elements/qm6.rs), overrides the three
/// and keeps `RECOVERY_LEN` f64 per element for its stress recovery.
pub trait Blocked<const N: usize>: Shape<N> {
    /// Registered name (`[[material]] element = "..."`).
    const NAME: &'static str;
    /// Precomputed geometry of `LANES` elements.
    type Pack: Copy + Send + Sync + 'static;
    /// Bytes of kernel data per element.
    const BYTES_PER_ELEM: usize = std::mem::size_of::<Self::Pack>() / LANES;
    /// f64 per element that `stress` needs beyond the geometry (built once by `recovery`);
    /// 0 for an isoparametric element, whose stress comes from the shape gradients alone.
    const RECOVERY_LEN: usize = 0;
    /// Packs the data of up to `LANES` elements (missing lanes give zero force). `d` and `t`
    /// are the block's elasticity and thickness (an element may fold them into the pack).
    fn pack(x: &[[[f64; 2]; N]], d: &Dmat, t: f64) -> Self::Pack;
    /// The D matrix with thickness and Gauss weight folded in (passed back to `forces`).
    fn scaled_d(d: &Dmat, t: f64) -> [f64; 3];
    /// Forces of the pack's elements, `f[a][dim][lane]`, from gathered `u[a][dim][lane]`.
    fn forces(p: &Self::Pack, d: &[f64; 3], u: &[[[f64; LANES]; 2]; N], f: &mut [[[f64; LANES]; 2]; N]);
    /// Internal force of one element, the reference the blocked kernel is tested against.
    #[inline(always)]
    fn force_ref(x: &[[f64; 2]; N], u: &[[f64; 2]; N], d: &Dmat, t: f64) -> [[f64; 2]; N] {
        crate::element::internal_force::<Self, N>(x, u, d, t)
    }
    /// Element stiffness, row-major (2N)^2, dofs x0 y0 x1 y1 ... (the implicit check and the
    /// stable-step bound); equal to the Jacobian of `forces`.
    fn stiffness(x: &[[f64; 2]; N], d: &Dmat, t: f64, k: &mut [f64]) {
        crate::element::stiffness::<Self, N>(x, d, t, k)
    }
    /// Fills `out` (`RECOVERY_LEN` values) with the element's stress-recovery data.
    fn recovery(_x: &[[f64; 2]; N], _d: &Dmat, _t: f64, _out: &mut [f64]) {}
    /// Stress `[sxx, syy, sxy]` at natural coordinate `xi`; `rec` is the element's `recovery`.
    fn stress(x: &[[f64; 2]; N], u: &[[f64; 2]; N], d: &Dmat, xi: [f64; 2], _rec: &[f64]) -> [f64; 3] {
        crate::element::stress_at::<Self, N>(x, u, d, xi)
    }
}

#[derive(Copy, Clone, Debug)]
#[repr(C, align(64))]
pub struct Q4Pack {
    ax: [f64; LANES],
    bx: [f64; LANES],
    hx: [f64; LANES],
    ay: [f64; LANES],
    by: [f64; LANES],
    hy: [f64; LANES],
    inv: [[f64; LANES]; 4],
}

const G: f64 = 0.577_350_269_189_625_8;
/// Gauss points of Q4 in the order of `Q4::GAUSS`.
const Q4_GP: [[f64; 2]; 4] = [[-G, -G], [G, -G], [G, G], [-G, G]];

/// The three corner combinations of a bilinear field: `d/dxi = a + eta h`, `d/deta = b + xi h`.
#[inline(always)]
fn abh(v0: f64, v1: f64, v2: f64, v3: f64) -> (f64, f64, f64) {
    (0.25 * ((v1 - v0) + (v2 - v3)), 0.25 * ((v3 - v0) + (v2 - v1)), 0.25 * ((v0 - v1) + (v2 - v3)))
}

/// The integrand at one Gauss point: strain from the displacement derivatives along the
/// parent axes, stress, and the stress pulled back to the parent axes (unscaled by 1/det J,
/// which cancels against the Gauss weight's det J): `(P_x,s, P_x,e, P_y,s, P_y,e)`.
#[inline(always)]
fn parent_stress(j: [f64; 4], inv: f64, du: [f64; 4], d: &[f64; 3]) -> (f64, f64, f64, f64) {
    let [j11, j12, j21, j22] = j;
    let [uxs, uxe, uys, uye] = du;
    let [d11, d12, d33] = *d;
    let exx = inv * (j22 * uxs - j12 * uxe);
    let eyy = inv * (j11 * uye - j21 * uys);
    let gxy = inv * ((j22 * uys - j12 * uye) + (j11 * uxe - j21 * uxs));
    let (sxx, syy, sxy) = (d11 * exx + d12 * eyy, d12 * exx + d11 * eyy, d33 * gxy);
    (j22 * sxx - j21 * sxy, j11 * sxy - j12 * sxx, j22 * sxy - j21 * syy, j11 * syy - j12 * sxy)
}

impl Blocked<4> for Q4 {
    const NAME: &'static str = "q4";
    type Pack = Q4Pack;
    fn pack(x: &[[[f64; 2]; 4]], _d: &Dmat, _t: f64) -> Q4Pack {
        let z = [0.0; LANES];
        let mut p = Q4Pack { ax: z, bx: z, hx: z, ay: z, by: z, hy: z, inv: [z; 4] };
        for (l, e) in x.iter().enumerate().take(LANES) {
            let (ax, bx, hx) = abh(e[0][0], e[1][0], e[2][0], e[3][0]);
            let (ay, by, hy) = abh(e[0][1], e[1][1], e[2][1], e[3][1]);
            (p.ax[l], p.bx[l], p.hx[l], p.ay[l], p.by[l], p.hy[l]) = (ax, bx, hx, ay, by, hy);
            for (g, &[xi, eta]) in Q4_GP.iter().enumerate() {
                let (j11, j12, j21, j22) = (ax + eta * hx, ay + eta * hy, bx + xi * hx, by + xi * hy);
                p.inv[g][l] = 1.0 / (j11 * j22 - j12 * j21);
            }
        }
        p
    }
    fn scaled_d(d: &Dmat, t: f64) -> [f64; 3] {
        [d.d11 * t, d.d12 * t, d.d33 * t]
    }
    #[inline(always)]
    fn forces(p: &Q4Pack, d: &[f64; 3], u: &[[[f64; LANES]; 2]; 4], f: &mut [[[f64; LANES]; 2]; 4]) {
        for l in 0..LANES {
            let (aux, bux, hux) = abh(u[0][0][l], u[1][0][l], u[2][0][l], u[3][0][l]);
            let (auy, buy, huy) = abh(u[0][1][l], u[1][1][l], u[2][1][l], u[3][1][l]);
            let (ax, bx, hx, ay, by, hy) = (p.ax[l], p.bx[l], p.hx[l], p.ay[l], p.by[l], p.hy[l]);
            // Sums over Gauss points of P (S) and of P times the other coordinate (T).
            let (mut sxs, mut txs, mut sxe, mut txe) = (0.0, 0.0, 0.0, 0.0);
            let (mut sys, mut tys, mut sye, mut tye) = (0.0, 0.0, 0.0, 0.0);
            for (g, &[xi, eta]) in Q4_GP.iter().enumerate() {
                let (j11, j12, j21, j22) = (ax + eta * hx, ay + eta * hy, bx + xi * hx, by + xi * hy);
                let (uxs, uxe, uys, uye) = (aux + eta * hux, bux + xi * hux, auy + eta * huy, buy + xi * huy);
                let (pxs, pxe, pys, pye) = parent_stress([j11, j12, j21, j22], p.inv[g][l], [uxs, uxe, uys, uye], d);
                sxs += pxs;
                txs += eta * pxs;
                sxe += pxe;
                txe += xi * pxe;
                sys += pys;
                tys += eta * pys;
                sye += pye;
                tye += xi * pye;
            }
            // f_a = 1/4 [xi_a (S_s + eta_a T_s) + eta_a (S_e + xi_a T_e)], corners (-,-) (+,-) (+,+) (-,+).
            f[0][0][l] = 0.25 * (-(sxs - txs) - (sxe - txe));
            f[1][0][l] = 0.25 * ((sxs - txs) - (sxe + txe));
            f[2][0][l] = 0.25 * ((sxs + txs) + (sxe + txe));
            f[3][0][l] = 0.25 * (-(sxs + txs) + (sxe - txe));
            f[0][1][l] = 0.25 * (-(sys - tys) - (sye - tye));
            f[1][1][l] = 0.25 * ((sys - tys) - (sye + tye));
            f[2][1][l] = 0.25 * ((sys + tys) + (sye + tye));
            f[3][1][l] = 0.25 * (-(sys + tys) + (sye - tye));
        }
    }
}

#[derive(Copy, Clone, Debug)]
#[repr(C, align(64))]
pub struct T3Pack {
    j11: [f64; LANES],
    j12: [f64; LANES],
    j21: [f64; LANES],
    j22: [f64; LANES],
    inv: [f64; LANES],
}

impl Blocked<3> for T3 {
    const NAME: &'static str = "t3";
    type Pack = T3Pack;
    fn pack(x: &[[[f64; 2]; 3]], _d: &Dmat, _t: f64) -> T3Pack {
        let z = [0.0; LANES];
        let mut p = T3Pack { j11: z, j12: z, j21: z, j22: z, inv: z };
        for (l, e) in x.iter().enumerate().take(LANES) {
            let (j11, j12, j21, j22) = (e[1][0] - e[0][0], e[1][1] - e[0][1], e[2][0] - e[0][0], e[2][1] - e[0][1]);
            (p.j11[l], p.j12[l], p.j21[l], p.j22[l]) = (j11, j12, j21, j22);
            p.inv[l] = 1.0 / (j11 * j22 - j12 * j21);
        }
        p
    }
    fn scaled_d(d: &Dmat, t: f64) -> [f64; 3] {
        // One Gauss point of weight 1/2.
        [d.d11 * t * 0.5, d.d12 * t * 0.5, d.d33 * t * 0.5]
    }
    #[inline(always)]
    fn forces(p: &T3Pack, d: &[f64; 3], u: &[[[f64; LANES]; 2]; 3], f: &mut [[[f64; LANES]; 2]; 3]) {
        for l in 0..LANES {
            let (uxs, uxe) = (u[1][0][l] - u[0][0][l], u[2][0][l] - u[0][0][l]);
            let (uys, uye) = (u[1][1][l] - u[0][1][l], u[2][1][l] - u[0][1][l]);
            let (pxs, pxe, pys, pye) = parent_stress([p.j11[l], p.j12[l], p.j21[l], p.j22[l]], p.inv[l], [uxs, uxe, uys, uye], d);
            f[0][0][l] = -pxs - pxe;
            f[1][0][l] = pxs;
            f[2][0][l] = pxe;
            f[0][1][l] = -pys - pye;
            f[1][1][l] = pys;
            f[2][1][l] = pye;
        }
    }
}

/// Chunks of packs and their colours (see the module doc).
#[derive(Clone, Debug, Default)]
pub struct Schedule {
    /// Packs per chunk.
    pub chunk_packs: usize,
    /// Chunk indices of each colour, in increasing order; colours run in this order.
    pub colours: Vec<Vec<u32>>,
}

impl Schedule {
    /// Chunk size from the block size only: about 64 chunks per block, 4 to 64 packs each.
    pub fn chunk_packs_for(n_packs: usize) -> usize {
        (n_packs / 64).clamp(4, 64)
    }

    /// Greedy colouring of chunks by shared clusters (`conn` of every element, in local order).
    pub fn build<const N: usize>(conn: &[[u32; N]], n_clusters: usize) -> Schedule {
        let n_packs = conn.len().div_ceil(LANES);
        let chunk_packs = Self::chunk_packs_for(n_packs);
        let chunk_elems = chunk_packs * LANES;
        let n_chunks = conn.len().div_ceil(chunk_elems);
        // Chunks touching each cluster (CSR), then the colour of each chunk.
        let mut count = vec![0u32; n_clusters + 1];
        let mut last = vec![u32::MAX; n_clusters];
        for (k, ch) in conn.chunks(chunk_elems).enumerate() {
            for c in ch.iter().flatten() {
                let c = *c as usize;
                if last[c] != k as u32 {
                    last[c] = k as u32;
                    count[c + 1] += 1;
                }
            }
        }
        for i in 0..n_clusters {
            count[i + 1] += count[i];
        }
        let mut items = vec![0u32; count[n_clusters] as usize];
        let mut fill = count.clone();
        last.iter_mut().for_each(|x| *x = u32::MAX);
        for (k, ch) in conn.chunks(chunk_elems).enumerate() {
            for c in ch.iter().flatten() {
                let c = *c as usize;
                if last[c] != k as u32 {
                    last[c] = k as u32;
                    items[fill[c] as usize] = k as u32;
                    fill[c] += 1;
                }
            }
        }
        let mut colour = vec![u32::MAX; n_chunks];
        let mut used: Vec<bool> = Vec::new();
        for (k, ch) in conn.chunks(chunk_elems).enumerate() {
            used.iter_mut().for_each(|u| *u = false);
            for c in ch.iter().flatten() {
                let c = *c as usize;
                for &o in &items[count[c] as usize..count[c + 1] as usize] {
                    let oc = colour[o as usize];
                    if oc != u32::MAX {
                        if used.len() <= oc as usize {
                            used.resize(oc as usize + 1, false);
                        }
                        used[oc as usize] = true;
                    }
                }
            }
            let free = used.iter().position(|u| !u).unwrap_or(used.len());
            colour[k] = free as u32;
        }
        let n_colours = colour.iter().map(|&c| c as usize + 1).max().unwrap_or(0);
        let mut colours = vec![Vec::new(); n_colours];
        for (k, &c) in colour.iter().enumerate() {
            colours[c as usize].push(k as u32);
        }
        Schedule { chunk_packs, colours }
    }

    pub fn n_chunks(&self) -> usize {
        self.colours.iter().map(Vec::len).sum()
    }
}

/// A raw view of the force array shared by the chunks of one colour.
///
/// Safety argument (why not a safe split): the clusters written by one chunk are scattered over
/// the whole array, so no slice split separates them. The colouring guarantees that chunks
/// running at the same time (one colour) write disjoint clusters, so no two threads touch the
/// same element of the array; `f` outlives every use (the colour loop joins before returning).
#[derive(Copy, Clone)]
pub struct SharedForces {
    ptr: *mut [f64; 2],
    len: usize,
}
unsafe impl Send for SharedForces {}
unsafe impl Sync for SharedForces {}

impl SharedForces {
    pub fn new(f: &mut [[f64; 2]]) -> Self {
        SharedForces { ptr: f.as_mut_ptr(), len: f.len() }
    }
    /// `f[c] += v`.
    ///
    /// # Safety
    /// No other thread may access `f[c]` during the call (guaranteed by the colouring).
    #[inline(always)]
    pub unsafe fn add(&self, c: usize, v: [f64; 2]) {
        assert!(c < self.len);
        // SAFETY: in bounds (checked), exclusive by the caller's contract.
        let x = unsafe { &mut *self.ptr.add(c) };
        x[0] += v[0];
        x[1] += v[1];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::element::{Material, Plane};

    fn lcg(s: &mut u64) -> f64 {
        *s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (*s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    }

    /// The blocked kernels equal `element::internal_force` (the reference, one element at a
    /// time) to 1e-12 relative on distorted elements and random displacements, including
    /// partially filled packs.
    fn check<S: Blocked<N>, const N: usize>(base: [[f64; 2]; N]) {
        let mut s = 7u64;
        for plane in [Plane::Strain, Plane::Stress] {
            let mat = Material { young: 210e9, poisson: 0.3, density: 1.0, thickness: 0.7, plane };
            let d = mat.dmat();
            for n in [LANES, 3] {
                let xs: Vec<[[f64; 2]; N]> = (0..n).map(|_| std::array::from_fn(|a| [1e3 + base[a][0] + 0.2 * lcg(&mut s), -5.0 + base[a][1] + 0.2 * lcg(&mut s)])).collect();
                let us: Vec<[[f64; 2]; N]> = (0..n).map(|_| std::array::from_fn(|_| [1e-3 * lcg(&mut s), 1e-3 * lcg(&mut s)])).collect();
                let p = S::pack(&xs, &d, mat.thickness);
                let mut ug = [[[0.0; LANES]; 2]; N];
                for (l, ue) in us.iter().enumerate() {
                    for a in 0..N {
                        ug[a][0][l] = ue[a][0];
                        ug[a][1][l] = ue[a][1];
                    }
                }
                let mut fg = [[[f64::NAN; LANES]; 2]; N];
                S::forces(&p, &S::scaled_d(&d, mat.thickness), &ug, &mut fg);
                for l in 0..LANES {
                    if l >= n {
                        assert!((0..N).all(|a| fg[a][0][l] == 0.0 && fg[a][1][l] == 0.0), "empty lane gives zero force");
                        continue;
                    }
                    let r = S::force_ref(&xs[l], &us[l], &d, mat.thickness);
                    let scale = r.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
                    for a in 0..N {
                        for k in 0..2 {
                            assert!((fg[a][k][l] - r[a][k]).abs() <= 1e-12 * scale, "corner {a} dim {k}: {} vs {}", fg[a][k][l], r[a][k]);
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn blocked_q4_matches_reference() {
        check::<Q4, 4>([[0.0, 0.0], [1.0, 0.0], [1.2, 0.9], [-0.1, 1.1]]);
    }

    #[test]
    fn blocked_t3_matches_reference() {
        check::<T3, 3>([[0.0, 0.0], [1.0, 0.1], [0.2, 0.9]]);
    }

    /// Chunks of one colour share no cluster; every chunk has one colour.
    #[test]
    fn colouring_separates_chunks() {
        // A structured 100 x 60 grid of quads, row by row.
        let nx = 100;
        let conn: Vec<[u32; 4]> = (0..60)
            .flat_map(|j| {
                (0..nx).map(move |i| {
                    let id = |i: u32, j: u32| j * (nx + 1) + i;
                    [id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]
                })
            })
            .collect();
        let s = Schedule::build(&conn, 101 * 61);
        let ce = s.chunk_packs * LANES;
        assert_eq!(s.n_chunks(), conn.len().div_ceil(ce));
        for col in &s.colours {
            let mut owner = vec![u32::MAX; 101 * 61];
            for &k in col {
                for e in conn.chunks(ce).nth(k as usize).unwrap() {
                    for &c in e {
                        assert!(owner[c as usize] == u32::MAX || owner[c as usize] == k, "two chunks of one colour share cluster {c}");
                        owner[c as usize] = k;
                    }
                }
            }
        }
    }
}
