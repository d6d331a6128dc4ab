"""A track irregularity as the user gives it: a spec string (``--irregularity``, the train node's
``irregularity``) of random profiles, measured profile files (CSV or TOML) and discrete defects.

The reader turns it into a :class:`adm_sim.model.irregularity.Profile` (the model's spectra, random
profiles and defects); every refusal is one line naming the part as typed.
"""

from __future__ import annotations

import csv
import math
import tomllib
from pathlib import Path

import numpy as np

from adm_sim.errors import InputError
from adm_sim.files import refuse_special
from adm_sim.model.irregularity import (DEFAULT_BAND_M, Profile, check_bounds, check_samples, joint, ramp,
                                        random_profile, refusal, spectrum)


def read_profile(path):
    """A measured profile from a CSV (two columns ``position_m, elevation_m``, a header line
    allowed) or a TOML file (arrays ``position_m`` and ``elevation_m``); elevations up, the
    profile's ``r`` is their negative."""
    p = Path(path)
    refuse_special(p, f"irregularity: file = {str(path)!r}")  # a fifo is named as one, never opened (no hang)
    if p.is_dir():
        raise InputError(f"irregularity: file = {str(path)!r} is a folder; allowed a CSV or TOML profile file")
    if not p.is_file():
        raise InputError(f"irregularity: file = {str(path)!r} does not exist; allowed a CSV or TOML profile file")
    if p.suffix.lower() == ".toml":
        try:
            data = tomllib.loads(p.read_text())
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            raise InputError(f"irregularity: file = {str(path)!r} is not valid TOML ({exc})") from None
        if "position_m" not in data or "elevation_m" not in data:
            raise InputError(f"irregularity: file = {str(path)!r} lacks position_m or elevation_m; "
                             f"allowed two arrays position_m and elevation_m (m)")
        try:
            x = np.asarray(data["position_m"], dtype=float)
            r = np.asarray(data["elevation_m"], dtype=float)
        except (TypeError, ValueError):
            raise InputError(f"irregularity: file = {str(path)!r}: position_m and elevation_m must be "
                             f"arrays of numbers") from None
    else:
        rows = []
        with p.open(newline="") as fh:
            for i, row in enumerate(csv.reader(fh)):
                if not row or row[0].strip().startswith("#"):
                    continue
                try:
                    rows.append((float(row[0]), float(row[1])))
                except (ValueError, IndexError):
                    if rows or i > 0:
                        raise InputError(f"irregularity: file = {str(path)!r} row {i + 1} = {','.join(row)!r}; "
                                         f"allowed two numbers position_m, elevation_m") from None
        a = np.asarray(rows, dtype=float).reshape(-1, 2)
        x, r = a[:, 0], a[:, 1]
    check_samples(x, r, "profile")  # on the file's own values (elevations)
    return Profile(x, -r, description=f"file={p}")


# ---------------------------------------------------------------------- the spec string
def parse_irregularity(text, length_m):
    """A :class:`Profile` over ``[0, length_m]`` from a spec string, or None for ``none``/empty.

    Parts joined by ``+`` add up:

    * ``german-low|german-high|fra-1..fra-6|iso-a..iso-h[:seed=N][:band=LO:HI]`` a random profile (seed 0,
      band :data:`DEFAULT_BAND_M` by default);
    * ``file=PATH`` a measured profile (CSV or TOML);
    * ``ramp:at=X:length=L:height=H`` and ``joint:at=X:length=L:depth=D`` discrete defects (m).
    """
    text = (text or "").strip()
    if text.lower() in ("", "none", "smooth"):
        return None
    length_m = float(length_m)
    parts = [p.strip() for p in text.split("+")]
    x = None
    r = None
    measured = None
    defects = []
    for part in parts:
        head, _, rest = part.partition(":")
        head = head.strip().lower()
        opts = _options(rest, part)
        if head.startswith("file="):
            measured = read_profile(part.split("=", 1)[1])
            continue
        if head in ("ramp", "joint"):
            defects.append((head, opts))
            continue
        spec = spectrum(head)
        seed = _int_opt(opts, "seed", 0)
        band = opts.get("band", None)
        band = DEFAULT_BAND_M if band is None else _band(band)
        prof = random_profile(spec.name, seed, length_m, band)
        x = prof.x_m if x is None else x
        r = prof.r_m if r is None else r + prof.evaluate(x)[0]
        for k in opts:
            if k not in ("seed", "band"):
                raise refusal(f"{head} option", k, "seed, band")
    if measured is not None:
        if x is None:
            x, r = measured.x_m, measured.r_m.copy()
        else:
            r = r + measured.evaluate(x)[0]
    if x is None:
        x = np.linspace(0.0, length_m, max(int(math.ceil(length_m / 0.01)), 4) + 1)
        r = np.zeros(x.size)
    for kind, opts in defects:
        allowed = ("at", "length", "height") if kind == "ramp" else ("at", "length", "depth")
        for k in opts:
            if k not in allowed:
                raise refusal(f"{kind} option", k, ", ".join(allowed))
        at = _float_opt(opts, "at", kind, 0.0, None)
        ln = _float_opt(opts, "length", kind, 1e-3, 100.0)
        if kind == "ramp":
            r = r - ramp(x, at, ln, _float_opt(opts, "height", kind, -0.05, 0.05))
        else:
            r = r - joint(x, at, ln, _float_opt(opts, "depth", kind, 0.0, 0.05))
    return check_bounds(Profile(x, r, description=text))


def _options(rest, part):
    out = {}
    tokens = [t for t in rest.split(":") if t != ""] if rest else []
    i = 0
    while i < len(tokens):
        tok = tokens[i]
        if "=" not in tok:
            raise InputError(f"irregularity: {part!r} has {tok!r}; allowed key=value options separated by ':'")
        k, v = tok.split("=", 1)
        k = k.strip().lower()
        if k == "band" and i + 1 < len(tokens) and "=" not in tokens[i + 1]:
            v = f"{v}:{tokens[i + 1]}"
            i += 1
        out[k] = v.strip()
        i += 1
    return out


def _band(text):
    try:
        lo, hi = (float(t) for t in str(text).split(":"))
    except ValueError:
        raise refusal("band", text, "LO:HI in m, e.g. 2:80") from None
    return lo, hi


def _int_opt(opts, key, default):
    v = opts.get(key)
    if v is None:
        return default
    try:
        n = int(v)
    except ValueError:
        raise refusal(key, v, "an integer >= 0") from None
    if n < 0:
        raise refusal(key, v, "an integer >= 0")
    return n


def _float_opt(opts, key, kind, lo, hi):
    if key not in opts:
        raise InputError(f"irregularity: {kind} needs {key}=<m>")
    try:
        v = float(opts[key])
    except ValueError:
        raise refusal(f"{kind} {key}", opts[key], "a number (m)") from None
    if not math.isfinite(v) or (lo is not None and v < lo) or (hi is not None and v > hi):
        rng = f"[{'-inf' if lo is None else f'{lo:g}'}, {'inf' if hi is None else f'{hi:g}'}] m"
        raise refusal(f"{kind} {key}", opts[key], rng)
    return v
