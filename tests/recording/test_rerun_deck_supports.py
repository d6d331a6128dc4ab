"""The beam view of a continuous deck: a support under each end and over every intermediate pier.

The bridge record of a continuous deck names its spans (``spans_m``, left to right; ``span_m`` is
their sum); the supports are drawn (static ``runs/beam/supports``) with their apex at the running
sums of the spans, read back from the ``.rrd`` with ``rerun.chunk.RrdReader``.
"""

from __future__ import annotations

import numpy as np

from adm_sim import protocol as P
from adm_sim.recording import rerun_log as rl


def test_support_abscissae_of_one_span_and_of_a_continuous_deck():
    assert rl.supports_m({"span_m": 15.0}) == [0.0, 15.0]
    assert rl.supports_m({"span_m": 65.0, "spans_m": [20.0, 25.0, 20.0]}) == [0.0, 20.0, 45.0, 65.0]
    # the running sums as floating point gives them: 0.1 + 0.2 is the deck's length
    assert rl.supports_m({"span_m": 0.1 + 0.2, "spans_m": [0.1, 0.2]})[-1] == 0.1 + 0.2


def _apexes(path):
    from rerun.chunk import RrdReader  # noqa: PLC0415  rerun (~0.9 s) in this test only

    for chunk in RrdReader(path).stream():
        if chunk.entity_path == "/" + P.beam_path(part="supports"):
            rb = chunk.to_record_batch()
            name = next(n for n in rb.schema.names if n.endswith("LineStrips2D:strips"))
            strips = rb.column(name).to_pylist()[-1]
            return [s[1] for s in strips]  # each triangle's second vertex is its apex on the axis
    raise AssertionError("no supports drawn")


def test_a_continuous_deck_is_drawn_with_every_support(tmp_path):
    path = tmp_path / "deck.rrd"
    rl.init_rerun("adm_sim_test", save_path=path, recording_id="deck")
    viz = rl.RunLogger()
    viz.bridge_description({"bridge": {"span_m": 65.0, "spans_m": [20.0, 25.0, 20.0], "n_modes": 3},
                            "n0_hz": 3.0, "description": "3-span deck"})
    rl.close_rerun()
    np.testing.assert_array_equal(_apexes(path), [[0.0, 0.0], [20.0, 0.0], [45.0, 0.0], [65.0, 0.0]])
