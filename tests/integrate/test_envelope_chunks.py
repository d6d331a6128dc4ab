"""The exact envelope in chunks of speeds (issue 38 item 1: work that fits is chunked rather than
allocated whole).

Every lane (speed) of :func:`adm_sim.integrate.envelope.moving_load_envelope` is propagated,
bounded and searched on its own, so a chunk of any width gives the same numbers: checked bit for
bit (``np.array_equal``) against the whole computation with the chunk forced down to one lane and
to a few lanes, over trains, bridges, mode counts and positions. The memory estimate
(:func:`adm_sim.integrate.envelope.envelope_bytes`) is the chunked peak: bounded whatever the
number of speeds, and not below what tracemalloc sees the numpy arrays take (the numba kernels'
own arrays, the bounds and the deck candidates, are in the estimate but not seen by tracemalloc,
so the true ratio is nearer 1 than the one asserted).
"""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from adm_sim import limits
from adm_sim.cli.sim_commands import main
from adm_sim.errors import EXIT_INPUT, InputError
from adm_sim.integrate import envelope as env
from adm_sim.inputs.train_files import load_train
from adm_sim.model.bridge import named_bridge

FIELDS = ("max_acc_m_s2", "max_disp_m", "t_acc_s", "t_disp_s", "x_acc_m", "x_disp_m", "max_moment_Nm",
          "t_moment_s", "max_disp_midspan_m", "refined", "speeds_kmh", "modes", "zeta")
SPEEDS_KMH = np.arange(144.0, 421.0, 3.1)  # 90 speeds


def _envelope(bridge, train, where, chunk_bytes, monkeypatch, speeds=SPEEDS_KMH):
    monkeypatch.setattr(env, "CHUNK_BYTES", chunk_bytes)
    return env.moving_load_envelope(bridge, train.axle_offsets_m, train.axle_loads_n, speeds, where=where,
                                    keep_intervals=True, delta_zeta=0.004)


def _events(bridge, train):
    return np.unique(np.concatenate([train.axle_offsets_m, train.axle_offsets_m + bridge.span_m])).size


@pytest.mark.parametrize("bridge_name,n_modes,train_name", [
    ("B1", 3, "ICE-2"), ("B1", 3, "HSLM-A4"), ("B4", 6, "HSLM-A9"), ("B4", 6, "Railjet")])
@pytest.mark.parametrize("where", ["midspan", "deck", 5.0])
def test_chunks_equal_the_whole_bit_for_bit(bridge_name, n_modes, train_name, where, monkeypatch):
    """Chunks of 1 lane, of a few lanes and of a width that does not divide the 90 speeds give every
    maximum, time, position, refinement count and kept coefficient of the whole run, bit for bit."""
    bridge, train = named_bridge(bridge_name, n_modes=n_modes), load_train(train_name)
    whole = _envelope(bridge, train, where, 2**62, monkeypatch)
    per_lane = env.lane_bytes(_events(bridge, train), n_modes, 3 if where == "midspan" else 4,
                              env.deck_positions_m(bridge.span_m, n_modes).size if where == "deck" else 1)
    for lanes in (1, 7, 41):
        monkeypatch.setattr(env, "CHUNK_BYTES", int(lanes * per_lane) + 1)
        assert env.chunk_lanes(_events(bridge, train), n_modes, 3 if where == "midspan" else 4,
                               env.deck_positions_m(bridge.span_m, n_modes).size if where == "deck" else 1) == lanes
        part = _envelope(bridge, train, where, int(lanes * per_lane) + 1, monkeypatch)
        for f in FIELDS:
            assert np.array_equal(getattr(part, f), getattr(whole, f)), (lanes, f)
        if where == "midspan":
            assert part.intervals is None and whole.intervals is None
        else:
            assert np.array_equal(part.intervals.P, whole.intervals.P), lanes
            assert np.array_equal(part.intervals.H, whole.intervals.H), lanes


def test_estimate_for_20000_speeds_is_one_chunk_and_the_results():
    """ICE-2 on B1, whole deck, 20000 speeds: the estimate is one chunk (1109 speeds, at most
    CHUNK_BYTES) plus the results (14 doubles a speed), 66.1 MiB, under 70 MiB (tracemalloc: 65.4 MiB
    of numpy arrays); at once it would be 20000 lanes of lane_bytes, 1154 MiB (tracemalloc saw 774 MiB
    of numpy arrays before the chunks, beside the numba kernels' own). Kept coefficients add
    2 x 16 K n_modes bytes a speed, exactly."""
    b, t = named_bridge("B1"), load_train("ICE-2")
    K, nm, nq, npos = _events(b, t), 3, 4, env.deck_positions_m(b.span_m, 3).size
    assert (K, npos) == (112, 3)
    est = env.envelope_bytes(20000, K, nm, nq, npos)
    per_lane = env.lane_bytes(K, nm, nq, npos)
    assert per_lane == pytest.approx(64 * K * nm + 24 * K * nq + 80 * K + 24 * 16 * nm + 0.25 * K * npos * 216)
    assert est == pytest.approx(env.chunk_lanes(K, nm, nq, npos) * per_lane + 20000 * 8 * 14)
    assert env.CHUNK_BYTES - per_lane < est - 20000 * 8 * 14 <= env.CHUNK_BYTES
    assert est < 70 * 2**20
    assert env.chunk_lanes(K, nm, nq, npos) == 1109 and 20000 * per_lane > 1150 * 2**20
    kept = env.envelope_bytes(20000, K, nm, nq, npos, keep_intervals=True)
    assert kept - est == 20000 * 32 * K * nm


@pytest.mark.parametrize("bridge_name,n_modes,train_name,where", [
    ("B1", 3, "ICE-2", "deck"), ("B1", 3, "HSLM-A1", "midspan"), ("B4", 8, "ICE-2", 5.0), ("B4", 8, "HSLM-A1", "deck")])
def test_estimate_bounds_the_measured_peak(bridge_name, n_modes, train_name, where, monkeypatch):
    """1000 speeds in chunks of 4 MB (9 to 30 chunks here): the numpy arrays' peak (tracemalloc) stays
    at or below the estimate, and the estimate within 1.7x of it (measured 1.14-1.64x; 1.13-1.60x with
    3000 speeds in 26 to 89 chunks: the estimate counts the numba kernels' bounds and deck candidates
    too, which tracemalloc does not see). The peak is one chunk's plus the results, so the number of
    chunks past a few does not change the property, only the cost (a third of 3000 speeds')."""
    bridge, train = named_bridge(bridge_name, n_modes=n_modes), load_train(train_name)
    speeds = np.linspace(144.0, 420.0, 1000)
    monkeypatch.setattr(env, "CHUNK_BYTES", 4_000_000)
    env.moving_load_envelope(bridge, train.axle_offsets_m, train.axle_loads_n, speeds[:2], where=where)  # compiled
    tracemalloc.start()
    try:
        env.moving_load_envelope(bridge, train.axle_offsets_m, train.axle_loads_n, speeds, where=where)
        real = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    nm = n_modes if where != "midspan" else (n_modes + 1) // 2
    npos = env.deck_positions_m(bridge.span_m, n_modes).size if where == "deck" else 1
    est = env.envelope_bytes(speeds.size, _events(bridge, train), nm, 3 if where == "midspan" else 4, npos)
    assert real <= est <= 1.7 * real, (real, est)


def test_envelope_beyond_the_memory_is_refused_before_it_starts(monkeypatch):
    """The estimate is checked against the memory available before anything is allocated: one line
    naming the speeds, the events, the modes and what makes it smaller."""
    monkeypatch.setattr(limits, "available_memory_bytes", lambda: 2e6)
    b, t = named_bridge("B1"), load_train("ICE-2")
    with pytest.raises(InputError, match=r"^memory: the exact envelope of 500 speeds with its coefficients kept would "
                                         r"take [0-9.]+ MiB; this machine has 1.91 MiB available \(a run may take "
                                         r"80% of it\); large because 500 speeds x 112 axle events x 3 modes; fewer "
                                         r"speeds or no kept coefficients make it smaller$"):
        env.moving_load_envelope(b, t.axle_offsets_m, t.axle_loads_n, np.linspace(150.0, 400.0, 500),
                                 where="deck", keep_intervals=True)


def test_cli_refusal_is_one_line_exit_2(monkeypatch, capsys):
    monkeypatch.setattr(limits, "available_memory_bytes", lambda: 1e5)
    assert main(["sweep", "--model", "mlm", "--speeds", "150:400:1", "--train", "ICE-2"]) == EXIT_INPUT
    err = capsys.readouterr().err
    assert err.startswith("error: memory: the exact envelope of 251 speeds would take ") and err.count("\n") == 1
    assert "large because 251 speeds x 112 axle events x 2 modes; fewer speeds make it smaller" in err
