# SPDX-License-Identifier: Apache-2.0
"""Baselines: SeqSLAM's patch-normalised raw UV image and the ORB bag of words."""

from __future__ import annotations

import numpy as np
import pytest

from skynav_core.maps import MapStore
from skynav_localize.descriptors import distance_matrix
from skynav_localize.eval.baselines import (
    RAW_UV_PATCH,
    RAW_UV_SIZE,
    BowVocabulary,
    as_uint8,
    kmeans,
    orb_descriptors,
    orb_mask,
    raw_uv_descriptor,
    train_bow,
)
from skynav_localize.matching import single_frame


def test_raw_uv_descriptor_is_patch_normalised_and_gain_free():
    rng = np.random.default_rng(0)
    image = rng.integers(0, 200, (240, 320)).astype(np.uint8)
    descriptor = raw_uv_descriptor(image)
    assert descriptor.shape == (RAW_UV_SIZE[0] * RAW_UV_SIZE[1],) and descriptor.dtype == np.float32
    patches = descriptor.reshape(
        RAW_UV_SIZE[1] // RAW_UV_PATCH, RAW_UV_PATCH, RAW_UV_SIZE[0] // RAW_UV_PATCH, RAW_UV_PATCH
    )
    np.testing.assert_allclose(patches.mean(axis=(1, 3)), 0.0, atol=1e-5)
    np.testing.assert_allclose(patches.std(axis=(1, 3)), 1.0, atol=1e-4)
    # another exposure (gain and black level) or encoding gives the same descriptor
    np.testing.assert_allclose(raw_uv_descriptor(image.astype(np.uint16) * 257 + 1000), descriptor, atol=1e-3)
    np.testing.assert_allclose(raw_uv_descriptor(image.astype(np.float32) * 0.01), descriptor, atol=1e-3)
    assert not np.any(raw_uv_descriptor(np.zeros((240, 320), np.uint8)))  # flat patches stay 0
    with pytest.raises(ValueError, match='multiple of the patch'):
        raw_uv_descriptor(image, (30, 24), 4)


def test_as_uint8_scales_other_encodings():
    image = np.linspace(0, 4000, 240 * 320).reshape(240, 320).astype(np.uint16)
    scaled = as_uint8(image)
    assert scaled.dtype == np.uint8 and scaled.max() == 255 and scaled.min() == 0


def test_kmeans_finds_separated_clusters():
    rng = np.random.default_rng(3)
    centres = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]])
    points = np.concatenate([c + 0.3 * rng.standard_normal((50, 2)) for c in centres]).astype(np.float32)
    found = kmeans(points, 3, np.random.default_rng(1))
    assert np.all(np.min(np.linalg.norm(found[:, None] - centres[None], axis=-1), axis=0) < 0.2)


def test_bag_of_orb_words_recognises_the_taught_views(garden, tmp_path):
    teach = garden['teach']
    features = [orb_descriptors(uv, teach.circle, 300) for uv in teach.uv[::4]]
    assert all(len(f) > 50 and f.dtype == np.uint8 and f.shape[1] == 32 for f in features)
    vocabulary = BowVocabulary.train(features, size=128, seed=0)
    assert vocabulary.words.shape == (128, 256) and vocabulary.idf.shape == (128,)
    vectors = vocabulary.vectors(features)
    np.testing.assert_allclose(np.linalg.norm(vectors, axis=1), 1.0)
    best, distance, _ = single_frame(distance_matrix(vectors, vectors, 'cosine'))
    np.testing.assert_array_equal(best, np.arange(len(features)))  # every view is nearest to itself
    np.testing.assert_allclose(distance, 0.0, atol=1e-6)
    # stored with the map and read back
    with MapStore.create(tmp_path / 'bow.db', 'bow', 2) as store:
        for f in features:
            store.add_snapshot(np.zeros(9), 0, None, {'orb': f})
        saved = train_bow(store, size=128, seed=0)
    loaded = BowVocabulary.load(MapStore.open(tmp_path / 'bow.db'))
    np.testing.assert_array_equal(loaded.words, saved.words)
    np.testing.assert_array_equal(loaded.idf, saved.idf)
    np.testing.assert_allclose(
        MapStore.open(tmp_path / 'bow.db').descriptor_matrix('bow-orb'), saved.vectors(features), atol=1e-6
    )


def test_orb_keeps_to_the_image_circle(garden):
    import cv2

    teach = garden['teach']
    mask = orb_mask(teach.circle, teach.circle.shape) > 0
    assert np.all(teach.circle[mask]) and mask.sum() < teach.circle.sum()
    keypoints = cv2.ORB_create(nfeatures=300).detect(teach.uv[0], mask.astype(np.uint8) * 255)
    assert len(keypoints) > 50
    assert all(mask[int(round(k.pt[1])), int(round(k.pt[0]))] for k in keypoints)
    assert len(orb_descriptors(np.zeros((240, 320), np.uint8), teach.circle)) == 0  # a black image: no words
    empty = BowVocabulary(np.zeros((4, 256), np.float32), np.ones(4)).vector(np.zeros((0, 32), np.uint8))
    assert not np.any(empty)
