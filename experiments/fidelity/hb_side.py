"""HumanoidBench's side of `hb_parity`: its own env scores states written by our harness.

Runs under HumanoidBench's Python (REFENV/bin/python, with `humanoid_bench` installed or
importable from `--hb-checkout`); it imports only humanoid_bench, gymnasium, mujoco and numpy
(never sirl_jax), so the two venvs stay apart.

    REFENV/bin/python experiments/fidelity/hb_side.py --task h1hand-push-v0 \
        --states states.npz --out hb.npz [--hb-checkout CHECKOUT]

For the task it makes `gymnasium.make(task, render_mode=None)` (HumanoidBench's env), resets
it once, and for each state of `--states`:

1. writes qpos and qvel into its `MjData` joint by joint, matching our joint names to its own
   (after the optional rename map; an unnamed joint by its body and its place there,
   `joint_key`), and ctrl actuator by actuator, likewise by name;
2. writes the task's hidden state where the harness names one (`hidden_kind`):
   `attr:NAME` sets `task.NAME` (push's and reach's goal, window's `head_pos0`, spoon's
   `step_counter`; a single column is written as a scalar), `body_quat:BODY` the model's
   body_quat (cube's target orientation, which HumanoidBench writes there), `body_pos:BODY`
   the body's position (package's destination), `basketball_stage` basketball's `stage`
   ("catch" for 0, "throw" for 1), `bookshelf` bookshelf's `task_index` (and for a 25-column
   state also `bookshelf_objects` and `placement_goals`), and `maze_stage` maze's
   `maze_stage`, with the `move_direction` that HumanoidBench's own `update_move_direction`
   leaves at that stage (`_maze_stages`: the pelvis is put on each checkpoint in turn from a
   reset, so the directions are HumanoidBench's, not ours);
3. runs `mj_forward` and calls the task's `get_reward()` -> (reward, info) and
   `get_terminated()` -> (terminated, info);
4. records every contact in `data.contact[:ncon]` as (state, geom1, geom2, dist).

The output .npz also carries the model's tables (geom names and bodies, body names, parents,
weld ids, which bodies carry a free joint) so that the harness classifies both models' contacts
with one function, and the joints/actuators that found no partner by name.

Textures a checkout lacks (a repository snapshot without its large image files) are replaced
by a 1x1 PNG in MuJoCo's asset dictionary: visual only, physics untouched; the replaced file
names are in the output (`stubbed_assets`).

Input .npz keys (written by `hb_parity`): task, joint_names, jnt_qposadr, jnt_dofadr, jnt_type,
qpos [N, nq], qvel [N, nv], actuator_names, ctrl [N, nu], hidden_kind, hidden [N, k],
rename_json.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import struct
import sys
import zlib

import numpy as np

_QPOS_SIZE = {0: 7, 1: 4, 2: 1, 3: 1}  # mjtJoint: free, ball, slide, hinge
_DOF_SIZE = {0: 6, 1: 3, 2: 1, 3: 1}


def _tiny_png() -> bytes:
    """A valid 1x1 grey RGB PNG."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        crc = zlib.crc32(kind + data) & 0xFFFFFFFF
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", crc)

    header = struct.pack(">IIBBBBB", 1, 1, 8, 2, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", header)
        + chunk(b"IDAT", zlib.compress(b"\x00\x80\x80\x80"))
        + chunk(b"IEND", b"")
    )


STUBBED: list[str] = []


def _patch_missing_textures(mujoco) -> None:
    """`MjModel.from_xml_path` that retries with a stub for each missing image file."""
    original = mujoco.MjModel.from_xml_path

    def from_xml_path(path, assets=None):
        assets = dict(assets or {})
        while True:
            try:
                return original(path, assets)
            except ValueError as e:
                found = re.search(r"resource not found[^']*'([^']+\.(png|jpg|jpeg))'", str(e))
                name = found and os.path.basename(found.group(1))
                if not name or name in assets:
                    raise
                assets[name] = _tiny_png()
                STUBBED.append(name)

    mujoco.MjModel.from_xml_path = from_xml_path


def model_tables(mujoco, m) -> dict[str, np.ndarray]:
    """The model tables hb_parity's `roles` reads (hb_parity imports this: one definition for
    both models; it takes the `mujoco` module so that this file imports no MuJoCo at load)."""
    free = np.zeros(m.nbody, bool)
    for j in range(m.njnt):
        if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
            free[m.jnt_bodyid[j]] = True
    return {
        "geom_name": np.array([m.geom(g).name for g in range(m.ngeom)]),
        "geom_body": np.asarray(m.geom_bodyid, np.int64),
        "geom_type": np.asarray(m.geom_type, np.int64),
        "body_name": np.array([m.body(b).name for b in range(m.nbody)]),
        "body_parent": np.asarray(m.body_parentid, np.int64),
        "body_weldid": np.asarray(m.body_weldid, np.int64),
        "body_free": free,
    }


def joint_key(m, j: int) -> str:
    """A joint's name, or for an unnamed joint "@BODY:K" (the K-th joint of its body), so that
    unnamed joints (window's wiper ball joint, on both sides) still find their partner."""
    name = m.joint(j).name
    if name:
        return name
    body = int(m.jnt_bodyid[j])
    return f"@{m.body(body).name}:{j - int(m.body_jntadr[body])}"


def _maze_stages(mujoco, m, d, task) -> list[tuple[int, np.ndarray]]:
    """[(maze_stage, move_direction)] for every stage, as HumanoidBench's maze reaches them:
    from `reset_model`, the pelvis (the free joint's x, y) is put on the current checkpoint and
    `update_move_direction` runs, until the stage stops advancing. MjData is left as found."""
    saved = d.qpos.copy()
    task.reset_model()
    out = [(int(task.maze_stage), np.array(task.move_direction, np.float64))]
    while True:
        d.qpos[:2] = task.checkpoints[task.maze_stage][:2]
        mujoco.mj_forward(m, d)
        task.update_move_direction()
        if int(task.maze_stage) == out[-1][0]:
            break
        out.append((int(task.maze_stage), np.array(task.move_direction, np.float64)))
    d.qpos[:] = saved
    return out


def _number(value) -> float:
    try:
        return float(np.asarray(value, np.float64).reshape(()))
    except (TypeError, ValueError):
        return float("nan")


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--task", required=True)
    p.add_argument("--states", required=True)
    p.add_argument("--out", required=True)
    p.add_argument("--hb-checkout", default=None, help="added to sys.path if given")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    if args.hb_checkout:
        sys.path.insert(0, args.hb_checkout)

    import gymnasium
    import mujoco

    _patch_missing_textures(mujoco)
    import humanoid_bench  # noqa: F401  (registers the tasks)

    env = gymnasium.make(args.task, render_mode=None)
    env.reset(seed=args.seed)
    hb = env.unwrapped
    m, d, task = hb.model, hb.data, hb.task

    s = np.load(args.states, allow_pickle=False)
    rename = json.loads(str(s["rename_json"]))
    n = s["qpos"].shape[0]

    # joints by name (unnamed ones by body and position: `joint_key`)
    keys = {joint_key(m, j): j for j in range(m.njnt)}
    qpos_src, qpos_dst, qvel_src, qvel_dst = [], [], [], []
    unmapped_ours = []
    for name, qa, da, jt in zip(
        s["joint_names"], s["jnt_qposadr"], s["jnt_dofadr"], s["jnt_type"], strict=True
    ):
        target = rename.get(str(name), str(name))
        j = keys.get(target, -1)
        if j < 0 or int(m.jnt_type[j]) != int(jt):
            unmapped_ours.append(str(name))
            continue
        nq, nv = _QPOS_SIZE[int(jt)], _DOF_SIZE[int(jt)]
        qpos_src += range(qa, qa + nq)
        qpos_dst += range(m.jnt_qposadr[j], m.jnt_qposadr[j] + nq)
        qvel_src += range(da, da + nv)
        qvel_dst += range(m.jnt_dofadr[j], m.jnt_dofadr[j] + nv)
    mapped = {rename.get(str(x), str(x)) for x in s["joint_names"]} - set(unmapped_ours)
    unmapped_hb = [k for k in keys if k not in mapped]
    # actuators by name
    act_src, act_dst, unmapped_act = [], [], []
    for i, name in enumerate(s["actuator_names"]):
        a = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, str(name))
        if a < 0:
            unmapped_act.append(str(name))
        else:
            act_src.append(i)
            act_dst.append(a)

    hidden_kind = str(s["hidden_kind"])
    hidden = s["hidden"]
    qpos_base, qvel_base = d.qpos.copy(), d.qvel.copy()
    stages = _maze_stages(mujoco, m, d, task) if hidden_kind == "maze_stage" else []

    rewards, terminated, infos = np.zeros(n), np.zeros(n, bool), []
    con_state, con_g1, con_g2, con_dist = [], [], [], []
    for i in range(n):
        qpos, qvel = qpos_base.copy(), qvel_base.copy()
        qpos[qpos_dst] = s["qpos"][i, qpos_src]
        qvel[qvel_dst] = s["qvel"][i, qvel_src]
        d.qpos[:], d.qvel[:] = qpos, qvel
        d.act[:] = 0
        d.ctrl[:] = 0
        d.ctrl[act_dst] = s["ctrl"][i, act_src]
        if hidden_kind.startswith("attr:"):
            value = hidden[i] if hidden.shape[1] > 1 else hidden[i, 0]  # a scalar: spoon's counter
            setattr(task, hidden_kind[5:], np.array(value, np.float64))
        elif hidden_kind.startswith("body_quat:"):
            m.body_quat[m.body(hidden_kind[10:]).id] = hidden[i]
        elif hidden_kind.startswith("body_pos:"):
            m.body_pos[m.body(hidden_kind[9:]).id] = hidden[i]
        elif hidden_kind == "bookshelf":  # [index] or [6 objects, 6 x 3 goals, index]
            h = hidden[i]
            if len(h) > 1:  # our objects 0..11 are HumanoidBench's last 12 bodies, -24..-13
                task.bookshelf_objects = h[:6].astype(np.int64) - 24
                task.placement_goals = h[6:24].reshape(6, 3)
            task.task_index = int(h[-1])
        elif hidden_kind == "basketball_stage":  # our CATCH 0, THROW 1
            task.stage = ("catch", "throw")[int(hidden[i, 0])]
        elif hidden_kind == "maze_stage":
            task.maze_stage, direction = stages[int(hidden[i, 0])]
            task.move_direction = direction.copy()
        elif hidden_kind:
            raise SystemExit(f"unknown hidden_kind {hidden_kind!r}")
        mujoco.mj_forward(m, d)
        reward, info = task.get_reward()
        term, _ = task.get_terminated()
        rewards[i] = _number(reward)
        terminated[i] = bool(term)
        infos.append({k: _number(v) for k, v in info.items()})
        for c in d.contact[: d.ncon]:
            con_state.append(i)
            con_g1.append(int(c.geom1))
            con_g2.append(int(c.geom2))
            con_dist.append(float(c.dist))

    keys = sorted({k for info in infos for k in info})
    info_arr = np.array([[info.get(k, np.nan) for k in keys] for info in infos], np.float64)
    np.savez(
        args.out,
        reward=rewards,
        terminated=terminated,
        info_keys=np.array(keys, dtype=str),
        info=info_arr.reshape(n, len(keys)),
        con_state=np.asarray(con_state, np.int64),
        con_g1=np.asarray(con_g1, np.int64),
        con_g2=np.asarray(con_g2, np.int64),
        con_dist=np.asarray(con_dist, np.float64),
        unmapped_ours=np.array(unmapped_ours, dtype=str),
        unmapped_hb=np.array(unmapped_hb, dtype=str),
        unmapped_actuators=np.array(unmapped_act, dtype=str),
        stubbed_assets=np.array(STUBBED, dtype=str),
        mujoco_version=np.array(mujoco.__version__),
        stage_table=np.array([[k, *v] for k, v in stages], np.float64).reshape(len(stages), 4),
        **model_tables(mujoco, m),
    )


if __name__ == "__main__":
    main()
