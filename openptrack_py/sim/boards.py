"""A checkerboard drawn into the simulated RGB-D world, as a sensor would image it.

Multi-sensor calibration in OpenPTrack (Munaro et al., OpenPTrack, §4) has someone walk
through the room holding a checkerboard so that pairs of sensors see it at once, then
lay it flat on the floor to fix the world frame. This module draws that board into the
simulated frames (the session's placements are planned by
:mod:`openptrack_py.sim.board_session`):

* :func:`draw_board` — draws a :class:`~openptrack_py.calibration.checkerboard.Checkerboard`
  at a world pose into a frame rendered by
  :class:`~openptrack_py.sim.render.DepthRenderer`. Each pixel's ray meets the board's
  plane; the board is drawn where it is nearer than the scene, in colour (shaded as the
  renderer shades) and in the infrared image (black squares of low infrared albedo, white
  ones high, amplitude falling with range squared), with its depth degraded by the
  sensor type's depth noise. Pixels are **supersampled** (``supersample x supersample``
  rays each) so that square edges and corners are area anti-aliased as a camera
  integrates them — without it, corner localisation would snap to the pixel grid. The
  sensor's image noise (read and shot noise of the colour and infrared images) is then
  added. The back of the board is plain grey card.

The default board, :data:`SIM_BOARD`, is OpenPTrack's: 5 x 6 inner corners, 0.12 m
squares (0.84 x 0.72 m of squares, 1.0 x 0.88 m with the margin). Big squares are needed
by the SR4500: at 176 x 144 pixels (128 px focal length) a 0.12 m square spans 6 pixels
at 2.5 m, about the smallest the corner detector still finds (after upscaling); smaller
squares would leave the SR4500 seeing the board only within arm's reach.

Rendering without a board is untouched: :func:`draw_board` returns a new frame.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from openptrack_py.calibration.checkerboard import Checkerboard
from openptrack_py.detection.frame import Frame, Intrinsics, image_box
from openptrack_py.geometry import invert
from openptrack_py.sensor_types import SENSOR_TYPES
from openptrack_py.sim.render import DEPTH_NOISE, INTENSITY_GAIN, RenderedFrame

__all__ = [
    "BOARD_THICKNESS_M",
    "IMAGE_NOISE",
    "SIM_BOARD",
    "Checkerboard",
    "ImageNoise",
    "draw_board",
]

SIM_BOARD = Checkerboard(rows=5, cols=6, square_m=0.12, margin_m=0.08)
"""OpenPTrack's calibration board: 5 x 6 inner corners of 0.12 m squares, 8 cm margin."""

BOARD_THICKNESS_M = 0.005
"""Thickness of the board: laid on the floor, its printed face is this high."""

# Reflectance of the print, colour and infrared.
_WHITE, _BLACK, _BACK = 0.88, 0.06, 0.45
_IR_WHITE, _IR_BLACK, _IR_BACK = 0.9, 0.05, 0.5
_LIGHT = np.array([0.3, 0.2, 1.0]) / np.linalg.norm([0.3, 0.2, 1.0])


@dataclass(frozen=True)
class ImageNoise:
    """Image noise of one sensor type.

    Parameters
    ----------
    colour_sigma : float
        Standard deviation of colour values, 8-bit levels.
    ir_read_sigma : float
        Infrared read noise, counts.
    ir_shot_gain : float
        Infrared shot noise: variance grows by this many counts per count of signal.
    """

    colour_sigma: float
    ir_read_sigma: float
    ir_shot_gain: float


IMAGE_NOISE: dict[str, ImageNoise] = {
    "kinect1": ImageNoise(colour_sigma=3.0, ir_read_sigma=4.0, ir_shot_gain=1.0),
    "kinect2": ImageNoise(colour_sigma=2.0, ir_read_sigma=3.0, ir_shot_gain=1.0),
    "realsense": ImageNoise(colour_sigma=2.0, ir_read_sigma=3.0, ir_shot_gain=1.0),
    "sr4500": ImageNoise(colour_sigma=2.0, ir_read_sigma=5.0, ir_shot_gain=2.0),
}
"""Image noise per sensor type (the SR4500's amplitude image is the noisiest)."""


# ----------------------------------------------------------------------------- drawing


def _pixel_box(
    board: Checkerboard, camera_from_board: np.ndarray, k: Intrinsics
) -> tuple[int, int, int, int] | None:
    """Pixel box ``(u0, u1, v0, v1)`` covering the board; None when out of view."""
    cam = board.outline() @ camera_from_board[:3, :3].T + camera_from_board[:3, 3]
    return image_box(cam, k, pad=1)


@dataclass(frozen=True, eq=False)
class _Coverage:
    """What the board adds to the pixels of its box (sums over subsamples)."""

    cover: np.ndarray  # share of subsamples on the board, 0-1
    shade: np.ndarray  # colour reflectance times coverage
    ir: np.ndarray  # infrared counts times coverage
    depth: np.ndarray  # mean depth of the covered subsamples (inf where none)
    cos: np.ndarray  # incidence cosine at the pixel's centre


def _cover(
    board: Checkerboard,
    camera_from_board: np.ndarray,
    k: Intrinsics,
    box: tuple[int, int, int, int],
    scene: np.ndarray,
    supersample: int,
) -> _Coverage:
    """Ray-plane intersection of ``supersample**2`` rays per pixel of ``box``."""
    u0, u1, v0, v1 = box
    rot, origin = camera_from_board[:3, :3], camera_from_board[:3, 3]
    normal = rot[:, 2]
    front = float(origin @ normal) > 0  # the camera sits on the printed side (board -z)
    x0, x1, y0, y1 = board.extent
    uu, vv = np.meshgrid(np.arange(u0, u1, dtype=np.float64), np.arange(v0, v1, dtype=np.float64))
    shape = uu.shape
    cover = np.zeros(shape)
    shade = np.zeros(shape)
    ir = np.zeros(shape)
    depth_sum = np.zeros(shape)
    offsets = (np.arange(supersample) + 0.5) / supersample - 0.5
    plane = float(normal @ origin)
    for dv in offsets:
        for du in offsets:
            dx, dy = k.rays(uu + du, vv + dv)
            denom = normal[0] * dx + normal[1] * dy + normal[2]
            with np.errstate(divide="ignore", invalid="ignore"):
                t = plane / denom  # depth along the optical axis
            hit = np.stack([dx * t, dy * t, t], axis=-1) - origin
            bx = hit @ rot[:, 0]
            by = hit @ rot[:, 1]
            on = (t > 0.05) & (t < scene) & (bx >= x0) & (bx <= x1) & (by >= y0) & (by <= y1)
            if not on.any():
                continue
            ray_len = np.sqrt(dx * dx + dy * dy + 1.0)
            cos = np.abs(denom) / ray_len
            if front:
                black = board.is_black(bx, by)
                refl = np.where(black, _BLACK, _WHITE)
                ir_refl = np.where(black, _IR_BLACK, _IR_WHITE)
            else:
                refl, ir_refl = _BACK, _IR_BACK
            amplitude = ir_refl * np.clip(cos, 0.05, 1.0) / np.maximum(t * ray_len, 0.3) ** 2
            cover += on
            shade += np.where(on, refl, 0.0)
            ir += np.where(on, amplitude * INTENSITY_GAIN, 0.0)
            depth_sum += np.where(on, t, 0.0)
    n = supersample * supersample
    with np.errstate(divide="ignore", invalid="ignore"):
        depth = np.where(cover > 0, depth_sum / cover, np.inf)
    dx, dy = k.rays(uu, vv)
    cos = np.abs(normal[0] * dx + normal[1] * dy + normal[2]) / np.sqrt(dx * dx + dy * dy + 1)
    return _Coverage(cover / n, shade / n, ir / n, depth, cos)


def _board_brightness(world_from_board: np.ndarray, front: bool) -> float:
    """Ambient plus diffuse light from above on the board's visible face (as the renderer)."""
    normal = -world_from_board[:3, 2] if front else world_from_board[:3, 2]
    return 0.8 + 0.35 * max(float(normal @ _LIGHT), 0.0)


def _degrade_board_depth(
    depth: np.ndarray,
    cover: np.ndarray,
    cos: np.ndarray,
    scene: np.ndarray,
    sensor_type: str,
    rng: np.random.Generator,
) -> np.ndarray:
    """The board's depth as the sensor type measures it (NaN where it reads nothing)."""
    noise = DEPTH_NOISE[sensor_type]
    s0, s1, s2 = noise.sigma
    z = np.where(np.isfinite(depth), depth, 0.0)
    out = depth + (s0 + s1 * z + s2 * z * z) * rng.standard_normal(depth.shape)
    with np.errstate(divide="ignore", invalid="ignore"):
        if noise.disparity_step > 0:
            step = noise.disparity_step
            out = 1.0 / (np.round(1.0 / out / step) * step)
        else:
            out = np.round(out * 1000.0) / 1000.0
    lost = rng.random(depth.shape) < noise.dropout
    lost |= cos < noise.grazing_cos
    if noise.edge_jump_m > 0:  # time-of-flight flying pixels at the board's edge
        edge = (cover < 1.0) & ~(
            np.abs(np.nan_to_num(scene, posinf=1e3) - depth) < noise.edge_jump_m
        )
        lost |= edge & (rng.random(depth.shape) < 0.5)
    out[lost] = np.nan
    return out


def _image_noise(
    color: np.ndarray, intensity: np.ndarray, sensor_type: str, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Colour and infrared images with the sensor type's read and shot noise."""
    noise = IMAGE_NOISE[sensor_type]
    rgb = color.astype(np.float32) + noise.colour_sigma * rng.standard_normal(
        color.shape, dtype=np.float32
    )
    ir = intensity.astype(np.float32)
    sigma = np.sqrt(noise.ir_read_sigma**2 + noise.ir_shot_gain * ir)
    ir = ir + sigma * rng.standard_normal(ir.shape, dtype=np.float32)
    return (
        np.clip(rgb + 0.5, 0, 255).astype(np.uint8),
        np.clip(ir + 0.5, 0, 65535).astype(np.uint16),
    )


def draw_board(
    rendered: RenderedFrame,
    board: Checkerboard,
    world_from_board: np.ndarray,
    world_from_camera: np.ndarray,
    intrinsics: Intrinsics,
    *,
    sensor_type: str,
    rng: np.random.Generator,
    scene_depth: np.ndarray | None = None,
    supersample: int = 4,
    noise: bool = True,
) -> RenderedFrame:
    """The rendered frame with a checkerboard drawn into it.

    Parameters
    ----------
    rendered : RenderedFrame
        A frame of :class:`~openptrack_py.sim.render.DepthRenderer` (not modified).
    board : Checkerboard
        The board.
    world_from_board : ndarray
        4x4 pose of the board frame in the world (see
        :class:`~openptrack_py.calibration.checkerboard.Checkerboard` for its axes).
    world_from_camera : ndarray
        4x4 pose of the camera's optical frame in the world.
    intrinsics : Intrinsics
        The camera's pinhole model (the frame's image size).
    sensor_type : str
        Whose depth and image noise to apply.
    rng : numpy.random.Generator
        Noise source.
    scene_depth : ndarray, optional
        The scene's noise-free depth, for the visibility test (a noise-free render of the
        same scene); the frame's measured depth when omitted (no reading counts as far).
    supersample : int
        Rays per pixel along each axis (area anti-aliasing).
    noise : bool
        Add the sensor type's depth noise on the board and image noise on the images.

    Returns
    -------
    RenderedFrame
        A new frame: the board in depth, colour and infrared where it is in front; labels
        show scenery (-1) where the board covers a pixel and the visible pixel counts are
        updated (the head counts are those of the render without the board).
    """
    frame = rendered.frame
    camera_from_board = invert(world_from_camera) @ world_from_board
    box = _pixel_box(board, camera_from_board, intrinsics)
    if box is None:
        return _with_noise(rendered, sensor_type, rng) if noise else rendered
    u0, u1, v0, v1 = box
    base = (frame.depth if scene_depth is None else scene_depth)[v0:v1, u0:u1]
    scene = np.nan_to_num(base.astype(np.float64), nan=np.inf)
    cov = _cover(board, camera_from_board, intrinsics, box, scene, supersample)
    board_depth = cov.depth
    if noise:
        board_depth = _degrade_board_depth(board_depth, cov.cover, cov.cos, base, sensor_type, rng)
    kind = SENSOR_TYPES[sensor_type]
    out_of_range = (board_depth < kind.min_range_m) | (board_depth > kind.max_range_m)
    board_depth = np.where(out_of_range, np.nan, board_depth)
    covered = cov.cover >= 0.5
    depth = frame.depth.copy()
    depth[v0:v1, u0:u1][covered] = board_depth[covered]
    labels = rendered.labels.copy()
    labels[v0:v1, u0:u1][covered] = -1
    front = float(camera_from_board[:3, 3] @ camera_from_board[:3, 2]) > 0
    color, intensity = _blend(frame, cov, box, _board_brightness(world_from_board, front))
    n = len(rendered.ids)
    out = replace(
        rendered,
        frame=replace(frame, depth=depth, color=color, intensity=intensity),
        labels=labels,
        visible_pixels=np.bincount(labels[labels >= 0], minlength=n)[:n],
    )
    return _with_noise(out, sensor_type, rng) if noise else out


def _blend(
    frame: Frame, cov: _Coverage, box: tuple[int, int, int, int], light: float
) -> tuple[np.ndarray, np.ndarray]:
    """Colour and infrared images with the board blended in by its pixel coverage."""
    u0, u1, v0, v1 = box
    color = frame.color.copy()
    intensity = frame.intensity.copy()
    keep = 1.0 - cov.cover
    board_rgb = np.minimum(cov.shade * light, 1.0) * 255.0
    rgb = color[v0:v1, u0:u1].astype(np.float64) * keep[..., None] + board_rgb[..., None]
    color[v0:v1, u0:u1] = np.clip(rgb + 0.5, 0, 255).astype(np.uint8)
    ir = intensity[v0:v1, u0:u1].astype(np.float64) * keep + cov.ir
    intensity[v0:v1, u0:u1] = np.clip(ir + 0.5, 0, 65535).astype(intensity.dtype)
    return color, intensity


def _with_noise(
    rendered: RenderedFrame, sensor_type: str, rng: np.random.Generator
) -> RenderedFrame:
    """The frame with the sensor type's image noise on colour and infrared."""
    frame = rendered.frame
    if frame.color is None or frame.intensity is None:
        return rendered
    color, intensity = _image_noise(frame.color, frame.intensity, sensor_type, rng)
    return replace(rendered, frame=replace(frame, color=color, intensity=intensity))
