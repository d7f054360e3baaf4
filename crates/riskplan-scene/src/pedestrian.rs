//! The pedestrian template (docs/formats.md §1.5.1, docs/design.md §3.11): a moving
//! disk (ball in 3-D) given by its predicted position and velocity at a time, Gaussian
//! errors of both, and a radius with a bounded support — what a perception stack sends
//! at 10 Hz for every person it tracks. It expands to the polynomial
//!
//! ```text
//! P = R² − Σ_i (x_i − p_i − a_i − (v_i + b_i)·(t − t_ref))²,
//! a_i ~ N(0, σ_p²),  b_i ~ N(0, σ_v²),  R as given
//! ```
//!
//! in variables of its own (its parameters are not the scene's: `x1..xn, t`, then
//! `a_1..a_n, b_1..b_n, R`), so that one pedestrian is rebuilt without touching the
//! rest of the scene. Its contour polynomials (E\[P\], E\[P²\]) are built only when
//! something asks for them; the certifier decides it by the Gaussian tail bound of
//! [`GaussianDisk`] instead (§3.11), which costs nothing to set up.

use super::file::{PedestrianFile, RadiusFile};
use super::num::Num;
use super::{err, Param, SceneError};
use num_rational::BigRational;
use num_traits::{Signed, Zero};
use riskplan_math::contour::tail::GaussianDisk;
use riskplan_math::contour::{Layout, RiskContour};
use riskplan_math::moments::Distribution;
use riskplan_math::poly::{rational_to_f64, Interval, Poly, QPoly, Var};

/// Largest |coordinate|, |velocity|, |time| or standard deviation of a pedestrian, as
/// a float: beyond it the tail bound's products would overflow and every piece near the
/// pedestrian would be refused; refused at once instead.
pub const MAX_PEDESTRIAN_MAGNITUDE: f64 = 1e150;

/// A validated pedestrian: the template as written, its tail-bound model and its own
/// parameters (variables `dim + 1 …` of its polynomial).
#[derive(Clone, Debug)]
pub struct Pedestrian {
    /// As written.
    pub file: PedestrianFile,
    /// The tail-bound model (reach = the radius's supremum; a robot body adds to it).
    pub disk: GaussianDisk,
    /// Its own parameters, in variable order (`Param::var` local to its polynomial).
    pub params: Vec<Param>,
    /// P in its own variables, grown by `body`: [`Pedestrian::poly`].
    poly: std::sync::OnceLock<QPoly>,
    /// P not grown: [`Pedestrian::original_poly`].
    original: std::sync::OnceLock<QPoly>,
    /// The largest radius (the supremum of its support), exact.
    pub r_max: BigRational,
    /// The robot's body radius this pedestrian has been grown by (0 unless the scene
    /// has a body, docs/design.md §3.12), exact.
    pub body: BigRational,
}

impl Pedestrian {
    /// Validates the template of obstacle `path` in a `dim`-D scene whose horizon is
    /// `horizon` (field paths in errors: `obstacles[3].pedestrian.velocity`).
    pub fn new(file: &PedestrianFile, dim: usize, path: &str) -> Result<Pedestrian, SceneError> {
        let field = |f: &str| format!("{path}.{f}");
        for (name, v) in [("position", &file.position), ("velocity", &file.velocity)] {
            if v.len() != dim {
                return Err(err(field(name), format!("must have {dim} entries (dim), got {}", v.len())));
            }
        }
        let finite = |f: &str, n: &Num| -> Result<f64, SceneError> {
            let x = n.f64();
            if x.is_nan() || x.abs() > MAX_PEDESTRIAN_MAGNITUDE {
                return Err(err(field(f), format!("must be a finite number of magnitude at most 1e150, got {x}")));
            }
            Ok(x)
        };
        for (i, n) in file.position.iter().enumerate() {
            finite(&format!("position[{i}]"), n)?;
        }
        for (i, n) in file.velocity.iter().enumerate() {
            finite(&format!("velocity[{i}]"), n)?;
        }
        finite("time", &file.time)?;
        let zero = Num(BigRational::zero());
        let sp = file.position_std.clone().unwrap_or_else(|| zero.clone());
        let sv = file.velocity_std.clone().unwrap_or(zero);
        for (name, s) in [("position_std", &sp), ("velocity_std", &sv)] {
            finite(name, s)?;
            if s.0.is_negative() {
                return Err(err(field(name), format!("must be ≥ 0, got {}", s.f64())));
            }
        }
        let radius: Distribution = match &file.radius {
            RadiusFile::Fixed(r) => {
                finite("radius", r)?;
                if !r.0.is_positive() {
                    return Err(err(field("radius"), format!("must be > 0, got {}", r.f64())));
                }
                Distribution::Uniform { low: r.0.clone(), high: r.0.clone() }
            }
            RadiusFile::Random(pf) => {
                let d = pf.to_distribution().validated().map_err(|e| err(field("radius"), e.to_string()))?;
                let Some((lo, hi)) = d.support() else {
                    return Err(err(
                        field("radius"),
                        "needs a bounded support (uniform, beta or discrete): the tail bound uses the largest radius",
                    ));
                };
                if lo.is_negative() || !hi.is_positive() || rational_to_f64(&hi) > MAX_PEDESTRIAN_MAGNITUDE {
                    return Err(err(
                        field("radius"),
                        "the support must lie in [0, 1e150] and include a positive radius",
                    ));
                }
                d
            }
        };
        let r_max = radius.support().map(|s| s.1).unwrap_or_default();
        let up = |q: &BigRational| Interval::enclose_rational(q).hi;
        let disk = GaussianDisk {
            position: file.position.iter().map(|n| Interval::enclose_rational(&n.0)).collect(),
            velocity: file.velocity.iter().map(|n| Interval::enclose_rational(&n.0)).collect(),
            t_ref: Interval::enclose_rational(&file.time.0),
            reach: up(&r_max),
            sigma_p: up(&sp.0),
            sigma_v: up(&sv.0),
        };
        // its own variables: x_i = i, t = dim, then a_i, b_i, R (the polynomial is built
        // on first use: most updates never need it)
        let mut params = Vec::new();
        let mut next: Var = (dim + 1) as Var;
        let mut param = |name: String, dist: Distribution| {
            params.push(Param { name, var: next, dist });
            next += 1;
        };
        let normal = |s: &Num| Distribution::Normal { mean: BigRational::zero(), std: s.0.clone() };
        if sp.0.is_positive() {
            (0..dim).for_each(|i| param(format!("a{}", i + 1), normal(&sp)));
        }
        if sv.0.is_positive() {
            (0..dim).for_each(|i| param(format!("b{}", i + 1), normal(&sv)));
        }
        if let RadiusFile::Random(_) = &file.radius {
            param("R".into(), radius);
        }
        Ok(Pedestrian {
            file: file.clone(),
            disk,
            params,
            poly: std::sync::OnceLock::new(),
            original: std::sync::OnceLock::new(),
            r_max,
            body: BigRational::zero(),
        })
    }

    /// P in its own variables (module docs), grown by `body` (R → R + body), built once.
    pub fn poly(&self) -> &QPoly {
        self.poly.get_or_init(|| self.build_poly(&self.body))
    }

    /// P before any growth (the pedestrian itself: what a Monte Carlo audit of body
    /// contact samples), built once.
    pub fn original_poly(&self) -> &QPoly {
        if self.body.is_zero() {
            return self.poly();
        }
        self.original.get_or_init(|| self.build_poly(&BigRational::zero()))
    }

    fn build_poly(&self, body: &BigRational) -> QPoly {
        let file = &self.file;
        let dim = file.position.len();
        let t = Poly::var(dim as Var).sub(&Poly::constant(file.time.0.clone()));
        let var = |name: String| self.params.iter().find(|p| p.name == name).map(|p| Poly::var(p.var));
        let r: QPoly = match &file.radius {
            RadiusFile::Fixed(r) => Poly::constant(&r.0 + body),
            RadiusFile::Random(_) => var("R".into()).unwrap_or_else(Poly::zero).add(&Poly::constant(body.clone())),
        };
        let mut poly = r.mul(&r);
        for i in 0..dim {
            let mut vel = Poly::constant(file.velocity[i].0.clone());
            if let Some(b) = var(format!("b{}", i + 1)) {
                vel = vel.add(&b);
            }
            let mut c = Poly::constant(file.position[i].0.clone()).add(&vel.mul(&t));
            if let Some(a) = var(format!("a{}", i + 1)) {
                c = c.add(&a);
            }
            let u = Poly::var(i as Var).sub(&c);
            poly = poly.sub(&u.mul(&u));
        }
        poly
    }

    /// The same pedestrian for a robot whose body is a disk/ball of radius `rho` ≥ 0
    /// (docs/design.md §3.12): contact of the body with the pedestrian is contact of its
    /// centre with the pedestrian grown by ρ, exactly — the radius R becomes R + ρ in the
    /// polynomial, the reach of the tail bound grows by ρ (rounded up), and `body` records
    /// ρ for the exact check. Growing twice adds the radii.
    pub fn grown(&self, rho: &BigRational) -> Pedestrian {
        let body = &self.body + rho;
        let mut disk = self.disk.clone();
        disk.reach = Interval::enclose_rational(&(&self.r_max + &body)).hi;
        Pedestrian {
            file: self.file.clone(),
            disk,
            params: self.params.clone(),
            poly: std::sync::OnceLock::new(),
            original: std::sync::OnceLock::new(),
            r_max: self.r_max.clone(),
            body,
        }
    }

    /// Builds its contour (E\[P\], E\[P²\] and what the other bounds need) from its own
    /// parameters' moments. Should a moment be missing — impossible for the normal
    /// errors and a bounded radius, whose moments exist at every order — the contour of
    /// the constant 1 is returned: an obstacle that fills the space, refused everywhere
    /// (sound).
    pub fn contour(&self, dim: usize) -> RiskContour {
        let layout = Layout { dim };
        let top = riskplan_math::contour::bounds::MAX_MOMENT_ORDER * 2;
        let moments: Vec<(Var, Vec<BigRational>)> =
            self.params.iter().filter_map(|p| Some((p.var, p.dist.raw_moments(top).ok()?))).collect();
        let lookup = |v: Var, k: u32| moments.iter().find(|m| m.0 == v).and_then(|m| m.1.get(k as usize)).cloned();
        let name = |v: Var| self.params.iter().find(|p| p.var == v).map_or_else(|| format!("#{v}"), |p| p.name.clone());
        let supports: Vec<(Var, BigRational, BigRational)> =
            self.params.iter().filter_map(|p| p.dist.support().map(|(lo, hi)| (p.var, lo, hi))).collect();
        match RiskContour::new(layout, self.poly(), &lookup, &name) {
            Ok(c) => {
                let laws: Vec<(Var, &riskplan_math::moments::Distribution)> =
                    self.params.iter().map(|p| (p.var, &p.dist)).collect();
                c.with_support(&supports).with_laws(&laws)
            }
            Err(_) => RiskContour::new(layout, &Poly::constant(BigRational::from_integer(1.into())), &lookup, &name)
                .expect("a constant polynomial needs no moment"),
        }
    }
}
