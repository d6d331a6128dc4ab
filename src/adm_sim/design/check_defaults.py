"""Every default of the EN 1991-2 dynamic check with its source: the standard's clause, or the
project's choice where the standard's text read here gives no number.

One list (:data:`DEFAULTS`) that the text output, the JSON (``defaults``), the report and
docs/check.md ("Defaults and their sources") all show; ``tests/design/test_check_defaults.py`` pins every
value against the code that applies it and keeps the docs table equal to this list.
"""

from __future__ import annotations

from dataclasses import dataclass

from adm_sim.design.check import (BALLAST_DENSITY_MAX_KG_M3, BALLAST_DENSITY_MIN_KG_M3, BALLAST_DEPTH_FACTOR_UPPER,
                                  NEAR_GOVERNING_FRACTION, REFINE_STEP_KMH)
from adm_sim.design.check_sls import (DEFLECTION_SPAN_RATIO, DELTA_H_LIMITS_M, END_ROTATION_LIMIT_RAD,
                                      LATERAL_FREQUENCY_MIN_HZ)
from adm_sim.design.design_loads import DEFAULT_MAINTENANCE
from adm_sim.design.check import MIN_SPEED_M_S
from adm_sim.limits import ACC_LIMITS_M_S2, DESIGN_SPEED_FACTOR

STANDARD = "standard"
PROJECT = "project's choice"


@dataclass(frozen=True)
class Default:
    """One default: what it is, its value, where it comes from, and whether it is the standard's."""

    name: str
    value: str
    source: str
    kind: str  # STANDARD or PROJECT

    def to_dict(self):
        return {"name": self.name, "value": self.value, "source": self.source, "kind": self.kind}

    def line(self):
        tag = "" if self.kind == STANDARD else " [project's choice]"
        return f"{self.name}: {self.value} ({self.source}){tag}"


DEFAULTS = (
    Default("speeds", f"{MIN_SPEED_M_S:g} m/s .. {DESIGN_SPEED_FACTOR:g} V", "EN 1991-2 6.4.6.2(1)", STANDARD),
    Default("speed step", f"1 km/h, refined at {REFINE_STEP_KMH:g} km/h around every resonance",
            "--speed-step; not a number of the standard", PROJECT),
    Default("track maintenance", f"{DEFAULT_MAINTENANCE} (Phi3 with phi'')",
            "EN 1991-2 6.4.5.2(3)P: Phi3 where no dynamic factor is specified", STANDARD),
    Default("acceleration limit", f"{ACC_LIMITS_M_S2['ballasted']:g} m/s2 ballasted, "
            f"{ACC_LIMITS_M_S2['direct_fastening']:g} m/s2 direct fastening", "EN 1990 A2.4.4.2.1(4)", STANDARD),
    Default("where the acceleration is taken", "anywhere on the deck", "EN 1990 A2.4.4.2.1", STANDARD),
    Default("modes", "every mode up to max(30 Hz, 1.5 n0, n3)", "EN 1990 A2.4.4.2.1", STANDARD),
    Default("damping per mode", "zeta on every mode (modal)",
            "the project's reading of EN 1991-2 6.4.6.3.1 (one zeta per bridge, Table 6.6)", PROJECT),
    Default("Table 6.6 length L of a continuous deck", "the longest span (conservative: Table 6.6 does not increase "
            "with L)", "EN 1991-2 6.4.6.3.1, Table 6.6; its wording of L for continuous decks could not be checked "
            "here", PROJECT),
    Default("additional damping", "none", "--damping; EN 1991-2 6.4.6.3.1 allows the ADM for L < 30 m", PROJECT),
    Default("classification factor alpha", "1.00", "EN 1991-2 6.3.2(3)", STANDARD),
    Default("determinant length L_Phi", "the span", "EN 1991-2 Table 6.2, case 5.1", STANDARD),
    Default("speed of phi''", "the maximum line speed V", "EN 1991-2 Annex C (maximum permitted vehicle speed)",
            STANDARD),
    Default("mass bounds", "on where the ballast is given (--ballast), else not checked",
            "EN 1991-2 6.4.6.3.2", STANDARD),
    Default("lower-bound ballast density", f"{BALLAST_DENSITY_MIN_KG_M3:g} kg/m3", "EN 1991-2 6.4.6.3.2, NOTE",
            STANDARD),
    Default("upper-bound ballast density", f"{BALLAST_DENSITY_MAX_KG_M3:g} kg/m3",
            "saturated dirty ballast; no number found in the standard's text", PROJECT),
    Default("upper-bound ballast depth allowance", f"+{100 * (BALLAST_DEPTH_FACTOR_UPPER - 1):g} %",
            "future track lifts; no number found in the standard's text", PROJECT),
    Default("vertical deflection limit", f"L/{DEFLECTION_SPAN_RATIO:g} under Phi x alpha x LM71",
            "EN 1990 A2.4.4.2.3(1)", STANDARD),
    Default("deck end rotation limit", f"{1e3 * END_ROTATION_LIMIT_RAD:g} mrad at an abutment, ballasted track",
            "an infrastructure manager's rule, not EN 1991-2 (6.5.4.5.2 limits displacements)", PROJECT),
    Default("deck-end displacement delta_H", f"theta h against {1e3 * DELTA_H_LIMITS_M[0]:g} mm and "
            f"{1e3 * DELTA_H_LIMITS_M[1]:g} mm where h is given (--deck-end-height), else not checked",
            "EN 1991-2 6.5.4.5.2", STANDARD),
    Default("lateral frequency", f">= {LATERAL_FREQUENCY_MIN_HZ:g} Hz where given", "EN 1990 A2.4.4.2.4(3)", STANDARD),
    Default("trains named near the governing one", f"within {100 * NEAR_GOVERNING_FRACTION:g} %",
            "a reporting rule, not a limit", PROJECT),
)


def defaults():
    """:data:`DEFAULTS` (a tuple of :class:`Default`)."""
    return DEFAULTS


def defaults_dict():
    """``{"defaults": [...], "project_choices": [...]}`` for a check's JSON."""
    return {"defaults": [d.to_dict() for d in DEFAULTS], "project_choices": [d.to_dict() for d in project_choices()]}


def project_choices():
    """The defaults that are the project's choice, not the standard's."""
    return tuple(d for d in DEFAULTS if d.kind == PROJECT)
