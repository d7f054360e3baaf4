//! The JSON Schemas of the wire messages (`proto/schemas/<message>.schema.json`), generated
//! from the Rust types of [`proto`](super::proto) by `schemars`: what the server decodes is
//! what the schemas describe, and a new field, planner or error code reaches them with
//! the type. Each schema is draft 2020-12, self-contained (what it uses is in its
//! `$defs`), with `$id` `https://riskplan.invalid/proto/v1/<message>.schema.json` and
//! `title` the message's name. Requests have `additionalProperties: false` (their types
//! deny unknown fields); replies are open (a client stays compatible with a server that
//! adds fields). The descriptions are the types' doc comments.
//!
//! The checked-in files are compared with these, byte for byte, by this module's test; to
//! write them after a change of the messages:
//!
//! ```text
//! RISKPLAN_WRITE_SCHEMAS=1 cargo test -p riskplan-service --lib schema
//! ```

use super::proto::{
    ApplyReply, ApplyRequest, ErrorReply, ObstaclePut, PlanReply, PlanRequest, RiskReply, RiskRequest, SceneReply,
    StatusReply, VerifyReply, VerifyRequest,
};
use schemars::generate::SchemaSettings;
use schemars::{JsonSchema, Schema};
use serde_json::{Map, Value};

/// The JSON Schema dialect of every schema.
pub const DIALECT: &str = "https://json-schema.org/draft/2020-12/schema";

/// The prefix of every schema's `$id`.
pub const ID_BASE: &str = "https://riskplan.invalid/proto/v1/";

/// A message's schema from its name ([`message`] of its type).
pub type MessageSchema = fn(&str) -> Schema;

/// The messages of proto/README.md, each with its schema: a new message is one line here
/// (and its golden example in `proto/examples/`).
pub const MESSAGES: [(&str, MessageSchema); 12] = [
    ("apply_request", message::<ApplyRequest>),
    ("apply_reply", message::<ApplyReply>),
    ("error", message::<ErrorReply>),
    ("obstacle_put", message::<ObstaclePut>),
    ("plan_request", message::<PlanRequest>),
    ("plan_reply", message::<PlanReply>),
    ("risk_request", message::<RiskRequest>),
    ("risk_reply", message::<RiskReply>),
    ("scene_reply", message::<SceneReply>),
    ("status_reply", message::<StatusReply>),
    ("verify_request", message::<VerifyRequest>),
    ("verify_reply", message::<VerifyReply>),
];

/// The schema of message `name`, whose type is `T`: `$schema`, `$id` and `title` (the
/// message's name), `T`'s schema, and the definitions it uses under `$defs`; descriptions
/// as prose (see [`tidy`]). (Written out, a schema's keywords come in `schemars`' order:
/// `$id` and `$schema` first, `$defs` last.)
pub fn message<T: JsonSchema>(name: &str) -> Schema {
    let generated = SchemaSettings::draft2020_12().into_generator().into_root_schema_for::<T>();
    let mut body = match generated.to_value() {
        Value::Object(m) => m,
        other => panic!("the schema of {name} is not an object: {other}"),
    };
    let mut out = Map::new();
    out.insert("$schema".into(), DIALECT.into());
    out.insert("$id".into(), format!("{ID_BASE}{name}.schema.json").into());
    out.insert("title".into(), name.into());
    body.remove("$schema");
    body.remove("title");
    out.extend(body);
    let mut v = Value::Object(out);
    tidy(&mut v);
    Schema::try_from(v).expect("an object is a schema")
}

/// What a schema file holds: the schema as pretty JSON and a newline.
pub fn render(schema: &Schema) -> String {
    let mut text = serde_json::to_string_pretty(schema).expect("a schema is JSON");
    text.push('\n');
    text
}

/// Every message's file name (`<message>.schema.json`) and text.
pub fn files() -> Vec<(String, String)> {
    MESSAGES.iter().map(|(name, schema)| (format!("{name}.schema.json"), render(&schema(name)))).collect()
}

/// Tidies what `schemars` derives from Rust for readers of the wire: no `"default": null`
/// (an absent optional field says it), and descriptions as prose — the doc comments'
/// line breaks joined (paragraphs kept), rustdoc's link brackets and escapes dropped
/// (`` [`X`] `` → `` `X` ``, `\[` → `[`).
pub fn tidy(v: &mut Value) {
    match v {
        Value::Object(m) => {
            if m.get("default").is_some_and(Value::is_null) {
                m.remove("default");
            }
            for (k, x) in m.iter_mut() {
                match x {
                    Value::String(s) if k == "description" => *s = prose(s),
                    _ => tidy(x),
                }
            }
        }
        Value::Array(a) => a.iter_mut().for_each(tidy),
        _ => {}
    }
}

/// A doc comment as one paragraph per paragraph, without rustdoc's markup of links.
fn prose(doc: &str) -> String {
    let paragraphs: Vec<String> = doc
        .split("\n\n")
        .map(|p| p.lines().map(str::trim).filter(|l| !l.is_empty()).collect::<Vec<_>>().join(" "))
        .filter(|p| !p.is_empty())
        .collect();
    let text = paragraphs.join("\n\n");
    let mut out = String::with_capacity(text.len());
    let mut rest = text.as_str();
    while let Some(i) = rest.find('[') {
        let (before, from) = rest.split_at(i);
        out.push_str(before);
        // `[label](target)` → label; `` [`item`] `` (an intra-doc link) → `` `item` ``
        let link = from[1..]
            .find(']')
            .map(|j| (&from[1..1 + j], &from[2 + j..]))
            .filter(|(label, _)| !before.ends_with('\\') && !label.contains('['));
        let target = link.and_then(|(_, after)| after.strip_prefix('(')?.find(')').map(|k| &after[k + 2..]));
        match (link, target) {
            (Some((label, _)), Some(after)) => {
                out.push_str(label);
                rest = after;
            }
            (Some((label, after)), None) if label.len() >= 2 && label.starts_with('`') && label.ends_with('`') => {
                out.push_str(label);
                rest = after;
            }
            _ => {
                out.push('[');
                rest = &from[1..];
            }
        }
    }
    out.push_str(rest);
    out.replace("\\[", "[").replace("\\]", "]")
}

#[cfg(test)]
mod tests {
    use super::super::error::ServiceError;
    use super::super::proto::{ErrorCode, Named};
    use super::*;
    use riskplan_app::PlannerKind;
    use riskplan_math::contour::BoundChoice;
    use std::path::PathBuf;

    /// `RISKPLAN_WRITE_SCHEMAS` set (and not `0`): write the files instead of comparing.
    fn writing() -> bool {
        std::env::var("RISKPLAN_WRITE_SCHEMAS").is_ok_and(|v| !v.is_empty() && v != "0")
    }

    /// The checked-in `proto/schemas/*.schema.json` are the schemas of the Rust types, byte
    /// for byte, one per message and nothing else; `RISKPLAN_WRITE_SCHEMAS=1` rewrites them
    /// (and removes strays).
    #[test]
    fn the_schema_files_are_generated_from_the_rust_types() {
        let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../proto/schemas");
        let generated = files();
        let mut stale = Vec::new();
        for (file, text) in &generated {
            let path = dir.join(file);
            if writing() {
                std::fs::write(&path, text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            } else if std::fs::read_to_string(&path).ok().as_deref() != Some(text.as_str()) {
                stale.push(file.clone());
            }
        }
        for e in std::fs::read_dir(&dir).expect("proto/schemas") {
            let path = e.expect("a directory entry").path();
            let file = path.file_name().map(|f| f.to_string_lossy().to_string()).unwrap_or_default();
            if file.ends_with(".schema.json") && !generated.iter().any(|(f, _)| *f == file) {
                if writing() {
                    std::fs::remove_file(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                } else {
                    stale.push(format!("{file} (no such message)"));
                }
            }
        }
        assert!(
            stale.is_empty(),
            "proto/schemas is not what the Rust types generate: {stale:?}; after changing the messages, \
             write the schemas with `RISKPLAN_WRITE_SCHEMAS=1 cargo test -p riskplan-service --lib schema` \
             and commit them"
        );
    }

    /// Every schema: the dialect, its `$id` and `title`, self-contained (every `$ref` is
    /// to its own `$defs`), requests closed and replies open.
    #[test]
    fn every_schema_is_self_contained_and_named() {
        fn refs(v: &Value, out: &mut Vec<String>) {
            match v {
                Value::Object(m) => {
                    if let Some(Value::String(r)) = m.get("$ref") {
                        out.push(r.clone());
                    }
                    m.values().for_each(|x| refs(x, out));
                }
                Value::Array(a) => a.iter().for_each(|x| refs(x, out)),
                _ => {}
            }
        }
        for (name, schema) in MESSAGES {
            let s = schema(name).to_value();
            assert_eq!(s["$schema"], DIALECT, "{name}");
            assert_eq!(s["$id"], format!("https://riskplan.invalid/proto/v1/{name}.schema.json"), "{name}");
            assert_eq!(s["title"], name);
            let mut all = Vec::new();
            refs(&s, &mut all);
            for r in all {
                let def = r.strip_prefix("#/$defs/").unwrap_or_else(|| panic!("{name}: a $ref outside: {r}"));
                assert!(s["$defs"].get(def).is_some(), "{name}: {r} is not in its $defs");
            }
            let closed = s.get("additionalProperties") == Some(&Value::Bool(false));
            let request = name.ends_with("_request") || name == "obstacle_put";
            assert_eq!(closed, request, "{name}: requests are closed, replies open");
        }
    }

    /// The error schema's codes are `ErrorCode::ALL`, and every `ServiceError` has its code
    /// among them.
    #[test]
    fn the_error_schema_lists_every_code() {
        let s = message::<ErrorReply>("error").to_value();
        let codes: Vec<&str> =
            s["properties"]["code"]["enum"].as_array().unwrap().iter().filter_map(Value::as_str).collect();
        assert_eq!(codes, ErrorCode::ALL.map(ErrorCode::as_str));
        assert!(codes.contains(&ServiceError::Busy(1).code().as_str()));
        for c in ErrorCode::ALL {
            assert_eq!(c.as_str().parse::<ErrorCode>(), Ok(c));
            assert_eq!(serde_json::to_value(c).unwrap(), c.as_str());
        }
    }

    /// The planner names of the plan schemas are `PlannerKind::ALL`'s, in order.
    #[test]
    fn the_plan_schemas_name_every_planner() {
        let names: Vec<Value> = PlannerKind::ALL.iter().map(|k| Value::from(k.as_str())).collect();
        let reply = message::<PlanReply>("plan_reply").to_value();
        assert_eq!(reply["properties"]["planner"]["enum"], Value::Array(names.clone()));
        let request = message::<PlanRequest>("plan_request").to_value();
        let mut nullable = names;
        nullable.push(Value::Null);
        assert_eq!(request["properties"]["planner"]["enum"], Value::Array(nullable));
    }

    /// A name outside its set decodes (JSON and bincode), keeps its set's message and
    /// encodes back as sent; a known one is the value.
    #[test]
    fn a_name_outside_its_set_is_kept_for_the_handler() {
        let n: Named<PlannerKind> = serde_json::from_str("\"astar\"").unwrap();
        let message = "unknown planner 'astar' (rrt-sos, rrt-sos-paper, mc-rrt, tv-sos, moment, moment-poly, receding)";
        assert_eq!(n.get(), Err(message));
        assert_eq!(serde_json::to_string(&n).unwrap(), "\"astar\"");
        let bytes = bincode::serde::encode_to_vec(&n, bincode::config::standard()).unwrap();
        let (back, _): (Named<PlannerKind>, usize) =
            bincode::serde::decode_from_slice(&bytes, bincode::config::standard()).unwrap();
        assert_eq!(back, n);
        let k: Named<PlannerKind> = serde_json::from_str("\"mc-rrt\"").unwrap();
        assert_eq!(k.get(), Ok(PlannerKind::McRrt));
        assert!(serde_json::from_str::<Named<PlannerKind>>("3").is_err(), "not a string: not a name");
        // a set with serde of its own (the bound choice's derived one) is a name too
        for b in BoundChoice::ALL {
            let n = Named::Known(b);
            assert_eq!(serde_json::to_value(&n).unwrap(), b.as_str());
            let bytes = bincode::serde::encode_to_vec(&n, bincode::config::standard()).unwrap();
            let (back, _): (Named<BoundChoice>, usize) =
                bincode::serde::decode_from_slice(&bytes, bincode::config::standard()).unwrap();
            assert_eq!(back, n);
        }
    }

    #[test]
    fn descriptions_are_prose() {
        let doc = "A [`Piece`] of\nthe [path](x::y), [`as_str`](T::as_str).\n\nNext E\\[P\\] on `[t0, t1]` [a, b].";
        assert_eq!(prose(doc), "A `Piece` of the path, `as_str`.\n\nNext E[P] on `[t0, t1]` [a, b].");
    }
}
