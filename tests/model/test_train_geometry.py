"""Vehicle geometry that no rail vehicle has is refused with the keys named (``adm_sim.model.trains``):
bogies whose axles interleave or coincide, within a vehicle, between coupled vehicles and in a
Jacobs set. Before, a train with b_m = 9.5 m > r_m = 9 m ran through the MLM and the DIM."""

import copy
import tomllib

import numpy as np
import pytest

from adm_sim.errors import InputError
from adm_sim.inputs.train_files import load_train, train_from_mapping

TRAINS = __import__("pathlib").Path(__file__).resolve().parents[2] / "src" / "adm_sim" / "data" / "trains"


def _data(name):
    return tomllib.loads((TRAINS / name).read_text())


@pytest.mark.parametrize("name", ["ICE-2", "Eurostar", "Railjet", "ICE-4", "Eurostar-table"])
def test_paper_trains_have_strictly_increasing_axles(name):
    """Every shipped train passes the rule: axles strictly one after another, no two closer than
    the train's shortest bogie wheelbase (2.3 m for the ICE-4, 2.5 .. 3 m for the others)."""
    t = load_train(name)
    gaps = np.diff(t.axle_offsets_m)
    assert gaps.min() >= min(v.b_m for v in t.vehicle_types.values()) - 1e-9


def test_interleaving_bogies_of_one_vehicle():
    d = _data("ice2.toml")
    d["vehicle_types"]["PC"].update(r_m=9.0, b_m=9.5)
    with pytest.raises(InputError, match=r"vehicle_types\.PC\.b_m: bogie wheelbase 9\.5 m is not shorter than "
                                         r"the pivot distance r_m 9 m.*allowed b_m < r_m"):
        train_from_mapping(d, "t.toml")


def test_coinciding_axles_of_coupled_vehicles():
    """r_m + b_m = d_m puts the last axle of one car on the first axle of the next."""
    d = _data("ice2.toml")
    d["vehicle_types"]["PC"].update(d_m=21.5, r_m=19.0, b_m=2.5)
    with pytest.raises(InputError, match=r"vehicle_types\.PC\.r_m: 19 m plus wheelbase b_m 2\.5 m is not shorter "
                                         r"than the vehicle length d_m 21\.5 m.*allowed r_m \+ b_m < d_m"):
        train_from_mapping(d, "t.toml")


def test_interleaving_jacobs_bogies():
    """Jacobs cars 2 m long carry bogies of 3 m wheelbase: the bogies' axles interleave."""
    d = copy.deepcopy(_data("eurostar.toml"))
    d["vehicle_types"]["PC 2-8"]["d_m"] = 2.0
    d["loads_differ_from_masses"] = True
    with pytest.raises(InputError, match=r"t\.toml: the axles of bogies 'PC 2-8' \(pivot .* m\) and 'PC 2-8' "
                                         r"\(pivot .* m\) coincide or interleave \(-1\.000 m apart\)"):
        train_from_mapping(d, "t.toml")
