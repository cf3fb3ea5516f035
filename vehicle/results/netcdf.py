"""netCDF-4 structure in HDF5 with h5py dimension scales: label coordinates (station, axle), dimensions
without a coordinate variable, and attaching scales to a variable, as netCDF-4 and h5netcdf write them."""
from __future__ import annotations

import h5py
import numpy as np

from vehicle.results.variables import LABEL_DIMS, label_attrs

NOT_A_VARIABLE = "This is a netCDF dimension but not a netCDF variable."   # netCDF-4's dimension-only scale


def labels(g: h5py.Group, stations, axles) -> dict[str, h5py.Dataset]:
    scales = {}
    for dim, labels in zip(LABEL_DIMS, (stations, axles)):
        ds = g.create_dataset(dim, data=np.array([str(s) for s in labels], dtype=h5py.string_dtype()))
        ds.make_scale(dim)
        for k, v in label_attrs(dim).items():
            ds.attrs[k] = v
        scales[dim] = ds
    return scales


def dimension_only(g: h5py.Group, name: str, size: int) -> h5py.Dataset:
    """A netCDF dimension without a coordinate variable (what netCDF-4 and h5netcdf write)."""
    ds = g.create_dataset(name, shape=(size,), dtype="f4")
    ds.make_scale(f"{NOT_A_VARIABLE}{size:10d}")
    return ds


def attach(ds: h5py.Dataset, dims, scales: dict, seats=None) -> None:
    """Attach the dimension scales of `dims`; a free dimension (variables.FREE_DIMS: seat, travel_bin)
    gets its scale when first used: the seat names when known (and of the right number), else a
    netCDF dimension without a coordinate variable."""
    for i, d in enumerate(dims):
        if d not in scales:
            g, size = ds.parent, ds.shape[i]
            if d == "seat" and seats is not None and len(seats) == size:
                sc = g.create_dataset(d, data=np.array([str(s) for s in seats], dtype=h5py.string_dtype()))
                sc.make_scale(d)
                for k, v in label_attrs(d).items():
                    sc.attrs[k] = v
            else:
                sc = dimension_only(g, d, size)
            scales[d] = sc
        ds.dims[i].attach_scale(scales[d])
