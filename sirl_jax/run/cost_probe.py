"""What the rest of a run costs, said before its first chunk: `cost_line` times one
`Train.act` (planning), one `Train.update` and one vectorised env step of the run, and
`run_cost_seconds` turns the first two into the agent's compute for the steps left.

`runner.train_run` prints the line for every model but the tiny one, on any device.
"""

from __future__ import annotations

import time
from typing import Any

import jax
import jax.numpy as jnp

from sirl_jax.envs import spec
from sirl_jax.presets import CPU_LEARNS, get_preset
from sirl_jax.run.progress import format_duration
from sirl_jax.train import Train


def run_cost_seconds(
    remaining_steps: int,
    seed_steps_left: int,
    num_envs: int,
    utd: float,
    pretrain_updates_left: int,
    act_seconds: float,
    update_seconds: float,
) -> float:
    """Seconds the agent's compute will take for the rest of a run (env physics excluded).

    After the seed phase (random actions, no updates) every vectorised step acts once for
    all `num_envs` envs and runs `num_envs * utd` updates; pretraining runs once.

    Args:
      remaining_steps: env transitions still to run (all envs).
      seed_steps_left: of those, transitions still in the seed phase.
      act_seconds: one plan (or policy) call for all envs; update_seconds: one update.
    """
    acting = max(remaining_steps - seed_steps_left, 0) / num_envs
    updates = acting * num_envs * utd + pretrain_updates_left
    return acting * act_seconds + updates * update_seconds


def cost_line(train: Train, state: Any, repeats: int = 3) -> str:
    """Times one `Train.act` (planning), one `Train.update` and one vectorised env step of this
    run (median of `repeats` calls after a warm-up) and says what the rest of the run costs.

    The same estimate on any device: for the reference config on a CPU the answer is days,
    on a GPU hours; either is worth having before the first chunk. The fused step overlaps
    nothing of this, so the sum is the run's wall-clock up to the shell's overhead.
    """
    key = jax.random.PRNGKey(0)
    t = train.config.train

    def seconds(fn, *args) -> float:
        jax.block_until_ready(fn(*args))  # compile and warm up
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            jax.block_until_ready(fn(*args))
            times.append(time.perf_counter() - t0)
        return sorted(times)[len(times) // 2]

    t_act = seconds(jax.jit(train.act), state.replace(planning=jnp.ones((), bool)), key)
    t_update = seconds(jax.jit(train.update), state.agent, state.buffer, key)
    action = jnp.zeros((t.num_envs, train.env.action_size), jnp.float32)
    t_env = seconds(jax.jit(train.vec_env.step), state.env, action)
    done, planning = (int(x) for x in jax.device_get((state.env_steps, state.planning)))
    remaining = max(t.steps - done, 0)
    cost = run_cost_seconds(
        remaining,
        seed_steps_left=0 if planning else max(train.seed_steps - done, 0),
        num_envs=t.num_envs,
        utd=train.updates_per_step / t.num_envs,
        pretrain_updates_left=0 if planning else train.pretrain_updates,
        act_seconds=t_act,
        update_seconds=t_update,
    )
    physics = remaining / t.num_envs * t_env
    device = jax.devices()[0]
    where = jax.default_backend().upper()
    where += "" if device.platform == "cpu" else f" ({device.device_kind})"
    what = "plan" if train.config.agent.plans else "policy"
    return (
        f"{where}: about {format_duration(cost)} of agent compute and "
        f"{format_duration(physics)} of env physics ({t.impl}) for the {remaining:,} steps "
        f"left (one {what} call for {t.num_envs} env(s) {t_act:.3g} s, one update "
        f"{t_update:.3g} s, one env step {t_env:.3g} s, measured now)"
    )


def cpu_hint(config) -> str:
    """What a CPU run's cost line adds: the preset measured to learn its task on a CPU, with
    the command (`presets.CPU_LEARNS`), unless the run already uses that preset's learner;
    for a task no preset is known to learn on a CPU, a GPU."""
    task = config.train.task
    try:
        task = spec(task).id
    except (KeyError, ValueError):
        pass
    if task not in CPU_LEARNS:
        return ("; no preset is measured to learn this task on a CPU (presets.CPU_LEARNS): "
                "use a GPU, or a smaller model (--preset smoke)")  # fmt: skip
    preset, flags, reached = CPU_LEARNS[task]
    if config.agent == get_preset(preset).agent:
        return f"; {preset} learns this task on a CPU: {reached}"
    return (f"; on a CPU use the {preset} preset, measured {reached}: python -m sirl_jax train "
            f"--task {task} --preset {preset} {flags}")
