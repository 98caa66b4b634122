"""Compile time and CPU throughput of the locomotion and manipulation tasks, beside the bare robot.

For each task: the contact slots MJX allocates per env, the time to compile `VecEnv.reset` and
`VecEnv.step` (E envs, jitted, the model as a jit argument; wall and process CPU seconds, the
latter less sensitive to other jobs on the machine), then control steps/s (E x calls / s) of the
compiled step under uniform random actions, with auto-resets. The reference row "bare" is the
robot on flat ground with a zero reward, so `ratio` is the task's cost of scene contacts and
reward. The ratio is measured side by side: `--rounds` alternating blocks of `--calls` steps of
the task and of the (already compiled) bare robot, ratio = median task rate / median bare rate,
so a change of machine load during the run moves both.

    .venv/bin/python -m experiments.bench.bench_tasks [--variant h1hand] [--num-envs 64]
        [--calls 10] [--rounds 3] [--tasks walk,pole] [--profile] [--max-geom-pairs K]
        [--contact-sets hb,reduced] [--hand-floors all,none] [--prism-sides K] [--out rows.json]

`--tasks` takes locomotion and manipulation names (a manipulation task runs on its own variant:
h1hand, or h1strong for highbar_hard).
`--profile` adds the cost of the manipulation contact profile: the robot and one free 0.2 m box
in front of it, with the hands off (locomotion profile; the box touches the floor only), with the
62 hand colliders on against the box, and with them on but `max_geom_pairs` 8.

`--max-geom-pairs K` adds, after each task, the same task with MJX keeping K candidate pairs per
collision function (the lever for a scene with many box colliders). `--max-contact-points K` adds
the same task with MJX's contact budget set to K (-1: none), for a task that sets one
(docs/tasks.md, "Contact budget"). `--contact-sets` and `--hand-floors` measure each task in each
contact set it reads and each `hand_floor` (the bare robot's hands never touch the floor).

`--prism-sides K` adds the same task with its colliding cylinders as K-sided prisms instead of
`scene.PRISM_SIDES` (the hb contact set's stand-in: MJX has no box-cylinder pair).

`--out` also writes every row, as it is measured, to a JSON file (the run's settings and one
object per row; `experiments.fidelity.task_table` reads it).

Compiles are not cached (a cached compile would time a disk read).
"""

from __future__ import annotations

import argparse
import copy
import itertools
import json
import statistics
import time
from collections.abc import Callable
from pathlib import Path

import jax
import jax.numpy as jnp
import mujoco

import sirl_jax.envs.tasks as tasks
from sirl_jax.envs.base import EnvState, VecEnv
from sirl_jax.envs.humanoid import HumanoidEnv, Task, contact_arrays
from sirl_jax.envs.physics import Physics
from sirl_jax.envs.tasks import scene
from sirl_jax.hb_compat import (
    CONTACT_SET_LOCOMOTION,
    CONTACT_SETS,
    HAND_FLOOR,
    HB,
    NO_HAND_FLOOR,
)

try:  # the contact slots MJX allocates per env (its collision driver's own count)
    from mujoco.mjx._src.collision_driver import make_condim as mjx_contact_dims
except ImportError:  # pragma: no cover - private MJX module moved

    def mjx_contact_dims(model):
        return []


class BareTask(Task):
    """No scene, zero reward, never terminates: the physics-only reference. Its hands pass
    through the floor (`hand_floor="none"`), as the reference of every earlier ratio did."""

    name = "bare"
    hand_floor = NO_HAND_FLOOR

    def evaluate(self, robot, data, task_state):
        return jnp.zeros(()), jnp.zeros((), bool), task_state, {}


class BoxTask(BareTask):
    """The bare robot and one free box (0.2 m, 0.3 kg) on the floor at x 0.45, within reach."""

    def __init__(self, contacts: str, max_geom_pairs: int = 0):
        self.name = f"box_{contacts[:5]}" + (f"_k{max_geom_pairs}" if max_geom_pairs else "")
        self.contacts, self.max_geom_pairs = contacts, max_geom_pairs

    def build(self, spec, variant):
        box = spec.worldbody.add_body(name="object", pos=(0.45, 0.0, 0.1))
        box.add_freejoint(name="free_object")
        scene.set_inertial(box, 0.3, (1e-3, 1e-3, 1e-3))
        if self.contacts == "manipulation":
            scene.use_hand_contacts(spec)
            scene.add_object_geom(box, type=scene.BOX, size=(0.1,) * 3, density=0.0)
        else:
            box.add_geom(type=scene.BOX, size=(0.1,) * 3, density=0.0, contype=0,
                         conaffinity=scene.FLOOR)  # fmt: skip
        if self.max_geom_pairs:
            scene.set_max_geom_pairs(spec, self.max_geom_pairs)


class Stepper:
    """One env's compiled `VecEnv.step` (state donated), its state and a block of actions."""

    def __init__(self, env: HumanoidEnv, num_envs: int, calls: int, seed: int = 0):
        """Compiles reset and step; `self.compile` holds wall and CPU seconds."""

        def reset(mx, key):
            return VecEnv(env.with_model(mx), num_envs).reset(key)

        def step(mx, state, action):
            return VecEnv(env.with_model(mx), num_envs).step(state, action)

        self.env, self.num_envs = env, num_envs
        key = jax.random.PRNGKey(seed)
        c0, t0 = time.process_time(), time.perf_counter()
        reset_c = jax.jit(reset).lower(env.mx, key).compile()
        c1, t1 = time.process_time(), time.perf_counter()
        self.state: EnvState = reset_c(env.mx, key)
        self.actions = jax.random.uniform(
            key, (calls, num_envs, env.action_size), minval=-1.0, maxval=1.0
        )  # [calls, E, A]
        c2, t2 = time.process_time(), time.perf_counter()
        self.step: Callable = (
            jax.jit(step, donate_argnums=1).lower(env.mx, self.state, self.actions[0]).compile()
        )
        c3, t3 = time.process_time(), time.perf_counter()
        self.compile = {
            "reset_compile_s": t1 - t0,
            "step_compile_s": t3 - t2,
            "compile_cpu_s": (c1 - c0) + (c3 - c2),
        }
        self.rate()  # warm-up

    def ncon(self) -> float:
        """Active contacts (dist < 0) per env in the current state, mean over envs."""
        dist, _ = jax.vmap(contact_arrays)(self.state.physics)  # [E, C]
        return float(jnp.mean(jnp.sum(dist < 0, axis=-1)))

    def rate(self) -> float:
        """Control steps/s (E x calls / wall s) of one block of `calls` steps."""
        jax.block_until_ready(self.state.obs)
        t0 = time.perf_counter()
        for action in self.actions:
            self.state = self.step(self.env.mx, self.state, action)
        jax.block_until_ready(self.state.obs)
        return self.num_envs * len(self.actions) / (time.perf_counter() - t0)


def with_numeric(env: HumanoidEnv, name: str, k: int) -> HumanoidEnv:
    """A copy of `env` whose compiled model's numeric `name` (`max_geom_pairs`,
    `max_contact_points`) is k, edited before `mjx.put_model`."""
    i = mujoco.mj_name2id(env.mj_model, mujoco.mjtObj.mjOBJ_NUMERIC, name)
    if i < 0:
        raise SystemExit(f"{env.task.name} sets no {name}")
    model = copy.deepcopy(env.mj_model)
    model.numeric_data[model.numeric_adr[i]] = k
    out = copy.copy(env)
    out.mj_model = model
    return out.with_physics(Physics())


def side_by_side(task: Stepper, bare: Stepper, rounds: int) -> tuple[float, float]:
    """(median task steps/s, median task / bare ratio) over `rounds` alternating blocks."""
    task_rates, bare_rates = [], []
    for _ in range(rounds):
        task_rates.append(task.rate())
        bare_rates.append(bare.rate())
    task_rate = statistics.median(task_rates)
    return task_rate, task_rate / statistics.median(bare_rates)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variant", default="h1hand", choices=tasks.VARIANTS)
    parser.add_argument("--num-envs", type=int, default=64)
    parser.add_argument("--calls", type=int, default=10)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--tasks", default="", help="comma-separated task names (default: all)")
    parser.add_argument("--profile", action="store_true", help="measure the contact profiles")
    parser.add_argument("--max-geom-pairs", type=int, default=0,
                        help="also measure each task with this max_geom_pairs (a lever test)")
    parser.add_argument("--max-contact-points", type=int, default=0,
                        help="also measure each task that has a contact budget with this one "
                        "(-1: none)")  # fmt: skip
    parser.add_argument("--prism-sides", type=int, default=0,
                        help="also measure each task that turns colliding cylinders into "
                        "prisms (the hb contact set) with prisms of this many sides")  # fmt: skip
    parser.add_argument("--contact-sets", default=HB,
                        help=f"comma-separated contact sets for the tasks that read one (the "
                        f"manipulation tasks, {', '.join(CONTACT_SET_LOCOMOTION)}), each "
                        f"measured (allowed: {', '.join(CONTACT_SETS)})")  # fmt: skip
    parser.add_argument("--hand-floors", default=HAND_FLOOR[0],
                        help=f"comma-separated hand_floor values, each measured (allowed: "
                        f"{', '.join(HAND_FLOOR)})")  # fmt: skip
    parser.add_argument("--out", type=Path, help="also write the rows to this JSON file")
    args = parser.parse_args()
    contact_sets = [c for c in args.contact_sets.split(",") if c]
    if not contact_sets or set(contact_sets) - set(CONTACT_SETS):
        raise SystemExit(f"--contact-sets {args.contact_sets!r}: allowed {CONTACT_SETS}")
    hand_floors = [c for c in args.hand_floors.split(",") if c]
    if not hand_floors or set(hand_floors) - set(HAND_FLOOR):
        raise SystemExit(f"--hand-floors {args.hand_floors!r}: allowed {HAND_FLOOR}")
    if args.calls < 1 or args.rounds < 1:
        raise SystemExit(f"--calls and --rounds must be >= 1, got {args.calls}, {args.rounds}")
    rows = {r.name: r for r in (*tasks.LOCOMOTION, *tasks.MANIPULATION)}
    names = list(rows)
    chosen = [n for n in args.tasks.split(",") if n] or (names if not args.profile else [])
    unknown = sorted(set(chosen) - set(names))
    if unknown:
        raise SystemExit(f"unknown tasks {unknown}; allowed: {names}")
    print(f"variant {args.variant}, E = {args.num_envs}, {args.rounds} x {args.calls} timed "
          f"calls, backend {jax.default_backend()}")
    header = (f"{'task':<26}{'contacts':>9}{'reset compile s':>16}{'step compile s':>16}"
              f"{'compile CPU s':>14}{'steps/s':>9}{'ratio':>7}{'ncon':>6}")
    print(header)
    print("-" * len(header))
    record = {"variant": args.variant, "num_envs": args.num_envs, "calls": args.calls,
              "rounds": args.rounds, "backend": jax.default_backend(), "rows": []}  # fmt: skip

    def report(name: str, stepper: Stepper, rate: float, ratio: float, **settings) -> None:
        contacts = len(mjx_contact_dims(stepper.env.mj_model))
        compile_s, ncon = stepper.compile, stepper.ncon()
        print(f"{name:<26}{contacts:>9}{compile_s['reset_compile_s']:>16.1f}"
              f"{compile_s['step_compile_s']:>16.1f}{compile_s['compile_cpu_s']:>14.1f}"
              f"{rate:>9.0f}{ratio:>7.2f}{ncon:>6.1f}", flush=True)
        if args.out:
            record["rows"].append({"label": name, **settings, "contacts": contacts, **compile_s,
                                   "steps_per_s": rate, "ratio": ratio, "ncon": ncon})  # fmt: skip
            args.out.parent.mkdir(parents=True, exist_ok=True)
            tmp = args.out.with_suffix(".tmp")
            tmp.write_text(json.dumps(record, indent=1) + "\n")
            tmp.replace(args.out)

    bare = Stepper(HumanoidEnv(BareTask(), args.variant), args.num_envs, args.calls)
    rate = statistics.median(bare.rate() for _ in range(args.rounds))
    report("bare", bare, rate, 1.0)
    if args.profile:
        for task in (BoxTask("locomotion"), BoxTask("manipulation"), BoxTask("manipulation", 8)):
            stepper = Stepper(HumanoidEnv(task, args.variant), args.num_envs, args.calls)
            report(task.name, stepper, *side_by_side(stepper, bare, args.rounds))
            del stepper
    for name in chosen:
        row = rows[name]
        manipulation = row in tasks.MANIPULATION
        variant = row.robot if manipulation else args.variant
        reads_set = manipulation or name in CONTACT_SET_LOCOMOTION
        for contact_set, hand_floor in itertools.product(
            contact_sets if reads_set else [HB], hand_floors
        ):
            task = row.task().with_contact_set(contact_set).with_hand_floor(hand_floor)
            env = HumanoidEnv(task, variant, success_bar=row.success_bar)
            stepper = Stepper(env, args.num_envs, args.calls)
            label = name + (f" {contact_set}" if reads_set and len(contact_sets) > 1 else "")
            label += f" hands:{hand_floor}" if len(hand_floors) > 1 else ""
            report(label, stepper, *side_by_side(stepper, bare, args.rounds), task=name,
                   contact_set=task.contact_set, hand_floor=hand_floor,
                   contact_budget=env.sim.contact_budget)  # fmt: skip
            del stepper
        levers = [("max_geom_pairs", args.max_geom_pairs, "k")]
        if env.sim.contact_budget:
            levers.append(("max_contact_points", args.max_contact_points, "budget "))
        for numeric, k, tag in levers:  # on the env of the last contact set measured
            if not k:
                continue
            stepper = Stepper(with_numeric(env, numeric, k), args.num_envs, args.calls)
            report(f"{name} {tag}{k}", stepper, *side_by_side(stepper, bare, args.rounds),
                   task=name, **{numeric: k})  # fmt: skip
            del stepper
        if args.prism_sides and scene.prism_meshes(env.mj_model):
            task = copy.copy(env.task)
            task.prism_sides = args.prism_sides
            stepper = Stepper(HumanoidEnv(task, variant, success_bar=row.success_bar),
                              args.num_envs, args.calls)  # fmt: skip
            report(f"{name} prism{args.prism_sides}", stepper,
                   *side_by_side(stepper, bare, args.rounds), task=name,
                   prism_sides=args.prism_sides)  # fmt: skip
            del stepper


if __name__ == "__main__":
    main()
