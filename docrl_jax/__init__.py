"""docrl_jax: DoCRL (double-critic deep RL for a hybrid aerial-underwater vehicle) in JAX and MJX."""

import os
import sys


def _headless_gl() -> None:
    """Chooses a headless OpenGL backend for MuJoCo's renderer on a Linux machine with no display.

    MuJoCo reads MUJOCO_GL once, when `mujoco` is first imported (docrl_jax.envs imports it, so this
    must run first, here); unset, it takes GLFW, which needs a display, and every render then fails.
    So, only when there is no display and neither MUJOCO_GL nor PYOPENGL_PLATFORM is set, this sets
    MUJOCO_GL to egl, or osmesa, whichever library loads (a few milliseconds). Neither loading, it
    stays unset: MUJOCO_GL=egl without libEGL would make `import mujoco` itself fail, not only the
    renderer. A value the user set is never changed (docrl_jax/envs/rendering.py explains a failure)."""
    if (not sys.platform.startswith("linux") or "MUJOCO_GL" in os.environ or "PYOPENGL_PLATFORM" in os.environ
            or os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        return
    import ctypes
    for backend, libraries in (("egl", ("libEGL.so.1", "libEGL.so")), ("osmesa", ("libOSMesa.so.8", "libOSMesa.so"))):
        for library in libraries:
            try:
                ctypes.CDLL(library)
            except OSError:
                continue
            os.environ.setdefault("MUJOCO_GL", backend)
            return


_headless_gl()

from docrl_jax import moved  # noqa: E402  (after the GL choice: nothing above imports mujoco)

moved.install()  # importing a module by its old name says where it lives now

__version__ = "0.1.0"
