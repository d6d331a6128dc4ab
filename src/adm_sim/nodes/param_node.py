"""ROS parameters of the nodes from the ROS-free specs (:mod:`adm_sim.nodes.params`): declared with
their descriptors, refused out of range in the core's words, unknown names refused at start-up."""

from __future__ import annotations

from rcl_interfaces.msg import SetParametersResult
from rclpy.exceptions import InvalidParameterTypeException

from adm_sim.errors import InputError
from adm_sim.nodes.params import RCLPY_PARAMETERS


class ParamNodeMixin:
    """Declares :class:`ParamSpec` parameters and refuses out-of-range values in the core's words.

    :meth:`declare_specs` declares the parameters, checks the start-up values (a node started
    with ``-p span_m:=-5.0`` raises :class:`InputError`, which :func:`run_node` prints as one
    line, exit 2) and registers an on-set callback that refuses later sets with the same reason
    (``span_m: -5 m is out of range; allowed [1, 150] m``); the node keeps its old values.
    """

    _specs: dict

    def declare_specs(self, specs, on_set=None):
        """Declare ``specs``, check their start-up values and refuse out-of-range sets.

        ``on_set`` (a node's own on-set callback) runs after the range checks have passed; on-set
        callbacks only validate, state changes belong in a post-set callback (ros2/demos).
        """

        self._specs = {s.name: s for s in specs}
        for s in specs:
            try:
                self.declare_parameter(s.name, s.default, s.descriptor())
            except InvalidParameterTypeException as exc:  # e.g. -p speeds_kmh:=280 (a YAML integer)
                unit = f" ({s.unit})" if s.unit else ""
                raise InputError(f"{s.name}: the given value has the wrong type ({exc}); expected a "
                                 f"{type(s.default).__name__}{unit}, e.g. {s.default!r}: quote text values "
                                 f"in YAML and -p overrides") from None
        for name, value in self.param_values().items():
            self._specs[name].check(value)
        self._refuse_undeclared()
        self._on_set_checked = on_set
        self.add_on_set_parameters_callback(self._check_ranges)

    def _refuse_undeclared(self):
        """A start-up value (``-p name:=value``, a params file's section of this node) for a
        parameter the node does not declare is refused: rclpy would silently ignore it, and a
        typo (``-p span:=20.0`` for ``span_m``) would run with the default. Names of a params
        file's ``/**`` section (meant for every node, each taking its own) are exempt."""
        overrides = getattr(self, "_parameter_overrides", {}) or {}
        unknown = sorted(n for n in overrides
                         if not self.has_parameter(n) and n not in SHARED_PARAMETER_NAMES)
        if unknown:
            allowed = sorted(set(self._parameters) | set(RCLPY_PARAMETERS))
            raise InputError(f"{unknown[0]}: unknown parameter of node '{self.get_name()}'; allowed "
                             f"{', '.join(allowed)}")

    def _check_ranges(self, params):
        """On-set callback: every value in its range (else the reason, old values kept), then the
        node's own callback."""
        for p in params:
            s = self._specs.get(p.name)
            if s is None:
                continue
            try:
                s.check(p.value)
            except InputError as exc:
                return SetParametersResult(successful=False, reason=f"{exc}; keeping {self.get_parameter(s.name).value!r}")
        return SetParametersResult(successful=True) if self._on_set_checked is None else self._on_set_checked(params)

    def param_values(self):
        """Current values of the declared parameters, ``{name: value}``."""
        return {n: self.get_parameter(n).value for n in self._specs}


#: Parameter names of the ``/**`` sections of the params files this process was started with
#: (set by :func:`run_node`): every node takes the ones it declares and ignores the others.
SHARED_PARAMETER_NAMES: set = set()
