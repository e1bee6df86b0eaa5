"""Offscreen rendering of the stereo pair with pyrender through EGL (Mesa llvmpipe needs no GPU).

Rules of the road:

* **One OpenGL context per process**, created lazily on the first render and shared by every
  :class:`StereoRenderer` of the process (renderers of other worlds or image sizes switch the
  scene and the viewport of the same context).
* **Never pickled**: a :class:`StereoRenderer` pickles its world and rig only; the scene is rebuilt
  from them when the unpickled copy first renders (in whatever process that is).
* **Never across a fork**: the context remembers the process that created it; a forked child that
  tries to render gets :class:`~sensor.rendering_errors.RenderingUnavailableError` instead of a
  corrupted context. Create renderers after forking, or use the ``spawn`` start method.

Speed (llvmpipe renders on the CPU; ``offtrack bench render`` measures it,
:func:`scenarios.bench.render.bench_render`; figures in ``benchmarks/README.md``):

* surfaces are drawn unlit (``RenderFlags.FLAT``: texture × baked vertex colour) by a lean forward
  pass (one shader program, cached uniform locations, state changed only when it differs) in a
  fixed order — objects, road, ground — so hidden ground fails the depth test early and the same
  world always gives the same image;
* static geometry is merged per texture and widely repeated objects are instanced; instances
  outside the view frustum are not drawn (:class:`~sensor.scene.InstanceCuller`);
* the colour buffer is read as RGBA into a preallocated array, depth only on request, and OpenCV
  converts to grey.

Most of the time is llvmpipe's rasterisation (fill rate: ~525 k pixels per view with trilinear
texture sampling); the rest is per-view CPU work in Python, PyOpenGL and llvmpipe's vertex stage. 4× multisampling
(``antialias=True``) smooths object silhouettes but costs time (``benchmarks/README.md``); road lines are antialiased
without it (soft-edged textures). Supersampling (:attr:`~sensor.camera.StereoRig.supersample` ``k``) draws ``k²``
times the pixels and averages them down, at several times the render time. Anisotropic filtering is very slow on
llvmpipe and off by default; a LOD bias of −0.5 keeps the road texture sharper at grazing angles.

Where things live: this module holds the public API (:class:`StereoRenderer`, :class:`StereoPair`);
what it raises when OpenGL is unusable (:class:`~sensor.rendering_errors.RenderingUnavailableError`) is in
:mod:`sensor.rendering_errors`; the process's OpenGL context and the pyrender import are in
:mod:`sensor.gl_context`, the lean forward pass and readback in :mod:`sensor.fast_renderer`, and the
scene of a world (draw groups, instancing, culling, the per-world cache) in :mod:`sensor.scene`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from vehicle_model.errors import InputError
from vehicle_model.geometry import ChainPose, CombinationPose
from vehicle_model.parameters import VehicleParams
from vehicle_model.terrain import Terrain

from .camera import StereoRig, Which, opencv_to_opengl
from .exposure import AutoExposure, FrameLight
from .gl_context import GLContext, import_pyrender
from .lighting import Lighting, light_world
from .scene import body_nodes, scene_for
from .vehicle_bodies import unit_poses
from .world import World

__all__ = ["StereoPair", "StereoRenderer"]


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


class StereoRenderer:
    """Renders the trailer's stereo pair in a world.

    Parameters
    ----------
    world : World
        What the cameras see.
    rig : StereoRig
        Cameras, mounting and image effects; its :attr:`~sensor.camera.StereoRig.supersample` renders each view at
        that many times the size and averages it down (``cv2.INTER_AREA``).
    params : VehicleParams, optional
        The combination, for :meth:`render` at a :class:`~vehicle_model.geometry.CombinationPose` (kingpin
        position, trailer rear).
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
    lighting : Lighting, optional
        Sun, shadows, sky and auto-exposure (:mod:`sensor.lighting`, :mod:`sensor.exposure`); default
        (None or ``Lighting()``) the flat lighting of the ideal study, images unchanged. With a sun
        the light and shadows are baked into a copy of the world once, and each pair gets the sky,
        the glare and one lagging exposure gain (carried from frame ``k − 1`` to ``k`` when frames
        come in order).
    frame_interval_s : float
        Time between frames [s] (1 / camera rate), over which the auto-exposure lags.
    bodies : bool
        Draw the combination's units (boxes and wheels, :mod:`sensor.vehicle_bodies`) at the vehicle pose of each
        render, all but the rig's own unit (:attr:`StereoRig.unit`), on the world's terrain (:attr:`terrain`);
        False: the world alone. Renders from camera poses alone (:meth:`render_poses` without ``vehicle``) draw no
        units.

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
        lighting: Lighting | None = None,
        frame_interval_s: float = 0.1,
        bodies: bool = True,
    ) -> None:
        self.world = world
        self.bodies = bool(bodies)
        self.rig = rig if rig is not None else StereoRig()
        self.params = params
        self.seed = int(world.config.seed if seed is None else seed)
        self.antialias = antialias
        self.anisotropy = float(anisotropy)
        self.lod_bias = float(lod_bias)
        self.cull = bool(cull)
        self.cull_distance = float(cull_distance)
        self.lighting = lighting if lighting is not None else Lighting()
        self.frame_interval_s = float(frame_interval_s)
        self.frame = 0
        self.timings: dict[str, float] = {}
        self._scene: Any = None
        self._camera_node: Any = None
        self._lit: tuple[World, FrameLight, AutoExposure] | None = None
        self._alpha: np.ndarray | None = None
        self.last_gain = 1.0

    # -- pickling: the world and the rig only -------------------------------------------------------
    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_scene"] = None
        state["_camera_node"] = None
        state["_lit"] = None
        state["_alpha"] = None
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        state.setdefault("lighting", Lighting())
        state.setdefault("frame_interval_s", 0.1)
        state.setdefault("_lit", None)
        state.setdefault("_alpha", None)
        state.setdefault("last_gain", 1.0)
        state.setdefault("bodies", True)
        self.__dict__.update(state)

    def _lit_parts(self) -> tuple[World, FrameLight, AutoExposure] | None:
        """The lit world, the sky/glare model and the exposure state (None under flat lighting)."""
        if not self.lighting.sun:
            return None
        if self._lit is None:
            rig = self.rig
            light = FrameLight(self.lighting, rig.intrinsics(), rig.width, rig.height, self.world.sky_rgb)
            exposure = AutoExposure(self.lighting, self.frame_interval_s)
            self._lit = (light_world(self.world, self.lighting), light, exposure)
        return self._lit

    # -- rendering ----------------------------------------------------------------------------------
    def _context(self) -> GLContext:
        rig = self.rig
        k = rig.supersample
        ctx = GLContext.get(k * rig.width, k * rig.height, 4 if self.antialias else 1)
        ctx.renderer.anisotropy = self.anisotropy
        ctx.renderer.lod_bias = self.lod_bias
        if self._scene is None:
            lit = self._lit_parts()
            self._scene, self._camera_node = scene_for(self.world if lit is None else lit[0])
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
        # pyrender measures pixels from the pixel edges; OpenCV from the centre of the first pixel. Supersampled,
        # every length in pixels from the image's corner grows k times, so each block of k × k samples covers
        # exactly one pixel of the rig.
        cam.fx = cam.fy = k * f
        cam.cx, cam.cy = k * (cx + 0.5), k * (cy + 0.5)
        cam.znear, cam.zfar = rig.znear, rig.zfar
        return ctx

    def _place_bodies(self, vehicle: CombinationPose | ChainPose | None) -> None:
        """Pose the combination's units in the scene for the next view (all hidden without a vehicle pose)."""
        table = getattr(self._scene, "offtrack_bodies", {})
        if vehicle is None or not self.bodies or self.params is None:
            for entry in table.values():
                entry.place(None)
            return
        nodes = body_nodes(self._scene, self.params)
        for entry in getattr(self._scene, "offtrack_bodies", {}).values():
            if entry is not nodes:
                entry.place(None)
        nodes.place(unit_poses(self.params, vehicle, self.terrain), hidden=self.rig.unit)

    def render_view(
        self,
        pose: CombinationPose | ChainPose | np.ndarray,
        *,
        depth: bool = False,
        which: Which = "left",
        vehicle: CombinationPose | ChainPose | None = None,
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Render one camera without noise or exposure.

        Parameters
        ----------
        pose : CombinationPose, ChainPose or numpy.ndarray
            Where the combination is (the camera ``which`` of the rig is rendered; needs the vehicle params), or
            directly the camera's pose ``T_world←camera`` (4×4, OpenCV axes).
        depth : bool
            Also read the depth buffer.
        which : {"left", "right"}
            The camera, for a combination pose.
        vehicle : CombinationPose or ChainPose, optional
            Where the combination's units are drawn when ``pose`` is a camera pose (default: the combination pose
            ``pose``, or none drawn for a camera pose).

        Returns
        -------
        grey, depth
            ``(height, width)`` uint8 image and, if ``depth``, float32 depth along the optical axis
            [m] (0 for the sky), else None.
        """
        if isinstance(pose, CombinationPose | ChainPose):
            vehicle = pose if vehicle is None else vehicle
            pose = self.rig.camera_in_world(self._params(None), pose, which, self.terrain)
        pyrender = import_pyrender()
        t0 = time.perf_counter()
        ctx = self._context()
        scene = self._scene
        self._place_bodies(vehicle)
        scene.set_pose(self._camera_node, opencv_to_opengl(pose))
        r = ctx.renderer
        r.want_depth = depth
        flags = pyrender.RenderFlags.FLAT | pyrender.RenderFlags.OFFSCREEN
        culler = getattr(scene, "offtrack_culler", None)
        if culler is not None:
            r.sync(scene, flags)  # upload new meshes first, then cut their instance lists
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
        self._alpha = np.ascontiguousarray(rgba[::-1, :, 3]) if self.lighting.sun else None
        if self.rig.supersample > 1:
            grey, dep = self._downsample(grey, dep)
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

    def _downsample(self, grey: np.ndarray, depth: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None]:
        """A supersampled view at the rig's size: grey levels and alpha averaged over each pixel's k × k samples
        (``cv2.INTER_AREA``); the depth is one sample's, the one nearest the pixel's centre (an average of depths
        across a silhouette would be a surface that is not there)."""
        rig = self.rig
        k = rig.supersample
        size = (rig.width, rig.height)
        grey = cv2.resize(grey, size, interpolation=cv2.INTER_AREA)
        if self._alpha is not None:
            self._alpha = cv2.resize(self._alpha, size, interpolation=cv2.INTER_AREA)
        if depth is not None:
            depth = np.ascontiguousarray(depth[k // 2 :: k, k // 2 :: k])
        return grey, depth

    def render_poses(
        self,
        pose_left: np.ndarray,
        pose_right: np.ndarray,
        *,
        depth: bool = False,
        frame: int | None = None,
        expose: bool = True,
        vehicle: CombinationPose | ChainPose | None = None,
    ) -> StereoPair:
        """Render the pair from two camera poses (``T_world←camera``, OpenCV axes), the combination's units drawn at
        ``vehicle`` (None: not drawn).

        Image noise and exposure variation of the rig are applied (frame ``frame``, default the
        renderer's running frame counter). With a sun and ``expose=False`` the pair is the radiance before
        the auto-exposure (float32, grey levels at gain 1) without sensor effects: for a caller that exposes
        the frames in their order itself (the exposure lags, so it depends on the frames before).
        """
        k = self.frame if frame is None else int(frame)
        self.frame = k + 1
        left, dl = self.render_view(pose_left, depth=depth, vehicle=vehicle)
        alpha_left = self._alpha
        right, dr = self.render_view(pose_right, depth=depth, vehicle=vehicle)
        t0 = time.perf_counter()
        lit = self._lit_parts()
        if lit is not None:  # sky, shade, glare, then one lagging exposure for the pair (sensor.exposure)
            _, light, exposure = lit
            rad_l = light.radiance(left, alpha_left, np.asarray(pose_left)[:3, :3])
            rad_r = light.radiance(right, self._alpha, np.asarray(pose_right)[:3, :3])
            if not expose:
                self.timings["pairs"] = self.timings.get("pairs", 0.0) + 1
                return StereoPair(rad_l.astype(np.float32), rad_r.astype(np.float32), dl, dr)
            gain = exposure.update(float(cv2.mean(rad_l)[0]), k)
            left, right = exposure.apply(rad_l, gain), exposure.apply(rad_r, gain)
            self.last_gain = gain
        left, right = self._effects(left, right, k)
        self.timings["effects_s"] = self.timings.get("effects_s", 0.0) + time.perf_counter() - t0
        self.timings["pairs"] = self.timings.get("pairs", 0.0) + 1
        return StereoPair(left, right, dl, dr)

    def render(
        self,
        pose: CombinationPose | ChainPose,
        *,
        depth: bool = False,
        frame: int | None = None,
        params: VehicleParams | None = None,
        expose: bool = True,
    ) -> StereoPair:
        """Render the pair at a combination pose (tractor CG position [m], heading ψ1 and articulation Γ [rad], or
        every coupling's articulation: :class:`~vehicle_model.geometry.ChainPose`), the units drawn at it.

        ``expose``: see :meth:`render_poses`."""
        params = self._params(params)
        pl = self.rig.camera_in_world(params, pose, "left", self.terrain)
        pr = self.rig.camera_in_world(params, pose, "right", self.terrain)
        return self.render_poses(pl, pr, depth=depth, frame=frame, expose=expose, vehicle=pose)

    @property
    def terrain(self) -> Terrain | None:
        """The ground the world is draped on (:attr:`World.terrain`): the cameras and units at a combination pose
        stand on it (``None``: the level road)."""
        return getattr(self.world, "terrain", None)

    def _params(self, params: VehicleParams | None) -> VehicleParams:
        params = params if params is not None else self.params
        if params is None:
            raise InputError("rendering at a combination pose needs the vehicle params (StereoRenderer(params=...))")
        return params

    def _effects(self, left: np.ndarray, right: np.ndarray, frame: int) -> tuple[np.ndarray, np.ndarray]:
        return apply_sensor_effects(left, right, self.rig, self.seed, frame)

    def reset_timings(self) -> None:
        """Zero the accumulated stage timings."""
        self.timings = {}

    @property
    def gl_info(self) -> dict[str, str]:
        """OpenGL version and renderer string of the process's context (creates it if needed)."""
        ctx = self._context()
        return {"version": ctx.gl_version, "renderer": ctx.gl_renderer}


def apply_sensor_effects(
    left: np.ndarray, right: np.ndarray, rig: StereoRig, seed: int, frame: int
) -> tuple[np.ndarray, np.ndarray]:
    """The image sensor's gain jitter and noise of frame ``frame`` (``rig.exposure_std``, ``rig.noise_std``).

    Seeded by ``(seed, frame)`` alone, so a frame's noise does not depend on the process or the order of
    rendering. Applied by the renderer to the images it returns, and by a lens model after distorting a
    noise-free render (the noise of a real sensor is not interpolated by the lens).
    """
    if rig.noise_std <= 0.0 and rig.exposure_std <= 0.0:
        return left, right
    rng = np.random.default_rng([seed, 0xCA3E, frame])
    gains = 1.0 + rig.exposure_std * rng.standard_normal(2) if rig.exposure_std > 0 else np.ones(2)
    out = []
    for img, g in zip((left, right), gains, strict=True):
        f = img.astype(np.float32) * np.float32(max(g, 0.0))
        if rig.noise_std > 0:
            f += rng.standard_normal(img.shape, dtype=np.float32) * np.float32(rig.noise_std)
        out.append(np.clip(f + 0.5, 0, 255).astype(np.uint8))
    return out[0], out[1]
