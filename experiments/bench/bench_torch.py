"""The 5M TD-MPC2 update here against the official PyTorch TD-MPC2's, side by side on one CPU.

    .venv/bin/python -m experiments.bench.bench_torch --checkout TDMPC2 --python REFENV/bin/python \
        [--rounds 9] [--out docs/benchmarks/bench_torch.json]

TDMPC2 is a checkout of the official TD-MPC2 (nicklashansen/tdmpc2, the repository root) and
REFENV a venv with torch (the CPU wheel) and PyYAML; nothing of TD-MPC2 is copied here. Both
sides run one update of the same problem: the 5M model (`model_size: 5`, the config.yaml
defaults: 5 Q heads, dropout 0.01, 101 bins), h1hand's O = 151 and A = 61, batch 256, horizon 3,
non-episodic; random observations, tanh of random actions, reward 1.

The torch side runs in one child process per mode, kept alive for the whole benchmark:
- `torch eager`: `TDMPC2._update` as written;
- `torch compiled`: the same with the official config's `compile: true`, that is
  `torch.compile(self._update, mode="reduce-overhead")`, TorchInductor's C++ backend on CPU
  (CUDA graphs, what "reduce-overhead" adds, do not apply to CPU tensors).
The official code targets CUDA; the child loads `tdmpc2.py` and `common/scale.py` from the
checkout's text with the device `'cuda:0'` read as `'cpu'`, Adam's `capturable=True` (a CUDA
graph option) as False, and the world model's `.to(device)` left out: it is built on the CPU
already, and with this tensordict the move trips over the meta copies the Q ensemble keeps
(`Cannot copy out of meta tensor`). Nothing else is changed, and the checkout is not edited.

Timing: every case is compiled and warmed first (3 calls), then the rounds go round-robin over
the cases (ours, eager, compiled), one call each, so a change of load hits every case alike;
the table gives the median ms per update and the ratio of torch's median to ours. torch uses
its default intra-op threads (the machine's cores), XLA:CPU its own pool of the same size.
Run it on an idle machine.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import jax

from experiments.bench.bench_agent import compile_timed, synthetic_batch
from sirl_jax.agent import AgentConfig, make_agent
from sirl_jax.run.runlog import write_json

O, A = 151, 61

# The torch child: builds the official agent, answers each line "N" from stdin with a JSON list
# of N update times in ms (one call each). argv: checkout, compile flag, batch, horizon. Its
# protocol lines start with "@@"; anything else it prints (the agent's own prints) is passed on.
CHILD = r"""
import json, os, sys, time, types
import torch, yaml

root, compiled, B, H = sys.argv[1], sys.argv[2] == "1", int(sys.argv[3]), int(sys.argv[4])
O, A = 151, 61
src = os.path.join(root, "tdmpc2")
sys.path.insert(0, src)


def load(name, rel, subs):
    path = os.path.join(src, rel)
    text = open(path).read()
    for old, new in subs:
        if old not in text:
            raise SystemExit(f"patch target {old!r} not in {rel}: another TD-MPC2 version?")
        text = text.replace(old, new)
    mod = types.ModuleType(name)
    mod.__file__ = path
    sys.modules[name] = mod
    exec(compile(text, path, "exec"), mod.__dict__)
    return mod


import common

common.scale = load("common.scale", "common/scale.py", [("'cuda:0'", "'cpu'")])
agent_mod = load("tdmpc2_cpu", "tdmpc2.py", [
    ("'cuda:0'", "'cpu'"), ("capturable=True", "capturable=False"),
    ("WorldModel(cfg).to(self.device)", "WorldModel(cfg)"),
])

raw = yaml.safe_load(open(os.path.join(src, "config.yaml")))
cfg = {}
for k, v in raw.items():
    if isinstance(v, str):
        try:
            v = float(v) if any(c in v for c in ".e") else int(v)
        except ValueError:
            pass
    cfg[k] = v
cfg.update(common.MODEL_SIZE[5])
cfg.update(obs="state", obs_shape={"state": (O,)}, action_dim=A, action_dims=[A],
           episode_length=1000, episode_lengths=[1000], multitask=False, task_dim=0,
           tasks=["h1hand"], episodic=False, compile=compiled, batch_size=B, horizon=H,
           model_size=5)
cfg["bin_size"] = (cfg["vmax"] - cfg["vmin"]) / (cfg["num_bins"] - 1)


class Cfg:
    def __init__(self, d):
        self.__dict__.update(d)

    def get(self, k, default=None):
        return getattr(self, k, default)


torch.manual_seed(0)
agent = agent_mod.TDMPC2(Cfg(cfg))
n_params = sum(p.numel() for g in agent.optim.param_groups + agent.pi_optim.param_groups
               for p in g["params"])  # what the two optimisers train
obs = torch.randn(H + 1, B, O)
action = torch.tanh(torch.randn(H, B, A))
reward = torch.ones(H, B, 1)
terminated = torch.zeros(H, B, 1)


def once():
    t = time.perf_counter()
    torch.compiler.cudagraph_mark_step_begin()
    out = agent._update(obs, action, reward, terminated)
    float(out["total_loss"])
    return (time.perf_counter() - t) * 1e3


t0 = time.perf_counter()
for _ in range(3):
    once()
print("@@" + json.dumps({"ready": True, "params": n_params, "threads": torch.get_num_threads(),
                  "torch": torch.__version__, "warm_s": time.perf_counter() - t0}), flush=True)
for line in sys.stdin:
    print("@@" + json.dumps([once() for _ in range(int(line))]), flush=True)
"""


class TorchCase:
    """One long-lived torch child process (eager or compiled)."""

    def __init__(self, python: str, checkout: str, compiled: bool, batch: int, horizon: int):
        argv = [python, "-c", CHILD, checkout, "1" if compiled else "0", str(batch), str(horizon)]
        self.proc = subprocess.Popen(argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        self.name = "compiled" if compiled else "eager"
        self.info = self._reply()

    def _reply(self):
        for line in self.proc.stdout:
            if line.startswith("@@"):
                return json.loads(line[2:])
            print(f"[torch {self.name}] {line}", end="", file=sys.stderr)
        raise SystemExit(f"the torch child ({self.name}) exited with {self.proc.wait()}; "
                         "see its stderr above")  # fmt: skip

    def time(self, n: int = 1) -> list[float]:
        self.proc.stdin.write(f"{n}\n")
        self.proc.stdin.flush()
        return self._reply()

    def close(self) -> None:
        self.proc.stdin.close()
        self.proc.wait(timeout=60)


def ours(cfg: AgentConfig):
    """A timer of one call of our jitted update (compiled and warmed here), and its compile s."""
    agent = make_agent(cfg, O, A, episode_length=1000)
    args = (agent.init(jax.random.PRNGKey(0)), synthetic_batch(cfg, O, A, jax.random.PRNGKey(1)),
            jax.numpy.float32(100.0), jax.random.PRNGKey(2))  # fmt: skip
    fn, compile_s = compile_timed(agent.update, *args)
    for _ in range(3):
        jax.block_until_ready(fn(*args))

    def once() -> float:
        t = time.perf_counter()
        jax.block_until_ready(fn(*args))
        return (time.perf_counter() - t) * 1e3

    return once, compile_s


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkout", required=True, help="a checkout of nicklashansen/tdmpc2")
    ap.add_argument("--python", required=True, help="a python with torch (CPU) and PyYAML")
    ap.add_argument("--rounds", type=int, default=9)
    ap.add_argument("--no-eager", action="store_true", help="time the compiled torch only")
    ap.add_argument("--out", default=None, help="write the medians and every time as JSON")
    args = ap.parse_args()
    if args.rounds < 1:
        raise SystemExit(f"--rounds must be >= 1, got {args.rounds}")
    if not os.path.isfile(os.path.join(args.checkout, "tdmpc2", "tdmpc2.py")):
        raise SystemExit(f"--checkout {args.checkout!r} has no tdmpc2/tdmpc2.py: pass the root "
                         "of a nicklashansen/tdmpc2 checkout")  # fmt: skip
    cfg = AgentConfig()
    ours_once, ours_compile = ours(cfg)
    torch_cases = {}
    for name, compiled in (("torch eager", False), ("torch compiled", True)):
        if compiled or not args.no_eager:
            t = time.perf_counter()
            case = TorchCase(args.python, args.checkout, compiled, cfg.batch_size, cfg.horizon)
            case.info["start_s"] = time.perf_counter() - t
            torch_cases[name] = case
            print(f"{name}: {case.info}", flush=True)
    times: dict[str, list[float]] = {"sirl_jax (jit)": []} | {n: [] for n in torch_cases}
    for r in range(args.rounds):
        times["sirl_jax (jit)"].append(ours_once())
        for name, case in torch_cases.items():
            times[name] += case.time(1)
        print(f"round {r + 1}/{args.rounds}: "
              + ", ".join(f"{n} {t[-1]:.0f} ms" for n, t in times.items()), flush=True)  # fmt: skip
    for case in torch_cases.values():
        case.close()
    med = {n: statistics.median(t) for n, t in times.items()}
    base = med["sirl_jax (jit)"]
    print(f"\n5M update, O={O} A={A} B={cfg.batch_size} H={cfg.horizon}, {args.rounds} rounds "
          f"round-robin, median; jax {jax.__version__} on {jax.default_backend()}")  # fmt: skip
    print(f"| {'update':<16} | {'ms':>7} | {'min-max ms':>13} | {'x ours':>6} |")
    print(f"|{'-' * 18}|{'-' * 9}|{'-' * 15}|{'-' * 8}|")
    for name, t in times.items():
        print(f"| {name:<16} | {med[name]:7.1f} | {min(t):6.0f}-{max(t):<6.0f} | "
              f"{med[name] / base:6.2f} |")  # fmt: skip
    if args.out:
        doc = {"config": {"model": "5M", "obs": O, "action": A, "batch": cfg.batch_size,
                          "horizon": cfg.horizon, "num_q": cfg.arch.num_q,
                          "dropout": cfg.dropout},
               "rounds": args.rounds, "median_ms": med, "times_ms": times,
               "ours_compile_s": ours_compile, "jax": jax.__version__,
               "torch": {n: c.info for n, c in torch_cases.items()}}  # fmt: skip
        write_json(Path(args.out), doc)


if __name__ == "__main__":
    sys.exit(main())
