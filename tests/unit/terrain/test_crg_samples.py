"""OpenCRG surfaces as proving grounds deliver them: a Belgian-block-like cobbled surface written as a binary file
(KRBI) starting at u = 730 m gives back, through hpsim's import, the OpenCRG C library's own evaluation at 100
points and the written grid (single precision) within 1e-6 m, and drives 10 m in a scenario (`road: {crg: ...}`).
With HPSIM_ASAM_CRG_DIR naming a folder of the ASAM OpenCRG sample files (not part of this repository), every
sample either imports as a plausible road or is refused with one line naming it."""
from __future__ import annotations

import os
from pathlib import Path

import h5py
import numpy as np
import pytest

pycrg = pytest.importorskip("pycrg")

from hpsim.errors import UserInputError                       # noqa: E402
from terrain.plausibility import check_plausible_tracks       # noqa: E402
from terrain.road import Road                                 # noqa: E402
from vehicle import cli                                       # noqa: E402

from .crg_files import belgian_block_like                     # noqa: E402

U0, SPACING, LENGTH = 730.0, 0.01, 12.0       # the drive of 10 m needs 10 m + 1 m + the tyre's contact length


@pytest.fixture(scope="module")
def block(tmp_path_factory):
    """(path, grid as written in single precision, v of the long sections) of a Belgian-block-like KRBI file."""
    z, v = belgian_block_like(seed=1, length_m=LENGTH, spacing_m=SPACING)
    path = tmp_path_factory.mktemp("block") / "block.crg"
    pycrg.write(path, z, SPACING, v, u0=U0, fmt="KRBI", comment="hpsim test: a Belgian-block-like surface")
    return path, z.astype(np.float32).astype(float), v


def test_the_import_equals_the_librarys_evaluation_at_100_points(block):
    path, z32, v = block
    road = Road.from_crg(path, track_width_m=2.5)
    assert road.info["u_start_m"] == U0 and road.length_m == pytest.approx(LENGTH)
    off = road.info["z_offset_m"]
    idx = np.sort(np.random.default_rng(4).choice(road.n_points, 100, replace=False))
    u = U0 + idx * SPACING
    j_left, j_right = int(np.argmin(np.abs(v - 1.25))), int(np.argmin(np.abs(v + 1.25)))
    with pycrg.RoadSurface.open(str(path)) as s:
        lib_left = np.asarray(s.uv_to_z_many(u, 1.25))
        lib_right = np.asarray(s.uv_to_z_many(u, -1.25))
        shift = float(s.uv_to_z(U0, v[j_left])) - z32[0, j_left]   # the default modifiers' reference point
    np.testing.assert_allclose(road.left_m[idx] + off, lib_left, atol=1e-9)
    np.testing.assert_allclose(road.right_m[idx] + off, lib_right, atol=1e-9)
    np.testing.assert_allclose(road.left_m + off - shift, z32[:, j_left], atol=1e-6)
    np.testing.assert_allclose(road.right_m + off - shift, z32[:, j_right], atol=1e-6)


def _drive(workdir: Path, road: str, name: str) -> Path:
    scenario = workdir / f"{name}.yaml"
    scenario.write_text(f"vehicle: {{name: apc_8x8}}\nroad: {road}\nspeed: 10 km/h\ndistance: 10 m\n"
                        "ambient_temperature: 25 degC\n")
    out = workdir / f"{name}.h5"
    assert cli.main(["run", str(scenario), "-o", str(out), "--no-progress", "-q"]) == 0
    return out


def test_a_belgian_block_drives_10_m_in_a_scenario(block, tmp_path):
    path, _, _ = block
    (tmp_path / "block.crg").write_bytes(path.read_bytes())
    out = _drive(tmp_path, "{crg: block.crg}", "crg")
    with h5py.File(out, "r") as f:
        assert f["timeseries/distance"][-1] == pytest.approx(10.0)
        roll = f["timeseries/roll_acceleration"][()]
        wheel_load = f["timeseries/wheel_load"][()]
    # the cobbles differ left and right: they roll the hull, which a road the same on both tracks would not;
    # the wheels stay on the ground and carry the vehicle's weight between them
    assert np.all(np.isfinite(roll)) and np.max(np.abs(roll)) > 0.01
    assert np.all(wheel_load > 0)


ASAM_DIR = os.environ.get("HPSIM_ASAM_CRG_DIR")


@pytest.mark.skipif(not ASAM_DIR, reason="HPSIM_ASAM_CRG_DIR does not name a folder of the ASAM OpenCRG samples")
def test_every_asam_sample_imports_as_a_road_or_is_refused_in_one_line():
    """Each file: the vehicle centred on the surface (lateral offset: the middle of its v range; track 2.5 m or
    the surface's width); either a plausible road or one UserInputError line that names the file."""
    files = sorted(Path(ASAM_DIR).glob("*.crg"))
    assert files, f"{ASAM_DIR}: no *.crg files"
    outcome = {}
    for path in files:
        try:
            with pycrg.RoadSurface.open(str(path)) as s:
                v0, v1 = s.v_range()
        except Exception:
            v0, v1 = -1.25, 1.25            # not loadable: hpsim's own refusal is checked below
        try:
            road = Road.from_crg(path, min(2.5, v1 - v0), lateral_offset_m=0.5 * (v0 + v1))
        except UserInputError as exc:
            text = str(exc)
            assert text.startswith(str(path)) and "\n" not in text, text
            outcome[path.name] = f"refused: {text[len(str(path)) + 2:]}"
            continue
        check_plausible_tracks(str(path), road.spacing_m, road.left_m, road.right_m)
        outcome[path.name] = (f"imported: {road.length_m:g} m at {road.spacing_m * 1e3:g} mm, RMS left "
                              f"{np.std(road.left_m) * 1e3:.3g} mm, right {np.std(road.right_m) * 1e3:.3g} mm")
    print("\n".join(f"{name}: {what}" for name, what in outcome.items()))
