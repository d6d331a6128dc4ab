"""A namespace moves a whole graph: two bridge/train pairs (``/b1``, ``/b3``) share one domain.

Every node creates its topics, services and parameter clients with relative names, so
``--ros-args -r __ns:=/b3`` moves the node and all it publishes (``/b3/adm/run/status``,
``/b3/clock``, ``/b3/train/start_run``). Both pairs run at the same time, each driven by a
driver node in its namespace, and each gets the exact result of its own in-process sweep.

The bridges are modelled with their first mode alone (modal damping): the step is set by the
highest mode kept, so the DIM co-simulation takes 9x fewer steps (about 1 s in place of 10-16 s of
lockstep exchange per pair); what is under test, the names and the exactness of each pair's
result, does not depend on how many modes the state holds (the three-mode co-simulation is
compared with the in-process sweep in tests/ros/test_ros_cosim.py).
"""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rclpy")
from ros_fixtures import driver_node, node_procs, ros_domain  # noqa: E402,F401

from adm_sim.inputs.bridges import resolve_bridge  # noqa: E402
from adm_sim.integrate.step_grid import StepOptions  # noqa: E402
from adm_sim.integrate.sweep import run_sweep  # noqa: E402
from adm_sim.inputs.train_files import load_train  # noqa: E402

pytestmark = pytest.mark.slow  # every test here starts processes

STEP = {"steps_per_period": 4.0, "free_vibration_periods": 1.0}
ONE_MODE = {"n_modes": 1, "damping_model": "modal"}
PAIRS = {"/b1": ("B1", "200,250,290"), "/b3": ("B3", "230,300,350")}


def test_two_namespaced_pairs_in_one_domain_give_each_its_exact_result(node_procs, ros_domain):
    for ns, (bridge, speeds) in PAIRS.items():
        tag = ns.strip("/")
        node_procs.start(f"bridge_{tag}", "adm_sim.nodes.bridge_node", {"bridge": bridge, **ONE_MODE, **STEP},
                         extra=["-r", f"__ns:={ns}"])
        node_procs.start(f"train_{tag}", "adm_sim.nodes.train_node", {"speeds_kmh": speeds},
                         extra=["-r", f"__ns:={ns}"])
    results, errors = {}, []
    with driver_node(ros_domain.domain_id, namespace="/b1") as d1, driver_node(ros_domain.domain_id, namespace="/b3") as d3:
        def go(ns, d):
            try:
                d.wait_for_graph()
                results[ns] = [d.request_run(model=m) for m in ("mlm", "dim")]
                results[ns].append(d.description("bridge"))
            except Exception as exc:  # reported below
                errors.append(f"{ns}: {exc}")

        threads = [threading.Thread(target=go, args=(ns, d)) for ns, d in (("/b1", d1), ("/b3", d3))]
        for t in threads:
            t.start()
        for t in threads:
            t.join(300)
        names = {n for n, _t in d1.get_topic_names_and_types()}
    assert not errors, errors
    assert {"/b1/adm/run/status", "/b3/adm/run/status", "/b1/clock", "/b3/clock", "/b1/adm/midspan/accel",
            "/b3/adm/midspan/accel"} <= names
    assert "/adm/run/status" not in names and "/clock" not in names
    train = load_train("ICE-2")
    for ns, (bridge, speeds) in PAIRS.items():
        assert results[ns][-1]["bridge"]["name"] == bridge and results[ns][-1]["bridge"]["n_modes"] == 1
        for r in results[ns][:-1]:
            ref = run_sweep(dataclasses.replace(resolve_bridge(bridge), **ONE_MODE), train, r["model"], r["speeds_kmh"],
                            options=StepOptions(**STEP))
            np.testing.assert_array_equal(r["speeds_kmh"], [float(v) for v in speeds.split(",")])
            np.testing.assert_array_equal(r["max_acc_m_s2"], ref.max_acc_m_s2)  # bit for bit
            np.testing.assert_array_equal(r["max_disp_m"], ref.max_disp_m)


# ---------------------------------------------------------------- launchers: --namespace

LAUNCH = Path(__file__).resolve().parents[2] / "launch_scripts"
SWEEP = Path(__file__).resolve().parents[2] / "ros_ws" / "params" / "sweep_b1_mlm.yaml"


#: The coarse steps of the other co-simulation tests (the names and the exactness of each launch's
#: result are under test, not the numbers' accuracy), added to the bridge section of a copy of the
#: shipped file: 1.0 s of CPU less per launch. A bridge section the namespaced node ignored would
#: now also show in the result (the default steps), besides the train section's model.
COARSE = {"steps_per_period": 4.0, "free_vibration_periods": 1.0}


def _sweep_file(tmp_path):
    """The shipped sweep_b1_mlm.yaml with :data:`COARSE` in its bridge section (bare sections still)."""
    text = SWEEP.read_text()
    anchor = "    monitor_speed_kmh: 263.0\n"
    assert text.count(anchor) == 1 and text.index("bridge:") < text.index(anchor) < text.index("train:")
    f = tmp_path / "sweep_b1_mlm_coarse.yaml"
    f.write_text(text.replace(anchor, anchor + "".join(f"    {k}: {v}\n" for k, v in COARSE.items())))
    return f


def _crossing(tmp_path, ns, domain_id, *extra, params=SWEEP):
    return subprocess.Popen([sys.executable, str(LAUNCH / "crossing.py"), "--params-file", str(params),
                             "--speeds", "250:270:10", "--domain-id", str(domain_id), "--namespace", ns,
                             "--out", str(tmp_path / ns.strip("/")), *extra],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def test_two_launches_of_one_preset_under_two_namespaces_share_a_domain(tmp_path, ros_domain):
    """``crossing.py --namespace`` twice at once, the same preset on one domain: each gets the exact
    in-process result, records its own namespace's topics only, and has its own frame id; the
    params file's bare sections (``bridge:``, ``train:``) reach the namespaced nodes (B1 x ICE-2,
    MLM, the file's train and model and the coarse steps; a section ignored would run the defaults:
    ICE-2 DIM, 16 steps per period)."""
    from adm_sim.recording.mcap_log import read_messages

    params = _sweep_file(tmp_path)
    procs = {ns: _crossing(tmp_path, ns, ros_domain.domain_id, params=params) for ns in ("/site_a", "/site_b")}
    outs = {}
    for ns, p in procs.items():
        out, err = p.communicate(timeout=600)
        assert p.returncode == 0, err
        outs[ns] = out
    speeds = np.array([250.0, 260.0, 270.0])
    ref = run_sweep(resolve_bridge("B1"), load_train("ICE-2"), "mlm", speeds, options=StepOptions(**COARSE))
    frames = {}
    for ns in procs:
        assert f"namespace {ns}" in outs[ns].splitlines()[0] and f"topics under {ns}" in outs[ns].splitlines()[1]
        folder = tmp_path / ns.strip("/")
        s = json.loads((folder / "summary.json").read_text())
        assert s["model"] == "mlm"
        np.testing.assert_array_equal(s["speeds_kmh"], speeds)
        np.testing.assert_array_equal(s["max_acc_m_s2"], ref.max_acc_m_s2)  # bit for bit
        frames[ns] = {m.header.frame_id for _t, _ns, m in read_messages(folder / "run.mcap", topics=["/adm/midspan/accel"])}
        assert s["samples"]["/adm/midspan/accel"] > 100
    assert frames == {"/site_a": {"site_a/B1/midspan"}, "/site_b": {"site_b/B1/midspan"}}


def test_launcher_refuses_an_invalid_namespace(tmp_path):
    r = subprocess.run([sys.executable, str(LAUNCH / "crossing.py"), "--namespace", "/b-3", "--out", str(tmp_path / "o")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.splitlines() == [
        "error: --namespace: '/b-3' is not a valid ROS 2 namespace; allowed '/'-separated names of letters, digits "
        "and '_', none starting with a digit or empty (e.g. /b3 or /site_1/b3), at most 255 characters"]
    assert not (tmp_path / "o").exists()


def test_node_refuses_a_params_section_its_namespace_would_ignore(tmp_path, ros_domain):
    """A node started by hand in /b3 with a section keyed ``bridge`` (rcl reads ``/bridge``): one line,
    exit 2, instead of a run on the defaults; keyed ``/**/bridge`` it is applied."""
    f = tmp_path / "b3.yaml"
    f.write_text("bridge:\n  ros__parameters:\n    bridge: B3\n")
    cmd = [sys.executable, "-m", "adm_sim.nodes.bridge_node", "--ros-args", "-r", "__ns:=/b3", "--params-file", str(f)]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=120, env=ros_domain)
    assert r.returncode == 2
    assert r.stderr.strip().splitlines() == [
        f"error: bridge: --params-file '{f}': section 'bridge' is not applied to the node '/b3/bridge' "
        "(rcl reads it as '/bridge'); key it '/b3/bridge' or '/**/bridge'"]
