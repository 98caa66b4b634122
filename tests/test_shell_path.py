"""A sweep's `train` call goes through the shell in one pass: parse -> configure -> build
(`runner`, once) -> the run directory and its files (`runlog`, once) -> the loop."""

from __future__ import annotations

import sys

import pytest

from sirl_jax.run import cli, sweep_run

WATCHED = ("sirl_jax.run.runner", "sirl_jax.run.runlog")


class _LoopReached(Exception):
    pass


def _entries(argv: list[str], monkeypatch) -> list[tuple[str, str]]:
    """(module, function) of each call into a watched module from outside it, up to the loop;
    consecutive calls into the same module are one entry."""
    def stop(*args, **kwargs):
        raise _LoopReached

    monkeypatch.setattr(sweep_run.SweepRun, "loop", stop)
    seen: list[tuple[str, str]] = []

    def profile(frame, event, arg):
        if event != "call":
            return
        module = frame.f_globals.get("__name__", "")
        caller = frame.f_back.f_globals.get("__name__", "") if frame.f_back else ""
        if module in WATCHED and caller != module and caller.startswith("sirl_jax"):
            if not seen or seen[-1][0] != module:
                seen.append((module, frame.f_code.co_name))

    sys.setprofile(profile)
    try:
        with pytest.raises(_LoopReached):
            cli.main(argv)
    finally:
        sys.setprofile(None)
    return seen


@pytest.mark.timeout(600)
def test_a_sweep_enters_runner_once_then_runlog_once(tmp_path, monkeypatch):
    argv = ["train", "--preset", "fasttd3-smoke", "--seeds", "2", "--sweep", "sirl.beta=0,1",
            "--steps", "1200", "--no-progress", "--no-tensorboard",
            "--run-dir", str(tmp_path / "sweep")]  # fmt: skip
    entries = _entries(argv, monkeypatch)
    assert [m for m, _ in entries] == list(WATCHED), entries  # build, then the run dir's files
    assert entries[0][1] == "build" and entries[1][1] == "new_run_dir"
    # the run dir was named, checked and written after the build, before the loop
    assert (tmp_path / "sweep" / "sweep.json").is_file()
    # a taken run dir is still refused in one line, nothing changed
    assert cli.main(argv) == cli.EXIT_USAGE
