//! The metrics endpoint of `serve --metrics ADDR`: a small HTTP/1.1 responder on the
//! server's tokio runtime, its own task beside the Zenoh loops (it never touches them).
//! `GET /metrics` (or `HEAD`) answers 200 with the text exposition of [`Metrics`] in the
//! format its `Accept` header prefers ([`negotiate`]): OpenMetrics 1.0.0 by default, the
//! Prometheus text format 0.0.4 when `text/plain` is preferred; any other path 404, any
//! other method 405, a request line that is not HTTP/1.x 400. One request per
//! connection (`Connection: close`), one task per connection, at most
//! [`MAX_CONNECTIONS`] at once (more are answered 503 without waiting). A request head must arrive within [`READ_TIMEOUT`] and [`MAX_HEAD_BYTES`]
//! (else 408 or 431), and a reply is abandoned after [`WRITE_TIMEOUT`]: a slow or
//! malformed client holds one connection slot for a few seconds at most, never the
//! server. No HTTP stack is pulled in for this (no hyper in the dependency tree).

use super::error::MetricsError;
use super::metrics::{Format, Metrics};
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
    let format = negotiate(head);
    match metrics.encode(format) {
        Ok(text) => response(200, format.content_type(), text.as_bytes(), with_body),
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

/// The media type of the OpenMetrics offer (the type and subtype of
/// [`Format::OpenMetrics`]'s content type) and the `version` it is.
const OPENMETRICS: (&str, &str, &str) = ("application", "openmetrics-text", "1.0.0");

/// The media type of the Prometheus text offer ([`Format::Text`]) and its `version`;
/// `text/plain` without a version is this format too (Prometheus's "Exposition
/// formats": version 0.0.4 is the text format's only version before 1.0.0).
const PROMETHEUS_TEXT: (&str, &str, &str) = ("text", "plain", "0.0.4");

/// The weight of a media range without a `q` parameter, in thousandths (RFC 9110
/// §12.4.2: a qvalue is 0 to 1 with at most three decimals; 1 when not given).
const FULL_WEIGHT: u16 = 1000;

/// The format a request head asks for by its `Accept` header fields (RFC 9110
/// §12.5.1): the Prometheus text format 0.0.4 when the ranges that match `text/plain;
/// version=0.0.4` give it a higher weight than the ranges that match
/// `application/openmetrics-text; version=1.0.0` give OpenMetrics; OpenMetrics
/// otherwise — on a tie (`*/*`), with no `Accept` field, and when neither is acceptable
/// (no 406: a scraper that names neither still gets the default). The head was read
/// within [`MAX_HEAD_BYTES`], so this reads at most that much.
fn negotiate(head: &[u8]) -> Format {
    let Some(accept) = accept_field(head) else { return Format::OpenMetrics };
    let ranges = media_ranges(&accept);
    if weight(&ranges, PROMETHEUS_TEXT) > weight(&ranges, OPENMETRICS) {
        Format::Text
    } else {
        Format::OpenMetrics
    }
}

/// The value of the head's `Accept` field: its field name matched without regard to
/// case (RFC 9110 §5.1), several `Accept` lines joined by commas as one list (§5.3),
/// and a line continued by obsolete folding (a line starting with a space or a tab)
/// taken as one space (RFC 9112 §5.2). `None` without one; a line that is not UTF-8 is
/// left out.
fn accept_field(head: &[u8]) -> Option<String> {
    let mut value: Option<String> = None;
    let mut in_accept = false;
    for line in head.split(|&b| b == b'\n').skip(1) {
        let line = line.strip_suffix(b"\r").unwrap_or(line);
        if line.first().is_some_and(|b| *b == b' ' || *b == b'\t') {
            if let (true, Some(v), Ok(more)) = (in_accept, value.as_mut(), std::str::from_utf8(line)) {
                v.push(' ');
                v.push_str(more.trim());
            }
            continue;
        }
        in_accept = false;
        let Some((name, v)) = std::str::from_utf8(line).ok().and_then(|l| l.split_once(':')) else { continue };
        if name.eq_ignore_ascii_case("accept") {
            in_accept = true;
            let v = v.trim();
            match value.as_mut() {
                Some(all) => {
                    all.push_str(", ");
                    all.push_str(v);
                }
                None => value = Some(v.to_string()),
            }
        }
    }
    value
}

/// One element of an `Accept` list (RFC 9110 §12.5.1): a media range, the `version`
/// parameter it names if any, and its weight.
#[derive(Debug, PartialEq)]
struct MediaRange {
    /// The type, lower case; `*` for any.
    kind: String,
    /// The subtype, lower case; `*` for any.
    subtype: String,
    /// Its `version` parameter (the one parameter of either offer that tells formats
    /// apart; `charset` and the rest are not compared).
    version: Option<String>,
    /// Its `q`, in thousandths ([`FULL_WEIGHT`] when not given).
    q: u16,
}

impl MediaRange {
    /// How specific the range is (RFC 9110 §12.5.1: the most specific reference that
    /// matches has precedence): `*/*`, `type/*`, `type/subtype`, and that with a version.
    fn specificity(&self) -> u8 {
        match (self.kind.as_str(), self.subtype.as_str()) {
            ("*", _) => 0,
            (_, "*") => 1,
            _ => 2 + u8::from(self.version.is_some()),
        }
    }

    /// Whether the range includes the offer (type, subtype, version).
    fn matches(&self, (kind, subtype, version): (&str, &str, &str)) -> bool {
        (self.kind == "*" || self.kind == kind)
            && (self.subtype == "*" || self.subtype == subtype)
            && self.version.as_deref().is_none_or(|v| v == version)
    }
}

/// The weight an `Accept` list gives an offer: the `q` of its most specific matching
/// range (the highest of several equally specific ones), 0 when none matches.
fn weight(ranges: &[MediaRange], offer: (&str, &str, &str)) -> u16 {
    ranges.iter().filter(|r| r.matches(offer)).max_by_key(|r| (r.specificity(), r.q)).map_or(0, |r| r.q)
}

/// The elements of an `Accept` value (RFC 9110 §12.5.1: `#( media-range [ weight ] )`,
/// a media range `type/subtype` or `type/*` or `*/*` followed by `;`-separated
/// parameters, a token or a quoted string each; `q` ends the media type's parameters,
/// and what follows it is ignored). An element that does not parse, or whose `q` is no
/// qvalue, is left out, as if it were not there.
fn media_ranges(accept: &str) -> Vec<MediaRange> {
    split_outside_quotes(accept, ',').into_iter().filter_map(media_range).collect()
}

fn media_range(element: &str) -> Option<MediaRange> {
    let mut parts = split_outside_quotes(element, ';').into_iter();
    let (kind, subtype) = parts.next()?.trim().split_once('/')?;
    let (kind, subtype) = (kind.to_ascii_lowercase(), subtype.to_ascii_lowercase());
    if !is_token(&kind) || !is_token(&subtype) || (kind == "*" && subtype != "*") {
        return None;
    }
    let (mut version, mut q) = (None, FULL_WEIGHT);
    for p in parts {
        let (name, value) = p.split_once('=')?;
        let (name, value) = (name.trim(), unquote(value.trim())?);
        if name.eq_ignore_ascii_case("q") {
            q = qvalue(&value)?;
            break;
        }
        if name.eq_ignore_ascii_case("version") {
            version = Some(value);
        }
    }
    Some(MediaRange { kind, subtype, version, q })
}

/// `s` split at each `sep` that is not inside a quoted string (RFC 9110 §5.6.4); the
/// empty elements of a list (`a,,b`) dropped (§5.6.1).
fn split_outside_quotes(s: &str, sep: char) -> Vec<&str> {
    let (mut out, mut start, mut quoted, mut escaped) = (Vec::new(), 0, false, false);
    for (i, c) in s.char_indices() {
        match c {
            _ if escaped => escaped = false,
            '\\' if quoted => escaped = true,
            '"' => quoted = !quoted,
            c if c == sep && !quoted => {
                out.push(&s[start..i]);
                start = i + c.len_utf8();
            }
            _ => {}
        }
    }
    out.push(&s[start..]);
    out.retain(|e| !e.trim().is_empty());
    out
}

/// A parameter value: a token as is, a quoted string without its quotes and escapes
/// (RFC 9110 §5.6.4); `None` for neither.
fn unquote(v: &str) -> Option<String> {
    match v.strip_prefix('"') {
        None => is_token(v).then(|| v.to_string()),
        Some(rest) => {
            let inner = rest.strip_suffix('"')?;
            let mut out = String::with_capacity(inner.len());
            let mut chars = inner.chars();
            while let Some(c) = chars.next() {
                out.push(if c == '\\' { chars.next()? } else { c });
            }
            Some(out)
        }
    }
}

/// A token of RFC 9110 §5.6.2 (`1*tchar`).
fn is_token(s: &str) -> bool {
    !s.is_empty() && s.bytes().all(|b| b.is_ascii_alphanumeric() || b"!#$%&'*+-.^_`|~".contains(&b))
}

/// A qvalue of RFC 9110 §12.4.2 in thousandths: `0`, `0.` and up to three digits,
/// `1`, or `1.` and up to three zeros; `None` for anything else.
fn qvalue(v: &str) -> Option<u16> {
    let (int, frac) = v.split_once('.').unwrap_or((v, ""));
    if frac.len() > 3 || !frac.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    let thousandths = format!("{frac:0<3}").parse::<u16>().ok()?;
    match int {
        "0" => Some(thousandths),
        "1" if thousandths == 0 => Some(FULL_WEIGHT),
        _ => None,
    }
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
        // the exposition's format follows the request's Accept field: a cache keys on it
        200 => head.push_str("Vary: Accept\r\n"),
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
        let m = Metrics::new(super::super::proto::Role::Primary, "h");
        let get = answer(b"GET /metrics HTTP/1.1\r\nHost: x\r\n\r\n", &m);
        assert_eq!(status_of(&get), 200);
        let text = String::from_utf8_lossy(&get);
        assert!(text.contains(&format!("Content-Type: {}\r\n", Format::OpenMetrics.content_type())), "{text}");
        assert!(text.contains("Vary: Accept\r\n"), "{text}");
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

    /// The format chosen for a request whose head has these header lines.
    fn chosen(fields: &str) -> Format {
        negotiate(format!("GET /metrics HTTP/1.1\r\nHost: x\r\n{fields}\r\n").as_bytes())
    }

    #[test]
    fn accept_chooses_the_format() {
        use Format::{OpenMetrics as Om, Text};
        for (accept, want) in [
            // what scrapers send: Prometheus 2.x, Prometheus without OpenMetrics, curl
            (
                "application/openmetrics-text;version=1.0.0,application/openmetrics-text;version=0.0.1;q=0.75,\
                 text/plain;version=0.0.4;q=0.5,*/*;q=0.1",
                Om,
            ),
            ("text/plain;version=0.0.4;q=1,*/*;q=0.1", Text),
            ("*/*", Om),
            // text/plain asked for, with or without the version, by its range or its type
            ("text/plain; version=0.0.4", Text),
            ("text/plain", Text),
            ("text/plain; charset=utf-8", Text),
            ("TEXT/Plain; Version=0.0.4", Text),
            ("text/plain; version=\"0.0.4\"", Text),
            ("text/*", Text),
            ("text/plain;q=0.5, */*;q=0.1", Text),
            ("text/plain;q=0.2, application/json", Text),
            // OpenMetrics preferred, or equal: OpenMetrics
            ("application/openmetrics-text", Om),
            ("application/openmetrics-text; version=1.0.0; charset=utf-8", Om),
            ("text/plain;q=0.5, application/openmetrics-text;q=0.5", Om),
            ("text/plain;q=0.5, application/openmetrics-text;q=0.6", Om),
            ("text/plain;q=0.5, application/*", Om),
            ("text/plain;q=0.9, */*", Om),
            // OpenMetrics refused: the text format wins even with a lower weight than 1
            ("application/openmetrics-text;q=0, text/plain;q=0.1", Text),
            ("application/openmetrics-text;q=0, */*;q=0.5", Text),
            // a more specific range overrides a wider one
            ("*/*;q=0.1, text/plain;q=0", Om),
            ("text/*;q=0.9, text/plain;q=0.1, */*;q=0.5", Om),
            ("text/plain;q=0.1, text/plain;version=0.0.4;q=0.9, */*;q=0.5", Text),
            // another version of a type does not match the offer
            ("text/plain; version=1.0.0", Om),
            ("text/plain; version=1.0.0, */*;q=0.1", Om),
            ("application/openmetrics-text; version=0.0.1, text/plain;q=0.5", Text),
            // neither acceptable, or nothing that parses: the default
            ("application/json", Om),
            ("text/html;q=0", Om),
            ("text/plain;q=0", Om),
            ("", Om),
            ("garbage", Om),
            ("*/plain", Om),
            // a q that is no qvalue leaves its element out
            ("text/plain;q=2", Om),
            ("text/plain;q=0.5000", Om),
            ("text/plain;q=-1, */*;q=0.1", Om),
            ("text/plain;q=NaN", Om),
            ("text/plain;q=1.0", Text),
            ("text/plain;q=1.", Text),
            ("text/plain;q=0.001, application/openmetrics-text;q=0", Text),
            // parameters after q are not the media type's
            ("text/plain;q=0.5;version=1.0.0, */*;q=0.1", Text),
            // quoted strings may hold the separators
            ("text/plain; foo=\"a,b;c\"; q=0.8, */*;q=0.5", Text),
            ("text/plain; version=\"0.0.4\\\"\", */*", Om),
            // empty list elements and spaces
            (" , text/plain ,, ", Text),
            ("text/plain\t;\tq=0.7", Text),
        ] {
            assert_eq!(chosen(&format!("Accept: {accept}\r\n")), want, "Accept: {accept}");
        }
    }

    #[test]
    fn the_accept_field_is_found_in_the_head() {
        assert_eq!(chosen(""), Format::OpenMetrics, "no Accept: the default");
        assert_eq!(chosen("accept: text/plain\r\n"), Format::Text);
        assert_eq!(chosen("ACCEPT:text/plain\r\n"), Format::Text);
        assert_eq!(chosen("User-Agent: x\r\nAccept: text/plain\r\nX-Other: y\r\n"), Format::Text);
        // LF-only line ends, as head_end allows
        assert_eq!(negotiate(b"GET /metrics HTTP/1.1\nAccept: text/plain\n\n"), Format::Text);
        // several Accept lines are one list
        assert_eq!(chosen("Accept: application/openmetrics-text;q=0.2\r\nAccept: text/plain\r\n"), Format::Text);
        assert_eq!(chosen("Accept: text/plain;q=0.2\r\nAccept: */*\r\n"), Format::OpenMetrics);
        // a folded line continues the field
        assert_eq!(chosen("Accept: application/openmetrics-text;q=0.1,\r\n text/plain\r\n"), Format::Text);
        // other fields are not read, nor field names that only end or start like it
        assert_eq!(chosen("X-Accept: text/plain\r\n"), Format::OpenMetrics);
        assert_eq!(chosen("Accept-Encoding: text/plain\r\n"), Format::OpenMetrics);
        assert_eq!(chosen("Content-Type: text/plain\r\n"), Format::OpenMetrics);
        // the request line is not a field
        assert_eq!(negotiate(b"GET /metrics?Accept:text/plain HTTP/1.1\r\n\r\n"), Format::OpenMetrics);
        // a line that is not UTF-8 is left out, the others are read
        assert_eq!(negotiate(b"GET /metrics HTTP/1.1\r\nX-Bin: \xff\xfe\r\nAccept: text/plain\r\n\r\n"), Format::Text);
        assert_eq!(negotiate(b"GET /metrics HTTP/1.1\r\nAccept: \xff\r\nAccept: text/plain\r\n\r\n"), Format::Text);
    }

    #[test]
    fn qvalues_and_media_ranges_parse_as_rfc_9110_says() {
        assert_eq!(qvalue("0"), Some(0));
        assert_eq!(qvalue("0.5"), Some(500));
        assert_eq!(qvalue("0.05"), Some(50));
        assert_eq!(qvalue("0.123"), Some(123));
        assert_eq!(qvalue("1"), Some(1000));
        assert_eq!(qvalue("1.000"), Some(1000));
        for bad in ["", ".5", "0.1234", "1.001", "2", "01", "-0", "+1", "0,5", "1e0", "inf", "0.5 "] {
            assert_eq!(qvalue(bad), None, "{bad:?}");
        }
        let r = media_range(" Text/Plain ; Version=\"0.0.4\" ; charset=utf-8 ; Q=0.3 ").unwrap();
        assert_eq!(
            r,
            MediaRange { kind: "text".into(), subtype: "plain".into(), version: Some("0.0.4".into()), q: 300 }
        );
        assert_eq!(r.specificity(), 3);
        assert_eq!(media_range("*/*").map(|r| r.specificity()), Some(0));
        assert_eq!(media_range("text/*").map(|r| r.specificity()), Some(1));
        assert_eq!(media_range("text/plain").map(|r| r.specificity()), Some(2));
        for bad in ["", "text", "text/", "/plain", "*/plain", "te xt/plain", "text/plain; version", "text/plain;q"] {
            assert_eq!(media_range(bad), None, "{bad:?}");
        }
        assert_eq!(split_outside_quotes(r#"a, "b,c" ,, d"#, ','), vec!["a", r#" "b,c" "#, " d"]);
        assert_eq!(unquote(r#""a\"b""#).as_deref(), Some(r#"a"b"#));
        assert_eq!(unquote(r#""open"#), None);
        assert_eq!(unquote("a b"), None);
    }

    #[test]
    fn text_plain_is_answered_in_the_0_0_4_format() {
        let m = Metrics::new(super::super::proto::Role::Primary, "h");
        let get = answer(b"GET /metrics HTTP/1.1\r\nAccept: text/plain; version=0.0.4\r\n\r\n", &m);
        assert_eq!(status_of(&get), 200);
        let text = String::from_utf8_lossy(&get);
        let (head, body) = text.split_once("\r\n\r\n").unwrap_or_default();
        let head = format!("{head}\r\n");
        assert!(head.contains("Content-Type: text/plain; version=0.0.4; charset=utf-8\r\n"), "{head}");
        assert!(head.contains("Vary: Accept\r\n"), "{head}");
        assert!(head.contains(&format!("Content-Length: {}\r\n", body.len())), "{head}");
        assert_eq!(body, m.encode(Format::Text).unwrap());
        assert!(body.contains("# TYPE riskplan_build_info gauge\n") && !body.contains("# EOF"), "{body}");
        // HEAD is negotiated too
        let head_only = answer(b"HEAD /metrics HTTP/1.1\r\nAccept: text/plain\r\n\r\n", &m);
        let head_only = String::from_utf8_lossy(&head_only);
        assert!(head_only.contains("Content-Type: text/plain; version=0.0.4; charset=utf-8\r\n"), "{head_only}");
        assert!(head_only.ends_with("\r\n\r\n"), "{head_only}");
        // errors are plain text whatever the Accept
        let missing = answer(b"GET /nope HTTP/1.1\r\nAccept: application/openmetrics-text\r\n\r\n", &m);
        assert_eq!(status_of(&missing), 404);
        assert!(!String::from_utf8_lossy(&missing).contains("Vary:"));
    }

    #[test]
    fn head_ends() {
        assert_eq!(head_end(b"GET / HTTP/1.1\r\n\r\nrest"), Some(18));
        assert_eq!(head_end(b"GET / HTTP/1.1\n\n"), Some(16));
        assert_eq!(head_end(b"GET / HTTP/1.1\r\nHost: x\r\n"), None);
    }
}
