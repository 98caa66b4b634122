"""One run over several devices with `jax.sharding`: one jitted program, no pmap.

Two layouts over a 1-D `Mesh` of local (or, after `jax.distributed.initialize`, global)
devices:

  seeds: S independent seeds, the train state vmapped with a leading [S] axis on every leaf,
    split over the mesh axis `seeds` (S / D seeds per device). Nothing is communicated: each
    device runs its seeds' envs, planner and updates.
  envs: one learner. The [E] axis of the env states, the planner's warm starts and the replay
    buffer is split over the mesh axis `envs` (E / D envs per device, each with its own ring of
    the buffer); parameters, optimiser states and counters are replicated. Each update's sampled
    batch is constrained to be split on its B axis, so every device computes the loss of B / D
    windows and XLA all-reduces the gradient: the same update as one device on the global
    batch, up to float summation order. Communication enters twice per update: gathering the
    B sampled windows from the envs' rings (B (H + 1) O floats) and the gradient all-reduce
    (one copy of the parameters).

Use:
    mesh = make_mesh(4, ENVS)
    shardings = env_shardings(jax.eval_shape(train.init, key), mesh, E, B)
    train = make_train(config, env, constrain_batch=batch_constraint(mesh))
    state = place(train.init(key), shardings)
    step = sharded_step(train.step, shardings)

Checkpoints are layout-free: `Checkpointer` writes the global arrays, and a restored state is
placed with `place` for whatever layout the resumed run uses (or none).

Shape letters: S seeds, E envs, D devices on the mesh axis, B batch, H horizon, O observation.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding
from jax.sharding import PartitionSpec as P

from sirl_jax.types import Batch

SEEDS, ENVS = "seeds", "envs"
LAYOUTS = (SEEDS, ENVS)


def make_mesh(num_shards: int, axis: str, devices: Sequence[Any] | None = None) -> Mesh:
    """A 1-D mesh of the first `num_shards` devices, its one axis named `axis`.

    Raises ValueError (one line) for an unknown axis or more shards than devices.
    """
    if axis not in LAYOUTS:
        raise ValueError(f"sharding axis {axis!r} is invalid; allowed: {', '.join(LAYOUTS)}")
    devices = list(jax.devices() if devices is None else devices)
    if not isinstance(num_shards, int) or not 1 <= num_shards <= len(devices):
        kind = devices[0].platform if devices else "no"
        raise ValueError(
            f"devices={num_shards!r} is invalid: this process sees {len(devices)} {kind} "
            f"device(s); allowed: 1..{len(devices)}"
        )
    return Mesh(np.array(devices[:num_shards]), (axis,))


def _check_divides(name: str, value: int, mesh: Mesh) -> None:
    d = mesh.devices.size
    if value % d:
        raise ValueError(
            f"{name}={value} does not divide over {d} devices; allowed: a multiple of {d}"
        )


def seed_shardings(abstract_state: Any, mesh: Mesh) -> Any:
    """Shardings for a seed-vmapped state: every leaf split on its leading [S] axis."""
    leaves = jax.tree.leaves(abstract_state)
    if not leaves or any(np.ndim(x) == 0 for x in leaves):
        raise ValueError("seed_shardings needs a vmapped state: every leaf with a leading [S]")
    _check_divides("seeds", int(np.shape(leaves[0])[0]), mesh)
    split = NamedSharding(mesh, P(SEEDS))
    return jax.tree.map(lambda _: split, abstract_state)


def env_shardings(abstract_state: Any, mesh: Mesh, num_envs: int, batch_size: int) -> Any:
    """Shardings for one learner's `TrainState` with its E envs split over the mesh.

    Leaves of `env`, `planner` and `buffer` whose leading axis is E are split; everything else
    (parameters, optimiser states, counters, R_max, the key) is replicated.
    """
    _check_divides("train.num_envs", num_envs, mesh)
    _check_divides("agent.batch_size", batch_size, mesh)
    split, whole = NamedSharding(mesh, P(ENVS)), NamedSharding(mesh, P())

    def per_env(tree):
        return jax.tree.map(lambda x: split if np.ndim(x) and np.shape(x)[0] == num_envs
                            else whole, tree)  # fmt: skip

    replicated = jax.tree.map(lambda _: whole, abstract_state)
    return replicated.replace(env=per_env(abstract_state.env),
                              planner=per_env(abstract_state.planner),
                              buffer=per_env(abstract_state.buffer))  # fmt: skip


def batch_constraint(mesh: Mesh) -> Callable[[Batch], Batch]:
    """For `make_train(..., constrain_batch=)`: split a sampled batch on its B axis."""
    time_major = NamedSharding(mesh, P(None, ENVS))
    spec = Batch(obs=time_major, action=time_major, reward=time_major,
                 terminated=time_major, episode_return=NamedSharding(mesh, P(ENVS)))  # fmt: skip

    def constrain(batch: Batch) -> Batch:
        return jax.lax.with_sharding_constraint(batch, spec)

    return constrain


def place(state: Any, shardings: Any) -> Any:
    """A copy of `state` on the mesh with `shardings` (from any layout before).

    Every leaf gets its own buffer: an eager `init` may return one array for two leaves
    (zeros), which a donating step would then be handed twice.
    """
    on_mesh = jax.device_put(state, shardings)
    return jax.jit(lambda s: jax.tree.map(jnp.copy, s), out_shardings=shardings)(on_mesh)


def sharded_step(step: Callable, shardings: Any) -> Callable:
    """`jax.jit(step, donate_argnums=0)` whose output state keeps `shardings`."""

    def run(state):
        state, metrics = step(state)
        return jax.lax.with_sharding_constraint(state, shardings), metrics

    return jax.jit(run, donate_argnums=0)


def initialize_multihost(coordinator: str, num_processes: int, process_id: int) -> None:
    """`jax.distributed.initialize` for a multi-host run; afterwards `jax.devices()` (and so
    `make_mesh`) spans every host. Each process then builds the same state from the same key
    and `place` keeps its own shards."""
    jax.distributed.initialize(coordinator_address=coordinator, num_processes=num_processes,
                               process_id=process_id)  # fmt: skip
