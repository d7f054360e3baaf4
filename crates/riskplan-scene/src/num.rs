//! Exact numbers in scene files: a JSON number (read through its shortest decimal
//! text, so `0.3` is 3/10) or a string holding a decimal or a fraction (`"37/300"`).

use num_rational::BigRational;
pub use riskplan_math::poly::parse_num_text;
use riskplan_math::poly::{f64_shortest_decimal, rational_to_f64, MAX_DECIMAL_DIGITS, MAX_DECIMAL_EXPONENT};
use serde::de::{self, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::fmt;

/// An exact rational read from a scene.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct Num(pub BigRational);

impl Num {
    /// The nearest `f64`.
    pub fn f64(&self) -> f64 {
        rational_to_f64(&self.0)
    }
}

struct NumVisitor;

impl Visitor<'_> for NumVisitor {
    type Value = Num;
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a number, or a string holding a decimal or a fraction like \"37/300\"")
    }
    fn visit_i64<E: de::Error>(self, v: i64) -> Result<Num, E> {
        Ok(Num(BigRational::from_integer(v.into())))
    }
    fn visit_u64<E: de::Error>(self, v: u64) -> Result<Num, E> {
        Ok(Num(BigRational::from_integer(v.into())))
    }
    fn visit_f64<E: de::Error>(self, v: f64) -> Result<Num, E> {
        f64_shortest_decimal(v).map(Num).ok_or_else(|| E::custom("the number must be finite"))
    }
    fn visit_str<E: de::Error>(self, v: &str) -> Result<Num, E> {
        parse_num_text(v).map(Num).ok_or_else(|| {
            E::custom(format!(
                "'{v}' is not a decimal number or a fraction p/q within the exact-number limits \
                 ({MAX_DECIMAL_DIGITS} digits, exponent ±{MAX_DECIMAL_EXPONENT})"
            ))
        })
    }
}

impl<'de> Deserialize<'de> for Num {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Num, D::Error> {
        d.deserialize_any(NumVisitor)
    }
}

/// A decimal (`0.3`, `-1e-3`, `.5`) or a fraction of two decimals (`37/300`), spaces allowed
/// around the parts: the strings [`parse_num_text`] may accept (it also bounds the digits and
/// the exponent).
pub const NUM_TEXT_PATTERN: &str = r"^\s*[+-]?([0-9]+(\.[0-9]*)?|\.[0-9]+)([eE][+-]?[0-9]+)?\s*(/\s*[+-]?([0-9]+(\.[0-9]*)?|\.[0-9]+)([eE][+-]?[0-9]+)?\s*)?$";

impl schemars::JsonSchema for Num {
    fn schema_name() -> std::borrow::Cow<'static, str> {
        "Num".into()
    }

    /// A JSON number, or a string holding a decimal or a fraction ([`NUM_TEXT_PATTERN`]).
    fn json_schema(_: &mut schemars::SchemaGenerator) -> schemars::Schema {
        schemars::json_schema!({
            "description": "a number of a scene file, read exactly: a JSON number (read through its shortest decimal text, so 0.3 is 3/10) or a string holding a decimal or a fraction such as \"37/300\"",
            "anyOf": [
                { "type": "number" },
                { "type": "string", "pattern": NUM_TEXT_PATTERN }
            ]
        })
    }
}

impl Serialize for Num {
    /// A JSON number when the `f64` reads back as the same rational, else `"p/q"`.
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let f = self.f64();
        if f64_shortest_decimal(f).as_ref() == Some(&self.0) {
            s.serialize_f64(f)
        } else {
            s.serialize_str(&self.0.to_string())
        }
    }
}
