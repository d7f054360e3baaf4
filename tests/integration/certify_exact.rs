//! Differential test of the exact positivity checkers (docs/design.md §5.8): Bernstein
//! subdivision in interval and in exact arithmetic, and the Sturm oracle, on random
//! polynomials from `riskplan_testkit::testgen`, plus fixtures.
//!
//! Run with `--nocapture` to see the counts. `RISKPLAN_DIFF_CASES` overrides the number
//! of random cases (default 100 000).

use crate::common;
use num_rational::BigRational;
use num_traits::{One, Signed, Zero};
use riskplan_certify::{
    check, check_exact, check_interval, positivity::bernstein, positivity::sturm, Verdict, DEFAULT_MAX_DEPTH,
};
use riskplan_math::poly::{parse_decimal, Interval, UPoly};
use riskplan_testkit::testgen::{Generator, IntPoly, Truth};
use std::collections::BTreeMap;
use std::time::Instant;

/// Seeds of the two halves run on the two threads.
const SEEDS: [u64; 2] = [0x5eed_0001, 0x5eed_0002];

fn q(text: &str) -> BigRational {
    parse_decimal(text).expect("test literal")
}

fn exact_of(x: f64) -> BigRational {
    BigRational::from_float(x).expect("finite")
}

/// Margins are checked against `p` on this grid (and against Sturm's margin).
const GRID: usize = 16;

/// `p > 0` on [0, 1], decided by root counting only (independent of `decide`'s
/// isolation and witness search).
fn positive_by_root_count(p: &UPoly<BigRational>, fast: &IntPoly) -> bool {
    let (zero, one) = (BigRational::zero(), BigRational::one());
    !p.is_zero()
        && fast.at(&BigRational::zero()).is_positive()
        && fast.at(&BigRational::one()).is_positive()
        && (p.degree() == 0 || sturm::count_roots_in(p, &zero, &one) == 0)
}

#[derive(Default, Clone)]
struct Tally {
    counts: BTreeMap<(&'static str, &'static str), usize>,
    truth: BTreeMap<&'static str, usize>,
    time: BTreeMap<&'static str, std::time::Duration>,
}

impl Tally {
    fn add(&mut self, method: &'static str, v: &Verdict) {
        let kind = match v {
            Verdict::Safe { .. } => "safe",
            Verdict::Unsafe(_) => "unsafe",
            Verdict::Undecided(_) => "undecided",
        };
        *self.counts.entry((method, kind)).or_default() += 1;
    }
    fn merge(&mut self, o: Tally) {
        for (k, v) in o.counts {
            *self.counts.entry(k).or_default() += v;
        }
        for (k, v) in o.truth {
            *self.truth.entry(k).or_default() += v;
        }
        for (k, v) in o.time {
            *self.time.entry(k).or_default() += v;
        }
    }
    fn get(&self, method: &'static str, kind: &'static str) -> usize {
        self.counts.get(&(method, kind)).copied().unwrap_or(0)
    }
}

/// Every property of one case; panics with the recipe on a violation.
fn check_case(p: &UPoly<BigRational>, pi: &UPoly<Interval>, truth: Truth, recipe: &str, tally: &mut Tally) {
    let fast = IntPoly::from_upoly(p);
    let positive = positive_by_root_count(p, &fast);
    match truth {
        Truth::Positive => assert!(positive, "construction says positive, root count disagrees: {recipe}"),
        Truth::NotPositive => assert!(!positive, "construction says not positive, root count disagrees: {recipe}"),
        Truth::Unknown => {}
    }
    *tally.truth.entry(if positive { "positive" } else { "not positive" }).or_default() += 1;

    let mut timed = |name: &'static str, f: &dyn Fn() -> Verdict| {
        let t0 = Instant::now();
        let v = f();
        *tally.time.entry(name).or_default() += t0.elapsed();
        v
    };
    let vi = timed("interval", &|| check_interval(pi, DEFAULT_MAX_DEPTH));
    let ve = timed("exact", &|| check_exact(p, DEFAULT_MAX_DEPTH));
    let vs = timed("sturm", &|| sturm::decide(p));
    let vc = timed("check", &|| check(pi, || p.clone()));
    let all = [("interval", &vi), ("exact", &ve), ("sturm", &vs), ("check", &vc)];
    let mut grid: Option<Vec<BigRational>> = None;
    let sturm_margin = match &vs {
        Verdict::Safe { margin } => Some(*margin),
        _ => None,
    };
    for (name, v) in all {
        tally.add(name, v);
        match v {
            Verdict::Safe { margin } => {
                // THE invariant: nobody certifies a polynomial that is ≤ 0 somewhere
                assert!(positive, "{name} says Safe but p ≤ 0 somewhere on [0,1]: {recipe}");
                assert!(*margin > 0.0, "{name}: non-positive margin {margin}: {recipe}");
                let m = exact_of(*margin);
                let values = grid.get_or_insert_with(|| {
                    (0..=GRID).map(|k| fast.at(&BigRational::new(k.into(), GRID.into()))).collect()
                });
                for (k, v) in values.iter().enumerate() {
                    assert!(m <= *v, "{name}: margin {margin} above p({k}/{GRID}) = {v}: {recipe}");
                }
                // Sturm's margin is within MARGIN_REL_TOL of min p, so min p ≤ it/(1 − tol)
                if let Some(sm) = sturm_margin {
                    assert!(
                        *margin <= sm / (1.0 - sturm::MARGIN_REL_TOL) * (1.0 + 1e-15),
                        "{name}: margin {margin} above min p ≈ {sm}: {recipe}"
                    );
                }
            }
            Verdict::Unsafe(w) => {
                assert!((0.0..=1.0).contains(&w.tau), "{name}: witness τ = {} outside [0,1]: {recipe}", w.tau);
                let val = fast.at(&exact_of(w.tau));
                assert!(!val.is_positive(), "{name}: witness {w:?} has p(τ) = {val} > 0: {recipe}");
                assert!(w.value <= 0.0, "{name}: witness value {} > 0: {recipe}", w.value);
            }
            Verdict::Undecided(_) => {}
        }
    }
    // pairwise: never one Safe and another Unsafe (implied by the above, asserted directly)
    for (a, va) in all {
        for (b, vb) in all {
            assert!(!(va.is_safe() && vb.is_unsafe()), "{a} Safe vs {b} Unsafe: {recipe}");
        }
    }
    // completeness of the oracle: Sturm decides every positive case
    if positive {
        assert!(vs.is_safe(), "sturm failed to certify a positive polynomial: {vs:?} {recipe}");
    }
    // `check` is the interval verdict when decided, else the exact one
    let expected = if matches!(vi, Verdict::Undecided(_)) { &ve } else { &vi };
    assert_eq!(&vc, expected, "check does not compose as documented: {recipe}");
}

#[test]
fn differential_random_polynomials() {
    let total = common::size("DIFF_CASES", 5_000, 100_000);
    let start = Instant::now();
    let tally = std::thread::scope(|s| {
        let handles: Vec<_> = SEEDS
            .iter()
            .enumerate()
            .map(|(i, &seed)| {
                let n = total / SEEDS.len() + usize::from(i < total % SEEDS.len());
                s.spawn(move || {
                    let mut g = Generator::new(seed);
                    let mut tally = Tally::default();
                    for k in 0..n {
                        let c = g.case();
                        let recipe = format!("seed {seed:#x} case {k}: {}", c.recipe);
                        check_case(&c.exact, &c.interval, c.truth, &recipe, &mut tally);
                        *tally
                            .truth
                            .entry(match c.truth {
                                Truth::Positive => "construction: positive",
                                Truth::NotPositive => "construction: not positive",
                                Truth::Unknown => "construction: unknown",
                            })
                            .or_default() += 1;
                    }
                    tally
                })
            })
            .collect();
        let mut all = Tally::default();
        for h in handles {
            all.merge(h.join().expect("worker panicked (see message above)"));
        }
        all
    });
    println!("differential test: {total} random polynomials of degree 1..=10 in {:.1?}", start.elapsed());
    for (k, v) in &tally.truth {
        println!("  {k:<28} {v:>7}");
    }
    println!("  {:<10} {:>8} {:>8} {:>10} {:>14}", "method", "safe", "unsafe", "undecided", "mean time");
    for m in ["interval", "exact", "sturm", "check"] {
        let mean = tally.time.get(m).copied().unwrap_or_default() / total.max(1) as u32;
        println!(
            "  {:<10} {:>8} {:>8} {:>10} {:>14.1?}",
            m,
            tally.get(m, "safe"),
            tally.get(m, "unsafe"),
            tally.get(m, "undecided"),
            mean
        );
    }
    let decided = tally.get("check", "safe") + tally.get("check", "unsafe");
    assert!(decided * 10 >= total * 9, "check decided only {decided} of {total}");
}

fn both(p: &UPoly<BigRational>) -> (UPoly<BigRational>, UPoly<Interval>) {
    (p.clone(), p.map(Interval::enclose_rational))
}

/// `(τ − 0.3)² + c`.
fn tangent(c: BigRational) -> UPoly<BigRational> {
    let lin = UPoly::linear(-q("0.3"), BigRational::one());
    lin.mul(&lin).add(&UPoly::constant(c))
}

fn verdicts(p: &UPoly<BigRational>) -> [(&'static str, Verdict); 4] {
    let (pe, pi) = both(p);
    [
        ("interval", check_interval(&pi, DEFAULT_MAX_DEPTH)),
        ("exact", check_exact(&pe, DEFAULT_MAX_DEPTH)),
        ("sturm", sturm::decide(&pe)),
        ("check", check(&pi, || pe.clone())),
    ]
}

fn assert_refutes(p: &UPoly<BigRational>, name: &str, v: &Verdict) {
    let Verdict::Unsafe(w) = v else { panic!("{name}: expected Unsafe, got {v:?}") };
    assert!(!p.eval(&exact_of(w.tau)).is_positive(), "{name}: {w:?}");
}

#[test]
fn fixture_touch_is_never_safe() {
    let p = tangent(BigRational::zero());
    for (name, v) in verdicts(&p) {
        assert!(!v.is_safe(), "{name}: {v:?}");
        if v.is_unsafe() {
            assert_refutes(&p, name, &v);
        }
    }
}

#[test]
fn fixture_barely_positive_is_safe() {
    let p = tangent(q("1e-9"));
    for (name, v) in verdicts(&p) {
        let Verdict::Safe { margin } = v else { panic!("{name}: {v:?}") };
        assert!(margin > 0.0 && margin <= 1e-9, "{name}: {margin}");
    }
}

#[test]
fn fixture_barely_negative_is_unsafe() {
    let p = tangent(-q("1e-12"));
    for (name, v) in verdicts(&p) {
        assert_refutes(&p, name, &v);
    }
}

#[test]
fn fixture_zero_at_both_ends_is_unsafe() {
    // −τ(1 − τ) = −τ + τ²
    let p = UPoly::new(vec![BigRational::zero(), -BigRational::one(), BigRational::one()]);
    for (name, v) in verdicts(&p) {
        assert_refutes(&p, name, &v);
    }
}

#[test]
fn fixture_constants() {
    for (text, safe) in [("2.5", true), ("1e-300", true), ("-0.1", false), ("0", false)] {
        let p = UPoly::constant(q(text));
        for (name, v) in verdicts(&p) {
            if safe {
                let Verdict::Safe { margin } = v else { panic!("{name} on {text}: {v:?}") };
                assert!(exact_of(margin) <= q(text) && margin > 0.0);
            } else {
                assert_refutes(&p, name, &v);
            }
        }
    }
}

#[test]
fn bernstein_coefficients_bound_the_polynomial() {
    // §5.5 normalises by max |b_k|, which bounds |p| on [0, 1]
    let mut g = Generator::new(11);
    for _ in 0..200 {
        let c = g.case();
        let b = bernstein::bernstein_coefficients(&c.exact);
        let s = b.iter().map(|x| x.abs()).fold(BigRational::zero(), |m, x| if x > m { x } else { m });
        for k in 0..=20 {
            assert!(c.exact.eval(&BigRational::new(k.into(), 20.into())).abs() <= s);
        }
        assert_eq!(b.first(), Some(&c.exact.eval(&BigRational::zero())));
        assert_eq!(b.last(), Some(&c.exact.eval(&BigRational::one())));
    }
}
