//! What a new user meets in the first hour with the service: errors that say what to do
//! (no server, a taken port, a mistyped scene name, a broken scene file), replies that name
//! the planner that ran, and the same plan for the same seed through the CLI and the
//! service in both encodings. Loopback only.

use crate::common;
use crate::common::run;
use crate::common::server::{free_port, reference_scene, serve};
use riskplan_app::PlanRequest as AppPlanRequest;
use riskplan_app::PlannerKind;
use riskplan_service::proto::{Codec, ErrorCode, PlanRequest};
use riskplan_service::{Client, ClientError};
use std::sync::Arc;
use std::time::Duration;

/// A client command with nothing listening says how to start a server, without Zenoh's
/// source paths.
#[test]
fn a_client_without_a_server_says_how_to_start_one() {
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let (code, _, err) = run(&["client", "--endpoint", &endpoint, "status"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains(&format!("cannot connect to {endpoint}")), "{err}");
    assert!(err.contains(&format!("riskplan serve --listen {endpoint}")), "{err}");
    assert!(!err.contains(".rs:"), "a source path: {err}");
}

/// A second server on a taken endpoint says so once, with the flag to listen elsewhere.
#[test]
fn a_second_server_on_a_taken_port_names_listen() {
    let first = serve(&[], &[], &["riskplan: ready"]);
    let dir = tempfile::tempdir().unwrap();
    let (code, _, err) =
        run(&["serve", "--listen", &first.endpoint, "--data", dir.path().join("data").to_str().unwrap()]);
    assert_ne!(code, 0, "{err}");
    assert!(err.contains(&format!("cannot listen on {}: the address is in use", first.endpoint)), "{err}");
    assert!(err.contains("--listen"), "{err}");
    assert!(!err.contains(".rs:"), "a source path: {err}");
    assert_eq!(err.matches("in use").count(), 1, "said more than once: {err}");
}

/// A mistyped scene name is answered with the name meant and the scenes the server holds;
/// the server's message is said once, its code after it; a broken scene file sent with
/// `client apply` is refused before sending, with its line and column.
#[test]
fn server_errors_name_what_to_do() {
    let server = serve(&[("illustrative-3", reference_scene("illustrative-3"))], &[], &["riskplan: ready"]);
    let (code, _, err) = run(&["client", "--endpoint", &server.endpoint, "plan", "--scene", "Illustrative-3"]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("unknown scene 'Illustrative-3': did you mean 'illustrative-3'? (loaded: illustrative-3)"),
        "{err}"
    );
    assert!(err.trim_end().ends_with("(unknown_scene)"), "{err}");
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.json");
    std::fs::write(&bad, "{\"format\": \"riskplan-scene/1\", \"name\": \"x\", \"dim\": 2,\n \"workspace\": 5}\n")
        .unwrap();
    let (code, _, err) =
        run(&["client", "--endpoint", &server.endpoint, "apply", "--scene", "x", "--file", bad.to_str().unwrap()]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("line 2 column"), "no line and column: {err}");
    // through the library: a typed error whose text says its message once
    let rt = tokio::runtime::Runtime::new().unwrap();
    rt.block_on(async {
        let c = Client::connect(&server.endpoint, Duration::from_secs(30), Codec::Json).await.unwrap();
        let e = c.plan("nope", &PlanRequest::default()).await.expect_err("an unknown scene");
        assert!(matches!(&e, ClientError::Server(r) if r.code == ErrorCode::UnknownScene), "{e:?}");
        let text = e.to_string();
        assert!(text.starts_with("unknown scene 'nope' (loaded: illustrative-3)"), "{text}");
        assert_eq!(text.matches("unknown scene").count(), 1, "{text}");
        c.close().await;
    });
}

/// The same seed gives the same pieces through the library (what `riskplan plan` runs),
/// the service with bincode and the service with JSON — the seeds that once ended in an
/// internal error among them; a receding request's reply names `receding`.
#[test]
fn the_same_seed_gives_the_same_plan_through_every_front_end() {
    let name = "illustrative-3";
    let server = serve(&[(name, reference_scene(name))], &[], &["riskplan: ready"]);
    let scene = Arc::new(common::scene(name));
    let rt = tokio::runtime::Runtime::new().unwrap();
    rt.block_on(async {
        let bin = Client::connect(&server.endpoint, Duration::from_secs(30), Codec::Bincode).await.unwrap();
        let json = Client::connect(&server.endpoint, Duration::from_secs(30), Codec::Json).await.unwrap();
        for seed in [1, 2, 3, 161, 192, 201] {
            let local = AppPlanRequest { seed, ..Default::default() };
            let (_, out) = local.run(scene.clone(), None).expect("a local plan");
            let pieces = out.trajectory.expect("a local trajectory").pieces;
            let req = PlanRequest { seed: Some(seed), ..Default::default() };
            for (codec, c) in [("bincode", &bin), ("json", &json)] {
                let reply = c.plan(name, &req).await.unwrap_or_else(|e| panic!("seed {seed} ({codec}): {e}"));
                assert!(reply.certified, "seed {seed} ({codec})");
                assert_eq!(reply.pieces, pieces, "seed {seed}: the service ({codec}) planned another trajectory");
            }
        }
        let receding = PlanRequest {
            t_now: Some(0.1),
            position: Some(vec![-1.0, -1.0]),
            horizon: Some(0.5),
            goal: Some(vec![1.0, 1.0]),
            ..Default::default()
        };
        let reply = bin.plan(name, &receding).await.expect("a receding plan");
        assert_eq!(reply.planner, PlannerKind::Receding);
        bin.close().await;
        json.close().await;
    });
}
