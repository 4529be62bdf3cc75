"""The package's error types, in a module of their own so that every layer (config loading, device
placement, run directories) can raise them without importing the others; and the two one-line
forms every command prints errors in (no page of traceback or TensorStore spec)."""


class ConfigError(ValueError):
    """An invalid configuration; the message names the key, the value and the valid choices."""


class RunDirError(ValueError):
    """A run directory is missing, incomplete or incompatible; the message says which and why."""


class ExportError(ValueError):
    """A policy export cannot be written as asked (an --out that holds one, an artefact that fails its
    check); the message says which and what to do."""


class RenderError(RuntimeError):
    """MuJoCo's renderer cannot run here (no OpenGL backend could be loaded); `no_gl` words it."""

    @classmethod
    def no_gl(cls, reason: str) -> "RenderError":
        """The error of a renderer that could not start: why, MUJOCO_GL and its valid values."""
        import os
        return cls(f"MuJoCo's renderer could not create an OpenGL context (MUJOCO_GL="
                   f"{os.environ.get('MUJOCO_GL') or 'unset'}: {reason}); set MUJOCO_GL, before Python starts, "
                   f"to one of {', '.join(GL_BACKENDS)} (egl: headless, a GPU driver or Mesa; osmesa: software, "
                   f"libOSMesa; glfw: a display) and install that library")


# The values of MUJOCO_GL a user chooses between (MuJoCo also takes glx, and 'disable').
GL_BACKENDS = ("egl", "osmesa", "glfw")


def short_reason(e: BaseException, limit: int = 200) -> str:
    """The first line of an exception, shortened: Orbax and TensorStore errors carry pages of spec."""
    text = (str(e).strip().splitlines() or [""])[0]
    text = text if len(text) <= limit else text[:limit] + " ..."
    return f"{type(e).__name__}: {text}" if text else type(e).__name__


def not_the_data(e: BaseException, what: str) -> RunDirError | None:
    """A RunDirError for a failure to read `what` that says nothing about the data (the device ran out
    of memory: XLA's RESOURCE_EXHAUSTED), or None. Readers that take any other failure for damage
    (and would skip, or call corrupt, a checkpoint that is whole) raise this instead."""
    if isinstance(e, MemoryError) or "RESOURCE_EXHAUSTED" in str(e):
        return RunDirError(f"out of device memory while reading {what}; the checkpoint itself was not found at "
                           f"fault (is another process holding the GPU?): {short_reason(e)}")
    return None


def os_error_line(e: OSError) -> str:
    """One line for a file-system error: the path and the cause ('/x/metrics.csv: No space left on device')."""
    what = e.strerror or short_reason(e)
    return f"{e.filename}: {what}" if e.filename else what
