"""RGB-D rendering of the simulated world: what a depth camera would actually deliver.

:class:`DepthRenderer` ray-casts one virtual sensor's view with its real intrinsics and
returns a depth image (metres, NaN where the sensor gives no reading), a colour image
registered to it, an infrared-like intensity image, and a label image saying which
person each pixel shows — so detectors can be scored against ground truth.

The scene:

* **static**: floor, four walls (3 m high) and a ceiling, and the room's furniture as
  boxes. Cast once per sensor, since neither moves.
* **people**: eight ellipsoids each — head, torso, shoulders, hips, two arms and two
  legs — sized
  from the person's stature and body radius (adults and children alike), facing their
  direction of motion, with legs and arms swinging while they walk. Clothing colours come
  from the world (the top's for torso and arms, the bottom's for hips and legs, as
  :meth:`~openptrack_py.sim.world.Snapshot.clothing` gives them).
  Each ellipsoid is intersected only with the pixels inside its projected bounding box,
  which keeps a frame at a few milliseconds.

Per sensor type, the depth is then degraded as that sensor degrades it: Gaussian noise
(Kinect v1 and structured light grow with distance squared, time-of-flight sensors are
nearly constant), quantisation (Kinect v1 in disparity, the others in millimetres),
depth limits (on the depth value, as the cameras apply them), random dropouts, readings
lost at grazing angles and, for time-of-flight sensors, "flying pixels" lost at depth
edges.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from openptrack_py.detection.frame import Frame, Intrinsics, image_box
from openptrack_py.geometry import apply, invert, world_from_optical
from openptrack_py.sim.clothing import SKIN
from openptrack_py.sim.sensor_spec import SensorSpec
from openptrack_py.sim.world import Room, Snapshot

WALL_HEIGHT_M = 3.0


@dataclass(frozen=True)
class DepthNoise:
    """How one sensor type degrades depth.

    Parameters
    ----------
    sigma : tuple of float
        ``(s0, s1, s2)``: per-pixel standard deviation ``s0 + s1*z + s2*z**2`` metres.
    disparity_step : float
        Kinect v1 style quantisation of ``1/z`` (1/m); 0 for millimetre quantisation.
    dropout : float
        Probability that a valid pixel reads nothing.
    grazing_cos : float
        Readings are lost where the cosine between ray and surface normal is below this.
    edge_jump_m : float
        Time-of-flight flying pixels: pixels next to a depth jump larger than this are
        lost (0 disables).
    """

    sigma: tuple[float, float, float]
    disparity_step: float = 0.0
    dropout: float = 0.01
    grazing_cos: float = 0.12
    edge_jump_m: float = 0.0


DEPTH_NOISE: dict[str, DepthNoise] = {
    # Khoshelham & Elberink: sigma ~1.4e-3 z^2, disparity steps ~2.9e-3 z^2.
    "kinect1": DepthNoise((0.0, 0.0, 0.0014), disparity_step=0.0029, dropout=0.02),
    "kinect2": DepthNoise((0.0015, 0.0007, 0.0), dropout=0.01, edge_jump_m=0.15),
    "realsense": DepthNoise((0.0015, 0.0, 0.0012), dropout=0.03, grazing_cos=0.2),
    "sr4500": DepthNoise((0.004, 0.0015, 0.0), dropout=0.02, edge_jump_m=0.2),
}

# Part kinds (which colour a part wears).
_SKIN, _TOP, _BOTTOM = 0, 1, 2
_PARTS = 8
_PART_KIND = np.array([_SKIN, _TOP, _BOTTOM, _BOTTOM, _BOTTOM, _TOP, _TOP, _TOP])

# Surface albedo in the infrared (intensity image) per material.
_IR_ALBEDO = {"skin": 0.55, "cloth": 0.7, "floor": 0.45, "wall": 0.8, "furniture": 0.5}


_LIGHT = np.array([0.3, 0.2, 1.0]) / np.linalg.norm([0.3, 0.2, 1.0])
_CORNER_SIGNS = np.array(
    [(a, b, c) for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)], dtype=float
)
_HAIR = np.array([0.18, 0.12, 0.08])
INTENSITY_GAIN = 6000.0
"""Intensity counts of a unit-albedo surface facing the sensor at 1 m."""


def _intensity(albedo: np.ndarray | float, cos: np.ndarray, range_m: np.ndarray) -> np.ndarray:
    """Time-of-flight style amplitude: albedo times incidence over range squared, uint16."""
    with np.errstate(invalid="ignore"):
        value = albedo * np.clip(cos, 0.05, 1.0) / np.maximum(range_m, 0.3) ** 2
    return np.clip(np.nan_to_num(value * INTENSITY_GAIN, posinf=0.0), 0, 65535).astype(np.uint16)


def _hsv_to_rgb(h_deg: np.ndarray, s: np.ndarray | float, v: np.ndarray | float) -> np.ndarray:
    """RGB in [0, 1] for hues in degrees, saturations and values on 0-1 (vectorised)."""
    h, s, v = np.broadcast_arrays(
        (np.asarray(h_deg, dtype=float) % 360.0) / 60.0,
        np.asarray(s, dtype=float),
        np.asarray(v, dtype=float),
    )
    c = v * s
    x = c * (1 - np.abs(h % 2 - 1))
    zero = np.zeros_like(h)
    sector = np.floor(h).astype(int) % 6
    table = [
        (c + zero, x, zero),
        (x, c + zero, zero),
        (zero, c + zero, x),
        (zero, x, c + zero),
        (x, zero, c + zero),
        (c + zero, zero, x),
    ]
    rgb = np.zeros((*h.shape, 3))
    for k, (r, g, b) in enumerate(table):
        m = sector == k
        rgb[m] = np.stack([r[m], g[m], b[m]], axis=-1)
    return rgb + (v - c)[..., None]


@dataclass(frozen=True, slots=True, eq=False)
class RenderedFrame:
    """One rendered capture with what it shows.

    Parameters
    ----------
    frame : Frame
        What the sensor delivers (depth, colour, intensity, intrinsics).
    labels : ndarray
        ``(height, width)`` int32: the snapshot row each pixel shows, -1 for scenery.
    ids : ndarray
        Person id per snapshot row.
    visible_pixels, body_pixels : ndarray
        Per snapshot row: pixels where the person is in front, and where their body
        would be seen if nobody and nothing stood in the way.
    head_visible, head_pixels : ndarray
        The same counts for the head alone.
    """

    frame: Frame
    labels: np.ndarray
    ids: np.ndarray
    visible_pixels: np.ndarray
    body_pixels: np.ndarray
    head_visible: np.ndarray
    head_pixels: np.ndarray


class DepthRenderer:
    """Renders one virtual sensor's depth, colour and intensity images.

    Parameters
    ----------
    spec : SensorSpec
        The sensor: type, true pose.
    room : Room
        The room and its furniture.
    rng : numpy.random.Generator
        Noise source.
    intrinsics : Intrinsics, optional
        Override the spec's camera model (its type's pinhole and the unit's lens, if
        any): a unit's own pinhole, and its lens (each pixel's ray is traced through it;
        pixels where the lens cannot be inverted see nothing).
    reports : Intrinsics, optional
        The camera model the frames carry, as the unit's driver reports it: by default
        ``intrinsics`` when given, else the spec's reported model (a factory lens, or
        none).
    noise : bool
        Apply the sensor type's depth degradation.
    """

    def __init__(
        self,
        spec: SensorSpec,
        room: Room,
        rng: np.random.Generator,
        *,
        intrinsics: Intrinsics | None = None,
        reports: Intrinsics | None = None,
        noise: bool = True,
    ) -> None:
        self.spec = spec
        self.room = room
        self.rng = rng
        self.intrinsics = intrinsics or spec.intrinsics
        self.reports = reports or intrinsics or spec.reported_intrinsics
        self.noise = DEPTH_NOISE[spec.type.name] if noise else None
        self.world_from_camera = world_from_optical(spec.pose)
        self.camera_from_world = invert(self.world_from_camera)
        k = self.intrinsics
        uu, vv = np.meshgrid(np.arange(k.width, dtype=np.float64), np.arange(k.height))
        rays = np.empty((k.height, k.width, 3))
        rays[..., 0], rays[..., 1] = k.rays(uu, vv)
        rays[..., 2] = 1.0
        # World-frame ray direction per pixel, scaled so that t along it is the depth z.
        self._rays = (rays @ self.world_from_camera[:3, :3].T).astype(np.float32)
        self._ray_norm = np.linalg.norm(rays, axis=-1).astype(np.float32)
        self.origin = self.world_from_camera[:3, 3].copy()
        self._static_depth, self._static_rgb, self._static_ir, self._static_grazing = (
            self._cast_static()
        )

    # ------------------------------------------------------------------ scenery

    def _cast_static(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Depth, shaded colour, IR albedo and incidence cosine of the empty room."""
        o = self.origin
        d = self._rays.astype(np.float64)
        h, w = d.shape[:2]
        depth = np.full((h, w), np.inf)
        normal = np.zeros((h, w, 3))
        albedo = np.zeros((h, w, 3))
        ir = np.zeros((h, w))
        room = self.room
        walls = np.array(_hsv_to_rgb(np.array(40.0), 0.12, 0.85))
        floor_rgb = np.array(_hsv_to_rgb(np.array(30.0), 0.25, 0.55))
        wood = np.array(_hsv_to_rgb(np.array(28.0), 0.5, 0.6))
        # (axis, coordinate, outward normal sign, colour, ir albedo)
        planes = [
            (2, 0.0, 1.0, floor_rgb, _IR_ALBEDO["floor"]),
            (2, WALL_HEIGHT_M, -1.0, walls * 0.95, _IR_ALBEDO["wall"]),
            (0, 0.0, 1.0, walls, _IR_ALBEDO["wall"]),
            (0, room.width, -1.0, walls, _IR_ALBEDO["wall"]),
            (1, 0.0, 1.0, walls, _IR_ALBEDO["wall"]),
            (1, room.depth, -1.0, walls, _IR_ALBEDO["wall"]),
        ]
        lo = np.array([0.0, 0.0, 0.0]) - 1e-6
        hi = np.array([room.width, room.depth, WALL_HEIGHT_M]) + 1e-6
        with np.errstate(divide="ignore", invalid="ignore"):
            for axis, coord, sign, rgb, ir_albedo in planes:
                t = (coord - o[axis]) / d[..., axis]
                hit = o + t[..., None] * d
                ok = (t > 1e-6) & np.all((hit >= lo) & (hit <= hi), axis=-1) & (t < depth)
                depth[ok] = t[ok]
                normal[ok] = 0.0
                normal[ok, axis] = sign
                albedo[ok] = rgb
                ir[ok] = ir_albedo
            for ob in room.obstacles:
                box_lo = np.array([ob.x0, ob.y0, 0.0])
                box_hi = np.array([ob.x1, ob.y1, ob.height])
                t0 = (box_lo - o) / d
                t1 = (box_hi - o) / d
                near = np.nanmax(np.minimum(t0, t1), axis=-1)
                far = np.nanmin(np.maximum(t0, t1), axis=-1)
                ok = (near <= far) & (near > 1e-6) & (near < depth)
                depth[ok] = near[ok]
                entry = np.argmax(np.minimum(t0, t1), axis=-1)
                sign = -np.sign(np.take_along_axis(d, entry[..., None], -1))
                n = np.zeros((h, w, 3))
                np.put_along_axis(n, entry[..., None], sign, -1)
                normal[ok] = n[ok]
                albedo[ok] = wood
                ir[ok] = _IR_ALBEDO["furniture"]
        cos = np.abs(np.einsum("hwk,hwk->hw", normal, d)) / np.linalg.norm(d, axis=-1)
        rgb = np.clip(self._shade(albedo, normal) * 255.0 + 0.5, 0, 255).astype(np.uint8)
        intensity = _intensity(ir, cos, depth * self._ray_norm)
        grazing = cos < (self.noise.grazing_cos if self.noise is not None else 0.0)
        return depth.astype(np.float32), rgb, intensity, grazing

    @staticmethod
    def _shade(albedo: np.ndarray, normal: np.ndarray) -> np.ndarray:
        """Ambient plus diffuse light from above, as an auto-exposed camera renders it.

        Float RGB in [0, 1]: a surface lit only by the ambient light (most of a standing
        body) reads at 0.8 of its albedo, so that clothes look as light or dark as they
        are (a white shirt light, a grey one grey); surfaces facing the light are
        brighter, up to saturation.
        """
        diffuse = np.clip(normal @ _LIGHT, 0.0, 1.0)
        return np.minimum(albedo * (0.8 + 0.35 * diffuse)[..., None], 1.0)

    # ------------------------------------------------------------------- people

    @staticmethod
    def body_parts(snap: Snapshot) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Ellipsoids of everyone's body: centres ``(n, 8, 3)``, axes ``(n, 8, 3, 3)``, radii.

        Axes are rotation matrices whose columns are the ellipsoid's principal directions
        in the world; radii are the semi-axis lengths along them.
        """
        n = len(snap)
        h = snap.height
        r = snap.radius
        speed = np.linalg.norm(snap.vel, axis=1) if n else np.zeros(0)
        facing = np.where(
            speed[:, None] > 0.05,
            snap.vel / np.maximum(speed, 1e-9)[:, None],
            np.column_stack([np.cos(snap.ids * 2.4), np.sin(snap.ids * 2.4)]),
        )
        fwd = np.column_stack([facing, np.zeros(n)])
        side = np.column_stack([-facing[:, 1], facing[:, 0], np.zeros(n)])
        up = np.tile([0.0, 0.0, 1.0], (n, 1))
        base = np.column_stack([snap.pos, np.zeros(n)])
        head_r = 0.045 * h + 0.03
        swing = 0.4 * np.clip(speed / 1.2, 0.0, 1.0) * np.sin(2 * np.pi * 1.7 * snap.t + snap.ids)
        centres = np.empty((n, _PARTS, 3))
        axes = np.empty((n, _PARTS, 3, 3))
        radii = np.empty((n, _PARTS, 3))
        upright = np.stack([fwd, side, up], axis=-1)  # columns: forward, side, up

        def limb(
            k: int, joint: np.ndarray, length: np.ndarray, thick: np.ndarray, angle: np.ndarray
        ) -> None:
            # A limb hanging from ``joint``, swung by ``angle`` about the side axis.
            direction = -np.cos(angle)[:, None] * up + np.sin(angle)[:, None] * fwd
            front = np.cos(angle)[:, None] * fwd + np.sin(angle)[:, None] * up
            centres[:, k] = joint + direction * (length / 2)[:, None]
            axes[:, k] = np.stack([front, side, -direction], axis=-1)
            radii[:, k] = np.column_stack([thick, thick, length / 2])

        centres[:, 0] = base + (h - head_r)[:, None] * up
        axes[:, 0] = upright
        radii[:, 0] = np.column_stack([head_r * 0.95, head_r * 0.85, head_r])
        torso_top = h - 2 * head_r - 0.02 * h
        torso_bottom = 0.5 * h
        centres[:, 1] = base + ((torso_top + torso_bottom) / 2)[:, None] * up
        axes[:, 1] = upright
        radii[:, 1] = np.column_stack([0.5 * r, 0.85 * r, (torso_top - torso_bottom) / 2])
        centres[:, 2] = base + (0.5 * h)[:, None] * up
        axes[:, 2] = upright
        radii[:, 2] = np.column_stack([0.48 * r, 0.75 * r, 0.07 * h])
        hip = base + (0.5 * h)[:, None] * up
        leg_len = 0.5 * h
        for k, sgn in ((3, 1.0), (4, -1.0)):
            limb(k, hip + side * (sgn * 0.38 * r)[:, None], leg_len, 0.32 * r, sgn * swing)
        shoulder = base + (torso_top - 0.04 * h)[:, None] * up
        for k, sgn in ((5, 1.0), (6, -1.0)):
            joint = shoulder + side * (sgn * (0.85 * r + 0.2 * r))[:, None]
            limb(k, joint, 0.36 * h, 0.2 * r, -sgn * swing)
        # the shoulder girdle: a flat span across the top of the torso to both arms
        centres[:, 7] = shoulder
        axes[:, 7] = upright
        radii[:, 7] = np.column_stack([0.42 * r, 1.2 * r, 0.035 * h])
        return centres, axes, radii

    def _part_box(
        self, centre: np.ndarray, axes: np.ndarray, radii: np.ndarray
    ) -> tuple[int, int, int, int] | None:
        """Pixel box ``(u0, u1, v0, v1)`` covering an ellipsoid; None when out of view."""
        corners = centre + (_CORNER_SIGNS * radii) @ axes.T
        return image_box(apply(self.camera_from_world, corners), self.intrinsics)

    # ------------------------------------------------------------------- render

    def render(self, snap: Snapshot, stamp: float = 0.0, seq: int = 0) -> RenderedFrame:
        """Render the world state ``snap`` as this sensor sees it."""
        k = self.intrinsics
        depth = self._static_depth.copy()
        labels = np.full((k.height, k.width), -1, dtype=np.int32)
        parts = np.full((k.height, k.width), -1, dtype=np.int8)
        rgb = self._static_rgb.copy()
        ir = self._static_ir.copy()
        grazing = self._static_grazing.copy()
        n = len(snap)
        body = np.zeros(n, dtype=np.int64)
        head = np.zeros(n, dtype=np.int64)
        if n:
            centres, axes, radii = self.body_parts(snap)
            top, bottom = snap.clothing()
            colours = np.stack(
                [
                    np.tile(_hsv_to_rgb(np.array(SKIN[0]), SKIN[1], SKIN[2]), (n, 1)),
                    _hsv_to_rgb(top[:, 0], top[:, 1], top[:, 2]),
                    _hsv_to_rgb(bottom[:, 0], bottom[:, 1], bottom[:, 2]),
                ],
                axis=1,
            )
            for i in range(n):
                body[i], head[i] = self._draw_person(
                    centres[i], axes[i], radii[i], colours[i], i,
                    depth, labels, parts, rgb, ir, grazing,
                )  # fmt: skip
        visible = np.bincount(labels[labels >= 0], minlength=n)[:n]
        head_visible = np.bincount(labels[parts == 0], minlength=n)[:n]
        measured = self._degrade(depth, grazing)
        frame = Frame(
            stamp=stamp, seq=seq, intrinsics=self.reports, depth=measured, color=rgb, intensity=ir
        )
        return RenderedFrame(frame, labels, snap.ids.copy(), visible, body, head_visible, head)

    def _draw_person(
        self,
        centres: np.ndarray,
        axes: np.ndarray,
        radii: np.ndarray,
        colours: np.ndarray,
        row: int,
        depth: np.ndarray,
        labels: np.ndarray,
        parts: np.ndarray,
        rgb: np.ndarray,
        ir: np.ndarray,
        grazing: np.ndarray,
    ) -> tuple[int, int]:
        """Z-buffer one person's ellipsoids into the images; return body and head pixels."""
        boxes = [self._part_box(centres[p], axes[p], radii[p]) for p in range(_PARTS)]
        present = [b for b in boxes if b is not None]
        head_pixels = 0
        if not present:
            return 0, 0
        bu0 = min(b[0] for b in present)
        bv0 = min(b[2] for b in present)
        person = np.zeros(
            (max(b[3] for b in present) - bv0, max(b[1] for b in present) - bu0), dtype=bool
        )
        o = self.origin
        noise = self.noise
        for p, box in enumerate(boxes):
            if box is None:
                continue
            u0, u1, v0, v1 = box
            rays = self._rays[v0:v1, u0:u1]
            to_unit = axes[p] / radii[p]  # world -> unit-sphere coordinates (columns scaled)
            oc = (o - centres[p]) @ to_unit
            dl = rays @ to_unit.astype(np.float32)
            a = np.einsum("hwk,hwk->hw", dl, dl)
            b = dl @ oc.astype(np.float32)
            disc = b * b - a * (float(oc @ oc) - 1.0)
            hit = disc > 0
            if not hit.any():
                continue
            t = np.where(hit, (-b - np.sqrt(np.maximum(disc, 0.0))) / a, np.inf)
            hit &= t > 0.05
            if p == 0:
                head_pixels = int(hit.sum())
            person[v0 - bv0 : v1 - bv0, u0 - bu0 : u1 - bu0] |= hit
            region = depth[v0:v1, u0:u1]
            front = hit & (t < region)
            if not front.any():
                continue
            tt = t[front]
            region[front] = tt
            labels[v0:v1, u0:u1][front] = row
            parts[v0:v1, u0:u1][front] = p
            normal = (oc + tt[:, None] * dl[front]) @ to_unit.T
            normal /= np.linalg.norm(normal, axis=1, keepdims=True)
            ray = rays[front]
            ray_len = np.linalg.norm(ray, axis=1)
            cos = np.abs(np.sum(normal * ray, axis=1)) / ray_len
            kind = _PART_KIND[p]
            albedo = np.broadcast_to(colours[kind], (len(tt), 3)).copy()
            if kind == _SKIN:
                albedo[normal[:, 2] > 0.35] = _HAIR
            rgb[v0:v1, u0:u1][front] = np.clip(self._shade(albedo, normal) * 255.0 + 0.5, 0, 255)
            ir_albedo = _IR_ALBEDO["skin" if kind == _SKIN else "cloth"]
            ir[v0:v1, u0:u1][front] = _intensity(ir_albedo, cos, tt * ray_len)
            if noise is not None:
                grazing[v0:v1, u0:u1][front] = cos < noise.grazing_cos
        return int(person.sum()), head_pixels

    def _degrade(self, depth: np.ndarray, grazing: np.ndarray) -> np.ndarray:
        """Apply the sensor type's noise, quantisation, range limits and lost readings."""
        kind = self.spec.type
        # Depth cameras limit the depth value (along the optical axis), not the range.
        invalid = ~np.isfinite(depth) | (depth < kind.min_range_m) | (depth > kind.max_range_m)
        out = depth
        noise = self.noise
        if noise is not None:
            s0, s1, s2 = noise.sigma
            z = np.nan_to_num(out, nan=0.0)
            sigma = s0 + s1 * z + s2 * z * z
            out = out + sigma * self.rng.standard_normal(out.shape, dtype=np.float32)
            if noise.disparity_step > 0:
                with np.errstate(divide="ignore", invalid="ignore"):
                    out = 1.0 / (np.round(1.0 / out / noise.disparity_step) * noise.disparity_step)
            else:
                out = np.round(out * 1000.0) / 1000.0
            invalid |= self.rng.random(out.shape, dtype=np.float32) < noise.dropout
            invalid |= grazing
            if noise.edge_jump_m > 0:
                filled = np.where(np.isfinite(depth), depth, 0.0)
                jump = np.zeros(out.shape, dtype=bool)
                dx = np.abs(np.diff(filled, axis=1)) > noise.edge_jump_m
                dy = np.abs(np.diff(filled, axis=0)) > noise.edge_jump_m
                jump[:, 1:] |= dx
                jump[:, :-1] |= dx
                jump[1:] |= dy
                jump[:-1] |= dy
                invalid |= jump & (self.rng.random(out.shape, dtype=np.float32) < 0.5)
        out[invalid] = np.nan
        return out
