//! A `riskplan serve` process for the service tests: started on free loopback ports with
//! scenes preloaded, its stderr lines on a channel, killed when dropped.

use std::io::{BufRead, BufReader};
use std::process::{Child, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// How long a server may take to print every line it is waited for.
pub const START_LIMIT: Duration = Duration::from_secs(30);

/// A free loopback TCP port (bound and released: another process may take it meanwhile,
/// which the start then reports).
pub fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

/// A child process killed and reaped when dropped.
pub struct KillOnDrop(pub Child);

impl Drop for KillOnDrop {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A running server.
pub struct Serve {
    /// The process.
    pub child: KillOnDrop,
    /// Its stderr, line by line (what came after the lines waited for).
    pub lines: mpsc::Receiver<String>,
    /// Its Zenoh endpoint (`tcp/127.0.0.1:PORT`).
    pub endpoint: String,
    _dir: tempfile::TempDir,
}

/// Starts `riskplan serve --listen <free port> --data <temp> --preload <scenes> <args>` with
/// the scenes given as (name, file text), and waits until every line of `wait_for` has been
/// seen on its stderr (each as a substring of some line), within [`START_LIMIT`].
pub fn serve(scenes: &[(&str, String)], args: &[&str], wait_for: &[&str]) -> Serve {
    let dir = tempfile::tempdir().unwrap();
    let preload = dir.path().join("scenes");
    std::fs::create_dir(&preload).unwrap();
    for (name, text) in scenes {
        std::fs::write(preload.join(format!("{name}.json")), text).unwrap();
    }
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let mut child = KillOnDrop(
        super::bin()
            .args(["serve", "--listen", &endpoint])
            .args(args)
            .arg("--data")
            .arg(dir.path().join("data"))
            .arg("--preload")
            .arg(&preload)
            .env("OPENBLAS_NUM_THREADS", "1")
            .stderr(Stdio::piped())
            .spawn()
            .expect("start riskplan serve"),
    );
    let (tx, rx) = mpsc::channel();
    let stderr = child.0.stderr.take().unwrap();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    let t = Instant::now();
    let mut seen = vec![false; wait_for.len()];
    while !seen.iter().all(|&s| s) {
        let left = START_LIMIT.saturating_sub(t.elapsed());
        let line = rx
            .recv_timeout(left)
            .unwrap_or_else(|_| panic!("the server did not print {wait_for:?} within {START_LIMIT:?}"));
        for (s, w) in seen.iter_mut().zip(wait_for) {
            *s |= line.contains(w);
        }
    }
    Serve { child, lines: rx, endpoint, _dir: dir }
}

/// A reference scene's file text, to preload.
pub fn reference_scene(name: &str) -> String {
    std::fs::read_to_string(super::reference_dir().join(format!("{name}.json"))).unwrap()
}

/// Sends SIGTERM to a running server and waits for it to exit: it must have been running,
/// and exit successfully within `limit` (the wait gives up after 30 s).
pub fn sigterm_and_wait(server: &mut KillOnDrop, limit: Duration) {
    assert!(server.0.try_wait().unwrap().is_none(), "the server ended by itself");
    let sent = Instant::now();
    let kill = std::process::Command::new("kill").args(["-TERM", &server.0.id().to_string()]).status().unwrap();
    assert!(kill.success());
    loop {
        if let Some(st) = server.0.try_wait().unwrap() {
            let took = sent.elapsed();
            assert!(took < limit, "the server took {took:?} to stop after SIGTERM");
            assert!(st.success(), "the server exited with {st}");
            break;
        }
        assert!(sent.elapsed() < Duration::from_secs(30), "the server is still running 30 s after SIGTERM");
        std::thread::sleep(Duration::from_millis(20));
    }
}
