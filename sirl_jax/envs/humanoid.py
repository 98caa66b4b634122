"""The generic H1 task environment: one MJX model (robot + task scene) and a `Task` that scores it.

`HumanoidEnv` implements the `Env` contract for every HumanoidBench task (locomotion and
manipulation; a `Task` may change the contact profile, the reset-noise scale, the observation's
state part and the reset state after its kinematics, see the `Task` attributes):

- reset: keyframe 0, plus U(-0.01, 0.01) on every qpos entry (the root quaternion is left
  un-normalised, as in HumanoidBench), qvel = 0, then the task's randomisation from the PRNG key;
  only the kinematics are computed (HumanoidBench runs a full `mj_forward`, whose outputs no
  observation or reward of the reset state uses).
- step: ctrl = low + (a + 1)/2 (high - low), 10 `mjx.step` substeps in a `lax.scan`, then reward,
  termination and metrics from the data the last `mjx.step` returned (kinematics of the forward
  pass at the start of the last substep, qpos/qvel after it: HumanoidBench's convention).
- observation: full qpos and qvel (robot and task objects, root x and y included) plus the
  task's extras; a task may keep the robot's part only (`Task.full_state_obs`) or positions
  only (`Task.qvel_obs`).

The jitted programs can take the `mjx.Model` as an argument (`with_model`), so a test or a
benchmark can reuse one compiled program for every model of the same shapes.

Shape letters: O observation size, A action size (nu), nq/nv the model's sizes.
"""

from __future__ import annotations

import abc
import copy
from typing import Any

import jax
import jax.numpy as jnp
import mujoco
from mujoco import mjx

from sirl_jax.envs import h1
from sirl_jax.envs.base import Env, EnvState, init_state
from sirl_jax.envs.control_step import make_budget_control_step, make_control_step
from sirl_jax.envs.physics import OVERFLOW_METRIC, Physics, Simulator
from sirl_jax.hb_compat import (
    EXACT,
    HAND_FLOOR,
    HB,
    check_contact_budget,
    check_contact_set,
    check_hand_floor,
    check_hb_compat,
)

FRAME_SKIP = h1.N_SUBSTEPS
"""Physics substeps per control step (dt 0.002 s -> 50 Hz control), as in HumanoidBench."""
RESET_NOISE = 0.01


class Task(abc.ABC):
    """A HumanoidBench task: scene, randomisation, reward, termination, observation extras.

    `build` edits the robot's `MjSpec` before compilation; `bind` reads static ids from the
    compiled model. The remaining methods are pure and run under jit/vmap.
    """

    name: str = ""
    metric_names: tuple[str, ...] = ()
    extra_obs_size: int = 0
    contacts: str = "locomotion"
    """`h1.robot_spec` contact profile ("manipulation" turns the hand colliders on)."""
    reset_noise: float = RESET_NOISE
    """Half-width of the uniform noise added to every keyframe qpos entry at reset."""
    full_state_obs: bool = True
    """Observation = full qpos and qvel (objects included) + extras; False: the robot's only."""
    qvel_obs: bool = True
    """False: the state part of the observation is positions only (kitchen)."""
    reset_edits: bool = False
    """`init` or `after_reset` change the noisy keyframe or draw from the key (a goal, an object
    pose, a throw). A task that declares it and can describe its edits overrides `reset_ops`;
    one that leaves it False promises the plain noisy keyframe, which the default `reset_ops`
    describes (tests/test_tasks.py checks every registered task keeps that promise)."""
    reads_contact_slots: bool = False
    """`evaluate` reads MJX's contact slots (not only positions, velocities, sensors and forces),
    so a state from another simulator cannot be scored by it (sim2sim)."""
    hb_compat: str = EXACT
    """HumanoidBench's quirks: "exact" reproduces them, "fixed" corrects them (`hb_compat.py`,
    docs/tasks.md); set it with `with_hb_compat`. Tasks without quirks never read it."""

    contact_set: str = HB
    """What the scene's colliders touch: "hb" (HumanoidBench's set) or "reduced" (`hb_compat.py`);
    set it with `with_contact_set`. The manipulation scenes read it, and the locomotion scenes
    whose geoms touched only some robot parts before (`hb_compat.CONTACT_SET_LOCOMOTION`)."""

    def with_contact_set(self, contact_set: str) -> Task:
        """A copy of this task that builds its scene with `contact_set` ("hb" or "reduced";
        anything else raises ValueError naming the value and the allowed ones)."""
        task = copy.copy(self)
        task.contact_set = check_contact_set(contact_set)
        return task

    hand_floor: str = HAND_FLOOR[0]
    """Which hand colliders touch the floor: "all" (HumanoidBench), "palms" or "none"
    (`h1.HAND_FLOOR_GEOMS`); set it with `with_hand_floor`. The env applies it after `build`."""

    def with_hand_floor(self, which: str) -> Task:
        """A copy of this task whose hands touch the floor as `which` says ("all", "palms" or
        "none"; anything else raises ValueError naming the value and the allowed ones)."""
        task = copy.copy(self)
        task.hand_floor = check_hand_floor(which)
        return task

    max_contact_points: int = 0
    """MJX's contact budget (`h1.set_max_contact_points`; 0: none), applied by the env after
    the scene; set it with `with_contact_budget`. The locomotion tasks set `LOCOMOTION_BUDGET`,
    the manipulation tasks `MANIPULATION_BUDGET` or their own (docs/tasks.md, "Contact
    budget")."""

    def with_contact_budget(self, budget: int) -> Task:
        """A copy of this task with MJX contact budget `budget`: -1 keeps the task's own, 0 none,
        k >= 1 k (anything else raises ValueError naming the value)."""
        check_contact_budget(budget)
        task = copy.copy(self)
        if budget >= 0:
            task.max_contact_points = budget
        return task

    def with_hb_compat(self, mode: str) -> Task:
        """A copy of this task that treats HumanoidBench's quirks as `mode` says ("exact" or
        "fixed"; anything else raises ValueError naming the value and the allowed ones)."""
        task = copy.copy(self)
        task.hb_compat = check_hb_compat(mode)
        return task

    @property
    def exact(self) -> bool:
        """HumanoidBench's quirks are reproduced (`hb_compat == "exact"`)."""
        return self.hb_compat == EXACT

    def build(self, spec: mujoco.MjSpec, variant: str) -> None:
        """Adds the task scene to `spec` (default: none)."""
        del spec, variant

    def bind(self, model: mujoco.MjModel, robot: Any) -> None:
        """Reads static ids and masks from the compiled model (default: none)."""
        del model, robot

    def init(self, key: jax.Array, qpos: jax.Array) -> tuple[jax.Array, Any]:
        """Task randomisation of the noisy keyframe qpos [nq]; returns (qpos, task state)."""
        del key
        return qpos, ()

    @abc.abstractmethod
    def evaluate(
        self, robot: Any, data: mjx.Data, task_state: Any
    ) -> tuple[jax.Array, jax.Array, Any, dict[str, jax.Array]]:
        """(reward [], terminated [] bool, new task state, metrics {name: []})."""

    def carry(self, previous: Any, fresh: Any) -> Any:
        """The task state an episode starts with when it follows one that ended in `previous`
        (`VecEnv`'s auto-reset; `fresh` is `init`'s). Default: `fresh`. HumanoidBench keeps some
        task state on its env object across resets; a task reproducing that returns it here."""
        del previous
        return fresh

    def after_reset(self, robot: Any, data: mjx.Data, task_state: Any) -> tuple[mjx.Data, Any]:
        """Edits the reset state once its kinematics are known (e.g. an object placed relative to
        a hand site); default: none. Positions it changes are stale until the first step."""
        del robot
        return data, task_state

    def extra_obs(self, robot: Any, data: mjx.Data, task_state: Any) -> jax.Array:
        """[extra_obs_size] observation entries after qpos and qvel (default: none)."""
        del robot, data, task_state
        return jnp.zeros((0,), jnp.float32)

    # -- What an exported policy's contract says of the task (sirl_jax/run/contract.py) -------
    # Each hook describes the method above it in the vocabulary `contract_sim` reads (docs/cli.md,
    # "Export and sim-to-sim"); None means "not describable", and the contract says so.

    def reset_ops(self) -> list[dict] | None:
        """What `init` and `after_reset` do to the noisy keyframe, as contract reset ops.

        Default: [] (the plain noisy keyframe) for a task that declares no `reset_edits`, None
        (not described) for one that does and describes nothing here."""
        return None if self.reset_edits else []

    def reset_state(self, values: dict[str, Any], qpos: jax.Array) -> Any:
        """The task state of an episode whose reset ops drew `values` ({name: array}).

        Default: `init`'s state, right for any task whose state does not depend on its key."""
        del values
        return self.init(jax.random.PRNGKey(0), qpos)[1]

    def extra_obs_fields(self) -> list[dict] | None:
        """`extra_obs` as contract observation fields (name, source, size, ...).

        Default: [] for a task without extras, None (not described) otherwise."""
        return [] if self.extra_obs_size == 0 else None

    def termination_rule(self) -> dict | None:
        """The contract's termination rule, where it is more than the task table's state test
        (balance's contacts); None: the table's rule (`contract._termination`)."""
        return None


class HumanoidEnv(Env):
    """One HumanoidBench task on the H1 (`variant` "h1hand" or "h1strong": 61 actuators, or
    "h1": 19)."""

    def __init__(
        self,
        task: Task,
        variant: str = "h1hand",
        episode_length: int = 1000,
        success_bar: float | None = None,
        physics: Physics | None = None,
    ):
        if variant not in h1.VARIANTS:
            raise ValueError(f"unknown robot variant {variant!r}; allowed: {sorted(h1.VARIANTS)}")
        if episode_length < 1:
            raise ValueError(f"episode_length must be >= 1, got {episode_length}")
        self.task = task
        self.variant = variant
        self._episode_length = int(episode_length)
        self._success_bar = success_bar
        spec = h1.robot_spec(variant=variant, contacts=task.contacts)
        task.build(spec, variant)
        h1.set_hand_floor(spec, task.hand_floor)
        if task.max_contact_points:
            h1.set_max_contact_points(spec, task.max_contact_points)
        self.mj_model = spec.compile()
        self.robot = h1.Robot(self.mj_model)
        task.bind(self.mj_model, self.robot)
        self._set_physics(physics or Physics())
        self._plain_step = make_control_step(FRAME_SKIP)
        self._qpos0 = jnp.asarray(self.mj_model.key_qpos[0], jnp.float32)
        if task.full_state_obs:
            nq, nv = self.mj_model.nq, self.mj_model.nv
        else:
            nq, nv = self.robot.nq_robot, self.robot.nv_robot
        self._obs_size = nq + (nv if task.qvel_obs else 0) + task.extra_obs_size

    def _set_physics(self, physics: Physics) -> None:
        self.sim = Simulator(self.mj_model, physics)
        self.mx = self.sim.mx
        budget = self.sim.contact_budget
        self._budget_step = make_budget_control_step(budget, FRAME_SKIP) if budget else None
        reports = self.sim.impl == "warp" or budget > 0
        self._metric_names = tuple(self.task.metric_names) + ((OVERFLOW_METRIC,) if reports else ())

    @property
    def physics_impl(self) -> str:
        return self.sim.impl

    def with_physics(self, physics: Physics) -> HumanoidEnv:
        """A copy that simulates with `physics` (impl, worlds, Warp buffer margin)."""
        env = copy.copy(self)
        env._set_physics(physics)
        return env

    # -- Env contract -------------------------------------------------------------------------
    @property
    def observation_size(self) -> int:
        return self._obs_size

    @property
    def action_size(self) -> int:
        return int(self.robot.nu)

    @property
    def episode_length(self) -> int:
        return self._episode_length

    @property
    def success_bar(self) -> float | None:
        return self._success_bar

    def metric_names(self) -> tuple[str, ...]:
        return self._metric_names

    def with_model(self, mx: mjx.Model) -> HumanoidEnv:
        """A shallow copy that steps `mx` (e.g. a traced jit argument) instead of its own model."""
        env = copy.copy(self)
        env.mx = mx
        return env

    def reset(self, key: jax.Array) -> EnvState:
        """Keyframe + U(+-0.01) on all qpos (task.reset_noise) + task randomisation; qvel = 0."""
        return self._start(key, None)

    def reset_next(self, key: jax.Array, previous: EnvState) -> EnvState:
        """`reset`, with the task state `Task.carry` keeps from the episode that ended."""
        return self._start(key, previous.task)

    def _start(self, key: jax.Array, previous_task: Any) -> EnvState:
        key_noise, key_task, key_next = jax.random.split(key, 3)
        scale = self.task.reset_noise
        noise = jax.random.uniform(key_noise, self._qpos0.shape, minval=-scale, maxval=scale)
        qpos, task_state = self.task.init(key_task, self._qpos0 + noise)
        if previous_task is not None:
            task_state = self.task.carry(previous_task, task_state)
        data = self.sim.make_data(self.mx)
        data = data.replace(qpos=qpos, qvel=jnp.zeros_like(data.qvel))
        # Positions only (xpos, xmat, site_xpos for the observation extras). `step` starts with a
        # full forward pass anyway, and leaving collision and the solver out of reset halves the
        # compiled program (VecEnv's auto-reset inlines a reset in every step).
        data = self.sim.detach_pool(mjx.kinematics(self.mx, self.sim.attach_pool(data)))
        data, task_state = self.task.after_reset(self.robot, data, task_state)
        obs = self._observe(data, task_state)
        metrics = {name: jnp.zeros((), jnp.float32) for name in self._metric_names}
        return init_state(data, obs, key_next, task=task_state, metrics=metrics)

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        """One control step: 10 physics substeps, then reward/termination of the returned data."""
        data = self.sim.attach_pool(state.physics)
        ctrl = self.robot.action_to_ctrl(action)
        if self._budget_step is None:
            data = self._plain_step(self.mx, data, ctrl)
            data, overflow = self.sim.pop_overflow(data)
        else:  # MJX-JAX with a contact budget: was it full at a substep?
            data, overflow = self._budget_step(self.mx, data, ctrl)
        reward, terminated, task_state, metrics = self.task.evaluate(self.robot, data, state.task)
        obs = self._observe(data, task_state)
        metrics = {k: jnp.asarray(v, jnp.float32) for k, v in metrics.items()}
        if OVERFLOW_METRIC in self._metric_names:
            metrics[OVERFLOW_METRIC] = overflow
        return state.replace(
            physics=self.sim.detach_pool(data),
            task=task_state,
            obs=obs,
            reward=jnp.asarray(reward, jnp.float32),
            terminated=jnp.asarray(terminated, bool),
            metrics=metrics,
        )

    def _observe(self, data: mjx.Data, task_state: Any) -> jax.Array:
        extra = self.task.extra_obs(self.robot, data, task_state)
        if self.task.full_state_obs:
            qpos, qvel = data.qpos, data.qvel
        else:
            qpos, qvel = data.qpos[self.robot.qpos_slice], data.qvel[self.robot.qvel_slice]
        state = [qpos, qvel] if self.task.qvel_obs else [qpos]
        return jnp.concatenate([*state, extra]).astype(jnp.float32)
