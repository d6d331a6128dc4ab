"""Whether a ``.rrd`` file was written whole: read back by rerun's own reader (``rerun.chunk.RrdReader``).

rerun's file sink writes from a thread of its own and reports a refused write (a full disk, a file
larger than ``ulimit -f``) only in its log: the Python call that logged the data returns as usual.
A recording is therefore read back before it gets its final name (:func:`check_rrd`). A file cut
anywhere fails one of two ways in rerun 0.41: a frame longer than what is left of the file
(``RuntimeError: ... exceeds file size``), or a file whose frames all decode but whose footer (the
manifest rerun writes when the sink is closed) is missing (``RerunWarning: RRD file has no
footer``). Both are a recording that is not whole.
"""

from __future__ import annotations

import warnings
from pathlib import Path

from rerun.chunk import RrdReader

from adm_sim.errors import RunError


def check_rrd(path, final=None, option="rrd_path") -> int:
    """Read the whole ``.rrd`` at ``path`` with rerun's reader; return its number of chunks.

    Parameters
    ----------
    path : path-like
        The file written (usually the temporary file beside the final one).
    final : path-like or None
        The name the file is meant to get (named in the error; default ``path``).
    option : str
        What the user named the output by (``--rrd``, ``rrd_path``), first in the error.

    Raises
    ------
    RunError
        One line: the file is missing, cut (a frame runs past its end), has no footer, or holds no
        recording.
    """
    path = Path(path)
    final = path if final is None else Path(final)
    where = f"{option}: rerun could not write '{final}' whole"
    if not path.is_file():
        raise RunError(f"{where} (no file was written)")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            reader = RrdReader(path)
            n = sum(1 for _ in reader.stream())
            recordings = reader.recordings()
        except (RuntimeError, ValueError, OSError) as exc:
            why = " ".join(str(exc).replace(f"Failed to read RRD file at {path}: ", "").replace(str(path), "the file").split())
            raise RunError(f"{where} ({why}; {path.stat().st_size} bytes written; is the disk full or a "
                           "file size limit set?)") from None
    cut = [w for w in caught if "footer" in str(w.message).lower()]
    if cut:
        raise RunError(f"{where} (the file ends before rerun's footer: {path.stat().st_size} bytes written; is "
                       "the disk full or a file size limit set?)")
    if not recordings:
        raise RunError(f"{where} (the file holds no recording)")
    return n
