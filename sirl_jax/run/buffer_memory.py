"""Whether the replay buffer fits in a device's free memory (the shell calls this before `init`)."""

from __future__ import annotations

from pathlib import Path

import jax

_MEMINFO = Path("/proc/meminfo")


class BufferTooLargeError(RuntimeError):
    """The replay buffer does not fit in the device's free memory."""


def _free_bytes(device: jax.Device) -> int | None:
    if device.platform == "cpu":
        try:
            for line in _MEMINFO.read_text().splitlines():
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
        except OSError:
            return None
        return None
    stats = device.memory_stats()
    if not stats or "bytes_limit" not in stats:
        return None
    return int(stats["bytes_limit"]) - int(stats.get("bytes_in_use", 0))


def check_buffer_fits(nbytes: int, device: jax.Device | None = None) -> None:
    """Raises `BufferTooLargeError` if `nbytes` exceeds the device's free memory.

    Free memory: `bytes_limit - bytes_in_use` from `device.memory_stats()` on accelerators
    (the XLA pool), `MemAvailable` from /proc/meminfo on CPU. Returns silently when the
    platform reports neither.
    """
    device = device or jax.devices()[0]
    free = _free_bytes(device)
    if free is not None and nbytes > free:
        raise BufferTooLargeError(
            f"replay buffer needs {nbytes / 1e9:.2f} GB but {device} has {free / 1e9:.2f} GB "
            "free: lower --buffer-size (or run fewer envs/seeds per process)"
        )
