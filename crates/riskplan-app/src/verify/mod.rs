//! Verification of trajectories against a scene: the reports behind `riskplan verify`
//! and the service's edge-verification query ([`verify`], [`verify_until`]), the final
//! check of every planned trajectory ([`final_check`], docs/design.md §5.12), and the
//! Monte Carlo audits ([`audit_trajectory`]).
//!
//! The decisions themselves are the certifiers' (`certify::checker`): for each piece and
//! obstacle both constraints of eq. (15) are decided on [0, 1] (docs/design.md §5) by
//! the exact checker (Bernstein subdivision in outward-rounded interval arithmetic,
//! exact rational fallback), the SOS certificate (Clarabel, rigorously re-checked), or
//! both. Only a proof counts as safe: an undecided constraint makes the piece unsafe.
//! The workspace box is checked exactly (non-strictly: start and goal may lie on it).

mod audit;

use riskplan_certify::checker::{
    combine, decide_obstacle, inside_by_box, piece_bbox, piece_passes_verify_path, worst, ObstacleFinding,
};
use riskplan_certify::compiled::{CompiledContour, Substitution};
use riskplan_certify::piece_bounds::{CoverFailure, Level, PieceBounds};
use riskplan_certify::positivity::sos;
use riskplan_certify::{PieceRef, Undecided, Verdict};
use riskplan_math::contour::{BoundChoice, BoundKind, RiskLevel};
use riskplan_scene::{Obstacle, Trajectory};
use serde::{Deserialize, Serialize};

pub use audit::{audit_trajectory, audit_trajectory_joint, audit_whole_path, Audit, AuditOptions, Exceedance};
pub use riskplan_certify::checker::{
    check_workspace, point_safe, point_safe_with, point_status, Interrupted, Method, PointStatus, SceneCertifier,
    SceneIndex, SceneKernel, Status, WitnessReport, WorkspaceStatus,
};

/// One method's verdict on one constraint.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
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
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ConstraintReport {
    /// `mean` (−E\[P\] > 0) or `cantelli` (E\[P\]² − (1−Δ)E\[P²\] > 0).
    #[schemars(extend("enum" = ["mean", "cantelli"]))]
    pub name: String,
    /// Combined status.
    pub status: Status,
    /// Proven lower bound on the constraint's minimum over the piece (safe), or the
    /// witness value (unsafe), combined over the methods.
    pub margin: Option<f64>,
    /// Witness (unsafe), combined over the methods.
    pub witness: Option<WitnessReport>,
    /// The method(s) used.
    pub method: String,
    /// Why undecided (the first method's reason).
    pub reason: Option<String>,
    /// Per method, with `--method both`.
    pub methods: Option<Vec<(String, MethodReport)>>,
}

/// One obstacle over one piece.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
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
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct BoundPartReport {
    /// Start (absolute time).
    pub t0: f64,
    /// End (absolute time).
    pub t1: f64,
    /// `cantelli`, `support`, `moment4`, `moment6` or `moment8`.
    pub bound: BoundKind,
}

/// One piece.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
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
    /// Per piece, or only the first not proven safe ([`Detail::FirstNotSafe`]).
    pub pieces: Vec<PieceReport>,
    /// Pieces decided.
    #[serde(default)]
    pub checked: usize,
    /// How many of them are not proven safe.
    #[serde(default)]
    pub not_safe: usize,
    /// Index of the first piece not proven safe.
    #[serde(default)]
    pub first_not_safe: Option<usize>,
    /// The certified bound on the probability of meeting any obstacle at any time of the
    /// trajectory, when asked for ([`VerifyOptions::whole_path`], docs/design.md §5.14).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub whole_path_risk: Option<WholePathRisk>,
}

/// The whole-path bound of a trajectory (docs/design.md §5.14): with ω drawn once,
/// P(∃ t, ∃ obstacle : x(t) in it) ≤ `bound` — beyond the per-instant risk the other
/// fields certify.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct WholePathRisk {
    /// The sum over the obstacles (Boole) of their bounds, at most 1 (a float at or above
    /// the exact sum).
    pub bound: f64,
    /// Per obstacle, in the scene's order.
    pub obstacles: Vec<ObstacleWholePath>,
}

/// One obstacle's part of a [`WholePathRisk`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ObstacleWholePath {
    /// The obstacle's id.
    pub id: String,
    /// P(∃ t : x(t) in this obstacle) ≤ `bound` (a float at or above the exact bound).
    pub bound: f64,
    /// `partition`: the parameter space partitioned over every piece at once; `pooled`:
    /// one moment envelope over every piece's coefficients; `sum`: the pieces' moment
    /// bounds added up.
    pub how: riskplan_certify::whole_path::PathRiskHow,
    /// Each piece's own bound, in order.
    pub pieces: Vec<f64>,
}

/// Most pieces whose whole-path bound [`verify_with`] computes (a piece near an obstacle
/// costs tens of milliseconds of exact arithmetic: example-d1's 7-piece plan takes 3 s):
/// longer trajectories get a typed error from the front ends.
pub const MAX_WHOLE_PATH_PIECES: usize = 2_000;

/// The whole-path bound of `pieces` against every obstacle of the kernel's scene
/// (docs/design.md §5.14): [`riskplan_certify::whole_path::trajectory_path_risk`] per
/// obstacle, summed (Boole). Asks `stop` between steps.
pub fn whole_path_risk(
    kernel: &SceneKernel,
    pieces: &[riskplan_scene::Piece],
    stop: &dyn Fn() -> bool,
) -> Result<WholePathRisk, Interrupted> {
    use riskplan_certify::whole_path::trajectory_path_risk;
    let scene = kernel.scene();
    let refs: Vec<PieceRef<'_>> = pieces.iter().map(|p| PieceRef { t0: p.t0, t1: p.t1, coeffs: &p.coeffs }).collect();
    let mut total = 0.0f64;
    let mut obstacles = Vec::with_capacity(scene.obstacles.len());
    // each obstacle in its own frame (§5.14)
    let frames = kernel.path_frames(stop)?;
    for (o, frame) in scene.obstacles.iter().zip(frames.iter()) {
        let r = trajectory_path_risk(o.contour.get(), &refs, frame, stop).ok_or(Interrupted)?;
        // the sum rounded up: a float at or above the exact sum of the obstacles' bounds
        total = riskplan_certify::whole_path::add_up(total, r.bound);
        obstacles.push(ObstacleWholePath { id: o.id.clone(), bound: r.bound, how: r.how, pieces: r.pieces });
    }
    Ok(WholePathRisk { bound: total.min(1.0), obstacles })
}

/// The whole-path bound of a plan (docs/design.md §5.14), as the final check reports it:
/// per obstacle one partition over all pieces at once ([`cells_path_risk`] with `effort`;
/// no per-piece breakdown), or — when `envelopes` allows it — the moment envelopes for an
/// obstacle with a parameter of no rigorous distribution function (exact arithmetic:
/// seconds on long plans; `Ok(None)` without it); summed over the obstacles (Boole),
/// rounded up, at most 1.
///
/// `slack`: how much the sum may exceed, in all, what `effort` alone would give — shared
/// evenly by the obstacles whose partition may run, those whose reach does not clear
/// the whole plan (the others add their laws' outside mass, with no slack): each one's
/// partition ends once its undecided probability is within its share
/// ([`CellEffort::with_slack`]). 0 (or not a number): none.
///
/// [`cells_path_risk`]: riskplan_certify::whole_path::cells_path_risk
/// [`CellEffort::with_slack`]: riskplan_certify::whole_path::CellEffort::with_slack
pub fn plan_whole_path_risk(
    kernel: &SceneKernel,
    pieces: &[riskplan_scene::Piece],
    effort: riskplan_certify::whole_path::CellEffort,
    slack: f64,
    envelopes: bool,
    stop: &dyn Fn() -> bool,
) -> Result<Option<f64>, Interrupted> {
    WholePathWork::new(kernel.clone(), pieces.to_vec(), effort, slack, envelopes).finish(stop)
}

/// [`plan_whole_path_risk`] as work two threads may share (docs/design.md §5.12, §5.14):
/// the obstacles whose reach the pieces enter are bounded one at a time, each by the
/// thread that claims it first ([`WholePathWork::run`]), and [`WholePathWork::finish`]
/// adds the bounds up in the obstacles' order, as one thread alone does — the answer does
/// not depend on which thread bounded what (each obstacle's partition depends only on its
/// own inputs). A plan starts it on the thread beside its final check and joins in when
/// its check is done: on 512 disks one or two obstacles the plan passes near take most of
/// the bound (400 boxes each), and the check alone was shorter than the bound.
pub struct WholePathWork {
    kernel: SceneKernel,
    pieces: Vec<riskplan_scene::Piece>,
    effort: riskplan_certify::whole_path::CellEffort,
    slack: f64,
    envelopes: bool,
    /// The obstacles' frames and reaches and the pieces' boxes, found by the first thread
    /// that runs (`Err`: it was stopped first).
    setup: std::sync::OnceLock<Result<WholePathSetup, Interrupted>>,
    /// The next obstacle of `setup.open` to claim.
    next: std::sync::atomic::AtomicUsize,
    /// Signalled (under its lock) whenever a claimed obstacle's bound is stored.
    stored: (std::sync::Mutex<()>, std::sync::Condvar),
    /// The sum is decided ([`Self::finish`] returned): nothing more is claimed.
    decided: std::sync::atomic::AtomicBool,
    /// When the first thread started, and the seconds from then to the sum.
    started: std::sync::OnceLock<std::time::Instant>,
    finished: std::sync::OnceLock<f64>,
}

/// What [`WholePathWork`] finds once.
struct WholePathSetup {
    frames: std::sync::Arc<Vec<riskplan_certify::compiled::Frame>>,
    reaches: Vec<Option<std::sync::Arc<riskplan_certify::whole_path::Reach>>>,
    boxes: riskplan_certify::whole_path::PieceBoxes,
    /// Per obstacle: its reach clears every piece (its bound is its laws' outside mass).
    cleared: Vec<bool>,
    /// The others, in increasing order, and each one's bound once found.
    open: Vec<usize>,
    bounds: Vec<std::sync::OnceLock<ObstacleBound>>,
    /// `effort` with each open obstacle's share of the slack.
    effort: riskplan_certify::whole_path::CellEffort,
}

/// One obstacle's part of a whole-path bound.
#[derive(Clone, Copy, Debug, PartialEq)]
enum ObstacleBound {
    Bound(f64),
    /// Neither the partition nor (without envelopes) anything else applies.
    None,
    Interrupted,
}

impl WholePathWork {
    /// The bound of `pieces` on `kernel`'s scene with `effort`, `slack` and `envelopes` as
    /// in [`plan_whole_path_risk`]; nothing is computed until a thread runs it.
    pub fn new(
        kernel: SceneKernel,
        pieces: Vec<riskplan_scene::Piece>,
        effort: riskplan_certify::whole_path::CellEffort,
        slack: f64,
        envelopes: bool,
    ) -> WholePathWork {
        WholePathWork {
            kernel,
            pieces,
            effort,
            slack,
            envelopes,
            setup: Default::default(),
            next: Default::default(),
            stored: Default::default(),
            decided: Default::default(),
            started: Default::default(),
            finished: Default::default(),
        }
    }

    fn refs(&self) -> Vec<PieceRef<'_>> {
        self.pieces.iter().map(|p| PieceRef { t0: p.t0, t1: p.t1, coeffs: &p.coeffs }).collect()
    }

    fn setup(&self, stop: &dyn Fn() -> bool) -> &Result<WholePathSetup, Interrupted> {
        use riskplan_certify::whole_path::PieceBoxes;
        self.setup.get_or_init(|| {
            // each obstacle in its own frame (§5.14)
            let (frames, reaches, grid) = self.kernel.path_reaches(stop)?;
            let boxes = PieceBoxes::new(&self.refs(), self.kernel.scene().dim);
            // the obstacles whose reach may not clear the pieces: from the grid of the
            // reaches (every other one's reach clears them: its bound is its laws'
            // outside mass), or all
            let candidates = grid.and_then(|g| g.candidates(&boxes));
            let examined = |i: usize| candidates.as_ref().is_none_or(|c| c[i]);
            // those whose reach does not clear them share the slack (an obstacle without
            // a reach counts among them: the grid never leaves one out)
            let clears = |i: usize| reaches[i].as_ref().is_some_and(|r| !examined(i) || r.clears_all(&boxes));
            let cleared: Vec<bool> = (0..reaches.len()).map(clears).collect();
            let open: Vec<usize> = (0..reaches.len()).filter(|&i| !cleared[i]).collect();
            let effort = self.effort.with_slack(self.slack / open.len().max(1) as f64);
            let bounds = open.iter().map(|_| std::sync::OnceLock::new()).collect();
            Ok(WholePathSetup { frames, reaches, boxes, cleared, open, bounds, effort })
        })
    }

    /// One obstacle's bound (`i`, open).
    fn bound_one(
        &self,
        setup: &WholePathSetup,
        refs: &[PieceRef<'_>],
        i: usize,
        stop: &dyn Fn() -> bool,
    ) -> ObstacleBound {
        use riskplan_certify::whole_path::{cells_path_risk_in, trajectory_path_risk};
        let c = self.kernel.scene().obstacles[i].contour.get();
        let (frame, reach) = (&setup.frames[i], setup.reaches[i].as_deref());
        match cells_path_risk_in(c, refs, &setup.boxes, frame, reach, setup.effort, stop) {
            Some(b) => ObstacleBound::Bound(b.bound),
            None if stop() => ObstacleBound::Interrupted,
            None if !self.envelopes => ObstacleBound::None,
            None => trajectory_path_risk(c, refs, frame, stop)
                .map_or(ObstacleBound::Interrupted, |b| ObstacleBound::Bound(b.bound)),
        }
    }

    /// Claims the next obstacle not claimed yet and bounds it; `false` when none is left
    /// or the sum is decided.
    fn claim_one(&self, setup: &WholePathSetup, refs: &[PieceRef<'_>], stop: &dyn Fn() -> bool) -> bool {
        use std::sync::atomic::Ordering;
        /// Marks a claimed obstacle done when dropped, interrupted unless bounded (a
        /// panicking thread leaves no claim for the others to wait on).
        struct Claim<'a>(&'a WholePathWork, &'a std::sync::OnceLock<ObstacleBound>);
        impl Drop for Claim<'_> {
            fn drop(&mut self) {
                let _ = self.1.set(ObstacleBound::Interrupted);
                let (lock, signal) = &self.0.stored;
                // (a poisoned lock still orders the store before the signal)
                let _held = lock.lock().unwrap_or_else(|e| e.into_inner());
                signal.notify_all();
            }
        }
        if self.decided.load(Ordering::Relaxed) {
            return false;
        }
        let k = self.next.fetch_add(1, Ordering::Relaxed);
        let (Some(&i), Some(slot)) = (setup.open.get(k), setup.bounds.get(k)) else { return false };
        let claim = Claim(self, slot);
        let _ = claim.1.set(self.bound_one(setup, refs, i, stop));
        true
    }

    /// Bounds obstacles not claimed yet, one at a time, until none is left or the sum is
    /// decided (or `stop` says stop: the obstacle then counts as interrupted, and
    /// [`Self::finish`] bounds it again unless its own `stop` says stop too). Any number
    /// of threads may run at once.
    pub fn run(&self, stop: &dyn Fn() -> bool) {
        self.started.get_or_init(std::time::Instant::now);
        let Ok(setup) = self.setup(stop) else { return };
        let refs = self.refs();
        while self.claim_one(setup, &refs, stop) {}
    }

    /// Adds the bounds up in the obstacles' order, as one thread alone does — bounding
    /// here each obstacle no thread has claimed yet when the sum reaches it, waiting for
    /// one another thread is bounding, and bounding again one whose thread was stopped or
    /// failed: the bound, at most 1 (ending, as alone, at a sum of 1); `Ok(None)` when an
    /// obstacle has none; `Err` when `stop` says stop. The other threads claim nothing
    /// after it returns.
    pub fn finish(&self, stop: &dyn Fn() -> bool) -> Result<Option<f64>, Interrupted> {
        let started = *self.started.get_or_init(std::time::Instant::now);
        let answer = match self.setup(stop) {
            Ok(setup) => self.add_up(setup, &self.refs(), stop),
            Err(e) => Err(*e),
        };
        self.decided.store(true, std::sync::atomic::Ordering::Relaxed);
        let _ = self.finished.set(started.elapsed().as_secs_f64());
        answer
    }

    fn add_up(
        &self,
        setup: &WholePathSetup,
        refs: &[PieceRef<'_>],
        stop: &dyn Fn() -> bool,
    ) -> Result<Option<f64>, Interrupted> {
        let mut total = 0.0f64;
        let mut k = 0;
        for (i, reach) in setup.reaches.iter().enumerate() {
            let b = match reach.as_ref().filter(|_| setup.cleared[i]) {
                Some(r) => r.cleared_bound(),
                None => {
                    // (every obstacle not cleared is open, in order)
                    let (Some(&j), Some(slot)) = (setup.open.get(k), setup.bounds.get(k)) else {
                        return Err(Interrupted);
                    };
                    if j != i {
                        return Err(Interrupted);
                    }
                    k += 1;
                    let found = loop {
                        if let Some(b) = slot.get() {
                            break *b;
                        }
                        // not bounded yet: bound the next obstacle no thread has claimed
                        // (this one, or one after it), else wait for the thread bounding it
                        if self.claim_one(setup, refs, stop) {
                            continue;
                        }
                        if stop() {
                            return Err(Interrupted);
                        }
                        let (lock, signal) = &self.stored;
                        let held = lock.lock().unwrap_or_else(|e| e.into_inner());
                        // (set before its thread takes the lock to signal: looked at again
                        // under the lock, no signal is missed; the other thread checks the
                        // same deadline, so it is not waited on for long)
                        if slot.get().is_none() {
                            let _ = signal.wait_timeout(held, WHOLE_PATH_WAIT_POLL);
                        }
                    };
                    // its thread stopped (its own deadline) or failed: bounded again here,
                    // from the same inputs (the same bound), unless this deadline is past too
                    let found = match found {
                        ObstacleBound::Interrupted if !stop() => self.bound_one(setup, refs, i, stop),
                        b => b,
                    };
                    match found {
                        ObstacleBound::Bound(b) => b,
                        ObstacleBound::None => return Ok(None),
                        ObstacleBound::Interrupted => return Err(Interrupted),
                    }
                }
            };
            total = riskplan_certify::whole_path::add_up(total, b);
            if total >= 1.0 {
                return Ok(Some(1.0));
            }
        }
        Ok(Some(total))
    }

    /// Seconds from the first thread's start to the sum (or to now, before it).
    pub fn seconds(&self) -> f64 {
        match (self.finished.get(), self.started.get()) {
            (Some(&s), _) => s,
            (None, Some(t)) => t.elapsed().as_secs_f64(),
            (None, None) => 0.0,
        }
    }
}

/// How often [`WholePathWork::finish`] looks at its deadline while it waits for an
/// obstacle another thread bounds (which checks the same deadline itself; a bound stored
/// signals at once).
const WHOLE_PATH_WAIT_POLL: std::time::Duration = std::time::Duration::from_millis(1);

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

/// [`verify_obstacle`] with the obstacle's compiled contour (the fast restriction), by
/// general composition otherwise; the other bounds by general composition first, then
/// compiled in the scene's frame (which keeps its digits at extreme scales), as the
/// final check does (docs/design.md §5.13). [`verify_until`] decides as the planners'
/// checker does instead ([`SceneCertifier`]).
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
    let mut constraints = Reports::new(piece, method);
    decide_obstacle(o, compiled, None, piece, delta.rational(), method, settings, |name, vs| {
        constraints.add(name, &vs);
        true
    });
    let status = constraints.status();
    let finding = if status == Status::Safe {
        ObstacleFinding::Proven
    } else if !bounds.beyond_cantelli() || constraints.mean_unsafe() {
        ObstacleFinding::NotProven(None)
    } else {
        let hint = constraints.hint();
        let level = Level::new(delta.rational());
        let general = PieceBounds::for_piece(&o.contour, piece, level).cover(hint);
        let cover = match (general, compiled) {
            (Err(_), Some(c)) => PieceBounds::for_piece_compiled(&o.contour, c, piece, level).cover(hint),
            (r, _) => r,
        };
        match cover {
            Ok(parts) => ObstacleFinding::Covered(parts),
            Err(f) => ObstacleFinding::NotProven(Some(f)),
        }
    };
    obstacle_report(&o.id, constraints, finding, piece, bounds)
}

/// The constraint reports of one obstacle over one piece, as the decisions arrive.
struct Reports<'p> {
    piece: PieceRef<'p>,
    method: Method,
    list: Vec<ConstraintReport>,
}

impl<'p> Reports<'p> {
    fn new(piece: PieceRef<'p>, method: Method) -> Self {
        Reports { piece, method, list: Vec::with_capacity(2) }
    }

    /// One constraint's verdicts (one per method).
    fn add(&mut self, name: &str, vs: &[(&'static str, Verdict)]) {
        let st = combine(vs);
        let reports: Vec<(&'static str, MethodReport)> =
            vs.iter().map(|(m, v)| (*m, method_report(v, self.piece))).collect();
        // The combined margin and witness: a witness from any method; the smallest proven margin.
        let witness = reports.iter().find_map(|(_, r)| r.witness);
        let margin = match st {
            Status::Safe => reports.iter().filter_map(|(_, r)| r.margin).reduce(f64::min),
            Status::Unsafe => witness.map(|w| w.value),
            Status::Undecided => None,
        };
        let reason = if st == Status::Undecided { reports.iter().find_map(|(_, r)| r.reason.clone()) } else { None };
        self.list.push(ConstraintReport {
            name: name.to_string(),
            status: st,
            margin,
            witness,
            reason,
            method: self.method.as_str().to_string(),
            methods: (self.method == Method::Both)
                .then(|| reports.into_iter().map(|(m, r)| (m.to_string(), r)).collect()),
        });
    }

    /// The worst status.
    fn status(&self) -> Status {
        self.list.iter().fold(Status::Safe, |s, c| worst(s, c.status))
    }

    fn mean_unsafe(&self) -> bool {
        self.list.first().is_some_and(|c| c.name == "mean" && c.status == Status::Unsafe)
    }

    /// Where a constraint failed, in local time.
    fn hint(&self) -> Option<f64> {
        let (t0, h) = (self.piece.t0, self.piece.t1 - self.piece.t0);
        self.list.iter().find_map(|c| c.witness.map(|w| (w.t - t0) / h)).filter(|h| h.is_finite())
    }
}

/// The report of one obstacle from its constraint reports and what the decision found.
fn obstacle_report(
    id: &str,
    constraints: Reports<'_>,
    finding: ObstacleFinding,
    piece: PieceRef<'_>,
    bounds: BoundChoice,
) -> ObstacleReport {
    let at = |tau: f64| piece.t0 + (piece.t1 - piece.t0) * tau;
    let whole = |bound| vec![BoundPartReport { t0: piece.t0, t1: piece.t1, bound }];
    let status = constraints.status();
    let mean_unsafe = constraints.mean_unsafe();
    let mut report = ObstacleReport {
        id: id.to_string(),
        status,
        constraints: constraints.list,
        bounds: Vec::new(),
        not_covered: None,
    };
    match finding {
        ObstacleFinding::Proven => {
            report.status = Status::Safe;
            report.bounds = whole(BoundKind::Cantelli);
        }
        ObstacleFinding::Covered(parts) => {
            report.status = Status::Safe;
            report.bounds =
                parts.iter().map(|p| BoundPartReport { t0: at(p.tau0), t1: at(p.tau1), bound: p.bound }).collect();
        }
        ObstacleFinding::NotProven(why) => {
            if report.status == Status::Safe {
                // every constraint visited is proven, yet the piece is not (never seen):
                // not safe is the only sound answer
                report.status = Status::Undecided;
            }
            report.not_covered = match why {
                Some(f) => Some(cover_failure_text(f, at)),
                None if bounds.beyond_cantelli() && mean_unsafe => {
                    Some("E[P] >= 0 on the piece: no bound applies".into())
                }
                None => None,
            };
        }
    }
    report
}

fn cover_failure_text(f: CoverFailure, at: impl Fn(f64) -> f64) -> String {
    match f {
        CoverFailure::MeanNotNegative { tau } => format!("E[P] >= 0 at t = {}: no bound applies", at(tau)),
        CoverFailure::AboveDelta { tau, best } => {
            format!("every bound is above the risk level at t = {} (smallest {best:.3e})", at(tau))
        }
        CoverFailure::Budget { tau } => {
            format!("no bound proves the piece near t = {} within the search limits", at(tau))
        }
    }
}

/// The report of an obstacle the scene index proved for a whole piece: its proven cover
/// (the region where its constraints may fail, docs/design.md §5.10) misses the piece's
/// bounding box, so each constraint holds there, with no per-piece margin; the method
/// is `cover`.
fn covered_report(o: &Obstacle, piece: PieceRef<'_>, bounds: BoundChoice) -> ObstacleReport {
    let tail = o.pedestrian.is_some() && bounds.beyond_cantelli();
    let names: &[&str] = if tail { &["tail"] } else { &["mean", "cantelli"] };
    ObstacleReport {
        id: o.id.clone(),
        status: Status::Safe,
        constraints: names
            .iter()
            .map(|n| ConstraintReport {
                name: n.to_string(),
                status: Status::Safe,
                margin: None,
                witness: None,
                method: COVER_METHOD.into(),
                reason: None,
                methods: None,
            })
            .collect(),
        bounds: vec![BoundPartReport {
            t0: piece.t0,
            t1: piece.t1,
            bound: if tail { BoundKind::Tail } else { BoundKind::Cantelli },
        }],
        not_covered: None,
    }
}

/// The `method` of a constraint proven by the scene index's cover (`covered_report`).
pub const COVER_METHOD: &str = "cover";

/// A pedestrian over one piece by its Gaussian tail bound, exactly (docs/design.md
/// §3.11): one constraint, `tail`, `‖x − m(t)‖² − r(t)² > 0` on the piece.
fn verify_pedestrian(
    o: &Obstacle,
    p: &riskplan_scene::Pedestrian,
    piece: PieceRef<'_>,
    delta: &RiskLevel,
    method: Method,
) -> ObstacleReport {
    let v = riskplan_certify::gaussian_tail::piece_clear_exact(p, delta.rational(), piece);
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
        bounds: if safe {
            vec![BoundPartReport { t0: piece.t0, t1: piece.t1, bound: BoundKind::Tail }]
        } else {
            Vec::new()
        },
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
            checked: 0,
            not_safe: 0,
            first_not_safe: None,
            whole_path_risk: None,
        },
    )
}

/// [`verify`] that asks `stop` before each piece and obstacle and gives up with
/// `Interrupted` as soon as it says yes (a service deadline). One check of one piece
/// against one obstacle is the largest step between two questions. Every piece's
/// report ([`verify_with`] with [`Detail::Every`]).
pub fn verify_until(
    kernel: &SceneKernel,
    traj: &Trajectory,
    delta: &RiskLevel,
    method: Method,
    settings: &sos::SosSettings,
    bounds: BoundChoice,
    stop: &(dyn Fn() -> bool + Sync),
) -> Result<VerifyReport, Interrupted> {
    let opts = VerifyOptions {
        method,
        settings: settings.clone(),
        bounds,
        detail: Detail::Every,
        threads: 1,
        whole_path: false,
    };
    Ok(verify_with(kernel, &traj.pieces, delta, &opts, stop)?.report)
}

/// How much of the report [`verify_with`] builds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Detail {
    /// Every piece's report.
    #[default]
    Every,
    /// Only the first piece not proven safe (the others are decided, counted and
    /// dropped; no report is built for them).
    FirstNotSafe,
}

/// How [`verify_with`] decides and reports.
#[derive(Clone, Debug, Default)]
pub struct VerifyOptions {
    /// Decision method.
    pub method: Method,
    /// SOS settings (the `sos` and `both` methods).
    pub settings: sos::SosSettings,
    /// Which bounds may prove a piece.
    pub bounds: BoundChoice,
    /// How much of the report to build.
    pub detail: Detail,
    /// Threads for a call of at least [`PARALLEL_MIN_PIECES`] pieces (0 and 1: the
    /// calling thread only; at most [`MAX_VERIFY_THREADS`]): that many contiguous chunks
    /// are verified as tasks on the rayon pool (at most one thread per core at once) and
    /// their reports merged in order, the same report as one thread's.
    pub threads: usize,
    /// Also the whole-path bound ([`VerifyReport::whole_path_risk`], at most
    /// [`MAX_WHOLE_PATH_PIECES`] pieces; more are left without it).
    pub whole_path: bool,
}

/// What [`verify_with`] found.
#[derive(Clone, Debug, PartialEq)]
pub struct VerifyOutcome {
    /// The report (all pieces, or the first not proven safe, per [`Detail`]).
    pub report: VerifyReport,
    /// Index of every piece not proven safe, in order.
    pub not_safe_indices: Vec<usize>,
}

/// Most pieces (of one trajectory, or segments of one batch) one verification may take
/// (the CLI's `verify`, the service's `verify` request): at the kernel's speed
/// (microseconds per piece and nearby obstacle) they take well under the service's
/// default job deadline. A plan has at most [`riskplan_scene::MAX_PIECES`].
pub const MAX_VERIFY_PIECES: usize = 200_000;

/// Fewest pieces for which [`verify_with`] splits the work among
/// [`VerifyOptions::threads`] threads: a piece of a reference scene takes a few
/// microseconds, a thread's start about 20, so below a few thousand pieces the split
/// would not pay.
pub const PARALLEL_MIN_PIECES: usize = 4096;

/// Most threads one [`verify_with`] call uses, whatever it is asked for.
pub const MAX_VERIFY_THREADS: usize = 64;

/// Fewest pieces for which [`verify_with`] builds the scene index (the obstacles'
/// proven covers, docs/design.md §5.10) when the kernel does not hold it yet: building
/// a static obstacle's cover costs about as much as checking it on a few hundred pieces
/// (`riskplan bench`), and a verify call with fewer pieces checks every obstacle on
/// every piece instead. A kernel that holds the index (the service's, once a plan or a
/// large verify made it) always uses the covers it has built (a plan on a small scene
/// builds them on demand: `certify::checker::LAZY_MAX_OBSTACLES`).
pub const INDEX_MIN_PIECES: usize = 512;

/// Verifies `pieces` (a trajectory's, or independent segments: each piece is decided on
/// its own time interval) against a kernel's scene, deciding as the planners' motion
/// checker does ([`SceneCertifier`], docs/design.md §5.10): the workspace from the
/// piece's proven bounding box (exactly otherwise); with the Exact method, obstacles
/// whose proven cover misses the piece skipped (reported with method `cover`); the
/// others on the compiled restriction with the exact fallback, then, when only
/// Cantelli's g₁ fails and the bounds are `auto`, the other bounds' cover. The final
/// check of a plan keeps its own independent path ([`final_check`]). Asks `stop`
/// before each piece and obstacle (from every thread with [`VerifyOptions::threads`]).
pub fn verify_with(
    kernel: &SceneKernel,
    pieces: &[riskplan_scene::Piece],
    delta: &RiskLevel,
    opts: &VerifyOptions,
    stop: &(dyn Fn() -> bool + Sync),
) -> Result<VerifyOutcome, Interrupted> {
    let v = Verifier::new(kernel, pieces.len(), delta, opts, stop);
    let threads = opts.threads.clamp(1, MAX_VERIFY_THREADS);
    let mut out = if threads > 1 && pieces.len() >= PARALLEL_MIN_PIECES {
        v.chunks(pieces, threads)?
    } else {
        v.chunk(0, pieces)?
    };
    if opts.whole_path && pieces.len() <= MAX_WHOLE_PATH_PIECES {
        out.report.whole_path_risk = Some(whole_path_risk(kernel, pieces, stop)?);
    }
    let r = &mut out.report;
    r.not_safe = out.not_safe_indices.len();
    r.first_not_safe = out.not_safe_indices.first().copied();
    r.safe = r.not_safe == 0;
    Ok(out)
}

/// What [`verify_with`] decides pieces with: the scene's certifier at Δ, its index of
/// covers where they may be used, and the compiled contours' frame.
struct Verifier<'a> {
    scene: &'a riskplan_scene::Scene,
    cert: SceneCertifier,
    index: Option<std::sync::Arc<riskplan_certify::checker::SceneIndex>>,
    compiled: std::sync::Arc<riskplan_certify::checker::CompiledSet>,
    delta: &'a RiskLevel,
    opts: &'a VerifyOptions,
    stop: &'a (dyn Fn() -> bool + Sync),
}

impl<'a> Verifier<'a> {
    /// The certifier of `kernel`'s scene at `delta` for a call of `pieces` pieces.
    fn new(
        kernel: &'a SceneKernel,
        pieces: usize,
        delta: &'a RiskLevel,
        opts: &'a VerifyOptions,
        stop: &'a (dyn Fn() -> bool + Sync),
    ) -> Self {
        let scene = kernel.scene();
        let n = scene.obstacles.len();
        let cert = SceneCertifier::with_deltas(kernel.clone(), vec![delta.clone(); n], opts.method)
            .with_bounds(opts.bounds)
            .with_settings(opts.settings.clone());
        // the covers prove "safe" by interval bounds: used with the Exact method only (the
        // others are asked for their own proofs), and for pedestrians only under `auto`
        // bounds (their covers are their tail bound's)
        let use_index = opts.method == Method::Exact
            && (opts.bounds.beyond_cantelli() || scene.obstacles.iter().all(|o| o.pedestrian.is_none()));
        let index = match (use_index, pieces >= INDEX_MIN_PIECES) {
            (false, _) => None,
            (true, true) => Some(kernel.index(cert.deltas(), stop)),
            (true, false) => kernel.peek_index(cert.deltas()),
        };
        Verifier { scene, cert, index, compiled: kernel.compiled(), delta, opts, stop }
    }

    /// An outcome with nothing checked yet, room for `capacity` piece reports.
    fn empty(&self, capacity: usize) -> VerifyOutcome {
        VerifyOutcome {
            report: VerifyReport {
                safe: true,
                method: self.opts.method.as_str().to_string(),
                risk: self.delta.to_f64(),
                bound: self.opts.bounds,
                pieces: Vec::with_capacity(capacity),
                checked: 0,
                not_safe: 0,
                first_not_safe: None,
                whole_path_risk: None,
            },
            not_safe_indices: Vec::new(),
        }
    }

    /// `pieces` in `threads` contiguous chunks at once (tasks on the rayon pool), merged
    /// in order: the same reports as one thread.
    fn chunks(&self, pieces: &[riskplan_scene::Piece], threads: usize) -> Result<VerifyOutcome, Interrupted>
    where
        Self: Sync,
    {
        let size = pieces.len().div_ceil(threads);
        let parts: Vec<Result<VerifyOutcome, Interrupted>> = {
            use rayon::prelude::*;
            pieces.par_chunks(size).enumerate().map(|(c, chunk)| self.chunk(c * size, chunk)).collect()
        };
        let mut all = self.empty(if self.opts.detail == Detail::Every { pieces.len() } else { 1 });
        for part in parts {
            let part = part?;
            all.report.checked += part.report.checked;
            all.report.pieces.extend(part.report.pieces);
            all.not_safe_indices.extend(part.not_safe_indices);
        }
        if self.opts.detail == Detail::FirstNotSafe {
            // each chunk reported its own first piece not safe: the call's is the first
            all.report.pieces.truncate(1);
        }
        Ok(all)
    }

    /// The pieces `chunk`, the first of which is piece `offset` of the call.
    fn chunk(&self, offset: usize, chunk: &[riskplan_scene::Piece]) -> Result<VerifyOutcome, Interrupted> {
        let n = self.scene.obstacles.len();
        let mut out = self.empty(if self.opts.detail == Detail::Every { chunk.len() } else { 1 });
        let mut cands = Vec::with_capacity(n);
        let mut near = vec![false; n];
        for (k, pc) in chunk.iter().enumerate() {
            let report_it = self.opts.detail == Detail::Every || out.not_safe_indices.is_empty();
            let (safe, report) = self.piece(pc, report_it, &mut cands, &mut near)?;
            if let Some(report) = report.filter(|r| self.opts.detail == Detail::Every || !r.safe) {
                out.report.pieces.push(report);
            }
            out.report.checked += 1;
            if !safe {
                out.not_safe_indices.push(offset + k);
            }
        }
        Ok(out)
    }

    /// Whether one piece is proven safe, and its report when `report_it` (with
    /// `Detail::FirstNotSafe`, only when it is not safe). `cands` and `near`: buffers.
    fn piece(
        &self,
        pc: &riskplan_scene::Piece,
        report_it: bool,
        cands: &mut Vec<usize>,
        near: &mut [bool],
    ) -> Result<(bool, Option<PieceReport>), Interrupted> {
        let (scene, opts, n) = (self.scene, self.opts, self.scene.obstacles.len());
        let ws = &scene.workspace;
        let pr = PieceRef { t0: pc.t0, t1: pc.t1, coeffs: &pc.coeffs };
        let bbox = piece_bbox(pr);
        let workspace = if inside_by_box(&ws.lower, &ws.upper, pr, bbox.as_deref()) {
            WorkspaceStatus { status: Status::Safe, witness: None }
        } else {
            check_workspace(&ws.lower, &ws.upper, pr)
        };
        // the covers say nothing outside the workspace
        match (&self.index, workspace.status) {
            (Some(ix), Status::Safe) => ix.candidates(bbox.as_deref(), pc.t0, pc.t1, cands),
            _ => {
                cands.clear();
                cands.extend(0..n);
            }
        }
        let tail_only = |i: usize| opts.bounds.beyond_cantelli() && scene.obstacles[i].pedestrian.is_some();
        let subs =
            if cands.iter().any(|&i| !tail_only(i)) { Substitution::new(pr, self.compiled.frame()) } else { None };
        // without a report to build, the first obstacle that fails decides
        let mut safe = workspace.status == Status::Safe;
        if opts.detail == Detail::FirstNotSafe {
            for &i in cands.iter() {
                if !safe {
                    break;
                }
                if (self.stop)() {
                    return Err(Interrupted);
                }
                safe = self.cert.obstacle_safe(i, pr, subs.as_ref());
            }
        }
        if !report_it || (opts.detail == Detail::FirstNotSafe && safe) {
            return Ok((safe, None));
        }
        near.iter_mut().for_each(|b| *b = false);
        cands.iter().for_each(|&i| near[i] = true);
        let mut obstacles = Vec::with_capacity(n);
        for (i, o) in scene.obstacles.iter().enumerate() {
            if !near[i] {
                obstacles.push(covered_report(o, pr, opts.bounds));
                continue;
            }
            if (self.stop)() {
                return Err(Interrupted);
            }
            obstacles.push(if let (Some(p), true) = (&o.pedestrian, opts.bounds.beyond_cantelli()) {
                verify_pedestrian(o, p, pr, self.delta, opts.method)
            } else {
                let mut constraints = Reports::new(pr, opts.method);
                let finding =
                    self.cert.decide_obstacle(i, pr, subs.as_ref(), true, &mut |name, vs| constraints.add(name, vs));
                obstacle_report(&o.id, constraints, finding, pr, opts.bounds)
            });
        }
        let safe = workspace.status == Status::Safe && obstacles.iter().all(|o| o.status == Status::Safe);
        Ok((safe, Some(PieceReport { t0: pc.t0, t1: pc.t1, safe, workspace, obstacles })))
    }
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
/// later leaves its beginning unproven and is refused.
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
/// tried once more with their compiled restriction, its moments restricted by the fast
/// path's own `f64` code (docs/design.md §5.13: at extreme
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
    let diag = riskplan_scene::motion::dist(&scene.workspace.lower, &scene.workspace.upper);
    if let Err(e) = traj.validate(scene.dim, scene.horizon, diag) {
        return Ok(done(Some(FinalFailure::Invalid(e.to_string()))));
    }
    let tol = riskplan_scene::CONTINUITY_TOLERANCE * diag.max(1.0);
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
    // on crowded scenes, the obstacles each piece must be examined against (§5.12)
    let grid = framed.grid(scene, deltas, stop)?;
    // each obstacle's box-test polynomials, formed on first use (the grid's, when there is
    // one: formed once for these risk levels)
    let local: Vec<std::sync::OnceLock<_>>;
    let bounds_of_tests = match &grid {
        Some(g) => g.bounds.as_slice(),
        None => {
            local = scene.obstacles.iter().map(|_| std::sync::OnceLock::new()).collect();
            local.as_slice()
        }
    };
    let near = near.map(|n| (n, bounds_of_tests));
    for (i, pc) in traj.pieces.iter().enumerate() {
        if stop() {
            return Err(Interrupted);
        }
        let pr = PieceRef { t0: pc.t0, t1: pc.t1, coeffs: &pc.coeffs };
        let only = grid.as_ref().and_then(|g| g.candidates(pr));
        if !piece_passes_verify_path(scene, &framed, near, pr, deltas, bounds, compiled.as_deref(), only.as_deref()) {
            return Ok(done(Some(FinalFailure::NotProven(i))));
        }
    }
    Ok(done(None))
}
