"""One switch for HumanoidBench's quirks: `hb_compat`, "exact" (the default) or "fixed".

HumanoidBench's task code has rules that depart from what its task descriptions intend (a
counter never reset, a list edited while iterated, zero start quaternions, a reset loop that
writes into the robot's fingers; docs/tasks.md, "HumanoidBench's quirks"). "exact" reproduces
each of them, so returns compare with the paper and HumanoidBench's published curves; "fixed"
applies this repo's corrections. The switch reaches a task through
`sirl_jax.envs.load(name, hb_compat=...)` (from the CLI: `--train.hb-compat`), which gives it to
every HumanoidBench task (`Task.with_hb_compat`); the compiled MuJoCo model is the same in both
modes, only reset, reward and task-state code read it. It lives outside `sirl_jax.envs` so that
the config can check it without importing MuJoCo (render must pick its GL backend first).
"""

from __future__ import annotations

from sirl_jax.agent.checks import choice

EXACT, FIXED = "exact", "fixed"
HB_COMPAT = (EXACT, FIXED)
"""The allowed values, the default first."""


def check_hb_compat(value: str, name: str = "hb_compat") -> str:
    """`value` if it is one of `HB_COMPAT`; else ValueError `hb_compat='x' is invalid; allowed:
    one of ('exact', 'fixed')`."""
    choice(name, value, HB_COMPAT)
    return value
