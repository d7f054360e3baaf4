use super::*;
use proptest::prelude::*;
use std::sync::OnceLock;

/// A scene, its grid, and its disks' nominal centres.
type Crowded = (Scene, NearGrid, Vec<(f64, f64)>);

/// 96 uncertain disks (radius scaled by s ~ U(0.9, 1.1), centre shifted by d ~ N(0, 0.05))
/// at constant density in a square 10·√96 wide, and the grid at Δ = 0.05.
fn crowded() -> &'static Crowded {
    static S: OnceLock<Crowded> = OnceLock::new();
    S.get_or_init(|| {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let n = 96;
        let side = 10.0 * (n as f64).sqrt();
        let mut params = serde_json::Map::new();
        let mut obstacles = Vec::new();
        let mut centres = Vec::new();
        for k in 0..n {
            let (cx, cy, r): (f64, f64, f64) =
                (rng.random_range(0.0..side), rng.random_range(0.0..side), rng.random_range(0.8..1.6));
            centres.push((cx, cy));
            params.insert(format!("s{k}"), serde_json::json!({"dist": "uniform", "low": 0.9, "high": 1.1}));
            params.insert(format!("d{k}"), serde_json::json!({"dist": "normal", "mean": 0, "std": 0.05}));
            obstacles.push(serde_json::json!({
                "id": format!("disk{k}"),
                "poly": format!("({r}*s{k})^2 - (x1 - {cx} - d{k})^2 - (x2 - {cy})^2"),
            }));
        }
        let text = serde_json::json!({
            "format": "riskplan-scene/1", "name": "crowded", "dim": 2,
            "workspace": {"lower": [0, 0], "upper": [side, side]}, "horizon": [0, 1], "risk": 0.05,
            "params": params, "obstacles": obstacles,
        })
        .to_string();
        let scene = Scene::from_json(&text).unwrap();
        let framed = FramedContours::new(&scene);
        let near = framed.near(&scene, &|| false).unwrap().expect("box tests on 96 disks");
        let deltas = vec![scene.risk.clone(); n];
        let grid = NearGrid::build(&scene, near, &deltas, None, &|| false).unwrap().expect("a grid worth building");
        (scene, grid, centres)
    })
}

/// Distance from a disk's centre beyond which the test's disks are safe (see below).
const FAR: f64 = 8.0;

/// Sampled times per piece.
const SAMPLES: usize = 64;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    /// Every obstacle the grid leaves out of a piece's candidates is safe at every sampled
    /// point of the piece, by exact rational evaluation of E[P] and E[P²] (no code of the
    /// grid or of the box tests): E[P] < 0 and E[P]² − (1 − Δ)·E[P²] > 0 (eq. 15). Points
    /// farther than [`FAR`] from a disk's centre are safe by its geometry (radius at most
    /// 1.6·1.1, a centre within a few 0.05 of nominal: Cantelli holds beyond about three
    /// radii) and are not evaluated.
    #[test]
    fn obstacles_left_out_by_the_grid_are_safe_on_the_piece(
        a in prop::collection::vec(0.0f64..1.0, 2),
        b in prop::collection::vec(0.0f64..1.0, 2),
        bend in prop::collection::vec(-0.2f64..0.2, 2),
        t0 in 0.0f64..0.5,
        len in 1e-3f64..0.5,
    ) {
        let side = crowded().0.workspace.upper[0];
        let p: Vec<f64> = a.iter().map(|v| v * side).collect();
        let q: Vec<f64> = b.iter().map(|v| v * side).collect();
        let c: Vec<f64> = bend.iter().map(|v| v * side).collect();
        check_left_out(&p, &q, &c, t0, len)?;
    }

    /// The same on short pieces near an obstacle, sampled densely: where the thin ring
    /// in which E[P] < 0 but Cantelli fails lies (a box test that dropped the variance
    /// term clears cells there).
    #[test]
    fn obstacles_left_out_near_a_piece_are_safe_on_it(
        k in 0usize..96,
        a in prop::collection::vec(-4.0f64..4.0, 2),
        dir in prop::collection::vec(-3.0f64..3.0, 2),
        bend in prop::collection::vec(-0.5f64..0.5, 2),
        t0 in 0.0f64..0.5,
        len in 1e-3f64..0.5,
    ) {
        let centre = crowded().2[k];
        let p = vec![centre.0 + a[0], centre.1 + a[1]];
        let q = vec![p[0] + dir[0], p[1] + dir[1]];
        check_left_out(&p, &q, &bend, t0, len)?;
    }
}

/// Every obstacle the grid leaves out of the quadratic from `p` to `q` bent by `c` over
/// `[t0, t0 + len]` is safe at its sampled points inside the workspace (exact rationals).
fn check_left_out(p: &[f64], q: &[f64], c: &[f64], t0: f64, len: f64) -> Result<(), TestCaseError> {
    {
        use num_rational::BigRational;
        let (scene, grid, centres) = crowded();
        let side = scene.workspace.upper[0];
        let t1 = t0 + len;
        // a quadratic from p to q, local τ in [0, 1], written in absolute time t:
        // x(t) = p0 + p1·τ + p2·τ², τ = (t − t0)/len
        let coeffs: Vec<Vec<f64>> = (0..2)
            .map(|d| {
                let (p, q, c) = (p[d], q[d], c[d]);
                let (p0, p1, p2) = (p, q - p + c, -c);
                // in t: p0 + p1 (t − t0)/len + p2 (t − t0)²/len²
                let (u, v) = (1.0 / len, 1.0 / (len * len));
                vec![p0 - p1 * t0 * u + p2 * t0 * t0 * v, p1 * u - 2.0 * p2 * t0 * v, p2 * v]
            })
            .collect();
        let pr = PieceRef { t0, t1, coeffs: &coeffs };
        let Some(cands) = grid.candidates(pr) else { return Ok(()) };
        let delta = scene.risk.rational();
        let omd = BigRational::from_integer(1.into()) - delta;
        let zero = BigRational::from_integer(0.into());
        for (i, o) in scene.obstacles.iter().enumerate() {
            if cands.binary_search(&i).is_ok() {
                continue;
            }
            for s in 0..=SAMPLES {
                let t = (t0 + len * s as f64 / SAMPLES as f64).clamp(t0, t1);
                let at: Vec<f64> = coeffs.iter().map(|row| row.iter().rev().fold(0.0, |acc, &c| acc * t + c)).collect();
                if (at[0] - centres[i].0).hypot(at[1] - centres[i].1) > FAR {
                    continue;
                }
                let tq = BigRational::from_float(t).unwrap();
                let mut x: Vec<BigRational> = coeffs
                    .iter()
                    .map(|row| {
                        row.iter().rev().fold(zero.clone(), |acc, &c| acc * &tq + BigRational::from_float(c).unwrap())
                    })
                    .collect();
                // a point outside the workspace is not what the grid speaks of
                if x.iter().any(|v| *v < zero || *v > BigRational::from_float(side).unwrap()) {
                    continue;
                }
                x.push(tq);
                let m = o.contour.mean.eval(&x);
                let m2 = o.contour.second.eval(&x);
                prop_assert!(m < zero, "obstacle {} left out, E[P] = {} at t = {}", i, m, t);
                prop_assert!(&m * &m - &omd * &m2 > zero, "obstacle {} left out, Cantelli fails at t = {}", i, t);
            }
        }
    }
    Ok(())
}

/// Every cell that leaves an obstacle out is safe from it everywhere: a 16 × 16 lattice of
/// points of each such cell near the obstacle (edges included), its E[P] and E[P²] in
/// floating point, and wherever either constraint is not clearly met (a margin far above
/// the rounding of these small polynomials), exactly in rationals. Fails when the box
/// test drops its variance term (it then clears cells that the ring between E[P] = 0 and
/// the Cantelli contour crosses).
#[test]
fn cleared_cells_are_safe_everywhere_in_them() {
    use num_rational::BigRational;
    let (scene, grid, centres) = crowded();
    let n = grid.per_axis;
    let one = BigRational::from_integer(1.into());
    let zero = BigRational::from_integer(0.into());
    let omd_q = &one - scene.risk.rational();
    let omd = 1.0 - scene.risk.to_f64();
    const LATTICE: usize = 16;
    const MARGIN: f64 = 1e-6;
    let mut exact_checks = 0;
    for (i, o) in scene.obstacles.iter().enumerate() {
        if grid.always.contains(&(i as u32)) {
            continue;
        }
        for cx in 0..n {
            for cy in 0..n {
                let cell = grid.cell_index(&[cx, cy]);
                if grid.cells[cell].contains(&(i as u32)) {
                    continue;
                }
                let (x0, x1, y0, y1) =
                    (grid.edges[0][cx], grid.edges[0][cx + 1], grid.edges[1][cy], grid.edges[1][cy + 1]);
                let nearest =
                    (centres[i].0.clamp(x0, x1) - centres[i].0).hypot(centres[i].1.clamp(y0, y1) - centres[i].1);
                if nearest > FAR {
                    continue;
                }
                for a in 0..=LATTICE {
                    for b in 0..=LATTICE {
                        let x = if a == LATTICE { x1 } else { x0 + (x1 - x0) * a as f64 / LATTICE as f64 };
                        let y = if b == LATTICE { y1 } else { y0 + (y1 - y0) * b as f64 / LATTICE as f64 };
                        let (m, m2) = o.contour.moments_f64(&[x, y, 0.5]);
                        let scale = m2.abs().max(1.0);
                        if m < -MARGIN * scale && m * m - omd * m2 > MARGIN * scale * scale {
                            continue;
                        }
                        exact_checks += 1;
                        let v: Vec<BigRational> =
                            [x, y, 0.5].iter().map(|&c| BigRational::from_float(c).unwrap()).collect();
                        let (mq, m2q) = (o.contour.mean.eval(&v), o.contour.second.eval(&v));
                        assert!(mq < zero, "obstacle {i} left out of cell ({cx}, {cy}): E[P] = {mq} at ({x}, {y})");
                        assert!(
                            &mq * &mq - &omd_q * &m2q > zero,
                            "obstacle {i} left out of cell ({cx}, {cy}): Cantelli fails at ({x}, {y})"
                        );
                    }
                }
            }
        }
    }
    println!("{exact_checks} lattice points decided exactly");
}

/// The grid leaves out most obstacles of a short piece (else it would not pay), and keeps
/// the obstacle a piece runs through.
#[test]
fn the_grid_keeps_what_a_piece_meets_and_drops_the_rest() {
    let (scene, grid, _) = crowded();
    let o = &scene.obstacles[0];
    // obstacle 0's centre: where its mean is largest on its box-test point
    let c = obstacle_point(scene, 0);
    let coeffs = vec![vec![c[0] - 0.5, 1.0], vec![c[1], 0.0]];
    let pr = PieceRef { t0: 0.0, t1: 1.0, coeffs: &coeffs };
    let cands = grid.candidates(pr).expect("a piece inside the grid");
    assert!(cands.contains(&0), "{}: {cands:?}", o.id);
    assert!(cands.len() < scene.obstacles.len() / 4, "{} candidates of {}", cands.len(), scene.obstacles.len());
}

fn obstacle_point(scene: &Scene, i: usize) -> Vec<f64> {
    let ws = &scene.workspace;
    let region = vec![(ws.lower[0], ws.upper[0]), (ws.lower[1], ws.upper[1]), scene.horizon];
    crate::checker::cover_index::obstacle_center(&scene.obstacles[i].contour, &region)
}
