"""Exception root of the project and the exit codes of its command lines.

:class:`AdmSimError` is the root. It has two branches:

* :class:`InputError`: bad user input (CLI option, input file, ROS parameter). The message names
  what the user typed, the value, the unit and the allowed range. Exit code 2.
* :class:`RunError`: a failure that is not bad input (an integration that became unstable, a
  viewer or a node that does not answer). Exit code 1.

Command lines print errors as one line ``error: ...`` and plausibility warnings as one line
``warning: ...`` each on stderr (:func:`run_cli`), ROS nodes ``error: <node>: ...`` and every
warning as ``warning: <node>: ...`` (:class:`one_line_warnings`); an interrupt
(Ctrl-C, SIGINT or SIGTERM) prints ``error: interrupted`` and exits with 130, leaving no partial
output (outputs are written beside and renamed, :mod:`adm_sim.files`).
"""

import sys

#: Exit codes of every command line of the project.
EXIT_OK, EXIT_RUN, EXIT_INPUT, EXIT_INTERRUPTED = 0, 1, 2, 130


class AdmSimError(Exception):
    """Root of all adm-sim errors."""


class InputError(AdmSimError, ValueError):
    """Bad user input (CLI argument, input file, ROS parameter): exit code 2.

    ``field``: the library function's argument the message starts with (``max_line_speed_kmh:
    ...``); a command line shows it as its flag (``--max-line-speed: ...``,
    :func:`adm_sim.cliutil.cli_message`). None for messages about files, parameters and flags.
    """

    def __init__(self, *args, field=None):
        super().__init__(*args)
        self.field = field


class RunError(AdmSimError, RuntimeError):
    """A failure that is not bad input (unstable integration, a viewer or node that does not answer):
    exit code 1."""


class PlausibilityWarning(UserWarning):
    """A value the model computes but no real bridge or train has: a warning, not an error
    (the bounds and their reasons: :mod:`adm_sim.plausibility`)."""


def one_line(exc):
    """The message of ``exc`` on one line (inner newlines and runs of blanks collapsed)."""
    return " ".join(str(exc).split())


def run_cli(call):
    """Call ``call()`` (a CLI's work, returning its exit code) and map errors to one line and an exit code.

    :class:`InputError` -> ``error: ...``, exit 2; :class:`RunError` (and any other
    :class:`AdmSimError`) -> ``error: ...``, exit 1; ``KeyboardInterrupt`` -> ``interrupted``, 130;
    ``BrokenPipeError`` (``... | head``) -> quiet exit 0. Anything else is a bug and keeps its traceback.
    Every output claimed during the call (:func:`adm_sim.files.claim_output`) is released at its end.
    A :class:`~adm_sim.plausibility.PlausibilityWarning` raised during the call is printed as one
    line ``warning: ...`` on stderr, each time it occurs (:func:`plausibility_warnings`).
    """
    with interrupt_signals(), plausibility_warnings():
        try:
            return _run(call)
        finally:
            from adm_sim.files import release_all

            release_all()


class one_line_warnings:
    """Within the block, every warning of ``categories`` is printed as one line on stderr:
    ``warning: <prefix><message>`` for a :class:`~adm_sim.plausibility.PlausibilityWarning`,
    ``warning: <prefix><Category>: <message>`` for any other (no ``file:line:`` and source line as
    Python's own display). ``repeat``: print every occurrence (``always``), else Python's filters
    decide (``default``: once per message and place). Other warnings keep their usual display;
    the warning filters and ``warnings.showwarning`` come back at its end. The ROS nodes use it
    with their name as the prefix (:func:`adm_sim.nodes.common.run_node`), as their ``error:`` lines.
    """

    def __init__(self, prefix="", categories=(PlausibilityWarning,), repeat=True):
        self.prefix, self.categories, self.repeat = prefix, tuple(categories), repeat

    def __enter__(self):
        import warnings

        self._catch = warnings.catch_warnings()
        self._catch.__enter__()
        if self.repeat:
            for category in self.categories:
                warnings.simplefilter("always", category)
        shown = warnings.showwarning

        def show(message, category, filename, lineno, file=None, line=None):
            if not issubclass(category, self.categories):
                shown(message, category, filename, lineno, file, line)
            elif issubclass(category, PlausibilityWarning):
                print(f"warning: {self.prefix}{one_line(message)}", file=sys.stderr, flush=True)
            else:
                print(f"warning: {self.prefix}{category.__name__}: {one_line(message)}", file=sys.stderr,
                      flush=True)

        warnings.showwarning = show
        return self

    def __exit__(self, *exc):
        self._catch.__exit__(*exc)
        return False


class plausibility_warnings(one_line_warnings):
    """Within the block, every :class:`~adm_sim.plausibility.PlausibilityWarning` is printed as one
    line ``warning: <message>`` on stderr (not deduplicated); other warnings keep their usual display.
    The warning filters and ``warnings.showwarning`` come back at its end: :class:`one_line_warnings`
    with its defaults, the form of the command lines."""


class interrupt_signals:
    """Within the block, SIGTERM and SIGINT both raise ``KeyboardInterrupt`` in the main thread
    (SIGINT too when a non-interactive shell started the process with SIGINT ignored); the old
    handlers come back at its end. Off the main thread it does nothing."""

    def __enter__(self):
        import signal
        import threading

        self._old = {}
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._old[sig] = signal.signal(sig, _raise_interrupt)
        return self

    def __exit__(self, *exc):
        import signal

        for sig, handler in self._old.items():
            signal.signal(sig, handler)
        return False


def _raise_interrupt(signum, frame):
    raise KeyboardInterrupt


def _run(call):
    try:
        return call()
    except BrokenPipeError:
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_OK
    except InputError as exc:
        from adm_sim.cliutil import cli_message

        print(f"error: {one_line(cli_message(exc))}", file=sys.stderr)
        return EXIT_INPUT
    except AdmSimError as exc:
        print(f"error: {one_line(exc)}", file=sys.stderr)
        return EXIT_RUN
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED


def check_range(field, value, unit, lo=None, hi=None, lo_open=False, hi_open=False, *, argument=False):
    """Return ``float(value)`` or raise :class:`InputError` naming field, value, unit and range.

    ``argument=True``: ``field`` is a function argument (the error's ``field``, shown as its flag
    on a command line).

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
    try:
        return _check_range(field, value, unit, lo, hi, lo_open, hi_open)
    except InputError as exc:
        if argument:
            exc.field = field
        raise


def _check_range(field, value, unit, lo, hi, lo_open, hi_open):
    import math

    rng = _range_text(lo, hi, lo_open, hi_open, unit)
    if isinstance(value, bool):  # a TOML/YAML true is not the number 1
        raise InputError(f"{field}: {str(value).lower()} is a boolean, not a number; allowed {rng}")
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


def check_number(field, value, unit, lo=None, hi=None, lo_open=False, hi_open=False):
    """:func:`check_range` for values read from a typed file (TOML): a string is refused too."""
    if isinstance(value, str):
        rng = _range_text(lo, hi, lo_open, hi_open, unit)
        raise InputError(f"{field}: {value!r} is a string, not a number (write it without quotes); allowed {rng}")
    return check_range(field, value, unit, lo, hi, lo_open, hi_open)


def check_int(field, value, lo, hi, unit=""):
    """An integer in ``[lo, hi]`` from a number or its text; booleans and fractions are refused."""
    u = f" {unit}" if unit else ""
    x = None
    if isinstance(value, int) and not isinstance(value, bool):
        x = value
    elif isinstance(value, str):
        try:
            x = int(value.strip())
        except ValueError:
            x = None
    if x is None:
        shown = str(value).lower() if isinstance(value, bool) else repr(value)
        raise InputError(f"{field}: {shown} is not an integer; allowed integer in [{lo}, {hi}]{u}")
    if not lo <= x <= hi:
        raise InputError(f"{field}: {x}{u} is out of range; allowed integer in [{lo}, {hi}]{u}")
    return x


def check_choice(field, value, allowed):
    """``value`` if it is one of the strings ``allowed``, else :class:`InputError` listing them."""
    if not isinstance(value, str) or value not in allowed:
        raise InputError(f"{field}: {value!r} is not allowed; allowed {' or '.join(repr(a) for a in allowed)}")
    return value


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

    from adm_sim.files import refuse_special

    p = Path(path)
    refuse_special(p, f"{what} {str(p)!r}")
    try:
        return tomllib.loads(p.read_text())
    except OSError as exc:
        raise InputError(f"{what} {str(p)!r}: cannot read ({exc.strerror})") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{what} {str(p)!r}: not valid TOML ({exc})") from None
