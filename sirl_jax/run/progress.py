"""Host-side run bookkeeping at chunk boundaries: the progress bar, throughput and ETA,
log/eval/checkpoint schedules, failure counters, metric reduction, and Ctrl-C handling."""

from __future__ import annotations

import math
import signal
import sys
import threading
import time
from collections.abc import Mapping

import numpy as np
from tqdm import tqdm


def format_duration(seconds: float) -> str:
    """`3.2 days`, `5.1 h`, `12 min`, `40 s`."""
    if not math.isfinite(seconds):
        return "?"
    if seconds >= 2 * 86400:
        return f"{seconds / 86400:.1f} days"
    if seconds >= 2 * 3600:
        return f"{seconds / 3600:.1f} h"
    if seconds >= 120:
        return f"{seconds / 60:.0f} min"
    return f"{seconds:.0f} s"


class Rate:
    """Env steps/s and updates/s over the chunks since the first `skip` (compile) ones."""

    def __init__(self, skip: int = 1):
        self.skip = skip
        self.chunks = 0
        self._t0: float | None = None
        self._start: tuple[int, int] = (0, 0)
        self.env_rate = math.nan
        self.update_rate = math.nan

    def update(self, env_steps: int, updates: int) -> None:
        now = time.perf_counter()
        self.chunks += 1
        if self.chunks == self.skip or (self.skip == 0 and self._t0 is None):
            self._t0, self._start = now, (env_steps, updates)
            return
        if self._t0 is not None and now > self._t0:
            dt = now - self._t0
            self.env_rate = (env_steps - self._start[0]) / dt
            self.update_rate = (updates - self._start[1]) / dt


class Progress:
    """A tqdm bar over env steps with steps/s, updates/s and the last episode return."""

    def __init__(self, total: int, initial: int = 0, enabled: bool = True):
        self.rate = Rate(skip=1)
        self._bar = tqdm(
            total=total,
            initial=initial,
            unit="step",
            unit_scale=True,
            dynamic_ncols=True,
            disable=not enabled,
            file=sys.stderr,
            smoothing=0.1,
        )
        self._last_return = math.nan

    def update(self, env_steps: int, updates: int, metrics: Mapping[str, float]) -> None:
        self.rate.update(env_steps, updates)
        ret = metrics.get("episode/return", math.nan)
        if math.isfinite(ret):
            self._last_return = ret
        self._bar.set_postfix(
            {
                "sps": f"{self.rate.env_rate:.0f}",
                "ups": f"{self.rate.update_rate:.1f}",
                "return": f"{self._last_return:.1f}",
            },
            refresh=False,
        )
        self._bar.update(env_steps - self._bar.n)

    def write(self, message: str) -> None:
        """Prints a line without breaking the bar."""
        self._bar.write(message, file=sys.stderr)

    def close(self) -> None:
        self._bar.close()


def crossed(before: int, after: int, every: int) -> bool:
    """Whether a multiple of `every` lies in (before, after]; never when every <= 0."""
    return every > 0 and after // every > before // every


def is_failure_metric(name: str) -> bool:
    """`nonfinite*` counters: non-zero means a NaN/inf loss or observation in the chunk.

    Losses themselves are NaN by design in chunks without updates (the seed phase), and
    episode returns in chunks where no episode ended, so only the counters are checked.
    """
    return name.startswith("nonfinite")


def failures(metrics: Mapping[str, float], env_steps: int = 0,
             max_blowup_rate: float = 1.0) -> list[str]:  # fmt: skip
    """Why a chunk of `env_steps` transitions must stop the run (empty: it need not).

    Each non-zero (or non-finite) `nonfinite*` counter as `name=value`, and `env/blowups` when
    it exceeds `max_blowup_rate` of the chunk's env steps (fewer are survived: the env resets).
    """
    bad = [
        f"{name}={value:g}"
        for name, value in metrics.items()
        if is_failure_metric(name) and (value != 0 or not math.isfinite(value))
    ]
    blowups = metrics.get("env/blowups", 0)
    if blowups > max_blowup_rate * env_steps or not math.isfinite(blowups):
        bad.append(f"env/blowups={blowups:g} of {env_steps:,} env steps "
                   f"(> max_blowup_rate={max_blowup_rate:g})")  # fmt: skip
    return bad


_LAST = ("env_steps", "updates", "planning", "r_max", "sirl/reference")
_SUM_SUFFIXES = ("/count", "/terminated", "/num_updates", "/blowups")


def _reduction(name: str) -> str:
    """How chunk values combine into a log row: state-like ones keep the last, counts add."""
    if name in _LAST or name.startswith("buffer/"):
        return "last"
    if name.startswith("nonfinite") or name.endswith(_SUM_SUFFIXES):
        return "sum"
    return "mean"


class MetricMean:
    """Combines chunk metrics between log rows: counters (`nonfinite*`, `*/count`,
    `*/num_updates`, ...) are summed, state-like values (`updates`, `r_max`, `buffer/*`) keep
    the last chunk's value, everything else is averaged over the chunks where it is finite
    (NaN if it never was, e.g. losses before the first update)."""

    def __init__(self) -> None:
        self._sum: dict[str, float] = {}
        self._count: dict[str, int] = {}
        self._last: dict[str, float] = {}

    def add(self, metrics: Mapping[str, float]) -> None:
        for name, value in metrics.items():
            self._last[name] = value
            self._sum.setdefault(name, 0.0)
            self._count.setdefault(name, 0)
            if math.isfinite(value) or _reduction(name) == "sum":
                self._sum[name] += value
                self._count[name] += 1

    def pending(self) -> bool:
        """Whether chunks were added since the last `pop`."""
        return bool(self._last)

    def pop(self) -> dict[str, float]:
        """The combined row since the last `pop`; then resets."""
        out = {}
        for name, last in self._last.items():
            how, total, n = _reduction(name), self._sum[name], self._count[name]
            if how == "last":
                out[name] = last
            elif how == "sum":
                out[name] = total
            else:
                out[name] = total / n if n else math.nan
        self._sum, self._count, self._last = {}, {}, {}
        return out


def host_scalars(tree: Mapping, prefix: str = "") -> dict[str, float]:
    """Flattens a (nested) dict of fetched metric arrays to {name: float} (mean if not [])."""
    out = {}
    for name, value in tree.items():
        if isinstance(value, Mapping):
            out.update(host_scalars(value, f"{prefix}{name}/"))
        else:
            out[prefix + name] = float(np.mean(value))
    return out


class StopOnSigint:
    """First Ctrl-C (SIGINT) or SIGTERM: sets `requested`; the loop finishes its chunk, saves
    and exits 0. A second one: KeyboardInterrupt. Installed only in the main thread."""

    _SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __enter__(self) -> StopOnSigint:
        self.requested = False
        self._previous: dict = {}
        if threading.current_thread() is threading.main_thread():
            for sig in self._SIGNALS:
                self._previous[sig] = signal.signal(sig, self._handle)
        return self

    def _handle(self, signum, frame) -> None:
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True
        name = signal.Signals(signum).name
        print(
            f"\n{name}: finishing the chunk, then saving a checkpoint (Ctrl-C again aborts)",
            file=sys.stderr,
        )

    def __exit__(self, *exc) -> None:
        for sig, previous in self._previous.items():
            signal.signal(sig, previous)
