//! Galerkin multigrid for an assembled symmetric matrix over a hierarchy of independent meshes:
//! the preconditioner of [`crate::statics::newton`]'s conjugate gradients
//! ([`crate::statics::newton::MultigridPcg`]).
//!
//! Level 0 is the assembled matrix `A₀` over the free dofs. Level `l + 1`'s operator is the
//! Galerkin product
//!
//! ```text
//! A_{l+1} = P_lᵀ A_l P_l,       (P_l u)_{i,c} = Σ_k ω_ik u_{k,c}
//! ```
//!
//! `P_l` interpolates the coarser level's nodal 3-vectors to the finer level's dofs with the
//! host weights `ω` of paper eq. 6 ([`crate::hierarchy::Transfer`]), component by component.
//! A fine node outside the coarse mesh (a quarter of the liver L0's, at its surface) keeps the
//! extrapolated weights of eq. 7, so `P_l` reproduces every linear field, linearised rigid
//! motions included, at every fine node: the coarse space then holds the soft, near-rigid
//! modes of a body hanging from a small support, which are what the smoother cannot reduce.
//! Convex weights reproduce only constants there, and conjugate gradients need more
//! iterations (`bench/RESULTS.md`). Only a node whose weights leave `[0, 1]` by more than
//! [`EXTRAPOLATION_LIMIT`] takes convex ones ([`crate::hierarchy::Transfer::limited`]).
//!
//! On level 0 only the free dofs are rows, so the coarse operators carry the fine level's
//! Dirichlet conditions and need none of their own. A coarse dof every fine row of which is
//! fixed has an empty row; it gets a unit diagonal. Unlike a rediscretised coarse level, `A_{l+1}` is exactly the fine energy
//! restricted to the interpolated displacements, whatever the two meshes' shapes.
//!
//! One V-cycle `z = B b` ([`GalerkinMultigrid::apply`]) on level l, from `z = 0`:
//! `ν` forward sweeps of the smoother ([`super::smoother`]) on `A_l z = b`; the residual restricted, `b_c = P_lᵀ (b − A_l z)`;
//! the coarse correction `z_c = B_{l+1} b_c` (on the coarsest level a sparse Cholesky solve,
//! faer's, with a diagonal shift where the coarsest operator is not positive definite:
//! [`super::coarse_factor`]) added,
//! `z += P_l z_c`; `ν` backward sweeps. The backward sweep is the forward one's adjoint and the
//! coarsest solve is exact (up to its factor's rounding to `f32`, [`super::coarse_factor`]),
//! so `B` is symmetric, and positive definite where every `A_l` is: a
//! preconditioner for conjugate gradients. Built for one matrix, it may precondition a later
//! one (a Newton iteration's next tangent): it stays symmetric and positive definite, only
//! less close to that matrix's inverse.
//!
//! The smoothed levels' sweeps and the cycle's residuals read their operator's values rounded to
//! single precision (`A_l` as `f32`, [`Entry`]), on the same pattern (rows in colour order for
//! [`Smoother::ColouredBlock`], [`super::smoother::ColourOrder`]); all arithmetic stays in
//! `f64`. The matrix rows are what a cycle spends its time reading, and single precision halves
//! the values' share of that traffic. The rounded operator is still symmetric (`a_ij` and `a_ji`
//! round alike), so `B` stays symmetric; it differs from the `f64` cycle by about `10⁻⁷` of the
//! operator, far below what a preconditioner needs. Conjugate gradients' own products and the
//! Galerkin products use the `f64` values.
//!
//! Everything is computed in a fixed order: the Galerkin products and the matrix-vector
//! products are split into row blocks that are independent (the same bits on any thread
//! count), and so are the smoothers' ([`super::smoother`]).
//!
//! A later hierarchy over the same finest pattern and prolongations (a later Newton tangent)
//! keeps what depends on the patterns alone ([`GalerkinSymbolic`]): each product's pattern,
//! the smoothed levels' colourings and colour orders, the coarsest level's symbolic
//! factorisation. Only the values are formed again, each sum in the order of the first build:
//! the bits of a build from scratch.

use super::coarse_factor::{CoarseFactor, CoarseSymbolic, Precision};
use super::smoother::{gauss_seidel, ColourOrder, Colouring, Smoother};
pub use super::sparse::{Csr, Entry, SymScatter};
use crate::hierarchy::Transfer;
use rayon::prelude::*;
use std::sync::Arc;

/// How far outside `[0, 1]` a fine node's host weights may reach and still be used as they
/// are (module docs); the liver levels' reach 2-3.
pub const EXTRAPOLATION_LIMIT: f64 = 4.0;

/// The interpolation from a coarser mesh's nodal 3-vectors (`3 × t.target_nodes` columns) to
/// the finer level's dofs `dofs` (`dofs[r] = 3 node + component` of row r), with `t`'s weights
/// (the finer level's nodes located in the coarser mesh).
pub fn prolongation(t: &Transfer, dofs: &[usize]) -> Csr {
    let mut ptr = Vec::with_capacity(dofs.len() + 1);
    ptr.push(0);
    let mut col = Vec::new();
    let mut val = Vec::new();
    let mut row: Vec<(u32, f64)> = Vec::with_capacity(4);
    for &d in dofs {
        let (a, c) = (d / 3, d % 3);
        row.clear();
        for j in 0..t.npe {
            let w = t.weights[a][j];
            if w != 0.0 {
                let k = 3 * t.nodes[a][j] + c as u32;
                match row.iter_mut().find(|(kk, _)| *kk == k) {
                    Some(e) => e.1 += w,
                    None => row.push((k, w)),
                }
            }
        }
        row.sort_unstable_by_key(|e| e.0);
        for &(k, w) in &row {
            col.push(k);
            val.push(w);
        }
        ptr.push(col.len());
    }
    Csr {
        rows: dofs.len(),
        cols: 3 * t.target_nodes,
        ptr,
        col,
        val,
    }
}

/// The fixed part of a hierarchy for [`GalerkinMultigrid`]: each interpolation and its
/// transpose, finest first.
#[derive(Clone, Debug, Default)]
pub struct Prolongations {
    /// `(P_l, P_lᵀ)`, level l's rows from level l + 1's columns.
    pub levels: Vec<(Csr, Csr)>,
    /// Level l's dofs (`3 node + component` of each row of `A_l`), for each level but the
    /// coarsest.
    pub dofs: Vec<Vec<usize>>,
    /// The patterns' identity: the same for [`Prolongations::masked`] copies (same patterns,
    /// other values), new for each [`Prolongations::new`]; 0 for the empty default.
    pattern: u64,
}

/// The next [`Prolongations::pattern`] identity.
static NEXT_PATTERN: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);

impl Prolongations {
    /// From the transfers `down[l]` (level l's nodes in level l + 1's mesh, limited here to
    /// [`EXTRAPOLATION_LIMIT`]),
    /// level 0's rows being its free dofs `free_dofs` (`3 node + component`, ascending).
    pub fn new(down: &[Transfer], free_dofs: &[usize]) -> Prolongations {
        let mut levels = Vec::with_capacity(down.len());
        let mut all = Vec::with_capacity(down.len());
        let mut dofs = free_dofs.to_vec();
        for t in down {
            let p = prolongation(&t.limited(EXTRAPOLATION_LIMIT), &dofs);
            let pt = p.transpose();
            all.push(std::mem::replace(
                &mut dofs,
                (0..3 * t.target_nodes).collect(),
            ));
            levels.push((p, pt));
        }
        Prolongations::from_levels(levels, all)
    }

    /// From the pairs `(P_l, P_lᵀ)` and level l's dofs (a new pattern identity).
    pub fn from_levels(levels: Vec<(Csr, Csr)>, dofs: Vec<Vec<usize>>) -> Prolongations {
        Prolongations {
            levels,
            dofs,
            pattern: NEXT_PATTERN.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
        }
    }

    /// These prolongations with level 0's rows `r` where `rows[r]` zeroed (and the matching
    /// entries of `P_0ᵀ`), the patterns kept: dofs held at run time, decoupled in the finest
    /// operator, then reach no coarser level, and the Galerkin operators are those of the
    /// other dofs alone (`P_Fᵀ A_FF P_F`) on the same patterns, so that a
    /// [`GalerkinSymbolic`] of the unmasked prolongations serves them.
    pub fn masked(&self, rows: &[bool]) -> Prolongations {
        let mut m = self.clone();
        if let Some((p, pt)) = m.levels.first_mut() {
            for (r, &held) in rows.iter().enumerate().take(p.rows) {
                if held {
                    p.val[p.ptr[r]..p.ptr[r + 1]]
                        .iter_mut()
                        .for_each(|v| *v = 0.0);
                }
            }
            for (c, v) in pt.col.iter().zip(pt.val.iter_mut()) {
                if rows.get(*c as usize).copied().unwrap_or(false) {
                    *v = 0.0;
                }
            }
        }
        m
    }

    /// Whether there is no coarser level.
    pub fn is_empty(&self) -> bool {
        self.levels.is_empty()
    }
}

/// Why a Galerkin hierarchy could not be set up: its coarsest level's factor
/// ([`super::coarse_factor::FactorError`]).
pub use super::coarse_factor::FactorError as GalerkinError;

/// One coarser level's Galerkin product patterns: `A_l P_l`'s and `A_{l+1} = P_lᵀ A_l P_l`'s
/// (an empty row's unit diagonal included), values empty. Fixed by the finer operator's
/// pattern and the prolongation.
#[derive(Clone, Debug)]
struct ProductPattern {
    ap: Csr,
    c: Csr,
    /// The rows of `A_{l+1}` given a unit diagonal ([`unit_empty_diagonal`]).
    empty: Vec<usize>,
}

impl ProductPattern {
    /// `Pᵀ A P` on this pattern: the bits of [`galerkin_product`], the patterns not searched
    /// again.
    fn product(&self, a: &Csr, pl: &Csr, pt: &Csr) -> Csr {
        let ap = a.product_values(pl, &pl.val, &self.ap);
        let mut val = pt.product_values(&self.ap, &ap, &self.c);
        for &i in &self.empty {
            val[self.c.ptr[i]] = 1.0;
        }
        let mut c = Csr {
            val,
            ..self.c.clone()
        };
        unit_zero_diagonal(&mut c);
        c
    }
}

/// What a Galerkin hierarchy keeps from one build to the next on the same finest pattern and
/// prolongations (a Newton solve's later tangents): the Galerkin products' patterns, the
/// smoothed levels' colourings and colour orders ([`Smoother::ColouredBlock`],
/// [`Smoother::BlockJacobi`]), the coarsest level's symbolic factorisation. Empty at first;
/// each [`GalerkinMultigrid::new`] fills in what it lacks. A call with other prolongations
/// or a finest operator of another shape starts it afresh; one with another pattern of the
/// same rows and entries per row is a caller's error.
#[derive(Default)]
pub struct GalerkinSymbolic {
    /// The prolongations' pattern identity and the finest pattern's row starts these are for.
    key: Option<(u64, Vec<usize>)>,
    products: Option<Arc<Vec<ProductPattern>>>,
    colourings: Option<Arc<Vec<Colouring>>>,
    orders: Option<Arc<Vec<ColourOrder>>>,
    coarse: Option<CoarseSymbolic>,
}

impl GalerkinSymbolic {
    /// Start afresh unless this was filled for `p` and a finest pattern with `a0`'s rows.
    fn check(&mut self, a0: &Csr, p: &Arc<Prolongations>) {
        let same = matches!(&self.key, Some((kp, ptr)) if *kp == p.pattern && *ptr == a0.ptr);
        if !same {
            *self = GalerkinSymbolic {
                key: Some((p.pattern, a0.ptr.clone())),
                ..Default::default()
            };
        }
    }
}

/// A Galerkin V-cycle for one matrix (module docs), its coarsest level factored.
pub struct GalerkinMultigrid {
    /// `A_l`, finest first.
    a: Vec<Csr>,
    /// The values of each smoothed level's `A_l` rounded to `f32` (module docs).
    single: Vec<Vec<f32>>,
    /// The smoother's inverse diagonals of each level but the coarsest.
    relax: Vec<Relax>,
    p: Arc<Prolongations>,
    /// Each coarser level's product patterns ([`GalerkinSymbolic`]).
    products: Arc<Vec<ProductPattern>>,
    sweeps: usize,
    smoother: Smoother,
    /// Each smoothed level's node blocks and colours ([`Smoother::ColouredBlock`]); fixed by
    /// the pattern, so kept by [`GalerkinMultigrid::refresh`].
    colourings: Arc<Vec<Colouring>>,
    /// Each smoothed level's rows in colour order, which its `f32` values follow
    /// ([`Smoother::ColouredBlock`] only; empty otherwise).
    orders: Arc<Vec<ColourOrder>>,
    coarse: CoarseFactor,
}

/// What one level's smoother needs from its operator's values.
enum Relax {
    /// `1 / A_ii`, 0 where that diagonal is not positive ([`Smoother::GaussSeidel`]).
    Point(Vec<f64>),
    /// Each node block's inverse diagonal block ([`Colouring::inverses`]).
    Block(Vec<[f64; 9]>),
    /// The same, and the damping ω ([`Smoother::BlockJacobi`]).
    Jacobi(Vec<[f64; 9]>, f64),
}

impl GalerkinMultigrid {
    /// The Galerkin operators of `a0` over `p`'s levels and the coarsest one's factorisation,
    /// solved in `precision` ([`super::coarse_factor`]); `sweeps` sweeps of `smoother` before
    /// and after each coarse correction. `symbolic`, what an earlier call on the same
    /// prolongations and finest pattern found ([`GalerkinSymbolic`]), is reused where it
    /// holds it and filled in where not, the coarsest factor's size checked against the
    /// available memory before it is first analysed ([`GalerkinError::Memory`]). Errors where the
    /// coarsest operator does not factor even shifted by 10⁶ times its mean diagonal
    /// ([`GalerkinError::Factor`]).
    pub fn new(
        a0: Csr,
        p: Arc<Prolongations>,
        sweeps: usize,
        smoother: Smoother,
        precision: Precision,
        symbolic: &mut GalerkinSymbolic,
    ) -> Result<Self, GalerkinError> {
        symbolic.check(&a0, &p);
        let a = operators(a0, &p, &mut symbolic.products);
        let products = symbolic.products.clone().expect("made by `operators`");
        let coarse = CoarseFactor::new(a.last().unwrap(), &mut symbolic.coarse, precision)?;
        let smoothed = &a[..a.len() - 1];
        let colourings = match smoother {
            Smoother::GaussSeidel => Arc::new(Vec::new()),
            Smoother::ColouredBlock | Smoother::BlockJacobi => symbolic
                .colourings
                .get_or_insert_with(|| {
                    Arc::new(
                        smoothed
                            .iter()
                            .zip(&p.dofs)
                            .map(|(al, dofs)| Colouring::new(al, dofs))
                            .collect(),
                    )
                })
                .clone(),
        };
        let orders = if smoother == Smoother::ColouredBlock {
            if symbolic.orders.is_none() {
                let bytes = smoothed
                    .iter()
                    .map(|m| ColourOrder::bytes(m.rows, m.col.len()))
                    .sum();
                crate::memory::check("the smoothed levels' rows in colour order", bytes)
                    .map_err(GalerkinError::Memory)?;
                symbolic.orders = Some(Arc::new(
                    smoothed
                        .iter()
                        .zip(colourings.iter())
                        .map(|(m, c)| c.order(m))
                        .collect(),
                ));
            }
            symbolic.orders.clone().expect("made above")
        } else {
            Arc::new(Vec::new())
        };
        let mut mg = GalerkinMultigrid {
            a,
            single: Vec::new(),
            relax: Vec::new(),
            p,
            products,
            sweeps,
            smoother,
            colourings,
            orders,
            coarse,
        };
        mg.relax = mg.relaxation();
        mg.single = mg.rounded();
        Ok(mg)
    }

    /// The finest operator, to be written in place (same pattern) before
    /// [`GalerkinMultigrid::refresh`].
    pub fn finest_mut(&mut self) -> &mut Csr {
        &mut self.a[0]
    }

    /// The Galerkin operators of the finest operator as it now is (written through
    /// [`GalerkinMultigrid::finest_mut`]), keeping the coarsest factorisation of the earlier
    /// one: the cycle stays symmetric, and positive definite where the new operators are, its
    /// coarse correction that of the earlier operator. Only the smoothed levels' operators are
    /// formed; with coarser levels the coarsest stays the earlier one, which its kept
    /// factorisation is of (the cycle uses it through that factorisation alone).
    pub fn refresh(&mut self) {
        let levels = self.a.len();
        let mut a = vec![std::mem::take(&mut self.a[0])];
        if levels > 1 {
            for ((pl, pt), pat) in self.p.levels[..levels - 2].iter().zip(self.products.iter()) {
                a.push(pat.product(a.last().unwrap(), pl, pt));
            }
            a.push(self.a.pop().expect("the coarsest operator"));
        }
        self.a = a;
        // Block Jacobi keeps the damping estimated when the hierarchy was built: D⁻¹A's
        // largest eigenvalue moves little from one Newton tangent to the next. A cycle that is
        // not positive on the first residual is rebuilt (`crate::statics::newton`); later in a solve
        // it truncates conjugate gradients.
        let omegas: Vec<Option<f64>> = self
            .relax
            .iter()
            .map(|r| match r {
                Relax::Jacobi(_, omega) => Some(*omega),
                _ => None,
            })
            .collect();
        self.relax = self.relaxation_with(&omegas);
        for (l, (m, single)) in self.a.iter().zip(self.single.iter_mut()).enumerate() {
            match self.orders.get(l) {
                Some(order) => order.fill(m, |v| v as f32, single),
                None => single
                    .par_iter_mut()
                    .zip(&m.val)
                    .for_each(|(s, &v)| *s = v as f32),
            }
        }
    }

    /// The smoothed levels' values rounded to `f32`.
    fn rounded(&self) -> Vec<Vec<f32>> {
        self.a[..self.a.len() - 1]
            .iter()
            .enumerate()
            .map(|(l, m)| match self.orders.get(l) {
                Some(order) => order.values(m, |v| v as f32),
                None => m.val.par_iter().map(|&v| v as f32).collect(),
            })
            .collect()
    }

    /// The smoother's inverse diagonals of each level but the coarsest.
    fn relaxation(&self) -> Vec<Relax> {
        self.relaxation_with(&[])
    }

    /// [`GalerkinMultigrid::relaxation`], block Jacobi's damping on level l `omegas[l]` where
    /// given, estimated where not.
    fn relaxation_with(&self, omegas: &[Option<f64>]) -> Vec<Relax> {
        let smoothed = &self.a[..self.a.len() - 1];
        match self.smoother {
            Smoother::GaussSeidel => smoothed
                .iter()
                .map(|m| {
                    Relax::Point(
                        m.diagonal()
                            .iter()
                            .map(|&d| if d > 0.0 { 1.0 / d } else { 0.0 })
                            .collect(),
                    )
                })
                .collect(),
            Smoother::ColouredBlock => smoothed
                .iter()
                .zip(self.colourings.iter())
                .map(|(m, c)| Relax::Block(c.inverses(m)))
                .collect(),
            Smoother::BlockJacobi => smoothed
                .iter()
                .zip(self.colourings.iter())
                .enumerate()
                .map(|(l, (m, c))| {
                    let inv = c.inverses(m);
                    let omega = omegas
                        .get(l)
                        .copied()
                        .flatten()
                        .unwrap_or_else(|| c.jacobi_damping(m, &inv));
                    Relax::Jacobi(inv, omega)
                })
                .collect(),
        }
    }

    /// The finest operator `A₀` (the matrix of [`GalerkinMultigrid::new`] or the latest
    /// [`GalerkinMultigrid::refresh`]).
    pub fn matrix(&self) -> &Csr {
        &self.a[0]
    }

    /// The shift the coarsest operator needed to factor, relative to its mean diagonal.
    pub fn coarse_shift(&self) -> f64 {
        self.coarse.shift
    }

    /// `z = B b`, one V-cycle from `z = 0`.
    pub fn apply(&self, b: &[f64], z: &mut [f64]) {
        self.cycle(0, b, z);
    }

    /// One smoothing sweep on level `l`; `zero`: `z` is 0 (the first sweep of a cycle).
    fn smooth(&self, l: usize, b: &[f64], z: &mut [f64], forward: bool, zero: bool) {
        let (a, v) = (&self.a[l], &self.single[l][..]);
        match &self.relax[l] {
            Relax::Point(inv) => gauss_seidel(a, v, inv, b, z, forward),
            Relax::Block(inv) => self.colourings[l].sweep(&self.orders[l], v, inv, b, z, forward),
            Relax::Jacobi(inv, omega) => {
                self.colourings[l].jacobi_sweep(a, v, inv, *omega, b, z, zero)
            }
        }
    }

    fn cycle(&self, l: usize, b: &[f64], z: &mut [f64]) {
        let a = &self.a[l];
        if l + 1 == self.a.len() {
            self.coarse.solve(b, z);
            return;
        }
        z.iter_mut().for_each(|v| *v = 0.0);
        for k in 0..self.sweeps {
            self.smooth(l, b, z, true, k == 0);
        }
        let mut r = vec![0.0; b.len()];
        match self.orders.get(l) {
            Some(order) => order.residual(&self.single[l], b, z, &mut r),
            None => {
                a.matvec_of(&self.single[l], z, &mut r);
                for (ri, bi) in r.iter_mut().zip(b) {
                    *ri = bi - *ri;
                }
            }
        }
        let (pl, pt) = &self.p.levels[l];
        let mut bc = vec![0.0; pl.cols];
        pt.matvec(&r, &mut bc);
        let mut zc = vec![0.0; pl.cols];
        self.cycle(l + 1, &bc, &mut zc);
        pl.matvec_add(&zc, z);
        for _ in 0..self.sweeps {
            self.smooth(l, b, z, false, false);
        }
    }
}

/// The Galerkin operators of `a0` over `p`'s levels, finest first.
/// `products`, the patterns of an earlier call on the same finest pattern, are used where
/// given and found (and kept) where not.
fn operators(
    a0: Csr,
    p: &Prolongations,
    products: &mut Option<Arc<Vec<ProductPattern>>>,
) -> Vec<Csr> {
    let mut a = vec![a0];
    match products {
        Some(pats) => {
            for ((pl, pt), pat) in p.levels.iter().zip(pats.iter()) {
                a.push(pat.product(a.last().unwrap(), pl, pt));
            }
        }
        None => {
            let mut pats = Vec::with_capacity(p.levels.len());
            for (pl, pt) in &p.levels {
                let (c, pat) = galerkin_product(a.last().unwrap(), pl, pt);
                a.push(c);
                pats.push(pat);
            }
            *products = Some(Arc::new(pats));
        }
    }
    a
}

/// `Pᵀ A P`, rows without a positive diagonal given a unit one, and its patterns.
fn galerkin_product(a: &Csr, pl: &Csr, pt: &Csr) -> (Csr, ProductPattern) {
    let ap = a.product(pl);
    let mut c = pt.product(&ap);
    let empty = unit_empty_diagonal(&mut c);
    unit_zero_diagonal(&mut c);
    let pat = ProductPattern {
        ap: ap.pattern(),
        c: c.pattern(),
        empty,
    };
    (c, pat)
}

/// Give every row whose diagonal is zero a unit one: a coarse dof that only fine dofs
/// [`Prolongations::masked`] reach has a row of zeros on its pattern (none otherwise: an
/// operator's diagonal is positive).
fn unit_zero_diagonal(c: &mut Csr) {
    for i in 0..c.rows {
        let (lo, hi) = (c.ptr[i], c.ptr[i + 1]);
        if let Ok(k) = c.col[lo..hi].binary_search(&(i as u32)) {
            if c.val[lo + k] == 0.0 {
                c.val[lo + k] = 1.0;
            }
        }
    }
}

/// Give every row without a positive diagonal (a coarse dof that only fixed fine dofs see)
/// a unit diagonal; such rows are empty. Returns those rows.
fn unit_empty_diagonal(c: &mut Csr) -> Vec<usize> {
    let empty: Vec<usize> = (0..c.rows).filter(|&i| c.ptr[i] == c.ptr[i + 1]).collect();
    if empty.is_empty() {
        return empty;
    }
    let mut ptr = Vec::with_capacity(c.rows + 1);
    ptr.push(0);
    let mut col = Vec::with_capacity(c.col.len() + empty.len());
    let mut val = Vec::with_capacity(c.col.len() + empty.len());
    for i in 0..c.rows {
        let (cc, vv) = c.row(i);
        if cc.is_empty() {
            col.push(i as u32);
            val.push(1.0);
        } else {
            col.extend_from_slice(cc);
            val.extend_from_slice(vv);
        }
        ptr.push(col.len());
    }
    c.ptr = ptr;
    c.col = col;
    c.val = val;
    empty
}

#[cfg(test)]
pub(crate) mod tests;
