//! Reading the numbers and distributions of a scene (format v1, `docs/formats.md`
//! §1.3–1.4) as `f64`, for the oracle's risk bounds ([`super::bounds`]). Written from the
//! format's documentation, sharing no code with riskplan's scene loader.
//!
//! Numbers are JSON numbers or strings holding a decimal (`"0.3"`, `"-2.5E2"`, `".5"`,
//! `"+4"`) or a fraction of two decimals (`"37/300"`, `" 1 / 3 "`), read as the nearest
//! `f64` (a fraction: the quotient of the two nearest `f64`s, within 1.5 ulp of the exact
//! value). The product reads them as exact rationals; the oracle evaluates in `f64`
//! anyway. A number whose `f64` is not finite is an error.

use super::generate::Dist;
use serde_json::{Map, Value};
use thiserror::Error;

/// Most atoms of a `discrete` distribution (the format's limit).
pub const MAX_DISCRETE_ATOMS: usize = 64;
/// Most raw moments of a `moments` distribution (the format's limit).
pub const MAX_RAW_MOMENTS: usize = 64;
/// Largest accepted |Σ weights − 1| of a `discrete` distribution (the format's
/// tolerance); the weights are then normalised.
pub const WEIGHT_SUM_TOLERANCE: f64 = 1e-9;

/// A malformed number or distribution: the path of the field (relative to the value
/// given) and the problem.
#[derive(Debug, Error, Clone, PartialEq)]
#[error("{path}: {message}")]
pub struct SceneJsonError {
    /// Field path, e.g. `std` or `weights[2]` (empty: the value itself).
    pub path: String,
    /// What is wrong.
    pub message: String,
}

fn err(path: impl Into<String>, message: impl Into<String>) -> SceneJsonError {
    SceneJsonError { path: path.into(), message: message.into() }
}

/// Whether `s` is a decimal of the format: optional sign, digits with at most one '.'
/// (at least one digit), optionally e|E, an optional sign and at least one digit.
fn is_decimal(s: &str) -> bool {
    let b = s.as_bytes();
    let mut i = 0;
    if i < b.len() && (b[i] == b'+' || b[i] == b'-') {
        i += 1;
    }
    let mut digits = 0;
    while i < b.len() && b[i].is_ascii_digit() {
        i += 1;
        digits += 1;
    }
    if i < b.len() && b[i] == b'.' {
        i += 1;
        while i < b.len() && b[i].is_ascii_digit() {
            i += 1;
            digits += 1;
        }
    }
    if digits == 0 {
        return false;
    }
    if i < b.len() && (b[i] == b'e' || b[i] == b'E') {
        i += 1;
        if i < b.len() && (b[i] == b'+' || b[i] == b'-') {
            i += 1;
        }
        let start = i;
        while i < b.len() && b[i].is_ascii_digit() {
            i += 1;
        }
        if i == start {
            return false;
        }
    }
    i == b.len()
}

fn decimal(s: &str) -> Option<f64> {
    let s = s.trim();
    if !is_decimal(s) {
        return None;
    }
    s.parse::<f64>().ok()
}

/// A scene number as `f64` (module documentation).
pub fn number(v: &Value) -> Result<f64, SceneJsonError> {
    let x = match v {
        Value::Number(n) => n.as_f64().ok_or_else(|| err("", "not a number"))?,
        Value::String(s) => match s.split_once('/') {
            Some((p, q)) => {
                let p = decimal(p).ok_or_else(|| err("", format!("{s:?}: bad numerator")))?;
                let q = decimal(q).ok_or_else(|| err("", format!("{s:?}: bad denominator")))?;
                if q == 0.0 {
                    return Err(err("", format!("{s:?}: zero denominator")));
                }
                p / q
            }
            None => decimal(s).ok_or_else(|| err("", format!("{s:?} is not a decimal or a fraction")))?,
        },
        _ => return Err(err("", "expected a number or a string holding one")),
    };
    if x.is_finite() {
        Ok(x)
    } else {
        Err(err("", "not a finite f64"))
    }
}

/// Prefixes an error's path with `field`.
fn at(field: &str) -> impl Fn(SceneJsonError) -> SceneJsonError + '_ {
    move |e| SceneJsonError {
        path: if e.path.is_empty() { field.to_string() } else { format!("{field}{}", e.path) },
        message: e.message,
    }
}

/// A list of scene numbers.
fn numbers(v: &Value, field: &str) -> Result<Vec<f64>, SceneJsonError> {
    let a = v.as_array().ok_or_else(|| err(field, "expected an array"))?;
    a.iter().enumerate().map(|(i, x)| number(x).map_err(at(&format!("{field}[{i}]")))).collect()
}

struct Fields<'a> {
    obj: &'a Map<String, Value>,
}

impl Fields<'_> {
    fn num(&self, name: &str) -> Result<f64, SceneJsonError> {
        self.obj.get(name).ok_or_else(|| err(name, "missing")).and_then(|v| number(v).map_err(at(name)))
    }

    fn num_or(&self, name: &str, default: f64) -> Result<f64, SceneJsonError> {
        match self.obj.get(name) {
            Some(v) => number(v).map_err(at(name)),
            None => Ok(default),
        }
    }

    fn list(&self, name: &str) -> Result<Vec<f64>, SceneJsonError> {
        numbers(self.obj.get(name).ok_or_else(|| err(name, "missing"))?, name)
    }
}

impl Dist {
    /// A distribution object of a scene's `params` (`{"dist": "normal", "mean": 0, "std":
    /// "1/20"}`, …), checked as the format states: exactly the family's fields, and
    /// uniform low < high; normal std ≥ 0; beta α, β > 0, low < high (defaults 0, 1);
    /// gamma shape, scale > 0; exponential rate > 0; laplace scale > 0; discrete 1 …
    /// [`MAX_DISCRETE_ATOMS`] values with as many weights ≥ 0 summing to 1 within
    /// [`WEIGHT_SUM_TOLERANCE`] (normalised); moments 1 … [`MAX_RAW_MOMENTS`] raw moments
    /// ([`Dist::RawMoments`]; whether they are moments of a distribution is checked when a
    /// rule is built from them).
    pub fn from_scene_json(v: &Value) -> Result<Dist, SceneJsonError> {
        let obj = v.as_object().ok_or_else(|| err("", "expected a distribution object"))?;
        let family = obj.get("dist").and_then(Value::as_str).ok_or_else(|| err("dist", "missing or not a string"))?;
        let allowed: &[&str] = match family {
            "uniform" => &["low", "high"],
            "normal" => &["mean", "std"],
            "beta" => &["alpha", "beta", "low", "high"],
            "gamma" => &["shape", "scale"],
            "exponential" => &["rate"],
            "laplace" => &["mean", "scale"],
            "discrete" => &["values", "weights"],
            "moments" => &["raw"],
            other => return Err(err("dist", format!("unknown family {other:?}"))),
        };
        if let Some(k) = obj.keys().find(|k| k.as_str() != "dist" && !allowed.contains(&k.as_str())) {
            return Err(err(k.as_str(), format!("unknown field for {family}")));
        }
        let f = Fields { obj };
        let d = match family {
            "uniform" => {
                let (low, high) = (f.num("low")?, f.num("high")?);
                if !(low < high && (high - low).is_finite()) {
                    return Err(err("high", "needs low < high"));
                }
                Dist::Uniform { low, high }
            }
            "normal" => {
                let (mean, std) = (f.num("mean")?, f.num("std")?);
                if std < 0.0 {
                    return Err(err("std", format!("must be ≥ 0, got {std}")));
                }
                Dist::Normal { mean, std }
            }
            "beta" => {
                let (alpha, beta) = (f.num("alpha")?, f.num("beta")?);
                let (low, high) = (f.num_or("low", 0.0)?, f.num_or("high", 1.0)?);
                if alpha <= 0.0 {
                    return Err(err("alpha", "must be > 0"));
                }
                if beta <= 0.0 {
                    return Err(err("beta", "must be > 0"));
                }
                if !(low < high && (high - low).is_finite()) {
                    return Err(err("high", "needs low < high"));
                }
                Dist::Beta { alpha, beta, low, high }
            }
            "gamma" => {
                let (shape, scale) = (f.num("shape")?, f.num("scale")?);
                if shape <= 0.0 {
                    return Err(err("shape", "must be > 0"));
                }
                if scale <= 0.0 {
                    return Err(err("scale", "must be > 0"));
                }
                Dist::Gamma { shape, scale }
            }
            "exponential" => {
                let rate = f.num("rate")?;
                if rate <= 0.0 {
                    return Err(err("rate", "must be > 0"));
                }
                Dist::Exponential { rate }
            }
            "laplace" => {
                let (mean, scale) = (f.num("mean")?, f.num("scale")?);
                if scale <= 0.0 {
                    return Err(err("scale", "must be > 0"));
                }
                Dist::Laplace { mean, scale }
            }
            "discrete" => {
                let (values, weights) = (f.list("values")?, f.list("weights")?);
                if values.is_empty() || values.len() > MAX_DISCRETE_ATOMS {
                    return Err(err("values", format!("needs 1 to {MAX_DISCRETE_ATOMS} values")));
                }
                if weights.len() != values.len() {
                    return Err(err("weights", "needs as many weights as values"));
                }
                if let Some(i) = weights.iter().position(|w| *w < 0.0) {
                    return Err(err(format!("weights[{i}]"), "must be ≥ 0"));
                }
                let total: f64 = weights.iter().sum();
                if (total - 1.0).abs() > WEIGHT_SUM_TOLERANCE {
                    return Err(err("weights", format!("sum to {total}, not 1")));
                }
                Dist::Discrete { values, weights: weights.iter().map(|w| w / total).collect() }
            }
            _ => {
                let raw = f.list("raw")?;
                if raw.is_empty() || raw.len() > MAX_RAW_MOMENTS {
                    return Err(err("raw", format!("needs 1 to {MAX_RAW_MOMENTS} moments")));
                }
                Dist::RawMoments { raw }
            }
        };
        Ok(d)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn numbers_of_every_spelling() {
        for (v, x) in [
            (json!(0.3), 0.3),
            (json!(-2), -2.0),
            (json!("0.3"), 0.3),
            (json!("-2.5E2"), -250.0),
            (json!(".5"), 0.5),
            (json!("+4"), 4.0),
            (json!("5."), 5.0),
            (json!("37/300"), 37.0 / 300.0),
            (json!(" 1 / 3 "), 1.0 / 3.0),
            (json!("0.5/3"), 0.5 / 3.0),
            (json!("1e-400"), 0.0),
        ] {
            assert_eq!(number(&v), Ok(x), "{v}");
        }
        for v in [json!("1/0"), json!("1e400"), json!("abc"), json!("1/2/3"), json!("inf"), json!("NaN"), json!(".")] {
            assert!(number(&v).is_err(), "{v}");
        }
        assert!(number(&json!(null)).is_err());
        assert!(number(&json!("e5")).is_err());
        assert!(number(&json!("1e")).is_err());
    }

    #[test]
    fn distributions_parse_and_validate() {
        let d = Dist::from_scene_json(&json!({"dist": "normal", "mean": 0, "std": "1/20"})).unwrap();
        assert_eq!(d, Dist::Normal { mean: 0.0, std: 0.05 });
        let d = Dist::from_scene_json(&json!({"dist": "beta", "alpha": 3, "beta": 3})).unwrap();
        assert_eq!(d, Dist::Beta { alpha: 3.0, beta: 3.0, low: 0.0, high: 1.0 });
        let d =
            Dist::from_scene_json(&json!({"dist": "discrete", "values": [1, 2], "weights": ["1/3", "2/3"]})).unwrap();
        assert!(matches!(d, Dist::Discrete { .. }));
        let d = Dist::from_scene_json(&json!({"dist": "moments", "raw": ["0.35", "37/300"]})).unwrap();
        assert_eq!(d, Dist::RawMoments { raw: vec![0.35, 37.0 / 300.0] });
        for (v, path) in [
            (json!({"dist": "normal", "mean": 0, "std": -0.1}), "std"),
            (json!({"dist": "normal", "mean": 0}), "std"),
            (json!({"dist": "normal", "mean": 0, "std": 1, "sd": 1}), "sd"),
            (json!({"dist": "uniform", "low": 1, "high": 1}), "high"),
            (json!({"dist": "cauchy"}), "dist"),
            (json!({"dist": "discrete", "values": [1, 2], "weights": [0.5, 0.4]}), "weights"),
            (json!({"dist": "discrete", "values": [1, 2], "weights": [1.5, -0.5]}), "weights[1]"),
            (json!({"dist": "gamma", "shape": 1, "scale": "x"}), "scale"),
            (json!({"dist": "discrete", "values": [1, "?"], "weights": [1, 0]}), "values[1]"),
            (json!({"dist": "moments", "raw": []}), "raw"),
        ] {
            let e = Dist::from_scene_json(&v).unwrap_err();
            assert_eq!(e.path, path, "{v}: {e}");
        }
        assert!(Dist::from_scene_json(&json!(3)).is_err());
    }
}
