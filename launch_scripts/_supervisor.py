"""What the launch scripts share: input checks, the output folder, the bridge/train/driver graph.

The processes are started, watched and stopped by :class:`adm_sim.ros.supervisor.Supervisor`
(the one supervisor of the launch scripts and the tests).
"""

from __future__ import annotations

import queue
import time
from pathlib import Path

from adm_sim.ros.supervisor import NodeDied, Supervisor, ros_args  # noqa: F401  (used by the scripts)

ROOT = Path(__file__).resolve().parents[1]
PARAMS_DIR = ROOT / "ros_ws" / "params"
#: Files a launch writes into its output folder.
OUTPUTS = ("run.mcap", "run.rrd", "summary.json")


def check_inputs(bridge=None, train=None, speeds=None, params_file=None):
    """Validate a launch's bridge, train, speeds and params file before any process starts.

    Raises :class:`adm_sim.errors.InputError` with the one-line reason.
    """
    from adm_sim.bridge import resolve_bridge
    from adm_sim.errors import InputError
    from adm_sim.sweep import parse_speeds
    from adm_sim.trains import load_train

    if bridge:
        resolve_bridge(bridge)
    if train:
        load_train(train)
    if speeds:
        parse_speeds(speeds)
    if params_file and not Path(params_file).is_file():
        raise InputError(f"--params-file: {params_file!r} does not exist")


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
