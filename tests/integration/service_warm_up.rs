//! `riskplan serve` warms scenes of many obstacles in the background (docs/design.md
//! §3.11, "Warm-ups"): a preloaded scene of 64 uncertain disks once loaded, another once
//! applied, a third once put; the metrics count each warm-up done, and the first plan on
//! each finds the scene index complete at its risk levels (a covers hit). With
//! `--no-warm-up` nothing is warmed and the same first plans build the index themselves
//! (covers misses). The plans are the same either way. A SIGTERM during a warm-up ends the
//! server promptly. Loopback only.

use crate::common::growth;
use crate::common::server::{free_port, serve, sigterm_and_wait};
use riskplan_service::proto::{ApplyRequest, Change, ChangeOp, Codec, EmbeddedJson, PlanRequest};
use riskplan_service::Client;
use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

/// The growth family of the benches (`disks_scene`: `n` uncertain disks at constant
/// density, start and goal in opposite corners), named `name`.
fn disks(n: usize, seed: u64, name: &str) -> serde_json::Value {
    let mut json: serde_json::Value = serde_json::from_str(&growth::disks_scene(n, seed)).unwrap();
    json["name"] = name.into();
    json
}

/// The samples of `GET /metrics` as series → value.
fn scrape(addr: &str) -> std::collections::BTreeMap<String, f64> {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(15))).unwrap();
    s.write_all(b"GET /metrics HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n").unwrap();
    let mut reply = String::new();
    s.read_to_string(&mut reply).unwrap();
    let (_, body) = reply.split_once("\r\n\r\n").expect("a head");
    body.lines()
        .filter(|l| !l.starts_with('#'))
        .filter_map(|l| l.rsplit_once(' ').map(|(k, v)| (k.to_string(), v.parse().unwrap())))
        .collect()
}

/// Waits until the metrics count `done` warm-ups done (none stopped or skipped): a bounded
/// wait for work that runs after the replies, not a timing.
fn wait_for_warm_ups(metrics: &str, done: f64) {
    let t = Instant::now();
    loop {
        let s = scrape(metrics);
        let count = |outcome: &str| s.get(&format!("riskplan_scene_warm_ups_total{{outcome=\"{outcome}\"}}")).copied();
        if count("done") == Some(done) {
            return;
        }
        assert_eq!((count("stopped"), count("skipped")), (Some(0.0), Some(0.0)), "{s:#?}");
        assert!(t.elapsed() < Duration::from_secs(120), "{done} warm-ups never done: {s:#?}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn scenes_of_many_obstacles_are_warm_before_their_first_plans_unless_turned_off() {
    let (preloaded, applied, put) = (disks(64, 5, "pre"), disks(48, 6, "disks"), disks(32, 7, "put"));
    let mut lengths = Vec::new();
    for warm in [true, false] {
        let metrics = format!("127.0.0.1:{}", free_port());
        let announced = format!("riskplan: metrics on http://{metrics}/metrics");
        let mut args = vec!["--workers", "1", "--metrics", &metrics];
        if !warm {
            args.push("--no-warm-up");
        }
        let server = serve(&[("pre", preloaded.to_string())], &args, &[&announced, "riskplan: ready"]);
        if warm {
            wait_for_warm_ups(&metrics, 1.0);
        }
        let rt = tokio::runtime::Runtime::new().unwrap();
        let c = rt.block_on(Client::connect(&server.endpoint, Duration::from_secs(60), Codec::Bincode)).unwrap();
        let request = ApplyRequest { scene: Some(EmbeddedJson(applied.clone())), ..Default::default() };
        assert_eq!(rt.block_on(c.apply("disks", &request)).expect("an apply").revision, 1);
        // a scene put (no reply: the scene is there once a read finds it)
        rt.block_on(c.put_scene("put", &put)).expect("a put");
        if warm {
            wait_for_warm_ups(&metrics, 3.0);
        } else {
            let t = Instant::now();
            while rt.block_on(c.get_scene("put")).is_err() {
                assert!(t.elapsed() < Duration::from_secs(60), "the put scene never arrived");
                std::thread::sleep(Duration::from_millis(20));
            }
        }
        for scene in ["pre", "disks", "put"] {
            let plan = rt.block_on(c.plan(scene, &PlanRequest::default())).expect("a plan");
            assert!(plan.certified, "{scene}");
            lengths.push((warm, scene, plan.stats.path_length));
        }
        // an update of one obstacle takes over what was built for the others: not warmed
        let moved = Change {
            op: ChangeOp::Put.into(),
            id: applied["obstacles"][0]["id"].as_str().unwrap().into(),
            poly: Some(applied["obstacles"][0]["poly"].as_str().unwrap().replace("(x2 - ", "(x2 - 0.5 - ")),
            params: None,
            pedestrian: None,
        };
        let request = ApplyRequest { changes: Some(vec![moved]), ..Default::default() };
        assert_eq!(rt.block_on(c.apply("disks", &request)).expect("an apply").revision, 2);
        assert!(rt.block_on(c.plan("disks", &PlanRequest::default())).expect("a plan").certified);
        let s = scrape(&metrics);
        let covers = |which: &str| s.get(&format!("riskplan_scene_cache_{which}_total{{cache=\"covers\"}}")).copied();
        let warm_ups =
            |outcome: &str| s.get(&format!("riskplan_scene_warm_ups_total{{outcome=\"{outcome}\"}}")).copied();
        if warm {
            // (the plan after the update: its kernel took over the covers of 47 obstacles
            // and builds the moved one's)
            assert_eq!((covers("hits"), covers("misses")), (Some(3.0), Some(1.0)), "{s:#?}");
            assert_eq!((warm_ups("done"), warm_ups("skipped")), (Some(3.0), Some(0.0)), "{s:#?}");
        } else {
            assert_eq!((covers("hits"), covers("misses")), (Some(0.0), Some(4.0)), "{s:#?}");
            for outcome in ["done", "stopped", "skipped"] {
                assert_eq!(warm_ups(outcome), Some(0.0), "{outcome}: {s:#?}");
            }
        }
        rt.block_on(c.close());
    }
    // what was built before a plan changes its cost, never its answer
    for k in 0..3 {
        assert_eq!(lengths[k].2, lengths[k + 3].2, "{lengths:?}");
    }
}

/// How soon the server must be gone after SIGTERM, a warm-up running.
const SHUTDOWN_LIMIT: Duration = Duration::from_secs(2);

#[test]
fn sigterm_during_a_warm_up_ends_the_service_promptly() {
    // 512 disks: their warm-up takes over a second in a release build, longer in this one
    let mut srv = serve(&[("big", disks(512, 8, "big").to_string())], &["--workers", "1"], &["warm-up started"]);
    std::thread::sleep(Duration::from_millis(200));
    let server = &mut srv.child;
    sigterm_and_wait(server, SHUTDOWN_LIMIT);
    // stopped by the shutdown, not finished meanwhile (then this test would prove nothing)
    let log: Vec<String> = srv.lines.try_iter().collect();
    assert!(
        log.iter().any(|l| l.contains("warm-up") && l.contains("outcome=Stopped")),
        "no record of the stopped warm-up in the log: {log:?}"
    );
}
