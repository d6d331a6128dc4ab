"""What several subcommands of ``adm-calib`` share: the output folder rule, list and speed options, train names
as typed, and the peak options of the calibrations."""

from __future__ import annotations

from adm_sim.cliutil import check_option
from adm_sim.errors import InputError
from adm_sim.files import check_output_folder, claim_output
from adm_sim.inputs.speeds import parse_speeds

from adm_calib.reference import canonical_train_name


def out_dir(text, option, names, overwrite, *, inputs=None):
    """Check an output folder and its files before any computation (the folder rule of
    :mod:`adm_sim.files`); returns ``(folder, paths)``. The files of a folder that exists are
    claimed here; a folder that does not exist yet is created by :func:`adm_sim.files.make_output_folder`
    once every input is checked."""
    out = check_output_folder(text, option, names, inputs)
    if out.is_dir():
        return out, [claim_output(str(out / n), option, overwrite, inputs=inputs) for n in names]
    return out, [out / n for n in names]


def once(values, field, text):
    """``values`` (canonical names of the items of ``text``) if none repeats, else one line naming ``field``."""
    if len(set(values)) != len(values):
        raise InputError(f"{field}: {text!r} names an item twice; give each once")
    return values


def comma_list(text, field):
    """The items of a comma list (blanks around them dropped); an empty list is one line naming ``field``."""
    items = [s.strip() for s in text.split(",") if s.strip()]
    if not items:
        raise InputError(f"{field}: {text!r} is empty; give a comma-separated list")
    return items


def steps_per_period_option(text):
    """``--steps-per-period`` checked by its registry field."""
    return check_option("--steps-per-period", text)


def speeds_option(text):
    """``--speeds`` (km/h): start:stop:step or a comma list, refused naming the option."""
    return parse_speeds(text, field="--speeds")


def as_option(option, label, fn, *args):
    """``fn(*args)``; an :class:`InputError` labelled ``label`` is relabelled with the ``option`` typed."""
    try:
        return fn(*args)
    except InputError as exc:
        raise InputError(f"{option}: {str(exc).removeprefix(label + ': ')}") from None


def study_train(text, option):
    """A study train's canonical name; the error names ``option`` as typed."""
    return as_option(option, "train", canonical_train_name, text)


def add_peaks_options(sp):
    """--dense-maxima and --refine-speed (calibrate, table4, study)."""
    sp.add_argument("--dense-maxima", action="store_true",
                    help="maximum acceleration also between time steps, from the RK4 step's dense output "
                         "(quintic Hermite); default: at the steps, as the shipped results")
    sp.add_argument("--refine-speed", action="store_true",
                    help="refined mode: locate the MLM and the DIM peak to 0.05 km/h; default: the paper's "
                         "1 km/h speed grid")
