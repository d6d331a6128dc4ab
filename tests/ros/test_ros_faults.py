"""Faults: a node killed mid-run, the salvage of its recording, concurrent launches.

Stated timeout: a node notices a vanished partner within ``partner_timeout_s`` (here 2 s; the
graph check catches a clean exit after 0.5 s) plus one executor turn; the tests allow 2 s on top.
"""

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rclpy")
from ros_fixtures import _HELD, ROOT, NodeProcs, driver_node, node_procs, ros_domain  # noqa: E402,F401

from adm_sim.inputs.bridges import resolve_bridge  # noqa: E402
from adm_sim.processes.dds_env import local_ros_env  # noqa: E402
from adm_sim.recording.mcap_log import salvage  # noqa: E402
from adm_sim.integrate.step_grid import StepOptions  # noqa: E402
from adm_sim.integrate.sweep import run_sweep  # noqa: E402
from adm_sim.inputs.train_files import load_train  # noqa: E402

pytestmark = pytest.mark.slow  # every test here starts processes

TIMEOUT_S = 2.0
#: The partner timeout plus the node's own exit (rclpy and Fast DDS teardown): 2.3-3.2 s quiet, 4.06 s
#: once in a loaded suite run; a node that never notices its partner gone still fails the bound.
SLACK_S = 4.0
DIM_CASE = {"bridge": "B3", "steps_per_period": 8.0, "partner_timeout_s": TIMEOUT_S}
TRAIN = {"speeds_kmh": "200,250,300", "model": "dim", "partner_timeout_s": TIMEOUT_S}


def wait_for_progress(procs, name, min_step=300, timeout_s=20.0):
    t_end = time.monotonic() + timeout_s
    while time.monotonic() < t_end:
        for line in procs.stdout(name).splitlines():
            if line.startswith("@progress") and json.loads(line.split(" ", 1)[1])["step"] >= min_step:
                return
        time.sleep(0.05)
    raise AssertionError(f"no progress from {name}: {procs.stderr(name)}")


def wait_exit(p, timeout_s):
    t0 = time.monotonic()
    p.wait(timeout_s)
    return time.monotonic() - t0


def group_gone(pid):
    try:
        os.killpg(pid, 0)
    except ProcessLookupError:
        return True
    return False


def test_train_killed_mid_run(node_procs, tmp_path):
    mcap = tmp_path / "run.mcap"
    b = node_procs.start("bridge", "adm_sim.nodes.bridge_node", DIM_CASE)
    node_procs.start("train", "adm_sim.nodes.train_node", TRAIN)
    node_procs.start("driver", "adm_sim.nodes.driver", {"record_path": str(mcap), "chunk_size": 4096})
    wait_for_progress(node_procs, "driver")
    node_procs.kill("train")
    node_procs.kill("driver")  # the recorder dies too: its file must be salvageable
    dt = wait_exit(b, TIMEOUT_S + SLACK_S + 1.0)
    assert dt <= TIMEOUT_S + SLACK_S
    assert b.returncode == 1  # a RunError, as at the CLIs
    assert "partner node 'train' vanished at step" in node_procs.stderr("bridge")
    assert all(group_gone(p.pid) for p in node_procs.procs.values())
    out = tmp_path / "salvaged.mcap"
    n = salvage(mcap, out)
    assert n > 50
    from rosbags.highlevel import AnyReader

    with AnyReader([out]) as reader:
        topics = {c.topic for c in reader.connections}
        assert {"/clock", "/adm/midspan/accel"} <= topics
        assert sum(1 for _ in reader.messages()) == n


def test_bridge_killed_mid_run(node_procs, tmp_path):
    node_procs.start("bridge", "adm_sim.nodes.bridge_node", DIM_CASE)
    t = node_procs.start("train", "adm_sim.nodes.train_node", TRAIN)
    d = node_procs.start("driver", "adm_sim.nodes.driver", {"record_path": str(tmp_path / "run.mcap")})
    wait_for_progress(node_procs, "driver")
    node_procs.kill("bridge")
    assert wait_exit(t, TIMEOUT_S + SLACK_S + 1.0) <= TIMEOUT_S + SLACK_S
    assert t.returncode == 1
    assert "partner node 'bridge' vanished at step" in node_procs.stderr("train")
    d.wait(10)
    assert d.returncode == 1 and "'bridge'" in node_procs.stderr("driver")
    # the driver was not killed: its file is complete
    from rosbags.highlevel import AnyReader

    with AnyReader([tmp_path / "run.mcap"]) as reader:
        assert sum(1 for _ in reader.messages()) > 50


def _children(pid):
    out = []
    for e in os.scandir("/proc"):
        if e.name.isdigit():
            try:
                stat = Path(f"/proc/{e.name}/stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                out.append(int(e.name))
    return out


@pytest.mark.parametrize("separate,module,n_kids,said", [
    (True, "train_node", 3, "node 'train' died (exit status -9)"),
    (False, "nodes.composed", 2, "nodes 'bridge' and 'train' (one process) died (exit status -9)"),
])
def test_launch_script_stops_everything_when_a_node_dies(separate, module, n_kids, said, tmp_path, ros_domain):
    """The train node killed (its own process, ``--separate-nodes``; or the process hosting the
    bridge and the train node, the default): the launcher names it, stops the rest, exit 1."""
    env = dict(ros_domain)
    p = subprocess.Popen([sys.executable, str(ROOT / "launch_scripts" / "calibrate.py"), "--bridge", "B3",
                          "--speeds", "240:300:2", "--out", str(tmp_path), "--no-rrd", "--quiet",
                          "--domain-id", str(ros_domain.domain_id)] + (["--separate-nodes"] if separate else []),
                         env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        t_end = time.monotonic() + 30
        kids = []
        while len(kids) < n_kids and time.monotonic() < t_end:
            kids = _children(p.pid)
            time.sleep(0.1)
        assert len(kids) == n_kids
        line = ""
        while not line.startswith("calibrating"):
            line = p.stdout.readline()
            assert line, p.stderr.read()
        train = [k for k in kids if module in Path(f"/proc/{k}/cmdline").read_text()][0]
        os.kill(train, signal.SIGKILL)
        _, err = p.communicate(timeout=15)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 1
    assert said in err
    assert all(group_gone(k) for k in kids)
    # the calibration node was stopped with SIGTERM: it finished its recording, a complete file
    # (its salvage holds every message) with the latched descriptions it had received
    from adm_sim.recording.mcap_log import read_messages

    topics = [t for t, _, _ in read_messages(tmp_path / "run.mcap")]
    assert {"/adm/bridge/description", "/adm/train/description"} <= set(topics)
    assert salvage(tmp_path / "run.mcap", tmp_path / "salvaged.mcap") == len(topics)


#: Short runs for the cross-talk test (the run ids and results, not the numbers' accuracy, are under test).
SHORT_RUN = {"steps_per_period": 4.0, "free_vibration_periods": 1.0}
#: The bridges' monitoring topics every 16th step and the beam and clock every 64th (outputs only: a
#: run's result is of every step whatever is published). At these coarse steps the automatic
#: decimation publishes every step, and each in-process driver receives and deserialises it all;
#: the result and the run ids it carries, what is under test, come on their own topics.
SPARSE = {"monitor_every_steps": 16, "beam_every_steps": 64}


def test_two_launches_do_not_cross_talk(tmp_path):
    """Two bridge/train pairs on their own domains, run at the same time, each gets its result."""
    cases = [("B1", "200,250,263"), ("B3", "200,250,263")]
    results, errors, launches = {}, [], []
    try:
        for bridge, speeds in cases:
            env = local_ros_env()
            _HELD.append(env)  # never reused by a later test of the session
            env["OPENBLAS_NUM_THREADS"] = "1"
            procs = NodeProcs(env, tmp_path / bridge)
            procs.start("bridge", "adm_sim.nodes.bridge_node", {"bridge": bridge, **SHORT_RUN, **SPARSE})
            procs.start("train", "adm_sim.nodes.train_node", {"speeds_kmh": speeds, "model": "mlm"})
            launches.append((bridge, env, procs))
        assert launches[0][1].domain_id != launches[1][1].domain_id

        def run(bridge, env):
            try:
                with driver_node(env.domain_id) as d:
                    d.wait_for_graph()
                    results[bridge] = [d.request_run() for _ in range(3)]
            except Exception as exc:  # reported below
                errors.append(exc)

        threads = [threading.Thread(target=run, args=(b, e)) for b, e, _ in launches]
        for th in threads:
            th.start()
        for th in threads:
            th.join(60)
    finally:
        for _, _env, procs in launches:
            procs.stop_all()
    assert not errors, errors
    train = load_train("ICE-2")
    for bridge, speeds in cases:
        ref = run_sweep(resolve_bridge(bridge), train, "mlm", [float(v) for v in speeds.split(",")],
                        options=StepOptions(**SHORT_RUN))
        runs = results[bridge]
        assert [r["run_id"] for r in runs] == [1, 2, 3]  # no foreign run ids
        for r in runs:
            np.testing.assert_array_equal(r["max_acc_m_s2"], ref.max_acc_m_s2)


# ---------------------------------------------------------------- children die with their parent
def _own_shm_segments(pid):
    """The Fast DDS data segments (``/dev/shm/fastrtps_<16 hex>[_el]``) process ``pid`` has mapped or
    open: they belong to its participants alone (port files may be shared with other runs)."""
    import re

    found = set()
    try:
        for fd in os.scandir(f"/proc/{pid}/fd"):
            try:
                found.add(os.readlink(fd.path))
            except OSError:
                pass
        found.update(ln.split()[-1] for ln in Path(f"/proc/{pid}/maps").read_text().splitlines() if "/dev/shm/" in ln)
    except OSError:
        return set()
    return {f for f in found if re.fullmatch(r"/dev/shm/fastrtps_[0-9a-f]{16}(_el)?", f)}


def _alive(pid):
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


@pytest.mark.parametrize("script,args,n_kids", [
    # bridge, train and driver as three processes (--separate-nodes); calibrate.py composes the pair
    ("crossing.py", ["--model", "dim", "--speeds", "200:300:5", "--separate-nodes"], (3,)),
    ("calibrate.py", ["--bridge", "B3", "--speeds", "240:300:2", "--no-rrd", "--quiet"], (2,)),  # bridge + train composed
])
def test_launcher_killed_with_sigkill_takes_every_node_with_it(script, args, n_kids, tmp_path, ros_domain):
    """SIGKILL of the launcher mid-run: every node it started ends within 5 s (PR_SET_PDEATHSIG ->
    SIGTERM, a clean rclpy shutdown) and removes its own Fast DDS segments from /dev/shm. The node
    processes are counted once the run is under way (the driver, started last, reports it)."""
    p = subprocess.Popen([sys.executable, str(ROOT / "launch_scripts" / script), "--out", str(tmp_path / "o"),
                          "--domain-id", str(ros_domain.domain_id)] + args,
                         env=dict(ros_domain), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    kids = []
    try:
        line = ""
        while not ("step" in line or line.startswith("calibrating")):  # mid-run: the nodes exchange
            line = p.stdout.readline()
            assert line, p.stderr.read()
        kids = _children(p.pid)
        assert len(kids) in n_kids, kids
        segments = {k: _own_shm_segments(k) for k in kids}
        assert all(segments.values()), segments  # each node holds segments of its own
        os.kill(p.pid, signal.SIGKILL)
        p.wait(5)
        t_end = time.monotonic() + 5.0
        while any(_alive(k) for k in kids) and time.monotonic() < t_end:
            time.sleep(0.05)
        assert not [k for k in kids if _alive(k)], "nodes outlived their launcher"
        left = sorted(f for fs in segments.values() for f in fs if os.path.exists(f))
        assert left == []
    finally:
        for k in kids:
            if _alive(k):
                os.kill(k, signal.SIGKILL)
        if p.poll() is None:
            p.kill()


def test_death_signal_survives_the_ros_bootstrap_reexec(tmp_path):
    """A child started without the ROS wheels' bootstrap flag is re-executed in place by their .pth
    (same pid, LD_LIBRARY_PATH set); the death signal set before exec still ends it when its
    parent is killed with SIGKILL."""
    code = (
        "import os, sys, time\n"
        "from adm_sim.processes.supervisor import Supervisor\n"
        "sup = Supervisor(sys.argv[1], domain_id=0)\n"
        "sup.env.pop('_ROS_WHEELS_BOOTSTRAP_COMPLETE', None)\n"
        "p = sup.start_command('sleeper', [sys.executable, '-c', 'import time; time.sleep(120)'])\n"
        "print(p.pid, flush=True)\n"
        "time.sleep(120)\n")
    parent = subprocess.Popen([sys.executable, "-c", code, str(tmp_path)], stdout=subprocess.PIPE, text=True,
                              cwd=ROOT)
    child = int(parent.stdout.readline())
    try:
        t_end = time.monotonic() + 20  # wait until the child has been re-executed by the bootstrapper
        while time.monotonic() < t_end:
            environ = Path(f"/proc/{child}/environ").read_bytes().split(b"\0")
            if b"_ROS_WHEELS_BOOTSTRAP_COMPLETE=1" in environ:
                break
            time.sleep(0.05)
        else:
            pytest.fail("the child was not re-executed by the ROS wheels' bootstrapper")
        assert _alive(child)
        parent.kill()
        parent.wait(5)
        t_end = time.monotonic() + 5.0
        while _alive(child) and time.monotonic() < t_end:
            time.sleep(0.05)
        assert not _alive(child)
    finally:
        if _alive(child):
            os.kill(child, signal.SIGKILL)
        if parent.poll() is None:
            parent.kill()


def test_overwrite_keeps_the_earlier_run_until_the_new_one_is_complete(tmp_path, ros_domain):
    """crossing.py --overwrite into a folder with the outputs of an earlier run: SIGTERM mid-run leaves
    the earlier files byte for byte (the driver wrote beside them and renames only at a successful
    end); a complete run then replaces all three. The earlier outputs are written by the test
    (a launch whose only use was to produce them cost 4.5 s of CPU): the launcher and the driver
    take files of those names as an earlier run's whatever they hold."""
    import hashlib

    from adm_sim.recording.mcap_log import read_messages

    out = tmp_path / "o"
    cmd = [sys.executable, str(ROOT / "launch_scripts" / "crossing.py"), "--out", str(out),
           "--domain-id", str(ros_domain.domain_id)]
    params = tmp_path / "coarse.yaml"  # the complete run: 4 steps per period, one period of free vibration
    params.write_text("bridge:\n  ros__parameters:\n    steps_per_period: 4.0\n    free_vibration_periods: 1.0\n")
    coarse = ["--params-file", str(params)]
    env = dict(ros_domain)

    def digests():
        return {f: hashlib.sha256((out / f).read_bytes()).hexdigest() for f in ("run.mcap", "run.rrd", "summary.json")}

    out.mkdir()  # the earlier run's three outputs (their bytes, not their contents, are under test)
    for f in ("run.mcap", "run.rrd", "summary.json"):
        (out / f).write_bytes(f"an earlier run's {f}\n".encode())
    first = digests()
    p = subprocess.Popen(cmd + ["--model", "dim", "--speeds", "200:300:5", "--overwrite"], env=env,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        line = ""
        while "step" not in line:
            line = p.stdout.readline()
            assert line, p.stderr.read()
        p.send_signal(signal.SIGTERM)
        _, err = p.communicate(timeout=30)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 130 and err.splitlines()[-1].startswith("error: interrupted"), err
    assert digests() == first
    assert sorted(f.name for f in out.iterdir()) == ["logs", "run.mcap", "run.rrd", "summary.json"]
    r = subprocess.run(cmd + coarse + ["--model", "mlm", "--speeds", "200:300:20", "--overwrite"], env=env,
                       capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    again = digests()
    assert all(again[f] != first[f] for f in first)
    assert json.loads((out / "summary.json").read_text())["speeds_kmh"] == [200.0, 220.0, 240.0, 260.0, 280.0, 300.0]
    assert sum(1 for _ in read_messages(out / "run.mcap")) > 0
