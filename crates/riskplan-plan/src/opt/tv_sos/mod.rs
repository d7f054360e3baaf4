//! The time-varying SOS planner (the paper's Section V-B; the authors' Julia
//! `func_PathPlanningSOS.jl` with the El Khadir–Lasserre–Sindhwani rank heuristic;
//! docs/design.md §8.2).
//!
//! # Formulation
//!
//! `s` straight pieces on equal time intervals. Piece `i` runs from its start `a_i`
//! to its end `b_i`, `x(t) = (1−t)·a_i + t·b_i` in local time `t ∈ [0, 1]`, at absolute
//! time `θ_i(t) = t0 + (tf − t0)(i + t)/s`. The unknown endpoints of each piece are
//! replaced by a probability measure `μ_i`, known through its moments of degree ≤ `K`
//! ([`riskplan_math::relax::MomentVars`]):
//!
//! * `a_0 = x0` and `b_(s−1) = xT` are **eliminated** (the authors impose them by
//!   localized equalities; a measure supported on the affine set is the same thing as a
//!   measure on the remaining coordinates, and the relaxation is invariant under that
//!   affine change of variables). The first and last pieces so carry measures on `ℝ^n`
//!   and the middle ones on `ℝ^(2n)`: for the paper's two-piece examples the moment
//!   matrix shrinks from 15×15 to 6×6;
//! * every obstacle's constraints `g1 = E[P]² − (1−Δ_opt)E[P²] ≥ 0` and `g2 = −E[P] ≥ 0`
//!   (eq. 12, at the tightened level `Δ_opt = η·Δ`) are composed with the piece,
//!   `G(z, t) = g(x(t), θ_i(t))`, and imposed through their localizing matrix
//!   polynomial `L(t) ⪰ 0 ∀t ∈ [0, 1]` (matrix Markov–Lukács, exact);
//! * the workspace box on each free coordinate, `(ζ − lo)(hi − ζ) ≥ 0` (a piece stays in
//!   the box iff its ends do, since the box is convex);
//! * continuity of the first moments, `E[b_i] = E[a_(i+1)]`;
//! * a length epigraph `α_i ≥ ‖E[b_i − a_i]‖` (second-order cone) and, with a speed
//!   limit, `α_i ≤ v_max·(tf − t0)/s`.
//!
//! Everything is normalised first (docs/design.md §0.3 of the algorithms note): space
//! by the workspace's centre and largest half-width, time by the horizon, each
//! constraint polynomial by its largest coefficient.
//!
//! # Iterations (convex–concave)
//!
//! Iteration `ℓ` minimises `Σ_(i,k) (E[z_k^K] − K·z̄_k^(K−1)·E[z_k]) + w_len·Σ α_i`, with
//! `z̄` the first moments of the previous solve (a seeded perturbation of the straight
//! line at first). By Jensen `E[z^K] ≥ E[z]^K` with equality only at a Dirac measure, so
//! the iterations push every `μ_i` towards a point. Only `q` changes between
//! iterations: the Clarabel solver is set up once per attempt ([`Model::prepare`]).
//!
//! # Read-out and certification
//!
//! Waypoints `x0`, `E[b_0]`, …, `E[b_(s−2)]`, `xT` (the ends snapped exactly), straight
//! pieces between them on the equal time intervals. Once the Dirac gap
//! `Σ (E[z_k²] − E[z_k]²)` is below [`TvSosParams::gap_tol`], every iterate's read-out
//! is sent to the motion checker; the first one accepted piece by piece is returned.
//! The optimum touches the Δ_opt-contour, never the Δ-contour the checker certifies
//! against, which is the point of the margin `η < 1`. Nothing uncertified is ever
//! returned: when the ladder is spent the outcome is a typed no-plan with the
//! ladder's log.
//!
//! # The ladder
//!
//! 1. the given (or scene's) pieces, seed and iterations, `η` = [`TvSosParams::eta`],
//!    started from the default RRT-SOS path; on a static scene, if that fails, one piece
//!    per segment of the unsmoothed RRT-SOS path started at its corners
//!    (`TvSos::corner_path`); then the perturbed straight line;
//! 2. the same with a fresh seed, then twice the iterations;
//! 3. one more piece at a time up to [`TvSosParams::max_pieces`], with the tighter
//!    [`TvSosParams::eta_retry`].
//!
//! Every rung runs under the same [`Termination`].

use super::{normalise_poly, Attempt, Ladder, Next, Normalised, RungFailure};
use crate::{
    begin, dist, rrt_planner, Begin, Built, Kinematics, LadderStep, MotionChecker, PaperRun, PlanError, PlanOptions,
    PlanOutcome, Planner, PlannerSpec, Problem, Setup, Termination,
};
use num_bigint::BigInt;
use num_rational::BigRational;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use riskplan_certify::checker::SceneCertifier;
use riskplan_math::contour::RiskLevel;
use riskplan_math::poly::{Poly, QPoly};
use riskplan_math::relax::{add_matrix_lukacs, MomentVars, ZtPoly};
use riskplan_math::sdp::{AffineExpr, Model, SdpError, SdpStatus, Var};
use riskplan_scene::{Piece, Trajectory};
use std::time::Instant;

/// Parameters of the time-varying SOS planner (defaults: the authors' values where
/// they have one, see [`TvSosParams::paper`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TvSosParams {
    /// Pieces `s` of the first rung.
    pub pieces: usize,
    /// Most pieces the ladder tries.
    pub max_pieces: usize,
    /// Convex–concave iterations per attempt (an attempt stops earlier when a read-out
    /// is certified).
    pub iterations: usize,
    /// Relaxation degree `K` (even; raised automatically to the degree of the
    /// highest constraint, up to [`MAX_RELAXATION_DEGREE`]).
    pub relaxation_degree: u32,
    /// Weight of the length term `w_len` (in normalised units).
    pub length_weight: f64,
    /// `η` of the first rungs: optimise at `Δ_opt = η·Δ`.
    pub eta: f64,
    /// `η` of the rungs with more pieces.
    pub eta_retry: f64,
    /// Standard deviation of the initial perturbation, as a fraction of the
    /// workspace's half-width.
    pub noise: f64,
    /// Dirac gap below which read-outs are certified (normalised units).
    pub gap_tol: f64,
    /// Solver tolerance (gap and feasibility).
    pub solver_tol: f64,
    /// Speed limit (its `max_speed`; tv-sos neither smooths nor blends).
    pub kinematics: Kinematics,
    /// Highest order of the localizing matrices (`None`: the full order
    /// `⌊(K − deg g)/2⌋` of the paper; see [`riskplan_math::relax::MomentVars::localizing_capped`]).
    pub localizing_order: Option<u32>,
}

/// After the first certified read-out the iterations go on while each certified
/// read-out is shorter than the best so far by at least this fraction; the shortest
/// certified read-out is returned.
pub const POLISH_MIN_GAIN: f64 = 0.002;

/// A Dirac gap above this fraction of the previous one counts as stalled (see
/// [`LENGTH_ANNEAL`]).
pub const STALL_RATIO: f64 = 0.5;
/// Factor applied to the length weight when the Dirac gap stalls.
pub const LENGTH_ANNEAL: f64 = 0.2;

/// How far below the workspace's lower corner (in half-widths of the workspace) the
/// rank term is centred: `z − c ≥ RANK_OFFSET` everywhere, so the penalty on a
/// measure's spread, `~ C(K,2)·(z − c)^(K−2)·σ²`, is strong in every coordinate (about
/// the corner itself it vanishes for coordinates near the corner).
pub const RANK_OFFSET: f64 = 1.0;

/// Highest relaxation degree the planner raises `K` to (the moments of a middle
/// piece in 3-D number `C(6 + K, K)`: 924 at `K = 6`).
pub const MAX_RELAXATION_DEGREE: u32 = 8;

/// Most pieces a request may ask for (the SDP grows linearly in `s`; 16 pieces of a
/// 3-D scene at `K = 4` hold about 3 000 moments).
pub const MAX_PIECES: usize = 16;

impl Default for TvSosParams {
    fn default() -> Self {
        TvSosParams {
            pieces: 2,
            max_pieces: 6,
            iterations: 40,
            relaxation_degree: 4,
            length_weight: 0.1,
            eta: 0.95,
            eta_retry: 0.9,
            noise: 0.1,
            gap_tol: 1e-2,
            solver_tol: 1e-6,
            kinematics: Kinematics::default(),
            localizing_order: None,
        }
    }
}

impl TvSosParams {
    /// The authors' values from a scene's `planner.time_varying_sos` block (pieces,
    /// iterations, relaxation degree, length weight), else the defaults.
    pub fn paper(block: Option<&riskplan_scene::TimeVaryingSosBlock>) -> TvSosParams {
        let mut p = TvSosParams::default();
        if let Some(b) = block {
            if let Some(s) = b.pieces {
                p.pieces = s;
                p.max_pieces = p.max_pieces.max(s + 2);
            }
            if let Some(i) = b.iterations {
                p.iterations = i;
            }
            if let Some(k) = b.relaxation_degree {
                p.relaxation_degree = k;
            }
            if let Some(w) = b.length_weight {
                p.length_weight = w;
            }
        }
        p
    }

    /// Checks every value (typed errors for requests).
    pub fn validate(&self) -> Result<(), PlanError> {
        let bad = |o: &str, m: &str| Err(PlanError::InvalidOption { option: o.into(), message: m.into() });
        if self.pieces == 0 || self.pieces > MAX_PIECES {
            return bad("pieces", &format!("tv-sos takes 1 to {MAX_PIECES} pieces"));
        }
        if self.max_pieces < self.pieces || self.max_pieces > MAX_PIECES {
            return bad("max_pieces", &format!("must be between pieces and {MAX_PIECES}"));
        }
        if self.iterations == 0 || self.iterations > 10_000 {
            return bad("iterations", "must be 1 to 10000");
        }
        if self.relaxation_degree < 2
            || self.relaxation_degree % 2 == 1
            || self.relaxation_degree > MAX_RELAXATION_DEGREE
        {
            return bad("relaxation_degree", &format!("must be even, 2 to {MAX_RELAXATION_DEGREE}"));
        }
        for (name, v) in [("eta", self.eta), ("eta_retry", self.eta_retry)] {
            if !(v > 0.0 && v <= 1.0) {
                return bad(name, "must be in (0, 1]");
            }
        }
        for (name, v) in [
            ("length_weight", self.length_weight),
            ("noise", self.noise),
            ("gap_tol", self.gap_tol),
            ("solver_tol", self.solver_tol),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(name, "must be a finite number ≥ 0");
            }
        }
        if self.solver_tol <= 0.0 {
            return bad("solver_tol", "must be > 0");
        }
        self.kinematics.validate()
    }
}

/// `tv-sos`: the scene's `planner.time_varying_sos` values, the request's pieces (the
/// first rung's) and speed limit; every read-out certified by the scene certifier
/// (without covers: a handful of pieces to check, covers would cost more than they
/// save).
pub static SPEC: PlannerSpec = PlannerSpec {
    certified: true,
    build: |s: &Setup<'_>| {
        super::refuse_rrt_options(s, "tv-sos")?;
        let mut params = TvSosParams::paper(s.block().and_then(|b| b.time_varying_sos.as_ref()));
        if let Some(n) = s.options.pieces {
            params.pieces = n;
            params.max_pieces = params.max_pieces.max(n);
        }
        // max_speed checked by validate, last, as every other parameter
        params.kinematics = Kinematics { max_accel: None, smooth: false, ..s.kinematics() };
        params.validate()?;
        Ok(Built {
            planner: Box::new(TvSos { params, deltas: Some(s.deltas.to_vec()) }),
            checker: Box::new(
                SceneCertifier::with_deltas(s.kernel, s.deltas.to_vec(), s.options.certifier)
                    .with_bounds(s.options.bounds)
                    .without_index_build(),
            ),
        })
    },
    paper_runs: |scene| {
        let ran = scene.file.planner.as_ref().is_some_and(|b| b.time_varying_sos.is_some());
        if ran {
            vec![PaperRun { label: "tv-sos", improve: false, paper_key: Some("time_varying_sos") }]
        } else {
            vec![]
        }
    },
};

/// The time-varying SOS planner.
#[derive(Clone, Debug)]
pub struct TvSos {
    /// Parameters.
    pub params: TvSosParams,
    /// Risk level of each obstacle (joint risk modes); `None`: the problem's Δ for each.
    pub deltas: Option<Vec<RiskLevel>>,
}

/// One attempt of the ladder.
#[derive(Clone, Copy, Debug)]
struct Rung {
    pieces: usize,
    seed: u64,
    eta: f64,
    iterations: usize,
    /// Start from the default RRT-SOS planner's path instead of the straight line.
    from_rrt: bool,
    /// Start from the corners of the unsmoothed RRT-SOS path, one piece per segment
    /// (static scenes, after the first rung fails: where two pieces cut the path's corners).
    from_corners: bool,
}

/// The built relaxation of one attempt.
struct Relaxation {
    model: Model,
    /// Per piece: moment variables, and for each free coordinate of the piece its
    /// role (`false`: start `a`, `true`: end `b`) and spatial coordinate.
    pieces: Vec<(MomentVars, Vec<(bool, usize)>)>,
    alphas: Vec<Var>,
    psd_cones: usize,
    largest_psd: usize,
}

impl TvSos {
    /// A planner with these parameters (per-obstacle Δ from the problem).
    pub fn new(params: TvSosParams) -> TvSos {
        TvSos { params, deltas: None }
    }

    fn ladder(&self, seed: u64) -> Vec<Rung> {
        let p = &self.params;
        let rung = |pieces, seed, eta, iterations, from_rrt| Rung {
            pieces,
            seed,
            eta,
            iterations,
            from_rrt,
            from_corners: false,
        };
        let mut r = vec![
            rung(p.pieces, seed, p.eta, p.iterations, true),
            rung(p.pieces, seed, p.eta, p.iterations, false),
            rung(p.pieces, seed.wrapping_add(1), p.eta, p.iterations, false),
            rung(p.pieces, seed.wrapping_add(2), p.eta_retry, 2 * p.iterations, false),
        ];
        for s in p.pieces + 1..=p.max_pieces {
            r.push(rung(s, seed, p.eta_retry, p.iterations, true));
        }
        r
    }

    /// The normalised constraints `(g1, g2)` of every obstacle at `η·Δ_i`.
    fn constraints(&self, p: &Problem, nrm: &Normalised, eta: f64) -> Result<Vec<[Poly<f64>; 2]>, PlanError> {
        let eta_q = BigRational::from_float(eta).unwrap_or_else(|| BigRational::from_integer(BigInt::from(1)));
        let mut out = Vec::with_capacity(p.scene.obstacles.len());
        for (j, o) in p.scene.obstacles.iter().enumerate() {
            let delta = self.deltas.as_ref().and_then(|d| d.get(j)).unwrap_or(&p.delta);
            let cs = o.contour.constraints(&(delta.rational() * &eta_q));
            let n = |g: &QPoly| {
                normalise_poly(g, nrm, p.horizon, p.scene.dim).ok_or_else(|| PlanError::InvalidRequest {
                    field: "scene".into(),
                    message: "workspace or horizon not finite".into(),
                })
            };
            out.push([n(&cs.cantelli)?, n(&cs.mean)?]);
        }
        Ok(out)
    }

    /// Builds the relaxation for `s` pieces.
    fn build(&self, p: &Problem, nrm: &Normalised, cons: &[[Poly<f64>; 2]], s: usize) -> Result<Relaxation, PlanError> {
        let n = p.scene.dim;
        let sdp = |e: SdpError| PlanError::SdpModel { planner: "tv-sos".into(), message: e.to_string() };
        // K: at least the z-degree of every composed constraint (the degree in x of g)
        let max_x_degree = cons
            .iter()
            .flat_map(|g| g.iter())
            .map(|g| g.degree_in_vars(|v| (v as usize) < n))
            .max()
            .unwrap_or(2)
            .max(2);
        let mut k = self.params.relaxation_degree.max(max_x_degree);
        k += k % 2;
        if k > MAX_RELAXATION_DEGREE {
            return Err(PlanError::InvalidOption {
                option: "planner".into(),
                message: format!(
                    "tv-sos: an obstacle's constraint has degree {max_x_degree} in x; the relaxation supports at most {MAX_RELAXATION_DEGREE}"
                ),
            });
        }
        let cap = self.params.localizing_order.unwrap_or(u32::MAX);
        let mut model = Model::new();
        let mut pieces = Vec::with_capacity(s);
        let mut alphas = Vec::with_capacity(s);
        let (mut psd_cones, mut largest_psd) = (0usize, 0usize);
        let mut note = |side: usize| {
            psd_cones += 1;
            largest_psd = largest_psd.max(side);
        };
        for i in 0..s {
            // free coordinates: a (if not the first piece), then b (if not the last)
            let mut free: Vec<(bool, usize)> = Vec::new();
            if i > 0 {
                free.extend((0..n).map(|c| (false, c)));
            }
            if i + 1 < s {
                free.extend((0..n).map(|c| (true, c)));
            }
            let nz = free.len();
            let y = MomentVars::new(&mut model, nz, k);
            let alpha = model.add_var();
            alphas.push(alpha);
            if nz > 0 {
                y.moment_matrix(&mut model).map_err(sdp)?;
                note(y.monomials().count_up_to(k / 2));
            }
            // x_c(t) = (1 − t)·a_c + t·b_c over z (0..nz) and t (nz)
            let tv = nz as u16;
            let coord = |end: bool, c: usize| -> Poly<f64> {
                match free.iter().position(|&f| f == (end, c)) {
                    Some(z) => Poly::var(z as u16),
                    None => Poly::constant(if end { nrm.xt[c] } else { nrm.x0[c] }),
                }
            };
            let t = Poly::<f64>::var(tv);
            let one_minus_t = Poly::constant(1.0).sub(&t);
            let xs: Vec<Poly<f64>> =
                (0..n).map(|c| one_minus_t.mul(&coord(false, c)).add(&t.mul(&coord(true, c)))).collect();
            // θ_i(t) = (i + t)/s in normalised time
            let theta = {
                let mut th = Poly::constant(i as f64 / s as f64);
                th = th.add(&t.scale(&(1.0 / s as f64)));
                th
            };
            if nz > 0 {
                for g in cons.iter().flat_map(|g| g.iter()) {
                    let composed = g.subst(&|v| {
                        let v = v as usize;
                        if v < n {
                            Some(xs[v].clone())
                        } else if v == n {
                            Some(theta.clone())
                        } else {
                            None
                        }
                    });
                    let Some(gz) = ZtPoly::from_poly(&composed, nz) else {
                        // identically zero on this piece: no constraint
                        continue;
                    };
                    let (side, entries) = y.localizing_capped(&gz, cap).ok_or_else(|| PlanError::SdpModel {
                        planner: "tv-sos".into(),
                        message: "a constraint's degree exceeds the relaxation degree".into(),
                    })?;
                    let sz = add_matrix_lukacs(&mut model, side, &entries).map_err(sdp)?;
                    if sz.q0 > 0 {
                        note(sz.q0);
                        note(sz.q1.max(1));
                    } else {
                        note(side);
                    }
                }
                // the box on each free coordinate
                for (z, &(_, c)) in free.iter().enumerate() {
                    let (lo, hi) = (nrm.lo[c], nrm.hi[c]);
                    let mut e = vec![0u8; nz];
                    let mut terms = vec![(e.clone(), vec![-lo * hi])];
                    e[z] = 1;
                    terms.push((e.clone(), vec![lo + hi]));
                    e[z] = 2;
                    terms.push((e, vec![-1.0]));
                    let (side, entries) = y.localizing_capped(&ZtPoly { terms }, cap).expect("degree 2 ≤ K");
                    add_matrix_lukacs(&mut model, side, &entries).map_err(sdp)?;
                    note(side);
                }
            }
            // α_i ≥ ‖E[b − a]‖
            let mean = |end: bool, c: usize| -> AffineExpr {
                match free.iter().position(|&f| f == (end, c)) {
                    Some(z) => y.expr(y.monomials().power(z, 1).expect("first moments exist")),
                    None => AffineExpr::constant(if end { nrm.xt[c] } else { nrm.x0[c] }),
                }
            };
            let mut soc = vec![AffineExpr::var(alpha)];
            for c in 0..n {
                let (b, a) = (mean(true, c), mean(false, c));
                let mut terms = b.terms.clone();
                terms.extend(a.terms.iter().map(|&(v, x)| (v, -x)));
                soc.push(AffineExpr { constant: b.constant - a.constant, terms });
            }
            model.add_soc(&soc).map_err(sdp)?;
            if let Some(v) = self.params.kinematics.max_speed {
                // 1 % below the limit, so that the rounded read-out keeps to it
                let cap = 0.99 * v * (p.horizon.1 - p.horizon.0) / s as f64 / nrm.l;
                model.add_le(&[(alpha, 1.0)], cap).map_err(sdp)?;
            }
            pieces.push((y, free));
        }
        // continuity E[b_i] = E[a_(i+1)]
        for i in 0..s.saturating_sub(1) {
            for c in 0..n {
                let (yi, fi) = &pieces[i];
                let (yj, fj) = &pieces[i + 1];
                let zi = fi.iter().position(|&f| f == (true, c)).expect("b free");
                let zj = fj.iter().position(|&f| f == (false, c)).expect("a free");
                let vi = yi.var(yi.monomials().power(zi, 1).expect("moment")).expect("variable");
                let vj = yj.var(yj.monomials().power(zj, 1).expect("moment")).expect("variable");
                model.add_eq(&[(vi, 1.0), (vj, -1.0)], 0.0).map_err(sdp)?;
            }
        }
        Ok(Relaxation { model, pieces, alphas, psd_cones, largest_psd })
    }

    /// The objective of one iteration, linearised at `zbar` (per piece, per free
    /// coordinate).
    ///
    /// The rank term is taken about the workspace's lower corner `c`:
    /// `E[(z−c)^K] − K(z̄−c)^(K−1)·E[z]` (up to constants). Jensen's gap
    /// `E[(z−c)^K] − (E[z]−c)^K` is zero exactly at a Dirac measure wherever `c` is, but
    /// about the centre of a symmetric scene the mixture of two mirror-image paths is a
    /// fixed point of the iteration (every even function of `z` takes the same value on
    /// the mixture and on each path, and the linear term `K·z̄^(K−1)` vanishes at its
    /// mean); about a corner the linear term is large and the initial perturbation picks
    /// a side. (The authors' `(u, v)` variables are offset the same way by accident:
    /// `v` is measured from the start.) `E[(z−c)^K]` expands into moments of degree ≤ K.
    fn objective(&self, rel: &Relaxation, zbar: &[Vec<f64>], lo: &[f64], length_weight: f64) -> Vec<f64> {
        let mut q = vec![0.0; rel.model.num_vars()];
        for ((y, free), zb) in rel.pieces.iter().zip(zbar) {
            let k = y.degree();
            for (z, &(_, coord)) in free.iter().enumerate() {
                let c = lo[coord] - RANK_OFFSET;
                let mono = y.monomials();
                // E[(z − c)^K] = Σ_j C(K, j) (−c)^(K−j) E[z^j]
                let mut binom = 1.0;
                for j in 0..=k {
                    if j > 0 {
                        binom = binom * (k - j + 1) as f64 / j as f64;
                    }
                    if let Some(v) = mono.power(z, j as u8).and_then(|i| y.var(i)) {
                        q[v.index()] += binom * (-c).powi((k - j) as i32);
                    }
                }
                if let Some(v) = mono.power(z, 1).and_then(|i| y.var(i)) {
                    q[v.index()] -= k as f64 * (zb[z] - c).powi(k as i32 - 1);
                }
            }
        }
        for a in &rel.alphas {
            q[a.index()] += length_weight;
        }
        q
    }

    /// The straight line with seeded Gaussian noise, as the first `z̄`.
    fn initial(&self, rel: &Relaxation, nrm: &Normalised, seed: u64) -> Vec<Vec<f64>> {
        let s = rel.pieces.len();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let normal = Normal::new(0.0, self.params.noise.max(0.0)).unwrap_or_else(|_| Normal::new(0.0, 0.0).unwrap());
        rel.pieces
            .iter()
            .enumerate()
            .map(|(i, (_, free))| {
                free.iter()
                    .map(|&(end, c)| {
                        let f = (i + end as usize) as f64 / s as f64;
                        nrm.x0[c] + f * (nrm.xt[c] - nrm.x0[c]) + normal.sample(&mut rng)
                    })
                    .collect()
            })
            .collect()
    }
}

impl TvSos {
    /// A certified path of the default RRT-SOS planner (shortcut and blended on static scenes), to start the
    /// iterations from when the straight line leads nowhere: its homotopy class is a
    /// feasible one, and the iterations then shorten it locally.
    fn rrt_path(&self, p: &Problem, checker: &dyn MotionChecker, term: &Termination) -> Option<Trajectory> {
        // shortcut paths start the iterations closer to the optimum on static scenes; with
        // moving obstacles the raw layered path is used (its positions at the piece times
        // keep clear of the obstacles, which a re-timed shortcut path need not)
        let smooth = !p.is_dynamic();
        let opts = PlanOptions { kinematics: Kinematics { smooth, ..self.params.kinematics }, ..Default::default() };
        let mut planner = rrt_planner(p, false, &opts).ok()?;
        let out = planner.solve(p, checker, term).ok()?;
        out.certified.then_some(out.trajectory).flatten()
    }
}

impl TvSos {
    /// The corners of a certified, unsmoothed path of the default planner (static scenes),
    /// collinear vertices dropped, re-timed to one piece per segment on equal intervals,
    /// so that sampling it at a rung's piece times gives the corners. `None` without a
    /// path or with more than [`MAX_PIECES`] segments.
    fn corner_path(&self, p: &Problem, checker: &dyn MotionChecker, term: &Termination) -> Option<Trajectory> {
        let opts =
            PlanOptions { kinematics: Kinematics { smooth: false, ..self.params.kinematics }, ..Default::default() };
        let mut planner = rrt_planner(p, false, &opts).ok()?;
        let out = planner.solve(p, checker, term).ok()?;
        let path = out.certified.then_some(out.trajectory).flatten()?;
        let mut pts: Vec<Vec<f64>> = vec![p.start.clone()];
        for pc in &path.pieces {
            let b = pc.at(pc.t1);
            // drop the last point when it lies on the segment from its predecessor to b
            if pts.len() >= 2 {
                let (a, m) = (&pts[pts.len() - 2], &pts[pts.len() - 1]);
                let (u, w): (Vec<f64>, Vec<f64>) =
                    (m.iter().zip(a).map(|(x, y)| x - y).collect(), b.iter().zip(a).map(|(x, y)| x - y).collect());
                let dot: f64 = u.iter().zip(&w).map(|(x, y)| x * y).sum();
                let (nu, nw) =
                    (u.iter().map(|x| x * x).sum::<f64>().sqrt(), w.iter().map(|x| x * x).sum::<f64>().sqrt());
                if nu > 0.0 && nw > 0.0 && dot >= nu * nw * (1.0 - COLLINEAR_COS) {
                    pts.pop();
                }
            }
            pts.push(b);
        }
        let k = pts.len() - 1;
        if !(1..=MAX_PIECES).contains(&k) {
            return None;
        }
        let (t0, tf) = p.horizon;
        let at = |i: usize| if i == k { tf } else { t0 + (tf - t0) * i as f64 / k as f64 };
        Some(Trajectory::new(
            pts.windows(2).enumerate().map(|(i, w)| Piece::segment(&w[0], &w[1], at(i), at(i + 1))).collect(),
        ))
    }
}

/// Two segments of the unsmoothed path whose directions' cosine is within this of 1
/// are one segment for [`TvSos::corner_path`] (a bend under 0.03°: only splitting
/// points of a straight run, which would add pieces without adding corners).
const COLLINEAR_COS: f64 = 1e-7;

impl Planner for TvSos {
    fn name(&self) -> &'static str {
        "tv-sos"
    }

    fn solve(
        &mut self,
        p: &Problem,
        checker: &dyn MotionChecker,
        term: &Termination,
    ) -> Result<PlanOutcome, PlanError> {
        let t_start = Instant::now();
        self.params.validate()?;
        let stats = match begin(p, checker, term, self.params.kinematics.max_speed, t_start)? {
            Begin::Plan(stats) => stats,
            Begin::Answered(outcome) => return Ok(outcome),
        };
        let nrm = Normalised::new(p);
        let mut ladder = Ladder::default();
        let mut cons_cache: Vec<(f64, Vec<[Poly<f64>; 2]>)> = Vec::new();
        let mut found = None;
        let (mut rrt_path, mut rrt_tried) = (None, false);
        let mut corners: Option<Trajectory> = None;
        let mut rungs: std::collections::VecDeque<Rung> = self.ladder(p.seed).into();
        while let Some(rung) = rungs.pop_front() {
            if term.expired() {
                ladder.stopped = true;
                break;
            }
            if !cons_cache.iter().any(|(e, _)| *e == rung.eta) {
                let c = self.constraints(p, &nrm, rung.eta)?;
                cons_cache.push((rung.eta, c));
            }
            let cons = &cons_cache.iter().find(|(e, _)| *e == rung.eta).expect("cached").1;
            let mut step = LadderStep {
                pieces: rung.pieces,
                seed: rung.seed,
                eta: rung.eta,
                iterations: 0,
                dirac_gap: None,
                from_rrt: rung.from_rrt,
                outcome: String::new(),
            };
            if rung.from_rrt && rrt_path.is_none() && !rrt_tried {
                rrt_tried = true;
                rrt_path = self.rrt_path(p, checker, term);
            }
            if rung.from_rrt && rrt_path.is_none() {
                ladder.skip(step, "no RRT-SOS path to start from");
                continue;
            }
            let init = if rung.from_corners {
                corners.as_ref()
            } else if rung.from_rrt {
                rrt_path.as_ref()
            } else {
                None
            };
            let attempt = self.attempt(p, checker, term, &nrm, cons, rung, init, &mut ladder, &mut step)?;
            match ladder.record(step, attempt) {
                Next::Found(pieces) => {
                    found = Some(pieces);
                    break;
                }
                Next::Failed(_) => {
                    // static scene, the first RRT-started rung failed: next, one piece per
                    // segment of the unsmoothed RRT path, started at its corners
                    if rung.from_rrt && !rung.from_corners && corners.is_none() && !p.is_dynamic() {
                        corners = self.corner_path(p, checker, term);
                        if let Some(c) = &corners {
                            if c.pieces.len() > rung.pieces {
                                rungs.push_front(Rung { pieces: c.pieces.len(), from_corners: true, ..rung });
                            }
                        }
                    }
                }
                Next::Stop => break,
            }
        }
        Ok(ladder.finish(found, stats, checker, term, t_start))
    }
}

impl TvSos {
    #[allow(clippy::too_many_arguments)]
    fn attempt(
        &self,
        p: &Problem,
        checker: &dyn MotionChecker,
        term: &Termination,
        nrm: &Normalised,
        cons: &[[Poly<f64>; 2]],
        rung: Rung,
        init: Option<&Trajectory>,
        ladder: &mut Ladder,
        step: &mut LadderStep,
    ) -> Result<Attempt<Vec<Piece>>, PlanError> {
        let s = rung.pieces;
        let times: Vec<f64> = (0..=s)
            .map(|i| if i == s { p.horizon.1 } else { p.horizon.0 + (p.horizon.1 - p.horizon.0) * i as f64 / s as f64 })
            .collect();
        let read_out = |waypoints: &[Vec<f64>]| -> Vec<Piece> {
            waypoints
                .windows(2)
                .enumerate()
                .map(|(i, w)| Piece::segment(&w[0], &w[1], times[i], times[i + 1]))
                .collect()
        };
        let max_speed = self.params.kinematics.max_speed;
        if s == 1 {
            let pieces = read_out(&[p.start.clone(), p.goal.clone()]);
            return Ok(match ladder.certify(&pieces, max_speed, checker) {
                Ok(()) => Attempt::Certified(pieces),
                Err(_) => Attempt::Failed(RungFailure::StraightLine),
            });
        }
        let t_build = Instant::now();
        let rel = self.build(p, nrm, cons, s)?;
        let mut prepared = ladder
            .prepare(&rel.model, self.params.solver_tol, term)
            .map_err(|e| PlanError::SdpModel { planner: "tv-sos".into(), message: e.to_string() })?;
        ladder.sdp.psd_cones = rel.psd_cones;
        ladder.sdp.largest_psd = rel.largest_psd;
        ladder.sdp.setup_time_s += t_build.elapsed().as_secs_f64();
        let mut zbar = self.initial(&rel, nrm, rung.seed);
        if let Some(path) = init {
            // the RRT path at the piece times, as every piece's (a, b)
            let at = |t: f64| -> Vec<f64> {
                let pc = path.pieces.iter().find(|pc| t <= pc.t1).or(path.pieces.last()).expect("a piece");
                pc.at(t.clamp(pc.t0, pc.t1)).iter().zip(&nrm.c).map(|(v, c)| (v - c) / nrm.l).collect()
            };
            for (i, (zb, (_, free))) in zbar.iter_mut().zip(&rel.pieces).enumerate() {
                for (v, &(end, c)) in zb.iter_mut().zip(free) {
                    *v = at(times[i + end as usize])[c];
                }
            }
        }
        let mut last_rejected: Option<usize> = None;
        let mut best: Option<(f64, Vec<Piece>)> = None;
        let mut length_weight = self.params.length_weight;
        let mut last_gap = f64::INFINITY;
        for it in 0..rung.iterations {
            if term.should_stop() {
                return Ok(match best {
                    Some((_, pieces)) => Attempt::Certified(pieces),
                    None => Attempt::Stopped,
                });
            }
            let q = self.objective(&rel, &zbar, &nrm.lo, length_weight);
            let sol = match prepared.update_q(&q).and_then(|_| prepared.solve()) {
                Ok(sol) => sol,
                Err(e) => return Ok(Attempt::Failed(RungFailure::Solver(e.to_string()))),
            };
            ladder.sdp.solves += 1;
            ladder.sdp.ipm_iterations += sol.iterations as u64;
            ladder.sdp.solver_time_s += sol.solve_time;
            step.iterations = it + 1;
            match sol.status {
                SdpStatus::Solved | SdpStatus::AlmostSolved => {}
                SdpStatus::PrimalInfeasible | SdpStatus::AlmostPrimalInfeasible if it == 0 => {
                    return Ok(Attempt::Failed(RungFailure::InfeasiblePieces { pieces: s }));
                }
                // the plan was cancelled inside the solve
                SdpStatus::CallbackTerminated => {
                    return Ok(match best {
                        Some((_, pieces)) => Attempt::Certified(pieces),
                        None => Attempt::Stopped,
                    });
                }
                other => {
                    if it == 0 {
                        return Ok(Attempt::Failed(RungFailure::Status { order: None, status: other }));
                    }
                    break;
                }
            }
            // first moments and the Dirac gap
            let mut gap = 0.0;
            for (zb, (y, _)) in zbar.iter_mut().zip(&rel.pieces) {
                for (z, v) in zb.iter_mut().enumerate() {
                    let m1 = y.mean(&sol.x, z);
                    let m2 = y.monomials().power(z, 2).map_or(f64::NAN, |i| y.value(&sol.x, i));
                    gap += (m2 - m1 * m1).max(0.0);
                    *v = m1;
                }
            }
            step.dirac_gap = Some(gap);
            // The gap has a floor where the length term's gain from spreading a measure
            // (first order in its spread) meets the rank term's penalty (second order):
            // when the gap stalls, the length term is weakened (the path's shape is set
            // by then) so that the measures can go on to points.
            if gap > self.params.gap_tol && gap > STALL_RATIO * last_gap {
                length_weight *= LENGTH_ANNEAL;
            }
            last_gap = gap;
            if !zbar.iter().flatten().all(|v| v.is_finite()) {
                return Ok(Attempt::Failed(RungFailure::NonFinite("solver output")));
            }
            if gap <= self.params.gap_tol || it + 1 == rung.iterations {
                let mut w = vec![p.start.clone()];
                for (zb, (_, free)) in zbar.iter().zip(&rel.pieces).take(s - 1) {
                    let xi: Vec<f64> = (0..p.scene.dim)
                        .map(|c| zb[free.iter().position(|&f| f == (true, c)).expect("b free")])
                        .collect();
                    let ws = &p.scene.workspace;
                    let x: Vec<f64> =
                        nrm.back(&xi).iter().enumerate().map(|(c, v)| v.clamp(ws.lower[c], ws.upper[c])).collect();
                    w.push(x);
                }
                w.push(p.goal.clone());
                let pieces = read_out(&w);
                let length: f64 = w.windows(2).map(|x| dist(&x[0], &x[1])).sum();
                match ladder.certify(&pieces, max_speed, checker) {
                    Ok(()) => {
                        // polish: go on while each certified read-out is clearly shorter
                        let improved = best.as_ref().is_none_or(|(l, _)| length < (1.0 - POLISH_MIN_GAIN) * l);
                        if best.as_ref().is_none_or(|(l, _)| length < *l) {
                            best = Some((length, pieces));
                        }
                        if !improved {
                            break;
                        }
                    }
                    Err(i) => {
                        last_rejected = Some(i);
                        if best.is_some() {
                            break;
                        }
                    }
                }
            }
        }
        if let Some((_, pieces)) = best {
            return Ok(Attempt::Certified(pieces));
        }
        Ok(Attempt::Failed(match last_rejected {
            Some(i) => RungFailure::ReadOut(i),
            None => RungFailure::NotConverged,
        }))
    }
}
