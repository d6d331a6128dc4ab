"""Two study result files compared case by case: the loop ``study_grid_compare.py`` and
``refined_study_compare.py`` share.

Cases are matched on their key (bridge, train: :func:`adm_calib.study.record_key`). Per case:
the status of both lines, their Δζ_VBI (%, ``None`` where a line has none) and, when asked, the
other fields of the result line that differ (floats to a relative and an absolute tolerance).
"""

from __future__ import annotations

import math
from typing import NamedTuple

from adm_calib import study as st

#: Default tolerances of the other floats: relative, and absolute for values near zero.
RTOL = 1e-9
ATOL = 1e-12


class CaseDiff(NamedTuple):
    """One case of both files: its key, the two statuses, the two Δζ_VBI (%, ``None`` where a line
    has none) and the paths of the other fields that differ (empty unless asked for)."""

    key: tuple
    status: tuple
    dz_pct: tuple
    fields: list

    @property
    def status_changed(self) -> bool:
        return self.status[0] != self.status[1]

    @property
    def dz_presence_changed(self) -> bool:
        """One line has a Δζ_VBI, the other none."""
        return (self.dz_pct[0] is None) != (self.dz_pct[1] is None)

    @property
    def dz_change_pct(self):
        """New minus old Δζ_VBI (%), ``None`` unless both lines have one."""
        d0, d1 = self.dz_pct
        return None if d0 is None or d1 is None else d1 - d0


def matched(path_a, path_b):
    """The records of two result files keyed by case, and the keys both hold (sorted):
    ``(old, new, keys)``."""
    old = {st.record_key(r): r for r in st.read_results(path_a).records}
    new = {st.record_key(r): r for r in st.read_results(path_b).records}
    return old, new, sorted(set(old) & set(new))


def field_diff(a, b, path="", rtol=RTOL, atol=ATOL):
    """Paths where two JSON values differ (floats to ``rtol`` relative or ``atol`` absolute)."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            out += field_diff(a.get(k), b.get(k), f"{path}.{k}" if path else k, rtol, atol)
        return out
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in field_diff(x, y, f"{path}[{i}]", rtol, atol)]
    if isinstance(a, float) and isinstance(b, float):
        return [] if math.isclose(a, b, rel_tol=rtol, abs_tol=atol) else [path]
    return [] if a == b else [path]


def compare_cases(old, new, keys, other_fields_except=None, rtol=RTOL, atol=ATOL):
    """:class:`CaseDiff` of every case of ``keys`` (both ``old`` and ``new`` hold it), in that order.

    ``other_fields_except``: compare the other fields of the two lines too, all but these and
    Δζ_VBI (fields that describe the run, not the result); ``None``: do not."""
    out = []
    for k in keys:
        r0, r1 = old[k], new[k]
        fields = []
        if other_fields_except is not None:
            skip = set(other_fields_except) | {"delta_zeta_vbi_pct"}
            fields = field_diff({x: v for x, v in r0.items() if x not in skip},
                                {x: v for x, v in r1.items() if x not in skip}, rtol=rtol, atol=atol)
        out.append(CaseDiff(k, (r0["status"], r1["status"]),
                            (r0.get("delta_zeta_vbi_pct"), r1.get("delta_zeta_vbi_pct")), fields))
    return out
