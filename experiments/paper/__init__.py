"""The TDMPBC paper's experiments as commands (see experiments/paper/README.md)."""
