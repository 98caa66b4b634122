"""sirl_jax.envs.playground_env: our tasks as Playground `MjxEnv`s, for Playground's wrappers
and brax's PPO; the same steps as our env, the task state reset with the episode, and a round
trip back through our Playground adapter into our trainer."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

pytest.importorskip("mujoco_playground")

from mujoco_playground import wrapper  # noqa: E402

from sirl_jax.envs import load, playground_env  # noqa: E402

STAND = "h1hand-stand-v0"


@pytest.fixture(scope="module")
def stand():
    return load(STAND)[1], playground_env(STAND)


@pytest.fixture(scope="module", params=[
    "h1-stand-v0", pytest.param(STAND, marks=pytest.mark.slow)])  # h1hand: 120 s cold
def pair(request):
    """(our env, the Playground env) of a task: the hand-less H1 in make test, h1hand slow."""
    return load(request.param)[1], playground_env(request.param)


def _actions(n: int, size: int) -> jax.Array:
    return jax.random.uniform(jax.random.PRNGKey(3), (n, size), minval=-1.0, maxval=1.0)


@pytest.mark.timeout(900)
def test_the_env_follows_playground_and_steps_our_task_exactly(pair):
    ours, env = pair
    sizes = {"h1-stand-v0": (51, 19, 26), "h1hand-stand-v0": (151, 61, 76)}[env.task_id]
    assert (env.observation_size, env.action_size, env.mjx_model.nq) == sizes  # HumanoidBench's
    assert (env.dt, env.sim_dt, env.n_substeps) == (0.02, 0.002, 10)
    assert (env.mjx_model.nq, env.mj_model.nu) == (ours.mx.nq, ours.mj_model.nu)
    key, actions = jax.random.PRNGKey(11), _actions(4, env.action_size)
    a, b = jax.jit(ours.reset)(key), jax.jit(env.reset)(key)
    np.testing.assert_array_equal(a.obs, b.obs)
    step_ours, step_env = jax.jit(ours.step), jax.jit(env.step)
    for action in actions:
        a, b = step_ours(a, action), step_env(b, action)
        np.testing.assert_array_equal(a.obs, b.obs)
        np.testing.assert_array_equal(a.reward, b.reward)
        assert float(b.done) == float(a.terminated)
        assert set(b.metrics) == set(a.metrics)
        np.testing.assert_array_equal(a.physics.qpos, b.data.qpos)
    # Playground's training wrappers (vmap, episode, auto-reset) change none of it
    wrapped = wrapper.wrap_for_brax_training(env, episode_length=1000)
    keys = jax.random.split(jax.random.PRNGKey(5), 2)
    w = jax.jit(wrapped.reset)(keys)
    plain = w.replace(info={k: w.info[k] for k in ("task", "first_task")})  # the env's own
    w_step, p_step = jax.jit(wrapped.step), jax.jit(jax.vmap(env.step))
    for action in actions[:2]:
        both = jnp.stack([action, -action])
        w, plain = w_step(w, both), p_step(plain, both)
        np.testing.assert_array_equal(w.obs, plain.obs)
        np.testing.assert_array_equal(w.reward, plain.reward)
        np.testing.assert_array_equal(w.done, plain.done)


@pytest.mark.timeout(900)
def test_an_episode_starts_from_its_resets_task_state():
    """Playground's default auto-reset puts back only `data` and `obs`; a step from data at
    time 0 takes the reset's task state (reach's goal), so a stale goal is never scored."""
    env = playground_env("h1-reach-v0")
    state = jax.jit(env.reset)(jax.random.PRNGKey(2))
    goal = state.info["first_task"]
    stale = state.replace(info={**state.info, "task": goal + 0.5})
    step = jax.jit(env.step)
    action = jnp.zeros(env.action_size)
    fresh, restarted = step(state, action), step(stale, action)
    np.testing.assert_array_equal(fresh.reward, restarted.reward)
    np.testing.assert_array_equal(fresh.obs, restarted.obs)  # reach observes its goal
    np.testing.assert_array_equal(restarted.info["task"], goal)
    # mid-episode (time > 0) the task state it carries is the one it observes and scores
    later = fresh.replace(info={**fresh.info, "task": goal + 0.5})
    moved, kept = step(later, action), step(fresh, action)
    assert not np.array_equal(moved.obs, kept.obs)
    np.testing.assert_array_equal(moved.info["task"], goal + 0.5)
    with pytest.raises(ValueError, match=r"playground_env\('pendulum'\): pendulum-swingup-v0 is "
                       r"not a HumanoidBench task; allowed: the h1hand-\* and h1-\* tasks"):
        playground_env("pendulum")


@pytest.mark.timeout(1200)  # the suite's one brax PPO run: about 2 min, most of it compiling
def test_brax_ppo_trains_on_it_with_finite_losses(stand):
    from brax.training.agents.ppo import train as ppo

    from sirl_jax.envs.playground_env import brax_compat

    brax_compat()  # brax 0.14.2 calls jax.device_put_replicated, gone from JAX 0.10
    _, env = stand
    seen = []
    _, params, metrics = ppo.train(
        environment=env, num_timesteps=2_048, episode_length=64, num_envs=8, batch_size=8,
        unroll_length=8, num_minibatches=2, num_updates_per_batch=1, num_evals=2,
        num_eval_envs=2, wrap_env_fn=wrapper.wrap_for_brax_training, seed=0,
        progress_fn=lambda step, m: seen.append((step, dict(m))))  # fmt: skip
    assert seen and seen[-1][0] >= 2_048
    losses = {k: float(v) for k, v in metrics.items() if "loss" in k}
    assert losses and all(np.isfinite(v) for v in losses.values()), losses
    assert np.isfinite(float(metrics["eval/episode_reward"]))
    assert all(np.all(np.isfinite(x)) for x in jax.tree.leaves(params))


@pytest.mark.slow  # 49 s: h1-stand's train step compiled through two adapters
@pytest.mark.timeout(900)
def test_a_round_trip_back_into_our_trainer_trains_a_chunk():
    """Our task -> Playground env -> our Playground adapter -> our trainer: one smoke chunk."""
    import dataclasses

    from sirl_jax.envs.playground_adapter import PlaygroundEnv
    from sirl_jax.presets import get_preset
    from sirl_jax.train import make_train

    ours = load("h1-stand-v0")[1]
    env = PlaygroundEnv("playground:h1-stand-v0", instance=playground_env("h1-stand-v0"))
    assert (env.observation_size, env.action_size) == (ours.observation_size, ours.action_size)
    assert env.episode_length == ours.episode_length == 1000
    cfg = get_preset("fasttd3-smoke")
    cfg = dataclasses.replace(cfg, train=dataclasses.replace(
        cfg.train, task="h1-stand-v0", num_envs=2, chunk_steps=10, steps=4_004, seed_steps=20,
        buffer_size=4_004))  # fmt: skip
    train = make_train(cfg, env)
    state = jax.jit(train.init)(jax.random.PRNGKey(0))
    state, m = jax.jit(train.step)(state)
    assert int(m["env_steps"]) == 20
    assert np.all(np.isfinite(np.asarray(state.env.obs)))
