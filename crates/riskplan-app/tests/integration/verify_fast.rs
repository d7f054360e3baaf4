//! `verify` at the kernel's speed: the verify path decides as the planners'
//! checker does (compiled restriction, covers of the scene index, a Bernstein witness
//! instead of the SDP), so its "safe" answers are checked here against oracles that share
//! no code with it, on random trajectories large enough to build the index:
//!
//! - illustrative-3 in closed form: the disk `‖x‖ ≤ w`, `w ~ U[0.3, 0.4]`, is met with
//!   probability `P(w ≥ d) = (0.4 − d)/0.1` at distance `d` from the origin, so a piece
//!   certified at Δ = 0.1 must keep `d ≥ 0.39` over its whole interval — the minimum
//!   distance of a straight piece is solved exactly, not sampled;
//! - d1 (Gaussian disks): the sampled oracle of `common::oracle` (the contour constraints
//!   term by term, and the independent bound oracle where other bounds prove a part).
//!
//! And the summary (`Detail::FirstNotSafe`: no report for safe pieces) decides every piece
//! as the full report does.

use crate::common::{oracle, scene, size};
use riskplan_app::verify::{
    verify_with, Detail, Method, SceneKernel, VerifyOptions, INDEX_MIN_PIECES, PARALLEL_MIN_PIECES,
};
use riskplan_certify::positivity::sos::SosSettings;
use riskplan_math::contour::RiskLevel;
use riskplan_scene::Piece;
use std::sync::Arc;

/// A seeded random trajectory of `n` straight pieces through uniform points of the box
/// `[lo, hi]²` over the horizon `[0, 1]` (a small linear congruential generator: the
/// test needs no statistics, only spread).
fn random_pieces(n: usize, lo: f64, hi: f64, seed: u64) -> Vec<Piece> {
    let mut s = seed;
    let mut next = || {
        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        lo + (hi - lo) * ((s >> 11) as f64 / (1u64 << 53) as f64)
    };
    let pts: Vec<[f64; 2]> = (0..=n).map(|_| [next(), next()]).collect();
    (0..n)
        .map(|i| {
            let (t0, t1) = (i as f64 / n as f64, if i + 1 == n { 1.0 } else { (i + 1) as f64 / n as f64 });
            Piece::segment(&pts[i], &pts[i + 1], t0, t1)
        })
        .collect()
}

/// The smallest distance from the origin of the straight piece `x(t) = c0 + c1·t` on
/// `[t0, t1]` (its float coefficients, as certified), by the closed-form minimiser.
fn min_distance(p: &Piece) -> f64 {
    let (c0, c1): (Vec<f64>, Vec<f64>) = p.coeffs.iter().map(|r| (r[0], r.get(1).copied().unwrap_or(0.0))).unzip();
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let vv = dot(&c1, &c1);
    let t = if vv > 0.0 { (-dot(&c0, &c1) / vv).clamp(p.t0, p.t1) } else { p.t0 };
    [p.t0, t, p.t1]
        .iter()
        .map(|&t| c0.iter().zip(&c1).map(|(a, b)| (a + b * t).powi(2)).sum::<f64>().sqrt())
        .fold(f64::INFINITY, f64::min)
}

fn check_summary_agrees(kernel: &SceneKernel, pieces: &[Piece], delta: &RiskLevel, method: Method) -> Vec<bool> {
    let every = VerifyOptions { method, settings: SosSettings::default(), ..Default::default() };
    let full = verify_with(kernel, pieces, delta, &every, &|| false).unwrap();
    let summary = VerifyOptions { detail: Detail::FirstNotSafe, ..every.clone() };
    let short = verify_with(kernel, pieces, delta, &summary, &|| false).unwrap();
    let safe: Vec<bool> = full.report.pieces.iter().map(|p| p.safe).collect();
    assert_eq!(safe.len(), pieces.len());
    let not_safe: Vec<usize> = (0..safe.len()).filter(|&i| !safe[i]).collect();
    assert_eq!(full.not_safe_indices, not_safe, "{method:?}: the full report's indices");
    assert_eq!(short.not_safe_indices, not_safe, "{method:?}: the summary decides as the full report");
    assert_eq!((short.report.checked, short.report.not_safe), (pieces.len(), not_safe.len()));
    assert_eq!(short.report.first_not_safe, not_safe.first().copied());
    assert_eq!(short.report.pieces.len(), usize::from(!not_safe.is_empty()), "the summary reports one piece");
    if let (Some(first), Some(&i)) = (short.report.pieces.first(), not_safe.first()) {
        assert_eq!(first, &full.report.pieces[i]);
    }
    assert_eq!(full.report.safe, not_safe.is_empty());
    safe
}

/// illustrative-3, exact and SOS: every piece called safe keeps its distance from the
/// disk's centre ≥ 0.39 (the true risk ≤ Δ = 0.1), and about half the pieces are unsafe.
#[test]
fn verify_safe_pieces_keep_off_the_disk_in_closed_form() {
    let s = scene("illustrative-3");
    let delta = s.risk.clone();
    let n = size("verify_fast_pieces", INDEX_MIN_PIECES + 200, 10_000);
    let pieces = random_pieces(n, -1.0, 1.0, 21);
    let kernel = SceneKernel::new(Arc::new(s));
    for method in [Method::Exact, Method::Sos] {
        let safe = check_summary_agrees(&kernel, &pieces, &delta, method);
        let n_safe = safe.iter().filter(|&&b| b).count();
        assert!(n_safe > n / 4 && n_safe < 3 * n / 4, "{method:?}: {n_safe} of {n} safe (about half expected)");
        for (p, _) in pieces.iter().zip(&safe).filter(|(_, &s)| s) {
            let d = min_distance(p);
            // the disk's Δ-radius is 0.39; a piece certified safe stays outside it
            assert!(d >= 0.39 - 1e-9, "{method:?}: certified piece comes within {d} of the centre: {p:?}");
        }
    }
}

/// Several threads give the very outcome of one (reports, indices of the pieces not safe,
/// counts), in both details, on a trajectory long enough to be split (an odd length, so
/// the chunks differ in size); a stop that says yes partway interrupts every thread.
#[test]
fn threads_give_the_report_of_one_thread() {
    let s = scene("illustrative-3");
    let delta = s.risk.clone();
    let pieces = random_pieces(PARALLEL_MIN_PIECES + 123, -1.0, 1.0, 8);
    let kernel = SceneKernel::new(Arc::new(s));
    for detail in [Detail::Every, Detail::FirstNotSafe] {
        let one = VerifyOptions { detail, threads: 1, ..Default::default() };
        let base = verify_with(&kernel, &pieces, &delta, &one, &|| false).unwrap();
        assert!(base.not_safe_indices.len() > pieces.len() / 4, "about half the pieces are not safe");
        for threads in [2, 3, 1000] {
            let many = VerifyOptions { threads, ..one.clone() };
            let out = verify_with(&kernel, &pieces, &delta, &many, &|| false).unwrap();
            assert_eq!(out, base, "{detail:?}, {threads} threads");
        }
        let calls = std::sync::atomic::AtomicUsize::new(0);
        let stop = || calls.fetch_add(1, std::sync::atomic::Ordering::Relaxed) > 1000;
        let many = VerifyOptions { threads: 2, ..one.clone() };
        assert!(verify_with(&kernel, &pieces, &delta, &many, &stop).is_err(), "{detail:?}: not interrupted");
    }
}

/// d1 (Gaussian disks, index with covers): the sampled oracle accepts every piece the
/// fast verify path calls safe, and the summary decides as the full report.
#[test]
fn verify_safe_pieces_pass_the_independent_oracle_on_d1() {
    let s = scene("example-d1-cluttered-2d");
    let delta = s.risk.clone();
    let n = size("verify_fast_d1_pieces", INDEX_MIN_PIECES + 100, 4_000);
    let pieces = random_pieces(n, 0.0, 5.0, 5);
    let kernel = SceneKernel::new(Arc::new(s.clone()));
    let safe = check_summary_agrees(&kernel, &pieces, &delta, Method::Exact);
    let bounds = oracle::bound_oracle(&s);
    let mut checked = 0;
    for (p, _) in pieces.iter().zip(&safe).filter(|(_, &s)| s) {
        oracle::check_piece_with(&s, p, &delta, 64, Some(&bounds)).unwrap_or_else(|e| panic!("{e}"));
        checked += 1;
    }
    assert!(checked > 0, "no random piece of d1 was safe");
}

/// A piece outside the horizon is checked against every obstacle, whatever the index says
/// (with 16 obstacles or more the index files a moving obstacle by its slabs, which end
/// with the horizon: one that is out of the workspace until then must not be skipped for a
/// later piece). Only the library takes such pieces: the CLI and the service refuse them
/// as input.
#[test]
fn pieces_after_the_horizon_are_not_skipped_by_the_index() {
    let mut obstacles: Vec<String> = (0..16)
        .map(|i| {
            let (x, y) = (0.5 + 3.0 * (i % 4) as f64, 0.5 + 3.0 * (i / 4) as f64);
            format!(r#"{{"id": "s{i}", "poly": "w^2 - (x1 - {x})^2 - (x2 - {y})^2"}}"#)
        })
        .collect();
    // out of the workspace during the horizon [0, 1]; at x1 = 5 at t = 1.75
    obstacles.push(r#"{"id": "late", "poly": "w^2 - (x1 - (-10 + 20*(t - 1)))^2 - (x2 - 5)^2"}"#.into());
    let text = format!(
        r#"{{"format": "riskplan-scene/1", "name": "late", "dim": 2,
            "workspace": {{"lower": [0, 0], "upper": [10, 10]}}, "horizon": [0, 1], "risk": 0.1,
            "params": {{"w": {{"dist": "uniform", "low": 0.2, "high": 0.3}}}},
            "obstacles": [{}], "start": [2, 2], "goal": [8, 8]}}"#,
        obstacles.join(", ")
    );
    let s = riskplan_scene::Scene::from_json(&text).unwrap();
    let delta = s.risk.clone();
    let kernel = SceneKernel::new(Arc::new(s.clone()));
    let index = kernel.index(&vec![delta.clone(); s.obstacles.len()], &|| false);
    assert!(index.complete());
    // x1 = 5 from x2 = 0 to 10 over [1.5, 2]: the late obstacle crosses it at t = 1.75
    let piece = Piece::segment(&[5.0, 0.0], &[5.0, 10.0], 1.5, 2.0);
    let r = verify_with(&kernel, std::slice::from_ref(&piece), &delta, &VerifyOptions::default(), &|| false).unwrap();
    let late = r.report.pieces[0].obstacles.iter().find(|o| o.id == "late").unwrap();
    assert!(!r.report.safe && late.status != riskplan_app::verify::Status::Safe, "{late:?}");
}

/// A piece running backwards in time (t0 > t1) is no piece: the motion checker refuses it,
/// and splitting it into parts (the cover lookup of long pieces) does not panic (no `clamp`
/// with min > max). Such a piece is reachable through the library only.
#[test]
fn a_piece_backwards_in_time_is_refused_without_a_panic() {
    use riskplan_scene::motion::{Motion, MotionChecker};
    let s = Arc::new(scene("example-d1-cluttered-2d"));
    let kernel = SceneKernel::new(s.clone());
    let deltas = vec![s.risk.clone(); s.obstacles.len()];
    kernel.index(&deltas, &|| false);
    let cert = riskplan_app::verify::SceneCertifier::with_deltas(&kernel, deltas, Method::Exact);
    let backwards = Piece { t0: 0.9, t1: 0.1, coeffs: vec![vec![0.05, 5.0], vec![0.05, 5.0]] };
    assert_eq!(cert.check(&backwards), Motion::Rejected);
    // the same check accepts a piece that stays at the scene's start (a certified point)
    let start = s.start.clone().expect("d1 has a start");
    let still = Piece::segment(&start, &start, 0.1, 0.9);
    assert_eq!(cert.check(&still), Motion::Accepted, "the start, held still");
}

/// The 128 disks of the tests below: the scene, each disk's nominal centre and radius, and
/// the side of the square workspace.
type Disks = (Arc<riskplan_scene::Scene>, Vec<(f64, f64, f64)>, f64);

fn disks_128(rng: &mut rand_chacha::ChaCha8Rng) -> Disks {
    use rand::Rng;
    let side = 10.0 * 128f64.sqrt();
    let mut params = serde_json::Map::new();
    let mut obstacles = Vec::new();
    let mut disks = Vec::new();
    for k in 1..=128 {
        let (cx, cy, r): (f64, f64, f64) = (
            (rng.random_range(0.0..side) * 100.0f64).round() / 100.0,
            (rng.random_range(0.0..side) * 100.0f64).round() / 100.0,
            (rng.random_range(0.8..1.6) * 100.0f64).round() / 100.0,
        );
        params.insert(format!("s{k}"), serde_json::json!({"dist": "uniform", "low": 0.9, "high": 1.1}));
        params.insert(format!("d{k}"), serde_json::json!({"dist": "normal", "mean": 0, "std": 0.05}));
        obstacles.push(serde_json::json!({"id": format!("disk{k}"), "poly": format!("({r}*s{k})^2 - (x1 - {cx} - d{k})^2 - (x2 - {cy})^2")}));
        disks.push((cx, cy, r));
    }
    let text = serde_json::json!({
        "format": "riskplan-scene/1", "name": "disks-128", "dim": 2,
        "workspace": {"lower": [0, 0], "upper": [side, side]}, "horizon": [0, 1], "risk": 0.05,
        "params": params, "obstacles": obstacles, "start": [0.5, 0.5], "goal": [side - 0.5, side - 0.5],
    })
    .to_string();
    (Arc::new(riskplan_scene::Scene::from_json(&text).unwrap()), disks, side)
}

/// The distance from point `c` to the segment `a`–`b`, in closed form.
fn segment_distance(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let vv = dx * dx + dy * dy;
    let u = if vv > 0.0 { (((c[0] - a[0]) * dx + (c[1] - a[1]) * dy) / vv).clamp(0.0, 1.0) } else { 0.0 };
    ((a[0] + u * dx - c[0]).powi(2) + (a[1] + u * dy - c[1]).powi(2)).sqrt()
}

/// The planners' checker on many obstacles: a piece whose box meets several obstacles'
/// covers is split into parts, each looked up in the index, and the parts' candidates
/// united (`SceneCertifier`, a bit per obstacle). 128 disks `(r·s)² − (x − cx − d)² −
/// (y − cy)²`, s ~ U[0.9, 1.1], d ~ N(0, 0.05), Δ = 0.05; 3000 random pieces of 2 to 12
/// disk radii. Oracle in closed form, sharing no code with the checker: a piece that comes
/// within 0.9·r − 0.25 of a nominal centre has a point that collides for every s and every
/// |d| ≤ 0.25 (5σ), with probability above 0.999 > Δ — it must be refused.
#[test]
fn checker_refuses_every_piece_through_a_disk_among_many() {
    use rand::{Rng, SeedableRng};
    use riskplan_scene::motion::{Motion, MotionChecker};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(128);
    let (s, disks, side) = disks_128(&mut rng);
    let checker = riskplan_certify::checker::SceneCertifier::new(s.clone(), s.risk.clone(), Method::Exact);
    let dist = segment_distance;
    let (mut through, mut accepted) = (0, 0);
    for _ in 0..3000 {
        let a = [rng.random_range(2.0..side - 2.0), rng.random_range(2.0..side - 2.0)];
        let (len, angle): (f64, f64) = (rng.random_range(2.4..14.4), rng.random_range(0.0..std::f64::consts::TAU));
        let b = [(a[0] + len * angle.cos()).clamp(0.0, side), (a[1] + len * angle.sin()).clamp(0.0, side)];
        let piece = Piece::segment(&a, &b, 0.0, 1.0);
        let hit = disks.iter().any(|&(cx, cy, r)| dist(a, b, [cx, cy]) < 0.9 * r - 0.25);
        let ok = checker.check(&piece) == Motion::Accepted;
        through += hit as usize;
        accepted += ok as usize;
        assert!(!(hit && ok), "a piece {a:?} -> {b:?} through a disk was accepted");
    }
    println!("128 disks: {through} of 3000 pieces through a disk (all refused), {accepted} accepted");
    assert!(through > 300 && accepted > 300, "the test exercises both answers: {through} through, {accepted} accepted");
}

/// The checker's guess for post-processing (`likely_rejected`, docs/design.md §6.8) on the
/// 128 disks: it never guesses "rejected" for a piece the check accepts (E\[P\] < 0 is then
/// proven along the whole piece), and it catches the pieces through the middle of a disk
/// (closed form: within half a radius of a nominal centre, where E\[P\] > 0 for these laws),
/// at least 95 % of them — its samples are a cover's quarter apart.
#[test]
fn the_guess_never_refuses_an_accepted_piece_and_finds_pieces_through_disks() {
    use rand::{Rng, SeedableRng};
    use riskplan_scene::motion::{Motion, MotionChecker};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(129);
    let (s, disks, side) = disks_128(&mut rng);
    let checker = riskplan_certify::checker::SceneCertifier::new(s.clone(), s.risk.clone(), Method::Exact);
    // the index (and its grid) is built by the first check
    let _ = checker.check(&Piece::segment(&[1.0, 1.0], &[1.5, 1.0], 0.0, 1.0));
    let (mut accepted, mut through, mut caught) = (0, 0, 0);
    for _ in 0..3000 {
        let a = [rng.random_range(2.0..side - 2.0), rng.random_range(2.0..side - 2.0)];
        let (len, angle): (f64, f64) = (rng.random_range(2.4..40.0), rng.random_range(0.0..std::f64::consts::TAU));
        let b = [(a[0] + len * angle.cos()).clamp(0.0, side), (a[1] + len * angle.sin()).clamp(0.0, side)];
        let piece = Piece::segment(&a, &b, 0.0, 1.0);
        let guess = checker.likely_rejected(&piece);
        if checker.check(&piece) == Motion::Accepted {
            accepted += 1;
            assert!(!guess, "an accepted piece {a:?} -> {b:?} guessed rejected");
        }
        if disks.iter().any(|&(cx, cy, r)| segment_distance(a, b, [cx, cy]) < 0.5 * r) {
            through += 1;
            caught += guess as usize;
        }
    }
    println!("128 disks: {accepted} accepted, {caught} of {through} pieces through a disk's middle guessed");
    assert!(accepted > 200 && through > 500, "both kinds exercised: {accepted} accepted, {through} through");
    assert!(caught as f64 >= 0.95 * through as f64, "guessed only {caught} of {through}");
}

/// On a crowded scene a plan's whole-path bound is computed on the thread beside its final
/// check (`app::WHOLE_PATH_BESIDE_MIN_OBSTACLES`): what the plan reports is the bound of its
/// trajectory at the plan's effort and slack, computed again here on this thread — the same
/// number, for several seeds one after another (the thread is reused).
#[test]
fn the_whole_path_bound_computed_beside_the_check_is_the_plans_own() {
    use rand::SeedableRng;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(130);
    let (s, _, _) = disks_128(&mut rng);
    assert!(s.obstacles.len() >= riskplan_app::WHOLE_PATH_BESIDE_MIN_OBSTACLES);
    let kernel = riskplan_app::verify::SceneKernel::from(s.clone());
    for seed in 1..=3 {
        let req = riskplan_app::PlanRequest { seed, ..Default::default() };
        let (problem, out) = req.run(&kernel, None).expect("plan");
        assert!(out.certified, "seed {seed}: {:?}", out.reason);
        let traj = out.trajectory.as_ref().expect("a trajectory");
        let slack = riskplan_app::WHOLE_PATH_SLACK_SHARE * problem.delta.floor_f64();
        let again = riskplan_app::verify::plan_whole_path_risk(
            &kernel,
            &traj.pieces,
            riskplan_certify::whole_path::CellEffort::PLAN,
            slack,
            false,
            &|| false,
        )
        .expect("not stopped");
        assert!(again.is_some(), "seed {seed}: a bound");
        assert_eq!(out.stats.whole_path_risk, again, "seed {seed}");
    }
}

/// The whole-path bound shared by two threads (`WholePathWork`: each obstacle bounded by
/// the thread that claims it, the bounds added up in the obstacles' order) equals the
/// bound one thread finds obstacle after obstacle, here written again from the public
/// parts (reaches, their grid, one partition per obstacle; the slack shared by the
/// obstacles whose reach the plan enters) — whichever thread bounds what: a helper racing
/// the plan, a helper that has finished before the plan joins, a helper stopped at once, one
/// that panics, and none; and a stopped plan gets an error, never a smaller bound. (The
/// per-obstacle bounds themselves are tested against closed forms and Monte Carlo beside
/// the partition, `certify::whole_path::partition`; this tests the sharing and the sum.)
#[test]
fn a_whole_path_bound_shared_by_two_threads_is_the_one_found_alone() {
    use rand::SeedableRng;
    use riskplan_app::verify::WholePathWork;
    use riskplan_certify::whole_path::{add_up, cells_path_risk_in, CellEffort, PieceBoxes};
    use riskplan_certify::PieceRef;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(131);
    let (s, _, _) = disks_128(&mut rng);
    let kernel = riskplan_app::verify::SceneKernel::from(s.clone());
    let alone = |pieces: &[Piece], slack: f64| -> Option<f64> {
        let refs: Vec<PieceRef<'_>> =
            pieces.iter().map(|p| PieceRef { t0: p.t0, t1: p.t1, coeffs: &p.coeffs }).collect();
        let (frames, reaches, grid) = kernel.path_reaches(&|| false).expect("not stopped");
        let boxes = PieceBoxes::new(&refs, 2);
        let marked = grid.and_then(|g| g.candidates(&boxes));
        let cleared: Vec<bool> = (0..reaches.len())
            .map(|i| {
                reaches[i].as_ref().is_some_and(|r| marked.as_ref().is_some_and(|m| !m[i]) || r.clears_all(&boxes))
            })
            .collect();
        let open = cleared.iter().filter(|&&c| !c).count();
        let effort = CellEffort::PLAN.with_slack(slack / open.max(1) as f64);
        let mut total = 0.0f64;
        for (i, o) in s.obstacles.iter().enumerate() {
            let b = if cleared[i] {
                reaches[i].as_ref().unwrap().cleared_bound()
            } else {
                cells_path_risk_in(o.contour.get(), &refs, &boxes, &frames[i], reaches[i].as_deref(), effort, &|| {
                    false
                })?
                .bound
            };
            total = add_up(total, b);
            if total >= 1.0 {
                return Some(1.0);
            }
        }
        Some(total)
    };
    let (mut compared, mut failed) = (0, 0);
    for seed in 1..=4 {
        let req = riskplan_app::PlanRequest { seed, ..Default::default() };
        let (problem, out) = req.run(&kernel, None).expect("plan");
        let Some(traj) = out.trajectory.as_ref() else { continue };
        let slack = riskplan_app::WHOLE_PATH_SLACK_SHARE * problem.delta.floor_f64();
        let truth = alone(&traj.pieces, slack);
        assert!(truth.is_some(), "seed {seed}: a bound");
        let new = || Arc::new(WholePathWork::new(kernel.clone(), traj.pieces.clone(), CellEffort::PLAN, slack, false));
        // a helper racing the plan's own thread; each waits (at most 2 s) in its first
        // partition until the other has begun one, so both bound obstacles when there are
        // two to bound
        let work = new();
        let (to_plan, plan_hears) = std::sync::mpsc::channel::<()>();
        let (to_helper, helper_hears) = std::sync::mpsc::channel::<()>();
        let meet = |tell: std::sync::mpsc::Sender<()>, hear: std::sync::mpsc::Receiver<()>| {
            let first = std::sync::atomic::AtomicBool::new(true);
            move || {
                if first.swap(false, std::sync::atomic::Ordering::Relaxed) {
                    let _ = tell.send(());
                    let _ = hear.recv_timeout(std::time::Duration::from_secs(2));
                }
                false
            }
        };
        let helper = {
            let w = work.clone();
            let stop = meet(to_plan, helper_hears);
            std::thread::spawn(move || w.run(&stop))
        };
        let shared = work.finish(&meet(to_helper, plan_hears)).expect("not stopped");
        helper.join().expect("the helper ends");
        assert_eq!(shared, truth, "seed {seed}: two threads");
        // a helper stopped at once, and one that fails: what they claimed is bounded again
        let work = new();
        let w = work.clone();
        std::thread::spawn(move || w.run(&|| true)).join().expect("the helper ends");
        assert_eq!(work.finish(&|| false).expect("not stopped"), truth, "seed {seed}: helper stopped");
        let work = new();
        let w = work.clone();
        failed += usize::from(std::thread::spawn(move || w.run(&|| panic!("a failing helper"))).join().is_err());
        assert_eq!(work.finish(&|| false).expect("not stopped"), truth, "seed {seed}: helper failed");
        // the plan stopped: never a smaller bound
        let stopped = new().finish(&|| true);
        assert!(stopped.is_err() || stopped == Ok(truth), "seed {seed}: stopped gave {stopped:?}");
        // a helper done before the plan joins (the plan only adds up)
        let work = new();
        let w = work.clone();
        std::thread::spawn(move || w.run(&|| false)).join().expect("the helper ends");
        assert_eq!(work.finish(&|| false).expect("not stopped"), truth, "seed {seed}: helper first");
        // no helper
        assert_eq!(new().finish(&|| false).expect("not stopped"), truth, "seed {seed}: alone");
        compared += 1;
    }
    assert!(compared >= 3, "only {compared} plans compared");
    assert!(failed >= 1, "no helper failed: the failing case was never tried");
}
