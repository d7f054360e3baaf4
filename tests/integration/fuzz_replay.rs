//! The fuzz targets of `riskplan_testkit::fuzzing` on stable, in every test run: each file of
//! `fuzz/corpus/<target>/` (what cargo-fuzz found, minimised, plus the seeds), the
//! seeds built here from the repository's scenes and protocol examples (requests in
//! both JSON and bincode), and a seeded mutation run from them. A panic names the
//! input (hex) and writes it to a file, ready to be replayed with
//! `cargo +nightly fuzz run <target> <file>`.
//!
//! `RISKPLAN_WRITE_FUZZ_SEEDS=1` writes the seeds built here into `fuzz/corpus/` (the
//! starting corpus of the cargo-fuzz targets).

use crate::common;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// An input taking longer than this is reported as a hang. libFuzzer's runs use one
/// second (`-timeout=1`); here, in a test binary that shares two cores with other
/// tests, the limit is looser so that it only catches real hangs.
const HANG_LIMIT: Duration = Duration::from_secs(5);

fn corpus_dir(target: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fuzz").join("corpus").join(target)
}

fn corpus(target: &str) -> Vec<Vec<u8>> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(corpus_dir(target))
        .map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).filter(|p| p.is_file()).collect())
        .unwrap_or_default();
    files.sort();
    files.iter().map(|p| std::fs::read(p).expect("corpus file")).collect()
}

fn scene_texts() -> Vec<String> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(common::reference_dir()).expect("scenes/") {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "json") {
            out.push(std::fs::read_to_string(p).unwrap());
        }
    }
    out.sort();
    out
}

fn poly_seeds() -> Vec<Vec<u8>> {
    let mut out: Vec<Vec<u8>> = Vec::new();
    for text in scene_texts() {
        let json: serde_json::Value = serde_json::from_str(&text).unwrap();
        for o in json["obstacles"].as_array().into_iter().flatten() {
            if let Some(p) = o["poly"].as_str() {
                out.push(p.as_bytes().to_vec());
            }
        }
    }
    for s in ["(((x1+1)^32)^32)^32", "(x1+x2+w+1)^30", "1e4000*x1 - w", "-(-(-x1))", "3/7*t^2*w - 0.25e-3", "x1^64"] {
        out.push(s.as_bytes().to_vec());
    }
    out
}

fn scene_seeds() -> Vec<Vec<u8>> {
    scene_texts().into_iter().map(String::into_bytes).collect()
}

#[cfg(feature = "proto")]
fn request_seeds() -> Vec<Vec<u8>> {
    use riskplan_service::proto::*;
    use riskplan_testkit::fuzzing::REQUEST_KINDS;
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("proto").join("examples");
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).collect();
    files.sort();
    let mut out = Vec::new();
    let mut push = |kind: &str, json: &[u8], bincode: Option<Vec<u8>>| {
        let k = REQUEST_KINDS.iter().position(|&n| n == kind).unwrap() as u8;
        out.push([&[k][..], json].concat());
        if let Some(b) = bincode {
            out.push([&[k + REQUEST_KINDS.len() as u8][..], &b].concat());
        }
    };
    fn both<T: serde::de::DeserializeOwned + serde::Serialize>(json: &[u8]) -> Option<Vec<u8>> {
        let v: T = Codec::Json.decode(json).ok()?;
        Some(Codec::Bincode.encode(&v))
    }
    for p in files {
        let name = p.file_name().unwrap().to_string_lossy().to_string();
        let bytes = std::fs::read(&p).unwrap();
        match name.split('.').next().unwrap() {
            "apply_request" => push("apply", &bytes, both::<ApplyRequest>(&bytes)),
            "plan_request" => push("plan", &bytes, both::<PlanRequest>(&bytes)),
            "verify_request" => push("verify", &bytes, both::<VerifyRequest>(&bytes)),
            "risk_request" => push("risk", &bytes, both::<RiskRequest>(&bytes)),
            "obstacle_put" => push("obstacle_put", &bytes, None),
            _ => {}
        }
    }
    for text in scene_texts().into_iter().take(3) {
        push("scene_put", text.as_bytes(), None);
    }
    out
}

/// One mutation of `input` (libFuzzer's simplest kinds: bit flips, byte changes,
/// inserts, deletes, chunk copies, splices from another input, interesting bytes).
fn mutate(rng: &mut ChaCha8Rng, input: &[u8], other: &[u8]) -> Vec<u8> {
    let mut v = input.to_vec();
    for _ in 0..rng.random_range(1..=4) {
        let n = v.len();
        match rng.random_range(0..7) {
            0 if n > 0 => {
                let i = rng.random_range(0..n);
                v[i] ^= 1 << rng.random_range(0..8);
            }
            1 if n > 0 => {
                let i = rng.random_range(0..n);
                v[i] = rng.random();
            }
            2 => {
                let i = rng.random_range(0..=n);
                const BYTES: &[u8] = b"()^-+*/0123456789e.x1tw \"{}[],:\xff\x00\xfd";
                v.insert(i, BYTES[rng.random_range(0..BYTES.len())]);
            }
            3 if n > 0 => {
                let i = rng.random_range(0..n);
                let len = rng.random_range(1..=(n - i).min(16));
                v.drain(i..i + len);
            }
            4 if n > 1 => {
                let i = rng.random_range(0..n);
                let len = rng.random_range(1..=(n - i).min(32));
                let chunk = v[i..i + len].to_vec();
                let at = rng.random_range(0..=n);
                v.splice(at..at, chunk);
            }
            5 if !other.is_empty() => {
                let i = rng.random_range(0..other.len());
                let len = rng.random_range(1..=(other.len() - i).min(64));
                let at = rng.random_range(0..=n);
                v.splice(at..at, other[i..i + len].iter().copied());
            }
            _ if n > 0 => {
                let i = rng.random_range(0..n);
                v[i] = [0u8, 0xff, 0x7f, 0x80, b'9', b'^', b'('][rng.random_range(0..7)];
            }
            _ => v.push(rng.random()),
        }
    }
    v
}

fn run_one(target: &str, f: fn(&[u8]), input: &[u8]) {
    let t = Instant::now();
    if let Err(p) = catch_unwind(AssertUnwindSafe(|| f(input))) {
        let file = std::env::temp_dir().join(format!("riskplan-fuzz-crash-{target}-{}", std::process::id()));
        let _ = std::fs::write(&file, input);
        let msg = p.downcast_ref::<String>().cloned().or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()));
        panic!(
            "fuzz target {target} panicked ({}) on input {} (written to {})",
            msg.unwrap_or_default(),
            hex(input),
            file.display()
        );
    }
    let took = t.elapsed();
    assert!(took < HANG_LIMIT, "fuzz target {target} took {took:?} on input {}", hex(input));
}

fn hex(b: &[u8]) -> String {
    b.iter().take(256).map(|x| format!("{x:02x}")).collect::<String>() + if b.len() > 256 { "…" } else { "" }
}

/// Replays the corpus and the seeds, then `mutations` seeded mutations of them.
fn replay(target: &str, f: fn(&[u8]), seeds: Vec<Vec<u8>>, mutations: usize) {
    if std::env::var("RISKPLAN_WRITE_FUZZ_SEEDS").is_ok_and(|v| v == "1") {
        write_seeds(&corpus_dir(target), &seeds);
    }
    let mut inputs = corpus(target);
    inputs.extend(seeds);
    assert!(!inputs.is_empty(), "no inputs for fuzz target {target}");
    for input in &inputs {
        run_one(target, f, input);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(0x5eed_f022);
    for _ in 0..mutations {
        let a = &inputs[rng.random_range(0..inputs.len())];
        let b = &inputs[rng.random_range(0..inputs.len())];
        let m = mutate(&mut rng, a, b);
        run_one(target, f, &m);
    }
}

fn write_seeds(dir: &Path, seeds: &[Vec<u8>]) {
    std::fs::create_dir_all(dir).unwrap();
    for s in seeds {
        // named like libFuzzer's corpus files: by a hash of the content
        let h = s.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| (h ^ b as u64).wrapping_mul(0x100_0000_01b3));
        std::fs::write(dir.join(format!("seed-{h:016x}")), s).unwrap();
    }
}

#[test]
fn fuzz_poly_parser() {
    replay("poly", riskplan_testkit::fuzzing::poly_text, poly_seeds(), common::size("FUZZ_MUTATIONS", 1000, 30_000));
}

#[test]
fn fuzz_scene_loader() {
    replay("scene", riskplan_testkit::fuzzing::scene_json, scene_seeds(), common::size("FUZZ_MUTATIONS", 300, 3000));
}

#[cfg(feature = "proto")]
#[test]
fn fuzz_requests() {
    replay("request", riskplan_testkit::fuzzing::request, request_seeds(), common::size("FUZZ_MUTATIONS", 300, 3000));
}
