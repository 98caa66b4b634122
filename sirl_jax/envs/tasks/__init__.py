"""HumanoidBench's 14 locomotion tasks, registered for both robot variants, and its 17 manipulation
tasks (h1hand; highbar_hard on h1strong).

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
from sirl_jax.envs.tasks.locomotion.balance import BalanceTask
from sirl_jax.envs.tasks.locomotion.basic import CrawlTask, ReachTask, WalkTask
from sirl_jax.envs.tasks.locomotion.obstacles import HurdleTask, MazeTask, PoleTask
from sirl_jax.envs.tasks.locomotion.sit import SitTask
from sirl_jax.envs.tasks.locomotion.terrain import ClimbTask
from sirl_jax.envs.tasks.manipulation.basketball import BasketballTask
from sirl_jax.envs.tasks.manipulation.bookshelf import BookshelfTask
from sirl_jax.envs.tasks.manipulation.cabinet import CabinetTask
from sirl_jax.envs.tasks.manipulation.cube import CubeTask
from sirl_jax.envs.tasks.manipulation.door import DoorTask
from sirl_jax.envs.tasks.manipulation.highbar import HighBarTask
from sirl_jax.envs.tasks.manipulation.insert import InsertTask
from sirl_jax.envs.tasks.manipulation.kitchen import KitchenTask
from sirl_jax.envs.tasks.manipulation.package import PackageTask
from sirl_jax.envs.tasks.manipulation.powerlift import PowerliftTask
from sirl_jax.envs.tasks.manipulation.push import PushTask
from sirl_jax.envs.tasks.manipulation.room import RoomTask
from sirl_jax.envs.tasks.manipulation.spoon import SpoonTask
from sirl_jax.envs.tasks.manipulation.truck import TruckTask
from sirl_jax.envs.tasks.manipulation.window import WindowTask
from sirl_jax.hb_compat import EXACT, HAND_FLOOR, HB, TASK_BUDGET

VARIANTS = ("h1hand", "h1")


@dataclasses.dataclass(frozen=True)
class TaskRow:
    """One row of HumanoidBench's task tables (spec §1). `robot`: the variant of a manipulation
    task (locomotion rows are registered for every variant in `VARIANTS`)."""

    name: str
    task: Callable[[], Task]
    success_bar: float
    termination: str
    episode_length: int = 1000
    robot: str = "h1hand"


LOCOMOTION = (
    TaskRow("stand", lambda: WalkTask("stand", 0.0), 800, "root z < 0.2"),
    TaskRow("walk", lambda: WalkTask("walk", R.WALK_SPEED), 700, "root z < 0.2"),
    TaskRow("run", lambda: WalkTask("run", R.RUN_SPEED), 700, "root z < 0.2"),
    TaskRow("reach", ReachTask, 12000, "never"),
    TaskRow("hurdle", HurdleTask, 700, "root z < 0.2"),
    TaskRow("crawl", CrawlTask, 700, "never"),
    TaskRow("maze", MazeTask, 1200, "root z < 0.2"),
    TaskRow("sit_simple", lambda: SitTask("sit_simple"), 750, "root z < 0.5"),
    TaskRow("sit_hard", lambda: SitTask("sit_hard"), 750, "root z < 0.5"),
    TaskRow(
        "balance_simple", lambda: BalanceTask("balance_simple"), 800,
        "root z < 0.8, or a bad sphere/floor contact",
    ),
    TaskRow(
        "balance_hard", lambda: BalanceTask("balance_hard"), 800,
        "root z < 0.8, or a bad sphere/floor contact",
    ),
    TaskRow("stair", lambda: ClimbTask("stair"), 700, "torso zz < 0.1"),
    TaskRow("slide", lambda: ClimbTask("slide"), 700, "torso zz < 0.1"),
    TaskRow("pole", PoleTask, 700, "root z < 0.5"),
)
"""The 14 tasks in HumanoidBench's order."""


MANIPULATION = (
    TaskRow("push", PushTask, 700, "box within 0.05 of the goal", 500),
    TaskRow("cube", CubeTask, 370, "root z < 0.58, or either cube z < 0.6", 500),
    TaskRow("powerlift", PowerliftTask, 800, "root z < 0.2"),
    TaskRow(
        "basketball", BasketballTask, 1200,
        "ball z < 0.5, root z < 0.5, or the ball within 0.05 of the hoop", 500,
    ),
    TaskRow("package", PackageTask, 1500, "package within 0.1 of the destination"),
    TaskRow("spoon", SpoonTask, 650, "root z < 0.58"),
    TaskRow("window", WindowTask, 650, "root z < 0.58, or the tool z < 0.58"),
    TaskRow(
        "insert_normal", lambda: InsertTask("insert_normal"), 350,
        "root z < 0.5, or a peg or block-end site z < 0.5", 500,
    ),
    TaskRow(
        "insert_small", lambda: InsertTask("insert_small"), 350,
        "root z < 0.5, or a peg or block-end site z < 0.5", 500,
    ),
    TaskRow("highbar_hard", HighBarTask, 750, "head z < 2.0", robot="h1strong"),
    TaskRow("door", DoorTask, 600, "root z < 0.58"),
    TaskRow("cabinet", CabinetTask, 2500, "the fourth subtask complete"),
    TaskRow("room", RoomTask, 400, "root z < 0.3"),
    TaskRow("truck", TruckTask, 3000, "all five packages on the table"),
    TaskRow(
        "bookshelf_simple", lambda: BookshelfTask("bookshelf_simple"), 2000,
        "root z < 0.58, the current object z < 0.5, or the fifth placement",
    ),
    TaskRow(
        "bookshelf_hard", lambda: BookshelfTask("bookshelf_hard"), 2000,
        "root z < 0.58, the current object z < 0.5, or the fifth placement",
    ),
    TaskRow(
        "kitchen", KitchenTask, 4,
        "all four subtasks done (microwave, kettle, bottom burner, light switch, in order)", 500,
    ),
)
"""HumanoidBench's 17 manipulation tasks (h1hand; highbar_hard on h1strong), with the episode
lengths and success bars of spec §1."""


def _factory(row: TaskRow, variant: str) -> Callable[..., HumanoidEnv]:
    def make_env(episode_length: int = row.episode_length, hb_compat: str = EXACT,
                 contact_set: str = HB, hand_floor: str = HAND_FLOOR[0],
                 contact_budget: int = TASK_BUDGET) -> HumanoidEnv:  # fmt: skip
        task = row.task().with_hb_compat(hb_compat).with_contact_set(contact_set)
        task = task.with_hand_floor(hand_floor).with_contact_budget(contact_budget)
        return HumanoidEnv(task, variant, episode_length=episode_length,
                           success_bar=row.success_bar)  # fmt: skip

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
                takes_hb_compat=True,
                description=(
                    f"HumanoidBench {_row.name} ({_variant}); terminates: {_row.termination}"
                ),
            )
        )

for _row in MANIPULATION:
    register(
        TaskSpec(
            id=task_id(_row.robot, _row.name),
            factory=_factory(_row, _row.robot),
            episode_length=_row.episode_length,
            success_bar=_row.success_bar,
            aliases=(_row.name,),
            takes_hb_compat=True,
            description=(
                f"HumanoidBench {_row.name} ({_row.robot}); terminates: {_row.termination}"
            ),
        )
    )
