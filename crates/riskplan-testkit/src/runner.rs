//! The robustness suite's runner: per scene the oracle's judgement, a plan with the
//! default options (at a common Δ and with a given bound if asked: [`RunOptions`]), a
//! Monte Carlo audit of the plan, and the exact-versus-SOS certification counts (with
//! Cantelli's bound); then a Markdown summary and a row of the Δ × bound table. Pure computation: the `robustness`
//! binary of this crate writes the records and prints the table. The scenes and the
//! oracle come from `riskplan-oracle`, which shares no code with riskplan.

use rand::SeedableRng;
use rand_chacha::ChaCha12Rng;
use riskplan_app::verify::{
    audit_trajectory, audit_whole_path, verify_until, AuditOptions, Method, SceneKernel, Status, VerifyReport,
};
use riskplan_app::{no_plan_reason, PlanRequest, RiskMode};
use riskplan_math::contour::{BoundChoice, RiskLevel, RiskLevelError};
use riskplan_math::mc::{clopper_pearson, McEstimate};
use riskplan_oracle::generate::{GeneratedScene, Intent, ObstacleSpec, Shape};
use riskplan_oracle::oracle::{judge, InfeasibleReason, Judgement, ObstacleMoments, OracleOptions, OracleReport};
use riskplan_plan::{PlanError, PlanStatus};
use riskplan_scene::{Scene, Trajectory};
use serde::Serialize;
use serde_json::Value;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// A piece counts as certified "with margin" when every constraint's proven margin,
/// relative to the constraint's value scale on the piece, is at least this.
pub const RELATIVE_MARGIN: f64 = 1e-4;
/// Times per piece at which the value scale of a constraint is sampled: the scale is
/// the largest |value| of the constraint (−E\[P\], or E\[P\]² − (1−Δ)E\[P²\]) at these
/// evenly spaced times, computed by the oracle's quadrature (a proxy for the size of
/// the restricted polynomial's coefficients).
pub const SCALE_SAMPLES: usize = 9;
/// Two-sided confidence of the audits' Clopper–Pearson intervals: the lower end is a
/// one-sided 99 % bound.
pub const AUDIT_CONFIDENCE: f64 = 0.98;

/// How to run the suite.
#[derive(Clone, Debug, PartialEq)]
pub struct RunOptions {
    /// Planner time limit per scene.
    pub time_limit: Duration,
    /// Monte Carlo scenarios per audited point.
    pub audit_samples: u64,
    /// Audited times per piece.
    pub audit_times: usize,
    /// Seed of the audits' scenarios.
    pub audit_seed: u64,
    /// Oracle options.
    pub oracle: OracleOptions,
    /// Δ for every scene instead of the generated one (the scene's `risk`, the plan
    /// request, the oracle, the audits and the certification counts all use it).
    pub delta: Option<f64>,
    /// Which risk bounds the planner may use (`PlanRequest::bound`); `None`: riskplan's
    /// default.
    pub bound: Option<BoundChoice>,
    /// What Δ bounds (`PlanRequest::risk_mode`; default per-obstacle).
    pub risk_mode: RiskMode,
    /// Scenarios of the whole-path audit ([`WholePathRecord`]); 0: no whole-path audit.
    pub whole_path_samples: u64,
    /// Audit the whole path of plans made in every risk mode, not only in trajectory mode.
    pub whole_path_all_modes: bool,
}

/// Least audited times per piece of the whole-path audit (it uses
/// `max(audit_times, WHOLE_PATH_MIN_TIMES)`).
pub const WHOLE_PATH_MIN_TIMES: usize = 100;

impl Default for RunOptions {
    /// The bench's defaults: 10 s, 4000 scenarios × 20 times per piece, audit seed 7,
    /// the generated Δ, riskplan's default bound, per-obstacle risk, 100000 whole-path
    /// scenarios (audited in trajectory mode only).
    fn default() -> Self {
        RunOptions {
            time_limit: Duration::from_secs(10),
            audit_samples: 4000,
            audit_times: 20,
            audit_seed: 7,
            oracle: OracleOptions::default(),
            delta: None,
            bound: None,
            risk_mode: RiskMode::PerObstacle,
            whole_path_samples: 100_000,
            whole_path_all_modes: false,
        }
    }
}

/// The risk bound the oracle judges with: its feasibility judgement says whether a path
/// exists that is safe by Cantelli's bound (the paper's contour), whatever bound the
/// planner is given.
pub const ORACLE_BOUND: &str = "cantelli";

/// The oracle's part of a record.
#[derive(Clone, Debug, Serialize)]
pub struct OracleRecord {
    /// The report (judgement, grid, evaluations).
    #[serde(flatten)]
    pub report: OracleReport,
    /// Wall time, seconds.
    pub time_s: f64,
    /// The bound of its judgement ([`ORACLE_BOUND`]).
    pub bound: &'static str,
}

/// The planner's part of a record.
#[derive(Clone, Debug, Default, Serialize)]
pub struct PlanRecord {
    /// A trajectory was returned.
    pub planned: bool,
    /// Every piece of it was accepted by a sound checker (the outcome's `certified`).
    pub certified: bool,
    /// Wall time of the request, seconds.
    pub time_s: f64,
    /// The outcome's status (no error).
    pub status: Option<PlanStatus>,
    /// The `PlanError` variant, if the request was refused.
    pub error_kind: Option<String>,
    /// The refusal or no-plan reason, as text.
    pub reason: Option<String>,
    /// Length of the path.
    pub path_length: Option<f64>,
    /// Pieces of the trajectory.
    pub pieces: usize,
    /// The certified whole-path bound of the plan (`outcome.stats.whole_path_risk`).
    pub whole_path_risk: Option<f64>,
}

impl PlanRecord {
    /// A typed refusal: a `PlanError`, or no plan with a typed reason (the planner's
    /// limits spent, the speed limit, or the deadline — the last counted separately in
    /// the table, since it says "not found in time", not "impossible").
    pub fn typed_refusal(&self) -> bool {
        !self.planned && (self.error_kind.is_some() || self.status.is_some())
    }
}

/// The audit of a plan.
#[derive(Clone, Debug, Serialize)]
pub struct AuditRecord {
    /// `crate` (`verify::audit_trajectory`) or `own` (sampling the true distributions
    /// of a scene with a `moments` parameter): which audit `max_estimate` and
    /// `over_delta` come from.
    pub method: &'static str,
    /// Largest estimated risk at one point for one obstacle.
    pub max_estimate: f64,
    /// Some point's Clopper–Pearson lower bound (99 %) exceeds Δ.
    pub over_delta: bool,
    /// Scenarios per point.
    pub samples: u64,
    /// Why no audit was made (an error).
    pub error: Option<String>,
    /// The runner's own audit ([`own_audit`]: true distributions, P evaluated from the
    /// structure, same points), made for every plan as a cross-check: its largest
    /// estimate.
    pub own_max_estimate: f64,
    /// The own audit's verdict (lower bound over Δ somewhere).
    pub own_over_delta: bool,
}

impl AuditRecord {
    /// The crate's audit and the own audit disagree about "over Δ".
    pub fn disagree(&self) -> bool {
        self.method == "crate" && self.error.is_none() && self.over_delta != self.own_over_delta
    }
}

/// The Monte Carlo audit of the whole-path event of a plan: one draw of every parameter
/// per scenario, shared by all audited times and obstacles; a hit is a scenario in
/// which some obstacle's P ≥ 0 at some audited time. Clopper–Pearson at
/// [`AUDIT_CONFIDENCE`] (each end a one-sided 99 % bound). Dense times estimate
/// P(∃ t, i : collision) from below (a contact between audited times is missed).
#[derive(Clone, Debug, Serialize)]
pub struct WholePathRecord {
    /// `crate` (`verify::audit_whole_path`) or `own` (the generator's true
    /// distributions and structured P, for scenes with a `moments` parameter:
    /// [`own_whole_path_audit`]).
    pub method: &'static str,
    /// The certified bound (`stats.whole_path_risk`); `None` if the plan has none.
    pub bound: Option<f64>,
    /// Δ of the scene.
    pub delta: f64,
    /// Hits / samples.
    pub estimate: f64,
    /// Clopper–Pearson lower end (one-sided 99 %).
    pub lower: f64,
    /// Clopper–Pearson upper end (one-sided 99 %).
    pub upper: f64,
    /// Scenarios.
    pub samples: u64,
    /// Scenarios with a contact.
    pub hits: u64,
    /// Audited times per piece.
    pub times_per_piece: usize,
    /// Per obstacle: scenarios in which it meets the plan at some audited time.
    pub per_obstacle_hits: Vec<(String, u64)>,
    /// The audit's upper end exceeds Δ (the target: upper ≤ Δ).
    pub over_delta: bool,
    /// The certified bound is below the audit's lower end (a soundness bug).
    pub bound_below_audit: bool,
    /// bound / estimate (when both are known and the estimate is > 0).
    pub conservatism: Option<f64>,
    /// Why no audit was made (then the numbers are NaN / 0).
    pub error: Option<String>,
    /// Wall time of the audit, seconds.
    pub time_s: f64,
}

/// Exact versus SOS certification of a plan's pieces.
#[derive(Clone, Debug, Serialize)]
pub struct CertifyRecord {
    /// Pieces.
    pub pieces: usize,
    /// Pieces the exact method certifies with relative margin ≥ [`RELATIVE_MARGIN`].
    pub exact_with_margin: usize,
    /// Of those, pieces the SOS method certifies too.
    pub sos_also: usize,
    /// Smallest relative margin over the exact-certified pieces.
    pub min_relative_margin: Option<f64>,
    /// Wall time of both verifications, seconds.
    pub time_s: f64,
}

/// Everything about one scene.
#[derive(Clone, Debug, Serialize)]
pub struct SceneRecord {
    /// Index in the suite.
    pub index: usize,
    /// Suite seed.
    pub seed: u64,
    /// Scene name.
    pub name: String,
    /// 2 or 3.
    pub dim: usize,
    /// Some obstacle moves.
    pub moving: bool,
    /// Shape classes present.
    pub shape_mix: String,
    /// Largest workspace side.
    pub width: f64,
    /// Width band label.
    pub width_band: &'static str,
    /// Obstacles.
    pub obstacles: usize,
    /// Δ the scene was run at (the generated one, or `RunOptions::delta`).
    pub delta: f64,
    /// The generated scene's own Δ.
    pub generated_delta: f64,
    /// The bound the plan request used (`auto` or `cantelli`: the request's, else
    /// riskplan's default); `None` if the scene did not load.
    pub bound: Option<String>,
    /// Pedestrians among the obstacles (`Shape::Pedestrian`).
    pub pedestrians: usize,
    /// Speed limit.
    pub max_speed: Option<f64>,
    /// Has a `moments` parameter.
    pub moments_param: bool,
    /// The generator's intent.
    pub intent: Intent,
    /// The scene failed to load (a generator or parser bug).
    pub load_error: Option<String>,
    /// The oracle (None if it failed: see `oracle_error`).
    pub oracle: Option<OracleRecord>,
    /// Why the oracle failed.
    pub oracle_error: Option<String>,
    /// The plan.
    pub plan: Option<PlanRecord>,
    /// The audit of the plan.
    pub audit: Option<AuditRecord>,
    /// The risk mode of the plan request.
    pub risk_mode: &'static str,
    /// The whole-path audit of the plan (trajectory mode, or every mode when asked).
    pub whole_path: Option<WholePathRecord>,
    /// Exact versus SOS.
    pub certify: Option<CertifyRecord>,
    /// The planned trajectory (to reproduce the audit and the certification).
    pub trajectory: Option<Trajectory>,
    /// The scene JSON (to reproduce).
    pub scene: Value,
}

impl SceneRecord {
    /// The oracle's label (`feasible`, `infeasible`, `ambiguous`, or `error`).
    pub fn label(&self) -> &'static str {
        self.oracle.as_ref().map(|o| o.report.judgement.label()).unwrap_or("error")
    }
}

/// Width bands of the summary.
pub fn width_band(w: f64) -> &'static str {
    if w < 3.0 {
        "width 1–3"
    } else if w < 10.0 {
        "width 3–10"
    } else if w < 30.0 {
        "width 10–30"
    } else {
        "width 30–100"
    }
}

/// Whether [`plan_request`] passes the scene's speed limit to the planner.
pub const SPEED_LIMIT_PASSED: bool = true;

/// The plan request of a generated scene: default options, the time limit, the bound
/// of `bound` (`None`: riskplan's default), the risk mode and the scene's Δ.
pub fn plan_request(
    g: &GeneratedScene,
    time_limit: Duration,
    bound: Option<BoundChoice>,
    risk_mode: RiskMode,
) -> Result<PlanRequest, RiskLevelError> {
    // the scene's planner block carries the same limit and its `risk` the same Δ;
    // passing them explicitly makes the request self-describing
    let delta = Some(RiskLevel::from_f64(g.delta)?);
    Ok(PlanRequest { time_limit, max_speed: g.max_speed, delta, bound, risk_mode, ..Default::default() })
}

/// `g` at level `delta` (the generated scene when `None`).
pub fn with_delta(g: &GeneratedScene, delta: Option<f64>) -> GeneratedScene {
    let mut g = g.clone();
    if let Some(d) = delta {
        g.delta = d;
    }
    g
}

/// Pedestrians among a scene's obstacles.
pub fn pedestrians(g: &GeneratedScene) -> usize {
    g.obstacles.iter().filter(|o| matches!(o.shape, Shape::Pedestrian { .. })).count()
}

fn error_kind(e: &PlanError) -> &'static str {
    match e {
        PlanError::InvalidRequest { .. } => "InvalidRequest",
        PlanError::OutsideWorkspace { .. } => "OutsideWorkspace",
        PlanError::UnsafeEndpoint { .. } => "UnsafeEndpoint",
        PlanError::InvalidOption { .. } => "InvalidOption",
        PlanError::SdpModel { .. } => "SdpModel",
    }
}

/// Runs one scene (at `o.delta` when given): oracle, plan, audit, certification counts.
pub fn run_scene(generated: &GeneratedScene, o: &RunOptions) -> SceneRecord {
    let g = &with_delta(generated, o.delta);
    let text = g.json();
    let mut rec = SceneRecord {
        index: g.index,
        seed: g.seed,
        name: g.name.clone(),
        dim: g.dim,
        moving: g.moving(),
        shape_mix: g.shape_mix(),
        width: g.width(),
        width_band: width_band(g.width()),
        obstacles: g.obstacles.len(),
        delta: g.delta,
        generated_delta: generated.delta,
        bound: None,
        pedestrians: pedestrians(g),
        max_speed: g.max_speed,
        moments_param: g.has_moments_param(),
        intent: g.intent,
        load_error: None,
        oracle: None,
        oracle_error: None,
        plan: None,
        audit: None,
        risk_mode: o.risk_mode.as_str(),
        whole_path: None,
        certify: None,
        trajectory: None,
        scene: g.json_value(),
    };
    let t = Instant::now();
    match judge(g, &o.oracle) {
        Ok(report) => {
            rec.oracle = Some(OracleRecord { report, time_s: t.elapsed().as_secs_f64(), bound: ORACLE_BOUND })
        }
        Err(e) => rec.oracle_error = Some(e.to_string()),
    }
    let scene = match Scene::from_json(&text) {
        Ok(s) => Arc::new(s),
        Err(e) => {
            rec.load_error = Some(e.to_string());
            return rec;
        }
    };
    let request = match plan_request(g, o.time_limit, o.bound, o.risk_mode) {
        Ok(r) => r,
        Err(e) => {
            rec.load_error = Some(e.to_string());
            return rec;
        }
    };
    rec.bound = Some(request.bound_on(&scene).as_str().to_string());
    let t = Instant::now();
    let result = request.run(scene.clone(), None);
    let mut plan = PlanRecord { time_s: t.elapsed().as_secs_f64(), ..Default::default() };
    let traj = match result {
        Err(e) => {
            plan.error_kind = Some(error_kind(&e).into());
            plan.reason = Some(e.to_string());
            None
        }
        Ok((_, out)) => {
            plan.status = Some(out.status);
            plan.certified = out.certified && out.trajectory.is_some();
            plan.whole_path_risk = out.stats.whole_path_risk;
            match out.trajectory {
                Some(tr) => {
                    plan.planned = true;
                    plan.pieces = tr.pieces.len();
                    plan.path_length = out.stats.path_length.or_else(|| Some(path_length(&tr)));
                    Some(tr)
                }
                None => {
                    plan.reason = Some(no_plan_reason(&out, o.time_limit));
                    None
                }
            }
        }
    };
    let bound = plan.whole_path_risk;
    rec.plan = Some(plan);
    if let Some(tr) = traj {
        rec.audit = Some(audit(g, &scene, &tr, o));
        if o.whole_path_samples > 0 && (o.risk_mode == RiskMode::Trajectory || o.whole_path_all_modes) {
            rec.whole_path = Some(whole_path_audit(g, &scene, &tr, bound, o));
        }
        rec.certify = certify_counts(g, &scene, &tr);
        rec.trajectory = Some(tr);
    }
    rec
}

/// Length of a trajectory (sampled, 32 points per piece).
fn path_length(tr: &Trajectory) -> f64 {
    tr.pieces
        .iter()
        .map(|p| {
            let pts: Vec<Vec<f64>> = (0..=32).map(|k| p.at(p.t0 + (p.t1 - p.t0) * k as f64 / 32.0)).collect();
            pts.windows(2)
                .map(|w| w[0].iter().zip(&w[1]).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt())
                .sum::<f64>()
        })
        .sum()
}

fn audit_points(tr: &Trajectory, n: usize) -> Vec<(Vec<f64>, f64)> {
    let n = n.max(2);
    tr.pieces
        .iter()
        .flat_map(|pc| {
            (0..n).map(move |k| {
                let t = pc.t0 + (pc.t1 - pc.t0) * k as f64 / (n - 1) as f64;
                (pc.at(t), t)
            })
        })
        .collect()
}

fn audit(g: &GeneratedScene, scene: &Scene, tr: &Trajectory, o: &RunOptions) -> AuditRecord {
    let (own_max_estimate, own_over_delta) = own_audit(&g.obstacles, g.delta, &audit_points(tr, o.audit_times), o);
    if !g.has_moments_param() {
        let opts = AuditOptions {
            times_per_piece: o.audit_times,
            samples: o.audit_samples,
            seed: o.audit_seed,
            confidence: AUDIT_CONFIDENCE,
        };
        return match audit_trajectory(scene, tr, g.delta, &opts) {
            Ok(a) => AuditRecord {
                method: "crate",
                max_estimate: a.max_estimate,
                over_delta: a.exceeds(),
                samples: o.audit_samples,
                error: None,
                own_max_estimate,
                own_over_delta,
            },
            Err(e) => AuditRecord {
                method: "crate",
                max_estimate: f64::NAN,
                over_delta: false,
                samples: o.audit_samples,
                error: Some(e.to_string()),
                own_max_estimate,
                own_over_delta,
            },
        };
    }
    AuditRecord {
        method: "own",
        max_estimate: own_max_estimate,
        over_delta: own_over_delta,
        samples: o.audit_samples,
        error: None,
        own_max_estimate,
        own_over_delta,
    }
}

/// Monte Carlo audit from the generator's true distributions and structured P: the
/// same scenarios at every point; a point is over Δ when the Clopper–Pearson lower
/// bound of an obstacle's collision probability there exceeds Δ.
pub fn own_audit(obstacles: &[ObstacleSpec], delta: f64, points: &[(Vec<f64>, f64)], o: &RunOptions) -> (f64, bool) {
    let mut rng = ChaCha12Rng::seed_from_u64(o.audit_seed);
    let scenarios: Vec<Vec<Vec<f64>>> = (0..o.audit_samples)
        .map(|_| obstacles.iter().map(|ob| ob.params.iter().map(|p| p.dist.sample(&mut rng)).collect()).collect())
        .collect();
    let (mut worst, mut over) = (0.0f64, false);
    for (x, t) in points {
        for (k, ob) in obstacles.iter().enumerate() {
            let hits = scenarios.iter().filter(|s| ob.eval(x, *t, &s[k]) >= 0.0).count() as u64;
            worst = worst.max(hits as f64 / o.audit_samples as f64);
            let (lower, _) = clopper_pearson(hits, o.audit_samples, AUDIT_CONFIDENCE);
            over |= lower > delta;
        }
    }
    (worst, over)
}

/// The whole-path audit of `tr` ([`WholePathRecord`]): the crate's, or the own one for
/// scenes with a `moments` parameter; `max(audit_times, 100)` times per piece.
fn whole_path_audit(
    g: &GeneratedScene,
    scene: &Scene,
    tr: &Trajectory,
    bound: Option<f64>,
    o: &RunOptions,
) -> WholePathRecord {
    let t = Instant::now();
    let times = o.audit_times.max(WHOLE_PATH_MIN_TIMES);
    let (method, result) = if g.has_moments_param() {
        let (per, any) =
            own_whole_path_audit(&g.obstacles, &audit_points(tr, times), o.whole_path_samples, o.audit_seed);
        let per = g.obstacles.iter().zip(per).map(|(ob, k)| (ob.id.clone(), k)).collect::<Vec<_>>();
        ("own", Ok((per, McEstimate::new(any, o.whole_path_samples, AUDIT_CONFIDENCE))))
    } else {
        let opts = AuditOptions {
            times_per_piece: times,
            samples: o.whole_path_samples,
            seed: o.audit_seed,
            confidence: AUDIT_CONFIDENCE,
        };
        let r = audit_whole_path(scene, tr, &opts)
            .map(|(per, any)| (per.into_iter().map(|(id, e)| (id, e.hits)).collect::<Vec<_>>(), any))
            .map_err(|e| e.to_string());
        ("crate", r)
    };
    let mut rec = WholePathRecord {
        method,
        bound,
        delta: g.delta,
        estimate: f64::NAN,
        lower: f64::NAN,
        upper: f64::NAN,
        samples: o.whole_path_samples,
        hits: 0,
        times_per_piece: times,
        per_obstacle_hits: vec![],
        over_delta: false,
        bound_below_audit: false,
        conservatism: None,
        error: None,
        time_s: 0.0,
    };
    match result {
        Ok((per, e)) => {
            rec.estimate = e.estimate;
            rec.lower = e.lower;
            rec.upper = e.upper;
            rec.hits = e.hits;
            rec.per_obstacle_hits = per;
            rec.over_delta = e.upper > g.delta;
            rec.bound_below_audit = bound.is_some_and(|b| b < e.lower);
            rec.conservatism = bound.filter(|_| e.estimate > 0.0).map(|b| b / e.estimate);
        }
        Err(e) => rec.error = Some(e),
    }
    rec.time_s = t.elapsed().as_secs_f64();
    rec
}

/// The whole-path variant of [`own_audit`]: per scenario one draw of every obstacle's
/// parameters from the generator's true distributions, shared by all `points` and
/// obstacles; returns per obstacle the scenarios in which its P ≥ 0 at some point, and
/// the scenarios in which some obstacle's does.
pub fn own_whole_path_audit(
    obstacles: &[ObstacleSpec],
    points: &[(Vec<f64>, f64)],
    samples: u64,
    seed: u64,
) -> (Vec<u64>, u64) {
    let mut rng = ChaCha12Rng::seed_from_u64(seed);
    let mut per = vec![0u64; obstacles.len()];
    let mut any = 0u64;
    for _ in 0..samples {
        let w: Vec<Vec<f64>> =
            obstacles.iter().map(|ob| ob.params.iter().map(|p| p.dist.sample(&mut rng)).collect()).collect();
        let mut hit = false;
        for (k, ob) in obstacles.iter().enumerate() {
            if points.iter().any(|(x, t)| ob.eval(x, *t, &w[k]) >= 0.0) {
                per[k] += 1;
                hit = true;
            }
        }
        any += u64::from(hit);
    }
    (per, any)
}

/// The scene's verification of `tr` at its Δ with Cantelli's bound only, whatever
/// riskplan's default bound (the relative margins below are of Cantelli's constraints).
fn cantelli_verify(kernel: &SceneKernel, tr: &Trajectory, method: Method) -> Option<VerifyReport> {
    let delta = &kernel.scene().risk;
    verify_until(kernel, tr, delta, method, &Default::default(), BoundChoice::Cantelli, &|| false).ok()
}

fn certify_counts(g: &GeneratedScene, scene: &Scene, tr: &Trajectory) -> Option<CertifyRecord> {
    let t = Instant::now();
    let moments: Vec<ObstacleMoments> = g.obstacles.iter().map(ObstacleMoments::new).collect::<Result<_, _>>().ok()?;
    let kernel = SceneKernel::from(scene);
    let exact = cantelli_verify(&kernel, tr, Method::Exact)?;
    let mut ok = vec![false; tr.pieces.len()];
    let mut min_rel: Option<f64> = None;
    for (pi, (pr, pc)) in exact.pieces.iter().zip(&tr.pieces).enumerate() {
        if !pr.safe {
            continue;
        }
        let times: Vec<f64> =
            (0..SCALE_SAMPLES).map(|k| pc.t0 + (pc.t1 - pc.t0) * k as f64 / (SCALE_SAMPLES - 1) as f64).collect();
        let mut piece_min = f64::INFINITY;
        for (orep, om) in pr.obstacles.iter().zip(&moments) {
            let vals: Vec<(f64, f64)> = times
                .iter()
                .map(|&tt| {
                    let (ep, ep2) = om.at(&pc.at(tt), tt);
                    (-ep, ep * ep - (1.0 - g.delta) * ep2)
                })
                .collect();
            for c in &orep.constraints {
                let scale =
                    vals.iter().map(|(a, b)| if c.name == "mean" { a.abs() } else { b.abs() }).fold(0.0, f64::max);
                let rel = match c.margin {
                    Some(mg) if c.status == Status::Safe && scale > 0.0 => mg / scale,
                    _ => f64::NEG_INFINITY,
                };
                piece_min = piece_min.min(rel);
            }
        }
        if piece_min >= RELATIVE_MARGIN {
            ok[pi] = true;
            min_rel = Some(min_rel.map_or(piece_min, |m: f64| m.min(piece_min)));
        }
    }
    let exact_with_margin = ok.iter().filter(|&&b| b).count();
    let sos_also = if exact_with_margin > 0 {
        let sos = cantelli_verify(&kernel, tr, Method::Sos)?;
        sos.pieces.iter().zip(&ok).filter(|(p, &k)| k && p.safe).count()
    } else {
        0
    };
    Some(CertifyRecord {
        pieces: tr.pieces.len(),
        exact_with_margin,
        sos_also,
        min_relative_margin: min_rel,
        time_s: t.elapsed().as_secs_f64(),
    })
}

fn median(mut v: Vec<f64>) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    Some(if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) })
}

fn row(label: &str, rs: &[&SceneRecord]) -> String {
    let count = |l: &str| rs.iter().filter(|r| r.label() == l).count();
    let (feas, infeas, amb, err) = (count("feasible"), count("infeasible"), count("ambiguous"), count("error"));
    let planned = |r: &&&SceneRecord| r.plan.as_ref().is_some_and(|p| p.planned);
    let plans_on_feasible = rs.iter().filter(|r| r.label() == "feasible").filter(planned).count();
    let times: Vec<f64> = rs.iter().filter(planned).filter_map(|r| r.plan.as_ref().map(|p| p.time_s)).collect();
    let audited: Vec<&AuditRecord> = rs.iter().filter_map(|r| r.audit.as_ref()).collect();
    let over = audited.iter().filter(|a| a.over_delta).count();
    let own_over = audited.iter().filter(|a| a.own_over_delta).count();
    let disagree = audited.iter().filter(|a| a.disagree()).count();
    let infeasible: Vec<&&SceneRecord> = rs.iter().filter(|r| r.label() == "infeasible").collect();
    let typed = infeasible.iter().filter(|r| r.plan.as_ref().is_some_and(|p| p.typed_refusal())).count();
    let deadline = infeasible
        .iter()
        .filter(|r| r.plan.as_ref().is_some_and(|p| !p.planned && p.status == Some(PlanStatus::DeadlineReached)))
        .count();
    let planned_infeasible = infeasible.iter().filter(|r| r.plan.as_ref().is_some_and(|p| p.planned)).count();
    let pieces: usize = rs.iter().filter_map(|r| r.certify.as_ref()).map(|c| c.pieces).sum();
    let exact: usize = rs.iter().filter_map(|r| r.certify.as_ref()).map(|c| c.exact_with_margin).sum();
    let sos: usize = rs.iter().filter_map(|r| r.certify.as_ref()).map(|c| c.sos_also).sum();
    let pct =
        if feas > 0 { format!(" ({:.0} %)", 100.0 * plans_on_feasible as f64 / feas as f64) } else { String::new() };
    let fmt = |v: Option<f64>| v.map(|x| format!("{x:.2}")).unwrap_or_else(|| "–".into());
    let maxt = times.iter().cloned().reduce(f64::max);
    format!(
        "| {label} | {} | {feas} | {infeas} | {amb}{} | {plans_on_feasible}/{feas}{pct} | {} | {} | {over}/{} | {own_over} ({disagree}) | {typed}/{} ({deadline} deadline) | {planned_infeasible} | {exact}/{pieces} | {sos}/{exact} |",
        rs.len(),
        if err > 0 { format!(" (+{err} oracle errors)") } else { String::new() },
        fmt(median(times)),
        fmt(maxt),
        audited.len(),
        infeasible.len(),
    )
}

/// A row of the summary: its label and which records it counts.
type Group = (String, Box<dyn Fn(&SceneRecord) -> bool>);

/// The Markdown summary of a suite run.
pub fn summary_table(records: &[SceneRecord]) -> String {
    let mut out = vec![
        "| class | scenes | feasible (Cantelli oracle) | infeasible | ambiguous | plans among feasible (target ≥ 95 %) | median plan time (s) | max plan time (s) | plans over Δ (target 0) | own audit over Δ (disagreeing) | infeasible with typed refusal (target all) | plans on infeasible | pieces exact-certified, rel. margin ≥ 1e-4 | of those SOS-certified |".to_string(),
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|".to_string(),
    ];
    let all: Vec<&SceneRecord> = records.iter().collect();
    out.push(row("all", &all));
    let mut groups: Vec<Group> = vec![];
    for dim in [2usize, 3] {
        for moving in [false, true] {
            groups.push((
                format!("{dim}-D {}", if moving { "moving" } else { "static" }),
                Box::new(move |r: &SceneRecord| r.dim == dim && r.moving == moving),
            ));
        }
    }
    let mut mixes: Vec<String> = records.iter().map(|r| r.shape_mix.clone()).collect();
    mixes.sort();
    mixes.dedup();
    for mix in mixes {
        let m = mix.clone();
        groups.push((format!("shapes {mix}"), Box::new(move |r: &SceneRecord| r.shape_mix == m)));
    }
    for band in ["width 1–3", "width 3–10", "width 10–30", "width 30–100"] {
        groups.push((band.into(), Box::new(move |r: &SceneRecord| r.width_band == band)));
    }
    groups.push(("with speed limit".into(), Box::new(|r: &SceneRecord| r.max_speed.is_some())));
    groups.push(("with a moments parameter".into(), Box::new(|r: &SceneRecord| r.moments_param)));
    groups.push(("with a pedestrian".into(), Box::new(|r: &SceneRecord| r.pedestrians > 0)));
    for (label, f) in groups {
        let rs: Vec<&SceneRecord> = records.iter().filter(|r| f(r)).collect();
        if !rs.is_empty() {
            out.push(row(&label, &rs));
        }
    }
    // infeasible reasons of the oracle and generator intents
    let mut reasons: std::collections::BTreeMap<String, usize> = Default::default();
    for r in records {
        let key = match r.oracle.as_ref().map(|o| &o.report.judgement) {
            Some(Judgement::Infeasible { reason }) => match reason {
                InfeasibleReason::EndpointUnsafe { .. } => "endpoint_unsafe",
                InfeasibleReason::Disconnected => "disconnected",
                InfeasibleReason::OutOfReach { .. } => "out_of_reach",
            },
            _ => continue,
        };
        *reasons.entry(format!("{key} (intent {:?})", r.intent)).or_default() += 1;
    }
    out.push(String::new());
    out.push(format!(
        "Oracle infeasibility reasons: {}.",
        reasons.iter().map(|(k, v)| format!("{k}: {v}")).collect::<Vec<_>>().join(", ")
    ));
    let intended_feasible_not = records.iter().filter(|r| r.intent.feasible() && r.label() != "feasible").count();
    out.push(format!("Intended feasible but not judged feasible by the oracle: {intended_feasible_not}."));
    if !SPEED_LIMIT_PASSED {
        out.push(
            "The planner is not given the scenes' speed limits yet (runner::plan_request): it may plan on \
             out-of-reach scenes, and such plans count under \"plans on infeasible\"."
                .into(),
        );
    }
    out.push(format!(
        "The oracle judges with Cantelli's bound ({ORACLE_BOUND}): \"feasible\" means a path safe by Cantelli's \
         contour exists, \"infeasible\" that none does. Run at Δ {} with bound {}: a planner given `auto` may \
         plan scenes the oracle calls infeasible (counted under \"plans on infeasible\"); the audit decides \
         whether such a plan keeps Δ.",
        deltas(records),
        bounds(records),
    ));
    out.push(
        "A typed refusal is a `PlanError` or a typed no-plan reason (limits spent, speed limit, or the deadline, \
         counted in brackets). \
         Plans over Δ: the audit's Clopper–Pearson lower bound (99 %) exceeds Δ at some point for some obstacle \
         (the crate's `audit_trajectory`, or the own audit for scenes with a `moments` parameter); the own audit \
         (true distributions, P evaluated from the generator's structure, never expanded) is run on every plan \
         as a cross-check, with the count of plans where the two disagree."
            .into(),
    );
    out.join("\n")
}

/// The header of [`whole_path_row`].
pub const WHOLE_PATH_HEADER: &str = "| risk mode | Δ | scenes | feasible (Cantelli oracle) | plans among feasible | plans (all) | whole-path bound ≤ Δ / plans | audited (crate; own; errors) | audits over Δ (upper end, target 0) | bounds below audit (lower end, target 0) | conservatism bound/estimate: median | worst (max) | least (min) | plans with estimate 0 | median plan time (s) | whole-path audit time (s, total) |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|";

/// One row of the whole-path table: the records of one run; `None` when no plan has a
/// whole-path audit. Conservatism is the certified bound over the audit's estimate, over
/// the plans with an estimate > 0.
pub fn whole_path_row(records: &[SceneRecord]) -> Option<String> {
    let audits: Vec<&WholePathRecord> = records.iter().filter_map(|r| r.whole_path.as_ref()).collect();
    if audits.is_empty() {
        return None;
    }
    let planned = |r: &&SceneRecord| r.plan.as_ref().is_some_and(|p| p.planned);
    let feasible = records.iter().filter(|r| r.label() == "feasible").count();
    let on_feasible = records.iter().filter(|r| r.label() == "feasible").filter(planned).count();
    let plans: Vec<&SceneRecord> = records.iter().filter(planned).collect();
    let within =
        plans.iter().filter(|r| r.plan.as_ref().and_then(|p| p.whole_path_risk).is_some_and(|b| b <= r.delta)).count();
    let ok: Vec<&&WholePathRecord> = audits.iter().filter(|a| a.error.is_none()).collect();
    let crate_n = ok.iter().filter(|a| a.method == "crate").count();
    let own_n = ok.iter().filter(|a| a.method == "own").count();
    let errors = audits.len() - ok.len();
    let over = ok.iter().filter(|a| a.over_delta).count();
    let below = ok.iter().filter(|a| a.bound_below_audit).count();
    let cons: Vec<f64> = ok.iter().filter_map(|a| a.conservatism).collect();
    let zero = ok.iter().filter(|a| a.hits == 0).count();
    let fmt = |v: Option<f64>| v.map(|x| format!("{x:.3}")).unwrap_or_else(|| "–".into());
    let worst = cons.iter().cloned().reduce(f64::max);
    let least = cons.iter().cloned().reduce(f64::min);
    let times: Vec<f64> = plans.iter().filter_map(|r| r.plan.as_ref().map(|p| p.time_s)).collect();
    let audit_s: f64 = audits.iter().map(|a| a.time_s).sum();
    let mut modes: Vec<&str> = records.iter().map(|r| r.risk_mode).collect();
    modes.sort();
    modes.dedup();
    let pct = |a: usize, b: usize| {
        if b > 0 {
            format!("{a}/{b} ({:.0} %)", 100.0 * a as f64 / b as f64)
        } else {
            format!("{a}/{b}")
        }
    };
    Some(format!(
        "| {} | {} | {} | {feasible} | {} | {} | {within}/{} | {crate_n}; {own_n}; {errors} | {over}/{} | {below}/{} | {} | {} | {} | {zero} | {} | {audit_s:.1} |",
        modes.join("/"),
        deltas(records),
        records.len(),
        pct(on_feasible, feasible),
        plans.len(),
        plans.len(),
        ok.len(),
        ok.len(),
        fmt(median(cons)),
        fmt(worst),
        fmt(least),
        median(times).map(|x| format!("{x:.2}")).unwrap_or_else(|| "–".into()),
    ))
}

/// The distinct Δ of the records (`0.01`, or `0.01–0.2 (generated)` when they vary).
fn deltas(records: &[SceneRecord]) -> String {
    let lo = records.iter().map(|r| r.delta).fold(f64::INFINITY, f64::min);
    let hi = records.iter().map(|r| r.delta).fold(f64::NEG_INFINITY, f64::max);
    if records.is_empty() {
        "–".into()
    } else if lo == hi {
        format!("{lo}")
    } else {
        format!("{lo}–{hi} (generated)")
    }
}

/// The distinct bounds of the records' plan requests, joined with `/`.
fn bounds(records: &[SceneRecord]) -> String {
    let mut b: Vec<&str> = records.iter().filter_map(|r| r.bound.as_deref()).collect();
    b.sort();
    b.dedup();
    if b.is_empty() {
        "–".into()
    } else {
        b.join("/")
    }
}

/// The header of [`delta_bound_row`] (docs/benchmarks.md, "Robustness suite", table "Risk
/// levels and bounds").
pub const DELTA_BOUND_HEADER: &str = "| Δ | bound | scenes | feasible (Cantelli oracle) | certified plans / feasible | certified plans / all | plans on infeasible | plans over Δ (audit; own audit) | median plan time (s) | pedestrian scenes: certified plans / feasible | pedestrian scenes: certified plans / all |\n|---|---|---|---|---|---|---|---|---|---|---|";

/// One row of the Δ × bound table: the records of one run (one Δ, one bound).
/// "Certified plans" are returned trajectories every piece of which a sound checker
/// accepted; "feasible" is the oracle's (Cantelli) judgement; plans over Δ count plans
/// whose audit (the crate's, or the own audit for scenes with a `moments` parameter)
/// has a Clopper–Pearson lower bound over Δ somewhere, then the own audit's count; the
/// median time is over the plans found.
pub fn delta_bound_row(records: &[SceneRecord]) -> String {
    let certified = |r: &SceneRecord| r.plan.as_ref().is_some_and(|p| p.planned && p.certified);
    let share = |a: usize, b: usize| {
        if b == 0 {
            format!("{a}/{b}")
        } else {
            format!("{a}/{b} ({:.0} %)", 100.0 * a as f64 / b as f64)
        }
    };
    let feasible: Vec<&SceneRecord> = records.iter().filter(|r| r.label() == "feasible").collect();
    let on_feasible = feasible.iter().filter(|r| certified(r)).count();
    let all = records.iter().filter(|r| certified(r)).count();
    let on_infeasible =
        records.iter().filter(|r| r.label() == "infeasible" && r.plan.as_ref().is_some_and(|p| p.planned)).count();
    let audited: Vec<&AuditRecord> = records.iter().filter_map(|r| r.audit.as_ref()).collect();
    let over = audited.iter().filter(|a| a.over_delta).count();
    let own_over = audited.iter().filter(|a| a.own_over_delta).count();
    let times: Vec<f64> =
        records.iter().filter_map(|r| r.plan.as_ref()).filter(|p| p.planned).map(|p| p.time_s).collect();
    let ped: Vec<&SceneRecord> = records.iter().filter(|r| r.pedestrians > 0).collect();
    let ped_feasible = ped.iter().filter(|r| r.label() == "feasible").count();
    let ped_on_feasible = ped.iter().filter(|r| r.label() == "feasible").filter(|r| certified(r)).count();
    let ped_all = ped.iter().filter(|r| certified(r)).count();
    format!(
        "| {} | {} | {} | {} | {} | {} | {on_infeasible} | {over}/{}; {own_over} | {} | {} | {} |",
        deltas(records),
        bounds(records),
        records.len(),
        feasible.len(),
        share(on_feasible, feasible.len()),
        share(all, records.len()),
        audited.len(),
        median(times).map(|x| format!("{x:.2}")).unwrap_or_else(|| "–".into()),
        share(ped_on_feasible, ped_feasible),
        share(ped_all, ped.len()),
    )
}
