"""The process's one offscreen OpenGL context (pyrender on EGL), created lazily and never used across a fork."""

from __future__ import annotations

import atexit
import os
from typing import Any

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")  # before anything imports OpenGL

from .fast_renderer import make_fast_renderer
from .rendering_errors import INSTALL_HINT, RenderingUnavailableError

__all__ = ["GLContext", "import_pyrender"]


def import_pyrender() -> Any:
    """Import pyrender, translating any failure into :class:`RenderingUnavailableError`.

    Returns
    -------
    module
        The ``pyrender`` package (on the platform of ``PYOPENGL_PLATFORM``, EGL by default).

    Raises
    ------
    RenderingUnavailableError
        If pyrender or OpenGL cannot be imported; the message names the fix (:data:`INSTALL_HINT`).
    """
    try:
        import pyrender

        return pyrender
    except Exception as exc:  # ImportError, OpenGL platform errors, missing libEGL, …
        raise RenderingUnavailableError(
            f"cannot import pyrender/OpenGL (PYOPENGL_PLATFORM={os.environ.get('PYOPENGL_PLATFORM')!r}): "
            f"{type(exc).__name__}: {exc}. {INSTALL_HINT}"
        ) from exc


class GLContext:
    """The process's one offscreen OpenGL context (pyrender ``OffscreenRenderer`` on EGL).

    Use :meth:`get`, not the constructor. Attributes: ``pid`` (the creating process), ``osr`` (the
    ``OffscreenRenderer``), ``renderer`` (its :func:`~sensor.fast_renderer.make_fast_renderer`
    renderer), ``gl_version`` and ``gl_renderer`` (driver strings) and ``scene`` (the pyrender scene
    whose meshes are in the context, or None).
    """

    _instance: GLContext | None = None

    def __init__(self, width: int, height: int, samples: int) -> None:
        pyrender = import_pyrender()
        self.pid = os.getpid()
        platform = os.environ.get("PYOPENGL_PLATFORM", "")
        try:
            self.osr = pyrender.OffscreenRenderer(width, height)
            self.renderer = make_fast_renderer(pyrender, self.osr, samples)
            self.osr._platform.make_current()
            from OpenGL import GL

            self.gl_version = GL.glGetString(GL.GL_VERSION).decode()
            self.gl_renderer = GL.glGetString(GL.GL_RENDERER).decode()
        except Exception as exc:
            raise RenderingUnavailableError(
                f"cannot create an offscreen OpenGL context with PYOPENGL_PLATFORM={platform!r}: "
                f"{type(exc).__name__}: {exc}. {INSTALL_HINT}"
            ) from exc
        self.scene: Any = None  # the scene whose meshes are in the context

    @classmethod
    def get(cls, width: int, height: int, samples: int) -> GLContext:
        """The process's context, made current with this viewport and multisampling.

        Parameters
        ----------
        width, height : int
            Viewport [px].
        samples : int
            Multisampling (1: off).

        Returns
        -------
        GLContext
            The one context of the process, created on the first call (and freed at exit).

        Raises
        ------
        RenderingUnavailableError
            If OpenGL cannot be used here, or the context was created in another process (a fork).
        """
        ctx = cls._instance
        if ctx is None:
            ctx = cls._instance = cls(width, height, samples)
            atexit.register(_shutdown)
        elif ctx.pid != os.getpid():
            raise RenderingUnavailableError(
                f"the OpenGL context was created in process {ctx.pid} and cannot be used in process "
                f"{os.getpid()} (a fork): a GL context must never cross a fork. Create renderers after "
                "forking, or start workers with the 'spawn' method (multiprocessing.get_context('spawn'))."
            )
        ctx.osr._platform.make_current()
        r = ctx.renderer
        r.viewport_width, r.viewport_height = width, height
        r.samples = samples
        return ctx


def _shutdown() -> None:
    """Free the context at exit, before PyOpenGL's modules are torn down."""
    ctx = GLContext._instance
    if ctx is not None and ctx.pid == os.getpid():
        try:
            ctx.osr.delete()
        except Exception:
            pass
        GLContext._instance = None
