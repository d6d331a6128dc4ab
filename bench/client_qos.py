#!/usr/bin/env python
"""What a client gets of the midspan acceleration with each QoS: live and in a replay at ``--rate 0``.

    .venv/bin/python bench/client_qos.py [--hogs 2] [--speeds 160:350:1] [--out DIR]

Five subscriber processes of ``/adm/midspan/accel`` (RELIABLE KEEP_LAST 5000 opted into the flow
control; RELIABLE KEEP_LAST 5000, KEEP_ALL and KEEP_LAST 10 not opted in; BEST_EFFORT KEEP_LAST 10)
follow a ``crossing.py`` MLM sweep (B1 x ICE-2, ``--wait-clients 1``), then ``replay.py --republish
--rate 0 --wait-clients 1`` of its recording, while ``--hogs`` busy processes hog the cores (killed
at the end). Each subscriber counts the samples it received; the run publishes its own count (the
bridge's ``done`` record). Prints one markdown table (docs/recording.md, "What each QoS gets").
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

SUB = r"""
import json, sys, rclpy
from geometry_msgs.msg import AccelStamped
from std_msgs.msg import String
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from adm_sim.nodes.common import QOS_CONTROL, FlowClient
history, depth, reliability, opt_in = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4] == "1"
rclpy.init()
node = rclpy.create_node("qos_" + sys.argv[5])
qos = QoSProfile(history=HistoryPolicy.KEEP_ALL if history == "all" else HistoryPolicy.KEEP_LAST, depth=depth,
                 reliability=ReliabilityPolicy.RELIABLE if reliability == "reliable" else ReliabilityPolicy.BEST_EFFORT)
got = [0, 0]  # received, published (sum over the runs' done records)
def on_sample(m):
    got[0] += 1
    if flow is not None:
        flow.received()
def on_status(m):
    rec = json.loads(m.data)
    if rec.get("node") == "bridge" and rec.get("state") == "done":
        got[1] += rec["samples"]["/adm/midspan/accel"]
node.create_subscription(AccelStamped, "adm/midspan/accel", on_sample, qos)
node.create_subscription(String, "adm/run/status", on_status, QOS_CONTROL)
flow = FlowClient(node) if opt_in else None
print("ready", flush=True)
try:
    rclpy.spin(node)
except KeyboardInterrupt:
    pass
print(json.dumps(got), flush=True)
"""

#: (label, history, depth, reliability, opted in)
CLIENTS = [
    ("RELIABLE, KEEP_LAST 5000, opted in (`FlowClient`)", "last", 5000, "reliable", True),
    ("RELIABLE, KEEP_LAST 5000", "last", 5000, "reliable", False),
    ("RELIABLE, KEEP_ALL", "all", 1, "reliable", False),
    ("RELIABLE, KEEP_LAST 10", "last", 10, "reliable", False),
    ("BEST_EFFORT, KEEP_LAST 10 (sensor data)", "last", 10, "best_effort", False),
]


def _start(env):
    procs = []
    for i, (_label, hist, depth, rel, opt) in enumerate(CLIENTS):
        p = subprocess.Popen([sys.executable, "-c", SUB, hist, str(depth), rel, "1" if opt else "0", str(i)],
                             env=env, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        assert p.stdout.readline().strip() == "ready"
        procs.append(p)
    return procs


def _stop(procs):
    time.sleep(2.0)  # the last samples of a client that did not opt in can follow the done record
    out = []
    for p in procs:
        p.send_signal(signal.SIGINT)
        out.append(json.loads(p.communicate(timeout=60)[0].strip().splitlines()[-1]))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--hogs", type=int, default=2, help="busy processes running meanwhile")
    ap.add_argument("--speeds", default="160:350:1", help="MLM speeds of the crossing (km/h)")
    ap.add_argument("--out", help="folder of the crossing's outputs (default: a temporary one)")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT / "src"))
    from adm_sim.processes.dds_env import local_ros_env

    out = Path(args.out or tempfile.mkdtemp(prefix="client_qos_")) / "crossing"
    hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(args.hogs)]
    rows = {}
    try:
        with local_ros_env() as env:
            env = dict(env)
            for stage in ("live", "replay"):
                procs = _start(env)
                if stage == "live":
                    cmd = [sys.executable, str(ROOT / "launch_scripts" / "crossing.py"), "--bridge", "B1", "--train",
                           "ICE-2", "--model", "mlm", "--speeds", args.speeds, "--out", str(out), "--wait-clients", "1"]
                else:
                    cmd = [sys.executable, str(ROOT / "launch_scripts" / "replay.py"), str(out / "run.mcap"),
                           "--republish", "--rate", "0", "--wait-clients", "1"]
                r = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=1800)
                if r.returncode != 0:
                    print(r.stderr, file=sys.stderr)
                    return 1
                rows[stage] = _stop(procs)
    finally:
        for h in hogs:
            h.kill()
            h.wait()
    print(f"B1 x ICE-2, MLM {args.speeds} km/h; {args.hogs} busy processes; cores {os.cpu_count()}\n")
    print("| subscriber of /adm/midspan/accel | live (`crossing.py`) | replay at `--rate 0` |")
    print("|---|---|---|")
    for i, (label, *_rest) in enumerate(CLIENTS):
        cells = [f"{g} of {n}" + (f" ({100 * (n - g) / n:.1f} % lost)" if n and g < n else "") for g, n in
                 (rows["live"][i], rows["replay"][i])]
        print(f"| {label} | {cells[0]} | {cells[1]} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
