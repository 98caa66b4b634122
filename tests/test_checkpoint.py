"""Checkpoints: round trip of a train-state-like pytree, atomicity, corruption, rotation."""

from __future__ import annotations

import os
import shutil

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from flax import struct

from sirl_jax.run.checkpoint import CHECKSUMS, Checkpointer, CheckpointError, CheckpointWriteError


@struct.dataclass
class _State:
    params: dict
    opt: tuple
    key: jax.Array
    env_steps: jax.Array
    updates: jax.Array
    buffer: dict | None


def _state(seed: int) -> _State:
    key = jax.random.PRNGKey(seed)
    k1, k2, k3 = jax.random.split(key, 3)
    return _State(
        params={"w": jax.random.normal(k1, (4, 3)), "b": jnp.arange(3, dtype=jnp.float32)},
        opt=(jnp.zeros((4, 3)), jnp.int32(seed)),
        key=k2,
        env_steps=jnp.int32(1000 + seed),
        updates=jnp.int32(7 * seed),
        buffer={"obs": jax.random.normal(k3, (2, 5, 3)), "ptr": jnp.int32(seed % 5)},
    )


def _assert_equal_trees(a, b) -> None:
    la, ta = jax.tree.flatten(a)
    lb, tb = jax.tree.flatten(b)
    assert ta == tb
    for x, y in zip(la, lb, strict=True):
        assert np.asarray(x).dtype == np.asarray(y).dtype
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))


def _save(ckpt: Checkpointer, state: _State, step: int, with_buffer: bool = True):
    items = {"state": state.replace(buffer=None)}
    if with_buffer:
        items["buffer"] = state.buffer
    return ckpt.save(step, items, meta={"env_steps": step})


def _targets(state: _State, with_buffer: bool = True) -> dict:
    abstract = jax.eval_shape(lambda: state)
    out = {"state": abstract.replace(buffer=None)}
    if with_buffer:
        out["buffer"] = abstract.buffer
    return out


@pytest.mark.timeout(60)
def test_round_trip_keeps_values_dtypes_keys_and_counters(tmp_path):
    state = _state(3)
    ckpt = Checkpointer(tmp_path / "ck")
    _save(ckpt, state, 10)
    restored = ckpt.restore(_targets(state))
    back = restored["state"].replace(buffer=restored["buffer"])
    _assert_equal_trees(back, state)
    assert back.key.dtype == jnp.uint32 and back.env_steps.dtype == jnp.int32
    assert restored["meta"] == {"env_steps": 10}
    # the restored PRNG key continues the same random stream
    np.testing.assert_array_equal(
        jax.random.normal(back.key, (3,)), jax.random.normal(state.key, (3,))
    )
    assert ckpt.item_names(10) == ["buffer", "state"]


@pytest.mark.timeout(60)
def test_state_without_buffer_and_latest_step(tmp_path):
    ckpt = Checkpointer(tmp_path / "ck")
    _save(ckpt, _state(1), 5, with_buffer=False)
    _save(ckpt, _state(2), 9, with_buffer=False)
    assert ckpt.steps() == [5, 9] and ckpt.latest_step() == 9
    assert ckpt.item_names(9) == ["state"]
    restored = ckpt.restore(_targets(_state(0), with_buffer=False))
    _assert_equal_trees(restored["state"], _state(2).replace(buffer=None))
    older = ckpt.restore(_targets(_state(0), with_buffer=False), step=5)
    _assert_equal_trees(older["state"], _state(1).replace(buffer=None))


@pytest.mark.timeout(60)
def test_rotation_keeps_last_n(tmp_path):
    ckpt = Checkpointer(tmp_path / "ck", max_to_keep=2)
    for step in (1, 2, 3):
        _save(ckpt, _state(step), step)
    assert ckpt.steps() == [2, 3]
    assert sorted(os.listdir(tmp_path / "ck")) == ["2", "3"]
    with pytest.raises(CheckpointError, match="already exists"):
        _save(ckpt, _state(3), 3)


@pytest.mark.timeout(60)
def test_crash_mid_save_leaves_previous_checkpoint_readable(tmp_path, monkeypatch):
    ckpt = Checkpointer(tmp_path / "ck")
    _save(ckpt, _state(1), 1)

    # The process dies after writing the data but before the atomic rename.
    def crash(*args, **kwargs):
        raise OSError("simulated crash before rename")

    with monkeypatch.context() as m:
        m.setattr(os, "rename", crash)
        m.setattr(os, "replace", crash)
        with pytest.raises(CheckpointWriteError, match="simulated crash before rename; the "
                           "newest intact checkpoint is 1"):  # fmt: skip
            _save(ckpt, _state(2), 2)
    # the failed save removed its own temporary directory (a SIGKILL leaves it: test_faults)
    assert os.listdir(tmp_path / "ck") == ["1"]

    reopened = Checkpointer(tmp_path / "ck")
    assert reopened.steps() == [1]
    restored = reopened.restore(_targets(_state(0)))
    _assert_equal_trees(restored["state"], _state(1).replace(buffer=None))
    # the same step can be written again afterwards
    _save(reopened, _state(2), 2)
    assert reopened.steps() == [1, 2]


@pytest.mark.timeout(60)
def test_damaged_file_is_named_and_nothing_deleted(tmp_path):
    ckpt = Checkpointer(tmp_path / "ck")
    _save(ckpt, _state(1), 1)
    _save(ckpt, _state(2), 2)
    data_files = sorted((tmp_path / "ck" / "2" / "buffer").rglob("*"))
    victim = max((p for p in data_files if p.is_file()), key=lambda p: p.stat().st_size)
    raw = bytearray(victim.read_bytes())
    raw[len(raw) // 2] ^= 0xFF
    victim.write_bytes(bytes(raw))
    before = sorted(str(p) for p in (tmp_path / "ck").rglob("*"))
    with pytest.raises(CheckpointError, match=str(victim.relative_to(tmp_path / "ck" / "2"))):
        ckpt.restore(_targets(_state(0)))
    assert sorted(str(p) for p in (tmp_path / "ck").rglob("*")) == before
    # the older checkpoint is intact
    restored = ckpt.restore(_targets(_state(0)), step=1)
    _assert_equal_trees(restored["buffer"], _state(1).buffer)


@pytest.mark.timeout(60)
def test_unreadable_checkpoint_without_checksums_gives_clear_error(tmp_path):
    ckpt = Checkpointer(tmp_path / "ck")
    step_dir = _save(ckpt, _state(1), 1)
    (step_dir / CHECKSUMS).unlink()
    (step_dir / "state" / "_METADATA").write_text("not json")
    with pytest.raises(CheckpointError, match=f"checkpoint {step_dir} is unreadable"):
        ckpt.restore(_targets(_state(0)))
    shutil.rmtree(step_dir / "buffer")
    with pytest.raises(CheckpointError, match="unreadable"):
        ckpt.restore(_targets(_state(0)))


@pytest.mark.timeout(60)
def test_shape_mismatch_and_missing_checkpoint(tmp_path):
    ckpt = Checkpointer(tmp_path / "ck")
    with pytest.raises(CheckpointError, match="no checkpoint"):
        ckpt.restore(_targets(_state(0)))
    _save(ckpt, _state(1), 1)
    wrong = _state(0).replace(params={"w": jnp.zeros((5, 3)), "b": jnp.zeros(3)})
    with pytest.raises(CheckpointError, match="unreadable"):
        ckpt.restore(_targets(wrong))


@pytest.mark.timeout(60)
def test_other_structure_is_refused_by_name(tmp_path):
    ckpt = Checkpointer(tmp_path / "ck")
    _save(ckpt, _state(1), 1)
    other = _state(0).replace(params={"w": jnp.zeros((4, 3)), "bias": jnp.zeros(3)})
    with pytest.raises(CheckpointError, match="params_b.*params_bias|does not match"):
        ckpt.restore(_targets(other))


@pytest.mark.timeout(60)
def test_a_field_removed_since_the_save_is_named(tmp_path):
    """An older run's checkpoint with a field this version dropped (as `TrainState.episodes`
    was): the error names the field instead of a leaf-by-leaf mismatch."""
    ckpt = Checkpointer(tmp_path / "ck")
    old = {"agent": {"w": jnp.zeros(3)}, "episodes": jnp.zeros((), jnp.int32), "x": jnp.ones(2)}
    ckpt.save(1, {"state": old})
    new = {"agent": {"w": jnp.zeros(3)}, "x": jnp.ones(2)}
    with pytest.raises(CheckpointError, match="it has episodes, which this version no longer"):
        ckpt.restore({"state": jax.eval_shape(lambda: new)})


@pytest.mark.timeout(60)
def test_zero_size_leaves_round_trip(tmp_path):
    # MJX data carries zero-size arrays (e.g. `act` of a model without actuator state)
    tree = {"act": jnp.zeros((2, 0)), "qpos": jnp.arange(4.0)}
    ckpt = Checkpointer(tmp_path / "ck")
    ckpt.save(3, {"state": tree})
    back = ckpt.restore({"state": jax.eval_shape(lambda: tree)})["state"]
    assert back["act"].shape == (2, 0)
    np.testing.assert_array_equal(back["qpos"], np.arange(4.0))


@pytest.mark.timeout(60)
def test_rotation_keeps_the_best_past_max_to_keep(tmp_path):
    ckpt = Checkpointer(tmp_path / "ck", max_to_keep=2)
    assert ckpt.best() is None
    with pytest.raises(CheckpointError, match="cannot mark env step 1 best: no checkpoint"):
        ckpt.mark_best(1, 5.0, "eval/policy_return")
    _save(ckpt, _state(1), 1)
    ckpt.mark_best(1, 5.0, "eval/policy_return")
    for step in (2, 3, 4):
        _save(ckpt, _state(step), step)
    assert ckpt.steps() == [1, 3, 4]  # the newest two and the best
    assert ckpt.best() == {"step": 1, "value": 5.0, "metric": "eval/policy_return"}
    ckpt.mark_best(3, 9.0, "eval/policy_return")  # the old best is rotated out at once
    assert ckpt.steps() == [3, 4]
    _save(ckpt, _state(5), 5)
    assert ckpt.steps() == [3, 4, 5]
    _save(ckpt, _state(6), 6)
    assert ckpt.steps() == [3, 5, 6]
    # A reader sees the same record; a best set aside as damaged is no longer named.
    assert Checkpointer(tmp_path / "ck").best()["step"] == 3
    ckpt.set_aside(3)
    assert ckpt.best() is None
    # None keeps every checkpoint.
    every = Checkpointer(tmp_path / "all", max_to_keep=None)
    for step in (1, 2, 3, 4):
        _save(every, _state(step), step)
    assert every.steps() == [1, 2, 3, 4]
    with pytest.raises(ValueError, match="max_to_keep=0 is invalid; allowed: an int >= 1"):
        Checkpointer(tmp_path / "bad", max_to_keep=0)
