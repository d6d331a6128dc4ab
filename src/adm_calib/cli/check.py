"""``adm-calib check``: the EN 1991-2 check of ``adm-sim check`` with all four damping methods.

The options and the run are :mod:`adm_sim.cli.check`'s; ``none`` and ``adm`` are the core's, ``lb`` (the
paper's lower bounds) and ``vbi`` (the calibrated Δζ_VBI) come from :func:`adm_calib.check.calibrated_damping`.
"""

from __future__ import annotations

from adm_sim.cli import check as sim_check

from adm_calib.check import calibrated_damping


def add_arguments(parser):
    """The options of ``adm-sim check``, one definition for both commands."""
    sim_check.add_arguments(parser)


def run(args):
    """``adm-sim check`` with the damping methods ``lb`` and ``vbi``."""
    return sim_check.run(args, damping_provider=calibrated_damping)
