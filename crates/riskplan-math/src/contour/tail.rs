//! The Gaussian tail bound of a moving disk or ball (docs/design.md §3.11; beyond the
//! paper): a pedestrian-like obstacle whose centre moves at a nominal velocity
//! with isotropic Gaussian errors of position and velocity, and whose radius has a
//! bounded support.
//!
//! The obstacle at time t is the disk (ball in 3-D) of radius `R` around
//!
//! ```text
//! c(t) = m(t) + e(t),   m(t) = p + v·(t − t_ref),   e(t) = a + b·(t − t_ref),
//! a ~ N(0, σ_p² I),  b ~ N(0, σ_v² I)  independent,  so  e(t) ~ N(0, s(t)·I),
//! s(t) = σ_p² + σ_v²·(t − t_ref)²,
//! ```
//!
//! and `R ≤ R_max` surely. A robot point x (or a robot disk/ball of radius ρ around x)
//! touches it only if `‖x − c(t)‖ ≤ R + ρ`, hence only if
//! `‖e(t)‖ ≥ ‖x − m(t)‖ − (R_max + ρ)`. With `reach = R_max + ρ` and `e/√s` a standard
//! normal vector in n dimensions,
//!
//! ```text
//! Prob(contact at t) ≤ Prob(χ²_n ≥ k²),   k = (‖x − m(t)‖ − reach)/√s(t),
//! ```
//!
//! so every point with `‖x − m(t)‖ ≥ reach + κ·√s(t)`, `Prob(χ²_n ≥ κ²) ≤ Δ`, has
//! probability of contact at most Δ at that instant. [`tail_kappa`] gives an upper bound
//! of the smallest such κ (exact tail in 2-D, Chernoff's bound otherwise);
//! [`GaussianDisk::sd_upper`] an upper bound of √s. Nothing here decides a piece; the
//! certifier (`certify::gaussian_tail`) proves the polynomial inequality on whole pieces.

use crate::poly::{rational_to_f64, Interval};
use num_rational::BigRational;

/// Relative margin added to every float result that must bound a real value from
/// above here (κ, √s): the libm functions used (`ln`, `hypot`, `sqrt`) err by at most a
/// few ulps (2⁻⁵⁰ relative), so 2⁻⁴⁰ covers them a thousand times over while changing
/// a distance by less than 10⁻¹² of itself.
pub const TAIL_REL_MARGIN: f64 = 1.0 / (1u64 << 40) as f64;

/// Absolute floor added to √s: a product `σ_v·|τ|` that underflows loses at most the
/// smallest subnormal; this covers it.
pub const TAIL_ABS_FLOOR: f64 = f64::MIN_POSITIVE;

/// A moving disk/ball with Gaussian centre error (module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct GaussianDisk {
    /// Nominal centre at `t_ref`, enclosed (the scene gives exact rationals).
    pub position: Vec<Interval>,
    /// Nominal velocity, enclosed.
    pub velocity: Vec<Interval>,
    /// The time of the prediction, enclosed.
    pub t_ref: Interval,
    /// The largest radius (the supremum of the radius's support) plus the robot's body
    /// radius: contact is impossible farther than `reach` from the true centre.
    pub reach: f64,
    /// Standard deviation of each coordinate of the position error at `t_ref` (rounded
    /// up from the scene's exact value).
    pub sigma_p: f64,
    /// Standard deviation of each coordinate of the velocity error (rounded up).
    pub sigma_v: f64,
}

impl GaussianDisk {
    /// Spatial dimension.
    pub fn dim(&self) -> usize {
        self.position.len()
    }

    /// An upper bound of the standard deviation `√s(t)` of each coordinate of the centre
    /// at time `t` (hypot avoids the overflow and underflow of squaring; module docs).
    pub fn sd_upper(&self, t: f64) -> f64 {
        let d = Interval::point(t) - self.t_ref;
        // an upper bound of |t − t_ref|, then of the product
        let tau = d.lo.abs().max(d.hi.abs());
        let b = self.sigma_v * tau * (1.0 + TAIL_REL_MARGIN) + TAIL_ABS_FLOOR;
        let h = self.sigma_p.hypot(b);
        h * (1.0 + TAIL_REL_MARGIN) + TAIL_ABS_FLOOR
    }

    /// An upper bound of the radius `reach + κ·√s(t)` outside of which (around the
    /// nominal centre) the probability of contact at `t` is at most Δ (`kappa` from
    /// [`tail_kappa`]); infinite when it overflows.
    pub fn radius_upper(&self, t: f64, kappa: f64) -> f64 {
        (Interval::point(self.reach) + Interval::point(kappa) * Interval::point(self.sd_upper(t))).hi
    }

    /// The nominal centre at `t`, enclosed.
    pub fn centre(&self, t: f64) -> Vec<Interval> {
        let tau = Interval::point(t) - self.t_ref;
        self.position.iter().zip(&self.velocity).map(|(&p, &v)| p + v * tau).collect()
    }

    /// A box that contains every point whose probability of contact exceeds Δ at some
    /// time of `[ta, tb]`: the nominal centre's range (affine in t: its end values)
    /// widened by the largest radius of [`GaussianDisk::radius_upper`] (√s is convex in
    /// t, so its largest value is at an end).
    pub fn slab_box(&self, ta: f64, tb: f64, kappa: f64) -> Vec<(f64, f64)> {
        let r = self.radius_upper(ta, kappa).max(self.radius_upper(tb, kappa));
        let (ca, cb) = (self.centre(ta), self.centre(tb));
        ca.iter()
            .zip(&cb)
            .map(|(a, b)| {
                let lo = Interval::point(a.lo.min(b.lo)) - Interval::point(r);
                let hi = Interval::point(a.hi.max(b.hi)) + Interval::point(r);
                (lo.lo, hi.hi)
            })
            .collect()
    }
}

/// The natural logarithm of an upper bound of `Prob(χ²_n ≥ k²)` for k > 0: in 2-D the
/// tail itself, `−k²/2`; in 1-D and 3-D the exact tails `erfc(k/√2)` and
/// `erfc(k/√2) + √(2/π)·k·e^{−k²/2}` bounded by the Mills ratio `erfc(k/√2) ≤
/// √(2/π)·e^{−k²/2}/k`; otherwise Chernoff's `(z·e^{1−z})^{n/2}`, `z = k²/n ≥ 1` (0 below).
pub fn log_tail_upper(dim: usize, k: f64) -> f64 {
    let c = (2.0 / std::f64::consts::PI).sqrt().ln();
    match dim {
        2 => -0.5 * k * k,
        1 => c - 0.5 * k * k - k.ln(),
        3 => c + (k + 1.0 / k).ln() - 0.5 * k * k,
        n => {
            let z = k * k / n as f64;
            if z <= 1.0 {
                0.0
            } else {
                0.5 * n as f64 * (z.ln() + 1.0 - z)
            }
        }
    }
    .min(0.0)
}

/// An upper bound of the smallest κ with `Prob(χ²_n ≥ κ²) ≤ Δ` (`n = dim`): the κ at
/// which [`log_tail_upper`] is at most ln Δ, by bisection (closed form in 2-D:
/// κ² = 2·ln(1/Δ)). Δ is rounded down to a float first (a smaller Δ needs a larger κ);
/// the logarithm compared is lowered by a relative [`TAIL_REL_MARGIN`] and κ rounded up
/// by it (the libm functions err by a few ulps). `None` when Δ is not in (0, 1) or the
/// dimension is 0.
pub fn tail_kappa(dim: usize, delta: &BigRational) -> Option<f64> {
    let mut d = rational_to_f64(delta);
    if BigRational::from_float(d).is_some_and(|e| &e > delta) {
        d = d.next_down();
    }
    if !(d > 0.0 && d < 1.0) || dim == 0 {
        return None;
    }
    let target = d.ln() * (1.0 + TAIL_REL_MARGIN);
    if dim == 2 {
        return Some((-2.0 * target).sqrt() * (1.0 + TAIL_REL_MARGIN));
    }
    // log_tail_upper(hi) ≤ target is kept; it needs only to hold at the κ returned (the
    // true tail decreases in k)
    let mut hi = 1.0;
    while log_tail_upper(dim, hi) > target {
        hi *= 2.0;
        if !hi.is_finite() {
            return None;
        }
    }
    let mut lo = 0.0;
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid > 0.0 && log_tail_upper(dim, mid) <= target {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Some(hi * (1.0 + TAIL_REL_MARGIN))
}

/// The probability bound at a point for this obstacle: `Prob(χ²_n ≥ k²)` with
/// `k = (‖x − m(t)‖ − reach)/√s(t)` (exact in 2-D, Chernoff's bound otherwise), 1 when
/// `k ≤ 0` — in floats, for displays (decisions use [`tail_kappa`] and the certifier).
pub fn tail_bound_f64(d: &GaussianDisk, x: &[f64], t: f64) -> f64 {
    let m = d.centre(t);
    let dist = x.iter().zip(&m).map(|(&xi, mi)| (xi - mi.mid()).powi(2)).sum::<f64>().sqrt();
    let s = d.sigma_p.hypot(d.sigma_v * (t - d.t_ref.mid()));
    let gap = dist - d.reach;
    if gap <= 0.0 {
        return 1.0;
    }
    if s == 0.0 {
        return 0.0;
    }
    log_tail_upper(d.dim(), gap / s).exp()
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_traits::FromPrimitive;
    use proptest::prelude::*;
    use statrs::distribution::{ChiSquared, ContinuousCDF};

    fn q(x: f64) -> BigRational {
        BigRational::from_f64(x).unwrap()
    }

    fn pts(v: &[f64]) -> Vec<Interval> {
        v.iter().map(|&x| Interval::point(x)).collect()
    }

    /// The threshold against statrs's χ² survival function (no shared code): the tail at
    /// κ² is at most Δ, and not far below it (Chernoff's slack aside).
    #[test]
    fn kappa_bounds_the_chi_square_tail() {
        for dim in 1..=8usize {
            let chi = ChiSquared::new(dim as f64).unwrap();
            for delta in [0.5, 0.3, 0.1, 0.05, 0.01, 1e-3, 1e-6, 1e-12] {
                let k = tail_kappa(dim, &q(delta)).unwrap();
                let tail = chi.sf(k * k);
                assert!(tail <= delta, "dim {dim} Δ {delta}: κ {k} tail {tail}");
                if dim == 2 {
                    assert!(tail >= delta * (1.0 - 1e-9), "2-D is exact: {tail} vs {delta}");
                } else if dim == 1 || dim == 3 {
                    assert!(tail >= delta / 2.0, "dim {dim} Δ {delta}: Mills bound too loose ({tail})");
                } else {
                    assert!(tail >= delta / 100.0, "dim {dim} Δ {delta}: Chernoff too loose ({tail})");
                }
            }
        }
        assert_eq!(tail_kappa(2, &q(0.0)), None);
        assert_eq!(tail_kappa(0, &q(0.1)), None);
        // a Δ that is not a float: κ for the float below it (larger)
        let third = BigRational::new(1.into(), 3.into());
        assert!(tail_kappa(2, &third).unwrap() >= (2.0f64 * 3f64.ln()).sqrt());
    }

    proptest! {
        /// sd_upper ≥ √(σ_p² + σ_v²·τ²) exactly (in rationals: its square is ≥ s), at
        /// every scale, underflow and overflow included.
        #[test]
        fn sd_upper_bounds_the_standard_deviation(
            sp_m in 0.0f64..1.0, sp_e in -330i32..300, sv_m in 0.0f64..1.0, sv_e in -330i32..300,
            tau_m in -1.0f64..1.0, tau_e in -330i32..300,
        ) {
            let sp = sp_m * 2f64.powi(sp_e);
            let sv = sv_m * 2f64.powi(sv_e);
            let tau = tau_m * 2f64.powi(tau_e);
            let d = GaussianDisk { position: pts(&[0.0, 0.0]), velocity: pts(&[0.0, 0.0]), t_ref: Interval::point(0.0), reach: 0.0, sigma_p: sp, sigma_v: sv };
            let u = d.sd_upper(tau);
            prop_assume!(u.is_finite());
            let s = q(sp) * q(sp) + q(sv) * q(sv) * q(tau) * q(tau);
            prop_assert!(q(u) * q(u) >= s, "σp {sp} σv {sv} τ {tau}: {u}");
        }

        /// The slab box contains the nominal centre ± (reach + κ·√s) at sampled times.
        #[test]
        fn slab_box_contains_the_risky_disk(
            px in -1e3f64..1e3, vx in -10.0f64..10.0, ta in -5.0f64..5.0, w in 0.0f64..3.0, u in 0.0f64..1.0,
            sp in 0.0f64..0.5, sv in 0.0f64..0.5, reach in 0.0f64..2.0,
        ) {
            let d = GaussianDisk { position: pts(&[px, -px]), velocity: pts(&[vx, 0.5 * vx]), t_ref: Interval::point(0.3), reach, sigma_p: sp, sigma_v: sv };
            let k = tail_kappa(2, &q(0.01)).unwrap();
            let b = d.slab_box(ta, ta + w, k);
            let t = ta + u * w;
            let r = reach + k * (sp * sp + sv * sv * (t - 0.3) * (t - 0.3)).sqrt();
            for (i, c) in [px + vx * (t - 0.3), -px + 0.5 * vx * (t - 0.3)].into_iter().enumerate() {
                prop_assert!(b[i].0 <= c - r * (1.0 - 1e-12) && c + r * (1.0 - 1e-12) <= b[i].1);
            }
        }
    }

    /// A Monte Carlo check of the guarantee itself (module docs): points just outside
    /// `reach + κ·√s` of a pedestrian are touched with frequency ≤ Δ.
    #[test]
    fn monte_carlo_contact_at_the_threshold_is_at_most_delta() {
        use rand::{Rng, SeedableRng};
        use rand_distr::{Distribution, Normal};
        let d = GaussianDisk {
            position: pts(&[1.0, -2.0]),
            velocity: pts(&[0.8, 0.1]),
            t_ref: Interval::point(0.0),
            reach: 0.35,
            sigma_p: 0.05,
            sigma_v: 0.1,
        };
        let delta = 0.05;
        let k = tail_kappa(2, &q(delta)).unwrap();
        let t = 2.0;
        let s = (0.05f64.powi(2) + (0.1f64 * t).powi(2)).sqrt();
        let m = [1.0 + 0.8 * t, -2.0 + 0.1 * t];
        let x = [m[0] + 0.35 + k * s, m[1]];
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let (np, nv) = (Normal::new(0.0, 0.05).unwrap(), Normal::new(0.0, 0.1).unwrap());
        let n = 200_000;
        let mut hits = 0;
        for _ in 0..n {
            let r = rng.random_range(0.25..0.35);
            let c: Vec<f64> = (0..2).map(|i| m[i] + np.sample(&mut rng) + nv.sample(&mut rng) * t).collect();
            if ((x[0] - c[0]).powi(2) + (x[1] - c[1]).powi(2)).sqrt() <= r {
                hits += 1;
            }
        }
        let est = hits as f64 / n as f64;
        assert!(est <= delta, "{est}");
        assert!(tail_bound_f64(&d, &x, t) <= delta * (1.0 + 1e-9));
    }
}
