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

`contact_set` says what the manipulation scenes' colliders touch. "hb" (the default) is
HumanoidBench's: the robot's colliders and hands against every fixture (tables, shelves,
cabinets, counters, window frame, truck), objects against each other and against every robot
collider (`scene.use_hb_contacts`). "reduced" is the cut set earlier versions trained with:
hands against free objects only, objects against fixtures and the floor, the robot's body
passing through fixtures; it is cheaper to simulate. Unlike `hb_compat` it changes the
compiled model. It reaches a task the same way (`load(name, contact_set=...)`,
`--train.contact-set`); locomotion tasks have HumanoidBench's contacts in both.
"""

from __future__ import annotations

from sirl_jax.agent.checks import choice

EXACT, FIXED = "exact", "fixed"
HB_COMPAT = (EXACT, FIXED)
"""The allowed values, the default first."""


HB, REDUCED = "hb", "reduced"
CONTACT_SETS = (HB, REDUCED)
"""The allowed contact sets, the default first."""


def check_contact_set(value: str, name: str = "contact_set") -> str:
    """`value` if it is one of `CONTACT_SETS`; else ValueError naming it and the allowed ones."""
    choice(name, value, CONTACT_SETS)
    return value


def check_hb_compat(value: str, name: str = "hb_compat") -> str:
    """`value` if it is one of `HB_COMPAT`; else ValueError `hb_compat='x' is invalid; allowed:
    one of ('exact', 'fixed')`."""
    choice(name, value, HB_COMPAT)
    return value
