"""Speed strings at every entry point: one line, exit 2, naming what was typed."""

from __future__ import annotations


import pytest

from adm_calib.calib_commands import main as calib_main
from adm_sim.cli.sim_commands import main as sim_main
from adm_sim.errors import InputError
from adm_sim.inputs.speeds import parse_speeds


BAD = [
    ("300:nan:1", "speeds_kmh: '300:nan:1' holds nan; every speed and step must be a finite number (km/h)"),
    ("inf,300", "speeds_kmh: 'inf,300' holds inf; every speed and step must be a finite number (km/h)"),
    ("250,263,200", "speeds_kmh: '250,263,200' must increase strictly (km/h), e.g. 200,250,263"),
    ("250,250,260", "speeds_kmh: '250,250,260' must increase strictly (km/h), e.g. 200,250,263"),
    ("350:160:1", "speeds_kmh: '350:160:1' needs start <= stop and step > 0 (km/h)"),
    ("160:350:0", "speeds_kmh: '160:350:0' needs start <= stop and step > 0 (km/h)"),
    ("fast", "speeds_kmh: 'fast' is not start:stop:step or a comma list (km/h)"),
]


@pytest.mark.parametrize("text,line", BAD)
def test_parse_speeds_refuses(text, line):
    with pytest.raises(InputError) as exc:
        parse_speeds(text)
    assert str(exc.value) == line


def test_parse_speeds_values():
    assert parse_speeds("160:170:5").tolist() == [160.0, 165.0, 170.0]
    assert parse_speeds("200,250.5,263").tolist() == [200.0, 250.5, 263.0]


@pytest.mark.parametrize("text,line", BAD[:3])
@pytest.mark.parametrize("argv,main", [
    (["sweep", "--bridge", "B1", "--train", "ICE-2", "--model", "mlm"], sim_main),
    (["calibrate", "--bridge", "B1", "--train", "ICE-2"], calib_main),
])
def test_cli_speed_errors_are_one_line(tmp_path, capsys, argv, main, text, line):
    assert main(argv + ["--speeds", text]) == 2
    err = capsys.readouterr().err
    assert err == f"error: --speeds{line.removeprefix('speeds_kmh')}\n"  # the library's argument, shown as the flag


def test_study_speed_error_before_any_work(tmp_path, capsys):
    out = tmp_path / "s"
    assert calib_main(["study", "--out", str(out), "--speeds", "300:nan:1"]) == 2
    assert capsys.readouterr().err == f"error: --speeds{BAD[0][1].removeprefix('speeds_kmh')}\n"
    assert not (out / "results.jsonl").exists()
