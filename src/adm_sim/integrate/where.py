"""Where on the deck a response is asked for: ``deck`` (the whole deck), ``midspan`` or a position x.

Parsed here, without the envelope's compiled kernels, so a command refuses a bad ``--where``
before it loads numba.
"""

from __future__ import annotations

from adm_sim.errors import InputError
from adm_sim.fields import check_range

#: Keywords of ``where`` (besides a position in metres).
WHERE_KEYWORDS = ("deck", "midspan")


def parse_where(where, span_m, field="where"):
    """``"deck"``, ``"midspan"`` or a position x (m, 0 < x < L) from ``"deck"``, ``"midspan"``,
    ``"x=<m>"`` or a number; anything else raises :class:`InputError` (one line, naming ``field``)."""
    if isinstance(where, str):
        w = where.strip().lower()
        if w in WHERE_KEYWORDS:
            return w
        if not w.startswith("x="):
            raise InputError(f"{field}: {where!r} is not allowed; allowed deck, midspan or x=<position in m> "
                             f"with 0 < x < {span_m:g} m", field=field)
        where = where.strip()[2:]
    return check_range(field, where, "m", 0.0, span_m, lo_open=True, hi_open=True, argument=True)


def where_text(where):
    """``"deck"``, ``"midspan"`` or ``"x=3.75 m"``."""
    return where if isinstance(where, str) else f"x={where:g} m"
