"""The lean forward renderer installed in place of pyrender's: FLAT pass, MSAA framebuffer, RGBA readback."""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from .rendering_errors import INSTALL_HINT, RenderingUnavailableError

__all__ = ["make_fast_renderer"]


def _upload_mipmaps(tex: Any) -> None:
    """Replace the box-filtered mipmap levels of a freshly uploaded texture by its ``offtrack_mipmaps``.

    The levels are in the row order of the texture's source; pyrender flips rows on upload, so they
    are flipped the same way here.
    """
    levels = getattr(tex, "offtrack_mipmaps", None)
    if not levels or tex._texid is None:
        return
    from OpenGL import GL

    fmt = GL.GL_RGBA if levels[0].shape[2] == 4 else GL.GL_RGB
    GL.glBindTexture(tex.tex_type, tex._texid)
    GL.glPixelStorei(GL.GL_UNPACK_ALIGNMENT, 1)
    for k, level in enumerate(levels, start=1):
        data = np.ascontiguousarray(level[::-1])
        GL.glTexSubImage2D(tex.tex_type, k, 0, 0, level.shape[1], level.shape[0], fmt, GL.GL_UNSIGNED_BYTE, data)
    GL.glBindTexture(tex.tex_type, 0)


def make_fast_renderer(pyrender: Any, osr: Any, samples: int) -> Any:
    """Swap the offscreen renderer's pyrender ``Renderer`` for one that reads back only what is needed.

    Parameters
    ----------
    pyrender : module
        The imported ``pyrender`` package (see :func:`sensor.gl_context.import_pyrender`).
    osr : pyrender.OffscreenRenderer
        The offscreen renderer whose context is current; its ``Renderer`` is replaced in place.
    samples : int
        Multisampling of the framebuffer (1: off).

    Returns
    -------
    FastRenderer
        The installed ``pyrender.renderer.Renderer`` subclass instance. It draws scenes that carry
        ``offtrack_draw_order`` with a lean FLAT forward pass (one texture per primitive, uniform
        locations cached, GL state changed only when it differs), reads the colour buffer as RGBA
        into a reused array and depth only when ``want_depth`` is set, and records the draw and
        readback times in ``timings``. Settable attributes: ``samples``, ``want_depth``,
        ``anisotropy``, ``lod_bias``.
    """
    from OpenGL import GL

    class FastRenderer(pyrender.renderer.Renderer):
        """pyrender's renderer with a configurable MSAA framebuffer, RGBA readback into a reused
        buffer, depth only on request, and anisotropic texture filtering."""

        want_depth = False
        samples = 4
        anisotropy = 1.0
        lod_bias = 0.0

        def __init__(self, width: int, height: int) -> None:
            super().__init__(width, height)
            self._rgba: np.ndarray | None = None
            self._fb_key: tuple[int, int, int] | None = None
            self._tex_key: tuple[float, float] | None = None
            self._uniform_locations: dict[int, dict[str, int]] = {}
            self._programs: dict[tuple[int, int], tuple[Any, Any]] = {}  # (id(primitive), flags) → (it, program)
            self._synced: Any = None  # the scene sync() brought the context up to date with
            self._max_aniso = 0.0
            try:
                self._max_aniso = float(GL.glGetFloatv(GL.GL_MAX_TEXTURE_MAX_ANISOTROPY))
            except Exception:
                self._max_aniso = 0.0
            self.timings: dict[str, float] = {}

        def sync(self, scene, flags):
            """Bring the context up to date with ``scene`` now (upload new meshes and textures), so that the
            next :meth:`render` of it need not do it again."""
            self._synced = None
            self._update_context(scene, flags)
            self._synced = scene

        def _update_context(self, scene, flags):
            if self._synced is scene:  # sync() just did it, for this render
                self._synced = None
                return
            self._synced = None
            before = set(self._mesh_textures)
            super()._update_context(scene, flags)
            key = (self.anisotropy, self.lod_bias)
            fresh = self._mesh_textures if key != self._tex_key else self._mesh_textures - before
            for tex in fresh:  # sampling parameters of newly uploaded textures, or of all when changed
                if tex._texid is None:
                    continue
                GL.glBindTexture(tex.tex_type, tex._texid)
                if self._max_aniso > 1.0:
                    aniso = min(max(self.anisotropy, 1.0), self._max_aniso)
                    GL.glTexParameterf(tex.tex_type, GL.GL_TEXTURE_MAX_ANISOTROPY, aniso)
                GL.glTexParameterf(tex.tex_type, GL.GL_TEXTURE_LOD_BIAS, self.lod_bias)
                GL.glBindTexture(tex.tex_type, 0)
            self._tex_key = key
            for tex in self._mesh_textures - before:
                _upload_mipmaps(tex)

        def _forward_pass(self, scene, flags, seg_node_map=None):
            """A lean forward pass for offtrack's scenes: FLAT shading, one texture per primitive,
            identity node poses; programs (per primitive) and uniform locations cached, state (texture, colour
            factor, blending) changed only when it differs; opaque surfaces drawn with blending off."""
            order = getattr(scene, "offtrack_draw_order", None)
            if order is None or not flags & pyrender.RenderFlags.FLAT or flags & pyrender.RenderFlags.SEG:
                return super()._forward_pass(scene, flags, seg_node_map)
            self._configure_forward_pass_viewport(flags)
            GL.glClearColor(*scene.bg_color)
            GL.glClear(GL.GL_COLOR_BUFFER_BIT | GL.GL_DEPTH_BUFFER_BIT)
            (GL.glEnable if self.samples > 1 else GL.glDisable)(GL.GL_MULTISAMPLE)
            v, p = self._get_camera_matrices(scene)
            v32, p32 = np.ascontiguousarray(v, np.float32), np.ascontiguousarray(p, np.float32)
            GL.glEnable(GL.GL_CULL_FACE)
            GL.glCullFace(GL.GL_BACK)
            GL.glPolygonMode(GL.GL_FRONT_AND_BACK, GL.GL_FILL)
            GL.glDisable(GL.GL_PROGRAM_POINT_SIZE)
            GL.glActiveTexture(GL.GL_TEXTURE0)
            program = None
            blend = None
            last_pose = last_texture = last_factor = None
            for node in order:
                mesh = node.mesh
                if not mesh.is_visible:
                    continue
                pose = scene.get_pose(node)
                alpha_only = getattr(node, "offtrack_alpha_only", False)
                for prim in mesh.primitives:
                    prog = self._program(prim, flags)
                    if prog is not program:
                        program = prog
                        prog._bind()
                        locs = self._locations(prog)
                        GL.glUniformMatrix4fv(locs["V"], 1, GL.GL_TRUE, v32)
                        GL.glUniformMatrix4fv(locs["P"], 1, GL.GL_TRUE, p32)
                        GL.glUniform1i(locs["material.base_color_texture"], 0)
                        last_pose = last_factor = None
                    material = prim.material
                    if last_pose is None or not np.array_equal(pose, last_pose):
                        GL.glUniformMatrix4fv(locs["M"], 1, GL.GL_TRUE, np.ascontiguousarray(pose, np.float32))
                        last_pose = pose
                    factor = np.asarray(material.baseColorFactor, np.float32)
                    if last_factor is None or not np.array_equal(factor, last_factor):
                        GL.glUniform4fv(locs["material.base_color_factor"], 1, factor)
                        last_factor = factor
                    texture = material.baseColorTexture._texid
                    if texture != last_texture:
                        GL.glBindTexture(GL.GL_TEXTURE_2D, texture)
                        last_texture = texture
                    want = "alpha" if alpha_only else material.alphaMode == "BLEND"
                    if want != blend:
                        if blend == "alpha":
                            GL.glColorMask(GL.GL_TRUE, GL.GL_TRUE, GL.GL_TRUE, GL.GL_TRUE)
                            GL.glDepthMask(GL.GL_TRUE)
                        if want == "alpha":  # shadow decals: alpha only, no depth write (no double shade)
                            GL.glColorMask(GL.GL_FALSE, GL.GL_FALSE, GL.GL_FALSE, GL.GL_TRUE)
                            GL.glDepthMask(GL.GL_FALSE)
                            GL.glDisable(GL.GL_BLEND)  # replace: what blending with (ONE, ZERO) gives
                        elif want:  # road lines over the asphalt; the alpha (sky/shade mask) is kept
                            GL.glEnable(GL.GL_BLEND)
                            GL.glBlendFuncSeparate(GL.GL_SRC_ALPHA, GL.GL_ONE_MINUS_SRC_ALPHA, GL.GL_ZERO, GL.GL_ONE)
                        else:
                            GL.glDisable(GL.GL_BLEND)
                        blend = want
                    GL.glBindVertexArray(prim._vaid)
                    n = 1 if prim.poses is None else len(prim.poses)
                    GL.glDrawElementsInstanced(GL.GL_TRIANGLES, prim.indices.size, GL.GL_UNSIGNED_INT, None, n)
            GL.glBindVertexArray(0)
            GL.glUseProgram(0)
            if blend == "alpha":
                GL.glColorMask(GL.GL_TRUE, GL.GL_TRUE, GL.GL_TRUE, GL.GL_TRUE)
                GL.glDepthMask(GL.GL_TRUE)
            GL.glFlush()
            return self._read_main_framebuffer(scene, flags)

        def _program(self, prim, flags):
            """pyrender's shader program of a primitive, looked up once per primitive and flags."""
            key = (id(prim), int(flags))
            entry = self._programs.get(key)
            if entry is None or entry[0] is not prim:
                use = pyrender.constants.ProgramFlags.USE_MATERIAL
                entry = self._programs[key] = (prim, self._get_primitive_program(prim, flags, use))
            return entry[1]

        def delete(self):
            self._programs.clear()  # pyrender frees its programs
            self._uniform_locations.clear()
            super().delete()

        def _locations(self, program):
            pid = program._program_id
            locs = self._uniform_locations.get(pid)
            if locs is None:
                names = ("V", "P", "M", "material.base_color_texture", "material.base_color_factor")
                locs = {name: GL.glGetUniformLocation(pid, name) for name in names}
                self._uniform_locations[pid] = locs
            return locs

        def _sorted_mesh_nodes(self, scene):
            order = getattr(scene, "offtrack_draw_order", None)
            return order if order is not None else super()._sorted_mesh_nodes(scene)

        def _configure_main_framebuffer(self):
            w, h = self.viewport_width, self.viewport_height
            key = (w, h, self.samples)
            if self._fb_key == key:
                return
            self._delete_main_framebuffer()
            self._main_cb, self._main_db = GL.glGenRenderbuffers(2)
            GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, self._main_cb)
            GL.glRenderbufferStorage(GL.GL_RENDERBUFFER, GL.GL_RGBA8, w, h)
            GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, self._main_db)
            GL.glRenderbufferStorage(GL.GL_RENDERBUFFER, GL.GL_DEPTH_COMPONENT24, w, h)
            self._main_fb = GL.glGenFramebuffers(1)
            GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, self._main_fb)
            GL.glFramebufferRenderbuffer(
                GL.GL_DRAW_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0, GL.GL_RENDERBUFFER, self._main_cb
            )
            GL.glFramebufferRenderbuffer(
                GL.GL_DRAW_FRAMEBUFFER, GL.GL_DEPTH_ATTACHMENT, GL.GL_RENDERBUFFER, self._main_db
            )
            if self.samples > 1:
                self._main_cb_ms, self._main_db_ms = GL.glGenRenderbuffers(2)
                GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, self._main_cb_ms)
                GL.glRenderbufferStorageMultisample(GL.GL_RENDERBUFFER, self.samples, GL.GL_RGBA8, w, h)
                GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, self._main_db_ms)
                GL.glRenderbufferStorageMultisample(GL.GL_RENDERBUFFER, self.samples, GL.GL_DEPTH_COMPONENT24, w, h)
                self._main_fb_ms = GL.glGenFramebuffers(1)
                GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, self._main_fb_ms)
                GL.glFramebufferRenderbuffer(
                    GL.GL_DRAW_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0, GL.GL_RENDERBUFFER, self._main_cb_ms
                )
                GL.glFramebufferRenderbuffer(
                    GL.GL_DRAW_FRAMEBUFFER, GL.GL_DEPTH_ATTACHMENT, GL.GL_RENDERBUFFER, self._main_db_ms
                )
            else:
                self._main_fb_ms = self._main_fb
            status = GL.glCheckFramebufferStatus(GL.GL_DRAW_FRAMEBUFFER)
            if status != GL.GL_FRAMEBUFFER_COMPLETE:
                raise RenderingUnavailableError(
                    f"offscreen framebuffer incomplete (status {status:#x}). {INSTALL_HINT}"
                )
            self._main_fb_dims = (w, h)
            self._fb_key = key
            self._rgba = np.empty((h, w, 4), np.uint8)

        def _delete_main_framebuffer(self):
            fbs = {b for b in (self._main_fb, self._main_fb_ms) if b is not None}
            if fbs:
                GL.glDeleteFramebuffers(len(fbs), list(fbs))
            rbs = [b for b in (self._main_cb, self._main_db, self._main_cb_ms, self._main_db_ms) if b is not None]
            if rbs:
                GL.glDeleteRenderbuffers(len(rbs), rbs)
            self._main_fb = self._main_cb = self._main_db = None
            self._main_fb_ms = self._main_cb_ms = self._main_db_ms = None
            self._main_fb_dims = (None, None)
            self._fb_key = None

        def _read_main_framebuffer(self, scene, flags):
            t0 = time.perf_counter()
            GL.glFinish()  # the draw calls complete here (llvmpipe rasterises asynchronously)
            t1 = time.perf_counter()
            w, h = self._main_fb_dims
            if self._main_fb_ms != self._main_fb:  # resolve the multisampled buffer
                GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, self._main_fb_ms)
                GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, self._main_fb)
                mask = GL.GL_COLOR_BUFFER_BIT | (GL.GL_DEPTH_BUFFER_BIT if self.want_depth else 0)
                GL.glBlitFramebuffer(0, 0, w, h, 0, 0, w, h, mask, GL.GL_NEAREST)
            GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, self._main_fb)
            GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
            GL.glReadPixels(0, 0, w, h, GL.GL_RGBA, GL.GL_UNSIGNED_BYTE, self._rgba)
            depth = None
            if self.want_depth:
                raw = GL.glReadPixels(0, 0, w, h, GL.GL_DEPTH_COMPONENT, GL.GL_FLOAT)
                d = np.frombuffer(raw, dtype=np.float32).reshape(h, w)[::-1]
                cam = scene.main_camera_node.camera
                n, f = cam.znear, cam.zfar
                ndc = 2.0 * d.astype(np.float64) - 1.0
                lin = 2.0 * n * f / (f + n - ndc * (f - n))
                depth = np.where(d >= 1.0, 0.0, lin).astype(np.float32)
            t2 = time.perf_counter()
            self.timings = {"draw_s": t1 - t0, "readback_s": t2 - t1}
            return self._rgba, depth

    osr._platform.make_current()
    r = FastRenderer(osr.viewport_width, osr.viewport_height)
    r.samples = samples
    osr._renderer.delete()
    osr._renderer = r
    return r
