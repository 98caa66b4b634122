"""Our side of hb_parity, and its table: the states drawn on our model in MuJoCo C, our task's
reward on them (`evaluate` after `mjx.forward`, vmapped in one jit), the statistics of a
difference, the printed table and the results file's merge rule; and how a task's state
travels to HumanoidBench (`HIDDEN`: where hb_side.py writes it, and the stages forced)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

from experiments.fidelity.hb_contacts import CLASSES

RENAME: dict[str, dict[str, str]] = {}
"""Per-task joint renames, our name -> HumanoidBench's. Empty: the H1's joints and the objects'
free joints of the tasks checked so far carry the same names in both models."""


def _leaves(task) -> np.ndarray:
    """The whole batched task state as [n, k]."""
    leaves = jax.tree.leaves(task)
    return np.concatenate([np.asarray(x, np.float64).reshape(len(x), -1) for x in leaves], 1)


def _same_stage(task, stage: int):
    """The batched task state with every leaf set to `stage` (maze: the stage is all of it)."""
    return jax.tree.map(lambda x: np.full_like(x, stage), task)


def _with(key: str):
    """(task state dict, stage) -> the same dict with `key` set to the stage on every state."""
    return lambda task, stage: {**task, key: np.full_like(task[key], stage)}


@dataclasses.dataclass(frozen=True)
class Transfer:
    """How a task's state reaches HumanoidBench (hb_side.py's `hidden_kind`), and its stages."""

    kind: str
    pick: Callable[[Any], np.ndarray] = _leaves
    """Our batched task state -> the [n, k] values hb_side writes."""
    stages: tuple[int, ...] = ()
    """Stages forced in turn on every state, both sides, each scored separately."""
    force: Callable[[Any, int], Any] = _same_stage
    """(our batched task state, stage) -> the task state with that stage."""


HIDDEN: dict[str, Transfer] = {
    "push": Transfer("attr:goal"),
    "cube": Transfer("body_quat:target_cube"),
    "reach": Transfer("attr:goal"),
    "maze": Transfer("maze_stage", stages=(0, 1, 2, 3, 4)),
    # HumanoidBench keeps the destination as the body's position (z 0; the site sits 0.35 up)
    "package": Transfer("body_pos:package_destination",
                        pick=lambda t: np.concatenate([t[:, :2], np.zeros((len(t), 1))], 1)),
    "window": Transfer("attr:head_pos0"),
    "spoon": Transfer("attr:step_counter", pick=lambda t: np.asarray(t["phase"])[:, None]),
    # bookshelf: the stage (`task_index`); hard also its drawn objects and goals, simple keeps
    # HumanoidBench's own fixed order, so that ours is checked against it
    "bookshelf_simple": Transfer("bookshelf", pick=lambda t: np.asarray(t["index"])[:, None],
                                 stages=(0, 1, 2, 3, 4), force=_with("index")),
    "bookshelf_hard": Transfer("bookshelf", pick=lambda t: np.concatenate(
        [np.asarray(t["order"], np.float64), np.asarray(t["goals"]).reshape(len(t["goals"]), -1),
         np.asarray(t["index"])[:, None]], 1), stages=(0, 1, 2, 3, 4), force=_with("index")),
    "basketball": Transfer("basketball_stage", pick=lambda t: np.asarray(t["stage"])[:, None],
                           stages=(0, 1), force=_with("stage")),
}  # fmt: skip
"""Where HumanoidBench keeps the task state that ours carries (see hb_side.py)."""


FALL_Z = 0.5


def draw_states(env, n: int, every: int, episode_steps: int, seed: int):
    """(qpos [n, nq], qvel [n, nv], ctrl [n, nu], task state tree [n, ...], episodes)."""
    m = env.mj_model
    d = mujoco.MjData(m)
    low, high = m.actuator_ctrlrange[:, 0], m.actuator_ctrlrange[:, 1]
    rng = np.random.default_rng(seed)
    reset = jax.jit(jax.vmap(env.reset))
    batch, key = 64, jax.random.PRNGKey(seed)
    rows, task_rows, episodes = [], [], 0
    while len(rows) < n:
        key, sub = jax.random.split(key)
        starts = reset(jax.random.split(sub, batch))
        qpos0 = np.asarray(starts.physics.qpos, np.float64)
        for e in range(batch):
            if len(rows) >= n:
                break
            episodes += 1
            mujoco.mj_resetData(m, d)
            d.qpos[:] = qpos0[e]
            for step in range(episode_steps):
                d.ctrl[:] = low + (rng.uniform(-1, 1, m.nu) + 1) / 2 * (high - low)
                mujoco.mj_step(m, d, nstep=10)
                if step % every == every - 1:
                    rows.append((d.qpos.copy(), d.qvel.copy(), d.ctrl.copy()))
                    task_rows.append(jax.tree.map(lambda x, e=e: np.asarray(x[e]), starts.task))
                if len(rows) >= n or d.qpos[2] < FALL_Z or not np.isfinite(d.qpos).all():
                    break
    qpos, qvel, ctrl = (np.stack([r[k] for r in rows]) for k in range(3))
    task = jax.tree.map(lambda *xs: np.stack(xs), *task_rows)
    return qpos, qvel, ctrl, task, episodes


def our_rewards(env, qpos, qvel, ctrl, task, chunk: int = 250):
    """[n] reward, [n] terminated, {metric: [n]} from `env.task.evaluate` after `mjx.forward`."""
    mx = env.mx

    @jax.jit
    def score(qp, qv, u, ts):
        def one(qp, qv, u, ts):
            d = mjx.make_data(mx).replace(qpos=qp, qvel=qv, ctrl=u)
            d = mjx.forward(mx, d)
            reward, terminated, _, metrics = env.task.evaluate(env.robot, d, ts)
            return reward, terminated, metrics

        return jax.vmap(one)(qp, qv, u, ts)

    n = len(qpos)
    pad = (-n) % chunk
    padded = [np.concatenate([x, np.repeat(x[-1:], pad, 0)]) for x in (qpos, qvel, ctrl)]
    task = jax.tree.map(lambda x: np.concatenate([x, np.repeat(x[-1:], pad, 0)]), task)
    outs = []
    for i in range(0, n + pad, chunk):
        part = [jnp.asarray(x[i : i + chunk], jnp.float32) for x in padded]
        ts = jax.tree.map(lambda x, i=i: jnp.asarray(x[i : i + chunk]), task)
        outs.append(jax.device_get(score(*part, ts)))
    reward = np.concatenate([o[0] for o in outs])[:n]
    terminated = np.concatenate([o[1] for o in outs])[:n]
    metrics = {k: np.concatenate([o[2][k] for o in outs])[:n] for k in outs[0][2]}
    return reward, terminated, metrics


def diff_stats(delta: np.ndarray) -> dict:
    a = np.abs(delta[np.isfinite(delta)])
    if not len(a):
        return {"median": None, "p95": None, "max": None}
    return {"median": float(np.median(a)), "p95": float(np.percentile(a, 95)),
            "max": float(a.max())}  # fmt: skip


def _pct(v) -> str:
    return "n/a" if v is None else f"{100 * v:.1f}%"


def print_table(rows: list[dict]) -> None:
    heads = ["robot-fixture/obstacle", "hand-object", "object-object", "robot-floor",
             "robot-object", "object-fixture/obstacle", "object-floor"]  # fmt: skip
    print("\n| task | states | " + " | ".join(heads)
          + " | reward median abs d | p95 | termination | notes |")  # fmt: skip
    print("|---|---:|" + "---:|" * (len(heads) + 3) + "---|")
    for r in rows:
        if "error" in r:
            print(f"| {r['task']} | {r['states']} | error: {r['error']} |")
            continue
        c = r["contacts"]
        cells = []
        for cls in CLASSES:
            for label in (cls.replace("static", "fixture"), cls.replace("static", "obstacle")):
                if label in c:
                    cells.append(_pct(c[label]["agreement"]))
                    break
        print(
            f"| {r['task']} | {r['states']} | "
            + " | ".join(cells)
            + f" | {r['reward']['median']:.2g} | {r['reward']['p95']:.2g} | "
            f"{_pct(r['terminated_agreement'])} | {'; '.join(r['notes'])} |"
        )


def merge(results: dict[str, dict], name: str, row: dict) -> bool:
    """Puts `row` under `name` in `results`, unless the row is a failure ("error") and
    `results` holds a measured row there: a failed rerun never replaces a measurement.
    Returns whether it did."""
    if "error" in row and name in results and "error" not in results[name]:
        return False
    results[name] = row
    return True
