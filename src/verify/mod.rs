//! Verification of trajectories against a scene: the reports behind `riskplan verify`
//! and the service's edge-verification query ([`verify`], [`verify_until`]), the final
//! check of every planned trajectory ([`final_check`], docs/design.md §5.12), and the
//! Monte Carlo audits ([`audit_trajectory`]).
//!
//! The decisions themselves are the certifiers' (`certify::scene`): for each piece and
//! obstacle both constraints of eq. (15) are decided on [0, 1] (docs/design.md §5) by
//! the exact checker (Bernstein subdivision in outward-rounded interval arithmetic,
//! exact rational fallback), the SOS certificate (Clarabel, rigorously re-checked), or
//! both. Only a proof counts as safe: an undecided constraint makes the piece unsafe.
//! The workspace box is checked exactly (non-strictly: start and goal may lie on it).

mod audit;

use crate::certify::fast::CompiledContour;
use crate::certify::scene::{combine, decide_obstacle, piece_passes_verify_path, worst};
use crate::certify::sos;
use crate::certify::{PieceRef, Undecided, Verdict};
use crate::certify::bounds::{CoverFailure, Level, PieceBounds};
use crate::contour::{BoundChoice, BoundKind, RiskLevel};
use crate::scene::{Obstacle, Trajectory};
use serde::{Deserialize, Serialize};

pub use crate::certify::scene::{
    check_workspace, point_safe, point_safe_with, point_status, Interrupted, Method, PointStatus, SceneCertifier,
    SceneIndex, SceneKernel, Status, WitnessReport, WorkspaceStatus,
};
pub use audit::{audit_trajectory, audit_trajectory_joint, Audit, AuditOptions, Exceedance};

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
    /// `mean` (−E\[P\] > 0) or `cantelli` (E\[P\]² − (1−Δ)E\[P²\] > 0).
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
    /// Which bound proved which part of the piece (absolute times), when it is safe:
    /// one `cantelli` part when Cantelli's constraints hold on the whole piece, else the
    /// sub-intervals of the cover (docs/design.md §5.13). Empty when not safe.
    #[serde(default)]
    pub bounds: Vec<BoundPartReport>,
    /// Why no bound proves the piece, when it is not safe and bounds beyond Cantelli were
    /// allowed (with the absolute time where the search stopped). Always serialized
    /// (`null` when absent): bincode is not self-describing, so a skipped field would
    /// make the reply undecodable.
    #[serde(default)]
    pub not_covered: Option<String>,
}

/// One part of a piece proven by one bound.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BoundPartReport {
    /// Start (absolute time).
    pub t0: f64,
    /// End (absolute time).
    pub t1: f64,
    /// `cantelli`, `support`, `moment4`, `moment6` or `moment8`.
    pub bound: BoundKind,
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
    /// The bounds allowed (`auto` or `cantelli`).
    #[serde(default)]
    pub bound: BoundChoice,
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

/// Verifies one obstacle over one piece, constraint by constraint.
pub fn verify_obstacle(
    o: &Obstacle,
    piece: PieceRef<'_>,
    delta: &RiskLevel,
    method: Method,
    settings: &sos::SosSettings,
) -> ObstacleReport {
    verify_obstacle_with(o, None, piece, delta, method, settings, BoundChoice::default())
}

/// [`verify_obstacle`] with the obstacle's compiled contour (the fast restriction).
pub fn verify_obstacle_with(
    o: &Obstacle,
    compiled: Option<&CompiledContour>,
    piece: PieceRef<'_>,
    delta: &RiskLevel,
    method: Method,
    settings: &sos::SosSettings,
    bounds: BoundChoice,
) -> ObstacleReport {
    if let (Some(p), true) = (&o.pedestrian, bounds.beyond_cantelli()) {
        return verify_pedestrian(o, p, piece, delta, method);
    }
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
    let at = |tau: f64| piece.t0 + (piece.t1 - piece.t0) * tau;
    let mut report = ObstacleReport { id: o.id.clone(), status, constraints, bounds: Vec::new(), not_covered: None };
    if status == Status::Safe {
        report.bounds.push(BoundPartReport { t0: piece.t0, t1: piece.t1, bound: BoundKind::Cantelli });
        return report;
    }
    let mean_unsafe = report.constraints.first().is_some_and(|c| c.name == "mean" && c.status == Status::Unsafe);
    if !bounds.beyond_cantelli() {
        return report;
    }
    if mean_unsafe {
        report.not_covered = Some("E[P] >= 0 on the piece: no bound applies".into());
        return report;
    }
    let hint = report.constraints.iter().find_map(|c| c.witness.map(|w| (w.t - piece.t0) / (piece.t1 - piece.t0)));
    let hint = hint.filter(|h| h.is_finite());
    let level = Level::new(delta.rational());
    // the general composition first, then the compiled one in the scene's frame (which keeps
    // its digits at extreme scales), as the final check does (docs/design.md §5.13)
    let general = PieceBounds::for_piece(&o.contour, piece, level).cover(hint);
    let cover = match (general, compiled) {
        (Err(_), Some(c)) => PieceBounds::for_piece_compiled(&o.contour, c, piece, level).cover(hint),
        (r, _) => r,
    };
    match cover {
        Ok(parts) => {
            report.status = Status::Safe;
            report.bounds =
                parts.iter().map(|p| BoundPartReport { t0: at(p.tau0), t1: at(p.tau1), bound: p.bound }).collect();
        }
        Err(f) => {
            report.not_covered = Some(match f {
                CoverFailure::MeanNotNegative { tau } => format!("E[P] >= 0 at t = {}: no bound applies", at(tau)),
                CoverFailure::AboveDelta { tau, best } => {
                    format!("every bound is above the risk level at t = {} (smallest {best:.3e})", at(tau))
                }
                CoverFailure::Budget { tau } => {
                    format!("no bound proves the piece near t = {} within the search limits", at(tau))
                }
            })
        }
    }
    report
}

/// A pedestrian over one piece by its Gaussian tail bound, exactly (docs/design.md
/// §3.11): one constraint, `tail`, `‖x − m(t)‖² − r(t)² > 0` on the piece.
fn verify_pedestrian(o: &Obstacle, p: &crate::scene::Pedestrian, piece: PieceRef<'_>, delta: &RiskLevel, method: Method) -> ObstacleReport {
    let v = crate::certify::tail::piece_clear_exact(p, delta.rational(), piece);
    let r = method_report(&v, piece);
    let safe = r.status == Status::Safe;
    ObstacleReport {
        id: o.id.clone(),
        status: r.status,
        constraints: vec![ConstraintReport {
            name: "tail".into(),
            status: r.status,
            margin: r.margin,
            witness: r.witness,
            reason: r.reason,
            method: method.as_str().to_string(),
            methods: None,
        }],
        bounds: if safe { vec![BoundPartReport { t0: piece.t0, t1: piece.t1, bound: BoundKind::Tail }] } else { Vec::new() },
        not_covered: (!safe).then(|| "the piece comes within the pedestrian's Δ-radius (tail bound)".to_string()),
    }
}

/// Verifies a trajectory against a scene (or its [`SceneKernel`], to reuse its
/// compiled contours) at risk level `delta`.
pub fn verify(
    scene: impl Into<SceneKernel>,
    traj: &Trajectory,
    delta: &RiskLevel,
    method: Method,
    settings: &sos::SosSettings,
) -> VerifyReport {
    // `stop` never says yes, so this is never interrupted; were it, the answer would
    // be "not safe" with no pieces, never a false "safe".
    verify_until(&scene.into(), traj, delta, method, settings, BoundChoice::default(), &|| false).unwrap_or_else(
        |Interrupted| VerifyReport {
            safe: false,
            method: method.as_str().to_string(),
            risk: delta.to_f64(),
            bound: BoundChoice::default(),
            pieces: Vec::new(),
        },
    )
}

/// [`verify`] that asks `stop` before each piece and obstacle and gives up with
/// `Interrupted` as soon as it says yes (a service deadline). One check of one piece
/// against one obstacle is the largest step between two questions.
pub fn verify_until(
    kernel: &SceneKernel,
    traj: &Trajectory,
    delta: &RiskLevel,
    method: Method,
    settings: &sos::SosSettings,
    bounds: BoundChoice,
    stop: &dyn Fn() -> bool,
) -> Result<VerifyReport, Interrupted> {
    let scene = kernel.scene();
    let mut pieces = Vec::with_capacity(traj.pieces.len());
    let compiled = kernel.compiled();
    for pc in &traj.pieces {
        let pr = PieceRef { t0: pc.t0, t1: pc.t1, coeffs: &pc.coeffs };
        let workspace = check_workspace(&scene.workspace.lower, &scene.workspace.upper, pr);
        let mut obstacles = Vec::with_capacity(scene.obstacles.len());
        for (i, o) in scene.obstacles.iter().enumerate() {
            if stop() {
                return Err(Interrupted);
            }
            let c = o.pedestrian.is_none().then(|| compiled.get(i));
            obstacles.push(verify_obstacle_with(o, c, pr, delta, method, settings, bounds));
        }
        let safe = workspace.status == Status::Safe && obstacles.iter().all(|o| o.status == Status::Safe);
        pieces.push(PieceReport { t0: pc.t0, t1: pc.t1, safe, workspace, obstacles });
    }
    Ok(VerifyReport {
        safe: pieces.iter().all(|p| p.safe),
        method: method.as_str().to_string(),
        risk: delta.to_f64(),
        bound: bounds,
        pieces,
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

/// How far after the problem's start time the first piece of a plan may begin (relative
/// to the larger of |t_start|, the horizon's length and 1): the planners compute their
/// first piece's start in floating point, a few ulps off at most; a plan that begins
/// later leaves its beginning unproven and is refused (issue 20 review).
pub const START_TIME_TOLERANCE: f64 = 1e-12;

/// The final check of every planned trajectory before it is called certified
/// (docs/design.md §5.12): first the trajectory as `verify` takes it as input
/// ([`Trajectory::validate`]: finite, contiguous, inside the horizon, pieces that meet)
/// and from `start` to `goal` (within the same continuity tolerance); then each piece
/// through the verify path — the workspace exactly, every obstacle (no covers) by
/// general interval composition with the exact fallback — at the plan's per-obstacle
/// risk levels. Its Cantelli path shares no code with the compiled fast path of the
/// planners' checker beyond the contour polynomials and the Bernstein decision; with
/// `bound: auto`, a piece the general composition of the other bounds cannot cover is
/// tried once more with their compiled restriction (docs/design.md §5.13: at extreme
/// scales only the frame keeps the digits), so there the final check is not independent
/// of the fast path — the bound oracle tests are. Asks `stop` before each piece.
pub fn final_check(
    kernel: &SceneKernel,
    traj: &Trajectory,
    endpoints: (&[f64], Option<&[f64]>),
    t_start: f64,
    deltas: &[RiskLevel],
    bounds: BoundChoice,
    stop: &dyn Fn() -> bool,
) -> Result<FinalCheck, Interrupted> {
    let scene = kernel.scene();
    let started = std::time::Instant::now();
    let done = |failure| FinalCheck { failure, pieces: traj.pieces.len(), seconds: started.elapsed().as_secs_f64() };
    let diag = crate::motion::dist(&scene.workspace.lower, &scene.workspace.upper);
    if let Err(e) = traj.validate(scene.dim, scene.horizon, diag) {
        return Ok(done(Some(FinalFailure::Invalid(e.to_string()))));
    }
    let tol = crate::scene::CONTINUITY_TOLERANCE * diag.max(1.0);
    let (first, last) = (&traj.pieces[0], &traj.pieces[traj.pieces.len() - 1]);
    // the plan covers its problem from its start: nothing before the first piece is proven
    let slack = START_TIME_TOLERANCE * t_start.abs().max(scene.horizon.1 - scene.horizon.0).max(1.0);
    if first.t0 > t_start + slack {
        return Ok(done(Some(FinalFailure::Invalid(format!(
            "the trajectory starts at t = {}, not at the problem's start t = {t_start}",
            first.t0
        )))));
    }
    let ends = [("start", first.at(first.t0), Some(endpoints.0)), ("goal", last.at(last.t1), endpoints.1)];
    for (which, at, want) in ends.iter().filter_map(|(w, a, e)| Some((*w, a, (*e)?))) {
        let gap = at.iter().zip(want).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        if at.len() != want.len() || gap.is_nan() || gap > tol {
            return Ok(done(Some(FinalFailure::Invalid(format!("the trajectory misses the {which} by {gap:e}")))));
        }
    }
    if deltas.len() != scene.obstacles.len() {
        return Ok(done(Some(FinalFailure::Invalid("one risk level per obstacle is needed".into()))));
    }
    let framed = kernel.framed();
    let compiled = bounds.beyond_cantelli().then(|| kernel.compiled());
    let near = framed.near(scene, stop)?;
    // each obstacle's Cantelli polynomial for the box tests, formed on first use
    let cantelli: Vec<std::cell::OnceCell<_>> = scene.obstacles.iter().map(|_| std::cell::OnceCell::new()).collect();
    let near = near.map(|n| (n, cantelli.as_slice()));
    for (i, pc) in traj.pieces.iter().enumerate() {
        if stop() {
            return Err(Interrupted);
        }
        let pr = PieceRef { t0: pc.t0, t1: pc.t1, coeffs: &pc.coeffs };
        if !piece_passes_verify_path(scene, &framed, near, pr, deltas, bounds, compiled.as_deref()) {
            return Ok(done(Some(FinalFailure::NotProven(i))));
        }
    }
    Ok(done(None))
}
