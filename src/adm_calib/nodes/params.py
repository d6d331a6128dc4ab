"""Parameters of the calibration node, free of ROS (a launcher checks them before it starts the node)."""

from __future__ import annotations

from adm_sim.limits import DEFAULT_SPEEDS
from adm_sim.nodes.params import param

CALIBRATION_SPECS = [
    param("speeds_kmh", DEFAULT_SPEEDS, "MLM speed range: start:stop:step or a comma list"),
    param("dim_grid", "window", "window (the paper's speeds where the associated DIM peak can lie: the paper grid's result) | paper (5 km/h + fine around the MLM peak) | full (every MLM speed)"),
]
