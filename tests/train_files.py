"""Train files the tests write (the vehicle-type form of :func:`adm_sim.inputs.train_files.train_from_mapping`)."""

from pathlib import Path

import adm_sim


def two_car_train_file(tmp_path, axle_kn=190.0, m_c_kg=40000.0):
    """``t.toml`` in ``tmp_path``: two cars of one vehicle type with axles of ``axle_kn`` (the masses
    say otherwise: ``loads_differ_from_masses``) and a car body of ``m_c_kg``; returns its path."""
    p = tmp_path / "t.toml"
    p.write_text(f"""name = "T"
loads_differ_from_masses = true
[vehicle_types.V]
m_c_kg = {m_c_kg}
J_c_kgm2 = 2e6
m_b_kg = 3000
J_b_kgm2 = 3000
m_w_kg = 1500
k_s_N_m = 3e5
c_s_Ns_m = 2e4
k_p_N_m = 1.6e6
c_p_Ns_m = 2e4
d_m = 26
r_m = 19
b_m = 2.5
axle_load_kN = {axle_kn}
[[composition]]
vehicle = "V"
count = 2
""")
    return p


def short_ice2_file(tmp_path, n_pc=2):
    """``ice2_short.toml`` in ``tmp_path``: the shipped ICE-2 (Table A1) with ``n_pc`` of its 12
    passenger cars between its two locomotives, named "ICE-2 short"; returns its path. Fewer steps
    for a property that holds car by car (a limiting case, a rigid bridge)."""
    ice2 = (Path(adm_sim.__file__).parent / "data" / "trains" / "ice2.toml").read_text(encoding="utf-8")
    assert ice2.count("count = 12\n") == 1 and ice2.count('name = "ICE-2"') == 1
    p = tmp_path / "ice2_short.toml"
    p.write_text(ice2.replace("count = 12\n", f"count = {n_pc}\n").replace('name = "ICE-2"', 'name = "ICE-2 short"'))
    return p
