"""Exception root of the project.

Every error raised on bad user input is an :class:`InputError` whose message names the field,
the value, the unit and the allowed range, so CLIs, file loaders and ROS parameter callbacks can
show it as one line.
"""


class AdmSimError(Exception):
    """Root of all adm-sim errors."""


class InputError(AdmSimError, ValueError):
    """Bad user input (CLI argument, input file, ROS parameter)."""


def check_range(field, value, unit, lo=None, hi=None, lo_open=False, hi_open=False):
    """Return ``float(value)`` or raise :class:`InputError` naming field, value, unit and range.

    Parameters
    ----------
    field : str
        Name shown to the user (``"span_m"``, ``"vehicles.PC.k_p_N_m"``).
    value : object
        Value to check; must convert to a finite float.
    unit : str
        Unit shown in the message (``"m"``, ``"%"``, ``"-"``).
    lo, hi : float or None
        Bounds; ``None`` means unbounded.
    lo_open, hi_open : bool
        Whether the bound itself is excluded.
    """
    import math

    rng = _range_text(lo, hi, lo_open, hi_open, unit)
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{field}: {value!r} is not a number; allowed {rng}") from None
    if not math.isfinite(x):
        raise InputError(f"{field}: {value!r} {unit} is not finite; allowed {rng}")
    bad_lo = lo is not None and (x <= lo if lo_open else x < lo)
    bad_hi = hi is not None and (x >= hi if hi_open else x > hi)
    if bad_lo or bad_hi:
        raise InputError(f"{field}: {x:g} {unit} is out of range; allowed {rng}")
    return x


def _range_text(lo, hi, lo_open, hi_open, unit):
    if lo is None and hi is None:
        return f"any finite value in {unit}"
    if hi is None:
        return f"{'>' if lo_open else '>='} {lo:g} {unit}"
    if lo is None:
        return f"{'<' if hi_open else '<='} {hi:g} {unit}"
    left = "(" if lo_open else "["
    right = ")" if hi_open else "]"
    return f"{left}{lo:g}, {hi:g}{right} {unit}"


def read_toml(path, what):
    """Parse a TOML input file; unreadable or invalid files raise :class:`InputError`.

    ``what`` names the file's role in the message (``"bridge file"``, ``"train file"``).
    """
    import tomllib
    from pathlib import Path

    p = Path(path)
    try:
        return tomllib.loads(p.read_text())
    except OSError as exc:
        raise InputError(f"{what} {str(p)!r}: cannot read ({exc.strerror})") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{what} {str(p)!r}: not valid TOML ({exc})") from None
