"""``adm-sim trains``: the trains, and with ``--check`` their axle loads and bogie frequencies against the paper's."""

from __future__ import annotations

from adm_sim.errors import InputError
from adm_sim.fields import AXLE_LOAD_REL_TOL
from adm_sim.inputs.train_files import load_train
from adm_sim.model.trains import TRAIN_NAMES, consistency_rows


def add_arguments(parser):
    """The options of ``adm-sim trains``."""
    parser.add_argument("--train", help="one train: a name or a TOML train file (default: all)")
    parser.add_argument("--check", action="store_true", help="axle loads (kN) against the masses (kg) times g, bogie frequencies (Hz)")


def run(args):
    """List the trains (``--train``: one); ``--check``: each value of Table A1 against the one computed."""
    if args.train is not None and not args.train.strip():
        raise InputError("--train: '' is empty; give a train name or a TOML train file (or omit --train for all)")
    names = [args.train] if args.train else list(TRAIN_NAMES) + ["Eurostar-table"]
    bad = 0
    for name in names:
        t = load_train(name)
        print(t.describe())
        if t.description:
            print(f"  {t.description}")
        if args.check:
            for r in consistency_rows(t, rel_tol=AXLE_LOAD_REL_TOL):
                flag = "ok " if r.ok else "MISMATCH"
                print(f"  {flag:8s} {r.item:42s} table {r.table_value:9.3f} {r.unit:3s} "
                      f"computed {r.computed_value:9.3f} {r.unit:3s}  ({r.note})")
                bad += not r.ok
    if args.check:
        print("MLM axle loads: the F column of Table A1 (per bogie for Jacobs sets), the same static "
              "loads the DIM carries; see the train files for choices made.")
        if bad:
            print(f"{bad} check(s) disagree with the paper's numbers (documented in the train files).")
    return 0
