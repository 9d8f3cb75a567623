//! The 3D linear implicit solve (issue 38): the sparse stiffness of a [`RawMesh3`] of one
//! isotropic linear elastic material, assembled from the 3D element kinds
//! (`crate::elements3d`: `t4`, `h8`, `h8_full`), solved with the project's sparse Cholesky
//! (`factor.rs`: its symbolic analysis and supernodal numeric factorisation, the same code as
//! the 2D check), and the nodal stress at the paper's 0.9999 corners averaged over the cells of
//! each point.
//!
//! Each point has three dofs (x, y, z). With `K = sum_e K_e` and the dofs split into free (`f`)
//! and prescribed (`p`) ones,
//!
//! ```text
//!     K u = f   =>   K_ff u_f = f_f - K_fp u_p,   u_p given,
//! ```
//!
//! `K_ff` (lower triangle, compressed columns) is assembled on a pattern built from the point
//! graph of the cells, factorised, solved, and the residual checked (one step of iterative
//! refinement when it is above `REFINE_RESIDUAL` of the load, `mod.rs`'s `refined_solve_with`).
//! The fill-reducing ordering is faer's approximate minimum degree (`amd::order`): the 2D
//! check's geometric nested dissection (`factor::nested_dissection`) takes 2D coordinates, and
//! this first 3D solve leaves the 2D code as it is (a 3D dissection is a later step when 3D
//! meshes grow large).
//!
//! Loads: point forces `f_ext` per point, and face loads on boundary faces of cells
//! ([`FaceLoad`]): a pressure `p` (positive pushes into the body: traction `-p n`, `n` the
//! outward unit normal) or a traction vector, turned into consistent corner forces
//! `f_a = integral_face N_a t dA` (a triangle: `t A / 3` per corner; a quadrilateral: bilinear
//! `N_a` and the area vector `dx/ds x dx/dt` at 2 x 2 Gauss points, exact for a flat or warped
//! bilinear face). Units: the scene's (consistent: modulus and pressure in force / length^2,
//! forces in force units, displacements in length).
//!
//! Errors name the mesh (`RawMesh3::source`) and the cell or points: a cell whose Jacobian is
//! not positive at a Gauss point or a 0.9999 corner (tangled, or corners not in VTK order), a
//! face load on a face that is no cell's face, a kind that does not fit a cell type, arrays of
//! the wrong length, non-finite input, and a body that is not supported against rigid motion
//! (a non-positive pivot or a refinement that does not converge).
use std::collections::BTreeMap;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::{SparseColMat, SymbolicSparseColMat};
use flem_core::element::shape3::{min_det3, Dmat3, Hex8, Tet4};
use flem_core::mesh::{face_integration, CellKind3, RawFace, RawMesh3, NO_CORNER};
use flem_core::FlemError;

use super::{factor, refined_solve_with};
use crate::elements3d::{self, Kind3};

const PREFIX: &str = "3D implicit solve";

/// How a face set is loaded.
#[derive(Copy, Clone, Debug, PartialEq)]
pub enum FaceLoadKind {
    /// Normal pressure (positive: into the body), force / length^2.
    Pressure(f64),
    /// Traction vector, force / length^2.
    Traction([f64; 3]),
}

/// A load on boundary faces (each must be a face of a cell; given by its corner points in any
/// order).
#[derive(Clone, Debug, PartialEq)]
pub struct FaceLoad {
    pub faces: Vec<RawFace>,
    pub load: FaceLoadKind,
}

/// A linear static 3D problem on a mesh.
#[derive(Clone, Debug)]
pub struct Problem3<'a> {
    pub mesh: &'a RawMesh3,
    pub young: f64,
    pub poisson: f64,
    /// The element kind of the hexahedra (`h8` or `h8_full`); tetrahedra are `t4`.
    pub hex: Kind3,
    /// Prescribed dofs per point: bit 1 = x, 2 = y, 4 = z.
    pub fix: Vec<u8>,
    /// Value of the prescribed dofs (others ignored).
    pub u_prescribed: Vec<[f64; 3]>,
    /// Point forces.
    pub f_ext: Vec<[f64; 3]>,
    pub face_loads: Vec<FaceLoad>,
    /// Per cell: its own Young's modulus, Poisson's ratio and kind (a scene of several regions,
    /// the 3D check of a scene); empty: `young`, `poisson` and `hex` for every cell.
    pub cells: Vec<(f64, f64, Kind3)>,
}

impl<'a> Problem3<'a> {
    /// A problem with no support and no load, `h8` for hexahedra.
    pub fn new(mesh: &'a RawMesh3, young: f64, poisson: f64) -> Self {
        let n = mesh.points.len();
        Problem3 { mesh, young, poisson, hex: Kind3::H8, fix: vec![0; n], u_prescribed: vec![[0.0; 3]; n], f_ext: vec![[0.0; 3]; n], face_loads: Vec::new(), cells: Vec::new() }
    }

    /// The kind of cell `e`.
    pub fn kind_of(&self, e: usize) -> Kind3 {
        if let Some(c) = self.cells.get(e) {
            return c.2;
        }
        match self.mesh.cells[e].kind {
            CellKind3::T4 => Kind3::T4,
            CellKind3::H8 => self.hex,
        }
    }

    /// The elasticity matrix of cell `e`.
    pub fn dmat_of(&self, e: usize) -> Dmat3 {
        match self.cells.get(e) {
            Some(c) => Dmat3::new(c.0, c.1),
            None => Dmat3::new(self.young, self.poisson),
        }
    }
}

/// The solution: displacement and nodal stress (Voigt `xx, yy, zz, xy, yz, zx`, tension
/// positive: the corner stresses at 0.9999 averaged over the cells of the point) of every
/// point, and the size of the system.
#[derive(Clone, Debug)]
pub struct Solution3 {
    pub u: Vec<[f64; 3]>,
    pub nodal_stress: Vec<[f64; 6]>,
    /// Free dofs.
    pub n_dofs: usize,
    /// Stored entries of the Cholesky factor `L`.
    pub factor_nnz: usize,
}

fn err(mesh: &RawMesh3, msg: String) -> FlemError {
    FlemError::Solve(format!("{PREFIX} of {}: {msg}", mesh.source))
}

/// The corners of cell `e` and their coordinates.
fn cell_x(mesh: &RawMesh3, e: usize) -> (&[u32], [[f64; 3]; 8]) {
    let c = mesh.cells[e].corners();
    let mut x = [[0.0; 3]; 8];
    for (a, &p) in c.iter().enumerate() {
        x[a] = mesh.points[p as usize];
    }
    (c, x)
}

/// Checks the input (module doc, "Errors").
fn validate(p: &Problem3) -> Result<(), FlemError> {
    let m = p.mesh;
    let np = m.points.len();
    if p.fix.len() != np || p.u_prescribed.len() != np || p.f_ext.len() != np {
        return Err(err(m, format!("the mesh has {np} points but fix, u_prescribed and f_ext have {}, {} and {} entries", p.fix.len(), p.u_prescribed.len(), p.f_ext.len())));
    }
    if !(p.young.is_finite() && p.young > 0.0) || !(p.poisson > -1.0 && p.poisson < 0.5) {
        return Err(err(m, format!("the material needs young_modulus > 0 and -1 < poisson_ratio < 0.5 (got {} and {})", p.young, p.poisson)));
    }
    if p.hex.cell() != CellKind3::H8 {
        return Err(err(m, format!("element \"{}\" is not a hexahedron kind (h8, h8_full)", p.hex.name())));
    }
    if !p.cells.is_empty() {
        if p.cells.len() != m.cells.len() {
            return Err(err(m, format!("the mesh has {} cells but {} per-cell materials are given", m.cells.len(), p.cells.len())));
        }
        for (e, &(young, poisson, kind)) in p.cells.iter().enumerate() {
            if !(young.is_finite() && young > 0.0) || !(poisson > -1.0 && poisson < 0.5) {
                return Err(err(m, format!("{}: the material needs young_modulus > 0 and -1 < poisson_ratio < 0.5 (got {young} and {poisson})", m.cell_name(e))));
            }
            if kind.cell() != m.cells[e].kind {
                return Err(err(m, format!("{}: element \"{}\" does not fit a {:?} cell", m.cell_name(e), kind.name(), m.cells[e].kind)));
            }
        }
    }
    if let Some(i) = (0..np).find(|&i| !m.points[i].iter().chain(&p.u_prescribed[i]).chain(&p.f_ext[i]).all(|v| v.is_finite())) {
        return Err(err(m, format!("point {} has a non-finite coordinate, prescribed displacement or force", m.point_name(i))));
    }
    for e in 0..m.cells.len() {
        let (c, x) = cell_x(m, e);
        if let Some(&q) = c.iter().find(|&&q| q as usize >= np) {
            return Err(err(m, format!("{} names point index {q}, but the mesh has {np} points", m.cell_name(e))));
        }
        let det = match m.cells[e].kind {
            CellKind3::T4 => min_det3::<Tet4, 4>(&std::array::from_fn(|a| x[a])),
            CellKind3::H8 => min_det3::<Hex8, 8>(&x),
        };
        if !(det > 0.0) {
            return Err(err(m, format!("{} ({}) is inverted or tangled (det J = {det:.3e} at a Gauss point or a 0.9999 corner): corners must follow VTK's order", m.cell_name(e), m.points_name(c))));
        }
    }
    Ok(())
}

/// Boundary faces of the cells by their sorted corners: (cell, local face) in the cell's
/// outward (anticlockwise from outside) order.
fn face_index(mesh: &RawMesh3) -> BTreeMap<[u32; 4], [u32; 4]> {
    let mut map = BTreeMap::new();
    for cell in &mesh.cells {
        for lf in cell.kind.faces() {
            let f: [u32; 4] = std::array::from_fn(|i| if lf[i] == NO_CORNER { NO_CORNER } else { cell.nodes[lf[i] as usize] });
            map.insert(RawFace(f).key(), f);
        }
    }
    map
}

/// Consistent corner forces of the face loads (module doc), added to `f`.
pub fn face_forces(mesh: &RawMesh3, loads: &[FaceLoad], f: &mut [[f64; 3]]) -> Result<(), FlemError> {
    if loads.is_empty() {
        return Ok(());
    }
    let index = face_index(mesh);
    for (li, l) in loads.iter().enumerate() {
        let finite = match l.load {
            FaceLoadKind::Pressure(p) => p.is_finite(),
            FaceLoadKind::Traction(t) => t.iter().all(|v| v.is_finite()),
        };
        if !finite {
            return Err(err(mesh, format!("face load {li} is not finite")));
        }
        for face in &l.faces {
            let Some(&oriented) = index.get(&face.key()) else {
                return Err(err(mesh, format!("face load {li}: the face of points {} is no face of a cell", mesh.points_name(face.corners()))));
            };
            let of = RawFace(oriented);
            let c = of.corners();
            let x: Vec<[f64; 3]> = c.iter().map(|&p| mesh.points[p as usize]).collect();
            // (weight per corner, area vector) at the face's integration points.
            let add = |nw: &[f64], area: [f64; 3]| {
                let t = match l.load {
                    FaceLoadKind::Pressure(p) => area.map(|a| -p * a),
                    FaceLoadKind::Traction(t) => {
                        let a = (area[0] * area[0] + area[1] * area[1] + area[2] * area[2]).sqrt();
                        t.map(|v| v * a)
                    }
                };
                for (k, &p) in c.iter().enumerate() {
                    for d in 0..3 {
                        f[p as usize][d] += nw[k] * t[d];
                    }
                }
            };
            face_integration(&x, add);
        }
    }
    Ok(())
}

/// Equation numbers: `eq[3 p + d]` the free dof's index or `usize::MAX`; and their count.
fn number_dofs(fix: &[u8]) -> (Vec<usize>, usize) {
    let mut eq = vec![usize::MAX; 3 * fix.len()];
    let mut n = 0;
    for (p, &b) in fix.iter().enumerate() {
        for d in 0..3 {
            if b & (1 << d) == 0 {
                eq[3 * p + d] = n;
                n += 1;
            }
        }
    }
    (eq, n)
}

/// The lower-triangle pattern of `K_ff` from the point graph of the cells.
fn pattern(mesh: &RawMesh3, eq: &[usize], n: usize) -> SymbolicSparseColMat<usize> {
    let np = mesh.points.len();
    let mut adj: Vec<Vec<u32>> = vec![Vec::new(); np];
    for cell in &mesh.cells {
        let c = cell.corners();
        for &a in c {
            adj[a as usize].extend_from_slice(c);
        }
    }
    let mut col_ptr = vec![0usize; n + 1];
    let mut row_idx = Vec::new();
    let mut rows = Vec::new();
    for (p, nb) in adj.iter_mut().enumerate() {
        nb.sort_unstable();
        nb.dedup();
        for d in 0..3 {
            let j = eq[3 * p + d];
            if j == usize::MAX {
                continue;
            }
            rows.clear();
            for &q in nb.iter() {
                for e in 0..3 {
                    let i = eq[3 * q as usize + e];
                    if i != usize::MAX && i >= j {
                        rows.push(i);
                    }
                }
            }
            rows.sort_unstable();
            row_idx.extend_from_slice(&rows);
            col_ptr[j + 1] = row_idx.len();
        }
    }
    // Dofs are numbered point by point, so the columns above were filled in order.
    SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx)
}

/// `K_ff` (lower triangle on `pat`) and the right-hand side `f_f - K_fp u_p`.
fn assemble(p: &Problem3, eq: &[usize], pat: &SymbolicSparseColMat<usize>, f: &[[f64; 3]]) -> (SparseColMat<usize, f64>, Vec<f64>) {
    let m = p.mesh;
    let n = pat.nrows();
    let (cp, ri) = (pat.col_ptr(), pat.row_idx());
    let mut vals = vec![0.0; ri.len()];
    let mut rhs = vec![0.0; n];
    for (pt, fp) in f.iter().enumerate() {
        for dd in 0..3 {
            let k = eq[3 * pt + dd];
            if k != usize::MAX {
                rhs[k] += fp[dd];
            }
        }
    }
    let mut ke = vec![0.0; 24 * 24];
    for e in 0..m.cells.len() {
        let (c, x) = cell_x(m, e);
        let kind = p.kind_of(e);
        let nn = 3 * c.len();
        elements3d::stiffness(kind, &x[..c.len()], &p.dmat_of(e), &mut ke);
        let gdof: Vec<usize> = (0..nn).map(|i| eq[3 * c[i / 3] as usize + i % 3]).collect();
        for jl in 0..nn {
            let gj = gdof[jl];
            if gj == usize::MAX {
                // A prescribed column: its value moves to the right-hand side.
                let up = p.u_prescribed[c[jl / 3] as usize][jl % 3];
                if up != 0.0 {
                    for il in 0..nn {
                        if gdof[il] != usize::MAX {
                            rhs[gdof[il]] -= ke[il * nn + jl] * up;
                        }
                    }
                }
                continue;
            }
            let col = &ri[cp[gj]..cp[gj + 1]];
            for il in 0..nn {
                let gi = gdof[il];
                if gi == usize::MAX || gi < gj {
                    continue;
                }
                let pos = cp[gj] + col.binary_search(&gi).expect("the pattern holds every coupling of a cell");
                vals[pos] += ke[il * nn + jl];
            }
        }
    }
    (SparseColMat::new(pat.clone(), vals), rhs)
}

/// faer's approximate minimum degree ordering of the lower pattern (`order[new] = old`).
fn amd_order(pat: &SymbolicSparseColMat<usize>) -> Result<Vec<usize>, String> {
    use faer::sparse::linalg::amd;
    let n = pat.nrows();
    let (mut perm, mut inv) = (vec![0usize; n], vec![0usize; n]);
    let mut mem = MemBuffer::try_new(amd::order_scratch::<usize>(n, pat.row_idx().len())).map_err(|e| format!("{e:?}"))?;
    amd::order(&mut perm, &mut inv, pat.as_ref(), amd::Control::default(), MemStack::new(&mut mem)).map_err(|e| format!("{e:?}"))?;
    Ok(perm)
}

/// Solves the problem (module doc).
pub fn solve(p: &Problem3) -> Result<Solution3, FlemError> {
    validate(p)?;
    let m = p.mesh;
    let np = m.points.len();
    let mut f = p.f_ext.clone();
    face_forces(m, &p.face_loads, &mut f)?;
    let (eq, n) = number_dofs(&p.fix);
    let mut u: Vec<[f64; 3]> = (0..np).map(|i| std::array::from_fn(|d| if p.fix[i] & (1 << d) != 0 { p.u_prescribed[i][d] } else { 0.0 })).collect();
    let mut factor_nnz = 0;
    if n > 0 {
        let mut in_cell = vec![false; np];
        for c in &m.cells {
            for &q in c.corners() {
                in_cell[q as usize] = true;
            }
        }
        if let Some(i) = (0..np).find(|&i| p.fix[i] & 7 != 7 && !in_cell[i]) {
            return Err(err(m, format!("point {} belongs to no cell and is not fixed: its stiffness is singular", m.point_name(i))));
        }
        let pat = pattern(m, &eq, n);
        let (a, rhs) = assemble(p, &eq, &pat, &f);
        let order = amd_order(&pat).map_err(|e| err(m, format!("ordering failed: {e}")))?;
        let sym = factor::symbolic(pat.as_ref(), &order).map_err(|e| err(m, format!("symbolic factorisation failed: {e}")))?;
        let singular = || err(m, "the stiffness is singular: the body is not supported against its six rigid motions (or holds a mechanism)".to_string());
        let l = match factor::Factor::new(sym, &a, factor::par(n)) {
            Ok(l) => l,
            Err(faer::sparse::linalg::LltError::Numeric(_)) => return Err(singular()),
            Err(e) => return Err(err(m, format!("numeric factorisation failed: {e:?}"))),
        };
        factor_nnz = l.nnz();
        let par = factor::par(n);
        let x = refined_solve_with(|b| l.solve(b, par), &a, &rhs, true).ok_or_else(singular)?;
        for i in 0..np {
            for d in 0..3 {
                let k = eq[3 * i + d];
                if k != usize::MAX {
                    u[i][d] = x[k];
                }
            }
        }
    }
    let nodal_stress = nodal_stress(p, &u);
    Ok(Solution3 { u, nodal_stress, n_dofs: n, factor_nnz })
}

/// The stress of every corner of every cell (0.9999 corners; `corner[e][a]`).
pub fn corner_stresses(p: &Problem3, u: &[[f64; 3]]) -> Vec<[[f64; 6]; 8]> {
    (0..p.mesh.cells.len())
        .map(|e| {
            let (c, x) = cell_x(p.mesh, e);
            let ue: [[f64; 3]; 8] = std::array::from_fn(|a| if a < c.len() { u[c[a] as usize] } else { [0.0; 3] });
            let mut s = [[0.0; 6]; 8];
            elements3d::corner_stresses(p.kind_of(e), &x[..c.len()], &ue[..c.len()], &p.dmat_of(e), &mut s);
            s
        })
        .collect()
}

/// Nodal stress: the corner stresses of the cells of each point, averaged (points of no cell:
/// zero).
pub fn nodal_stress(p: &Problem3, u: &[[f64; 3]]) -> Vec<[f64; 6]> {
    let np = p.mesh.points.len();
    let mut s = vec![[0.0; 6]; np];
    let mut cnt = vec![0u32; np];
    for (e, cs) in corner_stresses(p, u).iter().enumerate() {
        for (a, &q) in p.mesh.cells[e].corners().iter().enumerate() {
            for k in 0..6 {
                s[q as usize][k] += cs[a][k];
            }
            cnt[q as usize] += 1;
        }
    }
    for (v, &c) in s.iter_mut().zip(&cnt) {
        if c > 0 {
            *v = v.map(|x| x / c as f64);
        }
    }
    s
}

/// Internal forces `K u` of every point (the element force routines, no matrix), e.g. for
/// checking an equilibrium: at a solution they equal the external forces on free dofs.
pub fn internal_forces(p: &Problem3, u: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let mut out = vec![[0.0; 3]; p.mesh.points.len()];
    let mut fe = [[0.0; 3]; 8];
    for e in 0..p.mesh.cells.len() {
        let (c, x) = cell_x(p.mesh, e);
        let ue: [[f64; 3]; 8] = std::array::from_fn(|a| if a < c.len() { u[c[a] as usize] } else { [0.0; 3] });
        elements3d::internal_force(p.kind_of(e), &x[..c.len()], &ue[..c.len()], &p.dmat_of(e), &mut fe);
        for (a, &q) in c.iter().enumerate() {
            for k in 0..3 {
                out[q as usize][k] += fe[a][k];
            }
        }
    }
    out
}

/// The external forces of the problem (point forces plus the face loads' consistent forces).
pub fn external_forces(p: &Problem3) -> Result<Vec<[f64; 3]>, FlemError> {
    let mut f = p.f_ext.clone();
    face_forces(p.mesh, &p.face_loads, &mut f)?;
    Ok(f)
}
