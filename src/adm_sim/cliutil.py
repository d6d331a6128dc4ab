"""The command-line layer shared by ``adm-sim``, ``adm-calib`` and the launch scripts (core, no rclpy).

One runner (:func:`run_cli`: the one mapping of errors, interrupts and system failures to one line
``error: ...`` and an exit code, the warnings as one line ``warning: ...``), one parser class (usage
errors are one line, exit code 2) and one progress bar (tqdm on stderr). The output rule lives in
:mod:`adm_sim.files`, the exit codes in :mod:`adm_sim.errors`, the fields the options check in
:mod:`adm_sim.fields`.
"""

from __future__ import annotations

import argparse
import atexit
import errno
import gc
import importlib
import os
import resource
import signal
import sys
import threading
import warnings

from adm_sim import __version__
from adm_sim.errors import EXIT_INPUT, EXIT_INTERRUPTED, EXIT_OK, EXIT_RUN, AdmSimError, InputError, PlausibilityWarning
from adm_sim.fields import argument_flag, view
from adm_sim.files import release_all
from adm_sim.interrupts import armed, raise_interrupt
from adm_sim.limits import DEFAULT_SPEEDS, MAX_WORK, WORK_ENV, max_work, set_max_work


# ---------------------------------------------------------------------- the way out
_FROZEN_AT_EXIT: list[bool] = []  # not empty once freeze_at_exit has registered in this process


def freeze_at_exit():
    """Skip the interpreter's last garbage collections at the exit of a command-line process.

    At exit every object still alive is moved to the permanent generation (:func:`gc.freeze`, an
    ``atexit`` handler), which the collections of the interpreter's shutdown do not traverse: with numba's
    compiler loaded they cost about 0.3 s of CPU and wall time at the end of every ``adm-sim check``
    (docs/check.md, "Speed"). Every ``atexit``
    handler still runs, the standard streams are still flushed and what the modules hold is still freed;
    only objects in reference cycles are left to the operating system (Python does not promise their
    finalizers at exit, and the command's files are closed and its claims released before it returns).
    For the process's own command line only (a ``main()`` called without ``argv``), never in a process
    that goes on (a test calling ``main([...])``); registered once."""
    if not _FROZEN_AT_EXIT:
        _FROZEN_AT_EXIT.append(True)
        atexit.register(gc.freeze)


# ---------------------------------------------------------------------- the runner
def one_line(exc):
    """The message of ``exc`` on one line (inner newlines and runs of blanks collapsed)."""
    return " ".join(str(exc).split())


def run_cli(call):
    """Call ``call()`` (a CLI's work, returning its exit code) and map errors to one line and an exit code.

    The one runner of every entry point (``adm-sim``, ``adm-calib``, the launch scripts):
    :class:`InputError` -> ``error: ...``, exit 2; :class:`RunError` (and any other
    :class:`AdmSimError`) -> ``error: ...``, exit 1; an :class:`OSError` (a full disk, a file
    larger than ``ulimit -f``, a read-only folder) -> ``error: '<path>': <reason>``, exit 1;
    ``KeyboardInterrupt`` (Ctrl-C, SIGINT, SIGTERM) -> ``error: interrupted``, 130;
    ``BrokenPipeError`` (``... | head``) -> quiet exit 0; a path too long for the system
    (``ENAMETOOLONG``) is bad input, exit 2. :func:`check_environment` runs first. Anything else is
    a bug and keeps its traceback.
    Every output claimed during the call (:func:`adm_sim.files.claim_output`) is released at its end.
    A :class:`~adm_sim.model.plausibility.PlausibilityWarning` raised during the call is printed as one
    line ``warning: ...`` on stderr, each time it occurs (:func:`plausibility_warnings`).

    A signal has no window: once ``call()`` has returned (or raised), SIGINT and SIGTERM no longer
    raise but mark the run interrupted (its last line and the release of its claims are not cut,
    no traceback); a run that had succeeded then ends ``error: interrupted``, 130. Past the return
    of this function (the way out of the process) they print ``error: interrupted`` and end the
    process with 130 at once, instead of the default death by the signal (:class:`interrupt_signals`).
    """
    work_env = os.environ.get(WORK_ENV)  # --max-work holds for this call and what it starts, not after it
    with interrupt_signals() as sigs, plausibility_warnings():
        try:
            code = _run(lambda: _deferring(call, sigs))
        except KeyboardInterrupt:  # between the end of call() and the deferral
            print("error: interrupted", file=sys.stderr)
            code = EXIT_INTERRUPTED
        finally:
            sigs.defer()
            release_all()
            if work_env is None:
                os.environ.pop(WORK_ENV, None)
            else:
                os.environ[WORK_ENV] = work_env
    # read once the block has ended: a signal up to its end marks it (the exit handlers then stand);
    # read within the block, one landing between that reading and the end was lost (a run ended 0)
    if sigs.late and code == EXIT_OK:
        print("error: interrupted", file=sys.stderr)
        code = EXIT_INTERRUPTED
    return code


def _deferring(call, sigs):
    """``call()``; whatever way it ends, later signals are deferred (:meth:`interrupt_signals.defer`)."""
    try:
        return call()
    finally:
        sigs.defer()


class one_line_warnings:
    """Within the block, every warning of ``categories`` is printed as one line on stderr:
    ``warning: <prefix><message>`` for a :class:`~adm_sim.model.plausibility.PlausibilityWarning`,
    ``warning: <prefix><Category>: <message>`` for any other (no ``file:line:`` and source line as
    Python's own display). ``repeat``: print every occurrence (``always``), else Python's filters
    decide (``default``: once per message and place). Other warnings keep their usual display;
    the warning filters and ``warnings.showwarning`` come back at its end. The ROS nodes use it
    with their name as the prefix (:func:`adm_sim.nodes.common.run_node`), as their ``error:`` lines.
    """

    def __init__(self, prefix="", categories=(PlausibilityWarning,), repeat=True):
        self.prefix, self.categories, self.repeat = prefix, tuple(categories), repeat

    def __enter__(self):
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
    """Within the block, every :class:`~adm_sim.model.plausibility.PlausibilityWarning` is printed as one
    line ``warning: <message>`` on stderr (not deduplicated); other warnings keep their usual display.
    The warning filters and ``warnings.showwarning`` come back at its end: :class:`one_line_warnings`
    with its defaults, the form of the command lines."""


class interrupt_signals:
    """Within the block, SIGTERM and SIGINT both raise ``KeyboardInterrupt`` in the main thread
    (SIGINT too when a non-interactive shell started the process with SIGINT ignored; one that lands
    where Python cannot pass it on, a weakref callback or a ``__del__``, is raised again at the next
    line that can: :mod:`adm_sim.interrupts`), until
    :meth:`defer`: from then on they only set :attr:`late`. At its end the old handlers come back,
    except the interpreter's defaults (SIGTERM's death by the signal, SIGINT's
    ``KeyboardInterrupt`` with a traceback from wherever the process is on its way out): in their
    place a signal prints ``error: interrupted`` and ends the process with 130 at once. Off the
    main thread it does nothing."""

    def __enter__(self):
        self._old = {}
        self.late = False
        self._armed = armed()
        self._armed.__enter__()
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._old[sig] = signal.signal(sig, raise_interrupt)
        return self

    def defer(self):
        """From now on a signal marks the block interrupted (:attr:`late`) instead of raising."""
        def mark(signum, frame):
            self.late = True

        for sig in self._old:
            signal.signal(sig, mark)

    def __exit__(self, *exc):
        for sig, handler in self._old.items():
            default = handler is signal.SIG_DFL or handler is signal.default_int_handler
            signal.signal(sig, _exit_interrupted if default else handler)
        self._armed.__exit__(None, None, None)
        return False


def _exit_interrupted(signum, frame):
    """A signal on the way out of a command: one line and 130 now (stdout flushed if it can be)."""
    try:
        sys.stdout.flush()
    except Exception:  # a flush cut by this very signal: what it held is lost either way
        pass
    os.write(2, b"error: interrupted\n")
    os._exit(EXIT_INTERRUPTED)


def check_environment(environ=None):
    """Environment variables a run depends on, refused up front like an option: ``ADM_SIM_MAX_WORK``
    (the work limit, :func:`adm_sim.limits.max_work`) a number >= 1 when set; ``NUMBA_NUM_THREADS``
    (threads of the compiled kernels; numba itself fails deep inside the first parallel kernel)
    must be an integer >= 1 when set."""
    environ = os.environ if environ is None else environ
    max_work(environ)  # ADM_SIM_MAX_WORK, when set: a number >= 1
    text = environ.get("NUMBA_NUM_THREADS")
    if text is None:
        return
    try:
        n = int(text.strip())
    except ValueError:
        n = 0
    if n < 1:
        raise InputError(f"NUMBA_NUM_THREADS: {text!r} is not allowed; allowed an integer >= 1 (threads of the "
                         f"compiled kernels), or unset it")


def caused_by_interrupt(exc):
    """Whether ``exc`` was raised *from* a ``KeyboardInterrupt`` (its ``__cause__`` chain holds one).

    A library that turns whatever its initialisation raised into its own error does so: a Ctrl-C
    landing in the first import of ``scipy.optimize`` (a pybind11 module) comes out as
    ``ImportError: initialization failed`` whose direct cause is the ``KeyboardInterrupt``. That is
    the interrupt, not a bug. Only the explicit cause counts: an error raised while an interrupt was
    being handled (``__context__`` alone) stays a bug."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__
    return False


def _run(call):
    stdout = sys.stdout
    sys.stdout = _NamedStdout(stdout)
    try:
        check_environment()
        code = call()
        sys.stdout.flush()  # what the command printed reaches its file here, where a full device is one line
        return code
    except BrokenPipeError:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_OK
    except InputError as exc:
        print(f"error: {one_line(cli_message(exc))}", file=sys.stderr)
        return EXIT_INPUT
    except AdmSimError as exc:
        print(f"error: {one_line(cli_message(exc))}", file=sys.stderr)
        return EXIT_RUN
    except OSError as exc:  # inputs and outputs are checked first: what is left is the system
        note = address_space_note() if exc.filename is None else ""  # e.g. a library that cannot be mapped
        print(f"error: {one_line(os_message(exc))}{note}", file=sys.stderr)
        return EXIT_INPUT if exc.errno == errno.ENAMETOOLONG else EXIT_RUN  # a path the user typed
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except MemoryError as exc:  # numpy's _ArrayMemoryError included: one line, never a traceback
        what = one_line(exc) or "MemoryError"
        print(f"error: out of memory: {what}{address_space_note()}", file=sys.stderr)
        return EXIT_RUN
    except Exception as exc:
        if not caused_by_interrupt(exc):
            raise  # a bug keeps its traceback
        print("error: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    finally:
        if isinstance(sys.stdout, _NamedStdout):
            sys.stdout = stdout


class _NamedStdout:
    """Standard output whose write errors name it: an :class:`OSError` of ``write``/``flush``
    without a file name (a full device, ``ulimit -f`` under a redirected stdout) gets
    ``standard output (<its file>)``, so the one ``error:`` line names where it could not write.
    Everything else is the wrapped stream's."""

    def __init__(self, stream):
        self._stream = stream

    def _named(self, exc):
        if exc.filename is None:
            try:
                exc.filename = f"standard output ({os.readlink('/proc/self/fd/1')})"
            except OSError:
                exc.filename = "standard output"
        return exc

    def write(self, text):
        try:
            return self._stream.write(text)
        except BrokenPipeError:
            raise
        except OSError as exc:
            raise self._named(exc) from None

    def flush(self):
        try:
            return self._stream.flush()
        except BrokenPipeError:
            raise
        except OSError as exc:
            raise self._named(exc) from None

    def __getattr__(self, name):
        return getattr(self._stream, name)


def address_space_note():
    """``; the process runs under an address-space limit of N MB (ulimit -v) ...`` when one is set,
    else empty: the likely cause of a failed allocation or library load."""
    try:
        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    except (OSError, ValueError):
        return ""
    if soft == resource.RLIM_INFINITY:
        return ""
    return (f"; the process runs under an address-space limit of {soft / 2**20:.0f} MB (ulimit -v {soft // 1024}), "
            f"too small for this run: raise it or lift it (ulimit -v unlimited)")


def os_message(exc):
    """One line for an :class:`OSError` that reached a command line (a full disk, a file larger than
    ``ulimit -f``, a folder made read-only during the run): the path and the system's reason."""
    reason = exc.strerror or str(exc)
    if exc.filename is None:
        return reason
    return f"{str(exc.filename)!r}: {reason}"


# ---------------------------------------------------------------------- the parser


class Parser(argparse.ArgumentParser):
    """argparse whose usage errors raise :class:`InputError` (one line ``error: ...``, exit 2 under
    :func:`run_cli`, so ``parse_args`` belongs inside the call given to it).

    ``name_prog=True`` puts the program (``adm-sim sweep``) in front of the message; subparsers
    created by :meth:`add_subparsers` inherit it.
    """

    def __init__(self, *args, name_prog=False, **kwargs):
        super().__init__(*args, **kwargs)
        self.name_prog = name_prog

    def parse_args(self, args=None, namespace=None):
        """argparse's, then ``--max-work`` (where the command has it) put in force for this process
        and what it starts (:func:`adm_sim.limits.set_max_work`)."""
        ns = super().parse_args(args, namespace)
        if getattr(ns, "max_work", None) is not None:
            set_max_work("--max-work", ns.max_work)
        return ns

    def add_version(self):
        """``--version``: the program and the one version number of both packages, exit 0."""
        self.add_argument("--version", action="version", version=f"{self.prog} {__version__}",
                          help="print the version and exit")

    def add_subparsers(self, **kwargs):
        kwargs.setdefault("parser_class", type(self))
        action = super().add_subparsers(**kwargs)
        name_prog, add_parser = self.name_prog, action.add_parser

        def add(name, **kw):
            kw.setdefault("name_prog", name_prog)
            return add_parser(name, **kw)

        action.add_parser = add
        return action

    def error(self, message):
        raise InputError(f"{self.prog}: {message}" if self.name_prog else message)

    def parse_args_or_exit(self, args=None, namespace=None):
        """:meth:`parse_args` for a caller outside :func:`run_cli` (the launch scripts'
        :func:`launch`): a usage error prints its one line and exits with 2."""
        try:
            return self.parse_args(args, namespace)
        except InputError as exc:
            self.exit(EXIT_INPUT, f"error: {one_line(exc)}\n")


def add_commands(parser, commands, *, dest, command=None):
    """The subcommands of ``parser`` from ``commands``, ``(name, module, help)`` each in the order of ``--help``:
    each module holds ``add_arguments(parser)`` and ``run(args)``. Only the module of ``command`` is imported
    and gets its options (None: every module, for the documentation), so ``--help``, ``--version`` and a
    refusal of one subcommand do not import the others; ``args.func`` is the chosen module's ``run``."""
    sub = parser.add_subparsers(dest=dest, required=True)
    for name, module, text in commands:
        sp = sub.add_parser(name, help=text)
        if command is None or command == name:
            mod = importlib.import_module(module)
            mod.add_arguments(sp)
            sp.set_defaults(func=mod.run)
    return sub


def command_named(argv):
    """The subcommand ``argv`` names: its first item that is no option (the programs' own options, ``--help``
    and ``--version``, take no value), or ``""`` when there is none."""
    return next((a for a in argv if not a.startswith("-")), "")


def run_command(build_parser, argv=None):
    """Parse ``argv`` (default ``sys.argv[1:]``) with ``build_parser(command)``, the parser of the subcommand
    it names, and run that subcommand: its exit code. The work of :func:`run_cli`."""
    argv = sys.argv[1:] if argv is None else list(argv)
    args = build_parser(command_named(argv)).parse_args(argv)
    return args.func(args)


def cli_message(exc):
    """The message of an :class:`InputError` or :class:`RunError` ``exc`` as a command line shows it: a leading library
    argument (``exc.field``) becomes its flag in the field registry (:func:`adm_sim.fields.argument_flag`)."""
    msg, field = str(exc), getattr(exc, "field", None)
    flag = argument_flag(field)
    if flag is not None and msg.startswith(field):
        return flag + msg[len(field):]
    return msg


class _NoBar:
    """Stands in for a tqdm bar when tqdm is not installed."""

    n = total = 0

    def update(self, n=1):
        self.n += n

    def refresh(self):
        pass

    def set_postfix_str(self, text, refresh=True):
        pass

    def write(self, text):
        print(text, flush=True)

    def close(self):
        pass


def progress_bar(desc, total=None, enabled=None, unit="step", leave=False, **kwargs):
    """The progress bar of every command: tqdm on stderr, redrawn at most every 0.2 s.

    ``enabled``: True / False, or None for "only when stderr is a terminal". Without tqdm
    installed, a bar that draws nothing. A bar that would not draw (disabled, or stderr not a
    terminal) is that bar too, without importing tqdm (~30 ms of a command's start).
    """
    if enabled is False or (enabled is None and not sys.stderr.isatty()):
        return _NoBar()
    try:
        from tqdm import tqdm  # noqa: PLC0415  tqdm loads with the first bar, not with every command
    except ImportError:  # pragma: no cover - tqdm is a declared dependency
        return _NoBar()
    kwargs.setdefault("mininterval", 0.2)
    return tqdm(total=total, desc=desc, unit=unit, leave=leave, file=sys.stderr, dynamic_ncols=True,
                disable=None if enabled is None else not enabled, **kwargs)


def progress_callback(desc, enabled=None, **kwargs):
    """A ``progress(done, total, note=None)`` callback drawing a :func:`progress_bar`, and its ``close``.

    This is how the library reports progress (:func:`adm_sim.integrate.sweep.run_sweep`, the check, the
    calibration, Table 4, the study): it calls ``progress`` and never draws; the command line hands it
    this callback. ``total`` None: not known (a count without a bar); ``note``: a short status shown
    beside the count (the calibration's run phase).
    """
    bar = progress_bar(desc, total=0, enabled=enabled, **kwargs)

    def cb(done, total=None, note=None):
        if bar.total != total:
            bar.total = total
        bar.n = done
        if note is not None:
            bar.set_postfix_str(note, refresh=False)
        bar.refresh()

    return cb, bar.close


# ---------------------------------------------------------------------- options from the field registry
def _help(text):
    return text.replace("%", "%%")  # argparse formats help with %


def option_view(flag):
    """The registry's :class:`~adm_sim.fields.View` of ``flag`` (its unit, range, conversion to the core)."""
    return view("cli", flag)


def option_help(flag, text):
    """The help of ``flag``: ``text`` with the unit and the allowed values of its field in the
    registry (:meth:`adm_sim.fields.View.help`), so ``--help`` states the range the check applies."""
    return _help(option_view(flag).help(text))


def check_option(flag, value, **kw):
    """``value`` of ``flag`` checked by its registry field (:meth:`adm_sim.fields.View.check`):
    one line naming the flag, the value, the unit and the allowed range."""
    return option_view(flag).check(value, **kw)


def add_speeds(parser, text="speeds in km/h, start:stop:step (stop included) or a comma list", default=None,
               show_default=False):
    """``--speeds`` (default: the paper's :data:`adm_sim.limits.DEFAULT_SPEEDS`)."""
    default = DEFAULT_SPEEDS if default is None else default
    text = f"{text} (default {default})" if show_default else text
    parser.add_argument("--speeds", default=default, help=option_help("--speeds", text))


def add_steps_per_period(parser, text, default=None):
    """``--steps-per-period`` (checked by :func:`check_option` when the command uses it)."""
    parser.add_argument("--steps-per-period", default=default, help=option_help("--steps-per-period", text))


def add_delta_zeta_pct(parser, text="additional damping", default="0"):
    """``--delta-zeta-pct``: Δζ in % (the core's ``delta_zeta`` is a fraction, :data:`adm_sim.fields.SCALES`)."""
    parser.add_argument("--delta-zeta-pct", default=default, help=option_help("--delta-zeta-pct", text))


def add_choice(parser, flag, text=None, default=None, **kw):
    """``flag`` taking one of its registry field's choices (argparse refuses the others)."""
    parser.add_argument(flag, choices=option_view(flag).field.choices, default=default,
                        help=None if text is None else _help(text), **kw)


def add_dim_grid(parser, text=None):
    add_choice(parser, "--dim-grid", text, default="paper")


def add_progress(parser, negatable=True, text="progress bar (default: when stderr is a terminal)"):
    """``--progress``: with ``negatable`` also ``--no-progress`` (default None: when stderr is a
    terminal); else a plain switch (default False)."""
    if negatable:
        parser.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None, help=text)
    else:
        parser.add_argument("--progress", action="store_true", help=text)


def add_overwrite(parser, text, force_alias=False):
    """``--overwrite`` (with ``force_alias`` also spelled ``--force``, stored as ``force``)."""
    if force_alias:
        parser.add_argument("--overwrite", "--force", dest="force", action="store_true", help=text)
    else:
        parser.add_argument("--overwrite", action="store_true", help=text)


def add_max_work(parser):
    """``--max-work``: the work limit of one run (lanes x steps x modes, :data:`adm_sim.limits.MAX_WORK`)."""
    parser.add_argument("--max-work", default=None, metavar="N",
                        help=f"largest work of one run, lanes x steps x modes (default {MAX_WORK:.3g}, the project's "
                             f"choice; also {WORK_ENV}): larger runs are refused before they start")


def add_domain_id(parser, text="ROS_DOMAIN_ID (default: a free one, reserved)"):
    parser.add_argument("--domain-id", default=None, help=option_help("--domain-id", text))
