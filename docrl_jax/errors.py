"""The package's configuration error, in a module of its own so that every layer (config loading,
device placement) can raise it without importing the others."""


class ConfigError(ValueError):
    """An invalid configuration; the message names the key, the value and the valid choices."""
