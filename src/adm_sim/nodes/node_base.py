"""The bases of the adm-sim nodes: :class:`NodeBase` (the hooks of the main loop,
:func:`adm_sim.nodes.node_main.run_node`) and :class:`LockstepNode` (the parameter life cycle of
a node that runs lockstep runs: parameters locked while a run is active)."""

from __future__ import annotations

import warnings

from rcl_interfaces.msg import SetParametersResult
from rclpy.executors import SingleThreadedExecutor
from rclpy.experimental import EventsExecutor
from rclpy.node import Node

from adm_sim.errors import InputError, PlausibilityWarning
from adm_sim.nodes.param_node import ParamNodeMixin


class NodeBase(ParamNodeMixin, Node):
    """Base of the adm-sim nodes: the hooks of :func:`run_node` with their defaults.

    ``run`` is the active lockstep run (or None), ``exchange`` the node's :class:`ExchangeLane`
    (or None), ``finished`` ends the main loop.
    """

    run = None
    exchange = None
    finished = False

    def make_executor(self):
        """The executor :func:`run_node` spins the node with: a ``SingleThreadedExecutor``."""
        return SingleThreadedExecutor(context=self.context)

    def begin(self):
        """Called once before the main loop (a driver starts its job here)."""

    def watch(self):
        """Called between executor turns, never inside a callback; raises to end the node."""

    def end(self, executor):
        """Called when the loop ends normally; returns the exit code."""
        return 0

    def report_failure(self, message):
        """Tell the other nodes that this one stops with ``message`` (best effort)."""

    def close(self):
        """Finish the node's files (always called before :meth:`destroy_node`)."""

    def destroy_node(self):
        if self.exchange is not None:
            self.exchange.destroy()
            self.exchange = None
        return super().destroy_node()


class LockstepNode(NodeBase):
    """Base of the bridge and train nodes: the parameter life cycle of a node that runs lockstep runs.

    :meth:`declare_run_parameters` declares the specs; then every set passes three stages, in
    the order of ros2/demos ``set_parameters_callback.py``:

    1. the range of each value (:class:`ParamSpec`, in :class:`ParamNodeMixin`);
    2. on-set, :meth:`_check_set`: refused while a run is active (``<node>: parameters are locked
       while run 3 is in progress ...``, :meth:`lock_reason`) or when :meth:`validate` raises
       :class:`InputError` for the new values taken together; nothing changes here;
    3. post-set, :meth:`_apply_set`: :meth:`configure` with the new values, the partner timeout
       and the latched description (:meth:`publish_description`) follow them.
    """

    partner = None

    def make_executor(self):
        """rclpy's ``EventsExecutor`` for the node's own entities (parameter services, run control),
        as for the exchange lane: while a run is active :func:`run_node` gives it a turn every 50 ms,
        and a ``SingleThreadedExecutor`` rebuilt its wait set of a dozen services, subscriptions and
        publishers' events for each turn even with nothing to do. Callbacks and their order are
        those of a single-threaded executor."""
        return EventsExecutor(context=self.context)

    def declare_run_parameters(self, specs):
        """Declare ``specs`` and install the on-set and post-set stages; returns
        :meth:`validate` of the start-up values (they are checked before the node runs)."""
        self.declare_specs(specs, on_set=self._check_set)
        checked = self.validate(self.param_values())
        self._warn_implausible(self.param_values())
        self.add_post_set_parameters_callback(self._apply_set)
        return checked

    def plausibility(self, values):
        """Issue the :class:`~adm_sim.errors.PlausibilityWarning` of the valid values ``values``
        (:mod:`adm_sim.model.plausibility`: a value the model computes but no real bridge has)."""

    def _warn_implausible(self, values):
        """:meth:`plausibility` of ``values`` at start-up and after every set, each warning once
        per node (the same value set again is not warned again); :func:`run_node` prints each as
        one line ``warning: <node>: ...``."""
        said = self.__dict__.setdefault("_plausibility_said", set())
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", PlausibilityWarning)
            self.plausibility(values)
        for w in caught:
            text = str(w.message)
            if not issubclass(w.category, PlausibilityWarning):
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
            elif text not in said:
                said.add(text)
                warnings.warn(text, PlausibilityWarning, stacklevel=2)

    def validate(self, values):
        """Raise :class:`InputError` when ``values`` (every parameter) do not make a valid node."""

    def configure(self, values):
        """Change the node's state to ``values`` (post-set; they passed :meth:`validate`)."""

    def publish_description(self):
        """Publish the node's latched description."""

    def lock_reason(self):
        """Why parameters are locked now: the run in progress (``self.run``, a run-state dataclass
        with an ``id``, as :class:`~adm_sim.nodes.train_node.TrainRunState`)."""
        return f"run {self.run.id} is in progress"

    def _check_set(self, params):
        if self.run is not None:
            return SetParametersResult(successful=False, reason=(
                f"{self.get_name()}: parameters are locked while {self.lock_reason()}"))
        values = self.param_values()
        values.update({p.name: p.value for p in params})
        try:
            self.validate(values)
        except InputError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _apply_set(self, params):
        values = self.param_values()
        self.configure(values)
        self._warn_implausible(values)
        if self.partner is not None and any(p.name == "partner_timeout_s" for p in params):
            self.partner.timeout_s = float(values["partner_timeout_s"])
        self.publish_description()
