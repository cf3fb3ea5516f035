"""The mileage scenario, shortened to a few km, end to end through the CLI (issue 6).

The report must have physically consistent signs (every strut hotter, the hull higher at
every axle, the hottest axle taking load from the coolest) and conserve the load (the sum of
the after-drive wheel loads equals the weight within 0.5 %).
"""
import json

import pytest

from vehicle.cli import main
from vehicle.physics.params import load_vehicle
from tests.helpers import REPO

ROOT = REPO


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("mileage")
    text = (ROOT / "scenarios" / "mileage_106km.yaml").read_text()
    assert "distance: 106 km" in text
    scenario = tmp / "mileage_3km.yaml"
    scenario.write_text(text.replace("distance: 106 km", "distance: 3 km"))
    out = tmp / "m.h5"
    assert main(["run", str(scenario), "-o", str(out)]) == 0
    return out


def test_short_mileage_report_signs_and_conservation(report, capsys):
    capsys.readouterr()
    assert main(["report", str(report), "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["distance_km"] == pytest.approx(3.0, abs=0.01)
    axles = rep["axles"]
    assert len(axles) == 4
    rises = [a["T_end_C"] - a["T_start_C"] for a in axles]
    assert all(r > 0.5 for r in rises)                       # every strut heats up
    assert all(a["dh_mm"] > 0 for a in axles)                # heated sealed struts lift the hull
    assert all(a["energy_dissipated_MJ"] > 0 for a in axles)
    weight = load_vehicle("apc_8x8").total_weight()
    total_after = sum(2 * a["N_after_daN"] * 10.0 for a in axles)
    assert total_after == pytest.approx(weight, rel=5e-3)
    hot = max(range(4), key=lambda k: rises[k])
    cold = min(range(4), key=lambda k: rises[k])
    assert axles[hot]["dN_pct"] > axles[cold]["dN_pct"]    # the hotter strut pushes harder
