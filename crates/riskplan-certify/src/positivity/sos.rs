//! The SOS certificate of eq. (15) (`SOS_Cond`) for one univariate constraint on
//! [0, 1], solved with Clarabel and then **re-checked rigorously** (docs/design.md
//! §5.4–§5.6).
//!
//! Input: `p(τ)`, the restriction of a contour constraint to a trajectory piece with
//! the piece's time interval already rescaled to τ ∈ [0, 1] (§5.1), as a
//! [`UPoly<Interval>`] whose coefficients are outward enclosures of the exact ones.
//!
//! # Method
//!
//! 1. **Markov–Lukács, single form (§5.4).** `p ≥ 0` on [0, 1] iff
//!    `p = σ0 + τ(1−τ)σ1` with `σ0 = v_{e0}ᵀ Q0 v_{e0}`, `σ1 = v_{e0−1}ᵀ Q1 v_{e0−1}`,
//!    `Q0, Q1 ⪰ 0`, `v_e = (1, τ, …, τ^e)` and `e0 = ⌈n/2⌉` (also exact for odd `n`).
//! 2. **Margin maximisation (§5.5).** Normalise `p ← p/S`, `S = max_k |b_k|` over the
//!    Bernstein coefficients of the coefficient midpoints (just a scale, so `|p| ≲ 1`
//!    on [0, 1] and tolerances are relative; kept in the [`Certificate`]). Then
//!    `max γ  s.t.  p − γ = σ0 + τ(1−τ)σ1`: at the optimum `γ* = min_{[0,1]} p` (no
//!    relaxation gap for univariate polynomials). Equality row `k = 0..2e0` reads
//!    `γ[k=0] + [σ0]_k + [σ1]_{k−1} − [σ1]_{k−2} = p_k`, with `[σ]_k = Σ_{i+j=k} Q_ij`
//!    (full symmetric sum: raw `Q_ij`, `i < j`, gets coefficient 2).
//! 3. **Sound decision (§5.6).** A solver status is never a verdict:
//!    * status other than `Solved`/`AlmostSolved` → `Undecided(Solver(status))`;
//!    * `γ̂ ≤ ε_acc` ([`EPS_ACC`]) → search for a witness (interval Horner at the dual
//!      estimate `τ* = y1/y0` of the minimiser, Newton-refined, at 0, 1 and on a grid):
//!      an enclosure with `hi ≤ 0` proves `Unsafe`, else `Undecided(MarginTooSmall)`;
//!    * `γ̂ > ε_acc` → the rigorous floating-point re-check below ([`recheck`]);
//!      `Safe` iff the proven lower bound `LB > 0`, else
//!      `Undecided(CertificateRejected)`.
//!
//! # The rigorous lower bound
//!
//! Let `s0, s1` be the sides of `Q̂0, Q̂1` (`e0+1` and `e0` here) and define, in
//! outward-rounded interval arithmetic, the residuals
//! `r_k = p_k − γ̂[k=0] − [σ̂0]_k − [σ̂1]_{k−1} + [σ̂1]_{k−2}` for `k = 0..K`,
//! `K = max(n, 2(s0−1), 2 s1)`. These are identities of polynomials, so for every τ
//!
//! ```text
//! p(τ) = γ̂ + v0(τ)ᵀ Q̂0 v0(τ) + τ(1−τ) v1(τ)ᵀ Q̂1 v1(τ) + Σ_k r_k τ^k     (exact)
//! ```
//!
//! On [0, 1]:
//! * `vᵀ Q̂ v ≥ λmin(Q̂)·‖v‖² ≥ min(λ, 0)·s` for any proven `λ ≤ λmin(Q̂)`, because
//!   `‖v_e(τ)‖² = Σ_{i≤e} τ^{2i} ≤ e + 1 = s` (if `λ ≥ 0` the term is `≥ 0`);
//! * `0 ≤ τ(1−τ) ≤ 1/4`, so `τ(1−τ)·v1ᵀQ̂1v1 ≥ τ(1−τ)·min(λ1, 0)·s1 ≥ min(λ1, 0)·s1/4`;
//! * `|Σ r_k τ^k| ≤ Σ |r_k| τ^k ≤ Σ_k max|r_k|`.
//!
//! Hence `min_{[0,1]} p ≥ LB = γ̂ + min(λ0,0)·s0 + min(λ1,0)·s1/4 − Σ_k max|r_k|`,
//! with `s0 = e0+1`, `s1 = e0` as in §5.6. `LB` is itself evaluated with outward
//! rounding and its lower end is used. The eigenvalue bounds are proven: take the
//! float eigenvalue from nalgebra minus a slack ([`EIG_SLACK_REL`]) and show
//! `Q̂ − λI ≻ 0` by an interval `LDLᵀ` whose pivots all have positive lower ends
//! (inclusion monotonicity: the exact pivots are inside, so every leading principal
//! minor is positive); Gershgorin (rounded down) is the fallback. In the normalised
//! units the margin is `LB`; the reported margin is `LB·S` rounded down.
//!
//! Nothing in this module panics on any input; non-finite data gives
//! `Undecided(NonFinite)`.

use crate::positivity::verdict::{Undecided, Verdict, Witness};
use nalgebra::DMatrix;
use riskplan_math::poly::{Interval, UPoly};
use riskplan_math::sdp::{GramBlock, Model, Prepared, Rows, SdpError, SdpSettings, SdpSolution, SdpStatus, Var};
use serde::{Deserialize, Serialize};
use std::cell::RefCell;

/// Default acceptance threshold `ε_acc` on the solver's margin `γ̂`, **relative**
/// (the polynomial is normalised by its Bernstein scale, so `|p| ≲ 1`). With
/// `γ̂ ≤ ε_acc` the piece is never certified, whatever the re-check says; a larger
/// value is more conservative (fewer `Safe`), it never affects soundness, which rests
/// on the re-check alone.
pub const EPS_ACC: f64 = 1e-7;

/// Relative slack of the eigenvalue lower bound: `λ = λ̂ − δ` with
/// `δ = EIG_SLACK_REL·N·(1 + ‖Q̂‖_F)` (§5.6). Larger is more conservative (a lower
/// `λ`, slightly smaller `LB`); soundness does not depend on it because `Q̂ − λI ≻ 0`
/// is then *proven* by interval `LDLᵀ`. If that proof fails the slack is multiplied
/// by [`EIG_SLACK_GROWTH`] up to [`EIG_SLACK_TRIES`] times.
pub const EIG_SLACK_REL: f64 = 1e-12;
/// Growth factor of the eigenvalue slack between attempts (see [`EIG_SLACK_REL`]).
pub const EIG_SLACK_GROWTH: f64 = 1e3;
/// Number of slack attempts before falling back to Gershgorin (see [`EIG_SLACK_REL`]).
pub const EIG_SLACK_TRIES: usize = 3;

/// Default number of grid intervals for the witness search (`witness_grid + 1`
/// points). Candidates only propose points; the interval evaluation decides, so the
/// grid size affects how often `Unsafe` is found, never soundness.
pub const DEFAULT_WITNESS_GRID: usize = 32;

/// Newton steps used to refine a witness candidate towards a local minimum of `p`
/// (floating point; only proposes points).
pub const WITNESS_NEWTON_STEPS: usize = 12;

/// Default largest degree sent to the SDP; above it the answer is
/// `Undecided(Solver(..))` (conservative: never `Safe`).
pub const DEFAULT_MAX_DEGREE: usize = 40;

/// Largest Gram side [`recheck`] accepts (the check is `O(N³)`); larger certificates
/// are rejected (conservative).
pub const MAX_CERT_SIDE: usize = 256;

/// Settings of `certify`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SosSettings {
    /// Acceptance threshold on the normalised margin `γ̂` (default `EPS_ACC`).
    pub eps_acc: f64,
    /// Grid intervals of the witness search (default `DEFAULT_WITNESS_GRID`).
    pub witness_grid: usize,
    /// Largest degree sent to the solver (default `DEFAULT_MAX_DEGREE`).
    pub max_degree: usize,
    /// Solver settings.
    pub sdp: SdpSettings,
    /// Keep one prepared Clarabel solver per `e0`, settings and thread, and only
    /// update its right-hand side (skips the solver setup, ≈ 15% of a degree-4
    /// certificate). Off by default: the answers then agree with a fresh solve only to
    /// solver tolerance (Clarabel keeps some state between solves), so a result would
    /// depend on what the thread certified before. Soundness is unaffected either
    /// way: every verdict comes from the rigorous re-check.
    pub reuse_solver: bool,
    /// The paths without an interior-point solve first (default on): the certificate
    /// constructed from Bernstein coefficients (`construct`; for a quadratic in closed
    /// form), re-checked exactly like a solver's; and, when none is built, a witness
    /// point where `p ≤ 0` from the Bernstein subdivision (an unsafe piece needs no
    /// SDP). Otherwise the margin SDP runs as before. Off: always the SDP (its margin is
    /// the largest `γ`, about twice the constructed one).
    #[serde(default = "default_construct")]
    pub construct: bool,
}

fn default_construct() -> bool {
    true
}

impl Default for SosSettings {
    fn default() -> Self {
        SosSettings {
            eps_acc: EPS_ACC,
            witness_grid: DEFAULT_WITNESS_GRID,
            max_degree: DEFAULT_MAX_DEGREE,
            sdp: SdpSettings::default(),
            reuse_solver: false,
            construct: true,
        }
    }
}

/// A floating-point Markov–Lukács certificate (§5.6): `p/scale − gamma` is claimed
/// to equal `v0ᵀ q0 v0 + τ(1−τ) v1ᵀ q1 v1` up to small residuals. It proves nothing
/// by itself; [`recheck`] turns it into a verdict independently of the solver.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Certificate {
    /// Normalisation `S` (`p` was divided by it).
    pub scale: f64,
    /// Solver margin `γ̂` in normalised units.
    pub gamma: f64,
    /// Gram matrix of `σ0` (full symmetric, side `e0 + 1`), basis `1, τ, …, τ^{e0}`.
    pub q0: Vec<Vec<f64>>,
    /// Gram matrix of `σ1` (full symmetric, side `e0`), basis `1, τ, …, τ^{e0−1}`.
    pub q1: Vec<Vec<f64>>,
    /// Status the solver reported (informational only).
    pub solver_status: SdpStatus,
    /// Interior-point iterations.
    pub iterations: u32,
    /// Built from Bernstein coefficients without a solver ([`construct`]; then
    /// `solver_status` is `Unsolved` and `iterations` 0).
    #[serde(default)]
    pub constructed: bool,
}

/// The result of [`certify`]: the verdict, and the certificate when the solver
/// returned a point (`None` for degree ≤ 1, decided directly, and for solver
/// failures). `Undecided(MarginTooSmall(m))` carries `m = γ̂·S`, the solver's
/// estimate of `min p` (it may be ≤ 0 when no witness could be proven).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SosOutcome {
    /// The sound verdict.
    pub verdict: Verdict,
    /// The solver's certificate, for [`recheck`] by a third party.
    pub certificate: Option<Certificate>,
}

impl SosOutcome {
    fn bare(verdict: Verdict) -> Self {
        SosOutcome { verdict, certificate: None }
    }
}

/// Certifies `p > 0` on [0, 1] by eq. (15) (see the module docs). Never panics.
pub fn certify(p: &UPoly<Interval>, settings: &SosSettings) -> SosOutcome {
    let c = p.coeffs();
    if c.iter().any(|i| !(i.lo.is_finite() && i.hi.is_finite())) {
        return SosOutcome::bare(Verdict::Undecided(Undecided::NonFinite));
    }
    let n = p.degree();
    if n <= 1 {
        return SosOutcome::bare(decide_linear(p));
    }
    if n > settings.max_degree {
        return SosOutcome::bare(Verdict::Undecided(Undecided::Solver(format!(
            "degree {n} exceeds max_degree {}",
            settings.max_degree
        ))));
    }
    let mids: Vec<f64> = c.iter().map(Interval::mid).collect();
    let scale = bernstein_scale(&mids);
    let Some(inv) = inverse_enclosure(scale) else {
        if scale == 0.0 {
            // every coefficient straddles 0 around a zero midpoint: at most a witness
            return SosOutcome::bare(witness_or(p, &[], settings.witness_grid, 0.0));
        }
        return SosOutcome::bare(Verdict::Undecided(Undecided::NonFinite));
    };
    let pn: Vec<Interval> = c.iter().map(|&ci| ci * inv).collect();
    let rhs: Vec<f64> = pn.iter().map(Interval::mid).collect();
    if settings.construct {
        if let Some(done) = without_solve(p, &pn, &rhs, scale, settings) {
            return done;
        }
    }
    solved(p, &pn, &rhs, scale, settings)
}

/// The verdict without the interior-point solve, when there is one (docs/design.md
/// §5.11): a constructed certificate that proves `p > 0`, or a proven point where
/// `p ≤ 0` (no certificate can exist then, §5.5). `pn`: p's coefficients divided by
/// `scale`, `rhs` their midpoints.
fn without_solve(
    p: &UPoly<Interval>,
    pn: &[Interval],
    rhs: &[f64],
    scale: f64,
    settings: &SosSettings,
) -> Option<SosOutcome> {
    let built = if p.degree() == 2 { construct::quadratic_certificate(rhs, scale, settings.eps_acc) } else { None };
    if let Some(cert) = built.or_else(|| construct::bernstein_certificate(rhs, scale, settings.eps_acc)) {
        if let Ok(lb) = lower_bound(pn, &cert) {
            if let v @ Verdict::Safe { .. } = safe_if_positive(lb, scale) {
                return Some(SosOutcome { verdict: v, certificate: Some(cert) });
            }
        }
    }
    // the Bernstein subdivision finds a point where p dips below zero (its witnesses are
    // interval enclosures of p at a node's end) in about a microsecond, the SDP takes
    // hundreds; its other verdicts are not SOS proofs and are not used
    match crate::positivity::bernstein::check_interval_coeffs(
        p.coeffs(),
        crate::positivity::bernstein::DEFAULT_MAX_DEPTH,
    ) {
        Verdict::Unsafe(w) => Some(SosOutcome::bare(Verdict::Unsafe(w))),
        _ => None,
    }
}

/// The verdict of the margin SDP (eq. (15) on Clarabel), its certificate re-checked
/// rigorously (§5.4–§5.6); where the margin is not positive, a witness from the duals.
fn solved(p: &UPoly<Interval>, pn: &[Interval], rhs: &[f64], scale: f64, settings: &SosSettings) -> SosOutcome {
    let n = p.degree();
    let e0 = n.div_ceil(2);
    let (sol, layout) = match solve_margin_sdp(rhs, e0, settings) {
        Ok(r) => r,
        Err(e) => return SosOutcome::bare(Verdict::Undecided(Undecided::Solver(e.to_string()))),
    };
    let Layout { gamma, eq_rows, g0, g1 } = layout;
    if !sol.status.has_solution() {
        return SosOutcome::bare(Verdict::Undecided(Undecided::Solver(sol.status.to_string())));
    }
    let gamma_hat = sol.value(gamma);
    let (Some(q0), Some(q1)) = (g0.matrix(&sol.x), g1.matrix(&sol.x)) else {
        return SosOutcome::bare(Verdict::Undecided(Undecided::Solver("solution has the wrong size".into())));
    };
    if !gamma_hat.is_finite() || q0.iter().chain(&q1).flatten().any(|v| !v.is_finite()) {
        return SosOutcome::bare(Verdict::Undecided(Undecided::Solver(format!(
            "{} with a non-finite point",
            sol.status
        ))));
    }
    let cert = Certificate {
        scale,
        gamma: gamma_hat,
        q0,
        q1,
        solver_status: sol.status,
        iterations: sol.iterations,
        constructed: false,
    };

    let verdict = if gamma_hat > settings.eps_acc {
        match lower_bound(pn, &cert) {
            Ok(lb) => safe_if_positive(lb, scale),
            Err(reason) => Verdict::Undecided(Undecided::CertificateRejected(reason)),
        }
    } else {
        // τ* = y1/y0 from the duals of the matching rows (moments of a measure on the
        // minimisers, §5.5); any overall sign cancels.
        let y = sol.duals(eq_rows);
        let mut cands = Vec::with_capacity(2);
        if let (Some(&y0), Some(&y1)) = (y.first(), y.get(1)) {
            let t = y1 / y0;
            if t.is_finite() {
                cands.push(t.clamp(0.0, 1.0));
            }
        }
        witness_or(p, &cands, settings.witness_grid, gamma_hat * scale)
    };
    SosOutcome { verdict, certificate: Some(cert) }
}

/// Re-verifies a certificate for `p` independently of the solver: `Safe { margin }`
/// iff the rigorous lower bound of the module docs is positive, otherwise
/// `Undecided(CertificateRejected)` (or `NonFinite`). Never `Unsafe`: a certificate
/// cannot refute. This is a pure proof check; it does not apply `ε_acc`.
pub fn recheck(p: &UPoly<Interval>, cert: &Certificate) -> Verdict {
    let c = p.coeffs();
    if c.iter().any(|i| !(i.lo.is_finite() && i.hi.is_finite())) {
        return Verdict::Undecided(Undecided::NonFinite);
    }
    let Some(inv) = inverse_enclosure(cert.scale) else {
        return Verdict::Undecided(Undecided::CertificateRejected(format!("bad scale {}", cert.scale)));
    };
    let pn: Vec<Interval> = c.iter().map(|&ci| ci * inv).collect();
    match lower_bound(&pn, cert) {
        Ok(lb) => safe_if_positive(lb, cert.scale),
        Err(reason) => Verdict::Undecided(Undecided::CertificateRejected(reason)),
    }
}

/// `Safe { margin: LB·S }` (rounded down) when that is positive.
fn safe_if_positive(lb: f64, scale: f64) -> Verdict {
    if lb > 0.0 {
        let margin = (Interval::point(lb) * Interval::point(scale)).lo;
        if margin > 0.0 {
            return Verdict::Safe { margin };
        }
        return Verdict::Undecided(Undecided::CertificateRejected(format!("margin {lb:e} underflows")));
    }
    Verdict::Undecided(Undecided::CertificateRejected(format!("lower bound {lb:e} ≤ 0")))
}

/// An enclosure of `1/s`, if `s` is a finite positive float with a finite,
/// nonzero reciprocal. Division is correctly rounded, so one ulp each way encloses.
#[allow(clippy::incompatible_msrv)] // f64::next_up (1.86), as in poly::interval
fn inverse_enclosure(s: f64) -> Option<Interval> {
    if !(s.is_finite() && s > 0.0) {
        return None;
    }
    let r = 1.0 / s;
    if !(r.is_finite() && r > 0.0) {
        return None;
    }
    Some(Interval::new(r.next_down(), r.next_up()))
}

/// `S = max_k |b_k|` over the Bernstein coefficients on [0, 1] of the polynomial with
/// coefficients `a` (§5.3): `b_k = Σ_{i≤k} C(k,i)/C(n,i)·a_i`. Floating point: it is
/// only a scale.
pub fn bernstein_scale(a: &[f64]) -> f64 {
    if a.is_empty() {
        return 0.0;
    }
    construct::bernstein_coefficients(a).iter().fold(0.0, |s: f64, b| s.max(b.abs()))
}

/// Degree ≤ 1 directly: `p(τ) = (1−τ)p(0) + τp(1)`, so `min p = min(p(0), p(1))`.
fn decide_linear(p: &UPoly<Interval>) -> Verdict {
    if p.is_zero() {
        return Verdict::Unsafe(Witness { tau: 0.0, value: 0.0 });
    }
    let at0 = p.coeff(0);
    let at1 = if p.degree() == 0 { at0 } else { at0 + p.coeff(1) };
    if at0.lo > 0.0 && at1.lo > 0.0 {
        return Verdict::Safe { margin: at0.lo.min(at1.lo) };
    }
    if at0.hi <= 0.0 {
        return Verdict::Unsafe(Witness { tau: 0.0, value: at0.mid() });
    }
    if at1.hi <= 0.0 {
        return Verdict::Unsafe(Witness { tau: 1.0, value: at1.mid() });
    }
    Verdict::Undecided(Undecided::MarginTooSmall(at0.mid().min(at1.mid())))
}

/// Where the pieces of the §5.5 SDP live in a [`Model`].
#[derive(Clone, Copy, Debug)]
struct Layout {
    gamma: Var,
    eq_rows: Rows,
    g0: GramBlock,
    g1: GramBlock,
}

/// A prepared §5.5 SDP for one `e0` and one set of solver settings; only `b` (the
/// normalised coefficients) changes between polynomials of the same degree.
struct CachedSdp {
    e0: usize,
    settings: SdpSettings,
    prepared: Prepared,
    layout: Layout,
    b: Vec<f64>,
}

/// Most prepared SDPs kept per thread (one per `e0`/settings pair in practice).
const SOLVER_CACHE_LEN: usize = 8;

thread_local! {
    static SOLVER_CACHE: RefCell<Vec<CachedSdp>> = const { RefCell::new(Vec::new()) };
}

/// Solves the margin SDP for normalised coefficients `rhs`, reusing a prepared
/// solver of the same `e0` when [`SosSettings::reuse_solver`] is set (Clarabel
/// restarts from its default point on every solve, so reuse skips only the setup).
/// A failed solve drops its cache entry.
fn solve_margin_sdp(rhs: &[f64], e0: usize, settings: &SosSettings) -> Result<(SdpSolution, Layout), SdpError> {
    if !settings.reuse_solver {
        let (model, layout) = build_model(rhs, e0)?;
        return Ok((model.solve(&settings.sdp)?, layout));
    }
    SOLVER_CACHE.with(|cell| {
        let Ok(mut cache) = cell.try_borrow_mut() else {
            // re-entrant use (cannot happen today): solve without the cache
            let (model, layout) = build_model(rhs, e0)?;
            return Ok((model.solve(&settings.sdp)?, layout));
        };
        let hit = cache.iter().position(|c| c.e0 == e0 && c.settings == settings.sdp);
        let idx = match hit {
            Some(i) => {
                let c = &mut cache[i];
                // the matching rows follow the Gram blocks' cone rows
                let rows = c.layout.eq_rows;
                for (k, slot) in c.b[rows.range()].iter_mut().enumerate() {
                    *slot = rhs.get(k).copied().unwrap_or(0.0);
                }
                if let Err(e) = c.prepared.update_b(&c.b) {
                    cache.remove(i);
                    return Err(e);
                }
                i
            }
            None => {
                let (model, layout) = build_model(rhs, e0)?;
                let prepared = model.prepare(&settings.sdp)?;
                if cache.len() >= SOLVER_CACHE_LEN {
                    cache.remove(0);
                }
                cache.push(CachedSdp { e0, settings: settings.sdp.clone(), prepared, layout, b: model.rhs().to_vec() });
                cache.len() - 1
            }
        };
        match cache[idx].prepared.solve() {
            Ok(sol) => Ok((sol, cache[idx].layout)),
            Err(e) => {
                cache.remove(idx);
                Err(e)
            }
        }
    })
}

/// The margin-maximisation SDP of §5.5 for normalised coefficients `p` (`len ≤ 2e0+1`).
fn build_model(p: &[f64], e0: usize) -> Result<(Model, Layout), SdpError> {
    let (s0, s1) = (e0 + 1, e0);
    let n_rows = 2 * e0 + 1;
    let nvar = 1 + s0 * (s0 + 1) / 2 + s1 * (s1 + 1) / 2;
    let nnz = 1 + 2 * nvar + s1 * (s1 + 1);
    let mut m = Model::with_capacity(nvar, n_rows + nvar, nnz);
    let gamma = m.add_var();
    let g0 = m.add_gram(s0)?;
    let g1 = m.add_gram(s1)?;
    let mut terms: Vec<(Var, f64)> = Vec::with_capacity(s0 + 2 * s1 + 1);
    let mut first_row = None;
    for k in 0..n_rows {
        terms.clear();
        if k == 0 {
            terms.push((gamma, 1.0));
        }
        // σ0: i + j = k, i ≤ j
        push_antidiagonal(&mut terms, &g0, k, 1.0);
        // τσ1: i + j = k − 1; −τ²σ1: i + j = k − 2
        if k >= 1 {
            push_antidiagonal(&mut terms, &g1, k - 1, 1.0);
        }
        if k >= 2 {
            push_antidiagonal(&mut terms, &g1, k - 2, -1.0);
        }
        let rhs = p.get(k).copied().unwrap_or(0.0);
        let r = m.add_eq(&terms, rhs)?;
        first_row.get_or_insert(r.start);
    }
    m.set_objective(&[(gamma, -1.0)])?;
    let eq_rows = Rows { start: first_row.unwrap_or(0), len: n_rows };
    Ok((m, Layout { gamma, eq_rows, g0, g1 }))
}

/// Adds `sign·Σ_{i+j=k} Q_ij` (full symmetric sum) as raw-entry terms.
fn push_antidiagonal(terms: &mut Vec<(Var, f64)>, g: &GramBlock, k: usize, sign: f64) {
    let side = g.side();
    // i ≤ j = k − i < side
    for i in k.saturating_sub(side.saturating_sub(1))..=k / 2 {
        terms.push((g.var(i, k - i), sign * GramBlock::sym_factor(i, k - i)));
    }
}

/// Witness search (§5.6 step 2): interval Horner on the *given* `p` at the candidates,
/// their Newton refinements, 0, 1 and a grid. `Unsafe` with the most negative proven
/// value, else `Undecided(MarginTooSmall(margin))`.
fn witness_or(p: &UPoly<Interval>, cands: &[f64], grid: usize, margin: f64) -> Verdict {
    match find_witness(p, cands, grid) {
        Some(w) => Verdict::Unsafe(w),
        None => Verdict::Undecided(Undecided::MarginTooSmall(margin)),
    }
}

/// A point `τ ∈ [0, 1]` with a proven `p(τ) ≤ 0` (enclosure upper end ≤ 0), looked for
/// at `cands`, their Newton refinements, 0, 1, `grid + 1` grid points and the refined
/// grid minimum. Candidates only propose; the interval evaluation decides.
pub fn find_witness(p: &UPoly<Interval>, cands: &[f64], grid: usize) -> Option<Witness> {
    let f: Vec<f64> = p.coeffs().iter().map(Interval::mid).collect();
    let d1: Vec<f64> = f.iter().enumerate().skip(1).map(|(k, c)| k as f64 * c).collect();
    let d2: Vec<f64> = d1.iter().enumerate().skip(1).map(|(k, c)| k as f64 * c).collect();
    let mut pts: Vec<f64> = Vec::with_capacity(2 * cands.len() + grid + 4);
    for &t in cands {
        pts.push(t);
        pts.push(newton_min(&d1, &d2, t));
    }
    let mut best = (f64::INFINITY, 0.0);
    for j in 0..=grid {
        let t = if grid == 0 { 0.0 } else { j as f64 / grid as f64 };
        pts.push(t);
        let v = horner(&f, t);
        if v < best.0 {
            best = (v, t);
        }
    }
    pts.push(1.0);
    if best.0.is_finite() {
        pts.push(newton_min(&d1, &d2, best.1));
    }
    let mut found: Option<Witness> = None;
    for t in pts {
        if !(0.0..=1.0).contains(&t) {
            continue;
        }
        let v = p.eval(&Interval::point(t));
        if v.hi <= 0.0 && found.is_none_or(|w| v.mid() < w.value) {
            found = Some(Witness { tau: t, value: v.mid().min(v.hi) });
        }
    }
    found
}

fn horner(c: &[f64], t: f64) -> f64 {
    c.iter().rev().fold(0.0, |acc, &a| acc * t + a)
}

/// Newton iteration on `p'` from `t`, kept in [0, 1]; stops where `p'' ≤ 0`.
fn newton_min(d1: &[f64], d2: &[f64], mut t: f64) -> f64 {
    for _ in 0..WITNESS_NEWTON_STEPS {
        let g = horner(d1, t);
        let h = horner(d2, t);
        if h.is_nan() || h <= 0.0 {
            break;
        }
        let next = (t - g / h).clamp(0.0, 1.0);
        if !next.is_finite() || next == t {
            break;
        }
        t = next;
    }
    t
}

/// The rigorous lower bound `LB` on `min_{[0,1]} p̃` for normalised enclosures `pn`
/// (module docs). `Err` explains a malformed certificate.
fn lower_bound(pn: &[Interval], cert: &Certificate) -> Result<f64, String> {
    if !cert.gamma.is_finite() {
        return Err("non-finite gamma".into());
    }
    let s0 = check_symmetric(&cert.q0, "q0")?;
    let s1 = check_symmetric(&cert.q1, "q1")?;
    // highest power in the identity: p (n), σ0 (2(s0−1)), τ(1−τ)σ1 (2 s1)
    let kmax = pn.len().saturating_sub(1).max(2 * s0.saturating_sub(1)).max(2 * s1);
    let mut rsum = Interval::point(0.0);
    for k in 0..=kmax {
        let mut r = pn.get(k).copied().unwrap_or(Interval::point(0.0));
        if k == 0 {
            r = r - Interval::point(cert.gamma);
        }
        r = r - antidiagonal_sum(&cert.q0, k);
        if k >= 1 {
            r = r - antidiagonal_sum(&cert.q1, k - 1);
        }
        if k >= 2 {
            r = r + antidiagonal_sum(&cert.q1, k - 2);
        }
        let mag = r.lo.abs().max(r.hi.abs());
        rsum = rsum + Interval::point(mag);
    }
    let l0 = eig_lower_bound_nonpos(&cert.q0);
    let l1 = eig_lower_bound_nonpos(&cert.q1);
    let lb = Interval::point(cert.gamma)
        + Interval::point(l0) * Interval::point(s0 as f64)
        + Interval::point(l1) * Interval::point(s1 as f64) * Interval::point(0.25)
        - rsum;
    if lb.lo.is_nan() {
        return Err("lower bound is NaN".into());
    }
    Ok(lb.lo)
}

/// Side of a finite, exactly symmetric square matrix (0 for an empty one).
fn check_symmetric(q: &[Vec<f64>], name: &str) -> Result<usize, String> {
    let n = q.len();
    if n > MAX_CERT_SIDE {
        return Err(format!("{name} has side {n} > {MAX_CERT_SIDE}"));
    }
    for (i, row) in q.iter().enumerate() {
        if row.len() != n {
            return Err(format!("{name} is not square"));
        }
        for (j, &v) in row.iter().enumerate() {
            if !v.is_finite() {
                return Err(format!("{name} has a non-finite entry"));
            }
            if v != q[j][i] {
                return Err(format!("{name} is not symmetric"));
            }
        }
    }
    Ok(n)
}

/// `Σ_{i+j=k} Q_ij` over ordered pairs (an enclosure; entries are exact floats).
fn antidiagonal_sum(q: &[Vec<f64>], k: usize) -> Interval {
    let n = q.len();
    let mut acc = Interval::point(0.0);
    for (i, row) in q.iter().enumerate().take(k.min(n.saturating_sub(1)) + 1) {
        let j = k - i;
        if j < n {
            acc = acc + Interval::point(row[j]);
        }
    }
    acc
}

/// A proven `ℓ ≤ 0` with `ℓ ≤ λmin(Q)` (only `min(λmin, 0)` enters the bound).
/// `Q` is finite and symmetric.
fn eig_lower_bound_nonpos(q: &[Vec<f64>]) -> f64 {
    let n = q.len();
    if n == 0 || ldl_positive_definite(q, 0.0) {
        return 0.0;
    }
    let m = DMatrix::from_fn(n, n, |i, j| q[i][j]);
    let lam_hat = m.clone().symmetric_eigen().eigenvalues.min();
    let fro = m.norm();
    if lam_hat.is_finite() && fro.is_finite() {
        let mut delta = EIG_SLACK_REL * n as f64 * (1.0 + fro);
        for _ in 0..EIG_SLACK_TRIES {
            let lam = lam_hat - delta;
            if ldl_positive_definite(q, lam) {
                return lam.min(0.0);
            }
            delta *= EIG_SLACK_GROWTH;
        }
    }
    gershgorin_lower(q).min(0.0)
}

/// Proves `Q − λI ≻ 0` by symmetric Gaussian elimination in interval arithmetic:
/// `true` only if every pivot enclosure has a positive lower end.
fn ldl_positive_definite(q: &[Vec<f64>], lam: f64) -> bool {
    let n = q.len();
    if !lam.is_finite() {
        return false;
    }
    // upper triangle of W = Q − λI, row-major n×n
    let mut w = vec![Interval::point(0.0); n * n];
    for i in 0..n {
        for j in i..n {
            w[i * n + j] =
                if i == j { Interval::point(q[i][i]) - Interval::point(lam) } else { Interval::point(q[i][j]) };
        }
    }
    for k in 0..n {
        let piv = w[k * n + k];
        if piv.lo.is_nan() || piv.lo <= 0.0 || piv.hi.is_nan() {
            return false;
        }
        for i in k + 1..n {
            let l = div_pos(w[k * n + i], piv);
            for j in i..n {
                w[i * n + j] = w[i * n + j] - l * w[k * n + j];
            }
        }
    }
    true
}

/// `a / b` for `b.lo > 0`, outward rounded (IEEE division is correctly rounded).
#[allow(clippy::incompatible_msrv)] // f64::next_up (1.86), as in poly::interval
fn div_pos(a: Interval, b: Interval) -> Interval {
    let c = [a.lo / b.lo, a.lo / b.hi, a.hi / b.lo, a.hi / b.hi];
    if c.iter().any(|x| x.is_nan()) {
        return Interval::ENTIRE;
    }
    let lo = c.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = c.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    Interval { lo: lo.next_down(), hi: hi.next_up() }
}

/// Gershgorin: `λmin ≥ min_i (Q_ii − Σ_{j≠i} |Q_ij|)`, rounded down.
fn gershgorin_lower(q: &[Vec<f64>]) -> f64 {
    let mut best = f64::INFINITY;
    for (i, row) in q.iter().enumerate() {
        let mut acc = Interval::point(row[i]);
        for (j, &v) in row.iter().enumerate() {
            if j != i {
                acc = acc - Interval::point(v.abs());
            }
        }
        best = best.min(acc.lo);
    }
    if best.is_nan() {
        f64::NEG_INFINITY
    } else {
        best
    }
}

pub mod construct;
#[cfg(test)]
mod tests;
