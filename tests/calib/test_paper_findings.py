"""The paper's Section 4.4 statements, checked over our Table 4 (``adm_calib.table4.run_table4``).

Rules fixed before comparing (the README states the same): "X is non-conservative" means the
approach gives more additional damping than the interaction does, ``Δζ_X > Δζ_VBI`` (the MLM with it
under-estimates the DIM peak); "conservative" means ``Δζ_X <= Δζ_VBI``. "Slightly" is read as
within 0.1 percentage points. The ICE-4 statements are not asserted: our ICE-4 differs from the
paper (the car order of Fig. 14 is missing from our copy; docs/model.md, "Open discrepancy"); one
test pins the documented direction of that difference so that a change to it is seen.

Each statement is a separate test over one computation of the whole table (16 calibrations, about
3 s on the compiled backend).
"""

import pytest

from adm_calib.table4 import run_table4

#: The trains whose Section 4.4 statements we reproduce.
REPRODUCED = ("ICE-2", "Eurostar", "Railjet")
#: "slightly" (percentage points of Δζ).
SLIGHT_PCT = 0.1


# session scope: with --dist worksteal a worker can come back to this module after others, and a
# module-scoped fixture is then built again (3 s); the tests only read the table
@pytest.fixture(scope="session")
def table():
    return run_table4()


def _v(table, row, train, bridge):
    return table.value(row, train, bridge)


@pytest.mark.parametrize("train", ("ICE-2", "Eurostar", "Railjet", "ICE-4"))
def test_adm_is_non_conservative_on_b1_for_every_train(table, train):
    """"For the shorter span CFB bridge B1 ... the ADM is non-conservative for each train type"."""
    assert _v(table, "ADM", train, "B1") > _v(table, "VBI", train, "B1")


@pytest.mark.parametrize("train", ("ICE-2", "Railjet"))
def test_adm_is_conservative_on_b3_for_ice2_and_railjet(table, train):
    """"For the shorter span SC bridge B3, the ADM yields useful conservative results for the ICE-2
    and the Railjet"."""
    assert _v(table, "ADM", train, "B3") <= _v(table, "VBI", train, "B3")


def test_adm_is_slightly_non_conservative_on_b3_for_the_eurostar(table):
    """"... slightly non-conservative values for the Eurostar" (on B3)."""
    excess = _v(table, "ADM", "Eurostar", "B3") - _v(table, "VBI", "Eurostar", "B3")
    assert 0.0 < excess <= SLIGHT_PCT


@pytest.mark.parametrize("bridge", ("B2", "B4"))
@pytest.mark.parametrize("train", ("ICE-2", "Eurostar", "Railjet", "ICE-4"))
def test_adm_gives_nothing_on_the_30_m_spans(table, train, bridge):
    """"For the longer span bridges B2 and B4 the ADM does not provide any additional damping"
    (EN 1991-2 Fig. 6.15: Δζ = 0 at L = 30 m); and Δζ_VBI > 0 there, so the ADM is conservative."""
    assert _v(table, "ADM", train, bridge) == 0.0
    assert _v(table, "VBI", train, bridge) > 0.0


@pytest.mark.parametrize("train", REPRODUCED)
@pytest.mark.parametrize("bridge", ("B1", "B2", "B3", "B4"))
def test_lower_bound_below_vbi_except_ice2_on_b2(table, train, bridge):
    """"The lower bound functions ... prove to be a useful approximation ... Only for the ICE-2 at B2
    (and the ICE-4 at B3) the method slightly over-estimates the additional damping"."""
    lb, vbi = _v(table, "LB", train, bridge), _v(table, "VBI", train, bridge)
    if (train, bridge) == ("ICE-2", "B2"):
        assert 0.0 < lb - vbi <= SLIGHT_PCT
    else:
        assert lb <= vbi


def test_lower_bound_is_zero_for_the_eurostar_on_b1(table):
    """"The fundamental frequency of the bridge B1 is outside the application boundaries for the
    Eurostar, so that Δζ_LB = 0 in this situation"; the interaction itself is not zero there."""
    assert _v(table, "LB", "Eurostar", "B1") == 0.0
    assert _v(table, "VBI", "Eurostar", "B1") > 0.1


@pytest.mark.parametrize("train", ("ICE-2", "Railjet"))
@pytest.mark.parametrize("bridge", ("B1", "B2", "B3", "B4"))
def test_eada_is_conservative_for_ice2_and_railjet(table, train, bridge):
    """"For the ICE-2 and the Railjet, the EADA consistently yields conservative additional damping
    values"."""
    assert _v(table, "EADA", train, bridge) <= _v(table, "VBI", train, bridge)


@pytest.mark.parametrize("bridge", ("B1", "B2", "B3", "B4"))
def test_eada_is_not_determined_for_the_eurostar(table, bridge):
    """"As the vehicle model of the Eurostar is not consistent with the initial assumptions of the
    EADA, Δζ_EADA is not determined for this train"."""
    assert _v(table, "EADA", "Eurostar", bridge) is None


def test_ice4_on_b3_keeps_its_documented_difference(table):
    """The paper finds the ADM "clearly non-conservative" for the ICE-4 on B3; with the default car
    order we find Δζ_VBI above the ADM's 0.653 % (docs/model.md gives 0.847 %). Pinned so that a
    change of the ICE-4 model or the calibration shows here and the docs are revisited."""
    vbi = _v(table, "VBI", "ICE-4", "B3")
    assert vbi == pytest.approx(0.847, abs=0.0015)
    assert vbi > _v(table, "ADM", "ICE-4", "B3")
