# SPDX-License-Identifier: Apache-2.0
"""The per-image discriminant: exemplars where an upward view puts them, Fisher's direction, the class threshold."""

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from skynav_core.camera import EquidistantCamera
from skynav_skyline.discriminant import MIN_EXEMPLARS, class_threshold, exemplars, fit
from skynav_skyline.errors import SkylineError
from skynav_skyline.geometry import SkylineGeometry
from skynav_skyline.parameters import colour_params, skyline_params
from skynav_skyline.segment import FitCheckSchedule, SkylineSegmenter

CAMERA = EquidistantCamera.for_field_of_view(160, 120, math.radians(200))


@given(
    st.floats(-5, 5),
    st.floats(0.01, 3),
    st.floats(0.01, 10),
    st.floats(0.01, 3),
    st.floats(0.01, 0.99),
)
def test_the_class_threshold_lies_between_the_means(low, low_spread, gap, high_spread, prior):
    threshold = class_threshold(low + gap, high_spread, low, low_spread, prior)
    assert low <= threshold <= low + gap


def test_the_class_threshold_is_the_midpoint_of_like_classes_and_yields_to_the_likelier_one():
    assert class_threshold(2.0, 0.5, 0.0, 0.5, 0.5) == pytest.approx(1.0, abs=0.01)
    assert class_threshold(2.0, 0.5, 0.0, 0.5, 0.9) < 0.9  # sky more likely: more of the middle is sky
    assert class_threshold(2.0, 0.5, 0.0, 0.5, 0.1) > 1.1
    # a narrow high class and a wide low one meet twice; the meeting between the means is the threshold
    assert 0.0 < class_threshold(2.0, 0.1, 0.0, 1.0, 0.5) < 2.0


def gaussian_classes(rng, count=4000):
    """Return log features (3, n) of two Gaussian classes and which are sky: sky bright and blue, ground dark."""
    cov = np.array([[0.20, 0.15, 0.05], [0.15, 0.20, 0.08], [0.05, 0.08, 0.25]])
    sky = rng.multivariate_normal([-0.5, -0.3, 0.0], cov, count)
    ground = rng.multivariate_normal([-1.6, -1.4, -2.2], cov, count)
    return np.vstack([sky, ground]).T, np.r_[np.ones(count, bool), np.zeros(count, bool)]


def test_fit_finds_fishers_direction_and_puts_the_threshold_at_zero_in_spread_units():
    rng = np.random.default_rng(3)
    features, is_sky = gaussian_classes(rng)
    model = fit(features, is_sky, ~is_sky)
    assert model is not None
    pooled = 0.5 * (np.cov(features[:, is_sky]) + np.cov(features[:, ~is_sky]))
    fisher = np.linalg.solve(pooled, features[:, is_sky].mean(1) - features[:, ~is_sky].mean(1))
    cosine = model.weights @ fisher / np.linalg.norm(model.weights) / np.linalg.norm(fisher)
    assert cosine > 0.999
    projected = model.project(features)
    spread = math.sqrt(0.5 * (projected[is_sky].var() + projected[~is_sky].var()))
    assert spread == pytest.approx(1.0, rel=0.01)  # spread units
    assert abs(projected[is_sky].mean() + projected[~is_sky].mean()) < 0.05 * np.ptp(projected)  # 0 halfway
    fresh, fresh_sky = gaussian_classes(np.random.default_rng(4))
    assert np.mean((model.project(fresh) > 0) == fresh_sky) > 0.99


def test_fit_needs_exemplars_of_both_classes():
    features, is_sky = gaussian_classes(np.random.default_rng(5))
    few = np.zeros_like(is_sky)
    few[np.flatnonzero(~is_sky)[: MIN_EXEMPLARS - 1]] = True
    assert fit(features, is_sky, few) is None
    assert fit(features, is_sky, ~is_sky) is not None


def test_exemplars_are_bright_or_sky_coloured_inside_and_dark_outside():
    rng = np.random.default_rng(6)
    count = 2000
    inner = np.r_[np.ones(count, bool), np.zeros(count, bool)]
    logs = rng.normal(0.0, 1.0, (3, 2 * count))
    sky, ground = exemplars(logs, inner, np.ones(2 * count, bool))
    brightness, colour = logs.mean(0), logs[2] - logs[0]
    assert not (sky & ~inner).any() and not (ground & inner).any()
    assert sky.sum() >= 0.2 * count  # the brightest or the most sky-coloured fifth each
    assert np.all(
        (brightness[sky] >= np.quantile(brightness[inner], 0.8)) | (colour[sky] >= np.quantile(colour[inner], 0.8))
    )
    assert np.all(brightness[ground] <= np.quantile(brightness[~inner], 0.2))
    assert np.all(colour[ground] < np.quantile(colour[~inner], 0.5))
    untrusted = np.zeros(2 * count, bool)
    assert not any(e.any() for e in exemplars(logs, inner, untrusted))


@pytest.fixture(scope='module')
def upward_view():
    return scene()


def scene():
    """A synthetic upward view (linear RGB 0..1) and its truth (True sky): a blue sky four times brighter towards a
    low sun than across from it, bright grey clouds, and along the rim dark green vegetation and brown bark."""
    rng = np.random.default_rng(7)
    v, u = np.mgrid[0:120, 0:160]
    radius = np.hypot(u - CAMERA.cx, v - CAMERA.cy) / CAMERA.cy  # 1 at the image circle's edge
    angle = np.arctan2(v - CAMERA.cy, u - CAMERA.cx)
    glow = 1.0 + 3.0 * np.exp(-((u - 125) ** 2 + (v - 50) ** 2) / 600.0)
    rgb = np.stack([0.06 * glow, 0.11 * glow, 0.24 * glow], -1)  # clear sky: blue
    cloud = (np.sin(u / 9.0) + np.cos(v / 7.0)) > 1.3
    rgb[cloud] = (0.7, 0.72, 0.76)  # clouds: bright, nearly grey
    ground = radius > 0.8 + 0.07 * np.sin(3 * angle)
    rgb[ground] = (0.04, 0.07, 0.02)  # vegetation
    rgb[ground & (np.abs(angle - 2.2) < 0.3)] = (0.09, 0.06, 0.04)  # bark
    rgb *= rng.uniform(0.92, 1.08, rgb.shape)
    return np.clip(rgb, 0, 1), ~ground


def accuracy(mask, truth):
    inside = CAMERA.image_circle()
    return np.mean((mask[inside] > 127) == truth[inside])


def test_the_discriminant_separates_a_colour_view_that_no_learned_threshold_on_blue_does(upward_view):
    rgb, truth = upward_view
    linear = np.rint(rgb * 65535).astype(np.uint16)
    geometry = SkylineGeometry.from_camera(CAMERA)
    own = SkylineSegmenter(geometry, colour_params({})).segment_colour(linear)
    learned_params = colour_params({'colour_method': 'sector-min-error', 'max_disagreement': math.inf})
    learned = SkylineSegmenter(geometry, learned_params).segment_colour(linear)
    assert accuracy(own, truth) > 0.97
    assert accuracy(own, truth) > accuracy(learned, truth) + 0.03


def test_the_discriminant_ignores_gains_and_a_tone_curve(upward_view):
    """Log features turn per-channel gains into shifts and a power-law tone curve into a scale: Fisher's
    direction and the class threshold follow both, so the mask stays (up to quantisation)."""
    rgb, _ = upward_view
    segmenter = SkylineSegmenter(SkylineGeometry.from_camera(CAMERA), colour_params({}))
    reference = segmenter.segment_colour(np.rint(rgb * 65535).astype(np.uint16))
    changed = np.clip((rgb * np.array([0.6, 0.9, 0.45])) ** (1 / 2.2), 0, 1)
    other = segmenter.segment_colour(np.rint(changed * 65535).astype(np.uint16))
    inside = CAMERA.image_circle()
    assert np.mean(reference[inside] == other[inside]) > 0.995


def test_other_methods_on_a_colour_frame_read_blue_for_uv_and_green(upward_view):
    rgb, _ = upward_view
    linear = np.rint(rgb * 65535).astype(np.uint16)
    params = colour_params({'colour_method': 'sector-otsu'})
    segmenter = SkylineSegmenter(SkylineGeometry.from_camera(CAMERA), params)
    planes = segmenter.segment(linear[..., 2], linear[..., 1], 'mono16', 'mono16')
    assert np.array_equal(segmenter.segment_colour(linear), planes)


def test_the_uv_green_discriminant_takes_the_pairs_channels(upward_view):
    rgb, truth = upward_view
    uv, green = (np.rint(rgb[..., k] * 65535).astype(np.uint16) for k in (2, 1))
    params = replace(skyline_params({}), method='discriminant')
    mask = SkylineSegmenter(SkylineGeometry.from_camera(CAMERA), params).segment(uv, green, 'mono16', 'mono16')
    assert accuracy(mask, truth) > 0.95


def test_learned_thresholds_give_way_to_the_discriminant_where_they_do_not_fit(upward_view):
    """The fit check (max_disagreement) of the UV/green path: on the view above, blue for UV, the learned thresholds
    miss the dim sky and disagree with the image's own discriminant on much of it, so the discriminant's mask is
    taken; where the learned thresholds fit (a plain view), the mask is theirs, unchanged."""
    rgb, truth = upward_view
    uv, green = (np.rint(rgb[..., k] * 65535).astype(np.uint16) for k in (2, 1))
    geometry = SkylineGeometry.from_camera(CAMERA)
    checked = SkylineSegmenter(geometry, skyline_params({}))
    unchecked = SkylineSegmenter(geometry, skyline_params({'max_disagreement': math.inf}))
    own = SkylineSegmenter(geometry, replace(skyline_params({}), method='discriminant'))
    assert checked.params.method == 'sector-min-error' and checked.params.checks_fit
    learned = unchecked.segment(uv, green, 'mono16', 'mono16')
    assert accuracy(learned, truth) < 0.9
    assert np.array_equal(checked.segment(uv, green, 'mono16', 'mono16'), own.segment(uv, green, 'mono16', 'mono16'))
    plain = np.where(truth, 0.6, 0.03) * np.random.default_rng(8).uniform(0.95, 1.05, truth.shape)
    plain_uv, plain_green = np.rint(plain * 65535).astype(np.uint16), np.rint(plain * 0.8 * 65535).astype(np.uint16)
    assert np.array_equal(
        checked.segment(plain_uv, plain_green, 'mono16', 'mono16'),
        unchecked.segment(plain_uv, plain_green, 'mono16', 'mono16'),
    )


def test_the_fit_check_runs_on_one_exposure_in_a_period_and_on_each_while_near_its_bound():
    schedule = FitCheckSchedule(3, max_disagreement=0.2)
    checked = []
    for disagreement in [0.01, 0.01, 0.01, 0.01, 0.01, 0.01, 0.15, 0.3, 0.05, 0.05, 0.05]:
        due = schedule.due()
        checked.append(due)
        schedule.done(disagreement if due else None)
    # one in three, until a check comes above half the bound (0.15): then every one until one is well within it
    assert checked == [True, False, False, True, False, False, True, True, True, False, False]
    every = FitCheckSchedule(1, max_disagreement=0.2)
    for _ in range(5):
        assert every.due()
        every.done(0.0)
    with pytest.raises(SkylineError, match='at least 1'):
        FitCheckSchedule(0, max_disagreement=0.2)


def test_an_exposure_without_the_fit_check_keeps_the_learned_mask(upward_view):
    """check_fit=False: the learned thresholds' mask and no disagreement; True: the check's share is kept."""
    rgb, _ = upward_view
    uv, green = (np.rint(rgb[..., k] * 65535).astype(np.uint16) for k in (2, 1))
    geometry = SkylineGeometry.from_camera(CAMERA)
    checked = SkylineSegmenter(geometry, skyline_params({}))
    unchecked = SkylineSegmenter(geometry, skyline_params({'max_disagreement': math.inf}))
    learned = unchecked.segment(uv, green, 'mono16', 'mono16')
    assert np.array_equal(checked.segment(uv, green, 'mono16', 'mono16', check_fit=False), learned)
    assert checked.disagreement is None
    assert not np.array_equal(checked.segment(uv, green, 'mono16', 'mono16', check_fit=True), learned)
    assert checked.disagreement > checked.params.max_disagreement


def test_the_node_checks_the_fit_once_a_period_and_then_each_exposure_that_does_not_fit(upward_view):
    """fit_check_period 3: plain exposures 0-3 keep the learned masks (checked: 0 and 3); the misfit exposures
    from 4 keep the learned mask until the next check (6) hands over, and every one after it is checked."""
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import CameraInfo, Image

    from skynav_core.graph import in_process, type_name
    from skynav_core.images import fill_image, image_to_array
    from skynav_core.names import GREEN_IMAGE, SKYLINE_MASK, UV_CAMERA_INFO, UV_IMAGE
    from skynav_core.nodes import NodeSpec
    from skynav_core.recording.bag import RawMessage

    def raw(topic, message, stamp):
        message.header.stamp.sec, message.header.stamp.nanosec = divmod(stamp, 10**9)
        return RawMessage(topic, type_name(message), stamp, serialize_message(message))

    rgb, truth = upward_view
    misfit = [np.rint(rgb[..., k] * 65535).astype(np.uint16) for k in (2, 1)]
    plain = np.where(truth, 0.6, 0.03) * np.random.default_rng(8).uniform(0.95, 1.05, truth.shape)
    fitting = [np.rint(plain * 65535).astype(np.uint16), np.rint(plain * 0.8 * 65535).astype(np.uint16)]
    geometry = SkylineGeometry.from_camera(CAMERA)
    learned = SkylineSegmenter(geometry, skyline_params({'max_disagreement': math.inf}))
    own = SkylineSegmenter(geometry, replace(skyline_params({}), method='discriminant'))
    info = CameraInfo()
    for key, value in CAMERA.camera_info_fields().items():
        setattr(info, key, value)
    spec = NodeSpec('skyline', 'skynav_skyline', 'skynav_skyline.node:SkylineNode')
    exposures = [fitting] * 4 + [misfit] * 4
    with in_process([spec], ['-p', 'fit_check_period:=3']) as graph:
        graph.keep_outputs = True
        t0 = 1_700_000_000 * 10**9
        graph.feed(raw(UV_CAMERA_INFO, info, t0))
        for k, (uv, green) in enumerate(exposures):
            graph.feed(raw(UV_IMAGE, fill_image(Image(), uv, 'mono16'), t0 + k * 10**8))
            graph.feed(raw(GREEN_IMAGE, fill_image(Image(), green, 'mono16'), t0 + k * 10**8))
        masks = [image_to_array(o.message) for o in graph.outputs if o.topic == SKYLINE_MASK]
    assert len(masks) == len(exposures)
    expected = [learned.segment(*fitting, 'mono16', 'mono16')] * 4
    expected += [learned.segment(*misfit, 'mono16', 'mono16')] * 2 + [own.segment(*misfit, 'mono16', 'mono16')] * 2
    assert not np.array_equal(expected[4], expected[6])
    for k, (mask, wanted) in enumerate(zip(masks, expected)):
        assert np.array_equal(mask, wanted), f'exposure {k}'
