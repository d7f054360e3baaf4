use super::*;
use proptest::prelude::*;

fn q(n: i64, d: i64) -> BigRational {
    BigRational::new(n.into(), d.into())
}

fn table() -> VarTable {
    VarTable::new(["x1", "x2", "t", "w"].map(String::from))
}

fn p(text: &str) -> QPoly {
    let t = table();
    parse(text, &mut |n: &str| t.get(n).ok_or_else(|| format!("unknown variable '{n}'"))).unwrap()
}

fn perr(text: &str) -> PolyError {
    let t = table();
    parse(text, &mut |n: &str| t.get(n).ok_or_else(|| format!("unknown variable '{n}'"))).unwrap_err()
}

#[test]
fn parses_scene_grammar() {
    let a = p("w^2 - x1^2 - x2^2");
    assert_eq!(a.len(), 3);
    assert_eq!(a.coeff(&Monomial::var_pow(3, 2)), q(1, 1));
    assert_eq!(p("37/300"), Poly::constant(q(37, 300)));
    assert_eq!(p("1e-3*x1"), Poly::var(0).scale(&q(1, 1000)));
    assert_eq!(p("-x1^2"), Poly::var(0).pow(2).neg());
    assert_eq!(p("0.3^2 - (x1 - (t + 0.4 + w))^2"), p("9/100 - (x1 - t - 2/5 - w)*(x1 - t - 2/5 - w)"));
    assert_eq!(p("2*x1/4"), Poly::var(0).scale(&q(1, 2)));
    assert_eq!(p("--x1"), Poly::var(0));
    assert_eq!(p(" ( x1 ) "), Poly::var(0));
}

#[test]
fn errors_point_at_the_column() {
    let e = perr("x1 + * x2");
    assert_eq!(e.to_string(), "column 6: expected a number, an identifier or '(', found '*'");
    match perr("x1 + y") {
        PolyError::UnknownVariable { col: 6, message } => assert!(message.contains("'y'")),
        other => panic!("{other:?}"),
    }
    assert!(matches!(perr("x1 / x2"), PolyError::BadDivisor { col: 4 }));
    assert!(matches!(perr("x1 / 0"), PolyError::BadDivisor { .. }));
    assert!(matches!(perr("x1^x2"), PolyError::Unexpected { col: 4, .. }));
    assert!(matches!(perr("x1^1.5"), PolyError::Unexpected { col: 4, .. }));
    assert!(matches!(perr("x1^99"), PolyError::ExponentTooLarge { col: 4, .. }));
    assert!(matches!(perr("(x1 + x2"), PolyError::Unexpected { col: 9, .. }));
    assert!(matches!(perr("x1 x2"), PolyError::Unexpected { col: 4, .. }));
    assert!(matches!(perr("x1 # 2"), PolyError::Unexpected { col: 4, .. }));
    assert!(matches!(perr(""), PolyError::Unexpected { col: 1, .. }));
    assert!(matches!(perr("1.2.3"), PolyError::BadNumber { col: 1, .. }));
    assert!(matches!(perr("x1^2^2"), PolyError::Unexpected { .. }));
}

#[test]
fn prints_like_the_paper() {
    let names = |v: Var| table().name(v);
    assert_eq!(p("37/300 - x1^2 - x2^2").to_text(&names), "37/300 - x1^2 - x2^2");
    assert_eq!(p("-x1*x2 + 2").to_text(&names), "2 - x1*x2");
    assert_eq!(QPoly::zero().to_text(&names), "0");
}

#[test]
fn divisions_count_against_the_work_budget() {
    // a 528-term power (within the budget) divided a hundred times by constants: each
    // division costs like a product, so the work budget refuses it
    let text = format!("(x1+w+1+w+1)^31{}", "/831/2".repeat(60));
    let t = table();
    let r = parse(&text, &mut |n: &str| t.get(n).ok_or_else(|| format!("unknown variable '{n}'")));
    assert!(matches!(r, Err(PolyError::TooLarge { what: "work", .. })), "{r:?}");
}

#[test]
fn exponents_above_the_parsers_limit_print_as_repeated_factors() {
    // found by fuzzing: (x1+...)^32 expanded holds w^64, which a single '^' may not write
    let names = |v: Var| table().name(v);
    let q = p("(x1^2)^20");
    let text = q.to_text(&names);
    assert_eq!(text, "x1^32*x1^8");
    assert_eq!(p(&text), q);
}

#[test]
fn expectation_is_linear_and_uses_moments() {
    // E[w^2 - x1^2] with E[w^2] = 37/300
    let e = p("w^2 - x1^2").expect(|v| v == 3, |_, k| Some(if k == 2 { q(37, 300) } else { q(0, 1) })).unwrap();
    assert_eq!(e, p("37/300 - x1^2"));
    let missing = p("w^3").expect(|v| v == 3, |_, k| if k < 3 { Some(q(1, 1)) } else { None });
    assert_eq!(missing, Err((3, 3)));
}

#[test]
fn compose_univariate_restricts_to_a_segment() {
    // g = 1 - x1^2 - x2^2 on x = (-1,-1) + (2,2)τ
    let g = p("1 - x1^2 - x2^2");
    let lin = UPoly::linear(q(-1, 1), q(2, 1));
    let u = g.compose_univariate(&[lin.clone(), lin, UPoly::zero(), UPoly::zero()]);
    // 1 - 2(2τ-1)^2 = -1 + 8τ - 8τ^2
    assert_eq!(u.coeffs(), &[q(-1, 1), q(8, 1), q(-8, 1)]);
}

fn arb_poly() -> impl Strategy<Value = QPoly> {
    let term = (-50i64..50, 1i64..20, 0u32..4, 0u32..3, 0u32..3, 0u32..3);
    prop::collection::vec(term, 0..6).prop_map(|ts| {
        let mut acc = QPoly::zero();
        for (n, d, e0, e1, e2, e3) in ts {
            acc.add_term(Monomial::from_pairs([(0, e0), (1, e1), (2, e2), (3, e3)]), q(n, d));
        }
        acc
    })
}

proptest! {
    /// print → parse is the identity.
    #[test]
    fn print_parse_roundtrip(a in arb_poly()) {
        let names = |v: Var| table().name(v);
        let text = a.to_text(&names);
        prop_assert_eq!(p(&text), a, "text was {}", text);
    }

    /// Composition then evaluation equals evaluation then composition.
    #[test]
    fn subst_commutes_with_eval(a in arb_poly(), b in arb_poly(), xs in prop::collection::vec(-5i64..5, 4)) {
        let vals: Vec<BigRational> = xs.iter().map(|&x| q(x, 3)).collect();
        let composed = a.subst(&|v| if v == 1 { Some(b.clone()) } else { None });
        let mut vals2 = vals.clone();
        vals2[1] = b.eval(&vals);
        prop_assert_eq!(composed.eval(&vals), a.eval(&vals2));
    }

    /// The exact evaluation over one common denominator is the term-by-term one, at points
    /// with zero, negative and dyadic coordinates (those of floats).
    #[test]
    fn eval_exact_is_eval(a in arb_poly(), xs in prop::collection::vec((-40i64..40, 0u32..3, 0u32..70), 4)) {
        let vals: Vec<BigRational> = xs
            .iter()
            .map(|&(n, kind, k)| match kind {
                0 => q(n, 7),
                1 => q(n, 1) / BigRational::from_integer(num_bigint::BigInt::from(2).pow(k)),
                _ => BigRational::from_float(n as f64 * 1.000_000_000_1f64.powi(k as i32)).unwrap(),
            })
            .collect();
        prop_assert_eq!(a.eval_exact(&vals), a.eval(&vals));
    }

    /// Ring laws on random polynomials.
    #[test]
    fn ring_laws(a in arb_poly(), b in arb_poly(), c in arb_poly()) {
        prop_assert_eq!(a.mul(&b.add(&c)), a.mul(&b).add(&a.mul(&c)));
        prop_assert_eq!(a.mul(&b), b.mul(&a));
        prop_assert!(a.sub(&a).is_zero());
        prop_assert_eq!(a.pow(2), a.mul(&a));
    }

    /// Univariate composition agrees with evaluation.
    #[test]
    fn compose_univariate_agrees(a in arb_poly(), c0 in -4i64..4, c1 in -4i64..4, tau in -3i64..3) {
        let subs: Vec<UPoly<BigRational>> = (0..4).map(|i| UPoly::linear(q(c0 + i, 2), q(c1 - i, 3))).collect();
        let u = a.compose_univariate(&subs);
        let tq = q(tau, 5);
        let vals: Vec<BigRational> = subs.iter().map(|s| s.eval(&tq)).collect();
        prop_assert_eq!(u.eval(&tq), a.eval(&vals));
    }
}

/// Hostile polynomial text gets a typed error, bounded in stack and work: deep
/// nesting, long sign chains, nested powers and wide expansions are refused before
/// they are built; oversized numbers are malformed.
#[test]
fn hostile_text_is_refused_within_limits() {
    let deep = format!("{}x1{}", "(".repeat(2000), ")".repeat(2000));
    assert!(matches!(perr(&deep), PolyError::TooDeep { .. }), "{:?}", perr(&deep));
    let signs = format!("{}x1", "-".repeat(10_000));
    assert!(matches!(perr(&signs), PolyError::TooDeep { .. }));
    // at the limit itself, nesting is fine
    let ok = format!("{}x1{}", "(".repeat(MAX_NESTING), ")".repeat(MAX_NESTING));
    assert_eq!(p(&ok), p("x1"));
    assert_eq!(p(&format!("{}x1", "-".repeat(MAX_NESTING))), p("x1"));
    // nested powers: degree 32 768 is refused before expansion
    let e = perr("(((x1+1)^32)^32)^32");
    assert!(matches!(e, PolyError::TooLarge { what: "degree", .. }), "{e:?}");
    let e = perr("x1^30*x2^30*t^30");
    assert!(matches!(e, PolyError::TooLarge { what: "degree", .. }), "{e:?}");
    // wide expansions: too many terms or too much work
    let e = perr("(x1+x2+t+w+1)^32");
    assert!(matches!(e, PolyError::TooLarge { what: "terms" | "work", .. }), "{e:?}");
    let e = perr(&vec!["(x1+x2+t+w+1)^4*(x1+x2+t+w+1)^4"; 60].join("+"));
    assert!(matches!(e, PolyError::TooLarge { what: "work", .. }), "{e:?}");
    // a shared budget runs out across texts
    let t = table();
    let mut budget = 10_000;
    let mut resolve = |n: &str| t.get(n).ok_or_else(|| n.to_string());
    assert!(parse_with_budget("(x1+x2+t+w+1)^4", &mut resolve, &mut budget).is_ok());
    assert!(budget < 10_000);
    let mut runs = 0;
    while parse_with_budget("(x1+x2+t+w+1)^4", &mut resolve, &mut budget).is_ok() {
        runs += 1;
        assert!(runs < 100, "the budget never ran out");
    }
    // numbers beyond the exact-size limits
    assert!(matches!(perr("1e4000*x1"), PolyError::BadNumber { .. }));
    assert!(matches!(perr(&format!("{}*x1", "9".repeat(MAX_DECIMAL_DIGITS + 1))), PolyError::BadNumber { .. }));
    assert_eq!(p("1e400*x1 - 1e400*x1"), Poly::zero());
    // what the paper writes is far inside every limit
    assert_eq!(p("(x1 + x2 + t + w + 1)^8").len(), 495);
}
