"""Small MJX control tasks for tests, smoke runs and learning checks on CPU.

`pendulum`: a torque-limited pendulum swing-up in the manner of dm_control's `pendulum-swingup`
(random initial angle, control at 50 Hz), with a dense reward in the style of the
dm_control/Playground cartpole: upright * small_control * small_velocity, each in [0, 1].
The motor's torque limit (2 N m) is below the gravity torque at horizontal (m g l = 4.9 N m),
so the pole has to be pumped up; one episode is 250 control steps (5 s), so the return is at
most 250. The success bar (150) is reached by swinging up within ~1.5 s and balancing.

Observation [3]: cos(theta), sin(theta), theta_dot / 10, with theta = 0 upright.
Action [1] in [-1, 1]: motor torque as a fraction of the limit.
"""

from __future__ import annotations

import copy

import jax
import jax.numpy as jnp
import mujoco
from mujoco import mjx

from sirl_jax.envs.base import Env, EnvState, init_state
from sirl_jax.envs.physics import OVERFLOW_METRIC, Physics, Simulator
from sirl_jax.envs.registry import TASKS, TaskSpec, register

_PENDULUM_MJCF = """
<mujoco model="pendulum_swingup">
  <option timestep="0.01" integrator="RK4">
    <flag contact="disable"/>
  </option>
  <worldbody>
    <body name="pole" pos="0 0 1">
      <joint name="hinge" type="hinge" axis="0 1 0" damping="0.05"/>
      <geom name="rod" type="capsule" fromto="0 0 0 0 0 0.5" size="0.02" mass="0"/>
      <geom name="mass" type="sphere" pos="0 0 0.5" size="0.05" mass="1"/>
    </body>
  </worldbody>
  <actuator>
    <motor name="torque" joint="hinge" gear="2" ctrllimited="true" ctrlrange="-1 1"/>
  </actuator>
</mujoco>
"""


class PendulumSwingup(Env):
    """Torque-limited pendulum swing-up (see the module docstring)."""

    n_substeps = 2
    """Physics steps per control step: 2 x 0.01 s = 50 Hz control."""

    def __init__(self, episode_length: int = 250, physics: Physics | None = None):
        if episode_length < 1:
            raise ValueError(f"episode_length={episode_length!r} is invalid; allowed: >= 1")
        self._episode_length = episode_length
        self.mj_model = mujoco.MjModel.from_xml_string(_PENDULUM_MJCF)
        self._set_physics(physics or Physics())

    def _set_physics(self, physics: Physics) -> None:
        self.sim = Simulator(self.mj_model, physics)
        self.mjx_model = self.sim.mx
        self._data0 = self.sim.make_data()

    @property
    def physics_impl(self) -> str:
        return self.sim.impl

    def with_physics(self, physics: Physics) -> PendulumSwingup:
        """A copy that simulates with `physics` (impl, worlds, Warp buffer margin)."""
        env = copy.copy(self)
        env._set_physics(physics)
        return env

    @property
    def observation_size(self) -> int:
        return 3

    @property
    def action_size(self) -> int:
        return 1

    @property
    def episode_length(self) -> int:
        return self._episode_length

    @property
    def success_bar(self) -> float | None:
        return 150.0

    def metric_names(self) -> tuple[str, ...]:
        extra = (OVERFLOW_METRIC,) if self.sim.impl == "warp" else ()
        return ("upright", "small_control", "small_velocity", *extra)

    def reset(self, key: jax.Array) -> EnvState:
        key_angle, key_next = jax.random.split(key)
        angle = jax.random.uniform(key_angle, (1,), minval=-jnp.pi, maxval=jnp.pi)
        data = self._data0.replace(qpos=angle, qvel=jnp.zeros(1))
        data = self.sim.detach_pool(mjx.forward(self.mjx_model, self.sim.attach_pool(data)))
        zero = jnp.zeros((), jnp.float32)
        metrics = {name: zero for name in self.metric_names()}
        return init_state(data, self._obs(data), key_next, metrics=metrics)

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        ctrl = jnp.clip(action, -1.0, 1.0)
        data = self.sim.attach_pool(state.physics).replace(ctrl=ctrl)

        def substep(d, _):
            return mjx.step(self.mjx_model, d), None

        data, _ = jax.lax.scan(substep, data, None, length=self.n_substeps)
        data, overflow = self.sim.pop_overflow(data)
        terms = self._reward_terms(data, ctrl)
        reward = terms["upright"] * terms["small_control"] * terms["small_velocity"]
        if self.sim.impl == "warp":
            terms[OVERFLOW_METRIC] = overflow
        return state.replace(
            physics=self.sim.detach_pool(data),
            obs=self._obs(data),
            reward=reward.astype(jnp.float32),
            terminated=jnp.zeros((), bool),
            metrics=terms,
        )

    @staticmethod
    def _obs(data: mjx.Data) -> jax.Array:
        theta, theta_dot = data.qpos[0], data.qvel[0]
        return jnp.stack([jnp.cos(theta), jnp.sin(theta), theta_dot / 10.0]).astype(jnp.float32)

    @staticmethod
    def _reward_terms(data: mjx.Data, ctrl: jax.Array) -> dict[str, jax.Array]:
        theta_dot = data.qvel[0]
        return {
            "upright": ((jnp.cos(data.qpos[0]) + 1.0) / 2.0).astype(jnp.float32),
            "small_control": ((4.0 + (1.0 - ctrl[0] ** 2)) / 5.0).astype(jnp.float32),
            "small_velocity": ((1.0 + jnp.exp(-0.1 * theta_dot**2)) / 2.0).astype(jnp.float32),
        }


def energy_swingup_action(obs: jax.Array) -> jax.Array:
    """A hand-written controller (energy pumping, then PD near the top) for tests and baselines.

    Args:
      obs: [..., 3] pendulum observations.
    Returns:
      [..., 1] actions in [-1, 1].
    """
    cos_t, sin_t, theta_dot = obs[..., 0], obs[..., 1], obs[..., 2] * 10.0
    theta = jnp.arctan2(sin_t, cos_t)
    # Energy relative to resting upright, per unit m l^2 (l = 0.5, g = 9.81): 0 when balanced.
    energy = 0.5 * 0.25 * theta_dot**2 + 9.81 * 0.5 * (cos_t - 1.0)
    pump = jnp.sign(theta_dot + 1e-6) * jnp.sign(-energy)
    pd = -(10.0 * theta + 1.5 * theta_dot) / 2.0
    u = jnp.where(cos_t > 0.9, pd, pump)
    return jnp.clip(u, -1.0, 1.0)[..., None]


def _register() -> None:
    if "pendulum" not in TASKS:
        register(
            TaskSpec(
                id="pendulum-swingup-v0",
                factory=PendulumSwingup,
                episode_length=250,
                success_bar=150.0,
                aliases=("pendulum",),
                description="torque-limited pendulum swing-up (MJX, 1 dof), for CPU checks",
            )
        )


_register()
