"""A data logger's acceleration export (``monitor.py --csv FILE``): time and acceleration columns.

Format: a header line naming the columns, then one row per sample; comma, semicolon or tab
separated (the header line decides). The time column (default ``t``) is in seconds, strictly
increasing; the acceleration column (default ``a``) in m/s². Other columns are ignored. An empty
acceleration cell or ``nan``/``inf`` is a non-finite sample: kept, counted and excluded per passage
by the monitor (a dropout), never a silent loss.

Bad input (one :class:`InputError` line naming the file, the row and the value): a file that cannot
be read or is not UTF-8 text, no header or no data row, a column that is not in the header (the
message lists the ones that are), a time that is not a finite number, times that do not increase
(duplicate or going backwards), an acceleration that is not a number.
"""

from __future__ import annotations

import csv
import math

import numpy as np

from adm_sim.errors import InputError
from adm_sim.files import input_file, read_text

__all__ = ["read_sensor_csv"]

#: Cells taken as a non-finite acceleration sample (a logger's missing value).
NONFINITE_CELLS = {"", "nan", "-nan", "+nan", "inf", "+inf", "-inf", "infinity", "-infinity", "na", "n/a", "null"}


def read_sensor_csv(text, time_column="t", accel_column="a", option="--csv"):
    """``(t_s, a_m_s2)`` float arrays of the rows of the CSV file ``text``.

    ``a_m_s2`` holds NaN where the acceleration cell was empty or non-finite (see
    :data:`NONFINITE_CELLS`); the caller counts them. Raises :class:`InputError`.
    """
    path = input_file(text, option, "CSV file")
    body = read_text(path, option)
    lines = body.splitlines()
    where = f"{option}: {str(text)!r}"
    if not lines or not lines[0].strip():
        raise InputError(f"{where} has no header line; give a header naming the columns "
                         f"(e.g. '{time_column},{accel_column}')")
    head = lines[0]
    delim = max((",", ";", "\t"), key=head.count) if any(d in head for d in ",;\t") else ","
    header = [h.strip() for h in next(csv.reader([head], delimiter=delim))]
    cols = {}
    for name, opt in ((time_column, "--time-column"), (accel_column, "--accel-column")):
        if name not in header:
            raise InputError(f"{where} has no column {name!r} ({opt}); its columns: "
                             f"{', '.join(repr(h) for h in header)}")
        cols[name] = header.index(name)
    it, ia = cols[time_column], cols[accel_column]
    t_out, a_out = [], []
    prev = None
    for row_no, row in enumerate(csv.reader(lines[1:], delimiter=delim), start=2):
        if not row or all(not c.strip() for c in row):
            continue
        if len(row) <= max(it, ia):
            raise InputError(f"{where} line {row_no}: {len(row)} cells, the columns {time_column!r} and "
                             f"{accel_column!r} need {max(it, ia) + 1}")
        cell = row[it].strip()
        try:
            t = float(cell)
        except ValueError:
            t = float("nan")
        if not math.isfinite(t):
            raise InputError(f"{where} line {row_no}: time {cell!r} in column {time_column!r} is not a finite "
                             f"number of seconds")
        if prev is not None and t <= prev:
            what = "repeats the time" if t == prev else "goes back from"
            raise InputError(f"{where} line {row_no}: time {cell} s {what} {prev!r} s of the line before; times "
                             f"must strictly increase")
        prev = t
        cell = row[ia].strip()
        if cell.lower() in NONFINITE_CELLS:
            a = float("nan")
        else:
            try:
                a = float(cell)
            except ValueError:
                raise InputError(f"{where} line {row_no}: acceleration {cell!r} in column {accel_column!r} is not "
                                 f"a number (m/s^2; an empty cell or nan marks a missing sample)") from None
            if not math.isfinite(a):
                a = float("nan")
        t_out.append(t)
        a_out.append(a)
    if len(t_out) < 2:
        raise InputError(f"{where} has {len(t_out)} data row(s); at least 2 samples are needed")
    return np.asarray(t_out), np.asarray(a_out)
