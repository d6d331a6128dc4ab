"""Bad input at every entry point: one line ``error: ...`` naming what was typed (the option, the
spec key, the file and key), the value, the unit and the allowed range; exit code 2; nothing written,
nothing overwritten, no stub left behind. Each case states the exact line.

Entry points: ``adm-sim`` (sweep options, bridge specs, bridge files, train files, trains, bridges,
salvage), ``adm-calib`` (calibrate, table4, recommend, study, study-fit) and
``launch_scripts/replay.py``. ``{t}`` is a folder holding the input files written by
:func:`make_inputs` (and a few earlier outputs that must survive).
"""

from __future__ import annotations

import importlib.util
import json
from collections import Counter
from pathlib import Path

import pytest

from adm_calib.calib_commands import main as calib_main
from adm_sim.cli.sim_commands import main as sim_main


ROOT = Path(__file__).resolve().parents[2]

# ---------------------------------------------------------------- the input files of the cases

TRAIN_OK = """name = "mine"
[vehicle_types.PC]
m_c_kg = 30000
J_c_kgm2 = 1e6
m_b_kg = 2000
J_b_kgm2 = 2000
m_w_kg = 1500
k_s_N_m = 3e5
c_s_Ns_m = 6e3
k_p_N_m = 1.6e6
c_p_Ns_m = 2e4
d_m = 26
r_m = 19
b_m = 2.5
axle_load_kN = 98.1
[[composition]]
vehicle = "PC"
count = 3
"""
JACOBS_OK = """name = "jacobs"
[vehicle_types.E]
m_c_kg = 30000
J_c_kgm2 = 1e6
m_b_kg = 2000
J_b_kgm2 = 2000
m_w_kg = 1500
k_s_N_m = 3e5
c_s_Ns_m = 6e3
k_p_N_m = 1.6e6
c_p_Ns_m = 2e4
d_m = 20
r_m = 15
b_m = 2.5
axle_load_kN = 98.1
[vehicle_types.M]
m_c_kg = 20000
J_c_kgm2 = 1e6
m_b_kg = 2000
J_b_kgm2 = 2000
m_w_kg = 1500
k_s_N_m = 3e5
c_s_Ns_m = 6e3
k_p_N_m = 1.6e6
c_p_Ns_m = 2e4
d_m = 18
b_m = 2.5
axle_load_kN = 98.1
[[composition]]
jacobs_set = ["E", "M", "E"]
bogies = ["E", "M", "M", "E"]
axle_loads_kN = [100, 100, 100, 100]
"""
BRIDGE_OK = "L = 15\nn0 = 8.26\nmu = 19042\nzeta_pct = 1.85\n"
TRAIN_EDITS = {  # file -> (text to replace in TRAIN_OK, replacement)
    "t_bool": ("m_c_kg = 30000", "m_c_kg = true"),
    "t_str": ("m_c_kg = 30000", 'm_c_kg = "30000"'),
    "t_cnt": ("count = 3", "count = 3.0"),
    "t_cntq": ("count = 3", 'count = "8"'),
    "t_cout": ("count = 3", "cout = 8"),
    "t_vl": ('vehicle = "PC"', 'vehicle = ["PC"]'),
    "t_vt": ("[vehicle_types.PC]\n", "[vehicle_types]\nQ = 5\n[vehicle_types.PC]\n"),
    "t_al": ("axle_load_kN = 98.1", "axle_load_kN = [98.1, 98.1, 98.1]"),
    "t_al3": ("axle_load_kN = 98.1", "axle_load_kN = true"),
    "t_al4": ("axle_load_kN = 98.1", 'axle_load_kN = "98.1"'),
    "t_al300": ("axle_load_kN = 98.1", "axle_load_kN = 300"),
    "t_name": ('name = "mine"', "name = 5"),
    "t_desc": ('name = "mine"', 'name = "mine"\ndescription = 5'),
    "t_pt": ('name = "mine"', 'name = "mine"\npaper_train = "TGV"'),
    "t_top": ('name = "mine"', 'name = "mine"\ncolour = "red"'),
    "t_rb": ("r_m = 19", "r_m = 25"),
    "t_comp": ('[[composition]]\nvehicle = "PC"\ncount = 3\n', '[composition]\nvehicle = "PC"\n'),
    "t_ld": ('name = "mine"', 'name = "mine"\nloads_differ_from_masses = 1'),
    "t_nan": ("k_s_N_m = 3e5", "k_s_N_m = nan"),
    "t_both": ('vehicle = "PC"', 'vehicle = "PC"\njacobs_set = ["PC", "PC"]'),
}
JACOBS_EDITS = {
    "j_setl": ('jacobs_set = ["E", "M", "E"]', 'jacobs_set = [["E"], "M", "E"]'),
    "j_loads": ("axle_loads_kN = [100, 100, 100, 100]", "axle_loads_kN = 100"),
    "j_rev": ("axle_loads_kN = [100, 100, 100, 100]", 'axle_loads_kN = [100, 100, 100, 100]\nreversed = "false"'),
    "j_endM": ('jacobs_set = ["E", "M", "E"]', 'jacobs_set = ["M", "M", "E"]'),
    "j_count": ("axle_loads_kN = [100, 100, 100, 100]", "axle_loads_kN = [100, 100, 100, 100]\ncount = 2"),
    "j_nob": ('bogies = ["E", "M", "M", "E"]\n', ""),
}
BRIDGE_FILES = {
    "b_bool": BRIDGE_OK.replace("L = 15", "L = true"),
    "b_str": BRIDGE_OK.replace("L = 15", 'L = "15"'),
    "b_nm": BRIDGE_OK + "n_modes = 3.7\n",
    "b_nmb": BRIDGE_OK + "n_modes = true\n",
    "b_name": BRIDGE_OK + "name = 5\n",
    "b_tab": BRIDGE_OK + "[extra]\na = 1\n",
    "b_typ": BRIDGE_OK + 'type = "cfb"\n',
    "b_bad": "L = 15\nn0 = \n",
    "b_nan": BRIDGE_OK.replace("L = 15", "L = nan"),
    "b_dm": BRIDGE_OK + "damping_model = 3\n",
    "b_tl": BRIDGE_OK + 'class = ["cfb"]\n',
    "b_lst": BRIDGE_OK.replace("L = 15", "L = [15]"),
    "b_empty": "",
    "b_dup": BRIDGE_OK + "span_m = 20\n",
}
RECORD = {"bridge": "L10-f1-mu1", "train": "ICE-2", "span_m": 10.0, "n0_hz": 8.0, "mu_t_m": 18.88,
          "mass_function": "mu1", "freq_index": 1, "bridge_type": "cfb", "zeta_pct": 2.2, "status": "ok",
          "delta_zeta_vbi_pct": 0.5, "dim_is_local_max": True, "mlm_max_at_range_end": False}
RECORD_EDITS = {
    "r_nan": {"delta_zeta_vbi_pct": float("nan")},
    "r_inf": {"delta_zeta_vbi_pct": float("inf")},
    "r_str": {"delta_zeta_vbi_pct": "big"},
    "r_n0nan": {"n0_hz": float("nan")},
    "r_mf": {"mass_function": "mu9"},
    "r_flag": {"dim_is_local_max": "yes"},
    "r_status": {"status": 1},
    "r_list": {"bridge": ["L10"]},
    "r_ok": {},
    "r_peak": {"mlm_peak": "high"},
}


def make_inputs(t):
    """Write every bad (and a few good) input file of the hunt into the folder ``t``."""
    t = Path(t)
    for name, (old, new) in TRAIN_EDITS.items():
        assert old in TRAIN_OK, name
        (t / f"{name}.toml").write_text(TRAIN_OK.replace(old, new, 1))
    for name, (old, new) in JACOBS_EDITS.items():
        assert old in JACOBS_OK, name
        (t / f"{name}.toml").write_text(JACOBS_OK.replace(old, new, 1))
    for name, text in BRIDGE_FILES.items():
        (t / f"{name}.toml").write_text(text)
    (t / "b_bin.toml").write_bytes(b"\xff\xfe\x00L=15")
    for name, edit in RECORD_EDITS.items():
        (t / f"{name}.jsonl").write_text(json.dumps({**RECORD, **edit}) + "\n")
    (t / "r_empty.jsonl").write_text("")
    (t / "r_garb.jsonl").write_text("garbage\n{}\n")
    (t / "r_nob.jsonl").write_text('{"a": 1}\n')
    from mcap.writer import Writer

    with open(t / "run.mcap", "wb") as f:
        w = Writer(f)
        w.start()
        w.finish()
    (t / "trunc.mcap").write_bytes((t / "run.mcap").read_bytes()[:12])  # the magic and 4 bytes
    for name in ("old.json", "old.mcap", "old.rrd"):
        (t / name).write_text("earlier output\n")
    for d in ("old4", "oldfit"):
        (t / d).mkdir()
    (t / "old4" / "table4.txt").write_text("earlier output\n")
    (t / "oldfit" / "lower_bounds_fit.txt").write_text("earlier output\n")


#: (entry point, argv, the exact stderr line). Sweeps get ``--no-progress --speeds 250,260,270``
#: unless they give --speeds: every case is refused before any computation.
CASES = [
    ('adm-sim sweep', ['sweep', '--delta-zeta-pct', 'nan'],
     "error: --delta-zeta-pct: 'nan' % is not finite; allowed [-1.85, 20] %"),
    ('adm-sim sweep', ['sweep', '--delta-zeta-pct', 'inf'],
     "error: --delta-zeta-pct: 'inf' % is not finite; allowed [-1.85, 20] %"),
    ('adm-sim sweep', ['sweep', '--delta-zeta-pct', '25'],
     'error: --delta-zeta-pct: 25 % is out of range; allowed [-1.85, 20] %'),
    ('adm-sim sweep', ['sweep', '--delta-zeta-pct', '-2'],
     'error: --delta-zeta-pct: -2 % is out of range; allowed [-1.85, 20] %'),
    ('adm-sim sweep', ['sweep', '--delta-zeta-pct', 'abc'],
     "error: --delta-zeta-pct: 'abc' is not a number; allowed [-1.85, 20] %"),
    ('adm-sim sweep', ['sweep', '--steps-per-period', 'nan'],
     "error: --steps-per-period: 'nan' steps is not finite; allowed [4, 10000] steps"),
    ('adm-sim sweep', ['sweep', '--steps-per-period', '3'],
     'error: --steps-per-period: 3 steps is out of range; allowed [4, 10000] steps'),
    ('adm-sim sweep', ['sweep', '--steps-per-period', '1e9'],
     'error: --steps-per-period: 1e+09 steps is out of range; allowed [4, 10000] steps'),
    ('adm-sim sweep', ['sweep', '--speeds', '200,250:300'],
     "error: --speeds: '200,250:300' mixes ':' and ','; give start:stop:step or a comma list (km/h)"),
    ('adm-sim sweep', ['sweep', '--speeds', '160:350,5'],
     "error: --speeds: '160:350,5' mixes ':' and ','; give start:stop:step or a comma list (km/h)"),
    ('adm-sim sweep', ['sweep', '--speeds', '160::1'],
     "error: --speeds: '160::1' needs start <= stop and step > 0 (km/h)"),
    ('adm-sim sweep', ['sweep', '--speeds', ':350'],
     "error: --speeds: ':350' is not start:stop:step or a comma list (km/h)"),
    ('adm-sim sweep', ['sweep', '--speeds', '160:350:1:2'],
     "error: --speeds: '160:350:1:2' is not start:stop:step or a comma list (km/h)"),
    ('adm-sim sweep', ['sweep', '--speeds', '0:10:1'],
     "error: --speeds: '0:10:1' gives 0 km/h; allowed speeds in [1, 600] km/h"),
    ('adm-sim sweep', ['sweep', '--speeds', '600.1'],
     "error: --speeds: '600.1' gives 600.1 km/h; allowed speeds in [1, 600] km/h"),
    ('adm-sim sweep', ['sweep', '--speeds', ',,'],
     "error: --speeds: ',,' is not start:stop:step or a comma list (km/h)"),
    ('adm-sim sweep', ['sweep', '--speeds', '1e3'],
     "error: --speeds: '1e3' gives 1000 km/h; allowed speeds in [1, 600] km/h"),
    ('adm-sim sweep', ['sweep', '--speeds', '160:350:nan'],
     "error: --speeds: '160:350:nan' holds nan; every speed and step must be a finite number (km/h)"),
    ('adm-sim sweep', ['sweep', '--speeds', '160:350:-1'],
     "error: --speeds: '160:350:-1' needs start <= stop and step > 0 (km/h)"),
    ('adm-sim sweep', ['sweep', '--speeds', '0x10'],
     "error: --speeds: '0x10' is not start:stop:step or a comma list (km/h)"),
    ('adm-sim sweep', ['sweep', '--speeds', '160:350:0.0001'],
     "error: --speeds: '160:350:0.0001' gives 1900001 speeds; allowed at most 20000 speeds (speeds of one run or "
     "check; bounded work)"),
    ('adm-sim sweep', ['sweep', '--model', 'fem'],
     "error: adm-sim sweep: argument --model: invalid choice: 'fem' (choose from 'mlm', 'dim')"),
    ('adm-sim sweep', ['sweep', '--json', '{t}/nodir/r.json'],
     "error: --json: '{t}/nodir/r.json': the directory '{t}/nodir' does not exist"),
    ('adm-sim sweep', ['sweep', '--json', '{t}'],
     "error: --json: '{t}' is a directory; give a file name"),
    ('adm-sim sweep', ['sweep', '--json', '{t}/old.json'],
     "error: --json: '{t}/old.json' exists; use --overwrite to replace it"),
    ('adm-sim sweep', ['sweep', '--plot', '{t}/p.jpg'],
     "error: --plot: '{t}/p.jpg' must end in .png"),
    ('adm-sim sweep', ['sweep', '--json', '{t}/same.png', '--plot', '{t}/same.png'],
     "error: --plot: '{t}/same.png' is the --json file; give two different files"),
    ('adm-sim sweep', ['sweep', '--train', 'TGV'],
     "error: --train: 'TGV' is unknown; allowed ICE-2, Eurostar, Railjet, ICE-4, Eurostar-table, HSLM-A1 .. HSLM-A10, or a .toml train file"),
    ('adm-sim sweep', ['sweep', '--train', ''],
     "error: --train: '' is unknown; allowed ICE-2, Eurostar, Railjet, ICE-4, Eurostar-table, HSLM-A1 .. HSLM-A10, or a .toml train file"),
    ('adm-sim sweep', ['sweep', '--train', '{t}/missing.toml'],
     "error: train file '{t}/missing.toml': cannot read (No such file or directory)"),
    ('adm-sim sweep', ['sweep', '--bridge', 'B5'],
     "error: --bridge: 'B5' is neither a named bridge (B1, B2, B3, B4), a spec like L=15,n0=8.26,mu=19042,zeta_pct=1.85, nor a file"),
    ('adm-sim sweep', ['sweep', '--bridge', '{t}'],
     "error: --bridge: '{t}' is neither a named bridge (B1, B2, B3, B4), a spec like L=15,n0=8.26,mu=19042,zeta_pct=1.85, nor a file"),
    ('bridge spec', ['sweep', '--bridge', 'L=15,n0=8.26,mu=19042,zeta_pct=1.85,type=cfb'],
     "error: bridge spec: 'zeta_pct' and 'type' both give the damping; give one (class=cfb|sc classes a bridge of given damping for the lower-bound functions)"),
    ('bridge spec', ['sweep', '--bridge', 'L=15,n0=8.26,mu=19042,zeta=0.0185,type=cfb'],
     "error: bridge spec: 'zeta' and 'type' both give the damping; give one (class=cfb|sc classes a bridge of given damping for the lower-bound functions)"),
    ('bridge spec', ['sweep', '--bridge', 'L=15,n0=8.26,mu=19042,type=sc,class=cfb'],
     "error: bridge spec: 'type' already classes the bridge; drop 'class'"),
    ('bridge spec', ['sweep', '--bridge', 'L=15,n0=8.26,mu=19042,zeta_pct=1.85,class=steel'],
     "error: bridge spec.class: 'steel' is not allowed; allowed 'cfb' or 'sc'"),
    ('bridge spec', ['sweep', '--bridge', 'L=15,n0=8.26,mu=19042,type=xyz'],
     "error: bridge spec.type: 'xyz' is not allowed; allowed 'cfb' or 'sc'"),
    ('bridge spec', ['sweep', '--bridge', 'L=15,n0=8.26,mu=19042,zeta_pct=1.85,zeta=0.0185'],
     "error: bridge spec: 'zeta_pct' and 'zeta' both give the damping; give one"),
    ('bridge spec', ['sweep', '--bridge', 'L=15,L=20,n0=8.26,mu=19042,zeta_pct=1.85'],
     "error: bridge spec: 'L' is given twice ('15' and '20'); give it once"),
    ('bridge spec', ['sweep', '--bridge', 'L=15,span_m=20,n0=8.26,mu=19042,zeta_pct=1.85'],
     "error: bridge spec: 'L' and 'span_m' give the same quantity twice; give it once"),
    ('bridge spec', ['sweep', '--bridge', 'L=15,n0=8.26,mu=19.042,zeta_pct=1.85'],
     'error: bridge spec.mu: 19.042 kg/m is out of range; allowed [100, 1e+06] kg/m'),
    ('bridge spec', ['sweep', '--bridge', 'L=15,n0=8.26,mu=19042,zeta=1.85'],
     'error: bridge spec.zeta: 1.85 - (fraction) is out of range; allowed [0, 0.2] - (fraction)'),
    ('bridge spec', ['sweep', '--bridge', 'L=15,n0=8.26,mu=19042,zeta_pct=1.85,n_modes=3.5'],
     "error: bridge spec.n_modes: '3.5' is not an integer; allowed integer in [1, 20]"),
    ('bridge spec', ['sweep', '--bridge', 'L=15,n0=8.26,mu=19042,zeta_pct=1.85,n_modes=0'],
     'error: bridge spec.n_modes: 0 is out of range; allowed integer in [1, 20]'),
    ('bridge spec', ['sweep', '--bridge', 'L=15,n0=8.26,mu=19042,zeta_pct=1.85,n_modes=true'],
     "error: bridge spec.n_modes: 'true' is not an integer; allowed integer in [1, 20]"),
    ('bridge spec', ['sweep', '--bridge', 'L=15,n0=8.26,mu=19042,zeta_pct=1.85,damping_model=foo'],
     "error: bridge spec.damping_model: 'foo' is not allowed; allowed 'rayleigh' or 'modal'"),
    ('bridge spec', ['sweep', '--bridge', 'L=15,EJ=1e20,mu=19042,zeta_pct=1.85'],
     'error: bridge spec.EJ: 1e+20 N m^2 gives n0 = 5.059e+05 Hz with L = 15 m and mu = 19042 kg/m (Eq. 18); allowed n0 in [0.5, 100] Hz'),
    ('bridge spec', ['sweep', '--bridge', 'L=15,EJ=-1,mu=19042,zeta_pct=1.85'],
     'error: bridge spec.EJ: -1 N m^2 is out of range; allowed > 0 N m^2'),
    ('bridge spec', ['sweep', '--bridge', 'L=15,n0=8.26,EJ=2e10,mu=19042,zeta_pct=1.85'],
     'error: bridge spec: give either n0 (Hz) or EJ (N m^2), not both'),
    ('bridge spec', ['sweep', '--bridge', 'L=15,mu=19042,zeta_pct=1.85'],
     'error: bridge spec: missing stiffness: give n0 (Hz, 0.5..100) or EJ (N m^2, > 0)'),
    ('bridge spec', ['sweep', '--bridge', 'L=15,n0=8.26,zeta_pct=1.85'],
     'error: bridge spec: missing key mu (mass per length, kg/m)'),
    ('bridge spec', ['sweep', '--bridge', 'n0=8.26,mu=19042,zeta_pct=1.85'],
     'error: bridge spec: missing key L (span, m)'),
    ('bridge spec', ['sweep', '--bridge', 'L=15,n0=8.26,mu=19042'],
     'error: bridge spec: missing damping: give zeta_pct (%, 0..20), zeta (fraction, 0..0.2) or type=cfb|sc (Table 2 damping)'),
    ('bridge spec', ['sweep', '--bridge', '=15'],
     "error: bridge spec: unknown key ''; allowed EJ, EJ_Nm2, L, bridge_type, class, damping_model, damping_ratio, mass_per_length_kg_m, mu, mu_kg_m, n0, n0_hz, n_modes, name, span_m, spans, type, zeta, zeta_pct"),
    ('bridge spec', ['sweep', '--bridge', 'l=15,n0=8.26,mu=19042,zeta_pct=1.85'],
     "error: bridge spec: unknown key 'l'; allowed EJ, EJ_Nm2, L, bridge_type, class, damping_model, damping_ratio, mass_per_length_kg_m, mu, mu_kg_m, n0, n0_hz, n_modes, name, span_m, spans, type, zeta, zeta_pct"),
    ('bridge spec', ['sweep', '--bridge', 'L=15 m,n0=8.26,mu=19042,zeta_pct=1.85'],
     "error: bridge spec.L: '15 m' is not a number; allowed [1, 150] m"),
    ('bridge spec', ['sweep', '--bridge', 'L=nan,n0=8,mu=19042,zeta_pct=1'],
     "error: bridge spec.L: 'nan' m is not finite; allowed [1, 150] m"),
    ('bridge spec', ['sweep', '--bridge', 'L=1e1000,n0=8.26,mu=19042,zeta_pct=1.85'],
     "error: bridge spec.L: '1e1000' m is not finite; allowed [1, 150] m"),
    ('bridge spec', ['sweep', '--bridge', 'L=15,n0=0.4,mu=19042,zeta_pct=1'],
     'error: bridge spec.n0: 0.4 Hz is out of range; allowed [0.5, 100] Hz'),
    ('bridge spec', ['sweep', '--bridge', 'L=15,n0=8.26,mu=19042,zeta_pct=21'],
     'error: bridge spec.zeta_pct: 21 % is out of range; allowed [0, 20] %'),
    ('bridge spec', ['sweep', '--bridge', 'L=15,n0=8.26,mu=19042,zeta_pct=1.85,L15'],
     "error: bridge spec: 'L15' is not key=value (e.g. L=15,n0=8.26,mu=19042,zeta_pct=1.85)"),
    ('bridge file', ['sweep', '--bridge', '{t}/b_bool.toml'],
     'error: bridge file b_bool.toml.L: true is a boolean, not a number; allowed [1, 150] m'),
    ('bridge file', ['sweep', '--bridge', '{t}/b_str.toml'],
     "error: bridge file b_str.toml.L: '15' is a string, not a number (write it without quotes); allowed [1, 150] m"),
    ('bridge file', ['sweep', '--bridge', '{t}/b_nm.toml'],
     'error: bridge file b_nm.toml.n_modes: 3.7 is not an integer; allowed integer in [1, 20]'),
    ('bridge file', ['sweep', '--bridge', '{t}/b_nmb.toml'],
     'error: bridge file b_nmb.toml.n_modes: true is not an integer; allowed integer in [1, 20]'),
    ('bridge file', ['sweep', '--bridge', '{t}/b_name.toml'],
     'error: bridge file b_name.toml.name: 5 must be text in quotes'),
    ('bridge file', ['sweep', '--bridge', '{t}/b_tab.toml'],
     "error: bridge file b_tab.toml: unknown key 'extra'; allowed EJ, EJ_Nm2, L, bridge_type, class, damping_model, damping_ratio, mass_per_length_kg_m, mu, mu_kg_m, n0, n0_hz, n_modes, name, span_m, spans, type, zeta, zeta_pct"),
    ('bridge file', ['sweep', '--bridge', '{t}/b_typ.toml'],
     "error: bridge file b_typ.toml: 'zeta_pct' and 'type' both give the damping; give one (class=cfb|sc classes a bridge of given damping for the lower-bound functions)"),
    ('bridge file', ['sweep', '--bridge', '{t}/b_bad.toml'],
     "error: bridge file '{t}/b_bad.toml': not valid TOML (Invalid value (at line 2, column 6))"),
    ('bridge file', ['sweep', '--bridge', '{t}/b_nan.toml'],
     'error: bridge file b_nan.toml.L: nan m is not finite; allowed [1, 150] m'),
    ('bridge file', ['sweep', '--bridge', '{t}/b_dm.toml'],
     'error: bridge file b_dm.toml.damping_model: 3 must be text in quotes'),
    ('bridge file', ['sweep', '--bridge', '{t}/b_tl.toml'],
     "error: bridge file b_tl.toml.class: ['cfb'] must be text in quotes"),
    ('bridge file', ['sweep', '--bridge', '{t}/b_lst.toml'],
     'error: bridge file b_lst.toml.L: [15] is not a number; allowed [1, 150] m'),
    ('bridge file', ['sweep', '--bridge', '{t}/b_empty.toml'],
     'error: bridge file b_empty.toml: missing key L (span, m)'),
    ('bridge file', ['sweep', '--bridge', '{t}/b_dup.toml'],
     "error: bridge file b_dup.toml: 'L' and 'span_m' give the same quantity twice; give it once"),
    ('bridge file', ['sweep', '--bridge', '{t}/b_bin.toml'],
     "error: bridge file '{t}/b_bin.toml': not UTF-8 text (byte 0xff at offset 0); give a text file"),
    ('train file', ['sweep', '--train', '{t}/t_bool.toml'],
     'error: t_bool.toml: vehicle_types.PC.m_c_kg: true is a boolean, not a number; allowed [1, 500000] kg'),
    ('train file', ['sweep', '--train', '{t}/t_str.toml'],
     "error: t_str.toml: vehicle_types.PC.m_c_kg: '30000' is a string, not a number (write it without quotes); allowed [1, 500000] kg"),
    ('train file', ['sweep', '--train', '{t}/t_cnt.toml'],
     'error: t_cnt.toml: composition[0].count: 3.0 is not an integer; allowed integer in [1, 100]'),
    ('train file', ['sweep', '--train', '{t}/t_cntq.toml'],
     "error: t_cntq.toml: composition[0].count: '8' must be an integer without quotes; allowed integer in [1, 100]"),
    ('train file', ['sweep', '--train', '{t}/t_cout.toml'],
     "error: t_cout.toml: composition[0]: unknown key(s) 'cout'; allowed vehicle, count"),
    ('train file', ['sweep', '--train', '{t}/t_vl.toml'],
     "error: t_vl.toml: composition[0]: vehicle type ['PC'] not defined; defined: PC"),
    ('train file', ['sweep', '--train', '{t}/t_vt.toml'],
     'error: t_vt.toml: vehicle_types.Q: 5 is not a table; write [vehicle_types.Q] with its fields'),
    ('train file', ['sweep', '--train', '{t}/t_al.toml'],
     'error: t_al.toml: vehicle_types.PC.axle_load_kN: [98.1, 98.1, 98.1] must be one value or [front, rear] (kN)'),
    ('train file', ['sweep', '--train', '{t}/t_al3.toml'],
     'error: t_al3.toml: vehicle_types.PC.axle_load_kN: true is a boolean, not a number; allowed [1, 500] kN'),
    ('train file', ['sweep', '--train', '{t}/t_al4.toml'],
     "error: t_al4.toml: vehicle_types.PC.axle_load_kN: '98.1' is a string, not a number (write it without quotes); allowed [1, 500] kN"),
    ('train file', ['sweep', '--train', '{t}/t_al300.toml'],
     'error: t_al300.toml: F PC (per axle): axle load 300 kN disagrees with the masses, (m_c + 2 m_b + 4 m_w) g / 4 = 98.1 kN (allowed within 0.5 %); fix the loads or masses, or set loads_differ_from_masses = true if this is meant'),
    ('train file', ['sweep', '--train', '{t}/t_name.toml'],
     'error: t_name.toml: name: 5 must be a non-empty string'),
    ('train file', ['sweep', '--train', '{t}/t_desc.toml'],
     'error: t_desc.toml: description: 5 must be text in quotes'),
    ('train file', ['sweep', '--train', '{t}/t_pt.toml'],
     "error: t_pt.toml: paper_train: 'TGV' is not a train of the paper; allowed ICE-2, Eurostar, Railjet, ICE-4 (or omit it)"),
    ('train file', ['sweep', '--train', '{t}/t_top.toml'],
     "error: t_top.toml: unknown key(s) 'colour'; allowed name, description, source, paper_train, vehicle_types, composition, loads_differ_from_masses"),
    ('train file', ['sweep', '--train', '{t}/t_rb.toml'],
     'error: t_rb.toml: vehicle_types.PC.r_m: 25 m plus wheelbase b_m 2.5 m is not shorter than the vehicle length d_m 26 m: '
     'axles of coupled vehicles would coincide or overlap; allowed r_m + b_m < d_m'),
    ('train file', ['sweep', '--train', '{t}/t_comp.toml'],
     'error: t_comp.toml: missing [[composition]] entries'),
    ('train file', ['sweep', '--train', '{t}/t_ld.toml'],
     'error: t_ld.toml: loads_differ_from_masses: 1 must be true or false'),
    ('train file', ['sweep', '--train', '{t}/t_nan.toml'],
     'error: t_nan.toml: vehicle_types.PC.k_s_N_m: nan N/m is not finite; allowed [1, 1e+10] N/m'),
    ('train file', ['sweep', '--train', '{t}/t_both.toml'],
     "error: t_both.toml: composition[0]: has both 'vehicle' and 'jacobs_set'; give one per entry"),
    ('train file', ['sweep', '--train', '{t}/j_setl.toml'],
     "error: j_setl.toml: composition[0]: vehicle type ['E'] not defined; defined: E, M"),
    ('train file', ['sweep', '--train', '{t}/j_loads.toml'],
     'error: j_loads.toml: composition[0].axle_loads_kN: 100 must be a list of one load per bogie (kN)'),
    ('train file', ['sweep', '--train', '{t}/j_rev.toml'],
     "error: j_rev.toml: composition[0].reversed: 'false' must be true or false"),
    ('train file', ['sweep', '--train', '{t}/j_endM.toml'],
     "error: j_endM.toml: composition[0]: end car 'M' needs r_m (m)"),
    ('train file', ['sweep', '--train', '{t}/j_count.toml'],
     "error: j_count.toml: composition[0]: unknown key(s) 'count'; allowed jacobs_set, bogies, axle_loads_kN, reversed"),
    ('train file', ['sweep', '--train', '{t}/j_nob.toml'],
     "error: j_nob.toml: composition[0]: 'bogies' and 'axle_loads_kN' need len(jacobs_set) + 1 = 4 entries"),
    ('adm-sim trains/bridges/salvage', ['trains', '--train', ''],
     "error: --train: '' is empty; give a train name or a TOML train file (or omit --train for all)"),
    ('adm-sim trains/bridges/salvage', ['trains', '--train', 'TGV'],
     "error: --train: 'TGV' is unknown; allowed ICE-2, Eurostar, Railjet, ICE-4, Eurostar-table, HSLM-A1 .. HSLM-A10, or a .toml train file"),
    ('adm-sim trains/bridges/salvage', ['trains', '--train', '{t}/t_al300.toml', '--check'],
     'error: t_al300.toml: F PC (per axle): axle load 300 kN disagrees with the masses, (m_c + 2 m_b + 4 m_w) g / 4 = 98.1 kN (allowed within 0.5 %); fix the loads or masses, or set loads_differ_from_masses = true if this is meant'),
    ('adm-sim trains/bridges/salvage', ['bridges', '--field', 'x'],
     'error: adm-sim: unrecognized arguments: x'),
    ('adm-sim trains/bridges/salvage', ['salvage', '{t}/missing.mcap', '{t}/o.mcap'],
     "error: salvage SRC: '{t}/missing.mcap' is not a file"),
    ('adm-sim trains/bridges/salvage', ['salvage', '{t}/t_bool.toml', '{t}/o.mcap'],
     "error: salvage SRC: '{t}/t_bool.toml' is not an MCAP file (it does not start with the MCAP magic bytes)"),
    ('adm-sim trains/bridges/salvage', ['salvage', '{t}', '{t}/o.mcap'],
     "error: salvage SRC: '{t}' is not a file"),
    ('adm-sim trains/bridges/salvage', ['salvage', '{t}/run.mcap', '{t}/nodir/o.mcap'],
     "error: salvage DST: '{t}/nodir/o.mcap': the directory '{t}/nodir' does not exist"),
    ('adm-sim trains/bridges/salvage', ['salvage', '{t}/run.mcap', '{t}/o.txt'],
     "error: salvage DST: '{t}/o.txt' must end in .mcap"),
    ('adm-sim trains/bridges/salvage', ['salvage', '{t}/run.mcap', '{t}/run.mcap', '--overwrite'],
     "error: salvage DST: '{t}/run.mcap' is SRC; give another file"),
    ('adm-sim trains/bridges/salvage', ['salvage', '{t}/run.mcap', '{t}/old.mcap'],
     "error: salvage DST: '{t}/old.mcap' exists; use --overwrite to replace it"),
    ('adm-sim trains/bridges/salvage', ['frobnicate'],
     "error: adm-sim: argument cmd: invalid choice: 'frobnicate' (choose from 'sweep', 'check', 'trains', 'bridges', 'compile', 'salvage')"),
    ('adm-calib calibrate', ['calibrate', '--bridge', 'B1', '--train', 'ICE-2', '--steps-per-period', 'nan'],
     "error: --steps-per-period: 'nan' steps is not finite; allowed [4, 10000] steps"),
    ('adm-calib calibrate', ['calibrate', '--bridge', 'B1', '--train', 'ICE-2', '--speeds', '250,260'],
     'error: --speeds: need at least 3 speeds (km/h), got 2'),
    ('adm-calib calibrate', ['calibrate', '--bridge', 'B1', '--train', 'ICE-2', '--speeds', '300:nan:1'],
     "error: --speeds: '300:nan:1' holds nan; every speed and step must be a finite number (km/h)"),
    ('adm-calib calibrate', ['calibrate', '--bridge', 'B1', '--train', 'ICE-2', '--speeds', '250,263,200'],
     "error: --speeds: '250,263,200' must increase strictly (km/h), e.g. 200,250,263"),
    ('adm-calib calibrate', ['calibrate', '--bridge', 'B1', '--train', 'ICE-2', '--dim-grid', 'coarse'],
     "error: argument --dim-grid: invalid choice: 'coarse' (choose from 'paper', 'window', 'full')"),
    ('adm-calib calibrate', ['calibrate', '--bridge', 'B1', '--train', 'TGV'],
     "error: --train: 'TGV' is unknown; allowed ICE-2, Eurostar, Railjet, ICE-4, Eurostar-table, HSLM-A1 .. HSLM-A10, or a .toml train file"),
    ('adm-calib calibrate', ['calibrate', '--bridge', 'B9', '--train', 'ICE-2'],
     "error: --bridge: 'B9' is neither a named bridge (B1, B2, B3, B4), a spec like L=15,n0=8.26,mu=19042,zeta_pct=1.85, nor a file"),
    ('adm-calib calibrate', ['calibrate', '--bridge', 'L=15,n0=8.26,mu=19042,zeta_pct=1.85,type=cfb', '--train', 'ICE-2'],
     "error: bridge spec: 'zeta_pct' and 'type' both give the damping; give one (class=cfb|sc classes a bridge of given damping for the lower-bound functions)"),
    ('adm-calib calibrate', ['calibrate', '--bridge', 'B1', '--train', 'ICE-2', '--json', '{t}/nodir/x.json'],
     "error: --json: '{t}/nodir/x.json': the directory '{t}/nodir' does not exist"),
    ('adm-calib calibrate', ['calibrate', '--bridge', 'B1', '--train', 'ICE-2', '--json', '{t}/x.txt'],
     "error: --json: '{t}/x.txt' must end in .json"),
    ('adm-calib calibrate', ['calibrate', '--bridge', 'B1', '--train', 'ICE-2', '--plot', '{t}/x.jpg'],
     "error: --plot: '{t}/x.jpg' must end in .png"),
    ('adm-calib calibrate', ['calibrate', '--bridge', 'B1', '--train', 'ICE-2', '--json', '{t}/old.json'],
     "error: --json: '{t}/old.json' exists; use --overwrite to replace it"),
    ('adm-calib calibrate', ['calibrate', '--bridge', 'B1'],
     'error: the following arguments are required: --train'),
    ('adm-calib calibrate', ['frobnicate'],
     "error: argument command: invalid choice: 'frobnicate' (choose from 'calibrate', 'table4', 'recommend', 'study', 'study-fit', 'check')"),
    ('adm-calib table4', ['table4', '--out', '{t}/t4', '--bridges', 'B1,B9'],
     "error: --bridges: 'B9' is not a named bridge; allowed B1, B2, B3, B4"),
    ('adm-calib table4', ['table4', '--out', '{t}/t4', '--bridges', 'B1,B1'],
     "error: --bridges: 'B1,B1' names an item twice; give each once"),
    ('adm-calib table4', ['table4', '--out', '{t}/t4', '--bridges', ''],
     "error: --bridges: '' is empty; give a comma-separated list"),
    ('adm-calib table4', ['table4', '--out', '{t}/t4', '--trains', 'TGV'],
     "error: --trains: 'TGV' was not studied by the paper; allowed ICE-2, Eurostar, Railjet, ICE-4 (the lower-bound functions must not be applied to other trains, Section 4.3)"),
    ('adm-calib table4', ['table4', '--out', '{t}/t4', '--trains', 'ICE-2,ice2'],
     "error: --trains: 'ICE-2,ice2' names an item twice; give each once"),
    ('adm-calib table4', ['table4', '--out', '{t}/t4', '--jobs', '0'],
     'error: --jobs: 0 processes is out of range; allowed integer in [1, 64] processes'),
    ('adm-calib table4', ['table4', '--out', '{t}/t4', '--jobs', 'nan'],
     "error: --jobs: 'nan' is not an integer; allowed integer in [1, 64] processes"),
    ('adm-calib table4', ['table4', '--out', '{t}/t4', '--jobs', '1.5'],
     "error: --jobs: '1.5' is not an integer; allowed integer in [1, 64] processes"),
    ('adm-calib table4', ['table4', '--out', '{t}/old.json'],
     "error: --out: '{t}/old.json' is not a directory"),
    ('adm-calib table4', ['table4', '--out', ''],
     "error: --out: '' is empty; give a directory"),
    ('adm-calib table4', ['table4', '--out', '{t}/t4', '--speeds', 'nan'],
     "error: --speeds: 'nan' holds nan; every speed and step must be a finite number (km/h)"),
    ('adm-calib table4', ['table4', '--out', '{t}/t4', '--steps-per-period', '2'],
     'error: --steps-per-period: 2 steps is out of range; allowed [4, 10000] steps'),
    ('adm-calib table4', ['table4', '--out', '{t}/old4'],
     "error: --out: '{t}/old4/table4.txt' exists; use --overwrite to replace it"),
    ('adm-calib recommend', ['recommend', '--train', 'ICE-2', '--type', 'cfb', '--n0', 'nan', '--mu', '15000'],
     "error: --n0: 'nan' Hz is not finite; allowed [2.1, 35.73] Hz (validity of the lower-bound functions: 2.1 Hz up to the highest frequency of the studied bridges, Section 4.2.2)"),
    ('adm-calib recommend', ['recommend', '--train', 'ICE-2', '--type', 'cfb', '--n0', 'abc', '--mu', '15000'],
     "error: --n0: 'abc' is not a number; allowed [2.1, 35.73] Hz (validity of the lower-bound functions: 2.1 Hz up to the highest frequency of the studied bridges, Section 4.2.2)"),
    ('adm-calib recommend', ['recommend', '--train', 'ICE-2', '--type', 'cfb', '--n0', '1', '--mu', '15000'],
     'error: --n0: 1 Hz is out of range; allowed [2.1, 35.73] Hz (validity of the lower-bound functions: 2.1 Hz up to the highest frequency of the studied bridges, Section 4.2.2)'),
    ('adm-calib recommend', ['recommend', '--train', 'ICE-2', '--type', 'cfb', '--n0', '60', '--mu', '15000'],
     'error: --n0: 60 Hz is out of range; allowed [2.1, 35.73] Hz (validity of the lower-bound functions: 2.1 Hz up to the highest frequency of the studied bridges, Section 4.2.2)'),
    ('adm-calib recommend', ['recommend', '--train', 'ICE-2', '--type', 'cfb', '--n0', '6.5', '--mu', 'nan'],
     "error: --mu: 'nan' kg/m is not finite; allowed [500, 100000] kg/m"),
    ('adm-calib recommend', ['recommend', '--train', 'ICE-2', '--type', 'cfb', '--n0', '6.5', '--mu', 'inf'],
     "error: --mu: 'inf' kg/m is not finite; allowed [500, 100000] kg/m"),
    ('adm-calib recommend', ['recommend', '--train', 'ICE-2', '--type', 'cfb', '--n0', '6.5', '--mu', '15'],
     'error: --mu: 15 kg/m is out of range; allowed [500, 100000] kg/m (--mu is in kg/m like the bridge specs: 15 t/m = 15000 kg/m)'),
    ('adm-calib recommend', ['recommend', '--train', 'ICE-2', '--type', 'cfb', '--n0', '6.5', '--mu', '-1'],
     'error: --mu: -1 kg/m is out of range; allowed [500, 100000] kg/m'),
    ('adm-calib recommend', ['recommend', '--train', 'ICE-2', '--type', 'cfb', '--n0', '6.5', '--mu', '2e5'],
     'error: --mu: 200000 kg/m is out of range; allowed [500, 100000] kg/m'),
    ('adm-calib recommend', ['recommend', '--train', 'ICE-2', '--type', 'cfb', '--n0', '6.5', '--mu', '15000', '--span', 'nan'],
     "error: --span: 'nan' m is not finite; allowed [4, 40] m"),
    ('adm-calib recommend', ['recommend', '--train', 'ICE-2', '--type', 'cfb', '--n0', '6.5', '--mu', '15000', '--span', '3.9'],
     'error: --span: 3.9 m is out of range; allowed [4, 40] m'),
    ('adm-calib recommend', ['recommend', '--train', 'ICE-2', '--type', 'cfb', '--n0', '30', '--mu', '15000'],
     'error: --n0: 30 Hz gives an estimated span of 3.65 m (n0 = 97.76 L^-0.9124), outside the studied spans [4, 40] m; give --span'),
    ('adm-calib recommend', ['recommend', '--train', 'ICE-2', '--type', 'cfb', '--n0', '6.5', '--mu', '15000', '--functions', 'mine'],
     "error: --functions: 'mine' is not a set or a file; allowed paper, ours, conservative or a functions file of adm-calib study-fit (functions_<train>.toml)"),
    ('adm-calib recommend', ['recommend', '--train', 'TGV', '--type', 'cfb', '--n0', '6.5', '--mu', '15000'],
     "error: --train: 'TGV' was not studied by the paper; allowed ICE-2, Eurostar, Railjet, ICE-4 (the lower-bound functions must not be applied to other trains, Section 4.3)"),
    ('adm-calib recommend', ['recommend', '--train', 'ICE-2', '--type', 'steel', '--n0', '6.5', '--mu', '15000'],
     "error: argument --type: invalid choice: 'steel' (choose from 'cfb', 'sc')"),
    ('adm-calib recommend', ['recommend', '--train', 'ICE-2', '--n0', '6.5', '--mu', '15000'],
     'error: the following arguments are required: --type'),
    ('adm-calib study', ['study', '--out', '{t}/st', '--trains', 'TGV'],
     "error: --trains: 'TGV' is not a study train; allowed ICE-2, Eurostar, Railjet, ICE-4 or the variant Eurostar-table"),
    ('adm-calib study', ['study', '--out', '{t}/st', '--trains', ''],
     "error: --trains: '' is empty; give a comma-separated list"),
    ('adm-calib study', ['study', '--out', '{t}/st', '--trains', 'ICE-2,ice2'],
     "error: --trains: 'ice2' names ICE-2 twice; allowed each train once (trains are told apart by name)"),
    ('adm-calib study', ['study', '--out', '{t}/st', '--mass-functions', 'mu1,MU1'],
     "error: --mass-functions: 'mu1,MU1' names an item twice; give each once"),
    ('adm-calib study', ['study', '--out', '{t}/st', '--freq-index', '1,1'],
     "error: --freq-index: '1,1' names an item twice; give each once"),
    ('adm-calib study', ['study', '--out', '{t}/st', '--mass-functions', 'mu7'],
     "error: --mass-functions: 'mu7' is unknown; allowed mu1, mu2, mu3, mu4, mu5, mu6"),
    ('adm-calib study', ['study', '--out', '{t}/st', '--spans', 'nan:40'],
     "error: --spans: 'nan' m is not finite; allowed [4, 40] m"),
    ('adm-calib study', ['study', '--out', '{t}/st', '--spans', '3:40'],
     'error: --spans: 3 m is out of range; allowed [4, 40] m'),
    ('adm-calib study', ['study', '--out', '{t}/st', '--spans', '40:4'],
     "error: --spans: '40:4' is empty; allowed lo:hi with lo <= hi in [4, 40] m"),
    ('adm-calib study', ['study', '--out', '{t}/st', '--spans', '4:5:6'],
     "error: --spans: '4:5:6' is not lo:hi in m (e.g. 4:40)"),
    ('adm-calib study', ['study', '--out', '{t}/st', '--spans', '4.5:4.7'],
     "error: --spans/--freq-index: the options select no case (spans are the integers 4..40 m; --spans '4.5:4.7' holds none)"),
    ('adm-calib study', ['study', '--out', '{t}/st', '--freq-index', '0'],
     'error: --freq-index: 0 is out of range; allowed integer in [1, 5]'),
    ('adm-calib study', ['study', '--out', '{t}/st', '--freq-index', '1.5'],
     "error: --freq-index: '1.5' is not an integer; allowed integer in [1, 5]"),
    ('adm-calib study', ['study', '--out', '{t}/st', '--limit', '0'],
     'error: --limit: 0 cases is out of range; allowed integer in [1, 1000000] cases'),
    ('adm-calib study', ['study', '--out', '{t}/st', '--limit', 'nan'],
     "error: --limit: 'nan' is not an integer; allowed integer in [1, 1000000] cases"),
    ('adm-calib study', ['study', '--out', '{t}/st', '--workers', '0'],
     'error: --workers: 0 processes is out of range; allowed integer in [1, 64] processes'),
    ('adm-calib study', ['study', '--out', '{t}/st', '--workers', 'inf'],
     "error: --workers: 'inf' is not an integer; allowed integer in [1, 64] processes"),
    ('adm-calib study', ['study', '--out', '{t}/st', '--scheduler', 'http://x:1'],
     "error: --scheduler: 'http://x:1' is not an address like tcp://127.0.0.1:8786"),
    ('adm-calib study', ['study', '--out', '{t}/st', '--steps-per-period', 'nan'],
     "error: --steps-per-period: 'nan' steps is not finite; allowed [4, 10000] steps"),
    ('adm-calib study', ['study', '--out', '{t}/st', '--speeds', '300:nan:1'],
     "error: --speeds: '300:nan:1' holds nan; every speed and step must be a finite number (km/h)"),
    ('adm-calib study', ['study', '--out', '{t}/st', '--speeds', '160:350:1,5'],
     "error: --speeds: '160:350:1,5' mixes ':' and ','; give start:stop:step or a comma list (km/h)"),
    ('adm-calib study', ['study', '--out', '{t}/st', '--dim-grid', 'x'],
     "error: argument --dim-grid: invalid choice: 'x' (choose from 'paper', 'window', 'full')"),
    ('adm-calib study', ['study', '--out', '{t}/old.json'],
     "error: --out: '{t}/old.json' is not a directory"),
    ('adm-calib study', ['study', '--out', ''],
     "error: --out: '' is empty; give a directory"),
    ('adm-calib study-fit', ['study-fit', '--results', '{t}/missing.jsonl'],
     "error: --results: '{t}/missing.jsonl' is not a file"),
    ('adm-calib study-fit', ['study-fit', '--results', '{t}'],
     "error: --results: '{t}' is not a file"),
    ('adm-calib study-fit', ['study-fit', '--results', '{t}/r_empty.jsonl'],
     "error: --results: '{t}/r_empty.jsonl' holds no complete result line"),
    ('adm-calib study-fit', ['study-fit', '--results', '{t}/r_garb.jsonl'],
     "error: results '{t}/r_garb.jsonl': damaged line 1 (byte 0, 8 bytes): not valid JSON"
     "; a study resumed with the same --out drops damaged lines and computes those cases again"),
    ('adm-calib study-fit', ['study-fit', '--results', '{t}/r_nob.jsonl'],
     "error: results '{t}/r_nob.jsonl': damaged line 1 (byte 0, 9 bytes): lacks 'bridge' and 'train'"
     "; a study resumed with the same --out drops damaged lines and computes those cases again"),
    ('adm-calib study-fit', ['study-fit', '--results', '{t}/r_list.jsonl'],
     "error: results '{t}/r_list.jsonl': damaged line 1 (byte 0, 265 bytes): 'bridge' and 'train' must be names "
     "(text), got ['L10'] and 'ICE-2'; a study resumed with the same --out drops damaged lines and computes those cases again"),
    ('adm-calib study-fit', ['study-fit', '--results', '{t}/r_nan.jsonl', '--out', '{t}/sf'],
     "error: --results: '{t}/r_nan.jsonl': record 1 (L10-f1-mu1, ICE-2): delta_zeta_vbi_pct: nan % is not finite; allowed any finite value in %"),
    ('adm-calib study-fit', ['study-fit', '--results', '{t}/r_inf.jsonl', '--out', '{t}/sf'],
     "error: --results: '{t}/r_inf.jsonl': record 1 (L10-f1-mu1, ICE-2): delta_zeta_vbi_pct: inf % is not finite; allowed any finite value in %"),
    ('adm-calib study-fit', ['study-fit', '--results', '{t}/r_str.jsonl', '--out', '{t}/sf'],
     "error: --results: '{t}/r_str.jsonl': record 1 (L10-f1-mu1, ICE-2): delta_zeta_vbi_pct: 'big' is not a number (%)"),
    ('adm-calib study-fit', ['study-fit', '--results', '{t}/r_n0nan.jsonl', '--out', '{t}/sf'],
     "error: --results: '{t}/r_n0nan.jsonl': record 1 (L10-f1-mu1, ICE-2): n0_hz: nan Hz is not finite; allowed > 0 Hz"),
    ('adm-calib study-fit', ['study-fit', '--results', '{t}/r_mf.jsonl', '--out', '{t}/sf'],
     "error: --results: '{t}/r_mf.jsonl': record 1 (L10-f1-mu1, ICE-2): mass_function: 'mu9' is unknown; allowed mu1, mu2, mu3, mu4, mu5, mu6"),
    ('adm-calib study-fit', ['study-fit', '--results', '{t}/r_flag.jsonl', '--out', '{t}/sf'],
     "error: --results: '{t}/r_flag.jsonl': record 1 (L10-f1-mu1, ICE-2): dim_is_local_max: 'yes' must be true or false"),
    ('adm-calib study-fit', ['study-fit', '--results', '{t}/r_status.jsonl', '--out', '{t}/sf'],
     "error: --results: '{t}/r_status.jsonl': record 1 (L10-f1-mu1, ICE-2): status: 1 must be text ('ok', 'error', ...)"),
    ('adm-calib study-fit', ['study-fit', '--results', '{t}/r_peak.jsonl', '--out', '{t}/sf'],
     "error: --results: '{t}/r_peak.jsonl': record 1 (L10-f1-mu1, ICE-2): mlm_peak: 'high' must be null or "
     "{speed_kmh (km/h), acc_m_s2 (m/s^2)}"),
    ('adm-calib study-fit', ['study-fit', '--results', '{t}/r_ok.jsonl', '--out', '{t}/old.json'],
     "error: --out: '{t}/old.json' is not a directory"),
    ('adm-calib study-fit', ['study-fit', '--results', '{t}/r_ok.jsonl', '--out', '{t}/oldfit'],
     "error: --out: '{t}/oldfit/lower_bounds_fit.txt' exists; use --overwrite to replace it"),
    ('adm-calib study-fit', ['study-fit', '--results', '{t}/r_ok.jsonl', '--exclude', 'all'],
     "error: argument --exclude: invalid choice: 'all' (choose from 'none', 'step2', 'strict')"),
    ('adm-calib study-fit', ['study-fit', '--results', '{t}/r_ok.jsonl', '--exclude', 'none', '--exclude-flagged'],
     'error: --exclude-flagged means --exclude strict; it conflicts with --exclude none'),
    ('launch_scripts/replay.py', ['{t}/t_bool.toml', '--rrd', '{t}/o.rrd'],
     "error: RUN.mcap: '{t}/t_bool.toml' is not an MCAP file (it does not start with the MCAP magic bytes)"),
    ('launch_scripts/replay.py', ['{t}/missing.mcap', '--rrd', '{t}/o.rrd'],
     "error: RUN.mcap: '{t}/missing.mcap' is not a file"),
    ('launch_scripts/replay.py', ['{t}', '--rrd', '{t}/o.rrd'],
     "error: RUN.mcap: '{t}' is not a file"),
    ('launch_scripts/replay.py', ['{t}/run.mcap', '--republish', '--rate', 'nan'],
     "error: --rate: 'nan' x simulated time is not finite; allowed [0, 1e+06] x simulated time"),
    ('launch_scripts/replay.py', ['{t}/run.mcap', '--republish', '--rate', 'inf'],
     "error: --rate: 'inf' x simulated time is not finite; allowed [0, 1e+06] x simulated time"),
    ('launch_scripts/replay.py', ['{t}/run.mcap', '--republish', '--rate', '-1'],
     'error: --rate: -1 x simulated time is out of range; allowed [0, 1e+06] x simulated time'),
    ('launch_scripts/replay.py', ['{t}/run.mcap', '--rrd', '{t}/o.rrd', '--exaggeration', 'nan'],
     "error: --exaggeration: 'nan' x is not finite; allowed (0, 1e+06] x"),
    ('launch_scripts/replay.py', ['{t}/run.mcap', '--rrd', '{t}/o.rrd', '--exaggeration', '0'],
     'error: --exaggeration: 0 x is out of range; allowed (0, 1e+06] x'),
    ('launch_scripts/replay.py', ['{t}/run.mcap', '--rrd', '{t}/o.rrd', '--exaggeration', '-inf'],
     'error: argument --exaggeration: expected one argument'),
    ('launch_scripts/replay.py', ['{t}/run.mcap', '--republish', '--wait-subscribers', 'nan'],
     "error: --wait-subscribers: 'nan' s is not finite; allowed [0, 3600] s"),
    ('launch_scripts/replay.py', ['{t}/run.mcap', '--republish', '--wait-subscribers', '-1'],
     'error: --wait-subscribers: -1 s is out of range; allowed [0, 3600] s'),
    ('launch_scripts/replay.py', ['{t}/run.mcap', '--republish', '--domain-id', '500'],
     'error: --domain-id: 500 is out of range; allowed integer in [0, 232]'),
    ('launch_scripts/replay.py', ['{t}/run.mcap', '--republish', '--domain-id', 'x'],
     "error: --domain-id: 'x' is not an integer; allowed integer in [0, 232]"),
    ('launch_scripts/replay.py', ['{t}/run.mcap', '--rrd', '{t}/nodir/o.rrd'],
     "error: --rrd: '{t}/nodir/o.rrd': the directory '{t}/nodir' does not exist"),
    ('launch_scripts/replay.py', ['{t}/run.mcap', '--rrd', '{t}/o.txt'],
     "error: --rrd: '{t}/o.txt' must end in .rrd"),
    ('launch_scripts/replay.py', ['{t}/run.mcap', '--rrd', '{t}/old.rrd'],
     "error: --rrd: '{t}/old.rrd' exists; use --overwrite to replace it"),
    ('launch_scripts/replay.py', ['{t}/run.mcap', '--connect', 'rerun+http://example.com:9876/proxy'],
     "error: --connect: 'rerun+http://example.com:9876/proxy' is not a loopback rerun URL; allowed rerun+http://127.0.0.1:PORT/proxy (the viewer must run on this machine)"),
    ('launch_scripts/replay.py', ['{t}/run.mcap', '--rrd', '{t}/o.rrd', '--topics', '/x'],
     'error: --topics: only used with --republish; add --republish or drop --topics'),
    ('launch_scripts/replay.py', ['{t}/run.mcap', '--via-convert'],
     'error: --via-convert needs --rrd OUT.rrd'),
    ('launch_scripts/replay.py', ['{t}/run.mcap'],
     'error: nothing to do: give --rrd, --spawn, --connect and/or --republish'),
    ('launch_scripts/replay.py', ['{t}/run.mcap', '--rrd', '{t}/o.rrd', '--spawn'],
     'error: argument --spawn: not allowed with argument --rrd'),
    ('launch_scripts/replay.py', ['{t}/trunc.mcap', '--rrd', '{t}/o.rrd'],
     "error: RUN.mcap: '{t}/trunc.mcap' is not a complete MCAP file (it ends inside a record); recover it with: adm-sim salvage {t}/trunc.mcap OUT.mcap"),
]


def _replay_main():
    spec = importlib.util.spec_from_file_location("replay_script", ROOT / "launch_scripts" / "replay.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.main


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    t = tmp_path_factory.mktemp("inputs")
    make_inputs(t)
    return t


def _snapshot(t):
    return {str(p.relative_to(t)): (p.read_bytes() if p.is_file() else None) for p in sorted(t.rglob("*"))}


@pytest.mark.parametrize("entry,argv,line", CASES, ids=[f"{e}:{' '.join(a)[:60]}" for e, a, _ in CASES])
def test_bad_input_one_line_exit_2(inputs, capsys, entry, argv, line):
    main = calib_main if entry.startswith("adm-calib") else _replay_main() if entry.startswith("launch") else sim_main
    args = [a.replace("{t}", str(inputs)) for a in argv]
    if main is sim_main and args[0] == "sweep":
        args += ["--no-progress"] + ([] if "--speeds" in args else ["--speeds", "250,260,270"])
    before = _snapshot(inputs)
    try:
        rc = main(args)
    except SystemExit as exc:  # argparse's own usage errors (adm-sim, replay.py): one line, exit 2
        rc = exc.code
    err = capsys.readouterr().err.replace(str(inputs), "{t}")
    assert (rc, err) == (2, line + "\n")
    assert _snapshot(inputs) == before  # nothing written, overwritten or left behind


def bad_input_counts():
    """Bad-input cases of this file per entry point (the "Bad input" table of docs/cli.md)."""
    return Counter(e for e, _, _ in CASES)


def test_every_entry_point_is_covered():
    counts = bad_input_counts()
    assert set(counts) == {"adm-sim sweep", "bridge spec", "bridge file", "train file",
                           "adm-sim trains/bridges/salvage", "adm-calib calibrate", "adm-calib table4",
                           "adm-calib recommend", "adm-calib study", "adm-calib study-fit",
                           "launch_scripts/replay.py"}
    assert min(counts.values()) >= 8 and sum(counts.values()) == len(CASES) >= 200
    # the "Bad input" table of the CLI reference (docs/cli.md) states these counts
    readme = (ROOT / "docs" / "cli.md").read_text()
    table = readme[readme.index("| entry point | bad-input cases |"):]
    table = table[:table.index("\n\n")]
    stated = [int(row.rsplit("|", 2)[1].strip("* ")) for row in table.splitlines()[2:]]
    order = ["adm-sim sweep", "bridge spec", "bridge file", "train file", "adm-sim trains/bridges/salvage",
             "adm-calib calibrate", "adm-calib table4", "adm-calib recommend", "adm-calib study",
             "adm-calib study-fit", "launch_scripts/replay.py"]
    assert stated == [counts[e] for e in order] + [len(CASES)]
