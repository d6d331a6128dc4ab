"""What the launch scripts share: the runner, the pre-flight (input checks, the output folder), the
bridge/train/driver graph.

The processes are started, watched and stopped by :class:`adm_sim.processes.supervisor.Supervisor`
(the one supervisor of the launch scripts and the tests).
"""

from __future__ import annotations

import os
import queue
import shutil
import sys
import warnings
from pathlib import Path

import numpy as np
import yaml

from adm_calib.calibration_options import check_speeds
from adm_calib.nodes.params import CALIBRATION_SPECS
from adm_sim.cliutil import option_help, run_cli
from adm_sim.errors import InputError, PlausibilityWarning
from adm_sim.fields import view
from adm_sim.files import FOLDER_LOCK, check_output_folder, claim_folder, input_file, make_output_folder, release
from adm_sim.integrate.run_contract import check_model
from adm_sim.integrate.step_grid import make_grid
from adm_sim.integrate.sweep import check_spans_for_train
from adm_sim.inputs.speeds import parse_speeds
from adm_sim.inputs.train_files import load_train
from adm_sim.nodes.params import (DRIVER_SPECS, TRAIN_SPECS, bridge_from_params, bridge_plausibility, bridge_preset,
                                   bridge_specs, check_params_file, namespaced_params, param, step_options, validate_train)
from adm_sim.processes.dds_env import client_export_line, local_ros_env
from adm_sim.processes.supervisor import NodeDied, Supervisor, ros_args
from adm_sim.protocol import check_namespace
from adm_sim.recording.mcap_scan import scan
from adm_sim.recording.viewer_process import check_loopback, handshake, spawn_viewer

ROOT = Path(__file__).resolve().parents[1]
PARAMS_DIR = ROOT / "ros_ws" / "params"
#: Files a launch writes into its output folder.
OUTPUTS = ("run.mcap", "run.rrd", "summary.json")


def launch(body, args):
    """Run a launch script's ``body(args)`` under the runner of every command line
    (:func:`adm_sim.cliutil.run_cli`): bad input ``error: ...`` and 2, a failed run 1, a refused
    write (full disk, ``ulimit -f``, read-only folder) 1, SIGINT/SIGTERM ``error: interrupted`` and
    130, plausibility warnings one ``warning: ...`` line each; the body's return value is the exit code."""
    return run_cli(lambda: body(args))


def add_graph_options(parser):
    """The options every graph launcher shares beside ``--domain-id``: the viewer (``--spawn``,
    ``--connect``), ``--separate-nodes``, ``--namespace``, ``--wait-clients``."""
    parser.add_argument("--spawn", action="store_true", help="spawn a live rerun viewer (127.0.0.1)")
    parser.add_argument("--connect", help="stream to a running rerun viewer (loopback URL)")
    parser.add_argument("--separate-nodes", action="store_true",
                        help="run the bridge and train nodes as two processes (default: one process hosting both, "
                             "as ROS composition does; the same nodes, topics and results, the DIM round trips "
                             "cheaper)")
    parser.add_argument("--namespace", default="/", metavar="NS", help=(
        "start the whole graph (bridge, train, their exchange helpers, the driver or calibration node "
        "and its recorder) in the ROS 2 namespace NS (e.g. /b3: topics /b3/adm/midspan/accel, /b3/clock, "
        "frame ids b3/<bridge>/midspan); the params file's sections apply to the namespaced nodes; default /"))
    parser.add_argument("--wait-clients", default="0", metavar="N", help=option_help(
        "--wait-clients", "before the first run, wait until N clients opted into the flow control "
        "(docs/ros.md, 'Flow control'), so that they receive every sample"))


def preflight(args, default_out, dim=False, model=None):
    """Everything a launch checks before any process starts, then its output folder, its domain id
    and its viewer.

    The domain id and the viewer options, the inputs each node will start with
    (:func:`check_inputs`), the output folder ``args.out`` (``default_out`` when not given) by the
    folder rule of :mod:`adm_sim.files` (:func:`check_out`); then a ROS domain id is reserved, the
    folder created and claimed (:func:`prepare_out`), and last the viewer checked or spawned
    (:func:`viewer_ready`), so a refused folder never leaves a spawned viewer open. Bad input
    raises :class:`adm_sim.errors.InputError` before anything is created; a viewer that is not
    there raises :class:`~adm_sim.errors.RunError` with the claim released and a folder created
    here removed again.

    Returns ``(out, env, created, old)``: the folder, the :class:`~adm_sim.processes.dds_env.LocalRosEnv`
    (release it at the end), whether the folder was created here, the earlier outputs in it.
    """
    domain_id = check_domain_id(args.domain_id)
    args.wait_clients = view("cli", "--wait-clients").check(args.wait_clients)
    args.namespace = check_namespace(args.namespace)
    check_viewer(args.spawn, args.connect)
    if args.out is not None and not args.out.strip():
        raise InputError("--out: '' is empty; give a folder or omit --out")
    check_inputs(args.bridge, args.train, args.speeds, args.params_file, model=model, dim=dim)
    if dim and args.speeds is not None:  # a calibration: the speeds the calibration node will refuse
        check_calibration_speeds(args.speeds, "--speeds")
    out = Path(args.out) if args.out else default_out
    check_out(out, {"--params-file": args.params_file, "--bridge": args.bridge, "--train": args.train})
    env = local_ros_env(domain_id)  # reserved before the folder exists
    try:
        created, old = prepare_out(out, args.overwrite)
    except BaseException:
        env.release()
        raise
    try:  # the folder first: one refused (an earlier run, another launch's) starts no viewer
        viewer_ready(args)  # the viewer answers before any node starts (RunError, exit 1)
    except BaseException:  # the claim and a folder created here go again: nothing is left
        release_out(out)
        discard_outputs(out, created, old)
        env.release()
        raise
    return out, env, created, old


def check_calibration_speeds(text, option):
    """The speeds of a calibration, refused as ``adm-calib calibrate`` refuses them (a speed list
    of at least 3 speeds, each valid): one line naming ``option``."""
    v = parse_speeds(text, field=option)
    try:
        return check_speeds(v)
    except InputError as exc:
        raise InputError(f"{option}: {text!r}: {str(exc).removeprefix('speeds_kmh: ')}", field=option) from None


def launch_param_specs():
    """``node -> parameter specs`` of every node a launch may start (params files are shared by
    the scripts, so all four nodes are allowed in any of them), and the value checks beyond
    type and range (``(node, name) -> callable``)."""
    # ranges and choices (track_type, damping_model, model, dim_grid) are the specs' own, from the
    # field registry (adm_sim.fields); what is left needs more than one field
    specs = {
        "bridge": [param("bridge", "B1", "preset")] + bridge_specs(bridge_preset("B1")),
        "train": list(TRAIN_SPECS),
        "calibration": list(DRIVER_SPECS) + list(CALIBRATION_SPECS),
        "driver": list(DRIVER_SPECS),
    }
    checks = {
        ("bridge", "bridge"): bridge_preset,
        ("train", "train"): load_train,
        ("train", "speeds_kmh"): lambda v: parse_speeds(v, ordered=False, field="speeds_kmh"),
        ("calibration", "speeds_kmh"): lambda v: check_calibration_speeds(v, "speeds_kmh"),
    }
    return specs, checks


def _given(option, value):
    """``value`` unless it is an empty or blank string (then one line: an empty option never
    falls back to the default)."""
    if value is not None and not str(value).strip():
        raise InputError(f"{option}: '' is empty; give a value or omit {option}")
    return value


def check_inputs(bridge=None, train=None, speeds=None, params_file=None, model=None, dim=False):
    """Validate everything a launch hands to its nodes before any process starts or any folder
    is created; raise :class:`adm_sim.errors.InputError` with the one-line reason.

    The params file is checked key by key (:func:`adm_sim.nodes.params.check_params_file`):
    nodes, parameter names, duplicate keys, types, ranges, the bridge preset, train and speeds in
    it. Then the values each node will start with (its defaults, the params file, the command
    line) are checked together, as the node itself will check them: the bridge's parameters
    against its preset (:func:`adm_sim.nodes.params.bridge_from_params`), the train with its
    model (the DIM needs a train with vehicles; ``dim=True`` when the launch runs the DIM
    whatever the train node's model, as the calibration does).

    Returns ``{node: {name: value}}`` of the params file.
    """
    bridge, train, speeds = _given("--bridge", bridge), _given("--train", train), _given("--speeds", speeds)
    if bridge is not None:  # refused first; its warnings come once, with the preset below
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", PlausibilityWarning)
            bridge_preset(bridge)
    if train is not None:  # refused first; its warnings come once, with the train node's values below
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", PlausibilityWarning)
            load_train(train)
    if speeds is not None:
        parse_speeds(speeds, field="--speeds")
    file_values = {}
    if params_file is not None:
        try:
            input_file(_given("--params-file", params_file), "--params-file", "params YAML file")
        except InputError as exc:
            if not Path(params_file).exists():
                raise InputError(f"--params-file: {params_file!r} does not exist") from None
            raise exc from None
        file_values = check_params_file(params_file, *launch_param_specs())
    # the bridge node: its preset, then every numeric value against it
    bv = dict(file_values.get("bridge", {}))
    preset = bridge_preset(bridge if bridge is not None else bv.get("bridge", "B1"))
    values = {s.name: s.default for s in bridge_specs(preset)}
    values.update({k: v for k, v in bv.items() if k in values})
    try:
        bridge_from_params(preset, values)
    except InputError as exc:
        raise InputError(f"bridge node: {exc}") from None
    warn_bridge_node(preset, values)
    # the train node: the train with its model and speed lanes
    tv = {s.name: s.default for s in TRAIN_SPECS}
    tv.update({k: v for k, v in file_values.get("train", {}).items() if k in tv})
    tv.update({k: v for k, v in (("train", train), ("model", model), ("speeds_kmh", speeds)) if v is not None})
    try:
        t, lanes_kmh = validate_train(tv)
        if dim:
            check_model("dim", t)
    except InputError as exc:
        raise InputError(f"train node: {exc}") from None
    # the run's work and steps, as the bridge node will refuse them (adm_sim.limits.check_work), before any process
    try:
        b = bridge_from_params(preset, values)
        check_spans_for_train(b, t)  # a deck's span shorter than the train's longest axle group, as adm-sim sweep
        make_grid(b, t.length_m, np.asarray(lanes_kmh, dtype=float) / 3.6, step_options(values))
    except InputError as exc:
        raise InputError(f"bridge node: {exc}") from None
    return file_values


def warn_bridge_node(preset, values):
    """The plausibility warnings the bridge node will give its start-up values, here, where the
    user sees them (the node's own go to its log): one ``warning: bridge node: <parameter>: ...``
    line each (:func:`adm_sim.nodes.params.bridge_plausibility`)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", PlausibilityWarning)
        bridge_plausibility(preset, values)
    for w in caught:
        warnings.warn(f"bridge node: {w.message}", PlausibilityWarning, stacklevel=2)


def check_domain_id(domain_id):
    """``--domain-id`` in [0, 101] (Fast DDS ports, see :mod:`adm_sim.processes.dds_env`) or None."""
    return None if domain_id is None else view("cli", "--domain-id").check(domain_id)


def check_viewer(spawn, connect):
    """``--spawn`` and ``--connect`` exclude each other; ``--connect`` is a loopback rerun URL."""
    if spawn and connect is not None:
        raise InputError(f"--connect: {connect!r} with --spawn; give --spawn or --connect, not both")
    if connect is not None:
        try:
            check_loopback(_given("--connect", connect))
        except InputError as exc:
            raise InputError(f"--connect: {str(exc).removeprefix('connect_url: ')}") from None


def viewer_ready(args):
    """The live viewer answers before any node starts: ``--connect`` must answer the handshake of a rerun viewer (a closed port, another server, a silent socket:
    :class:`~adm_sim.errors.RunError`, one line, exit 1); ``--spawn`` starts the viewer here
    (listening, answering and alive a moment later, or one line with its own last word) and the
    driver streams to it as to ``--connect`` (``args.connect`` is set, ``args.spawn`` cleared)."""
    if args.connect is not None:
        handshake(args.connect, what="--connect")
    elif args.spawn:
        _, args.connect = spawn_viewer(what="--spawn")
        args.spawn = False


def check_out(out, inputs=None):
    """The output folder before anything is created (:func:`adm_sim.files.check_output_folder`): not
    a file, in a writable place, and none of its outputs an input of the launch (``inputs``:
    ``{option: path}``)."""
    return check_output_folder(out, "--out", OUTPUTS, inputs)


def prepare_out(out, overwrite):
    """Create the output folder and claim it (:func:`adm_sim.files.claim_folder`); an earlier run in
    it is kept unless ``overwrite`` (InputError), and a folder another launch is writing is refused
    naming its pid. With ``overwrite`` the earlier files stay until the new ones are complete: the
    driver node (parameter ``overwrite``) writes beside them and renames at a successful end.

    Returns ``(created, old)``: whether the folder was created here, and the earlier outputs in it.
    """
    created = make_output_folder(out, "--out")
    return created, set(claim_folder(out, "--out", OUTPUTS, overwrite))


def release_out(out):
    """Give up the claim of :func:`prepare_out` (its lock file is removed first)."""
    release(out)


def discard_outputs(out, created, old=()):
    """After an interrupt: remove what the launch wrote (its new outputs and logs; the whole
    folder if the launch created it), so no partial output is left. Earlier outputs (``old``)
    were never replaced (the node renames only at a successful end) and stay."""
    if created:
        shutil.rmtree(out, ignore_errors=True)
        return
    for f in OUTPUTS:
        if f not in old:
            try:
                (out / f).unlink()
            except OSError:
                pass


def after_node_died(out, started_s=None):
    """After a node died (a SIGKILL: its ``finally`` blocks never ran, the supervisor has stopped
    the rest): remove the sidecar lock files (``.<name>.lock``) and temporary files
    (``.<stem>.tmp-<pid><suffix>``) in ``out`` whose process is gone, and say whether the recording
    under its final name is whole. Returns the note for the launcher's one error line: ``;
    <out>/run.mcap is incomplete (...): recover its intact chunks with: adm-sim salvage ...`` or
    ``; <out>/run.mcap is whole``; empty without a recording of this launch (``started_s``: the
    launch's start, a recording older than it is an earlier run's)."""
    out = Path(out)
    for p in list(out.glob(".*.lock")) + list(out.glob(".*.tmp-*")):
        if p.name == FOLDER_LOCK:  # the launcher's own claim, released by release_out
            continue
        if p.name.endswith(".lock"):
            try:
                pid = int(p.read_text().strip() or "0")
            except (OSError, ValueError):
                continue
        else:
            digits = p.name.split(".tmp-", 1)[1].split(".")[0]
            pid = int(digits) if digits.isdigit() else 0
        if pid > 0 and not _alive(pid):
            try:
                p.unlink()
            except OSError:
                pass
    mcap = out / "run.mcap"
    if not mcap.is_file() or (started_s is not None and mcap.stat().st_mtime < started_s):
        return ""

    try:
        found = scan(mcap)
    except Exception as exc:  # noqa: BLE001  a file the scan cannot read at all is incomplete too
        why = type(exc).__name__
    else:
        if not (found.truncated or found.damaged):
            return f"; {mcap} is whole"
        why = f"{len(found.messages)} complete messages, the open chunk lost"
    return (f"; {mcap} is incomplete (its writer died: {why}): recover its intact chunks with: "
            f"adm-sim salvage {mcap} OUT.mcap")


def _alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


#: Process name (log ``logs/bridge_train.log``) of the bridge and train nodes composed in one process.
COMPOSED = "bridge_train"


def composed_args(params_file, bridge_params, train_params):
    """``--ros-args`` of :mod:`adm_sim.nodes.composed`: each node's overrides named by its node
    (``-p bridge:ds_m:=0.05``), so neither takes the other's."""
    return ros_args(params_file, {**{f"bridge:{k}": v for k, v in bridge_params.items()},
                                  **{f"train:{k}": v for k, v in train_params.items()}})


def supervise_graph(out, env, created, old, t_launch, start, on_stop=None):
    """``start(sup)`` under a :class:`Supervisor` logging to ``out/logs``, and the ending every graph
    launcher shares: on an interrupt the outputs of this run removed (:func:`discard_outputs`), one line,
    130; when a node dies its leftovers cleaned and the recording named (:func:`after_node_died`), one
    line, 1; else ``None``. Either way the domain id is given back, ``on_stop()`` runs (a progress bar
    closed) and the output folder's claim is released. ``out``, ``env``, ``created``, ``old``: what
    :func:`preflight` returned; ``t_launch``: the launch's start (``time.time()``)."""
    code = None
    try:
        with Supervisor(out / "logs", env=env) as sup:
            start(sup)
    except KeyboardInterrupt:
        code, line = 130, "interrupted (stopped every node; the outputs of this run are removed)"
    except NodeDied as exc:
        code, line = 1, str(exc).rstrip(": ")
    finally:
        env.release()
    if on_stop is not None:
        on_stop()
    if code == 1:
        line += after_node_died(out, t_launch)  # a killed node's locks and temporary files; the recording named
    release_out(out)
    if code == 130:
        discard_outputs(out, created, old)
    if code is not None:
        print(f"error: {line}", file=sys.stderr)
    return code


def graph_lines(sup, out, namespace):
    """The launcher's first two lines: the domain id (and namespace) and the client's export line."""
    where = "" if namespace == "/" else f", namespace {namespace}"
    print(f"ROS_DOMAIN_ID={sup.domain_id} (this machine only{where}); output in {out}", flush=True)
    topics = "" if namespace == "/" else f" (topics under {namespace})"
    print(f"{client_export_line(sup.env)}  # a ROS 2 client in another shell{topics}", flush=True)


def run_graph(sup, params_file, bridge_params, train_params, driver, driver_module, driver_params, on_line,
              composed=False, namespace="/"):
    """Start the bridge, train and driver nodes and follow the driver until it exits.

    ``composed``: the bridge and train nodes in one process (:mod:`adm_sim.nodes.composed`,
    process name :data:`COMPOSED`) instead of one each. ``namespace``: every process is started
    with ``-r __ns:=<namespace>`` (each node, its exchange helper and the driver's recorder) and
    the params file's sections keyed by the namespaced node names
    (:func:`adm_sim.nodes.params.namespaced_params`, a copy in the log folder). Every stdout line
    of the driver goes to ``on_line``. Raises :class:`NodeDied` naming the node when the bridge or
    the train dies, or when the driver fails.
    """
    ns_args = []
    if namespace != "/":
        if params_file:
            params_file = namespaced_params(params_file, namespace, sup.log_dir / "params_namespaced.yaml")
        ns_args = ["-r", f"__ns:={namespace}"]
    if composed and ns_args:  # rcl's node-prefixed -p cannot name a namespaced node: a second file

        ns = namespace.rstrip("/")
        overrides = sup.log_dir / "params_overrides.yaml"
        overrides.write_text(yaml.safe_dump({f"{ns}/bridge": {"ros__parameters": dict(bridge_params)},
                                             f"{ns}/train": {"ros__parameters": dict(train_params)}}))
        args = ros_args(params_file) + ["--params-file", str(overrides)]
        sup.start(COMPOSED, "adm_sim.nodes.composed", args + ns_args)
        pair = (COMPOSED,)
    elif composed:
        sup.start(COMPOSED, "adm_sim.nodes.composed", composed_args(params_file, bridge_params, train_params))
        pair = (COMPOSED,)
    else:
        sup.start("bridge", "adm_sim.nodes.bridge_node", ros_args(params_file, bridge_params) + ns_args)
        sup.start("train", "adm_sim.nodes.train_node", ros_args(params_file, train_params) + ns_args)
        pair = ("bridge", "train")
    sup.start(driver, driver_module, ros_args(params_file, driver_params) + ns_args, capture=True)
    while True:
        try:
            _, line = sup.lines.get(timeout=0.2)
        except queue.Empty:
            line = None
        if line is not None:
            on_line(line)
        died = sup.dead(pair)
        if died:
            who = "nodes 'bridge' and 'train' (one process)" if died[0] == COMPOSED else f"node '{died[0]}'"
            raise NodeDied(f"{who} died (exit status {died[1]}): {sup.log_tail(died[0])}")
        done = sup.dead((driver,))
        if done and sup.lines.empty():
            if done[1] != 0:
                raise NodeDied(f"node '{driver}' failed (exit status {done[1]}): {sup.log_tail(driver)}")
            return
