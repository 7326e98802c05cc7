"""Tests for openptrack_py.sim.clothing: palettes, their mapping of draws, uniforms."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from openptrack_py.detection.appearance import signature_bins
from openptrack_py.sim import Simulator, TruthFrame, build_scenario
from openptrack_py.sim.clothing import (
    BLACK,
    BOTTOM_PALETTE,
    SCHOOL_UNIFORMS,
    TOP_PALETTE,
    clothing_colour,
    palette_name,
)
from openptrack_py.sim.scenarios import scenario_world
from openptrack_py.sim.world import random_person


def _old_random_person_draws(rng: np.random.Generator, kind: str) -> None:
    """Every draw ``random_person`` made when clothes were uniformly random hues."""
    if kind == "child":
        rng.uniform(0.8, 1.2), rng.uniform(0.14, 0.18), rng.uniform(0.6, 1.0)
    else:
        rng.normal(1.74, 0.09), rng.uniform(0.2, 0.25), rng.uniform(0.9, 1.4)
    rng.uniform(0, 360), rng.uniform(0, 360)


@pytest.mark.parametrize("palette", [TOP_PALETTE, BOTTOM_PALETTE], ids=["top", "bottom"])
def test_palette_shares_sum_to_one_and_names_are_unique(palette: tuple) -> None:
    assert sum(c.share for c in palette) == pytest.approx(1.0)
    assert len({c.name for c in palette}) == len(palette)
    for c in palette:
        hue, saturation, value = c.hsv
        assert 0 <= hue < 360 and 0 <= saturation <= 1 and 0 <= value <= 1 and c.share > 0


def test_a_uniform_draw_maps_onto_the_palette_by_its_cumulative_shares() -> None:
    # top palette: black [0, 0.20), dark grey [0.20, 0.28), grey [0.28, 0.36), white...
    assert palette_name(0.0) == palette_name(0.1999) == "black"
    assert palette_name(0.2001) == "dark grey"
    assert palette_name(0.9999) == TOP_PALETTE[-1].name
    assert palette_name(0.0, BOTTOM_PALETTE) == "denim blue"
    # the rest of the draw shades the colour a little, never into another colour
    shades = np.array([clothing_colour(u) for u in np.linspace(0.0, 0.1999, 200)])
    assert np.all(np.abs(shades[:, 2] - BLACK[2]) <= 0.125 * BLACK[2] + 1e-12)
    assert np.all(np.abs((shades[:, 0] - BLACK[0] + 180) % 360 - 180) <= 6.0 + 1e-9)
    assert np.ptp(shades[:, 2]) > 0.02  # but it does shade
    assert clothing_colour(0.05) == clothing_colour(0.05)  # deterministic


@pytest.mark.parametrize("kind", ["adult", "child"])
@pytest.mark.parametrize("seed", [0, 1, 7])
def test_random_person_keeps_the_worlds_random_stream(kind: str, seed: int) -> None:
    new, old = np.random.default_rng(seed), np.random.default_rng(seed)
    spec = random_person(new, kind)  # type: ignore[arg-type]
    _old_random_person_draws(old, kind)
    assert new.bit_generator.state == old.bit_generator.state
    assert np.array_equal(new.random(8), old.random(8))  # every later draw is the same
    # and the drawn body is what it was
    again = np.random.default_rng(seed)
    if kind == "adult":
        assert spec.height == float(np.clip(again.normal(1.74, 0.09), 1.55, 1.95))
    else:
        assert spec.height == float(again.uniform(0.8, 1.2))


def test_people_mostly_wear_dark_and_achromatic_clothes() -> None:
    rng = np.random.default_rng(5)
    people = [random_person(rng) for _ in range(4000)]
    tops = np.array([p.top for p in people])
    bottoms = np.array([p.bottom for p in people])

    def achromatic(hsv: np.ndarray) -> np.ndarray:
        return signature_bins(hsv[:, 0], hsv[:, 1], hsv[:, 2]) >= 16

    def vivid(hsv: np.ndarray) -> np.ndarray:
        return (hsv[:, 1] > 0.6) & (hsv[:, 2] > 0.55)

    assert 0.4 < achromatic(tops).mean() < 0.6  # black, greys and white
    assert 0.35 < achromatic(bottoms).mean() < 0.55
    dark = (tops[:, 2] < 0.35).mean()
    assert 0.3 < dark < 0.55  # black, charcoal, navy, brown...
    assert vivid(tops).mean() < 0.12  # red, yellow, orange are the exception
    assert vivid(bottoms).mean() < 0.03
    blues = (np.abs(bottoms[:, 0] - 215) < 15) & (bottoms[:, 1] > 0.3)
    assert 0.3 < blues.mean() < 0.45  # denim and navy
    names = Counter(palette_name(u) for u in np.random.default_rng(1).random(4000))
    assert set(names) == {c.name for c in TOP_PALETTE}
    # many people share a look: far fewer distinct top colours than people
    assert names.most_common(1)[0][1] > 600


def test_uniforms_dress_everyone_in_one_of_two_combinations() -> None:
    scenario = build_scenario("uniforms", seed=3, duration_s=2.0)
    world = scenario_world(scenario)
    snap = world.snapshot()
    top, bottom = snap.clothing()
    looks = {(tuple(t), tuple(b)) for t, b in zip(top.tolist(), bottom.tolist(), strict=True)}
    assert looks <= set(SCHOOL_UNIFORMS) and len(looks) == 2
    assert len(snap) >= 16 and set(snap.kinds.tolist()) == {"adult", "child"}
    # the same children, walking the same paths, as in the classroom
    plain = build_scenario("classroom", seed=3, duration_s=2.0)
    paths = [
        [(p.id, p.x, p.y, p.height) for p in ev.frame.people]
        for s in (scenario, plain)
        for ev in Simulator(s).events(sensor_frames=False)
        if isinstance(ev, TruthFrame)
    ]
    half = len(paths) // 2
    assert paths[:half] == paths[half:]
    # and in the classroom, clothes are the palettes' variety
    top, _ = scenario_world(plain).snapshot().clothing()
    assert len({tuple(t) for t in top.tolist()}) > 10


def test_other_scenarios_dress_people_from_the_palettes() -> None:
    snap = scenario_world(build_scenario("crowd", seed=2)).snapshot()
    top, bottom = snap.clothing()
    assert len({tuple(t) for t in top.tolist()}) == len(snap)  # shaded: all distinct
    assert np.all((top[:, 1:] >= 0) & (top[:, 1:] <= 1))
    assert np.all((bottom[:, 1:] >= 0) & (bottom[:, 1:] <= 1))
