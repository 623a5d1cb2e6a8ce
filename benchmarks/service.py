"""Latency and throughput of the plan service, started for real on 127.0.0.1.

    .venv/bin/python benchmarks/service.py [--workers 2] [--rounds 5] [--clients 4]

Starts ``handover serve --port 0 --workers N`` on the built-in KB (its grasp database in a
temporary folder, so the first round also builds the candidates and the reachability map:
that round is reported apart), then plans the 10 built-in objects for the 4 receivers
(adult, seated_adult, child, elder: 40 queries):

- ``first round``: every query planned for the first time (the grasp database and the
  reachability map built on the way);
- ``second round`` and ``warm``: the same queries again (``--rounds`` times), answered from
  the service's memo (every query was planned in the first round);
- ``planned by a warm worker``: a second service with the memo off (``--memo-mb 0``), after
  one untimed round: every answer planned by a worker whose caches are warm, the cost of
  planning itself;
- throughput: ``--clients`` clients at once sending the 40 queries, answers per second, with
  and without the memo;
- ``a receiver new to the worker``: one worker, no memo, that has planned every object for
  adult and seated_adult, plans each for child and elder, first time: what is kept across
  plans by content (the grasp candidates, the arms and their maps, the torque tables, the
  pads' patches) serves; what depends on the receiver is computed. The cost of a query the
  service has not seen.

Prints p50/p95/max in ms (latency measured at the client: HTTP, JSON and all; the client's
connection sends without Nagle's delay, as ``handover.Client`` and curl do). Targets
(issue 30): warm p50 <= 60 ms, p95 <= 200 ms without physics.
"""

from __future__ import annotations

import argparse
import http.client
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor

from handover.engine.service.client import NoDelayConnection

OBJECTS = ("ball", "book", "bottle", "hammer", "knife", "mug", "pen", "scissors",
           "screwdriver", "tray")
RECEIVERS = ("adult", "seated_adult", "child", "elder")
CLI = ("import sys; from handover.engine.cli import main; "
       "sys.argv = ['handover', *sys.argv[1:]]; main()")


def start(workers: int, memo_mb: float, env: dict) -> tuple[subprocess.Popen, str, int]:
    proc = subprocess.Popen([sys.executable, "-c", CLI, "serve", "--port", "0", "--workers",
                             str(workers), "--memo-mb", str(memo_mb), "--deadline", "600"],
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                            env=env)
    line = proc.stdout.readline().strip()
    if not line.startswith("http://"):
        proc.kill()
        raise SystemExit(f"the service did not start: {line!r}")
    host, port = line.removeprefix("http://").rsplit(":", 1)
    return proc, host, int(port)


def stop(proc: subprocess.Popen) -> None:
    proc.send_signal(signal.SIGTERM)
    try:
        proc.wait(60)
    except subprocess.TimeoutExpired:
        proc.kill()


def ask(conn: http.client.HTTPConnection, body: dict) -> float:
    t = time.perf_counter()
    conn.request("POST", "/v1/plan", body=json.dumps(body))
    r = conn.getresponse()
    r.read()
    if r.status != 200:
        raise SystemExit(f"{body}: status {r.status}")
    return (time.perf_counter() - t) * 1000


def stats(label: str, ms: list[float]) -> None:
    ms = sorted(ms)
    p95 = ms[min(len(ms) - 1, int(round(0.95 * (len(ms) - 1))))]
    print(f"{label:<34} n={len(ms):4d}  p50 {statistics.median(ms):7.1f}  p95 {p95:7.1f}  "
          f"max {ms[-1]:7.1f} ms")


def throughput(host: str, port: int, queries: list[dict], clients: int, rounds: int) -> float:
    work = [q for _ in range(rounds) for q in queries]
    lock = threading.Lock()

    def client(_: int) -> None:
        conn = NoDelayConnection(host, port, timeout=600)
        while True:
            with lock:
                if not work:
                    break
                body = work.pop()
            ask(conn, body)
        conn.close()

    t = time.perf_counter()
    with ThreadPoolExecutor(clients) as pool:
        list(pool.map(client, range(clients)))
    return rounds * len(queries) / (time.perf_counter() - t)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--clients", type=int, default=4)
    args = ap.parse_args()
    queries = [{"object": o, "receiver": r} for o in OBJECTS for r in RECEIVERS]
    with tempfile.TemporaryDirectory() as db:
        env = dict(os.environ, HANDOVER_DB=db)
        print(f"## plan service, {args.workers} workers, {len(queries)} queries (10 objects x "
              f"4 receivers), latency at the client")
        t = time.perf_counter()
        proc, host, port = start(args.workers, 64, env)
        print(f"start-up (KB loaded, every worker ready): {time.perf_counter() - t:.2f} s")
        try:
            conn = NoDelayConnection(host, port, timeout=600)
            cold = [ask(conn, q) for q in queries]
            stats("first round (db and maps built)", cold)
            first = [ask(conn, q) for q in queries]
            stats("second round (memo)", first)
            warm = [ask(conn, q) for _ in range(args.rounds) for q in queries]
            stats(f"warm, {args.rounds} rounds", warm)
            conn.close()
            rate = throughput(host, port, queries, args.clients, args.rounds)
            print(f"throughput, {args.clients} clients, memo on: {rate:7.1f} answers/s")
        finally:
            stop(proc)
        proc, host, port = start(args.workers, 0, env)
        try:
            conn = NoDelayConnection(host, port, timeout=600)
            for q in queries:  # each worker's caches (maps, arms) warm
                ask(conn, q)
            planned = [ask(conn, q) for _ in range(max(1, args.rounds // 2)) for q in queries]
            stats("planned by a warm worker (no memo)", planned)
            conn.close()
            rate = throughput(host, port, queries, args.clients, 1)
            print(f"throughput, {args.clients} clients, no memo: {rate:7.1f} plans/s")
        finally:
            stop(proc)
        proc, host, port = start(1, 0, env)
        try:
            conn = NoDelayConnection(host, port, timeout=600)
            seen = [q for q in queries if q["receiver"] in RECEIVERS[:2]]
            new = [q for q in queries if q["receiver"] not in RECEIVERS[:2]]
            for q in seen:  # every object planned, for two receivers
                ask(conn, q)
            stats("a receiver new to the worker", [ask(conn, q) for q in new])
            conn.close()
        finally:
            stop(proc)
    print("targets: warm p50 <= 60 ms, p95 <= 200 ms")


if __name__ == "__main__":
    main()
