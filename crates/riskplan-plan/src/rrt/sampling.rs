//! Widening-stripe sampling around the start–goal line (Section V-A.3's "smart
//! initialization"; docs/design.md §6.3): points are drawn uniformly in the
//! workspace and kept when within the current half-width of the infinite line
//! through start and goal. The half-width grows with a stripe index chosen by the
//! planner; past the last width the stripe is the whole workspace.

use rand::Rng;

/// Tries per sample before giving up on a stripe and drawing from the whole
/// workspace: a thin stripe can miss a workspace almost entirely (e.g. a line
/// grazing a corner). 10 000 uniform draws make a miss of a stripe covering 1e-3 of
/// the box happen with probability e^-10.
pub const MAX_REJECTION_DRAWS: usize = 10_000;

/// Samples points of the workspace near the start–goal line.
#[derive(Clone, Debug)]
pub struct StripeSampler {
    lower: Vec<f64>,
    upper: Vec<f64>,
    start: Vec<f64>,
    dir: Vec<f64>,
    widths: Vec<f64>,
}

impl StripeSampler {
    /// A sampler for the box `[lower, upper]`, the line through `start` and `goal`,
    /// and half-widths `widths` (index 1 is `widths[0]`).
    pub fn new(lower: &[f64], upper: &[f64], start: &[f64], goal: &[f64], widths: Vec<f64>) -> Self {
        let d: Vec<f64> = goal.iter().zip(start).map(|(g, s)| g - s).collect();
        let n = d.iter().map(|v| v * v).sum::<f64>().sqrt();
        let dir = if n > 0.0 { d.iter().map(|v| v / n).collect() } else { vec![0.0; d.len()] };
        StripeSampler { lower: lower.to_vec(), upper: upper.to_vec(), start: start.to_vec(), dir, widths }
    }

    /// Distance of `p` from the line: `‖p − proj(p)‖`, correct in any dimension
    /// (the authors' 3-D sampler measured the foot point's norm instead, §6.3).
    pub fn dist_to_line(&self, p: &[f64]) -> f64 {
        let v: Vec<f64> = p.iter().zip(&self.start).map(|(a, b)| a - b).collect();
        let along: f64 = v.iter().zip(&self.dir).map(|(a, b)| a * b).sum();
        v.iter().zip(&self.dir).map(|(a, d)| (a - along * d).powi(2)).sum::<f64>().sqrt()
    }

    /// The half-width of stripe `index` (1-based), `∞` past the list.
    pub fn width(&self, index: usize) -> f64 {
        if index == 0 {
            return self.widths.first().copied().unwrap_or(f64::INFINITY);
        }
        self.widths.get(index - 1).copied().unwrap_or(f64::INFINITY)
    }

    /// A uniform point of the box.
    pub fn uniform<R: Rng>(&self, rng: &mut R) -> Vec<f64> {
        self.lower.iter().zip(&self.upper).map(|(&l, &u)| rng.random_range(l..=u)).collect()
    }

    /// A point of the box within the stripe of `index`.
    pub fn sample<R: Rng>(&self, rng: &mut R, index: usize) -> Vec<f64> {
        let w = self.width(index);
        for _ in 0..MAX_REJECTION_DRAWS {
            let p = self.uniform(rng);
            if w.is_infinite() || self.dist_to_line(&p) <= w {
                return p;
            }
        }
        self.uniform(rng)
    }
}

/// The authors' width list `start:step:stop` (inclusive, like MATLAB's colon).
pub fn width_range(start: f64, step: f64, stop: f64) -> Vec<f64> {
    if step.is_nan() || step <= 0.0 || matches!(start.partial_cmp(&stop), None | Some(std::cmp::Ordering::Greater)) {
        return vec![];
    }
    let n = ((stop - start) / step + 1e-9).floor() as usize + 1;
    (0..n).map(|i| start + step * i as f64).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn stripe_points_are_near_the_line() {
        let s = StripeSampler::new(
            &[-1.0, -1.0, -1.0],
            &[1.0, 1.0, 1.0],
            &[-1.0, -1.0, -1.0],
            &[1.0, 1.0, 1.0],
            vec![0.1, 0.2],
        );
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        for _ in 0..200 {
            let p = s.sample(&mut rng, 1);
            assert!(s.dist_to_line(&p) <= 0.1 + 1e-12);
        }
        assert!((s.dist_to_line(&[1.0, -1.0, 0.0]) - 2f64.sqrt()).abs() < 1e-12);
        assert_eq!(width_range(0.1, 0.5, 5.0).len(), 10);
        assert_eq!(s.width(3), f64::INFINITY);
    }
}
