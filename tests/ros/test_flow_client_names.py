"""Who counts as a client that opted into the flow control: a publisher of ``/adm/run/ack`` known by
its node's name. Discovery brings an endpoint before its node's name; rmw reports such a publisher
as ``_NODE_NAMESPACE_UNKNOWN_/_NODE_NAME_UNKNOWN_``. A replay that took that as a client waited for
its acknowledgements in vain (they carry the real name) for the whole acknowledgement timeout
(30 s) and then gave up waiting for the real client."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest
from ros_fixtures import ctx  # noqa: F401  the isolated rclpy context

pytest.importorskip("rclpy")

from adm_sim.nodes.flow_client import NODE_NAME_UNKNOWN, NODE_NAMESPACE_UNKNOWN, named_publishers  # noqa: E402


def _info(namespace, name):
    return SimpleNamespace(node_namespace=namespace, node_name=name)


def test_publishers_not_yet_known_by_name_are_left_out():
    infos = [_info("/", "monitor"), _info(NODE_NAMESPACE_UNKNOWN, NODE_NAME_UNKNOWN), _info("/b1", "recorder"),
             _info("/", NODE_NAME_UNKNOWN), _info(NODE_NAMESPACE_UNKNOWN, "x"), _info("/", "monitor")]
    assert named_publishers(infos) == ["/b1/recorder", "/monitor"]
    assert named_publishers([]) == []


def test_the_unknown_names_are_the_ones_rmw_reports(ctx):
    """The two spellings are rmw_dds_common's (the graph cache that answers
    ``get_publishers_info_by_topic``): both strings are in the library this process loaded with rclpy."""
    del ctx  # an initialised context: rmw and rmw_dds_common are loaded
    libs = {line.split()[-1] for line in Path("/proc/self/maps").read_text().splitlines()
            if "librmw_dds_common.so" in line}
    assert libs, "librmw_dds_common.so is not loaded"
    data = Path(sorted(libs)[0]).read_bytes()
    for name in (NODE_NAME_UNKNOWN, NODE_NAMESPACE_UNKNOWN):
        assert b"\0" + name.encode() + b"\0" in data, name
