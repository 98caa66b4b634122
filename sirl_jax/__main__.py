"""`python -m sirl_jax ...`: see `sirl_jax.cli` and docs/cli.md."""

from sirl_jax.cli import run

run()
