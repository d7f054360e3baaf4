//! Speed of the Bernstein positivity checker (docs/design.md §5.3) on realistic
//! constraints: the Cantelli constraint `g1 = E[P]² − 0.9·E[P²]` (Δ = 0.1, eq. (10))
//! and the mean constraint `g2 = −E[P]` of an uncertain disk, restricted to straight
//! segments — the univariate polynomials eq. (15) asks about.
//!
//! Obstacles: `w² − x1² − x2²` (degree 2, so `deg g2 = 2`, `deg g1 = 4`) and
//! `w⁴ − (x1² + x2²)²` (the same disk as a quartic, `deg g1 = 8`), `w ~ U[0.3, 0.4]`
//! (Illustrative Example 1). Positive cases: the segment `(−1, 0.9) → (1, 0.9)`, which
//! passes at distance 0.5 from the largest disk (radius 0.4). Negative cases: the
//! straight line `(−1, −1) → (1, 1)` of Illustrative Example 3, through the obstacle.
//!
//! Run: `cargo bench --no-default-features --bench certify_exact -- --warm-up-time 1 --measurement-time 3`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use num_rational::BigRational;
use riskplan_certify::{check, check_exact, check_interval, positivity::sturm, Verdict, DEFAULT_MAX_DEPTH};
use riskplan_math::contour::{Layout, RiskContour};
use riskplan_math::moments::Distribution;
use riskplan_math::poly::{parse, parse_decimal, Interval, UPoly, VarTable};
use std::hint::black_box;

fn q(text: &str) -> BigRational {
    parse_decimal(text).expect("bench literal")
}

/// `(g1, g2)` of obstacle `text` at Δ = 0.1, restricted to the segment `a → b`.
fn constraints_on_segment(text: &str, a: [&str; 2], b: [&str; 2]) -> (UPoly<BigRational>, UPoly<BigRational>) {
    let vars = VarTable::new(["x1", "x2", "t", "w"].map(String::from));
    let p = parse(text, &mut |n: &str| vars.get(n).ok_or_else(|| n.to_string())).expect("obstacle");
    let w = Distribution::Uniform { low: q("0.3"), high: q("0.4") };
    let moments = w.raw_moments(8).expect("uniform moments");
    let contour = RiskContour::new(Layout { dim: 2 }, &p, &|_, k| moments.get(k as usize).cloned(), &|v| vars.name(v))
        .expect("contour");
    let cons = contour.constraints(&q("0.1"));
    // x(τ) = a + (b − a)τ; t is unused by a static obstacle
    let line = |i: usize| UPoly::linear(q(a[i]), q(b[i]) - q(a[i]));
    let subs = [line(0), line(1), UPoly::linear(q("0"), q("1"))];
    (cons.cantelli.compose_univariate(&subs), cons.mean.compose_univariate(&subs))
}

struct Case {
    name: &'static str,
    exact: UPoly<BigRational>,
    interval: UPoly<Interval>,
    safe: bool,
}

fn cases() -> Vec<Case> {
    let clear = (["-1", "0.9"], ["1", "0.9"]);
    let through = (["-1", "-1"], ["1", "1"]);
    let disk = "w^2 - x1^2 - x2^2";
    let quartic = "w^4 - (x1^2 + x2^2)^2";
    let (g1_clear, g2_clear) = constraints_on_segment(disk, clear.0, clear.1);
    let (g1_through, g2_through) = constraints_on_segment(disk, through.0, through.1);
    let (g1q_clear, _) = constraints_on_segment(quartic, clear.0, clear.1);
    let (g1q_through, _) = constraints_on_segment(quartic, through.0, through.1);
    let list = [
        ("deg2_positive", g2_clear, true),
        ("deg4_positive", g1_clear, true),
        ("deg8_positive", g1q_clear, true),
        ("deg2_negative", g2_through, false),
        ("deg4_negative", g1_through, false),
        ("deg8_negative", g1q_through, false),
    ];
    list.into_iter()
        .map(|(name, exact, safe)| {
            let interval = exact.map(Interval::enclose_rational);
            Case { name, exact, interval, safe }
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let cases = cases();
    for case in &cases {
        // the bench measures the intended path: decided by the interval checker alone
        let v = check_interval(&case.interval, DEFAULT_MAX_DEPTH);
        assert_eq!(v.is_safe(), case.safe, "{}: {v:?}", case.name);
        assert!(!matches!(v, Verdict::Undecided(_)), "{}: {v:?}", case.name);
        assert_eq!(sturm::decide(&case.exact).is_safe(), case.safe, "{}", case.name);
        println!("{}: degree {}, interval verdict {v:?}", case.name, case.exact.degree());
    }
    let mut g = c.benchmark_group("interval");
    for case in &cases {
        g.bench_with_input(BenchmarkId::from_parameter(case.name), &case.interval, |b, p| {
            b.iter(|| check_interval(black_box(p), DEFAULT_MAX_DEPTH))
        });
    }
    g.finish();
    // for comparison: the recommended entry point (same work when decided), and the
    // exact paths that `check` falls back to and that tests use as the oracle
    let deg4 = cases.iter().filter(|c| c.name.starts_with("deg4"));
    let mut g = c.benchmark_group("reference");
    for case in deg4 {
        g.bench_with_input(BenchmarkId::new("check", case.name), case, |b, c| {
            b.iter(|| check(black_box(&c.interval), || c.exact.clone()))
        });
        g.bench_with_input(BenchmarkId::new("exact", case.name), &case.exact, |b, p| {
            b.iter(|| check_exact(black_box(p), DEFAULT_MAX_DEPTH))
        });
        g.bench_with_input(BenchmarkId::new("sturm", case.name), &case.exact, |b, p| {
            b.iter(|| sturm::decide(black_box(p)))
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
