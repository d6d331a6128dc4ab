"""The study shipped in ``results/study`` matches the code that produced it.

Three shipped batches (a short span, a long span and a Jacobs train; one on the paper's DIM grid
the study shipped was computed on, two on the study's default window grid) are recomputed and must match
the shipped lines to 1e-6 % on Δζ_VBI and 1e-9 relative on the peaks; the shipped re-derived
lower-bound functions (``--functions ours``) are the fit of the shipped lines, so neither the data
nor the functions can drift from the code silently.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from adm_calib import peaks as pk
from adm_calib import study as st
from adm_calib.reference import lower_bound_table
from adm_sim.integrate.contact import CONTACT_LOST

SHIPPED = Path(__file__).resolve().parents[2] / "results" / "study" / "results.jsonl.gz"


@pytest.fixture(scope="module")
def shipped():
    content = st.read_results(SHIPPED)
    return {st.record_key(r): r for r in content.records}, content


def test_shipped_study_is_complete(shipped):
    by_key, content = shipped
    assert len(content.records) == len(by_key) == 4440 and content.duplicates == 0
    assert {k for k in by_key} == {c.key for c in st.select_cases()}
    assert not [r for r in by_key.values() if r["status"] == "error"]
    for r in by_key.values():
        if r["delta_zeta_vbi_pct"] is not None:
            # a Δζ_VBI determined (ok), computed but not determined, or from a DIM peak whose run lost contact
            assert np.isfinite(r["delta_zeta_vbi_pct"])
            assert pk.has_delta_zeta(r["status"]) or r["status"] == CONTACT_LOST, r["status"]
        assert r["status"] in pk.STATUSES or r["status"] == CONTACT_LOST
        if r["status"] == CONTACT_LOST:  # the line names the speed, axle, time and force of the loss
            assert re.search(r"DIM peak at [0-9.]+ km/h .* axle \d+ would lift off the rail \(t = \S+ s, "
                             r"contact force -[0-9.]+ kN < 0\)", r["message"]), r["message"]
        assert "warnings" in r  # written with today's plausibility check


# the shipped study ran on the paper's DIM grid; one batch on it, two on the study's default window
# grid (the same results by construction, tests/calib/test_study_window_grid.py)
@pytest.mark.slow
@pytest.mark.parametrize("train,span,fi,grid", [("ICE-2", 5, 2, "paper"), ("Railjet", 38, 4, "window"),
                                                ("Eurostar", 14, 3, "window")])
def test_shipped_batches_recompute(shipped, train, span, fi, grid):
    by_key, _ = shipped
    cases = st.select_cases([train], st.MASS_FUNCTION_NAMES, (span, span), [fi])
    for rec in st.run_batch(cases, st.StudySettings(dim_grid=grid)):
        assert rec["dim_grid"] == grid
        old = by_key[st.record_key(rec)]
        assert rec["status"] == old["status"] and rec["message"] == old["message"]
        assert rec["mlm_max_at_range_end"] == old["mlm_max_at_range_end"]
        if old["delta_zeta_vbi_pct"] is None:
            assert rec["delta_zeta_vbi_pct"] is None
        else:
            assert abs(rec["delta_zeta_vbi_pct"] - old["delta_zeta_vbi_pct"]) <= 1e-6
        for k in ("mlm_peak_acc_m_s2", "dim_peak_acc_m_s2"):
            if old[k] is not None:
                assert rec[k] == pytest.approx(old[k], rel=1e-9)


def test_shipped_functions_are_the_fit_of_the_shipped_study(shipped):
    _, content = shipped
    fit = st.fit_study(content.records, rule=st.DEFAULT_RULE)
    ours = lower_bound_table("ours")
    n = 0
    for (t, m), f in fit.fits.items():
        if f.fit is None:
            continue
        lb = ours[t][m]
        np.testing.assert_allclose(lb.coefficients, f.fit.coefficients, rtol=1e-12)
        assert lb.r2 == pytest.approx(f.fit.r2, rel=1e-12)
        n += 1
    assert n == 24
