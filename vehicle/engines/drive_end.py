"""Where a drive ends, in whole steps of its solver: one decision shared by every engine.

The speed profile gives the time t(D) at which the drive's distance reaches the scenario's distance D
(`SpeedProfile.time_grid`, integrated in floating point: t(D) / dt is an integer only to ~1e-5 of a step
after 10^6 steps). A fixed-step solver cannot stop between steps, so the drive ends at the step nearest
t(D): its distance is D to within half a step's travel, and a rounding error of the map moves the end only
when t(D) falls within that error of a half step. Engines that keep whole output intervals (the multiscale
windows, the time-parallel segments before the last) end on `whole_samples`; the full drive then takes
the `tail_steps` left and ends at `time_s`.
"""
from __future__ import annotations

from dataclasses import dataclass, replace


@dataclass(frozen=True)
class DriveEnd:
    """The end of a drive of `distance_m` [m] as a count of solver steps of dt_s [s] from t = 0.

    steps             steps from the start to the end
    steps_per_sample  solver steps per output sample (K)
    """

    distance_m: float
    dt_s: float
    steps: int
    steps_per_sample: int

    @classmethod
    def of(cls, distance_m: float, time_at_distance_s: float, dt_s: float, steps_per_sample: int) -> "DriveEnd":
        """The end of a drive whose distance map reaches distance_m at time_at_distance_s: the nearest step."""
        return cls(float(distance_m), float(dt_s), int(round(time_at_distance_s / dt_s)), int(steps_per_sample))

    def at_sample(self, samples: int) -> "DriveEnd":
        """The same drive ended after `samples` whole output samples (a piece of a drive that another continues)."""
        return replace(self, steps=int(samples) * self.steps_per_sample)

    @property
    def sample_dt_s(self) -> float:
        return self.steps_per_sample * self.dt_s

    @property
    def whole_samples(self) -> int:
        """Whole output samples within the drive."""
        return self.steps // self.steps_per_sample

    @property
    def tail_steps(self) -> int:
        """Steps after the last whole sample to the end (0: the drive ends on a whole sample)."""
        return self.steps % self.steps_per_sample

    @property
    def whole_time_s(self) -> float:
        """Time of the last whole output sample [s]."""
        return self.whole_samples * self.sample_dt_s

    @property
    def time_s(self) -> float:
        """Time of the end [s]: the last whole sample and the tail's steps."""
        return self.whole_time_s + self.tail_steps * self.dt_s

    def steps_left(self, t_s: float) -> tuple[int, int]:
        """(whole output samples, tail steps) from a drive state at t_s [s] (on the step grid) to the end."""
        left = max(self.steps - int(round(t_s / self.dt_s)), 0)
        return left // self.steps_per_sample, left % self.steps_per_sample
