"""`hpsim vehicle response`: what it prints and rejects (the numbers are tested in tests/test_response.py)."""
from __future__ import annotations

import json

import pytest

from vehicle import cli


def test_response_json_and_plot(tmp_path, capsys):
    png = tmp_path / "response.png"
    assert cli.main(["vehicle", "response", "--points", "40", "--json", "--plot", str(png)]) == 0
    out = json.loads(capsys.readouterr().out)
    names = [m["name"] for m in out["modes"]]
    assert {"bounce", "pitch", "roll"} <= set(names) and any(n.startswith("wheel hop") for n in names)
    assert out["friction_velocity_m_s"] == pytest.approx(0.1)
    assert any("equivalent linear at a strut velocity amplitude of 100 mm/s" in n for n in out["notes"])
    assert len(out["f_hz"]) == 40 and len(out["axles"]) == 4
    assert set(out["axles"][0]["seat_acc_per_m"]) == {"driver", "rear_crew"}
    assert png.stat().st_size > 20_000


def test_response_table_says_what_the_linearisation_means(capsys):
    assert cli.main(["vehicle", "response", "--points", "20", "--friction-velocity", "0"]) == 0
    text = capsys.readouterr().out
    assert "seal friction: its smooth law differentiated at rest" in text
    assert "bounce" in text and "peak response to road input at one axle" in text


@pytest.mark.parametrize("argv, message", [
    (["--friction-velocity", "-1mm/s"], "--friction-velocity: must be in [0, 5] m/s"),
    (["--fmin", "10Hz", "--fmax", "1Hz"], "--fmin/--fmax: need 0.001 Hz <= fmin < fmax <= 1000 Hz"),
    (["--points", "3"], "--points: must be in [10, 5000], got 3"),
])
def test_response_rejects_bad_arguments(argv, message, capsys):
    assert cli.main(["vehicle", "response"] + argv) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
