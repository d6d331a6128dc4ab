"""A namespace moves a whole graph: two bridge/train pairs (``/b1``, ``/b3``) share one domain.

Every node creates its topics, services and parameter clients with relative names, so
``--ros-args -r __ns:=/b3`` moves the node and all it publishes (``/b3/adm/run/status``,
``/b3/clock``, ``/b3/train/start_run``). Both pairs run at the same time, each driven by a
driver node in its namespace, and each gets the exact result of its own in-process sweep.

The bridges are modelled with their first mode alone (modal damping): the step is set by the
highest mode kept, so the DIM co-simulation takes 9x fewer steps (about 1 s in place of 10-16 s of
lockstep exchange per pair); what is under test, the names and the exactness of each pair's
result, does not depend on how many modes the state holds (the three-mode co-simulation is
compared with the in-process sweep in tests/test_ros_cosim.py).
"""

from __future__ import annotations

import dataclasses
import threading

import numpy as np
import pytest

pytest.importorskip("rclpy")
from ros_fixtures import driver_node, node_procs, ros_domain  # noqa: E402,F401

from adm_sim.model.bridge import resolve_bridge  # noqa: E402
from adm_sim.integrate.step_grid import StepOptions  # noqa: E402
from adm_sim.integrate.sweep import run_sweep  # noqa: E402
from adm_sim.model.trains import load_train  # noqa: E402

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
