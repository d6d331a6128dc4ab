"""Train files the tests write (the vehicle-type form of :func:`adm_sim.inputs.train_files.train_from_mapping`)."""


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
