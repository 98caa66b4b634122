"""A sweep: a grid of runs (seeds x values of per-run scalars) trained as one vmapped program.

    sweep = Sweep.parse(seeds=2, specs=["sirl.beta=0,1"])   # 4 runs
    train = make_train(config, env)
    state = jax.jit(sweep.init(train, config))()            # [R, ...] every run's state
    step = jax.jit(jax.vmap(train.step), donate_argnums=0)  # one program for the R runs

A run of a sweep is the run its own config (`Sweep.configs`) trains alone: the same key
(`PRNGKey(train.seed)`) and, because the swept fields are read from `state.agent.hyper` rather
than traced into the program (`sirl_jax.agent.hyper`), the same program; only vmap's batching
can reorder float reductions (tests/test_sweep.py measures by how much). Fields that set shapes
or the trace are static and refused (`Sweep.parse`).
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Sequence

import jax
import jax.numpy as jnp

from sirl_jax.agent.hyper import SWEEPABLE, fields, get, init_hyper
from sirl_jax.config import Config


class SweepError(ValueError):
    """A --sweep spec that cannot be run: the message names the value and what is allowed."""


def _replace(obj, path: list[str], value):
    """A copy of a nested frozen dataclass with the field at `path` set to `value` (which runs
    the dataclasses' own checks)."""
    if len(path) == 1:
        return dataclasses.replace(obj, **{path[0]: value})
    return dataclasses.replace(obj, **{path[0]: _replace(getattr(obj, path[0]), path[1:], value)})


def _static_reason(field: str) -> str | None:
    """Why `field` (an AgentConfig path) cannot be swept, or None if it is not a field at all."""
    from sirl_jax.agent.config import AgentConfig
    from sirl_jax.config import TrainConfig

    for root, where in ((AgentConfig(), "agent"), (TrainConfig(), "train")):
        name = field.removeprefix(f"{where}.")
        try:
            get(root, name)
        except AttributeError:
            continue
        return (f"it is static: {where}.{name} sets array shapes or what the step traces, so "
                "each value would be another program")  # fmt: skip
    return None


@dataclasses.dataclass(frozen=True)
class Sweep:
    """seeds: runs per point of the grid (train.seed 0..seeds-1 offset by the config's seed);
    axes: ((AgentConfig field, values), ...), each field in `SWEEPABLE`.

    first_seed: the index of the first seed (a sweep of 1 seed from index 2 trains the third
    seed alone, e.g. one seed per process). split: 0, each run's key is PRNGKey(train.seed)
    of its own config, as a run trained alone; N > 0, seed index i's key is
    split(PRNGKey(base train.seed), N)[i], the scheme the study drivers used before sweeps,
    kept so that their committed runs reproduce (`experiments.study`; not on the CLI)."""

    seeds: int = 1
    axes: tuple[tuple[str, tuple[float, ...]], ...] = ()
    first_seed: int = 0
    split: int = 0

    def __post_init__(self):
        if self.first_seed < 0 or (self.split and self.first_seed + self.seeds > self.split):
            raise SweepError(f"seeds {self.first_seed}..{self.first_seed + self.seeds - 1} "
                             f"are invalid with split={self.split}; allowed: indices in "
                             f"0..{max(self.split, 1) - 1} when split > 0, >= 0 otherwise")

    @classmethod
    def parse(cls, seeds: int, specs: Sequence[str]) -> Sweep:
        """From CLI specs "FIELD=V1,V2,..." (FIELD as in `SWEEPABLE`, e.g. sirl.beta)."""
        if seeds < 1:
            raise SweepError(f"--seeds {seeds} is invalid; allowed: an int >= 1")
        axes, seen = [], set()
        allowed = ", ".join(SWEEPABLE)
        for spec in specs:
            field, sep, raw = spec.partition("=")
            field = field.strip().removeprefix("agent.")
            if not sep or not raw.strip():
                raise SweepError(f"--sweep {spec!r} is invalid; allowed: FIELD=V1,V2,... with "
                                 f"FIELD one of {allowed}")  # fmt: skip
            if field not in SWEEPABLE:
                why = _static_reason(field)
                if why is None:
                    raise SweepError(f"--sweep {field!r} is not a config field; allowed: {allowed}")
                raise SweepError(f"--sweep {field} cannot be swept: {why}; allowed: {allowed}")
            if field in seen:
                raise SweepError(f"--sweep {field} is given twice; give its values once")
            try:
                values = tuple(float(v) for v in raw.split(","))
            except ValueError:
                raise SweepError(f"--sweep {spec!r} has a value that is not a number; allowed: "
                                 "FIELD=V1,V2,... with numbers") from None  # fmt: skip
            if len(set(values)) != len(values):
                raise SweepError(f"--sweep {spec!r} repeats a value; give each once")
            seen.add(field)
            axes.append((field, values))
        return cls(seeds, tuple(axes))

    def points(self) -> list[dict[str, float]]:
        """Each point of the grid: {field: value}, the first axis slowest."""
        fields = [f for f, _ in self.axes]
        return [dict(zip(fields, vs, strict=True))
                for vs in itertools.product(*(v for _, v in self.axes))]  # fmt: skip

    def runs(self) -> list[tuple[dict[str, float], int]]:
        """(point, seed index) of every run, seeds innermost: the order of the R axis."""
        return [(p, s) for p in self.points()
                for s in range(self.first_seed, self.first_seed + self.seeds)]  # fmt: skip

    def names(self) -> list[str]:
        """Each run's name, e.g. "beta=0_seed=1" (its folder under a sweep's run dir)."""
        return ["_".join([f"{f.rsplit('.', 1)[-1]}={v:g}" for f, v in p.items()] + [f"seed={s}"])
                for p, s in self.runs()]  # fmt: skip

    def configs(self, config: Config) -> list[Config]:
        """Each run's own config: `config` with the run's values and train.seed + its index.
        Each is checked as a config is (a value out of range raises, naming it), and each
        swept field must be one `config.agent.kind`'s learner reads."""
        kind = config.agent.kind
        for field, _ in self.axes:
            if field not in fields(kind):
                raise SweepError(f"--sweep {field} cannot be swept with agent.kind={kind}: that "
                                 f"learner does not read it; allowed for {kind}: "
                                 f"{', '.join(fields(kind))}")  # fmt: skip
        out = []
        for point, s in self.runs():
            agent = config.agent
            for field, value in point.items():
                try:
                    agent = _replace(agent, field.split("."), value)
                except ValueError as e:
                    raise SweepError(f"--sweep {field}={value:g}: {e}") from None
            train = dataclasses.replace(config.train, seed=config.train.seed + s)
            out.append(dataclasses.replace(config, agent=agent, train=train))
        return out

    def keys(self, config: Config) -> jax.Array:
        """[R] each run's key (see `split`)."""
        if not self.split:
            return jnp.stack([jax.random.PRNGKey(c.train.seed) for c in self.configs(config)])
        split = jax.random.split(jax.random.PRNGKey(config.train.seed), self.split)
        return split[jnp.asarray([s for _, s in self.runs()])]

    def init(self, train, config: Config):
        """() -> the [R, ...] state of every run: `train.init` on each run's key, with each
        run's values written into `state.agent.hyper`. `train` is built from `config`."""
        configs = self.configs(config)
        keys = self.keys(config)
        hyper = jax.tree.map(lambda *xs: jnp.stack(xs), *[init_hyper(c.agent) for c in configs])

        def init():
            state = jax.vmap(train.init)(keys)
            return state.replace(agent=state.agent.replace(hyper=hyper))

        return init

    def __len__(self) -> int:
        return len(self.runs())
