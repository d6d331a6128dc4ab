"""``replay.py --rrd/--spawn/--connect``: a recording logged into rerun through the live driver's feed
(:class:`adm_sim.recording.viewer_feed.ViewerFeed`, the views of :mod:`adm_sim.recording.rerun_log`),
its metadata as a table. The command line, its checks, the viewer's watch and the ``.rrd``'s
verification are ``replay.py``'s; this module is imported only when a replay draws (rerun loads
here, ~0.9 s), so ``--help``, bad input and ``--republish`` answer without it.
"""

from __future__ import annotations

import time
from pathlib import Path

import rerun as rr
from mcap.reader import make_reader

from adm_sim import protocol as P
from adm_sim.recording import rerun_log as rl
from adm_sim.recording.viewer_feed import RunPhases, ViewerFeed, stamp_ns

__all__ = ["feed_all"]


def feed_all(args, messages, save_path, beat) -> dict[str, int]:
    """Log the decoded ``messages`` (topic, log time in ns, message) of ``args.mcap`` into rerun
    through the live driver's feed; ``beat``: ``[time of the last progress, the feed]`` for
    ``replay.show_in_rerun``'s watch. Returns the count of messages logged per topic."""
    rl.init_rerun("adm_sim_replay", spawn=args.spawn, connect_url=args.connect, save_path=save_path)
    viz = rl.RunLogger(exaggeration=args.exaggeration)
    viz.send_blueprint()
    table = _metadata_table(args.mcap)
    if table is not None:  # outside the default views
        rr.log(P.ENTITIES["metadata"], rr.TextDocument(table, media_type=rr.MediaType.MARKDOWN), static=True)
    feed = ViewerFeed(viz, RunPhases(f"RUN.mcap: '{args.mcap}'"))
    beat[1:] = [feed]
    for topic, log_time_ns, msg in _status_first(messages):
        feed(topic, msg, stamp_ns(msg, log_time_ns))
        beat[0] = time.monotonic()
    feed.finish()
    beat[0] = time.monotonic()
    rl.close_rerun()
    return dict(feed.counts)


def _metadata_table(path: Path) -> str | None:
    """The MCAP's metadata records as a Markdown table (logged to ``metadata``), or None when it has
    none or they cannot be read (they are optional decoration)."""
    info = {}
    with open(path, "rb") as f:
        try:
            for meta in make_reader(f).iter_metadata():
                for k, v in meta.metadata.items():
                    info[f"{meta.name}.{k}"] = v
        except Exception:  # metadata are optional decoration
            return None
    if not info:
        return None
    rows = "\n".join(f"| {k} | {v} |" for k, v in info.items())
    return f"| key | value |\n|---|---|\n{rows}\n"


def _status_first(messages):
    """``messages`` in log-time order with, among those of one log time, the run's opening topics
    first: the recorder writes in order of receipt, and the first monitoring sample of a run (step
    0) carries the same sim time as its ``started`` status, from another publisher."""
    group, t_group = [], None
    for item in messages:
        if item[1] != t_group and group:
            yield from sorted(group, key=lambda m: m[0] not in P.OPENING_TOPICS)  # stable: receipt order otherwise
            group = []
        group.append(item)
        t_group = item[1]
    yield from sorted(group, key=lambda m: m[0] not in P.OPENING_TOPICS)
