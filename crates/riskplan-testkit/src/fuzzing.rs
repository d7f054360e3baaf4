//! Fuzz targets: the entry points of `fuzz/` (cargo-fuzz, libFuzzer) and of the corpus
//! replay and seeded mutation run in riskplan's integration tests
//! (`tests/integration/fuzz_replay.rs`), which any stable toolchain runs.
//!
//! Every target takes arbitrary bytes and must return normally: a panic, an abort
//! (an allocation the input asked for), or more than a second of work is a bug. Each
//! also checks a property whose failure would be a bug even without a crash:
//! - [`poly_text`]: a parsed polynomial respects the parser's limits, and parsing its
//!   own text gives it back (the printer and the parser agree);
//! - [`scene_json`]: a scene that loads, written back and loaded again, loads the same;
//! - [`request`]: every request type in JSON and bincode, decoded as the server decodes
//!   it and, when it decodes, handled as the server handles it (apply on a scratch
//!   scene, plan, verify and risk on the paper's scenes with short deadlines); every
//!   reply and error encodes in the request's codec.
//!
//! A target's assertions are how it reports a bug to libFuzzer: they panic on purpose.

use riskplan_math::poly::{parse, PolyError, VarTable, MAX_DECIMAL_DIGITS, MAX_PARSE_DEGREE, MAX_PARSE_TERMS};
use riskplan_scene::Scene;

/// The variables a fuzzed polynomial may use (a 3-D space, time and two parameters).
const POLY_VARS: [&str; 6] = ["x1", "x2", "x3", "t", "w", "v"];

/// Parses `data` as polynomial text (when it is UTF-8).
pub fn poly_text(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let table = VarTable::new(POLY_VARS.iter().map(|s| s.to_string()));
    let mut resolve = |n: &str| table.get(n).ok_or_else(|| format!("unknown variable '{n}'"));
    let Ok(p) = parse(text, &mut resolve) else { return };
    assert!(p.degree() <= MAX_PARSE_DEGREE, "degree {} over the parser's limit", p.degree());
    assert!(p.len() <= MAX_PARSE_TERMS, "{} terms over the parser's limit", p.len());
    let printed = p.to_text(&|v| POLY_VARS[v as usize].to_string());
    match parse(&printed, &mut resolve) {
        Ok(q) => assert!(q == p, "'{text}' printed as '{printed}' parses to a different polynomial"),
        // the printed form of a large polynomial may need more expansion work than
        // the (factored) input did: a limit, never another error
        Err(PolyError::TooLarge { .. }) => {}
        // computed coefficients (1e400·1e400) may have more digits than a literal may
        Err(PolyError::BadNumber { .. })
            if printed.split(|c: char| !c.is_ascii_digit()).any(|run| run.len() > MAX_DECIMAL_DIGITS) => {}
        Err(e) => panic!("'{text}' printed as '{printed}' does not parse: {e}"),
    }
}

/// Loads `data` as a scene file (when it is UTF-8).
pub fn scene_json(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(scene) = Scene::from_json(text) else { return };
    let again = serde_json::to_string(&scene.file).expect("a loaded scene serialises");
    let reloaded = Scene::from_json(&again)
        .unwrap_or_else(|e| panic!("a loaded scene, written back, no longer loads: {e}\n{again}"));
    assert_eq!(reloaded.obstacles.len(), scene.obstacles.len());
    assert_eq!(reloaded.dim, scene.dim);
}

pub use request_target::{request, REQUEST_KINDS};

mod request_target {
    use riskplan_service::error::ServiceError;
    use riskplan_service::handlers;
    use riskplan_service::proto::*;
    use riskplan_service::registry::Registry;
    use riskplan_service::store::Store;
    use std::sync::atomic::AtomicBool;
    use std::sync::{Arc, OnceLock};
    use std::time::{Duration, Instant};

    /// The request types, selected by the first byte of a `request` input (`b % 6`;
    /// `(b / 6) % 2` selects JSON or bincode).
    pub const REQUEST_KINDS: [&str; 6] = ["apply", "plan", "verify", "risk", "obstacle_put", "scene_put"];

    /// Deadline of a fuzzed verify or risk job, and cap of a fuzzed plan: short, so
    /// that every input's handling stays far below libFuzzer's one-second hang limit.
    const JOB_BUDGET: Duration = Duration::from_millis(100);

    const FIXTURES: [(&str, &str); 2] = [
        ("illustrative-3", include_str!("../../../scenes/illustrative-3.json")),
        ("example-b-lane-change", include_str!("../../../scenes/example-b-lane-change.json")),
    ];
    const SCRATCH: &str = "scratch";

    fn registry() -> &'static Registry {
        static REG: OnceLock<Registry> = OnceLock::new();
        REG.get_or_init(|| {
            // tmpfs where there is one: applies are persisted with fsync
            let base = ["/dev/shm"].iter().map(std::path::PathBuf::from).find(|p| p.is_dir());
            let dir = base.unwrap_or_else(std::env::temp_dir).join(format!("riskplan-fuzz-{}", std::process::id()));
            let _ = std::fs::remove_dir_all(&dir);
            let reg = Registry::new(Store::open(&dir).expect("fuzz data directory"));
            for (name, text) in FIXTURES {
                let json = serde_json::from_str(text).expect("fixture scene");
                reg.put_scene(name, json).expect("fixture scene loads");
            }
            reg
        })
    }

    /// Decodes and handles one request: byte 0 selects the type and codec, the rest
    /// is the payload; byte 1's low bit selects the scene of plan, verify and risk.
    pub fn request(data: &[u8]) {
        let Some((&sel, rest)) = data.split_first() else { return };
        let kind = REQUEST_KINDS[sel as usize % REQUEST_KINDS.len()];
        let codec = if (sel as usize / REQUEST_KINDS.len()) % 2 == 0 { Codec::Json } else { Codec::Bincode };
        let reg = registry();
        let fixture = FIXTURES[rest.first().map_or(0, |b| (b & 1) as usize)].0;
        let check = |r: Result<Vec<u8>, ServiceError>| {
            if let Err(e) = r {
                let reply = e.reply();
                assert_eq!(reply.code, e.code());
                assert!(!codec.encode(&reply).is_empty());
            }
        };
        match kind {
            "apply" => {
                let Ok(req) = codec.decode::<ApplyRequest>(rest) else { return };
                reset_scratch(reg);
                check(
                    handlers::apply(reg, SCRATCH, req)
                        .map(|rev| codec.encode(&ApplyReply { scene: SCRATCH.into(), revision: rev })),
                );
            }
            "plan" => {
                let Ok(req) = codec.decode::<PlanRequest>(rest) else { return };
                let entry = reg.get(fixture).expect("fixture");
                let cancel = Arc::new(AtomicBool::new(false));
                let t = Instant::now();
                check(handlers::plan(reg, &entry, &req, JOB_BUDGET, t, cancel).map(|r| codec.encode(&r)));
            }
            "verify" => {
                let Ok(req) = codec.decode::<VerifyRequest>(rest) else { return };
                let entry = reg.get(fixture).expect("fixture");
                let until = Instant::now() + JOB_BUDGET;
                check(handlers::verify_request(&entry, &req, until).map(|r| codec.encode(&r)));
            }
            "risk" => {
                let Ok(req) = codec.decode::<RiskRequest>(rest) else { return };
                let entry = reg.get(fixture).expect("fixture");
                let until = Instant::now() + JOB_BUDGET;
                check(handlers::risk(&entry, &req, until).map(|r| codec.encode(&r)));
            }
            "obstacle_put" => {
                // puts are JSON only (the server reads them so); the codec bit is ignored
                let Ok(put) = Codec::Json.decode::<ObstaclePut>(rest) else { return };
                reset_scratch(reg);
                check(reg.put_obstacle(SCRATCH, "fuzz", &put).map(|_| Vec::new()));
            }
            _ => {
                let Ok(json) = Codec::Json.decode::<serde_json::Value>(rest) else { return };
                check(reg.put_scene(SCRATCH, json).map(|_| Vec::new()));
            }
        }
    }

    /// Puts the scratch scene back to illustrative-3, so that applies do not pile up.
    fn reset_scratch(reg: &Registry) {
        let json = serde_json::from_str(FIXTURES[0].1).expect("fixture scene");
        reg.put_scene(SCRATCH, json).expect("fixture scene loads");
    }
}
