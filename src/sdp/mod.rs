//! A small conic modelling layer over Clarabel (docs/design.md §4) — the only
//! place in the crate that talks to the solver.
//!
//! Clarabel solves `min qᵀx  s.t.  A x + s = b,  s ∈ K` (we never use the quadratic
//! term `P`), where `K` is a product of cones and the rows of `A` follow the cone
//! order. A [`Model`] collects
//!
//! * scalar variables ([`Model::add_var`]);
//! * **Gram blocks** `Q ⪰ 0` ([`Model::add_gram`], pattern 1, docs/design.md §4.2): one variable per
//!   upper-triangle entry holding the *raw* value `Q_ij` (`i ≤ j`), in Clarabel's svec
//!   order (column-major upper triangle, position `j(j+1)/2 + i`), plus `N(N+1)/2`
//!   PSD rows with `A = −1` (diagonal) or `A = −√2` (off-diagonal) and `b = 0`, so the
//!   slack is `s = svec(Q)`. Sides 1 and 2 use exactly equivalent cheaper cones by
//!   default ([`PsdForm`]: a nonnegative row, a 3-dimensional second-order cone).
//!   When `Q` enters a linear expression as a full symmetric sum
//!   `Σ_ij c_ij Q_ij`, the raw variable `Q_ij` (`i < j`) must get `c_ij + c_ji`
//!   ([`GramBlock::sym_factor`] gives the factor 2 for the common case `c_ij = c_ji`);
//! * **affine PSD constraints** `M0 + Σ_k x_k M_k ⪰ 0` ([`Model::add_psd_affine`],
//!   pattern 2): row `(i, j)` gets `A = −c_ij (M_k)_ij`, `b = c_ij (M0)_ij` with
//!   `c_ij = 1` on the diagonal and `√2` off it;
//! * equality rows, `≤`/`≥`/`≥ 0` rows, second-order cones, and a linear objective.
//!
//! [`Model::solve`] assembles the CSC matrix directly from row-ordered triplets (a
//! stable counting sort by column, no dense intermediate) and returns an
//! [`SdpSolution`]: status, primal `x`, duals `z`, slacks `s`, iterations and time.
//! [`Model::prepare`] keeps the set-up solver for re-solves after changing `b` or `q`.
//!
//! **A solver status is never a verdict.** Callers that need a proof (e.g.
//! [`crate::certify::sos`]) must re-check the returned point rigorously.
//!
//! Dual sign convention (Clarabel's KKT conditions): `Aᵀz + q = 0` and `z ∈ K*`, with
//! one dual per row in the order the rows were added. For an equality `Σ a x = rhs`
//! the row of `A` is `a` and `b = rhs`.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettings, DefaultSolver, IPSolver, SolverStatus, SupportedConeT};
use serde::{Deserialize, Serialize};
use std::fmt;

#[cfg(test)]
mod tests;

/// `√2`, the svec scaling of off-diagonal entries.
pub const SQRT2: f64 = std::f64::consts::SQRT_2;

/// Errors of the modelling layer. No input makes this module panic.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SdpError {
    /// A coefficient, constant or setting was NaN or infinite.
    #[error("non-finite number in {0}")]
    NonFinite(&'static str),
    /// A variable handle does not belong to this model.
    #[error("variable {var} out of range (model has {n} variables)")]
    VarOutOfRange {
        /// The offending index.
        var: usize,
        /// Number of variables in the model.
        n: usize,
    },
    /// A cone was given an impossible size.
    #[error("bad cone size: {0}")]
    BadConeSize(String),
    /// A setting is out of its valid range.
    #[error("bad setting: {0}")]
    BadSettings(&'static str),
    /// Clarabel refused the problem data or settings.
    #[error("solver setup failed: {0}")]
    Setup(String),
    /// Clarabel panicked (caught; reported instead of unwinding through the caller).
    #[error("solver panicked: {0}")]
    Panicked(String),
}

/// A scalar variable of a [`Model`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Var(usize);

impl Var {
    /// Index into the primal vector `x`.
    pub fn index(self) -> usize {
        self.0
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

/// Number of entries of the upper triangle of a side-`n` matrix: `n(n+1)/2`.
pub fn svec_len(n: usize) -> usize {
    n * (n + 1) / 2
}

/// Position of entry `(i, j)` (either order) in column-major upper-triangle order:
/// `j(j+1)/2 + i` for `i ≤ j` — Clarabel's svec layout.
pub fn svec_index(i: usize, j: usize) -> usize {
    let (i, j) = if i <= j { (i, j) } else { (j, i) };
    j * (j + 1) / 2 + i
}

/// Side `n` of a matrix whose upper triangle has `len` entries, if `len` is triangular.
pub fn svec_side(len: usize) -> Option<usize> {
    let mut n = 0usize;
    while svec_len(n) < len {
        n += 1;
    }
    (svec_len(n) == len).then_some(n)
}

/// Raw upper triangle (no scaling) of a square matrix, column-major: the layout of a
/// [`GramBlock`]'s variables. Only the upper triangle of `m` is read.
pub fn pack_upper(m: &[Vec<f64>]) -> Vec<f64> {
    let n = m.len();
    let mut v = Vec::with_capacity(svec_len(n));
    for j in 0..n {
        v.extend(m.iter().take(j + 1).map(|row| row.get(j).copied().unwrap_or(f64::NAN)));
    }
    v
}

/// Inverse of [`pack_upper`]: the full symmetric matrix. `None` if `v.len()` is not
/// triangular.
pub fn unpack_upper(v: &[f64]) -> Option<Vec<Vec<f64>>> {
    let n = svec_side(v.len())?;
    let mut m = vec![vec![0.0; n]; n];
    for j in 0..n {
        for i in 0..=j {
            let x = v[svec_index(i, j)];
            m[i][j] = x;
            m[j][i] = x;
        }
    }
    Some(m)
}

/// Clarabel's scaled svec of a symmetric matrix: upper triangle column-major,
/// off-diagonal entries times `√2`, so `⟨svec A, svec B⟩ = tr(AB)`.
pub fn pack_svec(m: &[Vec<f64>]) -> Vec<f64> {
    let mut v = pack_upper(m);
    let n = m.len();
    for j in 0..n {
        for i in 0..j {
            v[svec_index(i, j)] *= SQRT2;
        }
    }
    v
}

/// Inverse of [`pack_svec`] (divides off-diagonal entries by `√2`).
pub fn unpack_svec(v: &[f64]) -> Option<Vec<Vec<f64>>> {
    let n = svec_side(v.len())?;
    let mut raw = v.to_vec();
    for j in 0..n {
        for i in 0..j {
            raw[svec_index(i, j)] /= SQRT2;
        }
    }
    unpack_upper(&raw)
}

/// How a PSD constraint of side `N` is handed to Clarabel. All forms are exactly
/// equivalent to `M ⪰ 0`; the small ones avoid Clarabel's dense PSD-cone machinery
/// (eigen-decompositions and BLAS calls every iteration), which dominates the cost of
/// the tiny SDPs of eq. (15).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum PsdForm {
    /// `PSDTriangleConeT(N)`, rows `svec(M)` (√2 off the diagonal): any `N`.
    Triangle,
    /// `N = 2`: `(M00 + M11, M00 − M11, 2·M01) ∈ SOC(3)`, which holds iff
    /// `M00, M11 ≥ 0` and `M00·M11 ≥ M01²`, i.e. iff `M ⪰ 0`.
    Soc,
    /// `N = 1`: one nonnegative row `M00 ≥ 0`.
    Nonneg,
}

/// The cone rows of one PSD constraint `M ⪰ 0` (from [`Model::add_gram`] or
/// [`Model::add_psd_affine`]), with its [`PsdForm`]. In every form the duals `z` of
/// the rows and the dual matrix `Z` returned by [`PsdBlock::dual_matrix`] satisfy
/// `zᵀs = ⟨Z, M⟩` and `Z ⪰ 0`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PsdBlock {
    rows: Rows,
    side: usize,
    form: PsdForm,
}

impl PsdBlock {
    /// The cone rows.
    pub fn rows(&self) -> Rows {
        self.rows
    }
    /// Matrix side `N`.
    pub fn side(&self) -> usize {
        self.side
    }
    /// How the constraint was encoded.
    pub fn form(&self) -> PsdForm {
        self.form
    }

    /// Decodes a matrix from per-row values `v` (duals `z` or slacks `s`). For the
    /// triangle the rows are a scaled svec; for the SOC form `(a+c, a−c, 2b)` the
    /// slack decodes to `[[a, b], [b, c]]` and the dual `(z0, z1, z2)` to
    /// `[[z0+z1, z2], [z2, z0−z1]]` (so that `zᵀs = ⟨Z, M⟩`).
    fn decode(&self, v: &[f64], dual: bool) -> Option<Vec<Vec<f64>>> {
        let v = v.get(self.rows.range())?;
        match self.form {
            PsdForm::Triangle => unpack_svec(v),
            PsdForm::Nonneg => Some(vec![vec![v[0]]]),
            PsdForm::Soc => {
                let (a, c, b) = if dual {
                    (v[0] + v[1], v[0] - v[1], v[2])
                } else {
                    (0.5 * (v[0] + v[1]), 0.5 * (v[0] - v[1]), 0.5 * v[2])
                };
                Some(vec![vec![a, b], vec![b, c]])
            }
        }
    }

    /// The dual matrix `Z ⪰ 0` from the dual vector `z` of a solution.
    pub fn dual_matrix(&self, z: &[f64]) -> Option<Vec<Vec<f64>>> {
        self.decode(z, true)
    }

    /// The slack matrix `M(x)` from the slack vector `s` of a solution.
    pub fn slack_matrix(&self, s: &[f64]) -> Option<Vec<Vec<f64>>> {
        self.decode(s, false)
    }
}

/// A PSD Gram block `Q ⪰ 0` of a [`Model`] (pattern 1, docs/design.md §4.2).
///
/// Its `N(N+1)/2` variables hold the raw upper-triangle entries `Q_ij`, `i ≤ j`, in
/// svec order (`svec_index(i, j)`); its cone rows are described by [`GramBlock::psd`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GramBlock {
    first: usize,
    side: usize,
    psd: PsdBlock,
}

impl GramBlock {
    /// Matrix side `N`.
    pub fn side(&self) -> usize {
        self.side
    }

    /// The variable holding the raw entry `Q_ij` (`(i, j)` in either order).
    ///
    /// # Panics
    /// If `i` or `j` is not below [`GramBlock::side`] (a caller bug, not input).
    pub fn var(&self, i: usize, j: usize) -> Var {
        assert!(i < self.side && j < self.side, "Gram index out of range");
        Var(self.first + svec_index(i, j))
    }

    /// Coefficient multiplier of raw entry `(i, j)` in a full symmetric sum
    /// `Σ_ij c Q_ij` with `c_ij = c_ji`: 1 on the diagonal, 2 off it.
    pub fn sym_factor(i: usize, j: usize) -> f64 {
        if i == j {
            1.0
        } else {
            2.0
        }
    }

    /// The cone rows of `Q ⪰ 0`.
    pub fn psd(&self) -> PsdBlock {
        self.psd
    }

    /// The raw upper-triangle values from a primal vector, in svec order.
    pub fn raw<'a>(&self, x: &'a [f64]) -> Option<&'a [f64]> {
        x.get(self.first..self.first + svec_len(self.side))
    }

    /// The full symmetric matrix `Q` from a primal vector.
    pub fn matrix(&self, x: &[f64]) -> Option<Vec<Vec<f64>>> {
        unpack_upper(self.raw(x)?)
    }

    /// The dual matrix `Z ⪰ 0` of the block's cone.
    pub fn dual_matrix(&self, z: &[f64]) -> Option<Vec<Vec<f64>>> {
        self.psd.dual_matrix(z)
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ConeKind {
    Zero,
    Nonneg,
    Soc,
    Psd(usize),
}

/// Default gap and feasibility tolerance (Clarabel's own default). Tighter makes
/// the returned point more accurate (and the solve slower); it proves nothing either
/// way — callers re-check.
pub const DEFAULT_TOL: f64 = 1e-8;

/// Default iteration limit (Clarabel's own default). Hitting it gives
/// [`SdpStatus::MaxIterations`], never a usable point.
pub const DEFAULT_MAX_ITER: u32 = 200;

/// Solver settings. Defaults: [`DEFAULT_TOL`], [`DEFAULT_MAX_ITER`], no
/// time limit, presolve and chordal decomposition **off** (they only cost time on the
/// small dense problems of this crate and forbid data updates), equilibration on.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SdpSettings {
    /// Absolute duality-gap tolerance.
    pub tol_gap_abs: f64,
    /// Relative duality-gap tolerance.
    pub tol_gap_rel: f64,
    /// Feasibility tolerance.
    pub tol_feas: f64,
    /// Iteration limit.
    pub max_iter: u32,
    /// Time limit in seconds (`f64::INFINITY`: none).
    pub time_limit: f64,
    /// Clarabel's presolve.
    pub presolve: bool,
    /// Clarabel's chordal decomposition of PSD cones.
    pub chordal_decomposition: bool,
    /// Clarabel's Ruiz equilibration.
    pub equilibrate: bool,
}

impl Default for SdpSettings {
    fn default() -> Self {
        SdpSettings {
            tol_gap_abs: DEFAULT_TOL,
            tol_gap_rel: DEFAULT_TOL,
            tol_feas: DEFAULT_TOL,
            max_iter: DEFAULT_MAX_ITER,
            time_limit: f64::INFINITY,
            presolve: false,
            chordal_decomposition: false,
            equilibrate: true,
        }
    }
}

impl SdpSettings {
    fn to_clarabel(&self) -> Result<DefaultSettings<f64>, SdpError> {
        for (v, name) in [
            (self.tol_gap_abs, "tol_gap_abs must be finite and > 0"),
            (self.tol_gap_rel, "tol_gap_rel must be finite and > 0"),
            (self.tol_feas, "tol_feas must be finite and > 0"),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(SdpError::BadSettings(name));
            }
        }
        if self.time_limit.is_nan() || self.time_limit <= 0.0 {
            return Err(SdpError::BadSettings("time_limit must be > 0"));
        }
        Ok(DefaultSettings {
            tol_gap_abs: self.tol_gap_abs,
            tol_gap_rel: self.tol_gap_rel,
            tol_feas: self.tol_feas,
            max_iter: self.max_iter,
            time_limit: self.time_limit,
            verbose: false,
            presolve_enable: self.presolve,
            chordal_decomposition_enable: self.chordal_decomposition,
            equilibrate_enable: self.equilibrate,
            ..DefaultSettings::default()
        })
    }
}

/// Solver status, mirroring Clarabel's `SolverStatus`. Only [`SdpStatus::Solved`] and
/// [`SdpStatus::AlmostSolved`] come with a usable point; even then the point is just a
/// floating-point approximation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum SdpStatus {
    /// The solver did not run.
    Unsolved,
    /// Converged to the requested tolerances.
    Solved,
    /// Converged to reduced tolerances.
    AlmostSolved,
    /// Certificate of primal infeasibility.
    PrimalInfeasible,
    /// Certificate of dual infeasibility (primal unbounded).
    DualInfeasible,
    /// Primal infeasibility to reduced tolerances.
    AlmostPrimalInfeasible,
    /// Dual infeasibility to reduced tolerances.
    AlmostDualInfeasible,
    /// Iteration limit.
    MaxIterations,
    /// Time limit.
    MaxTime,
    /// Numerical failure.
    NumericalError,
    /// No progress.
    InsufficientProgress,
    /// A callback stopped the solver.
    CallbackTerminated,
}

impl SdpStatus {
    /// Whether the status comes with an (approximate) optimal point.
    pub fn has_solution(self) -> bool {
        matches!(self, SdpStatus::Solved | SdpStatus::AlmostSolved)
    }
}

impl From<SolverStatus> for SdpStatus {
    fn from(s: SolverStatus) -> Self {
        match s {
            SolverStatus::Unsolved => SdpStatus::Unsolved,
            SolverStatus::Solved => SdpStatus::Solved,
            SolverStatus::AlmostSolved => SdpStatus::AlmostSolved,
            SolverStatus::PrimalInfeasible => SdpStatus::PrimalInfeasible,
            SolverStatus::DualInfeasible => SdpStatus::DualInfeasible,
            SolverStatus::AlmostPrimalInfeasible => SdpStatus::AlmostPrimalInfeasible,
            SolverStatus::AlmostDualInfeasible => SdpStatus::AlmostDualInfeasible,
            SolverStatus::MaxIterations => SdpStatus::MaxIterations,
            SolverStatus::MaxTime => SdpStatus::MaxTime,
            SolverStatus::NumericalError => SdpStatus::NumericalError,
            SolverStatus::InsufficientProgress => SdpStatus::InsufficientProgress,
            SolverStatus::CallbackTerminated => SdpStatus::CallbackTerminated,
        }
    }
}

impl fmt::Display for SdpStatus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(self, f)
    }
}

/// What [`Model::solve`] returns.
#[derive(Clone, Debug, PartialEq)]
pub struct SdpSolution {
    /// Solver status.
    pub status: SdpStatus,
    /// Primal variables, indexed by [`Var::index`].
    pub x: Vec<f64>,
    /// Duals, one per row in the order rows were added (`Aᵀz + q = 0`, `z ∈ K*`).
    pub z: Vec<f64>,
    /// Slacks `s = b − Ax`, one per row.
    pub s: Vec<f64>,
    /// Primal objective `qᵀx`.
    pub obj_primal: f64,
    /// Dual objective.
    pub obj_dual: f64,
    /// Interior-point iterations.
    pub iterations: u32,
    /// Time in seconds as reported by Clarabel (its own timers).
    pub solve_time: f64,
}

impl SdpSolution {
    /// Value of a variable.
    pub fn value(&self, v: Var) -> f64 {
        self.x.get(v.0).copied().unwrap_or(f64::NAN)
    }
    /// Duals of a row range (empty if out of range).
    pub fn duals(&self, rows: Rows) -> &[f64] {
        self.z.get(rows.range()).unwrap_or(&[])
    }
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
    fn csc_a(&self) -> CscMatrix<f64> {
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

/// Runs `f`, turning a panic inside Clarabel into [`SdpError::Panicked`].
fn guarded<T>(f: impl FnOnce() -> Result<T, SdpError>) -> Result<T, SdpError> {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)) {
        Ok(r) => r,
        Err(payload) => {
            let msg = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            Err(SdpError::Panicked(msg))
        }
    }
}

/// A set-up Clarabel solver for one [`Model`] (see [`Model::prepare`]). Every
/// [`Prepared::solve`] starts from Clarabel's default initial point, but Clarabel
/// keeps some internal state between solves, so a re-solve agrees with a fresh
/// solve of the updated model only to solver tolerance, not bit for bit. After an
/// `Err` the solver may be unusable; drop it.
pub struct Prepared {
    solver: DefaultSolver<f64>,
    n: usize,
    m: usize,
}

impl fmt::Debug for Prepared {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Prepared").field("n", &self.n).field("m", &self.m).finish()
    }
}

impl Prepared {
    /// Number of variables.
    pub fn num_vars(&self) -> usize {
        self.n
    }

    /// Number of rows.
    pub fn num_rows(&self) -> usize {
        self.m
    }

    /// Replaces the right-hand side `b` (one entry per row, in the model's row order:
    /// an equality's `rhs`, an affine expression's constant, …, exactly as the model
    /// stored it; see [`Model::rhs`]).
    pub fn update_b(&mut self, b: &[f64]) -> Result<(), SdpError> {
        if b.len() != self.m {
            return Err(SdpError::BadConeSize(format!("b has {} entries, model has {} rows", b.len(), self.m)));
        }
        if b.iter().any(|v| !v.is_finite()) {
            return Err(SdpError::NonFinite("right-hand side"));
        }
        let solver = &mut self.solver;
        guarded(|| solver.update_b(&b.to_vec()).map_err(|e| SdpError::Setup(e.to_string())))
    }

    /// Replaces the objective vector `q` (one entry per variable).
    pub fn update_q(&mut self, q: &[f64]) -> Result<(), SdpError> {
        if q.len() != self.n {
            return Err(SdpError::BadConeSize(format!("q has {} entries, model has {} variables", q.len(), self.n)));
        }
        if q.iter().any(|v| !v.is_finite()) {
            return Err(SdpError::NonFinite("objective"));
        }
        let solver = &mut self.solver;
        guarded(|| solver.update_q(&q.to_vec()).map_err(|e| SdpError::Setup(e.to_string())))
    }

    /// Solves (from Clarabel's default start).
    pub fn solve(&mut self) -> Result<SdpSolution, SdpError> {
        let solver = &mut self.solver;
        guarded(|| {
            solver.solve();
            let sol = &solver.solution;
            Ok(SdpSolution {
                status: sol.status.into(),
                x: sol.x.clone(),
                z: sol.z.clone(),
                s: sol.s.clone(),
                obj_primal: sol.obj_val,
                obj_dual: sol.obj_val_dual,
                iterations: sol.iterations,
                solve_time: sol.solve_time,
            })
        })
    }
}
