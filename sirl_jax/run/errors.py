"""The shell's two error kinds, by exit code (light: importing this loads no simulator)."""


class UsageError(Exception):
    """Bad input: printed as one `error:` line, exit code 2."""


class TrainingFailure(Exception):
    """The run stopped on a failure (non-finite values, out of memory): exit code 1."""
