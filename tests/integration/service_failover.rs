//! Failover of the Rust client's reads (proto/README.md "Failover"): a read sent
//! to a server's own key is waited for only while that server's liveliness token is up. A
//! fake server — a token and a queryable on its own keys that holds every query without
//! answering, in a Zenoh session of the test — stands beside a real `riskplan serve`; its
//! token is withdrawn after 1 s. Every read must then be answered by the real server within
//! about the poll interval of the token's departure: without the watch, a read held by the
//! fake waits its whole 10 s timeout (what a server killed with a read in flight can do).
//! Loopback only.

use crate::common::server::{reference_scene, serve};
use riskplan_service::proto::Codec;
use riskplan_service::Client;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

#[test]
fn a_read_held_by_a_server_whose_token_goes_is_sent_elsewhere() {
    let real = serve(
        &[("illustrative-3", reference_scene("illustrative-3"))],
        &["--workers", "1", "--server-id", "real-1"],
        &["riskplan: ready"],
    );
    let rt = tokio::runtime::Runtime::new().unwrap();
    rt.block_on(async {
        let mut cfg = zenoh::Config::default();
        cfg.insert_json5("mode", "\"client\"").unwrap();
        cfg.insert_json5("connect/endpoints", &serde_json::to_string(&[&real.endpoint]).unwrap()).unwrap();
        cfg.insert_json5("scouting/multicast/enabled", "false").unwrap();
        let fake = zenoh::open(cfg).await.unwrap();
        let held: Arc<Mutex<Vec<zenoh::query::Query>>> = Arc::default();
        let keep = held.clone();
        let _queryable = fake
            .declare_queryable("riskplan/@fake-1/**")
            .callback(move |q| keep.lock().unwrap().push(q))
            .await
            .unwrap();
        let token = fake.liveliness().declare_token("riskplan/_servers/fake-1/replica").await.unwrap();
        let c = Client::connect(&real.endpoint, Duration::from_secs(10), Codec::Json).await.unwrap();
        let seen = Instant::now();
        while c.servers().len() < 2 {
            assert!(seen.elapsed() < Duration::from_secs(10), "the client never saw both servers: {:?}", c.servers());
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        let withdraw = tokio::spawn(async move {
            tokio::time::sleep(Duration::from_secs(1)).await;
            token.undeclare().await.unwrap();
        });
        let started = Instant::now();
        let mut slowest = Duration::ZERO;
        while started.elapsed() < Duration::from_millis(1500) {
            let t = Instant::now();
            let st = c.status().await.expect("every read answered");
            assert_eq!(st.server_id, "real-1");
            slowest = slowest.max(t.elapsed());
        }
        withdraw.await.unwrap();
        assert!(!held.lock().unwrap().is_empty(), "no read went to the fake server");
        assert!(slowest > Duration::from_millis(500), "a read was held by the fake: {slowest:?}");
        assert!(slowest < Duration::from_millis(2500), "a read waited {slowest:?} for a server that had gone");
        held.lock().unwrap().clear();
        c.close().await;
        let _ = fake.close().await;
    });
}
