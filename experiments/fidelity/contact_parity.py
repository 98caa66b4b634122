"""Contact-rule agreement of the obstacle tasks: MJX against MuJoCo C with every pair enabled.

For hurdle, maze, pole, balance_simple and balance_hard: roll E envs of uniform random actions
in MJX (each env's first episode, up to its termination), draw `--states` of the visited
(qpos, qvel), and evaluate on each state

- MJX: `mjx.forward` on the task's own model, then the task's `evaluate` (the code training
  runs): the collision discount (`wall_collision_discount` / `collision_discount`) and the
  termination;
- MuJoCo C: `mj_forward` on a copy of the same model in which every robot geom (hands
  included) collides with every obstacle geom and the floor, then HumanoidBench's rule applied
  to `d.contact` (written here from HumanoidBench's task files, not from sirl_jax's code):
  hurdle: a contact with a side or back barrier; maze: a contact with a block; pole: a contact
  with a pole that does not involve the floor; balance: root z < 0.8, a sphere contact with
  neither the floor nor the board, or a floor contact without the sphere.

    .venv/bin/python -m experiments.fidelity.contact_parity [--tasks hurdle,maze] [--states 1000]
        [--contact-rule query|contacts] [--num-envs 64] [--steps 80] [--seed 0]
        [--out docs/results/contact_parity.json]

Prints per task: agreement, how many states each side fires on, and the disagreements split
into C-only and MJX-only (with the geoms of the C contacts that MJX missed). It also reports
how complete MJX's physical contacts are: of the penetrating robot-obstacle pairs C finds,
how many MJX's model does not collide at all (`pairs_off`), and how many it collides but had
no penetrating slot for on that state (`pairs_missed`: pruned by `max_geom_pairs`, or missed
by the narrow phase).
"""

from __future__ import annotations

import argparse
import collections
import copy
import json
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx
from mujoco.mjx._src.collision_driver import geom_pairs

from sirl_jax.envs.h1 import GEOM_GROUPS
from sirl_jax.envs.humanoid import HumanoidEnv, contact_arrays
from sirl_jax.envs.tasks.locomotion.balance import BalanceTask
from sirl_jax.envs.tasks.locomotion.obstacles import HurdleTask, MazeTask, PoleTask

TASKS = {
    "hurdle": HurdleTask,
    "maze": MazeTask,
    "pole": PoleTask,
    "balance_simple": lambda rule: BalanceTask("balance_simple", rule),
    "balance_hard": lambda rule: BalanceTask("balance_hard", rule),
}
_PARITY_BIT = 1 << 10
"""Bit the C reference model gives every robot geom and every obstacle geom."""


def _obstacle_prefixes(task: str) -> tuple[str, ...]:
    return {
        "hurdle": ("left_barrier", "right_barrier", "behind_barrier", "hurdle"),
        "maze": ("block_collision",),
        "pole": ("pole_r",),
        "balance_simple": ("pivot_sphere_collision", "stand_board_collision"),
        "balance_hard": ("pivot_sphere_collision", "stand_board_collision"),
    }[task]


def reference_model(model: mujoco.MjModel, task: str) -> mujoco.MjModel:
    """A copy of `model` in which every robot geom touches every obstacle geom and the floor
    (no robot self-collision, as in sirl_jax's robot)."""
    m = copy.copy(model)  # MjModel's copy is a deep copy
    robot = {n for names in GEOM_GROUPS.values() for n in names} | {"left_fist", "right_fist"}
    prefixes = _obstacle_prefixes(task)
    for g in range(m.ngeom):
        name = m.geom(g).name
        if name in robot:
            m.geom_contype[g] = 2  # floor conaffinity 2
            m.geom_conaffinity[g] = 1 | _PARITY_BIT
        elif name.startswith(prefixes):
            m.geom_contype[g] |= _PARITY_BIT
    # MuJoCo C's broad phase filters bodies first, by the OR of their geoms' bits (set at
    # compile time): recompute it.
    m.body_contype[:] = 0
    m.body_conaffinity[:] = 0
    for g in range(m.ngeom):
        m.body_contype[m.geom_bodyid[g]] |= m.geom_contype[g]
        m.body_conaffinity[m.geom_bodyid[g]] |= m.geom_conaffinity[g]
    # Its mid-phase bounding-volume trees are also built at compile time, from the geoms that
    # collided then: a geom enabled here (the "links" capsules outside the obstacle tasks) is not
    # in them and its contacts are silently skipped. Without the mid-phase every geom pair of
    # two colliding bodies is tested.
    m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_MIDPHASE
    return m


def reference_rule(m: mujoco.MjModel, d: mujoco.MjData, task: str) -> tuple[bool, bool, list]:
    """(discounted, terminated, contacts that fired) by HumanoidBench's rule on `d.contact`."""
    names = [m.geom(g).name for g in range(m.ngeom)]
    pairs = [(names[int(c.geom1)], names[int(c.geom2)]) for c in d.contact[: d.ncon]]
    if task.startswith("balance"):
        sphere, board, floor = "pivot_sphere_collision", "stand_board_collision", "floor"
        bad = [
            p for p in pairs
            if (sphere in p and floor not in p and board not in p)
            or (floor in p and sphere not in p)
        ]  # fmt: skip
        return False, bool(d.qpos[2] < 0.8 or bad), bad
    if task == "pole":
        hits = [p for p in pairs if any(n.startswith("pole_r") for n in p) and "floor" not in p]
    elif task == "maze":
        hits = [p for p in pairs if any(n.startswith("block_collision") for n in p)]
    else:
        walls = ("left_barrier_collision", "right_barrier_collision", "behind_barrier_collision")
        hits = [p for p in pairs if any(n.startswith(walls) for n in p)]
    return bool(hits), False, hits


def rollout_states(env, num_envs: int, steps: int, seed: int) -> np.ndarray:
    """[M, nq + nv] the (qpos, qvel) of each env's first episode (up to its termination) under
    uniform random actions."""

    def run(key):
        keys = jax.random.split(key, num_envs + 1)
        state = jax.vmap(env.reset)(keys[1:])
        actions = jax.random.uniform(keys[0], (steps, num_envs, env.action_size), minval=-1.0)

        def body(carry, a):
            state, alive = carry
            state = jax.vmap(env.step)(state, a)
            row = jnp.concatenate([state.physics.qpos, state.physics.qvel], axis=-1)
            return (state, alive & ~state.terminated), (row, alive)

        alive = jnp.ones((num_envs,), bool)
        _, (rows, valid) = jax.lax.scan(body, (state, alive), actions)
        return rows, valid  # [T, E, D], [T, E] (the terminating step counts as valid)

    rows, valid = jax.jit(run)(jax.random.PRNGKey(seed))
    return np.asarray(rows)[np.asarray(valid)]


def mjx_rule(env, states: np.ndarray, batch: int = 250) -> tuple[np.ndarray, ...]:
    """[M] discounted, [M] terminated from the task's `evaluate` after `mjx.forward`, and the
    [M, C] contact slots' dist and [M, C, 2] geoms of that forward pass."""
    nq = env.mj_model.nq
    task_state = jax.eval_shape(env.reset, jax.random.PRNGKey(0)).task
    task_state = jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), task_state)
    discount_key = next((k for k in env.task.metric_names if "collision_discount" in k), None)

    @jax.jit
    def rule(x):
        def one(row):
            d = mjx.make_data(env.mx).replace(qpos=row[:nq], qvel=row[nq:])
            d = mjx.forward(env.mx, d)
            _, terminated, _, terms = env.task.evaluate(env.robot, d, task_state)
            disc = terms[discount_key] < 1.0 if discount_key else jnp.zeros((), bool)
            return disc, terminated, *contact_arrays(d)

        return jax.vmap(one)(x)

    out = [rule(jnp.asarray(states[i : i + batch])) for i in range(0, len(states), batch)]
    return tuple(np.concatenate([np.asarray(o[k]) for o in out]) for k in range(4))


def check(task: str, rule: str, n_states: int, num_envs: int, steps: int, seed: int) -> dict:
    env = HumanoidEnv(TASKS[task](rule), "h1hand")
    t0 = time.perf_counter()
    states = rollout_states(env, num_envs, steps, seed)
    rng = np.random.default_rng(seed)
    if len(states) > n_states:
        states = states[rng.choice(len(states), n_states, replace=False)]
    mjx_disc, mjx_term, slot_dist, slot_geom = mjx_rule(env, states)
    m = reference_model(env.mj_model, task)
    d = mujoco.MjData(m)
    nq = m.nq
    modelled = {tuple(sorted(p[:2])) for p in geom_pairs(env.mj_model)}
    obstacle = {g for g in range(m.ngeom) if m.geom(g).name.startswith(_obstacle_prefixes(task))}
    c_disc, c_term, missed = [], [], collections.Counter()
    pairs_c = pairs_off = pairs_missed = 0
    for i, row in enumerate(states):
        d.qpos[:], d.qvel[:] = row[:nq], row[nq:]
        mujoco.mj_forward(m, d)
        disc, term, pairs = reference_rule(m, d, task)
        c_disc.append(disc)
        c_term.append(term)
        mine = mjx_term[i] if task.startswith("balance") else mjx_disc[i]
        if (term or disc) and not mine:
            missed.update(tuple(sorted(p)) for p in pairs)
        found = {tuple(sorted(g)) for g in slot_geom[i][slot_dist[i] < 0].tolist()}
        touching = {
            tuple(sorted((int(c.geom1), int(c.geom2))))
            for c in d.contact[: d.ncon]
            if c.dist < 0 and (int(c.geom1) in obstacle or int(c.geom2) in obstacle)
        }
        pairs_c += len(touching)
        pairs_off += len(touching - modelled)
        pairs_missed += len((touching & modelled) - found)
    c = np.asarray(c_term if task.startswith("balance") else c_disc)
    x = mjx_term if task.startswith("balance") else mjx_disc
    return {
        "task": task,
        "rule": "termination" if task.startswith("balance") else "discount",
        "contact_rule": rule,
        "states": int(len(states)),
        "agreement": float((c == x).mean()),
        "c_fires": int(c.sum()),
        "mjx_fires": int(x.sum()),
        "c_only": int((c & ~x).sum()),
        "mjx_only": int((x & ~c).sum()),
        "missed_pairs": [f"{a}|{b}: {n}" for (a, b), n in missed.most_common(8)],
        "pairs_c": pairs_c,
        "pairs_off": pairs_off,
        "pairs_missed": pairs_missed,
        "seconds": round(time.perf_counter() - t0, 1),
    }


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--tasks", default=",".join(TASKS))
    p.add_argument("--states", type=int, default=1000)
    p.add_argument("--contact-rule", default="query", choices=("query", "contacts"))
    p.add_argument("--num-envs", type=int, default=64)
    p.add_argument("--steps", type=int, default=80)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args(argv)
    rows = []
    for task in args.tasks.split(","):
        if task not in TASKS:
            raise SystemExit(f"error: unknown task {task!r}; allowed: {', '.join(TASKS)}")
        row = check(task, args.contact_rule, args.states, args.num_envs, args.steps, args.seed)
        rows.append(row)
        print(json.dumps(row), flush=True)
        if args.out:
            args.out.parent.mkdir(parents=True, exist_ok=True)
            args.out.write_text(json.dumps(rows, indent=1) + "\n")
    print(
        "\n| task | rule | states | agreement | C fires | MJX fires | C only | MJX only "
        "| C pairs | not collided | missed |"
    )
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        print(
            f"| {r['task']} | {r['rule']} | {r['states']} | {100 * r['agreement']:.1f}% | "
            f"{r['c_fires']} | {r['mjx_fires']} | {r['c_only']} | {r['mjx_only']} | "
            f"{r['pairs_c']} | {r['pairs_off']} | {r['pairs_missed']} |"
        )


if __name__ == "__main__":
    main()
