"""The ``main`` of every node (:func:`run_node`): init, spin until finished, one-line errors and
warnings, clean shutdown; one process may host several nodes (:func:`spin_composed`)."""

from __future__ import annotations

import sys
import time

import rclpy
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException

from adm_sim.cliutil import caused_by_interrupt, one_line_warnings
from adm_sim.errors import AdmSimError, InputError
from adm_sim.files import release_all
from adm_sim.nodes.param_node import SHARED_PARAMETER_NAMES
from adm_sim.nodes.params import load_params_yaml, unapplied_sections
from adm_sim.recording.viewer_process import exit_if_abandoned


def stopped_by_signal(exc, context=None):
    """Whether ``exc`` is only the trace of a stop by SIGINT or SIGTERM, not a bug: raised *from* a
    ``KeyboardInterrupt`` (:func:`adm_sim.cliutil.caused_by_interrupt`, e.g. a Ctrl-C within a library's
    first import), or raised once the signal's handler had shut ``context`` (default: rclpy's) down. The
    handler does that from another thread; when it lands while an executor builds its next wait set,
    rclpy raises a ``RuntimeError`` of the invalid context instead of ``ExternalShutdownException``
    (ros2/rclpy#398), and a callback publishing at that moment fails the same way."""
    return not rclpy.ok(context=context) or caused_by_interrupt(exc)


def run_node(make_node, args=None, name="node"):
    """The ``main`` of every node: init, spin until finished, one-line errors and warnings, clean shutdown.

    ``make_node`` may also return a tuple of nodes: they are hosted by this one process (as ROS
    composition hosts nodes), every entity of theirs, exchange lanes included, served by one
    executor (:func:`spin_composed`).

    Every Python warning raised in the node (start-up, parameter callbacks, the driver's job) is
    printed as one line ``warning: <name>: ...`` on stderr, as the CLIs print theirs
    (:class:`adm_sim.cliutil.one_line_warnings`; Python's filters still print a repeated warning once).
    """

    with one_line_warnings(prefix=f"{name}: ", categories=(Warning,), repeat=False):
        code = _run_node(make_node, args, name)
    exit_if_abandoned(code)  # a rerun viewer given up: rerun's flush at exit would hang on it
    return code


def _run_node(make_node, args, name):
    """:func:`run_node` without the warning display: read the params files, start rclpy, make the
    node(s) and spin them (:func:`spin_single` or :func:`spin_composed`).

    Returns the process exit code: 0, 2 on bad input (start-up parameters, params file), 1 on a
    failed run or a lockstep failure (a :class:`RunError`), 130 on Ctrl-C or SIGTERM.
    """
    try:  # a params file that is not YAML: our line, before rcl prints its own
        param_docs = read_params_files(sys.argv if args is None else list(args))
    except InputError as exc:
        print(f"error: {name}: {exc}", file=sys.stderr, flush=True)
        return 2
    try:
        rclpy.init(args=args)
    except Exception as exc:  # malformed --ros-args: rcl's message, one line
        reason = " ".join(str(exc).split())
        print(f"error: {name}: cannot start: {reason}", file=sys.stderr, flush=True)
        return 2
    nodes = []
    try:
        made = make_node()
        nodes = list(made) if isinstance(made, tuple) else [made]
        check_sections_apply(nodes, param_docs)
        executor = nodes[0].make_executor()
        for n in nodes:
            executor.add_node(n)
        return spin_composed(nodes, executor) if len(nodes) > 1 else spin_single(nodes[0], executor)
    except (KeyboardInterrupt, ExternalShutdownException):
        return 130
    except AdmSimError as exc:  # ExchangeError is a RunError
        print(f"error: {name}: {exc}", file=sys.stderr, flush=True)
        report_failure(nodes, str(exc))
        return 2 if isinstance(exc, InputError) else 1  # the CLIs' mapping (adm_sim.cliutil.run_cli)
    except Exception as exc:
        if not stopped_by_signal(exc):
            raise
        return 130  # shut down (SIGINT/SIGTERM) under the executor or a publishing callback
    finally:
        for node in nodes:
            node.close()
            node.destroy_node()
        rclpy.try_shutdown()
        release_all()  # every output this node claimed, however it ended (no stray lock file)


def read_params_files(argv):
    """``[(file, its YAML), ...]`` of the ``--params-file`` arguments of ``argv`` (every section must
    reach its node: :func:`check_sections_apply`); the names of their ``/**`` sections join
    :data:`SHARED_PARAMETER_NAMES`. Raises :class:`InputError` for a file that is not YAML."""
    param_docs = []
    for i, a in enumerate(argv[:-1]):
        if a == "--params-file":
            doc = load_params_yaml(argv[i + 1])
            param_docs.append((argv[i + 1], doc))
            shared = doc.get("/**") if isinstance(doc, dict) else None
            if isinstance(shared, dict) and isinstance(shared.get("ros__parameters"), dict):
                SHARED_PARAMETER_NAMES.update(shared["ros__parameters"])
    return param_docs


def spin_single(node, executor):
    """The main loop of one node; returns its :meth:`~adm_sim.nodes.node_base.NodeBase.end`.

    While the node has a run active (``node.run``) its :class:`~adm_sim.nodes.exchange.ExchangeLane`
    is served in bursts of up to 50 ms, each followed by the partner watch and one turn of the
    node's executor; otherwise the executor spins with a 0.2 s timeout.
    """
    node.begin()
    lane = node.exchange
    while rclpy.ok() and not node.finished:
        if lane is not None and node.run is not None:
            lane.spin(time.monotonic() + 0.05, lambda: node.run is not None)
            node.watch()
            executor.spin_once(timeout_sec=0.0)
        else:
            executor.spin_once(timeout_sec=0.2)
            if lane is not None:  # a stray exchange message with no run active is an error now
                lane.turn()
        node.watch()
    return node.end(executor)


def report_failure(nodes, message):
    """Tell the other nodes that ``nodes`` stop with ``message`` (best effort): each node's
    :meth:`~adm_sim.nodes.node_base.NodeBase.report_failure`, then up to 1 s for its status
    publisher's subscribers to take it before the node leaves."""
    for node in nodes:
        try:
            node.report_failure(message)
            pub = getattr(node, "pub_status", None)
            if pub is not None:
                pub.wait_for_all_acked(Duration(seconds=1.0))
        except Exception:
            pass


def check_sections_apply(nodes, param_docs):
    """Refuse (:class:`InputError`, exit 2) a params-file section that names one of ``nodes`` but
    that rcl does not apply to it: rcl matches sections by fully qualified name, so under
    ``-r __ns:=/b3`` a section keyed ``bridge`` (read ``/bridge``) would leave the node
    ``/b3/bridge`` on its defaults without a word."""
    for node in nodes:
        fqn = node.get_fully_qualified_name()
        for path, doc in param_docs:
            missed = unapplied_sections(doc, fqn)
            if missed:
                base = fqn.rsplit("/", 1)[-1]
                raise InputError(f"--params-file {path!r}: section {missed[0]!r} is not applied to the node {fqn!r} "
                                 f"(rcl reads it as {('/' + missed[0]).replace('//', '/')!r}); key it {fqn!r} or "
                                 f"'/**/{base}'")


#: How often the composed loop runs the nodes' :meth:`NodeBase.watch` (s).
WATCH_EVERY_S = 0.05


def spin_composed(nodes, executor):
    """The main loop of several nodes in one process: one executor serves every entity of theirs
    (their exchange lanes moved onto it, :meth:`ExchangeLane.share`), one event per turn in the
    order they came, so a message one node publishes to another is taken on the next turn with
    no other process to wake. Between turns the kept exceptions of the lanes are raised and,
    every :data:`WATCH_EVERY_S`, every node's :meth:`NodeBase.watch` runs. Returns the exit code
    (the largest of the nodes' :meth:`NodeBase.end`)."""

    lanes = [n.exchange for n in nodes if n.exchange is not None]
    for lane in lanes:
        lane.share(executor)
    for n in nodes:
        n.begin()
    next_watch, timeout_s, now = 0.0, 0.2, time.monotonic
    while True:  # per event: one turn, the lanes' errors; the rest every WATCH_EVERY_S
        executor.spin_once(timeout_sec=timeout_s)
        for lane in lanes:
            if lane.error is not None:
                lane.raise_error()
        if now() >= next_watch:
            next_watch = now() + WATCH_EVERY_S
            for n in nodes:
                n.watch()
            if not rclpy.ok() or any(n.finished for n in nodes):
                break
            timeout_s = 0.05 if any(n.run is not None for n in nodes) else 0.2
    return max(n.end(executor) for n in nodes)
