//! A Markov–Lukács certificate of eq. (15) **constructed without an interior-point
//! solve** (docs/design.md §5.11), from Bernstein coefficients.
//!
//! For `p̃` of degree `n` with Bernstein coefficients `b_k` of degree `N ≥ n` on
//! [0, 1] (degree elevation, `N` even, `N = 2m`), and any `γ`,
//!
//! ```text
//! p̃(τ) − γ = Σ_k C(N,k)(b_k − γ) τ^k (1−τ)^(N−k)            (Σ_k C(N,k) τ^k (1−τ)^(N−k) = 1)
//!          = Σ_j w_2j (τ^j (1−τ)^(m−j))²  +  τ(1−τ) Σ_j w_(2j+1) (τ^j (1−τ)^(m−1−j))²
//!          = v_mᵀ Q0 v_m + τ(1−τ) v_(m−1)ᵀ Q1 v_(m−1),
//! ```
//!
//! with `w_k = C(N,k)(b_k − γ)`, `Q0 = Σ_j w_2j β_j β_jᵀ` and `Q1 = Σ_j w_(2j+1) β'_j β'_jᵀ`,
//! where `β_j` holds the monomial coefficients of `τ^j (1−τ)^(m−j)`. With every
//! `b_k > γ > 0` the weights are positive and the `β_j` (a Bernstein basis) independent,
//! so `Q0, Q1 ≻ 0`: the form of eq. (15), `σ0 + τ(1−τ)σ1` with `σ0, σ1` SOS. Bernstein
//! coefficients of a polynomial positive on [0, 1] become positive under enough degree
//! elevation (they converge to the values of `p̃` at `k/N`), so the construction
//! succeeds for every strictly positive `p̃` at some `N`; [`MAX_EXTRA_DEGREE`] bounds
//! the search, after which the caller falls back to the interior-point solve.
//!
//! Nothing here is trusted: the floating-point `Q0, Q1, γ` go through the same
//! rigorous re-check ([`super::recheck`]) as a solver's certificate. `γ` is half the
//! smallest Bernstein coefficient, leaving the other half as room for the rounding of
//! the construction.

use super::Certificate;
use riskplan_math::sdp::SdpStatus;

/// Most degrees the Bernstein coefficients are elevated by before the construction
/// gives up (the interior-point solve then takes over). Each elevation moves the
/// coefficients towards the polynomial's values; 16 extra degrees settle the margins of
/// the planners' pieces (a minimum about a tenth of the polynomial's scale) and keep the
/// binomials of the monomial expansion, whose rounding the re-check charges, below
/// `C(24, 12)·C(12, 6)² ≈ 2.3e12` relative to the unit scale.
pub const MAX_EXTRA_DEGREE: usize = 16;

/// The constructed certificate for the normalised coefficients `a` (monomial basis,
/// `|p̃| ≲ 1` on [0, 1]) when some elevation within [`MAX_EXTRA_DEGREE`] makes every
/// Bernstein coefficient exceed `2·min_gamma`; `None` otherwise (including non-finite
/// input). `scale` is recorded in the certificate as given.
pub fn bernstein_certificate(a: &[f64], scale: f64, min_gamma: f64) -> Option<Certificate> {
    if a.len() < 2 || a.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let n = a.len() - 1;
    let mut b = bernstein_coefficients(a);
    let mut deg = n;
    let max_deg = n + MAX_EXTRA_DEGREE;
    loop {
        let min_b = b.iter().copied().fold(f64::INFINITY, f64::min);
        if deg % 2 == 0 && min_b.is_finite() && min_b > 2.0 * min_gamma {
            return Some(assemble(&b, 0.5 * min_b, scale));
        }
        if deg >= max_deg {
            return None;
        }
        b = elevate(&b);
        deg += 1;
    }
}

/// The certificate of a quadratic `p̃ = a0 + a1·τ + a2·τ²` (normalised, as for
/// [`bernstein_certificate`]) in closed form: with `γ` half its minimum on [0, 1] and
/// any `λ ≥ 0`,
///
/// ```text
/// p̃(τ) − γ = [1 τ] [[a0 − γ, (a1 − λ)/2], [(a1 − λ)/2, a2 + λ]] [1 τ]ᵀ + τ(1−τ)·λ,
/// ```
///
/// and `λ = a1 + 2(a0 − γ)` (kept ≥ 0) maximises the determinant of `Q0` (it is
/// concave in `λ`), so `Q0 ⪰ 0` whenever any `λ ≥ 0` makes it so — Lukács' theorem
/// says one does for a quadratic positive on [0, 1]. The Bernstein construction needs
/// many elevations when the minimum is small against the scale (a path that grazes the
/// contour), and the interior-point solve costs a hundred times more. `None` when the
/// float minimum is not above `2·min_gamma`; the re-check decides as for every
/// certificate.
pub fn quadratic_certificate(a: &[f64], scale: f64, min_gamma: f64) -> Option<Certificate> {
    let [a0, a1, a2] = *a else { return None };
    if a.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let value = |t: f64| a0 + t * (a1 + t * a2);
    let mut min = value(0.0).min(value(1.0));
    if a2 > 0.0 {
        let vertex = -a1 / (2.0 * a2);
        if (0.0..=1.0).contains(&vertex) {
            min = min.min(value(vertex));
        }
    }
    // (a NaN minimum or threshold fails too)
    if min.partial_cmp(&(2.0 * min_gamma)) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    let gamma = 0.5 * min;
    let lambda = (a1 + 2.0 * (a0 - gamma)).max(0.0);
    let off = 0.5 * (a1 - lambda);
    let q0 = vec![vec![a0 - gamma, off], vec![off, a2 + lambda]];
    Some(Certificate {
        scale,
        gamma,
        q0,
        q1: vec![vec![lambda]],
        solver_status: SdpStatus::Unsolved,
        iterations: 0,
        constructed: true,
    })
}

/// Bernstein coefficients on [0, 1] of the degree-`n` polynomial with monomial
/// coefficients `a`: `b_k = Σ_(i≤k) C(k,i)/C(n,i)·a_i` (floating point; the re-check
/// decides; also the scale of [`super::bernstein_scale`]). `a` must not be empty.
pub(super) fn bernstein_coefficients(a: &[f64]) -> Vec<f64> {
    let n = a.len() - 1;
    (0..=n)
        .map(|k| {
            let mut ratio = 1.0; // C(k,i)/C(n,i)
            let mut s = 0.0;
            for (i, &ai) in a.iter().enumerate().take(k + 1) {
                s += ratio * ai;
                ratio *= (k - i) as f64 / (n - i) as f64;
            }
            s
        })
        .collect()
}

/// One degree elevation: `b'_k = (k/(N+1))·b_(k−1) + (1 − k/(N+1))·b_k`, `k = 0..N+1`.
fn elevate(b: &[f64]) -> Vec<f64> {
    let n1 = b.len() as f64; // N + 1
    (0..=b.len())
        .map(|k| {
            let t = k as f64 / n1;
            let lo = if k > 0 { t * b[k - 1] } else { 0.0 };
            let hi = if k < b.len() { (1.0 - t) * b[k] } else { 0.0 };
            lo + hi
        })
        .collect()
}

/// `Q0`, `Q1` from Bernstein coefficients `b` of even degree `N = 2m` and margin `γ`.
fn assemble(b: &[f64], gamma: f64, scale: f64) -> Certificate {
    let big_n = b.len() - 1;
    let m = big_n / 2;
    let mut q0 = vec![vec![0.0; m + 1]; m + 1];
    let mut q1 = vec![vec![0.0; m]; m];
    for (k, &bk) in b.iter().enumerate() {
        let w = binomial(big_n, k) * (bk - gamma);
        if k % 2 == 0 {
            add_outer(&mut q0, &basis(m, k / 2), w);
        } else {
            add_outer(&mut q1, &basis(m - 1, k / 2), w);
        }
    }
    Certificate { scale, gamma, q0, q1, solver_status: SdpStatus::Unsolved, iterations: 0, constructed: true }
}

/// Monomial coefficients (`1, τ, …, τ^d`) of `τ^j (1−τ)^(d−j)`:
/// `[τ^i] = (−1)^(i−j) C(d−j, i−j)` for `i ≥ j`.
fn basis(d: usize, j: usize) -> Vec<f64> {
    (0..=d)
        .map(|i| {
            if i < j {
                0.0
            } else {
                let c = binomial(d - j, i - j);
                if (i - j) % 2 == 0 {
                    c
                } else {
                    -c
                }
            }
        })
        .collect()
}

/// `q += w·v vᵀ`, written to both triangles from one product so `q` stays exactly
/// symmetric (the re-check refuses a matrix that is not).
fn add_outer(q: &mut [Vec<f64>], v: &[f64], w: f64) {
    for i in 0..v.len() {
        for j in i..v.len() {
            let x = q[i][j] + w * v[i] * v[j];
            q[i][j] = x;
            q[j][i] = x;
        }
    }
}

/// `C(n, k)` as a float (exact for the sizes used here: `n ≤ 56`).
fn binomial(n: usize, k: usize) -> f64 {
    let k = k.min(n - k);
    let mut c = 1.0;
    for i in 0..k {
        c = c * (n - i) as f64 / (i + 1) as f64;
    }
    c.round()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn eval(a: &[f64], t: f64) -> f64 {
        a.iter().rev().fold(0.0, |acc, &c| acc * t + c)
    }

    fn quad_form(q: &[Vec<f64>], t: f64) -> f64 {
        let v: Vec<f64> = (0..q.len()).map(|i| t.powi(i as i32)).collect();
        let mut s = 0.0;
        for i in 0..q.len() {
            for j in 0..q.len() {
                s += v[i] * q[i][j] * v[j];
            }
        }
        s
    }

    /// The identity `p − γ = σ0 + τ(1−τ)σ1` holds pointwise (floating point).
    #[test]
    fn identity_holds_at_many_points() {
        // (2τ − 1)² + 0.1: Bernstein coefficients of degree 2 are (1.1, −0.9, 1.1)
        let a = [1.1, -4.0, 4.0];
        let c = bernstein_certificate(&a, 1.0, 1e-7).expect("positive, needs elevation");
        assert!(c.q0.len() > 2, "elevated: side {}", c.q0.len());
        for i in 0..=100 {
            let t = i as f64 / 100.0;
            let rhs = c.gamma + quad_form(&c.q0, t) + t * (1.0 - t) * quad_form(&c.q1, t);
            assert!((eval(&a, t) - rhs).abs() < 1e-9, "τ = {t}: {} vs {rhs}", eval(&a, t));
        }
    }

    /// A polynomial with a root in [0, 1] never gets a certificate.
    #[test]
    fn no_certificate_for_a_polynomial_with_a_root() {
        assert!(bernstein_certificate(&[0.25, -1.0, 1.0], 1.0, 1e-7).is_none()); // (τ − ½)²
        assert!(bernstein_certificate(&[-0.01, 0.0, 1.0], 1.0, 1e-7).is_none());
        assert!(bernstein_certificate(&[f64::NAN, 0.0, 1.0], 1.0, 1e-7).is_none());
    }

    /// The closed form of a quadratic: the identity holds, `Q0 ⪰ 0`, `λ ≥ 0`, also for
    /// quadratics whose minimum is small against their scale (no elevation would do).
    #[test]
    fn quadratic_certificate_identity_and_psd() {
        for a in [
            [1.0, -3.3732634041575436, 2.9324526023890582],
            [1.1, 0.0, -1.0],
            [0.4268, -2.1494, 2.7226],
            [0.02, 0.3, 0.5],
        ] {
            let c = quadratic_certificate(&a, 1.0, 1e-9).expect("positive on [0, 1]");
            let (q, l) = (&c.q0, c.q1[0][0]);
            assert!(l >= 0.0 && q[0][0] > 0.0 && q[1][1] > 0.0 && q[0][0] * q[1][1] - q[0][1] * q[1][0] > 0.0, "{c:?}");
            for i in 0..=100 {
                let t = i as f64 / 100.0;
                let rhs = c.gamma + quad_form(&c.q0, t) + t * (1.0 - t) * quad_form(&c.q1, t);
                assert!((eval(&a, t) - rhs).abs() < 1e-12, "τ = {t}");
            }
        }
        // a root in [0, 1], or a negative end: none
        assert!(quadratic_certificate(&[0.25, -1.0, 1.0], 1.0, 1e-9).is_none());
        assert!(quadratic_certificate(&[1.0, 0.0, -1.0], 1.0, 1e-9).is_none());
        assert!(quadratic_certificate(&[1.0, 0.0], 1.0, 1e-9).is_none());
    }

    #[test]
    fn binomials_and_elevation() {
        assert_eq!(binomial(24, 12), 2_704_156.0);
        // elevation keeps the polynomial: 1 − τ in degree 1 → (1, ½, 0) in degree 2
        assert_eq!(elevate(&[1.0, 0.0]), vec![1.0, 0.5, 0.0]);
        assert_eq!(bernstein_coefficients(&[1.0, -4.0, 4.0]), vec![1.0, -1.0, 1.0]);
    }
}
