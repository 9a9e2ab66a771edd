"""ReportedSignal: noise, quantization and sampling of a signal the real arm reports."""

from __future__ import annotations

import functools
import math

import numpy as np
from pydrake.systems.framework import BasicVector, Context, LeafSystem

from physcap_drake.station.sim_config import SensorNoise

#: Noise samples kept for reuse (of up to 6 values each: a few MB when full).
NOISE_CACHE_SIZE = 16384


class ReportedSignal(LeafSystem):
    """Turns a true signal into what the arm would report on the bus.

    The value reported at time t is gain · (true input) + offset plus zero-mean Gaussian
    noise drawn for sample k = floor(t · sample_rate) (so the noise changes at the arm's
    feedback rate while the true part follows the simulation), rounded to the nearest
    multiple of `resolution`, then limited to [lower, upper] when given. The noise depends
    only on the seed and the sample index, so it is identical from run to run and needs no
    state.

    Input port:  true (n), in the signal's units.
    Output port: reported (n), same units.
    """

    def __init__(self, noise: SensorNoise, *, seed: int, stream: int,
                 lower: float | None = None, upper: float | None = None):
        super().__init__()
        size = len(noise.std)
        self._std = np.asarray(noise.std, dtype=float)
        self._resolution = np.asarray(noise.resolution, dtype=float)
        self._gain = np.asarray(noise.gain or [1.0] * size, dtype=float)
        self._offset = np.asarray(noise.offset or [0.0] * size, dtype=float)
        self._rate = float(noise.sample_rate)
        self._seed = int(seed)
        self._stream = int(stream)
        self._lower = -math.inf if lower is None else lower
        self._upper = math.inf if upper is None else upper
        # What _report does every evaluation, worked out once.
        self._quantized = self._resolution > 0
        self._quantum = np.where(self._quantized, self._resolution, 1.0)
        self._rounds = bool(self._quantized.any())
        self._limited = lower is not None or upper is not None
        self._true = self.DeclareVectorInputPort("true", size)
        self.DeclareVectorOutputPort("reported", size, self._report,
                                     {self.time_ticket(), self._true.ticket()})

    def sample_noise(self, sample_index: int) -> np.ndarray:
        """The noise added to sample `sample_index`, in the signal's units."""
        if not self._std.any():
            return np.zeros_like(self._std)
        return self._std * _standard_normal(self._seed, self._stream, int(sample_index),
                                            self._std.size)

    def _report(self, context: Context, output: BasicVector) -> None:
        sample_index = math.floor(context.get_time() * self._rate + 1e-9)
        value = (self._gain * self._true.Eval(context) + self._offset
                 + self.sample_noise(sample_index))
        if self._rounds:
            step = self._quantum
            value = np.where(self._quantized, np.round(value / step) * step, value)
        if self._limited:
            value = np.clip(value, self._lower, self._upper)
        output.SetFromVector(value)


@functools.lru_cache(maxsize=NOISE_CACHE_SIZE)
def _standard_normal(seed: int, stream: int, sample_index: int, size: int) -> np.ndarray:
    """`size` standard normal draws of the generator seeded with (seed, stream, index)
    (read only). Kept: seeding costs 25 us, and the episodes of one process read the same
    samples (the same scenario seed, events at the same times)."""
    draws = np.random.default_rng((seed, stream, sample_index)).standard_normal(size)
    draws.setflags(write=False)
    return draws
