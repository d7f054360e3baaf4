//! Verification of trajectories against a scene (layer L3): the kernel behind
//! `riskplan verify`, the service's edge-verification query, and the motion checker
//! of the RRT-SOS planners ([`SceneCertifier`]).
//!
//! For each piece and obstacle, the cached contour polynomials are composed with the
//! piece on its own absolute time interval (moving obstacles) and both constraints
//! of eq. (15) are decided on [0, 1] (docs/design.md §5) by the exact checker
//! (Bernstein subdivision in outward-rounded interval arithmetic, exact rational
//! fallback), the SOS certificate (Clarabel, rigorously re-checked), or both.
//! Only a proof counts as safe: an undecided constraint makes the piece unsafe.
//! The workspace box is checked exactly (non-strictly: start and goal may lie on it).

mod audit;
mod index;
mod workspace;

use crate::certify::fast::{CompiledContour, Substitution};
use crate::certify::{bernstein, restrict_exact, restrict_interval, sos, PieceRef, Undecided, Verdict};
use crate::contour::RiskLevel;
use crate::plan::{Motion, MotionChecker, Termination};
use crate::poly::{Interval, UPoly};
use crate::scene::{Obstacle, Piece, Scene, Trajectory};
use num_rational::BigRational;
use num_traits::Signed;
use serde::{Deserialize, Serialize};
use std::sync::{Arc, OnceLock};

pub use audit::{audit_trajectory, audit_trajectory_joint, Audit, AuditOptions, Exceedance};
pub use index::{compiled, piece_bbox, scene_center, scene_frame, KernelCache, SceneIndex};
pub use workspace::{check_workspace, WorkspaceStatus};

/// Which method decides positivity.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// The SOS certificate of eq. (15) on Clarabel, re-checked rigorously.
    Sos,
    /// Bernstein subdivision in interval arithmetic with an exact fallback.
    Exact,
    /// Both; safe only when both prove it.
    Both,
}

impl std::str::FromStr for Method {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "sos" => Ok(Method::Sos),
            "exact" => Ok(Method::Exact),
            "both" => Ok(Method::Both),
            _ => Err(format!("unknown method '{s}' (expected sos, exact or both)")),
        }
    }
}

impl Method {
    /// The name used in reports.
    pub fn as_str(&self) -> &'static str {
        match self {
            Method::Sos => "sos",
            Method::Exact => "exact",
            Method::Both => "both",
        }
    }
}

/// `safe`, `unsafe` or `undecided`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    /// Proven safe.
    Safe,
    /// Proven unsafe (with a witness).
    Unsafe,
    /// Not proven either way: never counts as safe.
    Undecided,
}

/// A time at which a constraint is ≤ 0, in absolute time.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct WitnessReport {
    /// Absolute time.
    pub t: f64,
    /// Constraint value there (≤ 0, proven).
    pub value: f64,
}

/// One method's verdict on one constraint.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MethodReport {
    /// Status.
    pub status: Status,
    /// Proven lower bound on the constraint's minimum over the piece (safe), or the
    /// witness value (unsafe).
    pub margin: Option<f64>,
    /// Witness (unsafe).
    pub witness: Option<WitnessReport>,
    /// Why undecided.
    pub reason: Option<String>,
}

/// The verdict on one constraint of one obstacle over one piece.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ConstraintReport {
    /// `mean` (−E[P] > 0) or `cantelli` (E[P]² − (1−Δ)E[P²] > 0).
    pub name: String,
    /// Combined status.
    pub status: Status,
    /// See [`MethodReport::margin`].
    pub margin: Option<f64>,
    /// See [`MethodReport::witness`].
    pub witness: Option<WitnessReport>,
    /// The method(s) used.
    pub method: String,
    /// Why undecided (the first method's reason).
    pub reason: Option<String>,
    /// Per method, with `--method both`.
    pub methods: Option<Vec<(String, MethodReport)>>,
}

/// One obstacle over one piece.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ObstacleReport {
    /// Obstacle id.
    pub id: String,
    /// Safe iff every constraint is safe.
    pub status: Status,
    /// `mean` then `cantelli`.
    pub constraints: Vec<ConstraintReport>,
}

/// One piece.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PieceReport {
    /// Start time.
    pub t0: f64,
    /// End time.
    pub t1: f64,
    /// Safe iff inside the workspace and safe for every obstacle.
    pub safe: bool,
    /// Workspace check.
    pub workspace: WorkspaceStatus,
    /// Per obstacle.
    pub obstacles: Vec<ObstacleReport>,
}

/// The report of `riskplan verify`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct VerifyReport {
    /// Every piece certified safe.
    pub safe: bool,
    /// Method.
    pub method: String,
    /// Δ used.
    pub risk: f64,
    /// Per piece.
    pub pieces: Vec<PieceReport>,
}

fn method_report(v: &Verdict, piece: PieceRef<'_>) -> MethodReport {
    let h = piece.t1 - piece.t0;
    match v {
        Verdict::Safe { margin } => {
            MethodReport { status: Status::Safe, margin: Some(*margin), witness: None, reason: None }
        }
        Verdict::Unsafe(w) => MethodReport {
            status: Status::Unsafe,
            margin: Some(w.value),
            witness: Some(WitnessReport { t: piece.t0 + h * w.tau, value: w.value }),
            reason: None,
        },
        Verdict::Undecided(u) => {
            MethodReport { status: Status::Undecided, margin: None, witness: None, reason: Some(undecided_text(u)) }
        }
    }
}

fn undecided_text(u: &Undecided) -> String {
    match u {
        Undecided::DepthLimit => "subdivision depth limit (near tangency)".into(),
        Undecided::Solver(s) => format!("SDP solver: {s}"),
        Undecided::CertificateRejected(s) => format!("certificate rejected by the re-check: {s}"),
        Undecided::MarginTooSmall(m) => format!("margin {m:e} below the acceptance threshold"),
        Undecided::NonFinite => "non-finite coefficients".into(),
    }
}

/// Decides one restricted constraint with `method`.
pub fn decide(
    method: Method,
    p: &UPoly<Interval>,
    exact: &dyn Fn() -> UPoly<BigRational>,
    sos_settings: &sos::SosSettings,
) -> Vec<(&'static str, Verdict)> {
    match method {
        Method::Exact => vec![("exact", bernstein::check(p, exact))],
        Method::Sos => vec![("sos", sos::certify(p, sos_settings).verdict)],
        Method::Both => vec![("exact", bernstein::check(p, exact)), ("sos", sos::certify(p, sos_settings).verdict)],
    }
}

fn combine(vs: &[(&'static str, Verdict)]) -> Status {
    if vs.iter().any(|(_, v)| v.is_unsafe()) {
        Status::Unsafe
    } else if vs.iter().all(|(_, v)| v.is_safe()) {
        Status::Safe
    } else {
        Status::Undecided
    }
}

fn worst(a: Status, b: Status) -> Status {
    match (a, b) {
        (Status::Unsafe, _) | (_, Status::Unsafe) => Status::Unsafe,
        (Status::Undecided, _) | (_, Status::Undecided) => Status::Undecided,
        _ => Status::Safe,
    }
}

/// Decides an obstacle's two constraints over a piece in order (`mean`, the lower
/// degree, first; then `cantelli`) and hands each decision to `visit`, which returns
/// whether to go on. The interval restriction is built once — from the compiled,
/// centred contour when given and within its capacity, else by general composition —
/// and the exact one only if a decision needs the exact fallback, then once for both.
fn decide_obstacle(
    o: &Obstacle,
    compiled: Option<&CompiledContour>,
    piece: PieceRef<'_>,
    delta: &BigRational,
    method: Method,
    settings: &sos::SosSettings,
    mut visit: impl FnMut(&'static str, Vec<(&'static str, Verdict)>) -> bool,
) {
    let omd = Interval::enclose_rational(&(BigRational::from_integer(1.into()) - delta));
    let fast = compiled.and_then(|c| c.restrict(piece)).and_then(|r| r.constraints(omd));
    let (cantelli, mean) = match fast {
        Some((g1, g2)) => (UPoly::new(g1.coeffs().to_vec()), UPoly::new(g2.coeffs().to_vec())),
        None => {
            let iv = restrict_interval(&o.contour, piece, delta);
            (iv.cantelli, iv.mean)
        }
    };
    let exact = std::cell::OnceCell::new();
    for (name, poly) in [("mean", &mean), ("cantelli", &cantelli)] {
        let ex = || {
            let r = exact.get_or_init(|| restrict_exact(&o.contour, piece, delta));
            if name == "mean" {
                r.mean.clone()
            } else {
                r.cantelli.clone()
            }
        };
        if !visit(name, decide(method, poly, &ex, settings)) {
            return;
        }
    }
}

/// Verifies one obstacle over one piece, constraint by constraint.
pub fn verify_obstacle(
    o: &Obstacle,
    piece: PieceRef<'_>,
    delta: &RiskLevel,
    method: Method,
    settings: &sos::SosSettings,
) -> ObstacleReport {
    verify_obstacle_with(o, None, piece, delta, method, settings)
}

/// [`verify_obstacle`] with the obstacle's compiled contour (the fast restriction).
pub fn verify_obstacle_with(
    o: &Obstacle,
    compiled: Option<&CompiledContour>,
    piece: PieceRef<'_>,
    delta: &RiskLevel,
    method: Method,
    settings: &sos::SosSettings,
) -> ObstacleReport {
    let mut constraints = Vec::with_capacity(2);
    let mut status = Status::Safe;
    decide_obstacle(o, compiled, piece, delta.rational(), method, settings, |name, vs| {
        let st = combine(&vs);
        status = worst(status, st);
        let reports: Vec<(&'static str, MethodReport)> =
            vs.iter().map(|(m, v)| (*m, method_report(v, piece))).collect();
        // The combined margin and witness: a witness from any method; the smallest proven margin.
        let witness = reports.iter().find_map(|(_, r)| r.witness);
        let margin = match st {
            Status::Safe => reports.iter().filter_map(|(_, r)| r.margin).reduce(f64::min),
            Status::Unsafe => witness.map(|w| w.value),
            Status::Undecided => None,
        };
        let reason = if st == Status::Undecided { reports.iter().find_map(|(_, r)| r.reason.clone()) } else { None };
        constraints.push(ConstraintReport {
            name: name.to_string(),
            status: st,
            margin,
            witness,
            reason,
            method: method.as_str().to_string(),
            methods: (method == Method::Both).then(|| reports.into_iter().map(|(m, r)| (m.to_string(), r)).collect()),
        });
        true
    });
    ObstacleReport { id: o.id.clone(), status, constraints }
}

/// Verifies a trajectory against a scene at risk level `delta`.
pub fn verify(
    scene: &Scene,
    traj: &Trajectory,
    delta: &RiskLevel,
    method: Method,
    settings: &sos::SosSettings,
) -> VerifyReport {
    // `stop` never says yes, so this is never interrupted; were it, the answer would
    // be "not safe" with no pieces, never a false "safe".
    verify_until(scene, traj, delta, method, settings, &|| false).unwrap_or_else(|Interrupted| VerifyReport {
        safe: false,
        method: method.as_str().to_string(),
        risk: delta.to_f64(),
        pieces: Vec::new(),
    })
}

/// `verify` stopped by its caller (a deadline or a cancellation): no verdict.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Interrupted;

/// [`verify`] that asks `stop` before each piece and obstacle and gives up with
/// [`Interrupted`] as soon as it says yes (a service deadline). One check of one piece
/// against one obstacle is the largest step between two questions.
pub fn verify_until(
    scene: &Scene,
    traj: &Trajectory,
    delta: &RiskLevel,
    method: Method,
    settings: &sos::SosSettings,
    stop: &dyn Fn() -> bool,
) -> Result<VerifyReport, Interrupted> {
    let mut pieces = Vec::with_capacity(traj.pieces.len());
    let compiled = compiled(scene);
    for pc in &traj.pieces {
        let pr = PieceRef { t0: pc.t0, t1: pc.t1, coeffs: &pc.coeffs };
        let workspace = check_workspace(&scene.workspace.lower, &scene.workspace.upper, pr);
        let mut obstacles = Vec::with_capacity(scene.obstacles.len());
        for (o, c) in scene.obstacles.iter().zip(compiled.iter()) {
            if stop() {
                return Err(Interrupted);
            }
            obstacles.push(verify_obstacle_with(o, Some(c), pr, delta, method, settings));
        }
        let safe = workspace.status == Status::Safe && obstacles.iter().all(|o| o.status == Status::Safe);
        pieces.push(PieceReport { t0: pc.t0, t1: pc.t1, safe, workspace, obstacles });
    }
    Ok(VerifyReport {
        safe: pieces.iter().all(|p| p.safe),
        method: method.as_str().to_string(),
        risk: delta.to_f64(),
        pieces,
    })
}

/// A scene's contour polynomials for the final check (docs/design.md §5.12), written in
/// the verify path's own frame `z_v = (x_v − c_v)·2^(−e_v)` (centre and power-of-two
/// scale from the workspace and the horizon) by general polynomial substitution in
/// exact arithmetic, then enclosed coefficient by coefficient. In the scene's own
/// coordinates a workspace at x ≈ 5·10⁶ (UTM) makes the monomials cancel by many orders
/// of magnitude and nearly every piece would go to the exact fallback. This is
/// deliberately not the compiled path's frame code (`certify::fast`): the final check
/// shares no code with it beyond the contour polynomials. A scene near the origin at
/// moderate scale keeps its own coordinates (`polys` is `None`): the exact substitution
/// costs about 0.25 ms per obstacle, more than the final check saves there.
#[derive(Debug)]
pub struct FramedContours {
    center: Vec<f64>,
    inv_scale: Vec<f64>,
    polys: Option<Vec<(crate::poly::Poly<Interval>, crate::poly::Poly<Interval>)>>,
    /// With more than [`FramedContours::NEAR_MIN_OBSTACLES`] obstacles in at most
    /// [`FramedContours::NEAR_MAX_DIM`] dimensions: each obstacle's contour polynomials
    /// rewritten exactly around a point of its own, for a box test that clears distant
    /// obstacles without a composition (`None` for an obstacle whose point is not
    /// finite). Built by the first final check that needs it, asking its `stop`.
    near: OnceLock<Option<Vec<Option<Near>>>>,
}

/// One obstacle's contour polynomials around a point of its own (`y = x − c`), with
/// interval coefficients: evaluated over a piece's bounding box they bound E[P] and
/// E[P²] there.
#[derive(Debug)]
struct Near {
    center: Vec<f64>,
    mean: crate::poly::Poly<Interval>,
    second: crate::poly::Poly<Interval>,
}

impl Near {
    /// The Cantelli polynomial g₁ = E[P]² − (1−Δ)·E[P²] around the centre, formed
    /// before any evaluation so that its leading terms cancel symbolically (evaluating
    /// E[P]² and E[P²] separately over a box cannot prove g₁ > 0 a few box-widths away).
    fn cantelli(&self, one_minus_delta: Interval) -> crate::poly::Poly<Interval> {
        self.mean.mul(&self.mean).sub(&self.second.scale(&one_minus_delta))
    }

    /// Whether both constraints of eq. (15) are proven over the box `bbox × t` by naive
    /// interval evaluation of −E[P] and of `cantelli` (from [`Near::cantelli`]).
    fn clears(&self, bbox: &[Interval], t: Interval, cantelli: &crate::poly::Poly<Interval>) -> bool {
        let mut vals: Vec<Interval> = bbox.iter().zip(&self.center).map(|(&b, &c)| b - Interval::point(c)).collect();
        vals.push(t - Interval::point(self.center[bbox.len()]));
        self.mean.eval(&vals).hi < 0.0 && cantelli.eval(&vals).lo > 0.0
    }
}

impl FramedContours {
    /// Largest scale exponent: `2^±1000` is a normal float.
    const MAX_EXPONENT: i32 = 1000;
    /// A centre within this many half-widths of the origin is not shifted: the
    /// monomials then cancel by at most about this factor to the power of the degree,
    /// which the interval enclosures absorb (Bernstein decides such scenes today).
    const CENTRE_KEPT: f64 = 16.0;
    /// A scale exponent of at most this magnitude is not applied (2^±16).
    const SCALE_KEPT: i32 = 16;
    /// Above this many obstacles distant ones are cleared by a box test first: below
    /// it composing with every obstacle costs less than preparing the test (a few
    /// tenths of a millisecond per obstacle, once per scene).
    const NEAR_MIN_OBSTACLES: usize = 16;
    /// The box tests' points are found on a grid of 16^dim points per obstacle
    /// (`index::obstacle_center`): beyond 3 dimensions that costs more than it saves.
    const NEAR_MAX_DIM: usize = 3;

    /// The box tests of every obstacle (`None` when the scene has too few obstacles or
    /// too many dimensions), built on first use; `Err` when `stop` says stop first
    /// (nothing is kept then).
    fn near(&self, scene: &Scene, stop: &dyn Fn() -> bool) -> Result<Option<&[Option<Near>]>, Interrupted> {
        if let Some(n) = self.near.get() {
            return Ok(n.as_deref());
        }
        if scene.obstacles.len() <= Self::NEAR_MIN_OBSTACLES || scene.dim > Self::NEAR_MAX_DIM {
            return Ok(self.near.get_or_init(|| None).as_deref());
        }
        let ws = &scene.workspace;
        let mut region: Vec<(f64, f64)> = ws.lower.iter().copied().zip(ws.upper.iter().copied()).collect();
        region.push(scene.horizon);
        let mut near = Vec::with_capacity(scene.obstacles.len());
        for o in &scene.obstacles {
            if stop() {
                return Err(Interrupted);
            }
            let center = index::obstacle_center(&o.contour, &region);
            // the same exact values substituted and subtracted; a point that is not a
            // finite float gets no box test
            let Some(exact) = center.iter().map(|&c| BigRational::from_float(c)).collect::<Option<Vec<_>>>() else {
                near.push(None);
                continue;
            };
            let subs: Vec<crate::poly::QPoly> = exact
                .into_iter()
                .enumerate()
                .map(|(v, c)| crate::poly::Poly::var(v as crate::poly::Var).add(&crate::poly::Poly::constant(c)))
                .collect();
            let around = |p: &crate::poly::QPoly| {
                p.subst(&|v| subs.get(v as usize).cloned()).map_coeffs(Interval::enclose_rational)
            };
            near.push(Some(Near { mean: around(&o.contour.mean), second: around(&o.contour.second), center }));
        }
        Ok(self.near.get_or_init(|| Some(near)).as_deref())
    }

    fn new(scene: &Scene) -> Self {
        let ws = &scene.workspace;
        let mut center = index::scene_center(scene);
        let mut half: Vec<f64> = ws.lower.iter().zip(&ws.upper).map(|(l, u)| 0.5 * u - 0.5 * l).collect();
        half.push(0.5 * scene.horizon.1 - 0.5 * scene.horizon.0);
        let exps: Vec<i32> = half
            .iter()
            .map(|&w| {
                let e = if w > 0.0 && w.is_finite() {
                    (w.log2().floor() as i32).clamp(-Self::MAX_EXPONENT, Self::MAX_EXPONENT)
                } else {
                    0
                };
                if e.abs() <= Self::SCALE_KEPT {
                    0
                } else {
                    e
                }
            })
            .collect();
        for (c, w) in center.iter_mut().zip(&half) {
            if c.abs() <= Self::CENTRE_KEPT * w {
                *c = 0.0;
            }
        }
        if center.iter().all(|&c| c == 0.0) && exps.iter().all(|&e| e == 0) {
            let n = center.len();
            return FramedContours { center, inv_scale: vec![1.0; n], polys: None, near: OnceLock::new() };
        }
        let two = BigRational::from_integer(2.into());
        let subs: Vec<crate::poly::QPoly> = center
            .iter()
            .zip(&exps)
            .enumerate()
            .map(|(v, (&c, &e))| {
                let scale: BigRational = num_traits::Pow::pow(&two, e);
                crate::poly::Poly::var(v as crate::poly::Var)
                    .scale(&scale)
                    .add(&crate::poly::Poly::constant(BigRational::from_float(c).unwrap_or_default()))
            })
            .collect();
        let frame =
            |p: &crate::poly::QPoly| p.subst(&|v| subs.get(v as usize).cloned()).map_coeffs(Interval::enclose_rational);
        let polys = scene.obstacles.iter().map(|o| (frame(&o.contour.mean), frame(&o.contour.second))).collect();
        let inv_scale = exps.iter().map(|&e| crate::certify::fast::pow2(-e)).collect();
        FramedContours { center, inv_scale, polys: Some(polys), near: OnceLock::new() }
    }

    /// The constraints of obstacle `o` (the scene's `i`-th) restricted to a piece, in
    /// interval arithmetic: `(g1, g2)` = (Cantelli, mean) of eq. (15) in τ ∈ [0, 1].
    fn restrict(
        &self,
        i: usize,
        o: &Obstacle,
        pr: PieceRef<'_>,
        one_minus_delta: Interval,
    ) -> (UPoly<Interval>, UPoly<Interval>) {
        let t0 = Interval::point(pr.t0);
        let h = Interval::point(pr.t1) - t0;
        let n = self.center.len();
        let mut subs: Vec<UPoly<Interval>> = (0..n - 1)
            .map(|d| {
                let row = pr.coeffs.get(d).map(|r| r.as_slice()).unwrap_or(&[]);
                let x = UPoly::new(row.iter().map(|&c| Interval::point(c)).collect()).compose_affine(&t0, &h);
                x.sub(&UPoly::constant(Interval::point(self.center[d]))).scale(&Interval::point(self.inv_scale[d]))
            })
            .collect();
        subs.push(
            UPoly::linear(t0 - Interval::point(self.center[n - 1]), h).scale(&Interval::point(self.inv_scale[n - 1])),
        );
        let (m, s) = match &self.polys {
            Some(p) => (&p[i].0, &p[i].1),
            None => o.contour.interval_polys(),
        };
        let e1 = m.compose_univariate(&subs);
        let e2 = s.compose_univariate(&subs);
        (e1.mul(&e1).sub(&e2.scale(&one_minus_delta)), e1.neg())
    }
}

/// The box tests of a final check: per obstacle its test (if any) and its Cantelli
/// polynomial at its Δᵢ, formed on first use.
type NearTests<'a> = (&'a [Option<Near>], &'a [std::cell::OnceCell<crate::poly::Poly<Interval>>]);

/// Whether one piece passes the verify path at one risk level per obstacle: inside the
/// workspace (exact check) and, for every obstacle, both constraints proven positive
/// on the general interval restriction in [`FramedContours`] with the exact rational
/// fallback (the `exact` method of [`verify`], without the compiled contours or the
/// covers of the fast path).
fn piece_passes_verify_path(
    scene: &Scene,
    framed: &FramedContours,
    near: Option<NearTests<'_>>,
    pr: PieceRef<'_>,
    deltas: &[RiskLevel],
) -> bool {
    if !pr.is_finite() || check_workspace(&scene.workspace.lower, &scene.workspace.upper, pr).status != Status::Safe {
        return false;
    }
    // the piece's bounding box (outward-rounded Bernstein hull of each coordinate), for
    // the box tests of distant obstacles
    let bbox = near.and_then(|_| workspace::interval_hull(pr));
    scene.obstacles.iter().zip(deltas).enumerate().all(|(i, (o, d))| {
        let omd = Interval::enclose_rational(&(BigRational::from_integer(1.into()) - d.rational()));
        if let (Some((Some(n), g1)), Some(b)) = (near.map(|(n, c)| (&n[i], &c[i])), &bbox) {
            if n.clears(b, Interval::new(pr.t0, pr.t1), g1.get_or_init(|| n.cantelli(omd))) {
                return true;
            }
        }
        let (cantelli, mean) = framed.restrict(i, o, pr, omd);
        let exact = std::cell::OnceCell::new();
        let exact = || exact.get_or_init(|| restrict_exact(&o.contour, pr, d.rational()));
        bernstein::check(&mean, || exact().mean.clone()).is_safe()
            && bernstein::check(&cantelli, || exact().cantelli.clone()).is_safe()
    })
}

/// Why the final check refused a planned trajectory (docs/design.md §5.12).
#[derive(Clone, Debug, PartialEq)]
pub enum FinalFailure {
    /// Not a valid trajectory of the problem: non-finite numbers, pieces that do not
    /// meet or leave the horizon, or not from the start to the goal (what `verify`
    /// refuses as input). A planner bug, not a fast-path one.
    Invalid(String),
    /// Piece `i` is not proven safe by the verify path: the fast path accepted what
    /// the verify path does not prove.
    NotProven(usize),
}

/// What the final check of a planned trajectory found (docs/design.md §5.12).
#[derive(Clone, Debug, PartialEq)]
pub struct FinalCheck {
    /// Why the trajectory is refused (`None`: valid, and every piece proven).
    pub failure: Option<FinalFailure>,
    /// Pieces checked.
    pub pieces: usize,
    /// Wall time, seconds.
    pub seconds: f64,
}

/// The final check of every planned trajectory before it is called certified
/// (docs/design.md §5.12): first the trajectory as `verify` takes it as input
/// ([`Trajectory::validate`]: finite, contiguous, inside the horizon, pieces that meet)
/// and from `start` to `goal` (within the same continuity tolerance); then each piece
/// through the verify path — the workspace exactly, every obstacle (no covers) by
/// general interval composition with the exact fallback — at the plan's per-obstacle
/// risk levels. It shares no code with the compiled fast path of the planners'
/// checker beyond the contour polynomials and the Bernstein decision. Asks `stop`
/// before each piece.
pub fn final_check(
    scene: &Scene,
    traj: &Trajectory,
    endpoints: (&[f64], &[f64]),
    deltas: &[RiskLevel],
    stop: &dyn Fn() -> bool,
) -> Result<FinalCheck, Interrupted> {
    let started = std::time::Instant::now();
    let done = |failure| FinalCheck { failure, pieces: traj.pieces.len(), seconds: started.elapsed().as_secs_f64() };
    let diag = crate::plan::dist(&scene.workspace.lower, &scene.workspace.upper);
    if let Err(e) = traj.validate(scene.dim, scene.horizon, diag) {
        return Ok(done(Some(FinalFailure::Invalid(e.to_string()))));
    }
    let tol = crate::scene::CONTINUITY_TOLERANCE * diag.max(1.0);
    let (first, last) = (&traj.pieces[0], &traj.pieces[traj.pieces.len() - 1]);
    for (which, at, want) in [("start", first.at(first.t0), endpoints.0), ("goal", last.at(last.t1), endpoints.1)] {
        let gap = at.iter().zip(want).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        if at.len() != want.len() || gap.is_nan() || gap > tol {
            return Ok(done(Some(FinalFailure::Invalid(format!("the trajectory misses the {which} by {gap:e}")))));
        }
    }
    if deltas.len() != scene.obstacles.len() {
        return Ok(done(Some(FinalFailure::Invalid("one risk level per obstacle is needed".into()))));
    }
    let framed = index::framed(scene);
    let near = framed.near(scene, stop)?;
    // each obstacle's Cantelli polynomial for the box tests, formed on first use
    let cantelli: Vec<std::cell::OnceCell<_>> = scene.obstacles.iter().map(|_| std::cell::OnceCell::new()).collect();
    let near = near.map(|n| (n, cantelli.as_slice()));
    for (i, pc) in traj.pieces.iter().enumerate() {
        if stop() {
            return Err(Interrupted);
        }
        let pr = PieceRef { t0: pc.t0, t1: pc.t1, coeffs: &pc.coeffs };
        if !piece_passes_verify_path(scene, &framed, near, pr, deltas) {
            return Ok(done(Some(FinalFailure::NotProven(i))));
        }
    }
    Ok(done(None))
}

/// Whether `x` at time `t` is strictly inside every Δ-contour (g1 > 0 and g2 > 0,
/// exactly) and inside the workspace.
pub fn point_safe(scene: &Scene, x: &[f64], t: f64, delta: &RiskLevel) -> bool {
    point_safe_with(scene, x, t, &vec![delta.clone(); scene.obstacles.len()])
}

/// Where a point stands at one instant (docs/design.md §3.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PointStatus {
    /// Inside the workspace and strictly inside every Δᵢ-contour, exactly.
    Safe,
    /// Outside the workspace box, or not finite.
    OutsideWorkspace,
    /// On or outside the Δᵢ-contour of obstacle `i` (the first such obstacle).
    InContour(usize),
}

/// The status of `x` at time `t` with one risk level per obstacle, exactly.
pub fn point_status(scene: &Scene, x: &[f64], t: f64, deltas: &[RiskLevel]) -> PointStatus {
    if !scene.workspace.contains(x) {
        return PointStatus::OutsideWorkspace;
    }
    let Some(mut xt) = x.iter().map(|&v| BigRational::from_float(v)).collect::<Option<Vec<_>>>() else {
        return PointStatus::OutsideWorkspace;
    };
    let Some(tq) = BigRational::from_float(t) else { return PointStatus::OutsideWorkspace };
    xt.push(tq);
    let bad = scene.obstacles.iter().zip(deltas).position(|(o, d)| {
        let one_minus = BigRational::from_integer(1.into()) - d.rational();
        let r = o.contour.risk_at(&xt);
        let g1 = &r.mean * &r.mean - &one_minus * &r.second_moment;
        !(r.mean.is_negative() && g1.is_positive())
    });
    bad.map_or(PointStatus::Safe, PointStatus::InContour)
}

/// [`point_safe`] with one risk level per obstacle.
pub fn point_safe_with(scene: &Scene, x: &[f64], t: f64, deltas: &[RiskLevel]) -> bool {
    point_status(scene, x, t, deltas) == PointStatus::Safe
}

/// The continuous-time certifier as a planner's motion checker: a piece is accepted
/// only when every constraint of every obstacle is proven positive on the piece and
/// the piece stays in the workspace. Stops at the first failure; the lower-degree
/// mean constraint is tried first.
///
/// Fast path (docs/design.md §5.10): the workspace is proven from the piece's
/// Bernstein bounding box (exact check otherwise); obstacles whose proven cover the
/// box misses are skipped ([`SceneIndex`]); the rest are decided on the compiled
/// restriction, with the exact rational fallback for undecided cases.
///
/// Each obstacle may have its own risk level Δᵢ (the joint risk mode: Σ Δᵢ = Δ bounds
/// the probability of colliding with any obstacle, by Boole's inequality).
#[derive(Debug)]
pub struct SceneCertifier {
    scene: Arc<Scene>,
    deltas: Vec<RiskLevel>,
    one_minus: Vec<(f64, bool)>,
    method: Method,
    settings: sos::SosSettings,
    compiled: Arc<Vec<CompiledContour>>,
    index: OnceLock<Arc<SceneIndex>>,
    /// Whether the fast path (covers, compiled restriction) is used; without it every
    /// obstacle is decided on every piece by the verify path ([`final_check`]'s).
    fast: bool,
}

impl SceneCertifier {
    /// A certifier for `scene` at risk `delta` for every obstacle.
    pub fn new(scene: Arc<Scene>, delta: RiskLevel, method: Method) -> Self {
        let deltas = vec![delta; scene.obstacles.len()];
        Self::with_deltas(scene, deltas, method)
    }

    /// A certifier with one risk level per obstacle (`deltas[i]` for obstacle `i`).
    pub fn with_deltas(scene: Arc<Scene>, deltas: Vec<RiskLevel>, method: Method) -> Self {
        assert_eq!(deltas.len(), scene.obstacles.len(), "one risk level per obstacle");
        let one_minus = deltas
            .iter()
            .map(|d| {
                let q = BigRational::from_integer(1.into()) - d.rational();
                let f = crate::poly::rational_to_f64(&q);
                (f, BigRational::from_float(f).is_some_and(|e| e == q))
            })
            .collect();
        let compiled = compiled(&scene);
        SceneCertifier {
            scene,
            deltas,
            one_minus,
            method,
            settings: sos::SosSettings::default(),
            compiled,
            index: OnceLock::new(),
            fast: true,
        }
    }

    /// The same certifier without the fast path: every obstacle on every piece by the
    /// verify path (general interval composition, exact fallback) — what a plan is
    /// re-planned with after the final check disagreed with the fast path
    /// (docs/design.md §5.12).
    pub fn without_fast_path(mut self) -> Self {
        self.fast = false;
        self
    }

    /// A certifier that does not build covers for its own use: it uses the scene's
    /// cached index when there is one and otherwise checks every obstacle on every
    /// piece (sound either way). For planners that check a handful of pieces, for
    /// which building the covers (milliseconds per moving obstacle) would cost more
    /// than it saves.
    pub fn without_index_build(self) -> Self {
        let index = SceneIndex::peek(&self.scene, &self.deltas)
            .unwrap_or_else(|| Arc::new(SceneIndex::build(&self.scene, &self.deltas, &|| true)));
        let _ = self.index.set(index);
        self
    }

    /// The per-obstacle risk levels.
    pub fn deltas(&self) -> &[RiskLevel] {
        &self.deltas
    }

    /// The index, built (without interruption) if [`MotionChecker::prepare`] did not.
    pub fn index(&self) -> &Arc<SceneIndex> {
        self.index.get_or_init(|| SceneIndex::cached(&self.scene, &self.deltas, &|| false))
    }

    /// Whether obstacle `i` is proven safe on a piece (Exact method, fast path; `subs`:
    /// the piece's centred coordinates, shared by all obstacles).
    fn obstacle_safe(&self, i: usize, pr: PieceRef<'_>, subs: Option<&Substitution>) -> bool {
        let o = &self.scene.obstacles[i];
        let delta = self.deltas[i].rational();
        if self.method == Method::Exact {
            let fast = subs.and_then(|subs| {
                self.compiled[i].with_constraints(subs, self.one_minus[i], |g2, g1| {
                    for g in [g2, g1] {
                        match bernstein::check_interval_coeffs(g, bernstein::DEFAULT_MAX_DEPTH) {
                            Verdict::Safe { .. } => {}
                            Verdict::Unsafe(_) => return Some(false),
                            Verdict::Undecided(_) => return None,
                        }
                    }
                    Some(true)
                })
            });
            match fast {
                Some(Some(v)) => return v,
                Some(None) => {
                    // undecided in floats: the exact rational check decides both constraints
                    let r = restrict_exact(&o.contour, pr, delta);
                    return [&r.mean, &r.cantelli]
                        .iter()
                        .all(|p| bernstein::check_exact(p, bernstein::DEFAULT_MAX_DEPTH).is_safe());
                }
                None => {}
            }
        }
        let mut safe = true;
        decide_obstacle(o, Some(&self.compiled[i]), pr, delta, self.method, &self.settings, |_, vs| {
            safe = combine(&vs) == Status::Safe;
            safe
        });
        safe
    }
}

/// Whether a coordinate of degree ≤ 1, `c0 + c1·t` on `[t0, t1]`, stays in `[l, u]`,
/// exactly (its extremes are its end values, evaluated in rationals): the float
/// enclosure of an edge that ends on the workspace boundary crosses it by rounding.
fn straight_coordinate_inside(c: &[f64], t0: f64, t1: f64, l: f64, u: f64) -> bool {
    if c.len() > 2 {
        return false;
    }
    let q = |v: f64| BigRational::from_float(v);
    let (Some(c0), Some(c1), Some(a), Some(b), Some(l), Some(u)) =
        (q(c.first().copied().unwrap_or(0.0)), q(c.get(1).copied().unwrap_or(0.0)), q(t0), q(t1), q(l), q(u))
    else {
        return false;
    };
    [a, b].iter().all(|t| {
        let x = &c0 + &c1 * t;
        l <= x && x <= u
    })
}

impl MotionChecker for SceneCertifier {
    fn name(&self) -> &str {
        self.method.as_str()
    }

    fn sound(&self) -> bool {
        true
    }

    fn prepare(&self, term: &Termination) {
        if !self.fast {
            return;
        }
        let _ = self.index.get_or_init(|| SceneIndex::cached(&self.scene, &self.deltas, &|| term.expired()));
    }

    fn check(&self, piece: &Piece) -> Motion {
        let pr = PieceRef { t0: piece.t0, t1: piece.t1, coeffs: &piece.coeffs };
        if !pr.is_finite() {
            return Motion::Rejected;
        }
        if !self.fast {
            return if piece_passes_verify_path(&self.scene, &index::framed(&self.scene), None, pr, &self.deltas) {
                Motion::Accepted
            } else {
                Motion::Rejected
            };
        }
        let ws = &self.scene.workspace;
        let bbox = piece_bbox(pr);
        let inside = bbox.as_ref().is_some_and(|b| {
            b.iter().zip(ws.lower.iter().zip(&ws.upper)).enumerate().all(|(d, (&(lo, hi), (&l, &u)))| {
                (l <= lo && hi <= u) || straight_coordinate_inside(&piece.coeffs[d], piece.t0, piece.t1, l, u)
            })
        });
        if !inside && check_workspace(&ws.lower, &ws.upper, pr).status != Status::Safe {
            return Motion::Rejected;
        }
        let mut cands = Vec::new();
        self.index().candidates(bbox.as_deref(), piece.t0, piece.t1, &mut cands);
        let subs = match (cands.is_empty(), self.compiled.first()) {
            (false, Some(c)) => Substitution::new(pr, c.frame()),
            _ => None,
        };
        for i in cands {
            if !self.obstacle_safe(i, pr, subs.as_ref()) {
                return Motion::Rejected;
            }
        }
        Motion::Accepted
    }

    fn blocking_obstacle(&self, x: &[f64], t: f64) -> Option<String> {
        match point_status(&self.scene, x, t, &self.deltas) {
            PointStatus::InContour(i) => Some(self.scene.obstacles[i].id.clone()),
            _ => None,
        }
    }

    fn check_point(&self, x: &[f64], t: f64) -> Motion {
        if !self.scene.workspace.contains(x) {
            return Motion::Rejected;
        }
        // obstacles whose proven cover misses the point are safe there; the others are
        // decided exactly
        let bbox: Vec<(f64, f64)> = x.iter().map(|&v| (v, v)).collect();
        let mut cands = Vec::new();
        if self.fast {
            self.index().candidates(Some(&bbox), t, t, &mut cands);
        } else {
            cands.extend(0..self.scene.obstacles.len());
        }
        let Some(mut xt) = x.iter().map(|&v| BigRational::from_float(v)).collect::<Option<Vec<_>>>() else {
            return Motion::Rejected;
        };
        let Some(tq) = BigRational::from_float(t) else { return Motion::Rejected };
        xt.push(tq);
        for i in cands {
            let one_minus = BigRational::from_integer(1.into()) - self.deltas[i].rational();
            let r = self.scene.obstacles[i].contour.risk_at(&xt);
            let g1 = &r.mean * &r.mean - &one_minus * &r.second_moment;
            if !(r.mean.is_negative() && g1.is_positive()) {
                return Motion::Rejected;
            }
        }
        Motion::Accepted
    }
}
