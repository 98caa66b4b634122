"""The sit_simple_solved study's summary.json and figure, from its arms' eval.csv (partial too).

    .venv/bin/python -m experiments.study sit_simple_solved --arm beta1 --seed 0   # each seed
    .venv/bin/python -m experiments.studies.sit_simple_solved_report \
        --results results/sit_simple_solved --out docs/results/sit_simple_solved
    .venv/bin/python -m experiments.studies.sit_simple_solved_report --pilot \
        --results results/sit_simple_solved_pilot    # the pilot's table, pilot.json

summary.json has exactly the keys the issue asks for: task, success_bar, env_steps_per_seed,
eval_episodes and, per arm, each seed's final 16-episode return, the mean of its last three
evaluations, and the wall-clock hours to its first evaluation (after step 0) at the bar (None
if it never got there), seeds in order. details.json holds the rest per arm: which seed each
entry is, its CPU hours to the bar and the env step of its final evaluation. The figure draws
each seed against env steps with FastTD3's published curve (fasttd3_published.json, its seeds'
mean and range) and the published TD-MPC2 curve (`sirl_jax/data/reference_curves.json`).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import tyro

from experiments.studies.curves import eval_curves, has_evals, hours_to
from experiments.studies.specs import RECIPES
from experiments.studies.specs import SIT as TASK

BAR, ZERO_ACTION = 750.0, 647.0  # HumanoidBench's bar; the zero action's return (the issue's)
ARM_LABELS = {"beta0": ("FastTD3 (beta 0)", "tab:green"),
              "beta1": ("FastTD3 + TDMPBC term (beta 1)", "tab:purple")}  # fmt: skip


SUMMARY_KEYS = ("final", "last3_mean", "hours_to_bar")


def summarize(root: Path) -> tuple[dict, dict]:
    """(summary.json, details.json): the issue's keys, and the rest of each arm's figures."""
    arms, steps = {}, []
    for arm in ARM_LABELS:
        if not has_evals(root / arm):
            continue
        by_seed = dict(sorted(eval_curves(root / arm, "policy_return").items()))
        curves = by_seed.values()
        arms[arm] = {
            "seeds": list(by_seed),  # the seed of each entry below (seeds may run one by one)
            "final": [round(float(c["return"][-1]), 1) for c in curves],
            "last3_mean": [round(float(np.mean(c["return"][-3:])), 1) for c in curves],
            "hours_to_bar": [hours_to(c, BAR) for c in curves],
            "cpu_hours_to_bar": [hours_to(c, BAR, "cpu_h") for c in curves],
            "final_steps": [int(c["steps"][-1]) for c in curves],
        }
        steps += arms[arm]["final_steps"]
    config = json.loads(next(root.glob("**/config.json")).read_text())
    summary = {"task": TASK, "success_bar": int(BAR), "env_steps_per_seed": min(steps, default=0),
               "eval_episodes": config["train"]["eval_episodes"],
               "arms": {a: {k: v[k] for k in SUMMARY_KEYS} for a, v in arms.items()}}
    details = {a: {k: x for k, x in v.items() if k not in SUMMARY_KEYS} for a, v in arms.items()}
    return summary, details


def figure(root: Path, published: Path, out: Path) -> None:
    import matplotlib

    from sirl_jax.run.reference import reference_curves

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 4.8))
    last = 0
    for arm, (label, color) in ARM_LABELS.items():
        if not has_evals(root / arm):
            continue
        for i, c in enumerate(eval_curves(root / arm, "policy_return").values()):
            ax.plot(c["steps"], c["return"], color=color, marker=".", lw=1,
                    label=label if i == 0 else None)  # fmt: skip
            last = max(last, int(c["steps"][-1]))
    pub = json.loads(published.read_text())
    ax.plot(pub["env_step"], pub["return"], color="tab:orange", marker="s", lw=1.5,
            label="FastTD3, published (its settings, mean of seeds)")  # fmt: skip
    ax.fill_between(pub["env_step"], pub["return_min"], pub["return_max"], color="tab:orange",
                    alpha=0.15)  # fmt: skip
    for curve in reference_curves(TASK):
        if curve.algo == "TD-MPC2":
            ax.plot(curve.steps, curve.mean, color="tab:blue", lw=1.5,
                    label="TD-MPC2, published (5M model)")  # fmt: skip
            ax.fill_between(curve.steps, curve.lcb, curve.ucb, color="tab:blue", alpha=0.12)
    ax.axhline(BAR, color="k", lw=0.9, label=f"success bar ({BAR:.0f})")
    ax.axhline(ZERO_ACTION, color="k", ls="--", lw=0.8, label=f"zero action ({ZERO_ACTION:.0f})")
    ax.set_xlim(0, max(2.5 * last, 1_300_000))
    ax.set(xlabel="env steps per seed", ylabel="eval return (16 episodes, eval mode)",
           title=f"{TASK}: FastTD3 with and without the TDMPBC term, 2-core CPU")  # fmt: skip
    ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)


def video(arm_dir: Path, out: Path, frames: int = 6) -> str:
    """One episode of the beta-1 seed whose final evaluation is best, at its final checkpoint
    (the vmapped state restored, that seed's agent sliced out), to `out`/best_seed.mp4, and
    `frames` frames spread over it side by side in `out`/frame_strip.png. `main` chose the
    headless GL backend before MuJoCo was imported."""
    import imageio.v2 as imageio
    import jax

    from sirl_jax.run.checkpoint import Checkpointer
    from sirl_jax.run.render import render_policy
    from sirl_jax.run.runlog import load_config
    from sirl_jax.run.runner import build, eval_key

    curves = eval_curves(arm_dir, "policy_return")
    seed = max(curves, key=lambda s: curves[s]["return"][-1])
    alone = (arm_dir / f"seed{seed}").is_dir()  # the seed ran as its own process
    run_dir = arm_dir / f"seed{seed}" if alone else arm_dir
    swept = run_dir / f"seed={seed}"  # a sweep's run (experiments.study), else the old layout
    swept = swept if swept.is_dir() else None
    config = load_config(swept or run_dir)
    spec, train = build(config)
    keys = jax.random.split(jax.random.PRNGKey(0), 1 if alone else len(curves))
    ckpt = Checkpointer((swept or run_dir) / "checkpoints")
    try:
        step = ckpt.latest_step()
        if swept:  # one run's state, its buffer a checkpoint item of its own
            abstract = jax.eval_shape(train.init, keys[0]).replace(buffer=None)
        else:  # the vmapped state of the arm's seeds
            abstract = jax.eval_shape(jax.vmap(train.init), keys)
        state = ckpt.restore({"state": abstract}, step)
    finally:
        ckpt.close()
    pick = (lambda x: x) if swept else (lambda x: x[0 if alone else seed])
    agent_state = jax.tree.map(pick, state["state"].agent)
    mp4 = out / "best_seed.mp4"
    summary = render_policy(train.env, train.agent, agent_state, "prior", 1,
                            eval_key(seed, step), mp4,
                            f"{spec.id} beta 1 seed {seed} @ {step:,} steps", width=480,
                            height=360)  # fmt: skip
    reader = imageio.get_reader(mp4)
    shots = [reader.get_data(int(i)) for i in np.linspace(0, summary["frames"] - 1, frames)]
    imageio.imwrite(out / "frame_strip.png", np.concatenate(shots, axis=1))
    return (f"seed {seed} at {step:,} steps: this episode {summary['returns'][0]:.1f} over "
            f"{summary['frames']} frames, {mp4.stat().st_size / 1e6:.2f} MB")


def pilot_rows(results: Path) -> list[dict]:
    """Each recipe's 16-episode evaluations at equal training CPU: up to the CPU time every
    recipe's run has reached, the later half of it summarised (mean, min, max, evaluations at
    the bar, mean change between consecutive evaluations), with the first one at the bar."""
    curves = {}
    for name in RECIPES:
        if has_evals(results / name):
            (curves[name],) = eval_curves(results / name, "policy_return").values()
    if not curves:
        raise SystemExit(f"error: no recipe under {results} has evaluations yet")
    limit = min(float(c["cpu_h"][-1]) for c in curves.values())
    rows = []
    for name, c in curves.items():
        keep = (c["cpu_h"] <= limit + 1e-9) & (c["steps"] > 0)
        late = keep & (c["cpu_h"] >= limit / 2)
        r = c["return"][late]
        hit = np.flatnonzero(keep & (c["return"] >= BAR))
        rows.append({
            "recipe": name, "cpu_h": round(limit, 3), "evals_late": int(late.sum()),
            "steps_at_limit": int(c["steps"][keep][-1]), "late_mean": round(float(r.mean()), 1),
            "late_min": round(float(r.min()), 1), "late_max": round(float(r.max()), 1),
            "late_at_bar": int(np.sum(r >= BAR)),
            "swing": round(float(np.mean(np.abs(np.diff(r)))), 1) if r.size > 1 else None,
            "last": round(float(c["return"][keep][-1]), 1),
            "first_bar_steps": int(c["steps"][hit[0]]) if hit.size else None,
        })  # fmt: skip
    return rows


def main(recipe: str = "", results: Path = Path("results/sit_simple_solved"),
         out: Path = Path("docs/results/sit_simple_solved"), with_video: bool = False,
         pilot: bool = False) -> None:  # fmt: skip
    """Writes `out`/summary.json and `out`/figure.png for the arms under `results` (or
    `results`/`recipe`: the committed runs' layout), and with `with_video` the best beta-1
    seed's mp4 and frame strip; `pilot`: the pilot's table as `results`/pilot.json."""
    if pilot:
        rows = pilot_rows(results)
        (results / "pilot.json").write_text(json.dumps(rows, indent=1))
        for r in rows:
            print(r)
        return
    if with_video:  # MuJoCo reads MUJOCO_GL once, at import
        from sirl_jax.run.render import select_gl

        select_gl()
    root = results / recipe if recipe else results
    if not any(has_evals(root / arm) for arm in ARM_LABELS):
        raise SystemExit(f"error: no arm of {root} has an eval.csv yet (run experiments.study "
                         "sit_simple_solved --arm beta1 first)")
    summary, details = summarize(root)
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    (out / "details.json").write_text(json.dumps(details, indent=1) + "\n")
    figure(root, out / "fasttd3_published.json", out / "figure.png")
    for arm, v in summary["arms"].items():
        d = details[arm]
        print(f"{arm}: seeds {d['seeds']} final {v['final']} last3 {v['last3_mean']} at "
              f"{d['final_steps']} steps; hours to bar {v['hours_to_bar']} (CPU hours "
              f"{d['cpu_hours_to_bar']})")  # fmt: skip
    print(f"wrote {out / 'summary.json'}, {out / 'details.json'} and {out / 'figure.png'}")
    if with_video:
        print(f"wrote {out / 'best_seed.mp4'}: {video(root / 'beta1', out)}")


if __name__ == "__main__":
    tyro.cli(main)
