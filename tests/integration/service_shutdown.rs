//! A SIGTERM while a long plan runs ends the service promptly: shutdown cancels the
//! running plans (their cancellation flags are registered with the server) instead
//! of waiting for their time limits.

use crate::common;
use crate::common::server::{serve, sigterm_and_wait, KillOnDrop};
use std::process::Stdio;
use std::time::{Duration, Instant};

/// How soon the server must be gone after SIGTERM.
const SHUTDOWN_LIMIT: Duration = Duration::from_secs(2);

/// A scene without a plan: the goal sits inside rings of obstacles (each ring a
/// degree-8 polynomial, so edge checks are not free); RRT-SOS searches until its
/// iteration limit or time limit — tens of seconds.
fn enclosed_goal_scene() -> serde_json::Value {
    let obstacles: Vec<_> = (0..6)
        .map(|i| serde_json::json!({"id": format!("ring{i}"), "poly": format!("w{i} - (x1^2 + x2^2 - 0.25)^4")}))
        .collect();
    let params: serde_json::Map<String, serde_json::Value> = (0..6)
        .map(|i| {
            (
                format!("w{i}"),
                serde_json::json!({"dist": "uniform", "low": 0.0001 * (1.0 + 0.01 * i as f64), "high": 0.00012}),
            )
        })
        .collect();
    serde_json::json!({
        "format": "riskplan-scene/1", "name": "enclosed", "dim": 2,
        "workspace": {"lower": [-1, -1], "upper": [1, 1]}, "horizon": [0, 1], "risk": 0.1,
        "params": params, "obstacles": obstacles, "start": [0.9, 0.9], "goal": [0, 0]
    })
}

fn client(endpoint: &str, args: &[&str]) -> std::process::Command {
    let mut c = common::bin();
    c.args(["client", "--endpoint", endpoint, "--json"]).args(args);
    c
}

#[test]
fn sigterm_during_a_long_plan_ends_the_service_within_2_s() {
    let mut srv = serve(
        &[("enclosed", enclosed_goal_scene().to_string())],
        &["--workers", "1", "--max-plan-seconds", "60"],
        &["riskplan: ready"],
    );
    let (server, rx, endpoint) = (&mut srv.child, &srv.lines, srv.endpoint.clone());
    let _plan = KillOnDrop(
        client(&endpoint, &["--timeout", "60", "plan", "--scene", "enclosed", "--time-limit", "50"])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    // wait until the plan is running on the worker
    let running = Instant::now();
    loop {
        let out = client(&endpoint, &["status"]).output().unwrap();
        let status: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap_or_default();
        if status["queue"]["running"].as_u64() == Some(1) {
            break;
        }
        assert!(running.elapsed() < Duration::from_secs(20), "the plan never started: {status}");
        std::thread::sleep(Duration::from_millis(100));
    }
    std::thread::sleep(Duration::from_millis(500));
    sigterm_and_wait(server, SHUTDOWN_LIMIT);
    // and it got there by cancelling the plan, not by abandoning it
    let log: Vec<String> = rx.try_iter().collect();
    assert!(
        log.iter().any(|l| l.contains("shutting down") && l.contains("cancelled=1")),
        "no record of the cancelled plan in the log: {log:?}"
    );
}
