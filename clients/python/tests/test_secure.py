"""The secure deployment of deploy/secure: TLS on the transport, user/password
authentication, and roles by access control. A reader may plan, verify, query risk
and read scenes; only a writer may put, delete or apply. The server runs with the
very configuration files that deploy/secure/make-secrets.sh writes.

How a client sees a denial (Zenoh drops denied messages silently): a denied `put` or
`delete` returns normally and changes nothing (read the revision back, or use
`apply`); a denied `apply` gets no reply at all, so the query ends without one
(`NoReplyError` at once, or `QueryTimeoutError`)."""
from __future__ import annotations

import subprocess
import time

import pytest

import riskplan

from conftest import REPO, Server, load_scene

MAKE_SECRETS = REPO / "deploy" / "secure" / "make-secrets.sh"
DENIED = (riskplan.NoReplyError, riskplan.QueryTimeoutError)
SETTLE_S = 1.0   # how long a put is given to arrive before we say it was dropped


@pytest.fixture(scope="module")
def secrets(tmp_path_factory):
    d = tmp_path_factory.mktemp("secrets")
    subprocess.run([str(MAKE_SECRETS), str(d)], check=True, capture_output=True)
    return d


@pytest.fixture(scope="module")
def secure(binary, secrets, tmp_path_factory):
    srv = Server(binary, tmp_path_factory.mktemp("secure-data"), scheme="tls", host="localhost",
                 extra=["--config", str(secrets / "server.json5")]).start()
    yield srv
    srv.stop()


def role(secure, secrets, name, timeout=5.0):
    return riskplan.Client(secure.endpoint, timeout=timeout, config_file=secrets / f"{name}.json5")


def test_a_writer_may_apply_put_and_delete(secure, secrets):
    with role(secure, secrets, "writer") as w:
        rev = w.apply("w-scene", scene=load_scene("illustrative-3"))
        w.update_obstacle("w-scene", "pole", "0.01 - (x1 - 0.5)^2 - (x2 + 0.5)^2")
        deadline = time.monotonic() + 10
        while w.revision("w-scene") == rev:
            assert time.monotonic() < deadline, "the writer's put never arrived"
            time.sleep(0.05)
        w.put("riskplan/scenes/w-gone", load_scene("illustrative-3"))
        deadline = time.monotonic() + 10
        while not any(s["name"] == "w-gone" for s in w.status()["scenes"]):
            assert time.monotonic() < deadline, "the writer's scene put never arrived"
            time.sleep(0.05)
        w.delete_scene("w-gone")
        deadline = time.monotonic() + 10
        while any(s["name"] == "w-gone" for s in w.status()["scenes"]):
            assert time.monotonic() < deadline, "the writer's delete never arrived"
            time.sleep(0.05)


def test_a_reader_may_read_plan_verify_and_query_risk(secure, secrets):
    with role(secure, secrets, "writer") as w:
        w.apply("r-scene", scene=load_scene("illustrative-3"))
    with role(secure, secrets, "reader", timeout=30) as r:
        assert r.status()["state"] == "ready"
        assert r.get_scene("r-scene")["revision"] >= 1
        plan = r.plan("r-scene", time_limit=10)
        assert r.verify("r-scene", trajectory=plan)["safe"]
        assert r.risk("r-scene", [[0.9, 0.9]]).shape == (1,)
        assert r.query("riskplan/echo", {"ping": 3}) == {"ping": 3}


def test_a_reader_may_not_write(secure, secrets):
    with role(secure, secrets, "writer") as w:
        rev = w.apply("ro-scene", scene=load_scene("illustrative-3"))
    with role(secure, secrets, "reader", timeout=2.0) as r:
        t = time.monotonic()
        with pytest.raises(DENIED):
            r.apply("ro-scene", changes=[{"op": "delete", "id": next(iter(_ids(r, "ro-scene")))}])
        assert time.monotonic() - t < 3.0
        with pytest.raises(DENIED):
            r.apply("ro-new", scene=load_scene("illustrative-3"))
        # puts and deletes return normally and change nothing
        r.update_obstacle("ro-scene", "evil", "1 - x1^2")
        r.delete_scene("ro-scene")
        r.put("riskplan/scenes/ro-new", load_scene("illustrative-3"))
        time.sleep(SETTLE_S)
    with role(secure, secrets, "writer") as w:
        assert w.revision("ro-scene") == rev
        assert "evil" not in _ids(w, "ro-scene")
        with pytest.raises(riskplan.UnknownSceneError):
            w.get_scene("ro-new")
        assert w.status()["requests"].get("put", {}).get("served", 0) >= 0


def _ids(client, name):
    return [o["id"] for o in client.get_scene(name)["scene"]["obstacles"]]


def test_sessions_without_valid_credentials_or_tls_are_refused(secure, secrets, tmp_path):
    cfg = (secrets / "reader.json5").read_text()
    password = next(line.split(":", 1)[1] for line in (secrets / "users.txt").read_text().splitlines()
                    if line.startswith("reader:"))
    cases = {
        "unknown-user": cfg.replace('user: "reader"', 'user: "mallory"'),
        "wrong-password": cfg.replace(password, "0" * len(password)),
        # TLS with the deployment's CA but no credentials at all
        "anonymous": '{ mode: "client", scouting: { multicast: { enabled: false } }, '
                     f'transport: {{ link: {{ tls: {{ root_ca_certificate: "{secrets / "ca.pem"}" }} }} }} }}',
        # credentials, but the server's certificate cannot be checked
        "no-ca": cfg.replace(str(secrets / "ca.pem"), str(tmp_path / "missing-ca.pem")),
    }
    for name, text in cases.items():
        f = tmp_path / f"{name}.json5"
        f.write_text(text)
        with pytest.raises(riskplan.ConnectError):
            riskplan.Client(secure.endpoint, timeout=2, config_file=f)
    # plain TCP to the TLS port: no session
    with pytest.raises(riskplan.ConnectError):
        riskplan.Client(secure.endpoint.replace("tls/localhost", "tcp/127.0.0.1"), timeout=2)
