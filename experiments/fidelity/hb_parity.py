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
import json
import subprocess
import tempfile
import time
from pathlib import Path

import jax
import mujoco
import numpy as np

from experiments.fidelity.hb_contacts import (
    BAR_CLASSES,
    CLASSES,
    OurGap,
    classify,
    contact_class,
    deepest,
    mm_stats,
    our_contacts,
    roles,
    tables,
)
from experiments.fidelity.hb_ours import (
    HIDDEN,
    RENAME,
    diff_stats,
    draw_states,
    merge,
    our_rewards,
    print_table,
)
from experiments.fidelity.hb_side import joint_key
from sirl_jax.envs import load
from sirl_jax.envs.loading import spec as task_spec
from sirl_jax.hb_compat import CONTACT_SETS, HAND_FLOOR, HB
from sirl_jax.run.compile_cache import enable_compilation_cache

HB_SIDE = Path(__file__).with_name("hb_side.py")


BAR_AGREEMENT, BAR_MEDIAN, BAR_P95 = 0.99, 0.005, 0.02


# -- roles and contact classes, one function for both models --------------------------------


# -- our side ---------------------------------------------------------------------------------


# -- why a state disagrees: how deep, how far -------------------------------------------------


# -- comparison -------------------------------------------------------------------------------


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
        stages[str(stage)] = {**diff_stats(ours - hb_s["reward"]), "ours_mean": float(ours.mean()),
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
            "ours_only_depth_mm": mm_stats(ours_deep[c][o & ~h]),
            "hb_only_depth_mm": mm_stats(hb_deep[c][hb_only]),
            "hb_only_our_gap_mm": mm_stats(gaps),
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
    terms = {k: diff_stats(metrics[k] - hb["info"][:, keys.index(k)]) for k in metrics if k in keys}
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
            **diff_stats(delta),
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
                for r in (diff_stats(delta), *stages.values())
            ),
        },
        "notes": notes,
        "hb_mujoco": str(hb["mujoco_version"]),
        "ours_mujoco": mujoco.__version__,
        "seconds": round(time.perf_counter() - t0, 1),
    }
    return result


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
