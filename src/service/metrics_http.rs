//! The metrics endpoint of `serve --metrics ADDR`: a small HTTP/1.1 responder on the
//! server's tokio runtime, its own task beside the Zenoh loops (it never touches them).
//! `GET /metrics` (or `HEAD`) answers 200 with the OpenMetrics text exposition of
//! [`Metrics`]; any other path 404, any other method 405, a request line that is not
//! HTTP/1.x 400. One request per connection (`Connection: close`), one task per
//! connection, at most [`MAX_CONNECTIONS`] at once (more are answered 503 without
//! waiting). A request head must arrive within [`READ_TIMEOUT`] and [`MAX_HEAD_BYTES`]
//! (else 408 or 431), and a reply is abandoned after [`WRITE_TIMEOUT`]: a slow or
//! malformed client holds one connection slot for a few seconds at most, never the
//! server. No HTTP stack is pulled in for this (no hyper in the dependency tree).

use super::error::MetricsError;
use super::metrics::Metrics;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::Semaphore;
use tracing::{debug, warn};

/// The largest request head read (request line and headers); a larger one is 431.
pub(crate) const MAX_HEAD_BYTES: usize = 8 * 1024;
/// Time for a client to send its request head, from its connection; then 408.
pub(crate) const READ_TIMEOUT: Duration = Duration::from_secs(5);
/// Time for a client to take the reply; then the connection is dropped.
pub(crate) const WRITE_TIMEOUT: Duration = Duration::from_secs(10);
/// Connections served at once; more are answered 503 at once.
pub(crate) const MAX_CONNECTIONS: usize = 16;
/// What a client may still send after the reply (read and thrown away before closing,
/// so that the close does not reset the reply away), and for how long.
const DRAIN_BYTES: usize = 64 * 1024;
const DRAIN_TIMEOUT: Duration = Duration::from_millis(500);

/// The OpenMetrics text format's media type.
pub(crate) const CONTENT_TYPE: &str = "application/openmetrics-text; version=1.0.0; charset=utf-8";

/// The path that serves the exposition.
pub(crate) const PATH: &str = "/metrics";

/// Listens on `addr` (before the server opens its Zenoh session: a bad address stops
/// the start with a typed error); returns the listener and the address it is bound to
/// (port 0 asks the system for a free one).
pub(crate) async fn bind(addr: SocketAddr) -> Result<(TcpListener, SocketAddr), MetricsError> {
    let listener = TcpListener::bind(addr).await.map_err(|source| MetricsError::Bind { addr, source })?;
    let local = listener.local_addr().map_err(|source| MetricsError::LocalAddr { addr, source })?;
    Ok((listener, local))
}

/// Serves scrapes on `listener` until the task is aborted.
pub(crate) fn spawn(listener: TcpListener, metrics: Arc<Metrics>) -> tokio::task::JoinHandle<()> {
    tokio::spawn(accept_loop(listener, metrics))
}

async fn accept_loop(listener: TcpListener, metrics: Arc<Metrics>) {
    let slots = Arc::new(Semaphore::new(MAX_CONNECTIONS));
    loop {
        let (stream, peer) = match listener.accept().await {
            Ok(c) => c,
            Err(e) => {
                // out of file descriptors, a connection reset before it was taken: wait
                // a little instead of spinning, and go on
                warn!("metrics: cannot accept a connection: {e}");
                tokio::time::sleep(Duration::from_millis(100)).await;
                continue;
            }
        };
        let Ok(permit) = slots.clone().try_acquire_owned() else {
            // every slot taken: refuse at once, without waiting on this client
            let _ = stream.try_write(&response(503, "text/plain; charset=utf-8", b"too many connections\n", true));
            debug!(%peer, "metrics: connection refused, {MAX_CONNECTIONS} already open");
            continue;
        };
        let m = metrics.clone();
        tokio::spawn(async move {
            serve_connection(stream, &m).await;
            drop(permit);
        });
    }
}

/// Why no request head was read.
#[derive(Debug, PartialEq)]
enum HeadError {
    /// The client closed (or reset) the connection before sending anything.
    Closed,
    /// The head grew past [`MAX_HEAD_BYTES`].
    TooLarge,
}

/// Answers the one request of a connection.
async fn serve_connection(mut stream: TcpStream, metrics: &Metrics) {
    let reply = match tokio::time::timeout(READ_TIMEOUT, read_head(&mut stream)).await {
        Err(_) => Some(response(408, "text/plain; charset=utf-8", b"request head not received in time\n", true)),
        Ok(Err(HeadError::Closed)) => None,
        Ok(Err(HeadError::TooLarge)) => {
            Some(response(431, "text/plain; charset=utf-8", b"request head too large\n", true))
        }
        Ok(Ok(head)) => Some(answer(&head, metrics)),
    };
    let Some(reply) = reply else { return };
    let sent = tokio::time::timeout(WRITE_TIMEOUT, async {
        stream.write_all(&reply).await?;
        stream.shutdown().await
    })
    .await;
    if matches!(sent, Ok(Ok(()))) {
        // what the client still sends (a body, a pipelined request) is read and dropped,
        // briefly, so that closing with unread data does not reset the reply away
        let _ = tokio::time::timeout(DRAIN_TIMEOUT, async {
            let mut buf = [0u8; 4096];
            let mut seen = 0;
            while seen < DRAIN_BYTES {
                match stream.read(&mut buf).await {
                    Ok(0) | Err(_) => break,
                    Ok(n) => seen += n,
                }
            }
        })
        .await;
    }
}

/// Reads up to the end of the request head (an empty line), at most
/// [`MAX_HEAD_BYTES`]. A connection closed after some bytes returns what came (the
/// request line decides: most likely 400).
async fn read_head(stream: &mut TcpStream) -> Result<Vec<u8>, HeadError> {
    let mut head = Vec::with_capacity(1024);
    let mut buf = [0u8; 1024];
    loop {
        let n = match stream.read(&mut buf).await {
            Ok(0) | Err(_) if head.is_empty() => return Err(HeadError::Closed),
            Ok(0) | Err(_) => return Ok(head),
            Ok(n) => n,
        };
        head.extend_from_slice(&buf[..n]);
        if let Some(end) = head_end(&head) {
            head.truncate(end);
            return Ok(head);
        }
        if head.len() > MAX_HEAD_BYTES {
            return Err(HeadError::TooLarge);
        }
    }
}

/// Where the head ends (after its empty line: CRLF CRLF, or LF LF from lenient clients).
fn head_end(b: &[u8]) -> Option<usize> {
    let crlf = b.windows(4).position(|w| w == b"\r\n\r\n").map(|i| i + 4);
    let lf = b.windows(2).position(|w| w == b"\n\n").map(|i| i + 2);
    match (crlf, lf) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// The reply to a request head.
fn answer(head: &[u8], metrics: &Metrics) -> Vec<u8> {
    const TEXT: &str = "text/plain; charset=utf-8";
    let line = head.split(|&b| b == b'\n').next().unwrap_or_default();
    let line = line.strip_suffix(b"\r").unwrap_or(line);
    let Some((method, path)) = request_line(line) else {
        return response(400, TEXT, b"bad request: expected METHOD /path HTTP/1.x\n", true);
    };
    let with_body = match method {
        "GET" => true,
        "HEAD" => false,
        _ => return response(405, TEXT, b"method not allowed: GET /metrics\n", true),
    };
    if path != PATH {
        return response(404, TEXT, b"not found: the metrics are at GET /metrics\n", with_body);
    }
    match metrics.encode() {
        Ok(text) => response(200, CONTENT_TYPE, text.as_bytes(), with_body),
        Err(e) => {
            warn!("metrics: cannot encode the exposition: {e}");
            response(500, TEXT, b"cannot encode the metrics\n", with_body)
        }
    }
}

/// The method and the path (without its query) of an HTTP/1.x request line
/// `METHOD SP target SP HTTP/1.x`; `None` for anything else.
fn request_line(line: &[u8]) -> Option<(&str, &str)> {
    let line = std::str::from_utf8(line).ok()?;
    let mut parts = line.split(' ');
    let (method, target, version) = (parts.next()?, parts.next()?, parts.next()?);
    let token = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_uppercase());
    if parts.next().is_some() || !token(method) || !target.starts_with('/') || !version.starts_with("HTTP/1.") {
        return None;
    }
    Some((method, target.split('?').next().unwrap_or(target)))
}

fn reason(status: u16) -> &'static str {
    match status {
        200 => "OK",
        400 => "Bad Request",
        404 => "Not Found",
        405 => "Method Not Allowed",
        408 => "Request Timeout",
        431 => "Request Header Fields Too Large",
        503 => "Service Unavailable",
        _ => "Internal Server Error",
    }
}

/// A complete HTTP/1.1 response; without the body for a `HEAD` (its length still
/// given).
fn response(status: u16, content_type: &str, body: &[u8], with_body: bool) -> Vec<u8> {
    let mut head = format!(
        "HTTP/1.1 {status} {}\r\nContent-Type: {content_type}\r\nContent-Length: {}\r\nCache-Control: no-store\r\n\
         Connection: close\r\n",
        reason(status),
        body.len()
    );
    match status {
        405 => head.push_str("Allow: GET, HEAD\r\n"),
        503 => head.push_str("Retry-After: 1\r\n"),
        _ => {}
    }
    head.push_str("\r\n");
    let mut out = head.into_bytes();
    if with_body {
        out.extend_from_slice(body);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn status_of(reply: &[u8]) -> u16 {
        let text = String::from_utf8_lossy(reply);
        text.split(' ').nth(1).and_then(|s| s.parse().ok()).unwrap_or(0)
    }

    #[test]
    fn request_lines() {
        assert_eq!(request_line(b"GET /metrics HTTP/1.1"), Some(("GET", "/metrics")));
        assert_eq!(request_line(b"GET /metrics?x=1 HTTP/1.0"), Some(("GET", "/metrics")));
        assert_eq!(request_line(b"POST /metrics HTTP/1.1"), Some(("POST", "/metrics")));
        for bad in [
            &b""[..],
            b"GET",
            b"GET /metrics",
            b"GET /metrics HTTP/2",
            b"GET  /metrics HTTP/1.1",
            b"get /metrics HTTP/1.1",
            b"GET metrics HTTP/1.1",
            b"GET /metrics HTTP/1.1 extra",
            b"\xff\xfe /metrics HTTP/1.1",
        ] {
            assert_eq!(request_line(bad), None, "{:?}", String::from_utf8_lossy(bad));
        }
    }

    #[test]
    fn answers_by_method_and_path() {
        let m = Metrics::new("primary", "h");
        let get = answer(b"GET /metrics HTTP/1.1\r\nHost: x\r\n\r\n", &m);
        assert_eq!(status_of(&get), 200);
        let text = String::from_utf8_lossy(&get);
        assert!(text.contains(&format!("Content-Type: {CONTENT_TYPE}\r\n")), "{text}");
        assert!(text.ends_with("# EOF\n"), "{text}");
        let (head, body) = text.split_once("\r\n\r\n").unwrap_or_default();
        assert!(head.contains(&format!("Content-Length: {}\r\n", body.len())), "{head}");
        let head_only = answer(b"HEAD /metrics HTTP/1.1\r\n\r\n", &m);
        assert_eq!(status_of(&head_only), 200);
        assert!(head_only.ends_with(b"\r\n\r\n"));
        assert_eq!(status_of(&answer(b"GET / HTTP/1.1\r\n\r\n", &m)), 404);
        assert_eq!(status_of(&answer(b"GET /metricsx HTTP/1.1\r\n\r\n", &m)), 404);
        let post = answer(b"POST /metrics HTTP/1.1\r\n\r\n", &m);
        assert_eq!(status_of(&post), 405);
        assert!(String::from_utf8_lossy(&post).contains("Allow: GET, HEAD\r\n"));
        assert_eq!(status_of(&answer(b"\x00\x01\x02garbage\r\n\r\n", &m)), 400);
        assert_eq!(status_of(&answer(b"", &m)), 400);
    }

    #[test]
    fn head_ends() {
        assert_eq!(head_end(b"GET / HTTP/1.1\r\n\r\nrest"), Some(18));
        assert_eq!(head_end(b"GET / HTTP/1.1\n\n"), Some(16));
        assert_eq!(head_end(b"GET / HTTP/1.1\r\nHost: x\r\n"), None);
    }
}
