//! The Newton view of a stateful block (`element::implicit`, the implicit plastic check):
//! its law, Gauss-point geometry (B-bar as the stateful block has it) and its own converged and
//! trial stress and history.
use crate::element::implicit::{ImplicitBlock, TangentKind};
use crate::element::law::MaterialLaw;
use crate::element::{self, Shape};

/// The Newton view of a stateful block with law `L` (module docs).
pub struct LawImplicit<L: MaterialLaw, const N: usize> {
    law: L,
    ng: usize,
    /// `Bbar` of each point: strain `[exx, eyy, gxy]` per unit displacement of node `a`, dof `d`.
    b: Vec<[[[f64; 3]; 2]; N]>,
    /// `w det J t` of each point.
    w: Vec<f64>,
    u_c: Vec<[[f64; 2]; N]>,
    u_t: Vec<[[f64; 2]; N]>,
    s_c: Vec<[f64; 4]>,
    s_t: Vec<[f64; 4]>,
    h_c: Vec<f64>,
    h_t: Vec<f64>,
    kind: TangentKind,
}

impl<L: MaterialLaw, const N: usize> LawImplicit<L, N> {
    /// From the reference coordinates `x` of the elements, with B-bar or not, thickness `t`.
    pub fn new<S: Shape<N>>(law: L, x: &[[[f64; 2]; N]], bbar: bool, t: f64) -> Self {
        let ng = S::GAUSS.len();
        let bbar = bbar && ng > 1;
        let (mut b, mut w) = (Vec::with_capacity(x.len() * ng), Vec::with_capacity(x.len() * ng));
        for xe in x {
            let mut gs = Vec::with_capacity(ng);
            let (mut gb, mut area) = ([[0.0; 2]; N], 0.0);
            for &(xi, wk) in S::GAUSS {
                let (g, det) = element::gradients::<S, N>(xe, xi);
                area += wk * det;
                for a in 0..N {
                    gb[a][0] += wk * det * g[a][0];
                    gb[a][1] += wk * det * g[a][1];
                }
                gs.push(g);
                w.push(wk * det * t);
            }
            for v in gb.iter_mut() {
                v[0] /= area;
                v[1] /= area;
            }
            for g in gs {
                b.push(std::array::from_fn(|a| {
                    let (g0, g1) = (g[a][0], g[a][1]);
                    // `strain_bar` of stateful.rs: eps + (ev_bar - ev) / 2 [1, 1, 0].
                    let (c0, c1) = if bbar { (0.5 * (gb[a][0] - g0), 0.5 * (gb[a][1] - g1)) } else { (0.0, 0.0) };
                    [[g0 + c0, c0, g1], [c1, g1 + c1, g0]]
                }));
            }
        }
        let ne = x.len();
        let ns = law.n_state();
        let mut t4 = [[0.0; 4]; 4];
        let kind = if law.tangent(&[0.0; 4], [0.0; 4], &vec![0.0; ns], &mut t4) { TangentKind::Consistent } else { TangentKind::Elastic };
        LawImplicit {
            law,
            ng,
            b,
            w,
            u_c: vec![[[0.0; 2]; N]; ne],
            u_t: vec![[[0.0; 2]; N]; ne],
            s_c: vec![[0.0; 4]; ne * ng],
            s_t: vec![[0.0; 4]; ne * ng],
            h_c: vec![0.0; ne * ng * ns],
            h_t: vec![0.0; ne * ng * ns],
            kind,
        }
    }
}

impl<L: MaterialLaw, const N: usize> ImplicitBlock for LawImplicit<L, N> {
    fn evaluate(&mut self, conn_all: &[u32], u: &[[f64; 2]], f: &mut [[f64; 2]], k: &mut dyn FnMut(&[u32], &[f64])) {
        let (ng, ns) = (self.ng, self.law.n_state());
        let n2 = 2 * N;
        let mut ke = vec![0.0; n2 * n2];
        let dm = self.law.elastic();
        let del = [[dm.d11, dm.d12, 0.0, 0.0], [dm.d12, dm.d11, 0.0, 0.0], [0.0, 0.0, dm.d33, 0.0], [0.0; 4]];
        for i in 0..self.u_c.len() {
            let conn = &conn_all[i * N..(i + 1) * N];
            let ue: [[f64; 2]; N] = std::array::from_fn(|a| u[conn[a] as usize]);
            let du: [[f64; 2]; N] = std::array::from_fn(|a| [ue[a][0] - self.u_c[i][a][0], ue[a][1] - self.u_c[i][a][1]]);
            self.u_t[i] = ue;
            ke.fill(0.0);
            let mut fe = [[0.0; 2]; N];
            for q in 0..ng {
                let j = i * ng + q;
                let b = &self.b[j];
                let mut e = [0.0; 3];
                for a in 0..N {
                    for d in 0..2 {
                        for c in 0..3 {
                            e[c] += b[a][d][c] * du[a][d];
                        }
                    }
                }
                let de = [e[0], e[1], e[2], 0.0];
                let mut s = self.s_c[j];
                let (hc, ht) = (&self.h_c[j * ns..(j + 1) * ns], &mut self.h_t[j * ns..(j + 1) * ns]);
                ht.copy_from_slice(hc);
                let mut dt = [[0.0; 4]; 4];
                if self.kind != TangentKind::Consistent || !self.law.tangent(&s, de, hc, &mut dt) {
                    dt = del;
                }
                self.law.update(&mut s, de, ht);
                self.s_t[j] = s;
                let w = self.w[j];
                // f += B^T s w; K += B^T D B w.
                let mut db = [[[0.0; 3]; 2]; N]; // D B columns
                for a in 0..N {
                    for d in 0..2 {
                        fe[a][d] += w * (b[a][d][0] * s[0] + b[a][d][1] * s[1] + b[a][d][2] * s[2]);
                        for r in 0..3 {
                            db[a][d][r] = dt[r][0] * b[a][d][0] + dt[r][1] * b[a][d][1] + dt[r][2] * b[a][d][2];
                        }
                    }
                }
                for a in 0..N {
                    for d in 0..2 {
                        let row = (2 * a + d) * n2;
                        for c in 0..N {
                            for e2 in 0..2 {
                                ke[row + 2 * c + e2] += w * (b[a][d][0] * db[c][e2][0] + b[a][d][1] * db[c][e2][1] + b[a][d][2] * db[c][e2][2]);
                            }
                        }
                    }
                }
            }
            for a in 0..N {
                let c = conn[a] as usize;
                f[c][0] += fe[a][0];
                f[c][1] += fe[a][1];
            }
            k(conn, &ke);
        }
    }
    fn commit(&mut self) {
        self.u_c.copy_from_slice(&self.u_t);
        self.s_c.copy_from_slice(&self.s_t);
        self.h_c.copy_from_slice(&self.h_t);
    }
    fn tangent(&self) -> TangentKind {
        self.kind
    }
    fn symmetric(&self) -> bool {
        self.kind == TangentKind::Elastic || self.law.tangent_symmetric()
    }
    fn yielded(&self, out: &mut Vec<bool>) {
        let ns = self.law.n_state();
        out.extend((0..self.u_c.len()).map(|i| (0..self.ng).any(|q| ns > 0 && self.law.output(&self.h_c[(i * self.ng + q) * ns..(i * self.ng + q + 1) * ns]).1 != 0)));
    }
    fn stress(&self) -> &[[f64; 4]] {
        &self.s_c
    }
}
