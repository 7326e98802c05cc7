"""People detector and RGB-D renderer cost per frame on one core (Kinect v2, 512 x 424).

Frames: the ``crowd`` scenario (7 adults, seed 0) and the ``classroom`` scenario (a
teacher and 18 children, seed 0), every sensor turned into a Kinect v2 and rendered by
``DepthRenderer`` with its depth noise, at ``FRAMES`` instants 0.5 s apart (so the frames
cover people all over each view). Rendering happens before any detector timing; each
``render`` call is timed on its own (the world's motion is not included).

Detector: one ``PeopleDetector`` per sensor (its pose given, default ``DetectorConfig``;
for ``classroom`` the ``child`` preset with ``max_height_m=2.3``, as the detector
evaluation uses). Its first frame, where the ground RANSAC runs (and the ray table is
built), is timed alone as ``ground_init_ms``; then ``detect`` is timed over all the
sensor's frames ``PASSES`` times. Per sensor and pooled over the three sensors: p50, p95
and mean milliseconds per frame, frames per second (``1 / p50`` and ``1 / mean``) and the
mean milliseconds of each stage (``DetectionResult.timings``; a stage that did not run
counts 0, so the stages plus ``overhead`` add up to the mean). ``meets_target``: every
sensor's ``1 / mean`` reaches ``TARGET_FPS``.

HOG check (crowd only, one pass): per sensor, three detectors (HOG off,
``HogConfig(enabled=True, image="color")``, ``image="ir"``) each see every frame in turn,
so load from other processes falls on all three alike; ``over_no_hog`` is the mean time
with HOG over the mean without. ``ms_per_detection`` is the ``hog`` stage's time over the
boxes it scored (the detections the HOG-less detector found in the same frame: the three
see the same frames in the same order with the same RANSAC seed, so their blobs are the
same). Split further with ``HogVerifier`` alone: ``image_prep_*_ms`` (luminance test
and grey conversion, or infrared equalisation, of the whole image) and
``score_ms_per_box``. When the installed OpenCV has no ``HOGDescriptor`` (OpenCV 5 moved
it out of the main package), ``hog_crowd`` says so instead.

Renderer: milliseconds per frame and frames per second for Kinect v2 (both scenarios,
from the pre-rendering above) and for ``kinect1``, ``realsense`` and ``sr4500`` (crowd,
``OTHER_TYPE_FRAMES`` frames per sensor); the simulated sensors must run at
``RENDER_TARGET_FPS``. ``setup_ms`` is the one-off cast of the empty room per sensor.

Baselines, same run: ``backprojection_full_ms`` multiplies a full 512 x 424 float32 depth
image by its cached rays (``rays * depth[..., None]``, the least any per-pixel detector
pays); ``backprojection_step2_ms`` does the same on every second pixel in each direction,
as the detector's ``cloud`` stage does with the default ``sampling_factor`` of 2. Ratios:
detector mean over each baseline, and detector mean over the renderer's mean.

Single thread: ``OMP_NUM_THREADS``, ``OPENBLAS_NUM_THREADS``, ``MKL_NUM_THREADS`` default
to 1 at the top of this module, before numpy is imported; ``single_thread_env_effective``
says whether that happened before numpy was loaded (under ``benchmarks.run_all`` it is
already loaded, so export the variables in the shell, as ``make bench`` does).

Prints one JSON line (milliseconds unless named otherwise).

Run from the repository root::

    python -m benchmarks.bench_detector [--frames N] [--passes N]
"""

# ruff: noqa: E402  (the thread variables must be set before numpy is imported)

from __future__ import annotations

import os
import sys

_NUMPY_PRELOADED = "numpy" in sys.modules
_THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
for _var in _THREAD_VARS:
    os.environ.setdefault(_var, "1")

import argparse
import gc
import time

import numpy as np

from benchmarks.common import emit, per_call_us
from openptrack_py.config import DetectorConfig, HogConfig
from openptrack_py.detection.frame import Frame
from openptrack_py.detection.hog import HogVerifier, equalised_ir, luminance
from openptrack_py.detection.pipeline import STAGES, PeopleDetector
from openptrack_py.errors import ConfigError
from openptrack_py.eval.detector import scenario_for_sensor_type
from openptrack_py.geometry import world_from_optical
from openptrack_py.sim.render import DepthRenderer
from openptrack_py.sim.scenarios import Scenario, scenario_world
from openptrack_py.sim.world import Snapshot

SEED = 0
FRAMES = 60
PASSES = 5
SPACING_S = 0.5
TARGET_FPS = 60.0
RENDER_TARGET_FPS = 15.0
OTHER_TYPES = ("kinect1", "realsense", "sr4500")
OTHER_TYPE_FRAMES = 10
CLASSROOM_CHILDREN = 18


def scenario(name: str, sensor_type: str, **options: int) -> Scenario:
    """``name`` with its own sensor layout, every sensor turned into ``sensor_type``."""
    return scenario_for_sensor_type(name, SEED, sensor_type, None, **options)


def snapshots(sc: Scenario, frames: int) -> list[Snapshot]:
    """World states at ``frames`` instants ``SPACING_S`` apart."""
    world = scenario_world(sc)
    return [world.state_at((k + 1) * SPACING_S) for k in range(frames)]


def render_all(sc: Scenario, snaps: list[Snapshot]) -> dict[str, object]:
    """Every sensor's frames, the time of each render call and the renderers' setup time."""
    frames: dict[str, list[Frame]] = {}
    render_s: list[float] = []
    setup_s: list[float] = []
    for i, spec in enumerate(sc.sensors):
        start = time.perf_counter()
        renderer = DepthRenderer(spec, sc.room, np.random.default_rng([SEED, 31, i]))
        setup_s.append(time.perf_counter() - start)
        out = []
        for k, snap in enumerate(snaps):
            start = time.perf_counter()
            shot = renderer.render(snap, stamp=snap.t, seq=k)
            render_s.append(time.perf_counter() - start)
            out.append(shot.frame)
        frames[spec.id] = out
    return {"frames": frames, "render_s": render_s, "setup_s": setup_s}


def ms_stats(seconds: list[float] | np.ndarray) -> dict[str, float]:
    """p50, p95 and mean milliseconds, and frames per second from p50 and from the mean."""
    ms = 1e3 * np.asarray(seconds, dtype=float)
    p50, mean = float(np.median(ms)), float(ms.mean())
    return {
        "p50_ms": round(p50, 3),
        "p95_ms": round(float(np.percentile(ms, 95)), 3),
        "mean_ms": round(mean, 3),
        "fps_median": round(1e3 / p50, 1),
        "fps_mean": round(1e3 / mean, 1),
        "n": len(ms),
    }


def stage_means(timings: list[dict[str, float]], total_s: list[float]) -> dict[str, float]:
    """Mean milliseconds per frame of each stage that ran at all, and the rest."""
    out = {}
    for name in STAGES:
        values = [t.get(name, 0.0) for t in timings]
        if any(name in t for t in timings):
            out[name] = round(1e3 * float(np.mean(values)), 3)
    staged = sum(sum(t.values()) for t in timings) / len(timings)
    out["overhead"] = round(1e3 * (float(np.mean(total_s)) - staged), 3)
    return out


def make_detector(
    sc: Scenario, index: int, config: DetectorConfig, sensor_type: str
) -> PeopleDetector:
    spec = sc.sensors[index]
    return PeopleDetector(
        config,
        world_from_camera=world_from_optical(spec.pose),
        sensor_type=sensor_type,
        rng=np.random.default_rng([SEED, 37, index]),
    )


def run_detector(detector: PeopleDetector, frames: list[Frame], passes: int) -> dict[str, object]:
    """Time the first frame alone, then ``passes`` passes over all ``frames``."""
    start = time.perf_counter()
    first = detector.detect(frames[0])
    init_s = time.perf_counter() - start
    gc.collect()
    total_s: list[float] = []
    timings: list[dict[str, float]] = []
    counts: list[int] = []
    for _ in range(passes):
        for frame in frames:
            start = time.perf_counter()
            result = detector.detect(frame)
            total_s.append(time.perf_counter() - start)
            timings.append(result.timings)
            counts.append(len(result.detections))
    return {
        "init_s": init_s,
        "init_ground_s": first.timings.get("ground", 0.0),
        "total_s": total_s,
        "timings": timings,
        "counts": counts,
        "ground_estimates": detector.ground.estimates,
        "plane_source": detector.ground.plane.source if detector.ground.plane else None,
    }


def detector_figures(
    sc: Scenario, frames: dict[str, list[Frame]], config: DetectorConfig, passes: int
) -> dict[str, object]:
    """Per-sensor and pooled detector figures."""
    per_sensor: dict[str, object] = {}
    pooled_s: list[float] = []
    pooled_t: list[dict[str, float]] = []
    fps_means = []
    for i, spec in enumerate(sc.sensors):
        run = run_detector(make_detector(sc, i, config, "kinect2"), frames[spec.id], passes)
        stats = ms_stats(run["total_s"])
        fps_means.append(stats["fps_mean"])
        per_sensor[spec.id] = {
            **stats,
            "ground_init_ms": round(1e3 * run["init_s"], 3),
            "ground_init_ransac_ms": round(1e3 * run["init_ground_s"], 3),
            "ground_estimates": run["ground_estimates"],
            "plane_source": run["plane_source"],
            "detections_per_frame": round(float(np.mean(run["counts"])), 2),
            "stages_mean_ms": stage_means(run["timings"], run["total_s"]),
        }
        pooled_s += run["total_s"]
        pooled_t += run["timings"]
    pooled = {
        **ms_stats(pooled_s),
        "stages_mean_ms": stage_means(pooled_t, pooled_s),
        "target_fps": TARGET_FPS,
        "meets_target": min(fps_means) >= TARGET_FPS,
    }
    return {"all_sensors": pooled, "sensors": per_sensor}


def hog_missing() -> str | None:
    """Why the HOG check cannot run here (None when it can)."""
    try:
        HogVerifier()
    except (AttributeError, ConfigError) as exc:
        import cv2

        return f"opencv {cv2.__version__}: {type(exc).__name__}: {exc}"
    return None


def hog_figures(sc: Scenario, frames: dict[str, list[Frame]]) -> dict[str, object]:
    """Detector cost without HOG and with it on colour and on infrared, interleaved."""
    configs = {
        "off": DetectorConfig(),
        "color": DetectorConfig(hog=HogConfig(enabled=True, image="color")),
        "ir": DetectorConfig(hog=HogConfig(enabled=True, image="ir")),
    }
    total_s: dict[str, list[float]] = {m: [] for m in configs}
    hog_s = dict.fromkeys(configs, 0.0)
    kept = dict.fromkeys(configs, 0)
    modes: dict[str, dict[str, int]] = {m: {} for m in configs}
    for i, spec in enumerate(sc.sensors):
        detectors = {m: make_detector(sc, i, c, "kinect2") for m, c in configs.items()}
        for detector in detectors.values():
            detector.detect(frames[spec.id][0])
        gc.collect()
        for frame in frames[spec.id]:
            for m, detector in detectors.items():
                start = time.perf_counter()
                result = detector.detect(frame)
                total_s[m].append(time.perf_counter() - start)
                hog_s[m] += result.timings.get("hog", 0.0)
                kept[m] += len(result.detections)
                modes[m][result.hog] = modes[m].get(result.hog, 0) + 1
    scored = kept["off"]
    off = ms_stats(total_s["off"])
    out: dict[str, object] = {"off": off}
    for m in ("color", "ir"):
        stats = ms_stats(total_s[m])
        out[m] = {
            **stats,
            "hog_stage_mean_ms": round(1e3 * hog_s[m] / len(total_s[m]), 3),
            "ms_per_detection": round(1e3 * hog_s[m] / max(scored, 1), 3),
            "boxes_scored": scored,
            "kept_share": round(kept[m] / max(scored, 1), 3),
            "modes": modes[m],
            "over_no_hog": round(stats["mean_ms"] / off["mean_ms"], 3),
            "meets_target": stats["fps_mean"] >= TARGET_FPS,
        }
    return out


def hog_parts(frames: list[Frame], boxes: list[tuple[int, int, int, int]]) -> dict[str, float]:
    """``HogVerifier`` alone: whole-image preparation per frame, scoring per box."""
    hog = HogVerifier()
    rgb = frames[0].color
    colour = per_call_us(lambda: (luminance(rgb), hog.gray(rgb)), repeat=5, number=50)
    ir = per_call_us(lambda: equalised_ir(frames[0].intensity), repeat=5, number=50)
    gray = hog.gray(rgb)
    start = time.perf_counter()
    for _ in range(3):
        hog.score(gray, boxes)
    per_box = (time.perf_counter() - start) / (3 * max(len(boxes), 1))
    return {
        "image_prep_color_ms": round(colour / 1e3, 4),
        "image_prep_ir_ms": round(ir / 1e3, 4),
        "score_ms_per_box": round(1e3 * per_box, 4),
        "boxes": len(boxes),
    }


def boxes_of(sc: Scenario, frames: dict[str, list[Frame]]) -> list[tuple[int, int, int, int]]:
    """Image boxes of the HOG-less detections in the first sensor's frames."""
    spec = sc.sensors[0]
    detector = make_detector(sc, 0, DetectorConfig(), "kinect2")
    out = []
    for frame in frames[spec.id]:
        out += [d.bbox for d in detector.detect(frame).detections]
    return out


def render_figures(render_s: list[float], setup_s: list[float]) -> dict[str, object]:
    stats = ms_stats(render_s)
    return {
        **stats,
        "setup_ms": round(1e3 * float(np.mean(setup_s)), 1),
        "target_fps": RENDER_TARGET_FPS,
        "meets_target": stats["fps_mean"] >= RENDER_TARGET_FPS,
    }


def other_renderers(frames: int) -> dict[str, object]:
    out: dict[str, object] = {}
    for kind in OTHER_TYPES:
        sc = scenario("crowd", kind)
        shots = render_all(sc, snapshots(sc, frames))
        first = next(iter(shots["frames"].values()))[0]
        k = first.intrinsics
        out[kind] = {
            "image": f"{k.width}x{k.height}",
            **render_figures(shots["render_s"], shots["setup_s"]),
        }
    return out


def backprojection(frame: Frame) -> dict[str, float]:
    """Depth times cached rays: the whole image, and every second pixel each way."""
    k = frame.intrinsics
    u = (np.arange(k.width) - k.cx) / k.fx
    v = (np.arange(k.height) - k.cy) / k.fy
    rays = np.empty((k.height, k.width, 3), dtype=np.float32)
    rays[..., 0] = u[None, :]
    rays[..., 1] = v[:, None]
    rays[..., 2] = 1.0
    depth = np.nan_to_num(frame.depth, nan=0.0).astype(np.float32)
    half_rays = np.ascontiguousarray(rays[::2, ::2])
    full = per_call_us(lambda: rays * depth[..., None], repeat=5, number=100)
    step2 = per_call_us(lambda: half_rays * depth[::2, ::2, None], repeat=5, number=200)
    return {"backprojection_full_ms": full / 1e3, "backprojection_step2_ms": step2 / 1e3}


def main(frames: int = FRAMES, passes: int = PASSES) -> dict[str, object]:
    wall = time.perf_counter()
    crowd = scenario("crowd", "kinect2")
    crowd_snaps = snapshots(crowd, frames)
    crowd_shots = render_all(crowd, crowd_snaps)
    crowd_det = detector_figures(crowd, crowd_shots["frames"], DetectorConfig(), passes)
    missing = hog_missing()
    if missing is None:
        hog: dict[str, object] = {
            "available": True,
            **hog_figures(crowd, crowd_shots["frames"]),
            "verifier_alone": hog_parts(
                crowd_shots["frames"][crowd.sensors[0].id], boxes_of(crowd, crowd_shots["frames"])
            ),
        }
    else:
        hog = {"available": False, "reason": missing}
    base = backprojection(crowd_shots["frames"][crowd.sensors[0].id][0])
    renderer = {
        "kinect2_crowd": render_figures(crowd_shots["render_s"], crowd_shots["setup_s"]),
    }
    del crowd_shots
    gc.collect()

    classroom = scenario("classroom", "kinect2", children=CLASSROOM_CHILDREN)
    class_snaps = snapshots(classroom, frames)
    class_shots = render_all(classroom, class_snaps)
    class_config = DetectorConfig(preset="child", max_height_m=2.3)
    class_det = detector_figures(classroom, class_shots["frames"], class_config, passes)
    renderer["kinect2_classroom"] = render_figures(class_shots["render_s"], class_shots["setup_s"])
    del class_shots
    gc.collect()

    renderer.update(other_renderers(OTHER_TYPE_FRAMES))

    det_ms = crowd_det["all_sensors"]["mean_ms"]
    ratios = {
        "detector_over_renderer_crowd": round(det_ms / renderer["kinect2_crowd"]["mean_ms"], 3),
        "detector_over_renderer_classroom": round(
            class_det["all_sensors"]["mean_ms"] / renderer["kinect2_classroom"]["mean_ms"], 3
        ),
        "detector_over_backprojection_full": round(det_ms / base["backprojection_full_ms"], 1),
        "detector_over_backprojection_step2": round(det_ms / base["backprojection_step2_ms"], 1),
        "cloud_stage_over_backprojection_step2": round(
            crowd_det["all_sensors"]["stages_mean_ms"]["cloud"] / base["backprojection_step2_ms"],
            2,
        ),
    }
    if missing is None:
        ratios["hog_color_over_no_hog"] = hog["color"]["over_no_hog"]
        ratios["hog_ir_over_no_hog"] = hog["ir"]["over_no_hog"]
    return emit(
        "detector",
        {
            "image": "512x424 (kinect2)",
            "frames_per_sensor": frames,
            "passes": passes,
            "frame_spacing_s": SPACING_S,
            "single_thread_env_effective": not _NUMPY_PRELOADED
            and all(os.environ[v] == "1" for v in _THREAD_VARS),
            "crowd": {"people": len(crowd_snaps[-1]), **crowd_det},
            "classroom": {
                "people": len(class_snaps[-1]),
                "preset": "child, max_height_m 2.3",
                **class_det,
            },
            "hog_crowd": hog,
            "renderer": renderer,
            "baseline": {k: round(v, 4) for k, v in base.items()},
            "ratios": ratios,
            "wall_s": round(time.perf_counter() - wall, 1),
        },
    )


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=FRAMES, help="frames per sensor")
    parser.add_argument("--passes", type=int, default=PASSES, help="timed passes per sensor")
    args = parser.parse_args()
    main(args.frames, args.passes)
