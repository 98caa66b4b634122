"""HumanoidBench's 14 locomotion tasks, registered for both robot variants, and the manipulation
tasks built so far (h1hand only).

Ids: `h1hand-{task}-v0` (H1 + Shadow hands, 61-D action) and `h1-{task}-v0` (H1 without hands,
19-D action); the short alias `{task}` names the h1hand id. Importing this package registers all
28 locomotion ids and the `MANIPULATION` ids; `sirl_jax.envs.make(id, episode_length=...)` builds
one (compiling its MuJoCo model).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

from sirl_jax.envs import rewards as R
from sirl_jax.envs.humanoid import HumanoidEnv, Task
from sirl_jax.envs.registry import TaskSpec, register
from sirl_jax.envs.tasks.balance import BalanceTask
from sirl_jax.envs.tasks.basic import CrawlTask, ReachTask, WalkTask
from sirl_jax.envs.tasks.basketball import BasketballTask
from sirl_jax.envs.tasks.cube import CubeTask
from sirl_jax.envs.tasks.obstacles import HurdleTask, MazeTask, PoleTask
from sirl_jax.envs.tasks.package import PackageTask
from sirl_jax.envs.tasks.powerlift import PowerliftTask
from sirl_jax.envs.tasks.push import PushTask
from sirl_jax.envs.tasks.sit import SitTask
from sirl_jax.envs.tasks.terrain import ClimbTask

VARIANTS = ("h1hand", "h1")


@dataclasses.dataclass(frozen=True)
class Locomotion:
    """One row of HumanoidBench's task tables (spec §1)."""

    name: str
    task: Callable[[], Task]
    success_bar: float
    termination: str
    episode_length: int = 1000


LOCOMOTION = (
    Locomotion("stand", lambda: WalkTask("stand", 0.0), 800, "root z < 0.2"),
    Locomotion("walk", lambda: WalkTask("walk", R.WALK_SPEED), 700, "root z < 0.2"),
    Locomotion("run", lambda: WalkTask("run", R.RUN_SPEED), 700, "root z < 0.2"),
    Locomotion("reach", ReachTask, 12000, "never"),
    Locomotion("hurdle", HurdleTask, 700, "root z < 0.2"),
    Locomotion("crawl", CrawlTask, 700, "never"),
    Locomotion("maze", MazeTask, 1200, "root z < 0.2"),
    Locomotion("sit_simple", lambda: SitTask("sit_simple"), 750, "root z < 0.5"),
    Locomotion("sit_hard", lambda: SitTask("sit_hard"), 750, "root z < 0.5"),
    Locomotion(
        "balance_simple", lambda: BalanceTask("balance_simple"), 800,
        "root z < 0.8, or a bad sphere/floor contact",
    ),
    Locomotion(
        "balance_hard", lambda: BalanceTask("balance_hard"), 800,
        "root z < 0.8, or a bad sphere/floor contact",
    ),
    Locomotion("stair", lambda: ClimbTask("stair"), 700, "torso zz < 0.1"),
    Locomotion("slide", lambda: ClimbTask("slide"), 700, "torso zz < 0.1"),
    Locomotion("pole", PoleTask, 700, "root z < 0.5"),
)
"""The 14 tasks in HumanoidBench's order."""


MANIPULATION = (
    Locomotion("push", PushTask, 700, "box within 0.05 of the goal", 500),
    Locomotion("cube", CubeTask, 370, "root z < 0.58, or either cube z < 0.6", 500),
    Locomotion("powerlift", PowerliftTask, 800, "root z < 0.2"),
    Locomotion(
        "basketball", BasketballTask, 1200,
        "ball z < 0.5, root z < 0.5, or the ball within 0.05 of the hoop", 500,
    ),
    Locomotion("package", PackageTask, 1500, "package within 0.1 of the destination"),
)
"""The manipulation tasks built so far (h1hand only), in HumanoidBench's units: obs sizes, episode
lengths and success bars of spec §1."""


def _factory(row: Locomotion, variant: str) -> Callable[..., HumanoidEnv]:
    def make_env(episode_length: int = row.episode_length) -> HumanoidEnv:
        return HumanoidEnv(
            row.task(), variant, episode_length=episode_length, success_bar=row.success_bar
        )

    return make_env


def task_id(variant: str, name: str) -> str:
    return f"{variant}-{name}-v0"


for _row in LOCOMOTION:
    for _variant in VARIANTS:
        register(
            TaskSpec(
                id=task_id(_variant, _row.name),
                factory=_factory(_row, _variant),
                episode_length=_row.episode_length,
                success_bar=_row.success_bar,
                aliases=(_row.name,) if _variant == "h1hand" else (),
                description=(
                    f"HumanoidBench {_row.name} ({_variant}); terminates: {_row.termination}"
                ),
            )
        )

for _row in MANIPULATION:
    register(
        TaskSpec(
            id=task_id("h1hand", _row.name),
            factory=_factory(_row, "h1hand"),
            episode_length=_row.episode_length,
            success_bar=_row.success_bar,
            aliases=(_row.name,),
            description=f"HumanoidBench {_row.name} (h1hand); terminates: {_row.termination}",
        )
    )
