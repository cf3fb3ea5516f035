"""Quantities converted once are kept in hpsim's private cache folder (hpsim.units): a later command reads them
without importing pint; what it gives is what pint gave; a damaged store or an untrusted folder is not used."""
from __future__ import annotations

import json
import os
import subprocess
import sys

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
_PARSE = ("import sys, json; from hpsim.units import parse_quantity; "
          "v = [parse_quantity(t, u) for t, u in [('20 km/h', 'm/s'), ('25 degC', 'K'), ('5.3 km', 'm'), "
          "('1.2e-5 m^2', 'm^2')]]; print(json.dumps({'values': v, 'pint': 'pint' in sys.modules}))")


def _run(cache):
    env = {**os.environ, "HPSIM_CACHE": str(cache)}
    res = subprocess.run([sys.executable, "-c", _PARSE], capture_output=True, text=True, env=env, cwd=REPO, check=True)
    return json.loads(res.stdout)


def test_a_second_command_reads_its_quantities_without_pint(tmp_path):
    cache = tmp_path / "cache"
    first = _run(cache)
    assert first["pint"] and first["values"] == [20 / 3.6, 298.15, 5300.0, 1.2e-5]
    stores = list(cache.glob("quantities_*.json"))
    assert len(stores) == 1 and stores[0].stat().st_mode & 0o077 == 0
    second = _run(cache)
    assert not second["pint"] and second["values"] == first["values"]
    # a damaged store: pint again, the same values, the store written anew
    stores[0].write_text("{not json")
    third = _run(cache)
    assert third["pint"] and third["values"] == first["values"]
    assert not _run(cache)["pint"]
    # values that are not finite numbers are not taken from the store
    data = json.loads(stores[0].read_text())
    data = {k: ("1" if "km/h" in k else v) for k, v in data.items()}
    stores[0].write_text(json.dumps(data))
    assert _run(cache)["values"] == first["values"]


def test_an_untrusted_folder_is_neither_read_nor_written(tmp_path):
    cache = tmp_path / "shared"
    cache.mkdir()
    cache.chmod(0o777)
    (cache / "quantities_planted.json").write_text("{}")
    out = _run(cache)
    assert out["pint"] and out["values"][0] == 20 / 3.6
    assert [p.name for p in cache.iterdir()] == ["quantities_planted.json"]
