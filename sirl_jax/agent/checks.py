"""The one error format of every config check: `name=value is invalid; allowed: ...`."""

from __future__ import annotations


def check(ok: bool, name: str, value: object, allowed: str) -> None:
    """Raises ValueError `name=value is invalid; allowed: ...` unless `ok` (every config check)."""
    if not ok:
        raise ValueError(f"{name}={value!r} is invalid; allowed: {allowed}")


def choice(name: str, value: str, allowed: tuple[str, ...]) -> None:
    """`check` for a field with a fixed set of string values."""
    check(value in allowed, name, value, f"one of {allowed}")
