"""``recommend`` names the study cases near the asked n0 where VBI raises the response or that lie
below the value it returns; the study README lists the excluded cases below the conservative bound."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from importlib import resources
from pathlib import Path

import pytest

from adm_calib.recommend_warnings import (CASES_FILE, excluded_below_bound, excluded_below_bound_markdown,
                                          excluded_negative_beyond_root, parse_cases, recommendation_warnings,
                                          study_cases, study_cases_csv)
from adm_calib.reference import recommend

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = ROOT / "results" / "study" / "results.jsonl.gz"
README = ROOT / "results" / "study" / "README.md"
CAL = [sys.executable, "-m", "adm_calib.calib_commands"]


def test_packaged_cases_are_the_shipped_study():
    """data/study_cases.csv is what study_cases_csv writes from results/study/results.jsonl.gz."""
    from adm_calib.study.store import read_results

    text = study_cases_csv(read_results(SHIPPED).records)
    assert resources.files("adm_calib").joinpath(CASES_FILE).read_text() == text
    cases = parse_cases(text)
    assert len(cases) == 4394  # 4440 cases, 2 without a dz_VBI, 44 whose DIM peak lost wheel-rail contact
    assert sum(1 for c in cases if c.excluded) == 98  # rule step2: the DIM value is not a local maximum


def test_excluded_below_the_conservative_bound():
    """30 excluded cases below the conservative bound where it is positive (the largest gap ICE-2
    L13-f3-mu6: -0.51 % against 1.42 %), 29 more negative beyond its root; all excluded by the
    local-maximum rule (the 31st of the first run, Railjet L23-f1-mu6, is contact_lost since the rerun
    of 2026-12-07 and no longer among the cases)."""
    rows = excluded_below_bound()
    assert len(rows) == 30
    assert len(excluded_negative_beyond_root()) == 29
    assert {c.excluded for c, _ in rows} == {"dim_not_local_max"}
    worst = min(rows, key=lambda r: r[0].delta_zeta_vbi_pct - r[1])
    assert (worst[0].train, worst[0].bridge) == ("ICE-2", "L13-f3-mu6")
    assert worst[0].delta_zeta_vbi_pct == pytest.approx(-0.5086, abs=1e-4)
    assert worst[1] == pytest.approx(1.4168, abs=1e-4)
    assert all(c.delta_zeta_vbi_pct < b and b > 0 for c, b in rows)


def test_readme_lists_the_generated_excluded_cases():
    text = README.read_text()
    m = re.search(r"<!-- excluded-below-bound:begin -->\n(.*?)<!-- excluded-below-bound:end -->", text, re.S)
    assert m, "results/study/README.md lost its excluded-below-bound block"
    assert m.group(1) == excluded_below_bound_markdown()
    assert m.group(1).count("| ICE-2 L13-f3-mu6 | 9.415 | -0.509 | 1.417 |") == 1


def test_recommend_names_negative_and_lower_neighbours():
    """Railjet mu1 at n0 = 3.63 Hz (L = 37 m): of the 23 cases within 0.5 Hz, 3 have dz_VBI < 0
    (L37-f3, L35-f3, L33-f3) and 7 lie below the returned 0.2824 %."""
    rec = recommend("Railjet", 3.63, 41.641, "cfb", span_m=37)
    assert rec.delta_zeta_pct == pytest.approx(0.2824, abs=1e-4)
    w = recommendation_warnings(rec)
    assert len(w) == 2
    assert w[0].startswith("3 of the Railjet mu1 within +/-0.5 Hz of n0 = 3.63 Hz (23 study cases) have dz_VBI < 0")
    assert [b for b in ("L37-f3-mu1", "L35-f3-mu1", "L33-f3-mu1") if b in w[0]] == ["L37-f3-mu1", "L35-f3-mu1",
                                                                                    "L33-f3-mu1"]
    assert w[1].startswith("7 of the Railjet mu1 within +/-0.5 Hz of n0 = 3.63 Hz (23 study cases) lie below the "
                           "returned dz_LB = 0.2824 %")
    assert "\n" not in "".join(w)


def test_recommend_names_an_excluded_case_with_its_reason():
    rec = recommend("ICE-2", 9.4, 3.76, "sc", span_m=13, functions="conservative")
    w = recommendation_warnings(rec)
    assert len(w) == 1 and "L19-f5-mu5 (9.79 Hz, dz_VBI +0.74 %)" in w[0]
    cases = [c for c in study_cases() if c.train == "ICE-2" and c.bridge == "L13-f3-mu6"]
    rec6 = recommend("ICE-2", 9.4, 3.0, "sc", span_m=13, functions="conservative", extrapolate=True)
    assert rec6.mass_functions == ("mu6",)
    text = " ".join(recommendation_warnings(rec6))
    assert cases[0].label() in text and "excluded: associated DIM value not a local maximum" in text


def test_no_warning_where_the_neighbourhood_is_above_the_bound():
    rec = recommend("ICE-2", 9.2, 5.0, "sc", span_m=13, functions="conservative")
    assert recommendation_warnings(rec) == []


@pytest.mark.slow
def test_cli_prints_the_warnings_on_stderr_and_in_json():
    args = CAL + ["recommend", "--train", "Railjet", "--n0", "3.63", "--mu", "41641", "--type", "cfb", "--span", "37"]
    r = subprocess.run(args, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    warn = [ln for ln in r.stderr.splitlines() if ln.startswith("warning: ")]
    assert len(warn) == 2 and "have dz_VBI < 0" in warn[0] and "lie below the returned dz_LB" in warn[1]
    assert "dz_LB = 0.2824 %" in r.stdout
    j = subprocess.run(args + ["--json"], capture_output=True, text=True, timeout=120)
    assert j.returncode == 0
    assert [f"warning: {w}" for w in json.loads(j.stdout)["study_warnings"]] == warn
