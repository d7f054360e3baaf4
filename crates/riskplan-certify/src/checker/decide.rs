//! Deciding one obstacle's constraints over one piece (docs/design.md §5.2, §5.9): the
//! methods, the three-valued status, and the exact status of a point.

use crate::compiled::{CompiledContour, Substitution};
use crate::piece_bounds::{Level, PieceBounds};
use crate::{positivity::bernstein, positivity::sos, restrict_exact, restrict_interval, PieceRef, Verdict};
use num_rational::BigRational;
use num_traits::Signed;
use riskplan_math::contour::{BoundChoice, RiskLevel};
use riskplan_math::poly::{Interval, UPoly};
use riskplan_scene::{Obstacle, Scene};
use serde::{Deserialize, Serialize};

/// Which method decides positivity: `exact`, `sos` or `both` (serde and JSON Schema by
/// [`riskplan_scene::closed_set!`]: its `as_str` names, read through `FromStr`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Method {
    /// The SOS certificate of eq. (15) on Clarabel, re-checked rigorously.
    Sos,
    /// Bernstein subdivision in interval arithmetic with an exact fallback (the default).
    #[default]
    Exact,
    /// Both; safe only when both prove it.
    Both,
}

impl std::str::FromStr for Method {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "sos" => Ok(Method::Sos),
            "exact" => Ok(Method::Exact),
            "both" => Ok(Method::Both),
            _ => Err(format!("unknown method '{s}' (expected sos, exact or both)")),
        }
    }
}

riskplan_scene::closed_set!(Method, "Method");

impl Method {
    /// Every method, in the order help texts and schemas list them.
    pub const ALL: [Method; 3] = [Method::Exact, Method::Sos, Method::Both];

    /// The name used in requests and reports.
    pub fn as_str(&self) -> &'static str {
        match self {
            Method::Sos => "sos",
            Method::Exact => "exact",
            Method::Both => "both",
        }
    }
}

/// `safe`, `unsafe` or `undecided`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[schemars(inline)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    /// Proven safe.
    Safe,
    /// Proven unsafe (with a witness).
    Unsafe,
    /// Not proven either way: never counts as safe.
    Undecided,
}

/// A time at which a constraint is ≤ 0 (absolute time) and the constraint's value there.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct WitnessReport {
    /// Absolute time.
    pub t: f64,
    /// Constraint value there (≤ 0, proven).
    pub value: f64,
}

/// Decides one restricted constraint with `method`.
pub fn decide(
    method: Method,
    p: &UPoly<Interval>,
    exact: &dyn Fn() -> UPoly<BigRational>,
    sos_settings: &sos::SosSettings,
) -> Vec<(&'static str, Verdict)> {
    match method {
        Method::Exact => vec![("exact", bernstein::check(p, exact))],
        Method::Sos => vec![("sos", sos::certify(p, sos_settings).verdict)],
        Method::Both => vec![("exact", bernstein::check(p, exact)), ("sos", sos::certify(p, sos_settings).verdict)],
    }
}

pub fn combine(vs: &[(&'static str, Verdict)]) -> Status {
    if vs.iter().any(|(_, v)| v.is_unsafe()) {
        Status::Unsafe
    } else if vs.iter().all(|(_, v)| v.is_safe()) {
        Status::Safe
    } else {
        Status::Undecided
    }
}

pub fn worst(a: Status, b: Status) -> Status {
    match (a, b) {
        (Status::Unsafe, _) | (_, Status::Unsafe) => Status::Unsafe,
        (Status::Undecided, _) | (_, Status::Undecided) => Status::Undecided,
        _ => Status::Safe,
    }
}

/// Decides an obstacle's two constraints over a piece in order (`mean`, the lower
/// degree, first; then `cantelli`) and hands each decision to `visit`, which returns
/// whether to go on. The interval restriction is built once — from the compiled,
/// centred contour when given and within its capacity (in `f64` with a running error
/// bound when `fast` gives the piece's [`Substitution`] and `1−Δ` as the nearest float
/// and whether it is exact, as the motion checker does), else by general composition —
/// and the exact one only if a decision needs the exact fallback, then once for both.
#[allow(clippy::too_many_arguments)]
pub fn decide_obstacle(
    o: &Obstacle,
    compiled: Option<&CompiledContour>,
    fast: Option<(&Substitution, (f64, bool))>,
    piece: PieceRef<'_>,
    delta: &BigRational,
    method: Method,
    settings: &sos::SosSettings,
    mut visit: impl FnMut(&'static str, Vec<(&'static str, Verdict)>) -> bool,
) {
    let restricted = compiled.and_then(|c| {
        fast.and_then(|(subs, omd)| {
            c.with_constraints(subs, omd, |g2, g1| (UPoly::new(g1.to_vec()), UPoly::new(g2.to_vec())))
        })
        .or_else(|| {
            let omd = Interval::enclose_rational(&(BigRational::from_integer(1.into()) - delta));
            let (g1, g2) = c.restrict(piece)?.constraints(omd)?;
            Some((UPoly::new(g1.coeffs().to_vec()), UPoly::new(g2.coeffs().to_vec())))
        })
    });
    let (cantelli, mean) = match restricted {
        Some(r) => r,
        None => {
            let iv = restrict_interval(&o.contour, piece, delta);
            (iv.cantelli, iv.mean)
        }
    };
    let exact = std::cell::OnceCell::new();
    for (name, poly) in [("mean", &mean), ("cantelli", &cantelli)] {
        let ex = || {
            let r = exact.get_or_init(|| restrict_exact(&o.contour, piece, delta));
            if name == "mean" {
                r.mean.clone()
            } else {
                r.cantelli.clone()
            }
        };
        if !visit(name, decide(method, poly, &ex, settings)) {
            return;
        }
    }
}

/// `verify` stopped by its caller (a deadline or a cancellation): no verdict.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Interrupted;

/// Whether `x` at time `t` is strictly inside every Δ-contour (g1 > 0 and g2 > 0,
/// exactly) or proven safe by another bound (`auto`, docs/design.md §3.10), and inside the
/// workspace.
pub fn point_safe(scene: &Scene, x: &[f64], t: f64, delta: &RiskLevel) -> bool {
    point_safe_with(scene, x, t, &vec![delta.clone(); scene.obstacles.len()])
}

/// Where a point stands at one instant (docs/design.md §3.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PointStatus {
    /// Inside the workspace and proven below every Δᵢ.
    Safe,
    /// Outside the workspace box, or not finite.
    OutsideWorkspace,
    /// Not proven below Δᵢ for obstacle `i` (the first such obstacle): on or outside its
    /// Δᵢ-contour for every bound allowed.
    InContour(usize),
}

/// Whether one obstacle's risk at the exact point `xt` = (x, t) is proven below `delta`:
/// Cantelli's constraints strictly positive (exactly), or, with `auto`, zero risk from the
/// support or a shifted moment bound (interval proofs at the point, §3.10).
pub fn point_obstacle_safe(o: &Obstacle, xt: &[BigRational], delta: &RiskLevel, bounds: BoundChoice) -> bool {
    point_obstacle_safe_at(o, xt, delta, None, None, bounds)
}

/// [`point_obstacle_safe`] with the level already converted (`level`: Δ as [`Level`], as a
/// certifier keeps it per obstacle) and, optionally, the obstacle's compiled contour with
/// the point's floats (the bounds beyond Cantelli are then restricted in its frame).
pub fn point_obstacle_safe_at(
    o: &Obstacle,
    xt: &[BigRational],
    delta: &RiskLevel,
    level: Option<Level>,
    compiled: Option<(&CompiledContour, &[f64])>,
    bounds: BoundChoice,
) -> bool {
    // a pedestrian with `auto`: its Gaussian tail bound, exactly (docs/design.md §3.11)
    if let (Some(p), true) = (&o.pedestrian, bounds.beyond_cantelli()) {
        let dim = p.file.position.len();
        if xt.len() != dim + 1 {
            return false;
        }
        let f: Vec<f64> = xt.iter().map(riskplan_math::poly::rational_to_f64).collect();
        // the exact check takes floats: a point that is not one is refused (sound)
        if xt.iter().zip(&f).any(|(q, &v)| BigRational::from_float(v).as_ref() != Some(q)) {
            return false;
        }
        // the interval test first (sound), then the exact one
        if let Some(k) = riskplan_math::contour::tail::tail_kappa(dim, delta.rational()) {
            if crate::gaussian_tail::point_clear(&p.disk, k, &f[..dim], f[dim]) {
                return true;
            }
        }
        let coeffs: Vec<Vec<f64>> = f[..dim].iter().map(|&v| vec![v]).collect();
        let pr = PieceRef { t0: f[dim], t1: f[dim], coeffs: &coeffs };
        return crate::gaussian_tail::piece_clear_exact(p, delta.rational(), pr).is_safe();
    }
    let one_minus = BigRational::from_integer(1.into()) - delta.rational();
    // the compiled moments in interval arithmetic first (sound; the exact evaluation
    // below decides what they leave open)
    if let Some((c, x)) = compiled {
        if c.proves_point(x, Interval::enclose_rational(&one_minus)) {
            return true;
        }
    }
    let r = o.contour.risk_at(xt);
    let g1 = &r.mean * &r.mean - &one_minus * &r.second_moment;
    if r.mean.is_negative() && g1.is_positive() {
        return true;
    }
    if !bounds.beyond_cantelli() {
        return false;
    }
    let level = level.unwrap_or_else(|| Level::new(delta.rational()));
    let pb = match compiled {
        Some((c, x)) => PieceBounds::for_point_compiled(&o.contour, c, x, xt, level),
        None => PieceBounds::for_point(&o.contour, xt, level),
    };
    pb.cover(None).is_ok()
}

/// The status of `x` at time `t` with one risk level per obstacle and a choice of bounds.
pub fn point_status(scene: &Scene, x: &[f64], t: f64, deltas: &[RiskLevel], bounds: BoundChoice) -> PointStatus {
    if !scene.workspace.contains(x) {
        return PointStatus::OutsideWorkspace;
    }
    let Some(mut xt) = x.iter().map(|&v| BigRational::from_float(v)).collect::<Option<Vec<_>>>() else {
        return PointStatus::OutsideWorkspace;
    };
    let Some(tq) = BigRational::from_float(t) else { return PointStatus::OutsideWorkspace };
    xt.push(tq);
    let bad = scene.obstacles.iter().zip(deltas).position(|(o, d)| !point_obstacle_safe(o, &xt, d, bounds));
    bad.map_or(PointStatus::Safe, PointStatus::InContour)
}

/// [`point_safe`] with one risk level per obstacle (all bounds: `auto`).
pub fn point_safe_with(scene: &Scene, x: &[f64], t: f64, deltas: &[RiskLevel]) -> bool {
    point_status(scene, x, t, deltas, BoundChoice::default()) == PointStatus::Safe
}
