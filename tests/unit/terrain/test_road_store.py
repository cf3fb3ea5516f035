"""The road store (terrain.store): a random road, its envelopes, spline slopes and pass surfaces read back from disk
equal the computed ones bit for bit; a damaged entry is computed again; the key follows the spec and the generator;
the store is bounded, can be turned off, and an untrusted cache folder is not read."""
from __future__ import annotations

import os
import threading
import time

import numpy as np
import pytest

from hpsim.errors import UserInputError
from terrain import RoadSpec, build_road
from terrain import store

SPEC = dict(iso_class="D", length="2 km", seed=3)


@pytest.fixture
def cache(tmp_path, monkeypatch):
    d = tmp_path / "cache"
    monkeypatch.setenv("HPSIM_CACHE", str(d))
    monkeypatch.delenv(store.ROAD_CACHE_MAX_ENV, raising=False)
    return d


def entries(cache) -> list:
    folder = cache / store.FOLDER
    return sorted(p.name for p in folder.iterdir() if not p.name.startswith(".")) if folder.exists() else []


def derived(road):
    """Everything the drives read of a road: the tracks, their envelope, its slopes (and the second pass's surface)."""
    env = road.enveloped(0.35)
    arrays = [road.left_m, road.right_m, env.left_m, env.right_m, env.knot_slopes(0), env.knot_slopes(1)]
    if len(env.passes) > 1:
        arrays += [env.heights(0, pass_index=1), env.knot_slopes(0, pass_index=1)]
    return arrays


def from_disk(a) -> bool:
    while a is not None and not isinstance(a, np.memmap):
        a = a.base
    return a is not None


def computed(spec, monkeypatch):
    with monkeypatch.context() as m:
        m.setenv(store.ROAD_CACHE_MAX_ENV, "0")
        return derived(build_road(RoadSpec(**spec)))


@pytest.mark.parametrize("extra", [{}, {"passes": [{"factor": 1.0}, {"factor": 0.6, "smoothing_length": "0.2 m"}],
                                        "events": [{"type": "step", "position": "500 m", "height": "30 mm"}]}])
def test_stored_road_equals_computed_bit_for_bit(cache, monkeypatch, extra):
    spec = {**SPEC, **extra}
    reference = computed(spec, monkeypatch)
    assert entries(cache) == []                      # store off: nothing written
    first = derived(build_road(RoadSpec(**spec)))    # computed and stored
    n_written = len(entries(cache))
    assert n_written >= 4                            # the road, its envelope, two slopes (+ the pass surface)
    second = derived(build_road(RoadSpec(**spec)))   # read back
    assert len(entries(cache)) == n_written
    assert all(from_disk(a) for a in second) and not any(from_disk(a) for a in first)
    for ref, a, b in zip(reference, first, second):
        assert ref.dtype == b.dtype and ref.shape == b.shape
        assert np.array_equal(ref, a) and np.array_equal(ref, b)
        assert not b.flags.writeable


def test_key_follows_the_spec_and_the_generator(cache, monkeypatch):
    road = build_road(RoadSpec(**SPEC))
    assert road.key == build_road(RoadSpec(**SPEC)).key
    assert road.key != build_road(RoadSpec(**{**SPEC, "seed": 4})).key
    assert road.key != build_road(RoadSpec(**{**SPEC, "iso_class": "C"})).key
    assert road.enveloped(0.35).key != road.enveloped(0.40).key
    store.generator_version.cache_clear()
    monkeypatch.setattr(np, "__version__", "0.0.0-other")
    try:
        assert store.key_of("road", 1) != road.key and build_road(RoadSpec(**SPEC)).key != road.key
    finally:
        store.generator_version.cache_clear()


def test_damaged_entry_is_computed_again(cache, monkeypatch):
    reference = computed(SPEC, monkeypatch)
    road = build_road(RoadSpec(**SPEC))
    entry = cache / store.FOLDER / road.key
    (entry / "left.npy").write_bytes((entry / "left.npy").read_bytes()[:1000])   # cut short
    again = build_road(RoadSpec(**SPEC))
    assert np.array_equal(again.left_m, reference[0]) and np.array_equal(again.right_m, reference[1])


def test_bounded_least_recently_used_first(cache, monkeypatch):
    a = build_road(RoadSpec(**{**SPEC, "seed": 1})).key
    os.utime(cache / store.FOLDER / a, (1e9, 1e9))                  # long unused
    one_road = sum(p.stat().st_size for p in (cache / store.FOLDER / a).iterdir())
    monkeypatch.setenv(store.ROAD_CACHE_MAX_ENV, str(1.5 * one_road / 1e6))
    b = build_road(RoadSpec(**{**SPEC, "seed": 2})).key
    assert entries(cache) == [b]


def test_limit_is_checked(cache, monkeypatch):
    monkeypatch.setenv(store.ROAD_CACHE_MAX_ENV, "lots")
    with pytest.raises(UserInputError, match="HPSIM_ROAD_CACHE_MAX_MB: expected the road store.s size limit.*>= 0.*.lots."):
        build_road(RoadSpec(**SPEC))


def test_untrusted_cache_folder_is_not_used(cache, monkeypatch):
    cache.mkdir(mode=0o700)
    build_road(RoadSpec(**SPEC))
    assert entries(cache)
    os.chmod(cache, 0o777)                            # writable by others: someone could plant a road
    try:
        calls = []
        real = store._read
        monkeypatch.setattr(store, "_read", lambda *a: calls.append(a) or real(*a))
        road = build_road(RoadSpec(**{**SPEC, "seed": 9}))
        assert calls == [] and road.key is not None
        assert not (cache / store.FOLDER / road.key).exists()
    finally:
        os.chmod(cache, 0o700)


def test_two_tracks_prepared_on_two_threads_open_their_entries_one_at_a_time(cache, monkeypatch):
    """`numpy.load` parses the header with `ast`, which CPython 3.11 cannot do on two threads at once
    (gh-106905, a SystemError seen in CI): the store opens entries one at a time however the tracks are read."""
    env = build_road(RoadSpec(**SPEC)).enveloped(0.35)
    env.prepare()                                    # both slopes computed and stored
    inside, most = [0], [0]
    count = threading.Lock()
    real_load = np.load

    def slow_load(*args, **kwargs):
        with count:
            inside[0] += 1
            most[0] = max(most[0], inside[0])
        time.sleep(0.05)                             # long enough for the other thread to arrive
        try:
            return real_load(*args, **kwargs)
        finally:
            with count:
                inside[0] -= 1

    monkeypatch.setattr(store.np, "load", slow_load)
    again = build_road(RoadSpec(**SPEC)).enveloped(0.35).prepare()
    assert from_disk(again.knot_slopes(0)) and from_disk(again.knot_slopes(1))
    assert most[0] == 1
