//! 3D element kinds (issue 38; docs/3d.md, "Elements"): `t4` (the linear tetrahedron), `h8`
//! (the brick with incompatible modes, which does not lock in bending: ours as the hexahedra's
//! default, the paper having no 3D) and `h8_full` (the plain trilinear brick, 2 x 2 x 2 Gauss
//! points, the twin of `q4`: it locks in bending; kept for comparison). The math shared by
//! them (shape functions, `D`, `B`) is `flem_core::element::shape3`.
//!
//! There is no 3D block or registry yet (the 3D explicit kernel is a later step): the kinds are
//! an enumeration, [`Kind3`], and each file's free functions are what a kernel calls (the
//! allocation-free force routines `t4::forces` / `t4::internal_force`, `h8::forces` /
//! `h8::internal_force`). The 3D implicit solve (`check::solid3`) uses them through the
//! dispatch functions below.
mod block;
pub mod h8;
pub mod t4;

use flem_core::element::shape3::{corner_xi3, internal_force3, stiffness3, stress_at3, Dmat3, Hex8, Tet4};
use flem_core::mesh::CellKind3;

/// A 3D element kind, by its name in a scene (`[[material]] element = "..."`).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub enum Kind3 {
    /// `t4`: linear tetrahedron (constant strain).
    T4,
    /// `h8`: brick with 9 incompatible modes, Taylor-corrected (ours as the default brick).
    H8,
    /// `h8_full`: trilinear brick, full 2 x 2 x 2 integration (locks in bending).
    H8Full,
}

impl Kind3 {
    pub const ALL: [Kind3; 3] = [Kind3::T4, Kind3::H8, Kind3::H8Full];

    pub fn name(self) -> &'static str {
        match self {
            Kind3::T4 => "t4",
            Kind3::H8 => "h8",
            Kind3::H8Full => "h8_full",
        }
    }

    pub fn from_name(s: &str) -> Option<Kind3> {
        Kind3::ALL.into_iter().find(|k| k.name() == s)
    }

    /// The cell type the kind is made for.
    pub fn cell(self) -> CellKind3 {
        match self {
            Kind3::T4 => CellKind3::T4,
            Kind3::H8 | Kind3::H8Full => CellKind3::H8,
        }
    }

    /// The default kind of a cell type (`t4`, `h8`).
    pub fn default_for(cell: CellKind3) -> Kind3 {
        match cell {
            CellKind3::T4 => Kind3::T4,
            CellKind3::H8 => Kind3::H8,
        }
    }
}

fn t4x(x: &[[f64; 3]]) -> [[f64; 3]; 4] {
    std::array::from_fn(|a| x[a])
}

fn h8x(x: &[[f64; 3]]) -> [[f64; 3]; 8] {
    std::array::from_fn(|a| x[a])
}

/// Element stiffness of kind `kind` (row-major `3n x 3n` into `k`, `n` corners of `x`).
pub fn stiffness(kind: Kind3, x: &[[f64; 3]], d: &Dmat3, k: &mut [f64]) {
    match kind {
        Kind3::T4 => stiffness3::<Tet4, 4>(&t4x(x), d, k),
        Kind3::H8Full => stiffness3::<Hex8, 8>(&h8x(x), d, k),
        Kind3::H8 => {
            let (kk, _) = h8::matrices(&h8x(x), d);
            for i in 0..24 {
                k[i * 24..i * 24 + 24].copy_from_slice(&kk[i]);
            }
        }
    }
}

/// Internal corner forces of kind `kind` into `f` (`n` corners).
pub fn internal_force(kind: Kind3, x: &[[f64; 3]], u: &[[f64; 3]], d: &Dmat3, f: &mut [[f64; 3]]) {
    match kind {
        Kind3::T4 => f[..4].copy_from_slice(&t4::internal_force(&t4x(x), &t4x(u), d)),
        Kind3::H8Full => f[..8].copy_from_slice(&internal_force3::<Hex8, 8>(&h8x(x), &h8x(u), d)),
        Kind3::H8 => f[..8].copy_from_slice(&h8::internal_force(&h8x(x), &h8x(u), d)),
    }
}

/// The nodal stress of each corner (paper 2.1 read in 3D: a brick's stress at its corners
/// scaled by 0.9999, a tetrahedron's constant stress; `shape3::corner_xi3`) into `out`.
pub fn corner_stresses(kind: Kind3, x: &[[f64; 3]], u: &[[f64; 3]], d: &Dmat3, out: &mut [[f64; 6]]) {
    match kind {
        Kind3::T4 => out[..4].fill(t4::stress(&t4x(x), &t4x(u), d)),
        Kind3::H8Full => {
            let (x, u) = (h8x(x), h8x(u));
            for (a, o) in out[..8].iter_mut().enumerate() {
                *o = stress_at3::<Hex8, 8>(&x, &u, d, corner_xi3::<Hex8, 8>(a));
            }
        }
        Kind3::H8 => {
            let (x, u) = (h8x(x), h8x(u));
            let al = h8::alpha(&h8::geometry(&x), &u, d);
            for (a, o) in out[..8].iter_mut().enumerate() {
                *o = h8::stress_with(&x, &u, &al, d, corner_xi3::<Hex8, 8>(a));
            }
        }
    }
}

/// Stress at natural coordinate `xi` (with the enhanced field for `h8`).
pub fn stress_at(kind: Kind3, x: &[[f64; 3]], u: &[[f64; 3]], d: &Dmat3, xi: [f64; 3]) -> [f64; 6] {
    match kind {
        Kind3::T4 => t4::stress(&t4x(x), &t4x(u), d),
        Kind3::H8Full => stress_at3::<Hex8, 8>(&h8x(x), &h8x(u), d, xi),
        Kind3::H8 => h8::stress(&h8x(x), &h8x(u), d, xi),
    }
}
