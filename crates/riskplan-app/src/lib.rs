//! The application layer (above the planners, below every front end): one typed
//! plan request, turned into a problem, a planner and a motion checker in one
//! place. The CLI, the service, the bench and the tests all go through
//! [`PlanRequest`], so a planner added here is available to each of them at once.
//!
//! A crate sees only the layers below it: an upward `use` (here of `riskplan-service`,
//! a layer above this one) does not compile.
//!
//! ```compile_fail,E0432
//! use riskplan_service::ServiceError;
//! ```

pub mod crowd;
pub mod names;
pub mod verify;

/// The git commit this build was made from (`build.rs`: `RISKPLAN_GIT_COMMIT` from the
/// build's environment, else `git rev-parse HEAD`, else "unknown"): the service's
/// `riskplan_build_info` metric and the bench's records carry it.
pub const GIT_COMMIT: &str = env!("RISKPLAN_GIT_COMMIT");

use crate::verify::{final_check, FinalFailure, Interrupted, Method, SceneCertifier, SceneKernel, WholePathWork};
use num_rational::BigRational;
use riskplan_math::contour::{BoundChoice, RiskLevel};
use riskplan_plan::{
    Built, FinalCheckStats, Kinematics, MotionChecker, NoPlanReason, PlanError, PlanOptions, PlanOutcome, PlanStatus,
    Planner, Problem, Setup, Termination,
};
pub use riskplan_plan::{PlannerKind, RiskMode, UnknownName};
use riskplan_scene::Scene;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

/// The time limit of a plan from seconds: positive and finite.
pub fn time_limit(seconds: f64) -> Result<Duration, PlanError> {
    (seconds > 0.0).then(|| Duration::try_from_secs_f64(seconds).ok()).flatten().ok_or_else(|| {
        PlanError::InvalidRequest {
            field: "time_limit".into(),
            message: format!("must be a positive, finite number of seconds, got {seconds}"),
        }
    })
}

/// One plan request, typed and validated: what every front end builds from its input.
#[derive(Clone, Debug, PartialEq)]
pub struct PlanRequest {
    /// Which planner.
    pub planner: PlannerKind,
    /// How RRT-SOS certifies its edges (ignored by the Monte Carlo baseline).
    pub certifier: Method,
    /// Risk level Δ; `None`: the scene's.
    pub delta: Option<RiskLevel>,
    /// Start and goal; `None`: the scene's.
    pub endpoints: Option<(Vec<f64>, Vec<f64>)>,
    /// Seed of the planner's RNG (and of the baseline's scenarios).
    pub seed: u64,
    /// Pieces of the time-layered planner; `Some` forces it.
    pub pieces: Option<usize>,
    /// The improve step of the paper's static planner.
    pub improve: bool,
    /// How long the planner may run.
    pub time_limit: Duration,
    /// Speed limit (`None`: the scene's `planner.max_speed`, if any).
    pub max_speed: Option<f64>,
    /// Acceleration limit for smoothing (`None`: the scene's, if any).
    pub max_accel: Option<f64>,
    /// Shortcut and blend the plan (default planners; on by default).
    pub smooth: bool,
    /// What Δ bounds.
    pub risk_mode: RiskMode,
    /// Which risk bounds may prove safety: `auto` (the tightest sound one) or `cantelli`
    /// (the paper's; docs/design.md §3.7–§3.10, §5.13). `None`: the scene's
    /// `planner.bound`, else `auto` ([`BoundChoice`]).
    pub bound: Option<BoundChoice>,
    /// A receding-horizon request (docs/design.md §6.9): plan from the robot's current
    /// state over a window; `None`: the scene's start at its horizon's start to the goal
    /// at its end.
    pub receding: Option<RecedingRequest>,
}

/// The robot's state and the window of a receding-horizon request (docs/design.md §6.9).
#[derive(Clone, Debug, PartialEq)]
pub struct RecedingRequest {
    /// The current time (inside the scene's horizon).
    pub t_now: f64,
    /// The robot's position at `t_now`.
    pub position: Vec<f64>,
    /// Its velocity at `t_now` (`None`: at rest).
    pub velocity: Option<Vec<f64>>,
    /// The window's length H (> 0): the plan covers `[t_now, t_now + H]`, cut at the
    /// scene's horizon.
    pub horizon: f64,
    /// The goal.
    pub goal: Vec<f64>,
    /// The previous plan, to continue where it still holds.
    pub warm_start: Option<Arc<riskplan_scene::Trajectory>>,
}

/// The time limit of a request that gives none (the service's default).
pub const DEFAULT_TIME_LIMIT: Duration = Duration::from_secs(10);

impl Default for PlanRequest {
    fn default() -> Self {
        PlanRequest {
            planner: PlannerKind::RrtSos,
            certifier: Method::Exact,
            delta: None,
            endpoints: None,
            seed: 1,
            pieces: None,
            improve: false,
            time_limit: DEFAULT_TIME_LIMIT,
            max_speed: None,
            max_accel: None,
            smooth: true,
            risk_mode: RiskMode::PerObstacle,
            bound: None,
            receding: None,
        }
    }
}

/// A request made ready to run: the problem, the planner and its motion checker.
pub struct PreparedPlan {
    /// The problem (scene, endpoints, horizon, Δ, seed).
    pub problem: Problem,
    /// The planner.
    pub planner: Box<dyn Planner>,
    /// The motion checker the planner consults.
    pub checker: Box<dyn MotionChecker>,
    /// The risk level of each obstacle in a joint risk mode (`None`: per obstacle).
    pub allocation: Option<Vec<(String, f64)>>,
    /// The risk level Δᵢ of each obstacle: what the final check proves.
    pub deltas: Vec<RiskLevel>,
    /// The scene's kernel: what its checkers and the final check cache.
    pub kernel: SceneKernel,
    /// What Δ bounds (`trajectory`: the final check also proves the whole-path bound).
    pub risk_mode: RiskMode,
    /// The bounds the checker and the final check may use.
    pub bounds: BoundChoice,
    /// The planner's kind and options (to build it again should its output need a re-plan).
    pub kind: PlannerKind,
    /// The options the planner was built with.
    pub options: PlanOptions,
}

/// The share of Δ by which the whole-path bound a plan reports may exceed, summed over the
/// obstacles, what the partition would give with unlimited boxes (docs/design.md §5.14):
/// an obstacle's partition stops once its undecided probability is below this share of Δ
/// over the number of obstacles whose reach the plan enters (the others need no
/// partition). Without it an obstacle at 10⁻⁹ beside the plan was
/// refined to 10⁻¹² (its whole box budget: on 512 disks, half the whole-path time) for a
/// sum of 10⁻⁴.
pub const WHOLE_PATH_SLACK_SHARE: f64 = 0.01;

/// How long the final check of a plan found in time may run past the plan's deadline
/// (docs/design.md §5.12): well inside the 100 ms within which plans answer after
/// their limit; a check still running then ends the plan as `deadline_reached`.
pub const FINAL_CHECK_GRACE: Duration = Duration::from_millis(50);

/// Fewest obstacles for which a plan computes its whole-path bound on a second thread while
/// its final check runs (docs/design.md §5.12, §5.14): on crowded scenes the two take about
/// as long each (512 disks: 0.3–2 ms and 0.6–1 ms); on small scenes both take
/// microseconds and handing the bound over would cost more than it saves.
pub const WHOLE_PATH_BESIDE_MIN_OBSTACLES: usize = 64;

/// The process's thread for whole-path bounds beside final checks: started on first use,
/// parked on a channel between bounds (a parked thread wakes in about 50 µs on this
/// machine; starting one per plan cost about 70 µs of the plan's own thread, and a new
/// thread was sometimes placed by the scheduler only after 1.4 ms). One bound at a time:
/// a plan that finds it busy computes its bound itself after its check.
struct Beside {
    jobs: std::sync::mpsc::Sender<Box<dyn FnOnce() + Send>>,
    busy: Arc<AtomicBool>,
}

static BESIDE: std::sync::OnceLock<Option<Beside>> = std::sync::OnceLock::new();

impl Beside {
    /// The thread, started on first use (`None` if it cannot be).
    fn get() -> Option<&'static Beside> {
        BESIDE
            .get_or_init(|| {
                let (jobs, rx) = std::sync::mpsc::channel::<Box<dyn FnOnce() + Send>>();
                std::thread::Builder::new()
                    .name("riskplan-beside".into())
                    .spawn(move || {
                        // a job that panics is reported (the default hook) and the thread
                        // goes on; its guard has freed the thread for the next bound
                        while let Ok(job) = rx.recv() {
                            let _ = std::panic::catch_unwind(std::panic::AssertUnwindSafe(job));
                        }
                    })
                    .ok()?;
                Some(Beside { jobs, busy: Arc::new(AtomicBool::new(false)) })
            })
            .as_ref()
    }

    /// Starts on `work` (a plan's whole-path bound, which the plan joins after its check:
    /// [`WholePathWork::finish`]) when the thread is free; `abandon` (or `term`'s grace)
    /// stops it. Nothing when it is busy or gone: the plan then bounds alone.
    fn help(&self, work: Arc<WholePathWork>, term: Termination, abandon: Arc<AtomicBool>) {
        use std::sync::atomic::Ordering;
        if self.busy.compare_exchange(false, true, Ordering::Acquire, Ordering::Relaxed).is_err() {
            return;
        }
        let free = Free(self.busy.clone());
        let job = move || {
            // the thread is free again when its share is done, or when the job panics
            let _free = free;
            work.run(&|| abandon.load(Ordering::Relaxed) || term.expired_by(FINAL_CHECK_GRACE));
        };
        // (a job the thread cannot take is dropped, and its guard frees the thread)
        let _ = self.jobs.send(Box::new(job));
    }
}

/// Sets its flag when dropped.
struct SetOnDrop(Arc<AtomicBool>);

impl Drop for SetOnDrop {
    fn drop(&mut self) {
        self.0.store(true, std::sync::atomic::Ordering::Relaxed);
    }
}

/// Marks [`Beside`] free when dropped (at the end of a job, or with a job never run).
struct Free(Arc<AtomicBool>);

impl Drop for Free {
    fn drop(&mut self) {
        self.0.store(false, std::sync::atomic::Ordering::Release);
    }
}

impl PreparedPlan {
    /// Runs the planner until it finishes or `term` says stop. A certified trajectory
    /// is called certified only after it passed the final check (docs/design.md §5.12):
    /// the verify path, piece by piece, every obstacle. Should the check reject a
    /// trajectory the planner's checker accepted — a bug of the fast path — the
    /// disagreement is counted in `stats.final_check`, and the plan is made again in
    /// the remaining time with a checker without the fast path.
    pub fn solve(&mut self, term: &Termination) -> Result<PlanOutcome, PlanError> {
        let started = std::time::Instant::now();
        // (receding plans outside trajectory mode carry no whole-path bound)
        let wants_whole = !(self.problem.receding && self.risk_mode != RiskMode::Trajectory);
        let crowded = self.kernel.scene().obstacles.len() >= WHOLE_PATH_BESIDE_MIN_OBSTACLES;
        let mut out = self.planner.solve(&self.problem, self.checker.as_ref(), term)?;
        let mut fc = FinalCheckStats::default();
        let stop = || term.expired_by(FINAL_CHECK_GRACE);
        while let Some(traj) = out.trajectory.as_ref().filter(|_| out.certified) {
            // a receding plan that ends short of the goal (`progress`) ends anywhere
            let goal = (out.status != PlanStatus::Progress).then_some(self.problem.goal.as_slice());
            let ends = (self.problem.start.as_slice(), goal);
            let t_start = self.problem.horizon.0;
            use riskplan_certify::path_risk::CellEffort;
            let delta = riskplan_plan::rrt::delta_floor(&self.problem.delta);
            // (outside trajectory mode, only when every obstacle admits the partition:
            // the moment envelopes' exact arithmetic can take seconds)
            let budgeted = self.risk_mode == RiskMode::Trajectory;
            // the whole-path bound at the plan's effort starts beside the check (crowded
            // scenes), and is abandoned if the check refuses the plan
            let abandon = Arc::new(AtomicBool::new(false));
            // (and once this pass ends, however it ends — a panic included — nothing is
            // left for it to do)
            let _abandon_at_end = SetOnDrop(abandon.clone());
            let slack = WHOLE_PATH_SLACK_SHARE * delta;
            let work = wants_whole.then(|| {
                Arc::new(WholePathWork::new(
                    self.kernel.clone(),
                    traj.pieces.clone(),
                    CellEffort::PLAN,
                    slack,
                    budgeted,
                ))
            });
            if let (Some(w), true) = (&work, crowded) {
                if let Some(b) = Beside::get() {
                    b.help(w.clone(), term.clone(), abandon.clone());
                }
            }
            let check = match final_check(&self.kernel, traj, ends, t_start, &self.deltas, self.bounds, &stop) {
                Ok(c) => c,
                Err(Interrupted) => {
                    abandon.store(true, std::sync::atomic::Ordering::Relaxed);
                    let status = if term.cancelled() { PlanStatus::Cancelled } else { PlanStatus::DeadlineReached };
                    let reason = NoPlanReason::from_status(status, &out.stats, term);
                    out = PlanOutcome::no_plan(status, out.stats, reason);
                    break;
                }
            };
            if check.failure.is_some() {
                abandon.store(true, std::sync::atomic::Ordering::Relaxed);
            }
            fc.seconds += check.seconds;
            fc.verify_seconds += check.seconds;
            fc.pieces += check.pieces;
            let why = match check.failure {
                None => {
                    // the whole-path bound of every certified plan (docs/design.md §5.14);
                    // in trajectory mode it must be within Δ. Receding plans (remade every
                    // cycle, within a cycle's latency) carry it only in trajectory mode
                    if !wants_whole {
                        break;
                    }
                    let t_wp = std::time::Instant::now();
                    let whole = |effort, slack| {
                        crate::verify::plan_whole_path_risk(&self.kernel, &traj.pieces, effort, slack, budgeted, &stop)
                    };
                    // the plan's effort first (begun beside the check on crowded scenes:
                    // joined here); in trajectory mode a bound above Δ is tried again with
                    // the report's (ten times the boxes)
                    let mut wp = match &work {
                        Some(w) => w.finish(&stop),
                        None => whole(CellEffort::PLAN, slack),
                    };
                    if budgeted && wp.as_ref().is_ok_and(|b| b.is_some_and(|b| b > delta)) {
                        wp = whole(CellEffort::REPORT, 0.0);
                    }
                    // in trajectory mode the planner's own sum over the pieces (what it kept
                    // within Δ) is a bound too: the smaller one decides
                    if budgeted {
                        let sum = riskplan_plan::rrt::path_risk_sum(self.checker.as_ref(), &traj.pieces, &stop);
                        wp = wp.map(|b| Some(b.map_or(sum, |b| b.min(sum))));
                    }
                    let here = t_wp.elapsed().as_secs_f64();
                    fc.whole_path_seconds = work.as_ref().map_or(0.0, |w| w.seconds()).max(here);
                    fc.seconds += here;
                    match wp {
                        Ok(None) => {}
                        Ok(Some(b)) => {
                            out.stats.whole_path_risk = Some(b);
                            if self.risk_mode == RiskMode::Trajectory && !(b <= delta && b < 1.0) {
                                let why = format!("the whole-path bound {b:.4e} of the plan exceeds Δ = {delta}");
                                out = PlanOutcome::no_plan(
                                    PlanStatus::Exhausted,
                                    out.stats,
                                    NoPlanReason::FinalCheckFailed { why },
                                );
                            }
                        }
                        Err(Interrupted) if self.risk_mode == RiskMode::Trajectory => {
                            let status =
                                if term.cancelled() { PlanStatus::Cancelled } else { PlanStatus::DeadlineReached };
                            let reason = NoPlanReason::from_status(status, &out.stats, term);
                            out = PlanOutcome::no_plan(status, out.stats, reason);
                        }
                        // out of time for a report: the plan stands without it
                        Err(Interrupted) => {}
                    }
                    break;
                }
                Some(FinalFailure::Invalid(why)) => {
                    fc.invalid += 1;
                    if fc.invalid == 1 && self.options.kinematics.smooth {
                        // the planner's output is not a valid trajectory (a bug of its
                        // post-processing): plan again without smoothing, whose straight
                        // pieces between certified waypoints always are
                        self.options.kinematics.smooth = false;
                        let setup = Setup {
                            problem: &self.problem,
                            kernel: &self.kernel,
                            deltas: &self.deltas,
                            options: &self.options,
                        };
                        self.planner = self.kind.build(&setup)?.planner;
                        out = self.planner.solve(&self.problem, self.checker.as_ref(), term)?;
                        continue;
                    }
                    why
                }
                Some(FinalFailure::NotProven(piece)) => {
                    fc.disagreements += 1;
                    if fc.disagreements == 1 {
                        // the fast path accepted what the verify path does not prove:
                        // plan again without it
                        let mut checker = SceneCertifier::with_deltas(&self.kernel, self.deltas.clone(), Method::Exact)
                            .with_bounds(self.bounds)
                            .without_fast_path();
                        if self.risk_mode == RiskMode::Trajectory {
                            let d = riskplan_plan::rrt::delta_floor(&self.problem.delta);
                            checker = checker.with_path_risk(d * riskplan_plan::rrt::PATH_RISK_NEGLIGIBLE_SHARE);
                        }
                        self.checker = Box::new(checker);
                        out = self.planner.solve(&self.problem, self.checker.as_ref(), term)?;
                        continue;
                    }
                    format!("piece {piece} is not proven safe, even planned without the fast path")
                }
            };
            out = PlanOutcome::no_plan(PlanStatus::Exhausted, out.stats, NoPlanReason::FinalCheckFailed { why });
        }
        if out.certified || fc.pieces > 0 {
            out.stats.final_check = Some(fc);
        }
        out.stats.planning_time_s = started.elapsed().as_secs_f64();
        out.stats.risk_allocation = self.allocation.clone();
        Ok(out)
    }
}

impl PlanRequest {
    /// The problem this request poses on `scene`.
    pub fn problem(&self, scene: Arc<Scene>) -> Result<Problem, PlanError> {
        if let Some(r) = &self.receding {
            return self.receding_problem(scene, r);
        }
        let mut p = match &self.endpoints {
            Some((start, goal)) => Problem {
                horizon: scene.horizon,
                delta: scene.risk.clone(),
                start: start.clone(),
                goal: goal.clone(),
                scene,
                seed: self.seed,
                receding: false,
                start_velocity: None,
                warm_start: None,
            },
            None => Problem::from_scene(scene, self.seed)?,
        };
        if let Some(d) = &self.delta {
            p.delta = d.clone();
        }
        Ok(p)
    }

    fn receding_problem(&self, scene: Arc<Scene>, r: &RecedingRequest) -> Result<Problem, PlanError> {
        let bad = |field: &str, message: String| PlanError::InvalidRequest { field: field.into(), message };
        let (h0, h1) = scene.horizon;
        if !(r.t_now >= h0 && r.t_now < h1) {
            return Err(bad("t_now", format!("{} is outside the scene's horizon [{h0}, {h1})", r.t_now)));
        }
        if !(r.horizon > 0.0 && r.horizon.is_finite()) {
            return Err(bad("horizon", format!("must be a positive number of time units, got {}", r.horizon)));
        }
        let end = (r.t_now + r.horizon).min(h1);
        if end <= r.t_now {
            return Err(bad("horizon", format!("the window [{}, {end}] is empty", r.t_now)));
        }
        if let Some(v) = &r.velocity {
            if v.len() != scene.dim || v.iter().any(|c| !c.is_finite()) {
                return Err(bad("velocity", format!("needs {} finite coordinates, got {v:?}", scene.dim)));
            }
        }
        if r.position.len() != scene.dim {
            return Err(bad("position", format!("needs {} coordinates, got {}", scene.dim, r.position.len())));
        }
        Ok(Problem {
            horizon: (r.t_now, end),
            delta: self.delta.clone().unwrap_or_else(|| scene.risk.clone()),
            start: r.position.clone(),
            goal: r.goal.clone(),
            scene,
            seed: self.seed,
            receding: true,
            start_velocity: r.velocity.clone(),
            warm_start: r.warm_start.clone(),
        })
    }

    /// The planner this request runs: a receding request runs the receding-horizon
    /// planner (named or by default), and no other.
    pub fn planner_kind(&self) -> Result<PlannerKind, PlanError> {
        match (&self.receding, self.planner) {
            (Some(_), PlannerKind::RrtSos | PlannerKind::Receding) => Ok(PlannerKind::Receding),
            (Some(_), other) => Err(PlanError::InvalidOption {
                option: "planner".into(),
                message: format!("{other} does not plan receding-horizon requests (use the default, receding)"),
            }),
            (None, PlannerKind::Receding) => Err(PlanError::InvalidOption {
                option: "planner".into(),
                message: "receding needs a receding-horizon request (t_now, position, horizon)".into(),
            }),
            (None, k) => Ok(k),
        }
    }

    /// The problem, the planner and the checker, with every option checked, on a scene
    /// (or its [`SceneKernel`], to share what its checkers cache across plans).
    pub fn prepare(&self, scene: impl Into<SceneKernel>) -> Result<PreparedPlan, PlanError> {
        let kernel = scene.into();
        let problem = self.problem(kernel.scene().clone())?;
        let bound = self.bound_on(kernel.scene());
        let options = PlanOptions {
            pieces: self.pieces,
            improve: self.improve,
            kinematics: Kinematics { max_speed: self.max_speed, max_accel: self.max_accel, smooth: self.smooth },
            certifier: self.certifier,
            risk_mode: self.risk_mode,
            bounds: bound,
        };
        let deltas = allocate(&kernel, &problem, self.risk_mode, bound)?;
        let setup = Setup { problem: &problem, kernel: &kernel, deltas: &deltas, options: &options };
        let kind = self.planner_kind()?;
        let Built { planner, checker } = kind.build(&setup)?;
        let allocation = matches!(self.risk_mode, RiskMode::JointUniform | RiskMode::JointWeighted)
            .then(|| problem.scene.obstacles.iter().zip(&deltas).map(|(o, d)| (o.id.clone(), d.to_f64())).collect());
        Ok(PreparedPlan {
            problem,
            planner,
            checker,
            allocation,
            deltas,
            kernel,
            bounds: bound,
            risk_mode: self.risk_mode,
            kind,
            options,
        })
    }

    /// The bounds this request uses on `scene`: its own, else the scene's
    /// `planner.bound`, else the default (`auto`).
    pub fn bound_on(&self, scene: &Scene) -> BoundChoice {
        self.bound.or_else(|| scene.file.planner.as_ref().and_then(|b| b.bound)).unwrap_or_default()
    }

    /// When to stop: this request's time limit from now, and `cancel` if given.
    pub fn termination(&self, cancel: Option<Arc<AtomicBool>>) -> Termination {
        let t = Termination::after(self.time_limit);
        match cancel {
            Some(c) => t.with_cancel(c),
            None => t,
        }
    }

    /// Prepares and runs the request; returns the problem it solved and the outcome.
    pub fn run(
        &self,
        scene: impl Into<SceneKernel>,
        cancel: Option<Arc<AtomicBool>>,
    ) -> Result<(Problem, PlanOutcome), PlanError> {
        let mut prepared = self.prepare(scene)?;
        let outcome = prepared.solve(&self.termination(cancel))?;
        Ok((prepared.problem, outcome))
    }
}

/// What [`warm_up`] built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WarmUp {
    /// Everything a default plan's checker and final check build on a cold scene
    /// ([`SceneKernel::is_warm`] at the scene's Δ).
    Done,
    /// `stop` said stop first: what was finished is kept, the rest is built on first use.
    Stopped,
}

/// Builds ahead of any request what a default plan (per-obstacle risk at the scene's Δ)
/// builds on first use on a new scene (docs/design.md §3.11 "Warm-ups", §5.10): the final
/// check's box tests and their grid (§5.12), the whole-path bound's frames and reaches
/// (§5.14), and the checker's proven covers and their grid (the scene index) — on 512
/// disks about 0.8 s that a cold plan would otherwise spend before its answer — and last
/// what plans build per obstacle where their edges go ([`SceneKernel::build_obstacle`]: the
/// compiled contour and bounds, the verify path's framed contours; without them a first pass
/// of plans on 512 disks took twice a steady plan's time). Every part is cached by `kernel`,
/// so the plans that follow find them, and a plan running meanwhile shares them: the covers
/// are built here from the last obstacle down, so that a plan building them from the first
/// up meets this warm-up halfway instead of building the same ones beside it. Nothing about
/// a plan's outcome depends on whether they were built before it. `stop` is asked between
/// obstacles.
pub fn warm_up(kernel: &SceneKernel, stop: &dyn Fn() -> bool) -> WarmUp {
    let scene = kernel.scene();
    let deltas = vec![scene.risk.clone(); scene.obstacles.len()];
    // (the final check's and the whole-path parts first: a plan that arrives meanwhile
    // builds the covers its search needs, and finds these built or being built)
    if kernel.framed().grid(scene, &deltas, stop).is_err() || kernel.path_reaches(stop).is_err() {
        return WarmUp::Stopped;
    }
    let index = kernel.lazy_index(&deltas);
    for i in (0..scene.obstacles.len()).rev() {
        if stop() {
            return WarmUp::Stopped;
        }
        index.ensure(scene, i, stop);
    }
    // (every cover built or tried: the grid over them)
    let _ = kernel.index(&deltas, stop);
    // then what a first pass of plans still builds per obstacle where its edges go: on 512
    // disks a plan on a kernel warmed without them took about twice a steady plan's time
    // (docs/benchmarks.md, issue 21 part 3, session 31)
    let beyond = PlanRequest::default().bound_on(scene).beyond_cantelli();
    for i in (0..scene.obstacles.len()).rev() {
        if stop() {
            return WarmUp::Stopped;
        }
        kernel.build_obstacle(i, beyond);
    }
    if kernel.is_warm(&deltas) {
        WarmUp::Done
    } else {
        WarmUp::Stopped
    }
}

/// Why an outcome has no trajectory, in one line (for replies and messages).
pub fn no_plan_reason(out: &PlanOutcome, limit: Duration) -> String {
    match &out.reason {
        Some(riskplan_plan::NoPlanReason::DeadlineReached { iterations, edges_checked, pieces_tried, ladder })
            if ladder.is_empty() =>
        {
            format!(
                "no plan within the time limit of {} s ({iterations} iterations, {edges_checked} edges checked{})",
                limit.as_secs_f64(),
                if pieces_tried.is_empty() { String::new() } else { format!(", pieces tried {pieces_tried:?}") }
            )
        }
        Some(r) => r.message(),
        None => format!("no plan ({} iterations, {} edges checked)", out.stats.iterations, out.stats.edges_checked),
    }
}

/// The risk level of each obstacle for `mode` (docs/design.md §3.6): Δ for each in the
/// paper's mode; in a joint mode exact rationals with Σ Δᵢ = Δ, so that by Boole's
/// inequality the probability of colliding with any obstacle at an instant is ≤ Δ
/// (`kernel`: the scene's, whose covers weigh the obstacles near the straight path).
pub fn allocate(
    kernel: &SceneKernel,
    p: &Problem,
    mode: RiskMode,
    bounds: BoundChoice,
) -> Result<Vec<RiskLevel>, PlanError> {
    let n = p.scene.obstacles.len();
    let delta = p.delta.rational().clone();
    let weights: Vec<BigRational> = match mode {
        // trajectory: each obstacle's per-instant constraint at Δ (implied by the
        // whole-path budget, which the planners and the final check keep)
        RiskMode::PerObstacle | RiskMode::Trajectory => return Ok(vec![p.delta.clone(); n]),
        RiskMode::JointUniform => vec![BigRational::from_integer(1.into()); n],
        RiskMode::JointWeighted => {
            // covers at the uniform allocation locate each obstacle
            let uniform = RiskLevel::new(&delta / BigRational::from_integer(n.max(1).into()))
                .map_err(|e| PlanError::InvalidOption { option: "risk_mode".into(), message: e.to_string() })?;
            let index = kernel.index(&vec![uniform; n], &|| false);
            let side = riskplan_plan::scale::Scale::of(p).side.max(f64::MIN_POSITIVE);
            index
                .cover_hulls()
                .iter()
                .map(|h| {
                    let d = h.as_ref().map_or(f64::INFINITY, |b| box_segment_distance(b, &p.start, &p.goal));
                    // weights in [1/64, 1], rounded to a float and used exactly
                    let w = (1.0 / (1.0 + d / side)).clamp(1.0 / 64.0, 1.0);
                    BigRational::from_float(w).unwrap_or_else(|| BigRational::from_integer(1.into()))
                })
                .collect()
        }
    };
    // floors: what each obstacle needs at the start (t0) and the goal (tf) — the
    // bound there (Cantelli's, or with `auto` the best proven one; weighted mode only);
    // the rest of Δ is split by weight
    let point = |v: &[f64], t: f64| -> Option<Vec<BigRational>> {
        let mut x: Vec<BigRational> = v.iter().map(|&c| BigRational::from_float(c)).collect::<Option<_>>()?;
        x.push(BigRational::from_float(t)?);
        Some(x)
    };
    let (Some(a), Some(b)) = (point(&p.start, p.horizon.0), point(&p.goal, p.horizon.1)) else {
        return Err(PlanError::InvalidRequest { field: "start".into(), message: "not finite".into() });
    };
    // strictly above the bound (the endpoint must be strictly inside), by 1 %
    let margin = BigRational::new(101.into(), 100.into());
    let needs: Vec<(BigRational, BigRational)> = if mode == RiskMode::JointWeighted {
        p.scene
            .obstacles
            .iter()
            .map(|o| {
                let bound = |x: &[BigRational]| match bounds {
                    BoundChoice::Cantelli => o.contour.risk_at(x).bound,
                    BoundChoice::Auto => riskplan_certify::bounds::point_bounds_proven(&o.contour, x).best().1,
                };
                (bound(&a) * &margin, bound(&b) * &margin)
            })
            .collect()
    } else {
        vec![(BigRational::from_integer(0.into()), BigRational::from_integer(0.into())); n]
    };
    let floors: Vec<BigRational> = needs.iter().map(|(s, g)| s.clone().max(g.clone())).collect();
    let floor_sum: BigRational = floors.iter().sum();
    if floor_sum >= delta {
        // the endpoints alone need more than Δ: name the obstacle that needs the most
        let worst = floors.iter().enumerate().max_by(|x, y| x.1.cmp(y.1)).map(|(i, _)| i).unwrap_or(0);
        let (which, point, t) = if needs[worst].0 >= needs[worst].1 {
            ("start", p.start.clone(), p.horizon.0)
        } else {
            ("goal", p.goal.clone(), p.horizon.1)
        };
        let obstacle = p.scene.obstacles[worst].id.clone();
        return Err(PlanError::UnsafeEndpoint { which: which.into(), point, t, obstacle });
    }
    let rest = &delta - &floor_sum;
    let total: BigRational = weights.iter().sum();
    weights
        .iter()
        .zip(&floors)
        .map(|(w, f)| {
            RiskLevel::new(f + &rest * w / &total)
                .map_err(|e| PlanError::InvalidOption { option: "risk_mode".into(), message: e.to_string() })
        })
        .collect()
}

/// Distance from a box to the segment `a–b` (sampled along the segment: a weight, not a
/// decision).
fn box_segment_distance(b: &[(f64, f64)], a: &[f64], c: &[f64]) -> f64 {
    (0..=64)
        .map(|k| {
            let s = k as f64 / 64.0;
            b.iter()
                .enumerate()
                .map(|(d, &(lo, hi))| {
                    let x = a[d] + (c[d] - a[d]) * s;
                    let e = if x < lo {
                        lo - x
                    } else if x > hi {
                        x - hi
                    } else {
                        0.0
                    };
                    e * e
                })
                .sum::<f64>()
                .sqrt()
        })
        .fold(f64::INFINITY, f64::min)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn planner_names_round_trip_and_unknown_names_are_typed_errors() {
        for k in PlannerKind::ALL {
            assert_eq!(k.as_str().parse::<PlannerKind>(), Ok(k));
        }
        let e = "rrt".parse::<PlannerKind>().unwrap_err();
        let names: Vec<&str> = PlannerKind::ALL.iter().map(|k| k.as_str()).collect();
        assert_eq!(e.to_string(), format!("unknown planner 'rrt' ({})", names.join(", ")));
        assert!(e.to_string().contains("tv-sos"), "{e}");
    }

    /// `n` uncertain disks (radius scaled by U(0.9, 1.1), centre shifted by N(0, 0.05)) on
    /// a lattice-like spread in a square 10·√n wide, start and goal in opposite corners.
    fn disks(n: usize) -> Arc<Scene> {
        let side = 10.0 * (n as f64).sqrt();
        let mut params = serde_json::Map::new();
        let mut obstacles = Vec::new();
        for k in 0..n {
            let u = |a: u64| ((k as u64 * a + 7) % 1000) as f64 / 1000.0;
            let (cx, cy, r) = (5.0 + u(377) * (side - 10.0), 5.0 + u(613) * (side - 10.0), 0.8 + 0.8 * u(271));
            params.insert(format!("s{k}"), serde_json::json!({"dist": "uniform", "low": 0.9, "high": 1.1}));
            params.insert(format!("d{k}"), serde_json::json!({"dist": "normal", "mean": 0, "std": 0.05}));
            obstacles.push(serde_json::json!({"id": format!("disk{k}"),
                "poly": format!("({r:.2}*s{k})^2 - (x1 - {cx:.2} - d{k})^2 - (x2 - {cy:.2})^2")}));
        }
        let json = serde_json::json!({"format": "riskplan-scene/1", "name": "disks", "dim": 2,
            "workspace": {"lower": [0, 0], "upper": [side, side]}, "horizon": [0, 1], "risk": 0.05,
            "params": params, "obstacles": obstacles, "start": [0.5, 0.5], "goal": [side - 0.5, side - 0.5]});
        Arc::new(Scene::from_json(&json.to_string()).unwrap())
    }

    #[test]
    fn a_warm_up_builds_what_a_plan_would() {
        let scene = disks(24);
        let deltas = vec![scene.risk.clone(); scene.obstacles.len()];
        // the oracle: what a default plan on a fresh kernel leaves built
        let planned = SceneKernel::new(scene.clone());
        assert!(!planned.is_warm(&deltas));
        let (_, cold) = PlanRequest::default().run(&planned, None).unwrap();
        assert!(cold.certified);
        assert!(planned.is_warm(&deltas), "a plan builds all of it: the oracle must hold");
        // a warm-up stopped at once builds none of it, and says so
        let stopped = SceneKernel::new(scene.clone());
        assert_eq!(warm_up(&stopped, &|| true), WarmUp::Stopped);
        assert!(!stopped.is_warm(&deltas));
        // a warm-up builds all of it, and the plan on the warm kernel is the same plan
        let warmed = SceneKernel::new(scene.clone());
        assert_eq!(warm_up(&warmed, &|| false), WarmUp::Done);
        assert!(warmed.is_warm(&deltas));
        // ... and what plans build per obstacle where their edges go, for every obstacle
        // (the cold plan built it for some only)
        let n = scene.obstacles.len();
        let some = planned.obstacles_built(true);
        assert!(some > 0 && some < n, "{some} of {n}: the plan's edges do not go everywhere");
        assert_eq!(warmed.obstacles_built(true), n);
        let (_, warm) = PlanRequest::default().run(&warmed, None).unwrap();
        let pieces = |o: &PlanOutcome| o.trajectory.as_ref().map(|t| t.pieces.clone());
        assert_eq!(pieces(&warm), pieces(&cold));
        assert_eq!(warm.stats.whole_path_risk, cold.stats.whole_path_risk);
    }

    /// How far the sum of a window's sub-intervals, each converted to seconds on its own,
    /// may exceed the window's own conversion: a few roundings of `as_secs_f64` (about
    /// 10⁻¹⁶ s each here), far below any interval measured.
    const SECONDS_ROUNDING: f64 = 1e-12;

    #[test]
    fn a_plans_phase_times_are_parts_of_its_totals() {
        // 64 obstacles: the whole-path bound runs beside the verify path; 8: after it
        for n in [WHOLE_PATH_BESIDE_MIN_OBSTACLES, 8] {
            let (_, out) = PlanRequest::default().run(SceneKernel::new(disks(n)), None).unwrap();
            assert!(out.certified, "{n} disks: {:?}", out.reason);
            let st = &out.stats;
            let sm = st.smoothing.as_ref().expect("a default plan is smoothed");
            let parts = [sm.shortcut_seconds, sm.reduction_seconds, sm.blend_seconds];
            assert!(parts.iter().all(|&t| t > 0.0), "{n} disks: {sm:?}");
            assert!(parts.iter().sum::<f64>() <= st.improve_time_s + SECONDS_ROUNDING, "{n} disks: {sm:?} {st:?}");
            let fc = st.final_check.as_ref().expect("a certified plan's final check");
            assert!(fc.verify_seconds > 0.0 && fc.whole_path_seconds > 0.0, "{n} disks: {fc:?}");
            assert!(fc.verify_seconds <= fc.seconds + SECONDS_ROUNDING, "{n} disks: {fc:?}");
            // (after the check, on a small scene, the bound is the rest of the final check)
            if n < WHOLE_PATH_BESIDE_MIN_OBSTACLES {
                assert!(fc.verify_seconds + fc.whole_path_seconds <= fc.seconds + SECONDS_ROUNDING, "{fc:?}");
            }
            assert!(st.improve_time_s + fc.seconds <= st.planning_time_s + SECONDS_ROUNDING, "{n} disks: {st:?}");
        }
    }

    #[test]
    fn time_limits_must_be_positive_and_finite() {
        assert_eq!(time_limit(1.5), Ok(Duration::from_millis(1500)));
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY, 1e300] {
            assert!(matches!(time_limit(bad), Err(PlanError::InvalidRequest { .. })), "{bad}");
        }
    }
}
