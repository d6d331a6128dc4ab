"""``adm-sim salvage``: recover the complete messages of a killed run's MCAP log into a new file."""

from __future__ import annotations

from pathlib import Path

from adm_sim.cliutil import add_overwrite
from adm_sim.errors import InputError
from adm_sim.files import claim_output, mcap_input
from adm_sim.recording.mcap_log import salvage


def add_arguments(parser):
    """The arguments of ``adm-sim salvage``: SRC, DST and ``--overwrite``."""
    parser.add_argument("src")
    parser.add_argument("dst")
    add_overwrite(parser, "replace an existing DST")


def run(args):
    """Recover SRC into DST (never SRC itself) and print what was recovered and where the damage was."""
    src = mcap_input(args.src, "salvage SRC", damaged_magic=True)  # a damaged magic is what salvage is for
    if Path(args.dst).resolve() == src.resolve():
        raise InputError(f"salvage DST: {args.dst!r} is SRC; give another file")
    dst = claim_output(args.dst, "salvage DST", args.overwrite, ".mcap")
    report = {}
    n = salvage(src, dst, overwrite=args.overwrite, report=report)
    print(f"recovered {n} messages into {args.dst}")
    if report.get("lost_chunks") or report.get("orphan_messages"):
        print(f"lost: {report['lost_chunks']} of {report['chunks']} chunks were damaged and skipped"
              + (f", {report['orphan_messages']} messages of channels declared in them" if report["orphan_messages"]
                 else ""))
    for line in report.get("damage", ()):  # each damaged place: offset, topics, messages lost (or none)
        print(f"{'damaged' if line.endswith('no message lost') else 'dropped'}: {line}")
    return 0
