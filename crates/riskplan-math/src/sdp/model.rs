//! The model under construction: variables, rows, cones, objective; assembly and solve.

use super::*;
use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSolver, SupportedConeT};

/// A scalar variable of a [`Model`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Var(pub(super) usize);

impl Var {
    /// Index into the primal vector `x`.
    pub fn index(self) -> usize {
        self.0
    }
    /// The handle of variable `i` (for modelling code that keeps indices; a handle
    /// that does not belong to the model it is used with is refused there with
    /// [`SdpError::VarOutOfRange`]).
    pub fn from_index(i: usize) -> Var {
        Var(i)
    }
}

/// `constant + Σ coeff · var`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AffineExpr {
    /// The constant term.
    pub constant: f64,
    /// Linear terms; repeated variables add up.
    pub terms: Vec<(Var, f64)>,
}

impl AffineExpr {
    /// A constant expression.
    pub fn constant(c: f64) -> Self {
        AffineExpr { constant: c, terms: Vec::new() }
    }
    /// The expression `v`.
    pub fn var(v: Var) -> Self {
        AffineExpr { constant: 0.0, terms: vec![(v, 1.0)] }
    }
}

/// A contiguous range of constraint rows (and so of dual and slack entries).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rows {
    /// First row.
    pub start: usize,
    /// Number of rows.
    pub len: usize,
}

impl Rows {
    /// The rows as a range.
    pub fn range(self) -> std::ops::Range<usize> {
        self.start..self.start + self.len
    }
}

/// The cone of a run of consecutive rows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ConeKind {
    Zero,
    Nonneg,
    Soc,
    Psd(usize),
}

/// A conic problem under construction; see the module docs.
#[derive(Clone, Debug, Default)]
pub struct Model {
    n: usize,
    q: Vec<f64>,
    // Triplets of A, in nondecreasing row order (rows are only ever appended).
    a_row: Vec<usize>,
    a_col: Vec<usize>,
    a_val: Vec<f64>,
    b: Vec<f64>,
    blocks: Vec<(ConeKind, usize)>,
    force_triangle: bool,
}

impl Model {
    /// An empty model.
    pub fn new() -> Self {
        Self::default()
    }

    /// An empty model with room for `vars` variables, `rows` rows and `nnz` nonzeros.
    pub fn with_capacity(vars: usize, rows: usize, nnz: usize) -> Self {
        Model {
            n: 0,
            q: Vec::with_capacity(vars),
            a_row: Vec::with_capacity(nnz),
            a_col: Vec::with_capacity(nnz),
            a_val: Vec::with_capacity(nnz),
            b: Vec::with_capacity(rows),
            blocks: Vec::new(),
            force_triangle: false,
        }
    }

    /// Number of variables.
    pub fn num_vars(&self) -> usize {
        self.n
    }

    /// Number of constraint rows.
    pub fn num_rows(&self) -> usize {
        self.b.len()
    }

    /// The right-hand side `b` as stored (one entry per row); a starting point for
    /// [`Prepared::update_b`].
    pub fn rhs(&self) -> &[f64] {
        &self.b
    }

    /// A new free scalar variable.
    pub fn add_var(&mut self) -> Var {
        self.n += 1;
        self.q.push(0.0);
        Var(self.n - 1)
    }

    /// `k` new free scalar variables.
    pub fn add_vars(&mut self, k: usize) -> Vec<Var> {
        (0..k).map(|_| self.add_var()).collect()
    }

    fn check_terms(&self, terms: &[(Var, f64)], what: &'static str) -> Result<(), SdpError> {
        for &(v, c) in terms {
            if v.0 >= self.n {
                return Err(SdpError::VarOutOfRange { var: v.0, n: self.n });
            }
            if !c.is_finite() {
                return Err(SdpError::NonFinite(what));
            }
        }
        Ok(())
    }

    fn check_expr(&self, e: &AffineExpr, what: &'static str) -> Result<(), SdpError> {
        if !e.constant.is_finite() {
            return Err(SdpError::NonFinite(what));
        }
        self.check_terms(&e.terms, what)
    }

    /// Appends one row `b − (A x)`: `A` row = `sign · terms`, `b = rhs`. Inputs checked.
    fn push_row(&mut self, terms: &[(Var, f64)], sign: f64, rhs: f64) {
        let r = self.b.len();
        for &(v, c) in terms {
            if c != 0.0 {
                self.a_row.push(r);
                self.a_col.push(v.0);
                self.a_val.push(sign * c);
            }
        }
        self.b.push(rhs);
    }

    fn push_block(&mut self, kind: ConeKind, len: usize) -> Rows {
        let start = self.b.len() - len;
        match (self.blocks.last_mut(), kind) {
            // adjacent zero / nonnegative blocks merge into one Clarabel cone
            (Some((ConeKind::Zero, m)), ConeKind::Zero) | (Some((ConeKind::Nonneg, m)), ConeKind::Nonneg) => *m += len,
            _ => self.blocks.push((kind, len)),
        }
        Rows { start, len }
    }

    /// The equality `Σ a·x = rhs`.
    pub fn add_eq(&mut self, terms: &[(Var, f64)], rhs: f64) -> Result<Rows, SdpError> {
        self.check_terms(terms, "equality row")?;
        if !rhs.is_finite() {
            return Err(SdpError::NonFinite("equality right-hand side"));
        }
        self.push_row(terms, 1.0, rhs);
        Ok(self.push_block(ConeKind::Zero, 1))
    }

    /// The inequality `Σ a·x ≤ rhs` (a nonnegative-cone row).
    pub fn add_le(&mut self, terms: &[(Var, f64)], rhs: f64) -> Result<Rows, SdpError> {
        self.check_terms(terms, "inequality row")?;
        if !rhs.is_finite() {
            return Err(SdpError::NonFinite("inequality right-hand side"));
        }
        self.push_row(terms, 1.0, rhs);
        Ok(self.push_block(ConeKind::Nonneg, 1))
    }

    /// The inequality `Σ a·x ≥ rhs`.
    pub fn add_ge(&mut self, terms: &[(Var, f64)], rhs: f64) -> Result<Rows, SdpError> {
        self.check_terms(terms, "inequality row")?;
        if !rhs.is_finite() {
            return Err(SdpError::NonFinite("inequality right-hand side"));
        }
        self.push_row(terms, -1.0, -rhs);
        Ok(self.push_block(ConeKind::Nonneg, 1))
    }

    /// `e ≥ 0` for an affine expression.
    pub fn add_nonneg(&mut self, e: &AffineExpr) -> Result<Rows, SdpError> {
        self.check_expr(e, "nonnegative row")?;
        self.push_row(&e.terms, -1.0, e.constant);
        Ok(self.push_block(ConeKind::Nonneg, 1))
    }

    /// The second-order cone `e_0 ≥ ‖(e_1, …, e_k)‖₂`; needs `k ≥ 1`.
    pub fn add_soc(&mut self, es: &[AffineExpr]) -> Result<Rows, SdpError> {
        if es.len() < 2 {
            return Err(SdpError::BadConeSize(format!("second-order cone of dimension {} (need ≥ 2)", es.len())));
        }
        for e in es {
            self.check_expr(e, "second-order cone row")?;
        }
        for e in es {
            self.push_row(&e.terms, -1.0, e.constant);
        }
        Ok(self.push_block(ConeKind::Soc, es.len()))
    }

    /// A new Gram block `Q ⪰ 0` of side `side ≥ 1` (pattern 1, docs/design.md §4.2): `side(side+1)/2`
    /// new variables (raw `Q_ij`, svec order) and the cone rows of `Q ⪰ 0`: PSD rows
    /// `s = svec(Q)` (coefficients −1 on the diagonal, −√2 off it), or the equivalent
    /// small form for side ≤ 2 (see [`PsdForm`], [`Model::set_force_psd_triangle`]).
    pub fn add_gram(&mut self, side: usize) -> Result<GramBlock, SdpError> {
        if side == 0 {
            return Err(SdpError::BadConeSize("Gram block of side 0".into()));
        }
        let len = svec_len(side);
        let first = self.n;
        for _ in 0..len {
            self.add_var();
        }
        let entries: Vec<AffineExpr> = (first..first + len).map(|v| AffineExpr::var(Var(v))).collect();
        let psd = self.push_psd(side, &entries);
        Ok(GramBlock { first, side, psd })
    }

    /// The affine matrix inequality `M(x) = M0 + Σ_k x_k M_k ⪰ 0` of side `side ≥ 1`
    /// (pattern 2, docs/design.md §4.3). `entries` holds the *raw* (unscaled) entries `M(x)_ij`,
    /// `i ≤ j`, in svec order (`entries[svec_index(i, j)]`); the √2 scaling of the
    /// off-diagonal rows (`A = −c_ij (M_k)_ij`, `b = c_ij (M0)_ij`) is applied here.
    /// Side ≤ 2 uses the equivalent small form unless
    /// [`Model::set_force_psd_triangle`] is set.
    pub fn add_psd_affine(&mut self, side: usize, entries: &[AffineExpr]) -> Result<PsdBlock, SdpError> {
        if side == 0 || entries.len() != svec_len(side) {
            return Err(SdpError::BadConeSize(format!(
                "affine PSD block of side {side} with {} entries (need {})",
                entries.len(),
                svec_len(side)
            )));
        }
        for e in entries {
            self.check_expr(e, "affine PSD entry")?;
        }
        Ok(self.push_psd(side, entries))
    }

    /// Always use `PSDTriangleConeT`, even for sides 1 and 2 (default: off, the small
    /// exact forms of [`PsdForm`] are used). Affects blocks added afterwards.
    pub fn set_force_psd_triangle(&mut self, on: bool) {
        self.force_triangle = on;
    }

    /// Rows of `M ⪰ 0` for checked entries (raw, svec order).
    fn push_psd(&mut self, side: usize, entries: &[AffineExpr]) -> PsdBlock {
        let start = self.b.len();
        let form = match side {
            1 if !self.force_triangle => PsdForm::Nonneg,
            2 if !self.force_triangle => PsdForm::Soc,
            _ => PsdForm::Triangle,
        };
        match form {
            PsdForm::Triangle => {
                for j in 0..side {
                    for i in 0..=j {
                        let e = &entries[svec_index(i, j)];
                        let c = if i == j { 1.0 } else { SQRT2 };
                        self.push_row(&e.terms, -c, c * e.constant);
                    }
                }
                self.push_block(ConeKind::Psd(side), svec_len(side));
            }
            PsdForm::Nonneg => {
                self.push_row(&entries[0].terms, -1.0, entries[0].constant);
                self.push_block(ConeKind::Nonneg, 1);
            }
            PsdForm::Soc => {
                let (a, b, c) = (&entries[0], &entries[1], &entries[2]);
                let mut t: Vec<(Var, f64)> = Vec::with_capacity(a.terms.len() + c.terms.len());
                t.extend_from_slice(&a.terms);
                t.extend_from_slice(&c.terms);
                self.push_row(&t, -1.0, a.constant + c.constant);
                t.clear();
                t.extend_from_slice(&a.terms);
                t.extend(c.terms.iter().map(|&(v, k)| (v, -k)));
                self.push_row(&t, -1.0, a.constant - c.constant);
                self.push_row(&b.terms, -2.0, 2.0 * b.constant);
                self.push_block(ConeKind::Soc, 3);
            }
        }
        PsdBlock { rows: Rows { start, len: self.b.len() - start }, side, form }
    }

    /// Sets the objective `min Σ c·x` (repeated variables add up; replaces any
    /// previous objective). To maximise, negate.
    pub fn set_objective(&mut self, terms: &[(Var, f64)]) -> Result<(), SdpError> {
        self.check_terms(terms, "objective")?;
        self.q.iter_mut().for_each(|c| *c = 0.0);
        for &(v, c) in terms {
            self.q[v.0] += c;
        }
        if self.q.iter().any(|c| !c.is_finite()) {
            return Err(SdpError::NonFinite("objective"));
        }
        Ok(())
    }

    /// `A` in CSC form, built from the row-ordered triplets by a stable counting sort
    /// on columns (rows stay increasing within each column; repeated `(row, col)`
    /// entries are adjacent and are summed).
    pub(super) fn csc_a(&self) -> CscMatrix<f64> {
        let (m, n, nnz) = (self.b.len(), self.n, self.a_val.len());
        let mut colptr = vec![0usize; n + 1];
        for &c in &self.a_col {
            colptr[c + 1] += 1;
        }
        for c in 0..n {
            colptr[c + 1] += colptr[c];
        }
        let mut next = colptr.clone();
        let mut rowval = vec![0usize; nnz];
        let mut nzval = vec![0.0; nnz];
        for t in 0..nnz {
            let c = self.a_col[t];
            let p = next[c];
            rowval[p] = self.a_row[t];
            nzval[p] = self.a_val[t];
            next[c] += 1;
        }
        // merge duplicates in place
        let mut out = 0usize;
        let mut start = 0usize;
        for c in 0..n {
            let end = colptr[c + 1];
            let col_start = out;
            for p in start..end {
                if out > col_start && rowval[out - 1] == rowval[p] {
                    nzval[out - 1] += nzval[p];
                } else {
                    rowval[out] = rowval[p];
                    nzval[out] = nzval[p];
                    out += 1;
                }
            }
            start = end;
            colptr[c + 1] = out;
        }
        rowval.truncate(out);
        nzval.truncate(out);
        CscMatrix::new(m, n, colptr, rowval, nzval)
    }

    fn cones(&self) -> Vec<SupportedConeT<f64>> {
        self.blocks
            .iter()
            .map(|&(k, len)| match k {
                ConeKind::Zero => SupportedConeT::ZeroConeT(len),
                ConeKind::Nonneg => SupportedConeT::NonnegativeConeT(len),
                ConeKind::Soc => SupportedConeT::SecondOrderConeT(len),
                ConeKind::Psd(side) => SupportedConeT::PSDTriangleConeT(side),
            })
            .collect()
    }

    /// Solves with Clarabel. An `Ok` result may still have any status; only the
    /// caller's own re-check can turn the point into a proof.
    pub fn solve(&self, settings: &SdpSettings) -> Result<SdpSolution, SdpError> {
        self.prepare(settings)?.solve()
    }

    /// Builds the Clarabel solver once (setup: KKT assembly, ordering, equilibration)
    /// so that it can be re-solved after [`Prepared::update_b`] / [`Prepared::update_q`]
    /// — the iterated SDPs of docs/design.md §8 change only `q`, and a family of
    /// certificates of one degree (§5.5) changes only `b`.
    pub fn prepare(&self, settings: &SdpSettings) -> Result<Prepared, SdpError> {
        let cs = settings.to_clarabel()?;
        if self.a_val.iter().any(|v| !v.is_finite()) {
            return Err(SdpError::NonFinite("constraint matrix"));
        }
        let a = self.csc_a();
        let p = CscMatrix::zeros((self.n, self.n));
        let cones = self.cones();
        let (q, b) = (&self.q, &self.b);
        let solver =
            guarded(|| DefaultSolver::new(&p, q, &a, b, &cones, cs).map_err(|e| SdpError::Setup(e.to_string())))?;
        Ok(Prepared { solver, n: self.n, m: self.b.len() })
    }
}
