"""Why the camera images cannot be rendered here: :class:`RenderingUnavailableError` and the install hint."""

from __future__ import annotations

from vehicle_model.errors import OfftrackError

__all__ = ["INSTALL_HINT", "RenderingUnavailableError"]

INSTALL_HINT = (
    "Headless rendering needs OpenGL through EGL (Mesa's llvmpipe works without a GPU). Install the "
    "system libraries with `sudo apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri` and select the "
    "platform with the environment variable `PYOPENGL_PLATFORM=egl` (set before Python imports OpenGL; "
    "offtrack sets it by default)."
)


class RenderingUnavailableError(OfftrackError, RuntimeError):
    """The camera images cannot be rendered here: no usable OpenGL, or a context from another process."""
