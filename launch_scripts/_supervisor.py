"""What the launch scripts share: input checks, the output folder, the bridge/train/driver graph.

The processes are started, watched and stopped by :class:`adm_sim.ros.supervisor.Supervisor`
(the one supervisor of the launch scripts and the tests).
"""

from __future__ import annotations

import queue
from pathlib import Path

from adm_sim.ros.supervisor import NodeDied, Supervisor, ros_args  # noqa: F401  (used by the scripts)

ROOT = Path(__file__).resolve().parents[1]
PARAMS_DIR = ROOT / "ros_ws" / "params"
#: Files a launch writes into its output folder.
OUTPUTS = ("run.mcap", "run.rrd", "summary.json")


def launch_param_specs():
    """``node -> parameter specs`` of every node a launch may start (params files are shared by
    the scripts, so all four nodes are allowed in any of them), and the value checks beyond
    type and range (``(node, name) -> callable``)."""
    from adm_calib.nodes.calibration_node import CALIBRATION_SPECS
    from adm_sim.bridge import resolve_bridge
    from adm_sim.errors import InputError
    from adm_sim.nodes.bridge_node import TRACK_TYPES, bridge_specs
    from adm_sim.nodes.common import ParamSpec
    from adm_sim.nodes.driver import DRIVER_SPECS
    from adm_sim.nodes.train_node import TRAIN_SPECS
    from adm_sim.stepping import MODELS
    from adm_sim.sweep import parse_speeds
    from adm_sim.trains import load_train

    def one_of(name, allowed):
        def check(value):
            if value not in allowed:
                raise InputError(f"{name}: {value!r} is not allowed; allowed {', '.join(map(repr, allowed))}")
        return check

    specs = {
        "bridge": [ParamSpec("bridge", "B1", "", "preset")] + bridge_specs(resolve_bridge("B1")),
        "train": list(TRAIN_SPECS),
        "calibration": list(DRIVER_SPECS) + list(CALIBRATION_SPECS),
        "driver": list(DRIVER_SPECS),
    }
    checks = {
        ("bridge", "bridge"): resolve_bridge,
        ("bridge", "track_type"): one_of("track_type", TRACK_TYPES),
        ("bridge", "damping_model"): one_of("damping_model", ("rayleigh", "modal")),
        ("train", "train"): load_train,
        ("train", "model"): one_of("model", MODELS),
        ("train", "speeds_kmh"): lambda v: parse_speeds(v, ordered=False),
        ("calibration", "speeds_kmh"): parse_speeds,
        ("calibration", "dim_grid"): one_of("dim_grid", ("paper", "full")),
    }
    return specs, checks


def check_inputs(bridge=None, train=None, speeds=None, params_file=None):
    """Validate a launch's bridge, train, speeds and params file before any process starts.

    The params file is checked key by key (:func:`adm_sim.nodes.common.check_params_file`):
    nodes, parameter names, types, ranges, the bridge preset, train and speeds in it.
    Raises :class:`adm_sim.errors.InputError` with the one-line reason.
    """
    from adm_sim.bridge import resolve_bridge
    from adm_sim.errors import InputError
    from adm_sim.nodes.common import check_params_file
    from adm_sim.sweep import parse_speeds
    from adm_sim.trains import load_train

    if bridge:
        resolve_bridge(bridge)
    if train:
        load_train(train)
    if speeds:
        parse_speeds(speeds)
    if params_file:
        if not Path(params_file).is_file():
            raise InputError(f"--params-file: {params_file!r} does not exist")
        check_params_file(params_file, *launch_param_specs())


def prepare_out(out, overwrite):
    """Create the output folder; an earlier run in it is kept unless ``overwrite`` (InputError)."""
    from adm_sim.errors import InputError

    out.mkdir(parents=True, exist_ok=True)
    old = [f for f in OUTPUTS if (out / f).exists()]
    if old and not overwrite:
        raise InputError(f"--out: {str(out)!r} holds an earlier run ({', '.join(old)}); "
                         f"choose another folder or pass --overwrite")
    for f in old:
        (out / f).unlink()


def run_graph(sup, params_file, bridge_params, train_params, driver, driver_module, driver_params, on_line):
    """Start the bridge, train and driver nodes and follow the driver until it exits.

    Every stdout line of the driver goes to ``on_line``. Raises :class:`NodeDied` naming the node
    when the bridge or the train dies, or when the driver fails.
    """
    sup.start("bridge", "adm_sim.nodes.bridge_node", ros_args(params_file, bridge_params))
    sup.start("train", "adm_sim.nodes.train_node", ros_args(params_file, train_params))
    sup.start(driver, driver_module, ros_args(params_file, driver_params), capture=True)
    while True:
        try:
            _, line = sup.lines.get(timeout=0.2)
        except queue.Empty:
            line = None
        if line is not None:
            on_line(line)
        died = sup.dead(("bridge", "train"))
        if died:
            raise NodeDied(f"node '{died[0]}' died (exit status {died[1]}): {sup.log_tail(died[0])}")
        done = sup.dead((driver,))
        if done and sup.lines.empty():
            if done[1] != 0:
                raise NodeDied(f"node '{driver}' failed (exit status {done[1]}): {sup.log_tail(driver)}")
            return
