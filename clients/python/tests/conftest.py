"""Fixtures: the real `riskplan serve` binary on a free 127.0.0.1 port, a client, the
reference scenes (scenes/ of the repository), the golden examples and JSON Schemas of
proto/.

The server binary: $RISKPLAN_BIN, else target/release/riskplan, else
target/debug/riskplan (under $CARGO_TARGET_DIR first when it is set). With
RISKPLAN_REQUIRE_SERVER=1 (scripts/test.sh, CI), or when $RISKPLAN_BIN is set, a missing or
broken binary fails the whole run at once; otherwise (a developer running the offline
tests) the tests needing a server are skipped, and the summary says why."""
from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from pathlib import Path
from typing import List, Optional, Tuple

import pytest

import riskplan

REPO = Path(__file__).resolve().parents[3]
PROTO = REPO / "proto"
SCHEMAS = PROTO / "schemas"
EXAMPLES = PROTO / "examples"
# The reference scenes live in the repository; $RISKPLAN_SCENES may point elsewhere.
SCENES = Path(os.environ.get("RISKPLAN_SCENES") or REPO / "scenes")

START_LIMIT_S = 30.0
READY_LINE = "riskplan: ready"          # printed once the stored scenes are in
LISTENING_LINE = "riskplan: listening on"  # printed as soon as queries are received


def require_server() -> bool:
    """RISKPLAN_REQUIRE_SERVER=1 (or any value but empty and 0): no server, no run."""
    return os.environ.get("RISKPLAN_REQUIRE_SERVER", "").strip() not in ("", "0")


def riskplan_bin() -> Optional[Path]:
    """$RISKPLAN_BIN, else target/release/riskplan, else target/debug/riskplan (under
    $CARGO_TARGET_DIR, then under the repository)."""
    env = os.environ.get("RISKPLAN_BIN")
    if env:
        return Path(env)
    for p in _bin_candidates():
        if p.is_file() and os.access(p, os.X_OK):
            return p
    return None


def _bin_candidates() -> List[Path]:
    targets = [Path(os.environ["CARGO_TARGET_DIR"])] if os.environ.get("CARGO_TARGET_DIR") else []
    targets.append(REPO / "target")
    return [t / kind / "riskplan" for t in targets for kind in ("release", "debug")]


def serve_problem(binary: Optional[Path]) -> Optional[str]:
    """Why ``binary`` cannot serve (None: it can): missing, not executable, or
    `serve --help` fails."""
    if binary is None:
        where = ", ".join(map(str, _bin_candidates()))
        return f"$RISKPLAN_BIN is not set and none of {where} is an executable file"
    if not binary.is_file():
        return f"{binary} is not a file"
    if not os.access(binary, os.X_OK):
        return f"{binary} is not executable"
    try:
        r = subprocess.run([str(binary), "serve", "--help"], capture_output=True, text=True, errors="replace",
                           timeout=20)
    except (OSError, subprocess.TimeoutExpired) as e:
        return f"`{binary} serve --help` did not run: {e}"
    if r.returncode != 0:
        return f"`{binary} serve --help` exited with {r.returncode}: {(r.stderr or r.stdout).strip()[-500:]}"
    return None


def has_serve(binary: Optional[Path]) -> bool:
    return serve_problem(binary) is None


_SERVER_CHECK: Optional[Tuple[Optional[Path], Optional[str]]] = None


def server_check() -> Tuple[Optional[Path], Optional[str]]:
    """(binary, problem) for this run, computed once."""
    global _SERVER_CHECK
    if _SERVER_CHECK is None:
        b = riskplan_bin()
        _SERVER_CHECK = (b, serve_problem(b))
    return _SERVER_CHECK


def server_is_required() -> bool:
    """A missing server fails the run: RISKPLAN_REQUIRE_SERVER=1, or $RISKPLAN_BIN is set
    (asking for a binary that does not work is an error, not a reason to skip)."""
    return require_server() or bool(os.environ.get("RISKPLAN_BIN"))


def pytest_sessionstart(session):
    if not SCENES.is_dir() or not any(SCENES.glob("*.json")):
        pytest.exit(f"no reference scenes: {SCENES} is not a directory holding *.json "
                    f"(scenes/ of the repository, or $RISKPLAN_SCENES)", returncode=1)
    binary, problem = server_check()
    if problem is not None and server_is_required():
        why = "RISKPLAN_REQUIRE_SERVER is set" if require_server() else "$RISKPLAN_BIN is set"
        pytest.exit(f"no working riskplan server binary ({why}): {problem}", returncode=1)


def pytest_report_header(config):
    binary, problem = server_check()
    if problem is None:
        return [f"riskplan server: {binary}", f"reference scenes: {SCENES}"]
    return [f"riskplan server: NONE ({problem}): tests needing a server are SKIPPED "
            "(set RISKPLAN_REQUIRE_SERVER=1 to make this an error)", f"reference scenes: {SCENES}"]


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    binary, problem = server_check()
    if problem is None:
        return
    skipped = [r for r in terminalreporter.stats.get("skipped", []) if NO_SERVER in str(r.longrepr)]
    if skipped:
        terminalreporter.write_sep("=", "riskplan server missing", yellow=True, bold=True)
        terminalreporter.write_line(f"{len(skipped)} tests needing a server were SKIPPED: {problem}")
        terminalreporter.write_line("Build it (cargo build --release) or set $RISKPLAN_BIN; "
                                    "RISKPLAN_REQUIRE_SERVER=1 makes a missing server fail the run.")


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Server:
    """One `riskplan serve` process listening on 127.0.0.1 only."""

    def __init__(self, binary: Path, data_dir: Path, extra: Optional[List[str]] = None, port: Optional[int] = None,
                 scheme: str = "tcp", host: str = "127.0.0.1"):
        self.binary = binary
        self.data_dir = Path(data_dir)
        self.extra = list(extra or []) + os.environ.get("RISKPLAN_SERVE_ARGS", "").split()
        self.port = port or free_port()
        self.endpoint = f"{scheme}/{host}:{self.port}"
        # a server of a cluster connects to the router and listens on nothing
        self.listens = not any(a == "--mode" and b == "client" for a, b in zip(self.extra, self.extra[1:]))
        self.proc: Optional[subprocess.Popen] = None
        self.lines: List[str] = []
        self._ready = threading.Event()
        self._ready_line = READY_LINE

    @property
    def argv(self) -> List[str]:
        listen = ["--listen", self.endpoint] if self.listens else []
        return [str(self.binary), "serve", *listen, "--data", str(self.data_dir), *self.extra]

    def start(self, limit: float = START_LIMIT_S, ready_line: str = READY_LINE) -> "Server":
        """Starts the process and waits for `ready_line` on its stderr (by default the
        line printed once the stored scenes are loaded)."""
        self.lines = []
        self._ready_line = ready_line
        self._ready.clear()
        self.proc = subprocess.Popen(self.argv, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                     stderr=subprocess.PIPE, text=True, errors="replace")
        threading.Thread(target=self._drain, args=(self.proc,), daemon=True).start()
        deadline = time.monotonic() + limit
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError(f"riskplan serve exited with {self.proc.returncode}: {self.log()}")
            if self._ready.wait(0.2):
                return self
            # also accept a server that answers status without printing the line
            if ready_line == READY_LINE and self.listens and self.endpoint.startswith("tcp/") and self._status_answers():
                return self
        self.kill()
        raise RuntimeError(f"riskplan serve not ready after {limit} s: {self.log()}")

    def _drain(self, proc: subprocess.Popen) -> None:
        for line in proc.stderr:
            self.lines.append(line.rstrip("\n"))
            if self._ready_line in line:
                self._ready.set()

    def _status_answers(self) -> bool:
        try:
            with riskplan.Client(self.endpoint, timeout=1.0) as c:
                return c.status().get("state", "ready") == "ready"
        except riskplan.RiskplanError:
            return False

    def log(self) -> str:
        return "\n".join(self.lines[-40:])

    def kill(self, sig: int = signal.SIGKILL) -> None:
        """Kills the process (SIGKILL by default) and waits for it."""
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=15)

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.kill(signal.SIGTERM)

    def client(self, timeout: float = 30.0) -> riskplan.Client:
        return riskplan.Client(self.endpoint, timeout=timeout)


NO_SERVER = "no riskplan binary with `serve`"


@pytest.fixture(scope="session")
def binary() -> Path:
    b, problem = server_check()
    if problem is not None:
        if server_is_required():  # normally stopped in pytest_sessionstart already
            pytest.fail(f"{NO_SERVER}: {problem}", pytrace=False)
        pytest.skip(f"{NO_SERVER}: {problem}")
    return b


@pytest.fixture(scope="session")
def server(binary, tmp_path_factory) -> Server:
    s = Server(binary, tmp_path_factory.mktemp("riskplan-data")).start()
    yield s
    s.stop()


@pytest.fixture(scope="session")
def client(server) -> riskplan.Client:
    c = server.client()
    yield c
    c.close()


def load_scene(name: str) -> dict:
    return json.loads((SCENES / f"{name}.json").read_text())


@pytest.fixture
def scene3() -> dict:
    """illustrative-3: a static disk, (-1,-1) → (1,1), Δ = 0.1."""
    return load_scene("illustrative-3")


@pytest.fixture
def unique(request):
    """A fresh scene name per call, derived from the test's name."""
    base = "".join(c if c.isalnum() or c in "_-." else "-" for c in request.node.name)[:80]

    def make(tag: str = "") -> str:
        return f"{base}{('-' + tag) if tag else ''}-{uuid.uuid4().hex[:8]}"

    return make


# An enclosed goal: a thin ring of radius 0.2-0.5 around (0.5, 0.5) (P >= 0 on the ring,
# P < 0 inside and outside), so no path reaches the goal at its centre.
RING_SCENE = {
    "format": "riskplan-scene/1",
    "name": "ring",
    "description": "goal enclosed by a ring-shaped obstacle: no plan exists",
    "dim": 2,
    "workspace": {"lower": [-1, -1], "upper": [1, 1]},
    "horizon": [0, 1],
    "risk": 0.1,
    "params": {"w": {"dist": "uniform", "low": -0.001, "high": 0.001}},
    "obstacles": [
        {"id": "ring",
         "poly": "(0.25 - (x1 - 0.5)^2 - (x2 - 0.5)^2) * ((x1 - 0.5)^2 + (x2 - 0.5)^2 - 0.04) + w"}
    ],
    "start": [-1, -1],
    "goal": [0.5, 0.5],
}


@pytest.fixture
def ring_scene() -> dict:
    return json.loads(json.dumps(RING_SCENE))


def load_schema(message: str) -> dict:
    return json.loads((SCHEMAS / f"{message}.schema.json").read_text())


_VALIDATORS = {}


def validate(message: str, payload) -> None:
    """Validates ``payload`` against proto/schemas/<message>.schema.json (raises)."""
    import jsonschema

    v = _VALIDATORS.get(message)
    if v is None:
        schema = load_schema(message)
        v = _VALIDATORS[message] = jsonschema.Draft202012Validator(schema, format_checker=jsonschema.FormatChecker())
    errors = sorted(v.iter_errors(payload), key=lambda e: list(e.absolute_path))
    if errors:
        detail = "; ".join(f"{'/'.join(map(str, e.absolute_path)) or '<root>'}: {e.message[:300]}" for e in errors[:5])
        raise AssertionError(f"{message} does not validate: {detail}")


def wait_for(predicate, limit: float = 10.0, every: float = 0.05, what: str = "condition"):
    """Polls ``predicate`` until it returns a truthy value (returned) or ``limit`` s pass."""
    deadline = time.monotonic() + limit
    last_exc = None
    while time.monotonic() < deadline:
        try:
            v = predicate()
            if v:
                return v
        except riskplan.RiskplanError as e:  # e.g. unknown_scene until a put lands
            last_exc = e
        time.sleep(every)
    raise AssertionError(f"timed out after {limit} s waiting for {what} (last error: {last_exc!r})")
