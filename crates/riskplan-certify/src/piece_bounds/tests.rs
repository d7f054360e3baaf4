use super::*;
use riskplan_math::contour::Layout;
use riskplan_math::moments::Distribution;
use riskplan_math::poly::{parse, parse_decimal, VarTable};

fn q(s: &str) -> BigRational {
    parse_decimal(s).unwrap()
}

/// A contour in 2-D from `poly` over parameters named in `params` with distributions.
pub(crate) fn contour(poly: &str, params: &[(&str, Distribution)]) -> RiskContour {
    let mut names: Vec<String> = ["x1", "x2", "t"].map(String::from).to_vec();
    names.extend(params.iter().map(|(n, _)| n.to_string()));
    let vars = VarTable::new(names);
    let p = parse(poly, &mut |n: &str| vars.get(n).ok_or_else(|| n.to_string())).unwrap();
    let moments: Vec<Vec<BigRational>> = params.iter().map(|(_, d)| d.raw_moments(64).unwrap()).collect();
    let lookup = |v: Var, k: u32| moments.get(v as usize - 3).and_then(|m| m.get(k as usize)).cloned();
    let support: Vec<(Var, BigRational, BigRational)> = params
        .iter()
        .enumerate()
        .filter_map(|(i, (_, d))| d.support().map(|(lo, hi)| (3 + i as Var, lo, hi)))
        .collect();
    RiskContour::new(Layout { dim: 2 }, &p, &lookup, &|v| vars.name(v)).unwrap().with_support(&support)
}

pub(crate) fn uniform_disk() -> RiskContour {
    contour("w^2 - x1^2 - x2^2", &[("w", Distribution::Uniform { low: q("0.3"), high: q("0.4") })])
}

pub(crate) fn gaussian_disk() -> RiskContour {
    let n = || Distribution::Normal { mean: q("0"), std: q("0.05") };
    contour("0.09 - (x1 - a)^2 - (x2 - b)^2", &[("a", n()), ("b", n())])
}

fn point(c: &RiskContour, x: f64, y: f64, delta: &str) -> Result<Vec<BoundPart>, CoverFailure> {
    let xt = [x, y, 0.0].map(|v| BigRational::from_float(v).unwrap());
    PieceBounds::for_point(c, &xt, Level::new(&q(delta))).cover(None)
}

/// Illustrative-1 at Δ = 10⁻³: beyond the largest radius 0.4 the risk is 0 and the support
/// proof says so; inside it, where the true risk is positive, nothing proves it.
#[test]
fn support_proves_zero_risk_outside_the_largest_disk() {
    let c = uniform_disk();
    let r = point(&c, 0.41, 0.0, "0.001").unwrap();
    assert_eq!(r[0].bound, BoundKind::Support);
    assert!(point(&c, 0.0, 0.399, "0.001").is_err());
    // at 0.39 the true risk is 0.1: not provable at Δ = 0.05
    assert!(point(&c, 0.39, 0.0, "0.05").is_err());
}

/// A Gaussian-centre disk (radius 0.3, σ = 0.05) at Δ = 10⁻³: Cantelli needs a distance of
/// about 3.2, the moment bounds prove 0.65.
#[test]
fn moment_bounds_prove_what_cantelli_cannot() {
    let c = gaussian_disk();
    let r = point(&c, 0.65, 0.0, "0.001").unwrap();
    assert!(matches!(r[0].bound, BoundKind::Moment(_)), "{r:?}");
    // Cantelli alone fails there
    let xt = [0.65, 0.0, 0.0].map(|v| BigRational::from_float(v).unwrap());
    let pr = c.risk_at(&xt);
    assert!(rational_to_f64(&pr.bound) > 0.001);
    // the true risk at 0.35 is far above 10⁻³: nothing may prove it
    assert!(point(&c, 0.35, 0.0, "0.001").is_err());
}

/// A straight piece passing the uniform disk at distance 0.42 is covered (support where
/// Cantelli fails); one through the disk is refused with E[P] ≥ 0.
#[test]
fn pieces_are_covered_by_sub_intervals() {
    let c = uniform_disk();
    let coeffs = vec![vec![-1.0, 2.0], vec![0.42, 0.0]];
    let piece = PieceRef { t0: 0.0, t1: 1.0, coeffs: &coeffs };
    let parts = PieceBounds::for_piece(&c, piece, Level::new(&q("0.001"))).cover(None).unwrap();
    assert!(parts.iter().any(|p| p.bound == BoundKind::Support), "{parts:?}");
    assert_eq!(parts.first().unwrap().tau0, 0.0);
    assert_eq!(parts.last().unwrap().tau1, 1.0);
    for w in parts.windows(2) {
        assert_eq!(w[0].tau1, w[1].tau0);
    }
    let through = vec![vec![-1.0, 2.0], vec![0.0, 0.0]];
    let piece = PieceRef { t0: 0.0, t1: 1.0, coeffs: &through };
    let f = PieceBounds::for_piece(&c, piece, Level::new(&q("0.001"))).cover(Some(0.5)).unwrap_err();
    assert!(matches!(f, CoverFailure::MeanNotNegative { .. }), "{f:?}");
}

/// The Gaussian disk passed at 0.7: covered by moment bounds (and Cantelli far out).
#[test]
fn gaussian_piece_is_covered_by_moment_bounds() {
    let c = gaussian_disk();
    let coeffs = vec![vec![-2.0, 4.0], vec![0.7, 0.0]];
    let piece = PieceRef { t0: 0.0, t1: 1.0, coeffs: &coeffs };
    let parts = PieceBounds::for_piece(&c, piece, Level::new(&q("0.001"))).cover(None).unwrap();
    assert!(parts.iter().any(|p| matches!(p.bound, BoundKind::Moment(_))), "{parts:?}");
    let near = vec![vec![-2.0, 4.0], vec![0.4, 0.0]];
    let piece = PieceRef { t0: 0.0, t1: 1.0, coeffs: &near };
    assert!(PieceBounds::for_piece(&c, piece, Level::new(&q("0.001"))).cover(None).is_err());
}

proptest::proptest! {
    /// The in-place reparametrisation of the sub-interval hulls encloses the exact
    /// coefficients of p(a + w·τ) (rational composition by the general polynomial code).
    #[test]
    fn sub_interval_reparametrisation_encloses_the_exact_one(
        coeffs in proptest::collection::vec(-1e3f64..1e3, 1..18), k in 0u32..64, depth in 0u32..7,
    ) {
        let w = 0.5f64.powi(depth as i32);
        let a = f64::from(k % (1 << depth).max(1)) * w;
        let mut c: Vec<Interval> = coeffs.iter().map(|&v| Interval::point(v)).collect();
        reparam_in_place(&mut c, a, w);
        let qf = |v: f64| BigRational::from_float(v).unwrap();
        let exact = UPoly::new(coeffs.iter().map(|&v| qf(v)).collect()).compose_affine(&qf(a), &qf(w));
        for (i, iv) in c.iter().enumerate() {
            let e = exact.coeff(i);
            proptest::prop_assert!(qf(iv.lo) <= e && e <= qf(iv.hi), "coefficient {i}: {e} not in {iv:?}");
        }
    }
}
