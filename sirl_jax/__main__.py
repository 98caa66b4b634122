"""`python -m sirl_jax ...`: see `sirl_jax.run.cli` and docs/cli.md."""

from sirl_jax.run.cli import run

run()
