"""experiments/studies/planner_probe: planner sizes parse, and bad ones are named."""

import pytest

from experiments.studies.planner_probe import parse_size


def test_reference_size_parses():
    assert parse_size("512x6:64:24") == dict(num_samples=512, iterations=6, num_elites=64,
                                             num_pi_trajs=24)  # fmt: skip


@pytest.mark.parametrize("bad", ["512x6", "512:64:24", "ax6:64:24", "64x2:128:8", "64x2:8:64"])
def test_bad_sizes_are_named(bad):
    with pytest.raises(SystemExit, match=bad):
        parse_size(bad)
