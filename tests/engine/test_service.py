"""The plan service, started for real (``handover serve --port 0`` in a subprocess, on a
copy of the built-in KB) and driven over HTTP on 127.0.0.1: the same queries as the CLI give
the same bytes; bad requests are JSON errors with their status; 32 clients at once are all
answered; a broken KB reload keeps the old KB; a request past its deadline is stopped and the
service stays healthy; the token guards every route but health."""

from __future__ import annotations

import http.client
import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
from typer.testing import CliRunner

from handover.engine.cli import app
from handover.engine.store.kb import builtin_kb_dir

TOKEN = "s3cret-token"
CLI = ("import sys; from handover.engine.cli import main; "
       "sys.argv = ['handover', *sys.argv[1:]]; main()")


class Running:
    """A service subprocess: its address, and HTTP requests to it (with the token)."""

    def __init__(self, proc: subprocess.Popen, url: str, log: Path):
        self.proc, self.url, self.log = proc, url, log
        host_port = url.removeprefix("http://")
        self.host, self.port = host_port.rsplit(":", 1)[0], int(host_port.rsplit(":", 1)[1])

    def request(self, method: str, path: str, body: bytes | str | dict | None = None,
                token: str | None = TOKEN, headers: dict | None = None
                ) -> tuple[int, dict, bytes]:
        conn = http.client.HTTPConnection(self.host, self.port, timeout=120)
        if isinstance(body, dict):
            body = json.dumps(body)
        sent = dict(headers or {})
        if token:
            sent["Authorization"] = f"Bearer {token}"
        conn.request(method, path, body=body, headers=sent)
        r = conn.getresponse()
        out = r.status, {k.lower(): v for k, v in r.getheaders()}, r.read()
        conn.close()
        return out

    def plan(self, body, path: str = "/v1/plan") -> tuple[int, dict, bytes]:
        return self.request("POST", path, body)

    def health(self) -> dict:
        status, _, body = self.request("GET", "/v1/health", token=None)
        assert status == 200
        return json.loads(body)


def start(kb: Path, tmp: Path, *args: str) -> Running:
    log = tmp / f"service-{time.monotonic_ns()}.log"
    proc = subprocess.Popen(
        [sys.executable, "-c", CLI, "--kb", str(kb), "serve", "--port", "0", *args],
        stdout=subprocess.PIPE, stderr=log.open("w"), text=True, env=dict(os.environ))
    line: list[str] = []
    reader = threading.Thread(target=lambda: line.append(proc.stdout.readline()), daemon=True)
    reader.start()
    reader.join(180)
    if not line or not line[0].startswith("http://127.0.0.1:"):
        proc.kill()
        raise AssertionError(f"the service did not start: {line}\n{log.read_text()}")
    return Running(proc, line[0].strip(), log)


def stop(running: Running) -> None:
    running.proc.send_signal(signal.SIGTERM)
    try:
        running.proc.wait(60)
    except subprocess.TimeoutExpired:
        running.proc.kill()
        running.proc.wait(10)


@pytest.fixture(scope="module")
def kb_dir(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("service") / "kb"
    shutil.copytree(builtin_kb_dir(), root, ignore=shutil.ignore_patterns("schema", "__*"))
    return root


@pytest.fixture(scope="module")
def service(kb_dir: Path, tmp_path_factory):
    running = start(kb_dir, tmp_path_factory.mktemp("logs"), "--token", TOKEN,
                    "--workers", "2", "--deadline", "120")
    yield running
    pids = running.health()["worker_pids"]
    stop(running)
    # uvicorn finishes the requests it has, then ends by the signal it was sent
    assert running.proc.returncode in (0, -signal.SIGTERM), running.log.read_text()
    assert "Traceback" not in running.log.read_text()
    time.sleep(0.5)
    assert not [p for p in pids if Path(f"/proc/{p}").exists()
                and "zombie" not in Path(f"/proc/{p}/status").read_text().lower()], \
        "worker processes outlived the service"


def cli(kb_dir: Path, *args: str) -> tuple[int, str]:
    got = CliRunner().invoke(app, ["--kb", str(kb_dir), *args])
    return got.exit_code, got.stdout


QUERIES = [  # (body, CLI arguments)
    ({"object": "knife"}, ["plan", "knife"]),
    ({"object": "mug", "receiver": "elder", "culture": "korean"},
     ["plan", "mug", "--receiver", "elder", "--culture", "korean"]),
    ({"object": "hammer", "task": "pull_nail", "mode": "h1g1"},
     ["plan", "hammer", "--task", "pull_nail", "--mode", "h1g1"]),
    ({"object": "knife", "receiver": "child"}, ["plan", "knife", "--receiver", "child"]),
    ({"object": "screwdriver", "why-not": [0, 3]},
     ["plan", "screwdriver", "--why-not", "0", "--why-not", "3"]),
]


@pytest.mark.parametrize(("body", "args"), QUERIES, ids=[q[1][1] + str(i) for i, q in
                                                        enumerate(QUERIES)])
def test_a_plan_is_the_cli_s_json_byte_for_byte(service, kb_dir, body, args) -> None:
    code, printed = cli(kb_dir, *args, "--json")
    status, headers, answer = service.plan(body)
    assert status == 200  # whatever the outcome, a refusal included
    assert answer.decode("utf-8") == printed
    outcome = json.loads(printed)["outcome"]
    assert headers["x-handover-outcome"] == outcome
    assert code == (0 if outcome in ("handover", "place") else 4)
    again = service.plan(body)[2]
    assert again == answer  # the memo gives the same bytes


def test_a_request_asked_again_is_answered_from_the_memo_whichever_worker_planned_it(
        service) -> None:
    # Two workers: the old memo was each worker's, so a request asked again was planned
    # again about every other time. Asked concurrently, both workers take some.
    body = {"object": "scissors", "receiver": "elder", "culture": "korean"}
    status, headers, answer = service.plan(body)
    assert status == 200 and "x-handover-memo" not in headers  # planned
    with ThreadPoolExecutor(4) as pool:
        again = list(pool.map(lambda _: service.plan(body), range(8)))
    assert all(s == 200 and h.get("x-handover-memo") == "true" and a == answer
               for s, h, a in again)
    logged = [json.loads(line) for line in service.log.read_text().splitlines()
              if line.startswith("{") and '"path": "/v1/plan"' in line]
    assert sum(1 for e in logged if e.get("memo")) >= 8


def test_a_query_planned_again_goes_to_the_worker_that_planned_it(kb_dir, tmp_path) -> None:
    # No memo: every answer is planned. A query asked again is sent to the worker whose
    # caches hold it (its inverse-kinematics answers); two requests at once take both
    # workers, the second not waiting behind the first while the other worker is free.
    running = start(kb_dir, tmp_path, "--workers", "2", "--memo-mb", "0", "--deadline", "120")
    try:
        queries = [{"object": o, "receiver": r} for o in ("knife", "scissors", "screwdriver")
                   for r in ("adult", "elder")]
        first = {}
        for body in queries:
            status, headers, answer = running.plan(body)
            assert status == 200 and "x-handover-memo" not in headers
            first[json.dumps(body)] = (headers["x-handover-worker"], answer)
        for _ in range(2):
            for body in queries:
                status, headers, answer = running.plan(body)
                assert status == 200 and "x-handover-memo" not in headers  # planned again
                assert (headers["x-handover-worker"], answer) == first[json.dumps(body)]
        pids = {str(p) for p in running.health()["worker_pids"]}
        assert {w for w, _ in first.values()} <= pids
        together = threading.Barrier(2)

        def book(receiver: str) -> str:
            together.wait()
            status, headers, _ = running.plan({"object": "book", "receiver": receiver})
            assert status == 200
            return headers["x-handover-worker"]

        with ThreadPoolExecutor(2) as pool:
            workers = list(pool.map(book, ("child", "seated_adult")))
        assert set(workers) == pids, workers  # one each, neither queued behind the other
        logged = [json.loads(line) for line in running.log.read_text().splitlines()
                  if line.startswith("{") and '"path": "/v1/plan"' in line]
        assert len(logged) == 3 * len(queries) + 2
        assert all(str(e["worker"]) in pids for e in logged)
    finally:
        stop(running)


def test_a_request_that_waits_past_its_deadline_for_a_worker_is_answered_and_counted(
        kb_dir, tmp_path) -> None:
    # One worker, busy with a long request (the tray's physics check, 3-4 s, stopped at 5 s
    # at the latest): a request behind it whose deadline passes while it waits is a 504 at
    # its deadline, not when the worker is free; the worker then serves the next request,
    # and nothing stays counted as pending.
    running = start(kb_dir, tmp_path, "--workers", "1", "--memo-mb", "0", "--deadline", "120")
    try:
        slow = {"object": "tray", "physics": True}
        with ThreadPoolExecutor(1) as pool:
            busy = pool.submit(running.plan, slow, "/v1/plan?deadline=5")
            time.sleep(0.5)  # the slow request has the worker
            began = time.monotonic()
            status, _, body = running.plan({"object": "knife"}, path="/v1/plan?deadline=0.5")
            waited = time.monotonic() - began
            assert status == 504 and _error(status, body)["code"] == "deadline_exceeded"
            assert waited < 1.5  # answered at its deadline, not when the worker was free
            assert busy.result()[0] in (200, 504)
        status, headers, body = running.plan({"object": "knife"})
        assert status == 200 and json.loads(body)["outcome"] == "handover"
        health = running.health()
        assert health["ok"] and health["pending"] == 0 and len(health["worker_pids"]) == 1
    finally:
        stop(running)


def test_moveit_and_mcap_are_the_cli_s(service, kb_dir, tmp_path) -> None:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    _, printed = cli(kb_dir, "plan", "book", "--format", "moveit", "--mcap",
                     str(tmp_path / "cli.mcap"))
    status, headers, answer = service.plan({"object": "book", "format": "moveit"})
    assert status == 200 and headers["content-type"].startswith("application/json")
    assert answer.decode("utf-8") == printed
    status, headers, bag = service.plan({"object": "book", "format": "mcap"})
    assert status == 200 and headers["content-type"] == "application/x-mcap"
    assert bag == (tmp_path / "cli.mcap").read_bytes()
    (tmp_path / "svc.mcap").write_bytes(bag)
    moveit = json.loads(printed)
    with open(tmp_path / "svc.mcap", "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        poses = [m.grasp_pose.pose for _, ch, _, m in reader.iter_decoded_messages()
                 if ch.topic == "/handover/grasps"]
    assert len(poses) == len(moveit["grasps"]) == 2  # the book: H2G2, two grasps
    for got, want in zip(poses, moveit["grasps"], strict=True):
        p = want["grasp_pose"]["pose"]
        assert [got.position.x, got.position.y, got.position.z] == \
            [p["position"][k] for k in "xyz"]
        assert [got.orientation.x, got.orientation.y, got.orientation.z,
                got.orientation.w] == [p["orientation"][k] for k in "xyzw"]


def test_a_grasp_planning_goal_is_answered_with_the_plan_s_grasps(service, kb_dir) -> None:
    # The GraspPlanning action's goal as `ros2 action send_goal` fills it in (empty geometry),
    # with the query's options as the object's properties.
    goal = {"object": {"header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": ""},
                       "name": "tray", "support_surface": "",
                       "properties": [{"name": "receiver", "value": "elder"},
                                      {"name": "culture", "value": "korean"}],
                       "point_cluster": {"height": 0, "width": 0, "fields": [], "data": []},
                       "primitives": [], "primitive_poses": [], "meshes": [],
                       "mesh_poses": [], "surface": {"coef": [0.0, 0.0, 0.0, 0.0]}},
            "group_name": ""}
    _, printed = cli(kb_dir, "plan", "tray", "--receiver", "elder", "--culture", "korean",
                     "--format", "moveit")
    _, plan_json = cli(kb_dir, "plan", "tray", "--receiver", "elder", "--culture", "korean",
                       "--json")
    status, headers, answer = service.plan(goal, "/v1/grasp_planning")
    assert status == 200 and headers["x-handover-outcome"] == "handover"
    result = json.loads(answer)
    assert list(result) == ["grasps"]
    assert result["grasps"] == json.loads(printed)["grasps"]
    arms = [g["arm"] for g in json.loads(plan_json)["robot_grasps"]]
    assert sorted(arms) == ["left", "right"]  # the korean elder: two hands (H2G1)
    # A group is one arm: only the grasp that arm takes; "<arm>_arm" names it too.
    for group in ("left", "right_arm"):
        status, _, answer = service.plan({**goal, "group_name": group}, "/v1/grasp_planning")
        side = group.removesuffix("_arm")
        assert status == 200
        assert json.loads(answer)["grasps"] == [
            g for g, arm in zip(result["grasps"], arms, strict=True) if arm == side]
    # A refusal is an answer with no grasp, as the action gives it.
    status, headers, answer = service.plan(
        {"object": {"name": "knife", "properties": [{"name": "receiver", "value": "child"}]}},
        "/v1/grasp_planning")
    assert status == 200 and json.loads(answer) == {"grasps": []}
    assert headers["x-handover-outcome"] != "handover"


@pytest.mark.parametrize(("goal", "status", "words"), [
    ({"object": {"name": "mug"}, "group_name": "torso"}, 400, "not an arm"),
    ({"object": {"name": "mug", "properties": [{"name": "colour", "value": "red"}]}}, 400,
     "unknown property 'colour'"),
    ({"object": {"name": "mug", "primitives": [{"type": 1, "dimensions": [0.1, 0.1, 0.1]}]}},
     400, "describes the object's geometry (primitives)"),
    ({"object": {"name": "mug"}, "planning_group": "left"}, 400, "unknown goal field"),
    ({"object": {"properties": []}}, 400, "needs a 'name'"),
    ({"object": {"name": "teapot"}}, 404, "teapot"),
    ("[1, 2]", 400, "JSON object"),
])
def test_bad_grasp_planning_goals_are_json_errors(service, goal, status, words) -> None:
    got, _, answer = service.plan(goal, "/v1/grasp_planning")
    assert got == status
    assert words in json.loads(answer)["error"]["message"]


def _error(status: int, body: bytes) -> dict:
    assert b"Traceback" not in body
    data = json.loads(body)
    assert set(data) == {"error"} and data["error"]["message"], data
    return data["error"]


@pytest.mark.parametrize(("body", "status", "code"), [
    (b"{not json", 400, "bad_json"),
    (b"", 400, "bad_request"),
    (b"[1, 2]", 400, "bad_request"),
    ({"receiver": "elder"}, 400, "bad_request"),  # no object
    ({"object": "knife", "colour": "red"}, 400, "bad_request"),
    ({"object": "knife", "mode": 3}, 400, "bad_request"),
    ({"object": "knife", "mode": "h3g3"}, 400, "bad_request"),
    ({"object": "knife", "why-not": "three"}, 400, "bad_request"),
    ({"object": "knife", "format": "xml"}, 400, "bad_request"),
    ({"object": "knife", "mesh-scale": -1}, 400, "bad_request"),
    ({"object": "/etc/passwd.stl"}, 400, "bad_request"),
    ({"object": "spork"}, 404, "unknown_id"),
    ({"object": "knife", "culture": "martian"}, 404, "unknown_id"),
    ({"object": "knife", "task": "juggle"}, 404, "unknown_id"),
    (b"{" + b" " * 70_000 + b"}", 413, "too_large"),
    ({"object": None}, 400, "bad_request"),  # null: no object
    (b"[" * 20_000 + b"]" * 20_000, 400, "bad_json"),  # nested past the parser's recursion
    (b'{"object": "knife", "object": "mug"}', 400, "bad_json"),  # a key twice
    ({"object": "knife", "why-not": 3, "why_not": 4}, 400, "bad_request"),  # twice, spelt so
    ({"object": "knife", "no-motion": "yes"}, 400, "bad_request"),
])
def test_bad_requests_are_json_errors(service, body, status, code) -> None:
    got, _, answer = service.plan(body)
    assert got == status
    assert _error(got, answer)["code"] == code


def test_unknown_routes_methods_and_deadlines_are_json_errors(service) -> None:
    for method, path, status, code in [("GET", "/v1/plans", 404, "not_found"),
                                       ("GET", "/v1/plan", 405, "method_not_allowed"),
                                       ("POST", "/v1/plan?deadline=soon", 400, "bad_request"),
                                       ("POST", "/v1/plan/", 404, "not_found")]:
        got, _, body = service.request(method, path, {"object": "knife"})
        assert got == status and _error(got, body)["code"] == code
        if status == 404:  # every route named, the GraspPlanning action's too
            assert "/v1/grasp_planning" in _error(got, body)["message"]


def test_the_token_guards_every_route_but_health(service) -> None:
    for token in (None, "wrong"):
        status, _, body = service.request("POST", "/v1/plan", {"object": "knife"}, token=token)
        assert status == 401 and _error(status, body)["code"] == "unauthorized"
    assert service.request("GET", "/v1/health", token=None)[0] == 200
    status, headers, _ = service.request("POST", "/v1/plan", {"object": "knife"}, token=None)
    assert status == 401 and headers["www-authenticate"].startswith("Bearer")
    # the scheme's case does not matter (RFC 7235); the token's does
    for scheme, want in (("bearer", 200), ("BEARER", 200), ("Bearer", 200), ("Basic", 401)):
        status, _, _ = service.request("POST", "/v1/plan", {"object": "knife"}, token=None,
                                       headers={"Authorization": f"{scheme} {TOKEN}"})
        assert status == want, scheme
    status, _, _ = service.request("POST", "/v1/plan", {"object": "knife"},
                                   token=TOKEN.upper())
    assert status == 401


def test_every_error_answer_s_code_is_in_the_request_log(service) -> None:
    marker = f"log-{time.monotonic_ns()}"
    for body, code in (({"object": "knife", "colour": "red"}, "bad_request"),
                       ({"object": "spork"}, "unknown_id")):
        status, _, _ = service.request("POST", "/v1/plan", body,
                                       headers={"X-Request-Id": f"{marker}-{code}"})
        assert status >= 400
    want = {f"{marker}-bad_request": "bad_request", f"{marker}-unknown_id": "unknown_id"}
    for _ in range(100):  # a request's line is written once its answer is sent
        logged = {entry["id"]: entry["error"] for entry in
                  (json.loads(line) for line in service.log.read_text().splitlines()
                   if line.startswith("{") and marker in line)}
        if len(logged) == len(want):
            break
        time.sleep(0.05)
    assert logged == want


def test_another_host_needs_a_token(kb_dir) -> None:
    from handover.engine.cli.app import main

    assert main(["--kb", str(kb_dir), "serve", "--host", "0.0.0.0", "--port", "0"]) == 2
    for option, value in (("--max-pending", "0"), ("--memo-mb", "-1"), ("--workers", "0")):
        assert main(["--kb", str(kb_dir), "serve", "--port", "0", option, value]) == 2


def test_verify_and_validate_are_the_cli_s(service, kb_dir) -> None:
    code, printed = cli(kb_dir, "kb", "test", "-k", "knife", "--json")
    status, _, answer = service.request("POST", "/v1/verify", {"k": "knife"})
    assert status == 200 and answer.decode() == printed and json.loads(printed)["passed"] >= 1
    code, printed = cli(kb_dir, "kb", "validate", "--json")
    status, _, answer = service.request("GET", "/v1/kb/validate")
    assert (status, code) == (200, 0) and answer.decode() == printed


def _rss_kib(pids: list[int]) -> int:
    total = 0
    for pid in pids:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                total += int(line.split()[1])
    return total


def test_32_clients_at_once_are_all_answered(service) -> None:
    valid = [{"object": "knife"}, {"object": "screwdriver"},
             {"object": "knife", "receiver": "child"}]  # a refusal: no mode is planned
    invalid = [(b"{oops", 400), ({"object": "spork"}, 404),
               ({"object": "knife", "culture": "martian"}, 404),
               ({"object": "knife", "colour": 1}, 400)]
    for body in valid:  # planned once; then they come from the service's memo
        assert service.plan(body)[0] == 200
    pids = [service.proc.pid, *service.health()["worker_pids"]]
    before = _rss_kib(pids)

    def client(k: int) -> Counter:
        seen: Counter = Counter()
        conn = http.client.HTTPConnection(service.host, service.port, timeout=120)
        for i in range(20):
            if (k + i) % 2:
                body, want = valid[(k + i) % len(valid)], 200
            else:
                body, want = invalid[(k + i) % len(invalid)]
            conn.request("POST", "/v1/plan?deadline=60", body=body if isinstance(body, bytes)
                         else json.dumps(body), headers={"Authorization": f"Bearer {TOKEN}"})
            r = conn.getresponse()
            payload = r.read()
            assert r.status == want, (body, r.status, payload[:300])
            if want != 200:
                _error(r.status, payload)
            else:
                assert json.loads(payload)["object"] == body["object"]
            seen[r.status] += 1
        conn.close()
        return seen

    with ThreadPoolExecutor(32) as pool:
        counts = sum(pool.map(client, range(32)), Counter())
    assert sum(counts.values()) == 32 * 20
    assert set(counts) <= {200, 400, 404}
    assert service.health()["pending"] == 0
    grown = _rss_kib([p for p in pids if Path(f"/proc/{p}").exists()]) - before
    assert grown < 150 * 1024, f"the service grew by {grown / 1024:.0f} MiB over 640 requests"


def test_a_request_past_its_deadline_is_stopped_and_the_service_goes_on(service) -> None:
    slow = {"object": "tray", "physics": True}  # its physics check: 3-4 s
    status, _, body = service.plan(slow, path="/v1/plan?deadline=0.5")
    assert status == 504
    error = _error(status, body)
    assert error["code"] == "deadline_exceeded" and error["deadline"] == 0.5
    assert service.health()["ok"]
    status, _, body = service.plan({"object": "knife"})
    assert status == 200 and json.loads(body)["outcome"] == "handover"


def test_the_cli_s_no_motion_flag_and_null_options_are_taken_as_the_cli_takes_them(
        service, kb_dir) -> None:
    code, printed = cli(kb_dir, "plan", "pen", "--no-motion", "--json")
    assert code == 0
    for body in ({"object": "pen", "no-motion": True}, {"object": "pen", "no_motion": True},
                 {"object": "pen", "motion": False, "physics": None, "why-not": None}):
        status, _, answer = service.plan(body)
        assert status == 200 and answer.decode() == printed, body


def test_a_reload_that_breaks_the_robot_s_urdf_keeps_the_old_kb(service, kb_dir) -> None:
    before = service.health()["kb"]["digest"]
    urdf = kb_dir / "robots" / "idro_arms.urdf"
    text = urdf.read_text()
    try:
        urdf.write_text('<robot name="x"><link name=')  # every plan needs the robot
        status, _, body = service.request("POST", "/v1/kb/reload")
        assert status == 422
        error = _error(status, body)
        assert error["code"] == "invalid_kb"
        assert [i["file"] for i in error["issues"]] == ["robots/idro.yaml"]
        assert "URDF" in error["issues"][0]["message"]
        assert service.health()["kb"]["digest"] == before
        status, _, body = service.plan({"object": "mug", "receiver": "child"})
        assert status == 200 and json.loads(body)["feasible"] is True  # the old KB serves
    finally:
        urdf.write_text(text)


def test_a_broken_reload_keeps_the_old_kb(service, kb_dir) -> None:
    before = service.health()["kb"]["digest"]
    knife = kb_dir / "objects" / "knife.yaml"
    text = knife.read_text()
    extra = kb_dir / "objects" / "knife2.yaml"
    try:
        knife.write_text(text.replace("mass:", "mass: -3\nmasss:", 1))
        status, _, body = service.request("POST", "/v1/kb/reload")
        assert status == 422
        error = _error(status, body)
        assert error["code"] == "invalid_kb"
        assert {i["file"] for i in error["issues"]} == {"objects/knife.yaml"}
        assert all(i["line"] > 0 for i in error["issues"])
        assert service.health()["kb"]["digest"] == before
        assert service.plan({"object": "knife"})[0] == 200  # the old KB serves
        knife.write_text(text)
        extra.write_text(text.replace("id: knife", "id: knife2", 1))
        assert service.plan({"object": "knife2"})[0] == 404
        status, _, body = service.request("POST", "/v1/kb/reload")
        assert status == 200 and json.loads(body)["changed"] is True
        assert service.health()["kb"]["digest"] != before
        status, _, body = service.plan({"object": "knife2"})
        assert status == 200 and json.loads(body)["object"] == "knife2"
    finally:
        knife.write_text(text)
        extra.unlink(missing_ok=True)


def test_the_client_is_the_planner(service, kb_dir) -> None:
    from handover import Client, Planner, Query
    from handover.engine.errors import UnknownIdError, UsageError

    client = Client(service.url, token=TOKEN)
    local = Planner(kb_dir)
    for planner in (client, local):
        plan = planner.plan("mug", receiver="elder", culture="korean")
        assert plan.feasible and plan.mode and plan.robot_grasps[0].pose.shape == (4, 4)
        with pytest.raises(UnknownIdError):
            planner.plan("spork")
        with pytest.raises(UsageError):
            planner.plan("knife", mode="h3g3")
    assert client.plan("mug", receiver="elder", culture="korean").to_json() == \
        local.plan("mug", receiver="elder", culture="korean").to_json()
    elder = Query("mug", receiver="elder", culture="korean")  # the Planner's own example
    assert client.plan(elder).to_json() == local.plan(elder).to_json()
    assert client.plan(elder, receiver="adult").mode == local.plan(elder, receiver="adult").mode
    assert client.plan(object="mug").to_json() == local.plan(object="mug").to_json()
    assert client.plan_json("pen", receiver="child") == local.plan_json("pen", receiver="child")
    assert client.moveit("knife") == local.moveit("knife")
    for planner in (client, local):
        with pytest.raises(ValueError, match="colour"):
            planner.plan("mug", colour="red")
    import trimesh

    with pytest.raises(ValueError, match="a mesh cannot be sent"):  # however it is given
        client.plan(object=trimesh.creation.box((0.05, 0.05, 0.05)))
    with pytest.raises(UsageError, match="no planning context"):
        client.plan("knife").record(kb_dir / "x.rrd")
    assert client.health()["kb"]["counts"]["objects"] >= 10


def test_the_service_answers_without_waiting_for_acknowledgements() -> None:
    # An answer under one TCP segment (a refusal, an error, the health) was held by Nagle's
    # algorithm until the client acknowledged the headers, which it delays: 40 ms each.
    # asyncio turns the algorithm off on the connections the service's socket accepts when
    # that socket says it is TCP.
    import asyncio
    import socket

    from handover.engine.service.server import bind

    async def accepted_nodelay() -> int:
        listening = bind("127.0.0.1", 0)
        seen: asyncio.Future = asyncio.get_running_loop().create_future()

        class Probe(asyncio.Protocol):
            def connection_made(self, transport) -> None:
                sock = transport.get_extra_info("socket")
                seen.set_result(sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY))
                transport.close()

        server = await asyncio.get_running_loop().create_server(Probe, sock=listening)
        with socket.create_connection(listening.getsockname()[:2]):
            value = await asyncio.wait_for(seen, 10)
        server.close()
        await server.wait_closed()
        return value

    assert asyncio.run(accepted_nodelay()) != 0


def test_the_client_sends_a_request_at_once(service) -> None:
    # http.client writes the headers and the body of a request in two sends; with Nagle's
    # algorithm on, the body may wait for the headers' acknowledgement. The client's
    # connection turns it off, as curl does.
    import socket

    from handover import Client

    client = Client(service.url, token=TOKEN)
    assert client.health()["kb"]["counts"]["objects"] >= 10
    sock = client._connection().sock
    assert sock is not None
    assert sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY) != 0


def test_the_documented_requests_are_answered(service, kb_dir, docs, tmp_path,
                                              monkeypatch) -> None:
    import re

    for line in docs.example("service-curl").text.splitlines():
        m = re.search(r"(-X POST )?'?http://127\.0\.0\.1:8750(\S+?)'?( -d '(.*?)')?( -o .*)?$",
                      line)
        assert m, line
        method = "POST" if m.group(1) else "GET"
        status, _, body = service.request(method, m.group(2), m.group(4))
        assert status == 200, (line, body[:300])
    code = docs.example("service-python").text.replace("http://127.0.0.1:8750", service.url)
    code = code.replace(f'Client("{service.url}")', f'Client("{service.url}", token="{TOKEN}")')
    monkeypatch.chdir(tmp_path)
    exec(compile(code, "docs/service.md", "exec"), {})
    assert (tmp_path / "book.mcap").stat().st_size > 0
    # "or: planner = Planner()": the same calls, in this process
    local = code.replace(f'planner = Client("{service.url}", token="{TOKEN}")',
                         f'planner = Planner({str(kb_dir)!r})', 1)
    assert local != code
    (tmp_path / "book.mcap").rename(tmp_path / "served.mcap")
    exec(compile(local, "docs/service.md", "exec"), {})
    assert (tmp_path / "book.mcap").read_bytes() == (tmp_path / "served.mcap").read_bytes()
