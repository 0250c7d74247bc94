# SPDX-License-Identifier: Apache-2.0
"""The global separator: the sort trick against brute force, learning on synthetic scenes, the rate."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

# Submodule imports: run from the repository root, `skynav_skyline` alone resolves to the outer folder.
from skynav_skyline.classify import GlobalModel, best_threshold, classification_rate, learn_global, project
from skynav_skyline.features import extract_features
from skynav_skyline.segment import SkylineParams, SkylineSegmenter


def brute_force_best_count(contrast, is_sky):
    """Largest count of labels matched by s > t over every t below, between and above the values."""
    values = np.unique(contrast)
    candidates = np.r_[values[0] - 1, values]  # s > v for each distinct v, and everything above
    matched = ((contrast[None, :] > candidates[:, None]) == is_sky[None, :]).sum(axis=1)
    return int(matched.max())


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.integers(-6, 6), st.booleans()), min_size=1, max_size=60))
def test_best_threshold_equals_brute_force_with_ties(pairs):
    contrast = np.array([p[0] for p in pairs], np.float32) / np.float32(4)
    is_sky = np.array([p[1] for p in pairs])
    t, correct = best_threshold(contrast, is_sky)
    assert correct == brute_force_best_count(contrast, is_sky)
    assert int(((contrast > t) == is_sky).sum()) == correct  # the returned t achieves the count


def test_best_threshold_lies_between_the_classes_of_separable_data():
    contrast = np.array([-3, -2.5, -2, 1, 1.5, 2], np.float32)
    t, correct = best_threshold(contrast, contrast > 0)
    assert correct == 6
    assert t == pytest.approx(-0.5)


def _training_set(scene_factory, encoder, seeds, encoding='mono8', rng_seed=7):
    encode, exposure_gain = encoder
    rng = np.random.default_rng(rng_seed)
    items = []
    for seed in seeds:
        scene = scene_factory(seed, sun=seed % 2 == 0, light=0.3)
        uv = encode(scene.uv, encoding, exposure_gain(scene.uv, scene.circle, encoding, rng.uniform(0.5, 1.0)))
        green = encode(scene.green, encoding, exposure_gain(scene.green, scene.circle, encoding, rng.uniform(0.5, 1.0)))
        items.append((scene, uv, green, extract_features(uv, green, encoding, encoding, scene.circle)))
    return items


def test_learned_uv_green_separator_beats_uv_only_on_minerals(scene_factory, encoder):
    items = _training_set(scene_factory, encoder, seeds=range(4))
    features = [f for *_, f in items]
    truths = [scene.truth for scene, *_ in items]
    circles = [scene.circle for scene, *_ in items]
    grid = np.deg2rad(np.arange(-90, 91, 3.0))
    uv_green = learn_global(features, truths, circles, 'uv-green', angles=grid)
    uv_only = learn_global(features, truths, circles, 'uv')
    assert uv_only.angle == 0.0
    assert uv_green.rate >= 0.99
    assert uv_green.rate > uv_only.rate + 0.03  # the mineral patch is bright in UV but has ground's colour
    assert np.deg2rad(-80) < uv_green.angle < np.deg2rad(-20)  # a UV/green contrast, not UV alone
    for model in (uv_only, uv_green):
        mineral_sky = [
            SkylineSegmenter(scene.circle, SkylineParams.from_model(model)).segment(uv, green, 'mono8', 'mono8')[
                scene.mineral
            ]
            == 255
            for scene, uv, green, _ in items
        ]
        share = np.concatenate(mineral_sky).mean()
        if model is uv_only:
            assert share > 0.1  # UV alone calls much of the mineral sky
        else:
            assert share < 0.01  # the contrast does not

    # The learned rate is exactly what segmenting the training images with the model gives (pooled).
    for model in (uv_green, uv_only):
        correct = total = 0
        for scene, uv, green, _ in items:
            mask = SkylineSegmenter(scene.circle, SkylineParams.from_model(model)).segment(uv, green, 'mono8', 'mono8')
            inside = int(scene.circle.sum())
            correct += classification_rate(mask, scene.truth, scene.circle) * inside
            total += inside
        assert correct / total == pytest.approx(model.rate, abs=1e-12)

    # A held-out scene with other gains, encoded as 16-bit and as radiance: the model still holds.
    encode, exposure_gain = encoder
    held_out = scene_factory(11, light=0.3)
    for encoding in ('mono16', '32FC1'):
        uv = encode(held_out.uv, encoding, exposure_gain(held_out.uv, held_out.circle, encoding, 0.33))
        green = encode(held_out.green, encoding, exposure_gain(held_out.green, held_out.circle, encoding, 0.9))
        mask = SkylineSegmenter(held_out.circle, SkylineParams.from_model(uv_green)).segment(
            uv, green, encoding, encoding
        )
        assert classification_rate(mask, held_out.truth, held_out.circle) >= 0.98


def test_threshold_for_a_fixed_angle_equals_brute_force(scene_factory, encoder):
    encode, exposure_gain = encoder
    features, truths, circles = [], [], []
    for seed in (21, 22):
        scene = scene_factory(seed, width=48, height=40)
        uv = encode(scene.uv, 'mono8', exposure_gain(scene.uv, scene.circle, 'mono8', 0.9))
        green = encode(scene.green, 'mono8', exposure_gain(scene.green, scene.circle, 'mono8', 0.6))
        features.append(extract_features(uv, green, 'mono8', 'mono8', scene.circle))
        truths.append(scene.truth)
        circles.append(scene.circle)
    angle = np.deg2rad(-30.0)
    model = learn_global(features, truths, circles, 'uv-green', angles=[angle], refine=0)
    assert model.angle == angle
    # Brute force: every threshold between distinct pooled contrasts, counting every pixel of the circles.
    contrast = np.concatenate([project(f.x, f.y, angle)[c & f.uv.trusted] for f, c in zip(features, circles)])
    sky = np.concatenate([t[c & f.uv.trusted] > 127 for f, t, c in zip(features, truths, circles)])
    fixed = sum(
        int(np.count_nonzero((f.uv.saturated[c & ~f.uv.trusted]) == (t[c & ~f.uv.trusted] > 127)))
        for f, t, c in zip(features, truths, circles)
    )
    total = sum(int(c.sum()) for c in circles)
    assert model.rate == pytest.approx((fixed + brute_force_best_count(contrast, sky)) / total, abs=1e-12)
    assert ((contrast > model.threshold) == sky).sum() == brute_force_best_count(contrast, sky)


def test_sampled_search_still_reports_the_exact_rate(scene_factory, encoder):
    items = _training_set(scene_factory, encoder, seeds=[3, 4])
    features = [f for *_, f in items]
    truths = [scene.truth for scene, *_ in items]
    circles = items[0][0].circle
    exact = learn_global(features, truths, circles, 'uv-green', angles=np.deg2rad(np.arange(-90, 91, 5.0)))
    sampled = learn_global(
        features, truths, circles, 'uv-green', angles=np.deg2rad(np.arange(-90, 91, 5.0)), max_samples=2000
    )
    assert sampled.rate <= exact.rate + 1e-12
    assert sampled.rate >= exact.rate - 0.01


def test_model_round_trips_through_a_dict():
    model = GlobalModel('uv-green', -0.83, -0.0123, 0.97, 85.0)
    assert GlobalModel.from_dict(model.to_dict()) == model


def test_learning_rejects_inconsistent_input(scene_factory):
    scene = scene_factory(0, width=40, height=32)
    features = extract_features(scene.uv, scene.green, '32FC1', '32FC1', scene.circle)
    other = extract_features(scene.uv, scene.green, '32FC1', '32FC1', scene.circle, reference_percentile=50)
    with pytest.raises(ValueError, match='reference percentiles'):
        learn_global([features, other], [scene.truth, scene.truth], scene.circle)
    with pytest.raises(ValueError, match='one ground-truth mask per'):
        learn_global([features], [], scene.circle)
    with pytest.raises(ValueError, match='differ in shape'):
        learn_global([features], [scene.truth[:-1]], scene.circle)
    with pytest.raises(ValueError, match='unknown channel mode'):
        learn_global([features], [scene.truth], scene.circle, channels='green')
    uv_only = extract_features(scene.uv, None, '32FC1', None, scene.circle)
    with pytest.raises(ValueError, match='green'):
        learn_global([uv_only], [scene.truth], scene.circle, channels='uv-green')
