"""Every output of ``adm-sim check`` on this tree against a baseline tree, byte for byte: a change that
should move no number (a faster search, a kernel split in helpers) proves it here.

Runs the same commands on both trees (``PYTHONPATH=<tree>/src``, this interpreter), each writing its
JSON, CSV, tables and HTML report and printing its text, and compares every file and the text byte for
byte, after masking what measures the run or names the code rather than the bridge: the JSON's
``timings_s`` and ``wall_time_s``, the text's ``N trains, X s`` line, the paths of the files written and
the program's commit. The cases: B1 ..
B4 with HSLM-A1..A10 and the four real trains and the standard's mass bounds (the target of issue 36),
B1 at midspan and at x = 5 m, and a continuous deck of three spans (no tables: they are of one span).

Run: .venv/bin/python bench/check_bits.py --baseline ROOT [--only B1,deck] [--keep DIR]
(ROOT a checkout, e.g. ``git worktree add --detach /tmp/base <commit>``). Prints one line per case
and output, ``same`` or the first differing line; exits 1 on any difference.
"""

import argparse
import difflib
import json
import os
import pathlib
import re
import subprocess
import sys
import tempfile

TRAINS = "hslm,ICE-2,Eurostar,Railjet,ICE-4"
BOUNDS = "--mass-bounds=standard:4000,2000"
#: name -> the options after ``adm-sim check`` (the outputs are added)
CASES = {
    "B1": ["--bridge", "B1", "--max-line-speed", "350", "--trains", TRAINS, BOUNDS],
    "B2": ["--bridge", "B2", "--max-line-speed", "300", "--trains", TRAINS, BOUNDS],
    "B3": ["--bridge", "B3", "--max-line-speed", "300", "--trains", TRAINS, BOUNDS],
    "B4": ["--bridge", "B4", "--max-line-speed", "300", "--trains", TRAINS, BOUNDS],
    "B1-midspan": ["--bridge", "B1", "--max-line-speed", "350", "--trains", TRAINS, "--where", "midspan"],
    "B1-x5": ["--bridge", "B1", "--max-line-speed", "350", "--trains", TRAINS, "--where", "x=5"],
    "deck": ["--bridge", "spans=12/16/12,EJ=8.5e9,mu=15000,zeta_pct=2", "--max-line-speed", "200",
             "--trains", "HSLM-A1,ICE-2"],
}
#: the cases whose check writes no tables (a continuous deck's report is not of one span)
NO_TABLES = {"deck"}
#: what names the program's commit (the trees differ in it, not in their numbers)
COMMIT = re.compile(rb"commit [0-9a-f]{7,40}\S*")


def src_of(root):
    """The ``src`` directory of a checkout ``root`` (or ``root`` itself when it holds ``adm_sim``)."""
    root = pathlib.Path(root).resolve()
    return root if (root / "adm_sim").is_dir() else root / "src"


def run_case(src, argv, out, tables=True):
    """``adm-sim check argv`` importing ``src``, its outputs in ``out``; returns the masked text."""
    out.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ, PYTHONPATH=str(src), OPENBLAS_NUM_THREADS="1", ADM_SIM_QUIET_COMPILE="1")
    files = ["--json", str(out / "check.json"), "--csv", str(out / "check.csv"), "--report", str(out / "report.html")]
    files += ["--tables", str(out / "tables")] if tables else []
    p = subprocess.run([sys.executable, "-m", "adm_sim.cli.sim_commands", "check", *argv, *files],
                       env=env, capture_output=True, text=True)
    text = f"exit {p.returncode}\n{p.stdout}\n{p.stderr}"
    text = re.sub(r"^\d+ trains?, [0-9.]+ s$", "N trains, X s", text, flags=re.M)
    return text.replace(str(out), "OUT")


def masked(path):
    """The bytes of an output file, the program's commit and the JSON's run times masked."""
    data = COMMIT.sub(b"commit C", path.read_bytes())
    if path.suffix == ".json":
        return json.dumps(_drop_times(json.loads(data)), indent=1, sort_keys=True).encode()
    return data


def _drop_times(doc):
    """``doc`` without its ``timings_s`` and ``wall_time_s`` at any depth."""
    if isinstance(doc, dict):
        return {k: _drop_times(v) for k, v in doc.items() if k not in ("timings_s", "wall_time_s")}
    if isinstance(doc, list):
        return [_drop_times(v) for v in doc]
    return doc


def first_difference(a, b):
    """The first differing line of two byte strings, or None."""
    if a == b:
        return None
    la, lb = a.decode(errors="replace").splitlines(), b.decode(errors="replace").splitlines()
    for line in difflib.unified_diff(la, lb, lineterm="", n=0):
        if line.startswith(("-", "+")) and not line.startswith(("---", "+++")):
            return line[:200]
    return "(same lines, different bytes)"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", metavar="ROOT", required=True, help="the checkout to compare with")
    ap.add_argument("--only", help=f"comma list of cases ({', '.join(CASES)})")
    ap.add_argument("--keep", metavar="DIR", help="keep the outputs here (default: a temporary directory)")
    args = ap.parse_args()
    names = args.only.split(",") if args.only else list(CASES)
    trees = {"baseline": src_of(args.baseline), "this": src_of(pathlib.Path(__file__).resolve().parents[1])}
    tmp = None if args.keep else tempfile.TemporaryDirectory(prefix="check-bits-")
    root = pathlib.Path(args.keep or tmp.name)
    differ = 0
    for name in names:
        texts = {t: run_case(src, CASES[name], root / t / name, name not in NO_TABLES) for t, src in trees.items()}
        outs = {"text": tuple(COMMIT.sub(b"commit C", texts[t].encode()) for t in trees)}
        files = sorted({p.relative_to(root / t / name) for t in trees for p in (root / t / name).rglob("*")
                        if p.is_file()})
        for rel in files:
            a, b = (root / t / name / rel for t in trees)
            outs[str(rel)] = (masked(a) if a.exists() else b"(missing)", masked(b) if b.exists() else b"(missing)")
        for what, (a, b) in outs.items():
            d = first_difference(a, b)
            differ += d is not None
            print(f"{name:11s} {what:34s} {'same' if d is None else 'DIFFERS: ' + d} ({len(b)} bytes)")
    if tmp is not None:
        tmp.cleanup()
    print(f"{len(names)} cases: {'every output the same' if not differ else f'{differ} outputs differ'}")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
