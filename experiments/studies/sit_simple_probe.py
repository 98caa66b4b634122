"""Why FastTD3 + TDMPBC's actor swings on sit_simple: every checkpoint of one pilot run probed.

    .venv/bin/python -m experiments.studies.sit_simple_probe \
        --run results/sit_simple_solved/pilot/base --out docs/results/sit_simple_solved/probe.csv

A pilot run (`experiments.studies.sit_simple_solved --pilot base`) keeps the checkpoint of each
10k-step evaluation. For each, this writes one row:
- 16 eval-mode episodes of the actor (fresh keys, the same for every checkpoint): mean, min and
  max return, how many reach the bar, how many end by a fall (terminated) and their mean length;
- the critic: min(Q1, Q2)(s, actor(s)) at the first step of the held (>= bar) and of the other
  episodes, and over the 25 steps before a fall;
- the actor: mean |a|, the share of |a| > 0.95, the mean step-to-step change |a_t - a_{t-1}|,
  and its drift: the RMS change of actor(s) since the previous checkpoint on 4,096 fixed states
  (two replay batches of the last checkpoint);
- the replay: R_max, and the mean BC weight omega of what the actor loss sees under
  episode-uniform sampling (an episode uniformly) and under transition-uniform sampling (each
  transition equally), with the share of transitions whose omega exceeds 0.5.
"""

from __future__ import annotations

import csv
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import tyro

from experiments.paper.common import arm_env, write_summary
from sirl_jax.agent import losses
from sirl_jax.agent.fasttd3_nets import ReluMLP, widths
from sirl_jax.envs.base import VecEnv
from sirl_jax.run.checkpoint import Checkpointer
from sirl_jax.run.runlog import load_config
from sirl_jax.train import make_train

BAR, EPISODES, BEFORE_FALL = 750.0, 16, 25


def make_probe(config, env):
    """(probe, actions): probe(state, states, key) -> the per-step arrays of 16 episodes, the
    replay's figures and the actor's actions on `states`, of one (unbatched) state; actions(
    state, states) -> those actions alone."""
    fc, A = config.agent.fasttd3, env.action_size
    actor = ReluMLP(widths(fc.actor_hidden_dim), A, fc.init_scale, tanh=True)
    critic = ReluMLP(widths(fc.critic_hidden_dim), fc.num_atoms)
    support = jnp.linspace(fc.v_min, fc.v_max, fc.num_atoms)
    vec, T = VecEnv(env, EPISODES), env.episode_length

    def pi(agent, obs):
        p = agent.params["actor_ema" if fc.actor_ema > 0 else "actor"]
        return actor.apply({"params": p}, agent.obs_norm(obs, fc.obs_norm_eps))

    def q(agent, obs, action):
        x = jnp.concatenate([agent.obs_norm(obs, fc.obs_norm_eps), action], axis=-1)
        logits = jax.vmap(lambda p: critic.apply({"params": p}, x))(agent.params["critic"])
        return jnp.min(jnp.sum(jax.nn.softmax(logits, -1) * support, -1), axis=0)

    def probe(state, states, key):
        agent = state.agent

        def body(carry, _):
            env_state, ended, prev = carry
            action = pi(agent, env_state.obs)
            value = q(agent, env_state.obs, action)
            nxt = vec.step(env_state, action)
            done = nxt.terminated | nxt.truncated | nxt.blowup
            out = {"alive": ~ended, "q": value, "reward": nxt.reward, "fell": nxt.terminated,
                   "abs": jnp.mean(jnp.abs(action), -1),
                   "sat": jnp.mean(jnp.abs(action) > 0.95, -1),
                   "jitter": jnp.mean(jnp.abs(action - prev), -1)}  # fmt: skip
            return (nxt, ended | done, action), out

        init = (vec.reset(key), jnp.zeros(EPISODES, bool), jnp.zeros((EPISODES, A)))
        _, steps = jax.lax.scan(body, init, None, length=T)
        buf = state.buffer
        m = buf.ep_length.shape[1]
        live = ((jnp.arange(m)[None] - buf.ep_head[:, None]) % m
                < (buf.ep_tail - buf.ep_head)[:, None])  # fmt: skip
        omega = losses.sirl_weight(buf.ep_return, buf.r_max, config.agent.sirl)
        n = jnp.where(live, buf.ep_length - 1, 0).astype(jnp.float32)  # transitions
        replay = {"r_max": buf.r_max, "episodes": jnp.sum(live),
                  "omega_episode": jnp.sum(jnp.where(live, omega, 0)) / jnp.sum(live),
                  "omega_transition": jnp.sum(n * jnp.where(live, omega, 0)) / jnp.sum(n),
                  "share_omega_half": jnp.sum(n * (live & (omega > 0.5))) / jnp.sum(n)}  # fmt: skip
        return steps, replay, pi(agent, states)

    return jax.jit(probe), jax.jit(lambda state, states: pi(state.agent, states))


def summarize(steps: dict, replay: dict, actions, previous) -> dict:
    """One checkpoint's row from `probe`'s arrays (numpy, time-major [T, N])."""
    alive = steps["alive"]
    returns = np.sum(steps["reward"] * alive, 0)
    fell = np.any(steps["fell"] & alive, 0)
    lengths = alive.sum(0)
    held = returns >= BAR
    q0 = steps["q"][0]
    before = [steps["q"][max(0, n - BEFORE_FALL):n, i].mean()
              for i, n in enumerate(lengths) if fell[i]]  # fmt: skip
    mask = alive.astype(bool)

    def mean(x, where=None):
        return round(float(np.mean(x[where] if where is not None else x)), 3) if (
            where is None or np.any(where)) else ""  # fmt: skip

    row = {"return_mean": mean(returns), "return_min": round(float(returns.min()), 1),
           "return_max": round(float(returns.max()), 1), "at_bar": int(held.sum()),
           "falls": int(fell.sum()), "fall_length": mean(lengths, fell),
           "q0_held": mean(q0, held), "q0_other": mean(q0, ~held),
           "q_before_fall": round(float(np.mean(before)), 3) if before else "",
           "abs_action": mean(steps["abs"][mask]), "saturated": mean(steps["sat"][mask]),
           "jitter": mean(steps["jitter"][1:][mask[1:]]),
           "drift": "" if previous is None else round(float(np.sqrt(np.mean(
               (actions - previous) ** 2))), 4)}  # fmt: skip
    return {**row, **{k: round(float(v), 4) for k, v in replay.items()}}


def main(run: Path, out: Path, seed: int = 0) -> None:
    """Probes every checkpoint of the pilot run `run` (one seed), one CSV row each, appended to
    `out` as it goes; checkpoints already in `out` are skipped (a rerun picks up new ones)."""
    config = load_config(run)
    env = arm_env(config)
    train = make_train(config, env)
    keys = jax.random.split(jax.random.PRNGKey(0), 1)
    abstract = {"state": jax.eval_shape(jax.vmap(train.init), keys)}
    ckpt = Checkpointer(run / "checkpoints", max_to_keep=None)
    steps_saved = ckpt.steps()
    if not steps_saved:
        raise SystemExit(f"error: {run} has no checkpoint to probe")
    last = jax.tree.map(lambda x: x[0], ckpt.restore(abstract, steps_saved[-1])["state"])
    states = jnp.concatenate([train.buffer.sample(last.buffer, k).obs[0]
                              for k in jax.random.split(jax.random.PRNGKey(seed), 2)])  # fmt: skip
    rows = list(csv.DictReader(open(out))) if out.exists() else []  # resume: rows kept
    done = {int(r["env_steps"]) for r in rows}
    (probe, probe_actions), previous = make_probe(config, env), None
    for step in steps_saved:
        state = jax.tree.map(lambda x: x[0], ckpt.restore(abstract, step)["state"])
        if step in done:  # its drift row needs the actions, which are cheap to recompute
            previous = jax.device_get(probe_actions(state, states))
            continue
        steps, replay, actions = jax.device_get(probe(state, states, jax.random.PRNGKey(seed)))
        rows.append({"env_steps": step, **summarize(steps, replay, actions, previous)})
        previous = actions
        print(rows[-1], flush=True)
        write_summary(rows, out)  # as it goes
    ckpt.close()


if __name__ == "__main__":
    tyro.cli(main)
