"""The task registry: duplicates refused, aliases resolve, unknown names list the valid ones."""

import pytest

from sirl_jax.envs.registry import TaskSpec, _Registry


def _spec(task_id, aliases=()):
    return TaskSpec(id=task_id, factory=lambda: None, episode_length=10, aliases=aliases)


def test_register_and_resolve_alias():
    reg = _Registry()
    reg.register(_spec("h1hand-walk-v0", aliases=("walk",)))
    assert reg.resolve("walk").id == "h1hand-walk-v0"
    assert reg["h1hand-walk-v0"].episode_length == 10
    assert "walk" in reg and "h1hand-walk-v0" in reg and "run" not in reg
    assert list(reg) == ["h1hand-walk-v0"]


@pytest.mark.parametrize("second", [_spec("h1hand-walk-v0"), _spec("other", aliases=("walk",))])
def test_duplicate_names_are_refused(second):
    reg = _Registry()
    reg.register(_spec("h1hand-walk-v0", aliases=("walk",)))
    with pytest.raises(ValueError, match="already registered"):
        reg.register(second)


def test_unknown_task_lists_valid_names():
    reg = _Registry()
    reg.register(_spec("h1hand-walk-v0", aliases=("walk",)))
    with pytest.raises(KeyError, match=r"unknown task 'hurdel'.*h1hand-walk-v0.*walk"):
        reg.resolve("hurdel")
