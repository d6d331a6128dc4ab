"""Limits and defaults that several commands, nodes and the study share, each written once.

* The deck acceleration limits of EN 1990 A2.4.4.2.1(4)P, one track vocabulary:
  ``ballasted`` (γ_bt = 3.5 m/s²) and ``direct_fastening`` (γ_df = 5 m/s², "direct fastened
  tracks with track and structural elements designed for high speed traffic"). ``direct`` is
  accepted as an alias of ``direct_fastening`` only where it was documented
  (``adm-sim check --track direct``, docs/check.md).
* The speed range of the EN 1991-2 dynamic check, 6.4.6.2(1): 40 m/s up to 1.2 x the maximum
  line speed.
* The default speed range of the paper, Section 3.3: 160 to 350 km/h every 1 km/h.
* The range of the additional damping Δζ: from ``-ζ`` (no negative total damping) to 20 %.
* The work limit of one run (lanes x steps x modes, :data:`MAX_WORK`, the project's choice) and
  the memory a run may ask for (:func:`check_memory`: this machine's available memory and the
  process's address-space limit), checked before anything is allocated or started.

Numpy only; no ROS, no CLI (messages name the field the caller gives). The Δζ checks are the field
registry's (:func:`adm_sim.fields.check_delta_zeta`, field ``delta_zeta``), whose bounds are the
numbers written here.
"""

from __future__ import annotations

import os

import numpy as np

from adm_sim.errors import InputError

# ---------------------------------------------------------------------- EN 1990 A2.4.4.2.1
#: Peak deck acceleration limits (m/s²) by track type, EN 1990 A2.4.4.2.1(4)P.
ACC_LIMITS_M_S2 = {"ballasted": 3.5, "direct_fastening": 5.0}
#: Track types, in the order of the table.
TRACK_TYPES = tuple(ACC_LIMITS_M_S2)
#: Other spellings accepted by the check's ``--track`` (documented interface) -> the track type.
TRACK_ALIASES = {"direct": "direct_fastening"}


def check_track_type(field, value, aliases=False):
    """The track type ``value`` (one of :data:`TRACK_TYPES`; with ``aliases`` also a key of
    :data:`TRACK_ALIASES`, returned as its track type); :class:`InputError` naming ``field``
    otherwise (``track_type: 'gravel' is not allowed; allowed ballasted or direct_fastening``)."""
    if aliases and value in TRACK_ALIASES:
        return TRACK_ALIASES[value]
    if value not in ACC_LIMITS_M_S2:
        raise InputError(f"{field}: {value!r} is not allowed; allowed {' or '.join(TRACK_TYPES)}")
    return value


def acc_limit_m_s2(track_type):
    """Peak deck acceleration limit (m/s²) of a track type (or alias), EN 1990 A2.4.4.2.1(4)P."""
    return ACC_LIMITS_M_S2[TRACK_ALIASES.get(track_type, track_type)]


# ---------------------------------------------------------------------- speeds, EN 1991-2 6.4.6.2(1)
#: Lowest speed of the dynamic check (m/s), EN 1991-2 6.4.6.2(1); the maximum line speed must exceed it.
CHECK_MIN_SPEED_M_S = 40.0
#: Maximum design speed = this factor x maximum line speed, EN 1991-2 6.4.6.2(1).
DESIGN_SPEED_FACTOR = 1.2


# ---------------------------------------------------------------------- speeds, Section 3.3
#: Default speed range (km/h), the paper's Section 3.3: ``start:stop:step``, stop included.
DEFAULT_SPEEDS = "160:350:1"


def default_speeds_kmh():
    """The default speeds (km/h), ``(191,)``: :data:`DEFAULT_SPEEDS` parsed (a new array each call)."""
    start, stop, step = (float(x) for x in DEFAULT_SPEEDS.split(":"))
    return np.arange(start, stop + 0.5 * step, step)


# ---------------------------------------------------------------------- additional damping
#: Largest additional damping Δζ (%); the smallest is ``-ζ`` (total damping ``ζ + Δζ >= 0``).
MAX_DELTA_ZETA_PCT = 20.0
#: The same as a fraction (0.2; the calibration's ladder ends here).
MAX_DELTA_ZETA = MAX_DELTA_ZETA_PCT / 100.0


# ---------------------------------------------------------------------- work and memory of one run
#: Largest work of one run, lanes x steps x modes (the project's choice: 1e10 is ~30x the largest
#: batch of the study and about a quarter of an hour of compiled DIM on 2 cores; a sweep that would
#: run for days is refused before it starts). Raised by ``--max-work`` or :data:`WORK_ENV`.
MAX_WORK = 1e10
#: Environment variable that raises the work limit for a process and everything it starts
#: (study workers, nodes): ``ADM_SIM_MAX_WORK=1e11``.
WORK_ENV = "ADM_SIM_MAX_WORK"
#: Share of the available memory one run may ask for (the project's choice).
MEMORY_SHARE = 0.8


def max_work(environ=None):
    """The work limit in force: :data:`WORK_ENV` when set (a number >= 1), else :data:`MAX_WORK`."""
    environ = os.environ if environ is None else environ
    text = environ.get(WORK_ENV)
    if text is None or not text.strip():
        return MAX_WORK
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (value >= 1.0 and np.isfinite(value)):
        raise InputError(f"{WORK_ENV}: {text!r} is not allowed; allowed a finite number >= 1 (lanes x steps x modes "
                         f"of one run; default {MAX_WORK:.3g})", field=WORK_ENV)
    return value


def set_max_work(flag, value):
    """``--max-work``: check ``value`` (a number >= 1, lanes x steps x modes) and put it in
    :data:`WORK_ENV` for this process and everything it starts; ``None`` leaves it."""
    if value is None:
        return
    try:
        x = float(value)
    except (TypeError, ValueError):
        x = float("nan")
    if not (x >= 1.0 and np.isfinite(x)):
        raise InputError(f"{flag}: {value!r} is not allowed; allowed a finite number >= 1 (lanes x steps x modes of "
                         f"one run; default {MAX_WORK:.3g})", field=flag)
    os.environ[WORK_ENV] = repr(x)


def check_work(n_lanes, n_steps, n_modes, why):
    """Refuse a run of ``n_lanes x n_steps x n_modes`` beyond :func:`max_work` before it starts:
    one-line :class:`InputError` naming the counts, the limit and ``why`` (the inputs that make it
    large: a string, or a callable giving it, called only for a refusal)."""
    work = float(n_lanes) * float(n_steps) * float(n_modes)
    if work <= MAX_WORK and WORK_ENV not in os.environ:  # the common case: no environment read, no text
        return work
    limit = max_work()
    if work > limit:
        why = why() if callable(why) else why
        raise InputError(f"work: {n_lanes} lanes x {_count(n_steps)} steps x {n_modes} modes = {_g(work)} is beyond "
                         f"the work limit {_g(limit)} (the project's choice; raise it with --max-work or "
                         f"{WORK_ENV}); {why}")
    return work


def available_memory_bytes():
    """Memory a new allocation can get (bytes): ``MemAvailable`` of ``/proc/meminfo`` and, under an
    address-space limit (``ulimit -v``), what is left of it; ``None`` when neither is known."""
    out = []
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    out.append(int(line.split()[1]) * 1024)
                    break
    except (OSError, ValueError, IndexError):
        pass
    try:
        import resource  # noqa: PLC0415  POSIX only

        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
        if soft != resource.RLIM_INFINITY:
            with open("/proc/self/statm") as fh:
                used = int(fh.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
            out.append(max(soft - used, 0))
    except (ImportError, OSError, ValueError, IndexError):
        pass
    return min(out) if out else None


def check_memory(n_bytes, what, why):
    """Refuse an allocation of ``n_bytes`` (``what``: the tables it is for) beyond
    :data:`MEMORY_SHARE` of :func:`available_memory_bytes`, before it is made: one-line
    :class:`InputError` naming the estimate, the memory left and ``why``."""
    avail = available_memory_bytes()
    if avail is not None and n_bytes > MEMORY_SHARE * avail:
        raise InputError(f"memory: {what} would take {_bytes(n_bytes)}; this machine has {_bytes(avail)} available "
                         f"(a run may take {MEMORY_SHARE:.0%} of it); {why}")
    return n_bytes


def _bytes(n):
    for unit, size in (("TiB", 2**40), ("GiB", 2**30), ("MiB", 2**20)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n / 1024:.3g} KiB"


def _g(x):
    """Exact below a billion (a whole number), else 3 significant digits."""
    return f"{int(x)}" if x < 1e9 and x == int(x) else f"{x:.3g}"


def _count(n):
    if n < 1_000_000:
        return f"{n}"
    return f"{n / 1e6:.3g} M" if n < 1e9 else f"{n:.3g}"


__all__ = ["ACC_LIMITS_M_S2", "TRACK_TYPES", "TRACK_ALIASES", "check_track_type", "acc_limit_m_s2",
           "CHECK_MIN_SPEED_M_S", "DESIGN_SPEED_FACTOR", "DEFAULT_SPEEDS", "default_speeds_kmh", "MAX_DELTA_ZETA_PCT", "MAX_DELTA_ZETA",
           "MAX_WORK", "WORK_ENV", "MEMORY_SHARE", "max_work", "set_max_work", "check_work", "available_memory_bytes",
           "check_memory"]
