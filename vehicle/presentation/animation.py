"""`hpsim animate RESULTS -o drive.mp4|.gif [--from 10km --to 10.2km]`: a side view of the vehicle driving
over its road, drawn from the stored series.

Each frame draws the left track of the road around the vehicle (rebuilt from the scenario, terrain.build_road)
and the hull (a box through the axle stations) heaving and pitching. The heave and pitch series move it (pitch +
nose up, so a point x behind the CG moves by -pitch x, vehicle.physics.hull). Then come the wheels on the road and the struts between
wheel and hull, each coloured by its strut's surface temperature. Below, the road over the whole span with a
cursor at the vehicle and the time and distance. The geometry is a drawing, not the vehicle's: the hull box
sits a fixed height above the axles at the first frame and moves with the stored heave and pitch from there
(vehicle.physics.hull.station_displacement). Each wheel stands on the road under its axle (the tyre's
deflection is not drawn) and the strut joins it to the hull, so its length shows the suspension working. With
equal axes: sizes at true scale, the road's heights and every motion MOTION_SCALE times larger (centimetres
would not show on a 10 m vehicle).

Frames are the stored samples (every k-th, k the largest that gives at least fps frames per second of driving,
played in real time): an .mp4 through matplotlib's ffmpeg writer where ffmpeg is installed, a .gif by Pillow
with one duration per frame. A GIF stores durations in whole centiseconds, so each frame shows from its own
sample's time to the next one's, both rounded to the centisecond (`gif_durations_ms`): the rounding never
accumulates and the movie lasts the span's driving time (the last frame one frame interval)."""
from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np

from hpsim.errors import UserInputError
from hpsim.outputs import atomic_output
from terrain.spec import RoadSpec, build_road

from vehicle.physics import hull as hull_eq
from vehicle.results.reader import open_results
from vehicle.presentation.plots import pyplot, save_figure

FPS = 20                       # frames per second of the movie (and of driving shown: real time)
VIEW_AHEAD_M, VIEW_BEHIND_M = 4.0, 10.0     # the side view's window around the first axle
HULL_CLEARANCE_M = 1.0         # drawing: hull bottom above the wheel centres
MOTION_SCALE = 5.0             # road heights and every motion drawn this many times larger (sizes true)
HULL_HEIGHT_M = 1.3            # drawing: hull box height
OVERHANG_M = 1.0               # drawing: hull ends beyond the first and last axle
TEMPERATURE_CMAP = "coolwarm"


def _road_of(resolved: dict):
    spec = RoadSpec.model_validate(resolved["road"])
    return build_road(spec, Path(resolved.get("base_dir") or "."))


def drive_frames(path, start_m: float | None = None, end_m: float | None = None, fps: float = FPS) -> dict:
    """The series of the animation over [start_m, end_m] of the drive, one row per frame (samples at about
    fps per second of driving): time, distance, heave, pitch and the strut temperature per station."""
    with open_results(path) as r:
        names = ("time", "distance", "heave", "pitch", "strut_temperature")
        data = {n: r.series(n) for n in names}
        resolved = json.loads(r.scenario_attrs["resolved_json"])
        stations = list(r.stations)
    missing = [n for n, v in data.items() if v is None or len(v) < 2]
    if missing:
        raise UserInputError(f"{path}: the animation needs the stored series {', '.join(missing)} "
                             "(a run with output.interval set, e.g. 0.05 s)")
    s = np.asarray(data["distance"], float)
    lo = s[0] if start_m is None else float(start_m)
    hi = s[-1] if end_m is None else float(end_m)
    # the first sample is one output interval after the start: a span from 0 means from the first sample
    near = 2.0 * float(np.max(np.diff(s)))
    if not (s[0] - near <= lo < hi <= s[-1] + near):
        raise UserInputError(f"--from/--to: [{lo / 1e3:.4g}, {hi / 1e3:.4g}] km must be an increasing span within "
                             f"the stored drive [{s[0] / 1e3:.4g}, {s[-1] / 1e3:.4g}] km")
    t = np.asarray(data["time"], float)
    dt = float(np.median(np.diff(t)))
    step = max(1, int(math.floor(1.0 / (fps * dt) + 1e-6)))      # every step-th sample: at least fps frames/s
    idx = np.flatnonzero((s >= lo - 1e-9) & (s <= hi + 1e-9))[::step]
    if len(idx) < 2:
        raise UserInputError(f"--from/--to: the span holds {len(idx)} stored sample(s) at {fps:g} frames/s; "
                             "give a longer span or store the series more densely (output.interval)")
    out = {n: np.asarray(v, float)[idx] for n, v in data.items()}
    out.update(resolved=resolved, stations=stations, frame_dt_s=step * dt, sample_dt_s=dt)
    return out


def frame_count(path, start_m=None, end_m=None, fps: float = FPS) -> int:
    return len(drive_frames(path, start_m, end_m, fps)["time"])


class SideView:
    """The figure and its artists; `update(k)` draws frame k."""

    def __init__(self, d: dict, road):
        from matplotlib import colors as mcolors
        from matplotlib.patches import Circle, Polygon

        plt = pyplot()
        self.d, self.road = d, road
        V = d["resolved"]["vehicle"]
        self.x_axle = np.array([a["position"] for a in V["axles"]])          # behind axle 1 [m]
        self.R = float((V.get("tyre") or {}).get("radius") or 0.5)
        self.x_cg = float(d["resolved"].get("vehicle_derived", {}).get("sprung_cg_x_m", np.mean(self.x_axle)))
        left = [i for i, n in enumerate(d["stations"]) if n.endswith("_left")] or list(range(0, len(d["stations"]), 2))
        self.left = np.array(left[:len(self.x_axle)])
        T = d["strut_temperature"][:, self.left] - 273.15
        self.norm = mcolors.Normalize(vmin=math.floor(np.min(T)) - 0.5, vmax=math.ceil(np.max(T)) + 0.5)
        self.cmap = plt.get_cmap(TEMPERATURE_CMAP)
        self.fig, (self.ax, self.ax2) = plt.subplots(2, 1, figsize=(10, 5.6), height_ratios=[3, 1.1],
                                                     layout="constrained")
        ax = self.ax
        ax.set_aspect("equal")
        self.road_line, = ax.plot([], [], color="0.3", lw=1.5)
        self.ground = None
        self.hull = Polygon(np.zeros((4, 2)), closed=True, fc="0.8", ec="0.2", lw=1.2, zorder=3)
        ax.add_patch(self.hull)
        self.wheels = [Circle((0, 0), self.R, fc="w", ec="k", lw=1.5, zorder=4) for _ in self.x_axle]
        for w in self.wheels:
            ax.add_patch(w)
        self.struts = [ax.plot([], [], lw=6, solid_capstyle="butt", zorder=5)[0] for _ in self.x_axle]
        sm = plt.cm.ScalarMappable(norm=self.norm, cmap=self.cmap)
        self.fig.colorbar(sm, ax=ax, label="strut surface temperature [degC]", fraction=0.03, pad=0.01)
        z0 = road.heights("left") * MOTION_SCALE
        ax.set_ylim(float(np.min(z0)) - 0.2, float(np.max(z0)) + 2 * self.R + HULL_CLEARANCE_M + HULL_HEIGHT_M + 0.4)
        ax.set(xlabel="distance along the road [m]", ylabel=f"height [m] (motions x{MOTION_SCALE:g})")
        self.label = ax.text(0.01, 0.97, "", transform=ax.transAxes, va="top", fontsize=9)
        s = d["distance"]
        span = (road.distance_m >= s[0] - VIEW_BEHIND_M) & (road.distance_m <= s[-1] + VIEW_AHEAD_M)
        self.ax2.plot(road.distance_m[span], road.heights("left")[span] * 1e3, color="0.3", lw=0.8)
        self.cursor = self.ax2.axvline(s[0], color="C3", lw=1.5)
        self.ax2.set(xlabel="distance [m]", ylabel="left track [mm]", xlim=(s[0] - VIEW_BEHIND_M, s[-1] + VIEW_AHEAD_M))
        self.ax2.grid(alpha=0.3)
        # the drawing's reference: wheel gaps and hull height at the first frame
        self.hull_bottom0 = self._road_at(s[0] - self.x_axle).max() + self.R + HULL_CLEARANCE_M
        self.fig.suptitle(f"side view (left track), {s[0] / 1e3:.3f}-{s[-1] / 1e3:.3f} km: sizes true, road and "
                          f"motions x{MOTION_SCALE:g} vertically; wheels and struts coloured by strut temperature",
                          fontsize=10)

    def _road_at(self, x):
        return np.interp(x, self.road.distance_m, self.road.heights("left")) * MOTION_SCALE

    def _hull_z(self, k, x_behind):
        """Hull bottom height [m] at points x_behind axle 1 in frame k (heave and pitch against frame 0)."""
        d = self.d
        dz = hull_eq.station_displacement(d["heave"][k] - d["heave"][0], d["pitch"][k] - d["pitch"][0], 0.0,
                                          np.asarray(x_behind, float), 0.0, self.x_cg, 0.0)
        return self.hull_bottom0 + MOTION_SCALE * dz

    def update(self, k: int):
        d = self.d
        s = float(d["distance"][k])
        xs = s - self.x_axle                                 # axle positions along the road
        self.ax.set_xlim(s - self.x_axle[-1] - VIEW_BEHIND_M + self.x_axle[-1], s + VIEW_AHEAD_M)
        lo, hi = self.ax.get_xlim()
        rd = (self.road.distance_m >= lo - 1) & (self.road.distance_m <= hi + 1)
        self.road_line.set_data(self.road.distance_m[rd], self.road.heights("left")[rd] * MOTION_SCALE)
        ends = np.array([-OVERHANG_M, self.x_axle[-1] + OVERHANG_M])
        zb = self._hull_z(k, ends)
        self.hull.set_xy([[s - ends[0], zb[0]], [s - ends[1], zb[1]], [s - ends[1], zb[1] + HULL_HEIGHT_M],
                          [s - ends[0], zb[0] + HULL_HEIGHT_M]])
        hz = self._hull_z(k, self.x_axle)
        wz = self._road_at(xs) + self.R                   # on the road (the tyre's deflection not drawn)
        T = d["strut_temperature"][k, self.left] - 273.15
        for w, strut, x, z, zt, temp in zip(self.wheels, self.struts, xs, wz, hz, T):
            c = self.cmap(self.norm(temp))
            w.center = (x, z)
            w.set_facecolor(c)
            strut.set_data([x, x], [z, zt])
            strut.set_color(c)
        self.cursor.set_xdata([s, s])
        self.label.set_text(f"t = {d['time'][k]:.2f} s, s = {s / 1e3:.4f} km")
        return [self.road_line, self.hull, self.cursor, self.label, *self.wheels, *self.struts]


def gif_durations_ms(times_s, last_s: float) -> list[int]:
    """Display time [ms, whole centiseconds] of each frame shown at times_s (the last one for last_s): the
    differences of the frame times from the first, each rounded to the centisecond, so the durations add up to
    the driving time to within 5 ms however many frames there are."""
    t = np.asarray(times_s, float)
    edges = np.append(t - t[0], t[-1] - t[0] + last_s)
    centiseconds = np.rint(edges * 100.0).astype(int)
    return [int(10 * max(1, d)) for d in np.diff(centiseconds)]


def _frames(view: "SideView", n: int, progress: bool, name: str):
    """The frame indices, with a progress bar on stderr when asked (a long span takes minutes to draw)."""
    if not progress:
        return range(n)
    from tqdm import tqdm

    return tqdm(range(n), desc=name, unit="frame", dynamic_ncols=True, mininterval=0.5)


def _write_gif(view: "SideView", out: Path, frames, durations_ms: list[int], dpi: int) -> None:
    """Every frame drawn and kept as an image (as matplotlib's PillowWriter does), then one GIF with a duration
    per frame."""
    import io

    from PIL import Image

    images = []
    for k in frames:
        view.update(k)
        buf = io.BytesIO()
        view.fig.savefig(buf, format="rgba", dpi=dpi)
        w, h = (int(round(x * dpi)) for x in view.fig.get_size_inches())
        images.append(Image.frombuffer("RGBA", (w, h), buf.getbuffer(), "raw", "RGBA", 0, 1))
    images[0].save(out, save_all=True, append_images=images[1:], duration=durations_ms, loop=0)


def animate(path, out: str | Path, start_m: float | None = None, end_m: float | None = None, fps: float = FPS,
            dpi: int = 80, progress: bool = False) -> dict:
    """Write the side-view movie (.mp4 with ffmpeg, .gif with Pillow); returns {file, frames, writer, fps,
    duration_s}. progress: a progress bar of the frames on stderr."""
    from matplotlib import animation

    out = Path(out)
    suffix = out.suffix.lower()
    if suffix not in (".mp4", ".gif"):
        raise UserInputError(f"-o/--output: {out.name!r} must end in .mp4 or .gif")
    if suffix == ".mp4" and not (animation.writers.is_available("ffmpeg") and shutil.which("ffmpeg")):
        raise UserInputError(f"-o/--output: {out.name}: an .mp4 needs ffmpeg, which is not installed; "
                             "write a .gif (Pillow) instead")
    d = drive_frames(path, start_m, end_m, fps)
    view = SideView(d, _road_of(d["resolved"]))
    n = len(d["time"])
    view.update(0)
    view.fig.canvas.draw()
    view.fig.set_layout_engine("none")          # laid out once: every frame keeps the first frame's layout
    real_fps = 1.0 / d["frame_dt_s"]
    frames = _frames(view, n, progress, out.name)
    # to a temporary file renamed when complete: an interrupted movie never replaces the old one
    try:
        with atomic_output(out) as tmp:
            if suffix == ".gif":
                durations = gif_durations_ms(d["time"], d["frame_dt_s"])
                _write_gif(view, tmp, frames, durations, dpi)
                duration_s = sum(durations) / 1e3
            else:
                writer = animation.FFMpegWriter(fps=real_fps)
                # frame by frame through the writer (one draw per frame; FuncAnimation.save draws each frame twice)
                with writer.saving(view.fig, str(tmp), dpi):
                    for k in frames:
                        view.update(k)
                        writer.grab_frame()
                duration_s = n / real_fps
    finally:
        pyplot().close(view.fig)
    return {"file": str(out), "frames": n, "writer": "ffmpeg" if suffix == ".mp4" else "pillow", "fps": real_fps,
            "duration_s": duration_s}


def save_frame(path, out: str | Path, at_m: float | None = None, dpi: int = 100) -> Path:
    """One frame as a PNG (the README's picture): the sample nearest at_m (default: the middle)."""
    d = drive_frames(path)
    view = SideView(d, _road_of(d["resolved"]))
    k = len(d["time"]) // 2 if at_m is None else int(np.argmin(np.abs(d["distance"] - at_m)))
    view.update(k)
    return save_figure(view.fig, out, dpi=dpi)
