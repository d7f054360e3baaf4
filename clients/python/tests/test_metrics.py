"""`riskplan serve --metrics`: the Prometheus endpoint scraped with urllib, as Prometheus
would, around requests sent with the Python client (the counts per kind and outcome, the
histograms' sample counts, the gauges, build info), and bad HTTP answered 404/405 while the
server keeps answering Zenoh queries. Loopback only."""
from __future__ import annotations

import re
import socket
import urllib.error
import urllib.request

import pytest

import riskplan

from conftest import Server, free_port, load_scene, wait_for

CONTENT_TYPE = "application/openmetrics-text; version=1.0.0; charset=utf-8"
SAMPLE = re.compile(r"^([a-zA-Z_:][a-zA-Z0-9_:]*)(\{.*\})? (\S+)$")


@pytest.fixture(scope="module")
def metered(binary, tmp_path_factory):
    port = free_port()
    s = Server(binary, tmp_path_factory.mktemp("riskplan-metrics"),
               extra=["--metrics", f"127.0.0.1:{port}", "--server-id", "py-metrics"]).start()
    s.metrics_url = f"http://127.0.0.1:{port}/metrics"
    assert any(f"riskplan: metrics on {s.metrics_url}" in line for line in s.lines), s.log()
    yield s
    s.stop()


def scrape(url: str) -> dict:
    """GET /metrics: {series: value}, the series as written (name and labels)."""
    with urllib.request.urlopen(url, timeout=10) as r:
        assert r.status == 200
        assert r.headers["Content-Type"] == CONTENT_TYPE
        text = r.read().decode()
    assert text.endswith("# EOF\n"), text[-200:]
    out = {}
    for line in text.splitlines():
        if line.startswith("#"):
            continue
        m = SAMPLE.match(line)
        assert m, f"not an OpenMetrics sample line: {line!r}"
        out[m.group(1) + (m.group(2) or "")] = float(m.group(3))
    return out


def requests_of(s: dict, kind: str, outcome: str) -> float:
    return s.get(f'riskplan_requests_total{{kind="{kind}",outcome="{outcome}"}}', 0.0)


def samples_of(s: dict, kind: str) -> float:
    return s[f'riskplan_request_duration_seconds_count{{kind="{kind}"}}']


def test_counts_follow_the_requests(metered, unique):
    url = metered.metrics_url
    name = unique()
    before = scrape(url)
    build = [k for k in before if k.startswith("riskplan_build_info{")]
    assert len(build) == 1 and before[build[0]] == 1.0, build
    assert 'role="primary"' in build[0] and 'server_id="py-metrics"' in build[0] and 'version="' in build[0]
    assert before["riskplan_ready"] == 1.0
    with metered.client() as c:
        rev = c.apply(name, scene=load_scene("illustrative-3"))
        plan = c.plan(name, time_limit=20.0)
        assert plan.certified
        assert c.verify(name, segment=([-1, -1], [1, 1]))["safe"] is False
        with pytest.raises(riskplan.UnknownSceneError):
            c.plan(name + "-missing", time_limit=5.0)
        with pytest.raises(riskplan.InvalidRequestError):
            c.verify(name, segment=([0], [1]))
        c.status()
    after = scrape(url)
    for kind, outcome, n in [("apply", "ok", 1), ("plan", "ok", 1), ("plan", "unknown_scene", 1),
                             ("verify", "ok", 1), ("verify", "invalid_request", 1), ("status", "ok", 1)]:
        assert requests_of(after, kind, outcome) - requests_of(before, kind, outcome) == n, (kind, outcome)
    for kind, n in [("apply", 1), ("plan", 2), ("verify", 2)]:
        assert samples_of(after, kind) - samples_of(before, kind) == n, kind
        assert after[f'riskplan_request_duration_seconds_bucket{{le="+Inf",kind="{kind}"}}'] == samples_of(after, kind)
    assert after[f'riskplan_scene_revision{{scene="{name}"}}'] == rev
    assert after["riskplan_scenes"] == before["riskplan_scenes"] + 1
    assert after["riskplan_queue_depth"] == 0 and after["riskplan_jobs_running"] == 0
    # a put has no reply: it shows in the metrics once applied. The put worker counts it
    # just after the scene is in, and a scrape is not one atomic snapshot (the counters
    # are written before the histograms): wait for the revision, the counter and the
    # histogram, each in the same scrape
    def put_applied():
        s = scrape(url)
        counted = (requests_of(s, "put", "ok") - requests_of(after, "put", "ok") >= 1
                   and samples_of(s, "put") - samples_of(after, "put") >= 1)
        return s if s[f'riskplan_scene_revision{{scene="{name}"}}'] == rev + 1 and counted else None

    with metered.client() as c:
        c.update_obstacle(name, "far", "0.01 - (x1 - 0.9)^2 - (x2 + 0.9)^2")
        s = wait_for(put_applied, what="the put in the metrics")
    assert requests_of(s, "put", "ok") - requests_of(after, "put", "ok") == 1
    assert samples_of(s, "put") - samples_of(after, "put") == 1


def test_bad_http_gets_4xx_and_the_server_goes_on(metered):
    base = metered.metrics_url.rsplit("/", 1)[0]
    for path, method, code in [("/", "GET", 404), ("/other", "GET", 404), ("/metrics", "POST", 405),
                               ("/metrics", "DELETE", 405)]:
        req = urllib.request.Request(base + path, method=method, data=b"x" if method == "POST" else None)
        with pytest.raises(urllib.error.HTTPError) as e:
            urllib.request.urlopen(req, timeout=10)
        assert e.value.code == code, (path, method)
    # garbage bytes: a 400, and the connection closed
    host, port = metered.metrics_url.split("/")[2].split(":")
    with socket.create_connection((host, int(port)), timeout=10) as s:
        s.sendall(b"\x00\x01\x02 not http at all\r\n\r\n")
        reply = b""
        while chunk := s.recv(4096):
            reply += chunk
    assert reply.startswith(b"HTTP/1.1 400 "), reply[:80]
    # Zenoh queries and scrapes still answered
    with metered.client() as c:
        assert c.status()["state"] == "ready"
    assert scrape(metered.metrics_url)["riskplan_ready"] == 1.0
