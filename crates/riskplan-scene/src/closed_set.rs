//! Closed sets of names on the wire and in files (a planner, a certifier, a risk mode, an
//! error code, ...): [`closed_set!`](crate::closed_set) gives such an enum its serde and
//! JSON Schema from the three things it already has — `ALL` (every value, in the order
//! help texts and schemas list them), `as_str` (its name) and `FromStr` (whose error is
//! the message users see) — so that the names in the schemas, in the JSON and in the
//! parser can never disagree.

/// A value of a closed set of names, with its name (what it is serialized as, in every
/// encoding): what holders of such a name, like the service's `Named`, need.
pub trait WireName: Copy {
    /// The name.
    fn wire_name(self) -> &'static str;
}

/// The bound choice keeps its derived serde (a scene file's unknown bound is serde's
/// error); its names are its `as_str` names (a test in `riskplan-math` holds them equal).
impl WireName for riskplan_math::contour::BoundChoice {
    fn wire_name(self) -> &'static str {
        self.as_str()
    }
}

/// Implements [`WireName`] and `Serialize` (the value's `as_str`), `Deserialize` (a string
/// through the type's `FromStr`, its error as the message) and `JsonSchema` (`{"type": "string",
/// "enum": [every name of ALL]}`, inlined where used, named `$name`) for a closed-set
/// enum `$ty` that has `const ALL: [$ty; N]`, `fn as_str(self) -> &'static str` (or
/// `&self`) and `impl FromStr`.
///
/// ```
/// use std::str::FromStr;
///
/// #[derive(Clone, Copy, Debug, PartialEq)]
/// enum Op {
///     Put,
///     Delete,
/// }
/// impl Op {
///     const ALL: [Op; 2] = [Op::Put, Op::Delete];
///     fn as_str(self) -> &'static str {
///         match self {
///             Op::Put => "put",
///             Op::Delete => "delete",
///         }
///     }
/// }
/// impl FromStr for Op {
///     type Err = String;
///     fn from_str(s: &str) -> Result<Op, String> {
///         Op::ALL.into_iter().find(|o| o.as_str() == s).ok_or_else(|| format!("'{s}' is not an operation"))
///     }
/// }
/// riskplan_scene::closed_set!(Op, "Op");
///
/// assert_eq!(serde_json::to_string(&Op::Delete).unwrap(), "\"delete\"");
/// let e = serde_json::from_str::<Op>("\"move\"").unwrap_err();
/// assert!(e.to_string().starts_with("'move' is not an operation"));
/// ```
#[macro_export]
macro_rules! closed_set {
    ($ty:ty, $name:expr) => {
        impl $crate::WireName for $ty {
            fn wire_name(self) -> &'static str {
                self.as_str()
            }
        }

        impl $crate::__private::serde::Serialize for $ty {
            fn serialize<S: $crate::__private::serde::Serializer>(&self, s: S) -> ::core::result::Result<S::Ok, S::Error> {
                s.serialize_str(self.as_str())
            }
        }

        impl<'de> $crate::__private::serde::Deserialize<'de> for $ty {
            fn deserialize<D: $crate::__private::serde::Deserializer<'de>>(d: D) -> ::core::result::Result<Self, D::Error> {
                let text = <::std::string::String as $crate::__private::serde::Deserialize>::deserialize(d)?;
                text.parse::<$ty>().map_err($crate::__private::serde::de::Error::custom)
            }
        }

        impl $crate::__private::schemars::JsonSchema for $ty {
            fn inline_schema() -> bool {
                true
            }

            fn schema_name() -> ::std::borrow::Cow<'static, str> {
                $name.into()
            }

            fn json_schema(_: &mut $crate::__private::schemars::SchemaGenerator) -> $crate::__private::schemars::Schema {
                let names: ::std::vec::Vec<&'static str> = <$ty>::ALL.iter().map(|v| v.as_str()).collect();
                $crate::__private::schemars::json_schema!({ "type": "string", "enum": names })
            }
        }
    };
}
