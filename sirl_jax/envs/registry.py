"""Task registry: ids, episode lengths, success bars, and lazily built environments.

Ids follow HumanoidBench (`h1hand-walk-v0`, `h1-walk-v0`); a spec may also list short aliases
(`walk`, `hurdle`) that the CLI accepts. Building an env is deferred to `make`, so importing the
registry compiles no model.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator, Mapping

from sirl_jax.envs.base import Env


@dataclasses.dataclass(frozen=True)
class TaskSpec:
    """A registered task.

    Attributes:
      id: the full id, e.g. `h1hand-walk-v0`.
      factory: builds the `Env` (called with the keyword arguments given to `make`).
      episode_length: time limit in control steps.
      success_bar: episode return counted as success (HumanoidBench's R_target), or None.
      aliases: short names that resolve to this id (e.g. `walk`).
      description: one line for `--help` and the docs.
      takes_hb_compat: the factory takes `hb_compat` and `contact_set` (HumanoidBench's tasks;
        `load` passes them).
    """

    id: str
    factory: Callable[..., Env]
    episode_length: int
    success_bar: float | None = None
    aliases: tuple[str, ...] = ()
    description: str = ""
    takes_hb_compat: bool = False


class _Registry(Mapping[str, TaskSpec]):
    def __init__(self) -> None:
        self._specs: dict[str, TaskSpec] = {}
        self._aliases: dict[str, str] = {}

    def register(self, spec: TaskSpec) -> TaskSpec:
        names = (spec.id, *spec.aliases)
        for name in names:
            if name in self._specs or name in self._aliases:
                raise ValueError(f"task name {name!r} is already registered")
        if len(set(names)) != len(names):
            raise ValueError(f"task {spec.id!r} lists a duplicate alias: {spec.aliases}")
        self._specs[spec.id] = spec
        for alias in spec.aliases:
            self._aliases[alias] = spec.id
        return spec

    def resolve(self, name: str) -> TaskSpec:
        """The spec for a full id or an alias; a clear error lists the valid names."""
        key = self._aliases.get(name, name)
        if key not in self._specs:
            valid = ", ".join(sorted(self._specs) + sorted(self._aliases))
            raise KeyError(f"unknown task {name!r}; valid tasks: {valid}")
        return self._specs[key]

    def __getitem__(self, name: str) -> TaskSpec:
        return self.resolve(name)

    def __contains__(self, name: object) -> bool:
        return name in self._specs or name in self._aliases

    def __iter__(self) -> Iterator[str]:
        return iter(self._specs)

    def __len__(self) -> int:
        return len(self._specs)

    def aliases(self) -> dict[str, str]:
        return dict(self._aliases)


TASKS = _Registry()
"""All registered tasks, keyed by full id; aliases resolve through `TASKS[alias]`."""


def register(spec: TaskSpec) -> TaskSpec:
    """Adds a task; raises ValueError if its id or an alias is taken."""
    return TASKS.register(spec)


def make(name: str, **kwargs) -> Env:
    """Builds the environment of a registered task (by id or alias)."""
    return TASKS.resolve(name).factory(**kwargs)
