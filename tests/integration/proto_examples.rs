//! Every golden payload of `proto/examples/` decodes into the Rust message type,
//! re-encodes to the same JSON (up to absent-versus-null optional fields and integer
//! versus float spelling), and round-trips through bincode unchanged — the same files
//! the Python tests validate against the JSON Schemas.

use riskplan_service::proto::*;
use serde::de::DeserializeOwned;
use serde::Serialize;
use serde_json::Value;
use std::fmt::Debug;
use std::path::PathBuf;

/// Drops nulls and writes every number as f64, so that `{"t0": 0}` and `{"t0": 0.0, "x": null}` compare equal.
fn normal(v: &Value) -> Value {
    match v {
        Value::Object(m) => {
            Value::Object(m.iter().filter(|(_, v)| !v.is_null()).map(|(k, v)| (k.clone(), normal(v))).collect())
        }
        Value::Array(a) => Value::Array(a.iter().map(normal).collect()),
        Value::Number(n) => serde_json::json!(n.as_f64()),
        other => other.clone(),
    }
}

fn roundtrip<T: Serialize + DeserializeOwned + PartialEq + Debug>(name: &str, text: &str) {
    let v: Value = serde_json::from_str(text).unwrap_or_else(|e| panic!("{name}: not JSON: {e}"));
    let msg: T = Codec::Json.decode(text.as_bytes()).unwrap_or_else(|e| panic!("{name}: does not decode: {e:?}"));
    let again: Value = serde_json::from_slice(&Codec::Json.encode(&msg)).unwrap();
    assert_eq!(normal(&again), normal(&v), "{name}: JSON round trip changes the payload");
    let bytes = Codec::Bincode.encode(&msg);
    let back: T = Codec::Bincode.decode(&bytes).unwrap_or_else(|e| panic!("{name}: bincode round trip fails: {e:?}"));
    assert_eq!(back, msg, "{name}: bincode round trip changes the message");
}

#[test]
fn every_example_round_trips() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("proto/examples");
    let mut n = 0;
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir).unwrap().filter_map(|e| e.ok().map(|e| e.path())).collect();
    files.sort();
    for f in files {
        let name = f.file_name().unwrap().to_string_lossy().to_string();
        let text = std::fs::read_to_string(&f).unwrap();
        match name.split('.').next().unwrap() {
            "apply_request" => roundtrip::<ApplyRequest>(&name, &text),
            "apply_reply" => roundtrip::<ApplyReply>(&name, &text),
            "obstacle_put" => roundtrip::<ObstaclePut>(&name, &text),
            "plan_request" => roundtrip::<PlanRequest>(&name, &text),
            "plan_reply" => roundtrip::<PlanReply>(&name, &text),
            "verify_request" => roundtrip::<VerifyRequest>(&name, &text),
            "verify_reply" => roundtrip::<VerifyReply>(&name, &text),
            "risk_request" => roundtrip::<RiskRequest>(&name, &text),
            "risk_reply" => roundtrip::<RiskReply>(&name, &text),
            "scene_reply" => roundtrip::<SceneReply>(&name, &text),
            "status_reply" => roundtrip::<StatusReply>(&name, &text),
            "error" => roundtrip::<ErrorReply>(&name, &text),
            other => panic!("{name}: unknown message kind '{other}'"),
        }
        n += 1;
    }
    assert!(n >= 30, "only {n} examples");
}

/// Bincode messages that announce huge lengths are errors, not allocations: the
/// 10-byte message that aborted the server (a string of 2^40 bytes claimed) and one
/// claiming 2^63 (which made the handler panic) decode into every request type as
/// `Err`, as do random short messages.
#[test]
fn bincode_length_claims_are_bounded() {
    let claim_2_40: &[u8] = &[0x01, 0xfd, 0x00, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00];
    let claim_2_63: &[u8] = &[0x01, 0xfd, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x80];
    let mut inputs: Vec<Vec<u8>> = vec![claim_2_40.to_vec(), claim_2_63.to_vec()];
    let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
    for n in 0..2000 {
        let len = 1 + n % 40;
        inputs.push(
            (0..len)
                .map(|_| {
                    x ^= x << 13;
                    x ^= x >> 7;
                    x ^= x << 17;
                    // mostly the bytes that make varints claim large lengths
                    if x % 3 == 0 {
                        0xfd
                    } else {
                        (x >> 24) as u8
                    }
                })
                .collect(),
        );
    }
    for bytes in &inputs {
        let _ = Codec::Bincode.decode::<VerifyRequest>(bytes);
        let _ = Codec::Bincode.decode::<ApplyRequest>(bytes);
        let _ = Codec::Bincode.decode::<PlanRequest>(bytes);
        let _ = Codec::Bincode.decode::<RiskRequest>(bytes);
    }
    for bytes in [claim_2_40, claim_2_63] {
        assert!(Codec::Bincode.decode::<VerifyRequest>(bytes).is_err());
        assert!(Codec::Bincode.decode::<ApplyRequest>(bytes).is_err());
    }
}
