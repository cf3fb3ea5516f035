"""The ensemble engine (issue 26): K drives of one model structure in lockstep through one vector step.

Each lane must be the scalar engine's drive: the lane code performs the same IEEE operations in the same order
(vehicle.numerics.lanes; no value-changing compiler flag, no fused multiply-add), so the comparison is bit for
bit. (It has to be: the drive amplifies a difference of one unit in the last place to 0.1 mm of strut travel
within 2 s (stick-slip friction); a tolerance would have to be huge to pass a wrong engine.)"""
from __future__ import annotations

import shutil
from pathlib import Path

import casadi as ca
import h5py
import numpy as np
import pytest
import yaml

from vehicle.engines.ensemble import eligible, group_size, grouped_jobs, run_lockstep
from vehicle.numerics.codegen import compile_function
from vehicle.numerics.lanes import LaneStepper, default_lanes
from tests.helpers import REPO as HELPERS_REPO
from vehicle.analysis.summary import report
from vehicle.studies.sweep import run_case

REPO = HELPERS_REPO
DISTANCE = "150 m"
# four parameter sets: a vehicle parameter, the speed, the initial temperatures, the road
CASES = [{"speed": "18 km/h", "initial_temperatures": "25 degC"},
         {"speed": "22 km/h", "initial_temperatures": "40 degC", "vehicle.overrides.tyre.stiffness": "1.2 MN/m"},
         {"speed": "20 km/h", "initial_temperatures": "30 degC", "road.seed": 4},
         {"speed": "24 km/h", "initial_temperatures": "35 degC", "vehicle.overrides.hull.cg_height": "1.4 m"}]


def _scenario(i: int) -> str:
    data = yaml.safe_load((REPO / "scenarios" / "quick_demo.yaml").read_text())
    data["distance"] = DISTANCE
    for key, value in CASES[i].items():
        if key.startswith("vehicle.overrides."):       # one dotted key of the vehicle's overrides
            data["vehicle"].setdefault("overrides", {})[key[len("vehicle.overrides."):]] = value
        else:
            section, _, name = key.rpartition(".")
            (data.setdefault(section, {}) if section else data)[name] = value
    return yaml.safe_dump(data)


def _items(folder: Path, prefix: str, n: int = 4):
    return [(f"{prefix}{i}", (_scenario(i), f"case {i}", str(REPO / "scenarios"), str(folder / f"{prefix}{i}.h5")))
            for i in range(n)]


def _series(path: Path) -> dict:
    out = {}
    with h5py.File(path, "r") as f:
        def visit(name, obj):
            if isinstance(obj, h5py.Dataset) and obj.dtype.kind == "f" and name.split("/")[0] in ("timeseries", "stats"):
                out[name] = obj[()]
        f.visititems(visit)
    return out


def _largest_relative_difference(a: Path, b: Path) -> float:
    sa, sb = _series(a), _series(b)
    assert sa.keys() == sb.keys() and len(sa) > 20
    worst = 0.0
    for k in sa:
        assert sa[k].shape == sb[k].shape, k
        x, y = sa[k], sb[k]
        differ = ~((x == y) | (np.isnan(x) & np.isnan(y)))
        if np.any(differ):
            worst = max(worst, float(np.max(np.abs(x - y)[differ] / np.maximum(np.abs(x)[differ], 1e-300))))
    return worst


def _report_numbers(path: Path) -> dict:
    rep = report(path)
    return {"dN": [a["dN_pct"] for a in rep["axles"]], "T": [a["T_end_C"] for a in rep["axles"]],
            "dh": [a["dh_mm"] for a in rep["axles"]], "E": rep["energy_dissipated_MJ"]}


@pytest.fixture(scope="module")
def singles(tmp_path_factory):
    """The four cases run one after the other on the scalar engine."""
    folder = tmp_path_factory.mktemp("singles")
    for _, args in _items(folder, "s"):
        r = run_case(*args)
        assert r["status"] == "done", r
    return folder


def test_four_lanes_equal_four_single_runs(singles, tmp_path):
    """The quick demo shortened to 150 m, four cases (speeds, initial temperatures, a tyre stiffness, a road seed, a
    centre of gravity): each lane's HDF5 series, statistics rows and report equal the single run's bit for bit
    (the issue's bound is 1e-12 relative); the drives differ among themselves (so the lanes are not one case)."""
    r = run_lockstep(run_case, _items(tmp_path, "e"), 4)
    assert {k: v["status"] for k, v in r["cases"].items()} == {f"e{i}": "done" for i in range(4)}
    assert r["calls"] > 0 and r["lane_blocks"] > r["calls"]          # lanes shared calls
    for i in range(4):
        assert _largest_relative_difference(singles / f"s{i}.h5", tmp_path / f"e{i}.h5") <= 1e-12
        assert _report_numbers(singles / f"s{i}.h5") == _report_numbers(tmp_path / f"e{i}.h5")
    T = [_report_numbers(singles / f"s{i}.h5")["T"] for i in range(4)]
    assert min(abs(T[i][0] - T[j][0]) for i in range(4) for j in range(i)) > 1.0        # K


def _poisoned(*args, make_solver, after_s: float = 3.0, action: str = "nan"):
    """run_case with this lane's road inputs made NaN (or Ctrl-C pressed) once the drive passes `after_s`: the lane's
    solver (make_solver, handed down to vehicle.engines.build.build_engine) sees the inputs of each block before it
    steps them."""

    def poisoned(dt):
        solver = make_solver(dt)
        advance, t = solver.advance, [0.0]

        def advance_poisoned(x0, U, p):
            if t[0] >= after_s:
                if action == "nan":
                    U = np.full_like(U, np.nan)
                else:
                    solver.group.request_stop()
            t[0] += (U.shape[1] - 1) * dt
            return advance(x0, U, p)

        solver.advance = advance_poisoned
        return solver

    return run_case(*args, make_solver=poisoned)


def test_a_lane_gone_non_finite_fails_alone(singles, tmp_path):
    """Lane 1's inputs turn NaN after 3 s: its drive stops with the non-finite error (recorded in its file, as a
    single run's), and the other three lanes finish with the single runs' results bit for bit."""
    items = _items(tmp_path, "e")
    items[1] = (items[1][0], (_poisoned, *items[1][1]))
    items = [(tag, args if tag == "e1" else (run_case, *args)) for tag, args in items]
    r = run_lockstep(lambda fn, *a, make_solver: fn(*a, make_solver=make_solver), items, 4)
    cases = r["cases"]
    assert cases["e1"]["status"] == "failed" and "non-finite" in cases["e1"]["error"]
    with h5py.File(tmp_path / "e1.h5", "r") as f:
        assert f["summary"].attrs["status"] == "failed"
    for i in (0, 2, 3):
        assert cases[f"e{i}"]["status"] == "done"
        assert _largest_relative_difference(singles / f"s{i}.h5", tmp_path / f"e{i}.h5") <= 1e-12


def test_an_interrupted_ensemble_resumes_to_the_single_runs(singles, tmp_path):
    """A Ctrl-C after 4 s of driving (request_stop, what the SIGINT handler calls) leaves every lane's file
    interrupted and resumable; running the ensemble again resumes each from its checkpoint and ends with the single
    runs' series bit for bit."""
    items = _items(tmp_path, "e")
    first = [(tag, (_poisoned if tag == "e2" else run_case, *args)) for tag, args in items]
    r = run_lockstep(lambda fn, *a, make_solver: fn(*a, make_solver=make_solver, after_s=4.0, action="stop")
                     if fn is _poisoned else fn(*a, make_solver=make_solver), first, 4)
    assert {v["status"] for v in r["cases"].values()} == {"interrupted"}
    for i in range(4):
        with h5py.File(tmp_path / f"e{i}.h5", "r") as f:
            assert f["summary"].attrs["status"] == "interrupted"
    r = run_lockstep(run_case, items, 4)
    assert {v["status"] for v in r["cases"].values()} == {"done"}
    for i in range(4):
        assert _largest_relative_difference(singles / f"s{i}.h5", tmp_path / f"e{i}.h5") <= 1e-12


def _toy_functions():
    """A small step with every kind of operation the lane code writes (arithmetic, comparisons, conditionals,
    fmin/fmax, sqrt, fabs, libm functions, constants, divisions) and its parametric part."""
    z, u0, u1, pw = ca.SX.sym("z", 4), ca.SX.sym("u0", 2), ca.SX.sym("u1", 2), ca.SX.sym("pw", 3)
    a = ca.fmin(z[0], z[1]) + ca.fmax(z[1], u0[0]) * pw[0]
    b = ca.if_else(z[2] <= u1[1], ca.exp(-ca.fabs(z[2])), ca.sqrt(ca.fabs(z[3]) + 1.0)) / (1.0 + z[0] ** 2)
    c = ca.tanh(z[3]) + ca.log1p(ca.fabs(z[1])) + ca.constpow(ca.fabs(z[0]) + 0.5, 1.4) - ca.logic_not(z[1])
    d = (z[3] / 3.0 + u1[0] / pw[1] - z[2] / pw[1] + pw[2] / pw[1]) * (z[0] < z[1]) - ca.sign(z[2])
    step = ca.Function("toy_step", [z, u0, u1, pw], [ca.vertcat(a, b, c, d)])
    p = ca.SX.sym("p", 2)
    parametric = ca.Function("toy_parametric", [p], [ca.vertcat(p[0] * 2.0, 1.0 / p[1], ca.exp(p[0]))])
    return step, parametric


@pytest.mark.parametrize("compiler", ["gcc", "clang"])
@pytest.mark.parametrize("scalar", [False, True])
def test_lane_code_compiles_and_equals_casadi(compiler, scalar):
    """The lane code of a small step, with the vector extension and with the scalar fallback
    (-DHPSIM_LANES_SCALAR), built by gcc and by clang (skipped where not installed), equals CasADi's generated C
    (the scalar engine's form) bit for bit in every lane, including NaN, infinite and signed-zero operands (fmin/fmax as the C
    library: a NaN gives the other operand, of -0 and +0 the minimum is -0)."""
    cc = shutil.which(compiler)
    if cc is None:
        pytest.skip(f"{compiler} not installed")
    step, parametric = _toy_functions()
    # the reference: CasADi's own C of the same functions, compiled as the scalar engine's (CasADi's virtual machine
    # rounds the same but may give the other zero: its fmin is not the C library's)
    ref_step, ref_parametric = compile_function(step), compile_function(parametric)
    lanes = 4
    ls = LaneStepper.from_functions(step, parametric, lanes, "hpsim_lanes_toy", scalar=scalar, cc=cc, isa="sse2")
    assert ls.vector_width == (1 if scalar else lanes)
    rng = np.random.default_rng(1)
    for trial in range(20):
        z = rng.normal(size=(4, lanes))
        z[rng.random(z.shape) < 0.15] = 0.0
        z[rng.random(z.shape) < 0.1] = -0.0
        z[rng.random(z.shape) < 0.05] = np.nan
        if trial == 0:
            z[:2] = [[0.0, -0.0, np.nan, np.inf], [-0.0, 0.0, 1.0, np.nan]]
        u0, u1 = rng.normal(size=(2, lanes)), rng.normal(size=(2, lanes))
        P = rng.uniform(0.5, 2.0, size=(2, lanes))
        pw = ls.parametric(P)
        out = ls.step(z, u0, u1, pw)
        for lane in range(lanes):
            ref_pw = np.asarray(ref_parametric(P[:, lane])).ravel()
            ref = np.asarray(ref_step(z[:, lane], u0[:, lane], u1[:, lane], ref_pw)).ravel()
            assert np.array_equal(pw[:, lane], ref_pw)
            got, nan = out[:, lane], np.isnan(ref)
            assert np.array_equal(np.isnan(got), nan), (trial, lane, got, ref)
            assert np.array_equal(got[~nan], ref[~nan]) and np.array_equal(np.signbit(got[~nan]), np.signbit(ref[~nan]))


def _done(i, make_solver=None) -> dict:
    """A case function for grouping: in a group it is handed the lane's solver factory, which it does not need."""
    return {"status": "done", "i": i}


def test_groups_and_eligibility():
    """Full and multiscale drives join, time-parallel ones do not; groups: K given, else one vector's lanes when
    there are more drives than workers (groups as full as the cases allow with every worker busy), else off."""
    assert eligible({"solver": {"dt": "4 ms"}}) and eligible({"solver": {"mode": "multiscale"}})
    assert not eligible({"solver": {"time_parallel": 2}})
    L = default_lanes()
    assert L in (2, 4, 8)
    assert group_size(None, 2, 2) == (1, 1) and group_size(None, 5, 2) == (L, min(L, 3))
    assert group_size(None, 64, 2) == (L, L)
    assert group_size(3, 2, 2) == (3, 3)
    jobs = [(f"c{i}", (i,)) for i in range(6)]
    fn, grouped, unpack = grouped_jobs(_done, jobs, 4, [True] * 5 + [False])
    assert [len(args[1]) for _, args in grouped] == [4, 1, 1]
    results = {tag: fn(*args) for tag, args in grouped}
    cases = dict(pair for tag in results for pair in unpack(tag, results[tag]))
    assert sorted(cases) == [f"c{i}" for i in range(6)] and all(r["status"] == "done" for r in cases.values())
    # with the drives' durations, cases of like duration share a group (the short ones are not masked waiting for
    # a long one): eight cases at two speeds in two groups of four, each of one speed
    durations = [100.0, 50.0] * 4
    jobs = [(f"d{i}", (i,)) for i in range(8)]
    fn, grouped, unpack = grouped_jobs(_done, jobs, 4, [True] * 8,
                                       durations=durations)
    members = [[t for t, _ in args[1]] for _, args in grouped]
    assert [sorted({durations[int(t[1:])] for t in group}) for group in members] == [[50.0], [100.0]]
    results = {tag: fn(*args) for tag, args in grouped}
    cases = dict(pair for tag in results for pair in unpack(tag, results[tag]))
    assert sorted(cases) == [f"d{i}" for i in range(8)]
    assert all(cases[f"d{i}"]["i"] == i for i in range(8))
