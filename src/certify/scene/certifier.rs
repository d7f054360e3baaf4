//! The scene certifier: the continuous-time certifier as a planner's motion checker
//! (docs/design.md §5.9, §5.10).

use super::decide::{combine, decide_obstacle, point_obstacle_safe_at, point_status, Method, PointStatus, Status};
use super::framed::piece_passes_verify_path;
use super::index::{piece_bbox, SceneIndex};
use super::kernel::{CompiledSet, SceneKernel};
use super::workspace::check_workspace;
use crate::certify::fast::{straight_value_sign, Substitution};
use crate::certify::bounds::{Level, PieceBounds};
use crate::certify::{bernstein, restrict_exact, sos, tail, PieceRef, Verdict};
use crate::contour::tail::tail_kappa;
use crate::contour::{BoundChoice, RiskLevel};
use crate::motion::{Motion, MotionChecker, Termination};
use crate::poly::Interval;
use crate::scene::{Piece, Scene};
use num_rational::BigRational;
use std::sync::{Arc, OnceLock};

/// The continuous-time certifier as a planner's motion checker: a piece is accepted
/// only when every constraint of every obstacle is proven positive on the piece and
/// the piece stays in the workspace. Stops at the first failure; the lower-degree
/// mean constraint is tried first.
///
/// Fast path (docs/design.md §5.10): the workspace is proven from the piece's
/// Bernstein bounding box (exact check otherwise); obstacles whose proven cover the
/// box misses are skipped ([`SceneIndex`]); the rest are decided on the compiled
/// restriction, with the exact rational fallback for undecided cases.
///
/// Each obstacle may have its own risk level Δᵢ (the joint risk mode: Σ Δᵢ = Δ bounds
/// the probability of colliding with any obstacle, by Boole's inequality).
#[derive(Debug)]
pub struct SceneCertifier {
    kernel: SceneKernel,
    scene: Arc<Scene>,
    deltas: Vec<RiskLevel>,
    one_minus: Vec<(f64, bool)>,
    method: Method,
    settings: sos::SosSettings,
    compiled: Arc<CompiledSet>,
    index: OnceLock<Arc<SceneIndex>>,
    /// Whether the fast path (covers, compiled restriction) is used; without it every
    /// obstacle is decided on every piece by the verify path (the final check's).
    fast: bool,
    /// Which bounds may prove a piece (docs/design.md §5.13).
    bounds: BoundChoice,
    /// Each obstacle's Δᵢ as the cover search uses it, converted once.
    levels: Vec<Level>,
    /// Each pedestrian's tail threshold κ at its Δᵢ (docs/design.md §3.11).
    kappas: Vec<Option<f64>>,
}

impl SceneCertifier {
    /// A certifier for a scene (or its [`SceneKernel`], to share what it caches) at risk
    /// `delta` for every obstacle.
    pub fn new(scene: impl Into<SceneKernel>, delta: RiskLevel, method: Method) -> Self {
        let kernel = scene.into();
        let deltas = vec![delta; kernel.scene().obstacles.len()];
        Self::with_deltas(kernel, deltas, method)
    }

    /// A certifier with one risk level per obstacle (`deltas[i]` for obstacle `i`).
    pub fn with_deltas(scene: impl Into<SceneKernel>, deltas: Vec<RiskLevel>, method: Method) -> Self {
        let kernel = scene.into();
        let scene = kernel.scene().clone();
        assert_eq!(deltas.len(), scene.obstacles.len(), "one risk level per obstacle");
        let one_minus = deltas
            .iter()
            .map(|d| {
                let q = BigRational::from_integer(1.into()) - d.rational();
                let f = crate::poly::rational_to_f64(&q);
                (f, BigRational::from_float(f).is_some_and(|e| e == q))
            })
            .collect();
        let compiled = kernel.compiled();
        let levels = deltas.iter().map(|d| Level::new(d.rational())).collect();
        let kappas = scene
            .obstacles
            .iter()
            .zip(&deltas)
            .map(|(o, d)| o.pedestrian.as_ref().and_then(|p| tail_kappa(p.disk.dim(), d.rational())))
            .collect();
        SceneCertifier {
            kernel,
            scene,
            deltas,
            one_minus,
            method,
            settings: sos::SosSettings::default(),
            compiled,
            index: OnceLock::new(),
            fast: true,
            bounds: BoundChoice::default(),
            levels,
            kappas,
        }
    }

    /// The same certifier with another choice of bounds (`auto` by default).
    pub fn with_bounds(mut self, bounds: BoundChoice) -> Self {
        self.bounds = bounds;
        self
    }

    /// The bounds it may use.
    pub fn bounds(&self) -> BoundChoice {
        self.bounds
    }

    /// The same certifier without the fast path: every obstacle on every piece by the
    /// verify path (general interval composition, exact fallback) — what a plan is
    /// re-planned with after the final check disagreed with the fast path
    /// (docs/design.md §5.12).
    pub fn without_fast_path(mut self) -> Self {
        self.fast = false;
        self
    }

    /// A certifier that does not build covers for its own use: it uses the scene's
    /// cached index when there is one and otherwise checks every obstacle on every
    /// piece (sound either way). For planners that check a handful of pieces, for
    /// which building the covers (milliseconds per moving obstacle) would cost more
    /// than it saves.
    pub fn without_index_build(self) -> Self {
        let index = self
            .kernel
            .peek_index(&self.deltas)
            .unwrap_or_else(|| Arc::new(SceneIndex::build(&self.scene, &self.deltas, &|| true)));
        let _ = self.index.set(index);
        self
    }

    /// The per-obstacle risk levels.
    pub fn deltas(&self) -> &[RiskLevel] {
        &self.deltas
    }

    /// The index, built (without interruption) if [`MotionChecker::prepare`] did not.
    pub fn index(&self) -> &Arc<SceneIndex> {
        self.index.get_or_init(|| self.kernel.index(&self.deltas, &|| false))
    }

    /// Whether obstacle `i` is proven safe on a piece (Exact method, fast path; `subs`:
    /// the piece's centred coordinates, shared by all obstacles). When Cantelli's
    /// constraints fail only in g₁ and the bounds are `auto`, the piece may still be
    /// covered by sub-intervals proven by other bounds (docs/design.md §5.13).
    fn obstacle_safe(&self, i: usize, pr: PieceRef<'_>, subs: Option<&Substitution>) -> bool {
        let o = &self.scene.obstacles[i];
        if let (Some(p), true) = (&o.pedestrian, self.bounds.beyond_cantelli()) {
            // a pedestrian: its Gaussian tail bound (docs/design.md §3.11)
            return self.kappas[i].is_some_and(|k| tail::piece_clear(&p.disk, k, pr).is_safe());
        }
        let delta = self.deltas[i].rational();
        // Cantelli: Ok(()) proven; Err(None) g₂ fails (E[P] ≥ 0 somewhere: no bound can
        // help); Err(Some(hint)) only g₁ fails or is undecided (hint: a local time, if known)
        // the fast path's enclosures of −E[P] and g₁ when g₁ fails there, for the other
        // bounds' search (the same polynomials it would restrict again)
        let mut restricted: Option<(Vec<Interval>, Vec<Interval>)> = None;
        let keep = self.bounds.beyond_cantelli() && self.fast;
        let cantelli: Result<(), Option<Option<f64>>> = 'cantelli: {
            if self.method == Method::Exact {
                let fast = subs.and_then(|subs| {
                    self.compiled.get(i).with_constraints(subs, self.one_minus[i], |g2, g1| {
                        for (k, g) in [g2, g1].into_iter().enumerate() {
                            match bernstein::check_interval_coeffs(g, bernstein::DEFAULT_MAX_DEPTH) {
                                Verdict::Safe { .. } => {}
                                Verdict::Unsafe(_) if k == 0 => return Some(Err(None)),
                                Verdict::Unsafe(w) => {
                                    if keep {
                                        restricted = Some((g2.to_vec(), g1.to_vec()));
                                    }
                                    return Some(Err(Some(Some(w.tau))));
                                }
                                Verdict::Undecided(_) => return None,
                            }
                        }
                        Some(Ok(()))
                    })
                });
                match fast {
                    Some(Some(v)) => break 'cantelli v,
                    Some(None) => {
                        // undecided in floats: the exact rational check decides both constraints
                        let r = restrict_exact(&o.contour, pr, delta);
                        break 'cantelli match bernstein::check_exact(&r.mean, bernstein::DEFAULT_MAX_DEPTH) {
                            Verdict::Safe { .. } => match bernstein::check_exact(&r.cantelli, bernstein::DEFAULT_MAX_DEPTH) {
                                Verdict::Safe { .. } => Ok(()),
                                Verdict::Unsafe(w) => Err(Some(Some(w.tau))),
                                Verdict::Undecided(_) => Err(Some(None)),
                            },
                            _ => Err(None),
                        };
                    }
                    None => {}
                }
            }
            let mut result = Ok(());
            decide_obstacle(o, Some(self.compiled.get(i)), pr, delta, self.method, &self.settings, |name, vs| {
                match combine(&vs) {
                    Status::Safe => true,
                    st => {
                        let hint = vs.iter().find_map(|(_, v)| if let Verdict::Unsafe(w) = v { Some(w.tau) } else { None });
                        result = if name == "mean" && st == Status::Unsafe { Err(None) } else { Err(Some(hint)) };
                        false
                    }
                }
            });
            result
        };
        match cantelli {
            Ok(()) => true,
            Err(Some(hint)) if self.bounds.beyond_cantelli() => {
                let pb = if self.fast {
                    PieceBounds::for_piece_compiled(&o.contour, self.compiled.get(i), pr, self.levels[i])
                        .with_substitution(subs)
                        .with_cantelli_restrictions(restricted)
                } else {
                    PieceBounds::for_piece(&o.contour, pr, self.levels[i])
                };
                pb.cover(hint).is_ok()
            }
            Err(_) => false,
        }
    }
}

/// Whether a coordinate of degree ≤ 1, `c0 + c1·t` on `[t0, t1]`, stays in `[l, u]`,
/// exactly (its extremes are its end values, evaluated in rationals): the float
/// enclosure of an edge that ends on the workspace boundary crosses it by rounding.
fn straight_coordinate_inside(c: &[f64], t0: f64, t1: f64, l: f64, u: f64) -> bool {
    if c.len() > 2 {
        return false;
    }
    // exactly in floating point by error-free transformations (rationals otherwise)
    let (c0, c1) = (c.first().copied().unwrap_or(0.0), c.get(1).copied().unwrap_or(0.0));
    let signs: Option<Vec<(std::cmp::Ordering, std::cmp::Ordering)>> = [t0, t1]
        .iter()
        .map(|&t| Some((straight_value_sign(c0, c1, t, l)?, straight_value_sign(c0, c1, t, u)?)))
        .collect();
    if let Some(signs) = signs {
        use std::cmp::Ordering::{Greater, Less};
        return signs.iter().all(|&(lo, hi)| lo != Less && hi != Greater);
    }
    let q = |v: f64| BigRational::from_float(v);
    let (Some(c0), Some(c1), Some(a), Some(b), Some(l), Some(u)) =
        (q(c.first().copied().unwrap_or(0.0)), q(c.get(1).copied().unwrap_or(0.0)), q(t0), q(t1), q(l), q(u))
    else {
        return false;
    };
    [a, b].iter().all(|t| {
        let x = &c0 + &c1 * t;
        l <= x && x <= u
    })
}

impl MotionChecker for SceneCertifier {
    fn name(&self) -> &str {
        self.method.as_str()
    }

    fn sound(&self) -> bool {
        true
    }

    fn prepare(&self, term: &Termination) {
        if !self.fast {
            return;
        }
        let _ = self.index.get_or_init(|| self.kernel.index(&self.deltas, &|| term.expired()));
    }

    fn check(&self, piece: &Piece) -> Motion {
        let pr = PieceRef { t0: piece.t0, t1: piece.t1, coeffs: &piece.coeffs };
        if !pr.is_finite() {
            return Motion::Rejected;
        }
        if !self.fast {
            return if piece_passes_verify_path(
                &self.scene,
                &self.kernel.framed(),
                None,
                pr,
                &self.deltas,
                self.bounds,
                Some(&self.compiled),
            ) {
                Motion::Accepted
            } else {
                Motion::Rejected
            };
        }
        let ws = &self.scene.workspace;
        let bbox = piece_bbox(pr);
        let inside = bbox.as_ref().is_some_and(|b| {
            b.iter().zip(ws.lower.iter().zip(&ws.upper)).enumerate().all(|(d, (&(lo, hi), (&l, &u)))| {
                (l <= lo && hi <= u) || straight_coordinate_inside(&piece.coeffs[d], piece.t0, piece.t1, l, u)
            })
        });
        if !inside && check_workspace(&ws.lower, &ws.upper, pr).status != Status::Safe {
            return Motion::Rejected;
        }
        let mut cands = Vec::new();
        self.index().candidates(bbox.as_deref(), piece.t0, piece.t1, &mut cands);
        // the compiled substitution, for the candidates that use it (not the pedestrians
        // decided by their tail bound)
        let tail_only = self.bounds.beyond_cantelli();
        let needs_subs = cands.iter().any(|&i| !(tail_only && self.scene.obstacles[i].pedestrian.is_some()));
        let subs = if needs_subs { Substitution::new(pr, self.compiled.frame()) } else { None };
        for i in cands {
            if !self.obstacle_safe(i, pr, subs.as_ref()) {
                return Motion::Rejected;
            }
        }
        Motion::Accepted
    }

    fn blocking_obstacle(&self, x: &[f64], t: f64) -> Option<String> {
        match point_status(&self.scene, x, t, &self.deltas, self.bounds) {
            PointStatus::InContour(i) => Some(self.scene.obstacles[i].id.clone()),
            _ => None,
        }
    }

    fn check_point(&self, x: &[f64], t: f64) -> Motion {
        if !self.scene.workspace.contains(x) {
            return Motion::Rejected;
        }
        // obstacles whose proven cover misses the point are safe there; the others are
        // decided exactly
        let bbox: Vec<(f64, f64)> = x.iter().map(|&v| (v, v)).collect();
        let mut cands = Vec::new();
        if self.fast {
            self.index().candidates(Some(&bbox), t, t, &mut cands);
        } else {
            cands.extend(0..self.scene.obstacles.len());
        }
        let Some(mut xt) = x.iter().map(|&v| BigRational::from_float(v)).collect::<Option<Vec<_>>>() else {
            return Motion::Rejected;
        };
        let Some(tq) = BigRational::from_float(t) else { return Motion::Rejected };
        xt.push(tq);
        let mut xf = x.to_vec();
        xf.push(t);
        for i in cands {
            let compiled =
                (self.fast && self.scene.obstacles[i].pedestrian.is_none()).then(|| (self.compiled.get(i), &xf[..]));
            if !point_obstacle_safe_at(&self.scene.obstacles[i], &xt, &self.deltas[i], Some(self.levels[i]), compiled, self.bounds)
            {
                return Motion::Rejected;
            }
        }
        Motion::Accepted
    }
}
