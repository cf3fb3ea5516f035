"""How each drive key of the output table (vehicle.physics.outputs) becomes one or more stored variables (names,
dimensions, attributes), and a group's variables as an xarray dataset. The HDF5 sinks, the reader and
`to_xarray()` all use it; the groups themselves and their record dimensions are vehicle.results.layout's."""
from __future__ import annotations

from hpsim.extras import install_hint

from dataclasses import dataclass, field

import numpy as np

from vehicle.physics.outputs import AUTO, Split, Var, lookup

LABEL_DIMS = ("station", "axle")
# dimensions whose size is the value's width (not the number of stations or axles): the seats of the
# vehicle file (labelled with their names when known), the strut-travel bins and their edges
FREE_DIMS = ("seat", "travel_bin", "travel_bin_edge")



@dataclass(frozen=True)
class FileVariable:
    """One variable as stored: where it comes from (drive key, row of a split, scale) and how it is laid out."""

    name: str
    key: str
    dims: tuple[str, ...]
    attrs: dict = field(hash=False, compare=False)
    role: str = "data"
    row: int | None = None
    scale: float = 1.0

    def take(self, value, record: bool) -> np.ndarray:
        """The drive's array (..., n) or (width,)/scalar -> the stored layout ((n, width) record-major)."""
        a = np.asarray(value, float)
        if self.row is not None:
            a = a[self.row]
        if record and a.ndim >= 2:
            a = np.moveaxis(a, -1, 0)
        return a * self.scale if self.scale != 1.0 else a


def _width_dim(key: str, var: Var, shape: tuple, n_stations: int, n_axles: int) -> tuple[str, ...]:
    if not shape:
        if var.dim not in (None, AUTO):
            raise ValueError(f"drive key {key!r}: the table gives dim {var.dim!r} but the value has no width")
        return ()
    sizes = {"station": n_stations, "axle": n_axles}
    if isinstance(var.dim, tuple):
        if len(shape) != len(var.dim):
            raise ValueError(f"drive key {key!r}: values of shape {shape} do not match the table's dims {var.dim}")
        for d, width in zip(var.dim, shape):
            if d not in FREE_DIMS and sizes.get(d) != width:
                raise ValueError(f"drive key {key!r}: width {width} does not match the table's dim {d!r}")
        return var.dim
    if len(shape) > 1:
        raise ValueError(f"drive key {key!r}: values of shape {shape} are not supported (at most one width axis)")
    width = shape[0]
    if var.dim in FREE_DIMS:
        return (var.dim,)
    if var.dim == AUTO:
        dims = [d for d, n in sizes.items() if n == width]
        if len(dims) != 1:
            raise ValueError(f"drive key {key!r}: width {width} is neither the {n_stations} stations nor the "
                             f"{n_axles} axles; give its dim in vehicle/physics/outputs.py VARIABLES")
        return (dims[0],)
    if var.dim is None or sizes.get(var.dim) != width:
        raise ValueError(f"drive key {key!r}: width {width} does not match the table's dim {var.dim!r}")
    return (var.dim,)


def file_variables(key: str, width_shape: tuple, record: str | None, n_stations: int,
                   n_axles: int) -> list[FileVariable]:
    """The stored variables of one drive key. width_shape: the value's shape without the sample axis
    ((), (width,) or (k,) for a split); record: the group's record dimension (`layout.RECORD_DIM`), None for a
    static group."""
    entry = lookup(key)
    lead = (record,) if record else ()
    if isinstance(entry, Split):
        if tuple(width_shape) != (len(entry.parts),):
            raise ValueError(f"drive key {key!r}: expected {len(entry.parts)} rows, got shape {width_shape}")
        return [FileVariable(v.name, key, lead, v.attrs(), v.role, j, v.scale) for j, v in enumerate(entry.parts)]
    dims = lead if entry.role == "record" else lead + _width_dim(key, entry, tuple(width_shape), n_stations, n_axles)
    return [FileVariable(entry.name, key, dims, entry.attrs(), entry.role, None, entry.scale)]


def label_attrs(dim: str) -> dict:
    return {"station": {"long_name": "wheel station (axle-major, left first)"},
            "axle": {"long_name": "axle (front first)"},
            "seat": {"long_name": "seat on the hull (vehicle file's seats)"}}[dim]


def group_dataset(record: str | None, arrays: dict, stations, axles, attrs: dict | None = None, seats=None):
    """An xarray.Dataset of one group from drive-keyed arrays (a record group, whose record dimension is `record`:
    drive-shaped (..., n) arrays; a static group, record None: (width,) or scalars) -- the same names, dims,
    coordinates and attributes that the HDF5 file holds (tests/unit/results/test_results_xarray.py checks both)."""
    xr = require_xarray()
    n_st, n_ax = len(stations), len(axles)
    data_vars, coords = {}, {}
    for key, value in arrays.items():
        a = np.asarray(value, float)
        width_shape = a.shape[:-1] if record else a.shape
        for v in file_variables(key, width_shape, record, n_st, n_ax):
            arr = v.take(a, bool(record))
            if v.role == "record":
                coords[v.name] = ((v.name,), arr, v.attrs)
            elif v.role == "coord":
                coords[v.name] = (v.dims, arr, v.attrs)
            else:
                data_vars[v.name] = (v.dims, arr, v.attrs)
    coords["station"] = (("station",), np.array([str(s) for s in stations]), label_attrs("station"))
    coords["axle"] = (("axle",), np.array([str(a) for a in axles]), label_attrs("axle"))
    if seats and any("seat" in v[0] for v in data_vars.values()):
        coords["seat"] = (("seat",), np.array([str(s) for s in seats]), label_attrs("seat"))
    return xr.Dataset(data_vars, coords=coords, attrs=dict(attrs or {}))


def require_xarray():
    try:
        import xarray
    except ImportError:
        raise ImportError(f"to_xarray() needs xarray and h5netcdf: {install_hint('xarray')}") from None
    return xarray
