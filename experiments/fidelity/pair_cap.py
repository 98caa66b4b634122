"""Which touching geom pairs MJX's `max_geom_pairs` cull drops, and how many active contacts its
`max_contact_points` budget must hold, task by task.

MJX groups the candidate geom pairs by collision function (geom types, mesh ids, condim) and,
in a group with more candidates than the model's `max_geom_pairs` numeric, runs the collision
function only on the `max_geom_pairs` pairs whose bounding spheres overlap most
(`mujoco.mjx._src.collision_driver.collision`: distance between centres minus the two
`geom_rbound`s, `top_k` of its negative). A pair that touches but ranks lower is not collided:
in MJX its geoms pass through each other.

For each task this draws states as `hb_parity` does (our env's reset, uniform random actions
in MuJoCo C on the model MJX compiles, 10 `mj_step`s per control step), takes MuJoCo C's
contacts of each state (every pair in `d.contact`: C runs the full broad phase), ranks every
culled group's candidates as MJX does on the same `geom_xpos`, and reports per group:

- `candidates`: the group's candidate pairs; `cap`: the task's `max_geom_pairs`;
- `touching_max`: the most pairs of the group that touch in one state;
- `dropped_states`: the fraction of states in which at least one touching pair ranks past
  the cap (MJX does not collide it), and `dropped_mean` pairs per state;
- `cap_needed_p99`: the cap under which every touching pair of the group is kept in 99% of
  the states (the 99th percentile of the worst touching pair's rank);
- `dropped_states_at`: `dropped_states` under each cap of `--caps` (what raising the task's
  `max_geom_pairs` would buy).

And, under `active`, the contacts the solver must see: MJX's own collision (`mjx.kinematics`,
`mjx.collision`, the task's `max_geom_pairs`, no contact budget) on the same states, counting
the active contacts (dist < 0) of each state:

- `mean`, `p99`, `max` per state, and the reset pose's count (`reset`);
- `full_states_at`: the share of states whose active contacts fill each budget of
  `--budgets` (with `max_contact_points` k, MJX's solver sees the k most penetrating contacts,
  so a state with k or more active ones may lose one); `budget`: the task's own.

    .venv/bin/python -m experiments.fidelity.pair_cap --tasks bookshelf_simple,room \
        --states 300 --out docs/results/pair_cap.json
"""

from __future__ import annotations

import copy
import dataclasses
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import tyro
from mujoco import mjx
from mujoco.mjx._src import collision_driver

from experiments.fidelity.hb_parity import draw_states
from sirl_jax.envs import load
from sirl_jax.envs.physics import contact_arrays, contact_budget
from sirl_jax.envs.tasks import MANIPULATION

_TYPE = {int(v): k.removeprefix("mjGEOM_").lower() for k, v in mujoco.mjtGeom.__members__.items()}


def culled_groups(m: mujoco.MjModel) -> dict[str, np.ndarray]:
    """{group name: [n, 2] candidate geom pairs} of the groups MJX culls in `m`."""
    cap = collision_driver._numeric(m, "max_geom_pairs")
    out = {}
    for key, pairs in collision_driver._geom_groups(m).items():
        if cap < 0 or len(pairs) <= cap or set(key.types) & collision_driver._GEOM_NO_BROADPHASE:
            continue
        name = "-".join(_TYPE[int(t)] for t in key.types)
        if any(i >= 0 for i in key.data_ids):
            name += f"[mesh {','.join(str(int(i)) for i in key.data_ids)}]"
        out[f"{name} condim {int(key.condim)}"] = np.asarray(pairs)[:, :2]
    return out


def ranks(m: mujoco.MjModel, d: mujoco.MjData, pairs: np.ndarray) -> np.ndarray:
    """Each candidate pair's 0-based rank in MJX's cull on `d.geom_xpos` (0: collided first)."""
    g1, g2 = pairs[:, 0], pairs[:, 1]
    dist = np.linalg.norm(d.geom_xpos[g2] - d.geom_xpos[g1], axis=1)
    dist -= m.geom_rbound[g1] + m.geom_rbound[g2]
    order = np.argsort(dist, kind="stable")  # top_k of -dist keeps the lower index on ties
    rank = np.empty(len(pairs), int)
    rank[order] = np.arange(len(pairs))
    return rank


def active_contacts(m: mujoco.MjModel, qpos: np.ndarray, chunk: int = 100) -> np.ndarray:
    """[n] active contacts (dist < 0) of MJX's collision at each of `qpos` [n, nq], with the
    model's `max_geom_pairs` cull and without its contact budget."""
    m = copy.copy(m)
    i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_NUMERIC, "max_contact_points")
    if i >= 0:
        m.numeric_data[m.numeric_adr[i]] = -1.0
    mx = mjx.put_model(m, impl="jax")
    d0 = mjx.make_data(mx)

    @jax.jit
    def count(qp):
        def one(q):
            d = mjx.collision(mx, mjx.kinematics(mx, d0.replace(qpos=q)))
            return jnp.sum(contact_arrays(d)[0] < 0)

        return jax.vmap(one)(qp)

    n = len(qpos)
    pad = np.concatenate([qpos, np.repeat(qpos[-1:], -n % chunk, 0)])
    out = [np.asarray(count(jnp.asarray(c, jnp.float32))) for c in np.split(pad, len(pad) // chunk)]
    return np.concatenate(out)[:n]


def budget_row(env, qpos: np.ndarray, budgets: tuple[int, ...]) -> dict:
    """The `active` entry of `check`: active contacts at the drawn states and at a reset."""
    m = env.mj_model
    active = active_contacts(m, qpos)
    start = np.asarray(env.reset(jax.random.PRNGKey(0)).physics.qpos)
    reset = int(active_contacts(m, start[None])[0])
    return {
        "budget": contact_budget(m),
        "reset": reset,
        "mean": float(active.mean()),
        "p99": int(np.percentile(active, 99, method="higher")),
        "max": int(active.max()),
        "full_states_at": {str(k): float((active >= k).mean()) for k in budgets},
    }


def check(task: str, n_states: int, seed: int, contact_set: str, caps: tuple[int, ...],
          budgets: tuple[int, ...] = ()) -> dict:  # fmt: skip
    spec, env = load(task, contact_set=contact_set)
    m = env.mj_model
    cap = collision_driver._numeric(m, "max_geom_pairs")
    groups = culled_groups(m)
    qpos, qvel, ctrl, _, episodes = draw_states(env, n_states, every=4, episode_steps=100,
                                                seed=seed)  # fmt: skip
    d = mujoco.MjData(m)
    index = {g: {(int(a), int(b)): i for i, (a, b) in enumerate(p)} for g, p in groups.items()}
    touching = {g: np.zeros(n_states, int) for g in groups}
    dropped = {g: np.zeros(n_states, int) for g in groups}
    worst = {g: np.full(n_states, -1) for g in groups}
    for s in range(n_states):
        d.qpos[:], d.qvel[:], d.ctrl[:] = qpos[s], qvel[s], ctrl[s]
        mujoco.mj_forward(m, d)
        touch = {
            (int(min(c.geom1, c.geom2)), int(max(c.geom1, c.geom2))) for c in d.contact[: d.ncon]
        }
        for g, pairs in groups.items():
            hit = [index[g][p] for p in touch if p in index[g]]
            hit += [index[g][p[::-1]] for p in touch if p[::-1] in index[g]]
            if not hit:
                continue
            r = ranks(m, d, pairs)[hit]
            touching[g][s], dropped[g][s], worst[g][s] = len(hit), int((r >= cap).sum()), r.max()
    rows = {}
    for g, pairs in groups.items():
        fired = worst[g] >= 0
        rows[g] = {
            "candidates": len(pairs),
            "touching_max": int(touching[g].max()),
            "touching_states": float(fired.mean()),
            "dropped_states": float((dropped[g] > 0).mean()),
            "dropped_mean": float(dropped[g].mean()),
            "cap_needed_p99": int(np.percentile(worst[g] + 1, 99, method="higher")),
            "dropped_states_at": {str(k): float((worst[g] >= k).mean()) for k in caps},
        }
    out = {"task": spec.id, "contact_set": contact_set, "cap": cap, "states": n_states,
           "episodes": episodes, "groups": rows}  # fmt: skip
    if budgets:
        out["active"] = budget_row(env, qpos, budgets)
    return out


@dataclasses.dataclass
class Args:
    tasks: str = ",".join(row.name for row in MANIPULATION)
    """Comma-separated task names or ids (default: the 17 manipulation tasks)."""
    states: int = 300
    seed: int = 0
    contact_set: str = "hb"
    caps: str = "8,12,16,24,32,48,64"
    """Caps to report `dropped_states_at` for."""
    budgets: str = "32,48,64,96,128"
    """Contact budgets to report `active.full_states_at` for (empty: skip the MJX count)."""
    out: str = ""
    """JSON file to write (merged by task id with what it already holds)."""


def main(args: Args) -> None:
    results = json.loads(Path(args.out).read_text()) if args.out and Path(args.out).exists() else {}
    for task in args.tasks.split(","):
        caps = tuple(int(k) for k in args.caps.split(","))
        budgets = tuple(int(k) for k in args.budgets.split(",") if k)
        row = check(task, args.states, args.seed, args.contact_set, caps, budgets)
        results[row["task"]] = row
        print(f"{row['task']} (cap {row['cap']}, {row['states']} states)")
        for g, r in row["groups"].items():
            print(
                f"  {g:32s} candidates {r['candidates']:5d}  touching max {r['touching_max']:3d}"
                f"  dropped in {100 * r['dropped_states']:5.1f}% of states"
                f" ({r['dropped_mean']:.2f}/state)  cap for 99%: {r['cap_needed_p99']}"
            )
            print(
                "    dropped in % of states at cap "
                + "  ".join(f"{k}: {100 * v:.1f}" for k, v in r["dropped_states_at"].items())
            )
        if "active" in row:
            a = row["active"]
            print(f"  active contacts (MJX, no budget; the task's budget {a['budget'] or 'none'}):"
                  f" reset {a['reset']}, mean {a['mean']:.1f}, p99 {a['p99']}, max {a['max']}")
            print("    states filling the budget, % at "
                  + "  ".join(f"{k}: {100 * v:.1f}" for k, v in a["full_states_at"].items()))
        if args.out:
            Path(args.out).write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main(tyro.cli(Args))
