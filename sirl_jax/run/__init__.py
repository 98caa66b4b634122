"""The shell around the pure core: CLI, run loop, checkpoints, run logs, progress.

The core (`agent/`, `envs/`, `buffer.py`, `buffer_state.py`, `train.py`, `evaluate.py`,
`config.py`, `presets.py`, `types.py`) never imports from here.
"""
