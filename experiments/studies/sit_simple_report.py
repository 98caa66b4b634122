"""The sit_simple study's summary.json and figure, from the arms' CSVs (partial ones too).

    .venv/bin/python -m experiments.studies.sit_simple_report \
        --results results/sit_simple --out docs/results/sit_simple_study

Reads the arms `experiments.study sit_simple --arm tdmpc2|tdmpbc` trained under `<results>`
(or the committed runs' `<results>/study/{tdmpc2,tdmpbc}`) and `<results>/random.json`;
writes `<out>/summary.json` (the keys the study promises) and `<out>/figure.png`: both arms'
mean +- std planner eval return over their seeds against env steps, over the published
TD-MPC2 and BMPC curves of the task, with the TDMPBC arm's R_max and 10x the random return,
and the official TD-MPC2's curve at the study's config where `<results>/official/eval.csv`
exists (`experiments.studies.official_tdmpc2`).
With `--video`, also `<out>/best_seed.mp4`: one episode of the best seed's policy (planner,
eval mode) from its arm's latest checkpoint, the seed with the highest last eval return.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import tyro

from experiments.studies.curves import eval_curves, train_rows
from sirl_jax.run.reference import reference_curves

TASK = "h1hand-sit_simple-v0"
ARMS = ("tdmpc2", "tdmpbc")
REFERENCE_100K = 308.6  # TD-MPC2's published mean at 100k (sirl_jax/data/reference_curves.json)


def arms_root(results: Path) -> Path:
    """Where the arms are: `results`/study (the committed runs), or `results` itself (the
    arms `experiments.study sit_simple` writes)."""
    return results / "study" if (results / "study").is_dir() else results


def arm_curves(arm_dir: Path) -> dict[int, dict[str, np.ndarray]]:
    """{seed: {"steps", "return", "r_max", ...}} of the planner's eval return, by env step."""
    return eval_curves(arm_dir, "planner_return")


def summarize(results: Path) -> dict:
    random = json.loads((results / "random.json").read_text())
    arms, wall = {}, 0.0
    for arm in ARMS:
        d = arms_root(results) / arm
        curves = arm_curves(d)
        at = [float(c["return"][c["steps"] == 100_000][0]) if (c["steps"] == 100_000).any()
              else None for c in curves.values()]  # fmt: skip
        arms[arm] = {"final": [float(c["return"][-1]) for c in curves.values()], "at_100k": at,
                     "final_steps": [int(c["steps"][-1]) for c in curves.values()]}  # fmt: skip
        if (d / "done.json").exists():
            wall = max(wall, float(json.loads((d / "done.json").read_text())["wall_s"]))
        else:
            last = train_rows(d)
            wall = max(wall, max(float(r["wall_s"]) for r in last) if last else 0.0)
    steps = min(min(a["final_steps"]) for a in arms.values())
    return {"task": TASK, "env_steps_per_seed": steps, "random_return": random["mean"],
            "reference_100k": REFERENCE_100K,
            "arms": {a: {"final": v["final"], "at_100k": v["at_100k"]} for a, v in arms.items()},
            "wall_clock_s": wall}  # fmt: skip


ENV_LABELS = {"hb": "HumanoidBench's contacts", "reduced": "reduced contacts"}
"""The figure's name for each of the study's envs (`specs.STUDY_ENV`, or the task defaults)."""


def env_label(arm_dir: Path) -> str:
    """" (<name>)" of the env set whose options the arm's config.json has (an old one reads as
    the env it ran on, `runlog.load_config`), the options themselves if none matches, "" without
    a config.json."""
    from experiments.studies.specs import STUDY_ENV
    from sirl_jax.config import TrainConfig
    from sirl_jax.run.runlog import RunDirError, load_config

    try:
        options = load_config(arm_dir).train.env_options
    except RunDirError:
        return ""
    for name, label in ENV_LABELS.items():
        if options == TrainConfig(task=TASK, **({} if name == "hb" else STUDY_ENV)).env_options:
            return f" ({label})"
    return " (" + ", ".join(f"{k}={v}" for k, v in options.items()) + ")"


def figure(results: Path, summary: dict, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    last = 0
    for arm, color, label in (("tdmpc2", "tab:blue", "TD-MPC2 (beta 0)"),
                              ("tdmpbc", "tab:red", "TDMPBC (beta 1)")):  # fmt: skip
        curves = list(arm_curves(arms_root(results) / arm).values())
        n = min(len(c["steps"]) for c in curves)
        steps = curves[0]["steps"][:n]
        ret = np.stack([c["return"][:n] for c in curves])
        mean, std = np.nanmean(ret, 0), np.nanstd(ret, 0)
        ax.plot(steps, mean, color=color, label=f"{label}, ours, {len(curves)} seeds")
        ax.fill_between(steps, mean - std, mean + std, color=color, alpha=0.2)
        if arm == "tdmpbc":
            r = np.stack([c["r_max"][:n] for c in curves])
            seen = np.isfinite(r).any(0)  # R_max exists once an episode has been recorded
            rmax = np.nanmean(r[:, seen], 0)
            ax.plot(steps[seen], rmax, color=color, ls=":", label="TDMPBC R_max (buffer), mean")
        last = max(last, int(steps[-1]))
    official = results / "official" / "eval.csv"  # experiments.studies.official_tdmpc2
    if official.exists():
        c = arm_curves(official.parent).get(0)
        if c is not None and len(c["steps"]):
            ax.plot(c["steps"], c["return"], color="k", ls=":", marker="o", ms=3,
                    label="TD-MPC2 official (HumanoidBench's PyTorch fork), our config, 1 seed")
            last = max(last, int(c["steps"][-1]))
    for ref, style in zip(reference_curves(TASK), ("--", "-."), strict=False):
        c = ref.until(max(last, 100_000))
        ax.plot(c.steps, c.mean, color="gray", ls=style,
                label=f"{ref.algo} published (full config, 3 seeds)")  # fmt: skip
    bar = 10 * summary["random_return"]
    ax.axhline(bar, color="k", lw=0.8, label=f"10x random ({bar:.0f})")
    ax.set_xlabel("env steps per seed")
    ax.set_ylabel("eval return (planner, eval mode)")
    ax.set_title(f"{TASK}{env_label(arms_root(results) / 'tdmpc2')}: eval return against env steps",
                 fontsize=10)  # fmt: skip
    ax.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    plt.close(fig)


def best_seed(results: Path) -> tuple[str, int, int, float]:
    """(arm, seed, env step, eval return) of the best last evaluation that has a checkpoint."""
    from sirl_jax.run.checkpoint import Checkpointer

    best = None
    for arm in ARMS:
        ckpt = Checkpointer(arms_root(results) / arm / "checkpoints")
        try:
            step = ckpt.latest_step()
        finally:
            ckpt.close()
        for seed, c in arm_curves(arms_root(results) / arm).items():
            at = c["steps"] == step
            if step is not None and at.any() and (best is None or c["return"][at][0] > best[3]):
                best = (arm, seed, step, float(c["return"][at][0]))
    if best is None:
        raise SystemExit(f"error: no arm under {results / 'study'} has a checkpoint to render")
    return best


def video(results: Path, out: Path, width: int, height: int) -> dict:
    """Renders one episode of the best seed (`best_seed`) to `out`: the vmapped train state of
    its arm is restored, and that seed's agent state is sliced out. `main` has chosen the
    headless GL backend (`select_gl`) before anything imported MuJoCo."""
    import jax

    from sirl_jax.run.checkpoint import Checkpointer
    from sirl_jax.run.render import render_policy
    from sirl_jax.run.runlog import load_config
    from sirl_jax.run.runner import build, eval_key

    arm, seed, step, ret = best_seed(results)
    d = arms_root(results) / arm
    config = load_config(d)
    spec, train = build(config)
    seeds = len(arm_curves(d))
    abstract = jax.eval_shape(jax.vmap(train.init), jax.random.split(jax.random.PRNGKey(0), seeds))
    ckpt = Checkpointer(d / "checkpoints")
    try:
        state = ckpt.restore({"state": abstract}, step)["state"]
    finally:
        ckpt.close()
    agent_state = jax.tree.map(lambda x: x[seed], state.agent)
    title = f"{spec.id} {arm} seed {seed} @ {step:,} steps, planner"
    summary = render_policy(train.env, train.agent, agent_state, "planner", 1,
                            eval_key(seed, step), out, title, width=width, height=height)
    size = out.stat().st_size / 1e6
    print(f"wrote {out}: {arm} seed {seed} at {step:,} env steps (eval return {ret:.1f}); this "
          f"episode {summary['returns'][0]:.1f} over {summary['frames']} frames, {size:.1f} MB")
    return summary


@dataclasses.dataclass(frozen=True)
class Args:
    results: str = "results/sit_simple"
    out: str = "docs/results/sit_simple_study"
    video: bool = False
    """Also render the best seed's final policy (one episode) to <out>/best_seed.mp4."""
    width: int = 480
    height: int = 360


def main(args: Args) -> None:
    if args.video:  # MuJoCo reads MUJOCO_GL once, at import (the figure's env label imports it)
        from sirl_jax.run.render import select_gl

        select_gl()
    results, out = Path(args.results), Path(args.out)
    summary = summarize(results)
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    figure(results, summary, out / "figure.png")
    ten_x = 10 * summary["random_return"]
    for arm, v in summary["arms"].items():
        print(f"{arm}: final {np.round(v['final'], 1)} (10x random = {ten_x:.1f}: "
              f"{sum(f >= ten_x for f in v['final'])}/{len(v['final'])} seeds), at 100k "
              f"{v['at_100k']}")  # fmt: skip
    td = [x for x in summary["arms"]["tdmpc2"]["at_100k"] if x is not None]
    if td:
        print(f"TD-MPC2 arm at 100k: {np.mean(td):.1f} = {np.mean(td) / REFERENCE_100K:.2f} of "
              f"the reference {REFERENCE_100K}")  # fmt: skip
    print(f"wrote {out / 'summary.json'} and {out / 'figure.png'}")
    if args.video:
        video(results, out / "best_seed.mp4", args.width, args.height)


if __name__ == "__main__":
    main(tyro.cli(Args))
