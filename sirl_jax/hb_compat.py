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
`--train.contact-set`). In the locomotion scenes of `CONTACT_SET_LOCOMOTION`, "hb" lets the
chair, the balance board and sphere and the crawl tunnel touch the whole robot (feet, legs, body,
arms, palms, link capsules), "reduced" only the parts earlier versions let them touch; the other
locomotion scenes are the same in both. A run saved before `hand_floor` existed trained
those scenes with what is now "reduced", and resumes with it (`runlog.load_config`).

`hand_floor` says which hand colliders touch the floor: "all" (HumanoidBench's: every one of the
62), "palms" (the wrist and palm boxes, 16) or "none" (earlier versions: the hands pass through
the floor). It changes the compiled model of every task on a robot with hands
(`load(name, hand_floor=...)`, `--train.hand-floor`); a run saved before it existed resumes
with "none".

`contact_budget` is MJX-JAX's contact budget of a scene (`max_contact_points`:
the solver sees the k most penetrating contacts): `TASK_BUDGET` (-1, the default) keeps the
task's own, 0 none, k >= 1 k (`load(name, contact_budget=...)`, `--train.contact-budget`).
"""

from __future__ import annotations

from sirl_jax.agent.checks import choice

EXACT, FIXED = "exact", "fixed"
HB_COMPAT = (EXACT, FIXED)
"""The allowed values, the default first."""


HB, REDUCED = "hb", "reduced"
CONTACT_SETS = (HB, REDUCED)
"""The allowed contact sets, the default first."""


HAND_FLOOR = ("all", "palms", "none")
"""The allowed `hand_floor` values, the default first."""
NO_HAND_FLOOR = "none"


CONTACT_SET_LOCOMOTION = ("sit_simple", "sit_hard", "balance_simple", "balance_hard", "crawl")
"""The locomotion tasks whose scene reads `contact_set`."""


TASK_BUDGET = -1
"""`contact_budget` value meaning "the task's own `max_contact_points`" (0: none; k >= 1: k)."""


def check_contact_budget(value: int, name: str = "contact_budget") -> int:
    """`value` if it is -1, 0 or an int >= 1; else ValueError naming it and what is allowed."""
    if isinstance(value, bool) or not isinstance(value, int) or value < TASK_BUDGET:
        raise ValueError(f"{name}={value!r} is invalid; allowed: -1 (the task's own), 0 (none) "
                         "or an int >= 1")  # fmt: skip
    return value


def check_hand_floor(value: str, name: str = "hand_floor") -> str:
    """`value` if it is one of `HAND_FLOOR`; else ValueError naming it and the allowed ones."""
    choice(name, value, HAND_FLOOR)
    return value


def check_contact_set(value: str, name: str = "contact_set") -> str:
    """`value` if it is one of `CONTACT_SETS`; else ValueError naming it and the allowed ones."""
    choice(name, value, CONTACT_SETS)
    return value


def check_hb_compat(value: str, name: str = "hb_compat") -> str:
    """`value` if it is one of `HB_COMPAT`; else ValueError `hb_compat='x' is invalid; allowed:
    one of ('exact', 'fixed')`."""
    choice(name, value, HB_COMPAT)
    return value
