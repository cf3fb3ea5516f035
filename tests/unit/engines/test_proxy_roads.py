"""The linear-model proxy's road part shared by the drives of one process (vehicle.engines.proxy_roads):

- two drives of different strut designs on one road get proxies equal bit for bit to those each computes alone,
  and the second drive's road part (road under each tyre, its spectrum, the matched stretch's spectrum) is not
  computed again;
- another road seed or speed profile is another key: computed anew, equal to its own computation;
- drives asking on threads at once compute a key once and all get the finished value; a failed computation
  leaves nothing behind.
"""
from __future__ import annotations

import threading

import numpy as np
import pytest
import yaml

from vehicle.engines.build import build_engine
from vehicle.engines.linear_proxy import LinearProxy
from vehicle.engines.proxy_roads import ComputedOnce
from vehicle.scenario.schema import prepare, read_scenario_text

BASE = {"description": "proxy roads", "vehicle": {"name": "apc_8x8"}, "road": {"iso_class": "D", "seed": 3},
        "speed": "20 km/h", "distance": "3 km", "ambient_temperature": "25 degC",
        "initial_temperatures": ["45 degC", "40 degC", "35 degC", "30 degC"],
        "output": {"interval": "1 s", "stats_interval": "0.5 km"},
        "solver": {"mode": "multiscale", "window": "200 m", "spacing": "600 m", "warm_up": "40 m"}}
# two strut designs (gas charge, valve bleed), another road, another speed
DESIGN_A = {"vehicle": {"name": "apc_8x8", "overrides": {"charging.fill_pressure_offset": "0.2 MPa"}}}
DESIGN_B = {"struts": {"all": {"overrides": {"valve.bleed_area": "1.4e-5 m^2"}}},
            "vehicle": {"name": "apc_8x8", "overrides": {"charging.fill_pressure_offset": "-0.3 MPa"}}}
MATCH = (20.0, 60.0, 0.05)        # a first window's stretch and RMS strut velocity [s, s, m/s]


def _drive(**changes):
    data = {**BASE, **changes}
    return build_engine(prepare(read_scenario_text(yaml.safe_dump(data), "pr.yaml", ".")))[1]


def _proxy(drive, kept: ComputedOnce):
    proxy = LinearProxy(drive, drive._linear_proxy_inputs(), kept)
    proxy.prepare()
    proxy.match(MATCH)
    return proxy, proxy.finish()


def _assert_same(got: tuple, alone: tuple):
    (t, c, V), (t0, c0, V0) = got, alone
    assert np.array_equal(t, t0) and np.array_equal(c, c0) and V == V0


@pytest.fixture(scope="module")
def drives():
    return {"a": _drive(**DESIGN_A), "b": _drive(**DESIGN_B), "seed": _drive(road={"iso_class": "D", "seed": 4}),
            "speed": _drive(speed="15 km/h")}


def test_designs_on_one_road_share_the_road_part_bit_for_bit(drives):
    a, b = drives["a"], drives["b"]
    alone_b = _proxy(b, ComputedOnce(0))[1]
    kept = ComputedOnce(2)
    proxy_a, got_a = _proxy(a, kept)
    assert kept.computed == 1 and proxy_a.road.stretches.computed == 1
    proxy_b, got_b = _proxy(b, kept)
    assert kept.computed == 1                                  # the second design computed no road part
    assert proxy_b.road is proxy_a.road and proxy_b.road.stretches.computed == 1
    _assert_same(got_b, alone_b)
    _assert_same(got_a, _proxy(a, ComputedOnce(0))[1])
    assert got_a[2] != got_b[2]                                # the designs' own part differs: the matched V


def test_another_road_seed_or_speed_is_computed_anew(drives):
    kept = ComputedOnce(4)
    first = _proxy(drives["a"], kept)[0]
    roads = {}
    for other, n in (("seed", 2), ("speed", 3)):
        proxy, got = _proxy(drives[other], kept)
        assert kept.computed == n
        _assert_same(got, _proxy(drives[other], ComputedOnce(0))[1])
        roads[other] = proxy.roads
    assert roads["seed"].shape == first.roads.shape and not np.array_equal(roads["seed"], first.roads)
    assert roads["speed"].shape[1] > first.roads.shape[1]     # slower: more time on the same road
    assert _proxy(drives["a"], kept)[0].road is first.road and kept.computed == 3   # the first is still kept


def test_callers_at_once_compute_a_key_once_and_see_it_whole():
    kept, started, release, calls = ComputedOnce(1), threading.Event(), threading.Event(), []

    def compute():
        calls.append(1)
        started.set()
        release.wait(5.0)
        return np.arange(3.0)

    got = [None, None]

    def ask(k):
        got[k] = kept.get("road", compute)

    first = threading.Thread(target=ask, args=(0,))
    first.start()
    started.wait(5.0)
    second = threading.Thread(target=ask, args=(1,))
    second.start()
    second.join(0.2)
    assert second.is_alive() and got[1] is None                # waits for the first, sees no half-built value
    release.set()
    first.join(5.0)
    second.join(5.0)
    assert len(calls) == 1 and kept.computed == 1 and got[0] is got[1]


def test_a_failed_computation_leaves_nothing_and_the_oldest_key_goes_first():
    kept = ComputedOnce(2)
    with pytest.raises(RuntimeError):
        kept.get("x", lambda: (_ for _ in ()).throw(RuntimeError("no road")))
    assert kept.get("x", lambda: 1) == 1 and kept.computed == 1
    kept.get("y", lambda: 2)
    kept.get("z", lambda: 3)                                   # "x" dropped: computed again when asked
    assert kept.get("x", lambda: 4) == 4 and kept.get("z", lambda: 5) == 3 and kept.computed == 4


def test_the_proxy_mean_over_a_stretch_reads_the_shared_grid_as_np_interp_would(drives):
    """`MultiscaleDrive.proxy` on the shared (read-only) grid equals np.interp on writeable copies of it, bit for
    bit: at grid points, between them and beyond both ends (held)."""
    d = drives["a"]
    d._linear_proxy_setup(MATCH)
    tg, c = d._proxy_t
    assert not tg.flags.writeable                    # the shared grid: np.interp would copy it whole per call
    tw, cw = np.array(tg), np.array(c)
    s_at = lambda t: float(np.interp(t, d.t_grid, d.s_grid))
    rng = np.random.default_rng(0)
    k = int(np.searchsorted(tg, 10.0))
    stretches = [(0.0, 250.0), (s_at(tg[k]), s_at(tg[k + 40])), (1000.0, d.settings.distance_m)]
    stretches += [tuple(sorted(rng.uniform(0.0, d.settings.distance_m, 2))) for _ in range(20)]
    for s0, s1 in stretches:
        t0, t1 = d.manifold.time_at(s0), d.manifold.time_at(s1)
        alone = np.array([np.interp(t1, tw, ci) - np.interp(t0, tw, ci) for ci in cw]) / (t1 - t0)
        assert np.array_equal(d.proxy(s0, s1), alone), (s0, s1)
