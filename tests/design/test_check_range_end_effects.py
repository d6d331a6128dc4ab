"""Every governing effect whose maximum lies at an end of the checked speeds is warned like the
acceleration (text, JSON, report).

The case: one 200 kN force on a stiff 15 m span (n0 = 30 Hz) at V = 150 km/h (144..180 km/h,
v / (2 L n0) <= 0.06): far below resonance, the dynamic increment of the effects near the
supports still grows with speed, so their maxima lie at 180 km/h. Each flag is checked by running
the effects again without the top speed (``train_effects``): a flagged maximum must then fall.
"""

import numpy as np
import pytest

from adm_sim.design import check as ck
from adm_sim.design.check_effects import train_effects
from adm_sim.design.check_report import report_html
from adm_sim.design.check_text import summary
from adm_sim.model.bridge import Bridge
from adm_sim.model.trains import moving_loads


@pytest.fixture(scope="module")
def one_force():
    b = Bridge.from_frequency(15.0, 30.0, 20000.0, 0.02, bridge_type="cfb")
    return ck.run_check(b, 150.0, [moving_loads([0.0], [200e3], name="one force")])


def test_flagged_effects_are_those_whose_maximum_is_the_top_speed(one_force):
    res = one_force
    flagged = res.effects_range_end()
    assert set(flagged) == {"top"}
    top = {e["effect"] for e in flagged["top"]}
    assert top >= {"M(1.5 m)", "V(1.5 m)"}
    t = res.trains[0]
    gov = {d.effect.label: (d, i) for _, d, i in res.effects_governing()}
    # independent: the same effects without the top speed (the check's own speeds, refinement included)
    v = np.unique(np.concatenate([res.speeds_kmh, t.speeds_kmh]))
    below = train_effects(res.bridge, [0.0], [200e3], v[v < res.speeds_kmh[-1] - 1e-6])
    for k, e in enumerate(below.effects):
        d, i = gov[e.label]
        if e.label in top:
            assert t.effects.at_speed_kmh[i] == res.speeds_kmh[-1]
            assert below.dynamic_max[k] < t.effects.dynamic_max[i] * (1 - 1e-9), e.label
        elif d.phi_dyn > 1e-9:
            assert res.speeds_kmh[0] < t.effects.at_speed_kmh[i] < res.speeds_kmh[-1], e.label
    # no dynamic increment (reaction A of one force: the static maximum at every speed): not flagged
    assert "reaction A" not in top and gov["reaction A"][0].phi_dyn == pytest.approx(0.0, abs=1e-12)


def test_warned_in_text_json_and_report(one_force):
    res = one_force
    n = len(res.effects_range_end()["top"])
    text = summary(res)
    assert f"WARNING: the maximum of {n} governing effect(s) lies at the top of the checked range, 180 km/h = 1.2 V: " \
           f"M(1.5 m) (one force, phi'_dyn 0.023" in text
    assert "  at the top of the range" in text
    d = res.to_dict()
    assert [e["effect"] for e in d["effects_range_end"]["top"]] == [e["effect"] for e in res.effects_range_end()["top"]]
    rows = {e["label"]: e for e in d["en1991_2_6_4_6_5_effects"]}
    assert rows["M(1.5 m)"]["at_range_end"] == "top" and rows["M(1.5 m)"]["at_speed_kmh"] == 180.0
    page = report_html(res, version="0", commit="x")
    assert f"The maximum of {n} governing effect(s) lies at the top of the checked range (180 km/h)" in page
    assert "<td>180.0 (range end)</td>" in page


def test_an_effect_maximum_inside_the_range_is_not_warned():
    """B1, V = 250 km/h, HSLM-A7: every governing effect peaks inside 144..300 km/h (at the HSLM-A7
    resonance near 238 km/h), so no warning."""
    from adm_sim.model.bridge import named_bridge

    res = ck.run_check(named_bridge("B1"), 250.0, ck.resolve_trains("HSLM-A7"))
    assert res.effects_range_end() == {} and "governing effect(s)" not in summary(res)
