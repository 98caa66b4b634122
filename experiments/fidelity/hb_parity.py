"""Our tasks against HumanoidBench itself, state by state: contacts and rewards.

For each task, `--states` states are drawn on our side and scored by both implementations:

- States. Episodes start from our env's `reset` (keyframe 0 + U(+-0.01) noise + the task's
  randomisation, e.g. push's goal, cube's orientations) and roll uniform random actions in
  MuJoCo C on our compiled model (`env.mj_model`, the model MJX simulates), with our control
  mapping ctrl = low + (a + 1)/2 (high - low) over each actuator's ctrlrange (HumanoidBench's
  `unnormalize_action`; all 61 are position actuators), 10 `mj_step`s per control step. An
  episode ends when the pelvis falls (qpos z < 0.5) or after `--episode-steps` control steps;
  every `--every`th control step's (qpos, qvel, ctrl) is kept, with the episode's task state.
- Our reward: the task's `evaluate` (the code training runs), vmapped in one jit per task over
  `mjx.forward` of (qpos, qvel, ctrl), with the episode's reset task state. A task whose task
  state has a stage (`Transfer.stages`: maze, basketball, bookshelf) is scored once per
  stage, the stage forced on every state on both sides; other tasks get the reset task state
  ("task state not transferred" in the notes where HumanoidBench's side does not get it).
- HumanoidBench: `hb_side.py` under REFENV's Python (`--python`): HumanoidBench's own env
  (`gymnasium.make`), qpos/qvel/ctrl written joint by joint and actuator by actuator by NAME
  (`RENAME` holds per-task name maps where names differ; joints without a partner are
  reported), the hidden task state written where HumanoidBench keeps it (`HIDDEN`: push's and
  reach's goal, cube's target orientation in the model's body_quat, package's destination,
  window's start head position, spoon's counter, maze's, basketball's and bookshelf's stage,
  bookshelf_hard's drawn objects and goals), then
  `mj_forward` and the task's `get_reward()` and `get_terminated()`.
- Contacts: on our side MuJoCo C's `mj_forward` contacts on our own model (not MJX's: MJX's
  own contact differences are `contact_parity`'s subject), on HumanoidBench's side its
  `data.contact`; every contact in `d.contact[:ncon]` counts, as HumanoidBench's rules read them.
  Each geom gets a role from its body, in each model separately (so obstacles need not share
  names): robot = the subtree of `pelvis`, hand = the subtrees of `left_hand`/`right_hand`,
  object = a body with a free joint that is not the robot (and its subtree), floor = the
  `floor` geom (or a plane on the world), static = any other geom (fixtures in manipulation
  tasks: table, shelves...; obstacles in locomotion tasks: hurdles, walls, poles...). Classes:
  robot-fixture / robot-obstacle, hand-object, object-object (the issue's bar classes), and
  robot-floor, robot-object (non-hand), object-fixture, object-floor (reported, no bar).
  Agreement of a class = the fraction of states where both sides agree on whether any contact
  of the class exists; "n/a" where no state fires on either side.

Bars (issue 29): contact agreement >= 99% per class; reward median |d| <= 0.005 and
p95 <= 0.02 in exact mode (`hb_compat="exact"`, the default).

    .venv/bin/python -m experiments.fidelity.hb_parity --python REFENV/bin/python \
        --tasks push,cube,walk [--states 500] [--out docs/results/hb_parity.json]
        [--hb-checkout CHECKOUT] [--every 4] [--episode-steps 100] [--seed 0] [--keep DIR]

Tasks are short names (`push`) or ids (`h1hand-push-v0`). Prints one table row per task:
states, agreement per class, reward median and p95 |d|, termination agreement, notes (classes
under 99%, unmapped joints, how the task state travelled); writes the results keyed by task to
`--out`, merged into what the file already holds (with per-side fire counts, the most frequent
disagreeing body pairs, and per-term |d| of the reward terms both sides name alike). `--keep`
keeps the exchanged .npz files (our states, HumanoidBench's answers).
"""

from __future__ import annotations

import argparse
import collections
import dataclasses
import itertools
import json
import subprocess
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

from experiments.fidelity.hb_side import joint_key, model_tables
from sirl_jax.envs import load
from sirl_jax.envs.loading import spec as task_spec
from sirl_jax.hb_compat import CONTACT_SETS, HAND_FLOOR, HB
from sirl_jax.run.compile_cache import enable_compilation_cache

HB_SIDE = Path(__file__).with_name("hb_side.py")
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
ROBOT_ROOT, HANDS, FLOOR = "pelvis", ("left_hand", "right_hand"), "floor"
FALL_Z = 0.5
BAR_AGREEMENT, BAR_MEDIAN, BAR_P95 = 0.99, 0.005, 0.02
CLASSES = ("robot-static", "hand-object", "object-object",
           "robot-floor", "robot-object", "object-static", "object-floor")  # fmt: skip
BAR_CLASSES = ("robot-static", "hand-object", "object-object")


# -- roles and contact classes, one function for both models --------------------------------
def tables(m: mujoco.MjModel) -> dict[str, np.ndarray]:
    """The model tables `roles` reads, as hb_side.py writes them for HumanoidBench's model."""
    return model_tables(mujoco, m)


def roles(t: dict[str, np.ndarray]) -> tuple[list[str], list[str]]:
    """([ngeom] role, [ngeom] label): role in {hand, robot, object, floor, static}; label =
    the body name, or the geom name for a geom welded to the world."""
    names = [str(x) for x in t["body_name"]]
    parent = t["body_parent"]

    def under(b: int, roots: set[int]) -> bool:
        while b > 0:
            if b in roots:
                return True
            b = int(parent[b])
        return False

    robot = {names.index(ROBOT_ROOT)}
    hands = {names.index(h) for h in HANDS}
    objects = {b for b in range(len(names)) if t["body_free"][b] and b not in robot}
    out_role, out_label = [], []
    for g, (gname, b) in enumerate(zip(t["geom_name"], t["geom_body"], strict=True)):
        b, gname = int(b), str(gname)
        if under(b, hands):
            role = "hand"
        elif under(b, robot):
            role = "robot"
        elif under(b, objects):
            role = "object"
        elif gname == FLOOR or (b == 0 and t["geom_type"][g] == mujoco.mjtGeom.mjGEOM_PLANE):
            role = "floor"
        else:
            role = "static"
        out_role.append(role)
        welded = int(t["body_weldid"][b]) == 0
        out_label.append((gname or f"geom{g}") if welded else names[b])
    return out_role, out_label


def contact_class(r1: str, r2: str) -> str | None:
    a, b = sorted((r1, r2))
    pair = {a, b}
    if pair == {"hand", "object"}:
        return "hand-object"
    if a == b == "object":
        return "object-object"
    if "object" in pair:
        other = (pair - {"object"}).pop()
        return {"robot": "robot-object", "static": "object-static", "floor": "object-floor"}.get(
            other
        )
    if pair & {"hand", "robot"}:
        other = pair - {"hand", "robot"}
        if other == {"static"}:
            return "robot-static"
        if other == {"floor"}:
            return "robot-floor"
    return None  # robot-robot, static-floor, ...


def classify(t, state, g1, g2, n):
    """({class: [n] bool fired}, {class: [n] Counter of label pairs})."""
    role, label = roles(t)
    fired = {c: np.zeros(n, bool) for c in CLASSES}
    pairs = {c: [collections.Counter() for _ in range(n)] for c in CLASSES}
    for i, a, b in zip(state, g1, g2, strict=True):
        c = contact_class(role[a], role[b])
        if c is None:
            continue
        fired[c][i] = True
        pairs[c][i]["|".join(sorted((label[a], label[b])))] += 1
    return fired, pairs


# -- our side ---------------------------------------------------------------------------------
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


def our_contacts(m: mujoco.MjModel, qpos, qvel, ctrl):
    """(state, geom1, geom2, dist) of every contact of every state, MuJoCo C on our model."""
    d = mujoco.MjData(m)
    state, g1, g2, dist = [], [], [], []
    for i in range(len(qpos)):
        d.qpos[:], d.qvel[:], d.ctrl[:] = qpos[i], qvel[i], ctrl[i]
        mujoco.mj_forward(m, d)
        for c in d.contact[: d.ncon]:
            state.append(i)
            g1.append(int(c.geom1))
            g2.append(int(c.geom2))
            dist.append(float(c.dist))
    return state, g1, g2, dist


# -- why a state disagrees: how deep, how far -------------------------------------------------
GAP_MAX = 0.25
"""Our gap is measured up to this many metres (`mj_geomDistance`'s distmax)."""


def deepest(t, state, g1, g2, dist, n) -> dict[str, np.ndarray]:
    """{class: [n] deepest penetration (m, >= 0; nan where the class has no contact)}."""
    role, _ = roles(t)
    out = {c: np.full(n, np.nan) for c in CLASSES}
    for i, a, b, x in zip(state, g1, g2, dist, strict=True):
        c = contact_class(role[a], role[b])
        if c is not None:
            out[c][i] = np.fmax(out[c][i], -x)
    return out


class OurGap:
    """Where HumanoidBench's model touches and ours does not: how far apart our colliders are.

    HumanoidBench's contact (geom A, geom B) maps to our geoms by body: a robot or hand geom to
    our geoms on the body of the same name, an object geom to our object of the same body name,
    the floor to our floor, a fixture or obstacle geom to our geom of the same name, else to
    every fixture or obstacle geom of ours. Of those pairs, only the ones our contact bits let
    collide count (contype / conaffinity; parent-child and welded pairs are already apart in
    the robot-versus-world classes measured here). Gap = the smallest `mj_geomDistance` among
    them; None where no pair may collide (our contact set leaves the pair out)."""

    def __init__(self, m: mujoco.MjModel, hb_tables: dict[str, np.ndarray]):
        self.m, self.d = m, mujoco.MjData(m)
        ours = tables(m)
        self.role, _ = roles(ours)
        self.hb_role, _ = roles(hb_tables)
        body = [str(ours["body_name"][b]) for b in ours["geom_body"]]
        self.by_body = collections.defaultdict(list)
        self.by_name = {str(n): g for g, n in enumerate(ours["geom_name"]) if str(n)}
        self.by_role = collections.defaultdict(list)
        for g in range(m.ngeom):
            if m.geom_contype[g] or m.geom_conaffinity[g]:
                self.by_body[body[g]].append(g)
                self.by_role[self.role[g]].append(g)
        self.hb_body = [str(hb_tables["body_name"][b]) for b in hb_tables["geom_body"]]
        self.hb_name = [str(x) for x in hb_tables["geom_name"]]

    def _ours(self, g: int) -> list[int]:
        role = self.hb_role[g]
        if role in ("robot", "hand", "object"):
            mine = self.by_body.get(self.hb_body[g], [])
            return mine if mine or role != "object" else self.by_role["object"]
        mine = self.by_name.get(self.hb_name[g])
        if mine is not None and self.role[mine] == role:
            return [mine]
        return self.by_role[role]

    def __call__(self, qpos: np.ndarray, hb_pairs: list[tuple[int, int]]) -> float | None:
        m, d = self.m, self.d
        d.qpos[:] = qpos
        mujoco.mj_kinematics(m, d)
        best = None
        for a, b in hb_pairs:
            for x, y in itertools.product(self._ours(a), self._ours(b)):
                if not (m.geom_contype[x] & m.geom_conaffinity[y]
                        or m.geom_contype[y] & m.geom_conaffinity[x]):  # fmt: skip
                    continue
                gap = mujoco.mj_geomDistance(m, d, x, y, GAP_MAX, None)
                best = gap if best is None else min(best, gap)
        return best


def _mm(x) -> dict:
    a = np.asarray([v for v in x if v is not None and np.isfinite(v)]) * 1000.0
    if not len(a):
        return {}
    return {"p50": round(float(np.median(a)), 1), "p95": round(float(np.percentile(a, 95)), 1),
            "max": round(float(a.max()), 1)}  # fmt: skip


# -- comparison -------------------------------------------------------------------------------
def _stats(delta: np.ndarray) -> dict:
    a = np.abs(delta[np.isfinite(delta)])
    if not len(a):
        return {"median": None, "p95": None, "max": None}
    return {"median": float(np.median(a)), "p95": float(np.percentile(a, 95)),
            "max": float(a.max())}  # fmt: skip


def check(name: str, args, workdir: Path) -> dict:
    t0 = time.perf_counter()
    spec, env = load(name, contact_set=args.contact_set, hand_floor=args.hand_floor)
    short = name.removeprefix("h1hand-").removesuffix("-v0")
    notes = []
    kind = "fixture" if env.task.contacts == "manipulation" else "obstacle"
    qpos, qvel, ctrl, task, episodes = draw_states(
        env, args.states, args.every, args.episode_steps, args.seed
    )
    n = len(qpos)
    task_leaves = jax.tree.leaves(task)
    transfer = HIDDEN.get(short)
    hidden_kind = transfer.kind if transfer else ""
    if task_leaves and not transfer:
        notes.append("task state not transferred to HumanoidBench; stages not forced")
    elif task_leaves:
        notes.append(f"task state written to HumanoidBench as {hidden_kind}")
    hidden = transfer.pick(task) if transfer else np.zeros((n, 0))

    m = env.mj_model

    def hb_side(tag: str, hidden: np.ndarray):
        """HumanoidBench's answers on the states with this hidden task state, or an error."""
        states_file = workdir / f"{short}{tag}_states.npz"
        hb_file = workdir / f"{short}{tag}_hb.npz"
        np.savez(
            states_file,
            task=np.array(name),
            joint_names=np.array([joint_key(m, j) for j in range(m.njnt)]),
            jnt_qposadr=np.asarray(m.jnt_qposadr), jnt_dofadr=np.asarray(m.jnt_dofadr),
            jnt_type=np.asarray(m.jnt_type),
            actuator_names=np.array([m.actuator(a).name for a in range(m.nu)]),
            qpos=qpos, qvel=qvel, ctrl=ctrl,
            hidden_kind=np.array(hidden_kind), hidden=hidden,
            rename_json=np.array(json.dumps(RENAME.get(short, {}))),
        )  # fmt: skip
        cmd = [args.python, str(HB_SIDE), "--task", name, "--states", str(states_file),
               "--out", str(hb_file), "--seed", str(args.seed)]  # fmt: skip
        if args.hb_checkout:
            cmd += ["--hb-checkout", args.hb_checkout]
        run = subprocess.run(cmd, capture_output=True, text=True)
        if run.returncode != 0:
            return " / ".join((run.stderr or run.stdout).strip().splitlines()[-3:])
        return np.load(hb_file, allow_pickle=False)

    reward, terminated, metrics = our_rewards(env, qpos, qvel, ctrl, task)
    hb = hb_side("", hidden)
    if isinstance(hb, str):
        return {"task": name, "states": n, "error": hb, "notes": notes}
    stages = {}
    for stage in transfer.stages if transfer else ():
        forced = transfer.force(task, stage)
        ours = our_rewards(env, qpos, qvel, ctrl, forced)[0]
        hb_s = hb_side(f"_stage{stage}", transfer.pick(forced))
        if isinstance(hb_s, str):
            return {"task": name, "states": n, "error": f"stage {stage}: {hb_s}", "notes": notes}
        stages[str(stage)] = {**_stats(ours - hb_s["reward"]), "ours_mean": float(ours.mean()),
                              "hb_mean": float(hb_s["reward"].mean())}  # fmt: skip
    if stages:
        notes.append(f"stages forced in turn: {', '.join(stages)}")

    ours_con = our_contacts(m, qpos, qvel, ctrl)
    hb_con = (hb["con_state"], hb["con_g1"], hb["con_g2"], hb["con_dist"])
    ours_t = tables(m)
    ours_fired, ours_pairs = classify(ours_t, *ours_con[:3], n)
    hb_fired, hb_pairs = classify(hb, *hb_con[:3], n)
    ours_deep, hb_deep = deepest(ours_t, *ours_con, n), deepest(hb, *hb_con, n)
    gap = OurGap(m, hb)
    hb_role, _ = roles(hb)
    hb_at = collections.defaultdict(list)  # (class, state) -> HumanoidBench's geom pairs
    for i, a, b in zip(*hb_con[:3], strict=True):
        hb_at[contact_class(hb_role[a], hb_role[b]), int(i)].append((int(a), int(b)))
    contacts = {}
    for c in CLASSES:
        o, h = ours_fired[c], hb_fired[c]
        label = c.replace("static", kind)
        if not (o.any() or h.any()):
            contacts[label] = {"agreement": None, "ours_fires": 0, "hb_fires": 0,
                               "bar": c in BAR_CLASSES}  # fmt: skip
            continue
        only_ours, only_hb = collections.Counter(), collections.Counter()
        for i in np.flatnonzero(o != h):
            (only_ours if o[i] else only_hb).update(ours_pairs[c][i] if o[i] else hb_pairs[c][i])
        hb_only = np.flatnonzero(h & ~o)
        gaps = [gap(qpos[i], hb_at[c, int(i)]) for i in hb_only]
        contacts[label] = {
            "agreement": float((o == h).mean()),
            "ours_fires": int(o.sum()),
            "hb_fires": int(h.sum()),
            "bar": c in BAR_CLASSES,
            "ours_only_pairs": [f"{k}: {v}" for k, v in only_ours.most_common(5)],
            "hb_only_pairs": [f"{k}: {v}" for k, v in only_hb.most_common(5)],
            # states where only one side touches: how deep that side's contact is, and (only
            # HumanoidBench's) how far apart our colliders are there (`OurGap`); in mm
            "ours_only_states": int((o & ~h).sum()),
            "hb_only_states": len(hb_only),
            "ours_only_depth_mm": _mm(ours_deep[c][o & ~h]),
            "hb_only_depth_mm": _mm(hb_deep[c][hb_only]),
            "hb_only_our_gap_mm": _mm(gaps),
            "hb_only_no_pair": sum(g is None for g in gaps),
        }

    for label, v in contacts.items():
        if v["agreement"] is None or v["agreement"] >= BAR_AGREEMENT:
            continue
        side = " (never on ours)" if not v["ours_fires"] else ""
        side = " (never on HumanoidBench's)" if not v["hb_fires"] else side
        bar = "below the bar" if v["bar"] else "no bar"
        notes.append(f"{label} {100 * v['agreement']:.1f}%, {bar}{side}")
    hb_reward = hb["reward"]
    delta = reward - hb_reward
    keys = [str(k) for k in hb["info_keys"]]
    terms = {k: _stats(metrics[k] - hb["info"][:, keys.index(k)]) for k in metrics if k in keys}
    for key, label in (("unmapped_ours", "our joints"), ("unmapped_hb", "HumanoidBench joints"),
                       ("unmapped_actuators", "actuators")):  # fmt: skip
        if len(hb[key]):
            notes.append(f"unmapped {label}: {', '.join(map(str, hb[key]))}")
    if len(hb["stubbed_assets"]):
        notes.append(f"textures stubbed on HumanoidBench's side: {len(hb['stubbed_assets'])}")
    if env.task.reads_contact_slots:
        notes.append("our reward reads MJX contacts")
    if getattr(env.task, "contact_rule", None) == "query":
        notes.append("our reward's contact rule: exact robot-obstacle pair query on MJX")
    worst = np.argsort(-np.abs(delta))[:3]
    result = {
        "task": name,
        "states": n,
        "episodes": episodes,
        "hb_compat": "exact",
        "contact_set": args.contact_set,
        "hand_floor": args.hand_floor,
        "contacts_ours": "MuJoCo C mj_forward on our model (MJX contacts: contact_parity)",
        "contacts": contacts,
        "reward": {
            **_stats(delta),
            "ours_mean": float(reward.mean()),
            "hb_mean": float(hb_reward.mean()),
            "worst": [
                {"state": int(i), "ours": float(reward[i]), "hb": float(hb_reward[i])}
                for i in worst
            ],
        },
        "terms": terms,
        "stages": stages,
        "terminated_agreement": float((terminated == hb["terminated"]).mean()),
        "passes": {
            "contacts": all(
                v["agreement"] is None or v["agreement"] >= BAR_AGREEMENT
                for v in contacts.values()
                if v["bar"]
            ),
            "reward": all(
                r["median"] <= BAR_MEDIAN and r["p95"] <= BAR_P95
                for r in (_stats(delta), *stages.values())
            ),
        },
        "notes": notes,
        "hb_mujoco": str(hb["mujoco_version"]),
        "ours_mujoco": mujoco.__version__,
        "seconds": round(time.perf_counter() - t0, 1),
    }
    return result


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


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--python", required=True, help="REFENV/bin/python (HumanoidBench's venv)")
    p.add_argument("--tasks", default="push,cube,walk")
    p.add_argument("--states", type=int, default=500)
    p.add_argument("--every", type=int, default=4, help="keep every N-th control step's state")
    p.add_argument("--episode-steps", type=int, default=100)
    p.add_argument("--hb-checkout", default=None, help="CHECKOUT, if REFENV lacks humanoid_bench")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--contact-set",
        choices=CONTACT_SETS,
        default=HB,
        help="our manipulation scenes' contact set (sirl_jax/hb_compat.py)",
    )
    p.add_argument(
        "--hand-floor",
        choices=HAND_FLOOR,
        default=HAND_FLOOR[0],
        help="which of our hand colliders touch the floor (sirl_jax/hb_compat.py)",
    )
    p.add_argument("--out", type=Path, default=None)
    p.add_argument("--keep", type=Path, default=None, help="folder for the exchanged .npz files")
    args = p.parse_args(argv)
    enable_compilation_cache()
    names = [task_spec(t).id for t in args.tasks.split(",")]  # ids or aliases
    results: dict[str, dict] = {}
    if args.out and args.out.exists():
        results = json.loads(args.out.read_text())
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        workdir = args.keep or Path(tmp)
        workdir.mkdir(parents=True, exist_ok=True)
        for name in names:
            row = check(name, args, workdir)
            rows.append(row)
            print(json.dumps(row), flush=True)
            if not merge(results, name, row):
                print(f"{name}: failed; {args.out} keeps its earlier row", flush=True)
                continue
            if args.out:
                args.out.parent.mkdir(parents=True, exist_ok=True)
                tmp = args.out.with_suffix(".tmp")
                tmp.write_text(json.dumps(results, indent=1) + "\n")
                tmp.replace(args.out)
    print_table(rows)


if __name__ == "__main__":
    main()
