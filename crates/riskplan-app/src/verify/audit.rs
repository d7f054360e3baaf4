//! The Monte Carlo audit of a trajectory: sampled estimates of the true probability
//! of collision along it, to compare with the certified bound Δ. An audit is
//! evidence for a test or a benchmark, never a decision (docs/design.md, Monte Carlo).

use riskplan_math::mc::{clopper_pearson, McEstimate};
use riskplan_scene::{Scene, SceneError, Trajectory};

/// How to audit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AuditOptions {
    /// Audited times per piece, evenly spaced over the piece including both ends (≥ 2).
    pub times_per_piece: usize,
    /// Scenarios of the uncertain parameters per audited point.
    pub samples: u64,
    /// Seed of the scenarios.
    pub seed: u64,
    /// Two-sided confidence of the Clopper–Pearson interval; a point "exceeds Δ"
    /// when the interval's lower end does. At 0.98 the lower end is a one-sided 99 %
    /// bound.
    pub confidence: f64,
}

impl Default for AuditOptions {
    fn default() -> Self {
        AuditOptions { times_per_piece: 50, samples: 2000, seed: 7, confidence: 0.98 }
    }
}

/// One audited point that exceeds Δ.
#[derive(Clone, Debug, PartialEq)]
pub struct Exceedance {
    /// The obstacle.
    pub obstacle: String,
    /// Position and time `(x, t)`.
    pub point: Vec<f64>,
    /// Clopper–Pearson lower bound of the risk there.
    pub lower: f64,
}

/// What an audit found.
#[derive(Clone, Debug, PartialEq)]
pub struct Audit {
    /// The largest estimated probability of collision with one obstacle at one point.
    pub max_estimate: f64,
    /// Points whose risk is above Δ with the audit's confidence.
    pub exceedances: Vec<Exceedance>,
    /// Point × obstacle estimates made.
    pub audited: u64,
}

impl Audit {
    /// Whether some point exceeds Δ with the audit's confidence.
    pub fn exceeds(&self) -> bool {
        !self.exceedances.is_empty()
    }
}

/// Audits `traj` in `scene` against the risk level `delta`, per obstacle and point.
/// Fails only when the scene's parameters cannot be sampled (a `moments`
/// distribution).
pub fn audit_trajectory(scene: &Scene, traj: &Trajectory, delta: f64, o: &AuditOptions) -> Result<Audit, SceneError> {
    audit(scene, traj, delta, o, false)
}

/// Audits `traj` for the joint risk mode: the probability that *any* obstacle contains
/// the point, at each audited point, against Δ (exceedances name the obstacle `any`).
pub fn audit_trajectory_joint(
    scene: &Scene,
    traj: &Trajectory,
    delta: f64,
    o: &AuditOptions,
) -> Result<Audit, SceneError> {
    audit(scene, traj, delta, o, true)
}

/// The audited points `(x, t)` of a trajectory: `times_per_piece` (≥ 2) evenly spaced
/// times per piece, both ends included.
fn audited_points(traj: &Trajectory, times_per_piece: usize) -> Vec<Vec<f64>> {
    let n = times_per_piece.max(2);
    traj.pieces
        .iter()
        .flat_map(|pc| {
            (0..n).map(move |k| {
                let t = pc.t0 + (pc.t1 - pc.t0) * k as f64 / (n - 1) as f64;
                let mut x = pc.at(t);
                x.push(t);
                x
            })
        })
        .collect()
}

/// The Monte Carlo audit of the whole-path event (docs/design.md §5.14): one
/// draw of the parameters per scenario, shared by every audited time and obstacle (and by
/// every point of the robot's body, when the scene has one); per obstacle, the scenarios
/// in which it meets the trajectory at some audited time, and those in which some
/// obstacle does — Clopper–Pearson intervals at `o.confidence`. Dense times
/// (`o.times_per_piece`) estimate P(∃ t : collision) from below (a contact between two
/// audited times is missed). Evidence for tests and benchmarks, never a decision.
pub fn audit_whole_path(
    scene: &Scene,
    traj: &Trajectory,
    o: &AuditOptions,
) -> Result<(Vec<(String, McEstimate)>, McEstimate), SceneError> {
    let model = scene.mc_model()?;
    let points = audited_points(traj, o.times_per_piece);
    let (per_obstacle, any) = model.path_hits(&points, o.samples, o.seed);
    Ok((
        scene
            .obstacles
            .iter()
            .zip(per_obstacle)
            .map(|(ob, k)| (ob.id.clone(), McEstimate::new(k, o.samples, o.confidence)))
            .collect(),
        McEstimate::new(any, o.samples, o.confidence),
    ))
}

fn audit(scene: &Scene, traj: &Trajectory, delta: f64, o: &AuditOptions, joint: bool) -> Result<Audit, SceneError> {
    let model = scene.mc_model()?;
    let points = audited_points(traj, o.times_per_piece);
    let (hits, any) = model.hits_and_any(&points, o.samples, o.seed);
    let mut audit = Audit { max_estimate: 0.0, exceedances: Vec::new(), audited: 0 };
    let mut record = |name: &str, p: &Vec<f64>, k: u64| {
        audit.audited += 1;
        audit.max_estimate = audit.max_estimate.max(k as f64 / o.samples as f64);
        let (lower, _) = clopper_pearson(k, o.samples, o.confidence);
        if lower > delta {
            audit.exceedances.push(Exceedance { obstacle: name.to_string(), point: p.clone(), lower });
        }
    };
    for ((p, h), &a) in points.iter().zip(&hits).zip(&any) {
        if joint {
            record("any", p, a);
        } else {
            for (ob, &k) in scene.obstacles.iter().zip(h) {
                record(&ob.id, p, k);
            }
        }
    }
    Ok(audit)
}
