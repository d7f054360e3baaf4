use super::*;
use crate::restrict::restrict_exact;
use num_traits::Signed;
use proptest::prelude::*;
use riskplan_math::contour::Layout;
use riskplan_math::poly::VarTable;

fn contour(text: &str, dim: usize) -> RiskContour {
    let mut names: Vec<String> = (1..=dim).map(|i| format!("x{i}")).collect();
    names.push("t".into());
    names.push("w".into());
    let vars = VarTable::new(names);
    // a large work budget: the extreme-scale texts carry numbers of thousands of digits
    let mut budget = usize::MAX;
    let p = riskplan_math::poly::parse_with_budget(
        text,
        &mut |n: &str| vars.get(n).ok_or_else(|| n.to_string()),
        &mut budget,
    )
    .unwrap();
    // w uniform on [0.3, 0.4]: raw moments (b^{k+1} − a^{k+1}) / ((k+1)(b − a))
    let m = |k: u32| {
        let (a, b) = (BigRational::new(3.into(), 10.into()), BigRational::new(4.into(), 10.into()));
        let p1 = |x: &BigRational| num_traits::pow(x.clone(), k as usize + 1);
        (p1(&b) - p1(&a)) / (BigRational::from_integer((k + 1).into()) * (b - a))
    };
    RiskContour::new(Layout { dim }, &p, &|_, k| Some(m(k)), &|v| vars.name(v)).unwrap()
}

fn encloses(i: &[Interval], e: &riskplan_math::poly::UPoly<BigRational>) -> Result<(), String> {
    for k in 0..=e.degree().max(i.len().saturating_sub(1)) {
        let v = e.coeff(k);
        let b = i.get(k).copied().unwrap_or(ZERO);
        // an infinite end bounds nothing on its side
        let above = b.lo == f64::NEG_INFINITY || BigRational::from_float(b.lo).is_some_and(|lo| lo <= v);
        let below = b.hi == f64::INFINITY || BigRational::from_float(b.hi).is_some_and(|hi| v <= hi);
        if !(above && below) {
            return Err(format!("coefficient {k}: {v} not in {b:?}"));
        }
    }
    Ok(())
}

/// Squaring a value that has already been rounded ten times: each sum `1 + b`
/// rounds back to 1, so the float result is 1 while the exact value is
/// `(1 + 10b)² ≈ 1 + 2.2e-15`. The enclosure must hold it; a rounding count of
/// `max(kx, ky) + min(len) + 1` would give an interval that misses it.
#[test]
fn product_of_two_computed_operands_is_enclosed() {
    let b = (1.0 - 2f64.powi(-10)) * 2f64.powi(-53);
    let mut x = EPoly::<4>::exact(1.0);
    for _ in 0..10 {
        x = x.add_signed(&EPoly::exact(b), 1.0);
    }
    assert_eq!(x.v[0], 1.0, "every sum rounds back to 1");
    let sq = x.mul(&x).unwrap();
    let mut out = [ZERO; 4];
    assert_eq!(sq.enclosure(&mut out), Some(1));
    let exact_x = BigRational::from_integer(1.into())
        + BigRational::from_float(b).unwrap() * BigRational::from_integer(10.into());
    let exact = exact_x.clone() * exact_x;
    let (lo, hi) = (BigRational::from_float(out[0].lo).unwrap(), BigRational::from_float(out[0].hi).unwrap());
    assert!(lo <= exact && exact <= hi, "{:?} misses {}", out[0], exact);
}

proptest! {
    /// The compiled restriction encloses the exact one (computed in rationals by a
    /// different code path: no centring, general polynomial composition), for moving
    /// and static obstacles, curved pieces, far-off centres and shifted times.
    #[test]
    fn compiled_restriction_encloses_the_exact_one(
        cx in -1e3f64..1e3, cy in -1e3f64..1e3, tc in -50f64..50.0,
        a in prop::collection::vec(-2f64..2.0, 3), b in prop::collection::vec(-2f64..2.0, 3),
        t0 in -20f64..20.0, h in 1e-3f64..10.0, moving in any::<bool>(),
    ) {
        let text = if moving {
            format!("w^2 - (x1 - {cx} - 0.1*t)^2 - (x2 - {cy} + 0.05*t^2)^2")
        } else {
            format!("w^2*(1 - x1 + x2) - (x1 - {cx})^4 - (x2 - {cy})^2")
        };
        let c = contour(&text, 2);
        let center = [cx + 0.3, cy - 0.2, tc];
        let cc = CompiledContour::new(&c, &Frame::new(&center, &[4.0, 0.3, 1e-3 + tc.abs()]));
        let coeffs = vec![vec![cx + a[0], a[1], a[2] * 0.1], vec![cy + b[0], b[1]]];
        let piece = PieceRef { t0, t1: t0 + h, coeffs: &coeffs };
        let delta = BigRational::new(1.into(), 20.into());
        let exact = restrict_exact(&c, piece, &delta);
        let fast = cc.restrict(piece).unwrap();
        let (g1, g2) = fast.constraints(Interval::enclose_rational(&(BigRational::from_integer(1.into()) - &delta))).unwrap();
        prop_assert!(encloses(g1.coeffs(), &exact.cantelli).is_ok(), "{:?}", encloses(g1.coeffs(), &exact.cantelli));
        prop_assert!(encloses(g2.coeffs(), &exact.mean).is_ok(), "{:?}", encloses(g2.coeffs(), &exact.mean));
        // the f64 path with a running error bound encloses it too
        let omd = BigRational::from_integer(1.into()) - &delta;
        let f = riskplan_math::poly::rational_to_f64(&omd);
        let fe = BigRational::from_float(f).is_some_and(|e| e == omd);
        let subs = Substitution::new(piece, cc.frame()).unwrap();
        let checked = cc.with_constraints(&subs, (f, fe), |g2, g1| {
            encloses(g1, &exact.cantelli).and_then(|_| encloses(g2, &exact.mean))
        }).unwrap();
        prop_assert!(checked.is_ok(), "{:?}", checked);
    }
}

proptest! {
    /// Each substituted coefficient is within `k·u·a` of the exact one (the model
    /// [`EPoly`] builds on), for straight pieces (error-free transformations) and
    /// curved ones (exact rationals), far from the origin and at shifted times.
    #[test]
    fn substitution_coefficients_meet_their_error_model(
        c in prop::collection::vec(-1e3f64..1e3, 3), slope in -5f64..5.0, curve in -1f64..1.0,
        t0 in -50f64..50.0, h in 1e-3f64..10.0, center in prop::collection::vec(-1e3f64..1e3, 3),
    ) {
        let coeffs = vec![vec![c[0], slope], vec![c[1], slope * 0.3, curve]];
        let piece = PieceRef { t0, t1: t0 + h, coeffs: &coeffs };
        let sub = Substitution::new(piece, &Frame::centred(&center)).unwrap();
        let q = |v: f64| BigRational::from_float(v).unwrap();
        for d in 0..2 {
            let exact = riskplan_math::poly::UPoly::new(coeffs[d].iter().map(|&v| q(v)).collect())
                .compose_affine(&q(t0), &(q(t0 + h) - q(t0)))
                .sub(&riskplan_math::poly::UPoly::constant(q(center[d])));
            for k in 0..sub.len[d] {
                let (v, a, r) = sub.coeffs[d][k];
                let err = (q(v) - exact.coeff(k)).abs();
                let bound = q(a * r as f64 * UNIT_ROUNDOFF * (1.0 + 1e-12) + 1e-300);
                prop_assert!(err <= bound, "coordinate {d}, τ^{k}: error {} > bound {}", riskplan_math::poly::rational_to_f64(&err), riskplan_math::poly::rational_to_f64(&bound));
            }
        }
    }
}

/// An obstacle at scale `10^k` (lengths `x/S`, `S = 10^k`) and horizon `T`, and a piece
/// through it: the three shapes of the extreme-scale tests — a superellipse (degree 8,
/// E\[P²\] of degree 16), a disk, and a mixed degree-6 polynomial; static or moving, in
/// 2-D or 3-D.
fn extreme_case(k: i32, t: f64, dim: usize, shape: usize, moving: bool) -> RiskContour {
    let s = format!("1e{k}");
    let x = |i: usize| {
        if moving && i == 1 {
            format!("(x1/{s} - 0.2*t/{t:e})")
        } else {
            format!("(x{i}/{s})")
        }
    };
    let text = match shape {
        0 => format!("w + 0.5 - {}", (1..=dim).map(|i| format!("{}^8", x(i))).collect::<Vec<_>>().join(" - ")),
        1 => format!("w^2 - {}", (1..=dim).map(|i| format!("({} - 0.1)^2", x(i))).collect::<Vec<_>>().join(" - ")),
        _ => {
            format!("w*{x1}^3*{x2} - {x1}^6 - 0.5*{x2}^4 + 0.1*w - 0.25*{xl}^2", x1 = x(1), x2 = x(2), xl = x(dim))
        }
    };
    contour(&text, dim)
}

/// The fast path's enclosures (the `f64` running error bound, and the interval
/// composition) hold the exact rational restriction (a different code path: no
/// frame, general composition in rationals), or the fast path refuses. Scales
/// 10⁻³⁰…10³⁰⁰, horizons 10⁻³…10⁶, degrees up to 8 (16 in E\[P²\]), 2-D and 3-D,
/// moving obstacles, straight and curved pieces cut down to 2⁻⁴⁰ of the horizon
/// (grazing), in three frames: the scene's (scaled to the workspace), a unit frame
/// (the compiled numbers then reach 10^±4800: underflow and overflow everywhere),
/// and one scaled wrongly by 2^±300.
/// The exact composition, in rationals, of `p` (frame variables) with a straight
/// piece `c0 + c1·t` per coordinate over [t0, t1] moved into `frame` — by general
/// polynomial composition, not by the Horner trees under test.
fn exact_in_frame(
    p: &QPoly,
    rows: &[[f64; 2]],
    t0: f64,
    t1: f64,
    frame: &Frame,
) -> riskplan_math::poly::UPoly<BigRational> {
    let q = |v: f64| BigRational::from_float(v).unwrap();
    let two = BigRational::from_integer(2.into());
    let scale = |e: i32| -> BigRational { num_traits::Pow::pow(&two, -e) };
    let (qt0, h) = (q(t0), q(t1) - q(t0));
    let lin = riskplan_math::poly::UPoly::new(vec![qt0.clone(), h.clone()]);
    let mut subs: Vec<riskplan_math::poly::UPoly<BigRational>> = rows
        .iter()
        .enumerate()
        .map(|(d, r)| {
            let x = riskplan_math::poly::UPoly::new(vec![q(r[0]), q(r[1])]);
            let x = riskplan_math::poly::UPoly::new(vec![x.coeff(0) + x.coeff(1) * &qt0, x.coeff(1) * &h]);
            x.sub(&riskplan_math::poly::UPoly::constant(q(frame.center[d]))).map(|c| c * scale(frame.exponents[d]))
        })
        .collect();
    let d = rows.len();
    subs.push(
        lin.sub(&riskplan_math::poly::UPoly::constant(q(frame.center[d]))).map(|c| c * scale(frame.exponents[d])),
    );
    p.compose_univariate(&subs)
}

proptest! {
    /// The `f64` mid-radius restriction of a polynomial with interval coefficients
    /// ([`Compiled::compose_r`]) encloses the exact restriction of every polynomial
    /// within those intervals: checked for the lower ends, the upper ends and a mix,
    /// against rational composition by a different code path.
    #[test]
    fn mid_radius_restriction_encloses_every_member(
        coeffs in prop::collection::vec((-3f64..3.0, 0f64..1e-3, 0u32..4, 0u32..4, 0u32..3), 1..12),
        rows in prop::collection::vec((-50f64..50.0, -20f64..20.0), 2),
        t0 in -5f64..5.0, h in 1e-3f64..4.0, cx in -40f64..40.0, scale in -3i32..3, pick in 0u32..3,
    ) {
        let frame = Frame::new(&[cx, -cx * 0.5, 0.25], &[2f64.powi(scale) * 20.0, 30.0, 3.0]);
        let mut p = Poly::<Interval>::zero();
        let mut members = vec![QPoly::zero(), QPoly::zero(), QPoly::zero()];
        for (k, &(m, r, e1, e2, e3)) in coeffs.iter().enumerate() {
            let mono = riskplan_math::poly::Monomial::from_pairs([(0, e1), (1, e2), (2, e3)].into_iter().filter(|x| x.1 > 0));
            let iv = Interval::new(m - r * m.abs(), m + r * m.abs());
            p.add_term(mono.clone(), iv);
            let q = |v: f64| BigRational::from_float(v).unwrap();
            let mix = if (k as u32 + pick) % 2 == 0 { iv.lo } else { iv.hi };
            for (member, v) in members.iter_mut().zip([iv.lo, iv.hi, mix]) {
                member.add_term(mono.clone(), q(v));
            }
        }
        let compiled = Compiled::from_intervals(&p, 3);
        let rows: Vec<[f64; 2]> = rows.iter().map(|&(a, b)| [a, b]).collect();
        let coeff_rows: Vec<Vec<f64>> = rows.iter().map(|r| r.to_vec()).collect();
        let piece = PieceRef { t0, t1: t0 + h, coeffs: &coeff_rows };
        let Some(sub) = Substitution::new(piece, &frame) else { return Ok(()) };
        let subs = sub.epolys::<CAPACITY>().unwrap();
        let Some(enc) = compiled.compose_r(&subs[..sub.len()]) else { return Ok(()) };
        for member in &members {
            let exact = exact_in_frame(member, &rows, t0, t0 + h, &frame);
            prop_assert!(encloses(enc.coeffs(), &exact).is_ok(), "{:?}", encloses(enc.coeffs(), &exact));
        }
    }
}

proptest! {
    /// The error-free sign of c0 + c1·t − l equals the sign computed in rationals,
    /// also for bounds at, one ulp around, and a rounding away from the float value.
    #[test]
    fn straight_value_sign_is_exact(
        c0 in -1e6f64..1e6, c1 in -1e6f64..1e6, t in -1e3f64..1e3, k in 0u32..5, scale in -300i32..300,
    ) {
        let sc = 2f64.powi(scale);
        let (c0, c1) = (c0 * sc, c1 * sc);
        let v = c0 + c1 * t;
        let l = match k { 0 => v, 1 => v.next_up(), 2 => v.next_down(), 3 => c0, _ => v * 1.5 };
        let q = |x: f64| BigRational::from_float(x).unwrap();
        if let Some(sign) = straight_value_sign(c0, c1, t, l) {
            let exact = (q(c0) + q(c1) * q(t) - q(l)).cmp(&BigRational::from_integer(0.into()));
            prop_assert_eq!(sign, exact);
        }
    }
}

/// An interval straddling 0 with a midpoint below `RADIUS_FLOOR` and a far larger
/// radius keeps its radius (it is not replaced by 0 ± 4·`RADIUS_FLOOR`).
#[test]
fn tiny_midpoint_with_a_wide_radius_is_enclosed() {
    let (lo, hi) = (-pow2(-860), pow2(-860) + pow2(-910));
    let iv = Interval::new(lo, hi);
    assert!(iv.mid() != 0.0 && iv.mid().abs() < RADIUS_FLOOR);
    let mut p = Poly::<Interval>::zero();
    p.add_term(riskplan_math::poly::Monomial::one(), iv);
    p.add_term(riskplan_math::poly::Monomial::var_pow(0, 1), Interval::point(1.0));
    let compiled = Compiled::from_intervals(&p, 3);
    let rows = vec![vec![0.0], vec![0.0]];
    let piece = PieceRef { t0: 0.0, t1: 1.0, coeffs: &rows };
    let sub = Substitution::new(piece, &Frame::centred(&[0.0, 0.0, 0.0])).unwrap();
    let subs = sub.epolys::<CAPACITY>().unwrap();
    let c0 = compiled.compose_r(&subs[..sub.len()]).expect("the f64 path").coeffs()[0];
    let q = |v: f64| BigRational::from_float(v).unwrap();
    assert!(q(c0.lo) <= q(lo) && q(hi) <= q(c0.hi), "[{lo:e}, {hi:e}] not in {c0:?}");
}

proptest! {
    /// [`Compiled::compose_r`] at extreme scales and shapes of coefficient intervals
    /// (points, one ulp, straddling 0, midpoints from 2⁻¹⁰⁰⁰ to 2⁶⁰), straight and
    /// curved pieces, frame exponents ±200: every member's exact restriction is enclosed.
    #[test]
    fn mid_radius_restriction_encloses_members_at_extreme_scales(
        coeffs in prop::collection::vec((-3f64..3.0, -1000i32..60, 0usize..6, -60i32..1, 0u32..7, 0u32..7, 0u32..4, 0usize..3), 1..20),
        rows in prop::collection::vec((-3f64..3.0, -3f64..3.0, -1f64..1.0, 0usize..3, -200i32..200), 2),
        t0 in -5f64..5.0, lh in -30i32..3, cx in prop::collection::vec(-3f64..3.0, 3), big in 0i32..40,
        fe in prop::collection::vec(-200i32..200, 3),
    ) {
        let q = |v: f64| BigRational::from_float(v).unwrap();
        let mut p = Poly::<Interval>::zero();
        let mut members = vec![QPoly::zero(), QPoly::zero(), QPoly::zero()];
        for &(m, e, kind, re, e1, e2, e3, pick) in &coeffs {
            let mid = m * 2f64.powi(e);
            let r = 2f64.powi(re) * mid.abs();
            let iv = match kind {
                0 => Interval::point(mid),
                1 => Interval::new(mid - r, mid + r),
                2 => Interval::new(-mid.abs() * 2.0, mid.abs() * 2.0 + r * 1e-3),
                3 => Interval::new(mid, (mid + r).max(mid)),
                4 => Interval::new(mid.min(mid.next_up()), mid.next_up()),
                _ => Interval::new(-mid.abs(), mid.abs().next_up()),
            };
            if !(iv.lo.is_finite() && iv.hi.is_finite()) {
                return Ok(());
            }
            let mono = riskplan_math::poly::Monomial::from_pairs([(0, e1), (1, e2), (2, e3)].into_iter().filter(|x| x.1 > 0));
            p.add_term(mono.clone(), iv);
            for (i, member) in members.iter_mut().enumerate() {
                let v = match (i, pick) { (0, _) | (2, 0) => iv.lo, (1, _) | (2, 1) => iv.hi, _ => iv.mid().clamp(iv.lo, iv.hi) };
                member.add_term(mono.clone(), q(v));
            }
        }
        let cx: Vec<f64> = cx
            .iter()
            .enumerate()
            .map(|(d, &c)| if d < 2 { rows[d].0 * 2f64.powi(rows[d].4) + c * 2f64.powi(rows[d].4 - big) } else { c })
            .collect();
        let frame = Frame { center: cx.clone(), exponents: fe.clone() };
        let compiled = Compiled::from_intervals(&p, 3);
        let t1 = t0 + 2f64.powi(lh);
        let rws: Vec<Vec<f64>> = rows
            .iter()
            .map(|&(a, b, c, deg, s)| {
                let sc = 2f64.powi(s);
                [a * sc, b * sc, c * sc][..=deg].to_vec()
            })
            .collect();
        let piece = PieceRef { t0, t1, coeffs: &rws };
        let Some(sub) = Substitution::new(piece, &frame) else { return Ok(()) };
        let Some(subs) = sub.epolys::<CAPACITY>() else { return Ok(()) };
        let Some(enc) = compiled.compose_r(&subs[..sub.len()]) else { return Ok(()) };
        let two = BigRational::from_integer(2.into());
        let exact_sub = |row: &[f64], c: f64, e: i32| {
            let sc: BigRational = num_traits::Pow::pow(&two, -e);
            riskplan_math::poly::UPoly::new(row.iter().map(|&v| q(v)).collect())
                .compose_affine(&q(t0), &(q(t1) - q(t0)))
                .sub(&riskplan_math::poly::UPoly::constant(q(c)))
                .map(|x| x * &sc)
        };
        let mut esubs: Vec<riskplan_math::poly::UPoly<BigRational>> = (0..2).map(|d| exact_sub(&rws[d], cx[d], fe[d])).collect();
        esubs.push(exact_sub(&[0.0, 1.0], cx[2], fe[2]));
        for member in &members {
            let exact = member.compose_univariate(&esubs);
            prop_assert!(encloses(enc.coeffs(), &exact).is_ok(), "{:?}", encloses(enc.coeffs(), &exact));
        }
    }
}

mod extreme_scales {
    use super::*;

    proptest! {
        #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]
        #[test]
        fn fast_path_encloses_the_exact_restriction_at_any_scale(
            k in -30i32..=300, tk in -3i32..=6, dim3 in any::<bool>(), moving in any::<bool>(),
            shape in 0usize..3, frame_kind in 0usize..4,
            p0 in prop::collection::vec(-0.95f64..0.95, 3), p1 in prop::collection::vec(-1.9f64..1.9, 3),
            curve in -0.5f64..0.5, cut in 0u32..=40, at in 0f64..1.0, delta_i in 0usize..3,
        ) {
            let dim = if dim3 { 3 } else { 2 };
            let (sc, t) = (10f64.powi(k), 10f64.powi(tk));
            let c = extreme_case(k, t, dim, shape, moving);
            let half: Vec<f64> = (0..dim).map(|_| 3.0 * sc).chain([t / 2.0]).collect();
            let mut center: Vec<f64> = vec![0.0; dim];
            center.push(t / 2.0);
            let frame = match frame_kind {
                0 | 1 => Frame::new(&center, &half),
                2 => Frame::centred(&center),
                _ => Frame { center: center.clone(), exponents: vec![if k % 2 == 0 { 300 } else { -300 }; dim + 1] },
            };
            let cc = CompiledContour::new(&c, &frame);
            // x_d(t) = S·(p0 + p1·t/T [+ curve·(t/T)²]), cut to [t0, t0 + T·2^-cut]
            let coeffs: Vec<Vec<f64>> = (0..dim)
                .map(|d| {
                    let mut row = vec![sc * p0[d], sc * p1[d] / t];
                    if d == 0 && frame_kind != 1 {
                        row.push(sc * curve / (t * t));
                    }
                    row
                })
                .collect();
            let len = t * 2f64.powi(-(cut as i32));
            let t0 = at * (t - len);
            let piece = PieceRef { t0, t1: t0 + len, coeffs: &coeffs };
            let delta = BigRational::new(1.into(), [10, 2, 1000][delta_i].into());
            let exact = restrict_exact(&c, piece, &delta);
            let omd = BigRational::from_integer(1.into()) - &delta;
            let f = riskplan_math::poly::rational_to_f64(&omd);
            let fe = BigRational::from_float(f).is_some_and(|e| e == omd);
            if let Some(subs) = Substitution::new(piece, cc.frame()) {
                if let Some(checked) = cc.with_constraints(&subs, (f, fe), |g2, g1| {
                    encloses(g1, &exact.cantelli).and_then(|_| encloses(g2, &exact.mean))
                }) {
                    prop_assert!(checked.is_ok(), "f64 path, scale 1e{k}, frame {frame_kind}: {:?}", checked);
                }
            }
            if let Some(r) = cc.restrict(piece) {
                if let Some((g1, g2)) = r.constraints(Interval::enclose_rational(&omd)) {
                    let checked = encloses(g1.coeffs(), &exact.cantelli).and_then(|_| encloses(g2.coeffs(), &exact.mean));
                    prop_assert!(checked.is_ok(), "interval path, scale 1e{k}, frame {frame_kind}: {:?}", checked);
                }
            }
        }
    }

    /// The scene's frame keeps the `f64` path in use at every scale (the property
    /// above is not vacuous): the extreme-scale superellipse from 10⁻³⁰ to 10³⁰⁰, a
    /// straight piece through it, is computed (not refused) and enclosed.
    #[test]
    fn scene_frame_keeps_the_fast_path_at_every_scale() {
        for k in [-30, -5, 0, 18, 20, 21, 41, 100, 200, 300] {
            let sc = 10f64.powi(k);
            let c = extreme_case(k, 1.0, 2, 0, false);
            let cc = CompiledContour::new(&c, &Frame::new(&[0.0, 0.0, 0.5], &[3.0 * sc, 3.0 * sc, 0.5]));
            let coeffs = vec![vec![-2.9 * sc, 5.8 * sc], vec![1.05 * sc]];
            let piece = PieceRef { t0: 0.0, t1: 1.0, coeffs: &coeffs };
            let delta = BigRational::new(1.into(), 10.into());
            let exact = restrict_exact(&c, piece, &delta);
            let subs = Substitution::new(piece, cc.frame()).expect("substitution");
            let checked = cc
                .with_constraints(&subs, (0.9, false), |g2, g1| {
                    encloses(g1, &exact.cantelli).and_then(|_| encloses(g2, &exact.mean))
                })
                .unwrap_or_else(|| panic!("scale 1e{k}: the fast path refused"));
            assert!(checked.is_ok(), "scale 1e{k}: {checked:?}");
        }
    }
}

/// Centring keeps the enclosures tight far from the origin: at x ≈ 1000 the
/// uncentred restriction's coefficients are orders of magnitude wider.
#[test]
fn centring_keeps_enclosures_tight_far_from_the_origin() {
    let c = contour("w^2 - (x1 - 1000)^2 - (x2 + 500)^2", 2);
    let coeffs = vec![vec![999.0, 0.5], vec![-501.0, 0.25]];
    let piece = PieceRef { t0: 10.0, t1: 11.0, coeffs: &coeffs };
    let delta = BigRational::new(1.into(), 20.into());
    let omd = Interval::enclose_rational(&(BigRational::from_integer(1.into()) - &delta));
    let width = |p: &FPoly| p.coeffs().iter().map(|i| i.width()).fold(0.0, f64::max);
    let centred = CompiledContour::new(&c, &Frame::centred(&[1000.0, -500.0, 10.0])).restrict(piece).unwrap();
    let origin = CompiledContour::new(&c, &Frame::centred(&[0.0, 0.0, 0.0])).restrict(piece).unwrap();
    let (g_c, _) = centred.constraints(omd).unwrap();
    let (g_o, _) = origin.constraints(omd).unwrap();
    assert!(width(&g_c) < 1e-8, "{}", width(&g_c));
    assert!(width(&g_o) > 1e3 * width(&g_c), "{} vs {}", width(&g_o), width(&g_c));
}

#[test]
fn box_evaluation_encloses_point_values_and_derivatives_are_exact() {
    let c = contour("w^2 - (x1 - t)^2 - x2^2", 2);
    let cc = Compiled::new(&c.mean, 3);
    let v = cc.eval_box(&[Interval::new(0.1, 0.2), Interval::new(-0.1, 0.3), Interval::new(0.0, 0.5)]);
    for &(x, y, t) in &[(0.1, -0.1, 0.0), (0.2, 0.3, 0.5), (0.15, 0.0, 0.25)] {
        let (m, _) = c.moments_f64(&[x, y, t]);
        assert!(v.lo <= m && m <= v.hi);
    }
    let d = derivative(&c.mean, 0); // ∂/∂x1 of E[w²] − (x1 − t)² − x2² = −2(x1 − t)
    let q = |v: i64| BigRational::from_integer(v.into());
    assert_eq!(d.eval(&[q(3), q(0), q(1), q(0)]), q(-4));
}
