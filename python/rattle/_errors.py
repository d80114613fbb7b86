"""The exceptions rattle raises (the extension raises them by these names)."""


class ConfigError(ValueError):
    """A config key or an option outside its allowed range; the message names the key and
    the range, as the command line's error does."""


class TooLargeError(ConfigError, MemoryError):
    """A run too large for this machine's memory, refused before anything is allocated
    (a `ConfigError` and a `MemoryError`)."""


class RattleError(RuntimeError):
    """Any other failure of a computation (no adapter where one was named, a GPU failure,
    files that cannot be written)."""
