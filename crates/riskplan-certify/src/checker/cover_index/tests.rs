use super::*;
use proptest::prelude::*;

/// A part of a piece in the marking test: its box (per axis) and its time interval.
type MarkingPart = (Vec<(f64, f64)>, (f64, f64));

proptest! {
    /// The parts' boxes cover the piece: every sampled point of the curve, evaluated
    /// directly (exact rationals, no code of the boxes), lies in the box of a part
    /// whose time interval holds its time — the property that lets the motion checker
    /// drop an obstacle whose cover misses every part.
    #[test]
    fn sub_boxes_cover_the_piece(
        coeffs in prop::collection::vec(prop::collection::vec(-1e3f64..1e3, 1..4), 2),
        t0 in -10.0f64..10.0,
        len in 1e-6f64..20.0,
        k in 1usize..40,
    ) {
        let t1 = t0 + len;
        let pr = PieceRef { t0, t1, coeffs: &coeffs };
        let parts = piece_sub_boxes(pr, k).expect("boxes of a low-degree piece");
        prop_assert_eq!(parts.len(), k);
        prop_assert_eq!(parts[0].1 .0, t0);
        prop_assert_eq!(parts[k - 1].1 .1, t1);
        for w in parts.windows(2) {
            prop_assert_eq!(w[0].1 .1, w[1].1 .0);
        }
        use num_rational::BigRational;
        for s in 0..=64 {
            let t = if s == 64 { t1 } else { t0 + len * s as f64 / 64.0 };
            let t = t.clamp(t0, t1);
            let tq = BigRational::from_float(t).unwrap();
            let x: Vec<BigRational> = coeffs
                .iter()
                .map(|row| row.iter().rev().fold(BigRational::from_integer(0.into()), |acc, &c| acc * &tq + BigRational::from_float(c).unwrap()))
                .collect();
            let inside = parts.iter().any(|(b, (a, z))| {
                *a <= t && t <= *z
                    && b.iter().zip(&x).all(|(&(lo, hi), v)| {
                        BigRational::from_float(lo).unwrap() <= *v && *v <= BigRational::from_float(hi).unwrap()
                    })
            });
            prop_assert!(inside, "t = {}", t);
        }
    }
}

/// `n` disks of uncertain size and centre in a square of side `side` (every seventh
/// moving along x), from `rng`; the static ones' (index, centre x, centre y, radius).
fn marking_scene(n: usize, side: f64, rng: &mut rand_chacha::ChaCha8Rng) -> (Scene, Vec<(usize, f64, f64, f64)>) {
    use rand::Rng;
    let mut params = serde_json::Map::new();
    let mut obstacles = Vec::new();
    let mut disks = Vec::new();
    for k in 0..n {
        let (cx, cy, r): (f64, f64, f64) = (
            (rng.random_range(0.0..side) * 100.0f64).round() / 100.0,
            (rng.random_range(0.0..side) * 100.0f64).round() / 100.0,
            (rng.random_range(0.8..1.6) * 100.0f64).round() / 100.0,
        );
        params.insert(format!("s{k}"), serde_json::json!({"dist": "uniform", "low": 0.9, "high": 1.1}));
        params.insert(format!("d{k}"), serde_json::json!({"dist": "normal", "mean": 0, "std": 0.05}));
        if k % 7 == 3 {
            // moving along x at speed ~ 1 (no closed form kept for it)
            obstacles.push(serde_json::json!({"id": format!("m{k}"), "poly": format!("({r}*s{k})^2 - (x1 - {cx} - d{k} - t)^2 - (x2 - {cy})^2")}));
        } else {
            obstacles.push(serde_json::json!({"id": format!("disk{k}"), "poly": format!("({r}*s{k})^2 - (x1 - {cx} - d{k})^2 - (x2 - {cy})^2")}));
            disks.push((k, cx, cy, r));
        }
    }
    let text = serde_json::json!({
        "format": "riskplan-scene/1", "name": "marking", "dim": 2,
        "workspace": {"lower": [0, 0], "upper": [side, side]}, "horizon": [0, 1], "risk": 0.05,
        "params": params, "obstacles": obstacles,
    })
    .to_string();
    (riskplan_scene::Scene::from_json(&text).unwrap(), disks)
}

/// Covers built on several threads are those one thread builds, obstacle for obstacle
/// (static and moving ones), and so is the grid; a build stopped on several threads
/// leaves no grid, and a later call completes it.
#[test]
fn covers_built_on_several_threads_are_the_ones_built_on_one() {
    use rand::SeedableRng;
    let n = PARALLEL_COVERS_MIN + 9;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let (scene, _) = marking_scene(n, 4.0 * (n as f64).sqrt() + 4.0, &mut rng);
    let deltas = vec![scene.risk.clone(); n];
    let one = SceneIndex::lazy(&scene, &deltas, &[]);
    one.ensure_all_on(&scene, &|| false, 1);
    let covers = |ix: &SceneIndex| -> Vec<String> { ix.covers.iter().map(|c| format!("{:?}", c.get())).collect() };
    for threads in [2, 3, MAX_COVER_BUILD_THREADS + 2] {
        let many = SceneIndex::lazy(&scene, &deltas, &[]);
        many.ensure_all_on(&scene, &|| false, threads);
        assert!(many.complete());
        assert_eq!(covers(&many), covers(&one), "{threads} threads");
        assert_eq!(format!("{:?}", many.grid.get()), format!("{:?}", one.grid.get()));
        assert_eq!(many.cells(), one.cells());
    }
    // stopped after a few obstacles (every thread asks the same `stop`): incomplete, no
    // grid; completed by a later call
    let stopped = SceneIndex::lazy(&scene, &deltas, &[]);
    let asked = std::sync::atomic::AtomicUsize::new(0);
    stopped.ensure_all_on(&scene, &|| asked.fetch_add(1, std::sync::atomic::Ordering::Relaxed) >= 5, 2);
    assert!(stopped.covers.iter().filter(|c| c.get().is_some()).count() <= 5);
    assert!(!stopped.complete());
    assert!(stopped.grid.get().is_none());
    stopped.ensure_all_on(&scene, &|| false, 2);
    assert_eq!(covers(&stopped), covers(&one));
}

/// Marking the parts of a piece into one set gives exactly the union over the
/// parts of the obstacles not proven skippable for that part (naive filter per part,
/// no bitset, no grid), on scene sizes around the 64-bit word boundaries, with moving
/// obstacles and parts outside the horizon; and every disk a part's box meets at
/// its certain-collision radius (closed form) is among them.
#[test]
fn marked_parts_are_the_union_of_the_parts_candidates() {
    use rand::{Rng, SeedableRng};
    for (n, seed) in [(1usize, 1u64), (15, 2), (16, 3), (63, 4), (64, 5), (65, 6), (129, 7)] {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let side = 4.0 * (n as f64).sqrt() + 4.0;
        let (scene, disks) = marking_scene(n, side, &mut rng);
        let deltas = vec![scene.risk.clone(); n];
        let index = SceneIndex::build(&scene, &deltas, &|| false);
        assert!(index.complete());
        assert_eq!(index.grid.get().is_some(), n >= GRID_MIN_OBSTACLES);
        let (mut nonempty, mut partial) = (0, 0);
        for _ in 0..400 {
            let k = rng.random_range(1..7);
            let parts: Vec<MarkingPart> = (0..k)
                .map(|_| {
                    let w: f64 = rng.random_range(0.0..3.0);
                    let (x, y) = (rng.random_range(0.0..side - w), rng.random_range(0.0..side - w));
                    let t0: f64 = if rng.random_bool(0.05) { -0.5 } else { rng.random_range(0.0..1.0) };
                    let t1 = if rng.random_bool(0.05) { 1.5 } else { rng.random_range(t0.max(0.0)..=1.0) };
                    (vec![(x, x + w * rng.random_range(0.0..1.0)), (y, y + w)], (t0, t1))
                })
                .collect();
            let mut set = index.candidate_set();
            for (b, (a, z)) in &parts {
                index.mark_candidates(Some(b), *a, *z, &mut set);
            }
            let mut got = Vec::new();
            set.emit(&mut got);
            let mut want: Vec<usize> = (0..n)
                .filter(|&i| {
                    parts.iter().any(|(b, (a, z))| {
                        let in_h = 0.0 <= *a && a <= z && *z <= 1.0;
                        !in_h || !index.skippable(i, b, *a, *z)
                    })
                })
                .collect();
            want.sort_unstable();
            assert_eq!(got, want, "n = {n}, parts {parts:?}");
            // one part at a time, through `candidates`, united
            let mut united: Vec<usize> = Vec::new();
            let mut one = vec![usize::MAX; 3];
            for (b, (a, z)) in &parts {
                index.candidates(Some(b), *a, *z, &mut one);
                assert!(one.windows(2).all(|w| w[0] < w[1]));
                united.extend(&one);
            }
            united.sort_unstable();
            united.dedup();
            assert_eq!(got, united);
            for &(i, cx, cy, r) in &disks {
                let meets = parts.iter().any(|(b, _)| {
                    let dx = (b[0].0 - cx).max(cx - b[0].1).max(0.0);
                    let dy = (b[1].0 - cy).max(cy - b[1].1).max(0.0);
                    (dx * dx + dy * dy).sqrt() < 0.9 * r - 0.25
                });
                assert!(!meets || got.contains(&i), "disk {i} met but not a candidate (n = {n})");
            }
            nonempty += (!got.is_empty()) as usize;
            partial += (got.len() < n) as usize;
        }
        assert!(nonempty > 50 && partial > 50, "n = {n}: {nonempty} nonempty, {partial} partial");
    }
}
