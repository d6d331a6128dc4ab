"""Property test of the input edge (hypothesis): bridge specs, train files and speed strings,
good and broken, through ``adm-sim sweep``. Every outcome is exit 0 with finite numbers in the
JSON, or exit 2 with exactly one line on stderr naming the problem; never a traceback, never NaN.
"""

from __future__ import annotations

import json
import math

from hypothesis import HealthCheck, given, settings, strategies as st

from adm_sim.cli.sim_commands import main
from adm_sim.errors import InputError
from adm_sim.inputs.speeds import parse_speeds


NUM = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=32), st.integers(-10**6, 10**12),
                st.sampled_from(["abc", "", "1e", "--3", "nan", "inf"]))

GOOD_BRIDGE = st.fixed_dictionaries({
    "L": st.integers(8, 40), "n0": st.floats(2.0, 12.0), "mu": st.floats(5000, 40000),
    "zeta_pct": st.floats(0.3, 3.0)})


@st.composite
def bridge_specs(draw):
    spec = {k: (f"{v:.6g}" if isinstance(v, float) else str(v)) for k, v in draw(GOOD_BRIDGE).items()}
    for _ in range(draw(st.integers(0, 2))):  # break some of it
        what = draw(st.sampled_from(["value", "drop", "extra", "twice", "alias"]))
        key = draw(st.sampled_from(sorted(spec)))
        if what == "value":
            spec[key] = str(draw(NUM))
        elif what == "drop":
            spec.pop(key)
        elif what == "extra":
            spec[draw(st.sampled_from(["foo", "zeta", "EJ", "type", "n_modes"]))] = str(draw(NUM))
        elif what == "twice":
            return ",".join(f"{k}={v}" for k, v in spec.items()) + f",{key}={spec[key]}"
        else:
            alias = {"L": "span_m", "n0": "n0_hz", "mu": "mu_kg_m", "zeta_pct": "zeta"}.get(key)
            if alias:
                spec[alias] = spec[key]
    return ",".join(f"{k}={v}" for k, v in spec.items())


GOOD_SPEEDS = st.sampled_from(["200,260,320", "250:270:10", "180:300:60"])
BROKEN_SPEEDS = st.text(alphabet="0123456789:,.-naif e", min_size=0, max_size=12)


def _broken(text):
    try:
        parse_speeds(text)
    except InputError:
        return True
    return False


SPEEDS = st.one_of(GOOD_SPEEDS, BROKEN_SPEEDS.filter(_broken))


@st.composite
def train_files(draw):
    vt = dict(m_c_kg=30000, J_c_kgm2=1e6, m_b_kg=2000, J_b_kgm2=2000, m_w_kg=1500, k_s_N_m=3e5,
              c_s_Ns_m=6e3, k_p_N_m=1.6e6, c_p_Ns_m=2e4, d_m=26, r_m=19, b_m=2.5, axle_load_kN=98.1)
    comp = {"vehicle": '"PC"', "count": "3"}
    top = {"name": '"mine"'}
    for _ in range(draw(st.integers(0, 2))):
        what = draw(st.sampled_from(["field", "count", "typo", "top", "bool"]))
        if what == "field":
            vt[draw(st.sampled_from(sorted(vt)))] = draw(st.sampled_from(["-5", "1e30", '"heavy"', "nan", "0", "300"]))
        elif what == "count":
            comp["count"] = draw(st.sampled_from(["0", "true", '"8"', "1000", "2"]))
        elif what == "typo":
            comp[draw(st.sampled_from(["cout", "vehicles", "reversed"]))] = "8"
        elif what == "top":
            top[draw(st.sampled_from(["colour", "loads_differ_from_masses"]))] = draw(st.sampled_from(["true", '"yes"', "1"]))
        else:
            top["loads_differ_from_masses"] = draw(st.sampled_from(["true", "false"]))
    lines = [f"{k} = {v}" for k, v in top.items()] + ["[vehicle_types.PC]"]
    lines += [f"{k} = {v}" for k, v in vt.items()] + ["[[composition]]"] + [f"{k} = {v}" for k, v in comp.items()]
    return "\n".join(lines) + "\n"


def _check(capsys, argv, json_path):
    try:
        rc = main(argv)
    except SystemExit as exc:  # argparse's own errors (e.g. a value starting with '-'), one line, exit 2
        rc = exc.code
    out = capsys.readouterr()
    assert "Traceback" not in out.err and "Traceback" not in out.out
    warnings_ = [ln for ln in out.err.strip().splitlines() if ln.startswith("warning: ")]
    assert all("\n" not in w and "nan" not in w for w in warnings_)  # plausibility warnings: one line each
    if rc == 2:
        lines = [ln for ln in out.err.strip().splitlines() if not ln.startswith("warning: ")]
        assert len(lines) == 1 and lines[0].startswith("error: ") and "nan" not in lines[0].split(":")[1], out.err
        return None
    assert rc == 0, out.err
    data = json.loads(json_path.read_text())
    json_path.unlink()
    values = data["max_acc_m_s2"] + data["max_disp_m"]
    assert values and all(math.isfinite(x) and x >= 0 for x in values)
    return data


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(spec=bridge_specs(), speeds=SPEEDS)
def test_bridge_specs_and_speeds(tmp_path, capsys, spec, speeds):
    j = tmp_path / "out.json"
    _check(capsys, ["sweep", "--bridge", spec, "--train", "ICE-2", "--model", "mlm", "--speeds", speeds,
                    "--json", str(j), "--no-progress"], j)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(text=train_files())
def test_train_files(tmp_path, capsys, text):
    f = tmp_path / "t.toml"
    f.write_text(text)
    j = tmp_path / "out.json"
    data = _check(capsys, ["sweep", "--bridge", "B2", "--train", str(f), "--model", "mlm", "--speeds", "200,300",
                           "--json", str(j), "--no-progress"], j)
    if data is not None and "loads_differ_from_masses = true" not in text:
        assert "axle_load_kN = 98.1" in text or "axle_load_kN = 300" not in text
