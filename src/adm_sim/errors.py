"""Exception root of the project and the exit codes of its command lines.

:class:`AdmSimError` is the root. It has three branches:

* :class:`InputError`: bad user input (CLI option, input file, ROS parameter). The message names
  what the user typed, the value, the unit and the allowed range. Exit code 2.
* :class:`ModelError`: a value that breaks an invariant of the model (not finite, not positive):
  the model's own guard behind the readers. Exit code 1.
* :class:`RunError`: a failure that is not bad input (an integration that became unstable, a
  viewer or a node that does not answer). Exit code 1.

Command lines map them to one line ``error: ...`` and these exit codes in one place
(:func:`adm_sim.cliutil.run_cli`); an interrupt (Ctrl-C, SIGINT or SIGTERM) prints
``error: interrupted`` and exits with 130, leaving no partial output (outputs are written beside
and renamed, :mod:`adm_sim.files`). The checks that raise :class:`InputError` live in
:mod:`adm_sim.fields`. This module imports nothing: every other module may import it.
"""

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
    """A failure that is not bad input (unstable integration, a viewer, node, scheduler or tool that
    does not answer): exit code 1. ``field`` as :class:`InputError` (a command line shows the flag)."""

    def __init__(self, *args, field=None):
        super().__init__(*args)
        self.field = field


class ModelError(AdmSimError, ValueError):
    """A value that breaks a physical invariant of the model (a length, stiffness or mass that is not
    finite and positive, a damping ratio outside [0, 1), a mode count below 1, per-span lists of
    different lengths). The readers refuse what a user typed before it reaches the model, with the
    field registry's ranges and the user's own names (exit 2); this is the model's own guard, met
    only by a caller that skipped them: exit code 1."""


class PlausibilityWarning(UserWarning):
    """A value the model computes but no real bridge or train has: a warning, not an error
    (the bounds and their reasons: :mod:`adm_sim.model.plausibility`)."""
