//! The closed-loop crowd simulation's world (docs/design.md §6.10; `riskplan sim crowd`
//! runs it against the service): a corridor with pedestrians whose true motion is drawn
//! from the distributions of their predictions, and a robot that follows its plans.
//! No I/O here: the command sends the predictions and the requests and moves the world.
//!
//! Sizes are derived from the corridor: it is `CORRIDOR_LENGTH × CORRIDOR_WIDTH` (a
//! hallway at human scale, the only absolute lengths; everything else follows from them
//! and from the robot's speed).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use riskplan_scene::{Piece, Trajectory};

/// The corridor's length (x).
pub const CORRIDOR_LENGTH: f64 = 16.0;
/// The corridor's width (y).
pub const CORRIDOR_WIDTH: f64 = 6.0;
/// The simulation's step and the replanning period (10 Hz).
pub const STEP: f64 = 0.1;
/// Sub-steps of a step at which contact is checked.
pub const CONTACT_SUBSTEPS: usize = 10;

/// A pedestrian's prediction parameters: position error (the perception's noise) and
/// velocity error per axis, as shares of the corridor's width and of a walking speed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CrowdParams {
    /// Standard deviation of the measured position, per axis.
    pub position_std: f64,
    /// Standard deviation of the true velocity around the predicted one, per axis.
    pub velocity_std: f64,
    /// Radius range of the pedestrians (uniform).
    pub radius: (f64, f64),
    /// Walking speeds (uniform, along the corridor, either way).
    pub speed: (f64, f64),
}

impl Default for CrowdParams {
    fn default() -> Self {
        CrowdParams { position_std: CORRIDOR_WIDTH / 300.0, velocity_std: 0.05, radius: (0.2, 0.3), speed: (0.5, 1.3) }
    }
}

/// One pedestrian: its true state and the velocity the predictions use.
#[derive(Clone, Debug, PartialEq)]
pub struct Walker {
    /// Id in the scene.
    pub id: String,
    /// True position.
    pub x: [f64; 2],
    /// True velocity (constant while it walks).
    pub v: [f64; 2],
    /// The nominal (predicted) velocity.
    pub nominal: [f64; 2],
    /// True radius.
    pub radius: f64,
}

/// The world of one episode.
#[derive(Clone, Debug)]
pub struct Crowd {
    /// The pedestrians.
    pub walkers: Vec<Walker>,
    /// Parameters.
    pub params: CrowdParams,
    rng: ChaCha8Rng,
    next_id: usize,
}

/// Corridor bounds: `[-L/2, L/2] × [-W/2, W/2]`.
pub fn bounds() -> ([f64; 2], [f64; 2]) {
    ([-CORRIDOR_LENGTH / 2.0, -CORRIDOR_WIDTH / 2.0], [CORRIDOR_LENGTH / 2.0, CORRIDOR_WIDTH / 2.0])
}

/// The robot's start and goal: near the two ends, at mid-width.
pub fn start_goal() -> ([f64; 2], [f64; 2]) {
    let e = CORRIDOR_LENGTH / 2.0 - CORRIDOR_LENGTH / 16.0;
    ([-e, 0.0], [e, 0.0])
}

impl Crowd {
    /// `n` pedestrians placed at random (seeded), none within `clear` of `avoid`.
    pub fn new(n: usize, seed: u64, params: CrowdParams, avoid: [f64; 2], clear: f64) -> Crowd {
        let mut c = Crowd { walkers: Vec::new(), params, rng: ChaCha8Rng::seed_from_u64(seed), next_id: 0 };
        for _ in 0..n {
            let w = c.spawn(None, avoid, clear);
            c.walkers.push(w);
        }
        c
    }

    /// A new pedestrian: anywhere (`end` = None) or entering at one end of the corridor,
    /// at least `clear` from `avoid`; its true velocity drawn around its nominal one.
    fn spawn(&mut self, end: Option<f64>, avoid: [f64; 2], clear: f64) -> Walker {
        let (lo, hi) = bounds();
        let p = self.params;
        let mut x = [0.0, 0.0];
        for _ in 0..1000 {
            x = [
                end.unwrap_or_else(|| self.rng.random_range(lo[0]..hi[0])),
                self.rng.random_range(lo[1] + 0.5..hi[1] - 0.5),
            ];
            if (x[0] - avoid[0]).hypot(x[1] - avoid[1]) >= clear {
                break;
            }
        }
        let dir = match end {
            Some(e) if e < 0.0 => 1.0,
            Some(_) => -1.0,
            None => {
                if self.rng.random_bool(0.5) {
                    1.0
                } else {
                    -1.0
                }
            }
        };
        let speed = self.rng.random_range(p.speed.0..p.speed.1);
        let nominal = [dir * speed, self.rng.random_range(-0.1..0.1) * speed];
        let err = Normal::new(0.0, p.velocity_std.max(0.0)).unwrap_or_else(|_| Normal::new(0.0, 0.0).unwrap());
        let v = [nominal[0] + err.sample(&mut self.rng), nominal[1] + err.sample(&mut self.rng)];
        let radius = self.rng.random_range(p.radius.0..=p.radius.1);
        self.next_id += 1;
        Walker { id: format!("ped{}", self.next_id), x, v, nominal, radius }
    }

    /// Moves every pedestrian by `dt`; one that leaves the corridor at an end is replaced
    /// by a new one entering at the other end (at least `clear` from the robot, else it
    /// waits outside); the side walls reflect. Returns the ids removed.
    pub fn step(&mut self, dt: f64, robot: [f64; 2], clear: f64) -> Vec<String> {
        let (lo, hi) = bounds();
        let mut gone = Vec::new();
        for i in 0..self.walkers.len() {
            let w = &mut self.walkers[i];
            w.x[0] += w.v[0] * dt;
            w.x[1] += w.v[1] * dt;
            if w.x[1] < lo[1] + w.radius || w.x[1] > hi[1] - w.radius {
                w.v[1] = -w.v[1];
                w.nominal[1] = -w.nominal[1];
                w.x[1] = w.x[1].clamp(lo[1] + w.radius, hi[1] - w.radius);
            }
            if w.x[0] < lo[0] - 1.0 || w.x[0] > hi[0] + 1.0 {
                let end = if w.x[0] > hi[0] { lo[0] - 0.5 } else { hi[0] + 0.5 };
                if (end - robot[0]).abs() >= clear {
                    gone.push(w.id.clone());
                    let nw = self.spawn(Some(end), robot, clear);
                    self.walkers[i] = nw;
                }
            }
        }
        gone
    }

    /// The prediction sent for a pedestrian at time `t`: the measured position (the
    /// true one plus the perception's noise), the nominal velocity, the errors and the
    /// radius range — the distributions the truth is drawn from.
    pub fn prediction(&mut self, i: usize, t: f64) -> serde_json::Value {
        let p = self.params;
        let noise = Normal::new(0.0, p.position_std.max(0.0)).unwrap_or_else(|_| Normal::new(0.0, 0.0).unwrap());
        let w = &self.walkers[i];
        let m = [w.x[0] + noise.sample(&mut self.rng), w.x[1] + noise.sample(&mut self.rng)];
        serde_json::json!({
            "position": m, "velocity": w.nominal, "time": t,
            "radius": {"dist": "uniform", "low": p.radius.0, "high": p.radius.1},
            "position_std": p.position_std, "velocity_std": p.velocity_std,
        })
    }

    /// Whether a robot of radius `rho` moving from `a` to `b` over the next `dt` touches
    /// a pedestrian (checked at [`CONTACT_SUBSTEPS`] instants, pedestrians moving too).
    pub fn contact(&self, robot: &dyn Fn(f64) -> [f64; 2], t: f64, dt: f64, rho: f64) -> Option<String> {
        for k in 0..=CONTACT_SUBSTEPS {
            let s = dt * k as f64 / CONTACT_SUBSTEPS as f64;
            let r = robot(t + s);
            for w in &self.walkers {
                let (px, py) = (w.x[0] + w.v[0] * s, w.x[1] + w.v[1] * s);
                if (r[0] - px).hypot(r[1] - py) <= w.radius + rho {
                    return Some(w.id.clone());
                }
            }
        }
        None
    }
}

/// The robot's position and velocity on a plan at `t` (at rest at its end after it).
pub fn follow(plan: &Trajectory, t: f64) -> ([f64; 2], [f64; 2]) {
    let last = plan.pieces.last();
    let pc: Option<&Piece> = plan.pieces.iter().find(|p| p.t0 <= t && t <= p.t1).or(last);
    let Some(pc) = pc else { return ([0.0; 2], [0.0; 2]) };
    let tt = t.clamp(pc.t0, pc.t1);
    let x = pc.at(tt);
    let mut v = [0.0; 2];
    if t <= pc.t1 {
        for (slot, c) in v.iter_mut().zip(pc.velocity(tt)) {
            *slot = c;
        }
    }
    ([x[0], x.get(1).copied().unwrap_or(0.0)], v)
}
