"""People blobs on the floor: height-band points projected onto a grid, split at heads.

The points of the height band (in a floor-aligned frame, ``z`` = height above the floor)
fall into square cells of the floor. Occupied cells that touch (8-neighbourhood, with a
one-cell tolerance for sparse far-away returns) form connected components, as the
connected-component labelling of the childcare tracking paper (§2.1). Inside a component
every local maximum of the height map that reaches ``min_top_m`` is a head candidate;
candidates closer than ``heads_minimum_distance_m`` belong to one head (the taller wins),
so that people standing shoulder to shoulder become separate blobs while a person's
shoulders do not.
Each cell goes to its nearest head. A blob survives if it has enough points and its
footprint's width, length and area lie within the limits (Zhang et al., children
behavior tracking, Eq. 3).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage


@dataclass(frozen=True, slots=True)
class Blobs:
    """The blobs of one frame, as per-point labels and per-blob summaries.

    Parameters
    ----------
    labels : ndarray
        Blob index per input point, -1 for points in no blob.
    head_xy : ndarray
        ``(k, 2)`` mean floor position of each blob's head points.
    top : ndarray
        Highest point of each blob above the floor.
    points : ndarray
        Point count per blob.
    width, length, area : ndarray
        Footprint extents (metres) and area (square metres) per blob.
    """

    labels: np.ndarray
    head_xy: np.ndarray
    top: np.ndarray
    points: np.ndarray
    width: np.ndarray
    length: np.ndarray
    area: np.ndarray

    def __len__(self) -> int:
        return len(self.top)

    def select(self, keep: np.ndarray) -> Blobs:
        """The blobs where ``keep`` is true, renumbered from 0."""
        renumber = np.full(len(self.top) + 1, -1, dtype=np.int64)
        renumber[:-1][keep] = np.arange(int(np.count_nonzero(keep)))
        return Blobs(
            labels=renumber[self.labels],  # -1 maps to the last entry, -1
            head_xy=self.head_xy[keep],
            top=self.top[keep],
            points=self.points[keep],
            width=self.width[keep],
            length=self.length[keep],
            area=self.area[keep],
        )


def _empty(n: int) -> Blobs:
    z = np.zeros(0)
    return Blobs(np.full(n, -1, dtype=np.int64), np.zeros((0, 2)), z, z, z, z, z)


def _fill_holes(top: np.ndarray) -> np.ndarray:
    """The height map with single-cell holes filled (sparse far returns are not dips).

    An empty cell between two occupied opposite neighbours (in a row, a column or a
    diagonal) takes the lower of the two; wider gaps stay empty and occupied cells keep
    their height, so the dip between two close heads is not bridged.
    """
    p = np.pad(top, 1, constant_values=-np.inf)
    rows, cols = top.shape
    bridged = np.full(top.shape, -np.inf)
    for (a0, b0), (a1, b1) in (
        ((0, 1), (2, 1)),
        ((1, 0), (1, 2)),
        ((0, 0), (2, 2)),
        ((0, 2), (2, 0)),
    ):
        across = np.minimum(p[a0 : a0 + rows, b0 : b0 + cols], p[a1 : a1 + rows, b1 : b1 + cols])
        bridged = np.maximum(bridged, across)
    return np.where(np.isfinite(top), top, bridged)


def _across(i: int, j: int, foot: np.ndarray) -> np.ndarray | None:
    """Unit vector across the line of sight at cell ``(i, j)`` (None right below the sensor)."""
    ray = np.array([i, j], dtype=float) - foot
    norm = float(np.hypot(*ray))
    return None if norm < 1.0 else np.array([-ray[1], ray[0]]) / norm


class HeadClusterer:
    """Clusters floor-frame points into person blobs.

    Parameters
    ----------
    cell_m : float
        Grid cell size.
    heads_minimum_distance_m : float
        Heads closer than this are one person.
    min_top_m : float
        A head must be at least this high.
    max_height_m : float
        Top of the height band: blobs cut by it (walls, tall furniture, people taller
        than the band) are not detections.
    min_points : int
        Fewest points of a blob.
    min_size_m, max_size_m : float
        Footprint width and length limits.
    min_area_m2, max_area_m2 : float
        Footprint area limits.
    """

    CAP_DEPTH_M = 0.06
    """Depth of the cap below a peak that must stay as small as a head."""
    CAP_REACH_M = 0.3
    """Farthest a head's cap may reach from its peak."""
    CROWN_CELLS_FACTOR = 1.5
    """A cap of more cells than this many head crowns is a head only with shoulders
    :attr:`CAP_DEPTH_M` below it."""
    SHOULDER_DROP_M = 0.10
    """Least depth, below a crown-like cap, of what is seen around it at shoulder reach.

    From the top of the head to the shoulders is about 0.3 m in adults (stature minus
    acromial height in anthropometric surveys such as ANSUR) and about 0.2 m in small
    children, whose heads are larger for their size; half the smaller figure allows
    for a slouch and a raised shoulder. The top edge of a board or the front edge of a
    shelf seen over people's heads is level with its surroundings."""
    CAP_LINE_M = 0.3
    """A cap longer than this ..."""
    CAP_ELONGATION = 2.5
    """... and this many times longer than wide is a line (a board's top edge)."""
    LINE_MIN_CELLS = 7
    """Fewer cap cells are not judged a line: a low-resolution sensor's single image row
    across a far head makes a short line of a few cells."""
    HEAD_BREADTH_M = 0.17
    """Broadest head: head breadth is about 0.155-0.16 m on average in adult men and
    under 0.17 m in all but the largest (anthropometric surveys such as ANSUR II)."""
    LEVEL_CELLS_FACTOR = 3.0
    """Cells at a peak's level within twice the cap reach, in head crowns (0.12 m radius)."""
    PROMINENCE_M = 0.15
    """Between two people's heads the height map dips at least this much."""
    ABOVE_HEAD_M = 0.05
    """Cells higher than their nearest head by more than this are not that person's."""
    SHOULDER_REACH_M = 0.36
    """Farthest a shoulder's or raised arm's peak stands from its own head."""
    FAR_PROMINENCE_M = 0.06
    """Dip enough between peaks farther apart than :attr:`SHOULDER_REACH_M`."""
    GAP_CELLS = 2
    """Longest run of empty cells between two peaks that is not itself a gap between people."""

    CUT_MARGIN_M = 0.08
    """A blob whose top is this close to the top of the band was cut by it."""

    def __init__(
        self,
        *,
        cell_m: float = 0.06,
        heads_minimum_distance_m: float = 0.3,
        min_top_m: float = 1.3,
        max_height_m: float = 2.3,
        min_points: int = 20,
        min_size_m: float = 0.06,
        max_size_m: float = 1.0,
        min_area_m2: float = 0.008,
        max_area_m2: float = 0.8,
    ) -> None:
        self.cell_m = cell_m
        self.heads_minimum_distance_m = heads_minimum_distance_m
        self.min_top_m = min_top_m
        self.max_height_m = max_height_m
        self.min_points = min_points
        self.min_size_m = min_size_m
        self.max_size_m = max_size_m
        self.min_area_m2 = min_area_m2
        self.max_area_m2 = max_area_m2
        # Local-maximum window: about half the head spacing on each side.
        half = max(1, round(0.5 * heads_minimum_distance_m / cell_m))
        self._window = 2 * half + 1
        # Cells closer than about twice the cell size belong together (OpenPTrack's
        # cluster tolerance is twice its voxel): bridges layered or sparse far returns.
        self._bridge = np.ones((5, 5), bool)

    def cluster(self, xyz: np.ndarray) -> Blobs:
        """Blobs of ``(n, 3)`` points ``(x, y, height)`` in a floor-aligned frame.

        The frame's origin is the sensor's foot (the point of the floor below it), so
        that the line of sight to every cell is known.
        """
        n = len(xyz)
        if n < self.min_points:
            return _empty(n)
        cell = self.cell_m
        lo = xyz[:, :2].min(axis=0) - cell
        ij = ((xyz[:, :2] - lo) / cell).astype(np.int64)
        rows, cols = int(ij[:, 0].max()) + 2, int(ij[:, 1].max()) + 2
        lin = ij[:, 0] * cols + ij[:, 1]
        h = xyz[:, 2]
        order = np.argsort(h)
        top = np.full(rows * cols, -np.inf)
        top[lin[order]] = h[order]  # last write wins: the highest point of each cell
        top = top.reshape(rows, cols)
        occupied = np.isfinite(top)
        components, count = ndimage.label(
            ndimage.binary_dilation(occupied, self._bridge), np.ones((3, 3), int)
        )
        components[~occupied] = 0
        if count == 0:
            return _empty(n)
        peaks = occupied & (top >= self.min_top_m)
        peaks &= top == ndimage.maximum_filter(
            top, size=self._window, mode="constant", cval=-np.inf
        )
        cell_blob = self._assign_heads(top, components, peaks, -lo / cell - 0.5)
        point_blob = cell_blob.ravel()[lin]
        return self._summarise(xyz, point_blob, cell_blob)

    def _assign_heads(
        self, top: np.ndarray, components: np.ndarray, peaks: np.ndarray, foot: np.ndarray
    ) -> np.ndarray:
        """Blob index per cell (-1 for none): each component split among its heads.

        ``foot`` is the sensor's foot in cell coordinates.
        """
        cell = self.cell_m
        pi, pj = np.nonzero(peaks)
        out = np.full(top.shape, -1, dtype=np.int64)
        if len(pi) == 0:
            return out
        comp = components[pi, pj]
        height = top[pi, pj]
        # Greedy head selection within each component, tallest first.
        order = np.lexsort((-height, comp))
        pi, pj, comp, height = pi[order], pj[order], comp[order], height[order]
        heads: list[tuple[int, int, int]] = []  # (component, i, j)
        # single-cell holes of sparse far returns are not dips
        filled = _fill_holes(top)
        min_d2 = (self.heads_minimum_distance_m / cell) ** 2
        start = 0
        for end in np.append(np.flatnonzero(np.diff(comp)) + 1, len(comp)):
            kept: list[tuple[int, int]] = []
            for k in range(start, end):
                i, j = int(pi[k]), int(pj[k])
                if all(
                    (i - a) ** 2 + (j - b) ** 2 >= min_d2 and self._dips(filled, (a, b), (i, j))
                    for a, b in kept
                ):
                    kept.append((i, j))
            heads.extend((int(comp[start]), a, b) for a, b in kept)
            start = end
        head_comp = np.array([c for c, _, _ in heads])
        head_ij = np.array([(a, b) for _, a, b in heads], dtype=float)
        rounded = np.array(
            [self._is_head(filled, int(a), int(b), _across(a, b, foot)) for _, a, b in heads]
        )
        ci, cj = np.nonzero(components > 0)
        cc = components[ci, cj]
        # Nearest head of the same component for every cell.
        d2 = (ci[:, None] - head_ij[None, :, 0]) ** 2 + (cj[:, None] - head_ij[None, :, 1]) ** 2
        d2[cc[:, None] != head_comp[None, :]] = np.inf
        best = np.argmin(d2, axis=1)
        has = np.isfinite(d2[np.arange(len(ci)), best]) & rounded[best]
        # nothing of a person stands above their head (a cupboard beside them does)
        head_top = top[head_ij[:, 0].astype(int), head_ij[:, 1].astype(int)]
        has &= top[ci, cj] <= head_top[best] + self.ABOVE_HEAD_M
        # nor farther from it than half the largest footprint (furniture they lean on)
        reach = 0.5 * self.max_size_m / cell
        has &= d2[np.arange(len(ci)), best] <= reach * reach
        out[ci[has], cj[has]] = best[has]
        return out

    def _dips(self, top: np.ndarray, head: tuple[int, int], other: tuple[int, int]) -> bool:
        """Whether the height map dips between a head and a lower peak (two people).

        A shoulder or a raised arm rises towards its own head without a dip; between two
        people the surface drops at least :attr:`PROMINENCE_M` below the lower peak.
        Only observed cells count: empty cells on the way are unseen (hidden behind the
        head, say), not low — unless the gap is wider than :attr:`GAP_CELLS` cells.
        Peaks farther apart than twice the head distance are always separate.
        """
        di, dj = other[0] - head[0], other[1] - head[1]
        if (di * di + dj * dj) * self.cell_m**2 > (2 * self.heads_minimum_distance_m) ** 2:
            return True
        steps = max(abs(di), abs(dj)) + 1
        f = np.linspace(0.0, 1.0, steps + 1)[1:-1]
        ii = np.rint(head[0] + f * di).astype(int)
        jj = np.rint(head[1] + f * dj).astype(int)
        line = top[ii, jj]
        seen = np.isfinite(line)
        if not seen.all():
            gap = np.diff(np.flatnonzero(np.concatenate(([True], seen, [True])))).max() - 1
            if gap > self.GAP_CELLS:
                return True
        saddle = line[seen].min() if seen.any() else np.inf
        # a shoulder stands at most about SHOULDER_REACH_M from its head; beyond, a
        # shallower dip is enough (side by side, shoulders overlap between the heads)
        far = (di * di + dj * dj) * self.cell_m**2 > self.SHOULDER_REACH_M**2
        prominence = self.FAR_PROMINENCE_M if far else self.PROMINENCE_M
        return bool(saddle < top[other] - prominence)

    def _cap_shape(self, ci: np.ndarray, cj: np.ndarray, across: np.ndarray | None = None) -> str:
        """``line``, ``large`` or ``crown``: what the cap's cells look like.

        A line (of at least :attr:`LINE_MIN_CELLS` cells) has a long axis over
        :attr:`CAP_LINE_M` and :attr:`CAP_ELONGATION` times its short one (the top edge
        of a board, a shelf's front seen between people); so is a cap wider across the
        line of sight (``across``, a unit vector in cell axes) than a head can be: a
        head of :attr:`HEAD_BREADTH_M` straddles at most ``int(breadth / cell) + 2``
        cells (four of 0.06 m), and one more is allowed for the pixel footprint.
        Depth noise stretches a cap along the line of sight only, so its width across
        it is measured clean. A large cap has more cells than
        :attr:`CROWN_CELLS_FACTOR` head crowns (0.12 m radius); anything else is the
        size and shape of a head's crown.
        """
        if across is not None:
            width = ci * across[0] + cj * across[1]
            if np.ptp(width) + 1 > int(self.HEAD_BREADTH_M / self.cell_m) + 3:
                return "line"
        if len(ci) >= self.LINE_MIN_CELLS:
            cov = np.cov(np.vstack([ci, cj]).astype(float))
            small, large = np.sqrt(12 * np.maximum(np.linalg.eigvalsh(cov), 0)) + 1
            if large * self.cell_m > self.CAP_LINE_M and large > self.CAP_ELONGATION * small:
                return "line"
        if len(ci) > self.CROWN_CELLS_FACTOR * np.pi * (0.12 / self.cell_m) ** 2:
            return "large"
        return "crown"

    def _is_head(self, top: np.ndarray, i: int, j: int, across: np.ndarray | None = None) -> bool:
        """Whether a height peak is a head's crown rather than a flat or long top.

        The cap of a head — the connected cells within :attr:`CAP_DEPTH_M` of the peak —
        is about as wide as a head; the cap of a wall, a table or a cabinet runs on. A
        line never is a head. What is seen in the ring 0.15-0.3 m around the peak (the
        shoulders') tells the rest: a crown-like cap (:meth:`_cap_shape`) up to
        :attr:`CAP_REACH_M` from the peak is a head unless that ring lies, by its median,
        less than :attr:`SHOULDER_DROP_M` below the peak (the top edge of a board or a
        shelf seen over people is level with its surroundings; a ring with nothing seen
        in it, a body hidden below the head, says nothing); a larger cap, or one up to
        twice that far (depth noise blurs far heads into their shoulders), is a head
        only if the ring lies :attr:`CAP_DEPTH_M` lower; anything larger is not a head;
        nor is a peak with many cells at its level around it (more than
        :attr:`LEVEL_CELLS_FACTOR` head crowns).
        ``top`` has single-cell holes filled; ``across`` is the unit vector across the
        line of sight at the peak, in cell axes (None: not known).
        """
        reach = self.CAP_REACH_M / self.cell_m
        span = int(np.ceil(2 * reach)) + 1
        i0, j0 = max(i - span, 0), max(j - span, 0)
        window = top[i0 : i + span + 1, j0 : j + span + 1]
        peak = top[i, j]
        cap, _ = ndimage.label(window >= peak - self.CAP_DEPTH_M, np.ones((3, 3), int))
        ci, cj = np.nonzero(cap == cap[i - i0, j - j0])
        di, dj = np.arange(window.shape[0])[:, None] + i0 - i, np.arange(window.shape[1]) + j0 - j
        d2 = di * di + dj * dj
        far = float(d2[ci, cj].max())
        # Many cells at the peak's level around it, connected or not, are a flat top
        # broken up by occlusion (a plinth behind a visitor), not a head.
        level = (np.abs(window - peak) <= self.CAP_DEPTH_M) & (d2 <= 4 * reach * reach)
        if np.count_nonzero(level) > self.LEVEL_CELLS_FACTOR * np.pi * (0.12 / self.cell_m) ** 2:
            return False
        shape = self._cap_shape(ci, cj, across)
        if shape == "line":
            return False
        if far > 4 * reach * reach:
            return False
        r1 = 0.5 * self.heads_minimum_distance_m / self.cell_m
        r2 = self.heads_minimum_distance_m / self.cell_m
        ring = (d2 >= r1 * r1) & (d2 <= r2 * r2) & np.isfinite(window) & (window <= peak)
        drop = peak - np.median(window[ring]) if ring.any() else None
        if far <= reach * reach and shape == "crown":
            # nothing seen around it (a body hidden below the head) says nothing
            return drop is None or drop > self.SHOULDER_DROP_M
        return drop is not None and drop > self.CAP_DEPTH_M

    def _summarise(self, xyz: np.ndarray, point_blob: np.ndarray, cell_blob: np.ndarray) -> Blobs:
        """Per-blob statistics, then the size tests; blobs renumbered from 0."""
        k = int(cell_blob.max()) + 1 if cell_blob.size else 0
        if k == 0:
            return _empty(len(xyz))
        member = point_blob >= 0
        b = point_blob[member]
        x, y, h = xyz[member, 0], xyz[member, 1], xyz[member, 2]
        count = np.bincount(b, minlength=k).astype(float)
        safe = np.maximum(count, 1.0)
        mx, my = np.bincount(b, x, k) / safe, np.bincount(b, y, k) / safe
        top = np.full(k, -np.inf)
        np.maximum.at(top, b, h)
        top[count == 0] = 0.0
        head_band = 0.12 * top + 0.02
        in_head = h >= (top - head_band)[b]
        head_n = np.maximum(np.bincount(b[in_head], minlength=k), 1)
        hx = np.bincount(b[in_head], x[in_head], k) / head_n
        hy = np.bincount(b[in_head], y[in_head], k) / head_n
        dx, dy = x - mx[b], y - my[b]
        sxx = np.bincount(b, dx * dx, k) / safe
        syy = np.bincount(b, dy * dy, k) / safe
        sxy = np.bincount(b, dx * dy, k) / safe
        mean = (sxx + syy) / 2
        spread = np.sqrt(((sxx - syy) / 2) ** 2 + sxy**2)
        # extent of a uniform spread with this variance, plus one cell
        length = np.sqrt(12 * np.maximum(mean + spread, 0)) + self.cell_m
        width = np.sqrt(12 * np.maximum(mean - spread, 0)) + self.cell_m
        area = np.bincount(cell_blob[cell_blob >= 0], minlength=k) * self.cell_m**2
        keep = (
            (count >= self.min_points)
            & (top >= self.min_top_m)
            & (top < self.max_height_m - self.CUT_MARGIN_M)
            & (width >= self.min_size_m)
            & (length <= self.max_size_m)
            & (area >= self.min_area_m2)
            & (area <= self.max_area_m2)
        )
        renumber = np.full(k, -1, dtype=np.int64)
        renumber[keep] = np.arange(int(keep.sum()))
        labels = np.full(len(xyz), -1, dtype=np.int64)
        labels[member] = renumber[b]
        return Blobs(
            labels=labels,
            head_xy=np.column_stack([hx, hy])[keep],
            top=top[keep],
            points=count[keep],
            width=width[keep],
            length=length[keep],
            area=area[keep],
        )
