"""Parameters of the calibration node, free of ROS (a launcher checks them before it starts the node).

It extends :mod:`adm_sim.nodes.params`: the calibration node is a run driver, so it declares the
core's ``DRIVER_SPECS`` and these specs after them, built with the core's :func:`~adm_sim.nodes.params.param`
from the one field registry.
"""

from __future__ import annotations

from adm_sim.limits import DEFAULT_SPEEDS
from adm_sim.nodes.params import param

CALIBRATION_SPECS = [
    param("speeds_kmh", DEFAULT_SPEEDS, "MLM speed range: start:stop:step or a comma list"),
    param("dim_grid", "window", "window (the paper's speeds where the associated DIM peak can lie: the paper grid's result) | paper (5 km/h + fine around the MLM peak) | full (every MLM speed)"),
]
