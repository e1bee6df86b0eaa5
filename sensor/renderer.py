"""Offscreen rendering of the stereo pair with pyrender through EGL (Mesa llvmpipe needs no GPU).

Rules of the road (DESIGN §6):

* **One OpenGL context per process**, created lazily on the first render and shared by every
  :class:`StereoRenderer` of the process (renderers of other worlds or image sizes switch the
  scene and the viewport of the same context).
* **Never pickled**: a :class:`StereoRenderer` pickles its world and rig only; the scene is rebuilt
  from them when the unpickled copy first renders (in whatever process that is).
* **Never across a fork**: the context remembers the process that created it; a forked child that
  tries to render gets :class:`RenderingUnavailableError` instead of a corrupted context. Create
  renderers after forking, or use the ``spawn`` start method.

Speed (llvmpipe renders on the CPU; measured on 2 cores at 1344 × 391, ``roundabout-3`` world,
~58 k triangles: about 20–25 ms per stereo pair on an idle machine, see
:func:`scenarios.rendering.bench_render`):

* surfaces are drawn unlit (``RenderFlags.FLAT``: texture × baked vertex colour) by a lean forward
  pass (one shader program, cached uniform locations, state changed only when it differs) in a
  fixed order — objects, road, ground — so hidden ground fails the depth test early and the same
  world always gives the same image;
* static geometry is merged per texture and widely repeated objects are instanced; instances
  outside the view frustum are not drawn (:class:`_InstanceCuller`);
* the colour buffer is read as RGBA into a preallocated array, depth only on request, and OpenCV
  converts to grey.

Most of the time is llvmpipe's rasterisation (fill rate: ~525 k pixels per view with trilinear
texture sampling); the rest is per-view CPU work in Python, PyOpenGL and llvmpipe's vertex stage.
4× multisampling (``antialias=True``) smooths object silhouettes but costs about 2.5× the time; road
lines are antialiased without it (soft-edged textures). Anisotropic filtering is very slow on
llvmpipe and off by default; a LOD bias of −0.5 keeps the road texture sharper at grazing angles.
"""

from __future__ import annotations

import atexit
import dataclasses
import os
import time
import weakref
from dataclasses import dataclass
from typing import Any

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import cv2
import numpy as np

from vehicle_model.errors import InputError, OfftrackError
from vehicle_model.parameters import VehicleParams

from .camera import StereoRig, opencv_to_opengl
from .world import World

INSTALL_HINT = (
    "Headless rendering needs OpenGL through EGL (Mesa's llvmpipe works without a GPU). Install the "
    "system libraries with `sudo apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri` and select the "
    "platform with the environment variable `PYOPENGL_PLATFORM=egl` (set before Python imports OpenGL; "
    "offtrack sets it by default)."
)


class RenderingUnavailableError(OfftrackError, RuntimeError):
    """The camera images cannot be rendered here: no usable OpenGL, or a context from another process."""


@dataclass(frozen=True)
class StereoPair:
    """One stereo frame.

    Attributes
    ----------
    left, right : numpy.ndarray
        ``(height, width)`` uint8 grey images.
    depth_left, depth_right : numpy.ndarray or None
        ``(height, width)`` float32 depth along each optical axis [m] (0 where nothing was hit,
        i.e. the sky); None unless requested.
    """

    left: np.ndarray
    right: np.ndarray
    depth_left: np.ndarray | None = None
    depth_right: np.ndarray | None = None


def _pyrender() -> Any:
    """Import pyrender, translating any failure into :class:`RenderingUnavailableError`."""
    try:
        import pyrender

        return pyrender
    except Exception as exc:  # ImportError, OpenGL platform errors, missing libEGL, …
        raise RenderingUnavailableError(
            f"cannot import pyrender/OpenGL (PYOPENGL_PLATFORM={os.environ.get('PYOPENGL_PLATFORM')!r}): "
            f"{type(exc).__name__}: {exc}. {INSTALL_HINT}"
        ) from exc


class _GLContext:
    """The process's one offscreen OpenGL context (pyrender ``OffscreenRenderer`` on EGL)."""

    _instance: _GLContext | None = None

    def __init__(self, width: int, height: int, samples: int) -> None:
        pyrender = _pyrender()
        self.pid = os.getpid()
        platform = os.environ.get("PYOPENGL_PLATFORM", "")
        try:
            self.osr = pyrender.OffscreenRenderer(width, height)
            self.renderer = _make_fast_renderer(pyrender, self.osr, samples)
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
    def get(cls, width: int, height: int, samples: int) -> _GLContext:
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
    ctx = _GLContext._instance
    if ctx is not None and ctx.pid == os.getpid():
        try:
            ctx.osr.delete()
        except Exception:
            pass
        _GLContext._instance = None


def _make_fast_renderer(pyrender: Any, osr: Any, samples: int) -> Any:
    """Swap the offscreen renderer's pyrender ``Renderer`` for one that reads back only what is needed."""
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
            self._max_aniso = 0.0
            try:
                self._max_aniso = float(GL.glGetFloatv(GL.GL_MAX_TEXTURE_MAX_ANISOTROPY))
            except Exception:
                self._max_aniso = 0.0
            self.timings: dict[str, float] = {}

        def _update_context(self, scene, flags):
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

        def _forward_pass(self, scene, flags, seg_node_map=None):
            """A lean forward pass for offtrack's scenes: FLAT shading, one texture per primitive,
            identity node poses; uniform locations cached, state changed only when it differs."""
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
            GL.glEnable(GL.GL_BLEND)
            GL.glActiveTexture(GL.GL_TEXTURE0)
            program = None
            blend = None
            last_pose = None
            for node in order:
                mesh = node.mesh
                if not mesh.is_visible:
                    continue
                pose = scene.get_pose(node)
                for prim in mesh.primitives:
                    prog = self._get_primitive_program(prim, flags, pyrender.constants.ProgramFlags.USE_MATERIAL)
                    if prog is not program:
                        program = prog
                        prog._bind()
                        locs = self._locations(prog)
                        GL.glUniformMatrix4fv(locs["V"], 1, GL.GL_TRUE, v32)
                        GL.glUniformMatrix4fv(locs["P"], 1, GL.GL_TRUE, p32)
                        GL.glUniform1i(locs["material.base_color_texture"], 0)
                        last_pose = None
                    material = prim.material
                    if last_pose is None or not np.array_equal(pose, last_pose):
                        GL.glUniformMatrix4fv(locs["M"], 1, GL.GL_TRUE, np.ascontiguousarray(pose, np.float32))
                        last_pose = pose
                    GL.glUniform4fv(
                        locs["material.base_color_factor"], 1, np.asarray(material.baseColorFactor, np.float32)
                    )
                    GL.glBindTexture(GL.GL_TEXTURE_2D, material.baseColorTexture._texid)
                    want = material.alphaMode == "BLEND"
                    if want != blend:
                        if want:
                            GL.glBlendFunc(GL.GL_SRC_ALPHA, GL.GL_ONE_MINUS_SRC_ALPHA)
                        else:
                            GL.glBlendFunc(GL.GL_ONE, GL.GL_ZERO)
                        blend = want
                    GL.glBindVertexArray(prim._vaid)
                    n = 1 if prim.poses is None else len(prim.poses)
                    GL.glDrawElementsInstanced(GL.GL_TRIANGLES, prim.indices.size, GL.GL_UNSIGNED_INT, None, n)
            GL.glBindVertexArray(0)
            GL.glUseProgram(0)
            GL.glFlush()
            return self._read_main_framebuffer(scene, flags)

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


BAKE_MAX_INSTANCES = 32
"""Instanced parts with at most this many copies are baked into static geometry (fewer draw calls)."""

_RANK = {"scenery": 0, "roundabout": 1, "road": 2, "ground": 3}


def _draw_groups(world: World) -> list[tuple[float, str, Any]]:
    """Group the world's parts into draw calls: ``(rank, texture, part)``, in draw order.

    Parts without instancing (and those with few copies, transformed to world coordinates) are
    merged per texture; widely instanced parts stay instanced. Order: objects, roundabout, road,
    blended road lines, ground — roughly near to far, so hidden ground fails the depth test early,
    and the lines blend onto the asphalt drawn before them.
    """
    static: dict[str, list] = {}
    ranks: dict[str, float] = {}
    out: list[tuple[float, str, Any]] = []
    for part in world.parts:
        rank = float(_RANK.get(part.category, 0))
        if world.textures[part.texture].shape[2] == 4:
            rank = 2.5
        if part.poses is not None and part.instances > BAKE_MAX_INSTANCES:
            out.append((rank, part.texture, part))
            continue
        poses = [np.eye(4)] if part.poses is None else list(part.poses)
        for pose in poses:
            pos = part.positions.astype(np.float64) @ pose[:3, :3].T + pose[:3, 3]
            static.setdefault(part.texture, []).append((pos, part.texcoords, part.colors, part.indices))
        ranks[part.texture] = min(ranks.get(part.texture, rank), rank)
    for texture, chunks in static.items():
        n, idx = 0, []
        for pos, _, _, ind in chunks:
            idx.append(ind.astype(np.int64) + n)
            n += len(pos)
        merged = dataclasses.replace(
            world.parts[0],
            name=f"static_{texture}",
            texture=texture,
            positions=np.vstack([c[0] for c in chunks]).astype(np.float32),
            texcoords=np.vstack([c[1] for c in chunks]).astype(np.float32),
            colors=np.vstack([c[2] for c in chunks]).astype(np.float32),
            indices=np.vstack(idx).astype(np.uint32),
            poses=None,
        )
        out.append((ranks[texture], texture, merged))
    out.sort(key=lambda g: g[0])  # stable: world order within a rank
    return out


def build_scene(world: World) -> tuple[Any, Any]:
    """The pyrender scene of a world and its camera node (intrinsics set per render).

    Parameters
    ----------
    world : World
        The procedural world.

    Returns
    -------
    scene, camera_node
        A ``pyrender.Scene`` (static geometry merged per texture, widely repeated objects
        instanced) and the node of its ``IntrinsicsCamera``. The scene carries its fixed draw
        order (``offtrack_draw_order``) and the per-view instance culler (``offtrack_culler``).
    """
    pyrender = _pyrender()
    sampler = pyrender.Sampler(wrapS=pyrender.GLTF.REPEAT, wrapT=pyrender.GLTF.REPEAT)
    materials = {}
    for name, img in world.textures.items():
        rgba = img.shape[2] == 4  # road lines: soft-edged, blended onto the asphalt
        tex = pyrender.Texture(source=img, source_channels="RGBA" if rgba else "RGB", sampler=sampler)
        materials[name] = pyrender.MetallicRoughnessMaterial(
            baseColorTexture=tex, metallicFactor=0.0, roughnessFactor=1.0, alphaMode="BLEND" if rgba else "OPAQUE"
        )
    scene = pyrender.Scene(bg_color=[*world.sky_rgb, 1.0], ambient_light=[1.0, 1.0, 1.0])
    nodes, instanced = [], []
    for _, texture, part in _draw_groups(world):
        prim = pyrender.Primitive(
            positions=part.positions,
            texcoord_0=part.texcoords,
            color_0=part.colors,
            indices=part.indices,
            material=materials[texture],
            poses=part.poses,
        )
        nodes.append(scene.add(pyrender.Mesh([prim], name=part.name)))
        if part.poses is not None:
            instanced.append((prim, part))
    scene.offtrack_draw_order = nodes
    camera = pyrender.IntrinsicsCamera(1.0, 1.0, 0.0, 0.0)
    camera_node = scene.add(camera, pose=np.eye(4))
    scene.offtrack_culler = _InstanceCuller(instanced)
    return scene, camera_node


class _InstanceCuller:
    """Draws only the instances whose bounding spheres meet the view frustum.

    pyrender draws every instance of an instanced primitive; llvmpipe shades their vertices on the
    CPU whether or not they are on screen. Before each view, the visible instances' poses are
    written to the front of the primitive's instance buffer and the primitive's pose array is cut
    to them (pyrender draws ``len(primitive.poses)`` instances). Relies on pyrender 1.0.x's layout
    of a primitive's buffers (vertex buffer, then the instance buffer); disables itself otherwise.
    """

    def __init__(self, items: list[tuple[Any, Any]]) -> None:
        self.items = []
        for prim, part in items:
            pos = part.positions.astype(np.float64)
            c0 = 0.5 * (pos.min(axis=0) + pos.max(axis=0))
            r0 = float(np.linalg.norm(pos - c0, axis=1).max())
            poses = np.asarray(part.poses, dtype=np.float64)
            centres = poses[:, :3, :3] @ c0 + poses[:, :3, 3]
            scale = np.linalg.norm(poses[:, :3, 0], axis=1)
            full = np.ascontiguousarray(np.transpose(poses, (0, 2, 1)).astype(np.float32))  # column-major rows
            self.items.append(
                {
                    "prim": prim,
                    "poses": prim.poses,
                    "gl": full,
                    "centres": centres,
                    "radius": r0 * scale,
                    "last": None,
                    "buffer": None,
                }
            )
        self.enabled = True

    def reset(self) -> None:
        """Forget the cut (before pyrender uploads the primitives again, e.g. after a scene switch)."""
        for it in self.items:
            it["prim"]._poses = it["poses"]
            it["last"] = it["buffer"] = None

    def apply(self, pose_cv: np.ndarray, half_h: float, half_v: float, far: float) -> None:
        if not self.enabled:
            return
        from OpenGL import GL

        r, t = pose_cv[:3, :3], pose_cv[:3, 3]
        ch, sh, cv, sv = np.cos(half_h), np.sin(half_h), np.cos(half_v), np.sin(half_v)
        for it in self.items:
            prim = it["prim"]
            if not prim._in_context() or len(prim._buffers) < 2:
                continue
            p = (it["centres"] - t) @ r  # camera frame (OpenCV)
            rad = it["radius"]
            x, y, z = p[:, 0], p[:, 1], p[:, 2]
            vis = (z > -rad) & (z < far + rad)
            vis &= (ch * x + sh * z >= -rad) & (-ch * x + sh * z >= -rad)
            vis &= (cv * y + sv * z >= -rad) & (-cv * y + sv * z >= -rad)
            key = vis.tobytes()
            buffer = prim._buffers[1]
            if key == it["last"] and buffer == it["buffer"]:
                continue
            sel = np.flatnonzero(vis)
            if len(sel) == 0:
                sel = np.array([0])  # keep one instance (a zero count is not drawable by pyrender)
            try:
                GL.glBindBuffer(GL.GL_ARRAY_BUFFER, buffer)
                if buffer != it["buffer"]:  # first cut since pyrender (re)created the buffer
                    GL.glBufferData(GL.GL_ARRAY_BUFFER, it["gl"].nbytes, it["gl"], GL.GL_DYNAMIC_DRAW)
                GL.glBufferSubData(GL.GL_ARRAY_BUFFER, 0, it["gl"][sel].nbytes, np.ascontiguousarray(it["gl"][sel]))
                GL.glBindBuffer(GL.GL_ARRAY_BUFFER, 0)
            except Exception:  # an unexpected pyrender layout: draw everything from now on
                self.enabled = False
                self.restore()
                return
            it["last"], it["buffer"] = key, buffer
            prim._poses = it["poses"][sel]

    def restore(self) -> None:
        """Draw every instance again (full instance buffers)."""
        from OpenGL import GL

        for it in self.items:
            prim = it["prim"]
            prim._poses = it["poses"]
            it["last"] = None
            if prim._in_context() and it["buffer"] is not None and prim._buffers[1] == it["buffer"]:
                GL.glBindBuffer(GL.GL_ARRAY_BUFFER, prim._buffers[1])
                GL.glBufferData(GL.GL_ARRAY_BUFFER, it["gl"].nbytes, it["gl"], GL.GL_DYNAMIC_DRAW)
                GL.glBindBuffer(GL.GL_ARRAY_BUFFER, 0)


_SCENES: dict[int, tuple[weakref.ref, Any, Any]] = {}
"""pyrender scenes by world (id → (weak reference, scene, camera node)): renderers of one world share
its scene, so switching between them does not upload the textures again."""


def _scene_for(world: World) -> tuple[Any, Any]:
    entry = _SCENES.get(id(world))
    if entry is not None and entry[0]() is world:
        return entry[1], entry[2]
    for key in [k for k, (ref, _, _) in _SCENES.items() if ref() is None]:
        del _SCENES[key]
    scene, node = build_scene(world)
    _SCENES[id(world)] = (weakref.ref(world), scene, node)
    return scene, node


class StereoRenderer:
    """Renders the trailer's stereo pair in a world.

    Parameters
    ----------
    world : World
        What the cameras see.
    rig : StereoRig
        Cameras, mounting and image effects.
    params : VehicleParams, optional
        The combination, for :meth:`render` from the tractor state (kingpin position, trailer rear).
    seed : int, optional
        Seed of the per-frame image noise and exposure (default: the world's seed). Frame ``k``
        draws from ``numpy.random.default_rng([seed, k])``, so images do not depend on the order
        in which frames are rendered.
    antialias : bool
        4× multisampling: smooth object silhouettes, at about 2.5× the render time on llvmpipe
        (road lines are antialiased either way).
    anisotropy : float
        Maximum anisotropic texture filtering (1: off). Very slow on llvmpipe.
    lod_bias : float
        Texture level-of-detail bias; negative values keep the ground texture sharper at grazing
        angles (more, slightly less stable, corner features far away).
    cull : bool
        Skip instanced objects outside the view frustum (no effect on the image).
    cull_distance : float
        ... and those farther than this along the optical axis [m] (they would cover a pixel or two).

    Notes
    -----
    The OpenGL context is created on the first render, shared by all renderers of the process,
    never pickled and never used across a fork (see the module docstring).
    """

    def __init__(
        self,
        world: World,
        rig: StereoRig | None = None,
        params: VehicleParams | None = None,
        *,
        seed: int | None = None,
        antialias: bool = False,
        anisotropy: float = 1.0,
        lod_bias: float = -0.5,
        cull: bool = True,
        cull_distance: float = 600.0,
    ) -> None:
        self.world = world
        self.rig = rig if rig is not None else StereoRig()
        self.params = params
        self.seed = int(world.config.seed if seed is None else seed)
        self.antialias = antialias
        self.anisotropy = float(anisotropy)
        self.lod_bias = float(lod_bias)
        self.cull = bool(cull)
        self.cull_distance = float(cull_distance)
        self.frame = 0
        self.timings: dict[str, float] = {}
        self._scene: Any = None
        self._camera_node: Any = None

    # -- pickling: the world and the rig only -------------------------------------------------------
    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_scene"] = None
        state["_camera_node"] = None
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)

    # -- rendering ----------------------------------------------------------------------------------
    def _context(self) -> _GLContext:
        rig = self.rig
        ctx = _GLContext.get(rig.width, rig.height, 4 if self.antialias else 1)
        ctx.renderer.anisotropy = self.anisotropy
        ctx.renderer.lod_bias = self.lod_bias
        if self._scene is None:
            self._scene, self._camera_node = _scene_for(self.world)
        if ctx.scene is not self._scene:
            # pyrender frees the previous scene's meshes and uploads this one's on the next render:
            # make sure it uploads every instance, then cut again.
            culler = getattr(self._scene, "offtrack_culler", None)
            if culler is not None:
                culler.reset()
            ctx.scene = self._scene
        cam = self._camera_node.camera
        f = rig.focal_length
        cx, cy = rig.principal_point
        # pyrender measures pixels from the pixel edges; OpenCV from the centre of the first pixel.
        cam.fx = cam.fy = f
        cam.cx, cam.cy = cx + 0.5, cy + 0.5
        cam.znear, cam.zfar = rig.znear, rig.zfar
        return ctx

    def render_view(self, pose: np.ndarray, *, depth: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
        """Render one camera at ``pose`` (``T_world←camera``, OpenCV axes), without noise or exposure.

        Returns
        -------
        grey, depth
            ``(height, width)`` uint8 image and, if ``depth``, float32 depth along the optical axis
            [m] (0 for the sky), else None.
        """
        pyrender = _pyrender()
        t0 = time.perf_counter()
        ctx = self._context()
        scene = self._scene
        scene.set_pose(self._camera_node, opencv_to_opengl(pose))
        r = ctx.renderer
        r.want_depth = depth
        flags = pyrender.RenderFlags.FLAT | pyrender.RenderFlags.OFFSCREEN
        culler = getattr(scene, "offtrack_culler", None)
        if culler is not None:
            r._update_context(scene, flags)  # upload new meshes first, then cut their instance lists
            if self.cull:
                rig = self.rig
                culler.apply(np.asarray(pose, float), 0.5 * rig.hfov, 0.5 * rig.vfov, min(rig.zfar, self.cull_distance))
            else:
                culler.restore()
        t1 = time.perf_counter()
        rgba, dep = r.render(scene, flags)
        t2 = time.perf_counter()
        grey = cv2.cvtColor(rgba, cv2.COLOR_RGBA2GRAY)
        grey = np.ascontiguousarray(grey[::-1])  # OpenGL rows run bottom-up
        t3 = time.perf_counter()
        gl = r.timings
        for key, value in (
            ("cull_s", t1 - t0),
            ("draw_s", gl.get("draw_s", 0.0)),
            ("readback_s", gl.get("readback_s", 0.0)),
            ("submit_s", (t2 - t1) - gl.get("draw_s", 0.0) - gl.get("readback_s", 0.0)),
            ("grey_s", t3 - t2),
        ):
            self.timings[key] = self.timings.get(key, 0.0) + value
        return grey, dep

    def render_poses(
        self, pose_left: np.ndarray, pose_right: np.ndarray, *, depth: bool = False, frame: int | None = None
    ) -> StereoPair:
        """Render the pair from two camera poses (``T_world←camera``, OpenCV axes).

        Image noise and exposure variation of the rig are applied (frame ``frame``, default the
        renderer's running frame counter).
        """
        k = self.frame if frame is None else int(frame)
        self.frame = k + 1
        left, dl = self.render_view(pose_left, depth=depth)
        right, dr = self.render_view(pose_right, depth=depth)
        t0 = time.perf_counter()
        left, right = self._effects(left, right, k)
        self.timings["effects_s"] = self.timings.get("effects_s", 0.0) + time.perf_counter() - t0
        self.timings["pairs"] = self.timings.get("pairs", 0.0) + 1
        return StereoPair(left, right, dl, dr)

    def render(
        self,
        x: float,
        y: float,
        psi1: float,
        gamma: float,
        *,
        depth: bool = False,
        frame: int | None = None,
        params: VehicleParams | None = None,
    ) -> StereoPair:
        """Render the pair for a tractor state (CG position [m], tractor heading ψ1 and articulation Γ [rad])."""
        params = params if params is not None else self.params
        if params is None:
            raise InputError("StereoRenderer.render needs the vehicle params (StereoRenderer(..., params=...))")
        pl = self.rig.camera_in_world(params, x, y, psi1, gamma, "left")
        pr = self.rig.camera_in_world(params, x, y, psi1, gamma, "right")
        return self.render_poses(pl, pr, depth=depth, frame=frame)

    def _effects(self, left: np.ndarray, right: np.ndarray, frame: int) -> tuple[np.ndarray, np.ndarray]:
        rig = self.rig
        if rig.noise_std <= 0.0 and rig.exposure_std <= 0.0:
            return left, right
        rng = np.random.default_rng([self.seed, 0xCA3E, frame])
        gains = 1.0 + rig.exposure_std * rng.standard_normal(2) if rig.exposure_std > 0 else np.ones(2)
        out = []
        for img, g in zip((left, right), gains, strict=True):
            f = img.astype(np.float32) * np.float32(max(g, 0.0))
            if rig.noise_std > 0:
                f += rng.standard_normal(img.shape, dtype=np.float32) * np.float32(rig.noise_std)
            out.append(np.clip(f + 0.5, 0, 255).astype(np.uint8))
        return out[0], out[1]

    def reset_timings(self) -> None:
        """Zero the accumulated stage timings."""
        self.timings = {}

    @property
    def gl_info(self) -> dict[str, str]:
        """OpenGL version and renderer string of the process's context (creates it if needed)."""
        ctx = self._context()
        return {"version": ctx.gl_version, "renderer": ctx.gl_renderer}
