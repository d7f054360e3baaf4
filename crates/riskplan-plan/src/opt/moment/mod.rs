//! The standard SOS planner with average risk (the paper's Section V-A.2, the
//! authors' GloptiPoly scripts `Example_3_Illustrative/Standard-SOS/*`;
//! docs/design.md §9).
//!
//! # Formulation
//!
//! Time is eliminated by treating it as uniform on each piece's interval: for a
//! trajectory `x(t)` with unknowns `z`, each obstacle's time-averaged moments
//! `F1(z) = avg_t E[P(x(t), t, ω)]` and `F2(z) = avg_t E[P²]` (eq. 12 averaged over `t`)
//! are polynomials in `z`, and the problem is
//!
//! ```text
//! min ∫ ‖ẋ‖² dt   s.t.  G1 = F1² − (1 − Δ_opt)·F2 ≥ 0,  G2 = −F1 ≥ 0   (per obstacle, per piece)
//! ```
//!
//! with `x(t0) = x0`, `x(tf) = xT` **eliminated** (the Lasserre hierarchy is invariant
//! under affine changes of variables):
//!
//! * [`MomentForm::PiecewiseLinear`] (default, `s` pieces on equal intervals): `z` = the
//!   `n(s−1)` interior waypoints, each in the workspace box;
//! * [`MomentForm::Polynomial`] (degree `d` over the horizon): `x(τ) = x0 + Σ_(j<d) z_j(τ^j −
//!   τ^d) + (xT − x0)τ^d`, `z` = the `n(d−1)` free coefficients, each bounded by the
//!   largest coefficient of the shifted Chebyshev polynomial `T_d(2τ − 1)` (Markov: a
//!   polynomial with values in `[−1, 1]` on `[0, 1]` has no larger coefficient; in
//!   normalised coordinates the workspace lies in `[−1, 1]^n`, and a trajectory that
//!   leaves it is rejected by the motion checker anyway).
//!
//! Everything is normalised as in the tv-sos planner (space by the workspace's centre
//! and largest half-width, time by the horizon; each constraint by its largest
//! coefficient).
//!
//! # Relaxation and extraction
//!
//! Lasserre's moment relaxation of order `r` ([`riskplan_math::relax::MomentVars`]): `M_r(y) ⪰ 0`,
//! a localizing matrix per constraint, objective `L_y(f)`. One SDP per rung, no
//! iterations. Its value is a lower bound on the problem's; the solution is read out by
//! the Henrion–Lasserre procedure ([`extract_atoms`]) when the moment matrix is flat
//! (Curto–Fialkow: `rank M_r = rank M_(r−v)`), giving one trajectory per atom (two
//! mirror images on illustrative-3, whose mean lies *inside* the obstacle: why a
//! rank-one read-out fails there).
//!
//! # Certification, and what the average risk is not
//!
//! The constraint bounds the **average** risk over a piece, a weak guarantee that does not
//! imply the per-instant bound the product promises. Every extracted trajectory is
//! therefore sent to the motion checker piece by piece like any other, and only a
//! certified one is returned. Its average-risk value is reported beside
//! ([`super::PlanStats::average_risk`]). The ladder tightens `Δ_opt = η·Δ`
//! ([`ETA_LADDER`]) until an atom is certified, then adds pieces (or degree), then raises
//! the order once per rung when extraction fails.

use super::{normalise_poly, Attempt, Ladder, Next, Normalised, RungFailure};
use crate::{
    begin, Begin, Built, Kinematics, LadderStep, MotionChecker, PaperRun, PlanError, PlanOutcome, Planner, PlannerSpec,
    Problem, Setup, Termination,
};
use riskplan_certify::checker::SceneCertifier;
use riskplan_math::contour::{cantelli_bound_f64, RiskLevel};
use riskplan_math::poly::{Monomial, Poly};
use riskplan_math::relax::extract_atoms;
use riskplan_math::relax::{add_matrix_lukacs, MomentVars, ZtPoly};
use riskplan_math::sdp::{Model, SdpError, SdpStatus};
use riskplan_scene::Piece;
use std::time::Instant;

/// The trajectory family of the standard SOS planner.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MomentForm {
    /// Straight pieces on equal time intervals; the unknowns are the interior waypoints.
    #[default]
    PiecewiseLinear,
    /// One polynomial of degree `d` over the horizon.
    Polynomial,
}

/// Parameters of the standard SOS planner.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MomentParams {
    /// Trajectory family.
    pub form: MomentForm,
    /// Pieces of the first rung (piecewise linear; the paper's: 2).
    pub pieces: usize,
    /// Degree of the first rung (polynomial; the paper's: 2).
    pub degree: usize,
    /// How many more pieces (or degrees) the ladder tries after the first.
    pub extra: usize,
    /// Relaxation order `r` (`None`: one above the smallest order that holds every
    /// constraint, where the paper's example is flat).
    pub order: Option<u32>,
    /// Solver tolerance (gap and feasibility).
    pub solver_tol: f64,
    /// Speed limit (its `max_speed`; the moment planner neither smooths nor blends).
    pub kinematics: Kinematics,
}

impl Default for MomentParams {
    fn default() -> Self {
        MomentParams {
            form: MomentForm::PiecewiseLinear,
            pieces: 2,
            degree: 2,
            extra: 1,
            order: None,
            solver_tol: 1e-8,
            kinematics: Kinematics::default(),
        }
    }
}

/// The tightening factors `η` of `Δ_opt = η·Δ` the ladder tries on each trajectory
/// family, in order. The first is the paper's problem (average risk at Δ); the
/// average over a piece is below the largest instantaneous risk on it, so its
/// atoms usually exceed Δ somewhere, and a tighter average is what makes a
/// certifiable trajectory.
pub const ETA_LADDER: [f64; 5] = [1.0, 0.5, 0.25, 0.1, 0.03];

/// Largest moment vector a rung may build (`C(N + 2r, 2r)` for `N` unknowns): above
/// it the rung is skipped and logged (a 3-D three-piece rung at `r = 3` holds 924).
pub const MAX_MOMENTS: usize = 1000;

/// Highest relaxation order.
pub const MAX_ORDER: u32 = 6;

/// Largest moment matrix `M_r` (side `C(N + r, r)`) a rung may build. Clarabel factors
/// its KKT system with a dense block per PSD cone before its first iteration and checks
/// its time limit only between iterations, so one factorisation must stay well inside
/// any plan's time limit: with side 70 (a degree-3 polynomial in 2-D at order 4, 6 249
/// KKT rows) one factorisation took over 40 s here; side 35 (three 2-D pieces at order
/// 3) takes a fraction of a second. Larger rungs are skipped and logged.
pub const MAX_MOMENT_SIDE: usize = 40;

/// Largest piece count or polynomial degree.
pub const MAX_FAMILY_SIZE: usize = 8;

impl MomentParams {
    /// The authors' values from a scene's `planner.standard_sos` block, else the
    /// defaults (the relaxation order is not taken from it: the authors' GloptiPoly
    /// order counts the non-eliminated variables).
    pub fn paper(block: Option<&riskplan_scene::StandardSosBlock>) -> MomentParams {
        let mut p = MomentParams::default();
        if let Some(b) = block {
            if let Some(s) = b.piecewise_linear_pieces {
                p.pieces = s;
            }
            if let Some(d) = b.polynomial_trajectory_degree {
                p.degree = d as usize;
            }
        }
        p
    }

    /// Checks every value (typed errors for requests).
    pub fn validate(&self) -> Result<(), PlanError> {
        let bad = |o: &str, m: String| Err(PlanError::InvalidOption { option: o.into(), message: m });
        if self.pieces < 1 || self.pieces > MAX_FAMILY_SIZE {
            return bad("pieces", format!("moment takes 1 to {MAX_FAMILY_SIZE} pieces"));
        }
        if self.degree < 1 || self.degree > MAX_FAMILY_SIZE {
            return bad("degree", format!("moment takes a trajectory degree of 1 to {MAX_FAMILY_SIZE}"));
        }
        if self.extra > MAX_FAMILY_SIZE {
            return bad("extra", format!("at most {MAX_FAMILY_SIZE}"));
        }
        if self.order.is_some_and(|r| r == 0 || r > MAX_ORDER) {
            return bad("order", format!("the relaxation order must be 1 to {MAX_ORDER}"));
        }
        if !(self.solver_tol.is_finite() && self.solver_tol > 0.0) {
            return bad("solver_tol", "must be a finite number > 0".into());
        }
        self.kinematics.validate()
    }
}

/// `moment`: piecewise-linear trajectories.
pub static PIECEWISE_LINEAR: PlannerSpec = PlannerSpec {
    certified: true,
    build: |s| build_planner(s, MomentForm::PiecewiseLinear),
    paper_runs: |scene| paper_run(scene, "moment", "standard_sos_piecewise_linear"),
};

/// `moment-poly`: one polynomial trajectory over the horizon.
pub static POLYNOMIAL: PlannerSpec = PlannerSpec {
    certified: true,
    build: |s| build_planner(s, MomentForm::Polynomial),
    paper_runs: |scene| paper_run(scene, "moment-poly", "standard_sos_polynomial"),
};

/// The standard SOS planner for a request: the scene's `planner.standard_sos` values,
/// the request's pieces (piecewise linear only) and speed limit; every atom's
/// trajectory certified by the scene certifier (without covers: a handful of pieces).
fn build_planner(s: &Setup<'_>, form: MomentForm) -> Result<Built, PlanError> {
    let name = match form {
        MomentForm::PiecewiseLinear => "moment",
        MomentForm::Polynomial => "moment-poly",
    };
    super::refuse_rrt_options(s, name)?;
    let mut params = MomentParams::paper(s.block().and_then(|b| b.standard_sos.as_ref()));
    params.form = form;
    if let Some(n) = s.options.pieces {
        if form == MomentForm::Polynomial {
            return Err(PlanError::InvalidOption {
                option: "pieces".into(),
                message: "moment-poly plans one polynomial over the horizon; pieces applies to moment".into(),
            });
        }
        params.pieces = n;
    }
    // max_speed checked by validate, last, as every other parameter
    params.kinematics = Kinematics { max_accel: None, smooth: false, ..s.kinematics() };
    params.validate()?;
    Ok(Built {
        planner: Box::new(MomentPlanner { params, deltas: Some(s.deltas.to_vec()) }),
        checker: Box::new(
            SceneCertifier::with_deltas(s.kernel, s.deltas.to_vec(), s.options.certifier)
                .with_bounds(s.options.bounds)
                .without_index_build(),
        ),
    })
}

/// The paper ran the standard SOS planner on the scenes with a `planner.standard_sos`
/// block.
fn paper_run(scene: &riskplan_scene::Scene, label: &'static str, key: &'static str) -> Vec<PaperRun> {
    match scene.file.planner.as_ref().is_some_and(|b| b.standard_sos.is_some()) {
        true => vec![PaperRun { label, improve: false, paper_key: Some(key) }],
        false => vec![],
    }
}

/// What a certified rung gives: the pieces and, per obstacle, the average risk bound.
type Found = (Vec<Piece>, Vec<f64>);

/// The standard SOS planner (average-risk moment relaxation, every output certified).
pub struct MomentPlanner {
    /// Parameters.
    pub params: MomentParams,
    /// Risk level of each obstacle (joint risk modes); `None`: the problem's Δ for each.
    pub deltas: Option<Vec<RiskLevel>>,
}

/// One trajectory family with its unknowns `z` (variables `0..N`) and the local time
/// `u` (variable `N`) of each piece.
struct Family {
    form: MomentForm,
    /// Pieces (piecewise linear) or degree (polynomial).
    size: usize,
    /// Unknowns `N`.
    nz: usize,
    /// Per piece: the normalised position as a polynomial in `(z, u)`, and the
    /// normalised time `τ(u)`.
    pieces: Vec<(Vec<Poly<f64>>, Poly<f64>)>,
    /// `∫ ‖ẋ‖² dτ` in normalised units, a quadratic in `z`.
    objective: Poly<f64>,
    /// Bound constraints `g(z) ≥ 0` on the unknowns.
    bounds: Vec<Poly<f64>>,
}

/// `Σ c·u^l → Σ c/(l+1)`: the average over `u ∈ [0, 1]` of a polynomial in `(z, u)`.
fn average(p: &Poly<f64>, u: u16) -> Poly<f64> {
    let mut out = Poly::zero();
    for (m, &c) in p.terms() {
        let l = m.exp(u);
        let (_, rest) = m.split(|v| v == u);
        out.add_term(rest, c / (l as f64 + 1.0));
    }
    out
}

/// The largest coefficient (in absolute value) of `T_d(2τ − 1)`.
fn chebyshev_coefficient_bound(d: usize) -> f64 {
    // T_0 = 1, T_1 = s, T_(k+1) = 2s·T_k − T_(k−1) with s = 2τ − 1, coefficients in τ
    let mut prev = vec![1.0];
    let mut cur = vec![-1.0, 2.0];
    if d == 0 {
        return 1.0;
    }
    for _ in 1..d {
        let mut next = vec![0.0; cur.len() + 1];
        for (k, &c) in cur.iter().enumerate() {
            next[k] -= 2.0 * c;
            next[k + 1] += 4.0 * c;
        }
        for (k, &c) in prev.iter().enumerate() {
            next[k] -= c;
        }
        prev = cur;
        cur = next;
    }
    cur.iter().fold(0.0, |m: f64, &c: &f64| m.max(c.abs()))
}

impl Family {
    fn new(form: MomentForm, size: usize, nrm: &Normalised, n: usize) -> Family {
        match form {
            MomentForm::PiecewiseLinear => Family::piecewise(size, nrm, n),
            MomentForm::Polynomial => Family::polynomial(size, nrm, n),
        }
    }

    fn piecewise(s: usize, nrm: &Normalised, n: usize) -> Family {
        let nz = n * (s - 1);
        let u = nz as u16;
        let point = |k: usize, d: usize| -> Poly<f64> {
            if k == 0 {
                Poly::constant(nrm.x0[d])
            } else if k == s {
                Poly::constant(nrm.xt[d])
            } else {
                Poly::var(((k - 1) * n + d) as u16)
            }
        };
        let mut pieces = Vec::with_capacity(s);
        let mut objective = Poly::zero();
        for i in 0..s {
            let mut xs = Vec::with_capacity(n);
            for d in 0..n {
                let (a, b) = (point(i, d), point(i + 1, d));
                let slope = b.sub(&a);
                xs.push(a.add(&slope.mul(&Poly::var(u))));
                // ∫ over a piece of length 1/s of ‖s(b − a)‖²
                objective = objective.add(&slope.mul(&slope).scale(&(s as f64)));
            }
            let tau = Poly::constant(i as f64 / s as f64).add(&Poly::var(u).scale(&(1.0 / s as f64)));
            pieces.push((xs, tau));
        }
        let bounds = (0..nz)
            .map(|k| {
                let d = k % n;
                let z = Poly::var(k as u16);
                z.sub(&Poly::constant(nrm.lo[d])).mul(&Poly::constant(nrm.hi[d]).sub(&z))
            })
            .collect();
        Family { form: MomentForm::PiecewiseLinear, size: s, nz, pieces, objective, bounds }
    }

    fn polynomial(deg: usize, nrm: &Normalised, n: usize) -> Family {
        let nz = n * (deg - 1);
        let u = nz as u16;
        let upow = |j: usize| Poly::monomial(Monomial::var_pow(u, j as u32), 1.0);
        let mut xs = Vec::with_capacity(n);
        let mut objective = Poly::zero();
        for d in 0..n {
            // x(u) = x0 + Σ_j z_j (u^j − u^d) + (xT − x0) u^d, and ẋ likewise
            let mut x = Poly::constant(nrm.x0[d]).add(&upow(deg).scale(&(nrm.xt[d] - nrm.x0[d])));
            let mut dx = upow(deg - 1).scale(&(deg as f64 * (nrm.xt[d] - nrm.x0[d])));
            for j in 1..deg {
                let z = Poly::var(((j - 1) * n + d) as u16);
                x = x.add(&z.mul(&upow(j).sub(&upow(deg))));
                let dbasis = upow(j - 1).scale(&(j as f64)).sub(&upow(deg - 1).scale(&(deg as f64)));
                dx = dx.add(&z.mul(&dbasis));
            }
            xs.push(x);
            objective = objective.add(&average(&dx.mul(&dx), u));
        }
        let b = chebyshev_coefficient_bound(deg);
        let bounds = (0..nz)
            .map(|k| {
                let z = Poly::var(k as u16);
                Poly::constant(b * b).sub(&z.mul(&z))
            })
            .collect();
        Family { form: MomentForm::Polynomial, size: deg, nz, pieces: vec![(xs, Poly::var(u))], objective, bounds }
    }

    /// The trajectory of the unknowns `z` (normalised), in absolute units, with the ends
    /// snapped to the problem's start and goal.
    fn trajectory(&self, z: &[f64], p: &Problem, nrm: &Normalised) -> Vec<Piece> {
        let n = p.scene.dim;
        let (t0, tf) = p.horizon;
        match self.form {
            MomentForm::PiecewiseLinear => {
                let s = self.size;
                let times: Vec<f64> =
                    (0..=s).map(|i| if i == s { tf } else { t0 + (tf - t0) * i as f64 / s as f64 }).collect();
                let mut wps = vec![p.start.clone()];
                for k in 1..s {
                    wps.push(nrm.back(&z[(k - 1) * n..k * n]));
                }
                wps.push(p.goal.clone());
                wps.windows(2).enumerate().map(|(i, w)| Piece::segment(&w[0], &w[1], times[i], times[i + 1])).collect()
            }
            MomentForm::Polynomial => {
                let deg = self.size;
                let h = tf - t0;
                let coeffs = (0..n)
                    .map(|d| {
                        // physical coefficients in τ = (t − t0)/h
                        let mut c = vec![0.0; deg + 1];
                        c[0] = p.start[d];
                        let mut inner = 0.0;
                        for j in 1..deg {
                            c[j] = nrm.l * z[(j - 1) * n + d];
                            inner += c[j];
                        }
                        c[deg] = p.goal[d] - p.start[d] - inner;
                        // to absolute time: Σ_j c_j h^(−j) (t − t0)^j
                        let mut out = vec![0.0; deg + 1];
                        for (j, &cj) in c.iter().enumerate() {
                            let a = cj / h.powi(j as i32);
                            let mut binom = 1.0;
                            for (k, ok) in out.iter_mut().enumerate().take(j + 1) {
                                // C(j, k) t^k (−t0)^(j−k)
                                *ok += a * binom * (-t0).powi((j - k) as i32);
                                binom = binom * (j - k) as f64 / (k + 1) as f64;
                            }
                        }
                        out
                    })
                    .collect();
                vec![Piece { t0, t1: tf, coeffs }]
            }
        }
    }
}

/// The time-averaged moments `(F1, F2)` of every obstacle on every piece, as
/// polynomials in `z`.
type Averaged = Vec<Vec<(Poly<f64>, Poly<f64>)>>;

impl MomentPlanner {
    /// A planner with these parameters (per-obstacle Δ from the problem).
    pub fn new(params: MomentParams) -> MomentPlanner {
        MomentPlanner { params, deltas: None }
    }

    fn delta(&self, p: &Problem, j: usize) -> f64 {
        self.deltas.as_ref().and_then(|d| d.get(j)).unwrap_or(&p.delta).to_f64()
    }

    /// `(F1, F2)` per obstacle per piece of a family.
    fn averaged(&self, p: &Problem, nrm: &Normalised, fam: &Family) -> Result<Averaged, PlanError> {
        let n = p.scene.dim;
        let u = fam.nz as u16;
        let mut out = Vec::with_capacity(p.scene.obstacles.len());
        for o in &p.scene.obstacles {
            let norm = |g| {
                normalise_poly(g, nrm, p.horizon, n).ok_or_else(|| PlanError::InvalidRequest {
                    field: "scene".into(),
                    message: "workspace or horizon not finite".into(),
                })
            };
            let (mean, second) = (norm(&o.contour.mean)?, norm(&o.contour.second)?);
            let mut per_piece = Vec::with_capacity(fam.pieces.len());
            for (xs, tau) in &fam.pieces {
                let sub = |v: u16| -> Option<Poly<f64>> {
                    let v = v as usize;
                    if v < n {
                        Some(xs[v].clone())
                    } else if v == n {
                        Some(tau.clone())
                    } else {
                        None
                    }
                };
                per_piece.push((average(&mean.subst(&sub), u), average(&second.subst(&sub), u)));
            }
            out.push(per_piece);
        }
        Ok(out)
    }
}

/// The relaxation of one rung: the model and its moment variables.
struct Relaxation {
    model: Model,
    moments: MomentVars,
    order: u32,
    /// `v = max_j ⌈deg g_j / 2⌉` (for the flatness test).
    v: u32,
    psd_cones: usize,
    largest_psd: usize,
}

/// Why a rung could not be built (kept in the ladder's log).
enum BuildError {
    TooLarge(usize),
    /// The moment matrix's side (above [`MAX_MOMENT_SIDE`]).
    TooLargeSide(usize),
    Model(SdpError),
    NonFinite,
}

fn build(
    fam: &Family,
    avg: &Averaged,
    deltas: &[f64],
    eta: f64,
    order: Option<u32>,
    raise: u32,
) -> Result<Relaxation, BuildError> {
    let mut gs: Vec<Poly<f64>> = fam.bounds.clone();
    for (per_piece, &delta) in avg.iter().zip(deltas) {
        let k = 1.0 - eta * delta;
        for (f1, f2) in per_piece {
            gs.push(f1.mul(f1).sub(&f2.scale(&k)));
            gs.push(f1.neg());
        }
    }
    let v = gs.iter().map(|g| g.degree().div_ceil(2)).max().unwrap_or(1).max(1);
    let r_min = v.max(fam.objective.degree().div_ceil(2)).max(1);
    let r = order.unwrap_or(r_min + 1).max(r_min) + raise;
    let moments_needed = binomial(fam.nz + 2 * r as usize, 2 * r as usize);
    if r > MAX_ORDER || moments_needed > MAX_MOMENTS {
        return Err(BuildError::TooLarge(moments_needed));
    }
    let side = binomial(fam.nz + r as usize, r as usize);
    if side > MAX_MOMENT_SIDE {
        return Err(BuildError::TooLargeSide(side));
    }
    let mut model = Model::new();
    let moments = MomentVars::new(&mut model, fam.nz, 2 * r);
    let mm = moments.moment_matrix(&mut model).map_err(BuildError::Model)?;
    let mut psd_cones = 1;
    let mut largest_psd = mm.side();
    for g in &gs {
        // a zero constraint (0 ≥ 0) holds for every measure
        if g.terms().all(|(_, &c)| c == 0.0) {
            continue;
        }
        let zt = ZtPoly::from_poly(g, fam.nz).ok_or(BuildError::NonFinite)?;
        let (side, entries) = moments.localizing(&zt).ok_or(BuildError::TooLarge(moments_needed))?;
        add_matrix_lukacs(&mut model, side, &entries).map_err(BuildError::Model)?;
        psd_cones += 1;
        largest_psd = largest_psd.max(side);
    }
    let mono = moments.monomials();
    let mut q: Vec<(riskplan_math::sdp::Var, f64)> = Vec::new();
    for (m, &c) in fam.objective.terms() {
        let mut e = vec![0u8; fam.nz];
        for &(var, k) in m.pairs() {
            e[var as usize] = k as u8;
        }
        if let Some(var) = mono.index(&e).and_then(|i| moments.var(i)) {
            q.push((var, c));
        }
    }
    model.set_objective(&q).map_err(BuildError::Model)?;
    Ok(Relaxation { model, moments, order: r, v, psd_cones, largest_psd })
}

fn binomial(n: usize, k: usize) -> usize {
    let mut r: usize = 1;
    for i in 0..k {
        r = r.saturating_mul(n - i) / (i + 1);
    }
    r
}

impl Planner for MomentPlanner {
    fn name(&self) -> &'static str {
        match self.params.form {
            MomentForm::PiecewiseLinear => "moment",
            MomentForm::Polynomial => "moment-poly",
        }
    }

    fn solve(
        &mut self,
        p: &Problem,
        checker: &dyn MotionChecker,
        term: &Termination,
    ) -> Result<PlanOutcome, PlanError> {
        let t_start = Instant::now();
        self.params.validate()?;
        let mut stats = match begin(p, checker, term, self.params.kinematics.max_speed, t_start)? {
            Begin::Plan(stats) => stats,
            Begin::Answered(outcome) => return Ok(outcome),
        };
        let nrm = Normalised::new(p);
        let deltas: Vec<f64> = (0..p.scene.obstacles.len()).map(|j| self.delta(p, j)).collect();
        let mut ladder = Ladder::default();
        let mut found = None;
        let first = match self.params.form {
            MomentForm::PiecewiseLinear => self.params.pieces,
            MomentForm::Polynomial => self.params.degree,
        };
        'families: for size in first..=(first + self.params.extra).min(MAX_FAMILY_SIZE) {
            let fam = Family::new(self.params.form, size, &nrm, p.scene.dim);
            let avg = self.averaged(p, &nrm, &fam)?;
            for eta in ETA_LADDER {
                if term.should_stop() {
                    ladder.stopped = true;
                    break 'families;
                }
                let mut step = LadderStep {
                    pieces: if fam.form == MomentForm::PiecewiseLinear { size } else { 1 },
                    seed: p.seed,
                    eta,
                    iterations: 0,
                    dirac_gap: None,
                    from_rrt: false,
                    outcome: String::new(),
                };
                let attempt = self.attempt(p, checker, term, &nrm, &fam, &avg, &deltas, eta, &mut ladder, &mut step)?;
                match ladder.record(step, attempt) {
                    Next::Found(f) => {
                        found = Some(f);
                        break 'families;
                    }
                    // a tighter Δ_opt only shrinks the feasible set
                    Next::Failed(why) if why.infeasible() => break,
                    Next::Failed(_) => {}
                    Next::Stop => break 'families,
                }
            }
        }
        let found = found.map(|(pieces, average_risk): Found| {
            stats.average_risk =
                Some(p.scene.obstacles.iter().zip(average_risk).map(|(o, r)| (o.id.clone(), r)).collect());
            pieces
        });
        Ok(ladder.finish(found, stats, checker, term, t_start))
    }
}

/// Whether a rejected trajectory visibly leaves the workspace box (at 65 times per
/// piece). For the ladder's log only: it explains a rejection, it never accepts.
fn leaves_workspace(pieces: &[Piece], p: &Problem) -> bool {
    const TIMES: usize = 64;
    let ws = &p.scene.workspace;
    pieces.iter().any(|pc| {
        (0..=TIMES).any(|k| {
            let x = pc.at(pc.t0 + (pc.t1 - pc.t0) * k as f64 / TIMES as f64);
            x.iter().zip(ws.lower.iter().zip(&ws.upper)).any(|(v, (lo, hi))| v < lo || v > hi)
        })
    })
}

impl MomentPlanner {
    /// One rung: build, solve, extract (raising the order once if the moment matrix is
    /// not flat), certify each atom's trajectory.
    #[allow(clippy::too_many_arguments)]
    fn attempt(
        &self,
        p: &Problem,
        checker: &dyn MotionChecker,
        term: &Termination,
        nrm: &Normalised,
        fam: &Family,
        avg: &Averaged,
        deltas: &[f64],
        eta: f64,
        ladder: &mut Ladder,
        step: &mut LadderStep,
    ) -> Result<Attempt<Found>, PlanError> {
        if fam.nz == 0 {
            // one straight piece (or a degree-1 polynomial): nothing to optimise
            let pieces = fam.trajectory(&[], p, nrm);
            return Ok(match ladder.certify(&pieces, self.params.kinematics.max_speed, checker) {
                Ok(()) => Attempt::Certified((pieces, average_risk(avg, &[]))),
                Err(_) => Attempt::Failed(RungFailure::StraightLine),
            });
        }
        let mut why: Vec<RungFailure> = Vec::new();
        let with_prior = |why: &[RungFailure], last: RungFailure| match why {
            [] => last,
            _ => RungFailure::Several(why.iter().cloned().chain([last]).collect()),
        };
        for raise in 0..2 {
            if term.should_stop() {
                return Ok(Attempt::Stopped);
            }
            let t_build = Instant::now();
            let rel = match build(fam, avg, deltas, eta, self.params.order, raise) {
                Ok(rel) => rel,
                Err(BuildError::TooLarge(moments)) => {
                    let last = RungFailure::TooManyMoments { moments, max: MAX_MOMENTS, max_order: MAX_ORDER };
                    return Ok(Attempt::Failed(with_prior(&why, last)));
                }
                Err(BuildError::TooLargeSide(side)) => {
                    let last = RungFailure::TooLargeSide { side, max: MAX_MOMENT_SIDE };
                    return Ok(Attempt::Failed(with_prior(&why, last)));
                }
                Err(BuildError::NonFinite) => return Ok(Attempt::Failed(RungFailure::NonFinite("constraint"))),
                Err(BuildError::Model(e)) => {
                    return Err(PlanError::SdpModel { planner: self.name().into(), message: e.to_string() })
                }
            };
            ladder.sdp.psd_cones = rel.psd_cones;
            ladder.sdp.largest_psd = rel.largest_psd;
            // the model's build; Clarabel's own setup counts in its solve time
            ladder.sdp.setup_time_s += t_build.elapsed().as_secs_f64();
            // a solver that cannot be set up is a failed rung (the ladder goes on)
            let sol = match ladder.prepare(&rel.model, self.params.solver_tol, term).and_then(|mut p| p.solve()) {
                Ok(sol) => sol,
                Err(e) => return Ok(Attempt::Failed(RungFailure::Solver(e.to_string()))),
            };
            ladder.sdp.solves += 1;
            ladder.sdp.ipm_iterations += sol.iterations as u64;
            ladder.sdp.solver_time_s += sol.solve_time;
            step.iterations += 1;
            match sol.status {
                SdpStatus::Solved | SdpStatus::AlmostSolved => {}
                SdpStatus::PrimalInfeasible | SdpStatus::AlmostPrimalInfeasible => {
                    return Ok(Attempt::Failed(RungFailure::InfeasibleOrder { order: rel.order }));
                }
                // the solve's time limit is what remains of the plan's, and its callback
                // the plan's cancel flag: the plan's time is up, or it was cancelled
                SdpStatus::MaxTime | SdpStatus::CallbackTerminated => return Ok(Attempt::Stopped),
                status => return Ok(Attempt::Failed(RungFailure::Status { order: Some(rel.order), status })),
            }
            let atoms = match extract_atoms(&rel.moments, &sol.x, rel.order, rel.v, p.seed) {
                Ok(a) => a,
                Err(e) => {
                    why.push(RungFailure::Extraction { order: rel.order, why: e });
                    continue;
                }
            };
            // cheapest first (the objective at each atom)
            let mut ranked: Vec<(f64, Vec<f64>)> = atoms.into_iter().map(|a| (fam.objective.eval(&a), a)).collect();
            ranked.sort_by(|a, b| a.0.total_cmp(&b.0));
            let n_atoms = ranked.len();
            let mut outside = 0;
            for (_, z) in &ranked {
                if term.should_stop() {
                    return Ok(Attempt::Stopped);
                }
                let pieces = fam.trajectory(z, p, nrm);
                if ladder.certify(&pieces, self.params.kinematics.max_speed, checker).is_ok() {
                    return Ok(Attempt::Certified((pieces, average_risk(avg, z))));
                }
                outside += usize::from(leaves_workspace(&pieces, p));
            }
            return Ok(Attempt::Failed(RungFailure::NoAtomCertified {
                order: rel.order,
                bound: sol.obj_primal + fam.objective.constant_term(),
                atoms: n_atoms,
                outside,
            }));
        }
        // both orders tried, neither gave atoms
        Ok(Attempt::Failed(RungFailure::Several(why)))
    }
}

/// Per obstacle, the largest Cantelli bound of the time-averaged moments over the pieces.
fn average_risk(avg: &Averaged, z: &[f64]) -> Vec<f64> {
    avg.iter()
        .map(|per_piece| {
            per_piece.iter().map(|(f1, f2)| cantelli_bound_f64(f1.eval(z), f2.eval(z))).fold(0.0, f64::max)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use riskplan_math::sdp::SdpSettings;

    #[test]
    fn chebyshev_bound_matches_closed_forms() {
        // T_1(2τ−1) = 2τ − 1; T_2 = 8τ² − 8τ + 1; T_3 = 32τ³ − 48τ² + 18τ − 1
        assert_eq!(chebyshev_coefficient_bound(1), 2.0);
        assert_eq!(chebyshev_coefficient_bound(2), 8.0);
        assert_eq!(chebyshev_coefficient_bound(3), 48.0);
    }

    fn illustrative_3() -> (Problem, Normalised) {
        let s = riskplan_scene::Scene::from_json(include_str!(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../scenes/illustrative-3.json"
        )))
        .unwrap();
        let p = Problem::from_scene(std::sync::Arc::new(s), 1).unwrap();
        let nrm = Normalised::new(&p);
        (p, nrm)
    }

    /// Solves the paper's average-risk problem (η = 1) and returns the bound and the atoms.
    fn paper_problem(form: MomentForm, size: usize) -> (f64, Vec<Vec<f64>>) {
        let (p, nrm) = illustrative_3();
        let planner = MomentPlanner::new(MomentParams::default());
        let fam = Family::new(form, size, &nrm, 2);
        let avg = planner.averaged(&p, &nrm, &fam).unwrap();
        let rel = build(&fam, &avg, &[0.1], 1.0, None, 0).ok().unwrap();
        assert_eq!(rel.order, 3);
        let sol = rel
            .model
            .solve(&SdpSettings { tol_gap_abs: 1e-8, tol_gap_rel: 1e-8, tol_feas: 1e-8, ..Default::default() })
            .unwrap();
        assert!(sol.status.has_solution(), "{:?}", sol.status);
        let atoms = extract_atoms(&rel.moments, &sol.x, rel.order, rel.v, 1).unwrap();
        (sol.obj_primal + fam.objective.constant_term(), atoms)
    }

    fn assert_mirror_atoms(atoms: &[Vec<f64>], a: [f64; 2], tol: f64) {
        assert_eq!(atoms.len(), 2, "{atoms:?}");
        for want in [a, [a[1], a[0]]] {
            assert!(
                atoms.iter().any(|z| (z[0] - want[0]).abs() < tol && (z[1] - want[1]).abs() < tol),
                "{want:?} not among {atoms:?}"
            );
        }
    }

    /// The reference values of the algorithms note (§6.3, computed independently): two
    /// pieces, bound 13.0901, two mirror-image atoms ±(−0.7977, 0.7977).
    #[test]
    fn piecewise_linear_reference_atoms() {
        let (bound, atoms) = paper_problem(MomentForm::PiecewiseLinear, 2);
        assert!((bound - 13.0901).abs() < 1e-3, "{bound}");
        assert_mirror_atoms(&atoms, [-0.7977, 0.7977], 1e-3);
    }

    /// Quadratic polynomial: bound 12.3382, atoms `c1` = (−0.5511, 4.5508) and its mirror.
    #[test]
    fn polynomial_reference_atoms() {
        let (bound, atoms) = paper_problem(MomentForm::Polynomial, 2);
        assert!((bound - 12.3382).abs() < 1e-3, "{bound}");
        assert_mirror_atoms(&atoms, [-0.5511, 4.5508], 2e-3);
    }

    #[test]
    fn binomials() {
        assert_eq!(binomial(2 + 6, 6), 28);
        assert_eq!(binomial(6 + 6, 6), 924);
    }
}
