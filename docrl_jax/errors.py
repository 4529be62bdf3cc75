"""The package's error types, in a module of their own so that every layer (config loading, device
placement, run directories) can raise them without importing the others."""


class ConfigError(ValueError):
    """An invalid configuration; the message names the key, the value and the valid choices."""


class RunDirError(ValueError):
    """A run directory is missing, incomplete or incompatible; the message says which and why."""
