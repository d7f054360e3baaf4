//! What a planner answers: its status, statistics, typed reasons and errors.

use riskplan_scene::motion::Termination;
use riskplan_scene::Trajectory;
use serde::Serialize;
use thiserror::Error;

/// How a planner ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PlanStatus {
    /// A trajectory from start to goal.
    Exact,
    /// The deadline passed first.
    DeadlineReached,
    /// Cancelled.
    Cancelled,
    /// The planner's own limits (iterations, attempts) were spent.
    Exhausted,
    /// A receding-horizon plan that does not reach the goal within its window: a
    /// certified trajectory to the end point of best progress (docs/design.md §6.9).
    Progress,
}

/// What a planner reports about its run.
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize, schemars::JsonSchema)]
pub struct PlanStats {
    /// Wall time of `solve`, seconds.
    pub planning_time_s: f64,
    /// Time until the first feasible path, seconds.
    pub time_to_feasible_s: Option<f64>,
    /// Time spent in the improve step, seconds.
    pub improve_time_s: f64,
    /// Sampling iterations.
    pub iterations: u64,
    /// Vertices in the tree (all layers).
    pub vertices: u64,
    /// Pieces sent to the motion checker.
    pub edges_checked: u64,
    /// Pieces it accepted.
    pub edges_accepted: u64,
    /// Time inside the motion checker, seconds.
    pub checker_time_s: f64,
    /// Restarts (layered planner).
    pub attempts: u64,
    /// Length of the returned path.
    pub path_length: Option<f64>,
    /// Length before the improve step.
    pub feasible_path_length: Option<f64>,
    /// The motion checker used.
    pub checker: String,
    /// Seed.
    pub seed: u64,
    /// Pieces of the layered planner's successful rung (or the last tried).
    #[serde(default)]
    pub pieces: Option<usize>,
    /// What shortcutting and blending did.
    #[serde(default)]
    pub smoothing: Option<super::smooth::SmoothStats>,
    /// The risk level Δᵢ of each obstacle in a joint risk mode (obstacle id, Δᵢ).
    #[serde(default)]
    pub risk_allocation: Option<Vec<(String, f64)>>,
    /// The SDPs of an optimisation planner (sizes of the last one built, totals of
    /// all solves).
    #[serde(default)]
    pub sdp: Option<SdpStats>,
    /// The steps of an optimisation planner's retry ladder, in order.
    #[serde(default)]
    pub ladder: Vec<LadderStep>,
    /// The average-risk bound of the standard SOS planner's trajectory: per obstacle,
    /// the largest Cantelli bound of the time-averaged moments over its pieces
    /// (Section V-A.2, a weak guarantee reported beside the certified one).
    #[serde(default)]
    pub average_risk: Option<Vec<(String, f64)>>,
    /// The final check of a certified plan (docs/design.md §5.12); null for an
    /// uncertified planner or without a trajectory.
    #[serde(default)]
    pub final_check: Option<FinalCheckStats>,
    /// The certified bound of the probability that the plan meets any obstacle at any time
    /// (docs/design.md §5.14), computed by the final check of every certified plan (absent
    /// when its time ran out first and, outside trajectory mode, for receding-horizon plans
    /// (remade every cycle) and where an obstacle has a parameter without a rigorous
    /// distribution function; in `risk_mode: trajectory` the plan needs it ≤ Δ).
    #[serde(default)]
    pub whole_path_risk: Option<f64>,
    /// What a receding-horizon plan achieved (docs/design.md §6.9); null otherwise.
    #[serde(default)]
    pub progress: Option<Progress>,
}

/// What a receding-horizon plan achieved: the goal, or how close it gets
/// (docs/design.md §6.9; the progress measure is the Euclidean distance to the goal).
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize, schemars::JsonSchema)]
pub struct Progress {
    /// Whether the trajectory ends at the goal, at rest.
    pub reached_goal: bool,
    /// Distance from the start position to the goal.
    pub start_distance: f64,
    /// Distance from the trajectory's end to the goal (0 when reached).
    pub remaining_distance: f64,
    /// When the trajectory ends.
    pub end_time: f64,
}

/// What the final check of a certified plan cost and found (docs/design.md §5.12).
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize, schemars::JsonSchema)]
pub struct FinalCheckStats {
    /// Wall time of the final checks, seconds (included in `planning_time_s`).
    pub seconds: f64,
    /// Pieces checked.
    pub pieces: usize,
    /// Trajectories the planners' checker accepted and the verify path did not: each
    /// is an internal error (a bug), logged; the plan was made again without the fast
    /// path.
    pub disagreements: u32,
    /// Trajectories the planner returned that the final check found not valid (pieces that
    /// do not meet, outside the horizon, …): each is an internal error (a bug of the
    /// planner's post-processing), logged; the plan was made again without smoothing.
    #[serde(default)]
    pub invalid: u32,
    /// Wall time of the whole-path bound (`stats.whole_path_risk`), seconds (included in
    /// `seconds`); 0 when none was computed.
    #[serde(default)]
    pub whole_path_seconds: f64,
    /// Wall time of the verify path alone (docs/design.md §5.12), seconds (included in
    /// `seconds`): on crowded scenes the whole-path bound runs beside it, and `seconds`
    /// less this is the wait for that bound (or the bound itself, after the check).
    #[serde(default)]
    pub verify_seconds: f64,
}

/// Sizes and solver totals of an optimisation planner's SDPs.
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize, schemars::JsonSchema)]
pub struct SdpStats {
    /// Variables of the last SDP built.
    pub variables: usize,
    /// Constraint rows of the last SDP built.
    pub rows: usize,
    /// PSD constraints of the last SDP built (Gram blocks and affine blocks).
    pub psd_cones: usize,
    /// Largest PSD side of the last SDP built.
    pub largest_psd: usize,
    /// Solves, in all.
    pub solves: u64,
    /// Interior-point iterations, in all.
    pub ipm_iterations: u64,
    /// Time inside the solver, seconds.
    pub solver_time_s: f64,
    /// Time building models and setting up solvers, seconds.
    pub setup_time_s: f64,
}

/// One step of an optimisation planner's retry ladder.
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize, schemars::JsonSchema)]
pub struct LadderStep {
    /// Pieces.
    pub pieces: usize,
    /// Seed of the initial point.
    pub seed: u64,
    /// `η` of the tightened risk level `Δ_opt = η·Δ`.
    pub eta: f64,
    /// Convex–concave iterations run.
    pub iterations: usize,
    /// The last Dirac gap `Σ (E[z²] − E[z]²)` (normalised units).
    pub dirac_gap: Option<f64>,
    /// Started from the default RRT-SOS planner's path (else the perturbed straight line).
    #[serde(default)]
    pub from_rrt: bool,
    /// How it ended (`certified`, or why not).
    pub outcome: String,
}

/// Why a planner returned no trajectory (a typed outcome, not an error).
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum NoPlanReason {
    /// The goal is farther than `max_speed` allows over the horizon (shown at once,
    /// or for the shortest path found).
    OutOfReach {
        /// Distance (or path length) to cover.
        distance: f64,
        /// The speed limit.
        max_speed: f64,
        /// The horizon's duration.
        duration: f64,
    },
    /// The planner's own limits were spent.
    Exhausted {
        /// Sampling iterations.
        iterations: u64,
        /// Edges checked.
        edges_checked: u64,
        /// Layered pieces tried (the ladder), if any.
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        pieces_tried: Vec<usize>,
        /// An optimisation planner's ladder, step by step.
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        ladder: Vec<LadderStep>,
    },
    /// The time limit passed first.
    DeadlineReached {
        /// Sampling iterations.
        iterations: u64,
        /// Edges checked.
        edges_checked: u64,
        /// Layered pieces tried (the ladder), if any.
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        pieces_tried: Vec<usize>,
        /// An optimisation planner's ladder, step by step.
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        ladder: Vec<LadderStep>,
    },
    /// Cancelled.
    Cancelled,
    /// The planned trajectory failed the final check (docs/design.md §5.12) and could
    /// not be planned again: it is not a valid trajectory of the problem (non-finite
    /// numbers, pieces that do not meet, endpoints missed — numeric limits of the
    /// planner), or even the plan made without the fast path was not proven. An
    /// internal error, never returned as certified.
    FinalCheckFailed {
        /// What failed.
        why: String,
    },
}

impl NoPlanReason {
    /// The reason for an unsuccessful status.
    pub fn from_status(status: PlanStatus, stats: &PlanStats, term: &Termination) -> Self {
        let (iterations, edges_checked) = (stats.iterations, stats.edges_checked);
        match status {
            PlanStatus::Cancelled => NoPlanReason::Cancelled,
            _ if term.cancelled() => NoPlanReason::Cancelled,
            PlanStatus::DeadlineReached => NoPlanReason::DeadlineReached {
                iterations,
                edges_checked,
                pieces_tried: Vec::new(),
                ladder: Vec::new(),
            },
            _ => NoPlanReason::Exhausted { iterations, edges_checked, pieces_tried: Vec::new(), ladder: Vec::new() },
        }
    }

    /// One line for messages.
    pub fn message(&self) -> String {
        match self {
            NoPlanReason::OutOfReach { distance, max_speed, duration } => format!(
                "the goal is out of reach: {distance:.6} to cover in {duration} at max_speed {max_speed} (at most {:.6})",
                max_speed * duration
            ),
            NoPlanReason::Exhausted { iterations, edges_checked, pieces_tried, ladder } => format!(
                "no plan within the planner's limits ({iterations} iterations, {edges_checked} edges checked{}{})",
                ladder_text(pieces_tried),
                steps_text(ladder)
            ),
            NoPlanReason::DeadlineReached { iterations, edges_checked, pieces_tried, ladder } => format!(
                "no plan within the time limit ({iterations} iterations, {edges_checked} edges checked{}{})",
                ladder_text(pieces_tried),
                steps_text(ladder)
            ),
            NoPlanReason::Cancelled => "the plan was cancelled".into(),
            NoPlanReason::FinalCheckFailed { why } => {
                format!("internal error: the planned trajectory failed the final check: {why} (reported)")
            }
        }
    }
}

fn steps_text(l: &[LadderStep]) -> String {
    if l.is_empty() {
        return String::new();
    }
    let steps: Vec<String> =
        l.iter().map(|s| format!("{} pieces, seed {}, η {}: {}", s.pieces, s.seed, s.eta, s.outcome)).collect();
    format!("; ladder: {}", steps.join("; "))
}

fn ladder_text(p: &[usize]) -> String {
    if p.is_empty() {
        String::new()
    } else {
        format!(", pieces tried {p:?}")
    }
}

/// The result of a planner run.
#[derive(Clone, Debug)]
pub struct PlanOutcome {
    /// How it ended.
    pub status: PlanStatus,
    /// The trajectory (with `Exact`).
    pub trajectory: Option<Trajectory>,
    /// Whether every piece was accepted by a sound checker.
    pub certified: bool,
    /// Statistics.
    pub stats: PlanStats,
    /// Tree edges, for figures.
    pub tree: Vec<(Vec<f64>, Vec<f64>)>,
    /// Why there is no trajectory (`None` with one).
    pub reason: Option<NoPlanReason>,
}

impl PlanOutcome {
    /// An outcome without a trajectory.
    pub fn no_plan(status: PlanStatus, stats: PlanStats, reason: NoPlanReason) -> Self {
        PlanOutcome { status, trajectory: None, certified: false, stats, tree: Vec::new(), reason: Some(reason) }
    }
}

/// A bad request (the caller's fault); "no plan found" is an outcome, not an error.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum PlanError {
    /// A malformed request field.
    #[error("{field}: {message}")]
    InvalidRequest {
        /// Field.
        field: String,
        /// What is wrong.
        message: String,
    },
    /// Start or goal outside the workspace.
    #[error("{which}: {point:?} is outside the workspace")]
    OutsideWorkspace {
        /// `start` or `goal`.
        which: String,
        /// The point.
        point: Vec<f64>,
    },
    /// Start or goal not inside the Δ-risk contour of every obstacle.
    #[error("{which}: {point:?} is not in the safe set of the Δ-risk contour of obstacle '{obstacle}' at t = {t} (its risk bound exceeds Δ, or it touches the contour)")]
    UnsafeEndpoint {
        /// `start` or `goal`.
        which: String,
        /// The point.
        point: Vec<f64>,
        /// The time.
        t: f64,
        /// The obstacle whose contour it is not inside (empty when unknown).
        obstacle: String,
    },
    /// Our own SDP model was refused by the solver or could not be built: a bug of
    /// the planner, not of the request (the service answers `internal`).
    #[error("{planner}: internal error in the SDP model: {message}")]
    SdpModel {
        /// The planner.
        planner: String,
        /// What failed.
        message: String,
    },
    /// Planner options out of range.
    #[error("invalid planner option {option}: {message}")]
    InvalidOption {
        /// Option name.
        option: String,
        /// What is wrong.
        message: String,
    },
}
