"""One self-updating progress line for runs on a terminal."""

from __future__ import annotations

import sys
import time
from typing import Any, TextIO


class Progress:
    """``on_step`` callback printing simulated time, dt, speed and time left.

    The line is redrawn at most every ``interval`` seconds of wall time.  It is shown
    only when ``stream`` (stderr by default) is a terminal and ``quiet`` is not set.
    The speed is in cell-steps per second (cells x layers x steps / wall time) and the
    time left extrapolates the simulated-time rate of the current session.
    """

    def __init__(
        self,
        t_end: float,
        cells: int,
        *,
        quiet: bool | None = None,
        stream: TextIO | None = None,
        interval: float = 0.2,
    ) -> None:
        self.stream = sys.stderr if stream is None else stream
        self.enabled = shown(quiet, self.stream)
        self.t_end = t_end
        self.cells = cells
        self.interval = interval
        self._start: tuple[float, float, int] | None = None
        self._last_draw = -float("inf")
        self._width = 0

    def __call__(self, sim: Any, dt: float) -> None:
        if not self.enabled:
            return
        now = time.perf_counter()
        if self._start is None:
            self._start = (now, sim.t - dt, sim.steps - 1)
        if now - self._last_draw >= self.interval or sim.t >= self.t_end:
            self._last_draw = now
            self._draw(self.line(sim.t, dt, sim.steps, now))

    def line(self, t: float, dt: float, steps: int, now: float) -> str:
        """The text of the progress line at simulated time ``t`` and wall time ``now``."""
        wall0, t0, steps0 = self._start or (now, t, steps)
        elapsed = now - wall0
        text = f"t = {t:.4g} / {self.t_end:.4g} s   dt = {dt:.3g} s"
        if elapsed > 0 and t > t0:
            speed = self.cells * (steps - steps0) / elapsed
            left = (self.t_end - t) * elapsed / (t - t0)
            text += f"   {speed:,.0f} cell-steps/s   {_duration(left)} left"
        return text

    def _draw(self, text: str) -> None:
        self._write("\r" + text.ljust(self._width))
        self._width = len(text)

    def finish(self) -> None:
        """End the progress line (call once the run stops, however it stops)."""
        if self.enabled and self._width:
            self._write("\n")
            self._width = 0

    def _write(self, text: str) -> None:
        """``text`` on the stream; a stream that went away (its pipe's reader gone, closed)
        ends the line, not the run, which it stopped as a failure of the simulation."""
        try:
            self.stream.write(text)
            self.stream.flush()
        except (OSError, ValueError):
            self.enabled = False


def shown(quiet: bool | None, stream: TextIO | None = None) -> bool:
    """Whether a run shows what it does on ``stream`` (stderr by default): unless
    ``quiet``; with ``quiet=None``, only on a terminal; never where there is no stream
    (``sys.stderr`` is None under pythonw: the run failed, blaming the simulation)."""
    stream = sys.stderr if stream is None else stream
    return stream is not None and (not quiet if quiet is not None else stream.isatty())


def _duration(seconds: float) -> str:
    """``seconds`` as ``1h02m``, ``3m05s`` or ``42s``."""
    s = int(round(seconds))
    if s >= 3600:
        return f"{s // 3600}h{s % 3600 // 60:02d}m"
    if s >= 60:
        return f"{s // 60}m{s % 60:02d}s"
    return f"{s}s"
